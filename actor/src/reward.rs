//! The per-site reward terms (spec/env.md "Reward", docs/env.md): the paper's Eq. (8) with the
//! RSRP classes of spec/radio.md §3, and the part of a step's reward that depends on the serving
//! site ([`site_term`]): what the environment scores its serving site with and the expansion
//! (`crate::expand`) every site's counterfactual.

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

/// The part of a step's reward that depends on the serving site: Eq. (8) with that
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
