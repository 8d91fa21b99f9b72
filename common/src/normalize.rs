//! The normalisers an exported policy carries: running observation statistics
//! ([`RunningMeanStd`], [`ObsNormalizer`]: the statistics that acted on a batch are the ones its
//! update uses) and the reward scaler (a running variance of the discounted return per stream).
//! They travel with the weights, so an actor normalises exactly as the learner did.

use serde::{Deserialize, Serialize};

/// Running mean and variance (parallel Welford / Chan et al.), the statistics of a normaliser.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunningMeanStd {
    #[serde(deserialize_with = "crate::budget::vec")]
    pub mean: Vec<f64>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub var: Vec<f64>,
    /// Number of samples seen (starts at a tiny ε so the first batch dominates, as in CleanRL).
    pub count: f64,
}

impl RunningMeanStd {
    /// Statistics of dimension `dim`: mean 0, variance 1, count 1e-4.
    pub fn new(dim: usize) -> RunningMeanStd {
        RunningMeanStd {
            mean: vec![0.0; dim],
            var: vec![1.0; dim],
            count: 1e-4,
        }
    }

    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Merges a batch of rows (`rows.len()` a multiple of `dim`).
    pub fn update<T: Copy + Into<f64>>(&mut self, rows: &[T]) {
        let dim = self.dim();
        if dim == 0 || rows.is_empty() {
            return;
        }
        let n = (rows.len() / dim) as f64;
        let mut mean = vec![0.0; dim];
        for row in rows.chunks_exact(dim) {
            for (m, &v) in mean.iter_mut().zip(row) {
                *m += v.into();
            }
        }
        mean.iter_mut().for_each(|m| *m /= n);
        let mut var = vec![0.0; dim];
        for row in rows.chunks_exact(dim) {
            for ((s, &v), m) in var.iter_mut().zip(row).zip(&mean) {
                let d = v.into() - m;
                *s += d * d;
            }
        }
        var.iter_mut().for_each(|s| *s /= n);
        self.merge(&mean, &var, n);
    }

    /// Merges batch moments (`batch_mean`, `batch_var` of `batch_count` samples).
    pub fn merge(&mut self, batch_mean: &[f64], batch_var: &[f64], batch_count: f64) {
        let tot = self.count + batch_count;
        for i in 0..self.dim() {
            let delta = batch_mean[i] - self.mean[i];
            let m_a = self.var[i] * self.count;
            let m_b = batch_var[i] * batch_count;
            let m2 = m_a + m_b + delta * delta * self.count * batch_count / tot;
            self.mean[i] += delta * batch_count / tot;
            self.var[i] = m2 / tot;
        }
        self.count = tot;
    }
}

/// Observation normaliser: `clamp((x − mean) / sqrt(var + 1e-8), ±clip)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ObsNormalizer {
    pub enabled: bool,
    pub clip: f64,
    pub stats: RunningMeanStd,
}

impl ObsNormalizer {
    pub fn new(dim: usize, enabled: bool, clip: f64) -> ObsNormalizer {
        ObsNormalizer {
            enabled,
            clip,
            stats: RunningMeanStd::new(dim),
        }
    }

    /// Normalises one observation into `out`.
    pub fn apply(&self, raw: &[f32], out: &mut [f32]) {
        if !self.enabled {
            out.copy_from_slice(raw);
            return;
        }
        let clip = self.clip;
        for (((o, &x), m), v) in out
            .iter_mut()
            .zip(raw)
            .zip(&self.stats.mean)
            .zip(&self.stats.var)
        {
            *o = ((f64::from(x) - m) / (v + 1e-8).sqrt()).clamp(-clip, clip) as f32;
        }
    }
}

/// Reward scaler: rewards divided by the running std of the discounted return (CleanRL's
/// `NormalizeReward`), per environment stream; clipped to ±`clip`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RewardScaler {
    pub enabled: bool,
    pub gamma: f64,
    pub clip: f64,
    pub stats: RunningMeanStd,
}

impl RewardScaler {
    pub fn new(enabled: bool, gamma: f64, clip: f64) -> RewardScaler {
        RewardScaler {
            enabled,
            gamma,
            clip,
            stats: RunningMeanStd::new(1),
        }
    }

    /// The scale a reward is divided by.
    pub fn std(&self) -> f64 {
        (self.stats.var[0] + 1e-8).sqrt()
    }

    pub fn scale(&self, r: f64) -> f64 {
        if self.enabled {
            (r / self.std()).clamp(-self.clip, self.clip)
        } else {
            r
        }
    }
}
