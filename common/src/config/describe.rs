//! The key reference of the configuration (`dupac config --describe`): every key with its
//! default and its meaning, read from the doc comments of the configuration structs through the
//! JSON schema that `schemars` derives from them, so a key and its description never part.

use super::Config;
use serde_json::Value;

/// One key of the configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct KeyDoc {
    /// Dotted path, e.g. `radio.fc_ghz`.
    pub key: String,
    /// Whether the key is a table (a section such as `radio` or `env.reward`).
    pub table: bool,
    /// The default as inline TOML; `None` for a table, or an optional key unset by default.
    pub default: Option<String>,
    /// The doc comment of the field (of its type for a table without one), lines joined.
    pub doc: String,
}

/// Every key of [`Config`] (the optional ones unset by default too), sorted by key within each
/// table, each table before its keys.
pub fn key_docs() -> Vec<KeyDoc> {
    let schema = schemars::schema_for!(Config).to_value();
    let defaults = toml::Value::try_from(Config::default()).ok();
    let mut out = Vec::new();
    walk(&schema, &schema, "", defaults.as_ref(), &mut out);
    out
}

/// `node` with its `$ref` followed (also inside an `anyOf`/`oneOf` with `null`, as an
/// `Option<T>` gives).
fn resolve<'a>(root: &'a Value, node: &'a Value) -> &'a Value {
    if let Some(r) = node.get("$ref").and_then(Value::as_str) {
        let name = r.rsplit('/').next().unwrap_or_default();
        if let Some(def) = root.get("$defs").and_then(|d| d.get(name)) {
            return resolve(root, def);
        }
    }
    for k in ["anyOf", "oneOf"] {
        if let Some(alts) = node.get(k).and_then(Value::as_array) {
            let real: Vec<&Value> = alts
                .iter()
                .filter(|a| a.get("type").and_then(Value::as_str) != Some("null"))
                .collect();
            if let [one] = real.as_slice()
                && one.get("$ref").is_some()
            {
                return resolve(root, one);
            }
        }
    }
    node
}

fn description(v: &Value) -> Option<String> {
    let d = v.get("description").and_then(Value::as_str)?;
    let joined = d.split_whitespace().collect::<Vec<_>>().join(" ");
    (!joined.is_empty()).then_some(joined)
}

fn walk(
    root: &Value,
    node: &Value,
    prefix: &str,
    defaults: Option<&toml::Value>,
    out: &mut Vec<KeyDoc>,
) {
    let Some(props) = resolve(root, node)
        .get("properties")
        .and_then(Value::as_object)
    else {
        return;
    };
    for (name, prop) in props {
        let key = if prefix.is_empty() {
            name.clone()
        } else {
            format!("{prefix}.{name}")
        };
        let target = resolve(root, prop);
        let table = target.get("properties").is_some();
        let default = defaults.and_then(|d| d.get(name));
        out.push(KeyDoc {
            key: key.clone(),
            table,
            default: (!table).then(|| default.map(inline)).flatten(),
            doc: [
                description(prop).or_else(|| description(target)),
                choices(target),
            ]
            .into_iter()
            .flatten()
            .collect::<Vec<_>>()
            .join(" "),
        });
        if table {
            walk(root, prop, &key, default, out);
        }
    }
}

/// The values of an enumeration, each with its meaning when it has one:
/// `One of: "learned" (DUPAC: …), "a3" (…).`
fn choices(target: &Value) -> Option<String> {
    let quoted = |v: &Value| v.as_str().map(|s| format!("{s:?}"));
    let items: Vec<String> = if let Some(alts) = target.get("oneOf").and_then(Value::as_array) {
        alts.iter()
            .filter_map(|a| {
                let name = a
                    .get("const")
                    .and_then(quoted)
                    .or_else(|| a.get("enum")?.as_array()?.first().and_then(quoted))?;
                Some(match description(a) {
                    Some(d) => format!("{name} ({})", d.trim_end_matches('.')),
                    None => name,
                })
            })
            .collect()
    } else {
        target
            .get("enum")
            .and_then(Value::as_array)
            .map(|v| v.iter().filter_map(quoted).collect())
            .unwrap_or_default()
    };
    (!items.is_empty()).then(|| format!("One of: {}.", items.join(", ")))
}

/// A TOML value as it is written after `key = `.
fn inline(v: &toml::Value) -> String {
    match v {
        toml::Value::String(s) => toml::Value::String(s.clone()).to_string(),
        other => other.to_string(),
    }
}

/// The reference as text: `[table]` and `key = default` lines, each followed by its meaning
/// indented and wrapped at `width` columns.
pub fn describe(width: usize) -> String {
    let mut s = String::new();
    for k in key_docs() {
        if k.table {
            s.push_str(&format!("\n[{}]\n", k.key));
        } else {
            match &k.default {
                Some(d) => s.push_str(&format!("{} = {d}\n", k.key)),
                None => s.push_str(&format!("{} (unset by default)\n", k.key)),
            }
        }
        let mut line = String::from("   ");
        for word in k.doc.split_whitespace() {
            if line.len() + 1 + word.len() > width && line.len() > 3 {
                s.push_str(&line);
                s.push('\n');
                line = String::from("   ");
            }
            line.push(' ');
            line.push_str(word);
        }
        if line.len() > 3 {
            s.push_str(&line);
            s.push('\n');
        }
    }
    s.trim_start().to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every key has a description: a key added without a doc comment fails here.
    #[test]
    fn every_key_is_described() {
        let docs = key_docs();
        let missing: Vec<&str> = docs
            .iter()
            .filter(|k| k.doc.is_empty())
            .map(|k| k.key.as_str())
            .collect();
        assert!(
            missing.is_empty(),
            "keys without a doc comment: {missing:?}"
        );
        // And the reference covers every key of the default configuration's TOML.
        fn keys(prefix: &str, t: &toml::Table, out: &mut Vec<String>) {
            for (k, v) in t {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                if let toml::Value::Table(inner) = v {
                    keys(&key, inner, out);
                }
                out.push(key);
            }
        }
        let mut toml_keys = Vec::new();
        let table = toml::Table::try_from(Config::default()).expect("default as TOML");
        keys("", &table, &mut toml_keys);
        let described: std::collections::HashSet<&str> =
            docs.iter().map(|k| k.key.as_str()).collect();
        let absent: Vec<&String> = toml_keys
            .iter()
            .filter(|k| !described.contains(k.as_str()))
            .collect();
        assert!(
            absent.is_empty(),
            "keys missing from the reference: {absent:?}"
        );
    }

    #[test]
    fn the_reference_gives_defaults_and_meanings() {
        let docs = key_docs();
        let fc = docs
            .iter()
            .find(|k| k.key == "radio.fc_ghz")
            .expect("radio.fc_ghz");
        assert_eq!(fc.default.as_deref(), Some("2.0"));
        assert!(!fc.table && fc.doc.contains("GHz"), "{fc:?}");
        let radio = docs.iter().position(|k| k.key == "radio").expect("radio");
        assert!(docs[radio].table);
        assert!(
            radio
                < docs
                    .iter()
                    .position(|k| k.key == "radio.fc_ghz")
                    .expect("key")
        );
        let text = describe(80);
        assert!(text.contains("\n[radio]\n") && text.contains("radio.fc_ghz = 2.0\n"));
        assert!(text.lines().all(|l| l.len() <= 80 || !l.contains(' ')));
        let association = docs
            .iter()
            .find(|k| k.key == "env.association")
            .expect("env.association");
        assert!(
            association.doc.contains("One of: \"learned\" (DUPAC"),
            "{association:?}"
        );
    }
}
