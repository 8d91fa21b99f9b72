//! Fault injection for the reliability tests (docs/reliability.md): a process started
//! with `DUPAC_FAULT=<point>:<n>` aborts (SIGABRT, no unwinding, no destructors: as a power cut
//! or a SIGKILL would leave it) the n-th time (1-based) it passes the crash point `<point>`.
//! Unset, a crash point costs one relaxed atomic load.
//!
//! Crash points:
//! - `atomic-write`: inside [`crate::fsio::write_atomic`] (checkpoints and policies), after half of the bytes went to the
//!   temporary file and before the rename (checkpoints, exported policies).

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};

/// The environment variable that arms a crash point.
pub const FAULT_ENV: &str = "DUPAC_FAULT";

fn armed() -> Option<&'static (String, u64)> {
    static ARMED: OnceLock<Option<(String, u64)>> = OnceLock::new();
    ARMED
        .get_or_init(|| {
            let v = std::env::var(FAULT_ENV).ok()?;
            let (point, n) = v.rsplit_once(':')?;
            Some((point.to_string(), n.parse().ok()?))
        })
        .as_ref()
}

/// Aborts the process here if `DUPAC_FAULT` names `point` and this is its n-th passage.
pub fn crash_point(point: &str) {
    static PASSED: AtomicU64 = AtomicU64::new(0);
    if let Some((p, n)) = armed()
        && p == point
        && PASSED.fetch_add(1, Ordering::Relaxed) + 1 == *n
    {
        eprintln!("{FAULT_ENV}: aborting at crash point {point} (passage {n})");
        std::process::abort();
    }
}
