//! The messages DUPAC processes exchange over Zenoh (issue 5); their validation is
//! [`crate::validate`].
//!
//! Every message starts with a [`Header`]; the codec frames it with an 8-byte magic per kind and
//! [`SCHEMA_VERSION`] ([`encode_msg`], [`decode_msg`]). Decoding is bounded by a size cap, and a
//! decoded trajectory chunk is checked against what the learner expects ([`ChunkExpect`]) before
//! anything reaches PPO: wrong run, incarnation, fingerprint, dimensions, non-finite numbers and
//! stale policy versions are each a [`DropReason`], counted by the learner.

use crate::codec::{self, CodecError};
use crate::ids::ActorId;
use crate::policy::PolicyWeights;
use crate::validate::{ChunkExpect, SiteSteps};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Version of every message layout below; bump on any change.
/// 4: the per-step site fields of [`EnvTrajectory`] (`env.site_every_step`).
/// 5: [`PolicyWeights::observation`] in the weights message.
/// 6: the path guide's keys in that observation (`env.observation.path_guide`).
/// 7: its planned path's clearance (`env.observation.path_guide_clearance_m`).
/// 8: the source of the sites' line of sight (`env.observation.site_los`).
/// 9: that observation without `site_trend`.
pub const SCHEMA_VERSION: u32 = 9;

/// Why an episode ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Within `env.goal_radius_m` of the destination (terminated).
    Goal,
    /// The swept UAV sphere touched a building (terminated).
    Collision,
    /// Left the flight area laterally (terminated).
    OutOfBounds,
    /// Reached the time limit T (truncated: the learner bootstraps).
    TimeLimit,
}

impl Outcome {
    /// Terminated (a true terminal state) rather than truncated.
    pub fn is_terminal(self) -> bool {
        !matches!(self, Outcome::TimeLimit)
    }
}

/// What one episode amounted to (spec/env.md "Metrics").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeSummary {
    /// Id of the pair in its pool or file.
    pub pair_id: u64,
    pub outcome: Outcome,
    /// Undiscounted sum of the raw rewards.
    pub episodic_return: f64,
    pub length: u32,
    /// Distance flown L (m).
    pub distance_flown_m: f64,
    /// Shortest flyable path D of the pair (m).
    pub shortest_m: f64,
    /// Distance left to the destination at the end (m).
    pub remaining_m: f64,
    /// Mean serving RSRP over the steps (dBm).
    pub mean_rsrp_dbm: f64,
    /// Fractions of steps (= flight time) per serving-RSRP class.
    pub frac_excellent: f64,
    pub frac_mediocre: f64,
    pub frac_poor: f64,
    pub handovers: u32,
    pub ping_pongs: u32,
    /// Mean site regret over the steps: best RSRP − serving RSRP (dB, issue 15).
    pub mean_site_regret_db: f64,
    /// Fraction of steps whose site regret exceeds `env.site_regret_threshold_db`.
    pub frac_site_regret_high: f64,
    /// Fraction of steps with class regret: the best site is excellent, the serving one is not.
    pub frac_class_regret: f64,
}

impl EpisodeSummary {
    /// Distance overhead over the shortest path, (L + remaining) / D − 1 (for a successful
    /// episode remaining ≤ the goal radius).
    pub fn overhead(&self) -> f64 {
        (self.distance_flown_m + self.remaining_m) / self.shortest_m - 1.0
    }

    fn is_finite(&self) -> bool {
        [
            self.episodic_return,
            self.distance_flown_m,
            self.shortest_m,
            self.remaining_m,
            self.mean_rsrp_dbm,
            self.frac_excellent,
            self.frac_mediocre,
            self.frac_poor,
            self.mean_site_regret_db,
            self.frac_site_regret_high,
            self.frac_class_regret,
        ]
        .iter()
        .all(|v| v.is_finite())
    }
}

/// One environment's steps of a rollout, time-ordered: what PPO needs.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct EnvTrajectory {
    /// Environment (stream) index within its actor: reward scaling keeps one discounted return
    /// per (actor, stream).
    pub env: u32,
    pub obs_dim: usize,
    /// Raw (unnormalised) observations `[T × obs_dim]`.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub obs: Vec<f32>,
    /// Unclipped moves `[T × 3]`.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub moves: Vec<f32>,
    /// Chosen site per step (0 without a site head).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub sites: Vec<u32>,
    /// log μ(a|s) of the behaviour policy (move and site together).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub logprobs: Vec<f32>,
    /// log μ(site|s) alone (0 without a site head); `logprobs − site_logprobs` is the move's.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub site_logprobs: Vec<f32>,
    /// Every site's decision reward `[T × n_sites]`, site-major per step: the reward the decision
    /// would have had with site k serving (`site_rewards[t·M + sites[t]] == rewards[t]`); empty
    /// when the site is not learned (issue 15, `Env::site_rewards`).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub site_rewards: Vec<f32>,
    /// With `env.site_every_step` (issue 15; empty otherwise, `site_rewards` then empty too):
    /// the steps each decision ran (1..=`env.action_repeat`) `[T]`; each of those steps' site
    /// features `[R × n_sites·F]` and every site's reward of that step `[R × n_sites]`
    /// (`Env::step_site_features`, `Env::step_site_rewards`), R = Σ `decision_steps`, decisions
    /// in order.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub decision_steps: Vec<u16>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub step_site_features: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub step_site_rewards: Vec<f32>,
    /// V(s) of the behaviour policy's critic.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub values: Vec<f32>,
    /// Raw rewards (scaling is the learner's).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub rewards: Vec<f32>,
    /// Episode ended in a terminal state (goal, collision, out of bounds).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub terminated: Vec<bool>,
    /// Episode cut by the time limit (the learner bootstraps).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub truncated: Vec<bool>,
    /// V(s_{t+1}) of the state each step reached (the final observation when the episode
    /// ended; meaningless, 0, after a termination).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub next_values: Vec<f32>,
    /// The raw observation after the last step (the state the next chunk starts from): the
    /// learner re-evaluates the last step's bootstrap value on it with its current critic.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub bootstrap_obs: Vec<f32>,
    /// Episodes that ended during this rollout.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub episodes: Vec<EpisodeSummary>,
}

impl EnvTrajectory {
    /// The first non-finite number of the trajectory, named (`"rewards[3] = NaN"`), or `None`
    /// when every number is finite (issue 7: a NaN or inf never reaches the learner's update).
    pub fn first_non_finite(&self) -> Option<String> {
        let fields = [
            ("obs", &self.obs),
            ("moves", &self.moves),
            ("logprobs", &self.logprobs),
            ("site_logprobs", &self.site_logprobs),
            ("site_rewards", &self.site_rewards),
            ("step_site_features", &self.step_site_features),
            ("step_site_rewards", &self.step_site_rewards),
            ("values", &self.values),
            ("rewards", &self.rewards),
            ("next_values", &self.next_values),
            ("bootstrap_obs", &self.bootstrap_obs),
        ];
        for (name, v) in fields {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Some(format!("{name}[{i}] = {}", v[i]));
            }
        }
        if self.episodes.iter().any(|e| !e.is_finite()) {
            return Some("episode summary".to_string());
        }
        None
    }

    pub fn len(&self) -> usize {
        self.rewards.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rewards.is_empty()
    }
}

/// Common header of every message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// [`SCHEMA_VERSION`] of the sender.
    pub schema_version: u32,
    /// `distributed.run` of the sender.
    #[serde(deserialize_with = "crate::budget::string")]
    pub run_id: String,
    /// Random id of the learner process the data belongs to (changes on every learner start;
    /// chunks acted with an earlier incarnation's weights are dropped).
    pub learner_incarnation: u64,
    /// The sending actor (`ActorId::LEARNER` for the learner).
    pub actor: ActorId,
    /// Random id of the sending process, new on every start (an actor restarted under the same
    /// id restarts `seq`): the learner keeps a sequence high-water mark per (actor, sender
    /// incarnation) and drops replays ([`crate::dedup`], issue 16).
    pub sender_incarnation: u64,
    /// Per-sender sequence number (chunks: 0, 1, 2, …).
    pub seq: u64,
    /// Policy version the data was produced with (weights: the version carried).
    pub policy_version: u64,
    /// [`crate::config::Config::env_fingerprint`] of the sender.
    pub config_fingerprint: u64,
    /// Sender's wall clock at sending (ms since the Unix epoch): latency figures on one host.
    pub sent_unix_ms: u64,
}

impl Header {
    pub fn new(run_id: &str, incarnation: u64, actor: ActorId, fingerprint: u64) -> Header {
        Header {
            schema_version: SCHEMA_VERSION,
            run_id: run_id.to_string(),
            learner_incarnation: incarnation,
            actor,
            sender_incarnation: 0,
            seq: 0,
            policy_version: 0,
            config_fingerprint: fingerprint,
            sent_unix_ms: unix_ms(),
        }
    }
}

/// Milliseconds since the Unix epoch.
pub fn unix_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

/// An actor's trajectories of one chunk: `actor_envs` environments × `chunk_steps` steps.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryChunk {
    pub header: Header,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub trajectories: Vec<EnvTrajectory>,
}

impl TrajectoryChunk {
    /// Samples (environment steps) in the chunk.
    pub fn samples(&self) -> usize {
        self.trajectories.iter().map(EnvTrajectory::len).sum()
    }
}

/// New policy weights from the learner (also the reply of the weights queryable).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeightsMsg {
    pub header: Header,
    pub policy: PolicyWeights,
}

/// How an actor is seen by the learner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ActorState {
    /// Liveliness token present, data arriving.
    Alive,
    /// Liveliness token present, nothing received for `distributed.silent_after_s`.
    Silent,
    /// Liveliness token gone (process ended, crashed or cut off).
    Left,
}

/// The learner's view of one actor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActorRow {
    pub actor: ActorId,
    pub state: ActorState,
    /// Accepted env steps per second over the last stats interval.
    pub steps_per_s: f64,
    /// Accepted env steps in total.
    pub env_steps: u64,
    pub chunks: u64,
    /// Learner version minus the version of the actor's last chunk.
    pub policy_lag: u64,
    /// Seconds since its last chunk.
    pub last_seen_s: f64,
}

/// The learner's periodic report (`dupac/<run>/stats/learner`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LearnerStats {
    pub header: Header,
    pub update: u64,
    pub total_updates: u64,
    pub global_step: u64,
    pub updates_per_s: f64,
    pub env_steps_per_s: f64,
    pub accepted_chunks: u64,
    /// Dropped messages by [`DropReason`] name.
    #[serde(deserialize_with = "crate::budget::map")]
    pub drops: BTreeMap<String, u64>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub actors: Vec<ActorRow>,
    /// The last update's metrics row (CleanRL names, `domain/*`, `eval/*`, `time/*`).
    #[serde(deserialize_with = "crate::budget::map")]
    pub metrics: BTreeMap<String, f64>,
    /// The run has reached `train.total_timesteps`.
    pub done: bool,
}

/// An actor's periodic report (`dupac/<run>/stats/actor/<id>`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ActorStats {
    pub header: Header,
    pub num_envs: u32,
    pub env_steps: u64,
    pub steps_per_s: f64,
    pub chunks_sent: u64,
    /// Weight swaps so far, and the last one's latency: learner publish → first step acted
    /// with the new version (ms, wall clocks of both hosts).
    pub swaps: u64,
    pub last_swap_latency_ms: f64,
    pub episodes: u64,
}

/// Any stats message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum StatsMsg {
    Learner(LearnerStats),
    Actor(ActorStats),
}

/// Commands on `dupac/<run>/ctrl`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Command {
    /// The run is over: actors and followers exit.
    Stop,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlMsg {
    pub header: Header,
    pub command: Command,
}

/// One kind of message: its codec magic and name.
pub trait Message: Serialize + serde::de::DeserializeOwned {
    const MAGIC: &'static [u8; 8];
    const NAME: &'static str;
}

impl Message for TrajectoryChunk {
    const MAGIC: &'static [u8; 8] = b"DUPACTRJ";
    const NAME: &'static str = "trajectory chunk";
}
impl Message for WeightsMsg {
    const MAGIC: &'static [u8; 8] = b"DUPACWTS";
    const NAME: &'static str = "weights";
}
impl Message for StatsMsg {
    const MAGIC: &'static [u8; 8] = b"DUPACSTA";
    const NAME: &'static str = "stats";
}
impl Message for ControlMsg {
    const MAGIC: &'static [u8; 8] = b"DUPACCTL";
    const NAME: &'static str = "control";
}

/// Encodes a message (magic + [`SCHEMA_VERSION`] + bincode body).
pub fn encode_msg<M: Message>(msg: &M) -> Result<Vec<u8>, CodecError> {
    codec::encode(M::MAGIC, SCHEMA_VERSION, msg, M::NAME)
}

/// How much of a message a receiver reads: its size on the wire, and what decoding it may
/// allocate (checked while decoding: [`crate::budget`]). Both derive from the receiver's
/// configuration, never from the message (issue 16).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MsgLimits {
    /// Largest message read (bytes); larger ones are dropped unread.
    pub bytes: usize,
    /// Most bytes decoding one message may allocate for its collections.
    pub budget_bytes: usize,
}

impl MsgLimits {
    /// `bytes` on the wire and as decoding budget (tools and tests that know their messages).
    pub fn both(bytes: usize) -> MsgLimits {
        MsgLimits {
            bytes,
            budget_bytes: bytes,
        }
    }

    /// Trajectory chunks as the learner expects them: [`ChunkExpect::budget_bytes`] for both,
    /// never above `distributed.max_message_mib`.
    pub fn chunk(cfg: &crate::config::Config, x: &ChunkExpect) -> MsgLimits {
        let need = x.budget_bytes();
        MsgLimits {
            bytes: need.min(cfg.distributed.max_message_bytes()),
            budget_bytes: need,
        }
    }

    /// Weights of a policy with this configuration's networks
    /// ([`crate::policy::weights_budget_bytes`]).
    pub fn weights(cfg: &crate::config::Config, obs_dim: usize, n_sites: usize) -> MsgLimits {
        let p = &cfg.ppo;
        let need = crate::policy::weights_budget_bytes(
            obs_dim,
            n_sites,
            &p.hidden,
            p.site_embed,
            &p.site_hidden,
        );
        MsgLimits {
            bytes: need.min(cfg.distributed.max_message_bytes()),
            budget_bytes: need,
        }
    }

    /// Stats and control messages: a header, a metrics row and one row per tracked actor.
    pub fn small(cfg: &crate::config::Config) -> MsgLimits {
        MsgLimits {
            bytes: STATS_BUDGET_BYTES.min(cfg.distributed.max_message_bytes()),
            budget_bytes: STATS_BUDGET_BYTES,
        }
    }

    /// The largest message of a run with this configuration (a router's or a session's
    /// receive limit: zenoh's `transport/link/rx/max_message_size`).
    pub fn run_max_bytes(cfg: &crate::config::Config, obs_dim: usize, n_sites: usize) -> usize {
        let x = ChunkExpect {
            run_id: String::new(),
            incarnation: 0,
            fingerprint: 0,
            obs_dim,
            n_sites,
            max_envs: cfg.distributed.actor_envs.max(cfg.train.num_envs),
            max_steps: cfg.distributed.chunk_steps.max(cfg.train.num_steps),
            site_steps: SiteSteps::of(cfg),
        };
        [
            MsgLimits::chunk(cfg, &x).bytes,
            MsgLimits::weights(cfg, obs_dim, n_sites).bytes,
            MsgLimits::small(cfg).bytes,
        ]
        .into_iter()
        .max()
        .unwrap_or(0)
    }
}

/// Budget of a stats or control message (bytes): ≈ 100 metrics and up to
/// [`crate::dedup::MAX_TRACKED_SENDERS`] actor rows fit with room to spare.
pub const STATS_BUDGET_BYTES: usize = 4 << 20;

/// Decodes a message within `limits`; `origin` (the key expression) names it in errors.
pub fn decode_msg<M: Message>(
    bytes: &[u8],
    limits: MsgLimits,
    origin: &str,
) -> Result<M, CodecError> {
    codec::decode_budgeted(
        M::MAGIC,
        SCHEMA_VERSION,
        bytes,
        limits.bytes,
        limits.budget_bytes,
        &format!("{} on {origin}", M::NAME),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::policy::MOVE_DIM;
    use crate::validate::{DropReason, validate_chunk};

    fn lim(bytes: usize) -> MsgLimits {
        MsgLimits {
            bytes,
            budget_bytes: bytes,
        }
    }

    fn expect() -> ChunkExpect {
        ChunkExpect {
            run_id: "r".into(),
            incarnation: 7,
            fingerprint: 9,
            obs_dim: 2,
            n_sites: 3,
            max_envs: 4,
            max_steps: 8,
            site_steps: None,
        }
    }

    fn chunk() -> TrajectoryChunk {
        let mut h = Header::new("r", 7, ActorId(1), 9);
        h.policy_version = 3;
        TrajectoryChunk {
            header: h,
            trajectories: vec![EnvTrajectory {
                env: 0,
                obs_dim: 2,
                obs: vec![0.0; 4],
                moves: vec![0.0; 6],
                sites: vec![0, 2],
                logprobs: vec![-1.0; 2],
                site_logprobs: vec![0.0; 2],
                site_rewards: vec![],
                decision_steps: vec![],
                step_site_features: vec![],
                step_site_rewards: vec![],
                values: vec![0.5; 2],
                rewards: vec![1.0; 2],
                terminated: vec![false, true],
                truncated: vec![false; 2],
                next_values: vec![0.5, 0.0],
                bootstrap_obs: vec![0.0; 2],
                episodes: vec![],
            }],
        }
    }

    #[test]
    fn a_valid_chunk_round_trips_and_passes() {
        let c = chunk();
        let bytes = encode_msg(&c).expect("encode");
        let d: TrajectoryChunk = decode_msg(&bytes, lim(1 << 20), "k").expect("decode");
        assert_eq!(d, c);
        assert_eq!(validate_chunk(&d, &expect()), Ok(()));
    }

    #[test]
    fn every_defect_has_its_reason() {
        let x = expect();
        let reason = |f: &dyn Fn(&mut TrajectoryChunk)| {
            let mut c = chunk();
            f(&mut c);
            validate_chunk(&c, &x).map_err(|r| r.reason)
        };
        assert_eq!(
            reason(&|c| c.header.run_id = "x".into()),
            Err(DropReason::WrongRun)
        );
        assert_eq!(
            reason(&|c| c.header.schema_version = 0),
            Err(DropReason::Schema)
        );
        assert_eq!(
            reason(&|c| c.header.config_fingerprint = 1),
            Err(DropReason::Fingerprint)
        );
        assert_eq!(
            reason(&|c| c.header.learner_incarnation = 1),
            Err(DropReason::Incarnation)
        );
        assert_eq!(
            reason(&|c| c.trajectories[0].obs.push(0.0)),
            Err(DropReason::Dimensions)
        );
        assert_eq!(
            reason(&|c| c.trajectories[0].sites[1] = 3),
            Err(DropReason::Dimensions)
        );
        assert_eq!(
            reason(&|c| c.trajectories[0].obs_dim = 3),
            Err(DropReason::Dimensions)
        );
        assert_eq!(
            reason(&|c| c.trajectories = vec![c.trajectories[0].clone(); 5]),
            Err(DropReason::Dimensions)
        );
        assert_eq!(
            reason(&|c| c.trajectories[0].env = 4),
            Err(DropReason::Dimensions)
        );
        assert_eq!(
            reason(&|c| c.trajectories[0].rewards[0] = f32::NAN),
            Err(DropReason::NonFinite)
        );
        assert_eq!(
            reason(&|c| c.trajectories[0].bootstrap_obs[1] = f32::INFINITY),
            Err(DropReason::NonFinite)
        );
    }

    #[test]
    fn decoding_names_garbage_schema_and_size() {
        let bytes = encode_msg(&chunk()).expect("encode");
        let e = decode_msg::<TrajectoryChunk>(b"not a message at all", lim(1 << 20), "k")
            .expect_err("garbage");
        assert_eq!(DropReason::of_codec(&e), DropReason::Garbage);
        let mut old = bytes.clone();
        old[8..12].copy_from_slice(&0u32.to_le_bytes());
        let e = decode_msg::<TrajectoryChunk>(&old, lim(1 << 20), "k").expect_err("schema");
        assert_eq!(DropReason::of_codec(&e), DropReason::Schema);
        let e = decode_msg::<TrajectoryChunk>(&bytes, lim(16), "k").expect_err("size");
        assert_eq!(DropReason::of_codec(&e), DropReason::TooLarge);
        let mut cut = bytes.clone();
        cut.truncate(bytes.len() - 3);
        let e = decode_msg::<TrajectoryChunk>(&cut, lim(1 << 20), "k").expect_err("cut");
        assert_eq!(DropReason::of_codec(&e), DropReason::Garbage);
        // A message of another kind is not a chunk.
        let w = encode_msg(&ControlMsg {
            header: Header::new("r", 7, ActorId::LEARNER, 9),
            command: Command::Stop,
        })
        .expect("encode");
        let e = decode_msg::<TrajectoryChunk>(&w, lim(1 << 20), "k").expect_err("kind");
        assert_eq!(DropReason::of_codec(&e), DropReason::Garbage);
    }

    /// A chunk with every vector at its largest: `max_envs × max_steps` steps, site rewards,
    /// one episode per step.
    fn maximal(x: &ChunkExpect) -> TrajectoryChunk {
        let t = x.max_steps;
        let summary = EpisodeSummary {
            pair_id: u64::MAX,
            outcome: Outcome::TimeLimit,
            episodic_return: 1.0,
            length: u32::MAX,
            distance_flown_m: 1.0,
            shortest_m: 1.0,
            remaining_m: 1.0,
            mean_rsrp_dbm: -70.0,
            frac_excellent: 1.0,
            frac_mediocre: 0.0,
            frac_poor: 0.0,
            handovers: u32::MAX,
            ping_pongs: u32::MAX,
            mean_site_regret_db: 0.0,
            frac_site_regret_high: 0.0,
            frac_class_regret: 0.0,
        };
        let mut h = Header::new(&"r".repeat(64), u64::MAX, ActorId(u32::MAX), u64::MAX);
        h.seq = u64::MAX;
        h.sender_incarnation = u64::MAX;
        // Per-step site rows (every decision at its longest) or decision-level site rewards.
        let (steps, rows, feats) = x.site_steps.map_or((0, 0, 0), |k| {
            (k.per_decision, t * k.per_decision, k.features)
        });
        TrajectoryChunk {
            header: h,
            trajectories: (0..x.max_envs)
                .map(|k| EnvTrajectory {
                    env: k as u32,
                    obs_dim: x.obs_dim,
                    obs: vec![1.0; t * x.obs_dim],
                    moves: vec![1.0; t * MOVE_DIM],
                    sites: vec![x.n_sites as u32 - 1; t],
                    logprobs: vec![1.0; t],
                    site_logprobs: vec![1.0; t],
                    site_rewards: if steps == 0 {
                        vec![1.0; t * x.n_sites]
                    } else {
                        vec![]
                    },
                    decision_steps: vec![steps as u16; if steps == 0 { 0 } else { t }],
                    step_site_features: vec![1.0; rows * x.n_sites * feats],
                    step_site_rewards: vec![1.0; rows * x.n_sites],
                    values: vec![1.0; t],
                    rewards: vec![1.0; t],
                    terminated: vec![true; t],
                    truncated: vec![false; t],
                    next_values: vec![1.0; t],
                    bootstrap_obs: vec![1.0; x.obs_dim],
                    episodes: vec![summary.clone(); t],
                })
                .collect(),
        }
    }

    #[test]
    fn the_largest_valid_chunk_fits_its_derived_limits() {
        let x = ChunkExpect {
            run_id: "r".repeat(64),
            obs_dim: 404,
            n_sites: 30,
            max_envs: 4,
            max_steps: 128,
            site_steps: None,
            ..expect()
        };
        let c = maximal(&x);
        let bytes = encode_msg(&c).expect("encode");
        let need = x.budget_bytes();
        assert!(bytes.len() <= need, "{} > {need}", bytes.len());
        let limits = MsgLimits {
            bytes: need,
            budget_bytes: need,
        };
        let d: TrajectoryChunk = decode_msg(&bytes, limits, "k").expect("fits its budget");
        assert_eq!(d.samples(), 4 * 128);
        // The bound is not wildly loose either: within 2× of the real size.
        assert!(need < 2 * bytes.len(), "{need} vs {}", bytes.len());
        // With a site chosen every step (5 steps per decision, 10 features per site).
        let per_step = ChunkExpect {
            site_steps: Some(SiteSteps {
                per_decision: 5,
                features: 10,
            }),
            ..x.clone()
        };
        let c = maximal(&per_step);
        let bytes = encode_msg(&c).expect("encode");
        let need = per_step.budget_bytes();
        assert!(bytes.len() <= need, "{} > {need}", bytes.len());
        let d: TrajectoryChunk =
            decode_msg(&bytes, MsgLimits::both(need), "k").expect("fits its budget");
        assert_eq!(d, c);
        assert!(need < 2 * bytes.len(), "{need} vs {}", bytes.len());
        // The per-step budget does not admit it without per-step fields expected.
        assert!(x.budget_bytes() < bytes.len());
    }

    /// The per-step site fields (`env.site_every_step`) are checked against their shape: each
    /// defect is refused with a message naming the field, and none is accepted when the run
    /// does not choose the site every step.
    #[test]
    fn per_step_site_fields_are_checked_against_their_shape() {
        let x = ChunkExpect {
            site_steps: Some(SiteSteps {
                per_decision: 2,
                features: 4,
            }),
            ..expect()
        };
        let good = |c: &mut TrajectoryChunk| {
            let tr = &mut c.trajectories[0];
            tr.decision_steps = vec![2, 1];
            tr.step_site_features = vec![0.5; 3 * 3 * 4];
            tr.step_site_rewards = vec![-1.0; 3 * 3];
        };
        let mut c = chunk();
        good(&mut c);
        assert_eq!(validate_chunk(&c, &x), Ok(()));
        let message = |f: &dyn Fn(&mut EnvTrajectory)| {
            let mut c = chunk();
            good(&mut c);
            f(&mut c.trajectories[0]);
            validate_chunk(&c, &x).map(|_| ()).map_err(|r| {
                assert_eq!(r.reason, DropReason::Dimensions);
                r.detail
            })
        };
        let err = |f: &dyn Fn(&mut EnvTrajectory), want: &str| {
            let e = message(f).expect_err(want);
            assert!(e.contains(want), "{e:?} should name {want}");
        };
        err(
            &|t| t.decision_steps = vec![2],
            "decision_steps has 1 values",
        );
        err(&|t| t.decision_steps = vec![3, 0], "a decision of 3 steps");
        err(&|t| t.decision_steps = vec![0, 2], "a decision of 0 steps");
        err(
            &|t| {
                t.step_site_features.pop();
            },
            "step_site_features",
        );
        err(&|t| t.step_site_rewards.push(0.0), "step_site_rewards");
        err(
            &|t| t.site_rewards = vec![0.0; 6],
            "site_rewards with per-step",
        );
        let mut nan = chunk();
        good(&mut nan);
        nan.trajectories[0].step_site_rewards[4] = f32::NAN;
        assert_eq!(
            validate_chunk(&nan, &x).map_err(|r| r.reason),
            Err(DropReason::NonFinite)
        );
        // A run without per-step sites refuses them.
        let r = validate_chunk(&c, &expect()).expect_err("not expected");
        assert!(r.detail.contains("env.site_every_step is off"), "{r:?}");
    }

    #[test]
    fn an_amplifying_chunk_is_refused_while_decoding() {
        // 200 000 empty trajectories: ≈ 3 MB on the wire, ≈ 70 MB decoded. Under a byte
        // limit that admits it, the budget of a 4 × 128-step chunk refuses it.
        let x = expect();
        let mut c = chunk();
        c.trajectories = vec![EnvTrajectory::default(); 200_000];
        let bytes = encode_msg(&c).expect("encode");
        let limits = MsgLimits {
            bytes: 64 << 20,
            budget_bytes: x.budget_bytes(),
        };
        let e = decode_msg::<TrajectoryChunk>(&bytes, limits, "k").expect_err("amplifying");
        assert!(e.to_string().contains("budget"), "{e}");
        assert_eq!(DropReason::of_codec(&e), DropReason::TooLarge);
    }
}
