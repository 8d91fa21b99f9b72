//! The episode's planned path as a guide (docs/env.md "Path guide"): how far along
//! it the UAV is, the distance still to fly, and a look-ahead point on it, for the `path_guide`
//! observation and the `path` progress of Eq. (8).
//!
//! The UAV's place on the path is *tracked*: each step it is the point of the path nearest to
//! the UAV among those within `window_m` of arc length of the previous place. A nearest point
//! over the whole path would jump to a later leg across a building, and the distance to go
//! would drop by the path between, paying for path not flown; the window keeps the place moving
//! along the path, and a window at least as long as a step keeps up with a UAV that flies
//! beside it. While the place catches up with a UAV ahead of it (a corner cut), the distance to
//! go falls by at most one window per step. The distance to go is the distance to that place plus the
//! path beyond it: the path's remaining length on the path, 0 at the destination.

use dupac_common::geometry::{Point, Vector};

/// A polyline from the episode's source to its destination with its cumulative arc lengths (m).
#[derive(Debug, Clone, PartialEq)]
pub struct PathGuide {
    points_m: Vec<Point>,
    /// Arc length from the first point to each point (m); `arc_m[0] = 0`.
    arc_m: Vec<f64>,
}

/// Where a point stands against the path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuideFix {
    /// Arc length of the UAV's place on the path (m).
    pub s_m: f64,
    /// Distance to go (m): to that place plus the path beyond it.
    pub to_go_m: f64,
    /// Distance (3D, m) from the point to that place: how far off the path it flies, measured
    /// to the tracked place (so it includes the lag along the path while the place catches up
    /// with a UAV that cut a corner), not to the nearest point of the whole path.
    pub off_m: f64,
}

impl PathGuide {
    /// The guide along `points_m` (at least one point; the first is the source, the last the
    /// destination). `None` when empty or a coordinate is not finite.
    pub fn new(points_m: &[Point]) -> Option<PathGuide> {
        if points_m.is_empty()
            || points_m
                .iter()
                .any(|p| !p.coords.iter().all(|v| v.is_finite()))
        {
            return None;
        }
        let mut arc_m = Vec::with_capacity(points_m.len());
        let mut s = 0.0;
        arc_m.push(0.0);
        for w in points_m.windows(2) {
            s += (w[1] - w[0]).norm();
            arc_m.push(s);
        }
        Some(PathGuide {
            points_m: points_m.to_vec(),
            arc_m,
        })
    }

    /// The path's points (m), source first.
    pub fn points_m(&self) -> &[Point] {
        &self.points_m
    }

    /// The path's first and last points (m).
    pub fn ends_m(&self) -> (Point, Point) {
        (self.points_m[0], self.points_m[self.points_m.len() - 1])
    }

    /// The same path flown the other way.
    pub fn reversed(&self) -> PathGuide {
        let mut points_m = self.points_m.clone();
        points_m.reverse();
        PathGuide::new(&points_m).unwrap_or_else(|| self.clone())
    }

    /// Path length (m).
    pub fn length_m(&self) -> f64 {
        self.arc_m.last().copied().unwrap_or(0.0)
    }

    /// The point at arc length `s_m` (clamped to the path).
    pub fn point_at(&self, s_m: f64) -> Point {
        let n = self.points_m.len();
        if n == 1 || s_m <= 0.0 {
            return self.points_m[0];
        }
        if s_m >= self.length_m() {
            return self.points_m[n - 1];
        }
        let i = self.arc_m.partition_point(|a| *a <= s_m).clamp(1, n - 1);
        let (a, b) = (self.points_m[i - 1], self.points_m[i]);
        let len = self.arc_m[i] - self.arc_m[i - 1];
        if len <= 0.0 {
            return b;
        }
        a + (b - a) * ((s_m - self.arc_m[i - 1]) / len)
    }

    /// Where `p_m` stands, its place sought within `window_m` (m) of arc length of `from_s_m`.
    pub fn fix(&self, p_m: Point, from_s_m: f64, window_m: f64) -> GuideFix {
        let total = self.length_m();
        let (lo, hi) = (from_s_m - window_m.max(0.0), from_s_m + window_m.max(0.0));
        if self.points_m.len() == 1 {
            let d = (p_m - self.points_m[0]).norm();
            return GuideFix {
                s_m: 0.0,
                to_go_m: d,
                off_m: d,
            };
        }
        // (distance to the path, arc length) of the nearest point within the window.
        let mut nearest = (f64::INFINITY, 0.0);
        for (i, w) in self.points_m.windows(2).enumerate() {
            let (s0, s1) = (self.arc_m[i], self.arc_m[i + 1]);
            if s1 < lo || s0 > hi {
                continue;
            }
            let len = s1 - s0;
            let (a, ab): (Point, Vector) = (w[0], w[1] - w[0]);
            let (t_lo, t_hi) = if len > 0.0 {
                (((lo - s0) / len).max(0.0), ((hi - s0) / len).min(1.0))
            } else {
                (0.0, 0.0)
            };
            let len2 = ab.norm_squared();
            let t = if len2 > 0.0 {
                ((p_m - a).dot(&ab) / len2).clamp(t_lo, t_hi)
            } else {
                0.0
            };
            let d = (p_m - (a + ab * t)).norm();
            if d < nearest.0 {
                nearest = (d, s0 + t * len);
            }
        }
        let mut best = GuideFix {
            s_m: nearest.1,
            to_go_m: nearest.0 + (total - nearest.1),
            off_m: nearest.0,
        };
        if best.to_go_m.is_infinite() {
            // The window is off the path (a start beyond it): the place clamped onto the path.
            let s_m = from_s_m.clamp(0.0, total);
            let off_m = (p_m - self.point_at(s_m)).norm();
            best = GuideFix {
                s_m,
                to_go_m: off_m + (total - s_m),
                off_m,
            };
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64) -> Point {
        Point::new(x, y, 50.0)
    }

    /// An L around a corner: (0,0) → (100,0) → (100,100); L = 200 m.
    fn ell() -> PathGuide {
        PathGuide::new(&[p(0.0, 0.0), p(100.0, 0.0), p(100.0, 100.0)]).unwrap()
    }

    /// Tracks `p_m` along the sweep `ps` from the start: the fixes.
    fn track(g: &PathGuide, ps: &[Point], window_m: f64) -> Vec<GuideFix> {
        let mut s = 0.0;
        ps.iter()
            .map(|p| {
                let f = g.fix(*p, s, window_m);
                s = f.s_m;
                f
            })
            .collect()
    }

    #[test]
    fn distance_to_go_is_the_path_beyond_the_tracked_place() {
        let g = ell();
        assert_eq!(g.length_m(), 200.0);
        assert!((g.fix(p(0.0, 0.0), 0.0, 10.0).to_go_m - 200.0).abs() < 1e-9);
        assert!((g.fix(p(100.0, 100.0), 200.0, 10.0).to_go_m).abs() < 1e-9);
        // 10 m off the first leg at x = 40: 10 + 160.
        let beside = g.fix(p(40.0, -10.0), 40.0, 10.0);
        assert!((beside.to_go_m - 170.0).abs() < 1e-9);
        assert!((beside.off_m - 10.0).abs() < 1e-9, "{beside:?}");
        // Inside the corner, near the second leg: a whole-path nearest point would say 80 m to
        // go (40 to the second leg, 40 beyond); tracked from the start it is still on the first.
        let f = g.fix(p(60.0, 60.0), 50.0, 10.0);
        assert!(
            (f.s_m - 60.0).abs() < 1e-9 && (f.to_go_m - 200.0).abs() < 1e-9,
            "{f:?}"
        );
    }

    #[test]
    fn the_tracked_place_follows_a_uav_flying_beside_the_path() {
        let g = ell();
        // 20 m outside the corner, 5 m per step: the place keeps up and ends at the end.
        let mut ps: Vec<Point> = (0..=24).map(|k| p(f64::from(k) * 5.0, -20.0)).collect();
        ps.extend((1..=24).map(|k| p(120.0, -20.0 + f64::from(k) * 5.0)));
        let fixes = track(&g, &ps, 10.0);
        let last = fixes.last().unwrap();
        assert!((last.s_m - 200.0).abs() < 1e-9, "{last:?}");
        assert!((last.to_go_m - 20.0).abs() < 1e-9, "{last:?}");
        for w in fixes.windows(2) {
            assert!(w[1].s_m >= w[0].s_m - 1e-9, "{w:?}");
            assert!((w[1].to_go_m - w[0].to_go_m).abs() <= 5.0 + 1e-9, "{w:?}");
        }
    }

    #[test]
    fn a_one_point_path_is_its_own_place() {
        let g = PathGuide::new(&[p(0.0, 0.0)]).unwrap();
        let f = g.fix(p(3.0, 4.0), 0.0, 10.0);
        assert!(
            (f.off_m - 5.0).abs() < 1e-9 && (f.to_go_m - 5.0).abs() < 1e-9,
            "{f:?}"
        );
    }

    #[test]
    fn hovering_beside_the_path_makes_no_progress() {
        let g = ell();
        // Started 40 m along, the place catches up in 4 windows, then stays.
        let hover = vec![p(40.0, -30.0); 20];
        let fixes = track(&g, &hover, 10.0);
        assert!(fixes[4..].iter().all(|f| *f == fixes[3]), "{fixes:?}");
        assert!(
            (fixes[3].to_go_m - (30.0 + 160.0)).abs() < 1e-9,
            "{:?}",
            fixes[3]
        );
    }

    #[test]
    fn the_point_at_an_arc_length_turns_the_corner_and_stops_at_the_destination() {
        let g = ell();
        assert!((g.point_at(120.0) - p(100.0, 20.0)).norm() < 1e-9);
        assert_eq!(g.point_at(250.0), p(100.0, 100.0));
        assert_eq!(g.point_at(-5.0), p(0.0, 0.0));
        let back = g.reversed();
        assert_eq!(back.ends_m(), (p(100.0, 100.0), p(0.0, 0.0)));
        assert!((back.point_at(20.0) - p(100.0, 80.0)).norm() < 1e-9);
    }

    #[test]
    fn empty_or_non_finite_paths_are_refused_and_one_point_works() {
        assert!(PathGuide::new(&[]).is_none());
        assert!(PathGuide::new(&[p(f64::NAN, 0.0)]).is_none());
        let g = PathGuide::new(&[p(3.0, 4.0)]).unwrap();
        let f = g.fix(p(0.0, 0.0), 0.0, 10.0);
        assert!((f.to_go_m - 5.0).abs() < 1e-12);
        assert_eq!(g.point_at(7.0), p(3.0, 4.0));
        // A window off the path still gives a finite answer.
        let f = ell().fix(p(0.0, 0.0), f64::NAN, 10.0);
        assert!(f.to_go_m.is_finite(), "{f:?}");
    }
}
