//! What every step reports besides the observation: the record evaluation is built from.

use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_radio::class::RsrpClass;
use serde::{Deserialize, Serialize};

use dupac_common::msg::Outcome;

/// One step's record (spec/env.md "Metrics").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepInfo {
    /// Step index within the episode (1 for the first step).
    pub step: u32,
    /// UAV position after the move (m).
    #[serde(with = "dupac_common::geometry::serde_point")]
    pub position_m: Point,
    pub serving: SiteId,
    pub serving_rsrp_dbm: f64,
    /// The strongest site and its RSRP at this position.
    pub best_site: SiteId,
    pub best_rsrp_dbm: f64,
    /// Class of the serving RSRP.
    pub class: RsrpClass,
    /// Class of the best site's RSRP (issue 15's class regret: the best site is excellent, the
    /// serving one is not).
    pub best_class: RsrpClass,
    /// Whether the serving link is line of sight (geometric).
    pub los: bool,
    pub handover: bool,
    /// A handover back to the previous site within `env.ping_pong_window_s`.
    pub ping_pong: bool,
    /// Length of this step's move (m).
    pub step_length_m: f64,
    /// Distance flown since the start of the episode (m).
    pub distance_flown_m: f64,
    /// Euclidean distance to the destination after the move (m).
    pub distance_to_goal_m: f64,
    pub reward: f64,
    pub outcome: Option<Outcome>,
}

impl StepInfo {
    /// Site regret: the best site's RSRP minus the serving one's (dB, ≥ 0), issue 15.
    pub fn site_regret_db(&self) -> f64 {
        (self.best_rsrp_dbm - self.serving_rsrp_dbm).max(0.0)
    }

    /// Class regret: the best site is excellent, the serving one is not.
    pub fn class_regret(&self) -> bool {
        self.best_class == RsrpClass::Excellent && self.class != RsrpClass::Excellent
    }
}
