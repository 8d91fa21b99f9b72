//! `dupac learner`: the central PPO learner of a Zenoh run (issue 5). Receives trajectory
//! chunks from any number of actors, updates, publishes weights, serves the latest by query,
//! writes the run directory like `dupac train --single-process`, and stops cleanly on Ctrl-C
//! (checkpoint written).

use super::net::{ConnectArgs, stop_flag};
use super::train::{
    RunArgs, RunOutput, checkpoint_to_resume, device, eval_due, held_out_pairs, method_name,
    progress_message, resolve_config, spread, summary_line, world_and_cache,
};
use crate::GlobalArgs;
use anyhow::Result;
use clap::Args;
use dupac_actor::env::Env;
use dupac_actor::planner::Planner;
use dupac_common::msg::DropReason;
use dupac_learner::dist::{LearnerNode, new_incarnation};
use dupac_learner::train::{
    Learner, Segment, Timings, domain_stats, evaluate, policy_shape, put_domain,
};
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct LearnerArgs {
    /// `--resume` continues the version counter too, so actors' data is not judged stale.
    #[command(flatten)]
    pub run: RunArgs,
    #[command(flatten)]
    pub net: ConnectArgs,
}

pub fn run(global: &GlobalArgs, args: &LearnerArgs) -> Result<ExitCode> {
    let stop = stop_flag()?;
    let run = &args.run;
    let cfg = resolve_config(global, run.association, run.out.as_ref())?;
    let checkpoint = checkpoint_to_resume(&cfg, run.resume, run.checkpoint.as_ref())?;
    let device = device(run.device)?;
    let (world, rsrp) = world_and_cache(&cfg, global.quiet)?;
    let fingerprint = cfg.env_fingerprint(world.fingerprint());
    let probe = Env::new(&cfg, world.clone(), rsrp.clone())?;
    let (obs_dim, n_sites) = policy_shape(&cfg, &probe);
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let eval_set = spread(
        &held_out_pairs(&cfg, &planner, global.quiet)?,
        cfg.train.eval_pairs,
    );

    let mut learner = Learner::new(cfg.clone(), obs_dim, n_sites, &device);
    if let Some(ck) = &checkpoint {
        learner.restore(&device, ck)?;
        eprintln!(
            "resuming at update {} ({} timesteps)",
            ck.meta.update, ck.meta.global_step
        );
    }
    let method = method_name(&cfg);
    let mut out = RunOutput::open(
        &cfg,
        learner.update,
        format!(
            "{method}, seed {}: {} (distributed)",
            cfg.train.seed, world.city.name
        ),
    )?;
    let session = args.net.open_retrying(
        &stop,
        dupac_common::msg::MsgLimits::run_max_bytes(&cfg, obs_dim, n_sites),
    )?;
    let incarnation = new_incarnation();
    let mut node = LearnerNode::start(session, &cfg, obs_dim, n_sites, fingerprint, incarnation)?;
    node.publish_weights(&learner.policy())?;
    eprintln!(
        "learner {incarnation:016x} of run {:?}: {method}, version {}, {} updates × {} samples, fingerprint {fingerprint:016x}",
        cfg.distributed.run,
        learner.update,
        learner.num_updates(),
        learner.batch_size()
    );
    let total = learner.num_updates() * learner.batch_size() as u64;
    let pb = super::progress_bar(total, "timesteps", global.quiet);
    pb.set_position(learner.global_step);

    let mut last_row = Default::default();
    while !learner.done() {
        let policy = learner.policy();
        let batch = node.next_batch(policy.version, learner.batch_size(), &stop, &mut |node| {
            let _ = node.publish_stats(
                learner.update,
                learner.num_updates(),
                learner.global_step,
                &last_row,
                false,
            );
        });
        let Some(batch) = batch else { break };
        let segments: Vec<Segment<'_>> = batch
            .chunks
            .iter()
            .flat_map(|c| {
                c.trajectories.iter().map(|traj| Segment {
                    actor: c.header.actor,
                    behaviour_version: c.header.policy_version,
                    traj,
                })
            })
            .collect();
        let t_ppo = Instant::now();
        let report = learner.learn(
            &policy,
            &segments,
            Timings {
                collect_s: batch.wait_s,
            },
        )?;
        let ppo_s = t_ppo.elapsed().as_secs_f64();
        let t_pub = Instant::now();
        node.publish_weights(&learner.policy())?;
        let publish_s = t_pub.elapsed().as_secs_f64();
        let mut row = report.row;
        row.insert("time/wait_s".into(), batch.wait_s);
        row.insert("time/ppo_s".into(), ppo_s);
        row.insert("time/publish_s".into(), publish_s);
        row.insert("dist/chunks".into(), batch.chunks.len() as f64);
        row.insert("dist/alive_actors".into(), node.alive_actors() as f64);
        let drops = node.drops();
        for r in DropReason::ALL {
            row.insert(
                format!("dist/dropped_{}", r.as_str()),
                drops.get(r.as_str()).copied().unwrap_or(0) as f64,
            );
        }
        let last = learner.done();
        if eval_due(&cfg, learner.update, last) {
            let eps = evaluate(&cfg, &world, &rsrp, &learner.policy(), &eval_set)?;
            put_domain(&mut row, "eval", &domain_stats(&eps));
        }
        pb.set_position(learner.global_step);
        pb.set_message(progress_message(&row));
        if global.quiet {
            tracing::info!(update = learner.update, "update");
        }
        out.push(row.clone())?;
        if learner.update.is_multiple_of(cfg.train.checkpoint_every) || last {
            out.checkpoint(&learner)?;
        }
        if node.since_stats_s() >= cfg.distributed.stats_every_s || last {
            node.publish_stats(
                learner.update,
                learner.num_updates(),
                learner.global_step,
                &row,
                last,
            )?;
        }
        last_row = row;
    }
    pb.finish_and_clear();
    let interrupted = stop.load(Ordering::Relaxed) && !learner.done();
    // Always leave a checkpoint behind, also on Ctrl-C.
    out.checkpoint(&learner)?;
    if interrupted {
        eprintln!(
            "interrupted at update {}: checkpoint written to {}; continue with --resume",
            learner.update,
            out.ck_path.display()
        );
    } else {
        node.send_stop(learner.update)?;
        println!("{}", summary_line(&learner, &out.last()));
    }
    node.close();
    eprintln!("wrote {}", out.out.display());
    Ok(ExitCode::SUCCESS)
}
