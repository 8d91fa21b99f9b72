//! RSRP reward classes (spec/radio.md §3): C1 excellent RSRP ≥ −80 dBm, C2 mediocre
//! −100 ≤ RSRP < −80 dBm, poor RSRP < −100 dBm (boundaries: −80 is excellent, −100 is mediocre).

use dupac_common::config::RadioConfig;
use serde::{Deserialize, Serialize};

/// RSRP class of a link (spec/radio.md §3): the three bands of the paper's reward.
/// Serialised as `"excellent"`, `"mediocre"`, `"poor"`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum RsrpClass {
    /// C1: RSRP ≥ `excellent_dbm` (−80 dBm by default).
    Excellent,
    /// C2: `poor_dbm` ≤ RSRP < `excellent_dbm` (−100 … −80 dBm by default).
    Mediocre,
    /// RSRP < `poor_dbm` (−100 dBm by default), or not a number.
    Poor,
}

impl RsrpClass {
    /// All classes, best first (spec/radio.md §3).
    pub const ALL: [RsrpClass; 3] = [RsrpClass::Excellent, RsrpClass::Mediocre, RsrpClass::Poor];

    /// Lower-case name, the same as the serde name: `"excellent"`, `"mediocre"`, `"poor"`
    /// (spec/radio.md §3).
    pub fn name(self) -> &'static str {
        match self {
            RsrpClass::Excellent => "excellent",
            RsrpClass::Mediocre => "mediocre",
            RsrpClass::Poor => "poor",
        }
    }

    /// Index of the class in [`RsrpClass::ALL`] (0 excellent, 1 mediocre, 2 poor): the one
    /// place per-class counts and shares are indexed from.
    pub fn index(self) -> usize {
        match self {
            RsrpClass::Excellent => 0,
            RsrpClass::Mediocre => 1,
            RsrpClass::Poor => 2,
        }
    }
}

/// The two class boundaries in dBm (spec/radio.md §3; config keys `radio.rsrp_excellent_dbm`,
/// `radio.rsrp_poor_dbm`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RsrpThresholds {
    /// Lowest RSRP (dBm) that is excellent (inclusive), default −80.
    pub excellent_dbm: f64,
    /// Lowest RSRP (dBm) that is mediocre (inclusive), default −100; below it is poor.
    pub poor_dbm: f64,
}

impl Default for RsrpThresholds {
    /// The paper's thresholds: −80 dBm and −100 dBm (spec/radio.md §3).
    fn default() -> Self {
        Self {
            excellent_dbm: -80.0,
            poor_dbm: -100.0,
        }
    }
}

impl RsrpThresholds {
    /// Takes `rsrp_excellent_dbm` and `rsrp_poor_dbm` (dBm) from the radio config
    /// (spec/radio.md §3).
    pub fn from_config(cfg: &RadioConfig) -> Self {
        Self {
            excellent_dbm: cfg.rsrp_excellent_dbm,
            poor_dbm: cfg.rsrp_poor_dbm,
        }
    }

    /// Class of an RSRP value in dBm (spec/radio.md §3): `≥ excellent_dbm` → Excellent,
    /// else `≥ poor_dbm` → Mediocre, else Poor. NaN is Poor.
    #[inline]
    pub fn classify(&self, rsrp_dbm: f64) -> RsrpClass {
        if rsrp_dbm >= self.excellent_dbm {
            RsrpClass::Excellent
        } else if rsrp_dbm >= self.poor_dbm {
            RsrpClass::Mediocre
        } else {
            RsrpClass::Poor
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn rank(c: RsrpClass) -> u8 {
        match c {
            RsrpClass::Poor => 0,
            RsrpClass::Mediocre => 1,
            RsrpClass::Excellent => 2,
        }
    }

    #[test]
    fn boundaries_are_exact() {
        let t = RsrpThresholds::default();
        assert_eq!(t.classify(-80.0), RsrpClass::Excellent);
        assert_eq!(t.classify(-79.0), RsrpClass::Excellent);
        assert_eq!(t.classify((-80.0f64).next_down()), RsrpClass::Mediocre);
        assert_eq!(t.classify(-100.0), RsrpClass::Mediocre);
        assert_eq!(t.classify(-100.0001), RsrpClass::Poor);
        assert_eq!(t.classify(f64::NAN), RsrpClass::Poor);
        assert_eq!(t.classify(f64::NEG_INFINITY), RsrpClass::Poor);
        assert_eq!(t.classify(f64::INFINITY), RsrpClass::Excellent);
    }

    #[test]
    fn spec_table_examples() {
        // spec §3 table: −75.34 excellent, −89.32 mediocre, −106.39 poor, −78.63 excellent
        let t = RsrpThresholds::default();
        assert_eq!(t.classify(-75.34), RsrpClass::Excellent);
        assert_eq!(t.classify(-89.32), RsrpClass::Mediocre);
        assert_eq!(t.classify(-106.39), RsrpClass::Poor);
        assert_eq!(t.classify(-78.63), RsrpClass::Excellent);
    }

    #[test]
    fn from_config_and_default_agree() {
        let cfg = RadioConfig::default();
        assert_eq!(RsrpThresholds::from_config(&cfg), RsrpThresholds::default());
        let cfg = RadioConfig {
            rsrp_excellent_dbm: -70.0,
            rsrp_poor_dbm: -90.0,
            ..RadioConfig::default()
        };
        let t = RsrpThresholds::from_config(&cfg);
        assert_eq!(t.classify(-75.0), RsrpClass::Mediocre);
        assert_eq!(t.classify(-90.5), RsrpClass::Poor);
    }

    #[test]
    fn names_and_serde() {
        let names: Vec<&str> = RsrpClass::ALL.iter().map(|c| c.name()).collect();
        assert_eq!(names, ["excellent", "mediocre", "poor"]);
        for c in RsrpClass::ALL {
            let s = serde_json::to_string(&c).expect("serialise");
            assert_eq!(s, format!("\"{}\"", c.name()));
            let back: RsrpClass = serde_json::from_str(&s).expect("deserialise");
            assert_eq!(back, c);
        }
    }

    proptest! {
        #[test]
        fn classify_is_monotone(a in -200.0f64..0.0, b in -200.0f64..0.0) {
            let t = RsrpThresholds::default();
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            prop_assert!(rank(t.classify(lo)) <= rank(t.classify(hi)));
        }
    }
}
