//! The city: buildings as plain data ([`Building`]), loaders (OSM GeoJSON in [`osm`], procedural
//! grid in [`procedural`]), the triangle mesh for line of sight and collisions ([`CityMesh`]), and
//! a 2D index for point-in-building and rooftop-height queries ([`FootprintIndex`]).

mod building;
mod index;
mod mesh;
pub mod osm;
pub mod procedural;

pub use building::{Building, point_in_ring, signed_area_m2};
pub use index::FootprintIndex;
pub use mesh::{CityMesh, to_vec3};

use crate::error::RadioError;
use crate::geo::LocalProjection;
use dupac_common::config::{CityKind, ScenarioConfig};
use dupac_common::geometry::{Bounds2, Point};

/// Buildings farther than this outside the flight area are dropped at load time (m). They can
/// still block links between a site and a UAV inside the area only if they lie between the two,
/// and every site is inside or within a few hundred metres of the area.
pub const BUILDING_MARGIN_M: f64 = 300.0;

/// A loaded city: buildings, their mesh and index, and the flight area.
#[derive(Debug, Clone)]
pub struct City {
    /// Scenario name (`midtown`, `procedural`, …).
    pub name: String,
    /// The flight area (m, local frame).
    pub area_m: Bounds2,
    pub buildings: Vec<Building>,
    pub mesh: CityMesh,
    pub index: FootprintIndex,
    /// lon/lat projection for real cities; `None` for synthetic ones.
    pub projection: Option<LocalProjection>,
}

impl City {
    /// Builds a city from plain buildings (used by the loaders and by tests with hand-built
    /// geometry).
    pub fn from_buildings(
        name: impl Into<String>,
        area_m: Bounds2,
        buildings: Vec<Building>,
        projection: Option<LocalProjection>,
    ) -> Result<City, RadioError> {
        let mesh = CityMesh::build(&buildings)?;
        let index = FootprintIndex::build(&buildings);
        Ok(City {
            name: name.into(),
            area_m,
            buildings,
            mesh,
            index,
            projection,
        })
    }

    /// Loads the city the scenario names: OSM buildings of the flight area, or the procedural grid.
    pub fn load(cfg: &ScenarioConfig) -> Result<City, RadioError> {
        match cfg.city {
            CityKind::Osm => {
                let projection = LocalProjection::centred_on(&cfg.area);
                let area_m = projection.box_m(&cfg.area);
                let keep = area_m.expanded(BUILDING_MARGIN_M);
                let buildings =
                    osm::load_buildings(&cfg.buildings_file, &projection, cfg.detail, keep)?;
                tracing::info!(
                    file = %cfg.buildings_file.display(),
                    buildings = buildings.len(),
                    "loaded OSM buildings"
                );
                City::from_buildings(cfg.name.clone(), area_m, buildings, Some(projection))
            }
            CityKind::Procedural => {
                let generated = procedural::generate(&cfg.procedural);
                let h = 0.5 * cfg.procedural.size_m;
                City::from_buildings(
                    cfg.name.clone(),
                    Bounds2::new(-h, -h, h, h),
                    generated.buildings,
                    None,
                )
            }
        }
    }

    /// Whether `(x, y)` lies inside the flight area.
    pub fn in_area(&self, x_m: f64, y_m: f64) -> bool {
        self.area_m.contains(x_m, y_m)
    }

    /// Whether the point is inside a building (between its floor and roof).
    pub fn is_inside_building(&self, p_m: Point) -> bool {
        self.index
            .containing(&self.buildings, p_m[0], p_m[1])
            .any(|b| p_m[2] >= b.z_min_m && p_m[2] <= b.z_max_m)
    }

    /// Highest roof at `(x, y)` (m above ground), 0 in the street.
    pub fn roof_height_m(&self, x_m: f64, y_m: f64) -> f64 {
        self.index
            .containing(&self.buildings, x_m, y_m)
            .map(|b| b.z_max_m)
            .fold(0.0, f64::max)
    }

    /// Whether the segment between two points crosses a building (NLoS, spec/radio.md D9).
    #[inline]
    pub fn segment_blocked(&self, a_m: Point, b_m: Point) -> bool {
        self.mesh.segment_blocked(a_m, b_m)
    }

    /// A short hash of the geometry (ids, rings, heights) for cache headers.
    pub fn fingerprint(&self) -> u64 {
        let mut h = dupac_common::fingerprint::Fnv64::new();
        h.write_str(&self.name);
        for v in self.area_m.to_array() {
            h.write_f64(v);
        }
        for b in &self.buildings {
            h.write_str(&b.id);
            h.write_f64(b.z_min_m);
            h.write_f64(b.z_max_m);
            for ring in std::iter::once(&b.outer_m).chain(b.holes_m.iter()) {
                h.write_u64(ring.len() as u64);
                for p in ring {
                    h.write_f64(p[0]);
                    h.write_f64(p[1]);
                }
            }
        }
        h.finish()
    }
}
