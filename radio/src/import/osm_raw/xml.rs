//! OSM XML (`.osm`, <https://wiki.openstreetmap.org/wiki/OSM_XML>): an `<osm>` root with
//! `<node id lat lon>`, `<way id>` with `<nd ref>`, `<relation id>` with
//! `<member type ref role>`, each with `<tag k v>` children. Elements marked deleted
//! (`action="delete"`, as JOSM saves them, or `visible="false"`) are skipped.
//!
//! Read with `roxmltree`: a read-only tree over the text that knows where each element starts,
//! so an error names its line; the file is held whole while it is read (as the GeoJSON and the
//! Overpass JSON are), and only the buildings' elements are kept from it.

use super::model::is_building_multipolygon;
use super::model::{Collector, Coord, Member, MemberKind, OsmData, Relation, TagList, Way};
use crate::error::RadioError;
use roxmltree::{Document, Node};
use std::path::Path;

/// The elements a building area needs, read from the OSM XML `text` of `path`.
pub fn read(text: &str, path: &Path) -> Result<OsmData, RadioError> {
    let doc = Document::parse(text).map_err(|e| RadioError::OsmFile {
        path: path.to_path_buf(),
        at: format!("line {}, column {}", e.pos().row, e.pos().col),
        message: format!("not valid XML: {e}"),
    })?;
    let root = doc.root_element();
    if root.tag_name().name() != "osm" {
        return Err(RadioError::OsmFile {
            path: path.to_path_buf(),
            at: line_of(&doc, root),
            message: format!(
                "the root element is <{}>, not <osm>",
                root.tag_name().name()
            ),
        });
    }
    let elements = |name: &'static str| {
        root.children()
            .filter(move |n| n.is_element() && n.tag_name().name() == name)
            .filter(|n| {
                n.attribute("action") != Some("delete") && n.attribute("visible") != Some("false")
            })
    };
    let mut c = Collector::default();
    for n in elements("relation") {
        let e = Element::new(&doc, n, path)?;
        if !is_building_multipolygon(e.tag_pairs()) {
            continue;
        }
        let tags = e.tags()?;
        let mut members = Vec::new();
        for m in e.children("member") {
            let kind = match m.attribute("type") {
                Some("node") => MemberKind::Node,
                Some("way") => MemberKind::Way,
                Some("relation") => MemberKind::Relation,
                _ => return Err(e.fail_at(m, "member `type` is not node, way or relation")),
            };
            let id = m
                .attribute("ref")
                .and_then(|r| r.parse().ok())
                .ok_or_else(|| e.fail_at(m, "member `ref` is not an integer"))?;
            let role = m.attribute("role").unwrap_or_default().to_string();
            members.push(Member { kind, id, role });
        }
        c.add_relation(e.id, Relation { members, tags });
    }
    for n in elements("way") {
        let e = Element::new(&doc, n, path)?;
        if !c.wants_way(e.id, e.tag_pairs()) {
            continue;
        }
        let tags = e.tags()?;
        let refs = e
            .children("nd")
            .map(|nd| {
                nd.attribute("ref")
                    .and_then(|r| r.parse().ok())
                    .ok_or_else(|| e.fail_at(nd, "<nd> `ref` is not a node id"))
            })
            .collect::<Result<Vec<i64>, _>>()?;
        c.add_way(e.id, Way { refs, tags });
    }
    for n in elements("node") {
        let e = Element::new(&doc, n, path)?;
        if !c.wants_node(e.id) {
            continue;
        }
        let deg = |k: &str| n.attribute(k).and_then(|v| v.trim().parse::<f64>().ok());
        let at = match (deg("lon"), deg("lat")) {
            (Some(lon), Some(lat)) => Coord::from_deg(lon, lat),
            _ => None,
        };
        let at = at.ok_or_else(|| e.fail_at(n, "`lat`/`lon` are not a WGS84 position"))?;
        c.add_node(e.id, at);
    }
    Ok(c.finish())
}

fn line_of(doc: &Document, n: Node) -> String {
    let pos = doc.text_pos_at(n.range().start);
    format!("line {}", pos.row)
}

/// One `<node>`, `<way>` or `<relation>`, for its children and messages.
struct Element<'d, 'i> {
    doc: &'d Document<'i>,
    node: Node<'d, 'i>,
    id: i64,
    path: &'d Path,
}

impl<'d, 'i> Element<'d, 'i> {
    fn new(doc: &'d Document<'i>, node: Node<'d, 'i>, path: &'d Path) -> Result<Self, RadioError> {
        let kind = node.tag_name().name();
        let id = node.attribute("id").and_then(|v| v.parse().ok());
        let Some(id) = id else {
            return Err(RadioError::OsmFile {
                path: path.to_path_buf(),
                at: format!("{}, <{kind}>", line_of(doc, node)),
                message: format!(
                    "`id` = {:?} is not an integer",
                    node.attribute("id").unwrap_or("")
                ),
            });
        };
        Ok(Element {
            doc,
            node,
            id,
            path,
        })
    }

    /// An error at `at` (this element or one of its children), naming this element.
    fn fail_at(&self, at: Node, message: &str) -> RadioError {
        RadioError::OsmFile {
            path: self.path.to_path_buf(),
            at: format!(
                "{} ({}/{})",
                line_of(self.doc, at),
                self.node.tag_name().name(),
                self.id
            ),
            message: message.to_string(),
        }
    }

    fn children(
        &self,
        name: &'static str,
    ) -> impl Iterator<Item = Node<'d, 'i>> + Clone + use<'d, 'i> {
        self.node
            .children()
            .filter(move |n| n.is_element() && n.tag_name().name() == name)
    }

    /// The complete `<tag k v>` children, borrowed: what decides whether the element is kept.
    fn tag_pairs(&self) -> impl Iterator<Item = (&'d str, &'d str)> + Clone + use<'d, 'i> {
        self.children("tag")
            .filter_map(|t| Some((t.attribute("k")?, t.attribute("v")?)))
    }

    /// The `<tag k v>` children; one without `k` or `v` is an error.
    fn tags(&self) -> Result<TagList, RadioError> {
        self.children("tag")
            .map(|t| match (t.attribute("k"), t.attribute("v")) {
                (Some(k), Some(v)) => Ok((k.to_string(), v.to_string())),
                _ => Err(self.fail_at(t, "<tag> without `k` or `v`")),
            })
            .collect()
    }
}
