//! `dupac fly` and `dupac eval` end to end with a policy trained once per test binary on the
//! small procedural run ([`trained_run`]): the methods an evaluation flies and replays, its
//! tables and figures, `failures.csv`, the seed-aware tables (`per_seed.csv`, `paired.csv`, the
//! bootstrap columns), refused `--hindsight` and `--bootstrap` values, and a report that is a
//! function of the saved records alone.

use crate::support::{TrainedRun, dupac_output, summary_column, trained_run};
use std::path::{Path, PathBuf};

/// The tables `dupac eval` writes from its records.
const TABLES: [&str; 7] = [
    "report.md",
    "summary.csv",
    "per_seed.csv",
    "paired.csv",
    "fig3_fig4_bins.csv",
    "pareto.csv",
    "failures.csv",
];

/// One evaluation per test binary: the trained policy twice (two "seeds": the same file) and the
/// planners over the held-out pairs, with the hindsight association at no cost and at a cost of
/// 1 000 with the minimum stay.
fn evaluated() -> &'static Path {
    static EVAL: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    EVAL.get_or_init(|| {
        let run = trained_run();
        let ev = run.dir.join("eval");
        let policy = format!("dupac={}", run.policy().display());
        let e = dupac_output(
            &run.args,
            &[
                "eval".into(),
                "-q".into(),
                "--policy".into(),
                policy.clone(),
                "--policy".into(),
                policy,
                "--lambda".into(),
                "1".into(),
                "--hindsight".into(),
                "0".into(),
                "--hindsight".into(),
                "1000:mts".into(),
                "--out".into(),
                ev.display().to_string(),
            ],
        );
        assert!(e.status.success(), "{}", String::from_utf8_lossy(&e.stderr));
        ev
    })
}

#[test]
fn fly_flies_a_held_out_pair_beside_the_shortest_path() {
    let run: &TrainedRun = trained_run();
    let dir = tempfile::tempdir().expect("tmp");
    let fly_out = dir.path().join("fly");
    let fly = dupac_output(
        &run.args,
        &[
            "fly".into(),
            "-q".into(),
            "--policy".into(),
            run.policy().display().to_string(),
            "--pair".into(),
            "1".into(),
            "--out".into(),
            fly_out.display().to_string(),
        ],
    );
    assert!(
        fly.status.success(),
        "{}",
        String::from_utf8_lossy(&fly.stderr)
    );
    for f in ["fly.png", "steps.csv", "summary.md"] {
        assert!(fly_out.join(f).exists(), "{f} missing");
    }
    assert!(String::from_utf8_lossy(&fly.stdout).contains("shortest path (A3)"));
}

/// Every method, the replays of the learned-site policy's moves (route against
/// association), the hindsight references, the tables, the figures and `failures.csv`.
#[test]
fn eval_flies_every_method_and_replays_the_association() {
    let ev = evaluated();
    let summary = std::fs::read_to_string(ev.join("summary.csv")).expect("summary.csv");
    let methods: Vec<&str> = summary
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap_or(""))
        .collect();
    assert_eq!(
        methods,
        [
            "dupac",
            "dupac+a3",
            "dupac+hindsight_0",
            "dupac+hindsight_1000_mts",
            "dupac+oracle",
            "dupac+predictive",
            "coverage_l1",
            "coverage_l1+oracle",
            "shortest_a3",
            "shortest_oracle",
            "shortest_predictive"
        ],
        "{summary}"
    );
    let col = |label: &str, name: &str| summary_column(&summary, label, name);
    assert_eq!(col("dupac+oracle", "site_regret_db"), 0.0, "{summary}");
    // The hindsight association: at no handover cost the best site every step (the oracle's
    // regret, to the replay's f32 positions); with the minimum stay, no ping-pong and no more
    // handovers than the oracle.
    assert!(
        col("dupac+hindsight_0", "site_regret_db") < 1e-3,
        "{summary}"
    );
    assert_eq!(
        col("dupac+hindsight_1000_mts", "ping_pongs_per_km"),
        0.0,
        "{summary}"
    );
    assert!(
        col("dupac+hindsight_1000_mts", "handovers_per_km")
            <= col("dupac+oracle", "handovers_per_km"),
        "{summary}"
    );
    assert_eq!(col("dupac+oracle", "pct_class_regret"), 0.0, "{summary}");
    // A replay flies the policy's moves and ends as its flights ended: a collision stays one.
    for replay in ["dupac+a3", "dupac+oracle", "dupac+predictive"] {
        for outcome in ["success", "collision", "timeout"] {
            assert_eq!(col(replay, outcome), col("dupac", outcome), "{summary}");
        }
    }
    let dupac_row: Vec<&str> = summary.lines().nth(1).expect("row").split(',').collect();
    assert_eq!(
        &dupac_row[1..3],
        &["2", "16"],
        "2 seeds × 8 held-out pairs: {summary}"
    );
    let shortest_row = summary
        .lines()
        .find(|l| l.starts_with("shortest_a3,"))
        .expect("row");
    assert!(
        shortest_row.split(',').nth(3) == Some("1"),
        "the planned shortest path always arrives: {shortest_row}"
    );
    for f in [
        "report.md",
        "fig3.png",
        "fig4.png",
        "pareto.png",
        "fig3_fig4_bins.csv",
        "pareto.csv",
    ] {
        assert!(ev.join(f).exists(), "{f} missing");
    }
    // failures.csv: one row per flight that missed its goal, none for the planned shortest path.
    let failures = std::fs::read_to_string(ev.join("failures.csv")).expect("failures.csv");
    let success: f64 = dupac_row[3].parse().expect("success rate");
    let failed = failures
        .lines()
        .skip(1)
        .filter(|l| l.starts_with("dupac,"))
        .count();
    assert_eq!(
        failed,
        ((1.0 - success) * 16.0).round() as usize,
        "{failures}"
    );
    assert!(!failures.lines().any(|l| l.starts_with("shortest_a3,")));
}

/// The seed-aware tables: the bootstrap interval around each rate, a row per seed (the two
/// "seeds" are one policy file, so their rows agree), and `dupac` against each planner flight
/// by flight.
#[test]
fn eval_writes_per_seed_rows_and_paired_differences() {
    let ev = evaluated();
    let summary = std::fs::read_to_string(ev.join("summary.csv")).expect("summary.csv");
    for label in ["dupac", "shortest_a3"] {
        let col = |name: &str| summary_column(&summary, label, name);
        assert!(
            col("success_boot_lo") <= col("success") && col("success") <= col("success_boot_hi"),
            "{summary}"
        );
    }
    let per_seed = std::fs::read_to_string(ev.join("per_seed.csv")).expect("per_seed.csv");
    assert!(
        per_seed.starts_with("method,seed,flights,success,"),
        "{per_seed}"
    );
    let dupac: Vec<Vec<&str>> = per_seed
        .lines()
        .filter(|l| l.starts_with("dupac,"))
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(dupac.len(), 2, "{per_seed}");
    assert_eq!((dupac[0][1], dupac[1][1], dupac[0][2]), ("0", "1", "8"));
    assert_eq!(dupac[0][2..], dupac[1][2..], "{per_seed}");
    let paired = std::fs::read_to_string(ev.join("paired.csv")).expect("paired.csv");
    let mut lines = paired.lines();
    assert_eq!(
        lines.next(),
        Some("method_a,method_b,metric,n,mean_diff,lo,hi,excludes_zero")
    );
    let against: Vec<&str> = lines
        .filter(|l| l.contains(",success,"))
        .map(|l| l.split(',').nth(1).unwrap_or(""))
        .collect();
    assert_eq!(
        against,
        [
            "coverage_l1",
            "coverage_l1+oracle",
            "shortest_a3",
            "shortest_oracle",
            "shortest_predictive"
        ],
        "{paired}"
    );
    // 2 seed indices × 8 pairs, every flight matched with the planner's.
    assert!(paired.contains("dupac,shortest_a3,success,16,"), "{paired}");
}

/// `--report-only` in a fresh directory holding nothing but a copy of the records writes the same
/// tables as the evaluation that flew them.
#[test]
fn eval_report_is_a_function_of_the_saved_records() {
    let run = trained_run();
    let ev = evaluated();
    let dir = tempfile::tempdir().expect("tmp");
    let again = dir.path().join("eval");
    std::fs::create_dir_all(again.join("records")).expect("mkdir");
    for e in std::fs::read_dir(ev.join("records")).expect("records") {
        let e = e.expect("entry");
        std::fs::copy(e.path(), again.join("records").join(e.file_name())).expect("copy");
    }
    let out = dupac_output(
        &run.args,
        &[
            "eval".into(),
            "-q".into(),
            "--report-only".into(),
            "--out".into(),
            again.display().to_string(),
        ],
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in TABLES {
        assert_eq!(
            std::fs::read_to_string(ev.join(f)).expect("read"),
            std::fs::read_to_string(again.join(f)).expect("regenerated"),
            "{f}: the report is a function of the saved records"
        );
    }
    assert!(again.join("fig3.png").exists());
}

/// A bad `--hindsight` value is refused before anything is flown, naming it.
#[test]
fn eval_refuses_a_bad_hindsight_value_before_flying() {
    let run = trained_run();
    let dir = tempfile::tempdir().expect("tmp");
    for (bad, says) in [
        ("abc", "--hindsight abc"),
        ("3:later", "--hindsight 3:later"),
        ("-1", "--hindsight -1"),
    ] {
        let e = dupac_output(
            &run.args,
            &[
                "eval".into(),
                "-q".into(),
                "--policy".into(),
                format!("dupac={}", run.policy().display()),
                format!("--hindsight={bad}"),
                "--out".into(),
                dir.path().join("eval_bad").display().to_string(),
            ],
        );
        let err = String::from_utf8_lossy(&e.stderr);
        assert!(!e.status.success() && err.contains(says), "{err}");
    }
    assert!(!dir.path().join("eval_bad").join("records").exists());
}

/// The fronts' and the predictive association's options are refused before flying, each naming
/// its flag: an A3 value TS 36.331 cannot signal, grid flags without `--a3-front`, a negative
/// cost, a learned-site policy flown "with the predictive association", an unknown label.
#[test]
fn eval_refuses_bad_front_and_predictive_options_before_flying() {
    let run = trained_run();
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("eval_bad");
    for (bad, says) in [
        (
            &["--a3-front", "--offset-db", "16"][..],
            "--offset-db: a3-Offset 16",
        ),
        (
            &["--a3-front", "--l3-filter-k", "10"],
            "--l3-filter-k: filterCoefficient k = 10",
        ),
        (&["--a3-front", "--l3-filter-k", "fast"], "--l3-filter-k"),
        (&["--ttt-ms", "320"], "give --a3-front"),
        (&["--hindsight-front=-1"], "--hindsight-front -1"),
        (&["--predictive-front", "60,-5"], "--predictive-front -5"),
        (&["--predictive-label", "dupac"], "--predictive-label dupac"),
        (
            &["--predictive-label", "nobody"],
            "--predictive-label nobody",
        ),
    ] {
        let mut command: Vec<String> = [
            "eval".to_string(),
            "-q".into(),
            "--policy".into(),
            format!("dupac={}", run.policy().display()),
            "--out".into(),
            out.display().to_string(),
        ]
        .into();
        command.extend(bad.iter().map(|s| s.to_string()));
        let e = dupac_output(&run.args, &command);
        let err = String::from_utf8_lossy(&e.stderr);
        assert!(!e.status.success() && err.contains(says), "{bad:?}: {err}");
    }
    assert!(!out.join("records").exists());
}

/// `--bootstrap 0` is refused before anything is flown, naming the option.
#[test]
fn eval_refuses_a_bootstrap_without_resamples_before_flying() {
    let run = trained_run();
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("eval_bad");
    let e = dupac_output(
        &run.args,
        &[
            "eval".into(),
            "-q".into(),
            "--bootstrap".into(),
            "0".into(),
            "--policy".into(),
            format!("dupac={}", run.policy().display()),
            "--out".into(),
            out.display().to_string(),
        ],
    );
    let err = String::from_utf8_lossy(&e.stderr);
    assert!(
        !e.status.success() && err.contains("--bootstrap 0"),
        "{err}"
    );
    assert!(!out.join("records").exists());
}

/// Without `--pairs` and without the held-out file, `fly` and `eval` draw the held-out pairs
/// (`pairs.eval_seed`) and write them to `pairs.eval_file`, the same pairs `dupac pairs` writes;
/// a `--pair` past the set's size is refused before anything is built.
#[test]
fn fly_and_eval_draw_a_missing_held_out_set() {
    let run = trained_run();
    let dir = tempfile::tempdir().expect("tmp");
    let file = |name: &str| dir.path().join(name);
    let with_file = |name: &str| {
        let mut a = run.args.clone();
        a.push("--set".into());
        a.push(format!("pairs.eval_file=\"{}\"", file(name).display()));
        a
    };
    let policy = run.policy().display().to_string();
    let ok = |o: std::process::Output| {
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    ok(dupac_output(
        &with_file("drawn_by_fly.jsonl"),
        &[
            "fly".into(),
            "-q".into(),
            "--policy".into(),
            policy.clone(),
            "--pair".into(),
            "7".into(),
            "--out".into(),
            file("fly").display().to_string(),
        ],
    ));
    ok(dupac_output(
        &with_file("drawn_by_eval.jsonl"),
        &[
            "eval".into(),
            "-q".into(),
            "--no-planners".into(),
            "--no-replay".into(),
            "--policy".into(),
            format!("dupac={policy}"),
            "--out".into(),
            file("eval").display().to_string(),
        ],
    ));
    ok(dupac_output(
        &with_file("unused.jsonl"),
        &[
            "pairs".into(),
            "-q".into(),
            "--split".into(),
            "validation".into(),
            "--out".into(),
            file("by_pairs.jsonl").display().to_string(),
        ],
    ));
    let by_pairs = std::fs::read_to_string(file("by_pairs.jsonl")).expect("dupac pairs");
    for drawn in ["drawn_by_fly.jsonl", "drawn_by_eval.jsonl"] {
        assert_eq!(
            std::fs::read_to_string(file(drawn)).expect(drawn),
            by_pairs,
            "{drawn}"
        );
    }
    let past = dupac_output(
        &with_file("never.jsonl"),
        &[
            "fly".into(),
            "-q".into(),
            "--policy".into(),
            policy,
            "--pair".into(),
            "8".into(),
        ],
    );
    let err = String::from_utf8_lossy(&past.stderr);
    assert!(
        !past.status.success() && err.contains("has 8 pairs"),
        "{err}"
    );
    assert!(!file("never.jsonl").exists());
}

/// Under the real channel a flight starts from the site the UAV measured strongest at the
/// source, for the metrics as for the environment: every recorded flight's handovers, recounted
/// from its start site, are the environment's per-step flags (a start site taken from the true
/// RSRP instead adds a phantom handover where the two differ). With `--a3-front` on a grid from
/// the flags (margins 0 and 12 dB, TTT 0 and 320 ms, without and with A3's filter k = 4): A3's
/// front on the policy's moves and on each planner's A3 path, 8 settings each, the 12 dB margin
/// flown with fewer handovers than 0 dB; the hindsight and the predictive association's fronts
/// on the policy's moves at two costs each (`front.csv`, `fronts.png`).
#[test]
fn eval_under_the_real_channel_counts_from_the_measured_start_and_flies_the_fronts() {
    let run = trained_run();
    let ev = run.dir.join("eval_real");
    let mut scenario = run.args.clone();
    scenario.extend(["--set".into(), "radio.channel.model=real".into()]);
    let e = dupac_output(
        &scenario,
        &[
            "eval",
            "-q",
            "--policy",
            &format!("dupac={}", run.policy().display()),
            "--lambda",
            "1",
            "--a3-front",
            "--offset-db",
            "0,12",
            "--ttt-ms",
            "0,320",
            "--l3-filter-k",
            "none,4",
            "--hindsight-front",
            "0,200",
            "--predictive-front",
            "0,300",
            "--out",
            &ev.display().to_string(),
        ]
        .map(String::from),
    );
    assert!(e.status.success(), "{}", String::from_utf8_lossy(&e.stderr));
    let files = dupac_eval::records::read_records(&ev.join("records")).expect("records");
    let mut flights = 0;
    for f in &files {
        for fl in &f.flights {
            let serving: Vec<u16> = std::iter::once(fl.start_serving)
                .chain(fl.steps.iter().map(|s| s.serving))
                .collect();
            let (recount, _) =
                dupac_actor::metrics::count_handovers(&serving, f.rules.ping_pong_window_steps);
            let flagged = fl.steps.iter().filter(|s| s.handover).count() as u32;
            assert_eq!(recount, flagged, "{} pair {}", f.method, fl.pair_id);
            flights += 1;
        }
    }
    assert!(flights >= 8 * 5, "{flights} flights");
    let front = std::fs::read_to_string(ev.join("front.csv")).expect("front.csv");
    let rows: Vec<std::collections::BTreeMap<&str, &str>> = {
        let mut lines = front.lines();
        let header: Vec<&str> = lines.next().expect("header").split(',').collect();
        lines
            .map(|l| header.iter().copied().zip(l.split(',')).collect())
            .collect()
    };
    let of = |method: &str, rule: &str| -> Vec<&std::collections::BTreeMap<&str, &str>> {
        rows.iter()
            .filter(|r| r["method"] == method && r["rule"] == rule)
            .collect()
    };
    for method in ["dupac", "shortest_a3", "coverage_l1"] {
        assert_eq!(of(method, "a3").len(), 8, "{method}: {front}");
    }
    for rule in ["hindsight", "predictive"] {
        assert_eq!(of("dupac", rule).len(), 2, "{rule}: {front}");
        assert!(of("shortest_a3", rule).is_empty(), "{front}");
    }
    // The planned paths arrive, so their excellent time is defined and their front has an
    // envelope (the small policy's flights may all fail: its time is over successes only); a
    // 12 dB margin flies, and hands over less than no margin.
    for method in ["shortest_a3", "coverage_l1"] {
        let a3 = of(method, "a3");
        assert!(
            a3.iter().any(|r| r["on_front"] == "true"),
            "{method}: {front}"
        );
        let rate = |margin: &str| -> f64 {
            a3.iter()
                .filter(|r| r["margin_db"] == margin)
                .map(|r| r["handovers_per_km"].parse::<f64>().expect("number"))
                .sum()
        };
        assert!(rate("12") < rate("0"), "{method}: {front}");
    }
    assert!(ev.join("fronts.png").exists());
}
