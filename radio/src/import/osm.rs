//! Raw OpenStreetMap buildings (GeoJSON, as Overpass Turbo, `osmtogeojson` or `osmium export`
//! write them, or OSM PBF, OSM XML and Overpass JSON assembled into the same features by
//! [`super::osm_raw`]) → the building features [`crate::city::osm`] loads (`kind`, `height_m`,
//! `min_height_m`, `has_parts`, …), by the rules of `docs/scenario.md`:
//!
//! - a feature tagged `building` (not `no`) is an outline, one tagged `building:part` a part;
//!   anything else, and underground features (`location=underground`), are
//!   skipped; only `Polygon`s and `MultiPolygon`s are areas;
//! - a part belongs to the smallest outline containing its centroid (an outline with parts is
//!   replaced by them, as Simple 3D Buildings says); a part in no outline becomes a building;
//! - whole features are kept when the centroid of their largest outer ring is inside the
//!   selection box (parts with their outline), never clipped;
//! - the roof: `height`, else levels ([`HeightRules`]), else (outlines) the highest of its parts,
//!   else (parts) its outline's tagged height, else the 75th percentile of tagged outlines within
//!   `nearby_m`, else `default_height_m`; the bottom: `min_height` or `building:min_level`,
//!   dropped (0) when not below the roof.

use super::osm_raw::{self, Source, area::Incomplete};
use super::tags::{HeightRules, HeightSource, TagError, Tags, quantile};
use crate::city::{Building, osm::polygon_to_building};
use crate::error::RadioError;
use crate::geo::LocalProjection;
use dupac_common::config::LonLatBox;
use geojson::{FeatureCollection, GeometryValue, PolygonType};
use serde::Serialize;
use serde_json::{Map, Value, json};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// How raw buildings are read.
#[derive(Debug, Clone, PartialEq)]
pub struct OsmRules {
    /// Levels → metres.
    pub heights: HeightRules,
    /// Radius of the nearby-height fallback (m); 0 turns it off.
    pub nearby_m: f64,
    /// Roof height of a feature nothing else gives one (m).
    pub default_height_m: f64,
    /// A tag value that is not what its key means is an error (otherwise a warning, and the
    /// value is ignored).
    pub strict: bool,
}

/// Bucket side of the spatial grids (m).
const GRID_M: f64 = 100.0;
/// Warnings printed one by one before only the count is reported.
const MAX_WARNINGS: usize = 20;

/// What the import did with the features it read.
#[derive(Debug, Clone, Default, Serialize)]
pub struct BuildingCounts {
    pub features: usize,
    pub not_building: usize,
    pub underground: usize,
    pub not_area: usize,
    /// Features no polygon of which is a usable footprint (too small, self-overlapping holes…).
    pub degenerate: usize,
    /// Polygons of kept features dropped as unusable.
    pub degenerate_polygons: usize,
    pub outside: usize,
    pub outlines: usize,
    pub outlines_with_parts: usize,
    pub parts: usize,
    /// Parts in no outline, written as buildings.
    pub orphan_parts: usize,
    /// Tag values ignored (not what their key means).
    pub bad_tags: usize,
    /// Bottoms dropped because they were not below the roof.
    pub min_height_dropped: usize,
    /// Features written per `height_source`.
    pub height_sources: BTreeMap<String, usize>,
    /// OSM formats: building ways and relations that are no area (a node or member way not in
    /// the file, rings that do not close); 0 for GeoJSON.
    pub incomplete: usize,
}

/// The imported buildings: the GeoJSON text to write and the counts.
#[derive(Debug, Clone)]
pub struct ImportedBuildings {
    pub geojson: String,
    pub counts: BuildingCounts,
    /// The file's format (`GeoJSON`, `OSM PBF`, `OSM XML`, `Overpass JSON`).
    pub format: &'static str,
    /// OSM formats: the building elements that are no area, with the extent of the nodes the
    /// file holds of them (by id, ways first).
    pub incomplete: Vec<Incomplete>,
}

/// The warnings of one import: the first [`MAX_WARNINGS`] are logged.
#[derive(Default)]
struct Warnings {
    shown: usize,
    bad_tags: usize,
}

impl Warnings {
    fn warn(&mut self, path: &Path, index: usize, id: &str, what: &str) {
        self.shown += 1;
        if self.shown <= MAX_WARNINGS {
            tracing::warn!(file = %path.display(), feature = index, id, "{what}");
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Kind {
    Outline,
    Part,
}

struct Raw {
    id: String,
    kind: Kind,
    /// The usable polygons, as read (lon/lat).
    polygons: Vec<PolygonType>,
    /// The same, projected.
    footprints: Vec<Building>,
    centroid_m: [f64; 2],
    area_m2: f64,
    top: Option<(f64, HeightSource)>,
    bottom_m: f64,
    levels: Option<f64>,
    building: Option<String>,
    name: Option<String>,
    parent: Option<usize>,
    kept_parts: usize,
}

/// Reads `path` in whichever format its content is ([`osm_raw::read`]: GeoJSON, OSM PBF, OSM
/// XML, Overpass JSON) and imports it ([`import_collection`]).
pub fn import_buildings(
    path: &Path,
    select: &LonLatBox,
    rules: &OsmRules,
) -> Result<ImportedBuildings, RadioError> {
    match osm_raw::read(path)? {
        Source::GeoJson(text) => import_buildings_text(&text, path, select, rules),
        Source::Osm(osm) => {
            let mut out = import_collection(&osm.collection, path, select, rules)?;
            out.counts.incomplete = osm.incomplete.len();
            out.format = osm.format.name();
            out.incomplete = osm.incomplete;
            Ok(out)
        }
    }
}

/// Imports the raw GeoJSON buildings of `text` whose centroid is in `select`; `path` names the
/// source in errors and in the output's metadata.
pub fn import_buildings_text(
    text: &str,
    path: &Path,
    select: &LonLatBox,
    rules: &OsmRules,
) -> Result<ImportedBuildings, RadioError> {
    import_collection(&parse_collection(text, path)?, path, select, rules)
}

/// The GeoJSON `FeatureCollection` of `text`; Overpass JSON is told apart in the message.
fn parse_collection(text: &str, path: &Path) -> Result<FeatureCollection, RadioError> {
    let geo_err = |message: String| RadioError::GeoJson {
        path: path.to_path_buf(),
        message,
    };
    if text.trim().is_empty() {
        return Err(geo_err("file is empty".into()));
    }
    let collection: FeatureCollection = text.parse().map_err(|e: geojson::Error| {
        if text.contains("\"elements\"") && !text.contains("\"features\"") {
            geo_err(
                "this is Overpass JSON, not GeoJSON: `import_buildings` reads it from its \
                 file (it tells the formats apart)"
                    .into(),
            )
        } else {
            geo_err(e.to_string())
        }
    })?;
    Ok(collection)
}

/// Imports the building features of `collection` whose centroid is in `select`; `path` names
/// the source in errors and in the output's metadata.
pub fn import_collection(
    collection: &FeatureCollection,
    path: &Path,
    select: &LonLatBox,
    rules: &OsmRules,
) -> Result<ImportedBuildings, RadioError> {
    let projection = LocalProjection::centred_on(select);
    let select_m = projection.box_m(select);
    // A part's outline has its centroid in the box and spans at most MAX_RING_SPAN_M.
    let candidates_m = select_m.expanded(crate::city::osm::MAX_RING_SPAN_M);
    let mut counts = BuildingCounts {
        features: collection.features.len(),
        ..Default::default()
    };
    let mut log = Warnings::default();
    let mut raws: Vec<Raw> = Vec::new();
    for (index, feature) in collection.features.iter().enumerate() {
        let empty = Map::new();
        let props = feature.properties.as_ref().unwrap_or(&empty);
        let tag_map = match props.get("tags") {
            Some(Value::Object(t)) => t,
            _ => props,
        };
        let id = feature_id(props, feature.id.as_ref(), index);
        let fail = |message: String| RadioError::Feature {
            path: path.to_path_buf(),
            index,
            id: id.clone(),
            message,
        };
        let mut tags = tag_map.clone();
        let warn = |e: TagError, tags: &mut Map<String, Value>, log: &mut Warnings| {
            if rules.strict {
                return Err(fail(format!("{e} (--strict)")));
            }
            log.warn(path, index, &id, &format!("{e}: ignored"));
            log.bad_tags += 1;
            tags.remove(&e.tag);
            Ok(())
        };
        let kind = loop {
            let building = Tags(&tags).get("building");
            let part = Tags(&tags).get("building:part");
            match (building, part) {
                (Err(e), _) | (_, Err(e)) => warn(e, &mut tags, &mut log)?,
                (Ok(Some(b)), _) if b != "no" => break Some(Kind::Outline),
                (_, Ok(Some(p))) if p != "no" => break Some(Kind::Part),
                _ => break None,
            }
        };
        let Some(kind) = kind else {
            counts.not_building += 1;
            continue;
        };
        let text_tag = |tags: &Map<String, Value>, k: &str| Tags(tags).get(k).ok().flatten();
        // `layer` orders crossing features (a building under a viaduct is `layer=-1`), not
        // depth (wiki Key:layer): only `location=underground` marks a building below ground.
        if text_tag(&tags, "location").as_deref() == Some("underground") {
            counts.underground += 1;
            continue;
        }
        let polygons: Vec<&PolygonType> = match feature.geometry.as_ref().map(|g| &g.value) {
            Some(GeometryValue::Polygon { coordinates }) => vec![coordinates],
            Some(GeometryValue::MultiPolygon { coordinates }) => coordinates.iter().collect(),
            _ => {
                counts.not_area += 1;
                continue;
            }
        };
        check_coordinates(&polygons).map_err(fail)?;
        let (mut valid, mut footprints) = (Vec::new(), Vec::new());
        for (k, polygon) in polygons.iter().enumerate() {
            match polygon_to_building(polygon, &projection, &id, 0.0, 1.0) {
                Ok(b) => {
                    valid.push((*polygon).clone());
                    footprints.push(b);
                }
                Err(why) => {
                    counts.degenerate_polygons += 1;
                    log.warn(path, index, &id, &format!("polygon {k}: {why}: dropped"));
                }
            }
        }
        let Some(largest) = footprints
            .iter()
            .max_by(|a, b| a.area_m2().total_cmp(&b.area_m2()))
        else {
            counts.degenerate += 1;
            continue;
        };
        let centroid_m = ring_centroid_m(&largest.outer_m);
        if !candidates_m.contains(centroid_m[0], centroid_m[1]) {
            counts.outside += 1;
            continue;
        }
        let top = loop {
            match rules.heights.roof_m(Tags(&tags)) {
                Ok(t) => break t,
                Err(e) => warn(e, &mut tags, &mut log)?,
            }
        };
        let bottom_m = loop {
            match rules.heights.bottom_m(Tags(&tags)) {
                Ok(b) => break b,
                Err(e) => warn(e, &mut tags, &mut log)?,
            }
        };
        let levels = Tags(&tags).levels("building:levels").ok().flatten();
        let building = match kind {
            Kind::Outline => text_tag(&tags, "building"),
            Kind::Part => text_tag(&tags, "building:part"),
        };
        raws.push(Raw {
            id,
            kind,
            polygons: valid,
            area_m2: footprints.iter().map(Building::area_m2).sum(),
            footprints,
            centroid_m,
            top,
            bottom_m,
            levels,
            building,
            name: text_tag(&tags, "name"),
            parent: None,
            kept_parts: 0,
        });
    }
    counts.bad_tags = log.bad_tags;
    if log.shown > MAX_WARNINGS {
        tracing::warn!(
            file = %path.display(),
            more = log.shown - MAX_WARNINGS,
            "further warnings not shown (see the counts)"
        );
    }
    attach_parts(&mut raws);
    let in_box = |r: &Raw| select_m.contains(r.centroid_m[0], r.centroid_m[1]);
    let kept: Vec<bool> = raws
        .iter()
        .map(|r| match r.parent {
            Some(p) => in_box(&raws[p]),
            None => in_box(r),
        })
        .collect();
    let mut kept_parts = vec![0usize; raws.len()];
    for (i, r) in raws.iter().enumerate() {
        if let (Some(p), true) = (r.parent, kept[i]) {
            kept_parts[p] += 1;
        }
    }
    for (r, n) in raws.iter_mut().zip(kept_parts) {
        r.kept_parts = n;
    }
    resolve_heights(&mut raws, rules);
    let mut lines = Vec::new();
    for (r, keep) in raws.iter().zip(&kept) {
        if !keep {
            counts.outside += 1;
            continue;
        }
        lines.push(feature_json(r, rules, &mut counts));
    }
    if lines.is_empty() {
        return Err(RadioError::NoBuildings {
            path: path.to_path_buf(),
        });
    }
    let metadata = json!({
        "made_by": "dupac scenario import",
        "source_file": path.file_name().map(|n| n.to_string_lossy().into_owned()),
        "license": "ODbL 1.0 - (c) OpenStreetMap contributors, https://www.openstreetmap.org/copyright",
        "bbox_selected": [select.lon_min_deg, select.lat_min_deg, select.lon_max_deg, select.lat_max_deg],
        "level_height_m": rules.heights.level_height_m,
        "nearby_m": rules.nearby_m,
        "default_height_m": rules.default_height_m,
        "height_units": "metres above ground (roof height)",
        "selection": "feature kept if the centroid of its largest outer ring lies in bbox_selected (parts with their outline)",
    });
    let geojson = format!(
        "{{\"type\":\"FeatureCollection\",\"name\":\"buildings\",\"metadata\":{metadata},\"features\":[\n{}\n]}}\n",
        lines.join(",\n")
    );
    Ok(ImportedBuildings {
        geojson,
        counts,
        format: "GeoJSON",
        incomplete: Vec::new(),
    })
}

/// The feature's OSM id as `osm:<type>/<id>`: `@id` (osmtogeojson), `type` + `id` (older
/// osmtogeojson), the feature's own id (`way/1` or osmium's `w1`), else `#<index>`.
fn feature_id(
    props: &Map<String, Value>,
    fid: Option<&geojson::feature::Id>,
    index: usize,
) -> String {
    let text = |v: &Value| match v {
        Value::String(s) => Some(s.clone()),
        Value::Number(n) => Some(n.to_string()),
        _ => None,
    };
    let raw = props
        .get("@id")
        .and_then(text)
        .or_else(|| {
            let t = props.get("type").and_then(Value::as_str)?;
            Some(format!("{t}/{}", props.get("id").and_then(text)?))
        })
        .or_else(|| match fid? {
            geojson::feature::Id::String(s) => Some(s.clone()),
            geojson::feature::Id::Number(n) => Some(n.to_string()),
        });
    let Some(raw) = raw else {
        return format!("#{index}");
    };
    let long = |c: char| match c {
        'w' => Some("way"),
        'r' => Some("relation"),
        'n' => Some("node"),
        _ => None,
    };
    let mut chars = raw.chars();
    if let (Some(kind), rest) = (chars.next().and_then(long), chars.as_str())
        && !rest.is_empty()
        && rest.chars().all(|c| c.is_ascii_digit())
    {
        return format!("osm:{kind}/{rest}");
    }
    if raw.starts_with("osm:") {
        raw
    } else {
        format!("osm:{raw}")
    }
}

/// Every vertex is a WGS84 lon/lat: a file that says otherwise is not an OSM extract.
fn check_coordinates(polygons: &[&PolygonType]) -> Result<(), String> {
    for (k, polygon) in polygons.iter().enumerate() {
        for (r, ring) in polygon.iter().enumerate() {
            for (v, pos) in ring.iter().enumerate() {
                let c = pos.as_slice();
                let ok = c.len() >= 2
                    && c[0].is_finite()
                    && c[1].is_finite()
                    && c[0].abs() <= 180.0
                    && c[1].abs() <= 90.0;
                if !ok {
                    return Err(format!(
                        "geometry: polygon {k}, ring {r}, vertex {v}: {c:?} is not a WGS84 lon/lat"
                    ));
                }
            }
        }
    }
    Ok(())
}

/// Area centroid of an open ring (m); its vertex mean when the area vanishes.
fn ring_centroid_m(ring: &[[f64; 2]]) -> [f64; 2] {
    let (o, n) = (ring[0], ring.len());
    let (mut a, mut cx, mut cy) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let (p, q) = (ring[i], ring[(i + 1) % n]);
        let (px, py, qx, qy) = (p[0] - o[0], p[1] - o[1], q[0] - o[0], q[1] - o[1]);
        let cross = px * qy - qx * py;
        a += cross;
        cx += (px + qx) * cross;
        cy += (py + qy) * cross;
    }
    if a.abs() < 1e-9 {
        let (sx, sy) = ring
            .iter()
            .fold((0.0, 0.0), |s, p| (s.0 + p[0], s.1 + p[1]));
        return [sx / n as f64, sy / n as f64];
    }
    [o[0] + cx / (3.0 * a), o[1] + cy / (3.0 * a)]
}

fn cell(p: [f64; 2], size_m: f64) -> (i64, i64) {
    (
        (p[0] / size_m).floor() as i64,
        (p[1] / size_m).floor() as i64,
    )
}

/// Each part's outline: the smallest outline one of whose footprints contains its centroid
/// (ties: the first). The parts' centroids are indexed on a grid (one entry per part); each
/// footprint visits the grid cells under its bounds, or every part when those are more, so
/// neither memory nor time grows with a footprint's size.
fn attach_parts(raws: &mut [Raw]) {
    let parts: Vec<usize> = (0..raws.len())
        .filter(|&i| raws[i].kind == Kind::Part)
        .collect();
    if parts.is_empty() {
        return;
    }
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for &p in &parts {
        grid.entry(cell(raws[p].centroid_m, GRID_M))
            .or_default()
            .push(p);
    }
    let mut parent: Vec<Option<usize>> = vec![None; raws.len()];
    for (o, r) in raws.iter().enumerate() {
        if r.kind != Kind::Outline {
            continue;
        }
        for b in &r.footprints {
            let bb = b.bounds_m();
            let (x0, y0) = cell([bb.min_m.x, bb.min_m.y], GRID_M);
            let (x1, y1) = cell([bb.max_m.x, bb.max_m.y], GRID_M);
            let cells =
                (i128::from(x1) - i128::from(x0) + 1) * (i128::from(y1) - i128::from(y0) + 1);
            let mut consider = |p: usize| {
                let c = raws[p].centroid_m;
                let smaller = parent[p].is_none_or(|q| r.area_m2 < raws[q].area_m2);
                if smaller && b.contains_xy(c[0], c[1]) {
                    parent[p] = Some(o);
                }
            };
            if cells <= parts.len() as i128 {
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        grid.get(&(x, y))
                            .into_iter()
                            .flatten()
                            .for_each(|&p| consider(p));
                    }
                }
            } else {
                parts.iter().for_each(|&p| consider(p));
            }
        }
    }
    for p in parts {
        raws[p].parent = parent[p];
    }
}

/// Fills every missing roof: outlines from their parts, parts from their outline, then the
/// nearby percentile and the default.
fn resolve_heights(raws: &mut [Raw], rules: &OsmRules) {
    let tagged: Vec<Option<f64>> = raws
        .iter()
        .map(|r| r.top.filter(|t| t.1.is_tagged()).map(|t| t.0))
        .collect();
    let mut parts_max: Vec<Option<f64>> = vec![None; raws.len()];
    for (r, t) in raws.iter().zip(&tagged) {
        if let (Some(p), Some(h)) = (r.parent, t) {
            parts_max[p] = Some(parts_max[p].map_or(*h, |m: f64| m.max(*h)));
        }
    }
    let mut nearby: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    let r_m = rules.nearby_m;
    if r_m > 0.0 {
        for (i, r) in raws.iter().enumerate() {
            if r.kind == Kind::Outline && tagged[i].is_some() {
                nearby.entry(cell(r.centroid_m, r_m)).or_default().push(i);
            }
        }
    }
    for i in 0..raws.len() {
        if raws[i].top.is_some() {
            continue;
        }
        let r = &raws[i];
        let from_family = match (r.kind, r.parent) {
            (Kind::Outline, _) => parts_max[i].map(|h| (h, HeightSource::Parts)),
            (Kind::Part, Some(p)) => tagged[p].map(|h| (h, HeightSource::Outline)),
            (Kind::Part, None) => None,
        };
        let top = from_family.or_else(|| {
            if r_m <= 0.0 {
                return None;
            }
            let (cx, cy) = cell(r.centroid_m, r_m);
            let c = r.centroid_m;
            let mut heights: Vec<f64> = (cy - 1..=cy + 1)
                .flat_map(|y| (cx - 1..=cx + 1).map(move |x| (x, y)))
                .filter_map(|k| nearby.get(&k))
                .flatten()
                .filter(|&&o| {
                    let q = raws[o].centroid_m;
                    (q[0] - c[0]).hypot(q[1] - c[1]) <= r_m
                })
                .filter_map(|&o| tagged[o])
                .collect();
            quantile(&mut heights, 0.75).map(|h| (h, HeightSource::Nearby(r_m)))
        });
        raws[i].top = Some(top.unwrap_or((
            rules.default_height_m,
            HeightSource::Default(rules.default_height_m),
        )));
    }
}

/// One output feature (a line of the GeoJSON), counted.
fn feature_json(r: &Raw, rules: &OsmRules, counts: &mut BuildingCounts) -> String {
    let (top, source) = r.top.unwrap_or((
        rules.default_height_m,
        HeightSource::Default(rules.default_height_m),
    ));
    let mut label = source.label(&rules.heights);
    let mut bottom = r.bottom_m;
    if bottom >= top {
        bottom = 0.0;
        label.push_str("|inconsistent_min_height_dropped");
        counts.min_height_dropped += 1;
    }
    *counts.height_sources.entry(label.clone()).or_default() += 1;
    let kind = match (r.kind, r.parent) {
        (Kind::Outline, _) => {
            counts.outlines += 1;
            counts.outlines_with_parts += usize::from(r.kept_parts > 0);
            "building"
        }
        (Kind::Part, Some(_)) => {
            counts.parts += 1;
            "building_part"
        }
        (Kind::Part, None) => {
            counts.orphan_parts += 1;
            "building"
        }
    };
    let geometry = if r.polygons.len() == 1 {
        json!({"type": "Polygon", "coordinates": r.polygons[0]})
    } else {
        json!({"type": "MultiPolygon", "coordinates": r.polygons})
    };
    let mut props = json!({
        "id": r.id,
        "kind": kind,
        "height_m": top,
        "min_height_m": bottom,
        "height_source": label,
        "levels": r.levels,
        "building": r.building,
        "name": r.name,
    });
    if r.kind == Kind::Outline {
        props["has_parts"] = json!(r.kept_parts > 0);
    }
    json!({"type": "Feature", "geometry": geometry, "properties": props}).to_string()
}

#[cfg(test)]
mod tests;
