//! An A3 setting (a3-Offset, Hysteresis, timeToTrigger: TS 36.331 §5.5.4.4, docs/spec/radio.md
//! §4) and the grid of settings `dupac tune-a3` tries and `dupac eval --a3-front` re-flies.

use dupac_common::config::A3Config;
use dupac_run::error::RunError;
use serde::{Deserialize, Serialize};

/// TS 36.331 ReportConfigEUTRA timeToTrigger values (ms).
pub const TTT_VALUES_MS: [f64; 16] = [
    0.0, 40.0, 64.0, 80.0, 100.0, 128.0, 160.0, 256.0, 320.0, 480.0, 512.0, 640.0, 1024.0, 1280.0,
    2560.0, 5120.0,
];

/// One A3 setting (TS 36.331 §5.5.4.4; all Of*/Oc* = 0): what `tuned_a3.toml` holds.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct A3Setting {
    /// a3-Offset (dB): −15…15 in 0.5 dB steps.
    pub offset_db: f64,
    /// Hysteresis (dB): 0…15 in 0.5 dB steps.
    pub hysteresis_db: f64,
    /// timeToTrigger (ms): one of [`TTT_VALUES_MS`].
    pub time_to_trigger_ms: f64,
}

impl A3Setting {
    /// The setting of `a3` (its L3 filter aside).
    pub fn of(a3: &A3Config) -> A3Setting {
        A3Setting {
            offset_db: a3.offset_db,
            hysteresis_db: a3.hysteresis_db,
            time_to_trigger_ms: a3.time_to_trigger_ms,
        }
    }

    /// Sets `a3`'s offset, hysteresis and time-to-trigger to this setting's (the L3 filter,
    /// `radio.a3.l3_filter_k`, stays as configured).
    pub fn apply(&self, a3: &mut A3Config) {
        a3.offset_db = self.offset_db;
        a3.hysteresis_db = self.hysteresis_db;
        a3.time_to_trigger_ms = self.time_to_trigger_ms;
    }

    /// Whether TS 36.331 can signal it (docs/spec/radio.md §4); the error names the value.
    pub fn check_legal(&self) -> Result<(), String> {
        let half_db = |x: f64| (2.0 * x - (2.0 * x).round()).abs() < 1e-9;
        if !(self.offset_db.is_finite()
            && (-15.0..=15.0).contains(&self.offset_db)
            && half_db(self.offset_db))
        {
            return Err(format!(
                "a3-Offset {} dB: TS 36.331 allows −15…15 dB in 0.5 dB steps",
                self.offset_db
            ));
        }
        if !(self.hysteresis_db.is_finite()
            && (0.0..=15.0).contains(&self.hysteresis_db)
            && half_db(self.hysteresis_db))
        {
            return Err(format!(
                "hysteresis {} dB: TS 36.331 allows 0…15 dB in 0.5 dB steps",
                self.hysteresis_db
            ));
        }
        if !TTT_VALUES_MS.contains(&self.time_to_trigger_ms) {
            return Err(format!(
                "timeToTrigger {} ms: TS 36.331 allows {TTT_VALUES_MS:?} ms",
                self.time_to_trigger_ms
            ));
        }
        Ok(())
    }
}

/// The grid of settings tried: every offset × hysteresis × time-to-trigger.
#[derive(Debug, Clone, PartialEq)]
pub struct A3Grid {
    pub offsets_db: Vec<f64>,
    pub hysteresis_db: Vec<f64>,
    pub ttt_ms: Vec<f64>,
}

impl Default for A3Grid {
    /// Offset {0, 1, 2, 3, 4} dB × hysteresis {0, 0.5, 1, 2} dB × TTT {0, 40, 80, 160, 320} ms.
    fn default() -> Self {
        A3Grid {
            offsets_db: vec![0.0, 1.0, 2.0, 3.0, 4.0],
            hysteresis_db: vec![0.0, 0.5, 1.0, 2.0],
            ttt_ms: vec![0.0, 40.0, 80.0, 160.0, 320.0],
        }
    }
}

impl A3Grid {
    /// Every setting, offset outermost, TTT innermost, duplicates dropped; refused (naming the
    /// flag) when a list is empty or a value is not TS 36.331's.
    pub fn settings(&self) -> Result<Vec<A3Setting>, RunError> {
        for (flag, v) in [
            ("--offset-db", &self.offsets_db),
            ("--hysteresis-db", &self.hysteresis_db),
            ("--ttt-ms", &self.ttt_ms),
        ] {
            if v.is_empty() {
                return Err(RunError::Refused(format!("{flag}: no values")));
            }
        }
        let mut out: Vec<A3Setting> = Vec::new();
        for &offset_db in &self.offsets_db {
            for &hysteresis_db in &self.hysteresis_db {
                for &time_to_trigger_ms in &self.ttt_ms {
                    let s = A3Setting {
                        offset_db,
                        hysteresis_db,
                        time_to_trigger_ms,
                    };
                    s.check_legal().map_err(|e| {
                        RunError::Refused(format!("--offset-db/--hysteresis-db/--ttt-ms: {e}"))
                    })?;
                    if !out.contains(&s) {
                        out.push(s);
                    }
                }
            }
        }
        Ok(out)
    }
}
