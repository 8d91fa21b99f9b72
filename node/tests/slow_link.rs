//! The learner's weights on a slow link, over real zenoh sessions (a learner router on
//! loopback, clients connected directly and through `dupac_relay`'s rate cap): a subscriber
//! behind a slow link delays nobody else's weights, and a query from a process that holds the
//! newest weights is answered in a few bytes.

use dupac_actor::expand::Expander;
use dupac_common::config::Config;
use dupac_common::geometry::{Bounds2, Point, Point2};
use dupac_common::ids::ActorId;
use dupac_common::msg::{MsgLimits, WeightsHeld, WeightsMsg, decode_msg, held_value, is_kind};
use dupac_common::normalize::{ObsNormalizer, RewardScaler};
use dupac_common::obs::OBS_VERSION;
use dupac_common::policy::mlp::{Dense, Mlp};
use dupac_common::policy::{MOVE_DIM, PolicyWeights};
use dupac_node::learner::LearnerNode;
use dupac_node::net::{ConnectOpts, Mode};
use dupac_relay::{LinkImpairment, Relay, RelayConfig};
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::Wait;

const OBS: usize = 8;
const INCARNATION: u64 = 0x5eed;

/// A free TCP port on loopback.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .map(|a| a.port())
        .expect("a free port")
}

fn open(mode: Mode, connect: Option<SocketAddr>, listen: Option<u16>) -> zenoh::Session {
    ConnectOpts {
        mode: Some(mode),
        connect: connect.map(|a| format!("tcp/{a}")).into_iter().collect(),
        listen: listen
            .map(|p| format!("tcp/127.0.0.1:{p}"))
            .into_iter()
            .collect(),
        no_multicast_scouting: true,
        ..ConnectOpts::default()
    }
    .open()
    .expect("session")
}

/// A policy of `hidden` × (`OBS` + 3) actor weights (≈ 2·hidden·(OBS + 3) bytes on the wire).
fn policy(version: u64, hidden: usize) -> PolicyWeights {
    let dense = |n_in: usize, n_out: usize| Dense {
        n_in,
        n_out,
        weight: (0..n_in * n_out).map(|i| (i as f32 * 0.37).sin()).collect(),
        bias: vec![0.0; n_out],
    };
    PolicyWeights {
        version,
        obs_version: OBS_VERSION,
        obs_dim: OBS,
        n_sites: 0,
        actor: Mlp {
            layers: vec![dense(OBS, hidden), dense(hidden, MOVE_DIM)],
        },
        critic: Mlp {
            layers: vec![dense(OBS, 4), dense(4, 1)],
        },
        site_head: None,
        log_std: [-0.5; MOVE_DIM],
        obs_norm: ObsNormalizer::new(OBS, true, 5.0),
        reward_scaler: RewardScaler::new(true, 0.95, 10.0),
        observation: None,
    }
}

fn learner(port: u16) -> LearnerNode {
    let mut cfg = Config::default();
    cfg.distributed.run = "slowlink".into();
    // No trajectory flows in these tests: any scenario's expansion does.
    let area = Bounds2 {
        min_m: Point2::new(0.0, 0.0),
        max_m: Point2::new(100.0, 100.0),
    };
    let expander = Expander::of_sites(&cfg, area, vec![Point::new(50.0, 50.0, 30.0)]);
    LearnerNode::start(
        open(Mode::Router, None, Some(port)),
        &cfg,
        expander,
        0,
        1,
        INCARNATION,
    )
    .expect("learner node")
}

/// Subscribes `session` to the run's weights: the versions received, in order.
fn versions(session: &zenoh::Session) -> (Arc<Mutex<Vec<u64>>>, zenoh::pubsub::Subscriber<()>) {
    let got: Arc<Mutex<Vec<u64>>> = Arc::default();
    let sink = got.clone();
    let sub = session
        .declare_subscriber("dupac/slowlink/weights")
        .callback(move |s| {
            let bytes = s.payload().to_bytes();
            if let Ok(w) = decode_msg::<WeightsMsg>(&bytes, MsgLimits::both(64 << 20), "weights")
                && let Ok(mut g) = sink.lock()
            {
                g.push(w.policy.version);
            }
        })
        .wait()
        .expect("subscriber");
    (got, sub)
}

fn newest(v: &Mutex<Vec<u64>>) -> u64 {
    v.lock().map_or(0, |v| v.iter().copied().max().unwrap_or(0))
}

/// Waits up to `t` for `ok`.
fn wait_for(t: Duration, ok: impl Fn() -> bool) -> bool {
    let t0 = Instant::now();
    while t0.elapsed() < t {
        if ok() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    ok()
}

/// Weights are published with congestion control Drop: a subscriber whose link is full misses
/// publications (it asks the queryable) instead of stalling the learner's publisher, and with
/// it everyone else's weights. With Block, the publisher waits on the slow link's queue (zenoh
/// closes that link only after 5 s) and the fast subscriber stops at the first versions.
#[test]
fn a_slow_subscriber_delays_nobody_elses_weights() {
    let port = free_port();
    let node = learner(port);
    let upstream: SocketAddr = ([127, 0, 0, 1], port).into();
    // 20 kB/s towards the slow subscriber: one 1.4 MB publication takes 70 s.
    let relay = Relay::start(RelayConfig {
        down: LinkImpairment::NONE.with_rate(20_000),
        max_queued_bytes: 2 * RelayConfig::DEFAULT_READ_CHUNK_BYTES,
        ..RelayConfig::new(([127, 0, 0, 1], 0).into(), upstream)
    })
    .expect("relay");
    let slow = open(Mode::Client, Some(relay.local_addr()), None);
    let fast = open(Mode::Client, Some(upstream), None);
    let (slow_got, _slow_sub) = versions(&slow);
    let (fast_got, _fast_sub) = versions(&fast);
    // Both subscriptions reach the learner's router (declarations go up the slow link
    // unimpaired).
    std::thread::sleep(Duration::from_secs(1));
    let hidden = 2 << 20 >> 2 >> 3; // ≈ 1.4 MB on the wire
    let last = 30;
    for v in 1..=last {
        node.publish_weights(&policy(v, hidden)).expect("publish");
        std::thread::sleep(Duration::from_millis(100));
    }
    // Each publication leaves 100 ms after the last: all of them reach the fast subscriber
    // unless the publisher waits on the slow link.
    wait_for(Duration::from_millis(1500), || newest(&fast_got) == last);
    let fast_versions = fast_got.lock().map(|v| v.len()).unwrap_or(0);
    eprintln!("the fast subscriber got {fast_versions} of {last} publications");
    assert!(
        fast_versions >= 20,
        "the fast subscriber got {fast_versions} of {last} publications (newest {}); the slow \
         one {:?}",
        newest(&fast_got),
        slow_got.lock().map(|v| v.clone()).unwrap_or_default()
    );
    drop((slow, relay));
    node.close(None).expect("close");
}

/// An actor that holds the learner's newest weights asks for them with `held=…` and gets the
/// header alone; any other query gets the whole weights.
#[test]
fn a_query_for_weights_already_held_gets_a_small_reply() {
    let port = free_port();
    let node = learner(port);
    let client = open(Mode::Client, Some(([127, 0, 0, 1], port).into()), None);
    let ask = |params: &str| -> Vec<Vec<u8>> {
        for _ in 0..20 {
            // A client's query right after connecting can end with no reply: ask again.
            let selector = format!("dupac/slowlink/weights{params}");
            let replies = client
                .get(selector)
                .timeout(Duration::from_secs(2))
                .wait()
                .expect("query");
            let got: Vec<Vec<u8>> = std::iter::from_fn(|| replies.recv().ok())
                .filter_map(|r| r.result().ok().map(|s| s.payload().to_bytes().into_owned()))
                .collect();
            if !got.is_empty() {
                return got;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        panic!("no reply to {params:?}");
    };
    node.publish_weights(&policy(4, 1024)).expect("publish");
    let full = ask("");
    assert!(
        full[0].len() > 10_000,
        "the whole weights: {} bytes",
        full[0].len()
    );
    assert!(decode_msg::<WeightsMsg>(&full[0], MsgLimits::both(1 << 20), "w").is_ok());
    let held = ask(&format!("?held={}", held_value(INCARNATION, 4)));
    assert!(is_kind::<WeightsHeld>(&held[0]), "a 'held' reply");
    assert!(held[0].len() < 200, "{} bytes", held[0].len());
    let h: WeightsHeld = decode_msg(&held[0], MsgLimits::both(1 << 10), "w").expect("decodes");
    assert_eq!(
        (
            h.header.learner_incarnation,
            h.header.policy_version,
            h.header.actor
        ),
        (INCARNATION, 4, ActorId::LEARNER)
    );
    let older = ask(&format!("?held={}", held_value(INCARNATION, 3)));
    assert!(
        is_kind::<WeightsMsg>(&older[0]),
        "an older version gets the weights"
    );
    // The counts follow each reply on its own thread.
    // (A query asked again after a reply too late to count adds a full one.)
    assert!(
        wait_for(Duration::from_secs(10), || {
            let (full, held) = node.weights_replies();
            full >= 2 && held == 1
        }),
        "replies (full, held): {:?}",
        node.weights_replies()
    );
    node.close(None).expect("close");
}
