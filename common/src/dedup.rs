//! At-most-once acceptance of trajectory chunks.
//!
//! Each actor process numbers its chunks 0, 1, 2, … ([`crate::msg::Header::seq`]) under a random
//! id drawn at its start ([`crate::msg::Header::sender_incarnation`]). The learner keeps, per
//! (actor id, sender incarnation), the highest sequence number it accepted: a chunk at or below
//! it is a duplicate or a replay and is refused ([`crate::validate::DropReason::Replay`]). Zenoh
//! delivers one publisher's samples in order, so an honest actor's chunks arrive with rising
//! numbers and a lost chunk only leaves a gap, which is allowed.
//!
//! Memory is bounded: at most [`MAX_INCARNATIONS`] incarnations per actor id (the least recently
//! accepted is forgotten first) and [`MAX_TRACKED_SENDERS`] actor ids; a chunk from an actor id
//! beyond that is refused ([`Verdict::TooManySenders`]), never tracked (an id is never forgotten:
//! forgetting one would let its old chunks be replayed). What is therefore not
//! promised: a chunk of an actor incarnation forgotten because the same id restarted more than
//! [`MAX_INCARNATIONS`] times since; it is still subject to the learner-incarnation and
//! staleness checks, so it can be trained only if it was acted with the learner's current or
//! previous version.

use crate::ids::ActorId;
use std::collections::BTreeMap;

/// Incarnations remembered per actor id.
pub const MAX_INCARNATIONS: usize = 8;
/// Actor ids tracked at once (a run has at most a few hundred actors).
pub const MAX_TRACKED_SENDERS: usize = 4096;

/// What [`SeqTracker::accept`] decided.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// New data: accepted and recorded.
    Accept,
    /// Its sequence number is at or below the high-water mark of its (actor, incarnation).
    Replay { high_water: u64 },
    /// A new actor id while [`MAX_TRACKED_SENDERS`] are tracked.
    TooManySenders,
}

#[derive(Debug, Clone)]
struct Mark {
    incarnation: u64,
    high_water: u64,
    /// Accept counter value at the last accept (recency for eviction).
    last: u64,
}

/// Sequence high-water marks per (actor, sender incarnation).
#[derive(Debug, Clone, Default)]
pub struct SeqTracker {
    marks: BTreeMap<ActorId, Vec<Mark>>,
    accepts: u64,
}

impl SeqTracker {
    pub fn new() -> SeqTracker {
        SeqTracker::default()
    }

    /// Decides on a chunk of `actor`'s process `incarnation` numbered `seq`, recording it when
    /// accepted.
    pub fn accept(&mut self, actor: ActorId, incarnation: u64, seq: u64) -> Verdict {
        if !self.marks.contains_key(&actor) && self.marks.len() >= MAX_TRACKED_SENDERS {
            return Verdict::TooManySenders;
        }
        self.accepts += 1;
        let now = self.accepts;
        let marks = self.marks.entry(actor).or_default();
        if let Some(m) = marks.iter_mut().find(|m| m.incarnation == incarnation) {
            if seq <= m.high_water {
                return Verdict::Replay {
                    high_water: m.high_water,
                };
            }
            m.high_water = seq;
            m.last = now;
            return Verdict::Accept;
        }
        if marks.len() >= MAX_INCARNATIONS
            && let Some(oldest) = (0..marks.len()).min_by_key(|&i| marks[i].last)
        {
            marks.swap_remove(oldest);
        }
        marks.push(Mark {
            incarnation,
            high_water: seq,
            last: now,
        });
        Verdict::Accept
    }

    /// Actor ids tracked.
    pub fn senders(&self) -> usize {
        self.marks.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_replayed_or_duplicated_chunk_is_refused_and_gaps_are_allowed() {
        let mut t = SeqTracker::new();
        let a = ActorId(1);
        assert_eq!(t.accept(a, 7, 0), Verdict::Accept);
        assert_eq!(t.accept(a, 7, 0), Verdict::Replay { high_water: 0 });
        assert_eq!(t.accept(a, 7, 3), Verdict::Accept); // 1 and 2 lost in transit
        assert_eq!(t.accept(a, 7, 2), Verdict::Replay { high_water: 3 });
        // The same id restarted: a new incarnation starts again at 0.
        assert_eq!(t.accept(a, 8, 0), Verdict::Accept);
        // The old incarnation is still remembered.
        assert_eq!(t.accept(a, 7, 3), Verdict::Replay { high_water: 3 });
        // Another actor with the same numbers is independent.
        assert_eq!(t.accept(ActorId(2), 7, 0), Verdict::Accept);
    }

    #[test]
    fn memory_is_bounded() {
        let mut t = SeqTracker::new();
        for i in 0..MAX_TRACKED_SENDERS as u32 {
            assert_eq!(t.accept(ActorId(i), 1, 0), Verdict::Accept);
        }
        assert_eq!(t.accept(ActorId(u32::MAX), 1, 0), Verdict::TooManySenders);
        assert_eq!(t.senders(), MAX_TRACKED_SENDERS);
        let a = ActorId(0);
        for inc in 2..100 {
            t.accept(a, inc, 0);
        }
        assert!(t.marks[&a].len() <= MAX_INCARNATIONS);
        assert_eq!(t.senders(), MAX_TRACKED_SENDERS);
    }
}
