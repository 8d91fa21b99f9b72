//! A lower bound on the length of any flyable path between two points (m), to measure how far
//! [`super::Planner::shortest`] is from optimal.
//!
//! A building whose prism spans the whole altitude band (base at or below `env.z_min_m`, roof at
//! or above `env.z_max_m`) cannot be flown over or under: every flyable path, which stays in the
//! band, projects onto a horizontal path that avoids its footprint. So the length of the shortest
//! 2D path around those footprints (not inflated by the clearance, holes kept as free courtyards),
//! `L2D`, bounds the horizontal length of every flyable path, and the vertical difference `dz` of
//! the endpoints bounds its vertical length; by Minkowski's inequality (the length of a curve is
//! at least the norm of its summed horizontal and vertical variations) the path is at least
//! `sqrt(L2D² + dz²)` long. Buildings that leave part of the band open, and the flight area's edge,
//! are ignored: the bound stays valid, only less tight.
//!
//! `L2D` is computed exactly on the visibility graph of the source, the destination and the
//! footprint corners that are convex towards free space (a shortest path among polygons bends only
//! there), searched with A* (Euclidean heuristic) and line-of-sight tests done when a corner is
//! reached. Given an upper bound `U` on `L2D` (e.g. the horizontal length of a flyable path), only
//! corners and footprints inside the ellipse `|p − s| + |p − t| ≤ U` are considered: a 2D path no
//! longer than `U` cannot leave it. Segments touching a footprint's boundary (along an edge,
//! through a corner) count as clear, so the bound errs only towards being lower.

use dupac_common::geometry::Point;
use dupac_radio::city::{City, signed_area_m2};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Relative tolerance of the orientation tests (× the product of the two segments' lengths).
const ORIENT_EPS: f64 = 1e-12;
/// A point this close (m) to a footprint's boundary is on it, not inside.
const BOUNDARY_M: f64 = 1e-7;
/// Slack (m) added to the ellipse's major axis for rounding.
const ELLIPSE_SLACK_M: f64 = 1e-6;

/// One footprint that blocks the whole band: its rings (outer first, then holes) and bounds.
#[derive(Debug, Clone)]
struct Obstacle {
    /// Outer ring then the holes, each open (the last vertex is not a repeat of the first).
    rings: Vec<Vec<[f64; 2]>>,
    /// Axis-aligned bounds `[x_min, y_min, x_max, y_max]` (m).
    bbox: [f64; 4],
}

impl Obstacle {
    /// Whether `p` is inside the footprint and farther than [`BOUNDARY_M`] from its boundary.
    fn strictly_contains(&self, p: [f64; 2]) -> bool {
        if p[0] < self.bbox[0] || p[0] > self.bbox[2] || p[1] < self.bbox[1] || p[1] > self.bbox[3]
        {
            return false;
        }
        let inside = dupac_radio::city::point_in_ring(&self.rings[0], p[0], p[1])
            && !self.rings[1..]
                .iter()
                .any(|h| dupac_radio::city::point_in_ring(h, p[0], p[1]));
        inside
            && self.edges().all(|(a, b)| {
                let q = nearest_on_segment(a, b, p);
                norm([p[0] - q[0], p[1] - q[1]]) > BOUNDARY_M
            })
    }

    /// Every edge of every ring.
    fn edges(&self) -> impl Iterator<Item = ([f64; 2], [f64; 2])> + '_ {
        self.rings.iter().flat_map(|r| {
            let n = r.len();
            (0..n).map(move |i| (r[i], r[(i + 1) % n]))
        })
    }

    /// Whether the bounds overlap those of the segment `p → q`.
    fn bbox_meets(&self, p: [f64; 2], q: [f64; 2]) -> bool {
        p[0].max(q[0]) >= self.bbox[0]
            && p[0].min(q[0]) <= self.bbox[2]
            && p[1].max(q[1]) >= self.bbox[1]
            && p[1].min(q[1]) <= self.bbox[3]
    }

    /// Whether the open segment `p → q` enters the footprint's interior: it properly crosses an
    /// edge, or a piece of it between two boundary contacts lies strictly inside.
    fn blocks(&self, p: [f64; 2], q: [f64; 2]) -> bool {
        if !self.bbox_meets(p, q) {
            return false;
        }
        let pq = [q[0] - p[0], q[1] - p[1]];
        let len2 = pq[0] * pq[0] + pq[1] * pq[1];
        let len = len2.sqrt();
        if len == 0.0 {
            return false;
        }
        let mut contacts = vec![0.0, 1.0];
        for (a, b) in self.edges() {
            let eps = ORIENT_EPS * len * norm([b[0] - a[0], b[1] - a[1]]).max(1.0);
            let d1 = orient(p, q, a);
            let d2 = orient(p, q, b);
            let d3 = orient(a, b, p);
            let d4 = orient(a, b, q);
            let strict = |u: f64, v: f64| (u > eps && v < -eps) || (u < -eps && v > eps);
            if strict(d1, d2) && strict(d3, d4) {
                return true;
            }
            // Corners on the segment split it into pieces each wholly inside or outside.
            for (c, d) in [(a, d1), (b, d2)] {
                if d.abs() <= eps {
                    let f = ((c[0] - p[0]) * pq[0] + (c[1] - p[1]) * pq[1]) / len2;
                    if f > 0.0 && f < 1.0 {
                        contacts.push(f);
                    }
                }
            }
        }
        contacts.sort_by(f64::total_cmp);
        contacts.windows(2).any(|w| {
            (w[1] - w[0]) * len > 2.0 * BOUNDARY_M && {
                let f = 0.5 * (w[0] + w[1]);
                self.strictly_contains([p[0] + f * pq[0], p[1] + f * pq[1]])
            }
        })
    }
}

/// The footprints that block the whole altitude band of one city, and the lower bound they give.
#[derive(Debug, Clone)]
pub struct LowerBound {
    obstacles: Vec<Obstacle>,
    /// For each obstacle, its corners convex towards free space.
    corners: Vec<Vec<[f64; 2]>>,
}

impl LowerBound {
    /// Collects the buildings of `city` whose prism spans `band_m` = `[z_min, z_max]` (m): base
    /// ≤ `z_min` and roof ≥ `z_max`.
    pub fn new(city: &City, band_m: [f64; 2]) -> LowerBound {
        let mut obstacles = Vec::new();
        let mut corners = Vec::new();
        for b in &city.buildings {
            if !(b.z_min_m <= band_m[0] && b.z_max_m >= band_m[1]) || b.outer_m.len() < 3 {
                continue;
            }
            // Orient every ring with the obstacle on its left: the outer ring counter-clockwise,
            // the holes clockwise. A corner is then convex towards free space when it turns left.
            let mut rings = Vec::with_capacity(1 + b.holes_m.len());
            let mut outer = b.outer_m.clone();
            if signed_area_m2(&outer) < 0.0 {
                outer.reverse();
            }
            rings.push(outer);
            for h in b.holes_m.iter().filter(|h| h.len() >= 3) {
                let mut h = h.clone();
                if signed_area_m2(&h) > 0.0 {
                    h.reverse();
                }
                rings.push(h);
            }
            let mut convex = Vec::new();
            for r in &rings {
                let n = r.len();
                for i in 0..n {
                    let (a, c, d) = (r[(i + n - 1) % n], r[i], r[(i + 1) % n]);
                    if orient(a, c, d) > 0.0 {
                        convex.push(c);
                    }
                }
            }
            let bbox = b.outer_m.iter().fold(
                [
                    f64::INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::NEG_INFINITY,
                ],
                |m, p| {
                    [
                        m[0].min(p[0]),
                        m[1].min(p[1]),
                        m[2].max(p[0]),
                        m[3].max(p[1]),
                    ]
                },
            );
            obstacles.push(Obstacle { rings, bbox });
            corners.push(convex);
        }
        LowerBound { obstacles, corners }
    }

    /// Number of footprints that block the whole band.
    pub fn num_obstacles(&self) -> usize {
        self.obstacles.len()
    }

    /// The lower bound (m) on the length of any flyable path from `source_m` to `destination_m`:
    /// `sqrt(L2D² + dz²)` (module documentation). `upper_2d_m`: an upper bound on `L2D` (m), the
    /// horizontal length of any path that avoids the blocking footprints (e.g. a flyable one),
    /// which limits the search to its ellipse; `None` searches every footprint.
    pub fn lower_bound_m(
        &self,
        source_m: Point,
        destination_m: Point,
        upper_2d_m: Option<f64>,
    ) -> f64 {
        let l2d = self
            .horizontal_m(source_m, destination_m, upper_2d_m)
            .or_else(|| self.horizontal_m(source_m, destination_m, None))
            .unwrap_or_else(|| {
                norm([
                    destination_m[0] - source_m[0],
                    destination_m[1] - source_m[1],
                ])
            });
        let dz = destination_m[2] - source_m[2];
        (l2d * l2d + dz * dz).sqrt()
    }

    /// The shortest horizontal path (m) from `source_m` to `destination_m` around the blocking
    /// footprints, within the ellipse of `upper_2d_m` when given; `None` when there is none there.
    pub fn horizontal_m(
        &self,
        source_m: Point,
        destination_m: Point,
        upper_2d_m: Option<f64>,
    ) -> Option<f64> {
        let s = [source_m[0], source_m[1]];
        let t = [destination_m[0], destination_m[1]];
        let limit = upper_2d_m
            .filter(|u| u.is_finite())
            .map_or(f64::INFINITY, |u| u + ELLIPSE_SLACK_M);
        let in_ellipse = |p: [f64; 2]| norm(sub(p, s)) + norm(sub(p, t)) <= limit;
        // Footprints that can meet a segment inside the ellipse: bounds within the ellipse's.
        let (cx, cy) = (0.5 * (s[0] + t[0]), 0.5 * (s[1] + t[1]));
        let half = 0.5 * limit;
        let near: Vec<usize> = (0..self.obstacles.len())
            .filter(|&k| {
                let b = self.obstacles[k].bbox;
                !limit.is_finite()
                    || (b[0] <= cx + half
                        && b[2] >= cx - half
                        && b[1] <= cy + half
                        && b[3] >= cy - half)
            })
            .collect();
        let clear =
            |p: [f64; 2], q: [f64; 2]| near.iter().all(|&k| !self.obstacles[k].blocks(p, q));
        if clear(s, t) {
            return Some(norm(sub(t, s)));
        }
        // Nodes: 0 = source, 1 = destination, then the convex corners in the ellipse.
        let mut nodes = vec![s, t];
        for &k in &near {
            nodes.extend(self.corners[k].iter().copied().filter(|&c| in_ellipse(c)));
        }
        let n = nodes.len();
        let mut g = vec![f64::INFINITY; n];
        let mut closed = vec![false; n];
        let mut heap = BinaryHeap::new();
        g[0] = 0.0;
        heap.push(Entry {
            f: norm(sub(t, s)),
            node: 0,
        });
        while let Some(Entry { node: u, .. }) = heap.pop() {
            if closed[u] {
                continue;
            }
            closed[u] = true;
            if u == 1 {
                return Some(g[1]);
            }
            let pu = nodes[u];
            for v in 1..n {
                if closed[v] {
                    continue;
                }
                let pv = nodes[v];
                let gv = g[u] + norm(sub(pv, pu));
                let f = gv + norm(sub(t, pv));
                if gv < g[v] && f <= limit && clear(pu, pv) {
                    g[v] = gv;
                    heap.push(Entry { f, node: v });
                }
            }
        }
        None
    }
}

/// A* entry, a min-heap on `f`.
#[derive(Clone, Copy)]
struct Entry {
    f: f64,
    node: usize,
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        other
            .f
            .total_cmp(&self.f)
            .then_with(|| other.node.cmp(&self.node))
    }
}

/// Twice the signed area of the triangle `a, b, c` (m²): > 0 when `c` is left of `a → b`.
#[inline]
fn orient(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
}

#[inline]
fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

#[inline]
fn norm(v: [f64; 2]) -> f64 {
    v[0].hypot(v[1])
}

/// Nearest point of segment `a → b` to `p`.
fn nearest_on_segment(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> [f64; 2] {
    let ab = sub(b, a);
    let l2 = ab[0] * ab[0] + ab[1] * ab[1];
    if l2 <= 0.0 {
        return a;
    }
    let f = (((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / l2).clamp(0.0, 1.0);
    [a[0] + f * ab[0], a[1] + f * ab[1]]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::tests::{boxb, city};

    const BAND: [f64; 2] = [20.0, 120.0];

    /// Length (m) of the polyline through `pts` (2D).
    fn polyline(pts: &[[f64; 2]]) -> f64 {
        pts.windows(2).map(|w| norm(sub(w[1], w[0]))).sum()
    }

    #[test]
    fn a_clear_line_is_the_straight_distance() {
        let c = city(vec![boxb("tower", 40.0, 40.0, 60.0, 60.0, 0.0, 200.0)]);
        let lb = LowerBound::new(&c, BAND);
        assert_eq!(lb.num_obstacles(), 1);
        let (s, t) = (Point::new(-50.0, 0.0, 30.0), Point::new(50.0, 0.0, 90.0));
        let want = (100f64.powi(2) + 60f64.powi(2)).sqrt();
        assert!((lb.lower_bound_m(s, t, None) - want).abs() < 1e-9);
    }

    #[test]
    fn a_tall_box_between_the_endpoints_gives_the_exact_detour() {
        // A 20 m × 40 m tower above the band, centred off the line: the shortest way passes its
        // two corners nearer the line (y = −10), s → (−10, −10) → (10, −10) → t.
        let c = city(vec![boxb("tower", -10.0, -10.0, 10.0, 30.0, 0.0, 200.0)]);
        let lb = LowerBound::new(&c, BAND);
        let (s, t) = (Point::new(-50.0, 0.0, 40.0), Point::new(50.0, 0.0, 70.0));
        let l2d = polyline(&[[-50.0, 0.0], [-10.0, -10.0], [10.0, -10.0], [50.0, 0.0]]);
        let got = lb.horizontal_m(s, t, None).expect("a way around");
        assert!((got - l2d).abs() < 1e-9, "{got} vs {l2d}");
        let want = (l2d * l2d + 30.0 * 30.0).sqrt();
        assert!((lb.lower_bound_m(s, t, None) - want).abs() < 1e-9);
        // The ellipse of a flyable path's horizontal length gives the same; one too short to hold
        // any way around falls back to the whole city.
        assert!((lb.lower_bound_m(s, t, Some(l2d + 5.0)) - want).abs() < 1e-9);
        assert!((lb.lower_bound_m(s, t, Some(101.0)) - want).abs() < 1e-9);
    }

    #[test]
    fn a_corner_on_the_line_does_not_let_it_through() {
        // The straight line passes exactly through a corner and then the tower's interior.
        let c = city(vec![boxb("tower", 0.0, 0.0, 20.0, 20.0, 0.0, 200.0)]);
        let lb = LowerBound::new(&c, BAND);
        let (s, t) = (Point::new(-30.0, -30.0, 50.0), Point::new(50.0, 50.0, 50.0));
        let want = polyline(&[[-30.0, -30.0], [20.0, 0.0], [50.0, 50.0]]);
        let got = lb.lower_bound_m(s, t, None);
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }

    #[test]
    fn buildings_that_leave_part_of_the_band_open_are_ignored() {
        // A low block (flown over) and a floating part (flown under) across the line.
        let mut floating = boxb("part", -5.0, -50.0, 5.0, 50.0, 30.0, 200.0);
        floating.id = "floating".into();
        let c = city(vec![
            boxb("low", -30.0, -50.0, -20.0, 50.0, 0.0, 119.0),
            floating,
        ]);
        let lb = LowerBound::new(&c, BAND);
        assert_eq!(lb.num_obstacles(), 0);
        let (s, t) = (Point::new(-50.0, 0.0, 50.0), Point::new(50.0, 0.0, 50.0));
        assert!((lb.lower_bound_m(s, t, None) - 100.0).abs() < 1e-9);
    }

    #[test]
    fn a_courtyard_is_free_and_its_walls_are_not() {
        // A tower with a courtyard: from inside it to outside there is no way (the walls span the
        // band); between two points of the courtyard, the line across it.
        let mut tower = boxb("court", -20.0, -20.0, 20.0, 20.0, 0.0, 200.0);
        tower.holes_m = vec![vec![
            [-10.0, -10.0],
            [-10.0, 10.0],
            [10.0, 10.0],
            [10.0, -10.0],
        ]];
        let c = city(vec![tower]);
        let lb = LowerBound::new(&c, BAND);
        let inside = Point::new(-5.0, -5.0, 50.0);
        assert!(
            lb.horizontal_m(inside, Point::new(5.0, 5.0, 50.0), None)
                .is_some()
        );
        assert!(
            lb.horizontal_m(inside, Point::new(50.0, 0.0, 50.0), None)
                .is_none()
        );
    }
}
