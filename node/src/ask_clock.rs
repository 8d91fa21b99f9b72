//! When an actor or a pilot asks the learner's queryable for weights: a publication may be
//! dropped on a full link, so a process that has heard no new weights for a while asks. How long
//! is "a while" follows the run's own pace: at least [`ASK_AFTER_MIN`], and twice the last
//! interval between two versions (up to [`ASK_AFTER_MAX`]). Asking sooner than a version comes
//! would, on a slow link, fetch the whole weights a second time while their publication is
//! still on its way (0.4 MB take 0.3 s at 10 Mbit/s), taking the link from it. No zenoh here:
//! the caller passes the time.

use std::time::{Duration, Instant};

/// The least wait before asking.
pub const ASK_AFTER_MIN: Duration = Duration::from_secs(1);
/// The longest wait before asking, however slow the run: a dropped publication costs at most
/// this.
pub const ASK_AFTER_MAX: Duration = Duration::from_secs(5);

/// The time of the last weights heard or asked for, and the run's last interval between
/// versions.
#[derive(Debug, Clone)]
pub struct AskClock {
    last_event: Instant,
    last_version: Option<Instant>,
    interval: Duration,
}

impl AskClock {
    /// A clock started at `now` (nothing heard yet).
    pub fn new(now: Instant) -> AskClock {
        AskClock {
            last_event: now,
            last_version: None,
            interval: Duration::ZERO,
        }
    }

    /// New weights were taken at `now`.
    pub fn took(&mut self, now: Instant) {
        if let Some(t) = self.last_version {
            self.interval = now.saturating_duration_since(t);
        }
        self.last_version = Some(now);
        self.last_event = now;
    }

    /// The queryable was asked at `now`.
    pub fn asked(&mut self, now: Instant) {
        self.last_event = now;
    }

    /// How long after the last weights or question the next question comes.
    pub fn ask_after(&self) -> Duration {
        (2 * self.interval).clamp(ASK_AFTER_MIN, ASK_AFTER_MAX)
    }

    /// Whether to ask at `now`.
    pub fn due(&self, now: Instant) -> bool {
        now.saturating_duration_since(self.last_event) > self.ask_after()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Duration {
        Duration::from_millis(v)
    }

    /// A run that publishes every 1.4 s is not asked 1 s after a version (the next one is on
    /// its way), but is 2.8 s after it (a publication was lost); asking waits as long again.
    #[test]
    fn the_wait_follows_the_runs_pace() {
        let t0 = Instant::now();
        let mut c = AskClock::new(t0);
        assert!(!c.due(t0 + ms(900)));
        assert!(
            c.due(t0 + ms(1_100)),
            "at least a second before any version"
        );
        c.took(t0 + ms(1_000));
        c.took(t0 + ms(2_400));
        assert_eq!(c.ask_after(), ms(2_800));
        assert!(!c.due(t0 + ms(3_400)), "1 s after a version of a 1.4 s run");
        assert!(c.due(t0 + ms(5_300)), "the next publication is 1.5 s late");
        c.asked(t0 + ms(5_300));
        assert!(!c.due(t0 + ms(7_000)));
        assert!(c.due(t0 + ms(8_200)));
    }

    /// However fast or slow the versions came, the wait stays between 1 and 5 s.
    #[test]
    fn the_wait_is_bounded() {
        let t0 = Instant::now();
        let mut c = AskClock::new(t0);
        c.took(t0);
        c.took(t0 + ms(100));
        assert_eq!(c.ask_after(), ASK_AFTER_MIN);
        c.took(t0 + ms(60_100));
        assert_eq!(c.ask_after(), ASK_AFTER_MAX);
        assert!(c.due(t0 + ms(65_200)));
    }
}
