//! Loader for the OpenStreetMap building export of `data/README.md` (GeoJSON, WGS84), projected
//! to the local ENU frame.
//!
//! Each feature is a `Polygon` or `MultiPolygon` with properties `kind` (`building` or
//! `building_part`), `height_m` (roof above ground), optional `min_height_m` (bottom of a floating
//! part) and `has_parts` (outline whose 3D detail is in `building_part`s). With
//! [`BuildingDetail::Parts`] an outline that has parts is replaced by its parts; with
//! [`BuildingDetail::Outlines`] parts are ignored and every outline stands on the ground.

use super::building::{Building, signed_area_m2};
use crate::error::RadioError;
use crate::geo::LocalProjection;
use dupac_common::config::BuildingDetail;
use dupac_common::geometry::Bounds2;
use geojson::{FeatureCollection, GeometryValue, JsonObject, PolygonType};
use std::path::Path;

/// Consecutive vertices closer than this are merged (m).
const DUPLICATE_VERTEX_M: f64 = 0.01;
/// Footprints smaller than this are rejected as degenerate (m²).
const MIN_FOOTPRINT_M2: f64 = 0.01;
/// Rings wider or longer than this are rejected: no building is, and the footprint index sizes
/// its grid by the buildings' extent (a ring around the globe asked for terabytes).
pub(crate) const MAX_RING_SPAN_M: f64 = 5_000.0;

/// Reads `path` (relative to the working directory; the default Midtown path falls back to the
/// built-in copy, [`crate::bundled::read`]) and returns the buildings whose footprint bounds
/// intersect `keep_box_m` (local metres).
pub fn load_buildings(
    path: &Path,
    projection: &LocalProjection,
    detail: BuildingDetail,
    keep_box_m: Bounds2,
) -> Result<Vec<Building>, RadioError> {
    let (bytes, _) = crate::bundled::read(path)?;
    let text = std::str::from_utf8(&bytes).map_err(|e| RadioError::GeoJson {
        path: path.to_path_buf(),
        message: format!("not UTF-8: {e}"),
    })?;
    parse_buildings(text, path, projection, detail, keep_box_m)
}

/// [`load_buildings`] on text already read; `path` only names the source in errors.
pub fn parse_buildings(
    text: &str,
    path: &Path,
    projection: &LocalProjection,
    detail: BuildingDetail,
    keep_box_m: Bounds2,
) -> Result<Vec<Building>, RadioError> {
    if text.trim().is_empty() {
        return Err(RadioError::GeoJson {
            path: path.to_path_buf(),
            message: "file is empty".into(),
        });
    }
    let collection: FeatureCollection =
        text.parse()
            .map_err(|e: geojson::Error| RadioError::GeoJson {
                path: path.to_path_buf(),
                message: e.to_string(),
            })?;
    let mut out = Vec::new();
    for (index, feature) in collection.features.iter().enumerate() {
        let props = feature.properties.as_ref();
        let id = prop_str(props, "id")
            .map(str::to_string)
            .or_else(|| feature.id.as_ref().map(|i| format!("{i:?}")))
            .unwrap_or_else(|| format!("#{index}"));
        let fail = |message: String| RadioError::Feature {
            path: path.to_path_buf(),
            index,
            id: id.clone(),
            message,
        };
        // Absent or null: a plain building without parts. Another type is an error, not the
        // default (a `kind` of 5 is no building).
        let kind = match props.and_then(|p| p.get("kind")) {
            None | Some(serde_json::Value::Null) => "building",
            Some(serde_json::Value::String(k)) => k.as_str(),
            Some(v) => {
                return Err(fail(format!(
                    "property `kind`: expected \"building\" or \"building_part\", got {v}"
                )));
            }
        };
        let has_parts = match props.and_then(|p| p.get("has_parts")) {
            None | Some(serde_json::Value::Null) => false,
            Some(serde_json::Value::Bool(b)) => *b,
            Some(v) => {
                return Err(fail(format!(
                    "property `has_parts`: expected true or false, got {v}"
                )));
            }
        };
        match (kind, detail) {
            ("building", BuildingDetail::Parts) if has_parts => continue,
            ("building_part", BuildingDetail::Outlines) => continue,
            ("building", _) | ("building_part", _) => {}
            (other, _) => {
                return Err(fail(format!(
                    "unsupported `kind` {other:?} (expected \"building\" or \"building_part\")"
                )));
            }
        }
        let z_max_m = prop_f64(props, "height_m")
            .map_err(|m| fail(format!("property `height_m`: {m}")))?
            .ok_or_else(|| fail("missing property `height_m` (roof height, m)".into()))?;
        // A part that starts below ground (OSM `min_height` < 0, seen in Midtown) is cut at
        // ground level: only the airspace matters here.
        let z_min_m = prop_f64(props, "min_height_m")
            .map_err(|m| fail(format!("property `min_height_m`: {m}")))?
            .unwrap_or(0.0)
            .max(0.0);
        if !(z_max_m > 0.0 && z_max_m < 2000.0) {
            return Err(fail(format!(
                "property `height_m` = {z_max_m} is not a roof height in (0, 2000) m"
            )));
        }
        if z_min_m >= z_max_m {
            return Err(fail(format!(
                "property `min_height_m` = {z_min_m} must be in [0, height_m = {z_max_m})"
            )));
        }
        let geometry = feature
            .geometry
            .as_ref()
            .ok_or_else(|| fail("feature has no geometry".into()))?;
        let polygons: Vec<&PolygonType> = match &geometry.value {
            GeometryValue::Polygon { coordinates } => vec![coordinates],
            GeometryValue::MultiPolygon { coordinates } => coordinates.iter().collect(),
            other => {
                return Err(fail(format!(
                    "geometry is a {}, expected Polygon or MultiPolygon",
                    other.type_name()
                )));
            }
        };
        for (k, polygon) in polygons.iter().enumerate() {
            let sub_id = if polygons.len() > 1 {
                format!("{id}#{k}")
            } else {
                id.clone()
            };
            let building = polygon_to_building(polygon, projection, &sub_id, z_min_m, z_max_m)
                .map_err(|m| {
                    fail(if polygons.len() > 1 {
                        format!("polygon {k}: {m}")
                    } else {
                        m
                    })
                })?;
            let b = building.bounds_m();
            if b.max_m.x >= keep_box_m.min_m.x
                && b.min_m.x <= keep_box_m.max_m.x
                && b.max_m.y >= keep_box_m.min_m.y
                && b.min_m.y <= keep_box_m.max_m.y
            {
                out.push(building);
            }
        }
    }
    if out.is_empty() {
        return Err(RadioError::NoBuildings {
            path: path.to_path_buf(),
        });
    }
    Ok(out)
}

fn prop_str<'a>(props: Option<&'a JsonObject>, key: &str) -> Option<&'a str> {
    props.and_then(|p| p.get(key)).and_then(|v| v.as_str())
}

fn prop_f64(props: Option<&JsonObject>, key: &str) -> Result<Option<f64>, String> {
    match props.and_then(|p| p.get(key)) {
        None | Some(serde_json::Value::Null) => Ok(None),
        Some(v) => match v.as_f64() {
            Some(x) if x.is_finite() => Ok(Some(x)),
            _ => Err(format!("expected a finite number, got {v}")),
        },
    }
}

/// Projects one GeoJSON polygon (outer ring then holes) into a [`Building`].
pub(crate) fn polygon_to_building(
    polygon: &PolygonType,
    projection: &LocalProjection,
    id: &str,
    z_min_m: f64,
    z_max_m: f64,
) -> Result<Building, String> {
    let mut rings = Vec::with_capacity(polygon.len());
    for (r, ring) in polygon.iter().enumerate() {
        let what = if r == 0 {
            "outer ring".to_string()
        } else {
            format!("hole {r}")
        };
        let mut pts: Vec<[f64; 2]> = Vec::with_capacity(ring.len());
        for (v, pos) in ring.iter().enumerate() {
            let c = pos.as_slice();
            if c.len() < 2 {
                return Err(format!("{what}, vertex {v}: fewer than 2 coordinates"));
            }
            let (lon, lat) = (c[0], c[1]);
            if !(lon.is_finite() && lat.is_finite() && lon.abs() <= 180.0 && lat.abs() <= 90.0) {
                return Err(format!(
                    "{what}, vertex {v}: ({lon}, {lat}) is not a WGS84 lon/lat"
                ));
            }
            let p = projection.to_local_m(lon, lat);
            if pts.last().is_none_or(|q| dist(*q, p) > DUPLICATE_VERTEX_M) {
                pts.push(p);
            }
        }
        while pts.len() > 1
            && let (Some(first), Some(last)) = (pts.first(), pts.last())
            && dist(*first, *last) <= DUPLICATE_VERTEX_M
        {
            pts.pop();
        }
        if pts.len() < 3 {
            return Err(format!(
                "{what} has {} distinct vertices, a footprint needs at least 3",
                pts.len()
            ));
        }
        let b = ring_bounds(&pts);
        let (w, h) = (b.max_m.x - b.min_m.x, b.max_m.y - b.min_m.y);
        if w > MAX_RING_SPAN_M || h > MAX_RING_SPAN_M {
            return Err(format!(
                "{what} spans {w:.0} m × {h:.0} m, more than the {MAX_RING_SPAN_M} m of any building"
            ));
        }
        let area = signed_area_m2(&pts);
        if area.abs() < MIN_FOOTPRINT_M2 {
            return Err(format!("{what} is degenerate (area {area:.4} m²)"));
        }
        if r == 0 && area < 0.0 {
            pts.reverse();
        }
        rings.push(pts);
    }
    let mut rings = rings.into_iter();
    let outer_m = rings.next().ok_or("polygon has no rings")?;
    let holes_m: Vec<Vec<[f64; 2]>> = rings.collect();
    // A hole outside the outer ring would add walls where the footprint has none, and holes
    // covering the whole footprint leave nothing (a negative area).
    let outer_box = ring_bounds(&outer_m);
    let mut net_m2 = signed_area_m2(&outer_m);
    for (k, hole) in holes_m.iter().enumerate() {
        let b = ring_bounds(hole);
        let tol = DUPLICATE_VERTEX_M;
        if b.min_m.x < outer_box.min_m.x - tol
            || b.min_m.y < outer_box.min_m.y - tol
            || b.max_m.x > outer_box.max_m.x + tol
            || b.max_m.y > outer_box.max_m.y + tol
        {
            return Err(format!("hole {} is not inside the outer ring", k + 1));
        }
        net_m2 -= signed_area_m2(hole).abs();
    }
    if net_m2 < MIN_FOOTPRINT_M2 {
        return Err(format!(
            "the holes cover the outer ring (area left {net_m2:.4} m²)"
        ));
    }
    Ok(Building {
        id: id.to_string(),
        outer_m,
        holes_m,
        z_min_m,
        z_max_m,
    })
}

/// The bounds of a ring (m).
fn ring_bounds(ring: &[[f64; 2]]) -> Bounds2 {
    ring.iter()
        .fold(Bounds2::empty(), |b, p| b.including(p[0], p[1]))
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn proj() -> LocalProjection {
        LocalProjection::new(-73.985, 40.75)
    }

    const BIG: Bounds2 = Bounds2::new(-1e6, -1e6, 1e6, 1e6);

    fn parse(text: &str) -> Result<Vec<Building>, RadioError> {
        parse_buildings(
            text,
            Path::new("t.geojson"),
            &proj(),
            BuildingDetail::Parts,
            BIG,
        )
    }

    fn square_feature(id: &str, kind: &str, extra: &str) -> String {
        format!(
            r#"{{"type":"Feature","properties":{{"id":"{id}","kind":"{kind}","height_m":30.0{extra}}},
            "geometry":{{"type":"Polygon","coordinates":[[[-73.985,40.75],[-73.985,40.7501],[-73.9849,40.7501],[-73.9849,40.75],[-73.985,40.75]]]}}}}"#
        )
    }

    fn collection(features: &[String]) -> String {
        format!(
            r#"{{"type":"FeatureCollection","features":[{}]}}"#,
            features.join(",")
        )
    }

    #[test]
    fn square_is_projected_closed_ring_dropped_and_made_ccw() {
        let b = parse(&collection(&[square_feature("osm:way/1", "building", "")])).expect("ok");
        assert_eq!(b.len(), 1);
        assert_eq!(b[0].outer_m.len(), 4);
        assert!(b[0].area_m2() > 0.0, "CCW");
        // 0.0001° × 0.0001° at 40.75 N ≈ 8.43 m × 11.10 m.
        assert!(
            (b[0].area_m2() - 8.43 * 11.10).abs() < 0.5,
            "{}",
            b[0].area_m2()
        );
        assert_eq!(b[0].z_max_m, 30.0);
    }

    #[test]
    fn parts_replace_outlines_that_have_parts() {
        let text = collection(&[
            square_feature("outline", "building", r#","has_parts":true"#),
            square_feature("part", "building_part", r#","min_height_m":10.0"#),
            square_feature("plain", "building", ""),
        ]);
        let parts = parse(&text).expect("ok");
        let ids: Vec<&str> = parts.iter().map(|b| b.id.as_str()).collect();
        assert_eq!(ids, vec!["part", "plain"]);
        assert_eq!(parts[0].z_min_m, 10.0);
        let outlines = parse_buildings(
            &text,
            Path::new("t"),
            &proj(),
            BuildingDetail::Outlines,
            BIG,
        )
        .expect("ok");
        let ids: Vec<&str> = outlines.iter().map(|b| b.id.as_str()).collect();
        assert_eq!(ids, vec!["outline", "plain"]);
    }

    #[test]
    fn empty_and_malformed_files_are_clear_errors() {
        let e = parse("").unwrap_err().to_string();
        assert!(e.contains("t.geojson") && e.contains("empty"), "{e}");
        let e = parse("{\"type\": \"FeatureCollection\", \"features\": [")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.geojson") && e.contains("GeoJSON"), "{e}");
        let e = parse(&collection(&[])).unwrap_err().to_string();
        assert!(e.contains("no usable buildings"), "{e}");
    }

    #[test]
    fn nan_coordinates_are_rejected_with_the_file_named() {
        let text = collection(&[square_feature("a", "building", "")])
            .replace("-73.9849,40.7501", "NaN,40.7501");
        let e = parse(&text).unwrap_err().to_string();
        assert!(e.contains("t.geojson"), "{e}");
    }

    #[test]
    fn short_footprint_names_the_feature() {
        let f = r#"{"type":"Feature","properties":{"id":"osm:way/9","kind":"building","height_m":20},
            "geometry":{"type":"Polygon","coordinates":[[[-73.985,40.75],[-73.985,40.7501],[-73.985,40.75]]]}}"#;
        let e = parse(&collection(&[f.to_string()]))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("osm:way/9") && e.contains("feature 0") && e.contains("at least 3"),
            "{e}"
        );
    }

    #[test]
    fn missing_or_bad_height_names_the_property() {
        let f = square_feature("x", "building", "").replace(r#","height_m":30.0"#, "");
        let e = parse(&collection(&[f])).unwrap_err().to_string();
        assert!(
            e.contains("height_m") && e.contains("\"x\"") || e.contains("(x)"),
            "{e}"
        );
        let f = square_feature("y", "building", r#","min_height_m":40"#);
        let e = parse(&collection(&[f])).unwrap_err().to_string();
        assert!(e.contains("min_height_m"), "{e}");
        let f = square_feature("z", "tax_lot", "");
        let e = parse(&collection(&[f])).unwrap_err().to_string();
        assert!(e.contains("tax_lot"), "{e}");
    }
}
