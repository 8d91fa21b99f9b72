//! Where the learner's trajectories come from: a small trait between the rollout side and the
//! learner (Sample Factory's rollout workers → batcher → learner). The learner asks for a batch,
//! updates on it and hands the new weights back; it never sees an environment. Two sources
//! exist: local rollout workers on threads (`dupac_run::local::LocalWorkers`, `dupac train
//! --single-process`) and trajectory chunks received over Zenoh
//! (`dupac_node::source::ZenohSource`, `dupac learner`).

use dupac_common::ids::ActorId;
use dupac_common::msg::EnvTrajectory;
use dupac_common::policy::PolicyWeights;
use std::collections::BTreeMap;

/// A source's failure (an environment, a rollout worker, the network), boxed so that the
/// learner does not depend on what the source is made of.
pub type SourceError = Box<dyn std::error::Error + Send + Sync>;

/// Where the run stands, for a source that reports it (the Zenoh source publishes it in its
/// statistics).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    /// Updates done.
    pub update: u64,
    /// Updates of the whole run.
    pub num_updates: u64,
    /// Decisions trained on so far.
    pub global_step: u64,
}

/// One environment's trajectory with where it came from.
#[derive(Debug, Clone)]
pub struct Sourced {
    /// The actor process (local workers are actor 0).
    pub actor: ActorId,
    /// Version of the policy that acted.
    pub behaviour_version: u64,
    pub traj: EnvTrajectory,
}

/// One batch from a source.
#[derive(Debug, Clone, Default)]
pub struct Collected {
    pub trajectories: Vec<Sourced>,
    /// Time spent collecting (s): rollout, or waiting for chunks; `None`: the learner measures
    /// the call.
    pub collect_s: Option<f64>,
    /// The source's own metrics for this update's row (e.g. `dist/chunks`, `time/wait_s`).
    pub metrics: BTreeMap<String, f64>,
}

/// A source of trajectories for [`Learner::iterate`](crate::learner::Learner::iterate).
pub trait TrajectorySource {
    /// At least `samples` decisions acted with `policy` (the learner's current weights) or, for
    /// an asynchronous source, with versions not older than it accepts; `None` when the run is
    /// stopping (Ctrl-C) and no batch will come.
    fn collect(
        &mut self,
        policy: &PolicyWeights,
        samples: usize,
        progress: &Progress,
    ) -> Result<Option<Collected>, SourceError>;

    /// The weights after an update (a distributed source broadcasts them); may add metrics to
    /// the update's row.
    fn publish(
        &mut self,
        _policy: &PolicyWeights,
        _row: &mut BTreeMap<String, f64>,
    ) -> Result<(), SourceError> {
        Ok(())
    }

    /// The update's complete row (evaluation included), once written; `last`: the run's final
    /// update.
    fn report(
        &mut self,
        _row: &BTreeMap<String, f64>,
        _progress: &Progress,
        _last: bool,
    ) -> Result<(), SourceError> {
        Ok(())
    }

    /// The run ends: `completed` when every update was done (not interrupted).
    fn finish(&mut self, _progress: &Progress, _completed: bool) -> Result<(), SourceError> {
        Ok(())
    }
}
