//! Local rollout workers as the learner's trajectory source (`dupac train --single-process`):
//! `train.num_envs` environments stepped on worker threads with the current policy, each
//! reseeded from `train.seed`, its index and the update, so one seed reproduces a run bit for
//! bit whatever the thread count; `--resume` continues the same streams from the saved update
//! (the environments restart their episodes, so a resumed run is not bit-identical to an
//! uninterrupted one).

use crate::error::RunError;
use dupac_actor::env::Env;
use dupac_actor::pairs::Pair;
use dupac_actor::rollout::Worker;
use dupac_common::config::Config;
use dupac_common::ids::ActorId;
use dupac_common::msg::EnvTrajectory;
use dupac_common::policy::PolicyWeights;
use dupac_common::seed::stream_seed;
use dupac_learner::source::{Collected, Progress, SourceError, Sourced, TrajectorySource};
use dupac_radio::world::RadioWorld;
use dupac_scenario::world::SharedRsrp;
use rayon::prelude::*;
use std::sync::Arc;

/// `train.num_envs` rollout workers in this process (actor 0).
pub struct LocalWorkers {
    workers: Vec<Worker>,
    seed: u64,
    num_steps: usize,
}

impl LocalWorkers {
    /// One worker per `train.num_envs`, drawing from `pool`, in the training environment (the
    /// sphere grown by `env.training_margin_m`).
    pub fn new(
        cfg: &Config,
        world: &Arc<RadioWorld>,
        rsrp: &SharedRsrp,
        pool: &Arc<Vec<Pair>>,
    ) -> Result<LocalWorkers, RunError> {
        let train_cfg = cfg.training();
        let workers = (0..cfg.train.num_envs)
            .map(|k| {
                let env = Env::new(&train_cfg, world.clone(), rsrp.clone())?;
                Ok(Worker::new(
                    k as u32,
                    env,
                    pool.clone(),
                    stream_seed(cfg.train.seed, k as u64, u64::MAX),
                )?)
            })
            .collect::<Result<_, RunError>>()?;
        Ok(LocalWorkers {
            workers,
            seed: cfg.train.seed,
            num_steps: cfg.train.num_steps,
        })
    }
}

impl TrajectorySource for LocalWorkers {
    /// One rollout of `train.num_steps` decisions per worker (`samples` is their product).
    fn collect(
        &mut self,
        policy: &PolicyWeights,
        _samples: usize,
        progress: &Progress,
    ) -> Result<Option<Collected>, SourceError> {
        for (k, w) in self.workers.iter_mut().enumerate() {
            w.reseed(stream_seed(self.seed, k as u64, progress.update));
        }
        let steps = self.num_steps;
        let trajs: Vec<EnvTrajectory> = self
            .workers
            .par_iter_mut()
            .map(|w| w.collect_expanded(policy, steps))
            .collect::<Result<_, _>>()?;
        Ok(Some(Collected {
            trajectories: trajs
                .into_iter()
                .map(|traj| Sourced {
                    actor: ActorId(0),
                    behaviour_version: policy.version,
                    traj,
                })
                .collect(),
            collect_s: None,
            metrics: Default::default(),
        }))
    }
}
