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

    fn wait() {
        std::thread::sleep(Duration::from_millis(150));
    }

    #[test]
    fn a_blip_shorter_than_the_grace_is_not_warned() {
        let log = PresenceLog::new(Duration::from_millis(60));
        log.left("a", "lost a".into());
        assert!(log.back("a", "a"));
        wait();
        assert!(
            !log.warned("a"),
            "a return within the grace leaves no warning"
        );
    }

    #[test]
    fn a_departure_longer_than_the_grace_is_warned_once_then_its_return() {
        let log = PresenceLog::new(Duration::from_millis(30));
        log.left("a", "lost a".into());
        assert!(!log.warned("a"), "not before the grace");
        wait();
        assert!(log.warned("a"));
        // A second departure notice while gone changes nothing.
        log.left("a", "lost a".into());
        assert!(log.warned("a"));
        assert!(log.back("a", "a"));
        assert!(!log.back("a", "a"), "a return is matched to one departure");
    }

    #[test]
    fn back_and_gone_again_is_a_new_departure() {
        let log = PresenceLog::new(Duration::from_millis(80));
        log.left("a", "lost a".into());
        std::thread::sleep(Duration::from_millis(40));
        log.back("a", "a");
        log.left("a", "lost a".into());
        // The first departure's timer fires now: it must not warn the second one early.
        std::thread::sleep(Duration::from_millis(50));
        assert!(!log.warned("a"));
        wait();
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
