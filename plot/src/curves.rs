//! Learning-curve PNGs from the metrics rows of `dupac train`: one small panel per metric,
//! against timesteps (decisions of the policy, `env.action_repeat` environment steps each).

use crate::draw::write_png_atomic;
use crate::error::{Context, Result};
use crate::style::{FONT, ensure_font, series_colour};
use dupac_common::metric;
use plotters::prelude::*;
use std::path::Path;

/// The panels drawn: (metric key, panel title with units).
pub const PANELS: &[(&str, &str)] = &[
    (metric::EPISODIC_RETURN, "episodic return (train, last 100)"),
    (metric::TRAIN.success_rate, "success rate (train, last 100)"),
    (
        metric::EVAL.success_rate,
        "success rate (held-out pairs, deterministic)",
    ),
    (
        metric::EVAL.collision_rate,
        "collision rate (held-out pairs)",
    ),
    (
        metric::TRAIN.mean_rsrp_dbm,
        "mean serving RSRP (dBm, train)",
    ),
    (
        metric::TRAIN.pct_excellent,
        "time in excellent RSRP (%, train)",
    ),
    (
        metric::EVAL.distance_overhead,
        "distance overhead (fraction, held-out successes)",
    ),
    (metric::TRAIN.handovers_per_km, "handovers per km (train)"),
    (
        metric::EVAL.site_regret_db,
        "site regret best − serving (dB, held-out)",
    ),
    (metric::SITE_LOSS, "site loss (all-sites gradient)"),
    (metric::VALUE_LOSS, "value loss"),
    (metric::ENTROPY, "entropy (move + site, nats)"),
    (metric::APPROX_KL, "approx KL"),
    (metric::SPS, "timesteps (decisions) per second"),
];

/// Draws the panels of [`PANELS`] that have data into `path` (atomically). `points(key)`: the
/// metric's (timesteps, value) points, in order (e.g. a run's `metrics.csv` columns
/// `global_step` and `key`).
pub fn render_curves(
    points: &dyn Fn(&str) -> Vec<(f64, f64)>,
    title: &str,
    path: &Path,
) -> Result<()> {
    ensure_font()?;
    write_png_atomic(path, |tmp| draw(points, title, tmp))
        .with_context(|| format!("cannot write learning curves {}", path.display()))
}

fn draw(points: &dyn Fn(&str) -> Vec<(f64, f64)>, title: &str, tmp: &Path) -> Result<()> {
    let root = BitMapBackend::new(tmp, (1800, 1700)).into_drawing_area();
    root.fill(&WHITE)?;
    let (head, body) = root.split_vertically(50);
    head.draw_text(title, &(FONT, 26).into_font().color(&BLACK), (20, 12))?;
    let cells = body.split_evenly((4, 4));
    for (cell, (key, label)) in cells.iter().zip(PANELS) {
        let pts = points(key);
        let x_max = pts.iter().map(|p| p.0).fold(1.0, f64::max);
        let (mut y_min, mut y_max) = pts
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.1), b.max(p.1))
            });
        if !y_min.is_finite() {
            (y_min, y_max) = (0.0, 1.0);
        }
        if (y_max - y_min).abs() < 1e-9 {
            y_min -= 0.5;
            y_max += 0.5;
        }
        let pad = 0.05 * (y_max - y_min);
        let mut chart = ChartBuilder::on(cell)
            .caption(*label, (FONT, 17))
            .margin(8)
            .x_label_area_size(34)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..x_max, (y_min - pad)..(y_max + pad))?;
        chart
            .configure_mesh()
            .x_desc("timesteps (policy decisions)")
            .label_style((FONT, 12))
            .x_label_formatter(&|x| format_steps(*x))
            .x_labels(5)
            .y_labels(5)
            .draw()?;
        if pts.is_empty() {
            continue;
        }
        chart.draw_series(LineSeries::new(
            pts.iter().copied(),
            series_colour(0).stroke_width(2),
        ))?;
        if pts.len() < 40 {
            chart.draw_series(
                pts.iter()
                    .map(|&p| Circle::new(p, 3, series_colour(0).filled())),
            )?;
        }
    }
    root.present()?;
    Ok(())
}

fn format_steps(x: f64) -> String {
    if x >= 1e6 {
        format!("{:.1}M", x / 1e6)
    } else if x >= 1e3 {
        format!("{:.0}k", x / 1e3)
    } else {
        format!("{x:.0}")
    }
}
