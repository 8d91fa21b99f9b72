//! A scenario directory from raw data: `buildings.geojson` ([`super::osm`]), `cells.csv`
//! ([`super::opencellid`]) and `config.toml`, the configuration `--config` takes. The
//! configuration sets only what differs from the defaults: the scenario's name, files, flight
//! area and (when fewer cells are found) site count, and its own RSRP cache, held-out pairs and
//! map folder, so nothing of another scenario is reused; a flight area narrower than Midtown's
//! scales the pair distances with it.

use super::opencellid::{CellCounts, CellRules, import_cells};
use super::osm::{BuildingCounts, OsmRules, import_buildings};
use crate::error::RadioError;
use crate::geo::LocalProjection;
use crate::world::RadioWorld;
use dupac_common::config::{Config, LonLatBox, PairsConfig, ScenarioConfig};
use std::path::{Path, PathBuf};

/// Widest selection box accepted (m): the local projection stays exact to centimetres only over
/// city-sized areas, and the flight area's RSRP cache grows with its square.
pub const MAX_SELECT_SPAN_M: f64 = 50_000.0;

/// What to import, and where.
#[derive(Debug, Clone)]
pub struct ImportPlan {
    /// Raw OSM buildings: OSM PBF, OSM XML, Overpass JSON or GeoJSON (told by content).
    pub buildings: PathBuf,
    /// OpenCelliD cells (CSV, or `.csv.gz`).
    pub cells: PathBuf,
    /// The flight area (`scenario.area`).
    pub area: LonLatBox,
    /// The box whose buildings and cells are kept; `None`: the area widened by `margin_m`.
    pub select: Option<LonLatBox>,
    /// Margin of the default selection box around the area (m).
    pub margin_m: f64,
    /// The scenario directory, as given (its files are named through it in the configuration).
    pub out: PathBuf,
    /// `scenario.name`.
    pub name: String,
    pub osm: OsmRules,
    pub cells_rules: CellRules,
    /// Overwrite a scenario directory that already has a `config.toml`.
    pub force: bool,
}

/// What an import wrote.
#[derive(Debug, Clone)]
pub struct ImportSummary {
    pub select: LonLatBox,
    pub buildings: BuildingCounts,
    pub cells: CellCounts,
    /// The configuration written (validated) and its path.
    pub config: Config,
    pub config_path: PathBuf,
    /// The text of `config.toml`.
    pub config_toml: String,
    /// The world the loaders make of the written files (what `map` and `train` load).
    pub world: RadioWorld,
}

/// `area` widened by `margin_m` metres on every side (in its own projection).
pub fn widen(area: &LonLatBox, margin_m: f64) -> LonLatBox {
    let p = LocalProjection::centred_on(area);
    let b = p.box_m(area).expanded(margin_m);
    let (lon_min_deg, lat_min_deg) = p.to_lon_lat_deg([b.min_m.x, b.min_m.y]);
    let (lon_max_deg, lat_max_deg) = p.to_lon_lat_deg([b.max_m.x, b.max_m.y]);
    LonLatBox {
        lon_min_deg,
        lon_max_deg,
        lat_min_deg,
        lat_max_deg,
    }
}

/// Imports the plan's buildings and cells and writes the scenario directory. `config.toml` is
/// written last, after the configuration validated and the written files loaded as the world
/// `map` and `train` build: a directory with one is complete.
pub fn import_scenario(plan: &ImportPlan) -> Result<ImportSummary, RadioError> {
    let bad = |message: String| RadioError::Import { message };
    let config_path = plan.out.join("config.toml");
    if config_path.exists() && !plan.force {
        return Err(bad(format!(
            "{} exists: the scenario directory holds an import (--force overwrites it)",
            config_path.display()
        )));
    }
    if !(plan.margin_m.is_finite() && plan.margin_m >= 0.0) {
        return Err(bad(format!("margin {} m: must be ≥ 0", plan.margin_m)));
    }
    if !(plan.osm.default_height_m > 0.0 && plan.osm.default_height_m < 2000.0) {
        return Err(bad(format!(
            "default height {} m: must be in (0, 2000)",
            plan.osm.default_height_m
        )));
    }
    let l = plan.osm.heights.level_height_m;
    if !(l > 0.0 && l <= 20.0) {
        return Err(bad(format!("level height {l} m: must be in (0, 20]")));
    }
    // 0 turns the nearby rule off; under 1 m the neighbour grid would have more cells than the
    // coordinates can index.
    let r = plan.osm.nearby_m;
    if !(r == 0.0 || (1.0..=5_000.0).contains(&r)) {
        return Err(bad(format!(
            "nearby radius {r} m: must be 0 (off) or in [1, 5000]"
        )));
    }
    // The area's own checks (the configuration's), before any work.
    let paths = ScenarioPaths::new(&plan.out)?;
    let probe = config_toml(plan, &paths, ScenarioConfig::default().n_sites)?;
    Config::from_toml_str(&probe, &config_path.display().to_string(), &[])
        .map_err(|e| bad(e.to_string()))?;
    let select = plan
        .select
        .unwrap_or_else(|| widen(&plan.area, plan.margin_m));
    check_select(&select)?;
    let buildings = import_buildings(&plan.buildings, &select, &plan.osm)?;
    let cells = import_cells(&plan.cells, &select, &plan.cells_rules)?;
    if cells.counts.sites == 0 {
        return Err(RadioError::Sites {
            path: plan.cells.clone(),
            message: format!(
                "no {} cells inside the selection box {select:?} ({} rows read, {} of another \
                 radio, {} outside)",
                plan.cells_rules.radio,
                cells.counts.rows,
                cells.counts.other_radio,
                cells.counts.outside
            ),
        });
    }
    let n_sites = cells.counts.sites.min(ScenarioConfig::default().n_sites);
    let text = config_toml(plan, &paths, n_sites)?;
    let config = Config::from_toml_str(&text, &config_path.display().to_string(), &[])
        .map_err(|e| bad(e.to_string()))?;
    dupac_common::fsio::write_atomic(&paths.buildings, buildings.geojson.as_bytes())?;
    dupac_common::fsio::write_atomic(&paths.cells, cells.csv.as_bytes())?;
    let world = RadioWorld::build(&config).map_err(|e| {
        bad(format!(
            "the imported files do not load, so no {} was written: {e}",
            config_path.display()
        ))
    })?;
    dupac_common::fsio::write_atomic(&config_path, text.as_bytes())?;
    Ok(ImportSummary {
        select,
        buildings: buildings.counts,
        cells: cells.counts,
        config,
        config_path,
        config_toml: text,
        world,
    })
}

/// The selection box must be a box and stay city-sized (it need not contain the flight area).
fn check_select(select: &LonLatBox) -> Result<(), RadioError> {
    let bad = |message: String| RadioError::Import { message };
    if !(select.lon_min_deg < select.lon_max_deg && select.lat_min_deg < select.lat_max_deg) {
        return Err(bad(format!("selection box {select:?} is empty")));
    }
    let b = LocalProjection::centred_on(select).box_m(select);
    if b.width_m() > MAX_SELECT_SPAN_M || b.height_m() > MAX_SELECT_SPAN_M {
        return Err(bad(format!(
            "selection box spans {:.0} m × {:.0} m, more than {MAX_SELECT_SPAN_M} m",
            b.width_m(),
            b.height_m()
        )));
    }
    Ok(())
}

/// The files of a scenario directory, as the configuration names them.
struct ScenarioPaths {
    buildings: PathBuf,
    cells: PathBuf,
    cache: PathBuf,
    pairs: PathBuf,
    test_pairs: PathBuf,
    map: PathBuf,
}

impl ScenarioPaths {
    fn new(out: &Path) -> Result<Self, RadioError> {
        let s = Self {
            buildings: out.join("buildings.geojson"),
            cells: out.join("cells.csv"),
            cache: out.join("cache").join("rsrp.bin"),
            pairs: out.join("pairs").join("eval_pairs.jsonl"),
            test_pairs: out.join("pairs").join("test_pairs.jsonl"),
            map: out.join("map"),
        };
        if out.to_str().is_none() {
            return Err(RadioError::Import {
                message: format!("{}: a configuration names only UTF-8 paths", out.display()),
            });
        }
        Ok(s)
    }
}

fn path_value(p: &Path) -> toml::Value {
    toml::Value::String(p.to_string_lossy().into_owned())
}

/// The short side of the default (Midtown) flight area (m): the scale of the default pairs.
fn default_short_side_m() -> f64 {
    let area = ScenarioConfig::default().area;
    let b = LocalProjection::centred_on(&area).box_m(&area);
    b.width_m().min(b.height_m())
}

/// `config.toml`: a header comment, then only the keys that differ from the defaults.
fn config_toml(
    plan: &ImportPlan,
    paths: &ScenarioPaths,
    n_sites: usize,
) -> Result<String, RadioError> {
    use toml::{Table, Value};
    let defaults = ScenarioConfig::default();
    let a = &plan.area;
    let mut area = Table::new();
    area.insert("lon_min_deg".into(), Value::Float(a.lon_min_deg));
    area.insert("lon_max_deg".into(), Value::Float(a.lon_max_deg));
    area.insert("lat_min_deg".into(), Value::Float(a.lat_min_deg));
    area.insert("lat_max_deg".into(), Value::Float(a.lat_max_deg));
    let mut scenario = Table::new();
    scenario.insert("name".into(), Value::String(plan.name.clone()));
    scenario.insert("buildings_file".into(), path_value(&paths.buildings));
    scenario.insert("cells_file".into(), path_value(&paths.cells));
    if n_sites != defaults.n_sites {
        scenario.insert("n_sites".into(), Value::Integer(n_sites as i64));
    }
    scenario.insert("area".into(), Value::Table(area));
    let mut cache = Table::new();
    cache.insert("path".into(), path_value(&paths.cache));
    let mut pairs = Table::new();
    pairs.insert("eval_file".into(), path_value(&paths.pairs));
    pairs.insert("test_file".into(), path_value(&paths.test_pairs));
    let b = LocalProjection::centred_on(a).box_m(a);
    let scale = b.width_m().min(b.height_m()) / default_short_side_m();
    if scale < 1.0 && scale.is_finite() {
        let d = PairsConfig::default();
        let r = |x: f64| (x * scale / 5.0).round().max(1.0) * 5.0;
        if r(d.min_m) >= r(d.max_m) {
            return Err(RadioError::Import {
                message: format!(
                    "the flight area {:.0} m × {:.0} m is too small for episodes: its pair \
                     distances would span {} m to {} m",
                    b.width_m(),
                    b.height_m(),
                    r(d.min_m),
                    r(d.max_m)
                ),
            });
        }
        let m = |x: f64| Value::Float(r(x));
        pairs.insert("min_m".into(), m(d.min_m));
        pairs.insert("max_m".into(), m(d.max_m));
        let mut bins: Vec<Value> = d.eval_bins_m.iter().map(|&x| m(x)).collect();
        bins.dedup();
        pairs.insert("eval_bins_m".into(), Value::Array(bins));
    }
    let mut map = Table::new();
    map.insert("out_dir".into(), path_value(&paths.map));
    let mut root = Table::new();
    root.insert("scenario".into(), Value::Table(scenario));
    root.insert("cache".into(), Value::Table(cache));
    root.insert("pairs".into(), Value::Table(pairs));
    root.insert("map".into(), Value::Table(map));
    let body = toml::to_string(&root).map_err(|e| RadioError::Import {
        message: format!("writing the configuration: {e}"),
    })?;
    Ok(format!(
        "# Scenario {:?}, made by `dupac scenario import` (docs/scenario.md).\n\
         # Paths are relative to the directory dupac runs in, as every path of a configuration:\n\
         # run it where the import ran, e.g. `dupac map --config {}`.\n\n{body}",
        plan.name,
        plan.out.join("config.toml").display()
    ))
}
