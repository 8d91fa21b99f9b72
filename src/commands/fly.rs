//! `dupac fly`: flies one pair with an exported policy (or a checkpoint) deterministically (mean
//! move, arg-max site) and plots it like `dupac plan`, beside the shortest flyable path flown
//! with A3.

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use dupac_actor::env::Env;
use dupac_actor::pairs::read_pairs_jsonl;
use dupac_actor::record::StepInfo;
use dupac_actor::rollout::fly_policy;
use dupac_common::config::Association;
use dupac_common::fsio::write_plain;
use dupac_common::msg::Outcome;
use dupac_eval::flight::{flight_record, fly_path_with_a3, policy_env};
use dupac_eval::pair_flights::{best_rsrp_at, summary_md, versions_md, write_versions_csv};
use dupac_eval::records::write_steps_csv;
use dupac_learner::checkpoint::load_policy;
use dupac_node::actor::Follower;
use dupac_node::follow::fly_following;
use dupac_plot::plan::{render_world_plan, trace_of};
use dupac_radio::class::RsrpThresholds;
use dupac_scenario::pairs::held_out_unguided;
use dupac_scenario::world::world_and_cache;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

#[derive(Args, Debug)]
pub struct FlyArgs {
    /// Exported policy (`policy.bin`) or checkpoint (`checkpoint.bin`) of `dupac train`.
    #[arg(long, value_name = "FILE", required_unless_present = "follow")]
    pub policy: Option<PathBuf>,
    /// Fly with the live weights of a running learner (`distributed.run`), swapping to each
    /// new version at a step boundary; `steps.csv` records the version used at every step.
    #[arg(long)]
    pub follow: bool,
    /// With `--follow`: `learned` (DUPAC) or `a3` (base method), as the learner trains.
    #[arg(long, value_enum, requires = "follow")]
    pub association: Option<super::run_args::AssociationArg>,
    /// With `--follow`: wall-clock pause after each decision (ms), to watch versions change.
    #[arg(long, default_value_t = 0, requires = "follow")]
    pub step_ms: u64,
    #[command(flatten)]
    pub net: super::net::ConnectArgs,
    /// A pairs file (default `pairs.eval_file`).
    #[arg(long, value_name = "FILE")]
    pub pairs: Option<PathBuf>,
    /// The pair to fly: its line in the pairs file, counted from 0 (blank lines skipped).
    #[arg(long, value_name = "N", default_value_t = 0)]
    pub pair: usize,
    /// Output directory.
    #[arg(long, default_value = "out/fly")]
    pub out: PathBuf,
}

pub fn run(global: &GlobalArgs, args: &FlyArgs) -> Result<ExitCode> {
    let mut cfg = super::run_args::resolve_config(global, args.association, None)?;
    // The arguments before the world, its cache and the guide path are built.
    if let Some(p) = &args.policy {
        crate::io::check_readable("--policy", p)?;
    }
    let pairs_file = args.pairs.as_ref().unwrap_or(&cfg.pairs.eval_file).clone();
    crate::io::check_pair_index(&pairs_file, args.pair, args.pairs.is_none().then_some(&cfg))?;
    let mut follower = None;
    let mut built = None;
    let policy = match &args.policy {
        Some(path) if !args.follow => load_policy(path)?,
        _ => {
            let (world, rsrp) = world_and_cache(&cfg, global.no_progress())?;
            built = Some((world.clone(), rsrp.clone()));
            let probe = Env::new(&cfg, world.clone(), rsrp.clone())?;
            let (obs_dim, n_sites) = probe.policy_shape();
            let stop = super::net::stop_flag()?;
            let session = args.net.open_retrying(
                &stop,
                dupac_common::msg::MsgLimits::run_max_bytes(&cfg, obs_dim, n_sites),
            )?;
            let mut f = Follower::new(
                session,
                &cfg,
                cfg.env_fingerprint(world.fingerprint()),
                obs_dim,
                n_sites,
            )?;
            let p = f.initial(Duration::from_secs(30))?.ok_or_else(|| {
                anyhow!(
                    "--follow: no learner of run {:?} answered within 30 s",
                    cfg.distributed.run
                )
            })?;
            eprintln!(
                "following run {:?} from version {}",
                cfg.distributed.run, p.version
            );
            follower = Some(f);
            p
        }
    };
    let learned = policy.n_sites > 0;
    cfg.env.association = if learned {
        Association::Learned
    } else if cfg.env.association == Association::Predictive {
        Association::Predictive
    } else {
        Association::A3
    };
    let policy_name = args.policy.as_ref().map_or_else(
        || "the followed weights".to_string(),
        |p| p.display().to_string(),
    );
    // Fly the policy with the observation it was trained on (every policy records it).
    let cfg = policy
        .configure(&cfg)
        .map_err(|e| anyhow!("{policy_name}: {e}"))?;
    // The radio world does not depend on the association: one build serves both paths.
    let (world, rsrp) = match built {
        Some(wr) => wr,
        None => world_and_cache(&cfg, global.no_progress())?,
    };
    let planners = dupac_scenario::planners::Planners::new(&cfg, &[], &world, &rsrp, false);
    let mut pairs = match &args.pairs {
        Some(file) => read_pairs_jsonl(file, &planners.pairs, &cfg.pairs)?,
        None => held_out_unguided(&cfg, &planners.pairs, global.no_progress())?,
    };
    if args.pair >= pairs.len() {
        bail!(
            "{}: --pair {} but the file has {} pairs",
            pairs_file.display(),
            args.pair,
            pairs.len()
        );
    }
    // Only the flown pair needs its guide path.
    let mut chosen = [pairs.swap_remove(args.pair)];
    dupac_scenario::pairs::guide_pairs(&cfg, &planners, &mut chosen)?;
    let p = &chosen[0];
    // Held-out pairs and the user's own fly in the validation's realisations (docs/env.md).
    let field = dupac_radio::channel::FieldSplit::Eval;
    let episode = p.episode(false, field);
    let mut env = policy_env(&cfg, &world, &rsrp, &policy).with_context(|| policy_name.clone())?;
    let (summary, steps, versions) = match &mut follower {
        None => {
            let (summary, steps) = fly_policy(&mut env, &policy, p.id, episode, p.id)?;
            let versions = vec![policy.version; steps.len()];
            (summary, steps, versions)
        }
        Some(f) => fly_following(&mut env, policy.clone(), f, p.id, episode, args.step_ms)?,
    };

    // The shortest flyable path flown with A3, for comparison.
    let shortest_path = planners.pairs.shortest(p.source_m, p.destination_m)?;
    let base = fly_path_with_a3(&cfg, &world, &rsrp, &shortest_path.waypoints_m, p, field)?;

    let thresholds = RsrpThresholds::from_config(&cfg.radio);
    let r0 = best_rsrp_at(rsrp.as_ref(), &world, p.source_m);
    let trace =
        |label: String, steps: &[StepInfo]| trace_of(label, p.source_m, r0, thresholds, steps);
    let method = if learned {
        "policy (learned site)"
    } else {
        "policy (A3)"
    };
    let mut flown = trace(format!("{method} v{}", policy.version), &steps);
    flown.reached = summary.outcome == Outcome::Goal;
    let mut shortest = trace("shortest path (A3)".into(), &base.flight.steps);
    shortest.reached = base.flight.outcome == Outcome::Goal;
    let traces = vec![flown, shortest];
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let title = format!(
        "{}: pair {} ({:.0} m shortest), {} → {:?}",
        world.city.name, p.id, p.shortest_m, method, summary.outcome
    );
    render_world_plan(
        &world,
        &cfg.radio,
        &traces,
        &title,
        &args.out.join("fly.png"),
    )?;
    let record = flight_record(
        &world,
        &rsrp,
        field,
        "policy",
        0,
        p,
        (env.start_serving(), &steps),
    );
    write_steps_csv(&args.out.join("steps.csv"), "policy", 0, &[record])?;
    write_versions_csv(&args.out.join("versions.csv"), &steps, &versions)?;
    let mut md = summary_md(
        &title,
        &[
            (method, None, &summary),
            (
                "shortest path (A3)",
                Some(shortest_path.length_m),
                &base.summary,
            ),
        ],
        "The policy flies deterministically (mean move, arg-max site); the shortest path is \
         flown by the scripted pilot with A3 association.",
    );
    if follower.is_some() {
        md.push_str(&versions_md(&versions));
    }
    write_plain(&args.out.join("summary.md"), md.as_bytes())?;
    print!("{md}");
    eprintln!("wrote {}", args.out.display());
    Ok(ExitCode::SUCCESS)
}
