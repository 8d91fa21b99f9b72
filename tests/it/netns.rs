//! The multi-host rehearsal of `deploy/netns/run.sh`: a router, the learner, two actors and a
//! monitor, each in its own Linux network namespace on a virtual bridge, train over TCP, with
//! the binary and files installed and the config made as deploy/README.md says. Needs root,
//! iproute2's `ip` and binutils' `strip`; without them the script exits 77 and this test fails
//! when `CI` is set, and prints a visible `SKIPPED` with the script's reason elsewhere.

use std::io::Read;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The script's learner timeout (seconds), passed to it as `DUPAC_NETNS_TIMEOUT`.
const LEARNER_TIMEOUT_S: u64 = 120;
/// A hang's bound on the script's preparation (install, namespaces, the RSRP cache and the
/// held-out pairs with their guide paths): about a minute on 2 idle cores for Midtown, and
/// past 270 s beside the rest of the suite and a flake hunt. The processes' own bound starts
/// when the script says the preparation is done.
const PREPARE_BOUND_S: u64 = 1200;
/// Everything the script may take after its preparation besides the learner: startup, actors,
/// checks, cleanup.
const SLACK_S: u64 = 150;
/// The line the script writes when its preparation is done.
const PREPARED: &str = "cache and pairs in";
/// `exit 77`: the conventional "skipped".
const SKIPPED: i32 = 77;

/// The deploy steps as written, on the default (Midtown) scenario from a directory without
/// `data/`: a tiny training, every process in its own namespace.
#[test]
fn the_deploy_steps_train_midtown_across_network_namespaces() {
    let output = run_script(&[("DUPAC_NETNS_CITY", "midtown")]);
    if let Some(output) = output {
        assert!(
            output.contains("the Midtown buildings and cells built into the binary were used"),
            "{output}"
        );
    }
}

/// Actor 2's link goes down for 12 s (longer than the zenoh lease) while actor 1
/// trains on, then comes back: the learner sees it leave and rejoin, and it acts with newer
/// versions after the partition; the script reports the drops the learner counted. On the
/// procedural city: the run is long, its scenario does not matter.
#[test]
fn an_actor_partitioned_past_the_lease_rejoins() {
    run_script(&[
        ("DUPAC_NETNS_PARTITION_S", "12"),
        ("DUPAC_NETNS_CITY", "procedural"),
    ]);
}

/// Runs the script with `envs`; its output when it ran (and passed), `None` when skipped.
fn run_script(envs: &[(&str, &str)]) -> Option<String> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let script = root.join("deploy/netns/run.sh");
    let log = tempfile::NamedTempFile::new().expect("temp file for the script's output");
    let out = log.reopen().expect("reopen the log");
    let err = log.reopen().expect("reopen the log");
    let mut child = match Command::new("bash")
        .arg(&script)
        .arg(env!("CARGO_BIN_EXE_dupac"))
        .current_dir(root)
        .env("DUPAC_NETNS_TIMEOUT", LEARNER_TIMEOUT_S.to_string())
        .envs(envs.iter().copied())
        .stdin(Stdio::null())
        .stdout(out)
        .stderr(err)
        .spawn()
    {
        Ok(c) => c,
        Err(e) => {
            crate::support::prerequisite(&format!("bash to run {}: {e}", script.display()), false);
            return None;
        }
    };

    // A hard bound on top of the script's own timeout: SIGTERM (the script cleans its
    // namespaces up), then SIGKILL. It counts from the end of the preparation, whose length
    // grows with the machine's load (bounded apart, against a hang).
    let mut deadline = Instant::now() + Duration::from_secs(PREPARE_BOUND_S);
    let mut prepared = false;
    let mut terminated = false;
    let status = loop {
        if let Some(s) = child.try_wait().expect("waiting for the script") {
            break s;
        }
        if !prepared {
            let mut so_far = String::new();
            let _ = log.reopen().map(|mut f| f.read_to_string(&mut so_far));
            if so_far.contains(PREPARED) {
                prepared = true;
                deadline = Instant::now() + Duration::from_secs(LEARNER_TIMEOUT_S + SLACK_S);
            }
        }
        if Instant::now() >= deadline && !terminated {
            let _ = Command::new("kill")
                .args(["-TERM", &child.id().to_string()])
                .status();
            terminated = true;
        } else if Instant::now() >= deadline + Duration::from_secs(20) {
            let _ = child.kill();
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    let mut output = String::new();
    log.reopen()
        .expect("reopen the log")
        .read_to_string(&mut output)
        .expect("read the script's output");

    if status.code() == Some(SKIPPED) {
        crate::support::prerequisite(
            &format!("what deploy/netns/run.sh needs (it exited 77):\n{output}"),
            false,
        );
        return None;
    }
    // Shown with --nocapture; the assertion below carries it on failure.
    println!("{output}");
    assert!(
        !terminated,
        "deploy/netns/run.sh ran past {} and was terminated:\n{output}",
        if prepared {
            format!("{} s after its preparation", LEARNER_TIMEOUT_S + SLACK_S)
        } else {
            format!("{PREPARE_BOUND_S} s in its preparation")
        }
    );
    assert!(
        status.success(),
        "deploy/netns/run.sh failed ({status}):\n{output}"
    );
    assert!(output.contains("PASS"), "no PASS line:\n{output}");
    Some(output)
}
