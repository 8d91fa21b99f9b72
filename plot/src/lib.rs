//! DUPAC's figures, all in one style: coverage maps ([`coverage`], paper Fig. 2(b)), a pair's
//! flights over the city with their altitude and RSRP profiles ([`plan`]), the learning curves
//! of a run directory ([`curves`]) and the evaluation's figures ([`eval`], paper Fig. 3 and 4).
//! Every PNG is written atomically through [`dupac_common::fsio`]; RSRP classes are coloured
//! from the configured thresholds ([`class_bands`]); the text is the bundled DejaVu Sans.

pub mod coverage;
pub mod curves;
pub mod error;
pub mod eval;
pub mod plan;

use dupac_common::geometry::Bounds2;
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use dupac_radio::sites::SiteKind;
use error::{PlotError, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontStyle;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;
use std::sync::OnceLock;

/// The RSRP classes as every figure draws them (spec/radio.md §3), from the configured
/// thresholds (`radio.rsrp_excellent_dbm`, `radio.rsrp_poor_dbm`), never from literals: each
/// class with the band it covers between `lo_dbm` and `hi_dbm` (the plot's range) and its
/// legend label.
pub fn class_bands(
    t: &RsrpThresholds,
    lo_dbm: f64,
    hi_dbm: f64,
) -> [(RsrpClass, f64, f64, String); 3] {
    [
        (
            RsrpClass::Excellent,
            t.excellent_dbm,
            hi_dbm,
            format!("excellent (≥ {} dBm)", fmt_num(t.excellent_dbm)),
        ),
        (
            RsrpClass::Mediocre,
            t.poor_dbm,
            t.excellent_dbm,
            "mediocre".to_string(),
        ),
        (
            RsrpClass::Poor,
            lo_dbm,
            t.poor_dbm,
            format!("poor (< {} dBm)", fmt_num(t.poor_dbm)),
        ),
    ]
}

pub(crate) const FONT: &str = "sans-serif";

/// The one palette of every figure. RSRP classes (ColorBrewer-like green / orange / red, in
/// [`RsrpClass::ALL`] order) wherever a class is drawn.
pub(crate) const CLASS_COLOURS: [RGBColor; 3] = [
    RGBColor(26, 152, 80),
    RGBColor(240, 140, 20),
    RGBColor(215, 25, 35),
];
/// Series of a chart (methods, metrics): matplotlib's tab10.
pub(crate) const SERIES: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];
/// Paths drawn over class-coloured segments (plan figures): away from the class colours.
pub(crate) const TRACES: [RGBColor; 6] = [
    RGBColor(30, 80, 190),
    RGBColor(150, 45, 170),
    RGBColor(25, 25, 25),
    RGBColor(0, 165, 205),
    RGBColor(135, 85, 50),
    RGBColor(120, 120, 120),
];

/// The colour of an RSRP class.
pub(crate) fn class_colour(c: RsrpClass) -> RGBColor {
    CLASS_COLOURS[c.index()]
}

/// The colour of chart series `i`.
pub(crate) fn series_colour(i: usize) -> RGBColor {
    SERIES[i % SERIES.len()]
}

/// The colour of plan path `i`.
pub(crate) fn trace_colour(i: usize) -> RGBColor {
    TRACES[i % TRACES.len()]
}
const MACRO_FILL: RGBColor = RGBColor(230, 35, 55);
const MICRO_FILL: RGBColor = RGBColor(255, 255, 255);

/// Registers the bundled DejaVu Sans as `sans-serif` (the ab_glyph text backend has no system
/// fonts); once per process.
pub fn ensure_font() -> Result<()> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            include_bytes!("../../assets/DejaVuSans.ttf"),
        )
        .is_ok()
    });
    if ok { Ok(()) } else { Err(PlotError::Font) }
}

/// Plotters' errors carry the backend type; flatten them into [`PlotError::Draw`] with their
/// message.
pub(crate) fn pe<E: std::fmt::Display>(e: E) -> PlotError {
    PlotError::Draw(e.to_string())
}

/// Number with a typographic minus sign.
pub(crate) fn fmt_num(v: f64) -> String {
    format!("{v:.0}").replace('-', "\u{2212}")
}

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
