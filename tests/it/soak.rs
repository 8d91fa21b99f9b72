//! The short CI variant of the soak test (`deploy/soak/run.sh`): a learner and three
//! actors on loopback train 600 updates of a small procedural run while actors are killed with
//! SIGKILL and restarted every 2–4 s and the learner is killed and `--resume`d half-way; then
//! the same budget without faults. The script checks that both runs complete with an unbroken
//! learning curve, that no process's memory grows, and that the faulty run's held-out success
//! is no worse than the baseline's (within 0.25 here). The long run's figures are in
//! docs/reliability.md.

use std::path::Path;
use std::process::Command;

#[test]
fn soak_short_variant_passes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = tempfile::tempdir().expect("tmp");
    let o = Command::new("bash")
        .arg(root.join("deploy/soak/run.sh"))
        .arg(env!("CARGO_BIN_EXE_dupac"))
        .env("SOAK_UPDATES", "600")
        .env("SOAK_KILL_EVERY_S", "2")
        // 600 updates is short: both runs are still learning, so allow more spread between
        // them than the long run's 0.15 (100 held-out pairs; this guards against collapse).
        .env("SOAK_TOLERANCE", "0.25")
        .env("SOAK_DIR", dir.path())
        .output()
        .expect("run deploy/soak/run.sh");
    let out = String::from_utf8_lossy(&o.stdout);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "soak failed:\n{out}\n{err}");
    assert!(out.contains("PASS"), "{out}");
    assert!(
        out.contains("ok: faulty run: learner exit 0, 600/600 updates, 0 gaps"),
        "{out}"
    );
    // The faults really happened: actors were killed and the learner was restarted.
    let kills: u32 = std::fs::read_to_string(dir.path().join("faulty/kills"))
        .expect("kills")
        .trim()
        .parse()
        .expect("number");
    assert!(kills >= 1, "no actor was killed: {out}");
    assert!(
        dir.path().join("faulty/learner_killed_at").exists(),
        "{out}"
    );
}
