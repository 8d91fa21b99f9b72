//! The conditioned policy (docs/env.md "Handover weight"): one committed Midtown policy trained
//! with the handover weight drawn per episode and observed, flown by `dupac eval
//! --handover-weight` at three weights on the same pairs. Its handovers per km must fall as the
//! weight rises: the flights are deterministic and the reward plays no part in them, so the only
//! way the weight reaches the flight is through the observation — with the input ignored (or
//! zeroed on its way to the network) all three rows are equal and the test fails.

use crate::support::{dupac_output, fly_committed_policy, summary_column};

/// The committed conditioned policy's point directory (its training `config.toml` and
/// `policy.bin`): real channel, seed 1.
const CONDITIONED: &str = "results/complete/real/dupac_s1";

/// Six validation pairs of the complete city (`pairs.eval_seed = 2024`, ids 0–2 of the 200 m bin
/// and 50–52 of the 300 m bin).
const PAIRS: &str = r#"{"id":0,"source_m":[344.52778429767,414.2671568081946,75.08223095868854],"destination_m":[158.39216795347298,462.94155040488107,111.30820370432318],"shortest_m":197.5212664008888,"straight_m":195.77534411975049,"bin_m":200.0}
{"id":1,"source_m":[52.89475058095195,-501.3510547103173,22.10875457840507],"destination_m":[-103.57135682984102,-396.9222036585497,86.78631536157738],"shortest_m":200.34746888507178,"straight_m":198.9226346325099,"bin_m":200.0}
{"id":2,"source_m":[-251.11257724275697,-185.73048362944513,102.23549779130495],"destination_m":[-79.19100353758373,-272.28843426272937,63.85204582177551],"shortest_m":196.27173945373428,"straight_m":196.27173945373428,"bin_m":200.0}
{"id":50,"source_m":[233.04348838139435,393.95017736206114,107.04099127392185],"destination_m":[259.53866908867445,108.66999739459101,34.79757477600545],"shortest_m":298.2236307667484,"straight_m":295.4756959722322,"bin_m":300.0}
{"id":51,"source_m":[190.15904524916436,423.6568002844242,49.74205002237325],"destination_m":[3.7634450576200322,632.4770965072931,44.10505111578436],"shortest_m":285.1679976432047,"straight_m":279.966090164587,"bin_m":300.0}
{"id":52,"source_m":[-203.7330292685806,-611.6350970709625,101.47845209747868],"destination_m":[-418.07273369104746,-419.6406817965169,107.32796693386582],"shortest_m":287.8151858611839,"straight_m":287.8151858611839,"bin_m":300.0}
"#;

#[test]
fn the_conditioned_policy_hands_over_less_as_its_weight_rises() {
    let dir = tempfile::tempdir().expect("tmp");
    let pairs = dir.path().join("pairs.jsonl");
    std::fs::write(&pairs, PAIRS).expect("pairs");
    let out = dir.path().join("eval");
    let e = fly_committed_policy(CONDITIONED, "c", &pairs, "0,3,6", dir.path(), &out);
    assert!(e.status.success(), "{}", String::from_utf8_lossy(&e.stderr));
    let summary = std::fs::read_to_string(out.join("summary.csv")).expect("summary.csv");
    let rate = |label: &str| summary_column(&summary, label, "handovers_per_km");
    let [w0, w3, w6] = ["c_w0", "c_w3", "c_w6"].map(rate);
    assert!(
        w0 > w3 && w3 > w6,
        "handovers/km at w = 0, 3, 6: {w0:.2}, {w3:.2}, {w6:.2} (must fall as the weight rises)"
    );
}

#[test]
fn a_handover_weight_out_of_range_is_refused_before_flying() {
    let dir = tempfile::tempdir().expect("tmp");
    let out = dir.path().join("eval");
    let e = dupac_output(
        &[],
        &[
            "eval".into(),
            "-q".into(),
            "--policy".into(),
            format!("c={CONDITIONED}/policy.bin"),
            "--handover-weight=0,101".into(),
            "--out".into(),
            out.display().to_string(),
        ],
    );
    let err = String::from_utf8_lossy(&e.stderr);
    assert!(!e.status.success());
    assert!(
        err.contains("--handover-weight 101: must be a number in [0, 100]"),
        "{err}"
    );
    assert!(!out.exists(), "nothing is written for a refused evaluation");
}
