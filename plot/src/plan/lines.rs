//! The top view's geometry: the view's bounds around the traces, polylines clipped to it and
//! simplified to the pixel, and a trace's runs of one RSRP class.

use super::FlightTrace;
use super::layout::{MIN_VIEW_M, VIEW_MARGIN_M};
use dupac_common::geometry::Bounds2;
use dupac_radio::class::RsrpClass;

/// Top view bounds (m): the traces' bounding box plus the margin, at least
/// [`MIN_VIEW_M`] wide and high, widened to the panel aspect `aspect` (width / height) and kept
/// inside the flight area where possible.
pub(super) fn view_bounds(traces: &[FlightTrace], area: Bounds2, aspect: f64) -> Bounds2 {
    let padded = traces
        .iter()
        .flat_map(|t| &t.points_m)
        .fold(Bounds2::empty(), |b, p| b.including(p.x, p.y))
        .expanded(VIEW_MARGIN_M)
        .to_array();
    let clipped = [
        padded[0].max(area.min_m.x),
        padded[1].max(area.min_m.y),
        padded[2].min(area.max_m.x),
        padded[3].min(area.max_m.y),
    ];
    // Traces entirely outside the area: show them anyway rather than an empty map.
    let (mut v, bound) = if clipped[2] > clipped[0] && clipped[3] > clipped[1] {
        (clipped, area.to_array())
    } else {
        (padded, padded)
    };
    // One axis at a time: grow `[lo, hi]` to `len` around its centre, then slide it into
    // `[blo, bhi]` and clip.
    let grow = |lo: f64, hi: f64, len: f64, blo: f64, bhi: f64| -> (f64, f64) {
        if hi - lo >= len {
            return (lo, hi);
        }
        let c = 0.5 * (lo + hi);
        let (mut a, mut z) = (c - 0.5 * len, c + 0.5 * len);
        if a < blo {
            z += blo - a;
            a = blo;
        }
        if z > bhi {
            a -= z - bhi;
            z = bhi;
        }
        (a.max(blo), z)
    };
    let big = [f64::NEG_INFINITY, f64::INFINITY];
    // The minimum extent may leave the area (a tiny area is still drawn at a legible scale).
    (v[0], v[2]) = grow(v[0], v[2], MIN_VIEW_M, big[0], big[1]);
    (v[1], v[3]) = grow(v[1], v[3], MIN_VIEW_M, big[0], big[1]);
    let (w, h) = (v[2] - v[0], v[3] - v[1]);
    if w / h < aspect {
        (v[0], v[2]) = grow(
            v[0],
            v[2],
            h * aspect,
            bound[0].min(v[0]),
            bound[2].max(v[2]),
        );
    } else {
        (v[1], v[3]) = grow(
            v[1],
            v[3],
            w / aspect,
            bound[1].min(v[1]),
            bound[3].max(v[3]),
        );
    }
    Bounds2::new(v[0], v[1], v[2], v[3])
}

/// Clips a polyline to the rectangle `r` (Liang–Barsky per segment); the
/// visible pieces, each with two or more points.
pub(super) fn clip_polyline(pts: &[(f64, f64)], r: Bounds2) -> Vec<Vec<(f64, f64)>> {
    let mut pieces: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut cur: Vec<(f64, f64)> = Vec::new();
    for w in pts.windows(2) {
        let (p, q) = (w[0], w[1]);
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
        let mut visible = true;
        for (pk, qk) in [
            (-dx, p.0 - r.min_m.x),
            (dx, r.max_m.x - p.0),
            (-dy, p.1 - r.min_m.y),
            (dy, r.max_m.y - p.1),
        ] {
            if pk == 0.0 {
                if qk < 0.0 {
                    visible = false;
                    break;
                }
            } else {
                let t = qk / pk;
                if pk < 0.0 {
                    t0 = t0.max(t);
                } else {
                    t1 = t1.min(t);
                }
            }
        }
        if !visible || t0 > t1 {
            if cur.len() >= 2 {
                pieces.push(std::mem::take(&mut cur));
            }
            cur.clear();
            continue;
        }
        let a = (p.0 + t0 * dx, p.1 + t0 * dy);
        let b = (p.0 + t1 * dx, p.1 + t1 * dy);
        if t0 > 0.0 || cur.is_empty() {
            if cur.len() >= 2 {
                pieces.push(std::mem::take(&mut cur));
            }
            cur = vec![a];
        }
        cur.push(b);
        if t1 < 1.0 {
            pieces.push(std::mem::take(&mut cur));
        }
    }
    if cur.len() >= 2 {
        pieces.push(cur);
    }
    pieces
}

/// Douglas–Peucker simplification with tolerance `tol` (same units as the points): drops
/// points that lie within `tol` of the line through their kept neighbours, so that densely
/// sampled straight stretches are drawn as one clean thick segment.
pub(super) fn simplify(pts: &[(f64, f64)], tol: f64) -> Vec<(f64, f64)> {
    if pts.len() <= 2 {
        return pts.to_vec();
    }
    let mut keep = vec![false; pts.len()];
    keep[0] = true;
    keep[pts.len() - 1] = true;
    let mut stack = vec![(0, pts.len() - 1)];
    while let Some((a, b)) = stack.pop() {
        let (p, q) = (pts[a], pts[b]);
        let (dx, dy) = (q.0 - p.0, q.1 - p.1);
        let len = (dx * dx + dy * dy).sqrt();
        let mut worst = (0.0, a);
        for (k, r) in pts.iter().enumerate().take(b).skip(a + 1) {
            let d = if len > 0.0 {
                ((r.0 - p.0) * dy - (r.1 - p.1) * dx).abs() / len
            } else {
                ((r.0 - p.0).powi(2) + (r.1 - p.1).powi(2)).sqrt()
            };
            if d > worst.0 {
                worst = (d, k);
            }
        }
        if worst.0 > tol {
            keep[worst.1] = true;
            stack.push((a, worst.1));
            stack.push((worst.1, b));
        }
    }
    pts.iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(*p))
        .collect()
}

/// Maximal runs of equal class along a trace, as `(class, polyline)`: each point owns the
/// halves of its two adjacent segments.
pub(super) fn class_runs(t: &FlightTrace) -> Vec<(RsrpClass, Vec<(f64, f64)>)> {
    let p: Vec<(f64, f64)> = t.points_m.iter().map(|p| (p[0], p[1])).collect();
    let n = p.len();
    let mid = |a: usize, b: usize| (0.5 * (p[a].0 + p[b].0), 0.5 * (p[a].1 + p[b].1));
    let mut runs = Vec::new();
    let mut a = 0;
    while a < n {
        let mut b = a;
        while b + 1 < n && t.class[b + 1] == t.class[a] {
            b += 1;
        }
        let mut line = Vec::with_capacity(b - a + 3);
        if a > 0 {
            line.push(mid(a - 1, a));
        }
        line.extend_from_slice(&p[a..=b]);
        if b + 1 < n {
            line.push(mid(b, b + 1));
        }
        if line.len() >= 2 {
            runs.push((t.class[a], line));
        }
        a = b + 1;
    }
    runs
}
