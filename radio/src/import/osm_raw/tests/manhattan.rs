//! The real extract `data/source/manhattan.osm.pbf` (osmium, bbox −74.014, 40.736, −73.963,
//! 40.759; data/README.md): real PBF decoding (zlib blobs, dense nodes) and the assembly of a
//! city's buildings, with the numbers they give.

use super::super::area::{Incomplete, Why};
use super::super::{Source, read};
use crate::import::osm::import_buildings;
use dupac_common::config::LonLatBox;
use std::path::{Path, PathBuf};

fn extract() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../data/source/manhattan.osm.pbf")
}

/// The extract's box (osmium's `--bbox`).
const EXTRACT: [f64; 4] = [-74.014, 40.736, -73.963, 40.759];

/// data/README.md's selection box of the Midtown buildings.
const SELECT: LonLatBox = LonLatBox {
    lon_min_deg: -73.99737,
    lat_min_deg: 40.74820,
    lon_max_deg: -73.97263,
    lat_max_deg: 40.76780,
};

/// The counts of the extract in the Midtown selection box: data/README.md's pyosmium
/// conversion gave 1 809 outlines (267 with parts), 2 623 parts, 46 parts without an outline.
#[test]
fn the_manhattan_extract_imports() {
    let out = import_buildings(&extract(), &SELECT, &super::rules()).expect("imports");
    let c = &out.counts;
    assert_eq!(out.format, "OSM PBF");
    assert_eq!(
        (
            c.features,
            c.outlines,
            c.outlines_with_parts,
            c.parts,
            c.orphan_parts
        ),
        (13_493, 1_810, 267, 2_626, 46),
        "{c:?}"
    );
    // osmium cut the ways at the box, keeping only their nodes inside it: every building
    // crossing an edge is left open.
    assert_eq!(c.incomplete, 143);
    assert!(out.incomplete.iter().all(|i| i.why == Why::Unclosed));
    let north: Vec<&Incomplete> = out
        .incomplete
        .iter()
        .filter(|i| edges(i).contains("north"))
        .collect();
    assert_eq!(north.len(), 63);
    let south_most = north
        .iter()
        .filter_map(|i| i.present_bbox_deg.map(|b| b[1]))
        .fold(f64::INFINITY, f64::min);
    assert_eq!(south_most, 40.7562151);
}

/// Which edges of the extract an incomplete element's present nodes come within 0.001° of.
fn edges(i: &Incomplete) -> String {
    let Some(b) = i.present_bbox_deg else {
        return "no nodes".into();
    };
    let near = 1e-3;
    let mut e = Vec::new();
    if b[3] > EXTRACT[3] - near {
        e.push("north");
    }
    if b[1] < EXTRACT[1] + near {
        e.push("south");
    }
    if b[0] < EXTRACT[0] + near {
        e.push("west");
    }
    if b[2] > EXTRACT[2] - near {
        e.push("east");
    }
    if e.is_empty() {
        "inside".into()
    } else {
        e.join("+")
    }
}

/// Prints the building elements the extract's cut left incomplete, by edge (with the southern-
/// and northernmost latitude of their present nodes), and the complete outlines per 0.0005°
/// band of latitude by the centroid of their largest outer ring.
/// `cargo test -p dupac-radio --lib manhattan_report -- --ignored --nocapture`
#[test]
#[ignore = "prints an analysis of the extract"]
fn manhattan_report() {
    let Source::Osm(o) = read(&extract()).expect("reads") else {
        panic!("not read as OSM")
    };
    println!(
        "areas {}, incomplete {}",
        o.collection.features.len(),
        o.incomplete.len()
    );
    let mut by_edge: std::collections::BTreeMap<(String, String), Vec<&Incomplete>> =
        Default::default();
    for i in &o.incomplete {
        let kind = if i.id.starts_with("way/") {
            "way"
        } else {
            "relation"
        };
        let why = match i.why {
            Why::MissingMembers => "missing members",
            Why::Unclosed => "unclosed",
            Why::InnerOutside => "inner outside",
        };
        by_edge
            .entry((edges(i), format!("{kind}, {why}")))
            .or_default()
            .push(i);
    }
    for ((edge, what), list) in &by_edge {
        let lat_min = list
            .iter()
            .filter_map(|i| i.present_bbox_deg.map(|b| b[1]))
            .fold(f64::INFINITY, f64::min);
        let lat_max = list
            .iter()
            .filter_map(|i| i.present_bbox_deg.map(|b| b[3]))
            .fold(f64::NEG_INFINITY, f64::max);
        let south = list
            .iter()
            .min_by(|a, b| {
                let l = |i: &&&Incomplete| i.present_bbox_deg.map_or(f64::INFINITY, |b| b[1]);
                l(a).total_cmp(&l(b))
            })
            .map(|i| i.id.as_str())
            .unwrap_or("");
        println!(
            "{edge:>12} | {what:<28} | {:>4} | present nodes' lat {lat_min:.7} … {lat_max:.7} \
             (southernmost: {south})",
            list.len()
        );
    }
    for i in &o.incomplete {
        println!(
            "  {} {:?} nodes {}/{} bbox {:?} [{}]",
            i.id,
            i.why,
            i.nodes_present,
            i.nodes,
            i.present_bbox_deg,
            edges(i)
        );
    }
    // Complete outlines (tagged `building`, not `no`) per 0.0005° band by the centroid of their
    // largest outer ring (planar, in degrees: the bands are 55 m, the rings a few dozen).
    let mut bands = vec![0usize; 46];
    let mut outside = 0;
    for f in &o.collection.features {
        let p = f.properties.as_ref().expect("props");
        if p.get("building")
            .and_then(|v| v.as_str())
            .is_none_or(|v| v == "no")
        {
            continue;
        }
        let value = serde_json::to_value(f.geometry.as_ref().expect("geometry")).expect("json");
        let polygons: Vec<Vec<Vec<[f64; 2]>>> = match value["type"].as_str() {
            Some("Polygon") => {
                vec![serde_json::from_value(value["coordinates"].clone()).expect("rings")]
            }
            _ => serde_json::from_value(value["coordinates"].clone()).expect("polygons"),
        };
        let (_, c) = polygons
            .iter()
            .map(|p| area_centroid(&p[0]))
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .expect("a polygon");
        let band = ((c[1] - 40.736) / 0.0005).floor();
        if (0.0..46.0).contains(&band) {
            bands[band as usize] += 1;
        } else {
            outside += 1;
        }
    }
    for (k, n) in bands.iter().enumerate() {
        let lo = 40.736 + 0.0005 * k as f64;
        println!("{lo:.4}–{:.4} {n:>4}", lo + 0.0005);
    }
    println!("outside the bands: {outside}");
}

/// |area| and area centroid of a closed ring (degrees, planar).
fn area_centroid(ring: &[[f64; 2]]) -> (f64, [f64; 2]) {
    let o = ring[0];
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for w in ring.windows(2) {
        let (px, py, qx, qy) = (
            w[0][0] - o[0],
            w[0][1] - o[1],
            w[1][0] - o[0],
            w[1][1] - o[1],
        );
        let cross = px * qy - qx * py;
        a += cross;
        cx += (px + qx) * cross;
        cy += (py + qy) * cross;
    }
    if a.abs() < 1e-18 {
        return (0.0, o);
    }
    (
        a.abs() / 2.0,
        [o[0] + cx / (3.0 * a), o[1] + cy / (3.0 * a)],
    )
}
