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
//!   actor sent its share for `resend_after` after the share's last chunk left (not after it was
//!   wrapped: on a slow link a share takes seconds to leave), chunks were lost (a partition, a
//!   router restart) and the actor sends another share rather than wait for ever.
//! * **Staleness before sending** ([`Delivery`]): a queued chunk the learner would drop as too
//!   old (`distributed.max_policy_lag`) by the time it leaves is dropped instead of sent.

use crate::intake::WeightsKey;
use dupac_common::compact::CompactTrajectory;
use dupac_common::ids::ActorId;
use dupac_common::msg::{Header, TrajectoryChunk};
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
    /// The last chunk that left (sent, or dropped as stale) and when.
    left: Option<(u64, Instant)>,
}

impl ChunkOutbox {
    /// The outbox of actor `actor` of `run` in world `fingerprint`; `sender_incarnation` is this
    /// process's random id; a share is sent again when the learner is still at its version
    /// `resend_after` after the share's last chunk left.
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
            left: None,
        }
    }

    /// Chunk `seq` left at `at` (the network side sent it, or dropped it as stale).
    pub fn left(&mut self, seq: u64, at: Instant) {
        if self.left.is_none_or(|(s, _)| seq > s) {
            self.left = Some((seq, at));
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
    /// actor acts with, every chunk wrapped has left, and `resend_after` has passed since the
    /// swap and since the last chunk left, its share was lost in transit, and a new share starts
    /// (`true`, once per `resend_after`).
    pub fn resend_if_lost(&mut self, learner_at: WeightsKey) -> bool {
        self.resend_if_lost_at(learner_at, Instant::now())
    }

    /// [`ChunkOutbox::resend_if_lost`] at `now`.
    pub fn resend_if_lost_at(&mut self, learner_at: WeightsKey, now: Instant) -> bool {
        let all_left = self.seq == 0 || self.left.is_some_and(|(s, _)| s + 1 >= self.seq);
        let last_left = self.left.map(|(_, at)| at);
        match &mut self.acting {
            Some((key, since))
                if *key == learner_at
                    && all_left
                    && now
                        .saturating_duration_since(last_left.map_or(*since, |l| l.max(*since)))
                        > self.resend_after =>
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
    pub fn wrap(&mut self, trajectories: Vec<CompactTrajectory>) -> Option<TrajectoryChunk> {
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

/// Whether a chunk acted with `chunk` is too old for a learner known to be at `learner` (or
/// later): another learner incarnation (its chunks are refused), or stale by the learner's rule
/// ([`crate::accept::is_stale`]). A chunk of a version newer than the one known is not: the
/// learner is there already.
pub fn is_stale(chunk: WeightsKey, learner: WeightsKey, max_policy_lag: u64) -> bool {
    chunk.incarnation != learner.incarnation
        || (chunk.version <= learner.version
            && crate::accept::is_stale(chunk.version, learner.version, max_policy_lag))
}

/// What an actor's thread and its network side share about outgoing chunks: the newest weights
/// the learner is known to be at (from publications and query answers), which chunk left last,
/// and the chunks dropped as stale before sending.
#[derive(Debug, Clone)]
pub struct Delivery {
    max_policy_lag: u64,
    learner_at: Option<WeightsKey>,
    left: Option<(u64, Instant)>,
    /// Chunks dropped before sending: stale by the time their turn came.
    pub dropped_stale: u64,
}

impl Delivery {
    /// Delivery of chunks for a learner keeping `max_policy_lag` versions
    /// (`distributed.max_policy_lag`).
    pub fn new(max_policy_lag: u64) -> Delivery {
        Delivery {
            max_policy_lag,
            learner_at: None,
            left: None,
            dropped_stale: 0,
        }
    }

    /// The learner is at `key` (or later).
    pub fn learner_at(&mut self, key: WeightsKey) {
        let newer = self
            .learner_at
            .is_none_or(|k| k.incarnation != key.incarnation || key.version > k.version);
        if newer {
            self.learner_at = Some(key);
        }
    }

    /// Chunk `seq` acted with `key` is next to leave at `now`: `true` to send it, `false` when it
    /// turned stale while queued (counted; it has left all the same).
    pub fn admit(&mut self, seq: u64, key: WeightsKey, now: Instant) -> bool {
        let fresh = self
            .learner_at
            .is_none_or(|l| !is_stale(key, l, self.max_policy_lag));
        if !fresh {
            self.dropped_stale += 1;
            self.left = Some((seq, now));
        }
        fresh
    }

    /// Chunk `seq` was handed to zenoh at `now`.
    pub fn sent(&mut self, seq: u64, now: Instant) {
        self.left = Some((seq, now));
    }

    /// The last chunk that left, and when.
    pub fn last_left(&self) -> Option<(u64, Instant)> {
        self.left
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
        o.left(1, t0);
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

    /// On a slow link a share leaves long after it was wrapped: the period counts from the
    /// last chunk that left, and nothing is sent again while chunks are still queued.
    #[test]
    fn a_share_still_leaving_is_not_sent_again() {
        let mut o = outbox(Duration::from_secs(5));
        let t0 = Instant::now();
        let at = |s: f64| t0 + Duration::from_secs_f64(s);
        o.swap_at(key(1, 4), t0);
        o.wrap(Vec::new()); // seq 0
        o.wrap(Vec::new()); // seq 1
        o.left(0, at(8.0));
        assert!(
            !o.resend_if_lost_at(key(1, 4), at(9.0)),
            "chunk 1 is still queued: nothing lost yet"
        );
        o.left(1, at(15.0));
        assert!(
            !o.resend_if_lost_at(key(1, 4), at(19.0)),
            "4 s after the share left: the learner may still be training"
        );
        assert!(o.resend_if_lost_at(key(1, 4), at(20.5)));
    }

    #[test]
    fn a_chunk_that_turned_stale_in_the_queue_is_not_sent() {
        let mut d = Delivery::new(1);
        let t0 = Instant::now();
        assert!(d.admit(0, key(1, 4), t0), "no learner version known: send");
        d.learner_at(key(1, 5));
        assert!(
            d.admit(1, key(1, 4), t0),
            "one version behind: still trained on"
        );
        d.learner_at(key(1, 3));
        d.learner_at(key(1, 6));
        assert!(
            !d.admit(2, key(1, 4), t0),
            "two behind: the learner drops it"
        );
        assert!(d.admit(3, key(1, 6), t0));
        d.learner_at(key(2, 1));
        assert!(!d.admit(4, key(1, 6), t0), "another learner incarnation");
        assert_eq!(d.dropped_stale, 2);
        assert_eq!(
            d.last_left().map(|(s, _)| s),
            Some(4),
            "a dropped chunk has left"
        );
        d.sent(5, t0);
        assert_eq!(d.last_left().map(|(s, _)| s), Some(5));
    }

    /// The clock the actor uses: a share swapped in now is not re-sent at once.
    #[test]
    fn a_share_is_not_resent_before_its_period_on_the_real_clock() {
        let mut o = outbox(Duration::from_secs(3600));
        o.swap(key(1, 4));
        assert!(!o.resend_if_lost(key(1, 4)));
    }
}
