#[path = "../src/plot.rs"]
mod plot;

use dupac_common::SiteId;
use dupac_radio::city::procedural;
use dupac_radio::coverage::CoverageSlice;
use dupac_radio::sites::{Mount, Site, SiteKind};

fn main() -> anyhow::Result<()> {
    let cfg = dupac_common::config::ProceduralConfig::default();
    let city = procedural::generate(&cfg);
    let alt = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(60.0);
    let out = std::env::args()
        .nth(2)
        .unwrap_or("/tmp/plot_check.png".into());
    let sites: Vec<Site> = city
        .site_candidates_m
        .iter()
        .enumerate()
        .map(|(i, p)| Site {
            id: SiteId(i as u16),
            name: format!("c{i}"),
            position_m: [p[0], p[1], 30.0],
            kind: if i % 3 == 0 {
                SiteKind::Macro
            } else {
                SiteKind::Micro
            },
            boresights_deg: vec![30.0, 150.0, 270.0],
            electrical_tilt_deg: 10.0,
            tx_power_dbm: 15.2,
            mount: Mount::User,
        })
        .collect();
    let res = 5.0;
    let n = 280;
    let half = 0.5 * n as f64 * res;
    let mut rsrp = vec![0f32; n * n];
    for iy in 0..n {
        for ix in 0..n {
            let x = -half + (ix as f64 + 0.5) * res;
            let y = -half + (iy as f64 + 0.5) * res;
            let inside = city
                .buildings
                .iter()
                .any(|b| b.z_max_m > alt && b.contains_xy(x, y));
            let d = sites
                .iter()
                .map(|s| ((x - s.position_m[0]).powi(2) + (y - s.position_m[1]).powi(2)).sqrt())
                .fold(f64::INFINITY, f64::min);
            rsrp[iy * n + ix] = if inside {
                f32::NAN
            } else {
                (-55.0 - 25.0 * (d.max(1.0)).log10() + 10.0 * ((x / 37.0).sin() * (y / 53.0).cos()))
                    as f32
            };
        }
    }
    let slice = CoverageSlice {
        altitude_m: alt,
        x0_m: -half,
        y0_m: -half,
        resolution_m: res,
        nx: n,
        ny: n,
        rsrp_dbm: rsrp,
        serving: vec![None; n * n],
        los: vec![false; n * n],
    };
    let t = std::time::Instant::now();
    plot::render_coverage_png(
        &slice,
        &city.buildings,
        &sites,
        {
            let h: f64 = std::env::args()
                .nth(3)
                .and_then(|a| a.parse().ok())
                .unwrap_or(700.0);
            [-h, -h * 0.6, h, h * 0.6]
        },
        &format!(
            "Best-server RSRP at {alt} m — procedural Midtown (seed {})",
            cfg.seed
        ),
        std::path::Path::new(&out),
    )?;
    eprintln!(
        "rendered in {:?}, {} buildings",
        t.elapsed(),
        city.buildings.len()
    );
    Ok(())
}
