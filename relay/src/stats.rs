//! The relay's counters: one [`RelayStats`] behind one lock, which the relay's tasks update and
//! [`crate::Relay::stats`] copies while it runs. Counters that move together move in one
//! update (a connection's end leaves `connections_active` and enters `connections_closed`,
//! `_failed` or `_aborted_by_fault` at once; a read adds to `bytes_read` and `bytes_queued` at
//! once), so a snapshot is one instant's: every connection accepted is active or ended in
//! exactly one way. The lock is held for a few additions, once per read and per write.

use std::sync::{Arc, Mutex, MutexGuard};

use crate::fault::RelayState;

/// One direction's byte counts, in bytes, summed over every connection.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DirectionStats {
    /// Read from the sending peer.
    pub bytes_read: u64,
    /// Written to the receiving peer.
    pub bytes_forwarded: u64,
    /// Held in the delay queues now (read, and not yet written whole; payload bytes only).
    pub bytes_queued: u64,
}

/// A snapshot of the relay's counters, all of one instant.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RelayStats {
    /// What the fault schedule says now.
    pub state: RelayState,
    /// Downstream → upstream (what the connecting peers send).
    pub up: DirectionStats,
    /// Upstream → downstream (what the upstream answers).
    pub down: DirectionStats,
    /// Connections taken on (accepted outside a partition): always the sum of `_active`,
    /// `_closed`, `_aborted_by_fault` and `_failed`.
    pub connections_accepted: u64,
    /// Connections open now.
    pub connections_active: u64,
    /// Connections the relay ended normally (both directions reached their end of stream).
    pub connections_closed: u64,
    /// Open connections the relay aborted for a reset or a partition start.
    pub connections_aborted_by_fault: u64,
    /// Connections accepted during a partition and aborted at once (not in `_accepted`).
    pub connections_refused: u64,
    /// Connections that failed: upstream unreachable, or an I/O error on either side (the
    /// relay then aborts both sides).
    pub connections_failed: u64,
}

/// A direction of a relayed connection, naming its [`DirectionStats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Side {
    /// Downstream → upstream.
    Up,
    /// Upstream → downstream.
    Down,
}

/// How a relayed connection ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Ending {
    Closed,
    Failed,
    AbortedByFault,
}

/// The relay's counters, shared by its tasks.
#[derive(Debug)]
pub(crate) struct Counters {
    now: Mutex<RelayStats>,
}

impl Counters {
    pub(crate) fn new(state: RelayState) -> Counters {
        Counters {
            now: Mutex::new(RelayStats {
                state,
                up: DirectionStats::default(),
                down: DirectionStats::default(),
                connections_accepted: 0,
                connections_active: 0,
                connections_closed: 0,
                connections_aborted_by_fault: 0,
                connections_refused: 0,
                connections_failed: 0,
            }),
        }
    }

    /// The counters, locked. A panic elsewhere while they were held leaves whole numbers (each
    /// update is a few additions), so a poisoned lock is taken as it is.
    fn lock(&self) -> MutexGuard<'_, RelayStats> {
        self.now.lock().unwrap_or_else(|p| p.into_inner())
    }

    fn side(s: &mut RelayStats, side: Side) -> &mut DirectionStats {
        match side {
            Side::Up => &mut s.up,
            Side::Down => &mut s.down,
        }
    }

    /// Sets the state, calling `tell` (which tells the connections) under the same lock: a
    /// connection that ends on what it was told counts its end after the state is set.
    pub(crate) fn set_state_telling(&self, state: RelayState, tell: impl FnOnce()) {
        let mut s = self.lock();
        tell();
        s.state = state;
    }

    pub(crate) fn state(&self) -> RelayState {
        self.lock().state
    }

    pub(crate) fn snapshot(&self) -> RelayStats {
        *self.lock()
    }

    /// `n` bytes read on `side`: read and queued.
    pub(crate) fn add_read(&self, side: Side, n: usize) {
        let mut s = self.lock();
        let d = Self::side(&mut s, side);
        d.bytes_read += n as u64;
        d.bytes_queued += n as u64;
    }

    /// `n` bytes written on `side`.
    pub(crate) fn add_forwarded(&self, side: Side, n: usize) {
        Self::side(&mut self.lock(), side).bytes_forwarded += n as u64;
    }

    /// `n` bytes left the queue of `side` (written whole, or discarded).
    pub(crate) fn sub_queued(&self, side: Side, n: usize) {
        let mut s = self.lock();
        let d = Self::side(&mut s, side);
        d.bytes_queued = d.bytes_queued.saturating_sub(n as u64);
    }

    /// A connection refused during a partition.
    pub(crate) fn refused(&self) {
        self.lock().connections_refused += 1;
    }

    /// A connection taken on: accepted and active from now until its [`Connection`] ends or
    /// is dropped.
    pub(crate) fn accept(self: &Arc<Self>) -> Connection {
        let mut s = self.lock();
        s.connections_accepted += 1;
        s.connections_active += 1;
        Connection {
            counters: self.clone(),
            ended: false,
        }
    }
}

/// A connection counted active; [`Connection::end`] moves it to its ending's counter in the
/// same update. Dropped without an end (the runtime dropping the relay's tasks), it only
/// leaves the active count.
#[derive(Debug)]
pub(crate) struct Connection {
    counters: Arc<Counters>,
    ended: bool,
}

impl Connection {
    pub(crate) fn end(mut self, ending: Ending) {
        let mut s = self.counters.lock();
        s.connections_active -= 1;
        match ending {
            Ending::Closed => s.connections_closed += 1,
            Ending::Failed => s.connections_failed += 1,
            Ending::AbortedByFault => s.connections_aborted_by_fault += 1,
        }
        drop(s);
        self.ended = true;
    }
}

impl Drop for Connection {
    fn drop(&mut self) {
        if !self.ended {
            self.counters.lock().connections_active -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Connections end on two threads while a third reads snapshots: every snapshot adds up
    /// (accepted = active + closed + failed + aborted), and bytes read are all queued or
    /// forwarded. With the counters as separate atomics (the relay's first version) a reader
    /// saw a connection both closed and active within a few thousand snapshots.
    #[test]
    fn a_snapshot_never_shows_a_half_updated_connection() {
        let counters = Arc::new(Counters::new(RelayState::Forwarding));
        let done = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let workers: Vec<_> = (0..2)
            .map(|w| {
                let counters = counters.clone();
                std::thread::spawn(move || {
                    for i in 0..20_000u32 {
                        let c = counters.accept();
                        counters.add_read(Side::Up, 100);
                        counters.sub_queued(Side::Up, 100);
                        counters.add_forwarded(Side::Up, 100);
                        c.end(match (i + w) % 3 {
                            0 => Ending::Closed,
                            1 => Ending::Failed,
                            _ => Ending::AbortedByFault,
                        });
                    }
                })
            })
            .collect();
        let reader = {
            let counters = counters.clone();
            let done = done.clone();
            std::thread::spawn(move || {
                let mut seen = 0u64;
                while !done.load(std::sync::atomic::Ordering::Relaxed) || seen == 0 {
                    let s = counters.snapshot();
                    let ended = s.connections_closed
                        + s.connections_failed
                        + s.connections_aborted_by_fault;
                    assert_eq!(
                        s.connections_active + ended,
                        s.connections_accepted,
                        "half-updated: {s:?}"
                    );
                    assert!(s.up.bytes_read >= s.up.bytes_queued, "{s:?}");
                    seen += 1;
                }
                seen
            })
        };
        for w in workers {
            w.join().unwrap();
        }
        done.store(true, std::sync::atomic::Ordering::Relaxed);
        assert!(reader.join().unwrap() > 0);
        let s = counters.snapshot();
        assert_eq!(s.connections_accepted, 40_000);
        assert_eq!(s.connections_active, 0);
        assert_eq!(s.up.bytes_queued, 0);
    }

    /// The pair the end-of-stream test reads: once the end is counted the connection is no
    /// longer active, in the same snapshot.
    #[test]
    fn an_ended_connection_is_not_active() {
        let counters = Arc::new(Counters::new(RelayState::Forwarding));
        let c = counters.accept();
        assert_eq!(counters.snapshot().connections_active, 1);
        c.end(Ending::Closed);
        let s = counters.snapshot();
        assert_eq!(
            (
                s.connections_accepted,
                s.connections_active,
                s.connections_closed
            ),
            (1, 0, 1)
        );
        drop(counters.accept());
        let s = counters.snapshot();
        assert_eq!((s.connections_accepted, s.connections_active), (2, 0));
    }
}
