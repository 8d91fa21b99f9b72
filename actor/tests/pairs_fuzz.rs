//! Property tests of the pairs-file reader: arbitrary bytes, a
//! valid file with bytes flipped, cut or extended, and valid lines with one value replaced by a
//! hostile one (NaN, huge, negative, a string where a number belongs, missing fields). The reader
//! must never panic; every error names the file and, for a bad line, its line number; valid
//! files (blank lines, missing optional fields) still load.

use dupac_actor::pairs::{Pair, PairsError, read_pairs_jsonl, training_pool};
use dupac_actor::planner::Planner;
use dupac_common::config::{CityKind, Config, PairsConfig, ScenarioConfig};
use dupac_radio::city::City;
use proptest::prelude::*;
use serde_json::{Value, json};
use std::sync::OnceLock;

fn city() -> &'static City {
    static CITY: OnceLock<City> = OnceLock::new();
    CITY.get_or_init(|| {
        let mut sc = ScenarioConfig {
            city: CityKind::Procedural,
            name: "procedural".into(),
            ..ScenarioConfig::default()
        };
        sc.procedural.size_m = 400.0;
        City::load(&sc).expect("procedural city")
    })
}

fn config() -> &'static Config {
    static CONFIG: OnceLock<Config> = OnceLock::new();
    CONFIG.get_or_init(Config::default)
}

fn planner() -> &'static Planner<'static> {
    static PLANNER: OnceLock<Planner<'static>> = OnceLock::new();
    PLANNER.get_or_init(|| Planner::new(city(), &config().env, &config().planner))
}

fn pairs_cfg() -> PairsConfig {
    PairsConfig {
        eval_bins_m: vec![100.0, 200.0],
        eval_per_bin: 2,
        min_m: 80.0,
        max_m: 250.0,
        ..PairsConfig::default()
    }
}

/// Three valid pairs of the 400 m procedural city, as JSON lines.
fn valid_pairs() -> &'static [Pair] {
    static PAIRS: OnceLock<Vec<Pair>> = OnceLock::new();
    PAIRS.get_or_init(|| {
        let p = training_pool(planner(), &pairs_cfg(), &config().env, 3, 11, &|_| {});
        assert_eq!(p.len(), 3);
        p
    })
}

fn valid_lines() -> Vec<String> {
    valid_pairs()
        .iter()
        .map(|p| serde_json::to_string(p).expect("json"))
        .collect()
}

/// Writes `bytes` to a uniquely named file under the system temporary directory and reads it
/// back as a pairs file. Checks that an error names the file and a line of it.
fn judge(bytes: &[u8]) -> Result<Vec<Pair>, PairsError> {
    let mut f = tempfile::Builder::new()
        .prefix("dupac-pairs-fuzz-")
        .suffix(".jsonl")
        .tempfile_in(std::env::temp_dir())
        .expect("temp file");
    std::io::Write::write_all(&mut f, bytes).expect("write");
    let r = read_pairs_jsonl(f.path(), planner(), &pairs_cfg());
    let name = f.path().display().to_string();
    match &r {
        Ok(pairs) => {
            assert!(!pairs.is_empty());
            for p in pairs {
                assert!(p.shortest_m.is_finite() && p.shortest_m > 0.0, "{p:?}");
                assert!(p.straight_m.is_finite() && p.shortest_m >= p.straight_m - 1e-6);
            }
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains(&name), "error without the file: {msg}");
            if let PairsError::Line { line, .. } = e {
                let lines = bytes.split(|&b| b == b'\n').count();
                assert!(
                    *line >= 1 && *line <= lines,
                    "line {line} of {lines}: {msg}"
                );
                assert!(msg.contains(&format!("{name}:{line}: ")), "{msg}");
                // No other line number that could be taken for the file's.
                if *line != 1 {
                    assert!(!msg.contains("line 1 "), "{msg}");
                }
            }
        }
    }
    r
}

/// JSON text put in place of a value.
const HOSTILE: &[&str] = &[
    "NaN",
    "Infinity",
    "1e999",
    "1e308",
    "-1e308",
    "0",
    "-0.0",
    "-1",
    "1.5",
    "18446744073709551615",
    "18446744073709551616",
    "\"12\"",
    "\"\"",
    "null",
    "true",
    "[]",
    "[0, 0]",
    "[0, 0, 0, 0]",
    "[1e308, 0, 50]",
    "[\"a\", 0, 50]",
    "[null, null, null]",
    "{}",
];

/// Where a hostile value goes in a line: a JSON pointer into the pair.
const TARGETS: &[&str] = &[
    "/id",
    "/source_m",
    "/source_m/0",
    "/source_m/2",
    "/destination_m",
    "/destination_m/1",
    "/destination_m/2",
    "/shortest_m",
    "/straight_m",
    "/bin_m",
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        let _ = judge(&bytes);
    }

    #[test]
    fn arbitrary_json_lines_never_panic(
        lines in proptest::collection::vec(
            prop_oneof![
                Just(String::new()),
                "[ -~]{0,60}",
                "\\{(\"[a-z_]{1,12}\": ?(-?[0-9]{1,4}(\\.[0-9]{1,3})?|\\[[0-9, .e-]{0,20}\\]|null|\"x\"),? ?){0,6}\\}",
            ],
            0..5,
        ),
    ) {
        let _ = judge(lines.join("\n").as_bytes());
    }

    #[test]
    fn mutated_valid_files_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..24),
    ) {
        let mut bytes = valid_lines().join("\n").into_bytes();
        for (at, x) in flips {
            let n = bytes.len();
            bytes[at % n] ^= x;
        }
        bytes.truncate(cut % (bytes.len() + 1));
        bytes.extend_from_slice(&tail);
        let _ = judge(&bytes);
    }

    #[test]
    fn hostile_values_name_the_line(
        line in 0usize..3,
        target in prop::sample::select(TARGETS),
        raw in prop::sample::select(HOSTILE),
        blank in 0usize..3,
    ) {
        let mut lines = valid_lines();
        let mut v: Value = serde_json::from_str(&lines[line]).expect("json");
        if target == "/bin_m" {
            v["bin_m"] = json!(0);
        }
        *v.pointer_mut(target).expect("pointer") = json!("@@HOSTILE@@");
        lines[line] = v.to_string().replace("\"@@HOSTILE@@\"", raw);
        // Blank lines before the bad one still count.
        for _ in 0..blank {
            lines.insert(0, String::new());
        }
        if let Err(e) = judge(lines.join("\n").as_bytes()) {
            let want = line + 1 + blank;
            // A changed id may collide with a later line's: that line is the duplicate.
            let duplicate = target == "/id" && e.to_string().contains("duplicate id");
            prop_assert!(
                matches!(e, PairsError::Line { line: l, .. } if l == want || duplicate && l > want),
                "{target} = {raw}: {e} (wanted line {want})"
            );
        }
    }

    #[test]
    fn missing_fields_name_the_line(
        line in 0usize..3,
        field in prop::sample::select(vec!["id", "source_m", "destination_m", "shortest_m", "straight_m"]),
        also_shortest in any::<bool>(),
    ) {
        // Dropping an optional field leaves a valid line (shortest_m is then planned); dropping
        // an endpoint is an error on that line.
        let mut lines = valid_lines();
        let mut v: Value = serde_json::from_str(&lines[line]).expect("json");
        let m = v.as_object_mut().expect("object");
        m.remove(field);
        if also_shortest {
            m.remove("shortest_m");
        }
        lines[line] = v.to_string();
        match judge(lines.join("\n").as_bytes()) {
            Ok(pairs) => {
                prop_assert!(["id", "shortest_m", "straight_m"].contains(&field), "without {field}");
                prop_assert_eq!(pairs.len(), 3);
            }
            Err(e) => {
                let msg = e.to_string();
                prop_assert!(
                    matches!(e, PairsError::Line { line: l, .. } if l == line + 1)
                        && (msg.contains(field) || msg.contains("duplicate id")),
                    "without {field}: {msg}"
                );
            }
        }
    }

    #[test]
    fn valid_files_with_blank_lines_load(
        order in Just(vec![0usize, 1, 2]).prop_shuffle(),
        blanks in proptest::collection::vec(prop::sample::select(vec!["", " ", "\t", "  \r"]), 0..4),
        crlf in any::<bool>(),
    ) {
        let lines = valid_lines();
        let mut out: Vec<String> = order.iter().map(|&i| lines[i].clone()).collect();
        for (k, b) in blanks.iter().enumerate() {
            out.insert(k % (out.len() + 1), b.to_string());
        }
        let sep = if crlf { "\r\n" } else { "\n" };
        let pairs = judge(out.join(sep).as_bytes()).unwrap_or_else(|e| panic!("{e}"));
        let ids: Vec<u64> = pairs.iter().map(|p| p.id).collect();
        let want: Vec<u64> = order.iter().map(|&i| valid_pairs()[i].id).collect();
        prop_assert_eq!(ids, want);
    }
}

#[test]
fn the_valid_file_loads() {
    let pairs = judge(valid_lines().join("\n").as_bytes()).expect("valid");
    assert_eq!(pairs.len(), 3);
    for (a, b) in pairs.iter().zip(valid_pairs()) {
        assert_eq!(a.id, b.id);
        assert!((a.shortest_m - b.shortest_m).abs() < 1e-9);
    }
}

#[test]
fn empty_and_blank_files_name_the_file() {
    for text in ["", "\n", "\n\n  \n"] {
        let e = judge(text.as_bytes()).expect_err("no pairs");
        assert!(matches!(e, PairsError::Empty { .. }), "{e}");
    }
}

#[test]
fn regression_json_error_does_not_name_line_1_of_a_later_line() {
    // serde_json locates errors "at line 1 column N" of the one line it parses: after the file's
    // `FILE:3:` that read as a contradiction.
    let mut lines = valid_lines();
    lines.insert(1, String::new());
    lines[2] = lines[2].replacen("\"shortest_m\":", "\"shortest_m\":\"12\",\"x\":", 1);
    let e = judge(lines.join("\n").as_bytes()).expect_err("a string for shortest_m");
    let msg = e.to_string();
    assert!(matches!(e, PairsError::Line { line: 3, .. }), "{msg}");
    assert!(msg.contains("(column ") && !msg.contains("line 1"), "{msg}");
}
