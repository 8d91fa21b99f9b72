use super::lines::{class_runs, clip_polyline, view_bounds};
use super::*;
use crate::style::{class_bands, fmt_num};
use dupac_common::ids::SiteId;
use dupac_radio::sites::{Mount, SiteKind};

fn bld(id: &str, x: f64, y: f64, w: f64, h: f64, z: f64) -> Building {
    Building {
        id: id.into(),
        outer_m: vec![[x, y], [x + w, y], [x + w, y + h], [x, y + h]],
        holes_m: vec![],
        z_min_m: 0.0,
        z_max_m: z,
    }
}

fn class_of(rsrp: f64) -> RsrpClass {
    RsrpThresholds::default().classify(rsrp)
}

/// A trace through `waypoints` (x, y, z), sampled every ~5 m, with a synthetic RSRP field.
fn trace(label: &str, waypoints: &[Point]) -> FlightTrace {
    let mut points_m = vec![waypoints[0]];
    for w in waypoints.windows(2) {
        let (a, b) = (w[0], w[1]);
        let l = ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt();
        let n = ((l / 5.0).ceil() as usize).max(1);
        for k in 1..=n {
            let f = k as f64 / n as f64;
            points_m.push(Point::new(
                a[0] + f * (b[0] - a[0]),
                a[1] + f * (b[1] - a[1]),
                a[2] + f * (b[2] - a[2]),
            ));
        }
    }
    let serving_rsrp_dbm: Vec<f64> = points_m
        .iter()
        .map(|p| {
            let d = ((p[0] - 150.0).powi(2) + (p[1] - 100.0).powi(2)).sqrt();
            -62.0 - 0.11 * d + 6.0 * (p[0] / 37.0).sin() + 0.05 * p[2]
        })
        .collect();
    let class = serving_rsrp_dbm.iter().map(|&v| class_of(v)).collect();
    FlightTrace {
        label: label.into(),
        points_m,
        serving_rsrp_dbm,
        class,
        reached: true,
    }
}

fn scene() -> (Vec<Building>, Vec<Site>, Bounds2, Vec<FlightTrace>) {
    let mut buildings = Vec::new();
    let mut k = 0;
    for ix in -4_i32..6 {
        for iy in -3..5 {
            let (x, y) = (f64::from(ix) * 80.0, f64::from(iy) * 70.0);
            let z = 15.0 + f64::from((ix * 7 + iy * 13).rem_euclid(11)) * 22.0;
            buildings.push(bld(&format!("b{k}"), x + 8.0, y + 8.0, 62.0, 52.0, z));
            k += 1;
        }
    }
    // A courtyard building.
    buildings.push(Building {
        id: "court".into(),
        outer_m: vec![
            [500.0, 100.0],
            [580.0, 100.0],
            [580.0, 170.0],
            [500.0, 170.0],
        ],
        holes_m: vec![vec![
            [520.0, 120.0],
            [560.0, 120.0],
            [560.0, 150.0],
            [520.0, 150.0],
        ]],
        z_min_m: 0.0,
        z_max_m: 60.0,
    });
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
        site(3, 150.0, 100.0, SiteKind::Macro),
        site(7, -160.0, 250.0, SiteKind::Micro),
        site(11, 380.0, -140.0, SiteKind::Micro),
        site(40, 3000.0, 3000.0, SiteKind::Macro), // outside the view
    ];
    let shortest = trace(
        "shortest (A3)",
        &[
            Point::new(-230.0, -150.0, 0.0),
            Point::new(-230.0, -150.0, 60.0),
            Point::new(400.0, 290.0, 60.0),
            Point::new(400.0, 290.0, 0.0),
        ],
    );
    let aware = trace(
        "coverage-aware λ=1 (A3)",
        &[
            Point::new(-230.0, -150.0, 0.0),
            Point::new(-230.0, -150.0, 90.0),
            Point::new(-0.0, -150.0, 90.0),
            Point::new(160.0, 75.0, 120.0),
            Point::new(240.0, 75.0, 120.0),
            Point::new(400.0, 220.0, 90.0),
            Point::new(400.0, 290.0, 90.0),
            Point::new(400.0, 290.0, 0.0),
        ],
    );
    (
        buildings,
        sites,
        Bounds2::new(-600.0, -500.0, 900.0, 700.0),
        vec![shortest, aware],
    )
}

#[test]
fn renders_two_traces() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("sub").join("plan.png");
    let (buildings, sites, area, traces) = scene();
    render_plan_png(
        &buildings,
        &sites,
        area,
        &traces,
        &RsrpThresholds::default(),
        "synthetic plan",
        &path,
    )
    .expect("render");
    let bytes = std::fs::read(&path).expect("png exists");
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n");
    assert!(bytes.len() > 20_000, "{} bytes", bytes.len());
    let left: Vec<_> = std::fs::read_dir(path.parent().expect("parent"))
        .expect("dir")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name())
        .collect();
    assert_eq!(left.len(), 1, "{left:?}");
}

/// The class bands and legends come from the configuration. With
/// `radio.rsrp_excellent_dbm` and `radio.rsrp_poor_dbm` changed, the bands and legend
/// labels every figure draws move with them, and the rendered plan differs from the one with
/// the paper's thresholds (a renderer that kept −80/−100 would draw the same image).
#[test]
fn class_bands_and_legend_follow_the_configured_thresholds() {
    let radio = dupac_common::config::RadioConfig {
        rsrp_excellent_dbm: -72.0,
        rsrp_poor_dbm: -95.0,
        ..Default::default()
    };
    let t = RsrpThresholds::from_config(&radio);
    let bands = class_bands(&t, -130.0, -50.0);
    let edges: Vec<(RsrpClass, f64, f64)> = bands.iter().map(|b| (b.0, b.1, b.2)).collect();
    assert_eq!(
        edges,
        vec![
            (RsrpClass::Excellent, -72.0, -50.0),
            (RsrpClass::Mediocre, -95.0, -72.0),
            (RsrpClass::Poor, -130.0, -95.0),
        ]
    );
    assert_eq!(bands[0].3, format!("excellent (≥ {} dBm)", fmt_num(-72.0)));
    assert_eq!(bands[2].3, format!("poor (< {} dBm)", fmt_num(-95.0)));
    let default_labels: Vec<String> = class_bands(&RsrpThresholds::default(), -130.0, -50.0)
        .into_iter()
        .map(|b| b.3)
        .collect();
    assert_eq!(
        default_labels[0],
        format!("excellent (≥ {} dBm)", fmt_num(-80.0))
    );

    let dir = tempfile::tempdir().expect("tempdir");
    let (buildings, sites, area, traces) = scene();
    let draw = |th: &RsrpThresholds, name: &str| {
        let p = dir.path().join(name);
        render_plan_png(&buildings, &sites, area, &traces, th, "thresholds", &p).expect("render");
        std::fs::read(&p).expect("png")
    };
    assert_ne!(
        draw(&RsrpThresholds::default(), "paper.png"),
        draw(&t, "configured.png"),
        "the figure must change with the configured thresholds"
    );
}

#[test]
fn rejects_bad_traces_naming_path_and_label() {
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("bad.png");
    let (buildings, sites, area, mut traces) = scene();
    traces[1].serving_rsrp_dbm.pop();
    let err = render_plan_png(
        &buildings,
        &sites,
        area,
        &traces,
        &RsrpThresholds::default(),
        "t",
        &path,
    )
    .expect_err("length mismatch");
    let msg = format!("{err:#}");
    assert!(
        msg.contains("bad.png") && msg.contains("coverage-aware λ=1 (A3)"),
        "{msg}"
    );
    assert!(!path.exists());

    let (_, _, _, mut traces) = scene();
    traces[0].points_m[3][2] = f64::NAN;
    let msg = format!(
        "{:#}",
        render_plan_png(
            &buildings,
            &sites,
            area,
            &traces,
            &RsrpThresholds::default(),
            "t",
            &path
        )
        .expect_err("NaN")
    );
    assert!(msg.contains("shortest (A3)"), "{msg}");

    let (_, _, _, mut traces) = scene();
    traces.iter_mut().for_each(|t| {
        t.points_m.truncate(1);
        t.serving_rsrp_dbm.truncate(1);
        t.class.truncate(1);
    });
    assert!(
        render_plan_png(
            &buildings,
            &sites,
            area,
            &traces,
            &RsrpThresholds::default(),
            "t",
            &path
        )
        .is_err()
    );
    assert!(
        render_plan_png(
            &buildings,
            &sites,
            area,
            &[],
            &RsrpThresholds::default(),
            "t",
            &path
        )
        .is_err()
    );
    assert!(!path.exists());
}

#[test]
fn clip_polyline_cuts_and_rejoins() {
    let r = Bounds2::new(0.0, 0.0, 10.0, 10.0);
    let inside = vec![(1.0, 1.0), (5.0, 5.0), (9.0, 1.0)];
    assert_eq!(clip_polyline(&inside, r), vec![inside.clone()]);
    // Out and back in: two pieces, cut at the border.
    let p = vec![(5.0, 5.0), (15.0, 5.0), (15.0, 8.0), (5.0, 8.0)];
    let pieces = clip_polyline(&p, r);
    assert_eq!(
        pieces,
        vec![vec![(5.0, 5.0), (10.0, 5.0)], vec![(10.0, 8.0), (5.0, 8.0)]]
    );
    assert!(clip_polyline(&[(20.0, 20.0), (30.0, 30.0)], r).is_empty());
}

#[test]
fn class_runs_split_segments_at_midpoints() {
    let t = FlightTrace {
        label: "t".into(),
        points_m: vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(10.0, 0.0, 0.0),
            Point::new(20.0, 0.0, 0.0),
        ],
        serving_rsrp_dbm: vec![-70.0, -90.0, -90.0],
        class: vec![
            RsrpClass::Excellent,
            RsrpClass::Mediocre,
            RsrpClass::Mediocre,
        ],
        reached: true,
    };
    let runs = class_runs(&t);
    assert_eq!(runs.len(), 2);
    assert_eq!(
        runs[0],
        (RsrpClass::Excellent, vec![(0.0, 0.0), (5.0, 0.0)])
    );
    assert_eq!(
        runs[1],
        (
            RsrpClass::Mediocre,
            vec![(5.0, 0.0), (10.0, 0.0), (20.0, 0.0)]
        )
    );
    let d = derive(&t);
    assert_eq!(d.dist_m, vec![0.0, 10.0, 20.0]);
    assert!((d.share[0] - 0.25).abs() < 1e-12 && (d.share[1] - 0.75).abs() < 1e-12);
}

#[test]
fn view_contains_traces_and_stays_in_area() {
    let (_, _, area, traces) = scene();
    let v = view_bounds(&traces, area, 1.2);
    assert!(
        v.min_m.x <= -230.0 - VIEW_MARGIN_M + 1e-9 && v.max_m.x >= 400.0 + VIEW_MARGIN_M - 1e-9
    );
    assert!(
        v.min_m.x >= area.min_m.x
            && v.max_m.x <= area.max_m.x
            && v.min_m.y >= area.min_m.y
            && v.max_m.y <= area.max_m.y
    );
    assert!(
        (((v.max_m.x - v.min_m.x) / (v.max_m.y - v.min_m.y)) - 1.2).abs() < 1e-9,
        "{v:?}"
    );
}

/// Renders the synthetic plan to `$DUPAC_PLAN_PLOT_DEMO` for a visual check (ignored).
#[test]
#[ignore]
fn demo_png() {
    let Ok(out) = std::env::var("DUPAC_PLAN_PLOT_DEMO") else {
        return;
    };
    let (buildings, sites, area, traces) = scene();
    render_plan_png(
        &buildings,
        &sites,
        area,
        &traces,
        &RsrpThresholds::default(),
        "Planned paths, synthetic scene, A3 handover",
        Path::new(&out),
    )
    .expect("render");
}
