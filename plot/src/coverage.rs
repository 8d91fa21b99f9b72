//! Coverage maps as PNG (paper Fig. 2(b)): a best-server RSRP heatmap of one horizontal
//! slice with building footprints, sites, axes in metres (equal aspect) and a colour bar.
//!
//! The colour scale is fixed to −130 … −50 dBm (viridis) so that maps at different altitudes are
//! comparable; the RSRP class boundaries −80 and −100 dBm (spec/radio.md §3, the defaults of
//! `radio.rsrp_excellent_dbm` / `radio.rsrp_poor_dbm`) are marked on the colour bar.

use crate::draw::{clip_ring, draw_halo_text, draw_map_axes, draw_site_marker, write_png_atomic};
use crate::error::{Context, PlotError, Result, pe};
use crate::style::{FONT, class_bands, ensure_font, fmt_num};
use dupac_common::geometry::Bounds2;
use dupac_radio::city::Building;
use dupac_radio::class::RsrpThresholds;
use dupac_radio::coverage::CoverageSlice;
use dupac_radio::sites::{Site, SiteKind};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::FontTransform;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// Lower end of the colour scale (dBm); weaker values are drawn in its colour.
pub const RSRP_SCALE_MIN_DBM: f64 = -130.0;
/// Upper end of the colour scale (dBm); stronger values are drawn in its colour.
pub const RSRP_SCALE_MAX_DBM: f64 = -50.0;

/// Image width and largest height (px); the height shrinks for areas wider than tall.
const WIDTH: u32 = 1400;
const HEIGHT: u32 = 1200;
/// Smallest image height (px), room for the colour bar and legend.
const MIN_HEIGHT: u32 = 760;
/// White space below the map (px).
const BOTTOM_PAD: i32 = 10;
/// Width of the column right of the map holding colour bar and legend (px).
const SIDE_W: i32 = 270;
/// Chart margin and axis label areas (px).
const MARGIN: i32 = 14;
const X_LABEL_AREA: i32 = 78;
const Y_LABEL_AREA: i32 = 100;
const TITLE_PX: f64 = 32.0;
/// Height of the title strip (px).
const TITLE_H: i32 = 64;
const LABEL_PX: f64 = 21.0;
const DESC_PX: f64 = 25.0;
const SMALL_PX: f64 = 19.0;

const NAN_GREY: RGBColor = RGBColor(150, 150, 150);
const OUTSIDE_GRID: RGBColor = RGBColor(235, 235, 235);
const OUTLINE: RGBColor = RGBColor(35, 35, 35);
const TALL_FILL: RGBColor = RGBColor(70, 70, 70);
const TALL_ALPHA: f64 = 0.45;

/// Matplotlib's viridis at 0, 0.1, …, 1 (perceptually uniform, colour-blind safe).
const VIRIDIS: [[u8; 3]; 11] = [
    [68, 1, 84],
    [72, 36, 117],
    [65, 68, 135],
    [53, 95, 141],
    [42, 120, 142],
    [33, 145, 140],
    [34, 168, 132],
    [68, 191, 112],
    [122, 209, 81],
    [189, 223, 38],
    [253, 231, 37],
];

/// Viridis colour of `t ∈ [0, 1]` (clamped), linear between the anchors.
fn viridis(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let s = t * (VIRIDIS.len() - 1) as f64;
    let i = (s.floor() as usize).min(VIRIDIS.len() - 2);
    let f = s - i as f64;
    let (a, b) = (VIRIDIS[i], VIRIDIS[i + 1]);
    let mix = |k: usize| (f64::from(a[k]) + f * (f64::from(b[k]) - f64::from(a[k]))).round() as u8;
    RGBColor(mix(0), mix(1), mix(2))
}

/// Colour of an RSRP value (dBm) on the fixed scale; NaN (inside a building) is grey.
fn rsrp_colour(rsrp_dbm: f64) -> RGBColor {
    if rsrp_dbm.is_nan() {
        return NAN_GREY;
    }
    viridis((rsrp_dbm - RSRP_SCALE_MIN_DBM) / (RSRP_SCALE_MAX_DBM - RSRP_SCALE_MIN_DBM))
}
/// Renders one coverage slice to a PNG 1400 px wide and up to 1200 px high at `path` (written to a temporary file
/// in the same directory, then renamed).
///
/// * `slice` — best-server RSRP (dBm) on a regular grid; NaN cells (inside buildings) are grey.
/// * `buildings` — footprints drawn as thin outlines; those that occupy the slice altitude
///   (`z_min_m ≤ altitude < z_max_m`) are also filled semi-transparent grey.
/// * `sites` — triangles for macro sites, circles for micro sites, labelled with the site index.
/// * `area_m` — the flight area (m): the axis ranges; the map
///   has an equal aspect ratio (1 m in x is as long as 1 m in y).
/// * `title` — drawn above the map.
pub fn render_coverage_png(
    slice: &CoverageSlice,
    buildings: &[Building],
    sites: &[Site],
    area_m: Bounds2,
    thresholds: &RsrpThresholds,
    title: &str,
    path: &Path,
) -> Result<()> {
    let corners = area_m.to_array();
    let [x_min, y_min, x_max, y_max] = corners;
    if !(corners.iter().all(|v| v.is_finite()) && x_max > x_min && y_max > y_min) {
        return Err(PlotError::Invalid(format!(
            "cannot plot {}: flight area {area_m} is empty or not finite",
            path.display()
        )));
    }
    let expected = slice.nx.checked_mul(slice.ny);
    if expected != Some(slice.rsrp_dbm.len()) {
        return Err(PlotError::Invalid(format!(
            "cannot plot {}: coverage slice has {} values for a {}×{} grid",
            path.display(),
            slice.rsrp_dbm.len(),
            slice.nx,
            slice.ny
        )));
    }
    ensure_font()?;

    write_png_atomic(path, |tmp| {
        draw(slice, buildings, sites, area_m, thresholds, title, tmp)
    })
    .with_context(|| format!("cannot write coverage map {}", path.display()))
}

/// Draws the whole figure into `file` (a .png path).
fn draw(
    slice: &CoverageSlice,
    buildings: &[Building],
    sites: &[Site],
    area_m: Bounds2,
    thresholds: &RsrpThresholds,
    title: &str,
    file: &Path,
) -> Result<()> {
    let [x_min, y_min, x_max, y_max] = area_m.to_array();
    // Layout first (pure arithmetic): a plot area of equal aspect, as large as fits next to the
    // side column in WIDTH × HEIGHT; the canvas is then cut to the map's height (≥ MIN_HEIGHT).
    let body_w = WIDTH as i32;
    let pw_max = (body_w - SIDE_W - Y_LABEL_AREA - 2 * MARGIN - 10).max(50);
    let ph_max = (HEIGHT as i32 - TITLE_H - BOTTOM_PAD - X_LABEL_AREA - 2 * MARGIN).max(50);
    let aspect = (x_max - x_min) / (y_max - y_min);
    let (pw, ph) = if f64::from(pw_max) / f64::from(ph_max) > aspect {
        (((f64::from(ph_max) * aspect).round() as i32).max(1), ph_max)
    } else {
        (pw_max, ((f64::from(pw_max) / aspect).round() as i32).max(1))
    };
    let map_w = pw + Y_LABEL_AREA + 2 * MARGIN;
    let map_h = ph + X_LABEL_AREA + 2 * MARGIN;
    let canvas_h = (TITLE_H + map_h + BOTTOM_PAD).clamp(MIN_HEIGHT as i32, HEIGHT as i32);
    let left = ((body_w - map_w - SIDE_W) / 2).max(0);
    let top = ((canvas_h - TITLE_H - BOTTOM_PAD - map_h) / 2).max(0);

    let root = BitMapBackend::new(file, (WIDTH, canvas_h as u32)).into_drawing_area();
    root.fill(&WHITE).map_err(pe)?;
    let (title_area, body) = root.split_vertically(TITLE_H);
    // The title, shrunk until it fits the width.
    let mut size = TITLE_PX;
    while size > 14.0 {
        let (w, _) = title_area
            .estimate_text_size(title, &(FONT, size).into_text_style(&title_area))
            .map_err(pe)?;
        if w + 40 <= WIDTH {
            break;
        }
        size -= 2.0;
    }
    let title_style = (FONT, size)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Center));
    title_area
        .draw_text(title, &title_style, (WIDTH as i32 / 2, TITLE_H / 2 + 4))
        .map_err(pe)?;
    let map_area = body.clone().shrink((left, top), (map_w, map_h));
    let side = body.clone().shrink((left + map_w, top), (SIDE_W, map_h));

    let mut chart = ChartBuilder::on(&map_area)
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(x_min..x_max, y_min..y_max)
        .map_err(pe)?;
    let plot = chart.plotting_area();
    let (pw, ph) = plot.dim_in_pixel();
    let (base_x, base_y) = plot.get_base_pixel();

    // Heatmap: one pixel at a time into an RGB buffer, blitted in one go.
    let mut buf = vec![0u8; pw as usize * ph as usize * 3];
    let (dx, dy) = (
        (x_max - x_min) / f64::from(pw),
        (y_max - y_min) / f64::from(ph),
    );
    let res = slice.resolution_m;
    for py in 0..ph as usize {
        let y = y_max - (py as f64 + 0.5) * dy;
        let fy = (y - slice.y0_m) / res;
        for px in 0..pw as usize {
            let x = x_min + (px as f64 + 0.5) * dx;
            let fx = (x - slice.x0_m) / res;
            let c = if res > 0.0
                && fx >= 0.0
                && fy >= 0.0
                && (fx as usize) < slice.nx
                && (fy as usize) < slice.ny
            {
                rsrp_colour(f64::from(
                    slice.rsrp_dbm[fy as usize * slice.nx + fx as usize],
                ))
            } else {
                OUTSIDE_GRID
            };
            let k = (py * pw as usize + px) * 3;
            buf[k..k + 3].copy_from_slice(&[c.0, c.1, c.2]);
        }
    }
    let bitmap = BitMapElement::with_owned_buffer((base_x, base_y), (pw, ph), buf)
        .ok_or_else(|| PlotError::Invalid("heatmap buffer has the wrong size".into()))?;
    root.draw(&bitmap).map_err(pe)?;

    // Buildings, clipped to the area.
    let clip = area_m;
    let tall_style = TALL_FILL.mix(TALL_ALPHA).filled();
    let outline_style = OUTLINE.stroke_width(1);
    for b in buildings {
        let bb = b.bounds_m();
        if bb.max_m.x < x_min || bb.min_m.x > x_max || bb.max_m.y < y_min || bb.min_m.y > y_max {
            continue;
        }
        let tall = b.z_min_m <= slice.altitude_m && slice.altitude_m < b.z_max_m;
        let outer = clip_ring(&b.outer_m, clip);
        if outer.len() < 3 {
            continue;
        }
        let pts: Vec<(f64, f64)> = outer.iter().map(|p| (p[0], p[1])).collect();
        if tall {
            plot.draw(&Polygon::new(pts.clone(), tall_style))
                .map_err(pe)?;
        }
        let mut closed = pts;
        closed.push(closed[0]);
        plot.draw(&PathElement::new(closed, outline_style))
            .map_err(pe)?;
        for h in &b.holes_m {
            let hole = clip_ring(h, clip);
            if hole.len() >= 3 {
                let mut closed: Vec<(f64, f64)> = hole.iter().map(|p| (p[0], p[1])).collect();
                closed.push(closed[0]);
                plot.draw(&PathElement::new(closed, outline_style))
                    .map_err(pe)?;
            }
        }
    }

    // Frame around the map.
    root.draw(&Rectangle::new(
        [
            (base_x - 1, base_y - 1),
            (base_x + pw as i32, base_y + ph as i32),
        ],
        BLACK.stroke_width(1),
    ))
    .map_err(pe)?;

    // Sites: marker + index label with a white halo.
    let label_font = (FONT, SMALL_PX).into_font();
    for s in sites {
        let (x, y) = (s.position_m[0], s.position_m[1]);
        if !(x >= x_min && x <= x_max && y >= y_min && y <= y_max) {
            continue;
        }
        let (cx, cy) = plot.map_coordinate(&(x, y));
        draw_site_marker(&root, (cx, cy), s.kind)?;
        let label = s.id.0.to_string();
        draw_halo_text(
            &root,
            &label,
            (cx + 10, cy - 10),
            &label_font,
            HPos::Left,
            VPos::Bottom,
        )?;
    }

    draw_map_axes(&mut chart, 8, LABEL_PX, DESC_PX)?;

    draw_side(&side, slice.altitude_m, thresholds, MARGIN, ph as i32)?;

    root.present().map_err(pe)?;
    Ok(())
}

/// The side column: colour bar with ticks, class boundaries and label, then the legend.
/// `top` is the pixel offset of the map's plot area within `side`, `plot_h` its height.
fn draw_side(
    side: &DrawingArea<BitMapBackend, Shift>,
    altitude_m: f64,
    thresholds: &RsrpThresholds,
    top: i32,
    plot_h: i32,
) -> Result<()> {
    let bar_x0 = 112;
    let bar_w = 34;
    let bar_y0 = top;
    let bar_h = ((f64::from(plot_h) * 0.62) as i32).max(100);
    let span = RSRP_SCALE_MAX_DBM - RSRP_SCALE_MIN_DBM;
    let y_of =
        |v: f64| bar_y0 + ((RSRP_SCALE_MAX_DBM - v) / span * f64::from(bar_h)).round() as i32;

    for row in 0..bar_h {
        let v = RSRP_SCALE_MAX_DBM - (f64::from(row) + 0.5) / f64::from(bar_h) * span;
        side.draw(&Rectangle::new(
            [(bar_x0, bar_y0 + row), (bar_x0 + bar_w, bar_y0 + row + 1)],
            rsrp_colour(v).filled(),
        ))
        .map_err(pe)?;
    }
    side.draw(&Rectangle::new(
        [(bar_x0, bar_y0), (bar_x0 + bar_w, bar_y0 + bar_h)],
        BLACK.stroke_width(1),
    ))
    .map_err(pe)?;

    // Ticks every 10 dB.
    let tick_font = (FONT, LABEL_PX)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    let mut v = RSRP_SCALE_MIN_DBM;
    while v <= RSRP_SCALE_MAX_DBM + 1e-9 {
        let y = y_of(v);
        side.draw(&PathElement::new(
            vec![(bar_x0 + bar_w, y), (bar_x0 + bar_w + 6, y)],
            BLACK.stroke_width(1),
        ))
        .map_err(pe)?;
        side.draw_text(&fmt_num(v), &tick_font, (bar_x0 + bar_w + 10, y))
            .map_err(pe)?;
        v += 10.0;
    }

    // Class boundaries: a bold line across the bar and the class names to its left.
    for b in [thresholds.excellent_dbm, thresholds.poor_dbm] {
        let y = y_of(b);
        side.draw(&Rectangle::new(
            [(bar_x0 - 8, y - 1), (bar_x0 + bar_w + 1, y + 2)],
            BLACK.filled(),
        ))
        .map_err(pe)?;
        side.draw(&PathElement::new(
            vec![(bar_x0, y + 3), (bar_x0 + bar_w, y + 3)],
            WHITE.stroke_width(1),
        ))
        .map_err(pe)?;
        side.draw(&PathElement::new(
            vec![(bar_x0, y - 2), (bar_x0 + bar_w, y - 2)],
            WHITE.stroke_width(1),
        ))
        .map_err(pe)?;
    }
    let class_font = (FONT, SMALL_PX)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Right, VPos::Center));
    for (class, lo, hi, _) in class_bands(thresholds, RSRP_SCALE_MIN_DBM, RSRP_SCALE_MAX_DBM) {
        let y = (y_of(lo) + y_of(hi)) / 2;
        side.draw_text(class.name(), &class_font, (bar_x0 - 12, y))
            .map_err(pe)?;
    }

    // Colour bar label, rotated, right of the tick labels.
    let desc = (FONT, DESC_PX)
        .into_font()
        .transform(FontTransform::Rotate270)
        .color(&BLACK)
        .pos(Pos::new(HPos::Center, VPos::Top));
    side.draw_text(
        "RSRP (dBm)",
        &desc,
        (bar_x0 + bar_w + 72, bar_y0 + bar_h / 2),
    )
    .map_err(pe)?;

    // Legend.
    let text = (FONT, SMALL_PX)
        .into_font()
        .color(&BLACK)
        .pos(Pos::new(HPos::Left, VPos::Center));
    let x_icon = 26;
    let x_text = 50;
    let mut y = bar_y0 + bar_h + 50;
    side.draw_text(
        &format!("slice at {} m above ground", fmt_num(altitude_m)),
        &text,
        (12, y),
    )
    .map_err(pe)?;
    y += 38;
    draw_site_marker(side, (x_icon, y), SiteKind::Macro)?;
    side.draw_text("macro site (id)", &text, (x_text, y))
        .map_err(pe)?;
    y += 32;
    draw_site_marker(side, (x_icon, y), SiteKind::Micro)?;
    side.draw_text("micro site (id)", &text, (x_text, y))
        .map_err(pe)?;
    y += 32;
    let sq = |y: i32| [(x_icon - 9, y - 9), (x_icon + 9, y + 9)];
    side.draw(&Rectangle::new(sq(y), NAN_GREY.filled()))
        .map_err(pe)?;
    side.draw(&Rectangle::new(sq(y), TALL_FILL.mix(TALL_ALPHA).filled()))
        .map_err(pe)?;
    side.draw(&Rectangle::new(sq(y), OUTLINE.stroke_width(1)))
        .map_err(pe)?;
    side.draw_text("building at slice", &text, (x_text, y))
        .map_err(pe)?;
    side.draw_text("height (no RSRP)", &text, (x_text, y + 22))
        .map_err(pe)?;
    y += 54;
    side.draw(&Rectangle::new(sq(y), rsrp_colour(-75.0).filled()))
        .map_err(pe)?;
    side.draw(&Rectangle::new(sq(y), OUTLINE.stroke_width(1)))
        .map_err(pe)?;
    side.draw_text("lower building", &text, (x_text, y))
        .map_err(pe)?;
    Ok(())
}
#[cfg(test)]
mod tests {
    use super::*;
    use dupac_common::geometry::Point;
    use dupac_common::ids::SiteId;
    use dupac_radio::sites::Mount;

    fn synthetic(n: usize, res: f64) -> (CoverageSlice, Vec<Building>, Vec<Site>, Bounds2) {
        let half = 0.5 * n as f64 * res;
        let bld = |id: &str, x: f64, y: f64, w: f64, h: f64, z: f64| Building {
            id: id.into(),
            outer_m: vec![[x, y], [x + w, y], [x + w, y + h], [x, y + h]],
            holes_m: vec![],
            z_min_m: 0.0,
            z_max_m: z,
        };
        let buildings = vec![
            bld("a", -100.0, -80.0, 60.0, 40.0, 120.0),
            bld("b", 50.0, 60.0, 30.0, 80.0, 20.0),
            bld("c", half - 20.0, 0.0, 60.0, 30.0, 90.0), // crosses the edge: clipped
        ];
        let mut rsrp = vec![0f32; n * n];
        for iy in 0..n {
            for ix in 0..n {
                let x = -half + (ix as f64 + 0.5) * res;
                let y = -half + (iy as f64 + 0.5) * res;
                let inside = buildings
                    .iter()
                    .any(|b| b.z_max_m > 60.0 && b.contains_xy(x, y));
                let d = ((x - 30.0).powi(2) + (y - 20.0).powi(2)).sqrt();
                rsrp[iy * n + ix] = if inside {
                    f32::NAN
                } else {
                    (-60.0 - 0.08 * d) as f32
                };
            }
        }
        let slice = CoverageSlice {
            altitude_m: 60.0,
            x0_m: -half,
            y0_m: -half,
            resolution_m: res,
            nx: n,
            ny: n,
            rsrp_dbm: rsrp,
            serving: vec![None; n * n],
            los: vec![false; n * n],
        };
        let site = |i: u16, x: f64, y: f64, kind| Site {
            id: SiteId(i),
            name: format!("s{i}"),
            position_m: Point::new(x, y, 30.0),
            kind,
            boresights_deg: vec![30.0, 150.0, 270.0],
            electrical_tilt_deg: 10.0,
            tx_power_dbm: 15.2,
            mount: Mount::User,
        };
        let sites = vec![
            site(0, 30.0, 20.0, SiteKind::Macro),
            site(1, -150.0, 100.0, SiteKind::Micro),
            site(12, 100.0, -120.0, SiteKind::Micro),
        ];
        (
            slice,
            buildings,
            sites,
            Bounds2::new(-half, -half, half, half),
        )
    }

    #[test]
    fn viridis_ends_and_nan() {
        assert_eq!(rsrp_colour(-200.0), RGBColor(68, 1, 84));
        assert_eq!(rsrp_colour(0.0), RGBColor(253, 231, 37));
        assert_eq!(rsrp_colour(f64::NAN), NAN_GREY);
    }

    #[test]
    fn renders_a_png() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("sub").join("map_60m.png");
        let (slice, buildings, sites, area) = synthetic(80, 5.0);
        render_coverage_png(
            &slice,
            &buildings,
            &sites,
            area,
            &RsrpThresholds::default(),
            "synthetic, 60 m",
            &path,
        )
        .expect("render");
        let bytes = std::fs::read(&path).expect("png exists");
        assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
        assert!(bytes.len() > 10_000, "{} bytes", bytes.len());
        // No temporary files left behind.
        let left: Vec<_> = std::fs::read_dir(path.parent().expect("parent"))
            .expect("dir")
            .filter_map(|e| e.ok())
            .map(|e| e.file_name())
            .collect();
        assert_eq!(left.len(), 1, "{left:?}");
    }

    #[test]
    fn rejects_bad_input_naming_the_path() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("bad.png");
        let (slice, buildings, sites, _) = synthetic(10, 5.0);
        let err = render_coverage_png(
            &slice,
            &buildings,
            &sites,
            Bounds2::new(0.0, 0.0, 0.0, 1.0),
            &RsrpThresholds::default(),
            "t",
            &path,
        )
        .expect_err("empty area");
        assert!(format!("{err:#}").contains("bad.png"));
        assert!(!path.exists());
    }

    /// Renders the synthetic map to `$DUPAC_PLOT_DEMO` for a visual check (ignored by default).
    #[test]
    #[ignore]
    fn demo_png() {
        let Ok(out) = std::env::var("DUPAC_PLOT_DEMO") else {
            return;
        };
        let (slice, buildings, sites, area) = synthetic(290, 5.0);
        let t = std::time::Instant::now();
        render_coverage_png(
            &slice,
            &buildings,
            &sites,
            area,
            &RsrpThresholds::default(),
            "Best-server RSRP, synthetic, 60 m",
            Path::new(&out),
        )
        .expect("render");
        eprintln!("rendered in {:?}", t.elapsed());
    }
}
