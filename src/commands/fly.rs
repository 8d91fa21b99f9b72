//! `dupac fly`: flies one pair with an exported policy (or a checkpoint) deterministically (mean
//! move, arg-max site) and plots it like `dupac plan`, beside the shortest flyable path flown
//! with A3.

use crate::GlobalArgs;
use crate::commands::plan::{env_rsrp_at, trace_of, write_steps_csv};
use crate::commands::train::world_and_cache;
use crate::io::write_atomic;
use crate::plan_plot::render_plan_png;
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use dupac_actor::env::{Env, Episode, StepInfo};
use dupac_actor::pairs::read_pairs_jsonl;
use dupac_actor::pilot::fly_waypoints;
use dupac_actor::planner::Planner;
use dupac_actor::rollout::{EpisodeAccumulator, fly_policy};
use dupac_common::config::Association;
use dupac_learner::checkpoint::load_policy;
use dupac_radio::class::RsrpThresholds;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct FlyArgs {
    /// Exported policy (`policy.bin`) or checkpoint (`checkpoint.bin`) of `dupac train`.
    #[arg(long, value_name = "FILE")]
    pub policy: PathBuf,
    /// A pairs file (default `pairs.eval_file`).
    #[arg(long, value_name = "FILE")]
    pub pairs: Option<PathBuf>,
    /// Line of the pair in the pairs file (0-based).
    #[arg(long, default_value_t = 0)]
    pub pair: usize,
    /// Output directory.
    #[arg(long, default_value = "out/fly")]
    pub out: PathBuf,
}

pub fn run(global: &GlobalArgs, args: &FlyArgs) -> Result<ExitCode> {
    let mut cfg = global.config()?;
    let policy = load_policy(&args.policy)?;
    let learned = policy.n_sites > 0;
    cfg.env.association = if learned {
        Association::Learned
    } else {
        Association::A3
    };
    let (world, rsrp) = world_and_cache(&cfg, global.quiet)?;
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let file = args
        .pairs
        .clone()
        .unwrap_or_else(|| cfg.pairs.eval_file.clone());
    let pairs = read_pairs_jsonl(&file, &planner, &cfg.pairs).with_context(|| {
        format!(
            "reading pairs {} (make them with `dupac pairs`)",
            file.display()
        )
    })?;
    let p = pairs.get(args.pair).ok_or_else(|| {
        anyhow!(
            "{}: --pair {} but the file has {} pairs",
            file.display(),
            args.pair,
            pairs.len()
        )
    })?;
    let episode = Episode {
        source_m: p.source_m,
        destination_m: p.destination_m,
        shortest_m: p.shortest_m,
    };
    let mut env = Env::new(&cfg, world.clone(), rsrp.clone())?;
    if env.layout().len() != policy.obs_dim {
        bail!(
            "{}: the policy expects {} observations, this configuration gives {}",
            args.policy.display(),
            policy.obs_dim,
            env.layout().len()
        );
    }
    let (summary, steps) = fly_policy(&mut env, &policy, p.id, episode, p.id)?;

    // The shortest flyable path flown with A3, for comparison.
    let mut a3_cfg = cfg.clone();
    a3_cfg.env.association = Association::A3;
    let mut a3_env = Env::new(&a3_cfg, world.clone(), rsrp.clone())?;
    let shortest = planner.shortest(p.source_m, p.destination_m)?;
    let base = fly_waypoints(&mut a3_env, p.id, episode, &shortest.waypoints_m, |e| {
        e.serving()
    })?;
    let mut acc = EpisodeAccumulator::default();
    base.steps.iter().for_each(|s| acc.push(s));
    let base_summary = acc.finish(p.id, p.shortest_m, base.outcome);

    let thresholds = RsrpThresholds::from_config(&cfg.radio);
    let r0 = env_rsrp_at(rsrp.as_ref(), &world, p.source_m);
    let trace =
        |label: String, steps: &[StepInfo]| trace_of(label, p.source_m, r0, thresholds, steps);
    let method = if learned {
        "policy (learned site)"
    } else {
        "policy (A3)"
    };
    let traces = vec![
        trace(format!("{method} v{}", policy.version), &steps),
        trace("shortest path (A3)".into(), &base.steps),
    ];
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let title = format!(
        "{}: pair {} ({:.0} m shortest), {} → {:?}",
        world.city.name, p.id, p.shortest_m, method, summary.outcome
    );
    render_plan_png(
        &world.city.buildings,
        &world.sites,
        world.city.area_m,
        &traces,
        &title,
        &args.out.join("fly.png"),
    )?;
    write_steps_csv(&args.out.join("steps.csv"), &steps)?;
    let mut md = String::new();
    let _ = writeln!(md, "{title}\n");
    let _ = writeln!(
        md,
        "| flight | outcome | flown (m) | overhead (%) | mean RSRP (dBm) | excellent (%) | mediocre (%) | poor (%) | handovers | return |"
    );
    let _ = writeln!(md, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (label, s) in [(method, &summary), ("shortest path (A3)", &base_summary)] {
        let _ = writeln!(
            md,
            "| {label} | {:?} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.1} |",
            s.outcome,
            s.distance_flown_m,
            100.0 * s.overhead(),
            s.mean_rsrp_dbm,
            100.0 * s.frac_excellent,
            100.0 * s.frac_mediocre,
            100.0 * s.frac_poor,
            s.handovers,
            s.episodic_return
        );
    }
    write_atomic(&args.out.join("summary.md"), md.as_bytes())?;
    print!("{md}");
    eprintln!("wrote {}", args.out.display());
    Ok(ExitCode::SUCCESS)
}
