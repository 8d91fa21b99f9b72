//! The left half of a plan figure: the top view of the paths over the buildings and sites,
//! each path coloured by RSRP class, with its legend.

use super::*;
use crate::error::Result;
use crate::{FONT, class_bands, clip_ring, draw_halo_text, draw_site_marker, fmt_num, pe};
use dupac_common::geometry::{Bounds2, Point};
use dupac_radio::city::Building;
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use dupac_radio::sites::{Site, SiteKind};
use plotters::style::text_anchor::{HPos, Pos, VPos};

/// One entry of the top view's legend.
pub(super) enum Icon {
    Class(RsrpClass),
    Trace(usize),
    Source,
    Destination,
    Site(SiteKind),
    Heights,
}

/// Width of an icon in the legend (px).
pub(super) fn icon_w(icon: &Icon) -> i32 {
    match icon {
        Icon::Class(_) => 34,
        Icon::Trace(_) => 62,
        Icon::Heights => 74,
        _ => 24,
    }
}

pub(super) fn draw_star(area: &Area, c: (i32, i32), r: f64, fill: RGBColor) -> Result<()> {
    let pts: Vec<(i32, i32)> = (0..10)
        .map(|k| {
            let rr = if k % 2 == 0 { r } else { 0.45 * r };
            let a = (90.0 + 36.0 * f64::from(k)).to_radians();
            (
                c.0 + (rr * a.cos()).round() as i32,
                c.1 - (rr * a.sin()).round() as i32,
            )
        })
        .collect();
    area.draw(&Polygon::new(pts.clone(), fill.filled()))
        .map_err(pe)?;
    let mut closed = pts;
    closed.push(closed[0]);
    area.draw(&PathElement::new(closed, WHITE.stroke_width(2)))
        .map_err(pe)?;
    Ok(())
}

pub(super) fn draw_source(area: &Area, c: (i32, i32)) -> Result<()> {
    area.draw(&Circle::new(c, 13, WHITE.filled())).map_err(pe)?;
    area.draw(&Circle::new(c, 11, BLACK.filled())).map_err(pe)?;
    let s = (FONT, 17.0)
        .into_font()
        .color(&WHITE)
        .pos(Pos::new(HPos::Center, VPos::Center));
    area.draw_text("S", &s, (c.0, c.1 + 1)).map_err(pe)?;
    Ok(())
}

pub(super) fn draw_icon(
    area: &Area,
    icon: &Icon,
    x: i32,
    y: i32,
    heights: (f64, f64),
) -> Result<()> {
    let w = icon_w(icon);
    match *icon {
        Icon::Class(c) => {
            area.draw(&PathElement::new(
                vec![(x, y), (x + w, y)],
                class_colour(c).stroke_width(8),
            ))
            .map_err(pe)?;
        }
        Icon::Trace(i) => {
            let (outer, inner) = map_widths(i);
            area.draw(&PathElement::new(
                vec![(x, y), (x + w, y)],
                trace_colour(i).stroke_width(outer),
            ))
            .map_err(pe)?;
            let third = w / 3;
            for (k, c) in crate::CLASS_COLOURS.into_iter().enumerate() {
                let k = k as i32;
                area.draw(&PathElement::new(
                    vec![(x + k * third, y), (x + (k + 1) * third, y)],
                    c.stroke_width(inner),
                ))
                .map_err(pe)?;
            }
        }
        Icon::Source => draw_source(area, (x + w / 2, y))?,
        Icon::Destination => draw_star(area, (x + w / 2, y), 13.0, BLACK)?,
        Icon::Site(kind) => draw_site_marker(area, (x + w / 2, y), kind)?,
        Icon::Heights => {
            for px in 0..w {
                let z = heights.0 + (heights.1 - heights.0) * f64::from(px) / f64::from(w - 1);
                area.draw(&Rectangle::new(
                    [(x + px, y - 9), (x + px + 1, y + 9)],
                    building_grey(z, heights.1).filled(),
                ))
                .map_err(pe)?;
            }
            area.draw(&Rectangle::new(
                [(x, y - 9), (x + w, y + 9)],
                OUTLINE.stroke_width(1),
            ))
            .map_err(pe)?;
        }
    }
    Ok(())
}

/// A legend item placed by [`layout_legend`]: item index, x offset (px), row, text as drawn.
pub(super) type Placed = (usize, i32, i32, String);

/// Lays out legend items left to right, wrapping at `width`; `None` forces a new row.
/// Texts too wide for a row are cut. Returns `(item index, x, row, text)` and the number of rows.
pub(super) fn layout_legend(
    area: &Area,
    items: &[Option<(Icon, String)>],
    width: i32,
) -> Result<(Vec<Placed>, i32)> {
    let font = (FONT, LEGEND_PX).into_text_style(area);
    let (mut x, mut row) = (0, 0);
    let mut placed = Vec::new();
    for (k, item) in items.iter().enumerate() {
        let Some((icon, text)) = item else {
            if x > 0 {
                x = 0;
                row += 1;
            }
            continue;
        };
        let text = fit_text(area, text, &font, width - icon_w(icon) - 8)?;
        let (tw, _) = area.estimate_text_size(&text, &font).map_err(pe)?;
        let w = icon_w(icon) + 8 + tw as i32;
        if x > 0 && x + w > width {
            x = 0;
            row += 1;
        }
        placed.push((k, x, row, text));
        x += w + 28;
    }
    Ok((placed, row + 1))
}

pub(super) fn draw_top_view(
    root: &Area,
    buildings: &[Building],
    sites: &[Site],
    area_m: Bounds2,
    traces: &[FlightTrace],
    derived: &[Derived],
    thresholds: &RsrpThresholds,
) -> Result<()> {
    // Legend content first: its height decides the map's.
    let mut items: Vec<Option<(Icon, String)>> = class_bands(thresholds, f64::NAN, f64::NAN)
        .into_iter()
        .map(|(class, _, _, label)| Some((Icon::Class(class), label)))
        .collect();
    items.push(None);
    let legend_w = LEFT_W - 2 * MARGIN - 20;
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
        // A long label is cut so that the statistics stay readable.
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

    // Layout: caption, map (equal aspect, as large as fits), legend below it.
    let panel_x = 0;
    // Building heights item text depends on the view, so measure with a placeholder.
    items.push(Some((Icon::Heights, "building height 000 … 000 m".into())));
    let (_, rows) = layout_legend(root, &items, legend_w)?;
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
    let map_w = pw + MAP_Y_LABEL + 2 * MARGIN;
    let map_h = ph + MAP_X_LABEL + 2 * MARGIN;
    let map_left = panel_x + ((LEFT_W - map_w) / 2).max(0);
    let map_area = root.clone().shrink((map_left, region_top), (map_w, map_h));

    let mut chart = ChartBuilder::on(&map_area)
        .margin(MARGIN)
        .x_label_area_size(MAP_X_LABEL)
        .y_label_area_size(MAP_Y_LABEL)
        .build_cartesian_2d(vx0..vx1, vy0..vy1)
        .map_err(pe)?;
    let plot = chart.plotting_area().clone();
    let (ppw, pph) = plot.dim_in_pixel();
    let (base_x, base_y) = plot.get_base_pixel();
    root.draw(&Rectangle::new(
        [(base_x, base_y), (base_x + ppw as i32, base_y + pph as i32)],
        GROUND.filled(),
    ))
    .map_err(pe)?;

    // Caption centred over the plot.
    let cap = (FONT, CAPTION_PX)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Bottom));
    root.draw_text(
        "Top view, paths coloured by RSRP class",
        &cap,
        (base_x + ppw as i32 / 2, region_top + MARGIN - 6),
    )
    .map_err(pe)?;

    // Buildings in view, lowest first so taller ones stay on top.
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

    // Traces: the identity-coloured outline, then the class-coloured core, trace by trace.
    let m_per_px = (vx1 - vx0) / f64::from(ppw.max(1));
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

    // Sites in view, above the traces.
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

    // Sources and destinations, each place once.
    let inside = |p: &Point| p[0] >= vx0 && p[0] <= vx1 && p[1] >= vy0 && p[1] <= vy1;
    let mut drawn: Vec<(i32, i32)> = Vec::new();
    let near = |drawn: &[(i32, i32)], c: (i32, i32)| {
        drawn
            .iter()
            .any(|d| (d.0 - c.0).abs() <= 4 && (d.1 - c.1).abs() <= 4)
    };
    for t in traces.iter().filter(|t| !t.reached) {
        if let Some(p) = t
            .points_m
            .last()
            .filter(|p| inside(p) && t.points_m.len() >= 2)
        {
            let c = plot.map_coordinate(&(p[0], p[1]));
            let r = 9;
            for (a, b) in [((-r, -r), (r, r)), ((-r, r), (r, -r))] {
                root.draw(&PathElement::new(
                    vec![(c.0 + a.0, c.1 + a.1), (c.0 + b.0, c.1 + b.1)],
                    BLACK.stroke_width(4),
                ))?;
            }
        }
    }
    for t in traces.iter().filter(|t| t.reached) {
        if let Some(p) = t
            .points_m
            .last()
            .filter(|p| inside(p) && t.points_m.len() >= 2)
        {
            let c = plot.map_coordinate(&(p[0], p[1]));
            if !near(&drawn, c) {
                draw_star(root, c, 15.0, BLACK)?;
                // "D" right of the star, or left of it at the right edge of the map.
                let (x, h) = if c.0 + 40 < base_x + ppw as i32 {
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
        }
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

    root.draw(&Rectangle::new(
        [
            (base_x - 1, base_y - 1),
            (base_x + ppw as i32, base_y + pph as i32),
        ],
        BLACK.stroke_width(1),
    ))
    .map_err(pe)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("x east (m)")
        .y_desc("y north (m)")
        .x_labels(7)
        .y_labels(7)
        .x_label_formatter(&|v| fmt_num(*v))
        .y_label_formatter(&|v| fmt_num(*v))
        .label_style((FONT, LABEL_PX))
        .axis_desc_style((FONT, DESC_PX))
        .axis_style(BLACK.stroke_width(1))
        .draw()
        .map_err(pe)?;

    // Legend below the map, aligned with the plot's left edge where there is room.
    let z_low = visible
        .iter()
        .map(|b| b.z_max_m)
        .fold(f64::INFINITY, f64::min);
    let z_low = if z_low.is_finite() { z_low } else { 0.0 };
    if let Some(Some((_, text))) = items.last_mut() {
        *text = format!("building height {} … {} m", fmt_num(z_low), fmt_num(z_top));
    }
    let (placed, _) = layout_legend(root, &items, legend_w)?;
    let legend_left = (base_x - 40).max(MARGIN + 10);
    let legend_top = region_top + map_h + 4;
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
