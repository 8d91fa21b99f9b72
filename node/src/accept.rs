//! What the learner does with one received trajectory message, and which chunks train which
//! version. No zenoh here: the inbox hands over the sender (from the key) and the bytes, so
//! the rules are tested on their own.
//!
//! A message is decoded within its allocation budget ([`MsgLimits::chunk`]), must come from
//! the actor its key names, must pass [`validate_compact`] (run, learner incarnation, environment
//! fingerprint, counts), is expanded within the same budget ([`Expander::trajectory`]: the
//! columns' shapes, finite numbers), must pass [`validate_chunk`] expanded, and must not be a
//! replay ([`SeqTracker`]: at most once
//! per (actor, sender incarnation, seq)). A chunk waiting for PPO is **stale** when its version
//! is more than `distributed.max_policy_lag` behind the version being trained, or ahead of it
//! (a version this learner has not published).

use dupac_actor::expand::{ExpandError, Expander};
use dupac_common::dedup::{SeqTracker, Verdict};
use dupac_common::ids::ActorId;
use dupac_common::msg::{ExpandedChunk, MsgLimits, TrajectoryChunk, decode_msg};
use dupac_common::validate::{ChunkExpect, DropReason, validate_chunk, validate_compact};
use std::fmt;
use std::sync::Arc;

/// Why a message was refused: the drop counter it adds to, the kind of warning line it gets
/// and the detail.
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    pub reason: DropReason,
    /// The warning's kind (one line per kind per period).
    pub kind: &'static str,
    pub detail: String,
}

impl fmt::Display for Refusal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.kind, self.detail)
    }
}

/// The learner's acceptance of trajectory messages: what it expects, its decoding limits, the
/// expansion of the compact trajectories, and the sequence numbers seen.
#[derive(Debug)]
pub struct Acceptor {
    expect: ChunkExpect,
    limits: MsgLimits,
    expander: Arc<Expander>,
    seqs: SeqTracker,
    /// Time spent expanding since [`Acceptor::take_expand_time`] was last called.
    expand_time: std::time::Duration,
}

impl Acceptor {
    /// Accepts chunks matching `expect`, decoded and expanded (with `expander`) each within
    /// `limits`' budget.
    pub fn new(expect: ChunkExpect, limits: MsgLimits, expander: Arc<Expander>) -> Acceptor {
        Acceptor {
            expect,
            limits,
            expander,
            seqs: SeqTracker::new(),
            expand_time: std::time::Duration::ZERO,
        }
    }

    /// The chunk in `bytes`, received from `sender` on `key`, or why it is refused.
    pub fn accept(
        &mut self,
        sender: ActorId,
        key: &str,
        bytes: &[u8],
    ) -> Result<ExpandedChunk, Refusal> {
        let chunk: TrajectoryChunk = decode_msg(bytes, self.limits, key).map_err(|e| Refusal {
            reason: DropReason::of_codec(&e),
            kind: "undecodable chunk",
            detail: e.to_string(),
        })?;
        if chunk.header.actor != sender {
            return Err(Refusal {
                reason: DropReason::Garbage,
                kind: "chunk on another actor's key",
                detail: format!("actor {} on {key}", chunk.header.actor),
            });
        }
        let rejected = |r: dupac_common::validate::Rejection| Refusal {
            reason: r.reason,
            kind: "rejected chunk",
            detail: r.to_string(),
        };
        validate_compact(&chunk, &self.expect).map_err(rejected)?;
        let t0 = std::time::Instant::now();
        let chunk = self.expand(chunk);
        self.expand_time += t0.elapsed();
        let chunk = chunk?;
        validate_chunk(&chunk, &self.expect).map_err(rejected)?;
        let h = &chunk.header;
        match self.seqs.accept(h.actor, h.sender_incarnation, h.seq) {
            Verdict::Accept => Ok(chunk),
            Verdict::Replay { high_water } => Err(Refusal {
                reason: DropReason::Replay,
                kind: "replayed chunk",
                detail: format!("seq {} at or below {high_water} (already received)", h.seq),
            }),
            Verdict::TooManySenders => Err(Refusal {
                reason: DropReason::Overflow,
                kind: "chunk of one actor id too many",
                detail: "more actor ids than the learner tracks".into(),
            }),
        }
    }
}

impl Acceptor {
    /// The time spent expanding since the last call (zero after it).
    pub fn take_expand_time(&mut self) -> std::time::Duration {
        std::mem::take(&mut self.expand_time)
    }

    /// Each trajectory of `chunk` expanded, all of them within the decoding budget.
    fn expand(&self, chunk: TrajectoryChunk) -> Result<ExpandedChunk, Refusal> {
        let mut left = self.limits.budget_bytes;
        let mut trajectories = Vec::with_capacity(chunk.trajectories.len());
        for (k, c) in chunk.trajectories.iter().enumerate() {
            let tr = self.expander.trajectory(c, left).map_err(|e| Refusal {
                reason: match e {
                    ExpandError::Shape(_) => DropReason::Dimensions,
                    ExpandError::NonFinite(_) => DropReason::NonFinite,
                    ExpandError::OverBudget { .. } => DropReason::Overflow,
                },
                kind: "rejected chunk",
                detail: format!("trajectory {k}: {e}"),
            })?;
            left = left.saturating_sub(self.expander.expanded_bytes(c));
            trajectories.push(tr);
        }
        Ok(ExpandedChunk {
            header: chunk.header,
            trajectories,
        })
    }
}

/// Whether a chunk acted with `chunk_version` is stale for training `version` with
/// `max_policy_lag` (more than that many versions behind, or ahead of it).
pub fn is_stale(chunk_version: u64, version: u64, max_policy_lag: u64) -> bool {
    chunk_version > version || version - chunk_version > max_policy_lag
}

/// The node's unit tests' scenario: two sites 200 m apart in a 1 km square, the base method
/// (one state per decision, no site rows), the default observation otherwise.
#[cfg(test)]
pub(crate) fn test_expander() -> Arc<Expander> {
    use dupac_common::config::{Association, Config};
    use dupac_common::geometry::{Bounds2, Point, Point2};
    let mut cfg = Config::default();
    cfg.env.association = Association::A3;
    let area = Bounds2 {
        min_m: Point2::new(0.0, 0.0),
        max_m: Point2::new(1000.0, 1000.0),
    };
    let sites = vec![
        Point::new(400.0, 500.0, 30.0),
        Point::new(600.0, 500.0, 30.0),
    ];
    Arc::new(Expander::of_sites(&cfg, area, sites))
}

/// What the node's unit tests' learner expects: run `run-a`, incarnation 5, fingerprint 7,
/// [`test_expander`]'s observations, no site logits, up to 2 environments × 4 steps.
#[cfg(test)]
pub(crate) fn test_expect() -> ChunkExpect {
    ChunkExpect {
        run_id: "run-a".into(),
        incarnation: 5,
        fingerprint: 7,
        obs_dim: test_expander().layout().len(),
        n_sites: 0,
        max_envs: 2,
        max_steps: 4,
        site_steps: None,
    }
}

/// A valid chunk for `x` from `actor` with sequence number `seq`: one environment, one decision
/// in [`test_expander`]'s scenario (the node's unit tests).
#[cfg(test)]
pub(crate) fn one_step_chunk(x: &ChunkExpect, actor: u32, seq: u64) -> TrajectoryChunk {
    use dupac_common::compact::{CompactTrajectory, StateRow, TrunkRow};
    use dupac_common::msg::Header;
    let mut header = Header::new(&x.run_id, x.incarnation, ActorId(actor), x.fingerprint);
    header.sender_incarnation = 11;
    header.seq = seq;
    let expander = test_expander();
    let shape = expander.shape();
    let mut tr = CompactTrajectory {
        moves: vec![0.0; 3],
        sites: vec![0],
        logprobs: vec![-1.0],
        site_logprobs: vec![0.0],
        values: vec![0.5],
        rewards: vec![1.0],
        terminated: vec![false],
        truncated: vec![false],
        next_values: vec![0.5],
        decision_steps: vec![5],
        crashed: vec![false],
        ..CompactTrajectory::default()
    };
    let trunk = TrunkRow {
        destination_m: [700.0, 500.0, 60.0],
        ..TrunkRow::default()
    };
    let state = StateRow {
        position_m: [300.0, 500.0, 60.0],
        rsrp: vec![120, 110],
        ..StateRow::default()
    };
    for _ in 0..2 {
        tr.push_trunk(shape, &trunk);
        tr.push_state(shape, &state);
    }
    TrajectoryChunk {
        header,
        trajectories: vec![tr],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dupac_common::msg::encode_msg;

    fn expect() -> ChunkExpect {
        test_expect()
    }

    fn chunk(actor: u32, seq: u64) -> TrajectoryChunk {
        one_step_chunk(&expect(), actor, seq)
    }

    fn bytes(c: &TrajectoryChunk) -> Vec<u8> {
        encode_msg(c).expect("encode")
    }

    fn acceptor() -> Acceptor {
        Acceptor::new(expect(), MsgLimits::both(1 << 20), test_expander())
    }

    #[test]
    fn a_valid_chunk_is_accepted_once() {
        let mut a = acceptor();
        let c = chunk(3, 0);
        let got = a.accept(ActorId(3), "k", &bytes(&c)).expect("accepted");
        let want = test_expander()
            .trajectory(&c.trajectories[0], usize::MAX)
            .expect("expands");
        assert_eq!(
            (got.header, got.trajectories),
            (c.header.clone(), vec![want])
        );
        let again = a.accept(ActorId(3), "k", &bytes(&c)).expect_err("a replay");
        assert_eq!(again.reason, DropReason::Replay);
        assert!(a.accept(ActorId(3), "k", &bytes(&chunk(3, 1))).is_ok());
    }

    #[test]
    fn garbage_another_actors_key_and_another_run_are_refused_by_name() {
        let mut a = acceptor();
        let r = a
            .accept(ActorId(3), "k", b"not a chunk")
            .expect_err("garbage");
        assert_eq!(r.kind, "undecodable chunk");
        let r = a
            .accept(ActorId(4), "dupac/run-a/traj/4", &bytes(&chunk(3, 0)))
            .expect_err("another actor's key");
        assert_eq!(r.reason, DropReason::Garbage);
        assert!(r.detail.contains("actor 3 on dupac/run-a/traj/4"), "{r}");
        let mut other = chunk(3, 0);
        other.header.run_id = "run-b".into();
        let r = a
            .accept(ActorId(3), "k", &bytes(&other))
            .expect_err("another run");
        assert_eq!(r.reason, DropReason::WrongRun);
        // A refused chunk does not count as received: the same seq, valid, is accepted.
        assert!(a.accept(ActorId(3), "k", &bytes(&chunk(3, 0))).is_ok());
    }

    #[test]
    fn a_message_over_the_decoding_budget_is_refused_as_too_large() {
        let mut a = Acceptor::new(expect(), MsgLimits::both(64), test_expander());
        let r = a
            .accept(ActorId(3), "k", &bytes(&chunk(3, 0)))
            .expect_err("over budget");
        assert_eq!(r.reason, DropReason::TooLarge);
    }

    /// A chunk whose columns do not hold its decisions is refused by the expansion, naming the
    /// column; one that fits the decoding budget but whose expansion would not is refused as
    /// an overflow (seen failing with the expansion's budget check removed).
    #[test]
    fn the_expansion_checks_shapes_and_its_budget() {
        let mut a = acceptor();
        let mut bad = chunk(3, 0);
        bad.trajectories[0].rsrp_codes.pop();
        let r = a
            .accept(ActorId(3), "k", &bytes(&bad))
            .expect_err("a short column");
        assert_eq!(r.reason, DropReason::Dimensions);
        assert!(r.detail.contains("rsrp_codes"), "{r}");
        let mut nan = chunk(3, 1);
        nan.trajectories[0].position_m[1] = f32::NAN;
        let r = a.accept(ActorId(3), "k", &bytes(&nan)).expect_err("NaN");
        assert_eq!(r.reason, DropReason::NonFinite);
        // With the site learned every step, the expansion (every step's site features and
        // rewards) needs far more than decoding the message (its compressed body and compact
        // columns): a budget between the two.
        let mut cfg = dupac_common::config::Config::default();
        cfg.env.association = dupac_common::config::Association::Learned;
        let learned = Arc::new(Expander::of_sites(
            &cfg,
            dupac_common::geometry::Bounds2 {
                min_m: dupac_common::geometry::Point2::new(0.0, 0.0),
                max_m: dupac_common::geometry::Point2::new(1000.0, 1000.0),
            },
            vec![
                dupac_common::geometry::Point::new(400.0, 500.0, 30.0),
                dupac_common::geometry::Point::new(600.0, 500.0, 30.0),
            ],
        ));
        let x = ChunkExpect {
            obs_dim: learned.layout().len(),
            n_sites: 2,
            site_steps: dupac_common::validate::SiteSteps::of(&cfg),
            ..expect()
        };
        let mut c = chunk(3, 2);
        c.trajectories = vec![learned.sample_trajectory(4, 9)];
        let need = learned.expanded_bytes(&c.trajectories[0]);
        let mut tight = Acceptor::new(x.clone(), MsgLimits::both(need - 1), learned.clone());
        let r = tight
            .accept(ActorId(3), "k", &bytes(&c))
            .expect_err("over the expansion budget");
        assert_eq!(r.reason, DropReason::Overflow, "{r}");
        let mut enough = Acceptor::new(x, MsgLimits::both(need), learned);
        assert!(enough.accept(ActorId(3), "k", &bytes(&c)).is_ok());
    }

    #[test]
    fn a_chunk_more_than_the_lag_behind_or_ahead_is_stale() {
        assert!(!is_stale(10, 10, 1));
        assert!(!is_stale(9, 10, 1));
        assert!(is_stale(8, 10, 1));
        assert!(is_stale(11, 10, 1), "a version not published yet");
        assert!(!is_stale(7, 10, 3));
    }
}
