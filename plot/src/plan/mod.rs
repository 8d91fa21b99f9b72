//! Planned or flown UAV paths as PNG: a top view of the paths over the buildings, each path
//! coloured by the RSRP class along it (spec/radio.md §3), next to the altitude profile and the
//! serving RSRP against the distance flown.
//!
//! Layout (1600 × 1100 px): title strip; left, the top view (x east / y north in m, equal aspect)
//! zoomed to the paths plus [`VIEW_MARGIN_M`] and a legend below it; right, the altitude profile
//! above the serving-RSRP profile, sharing the distance axis. Each trace keeps one identity colour
//! throughout: the outline of its path on the map and its line in both profiles.

use crate::draw::write_png_atomic;
use crate::error::{Context, PlotError, Result, pe};
use crate::style::{FONT, ensure_font};
use dupac_common::geometry::{Bounds2, Point};
use dupac_radio::city::Building;
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use dupac_radio::sites::Site;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

mod layout;
mod legend;
mod lines;
mod profiles;
mod top_view;

pub use layout::VIEW_MARGIN_M;
use layout::{Derived, HEIGHT, TITLE_H, TITLE_PX, WIDTH, derive};
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

    write_png_atomic(path, |tmp| {
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
