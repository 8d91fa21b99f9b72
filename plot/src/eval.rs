//! The evaluation's figures (`dupac eval`): the paper's Fig. 3 (distance and overhead
//! per bin) and Fig. 4 (RSRP and class fractions per bin), the Pareto plot of distance
//! overhead against time in excellent RSRP, and example flights over the city. Drawn from the
//! statistics of `dupac_eval::report`, thresholds from the configuration.

use super::plan::{FlightTrace, render_world_plan};
use crate::draw::write_png_atomic;
use crate::error::{Context, Result};
use crate::style::{CLASS_COLOURS, FONT, series_colour};
use dupac_common::fsio::write_atomic_with;
use dupac_common::geometry::Point;
use dupac_common::msg::Outcome;
use dupac_eval::front::{FrontFile, FrontMeasures, FrontRow, FrontRule, front_rows, own_points};
use dupac_eval::interval::MeanCi;
use dupac_eval::metrics::FlightMetrics;
use dupac_eval::records::RecordsFile;
use dupac_eval::report::MethodData;
use plotters::prelude::*;
use std::path::Path;

pub fn draw_fig3(out: &Path, data: &[MethodData], bins: &[f64]) -> Result<()> {
    let path = out.join("fig3.png");
    write_png_atomic(&path, |tmp| {
        let root = BitMapBackend::new(tmp, (1800, 620)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((1, 3));
        type Pick = fn(&FlightMetrics) -> f64;
        let specs: [(&str, Pick, f64); 3] = [
            ("flight distance (m)", |m| m.distance_m, 1.0),
            (
                "distance overhead over the shortest path (%)",
                |m| m.overhead,
                100.0,
            ),
            ("mean serving RSRP (dBm)", |m| m.mean_rsrp_dbm, 1.0),
        ];
        let (x0, x1) = (
            bins.first().copied().unwrap_or(0.0) - 50.0,
            bins.last().copied().unwrap_or(1.0) + 50.0,
        );
        for (panel, (title, pick, scale)) in panels.iter().zip(specs) {
            let series: Vec<(String, Vec<(f64, MeanCi)>)> = data
                .iter()
                .map(|d| {
                    (
                        d.label.clone(),
                        bins.iter().map(|&b| (b, d.ci(Some(b), pick))).collect(),
                    )
                })
                .collect();
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for (_, pts) in &series {
                for (_, c) in pts.iter().filter(|(_, c)| c.n > 0) {
                    let h = if c.half_width.is_nan() {
                        0.0
                    } else {
                        c.half_width
                    };
                    lo = lo.min((c.mean - h) * scale);
                    hi = hi.max((c.mean + h) * scale);
                }
            }
            if !lo.is_finite() {
                (lo, hi) = (0.0, 1.0);
            }
            let pad = 0.05 * (hi - lo).max(1e-6);
            let mut chart = ChartBuilder::on(panel)
                .caption(title, (FONT, 20))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(x0..x1, (lo - pad)..(hi + pad))?;
            chart
                .configure_mesh()
                .x_desc("shortest flyable distance D (m)")
                .label_style((FONT, 14))
                .draw()?;
            for (k, (label, pts)) in series.iter().enumerate() {
                let c = series_colour(k);
                let dx = (k as f64 - series.len() as f64 / 2.0) * 4.0;
                let good: Vec<(f64, MeanCi)> =
                    pts.iter().copied().filter(|(_, c)| c.n > 0).collect();
                chart
                    .draw_series(LineSeries::new(
                        good.iter().map(|(b, m)| (b + dx, m.mean * scale)),
                        c.stroke_width(2),
                    ))?
                    .label(label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(3))
                    });
                chart.draw_series(good.iter().filter(|(_, m)| m.half_width.is_finite()).map(
                    |(b, m)| {
                        vbar(
                            b + dx,
                            (m.mean - m.half_width) * scale,
                            (m.mean + m.half_width) * scale,
                            c.filled(),
                        )
                    },
                ))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font((FONT, 13))
                .position(SeriesLabelPosition::UpperLeft)
                .draw()?;
        }
        root.present()?;
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))
}

pub fn draw_fig4(out: &Path, data: &[MethodData], bins: &[f64]) -> Result<()> {
    let path = out.join("fig4.png");
    write_png_atomic(&path, |tmp| {
        let root = BitMapBackend::new(tmp, (1800, 700)).into_drawing_area();
        root.fill(&WHITE)?;
        let nm = data.len().max(1) as f64;
        let group = nm + 1.0;
        // One group's width of room on the right for the legend.
        let x_max = (bins.len() as f64 + 1.7) * group;
        let mut chart = ChartBuilder::on(&root)
            .caption("Fig. 4: fraction of flight time per RSRP class (successful flights); bars per method, groups per distance bin", (FONT, 20))
            .margin(14)
            .x_label_area_size(70)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..x_max, 0.0..106.0)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .y_desc("flight time (%)")
            .x_desc("groups of bars: one per distance bin (labelled above), one bar per method")
            .x_labels(0)
            .label_style((FONT, 14))
            .draw()?;
        for (bi, &b) in bins.iter().enumerate() {
            chart.draw_series(std::iter::once(Text::new(
                format!("D ≈ {b:.0} m"),
                (bi as f64 * group + 0.5, 104.5),
                (FONT, 15),
            )))?;
            for (mi, d) in data.iter().enumerate() {
                let x = bi as f64 * group + mi as f64 + 0.5;
                let f = [0, 1, 2].map(|k| d.ci(Some(b), |m| m.frac_class[k]).mean);
                if f.iter().any(|v| v.is_nan()) {
                    continue;
                }
                let mut y = 0.0;
                for (k, v) in f.iter().enumerate() {
                    let top = y + 100.0 * v;
                    chart.draw_series(std::iter::once(Rectangle::new([(x, y), (x + 0.9, top)], CLASS_COLOURS[k].filled())))?;
                    y = top;
                }
                // Method marker under each bar: its colour.
                chart.draw_series(std::iter::once(Rectangle::new([(x, 0.0), (x + 0.9, 1.5)], series_colour(mi).filled())))?;
            }
        }
        for (k, name) in ["excellent (≥ −80 dBm)", "mediocre", "poor (< −100 dBm)"].iter().enumerate() {
            let c = CLASS_COLOURS[k];
            chart
                .draw_series(std::iter::once(Rectangle::new([(0.0, 0.0), (0.0, 0.0)], c.filled())))?
                .label(*name)
                .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 14, y + 6)], c.filled()));
        }
        for (mi, d) in data.iter().enumerate() {
            let c = series_colour(mi);
            chart
                .draw_series(std::iter::once(Rectangle::new([(0.0, 0.0), (0.0, 0.0)], c.filled())))?
                .label(format!("bar {}: {}", mi + 1, d.label))
                .legend(move |(x, y)| Rectangle::new([(x, y - 3), (x + 14, y + 3)], c.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font((FONT, 13))
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;
        root.present()?;
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))
}

pub fn draw_pareto(out: &Path, data: &[MethodData]) -> Result<()> {
    let path = out.join("pareto.png");
    let pts: Vec<(String, MeanCi, MeanCi)> = data
        .iter()
        .map(|d| {
            (
                d.label.clone(),
                d.ci(None, |m| m.overhead),
                d.ci(None, |m| m.frac_class[0]),
            )
        })
        .filter(|(_, o, e)| o.n > 0 && e.n > 0)
        .collect();
    write_atomic_with(&out.join("pareto.csv"), |w| {
        writeln!(
            w,
            "method,overhead_pct,overhead_ci_pct,pct_excellent,pct_excellent_ci"
        )?;
        for (l, o, e) in &pts {
            writeln!(
                w,
                "{l},{},{},{},{}",
                100.0 * o.mean,
                100.0 * o.half_width,
                100.0 * e.mean,
                100.0 * e.half_width
            )?;
        }
        Ok(())
    })?;
    write_png_atomic(&path, |tmp| {
        let root = BitMapBackend::new(tmp, (1100, 800)).into_drawing_area();
        root.fill(&WHITE)?;
        let hw = |c: &MeanCi| {
            if c.half_width.is_finite() {
                c.half_width
            } else {
                0.0
            }
        };
        let x_hi = pts
            .iter()
            .map(|(_, o, _)| 100.0 * (o.mean + hw(o)))
            .fold(1.0, f64::max)
            * 1.1;
        let x_lo = pts
            .iter()
            .map(|(_, o, _)| 100.0 * (o.mean - hw(o)))
            .fold(0.0, f64::min)
            - 0.04 * x_hi;
        let y_lo = pts
            .iter()
            .map(|(_, _, e)| 100.0 * (e.mean - hw(e)))
            .fold(100.0, f64::min)
            .max(0.0)
            - 5.0;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Distance overhead against time in excellent RSRP (successful flights, 95 % CI)",
                (FONT, 20),
            )
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(x_lo..x_hi, y_lo.max(0.0)..100.0)?;
        chart
            .configure_mesh()
            .x_desc("distance overhead over the shortest path (%)")
            .y_desc("flight time in excellent RSRP (%)")
            .label_style((FONT, 14))
            .draw()?;
        for (k, (label, o, e)) in pts.iter().enumerate() {
            let c = series_colour(k);
            let (x, y) = (100.0 * o.mean, 100.0 * e.mean);
            chart.draw_series(std::iter::once(hbar(
                y,
                x - 100.0 * hw(o),
                x + 100.0 * hw(o),
                c.filled(),
            )))?;
            chart.draw_series(std::iter::once(vbar(
                x,
                y - 100.0 * hw(e),
                y + 100.0 * hw(e),
                c.filled(),
            )))?;
            chart
                .draw_series(std::iter::once(Circle::new((x, y), 7, c.filled())))?
                .label(label.as_str())
                .legend(move |(x, y)| Circle::new((x + 7, y), 6, c.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font((FONT, 14))
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;
        root.present()?;
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))
}

/// A vertical error bar at `x` from `lo` to `hi` (data units).
fn vbar(x: f64, lo: f64, hi: f64, style: ShapeStyle) -> PathElement<(f64, f64)> {
    PathElement::new(vec![(x, lo), (x, hi)], style.stroke_width(2))
}

/// A horizontal error bar at `y` from `lo` to `hi` (data units).
fn hbar(y: f64, lo: f64, hi: f64, style: ShapeStyle) -> PathElement<(f64, f64)> {
    PathElement::new(vec![(lo, y), (hi, y)], style.stroke_width(2))
}

/// Example flights over the city (top view, altitude profile, RSRP along the way, coloured by
/// class): for the shortest, a middle and the longest bin, the first pair of that bin, every
/// method's seed-0 flight, the coverage-aware planner at λ = 1 only (`example_pair<ID>.png`).
pub fn draw_examples(
    out: &Path,
    world: &dupac_radio::world::RadioWorld,
    files: &[RecordsFile],
    radio: &dupac_common::config::RadioConfig,
) -> Result<()> {
    // Seed 0 of every method; of the coverage-aware sweep only λ = 1 (readability).
    let seed0: Vec<&RecordsFile> = files
        .iter()
        .filter(|f| {
            f.seed == 0 && (!f.method.starts_with("coverage_l") || f.method == "coverage_l1")
        })
        .collect();
    let Some(first) = seed0.first() else {
        return Ok(());
    };
    let mut bins: Vec<f64> = first.flights.iter().map(|f| f.bin_m).collect();
    bins.sort_by(f64::total_cmp);
    bins.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    let mut picks: Vec<f64> = [0, bins.len() / 2, bins.len().saturating_sub(1)]
        .iter()
        .filter_map(|&i| bins.get(i).copied())
        .collect();
    picks.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    for b in picks {
        let Some(pair) = first.flights.iter().find(|f| (f.bin_m - b).abs() < 1e-6) else {
            continue;
        };
        let mut traces = Vec::new();
        for f in &seed0 {
            let Some(r) = f.flights.iter().find(|r| r.pair_id == pair.pair_id) else {
                continue;
            };
            if r.steps.is_empty() {
                continue;
            }
            let mut t = FlightTrace {
                label: format!("{} ({:?})", r.method, r.outcome).to_lowercase(),
                points_m: vec![r.source_m],
                serving_rsrp_dbm: vec![],
                class: vec![],
                reached: r.outcome == Outcome::Goal,
            };
            // At the source: the first step's values (one step away at most).
            t.serving_rsrp_dbm
                .push(f64::from(r.steps[0].serving_rsrp_dbm));
            t.class.push(r.steps[0].class);
            for s in &r.steps {
                t.points_m.push(Point::from(s.position_m.map(f64::from)));
                t.serving_rsrp_dbm.push(f64::from(s.serving_rsrp_dbm));
                t.class.push(s.class);
            }
            if t.serving_rsrp_dbm.iter().all(|v| v.is_finite()) {
                traces.push(t);
            }
        }
        if traces.is_empty() {
            continue;
        }
        let title = format!(
            "held-out pair {} (bin {:.0} m): shortest flyable {:.0} m, straight {:.0} m; colour = RSRP class",
            pair.pair_id, pair.bin_m, pair.shortest_m, pair.straight_m
        );
        let png = out.join(format!("example_pair{}.png", pair.pair_id));
        render_world_plan(world, radio, &traces, &title, &png)?;
    }
    Ok(())
}

/// `fronts.png`: time in excellent RSRP against handovers per km, one colour per method. Each
/// policy of the records and each planner with a front as a triangle (its own flights); A3's
/// front on the same flights (every setting of the grid, `front.csv`) as small dots and a solid
/// line through its upper envelope, an envelope point whose excellent time is bought by
/// ping-pongs (`pp_marked`) as a hollow ring; the predictive association's front as a dashed
/// line with squares and the hindsight association's (a bound: perfect foresight) as a finely
/// dashed line with crosses, through their settings in order of handovers; one policy flown at
/// several handover weights (`LABEL_w<W>`) joined by a black line, the learned front, its
/// points marked with their weight. A policy's weights share one colour and one
/// legend entry per rule.
pub fn draw_fronts(out: &Path, files: &[RecordsFile], fronts: &[FrontFile]) -> Result<()> {
    let rows = front_rows(fronts);
    // The policies of the records (a learned front is several of them: DUPAC at several handover
    // weights), then the methods whose flights have a front, each with its own point.
    let points = own_points(files, &rows);
    let methods: Vec<&str> = points.iter().map(|(l, _)| l.as_str()).collect();
    let own: Vec<(String, FrontMeasures)> = points
        .iter()
        .filter_map(|(l, m)| m.map(|m| (l.clone(), m)))
        .collect();
    let xs = rows
        .iter()
        .map(|r| r.measures.handovers_per_km)
        .chain(own.iter().map(|(_, m)| m.handovers_per_km))
        .filter(|x| x.is_finite());
    let x_hi = xs.fold(1.0, f64::max) * 1.08;
    let ys = rows
        .iter()
        .map(|r| r.measures.excellent_pct)
        .chain(own.iter().map(|(_, m)| m.excellent_pct))
        .filter(|y| y.is_finite());
    let y_lo = (ys.fold(100.0, f64::min) - 2.0).max(0.0);
    let xy = |r: &FrontRow| (r.measures.handovers_per_km, r.measures.excellent_pct);
    write_png_atomic(&out.join("fronts.png"), |tmp| {
        let root = BitMapBackend::new(tmp, (1100, 800)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Excellent RSRP against handovers on the same flights: A3 (solid; ring: bought by ping-pongs), predictive (dashed), hindsight (fine dashes, a bound)",
                (FONT, 16),
            )
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..x_hi, y_lo..100.0)?;
        chart
            .configure_mesh()
            .x_desc("handovers per km")
            .y_desc("flight time in excellent RSRP (%, successful flights)")
            .label_style((FONT, 14))
            .draw()?;
        // One colour per family (a policy flown at several handover weights is one family), one
        // legend entry per family and rule.
        let mut families: Vec<&str> = Vec::new();
        for m in &methods {
            if !families.contains(&family(m)) {
                families.push(family(m));
            }
        }
        let mut labelled = std::collections::BTreeSet::new();
        for method in &methods {
            let fam = family(method);
            let c = series_colour(families.iter().position(|f| *f == fam).unwrap_or(0));
            let mut weights: Vec<&str> = methods
                .iter()
                .filter_map(|m| weighted(m))
                .filter(|(policy, _)| *policy == fam)
                .map(|(_, w)| w)
                .collect();
            weights.sort_by(|a, b| {
                let w = |s: &str| s.parse::<f64>().unwrap_or(f64::INFINITY);
                w(a).total_cmp(&w(b))
            });
            let mut first = |rule: &'static str| labelled.insert((fam, rule));
            if let Some((_, m)) = own.iter().find(|(l, _)| l == method) {
                let p = (m.handovers_per_km, m.excellent_pct);
                let weight = weighted(method);
                if let Some((_, w)) = weight {
                    chart.draw_series(std::iter::once(
                        EmptyElement::at(p) + Text::new(format!("w{w}"), (8, -16), (FONT, 12)),
                    ))?;
                }
                let s = chart.draw_series(std::iter::once(TriangleMarker::new(p, 9, c.filled())))?;
                if first("own") {
                    let label = match weight {
                        Some(_) => format!("{fam} at w = {} (its own flights)", weights.join(", ")),
                        None => format!("{method} ({:.2} ping-pongs/km)", m.ping_pongs_per_km),
                    };
                    s.label(label)
                        .legend(move |(x, y)| TriangleMarker::new((x + 9, y), 6, c.filled()));
                }
            }
            let of = |rule: FrontRule| -> Vec<&FrontRow> {
                let mut v: Vec<&FrontRow> = rows
                    .iter()
                    .filter(|r| r.method == *method && r.rule == rule)
                    .collect();
                v.sort_by(|a, b| {
                    a.measures
                        .handovers_per_km
                        .total_cmp(&b.measures.handovers_per_km)
                });
                v
            };
            let a3 = of(FrontRule::A3);
            if !a3.is_empty() {
                chart.draw_series(
                    a3.iter()
                        .filter(|r| !r.on_front)
                        .map(|r| Circle::new(xy(r), 2, c.mix(0.3).filled())),
                )?;
                let env: Vec<&&FrontRow> = a3.iter().filter(|r| r.on_front).collect();
                let s = chart
                    .draw_series(LineSeries::new(env.iter().map(|r| xy(r)), c.stroke_width(2)))?;
                if first("a3") {
                    s.label(format!("A3 on {fam}'s flights")).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                    });
                }
                chart.draw_series(env.iter().map(|r| {
                    if r.pp_marked {
                        Circle::new(xy(r), 6, c.stroke_width(2))
                    } else {
                        Circle::new(xy(r), 3, c.filled())
                    }
                }))?;
            }
            let predictive = of(FrontRule::Predictive);
            if !predictive.is_empty() {
                let pts: Vec<(f64, f64)> = predictive.iter().map(|r| xy(r)).collect();
                let s = chart.draw_series(DashedLineSeries::new(
                    pts.clone(),
                    10,
                    6,
                    c.stroke_width(2),
                ))?;
                if first("predictive") {
                    s.label(format!("predictive on {fam}'s flights"))
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 8, y)], c.stroke_width(2))
                        });
                }
                chart.draw_series(pts.iter().map(|&p| {
                    EmptyElement::at(p) + Rectangle::new([(-4, -4), (4, 4)], c.filled())
                }))?;
            }
            let hindsight = of(FrontRule::Hindsight);
            if !hindsight.is_empty() {
                let pts: Vec<(f64, f64)> = hindsight.iter().map(|r| xy(r)).collect();
                let s =
                    chart.draw_series(DashedLineSeries::new(pts.clone(), 3, 4, c.stroke_width(2)))?;
                if first("hindsight") {
                    s.label(format!("hindsight on {fam}'s flights (a bound)"))
                        .legend(move |(x, y)| Cross::new((x + 9, y), 5, c.stroke_width(2)));
                }
                chart.draw_series(pts.iter().map(|&p| Cross::new(p, 5, c.stroke_width(2))))?;
            }
        }
        // One policy flown at several handover weights (`LABEL_w<W>`, `dupac eval
        // --handover-weight`): its points joined, the learned front.
        let mut learned: std::collections::BTreeMap<&str, Vec<(f64, f64)>> = Default::default();
        for (label, m) in &own {
            if let Some((policy, _)) = weighted(label) {
                learned
                    .entry(policy)
                    .or_default()
                    .push((m.handovers_per_km, m.excellent_pct));
            }
        }
        for (policy, mut points) in learned {
            if points.len() < 2 {
                continue;
            }
            points.sort_by(|a, b| a.0.total_cmp(&b.0));
            chart
                .draw_series(LineSeries::new(points, BLACK.stroke_width(2)))?
                .label(format!("{policy}'s front (one policy, several weights)"))
                .legend(|(x, y)| {
                    PathElement::new(vec![(x, y), (x + 18, y)], BLACK.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerRight)
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .draw()?;
        root.present()?;
        Ok(())
    })
    .with_context(|| "writing fronts.png".to_string())
}

/// A method flown at one handover weight (`LABEL_w<W>`, `dupac eval --handover-weight`): its
/// policy's label and the weight as written; `None` for any other method.
fn weighted(label: &str) -> Option<(&str, &str)> {
    label
        .rsplit_once("_w")
        .filter(|(_, w)| w.parse::<f64>().is_ok())
}

/// The family of method `label` in `fronts.png`: a policy flown at several handover weights
/// (`LABEL_w<W>`) is `LABEL`; any other method is its own.
fn family(label: &str) -> &str {
    weighted(label).map_or(label, |(policy, _)| policy)
}

#[cfg(test)]
mod tests;
