//! OSM area assembly: building ways and multipolygon relations → polygons, as libosmium and
//! osmtogeojson assemble them (<https://wiki.openstreetmap.org/wiki/Relation:multipolygon>):
//!
//! - a closed way (first reference = last, at least 4 references) tagged as a building is a
//!   polygon, id `way/<id>`;
//! - a building `type=multipolygon` relation is a multipolygon, id `relation/<id>`: its `outer`
//!   member ways (an empty role counts as `outer`) and its `inner` ones are each joined end to
//!   end by shared node ids into closed rings, a way reversed where it runs the other way; each
//!   inner ring goes to the smallest outer ring containing it;
//! - an element referencing a node or way the file lacks (an extract cut through it), or whose
//!   rings do not close, is no area: it is returned as [`Incomplete`], with the extent of the
//!   nodes it has.
//!
//! Ways come first, by id, then relations, by id; rings keep the direction their ways give them.

use super::model::{Coord, MemberKind, OsmData, TagList};
use serde::Serialize;

/// One assembled area: its tags and polygons (each an outer ring, then its inner rings; every
/// ring closed, first vertex = last).
#[derive(Debug, Clone, PartialEq)]
pub struct Area {
    /// `way/<id>` or `relation/<id>`.
    pub id: String,
    pub tags: TagList,
    /// `true` for a relation (written as a MultiPolygon).
    pub multi: bool,
    pub polygons: Vec<Vec<Vec<Coord>>>,
}

/// Why a building element is no area.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Why {
    /// It references nodes (or, a relation, ways) the file does not hold.
    MissingMembers,
    /// Every member is there, but its ways do not close into rings.
    Unclosed,
    /// An inner ring lies in no outer ring.
    InnerOutside,
}

/// A building way or relation that is no area, with the extent of the nodes the file holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Incomplete {
    /// `way/<id>` or `relation/<id>`.
    pub id: String,
    pub why: Why,
    /// Nodes referenced, and of those the file holds.
    pub nodes: usize,
    pub nodes_present: usize,
    /// Extent of the present nodes (degrees): `[lon_min, lat_min, lon_max, lat_max]`; `None`
    /// when none is present.
    pub present_bbox_deg: Option<[f64; 4]>,
}

/// The areas of a file and the building elements that are none.
#[derive(Debug, Clone, Default)]
pub struct Assembled {
    pub areas: Vec<Area>,
    pub incomplete: Vec<Incomplete>,
}

/// Assembles every building way and relation of `data`.
pub fn assemble(data: &OsmData) -> Assembled {
    let mut out = Assembled::default();
    for (id, way) in &data.ways {
        if !super::model::is_building(tags_of(&way.tags)) {
            continue;
        }
        let id = format!("way/{id}");
        let incomplete = |why| incomplete_of(&id, why, [way.refs.as_slice()], data);
        if way.refs.iter().any(|r| !data.nodes.contains_key(r)) {
            out.incomplete.push(incomplete(Why::MissingMembers));
        } else if way.refs.len() < 4 || way.refs.first() != way.refs.last() {
            out.incomplete.push(incomplete(Why::Unclosed));
        } else {
            out.areas.push(Area {
                id,
                tags: way.tags.clone(),
                multi: false,
                polygons: vec![vec![coords(&way.refs, data)]],
            });
        }
    }
    for (id, rel) in &data.relations {
        let id = format!("relation/{id}");
        let mut outer: Vec<&[i64]> = Vec::new();
        let mut inner: Vec<&[i64]> = Vec::new();
        let mut missing_way = false;
        for m in rel.members.iter().filter(|m| m.kind == MemberKind::Way) {
            let list = match m.role.as_str() {
                "outer" | "" => &mut outer,
                "inner" => &mut inner,
                _ => continue,
            };
            match data.ways.get(&m.id) {
                Some(w) => list.push(&w.refs),
                None => missing_way = true,
            }
        }
        let all = || outer.iter().chain(&inner).copied();
        let incomplete = |why| incomplete_of(&id, why, all(), data);
        let missing_node = all().flatten().any(|r| !data.nodes.contains_key(r));
        if missing_way || missing_node {
            out.incomplete.push(incomplete(Why::MissingMembers));
            continue;
        }
        let (Some(outer), Some(inner)) = (join_rings(&outer), join_rings(&inner)) else {
            out.incomplete.push(incomplete(Why::Unclosed));
            continue;
        };
        if outer.is_empty() {
            out.incomplete.push(incomplete(Why::Unclosed));
            continue;
        }
        let outer: Vec<Vec<Coord>> = outer.iter().map(|r| coords(r, data)).collect();
        let mut polygons: Vec<Vec<Vec<Coord>>> = outer.iter().map(|r| vec![r.clone()]).collect();
        let mut placed = true;
        for ring in inner.iter().map(|r| coords(r, data)) {
            match containing_ring(&outer, &ring) {
                Some(o) => polygons[o].push(ring),
                None => placed = false,
            }
        }
        if !placed {
            out.incomplete.push(incomplete(Why::InnerOutside));
            continue;
        }
        out.areas.push(Area {
            id,
            tags: rel.tags.clone(),
            multi: true,
            polygons,
        });
    }
    out
}

fn tags_of(tags: &TagList) -> impl Iterator<Item = (&str, &str)> + Clone {
    tags.iter().map(|(k, v)| (k.as_str(), v.as_str()))
}

/// The coordinates of references that are all present.
fn coords(refs: &[i64], data: &OsmData) -> Vec<Coord> {
    refs.iter().map(|r| data.nodes[r]).collect()
}

fn incomplete_of<'a>(
    id: &str,
    why: Why,
    ways: impl IntoIterator<Item = &'a [i64]>,
    data: &OsmData,
) -> Incomplete {
    let (mut nodes, mut present) = (0, 0);
    let mut bbox: Option<[i64; 4]> = None;
    for r in ways.into_iter().flatten() {
        nodes += 1;
        let Some(c) = data.nodes.get(r) else { continue };
        present += 1;
        let b = bbox.get_or_insert([c.lon_e7, c.lat_e7, c.lon_e7, c.lat_e7]);
        *b = [
            b[0].min(c.lon_e7),
            b[1].min(c.lat_e7),
            b[2].max(c.lon_e7),
            b[3].max(c.lat_e7),
        ];
    }
    Incomplete {
        id: id.to_string(),
        why,
        nodes,
        nodes_present: present,
        present_bbox_deg: bbox.map(|b| b.map(|v| v as f64 / 1e7)),
    }
}

/// Joins ways end to end into closed rings of at least 4 references: a ring starts with the
/// first unused way and takes, in member order, the first unused way sharing its open end's
/// node (reversed when that way ends there). `None` when a ring cannot be closed.
fn join_rings(ways: &[&[i64]]) -> Option<Vec<Vec<i64>>> {
    let mut used = vec![false; ways.len()];
    let mut rings = Vec::new();
    while let Some(start) = used.iter().position(|u| !u) {
        used[start] = true;
        let mut ring: Vec<i64> = ways[start].to_vec();
        while ring.len() < 2 || ring.first() != ring.last() {
            let end = *ring.last()?;
            let next = (0..ways.len()).find(|&k| {
                !used[k] && (ways[k].first() == Some(&end) || ways[k].last() == Some(&end))
            })?;
            used[next] = true;
            if ways[next].first() == Some(&end) {
                ring.extend_from_slice(&ways[next][1..]);
            } else {
                ring.extend(ways[next].iter().rev().skip(1));
            }
        }
        if ring.len() < 4 {
            return None;
        }
        rings.push(ring);
    }
    Some(rings)
}

/// The smallest of `outer` containing `ring`: tested with the first vertex of `ring` that is no
/// vertex of the outer ring (rings may touch at a node); `None` when none contains it.
fn containing_ring(outer: &[Vec<Coord>], ring: &[Coord]) -> Option<usize> {
    outer
        .iter()
        .enumerate()
        .filter(|(_, o)| {
            ring.iter()
                .find(|p| !o.contains(p))
                .is_some_and(|p| contains(o, *p))
        })
        .min_by(|a, b| area_abs(a.1).total_cmp(&area_abs(b.1)))
        .map(|(k, _)| k)
}

/// Even-odd point in a closed ring, in the 10⁻⁷-degree plane.
fn contains(ring: &[Coord], p: Coord) -> bool {
    let (px, py) = (p.lon_e7 as f64, p.lat_e7 as f64);
    let mut inside = false;
    for w in ring.windows(2) {
        let (ax, ay) = (w[0].lon_e7 as f64, w[0].lat_e7 as f64);
        let (bx, by) = (w[1].lon_e7 as f64, w[1].lat_e7 as f64);
        if (ay > py) != (by > py) && px < ax + (py - ay) * (bx - ax) / (by - ay) {
            inside = !inside;
        }
    }
    inside
}

/// Shoelace area of a closed ring (10⁻¹⁴ degree²).
fn area_abs(ring: &[Coord]) -> f64 {
    let o = ring[0];
    ring.windows(2)
        .map(|w| {
            let (ax, ay) = (
                (w[0].lon_e7 - o.lon_e7) as f64,
                (w[0].lat_e7 - o.lat_e7) as f64,
            );
            let (bx, by) = (
                (w[1].lon_e7 - o.lon_e7) as f64,
                (w[1].lat_e7 - o.lat_e7) as f64,
            );
            ax * by - bx * ay
        })
        .sum::<f64>()
        .abs()
        / 2.0
}
