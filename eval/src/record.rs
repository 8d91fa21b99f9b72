//! A flight as evaluation keeps it (spec/env.md "Metrics"): each step's record
//! ([`StepRecord`], from the environment's [`StepInfo`] and the SINR evaluation computes) and the
//! whole flight ([`FlightRecord`]): what records files hold and every metric is computed from.

use dupac_actor::record::StepInfo;
use dupac_common::geometry::Point;
use dupac_common::msg::Outcome;
use dupac_radio::class::RsrpClass;
use serde::{Deserialize, Serialize};

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
    /// SINR of the serving site against all others ([`crate::sinr::sinr_db`]).
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

#[cfg(test)]
mod tests {
    use super::*;
    use dupac_common::ids::SiteId;

    /// A step's record keeps the true and the measured serving RSRP apart (metrics score the
    /// true one), as f32.
    #[test]
    fn a_step_record_keeps_the_true_and_the_measured_rsrp() {
        let info = StepInfo {
            step: 1,
            position_m: Point::new(1.0, 2.0, 50.0),
            serving: SiteId(3),
            serving_rsrp_dbm: -81.25,
            measured_serving_rsrp_dbm: -78.5,
            best_site: SiteId(4),
            best_rsrp_dbm: -75.0,
            class: RsrpClass::Mediocre,
            best_class: RsrpClass::Excellent,
            los: true,
            handover: true,
            ping_pong: false,
            step_length_m: 1.0,
            distance_flown_m: 1.0,
            distance_to_goal_m: 99.0,
            reward: 0.5,
            outcome: None,
        };
        let r = StepRecord::from_info(&info, 4.5);
        assert_eq!(r.serving_rsrp_dbm, -81.25);
        assert_eq!(r.measured_serving_rsrp_dbm, -78.5);
        assert_eq!((r.serving, r.best_site, r.sinr_db), (3, 4, 4.5));
        assert_eq!(r.position_m, [1.0, 2.0, 50.0]);
        assert!(r.handover && !r.ping_pong && r.los);
    }
}
