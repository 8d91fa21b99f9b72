//! The PPO update, readable top to bottom like CleanRL's `ppo_continuous_action.py`:
//! epochs × shuffled minibatches, per-minibatch advantage normalisation, clipped surrogate,
//! clipped value loss, separately weighted entropy bonuses of the move and site heads, Adam with a
//! caller-annealed learning rate, *global* gradient-norm clipping, optional target-KL early stop.
//!
//! The site head learns in one of two ways (`ppo.site_gradient`):
//! - `sampled` (the paper): the site's log-prob joins the move's in one ratio and one clip;
//! - `all_sites`: the move alone is PPO's ratio and clip; the site head minimises
//!   `−site_coef · mean_b Σ_k π(k|s_b) · Â_{b,k}` with `Â_{b,k}` the decision reward of site k
//!   (every site's is recorded, the site not changing the flight) minus the best, normalised per
//!   minibatch: the exact expected gradient Σ_k ∇π(k|s) A_k of the decision's reward, with no
//!   sampling noise, no ratio and nothing to explore (so no site entropy bonus). It is myopic:
//!   the site's later effect (the next decision's handover cost) is not in Â.
//!
//! The update does not care where the batch came from (one process or many actors).

use crate::model::{ActorCritic, Evaluated, tensor_to_vec};
use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams, ModuleOptimizer};
use burn::tensor::{Device, Int, Tensor, TensorData};
use dupac_common::config::{PpoConfig, SiteGradient};
use dupac_common::policy::MOVE_DIM;
use rand::RngExt;
use rand::seq::SliceRandom;

/// A batch of samples, flat (`len` rows), observations already normalised with the statistics
/// the acting policy used.
#[derive(Debug, Clone, Default)]
pub struct Batch {
    pub obs_dim: usize,
    /// `[len × obs_dim]`.
    pub obs: Vec<f32>,
    /// Unclipped moves `[len × 3]`.
    pub moves: Vec<f32>,
    /// Site indices `[len]` (0 without a site head).
    pub sites: Vec<i64>,
    /// log π_old(a|s) `[len]`: of the move and site together, or of the move alone when
    /// `site_rewards` is not empty (the all-sites gradient).
    pub logprobs: Vec<f32>,
    /// Every site's decision reward, scaled like the rewards, `[len × n_sites]`; empty unless
    /// the site head learns from all sites.
    pub site_rewards: Vec<f32>,
    /// Sites per row of `site_rewards` (and of the per-step rows).
    pub n_sites: usize,
    /// With `env.site_every_step`: decision i's steps are the rows
    /// `step_offsets[i]..step_offsets[i + 1]` (`len + 1` entries; empty otherwise) of each
    /// step's raw site features `[R × n_sites·F]` and every site's reward of that step, scaled
    /// like the rewards, `[R × n_sites]`; the site head learns from those rows instead of
    /// `site_rewards`.
    pub step_offsets: Vec<usize>,
    pub step_site_features: Vec<f32>,
    pub step_site_rewards: Vec<f32>,
    /// V_old(s) `[len]`.
    pub values: Vec<f32>,
    pub advantages: Vec<f32>,
    pub returns: Vec<f32>,
    /// Decoupled-PPO importance weights π_prox / π_behaviour `[len]` (Hilton et al. 2021),
    /// applied to the normalised advantages; empty means all 1 (on-policy data, where
    /// `logprobs` are the behaviour policy's).
    pub is_weights: Vec<f32>,
}

impl Batch {
    pub fn len(&self) -> usize {
        self.logprobs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.logprobs.is_empty()
    }

    /// Whether the per-step site rows are present and consistent for `features` values per
    /// site (`env.site_every_step`).
    pub fn per_step_rows(&self, features: usize) -> bool {
        let m = self.n_sites;
        let r = self.step_offsets.last().copied().unwrap_or(0);
        m > 0
            && features > 0
            && self.step_offsets.len() == self.len() + 1
            && self.step_offsets.windows(2).all(|w| w[0] <= w[1])
            && self.step_site_rewards.len() == r * m
            && self.step_site_features.len() == r * m * features
    }
}

/// What one update reports, with the metric names RL users know (CleanRL's `losses/*`).
#[derive(Debug, Clone, Default, serde::Serialize)]
pub struct UpdateStats {
    pub policy_loss: f64,
    pub value_loss: f64,
    /// Total entropy (move + site), mean over the last epoch.
    pub entropy: f64,
    pub entropy_move: f64,
    pub entropy_site: f64,
    /// All-sites loss `−mean_b Σ_k π(k|s_b) Â_{b,k}` (0 under the sampled estimator).
    pub site_loss: f64,
    /// Mean over the batch of the policy's expected decision-reward regret of its site choice,
    /// Σ_k π(k|s)(max_j r_j − r_k) in raw reward units, before the update (NaN when not
    /// learned from all sites).
    pub site_expected_regret: f64,
    pub old_approx_kl: f64,
    pub approx_kl: f64,
    pub clipfrac: f64,
    pub explained_variance: f64,
    /// Global gradient norm before clipping, mean over minibatches.
    pub grad_norm: f64,
    pub epochs: usize,
    pub minibatches: usize,
    /// Minibatches whose loss or gradient was not finite: skipped, weights untouched.
    pub skipped_nonfinite: usize,
    pub learning_rate: f64,
}

impl UpdateStats {
    /// The statistics of an update skipped for a numerical fault: no losses (NaN, written as
    /// `null` in metrics.jsonl), the learning rate it would have used.
    pub fn skipped(learning_rate: f64) -> UpdateStats {
        UpdateStats {
            policy_loss: f64::NAN,
            value_loss: f64::NAN,
            entropy: f64::NAN,
            entropy_move: f64::NAN,
            entropy_site: f64::NAN,
            site_loss: f64::NAN,
            site_expected_regret: f64::NAN,
            old_approx_kl: f64::NAN,
            approx_kl: f64::NAN,
            clipfrac: f64::NAN,
            explained_variance: f64::NAN,
            grad_norm: f64::NAN,
            learning_rate,
            ..UpdateStats::default()
        }
    }
}

/// Clipped surrogate policy loss `mean(max(−A·ρ, −A·clip(ρ, 1 − ε, 1 + ε)))`, ρ = exp(logπ − logπ_old).
pub fn policy_loss(
    new_logprob: Tensor<1>,
    old_logprob: Tensor<1>,
    adv: Tensor<1>,
    clip: f64,
) -> (Tensor<1>, Tensor<1>) {
    let logratio = new_logprob - old_logprob;
    let ratio = logratio.clone().exp();
    let pg1 = adv.clone().neg() * ratio.clone();
    let pg2 = adv.neg() * ratio.clone().clamp(1.0 - clip, 1.0 + clip);
    (pg1.max_pair(pg2).mean(), ratio)
}

/// The all-sites site loss `−mean_b Σ_k π(k|s_b) · A_{b,k}` from log π `[B, M]` and the sites'
/// advantages `[B, M]` (constants): its gradient in the logits is the exact expected policy
/// gradient `−π_j (A_j − Σ_k π_k A_k) / B`.
pub fn all_sites_loss(site_logp: Tensor<2>, adv: Tensor<2>) -> Tensor<1> {
    (site_logp.exp() * adv).sum_dim(1).mean().neg()
}

/// Value loss `0.5 · mean(max((V − R)², (V_old + clip(V − V_old, ±ε) − R)²))`, or the
/// unclipped `0.5 · mean((V − R)²)`.
pub fn value_loss(
    new_value: Tensor<1>,
    old_value: Tensor<1>,
    returns: Tensor<1>,
    clip: Option<f64>,
) -> Tensor<1> {
    let unclipped = (new_value.clone() - returns.clone()).square();
    match clip {
        Some(eps) => {
            let clipped = old_value.clone() + (new_value - old_value).clamp(-eps, eps);
            let clipped = (clipped - returns).square();
            unclipped.max_pair(clipped).mean().mul_scalar(0.5)
        }
        None => unclipped.mean().mul_scalar(0.5),
    }
}

/// Sums the squares of every gradient of `module`'s float parameters.
struct SquaredNorm<'a> {
    grads: &'a GradientsParams,
    sum: f64,
}

impl ModuleVisitor for SquaredNorm<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.get::<D>(param.id) {
            self.sum += f64::from(g.square().sum().into_scalar::<f32>());
        }
    }
}

/// Multiplies every gradient by `scale`.
struct Scale<'a> {
    grads: &'a mut GradientsParams,
    scale: f64,
}

impl ModuleVisitor for Scale<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = self.grads.remove::<D>(param.id) {
            self.grads.register(param.id, g.mul_scalar(self.scale));
        }
    }
}

/// Global gradient-norm clipping (what `torch.nn.utils.clip_grad_norm_` does; burn's
/// `GradientClippingConfig::Norm` clips each tensor separately): if ‖g‖₂ over all parameters
/// exceeds `max_norm`, every gradient is scaled by `max_norm / ‖g‖₂`. Returns ‖g‖₂ before
/// clipping (non-finite when a gradient is).
pub fn clip_global_grad_norm<M: Module>(
    module: &M,
    grads: &mut GradientsParams,
    max_norm: f64,
) -> f64 {
    let mut sq = SquaredNorm { grads, sum: 0.0 };
    module.visit(&mut sq);
    let norm = sq.sum.sqrt();
    if norm.is_finite() && norm > max_norm {
        let mut sc = Scale {
            grads,
            scale: max_norm / (norm + 1e-6),
        };
        module.visit(&mut sc);
    }
    norm
}

/// The PPO learner state: model on an autodiff device and its Adam optimiser.
pub struct Ppo {
    pub cfg: PpoConfig,
    pub model: ActorCritic,
    pub optim: ModuleOptimizer,
    pub device: Device,
}

impl Ppo {
    /// `model` must live on `device` (an autodiff device).
    pub fn new(cfg: PpoConfig, model: ActorCritic, device: Device) -> Ppo {
        let optim = AdamConfig::new().with_epsilon(cfg.adam_eps as f32).init();
        Ppo {
            cfg,
            model,
            optim,
            device,
        }
    }

    fn t1(&self, v: Vec<f32>) -> Tensor<1> {
        let n = v.len();
        Tensor::from_data(TensorData::new(v, [n]), &self.device)
    }

    /// Runs `update_epochs` × `num_minibatches` gradient steps on `batch` at learning rate `lr`,
    /// shuffling with `rng`.
    pub fn update(&mut self, batch: &Batch, lr: f64, rng: &mut impl RngExt) -> UpdateStats {
        let n = batch.len();
        let d = batch.obs_dim;
        let mb = (n / self.cfg.num_minibatches).max(1);
        let clip = self.cfg.clip_coef;
        let mut stats = UpdateStats {
            learning_rate: lr,
            ..UpdateStats::default()
        };
        let mut order: Vec<usize> = (0..n).collect();
        let mut grad_norm_sum = 0.0;
        let m = batch.n_sites;
        let per_step = batch.per_step_rows(self.model.site_features());
        if !batch.step_offsets.is_empty() && !per_step {
            tracing::error!(
                rows = batch.step_offsets.len(),
                decisions = n,
                "per-step site rows that do not fit the batch: the site head does not learn from them"
            );
        }
        let all_sites = self.cfg.site_gradient == SiteGradient::AllSites
            && m > 0
            && (per_step || batch.site_rewards.len() == n * m);
        stats.site_expected_regret = f64::NAN;
        'epochs: for _epoch in 0..self.cfg.update_epochs {
            stats.epochs += 1;
            order.shuffle(rng);
            let mut sums = [0.0f64; 8];
            let mut count = 0usize;
            for idx in order.chunks(mb) {
                let b = idx.len();
                let mut obs = Vec::with_capacity(b * d);
                let mut moves = Vec::with_capacity(b * MOVE_DIM);
                let mut sites = Vec::with_capacity(b);
                let (mut oldlp, mut oldv, mut adv, mut ret) = (
                    Vec::with_capacity(b),
                    Vec::with_capacity(b),
                    Vec::with_capacity(b),
                    Vec::with_capacity(b),
                );
                for &i in idx {
                    obs.extend_from_slice(&batch.obs[i * d..(i + 1) * d]);
                    moves.extend_from_slice(&batch.moves[i * MOVE_DIM..(i + 1) * MOVE_DIM]);
                    sites.push(batch.sites[i]);
                    oldlp.push(batch.logprobs[i]);
                    oldv.push(batch.values[i]);
                    adv.push(batch.advantages[i]);
                    ret.push(batch.returns[i]);
                }
                if self.cfg.norm_adv && b > 1 {
                    let mean = adv.iter().map(|&a| f64::from(a)).sum::<f64>() / b as f64;
                    // torch.std is the unbiased estimate.
                    let var = adv
                        .iter()
                        .map(|&a| (f64::from(a) - mean).powi(2))
                        .sum::<f64>()
                        / (b - 1) as f64;
                    let sd = var.sqrt() + 1e-8;
                    adv.iter_mut()
                        .for_each(|a| *a = ((f64::from(*a) - mean) / sd) as f32);
                }
                // w · min(ρA, clip(ρ)A) = min(ρ(wA), clip(ρ)(wA)) for w ≥ 0.
                if !batch.is_weights.is_empty() {
                    for (a, &i) in adv.iter_mut().zip(idx) {
                        *a *= batch.is_weights[i];
                    }
                }
                let obs = Tensor::<2>::from_data(TensorData::new(obs, [b, d]), &self.device);
                let moves =
                    Tensor::<2>::from_data(TensorData::new(moves, [b, MOVE_DIM]), &self.device);
                let sites = Tensor::<1, Int>::from_data(TensorData::new(sites, [b]), &self.device);
                // The per-step rows alone teach the site head: the decision rows' site logits
                // are not computed.
                let sites = (!(all_sites && per_step)).then_some(sites);
                let Evaluated {
                    logprob,
                    logprob_move,
                    site_logp,
                    entropy_move,
                    entropy_site,
                    value,
                    actor_hidden,
                    ..
                } = self.model.evaluate_rows(obs, moves, sites);
                // Under the all-sites gradient the ratio and clip are the move's alone.
                let logprob = if all_sites { logprob_move } else { logprob };
                let oldlp = self.t1(oldlp);
                let (pg_loss, ratio) =
                    policy_loss(logprob.clone(), oldlp.clone(), self.t1(adv), clip);
                // Under per-step rows the site entropy reported is of those rows (no gradient).
                let mut step_entropy = None;
                let site_loss = match (&site_logp, all_sites) {
                    (_, true) if per_step => actor_hidden.map(|hidden| {
                        let (loss, entropy) = self.step_site_loss(batch, idx, hidden, rng);
                        step_entropy = Some(entropy);
                        loss.mul_scalar(self.cfg.site_coef)
                    }),
                    (Some(logp), true) => {
                        let a = site_advantages(&batch.site_rewards, idx, m, self.cfg.norm_adv);
                        let a = Tensor::<2>::from_data(TensorData::new(a, [b, m]), &self.device);
                        Some(all_sites_loss(logp.clone(), a).mul_scalar(self.cfg.site_coef))
                    }
                    _ => None,
                };
                let v_loss = value_loss(
                    value,
                    self.t1(oldv),
                    self.t1(ret),
                    self.cfg.clip_vloss.then_some(clip),
                );
                let ent_move = entropy_move.clone().mean();
                let ent_site = entropy_site.clone().mean();
                // The site's entropy bonus serves exploration, which the all-sites gradient
                // does not need.
                let ent_coef_site = if all_sites {
                    0.0
                } else {
                    self.cfg.ent_coef_site
                };
                let mut loss = pg_loss.clone()
                    - ent_move.clone().mul_scalar(self.cfg.ent_coef_move)
                    - ent_site.clone().mul_scalar(ent_coef_site)
                    + v_loss.clone().mul_scalar(self.cfg.vf_coef);
                let mut site_v = 0.0;
                if let Some(sl) = site_loss {
                    site_v = f64::from(sl.clone().into_scalar::<f32>());
                    loss = loss + sl;
                }

                // Diagnostics (no gradient): KL estimators of Schulman's blog, clip fraction.
                let logratio = tensor_to_vec(logprob.detach() - oldlp);
                let ratio = tensor_to_vec(ratio.detach());
                let (mut old_kl, mut kl, mut cf) = (0.0, 0.0, 0.0);
                for (lr_, r) in logratio.iter().zip(&ratio) {
                    let (lr_, r) = (f64::from(*lr_), f64::from(*r));
                    old_kl += -lr_;
                    kl += (r - 1.0) - lr_;
                    cf += f64::from(u8::from((r - 1.0).abs() > clip));
                }
                let bf = b as f64;
                let loss_v = f64::from(loss.clone().into_scalar::<f32>());
                let pg_v = f64::from(pg_loss.into_scalar::<f32>());
                let vl_v = f64::from(v_loss.into_scalar::<f32>());
                let em_v = f64::from(ent_move.into_scalar::<f32>());
                let es_v = step_entropy.unwrap_or_else(|| f64::from(ent_site.into_scalar::<f32>()));

                let grads = loss.backward();
                let mut grads = GradientsParams::from_grads(grads, &self.model);
                let norm = clip_global_grad_norm(&self.model, &mut grads, self.cfg.max_grad_norm);
                if !(loss_v.is_finite() && norm.is_finite()) {
                    stats.skipped_nonfinite += 1;
                    tracing::warn!(
                        loss = loss_v,
                        grad_norm = norm,
                        "non-finite minibatch skipped"
                    );
                    continue;
                }
                self.model = self.optim.step(lr, self.model.clone(), grads);
                stats.minibatches += 1;
                grad_norm_sum += norm;
                for (s, v) in sums.iter_mut().zip([
                    pg_v,
                    vl_v,
                    em_v,
                    es_v,
                    old_kl / bf,
                    kl / bf,
                    cf / bf,
                    site_v,
                ]) {
                    *s += v;
                }
                count += 1;
            }
            if count > 0 {
                let c = count as f64;
                stats.policy_loss = sums[0] / c;
                stats.value_loss = sums[1] / c;
                stats.entropy_move = sums[2] / c;
                stats.entropy_site = sums[3] / c;
                stats.entropy = stats.entropy_move + stats.entropy_site;
                stats.old_approx_kl = sums[4] / c;
                stats.approx_kl = sums[5] / c;
                stats.clipfrac = sums[6] / c;
                stats.site_loss = sums[7] / c;
            }
            if self.cfg.target_kl > 0.0 && stats.approx_kl > self.cfg.target_kl {
                break 'epochs;
            }
        }
        if stats.minibatches > 0 {
            stats.grad_norm = grad_norm_sum / stats.minibatches as f64;
        }
        stats.explained_variance = explained_variance(&batch.values, &batch.returns);
        stats
    }
}

/// With `env.site_every_step`: how many steps of each decision the site loss reads per
/// minibatch, drawn uniformly without replacement with the update's RNG. One keeps the site
/// head's work per update that of a decision-level site (a decision's 5 steps × 30 sites through
/// the site MLP every epoch made an update ≈ 6× slower on 2 cores; seed 1 of the M = 10
/// scenario at 1 M decisions learned no better with 2 or 5, docs/training.md); with 4 epochs a
/// step is read 0.8 times per update on average. The estimate is unbiased for the mean over a
/// decision's steps.
pub const SITE_STEP_ROWS: usize = 1;

impl Ppo {
    /// The all-sites loss over the steps of the minibatch's decisions `idx`
    /// (`env.site_every_step`): [`SITE_STEP_ROWS`] steps of each decision drawn with `rng`;
    /// step j of decision i is scored by the site head from its own features
    /// with the actor's hidden activation `hidden[i]` of the decision's observation
    /// (`[idx.len(), H]`, as the actors score it), against that step's site advantages
    /// ([`site_advantages`] of its rows). Returns the loss and the mean entropy of the rows'
    /// site distributions (a diagnostic, no gradient).
    pub fn step_site_loss(
        &self,
        batch: &Batch,
        idx: &[usize],
        hidden: Tensor<2>,
        rng: &mut impl RngExt,
    ) -> (Tensor<1>, f64) {
        let m = batch.n_sites;
        let f = self.model.site_features() * m;
        let per = SITE_STEP_ROWS;
        let (mut parent, mut feats, mut rows) = (Vec::new(), Vec::new(), Vec::new());
        let mut steps = Vec::new();
        for (j, &i) in idx.iter().enumerate() {
            steps.clear();
            steps.extend(batch.step_offsets[i]..batch.step_offsets[i + 1]);
            let chosen: &[usize] = if steps.len() > per {
                steps.partial_shuffle(rng, per).0
            } else {
                &steps
            };
            for &r in chosen {
                parent.push(j as i64);
                feats.extend_from_slice(&batch.step_site_features[r * f..(r + 1) * f]);
                rows.push(r);
            }
        }
        let k = rows.len();
        let adv = site_advantages(&batch.step_site_rewards, &rows, m, self.cfg.norm_adv);
        let dev = &self.device;
        let parent = Tensor::<1, Int>::from_data(TensorData::new(parent, [k]), dev);
        let feats = Tensor::<2>::from_data(TensorData::new(feats, [k, f]), dev);
        let adv = Tensor::<2>::from_data(TensorData::new(adv, [k, m]), dev);
        let logp = self.model.step_site_logp(hidden, parent, feats);
        let p_logp = tensor_to_vec(logp.clone().detach());
        let entropy =
            -p_logp.iter().map(|&l| f64::from(l.exp() * l)).sum::<f64>() / k.max(1) as f64;
        (all_sites_loss(logp, adv), entropy)
    }
}

/// The all-sites advantages `[idx.len() × m]` of the rows `idx`: each site's decision reward
/// minus the row's best (≤ 0; a constant per row does not change Σ_k ∇π_k A_k, this one makes
/// the loss the expected regret), divided by their root mean square over the minibatch when
/// `normalise` (so the site head's step does not depend on the reward scale).
pub fn site_advantages(site_rewards: &[f32], idx: &[usize], m: usize, normalise: bool) -> Vec<f32> {
    let mut a = Vec::with_capacity(idx.len() * m);
    for &i in idx {
        let row = &site_rewards[i * m..(i + 1) * m];
        let best = row.iter().fold(f32::NEG_INFINITY, |x, &y| x.max(y));
        a.extend(row.iter().map(|&r| r - best));
    }
    if normalise && !a.is_empty() {
        let ms = a.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() / a.len() as f64;
        let rms = ms.sqrt() + 1e-8;
        a.iter_mut().for_each(|x| *x = (f64::from(*x) / rms) as f32);
    }
    a
}

/// 1 − Var(R − V) / Var(R) (NaN when the returns have no variance), as CleanRL reports it.
pub fn explained_variance(values: &[f32], returns: &[f32]) -> f64 {
    let n = returns.len() as f64;
    if n < 2.0 {
        return f64::NAN;
    }
    let var = |xs: &mut dyn Iterator<Item = f64>| {
        let v: Vec<f64> = xs.collect();
        let m = v.iter().sum::<f64>() / n;
        v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n
    };
    let var_y = var(&mut returns.iter().map(|&r| f64::from(r)));
    if var_y == 0.0 {
        return f64::NAN;
    }
    let var_res = var(&mut returns
        .iter()
        .zip(values)
        .map(|(&r, &v)| f64::from(r) - f64::from(v)));
    1.0 - var_res / var_y
}
