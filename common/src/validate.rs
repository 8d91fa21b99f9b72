//! Validation of received messages: nothing reaches PPO or an actor's
//! policy before it is checked against what the receiver expects ([`ChunkExpect`]): wrong run,
//! incarnation, fingerprint or schema, wrong dimensions, non-finite numbers. Each refusal is a
//! [`DropReason`] (counted by the learner) with the detail of what was wrong ([`Rejection`]).

use crate::codec::CodecError;
use crate::compact::CompactTrajectory;
use crate::config::{Association, Config};
use crate::msg::{
    EnvTrajectory, EpisodeSummary, ExpandedChunk, HEADER_BUDGET_BYTES, Header, MsgLimits,
    SCHEMA_VERSION, STATS_BUDGET_BYTES, TrajectoryChunk, WeightsMsg,
};
use crate::policy::{MOVE_DIM, weights_budget_bytes};
use std::fmt;

/// Why a received message was not used. Counted by name in
/// [`crate::msg::LearnerStats::drops`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DropReason {
    /// Larger than its limit on the wire, or decoding it would allocate more than its budget
    /// ([`MsgLimits`]).
    TooLarge,
    /// Not a message of this kind, or a body that does not decode.
    Garbage,
    /// Another [`SCHEMA_VERSION`] (or, for a JSON message, another
    /// [`crate::jsonmsg::JSON_SCHEMA_VERSION`] or the binary format).
    Schema,
    /// Another `distributed.run`.
    WrongRun,
    /// Another environment/radio configuration.
    Fingerprint,
    /// Acted with the weights of an earlier learner process.
    Incarnation,
    /// Acted with a policy more than `distributed.max_policy_lag` versions old.
    Stale,
    /// Sizes or dimensions that do not match the configuration.
    Dimensions,
    /// A NaN or infinity.
    NonFinite,
    /// The receive queue, or its sender's share of it, was full (the sender's oldest message
    /// was dropped), or the learner already tracks `dedup::MAX_TRACKED_SENDERS` senders.
    Overflow,
    /// A chunk whose (actor, sender incarnation, sequence number) was already accepted: a
    /// duplicate or a replay (at-most-once).
    Replay,
}

impl DropReason {
    pub const ALL: [DropReason; 11] = [
        DropReason::TooLarge,
        DropReason::Garbage,
        DropReason::Schema,
        DropReason::WrongRun,
        DropReason::Fingerprint,
        DropReason::Incarnation,
        DropReason::Stale,
        DropReason::Dimensions,
        DropReason::NonFinite,
        DropReason::Overflow,
        DropReason::Replay,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            DropReason::TooLarge => "too_large",
            DropReason::Garbage => "garbage",
            DropReason::Schema => "schema",
            DropReason::WrongRun => "wrong_run",
            DropReason::Fingerprint => "fingerprint",
            DropReason::Incarnation => "incarnation",
            DropReason::Stale => "stale",
            DropReason::Dimensions => "dimensions",
            DropReason::NonFinite => "non_finite",
            DropReason::Overflow => "overflow",
            DropReason::Replay => "replay",
        }
    }

    /// The reason a decoding error stands for.
    pub fn of_codec(e: &CodecError) -> DropReason {
        match e {
            CodecError::TooLarge { .. } | CodecError::OverBudget { .. } => DropReason::TooLarge,
            CodecError::Version { .. } | CodecError::Binary { .. } => DropReason::Schema,
            _ => DropReason::Garbage,
        }
    }
}

impl fmt::Display for DropReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A rejected message: the reason and what exactly was wrong.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    pub reason: DropReason,
    pub detail: String,
}

impl fmt::Display for Rejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.reason, self.detail)
    }
}

/// What the learner accepts.
#[derive(Debug, Clone)]
pub struct ChunkExpect {
    pub run_id: String,
    pub incarnation: u64,
    pub fingerprint: u64,
    pub obs_dim: usize,
    /// Site logits of the policy (0: base method, every site index must be 0… any < 65536).
    pub n_sites: usize,
    /// Most environments and steps per environment in one chunk.
    pub max_envs: usize,
    pub max_steps: usize,
    /// With `env.site_every_step`: steps per decision (`env.action_repeat`) and features per
    /// site of the per-step site fields; `None`: those fields must be empty.
    pub site_steps: Option<SiteSteps>,
}

/// The shape of a trajectory's per-step site fields (`env.site_every_step`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SiteSteps {
    /// Most steps of one decision (`env.action_repeat`).
    pub per_decision: usize,
    /// Features per site ([`crate::obs::site_features_per_site`]).
    pub features: usize,
}

impl SiteSteps {
    /// The per-step site shape of a configuration (`None` unless `env.site_every_step` with the
    /// learned association).
    pub fn of(cfg: &Config) -> Option<SiteSteps> {
        let e = &cfg.env;
        (e.site_every_step && e.association == Association::Learned).then(|| SiteSteps {
            per_decision: e.action_repeat as usize,
            features: crate::obs::site_features_per_site(&e.observation),
        })
    }
}

impl ChunkExpect {
    /// Upper bound (bytes) on what a valid chunk allocates once expanded: `max_envs`
    /// trajectories of `max_steps` decisions with every per-step vector full and one episode
    /// summary per decision, plus the header. The compact form is smaller, on the wire and
    /// decoded (per decision a trunk row of ≤ 100 bytes against the observation's 4 per value,
    /// per state ≤ 30 + M·(3 + look-ahead distances) bytes against 4·M·(features + 1); a wire
    /// value is never larger than its decoded form: f32 4 → 4 bytes, u8 1 → 1, bool 1 → 1,
    /// varint lengths ≤ 9 bytes against a 24-byte `Vec`), so the same figure caps the message
    /// size, the decoding budget and the expansion's (`dupac_actor::expand`).
    pub fn budget_bytes(&self) -> usize {
        let f = size_of::<f32>();
        let per_step = f * (self.obs_dim + MOVE_DIM + self.n_sites)
            + size_of::<u32>()
            + 5 * f
            + 2 * size_of::<bool>()
            + size_of::<EpisodeSummary>()
            + self.site_steps.map_or(0, |k| {
                // A u16 of 251 or more takes 3 bytes as a bincode varint.
                3 + f * k.per_decision * self.n_sites * (k.features + 1)
            });
        let per_env = size_of::<EnvTrajectory>().max(size_of::<CompactTrajectory>())
            + f * self.obs_dim
            + self.max_steps.saturating_mul(per_step);
        self.max_envs
            .saturating_mul(per_env)
            .saturating_add(HEADER_BUDGET_BYTES)
    }
}

/// [`MsgLimits`] from a receiver's configuration: the most it reads of each message kind.
impl MsgLimits {
    /// Trajectory chunks as the learner expects them: [`ChunkExpect::budget_bytes`] for both,
    /// never above `distributed.max_message_mib`.
    pub fn chunk(cfg: &Config, x: &ChunkExpect) -> MsgLimits {
        let need = x.budget_bytes();
        MsgLimits {
            bytes: need.min(cfg.distributed.max_message_bytes()),
            budget_bytes: need,
        }
    }

    /// Weights of a policy with this configuration's networks: its
    /// [`weights_budget_bytes`] and a header.
    pub fn weights(cfg: &Config, obs_dim: usize, n_sites: usize) -> MsgLimits {
        let p = &cfg.ppo;
        let need = weights_budget_bytes(obs_dim, n_sites, &p.hidden, p.site_embed, &p.site_hidden)
            .saturating_add(HEADER_BUDGET_BYTES);
        MsgLimits {
            bytes: need.min(cfg.distributed.max_message_bytes()),
            budget_bytes: need,
        }
    }

    /// Stats and control messages: a header, a metrics row and one row per tracked actor.
    pub fn small(cfg: &Config) -> MsgLimits {
        MsgLimits {
            bytes: STATS_BUDGET_BYTES.min(cfg.distributed.max_message_bytes()),
            budget_bytes: STATS_BUDGET_BYTES,
        }
    }

    /// The largest message of a run with this configuration (a router's or a session's
    /// receive limit: zenoh's `transport/link/rx/max_message_size`).
    pub fn run_max_bytes(cfg: &Config, obs_dim: usize, n_sites: usize) -> usize {
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

fn reject(reason: DropReason, detail: impl Into<String>) -> Rejection {
    Rejection {
        reason,
        detail: detail.into(),
    }
}

/// Checks the header of any message from this run.
pub fn check_header(h: &Header, x: &ChunkExpect) -> Result<(), Rejection> {
    if h.schema_version != SCHEMA_VERSION {
        return Err(reject(
            DropReason::Schema,
            format!("schema {} (this build: {SCHEMA_VERSION})", h.schema_version),
        ));
    }
    if h.run_id != x.run_id {
        return Err(reject(
            DropReason::WrongRun,
            format!("run {:?}, expected {:?}", h.run_id, x.run_id),
        ));
    }
    if h.config_fingerprint != x.fingerprint {
        return Err(reject(
            DropReason::Fingerprint,
            format!(
                "configuration fingerprint {:016x} in the message, {:016x} in this process",
                h.config_fingerprint, x.fingerprint
            ),
        ));
    }
    Ok(())
}

/// Checks a received compact chunk before its expansion: the header, the learner incarnation,
/// the number of environments and, per trajectory, its environment id, its decisions, sites and
/// episodes (the columns' shapes and numbers are the expansion's to check,
/// `dupac_actor::expand::Expander::trajectory`).
pub fn validate_compact(c: &TrajectoryChunk, x: &ChunkExpect) -> Result<(), Rejection> {
    check_chunk_header(&c.header, c.trajectories.len(), x)?;
    let dims = |d: String| reject(DropReason::Dimensions, d);
    for (k, tr) in c.trajectories.iter().enumerate() {
        let at = |what: &str| format!("trajectory {k}: {what}");
        check_counts(k, tr.env, tr.len(), tr.episodes.len(), x)?;
        let max_site = x.n_sites.max(1) as u32;
        if let Some(s) = tr.sites.iter().find(|&&s| s >= max_site) {
            return Err(dims(at(&format!("site {s} outside 0..{max_site}"))));
        }
    }
    Ok(())
}

/// The header, the learner incarnation and the number of environments of a chunk.
fn check_chunk_header(h: &Header, envs: usize, x: &ChunkExpect) -> Result<(), Rejection> {
    check_header(h, x)?;
    if h.learner_incarnation != x.incarnation {
        return Err(reject(
            DropReason::Incarnation,
            format!(
                "acted with weights of learner incarnation {:016x}, this one is {:016x}",
                h.learner_incarnation, x.incarnation
            ),
        ));
    }
    if envs == 0 || envs > x.max_envs {
        return Err(reject(
            DropReason::Dimensions,
            format!("{envs} environments (1..={} allowed)", x.max_envs),
        ));
    }
    Ok(())
}

/// Trajectory `k`'s environment id, decisions `t` and episodes.
fn check_counts(
    k: usize,
    env: u32,
    t: usize,
    episodes: usize,
    x: &ChunkExpect,
) -> Result<(), Rejection> {
    let dims = |d: String| reject(DropReason::Dimensions, format!("trajectory {k}: {d}"));
    if env as usize >= x.max_envs {
        return Err(dims(format!(
            "environment id {env} outside 0..{}",
            x.max_envs
        )));
    }
    if t == 0 || t > x.max_steps {
        return Err(dims(format!("{t} steps (1..={} allowed)", x.max_steps)));
    }
    if episodes > t {
        return Err(dims(format!("{episodes} episodes in {t} steps")));
    }
    Ok(())
}

/// Validates an expanded chunk's header, sizes, dimensions and numbers (not its staleness,
/// which depends on the learner's version at use).
pub fn validate_chunk(c: &ExpandedChunk, x: &ChunkExpect) -> Result<(), Rejection> {
    check_chunk_header(&c.header, c.trajectories.len(), x)?;
    let dims = |d: String| reject(DropReason::Dimensions, d);
    for (k, tr) in c.trajectories.iter().enumerate() {
        let t = tr.len();
        let at = |what: &str| format!("trajectory {k}: {what}");
        check_counts(k, tr.env, t, tr.episodes.len(), x)?;
        if tr.obs_dim != x.obs_dim {
            return Err(dims(at(&format!(
                "observation size {}, expected {}",
                tr.obs_dim, x.obs_dim
            ))));
        }
        let want = [
            ("obs", tr.obs.len(), t * x.obs_dim),
            ("moves", tr.moves.len(), t * MOVE_DIM),
            ("sites", tr.sites.len(), t),
            ("logprobs", tr.logprobs.len(), t),
            ("site_logprobs", tr.site_logprobs.len(), t),
            ("values", tr.values.len(), t),
            ("terminated", tr.terminated.len(), t),
            ("truncated", tr.truncated.len(), t),
            ("next_values", tr.next_values.len(), t),
            ("bootstrap_obs", tr.bootstrap_obs.len(), x.obs_dim),
        ];
        for (name, got, expected) in want {
            if got != expected {
                return Err(dims(at(&format!(
                    "{name} has {got} values, expected {expected}"
                ))));
            }
        }
        if !tr.site_rewards.is_empty() && tr.site_rewards.len() != t * x.n_sites {
            return Err(dims(at(&format!(
                "site_rewards has {} values, expected 0 or {}",
                tr.site_rewards.len(),
                t * x.n_sites
            ))));
        }
        check_site_steps(tr, x).map_err(|w| dims(at(&w)))?;
        let max_site = x.n_sites.max(1) as u32;
        if let Some(s) = tr.sites.iter().find(|&&s| s >= max_site) {
            return Err(dims(at(&format!("site {s} outside 0..{max_site}"))));
        }
        if let Some(what) = tr.first_non_finite() {
            return Err(reject(DropReason::NonFinite, at(&what)));
        }
    }
    Ok(())
}

/// The per-step site fields of one trajectory against the expected shape.
fn check_site_steps(tr: &EnvTrajectory, x: &ChunkExpect) -> Result<(), String> {
    let Some(k) = x.site_steps else {
        let n = tr.decision_steps.len() + tr.step_site_features.len() + tr.step_site_rewards.len();
        return if n == 0 {
            Ok(())
        } else {
            Err(format!(
                "{n} per-step site values, expected none (env.site_every_step is off)"
            ))
        };
    };
    if tr.decision_steps.len() != tr.len() {
        return Err(format!(
            "decision_steps has {} values, expected {}",
            tr.decision_steps.len(),
            tr.len()
        ));
    }
    if let Some(s) = tr
        .decision_steps
        .iter()
        .find(|&&s| s == 0 || usize::from(s) > k.per_decision)
    {
        return Err(format!(
            "a decision of {s} steps (1..={} allowed)",
            k.per_decision
        ));
    }
    let rows: usize = tr.decision_steps.iter().map(|&s| usize::from(s)).sum();
    for (name, got, want) in [
        (
            "step_site_features",
            tr.step_site_features.len(),
            rows * x.n_sites * k.features,
        ),
        (
            "step_site_rewards",
            tr.step_site_rewards.len(),
            rows * x.n_sites,
        ),
    ] {
        if got != want {
            return Err(format!("{name} has {got} values, expected {want}"));
        }
    }
    if !tr.site_rewards.is_empty() {
        return Err("site_rewards with per-step site rewards".into());
    }
    Ok(())
}

/// Checks received weights against the actor's expectations (fingerprint, run, shapes,
/// finiteness).
pub fn validate_weights(w: &WeightsMsg, x: &ChunkExpect) -> Result<(), Rejection> {
    check_header(&w.header, x)?;
    let p = &w.policy;
    if p.obs_dim != x.obs_dim || p.n_sites != x.n_sites {
        return Err(reject(
            DropReason::Dimensions,
            format!(
                "policy for {} observations and {} sites, expected {} and {}",
                p.obs_dim, p.n_sites, x.obs_dim, x.n_sites
            ),
        ));
    }
    p.validate()
        .map_err(|e| reject(DropReason::Dimensions, e))?;
    if let Some(k) = x.site_steps {
        // A site chosen every step is scored by the equivariant head over these features.
        if p.site_head
            .as_ref()
            .is_none_or(|h| h.features != k.features)
        {
            return Err(reject(
                DropReason::Dimensions,
                format!(
                    "env.site_every_step needs the equivariant site head over {} features per site",
                    k.features
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests;
