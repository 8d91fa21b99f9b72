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
    /// shuffling with `rng`: CleanRL's loop, each step a named function below.
    pub fn update(&mut self, batch: &Batch, lr: f64, rng: &mut impl RngExt) -> UpdateStats {
        let n = batch.len();
        let mb = (n / self.cfg.num_minibatches).max(1);
        let site = self.site_learning(batch);
        let mut stats = UpdateStats {
            learning_rate: lr,
            site_expected_regret: f64::NAN,
            ..UpdateStats::default()
        };
        let mut order: Vec<usize> = (0..n).collect();
        let mut grad_norm_sum = 0.0;
        for _epoch in 0..self.cfg.update_epochs {
            stats.epochs += 1;
            order.shuffle(rng);
            let mut epoch = EpochMeans::default();
            for idx in order.chunks(mb) {
                let minibatch = self.minibatch(batch, idx);
                let losses = self.losses(batch, idx, minibatch, site, rng);
                let Some(grad_norm) = self.step(&losses, lr) else {
                    stats.skipped_nonfinite += 1;
                    continue;
                };
                stats.minibatches += 1;
                grad_norm_sum += grad_norm;
                epoch.add(&losses.report);
            }
            epoch.write_into(&mut stats);
            if self.cfg.target_kl > 0.0 && stats.approx_kl > self.cfg.target_kl {
                break;
            }
        }
        if stats.minibatches > 0 {
            stats.grad_norm = grad_norm_sum / stats.minibatches as f64;
        }
        stats.explained_variance = explained_variance(&batch.values, &batch.returns);
        stats
    }

    /// How the site head learns from `batch` (`ppo.site_gradient`, and whether the per-step
    /// rows of `env.site_every_step` are there and fit).
    fn site_learning(&self, batch: &Batch) -> SiteLearning {
        let m = batch.n_sites;
        let per_step = batch.per_step_rows(self.model.site_features());
        if !batch.step_offsets.is_empty() && !per_step {
            tracing::error!(
                rows = batch.step_offsets.len(),
                decisions = batch.len(),
                "per-step site rows that do not fit the batch: the site head does not learn from them"
            );
        }
        let all_sites = self.cfg.site_gradient == SiteGradient::AllSites
            && m > 0
            && (per_step || batch.site_rewards.len() == batch.len() * m);
        SiteLearning {
            all_sites,
            per_step,
        }
    }

    /// The rows `idx` of `batch` as tensors, the advantages normalised over them
    /// (`ppo.norm_adv`, torch's unbiased std) and weighted by the decoupled importance weights.
    fn minibatch(&self, batch: &Batch, idx: &[usize]) -> Minibatch {
        let (b, d) = (idx.len(), batch.obs_dim);
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
        let dev = &self.device;
        Minibatch {
            obs: Tensor::<2>::from_data(TensorData::new(obs, [b, d]), dev),
            moves: Tensor::<2>::from_data(TensorData::new(moves, [b, MOVE_DIM]), dev),
            sites: Tensor::<1, Int>::from_data(TensorData::new(sites, [b]), dev),
            old_logprob: self.t1(oldlp),
            old_value: self.t1(oldv),
            advantages: self.t1(adv),
            returns: self.t1(ret),
        }
    }

    /// The forward pass over a minibatch and its loss: clipped surrogate, the site loss, value
    /// loss, entropy bonuses; with what the update reports of it (no gradient).
    fn losses(
        &self,
        batch: &Batch,
        idx: &[usize],
        mb: Minibatch,
        site: SiteLearning,
        rng: &mut impl RngExt,
    ) -> Losses {
        let clip = self.cfg.clip_coef;
        // The per-step rows alone teach the site head: the decision rows' site logits are not
        // computed.
        let sites = (!(site.all_sites && site.per_step)).then_some(mb.sites);
        let Evaluated {
            logprob,
            logprob_move,
            site_logp,
            entropy_move,
            entropy_site,
            value,
            actor_hidden,
            ..
        } = self.model.evaluate_rows(mb.obs, mb.moves, sites);
        // Under the all-sites gradient the ratio and clip are the move's alone.
        let logprob = if site.all_sites {
            logprob_move
        } else {
            logprob
        };
        let (pg_loss, ratio) =
            policy_loss(logprob.clone(), mb.old_logprob.clone(), mb.advantages, clip);
        // Under per-step rows the site entropy reported is of those rows (no gradient).
        let mut step_entropy = None;
        let site_loss = match (&site_logp, site.all_sites) {
            (_, true) if site.per_step => actor_hidden.map(|hidden| {
                let (loss, entropy) = self.step_site_loss(batch, idx, hidden, rng);
                step_entropy = Some(entropy);
                loss.mul_scalar(self.cfg.site_coef)
            }),
            (Some(logp), true) => {
                let (b, m) = (idx.len(), batch.n_sites);
                let a = site_advantages(&batch.site_rewards, idx, m, self.cfg.norm_adv);
                let a = Tensor::<2>::from_data(TensorData::new(a, [b, m]), &self.device);
                Some(all_sites_loss(logp.clone(), a).mul_scalar(self.cfg.site_coef))
            }
            _ => None,
        };
        let v_loss = value_loss(
            value,
            mb.old_value,
            mb.returns,
            self.cfg.clip_vloss.then_some(clip),
        );
        let ent_move = entropy_move.mean();
        let ent_site = entropy_site.mean();
        // The site's entropy bonus serves exploration, which the all-sites gradient does not
        // need.
        let ent_coef_site = if site.all_sites {
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
        let logratio = tensor_to_vec(logprob.detach() - mb.old_logprob);
        let ratio = tensor_to_vec(ratio.detach());
        let (mut old_kl, mut kl, mut cf) = (0.0, 0.0, 0.0);
        for (lr_, r) in logratio.iter().zip(&ratio) {
            let (lr_, r) = (f64::from(*lr_), f64::from(*r));
            old_kl += -lr_;
            kl += (r - 1.0) - lr_;
            cf += f64::from(u8::from((r - 1.0).abs() > clip));
        }
        let bf = idx.len() as f64;
        let loss_value = f64::from(loss.clone().into_scalar::<f32>());
        let report = [
            f64::from(pg_loss.into_scalar::<f32>()),
            f64::from(v_loss.into_scalar::<f32>()),
            f64::from(ent_move.into_scalar::<f32>()),
            step_entropy.unwrap_or_else(|| f64::from(ent_site.into_scalar::<f32>())),
            old_kl / bf,
            kl / bf,
            cf / bf,
            site_v,
        ];
        Losses {
            loss,
            loss_value,
            report,
        }
    }

    /// Backward pass, global gradient-norm clipping and the Adam step: the gradient norm before
    /// clipping, or `None` (weights untouched, logged) when the loss or the gradient is not
    /// finite.
    fn step(&mut self, losses: &Losses, lr: f64) -> Option<f64> {
        let grads = losses.loss.backward();
        let mut grads = GradientsParams::from_grads(grads, &self.model);
        let norm = clip_global_grad_norm(&self.model, &mut grads, self.cfg.max_grad_norm);
        if !(losses.loss_value.is_finite() && norm.is_finite()) {
            tracing::warn!(
                loss = losses.loss_value,
                grad_norm = norm,
                "non-finite minibatch skipped"
            );
            return None;
        }
        self.model = self.optim.step(lr, self.model.clone(), grads);
        Some(norm)
    }
}

/// How the site head learns in an update ([`Ppo::site_learning`]).
#[derive(Debug, Clone, Copy)]
struct SiteLearning {
    /// The all-sites gradient (`ppo.site_gradient = "all_sites"` with the rows it needs).
    all_sites: bool,
    /// From the per-step rows of `env.site_every_step`.
    per_step: bool,
}

/// One minibatch as tensors ([`Ppo::minibatch`]).
struct Minibatch {
    obs: Tensor<2>,
    moves: Tensor<2>,
    sites: Tensor<1, Int>,
    old_logprob: Tensor<1>,
    old_value: Tensor<1>,
    /// Normalised and importance-weighted.
    advantages: Tensor<1>,
    returns: Tensor<1>,
}

/// A minibatch's loss ([`Ppo::losses`]): the tensor to differentiate, its value, and what the
/// update reports of it, in [`EpochMeans`]'s order.
struct Losses {
    loss: Tensor<1>,
    loss_value: f64,
    report: [f64; 8],
}

/// Sums over an epoch's minibatches of what [`Losses::report`] holds: policy loss, value loss,
/// move entropy, site entropy, old approx KL, approx KL, clip fraction, site loss.
#[derive(Debug, Default)]
struct EpochMeans {
    sums: [f64; 8],
    count: usize,
}

impl EpochMeans {
    fn add(&mut self, report: &[f64; 8]) {
        for (s, v) in self.sums.iter_mut().zip(report) {
            *s += v;
        }
        self.count += 1;
    }

    /// The epoch's means into `stats` (nothing when every minibatch was skipped).
    fn write_into(&self, stats: &mut UpdateStats) {
        if self.count == 0 {
            return;
        }
        let [pg, vl, em, es, old_kl, kl, cf, site] = self.sums.map(|s| s / self.count as f64);
        stats.policy_loss = pg;
        stats.value_loss = vl;
        stats.entropy_move = em;
        stats.entropy_site = es;
        stats.entropy = em + es;
        stats.old_approx_kl = old_kl;
        stats.approx_kl = kl;
        stats.clipfrac = cf;
        stats.site_loss = site;
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
