//! The records of a flight (spec/env.md "Metrics"): what every environment step reports besides
//! the observation ([`StepInfo`]), what evaluation keeps of a step ([`StepRecord`]) and of a
//! whole flight ([`FlightRecord`]). Plain data, a leaf of the crate: the environment writes
//! these, metrics and evaluation read them, and this module depends on none of them. How a
//! flight ended is [`dupac_common::msg::Outcome`].

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

/// One step of a flight, as evaluation keeps it (f32 positions and powers: 40 bytes a step).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct StepRecord {
    /// UAV position after the move (m).
    pub position_m: [f32; 3],
    pub serving: u16,
    /// True RSRP of the serving site (dBm).
    pub serving_rsrp_dbm: f32,
    /// What the UAV measured of it (dBm).
    pub measured_serving_rsrp_dbm: f32,
    /// The strongest site here and its RSRP.
    pub best_site: u16,
    pub best_rsrp_dbm: f32,
    /// SINR of the serving site against all others (`dupac_eval::sinr::sinr_db`).
    pub sinr_db: f32,
    pub class: RsrpClass,
    /// Class of the best site's RSRP (class regret: best excellent, serving not).
    pub best_class: RsrpClass,
    /// Geometric line of sight to the serving site.
    pub los: bool,
    pub handover: bool,
    pub ping_pong: bool,
}

impl StepRecord {
    /// The record of an environment step, with the SINR computed by the caller.
    pub fn from_info(info: &StepInfo, sinr_db: f64) -> StepRecord {
        let p = info.position_m;
        StepRecord {
            position_m: [p[0] as f32, p[1] as f32, p[2] as f32],
            serving: info.serving.0,
            serving_rsrp_dbm: info.serving_rsrp_dbm as f32,
            measured_serving_rsrp_dbm: info.measured_serving_rsrp_dbm as f32,
            best_site: info.best_site.0,
            best_rsrp_dbm: info.best_rsrp_dbm as f32,
            sinr_db: sinr_db as f32,
            class: info.class,
            best_class: info.best_class,
            los: info.los,
            handover: info.handover,
            ping_pong: info.ping_pong,
        }
    }
}

/// One flight of one method (and training seed) over one pair.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FlightRecord {
    /// Method label (`dupac`, `base`, `shortest_a3`, `coverage_l1`, …).
    pub method: String,
    /// Training seed index of the method's policy (0 for planners).
    pub seed: u32,
    pub pair_id: u64,
    /// Evaluation bin of the pair (m of shortest flyable distance).
    pub bin_m: f64,
    /// Shortest flyable path D and straight line of the pair (m).
    pub shortest_m: f64,
    pub straight_m: f64,
    pub outcome: Outcome,
    /// Source of the flight (m): the first step's distance is measured from it.
    #[serde(with = "dupac_common::geometry::serde_point")]
    pub source_m: Point,
    /// Destination of the flight (m).
    #[serde(with = "dupac_common::geometry::serde_point")]
    pub destination_m: Point,
    /// Distance left to the destination at the end (m; ≤ the goal radius on success).
    pub remaining_m: f64,
    /// The serving site before the first step: the one the environment chose at the source (the
    /// strongest that the UAV measured); handovers are counted from it.
    pub start_serving: u16,
    pub steps: Vec<StepRecord>,
}
