//! `dupac scenario import`: another city from raw OpenStreetMap buildings and OpenCelliD cells
//! (docs/scenario.md): a scenario directory and the configuration `--config` takes.

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use dupac_common::config::LonLatBox;
use dupac_radio::import::opencellid::CellRules;
use dupac_radio::import::osm::OsmRules;
use dupac_radio::import::scenario::{ImportPlan, import_scenario};
use dupac_radio::import::tags::{DEFAULT_LEVEL_HEIGHT_M, HeightRules};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum ScenarioCommand {
    /// Import raw OSM buildings (PBF, XML, Overpass JSON, GeoJSON) and OpenCelliD cells (CSV) in a
    /// lon/lat box into a scenario directory: `buildings.geojson`, `cells.csv`, `config.toml` (use
    /// it with `--config`). The rules (heights, parts, selection, sites): docs/scenario.md.
    Import(ImportArgs),
}

#[derive(Args, Debug)]
#[command(next_help_heading = "Import")]
pub struct ImportArgs {
    /// Raw OSM buildings: `.osm.pbf`, `.osm` XML, Overpass JSON or GeoJSON (told by content).
    #[arg(long, value_name = "FILE")]
    pub buildings: PathBuf,
    /// OpenCelliD cells: CSV in its columns (radio,mcc,net,area,cell,unit,lon,lat,range,…), with
    /// or without the header line, or gzip-compressed (e.g. `.csv.gz`).
    #[arg(long, value_name = "FILE")]
    pub cells: PathBuf,
    /// The flight area, `LON_MIN,LAT_MIN,LON_MAX,LAT_MAX` (WGS84 degrees, west,south,east,north).
    #[arg(long = "box", value_name = "W,S,E,N", value_parser = lon_lat_box, allow_hyphen_values = true)]
    pub area: LonLatBox,
    /// The scenario directory (its files are named through it in `config.toml`, relative to the
    /// working directory like every path of a configuration).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// `scenario.name` (default: the directory's name).
    #[arg(long)]
    pub name: Option<String>,
    /// Overwrite a scenario directory that already has a `config.toml`.
    #[arg(long)]
    pub force: bool,
    /// Keep buildings and cells in this box instead of the flight area widened by `--margin-m`.
    #[arg(long, value_name = "W,S,E,N", value_parser = lon_lat_box, allow_hyphen_values = true, help_heading = "Selection")]
    pub select: Option<LonLatBox>,
    /// Widen the flight area by this much for the selection (m): buildings and sites just
    /// outside it still block and serve (the city loader keeps buildings within 300 m).
    #[arg(
        long,
        default_value_t = 300.0,
        value_name = "M",
        help_heading = "Selection"
    )]
    pub margin_m: f64,
    /// Metres per storey for `building:levels`, `roof:levels`, `building:min_level`.
    #[arg(long, default_value_t = DEFAULT_LEVEL_HEIGHT_M, value_name = "M", help_heading = "Heights")]
    pub level_height_m: f64,
    /// A building without height or levels: the 75th percentile of tagged buildings within
    /// this radius (m; 0: off, else ≥ 1) …
    #[arg(
        long,
        default_value_t = 150.0,
        value_name = "M",
        help_heading = "Heights"
    )]
    pub nearby_m: f64,
    /// … else this height (m).
    #[arg(
        long,
        default_value_t = 10.0,
        value_name = "M",
        help_heading = "Heights"
    )]
    pub default_height_m: f64,
    /// The cells' radio kept (LTE: eNodeB = cell >> 8; another radio: one site per cell).
    #[arg(long, default_value = "LTE", help_heading = "Cells")]
    pub radio: String,
    /// The `source` column written into `cells.csv`.
    #[arg(long, default_value = "opencellid", help_heading = "Cells")]
    pub source: String,
    /// A tag value that is not a height, or a cell id not of its radio, is an error (default:
    /// a warning, and the value or row is ignored and counted).
    #[arg(long)]
    pub strict: bool,
}

/// `W,S,E,N` in degrees.
fn lon_lat_box(s: &str) -> Result<LonLatBox, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|e| format!("{x:?}: {e}")))
        .collect::<Result<_, _>>()?;
    let [w, south, e, n] = v[..] else {
        return Err(format!("expected 4 numbers W,S,E,N, got {}", v.len()));
    };
    if !(w < e && south < n) {
        return Err("expected west < east and south < north".into());
    }
    Ok(LonLatBox {
        lon_min_deg: w,
        lon_max_deg: e,
        lat_min_deg: south,
        lat_max_deg: n,
    })
}

pub fn run(global: &GlobalArgs, cmd: &ScenarioCommand) -> Result<ExitCode> {
    let ScenarioCommand::Import(a) = cmd;
    if global.config.is_some() || !global.set.is_empty() {
        anyhow::bail!(
            "scenario import writes a configuration; --config and --set apply to the commands \
             that use it (`dupac map --config {}`)",
            a.out.join("config.toml").display()
        );
    }
    crate::io::check_readable("--buildings", &a.buildings)?;
    crate::io::check_readable("--cells", &a.cells)?;
    let name = match &a.name {
        Some(n) => n.clone(),
        None => a
            .out
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .context("--out has no directory name: give --name")?,
    };
    let plan = ImportPlan {
        buildings: a.buildings.clone(),
        cells: a.cells.clone(),
        area: a.area,
        select: a.select,
        margin_m: a.margin_m,
        out: a.out.clone(),
        name,
        osm: OsmRules {
            heights: HeightRules {
                level_height_m: a.level_height_m,
            },
            nearby_m: a.nearby_m,
            default_height_m: a.default_height_m,
            strict: a.strict,
        },
        cells_rules: CellRules {
            radio: a.radio.clone(),
            source: a.source.clone(),
            strict: a.strict,
        },
        force: a.force,
    };
    let t = Instant::now();
    let s = import_scenario(&plan)?;
    let imported_s = t.elapsed().as_secs_f64();
    let world = &s.world;
    let (b, c, x) = (&s.buildings, &s.cells, s.select);
    let (w, south, e, n) = (x.lon_min_deg, x.lat_min_deg, x.lon_max_deg, x.lat_max_deg);
    println!("selection box {w:.6},{south:.6},{e:.6},{n:.6}");
    println!(
        "buildings: {} features read ({} OSM buildings incomplete, no area); kept {} outlines \
         ({} with parts), {} parts, {} parts without an outline; skipped {} not buildings, {} \
         underground, {} not areas, {} degenerate, {} outside; {} polygons dropped, {} tag \
         values ignored, {} bottoms dropped",
        b.features,
        b.incomplete,
        b.outlines,
        b.outlines_with_parts,
        b.parts,
        b.orphan_parts,
        b.not_building,
        b.underground,
        b.not_area,
        b.degenerate,
        b.outside,
        b.degenerate_polygons,
        b.bad_tags,
        b.min_height_dropped
    );
    for (source, n) in &b.height_sources {
        println!("  height_source {source}: {n}");
    }
    println!(
        "cells: {} rows read; kept {} ({} sites); skipped {} of another radio, {} outside, {} \
         invalid cell ids",
        c.rows, c.kept, c.sites, c.other_radio, c.outside, c.invalid_cell
    );
    println!(
        "loaded: {} buildings, {} sites (scenario.n_sites = {}); imported in {imported_s:.2} s",
        world.city.buildings.len(),
        world.num_sites(),
        s.config.scenario.n_sites
    );
    println!(
        "wrote {} — e.g. `dupac map --config {}`",
        s.config_path.display(),
        s.config_path.display()
    );
    Ok(ExitCode::SUCCESS)
}
