//! The observation (spec/env.md "Observation", docs/env.md): the sensor fan with the nearest
//! surface (the area edge sensed as a wall), the goal direction, the radio block and the
//! per-site features the equivariant site head reads, written once per decision.

use super::{Env, RSRP_FLOOR_DBM, argmax};
use dupac_common::config::{NearestObstacle, PATH_OFFSET_SCALE_M, SiteLos};
use dupac_common::geometry::{Bounds2, Point, Vector};
use dupac_common::ids::SiteId;
use dupac_common::obs::{ObsLayout, field, site_feature, site_features_per_site};
use std::ops::Range;

/// Observation slices resolved once from the layout.
#[derive(Debug, Clone)]
pub(super) struct Slots {
    position: Range<usize>,
    velocity: Range<usize>,
    goal_vector: Option<Range<usize>>,
    goal_distance: Option<Range<usize>>,
    goal_direction: Option<Range<usize>>,
    path_guide: Option<Range<usize>>,
    path_offset: Option<Range<usize>>,
    handover_weight: Option<Range<usize>>,
    obstacle_distance: Range<usize>,
    obstacle_direction: Range<usize>,
    sensor_fan: Option<Range<usize>>,
    serving_one_hot: Range<usize>,
    rsrp_all: Option<Range<usize>>,
    rsrp_serving: Option<Range<usize>>,
    pub(super) site_features: Option<Range<usize>>,
}

impl Slots {
    /// The slices of `layout` (an absent required field: an empty range).
    pub(super) fn new(layout: &ObsLayout) -> Slots {
        let req = |name: &str| layout.range(name).unwrap_or(0..0);
        Slots {
            position: req(field::POSITION),
            velocity: req(field::VELOCITY),
            goal_vector: layout.range(field::GOAL_VECTOR),
            goal_distance: layout.range(field::GOAL_DISTANCE),
            goal_direction: layout.range(field::GOAL_DIRECTION),
            path_guide: layout.range(field::PATH_GUIDE),
            path_offset: layout.range(field::PATH_OFFSET),
            handover_weight: layout.range(field::HANDOVER_WEIGHT),
            obstacle_distance: req(field::OBSTACLE_DISTANCE),
            obstacle_direction: req(field::OBSTACLE_DIRECTION),
            sensor_fan: layout.range(field::SENSOR_FAN),
            serving_one_hot: req(field::SERVING_ONE_HOT),
            rsrp_all: layout.range(field::RSRP_ALL),
            rsrp_serving: layout.range(field::RSRP_SERVING),
            site_features: layout.range(field::SITE_FEATURES),
        }
    }
}

impl Env {
    /// Nearest obstacle along the sensor fan: writes normalised distances into `fan` and returns
    /// (c_t normalised, index of the nearest ray or `None`).
    pub(super) fn sense(&self, fan: &mut [f32; 26]) -> (f32, Option<usize>) {
        let range = self.cfg.observation.sensor_range_m;
        let scale = self.cfg.observation.sensor_scale;
        let fence = self.cfg.observation.geofence;
        let mut best = (1.0f32, None);
        for (i, d) in self.sensor_dirs.iter().enumerate() {
            let mut hit = self
                .world
                .city
                .mesh
                .ray_distance_m(self.position_m, *d, range);
            if fence {
                let edge = area_exit_m(self.world.city.area_m, self.position_m, *d);
                if edge <= range && hit.is_none_or(|t| edge < t) {
                    hit = Some(edge);
                }
            }
            let v = match hit {
                Some(t) => scale.scale(t, range) as f32,
                None => 1.0,
            };
            fan[i] = v;
            if v < best.0 {
                best = (v, Some(i));
            }
        }
        best
    }

    pub(super) fn write_observation(&mut self) {
        let s = self.slots.clone();
        let o = &self.cfg.observation;
        let a = self.world.city.area_m;
        let (cx, cy) = (0.5 * (a.min_m.x + a.max_m.x), 0.5 * (a.min_m.y + a.max_m.y));
        let (hx, hy) = (0.5 * (a.max_m.x - a.min_m.x), 0.5 * (a.max_m.y - a.min_m.y));
        let zc = 0.5 * (self.cfg.z_min_m + self.cfg.z_max_m);
        let hz = 0.5 * (self.cfg.z_max_m - self.cfg.z_min_m);
        let p = self.position_m;
        let pos = [(p[0] - cx) / hx, (p[1] - cy) / hy, (p[2] - zc) / hz];
        let mut fan = [1.0f32; 26];
        let (mut c_t, nearest) = self.sense(&mut fan);
        let mut dir = nearest
            .map(|i| self.sensor_dirs[i])
            .unwrap_or(Vector::zeros());
        if o.nearest_obstacle == NearestObstacle::Exact {
            let range = o.sensor_range_m;
            let mut nearest = self.world.city.mesh.nearest_surface_m(p, range);
            if o.geofence {
                let (d, u) = nearest_edge_m(a, p);
                if d <= range && nearest.is_none_or(|(t, _)| d < t) {
                    nearest = Some((d, u));
                }
            }
            (c_t, dir) = match nearest {
                Some((d, u)) => (o.sensor_scale.scale(d, range) as f32, u),
                None => (1.0, Vector::zeros()),
            };
        }
        let rsrp_norm = |v: f64| {
            let x = (v - o.rsrp_centre_dbm) / o.rsrp_scale_db;
            // −∞ (a site that cannot be measured) and extreme nulls are clipped.
            x.clamp(-10.0, 10.0) as f32
        };
        let obs = &mut self.obs;
        for (k, v) in pos.iter().enumerate() {
            obs[s.position.start + k] = *v as f32;
        }
        for k in 0..3 {
            obs[s.velocity.start + k] = self.velocity_per_max_step[k] as f32;
        }
        if let (Some(gv), Some(gd), Some(ep)) = (&s.goal_vector, &s.goal_distance, &self.episode) {
            for k in 0..3 {
                obs[gv.start + k] = ((ep.destination_m[k] - p[k]) / o.goal_scale_m) as f32;
            }
            obs[gd.start] = (self.distance_to_goal_m / o.goal_scale_m) as f32;
            if let Some(u) = &s.goal_direction {
                let d = self.distance_to_goal_m;
                for k in 0..3 {
                    let v = if d > 1e-9 {
                        (ep.destination_m[k] - p[k]) / d
                    } else {
                        0.0
                    };
                    obs[u.start + k] = v as f32;
                }
            }
        }
        if let (Some(r), Some(g)) = (
            &s.path_guide,
            self.episode.as_ref().and_then(|e| e.guide.as_ref()),
        ) {
            let to = g.point_at(self.path_s_m + o.path_lookahead_m) - p;
            let n = to.norm();
            for k in 0..3 {
                obs[r.start + k] = if n > 1e-9 { (to[k] / n) as f32 } else { 0.0 };
            }
            obs[r.start + 3] = (self.path_to_go_m / o.goal_scale_m) as f32;
            if let Some(r) = &s.path_offset {
                let off = g.point_at(self.path_s_m) - p;
                for k in 0..3 {
                    obs[r.start + k] = (off[k] / PATH_OFFSET_SCALE_M).clamp(-3.0, 3.0) as f32;
                }
            }
        }
        if let Some(r) = &s.handover_weight {
            obs[r.start] = self.handover_weight.ln_1p() as f32;
        }
        obs[s.obstacle_distance.start] = c_t;
        for k in 0..3 {
            obs[s.obstacle_direction.start + k] = dir[k] as f32;
        }
        if let Some(f) = &s.sensor_fan {
            obs[f.clone()].copy_from_slice(&fan);
        }
        obs[s.serving_one_hot.clone()].fill(0.0);
        obs[s.serving_one_hot.start + self.serving.index()] = 1.0;
        if let Some(r) = &s.rsrp_all {
            for (i, v) in self.measured_dbm.iter().enumerate() {
                obs[r.start + i] = rsrp_norm(*v);
            }
        }
        if let Some(r) = &s.rsrp_serving {
            obs[r.start] = rsrp_norm(self.measured_dbm[self.serving.index()]);
        }
        if let Some(r) = &s.site_features {
            let mut obs = std::mem::take(&mut self.obs);
            if self.site_rewards.is_empty() {
                // Not a learned association: nothing reads them.
                obs[r.clone()].fill(0.0);
            } else {
                self.site_features_into(&mut obs[r.clone()]);
            }
            self.obs = obs;
        }
    }

    /// The `site_features` field (obs::site_feature) at the current state into `out`
    /// (`M × features`, site-major): each site's own features on fixed physical scales, for the
    /// equivariant site head.
    pub(super) fn site_features_into(&self, out: &mut [f32]) {
        let o = &self.cfg.observation;
        let p = self.position_m;
        let best = self.measured_dbm[argmax(&self.measured_dbm).index()].max(RSRP_FLOOR_DBM);
        let unit2 = |x: f64, y: f64| {
            let n = x.hypot(y);
            (n > 1e-9).then(|| [x / n, y / n])
        };
        let goal = self
            .episode
            .as_ref()
            .and_then(|e| unit2(e.destination_m[0] - p[0], e.destination_m[1] - p[1]));
        let heading = unit2(self.velocity_per_max_step[0], self.velocity_per_max_step[1])
            .or(goal)
            .unwrap_or([1.0, 0.0]);
        let goal = goal.unwrap_or(heading);
        let serving = self.serving.index();
        let per_site = site_features_per_site(o);
        let ping_pong_at = site_feature::ping_pong(o);
        let lookahead_at = site_feature::lookahead(o);
        let stay_at = site_feature::stay(o);
        let choice = site_feature::predictive_choice(o).map(|i| {
            let cost = o.site_prediction.handover_cost_db_m * self.handover_weight;
            (i, self.ahead.choice(self.serving, cost).index())
        });
        // The predicted RSRP of every site, and the predicted best, at each look-ahead distance.
        let n_sites = self.world.sites.len();
        let mut ahead_dbm = vec![f64::NEG_INFINITY; n_sites * o.site_lookahead_m.len()];
        let mut ahead_best = vec![RSRP_FLOOR_DBM; o.site_lookahead_m.len()];
        for ((row, best), &d) in ahead_dbm
            .chunks_mut(n_sites.max(1))
            .zip(&mut ahead_best)
            .zip(&o.site_lookahead_m)
        {
            self.ahead.at(d, row);
            *best = row.iter().copied().fold(RSRP_FLOOR_DBM, f64::max);
        }
        let mut los = vec![0.0; self.world.sites.len()];
        if o.site_los == SiteLos::Ray || !self.rsrp.los_all(p, &mut los) {
            for (k, l) in los.iter_mut().enumerate() {
                *l = f64::from(u8::from(self.world.los(SiteId(k as u16), p)));
            }
        }
        for (k, site) in self.world.sites.iter().enumerate() {
            let f = &mut out[k * per_site..][..per_site];
            let w = self.measured_dbm[k].max(RSRP_FLOOR_DBM);
            let q = site.position_m;
            let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
            let d3d = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-3);
            let u = unit2(d[0], d[1]).unwrap_or(heading);
            let rel = |h: [f64; 2]| (h[0] * u[0] + h[1] * u[1], h[0] * u[1] - h[1] * u[0]);
            let (ch, sh) = rel(heading);
            let (cg, sg) = rel(goal);
            use site_feature::*;
            f[RSRP] = ((w - o.rsrp_centre_dbm) / o.rsrp_scale_db).clamp(-10.0, 10.0) as f32;
            f[RSRP_MINUS_BEST] = ((w - best) / 10.0).clamp(-6.0, 0.0) as f32;
            f[SERVING] = f32::from(u8::from(k == serving));
            f[LOG_DISTANCE] = (d3d / 100.0).ln_1p() as f32;
            f[SIN_ELEVATION] = (d[2] / d3d) as f32;
            f[COS_BEARING_HEADING] = ch as f32;
            f[SIN_BEARING_HEADING] = sh as f32;
            f[COS_BEARING_GOAL] = cg as f32;
            f[SIN_BEARING_GOAL] = sg as f32;
            f[LOS] = los[k] as f32;
            if let Some(i) = ping_pong_at {
                // Serving k at the next step (step + 1) would be a ping-pong.
                let pp = self
                    .handovers
                    .would_ping_pong(serving as u16, k as u16, self.step + 1);
                f[i] = f32::from(u8::from(pp));
            }
            for (j, i) in lookahead_at.clone().enumerate() {
                let v = ahead_dbm[j * n_sites + k].max(RSRP_FLOOR_DBM);
                f[i] = ((v - ahead_best[j]) / 10.0).clamp(-6.0, 0.0) as f32;
            }
            if let Some(i) = stay_at {
                let h = o.site_prediction.horizon_m;
                f[i] = (self.ahead.stay_m(k, o.site_stay_within_db) / h).clamp(0.0, 1.0) as f32;
            }
            if let Some((i, c)) = choice {
                f[i] = f32::from(u8::from(k == c));
            }
        }
    }
}

/// Distance (m) from `p` along the unit direction `d` to the lateral edge of the flight area
/// `area` (∞ for a vertical ray); 0 outside the area.
fn area_exit_m(area: Bounds2, p: Point, d: Vector) -> f64 {
    let mut t = f64::INFINITY;
    for (k, (lo, hi)) in [(area.min_m.x, area.max_m.x), (area.min_m.y, area.max_m.y)]
        .into_iter()
        .enumerate()
    {
        if d[k] > 0.0 {
            t = t.min((hi - p[k]) / d[k]);
        } else if d[k] < 0.0 {
            t = t.min((lo - p[k]) / d[k]);
        }
    }
    t.max(0.0)
}

/// The nearest point of the flight area's lateral edge: its distance (m, 0 outside) and the unit
/// horizontal direction towards it.
fn nearest_edge_m(area: Bounds2, p: Point) -> (f64, Vector) {
    [
        // Written out (not `-Vector::x()`): a negated unit vector has −0.0 components, and the
        // observation keeps the +0.0 it always had.
        (p[0] - area.min_m.x, Vector::new(-1.0, 0.0, 0.0)),
        (area.max_m.x - p[0], Vector::new(1.0, 0.0, 0.0)),
        (p[1] - area.min_m.y, Vector::new(0.0, -1.0, 0.0)),
        (area.max_m.y - p[1], Vector::new(0.0, 1.0, 0.0)),
    ]
    .into_iter()
    .map(|(d, u)| (d.max(0.0), u))
    .fold((f64::INFINITY, Vector::zeros()), |b, e| {
        if e.0 < b.0 { e } else { b }
    })
}
