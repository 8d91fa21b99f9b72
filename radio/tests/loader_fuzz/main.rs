//! Property tests of the radio crate's file loaders ("bad input, fuzzed"): the GeoJSON
//! buildings loader ([`parse_buildings`]), the LTE cells CSV ([`read_cells_csv`]) and the user
//! sites file ([`read_sites_file`], and through [`place_sites`] the per-site checks). Arbitrary
//! text, valid files with bytes flipped, cut or extended, and valid files with one value replaced
//! by a hostile one (NaN, huge, negative, a string where a number belongs, missing fields, short
//! rings, …) must never panic; every error names the file and, where the input has one, the line,
//! feature, column or key; valid files still load.

use dupac_common::config::{BuildingDetail, CityKind, Config, ScenarioConfig};
use dupac_common::geometry::Bounds2;
use dupac_radio::city::osm::parse_buildings;
use dupac_radio::city::{Building, City};
use dupac_radio::error::RadioError;
use dupac_radio::geo::LocalProjection;
use dupac_radio::sites::{SiteSpec, place_sites, read_cells_csv, read_sites_file};
use proptest::prelude::*;
use serde_json::{Value, json};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

#[path = "../common/mod.rs"]
mod common;
use common::mutate;

mod regressions;

const GEO_PATH: &str = "fuzz-buildings.geojson";
const LON0: f64 = -73.985;
const LAT0: f64 = 40.75;
const BIG: Bounds2 = Bounds2::new(-1e9, -1e9, 1e9, 1e9);

fn projection() -> LocalProjection {
    LocalProjection::new(LON0, LAT0)
}

// ---------------------------------------------------------------------------------------------
// GeoJSON buildings
// ---------------------------------------------------------------------------------------------

/// A closed rectangular ring (lon, lat), like the OSM export's.
fn rect(lon: f64, lat: f64, dlon: f64, dlat: f64) -> Value {
    json!([[
        [lon, lat],
        [lon + dlon, lat],
        [lon + dlon, lat + dlat],
        [lon, lat + dlat],
        [lon, lat]
    ]])
}

/// One feature in the shape of `data/nyc_midtown_buildings.geojson`.
fn feature(id: &str, kind: &str, ring: Value, height_m: f64, min_height_m: f64) -> Value {
    json!({
        "type": "Feature",
        "geometry": {"type": "Polygon", "coordinates": ring},
        "properties": {
            "id": id,
            "kind": kind,
            "height_m": height_m,
            "min_height_m": min_height_m,
            "height_source": "osm",
            "levels": null,
            "building": "yes",
            "name": null,
            "has_parts": false,
            "near_extract_edge": false
        }
    })
}

fn collection(features: Vec<Value>) -> Value {
    json!({"type": "FeatureCollection", "name": "fuzz", "features": features})
}

/// Three buildings: a plain one, an outline with parts and its part (with a hole).
fn valid_geojson() -> Value {
    let mut outline = feature(
        "osm:way/2",
        "building",
        rect(LON0, LAT0, 2e-4, 2e-4),
        80.0,
        0.0,
    );
    outline["properties"]["has_parts"] = json!(true);
    let mut part = feature(
        "osm:way/3",
        "building_part",
        rect(LON0, LAT0, 2e-4, 1e-4),
        80.0,
        20.0,
    );
    part["geometry"]["coordinates"]
        .as_array_mut()
        .expect("rings")
        .push(rect(LON0 + 5e-5, LAT0 + 2e-5, 2e-5, 2e-5)[0].clone());
    collection(vec![
        feature(
            "osm:way/1",
            "building",
            rect(LON0 - 5e-4, LAT0, 1e-4, 1e-4),
            30.0,
            0.0,
        ),
        outline,
        part,
    ])
}

/// Parses with both levels of detail; checks every error names the file (and the feature), and
/// every accepted building is sane.
fn judge_geojson(text: &str) -> Vec<Result<Vec<Building>, String>> {
    [BuildingDetail::Parts, BuildingDetail::Outlines]
        .into_iter()
        .map(|detail| {
            let r = parse_buildings(text, Path::new(GEO_PATH), &projection(), detail, BIG);
            match r {
                Ok(buildings) => {
                    assert!(!buildings.is_empty());
                    for b in &buildings {
                        assert!(b.outer_m.len() >= 3, "{b:?}");
                        assert!(b.holes_m.iter().all(|h| h.len() >= 3), "{b:?}");
                        let all = std::iter::once(&b.outer_m).chain(b.holes_m.iter());
                        assert!(all.flatten().flatten().all(|v| v.is_finite()), "{b:?}");
                        assert!(0.0 <= b.z_min_m && b.z_min_m < b.z_max_m, "{b:?}");
                        assert!(b.z_max_m < 2000.0 && b.area_m2() > 0.0, "{b:?}");
                    }
                    // What the loader hands on must build a city (mesh and footprint index).
                    let city = City::from_buildings(
                        "fuzz",
                        Bounds2::new(-1e3, -1e3, 1e3, 1e3),
                        buildings.clone(),
                        None,
                    );
                    if let Err(e) = city {
                        assert!(!e.to_string().is_empty());
                    }
                    Ok(buildings)
                }
                Err(e) => {
                    let msg = e.to_string();
                    assert!(msg.contains(GEO_PATH), "error without the file: {msg}");
                    if let RadioError::Feature { index, .. } = &e {
                        assert!(msg.contains(&format!("feature {index}")), "{msg}");
                    }
                    Err(msg)
                }
            }
        })
        .collect()
}

/// JSON text put in place of a value: some are not JSON at all (NaN, Infinity), most are JSON of
/// the wrong type or range.
const HOSTILE_JSON: &[&str] = &[
    "NaN",
    "Infinity",
    "-Infinity",
    "1e999",
    "1e308",
    "-1e308",
    "0",
    "-0.0",
    "-5",
    "1e-300",
    "2000",
    "18446744073709551616",
    "\"12\"",
    "\"\"",
    "\"building\"",
    "\"building_part\"",
    "\"tax_lot\"",
    "null",
    "true",
    "[]",
    "[[]]",
    "[[[]]]",
    "[1]",
    "[-73.985]",
    "[-73.985, 40.75, 10, 20]",
    "[[-73.985, 40.75], [-73.9849, 40.75]]",
    "{}",
    "{\"type\": \"Point\", \"coordinates\": [-73.985, 40.75]}",
];

/// Where a hostile value goes in [`valid_geojson`]: a JSON pointer, and the name an error about
/// it should carry (`None`: a structural place without a single name).
const GEO_TARGETS: &[(&str, Option<&str>)] = &[
    ("/features/0/properties/height_m", Some("height_m")),
    ("/features/2/properties/height_m", Some("height_m")),
    ("/features/2/properties/min_height_m", Some("min_height_m")),
    ("/features/0/properties/kind", Some("kind")),
    ("/features/1/properties/has_parts", Some("has_parts")),
    ("/features/0/properties/id", None),
    ("/features/0/properties", None),
    ("/features/0/geometry", None),
    ("/features/0/geometry/type", None),
    ("/features/0/geometry/coordinates", None),
    ("/features/0/geometry/coordinates/0", None),
    ("/features/0/geometry/coordinates/0/1", None),
    ("/features/0/geometry/coordinates/0/1/0", None),
    ("/features/0/geometry/coordinates/0/1/1", None),
    ("/features/2/geometry/coordinates/1", None),
    ("/features/2/geometry/coordinates/1/0", None),
    ("/features/1/type", None),
    ("/features/1", None),
    ("/features", None),
    ("/type", None),
];

/// [`valid_geojson`] with the value at `pointer` replaced by the raw text `raw`.
fn geojson_with(pointer: &str, raw: &str) -> String {
    let mut v = valid_geojson();
    *v.pointer_mut(pointer).expect("pointer") = json!("@@HOSTILE@@");
    v.to_string().replace("\"@@HOSTILE@@\"", raw)
}

/// [`valid_geojson`] with the field at `pointer` removed.
fn geojson_without(pointer: &str) -> String {
    let mut v = valid_geojson();
    let (parent, key) = pointer.rsplit_once('/').expect("pointer");
    match v.pointer_mut(parent).expect("parent") {
        Value::Object(m) => {
            m.remove(key);
        }
        Value::Array(a) => {
            a.remove(key.parse::<usize>().expect("index"));
        }
        _ => unreachable!("parents are objects or arrays"),
    }
    v.to_string()
}

/// Short, degenerate and odd polygons (GeoJSON `coordinates` of a Polygon).
fn odd_polygons() -> Vec<String> {
    let (a, b) = (LON0, LAT0);
    vec![
        "[]".into(),
        "[[]]".into(),
        format!("[[[{a},{b}]]]"),
        format!("[[[{a},{b}],[{a},{b}]]]"),
        // Two distinct points, closed: a ring of two vertices.
        format!("[[[{a},{b}],[{},{b}],[{a},{b}]]]", a + 1e-4),
        // Collinear: zero area.
        format!(
            "[[[{a},{b}],[{},{b}],[{},{b}],[{a},{b}]]]",
            a + 1e-4,
            a + 2e-4
        ),
        // Points closer than the 1 cm duplicate threshold.
        format!(
            "[[[{a},{b}],[{},{b}],[{},{}],[{a},{b}]]]",
            a + 1e-10,
            a + 1e-10,
            b + 1e-10
        ),
        // A valid outer ring with a 2-point hole.
        format!(
            "[{},[[{a},{b}],[{},{b}],[{a},{b}]]]",
            rect(a, b, 1e-4, 1e-4)[0],
            a + 1e-5
        ),
        // Self-intersecting bow tie.
        format!(
            "[[[{a},{b}],[{},{}],[{},{b}],[{a},{}],[{a},{b}]]]",
            a + 1e-4,
            b + 1e-4,
            a + 1e-4,
            b + 1e-4
        ),
        // Poles and the antimeridian.
        "[[[-180,-90],[180,-90],[180,90],[-180,90],[-180,-90]]]".into(),
        "[[[180.0000001,0],[0,0],[0,1],[180.0000001,0]]]".into(),
        // Coordinates with one, three and many numbers.
        format!("[[[{a}],[{a}],[{a}]]]"),
        format!(
            "[[[{a},{b},5],[{},{b},5],[{a},{},5],[{a},{b},5]]]",
            a + 1e-4,
            b + 1e-4
        ),
        format!("[[[{a},{b},1,2,3,4,5,6,7,8,9]]]"),
    ]
}

fn hostile_json() -> impl Strategy<Value = &'static str> {
    prop::sample::select(HOSTILE_JSON)
}

fn geo_target() -> impl Strategy<Value = (&'static str, Option<&'static str>)> {
    prop::sample::select(GEO_TARGETS)
}

// ---------------------------------------------------------------------------------------------
// CSV and TOML
// ---------------------------------------------------------------------------------------------

/// A file under the system temporary directory with a unique name, removed on drop.
fn temp_file(suffix: &str, contents: &[u8]) -> tempfile::NamedTempFile {
    let mut f = tempfile::Builder::new()
        .prefix("dupac-loader-fuzz-")
        .suffix(suffix)
        .tempfile_in(std::env::temp_dir())
        .expect("temp file");
    std::io::Write::write_all(&mut f, contents).expect("write temp file");
    f
}

const CELLS_HEADER: &str = "lat,lon,radio,mcc,mnc,cell_id,enb_id,local_cell_id,range_m,source";

/// Rows of the shape of `data/nyc_midtown_cells.csv`: (lat, lon, enb_id).
fn cells_text(rows: &[(f64, f64, u64)]) -> String {
    let mut s = format!("{CELLS_HEADER}\n");
    for (i, (lat, lon, enb)) in rows.iter().enumerate() {
        s.push_str(&format!(
            "{lat},{lon},LTE,,,{},{enb},{},,radiocells-2017\n",
            10_000_000 + i,
            i % 3 + 1
        ));
    }
    s
}

fn valid_cells() -> Vec<(f64, f64, u64)> {
    vec![
        (40.7675568, -73.9822783, 41156),
        (40.7596677, -73.9838201, 41169),
        (40.7600099, -73.9847174, 41169),
        (40.7590093, -73.9819709, 41170),
    ]
}

/// Reads cells text from a temporary file; checks the error names the file and a line ≥ 1.
fn judge_cells(text: &[u8]) -> Result<usize, (RadioError, PathBuf)> {
    let f = temp_file(".csv", text);
    let path = f.path().to_path_buf();
    match read_cells_csv(&path, &projection()) {
        Ok(c) => {
            assert!(
                c.iter().all(|c| c.xy_m.iter().all(|v| v.is_finite())),
                "{c:?}"
            );
            Ok(c.len())
        }
        Err(e) => {
            check_file_error(&e, &path);
            Err((e, path))
        }
    }
}

fn check_file_error(e: &RadioError, path: &Path) {
    let msg = e.to_string();
    let name = path.display().to_string();
    assert!(msg.contains(&name), "error without the file: {msg}");
    if let RadioError::Table { line, .. } = e {
        assert!(*line >= 1, "line 0 is no line: {msg}");
        assert!(msg.contains(&format!("{name}:{line}")), "{msg}");
    }
}

/// Cell (CSV field) values that do not belong in a numeric column.
const HOSTILE_CELLS: &[&str] = &[
    "",
    " ",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e309",
    "1e308",
    "-1e308",
    "-91",
    "181",
    "-0",
    "abc",
    "0x10",
    "1_000",
    "-1",
    "18446744073709551616",
    "4.5",
    "\"40.75\"",
    "\"a,b\"",
    "\u{FEFF}1",
    "é",
];

const SITES_HEADER: &str = "name,x_m,y_m,z_m,kind,boresights_deg,tilt_deg,tx_power_dbm";

fn sites_csv(rows: &[[&str; 8]]) -> String {
    let mut s = format!("{SITES_HEADER}\n");
    for r in rows {
        s.push_str(&r.join(","));
        s.push('\n');
    }
    s
}

fn valid_sites_rows() -> Vec<[&'static str; 8]> {
    vec![
        ["a", "10", "20", "30", "macro", "0;120;240", "6", "18"],
        ["b", "-50", "40", "", "micro", "", "", ""],
        ["c", "100", "-100", "25", "", "45", "", "15"],
    ]
}

const SITES_TOML: &str = "# user sites\n\
[[site]]\nname = \"t\"\nx_m = 1.0\ny_m = 2.0\nz_m = 40.0\nkind = \"macro\"\n\n\
[[site]]\nname = \"u\"\nx_m = -30.0\ny_m = 60.0\nboresights_deg = [0.0, 120.0, 240.0]\ntilt_deg = 4.0\n";

/// Hostile TOML values for a `key = value` line.
const HOSTILE_TOML: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "0",
    "-1",
    "\"12\"",
    "\"\"",
    "\"1;x;3\"",
    "true",
    "[]",
    "[nan]",
    "[\"a\"]",
    "{}",
    "\"giant\"",
    "9223372036854775807",
    "",
    "[",
];

fn judge_sites(suffix: &str, text: &[u8]) -> Result<Vec<(u64, SiteSpec)>, String> {
    let f = temp_file(suffix, text);
    let path = f.path().to_path_buf();
    match read_sites_file(&path) {
        Ok(specs) => {
            assert!(!specs.is_empty());
            let lines = String::from_utf8_lossy(text).lines().count() as u64;
            for (line, _) in &specs {
                assert!(
                    *line >= 1 && *line <= lines.max(1),
                    "line {line} of {lines}"
                );
            }
            // The per-site checks (position, height, angles) name the file and line too.
            let mut cfg = city_config();
            cfg.sites_file = Some(path.clone());
            match place_sites(&cfg, &Config::default().radio, city()) {
                Ok(sites) => {
                    assert_eq!(sites.len(), specs.len());
                    Ok(specs)
                }
                Err(e) => {
                    check_file_error(&e, &path);
                    Err(e.to_string())
                }
            }
        }
        Err(e) => {
            check_file_error(&e, &path);
            Err(e.to_string())
        }
    }
}

fn city_config() -> ScenarioConfig {
    let mut sc = ScenarioConfig {
        city: CityKind::Procedural,
        name: "procedural".into(),
        ..ScenarioConfig::default()
    };
    sc.procedural.size_m = 400.0;
    sc
}

fn city() -> &'static City {
    static CITY: OnceLock<City> = OnceLock::new();
    CITY.get_or_init(|| City::load(&city_config()).expect("procedural city"))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    // ----- GeoJSON -----

    #[test]
    fn geojson_arbitrary_text_never_panics(text in any::<String>()) {
        judge_geojson(&text);
    }

    #[test]
    fn geojson_mutated_bytes_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..8),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..24),
    ) {
        let bytes = mutate(valid_geojson().to_string().into_bytes(), flips, cut, tail);
        judge_geojson(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn geojson_hostile_values_are_named((pointer, name) in geo_target(), raw in hostile_json()) {
        let text = geojson_with(pointer, raw);
        // The feature the value is in, if any.
        let index = pointer.strip_prefix("/features/").and_then(|r| r.split('/').next());
        let results = judge_geojson(&text);
        for r in &results {
            let Err(msg) = r else { continue };
            // Not JSON at all: the position in the text; else the property at fault.
            prop_assert!(
                name.is_none_or(|name| msg.contains(name)) || msg.contains("line 1 column"),
                "{pointer} = {raw}: {msg}"
            );
            if let Some(i) = index {
                prop_assert!(
                    msg.contains(&format!("feature {i}")) || msg.contains("line 1 column"),
                    "{pointer} = {raw}: {msg}"
                );
            }
        }
        // A property of the wrong type or range is an error, never silently read as a default.
        if let Some(name) = name {
            let fine: &[&str] = match name {
                "height_m" => &["1e-300"],
                "min_height_m" => &["0", "-0.0", "-5", "1e-300", "-1e308", "null"],
                "kind" => &["\"building\"", "\"building_part\"", "null"],
                "has_parts" => &["true", "null"],
                _ => &[],
            };
            prop_assert!(
                fine.contains(&raw) || results.iter().any(|r| r.is_err()),
                "{pointer} = {raw} accepted"
            );
        }
    }

    #[test]
    fn geojson_missing_fields_never_panic((pointer, name) in geo_target()) {
        let text = geojson_without(pointer);
        for r in judge_geojson(&text) {
            if let (Err(msg), Some(name)) = (r, name) {
                prop_assert!(msg.contains(name), "without {pointer}: {msg}");
            }
        }
    }

    #[test]
    fn geojson_odd_polygons_are_rejected_with_the_feature_named(
        k in 0usize..14,
        multi in any::<bool>(),
    ) {
        let polygons = odd_polygons();
        let poly = &polygons[k % polygons.len()];
        let mut v = valid_geojson();
        *v.pointer_mut("/features/0/geometry").expect("geometry") = json!("@@HOSTILE@@");
        let geometry = if multi {
            format!(r#"{{"type":"MultiPolygon","coordinates":[{},{poly}]}}"#, rect(LON0, LAT0, 1e-4, 1e-4))
        } else {
            format!(r#"{{"type":"Polygon","coordinates":{poly}}}"#)
        };
        let text = v.to_string().replace("\"@@HOSTILE@@\"", &geometry);
        for r in judge_geojson(&text) {
            if let Err(msg) = r {
                prop_assert!(msg.contains("feature 0") && msg.contains("osm:way/1"), "{geometry}: {msg}");
            }
        }
    }

    #[test]
    fn geojson_random_polygons_never_panic(
        rings in proptest::collection::vec(
            proptest::collection::vec((-2e-3f64..2e-3, -2e-3f64..2e-3), 0..10),
            1..4,
        ),
        closed in any::<bool>(),
        scale in prop::sample::select(vec![1e-7, 1.0, 1e3, 1e5]),
        multi in any::<bool>(),
    ) {
        // Random rings (self-intersecting, holes outside the outer ring, …) at scales from
        // sub-millimetre to the whole globe (clamped to WGS84 by the loader's check).
        let rings: Vec<Value> = rings
            .into_iter()
            .map(|ring| {
                let mut pts: Vec<Value> = ring
                    .iter()
                    .map(|&(x, y)| json!([LON0 + x * scale, LAT0 + y * scale]))
                    .collect();
                if closed && let Some(first) = pts.first().cloned() {
                    pts.push(first);
                }
                Value::Array(pts)
            })
            .collect();
        let mut v = valid_geojson();
        v["features"][0]["geometry"] = if multi {
            json!({"type": "MultiPolygon", "coordinates": [rings, rect(LON0, LAT0, 1e-4, 1e-4)]})
        } else {
            json!({"type": "Polygon", "coordinates": rings})
        };
        for r in judge_geojson(&v.to_string()) {
            if let Err(msg) = r {
                prop_assert!(msg.contains("feature 0"), "{msg}");
            }
        }
    }

    #[test]
    fn geojson_valid_collections_load(
        boxes in proptest::collection::vec(
            (-0.01f64..0.01, -0.01f64..0.01, 2e-5f64..1e-3, 2e-5f64..1e-3, 1.0f64..1999.0,
             0.0f64..0.99, any::<bool>(), any::<bool>()),
            1..8,
        ),
    ) {
        let mut features = Vec::new();
        let (mut parts_n, mut outlines_n) = (0, 0);
        for (i, &(x, y, w, h, height, min_frac, is_part, has_parts)) in boxes.iter().enumerate() {
            let kind = if is_part { "building_part" } else { "building" };
            let min = if is_part { height * min_frac } else { 0.0 };
            let mut f = feature(&format!("f{i}"), kind, rect(LON0 + x, LAT0 + y, w, h), height, min);
            f["properties"]["has_parts"] = json!(has_parts && !is_part);
            features.push(f);
            if is_part { parts_n += 1 } else { outlines_n += 1; if !has_parts { parts_n += 1 } }
        }
        let text = collection(features).to_string();
        for (r, want) in judge_geojson(&text).into_iter().zip([parts_n, outlines_n]) {
            match r {
                Ok(b) => prop_assert_eq!(b.len(), want),
                Err(msg) => prop_assert!(want == 0 && msg.contains("no usable buildings"), "{msg}"),
            }
        }
    }

    // ----- cells CSV -----

    #[test]
    fn cells_arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..256)) {
        let _ = judge_cells(&bytes);
    }

    #[test]
    fn cells_mutated_bytes_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..24),
    ) {
        let bytes = mutate(cells_text(&valid_cells()).into_bytes(), flips, cut, tail);
        let _ = judge_cells(&bytes);
    }

    #[test]
    fn cells_hostile_fields_name_the_line_and_column(
        row in 0usize..4,
        column in prop::sample::select(vec![0usize, 1, 6]),
        value in prop::sample::select(HOSTILE_CELLS),
        blank in 0usize..3,
    ) {
        let text = cells_text(&valid_cells());
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        let mut fields: Vec<&str> = lines[row + 1].split(',').collect();
        fields[column] = value;
        lines[row + 1] = fields.join(",");
        // Blank lines before the changed row (the reader skips them).
        for _ in 0..blank {
            lines.insert(row + 1, String::new());
        }
        if let Err((e, path)) = judge_cells(lines.join("\n").as_bytes()) {
            let msg = e.to_string();
            // The line of the row that was changed (line 1 is the header).
            let at = format!("{}:{}:", path.display(), row + 2 + blank);
            prop_assert!(msg.contains(&at), "{value:?} in column {column}: {msg}");
            let name = ["lat", "lon", "", "", "", "", "enb_id"][column];
            prop_assert!(
                msg.contains(name) || msg.contains("fields") || msg.contains("WGS84"),
                "{value:?} in column {column}: {msg}"
            );
        }
    }

    // ----- sites files -----

    #[test]
    fn sites_arbitrary_bytes_never_panic(
        bytes in proptest::collection::vec(any::<u8>(), 0..256),
        toml in any::<bool>(),
    ) {
        let _ = judge_sites(if toml { ".toml" } else { ".csv" }, &bytes);
    }

    #[test]
    fn sites_mutated_bytes_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..24),
        toml in any::<bool>(),
    ) {
        let (suffix, text) = if toml {
            (".toml", SITES_TOML.to_string())
        } else {
            (".csv", sites_csv(&valid_sites_rows()))
        };
        let bytes = mutate(text.into_bytes(), flips, cut, tail);
        let _ = judge_sites(suffix, &bytes);
    }

    #[test]
    fn sites_csv_hostile_fields_name_the_line(
        row in 0usize..3,
        column in 0usize..8,
        value in prop::sample::select(HOSTILE_CELLS),
    ) {
        let mut rows = valid_sites_rows();
        rows[row][column] = value;
        let text = sites_csv(&rows);
        if let Err(msg) = judge_sites(".csv", text.as_bytes()) {
            let name = SITES_HEADER.split(',').nth(column).expect("column");
            prop_assert!(
                msg.contains(&format!(".csv:{}:", row + 2)) && msg.contains(name),
                "{value:?} in column {column}: {msg}"
            );
        }
    }

    #[test]
    fn sites_csv_errors_name_the_line_of_the_record(
        blanks in proptest::collection::vec(0usize..3, 4),
        multiline in proptest::collection::vec(any::<bool>(), 3),
        bad in 0usize..3,
    ) {
        // Blank lines between records and names quoted across lines: the reported line is where
        // the bad record starts.
        let mut text = format!("{SITES_HEADER}\n");
        let mut line = 2;
        let mut bad_line = 0;
        for (i, row) in valid_sites_rows().iter().enumerate() {
            for _ in 0..blanks[i] {
                text.push('\n');
                line += 1;
            }
            let mut row = row.map(str::to_string);
            if multiline[i] {
                row[0] = format!("\"{}\nsecond line\"", row[0]);
            }
            if i == bad {
                row[2] = String::new(); // no y_m: no position
                bad_line = line;
            }
            text.push_str(&row.join(","));
            text.push('\n');
            line += 1 + usize::from(multiline[i]);
        }
        for _ in 0..blanks[3] {
            text.push('\n');
        }
        let msg = judge_sites(".csv", text.as_bytes()).expect_err("a site without y_m");
        prop_assert!(msg.contains(&format!(".csv:{bad_line}:")) && msg.contains("y_m"), "{text}: {msg}");
    }

    #[test]
    fn sites_toml_hostile_values_name_the_line(
        line in 0usize..13,
        value in prop::sample::select(HOSTILE_TOML),
    ) {
        let mut lines: Vec<String> = SITES_TOML.lines().map(str::to_string).collect();
        let at = line % lines.len();
        let Some((key, _)) = lines[at].split_once(" = ") else {
            return Ok(());
        };
        let key = key.to_string();
        lines[at] = format!("{key} = {value}");
        // The `[[site]]` header of the site holding the key.
        let header = (0..=at).rev().find(|&l| lines[l] == "[[site]]").expect("header") + 1;
        if let Err(msg) = judge_sites(".toml", lines.join("\n").as_bytes()) {
            // A value left open (`[`, `"`) is noticed on a later line.
            let parse_line = msg
                .split_once("at line ")
                .and_then(|(_, r)| r.split(|c: char| !c.is_ascii_digit()).next())
                .and_then(|n| n.parse::<usize>().ok());
            prop_assert!(
                parse_line.is_some_and(|n| n == at + 1 || n > at + 1 && value == "[")
                    || msg.contains(&format!(".toml:{header}:")) && msg.contains(&key),
                "{key} = {value}: {msg}"
            );
        }
    }
}
