//! Drawing helpers every figure shares: a polygon clipped to the plotted rectangle, a site's
//! marker, text with a halo, and a PNG written atomically.

use crate::error::{Result, pe};
use crate::style::{FONT, fmt_num};
use dupac_common::geometry::Bounds2;
use dupac_radio::sites::SiteKind;
use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

const MACRO_FILL: RGBColor = RGBColor(230, 35, 55);
const MICRO_FILL: RGBColor = RGBColor(255, 255, 255);

/// Clips a polygon ring (open) to the rectangle `[x0, x1] × [y0, y1]` (Sutherland–Hodgman).
pub(crate) fn clip_ring(ring: &[[f64; 2]], r: Bounds2) -> Vec<[f64; 2]> {
    // Each edge: (axis, bound, keep if coordinate ≥ bound when `lower`).
    let edges = [
        (0usize, r.min_m.x, true),
        (0, r.max_m.x, false),
        (1, r.min_m.y, true),
        (1, r.max_m.y, false),
    ];
    let mut poly: Vec<[f64; 2]> = ring.to_vec();
    for (axis, bound, lower) in edges {
        if poly.is_empty() {
            break;
        }
        let inside = |p: &[f64; 2]| {
            if lower {
                p[axis] >= bound
            } else {
                p[axis] <= bound
            }
        };
        let mut out = Vec::with_capacity(poly.len() + 4);
        for i in 0..poly.len() {
            let cur = poly[i];
            let prev = poly[(i + poly.len() - 1) % poly.len()];
            let (ci, pi) = (inside(&cur), inside(&prev));
            if ci != pi {
                let t = (bound - prev[axis]) / (cur[axis] - prev[axis]);
                let mut q = [
                    prev[0] + t * (cur[0] - prev[0]),
                    prev[1] + t * (cur[1] - prev[1]),
                ];
                q[axis] = bound;
                out.push(q);
            }
            if ci {
                out.push(cur);
            }
        }
        poly = out;
    }
    poly
}

/// Renders with `draw` into a temporary `.png` next to `path` (the bitmap encoder picks the
/// format from the extension), then commits it like every other file
/// ([`dupac_common::fsio::write_atomic_via_path`]): a reader never sees half a PNG.
pub(crate) fn write_png_atomic(path: &Path, draw: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let mut failure = None;
    let written = dupac_common::fsio::write_atomic_via_path(path, |tmp| {
        draw(tmp).map_err(|e| {
            let io = std::io::Error::other(e.to_string());
            failure = Some(e);
            io
        })
    });
    match (written, failure) {
        (_, Some(e)) => Err(e),
        (r, None) => Ok(r?),
    }
}

/// The axes of a top-view map, x east and y north in m with `labels` ticks each, labels and
/// descriptions of DejaVu Sans at `label_px` and `desc_px`: the one axis style of every map
/// figure (the coverage maps, the planned paths' top view).
pub(crate) fn draw_map_axes<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    labels: usize,
    label_px: f64,
    desc_px: f64,
) -> Result<()> {
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x east (m)")
        .y_desc("y north (m)")
        .x_labels(labels)
        .y_labels(labels)
        .x_label_formatter(&|v| fmt_num(*v))
        .y_label_formatter(&|v| fmt_num(*v))
        .label_style((FONT, label_px))
        .axis_desc_style((FONT, desc_px))
        .axis_style(BLACK.stroke_width(1))
        .draw()
        .map_err(pe)
}

/// A site marker centred at pixel `c` on `area` (pixel coordinates).
pub(crate) fn draw_site_marker(
    area: &DrawingArea<BitMapBackend, Shift>,
    c: (i32, i32),
    kind: SiteKind,
) -> Result<()> {
    match kind {
        SiteKind::Macro => {
            let r = 11.0_f64;
            let pts: Vec<(i32, i32)> = [90.0_f64, 210.0, 330.0]
                .iter()
                .map(|a| {
                    let t = a.to_radians();
                    (
                        c.0 + (r * t.cos()).round() as i32,
                        c.1 - (r * t.sin()).round() as i32 + 2,
                    )
                })
                .collect();
            area.draw(&Polygon::new(pts.clone(), MACRO_FILL.filled()))
                .map_err(pe)?;
            let mut closed = pts;
            closed.push(closed[0]);
            area.draw(&PathElement::new(closed, BLACK.stroke_width(2)))
                .map_err(pe)?;
        }
        SiteKind::Micro => {
            area.draw(&Circle::new(c, 7, MICRO_FILL.filled()))
                .map_err(pe)?;
            area.draw(&Circle::new(c, 7, BLACK.stroke_width(2)))
                .map_err(pe)?;
        }
    }
    Ok(())
}

/// Black text with a one-pixel white halo, so it reads on any colour.
pub(crate) fn draw_halo_text(
    area: &DrawingArea<BitMapBackend, Shift>,
    text: &str,
    pos: (i32, i32),
    font: &FontDesc,
    h: HPos,
    v: VPos,
) -> Result<()> {
    let halo = font.color(&WHITE).pos(Pos::new(h, v));
    for (ox, oy) in [
        (-1, -1),
        (0, -1),
        (1, -1),
        (-1, 0),
        (1, 0),
        (-1, 1),
        (0, 1),
        (1, 1),
        (2, 0),
        (-2, 0),
        (0, 2),
        (0, -2),
    ] {
        area.draw_text(text, &halo, (pos.0 + ox, pos.1 + oy))
            .map_err(pe)?;
    }
    let style = font.color(&BLACK).pos(Pos::new(h, v));
    area.draw_text(text, &style, pos).map_err(pe)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_ring_keeps_inside_and_cuts_outside() {
        let sq = vec![[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
        assert_eq!(clip_ring(&sq, Bounds2::new(-2.0, -2.0, 2.0, 2.0)), sq);
        let c = clip_ring(&sq, Bounds2::new(0.0, 0.0, 5.0, 5.0));
        let a = dupac_radio::city::signed_area_m2(&c);
        assert!((a - 1.0).abs() < 1e-12, "{c:?}");
        assert!(clip_ring(&sq, Bounds2::new(3.0, 3.0, 5.0, 5.0)).is_empty());
    }
}
