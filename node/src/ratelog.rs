//! Warnings that a peer can cause, one line per kind per period with counts: a flood of bad
//! messages writes a few lines, not one per message (the log, and the disk under it, must not
//! grow with an attack).
//!
//! The first event of a kind is logged at once, with its detail. Further events of that kind
//! within `period` are counted (events, distinct senders, the latest detail) and summed into one
//! line once the period is over: at the next event of any kind, or at [`RateLog::flush_due`],
//! which the node calls from its loops, or at [`RateLog::flush`]. Written by hand: the tracing
//! ecosystem's rate limiters (e.g. `tracing-throttle`) drop repeated lines but do not sum them
//! into counts with their senders, which is what a person reading the log needs.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Display;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// Most distinct senders counted per kind and period (beyond: counted as "at least").
const MAX_SENDERS: usize = 4096;
/// Longest detail kept (characters); longer ones are cut with "…".
pub const MAX_DETAIL_CHARS: usize = 240;
/// Longest log line the binary writes (characters; `dupac`'s log writer cuts longer ones).
pub const MAX_LINE_CHARS: usize = 400;

/// One kind's events since its last line.
#[derive(Debug)]
struct Window {
    started: Instant,
    count: u64,
    senders: BTreeSet<u32>,
    detail: String,
}

/// Rate-limited warnings by kind (see the module documentation).
#[derive(Debug)]
pub struct RateLog {
    period: Duration,
    windows: Mutex<BTreeMap<&'static str, Window>>,
}

/// `detail` cut to [`MAX_DETAIL_CHARS`] characters.
pub fn cut(detail: &str) -> String {
    cut_to(detail, MAX_DETAIL_CHARS)
}

/// `text` cut to `max_chars` characters, saying how many bytes were left out.
pub fn cut_to(text: &str, max_chars: usize) -> String {
    match text.char_indices().nth(max_chars) {
        None => text.to_string(),
        Some((at, _)) => format!("{}… ({} more bytes)", &text[..at], text.len() - at),
    }
}

impl RateLog {
    /// At most one line per kind per `period`.
    pub fn new(period: Duration) -> RateLog {
        RateLog {
            period,
            windows: Mutex::new(BTreeMap::new()),
        }
    }

    /// One event: `what` is the noun of what was dropped ("trajectory chunk"; the sums add "s"),
    /// `sender` the actor it came from (when known), `detail` why (cut to
    /// [`MAX_DETAIL_CHARS`]).
    pub fn warn(&self, what: &'static str, sender: Option<u32>, detail: impl Display) {
        let detail = cut(&detail.to_string());
        let mut lines = Vec::new();
        if let Ok(mut w) = self.windows.lock() {
            self.take_due(&mut w, &mut lines);
            match w.get_mut(what) {
                Some(win) => {
                    win.count += 1;
                    if win.senders.len() < MAX_SENDERS {
                        win.senders.extend(sender);
                    }
                    win.detail = detail;
                }
                None => {
                    let from = sender.map_or(String::new(), |s| format!(" from actor {s}"));
                    lines.push(format!("dropped one {what}{from}: {detail}"));
                    w.insert(
                        what,
                        Window {
                            started: Instant::now(),
                            count: 0,
                            senders: BTreeSet::new(),
                            detail: String::new(),
                        },
                    );
                }
            }
        }
        for l in lines {
            tracing::warn!("{l}");
        }
    }

    /// Writes the sums of the kinds whose period is over.
    pub fn flush_due(&self) {
        let mut lines = Vec::new();
        if let Ok(mut w) = self.windows.lock() {
            self.take_due(&mut w, &mut lines);
        }
        for l in lines {
            tracing::warn!("{l}");
        }
    }

    /// Writes every sum now (at the end of a run).
    pub fn flush(&self) {
        let mut lines = Vec::new();
        if let Ok(mut w) = self.windows.lock() {
            for (what, win) in std::mem::take(&mut *w) {
                lines.extend(summary(what, &win));
            }
        }
        for l in lines {
            tracing::warn!("{l}");
        }
    }

    /// Removes the windows whose period is over, their sums into `lines`.
    fn take_due(&self, w: &mut BTreeMap<&'static str, Window>, lines: &mut Vec<String>) {
        let period = self.period;
        w.retain(|what, win| {
            if win.started.elapsed() < period {
                return true;
            }
            lines.extend(summary(what, win));
            false
        });
    }
}

/// The line of a window's events after the first, if any.
fn summary(what: &str, win: &Window) -> Option<String> {
    if win.count == 0 {
        return None;
    }
    let senders = match win.senders.len() {
        0 => String::new(),
        n if n >= MAX_SENDERS => format!(" from at least {n} senders"),
        1 => " from 1 sender".to_string(),
        n => format!(" from {n} senders"),
    };
    Some(format!(
        "dropped {} more {what}s{senders} in the last {:.0} s: {}",
        win.count,
        win.started.elapsed().as_secs_f64(),
        win.detail
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn details_are_cut() {
        assert_eq!(cut("short"), "short");
        let long = "x".repeat(1000);
        let c = cut(&long);
        assert!(c.starts_with(&"x".repeat(MAX_DETAIL_CHARS)));
        assert!(c.ends_with("… (760 more bytes)"), "{c}");
    }

    #[test]
    fn a_burst_is_one_line_then_a_sum() {
        // An hour's period: the whole burst falls in one window however slow the machine.
        let mut log = RateLog::new(Duration::from_secs(3600));
        for k in 0..40u32 {
            log.warn("trajectory chunk", Some(k % 8), "over the decoding budget");
        }
        let w = log.windows.lock().expect("lock");
        let win = w.get("trajectory chunk").expect("window");
        assert_eq!((win.count, win.senders.len()), (39, 8));
        let line = summary("trajectory chunk", win).expect("a sum");
        assert!(
            line.starts_with("dropped 39 more trajectory chunks from 8 senders in the last"),
            "{line}"
        );
        drop(w);
        log.flush_due();
        assert!(
            !log.windows.lock().expect("lock").is_empty(),
            "not due before its period"
        );
        log.period = Duration::ZERO; // the period is over
        log.flush_due();
        assert!(
            log.windows.lock().expect("lock").is_empty(),
            "the sum was written"
        );
    }
}
