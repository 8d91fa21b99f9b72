//! Policy files of format 8: the observation recorded field by field, before the look-ahead
//! keys (`env.observation.site_lookahead_m` and the rest). Read and converted, so that the
//! policies trained before those keys (results/) still fly; the current format records the
//! observation as TOML text, which later keys with a default do not break
//! ([`super::PolicyWeights::observation`]).

use super::mlp::Mlp;
use super::{MOVE_DIM, PolicyWeights, SiteHead};
use crate::config::{NearestObstacle, ObservationConfig, SensorScale, SiteLos};
use crate::normalize::{ObsNormalizer, RewardScaler};
use serde::Deserialize;

/// [`PolicyWeights`] as format 8 wrote it.
#[derive(Deserialize)]
pub struct PolicyWeightsV8 {
    version: u64,
    obs_version: u32,
    obs_dim: usize,
    n_sites: usize,
    actor: Mlp,
    critic: Mlp,
    site_head: Option<SiteHead>,
    log_std: [f32; MOVE_DIM],
    obs_norm: ObsNormalizer,
    reward_scaler: RewardScaler,
    observation: Option<ObservationV8>,
}

/// `env.observation` as format 8 wrote it, field by field in its order.
#[derive(Deserialize)]
struct ObservationV8 {
    goal: bool,
    sensor_fan: bool,
    rsrp_all: bool,
    rsrp_serving: bool,
    sensor_range_m: f64,
    sensor_scale: SensorScale,
    nearest_obstacle: NearestObstacle,
    geofence: bool,
    goal_scale_m: f64,
    goal_direction: bool,
    rsrp_centre_dbm: f64,
    rsrp_scale_db: f64,
    site_features: bool,
    site_ping_pong: bool,
    path_guide: bool,
    path_lookahead_m: f64,
    path_guide_lambda: f64,
    path_guide_clearance_m: f64,
    handover_weight: bool,
    site_los: SiteLos,
}

impl From<ObservationV8> for ObservationConfig {
    /// The same observation; the keys format 8 did not have take their defaults (no
    /// look-ahead).
    fn from(o: ObservationV8) -> Self {
        ObservationConfig {
            goal: o.goal,
            sensor_fan: o.sensor_fan,
            rsrp_all: o.rsrp_all,
            rsrp_serving: o.rsrp_serving,
            sensor_range_m: o.sensor_range_m,
            sensor_scale: o.sensor_scale,
            nearest_obstacle: o.nearest_obstacle,
            geofence: o.geofence,
            goal_scale_m: o.goal_scale_m,
            goal_direction: o.goal_direction,
            rsrp_centre_dbm: o.rsrp_centre_dbm,
            rsrp_scale_db: o.rsrp_scale_db,
            site_features: o.site_features,
            site_ping_pong: o.site_ping_pong,
            path_guide: o.path_guide,
            path_lookahead_m: o.path_lookahead_m,
            path_guide_lambda: o.path_guide_lambda,
            path_guide_clearance_m: o.path_guide_clearance_m,
            handover_weight: o.handover_weight,
            site_los: o.site_los,
            ..ObservationConfig::default()
        }
    }
}

impl From<PolicyWeightsV8> for PolicyWeights {
    fn from(p: PolicyWeightsV8) -> Self {
        PolicyWeights {
            version: p.version,
            obs_version: p.obs_version,
            obs_dim: p.obs_dim,
            n_sites: p.n_sites,
            actor: p.actor,
            critic: p.critic,
            site_head: p.site_head,
            log_std: p.log_std,
            obs_norm: p.obs_norm,
            reward_scaler: p.reward_scaler,
            observation: p.observation.map(ObservationConfig::from),
        }
    }
}
