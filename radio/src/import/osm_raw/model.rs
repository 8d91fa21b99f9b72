//! The plain OpenStreetMap element model the raw readers fill: nodes with their position, ways
//! with their node references and tags, relations with their members and tags (the OSM data
//! model, <https://wiki.openstreetmap.org/wiki/Elements>), and [`Collector`], which keeps only
//! what the building areas need.

use std::collections::{BTreeMap, HashMap, HashSet};

/// A node's position in OSM's own fixed point: 10⁻⁷ degrees, as the database stores it (and as
/// PBF's default granularity of 100 nanodegrees gives it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Coord {
    /// Longitude (10⁻⁷ degrees).
    pub lon_e7: i64,
    /// Latitude (10⁻⁷ degrees).
    pub lat_e7: i64,
}

impl Coord {
    /// The position of decimal degrees as written in XML or JSON, rounded to 10⁻⁷ degrees;
    /// `None` when it is not a WGS84 lon/lat.
    pub fn from_deg(lon: f64, lat: f64) -> Option<Coord> {
        let ok = lon.is_finite() && lat.is_finite() && lon.abs() <= 180.0 && lat.abs() <= 90.0;
        ok.then(|| Coord {
            lon_e7: (lon * 1e7).round() as i64,
            lat_e7: (lat * 1e7).round() as i64,
        })
    }

    /// The position of nanodegrees (PBF), rounded to 10⁻⁷ degrees.
    pub fn from_nano(lon_nano: i64, lat_nano: i64) -> Coord {
        let e7 = |n: i64| {
            let (q, r) = (n.div_euclid(100), n.rem_euclid(100));
            q + i64::from(r >= 50)
        };
        Coord {
            lon_e7: e7(lon_nano),
            lat_e7: e7(lat_nano),
        }
    }

    /// Longitude (degrees): the nearest `f64` to the 7-decimal value.
    pub fn lon_deg(self) -> f64 {
        self.lon_e7 as f64 / 1e7
    }

    /// Latitude (degrees): the nearest `f64` to the 7-decimal value.
    pub fn lat_deg(self) -> f64 {
        self.lat_e7 as f64 / 1e7
    }
}

/// An element's tags, in the order read.
pub type TagList = Vec<(String, String)>;

/// A way: its node references in order and its tags.
#[derive(Debug, Clone, PartialEq)]
pub struct Way {
    pub refs: Vec<i64>,
    pub tags: TagList,
}

/// What a relation member is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MemberKind {
    Node,
    Way,
    Relation,
}

/// One member of a relation.
#[derive(Debug, Clone, PartialEq)]
pub struct Member {
    pub kind: MemberKind,
    pub id: i64,
    /// `outer`, `inner`, … (empty when none).
    pub role: String,
}

/// A relation: its members in order and its tags.
#[derive(Debug, Clone, PartialEq)]
pub struct Relation {
    pub members: Vec<Member>,
    pub tags: TagList,
}

/// The elements of one file that the building areas need.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OsmData {
    /// The nodes the kept ways reference and the file holds.
    pub nodes: HashMap<i64, Coord>,
    /// Ways tagged as buildings, and the ways of kept relations.
    pub ways: BTreeMap<i64, Way>,
    /// Multipolygon relations tagged as buildings.
    pub relations: BTreeMap<i64, Relation>,
}

/// Tagged `building` or `building:part` with another value than `no`: what the import reads as
/// a building (docs/scenario.md, "what is a building").
pub fn is_building<'a>(tags: impl IntoIterator<Item = (&'a str, &'a str)>) -> bool {
    tags.into_iter()
        .any(|(k, v)| (k == "building" || k == "building:part") && v != "no")
}

/// A building area relation: `type=multipolygon` and [`is_building`].
pub fn is_building_multipolygon<'a>(
    tags: impl IntoIterator<Item = (&'a str, &'a str)> + Clone,
) -> bool {
    tags.clone()
        .into_iter()
        .any(|(k, v)| k == "type" && v == "multipolygon")
        && is_building(tags)
}

/// Keeps what the areas need while a reader goes over a file three times: relations first (the
/// building multipolygons, whose member ways are then wanted), then ways (building ways and
/// those members, whose nodes are then wanted), then nodes (only those). Memory grows with the
/// buildings of the file, not with the file.
#[derive(Debug, Default)]
pub struct Collector {
    data: OsmData,
    member_ways: HashSet<i64>,
    wanted_nodes: HashSet<i64>,
    /// Node ids by position, for ways known only by their geometry.
    by_position: Option<HashMap<Coord, i64>>,
    /// The last id given to a position no node of the file has (counting down from -1).
    last_synthetic: i64,
}

impl Collector {
    /// First pass: keeps a building multipolygon.
    pub fn add_relation(&mut self, id: i64, relation: Relation) {
        for m in &relation.members {
            if m.kind == MemberKind::Way {
                self.member_ways.insert(m.id);
            }
        }
        self.data.relations.insert(id, relation);
    }

    /// Second pass: whether the way with `id` and `tags` is needed.
    pub fn wants_way<'a>(
        &self,
        id: i64,
        tags: impl IntoIterator<Item = (&'a str, &'a str)>,
    ) -> bool {
        self.member_ways.contains(&id) || is_building(tags)
    }

    /// Second pass: keeps a way ([`Self::wants_way`]).
    pub fn add_way(&mut self, id: i64, way: Way) {
        self.wanted_nodes.extend(way.refs.iter().copied());
        self.data.ways.insert(id, way);
    }

    /// Third pass: whether the node `id` is needed.
    pub fn wants_node(&self, id: i64) -> bool {
        self.wanted_nodes.contains(&id)
    }

    /// Third pass: keeps a node ([`Self::wants_node`]).
    pub fn add_node(&mut self, id: i64, at: Coord) {
        self.data.nodes.insert(id, at);
    }

    /// Whether the way `id` is kept already.
    pub fn has_way(&self, id: i64) -> bool {
        self.data.ways.contains_key(&id)
    }

    /// After the third pass: keeps a way known only by its node positions (an Overpass
    /// `out geom` relation member; `None`: a position left out, as for a node outside the
    /// query's box). Each position becomes the id of a kept node there (the smallest, if
    /// several), else a new negative id, so that ways meeting at a point share a node and join
    /// as the same ways with their node ids would; a `None` becomes an id no node has.
    pub fn add_way_geometry(&mut self, id: i64, points: &[Option<Coord>], tags: TagList) {
        let nodes = &self.data.nodes;
        let by_position = self.by_position.get_or_insert_with(|| {
            let mut m: HashMap<Coord, i64> = HashMap::new();
            for (&n, &c) in nodes {
                let e = m.entry(c).or_insert(n);
                *e = (*e).min(n);
            }
            m
        });
        let mut refs = Vec::with_capacity(points.len());
        for p in points {
            let node = match p {
                Some(c) => match by_position.get(c) {
                    Some(&n) => n,
                    None => {
                        self.last_synthetic -= 1;
                        by_position.insert(*c, self.last_synthetic);
                        self.data.nodes.insert(self.last_synthetic, *c);
                        self.last_synthetic
                    }
                },
                None => {
                    self.last_synthetic -= 1;
                    self.last_synthetic
                }
            };
            refs.push(node);
        }
        self.data.ways.insert(id, Way { refs, tags });
    }

    /// The elements kept.
    pub fn finish(self) -> OsmData {
        self.data
    }
}
