//! Every reward term of a step (spec/env.md "Reward", docs/env.md): the paper's Eq. (8) with the
//! RSRP classes of spec/radio.md §3, the terminal rewards, the route's connectivity term, the
//! handover and ping-pong costs and the site regret; [`StepTerms`] sums them for the site that
//! serves (every site's counterfactual: [`crate::expand::Expander::site_rows`]).

use crate::reward::site_term;
use dupac_common::config::RewardConfig;
use dupac_common::msg::Outcome;
use dupac_radio::class::{RsrpClass, RsrpThresholds};

/// One step's reward terms, from what the step's stages produced: the site-independent part
/// (terminal rewards, the route's connectivity term, the goal) and what the per-site part
/// ([`site_term`]) reads.
pub(super) struct StepTerms<'a> {
    cfg: &'a RewardConfig,
    thresholds: &'a RsrpThresholds,
    /// The site-independent reward: `collision_reward` or `out_of_bounds_reward`, minus the
    /// route term, plus `goal_reward`.
    common: f64,
    /// A collision or leaving the area: its reward replaces Eq. (8).
    crashed: bool,
    /// The step's progress towards the destination (m).
    progress_m: f64,
    /// The strongest site's RSRP at the new position (dBm).
    best_rsrp_dbm: f64,
}

impl<'a> StepTerms<'a> {
    /// The terms of a step with `outcome` (collision, out of bounds or goal; none yet for the
    /// time limit) that flew `step_length_m` (m) with `progress_m` (m) of progress, the
    /// strongest site at `best_rsrp_dbm` (dBm); `route_penalty` is the coverage-aware planner's
    /// per-metre penalty of a mediocre and a poor best site, for `route_connectivity_weight`.
    pub fn new(
        cfg: &'a RewardConfig,
        thresholds: &'a RsrpThresholds,
        route_penalty: [f64; 2],
        outcome: Option<Outcome>,
        step_length_m: f64,
        progress_m: f64,
        best_rsrp_dbm: f64,
    ) -> StepTerms<'a> {
        let crashed = matches!(outcome, Some(Outcome::Collision | Outcome::OutOfBounds));
        let mut common = match outcome {
            Some(Outcome::Collision) => cfg.collision_reward,
            Some(Outcome::OutOfBounds) => cfg.out_of_bounds_reward,
            _ => 0.0,
        };
        if cfg.route_connectivity_weight > 0.0 {
            let penalty = match thresholds.classify(best_rsrp_dbm) {
                RsrpClass::Excellent => 0.0,
                RsrpClass::Mediocre => route_penalty[0],
                RsrpClass::Poor => route_penalty[1],
            };
            common -= cfg.mu1 * cfg.route_connectivity_weight * penalty * step_length_m;
        }
        if outcome == Some(Outcome::Goal) {
            common += cfg.goal_reward;
        }
        StepTerms {
            cfg,
            thresholds,
            common,
            crashed,
            progress_m,
            best_rsrp_dbm,
        }
    }

    /// The step's reward with a site of `rsrp_dbm` (dBm) serving, `handover` and `ping_pong`
    /// saying whether serving it was one.
    pub fn reward(&self, rsrp_dbm: f64, handover: bool, ping_pong: bool) -> f64 {
        self.common
            + site_term(
                self.cfg,
                self.thresholds,
                self.crashed,
                self.progress_m,
                rsrp_dbm,
                self.best_rsrp_dbm,
                handover,
                ping_pong,
            )
    }

    /// The step's site-independent reward (terminal rewards, the route term, the goal).
    pub fn common(&self) -> f64 {
        self.common
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reward::step_reward;

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
