//! Overpass API JSON (`[out:json]`, <https://dev.overpass-api.de/output_formats.html#json>):
//! `{"elements": [...]}`, each element `{"type", "id", "tags", …}`. Both forms a building query
//! writes: `out body; >; out skel qt;` (nodes with `lat`/`lon`, ways with `nodes` id lists,
//! relations with `members` of `type`, `ref`, `role`) and `out geom` (ways and relation members
//! with a `geometry` array of `{lat, lon}`, `null` for a node left out).

use super::model::is_building_multipolygon;
use super::model::{Collector, Coord, Member, MemberKind, OsmData, Relation, TagList, Way};
use crate::error::RadioError;
use serde::Deserialize;
use serde_json::{Map, Value};
use std::collections::BTreeMap;
use std::path::Path;

type Object = Map<String, Value>;

/// The elements a building area needs, read from the Overpass JSON `text` of `path`.
pub fn read(text: &str, path: &Path) -> Result<OsmData, RadioError> {
    #[derive(Deserialize)]
    struct Doc {
        elements: Vec<Object>,
    }
    let doc: Doc = serde_json::from_str(text).map_err(|e| {
        let message = e.to_string();
        let message = message.split(" at line ").next().unwrap_or_default();
        RadioError::OsmFile {
            path: path.to_path_buf(),
            at: format!("line {}, column {}", e.line(), e.column()),
            message: format!("not valid Overpass JSON: {message}"),
        }
    })?;
    let elements: Vec<Element> = doc
        .elements
        .iter()
        .enumerate()
        .filter_map(|(index, object)| Element::new(index, object, path).transpose())
        .collect::<Result<_, _>>()?;
    let mut c = Collector::default();
    let mut geometry_members: BTreeMap<i64, Vec<Option<Coord>>> = BTreeMap::new();
    for e in elements.iter().filter(|e| e.kind == "relation") {
        if !is_building_multipolygon(e.tag_pairs()) {
            continue;
        }
        let tags = e.tags()?;
        let list: &[Value] = e.array("members")?.map_or(&[], |v| v.as_slice());
        let mut members = Vec::with_capacity(list.len());
        for (k, m) in list.iter().enumerate() {
            let at = |what: &str| e.fail(format!("member {k}: {what}"));
            let m = m.as_object().ok_or_else(|| at("not an object"))?;
            let kind = match m.get("type").and_then(Value::as_str) {
                Some("node") => MemberKind::Node,
                Some("way") => MemberKind::Way,
                Some("relation") => MemberKind::Relation,
                _ => return Err(at("`type` is not node, way or relation")),
            };
            let id = m
                .get("ref")
                .and_then(Value::as_i64)
                .ok_or_else(|| at("`ref` is not an integer"))?;
            let role = match m.get("role") {
                None | Some(Value::Null) => String::new(),
                Some(Value::String(s)) => s.clone(),
                Some(_) => return Err(at("`role` is not a string")),
            };
            if let (MemberKind::Way, Some(g)) = (kind, m.get("geometry")) {
                geometry_members.insert(id, points(g).map_err(|w| at(&w))?);
            }
            members.push(Member { kind, id, role });
        }
        c.add_relation(e.id, Relation { members, tags });
    }
    let mut geometry_ways: Vec<(i64, Vec<Option<Coord>>, TagList)> = Vec::new();
    for e in elements.iter().filter(|e| e.kind == "way") {
        if !c.wants_way(e.id, e.tag_pairs()) {
            continue;
        }
        let tags = e.tags()?;
        let geometry = match e.object.get("geometry") {
            Some(g) => Some(points(g).map_err(|w| e.fail(w))?),
            None => None,
        };
        let Some(nodes) = e.array("nodes")? else {
            match geometry {
                Some(g) => geometry_ways.push((e.id, g, tags)),
                None => return Err(e.fail("neither `nodes` nor `geometry`".into())),
            }
            continue;
        };
        let refs = nodes
            .iter()
            .enumerate()
            .map(|(k, n)| {
                n.as_i64()
                    .ok_or_else(|| e.fail(format!("`nodes`[{k}] = {n} is not a node id")))
            })
            .collect::<Result<Vec<i64>, _>>()?;
        if let Some(g) = geometry {
            if g.len() != refs.len() {
                return Err(e.fail("`geometry` and `nodes` differ in length".into()));
            }
            for (&n, p) in refs.iter().zip(g) {
                if let Some(p) = p {
                    c.add_node(n, p);
                }
            }
        }
        c.add_way(e.id, Way { refs, tags });
    }
    for e in elements.iter().filter(|e| e.kind == "node") {
        if !c.wants_node(e.id) {
            continue;
        }
        let deg = |k: &str| e.object.get(k).and_then(Value::as_f64);
        let at = match (deg("lon"), deg("lat")) {
            (Some(lon), Some(lat)) => Coord::from_deg(lon, lat),
            _ => None,
        };
        let at = at.ok_or_else(|| e.fail("`lat`/`lon` are not a WGS84 position".into()))?;
        c.add_node(e.id, at);
    }
    for (id, g, tags) in geometry_ways {
        c.add_way_geometry(id, &g, tags);
    }
    for (id, g) in geometry_members {
        if !c.has_way(id) {
            c.add_way_geometry(id, &g, TagList::new());
        }
    }
    Ok(c.finish())
}

/// One element of the file: its index, type and id, for messages.
struct Element<'a> {
    index: usize,
    kind: &'a str,
    id: i64,
    object: &'a Object,
    path: &'a Path,
}

impl<'a> Element<'a> {
    /// The element at `index`; `None` for types that are no OSM element (`area`, `count`, …).
    fn new(index: usize, object: &'a Object, path: &'a Path) -> Result<Option<Self>, RadioError> {
        let kind = match object.get("type").and_then(Value::as_str) {
            Some(k @ ("node" | "way" | "relation")) => k,
            _ => return Ok(None),
        };
        let Some(id) = object.get("id").and_then(Value::as_i64) else {
            return Err(RadioError::OsmFile {
                path: path.to_path_buf(),
                at: format!("element {index} ({kind})"),
                message: format!(
                    "`id` = {} is not an integer",
                    object.get("id").unwrap_or(&Value::Null)
                ),
            });
        };
        Ok(Some(Element {
            index,
            kind,
            id,
            object,
            path,
        }))
    }

    fn fail(&self, message: String) -> RadioError {
        RadioError::OsmFile {
            path: self.path.to_path_buf(),
            at: format!("element {} ({}/{})", self.index, self.kind, self.id),
            message,
        }
    }

    /// The tags whose values are strings, borrowed: what decides whether the element is kept.
    fn tag_pairs(&self) -> impl Iterator<Item = (&'a str, &'a str)> + Clone + use<'a> {
        self.object
            .get("tags")
            .and_then(Value::as_object)
            .into_iter()
            .flatten()
            .filter_map(|(k, v)| Some((k.as_str(), v.as_str()?)))
    }

    /// The tags; absent is none, a value that is no string an error.
    fn tags(&self) -> Result<TagList, RadioError> {
        let Some(tags) = self.object.get("tags") else {
            return Ok(TagList::new());
        };
        let tags = tags
            .as_object()
            .ok_or_else(|| self.fail("`tags` is not an object".into()))?;
        tags.iter()
            .map(|(k, v)| match v {
                Value::String(s) => Ok((k.clone(), s.clone())),
                _ => Err(self.fail(format!("tag `{k}` = {v} is not a string"))),
            })
            .collect()
    }

    /// The array under `key`; absent is `None`, another type an error.
    fn array(&self, key: &str) -> Result<Option<&'a Vec<Value>>, RadioError> {
        match self.object.get(key) {
            None => Ok(None),
            Some(Value::Array(a)) => Ok(Some(a)),
            Some(_) => Err(self.fail(format!("`{key}` is not an array"))),
        }
    }
}

/// A `geometry` array: `{lat, lon}` objects, `null` for a position left out.
fn points(g: &Value) -> Result<Vec<Option<Coord>>, String> {
    let list = g.as_array().ok_or("`geometry` is not an array")?;
    list.iter()
        .enumerate()
        .map(|(k, p)| {
            if p.is_null() {
                return Ok(None);
            }
            let deg = |key: &str| p.get(key).and_then(Value::as_f64);
            match (deg("lon"), deg("lat")) {
                (Some(lon), Some(lat)) => Coord::from_deg(lon, lat).map(Some),
                _ => None,
            }
            .ok_or_else(|| format!("`geometry`[{k}] = {p} is not a WGS84 position"))
        })
        .collect()
}
