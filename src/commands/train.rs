//! `dupac train`: by default a learner and actor processes over Zenoh on this machine
//! (`commands::orchestrate`); with `--single-process`, PPO in one process:
//! local rollout workers on threads as the trajectory source of the one training loop
//! (`commands::training`), bit-reproducible from `train.seed`.

use super::run_args::TrainArgs;
use super::training::Training;
use crate::global_args::GlobalArgs;
use anyhow::Result;
use std::process::ExitCode;

pub fn run(global: &GlobalArgs, args: &TrainArgs) -> Result<ExitCode> {
    if !args.single_process {
        return super::orchestrate::run(global, args);
    }
    let mut t = Training::prepare(global, &args.run, "", true)?;
    let Some(mut workers) = t.local.take() else {
        anyhow::bail!("no local rollout workers were started");
    };
    eprintln!(
        "training {} in one process: {} updates × {} samples, {} envs, seed {}",
        t.method,
        t.learner.num_updates(),
        t.learner.batch_size(),
        t.cfg.train.num_envs,
        t.cfg.train.seed
    );
    // Ctrl-C (SIGINT; SIGTERM too, through the ctrlc crate's termination feature): finish the
    // update in progress, write a checkpoint, exit 0 (docs/reliability.md).
    let stop = super::net::stop_flag()?;
    t.run(global, &mut workers, &stop)
}
