//! The learner's side of the Zenoh actor/learner system.
//!
//! The rules live in zenoh-free modules; this one wires them to zenoh:
//!
//! * zenoh's receive callback takes `dupac/<run>/traj/*` without ever blocking (a blocked
//!   `Block` sender gets its transport closed after 5 s) into the [`Inbox`] (byte budgets per
//!   sender and in total); a decode task accepts each message ([`Acceptor`]: decoding within
//!   its budget, sender, validation, replays) into the inbox's decoded queue.
//! * [`LearnerNode::gather`] takes queued chunks until the batch (`train.num_envs ×
//!   train.num_steps` samples) is full, dropping stale ones ([`accept::is_stale`]).
//! * Weights are published with `CongestionControl::Drop` (a slow subscriber misses one and
//!   asks) and high priority, and served by a queryable ([`crate::weights_server`], within
//!   the [`TokenBucket`]'s rate) for actors that join late or missed a publication; a
//!   liveliness token announces the learner; a liveliness subscriber keeps the [`Roster`].
//! * Stats for monitors go to `dupac/<run>/stats/learner`; `Stop` goes to `dupac/<run>/ctrl`;
//!   both in JSON ([`dupac_common::jsonmsg`]) with zenoh's encoding `application/json`.
//! * Decoding, publishing and query replies are tasks on the node's network side
//!   ([`crate::netside`]): the PPO loop hands over encoded weights and stats and goes on.

use crate::accept::{self, Acceptor};
use crate::inbox::{Inbox, InboxBudget, decode_task};
use crate::netside::{Latest, NetSide};
use crate::presence::{LOSS_GRACE, PresenceLog};
use crate::ratelimit::TokenBucket;
use crate::roster::Roster;
use crate::weights_server::{self, ReplyCounts, Served, WeightsQuery};
use dupac_actor::expand::Expander;
use dupac_common::config::Config;
use dupac_common::ids::ActorId;
use dupac_common::jsonmsg::encode_json;
use dupac_common::keys::{KeySpace, Role};
use dupac_common::msg::{
    Command, ControlMsg, ExpandedChunk, HELD_PARAMETER, Header, LearnerStats, MsgLimits,
    WeightsHeld, WeightsMsg, encode_msg, unix_ms,
};
use dupac_common::policy::PolicyWeights;
use dupac_common::validate::{ChunkExpect, DropReason, SiteSteps};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::watch;
use zenoh::Wait;
use zenoh::bytes::{Encoding, ZBytes};
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::SampleKind;

/// Errors of the learner node.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    #[error("zenoh: {0}")]
    Zenoh(String),
    #[error(transparent)]
    Codec(#[from] dupac_common::codec::CodecError),
    #[error(
        "another learner is live on run {run:?} ({key}): stop it, or give this run another distributed.run"
    )]
    AnotherLearner { run: String, key: String },
}

/// The liveliness key of a live learner of this run, if any: asked twice a second apart, so a
/// learner that has just died (its token not yet withdrawn) does not block its successor.
fn live_learner(session: &zenoh::Session, keys: &KeySpace) -> Result<Option<String>, NodeError> {
    let mut found = None;
    for attempt in 0..2 {
        if attempt > 0 {
            std::thread::sleep(Duration::from_secs(1));
        }
        let replies = session
            .liveliness()
            .get(keys.alive_role(Role::Learner))
            .timeout(Duration::from_secs(2))
            .wait()
            .map_err(z)?;
        found = None;
        while let Ok(r) = replies.recv() {
            if let Ok(s) = r.result() {
                found = Some(s.key_expr().as_str().to_string());
            }
        }
        if found.is_none() {
            break;
        }
    }
    Ok(found)
}

fn z(e: impl std::fmt::Display) -> NodeError {
    NodeError::Zenoh(crate::net::zenoh_message(&e))
}

/// Weights replies sent at once at most (each on a blocking thread of its own).
const MAX_PARALLEL_REPLIES: usize = 64;

/// A zenoh weights query for the weights server.
struct ZenohQuery {
    query: zenoh::query::Query,
    key: String,
}

impl WeightsQuery for ZenohQuery {
    type Bytes = ZBytes;

    fn held(&self) -> Option<String> {
        self.query
            .parameters()
            .get(HELD_PARAMETER)
            .map(str::to_string)
    }

    fn reply(self, bytes: ZBytes) -> Result<(), String> {
        self.query
            .reply(self.key, bytes)
            .wait()
            .map_err(|e| crate::net::zenoh_message(&e))
    }
}

/// The learner's Zenoh presence: subscriptions, publishers, queryable, liveliness.
pub struct LearnerNode {
    session: zenoh::Session,
    keys: KeySpace,
    expect: ChunkExpect,
    max_policy_lag: u64,
    stats_every_s: f64,
    inbox: Arc<Inbox>,
    roster: Arc<Mutex<Roster>>,
    weights: Latest,
    /// The newest weights for the queryable.
    served: watch::Sender<Option<Served<ZBytes>>>,
    replies: Arc<ReplyCounts>,
    stats: Latest,
    _token: zenoh::liveliness::LivelinessToken,
    _queryable: zenoh::query::Queryable<()>,
    _alive_sub: zenoh::pubsub::Subscriber<()>,
    _traj_sub: zenoh::pubsub::Subscriber<()>,
    net: NetSide,
    closing: Arc<AtomicBool>,
    accepted_chunks: u64,
    stats_seq: u64,
    last_stats: Instant,
    updates_at_last_stats: u64,
    steps_at_last_stats: u64,
}

/// A batch being gathered from the inbox ([`LearnerNode::gather`]).
#[derive(Default)]
pub struct BatchChunks {
    pub chunks: Vec<ExpandedChunk>,
    /// Samples in `chunks`.
    pub samples: usize,
    /// Time spent waiting for data (s).
    pub wait_s: f64,
}

/// What [`LearnerNode::gather`] came back with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Gathered {
    /// The batch holds its samples.
    Full,
    /// The deadline came first (the batch keeps what it has).
    Due,
    /// `stop` was set.
    Stopped,
}

impl LearnerNode {
    /// Joins the run on `session` as its learner. `incarnation` is random per process start;
    /// `fingerprint` is [`Config::env_fingerprint`]; `expander` expands the received compact
    /// trajectories (the scenario's, `Expander::new`).
    pub fn start(
        session: zenoh::Session,
        cfg: &Config,
        expander: Expander,
        n_sites: usize,
        fingerprint: u64,
        incarnation: u64,
    ) -> Result<LearnerNode, NodeError> {
        let obs_dim = expander.layout().len();
        let d = &cfg.distributed;
        let keys = KeySpace::new(&d.run);
        // One learner per run name: actors would flip between two.
        if let Some(key) = live_learner(&session, &keys)? {
            return Err(NodeError::AnotherLearner {
                run: d.run.clone(),
                key,
            });
        }
        let expect = ChunkExpect {
            run_id: d.run.clone(),
            incarnation,
            fingerprint,
            obs_dim,
            n_sites,
            max_envs: d.actor_envs.max(cfg.train.num_envs),
            max_steps: d.chunk_steps.max(cfg.train.num_steps),
            site_steps: SiteSteps::of(cfg),
        };
        let mut net = NetSide::new()
            .map_err(|e| NodeError::Zenoh(format!("cannot start the network side: {e}")))?;
        let closing = Arc::new(AtomicBool::new(false));
        let (inbox, traj_sub) =
            receive_chunks(&session, &keys, cfg, &expect, expander, &mut net, &closing)?;
        // Drop, not Block: a subscriber behind a slow link misses a publication (and asks the
        // queryable) rather than holding back everyone's weights.
        let weights = publisher(&session, keys.weights(), CongestionControl::Drop, None)?;
        let weights = Latest::start(&mut net, weights, "weights");
        let json = Some(Encoding::APPLICATION_JSON);
        let stats = publisher(
            &session,
            keys.stats_learner(),
            CongestionControl::Drop,
            json,
        )?;
        let stats = Latest::start(&mut net, stats, "stats");
        let (served, _) = watch::channel(None);
        let replies = Arc::new(ReplyCounts::default());
        let queryable = serve_weights(&session, &keys, cfg, &served, &replies, &mut net)?;
        let token = session
            .liveliness()
            .declare_token(keys.alive(Role::Learner, &format!("{incarnation:016x}")))
            .wait()
            .map_err(z)?;
        // Validated to [0, 1 day]: the conversion cannot fail; a day if it did.
        let silent_after =
            Duration::try_from_secs_f64(d.silent_after_s).unwrap_or(Duration::from_secs(86_400));
        let roster = Arc::new(Mutex::new(Roster::new(silent_after)));
        let alive_sub = track_actors(&session, &keys, &roster)?;
        Ok(LearnerNode {
            session,
            keys,
            expect,
            max_policy_lag: d.max_policy_lag,
            stats_every_s: d.stats_every_s,
            inbox,
            roster,
            weights,
            served,
            replies,
            stats,
            _token: token,
            _queryable: queryable,
            _alive_sub: alive_sub,
            _traj_sub: traj_sub,
            net,
            closing,
            accepted_chunks: 0,
            stats_seq: 0,
            last_stats: Instant::now(),
            updates_at_last_stats: 0,
            steps_at_last_stats: 0,
        })
    }

    fn header(&self, version: u64) -> Header {
        let mut h = Header::new(
            &self.expect.run_id,
            self.expect.incarnation,
            ActorId::LEARNER,
            self.expect.fingerprint,
        );
        h.policy_version = version;
        h
    }

    /// Publishes `policy` (and keeps it for the queryable): encodes it and hands it to the
    /// network side, which publishes the newest weights it has. Returns the encoded size.
    pub fn publish_weights(&self, policy: &PolicyWeights) -> Result<usize, NodeError> {
        let msg = WeightsMsg {
            header: self.header(policy.version),
            policy: policy.clone(),
        };
        let bytes = encode_msg(&msg)?;
        let held = encode_msg(&WeightsHeld { header: msg.header })?;
        let n = bytes.len();
        let full = ZBytes::from(bytes);
        self.served.send_replace(Some(Served {
            incarnation: self.expect.incarnation,
            version: policy.version,
            full: full.clone(),
            held: held.into(),
        }));
        self.weights.set_bytes(full);
        Ok(n)
    }

    /// Weights query replies so far: (full weights, [`WeightsHeld`]).
    pub fn weights_replies(&self) -> (u64, u64) {
        self.replies.get()
    }

    /// Takes queued chunks into `batch` until it holds `samples` samples for policy `version`
    /// (`Full`), `until` passes (`Due`: the caller publishes its stats and gathers on) or
    /// `stop` is set. Stale chunks ([`accept::is_stale`]) are dropped and counted.
    pub fn gather(
        &mut self,
        batch: &mut BatchChunks,
        version: u64,
        samples: usize,
        stop: &AtomicBool,
        until: Instant,
    ) -> Gathered {
        let t0 = Instant::now();
        let result = loop {
            if batch.samples >= samples {
                break Gathered::Full;
            }
            if stop.load(Ordering::Relaxed) {
                break Gathered::Stopped;
            }
            if Instant::now() >= until {
                break Gathered::Due;
            }
            self.inbox.warnings.flush_due();
            let Some(r) = self.inbox.take(Duration::from_millis(100)) else {
                continue;
            };
            let v = r.chunk.header.policy_version;
            if accept::is_stale(v, version, self.max_policy_lag) {
                self.inbox.drop_one(DropReason::Stale);
                tracing::debug!(actor = %r.chunk.header.actor, chunk_version = v, version, "stale chunk dropped");
                continue;
            }
            let n = r.chunk.samples();
            if let Ok(mut roster) = self.roster.lock() {
                roster.accepted(r.chunk.header.actor, n, v, r.at);
            }
            self.accepted_chunks += 1;
            batch.samples += n;
            batch.chunks.push(r.chunk);
        };
        batch.wait_s += t0.elapsed().as_secs_f64();
        result
    }

    /// When the next stats message is due.
    pub fn stats_due_at(&self) -> Instant {
        self.last_stats + Duration::try_from_secs_f64(self.stats_every_s).unwrap_or_default()
    }

    /// Drops counted so far, by reason name.
    pub fn drops(&self) -> BTreeMap<String, u64> {
        let d = self
            .inbox
            .drops
            .lock()
            .map(|d| d.clone())
            .unwrap_or_default();
        d.into_iter()
            .map(|(k, v)| (k.as_str().to_string(), v))
            .collect()
    }

    /// Bytes of every trajectory message received so far (accepted or not).
    pub fn received_bytes(&self) -> u64 {
        self.inbox
            .received_bytes
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// Seconds the network side spent accepting trajectory messages so far (decoding,
    /// validating, expanding), and of them expanding.
    pub fn accept_s(&self) -> (f64, f64) {
        let s = |a: &std::sync::atomic::AtomicU64| {
            a.load(std::sync::atomic::Ordering::Relaxed) as f64 / 1e9
        };
        (s(&self.inbox.accept_ns), s(&self.inbox.expand_ns))
    }

    /// Actors whose liveliness token is present.
    pub fn alive_actors(&self) -> usize {
        self.roster.lock().map_or(0, |r| r.alive())
    }

    /// Publishes the learner's stats.
    pub fn publish_stats(
        &mut self,
        update: u64,
        total_updates: u64,
        global_step: u64,
        metrics: &BTreeMap<String, f64>,
        done: bool,
    ) -> Result<LearnerStats, NodeError> {
        let dt = self.last_stats.elapsed().as_secs_f64().max(1e-9);
        let actors = self
            .roster
            .lock()
            .map(|mut r| r.rows(update, Instant::now()))
            .unwrap_or_default();
        let mut header = self.header(update);
        header.seq = self.stats_seq;
        self.stats_seq += 1;
        let stats = LearnerStats {
            header,
            update,
            total_updates,
            global_step,
            updates_per_s: (update.saturating_sub(self.updates_at_last_stats)) as f64 / dt,
            env_steps_per_s: (global_step.saturating_sub(self.steps_at_last_stats)) as f64 / dt,
            accepted_chunks: self.accepted_chunks,
            drops: self.drops(),
            actors,
            metrics: metrics
                .iter()
                .filter(|(_, v)| v.is_finite())
                .map(|(k, v)| (k.clone(), *v))
                .collect(),
            done,
        };
        self.last_stats = Instant::now();
        self.updates_at_last_stats = update;
        self.steps_at_last_stats = global_step;
        self.stats.set(encode_json(&stats)?);
        Ok(stats)
    }

    /// Seconds since the last stats message.
    pub fn since_stats_s(&self) -> f64 {
        self.last_stats.elapsed().as_secs_f64()
    }

    /// Publishes what is still queued (the last weights and stats), stops the network side's
    /// tasks, then — with `stop_version`, a completed run — tells actors and followers that the
    /// run is over (the node's last message, so that they have the last weights first), and
    /// closes the session.
    pub fn close(self, stop_version: Option<u64>) -> Result<(), NodeError> {
        let stop = stop_version
            .map(|v| {
                encode_json(&ControlMsg {
                    header: self.header(v),
                    command: Command::Stop,
                })
            })
            .transpose()?;
        let ctrl = self.keys.ctrl();
        let last = self.served.borrow().as_ref().map(|s| s.full.clone());
        let weights_key = self.keys.weights();
        let LearnerNode {
            session,
            inbox,
            closing,
            weights,
            stats,
            net,
            _queryable,
            ..
        } = self;
        closing.store(true, Ordering::Relaxed);
        inbox.arrived.notify_one();
        inbox.warnings.flush();
        // Their senders gone, the publishing and replying tasks send what is left and end.
        drop((weights, stats, _queryable));
        net.finish(Duration::from_secs(5));
        let sent = match stop {
            Some(bytes) => {
                // The last weights once more, blocking (publications may drop): a follower has
                // them before the run's end.
                if let Some(w) = last {
                    let _ = session
                        .put(weights_key, w)
                        .congestion_control(CongestionControl::Block)
                        .priority(Priority::InteractiveHigh)
                        .wait();
                }
                session
                    .put(ctrl, bytes)
                    .encoding(Encoding::APPLICATION_JSON)
                    .congestion_control(CongestionControl::Block)
                    .priority(Priority::InteractiveHigh)
                    .wait()
                    .map_err(z)
            }
            None => Ok(()),
        };
        let _ = session.close().wait();
        sent
    }
}

/// The trajectory subscription: zenoh's callback only queues (bounded by the inbox's byte
/// budgets); the decode task on `net` accepts ([`Acceptor`]).
fn receive_chunks(
    session: &zenoh::Session,
    keys: &KeySpace,
    cfg: &Config,
    expect: &ChunkExpect,
    expander: Expander,
    net: &mut NetSide,
    closing: &Arc<AtomicBool>,
) -> Result<(Arc<Inbox>, zenoh::pubsub::Subscriber<()>), NodeError> {
    let limits = MsgLimits::chunk(cfg, expect);
    let budget = InboxBudget::new(
        limits,
        cfg.train.num_envs * cfg.train.num_steps,
        expect.max_envs * expect.max_steps,
        cfg.distributed.queue_chunks,
    );
    tracing::info!(
        message_bytes = limits.bytes,
        decode_budget_bytes = limits.budget_bytes,
        per_sender_bytes = budget.per_sender_bytes,
        total_bytes = budget.total_bytes,
        "receive limits"
    );
    let inbox = Arc::new(Inbox::new(budget));
    let sub = {
        let (inbox, keys) = (inbox.clone(), keys.clone());
        session
            .declare_subscriber(keys.traj_all())
            .callback(move |sample| inbox.admit(&keys, &sample))
            .wait()
            .map_err(z)?
    };
    let acceptor = Acceptor::new(expect.clone(), limits, Arc::new(expander));
    net.spawn(decode_task(inbox.clone(), closing.clone(), acceptor));
    Ok((inbox, sub))
}

/// A publisher on `key` with high priority when it carries weights.
fn publisher(
    session: &zenoh::Session,
    key: String,
    congestion: CongestionControl,
    encoding: Option<Encoding>,
) -> Result<zenoh::pubsub::Publisher<'static>, NodeError> {
    let b = session
        .declare_publisher(key)
        .congestion_control(congestion);
    let b = match encoding {
        Some(e) => b.encoding(e),
        None => b.priority(Priority::InteractiveHigh),
    };
    b.wait().map_err(z)
}

/// The weights queryable: queries within `distributed.weights_replies_per_s` go to the weights
/// server ([`crate::weights_server`]) on `net`; over the rate, or while a burst of them waits,
/// they go unanswered.
fn serve_weights(
    session: &zenoh::Session,
    keys: &KeySpace,
    cfg: &Config,
    served: &watch::Sender<Option<Served<ZBytes>>>,
    replies: &Arc<ReplyCounts>,
    net: &mut NetSide,
) -> Result<zenoh::query::Queryable<()>, NodeError> {
    let rate = cfg.distributed.weights_replies_per_s;
    let bucket = Mutex::new(TokenBucket::new(rate, 2.0 * rate));
    let burst = (2.0 * rate).ceil().clamp(1.0, 1024.0) as usize;
    let (tx, rx) = tokio::sync::mpsc::channel::<ZenohQuery>(burst);
    let parallel = burst.min(MAX_PARALLEL_REPLIES);
    net.spawn(weights_server::serve(
        rx,
        served.subscribe(),
        parallel,
        replies.clone(),
    ));
    let key = keys.weights();
    session
        .declare_queryable(keys.weights())
        .callback(move |query| {
            if !bucket.lock().is_ok_and(|mut b| b.take(Instant::now())) {
                tracing::debug!("weights query left unanswered: over the reply rate");
                return;
            }
            let q = ZenohQuery {
                query,
                key: key.clone(),
            };
            if tx.try_send(q).is_err() {
                tracing::debug!("weights query left unanswered: a burst already waits");
            }
        })
        .wait()
        .map_err(z)
}

/// The liveliness subscriber of the run's actors (with history: tokens declared before it
/// count), reporting to `roster` and the log (a blip at debug, a loss warned once).
fn track_actors(
    session: &zenoh::Session,
    keys: &KeySpace,
    roster: &Arc<Mutex<Roster>>,
) -> Result<zenoh::pubsub::Subscriber<()>, NodeError> {
    let (roster, keys2) = (roster.clone(), keys.clone());
    let presence = PresenceLog::default();
    session
        .liveliness()
        .declare_subscriber(keys.alive_role(Role::Actor))
        .history(true)
        .callback(move |sample| {
            let Some(id) = keys2
                .parse_alive(sample.key_expr().as_str())
                .and_then(|(_, id)| id.parse::<u32>().ok())
                .map(ActorId)
            else {
                return;
            };
            let present = sample.kind() == SampleKind::Put;
            if !roster.lock().is_ok_and(|mut r| r.presence(id, present)) {
                tracing::warn!(actor = %id, "too many actor ids: liveliness ignored");
                return;
            }
            if !present {
                presence.left(
                    &id.to_string(),
                    format!(
                        "actor {id} left {} s ago (its process ended or the network parted it); \
                         training goes on with the others, it rejoins by itself",
                        LOSS_GRACE.as_secs()
                    ),
                );
            } else if !presence.back(&id.to_string(), &format!("actor {id}")) {
                tracing::info!(actor = %id, "actor joined");
            }
        })
        .wait()
        .map_err(z)
}

/// A random 64-bit incarnation id (time and process id through SplitMix64).
pub fn new_incarnation() -> u64 {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    dupac_common::seed::stream_seed(t, u64::from(std::process::id()), unix_ms())
}
