//! The checks every section's validation uses; each error names the key.

use super::ConfigError;

/// A day (s): the bound of durations that size waiting.
pub(crate) const DAY_S: f64 = 86_400.0;

pub(crate) fn bad(key: &str, message: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        key: key.to_string(),
        message: message.into(),
    }
}

pub(crate) fn positive(key: &str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(bad(key, format!("must be a finite number > 0, got {v}")))
    }
}

pub(crate) fn finite(key: &str, v: f64) -> Result<(), ConfigError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(bad(key, format!("must be finite, got {v}")))
    }
}

pub(crate) fn within(key: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Result<(), ConfigError> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(ConfigError::Invalid {
            key: key.to_string(),
            message: format!("must be in [{lo}, {hi}] {unit}, got {v}"),
        })
    }
}

pub(crate) fn at_most(key: &str, v: u64, hi: u64) -> Result<(), ConfigError> {
    if v <= hi {
        Ok(())
    } else {
        Err(ConfigError::Invalid {
            key: key.to_string(),
            message: format!("must be at most {hi}, got {v}"),
        })
    }
}
