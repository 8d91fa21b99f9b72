//! `dupac plan`: the shortest flyable path and the coverage-aware path of one pair, flown by the
//! scripted pilot through the environment with A3 association; table, PNG and CSVs.

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use dupac_actor::env::{Env, Episode, PathGuide};
use dupac_actor::pairs::{Pair, Split, read_pairs_jsonl};
use dupac_actor::planner::Planner;
use dupac_common::config::Association;
use dupac_common::fsio::write_plain;
use dupac_common::geometry::{Point, distance_m as dist};
use dupac_eval::flight::{flight_record, fly_path};
use dupac_eval::pair_flights::{best_rsrp_at, slug, summary_md};
use dupac_eval::records::write_steps_csv;
use dupac_plot::plan::{render_world_plan, trace_of};
use dupac_radio::cache::RsrpCache;
use dupac_radio::class::RsrpThresholds;
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use dupac_scenario::pairs::held_out_unguided;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

#[derive(Args, Debug)]
pub struct PlanArgs {
    /// Source `x,y,z` (m, local frame).
    #[arg(
        long,
        value_name = "X,Y,Z",
        requires = "to",
        allow_hyphen_values = true
    )]
    pub from: Option<String>,
    /// Destination `x,y,z` (m).
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub to: Option<String>,
    /// A pairs file (JSON Lines, e.g. from `dupac pairs`); with `--pair`.
    #[arg(long, value_name = "FILE", conflicts_with = "from")]
    pub pairs: Option<PathBuf>,
    /// The pair to plan: its line in `--pairs` (default: this city's validation split,
    /// `pairs.eval_file`, drawn when missing), counted from 0 (blank lines skipped).
    #[arg(long, value_name = "N", conflicts_with = "from")]
    pub pair: Option<usize>,
    /// λ values of the coverage-aware planner (repeatable; default `planner.lambda`).
    #[arg(long = "lambda")]
    pub lambdas: Vec<f64>,
    /// Output directory.
    #[arg(long, default_value = "out/plan")]
    pub out: PathBuf,
}

fn parse_xyz(s: &str, what: &str) -> Result<Point> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--{what} {s:?}: expected X,Y,Z in metres"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Point::new(*x, *y, *z)),
        _ => bail!("--{what} {s:?}: expected three finite numbers X,Y,Z"),
    }
}

pub fn run(global: &GlobalArgs, args: &PlanArgs) -> Result<ExitCode> {
    let mut cfg = global.config()?;
    cfg.env.association = Association::A3;
    // The arguments before the world is built.
    if let Some(file) = &args.pairs {
        crate::io::check_pair_index(file, args.pair.unwrap_or(0), None)?;
    }
    for l in &args.lambdas {
        if !(l.is_finite() && *l >= 0.0) {
            bail!("--lambda {l}: must be a finite number >= 0");
        }
    }
    let world = Arc::new(RadioWorld::build(&cfg).context("building the radio world")?);
    let mut planner = Planner::new(&world.city, &cfg.env, &cfg.planner);

    let (source, destination) = match (&args.from, &args.to, &args.pairs) {
        (Some(f), Some(t), None) => (parse_xyz(f, "from")?, parse_xyz(t, "to")?),
        (None, None, file) if file.is_some() || args.pair.is_some() => {
            let (name, pairs) = match file {
                Some(file) => (
                    file.display().to_string(),
                    read_pairs_jsonl(file, &planner, &cfg.pairs)?,
                ),
                None => (
                    Split::Validation
                        .file(&cfg.pairs, planner.city())
                        .display()
                        .to_string(),
                    held_out_unguided(&cfg, &planner, global.no_progress())?,
                ),
            };
            let k = args.pair.unwrap_or(0);
            let p = pairs.get(k).ok_or_else(|| {
                anyhow!("{name}: --pair {k} but the file has {} pairs", pairs.len())
            })?;
            (p.source_m, p.destination_m)
        }
        _ => bail!(
            "give --from X,Y,Z --to X,Y,Z, --pair N (the validation split) or --pairs FILE [--pair N]"
        ),
    };
    let shortest = planner
        .shortest(source, destination)
        .context("planning the shortest flyable path")?;
    // The radio map only after the endpoints are known to be good (it may take a while).
    let grid_rows = dupac_radio::cache::GridSpec::covering(world.city.area_m, &cfg.cache).ny;
    let pb = dupac_scenario::progress::progress_bar(
        grid_rows as u64,
        "RSRP cache",
        global.no_progress(),
    );
    let (cache, _) = RsrpCache::open_or_build(&world, &cfg.cache, &|n| pb.inc(n))?;
    pb.finish_and_clear();
    let cache: Arc<dyn RsrpSource + Send + Sync> = Arc::new(cache);
    let thresholds = RsrpThresholds::from_config(&cfg.radio);
    planner.with_coverage(cache.as_ref(), thresholds);
    let straight = dist(source, destination);
    // Planned endpoints fly in the validation's realisations, as `dupac fly` flies a pair: as
    // episode 0 of the field of pair 0.
    let field = dupac_radio::channel::FieldSplit::Eval;
    let episode = Episode {
        source_m: source,
        destination_m: destination,
        field,
        shortest_m: shortest.length_m,
        guide: PathGuide::new(&shortest.waypoints_m).map(Arc::new),
    };
    let pair = Pair {
        id: 0,
        source_m: source,
        destination_m: destination,
        shortest_m: shortest.length_m,
        straight_m: straight,
        bin_m: None,
        path: None,
        path_lambda: 0.0,
        path_clearance_m: 0.0,
    };
    let lambdas = if args.lambdas.is_empty() {
        vec![cfg.planner.lambda]
    } else {
        args.lambdas.clone()
    };
    let mut plans = vec![("shortest".to_string(), shortest)];
    for l in lambdas {
        let p = planner
            .coverage_aware(source, destination, l)
            .with_context(|| format!("planning the coverage-aware path (λ = {l})"))?;
        plans.push((format!("coverage-aware λ={l}"), p));
    }

    let mut env = Env::new(&cfg, world.clone(), cache.clone())?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let mut traces = Vec::new();
    let mut flown = Vec::new();
    let start_rsrp = best_rsrp_at(cache.as_ref(), &world, source);
    for (label, plan) in &plans {
        let f = fly_path(&mut env, pair.id, episode.clone(), &plan.waypoints_m)?;
        let steps = (f.start_serving, f.flight.steps.as_slice());
        let record = flight_record(&world, &cache, field, label, 0, &pair, steps);
        let file = format!("flight_{}.csv", slug(label));
        write_steps_csv(&args.out.join(&file), label, 0, &[record])?;
        traces.push(trace_of(
            format!("{label} (A3)"),
            source,
            start_rsrp,
            thresholds,
            &f.flight.steps,
        ));
        flown.push((label.as_str(), plan.length_m, f.summary));
    }
    let title = format!(
        "{}: ({:.0}, {:.0}, {:.0}) → ({:.0}, {:.0}, {:.0}) m, straight {:.0} m, shortest {:.0} m",
        world.city.name,
        source[0],
        source[1],
        source[2],
        destination[0],
        destination[1],
        destination[2],
        straight,
        episode.shortest_m
    );
    render_world_plan(
        &world,
        &cfg.radio,
        &traces,
        &title,
        &args.out.join("plan.png"),
    )?;
    let rows: Vec<_> = flown.iter().map(|(l, m, s)| (*l, Some(*m), s)).collect();
    let md = summary_md(
        &title,
        &rows,
        "Every path is flown by the scripted pilot through the environment with A3 association.",
    );
    write_plain(&args.out.join("summary.md"), md.as_bytes())?;
    print!("{md}");
    eprintln!("wrote {}", args.out.display());
    Ok(ExitCode::SUCCESS)
}
