//! The top view's legend: its entries (RSRP classes, traces, markers, building heights), their
//! icons, the markers the map shares with them (source, destination), and their layout in rows.

use super::layout::{Area, LEGEND_PX, OUTLINE, building_grey, fit_text, map_widths};
use crate::draw::draw_site_marker;
use crate::error::{Result, pe};
use crate::style::{CLASS_COLOURS, FONT, class_colour, trace_colour};
use dupac_radio::class::RsrpClass;
use dupac_radio::sites::SiteKind;
use plotters::prelude::*;
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

/// A five-pointed star of outer radius `r` px centred at pixel `c`, outlined in white.
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

/// The source marker (a black disc with a white "S") centred at pixel `c`.
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

/// The legend's icon of `icon` at pixel (`x`, `y`) (its left end, centred vertically);
/// `heights`: the lowest and tallest building in view (m), for the heights ramp.
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
            for (k, c) in CLASS_COLOURS.into_iter().enumerate() {
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
