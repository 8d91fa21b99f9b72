//! `dupac map`: best-server coverage maps on horizontal slices (paper Fig. 2(b)).

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result};
use clap::Args;
use dupac_common::fsio::{write_atomic_with, write_plain};
use dupac_radio::channel::FieldSplit;
use dupac_radio::coverage::{Server, SliceSummary, compute_slice, summarise, write_slice_csv};
use dupac_radio::world::RadioWorld;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct MapArgs {
    /// Output directory (default: `map.out_dir` of the configuration, `out/map`).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Map one site's RSRP instead of the best server (its shadows and antenna-null rings).
    #[arg(long, value_name = "ID")]
    pub site: Option<u16>,
    /// Under `radio.channel.model = "real"`: the shadow-fading realisation shown (validation
    /// field K mod `radio.channel.eval_fields`, as evaluation flies pair K in).
    #[arg(long, value_name = "K", default_value_t = 0)]
    pub field: u64,
}

pub fn run(global: &GlobalArgs, args: &MapArgs) -> Result<ExitCode> {
    let cfg = global.config()?;
    let out = args.out.clone().unwrap_or_else(|| cfg.map.out_dir.clone());
    let t0 = Instant::now();
    let world = RadioWorld::build(&cfg).context("building the radio world")?;
    eprintln!(
        "{}: {} buildings ({} triangles), {} sites ({} macro), built in {:.1} s",
        world.city.name,
        world.city.buildings.len(),
        world.city.mesh.num_triangles(),
        world.num_sites(),
        world
            .sites
            .iter()
            .filter(|s| s.kind == dupac_radio::sites::SiteKind::Macro)
            .count(),
        t0.elapsed().as_secs_f64()
    );
    let server = match args.site {
        None => Server::Best,
        Some(id) if usize::from(id) < world.num_sites() => {
            Server::Site(dupac_common::ids::SiteId(id))
        }
        Some(id) => anyhow::bail!(
            "--site {id}: the scenario has sites 0..{}",
            world.num_sites() - 1
        ),
    };
    let what = match server {
        Server::Best => "best-server RSRP".to_string(),
        Server::Site(id) => format!("RSRP of site {}", id.0),
    };
    // Under the real channel the map shows one realisation: validation field `--field`.
    let shadow = world
        .channel
        .as_ref()
        .map(|c| c.field(FieldSplit::Eval, args.field));
    let what = match &shadow {
        Some(_) => format!("{what}, shadowed (validation field {})", args.field),
        None => what,
    };
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    write_plain(&out.join("config.toml"), cfg.to_toml_string().as_bytes())?;
    write_atomic_with(&out.join("sites.csv"), |w| {
        dupac_radio::link_calc::write_sites_csv(&world, w)
    })?;

    let mut summaries: Vec<SliceSummary> = Vec::new();
    for &alt in &cfg.map.altitudes_m {
        let t = Instant::now();
        let ny = ((world.city.area_m.max_m.y - world.city.area_m.min_m.y) / cfg.map.resolution_m)
            .floor()
            .max(1.0) as u64;
        let pb = dupac_scenario::progress::progress_bar(
            ny,
            &format!("map at {alt} m"),
            global.no_progress(),
        );
        let slice = compute_slice(
            &world,
            server,
            shadow.as_deref(),
            world.city.area_m,
            alt,
            cfg.map.resolution_m,
            &|n| pb.inc(n),
        );
        pb.finish_and_clear();
        let stem = format!("rsrp_{}m", fmt_alt(alt));
        write_atomic_with(&out.join(format!("{stem}.csv")), |w| {
            write_slice_csv(&slice, w)
        })?;
        let title = format!(
            "{}: {what} at {} m ({} m grid, {} sites)",
            world.city.name,
            fmt_alt(alt),
            cfg.map.resolution_m,
            world.num_sites()
        );
        dupac_plot::coverage::render_coverage_png(
            &slice,
            &world.city.buildings,
            &world.sites,
            world.city.area_m,
            &dupac_radio::class::RsrpThresholds::from_config(&cfg.radio),
            &title,
            &out.join(format!("{stem}.png")),
        )?;
        let s = summarise(&world, &slice);
        eprintln!(
            "  {alt:>6.1} m: {} x {} cells in {:.1} s",
            slice.nx,
            slice.ny,
            t.elapsed().as_secs_f64()
        );
        summaries.push(s);
    }
    let md = summary_markdown(&world, &summaries);
    write_plain(&out.join("summary.md"), md.as_bytes())?;
    write_atomic_with(&out.join("summary.csv"), |w| {
        let mut c = csv::Writer::from_writer(w);
        for s in &summaries {
            c.serialize(s).map_err(std::io::Error::other)?;
        }
        c.flush()
    })?;
    print!("{md}");
    eprintln!(
        "wrote {} ({:.1} s in all)",
        out.display(),
        t0.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}

fn fmt_alt(alt: f64) -> String {
    if alt.fract() == 0.0 {
        format!("{alt:.0}")
    } else {
        format!("{alt}")
    }
}

/// The summary table of every slice, as Markdown.
pub fn summary_markdown(world: &RadioWorld, rows: &[SliceSummary]) -> String {
    let t = &world.link.thresholds;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| altitude (m) | cells | mean RSRP (dBm) | median (dBm) | p10 (dBm) | p90 (dBm) | excellent ≥ {} (%) | mediocre (%) | poor < {} (%) | best server NLoS (%) | inside buildings (%) |",
        t.excellent_dbm, t.poor_dbm
    );
    let _ = writeln!(
        s,
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} |",
            fmt_alt(r.altitude_m),
            r.cells,
            r.mean_rsrp_dbm,
            r.median_rsrp_dbm,
            r.p10_rsrp_dbm,
            r.p90_rsrp_dbm,
            r.excellent_pct,
            r.mediocre_pct,
            r.poor_pct,
            r.nlos_pct,
            r.inside_buildings_pct
        );
    }
    s
}
