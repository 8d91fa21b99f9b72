//! The observation layout (spec/env.md "Observation", version [`OBS_VERSION`]): which field sits
//! at which index of the flat `f32` observation vector. The environment writes it, the learner
//! and every exported policy read it; nothing indexes observations by bare numbers.

use crate::config::ObservationConfig;
use std::ops::Range;

/// Version of the observation layout; bump on any change of order, scaling or meaning.
/// 2: the goal direction field (`goal_direction`) and the geofence in the sensors
/// (`geofence`). 3: the per-site features of the equivariant site head (`site_features`, last).
/// The optional `path_guide` field does not bump it: a layout without it is unchanged, and one
/// with it is 4 values longer and recorded in the policy (`env.observation.path_guide`); the same
/// holds for the optional `path_offset` and `handover_weight` fields
/// (`env.observation.path_offset`, `env.observation.handover_weight`).
pub const OBS_VERSION: u32 = 3;

/// Features per site in the `site_features` field, in this order (fixed physical scales, not
/// the running normaliser):
pub mod site_feature {
    /// (RSRP − rsrp_centre_dbm) / rsrp_scale_db, clipped to ±10.
    pub const RSRP: usize = 0;
    /// (RSRP − best RSRP here) / 10 dB, clipped to [−6, 0].
    pub const RSRP_MINUS_BEST: usize = 1;
    /// 1 for the serving site, else 0.
    pub const SERVING: usize = 2;
    /// ln(1 + d3D / 100 m).
    pub const LOG_DISTANCE: usize = 3;
    /// sin of the elevation of the site seen from the UAV ((z_site − z_uav) / d3D).
    pub const SIN_ELEVATION: usize = 4;
    /// cos, sin of the site's horizontal bearing relative to the UAV's heading (its last move;
    /// the goal direction before the first move).
    pub const COS_BEARING_HEADING: usize = 5;
    pub const SIN_BEARING_HEADING: usize = 6;
    /// cos, sin of the site's horizontal bearing relative to the direction to the destination.
    pub const COS_BEARING_GOAL: usize = 7;
    pub const SIN_BEARING_GOAL: usize = 8;
    /// 1 when the geometric line of sight to the site is clear.
    pub const LOS: usize = 9;
    /// With `env.observation.site_ping_pong` only, last: 1 for the site that serving at the next
    /// step would make a ping-pong (the site the last handover left, within
    /// `env.ping_pong_window_s`), else 0.
    pub fn ping_pong(cfg: &crate::config::ObservationConfig) -> Option<usize> {
        cfg.site_ping_pong.then_some(super::SITE_FEATURES)
    }

    /// With `env.observation.site_lookahead_m`, after the ping-pong flag: one value per distance
    /// ahead, the site's predicted RSRP minus the predicted best there (/ 10 dB, clipped to
    /// [−6, 0]).
    pub fn lookahead(cfg: &crate::config::ObservationConfig) -> std::ops::Range<usize> {
        let start = super::SITE_FEATURES + usize::from(cfg.site_ping_pong);
        start..start + cfg.site_lookahead_m.len()
    }

    /// With `env.observation.site_lookahead_stay`, after the look-ahead distances: how far ahead
    /// the site stays within `site_stay_within_db` of the predicted best (fraction of
    /// `env.predictive.horizon_m`, in [0, 1]).
    pub fn stay(cfg: &crate::config::ObservationConfig) -> Option<usize> {
        cfg.site_lookahead_stay.then_some(lookahead(cfg).end)
    }

    /// With `env.observation.site_predictive_choice`, last: 1 for the predictive association's
    /// choice, else 0.
    pub fn predictive_choice(cfg: &crate::config::ObservationConfig) -> Option<usize> {
        cfg.site_predictive_choice
            .then_some(lookahead(cfg).end + usize::from(cfg.site_lookahead_stay))
    }
}

/// Number of features per site in the `site_features` field without `site_ping_pong`.
pub const SITE_FEATURES: usize = 10;

/// Features per site in the `site_features` field under `cfg`.
pub fn site_features_per_site(cfg: &ObservationConfig) -> usize {
    SITE_FEATURES
        + usize::from(cfg.site_ping_pong)
        + cfg.site_lookahead_m.len()
        + usize::from(cfg.site_lookahead_stay)
        + usize::from(cfg.site_predictive_choice)
}

/// Directions of the obstacle-sensor fan: the 26 non-zero vectors of {−1, 0, 1}³ (unnormalised),
/// in lexicographic order of (x, y, z).
pub const SENSOR_DIRECTIONS: [[i8; 3]; 26] = {
    let mut out = [[0i8; 3]; 26];
    let mut k = 0;
    let mut x = -1;
    while x <= 1 {
        let mut y = -1;
        while y <= 1 {
            let mut z = -1;
            while z <= 1 {
                if !(x == 0 && y == 0 && z == 0) {
                    out[k] = [x as i8, y as i8, z as i8];
                    k += 1;
                }
                z += 1;
            }
            y += 1;
        }
        x += 1;
    }
    out
};

/// One named field of the observation.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObsField {
    pub name: &'static str,
    pub range: Range<usize>,
    /// Units and scaling, for documentation and exported policies.
    pub meaning: &'static str,
}

/// Field names (stable across versions as long as the field exists).
pub mod field {
    pub const POSITION: &str = "position";
    pub const VELOCITY: &str = "velocity";
    pub const GOAL_VECTOR: &str = "goal_vector";
    pub const GOAL_DISTANCE: &str = "goal_distance";
    pub const GOAL_DIRECTION: &str = "goal_direction";
    pub const PATH_GUIDE: &str = "path_guide";
    pub const PATH_OFFSET: &str = "path_offset";
    pub const HANDOVER_WEIGHT: &str = "handover_weight";
    pub const OBSTACLE_DISTANCE: &str = "obstacle_distance";
    pub const OBSTACLE_DIRECTION: &str = "obstacle_direction";
    pub const SENSOR_FAN: &str = "sensor_fan";
    pub const SERVING_ONE_HOT: &str = "serving_one_hot";
    pub const RSRP_ALL: &str = "rsrp_all";
    pub const RSRP_SERVING: &str = "rsrp_serving";
    pub const SITE_FEATURES: &str = "site_features";
}

/// The layout for a given observation configuration and number of sites M.
#[derive(Debug, Clone, PartialEq)]
pub struct ObsLayout {
    fields: Vec<ObsField>,
    len: usize,
    n_sites: usize,
}

impl ObsLayout {
    pub fn new(cfg: &ObservationConfig, n_sites: usize) -> ObsLayout {
        use field::*;
        let mut fields = Vec::new();
        let mut at = 0usize;
        let mut push = |name: &'static str, n: usize, meaning: &'static str| {
            fields.push(ObsField {
                name,
                range: at..at + n,
                meaning,
            });
            at += n;
        };
        push(
            POSITION,
            3,
            "x, y: position / half the area extent about its centre; z: (z − band centre) / half band",
        );
        push(VELOCITY, 3, "last displacement / max_step_m per axis");
        if cfg.goal {
            push(GOAL_VECTOR, 3, "(destination − position) / goal_scale_m");
            push(GOAL_DISTANCE, 1, "|destination − position| / goal_scale_m");
            if cfg.goal_direction {
                push(
                    GOAL_DIRECTION,
                    3,
                    "(destination − position) / |destination − position| (zeros at the destination)",
                );
            }
        }
        if cfg.path_guide {
            push(
                PATH_GUIDE,
                4,
                "unit direction to the point path_lookahead_m along the planned path beyond the UAV's tracked place on it (zeros at the destination), then the path distance to go / goal_scale_m",
            );
        }
        if cfg.path_guide && cfg.path_offset {
            push(
                PATH_OFFSET,
                3,
                "(the UAV's tracked place on the planned path − position) / PATH_OFFSET_SCALE_M (10 m), each clipped to ±3",
            );
        }
        if cfg.handover_weight {
            push(
                HANDOVER_WEIGHT,
                1,
                "ln(1 + w), the episode's handover weight w (env.reward.handover_weight)",
            );
        }
        push(
            OBSTACLE_DISTANCE,
            1,
            "c_t: nearest obstacle along the sensor fan, scaled by sensor_scale (1 = none in range)",
        );
        push(
            OBSTACLE_DIRECTION,
            3,
            "θ_t: unit direction of the nearest obstacle (zeros when none in range)",
        );
        if cfg.sensor_fan {
            push(
                SENSOR_FAN,
                SENSOR_DIRECTIONS.len(),
                "distance along each SENSOR_DIRECTIONS ray, scaled by sensor_scale (1 = free)",
            );
        }
        push(SERVING_ONE_HOT, n_sites, "one-hot of the serving GBS id");
        if cfg.rsrp_all {
            push(
                RSRP_ALL,
                n_sites,
                "RSRP of every site, (dBm − rsrp_centre_dbm) / rsrp_scale_db",
            );
        }
        if cfg.rsrp_serving {
            push(
                RSRP_SERVING,
                1,
                "serving RSRP, (dBm − rsrp_centre_dbm) / rsrp_scale_db",
            );
        }
        // Last, so the MLPs read the prefix and the site head the tail.
        if cfg.site_features {
            push(
                SITE_FEATURES,
                n_sites * site_features_per_site(cfg),
                "per site (site-major) the site_features_per_site values of obs::site_feature, fixed scales",
            );
        }
        ObsLayout {
            fields,
            len: at,
            n_sites,
        }
    }

    /// Length of the observation vector.
    pub fn len(&self) -> usize {
        self.len
    }

    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    pub fn n_sites(&self) -> usize {
        self.n_sites
    }

    /// All fields in order.
    pub fn fields(&self) -> &[ObsField] {
        &self.fields
    }

    /// Length of the prefix the actor and critic MLPs read: everything but `site_features`.
    pub fn trunk_len(&self) -> usize {
        self.range(field::SITE_FEATURES)
            .map(|r| r.start)
            .unwrap_or(self.len)
    }

    /// Index range of a field, `None` when it is switched off.
    pub fn range(&self, name: &str) -> Option<Range<usize>> {
        self.fields
            .iter()
            .find(|f| f.name == name)
            .map(|f| f.range.clone())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_layout_is_the_documented_one() {
        let l = ObsLayout::new(&ObservationConfig::default(), 30);
        // 3 + 3 + 3 + 1 + 3 + 4 + 1 + 3 + 26 + 30 + 30 + 1, then 30 × 11 site features (the
        // path guide and the ping-pong flag on by default)
        assert_eq!(l.len(), 108 + 330);
        assert_eq!(l.trunk_len(), 108);
        assert_eq!(l.range(field::SITE_FEATURES), Some(108..438));
        assert_eq!(l.range(field::POSITION), Some(0..3));
        assert_eq!(l.range(field::GOAL_DIRECTION), Some(10..13));
        assert_eq!(l.range(field::PATH_GUIDE), Some(13..17));
        assert_eq!(l.range(field::SENSOR_FAN), Some(21..47));
        assert_eq!(l.range(field::SERVING_ONE_HOT), Some(47..77));
        assert_eq!(l.range(field::RSRP_SERVING), Some(107..108));
        // Without the guide: the version-3 layout with no guide field.
        let unguided = ObservationConfig {
            path_guide: false,
            ..Default::default()
        };
        let u = ObsLayout::new(&unguided, 30);
        assert_eq!((u.len(), u.trunk_len()), (104 + 330, 104));
        assert_eq!(u.range(field::SENSOR_FAN), Some(17..43));
        // Fields tile the vector without gaps.
        let mut at = 0;
        for f in l.fields() {
            assert_eq!(f.range.start, at);
            at = f.range.end;
        }
        assert_eq!(at, l.len());
    }

    #[test]
    fn ablations_remove_fields() {
        let cfg = ObservationConfig {
            goal: false,
            sensor_fan: false,
            rsrp_all: false,
            rsrp_serving: false,
            site_features: false,
            path_guide: false,
            ..Default::default()
        };
        let l = ObsLayout::new(&cfg, 5);
        assert_eq!(l.len(), 3 + 3 + 1 + 3 + 5);
        assert_eq!(l.trunk_len(), l.len());
        assert_eq!(l.range(field::RSRP_ALL), None);
    }

    #[test]
    fn sensor_directions_are_the_26_neighbours() {
        let mut seen = std::collections::HashSet::new();
        for d in SENSOR_DIRECTIONS {
            assert_ne!(d, [0, 0, 0]);
            assert!(seen.insert(d));
        }
        assert_eq!(seen.len(), 26);
    }
}
