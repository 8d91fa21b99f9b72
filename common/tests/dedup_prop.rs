//! Property test of at-most-once acceptance: whatever the interleaving of honest
//! deliveries, losses, duplicates and replays of earlier chunks, no chunk is accepted twice,
//! and every chunk delivered for the first time in its sender's order is accepted.

use dupac_common::dedup::{MAX_INCARNATIONS, SeqTracker, Verdict};
use dupac_common::ids::ActorId;
use proptest::prelude::*;
use std::collections::BTreeSet;

/// One event on the wire: the next honest chunk of a stream, a lost one, or a replay of the
/// `k`-th chunk delivered so far.
#[derive(Debug, Clone)]
enum Event {
    Next { stream: usize },
    Lost { stream: usize },
    Replay { k: usize },
}

fn event() -> impl Strategy<Value = Event> {
    prop_oneof![
        4 => (0usize..12).prop_map(|stream| Event::Next { stream }),
        1 => (0usize..12).prop_map(|stream| Event::Lost { stream }),
        3 => any::<usize>().prop_map(|k| Event::Replay { k }),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn no_chunk_is_accepted_twice(events in prop::collection::vec(event(), 1..400)) {
        // 12 streams: 3 actor ids × 4 incarnations (≤ MAX_INCARNATIONS each).
        const { assert!(4 <= MAX_INCARNATIONS) };
        let stream = |s: usize| (ActorId((s % 3) as u32), 1000 + (s / 3) as u64);
        let mut next_seq = [0u64; 12];
        let mut delivered: Vec<(ActorId, u64, u64)> = Vec::new();
        let mut accepted: BTreeSet<(ActorId, u64, u64)> = BTreeSet::new();
        let mut t = SeqTracker::new();
        for e in events {
            let (chunk, fresh) = match e {
                Event::Next { stream: s } => {
                    let (a, inc) = stream(s);
                    next_seq[s] += 1;
                    ((a, inc, next_seq[s] - 1), true)
                }
                Event::Lost { stream: s } => {
                    next_seq[s] += 1;
                    continue;
                }
                Event::Replay { k } => {
                    if delivered.is_empty() {
                        continue;
                    }
                    (delivered[k % delivered.len()], false)
                }
            };
            delivered.push(chunk);
            match t.accept(chunk.0, chunk.1, chunk.2) {
                Verdict::Accept => {
                    prop_assert!(accepted.insert(chunk), "{chunk:?} accepted twice");
                }
                Verdict::Replay { .. } => prop_assert!(!fresh, "fresh {chunk:?} refused"),
                Verdict::TooManySenders => prop_assert!(false, "3 senders are not too many"),
            }
        }
    }
}
