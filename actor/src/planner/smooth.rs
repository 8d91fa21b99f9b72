//! Path cost along straight segments and any-angle smoothing of a lattice path.
//!
//! Smoothing has two stages; every segment it creates passes [`FreeSpace::segment_clear`] with a
//! margin of [`SMOOTHING_MARGIN_M`] on the clearance, so that a path pressed against the clearance
//! surface still passes the exact test robustly (f32 geometry):
//! 1. greedy string pulling: from an anchor, extend a straight segment over the following
//!    waypoints while it stays clear (and acceptable, see below), then make its end the next anchor;
//! 2. waypoint relaxation, in passes until a pass gains less than 1 cm (at most 60): for each
//!    interior waypoint, drop it when the chord between its neighbours is clear; else move it
//!    towards the nearest point of that chord (fractions 1/2, 1/4, … down to a 0.1 m move) while
//!    both new segments stay clear; else cut the corner (replace it by one point on each adjacent
//!    segment, at the same fractions, when the segment between them is clear). Moving towards the
//!    chord never lengthens the path (the two-segment length is convex along the move), and cuts
//!    shorten it, so this pulls the path taut around buildings at about the clearance, off the
//!    lattice.
//!
//! A replacement is *acceptable* when its cost (sampled every `voxel_m`, [`CostField::segment`])
//! is not higher than that of the part it replaces and its worst RSRP class is not worse. Without
//! coverage the cost is the length and the class is always excellent, so only clearance matters.

use super::dist;
use super::free_space::FreeSpace;
#[cfg(doc)]
use super::free_space::SMOOTHING_MARGIN_M;
use dupac_common::geometry::Point;

/// Relative slack when comparing costs (rounding of sums of lengths).
const COST_EPS: f64 = 1e-9;
/// Relaxation stops when a pass shortens the path by less than this (m).
const RELAX_STOP_M: f64 = 1e-2;
/// [`polish`] stops when a pass shortens the path by less than this (m).
const POLISH_STOP_M: f64 = 1e-4;
/// Smallest waypoint move tried by [`polish`] (m).
const POLISH_MIN_MOVE_M: f64 = 1e-3;
/// At most this many [`polish`] passes.
const POLISH_MAX_PASSES: usize = 200;
/// A corner is cut only when that shortens the path by at least this (m).
const CUT_MIN_GAIN_M: f64 = 1e-3;
/// Smallest waypoint move tried (m): step fractions halve from 1/2 down to this.
const MIN_MOVE_M: f64 = 0.1;
/// At most this many relaxation passes.
const RELAX_MAX_PASSES: usize = 60;

/// The planner's cost of flying through space: length × (1 + λ · penalty(class)) with the class of
/// the nearest lattice point, or plain length without coverage.
pub(crate) struct CostField<'a> {
    fs: &'a FreeSpace,
    /// Per-voxel class codes (0 excellent, 1 mediocre, 2 poor) and the cost multiplier per code.
    coverage: Option<(&'a [u8], [f64; 3])>,
}

impl<'a> CostField<'a> {
    pub(crate) fn new(fs: &'a FreeSpace, coverage: Option<(&'a [u8], [f64; 3])>) -> Self {
        CostField { fs, coverage }
    }

    /// Class code of lattice point `idx` (0 without coverage; unknown points are poor).
    #[inline]
    pub(crate) fn voxel_class(&self, idx: u32) -> u8 {
        match self.coverage {
            None => 0,
            Some((classes, _)) => classes.get(idx as usize).copied().unwrap_or(2).min(2),
        }
    }

    /// Cost multiplier of lattice point `idx` (1 without coverage).
    #[inline]
    pub(crate) fn voxel_mult(&self, idx: u32) -> f64 {
        match self.coverage {
            None => 1.0,
            Some((_, mult)) => mult[usize::from(self.voxel_class(idx))],
        }
    }

    /// Class code at a point: that of the nearest lattice point.
    #[inline]
    fn point_class(&self, p_m: Point) -> u8 {
        if self.coverage.is_none() {
            return 0;
        }
        match self.fs.nearest_triple(p_m) {
            Some(i) => self.voxel_class(self.fs.index(i)),
            None => 2,
        }
    }

    /// Cost multiplier at a point (that of the nearest lattice point).
    #[inline]
    pub(crate) fn point_mult(&self, p_m: Point) -> f64 {
        match self.coverage {
            None => 1.0,
            Some((_, mult)) => mult[usize::from(self.point_class(p_m))],
        }
    }

    /// `(cost, worst class code)` of the straight segment `a_m → b_m`: the segment is cut into
    /// `ceil(length / voxel_m)` equal pieces, each charged its length times the multiplier at its
    /// midpoint. Without coverage: `(length, 0)`.
    pub(crate) fn segment(&self, a_m: Point, b_m: Point) -> (f64, u8) {
        let len = dist(a_m, b_m);
        let Some((_, mult)) = self.coverage else {
            return (len, 0);
        };
        let n = (len / self.fs.voxel_m()).ceil().clamp(1.0, 1e6) as usize;
        let piece = len / n as f64;
        let mut cost = 0.0;
        let mut worst = 0u8;
        for k in 0..n {
            let f = (k as f64 + 0.5) / n as f64;
            let p = Point::new(
                a_m[0] + f * (b_m[0] - a_m[0]),
                a_m[1] + f * (b_m[1] - a_m[1]),
                a_m[2] + f * (b_m[2] - a_m[2]),
            );
            let c = self.point_class(p);
            worst = worst.max(c);
            cost += piece * mult[usize::from(c)];
        }
        (cost, worst)
    }
}

/// Whether a replacement `new` = (cost, worst class) is acceptable instead of `old`.
#[inline]
fn acceptable(new: (f64, u8), old: (f64, u8)) -> bool {
    new.1 <= old.1 && new.0 <= old.0 + COST_EPS * old.0.max(1.0)
}

#[inline]
fn join(a: (f64, u8), b: (f64, u8)) -> (f64, u8) {
    (a.0 + b.0, a.1.max(b.1))
}

/// Smooths a flyable polyline (every segment clear) into an any-angle path with the same ends;
/// the result's segments are all clear and its cost is not higher.
pub(crate) fn smooth(fs: &FreeSpace, field: &CostField, pts: Vec<Point>) -> Vec<Point> {
    let pulled = pull(fs, field, pts);
    relax(fs, field, pulled, RELAX)
}

/// Pulls a smoothed path tighter: string pulling again over its waypoints, then the waypoint
/// relaxation with moves down to [`POLISH_MIN_MOVE_M`] until a pass gains less than
/// [`POLISH_STOP_M`]. The first relaxation stops at 1 cm per pass and 0.1 m moves, which leaves
/// the path up to a few centimetres from taut; two paths of the same homotopy polished this way
/// agree to about a millimetre, so the shortest of several candidates is decided by their routes,
/// not by where their relaxation happened to stop. Same guarantees as [`smooth`].
pub(crate) fn polish(fs: &FreeSpace, field: &CostField, pts: Vec<Point>) -> Vec<Point> {
    let pulled = pull(fs, field, pts);
    relax(fs, field, pulled, POLISH)
}

/// How far the waypoint relaxation goes.
#[derive(Clone, Copy)]
struct Relax {
    /// Stop when a pass gains less than this (m).
    stop_m: f64,
    /// Smallest waypoint move tried (m).
    min_move_m: f64,
    /// At most this many passes.
    max_passes: usize,
}

/// The relaxation of [`smooth`].
const RELAX: Relax = Relax {
    stop_m: RELAX_STOP_M,
    min_move_m: MIN_MOVE_M,
    max_passes: RELAX_MAX_PASSES,
};

/// The relaxation of [`polish`].
const POLISH: Relax = Relax {
    stop_m: POLISH_STOP_M,
    min_move_m: POLISH_MIN_MOVE_M,
    max_passes: POLISH_MAX_PASSES,
};

/// Greedy string pulling (stage 1).
fn pull(fs: &FreeSpace, field: &CostField, pts: Vec<Point>) -> Vec<Point> {
    let n = pts.len();
    if n <= 2 {
        return pts;
    }
    let seg: Vec<(f64, u8)> = pts.windows(2).map(|w| field.segment(w[0], w[1])).collect();
    let mut out = vec![pts[0]];
    let mut a = 0;
    while a + 1 < n {
        let mut best = a + 1;
        let mut replaced = seg[a];
        let mut j = a + 1;
        while j + 1 < n {
            replaced = join(replaced, seg[j]);
            if fs.segment_clear_smoothing(pts[a], pts[j + 1])
                && acceptable(field.segment(pts[a], pts[j + 1]), replaced)
            {
                best = j + 1;
                j += 1;
            } else {
                break;
            }
        }
        out.push(pts[best]);
        a = best;
    }
    out
}

/// Nearest point of segment `a → b` to `w`.
fn nearest_on_segment(a: Point, b: Point, w: Point) -> Point {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let l2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    if l2 <= 0.0 {
        return a;
    }
    let t = (((w[0] - a[0]) * ab[0] + (w[1] - a[1]) * ab[1] + (w[2] - a[2]) * ab[2]) / l2)
        .clamp(0.0, 1.0);
    Point::new(a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2])
}

/// Waypoint relaxation (stage 2).
fn relax(fs: &FreeSpace, field: &CostField, mut pts: Vec<Point>, how: Relax) -> Vec<Point> {
    let max_points = 4 * pts.len() + 64;
    for _ in 0..how.max_passes {
        let mut gained_m = 0.0;
        let mut i = 1;
        while i + 1 < pts.len() {
            let (a, w, b) = (pts[i - 1], pts[i], pts[i + 1]);
            let old_len = dist(a, w) + dist(w, b);
            let old = join(field.segment(a, w), field.segment(w, b));
            // Drop the waypoint.
            if fs.segment_clear_smoothing(a, b) && acceptable(field.segment(a, b), old) {
                gained_m += old_len - dist(a, b);
                pts.remove(i);
                continue;
            }
            // Slide it towards the chord.
            let q = nearest_on_segment(a, b, w);
            let mut moved = false;
            let reach = dist(w, q);
            let mut f = 0.5;
            while f * reach >= how.min_move_m {
                let m = lerp(w, q, f);
                let new_len = dist(a, m) + dist(m, b);
                if new_len < old_len
                    && fs.segment_clear_smoothing(a, m)
                    && fs.segment_clear_smoothing(m, b)
                    && acceptable(join(field.segment(a, m), field.segment(m, b)), old)
                {
                    gained_m += old_len - new_len;
                    pts[i] = m;
                    moved = true;
                    break;
                }
                f *= 0.5;
            }
            if moved {
                i += 1;
                continue;
            }
            // Cut the corner: replace it by one point on each adjacent segment.
            if pts.len() < max_points {
                let reach = dist(w, a).max(dist(w, b));
                let mut f = 0.5;
                while f * reach >= how.min_move_m {
                    let (w1, w2) = (lerp(w, a, f), lerp(w, b, f));
                    let new_len = dist(a, w1) + dist(w1, w2) + dist(w2, b);
                    if old_len - new_len < CUT_MIN_GAIN_M {
                        break;
                    }
                    if fs.segment_clear_smoothing(w1, w2)
                        && fs.segment_clear_smoothing(a, w1)
                        && fs.segment_clear_smoothing(w2, b)
                        && acceptable(
                            join(
                                join(field.segment(a, w1), field.segment(w1, w2)),
                                field.segment(w2, b),
                            ),
                            old,
                        )
                    {
                        gained_m += old_len - new_len;
                        pts[i] = w1;
                        pts.insert(i + 1, w2);
                        i += 1;
                        break;
                    }
                    f *= 0.5;
                }
            }
            i += 1;
        }
        if gained_m < how.stop_m {
            break;
        }
    }
    pts
}

/// `a + f (b − a)`.
#[inline]
fn lerp(a: Point, b: Point, f: f64) -> Point {
    Point::new(
        a[0] + f * (b[0] - a[0]),
        a[1] + f * (b[1] - a[1]),
        a[2] + f * (b[2] - a[2]),
    )
}
