//! `[ppo]` (the update and its site head) and `[train]` (the run).

use super::ConfigError;
#[allow(unused_imports)]
use super::check::*;
use serde::{Deserialize, Serialize};
#[allow(unused_imports)]
use std::path::PathBuf;

use super::{Association, EnvConfig};

/// The network that scores sites (see [`PpoConfig::site_head`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SiteHead {
    /// M logits of the actor MLP, one per slot (the paper).
    Slots,
    /// A per-site MLP shared by all sites over their own features and a state embedding.
    Equivariant,
}

/// The estimator of the site head's gradient (see [`PpoConfig::site_gradient`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SiteGradient {
    /// PPO on the sampled site, one joint ratio with the move (the paper).
    Sampled,
    /// Σ_k ∇π(k|s) · A_k over every site k, with A_k from each site's own decision reward.
    AllSites,
}

/// PPO hyperparameters (paper Sec. IV-A for lr, γ, ε; the rest CleanRL's
/// `ppo_continuous_action.py` defaults unless noted).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PpoConfig {
    /// Adam learning rate (paper: 3e-4).
    pub learning_rate: f64,
    /// Linear annealing of the learning rate to 0 over the run.
    pub anneal_lr: bool,
    /// Discount γ (paper: 0.95).
    pub gamma: f64,
    /// GAE λ.
    pub gae_lambda: f64,
    /// Minibatches per epoch (minibatch = num_envs × num_steps / num_minibatches).
    pub num_minibatches: usize,
    /// Epochs over each batch.
    pub update_epochs: usize,
    /// Normalise advantages per minibatch.
    pub norm_adv: bool,
    /// Clip ε of the surrogate (paper: 0.2).
    pub clip_coef: f64,
    /// Clip the value loss like the surrogate.
    pub clip_vloss: bool,
    /// Entropy bonus of the move Gaussian.
    pub ent_coef_move: f64,
    /// Entropy bonus of the site categorical.
    pub ent_coef_site: f64,
    /// Weight of the value loss.
    pub vf_coef: f64,
    /// Global gradient-norm clip (over both networks and the log-std).
    pub max_grad_norm: f64,
    /// Stop the epochs of an update early when the approximate KL exceeds this (0 = off).
    pub target_kl: f64,
    /// Adam ε.
    pub adam_eps: f64,
    /// Hidden layer widths of both MLPs.
    pub hidden: Vec<usize>,
    /// The site head: `slots` = M logits of the actor MLP (the paper), `equivariant` = one small
    /// network shared by all sites scoring each from its own features.
    pub site_head: SiteHead,
    /// How the site head learns: `sampled` = the paper's PPO on the sampled site (one joint ratio
    /// and clip with the move), `all_sites` = the exact expected gradient over every site's
    /// reward (the environment evaluates all of them), apart from the move's ratio and clip.
    pub site_gradient: SiteGradient,
    /// Width of the state embedding the equivariant head appends to each site's features.
    pub site_embed: usize,
    /// Hidden widths of the equivariant head's per-site MLP.
    pub site_hidden: Vec<usize>,
    /// Weight of the all-sites loss (`site_gradient = "all_sites"`).
    pub site_coef: f64,
    /// Initial log-std of the move Gaussian.
    pub init_log_std: f64,
    /// Normalise observations by running mean/variance, clipped to ±obs_clip.
    pub normalize_obs: bool,
    /// Normalised observations are clipped to ±obs_clip.
    pub obs_clip: f64,
    /// Scale rewards by the running std of the discounted return, clipped to ±reward_clip.
    pub normalize_reward: bool,
    /// Scaled rewards are clipped to ±reward_clip.
    pub reward_clip: f64,
    /// Consecutive updates skipped for numerical faults (a non-finite observation, reward or
    /// value in the batch, or non-finite weights after the update) before the run stops with an
    /// error; 0 = never stop. A skipped update leaves the weights, optimiser and normalisers as
    /// they were (docs/reliability.md).
    pub max_bad_updates: u32,
}

impl Default for PpoConfig {
    fn default() -> Self {
        Self {
            learning_rate: 3e-4,
            anneal_lr: true,
            gamma: 0.95,
            gae_lambda: 0.95,
            num_minibatches: 8,
            update_epochs: 4,
            norm_adv: true,
            clip_coef: 0.2,
            clip_vloss: true,
            ent_coef_move: 0.0,
            ent_coef_site: 0.001,
            vf_coef: 0.5,
            max_grad_norm: 0.5,
            target_kl: 0.0,
            adam_eps: 1e-5,
            hidden: vec![256, 256],
            site_head: SiteHead::Equivariant,
            site_gradient: SiteGradient::AllSites,
            site_embed: 16,
            site_hidden: vec![32],
            site_coef: 1.0,
            init_log_std: 0.0,
            normalize_obs: true,
            obs_clip: 10.0,
            normalize_reward: true,
            reward_clip: 10.0,
            max_bad_updates: 5,
        }
    }
}

/// The training run (`dupac train`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Seed of the run: network init, action sampling, episode pairs and resets.
    pub seed: u64,
    /// Total timesteps (samples): decisions of the policy, each `env.action_repeat` steps of the
    /// environment.
    pub total_timesteps: u64,
    /// Parallel environments (stepped on worker threads).
    pub num_envs: usize,
    /// Decisions per environment per rollout (batch = num_envs × num_steps).
    pub num_steps: usize,
    /// Training pairs in the pool episodes are drawn from (`pairs.min_m..max_m`).
    pub pool_size: usize,
    /// Output directory: checkpoints, metrics, curves, exported policy.
    pub out_dir: PathBuf,
    /// Write a checkpoint every this many updates (and at the end).
    pub checkpoint_every: u64,
    /// Evaluate the deterministic policy on `eval_pairs` held-out pairs every this many updates
    /// (0 = only at the end).
    pub eval_every: u64,
    /// Held-out pairs of each evaluation during training (spread over the bins).
    pub eval_pairs: usize,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            total_timesteps: 4_000_000,
            num_envs: 16,
            num_steps: 256,
            pool_size: 2000,
            out_dir: "out/train".into(),
            checkpoint_every: 10,
            eval_every: 25,
            eval_pairs: 70,
        }
    }
}

impl PpoConfig {
    /// Checks `[ppo]` against `[env]`.
    pub(crate) fn validate(&self, e: &EnvConfig) -> Result<(), ConfigError> {
        let o = &e.observation;
        let pp = self;
        positive("ppo.learning_rate", pp.learning_rate)?;
        for (k, v) in [("ppo.gamma", pp.gamma), ("ppo.gae_lambda", pp.gae_lambda)] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(bad(k, format!("must be in [0, 1], got {v}")));
            }
        }
        if pp.num_minibatches == 0 {
            return Err(bad("ppo.num_minibatches", "must be >= 1"));
        }
        if pp.update_epochs == 0 {
            return Err(bad("ppo.update_epochs", "must be >= 1"));
        }
        positive("ppo.clip_coef", pp.clip_coef)?;
        for (k, v) in [
            ("ppo.ent_coef_move", pp.ent_coef_move),
            ("ppo.ent_coef_site", pp.ent_coef_site),
            ("ppo.vf_coef", pp.vf_coef),
            ("ppo.target_kl", pp.target_kl),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(k, format!("must be a finite number >= 0, got {v}")));
            }
        }
        positive("ppo.max_grad_norm", pp.max_grad_norm)?;
        positive("ppo.adam_eps", pp.adam_eps)?;
        if pp.hidden.is_empty() || pp.hidden.iter().any(|&h| h == 0 || h > 65_536) {
            return Err(bad("ppo.hidden", "must list 1 or more widths in 1..=65536"));
        }
        if pp.site_head == SiteHead::Equivariant
            && e.association == Association::Learned
            && !o.site_features
        {
            return Err(bad(
                "ppo.site_head",
                "\"equivariant\" scores sites from env.observation.site_features: set it to true, or use \"slots\"",
            ));
        }
        if e.reward.ping_pong_reward != 0.0
            && e.association == Association::Learned
            && !o.site_ping_pong
        {
            return Err(bad(
                "env.reward.ping_pong_reward",
                "the learned site must see which site would be a ping-pong: set env.observation.site_ping_pong = true (and env.observation.site_features), or the cost to 0",
            ));
        }
        if e.site_every_step && e.association == Association::Learned {
            let need = [
                (
                    pp.site_head != SiteHead::Equivariant,
                    "ppo.site_head = \"equivariant\"",
                ),
                (
                    pp.site_gradient != SiteGradient::AllSites,
                    "ppo.site_gradient = \"all_sites\"",
                ),
            ];
            if let Some((_, what)) = need.iter().find(|(missing, _)| *missing) {
                return Err(bad(
                    "env.site_every_step",
                    format!(
                        "a site chosen every step needs {what} (the site is chosen every step by default; set env.site_every_step = false to hold it for a decision, as the paper does)"
                    ),
                ));
            }
        }
        if !(1..=1024).contains(&pp.site_embed) {
            return Err(bad("ppo.site_embed", "must be in 1..=1024"));
        }
        if pp.site_hidden.is_empty() || pp.site_hidden.iter().any(|&h| h == 0 || h > 4096) {
            return Err(bad(
                "ppo.site_hidden",
                "must list 1 or more widths in 1..=4096",
            ));
        }
        if !(pp.site_coef.is_finite() && pp.site_coef >= 0.0) {
            return Err(bad("ppo.site_coef", "must be a finite number >= 0"));
        }
        finite("ppo.init_log_std", pp.init_log_std)?;
        positive("ppo.obs_clip", pp.obs_clip)?;
        positive("ppo.reward_clip", pp.reward_clip)?;
        Ok(())
    }

    /// Upper bounds of `[ppo]` values that size time or memory.
    pub(crate) fn validate_bounds(&self) -> Result<(), ConfigError> {
        let pp = self;
        at_most("ppo.update_epochs", pp.update_epochs as u64, 1_000)?;
        at_most("ppo.hidden", pp.hidden.len() as u64, 16).map_err(|_| ConfigError::Invalid {
            key: "ppo.hidden".into(),
            message: format!("at most 16 layers, got {}", pp.hidden.len()),
        })?;
        if let Some(&h) = pp.hidden.iter().find(|&&h| h > 4096) {
            return Err(ConfigError::Invalid {
                key: "ppo.hidden".into(),
                message: format!("widths must be at most 4096, got {h}"),
            });
        }
        let weights: usize = pp.hidden.windows(2).map(|w| w[0] * w[1]).sum();
        if weights > 16 << 20 {
            return Err(ConfigError::Invalid {
                key: "ppo.hidden".into(),
                message: format!(
                    "{weights} hidden-to-hidden weights per network, at most {}",
                    16 << 20
                ),
            });
        }
        Ok(())
    }
}

impl TrainConfig {
    /// Checks `[train]` against `[ppo]`.
    pub(crate) fn validate(&self, pp: &PpoConfig) -> Result<(), ConfigError> {
        let t = self;
        if t.num_envs == 0 || t.num_envs > 4096 {
            return Err(bad("train.num_envs", "must be in 1..=4096"));
        }
        if t.num_steps == 0 {
            return Err(bad("train.num_steps", "must be >= 1"));
        }
        let Some(batch) = t.num_envs.checked_mul(t.num_steps) else {
            return Err(bad(
                "train.num_steps",
                "train.num_envs × train.num_steps overflows",
            ));
        };
        if !batch.is_multiple_of(pp.num_minibatches) || batch < pp.num_minibatches {
            return Err(bad(
                "ppo.num_minibatches",
                format!("must divide the batch train.num_envs × train.num_steps = {batch}"),
            ));
        }
        if t.pool_size == 0 {
            return Err(bad("train.pool_size", "must be >= 1"));
        }
        if t.checkpoint_every == 0 {
            return Err(bad("train.checkpoint_every", "must be >= 1"));
        }
        Ok(())
    }
}
