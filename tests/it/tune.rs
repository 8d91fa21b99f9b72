//! `dupac tune-a3` on the small procedural world: the default grid of every setting (margins
//! 0–15 dB, TTT 0–1 280 ms, A3's filter k 0, 4, 8) and the reference, a chosen setting with no
//! more ping-pongs per km and no less excellent time than the reference (3 dB / 1 dB / 160 ms),
//! a byte-identical grid when run again, a value TS 36.331 cannot signal refused naming its flag
//! (`--ttt-ms`, `--offset-db`, `--l3-filter-k`), a 12 dB margin flown from the flags, and `dupac
//! eval --a3-tuned` flying the planners with the tuned A3 as extra rows.

use crate::support::{dupac_output, split_world_args as args};

fn cmd(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The CSV's rows as name → value maps.
fn rows(csv: &str) -> Vec<std::collections::BTreeMap<String, String>> {
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    lines
        .map(|l| {
            header
                .iter()
                .map(|h| h.to_string())
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

#[test]
fn tune_a3_writes_the_grid_and_a_setting_no_worse_than_the_reference() {
    let dir = tempfile::tempdir().expect("tmp");
    let a = args(dir.path());
    let out = dir.path().join("tune");
    let out_s = out.display().to_string();
    ok(&dupac_output(&a, &cmd(&["tune-a3", "-q", "--out", &out_s])));
    let csv = std::fs::read_to_string(out.join("a3_grid.csv")).expect("a3_grid.csv");
    let r = rows(&csv);
    // The default grid (16 offsets × 6 TTT × 3 filters) and the reference (3 / 1 / 160 ms).
    assert_eq!(r.len(), 16 * 6 * 3 + 1, "{csv}");
    let num = |row: &std::collections::BTreeMap<String, String>, k: &str| -> f64 {
        row[k].parse().expect("number")
    };
    for row in &r {
        assert_eq!(row["flights"], "8", "{csv}");
    }
    let reference: Vec<_> = r.iter().filter(|x| x["reference"] == "1").collect();
    let chosen: Vec<_> = r.iter().filter(|x| x["chosen"] == "1").collect();
    assert_eq!((reference.len(), chosen.len()), (1, 1), "{csv}");
    let (re, ch) = (reference[0], chosen[0]);
    assert_eq!(
        (
            re["offset_db"].as_str(),
            re["hysteresis_db"].as_str(),
            re["time_to_trigger_ms"].as_str()
        ),
        ("3", "1", "160")
    );
    assert!(num(ch, "ping_pongs_per_km") <= num(re, "ping_pongs_per_km") + 1e-6);
    assert!(num(ch, "excellent_pct") >= num(re, "excellent_pct") - 1e-6);
    // The tuned file holds the chosen setting (and is a configuration file: `dupac config`).
    let tuned = out.join("tuned_a3.toml");
    let cfg_out = dupac_output(
        &cmd(&["--config", tuned.to_str().expect("utf-8")]),
        &cmd(&["config"]),
    );
    ok(&cfg_out);
    let printed = String::from_utf8_lossy(&cfg_out.stdout);
    assert!(
        printed.contains(&format!("offset_db = {:?}", num(ch, "offset_db"))),
        "{printed}"
    );
    // Deterministic: the same inputs, the same bytes.
    let again = dir.path().join("again");
    ok(&dupac_output(
        &a,
        &cmd(&["tune-a3", "-q", "--out", &again.display().to_string()]),
    ));
    assert_eq!(
        std::fs::read(again.join("a3_grid.csv")).expect("again"),
        csv.as_bytes()
    );
    // Values TS 36.331 cannot signal: refused before any work, naming the flag and the value.
    for (flag, value, says) in [
        ("--ttt-ms", "50", "timeToTrigger 50"),
        ("--offset-db", "16", "a3-Offset 16"),
        ("--l3-filter-k", "10", "filterCoefficient k = 10"),
    ] {
        let bad = dupac_output(&a, &cmd(&["tune-a3", "-q", flag, value, "--out", &out_s]));
        let err = String::from_utf8_lossy(&bad.stderr);
        assert!(
            !bad.status.success() && err.contains(flag) && err.contains(says),
            "{err}"
        );
    }
    // A margin of 12 dB flies (with A3's own filter), and hands over less than none.
    let wide = dir.path().join("wide");
    ok(&dupac_output(
        &a,
        &cmd(&[
            "tune-a3",
            "-q",
            "--offset-db",
            "0,12",
            "--ttt-ms",
            "0",
            "--l3-filter-k",
            "4",
            "--out",
            &wide.display().to_string(),
        ]),
    ));
    let csv = std::fs::read_to_string(wide.join("a3_grid.csv")).expect("a3_grid.csv");
    let r = rows(&csv);
    let at = |margin: &str| {
        r.iter()
            .find(|x| x["margin_db"] == margin && x["l3_filter_k"] == "4")
            .unwrap_or_else(|| panic!("margin {margin}: {csv}"))
    };
    assert_eq!(at("12")["flights"], "8", "{csv}");
    assert!(
        num(at("12"), "handovers_per_km") < num(at("0"), "handovers_per_km"),
        "{csv}"
    );
    // eval --a3-tuned: the planners flown with the tuned A3 too.
    let ev = dir.path().join("eval");
    let ev_s = ev.display().to_string();
    let tuned_s = tuned.display().to_string();
    ok(&dupac_output(
        &a,
        &cmd(&[
            "eval",
            "-q",
            "--lambda",
            "1",
            "--a3-tuned",
            &tuned_s,
            "--out",
            &ev_s,
        ]),
    ));
    let summary = std::fs::read_to_string(ev.join("summary.csv")).expect("summary.csv");
    let methods: Vec<&str> = summary
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap_or(""))
        .collect();
    assert_eq!(
        methods,
        [
            "coverage_l1",
            "coverage_l1+a3tuned",
            "coverage_l1+oracle",
            "shortest_a3",
            "shortest_a3tuned",
            "shortest_oracle",
            "shortest_predictive"
        ],
        "{summary}"
    );
    let refused = dupac_output(
        &a,
        &cmd(&[
            "eval",
            "-q",
            "--no-planners",
            "--a3-tuned",
            &tuned_s,
            "--out",
            &ev_s,
        ]),
    );
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && err.contains("--a3-tuned"),
        "{err}"
    );
}
