//! `[scenario]`: the area, the city (OSM or procedural) and the sites (spec/env.md "World").

use super::ConfigError;
#[allow(unused_imports)]
use super::check::*;
use serde::{Deserialize, Serialize};
#[allow(unused_imports)]
use std::path::PathBuf;

/// `scenario.buildings_file` of the default (Midtown) scenario, relative to the working
/// directory; when no file is there, the copy built into the binary is used
/// (`dupac_radio::bundled`).
pub const MIDTOWN_BUILDINGS_FILE: &str = "data/nyc_midtown_buildings.geojson";
/// `scenario.cells_file` of the default (Midtown) scenario, relative to the working directory;
/// when no file is there, the copy built into the binary is used.
pub const MIDTOWN_CELLS_FILE: &str = "data/nyc_midtown_cells.csv";

/// Which kind of city a scenario is built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum CityKind {
    /// Real OpenStreetMap footprints with heights from `scenario.buildings_file`.
    Osm,
    /// Seeded procedural Manhattan grid (`scenario.procedural`).
    Procedural,
}

/// How OSM building outlines that have 3D `building_part`s are extruded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BuildingDetail {
    /// Outlines with parts are replaced by their parts (each from `min_height_m` to `height_m`).
    Parts,
    /// Every outline is extruded from the ground to its roof (conservative, over-estimates set-backs).
    Outlines,
}

/// A lon/lat box (WGS84 degrees). Each bound defaults to the Midtown flight area's, so that one
/// bound can be set alone (`--set scenario.area.lat_max_deg=40.76`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct LonLatBox {
    /// West edge (degrees of longitude).
    pub lon_min_deg: f64,
    /// East edge (degrees of longitude).
    pub lon_max_deg: f64,
    /// South edge (degrees of latitude).
    pub lat_min_deg: f64,
    /// North edge (degrees of latitude).
    pub lat_max_deg: f64,
}

impl Default for LonLatBox {
    fn default() -> Self {
        ScenarioConfig::default().area
    }
}

impl LonLatBox {
    /// Centre of the box, `(lon, lat)` in degrees: the origin of the local ENU frame.
    pub fn centre_deg(&self) -> (f64, f64) {
        (
            0.5 * (self.lon_min_deg + self.lon_max_deg),
            0.5 * (self.lat_min_deg + self.lat_max_deg),
        )
    }
}

/// The scenario: which city, which flight area, where the base stations are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ScenarioConfig {
    /// Name written into caches and reports.
    pub name: String,
    /// Which kind of city the scenario is built from.
    pub city: CityKind,
    /// GeoJSON of building footprints (OSM export format of `data/README.md`), relative to the
    /// working directory. The default path, when no file is there, reads the Midtown copy
    /// built into the binary.
    pub buildings_file: PathBuf,
    /// How OSM building outlines that have 3D parts are extruded.
    pub detail: BuildingDetail,
    /// The flight area (spec/env.md "World"); its centre is the frame origin. Midtown's:
    /// lon −73.9935…−73.9765, lat 40.7460…40.7580. Its north edge lies 64 m south of where the
    /// buildings the OSM extract cut at lat 40.759 reach (40.75858 within the area's
    /// longitudes), so every building in the area is whole (data/README.md "North edge").
    pub area: LonLatBox,
    /// LTE cell-site estimates (CSV with `lat,lon,...,enb_id`), used when `sites_file` is unset;
    /// relative to the working directory. The default path, when no file is there, reads the
    /// Midtown copy built into the binary.
    pub cells_file: PathBuf,
    /// Optional explicit sites (CSV or TOML), replacing the placement from `cells_file`.
    pub sites_file: Option<PathBuf>,
    /// M, the number of GBSs (paper: 30).
    pub n_sites: usize,
    /// Roof search radius for mounting a site on a building (m).
    pub roof_search_m: f64,
    /// Mast height above the roof for a rooftop site (m).
    pub roof_mast_m: f64,
    /// Antenna height of a street-pole site when no roof is within `roof_search_m` (m).
    pub pole_height_m: f64,
    /// Radius within which the median rooftop height decides macro vs micro (m).
    pub macro_radius_m: f64,
    /// The procedural city's generator (`city = "procedural"`).
    pub procedural: ProceduralConfig,
}

impl Default for ScenarioConfig {
    fn default() -> Self {
        Self {
            name: "midtown".into(),
            city: CityKind::Osm,
            buildings_file: MIDTOWN_BUILDINGS_FILE.into(),
            detail: BuildingDetail::Parts,
            area: LonLatBox {
                lon_min_deg: -73.9935,
                lon_max_deg: -73.9765,
                lat_min_deg: 40.7460,
                lat_max_deg: 40.7580,
            },
            cells_file: MIDTOWN_CELLS_FILE.into(),
            sites_file: None,
            n_sites: 30,
            roof_search_m: 50.0,
            roof_mast_m: 3.0,
            pole_height_m: 10.0,
            macro_radius_m: 150.0,
            procedural: ProceduralConfig::default(),
        }
    }
}

/// The seeded Manhattan-grid generator, calibrated on Midtown (`data/README.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ProceduralConfig {
    /// Seed of the generator.
    pub seed: u64,
    /// Size of the square area (m); the frame origin is its centre.
    pub size_m: f64,
    /// Grid rotation, degrees east of true north (Manhattan: 29°).
    pub rotation_deg: f64,
    /// Street pitch along the avenues, centre to centre (m).
    pub street_pitch_m: f64,
    /// Width of a street (m).
    pub street_width_m: f64,
    /// Avenue spacing, centre to centre (m).
    pub avenue_spacing_m: f64,
    /// Width of an avenue (m).
    pub avenue_width_m: f64,
    /// Building height distribution: log-normal with this median and 90th percentile (m).
    pub height_median_m: f64,
    /// 90th percentile of the building heights (m).
    pub height_p90_m: f64,
    /// Lowest building height (m): the distribution is clamped to [height_min_m, height_max_m].
    pub height_min_m: f64,
    /// Highest building height (m).
    pub height_max_m: f64,
    /// Number of sites placed on a jittered lattice over the area.
    pub n_sites: usize,
}

impl Default for ProceduralConfig {
    fn default() -> Self {
        Self {
            seed: 7,
            size_m: 1400.0,
            rotation_deg: 29.0,
            street_pitch_m: 79.0,
            street_width_m: 18.0,
            avenue_spacing_m: 274.0,
            avenue_width_m: 30.0,
            height_median_m: 30.0,
            height_p90_m: 95.0,
            height_min_m: 6.0,
            height_max_m: 400.0,
            n_sites: 30,
        }
    }
}

impl ScenarioConfig {
    /// Checks `[scenario]` (each error names the key).
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        let s = self;
        let a = &s.area;
        for (k, v) in [
            ("scenario.area.lon_min_deg", a.lon_min_deg),
            ("scenario.area.lon_max_deg", a.lon_max_deg),
        ] {
            if !(v.is_finite() && (-180.0..=180.0).contains(&v)) {
                return Err(bad(
                    k,
                    format!("must be a longitude in [-180, 180], got {v}"),
                ));
            }
        }
        for (k, v) in [
            ("scenario.area.lat_min_deg", a.lat_min_deg),
            ("scenario.area.lat_max_deg", a.lat_max_deg),
        ] {
            if !(v.is_finite() && (-85.0..=85.0).contains(&v)) {
                return Err(bad(k, format!("must be a latitude in [-85, 85], got {v}")));
            }
        }
        if a.lon_min_deg >= a.lon_max_deg {
            return Err(bad("scenario.area.lon_max_deg", "must be > lon_min_deg"));
        }
        if a.lat_min_deg >= a.lat_max_deg {
            return Err(bad("scenario.area.lat_max_deg", "must be > lat_min_deg"));
        }
        if s.n_sites == 0 || s.n_sites > usize::from(u16::MAX) {
            return Err(bad("scenario.n_sites", "must be in 1..=65535"));
        }
        positive("scenario.roof_search_m", s.roof_search_m)?;
        finite("scenario.roof_mast_m", s.roof_mast_m)?;
        positive("scenario.pole_height_m", s.pole_height_m)?;
        positive("scenario.macro_radius_m", s.macro_radius_m)?;
        let p = &s.procedural;
        positive("scenario.procedural.size_m", p.size_m)?;
        finite("scenario.procedural.rotation_deg", p.rotation_deg)?;
        positive("scenario.procedural.street_pitch_m", p.street_pitch_m)?;
        positive("scenario.procedural.avenue_spacing_m", p.avenue_spacing_m)?;
        if !(p.street_width_m >= 0.0 && p.street_width_m < p.street_pitch_m) {
            return Err(bad(
                "scenario.procedural.street_width_m",
                "must be in [0, street_pitch_m)",
            ));
        }
        if !(p.avenue_width_m >= 0.0 && p.avenue_width_m < p.avenue_spacing_m) {
            return Err(bad(
                "scenario.procedural.avenue_width_m",
                "must be in [0, avenue_spacing_m)",
            ));
        }
        positive("scenario.procedural.height_median_m", p.height_median_m)?;
        if !(p.height_p90_m.is_finite() && p.height_p90_m > p.height_median_m) {
            return Err(bad(
                "scenario.procedural.height_p90_m",
                "must be > height_median_m",
            ));
        }
        positive("scenario.procedural.height_min_m", p.height_min_m)?;
        if !(p.height_max_m.is_finite() && p.height_max_m > p.height_min_m) {
            return Err(bad(
                "scenario.procedural.height_max_m",
                "must be > height_min_m",
            ));
        }
        if p.n_sites == 0 || p.n_sites > usize::from(u16::MAX) {
            return Err(bad("scenario.procedural.n_sites", "must be in 1..=65535"));
        }
        Ok(())
    }
}
