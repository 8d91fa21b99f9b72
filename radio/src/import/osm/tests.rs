use super::*;
use crate::city::osm::parse_buildings;
use dupac_common::config::BuildingDetail;
use dupac_common::geometry::Bounds2;

/// ≈ 850 m × 1100 m around (-73.985, 40.75).
const SELECT: LonLatBox = LonLatBox {
    lon_min_deg: -73.990,
    lon_max_deg: -73.980,
    lat_min_deg: 40.745,
    lat_max_deg: 40.755,
};

fn rules() -> OsmRules {
    OsmRules {
        heights: HeightRules::default(),
        nearby_m: 150.0,
        default_height_m: 10.0,
        strict: false,
    }
}

/// A square of `side` degrees with its south-west corner at (lon, lat).
fn square(lon: f64, lat: f64, side: f64) -> Value {
    json!({"type": "Polygon", "coordinates": [[[lon, lat], [lon + side, lat],
        [lon + side, lat + side], [lon, lat + side], [lon, lat]]]})
}

fn feature(id: u64, geometry: Value, tags: Value) -> Value {
    let mut p = tags;
    p["@id"] = json!(format!("way/{id}"));
    json!({"type": "Feature", "properties": p, "geometry": geometry})
}

fn run(features: Vec<Value>, rules: &OsmRules) -> Result<(Vec<Value>, BuildingCounts), RadioError> {
    let text = json!({"type": "FeatureCollection", "features": features}).to_string();
    let out = import_buildings_text(&text, Path::new("raw.geojson"), &SELECT, rules)?;
    let v: Value = serde_json::from_str(&out.geojson).expect("json");
    let props = v["features"]
        .as_array()
        .expect("features")
        .iter()
        .map(|f| f["properties"].clone())
        .collect();
    Ok((props, out.counts))
}

fn by_id<'a>(props: &'a [Value], id: &str) -> &'a Value {
    props
        .iter()
        .find(|p| p["id"] == id)
        .unwrap_or_else(|| panic!("{id} missing"))
}

#[test]
fn parts_replace_their_outline_and_give_it_a_height() {
    let (props, counts) = run(
        vec![
            feature(1, square(-73.985, 40.75, 4e-4), json!({"building": "yes"})),
            feature(
                2,
                square(-73.985, 40.75, 2e-4),
                json!({"building:part": "yes", "height": "40"}),
            ),
            feature(
                3,
                square(-73.9848, 40.7502, 2e-4),
                json!({"building:part": "yes", "height": "80", "min_height": "40"}),
            ),
            feature(
                4,
                square(-73.9848, 40.75, 1e-4),
                json!({"building:part": "yes"}),
            ),
            feature(
                5,
                square(-73.983, 40.75, 1e-4),
                json!({"building:part": "yes", "height": "9"}),
            ),
        ],
        &rules(),
    )
    .expect("ok");
    let outline = by_id(&props, "osm:way/1");
    assert_eq!(outline["has_parts"], json!(true));
    assert_eq!(outline["height_m"], json!(80.0));
    assert_eq!(outline["height_source"], "max_of_osm_building_parts");
    assert_eq!(by_id(&props, "osm:way/3")["min_height_m"], json!(40.0));
    assert_eq!(by_id(&props, "osm:way/3")["kind"], "building_part");
    // A part without height or levels, and an outline without a tagged height: the
    // nearby percentile (the only tagged outline is none here: the default).
    assert_eq!(
        by_id(&props, "osm:way/4")["height_source"],
        "fallback:default_10m"
    );
    assert_eq!(
        by_id(&props, "osm:way/5")["kind"],
        "building",
        "an orphan part"
    );
    assert_eq!(
        (counts.outlines, counts.parts, counts.orphan_parts),
        (1, 3, 1)
    );
    assert_eq!(counts.outlines_with_parts, 1);
}

#[test]
fn a_part_takes_its_outlines_tagged_height() {
    let (props, _) = run(
        vec![
            feature(
                1,
                square(-73.985, 40.75, 4e-4),
                json!({"building": "yes", "height": "33"}),
            ),
            feature(
                2,
                square(-73.985, 40.75, 2e-4),
                json!({"building:part": "yes"}),
            ),
        ],
        &rules(),
    )
    .expect("ok");
    assert_eq!(by_id(&props, "osm:way/2")["height_m"], json!(33.0));
    assert_eq!(
        by_id(&props, "osm:way/2")["height_source"],
        "osm:height_of_outline"
    );
}

#[test]
fn whole_buildings_are_kept_by_centroid_never_clipped() {
    // Straddles the east edge (-73.980) with its centroid inside; the next one outside.
    let inside = square(-73.9803, 40.75, 2e-4);
    let (props, counts) = run(
        vec![
            feature(
                1,
                inside.clone(),
                json!({"building": "yes", "height": "20"}),
            ),
            feature(
                2,
                square(-73.9799, 40.75, 2e-4),
                json!({"building": "yes", "height": "20"}),
            ),
        ],
        &rules(),
    )
    .expect("ok");
    assert_eq!(props.len(), 1);
    assert_eq!(counts.outside, 1);
    let text = json!({"type": "FeatureCollection", "features": [
        feature(1, inside.clone(), json!({"building": "yes", "height": "20"}))]})
    .to_string();
    let out = import_buildings_text(&text, Path::new("r"), &SELECT, &rules()).expect("ok");
    let v: Value = serde_json::from_str(&out.geojson).expect("json");
    assert_eq!(v["features"][0]["geometry"], inside, "coordinates as read");
}

#[test]
fn untagged_buildings_take_the_nearby_75th_percentile() {
    let mut features: Vec<Value> = [10.0, 20.0, 30.0, 40.0]
        .iter()
        .enumerate()
        .map(|(i, h)| {
            feature(
                i as u64 + 1,
                square(-73.985 + 2e-4 * i as f64, 40.75, 1e-4),
                json!({"building": "yes", "height": h.to_string()}),
            )
        })
        .collect();
    features.push(feature(
        9,
        square(-73.985, 40.7503, 1e-4),
        json!({"building": "yes"}),
    ));
    let (props, counts) = run(features.clone(), &rules()).expect("ok");
    assert_eq!(by_id(&props, "osm:way/9")["height_m"], json!(32.5));
    assert_eq!(counts.height_sources["osm:height"], 4);
    let off = OsmRules {
        nearby_m: 0.0,
        ..rules()
    };
    let (props, _) = run(features, &off).expect("ok");
    assert_eq!(by_id(&props, "osm:way/9")["height_m"], json!(10.0));
}

#[test]
fn skipped_features_are_counted_and_bottoms_above_the_roof_dropped() {
    let (props, counts) = run(
        vec![
            feature(
                1,
                square(-73.985, 40.75, 1e-4),
                json!({"building": "yes", "height": "10", "min_height": "12"}),
            ),
            feature(
                2,
                square(-73.984, 40.75, 1e-4),
                json!({"building": "yes", "location": "underground"}),
            ),
            // Under a viaduct: `layer` orders crossings, the building stands.
            feature(
                6,
                square(-73.981, 40.75, 1e-4),
                json!({"building": "yes", "layer": "-1", "height": "8"}),
            ),
            feature(
                3,
                square(-73.983, 40.75, 1e-4),
                json!({"building": "no", "height": "5"}),
            ),
            feature(
                4,
                json!({"type": "Point", "coordinates": [-73.985, 40.75]}),
                json!({"building": "yes"}),
            ),
            feature(5, square(-73.982, 40.75, 1e-9), json!({"building": "yes"})),
        ],
        &rules(),
    )
    .expect("ok");
    assert_eq!(props.len(), 2);
    assert_eq!(props[1]["height_m"], json!(8.0));
    assert_eq!(props[0]["min_height_m"], json!(0.0));
    assert_eq!(
        props[0]["height_source"],
        "osm:height|inconsistent_min_height_dropped"
    );
    let c = counts;
    assert_eq!(
        (c.underground, c.not_building, c.not_area, c.degenerate),
        (1, 1, 1, 1)
    );
    assert_eq!(c.min_height_dropped, 1);
}

#[test]
fn bad_tags_are_ignored_or_refused_naming_file_feature_and_tag() {
    let f = vec![feature(
        7,
        square(-73.985, 40.75, 1e-4),
        json!({"building": "yes", "height": "12,5", "building:levels": "4"}),
    )];
    let (props, counts) = run(f.clone(), &rules()).expect("lenient");
    assert_eq!(
        props[0]["height_m"],
        json!(12.0),
        "levels after the bad height"
    );
    assert_eq!(counts.bad_tags, 1);
    let strict = OsmRules {
        strict: true,
        ..rules()
    };
    let e = run(f, &strict).expect_err("strict").to_string();
    assert!(
        e.contains("raw.geojson")
            && e.contains("feature 0")
            && e.contains("osm:way/7")
            && e.contains("`height`"),
        "{e}"
    );
    let e = run(
        vec![feature(
            8,
            json!({"type": "Polygon", "coordinates": [[[-73.985, 40.75],
        [200.0, 40.75], [-73.985, 40.76], [-73.985, 40.75]]]}),
            json!({"building": "yes"}),
        )],
        &rules(),
    )
    .expect_err("lon 200")
    .to_string();
    assert!(e.contains("osm:way/8") && e.contains("WGS84"), "{e}");
    let e = import_buildings_text(
        r#"{"version":0.6,"elements":[]}"#,
        Path::new("o.json"),
        &SELECT,
        &rules(),
    )
    .expect_err("overpass")
    .to_string();
    assert!(e.contains("o.json") && e.contains("Overpass JSON"), "{e}");
    let e = run(vec![], &rules()).expect_err("none").to_string();
    assert!(e.contains("no usable buildings"), "{e}");
}

#[test]
fn ids_of_every_converter_become_osm_ids() {
    let p = |v: Value| v.as_object().expect("obj").clone();
    assert_eq!(
        feature_id(&p(json!({"@id": "way/5"})), None, 0),
        "osm:way/5"
    );
    assert_eq!(
        feature_id(&p(json!({"type": "relation", "id": 6})), None, 0),
        "osm:relation/6"
    );
    let id = geojson::feature::Id::String("w7".into());
    assert_eq!(feature_id(&p(json!({})), Some(&id), 0), "osm:way/7");
    assert_eq!(feature_id(&p(json!({})), None, 3), "#3");
}

#[test]
fn the_output_loads_with_parts_and_with_outlines() {
    let text = json!({"type": "FeatureCollection", "features": [
        feature(1, square(-73.985, 40.75, 4e-4), json!({"building": "yes", "height": "50"})),
        feature(2, square(-73.985, 40.75, 2e-4), json!({"building:part": "yes", "height": "50"})),
        feature(3, square(-73.983, 40.75, 2e-4), json!({"building": "yes", "building:levels": "3"})),
    ]})
    .to_string();
    let out = import_buildings_text(&text, Path::new("r"), &SELECT, &rules()).expect("ok");
    let p = LocalProjection::centred_on(&SELECT);
    let big = Bounds2::new(-1e6, -1e6, 1e6, 1e6);
    let parts = parse_buildings(&out.geojson, Path::new("b"), &p, BuildingDetail::Parts, big)
        .expect("loads");
    let ids: Vec<&str> = parts.iter().map(|b| b.id.as_str()).collect();
    assert_eq!(ids, ["osm:way/2", "osm:way/3"]);
    let outlines = parse_buildings(
        &out.geojson,
        Path::new("b"),
        &p,
        BuildingDetail::Outlines,
        big,
    )
    .expect("loads");
    assert_eq!(outlines.len(), 2);
    assert_eq!(outlines[1].z_max_m, 9.0);
}
