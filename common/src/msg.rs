//! The messages DUPAC processes exchange over Zenoh (checked by the `validate` module).
//!
//! Every message starts with a [`Header`]. Data (trajectory chunks, weights) is binary: the
//! codec frames it with an 8-byte magic per kind and [`SCHEMA_VERSION`] ([`encode_msg`],
//! [`decode_msg`]). Stats ([`StatsMsg`]) and control messages ([`ControlMsg`]), which any zenoh
//! client may read, are JSON ([`crate::jsonmsg`]). Decoding is bounded by [`MsgLimits`] (the size
//! on the wire and what decoding may allocate).

use crate::codec::{self, CodecError};
use crate::compact::CompactTrajectory;
use crate::ids::ActorId;
use crate::policy::PolicyWeights;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Version of every message layout below; bump on any change.
/// 4: the per-step site fields of [`EnvTrajectory`] (`env.site_every_step`).
/// 5: [`PolicyWeights::observation`] in the weights message.
/// 6: the path guide's keys in that observation (`env.observation.path_guide`).
/// 7: its planned path's clearance (`env.observation.path_guide_clearance_m`).
/// 8: the source of the sites' line of sight (`env.observation.site_los`).
/// 9: that observation without `site_trend`.
/// 10: stats and control messages in JSON ([`crate::jsonmsg`]), not in this binary codec.
/// 11: the handover weight in that observation (`env.observation.handover_weight`).
/// 12: that observation as TOML text, with the look-ahead keys (`env.observation.site_lookahead_m`).
/// 13: [`WeightsHeld`], the small reply to a weights query from a process that holds the newest
/// weights ([`HELD_PARAMETER`]).
/// 14: the weights' dense layers in half precision ([`crate::policy::wire`]).
/// 15: trajectories in compact form ([`crate::compact::CompactTrajectory`]).
/// 16: trajectory chunks compressed ([`Message::COMPRESSED`]).
pub const SCHEMA_VERSION: u32 = 16;

pub use crate::episode::{EpisodeSummary, Outcome};

/// One environment's steps of a rollout, time-ordered: what PPO needs (the expansion of a
/// [`crate::compact::CompactTrajectory`]; never on the wire).
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
    /// when the site is not learned (`Env::site_rewards`).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub site_rewards: Vec<f32>,
    /// With `env.site_every_step` (empty otherwise, `site_rewards` then empty too):
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

/// Whether every value of `v` is finite: a branch-free scan per block of 64 (the compiler
/// vectorises it; the learner checks ≈ 10 M values per update), the slow search only on failure.
fn all_finite(v: &[f32]) -> bool {
    v.chunks(64)
        .all(|b| b.iter().fold(true, |ok, x| ok & x.is_finite()))
}

impl EnvTrajectory {
    /// The first non-finite number of the trajectory, named (`"rewards[3] = NaN"`), or `None`
    /// when every number is finite (a NaN or inf never reaches the learner's update).
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
            if all_finite(v) {
                continue;
            }
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
#[serde(deny_unknown_fields)]
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
    /// incarnation) and drops replays ([`crate::dedup`]).
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

/// Decoding budget of a header and a small message (stats, control): run names are short.
pub const HEADER_BUDGET_BYTES: usize = 64 * 1024;

/// Milliseconds since the Unix epoch.
pub fn unix_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_millis() as u64)
        .unwrap_or(0)
}

/// An actor's trajectories of one chunk: `actor_envs` environments × `chunk_steps` decisions,
/// in compact form.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrajectoryChunk {
    pub header: Header,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub trajectories: Vec<CompactTrajectory>,
}

impl TrajectoryChunk {
    /// Samples (decisions) in the chunk.
    pub fn samples(&self) -> usize {
        self.trajectories.iter().map(CompactTrajectory::len).sum()
    }
}

/// A chunk as the learner trains on it: its header and the expansion of each trajectory.
#[derive(Debug, Clone, PartialEq)]
pub struct ExpandedChunk {
    pub header: Header,
    pub trajectories: Vec<EnvTrajectory>,
}

impl ExpandedChunk {
    /// Samples (decisions) in the chunk.
    pub fn samples(&self) -> usize {
        self.trajectories.iter().map(EnvTrajectory::len).sum()
    }
}

/// New policy weights from the learner (also the reply of the weights queryable). On the wire
/// the dense layers' weights are half precision ([`crate::policy::wire`]): a decoded message
/// holds the rounded policy the actors act with.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeightsMsg {
    pub header: Header,
    #[serde(with = "crate::policy::wire")]
    pub policy: PolicyWeights,
}

/// The learner's reply to a weights query from a process that already holds its newest weights
/// (the query's [`HELD_PARAMETER`] names them): the header alone, ≈ 100 bytes instead of the
/// policy. `header.learner_incarnation` and `header.policy_version` say which weights the
/// learner is at.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct WeightsHeld {
    pub header: Header,
}

/// The selector parameter of a weights query naming the weights the asker holds,
/// `held=<learner incarnation>.<policy version>` (decimal): the learner answers with
/// [`WeightsHeld`] when they are its newest.
pub const HELD_PARAMETER: &str = "held";

/// The [`HELD_PARAMETER`] value of the weights of learner `incarnation` at `version`.
pub fn held_value(incarnation: u64, version: u64) -> String {
    format!("{incarnation}.{version}")
}

/// The (learner incarnation, policy version) of a [`HELD_PARAMETER`] value; `None` for
/// anything else (a malformed value is a query for the full weights).
pub fn parse_held(value: &str) -> Option<(u64, u64)> {
    let (i, v) = value.split_once('.')?;
    Some((i.parse().ok()?, v.parse().ok()?))
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
#[serde(deny_unknown_fields)]
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
    /// Seconds since its last accepted chunk (`None`: none yet).
    pub last_seen_s: Option<f64>,
}

/// The learner's periodic report (`dupac/<run>/stats/learner`, JSON: [`crate::jsonmsg`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LearnerStats {
    /// `seq` counts the learner's stats messages (0, 1, 2, …); `policy_version` is `update`.
    pub header: Header,
    /// Policy version: PPO updates done.
    pub update: u64,
    /// Updates of the whole run (`train.total_timesteps` / batch).
    pub total_updates: u64,
    /// Env steps trained on so far.
    pub global_step: u64,
    /// Updates per second over the last stats interval.
    pub updates_per_s: f64,
    /// Env steps trained on per second over the last stats interval.
    pub env_steps_per_s: f64,
    /// Chunks that passed validation so far.
    pub accepted_chunks: u64,
    /// Dropped messages by drop-reason name (`validate::DropReason`).
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

/// An actor's periodic report (`dupac/<run>/stats/actor/<id>`, JSON: [`crate::jsonmsg`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActorStats {
    /// `seq` is the sequence number of the actor's next chunk; `policy_version` the version
    /// it acts with.
    pub header: Header,
    /// Environments this actor steps (`distributed.actor_envs`).
    pub num_envs: u32,
    /// Env steps sent in chunks so far.
    pub env_steps: u64,
    /// Env steps per second over the last stats interval.
    pub steps_per_s: f64,
    pub chunks_sent: u64,
    /// Weight swaps so far, and the last one's latency: learner publish → first step acted
    /// with the new version (ms, wall clocks of both hosts; `None` before the first swap).
    pub swaps: u64,
    pub last_swap_latency_ms: Option<f64>,
    /// Episodes ended so far.
    pub episodes: u64,
}

/// Any stats message (told apart by the JSON `kind`).
#[derive(Debug, Clone, PartialEq)]
pub enum StatsMsg {
    Learner(LearnerStats),
    Actor(ActorStats),
}

/// Commands on `dupac/<run>/ctrl`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Command {
    /// The run is over: actors and followers exit.
    Stop,
}

/// A command of the learner to every process of the run (`dupac/<run>/ctrl`, JSON:
/// [`crate::jsonmsg`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlMsg {
    pub header: Header,
    pub command: Command,
}

/// One kind of binary message: its codec magic and name.
pub trait Message: Serialize + serde::de::DeserializeOwned {
    const MAGIC: &'static [u8; 8];
    const NAME: &'static str;
    /// Whether the body travels zstd-compressed ([`codec::encode_compressed`]): trajectory
    /// chunks (≈ 1.8× smaller); the weights' half-precision values gain too little.
    const COMPRESSED: bool = false;
}

impl Message for TrajectoryChunk {
    const MAGIC: &'static [u8; 8] = b"DUPACTRJ";
    const NAME: &'static str = "trajectory chunk";
    const COMPRESSED: bool = true;
}
impl Message for WeightsMsg {
    const MAGIC: &'static [u8; 8] = b"DUPACWTS";
    const NAME: &'static str = "weights";
}
impl Message for WeightsHeld {
    const MAGIC: &'static [u8; 8] = b"DUPACWHD";
    const NAME: &'static str = "weights held";
}

/// Whether `bytes` start with `M`'s magic (which kind of message a reply is, before decoding).
pub fn is_kind<M: Message>(bytes: &[u8]) -> bool {
    bytes.starts_with(M::MAGIC)
}

/// Encodes a message (magic + [`SCHEMA_VERSION`] + bincode body, compressed for
/// [`Message::COMPRESSED`] kinds).
pub fn encode_msg<M: Message>(msg: &M) -> Result<Vec<u8>, CodecError> {
    if M::COMPRESSED {
        codec::encode_compressed(M::MAGIC, SCHEMA_VERSION, msg, M::NAME)
    } else {
        codec::encode(M::MAGIC, SCHEMA_VERSION, msg, M::NAME)
    }
}

/// How much of a message a receiver reads: its size on the wire, and what decoding it may
/// allocate (checked while decoding: [`crate::budget`]). Both derive from the receiver's
/// configuration, never from the message: the constructors from a configuration are with the
/// receiver's expectations in the `validate` module.
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
    let what = format!("{} on {origin}", M::NAME);
    let decode = if M::COMPRESSED {
        codec::decode_compressed_budgeted
    } else {
        codec::decode_budgeted
    };
    decode(
        M::MAGIC,
        SCHEMA_VERSION,
        bytes,
        limits.bytes,
        limits.budget_bytes,
        &what,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_held_value_reads_back_and_anything_else_is_none() {
        let v = held_value(u64::MAX, 41);
        assert_eq!(parse_held(&v), Some((u64::MAX, 41)));
        for bad in [
            "",
            "12",
            "12.",
            ".3",
            "a.3",
            "1.2.3",
            "-1.2",
            "1.99999999999999999999",
        ] {
            assert_eq!(parse_held(bad), None, "{bad:?}");
        }
    }
}
