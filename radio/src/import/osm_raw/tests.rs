use super::model::MemberKind;
use super::*;
use crate::import::osm::{OsmRules, import_buildings};
use crate::import::tags::HeightRules;
use dupac_common::config::LonLatBox;
use serde_json::json;
use std::path::PathBuf;

mod manhattan;
mod pbf_writer;

/// An element's tags.
type Tags = Vec<(&'static str, &'static str)>;

/// A relation member: kind, id, role.
type Member = (MemberKind, i64, &'static str);

/// A small OSM data set, written by the tests in every format.
struct Data {
    /// `(id, lon, lat)`, positions in 10⁻⁷ degrees.
    nodes: Vec<(i64, i64, i64)>,
    ways: Vec<(i64, Vec<i64>, Tags)>,
    relations: Vec<(i64, Vec<Member>, Tags)>,
}

/// Around (-73.985, 40.75).
const LON0: i64 = -739_850_000;
const LAT0: i64 = 407_500_000;

/// The nodes of an axis-aligned square: ids `first..first+4`, south-west corner at
/// `(LON0 + dx, LAT0 + dy)`, side `side` (10⁻⁷ degrees), counter-clockwise.
fn square(first: i64, dx: i64, dy: i64, side: i64) -> Vec<(i64, i64, i64)> {
    let (x, y) = (LON0 + dx, LAT0 + dy);
    vec![
        (first, x, y),
        (first + 1, x + side, y),
        (first + 2, x + side, y + side),
        (first + 3, x, y + side),
    ]
}

/// A building outline (way 10) with a part (way 11) inside it; a multipolygon building
/// (relation 100) whose outer ring is way 20 and whose inner ring is ways 21 and 22, the second
/// drawn the other way; a building (way 12) with a node the file lacks; a closed road (way 13).
fn fixture() -> Data {
    let mut nodes = Vec::new();
    nodes.extend(square(1, 0, 0, 4000));
    nodes.extend(square(5, 1000, 1000, 1500));
    nodes.extend(square(20, 10_000, 0, 6000));
    nodes.extend(square(30, 12_000, 2000, 2000));
    nodes.extend(square(40, 0, 10_000, 3000));
    nodes.extend(square(50, 20_000, 0, 3000));
    Data {
        nodes,
        ways: vec![
            (
                10,
                vec![1, 2, 3, 4, 1],
                vec![("building", "yes"), ("height", "20")],
            ),
            (
                11,
                vec![5, 6, 7, 8, 5],
                vec![("building:part", "yes"), ("height", "30")],
            ),
            (12, vec![40, 41, 999, 43, 40], vec![("building", "house")]),
            (13, vec![50, 51, 52, 53, 50], vec![("highway", "service")]),
            (20, vec![20, 21, 22, 23, 20], vec![]),
            (21, vec![30, 31, 32], vec![]),
            (22, vec![30, 33, 32], vec![]),
        ],
        relations: vec![(
            100,
            vec![
                (MemberKind::Way, 20, "outer"),
                (MemberKind::Way, 21, "inner"),
                (MemberKind::Way, 22, "inner"),
            ],
            vec![
                ("type", "multipolygon"),
                ("building", "yes"),
                ("height", "50"),
            ],
        )],
    }
}

/// 10⁻⁷ degrees as OSM writes them: 7 decimals.
fn deg(e7: i64) -> String {
    format!("{:.7}", e7 as f64 / 1e7)
}

fn xml(d: &Data) -> String {
    let tags = |t: &[(&str, &str)]| {
        t.iter()
            .map(|(k, v)| format!("    <tag k=\"{k}\" v=\"{v}\"/>\n"))
            .collect::<String>()
    };
    let mut s = String::from(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<osm version=\"0.6\" generator=\"test\">\n",
    );
    for &(id, lon, lat) in &d.nodes {
        s += &format!(
            "  <node id=\"{id}\" lat=\"{}\" lon=\"{}\"/>\n",
            deg(lat),
            deg(lon)
        );
    }
    for (id, refs, t) in &d.ways {
        s += &format!("  <way id=\"{id}\">\n");
        for r in refs {
            s += &format!("    <nd ref=\"{r}\"/>\n");
        }
        s += &tags(t);
        s += "  </way>\n";
    }
    for (id, members, t) in &d.relations {
        s += &format!("  <relation id=\"{id}\">\n");
        for (kind, r, role) in members {
            let kind = kind_name(*kind);
            s += &format!("    <member type=\"{kind}\" ref=\"{r}\" role=\"{role}\"/>\n");
        }
        s += &tags(t);
        s += "  </relation>\n";
    }
    s + "</osm>\n"
}

fn kind_name(k: MemberKind) -> &'static str {
    match k {
        MemberKind::Node => "node",
        MemberKind::Way => "way",
        MemberKind::Relation => "relation",
    }
}

fn tag_object(t: &[(&str, &str)]) -> Value {
    Value::Object(t.iter().map(|(k, v)| (k.to_string(), json!(v))).collect())
}

/// The position of node `n` as Overpass writes it, `null` when the data lacks it.
fn point(d: &Data, n: i64) -> Value {
    match d.nodes.iter().find(|x| x.0 == n) {
        Some(&(_, lon, lat)) => json!({"lat": lat as f64 / 1e7, "lon": lon as f64 / 1e7}),
        None => Value::Null,
    }
}

/// Overpass JSON as `out body; >; out skel qt;` writes it: the ways and relations, then the
/// nodes.
fn overpass_body(d: &Data) -> String {
    let mut elements = Vec::new();
    for (id, refs, t) in &d.ways {
        elements.push(json!({"type": "way", "id": id, "nodes": refs, "tags": tag_object(t)}));
    }
    for (id, members, t) in &d.relations {
        let m: Vec<Value> = members
            .iter()
            .map(|(k, r, role)| json!({"type": kind_name(*k), "ref": r, "role": role}))
            .collect();
        elements.push(json!({"type": "relation", "id": id, "members": m, "tags": tag_object(t)}));
    }
    for &(id, lon, lat) in &d.nodes {
        elements.push(
            json!({"type": "node", "id": id, "lat": lat as f64 / 1e7, "lon": lon as f64 / 1e7}),
        );
    }
    serde_json::to_string_pretty(
        &json!({"version": 0.6, "generator": "test", "elements": elements}),
    )
    .expect("json")
}

/// Overpass JSON as `out geom` writes a building query: the tagged ways with `nodes` and
/// `geometry`, the relations with their members' geometry; no nodes, no untagged ways.
fn overpass_geom(d: &Data) -> String {
    let mut elements = Vec::new();
    for (id, refs, t) in d.ways.iter().filter(|w| !w.2.is_empty()) {
        let g: Vec<Value> = refs.iter().map(|&n| point(d, n)).collect();
        elements.push(
            json!({"type": "way", "id": id, "nodes": refs, "geometry": g, "tags": tag_object(t)}),
        );
    }
    for (id, members, t) in &d.relations {
        let m: Vec<Value> = members
            .iter()
            .map(|(k, r, role)| {
                let refs = &d.ways.iter().find(|w| w.0 == *r).expect("member").1;
                let g: Vec<Value> = refs.iter().map(|&n| point(d, n)).collect();
                json!({"type": kind_name(*k), "ref": r, "role": role, "geometry": g})
            })
            .collect();
        elements.push(json!({"type": "relation", "id": id, "members": m, "tags": tag_object(t)}));
    }
    json!({"version": 0.6, "elements": elements}).to_string()
}

/// The areas of the fixture as osmtogeojson would write them.
fn geojson(d: &Data) -> String {
    let ring = |refs: &[i64]| -> Vec<Value> {
        refs.iter()
            .map(|&n| {
                let p = point(d, n);
                json!([p["lon"], p["lat"]])
            })
            .collect()
    };
    let way = |id: i64| &d.ways.iter().find(|w| w.0 == id).expect("way").1;
    let props = |t: &[(&str, &str)], id: &str| {
        let mut p = tag_object(t);
        p["@id"] = json!(id);
        p
    };
    let features = vec![
        json!({"type": "Feature", "properties": props(&d.ways[0].2, "way/10"),
            "geometry": {"type": "Polygon", "coordinates": [ring(way(10))]}}),
        json!({"type": "Feature", "properties": props(&d.ways[1].2, "way/11"),
            "geometry": {"type": "Polygon", "coordinates": [ring(way(11))]}}),
        json!({"type": "Feature", "properties": props(&d.relations[0].2, "relation/100"),
            "geometry": {"type": "MultiPolygon", "coordinates":
                [[ring(way(20)), ring(&[30, 31, 32, 33, 30])]]}}),
    ];
    json!({"type": "FeatureCollection", "features": features}).to_string()
}

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

/// Writes `bytes` as `<dir>/<sub>/buildings.osm`: one name for every format, which is told by
/// content.
fn write(dir: &Path, sub: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(sub).join("buildings.osm");
    std::fs::create_dir_all(path.parent().expect("dir")).expect("mkdir");
    std::fs::write(&path, bytes).expect("write");
    path
}

fn osm(path: &Path) -> OsmBuildings {
    match read(path).expect("reads") {
        Source::Osm(o) => o,
        Source::GeoJson(_) => panic!("{}: read as GeoJSON", path.display()),
    }
}

#[test]
fn areas_are_assembled_from_ways_and_multipolygons() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = fixture();
    let o = osm(&write(dir.path(), "xml", xml(&d).as_bytes()));
    assert_eq!(o.format, Format::Xml);
    let ids: Vec<&str> = o
        .collection
        .features
        .iter()
        .map(|f| {
            f.properties.as_ref().expect("props")["@id"]
                .as_str()
                .expect("id")
        })
        .collect();
    assert_eq!(
        ids,
        ["way/10", "way/11", "relation/100"],
        "ways by id, then relations"
    );
    let rel = serde_json::to_value(&o.collection.features[2]).expect("json");
    let e7 = |v: &Value| (v.as_f64().expect("deg") * 1e7).round() as i64;
    let rings: Vec<Vec<(i64, i64)>> = rel["geometry"]["coordinates"][0]
        .as_array()
        .expect("polygon")
        .iter()
        .map(|r| {
            r.as_array()
                .expect("ring")
                .iter()
                .map(|p| (e7(&p[0]), e7(&p[1])))
                .collect()
        })
        .collect();
    let at = |ids: &[i64]| -> Vec<(i64, i64)> {
        ids.iter()
            .map(|n| {
                let x = d.nodes.iter().find(|x| x.0 == *n).expect("node");
                (x.1, x.2)
            })
            .collect()
    };
    assert_eq!(rel["geometry"]["type"], "MultiPolygon");
    assert_eq!(
        rings,
        [at(&[20, 21, 22, 23, 20]), at(&[30, 31, 32, 33, 30])]
    );
    assert_eq!(rel["properties"]["height"], "50");
    assert_eq!(o.incomplete.len(), 1);
    let cut = &o.incomplete[0];
    assert_eq!(
        (cut.id.as_str(), cut.why),
        ("way/12", area::Why::MissingMembers)
    );
    assert_eq!((cut.nodes, cut.nodes_present), (5, 4));
    let b = cut.present_bbox_deg.expect("bbox");
    assert_eq!(b, [-73.985, 40.751, -73.9847, 40.7513]);
}

#[test]
fn every_format_gives_the_same_buildings_byte_for_byte() {
    let dir = tempfile::tempdir().expect("tmp");
    let d = fixture();
    let files = [
        ("geojson", geojson(&d).into_bytes(), "GeoJSON"),
        ("xml", xml(&d).into_bytes(), "OSM XML"),
        ("body", overpass_body(&d).into_bytes(), "Overpass JSON"),
        ("geom", overpass_geom(&d).into_bytes(), "Overpass JSON"),
        ("pbf", pbf_writer::write(&d), "OSM PBF"),
    ];
    let mut outputs = Vec::new();
    for (sub, bytes, format) in files {
        let out = import_buildings(&write(dir.path(), sub, &bytes), &SELECT, &rules())
            .unwrap_or_else(|e| panic!("{sub}: {e}"));
        assert_eq!(out.format, format, "{sub}");
        let incomplete = if sub == "geojson" { 0 } else { 1 };
        assert_eq!(out.counts.incomplete, incomplete, "{sub}");
        outputs.push((sub, out));
    }
    let first = &outputs[0].1;
    let v: Value = serde_json::from_str(&first.geojson).expect("json");
    let props: Vec<(&str, &str)> = v["features"]
        .as_array()
        .expect("features")
        .iter()
        .map(|f| {
            let p = &f["properties"];
            (
                p["id"].as_str().expect("id"),
                p["kind"].as_str().expect("kind"),
            )
        })
        .collect();
    assert_eq!(
        props,
        [
            ("osm:way/10", "building"),
            ("osm:way/11", "building_part"),
            ("osm:relation/100", "building")
        ]
    );
    assert_eq!(v["features"][0]["properties"]["has_parts"], json!(true));
    assert_eq!(v["features"][2]["properties"]["height_m"], json!(50.0));
    for (sub, out) in &outputs[1..] {
        assert_eq!(out.geojson, first.geojson, "{sub} differs from GeoJSON");
    }
}

#[test]
fn positions_are_osms_seven_decimals() {
    assert_eq!(
        model::Coord::from_nano(-73_985_012_349, 40_750_000_050).lon_e7,
        -739_850_123
    );
    assert_eq!(
        model::Coord::from_nano(-73_985_012_351, 40_750_000_050).lon_e7,
        -739_850_124
    );
    assert_eq!(
        model::Coord::from_nano(0, 40_750_000_050).lat_e7,
        407_500_001
    );
    let c = model::Coord::from_deg(-73.9851234, 40.7512345).expect("wgs84");
    assert_eq!((c.lon_e7, c.lat_e7), (-739_851_234, 407_512_345));
    assert_eq!(c.lat_deg().to_string(), "40.7512345");
    assert!(model::Coord::from_deg(200.0, 0.0).is_none());
}

#[test]
fn rings_that_do_not_close_are_no_area() {
    let mut d = fixture();
    // The inner ring loses its second half: relation 100 cannot close it.
    d.relations[0].1.pop();
    // Way 10 no longer returns to its first node.
    d.ways[0].1.pop();
    let dir = tempfile::tempdir().expect("tmp");
    let o = osm(&write(dir.path(), "x", xml(&d).as_bytes()));
    let ids: Vec<(&str, area::Why)> = o
        .incomplete
        .iter()
        .map(|i| (i.id.as_str(), i.why))
        .collect();
    assert_eq!(
        ids,
        [
            ("way/10", area::Why::Unclosed),
            ("way/12", area::Why::MissingMembers),
            ("relation/100", area::Why::Unclosed)
        ]
    );
    assert_eq!(o.collection.features.len(), 1, "only the part is left");
}

fn error(dir: &Path, sub: &str, bytes: &[u8]) -> String {
    let path = write(dir, sub, bytes);
    match read(&path) {
        Ok(_) => panic!("{sub}: read"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn malformed_files_are_refused_naming_file_and_line_or_element() {
    let dir = tempfile::tempdir().expect("tmp");
    let e = error(
        dir.path(),
        "xml1",
        b"<?xml version=\"1.0\"?>\n<osm>\n  <way id=\"1\">\n</osm>\n",
    );
    assert!(
        e.contains("xml1/buildings.osm") && e.contains("line 4"),
        "{e}"
    );
    let bad_ref = "<osm>\n <way id=\"7\">\n  <nd ref=\"1\"/>\n  <nd ref=\"x\"/>\n  \
                   <tag k=\"building\" v=\"yes\"/>\n </way>\n</osm>\n";
    let e = error(dir.path(), "xml2", bad_ref.as_bytes());
    assert!(
        e.contains("xml2/buildings.osm: line 4 (way/7)") && e.contains("`ref`"),
        "{e}"
    );
    let e = error(
        dir.path(),
        "xml3",
        b"<osm>\n<node id=\"a\" lat=\"1\" lon=\"2\"/>\n</osm>",
    );
    assert!(e.contains("line 2") && e.contains("`id`"), "{e}");

    let e = error(
        dir.path(),
        "json1",
        b"{\"elements\": [\n  {\"type\": \"node\" \"id\": 1}\n]}",
    );
    assert!(
        e.contains("json1/buildings.osm: line 2, column") && e.contains("Overpass"),
        "{e}"
    );
    let e = error(
        dir.path(),
        "json2",
        br#"{"elements": [{"type": "way", "id": 9, "nodes": [1, "2"], "tags": {"building": "yes"}}]}"#,
    );
    assert!(
        e.contains("element 0 (way/9)") && e.contains("`nodes`[1]"),
        "{e}"
    );

    let mut pbf = pbf_writer::write(&fixture());
    let cut = pbf.len() - 20;
    pbf.truncate(cut);
    let e = error(dir.path(), "pbf", &pbf);
    assert!(
        e.contains("pbf/buildings.osm: blob 1") && e.contains("PBF"),
        "{e}"
    );

    let e = error(dir.path(), "other", b"name,height\nA,3\n");
    assert!(
        e.contains("other/buildings.osm") && e.contains("not a buildings file"),
        "{e}"
    );
}

#[test]
fn content_not_name_tells_the_format() {
    use format::{json_kind, sniff};
    assert_eq!(
        sniff(&pbf_writer::write(&fixture())[..32]),
        Some(Format::Pbf)
    );
    assert_eq!(sniff(b"\xEF\xBB\xBF  <?xml version"), Some(Format::Xml));
    assert_eq!(sniff(b"\n<osm version=\"0.6\">"), Some(Format::Xml));
    assert_eq!(sniff(b"{\"type\""), Some(Format::GeoJson));
    assert_eq!(sniff(b"<html>"), None);
    assert_eq!(sniff(b"\x00\x00\x00\x0e\x0a\x07OSMData"), None);
    assert_eq!(
        json_kind(r#"{"version":0.6,"elements":[]}"#),
        Format::OverpassJson
    );
    assert_eq!(
        json_kind(r#"{"type":"FeatureCollection","features":[]}"#),
        Format::GeoJson
    );
}
