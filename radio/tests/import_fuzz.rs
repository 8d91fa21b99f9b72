//! Property tests of `dupac scenario import`'s readers (bad input, fuzzed): raw OSM GeoJSON and
//! OpenCelliD CSV with bytes flipped, cut or extended, and buildings with any text as their
//! height tags, never panic; every error names the file; hostile tag values are ignored (or,
//! strict, refused naming the tag) and what is written still loads.

use dupac_common::config::{BuildingDetail, LonLatBox};
use dupac_common::geometry::Bounds2;
use dupac_radio::city::osm::parse_buildings;
use dupac_radio::geo::LocalProjection;
use dupac_radio::import::opencellid::{CellRules, import_cells_from};
use dupac_radio::import::osm::{OsmRules, import_buildings_text};
use dupac_radio::import::tags::HeightRules;
use proptest::prelude::*;
use serde_json::{Value, json};
use std::path::Path;

mod common;
use common::mutate;

const SELECT: LonLatBox = LonLatBox {
    lon_min_deg: -73.990,
    lon_max_deg: -73.980,
    lat_min_deg: 40.745,
    lat_max_deg: 40.755,
};

fn rules(strict: bool) -> OsmRules {
    OsmRules {
        heights: HeightRules::default(),
        nearby_m: 150.0,
        default_height_m: 10.0,
        strict,
    }
}

fn square(lon: f64, lat: f64, side: f64) -> Value {
    json!({"type": "Polygon", "coordinates": [[[lon, lat], [lon + side, lat],
        [lon + side, lat + side], [lon, lat + side], [lon, lat]]]})
}

/// An outline with a floating part, a building by levels, one without height.
fn raw_buildings(tags: Value) -> String {
    let f = |id: u64, g: Value, t: Value| {
        let mut p = t;
        p["@id"] = json!(format!("way/{id}"));
        json!({"type": "Feature", "properties": p, "geometry": g})
    };
    json!({"type": "FeatureCollection", "features": [
        f(1, square(-73.985, 40.75, 4e-4), json!({"building": "yes", "height": "60 m"})),
        f(2, square(-73.985, 40.75, 2e-4), json!({"building:part": "yes", "height": "90", "min_height": "60"})),
        f(3, square(-73.983, 40.75, 2e-4), json!({"building": "yes", "building:levels": "4", "roof:levels": "1"})),
        f(4, square(-73.982, 40.75, 1e-4), tags),
    ]})
    .to_string()
}

const CELLS: &str = "radio,mcc,net,area,cell,unit,lon,lat,range,samples,changeable,created,updated,averageSignal\n\
LTE,310,410,7,10535937,7,-73.9822783,40.7475568,500,3,1,1,2,-80\n\
LTE,310,410,7,10535938,7,-73.9822,40.7476,,3,1,1,2,\n\
GSM,310,410,7,4321,,-73.983,40.748,2000,5,1,1,2,\n";

/// The import of `text` either succeeds with output the city loader reads, or fails naming the
/// file.
fn judge_buildings(text: &str, strict: bool) {
    match import_buildings_text(text, Path::new("raw-fuzz.geojson"), &SELECT, &rules(strict)) {
        Ok(out) => {
            let p = LocalProjection::centred_on(&SELECT);
            let big = Bounds2::new(-1e9, -1e9, 1e9, 1e9);
            for detail in [BuildingDetail::Parts, BuildingDetail::Outlines] {
                let r = parse_buildings(&out.geojson, Path::new("out"), &p, detail, big);
                // Outlines alone may be none (every feature a part): that is the loader's clear
                // error, never a panic; anything else must load.
                if let Err(e) = r {
                    assert!(e.to_string().contains("no usable buildings"), "{e}");
                }
            }
        }
        Err(e) => assert!(e.to_string().contains("raw-fuzz.geojson"), "{e}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn raw_geojson_mutated_bytes_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..8),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..24),
    ) {
        let bytes = mutate(raw_buildings(json!({"building": "yes"})).into_bytes(), flips, cut, tail);
        judge_buildings(&String::from_utf8_lossy(&bytes), false);
    }

    #[test]
    fn any_height_tag_text_is_ignored_or_named(
        height in any::<String>(),
        levels in "[-0-9.;, a-z']{0,8}",
        min_height in "[-0-9.;, a-z'\"]{0,8}",
        strict in any::<bool>(),
    ) {
        let tags = json!({"building": "yes", "height": height, "building:levels": levels,
                          "min_height": min_height, "roof:levels": levels});
        let text = raw_buildings(tags);
        if strict {
            if let Err(e) = import_buildings_text(&text, Path::new("raw-fuzz.geojson"), &SELECT, &rules(true)) {
                let e = e.to_string();
                prop_assert!(e.contains("osm:way/4") && e.contains("tag `"), "{}", e);
            }
        } else {
            let out = import_buildings_text(&text, Path::new("raw-fuzz.geojson"), &SELECT, &rules(false));
            prop_assert!(out.is_ok(), "lenient import refused: {:?}", out.err());
            judge_buildings(&text, false);
        }
    }

    #[test]
    fn opencellid_mutated_bytes_never_panic(
        flips in proptest::collection::vec((any::<usize>(), any::<u8>()), 0..8),
        cut in any::<usize>(),
        tail in proptest::collection::vec(any::<u8>(), 0..24),
        strict in any::<bool>(),
    ) {
        let bytes = mutate(CELLS.as_bytes().to_vec(), flips, cut, tail);
        let rules = CellRules { radio: "LTE".into(), source: "fuzz".into(), strict };
        match import_cells_from(bytes.as_slice(), Path::new("cells-fuzz.csv"), &SELECT, &rules) {
            Ok(out) => prop_assert!(out.counts.kept <= out.counts.rows),
            Err(e) => prop_assert!(e.to_string().contains("cells-fuzz.csv"), "{}", e),
        }
    }
}

#[test]
fn the_valid_samples_import() {
    let out = import_buildings_text(
        &raw_buildings(json!({"building": "yes"})),
        Path::new("r"),
        &SELECT,
        &rules(true),
    )
    .expect("buildings");
    assert_eq!(
        (out.counts.outlines, out.counts.parts),
        (3, 1),
        "{:?}",
        out.counts
    );
    let rules = CellRules {
        radio: "LTE".into(),
        source: "fuzz".into(),
        strict: true,
    };
    let cells =
        import_cells_from(CELLS.as_bytes(), Path::new("c"), &SELECT, &rules).expect("cells");
    assert_eq!((cells.counts.kept, cells.counts.sites), (2, 1));
}
