//! Planned or flown UAV paths as PNG: a top view of the paths over the buildings, each path
//! coloured by the RSRP class along it (spec/radio.md §3), next to the altitude profile and the
//! serving RSRP against the distance flown.
//!
//! Layout (1600 × 1100 px): title strip; left, the top view (x east / y north in m, equal aspect)
//! zoomed to the paths plus [`VIEW_MARGIN_M`] and a legend below it; right, the altitude profile
//! above the serving-RSRP profile, sharing the distance axis. Each trace keeps one identity colour
//! throughout: the outline of its path on the map and its line in both profiles.

use crate::error::{Context, PlotError, Result};
use crate::{FONT, class_colour, ensure_font, pe, trace_colour};
use dupac_common::geometry::{Bounds2, Point};
use dupac_radio::city::Building;
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use dupac_radio::sites::Site;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

mod profiles;
mod top_view;

use profiles::draw_profiles;
use top_view::draw_top_view;

/// One flown or planned path with the radio along it.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightTrace {
    /// Legend label, e.g. `"shortest (A3)"`, `"coverage-aware λ=1 (A3)"`.
    pub label: String,
    /// Positions along the path (m); the first is the source, the last the
    /// destination.
    pub points_m: Vec<Point>,
    /// Serving-cell RSRP at each position (dBm); same length as `points_m`.
    pub serving_rsrp_dbm: Vec<f64>,
    /// RSRP class at each position; same length as `points_m`.
    pub class: Vec<RsrpClass>,
    /// Whether the last point is the destination (a star "D" is drawn there); a flight that
    /// ended early (collision, out of bounds, time limit) gets a cross instead.
    pub reached: bool,
}

/// Image size (px).
const WIDTH: u32 = 1600;
const HEIGHT: u32 = 1100;
/// Height of the title strip (px).
const TITLE_H: i32 = 58;
/// Width of the left column holding the top view and its legend (px).
const LEFT_W: i32 = 900;
/// Space around the traces' bounding box in the top view (m).
pub const VIEW_MARGIN_M: f64 = 80.0;
/// Smallest extent of the top view (m), for paths that barely move horizontally.
const MIN_VIEW_M: f64 = 200.0;
/// Chart margin and label areas (px).
const MARGIN: i32 = 12;
const MAP_X_LABEL: i32 = 66;
const MAP_Y_LABEL: i32 = 90;
/// Height of a panel caption (px).
const CAPTION_H: i32 = 34;
/// Legend row height (px).
const ROW_H: i32 = 30;

const TITLE_PX: f64 = 30.0;
const CAPTION_PX: f64 = 23.0;
const LABEL_PX: f64 = 18.0;
const DESC_PX: f64 = 21.0;
const LEGEND_PX: f64 = 18.0;

/// Map background (streets) and building outline.
const GROUND: RGBColor = RGBColor(252, 252, 250);
const OUTLINE: RGBColor = RGBColor(70, 70, 70);
/// Building fill grey for the lowest and the tallest building in view.
const GREY_LOW: f64 = 222.0;
const GREY_HIGH: f64 = 100.0;

/// Map stroke widths (px) of trace `i`: outline (identity colour) and class-coloured core.
/// Earlier traces are wider, so a later one drawn on top of a shared stretch leaves the
/// earlier one's colours visible along both sides.
fn map_widths(i: usize) -> (u32, u32) {
    [(15, 9), (10, 5), (8, 3)][i.min(2)]
}

/// Profile line width (px) of trace `i` (wider first, for the same reason).
fn profile_width(i: usize) -> u32 {
    [5, 3, 2][i.min(2)]
}

/// Building fill of height `z` relative to the tallest building in view `z_top`.
fn building_grey(z: f64, z_top: f64) -> RGBColor {
    let t = if z_top > 0.0 {
        (z / z_top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let g = (GREY_LOW + t * (GREY_HIGH - GREY_LOW)).round() as u8;
    RGBColor(g, g, g)
}

/// Per-trace quantities derived once.
struct Derived {
    /// Distance flown from the source to each point (m), 3D.
    dist_m: Vec<f64>,
    /// Share of the flown distance in each class (excellent, mediocre, poor); each segment is
    /// split half-and-half between the classes of its two ends.
    share: [f64; 3],
}

fn derive(t: &FlightTrace) -> Derived {
    let mut dist_m = Vec::with_capacity(t.points_m.len());
    let mut share = [0.0; 3];
    let idx = RsrpClass::index;
    let mut d = 0.0;
    for (k, p) in t.points_m.iter().enumerate() {
        if k > 0 {
            let q = t.points_m[k - 1];
            let l = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            d += l;
            share[idx(t.class[k - 1])] += 0.5 * l;
            share[idx(t.class[k])] += 0.5 * l;
        }
        dist_m.push(d);
    }
    if d > 0.0 {
        for s in &mut share {
            *s /= d;
        }
    }
    Derived { dist_m, share }
}

/// Checks the inputs; the error names the output path and, where one is at fault, the trace.
fn validate(area_m: Bounds2, traces: &[FlightTrace], path: &Path) -> Result<()> {
    let corners = area_m.to_array();
    let [x_min, y_min, x_max, y_max] = corners;
    if !(corners.iter().all(|v| v.is_finite()) && x_max > x_min && y_max > y_min) {
        return Err(PlotError::Invalid(format!(
            "cannot plot {}: flight area {area_m} is empty or not finite",
            path.display()
        )));
    }
    for t in traces {
        let n = t.points_m.len();
        if t.serving_rsrp_dbm.len() != n || t.class.len() != n {
            return Err(PlotError::Invalid(format!(
                "cannot plot {}: trace '{}' has {} points, {} RSRP values and {} classes",
                path.display(),
                t.label,
                n,
                t.serving_rsrp_dbm.len(),
                t.class.len()
            )));
        }
        if let Some(k) = t
            .points_m
            .iter()
            .position(|p| !p.iter().all(|v| v.is_finite()))
        {
            return Err(PlotError::Invalid(format!(
                "cannot plot {}: trace '{}' has a non-finite position {:?} at point {k}",
                path.display(),
                t.label,
                t.points_m[k]
            )));
        }
        if let Some(k) = t.serving_rsrp_dbm.iter().position(|v| !v.is_finite()) {
            return Err(PlotError::Invalid(format!(
                "cannot plot {}: trace '{}' has a non-finite RSRP {} at point {k}",
                path.display(),
                t.label,
                t.serving_rsrp_dbm[k]
            )));
        }
    }
    if !traces.iter().any(|t| t.points_m.len() >= 2) {
        let labels: Vec<&str> = traces.iter().map(|t| t.label.as_str()).collect();
        return Err(PlotError::Invalid(format!(
            "cannot plot {}: no trace has two or more points (traces: {labels:?})",
            path.display()
        )));
    }
    Ok(())
}

/// Renders the traces to a 1600 × 1100 px PNG at `path` (written to a temporary file in the same
/// directory, then renamed).
///
/// * `buildings` — footprints in the top view, filled grey, darker for taller ones.
/// * `sites` — those inside the view, as in the coverage maps (triangle macro, circle micro).
/// * `area_m` — the flight area (m); the top view is the
///   traces' bounding box plus [`VIEW_MARGIN_M`], widened to fill the panel, within this area.
/// * `traces` — at least one with two or more points; each vector of a trace has one entry per
///   point and every value is finite.
/// * `title` — drawn at the top.
pub fn render_plan_png(
    buildings: &[Building],
    sites: &[Site],
    area_m: Bounds2,
    traces: &[FlightTrace],
    thresholds: &RsrpThresholds,
    title: &str,
    path: &Path,
) -> Result<()> {
    validate(area_m, traces, path)?;
    ensure_font()?;

    crate::write_png_atomic(path, |tmp| {
        draw(buildings, sites, area_m, traces, thresholds, title, tmp)
    })
    .with_context(|| format!("cannot write path plot {}", path.display()))
}

/// [`render_plan_png`] over `world`'s buildings, sites and area, with the RSRP class thresholds
/// of `radio` (`radio.rsrp_excellent_dbm`, `radio.rsrp_poor_dbm`): what `dupac plan`, `dupac fly`
/// and `dupac eval` draw.
pub fn render_world_plan(
    world: &dupac_radio::world::RadioWorld,
    radio: &dupac_common::config::RadioConfig,
    traces: &[FlightTrace],
    title: &str,
    path: &Path,
) -> Result<()> {
    render_plan_png(
        &world.city.buildings,
        &world.sites,
        world.city.area_m,
        traces,
        &RsrpThresholds::from_config(radio),
        title,
        path,
    )
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

fn draw(
    buildings: &[Building],
    sites: &[Site],
    area_m: Bounds2,
    traces: &[FlightTrace],
    thresholds: &RsrpThresholds,
    title: &str,
    file: &Path,
) -> Result<()> {
    let derived: Vec<Derived> = traces.iter().map(derive).collect();
    let root = BitMapBackend::new(file, (WIDTH, HEIGHT)).into_drawing_area();
    root.fill(&WHITE).map_err(pe)?;

    // Title, shrunk until it fits the width.
    let mut size = TITLE_PX;
    while size > 14.0 {
        let (w, _) = root
            .estimate_text_size(title, &(FONT, size).into_text_style(&root))
            .map_err(pe)?;
        if w + 40 <= WIDTH {
            break;
        }
        size -= 2.0;
    }
    let title_style = (FONT, size)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Center));
    root.draw_text(title, &title_style, (WIDTH as i32 / 2, TITLE_H / 2 + 2))
        .map_err(pe)?;

    draw_top_view(
        &root, buildings, sites, area_m, traces, &derived, thresholds,
    )?;
    draw_profiles(&root, traces, &derived, thresholds)?;
    root.present().map_err(pe)?;
    Ok(())
}

/// Top view bounds (m): the traces' bounding box plus the margin, at least
/// [`MIN_VIEW_M`] wide and high, widened to the panel aspect `aspect` (width / height) and kept
/// inside the flight area where possible.
fn view_bounds(traces: &[FlightTrace], area: Bounds2, aspect: f64) -> Bounds2 {
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
fn clip_polyline(pts: &[(f64, f64)], r: Bounds2) -> Vec<Vec<(f64, f64)>> {
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
fn simplify(pts: &[(f64, f64)], tol: f64) -> Vec<(f64, f64)> {
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

/// `text` cut with an ellipsis until it is at most `max_w` px wide in `style`.
fn fit_text(area: &Area, text: &str, style: &TextStyle, max_w: i32) -> Result<String> {
    let mut chars: Vec<char> = text.chars().collect();
    let mut out = text.to_string();
    loop {
        let (w, _) = area.estimate_text_size(&out, style).map_err(pe)?;
        if w as i32 <= max_w || chars.len() <= 1 {
            return Ok(out);
        }
        chars.pop();
        out = chars.iter().collect::<String>() + "…";
    }
}

/// Maximal runs of equal class along a trace, as `(class, polyline)`: each point owns the
/// halves of its two adjacent segments.
fn class_runs(t: &FlightTrace) -> Vec<(RsrpClass, Vec<(f64, f64)>)> {
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

/// A plotted trace: the source (with the best RSRP there) followed by every step's position,
/// serving RSRP and class.
pub fn trace_of(
    label: String,
    source_m: Point,
    source_rsrp_dbm: f64,
    thresholds: RsrpThresholds,
    steps: &[dupac_actor::record::StepInfo],
) -> FlightTrace {
    let mut t = FlightTrace {
        label,
        points_m: vec![source_m],
        serving_rsrp_dbm: vec![source_rsrp_dbm],
        class: vec![thresholds.classify(source_rsrp_dbm)],
        reached: true,
    };
    for s in steps {
        t.points_m.push(s.position_m);
        t.serving_rsrp_dbm.push(s.serving_rsrp_dbm);
        t.class.push(s.class);
    }
    t
}

#[cfg(test)]
mod tests;
