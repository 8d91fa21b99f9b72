//! The actor's side of the Zenoh actor/learner system.
//!
//! An actor joins a run, fetches the latest weights by query, announces itself with a
//! liveliness token, steps `distributed.actor_envs` environments on its own thread pool (not on
//! zenoh's runtime), and publishes one [`TrajectoryChunk`] per `distributed.chunk_steps` steps
//! with `CongestionControl::Block` (the default `Drop` silently loses multi-MB messages) from a
//! task of its network side ([`crate::netside`]): the environments step the next chunk while
//! the last one is sent, and wait only when two are queued.
//! Weights arrive on a ring channel of 1 (only the newest matters) and are swapped between
//! chunks. The actor refuses weights whose configuration fingerprint differs from its own,
//! waits while no learner is alive, and follows a restarted learner (a new incarnation's
//! weights replace the old ones even with a lower version). Its stats, and the learner's
//! `Stop`, are JSON ([`dupac_common::jsonmsg`], zenoh encoding `application/json`).

use crate::netside::{Every, Latest, NetSide};
use dupac_actor::env::{Env, EnvError};
use dupac_actor::pairs::Pair;
use dupac_actor::rollout::{RolloutError, Worker};
use dupac_common::config::Config;
use dupac_common::ids::ActorId;
use dupac_common::jsonmsg::{decode_json, encode_json};
use dupac_common::keys::{KeySpace, Role};
use dupac_common::msg::EnvTrajectory;
use dupac_common::msg::{
    ActorStats, Command, ControlMsg, Header, MsgLimits, TrajectoryChunk, WeightsMsg, decode_msg,
    encode_msg, unix_ms,
};
use dupac_common::policy::PolicyWeights;
use dupac_common::seed::stream_seed;
use dupac_common::validate::{ChunkExpect, DropReason, SiteSteps, validate_weights};
use dupac_radio::cache::RsrpSource;
use dupac_radio::world::RadioWorld;
use rayon::prelude::*;
use std::collections::HashSet;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use zenoh::Wait;
use zenoh::bytes::Encoding;
use zenoh::handlers::{RingChannel, RingChannelHandler};
use zenoh::qos::CongestionControl;
use zenoh::sample::{Sample, SampleKind};

/// Errors of an actor.
#[derive(Debug, thiserror::Error)]
pub enum ActorError {
    #[error("zenoh: {0}")]
    Zenoh(String),
    #[error(transparent)]
    Env(#[from] EnvError),
    #[error(transparent)]
    Rollout(#[from] RolloutError),
    #[error(transparent)]
    Codec(#[from] dupac_common::codec::CodecError),
    #[error(
        "refusing to act for this learner: {0}. Start the actor with the learner's configuration (the same city, radio, environment and pairs settings)"
    )]
    Refused(String),
    #[error("cannot start the environment threads: {0}")]
    Threads(String),
}

/// Chunks queued for the network side before the environments wait (besides the one being sent).
const CHUNKS_IN_FLIGHT: usize = 2;

fn z(e: impl std::fmt::Display) -> ActorError {
    ActorError::Zenoh(crate::net::zenoh_message(&e))
}

/// How one actor process runs.
#[derive(Debug, Clone)]
pub struct ActorOptions {
    pub id: ActorId,
    /// Threads stepping the environments (≥ 1).
    pub threads: usize,
    /// Stop after this many chunks (0 = until the learner says stop).
    pub max_chunks: u64,
    /// Recorded chunks sent in turn instead of stepping the environments ([`read_recording`]):
    /// each under this actor's header as acted with the current version. An actor of unbounded
    /// speed, for the learner's scaling bench (`benches/learner_scaling.sh`).
    pub replay: Option<Arc<Vec<Vec<EnvTrajectory>>>>,
    /// Where to write the trajectories of the chunks this actor sent, when it stops
    /// ([`write_recording`]).
    pub record: Option<std::path::PathBuf>,
}

const RECORDING_MAGIC: &[u8; 8] = b"DUPACREC";
const RECORDING_VERSION: u32 = 1;
/// Most bytes a recording may have, and may allocate when read.
const RECORDING_MAX_BYTES: usize = 1 << 30;

/// Writes recorded chunks' trajectories to `path` (atomically).
pub fn write_recording(
    path: &std::path::Path,
    chunks: &[Vec<EnvTrajectory>],
) -> Result<(), ActorError> {
    let bytes = dupac_common::codec::encode(
        RECORDING_MAGIC,
        RECORDING_VERSION,
        &chunks,
        "recorded chunks",
    )?;
    dupac_common::codec::write_atomic(path, &bytes)?;
    Ok(())
}

/// Reads chunks written by [`write_recording`]; at least one.
pub fn read_recording(path: &std::path::Path) -> Result<Vec<Vec<EnvTrajectory>>, ActorError> {
    let bytes = dupac_common::codec::read_limited(path, RECORDING_MAX_BYTES)?;
    let chunks: Vec<Vec<EnvTrajectory>> = dupac_common::codec::decode_budgeted(
        RECORDING_MAGIC,
        RECORDING_VERSION,
        &bytes,
        RECORDING_MAX_BYTES,
        RECORDING_MAX_BYTES,
        &path.display().to_string(),
    )?;
    if chunks.is_empty() {
        return Err(ActorError::Refused(format!(
            "{}: a recording of no chunks",
            path.display()
        )));
    }
    Ok(chunks)
}

/// What an actor did, for its exit message.
#[derive(Debug, Clone, Default)]
pub struct ActorReport {
    pub chunks_sent: u64,
    pub env_steps: u64,
    pub swaps: u64,
    /// Policy versions acted with, in order of first use (the hot-swaps).
    pub versions: Vec<u64>,
    /// Weight messages refused (wrong shape, non-finite).
    pub refused_weights: u64,
    /// Shares sent again because the learner stayed at a version (`distributed.resend_after_s`).
    pub resent_shares: u64,
}

/// The weights in use and where they came from.
struct Current {
    policy: Arc<PolicyWeights>,
    incarnation: u64,
    sent_unix_ms: u64,
}

/// Decodes and checks a weights message; a fingerprint or run mismatch is fatal (`Refused`).
fn accept_weights(
    bytes: &[u8],
    expect: &ChunkExpect,
    limits: MsgLimits,
    origin: &str,
) -> Result<Option<WeightsMsg>, ActorError> {
    let w: WeightsMsg = match decode_msg(bytes, limits, origin) {
        Ok(w) => w,
        Err(e) => {
            tracing::warn!("weights ignored: {e}");
            return Ok(None);
        }
    };
    match validate_weights(&w, expect) {
        Ok(()) => Ok(Some(w)),
        Err(r) if matches!(r.reason, DropReason::Fingerprint | DropReason::WrongRun) => {
            Err(ActorError::Refused(r.detail))
        }
        Err(r) => {
            tracing::warn!("weights ignored: {r}");
            Ok(None)
        }
    }
}

/// Everything an actor holds on the Zenoh side.
struct Wiring {
    session: zenoh::Session,
    keys: KeySpace,
    weights: zenoh::pubsub::Subscriber<RingChannelHandler<Sample>>,
    learners: Arc<Mutex<HashSet<String>>>,
    /// Actors of the run with a liveliness token (this one included).
    actors: Arc<Mutex<HashSet<String>>>,
    stop: Arc<AtomicBool>,
    traj: Every,
    stats: Latest,
    net: NetSide,
    _token: zenoh::liveliness::LivelinessToken,
    _learner_sub: zenoh::pubsub::Subscriber<()>,
    _actors_sub: zenoh::pubsub::Subscriber<()>,
    _ctrl_sub: zenoh::pubsub::Subscriber<()>,
}

impl Wiring {
    fn new(session: zenoh::Session, cfg: &Config, id: ActorId) -> Result<Wiring, ActorError> {
        Wiring::with_role(session, cfg, id, Role::Actor)
    }

    fn new_pilot(session: zenoh::Session, cfg: &Config, id: ActorId) -> Result<Wiring, ActorError> {
        Wiring::with_role(session, cfg, id, Role::Pilot)
    }

    fn with_role(
        session: zenoh::Session,
        cfg: &Config,
        id: ActorId,
        role: Role,
    ) -> Result<Wiring, ActorError> {
        let keys = KeySpace::new(&cfg.distributed.run);
        let weights = session
            .declare_subscriber(keys.weights())
            .with(RingChannel::new(1))
            .wait()
            .map_err(z)?;
        let (learners, learner_sub) = track_alive(&session, &keys, Role::Learner, true)?;
        let (actors, actors_sub) = track_alive(&session, &keys, Role::Actor, false)?;
        let stop = Arc::new(AtomicBool::new(false));
        let ctrl_sub = {
            let (stop, limit) = (stop.clone(), MsgLimits::small(cfg));
            let key = keys.ctrl();
            session
                .declare_subscriber(keys.ctrl())
                .callback(move |s| {
                    match decode_json::<ControlMsg>(&s.payload().to_bytes(), limit, &key) {
                        Ok(m) if m.command == Command::Stop => {
                            tracing::info!("the learner ended the run");
                            stop.store(true, Ordering::Relaxed);
                        }
                        Ok(_) => {}
                        Err(e) => tracing::warn!("control message ignored: {e}"),
                    }
                })
                .wait()
                .map_err(z)?
        };
        let mut net = NetSide::new()
            .map_err(|e| ActorError::Zenoh(format!("cannot start the network side: {e}")))?;
        let traj = Every::start(
            &mut net,
            session
                .declare_publisher(keys.traj(id))
                .congestion_control(CongestionControl::Block)
                .wait()
                .map_err(z)?,
            CHUNKS_IN_FLIGHT,
            "trajectory chunk",
        );
        let stats = Latest::start(
            &mut net,
            session
                .declare_publisher(keys.stats_actor(id))
                .congestion_control(CongestionControl::Drop)
                .encoding(Encoding::APPLICATION_JSON)
                .wait()
                .map_err(z)?,
            "stats",
        );
        let token = session
            .liveliness()
            .declare_token(keys.alive(role, &id.0.to_string()))
            .wait()
            .map_err(z)?;
        Ok(Wiring {
            session,
            keys,
            weights,
            learners,
            actors,
            stop,
            traj,
            stats,
            net,
            _token: token,
            _learner_sub: learner_sub,
            _actors_sub: actors_sub,
            _ctrl_sub: ctrl_sub,
        })
    }

    /// Sends what is still queued, stops the network side and closes the session.
    fn close(self) {
        let Wiring {
            session,
            traj,
            stats,
            net,
            ..
        } = self;
        drop((traj, stats));
        net.finish(Duration::from_secs(5));
        let _ = session.close().wait();
    }

    fn actors_alive(&self) -> usize {
        self.actors.lock().map(|a| a.len()).unwrap_or(1).max(1)
    }

    fn learner_alive(&self) -> bool {
        self.learners.lock().map(|l| !l.is_empty()).unwrap_or(false)
    }

    /// Asks the learner's queryable for its latest weights.
    fn query_weights(
        &self,
        expect: &ChunkExpect,
        limit: MsgLimits,
    ) -> Result<Option<WeightsMsg>, ActorError> {
        let replies = self
            .session
            .get(self.keys.weights())
            .timeout(Duration::from_secs(2))
            .wait()
            .map_err(z)?;
        let mut best: Option<WeightsMsg> = None;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result()
                && let Some(w) = accept_weights(
                    &sample.payload().to_bytes(),
                    expect,
                    limit,
                    &self.keys.weights(),
                )?
                && best
                    .as_ref()
                    .is_none_or(|b| w.policy.version > b.policy.version)
            {
                best = Some(w);
            }
        }
        Ok(best)
    }
}

/// The ids of the processes of `role` whose liveliness token is present, kept current by a
/// liveliness subscriber (with history: tokens declared before it count); `log` reports joins
/// and departures.
#[allow(clippy::type_complexity)]
fn track_alive(
    session: &zenoh::Session,
    keys: &KeySpace,
    role: Role,
    log: bool,
) -> Result<(Arc<Mutex<HashSet<String>>>, zenoh::pubsub::Subscriber<()>), ActorError> {
    let present: Arc<Mutex<HashSet<String>>> = Arc::default();
    let (set, keys2) = (present.clone(), keys.clone());
    let sub = session
        .liveliness()
        .declare_subscriber(keys.alive_role(role))
        .history(true)
        .callback(move |s| {
            let Some((_, id)) = keys2.parse_alive(s.key_expr().as_str()) else {
                return;
            };
            let Ok(mut set) = set.lock() else { return };
            match s.kind() {
                SampleKind::Put => {
                    if log {
                        tracing::info!(%role, id, "present");
                    }
                    set.insert(id);
                }
                SampleKind::Delete => {
                    if log {
                        tracing::warn!(%role, id, "gone");
                    }
                    set.remove(&id);
                }
            }
        })
        .wait()
        .map_err(z)?;
    Ok((present, sub))
}

/// Runs one actor until the learner stops the run, `stop` is set, or `max_chunks` chunks are
/// sent. `fingerprint` is [`Config::env_fingerprint`] of this process's world.
#[allow(clippy::too_many_arguments)]
pub fn run_actor(
    session: zenoh::Session,
    cfg: &Config,
    world: Arc<RadioWorld>,
    rsrp: Arc<dyn RsrpSource + Send + Sync>,
    pool: Arc<Vec<Pair>>,
    fingerprint: u64,
    opts: &ActorOptions,
    stop: &AtomicBool,
) -> Result<ActorReport, ActorError> {
    let d = &cfg.distributed;
    let probe = Env::new(cfg, world.clone(), rsrp.clone())?;
    let (obs_dim, n_sites) = probe.policy_shape();
    let limit = MsgLimits::weights(cfg, obs_dim, n_sites);
    let expect = ChunkExpect {
        run_id: d.run.clone(),
        incarnation: 0,
        fingerprint,
        obs_dim: probe.layout().len(),
        n_sites,
        max_envs: d.actor_envs,
        max_steps: d.chunk_steps,
        site_steps: SiteSteps::of(cfg),
    };
    let wiring = Wiring::new(session, cfg, opts.id)?;
    let threads = rayon::ThreadPoolBuilder::new()
        .num_threads(opts.threads.max(1))
        .thread_name(|k| format!("dupac-env-{k}"))
        .build()
        .map_err(|e| ActorError::Threads(e.to_string()))?;
    // A restarted actor must not replay its earlier episodes: the salt differs per start.
    let salt = unix_ms() ^ u64::from(std::process::id()).rotate_left(32);
    // This process's id in chunk headers: the learner's replay check is per (actor, this).
    let sender_incarnation = stream_seed(salt, u64::from(opts.id.0), 0x5e9d_e1ca);
    // Training rollouts: the sphere grown by env.training_margin_m.
    let train_cfg = cfg.training();
    let mut workers: Vec<Worker> = (0..d.actor_envs)
        .map(|k| {
            let env = Env::new(&train_cfg, world.clone(), rsrp.clone())?;
            let stream = (u64::from(opts.id.0) << 20) | k as u64;
            Ok(Worker::new(
                k as u32,
                env,
                pool.clone(),
                stream_seed(cfg.train.seed, stream, salt),
            )?)
        })
        .collect::<Result<_, ActorError>>()?;

    let mut report = ActorReport::default();
    let mut recorded: Vec<Vec<EnvTrajectory>> = Vec::new();
    let mut current: Option<Current> = None;
    let mut seq = 0u64;
    let mut episodes = 0u64;
    let mut last_swap_latency_ms = None;
    let (mut last_stats, mut steps_at_stats) = (Instant::now(), 0u64);
    let mut waiting_logged = false;
    let batch = cfg.train.num_envs * cfg.train.num_steps;
    let cap = |actors: usize| d.chunks_per_version(batch, actors);
    let mut chunks_this_version = 0usize;
    let mut last_key: Option<(u64, u64)> = None;
    let mut last_weights_at = Instant::now();
    let mut swapped_at = Instant::now();
    let stopped = || stop.load(Ordering::Relaxed) || wiring.stop.load(Ordering::Relaxed);
    tracing::info!(actor = %opts.id, envs = d.actor_envs, "actor started; waiting for weights");
    while !stopped() {
        if opts.max_chunks > 0 && report.chunks_sent >= opts.max_chunks {
            break;
        }
        // Newest published weights (ring channel of 1), swapped at the chunk boundary. An actor
        // that has sent its share for this version waits for the next one.
        let at_cap = current.is_some() && chunks_this_version >= cap(wiring.actors_alive());
        let received = if at_cap {
            wiring.weights.recv_timeout(Duration::from_millis(50))
        } else {
            wiring.weights.try_recv()
        };
        let mut incoming: Option<WeightsMsg> = None;
        if let Ok(Some(sample)) = received {
            incoming = accept_weights(
                &sample.payload().to_bytes(),
                &expect,
                limit,
                &wiring.keys.weights(),
            )?;
            if incoming.is_none() {
                report.refused_weights += 1;
            }
        }
        let learner_alive = wiring.learner_alive();
        // Waiting long at the cap means a publication was missed (a learner that restarted
        // while this actor reconnected): ask the queryable, which always has the latest.
        if incoming.is_none() && at_cap && last_weights_at.elapsed() > Duration::from_secs(1) {
            incoming = wiring.query_weights(&expect, limit)?;
            last_weights_at = Instant::now();
            // Still the version this actor acts with: the learner is waiting for data, so
            // chunks of this share were lost (a router restart, a partition: delivery is at
            // most once). Produce another share rather than wait for ever.
            if let (Some(w), Some(c)) = (&incoming, &current)
                && w.header.learner_incarnation == c.incarnation
                && w.policy.version == c.policy.version
                && swapped_at.elapsed().as_secs_f64() > d.resend_after_s
            {
                tracing::info!(actor = %opts.id, version = c.policy.version, "the learner still waits at this version; sending another share");
                chunks_this_version = 0;
                swapped_at = Instant::now();
                report.resent_shares += 1;
            }
        }
        if current.is_none() || (!learner_alive && incoming.is_none()) {
            // Joining, or the learner is gone: ask for weights (a restarted learner answers).
            if let Some(w) = wiring.query_weights(&expect, limit)? {
                incoming = Some(w);
            }
            if incoming.is_none() {
                if !waiting_logged {
                    tracing::info!(actor = %opts.id, "no learner answers; waiting");
                    waiting_logged = true;
                }
                std::thread::sleep(Duration::from_millis(200));
                continue;
            }
        }
        if let Some(w) = incoming {
            let newer = match &current {
                None => true,
                Some(c) => {
                    w.header.learner_incarnation != c.incarnation
                        || w.policy.version > c.policy.version
                }
            };
            if newer {
                last_weights_at = Instant::now();
                if let Some(c) = &current
                    && w.header.learner_incarnation != c.incarnation
                {
                    tracing::info!(
                        actor = %opts.id,
                        version = w.policy.version,
                        "following a new learner incarnation"
                    );
                }
                current = Some(Current {
                    policy: Arc::new(w.policy),
                    incarnation: w.header.learner_incarnation,
                    sent_unix_ms: w.header.sent_unix_ms,
                });
                waiting_logged = false;
            }
        }
        let Some(cur) = &current else { continue };
        let version = cur.policy.version;
        let swapped = last_key != Some((cur.incarnation, version));
        if at_cap && !swapped {
            continue;
        }
        if swapped {
            last_key = Some((cur.incarnation, version));
            chunks_this_version = 0;
            swapped_at = Instant::now();
            // The first step acted with this version starts now.
            let latency_ms = unix_ms().saturating_sub(cur.sent_unix_ms) as f64;
            last_swap_latency_ms = Some(latency_ms);
            if !report.versions.is_empty() {
                report.swaps += 1;
            }
            report.versions.push(version);
            tracing::debug!(actor = %opts.id, version, latency_ms, "acting with new weights");
        }
        let policy = cur.policy.clone();
        let steps = d.chunk_steps;
        let trajectories: Vec<EnvTrajectory> = match &opts.replay {
            Some(chunks) => chunks[(report.chunks_sent % chunks.len() as u64) as usize].clone(),
            None => threads.install(|| {
                workers
                    .par_iter_mut()
                    .map(|w| w.collect(&policy, steps))
                    .collect::<Result<_, _>>()
            })?,
        };
        if opts.record.is_some() {
            recorded.push(trajectories.clone());
        }
        let mut header = Header::new(&d.run, cur.incarnation, opts.id, fingerprint);
        header.sender_incarnation = sender_incarnation;
        header.seq = seq;
        header.policy_version = version;
        let chunk = TrajectoryChunk {
            header,
            trajectories,
        };
        let n = chunk.samples() as u64;
        episodes += chunk
            .trajectories
            .iter()
            .map(|t| t.episodes.len() as u64)
            .sum::<u64>();
        wiring
            .traj
            .send(encode_msg(&chunk)?)
            .map_err(ActorError::Zenoh)?;
        seq += 1;
        chunks_this_version += 1;
        report.chunks_sent += 1;
        report.env_steps += n;

        if last_stats.elapsed().as_secs_f64() >= d.stats_every_s {
            let dt = last_stats.elapsed().as_secs_f64();
            let mut header = Header::new(&d.run, cur.incarnation, opts.id, fingerprint);
            header.sender_incarnation = sender_incarnation;
            header.policy_version = version;
            header.seq = seq;
            let stats = ActorStats {
                header,
                num_envs: d.actor_envs as u32,
                env_steps: report.env_steps,
                steps_per_s: (report.env_steps - steps_at_stats) as f64 / dt,
                chunks_sent: report.chunks_sent,
                swaps: report.swaps,
                last_swap_latency_ms,
                episodes,
            };
            wiring.stats.set(encode_json(&stats)?);
            last_stats = Instant::now();
            steps_at_stats = report.env_steps;
        }
    }
    wiring.close();
    if let Some(path) = &opts.record {
        write_recording(path, &recorded)?;
    }
    Ok(report)
}

/// A pilot that follows a run's weights (`dupac fly --follow`): the newest published version,
/// checked like an actor checks it, swapped in by the caller at a step boundary.
pub struct Follower {
    wiring: Wiring,
    expect: ChunkExpect,
    limit: MsgLimits,
    current: Option<(u64, u64)>,
}

impl Follower {
    /// Joins run `cfg.distributed.run` as a pilot; `obs_dim`/`n_sites` are what the flying
    /// environment needs.
    pub fn new(
        session: zenoh::Session,
        cfg: &Config,
        fingerprint: u64,
        obs_dim: usize,
        n_sites: usize,
    ) -> Result<Follower, ActorError> {
        let d = &cfg.distributed;
        let id = ActorId(u32::MAX - 1 - (std::process::id() % 1_000_000));
        let wiring = Wiring::new_pilot(session, cfg, id)?;
        Ok(Follower {
            wiring,
            expect: ChunkExpect {
                run_id: d.run.clone(),
                incarnation: 0,
                fingerprint,
                obs_dim,
                n_sites,
                max_envs: d.actor_envs,
                max_steps: d.chunk_steps,
                site_steps: SiteSteps::of(cfg),
            },
            limit: MsgLimits::weights(cfg, obs_dim, n_sites),
            current: None,
        })
    }

    /// Waits (up to `timeout`) for the learner's current weights by query.
    pub fn initial(&mut self, timeout: Duration) -> Result<Option<PolicyWeights>, ActorError> {
        let t0 = Instant::now();
        while t0.elapsed() < timeout {
            if let Some(w) = self.wiring.query_weights(&self.expect, self.limit)? {
                self.current = Some((w.header.learner_incarnation, w.policy.version));
                return Ok(Some(w.policy));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        Ok(None)
    }

    /// Newer weights than the ones in use, if any arrived.
    pub fn newer(&mut self) -> Result<Option<PolicyWeights>, ActorError> {
        let Ok(Some(sample)) = self.wiring.weights.try_recv() else {
            return Ok(None);
        };
        let Some(w) = accept_weights(
            &sample.payload().to_bytes(),
            &self.expect,
            self.limit,
            &self.wiring.keys.weights(),
        )?
        else {
            return Ok(None);
        };
        let key = (w.header.learner_incarnation, w.policy.version);
        let newer = match self.current {
            None => true,
            Some((inc, v)) => key.0 != inc || key.1 > v,
        };
        if newer {
            self.current = Some(key);
            Ok(Some(w.policy))
        } else {
            Ok(None)
        }
    }

    /// The learner ended the run.
    pub fn stopped(&self) -> bool {
        self.wiring.stop.load(Ordering::Relaxed)
    }
}
