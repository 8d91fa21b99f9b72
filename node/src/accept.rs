//! What the learner does with one received trajectory message, and which chunks train which
//! version. No zenoh here: the inbox hands over the sender (from the key) and the bytes, so
//! the rules are tested on their own.
//!
//! A message is decoded within its allocation budget ([`MsgLimits::chunk`]), must come from
//! the actor its key names, must pass [`validate_chunk`] (run, learner incarnation, environment
//! fingerprint, shapes, finite numbers) and must not be a replay ([`SeqTracker`]: at most once
//! per (actor, sender incarnation, seq)). A chunk waiting for PPO is **stale** when its version
//! is more than `distributed.max_policy_lag` behind the version being trained, or ahead of it
//! (a version this learner has not published).

use dupac_common::dedup::{SeqTracker, Verdict};
use dupac_common::ids::ActorId;
use dupac_common::msg::{MsgLimits, TrajectoryChunk, decode_msg};
use dupac_common::validate::{ChunkExpect, DropReason, validate_chunk};
use std::fmt;

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

/// The learner's acceptance of trajectory messages: what it expects, its decoding limits, and
/// the sequence numbers seen.
#[derive(Debug)]
pub struct Acceptor {
    expect: ChunkExpect,
    limits: MsgLimits,
    seqs: SeqTracker,
}

impl Acceptor {
    /// Accepts chunks matching `expect`, decoded within `limits`.
    pub fn new(expect: ChunkExpect, limits: MsgLimits) -> Acceptor {
        Acceptor {
            expect,
            limits,
            seqs: SeqTracker::new(),
        }
    }

    /// The chunk in `bytes`, received from `sender` on `key`, or why it is refused.
    pub fn accept(
        &mut self,
        sender: ActorId,
        key: &str,
        bytes: &[u8],
    ) -> Result<TrajectoryChunk, Refusal> {
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
        validate_chunk(&chunk, &self.expect).map_err(|r| Refusal {
            reason: r.reason,
            kind: "rejected chunk",
            detail: r.to_string(),
        })?;
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

/// Whether a chunk acted with `chunk_version` is stale for training `version` with
/// `max_policy_lag` (more than that many versions behind, or ahead of it).
pub fn is_stale(chunk_version: u64, version: u64, max_policy_lag: u64) -> bool {
    chunk_version > version || version - chunk_version > max_policy_lag
}

/// What the node's unit tests' learner expects: run `run-a`, incarnation 5, fingerprint 7,
/// `obs_dim` observations, no sites, up to 2 environments × 4 steps.
#[cfg(test)]
pub(crate) fn test_expect(obs_dim: usize) -> ChunkExpect {
    ChunkExpect {
        run_id: "run-a".into(),
        incarnation: 5,
        fingerprint: 7,
        obs_dim,
        n_sites: 0,
        max_envs: 2,
        max_steps: 4,
        site_steps: None,
    }
}

/// A valid chunk for `x` from `actor` with sequence number `seq`: one environment, one step
/// (the node's unit tests).
#[cfg(test)]
pub(crate) fn one_step_chunk(x: &ChunkExpect, actor: u32, seq: u64) -> TrajectoryChunk {
    use dupac_common::msg::{EnvTrajectory, Header};
    let mut header = Header::new(&x.run_id, x.incarnation, ActorId(actor), x.fingerprint);
    header.sender_incarnation = 11;
    header.seq = seq;
    TrajectoryChunk {
        header,
        trajectories: vec![EnvTrajectory {
            obs_dim: x.obs_dim,
            obs: vec![0.1; x.obs_dim],
            moves: vec![0.0; 3],
            sites: vec![0],
            logprobs: vec![-1.0],
            site_logprobs: vec![0.0],
            values: vec![0.5],
            rewards: vec![1.0],
            terminated: vec![false],
            truncated: vec![false],
            next_values: vec![0.5],
            bootstrap_obs: vec![0.1; x.obs_dim],
            ..EnvTrajectory::default()
        }],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dupac_common::msg::encode_msg;

    fn expect() -> ChunkExpect {
        test_expect(2)
    }

    fn chunk(actor: u32, seq: u64) -> TrajectoryChunk {
        one_step_chunk(&expect(), actor, seq)
    }

    fn bytes(c: &TrajectoryChunk) -> Vec<u8> {
        encode_msg(c).expect("encode")
    }

    fn acceptor() -> Acceptor {
        Acceptor::new(expect(), MsgLimits::both(1 << 20))
    }

    #[test]
    fn a_valid_chunk_is_accepted_once() {
        let mut a = acceptor();
        let c = chunk(3, 0);
        assert_eq!(a.accept(ActorId(3), "k", &bytes(&c)), Ok(c.clone()));
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
        let mut a = Acceptor::new(expect(), MsgLimits::both(64));
        let r = a
            .accept(ActorId(3), "k", &bytes(&chunk(3, 0)))
            .expect_err("over budget");
        assert_eq!(r.reason, DropReason::TooLarge);
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
