//! A step's record (spec/env.md "Metrics"): what every environment step reports besides the
//! observation ([`StepInfo`]). Plain data, a leaf of the crate: the environment writes it,
//! episode metrics and evaluation read it. How a flight ended is
//! [`dupac_common::msg::Outcome`].

use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;
use dupac_radio::class::RsrpClass;
use serde::{Deserialize, Serialize};

/// One step's record (spec/env.md "Metrics").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepInfo {
    /// Step index within the episode (1 for the first step).
    pub step: u32,
    /// UAV position after the move (m).
    #[serde(with = "dupac_common::geometry::serde_point")]
    pub position_m: Point,
    pub serving: SiteId,
    /// The serving site's true RSRP (dBm): what metrics score.
    pub serving_rsrp_dbm: f64,
    /// What the UAV measured of it (dBm; noisy and filtered under the real channel, equal to
    /// `serving_rsrp_dbm` where measurement is exact).
    pub measured_serving_rsrp_dbm: f64,
    /// The strongest site and its RSRP at this position.
    pub best_site: SiteId,
    pub best_rsrp_dbm: f64,
    /// Class of the serving RSRP.
    pub class: RsrpClass,
    /// Class of the best site's RSRP (class regret: the best site is excellent, the serving one
    /// is not).
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
    /// Site regret: the best site's RSRP minus the serving one's (dB, ≥ 0).
    pub fn site_regret_db(&self) -> f64 {
        (self.best_rsrp_dbm - self.serving_rsrp_dbm).max(0.0)
    }

    /// Class regret: the best site is excellent, the serving one is not.
    pub fn class_regret(&self) -> bool {
        self.best_class == RsrpClass::Excellent && self.class != RsrpClass::Excellent
    }
}
