//! Departures and returns of peers (liveliness tokens going and coming), logged as a person
//! reads them: a peer back within [`LOSS_GRACE`] was a blip (a transport reset reconnects in
//! well under a second: 0.3 s measured through `dupac relay`) and is logged at debug; a peer gone
//! longer gets one warning saying what happened and what DUPAC does, and its return a second
//! ("… back after 21 s"). So a reset writes no warning and a partition writes two lines.
//!
//! The deferred warning is a short-lived thread per departure (at most [`MAX_PENDING`] at once;
//! beyond that a departure is warned at once): liveliness callbacks run on zenoh's threads and
//! must not block.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long a peer may be gone before its departure is warned about (s): longer than a
/// transport reset's reconnection, far shorter than the 10 s lease that a partition outlasts.
pub const LOSS_GRACE: Duration = Duration::from_secs(3);
/// Most departures tracked at once (each return is matched to its departure).
pub const MAX_PENDING: usize = 64;

/// One departed peer.
#[derive(Debug)]
struct Departure {
    at: Instant,
    /// Its departure has been warned about (then its return is warned about too).
    warned: bool,
}

/// Departures of peers by id (see the module documentation).
#[derive(Debug, Clone)]
pub struct PresenceLog {
    grace: Duration,
    gone: Arc<Mutex<HashMap<String, Departure>>>,
}

impl Default for PresenceLog {
    fn default() -> Self {
        PresenceLog::new(LOSS_GRACE)
    }
}

impl PresenceLog {
    pub fn new(grace: Duration) -> PresenceLog {
        PresenceLog {
            grace,
            gone: Arc::default(),
        }
    }

    /// Peer `id` left; `warning` is the line to write if it is still gone after the grace.
    pub fn left(&self, id: &str, warning: String) {
        let Ok(mut gone) = self.gone.lock() else {
            return;
        };
        if gone.contains_key(id) {
            return;
        }
        if gone.len() >= MAX_PENDING {
            tracing::warn!("{warning}");
            return;
        }
        let at = Instant::now();
        gone.insert(id.to_string(), Departure { at, warned: false });
        drop(gone);
        let (log, who) = (self.clone(), id.to_string());
        let spawned = std::thread::Builder::new()
            .name("dupac-presence".into())
            .spawn(move || {
                std::thread::sleep(log.grace);
                log.warn_if_still_gone(&who, at, &warning);
            });
        if spawned.is_err() {
            tracing::warn!(id, "peer left (no thread to defer the warning)");
        }
    }

    /// Peer `id` is present again (or for the first time: then `false`). Returns whether it had
    /// departed; its return is written at warn when the departure was, at debug otherwise.
    pub fn back(&self, id: &str, what: &str) -> bool {
        let Some(d) = self.gone.lock().ok().and_then(|mut g| g.remove(id)) else {
            return false;
        };
        let s = d.at.elapsed().as_secs_f64();
        if d.warned {
            tracing::warn!("{what} back after {s:.0} s");
        } else {
            tracing::debug!("{what} back after {s:.1} s (a blip: no warning)");
        }
        true
    }

    fn warn_if_still_gone(&self, id: &str, at: Instant, warning: &str) {
        let Ok(mut gone) = self.gone.lock() else {
            return;
        };
        // Still the same departure (not back, not back and gone again since).
        if let Some(d) = gone.get_mut(id)
            && d.at == at
        {
            d.warned = true;
            tracing::warn!("{warning}");
        }
    }

    /// Whether `id` is gone and its departure has been warned about (tests).
    pub fn warned(&self, id: &str) -> bool {
        self.gone
            .lock()
            .ok()
            .and_then(|g| g.get(id).map(|d| d.warned))
            .unwrap_or(false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_blip_shorter_than_the_grace_is_not_warned() {
        let log = PresenceLog::new(Duration::from_secs(3600));
        log.left("a", "lost a".into());
        let at = departed_at(&log, "a");
        assert!(log.back("a", "a"));
        // The grace's timer fires after the return.
        log.warn_if_still_gone("a", at, "lost a");
        assert!(
            !log.warned("a"),
            "a return within the grace leaves no warning"
        );
    }

    /// When `id` departed (its pending departure's timer compares it).
    fn departed_at(log: &PresenceLog, id: &str) -> Instant {
        log.gone.lock().unwrap()[id].at
    }

    #[test]
    fn a_departure_longer_than_the_grace_is_warned_once_then_its_return() {
        // The grace's timer is called by hand: an hour's grace never fires in the test.
        let log = PresenceLog::new(Duration::from_secs(3600));
        log.left("a", "lost a".into());
        assert!(!log.warned("a"), "not before the grace");
        log.warn_if_still_gone("a", departed_at(&log, "a"), "lost a");
        assert!(log.warned("a"));
        // A second departure notice while gone changes nothing.
        log.left("a", "lost a".into());
        assert!(log.warned("a"));
        assert!(log.back("a", "a"));
        assert!(!log.back("a", "a"), "a return is matched to one departure");
    }

    #[test]
    fn the_grace_timer_warns_a_departure_that_lasts() {
        let log = PresenceLog::new(Duration::from_millis(30));
        log.left("a", "lost a".into());
        // The timer thread's turn may come late on a busy machine: 10 s is its bound.
        let deadline = Instant::now() + Duration::from_secs(10);
        while !log.warned("a") && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert!(log.warned("a"), "no warning 10 s after a 30 ms grace");
    }

    #[test]
    fn back_and_gone_again_is_a_new_departure() {
        let log = PresenceLog::new(Duration::from_secs(3600));
        log.left("a", "lost a".into());
        let first = departed_at(&log, "a");
        log.back("a", "a");
        std::thread::sleep(Duration::from_millis(2)); // a later instant for the second
        log.left("a", "lost a".into());
        // The first departure's timer fires: it must not warn the second one early.
        log.warn_if_still_gone("a", first, "lost a");
        assert!(!log.warned("a"));
        log.warn_if_still_gone("a", departed_at(&log, "a"), "lost a");
        assert!(log.warned("a"));
    }

    #[test]
    fn pending_departures_are_bounded() {
        let log = PresenceLog::new(Duration::from_secs(3600));
        for k in 0..(MAX_PENDING + 10) {
            log.left(&k.to_string(), format!("lost {k}"));
        }
        assert_eq!(log.gone.lock().map(|g| g.len()).unwrap_or(0), MAX_PENDING);
    }
}
