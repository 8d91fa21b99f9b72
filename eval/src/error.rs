//! The evaluation's refusals: `refused!(…)`, a refusal with a formatted reason.

/// A refusal with a formatted reason.
macro_rules! refused {
    ($($t:tt)*) => { dupac_run::error::RunError::Refused(format!($($t)*)) };
}
pub(crate) use refused;
