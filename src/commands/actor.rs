//! `dupac actor`: one actor process of a Zenoh run: simulates UAV episodes with the
//! newest weights and publishes trajectory chunks to the learner.

use super::net::{ConnectArgs, stop_flag};
use crate::global_args::GlobalArgs;
use anyhow::{Context, Result};
use clap::Args;
use dupac_actor::pairs::read_pairs_jsonl;
use dupac_common::ids::ActorId;
use dupac_node::actor::{ActorOptions, run_actor};
use dupac_scenario::pairs::{guide_pairs_cached, pool_cached};
use dupac_scenario::world::world_and_cache;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

#[derive(Args, Debug)]
pub struct ActorArgs {
    /// This actor's id within the run (unique per run; default: from the process id).
    #[arg(long)]
    pub id: Option<u32>,
    /// Threads stepping the environments (default: one per `distributed.actor_envs`, at most
    /// the cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Stop after this many chunks (default: until the learner ends the run).
    #[arg(long, default_value_t = 0)]
    pub max_chunks: u64,
    /// Training pairs file (JSON Lines, as `dupac train` writes `train_pool.jsonl`); default:
    /// drawn from `train.seed` like the learner's pool.
    #[arg(long, value_name = "FILE")]
    pub pool: Option<PathBuf>,
    /// `learned` (DUPAC) or `a3` (base method); must match the learner's.
    #[arg(long, value_enum)]
    pub association: Option<super::run_args::AssociationArg>,
    /// Write the trajectories of the chunks sent to FILE when the actor stops (with
    /// `--max-chunks`): a recording for `--replay`.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Send the chunks of a `--record` file in turn instead of stepping environments: an actor
    /// of unbounded speed, for the learner's scaling bench (`benches/learner_scaling.sh`).
    #[arg(long, value_name = "FILE", conflicts_with = "record")]
    pub replay: Option<PathBuf>,
    #[command(flatten)]
    pub net: ConnectArgs,
}

pub fn run(global: &GlobalArgs, args: &ActorArgs) -> Result<ExitCode> {
    let stop = stop_flag()?;
    let cfg = super::run_args::resolve_config(global, args.association, None)?;
    // The files named by arguments before the world is built.
    for (flag, file) in [("--pool", &args.pool), ("--replay", &args.replay)] {
        if let Some(f) = file {
            crate::io::check_readable(flag, f)?;
        }
    }
    let (world, rsrp) = world_and_cache(&cfg, global.no_progress())?;
    let fingerprint = cfg.env_fingerprint(world.fingerprint());
    // The pairs with a planner of their own clearance (no coverage classes); their guide paths
    // from the host's guide cache, planned only when this host has not planned them yet.
    let unguided = dupac_scenario::planners::unguided(&cfg);
    let planners = dupac_scenario::planners::Planners::new(&unguided, &[], &world, &rsrp, false);
    let mut pool = match &args.pool {
        Some(p) => read_pairs_jsonl(p, &planners.pairs, &cfg.pairs)
            .with_context(|| format!("--pool {}", p.display()))?,
        None => pool_cached(&unguided, &world, &planners, global.no_progress())?,
    };
    drop(planners);
    guide_pairs_cached(&cfg, &world, &rsrp, &mut pool, global.no_progress())?;
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let opts = ActorOptions {
        id: ActorId(args.id.unwrap_or(std::process::id())),
        threads: args
            .threads
            .unwrap_or(cfg.distributed.actor_envs.min(cores))
            .max(1),
        max_chunks: args.max_chunks,
        replay: match &args.replay {
            Some(p) => Some(Arc::new(
                dupac_node::actor::read_recording(p)
                    .with_context(|| format!("--replay {}", p.display()))?,
            )),
            None => None,
        },
        record: args.record.clone(),
    };
    // Stopped before it could join (Ctrl-C or the orchestrator's SIGTERM at the end of a run):
    // leave cleanly, with the summary line of an actor that sent nothing.
    let probe = dupac_actor::env::Env::new(&cfg, world.clone(), rsrp.clone())?;
    let (obs_dim, n_sites) = probe.policy_shape();
    drop(probe);
    let joined = args.net.open_retrying(
        &stop,
        dupac_common::msg::MsgLimits::run_max_bytes(&cfg, obs_dim, n_sites),
    );
    if stop.load(std::sync::atomic::Ordering::Relaxed) {
        println!(
            "actor {}: 0 chunks, 0 timesteps, 0 weight swaps, 0 shares re-sent; stopped before joining",
            opts.id
        );
        return Ok(ExitCode::SUCCESS);
    }
    let session = joined?;
    eprintln!(
        "actor {} of run {:?}: {} environments on {} threads, fingerprint {fingerprint:016x}",
        opts.id, cfg.distributed.run, cfg.distributed.actor_envs, opts.threads
    );
    let report = run_actor(
        session,
        &cfg,
        world,
        rsrp,
        Arc::new(pool),
        fingerprint,
        &opts,
        &stop,
    )?;
    let (first, last) = (
        report.versions.first().copied().unwrap_or(0),
        report.versions.last().copied().unwrap_or(0),
    );
    println!(
        "actor {}: {} chunks ({} stale, not sent; {:.0} bytes per decision), {} timesteps, {} weight swaps, {} shares re-sent; acted with versions {first}..={last}",
        opts.id,
        report.chunks_sent,
        report.stale_unsent,
        report.chunk_bytes as f64 / report.env_steps.max(1) as f64,
        report.env_steps,
        report.swaps,
        report.resent_shares,
    );
    Ok(ExitCode::SUCCESS)
}
