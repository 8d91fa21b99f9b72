//! The left half of a plan figure: the top view of the paths over the buildings and sites,
//! each path coloured by RSRP class, with its legend. [`draw_top_view`] reads top to bottom:
//! the legend's entries, the map's frame, then each layer drawn over the last.

use super::FlightTrace;
use super::layout::{
    Area, CAPTION_H, CAPTION_PX, DESC_PX, Derived, GROUND, HEIGHT, LABEL_PX, LEFT_W, LEGEND_PX,
    MAP_X_LABEL, MAP_Y_LABEL, MARGIN, OUTLINE, ROW_H, TITLE_H, building_grey, fit_text, map_widths,
};
use super::legend::{Icon, draw_icon, draw_source, draw_star, icon_w, layout_legend};
use super::lines::{class_runs, clip_polyline, simplify, view_bounds};
use crate::draw::{clip_ring, draw_halo_text, draw_map_axes, draw_site_marker};
use crate::error::{Result, pe};
use crate::style::{FONT, class_bands, class_colour, fmt_num, trace_colour};
use dupac_common::geometry::{Bounds2, Point};
use dupac_radio::city::Building;
use dupac_radio::class::RsrpThresholds;
use dupac_radio::sites::{Site, SiteKind};
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// The legend's entries in order; `None` starts a new row.
type Items = Vec<Option<(Icon, String)>>;

/// The map's plotting area, in metres (x east, y north).
type MapArea<'a> = DrawingArea<BitMapBackend<'a>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Where the map lies on the figure: the view (m), the region below the caption and the map's
/// own box (px).
struct Frame {
    view: Bounds2,
    /// Top of the map's region (below the title strip and the caption), px.
    region_top: i32,
    /// The map's box with its axes: left edge, width and height, px.
    left: i32,
    width: i32,
    height: i32,
}

/// The plotting area in pixels: its top-left corner and size.
#[derive(Clone, Copy)]
struct Pixels {
    x: i32,
    y: i32,
    w: i32,
    h: i32,
}

impl Pixels {
    fn of(plot: &MapArea) -> Pixels {
        let (w, h) = plot.dim_in_pixel();
        let (x, y) = plot.get_base_pixel();
        Pixels {
            x,
            y,
            w: w as i32,
            h: h as i32,
        }
    }
}

/// The top view on the left half of `root`: legend entries, frame, ground and caption,
/// buildings, traces, sites, sources and destinations, the frame's border and axes, the legend.
pub(super) fn draw_top_view(
    root: &Area,
    buildings: &[Building],
    sites: &[Site],
    area_m: Bounds2,
    traces: &[FlightTrace],
    derived: &[Derived],
    thresholds: &RsrpThresholds,
) -> Result<()> {
    let legend_w = LEFT_W - 2 * MARGIN - 20;
    // Legend content first: its height decides the map's.
    let mut items = legend_items(root, traces, derived, thresholds, legend_w)?;
    let frame = frame_map(root, &items, traces, area_m, legend_w)?;
    let [vx0, vy0, vx1, vy1] = frame.view.to_array();
    let map_area = root
        .clone()
        .shrink((frame.left, frame.region_top), (frame.width, frame.height));
    let mut chart = ChartBuilder::on(&map_area)
        .margin(MARGIN)
        .x_label_area_size(MAP_X_LABEL)
        .y_label_area_size(MAP_Y_LABEL)
        .build_cartesian_2d(vx0..vx1, vy0..vy1)
        .map_err(pe)?;
    let plot = chart.plotting_area().clone();
    let px = Pixels::of(&plot);
    draw_ground_and_caption(root, px, frame.region_top)?;
    let heights = draw_buildings(&plot, buildings, frame.view)?;
    draw_traces(root, &plot, traces, frame.view, px)?;
    draw_sites(root, &plot, sites, frame.view)?;
    draw_ends(root, &plot, traces, frame.view, px)?;
    root.draw(&Rectangle::new(
        [(px.x - 1, px.y - 1), (px.x + px.w, px.y + px.h)],
        BLACK.stroke_width(1),
    ))
    .map_err(pe)?;
    draw_map_axes(&mut chart, 7, LABEL_PX, DESC_PX)?;
    draw_legend(root, &mut items, heights, legend_w, px, &frame)
}

/// The legend's entries: the RSRP classes, each trace with its length and class shares (its
/// label cut so the statistics stay readable), the markers, and the building heights (with a
/// placeholder text of the final width: the heights in view are known once the map is drawn).
fn legend_items(
    root: &Area,
    traces: &[FlightTrace],
    derived: &[Derived],
    thresholds: &RsrpThresholds,
    legend_w: i32,
) -> Result<Items> {
    let mut items: Items = class_bands(thresholds, f64::NAN, f64::NAN)
        .into_iter()
        .map(|(class, _, _, label)| Some((Icon::Class(class), label)))
        .collect();
    items.push(None);
    let legend_style = (FONT, LEGEND_PX).into_text_style(root);
    for (i, (t, d)) in traces.iter().zip(derived).enumerate() {
        let len = d.dist_m.last().copied().unwrap_or(0.0);
        let stats = if t.points_m.len() >= 2 {
            format!(
                ": {} m flown, {:.0} % excellent, {:.0} % poor",
                fmt_num(len),
                100.0 * d.share[0],
                100.0 * d.share[2]
            )
        } else {
            ": fewer than two points".into()
        };
        let (stats_w, _) = root.estimate_text_size(&stats, &legend_style).map_err(pe)?;
        let label_w = legend_w - icon_w(&Icon::Trace(i)) - 8 - stats_w as i32;
        let label = fit_text(root, &t.label, &legend_style, label_w.max(60))?;
        items.push(Some((Icon::Trace(i), label + &stats)));
        items.push(None);
    }
    items.push(Some((Icon::Source, "source".into())));
    items.push(Some((Icon::Destination, "destination".into())));
    items.push(Some((
        Icon::Site(SiteKind::Macro),
        "macro site (id)".into(),
    )));
    items.push(Some((
        Icon::Site(SiteKind::Micro),
        "micro site (id)".into(),
    )));
    items.push(Some((Icon::Heights, "building height 000 … 000 m".into())));
    Ok(items)
}

/// The map's frame: the region between the caption and the legend, the view around the traces
/// with the region's aspect, and the map (equal aspect, as large as fits) centred in the left
/// column.
fn frame_map(
    root: &Area,
    items: &Items,
    traces: &[FlightTrace],
    area_m: Bounds2,
    legend_w: i32,
) -> Result<Frame> {
    let (_, rows) = layout_legend(root, items, legend_w)?;
    let legend_h = rows * ROW_H + 14;
    let region_top = TITLE_H + CAPTION_H;
    let region_h = HEIGHT as i32 - region_top - legend_h - 8;
    let pw_max = LEFT_W - MAP_Y_LABEL - 2 * MARGIN - 14;
    let ph_max = region_h - MAP_X_LABEL - 2 * MARGIN;
    let view = view_bounds(traces, area_m, f64::from(pw_max) / f64::from(ph_max));
    let [vx0, vy0, vx1, vy1] = view.to_array();
    let aspect = (vx1 - vx0) / (vy1 - vy0);
    let (pw, ph) = if f64::from(pw_max) / f64::from(ph_max) > aspect {
        (((f64::from(ph_max) * aspect).round() as i32).max(1), ph_max)
    } else {
        (pw_max, ((f64::from(pw_max) / aspect).round() as i32).max(1))
    };
    let width = pw + MAP_Y_LABEL + 2 * MARGIN;
    let height = ph + MAP_X_LABEL + 2 * MARGIN;
    Ok(Frame {
        view,
        region_top,
        left: ((LEFT_W - width) / 2).max(0),
        width,
        height,
    })
}

/// The streets' ground under the plotting area, and the caption centred over it.
fn draw_ground_and_caption(root: &Area, px: Pixels, region_top: i32) -> Result<()> {
    root.draw(&Rectangle::new(
        [(px.x, px.y), (px.x + px.w, px.y + px.h)],
        GROUND.filled(),
    ))
    .map_err(pe)?;
    let cap = (FONT, CAPTION_PX)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Bottom));
    root.draw_text(
        "Top view, paths coloured by RSRP class",
        &cap,
        (px.x + px.w / 2, region_top + MARGIN - 6),
    )
    .map_err(pe)
}

/// The buildings in view, clipped to it, lowest first so taller ones stay on top, filled by
/// height with their holes and outlines. Returns the lowest and the tallest building's height
/// in view (m; 0 and 1 when none is).
fn draw_buildings(plot: &MapArea, buildings: &[Building], view: Bounds2) -> Result<(f64, f64)> {
    let [vx0, vy0, vx1, vy1] = view.to_array();
    let mut visible: Vec<&Building> = buildings
        .iter()
        .filter(|b| {
            let bb = b.bounds_m();
            !(bb.max_m.x < vx0 || bb.min_m.x > vx1 || bb.max_m.y < vy0 || bb.min_m.y > vy1)
        })
        .collect();
    visible.sort_by(|a, b| a.z_max_m.total_cmp(&b.z_max_m));
    let z_top = visible
        .iter()
        .map(|b| b.z_max_m)
        .fold(0.0_f64, f64::max)
        .max(1.0);
    let outline = OUTLINE.stroke_width(1);
    for b in &visible {
        let outer = clip_ring(&b.outer_m, view);
        if outer.len() < 3 {
            continue;
        }
        let pts: Vec<(f64, f64)> = outer.iter().map(|p| (p[0], p[1])).collect();
        plot.draw(&Polygon::new(
            pts.clone(),
            building_grey(b.z_max_m, z_top).filled(),
        ))
        .map_err(pe)?;
        let mut rings = vec![pts];
        for h in &b.holes_m {
            let hole = clip_ring(h, view);
            if hole.len() >= 3 {
                let hp: Vec<(f64, f64)> = hole.iter().map(|p| (p[0], p[1])).collect();
                plot.draw(&Polygon::new(hp.clone(), GROUND.filled()))
                    .map_err(pe)?;
                rings.push(hp);
            }
        }
        for mut ring in rings {
            ring.push(ring[0]);
            plot.draw(&PathElement::new(ring, outline)).map_err(pe)?;
        }
    }
    let z_low = visible
        .iter()
        .map(|b| b.z_max_m)
        .fold(f64::INFINITY, f64::min);
    let z_low = if z_low.is_finite() { z_low } else { 0.0 };
    Ok((z_low, z_top))
}

/// Each trace of two or more points, clipped to the view and simplified to the pixel: its
/// identity-coloured outline, then its class-coloured core, trace by trace.
fn draw_traces(
    root: &Area,
    plot: &MapArea,
    traces: &[FlightTrace],
    view: Bounds2,
    px: Pixels,
) -> Result<()> {
    let m_per_px = (view.max_m.x - view.min_m.x) / f64::from(px.w.max(1));
    let to_px = |line: &[(f64, f64)]| -> Vec<Vec<(i32, i32)>> {
        clip_polyline(line, view)
            .into_iter()
            .map(|piece| {
                simplify(&piece, 0.4 * m_per_px)
                    .iter()
                    .map(|p| plot.map_coordinate(p))
                    .collect()
            })
            .collect()
    };
    for (i, t) in traces.iter().enumerate() {
        if t.points_m.len() < 2 {
            continue;
        }
        let (outer, inner) = map_widths(i);
        let all: Vec<(f64, f64)> = t.points_m.iter().map(|p| (p[0], p[1])).collect();
        for piece in to_px(&all) {
            root.draw(&PathElement::new(
                piece,
                trace_colour(i).stroke_width(outer),
            ))
            .map_err(pe)?;
        }
        for (class, line) in class_runs(t) {
            for piece in to_px(&line) {
                root.draw(&PathElement::new(
                    piece,
                    class_colour(class).stroke_width(inner),
                ))
                .map_err(pe)?;
            }
        }
    }
    Ok(())
}

/// The sites in view, above the traces: each marker with its id.
fn draw_sites(root: &Area, plot: &MapArea, sites: &[Site], view: Bounds2) -> Result<()> {
    let [vx0, vy0, vx1, vy1] = view.to_array();
    let label_font = (FONT, LEGEND_PX).into_font();
    for s in sites {
        let (x, y) = (s.position_m[0], s.position_m[1]);
        if !(x >= vx0 && x <= vx1 && y >= vy0 && y <= vy1) {
            continue;
        }
        let c = plot.map_coordinate(&(x, y));
        draw_site_marker(root, c, s.kind)?;
        draw_halo_text(
            root,
            &s.id.0.to_string(),
            (c.0 + 10, c.1 - 10),
            &label_font,
            HPos::Left,
            VPos::Bottom,
        )?;
    }
    Ok(())
}

/// The ends of the traces in view, each place once: a cross where a flight ended early, a star
/// and "D" at a reached destination (left of it at the map's right edge), the source marker.
fn draw_ends(
    root: &Area,
    plot: &MapArea,
    traces: &[FlightTrace],
    view: Bounds2,
    px: Pixels,
) -> Result<()> {
    let [vx0, vy0, vx1, vy1] = view.to_array();
    let inside = |p: &Point| p[0] >= vx0 && p[0] <= vx1 && p[1] >= vy0 && p[1] <= vy1;
    let near = |drawn: &[(i32, i32)], c: (i32, i32)| {
        drawn
            .iter()
            .any(|d| (d.0 - c.0).abs() <= 4 && (d.1 - c.1).abs() <= 4)
    };
    let last_in_view = |t: &FlightTrace| {
        t.points_m
            .last()
            .filter(|p| inside(p) && t.points_m.len() >= 2)
            .map(|p| plot.map_coordinate(&(p[0], p[1])))
    };
    for c in traces
        .iter()
        .filter(|t| !t.reached)
        .filter_map(last_in_view)
    {
        let r = 9;
        for (a, b) in [((-r, -r), (r, r)), ((-r, r), (r, -r))] {
            root.draw(&PathElement::new(
                vec![(c.0 + a.0, c.1 + a.1), (c.0 + b.0, c.1 + b.1)],
                BLACK.stroke_width(4),
            ))?;
        }
    }
    let mut drawn: Vec<(i32, i32)> = Vec::new();
    for c in traces.iter().filter(|t| t.reached).filter_map(last_in_view) {
        if near(&drawn, c) {
            continue;
        }
        draw_star(root, c, 15.0, BLACK)?;
        let (x, h) = if c.0 + 40 < px.x + px.w {
            (c.0 + 16, HPos::Left)
        } else {
            (c.0 - 16, HPos::Right)
        };
        draw_halo_text(
            root,
            "D",
            (x, c.1),
            &(FONT, 22.0).into_font(),
            h,
            VPos::Center,
        )?;
        drawn.push(c);
    }
    let mut drawn_s: Vec<(i32, i32)> = Vec::new();
    for t in traces {
        if let Some(p) = t.points_m.first().filter(|p| inside(p)) {
            let c = plot.map_coordinate(&(p[0], p[1]));
            if !near(&drawn_s, c) {
                draw_source(root, c)?;
                drawn_s.push(c);
            }
        }
    }
    Ok(())
}

/// The legend below the map, aligned with the plot's left edge where there is room, its
/// building heights now those in view (`heights`: lowest and tallest, m).
fn draw_legend(
    root: &Area,
    items: &mut Items,
    heights: (f64, f64),
    legend_w: i32,
    px: Pixels,
    frame: &Frame,
) -> Result<()> {
    let (z_low, z_top) = heights;
    if let Some(Some((_, text))) = items.last_mut() {
        *text = format!("building height {} … {} m", fmt_num(z_low), fmt_num(z_top));
    }
    let (placed, _) = layout_legend(root, items, legend_w)?;
    let legend_left = (px.x - 40).max(MARGIN + 10);
    let legend_top = frame.region_top + frame.height + 4;
    let text = (FONT, LEGEND_PX)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    for (k, x, row, label) in placed {
        let Some((icon, _)) = &items[k] else {
            continue;
        };
        let (x, y) = (legend_left + x, legend_top + row * ROW_H + ROW_H / 2);
        draw_icon(root, icon, x, y, (z_low, z_top))?;
        root.draw_text(&label, &text, (x + icon_w(icon) + 8, y))
            .map_err(pe)?;
    }
    Ok(())
}
