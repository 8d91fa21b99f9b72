//! The exported policy: the weights of the actor and critic MLPs *with* the observation
//! normaliser they were trained with, and a hand-written forward pass over them.
//!
//! This is what travels from the learner to actors and deployed pilots, and what `dupac fly`
//! loads. It has no burn dependency: an actor steps environments and samples actions on plain
//! `f32` slices (burn's per-call overhead at batch 1 is larger than the whole forward pass here),
//! and `learner` proves with a test that this forward pass and the burn model give the same
//! outputs to 1e-5 for the same weights.
//!
//! Network: separate MLPs `obs → hidden… → out` with tanh hidden activations, reading
//! the observation without its `site_features` tail ([`crate::obs::ObsLayout::trunk_len`]). The
//! actor outputs 3 Gaussian means (the move, before clipping to [−1, 1]³); the move's log-std is
//! state-independent. The critic outputs one value. The categorical site choice (absent,
//! `n_sites = 0`, for the base method whose site A3 chooses) has `n_sites` logits from one of two
//! heads:
//! - slots (the paper): `n_sites` more outputs of the actor MLP, one per site index;
//! - equivariant ([`SiteHead`]): one MLP shared by all sites scores site k from its own features
//!   (the tail of the observation, fixed scales) and an embedding `tanh(E·h)` of the actor's last
//!   hidden activation `h`, so permuting the sites permutes the logits.

pub mod format8;
pub mod mlp;
pub mod wire;

use crate::config::{Config, ObservationConfig};
use crate::normalize::{ObsNormalizer, RewardScaler};
use mlp::{Dense, Mlp, tanh_f32};
use serde::{Deserialize, Serialize};

/// Dimension of the continuous move action (x, y, z).
pub const MOVE_DIM: usize = 3;

/// ln(2π)/2, used by the Gaussian log-density.
pub const HALF_LN_2PI: f64 = 0.918_938_533_204_672_8;

/// The permutation-equivariant site head: `logit_k = g([f_k, tanh(E·h)])` with `f_k`
/// site k's `features` values of the observation's tail, `h` the actor's last hidden activation
/// and `g` an MLP (tanh hidden, one output) shared by every site.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SiteHead {
    /// Features per site ([`crate::obs::SITE_FEATURES`]).
    pub features: usize,
    /// E: actor hidden width → embedding width.
    pub embed: Dense,
    /// g: `features + embedding` → … → 1.
    pub mlp: Mlp,
}

/// Buffers of the site head's forward pass.
#[derive(Debug, Default, Clone)]
struct SiteScratch {
    emb: Vec<f32>,
    pre: Vec<f32>,
    z: Vec<f32>,
    layers: [Vec<f32>; 2],
}

impl SiteHead {
    /// Logits of the `out.len()` sites from the actor's last hidden activation `hidden` and the
    /// site features `feats` (`out.len() × features`, site-major). The first layer of `g` is
    /// split: the embedding's part is computed once per state, the features' part per site.
    fn logits(&self, hidden: &[f32], feats: &[f32], out: &mut [f32], s: &mut SiteScratch) {
        let f = self.features;
        s.emb.resize(self.embed.n_out, 0.0);
        self.embed.forward(hidden, &mut s.emb);
        s.emb.iter_mut().for_each(|v| *v = tanh_f32(*v));
        let first = &self.mlp.layers[0];
        let h1 = first.n_out;
        // pre = b + emb · W[f..f+e]
        s.pre.clear();
        s.pre.extend_from_slice(&first.bias);
        for (i, &e) in s.emb.iter().enumerate() {
            let row = &first.weight[(f + i) * h1..(f + i + 1) * h1];
            for (p, &w) in s.pre.iter_mut().zip(row) {
                *p += e * w;
            }
        }
        let rest = &self.mlp.layers[1..];
        for (k, o) in out.iter_mut().enumerate() {
            s.z.clear();
            s.z.extend_from_slice(&s.pre);
            for (i, &x) in feats[k * f..(k + 1) * f].iter().enumerate() {
                let row = &first.weight[i * h1..(i + 1) * h1];
                for (z, &w) in s.z.iter_mut().zip(row) {
                    *z += x * w;
                }
            }
            if rest.is_empty() {
                *o = s.z[0];
                continue;
            }
            s.z.iter_mut().for_each(|v| *v = tanh_f32(*v));
            let [a, b] = &mut s.layers;
            a.clear();
            a.extend_from_slice(&s.z);
            for (j, layer) in rest.iter().enumerate() {
                b.resize(layer.n_out, 0.0);
                layer.forward(a, b);
                if j + 1 < rest.len() {
                    b.iter_mut().for_each(|v| *v = tanh_f32(*v));
                }
                std::mem::swap(a, b);
            }
            *o = a[0];
        }
    }

    fn check(&self, hidden: usize) -> Result<(), String> {
        if self.features == 0 {
            return Err("site head: 0 features per site".into());
        }
        self.embed.check("site head embedding")?;
        if self.embed.n_in != hidden {
            return Err(format!(
                "site head embedding reads {} values, the actor's last hidden layer has {hidden}",
                self.embed.n_in
            ));
        }
        self.mlp
            .check("site head", self.features + self.embed.n_out, 1)
    }
}

/// The exported policy: both networks, the move's log-std and the normalisers.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PolicyWeights {
    /// Policy version (number of PPO updates that produced it).
    pub version: u64,
    /// [`crate::obs::OBS_VERSION`] of the layout the policy was trained on: a policy of another
    /// layout is refused ([`PolicyWeights::validate`]).
    pub obs_version: u32,
    /// Observation length (the [`crate::obs::ObsLayout`] of the environment).
    pub obs_dim: usize,
    /// Sites of the categorical head; 0 when the site is not learned (base method).
    pub n_sites: usize,
    /// Actor MLP over the observation's first `actor.n_in()` values: 3 means, then `n_sites`
    /// logits unless `site_head` scores the sites.
    pub actor: Mlp,
    pub critic: Mlp,
    /// The equivariant site head; `None` = slot logits of `actor` (the paper).
    pub site_head: Option<SiteHead>,
    /// Log standard deviation of the move Gaussian, per axis.
    pub log_std: [f32; MOVE_DIM],
    pub obs_norm: ObsNormalizer,
    pub reward_scaler: RewardScaler,
    /// The observation the policy was trained on (`env.observation`): flags that give layouts
    /// of one length and the scales of its values (sensor range, RSRP centre) are not visible in
    /// the weights' shapes. The learner always records it; `None` only in a policy built in
    /// code without one, which is checked by its length alone and is not flown
    /// ([`PolicyWeights::configure`]). Encoded as TOML text, so that a key added later with a
    /// default does not change the format ([`format8`] reads the files that recorded it field
    /// by field).
    #[serde(with = "observation_toml")]
    pub observation: Option<ObservationConfig>,
}

/// [`PolicyWeights::observation`] as TOML text.
mod observation_toml {
    use crate::config::ObservationConfig;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(
        o: &Option<ObservationConfig>,
        s: S,
    ) -> Result<S::Ok, S::Error> {
        o.as_ref()
            .map(toml::to_string)
            .transpose()
            .map_err(serde::ser::Error::custom)?
            .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(
        d: D,
    ) -> Result<Option<ObservationConfig>, D::Error> {
        Option::<String>::deserialize(d)?
            .map(|t| toml::from_str(&t))
            .transpose()
            .map_err(|e| serde::de::Error::custom(format!("the recorded observation: {e}")))
    }
}

/// The `env.observation` keys on which `a` and `b` differ, each as `key: a vs b` (empty when
/// equal).
pub fn observation_diff(a: &ObservationConfig, b: &ObservationConfig) -> Vec<String> {
    let table = |o: &ObservationConfig| match toml::Value::try_from(o) {
        Ok(toml::Value::Table(t)) => t,
        _ => toml::Table::new(),
    };
    let (ta, tb) = (table(a), table(b));
    let mut keys: Vec<&String> = ta.keys().chain(tb.keys()).collect();
    keys.sort();
    keys.dedup();
    let show = |v: Option<&toml::Value>| v.map_or_else(|| "–".to_string(), |v| v.to_string());
    keys.into_iter()
        .filter(|k| ta.get(*k) != tb.get(*k))
        .map(|k| {
            format!(
                "env.observation.{k}: {} vs {}",
                show(ta.get(k)),
                show(tb.get(k))
            )
        })
        .collect()
}

/// One sampled (or deterministic) action with what the learner stores about it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ActionSample {
    /// The move before clipping to [−1, 1]³ (what the learner stores).
    pub move_raw: [f32; MOVE_DIM],
    /// Chosen site index (0 when `n_sites == 0`).
    pub site: u32,
    /// log π(a|s) of the whole hybrid action (move + site).
    pub logprob: f32,
    /// log π(site|s) alone (0 without a site head): `logprob − site_logprob` is the move's.
    pub site_logprob: f32,
    /// V(s), in the critic's (scaled-reward) units.
    pub value: f32,
}

/// Reusable buffers of one inference thread.
#[derive(Debug, Default, Clone)]
pub struct Scratch {
    norm: Vec<f32>,
    head: Vec<f32>,
    value: Vec<f32>,
    layers: [Vec<f32>; 2],
    hidden: Vec<f32>,
    site: SiteScratch,
    step_logits: Vec<f32>,
}

/// Upper bound (bytes) on what a [`PolicyWeights`] of this shape allocates decoded (and on its
/// encoded size): every dense layer of the actor, the critic and the site head bounded by the
/// widest width `w` of the configuration, `(w + 1) · w` f32 parameters each, plus the
/// observation normaliser (two f64 vectors); the weights message adds its header
/// (`MsgLimits::weights`). Loose by design (a 10× margin on the default network): a weights
/// message a peer sends cannot make an actor or pilot allocate more than its own configuration
/// could ever need.
pub fn weights_budget_bytes(
    obs_dim: usize,
    n_sites: usize,
    hidden: &[usize],
    site_embed: usize,
    site_hidden: &[usize],
) -> usize {
    let w = hidden
        .iter()
        .chain(site_hidden)
        .copied()
        .chain([obs_dim, MOVE_DIM + n_sites, site_embed + obs_dim])
        .max()
        .unwrap_or(0);
    let layers = 2 * (hidden.len() + 1) + site_hidden.len() + 2;
    let per_layer = size_of::<Dense>() + size_of::<f32>() * (w + 1).saturating_mul(w);
    layers
        .saturating_mul(per_layer)
        .saturating_add(2 * size_of::<f64>() * obs_dim)
}

impl PolicyWeights {
    /// Checks version, shapes, finiteness and the normalisers (weights can come from a file or
    /// the network).
    pub fn validate(&self) -> Result<(), String> {
        if self.obs_version != crate::obs::OBS_VERSION {
            return Err(format!(
                "trained on observation layout version {}; this build reads version {}: retrain the policy (dupac train)",
                self.obs_version,
                crate::obs::OBS_VERSION
            ));
        }
        if let Some(o) = &self.observation {
            o.validate()
                .map_err(|e| format!("the recorded observation: {e}"))?;
            if let Some(h) = &self.site_head {
                let f = crate::obs::site_features_per_site(o);
                if !o.site_features || h.features != f {
                    return Err(format!(
                        "the site head reads {} features per site, the recorded observation has {}",
                        h.features,
                        if o.site_features { f } else { 0 }
                    ));
                }
            }
        }
        let trunk = self.trunk_dim();
        if trunk == 0 || trunk > self.obs_dim {
            return Err(format!(
                "actor reads {trunk} values of observations of {}",
                self.obs_dim
            ));
        }
        match &self.site_head {
            None => self.actor.check("actor", trunk, MOVE_DIM + self.n_sites)?,
            Some(h) => {
                self.actor.check("actor", trunk, MOVE_DIM)?;
                let hidden = self.actor.layers.last().map(|l| l.n_in).unwrap_or(0);
                h.check(hidden)?;
                let tail = self.obs_dim - trunk;
                if self.n_sites == 0 || self.n_sites.checked_mul(h.features) != Some(tail) {
                    return Err(format!(
                        "site head: {tail} feature values for {} sites of {} features",
                        self.n_sites, h.features
                    ));
                }
            }
        }
        self.critic.check("critic", trunk, 1)?;
        if !self.log_std.iter().all(|v| v.is_finite()) {
            return Err("log_std: non-finite".into());
        }
        let s = &self.obs_norm.stats;
        if s.dim() != self.obs_dim || s.var.len() != self.obs_dim {
            return Err(format!(
                "obs_norm: dimension {} for observations of {}",
                s.dim(),
                self.obs_dim
            ));
        }
        if !s.mean.iter().chain(&s.var).all(|v| v.is_finite()) || s.var.iter().any(|v| *v < 0.0) {
            return Err("obs_norm: non-finite or negative statistics".into());
        }
        if let Some(o) = &self.observation {
            // After the shape checks, which bound obs_dim and n_sites by the weights' real sizes.
            // A policy without site outputs (A3) does not know M: any M the record allows.
            let len = |m: usize| crate::obs::ObsLayout::new(o, m).len();
            let fits = if self.n_sites > 0 {
                len(self.n_sites) == self.obs_dim
            } else {
                let (base, per) = (len(0), len(1) - len(0));
                self.obs_dim >= base && per > 0 && (self.obs_dim - base).is_multiple_of(per)
            };
            if !fits {
                return Err(format!(
                    "the recorded observation does not give {} values for {} sites",
                    self.obs_dim,
                    if self.n_sites > 0 {
                        self.n_sites.to_string()
                    } else {
                        "any number of".into()
                    }
                ));
            }
        }
        if !(self.obs_norm.clip.is_finite() && self.obs_norm.clip > 0.0) {
            return Err(format!(
                "obs_norm.clip = {}: must be finite and > 0",
                self.obs_norm.clip
            ));
        }
        let r = &self.reward_scaler;
        let rs = &r.stats;
        if rs.dim() != 1
            || rs.var.len() != 1
            || !(rs.mean[0].is_finite() && rs.var[0].is_finite() && rs.var[0] >= 0.0)
            || !(rs.count.is_finite() && rs.count >= 0.0)
            || !(r.clip.is_finite() && r.clip > 0.0)
            || !(r.gamma.is_finite() && (0.0..=1.0).contains(&r.gamma))
        {
            return Err("reward_scaler: statistics, clip or gamma out of range".into());
        }
        Ok(())
    }

    /// `cfg` with `env.observation` set to the observation this policy was trained on, checked
    /// on its own ([`ObservationConfig::validate`]; a file is untrusted input): what `dupac eval`
    /// and `dupac fly` fly it with, whatever the configuration says. The error names the
    /// invalid key (a loaded policy has passed [`PolicyWeights::validate`] already; this also
    /// guards one built in code), or says that the policy records none. Only the observation is taken: the training-time rules that tie it to
    /// the reward (a ping-pong cost needs its feature) are not about flying.
    pub fn configure(&self, cfg: &Config) -> Result<Config, String> {
        let mut c = cfg.clone();
        let o = self
            .observation
            .as_ref()
            .ok_or("the policy records no observation to fly it with")?;
        o.validate()
            .map_err(|e| format!("the observation recorded in the policy: {e}"))?;
        c.env.observation = o.clone();
        Ok(c)
    }

    /// Refuses a policy trained on another observation than `cfg`'s (what an actor or a resumed
    /// learner needs: they cannot fly it with another); the error lists the keys that differ.
    /// A policy that records none (built in code) passes: its length is checked apart.
    pub fn check_observation(&self, cfg: &ObservationConfig) -> Result<(), String> {
        match &self.observation {
            Some(o) if o != cfg => Err(format!(
                "trained on another observation than this configuration's (policy vs configuration): {}",
                observation_diff(o, cfg).join(", ")
            )),
            _ => Ok(()),
        }
    }

    /// Values of the observation the actor and critic MLPs read (the rest are site features).
    pub fn trunk_dim(&self) -> usize {
        self.actor.n_in()
    }

    /// Normalised observation, actor head (means then logits) and value for a raw observation.
    fn heads<'a>(&self, raw_obs: &[f32], s: &'a mut Scratch) -> (&'a [f32], f32) {
        let trunk = self.trunk_dim();
        s.norm.resize(self.obs_dim, 0.0);
        self.obs_norm.apply(raw_obs, &mut s.norm);
        s.head.resize(MOVE_DIM + self.n_sites, 0.0);
        match &self.site_head {
            None => self
                .actor
                .forward(&s.norm[..trunk], &mut s.head, &mut s.layers),
            Some(h) => {
                self.actor.forward_with_hidden(
                    &s.norm[..trunk],
                    &mut s.head[..MOVE_DIM],
                    &mut s.layers,
                    &mut s.hidden,
                );
                // The features are on fixed scales: read raw, not normalised.
                h.logits(
                    &s.hidden,
                    &raw_obs[trunk..],
                    &mut s.head[MOVE_DIM..],
                    &mut s.site,
                );
            }
        }
        s.value.resize(1, 0.0);
        self.critic
            .forward(&s.norm[..trunk], &mut s.value, &mut s.layers);
        (&s.head, s.value[0])
    }

    /// V(s) of a raw observation.
    pub fn value(&self, raw_obs: &[f32], s: &mut Scratch) -> f32 {
        let trunk = self.trunk_dim();
        s.norm.resize(self.obs_dim, 0.0);
        self.obs_norm.apply(raw_obs, &mut s.norm);
        s.value.resize(1, 0.0);
        self.critic
            .forward(&s.norm[..trunk], &mut s.value, &mut s.layers);
        s.value[0]
    }

    /// The deterministic action (Gaussian mean, arg-max site) used to fly and evaluate.
    pub fn act_deterministic(&self, raw_obs: &[f32], s: &mut Scratch) -> ActionSample {
        let (head, value) = self.heads(raw_obs, s);
        let mut move_raw = [0.0; MOVE_DIM];
        move_raw.copy_from_slice(&head[..MOVE_DIM]);
        let logits = &head[MOVE_DIM..];
        let site = argmax(logits);
        let (lp_move, lp_site) = self.logprob_of(head, &move_raw, site);
        ActionSample {
            move_raw,
            site: site as u32,
            logprob: lp_move + lp_site,
            site_logprob: lp_site,
            value,
        }
    }

    /// Samples an action: `u` supplies uniform numbers in [0, 1) (3 Box–Muller pairs and one for
    /// the site), so the caller owns the RNG and runs are reproducible.
    pub fn act_sample(
        &self,
        raw_obs: &[f32],
        s: &mut Scratch,
        mut u: impl FnMut() -> f64,
    ) -> ActionSample {
        let (head, value) = self.heads(raw_obs, s);
        let mut move_raw = [0.0f32; MOVE_DIM];
        for (k, m) in move_raw.iter_mut().enumerate() {
            let u1 = u().max(1e-300);
            let u2 = u();
            let z = (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
            *m = (f64::from(head[k]) + f64::from(self.log_std[k]).exp() * z) as f32;
        }
        let logits = &head[MOVE_DIM..];
        let site = if logits.is_empty() {
            0
        } else {
            sample_categorical(logits, u())
        };
        let (lp_move, lp_site) = self.logprob_of(head, &move_raw, site);
        ActionSample {
            move_raw,
            site: site as u32,
            logprob: lp_move + lp_site,
            site_logprob: lp_site,
            value,
        }
    }

    /// The site logits at a later step of the decision last acted on with `s`
    /// (`env.site_every_step`): the site head over this step's `feats` (`n_sites ×
    /// features`, the `site_features` layout) with the actor's hidden activation of the
    /// decision's observation, which [`PolicyWeights::act_sample`] and
    /// [`PolicyWeights::act_deterministic`] leave in `s` ([`PolicyWeights::value`] does not
    /// touch it). Empty without an equivariant site head.
    pub fn step_site_logits<'a>(&self, feats: &[f32], s: &'a mut Scratch) -> &'a [f32] {
        let Some(h) = &self.site_head else {
            return &[];
        };
        s.step_logits.resize(self.n_sites, 0.0);
        let fits = feats.len() == self.n_sites * h.features && s.hidden.len() == h.embed.n_in;
        debug_assert!(
            fits,
            "step_site_logits before an act on this scratch, or other features"
        );
        if !fits {
            // Not the layout this head reads, or no decision acted on yet: no scores.
            s.step_logits.fill(0.0);
        } else {
            h.logits(&s.hidden, feats, &mut s.step_logits, &mut s.site);
        }
        &s.step_logits
    }

    /// (log π(move), log π(site)) given the actor head.
    fn logprob_of(&self, head: &[f32], move_raw: &[f32; MOVE_DIM], site: usize) -> (f32, f32) {
        let mut lp = 0.0f64;
        for k in 0..MOVE_DIM {
            let log_std = f64::from(self.log_std[k]);
            let z = (f64::from(move_raw[k]) - f64::from(head[k])) / log_std.exp();
            lp += -0.5 * z * z - log_std - HALF_LN_2PI;
        }
        let logits = &head[MOVE_DIM..];
        let mut lp_site = 0.0f64;
        if !logits.is_empty() {
            let max = logits.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
            let lse = f64::from(max)
                + logits
                    .iter()
                    .map(|&l| f64::from(l - max).exp())
                    .sum::<f64>()
                    .ln();
            lp_site = f64::from(logits[site]) - lse;
        }
        (lp as f32, lp_site as f32)
    }

    /// log π(move, site | s) of a raw observation under these weights (the learner's proximal
    /// policy for data acted with an older version).
    pub fn logprob(
        &self,
        raw_obs: &[f32],
        move_raw: &[f32; MOVE_DIM],
        site: u32,
        s: &mut Scratch,
    ) -> f32 {
        let (m, k) = self.logprob_parts(raw_obs, move_raw, site, s);
        m + k
    }

    /// (log π(move | s), log π(site | s)) of a raw observation (the site part 0 without a site
    /// head).
    pub fn logprob_parts(
        &self,
        raw_obs: &[f32],
        move_raw: &[f32; MOVE_DIM],
        site: u32,
        s: &mut Scratch,
    ) -> (f32, f32) {
        let (head, _) = self.heads(raw_obs, s);
        let site = (site as usize).min(self.n_sites.saturating_sub(1));
        self.logprob_of(head, move_raw, site)
    }

    /// Actor head (means then logits) and value of a raw observation (for tests and tools).
    pub fn forward(&self, raw_obs: &[f32], s: &mut Scratch) -> (Vec<f32>, f32) {
        let (h, v) = self.heads(raw_obs, s);
        (h.to_vec(), v)
    }
}

/// The index of a categorical draw from `logits` (not empty) with the uniform number `u` in
/// [0, 1): inverse transform sampling over the softmax weights, in index order.
pub fn sample_categorical(logits: &[f32], u: f64) -> usize {
    let max = logits.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
    let total: f64 = logits.iter().map(|&l| f64::from(l - max).exp()).sum();
    let mut target = u * total;
    for (k, &l) in logits.iter().enumerate() {
        target -= f64::from(l - max).exp();
        if target < 0.0 {
            return k;
        }
    }
    logits.len().saturating_sub(1)
}

/// The first index of the largest value (0 for an empty slice): the deterministic site.
pub fn argmax(v: &[f32]) -> usize {
    let mut best = 0;
    for (k, &x) in v.iter().enumerate() {
        if x > v[best] {
            best = k;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::normalize::RunningMeanStd;

    #[test]
    fn running_mean_std_matches_two_pass_statistics() {
        let data: Vec<f64> = (0..100)
            .map(|i| (i as f64 * 0.37).sin() * 5.0 + 2.0)
            .collect();
        let mut rms = RunningMeanStd::new(1);
        for chunk in data.chunks(7) {
            rms.update(chunk);
        }
        let n = data.len() as f64;
        let mean = data.iter().sum::<f64>() / n;
        let var = data.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
        // The initial pseudo-count 1e-4 (mean 0, var 1) perturbs by ~1e-6.
        assert!(
            (rms.mean[0] - mean).abs() < 1e-5,
            "{} vs {mean}",
            rms.mean[0]
        );
        assert!((rms.var[0] - var).abs() < 1e-4, "{} vs {var}", rms.var[0]);
        assert!((rms.count - n).abs() < 1e-3);
    }

    #[test]
    fn normaliser_clips_and_centres() {
        let mut n = ObsNormalizer::new(2, true, 10.0);
        n.stats.mean = vec![1.0, -2.0];
        n.stats.var = vec![4.0, 1e-12];
        let mut out = [0.0; 2];
        n.apply(&[5.0, -1.0], &mut out);
        assert!((out[0] - 2.0).abs() < 1e-6);
        assert_eq!(out[1], 10.0, "tiny variance is clipped to ±clip");
    }

    #[test]
    fn tanh_rewrite_matches_libm() {
        for i in -400_000..=400_000 {
            let x = i as f32 * 5e-5;
            assert!((tanh_f32(x) - x.tanh()).abs() < 5e-7, "x = {x}");
            assert!(tanh_f32(x).abs() <= 1.0);
        }
        assert_eq!(tanh_f32(f32::INFINITY), 1.0);
        assert_eq!(tanh_f32(f32::NEG_INFINITY), -1.0);
        assert!(tanh_f32(f32::NAN).is_nan(), "a NaN is not hidden");
    }
}
