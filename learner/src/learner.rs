//! The learner: PPO with its normalisers and counters, fed with trajectories from anywhere.
//! [`Learner`] assembles each batch ([`crate::batch`]: reward scaling, GAE, the decoupled-PPO
//! correction for older data), runs the update, keeps the normalisers and counters, writes the
//! update's metrics and checkpoints; it never sees an environment. [`Learner::iterate`] takes
//! one batch from a [`TrajectorySource`](crate::source::TrajectorySource) (local rollout
//! workers, or chunks over Zenoh) and updates on it; the run layer (`dupac-run`) owns the loop
//! that decides when to evaluate, log and checkpoint.
//!
//! Determinism: the network init and the minibatch shuffles derive from `train.seed` and the
//! update index ([`stream_seed`]), so with a deterministic source one seed reproduces a run bit
//! for bit whatever the thread count.

use crate::batch::{Assembler, Segment};
use crate::checkpoint::{CheckpointError, CheckpointMeta, LoadedCheckpoint, save_checkpoint};
use crate::model::{ActorCritic, init_plain};
use crate::ppo::{Batch, Ppo, UpdateStats};
use crate::source::{Progress, SourceError, TrajectorySource};
use dupac_common::config::{Config, SiteHead};
use dupac_common::ids::ActorId;
use dupac_common::metric;
use dupac_common::msg::EpisodeSummary;
use dupac_common::normalize::{ObsNormalizer, RewardScaler};
use dupac_common::policy::{MOVE_DIM, PolicyWeights, SiteHead as PlainSiteHead};
use dupac_common::seed::stream_seed;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;
use std::path::Path;
use std::time::Instant;

/// Errors of the learner.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// The trajectory source failed (an environment, a rollout, the network).
    #[error(transparent)]
    Source(SourceError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error("{0}")]
    Invalid(String),
    /// `ppo.max_bad_updates` consecutive updates were skipped for numerical faults.
    #[error(
        "stopping: {streak} consecutive updates skipped for numerical faults (ppo.max_bad_updates = {max}); last: {last}. The weights are the last good ones (version {version}); the last checkpoint holds them"
    )]
    Numerics {
        streak: u32,
        max: u32,
        last: String,
        version: u64,
    },
}

/// One row of metrics: CleanRL's names plus the domain ones.
pub type MetricsRow = BTreeMap<String, f64>;

/// What one update did: its statistics, its metrics row and the episodes that ended in its
/// batch (for the run layer's rolling episode metrics).
#[derive(Debug)]
pub struct IterationReport {
    pub stats: UpdateStats,
    pub row: MetricsRow,
    /// Episodes that ended in the batch (none when the update was skipped for non-finite input).
    pub episodes: Vec<EpisodeSummary>,
}

/// Extra timings of one iteration, reported as `time/*` metrics (s).
#[derive(Debug, Clone, Copy, Default)]
pub struct Timings {
    /// Collecting the batch: rollout (one process) or waiting for chunks (distributed).
    pub collect_s: f64,
}

/// PPO with its normalisers and counters, fed with trajectories from anywhere.
pub struct Learner {
    pub cfg: Config,
    ppo: Ppo,
    obs_norm: ObsNormalizer,
    reward_scaler: RewardScaler,
    /// Running discounted return per (actor, environment) for reward scaling.
    return_acc: BTreeMap<(ActorId, u32), f64>,
    n_sites: usize,
    obs_dim: usize,
    /// Observation values the MLPs read (the rest: the site head's features).
    trunk_dim: usize,
    pub update: u64,
    pub global_step: u64,
    pub episodes: u64,
    pub train_seconds: f64,
    /// Samples trained with the decoupled correction (acted with an older version) so far.
    pub off_policy_samples: u64,
    /// Updates skipped for numerical faults, in all and in a row.
    pub skipped_updates: u64,
    bad_streak: u32,
}

/// The MLPs' input length and the equivariant head's features per site, for observations of
/// `obs_dim` values and `n_sites` learned sites: the layout of `env.observation` of that length
/// tells where the `site_features` tail starts (the MLPs read what comes before it). The head is
/// built when `ppo.site_head = "equivariant"` and the tail holds `n_sites × site_features_per_site`
/// values (configuration validation guarantees it in a run); otherwise slot logits.
fn trunk_shape(cfg: &Config, obs_dim: usize, n_sites: usize) -> (usize, Option<usize>) {
    use dupac_common::obs::{ObsLayout, site_features_per_site};
    let per_site = site_features_per_site(&cfg.env.observation);
    let trunk = (0..=obs_dim)
        .map(|m| ObsLayout::new(&cfg.env.observation, m))
        .find(|l| l.len() == obs_dim)
        .map(|l| l.trunk_len())
        .unwrap_or(obs_dim);
    let want = n_sites > 0 && cfg.ppo.site_head == SiteHead::Equivariant;
    let fits = obs_dim - trunk == n_sites * per_site;
    if want && !fits {
        tracing::warn!(
            obs_dim,
            n_sites,
            "no site features in the observation: slot logits instead of the equivariant head"
        );
    }
    (trunk, (want && fits).then_some(per_site))
}

impl Learner {
    /// Fresh networks initialised from `train.seed`.
    pub fn new(
        cfg: Config,
        obs_dim: usize,
        n_sites: usize,
        device: &burn::tensor::Device,
    ) -> Learner {
        // Parameters live on the autodiff decoration of the chosen device.
        let device = &device.clone().autodiff();
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(cfg.train.seed, u64::MAX - 1, 0));
        let pp = &cfg.ppo;
        let (trunk_dim, head_features) = trunk_shape(&cfg, obs_dim, n_sites);
        let slot_logits = if head_features.is_some() { 0 } else { n_sites };
        let actor = init_plain(
            trunk_dim,
            &pp.hidden,
            MOVE_DIM + slot_logits,
            0.01,
            &mut rng,
        );
        let critic = init_plain(trunk_dim, &pp.hidden, 1, 1.0, &mut rng);
        let log_std = [pp.init_log_std as f32; MOVE_DIM];
        let site = head_features.map(|f| {
            let hidden = *pp.hidden.last().unwrap_or(&trunk_dim);
            let embed = init_plain(hidden, &[], pp.site_embed, 2f64.sqrt(), &mut rng);
            PlainSiteHead {
                features: f,
                embed: embed.layers.into_iter().next().expect("one layer"),
                mlp: init_plain(f + pp.site_embed, &pp.site_hidden, 1, 0.01, &mut rng),
            }
        });
        let model =
            ActorCritic::from_plain(&actor, &critic, log_std, site.as_ref(), n_sites, device);
        let ppo = Ppo::new(pp.clone(), model, device.clone());
        Learner {
            obs_norm: ObsNormalizer::new(obs_dim, pp.normalize_obs, pp.obs_clip),
            reward_scaler: RewardScaler::new(pp.normalize_reward, pp.gamma, pp.reward_clip),
            return_acc: BTreeMap::new(),
            n_sites,
            obs_dim,
            trunk_dim,
            ppo,
            update: 0,
            global_step: 0,
            episodes: 0,
            train_seconds: 0.0,
            off_policy_samples: 0,
            skipped_updates: 0,
            bad_streak: 0,
            cfg,
        }
    }

    /// Takes over a checkpoint's model, Adam state, normalisers and counters.
    pub fn restore(
        &mut self,
        device: &burn::tensor::Device,
        ck: &LoadedCheckpoint,
    ) -> Result<(), TrainError> {
        let device = &device.clone().autodiff();
        let p = &ck.meta.policy;
        p.check_observation(&self.cfg.env.observation)
            .map_err(|m| TrainError::Invalid(format!("checkpoint policy: {m}")))?;
        if p.obs_dim != self.obs_dim
            || p.n_sites != self.n_sites
            || p.trunk_dim() != self.trunk_dim
            || p.site_head.is_some() != self.ppo.model.site.is_some()
        {
            return Err(TrainError::Invalid(format!(
                "checkpoint policy has {} observations, {} site logits and {} site head; this configuration gives {}, {} and {} (ppo.site_head)",
                p.obs_dim,
                p.n_sites,
                if p.site_head.is_some() {
                    "an equivariant"
                } else {
                    "a slot"
                },
                self.obs_dim,
                self.n_sites,
                if self.ppo.model.site.is_some() {
                    "an equivariant"
                } else {
                    "a slot"
                },
            )));
        }
        let optim = burn::optim::AdamConfig::new()
            .with_epsilon(self.cfg.ppo.adam_eps as f32)
            .init();
        let (model, optim) = ck.restore(device, optim)?;
        self.ppo.model = model;
        self.ppo.optim = optim;
        self.obs_norm = p.obs_norm.clone();
        self.reward_scaler = p.reward_scaler.clone();
        self.return_acc = ck
            .meta
            .return_acc
            .iter()
            .enumerate()
            .map(|(k, &v)| ((ActorId(0), k as u32), v))
            .collect();
        self.update = ck.meta.update;
        self.global_step = ck.meta.global_step;
        self.episodes = ck.meta.episodes;
        self.train_seconds = ck.meta.train_seconds;
        Ok(())
    }

    /// Samples per update (num_envs × num_steps).
    pub fn batch_size(&self) -> usize {
        self.cfg.train.num_envs * self.cfg.train.num_steps
    }

    /// Updates of the whole run.
    pub fn num_updates(&self) -> u64 {
        (self.cfg.train.total_timesteps / self.batch_size() as u64).max(1)
    }

    pub fn done(&self) -> bool {
        self.update >= self.num_updates()
    }

    pub fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    pub fn n_sites(&self) -> usize {
        self.n_sites
    }

    /// The current policy, exported (weights, log-std, normalisers, version).
    pub fn policy(&self) -> PolicyWeights {
        let (actor, critic, log_std, site_head) = self.ppo.model.to_plain();
        PolicyWeights {
            version: self.update,
            obs_version: dupac_common::obs::OBS_VERSION,
            obs_dim: self.obs_dim,
            n_sites: self.n_sites,
            actor,
            critic,
            site_head,
            log_std,
            obs_norm: self.obs_norm.clone(),
            reward_scaler: self.reward_scaler.clone(),
            observation: Some(self.cfg.env.observation.clone()),
        }
    }

    /// Where the run stands (what a source reports to its peers).
    pub fn progress(&self) -> Progress {
        Progress {
            update: self.update,
            num_updates: self.num_updates(),
            global_step: self.global_step,
        }
    }

    /// One iteration: a batch from `source` for the current policy, the PPO update on it, the
    /// new weights handed back to the source. `None` when the source is stopping (no update).
    /// The row gets the source's metrics and `time/ppo_s` (the update with its batch assembly).
    pub fn iterate(
        &mut self,
        source: &mut dyn TrajectorySource,
    ) -> Result<Option<IterationReport>, TrainError> {
        let t0 = Instant::now();
        let policy = self.policy();
        let Some(batch) = source
            .collect(&policy, self.batch_size(), &self.progress())
            .map_err(TrainError::Source)?
        else {
            return Ok(None);
        };
        let collect_s = batch
            .collect_s
            .unwrap_or_else(|| t0.elapsed().as_secs_f64());
        let segments: Vec<Segment<'_>> = batch
            .trajectories
            .iter()
            .map(|s| Segment {
                actor: s.actor,
                behaviour_version: s.behaviour_version,
                traj: &s.traj,
            })
            .collect();
        let t_ppo = Instant::now();
        let mut report = self.learn(&policy, &segments, Timings { collect_s })?;
        report
            .row
            .insert(metric::PPO_S.into(), t_ppo.elapsed().as_secs_f64());
        report.row.extend(batch.metrics);
        source
            .publish(&self.policy(), &mut report.row)
            .map_err(TrainError::Source)?;
        Ok(Some(report))
    }

    /// One PPO update on `segments`; `policy` is [`Learner::policy`] (the current version,
    /// the proximal policy of the decoupled correction).
    pub fn learn(
        &mut self,
        policy: &PolicyWeights,
        segments: &[Segment<'_>],
        timings: Timings,
    ) -> Result<IterationReport, TrainError> {
        let t0 = Instant::now();
        let n_samples: usize = segments.iter().map(|s| s.traj.len()).sum();
        // Numerical faults: a non-finite number in the batch skips the whole update
        // before anything (normalisers, return accumulators, weights) has seen it.
        let bad_input = segments.iter().find_map(|s| {
            s.traj.first_non_finite().map(|w| {
                format!(
                    "non-finite input from actor {} env {}: {w}",
                    s.actor, s.traj.env
                )
            })
        });
        let frac = 1.0 - self.update as f64 / self.num_updates() as f64;
        let lr = if self.cfg.ppo.anneal_lr {
            frac.max(0.0) * self.cfg.ppo.learning_rate
        } else {
            self.cfg.ppo.learning_rate
        };
        let bad_input_skipped = bad_input.is_some();
        let (stats, update_s, skipped) = match bad_input {
            Some(why) => (UpdateStats::skipped(lr), 0.0, Some(why)),
            None => self.update_on(policy, segments, lr),
        };
        if let Some(why) = &skipped {
            self.skipped_updates += 1;
            self.bad_streak += 1;
            tracing::warn!(
                update = self.update + 1,
                streak = self.bad_streak,
                "update skipped: {why}"
            );
        } else {
            self.bad_streak = 0;
        }
        self.update += 1;
        self.global_step += n_samples as u64;
        let elapsed = timings.collect_s + t0.elapsed().as_secs_f64();
        self.train_seconds += elapsed;
        let mut row = MetricsRow::new();
        let mut put = |k: &str, v: f64| {
            row.insert(k.to_string(), v);
        };
        put(metric::GLOBAL_STEP, self.global_step as f64);
        put(metric::UPDATE, self.update as f64);
        put(metric::TIME_S, self.train_seconds);
        put(metric::SPS, n_samples as f64 / elapsed);
        put(metric::ROLLOUT_S, timings.collect_s);
        put(metric::UPDATE_S, update_s);
        put(metric::LEARNING_RATE, lr);
        let older: usize = segments
            .iter()
            .filter(|s| s.behaviour_version != policy.version)
            .map(|s| s.traj.len())
            .sum();
        put(
            metric::OLDER_POLICY_FRAC,
            older as f64 / n_samples.max(1) as f64,
        );
        put(metric::POLICY_LOSS, stats.policy_loss);
        put(metric::VALUE_LOSS, stats.value_loss);
        put(metric::ENTROPY, stats.entropy);
        put(metric::ENTROPY_MOVE, stats.entropy_move);
        put(metric::ENTROPY_SITE, stats.entropy_site);
        put(metric::SITE_LOSS, stats.site_loss);
        put(metric::OLD_APPROX_KL, stats.old_approx_kl);
        put(metric::APPROX_KL, stats.approx_kl);
        put(metric::CLIPFRAC, stats.clipfrac);
        put(metric::EXPLAINED_VARIANCE, stats.explained_variance);
        put(metric::GRAD_NORM, stats.grad_norm);
        put(metric::SKIPPED_NONFINITE, stats.skipped_nonfinite as f64);
        put(
            metric::SKIPPED_UPDATE,
            f64::from(u8::from(skipped.is_some())),
        );
        put(metric::SKIPPED_UPDATES, self.skipped_updates as f64);
        let max = self.cfg.ppo.max_bad_updates;
        if let Some(last) = skipped
            && max > 0
            && self.bad_streak >= max
        {
            return Err(TrainError::Numerics {
                streak: self.bad_streak,
                max,
                last,
                version: self.update,
            });
        }
        let episodes = if bad_input_skipped {
            Vec::new()
        } else {
            segments
                .iter()
                .flat_map(|s| s.traj.episodes.iter().cloned())
                .collect()
        };
        Ok(IterationReport {
            stats,
            row,
            episodes,
        })
    }

    /// The update proper on finite data: returns its statistics, its duration and, when the
    /// weights came out non-finite, why it was undone (weights, optimiser, normalisers and return
    /// accumulators restored to what they were).
    fn update_on(
        &mut self,
        policy: &PolicyWeights,
        segments: &[Segment<'_>],
        lr: f64,
    ) -> (UpdateStats, f64, Option<String>) {
        let before = (
            self.ppo.model.clone(),
            self.ppo.optim.clone(),
            self.obs_norm.clone(),
            self.reward_scaler.clone(),
            self.return_acc.clone(),
        );
        let batch = self.assemble(policy, segments);
        self.episodes += segments
            .iter()
            .map(|s| s.traj.episodes.len() as u64)
            .sum::<u64>();
        // The next policy's observation statistics include this batch.
        if self.obs_norm.enabled {
            for seg in segments {
                self.obs_norm.stats.update(&seg.traj.obs);
            }
        }
        let mut rng =
            ChaCha8Rng::seed_from_u64(stream_seed(self.cfg.train.seed, u64::MAX, self.update));
        let t1 = Instant::now();
        let stats = self.ppo.update(&batch, lr, &mut rng);
        let update_s = t1.elapsed().as_secs_f64();
        let (actor, critic, log_std, site) = self.ppo.model.to_plain();
        let finite = actor.all_finite()
            && critic.all_finite()
            && log_std.iter().all(|v| v.is_finite())
            && site.as_ref().is_none_or(|h| {
                h.mlp.all_finite()
                    && h.embed
                        .weight
                        .iter()
                        .chain(&h.embed.bias)
                        .all(|v| v.is_finite())
            });
        if finite {
            return (stats, update_s, None);
        }
        (
            self.ppo.model,
            self.ppo.optim,
            self.obs_norm,
            self.reward_scaler,
            self.return_acc,
        ) = before;
        (
            UpdateStats::skipped(lr),
            update_s,
            Some("non-finite weights after the update (undone)".to_string()),
        )
    }

    /// The batch of `segments` ([`crate::batch`]): reward scaling per stream, GAE per stream,
    /// observations normalised with the statistics of `policy`, the decoupled correction for
    /// segments acted with an older version, flattened.
    fn assemble(&mut self, policy: &PolicyWeights, segments: &[Segment<'_>]) -> Batch {
        let assembled = Assembler {
            cfg: &self.cfg,
            obs_dim: self.obs_dim,
            trunk_dim: self.trunk_dim,
            n_sites: self.n_sites,
            reward_scaler: &mut self.reward_scaler,
            return_acc: &mut self.return_acc,
        }
        .assemble(policy, segments);
        self.off_policy_samples += assembled.off_policy_samples;
        assembled.batch
    }

    /// Writes a checkpoint atomically.
    pub fn save(&self, path: &Path) -> Result<(), TrainError> {
        let n = self.cfg.train.num_envs as u32;
        let meta = CheckpointMeta {
            seed: self.cfg.train.seed,
            update: self.update,
            global_step: self.global_step,
            episodes: self.episodes,
            train_seconds: self.train_seconds,
            config_toml: self.cfg.to_toml_string(),
            policy: self.policy(),
            return_acc: (0..n)
                .map(|k| {
                    self.return_acc
                        .get(&(ActorId(0), k))
                        .copied()
                        .unwrap_or(0.0)
                })
                .collect(),
        };
        save_checkpoint(path, &meta, &self.ppo.model, &self.ppo.optim)?;
        Ok(())
    }

    pub fn model(&self) -> &ActorCritic {
        &self.ppo.model
    }
}

#[cfg(test)]
mod tests;
