//! `[distributed]`: the Zenoh actor/learner system (docs/distributed.md).

use super::ConfigError;
#[allow(unused_imports)]
use super::check::*;
use serde::{Deserialize, Serialize};
#[allow(unused_imports)]
use std::path::PathBuf;

/// The Zenoh actor/learner system (`dupac train`, `dupac learner`, `dupac actor`).
/// The learner's batch is still `train.num_envs × train.num_steps` samples, whatever the number
/// of actors: it is filled with chunks of `actor_envs × chunk_steps` samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct DistributedConfig {
    /// Run name: every key expression is `dupac/<run>/…` (letters, digits, `-`, `_`).
    pub run: String,
    /// Actor processes `dupac train` starts (0 = one per core).
    pub actors: usize,
    /// Environments each actor process steps (on its own threads).
    pub actor_envs: usize,
    /// Steps per environment in one trajectory chunk.
    pub chunk_steps: usize,
    /// Chunks an actor publishes per policy version before it waits for the next one (0 =
    /// its share of a learner batch: ⌈train.num_envs × train.num_steps / (actor_envs ×
    /// chunk_steps × actors alive)⌉). Actors faster than the learner would otherwise mostly
    /// produce data that is dropped as stale, on cores the learner needs. On dedicated actor
    /// hosts, one more than the share keeps actors busy during updates (that data arrives one
    /// version old and is trained with the decoupled correction).
    pub max_chunks_per_version: usize,
    /// Oldest policy accepted: data from version `v − max_policy_lag` or newer trains version
    /// `v`; older data is dropped and counted (`stale`).
    pub max_policy_lag: u64,
    /// Decoupled PPO (Hilton et al. 2021) for data from an older version: the clipped ratio is
    /// taken against the current (proximal) policy, and the advantage weighted by
    /// π_prox / π_behaviour, capped at `max_importance_weight`.
    pub decoupled_correction: bool,
    /// Cap on the importance weight π_prox / π_behaviour of `decoupled_correction`.
    pub max_importance_weight: f64,
    /// Hard cap on any received message (MiB); larger ones are dropped unread.
    pub max_message_mib: f64,
    /// Chunks the learner's receive queue holds; when full the oldest is dropped (`overflow`).
    pub queue_chunks: usize,
    /// An actor that published nothing for this long is reported silent (s).
    pub silent_after_s: f64,
    /// An actor that has sent its share for the current version and still sees the learner at
    /// that version this many seconds after the share's last chunk left sends another share:
    /// its chunks were lost (router restart, partition; delivery is at most once). Longer than
    /// a PPO update.
    pub resend_after_s: f64,
    /// Interval of the stats messages of learner and actors (s).
    pub stats_every_s: f64,
    /// Replies per second the learner's weights queryable gives at most (the whole policy, or
    /// ≈ 100 bytes to an asker that holds the newest), with a burst of twice that: actors and
    /// pilots query when they join and after a while without weights (`node::ask_clock`); a flood of queries is
    /// left unanswered.
    pub weights_replies_per_s: f64,
}

impl Default for DistributedConfig {
    fn default() -> Self {
        Self {
            run: "default".into(),
            actors: 0,
            actor_envs: 4,
            chunk_steps: 128,
            max_chunks_per_version: 0,
            max_policy_lag: 1,
            decoupled_correction: true,
            max_importance_weight: 2.0,
            max_message_mib: 64.0,
            queue_chunks: 256,
            silent_after_s: 10.0,
            resend_after_s: 5.0,
            stats_every_s: 1.0,
            weights_replies_per_s: 10.0,
        }
    }
}

impl DistributedConfig {
    /// [`DistributedConfig::max_chunks_per_version`] resolved for a learner batch of
    /// `batch_samples` shared by `actors` actors.
    pub fn chunks_per_version(&self, batch_samples: usize, actors: usize) -> usize {
        if self.max_chunks_per_version > 0 {
            return self.max_chunks_per_version;
        }
        let per_actor = (self.actor_envs * self.chunk_steps * actors.max(1)).max(1);
        batch_samples.div_ceil(per_actor)
    }

    /// The message size cap in bytes.
    pub fn max_message_bytes(&self) -> usize {
        (self.max_message_mib * 1024.0 * 1024.0) as usize
    }
}

impl DistributedConfig {
    /// Checks `[distributed]`.
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        let d = self;
        if d.run.is_empty()
            || d.run.len() > 64
            || !d
                .run
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(bad(
                "distributed.run",
                format!(
                    "must be 1 to 64 letters, digits, '-' or '_' (it is a key-expression chunk), got {:?}",
                    d.run
                ),
            ));
        }
        if d.actors > 1024 {
            return Err(bad("distributed.actors", "must be in 0..=1024"));
        }
        if d.actor_envs == 0 || d.actor_envs > 4096 {
            return Err(bad("distributed.actor_envs", "must be in 1..=4096"));
        }
        if d.chunk_steps == 0 || d.chunk_steps > 65_536 {
            return Err(bad("distributed.chunk_steps", "must be in 1..=65536"));
        }
        if d.max_importance_weight.is_nan() || d.max_importance_weight < 1.0 {
            return Err(bad("distributed.max_importance_weight", "must be >= 1"));
        }
        if !(d.max_message_mib.is_finite()
            && d.max_message_mib > 0.0
            && d.max_message_mib <= 1024.0)
        {
            return Err(bad("distributed.max_message_mib", "must be in (0, 1024]"));
        }
        if d.queue_chunks == 0 {
            return Err(bad("distributed.queue_chunks", "must be >= 1"));
        }
        positive("distributed.silent_after_s", d.silent_after_s)?;
        positive("distributed.resend_after_s", d.resend_after_s)?;
        positive("distributed.stats_every_s", d.stats_every_s)?;
        Ok(())
    }

    /// Upper bounds of `[distributed]` values that size time or memory.
    pub(crate) fn validate_bounds(&self) -> Result<(), ConfigError> {
        let d = self;
        within(
            "distributed.silent_after_s",
            d.silent_after_s,
            0.0,
            DAY_S,
            "s",
        )?;
        within(
            "distributed.resend_after_s",
            d.resend_after_s,
            0.0,
            DAY_S,
            "s",
        )?;
        within(
            "distributed.stats_every_s",
            d.stats_every_s,
            0.0,
            3600.0,
            "s",
        )?;
        within(
            "distributed.weights_replies_per_s",
            d.weights_replies_per_s,
            0.01,
            10_000.0,
            "per s",
        )?;
        at_most("distributed.queue_chunks", d.queue_chunks as u64, 65_536)?;
        at_most("distributed.max_policy_lag", d.max_policy_lag, 1_000)?;
        at_most(
            "distributed.chunk_steps",
            (d.actor_envs * d.chunk_steps) as u64,
            1 << 22,
        )
        .map_err(|_| ConfigError::Invalid {
            key: "distributed.chunk_steps".into(),
            message: format!(
                "actor_envs × chunk_steps = {} samples per chunk, at most {}",
                d.actor_envs * d.chunk_steps,
                1 << 22
            ),
        })?;
        Ok(())
    }
}
