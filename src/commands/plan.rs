//! `dupac plan`: the shortest flyable path and the coverage-aware path of one pair, flown by the
//! scripted pilot through the environment with A3 association; table, PNG and CSVs.

use crate::GlobalArgs;
use crate::io::{write_atomic, write_atomic_with};
use crate::plan_plot::{FlightTrace, render_plan_png};
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use dupac_actor::env::{Env, Episode, Outcome, StepInfo};
use dupac_actor::pairs::read_pairs_jsonl;
use dupac_actor::pilot::{Flight, fly_waypoints};
use dupac_actor::planner::Planner;
use dupac_common::config::Association;
use dupac_radio::cache::{RsrpCache, RsrpSource};
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use dupac_radio::world::RadioWorld;
use std::fmt::Write as _;
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
    /// A pairs file (JSON Lines, e.g. from `dupac pairs`); with `--index`.
    #[arg(long, value_name = "FILE", conflicts_with = "from")]
    pub pairs: Option<PathBuf>,
    /// Line of the pair in `--pairs` (0-based).
    #[arg(long, default_value_t = 0)]
    pub index: usize,
    /// λ values of the coverage-aware planner (repeatable; default `planner.lambda`).
    #[arg(long = "lambda")]
    pub lambdas: Vec<f64>,
    /// Output directory.
    #[arg(long, default_value = "out/plan")]
    pub out: PathBuf,
}

fn parse_xyz(s: &str, what: &str) -> Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--{what} {s:?}: expected X,Y,Z in metres"))?;
    match v.as_slice() {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([*x, *y, *z]),
        _ => bail!("--{what} {s:?}: expected three finite numbers X,Y,Z"),
    }
}

/// Statistics of one flight (shared with evaluation later).
#[derive(Debug, Clone, serde::Serialize)]
pub struct FlightSummary {
    pub label: String,
    pub planned_m: f64,
    pub flown_m: f64,
    pub overhead_pct: f64,
    pub mean_rsrp_dbm: f64,
    pub excellent_pct: f64,
    pub mediocre_pct: f64,
    pub poor_pct: f64,
    pub handovers: usize,
    pub outcome: Outcome,
    pub steps: usize,
    pub episodic_return: f64,
}

fn summarise(label: &str, planned_m: f64, shortest_m: f64, f: &Flight) -> FlightSummary {
    let n = f.steps.len().max(1) as f64;
    let remaining = f.steps.last().map(|s| s.distance_to_goal_m).unwrap_or(0.0);
    let count = |c: RsrpClass| f.steps.iter().filter(|s| s.class == c).count() as f64;
    FlightSummary {
        label: label.to_string(),
        planned_m,
        flown_m: f.distance_m(),
        // Flown distance plus what is left to the destination (the episode ends within
        // `env.goal_radius_m`), against the shortest flyable path.
        overhead_pct: 100.0 * ((f.distance_m() + remaining) / shortest_m - 1.0),
        mean_rsrp_dbm: f.steps.iter().map(|s| s.serving_rsrp_dbm).sum::<f64>() / n,
        excellent_pct: 100.0 * count(RsrpClass::Excellent) / n,
        mediocre_pct: 100.0 * count(RsrpClass::Mediocre) / n,
        poor_pct: 100.0 * count(RsrpClass::Poor) / n,
        handovers: f.steps.iter().filter(|s| s.handover).count(),
        outcome: f.outcome,
        steps: f.steps.len(),
        episodic_return: f.episodic_return,
    }
}

pub fn run(global: &GlobalArgs, args: &PlanArgs) -> Result<ExitCode> {
    let mut cfg = global.config()?;
    cfg.env.association = Association::A3;
    let world = Arc::new(RadioWorld::build(&cfg).context("building the radio world")?);
    let mut planner = Planner::new(&world.city, &cfg.env, &cfg.planner);

    let (source, destination) = match (&args.from, &args.to, &args.pairs) {
        (Some(f), Some(t), None) => (parse_xyz(f, "from")?, parse_xyz(t, "to")?),
        (None, None, Some(file)) => {
            let pairs = read_pairs_jsonl(file, &planner, &cfg.pairs)?;
            let p = pairs.get(args.index).ok_or_else(|| {
                anyhow!(
                    "{}: --index {} but the file has {} pairs",
                    file.display(),
                    args.index,
                    pairs.len()
                )
            })?;
            (p.source_m, p.destination_m)
        }
        _ => bail!("give --from X,Y,Z --to X,Y,Z, or --pairs FILE [--index N]"),
    };
    let shortest = planner
        .shortest(source, destination)
        .context("planning the shortest flyable path")?;
    // The radio map only after the endpoints are known to be good (it may take a while).
    let grid_rows = dupac_radio::cache::GridSpec::covering(world.city.area_m, &cfg.cache).ny;
    let pb = super::progress_bar(grid_rows as u64, "RSRP cache", global.quiet);
    let (cache, _) = RsrpCache::open_or_build(&world, &cfg.cache, &|n| pb.inc(n))?;
    pb.finish_and_clear();
    let cache: Arc<dyn RsrpSource + Send + Sync> = Arc::new(cache);
    let thresholds = RsrpThresholds::from_config(&cfg.radio);
    planner.with_coverage(cache.as_ref(), thresholds);
    let straight = dist(source, destination);
    let episode = Episode {
        source_m: source,
        destination_m: destination,
        shortest_m: shortest.length_m,
    };
    let lambdas = if args.lambdas.is_empty() {
        vec![cfg.planner.lambda]
    } else {
        args.lambdas.clone()
    };
    let mut plans = vec![("shortest".to_string(), shortest)];
    for l in lambdas {
        if !(l.is_finite() && l >= 0.0) {
            bail!("--lambda {l}: must be a finite number >= 0");
        }
        let p = planner
            .coverage_aware(source, destination, l)
            .with_context(|| format!("planning the coverage-aware path (λ = {l})"))?;
        plans.push((format!("coverage-aware λ={l}"), p));
    }

    let mut env = Env::new(&cfg, world.clone(), cache.clone())?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let mut traces = Vec::new();
    let mut rows = Vec::new();
    for (label, plan) in &plans {
        let flight = fly_waypoints(&mut env, 0, episode, &plan.waypoints_m, |e| e.serving())?;
        rows.push(summarise(label, plan.length_m, episode.shortest_m, &flight));
        let start_rsrp = env_rsrp_at(cache.as_ref(), &world, source);
        let file = format!("flight_{}.csv", slug(label));
        write_steps_csv(&args.out.join(&file), &flight.steps)?;
        traces.push(trace_of(
            format!("{label} (A3)"),
            source,
            start_rsrp,
            thresholds,
            &flight.steps,
        ));
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
    render_plan_png(
        &world.city.buildings,
        &world.sites,
        world.city.area_m,
        &traces,
        &dupac_radio::class::RsrpThresholds::from_config(&cfg.radio),
        &title,
        &args.out.join("plan.png"),
    )?;
    let mut md = String::new();
    let _ = writeln!(md, "{title}\n");
    let _ = writeln!(
        md,
        "| path | planned (m) | flown (m) | overhead vs shortest (%) ¹ | mean RSRP (dBm) | excellent (%) | mediocre (%) | poor (%) | handovers | outcome | return |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|");
    for r in &rows {
        let _ = writeln!(
            md,
            "| {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:?} | {:.1} |",
            r.label,
            r.planned_m,
            r.flown_m,
            r.overhead_pct,
            r.mean_rsrp_dbm,
            r.excellent_pct,
            r.mediocre_pct,
            r.poor_pct,
            r.handovers,
            r.outcome,
            r.episodic_return
        );
    }
    let _ = writeln!(
        md,
        "\n¹ (flown + distance left to the destination when the episode ends) / shortest − 1; \
         every path is flown by the scripted pilot through the environment with A3 association."
    );
    write_atomic(&args.out.join("summary.md"), md.as_bytes())?;
    print!("{md}");
    eprintln!("wrote {}", args.out.display());
    Ok(ExitCode::SUCCESS)
}

pub fn env_rsrp_at(rsrp: &dyn RsrpSource, world: &RadioWorld, p: [f64; 3]) -> f64 {
    let mut all = vec![0.0; world.num_sites()];
    rsrp.rsrp_all_dbm(p, &mut all);
    all.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

fn slug(s: &str) -> String {
    s.replace('λ', "lambda")
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}

/// Writes one row per step record (the columns evaluation re-plots from), atomically.
pub fn write_steps_csv(path: &std::path::Path, steps: &[StepInfo]) -> Result<()> {
    write_atomic_with(path, |w| {
        let mut c = csv::Writer::from_writer(w);
        c.write_record([
            "step",
            "x_m",
            "y_m",
            "z_m",
            "serving",
            "serving_rsrp_dbm",
            "best_site",
            "best_rsrp_dbm",
            "class",
            "los",
            "handover",
            "ping_pong",
            "distance_flown_m",
            "reward",
        ])?;
        for s in steps {
            c.write_record([
                s.step.to_string(),
                format!("{:.3}", s.position_m[0]),
                format!("{:.3}", s.position_m[1]),
                format!("{:.3}", s.position_m[2]),
                s.serving.0.to_string(),
                format!("{:.3}", s.serving_rsrp_dbm),
                s.best_site.0.to_string(),
                format!("{:.3}", s.best_rsrp_dbm),
                s.class.name().to_string(),
                u8::from(s.los).to_string(),
                u8::from(s.handover).to_string(),
                u8::from(s.ping_pong).to_string(),
                format!("{:.3}", s.distance_flown_m),
                format!("{:.5}", s.reward),
            ])?;
        }
        c.flush()
    })
}

/// A plotted trace: the source (with the best RSRP there) followed by every step's position,
/// serving RSRP and class.
pub fn trace_of(
    label: String,
    source_m: [f64; 3],
    source_rsrp_dbm: f64,
    thresholds: RsrpThresholds,
    steps: &[StepInfo],
) -> FlightTrace {
    let mut t = FlightTrace {
        label,
        points_m: vec![source_m],
        serving_rsrp_dbm: vec![source_rsrp_dbm],
        class: vec![thresholds.classify(source_rsrp_dbm)],
        reached: true,
    };
    for s in steps {
        t.points_m.push(s.position_m);
        t.serving_rsrp_dbm.push(s.serving_rsrp_dbm);
        t.class.push(s.class);
    }
    t
}
