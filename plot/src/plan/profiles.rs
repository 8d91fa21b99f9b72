//! The right half of a plan figure: the altitude profile and the serving RSRP with the class
//! bands against the distance flown, sharing the distance axis.

use super::FlightTrace;
use super::layout::{
    Area, CAPTION_H, CAPTION_PX, DESC_PX, Derived, HEIGHT, LABEL_PX, LEFT_W, LEGEND_PX, MARGIN,
    TITLE_H, WIDTH, fit_text, profile_width,
};
use crate::error::{Result, pe};
use crate::style::{FONT, class_bands, class_colour, fmt_num, trace_colour};
use dupac_radio::class::RsrpThresholds;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// `hi` raised so that the top `frac` of the axis `[lo, new hi]` lies above the data (room for
/// the legend).
pub(super) fn with_headroom(lo: f64, hi: f64, frac: f64) -> f64 {
    hi + (hi - lo) * frac / (1.0 - frac)
}

pub(super) fn draw_profiles(
    root: &Area,
    traces: &[FlightTrace],
    derived: &[Derived],
    thresholds: &RsrpThresholds,
) -> Result<()> {
    let right = root.clone().shrink(
        (LEFT_W, TITLE_H),
        (WIDTH as i32 - LEFT_W, HEIGHT as i32 - TITLE_H),
    );
    let (top, bottom) = right.split_vertically((HEIGHT as i32 - TITLE_H) / 2);
    let d_max = derived
        .iter()
        .filter_map(|d| d.dist_m.last().copied())
        .fold(0.0_f64, f64::max)
        .max(1.0);
    let drawable: Vec<usize> = (0..traces.len())
        .filter(|&i| !traces[i].points_m.is_empty())
        .collect();
    // Legend labels cut to the plot width (about 720 px less label areas and the legend's
    // line sample).
    let label_style = (FONT, LEGEND_PX).into_text_style(root);
    let labels = traces
        .iter()
        .map(|t| fit_text(root, &t.label, &label_style, 430))
        .collect::<Result<Vec<String>>>()?;
    // Legend rows above the data: its height as a share of the plot height (estimate).
    let plot_h_est = f64::from((HEIGHT as i32 - TITLE_H) / 2 - CAPTION_H - 60 - 2 * MARGIN);
    let legend_frac =
        ((drawable.len() as f64 * (LEGEND_PX + 8.0) + 28.0) / plot_h_est).clamp(0.1, 0.6);

    // Altitude profile.
    let z_max = traces
        .iter()
        .flat_map(|t| &t.points_m)
        .map(|p| p[2])
        .fold(10.0_f64, f64::max);
    let z_min = traces
        .iter()
        .flat_map(|t| &t.points_m)
        .map(|p| p[2])
        .fold(0.0_f64, f64::min);
    let z_top = with_headroom(z_min, z_max * 1.03, legend_frac);
    let mut chart = profile_chart(&top, "Altitude profile", d_max, z_min..z_top)?;
    mesh(&mut chart, "altitude z (m)")?;
    series(&mut chart, traces, derived, &labels, &drawable, |t, k| {
        t.points_m[k][2]
    })?;
    legend(&mut chart)?;

    // Serving RSRP with the class bands.
    let (r_lo, r_hi) = traces
        .iter()
        .flat_map(|t| &t.serving_rsrp_dbm)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let r_bot = (r_lo - 3.0).min(-130.0);
    let r_top = with_headroom(r_bot, (r_hi + 3.0).max(-50.0), legend_frac);
    let mut chart = profile_chart(&bottom, "Serving RSRP", d_max, r_bot..r_top)?;
    let bands = class_bands(thresholds, r_bot, r_top);
    for (class, lo, hi, _) in bands.iter().cloned() {
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(0.0, lo), (d_max, hi)],
                class_colour(class).mix(0.13).filled(),
            )))
            .map_err(pe)?;
    }
    mesh(&mut chart, "serving RSRP (dBm)")?;
    for b in [thresholds.excellent_dbm, thresholds.poor_dbm] {
        chart
            .draw_series(DashedLineSeries::new(
                vec![(0.0, b), (d_max, b)],
                10,
                7,
                RGBColor(60, 60, 60).stroke_width(2),
            ))
            .map_err(pe)?;
    }
    series(&mut chart, traces, derived, &labels, &drawable, |t, k| {
        t.serving_rsrp_dbm[k]
    })?;
    legend(&mut chart)?;
    // Class names right of the plot, beside their bands.
    let plot = chart.plotting_area();
    let text = (FONT, LEGEND_PX)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (class, lo, hi, _) in bands {
        let (x, y) = plot.map_coordinate(&(d_max, 0.5 * (lo + hi)));
        let x = x + 10;
        root.draw(&Rectangle::new(
            [(x, y - 8), (x + 14, y + 8)],
            class_colour(class).filled(),
        ))
        .map_err(pe)?;
        root.draw_text(class.name(), &text, (x + 20, y))
            .map_err(pe)?;
    }
    Ok(())
}

pub(super) type Chart<'a, 'b> = ChartContext<
    'a,
    BitMapBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

pub(super) fn profile_chart<'a, 'b>(
    area: &'a Area<'b>,
    caption: &str,
    d_max: f64,
    y: std::ops::Range<f64>,
) -> Result<Chart<'a, 'b>> {
    ChartBuilder::on(area)
        .caption(caption, (FONT, CAPTION_PX))
        .margin(MARGIN)
        .margin_right(125)
        .x_label_area_size(60)
        .y_label_area_size(84)
        .build_cartesian_2d(0.0..d_max, y)
        .map_err(pe)
}

pub(super) fn mesh(chart: &mut Chart, y_desc: &str) -> Result<()> {
    chart
        .configure_mesh()
        .x_desc("distance flown (m)")
        .y_desc(y_desc)
        .x_labels(8)
        .y_labels(7)
        .x_label_formatter(&|v| fmt_num(*v))
        .y_label_formatter(&|v| fmt_num(*v))
        .label_style((FONT, LABEL_PX))
        .axis_desc_style((FONT, DESC_PX))
        .axis_style(BLACK.stroke_width(1))
        .bold_line_style(RGBColor(0, 0, 0).mix(0.12))
        .light_line_style(TRANSPARENT)
        .draw()
        .map_err(pe)
}

pub(super) fn series<'a, 'b: 'a>(
    chart: &mut Chart<'a, 'b>,
    traces: &[FlightTrace],
    derived: &[Derived],
    labels: &[String],
    drawable: &[usize],
    value: impl Fn(&FlightTrace, usize) -> f64,
) -> Result<()> {
    for &i in drawable {
        let (t, d) = (&traces[i], &derived[i]);
        let colour = trace_colour(i);
        let w = profile_width(i);
        let pts: Vec<(f64, f64)> = (0..t.points_m.len())
            .map(|k| (d.dist_m[k], value(t, k)))
            .collect();
        if pts.len() == 1 {
            chart
                .draw_series(std::iter::once(Circle::new(pts[0], 4, colour.filled())))
                .map_err(pe)?;
        }
        chart
            .draw_series(LineSeries::new(pts, colour.stroke_width(w)))
            .map_err(pe)?
            .label(labels[i].clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x - 2, y), (x + 26, y)], colour.stroke_width(w))
            });
    }
    Ok(())
}

pub(super) fn legend<'a, 'b: 'a>(chart: &mut Chart<'a, 'b>) -> Result<()> {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .margin(8)
        .legend_area_size(36)
        .label_font((FONT, LEGEND_PX))
        .background_style(WHITE.mix(0.92))
        .border_style(RGBColor(0, 0, 0).mix(0.5))
        .draw()
        .map_err(pe)
}
