//! OpenStreetMap's own formats for `dupac scenario import`: OSM PBF, OSM XML and Overpass JSON,
//! told by their content ([`format`]), read into the plain element model ([`model`]: only what
//! the buildings need), assembled into areas ([`area`]) and handed on as the GeoJSON features
//! the GeoJSON reader would get from `osmtogeojson` (tags as flat properties, `@id` =
//! `way/<id>` or `relation/<id>`), so selection, parts and heights are the same whatever the
//! format.

pub mod area;
pub mod format;
pub mod model;
pub mod overpass;
pub mod pbf;
pub mod xml;

use crate::error::RadioError;
use area::{Area, Incomplete};
use format::Format;
use geojson::{Feature, FeatureCollection, Geometry, GeometryValue, Position};
use serde_json::{Map, Value};
use std::io::Read;
use std::path::Path;

/// A buildings file, read.
#[derive(Debug, Clone)]
pub enum Source {
    /// GeoJSON: its text, for the GeoJSON reader.
    GeoJson(String),
    /// An OSM format, assembled.
    Osm(OsmBuildings),
}

/// The building areas of an OSM file and the building elements that are none.
#[derive(Debug, Clone)]
pub struct OsmBuildings {
    pub format: Format,
    /// The areas as GeoJSON features: ways by id, then relations by id.
    pub collection: FeatureCollection,
    /// Building ways and relations that are no area (cut by the extract, unclosed).
    pub incomplete: Vec<Incomplete>,
}

/// Reads the buildings file `path` in whichever format its content is.
pub fn read(path: &Path) -> Result<Source, RadioError> {
    let mut head = Vec::with_capacity(format::SNIFF_BYTES);
    std::fs::File::open(path)
        .and_then(|f| f.take(format::SNIFF_BYTES as u64).read_to_end(&mut head))
        .map_err(|e| RadioError::io(path, e))?;
    let text = || std::fs::read_to_string(path).map_err(|e| RadioError::io(path, e));
    let (format, data) = match format::sniff(&head) {
        Some(Format::Pbf) => (Format::Pbf, pbf::read(path)?),
        Some(Format::Xml) => (Format::Xml, xml::read(&text()?, path)?),
        Some(_) => {
            let text = text()?;
            match format::json_kind(&text) {
                Format::OverpassJson => (Format::OverpassJson, overpass::read(&text, path)?),
                _ => return Ok(Source::GeoJson(text)),
            }
        }
        None => {
            return Err(RadioError::OsmFile {
                path: path.to_path_buf(),
                at: "start".into(),
                message: "not a buildings file: expected GeoJSON or Overpass JSON (`{`), OSM \
                          XML (`<?xml` or `<osm`) or OSM PBF (an `OSMHeader` blob)"
                    .into(),
            });
        }
    };
    let assembled = area::assemble(&data);
    drop(data);
    tracing::info!(
        file = %path.display(),
        format = format.name(),
        areas = assembled.areas.len(),
        incomplete = assembled.incomplete.len(),
        "OSM buildings assembled"
    );
    Ok(Source::Osm(OsmBuildings {
        format,
        collection: FeatureCollection {
            bbox: None,
            features: assembled.areas.iter().map(feature).collect(),
            foreign_members: None,
        },
        incomplete: assembled.incomplete,
    }))
}

/// An area as osmtogeojson writes it: tags flat, `@id`, a Polygon (way) or MultiPolygon
/// (relation) in degrees with 7 decimals.
pub fn feature(a: &Area) -> Feature {
    let ring = |r: &Vec<model::Coord>| -> Vec<Position> {
        r.iter()
            .map(|c| Position::from([c.lon_deg(), c.lat_deg()]))
            .collect()
    };
    let polygon = |p: &Vec<Vec<model::Coord>>| p.iter().map(ring).collect::<Vec<_>>();
    let value = if a.multi {
        GeometryValue::new_multi_polygon(a.polygons.iter().map(polygon).collect::<Vec<_>>())
    } else {
        GeometryValue::new_polygon(polygon(&a.polygons[0]))
    };
    let mut props: Map<String, Value> = a
        .tags
        .iter()
        .map(|(k, v)| (k.clone(), Value::String(v.clone())))
        .collect();
    props.insert("@id".into(), Value::String(a.id.clone()));
    Feature {
        bbox: None,
        geometry: Some(Geometry::new(value)),
        id: None,
        properties: Some(props),
        foreign_members: None,
    }
}

#[cfg(test)]
mod tests;
