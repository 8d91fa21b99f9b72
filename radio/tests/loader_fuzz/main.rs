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

mod cells_sites;
use cells_sites::*;

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
}
