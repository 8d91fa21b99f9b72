//! The relay's fault schedule: stalls, resets and partitions at fixed offsets (milliseconds) from
//! the relay's time origin ([`crate::Relay::origin`], the moment it started).
//!
//! A fault acts on the whole relay, every connection at once:
//! - [`FaultKind::Stall`]: for its duration nothing is forwarded either way; the bytes read are
//!   held (up to the queue bound, then the relay stops reading) and none is dropped;
//!   connections stay open.
//! - [`FaultKind::Reset`]: at its start every open connection is aborted (an RST to both
//!   peers); new connections are accepted at once. It has no duration.
//! - [`FaultKind::Partition`]: at its start every open connection is aborted, and until it ends
//!   every new one is accepted and aborted at once (the peer sees a reset, nothing reaches the
//!   upstream).
//!
//! Overlapping faults combine: a partition wins over a stall, which wins over forwarding.
//! The schedule is a pure function of the time since the origin ([`FaultSchedule::state_at`],
//! [`FaultSchedule::epoch_at`]); the relay re-evaluates it at each boundary.

use std::time::Duration;

/// What a scheduled fault does (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FaultKind {
    /// Nothing forwarded either way for the duration; bytes held, connections kept.
    Stall,
    /// Every open connection aborted at the start; no duration.
    Reset,
    /// Every open connection aborted at the start, new ones refused until the end.
    Partition,
}

impl FaultKind {
    /// The name the text spec uses (`stall`, `reset`, `partition`).
    pub fn name(self) -> &'static str {
        match self {
            FaultKind::Stall => "stall",
            FaultKind::Reset => "reset",
            FaultKind::Partition => "partition",
        }
    }
}

/// One scheduled fault: `kind` from `at_ms` after the origin for `duration_ms` milliseconds
/// (0 for a reset, which is an instant).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Fault {
    /// Start, in milliseconds after the relay's origin.
    pub at_ms: u64,
    /// Length in milliseconds; 0 for [`FaultKind::Reset`], > 0 for the others.
    pub duration_ms: u64,
    /// What happens.
    pub kind: FaultKind,
}

impl Fault {
    /// A stall from `at_ms` for `duration_ms` milliseconds.
    pub fn stall(at_ms: u64, duration_ms: u64) -> Fault {
        Fault {
            at_ms,
            duration_ms,
            kind: FaultKind::Stall,
        }
    }

    /// A reset at `at_ms`.
    pub fn reset(at_ms: u64) -> Fault {
        Fault {
            at_ms,
            duration_ms: 0,
            kind: FaultKind::Reset,
        }
    }

    /// A partition from `at_ms` for `duration_ms` milliseconds.
    pub fn partition(at_ms: u64, duration_ms: u64) -> Fault {
        Fault {
            at_ms,
            duration_ms,
            kind: FaultKind::Partition,
        }
    }

    /// The end (exclusive), in milliseconds after the origin.
    pub fn end_ms(&self) -> u64 {
        self.at_ms.saturating_add(self.duration_ms)
    }

    /// Whether it holds at `t` (start inclusive, end exclusive; a reset never "holds").
    fn active_at(&self, t: Duration) -> bool {
        let start = Duration::from_millis(self.at_ms);
        let end = Duration::from_millis(self.end_ms());
        start <= t && t < end
    }

    /// A reset's or a partition's start: every open connection is aborted then.
    fn aborts_connections(&self) -> bool {
        matches!(self.kind, FaultKind::Reset | FaultKind::Partition)
    }

    /// Why it cannot be scheduled, if so.
    pub fn check(&self) -> Result<(), String> {
        match (self.kind, self.duration_ms) {
            (FaultKind::Reset, 0) => Ok(()),
            (FaultKind::Reset, _) => Err(format!("{self}: a reset takes no duration")),
            (_, 0) => Err(format!(
                "{self}: a {} needs a duration > 0",
                self.kind.name()
            )),
            _ => Ok(()),
        }
    }
}

/// What the relay does at a moment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RelayState {
    /// Bytes flow (with the links' impairments).
    Forwarding,
    /// A stall holds every byte.
    Stalled,
    /// A partition: no connection open, new ones refused.
    Partitioned,
}

/// What the connections obey at a moment: the state, and the abort epoch (the number of
/// resets and partition starts so far; a connection accepted in an earlier epoch is aborted).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Control {
    pub(crate) state: RelayState,
    pub(crate) epoch: u64,
}

/// A list of faults as a function of the time since the origin.
#[derive(Debug, Clone, Default)]
pub(crate) struct FaultSchedule {
    faults: Vec<Fault>,
}

impl FaultSchedule {
    pub(crate) fn new(faults: Vec<Fault>) -> FaultSchedule {
        FaultSchedule { faults }
    }

    /// The state at `t` after the origin.
    pub(crate) fn state_at(&self, t: Duration) -> RelayState {
        let active = |kind| self.faults.iter().any(|f| f.kind == kind && f.active_at(t));
        if active(FaultKind::Partition) {
            RelayState::Partitioned
        } else if active(FaultKind::Stall) {
            RelayState::Stalled
        } else {
            RelayState::Forwarding
        }
    }

    /// How many resets and partition starts happened at or before `t`.
    pub(crate) fn epoch_at(&self, t: Duration) -> u64 {
        self.faults
            .iter()
            .filter(|f| f.aborts_connections() && Duration::from_millis(f.at_ms) <= t)
            .count() as u64
    }

    pub(crate) fn control_at(&self, t: Duration) -> Control {
        Control {
            state: self.state_at(t),
            epoch: self.epoch_at(t),
        }
    }

    /// The first start or end strictly after `t`, if any.
    pub(crate) fn next_boundary_after(&self, t: Duration) -> Option<Duration> {
        self.faults
            .iter()
            .flat_map(|f| [f.at_ms, f.end_ms()])
            .map(Duration::from_millis)
            .filter(|&b| b > t)
            .min()
    }

    /// The faults that start at or before `t` and after `since` (for the log).
    pub(crate) fn starting_in(&self, since: Option<Duration>, t: Duration) -> Vec<Fault> {
        self.faults
            .iter()
            .filter(|f| {
                let s = Duration::from_millis(f.at_ms);
                s <= t && since.is_none_or(|p| s > p)
            })
            .copied()
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Duration {
        Duration::from_millis(v)
    }

    #[test]
    fn states_combine_with_partition_over_stall() {
        let s = FaultSchedule::new(vec![
            Fault::stall(100, 200),
            Fault::partition(200, 200),
            Fault::reset(500),
        ]);
        assert_eq!(s.state_at(ms(0)), RelayState::Forwarding);
        assert_eq!(s.state_at(ms(100)), RelayState::Stalled);
        assert_eq!(s.state_at(ms(199)), RelayState::Stalled);
        assert_eq!(s.state_at(ms(200)), RelayState::Partitioned);
        assert_eq!(s.state_at(ms(350)), RelayState::Partitioned);
        assert_eq!(s.state_at(ms(400)), RelayState::Forwarding);
        assert_eq!(s.state_at(ms(500)), RelayState::Forwarding);
    }

    #[test]
    fn epochs_count_resets_and_partition_starts() {
        let s = FaultSchedule::new(vec![
            Fault::stall(0, 1000),
            Fault::partition(200, 200),
            Fault::reset(500),
        ]);
        assert_eq!(s.epoch_at(ms(0)), 0);
        assert_eq!(s.epoch_at(ms(199)), 0);
        assert_eq!(s.epoch_at(ms(200)), 1);
        assert_eq!(s.epoch_at(ms(499)), 1);
        assert_eq!(s.epoch_at(ms(500)), 2);
    }

    #[test]
    fn boundaries_are_every_start_and_end_in_order() {
        let s = FaultSchedule::new(vec![Fault::partition(200, 300), Fault::stall(100, 50)]);
        let mut t = Duration::ZERO;
        let mut seen = vec![];
        while let Some(b) = s.next_boundary_after(t) {
            seen.push(b.as_millis());
            t = b;
        }
        assert_eq!(seen, [100, 150, 200, 500]);
        assert_eq!(
            s.starting_in(Some(ms(100)), ms(200)),
            [Fault::partition(200, 300)]
        );
    }

    #[test]
    fn durations_are_checked() {
        assert!(Fault::reset(5).check().is_ok());
        assert!(Fault::stall(5, 1).check().is_ok());
        let e = Fault::stall(5, 0).check().unwrap_err();
        assert!(e.contains("needs a duration"), "{e}");
        let e = Fault {
            at_ms: 5,
            duration_ms: 3,
            kind: FaultKind::Reset,
        }
        .check()
        .unwrap_err();
        assert!(e.contains("no duration"), "{e}");
    }
}
