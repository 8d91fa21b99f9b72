//! The one style of every figure: the RSRP classes' bands and colours (from the configured
//! thresholds), the series and trace palettes, the font (the bundled DejaVu Sans) and how a
//! number is written.

use crate::error::{PlotError, Result};
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use plotters::prelude::*;
use plotters::style::FontStyle;
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

/// The font family every figure's text is set in (the bundled DejaVu Sans, [`ensure_font`]).
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

/// Number with a typographic minus sign.
pub(crate) fn fmt_num(v: f64) -> String {
    format!("{v:.0}").replace('-', "\u{2212}")
}
