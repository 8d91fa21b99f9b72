//! The held-out splits on the small procedural world: `dupac pairs` writes validation and
//! test (same bins and counts, other pairs, a function of the seed), `dupac eval --split test`
//! flies the test split (drawn when missing, the same pairs `dupac pairs` writes) and says so in
//! `report.md`, `summary.csv` and `records/split.txt`; `--split` with `--pairs` and `--out`
//! without `--split` are refused.

use crate::support::{dupac_output, split_world_args as args};
use std::path::Path;

fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn cmd(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

/// (bin, source, destination) of every line of a pairs file.
fn pairs_of(path: &Path) -> Vec<(f64, Vec<f64>, Vec<f64>)> {
    std::fs::read_to_string(path)
        .expect("pairs file")
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).expect("json");
            let pt = |k: &str| -> Vec<f64> {
                v[k].as_array()
                    .expect("point")
                    .iter()
                    .map(|x| x.as_f64().expect("number"))
                    .collect()
            };
            (
                v["bin_m"].as_f64().expect("bin"),
                pt("source_m"),
                pt("destination_m"),
            )
        })
        .collect()
}

#[test]
fn pairs_writes_both_splits_binned_alike_and_disjoint() {
    let dir = tempfile::tempdir().expect("tmp");
    let a = args(dir.path());
    let out = dupac_output(&a, &cmd(&["pairs", "-q"]));
    ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("split: validation (pairs.eval_seed = 2024)")
            && stdout.contains("split: test (pairs.test_seed = 8117)"),
        "{stdout}"
    );
    let (val, test) = (
        pairs_of(&dir.path().join("val.jsonl")),
        pairs_of(&dir.path().join("test.jsonl")),
    );
    assert_eq!(val.len(), 8);
    let bins = |v: &[(f64, Vec<f64>, Vec<f64>)]| v.iter().map(|p| p.0).collect::<Vec<_>>();
    assert_eq!(bins(&val), bins(&test), "same bins, same counts");
    // No endpoint shared (within 1e-6 m) between the splits, either way round.
    let d = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
    for t in &test {
        for v in &val {
            for (x, y) in [(&t.1, &v.1), (&t.1, &v.2), (&t.2, &v.1), (&t.2, &v.2)] {
                assert!(d(x, y).sqrt() > 1e-6, "shared endpoint {x:?}");
            }
        }
    }
    // The same seed gives the same file; --out without --split is refused, naming both flags.
    let again = dir.path().join("again.jsonl");
    ok(&dupac_output(
        &a,
        &cmd(&[
            "pairs",
            "-q",
            "--split",
            "test",
            "--out",
            again.to_str().expect("utf-8"),
        ]),
    ));
    assert_eq!(
        std::fs::read(&again).expect("again"),
        std::fs::read(dir.path().join("test.jsonl")).expect("test")
    );
    let bad = dupac_output(&a, &cmd(&["pairs", "-q", "--out", "x.jsonl"]));
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("--out") && err.contains("--split"),
        "{err}"
    );
}

#[test]
fn eval_flies_the_test_split_and_says_so() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut a = args(dir.path());
    a.extend(cmd(&["--set", "pairs.test_seed=77"]));
    let ev = dir.path().join("eval");
    let ev_s = ev.display().to_string();
    ok(&dupac_output(
        &a,
        &cmd(&[
            "eval", "-q", "--split", "test", "--lambda", "1", "--out", &ev_s,
        ]),
    ));
    let report = std::fs::read_to_string(ev.join("report.md")).expect("report.md");
    assert_eq!(
        report.lines().next(),
        Some("split: test (pairs.test_seed = 77)")
    );
    let split = std::fs::read_to_string(ev.join("records/split.txt")).expect("split.txt");
    assert!(split.contains("test.jsonl"), "{split}");
    let summary = std::fs::read_to_string(ev.join("summary.csv")).expect("summary.csv");
    assert!(summary.lines().next().expect("header").ends_with(",split"));
    assert!(
        summary.lines().skip(1).all(|l| l.ends_with(",test")),
        "{summary}"
    );
    // The test file was drawn (it was missing): the pairs `dupac pairs --split test` writes.
    let by_pairs = dir.path().join("by_pairs.jsonl");
    ok(&dupac_output(
        &a,
        &cmd(&[
            "pairs",
            "-q",
            "--split",
            "test",
            "--out",
            by_pairs.to_str().expect("utf-8"),
        ]),
    ));
    assert_eq!(
        std::fs::read(&by_pairs).expect("by pairs"),
        std::fs::read(dir.path().join("test.jsonl")).expect("drawn by eval")
    );
    assert!(
        !dir.path().join("val.jsonl").exists(),
        "validation untouched"
    );
    // --report-only reads the split back from the records.
    ok(&dupac_output(
        &a,
        &cmd(&["eval", "-q", "--report-only", "--out", &ev_s]),
    ));
    assert_eq!(
        std::fs::read_to_string(ev.join("report.md")).expect("report.md"),
        report
    );
    // --split and --pairs together: refused, naming both.
    let both = dupac_output(
        &a,
        &cmd(&[
            "eval", "-q", "--split", "test", "--pairs", "x.jsonl", "--out", &ev_s,
        ]),
    );
    let err = String::from_utf8_lossy(&both.stderr);
    assert!(
        !both.status.success() && err.contains("--split") && err.contains("--pairs"),
        "{err}"
    );
}

/// `dupac pairs --audit`: every pair drawn gets a row of `<pairs file>.audit.csv` (its shortest
/// path, its four coverage-aware paths and the lower bound), and the summary line counts the
/// pairs with a shorter coverage-aware path as the rows show them (on this world one pair has
/// one, by 0.74 m: docs/results.md "The shortest path"); no shortest path is below the bound.
#[test]
fn pairs_audit_writes_a_row_per_pair_and_a_summary() {
    let dir = tempfile::tempdir().expect("tmp");
    let a = args(dir.path());
    let out = dupac_output(
        &a,
        &cmd(&["pairs", "-q", "--split", "validation", "--audit"]),
    );
    ok(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let csv = std::fs::read_to_string(dir.path().join("val.jsonl.audit.csv")).expect("audit csv");
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("pair_id,shortest_m,lambda_0.5_m,lambda_1_m,lambda_2_m,lambda_4_m,bound_m,gap_m")
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|x| x.parse().expect("number")).collect())
        .collect();
    assert_eq!(rows.len(), 8);
    for r in &rows {
        assert!(r[1] >= r[6] - 1e-6, "shortest below the bound: {r:?}");
        assert!(
            (r[7] - (r[1] - r[6])).abs() < 1e-9,
            "gap = shortest − bound: {r:?}"
        );
    }
    let shorter = rows
        .iter()
        .filter(|r| r[2..6].iter().any(|l| *l < r[1] - 1e-6))
        .count();
    assert!(
        stdout.contains(&format!(
            "audit: 8 pairs; a coverage-aware path shorter than the shortest: {shorter} "
        )) && stdout.contains("shortest below the bound: 0"),
        "{stdout}"
    );
}

/// The default pair files follow the city (`{city}` in `pairs.eval_file`: its fingerprint): two
/// procedural cities evaluated one after the other in one working directory, neither naming a
/// pairs file, each draw and fly their own pairs. (With a fixed default path the second city
/// read the first one's file and stopped: "source … is 4.22 m from a building".)
#[test]
fn switching_the_city_evaluates_its_own_pairs_without_a_path() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut dirs = Vec::new();
    for size_m in [500, 420] {
        let mut a = crate::support::small_world_args(dir.path());
        for kv in [
            format!("scenario.procedural.size_m={size_m}"),
            "pairs.min_m=40".into(),
            "pairs.max_m=70".into(),
            "pairs.eval_bins_m=[50, 60]".into(),
            "pairs.eval_per_bin=4".into(),
            "pairs.bin_tolerance=0.1".into(),
        ] {
            a.push("--set".into());
            a.push(kv);
        }
        let out = dir.path().join(format!("eval{size_m}"));
        let run = crate::support::dupac_cmd()
            .current_dir(dir.path())
            .args(cmd(&[
                "eval",
                "-q",
                "--lambda",
                "1",
                "--out",
                &out.display().to_string(),
            ]))
            .args(&a)
            .stdin(std::process::Stdio::null())
            .output()
            .expect("run dupac");
        ok(&run);
        assert!(out.join("report.md").exists());
        dirs = std::fs::read_dir(dir.path().join("out/pairs"))
            .expect("out/pairs written in the working directory")
            .map(|e| e.expect("entry").path())
            .collect();
    }
    assert_eq!(dirs.len(), 2, "one pairs directory per city: {dirs:?}");
    for d in &dirs {
        assert_eq!(
            pairs_of(&d.join("eval_pairs.jsonl")).len(),
            8,
            "{}",
            d.display()
        );
        let name = d.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        assert!(
            name.len() == 16 && name.chars().all(|c| c.is_ascii_hexdigit()),
            "{name}"
        );
    }
}

/// `plan --pair N` without `--pairs` plans pair N of this city's validation split (drawn and
/// written when missing), the pair `dupac fly --pair N` flies.
#[test]
fn plan_takes_a_pair_of_the_validation_split_by_default() {
    let dir = tempfile::tempdir().expect("tmp");
    let a = args(dir.path());
    let out = dir.path().join("plan");
    let o = out.display().to_string();
    ok(&dupac_output(
        &a,
        &cmd(&["plan", "-q", "--pair", "3", "--lambda", "1", "--out", &o]),
    ));
    let val = pairs_of(&dir.path().join("val.jsonl"));
    assert_eq!(val.len(), 8, "the split was drawn and written");
    let bad = dupac_output(&a, &cmd(&["plan", "-q", "--pair", "8", "--out", &o]));
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        err.contains("val.jsonl: --pair 8 but the file has 8 pairs"),
        "{err}"
    );
}
