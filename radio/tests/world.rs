//! Integration tests of the radio world: sites, links with geometric LoS, coverage and the cache,
//! on hand-built geometry and on the procedural city.

use dupac_common::config::{CityKind, Config};
use dupac_common::geometry::{Bounds2, Point};
use dupac_common::ids::SiteId;
use dupac_radio::cache::{GridSpec, Opened, RsrpCache};
use dupac_radio::city::{Building, City};
use dupac_radio::class::RsrpClass;
use dupac_radio::coverage::{Server, compute_slice, summarise};
use dupac_radio::sites::{Mount, Site, SiteKind, place_sites};
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;

fn block(id: &str, x0: f64, y0: f64, x1: f64, y1: f64, h: f64) -> Building {
    Building {
        id: id.into(),
        outer_m: vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
        holes_m: vec![],
        z_min_m: 0.0,
        z_max_m: h,
    }
}

fn macro_site(id: u16, xyz: Point) -> Site {
    Site {
        id: SiteId(id),
        name: format!("s{id}"),
        position_m: xyz,
        kind: SiteKind::Macro,
        boresights_deg: vec![30.0, 150.0, 270.0],
        electrical_tilt_deg: 10.0,
        tx_power_dbm: 15.2,
        mount: Mount::User,
    }
}

/// A 1 km square with one 80 m tower at x ∈ [200, 260] between a macro site at the origin and
/// the east.
fn tower_world() -> RadioWorld {
    let cfg = Config::default();
    let city = City::from_buildings(
        "tower",
        Bounds2::new(-500.0, -500.0, 500.0, 500.0),
        vec![block("tower", 200.0, -30.0, 260.0, 30.0, 80.0)],
        None,
    )
    .expect("city");
    RadioWorld::from_parts(
        city,
        vec![macro_site(0, Point::new(0.0, 0.0, 25.0))],
        &cfg.radio,
    )
}

#[test]
fn tower_shadows_the_link_and_nlos_follows_the_spec_formula() {
    let w = tower_world();
    // UAV at 50 m, 400 m east, behind the tower: NLoS. At 100 m: the segment clears 80 m? The
    // segment from 25 m to 100 m over 400 m is at 25 + 75·(200/400) = 62.5 m at x = 200: blocked.
    let behind = Point::new(400.0, 0.0, 50.0);
    let b = w.link_budget(SiteId(0), behind);
    assert!(!b.los);
    // Independent arithmetic (spec §1, UMa-AV NLoS ω8 at h = 50): d3D = hypot(400, 25) = 400.78 m,
    // L = −17.5 + (46 − 7 log10 50)·log10 400.78 + 20 log10(40π·2/3) = 109.7403 dB.
    assert!((b.d3d_m - 400.780_488).abs() < 1e-5, "{}", b.d3d_m);
    assert!((b.pl_db - 109.7403).abs() < 1e-3, "{}", b.pl_db);
    // North of the tower the same distance is LoS: ω4 = 28 + 22 log10 400.78 + 20 log10 2 = 91.2845 dB.
    let clear = Point::new(0.0, 400.0, 50.0);
    let c = w.link_budget(SiteId(0), clear);
    assert!(c.los);
    assert!((c.pl_db - 91.2845).abs() < 1e-3, "{}", c.pl_db);
    assert!(c.rsrp_dbm > b.rsrp_dbm + 10.0);
    // Far above the tower: LoS again.
    assert!(w.los(SiteId(0), Point::new(400.0, 0.0, 300.0)));
}

#[test]
fn spec_table_row_macro_500m_through_the_world() {
    // spec/radio.md §3: macro 25 m, UAV 100 m, d2D 500 m, boresights 30/150/270, UAV on the
    // +x axis (30° off the nearest boresight): G = 0.41 dBi, L = 93.50 dB, RSRP = −77.89 dBm, LoS.
    let cfg = Config::default();
    let city = City::from_buildings(
        "empty",
        Bounds2::new(-1000.0, -1000.0, 1000.0, 1000.0),
        vec![block("far", 900.0, 900.0, 950.0, 950.0, 10.0)],
        None,
    )
    .expect("city");
    let w = RadioWorld::from_parts(
        city,
        vec![macro_site(0, Point::new(0.0, 0.0, 25.0))],
        &cfg.radio,
    );
    let b = w.link_budget(SiteId(0), Point::new(500.0, 0.0, 100.0));
    assert!(b.los);
    assert!((b.theta_deg - 81.47).abs() < 0.01, "{}", b.theta_deg);
    assert!((b.gain_dbi - 0.41).abs() < 0.01, "{}", b.gain_dbi);
    assert!((b.pl_db - 93.50).abs() < 0.01, "{}", b.pl_db);
    assert!((b.rsrp_dbm + 77.89).abs() < 0.01, "{}", b.rsrp_dbm);
    assert_eq!(b.class, RsrpClass::Excellent);
}

#[test]
fn coverage_slice_masks_buildings_and_is_worse_in_the_shadow() {
    let w = tower_world();
    let slice = compute_slice(
        &w,
        Server::Best,
        None,
        Bounds2::new(-500.0, -500.0, 500.0, 500.0),
        30.0,
        10.0,
        &|_| {},
    );
    assert_eq!((slice.nx, slice.ny), (100, 100));
    let at = |x: f64, y: f64| {
        let ix = ((x + 500.0) / 10.0) as usize;
        let iy = ((y + 500.0) / 10.0) as usize;
        iy * slice.nx + ix
    };
    assert!(slice.rsrp_dbm[at(230.0, 0.0)].is_nan(), "inside the tower");
    assert_eq!(slice.serving[at(230.0, 0.0)], None);
    let shadow = slice.rsrp_dbm[at(400.0, 0.0)];
    let open = slice.rsrp_dbm[at(0.0, 400.0)];
    assert!(!slice.los[at(400.0, 0.0)] && slice.los[at(0.0, 400.0)]);
    assert!(open > shadow + 10.0, "open {open} shadow {shadow}");
    let s = summarise(&w, &slice);
    assert_eq!(s.cells, 100 * 100 - 6 * 6);
    // With a single site the slice is that site's RSRP; here it is the only one, so identical.
    let one = compute_slice(
        &w,
        Server::Site(SiteId(0)),
        None,
        Bounds2::new(-500.0, -500.0, 500.0, 500.0),
        30.0,
        10.0,
        &|_| {},
    );
    assert_eq!(one.rsrp_dbm[at(400.0, 0.0)], shadow);
    assert!((s.excellent_pct + s.mediocre_pct + s.poor_pct - 100.0).abs() < 1e-9);
    assert!(s.nlos_pct > 0.0 && s.nlos_pct < 20.0, "{}", s.nlos_pct);
}

fn procedural_config(dir: &std::path::Path) -> Config {
    Config::load(
        None,
        &[
            "scenario.city=procedural".into(),
            "scenario.name=\"proc-test\"".into(),
            "scenario.procedural.size_m=400".into(),
            "scenario.procedural.n_sites=6".into(),
            "scenario.n_sites=6".into(),
            "cache.horizontal_m=10".into(),
            "cache.vertical_m=10".into(),
            format!("cache.path=\"{}\"", dir.join("rsrp.bin").display()),
        ],
    )
    .expect("config")
}

#[test]
fn procedural_world_places_sites_on_roofs_or_poles() {
    let dir = tempfile::tempdir().expect("tmp");
    let cfg = procedural_config(dir.path());
    assert_eq!(cfg.scenario.city, CityKind::Procedural);
    let w = RadioWorld::build(&cfg).expect("world");
    assert_eq!(w.num_sites(), 6);
    for s in &w.sites {
        match &s.mount {
            Mount::Roof { roof_m, .. } => {
                assert!((s.position_m[2] - roof_m - 3.0).abs() < 1e-9);
                assert!(w.city.roof_height_m(s.position_m[0], s.position_m[1]) > 0.0);
            }
            Mount::Pole => assert_eq!(s.position_m[2], 10.0),
            Mount::User => panic!("no sites file given"),
        }
    }
    let ids: Vec<u16> = w.sites.iter().map(|s| s.id.0).collect();
    assert_eq!(ids, vec![0, 1, 2, 3, 4, 5]);
}

#[test]
fn cache_matches_exact_mode_at_grid_points_and_detects_staleness() {
    let dir = tempfile::tempdir().expect("tmp");
    let cfg = procedural_config(dir.path());
    let w = RadioWorld::build(&cfg).expect("world");
    let (cache, built) = RsrpCache::open_or_build(&w, &cfg.cache, &|_| {}).expect("cache");
    assert!(built);
    assert!(cache.path().is_some(), "memory-mapped from disk");
    let g = *cache.grid();
    assert_eq!((g.nx, g.ny, g.nz), (41, 41, 11));
    let m = w.num_sites();
    let (mut exact, mut cached) = (vec![0.0; m], vec![0.0; m]);
    for (ix, iy, iz) in [(0, 0, 0), (7, 13, 3), (40, 40, 10), (20, 5, 9)] {
        let p = g.point_m(ix, iy, iz);
        w.rsrp_all_dbm(p, &mut exact);
        cache.rsrp_all_dbm(p, &mut cached);
        for s in 0..m {
            assert!(
                (exact[s] - cached[s]).abs() < 1e-4,
                "grid point {p:?} site {s}"
            );
            let one = cache.rsrp_dbm(SiteId(s as u16), p);
            assert!((one - cached[s]).abs() < 1e-4);
        }
    }
    // Midway between two grid points the value is their mean (trilinear along one axis).
    let a = g.point_m(7, 13, 3);
    let b = g.point_m(8, 13, 3);
    let mid = Point::new((a[0] + b[0]) / 2.0, a[1], a[2]);
    let (ea, eb) = (cache.rsrp_dbm(SiteId(2), a), cache.rsrp_dbm(SiteId(2), b));
    assert!((cache.rsrp_dbm(SiteId(2), mid) - (ea + eb) / 2.0).abs() < 1e-4);

    // Re-opening is valid and does not rebuild.
    let (_, rebuilt) = RsrpCache::open_or_build(&w, &cfg.cache, &|_| {}).expect("cache");
    assert!(!rebuilt);
    // A different radio configuration makes it stale.
    let mut cfg2 = cfg.clone();
    cfg2.radio.tx_power_dbm = 20.0;
    let w2 = RadioWorld::build(&cfg2).expect("world");
    let expected = RsrpCache::expected_header(&w2, GridSpec::covering(w2.city.area_m, &cfg2.cache));
    assert!(matches!(
        RsrpCache::open(&cfg.cache.path, &expected).expect("open"),
        Opened::Stale(_)
    ));
    // A changed A3 rule does not (it does not change RSRP).
    let mut cfg3 = cfg.clone();
    cfg3.radio.a3.offset_db = 5.0;
    let w3 = RadioWorld::build(&cfg3).expect("world");
    assert_eq!(w3.fingerprint(), w.fingerprint());
}

/// The cache's line of sight (what the site features observe under `env.observation.site_los =
/// "cache"`) is the ray's at every grid point, read back from the file as it was built, and
/// interpolated like the RSRP between grid points.
#[test]
fn the_caches_line_of_sight_is_the_rays_at_grid_points_and_interpolated_between() {
    let dir = tempfile::tempdir().expect("tmp");
    let cfg = procedural_config(dir.path());
    let w = RadioWorld::build(&cfg).expect("world");
    let (cache, _) = RsrpCache::open_or_build(&w, &cfg.cache, &|_| {}).expect("cache");
    let g = *cache.grid();
    let m = w.num_sites();
    let (mut cached, mut rays) = (vec![0.0; m], vec![0.0; m]);
    let (mut seen, mut blocked) = (0, 0);
    for iy in (0..g.ny).step_by(3) {
        for ix in (0..g.nx).step_by(3) {
            for iz in [0, g.nz / 2, g.nz - 1] {
                let p = g.point_m(ix, iy, iz);
                assert!(cache.los_all(p, &mut cached));
                assert!(RsrpSource::los_all(&w, p, &mut rays));
                for s in 0..m {
                    assert_eq!(cached[s], rays[s], "grid point {p:?} site {s}");
                    assert_eq!(rays[s] == 1.0, w.los(SiteId(s as u16), p));
                    if rays[s] == 1.0 {
                        seen += 1;
                    } else {
                        blocked += 1;
                    }
                }
            }
        }
    }
    assert!(
        seen > 100 && blocked > 100,
        "both kinds tested: {seen} LoS, {blocked} NLoS"
    );
    // Between two grid points that disagree, the value is the interpolation weight.
    let (a, b, s) = (0..g.ny)
        .flat_map(|iy| (0..g.nx - 1).map(move |ix| (ix, iy)))
        .flat_map(|(ix, iy)| (0..m).map(move |s| (ix, iy, s)))
        .map(|(ix, iy, s)| {
            (
                g.point_m(ix, iy, 0),
                g.point_m(ix + 1, iy, 0),
                SiteId(s as u16),
            )
        })
        .find(|(a, b, s)| w.los(*s, *a) && !w.los(*s, *b))
        .expect("a shadow edge along a row");
    let quarter = Point::new(a[0] + 0.25 * (b[0] - a[0]), a[1], a[2]);
    assert!(cache.los_all(quarter, &mut cached));
    assert!(
        (cached[s.index()] - 0.75).abs() < 1e-9,
        "{}",
        cached[s.index()]
    );
}

#[test]
fn truncated_cache_is_an_error_not_a_panic() {
    let dir = tempfile::tempdir().expect("tmp");
    let cfg = procedural_config(dir.path());
    let w = RadioWorld::build(&cfg).expect("world");
    let (cache, _) = RsrpCache::open_or_build(&w, &cfg.cache, &|_| {}).expect("cache");
    let expected = cache.header().clone();
    drop(cache);
    let bytes = std::fs::read(&cfg.cache.path).expect("read");
    std::fs::write(&cfg.cache.path, &bytes[..bytes.len() - 100]).expect("write");
    let e = RsrpCache::open(&cfg.cache.path, &expected)
        .err()
        .expect("error");
    assert!(e.to_string().contains("truncated"), "{e}");
    std::fs::write(&cfg.cache.path, b"garbage").expect("write");
    assert!(matches!(
        RsrpCache::open(&cfg.cache.path, &expected).expect("open"),
        Opened::Stale(_)
    ));
}

#[test]
fn sites_file_overrides_placement_and_bad_files_name_the_line() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut cfg = procedural_config(dir.path());
    let csv = dir.path().join("sites.csv");
    std::fs::write(
        &csv,
        "name,x_m,y_m,z_m,kind,boresights_deg,tilt_deg,tx_power_dbm\n\
         a,10,20,30,macro,0;120;240,6,18\n\
         b,-50,40,,micro,,,\n",
    )
    .expect("write");
    cfg.scenario.sites_file = Some(csv.clone());
    let city = City::load(&cfg.scenario).expect("city");
    let sites = place_sites(&cfg.scenario, &cfg.radio, &city).expect("sites");
    assert_eq!(sites.len(), 2);
    assert_eq!(sites[0].position_m, Point::new(10.0, 20.0, 30.0));
    assert_eq!(sites[0].boresights_deg, vec![0.0, 120.0, 240.0]);
    assert_eq!(sites[0].electrical_tilt_deg, 6.0);
    assert_eq!(sites[0].tx_power_dbm, 18.0);
    assert_eq!(sites[0].mount, Mount::User);
    assert_eq!(sites[1].kind, SiteKind::Micro);
    assert_ne!(sites[1].mount, Mount::User, "no z_m: mounted by the rule");
    assert_eq!(sites[1].tx_power_dbm, 15.2);

    // Out of physical range: a position 1e308 m away, an antenna 5 km up, 200 dBm.
    for (row, what) in [
        ("a,1e308,20,30", "from the scenario centre"),
        ("a,10,20,5000", "z_m"),
        ("a,10,20,30,macro,0,6,200", "tx_power_dbm"),
    ] {
        std::fs::write(
            &csv,
            format!("name,x_m,y_m,z_m,kind,boresights_deg,tilt_deg,tx_power_dbm\n{row}\n")
                .replace("a,1e308,20,30\n", "a,1e308,20,30,,,,\n")
                .replace("a,10,20,5000\n", "a,10,20,5000,,,,\n"),
        )
        .expect("write");
        let e = place_sites(&cfg.scenario, &cfg.radio, &city)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sites.csv") && e.contains(what), "{row}: {e}");
    }

    // A missing position column: named, with the line.
    std::fs::write(&csv, "name,x_m,z_m\na,10,30\n").expect("write");
    let e = place_sites(&cfg.scenario, &cfg.radio, &city)
        .unwrap_err()
        .to_string();
    assert!(e.contains("sites.csv:2") && e.contains("y_m"), "{e}");
    // An unknown column.
    std::fs::write(&csv, "name,x_m,y_m,height\na,10,30,5\n").expect("write");
    let e = place_sites(&cfg.scenario, &cfg.radio, &city)
        .unwrap_err()
        .to_string();
    assert!(e.contains("sites.csv") && e.contains("height"), "{e}");
    // A non-number.
    std::fs::write(&csv, "name,x_m,y_m\na,10,abc\n").expect("write");
    let e = place_sites(&cfg.scenario, &cfg.radio, &city)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("sites.csv") && e.contains("line 2") || e.contains("sites.csv:2"),
        "{e}"
    );

    // TOML form.
    let toml = dir.path().join("sites.toml");
    std::fs::write(
        &toml,
        "[[site]]\nname = \"t\"\nx_m = 1.0\ny_m = 2.0\nz_m = 40.0\nkind = \"macro\"\n",
    )
    .expect("write");
    cfg.scenario.sites_file = Some(toml.clone());
    let sites = place_sites(&cfg.scenario, &cfg.radio, &city).expect("sites");
    assert_eq!(sites[0].position_m, Point::new(1.0, 2.0, 40.0));
    std::fs::write(&toml, "[[site]]\nname = \"t\"\nx_m = 1.0\n").expect("write");
    let e = place_sites(&cfg.scenario, &cfg.radio, &city)
        .unwrap_err()
        .to_string();
    assert!(e.contains("sites.toml:1") && e.contains("y_m"), "{e}");
}

#[test]
fn cells_csv_with_a_missing_column_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("cells.csv");
    std::fs::write(&path, "lat,lon,cell_id\n40.75,-73.98,1\n").expect("write");
    let p = dupac_radio::geo::LocalProjection::new(-73.985, 40.7525);
    let e = dupac_radio::sites::read_cells_csv(&path, &p)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cells.csv:1") && e.contains("enb_id"), "{e}");
    std::fs::write(&path, "lat,lon,enb_id\n40.75,-73.98,1\n40.75,NaN,2\n").expect("write");
    let e = dupac_radio::sites::read_cells_csv(&path, &p)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cells.csv:3") && e.contains("lon"), "{e}");
    // Two cells of one eNB merge into one site at their mean position.
    std::fs::write(
        &path,
        "lat,lon,enb_id\n40.75,-73.98,7\n40.76,-73.98,7\n40.75,-73.99,8\n",
    )
    .expect("write");
    let c = dupac_radio::sites::read_cells_csv(&path, &p).expect("ok");
    assert_eq!(c.len(), 2);
    assert_eq!(c[0].name, "enb:7");
    let mid = p.to_local_m(-73.98, 40.755);
    assert!((c[0].xy_m[0] - mid[0]).abs() < 1e-6 && (c[0].xy_m[1] - mid[1]).abs() < 1e-6);
}

/// eNodeB ids are unique only within a network: the same id on two networks is two sites, and
/// a network code that is not digits is named.
#[test]
fn cells_of_one_enodeb_id_on_two_networks_are_two_sites() {
    let dir = tempfile::tempdir().expect("tmp");
    let path = dir.path().join("cells.csv");
    std::fs::write(
        &path,
        "lat,lon,mcc,mnc,enb_id\n40.75,-73.98,310,410,7\n40.76,-73.98,310,410,7\n40.75,-73.99,310,260,7\n",
    )
    .expect("write");
    let p = dupac_radio::geo::LocalProjection::new(-73.985, 40.7525);
    let c = dupac_radio::sites::read_cells_csv(&path, &p).expect("ok");
    let names: Vec<&str> = c.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["enb:310-260:7", "enb:310-410:7"]);
    std::fs::write(&path, "lat,lon,mcc,mnc,enb_id\n40.75,-73.98,310,x1,7\n").expect("write");
    let e = dupac_radio::sites::read_cells_csv(&path, &p)
        .unwrap_err()
        .to_string();
    assert!(e.contains("cells.csv:2") && e.contains("`mnc`"), "{e}");
}

/// The RSRP cache stores the deterministic model only, so one cache serves every channel: the
/// world's fingerprint (the cache's staleness key) leaves `radio.channel` out, and is the same
/// string it was before that section existed (the section is cut from the end of the text).
#[test]
fn the_channel_does_not_change_the_world_fingerprint() {
    let dir = tempfile::tempdir().expect("tempdir");
    let cfg = procedural_config(dir.path());
    let det = RadioWorld::build(&cfg).expect("world");
    let mut real_cfg = cfg.clone();
    real_cfg.radio.channel.model = dupac_common::config::ChannelModel::Real;
    real_cfg.radio.channel.measurement_sigma_db = 5.0;
    let real = RadioWorld::build(&real_cfg).expect("world");
    assert!(det.channel.is_none() && real.channel.is_some());
    assert_eq!(det.fingerprint(), real.fingerprint());
    // An RSRP parameter still changes it.
    let mut other = cfg.clone();
    other.radio.tx_power_dbm += 1.0;
    assert_ne!(
        det.fingerprint(),
        RadioWorld::build(&other).expect("world").fingerprint()
    );
    // The channel section is the last of the text the fingerprint cuts.
    let text = toml::to_string(&cfg.radio).expect("toml");
    assert!(
        text.trim_end()
            .ends_with(&format!("knowledge = \"{}\"", "operator"))
            && text.contains("\n[channel]\n")
    );
}
