//! Secured multi-machine runs: mutual TLS and access control by certificate, set up
//! with `deploy/tls/make-certs.sh` and the configs it writes, proven with real processes over
//! loopback: a `dupac router` that only speaks TLS, a learner and an actor with their role
//! certificates, and the test's own Zenoh sessions playing a monitor, a rogue actor and a
//! process without a certificate.

use crate::support::*;
use dupac_common::ids::ActorId;
use dupac_common::keys::KeySpace;
use dupac_common::msg::{
    ActorState, Command as Control, ControlMsg, Header, WeightsMsg, decode_msg, encode_msg,
};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};
use zenoh::Wait;

/// A role's client config as written by make-certs.sh, pointed at `endpoint`.
fn role_config(certs: &Path, role: &str, endpoint: &str) -> zenoh::Config {
    let mut c = zenoh::Config::from_file(certs.join(format!("{role}.json5")))
        .unwrap_or_else(|e| panic!("{role}.json5: {e}"));
    c.insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
        .expect("connect");
    c
}

fn open(c: zenoh::Config) -> zenoh::Result<zenoh::Session> {
    zenoh::open(c).wait()
}

/// An actor with a valid certificate trains; a process without a certificate, or speaking plain
/// TCP to the router is not offered (it listens on TLS only); an authenticated actor that publishes weights (and a Stop) is
/// denied at the router: subscribers never see the forged weights, the learner's weights and run
/// go on; a monitor that publishes trajectories is denied too (the learner never sees them).
/// Least privilege: a monitor subscribing to trajectories receives none; actor 0's
/// certificate can neither publish on actor 1's key nor declare actor 7's token; a flood of
/// weights queries gets replies at the learner's rate. Checked to fail with each rule widened in
/// the router's config (see docs/reliability.md).
#[test]
fn mutual_tls_and_access_control_admit_the_run_and_deny_the_rest() {
    if !prerequisite(
        "openssl (deploy/tls/make-certs.sh needs it)",
        Command::new("openssl").arg("version").output().is_ok(),
    ) {
        return;
    }
    let dir = tempfile::tempdir().expect("tmp");
    let certs = dir.path().join("certs");
    let made = Command::new("bash")
        .arg(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/deploy/tls/make-certs.sh"
        ))
        .arg(&certs)
        .output()
        .expect("make-certs.sh");
    assert!(
        made.status.success(),
        "make-certs.sh failed: {}",
        String::from_utf8_lossy(&made.stderr)
    );
    let cfg = |role: &str| certs.join(format!("{role}.json5")).display().to_string();

    let run = "secure";
    let mut p = Procs::new(dir.path(), run, 100_000_000);
    let port = free_port();
    let listen = format!("tls/127.0.0.1:{port}");
    // Clients name the router as in its certificate (subjectAltName localhost).
    let ep = format!("tls/localhost:{port}");
    let out = dir.path().join("run").display().to_string();
    p.spawn(
        "router",
        &[
            "router",
            "--zenoh-config",
            &cfg("router"),
            "--listen",
            &listen,
        ],
    );
    p.spawn(
        "learner",
        &[
            "learner",
            "--out",
            &out,
            "--zenoh-config",
            &cfg("learner"),
            "--connect",
            &ep,
        ],
    );
    p.spawn(
        "actor1",
        &[
            "actor",
            "--id",
            "1",
            "--threads",
            "1",
            "--zenoh-config",
            &cfg("actor-1"),
            "--connect",
            &ep,
        ],
    );

    // A monitor (read-only certificate) sees the run train on the certified actor's data.
    let monitor = Watcher::with_config(role_config(&certs, "monitor", &ep), run);
    let before = monitor.wait_for(&p, "updates from the certified actor", 90, |s| {
        s.update >= 5
            && s.actors
                .iter()
                .any(|a| a.actor == ActorId(1) && a.chunks > 0 && a.state == ActorState::Alive)
    });
    let keys = KeySpace::new(run);
    let weights_seen = monitor
        .session
        .declare_subscriber(keys.weights())
        .with(zenoh::handlers::FifoChannel::new(4096))
        .wait()
        .expect("subscribe weights");

    // No certificate: the CA alone (the client can check the router, not be checked by it).
    let mut no_cert = zenoh::Config::default();
    no_cert.insert_json5("mode", "\"client\"").expect("mode");
    no_cert
        .insert_json5("connect/endpoints", &format!("[\"{ep}\"]"))
        .expect("connect");
    no_cert
        .insert_json5("scouting/multicast/enabled", "false")
        .expect("scouting");
    no_cert
        .insert_json5(
            "transport/link/tls/root_ca_certificate",
            &format!("\"{}\"", certs.join("ca.pem").display()),
        )
        .expect("ca");
    assert!(
        open(no_cert).is_err(),
        "a client without a certificate opened a session"
    );
    // No plain-TCP endpoint: the router's configuration listens on TLS only. (A plain-TCP client
    // against the TLS port fails whatever the TLS settings, so it would prove nothing.)
    let router_cfg = zenoh::Config::from_file(certs.join("router.json5")).expect("router.json5");
    let listen = router_cfg.get_json("listen/endpoints").expect("listen");
    assert!(
        listen.contains("tls/") && !listen.contains("tcp/"),
        "the router listens on {listen}"
    );

    // Least privilege: a monitor reads no trajectory, though actor 1 is sending.
    let traj_tap = monitor
        .session
        .declare_subscriber(keys.traj_all())
        .with(zenoh::handlers::FifoChannel::new(64))
        .wait()
        .expect("subscribe (denied at the router, not locally)");
    std::thread::sleep(Duration::from_secs(1));
    assert!(
        traj_tap.try_recv().ok().flatten().is_none(),
        "a monitor received a trajectory chunk"
    );
    // The weights queryable answers a flood at its rate (10/s, burst 20), not at the flood's.
    // A query answered first (the client's session knows the queryable: see
    // `Watcher::weights`), then two seconds for the bucket to refill.
    monitor.weights();
    std::thread::sleep(Duration::from_secs(2));
    let t0 = Instant::now();
    let mut replies = 0usize;
    let flood: Vec<_> = (0..100)
        .map(|_| {
            monitor
                .session
                .get(keys.weights())
                .timeout(Duration::from_secs(3))
                .wait()
                .expect("query")
        })
        .collect();
    for r in flood {
        while let Ok(reply) = r.recv() {
            replies += usize::from(reply.result().is_ok());
        }
    }
    let limit = 20.0 + 10.0 * t0.elapsed().as_secs_f64() + 1.0;
    assert!(
        replies >= 1 && replies as f64 <= limit,
        "{replies} replies to 100 queries in {:.1} s (at most {limit:.0})",
        t0.elapsed().as_secs_f64()
    );
    // The flood spent the bucket; two seconds refill it for the queries below.
    std::thread::sleep(Duration::from_secs(2));

    // The rogue: actor 0's certificate publishing forged weights (version 10^9), a Stop,
    // garbage on actor 1's key and actor 7's liveliness token.
    let genuine: WeightsMsg = monitor.weights();
    let rogue = Watcher::with_config(role_config(&certs, "actor-0", &ep), run);
    let _fake_token = rogue
        .session
        .liveliness()
        .declare_token(keys.alive(dupac_common::keys::Role::Actor, "7"))
        .wait()
        .expect("token (denied at the router, not locally)");
    let mut forged = genuine.clone();
    forged.header.policy_version = 1_000_000_000;
    forged.policy.version = 1_000_000_000;
    let stop = ControlMsg {
        header: Header::new(
            run,
            genuine.header.learner_incarnation,
            ActorId::LEARNER,
            genuine.header.config_fingerprint,
        ),
        command: Control::Stop,
    };
    for _ in 0..5 {
        for (key, bytes) in [
            (keys.weights(), encode_msg(&forged).expect("encode")),
            (
                keys.ctrl(),
                dupac_common::jsonmsg::encode_json(&stop).expect("encode"),
            ),
        ] {
            rogue
                .session
                .put(key, bytes)
                .congestion_control(zenoh::qos::CongestionControl::Block)
                .wait()
                .expect("put (denied at the router, not locally)");
        }
        // A monitor publishing trajectories, and actor 0 on actor 1's key: garbage the
        // learner would count if it arrived.
        monitor.publish(9, b"not a chunk".to_vec());
        rogue.publish(1, b"not a chunk either".to_vec());
        std::thread::sleep(Duration::from_millis(100));
    }

    // The run goes on past the forgery; meanwhile the weights subscriber sees only the learner.
    let after = monitor.wait_for(&p, "updates after the forgery", 60, |s| {
        s.update >= before.update + 10
    });
    let t0 = Instant::now();
    let mut genuine_seen = 0;
    while t0.elapsed() < Duration::from_secs(1) {
        if let Ok(Some(s)) = weights_seen.recv_timeout(Duration::from_millis(100)) {
            let w: WeightsMsg = decode_msg(
                &s.payload().to_bytes(),
                dupac_common::msg::MsgLimits::both(1 << 26),
                "weights",
            )
            .expect("only the learner's weights reach subscribers");
            assert!(
                w.header.policy_version < 1_000_000_000,
                "forged weights reached a subscriber"
            );
            assert_eq!(
                w.header.learner_incarnation,
                genuine.header.learner_incarnation
            );
            genuine_seen += 1;
        }
    }
    let drained: Vec<_> = weights_seen.drain().collect();
    for s in drained {
        let w: WeightsMsg = decode_msg(
            &s.payload().to_bytes(),
            dupac_common::msg::MsgLimits::both(1 << 26),
            "weights",
        )
        .expect("w");
        assert!(
            w.header.policy_version < 1_000_000_000,
            "forged weights seen"
        );
        genuine_seen += 1;
    }
    assert!(
        genuine_seen > 0,
        "the monitor saw no weights at all: the check above proves nothing"
    );
    let now = monitor.weights();
    assert!(
        now.header.policy_version > genuine.header.policy_version
            && now.header.policy_version < 1_000_000_000,
        "the learner's weights: {} then {}",
        genuine.header.policy_version,
        now.header.policy_version
    );
    assert_eq!(
        drops(&after, "garbage"),
        0,
        "a monitor's trajectory, or actor 0's on actor 1's key, reached the learner: {:?}",
        after.drops
    );
    assert!(
        after.actors.iter().all(|a| a.actor != ActorId(7)),
        "actor 0's certificate declared actor 7's liveliness token: {:?}",
        after.actors
    );
    // The learner and the actor are still running (the forged Stop never arrived).
    assert!(p.child("learner").try_wait().expect("wait").is_none());
    assert!(p.child("actor1").try_wait().expect("wait").is_none());

    // Ctrl-C to both: the actor reports the versions it acted with, all genuine.
    p.signal_and_wait("learner", "-INT");
    let st = p.signal_and_wait("actor1", "-INT");
    assert!(st.success(), "actor exit: {st:?}{}", p.logs());
    let actor_out = p.read("actor1.out");
    assert!(
        actor_out.contains("acted with versions") && !actor_out.contains("1000000000"),
        "the actor acted with the forged version: {actor_out}"
    );
}
