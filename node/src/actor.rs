//! The actor's side of the Zenoh actor/learner system.
//!
//! An actor joins a run, fetches the latest weights by query, announces itself with a
//! liveliness token, steps `distributed.actor_envs` environments on its own thread pool (not on
//! zenoh's runtime), and publishes one [`TrajectoryChunk`] per `distributed.chunk_steps` steps
//! with `CongestionControl::Block` (the default `Drop` silently loses multi-MB messages) from a
//! task of its network side ([`crate::netside`]): the environments step the next chunk while
//! the last one is sent, and wait only when two are queued.
//! Weights arrive on a ring channel of 1 (only the newest matters) and are swapped between
//! chunks; publications may be dropped on a full link, so an actor that has heard none for a
//! while ([`crate::ask_clock`]: twice the run's interval between versions, 1 to 5 s) asks the
//! queryable, naming the weights it holds (an unchanged version costs a few bytes). The actor refuses weights whose configuration fingerprint differs from its own,
//! waits while no learner is alive, and follows a restarted learner (a new incarnation's
//! weights replace the old ones even with a lower version). Its stats, and the learner's
//! `Stop`, are JSON ([`dupac_common::jsonmsg`], zenoh encoding `application/json`).

use crate::ask_clock::AskClock;
use crate::intake::{Answer, Offer, WeightsIntake, WeightsKey};
use crate::netside::Outgoing;
use crate::outbox::ChunkOutbox;
use crate::wiring::Wiring;
use dupac_actor::env::Env;
use dupac_actor::pairs::Pair;
use dupac_actor::rollout::Worker;
use dupac_common::compact::CompactTrajectory;
use dupac_common::config::Config;
use dupac_common::ids::ActorId;
use dupac_common::jsonmsg::encode_json;
use dupac_common::msg::{ActorStats, MsgLimits, TrajectoryChunk, encode_msg, unix_ms};
use dupac_common::policy::PolicyWeights;
use dupac_common::seed::stream_seed;
use dupac_common::validate::{ChunkExpect, SiteSteps};
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use rayon::prelude::*;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

pub use crate::actor_error::ActorError;

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
    pub replay: Option<Arc<Vec<Vec<CompactTrajectory>>>>,
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
    chunks: &[Vec<CompactTrajectory>],
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
pub fn read_recording(path: &std::path::Path) -> Result<Vec<Vec<CompactTrajectory>>, ActorError> {
    let bytes = dupac_common::codec::read_limited(path, RECORDING_MAX_BYTES)?;
    let chunks: Vec<Vec<CompactTrajectory>> = dupac_common::codec::decode_budgeted(
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
    /// Bytes of the chunks sent (as encoded, before zenoh's framing).
    pub chunk_bytes: u64,
    pub env_steps: u64,
    pub swaps: u64,
    /// Policy versions acted with, in order of first use (the hot-swaps).
    pub versions: Vec<u64>,
    /// Weight messages refused (wrong shape, non-finite).
    pub refused_weights: u64,
    /// Shares sent again because the learner stayed at a version (`distributed.resend_after_s`).
    pub resent_shares: u64,
    /// Chunks not sent: stale (`distributed.max_policy_lag`) by the time their turn came.
    pub stale_unsent: u64,
}

/// What a process expects of its weights: `cfg`'s run and chunk sizes, the environment
/// `fingerprint`, a policy of `obs_dim` observations and `n_sites` site logits.
fn weights_intake(cfg: &Config, fingerprint: u64, obs_dim: usize, n_sites: usize) -> WeightsIntake {
    let d = &cfg.distributed;
    let expect = ChunkExpect {
        run_id: d.run.clone(),
        incarnation: 0,
        fingerprint,
        obs_dim,
        n_sites,
        max_envs: d.actor_envs,
        max_steps: d.chunk_steps,
        site_steps: SiteSteps::of(cfg),
    };
    WeightsIntake::new(expect, MsgLimits::weights(cfg, obs_dim, n_sites))
}

/// The weights an actor acts with, kept current from the learner's publications and its
/// queryable.
struct Acting {
    intake: WeightsIntake,
    /// The policy in use and when the learner sent it (Unix ms).
    policy: Option<(Arc<PolicyWeights>, u64)>,
    ask: AskClock,
    waiting_logged: bool,
}

impl Acting {
    fn new(intake: WeightsIntake) -> Acting {
        Acting {
            intake,
            policy: None,
            ask: AskClock::new(Instant::now()),
            waiting_logged: false,
        }
    }

    /// One turn of the actor's loop: takes the newest weights (waiting briefly for them when
    /// this version's share is sent: `at_cap`), asks the queryable when a publication may have
    /// been missed or no learner is alive (and starts a new share when the learner is still at
    /// this version: the last one was lost), and waits when there are no weights at all.
    /// `false`: nothing to act with yet.
    fn update(
        &mut self,
        wiring: &Wiring,
        outbox: &mut ChunkOutbox,
        at_cap: bool,
        report: &mut ActorReport,
    ) -> Result<bool, ActorError> {
        let wait = at_cap.then_some(Duration::from_millis(50));
        let mut incoming = wiring.receive_weights(&mut self.intake, wait)?;
        // Publications may be dropped on a slow link: an actor that has heard nothing for a
        // while asks (a few bytes when it holds the newest weights).
        if incoming.is_none() && self.ask.due(Instant::now()) {
            let answer = wiring.query_weights(&mut self.intake)?;
            self.ask.asked(Instant::now());
            if let Some(a) = &answer {
                wiring.learner_at(a.learner_at());
                if let Some((seq, at)) = wiring.last_left() {
                    outbox.left(seq, at);
                }
                if at_cap && outbox.resend_if_lost(a.learner_at()) {
                    tracing::info!(
                        version = a.learner_at().version,
                        "the learner still waits at this version; sending another share"
                    );
                    report.resent_shares += 1;
                }
            }
            incoming = answer.and_then(Answer::into_weights);
        }
        if self.policy.is_none() || (!wiring.learner_alive() && incoming.is_none()) {
            // Joining, or the learner is gone: ask for weights (a restarted learner answers).
            if let Some(w) = wiring
                .query_weights(&mut self.intake)?
                .and_then(Answer::into_weights)
            {
                incoming = Some(w);
            }
            if incoming.is_none() {
                if !self.waiting_logged {
                    tracing::info!("no learner answers; waiting");
                    self.waiting_logged = true;
                }
                std::thread::sleep(Duration::from_millis(200));
                return Ok(false);
            }
        }
        if let Some(w) = incoming {
            let offer = self.intake.offer(WeightsKey::of(&w));
            if offer == Offer::NewIncarnation {
                tracing::info!(
                    version = w.policy.version,
                    "following a new learner incarnation"
                );
            }
            if offer != Offer::Stale {
                // Only weights taken say where the learner is (a late publication of an earlier
                // incarnation would make every fresh chunk look stale).
                wiring.learner_at(WeightsKey::of(&w));
                self.ask.took(Instant::now());
                self.policy = Some((Arc::new(w.policy), w.header.sent_unix_ms));
                self.waiting_logged = false;
            }
        }
        Ok(self.policy.is_some())
    }
}

/// An actor's environments on their own thread pool (or a recording replayed in their place),
/// and the chunks kept for `--record`.
struct Rollouts {
    threads: rayon::ThreadPool,
    workers: Vec<Worker>,
    steps: usize,
    replay: Option<Arc<Vec<Vec<CompactTrajectory>>>>,
    recorded: Option<Vec<Vec<CompactTrajectory>>>,
}

impl Rollouts {
    /// `distributed.actor_envs` training environments seeded from `train.seed`, the actor's id
    /// and `salt` (new per start: a restarted actor does not replay its earlier episodes).
    fn new(
        cfg: &Config,
        world: &Arc<RadioWorld>,
        rsrp: &Arc<dyn RsrpSource + Send + Sync>,
        pool: &Arc<Vec<Pair>>,
        opts: &ActorOptions,
        salt: u64,
    ) -> Result<Rollouts, ActorError> {
        let threads = rayon::ThreadPoolBuilder::new()
            .num_threads(opts.threads.max(1))
            .thread_name(|k| format!("dupac-env-{k}"))
            .build()
            .map_err(|e| ActorError::Threads(e.to_string()))?;
        // Training rollouts: the sphere grown by env.training_margin_m.
        let train_cfg = cfg.training();
        let workers = (0..cfg.distributed.actor_envs)
            .map(|k| {
                let env = Env::new(&train_cfg, world.clone(), rsrp.clone())?;
                let stream = (u64::from(opts.id.0) << 20) | k as u64;
                let seed = stream_seed(cfg.train.seed, stream, salt);
                Ok(Worker::new(k as u32, env, pool.clone(), seed)?)
            })
            .collect::<Result<_, ActorError>>()?;
        Ok(Rollouts {
            threads,
            workers,
            steps: cfg.distributed.chunk_steps,
            replay: opts.replay.clone(),
            recorded: opts.record.as_ref().map(|_| Vec::new()),
        })
    }

    /// The next chunk's trajectories acted with `policy` (chunk `index` of a replay).
    fn collect(
        &mut self,
        policy: &Arc<PolicyWeights>,
        index: u64,
    ) -> Result<Vec<CompactTrajectory>, ActorError> {
        let trajectories: Vec<CompactTrajectory> = match &self.replay {
            Some(chunks) => chunks[(index % chunks.len() as u64) as usize].clone(),
            None => {
                let (workers, steps) = (&mut self.workers, self.steps);
                self.threads.install(|| {
                    workers
                        .par_iter_mut()
                        .map(|w| w.collect(policy, steps))
                        .collect::<Result<_, _>>()
                })?
            }
        };
        if let Some(r) = &mut self.recorded {
            r.push(trajectories.clone());
        }
        Ok(trajectories)
    }
}

/// An actor's statistics since its start, published every `distributed.stats_every_s`.
struct StatsClock {
    every_s: f64,
    last: Instant,
    steps_at_last: u64,
    episodes: u64,
    last_swap_latency_ms: Option<f64>,
}

impl StatsClock {
    /// Stats due every `every_s` seconds from now.
    fn new(every_s: f64) -> StatsClock {
        StatsClock {
            every_s,
            last: Instant::now(),
            steps_at_last: 0,
            episodes: 0,
            last_swap_latency_ms: None,
        }
    }

    /// Counts a chunk's episodes.
    fn sent(&mut self, chunk: &TrajectoryChunk) {
        self.episodes += chunk
            .trajectories
            .iter()
            .map(|t| t.episodes.len() as u64)
            .sum::<u64>();
    }

    /// The stats to publish when they are due.
    fn due(
        &mut self,
        report: &ActorReport,
        outbox: &ChunkOutbox,
        num_envs: usize,
    ) -> Option<ActorStats> {
        let dt = self.last.elapsed().as_secs_f64();
        if dt < self.every_s {
            return None;
        }
        let stats = ActorStats {
            header: outbox.header(outbox.acting()?),
            num_envs: num_envs as u32,
            env_steps: report.env_steps,
            steps_per_s: (report.env_steps - self.steps_at_last) as f64 / dt,
            chunks_sent: report.chunks_sent,
            swaps: report.swaps,
            last_swap_latency_ms: self.last_swap_latency_ms,
            episodes: self.episodes,
        };
        self.last = Instant::now();
        self.steps_at_last = report.env_steps;
        Some(stats)
    }
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
    let (obs_dim, n_sites) = Env::new(cfg, world.clone(), rsrp.clone())?.policy_shape();
    let wiring = Wiring::new(session, cfg, opts.id)?;
    // A restarted actor must not replay its earlier episodes: the salt differs per start, and
    // the chunks' sender id (the learner's replay check is per actor and sender) with it.
    let salt = unix_ms() ^ u64::from(std::process::id()).rotate_left(32);
    let mut rollouts = Rollouts::new(cfg, &world, &rsrp, &pool, opts, salt)?;
    let sender = stream_seed(salt, u64::from(opts.id.0), 0x5e9d_e1ca);
    let resend_after = Duration::from_secs_f64(d.resend_after_s);
    let mut outbox = ChunkOutbox::new(&d.run, opts.id, fingerprint, sender, resend_after);
    let mut acting = Acting::new(weights_intake(cfg, fingerprint, obs_dim, n_sites));
    let (mut report, mut stats) = (ActorReport::default(), StatsClock::new(d.stats_every_s));
    let cap =
        |actors: usize| d.chunks_per_version(cfg.train.num_envs * cfg.train.num_steps, actors);
    tracing::info!(actor = %opts.id, envs = d.actor_envs, "actor started; waiting for weights");
    while !(stop.load(Ordering::Relaxed) || wiring.stopped()) {
        if opts.max_chunks > 0 && report.chunks_sent >= opts.max_chunks {
            break;
        }
        let at_cap = outbox.at_cap(cap(wiring.actors_alive()));
        if !acting.update(&wiring, &mut outbox, at_cap, &mut report)? {
            continue;
        }
        let (Some((policy, sent_unix_ms)), Some(key)) =
            (acting.policy.clone(), acting.intake.current())
        else {
            continue;
        };
        if outbox.swap(key) {
            // The first step acted with this version starts now.
            let latency_ms = unix_ms().saturating_sub(sent_unix_ms) as f64;
            stats.last_swap_latency_ms = Some(latency_ms);
            report.swaps += u64::from(!report.versions.is_empty());
            report.versions.push(key.version);
            tracing::debug!(actor = %opts.id, version = key.version, latency_ms, "acting with new weights");
        } else if at_cap {
            continue;
        }
        let trajectories = rollouts.collect(&policy, report.chunks_sent)?;
        let Some(chunk) = outbox.wrap(trajectories) else {
            continue;
        };
        stats.sent(&chunk);
        report.chunks_sent += 1;
        report.env_steps += chunk.samples() as u64;
        let out = Outgoing {
            bytes: encode_msg(&chunk)?,
            seq: chunk.header.seq,
            key,
        };
        report.chunk_bytes += out.bytes.len() as u64;
        wiring.traj.send(out).map_err(ActorError::Zenoh)?;
        if let Some(s) = stats.due(&report, &outbox, d.actor_envs) {
            wiring.stats.set(encode_json(&s)?);
        }
    }
    let delivery = wiring.delivery.clone();
    wiring.close();
    // After the close: chunks dropped while the queue drained count too.
    report.stale_unsent = delivery.lock().map_or(0, |d| d.dropped_stale);
    report.refused_weights = acting.intake.refused;
    if let (Some(path), Some(recorded)) = (&opts.record, &rollouts.recorded) {
        write_recording(path, recorded)?;
    }
    Ok(report)
}

/// A pilot that follows a run's weights (`dupac fly --follow`): the newest published version,
/// checked like an actor checks it, swapped in by the caller at a step boundary.
pub struct Follower {
    wiring: Wiring,
    intake: WeightsIntake,
    /// When to ask for weights.
    ask: AskClock,
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
        let id = ActorId(u32::MAX - 1 - (std::process::id() % 1_000_000));
        Ok(Follower {
            wiring: Wiring::new_pilot(session, cfg, id)?,
            intake: weights_intake(cfg, fingerprint, obs_dim, n_sites),
            ask: AskClock::new(Instant::now()),
        })
    }

    /// Waits (up to `timeout`) for the learner's current weights by query.
    pub fn initial(&mut self, timeout: Duration) -> Result<Option<PolicyWeights>, ActorError> {
        let t0 = Instant::now();
        while t0.elapsed() < timeout {
            if let Some(w) = self
                .wiring
                .query_weights(&mut self.intake)?
                .and_then(Answer::into_weights)
            {
                self.intake.offer(WeightsKey::of(&w));
                return Ok(Some(w.policy));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        Ok(None)
    }

    /// Newer weights than the ones in use, if any arrived; after a while without any
    /// ([`AskClock`]), while
    /// the learner is alive and the run goes on, asked for (a publication dropped on a slow
    /// link).
    pub fn newer(&mut self) -> Result<Option<PolicyWeights>, ActorError> {
        let mut w = self.wiring.receive_weights(&mut self.intake, None)?;
        let ask = self.wiring.learner_alive() && !self.wiring.stopped();
        if w.is_none() && ask && self.ask.due(Instant::now()) {
            self.ask.asked(Instant::now());
            w = self
                .wiring
                .query_weights(&mut self.intake)?
                .and_then(Answer::into_weights);
        }
        match w {
            Some(w) if self.intake.offer(WeightsKey::of(&w)) != Offer::Stale => {
                self.ask.took(Instant::now());
                Ok(Some(w.policy))
            }
            _ => Ok(None),
        }
    }

    /// The learner ended the run.
    pub fn stopped(&self) -> bool {
        self.wiring.stopped()
    }
}
