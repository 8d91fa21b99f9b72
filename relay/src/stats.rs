//! The relay's counters: atomics the relay's tasks update and [`crate::Relay::stats`] reads
//! while it runs, as a [`RelayStats`] snapshot (each counter read on its own, relaxed: the
//! snapshot is not one instant's, which counters for a log or a test's bound do not need).

use std::sync::atomic::{AtomicU8, AtomicU64, Ordering::Relaxed};

use crate::fault::RelayState;

/// One direction's byte counts, in bytes, summed over every connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DirectionStats {
    /// Read from the sending peer.
    pub bytes_read: u64,
    /// Written to the receiving peer.
    pub bytes_forwarded: u64,
    /// Held in the delay queues now (read, not yet written; payload bytes only).
    pub bytes_queued: u64,
}

/// A snapshot of the relay's counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RelayStats {
    /// What the fault schedule says now.
    pub state: RelayState,
    /// Downstream → upstream (what the connecting peers send).
    pub up: DirectionStats,
    /// Upstream → downstream (what the upstream answers).
    pub down: DirectionStats,
    /// Connections taken on (accepted outside a partition).
    pub connections_accepted: u64,
    /// Connections open now.
    pub connections_active: u64,
    /// Connections the relay ended normally (both directions reached their end of stream).
    pub connections_closed: u64,
    /// Open connections the relay aborted for a reset or a partition start.
    pub connections_aborted_by_fault: u64,
    /// Connections accepted during a partition and aborted at once.
    pub connections_refused: u64,
    /// Connections that failed: upstream unreachable, or an I/O error on either side (the
    /// relay then aborts both sides).
    pub connections_failed: u64,
}

#[derive(Debug, Default)]
pub(crate) struct DirectionCounters {
    read: AtomicU64,
    forwarded: AtomicU64,
    queued: AtomicU64,
}

impl DirectionCounters {
    pub(crate) fn add_read(&self, n: usize) {
        self.read.fetch_add(n as u64, Relaxed);
        self.queued.fetch_add(n as u64, Relaxed);
    }

    pub(crate) fn add_forwarded(&self, n: usize) {
        self.forwarded.fetch_add(n as u64, Relaxed);
    }

    pub(crate) fn sub_queued(&self, n: usize) {
        self.queued.fetch_sub(n as u64, Relaxed);
    }

    fn snapshot(&self) -> DirectionStats {
        DirectionStats {
            bytes_read: self.read.load(Relaxed),
            bytes_forwarded: self.forwarded.load(Relaxed),
            bytes_queued: self.queued.load(Relaxed),
        }
    }
}

#[derive(Debug, Default)]
pub(crate) struct Counters {
    pub(crate) up: std::sync::Arc<DirectionCounters>,
    pub(crate) down: std::sync::Arc<DirectionCounters>,
    state: AtomicU8,
    pub(crate) accepted: AtomicU64,
    pub(crate) active: AtomicU64,
    pub(crate) closed: AtomicU64,
    pub(crate) aborted_by_fault: AtomicU64,
    pub(crate) refused: AtomicU64,
    pub(crate) failed: AtomicU64,
}

impl Counters {
    pub(crate) fn set_state(&self, state: RelayState) {
        self.state.store(state.to_u8(), Relaxed);
    }

    pub(crate) fn state(&self) -> RelayState {
        RelayState::from_u8(self.state.load(Relaxed))
    }

    pub(crate) fn bump(counter: &AtomicU64) {
        counter.fetch_add(1, Relaxed);
    }

    pub(crate) fn snapshot(&self) -> RelayStats {
        RelayStats {
            state: self.state(),
            up: self.up.snapshot(),
            down: self.down.snapshot(),
            connections_accepted: self.accepted.load(Relaxed),
            connections_active: self.active.load(Relaxed),
            connections_closed: self.closed.load(Relaxed),
            connections_aborted_by_fault: self.aborted_by_fault.load(Relaxed),
            connections_refused: self.refused.load(Relaxed),
            connections_failed: self.failed.load(Relaxed),
        }
    }
}
