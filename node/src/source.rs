//! The learner's trajectory source over Zenoh: [`ZenohSource`] wraps a [`LearnerNode`] as a
//! [`TrajectorySource`], so `dupac learner` runs the same training loop as `dupac train
//! --single-process`. A batch is the queued chunks of at least a batch's samples; after each
//! update the new weights are broadcast; statistics go out every `distributed.stats_every_s`
//! (also while waiting for data) and with the last update; a completed run tells actors to stop.

use crate::learner::{BatchChunks, Gathered, LearnerNode, NodeError};
use dupac_common::metric;
use dupac_common::policy::PolicyWeights;
use dupac_common::validate::DropReason;
use dupac_learner::source::{Collected, Progress, SourceError, Sourced, TrajectorySource};
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::Instant;

/// A [`LearnerNode`] as the learner's trajectory source.
pub struct ZenohSource {
    node: Option<LearnerNode>,
    stop: Arc<AtomicBool>,
    stats_every_s: f64,
    /// The last update's row: what statistics published while waiting carry.
    last_row: BTreeMap<String, f64>,
}

impl ZenohSource {
    /// `stop` (Ctrl-C) ends a wait for data with no batch.
    pub fn new(node: LearnerNode, stop: Arc<AtomicBool>, stats_every_s: f64) -> ZenohSource {
        ZenohSource {
            node: Some(node),
            stop,
            stats_every_s,
            last_row: BTreeMap::new(),
        }
    }

    fn node(&mut self) -> Result<&mut LearnerNode, SourceError> {
        self.node
            .as_mut()
            .ok_or_else(|| "the learner node is closed".into())
    }
}

impl TrajectorySource for ZenohSource {
    fn collect(
        &mut self,
        policy: &PolicyWeights,
        samples: usize,
        progress: &Progress,
    ) -> Result<Option<Collected>, SourceError> {
        let stop = self.stop.clone();
        let last_row = &self.last_row;
        let node = self.node.as_mut().ok_or("the learner node is closed")?;
        let p = *progress;
        let mut batch = BatchChunks::default();
        loop {
            let until = node.stats_due_at();
            match node.gather(&mut batch, policy.version, samples, &stop, until) {
                Gathered::Full => break,
                Gathered::Stopped => return Ok(None),
                // Monitors hear from a learner waiting for data.
                // (A stats message that cannot be encoded is not worth stopping the wait for.)
                Gathered::Due => {
                    let _ =
                        node.publish_stats(p.update, p.num_updates, p.global_step, last_row, false);
                }
            }
        }
        let mut metrics = BTreeMap::new();
        metrics.insert(metric::WAIT_S.into(), batch.wait_s);
        metrics.insert(metric::CHUNKS.into(), batch.chunks.len() as f64);
        let trajectories = batch
            .chunks
            .into_iter()
            .flat_map(|c| {
                let (actor, version) = (c.header.actor, c.header.policy_version);
                c.trajectories.into_iter().map(move |traj| Sourced {
                    actor,
                    behaviour_version: version,
                    traj,
                })
            })
            .collect();
        Ok(Some(Collected {
            trajectories,
            collect_s: Some(batch.wait_s),
            metrics,
        }))
    }

    fn publish(
        &mut self,
        policy: &PolicyWeights,
        row: &mut BTreeMap<String, f64>,
    ) -> Result<(), SourceError> {
        let node = self.node()?;
        let t = Instant::now();
        node.publish_weights(policy)?;
        row.insert(metric::PUBLISH_S.into(), t.elapsed().as_secs_f64());
        row.insert(metric::ALIVE_ACTORS.into(), node.alive_actors() as f64);
        row.insert(
            metric::RECEIVED_MB.into(),
            node.received_bytes() as f64 / 1e6,
        );
        let (full, held) = node.weights_replies();
        row.insert(metric::WEIGHTS_REPLIES_FULL.into(), full as f64);
        row.insert(metric::WEIGHTS_REPLIES_HELD.into(), held as f64);
        let (accept_s, expand_s) = node.accept_s();
        row.insert(metric::ACCEPT_S.into(), accept_s);
        row.insert(metric::EXPAND_S.into(), expand_s);
        let drops = node.drops();
        for r in DropReason::ALL {
            row.insert(
                metric::dropped(r.as_str()),
                drops.get(r.as_str()).copied().unwrap_or(0) as f64,
            );
        }
        Ok(())
    }

    fn report(
        &mut self,
        row: &BTreeMap<String, f64>,
        p: &Progress,
        last: bool,
    ) -> Result<(), SourceError> {
        let every = self.stats_every_s;
        let node = self.node()?;
        if node.since_stats_s() >= every || last {
            node.publish_stats(p.update, p.num_updates, p.global_step, row, last)?;
        }
        self.last_row = row.clone();
        Ok(())
    }

    fn finish(&mut self, p: &Progress, completed: bool) -> Result<(), SourceError> {
        let Some(node) = self.node.take() else {
            return Ok(());
        };
        node.close(completed.then_some(p.update))
            .map_err(|e: NodeError| e.into())
    }
}
