//! OSM PBF (`.osm.pbf`, <https://wiki.openstreetmap.org/wiki/PBF_Format>), read with `osmpbf`
//! blob by blob, three times over ([`Collector`]): the building multipolygons, then the building
//! ways and those relations' member ways, then only the nodes these reference. Memory grows
//! with the buildings, not with the extract; a blob is at most `osmpbf`'s 32 MiB.
//!
//! Positions are PBF's nanodegrees (offset + granularity × value) rounded to 10⁻⁷ degrees.

use super::model::is_building_multipolygon;
use super::model::{Collector, Coord, Member, MemberKind, OsmData, Relation, TagList, Way};
use crate::error::RadioError;
use osmpbf::{BlobDecode, BlobReader, Element, PrimitiveBlock, RelMemberType};
use std::path::Path;

/// The elements a building area needs, read from the PBF file `path`.
pub fn read(path: &Path) -> Result<OsmData, RadioError> {
    let mut c = Collector::default();
    each_block(path, "relations", |block| {
        for e in block.elements() {
            let Element::Relation(r) = e else { continue };
            if !is_building_multipolygon(r.tags()) {
                continue;
            }
            let members = r
                .members()
                .map(|m| {
                    let role = m
                        .role()
                        .map_err(|e| format!("relation/{}: a member's role: {e}", r.id()))?;
                    let kind = match m.member_type {
                        RelMemberType::Node => MemberKind::Node,
                        RelMemberType::Way => MemberKind::Way,
                        RelMemberType::Relation => MemberKind::Relation,
                    };
                    Ok(Member {
                        kind,
                        id: m.member_id,
                        role: role.to_string(),
                    })
                })
                .collect::<Result<Vec<_>, String>>()?;
            c.add_relation(
                r.id(),
                Relation {
                    members,
                    tags: tag_list(r.tags()),
                },
            );
        }
        Ok(())
    })?;
    each_block(path, "ways", |block| {
        for e in block.elements() {
            let Element::Way(w) = e else { continue };
            if c.wants_way(w.id(), w.tags()) {
                let way = Way {
                    refs: w.refs().collect(),
                    tags: tag_list(w.tags()),
                };
                c.add_way(w.id(), way);
            }
        }
        Ok(())
    })?;
    each_block(path, "nodes", |block| {
        for e in block.elements() {
            let (id, lon, lat) = match e {
                Element::Node(n) => (n.id(), n.nano_lon(), n.nano_lat()),
                Element::DenseNode(n) => (n.id(), n.nano_lon(), n.nano_lat()),
                _ => continue,
            };
            if c.wants_node(id) {
                c.add_node(id, Coord::from_nano(lon, lat));
            }
        }
        Ok(())
    })?;
    Ok(c.finish())
}

fn tag_list<'a>(tags: impl Iterator<Item = (&'a str, &'a str)>) -> TagList {
    tags.map(|(k, v)| (k.to_string(), v.to_string())).collect()
}

/// Calls `f` on every data block of the file; an error names the blob (index and byte offset)
/// and the pass.
fn each_block(
    path: &Path,
    pass: &str,
    mut f: impl FnMut(&PrimitiveBlock) -> Result<(), String>,
) -> Result<(), RadioError> {
    let fail = |at: String, message: String| RadioError::OsmFile {
        path: path.to_path_buf(),
        at,
        message: format!("PBF, reading the {pass}: {message}"),
    };
    let reader = BlobReader::from_path(path).map_err(|e| fail("opening".into(), e.to_string()))?;
    for (index, blob) in reader.enumerate() {
        let blob = blob.map_err(|e| fail(format!("blob {index}"), e.to_string()))?;
        let at = match blob.offset() {
            Some(o) => format!("blob {index} (byte {})", o.0),
            None => format!("blob {index}"),
        };
        match blob.decode().map_err(|e| fail(at.clone(), e.to_string()))? {
            BlobDecode::OsmData(block) => f(&block).map_err(|e| fail(at, e))?,
            BlobDecode::OsmHeader(_) | BlobDecode::Unknown(_) => {}
        }
    }
    Ok(())
}
