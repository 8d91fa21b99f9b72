//! End-to-end tests of the `dupac` binary: real processes, the real Midtown data, real files.

use crate::support::{dupac_cmd, small_world_args};
use std::io::Write;
use std::process::{Output, Stdio};

fn dupac(args: &[&str], stdin: Option<&str>) -> Output {
    dupac_bytes(args, stdin.map(str::as_bytes))
}

/// [`dupac`] with any bytes on stdin (not UTF-8, say).
fn dupac_bytes(args: &[&str], stdin: Option<&[u8]>) -> Output {
    let mut child = dupac_cmd()
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn dupac");
    if let Some(input) = stdin {
        child
            .stdin
            .take()
            .expect("stdin")
            .write_all(input)
            .expect("write stdin");
    } else {
        drop(child.stdin.take());
    }
    child.wait_with_output().expect("wait dupac")
}

fn json_lines(out: &Output) -> Vec<serde_json::Value> {
    String::from_utf8_lossy(&out.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("json line"))
        .collect()
}

#[test]
fn link_calculator_reproduces_the_spec_table() {
    // spec/radio.md §3, first row: macro 25 m, UAV 100 m, d2D 500 m along a boresight (30°).
    let (c, s) = (
        30f64.to_radians().cos() * 500.0,
        30f64.to_radians().sin() * 500.0,
    );
    let input = format!(
        "{{\"bs_xyz\":[0,0,25],\"uav_xyz\":[{c},{s},100],\"scenario\":\"uma\",\"los\":true}}\n\
         {{\"bs_xyz\":[0,0,25],\"uav_xyz\":[{c},{s},100],\"scenario\":\"uma\",\"los\":false}}\n\
         {{\"bs_xyz\":[0,0,10],\"uav_xyz\":[{},{},60],\"scenario\":\"umi\",\"los\":true}}\n",
        30f64.to_radians().cos() * 200.0,
        30f64.to_radians().sin() * 200.0
    );
    let out = dupac(&["radio", "link"], Some(&input));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json_lines(&out);
    assert_eq!(v.len(), 3);
    let f = |i: usize, k: &str| v[i][k].as_f64().expect(k);
    assert!((f(0, "rsrp_dbm") + 75.34).abs() < 0.01, "{}", v[0]);
    assert!((f(0, "gain_dbi") - 2.97).abs() < 0.01);
    assert!((f(0, "pl_db") - 93.50).abs() < 0.01);
    assert!((f(0, "theta_deg") - 81.47).abs() < 0.01);
    assert_eq!(v[0]["class"], "excellent");
    assert_eq!(v[0]["best_sector"], 0);
    assert!((f(1, "rsrp_dbm") + 89.32).abs() < 0.01);
    assert_eq!(v[1]["class"], "mediocre");
    assert_eq!(v[1]["los"], false);
    // micro 10 m, UAV 60 m, 200 m, LoS: −69.64 dBm.
    assert!((f(2, "rsrp_dbm") + 69.64).abs() < 0.01, "{}", v[2]);
    for k in [
        "d3d_m",
        "d2d_m",
        "theta_deg",
        "best_sector",
        "gain_dbi",
        "pl_db",
        "rsrp_dbm",
        "class",
        "los",
    ] {
        assert!(v[0].get(k).is_some(), "missing output field {k}");
    }
}

#[test]
fn link_calculator_overrides_change_the_result() {
    let base = r#"{"bs_xyz":[0,0,25],"uav_xyz":[433.0127,250,100],"scenario":"uma","los":true"#;
    let input = format!(
        "{base}}}\n{base},\"tx_power_dbm\":25.2}}\n{base},\"fc_ghz\":4.0}}\n{base},\"tilt_deg\":0,\"n\":1}}\n"
    );
    let out = dupac(&["radio", "link"], Some(&input));
    assert!(out.status.success());
    let v = json_lines(&out);
    let r = |i: usize| v[i]["rsrp_dbm"].as_f64().expect("rsrp");
    assert!((r(1) - r(0) - 10.0).abs() < 1e-9, "power +10 dB");
    // fc doubled: +20 log10 2 = 6.02 dB more loss for UMa-AV LoS.
    assert!((r(0) - r(2) - 6.0206).abs() < 1e-3);
    // A single element has no array gain: element only (A_E at θ = 81.47°, φ = 0).
    let g = v[3]["gain_dbi"].as_f64().expect("gain");
    let expected = 8.0 - 12.0 * ((81.4718_f64 - 90.0) / 65.0).powi(2);
    assert!((g - expected).abs() < 0.01, "{g} vs {expected}");
}

#[test]
fn link_calculator_reports_bad_lines_and_keeps_going() {
    let input = "\
{\"bs_xyz\":[0,0,25],\"uav_xyz\":[100,0,50],\"scenario\":\"uma\",\"los\":true}
{\"bs_xyz\":[0,0,25],\"scenario\":\"uma\"}
not json
{\"bs_xyz\":[0,0,25],\"uav_xyz\":[100,0,50],\"scenario\":\"rma\",\"los\":true}
{\"bs_xyz\":[0,0,25],\"uav_xyz\":[100,0,50],\"scenario\":\"uma\",\"los\":true,\"colour\":1}
{\"bs_xyz\":[0,0,25],\"uav_xyz\":[5000,0,50],\"scenario\":\"uma\"}
{\"bs_xyz\":[0,0,25],\"uav_xyz\":[100,0,50],\"scenario\":\"uma\",\"fc_ghz\":-2,\"los\":true}
{\"bs_xyz\":[0,0,25],\"uav_xyz\":[120,0,50],\"scenario\":\"uma\",\"los\":false}
";
    let out = dupac(&["radio", "link"], Some(input));
    assert!(
        !out.status.success(),
        "a failed line makes the exit status non-zero"
    );
    let v = json_lines(&out);
    assert_eq!(v.len(), 2, "the two good lines are still answered");
    assert_eq!(v[1]["los"], false);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("line 2:") && err.contains("uav_xyz"), "{err}");
    assert!(err.contains("line 3:"), "{err}");
    assert!(err.contains("line 4:") && err.contains("rma"), "{err}");
    assert!(err.contains("line 5:") && err.contains("colour"), "{err}");
    assert!(
        err.contains("line 6:") && err.contains("outside the map"),
        "{err}"
    );
    assert!(err.contains("line 7:") && err.contains("fc_ghz"), "{err}");
}

#[test]
fn link_calculator_decides_los_against_the_midtown_buildings() {
    // Read the real sites, then ask for a link from site 0 straight up (always LoS above its own
    // roof) and for links to points at 120 m along a diagonal across the map: the towers of
    // Midtown block some of them, not all.
    let sites = dupac(&["radio", "sites"], None);
    assert!(
        sites.status.success(),
        "{}",
        String::from_utf8_lossy(&sites.stderr)
    );
    let text = String::from_utf8_lossy(&sites.stdout);
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("name,x_m,y_m,z_m,kind,boresights_deg,tilt_deg,tx_power_dbm")
    );
    let rows: Vec<Vec<String>> = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    assert_eq!(rows.len(), 30, "M = 30 sites");
    let xyz: Vec<f64> = rows[0][1..4]
        .iter()
        .map(|s| s.parse().expect("num"))
        .collect();
    let mut input = String::new();
    input += &format!(
        "{{\"bs_xyz\":[{},{},{}],\"uav_xyz\":[{},{},{}],\"scenario\":\"uma\"}}\n",
        xyz[0],
        xyz[1],
        xyz[2],
        xyz[0] + 1.0,
        xyz[1],
        xyz[2] + 100.0
    );
    // Points at 120 m across the map: some must be blocked, some not.
    for i in 0..40 {
        let x = -650.0 + 33.0 * i as f64;
        input += &format!(
            "{{\"bs_xyz\":[{},{},{}],\"uav_xyz\":[{x},{},120],\"scenario\":\"uma\"}}\n",
            xyz[0],
            xyz[1],
            xyz[2],
            -500.0 + 20.0 * i as f64
        );
    }
    let out = dupac(&["radio", "link"], Some(&input));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = json_lines(&out);
    assert_eq!(v[0]["los"], true);
    let blocked = v[1..].iter().filter(|x| x["los"] == false).count();
    assert!(blocked > 5 && blocked < 40, "{blocked} of 40 links blocked");
}

#[test]
fn map_writes_png_csv_and_summary_for_a_small_scenario() {
    let dir = tempfile::tempdir().expect("tmp");
    let out_dir = dir.path().join("map");
    let out = dupac(
        &[
            "map",
            "-q",
            "--out",
            out_dir.to_str().expect("utf8"),
            "--set",
            "map.resolution_m=25",
            "--set",
            "map.altitudes_m=[30, 120]",
        ],
        None,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "rsrp_30m.png",
        "rsrp_120m.png",
        "rsrp_30m.csv",
        "summary.md",
        "summary.csv",
        "sites.csv",
        "config.toml",
    ] {
        assert!(out_dir.join(f).exists(), "{f} missing");
    }
    let png = std::fs::read(out_dir.join("rsrp_30m.png")).expect("png");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let csv = std::fs::read_to_string(out_dir.join("rsrp_30m.csv")).expect("csv");
    assert!(csv.starts_with("ix,iy,x_m,y_m,rsrp_dbm,serving,los\n"));
    // 1432 m / 25 m = 57 columns, 1332 / 25 = 53 rows.
    assert_eq!(csv.lines().count(), 1 + 57 * 53);
    let summary = std::fs::read_to_string(out_dir.join("summary.csv")).expect("summary");
    let mut rows = summary.lines().skip(1).map(|l| {
        let f: Vec<f64> = l.split(',').map(|x| x.parse().expect("num")).collect();
        f
    });
    let (low, high) = (rows.next().expect("30 m"), rows.next().expect("120 m"));
    // Columns: altitude, cells, mean, median, p10, p90, exc, med, poor, nlos, inside.
    assert!(
        low[9] > high[9],
        "less NLoS at 120 m than at 30 m: {} vs {}",
        low[9],
        high[9]
    );
    assert!(low[10] > high[10], "fewer cells inside buildings higher up");
    assert!(
        low[2] > -100.0 && low[2] < -60.0,
        "plausible mean RSRP {}",
        low[2]
    );
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("| altitude (m) |"), "{stdout}");
}

#[test]
fn config_errors_name_the_key() {
    let out = dupac(&["config", "--set", "radio.fc_gz=3"], None);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("fc_gz"), "{err}");
    let out = dupac(&["config", "--set", "map.resolution_m=0"], None);
    assert!(String::from_utf8_lossy(&out.stderr).contains("map.resolution_m"));
    let out = dupac(&["config", "--set", "radio.fc_ghz=3.5"], None);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("fc_ghz = 3.5"));
}

/// A global option given on both sides of the command would lose the occurrences before it
/// (clap keeps one side); `dupac` refuses that instead of running with a configuration the user
/// did not write, and either side alone works.
#[test]
fn a_set_on_both_sides_of_the_command_is_refused_not_dropped() {
    let out = dupac(
        &[
            "--set",
            "train.seed=5",
            "config",
            "--set",
            "train.num_envs=3",
        ],
        None,
    );
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--set was given 2 times but 1 reached the command"),
        "{err}"
    );
    let out = dupac(
        &["--config", "a.toml", "config", "--config", "b.toml"],
        None,
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--config was given 2 times"));
    for args in [
        &[
            "--set",
            "train.seed=5",
            "--set",
            "train.num_envs=3",
            "config",
        ][..],
        &["config", "--set", "train.seed=5", "--set=train.num_envs=3"][..],
    ] {
        let out = dupac(args, None);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            text.contains("seed = 5") && text.contains("num_envs = 3"),
            "{args:?}: {text}"
        );
    }
}

#[test]
fn broken_city_file_is_a_clear_error() {
    let dir = tempfile::tempdir().expect("tmp");
    let bad = dir.path().join("bad.geojson");
    std::fs::write(&bad, "{\"type\":\"FeatureCollection\",\"features\":[").expect("write");
    let out = dupac(
        &[
            "radio",
            "sites",
            "--set",
            &format!("scenario.buildings_file=\"{}\"", bad.display()),
        ],
        None,
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.geojson") && !err.contains("panicked"),
        "{err}"
    );
}

#[test]
fn pairs_then_plan_writes_a_flown_comparison() {
    let dir = tempfile::tempdir().expect("tmp");
    let pairs = dir.path().join("pairs.jsonl");
    let mut args: Vec<String> = vec![
        "pairs".into(),
        "-q".into(),
        "--split".into(),
        "validation".into(),
        "--out".into(),
        pairs.display().to_string(),
    ];
    args.extend(small_world_args(dir.path()));
    args.extend(
        [
            "--set",
            "pairs.eval_bins_m=[200, 300]",
            "--set",
            "pairs.eval_per_bin=3",
        ]
        .map(String::from),
    );
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = dupac(&a, None);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&pairs)
        .expect("pairs file")
        .lines()
        .map(|l| serde_json::from_str(l).expect("json"))
        .collect();
    assert_eq!(lines.len(), 6);
    for p in &lines {
        let (bin, d) = (
            p["bin_m"].as_f64().expect("bin"),
            p["shortest_m"].as_f64().expect("d"),
        );
        assert!((d - bin).abs() <= 0.05 * bin + 1e-9, "{p}");
        assert!(d >= p["straight_m"].as_f64().expect("straight") - 1e-9);
    }
    // The same seed gives the same file.
    let again = dir.path().join("again.jsonl");
    let mut args2 = args.clone();
    args2[5] = again.display().to_string();
    let a2: Vec<&str> = args2.iter().map(String::as_str).collect();
    assert!(dupac(&a2, None).status.success());
    assert_eq!(
        std::fs::read(&pairs).expect("a"),
        std::fs::read(&again).expect("b")
    );

    let plan_dir = dir.path().join("plan");
    let mut args: Vec<String> = [
        "plan",
        "-q",
        "--pairs",
        &pairs.display().to_string(),
        "--pair",
        "4",
        "--lambda",
        "0",
        "--lambda",
        "5",
        "--out",
        &plan_dir.display().to_string(),
    ]
    .map(String::from)
    .to_vec();
    args.extend(small_world_args(dir.path()));
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = dupac(&a, None);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let table = String::from_utf8_lossy(&out.stdout);
    let rows: Vec<&str> = table
        .lines()
        .filter(|l| l.starts_with("| shortest") || l.starts_with("| coverage"))
        .collect();
    assert_eq!(rows.len(), 3, "{table}");
    for r in &rows {
        assert!(
            r.contains("| Goal |"),
            "every planned path is flown to the goal: {r}"
        );
    }
    // λ = 0 is the shortest path: same planned length.
    let planned = |r: &str| {
        r.split('|')
            .nth(2)
            .expect("col")
            .trim()
            .parse::<f64>()
            .expect("num")
    };
    assert!(
        (planned(rows[0]) - planned(rows[1])).abs() < 1e-6,
        "{table}"
    );
    assert!(planned(rows[2]) >= planned(rows[0]) - 1e-6);
    for f in [
        "plan.png",
        "summary.md",
        "flight_shortest.csv",
        "flight_coverage_aware_lambda_0.csv",
    ] {
        assert!(plan_dir.join(f).exists(), "{f} missing");
    }
    // A pair index past the end is a clear error.
    let mut bad = args.clone();
    bad[5] = "99".into();
    let b: Vec<&str> = bad.iter().map(String::as_str).collect();
    let out = dupac(&b, None);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--pair 99"));
}

#[test]
fn plan_rejects_an_endpoint_off_the_map() {
    // Midtown spans x ∈ [−716, 716] m: a source 5 km east is refused before anything is built.
    let out = dupac(
        &[
            "plan",
            "-q",
            "--from",
            "5000,0,50",
            "--to",
            "0,0,50",
            "--out",
            "/tmp/dupac-never",
        ],
        None,
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.to_lowercase().contains("source") && !err.contains("panicked"),
        "{err}"
    );
}

/// Every line of `dupac radio link` is judged on its own: a line that is not UTF-8, one
/// longer than 64 KiB, coordinates out of physical range, a UAV below the ground and a carrier
/// frequency outside the models' range are each an error naming the line; the other lines are
/// answered, and the exit status says some failed.
#[test]
fn link_calculator_refuses_unphysical_and_undecodable_lines_one_by_one() {
    let good = b"{\"bs_xyz\":[0,0,25],\"uav_xyz\":[100,0,50],\"scenario\":\"uma\",\"los\":true}\n";
    let mut input = Vec::new();
    input.extend_from_slice(good);
    input.extend_from_slice(
        b"{\"bs_xyz\":[0,0,25],\"uav_xyz\":[1e308,0,50],\"scenario\":\"uma\",\"los\":true}\n",
    );
    input.extend_from_slice(b"{\"bs_xyz\":[0,0,25],\"uav_xyz\":[100,0,50],\"scenario\":\"uma\",\"los\":true,\"fc_ghz\":1e-300}\n");
    input.extend_from_slice(
        b"{\"bs_xyz\":[0,0,25],\"uav_xyz\":[100,0,-5],\"scenario\":\"uma\",\"los\":true}\n",
    );
    input.extend_from_slice(
        b"{\"bs_xyz\":[0,0,25],\"uav_xyz\":[100,0,\xff50],\"scenario\":\"uma\"}\n",
    );
    input.extend_from_slice(&vec![b' '; 100_000]);
    input.extend_from_slice(b"\n");
    input.extend_from_slice(good);
    let out = dupac_bytes(&["radio", "link"], Some(&input));
    assert!(!out.status.success());
    assert_eq!(json_lines(&out).len(), 2, "the good lines are answered");
    let err = String::from_utf8_lossy(&out.stderr);
    for (line, what) in [
        (2, "from the scenario centre"),
        (3, "fc_ghz"),
        (4, "above the ground"),
        (5, "not UTF-8"),
        (6, "longer than"),
    ] {
        assert!(
            err.lines()
                .any(|l| l.starts_with(&format!("line {line}:")) && l.contains(what)),
            "line {line} ({what}): {err}"
        );
    }
}

/// A `--device` this build or machine cannot run is refused before anything starts, with the
/// flag and the remedy named, not a panic (CI's build has no GPU backend).
#[test]
fn an_unavailable_device_is_a_clear_error() {
    let dir = tempfile::tempdir().expect("temp dir");
    let out_dir = dir.path().join("run");
    let out_dir = out_dir.to_str().expect("utf-8");
    for (command, device) in [
        (&["train", "--single-process"][..], "cuda"),
        (&["train"][..], "wgpu"),
        (&["learner"][..], "cuda"),
    ] {
        let mut args = command.to_vec();
        args.extend(["--device", device, "--out", out_dir]);
        let out = dupac(&args, None);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} ran");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(
            err.contains(&format!("--device {device}"))
                && (err.contains(&format!("--features {device}"))
                    || err.contains("found on this machine")),
            "{args:?}: {err}"
        );
    }
}
