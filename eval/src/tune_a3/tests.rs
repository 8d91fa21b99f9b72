use super::*;
use dupac_common::config::A3Config;

fn result(o: f64, h: f64, t: f64, excellent: f64, ho: f64, pp: f64) -> SettingResult {
    let setting = A3Setting {
        offset_db: o,
        hysteresis_db: h,
        time_to_trigger_ms: t,
        l3_filter_k: None,
    };
    SettingResult {
        setting,
        reference: setting == A3Setting::of(&A3Config::default()),
        flights: 10,
        success_pct: 100.0,
        excellent_pct: excellent,
        handovers_per_km: ho,
        ping_pongs_per_km: pp,
        sinr_below_m6db_pct: 1.0,
    }
}

#[test]
fn the_default_grid_spans_ts_36_331s_useful_range_once_each() {
    let s = A3Grid::default().settings().expect("legal");
    assert_eq!(s.len(), 16 * 6 * 3);
    let margins: Vec<f64> = s.iter().map(A3Setting::margin_db).collect();
    for m in 0..=15 {
        assert!(margins.contains(&f64::from(m)), "margin {m} dB");
    }
    assert!(s.iter().any(|x| x.time_to_trigger_ms == 1280.0));
    for k in [0, 4, 8] {
        assert!(s.iter().any(|x| x.l3_filter_k == Some(k)), "k {k}");
    }
    let dup = A3Grid {
        offsets_db: vec![1.0, 1.0],
        hysteresis_db: vec![0.5],
        ttt_ms: vec![40.0],
        l3_filter_k: vec![None, None],
    };
    assert_eq!(dup.settings().expect("legal").len(), 1);
}

#[test]
fn values_ts_36_331_cannot_signal_are_refused_naming_them() {
    for (grid, says) in [
        (
            A3Grid {
                offsets_db: vec![0.3],
                ..A3Grid::default()
            },
            "a3-Offset 0.3",
        ),
        (
            A3Grid {
                offsets_db: vec![16.0],
                ..A3Grid::default()
            },
            "a3-Offset 16",
        ),
        (
            A3Grid {
                hysteresis_db: vec![-0.5],
                ..A3Grid::default()
            },
            "hysteresis -0.5",
        ),
        (
            A3Grid {
                ttt_ms: vec![50.0],
                ..A3Grid::default()
            },
            "timeToTrigger 50",
        ),
        (
            A3Grid {
                ttt_ms: vec![f64::NAN],
                ..A3Grid::default()
            },
            "timeToTrigger NaN",
        ),
        (
            A3Grid {
                ttt_ms: vec![],
                ..A3Grid::default()
            },
            "--ttt-ms: no values",
        ),
        (
            A3Grid {
                l3_filter_k: vec![Some(10)],
                ..A3Grid::default()
            },
            "--l3-filter-k: filterCoefficient k = 10",
        ),
        (
            A3Grid {
                offsets_db: vec![12.0, 16.0],
                ..A3Grid::default()
            },
            "--offset-db: a3-Offset 16",
        ),
    ] {
        let e = grid.settings().unwrap_err().to_string();
        assert!(e.contains(says), "{e}");
    }
    assert!(
        A3Setting {
            offset_db: -15.0,
            hysteresis_db: 15.0,
            time_to_trigger_ms: 5120.0,
            l3_filter_k: Some(19),
        }
        .check_legal()
        .is_ok()
    );
}

#[test]
fn the_choice_keeps_ping_pongs_at_most_the_reference_and_breaks_ties_by_handovers() {
    let rs = vec![
        // More excellent time, but more ping-pongs than the reference: not eligible.
        result(0.0, 0.0, 0.0, 95.0, 9.0, 2.0),
        // Eligible, the most excellent time, tied with the next one.
        result(2.0, 1.0, 80.0, 91.0, 5.0, 0.5),
        result(2.0, 0.5, 160.0, 91.0, 4.0, 0.4),
        result(3.0, 1.0, 160.0, 90.0, 3.0, 0.6),
        result(4.0, 2.0, 320.0, 80.0, 1.0, 0.0),
    ];
    let c = choose(&rs).expect("reference present");
    assert_eq!(
        (c.setting.hysteresis_db, c.setting.time_to_trigger_ms),
        (0.5, 160.0)
    );
    // Nothing better: the reference.
    let only = vec![result(3.0, 1.0, 160.0, 90.0, 3.0, 0.6)];
    assert!(choose(&only).expect("reference").reference);
    assert!(choose(&rs[..1]).is_err(), "no reference");
    let csv = grid_csv(&rs, c);
    assert_eq!(csv.lines().count(), 6);
    assert_eq!(
        csv.lines().filter(|l| l.ends_with(",1")).count(),
        1,
        "{csv}"
    );
    assert!(csv.contains("\n3,1,4,160,,10,"), "{csv}");
}

#[test]
fn the_tuned_file_reads_back_and_is_a_configuration_file() {
    let mut filtered = result(12.0, 0.0, 1280.0, 91.0, 4.0, 0.4);
    filtered.setting.l3_filter_k = Some(8);
    let rs = [
        result(3.0, 1.0, 160.0, 90.0, 3.0, 0.6),
        result(2.0, 0.5, 40.0, 91.0, 4.0, 0.4),
        filtered,
    ];
    let dir = tempfile::tempdir().expect("tmp");
    let f = dir.path().join("tuned_a3.toml");
    for chosen in &rs[1..] {
        let text = tuned_toml(chosen, &rs[0], Path::new("out/pairs/eval_pairs.jsonl"), 1.0);
        std::fs::write(&f, &text).expect("write");
        assert_eq!(read_tuned(&f).expect("reads back"), chosen.setting);
        // The same file as `--config`: the setting's keys, the rest defaults.
        let c = Config::from_toml_str(&text, "tuned_a3.toml", &[]).expect("a configuration");
        assert_eq!(A3Setting::of(&c.radio.a3), chosen.setting);
        // Its `--set` options say the same.
        let sets: Vec<String> = set_options(&chosen.setting)
            .split_whitespace()
            .filter(|w| *w != "--set")
            .map(str::to_string)
            .collect();
        let c = Config::from_toml_str("", "none", &sets).expect("the --set options");
        assert_eq!(A3Setting::of(&c.radio.a3), chosen.setting);
    }
    assert!(tuned_toml(&rs[2], &rs[0], Path::new("p"), 1.0).contains("\nl3_filter_k = 8\n"));
    // Bad files name the file and what is wrong.
    for (body, says) in [
        ("[radio.a3]\noffset_db = 2.0\n", "missing field"),
        (
            "[radio.a3]\noffset_db = 2.0\nhysteresis_db = 0.5\ntime_to_trigger_ms = 50.0\n",
            "timeToTrigger 50",
        ),
        (
            "[radio]\nfc_ghz = 2.0\n[radio.a3]\noffset_db = 2.0\nhysteresis_db = 0.5\ntime_to_trigger_ms = 40.0\n",
            "unknown field",
        ),
        ("not toml", "expected [radio.a3]"),
    ] {
        std::fs::write(&f, body).expect("write");
        let e = read_tuned(&f).unwrap_err().to_string();
        assert!(e.contains("tuned_a3.toml") && e.contains(says), "{e}");
    }
    let e = read_tuned(&dir.path().join("missing.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("missing.toml"), "{e}");
}
