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
mod tests {
    use super::*;
    use crate::compact::{CompactShape, CompactTrajectory, StateRow, TrunkRow};
    use crate::ids::ActorId;
    use crate::msg::{
        Command, ControlMsg, EnvTrajectory, EpisodeSummary, Outcome, decode_msg, encode_msg,
    };

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

    /// A compact chunk of two decisions, one state each (no learned site).
    fn wire() -> TrajectoryChunk {
        let mut h = Header::new("r", 7, ActorId(1), 9);
        h.policy_version = 3;
        let shape = CompactShape {
            n_sites: 3,
            path_guide: false,
            path_offset: false,
            sensor_fan: false,
            learned: false,
            lookahead: 0,
            stay: false,
            true_rsrp_every_step: false,
        };
        let mut tr = CompactTrajectory {
            moves: vec![0.0; 6],
            sites: vec![0, 2],
            logprobs: vec![-1.0; 2],
            site_logprobs: vec![0.0; 2],
            values: vec![0.5; 2],
            rewards: vec![1.0; 2],
            terminated: vec![false, true],
            truncated: vec![false; 2],
            next_values: vec![0.5, 0.0],
            decision_steps: vec![1, 1],
            crashed: vec![false; 2],
            ..CompactTrajectory::default()
        };
        let state = StateRow {
            rsrp: vec![100, 0, 255],
            los: vec![0],
            ..StateRow::default()
        };
        for _ in 0..3 {
            tr.push_trunk(&shape, &TrunkRow::default());
            tr.push_state(&shape, &state);
        }
        assert_eq!(tr.shape_error(&shape, 1), None);
        TrajectoryChunk {
            header: h,
            trajectories: vec![tr],
        }
    }

    fn chunk() -> ExpandedChunk {
        let mut h = Header::new("r", 7, ActorId(1), 9);
        h.policy_version = 3;
        ExpandedChunk {
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
        let c = wire();
        let bytes = encode_msg(&c).expect("encode");
        let d: TrajectoryChunk = decode_msg(&bytes, lim(1 << 20), "k").expect("decode");
        assert_eq!(d, c);
        assert_eq!(validate_compact(&d, &expect()), Ok(()));
        assert_eq!(validate_chunk(&chunk(), &expect()), Ok(()));
    }

    /// Each defect of a chunk's header has its reason, whatever the chunk (`reason` validates
    /// one with the header changed by its argument).
    /// A validation of a chunk whose header its argument changes.
    type HeaderCase<'a> = &'a dyn Fn(&dyn Fn(&mut Header)) -> Result<(), DropReason>;

    fn header_defects(reason: HeaderCase<'_>) {
        assert_eq!(
            reason(&|h| h.run_id = "x".into()),
            Err(DropReason::WrongRun)
        );
        assert_eq!(reason(&|h| h.schema_version = 0), Err(DropReason::Schema));
        assert_eq!(
            reason(&|h| h.config_fingerprint = 1),
            Err(DropReason::Fingerprint)
        );
        assert_eq!(
            reason(&|h| h.learner_incarnation = 1),
            Err(DropReason::Incarnation)
        );
    }

    #[test]
    fn every_defect_of_a_compact_chunk_has_its_reason() {
        let x = expect();
        let reason = |f: &dyn Fn(&mut TrajectoryChunk)| {
            let mut c = wire();
            f(&mut c);
            validate_compact(&c, &x).map_err(|r| r.reason)
        };
        assert_eq!(reason(&|_| {}), Ok(()));
        header_defects(&|f| reason(&|c| f(&mut c.header)));
        assert_eq!(
            reason(&|c| c.trajectories[0].sites[1] = 3),
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
            reason(&|c| c.trajectories[0].rewards = vec![0.0; 9]),
            Err(DropReason::Dimensions)
        );
    }

    #[test]
    fn every_defect_has_its_reason() {
        let x = expect();
        let reason = |f: &dyn Fn(&mut ExpandedChunk)| {
            let mut c = chunk();
            f(&mut c);
            validate_chunk(&c, &x).map_err(|r| r.reason)
        };
        header_defects(&|f| reason(&|c| f(&mut c.header)));
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
        let bytes = encode_msg(&wire()).expect("encode");
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
        // A message of another kind (a JSON control message) is not a chunk.
        let w = crate::jsonmsg::encode_json(&ControlMsg {
            header: Header::new("r", 7, ActorId::LEARNER, 9),
            command: Command::Stop,
        })
        .expect("encode");
        let e = decode_msg::<TrajectoryChunk>(&w, lim(1 << 20), "k").expect_err("kind");
        assert_eq!(DropReason::of_codec(&e), DropReason::Garbage);
    }

    /// A compact chunk with every vector at its largest for `shape`: `max_envs × max_steps`
    /// decisions of `env.action_repeat` steps, one episode per decision.
    fn maximal(x: &ChunkExpect, shape: &CompactShape, repeat: u16) -> TrajectoryChunk {
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
        let m = shape.n_sites;
        let state = StateRow {
            position_m: [1.0; 3],
            velocity_xy: [u16::MAX; 2],
            serving: m as u16 - 1,
            ping_pong: m as u16,
            rsrp: vec![255; m],
            los: vec![255; shape.los_bytes()],
            lookahead: vec![255; m * shape.lookahead],
            stay: vec![255; if shape.stay { m } else { 0 }],
            choice: m as u16,
        };
        let trunk = TrunkRow {
            velocity_z: u16::MAX,
            ..TrunkRow::default()
        };
        let per = usize::from(repeat);
        // Steps with site rows: every decision's, when the site is learned.
        let rows = if shape.learned { t * per } else { 0 };
        let states = if shape.learned { t * per } else { t };
        TrajectoryChunk {
            header: h,
            trajectories: (0..x.max_envs)
                .map(|k| {
                    let mut tr = CompactTrajectory {
                        env: k as u32,
                        moves: vec![1.0; t * MOVE_DIM],
                        sites: vec![x.n_sites.max(1) as u32 - 1; t],
                        logprobs: vec![1.0; t],
                        site_logprobs: vec![1.0; t],
                        values: vec![1.0; t],
                        rewards: vec![1.0; t],
                        terminated: vec![true; t],
                        truncated: vec![false; t],
                        next_values: vec![1.0; t],
                        decision_steps: vec![repeat; t],
                        crashed: vec![true; t],
                        progress_m: vec![1.0; rows],
                        common_reward: vec![1.0; rows],
                        reward_rsrp_codes: vec![255; rows * m],
                        episodes: vec![summary.clone(); t],
                        ..CompactTrajectory::default()
                    };
                    for _ in 0..=t {
                        tr.push_trunk(shape, &trunk);
                    }
                    for _ in 0..=states {
                        tr.push_state(shape, &state);
                    }
                    assert_eq!(tr.shape_error(shape, per), None);
                    tr
                })
                .collect(),
        }
    }

    /// The budget derived from the expected shape ([`ChunkExpect::budget_bytes`], which also
    /// bounds the expansion) admits the largest valid compact chunk, on the wire and decoded:
    /// the default scenario's 30 sites, 5 steps per decision, three look-ahead distances, the
    /// stay fractions and the true RSRP of every step (the largest per-state columns).
    #[test]
    fn the_largest_valid_chunk_fits_its_derived_limits() {
        let x = ChunkExpect {
            run_id: "r".repeat(64),
            obs_dim: 108 + 30 * 15,
            n_sites: 30,
            max_envs: 4,
            max_steps: 128,
            site_steps: Some(SiteSteps {
                per_decision: 5,
                features: 15,
            }),
            ..expect()
        };
        let shape = CompactShape {
            n_sites: 30,
            path_guide: true,
            path_offset: true,
            sensor_fan: true,
            learned: true,
            lookahead: 3,
            stay: true,
            true_rsrp_every_step: true,
        };
        let c = maximal(&x, &shape, 5);
        let bytes = encode_msg(&c).expect("encode");
        let need = x.budget_bytes();
        assert!(bytes.len() <= need, "{} > {need}", bytes.len());
        let d: TrajectoryChunk =
            decode_msg(&bytes, MsgLimits::both(need), "k").expect("fits its budget");
        assert_eq!(d, c);
        assert_eq!(d.samples(), 4 * 128);
        // The base method's: one state per decision, no site rows.
        let base = ChunkExpect {
            obs_dim: 108 + 30 * 11,
            n_sites: 0,
            site_steps: None,
            ..x.clone()
        };
        let shape = CompactShape {
            learned: false,
            lookahead: 0,
            stay: false,
            ..shape
        };
        let c = maximal(&base, &shape, 5);
        let bytes = encode_msg(&c).expect("encode");
        let need = base.budget_bytes();
        assert!(bytes.len() <= need, "{} > {need}", bytes.len());
        decode_msg::<TrajectoryChunk>(&bytes, MsgLimits::both(need), "k").expect("fits");
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
        let good = |c: &mut ExpandedChunk| {
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
        // 200 000 empty trajectories: ≈ 6 MB on the wire, ≈ 150 MB decoded. Under a byte
        // limit that admits it, the budget of a 4 × 128-step chunk refuses it.
        let x = expect();
        let mut c = wire();
        c.trajectories = vec![CompactTrajectory::default(); 200_000];
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
