//! The learner's side of the Zenoh actor/learner system.
//!
//! * zenoh's receive callback takes `dupac/<run>/traj/*` without ever blocking (a blocked
//!   `Block` sender gets its transport closed after 5 s): it drops messages over the chunk
//!   limit unread and queues the rest under byte budgets per sender and in total
//!   ([`InboxBudget`]; over budget, the sender's own oldest message goes, then the biggest
//!   holder's: `overflow`). A decode task decodes each within its allocation budget
//!   ([`MsgLimits::chunk`]), validates it ([`dupac_common::validate::validate_chunk`]),
//!   drops replays ([`SeqTracker`]: at most once per (actor, sender incarnation, seq)) and
//!   queues it for PPO (at most `distributed.queue_chunks`).
//! * [`LearnerNode::next_batch`] takes queued chunks until the batch (`train.num_envs ×
//!   train.num_steps` samples) is full, dropping data more than `distributed.max_policy_lag`
//!   versions old (`stale`).
//! * Weights are published with `CongestionControl::Block` and high priority, and served by a
//!   queryable for actors that join late; a liveliness token announces the learner; a
//!   liveliness subscriber tracks actors (joined, left, silent).
//! * Stats for monitors go to `dupac/<run>/stats/learner`; `Stop` goes to `dupac/<run>/ctrl`;
//!   both in JSON ([`dupac_common::jsonmsg`]) with zenoh's encoding `application/json`.
//! * Decoding, publishing and query replies are tasks on the node's network side
//!   ([`crate::netside`]): the PPO loop hands over encoded weights and stats and goes on.

use crate::inbox::{Inbox, InboxBudget, decode_task};
use crate::netside::{Latest, NetSide};
use crate::presence::{LOSS_GRACE, PresenceLog};
use dupac_common::config::Config;
use dupac_common::dedup::MAX_TRACKED_SENDERS;
use dupac_common::ids::ActorId;
use dupac_common::jsonmsg::encode_json;
use dupac_common::keys::{KeySpace, Role};
use dupac_common::msg::{
    ActorRow, ActorState, Command, ControlMsg, Header, LearnerStats, MsgLimits, TrajectoryChunk,
    WeightsMsg, encode_msg, unix_ms,
};
use dupac_common::policy::PolicyWeights;
use dupac_common::validate::{ChunkExpect, DropReason, SiteSteps};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::bytes::Encoding;
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

/// A token bucket: `rate` tokens a second, at most `burst` saved.
#[derive(Debug, Clone)]
pub struct TokenBucket {
    rate: f64,
    burst: f64,
    tokens: f64,
    at: Option<Instant>,
}

impl TokenBucket {
    pub fn new(rate: f64, burst: f64) -> TokenBucket {
        TokenBucket {
            rate,
            burst: burst.max(1.0),
            tokens: burst.max(1.0),
            at: None,
        }
    }

    /// Takes a token if there is one at `now`.
    pub fn take(&mut self, now: Instant) -> bool {
        if let Some(at) = self.at {
            let dt = now.saturating_duration_since(at).as_secs_f64();
            self.tokens = (self.tokens + dt * self.rate).min(self.burst);
        }
        self.at = Some(now);
        if self.tokens >= 1.0 {
            self.tokens -= 1.0;
            true
        } else {
            false
        }
    }
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

/// The learner's view of one actor.
#[derive(Debug, Clone)]
struct ActorInfo {
    state: ActorState,
    env_steps: u64,
    chunks: u64,
    last_version: u64,
    last_seen: Option<Instant>,
    steps_at_last_stats: u64,
}

impl ActorInfo {
    fn new() -> ActorInfo {
        ActorInfo {
            state: ActorState::Alive,
            env_steps: 0,
            chunks: 0,
            last_version: 0,
            last_seen: None,
            steps_at_last_stats: 0,
        }
    }
}

type ActorTable = Arc<Mutex<BTreeMap<ActorId, ActorInfo>>>;

/// The learner's Zenoh presence: subscriptions, publishers, queryable, liveliness.
pub struct LearnerNode {
    session: zenoh::Session,
    keys: KeySpace,
    expect: ChunkExpect,
    max_policy_lag: u64,
    silent_after: Duration,
    stats_every_s: f64,
    inbox: Arc<Inbox>,
    actors: ActorTable,
    weights: Latest,
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

/// Chunks taken for one batch.
pub struct BatchChunks {
    pub chunks: Vec<TrajectoryChunk>,
    /// Time spent waiting for data (s).
    pub wait_s: f64,
}

impl LearnerNode {
    /// Joins the run on `session` as its learner. `incarnation` is random per process start;
    /// `fingerprint` is [`Config::env_fingerprint`].
    pub fn start(
        session: zenoh::Session,
        cfg: &Config,
        obs_dim: usize,
        n_sites: usize,
        fingerprint: u64,
        incarnation: u64,
    ) -> Result<LearnerNode, NodeError> {
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
        let limits = MsgLimits::chunk(cfg, &expect);
        let budget = InboxBudget::new(
            limits,
            cfg.train.num_envs * cfg.train.num_steps,
            expect.max_envs * expect.max_steps,
            d.queue_chunks,
        );
        tracing::info!(
            message_bytes = limits.bytes,
            decode_budget_bytes = limits.budget_bytes,
            per_sender_bytes = budget.per_sender_bytes,
            total_bytes = budget.total_bytes,
            "receive limits"
        );
        let inbox = Arc::new(Inbox::new(budget));
        let closing = Arc::new(AtomicBool::new(false));
        let actors: ActorTable = Arc::default();

        let mut net = NetSide::new()
            .map_err(|e| NodeError::Zenoh(format!("cannot start the network side: {e}")))?;
        // zenoh's callback only queues (bounded by the byte budgets); a task decodes.
        let sub = {
            let (inbox, keys) = (inbox.clone(), keys.clone());
            session
                .declare_subscriber(keys.traj_all())
                .callback(move |sample| inbox.admit(&keys, &sample))
                .wait()
                .map_err(z)?
        };
        net.spawn(decode_task(
            inbox.clone(),
            closing.clone(),
            expect.clone(),
            limits,
        ));

        let weights = Latest::start(
            &mut net,
            session
                .declare_publisher(keys.weights())
                .congestion_control(CongestionControl::Block)
                .priority(Priority::InteractiveHigh)
                .wait()
                .map_err(z)?,
            "weights",
        );
        let stats = Latest::start(
            &mut net,
            session
                .declare_publisher(keys.stats_learner())
                .congestion_control(CongestionControl::Drop)
                .encoding(Encoding::APPLICATION_JSON)
                .wait()
                .map_err(z)?,
            "stats",
        );
        // Queries within the reply rate are passed to a task that replies with the newest
        // weights; over the rate, or while a burst of them waits, they go unanswered.
        let queryable = {
            let rate = d.weights_replies_per_s;
            let bucket = Mutex::new(TokenBucket::new(rate, 2.0 * rate));
            let burst = (2.0 * rate).ceil().clamp(1.0, 1024.0) as usize;
            let (tx, mut rx) = tokio::sync::mpsc::channel::<zenoh::query::Query>(burst);
            let (latest, key) = (weights.receiver(), keys.weights());
            net.spawn(async move {
                while let Some(query) = rx.recv().await {
                    let bytes = latest.borrow().as_ref().map(|(_, b)| b.clone());
                    if let Some(b) = bytes
                        && let Err(e) = query.reply(key.clone(), b).await
                    {
                        tracing::warn!("weights query: cannot reply: {e}");
                    }
                }
            });
            session
                .declare_queryable(keys.weights())
                .callback(move |query| {
                    if !bucket.lock().is_ok_and(|mut b| b.take(Instant::now())) {
                        tracing::debug!("weights query left unanswered: over the reply rate");
                    } else if tx.try_send(query).is_err() {
                        tracing::debug!("weights query left unanswered: a burst already waits");
                    }
                })
                .wait()
                .map_err(z)?
        };
        let token = session
            .liveliness()
            .declare_token(keys.alive(Role::Learner, &format!("{incarnation:016x}")))
            .wait()
            .map_err(z)?;
        let alive_sub = {
            let (actors, keys2) = (actors.clone(), keys.clone());
            let presence = PresenceLog::default();
            session
                .liveliness()
                .declare_subscriber(keys.alive_role(Role::Actor))
                .history(true)
                .callback(move |sample| {
                    let Some((_, id)) = keys2.parse_alive(sample.key_expr().as_str()) else {
                        return;
                    };
                    let Ok(id) = id.parse::<u32>() else { return };
                    let id = ActorId(id);
                    let Ok(mut t) = actors.lock() else { return };
                    if !t.contains_key(&id) && t.len() >= MAX_TRACKED_SENDERS {
                        tracing::warn!(actor = %id, "too many actor ids: liveliness ignored");
                        return;
                    }
                    let info = t.entry(id).or_insert_with(ActorInfo::new);
                    match sample.kind() {
                        SampleKind::Put => {
                            if !presence.back(&id.to_string(), &format!("actor {id}")) {
                                tracing::info!(actor = %id, "actor joined");
                            }
                            info.state = ActorState::Alive;
                        }
                        SampleKind::Delete => {
                            presence.left(
                                &id.to_string(),
                                format!(
                                    "actor {id} left {} s ago (its process ended or the network \
                                     parted it); training goes on with the others, it rejoins \
                                     by itself",
                                    LOSS_GRACE.as_secs()
                                ),
                            );
                            info.state = ActorState::Left;
                        }
                    }
                })
                .wait()
                .map_err(z)?
        };
        Ok(LearnerNode {
            session,
            keys,
            expect,
            max_policy_lag: d.max_policy_lag,
            // Validated to [0, 1 day]: the conversion cannot fail; a day if it did.
            silent_after: Duration::try_from_secs_f64(d.silent_after_s)
                .unwrap_or(Duration::from_secs(86_400)),
            stats_every_s: d.stats_every_s,
            inbox,
            actors,
            weights,
            stats,
            _token: token,
            _queryable: queryable,
            _alive_sub: alive_sub,
            _traj_sub: sub,
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
        let n = bytes.len();
        self.weights.set(bytes);
        Ok(n)
    }

    /// Takes queued chunks until `samples` samples for policy `version` are gathered, or
    /// `stop` is set (then `None`). Chunks older than `version − max_policy_lag`, or from a
    /// version the learner has not published, are dropped (`stale`). While waiting, `idle` is
    /// called every `distributed.stats_every_s` (to keep monitors informed).
    pub fn next_batch(
        &mut self,
        version: u64,
        samples: usize,
        stop: &AtomicBool,
        idle: &mut dyn FnMut(&mut LearnerNode),
    ) -> Option<BatchChunks> {
        let t0 = Instant::now();
        let mut chunks = Vec::new();
        let mut have = 0usize;
        while have < samples {
            if stop.load(Ordering::Relaxed) {
                return None;
            }
            if self.since_stats_s() >= self.stats_every_s {
                idle(self);
            }
            self.inbox.warnings.flush_due();
            let next = {
                let Ok(mut q) = self.inbox.queues.lock() else {
                    return None;
                };
                if q.decoded.is_empty() {
                    q = match self.inbox.ready.wait_timeout(q, Duration::from_millis(100)) {
                        Ok((q, _)) => q,
                        Err(_) => return None,
                    };
                }
                let r = q.decoded.pop_front();
                if let Some(r) = &r {
                    q.release(r.sender, r.charge);
                }
                r
            };
            let Some(r) = next else { continue };
            let c = r.chunk;
            let v = c.header.policy_version;
            if v > version || version - v > self.max_policy_lag {
                self.inbox.drop_one(DropReason::Stale);
                tracing::debug!(
                    actor = %c.header.actor,
                    chunk_version = v,
                    version,
                    "stale chunk dropped"
                );
                continue;
            }
            let n = c.samples();
            if let Ok(mut t) = self.actors.lock() {
                let a = t.entry(c.header.actor).or_insert_with(ActorInfo::new);
                a.env_steps += n as u64;
                a.chunks += 1;
                a.last_version = v;
                a.last_seen = Some(r.at);
            }
            self.accepted_chunks += 1;
            have += n;
            chunks.push(c);
        }
        Some(BatchChunks {
            chunks,
            wait_s: t0.elapsed().as_secs_f64(),
        })
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

    /// The actor table as monitors see it (silent actors marked).
    pub fn actor_rows(&mut self, version: u64) -> Vec<ActorRow> {
        let dt = self.last_stats.elapsed().as_secs_f64().max(1e-9);
        let Ok(mut t) = self.actors.lock() else {
            return Vec::new();
        };
        t.iter_mut()
            .map(|(id, a)| {
                let last_seen_s = a.last_seen.map(|s| s.elapsed().as_secs_f64());
                let state = match a.state {
                    ActorState::Alive | ActorState::Silent
                        if last_seen_s.is_none_or(|s| s > self.silent_after.as_secs_f64()) =>
                    {
                        ActorState::Silent
                    }
                    ActorState::Silent => ActorState::Alive,
                    s => s,
                };
                let steps_per_s = (a.env_steps - a.steps_at_last_stats) as f64 / dt;
                a.steps_at_last_stats = a.env_steps;
                ActorRow {
                    actor: *id,
                    state,
                    steps_per_s,
                    env_steps: a.env_steps,
                    chunks: a.chunks,
                    policy_lag: version.saturating_sub(a.last_version),
                    last_seen_s,
                }
            })
            .collect()
    }

    /// Actors whose liveliness token is present.
    pub fn alive_actors(&self) -> usize {
        self.actors
            .lock()
            .map(|t| t.values().filter(|a| a.state != ActorState::Left).count())
            .unwrap_or(0)
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
        let actors = self.actor_rows(update);
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
            Some(bytes) => session
                .put(ctrl, bytes)
                .encoding(Encoding::APPLICATION_JSON)
                .congestion_control(CongestionControl::Block)
                .priority(Priority::InteractiveHigh)
                .wait()
                .map_err(z),
            None => Ok(()),
        };
        let _ = session.close().wait();
        sent
    }
}

/// A random 64-bit incarnation id (time and process id through SplitMix64).
pub fn new_incarnation() -> u64 {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_nanos() as u64)
        .unwrap_or(0);
    dupac_common::seed::stream_seed(t, u64::from(std::process::id()), unix_ms())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_token_bucket_allows_its_burst_then_its_rate() {
        let t0 = Instant::now();
        let mut b = TokenBucket::new(10.0, 20.0);
        let burst = (0..100).filter(|_| b.take(t0)).count();
        assert_eq!(burst, 20);
        // One second later: 10 more.
        let later = t0 + Duration::from_secs(1);
        assert_eq!((0..100).filter(|_| b.take(later)).count(), 10);
        // Idle for a minute: never more than the burst.
        let much_later = later + Duration::from_secs(60);
        assert_eq!((0..100).filter(|_| b.take(much_later)).count(), 20);
    }
}
