//! Property tests of the configuration parser ("bad input, fuzzed"): arbitrary TOML text,
//! the default configuration with bytes flipped, cut or extended, every value replaced by a
//! hostile one (NaN, ±inf, huge, negative, zero, wrong type), and arbitrary `--set KEY=VALUE`
//! arguments. [`Config::from_toml_str`] must never panic, every error must name the file (or the
//! `--set` argument) and, where the input has one, the key; valid input must still load.

use dupac_common::config::{Config, ConfigError};
use proptest::prelude::*;

const ORIGIN: &str = "fuzz-origin.toml";

fn valid_text() -> String {
    Config::default().to_toml_string()
}

/// Every leaf of the default configuration: its dotted key and its TOML value.
fn leaves() -> Vec<(String, toml::Value)> {
    fn walk(prefix: &str, t: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
        for (k, v) in t {
            let key = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            match v {
                toml::Value::Table(sub) => walk(&key, sub, out),
                other => out.push((key, other.clone())),
            }
        }
    }
    let table: toml::Table = toml::from_str(&valid_text()).expect("default config is TOML");
    let mut out = Vec::new();
    walk("", &table, &mut out);
    assert!(out.len() > 50, "found only {} leaves", out.len());
    out
}

/// Values that no key of the configuration should take without a clear error (or that some keys
/// accept: the property only asks for no panic and a named error).
const HOSTILE: &[&str] = &[
    "nan",
    "+nan",
    "-nan",
    "inf",
    "-inf",
    "-1",
    "-1.5",
    "0",
    "0.0",
    "-0.0",
    "1e308",
    "-1e308",
    "9223372036854775807",
    "-9223372036854775808",
    "4294967296",
    "65536",
    "\"text\"",
    "\"\"",
    "true",
    "[]",
    "[nan]",
    "[-1, 0, 1e308]",
    "[\"a\"]",
    "{}",
    "{ x = 1 }",
    "1979-05-27T07:32:00Z",
];

/// The error must not be empty and must name where the input came from: the origin for file
/// errors, the argument for `--set` errors.
fn check_error(e: &ConfigError, sets: &[String]) {
    let msg = e.to_string();
    assert!(!msg.trim().is_empty());
    match e {
        ConfigError::Override { arg, .. } => {
            assert!(sets.iter().any(|s| s == arg), "{msg}");
            assert!(msg.contains(&format!("{arg:?}")), "{msg}");
        }
        ConfigError::InvalidIn { origin, key, .. } => {
            assert!(!key.is_empty(), "{msg}");
            assert!(msg.contains(key.as_str()), "{msg}");
            assert!(origin.contains(ORIGIN), "{msg}");
            assert!(
                msg.contains(ORIGIN),
                "validation error without the origin: {msg}"
            );
        }
        _ => assert!(msg.contains(ORIGIN), "error without the origin: {msg}"),
    }
}

fn judge(text: &str, sets: &[String]) -> Result<Config, ConfigError> {
    let r = Config::from_toml_str(text, ORIGIN, sets);
    if let Err(e) = &r {
        check_error(e, sets);
    }
    r
}

fn toml_ish() -> impl Strategy<Value = String> {
    // Mostly TOML punctuation and key characters, so that the parser gets past the first byte.
    proptest::string::string_regex(
        r#"([\[\]{}=., \n"'#a-z_0-9+\-]|nan|inf|true|radio|env|ppo|max_step_m|\u{0}|\u{FEFF}|é){0,200}"#,
    )
    .expect("regex")
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn arbitrary_text_never_panics(text in any::<String>()) {
        let _ = judge(&text, &[]);
    }

    #[test]
    fn toml_like_text_never_panics(text in toml_ish()) {
        let _ = judge(&text, &[]);
    }

    #[test]
    fn mutated_valid_toml_never_panics(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..8),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..32),
    ) {
        let mut bytes = valid_text().into_bytes();
        for (at, x) in flips {
            let n = bytes.len();
            bytes[at % n] ^= x;
        }
        bytes.truncate(cut % (bytes.len() + 1));
        bytes.extend_from_slice(&tail);
        let _ = judge(&String::from_utf8_lossy(&bytes), &[]);
    }

    #[test]
    fn hostile_values_in_the_file_name_the_key(
        which in any::<prop::sample::Index>(),
        value in prop::sample::select(HOSTILE),
    ) {
        let leaves = leaves();
        let (key, _) = &leaves[which.index(leaves.len())];
        let (section, leaf) = key.rsplit_once('.').expect("every key is in a section");
        let text = format!("[{section}]\n{leaf} = {value}\n");
        if let Err(e) = judge(&text, &[]) {
            let msg = e.to_string();
            prop_assert!(msg.contains(leaf), "{text}: {msg}");
        }
    }

    #[test]
    fn hostile_values_by_set_name_the_key(
        which in any::<prop::sample::Index>(),
        value in prop::sample::select(HOSTILE),
    ) {
        let leaves = leaves();
        let (key, _) = &leaves[which.index(leaves.len())];
        let sets = vec![format!("{key}={value}")];
        if let Err(e) = judge("", &sets) {
            let msg = e.to_string();
            let leaf = key.rsplit('.').next().expect("leaf");
            prop_assert!(msg.contains(leaf), "{sets:?}: {msg}");
        }
    }

    #[test]
    fn arbitrary_set_arguments_never_panic(
        sets in proptest::collection::vec(
            prop_oneof![
                any::<String>(),
                "[a-z_.=\\[\\]{}\" 0-9\\-]{0,40}",
                (prop::sample::select(vec!["radio", "env", "ppo", "radio.fc_ghz", "env.max_step_m",
                    "scenario.area", "ppo.hidden", "train", "x.y.z", "radio.a3.l3_filter_k", ".",
                    "a..b", "", " "]),
                 prop::sample::select(HOSTILE))
                    .prop_map(|(k, v)| format!("{k}={v}")),
            ],
            0..4,
        ),
        text in prop_oneof![Just(String::new()), Just(valid_text()), toml_ish()],
    ) {
        let _ = judge(&text, &sets);
    }

    #[test]
    fn restating_the_defaults_by_set_still_loads(which in any::<prop::sample::Index>()) {
        let leaves = leaves();
        let (key, value) = &leaves[which.index(leaves.len())];
        let sets = vec![format!("{key}={value}")];
        let c = Config::from_toml_str("", ORIGIN, &sets)
            .unwrap_or_else(|e| panic!("{sets:?}: {e}"));
        prop_assert_eq!(c, Config::default());
    }
}

#[test]
fn the_default_configuration_round_trips() {
    let c = Config::from_toml_str(&valid_text(), ORIGIN, &[]).expect("valid");
    assert_eq!(c, Config::default());
    let c = Config::from_toml_str("", ORIGIN, &[]).expect("valid");
    assert_eq!(c, Config::default());
}

#[test]
fn an_unknown_key_in_the_file_is_rejected_naming_it_and_its_line() {
    let text = "[env]\nmax_step_m = 5.0\nmax_stepp_m = 5.0\n";
    let msg = Config::from_toml_str(text, ORIGIN, &[])
        .unwrap_err()
        .to_string();
    assert!(msg.contains(ORIGIN), "{msg}");
    assert!(msg.contains("max_stepp_m"), "{msg}");
    assert!(msg.contains("line 3"), "{msg}");
    let msg = Config::from_toml_str("[enviroment]\nx = 1\n", ORIGIN, &[])
        .unwrap_err()
        .to_string();
    assert!(msg.contains("enviroment") && msg.contains(ORIGIN), "{msg}");
}

/// The keys tried and dropped (docs/training.md "Tried and dropped") are unknown keys: a file or
/// a `--set` that names one is refused naming it, never read with its value ignored.
#[test]
fn dropped_keys_are_refused_as_unknown() {
    for (section, leaf, value) in [
        ("env.reward", "guide_deviation_weight", "0.0"),
        ("env.reward", "guide_deviation_free_m", "2.0"),
        ("env", "handover_margin_db", "0.0"),
        ("env", "min_time_of_stay_s", "0.0"),
        ("env.observation", "site_trend", "false"),
        ("ppo", "site_horizon", "\"decision\""),
        ("ppo", "site_step_rows", "1"),
    ] {
        let text = format!("[{section}]\n{leaf} = {value}\n");
        let msg = Config::from_toml_str(&text, ORIGIN, &[])
            .unwrap_err()
            .to_string();
        assert!(
            msg.contains(ORIGIN) && msg.contains(leaf) && msg.contains("unknown"),
            "{section}.{leaf}: {msg}"
        );
        let arg = format!("{section}.{leaf}={value}");
        let msg = Config::from_toml_str("", ORIGIN, std::slice::from_ref(&arg))
            .unwrap_err()
            .to_string();
        assert!(msg.contains(leaf) && msg.contains("unknown"), "{msg}");
        // Nor written by the default configuration.
        assert!(
            !valid_text().contains(leaf),
            "{leaf} in the default configuration"
        );
    }
}

#[test]
fn an_unknown_key_by_set_is_rejected_naming_it() {
    for arg in [
        "env.max_stepp_m=5",
        "enviroment.max_step_m=5",
        "radio.a3.x=1",
    ] {
        let e = Config::from_toml_str("", ORIGIN, &[arg.to_string()]).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains(arg), "{msg}");
        let leaf_or_section = arg
            .split(['.', '='])
            .find(|p| !["env", "radio", "a3", "max_step_m"].contains(p));
        assert!(
            msg.contains(leaf_or_section.expect("unknown part")),
            "{msg}"
        );
    }
    // The file is fine, the override is not: the error blames the override.
    let e = Config::from_toml_str(
        "[env]\nmax_step_m = 5.0\n",
        ORIGIN,
        &[
            "radio.fc_ghz=3.5".to_string(),
            "env.max_stepp_m=5".to_string(),
        ],
    )
    .unwrap_err();
    assert!(
        matches!(&e, ConfigError::Override { arg, .. } if arg == "env.max_stepp_m=5"),
        "{e}"
    );
}

#[test]
fn out_of_range_values_are_rejected_naming_the_key() {
    let cases = [
        ("env", "max_step_m", "-1.0"),
        ("env", "max_step_m", "0.0"),
        ("env", "max_step_m", "nan"),
        ("env", "speed_mps", "inf"),
        ("ppo", "num_minibatches", "0"),
        ("ppo", "update_epochs", "0"),
        ("ppo", "gamma", "1.5"),
        ("radio", "fc_ghz", "-2.0"),
        ("train", "num_envs", "0"),
        ("train", "num_envs", "5000"),
        ("pairs", "bin_tolerance", "0.5"),
        ("distributed", "max_message_mib", "1e308"),
        ("env.reward", "ping_pong_reward", "1.0"),
        ("env.reward", "ping_pong_reward", "-1e9"),
    ];
    for (section, leaf, value) in cases {
        let key = format!("{section}.{leaf}");
        let text = format!("[{section}]\n{leaf} = {value}\n");
        let e = Config::from_toml_str(&text, ORIGIN, &[]).unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(&e, ConfigError::InvalidIn { key: k, .. } if *k == key),
            "{key} = {value}: {msg}"
        );
        assert!(msg.contains(&key) && msg.contains(ORIGIN), "{msg}");
        // The same value by --set: still named.
        let e = Config::from_toml_str("", ORIGIN, &[format!("{key}={value}")]).unwrap_err();
        assert!(e.to_string().contains(&key), "{e}");
    }
    // A site feature without the site features.
    let e = Config::from_toml_str(
        "[env.observation]\nsite_features = false\nsite_ping_pong = true\n[ppo]\nsite_head = \"slots\"\n",
        ORIGIN,
        &[],
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("env.observation.site_ping_pong"),
        "{e}"
    );
    // A ping-pong cost the learned site cannot see: the feature it needs is named.
    let pp = "env.reward.ping_pong_reward=-4".to_string();
    let off = "env.observation.site_ping_pong=false".to_string();
    let e = Config::from_toml_str("", ORIGIN, &[pp.clone(), off])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("env.reward.ping_pong_reward") && e.contains("env.observation.site_ping_pong"),
        "{e}"
    );
    let with_feature = [pp.clone(), "env.observation.site_ping_pong=true".into()];
    assert!(Config::from_toml_str("", ORIGIN, &with_feature).is_ok());
    // The base method's A3 ping-pongs are charged without a feature (nothing learns the site).
    let a3 = [
        pp,
        "env.observation.site_ping_pong=false".into(),
        "env.association=\"a3\"".into(),
    ];
    assert!(Config::from_toml_str("", ORIGIN, &a3).is_ok());
    // A site chosen every step with what it cannot run with: each requirement named.
    for (set, needs) in [
        ("ppo.site_head=\"slots\"", "ppo.site_head = \"equivariant\""),
        (
            "ppo.site_gradient=\"sampled\"",
            "ppo.site_gradient = \"all_sites\"",
        ),
    ] {
        let sets = [
            "env.site_every_step=true".to_string(),
            "env.reward.ping_pong_reward=0".to_string(),
            set.to_string(),
        ];
        let e = Config::from_toml_str("", ORIGIN, &sets)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("env.site_every_step") && e.contains(needs),
            "{e}"
        );
    }
    assert!(Config::from_toml_str("", ORIGIN, &["env.site_every_step=true".into()]).is_ok());
    // Negative where an unsigned integer is expected: a type error at the line of the key.
    let msg = Config::from_toml_str("[ppo]\nnum_minibatches = -4\n", ORIGIN, &[])
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains(ORIGIN) && msg.contains("num_minibatches") && msg.contains("line 2"),
        "{msg}"
    );
}

#[test]
fn regression_huge_num_steps_does_not_overflow_the_batch_size() {
    // train.num_envs × train.num_steps overflowed usize (a panic in debug builds, a wrapped
    // product that could pass the minibatch check in release).
    let text = "[train]\nnum_envs = 4096\nnum_steps = 9223372036854775807\n";
    let e = Config::from_toml_str(text, ORIGIN, &[]).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains("train.num_steps") && msg.contains(ORIGIN),
        "{msg}"
    );
}

#[test]
fn regression_set_of_one_area_bound_loads() {
    // `scenario.area` had no serde default per bound: restating one bound by --set (or writing
    // one bound in a file) failed with "missing field `lon_min_deg`".
    let c = Config::from_toml_str("", ORIGIN, &["scenario.area.lat_max_deg=40.76".to_string()])
        .expect("one bound");
    assert_eq!(c.scenario.area.lat_max_deg, 40.76);
    assert_eq!(
        c.scenario.area.lon_min_deg,
        Config::default().scenario.area.lon_min_deg
    );
    let c = Config::from_toml_str("[scenario.area]\nlon_min_deg = -73.99\n", ORIGIN, &[])
        .expect("one bound in a file");
    assert_eq!(c.scenario.area.lon_min_deg, -73.99);
}

#[test]
fn regression_validation_errors_name_the_file_or_the_override() {
    // Range errors named the key but neither the file nor the --set argument.
    let e = Config::from_toml_str("[env]\nmax_step_m = -1.0\n", ORIGIN, &[]).unwrap_err();
    let msg = e.to_string();
    assert!(
        msg.contains(ORIGIN) && msg.contains("env.max_step_m"),
        "{msg}"
    );
    let e = Config::from_toml_str(
        "",
        ORIGIN,
        &[
            "radio.fc_ghz=3.5".to_string(),
            "env.max_step_m=-1".to_string(),
        ],
    )
    .unwrap_err();
    assert!(
        matches!(&e, ConfigError::Override { arg, .. } if arg == "env.max_step_m=-1"),
        "{e}"
    );
    assert!(e.to_string().contains("env.max_step_m"), "{e}");
}

#[test]
fn regression_unknown_key_by_set_names_the_override() {
    // The deserialisation error after --set overrides said "config file X (with --set
    // overrides): unknown field `max_stepp_m`" without saying which override.
    let e = Config::from_toml_str("", ORIGIN, &["env.max_stepp_m=5".to_string()]).unwrap_err();
    assert!(
        matches!(&e, ConfigError::Override { arg, message } if arg == "env.max_stepp_m=5"
            && message.contains("max_stepp_m")),
        "{e}"
    );
}

/// Values that pass validation and then panic or abort later.
#[test]
fn regression_values_that_sized_memory_or_time_without_bound_are_refused() {
    for (set, key) in [
        (
            "distributed.silent_after_s=1e300",
            "distributed.silent_after_s",
        ),
        (
            "distributed.resend_after_s=1e300",
            "distributed.resend_after_s",
        ),
        ("train.pool_size=1000000000000", "train.pool_size"),
        ("ppo.hidden=[65536, 65536]", "ppo.hidden"),
        ("ppo.hidden=[4096, 4096, 4096, 4096, 4096]", "ppo.hidden"),
        ("radio.fc_ghz=1e-300", "radio.fc_ghz"),
        ("cache.horizontal_m=1e-300", "cache.horizontal_m"),
        ("train.eval_pairs=100000000", "train.eval_pairs"),
        (
            "distributed.queue_chunks=100000000",
            "distributed.queue_chunks",
        ),
    ] {
        let e = Config::load(None, &[set.to_string()]).expect_err(set);
        assert!(e.to_string().contains(key), "{set}: {e}");
    }
}

#[test]
fn a_config_file_over_the_size_limit_is_refused_unread() {
    let dir = std::env::temp_dir().join(format!("dupac-cfg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("dir");
    let p = dir.join("huge.toml");
    let big = format!(
        "# {}\n",
        "x".repeat(dupac_common::config::MAX_CONFIG_BYTES as usize)
    );
    std::fs::write(&p, big).expect("write");
    let e = Config::load(Some(&p), &[]).expect_err("too big");
    assert!(
        e.to_string().contains("huge.toml") && e.to_string().contains("at most"),
        "{e}"
    );
    std::fs::write(&p, b"[train]\nseed = 1\n# \xff\n").expect("write");
    let e = Config::load(Some(&p), &[]).expect_err("not utf-8");
    assert!(e.to_string().contains("not UTF-8"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    /// Any configuration that validates (hostile values on one or two keys) gives durations,
    /// message limits and batch sizes that convert without a panic.
    #[test]
    fn what_a_valid_configuration_sizes_never_panics(
        picks in prop::collection::vec((any::<prop::sample::Index>(), prop::sample::select(HOSTILE)), 1..3),
    ) {
        let leaves = leaves();
        let sets: Vec<String> = picks
            .iter()
            .map(|(i, v)| format!("{}={v}", leaves[i.index(leaves.len())].0))
            .collect();
        if let Ok(c) = Config::load(None, &sets) {
            let d = &c.distributed;
            for s in [d.silent_after_s, d.resend_after_s, d.stats_every_s] {
                prop_assert!(std::time::Duration::try_from_secs_f64(s).is_ok(), "{sets:?}");
            }
            let run_max = dupac_common::msg::MsgLimits::run_max_bytes(&c, 404, 30);
            prop_assert!(run_max > 0 && run_max <= d.max_message_bytes().max(4 << 20));
            prop_assert!(c.train.num_envs.checked_mul(c.train.num_steps).is_some());
        }
    }
}
