//! The budget of one GBS → UAV link: geometry, best-sector gain, path loss and RSRP
//! (spec/radio.md §1–§3, paper Eqs. (1)–(5)).

use crate::antenna::AntennaPattern;
use crate::class::{RsrpClass, RsrpThresholds};
use crate::pathloss::{PathLossModel, Scenario};
use dupac_common::config::RadioConfig;
use dupac_common::geometry::Point;
use serde::Serialize;

/// Everything about one link, as `dupac radio link` prints it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LinkBudget {
    /// 3D distance antenna ↔ UAV (m).
    pub d3d_m: f64,
    /// Horizontal distance (m).
    pub d2d_m: f64,
    /// Zenith angle at the GBS (deg; 0 above, 90 horizon, 180 below), spec D13.
    pub theta_deg: f64,
    /// Azimuth of the UAV seen from the GBS (deg, CCW from east, in (−180, 180]).
    pub phi_deg: f64,
    /// Index of the serving sector in the site's boresight list.
    pub best_sector: usize,
    /// Best-sector composite gain A_A (dBi), spec §2.
    pub gain_dbi: f64,
    /// Path loss L (dB), spec §1.
    pub pl_db: f64,
    /// RSRP = P + G − L (+ UE gain) (dBm), spec §3 D14.
    pub rsrp_dbm: f64,
    pub class: RsrpClass,
    pub los: bool,
}

/// The parts of the radio model shared by every link: path loss, classes, UE gain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkModel {
    pub pathloss: PathLossModel,
    pub thresholds: RsrpThresholds,
    /// UAV antenna gain (dBi), 0 in the paper.
    pub ue_gain_dbi: f64,
}

/// The transmitter side of a link: a site's antenna and deployment.
#[derive(Debug, Clone, Copy)]
pub struct Transmitter<'a> {
    /// Antenna position (m), z = antenna height above ground.
    pub position_m: Point,
    pub antenna: &'a AntennaPattern,
    pub boresights_deg: &'a [f64],
    pub scenario: Scenario,
    /// Reference-signal power per RE, P (dBm).
    pub tx_power_dbm: f64,
}

impl LinkModel {
    pub fn from_config(cfg: &RadioConfig) -> Self {
        LinkModel {
            pathloss: PathLossModel::from_config(cfg),
            thresholds: RsrpThresholds::from_config(cfg),
            ue_gain_dbi: cfg.ue_gain_dbi,
        }
    }

    /// The full budget of the link `tx → uav_m` with the given LoS state.
    pub fn evaluate(&self, tx: &Transmitter<'_>, uav_m: Point, los: bool) -> LinkBudget {
        let (d2d_m, d3d_m, theta_deg, phi_deg) = geometry(tx.position_m, uav_m);
        let phi_deg = crate::antenna::wrap_deg(phi_deg);
        let g = tx
            .antenna
            .site_gain_dbi(theta_deg, phi_deg, tx.boresights_deg);
        let pl_db = self
            .pathloss
            .path_loss_db(tx.scenario, los, d3d_m, uav_m[2]);
        let rsrp_dbm = tx.tx_power_dbm + g.gain_dbi + self.ue_gain_dbi - pl_db;
        LinkBudget {
            d3d_m,
            d2d_m,
            theta_deg,
            phi_deg,
            best_sector: g.sector,
            gain_dbi: g.gain_dbi,
            pl_db,
            rsrp_dbm,
            class: self.thresholds.classify(rsrp_dbm),
            los,
        }
    }

    /// RSRP only (dBm): the hot path of coverage maps and the cache.
    #[inline]
    pub fn rsrp_dbm(&self, tx: &Transmitter<'_>, uav_m: Point, los: bool) -> f64 {
        let (_, d3d_m, theta_deg, phi_deg) = geometry(tx.position_m, uav_m);
        let g = tx
            .antenna
            .site_gain_dbi(theta_deg, phi_deg, tx.boresights_deg);
        tx.tx_power_dbm + g.gain_dbi + self.ue_gain_dbi
            - self
                .pathloss
                .path_loss_db(tx.scenario, los, d3d_m, uav_m[2])
    }
}

/// Link geometry (spec/radio.md §2): `(d2D m, d3D m, θ deg zenith at the GBS, φ deg CCW from
/// east, unwrapped)`.
#[inline(always)]
fn geometry(bs_m: Point, uav_m: Point) -> (f64, f64, f64, f64) {
    let dx = uav_m[0] - bs_m[0];
    let dy = uav_m[1] - bs_m[1];
    let dz = uav_m[2] - bs_m[2];
    let d2d_m = dx.hypot(dy);
    let d3d_m = d2d_m.hypot(dz);
    (
        d2d_m,
        d3d_m,
        d2d_m.atan2(dz).to_degrees(),
        dy.atan2(dx).to_degrees(),
    )
}
