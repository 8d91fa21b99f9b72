//! A building (or building part) as plain data: a 2D footprint extruded vertically.

use dupac_common::geometry::Bounds2;

/// A vertical prism: footprint polygon (outer ring plus holes) extruded from `z_min_m` to
/// `z_max_m`. Coordinates are local ENU metres. Rings are open (the last vertex is not a repeat
/// of the first), have ≥ 3 distinct vertices, and the outer ring is counter-clockwise.
#[derive(Debug, Clone, PartialEq)]
pub struct Building {
    /// Source id, e.g. `osm:way/123` or `proc:17`.
    pub id: String,
    /// Outer ring `[x_m, y_m]`, counter-clockwise.
    pub outer_m: Vec<[f64; 2]>,
    /// Inner rings (courtyards), any orientation.
    pub holes_m: Vec<Vec<[f64; 2]>>,
    /// Bottom of the prism above ground (m); > 0 for floating building parts.
    pub z_min_m: f64,
    /// Roof height above ground (m).
    pub z_max_m: f64,
}

impl Building {
    /// Axis-aligned 2D bounds of the outer ring (m).
    pub fn bounds_m(&self) -> Bounds2 {
        self.outer_m
            .iter()
            .fold(Bounds2::empty(), |b, p| b.including(p[0], p[1]))
    }

    /// Signed area of the outer ring minus the holes (m²), positive for CCW outer rings.
    pub fn area_m2(&self) -> f64 {
        let outer = signed_area_m2(&self.outer_m);
        let holes: f64 = self.holes_m.iter().map(|h| signed_area_m2(h).abs()).sum();
        outer - holes
    }

    /// Whether the 2D point lies inside the footprint (outer ring, not in a hole).
    pub fn contains_xy(&self, x_m: f64, y_m: f64) -> bool {
        point_in_ring(&self.outer_m, x_m, y_m)
            && !self.holes_m.iter().any(|h| point_in_ring(h, x_m, y_m))
    }

    /// Centroid of the outer ring's vertices (m), a cheap representative point.
    pub fn vertex_centroid_m(&self) -> [f64; 2] {
        let n = self.outer_m.len().max(1) as f64;
        let (sx, sy) = self
            .outer_m
            .iter()
            .fold((0.0, 0.0), |(sx, sy), p| (sx + p[0], sy + p[1]));
        [sx / n, sy / n]
    }
}

/// Shoelace signed area of an open ring (m²), positive when counter-clockwise.
pub fn signed_area_m2(ring: &[[f64; 2]]) -> f64 {
    let n = ring.len();
    if n < 3 {
        return 0.0;
    }
    let mut s = 0.0;
    for i in 0..n {
        let a = ring[i];
        let b = ring[(i + 1) % n];
        s += a[0] * b[1] - b[0] * a[1];
    }
    0.5 * s
}

/// Even-odd point-in-polygon test on an open ring.
pub fn point_in_ring(ring: &[[f64; 2]], x: f64, y: f64) -> bool {
    let n = ring.len();
    let mut inside = false;
    let mut j = n.wrapping_sub(1);
    for i in 0..n {
        let (xi, yi) = (ring[i][0], ring[i][1]);
        let (xj, yj) = (ring[j][0], ring[j][1]);
        if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
            inside = !inside;
        }
        j = i;
    }
    inside
}
