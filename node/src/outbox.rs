//! The chunk outbox of an actor: the headers it sends under, its sequence numbers, its share of
//! each policy version, and when to send a share again. No zenoh here: the node sends what it
//! wraps, so the rules are tested on their own.
//!
//! * **Headers**: one builder for chunks and stats, carrying the run, the learner incarnation
//!   the data was acted for, this actor's id, the environment fingerprint, this process's
//!   random id (`sender_incarnation`, new on every start, so that the learner's replay check
//!   never mistakes a restarted actor's chunks for replays) and the policy version acted with.
//! * **Sequence numbers**: 0, 1, 2, … per process, one per chunk (the learner drops anything at
//!   or below the highest it has seen from this process).
//! * **Share**: the learner needs about one batch per version, so an actor sends at most
//!   `cap` chunks of a version (`distributed.chunks_per_version` with the actors alive) and
//!   then waits for the next version.
//! * **Re-send**: delivery is at most once; when the learner is still at the version this
//!   actor sent its share for `resend_after` after the swap, chunks were lost (a partition, a
//!   router restart) and the actor sends another share rather than wait for ever.

use crate::intake::WeightsKey;
use dupac_common::ids::ActorId;
use dupac_common::msg::{EnvTrajectory, Header, TrajectoryChunk};
use std::time::{Duration, Instant};

/// An actor's outgoing chunks.
#[derive(Debug, Clone)]
pub struct ChunkOutbox {
    run: String,
    actor: ActorId,
    fingerprint: u64,
    sender_incarnation: u64,
    resend_after: Duration,
    /// Sequence number of the next chunk.
    seq: u64,
    /// The weights the chunks are acted with, and when they were swapped in.
    acting: Option<(WeightsKey, Instant)>,
    /// Chunks sent of the current version's share.
    sent_of_share: usize,
}

impl ChunkOutbox {
    /// The outbox of actor `actor` of `run` in world `fingerprint`; `sender_incarnation` is this
    /// process's random id; a share is sent again when the learner is still at its version
    /// `resend_after` after the swap.
    pub fn new(
        run: &str,
        actor: ActorId,
        fingerprint: u64,
        sender_incarnation: u64,
        resend_after: Duration,
    ) -> ChunkOutbox {
        ChunkOutbox {
            run: run.to_string(),
            actor,
            fingerprint,
            sender_incarnation,
            resend_after,
            seq: 0,
            acting: None,
            sent_of_share: 0,
        }
    }

    /// The header of this actor's next message acted with `key` (sequence number: the next
    /// chunk's).
    pub fn header(&self, key: WeightsKey) -> Header {
        let mut h = Header::new(&self.run, key.incarnation, self.actor, self.fingerprint);
        h.sender_incarnation = self.sender_incarnation;
        h.seq = self.seq;
        h.policy_version = key.version;
        h
    }

    /// The weights the chunks are acted with.
    pub fn acting(&self) -> Option<WeightsKey> {
        self.acting.map(|(k, _)| k)
    }

    /// Acts with `key` from now on; `true` when that is a swap (other weights than before), which
    /// starts a new share.
    pub fn swap(&mut self, key: WeightsKey) -> bool {
        self.swap_at(key, Instant::now())
    }

    /// [`ChunkOutbox::swap`] at `now`.
    pub fn swap_at(&mut self, key: WeightsKey, now: Instant) -> bool {
        if self.acting() == Some(key) {
            return false;
        }
        self.acting = Some((key, now));
        self.sent_of_share = 0;
        true
    }

    /// Whether this version's share (`cap` chunks) is sent.
    pub fn at_cap(&self, cap: usize) -> bool {
        self.acting.is_some() && self.sent_of_share >= cap
    }

    /// The learner answered a query with `learner_at`: when that is still the version this
    /// actor acts with, `resend_after` after the swap, its share was lost in transit, and a new
    /// share starts (`true`, once per `resend_after`).
    pub fn resend_if_lost(&mut self, learner_at: WeightsKey) -> bool {
        self.resend_if_lost_at(learner_at, Instant::now())
    }

    /// [`ChunkOutbox::resend_if_lost`] at `now`.
    pub fn resend_if_lost_at(&mut self, learner_at: WeightsKey, now: Instant) -> bool {
        match &mut self.acting {
            Some((key, since))
                if *key == learner_at
                    && now.saturating_duration_since(*since) > self.resend_after =>
            {
                *since = now;
                self.sent_of_share = 0;
                true
            }
            _ => false,
        }
    }

    /// Wraps `trajectories` acted with the current weights into the next chunk (its sequence
    /// number taken, counted in the share); `None` before any weights.
    pub fn wrap(&mut self, trajectories: Vec<EnvTrajectory>) -> Option<TrajectoryChunk> {
        let key = self.acting()?;
        let chunk = TrajectoryChunk {
            header: self.header(key),
            trajectories,
        };
        self.seq += 1;
        self.sent_of_share += 1;
        Some(chunk)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn key(incarnation: u64, version: u64) -> WeightsKey {
        WeightsKey {
            incarnation,
            version,
        }
    }

    fn outbox(resend_after: Duration) -> ChunkOutbox {
        ChunkOutbox::new("run-a", ActorId(3), 7, 0xabc, resend_after)
    }

    #[test]
    fn chunks_carry_the_header_and_consecutive_sequence_numbers() {
        let mut o = outbox(Duration::from_secs(5));
        assert!(o.wrap(Vec::new()).is_none(), "no chunk before any weights");
        o.swap(key(2, 10));
        let seqs: Vec<u64> = (0..3)
            .map(|_| o.wrap(Vec::new()).expect("chunk").header.seq)
            .collect();
        assert_eq!(seqs, [0, 1, 2]);
        o.swap(key(2, 11));
        let c = o.wrap(Vec::new()).expect("chunk");
        let h = &c.header;
        assert_eq!(
            (h.seq, h.policy_version, h.learner_incarnation),
            (3, 11, 2),
            "sequence numbers run on across versions"
        );
        assert_eq!(
            (h.run_id.as_str(), h.actor, h.config_fingerprint),
            ("run-a", ActorId(3), 7)
        );
        assert_eq!(h.sender_incarnation, 0xabc);
        // Stats go under the same header as the next chunk.
        let s = o.header(key(2, 11));
        assert_eq!(
            (s.seq, s.sender_incarnation, s.policy_version),
            (4, 0xabc, 11)
        );
    }

    #[test]
    fn a_share_is_capped_and_a_swap_starts_the_next() {
        let mut o = outbox(Duration::from_secs(5));
        assert!(!o.at_cap(2), "no weights: nothing to cap");
        assert!(o.swap(key(1, 1)));
        o.wrap(Vec::new());
        assert!(!o.at_cap(2));
        o.wrap(Vec::new());
        assert!(o.at_cap(2));
        assert!(!o.swap(key(1, 1)), "the same weights are not a swap");
        assert!(o.at_cap(2), "and do not reopen the share");
        assert!(o.swap(key(1, 2)));
        assert!(!o.at_cap(2));
    }

    #[test]
    fn a_lost_share_is_sent_again_once_per_period() {
        let period = Duration::from_secs(5);
        let mut o = outbox(period);
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        o.swap_at(key(1, 4), t0);
        o.wrap(Vec::new());
        o.wrap(Vec::new());
        assert!(o.at_cap(2));
        assert!(
            !o.resend_if_lost_at(key(1, 4), at(4.9)),
            "too early: the learner may still be training"
        );
        assert!(
            !o.resend_if_lost_at(key(1, 5), at(5.1)),
            "the learner moved on: nothing was lost"
        );
        assert!(
            !o.resend_if_lost_at(key(2, 4), at(5.1)),
            "another learner incarnation: not our share"
        );
        assert!(o.resend_if_lost_at(key(1, 4), at(5.1)));
        assert!(!o.at_cap(2), "a new share starts");
        assert!(!o.resend_if_lost_at(key(1, 4), at(10.0)), "once per period");
        assert!(o.resend_if_lost_at(key(1, 4), at(10.2)));
    }

    /// The clock the actor uses: a share swapped in now is not re-sent at once.
    #[test]
    fn a_share_is_not_resent_before_its_period_on_the_real_clock() {
        let mut o = outbox(Duration::from_secs(3600));
        o.swap(key(1, 4));
        assert!(!o.resend_if_lost(key(1, 4)));
    }
}
