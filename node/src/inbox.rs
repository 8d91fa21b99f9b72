//! The learner's inbox: zenoh's receive callback queues raw trajectory messages
//! under byte budgets per sender and in total ([`InboxBudget`]; over budget the sender's own
//! oldest message goes, then the biggest holder's: `overflow`), without ever blocking; the
//! decode task ([`decode_task`], on the node's network side) decodes each within its
//! allocation budget, validates it, drops replays and queues it for PPO.

use crate::ratelog::RateLog;
use dupac_common::dedup::{SeqTracker, Verdict};
use dupac_common::ids::ActorId;
use dupac_common::keys::KeySpace;
use dupac_common::msg::{MsgLimits, TrajectoryChunk, decode_msg};
use dupac_common::validate::{ChunkExpect, DropReason, validate_chunk};
use std::collections::{BTreeMap, VecDeque};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// A chunk that passed validation, waiting for the PPO loop.
#[derive(Debug)]
pub struct Received {
    pub chunk: TrajectoryChunk,
    pub at: Instant,
    /// The sender (from the key) and the bytes charged to it until the chunk is taken.
    pub(crate) sender: ActorId,
    pub(crate) charge: usize,
}

/// A message as received, not yet decoded.
pub(crate) struct Raw {
    pub(crate) key: String,
    pub(crate) sender: ActorId,
    pub(crate) payload: zenoh::bytes::ZBytes,
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

    /// zenoh's receive callback: size and key checks, then the byte budgets; never blocks on
    /// the decoder (a blocked `Block` sender would lose its transport).
    pub(crate) fn admit(&self, keys: &KeySpace, sample: &zenoh::sample::Sample) {
        let key = sample.key_expr().as_str();
        let len = sample.payload().len();
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
            payload: sample.payload().clone(),
            charge: len,
        });
        *q.held.entry(sender).or_insert(0) += len;
        q.total += len;
        drop(q);
        self.drop_n(DropReason::Overflow, evicted);
        self.arrived.notify_one();
    }
}

/// The decode task (on the node's network side): queued bytes → decode within the budget →
/// validate → at-most-once → decoded queue. The message keeps its charge against its sender
/// until the PPO loop takes it. Ends when `closing` is set (and `arrived` notified).
pub(crate) async fn decode_task(
    inbox: Arc<Inbox>,
    closing: Arc<AtomicBool>,
    expect: ChunkExpect,
    limits: MsgLimits,
) {
    let mut seqs = SeqTracker::new();
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
        let refuse = |reason: DropReason| {
            inbox.drop_one(reason);
            if let Ok(mut q) = inbox.queues.lock() {
                q.release(raw.sender, raw.charge);
            }
        };
        let chunk: TrajectoryChunk = match decode_msg(&raw.payload.to_bytes(), limits, &raw.key) {
            Ok(c) => c,
            Err(e) => {
                refuse(DropReason::of_codec(&e));
                inbox
                    .warnings
                    .warn("undecodable chunk", Some(raw.sender.0), e);
                continue;
            }
        };
        if chunk.header.actor != raw.sender {
            refuse(DropReason::Garbage);
            inbox.warnings.warn(
                "chunk on another actor's key",
                Some(raw.sender.0),
                format_args!("actor {} on {}", chunk.header.actor, raw.key),
            );
            continue;
        }
        if let Err(r) = validate_chunk(&chunk, &expect) {
            refuse(r.reason);
            inbox.warnings.warn("rejected chunk", Some(raw.sender.0), r);
            continue;
        }
        let h = &chunk.header;
        match seqs.accept(h.actor, h.sender_incarnation, h.seq) {
            Verdict::Accept => {}
            Verdict::Replay { high_water } => {
                refuse(DropReason::Replay);
                inbox.warnings.warn(
                    "replayed chunk",
                    Some(raw.sender.0),
                    format_args!("seq {} at or below {high_water} (already received)", h.seq),
                );
                continue;
            }
            Verdict::TooManySenders => {
                refuse(DropReason::Overflow);
                inbox.warnings.warn(
                    "chunk of one actor id too many",
                    Some(raw.sender.0),
                    "more actor ids than the learner tracks",
                );
                continue;
            }
        }
        let Ok(mut q) = inbox.queues.lock() else {
            break;
        };
        q.decoded.push_back(Received {
            chunk,
            at: Instant::now(),
            sender: raw.sender,
            charge: raw.charge,
        });
        let mut evicted = 0;
        while q.decoded.len() > inbox.budget.max_chunks {
            if let Some(old) = q.decoded.pop_front() {
                q.release(old.sender, old.charge);
                evicted += 1;
            }
        }
        drop(q);
        inbox.drop_n(DropReason::Overflow, evicted);
        inbox.ready.notify_one();
    }
}
