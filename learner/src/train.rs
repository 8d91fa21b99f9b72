//! The synchronous training loop (issue 4): vectorised environments stepped on worker threads
//! with the exported policy, reward scaling and GAE, the PPO update, observation statistics,
//! metrics, evaluation and checkpoints. The distributed learner (issue 5) replaces only where the
//! trajectories come from.
//!
//! Determinism: the network init, every worker's RNG and the minibatch shuffles derive from
//! `train.seed` and the update index, so one seed reproduces a run bit for bit in one process
//! whatever the thread count; `--resume` continues the same streams from the saved update (the
//! environments restart their episodes, so a resumed run is not bit-identical to an
//! uninterrupted one).

use crate::checkpoint::{CheckpointError, CheckpointMeta, LoadedCheckpoint, save_checkpoint};
use crate::gae::{Trajectory, gae};
use crate::model::{ActorCritic, init_plain};
use crate::ppo::{Batch, Ppo, UpdateStats};
use dupac_actor::env::{Env, EnvError, Episode, Outcome};
use dupac_actor::pairs::Pair;
use dupac_actor::rollout::{
    EnvTrajectory, EpisodeSummary, RolloutError, Worker, fly_policy, stream_seed,
};
use dupac_common::config::{Association, Config};
use dupac_common::policy::{MOVE_DIM, ObsNormalizer, PolicyWeights, RewardScaler};
use dupac_radio::cache::RsrpSource;
use dupac_radio::world::RadioWorld;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::{BTreeMap, VecDeque};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

/// Errors of the training loop.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    #[error(transparent)]
    Env(#[from] EnvError),
    #[error(transparent)]
    Rollout(#[from] RolloutError),
    #[error(transparent)]
    Checkpoint(#[from] CheckpointError),
    #[error("{0}")]
    Invalid(String),
}

/// Domain metrics over a set of episodes (spec/env.md "Metrics").
#[derive(Debug, Clone, Default, Serialize)]
pub struct DomainStats {
    pub episodes: usize,
    pub success_rate: f64,
    pub collision_rate: f64,
    pub out_of_bounds_rate: f64,
    pub timeout_rate: f64,
    pub episodic_return: f64,
    pub episodic_length: f64,
    /// Mean serving RSRP over all steps (dBm).
    pub mean_rsrp_dbm: f64,
    /// Percent of flight time per class, over all steps.
    pub pct_excellent: f64,
    pub pct_mediocre: f64,
    pub pct_poor: f64,
    /// Handovers per km flown.
    pub handovers_per_km: f64,
    /// Mean distance overhead over the shortest path of the successful episodes (fraction).
    pub distance_overhead: f64,
}

/// Aggregates episode summaries (step-weighted for RSRP and classes).
pub fn domain_stats(eps: &[EpisodeSummary]) -> DomainStats {
    let n = eps.len();
    if n == 0 {
        return DomainStats::default();
    }
    let nf = n as f64;
    let rate = |o: Outcome| eps.iter().filter(|e| e.outcome == o).count() as f64 / nf;
    let steps: f64 = eps
        .iter()
        .map(|e| f64::from(e.length))
        .sum::<f64>()
        .max(1.0);
    let w = |f: &dyn Fn(&EpisodeSummary) -> f64| {
        eps.iter().map(|e| f(e) * f64::from(e.length)).sum::<f64>() / steps
    };
    let km: f64 = eps.iter().map(|e| e.distance_flown_m).sum::<f64>() / 1000.0;
    let ho: f64 = eps.iter().map(|e| f64::from(e.handovers)).sum();
    let ok: Vec<&EpisodeSummary> = eps.iter().filter(|e| e.outcome == Outcome::Goal).collect();
    DomainStats {
        episodes: n,
        success_rate: rate(Outcome::Goal),
        collision_rate: rate(Outcome::Collision),
        out_of_bounds_rate: rate(Outcome::OutOfBounds),
        timeout_rate: rate(Outcome::TimeLimit),
        episodic_return: eps.iter().map(|e| e.episodic_return).sum::<f64>() / nf,
        episodic_length: eps.iter().map(|e| f64::from(e.length)).sum::<f64>() / nf,
        mean_rsrp_dbm: w(&|e| e.mean_rsrp_dbm),
        pct_excellent: 100.0 * w(&|e| e.frac_excellent),
        pct_mediocre: 100.0 * w(&|e| e.frac_mediocre),
        pct_poor: 100.0 * w(&|e| e.frac_poor),
        handovers_per_km: if km > 0.0 { ho / km } else { 0.0 },
        distance_overhead: if ok.is_empty() {
            f64::NAN
        } else {
            ok.iter().map(|e| e.overhead()).sum::<f64>() / ok.len() as f64
        },
    }
}

/// Flies `pairs` with the deterministic policy in parallel (one environment per task).
pub fn evaluate(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &Arc<dyn RsrpSource + Send + Sync>,
    policy: &PolicyWeights,
    pairs: &[Pair],
) -> Result<Vec<EpisodeSummary>, TrainError> {
    pairs
        .par_iter()
        .map(|p| {
            let mut env = Env::new(cfg, world.clone(), rsrp.clone())?;
            let ep = Episode {
                source_m: p.source_m,
                destination_m: p.destination_m,
                shortest_m: p.shortest_m,
            };
            Ok(fly_policy(&mut env, policy, p.id, ep, p.id)?.0)
        })
        .collect()
}

/// One row of metrics: CleanRL's names plus the domain ones.
pub type MetricsRow = BTreeMap<String, f64>;

/// What one call of [`Trainer::iteration`] did.
pub struct IterationReport {
    pub stats: UpdateStats,
    pub row: MetricsRow,
}

/// The learner with its environments.
pub struct Trainer {
    pub cfg: Config,
    world: Arc<RadioWorld>,
    rsrp: Arc<dyn RsrpSource + Send + Sync>,
    ppo: Ppo,
    obs_norm: ObsNormalizer,
    reward_scaler: RewardScaler,
    return_acc: Vec<f64>,
    workers: Vec<Worker>,
    n_sites: usize,
    obs_dim: usize,
    pub update: u64,
    pub global_step: u64,
    pub episodes: u64,
    pub train_seconds: f64,
    recent: VecDeque<EpisodeSummary>,
}

/// Episodes kept for the rolling training metrics.
const RECENT_EPISODES: usize = 100;

impl Trainer {
    /// A fresh run: networks initialised from `train.seed`, one worker per `train.num_envs`
    /// drawing from `pool`.
    pub fn new(
        cfg: Config,
        world: Arc<RadioWorld>,
        rsrp: Arc<dyn RsrpSource + Send + Sync>,
        pool: Arc<Vec<Pair>>,
        device: &burn::tensor::Device,
    ) -> Result<Trainer, TrainError> {
        // Parameters live on the autodiff decoration of the chosen device.
        let device = &device.clone().autodiff();
        let probe = Env::new(&cfg, world.clone(), rsrp.clone())?;
        let obs_dim = probe.layout().len();
        let n_sites = match cfg.env.association {
            Association::Learned => probe.num_sites(),
            Association::A3 | Association::BestRsrp => 0,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(cfg.train.seed, u64::MAX - 1, 0));
        let pp = &cfg.ppo;
        let actor = init_plain(obs_dim, &pp.hidden, MOVE_DIM + n_sites, 0.01, &mut rng);
        let critic = init_plain(obs_dim, &pp.hidden, 1, 1.0, &mut rng);
        let log_std = [pp.init_log_std as f32; MOVE_DIM];
        let model = ActorCritic::from_plain(&actor, &critic, log_std, device);
        let ppo = Ppo::new(pp.clone(), model, device.clone());
        let workers = make_workers(&cfg, &world, &rsrp, &pool)?;
        Ok(Trainer {
            obs_norm: ObsNormalizer::new(obs_dim, pp.normalize_obs, pp.obs_clip),
            reward_scaler: RewardScaler::new(pp.normalize_reward, pp.gamma, pp.reward_clip),
            return_acc: vec![0.0; cfg.train.num_envs],
            workers,
            n_sites,
            obs_dim,
            ppo,
            update: 0,
            global_step: 0,
            episodes: 0,
            train_seconds: 0.0,
            recent: VecDeque::new(),
            cfg,
            world,
            rsrp,
        })
    }

    /// Continues a run from a checkpoint (its counters, normalisers, model and Adam state);
    /// `cfg` may raise `train.total_timesteps`.
    pub fn resume(
        cfg: Config,
        world: Arc<RadioWorld>,
        rsrp: Arc<dyn RsrpSource + Send + Sync>,
        pool: Arc<Vec<Pair>>,
        device: &burn::tensor::Device,
        ck: &LoadedCheckpoint,
    ) -> Result<Trainer, TrainError> {
        let mut t = Trainer::new(cfg, world, rsrp, pool, device)?;
        let device = &device.clone().autodiff();
        let p = &ck.meta.policy;
        if p.obs_dim != t.obs_dim || p.n_sites != t.n_sites {
            return Err(TrainError::Invalid(format!(
                "checkpoint policy has {} observations and {} site logits; this configuration gives {} and {}",
                p.obs_dim, p.n_sites, t.obs_dim, t.n_sites
            )));
        }
        let optim = burn::optim::AdamConfig::new()
            .with_epsilon(t.cfg.ppo.adam_eps as f32)
            .init();
        let (model, optim) = ck.restore(device, optim)?;
        t.ppo.model = model;
        t.ppo.optim = optim;
        t.obs_norm = p.obs_norm.clone();
        t.reward_scaler = p.reward_scaler.clone();
        if ck.meta.return_acc.len() == t.return_acc.len() {
            t.return_acc = ck.meta.return_acc.clone();
        }
        t.update = ck.meta.update;
        t.global_step = ck.meta.global_step;
        t.episodes = ck.meta.episodes;
        t.train_seconds = ck.meta.train_seconds;
        Ok(t)
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

    /// The current policy, exported (weights, log-std, normalisers, version).
    pub fn policy(&self) -> PolicyWeights {
        let (actor, critic, log_std) = self.ppo.model.to_plain();
        PolicyWeights {
            version: self.update,
            obs_dim: self.obs_dim,
            n_sites: self.n_sites,
            actor,
            critic,
            log_std,
            obs_norm: self.obs_norm.clone(),
            reward_scaler: self.reward_scaler.clone(),
        }
    }

    /// One rollout of every worker and one PPO update.
    pub fn iteration(&mut self) -> Result<IterationReport, TrainError> {
        let t0 = Instant::now();
        let policy = self.policy();
        let (seed, update) = (self.cfg.train.seed, self.update);
        let steps = self.cfg.train.num_steps;
        for (k, w) in self.workers.iter_mut().enumerate() {
            w.reseed(stream_seed(seed, k as u64, update));
        }
        let trajs: Vec<EnvTrajectory> = self
            .workers
            .par_iter_mut()
            .map(|w| w.collect(&policy, steps))
            .collect::<Result<_, _>>()?;
        let rollout_s = t0.elapsed().as_secs_f64();
        let batch = self.assemble(&policy, &trajs);
        for tr in &trajs {
            for e in &tr.episodes {
                self.recent.push_back(e.clone());
                if self.recent.len() > RECENT_EPISODES {
                    self.recent.pop_front();
                }
                self.episodes += 1;
            }
        }
        // The next policy's observation statistics include this batch.
        if self.obs_norm.enabled {
            for tr in &trajs {
                self.obs_norm.stats.update(&tr.obs);
            }
        }
        let frac = 1.0 - self.update as f64 / self.num_updates() as f64;
        let lr = if self.cfg.ppo.anneal_lr {
            frac * self.cfg.ppo.learning_rate
        } else {
            self.cfg.ppo.learning_rate
        };
        let mut rng = ChaCha8Rng::seed_from_u64(stream_seed(seed, u64::MAX, update));
        let t1 = Instant::now();
        let stats = self.ppo.update(&batch, lr, &mut rng);
        let update_s = t1.elapsed().as_secs_f64();
        self.update += 1;
        self.global_step += batch.len() as u64;
        let elapsed = t0.elapsed().as_secs_f64();
        self.train_seconds += elapsed;

        let mut row = MetricsRow::new();
        let mut put = |k: &str, v: f64| {
            row.insert(k.to_string(), v);
        };
        put("global_step", self.global_step as f64);
        put("update", self.update as f64);
        put("time_s", self.train_seconds);
        put("charts/SPS", batch.len() as f64 / elapsed);
        put("charts/rollout_s", rollout_s);
        put("charts/update_s", update_s);
        put("charts/learning_rate", lr);
        put("losses/policy_loss", stats.policy_loss);
        put("losses/value_loss", stats.value_loss);
        put("losses/entropy", stats.entropy);
        put("losses/entropy_move", stats.entropy_move);
        put("losses/entropy_site", stats.entropy_site);
        put("losses/old_approx_kl", stats.old_approx_kl);
        put("losses/approx_kl", stats.approx_kl);
        put("losses/clipfrac", stats.clipfrac);
        put("losses/explained_variance", stats.explained_variance);
        put("losses/grad_norm", stats.grad_norm);
        put("losses/skipped_nonfinite", stats.skipped_nonfinite as f64);
        let recent: Vec<EpisodeSummary> = self.recent.iter().cloned().collect();
        let d = domain_stats(&recent);
        put("charts/episodic_return", d.episodic_return);
        put("charts/episodic_length", d.episodic_length);
        put_domain(&mut row, "domain", &d);
        Ok(IterationReport { stats, row })
    }

    /// Reward scaling per stream, GAE per stream, observations normalised with the statistics
    /// the acting policy used, flattened.
    fn assemble(&mut self, policy: &PolicyWeights, trajs: &[EnvTrajectory]) -> Batch {
        let (gamma, lambda) = (self.cfg.ppo.gamma, self.cfg.ppo.gae_lambda);
        // Discounted returns per stream update the reward scaler first (CleanRL's wrapper does
        // this step by step; here per batch, in the same order).
        let mut scaled: Vec<Vec<f32>> = Vec::with_capacity(trajs.len());
        let mut returns_seen = Vec::new();
        for tr in trajs {
            let n_acc = self.return_acc.len();
            let acc = &mut self.return_acc[tr.env as usize % n_acc];
            for t in 0..tr.len() {
                *acc = *acc * gamma + f64::from(tr.rewards[t]);
                returns_seen.push(*acc);
                if tr.terminated[t] || tr.truncated[t] {
                    *acc = 0.0;
                }
            }
        }
        if self.reward_scaler.enabled {
            self.reward_scaler.stats.update(&returns_seen);
        }
        for tr in trajs {
            scaled.push(
                tr.rewards
                    .iter()
                    .map(|&r| self.reward_scaler.scale(f64::from(r)) as f32)
                    .collect(),
            );
        }
        let mut batch = Batch {
            obs_dim: self.obs_dim,
            ..Batch::default()
        };
        let mut norm = vec![0.0f32; self.obs_dim];
        for (tr, rewards) in trajs.iter().zip(&scaled) {
            let (adv, ret) = gae(
                Trajectory {
                    rewards,
                    values: &tr.values,
                    next_values: &tr.next_values,
                    terminated: &tr.terminated,
                    truncated: &tr.truncated,
                },
                gamma,
                lambda,
            );
            for row in tr.obs.chunks_exact(self.obs_dim) {
                policy.obs_norm.apply(row, &mut norm);
                batch.obs.extend_from_slice(&norm);
            }
            batch.moves.extend_from_slice(&tr.moves);
            batch.sites.extend(tr.sites.iter().map(|&s| i64::from(s)));
            batch.logprobs.extend_from_slice(&tr.logprobs);
            batch.values.extend_from_slice(&tr.values);
            batch.advantages.extend(adv);
            batch.returns.extend(ret);
        }
        batch
    }

    /// Flies `pairs` with the current deterministic policy.
    pub fn evaluate(&self, pairs: &[Pair]) -> Result<Vec<EpisodeSummary>, TrainError> {
        evaluate(&self.cfg, &self.world, &self.rsrp, &self.policy(), pairs)
    }

    /// Writes a checkpoint atomically.
    pub fn save(&self, path: &Path) -> Result<(), TrainError> {
        let meta = CheckpointMeta {
            seed: self.cfg.train.seed,
            update: self.update,
            global_step: self.global_step,
            episodes: self.episodes,
            train_seconds: self.train_seconds,
            config_toml: self.cfg.to_toml_string(),
            policy: self.policy(),
            return_acc: self.return_acc.clone(),
        };
        save_checkpoint(path, &meta, &self.ppo.model, &self.ppo.optim)?;
        Ok(())
    }

    pub fn model(&self) -> &ActorCritic {
        &self.ppo.model
    }
}

/// Adds the domain statistics under `prefix/…`.
pub fn put_domain(row: &mut MetricsRow, prefix: &str, d: &DomainStats) {
    let mut put = |k: &str, v: f64| {
        row.insert(format!("{prefix}/{k}"), v);
    };
    put("episodes", d.episodes as f64);
    put("success_rate", d.success_rate);
    put("collision_rate", d.collision_rate);
    put("out_of_bounds_rate", d.out_of_bounds_rate);
    put("timeout_rate", d.timeout_rate);
    put("mean_rsrp_dbm", d.mean_rsrp_dbm);
    put("pct_excellent", d.pct_excellent);
    put("pct_mediocre", d.pct_mediocre);
    put("pct_poor", d.pct_poor);
    put("handovers_per_km", d.handovers_per_km);
    put("distance_overhead", d.distance_overhead);
}

fn make_workers(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &Arc<dyn RsrpSource + Send + Sync>,
    pool: &Arc<Vec<Pair>>,
) -> Result<Vec<Worker>, TrainError> {
    (0..cfg.train.num_envs)
        .map(|k| {
            let env = Env::new(cfg, world.clone(), rsrp.clone())?;
            Ok(Worker::new(
                k as u32,
                env,
                pool.clone(),
                stream_seed(cfg.train.seed, k as u64, u64::MAX),
            )?)
        })
        .collect()
}
