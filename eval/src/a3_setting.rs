//! An A3 setting (a3-Offset, Hysteresis, timeToTrigger: TS 36.331 §5.5.4.4, and A3's own
//! layer-3 filterCoefficient: §5.5.3.2; docs/spec/radio.md §4) and the grid of settings
//! `dupac tune-a3` tries and `dupac eval --a3-front` re-flies.

use crate::error::EvalError;
use dupac_common::config::A3Config;
use serde::{Deserialize, Serialize};

/// TS 36.331 ReportConfigEUTRA timeToTrigger values (ms).
pub const TTT_VALUES_MS: [f64; 16] = [
    0.0, 40.0, 64.0, 80.0, 100.0, 128.0, 160.0, 256.0, 320.0, 480.0, 512.0, 640.0, 1024.0, 1280.0,
    2560.0, 5120.0,
];

/// TS 36.331 FilterCoefficient values k (fc0 … fc9, fc11, fc13, fc15, fc17, fc19).
pub const FILTER_K_VALUES: [u32; 15] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 11, 13, 15, 17, 19];

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
    /// A3's own layer-3 filter coefficient k (one of [`FILTER_K_VALUES`]): A3 filters the UAV's
    /// unfiltered measurements with it (`radio.a3.l3_filter_k`); `None`: A3 compares what the
    /// UAV holds (the channel's filter, `radio.channel.l3_filter_k`, under the real channel;
    /// none in the deterministic world).
    #[serde(default)]
    pub l3_filter_k: Option<u32>,
}

impl A3Setting {
    /// The setting of `a3`.
    pub fn of(a3: &A3Config) -> A3Setting {
        A3Setting {
            offset_db: a3.offset_db,
            hysteresis_db: a3.hysteresis_db,
            time_to_trigger_ms: a3.time_to_trigger_ms,
            l3_filter_k: a3.l3_filter_k,
        }
    }

    /// Sets `a3` to this setting.
    pub fn apply(&self, a3: &mut A3Config) {
        a3.offset_db = self.offset_db;
        a3.hysteresis_db = self.hysteresis_db;
        a3.time_to_trigger_ms = self.time_to_trigger_ms;
        a3.l3_filter_k = self.l3_filter_k;
    }

    /// The entering margin offset + hysteresis (dB): with every Of*/Oc* = 0 the handover
    /// condition `M_n − Hys > M_s + Off` depends on nothing else of the two.
    pub fn margin_db(&self) -> f64 {
        self.offset_db + self.hysteresis_db
    }

    /// `offset / hysteresis / TTT` (and `/ kK` with A3's own filter), as the tables write it.
    pub fn label(&self) -> String {
        let mut s = format!(
            "{} / {} / {} ms",
            self.offset_db, self.hysteresis_db, self.time_to_trigger_ms
        );
        if let Some(k) = self.l3_filter_k {
            s.push_str(&format!(" / k{k}"));
        }
        s
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
        if let Some(k) = self.l3_filter_k
            && !FILTER_K_VALUES.contains(&k)
        {
            return Err(format!(
                "filterCoefficient k = {k}: TS 36.331 allows {FILTER_K_VALUES:?}"
            ));
        }
        Ok(())
    }
}

/// The grid of settings tried: every offset × hysteresis × time-to-trigger × A3 filter.
#[derive(Debug, Clone, PartialEq)]
pub struct A3Grid {
    pub offsets_db: Vec<f64>,
    pub hysteresis_db: Vec<f64>,
    pub ttt_ms: Vec<f64>,
    /// A3's own filter coefficients (`None`: what the UAV holds).
    pub l3_filter_k: Vec<Option<u32>>,
}

impl Default for A3Grid {
    /// TS 36.331's useful range: offset 0, 1, …, 15 dB at hysteresis 0 (the handover depends on
    /// their sum only, [`A3Setting::margin_db`], and 15 dB is the offset's largest value) ×
    /// TTT {0, 80, 160, 320, 640, 1280} ms × A3's filter k ∈ {0, 4, 8}.
    fn default() -> Self {
        A3Grid {
            offsets_db: (0..=15).map(f64::from).collect(),
            hysteresis_db: vec![0.0],
            ttt_ms: vec![0.0, 80.0, 160.0, 320.0, 640.0, 1280.0],
            l3_filter_k: vec![Some(0), Some(4), Some(8)],
        }
    }
}

impl A3Grid {
    /// Every setting, offset outermost, the filter innermost, duplicates dropped; refused
    /// (naming the flag and the value) when a list is empty or a value is not TS 36.331's.
    pub fn settings(&self) -> Result<Vec<A3Setting>, EvalError> {
        let base = A3Setting {
            offset_db: 0.0,
            hysteresis_db: 0.0,
            time_to_trigger_ms: 0.0,
            l3_filter_k: None,
        };
        // Each flag's values, each in a setting that is legal but for it.
        let check = |flag: &str, n: usize, at: &dyn Fn(usize) -> A3Setting| {
            if n == 0 {
                return Err(EvalError::Refused(format!("{flag}: no values")));
            }
            (0..n).try_for_each(|i| {
                at(i)
                    .check_legal()
                    .map_err(|e| EvalError::Refused(format!("{flag}: {e}")))
            })
        };
        check("--offset-db", self.offsets_db.len(), &|i| A3Setting {
            offset_db: self.offsets_db[i],
            ..base
        })?;
        check("--hysteresis-db", self.hysteresis_db.len(), &|i| {
            A3Setting {
                hysteresis_db: self.hysteresis_db[i],
                ..base
            }
        })?;
        check("--ttt-ms", self.ttt_ms.len(), &|i| A3Setting {
            time_to_trigger_ms: self.ttt_ms[i],
            ..base
        })?;
        check("--l3-filter-k", self.l3_filter_k.len(), &|i| A3Setting {
            l3_filter_k: self.l3_filter_k[i],
            ..base
        })?;
        let mut out: Vec<A3Setting> = Vec::new();
        for &offset_db in &self.offsets_db {
            for &hysteresis_db in &self.hysteresis_db {
                for &time_to_trigger_ms in &self.ttt_ms {
                    for &l3_filter_k in &self.l3_filter_k {
                        let s = A3Setting {
                            offset_db,
                            hysteresis_db,
                            time_to_trigger_ms,
                            l3_filter_k,
                        };
                        if !out.contains(&s) {
                            out.push(s);
                        }
                    }
                }
            }
        }
        Ok(out)
    }
}
