//! The learner's inbox: zenoh's receive callback queues raw trajectory messages
//! under byte budgets per sender and in total ([`InboxBudget`]; over budget the sender's own
//! oldest message goes, then the biggest holder's: `overflow`), without ever blocking; the
//! decode task ([`decode_task`], on the node's network side) decodes each within its
//! allocation budget, validates it, drops replays and queues it for PPO.

use crate::accept::{Acceptor, Refusal};
use crate::ratelog::RateLog;
use dupac_common::ids::ActorId;
use dupac_common::keys::KeySpace;
use dupac_common::msg::{ExpandedChunk, MsgLimits};
use dupac_common::validate::DropReason;
use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};
use zenoh::bytes::ZBytes;

/// A chunk that passed validation, waiting for the PPO loop.
#[derive(Debug)]
pub struct Received {
    pub chunk: ExpandedChunk,
    pub at: Instant,
    /// The sender (from the key) and the bytes charged to it until the chunk is taken.
    pub(crate) sender: ActorId,
    pub(crate) charge: usize,
}

/// A message as received, not yet decoded.
pub(crate) struct Raw {
    pub(crate) key: String,
    pub(crate) sender: ActorId,
    pub(crate) payload: ZBytes,
    pub(crate) charge: usize,
}

/// Byte budgets of the inbox: what one sender, and all together, may hold queued
/// (received and not yet decoded, or decoded and not yet trained), counted in message bytes.
#[derive(Debug, Clone, Copy)]
pub struct InboxBudget {
    /// Largest message accepted (the chunk limit).
    pub message_bytes: usize,
    /// One sender (an actor id, from the key): a learner batch plus one chunk: an actor never
    /// usefully has more than its share of a batch in flight.
    pub per_sender_bytes: usize,
    /// Everyone: two batches plus two chunks.
    pub total_bytes: usize,
    /// Decoded chunks held at most (`distributed.queue_chunks`).
    pub max_chunks: usize,
}

impl InboxBudget {
    /// The budget of a learner with `limits` for chunks and batches of `batch_samples` samples,
    /// chunks being at most `chunk_samples` samples.
    pub fn new(
        limits: MsgLimits,
        batch_samples: usize,
        chunk_samples: usize,
        max_chunks: usize,
    ) -> InboxBudget {
        let per_sample = limits.bytes.div_ceil(chunk_samples.max(1));
        let batch_bytes = batch_samples.saturating_mul(per_sample);
        InboxBudget {
            message_bytes: limits.bytes,
            per_sender_bytes: batch_bytes.saturating_add(limits.bytes),
            total_bytes: batch_bytes.saturating_add(limits.bytes).saturating_mul(2),
            max_chunks,
        }
    }
}

/// The queues between zenoh's receive callback, the decode task and the PPO loop, with the
/// bytes each sender holds in them.
#[derive(Default)]
pub(crate) struct Queues {
    pub(crate) raw: VecDeque<Raw>,
    pub(crate) decoded: VecDeque<Received>,
    pub(crate) held: BTreeMap<ActorId, usize>,
    pub(crate) total: usize,
}

impl Queues {
    pub(crate) fn release(&mut self, sender: ActorId, charge: usize) {
        self.total = self.total.saturating_sub(charge);
        if let Some(h) = self.held.get_mut(&sender) {
            *h = h.saturating_sub(charge);
            if *h == 0 {
                self.held.remove(&sender);
            }
        }
    }

    /// Drops `sender`'s oldest queued message (undecoded first). False when it holds none.
    pub(crate) fn evict_oldest_of(&mut self, sender: ActorId) -> bool {
        if let Some(i) = self.raw.iter().position(|r| r.sender == sender)
            && let Some(r) = self.raw.remove(i)
        {
            self.release(r.sender, r.charge);
            return true;
        }
        if let Some(i) = self.decoded.iter().position(|r| r.sender == sender)
            && let Some(r) = self.decoded.remove(i)
        {
            self.release(r.sender, r.charge);
            return true;
        }
        false
    }

    /// Makes room for `charge` more bytes of `sender`: its own oldest messages go first when it
    /// is over its share, then the oldest of whoever holds the most when all are over the
    /// total. Returns the messages dropped.
    pub(crate) fn make_room(&mut self, sender: ActorId, charge: usize, b: &InboxBudget) -> u64 {
        let mut dropped = 0;
        while self.held.get(&sender).copied().unwrap_or(0) + charge > b.per_sender_bytes
            && self.evict_oldest_of(sender)
        {
            dropped += 1;
        }
        while self.total + charge > b.total_bytes {
            let Some((&biggest, _)) = self.held.iter().max_by_key(|(_, h)| **h) else {
                break;
            };
            if !self.evict_oldest_of(biggest) {
                break;
            }
            dropped += 1;
        }
        dropped
    }
}

/// What the receive callback, the decode task and the PPO loop share.
pub(crate) struct Inbox {
    pub(crate) queues: Mutex<Queues>,
    /// A decoded chunk is ready (PPO loop).
    pub(crate) ready: Condvar,
    /// A raw message arrived, or the node closes (decode task).
    pub(crate) arrived: tokio::sync::Notify,
    pub(crate) drops: Mutex<BTreeMap<DropReason, u64>>,
    /// Bytes of every trajectory message that arrived (accepted or not).
    pub(crate) received_bytes: std::sync::atomic::AtomicU64,
    /// Time the decode task spent accepting messages (decoding, validating, expanding; ns), and
    /// of it expanding the compact trajectories.
    pub(crate) accept_ns: std::sync::atomic::AtomicU64,
    pub(crate) expand_ns: std::sync::atomic::AtomicU64,
    pub(crate) budget: InboxBudget,
    /// The drops' warnings: one line per kind per [`WARN_PERIOD`], with counts.
    pub(crate) warnings: RateLog,
}

/// At most one warning line per kind of dropped message in this period.
pub(crate) const WARN_PERIOD: Duration = Duration::from_secs(10);

impl Inbox {
    pub(crate) fn new(budget: InboxBudget) -> Inbox {
        Inbox {
            queues: Mutex::default(),
            ready: Condvar::new(),
            arrived: tokio::sync::Notify::new(),
            drops: Mutex::default(),
            received_bytes: std::sync::atomic::AtomicU64::new(0),
            accept_ns: std::sync::atomic::AtomicU64::new(0),
            expand_ns: std::sync::atomic::AtomicU64::new(0),
            budget,
            warnings: RateLog::new(WARN_PERIOD),
        }
    }

    pub(crate) fn drop_n(&self, reason: DropReason, n: u64) {
        if n > 0
            && let Ok(mut d) = self.drops.lock()
        {
            *d.entry(reason).or_insert(0) += n;
        }
    }

    pub(crate) fn drop_one(&self, reason: DropReason) {
        self.drop_n(reason, 1);
    }

    /// A refused message: counted, its bytes released, warned (one line per kind per period).
    fn refuse(&self, raw: &Raw, r: Refusal) {
        self.drop_one(r.reason);
        if let Ok(mut q) = self.queues.lock() {
            q.release(raw.sender, raw.charge);
        }
        self.warnings.warn(r.kind, Some(raw.sender.0), r.detail);
    }

    /// An accepted chunk joins the decoded queue (the oldest go past `max_chunks`).
    fn decoded(&self, chunk: ExpandedChunk, sender: ActorId, charge: usize) {
        let Ok(mut q) = self.queues.lock() else {
            return;
        };
        q.decoded.push_back(Received {
            chunk,
            at: Instant::now(),
            sender,
            charge,
        });
        let mut evicted = 0;
        while q.decoded.len() > self.budget.max_chunks {
            if let Some(old) = q.decoded.pop_front() {
                q.release(old.sender, old.charge);
                evicted += 1;
            }
        }
        drop(q);
        self.drop_n(DropReason::Overflow, evicted);
        self.ready.notify_one();
    }

    /// The oldest decoded chunk, waiting up to `wait` for one; its bytes are released.
    pub(crate) fn take(&self, wait: Duration) -> Option<Received> {
        let Ok(mut q) = self.queues.lock() else {
            return None;
        };
        if q.decoded.is_empty() {
            q = self.ready.wait_timeout(q, wait).ok()?.0;
        }
        let r = q.decoded.pop_front()?;
        q.release(r.sender, r.charge);
        Some(r)
    }

    /// zenoh's receive callback: size and key checks, then the byte budgets; never blocks on
    /// the decoder (a blocked `Block` sender would lose its transport).
    pub(crate) fn admit(&self, keys: &KeySpace, sample: &zenoh::sample::Sample) {
        self.push(keys, sample.key_expr().as_str(), sample.payload());
    }

    /// [`Inbox::admit`] of `payload` received on `key`.
    pub(crate) fn push(&self, keys: &KeySpace, key: &str, payload: &ZBytes) {
        let len = payload.len();
        self.received_bytes
            .fetch_add(len as u64, std::sync::atomic::Ordering::Relaxed);
        let Some(sender) = keys.actor_of_traj(key) else {
            self.drop_one(DropReason::Garbage);
            return;
        };
        if len > self.budget.message_bytes {
            self.drop_one(DropReason::TooLarge);
            self.warnings.warn(
                "oversized message",
                Some(sender.0),
                format_args!(
                    "{len} bytes on {key}, over the {} byte limit (dropped unread)",
                    self.budget.message_bytes
                ),
            );
            return;
        }
        let Ok(mut q) = self.queues.lock() else {
            return;
        };
        let evicted = q.make_room(sender, len, &self.budget);
        q.raw.push_back(Raw {
            key: key.to_string(),
            sender,
            payload: payload.clone(),
            charge: len,
        });
        *q.held.entry(sender).or_insert(0) += len;
        q.total += len;
        drop(q);
        self.drop_n(DropReason::Overflow, evicted);
        self.arrived.notify_one();
    }
}

/// The decode task (on the node's network side): queued bytes → [`Acceptor::accept`] →
/// decoded queue. The message keeps its charge against its sender until the PPO loop takes it
/// ([`Inbox::take`]). Ends when `closing` is set (and `arrived` notified).
pub(crate) async fn decode_task(
    inbox: Arc<Inbox>,
    closing: Arc<AtomicBool>,
    mut acceptor: Acceptor,
) {
    while !closing.load(Ordering::Relaxed) {
        let raw = {
            let Ok(mut q) = inbox.queues.lock() else {
                break;
            };
            q.raw.pop_front()
        };
        let Some(raw) = raw else {
            // A notification sent since the queue was found empty is kept: none is lost.
            inbox.arrived.notified().await;
            continue;
        };
        // A backlog (or a flood of refused messages) is worked through a message at a time
        // between the other tasks' turns.
        tokio::task::yield_now().await;
        let t0 = std::time::Instant::now();
        let accepted = acceptor.accept(raw.sender, &raw.key, &raw.payload.to_bytes());
        let ns = |d: Duration| d.as_nanos().min(u128::from(u64::MAX)) as u64;
        inbox
            .accept_ns
            .fetch_add(ns(t0.elapsed()), Ordering::Relaxed);
        inbox
            .expand_ns
            .fetch_add(ns(acceptor.take_expand_time()), Ordering::Relaxed);
        match accepted {
            Ok(chunk) => inbox.decoded(chunk, raw.sender, raw.charge),
            Err(r) => inbox.refuse(&raw, r),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dupac_common::msg::encode_msg;
    use dupac_common::validate::ChunkExpect;

    const RUN: &str = "run-a";

    fn expect() -> ChunkExpect {
        crate::accept::test_expect()
    }

    /// The bytes of a valid one-step chunk of `actor` with sequence number `seq`.
    fn chunk(actor: u32, seq: u64) -> ZBytes {
        let c = crate::accept::one_step_chunk(&expect(), actor, seq);
        encode_msg(&c).expect("encode").into()
    }

    fn inbox(message_bytes: usize, per_sender_bytes: usize, total_bytes: usize) -> Arc<Inbox> {
        Arc::new(Inbox::new(InboxBudget {
            message_bytes,
            per_sender_bytes,
            total_bytes,
            max_chunks: 8,
        }))
    }

    fn drops(i: &Inbox, r: DropReason) -> u64 {
        i.drops
            .lock()
            .map_or(0, |d| d.get(&r).copied().unwrap_or(0))
    }

    /// The decode task on a runtime of its own, fed through `push`, read through `take`.
    #[test]
    fn chunks_pass_the_decode_task_in_order_and_refusals_are_counted_and_released() {
        let keys = KeySpace::new(RUN);
        let one = chunk(1, 0).len();
        let i = inbox(10 * one, 10 * one, 10 * one);
        let rt = tokio::runtime::Builder::new_current_thread()
            .build()
            .expect("runtime");
        let closing = Arc::new(AtomicBool::new(false));
        let acceptor = Acceptor::new(
            expect(),
            MsgLimits::both(1 << 20),
            crate::accept::test_expander(),
        );
        let task = std::thread::spawn({
            let (i, closing) = (i.clone(), closing.clone());
            move || rt.block_on(decode_task(i, closing, acceptor))
        });
        i.push(&keys, &keys.traj(ActorId(1)), &chunk(1, 0));
        i.push(
            &keys,
            &keys.traj(ActorId(1)),
            &ZBytes::from(b"garbage".to_vec()),
        );
        i.push(&keys, &keys.traj(ActorId(1)), &chunk(1, 0));
        i.push(&keys, &keys.traj(ActorId(2)), &chunk(1, 1));
        i.push(&keys, &keys.traj(ActorId(1)), &chunk(1, 1));
        i.push(&keys, "dupac/run-a/elsewhere", &chunk(1, 2));
        let first = i.take(Duration::from_secs(10)).expect("the first chunk");
        assert_eq!((first.sender, first.chunk.header.seq), (ActorId(1), 0));
        let second = i.take(Duration::from_secs(10)).expect("the second chunk");
        assert_eq!(second.chunk.header.seq, 1);
        assert!(
            i.take(Duration::from_millis(200)).is_none(),
            "nothing else passed"
        );
        assert_eq!(drops(&i, DropReason::Replay), 1);
        assert_eq!(
            drops(&i, DropReason::Garbage),
            3,
            "garbage, another's key, no actor key"
        );
        let q = i.queues.lock().expect("queues");
        assert_eq!((q.total, q.held.len()), (0, 0), "every byte released");
        drop(q);
        closing.store(true, Ordering::Relaxed);
        i.arrived.notify_one();
        task.join().expect("the decode task ends");
    }

    #[test]
    fn over_its_share_a_sender_loses_its_own_oldest_then_the_biggest_holder_loses_its() {
        let keys = KeySpace::new(RUN);
        // Compressed, the chunks' sizes differ by a few bytes: the limits in the largest's.
        let one = [(1, 0), (1, 1), (1, 2), (2, 0), (3, 0)]
            .map(|(a, s)| chunk(a, s).len())
            .into_iter()
            .max()
            .unwrap_or(0);
        let i = inbox(one, 2 * one, 3 * one);
        for seq in 0..3 {
            i.push(&keys, &keys.traj(ActorId(1)), &chunk(1, seq));
        }
        assert_eq!(
            drops(&i, DropReason::Overflow),
            1,
            "actor 1 over its two-chunk share"
        );
        i.push(&keys, &keys.traj(ActorId(2)), &chunk(2, 0));
        i.push(&keys, &keys.traj(ActorId(3)), &chunk(3, 0));
        assert_eq!(
            drops(&i, DropReason::Overflow),
            2,
            "the biggest holder gave way"
        );
        let q = i.queues.lock().expect("queues");
        let senders: Vec<u32> = q.raw.iter().map(|r| r.sender.0).collect();
        assert_eq!(senders, [1, 2, 3], "actor 1 keeps its newest");
        let held = [(1, 2), (2, 0), (3, 0)].map(|(a, s)| chunk(a, s).len());
        assert_eq!(q.total, held.iter().sum::<usize>());
        drop(q);
        i.push(
            &keys,
            &keys.traj(ActorId(1)),
            &ZBytes::from(vec![0u8; one + 1]),
        );
        assert_eq!(
            drops(&i, DropReason::TooLarge),
            1,
            "over the chunk limit, unread"
        );
    }
}
