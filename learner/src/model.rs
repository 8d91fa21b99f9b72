//! The actor-critic in burn: separate MLPs (default 2 × 256, tanh) over the observation without
//! its site-features tail, orthogonal init (gain √2 hidden, 0.01 policy head, 1.0 value head,
//! zero biases), a state-independent log-std for the 3D move Gaussian and an optional categorical
//! head over the M sites: slot logits of the actor MLP (the paper), or the
//! permutation-equivariant [`SiteHeadModule`] (mirrored by
//! [`dupac_common::policy::SiteHead`]).
//!
//! Layers are written here rather than taken from `burn::nn::Linear` because burn's orthogonal
//! initializer panics on a bias, and because the weights must export one-to-one to the plain
//! [`dupac_common::policy::PolicyWeights`] the actors run.

use burn::module::{Module, Param};
use burn::tensor::activation::log_softmax;
use burn::tensor::{Device, Int, Tensor, TensorData};
use dupac_common::policy::mlp::{Dense as PlainDense, Mlp as PlainMlp, tanh_f32};
use dupac_common::policy::{HALF_LN_2PI, MOVE_DIM, SiteHead as PlainSiteHead};
use rand::RngExt;

/// A dense layer `y = x·W + b`, `W: [n_in, n_out]`.
#[derive(Module, Debug)]
pub struct Dense {
    pub weight: Param<Tensor<2>>,
    pub bias: Param<Tensor<1>>,
}

/// The hidden layers' tanh. On burn's CPU backend (`flex`) the values are computed in one pass
/// by [`tanh_f32`] (the actors' function) and the gradient is taken from that output: the
/// layer returns the linearisation `y = x·d + (h − x·d)` with `h = tanh(x)` and `d = 1 − h²`
/// held constant, whose value is `h` (to one rounding of `x·d`, |x·d| < 0.45) and whose
/// derivative is exactly `d`. Two tracked element-wise passes forward and one backward, where
/// burn's `tanh` (libm per element, recomputed in the backward pass) or any composition of its
/// element-wise ops costs 4–7× as much (BENCHMARKS.md, learner section). On other devices
/// (GPU backends, whose fused kernels do not need this) burn's `tanh`.
pub fn fast_tanh<const D: usize>(x: Tensor<D>) -> Tensor<D> {
    let device = x.device();
    if device.clone().without_autodiff() != Device::flex() {
        return burn::tensor::activation::tanh(x);
    }
    let dims = x.dims();
    let values = tensor_to_vec(x.clone().without_autodiff());
    let mut slope = vec![0.0f32; values.len()];
    let mut offset = vec![0.0f32; values.len()];
    for ((&v, d), c) in values.iter().zip(&mut slope).zip(&mut offset) {
        let h = tanh_f32(v);
        *d = 1.0 - h * h;
        *c = h - v * *d;
    }
    let slope = Tensor::<D>::from_data(TensorData::new(slope, dims), &device);
    let offset = Tensor::<D>::from_data(TensorData::new(offset, dims), &device);
    x * slope + offset
}

impl Dense {
    pub fn forward(&self, x: Tensor<2>) -> Tensor<2> {
        x.matmul(self.weight.val()) + self.bias.val().unsqueeze::<2>()
    }

    fn from_plain(d: &PlainDense, device: &Device) -> Dense {
        Dense {
            weight: Param::from_data(TensorData::new(d.weight.clone(), [d.n_in, d.n_out]), device),
            bias: Param::from_data(TensorData::new(d.bias.clone(), [d.n_out]), device),
        }
    }

    fn to_plain(&self) -> PlainDense {
        let [n_in, n_out] = self.weight.val().dims();
        PlainDense {
            n_in,
            n_out,
            weight: tensor_to_vec(self.weight.val()),
            bias: tensor_to_vec(self.bias.val()),
        }
    }
}

/// An MLP, tanh after every layer but the last.
#[derive(Module, Debug)]
pub struct Mlp {
    pub layers: Vec<Dense>,
}

impl Mlp {
    pub fn forward(&self, mut x: Tensor<2>) -> Tensor<2> {
        let last = self.layers.len() - 1;
        for (k, l) in self.layers.iter().enumerate() {
            x = l.forward(x);
            if k < last {
                x = fast_tanh(x);
            }
        }
        x
    }

    /// The output and the input of the last layer (the last hidden activation).
    pub fn forward_with_hidden(&self, mut x: Tensor<2>) -> (Tensor<2>, Tensor<2>) {
        let last = self.layers.len() - 1;
        for l in &self.layers[..last] {
            x = fast_tanh(l.forward(x));
        }
        (self.layers[last].forward(x.clone()), x)
    }

    pub fn from_plain(m: &PlainMlp, device: &Device) -> Mlp {
        Mlp {
            layers: m
                .layers
                .iter()
                .map(|l| Dense::from_plain(l, device))
                .collect(),
        }
    }

    pub fn to_plain(&self) -> PlainMlp {
        PlainMlp {
            layers: self.layers.iter().map(Dense::to_plain).collect(),
        }
    }
}

/// The permutation-equivariant site head: `logit_k = mlp([f_k, tanh(embed(h))])`, one MLP
/// shared by every site k (its features `f_k`) with the actor's last hidden activation `h`.
#[derive(Module, Debug)]
pub struct SiteHeadModule {
    pub embed: Dense,
    pub mlp: Mlp,
    /// Features per site.
    #[module(skip)]
    pub features: usize,
}

impl SiteHeadModule {
    /// Logits `[B, n_sites]` from the hidden activation `[B, H]` and features `[B, n_sites·F]`.
    pub fn logits(&self, hidden: Tensor<2>, feats: Tensor<2>, n_sites: usize) -> Tensor<2> {
        self.logits_of_embedding(self.embedding(hidden), feats, n_sites)
    }

    /// The state embedding `tanh(E·h)` `[B, E]` of hidden activations `[B, H]`.
    pub fn embedding(&self, hidden: Tensor<2>) -> Tensor<2> {
        fast_tanh(self.embed.forward(hidden))
    }

    /// Logits `[B, n_sites]` from state embeddings `[B, E]` ([`SiteHeadModule::embedding`]) and
    /// features `[B, n_sites·F]`. The first layer of the MLP is applied split, as the actors do:
    /// its embedding rows (and bias) once per state, `[B, H1]`, its feature rows as one matmul
    /// over every (state, site) pair, `[B·n_sites, F] × [F, H1]`, the two added by broadcasting
    /// over the sites; the rest of the MLP over the `B·n_sites` rows.
    pub fn logits_of_embedding(
        &self,
        emb: Tensor<2>,
        feats: Tensor<2>,
        n_sites: usize,
    ) -> Tensor<2> {
        let [b, e] = emb.dims();
        let f = self.features;
        let first = &self.mlp.layers[0];
        let w = first.weight.val();
        let h1 = w.dims()[1];
        let state = emb.matmul(w.clone().narrow(0, f, e)) + first.bias.val().unsqueeze::<2>();
        let pairs = feats
            .reshape([b * n_sites, f])
            .matmul(w.narrow(0, 0, f))
            .reshape([b, n_sites, h1]);
        let mut x = (pairs + state.unsqueeze_dim::<3>(1)).reshape([b * n_sites, h1]);
        for l in &self.mlp.layers[1..] {
            x = l.forward(fast_tanh(x));
        }
        x.reshape([b, n_sites])
    }
}

/// Actor and critic with the move's log-std.
#[derive(Module, Debug)]
pub struct ActorCritic {
    pub actor: Mlp,
    pub critic: Mlp,
    pub log_std: Param<Tensor<1>>,
    /// The equivariant site head (`None`: slot logits of `actor`, or no site choice).
    pub site: Option<SiteHeadModule>,
    /// Sites of the categorical choice (0 when the site is not learned).
    #[module(skip)]
    pub n_sites: usize,
    /// Observation values the MLPs read (the rest are the site head's features).
    #[module(skip)]
    pub trunk_dim: usize,
}

/// What the update needs from a forward pass over a minibatch.
pub struct Evaluated {
    /// log π(a|s) of the stored hybrid actions, `[B]`.
    pub logprob: Tensor<1>,
    /// Its parts: log π(move|s) and log π(site|s) (zeros without a site head), `[B]`.
    pub logprob_move: Tensor<1>,
    pub logprob_site: Tensor<1>,
    /// log π(k|s) of every site, `[B, M]` (`None` without a site head).
    pub site_logp: Option<Tensor<2>>,
    /// Entropy of the move Gaussian (state-independent, scalar `[1]`).
    pub entropy_move: Tensor<1>,
    /// Entropy of the site categorical, `[B]` (zeros without a site head).
    pub entropy_site: Tensor<1>,
    /// V(s), `[B]`.
    pub value: Tensor<1>,
    /// The actor's last hidden activation `[B, H]` the equivariant site head reads (`None`
    /// without one).
    pub actor_hidden: Option<Tensor<2>>,
}

impl ActorCritic {
    /// The networks of an exported policy (its MLPs, site head and log-std).
    pub fn from_policy(p: &dupac_common::policy::PolicyWeights, device: &Device) -> ActorCritic {
        ActorCritic::from_plain(
            &p.actor,
            &p.critic,
            p.log_std,
            p.site_head.as_ref(),
            p.n_sites,
            device,
        )
    }

    /// Weights from plain ones (see [`init_plain`]); `n_sites` site logits, from `site` when
    /// given, else from the actor's outputs after the 3 means.
    pub fn from_plain(
        actor: &PlainMlp,
        critic: &PlainMlp,
        log_std: [f32; 3],
        site: Option<&PlainSiteHead>,
        n_sites: usize,
        device: &Device,
    ) -> Self {
        ActorCritic {
            actor: Mlp::from_plain(actor, device),
            critic: Mlp::from_plain(critic, device),
            log_std: Param::from_data(TensorData::new(log_std.to_vec(), [MOVE_DIM]), device),
            site: site.map(|h| SiteHeadModule {
                embed: Dense::from_plain(&h.embed, device),
                mlp: Mlp::from_plain(&h.mlp, device),
                features: h.features,
            }),
            n_sites,
            trunk_dim: actor.n_in(),
        }
    }

    /// Number of sites of the categorical head.
    pub fn n_sites(&self) -> usize {
        self.n_sites
    }

    /// Features per site of the equivariant site head (0 without one).
    pub fn site_features(&self) -> usize {
        self.site.as_ref().map_or(0, |h| h.features)
    }

    /// log π(k | ·) `[R, M]` of the equivariant site head over per-step site features
    /// `[R, M·F]`, row r with the state embedding of the actor's hidden activation
    /// `hidden[parent[r]]` (`hidden: [B, H]`; `env.site_every_step`). The embedding is computed
    /// per decision, then repeated for its steps.
    pub fn step_site_logp(
        &self,
        hidden: Tensor<2>,
        parent: Tensor<1, Int>,
        feats: Tensor<2>,
    ) -> Tensor<2> {
        let r = feats.dims()[0];
        match &self.site {
            Some(h) => {
                let emb = h.embedding(hidden).select(0, parent);
                log_softmax(h.logits_of_embedding(emb, feats, self.n_sites), 1)
            }
            None => Tensor::<2>::zeros([r, self.n_sites], &feats.device()),
        }
    }

    /// Move means `[B, 3]` and site logits `[B, M]` of normalised observations `[B, obs_dim]`
    /// (`None` without a site head, or when `site_logits` is false), the trunk input, and the
    /// actor's last hidden activation when the equivariant head reads it.
    fn heads(
        &self,
        obs: Tensor<2>,
        site_logits: bool,
    ) -> (Tensor<2>, Option<Tensor<2>>, Tensor<2>, Option<Tensor<2>>) {
        let [_, d] = obs.dims();
        let trunk = obs.clone().narrow(1, 0, self.trunk_dim);
        let m = self.n_sites;
        match &self.site {
            Some(h) => {
                let (mean, hidden) = self.actor.forward_with_hidden(trunk.clone());
                let logits = site_logits.then(|| {
                    let feats = obs.narrow(1, self.trunk_dim, d - self.trunk_dim);
                    h.logits(hidden.clone(), feats, m)
                });
                (mean, logits, trunk, Some(hidden))
            }
            None => {
                let head = self.actor.forward(trunk.clone());
                let logits = (m > 0 && site_logits).then(|| head.clone().narrow(1, MOVE_DIM, m));
                (head.narrow(1, 0, MOVE_DIM), logits, trunk, None)
            }
        }
    }

    /// Log-probabilities, entropies and values of stored actions.
    /// `obs: [B, obs_dim]` (normalised), `moves: [B, 3]` (unclipped), `sites: [B]`.
    pub fn evaluate(&self, obs: Tensor<2>, moves: Tensor<2>, sites: Tensor<1, Int>) -> Evaluated {
        self.evaluate_rows(obs, moves, Some(sites))
    }

    /// [`ActorCritic::evaluate`] without the site head over the observations' own site rows
    /// (`sites: None`): the site parts are zeros and `site_logp` is `None`; the move, the value
    /// and the actor's hidden activation as there. What the update needs when the site head
    /// learns from per-step rows alone (`env.site_every_step` with the all-sites gradient), where
    /// the decision rows' site logits would be computed and differentiated for nothing.
    pub fn evaluate_rows(
        &self,
        obs: Tensor<2>,
        moves: Tensor<2>,
        sites: Option<Tensor<1, Int>>,
    ) -> Evaluated {
        let [b, _] = obs.dims();
        let (mean, logits, trunk, actor_hidden) = self.heads(obs, sites.is_some());
        let log_std = self.log_std.val();
        let inv_std = log_std.clone().neg().exp().unsqueeze::<2>();
        let z = (moves - mean) * inv_std;
        // log N(a; μ, σ) summed over the 3 axes.
        let lp_move = z
            .square()
            .mul_scalar(-0.5)
            .sum_dim(1)
            .squeeze_dim::<1>(1)
            .sub(
                log_std
                    .clone()
                    .sum()
                    .add_scalar(HALF_LN_2PI * MOVE_DIM as f64)
                    .expand([b]),
            );
        let entropy_move = log_std
            .sum()
            .add_scalar((0.5 + HALF_LN_2PI) * MOVE_DIM as f64);
        let dev = trunk.device();
        let (lp_site, entropy_site, site_logp) = match (logits, sites) {
            (Some(logits), Some(sites)) => {
                let logp = log_softmax(logits, 1);
                let lp_site = logp
                    .clone()
                    .gather(1, sites.unsqueeze_dim::<2>(1))
                    .squeeze_dim::<1>(1);
                let ent = (logp.clone().exp() * logp.clone())
                    .sum_dim(1)
                    .squeeze_dim::<1>(1)
                    .neg();
                (lp_site, ent, Some(logp))
            }
            _ => (
                Tensor::<1>::zeros([b], &dev),
                Tensor::<1>::zeros([b], &dev),
                None,
            ),
        };
        let value = self.critic.forward(trunk).squeeze_dim::<1>(1);
        Evaluated {
            logprob: lp_move.clone() + lp_site.clone(),
            logprob_move: lp_move,
            logprob_site: lp_site,
            site_logp,
            entropy_move,
            entropy_site,
            value,
            actor_hidden,
        }
    }

    /// V(s) of a batch `[B, obs_dim]` → `[B]`.
    pub fn value(&self, obs: Tensor<2>) -> Tensor<1> {
        let trunk = obs.narrow(1, 0, self.trunk_dim);
        self.critic.forward(trunk).squeeze_dim::<1>(1)
    }

    /// Plain copies of the weights: actor, critic, log-std, site head.
    pub fn to_plain(&self) -> (PlainMlp, PlainMlp, [f32; 3], Option<PlainSiteHead>) {
        let v = tensor_to_vec(self.log_std.val());
        let mut log_std = [0.0; 3];
        log_std.copy_from_slice(&v[..3]);
        let site = self.site.as_ref().map(|h| PlainSiteHead {
            features: h.features,
            embed: h.embed.to_plain(),
            mlp: h.mlp.to_plain(),
        });
        (self.actor.to_plain(), self.critic.to_plain(), log_std, site)
    }
}

/// Reads a float tensor back as a `Vec<f32>`.
pub fn tensor_to_vec<const D: usize>(t: Tensor<D>) -> Vec<f32> {
    t.into_data()
        .convert::<f32>()
        .try_into_vec::<f32>()
        .unwrap_or_default()
}

/// A random `rows × cols` matrix with orthonormal rows or columns (whichever are fewer) times
/// `gain`: the orthogonal initialisation of Saxe et al. (QR of a Gaussian matrix, here by
/// modified Gram–Schmidt), as CleanRL's `layer_init`. Seeded by the caller's RNG.
pub fn orthogonal(rows: usize, cols: usize, gain: f64, rng: &mut impl RngExt) -> Vec<f32> {
    let (n, k) = if rows >= cols {
        (rows, cols)
    } else {
        (cols, rows)
    };
    // k orthonormal vectors of length n.
    let mut q: Vec<Vec<f64>> = Vec::with_capacity(k);
    while q.len() < k {
        let mut v: Vec<f64> = (0..n).map(|_| gaussian(rng)).collect();
        for u in &q {
            let d: f64 = v.iter().zip(u).map(|(a, b)| a * b).sum();
            v.iter_mut().zip(u).for_each(|(a, b)| *a -= d * b);
        }
        let norm = v.iter().map(|a| a * a).sum::<f64>().sqrt();
        if norm > 1e-8 {
            v.iter_mut().for_each(|a| *a /= norm);
            q.push(v);
        }
    }
    let mut w = vec![0.0f32; rows * cols];
    for r in 0..rows {
        for c in 0..cols {
            let val = if rows >= cols { q[c][r] } else { q[r][c] };
            w[r * cols + c] = (gain * val) as f32;
        }
    }
    w
}

fn gaussian(rng: &mut impl RngExt) -> f64 {
    let u1: f64 = rng.random::<f64>().max(1e-300);
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Initial plain weights: an MLP `n_in → hidden… → n_out`, hidden layers with gain √2, the last
/// with `out_gain`, biases zero.
pub fn init_plain(
    n_in: usize,
    hidden: &[usize],
    n_out: usize,
    out_gain: f64,
    rng: &mut impl RngExt,
) -> PlainMlp {
    let mut layers = Vec::new();
    let mut width = n_in;
    for (k, &h) in hidden.iter().chain(std::iter::once(&n_out)).enumerate() {
        let gain = if k < hidden.len() {
            2f64.sqrt()
        } else {
            out_gain
        };
        layers.push(PlainDense {
            n_in: width,
            n_out: h,
            weight: orthogonal(width, h, gain, rng),
            bias: vec![0.0; h],
        });
        width = h;
    }
    PlainMlp { layers }
}
