//! Joins a running training from another process and prints what it sees: the learner's stats
//! (JSON) as they arrive, and once a second the learner's weights version by query (naming the
//! version already seen, so that an unchanged one costs a few bytes).
//!
//! ```text
//! dupac train                      # prints: learner (router on tcp/127.0.0.1:PORT)
//! cargo run -p dupac-node --example join_run -- tcp/127.0.0.1:PORT [RUN] [SECONDS]
//! ```
//!
//! RUN is `distributed.run` (default `default`, as the configuration's); SECONDS how long to
//! watch (default 30).

use dupac_common::jsonmsg::decode_json;
use dupac_common::keys::{KeySpace, Role};
use dupac_common::msg::{
    MsgLimits, STATS_BUDGET_BYTES, StatsMsg, WeightsHeld, WeightsMsg, decode_msg, held_value,
    is_kind,
};
use dupac_node::net::{ConnectOpts, Mode};
use std::time::{Duration, Instant};
use zenoh::Wait;

fn main() -> zenoh::Result<()> {
    let mut args = std::env::args().skip(1);
    let endpoint = args
        .next()
        .ok_or("usage: join_run tcp/HOST:PORT [RUN] [SECONDS]")?;
    let run = args.next().unwrap_or_else(|| "default".to_string());
    let seconds: u64 = args.next().map(|s| s.parse()).transpose()?.unwrap_or(30);

    // The connection arguments every DUPAC process takes.
    let session = ConnectOpts {
        mode: Some(Mode::Client),
        connect: vec![endpoint],
        no_multicast_scouting: true,
        ..ConnectOpts::default()
    }
    .open()?;
    let keys = KeySpace::new(&run);
    // Presence: the learner and `dupac monitor` see a monitor join.
    let _token = session
        .liveliness()
        .declare_token(keys.alive(Role::Monitor, &session.zid().to_string()))
        .wait()?;
    let stats_key = keys.stats_all();
    let _stats = session
        .declare_subscriber(keys.stats_all())
        .callback(move |s| {
            let limit = MsgLimits::both(STATS_BUDGET_BYTES);
            match decode_json::<StatsMsg>(&s.payload().to_bytes(), limit, &stats_key) {
                Ok(StatsMsg::Learner(l)) => println!(
                    "learner: update {}/{}, {:.0} env steps/s, {} chunks accepted, {} actors",
                    l.update,
                    l.total_updates,
                    l.env_steps_per_s,
                    l.accepted_chunks,
                    l.actors.len()
                ),
                Ok(StatsMsg::Actor(a)) => println!(
                    "actor {}: {:.0} steps/s, acting with version {}",
                    a.header.actor, a.steps_per_s, a.header.policy_version
                ),
                Err(e) => eprintln!("stats ignored: {e}"),
            }
        })
        .wait()?;

    let weights_limit = MsgLimits::both(256 << 20);
    let mut held: Option<(u64, u64)> = None;
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(seconds) {
        let selector = match held {
            Some((i, v)) => format!("{}?held={}", keys.weights(), held_value(i, v)),
            None => keys.weights(),
        };
        let replies = session
            .get(selector)
            .timeout(Duration::from_secs(2))
            .wait()?;
        while let Ok(reply) = replies.recv() {
            let Ok(sample) = reply.result() else { continue };
            let bytes = sample.payload().to_bytes();
            if is_kind::<WeightsHeld>(&bytes) {
                let h: WeightsHeld = decode_msg(&bytes, weights_limit, "weights")?;
                println!(
                    "weights: still version {} ({} bytes)",
                    h.header.policy_version,
                    bytes.len()
                );
            } else {
                let w: WeightsMsg = decode_msg(&bytes, weights_limit, "weights")?;
                println!(
                    "weights: version {} ({} bytes)",
                    w.policy.version,
                    bytes.len()
                );
                held = Some((w.header.learner_incarnation, w.policy.version));
            }
        }
        std::thread::sleep(Duration::from_secs(1));
    }
    session.close().wait()?;
    Ok(())
}
