//! Batch assembly: one update's segments (each an environment's trajectory with the actor and the
//! policy version that acted) into the flat [`Batch`] PPO trains on. In order:
//!
//! 1. [`scale_returns`]: each (actor, environment) stream's running discounted return, per step,
//!    updates the reward scaler (CleanRL's wrapper does this step by step; here per batch, in the
//!    same order);
//! 2. [`SiteRows::of`]: which site rows the site head learns from (none, every site's decision
//!    reward, or every step's site features and rewards under `env.site_every_step`);
//! 3. [`evaluate`]: the network evaluations of each segment, in parallel: the proximal
//!    log-probs of data acted with an older version (the decoupled correction) and the last
//!    step's bootstrap value under the current critic;
//! 4. per segment, appended in order: rewards scaled, GAE ([`crate::gae`]), observations
//!    normalised with the statistics of the current policy (the site features raw), the site
//!    rows (rewards scaled), the log-probs with the importance weights of older data (capped at
//!    `distributed.max_importance_weight`), moves, sites, values, advantages and returns.

use crate::gae::{Trajectory, gae};
use crate::ppo::Batch;
use dupac_common::config::{Config, SiteGradient};
use dupac_common::ids::ActorId;
use dupac_common::msg::EnvTrajectory;
use dupac_common::normalize::RewardScaler;
use dupac_common::policy::{MOVE_DIM, PolicyWeights, Scratch};
use rayon::prelude::*;
use std::collections::BTreeMap;

/// One environment's trajectory handed to [`crate::learner::Learner::learn`], with where it came from.
#[derive(Debug, Clone, Copy)]
pub struct Segment<'a> {
    /// The actor process (the synchronous trainer is actor 0).
    pub actor: ActorId,
    /// Version of the policy that acted.
    pub behaviour_version: u64,
    pub traj: &'a EnvTrajectory,
}

/// What assembly reads of the learner (shapes, configuration) and updates (reward scaling).
pub struct Assembler<'a> {
    pub cfg: &'a Config,
    /// Observation length.
    pub obs_dim: usize,
    /// Observation values the MLPs read (normalised); the rest are the site features (raw).
    pub trunk_dim: usize,
    /// Learned sites (0: the site is not the policy's to choose).
    pub n_sites: usize,
    pub reward_scaler: &'a mut RewardScaler,
    /// Running discounted return per (actor, environment) stream.
    pub return_acc: &'a mut BTreeMap<(ActorId, u32), f64>,
}

/// An assembled batch with the number of its samples acted with an older policy version.
pub struct Assembled {
    pub batch: Batch,
    pub off_policy_samples: u64,
}

/// Which site rows the batch carries (`ppo.site_gradient`, `env.site_every_step`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SiteRows {
    /// The all-sites gradient: the ratio covers the move alone, the site head learns from every
    /// site's reward.
    pub all_sites: bool,
    /// Of those, one row per step of each decision (every segment records them).
    pub per_step: bool,
}

/// The network evaluations of one segment: proximal log-probs of what the ratio covers (data
/// acted with an older version, with the decoupled correction on) and the value of the last
/// step's bootstrap observation (when it neither terminated nor was truncated).
struct Evaluated {
    prox: Option<Vec<f32>>,
    boot: Option<f32>,
}

impl Assembler<'_> {
    /// The batch of `segments`; `policy` is the current one (the proximal policy of the
    /// decoupled correction, and the source of the observation statistics).
    pub fn assemble(&mut self, policy: &PolicyWeights, segments: &[Segment<'_>]) -> Assembled {
        scale_returns(
            self.reward_scaler,
            self.return_acc,
            self.cfg.ppo.gamma,
            segments,
        );
        let rows = SiteRows::of(self.cfg, self.n_sites, segments);
        let mut batch = Batch {
            obs_dim: self.obs_dim,
            n_sites: if rows.all_sites { self.n_sites } else { 0 },
            step_offsets: if rows.per_step { vec![0] } else { Vec::new() },
            ..Batch::default()
        };
        let evals = evaluate(
            policy,
            segments,
            self.obs_dim,
            rows,
            self.cfg.distributed.decoupled_correction,
        );
        let mut norm = vec![0.0f32; self.obs_dim];
        let mut any_off_policy = false;
        let mut off_policy_samples = 0;
        for (seg, eval) in segments.iter().zip(evals) {
            let tr = seg.traj;
            let n = tr.len();
            let (adv, ret) = self.advantages(seg, eval.boot);
            self.push_observations(&mut batch, policy, seg, &mut norm);
            let behaviour = behaviour_logprobs(seg, rows);
            self.push_site_rows(&mut batch, seg, rows);
            if eval.prox.is_some() {
                any_off_policy = true;
                off_policy_samples += n as u64;
            }
            self.push_logprobs(&mut batch, eval.prox, behaviour);
            batch.moves.extend_from_slice(&tr.moves);
            batch.sites.extend(tr.sites.iter().map(|&s| i64::from(s)));
            batch.values.extend_from_slice(&tr.values);
            batch.advantages.extend(adv);
            batch.returns.extend(ret);
        }
        if !any_off_policy {
            batch.is_weights.clear();
        }
        Assembled {
            batch,
            off_policy_samples,
        }
    }

    /// GAE of one segment on its scaled rewards, the last step bootstrapping from `boot` (the
    /// current critic's value; identical for data of the current version, better for older
    /// data) where there is one.
    fn advantages(&self, seg: &Segment<'_>, boot: Option<f32>) -> (Vec<f32>, Vec<f32>) {
        let tr = seg.traj;
        let n = tr.len();
        let rewards: Vec<f32> = tr
            .rewards
            .iter()
            .map(|&r| self.reward_scaler.scale(f64::from(r)) as f32)
            .collect();
        let mut next_values = tr.next_values.clone();
        if let Some(v) = boot {
            next_values[n - 1] = v;
        }
        gae(
            Trajectory {
                rewards: &rewards,
                values: &tr.values,
                next_values: &next_values,
                terminated: &tr.terminated,
                truncated: &tr.truncated,
            },
            self.cfg.ppo.gamma,
            self.cfg.ppo.gae_lambda,
        )
    }

    /// The segment's observations normalised with `policy`'s statistics; the site features are
    /// kept raw (fixed scales), as the actors read them. `norm` is scratch of `obs_dim` values.
    fn push_observations(
        &self,
        batch: &mut Batch,
        policy: &PolicyWeights,
        seg: &Segment<'_>,
        norm: &mut [f32],
    ) {
        let trunk = self.trunk_dim;
        for row in seg.traj.obs.chunks_exact(self.obs_dim) {
            policy.obs_norm.apply(row, norm);
            norm[trunk..].copy_from_slice(&row[trunk..]);
            batch.obs.extend_from_slice(norm);
        }
    }

    /// The segment's site rows, rewards scaled like the rewards: every step's (per-step rows,
    /// with the decision's step offsets) or every site's decision reward.
    fn push_site_rows(&self, batch: &mut Batch, seg: &Segment<'_>, rows: SiteRows) {
        let tr = seg.traj;
        if rows.per_step {
            let mut end = batch.step_offsets.last().copied().unwrap_or(0);
            for &k in &tr.decision_steps {
                end += usize::from(k);
                batch.step_offsets.push(end);
            }
            batch
                .step_site_features
                .extend_from_slice(&tr.step_site_features);
            batch.step_site_rewards.extend(
                tr.step_site_rewards
                    .iter()
                    .map(|&r| self.reward_scaler.scale(f64::from(r)) as f32),
            );
        } else if rows.all_sites {
            batch.site_rewards.extend(
                tr.site_rewards
                    .iter()
                    .map(|&r| self.reward_scaler.scale(f64::from(r)) as f32),
            );
        }
    }

    /// The log-probs the ratio starts from: the proximal ones with their importance weights
    /// `min(π_prox / μ, distributed.max_importance_weight)` for older data, else the behaviour
    /// ones with weight 1.
    fn push_logprobs(&self, batch: &mut Batch, prox: Option<Vec<f32>>, behaviour: Vec<f32>) {
        match &prox {
            Some(prox) => {
                for (&p, &b) in prox.iter().zip(&behaviour) {
                    let w = (f64::from(p) - f64::from(b))
                        .exp()
                        .min(self.cfg.distributed.max_importance_weight);
                    batch.logprobs.push(p);
                    batch.is_weights.push(w as f32);
                }
            }
            None => {
                let n = behaviour.len();
                batch.logprobs.extend_from_slice(&behaviour);
                batch.is_weights.extend(std::iter::repeat_n(1.0, n));
            }
        }
    }
}

/// Updates each (actor, environment) stream's running discounted return with every step's reward
/// (reset after an episode's end) and the reward scaler's statistics with those returns, in
/// segment and step order.
pub fn scale_returns(
    scaler: &mut RewardScaler,
    return_acc: &mut BTreeMap<(ActorId, u32), f64>,
    gamma: f64,
    segments: &[Segment<'_>],
) {
    let mut returns_seen = Vec::new();
    for seg in segments {
        let tr = seg.traj;
        let acc = return_acc.entry((seg.actor, tr.env)).or_insert(0.0);
        for t in 0..tr.len() {
            *acc = *acc * gamma + f64::from(tr.rewards[t]);
            returns_seen.push(*acc);
            if tr.terminated[t] || tr.truncated[t] {
                *acc = 0.0;
            }
        }
    }
    if scaler.enabled {
        scaler.stats.update(&returns_seen);
    }
}

impl SiteRows {
    /// The rows of `segments` for `n_sites` learned sites: all-sites when `ppo.site_gradient =
    /// "all_sites"` and every segment records every site's reward per decision; per-step when
    /// every segment records the steps of each decision (`env.site_every_step`).
    pub fn of(cfg: &Config, n_sites: usize, segments: &[Segment<'_>]) -> SiteRows {
        let per_step = cfg.ppo.site_gradient == SiteGradient::AllSites
            && n_sites > 0
            && !segments.is_empty()
            && segments
                .iter()
                .all(|s| s.traj.decision_steps.len() == s.traj.len());
        let all_sites = per_step
            || (cfg.ppo.site_gradient == SiteGradient::AllSites
                && n_sites > 0
                && segments
                    .iter()
                    .all(|s| s.traj.site_rewards.len() == s.traj.len() * n_sites));
        if cfg.env.site_every_step
            && cfg.env.association == dupac_common::config::Association::Learned
            && !segments.is_empty()
            && !per_step
        {
            tracing::error!(
                "env.site_every_step is on but the trajectories carry no per-step site rows: the site head learns from decision rows or not at all"
            );
        }
        SiteRows {
            all_sites,
            per_step,
        }
    }
}

/// The network evaluations of every segment (independent per segment: in parallel).
fn evaluate(
    policy: &PolicyWeights,
    segments: &[Segment<'_>],
    obs_dim: usize,
    rows: SiteRows,
    decoupled_correction: bool,
) -> Vec<Evaluated> {
    segments
        .par_iter()
        .map(|seg| {
            let tr = seg.traj;
            let n = tr.len();
            let mut scratch = Scratch::default();
            let off_policy = seg.behaviour_version != policy.version && decoupled_correction;
            let prox = off_policy.then(|| {
                tr.obs
                    .chunks_exact(obs_dim)
                    .enumerate()
                    .map(|(t, row)| {
                        let mut m = [0.0f32; MOVE_DIM];
                        m.copy_from_slice(&tr.moves[t * MOVE_DIM..(t + 1) * MOVE_DIM]);
                        let (lp_move, lp_site) =
                            policy.logprob_parts(row, &m, tr.sites[t], &mut scratch);
                        if rows.all_sites {
                            lp_move
                        } else {
                            lp_move + lp_site
                        }
                    })
                    .collect()
            });
            let boot = (n > 0
                && !tr.terminated[n - 1]
                && !tr.truncated[n - 1]
                && tr.bootstrap_obs.len() == obs_dim)
                .then(|| policy.value(&tr.bootstrap_obs, &mut scratch));
            Evaluated { prox, boot }
        })
        .collect()
}

/// Behaviour log-probs of what the ratio covers: the move's and the site's together, or the
/// move's alone under the all-sites gradient.
fn behaviour_logprobs(seg: &Segment<'_>, rows: SiteRows) -> Vec<f32> {
    let tr = seg.traj;
    if rows.all_sites {
        tr.logprobs
            .iter()
            .zip(&tr.site_logprobs)
            .map(|(&j, &k)| j - k)
            .collect()
    } else {
        tr.logprobs.clone()
    }
}
