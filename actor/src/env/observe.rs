//! The observation (spec/env.md "Observation", docs/env.md): the state it is computed from, as
//! the compact trajectory carries it ([`TrunkRow`], [`StateRow`]): the sensor fan with the
//! nearest surface (the area edge sensed as a wall), the goal, the planned path, every site's
//! measured RSRP and line of sight and the look-ahead's predictions; the observation and the
//! site features are its expansion ([`crate::expand::Expander`]).

use super::{Env, RSRP_FLOOR_DBM};
use dupac_common::compact::{StateRow, TrunkRow, code};
use dupac_common::config::{NearestObstacle, PATH_OFFSET_SCALE_M, SiteLos};
use dupac_common::geometry::{Bounds2, Point, Vector};
use dupac_common::ids::SiteId;

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

    /// The trunk's own quantities at the current state.
    fn trunk_row(&self) -> TrunkRow {
        let o = &self.cfg.observation;
        let p = self.position_m;
        let mut fan = [1.0f32; 26];
        let (mut c_t, nearest) = self.sense(&mut fan);
        let mut dir = nearest
            .map(|i| self.sensor_dirs[i])
            .unwrap_or(Vector::zeros());
        if o.nearest_obstacle == NearestObstacle::Exact {
            let range = o.sensor_range_m;
            let mut nearest = self.world.city.mesh.nearest_surface_m(p, range);
            if o.geofence {
                let (d, u) = nearest_edge_m(self.world.city.area_m, p);
                if d <= range && nearest.is_none_or(|(t, _)| d < t) {
                    nearest = Some((d, u));
                }
            }
            (c_t, dir) = match nearest {
                Some((d, u)) => (o.sensor_scale.scale(d, range) as f32, u),
                None => (1.0, Vector::zeros()),
            };
        }
        let mut r = TrunkRow {
            handover_weight: self.handover_weight as f32,
            velocity_z: code::signed(self.velocity_per_max_step[2]),
            obstacle_distance: code::unit(f64::from(c_t)),
            obstacle_direction: [0, 1, 2].map(|k| code::signed(dir[k])),
            sensor_fan: fan.map(|v| code::unit(f64::from(v))),
            path_direction: [code::signed(0.0); 3],
            ..TrunkRow::default()
        };
        let Some(ep) = &self.episode else {
            return r;
        };
        r.destination_m = [0, 1, 2].map(|k| ep.destination_m[k] as f32);
        if let Some(g) = &ep.guide {
            let to = g.point_at(self.path_s_m + o.path_lookahead_m) - p;
            let n = to.norm();
            r.path_direction =
                [0, 1, 2].map(|k| code::signed(if n > 1e-9 { to[k] / n } else { 0.0 }));
            r.path_to_go = (self.path_to_go_m / o.goal_scale_m) as f32;
            let off = g.point_at(self.path_s_m) - p;
            r.path_offset =
                [0, 1, 2].map(|k| (off[k] / PATH_OFFSET_SCALE_M).clamp(-3.0, 3.0) as f32);
        }
        r
    }

    /// The state at the current step: the UAV's place and heading, the serving and ping-pong
    /// sites, every site's measured RSRP and, with `full` (the site features will be read), its
    /// line of sight and the look-ahead's predictions.
    pub(super) fn state_row(&self, full: bool) -> StateRow {
        let o = &self.cfg.observation;
        let p = self.position_m;
        let m = self.world.sites.len();
        let serving = self.serving.index();
        let v = self.velocity_per_max_step;
        let ping_pong = (0..m)
            .find(|&k| {
                self.handovers
                    .would_ping_pong(serving as u16, k as u16, self.step + 1)
            })
            .unwrap_or(m);
        let mut s = StateRow {
            position_m: [0, 1, 2].map(|k| p[k] as f32),
            velocity_xy: [code::signed(v[0]), code::signed(v[1])],
            serving: serving as u16,
            ping_pong: ping_pong as u16,
            rsrp: self.measured_dbm.iter().map(|&d| code::rsrp(d)).collect(),
            los: vec![0; m.div_ceil(8)],
            lookahead: vec![
                0;
                if self.learned {
                    m * o.site_lookahead_m.len()
                } else {
                    0
                }
            ],
            stay: vec![
                0;
                if self.learned && o.site_lookahead_stay {
                    m
                } else {
                    0
                }
            ],
            choice: m as u16,
        };
        if !full {
            return s;
        }
        let mut los = vec![0.0; m];
        if o.site_los == SiteLos::Ray || !self.rsrp.los_all(p, &mut los) {
            for (k, l) in los.iter_mut().enumerate() {
                *l = f64::from(u8::from(self.world.los(SiteId(k as u16), p)));
            }
        }
        for (k, l) in los.iter().enumerate() {
            if *l > 0.5 {
                s.los[k / 8] |= 1 << (k % 8);
            }
        }
        // The predicted RSRP of every site, and the predicted best, at each look-ahead distance.
        let n_ahead = o.site_lookahead_m.len();
        let mut row = vec![f64::NEG_INFINITY; m];
        for (j, &d) in o.site_lookahead_m.iter().enumerate() {
            self.ahead.at(d, &mut row);
            let best = row.iter().copied().fold(RSRP_FLOOR_DBM, f64::max);
            for (k, v) in row.iter().enumerate() {
                let rel = ((v.max(RSRP_FLOOR_DBM) - best) / 10.0).clamp(-6.0, 0.0);
                s.lookahead[k * n_ahead + j] = code::byte(-rel / 6.0);
            }
        }
        if o.site_lookahead_stay {
            let h = o.site_prediction.horizon_m;
            for k in 0..m {
                s.stay[k] = code::byte(self.ahead.stay_m(k, o.site_stay_within_db) / h);
            }
        }
        if o.site_predictive_choice {
            let cost = o.site_prediction.handover_cost_db_m * self.handover_weight;
            s.choice = self.ahead.choice(self.serving, cost).0;
        }
        s
    }

    /// Writes the observation: the expansion of the current state's rows, kept for the compact
    /// trajectory ([`Env::observed_rows`]).
    pub(super) fn write_observation(&mut self) {
        self.obs_trunk = self.trunk_row();
        self.obs_state = self.state_row(self.learned);
        let mut obs = std::mem::take(&mut self.obs);
        self.expander
            .observation(&self.obs_trunk, &self.obs_state, &mut obs);
        self.obs = obs;
    }

    /// The rows the current observation is the expansion of.
    pub fn observed_rows(&self) -> (&TrunkRow, &StateRow) {
        (&self.obs_trunk, &self.obs_state)
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
