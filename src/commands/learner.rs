//! `dupac learner`: the central PPO learner of a Zenoh run. Receives trajectory
//! chunks from any number of actors, updates, publishes weights, serves the latest by query:
//! the one training loop (`commands::training`) over a Zenoh trajectory source, writing the
//! run directory like `dupac train --single-process`, and stopping cleanly on Ctrl-C
//! (checkpoint written).

use super::net::{ConnectArgs, stop_flag};
use super::run_args::RunArgs;
use super::training::Training;
use crate::global_args::GlobalArgs;
use anyhow::Result;
use clap::Args;
use dupac_actor::expand::Expander;
use dupac_common::msg::MsgLimits;
use dupac_node::learner::{LearnerNode, new_incarnation};
use dupac_node::source::ZenohSource;
use std::process::ExitCode;

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
    let t = Training::prepare(global, &args.run, " (distributed)", false)?;
    let (cfg, l) = (&t.cfg, &t.learner);
    let fingerprint = cfg.env_fingerprint(t.world.fingerprint());
    let (obs_dim, n_sites) = (l.obs_dim(), l.n_sites());
    let session = args
        .net
        .open_retrying(&stop, MsgLimits::run_max_bytes(cfg, obs_dim, n_sites))?;
    let incarnation = new_incarnation();
    let expander = Expander::new(cfg, &t.world);
    let node = LearnerNode::start(session, cfg, expander, n_sites, fingerprint, incarnation)?;
    node.publish_weights(&l.policy())?;
    eprintln!(
        "learner {incarnation:016x} of run {:?}: {}, version {}, {} updates × {} samples, fingerprint {fingerprint:016x}",
        cfg.distributed.run,
        t.method,
        l.update,
        l.num_updates(),
        l.batch_size()
    );
    let mut source = ZenohSource::new(node, stop.clone(), cfg.distributed.stats_every_s);
    t.run(global, &mut source, &stop)
}
