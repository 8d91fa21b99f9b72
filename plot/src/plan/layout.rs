//! The plan figure's layout and look: its size and regions, font sizes, the map's colours and
//! stroke widths, and what each trace's drawing derives from it once (distance flown, class
//! shares).

use super::FlightTrace;
use crate::error::{Result, pe};
use dupac_radio::class::RsrpClass;
use plotters::coord::Shift;
use plotters::prelude::*;

/// Image size (px).
pub(super) const WIDTH: u32 = 1600;
pub(super) const HEIGHT: u32 = 1100;
/// Height of the title strip (px).
pub(super) const TITLE_H: i32 = 58;
/// Width of the left column holding the top view and its legend (px).
pub(super) const LEFT_W: i32 = 900;
/// Space around the traces' bounding box in the top view (m).
pub const VIEW_MARGIN_M: f64 = 80.0;
/// Smallest extent of the top view (m), for paths that barely move horizontally.
pub(super) const MIN_VIEW_M: f64 = 200.0;
/// Chart margin and label areas (px).
pub(super) const MARGIN: i32 = 12;
pub(super) const MAP_X_LABEL: i32 = 66;
pub(super) const MAP_Y_LABEL: i32 = 90;
/// Height of a panel caption (px).
pub(super) const CAPTION_H: i32 = 34;
/// Legend row height (px).
pub(super) const ROW_H: i32 = 30;

pub(super) const TITLE_PX: f64 = 30.0;
pub(super) const CAPTION_PX: f64 = 23.0;
pub(super) const LABEL_PX: f64 = 18.0;
pub(super) const DESC_PX: f64 = 21.0;
pub(super) const LEGEND_PX: f64 = 18.0;

/// Map background (streets) and building outline.
pub(super) const GROUND: RGBColor = RGBColor(252, 252, 250);
pub(super) const OUTLINE: RGBColor = RGBColor(70, 70, 70);
/// Building fill grey for the lowest and the tallest building in view.
const GREY_LOW: f64 = 222.0;
const GREY_HIGH: f64 = 100.0;

/// Map stroke widths (px) of trace `i`: outline (identity colour) and class-coloured core.
/// Earlier traces are wider, so a later one drawn on top of a shared stretch leaves the
/// earlier one's colours visible along both sides.
pub(super) fn map_widths(i: usize) -> (u32, u32) {
    [(15, 9), (10, 5), (8, 3)][i.min(2)]
}

/// Profile line width (px) of trace `i` (wider first, for the same reason).
pub(super) fn profile_width(i: usize) -> u32 {
    [5, 3, 2][i.min(2)]
}

/// Building fill of height `z` relative to the tallest building in view `z_top`.
pub(super) fn building_grey(z: f64, z_top: f64) -> RGBColor {
    let t = if z_top > 0.0 {
        (z / z_top).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let g = (GREY_LOW + t * (GREY_HIGH - GREY_LOW)).round() as u8;
    RGBColor(g, g, g)
}

/// The drawing area of a plan figure.
pub(super) type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Per-trace quantities derived once.
pub(super) struct Derived {
    /// Distance flown from the source to each point (m), 3D.
    pub(super) dist_m: Vec<f64>,
    /// Share of the flown distance in each class (excellent, mediocre, poor); each segment is
    /// split half-and-half between the classes of its two ends.
    pub(super) share: [f64; 3],
}

pub(super) fn derive(t: &FlightTrace) -> Derived {
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

/// `text` cut with an ellipsis until it is at most `max_w` px wide in `style`.
pub(super) fn fit_text(area: &Area, text: &str, style: &TextStyle, max_w: i32) -> Result<String> {
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
