//! The paper's reward, Eq. (8), with the RSRP classes of spec/radio.md §3.

use dupac_common::config::RewardConfig;
use dupac_radio::class::{RsrpClass, RsrpThresholds};

/// Per-step reward of paper Eq. (8): excellent `μ1·Δd`; mediocre `μ1·Δd + μ2·w`; poor `μ3·w`,
/// with `Δd` the progress towards the destination (m) and `w` the serving RSRP (dBm).
#[inline]
pub fn step_reward(
    cfg: &RewardConfig,
    class: RsrpClass,
    progress_m: f64,
    serving_rsrp_dbm: f64,
) -> f64 {
    match class {
        RsrpClass::Excellent => cfg.mu1 * progress_m,
        RsrpClass::Mediocre => cfg.mu1 * progress_m + cfg.mu2 * serving_rsrp_dbm,
        RsrpClass::Poor => cfg.mu3 * serving_rsrp_dbm,
    }
}

/// RSRP below this (dBm) counts as this in rewards: a site that cannot be measured (−∞) gets a
/// finite, very poor reward instead of a non-finite one.
pub const RSRP_FLOOR_DBM: f64 = -200.0;

/// Site regret (dB) above this adds no more to the regret term.
pub const MAX_REGRET_DB: f64 = 60.0;

/// The part of a step's reward that depends on the serving site (issue 15): Eq. (8) with that
/// site's RSRP and class (nothing after a collision or leaving the area, whose reward replaces
/// Eq. (8)), the handover cost `handover_reward` if serving it is a handover (and
/// `ping_pong_reward` too if that handover is a ping-pong), and
/// `−site_regret_weight · min(best − rsrp, 60 dB)`.
#[allow(clippy::too_many_arguments)]
pub fn site_term(
    cfg: &RewardConfig,
    thresholds: &RsrpThresholds,
    crashed: bool,
    progress_m: f64,
    rsrp_dbm: f64,
    best_rsrp_dbm: f64,
    handover: bool,
    ping_pong: bool,
) -> f64 {
    let w = rsrp_dbm.max(RSRP_FLOOR_DBM);
    let mut r = if crashed {
        0.0
    } else {
        step_reward(cfg, thresholds.classify(w), progress_m, w)
    };
    if handover {
        r += cfg.handover_reward;
        if ping_pong {
            r += cfg.ping_pong_reward;
        }
    }
    if cfg.site_regret_weight > 0.0 {
        let regret = (best_rsrp_dbm.max(RSRP_FLOOR_DBM) - w).clamp(0.0, MAX_REGRET_DB);
        r -= cfg.site_regret_weight * regret;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn r(rsrp: f64, progress: f64) -> f64 {
        let t = RsrpThresholds::default();
        step_reward(&RewardConfig::default(), t.classify(rsrp), progress, rsrp)
    }

    #[test]
    fn each_class_and_its_boundaries() {
        // Excellent (≥ −80): 10 · Δd, RSRP ignored.
        assert_eq!(r(-60.0, 0.5), 5.0);
        assert_eq!(r(-80.0, 1.0), 10.0);
        // Mediocre [−100, −80): 10 · Δd + 0.01 · w.
        assert!((r(-80.0001, 1.0) - (10.0 - 0.800001)).abs() < 1e-9);
        assert!((r(-90.0, 1.0) - 9.1).abs() < 1e-12);
        assert!((r(-100.0, -1.0) - (-10.0 - 1.0)).abs() < 1e-12);
        // Poor (< −100): 0.1 · w, no progress term.
        assert!((r(-100.5, 1.0) - (-10.05)).abs() < 1e-12);
        assert!((r(-120.0, 1.0) - (-12.0)).abs() < 1e-12);
        assert_eq!(r(-120.0, 1.0), r(-120.0, -1.0));
    }
}
