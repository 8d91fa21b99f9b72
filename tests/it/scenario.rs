//! `dupac scenario import` end to end: a small raw extract made here (OSM buildings with raw tags
//! as Overpass Turbo exports them, an OpenCelliD cell table) becomes a scenario directory whose
//! configuration `dupac map` and `dupac train` take, run from another working directory than
//! the repository's (paths in a configuration are relative to the working directory).

use crate::support::{dupac_cmd, small_train_args};
use serde_json::{Value, json};
use std::path::Path;
use std::process::{Output, Stdio};

/// The flight area of the extract: ≈ 440 m × 445 m of a made-up town (W, S, E, N).
const AREA: [f64; 4] = [2.3400, 48.8500, 2.3460, 48.8540];
const M_PER_DEG_LAT: f64 = 111_200.0;

fn m_per_deg_lon() -> f64 {
    111_320.0 * 48.852f64.to_radians().cos()
}

/// A closed rectangle `w × h` metres whose south-west corner is `(x, y)` metres east and north
/// of the area's south-west corner, as lon/lat.
fn rect(x: f64, y: f64, w: f64, h: f64) -> Value {
    let (lon0, lat0) = (AREA[0] + x / m_per_deg_lon(), AREA[1] + y / M_PER_DEG_LAT);
    let (lon1, lat1) = (
        AREA[0] + (x + w) / m_per_deg_lon(),
        AREA[1] + (y + h) / M_PER_DEG_LAT,
    );
    json!([
        [lon0, lat0],
        [lon1, lat0],
        [lon1, lat1],
        [lon0, lat1],
        [lon0, lat0]
    ])
}

fn way(id: u64, geometry: Value, tags: Value) -> Value {
    let mut props = tags;
    props["@id"] = json!(format!("way/{id}"));
    json!({"type": "Feature", "id": format!("way/{id}"), "properties": props, "geometry": geometry})
}

fn polygon(ring: Value) -> Value {
    json!({"type": "Polygon", "coordinates": [ring]})
}

/// 36 blocks of 40 m on a 70 m grid with every way of giving a height, a tower with two parts
/// (one floating), a courtyard building with a hole, and features the import must skip.
fn raw_buildings() -> Value {
    let mut features = Vec::new();
    let tag_sets = [
        json!({"building": "yes", "height": "30"}),
        json!({"building": "office", "height": "98'"}),
        json!({"building": "apartments", "building:levels": "8", "roof:levels": "1"}),
        json!({"building": "yes"}),
        json!({"building": "retail", "height": "12 m"}),
        json!({"building": "yes", "height": "tall", "building:levels": "5"}),
    ];
    for i in 0..6 {
        for j in 0..6 {
            let k = i * 6 + j;
            if k == 14 || k == 21 {
                continue; // the tower and the courtyard stand there
            }
            let g = polygon(rect(
                15.0 + 70.0 * j as f64,
                15.0 + 70.0 * i as f64,
                40.0,
                40.0,
            ));
            features.push(way(100 + k as u64, g, tag_sets[k % 6].clone()));
        }
    }
    // Block 14 (row 2, column 2): an outline without height and its two parts.
    let (x, y) = (15.0 + 140.0, 15.0 + 140.0);
    features.push(way(
        500,
        polygon(rect(x, y, 40.0, 40.0)),
        json!({"building": "yes", "name": "Tower"}),
    ));
    features.push(way(
        501,
        polygon(rect(x, y, 40.0, 20.0)),
        json!({"building:part": "yes", "height": "60"}),
    ));
    features.push(way(
        502,
        polygon(rect(x, y + 20.0, 40.0, 20.0)),
        json!({"building:part": "yes", "height": "90", "min_height": "60"}),
    ));
    // Block 21 (row 3, column 3): a multipolygon relation with a courtyard, older osmtogeojson
    // style (tags nested, type and id apart).
    let (x, y) = (15.0 + 210.0, 15.0 + 210.0);
    features.push(json!({
        "type": "Feature",
        "properties": {"type": "relation", "id": 600,
                       "tags": {"type": "multipolygon", "building": "yes", "height": "25"}},
        "geometry": {"type": "Polygon",
                     "coordinates": [rect(x, y, 40.0, 40.0), rect(x + 15.0, y + 15.0, 10.0, 10.0)]},
    }));
    // Skipped: underground, a road, a building node, a building 3 km away.
    features.push(way(
        700,
        polygon(rect(60.0, 60.0, 5.0, 5.0)),
        json!({"building": "yes", "location": "underground"}),
    ));
    features.push(way(
        701,
        json!({"type": "LineString", "coordinates": [[2.341, 48.851], [2.342, 48.852]]}),
        json!({"highway": "residential"}),
    ));
    features.push(json!({"type": "Feature", "id": "node/702",
        "properties": {"building": "yes"},
        "geometry": {"type": "Point", "coordinates": [2.341, 48.851]}}));
    features.push(way(
        703,
        polygon(rect(3000.0, 0.0, 40.0, 40.0)),
        json!({"building": "yes", "height": "20"}),
    ));
    json!({"type": "FeatureCollection", "generator": "overpass-turbo", "features": features})
}

/// Five eNodeBs of two networks (12 LTE cells), plus rows the import skips.
fn raw_cells() -> String {
    let mut s = String::from(
        "radio,mcc,net,area,cell,unit,lon,lat,range,samples,changeable,created,updated,averageSignal\n",
    );
    let sites = [
        (310, 410, 1000, 60.0, 60.0),
        (310, 410, 1001, 380.0, 70.0),
        (310, 260, 1000, 220.0, 230.0),
        (310, 260, 2002, 70.0, 390.0),
        (310, 260, 2003, 390.0, 380.0),
    ];
    for (mcc, net, enb, x, y) in sites {
        for local in 0..3u64 {
            if enb == 2003 && local > 0 {
                break;
            }
            let lon = AREA[0] + (x + 3.0 * local as f64) / m_per_deg_lon();
            let lat = AREA[1] + y / M_PER_DEG_LAT;
            let cell = (enb << 8) | local;
            s.push_str(&format!(
                "LTE,{mcc},{net},7,{cell},{local},{lon:.7},{lat:.7},800,12,1,1400000000,1500000000,-85\n"
            ));
        }
    }
    s.push_str("GSM,310,410,7,4321,,2.343,48.852,2000,5,1,1,2,\n");
    s.push_str("UMTS,310,410,7,98765,12,2.343,48.852,2000,5,1,1,2,\n");
    s.push_str("LTE,310,410,7,777777,5,2.40,48.90,2000,5,1,1,2,\n");
    s.push_str("LTE,310,410,7,300000000,5,2.343,48.852,2000,5,1,1,2,\n");
    s
}

fn run_in(dir: &Path, args: &[&str]) -> Output {
    dupac_cmd()
        .current_dir(dir)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("run dupac")
}

fn ok(out: &Output) -> String {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn area_arg() -> String {
    AREA.map(|v| v.to_string()).join(",")
}

fn write_extract(dir: &Path) {
    std::fs::create_dir_all(dir.join("raw")).expect("mkdir");
    std::fs::write(
        dir.join("raw/buildings.geojson"),
        serde_json::to_string_pretty(&raw_buildings()).expect("json"),
    )
    .expect("write");
    std::fs::write(dir.join("raw/cells.csv"), raw_cells()).expect("write");
}

fn import(dir: &Path, extra: &[&str]) -> Output {
    import_box(dir, &area_arg(), extra)
}

/// `dupac scenario import` of the extract with the flight area `area` (`W,S,E,N`).
fn import_box(dir: &Path, area: &str, extra: &[&str]) -> Output {
    let mut args = vec![
        "scenario",
        "import",
        "--buildings",
        "raw/buildings.geojson",
        "--cells",
        "raw/cells.csv",
        "--box",
        area,
        "--out",
        "scenarios/town",
    ];
    args.extend_from_slice(extra);
    run_in(dir, &args)
}

/// The import keeps and skips what docs/scenario.md says, writes a configuration of only what
/// differs from the defaults, and `dupac map` and a short `dupac train` run on it.
#[test]
fn an_imported_city_maps_and_trains() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path();
    write_extract(dir);
    let stdout = ok(&import(dir, &[]));
    assert!(
        stdout.contains("kept 36 outlines (1 with parts), 2 parts"),
        "{stdout}"
    );
    assert!(
        stdout.contains(
            "skipped 1 not buildings, 1 underground, 1 not areas, 0 degenerate, 1 outside"
        ),
        "{stdout}"
    );
    assert!(stdout.contains("kept 13 (5 sites)"), "{stdout}");
    assert!(
        stdout.contains("skipped 2 of another radio, 1 outside, 1 invalid"),
        "{stdout}"
    );
    assert!(
        stdout.contains("5 sites (scenario.n_sites = 5)"),
        "{stdout}"
    );

    let text = std::fs::read_to_string(dir.join("scenarios/town/config.toml")).expect("config");
    let cfg: toml::Table = text.parse().expect("toml");
    let scenario = cfg["scenario"].as_table().expect("scenario");
    let mut keys: Vec<&str> = scenario.keys().map(String::as_str).collect();
    keys.sort_unstable();
    assert_eq!(
        keys,
        ["area", "buildings_file", "cells_file", "n_sites", "name"],
        "only what differs from the defaults"
    );
    assert_eq!(
        scenario["buildings_file"].as_str(),
        Some("scenarios/town/buildings.geojson")
    );
    assert_eq!(
        cfg["cache"]["path"].as_str(),
        Some("scenarios/town/cache/rsrp.bin")
    );
    assert_eq!(
        cfg["pairs"]["eval_file"].as_str(),
        Some("scenarios/town/pairs/eval_pairs.jsonl")
    );
    assert_eq!(
        cfg["pairs"]["test_file"].as_str(),
        Some("scenarios/town/pairs/test_pairs.jsonl")
    );
    // The area is ≈ 0.31 of Midtown's short side: the pair distances scale with it.
    assert!(
        cfg["pairs"]["max_m"]
            .as_float()
            .is_some_and(|m| m > 200.0 && m < 300.0)
    );

    let geo: Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("scenarios/town/buildings.geojson")).expect("geojson"),
    )
    .expect("json");
    let by_id = |id: &str| {
        geo["features"]
            .as_array()
            .expect("features")
            .iter()
            .find(|f| f["properties"]["id"] == id)
            .unwrap_or_else(|| panic!("{id} missing"))["properties"]
            .clone()
    };
    let feet = by_id("osm:way/101");
    assert!((feet["height_m"].as_f64().expect("h") - 98.0 * 0.3048).abs() < 1e-9);
    let levels = by_id("osm:way/102");
    assert_eq!(
        levels["height_m"],
        json!(27.0),
        "8 levels + 1 roof level × 3 m"
    );
    assert_eq!(levels["height_source"], "estimated:building:levels*3m");
    assert_eq!(
        by_id("osm:way/103")["height_source"],
        "fallback:p75_of_tagged_buildings_within_150m"
    );
    assert_eq!(
        by_id("osm:way/105")["height_m"],
        json!(15.0),
        "`tall` ignored: 5 levels"
    );
    let tower = by_id("osm:way/500");
    assert_eq!(
        (tower["has_parts"].clone(), tower["height_m"].clone()),
        (json!(true), json!(90.0))
    );
    let floating = by_id("osm:way/502");
    assert_eq!(floating["kind"], "building_part");
    assert_eq!(floating["min_height_m"], json!(60.0));
    assert_eq!(by_id("osm:relation/600")["height_m"], json!(25.0));

    // Importing again is refused without --force, and reproduces the files byte for byte.
    let again = import(dir, &[]);
    assert!(!again.status.success());
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    let before = std::fs::read(dir.join("scenarios/town/buildings.geojson")).expect("read");
    ok(&import(dir, &["--force"]));
    let after = std::fs::read(dir.join("scenarios/town/buildings.geojson")).expect("read");
    assert!(before == after, "the import is deterministic");

    let config = "scenarios/town/config.toml";
    let map = run_in(
        dir,
        &[
            "map",
            "-q",
            "--config",
            config,
            "--set",
            "map.resolution_m=20",
            "--set",
            "map.altitudes_m=[30, 90]",
        ],
    );
    let table = ok(&map);
    assert!(table.contains("| altitude (m) |"), "{table}");
    let maps = dir.join("scenarios/town/map");
    let png = std::fs::read(maps.join("rsrp_30m.png")).expect("png");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    let sites = std::fs::read_to_string(maps.join("sites.csv")).expect("sites");
    assert_eq!(sites.lines().count(), 1 + 5, "{sites}");

    let mut args: Vec<String> = [
        "train",
        "-q",
        "--single-process",
        "--out",
        "runs/town",
        "--config",
        config,
        "--set",
        "train.total_timesteps=1024",
        "--set",
        "cache.horizontal_m=10",
        "--set",
        "cache.vertical_m=10",
    ]
    .map(String::from)
    .to_vec();
    args.extend(small_train_args(&dir.join("scenarios/town/pairs")));
    let a: Vec<&str> = args.iter().map(String::as_str).collect();
    ok(&run_in(dir, &a));
    let rows = std::fs::read_to_string(dir.join("runs/town/metrics.jsonl")).expect("metrics");
    assert_eq!(rows.lines().count(), 4, "1024 decisions / 256 per update");
    assert!(dir.join("runs/town/policy.bin").exists());
    assert!(
        dir.join("scenarios/town/cache/rsrp.bin").exists(),
        "the scenario's own cache"
    );
}

/// Bad input is refused with the file, the feature or line, and the field named.
#[test]
fn bad_raw_input_is_named() {
    let tmp = tempfile::tempdir().expect("tmp");
    let dir = tmp.path();
    write_extract(dir);
    let strict = import(dir, &["--strict"]);
    assert!(!strict.status.success());
    let e = String::from_utf8_lossy(&strict.stderr);
    assert!(
        e.contains("raw/buildings.geojson") && e.contains("osm:way/105") && e.contains("`height`"),
        "{e}"
    );
    // A flight area too small for episodes (the pairs' distances would collapse) is refused,
    // the extract's own box selecting what to keep.
    let tiny = import_box(
        dir,
        "2.3430,48.8520,2.3431,48.8521",
        &["--select", &area_arg()],
    );
    let e = String::from_utf8_lossy(&tiny.stderr);
    assert!(
        !tiny.status.success() && e.contains("too small for episodes"),
        "{e}"
    );
    // A neighbour radius below 1 m is refused before any work (it would overflow the grid).
    let tiny_r = import(dir, &["--nearby-m", "1e-300"]);
    let e = String::from_utf8_lossy(&tiny_r.stderr);
    assert!(
        !tiny_r.status.success() && e.contains("nearby radius"),
        "{e}"
    );
    let mut cells = raw_cells();
    cells.push_str("LTE,310,410,7,2560,5,2.343,north,2000,5,1,1,2,\n");
    std::fs::write(dir.join("raw/cells.csv"), cells).expect("write");
    let bad = import(dir, &[]);
    assert!(!bad.status.success());
    let e = String::from_utf8_lossy(&bad.stderr);
    assert!(e.contains("raw/cells.csv:19") && e.contains("`lat`"), "{e}");
    assert!(
        !dir.join("scenarios/town/config.toml").exists(),
        "nothing half-made"
    );
}

/// data/README.md "Reproduce": Midtown's committed buildings and cells are what `dupac scenario
/// import` writes from the source extract and cell rows in `data/source/`, byte for byte, with
/// the flight area of the default configuration.
#[test]
fn midtown_is_what_the_import_writes_from_the_source() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("midtown");
    let out_arg = out.display().to_string();
    let a = dupac_common::config::ScenarioConfig::default().area;
    let area = format!(
        "{},{},{},{}",
        a.lon_min_deg, a.lat_min_deg, a.lon_max_deg, a.lat_max_deg
    );
    ok(&run_in(
        repo,
        &[
            "scenario",
            "import",
            "--buildings",
            "data/source/manhattan.osm.pbf",
            "--cells",
            "data/source/midtown_cells_opencellid.csv",
            "--box",
            &area,
            "--select",
            "-73.99737,40.74330,-73.97263,40.76780",
            "--level-height-m",
            "3.5",
            "--source",
            "radiocells-2017",
            "--name",
            "midtown",
            "--out",
            &out_arg,
        ],
    ));
    for (written, committed) in [
        ("buildings.geojson", "data/nyc_midtown_buildings.geojson"),
        ("cells.csv", "data/nyc_midtown_cells.csv"),
    ] {
        let w = std::fs::read(out.join(written)).expect("read the import");
        let c = std::fs::read(repo.join(committed)).expect("read the committed file");
        assert!(
            w == c,
            "{committed} is not what the import writes ({} against {} bytes)",
            w.len(),
            c.len()
        );
    }
}
