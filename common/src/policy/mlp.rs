//! The policy's plain MLP: dense layers with tanh hidden activations on `f32` slices, the
//! forward pass actors and deployed pilots run (no burn), and the tanh the learner shares.

use serde::{Deserialize, Serialize};

/// tanh as the learner and the actors compute it: the rational approximation of Eigen's
/// `ptanh_float` (odd polynomial of degree 13 over an even one of degree 6, argument clamped to
/// ±7.905 31, result to ±1), max |error| against the exact tanh ≈ 4e-7. No `exp`: the loop
/// over a slice vectorises, ≈ 3× faster than `1 − 2/(exp(2x) + 1)` here and ≈ 10× burn's CPU
/// `tanh` (BENCHMARKS.md, notes/burn-cpu.md). NaN stays NaN.
#[inline(always)]
pub fn tanh_f32(x: f32) -> f32 {
    let x = x.clamp(-7.905_311, 7.905_311);
    let x2 = x * x;
    let p = x2 * -2.760_768_5e-16 + 2.000_188e-13;
    let p = x2 * p + -8.604_672e-11;
    let p = x2 * p + 5.122_297e-8;
    let p = x2 * p + 1.485_722_4e-5;
    let p = x2 * p + 6.372_619_3e-4;
    let p = x2 * p + 4.893_524_6e-3;
    let q = x2 * 1.198_258_4e-6 + 1.185_347_1e-4;
    let q = x2 * q + 2.268_434_7e-3;
    let q = x2 * q + 4.893_525e-3;
    (x * p / q).clamp(-1.0, 1.0)
}

/// One dense layer `y = x·W + b`, `W` stored row-major as `[n_in][n_out]` (burn's layout).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dense {
    pub n_in: usize,
    pub n_out: usize,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub weight: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub bias: Vec<f32>,
}

impl Dense {
    /// `out = x·W + b` (`x.len() == n_in`, `out.len() == n_out`).
    #[inline]
    pub fn forward(&self, x: &[f32], out: &mut [f32]) {
        out.copy_from_slice(&self.bias);
        for (i, &xi) in x.iter().enumerate() {
            let row = &self.weight[i * self.n_out..(i + 1) * self.n_out];
            for (o, &w) in out.iter_mut().zip(row) {
                *o += xi * w;
            }
        }
    }

    pub(super) fn check(&self, what: &str) -> Result<(), String> {
        if self.weight.len() != self.n_in * self.n_out || self.bias.len() != self.n_out {
            return Err(format!(
                "{what}: weight has {} values and bias {}, expected {}×{} and {}",
                self.weight.len(),
                self.bias.len(),
                self.n_in,
                self.n_out,
                self.n_out
            ));
        }
        if !self.weight.iter().chain(&self.bias).all(|v| v.is_finite()) {
            return Err(format!("{what}: non-finite weight"));
        }
        Ok(())
    }
}

/// An MLP: tanh after every layer but the last.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Mlp {
    #[serde(deserialize_with = "crate::budget::vec")]
    pub layers: Vec<Dense>,
}

impl Mlp {
    /// Whether every weight and bias is finite.
    pub fn all_finite(&self) -> bool {
        self.layers
            .iter()
            .all(|l| l.weight.iter().chain(&l.bias).all(|v| v.is_finite()))
    }

    pub fn n_in(&self) -> usize {
        self.layers.first().map(|l| l.n_in).unwrap_or(0)
    }

    pub fn n_out(&self) -> usize {
        self.layers.last().map(|l| l.n_out).unwrap_or(0)
    }

    /// [`Mlp::forward`] that also returns the input of the last layer (the last hidden
    /// activation, or `x` for a one-layer MLP) in `hidden`.
    pub fn forward_with_hidden(
        &self,
        x: &[f32],
        out: &mut [f32],
        scratch: &mut [Vec<f32>; 2],
        hidden: &mut Vec<f32>,
    ) {
        self.forward(x, out, scratch);
        // After the last swap, scratch[1] holds what the last layer read.
        let n = self.layers.last().map(|l| l.n_in).unwrap_or(0);
        hidden.clear();
        hidden.extend_from_slice(&scratch[1][..n]);
    }

    /// Forward pass into `out` (`n_out` values), using `scratch` (two buffers of the widest layer).
    pub fn forward(&self, x: &[f32], out: &mut [f32], scratch: &mut [Vec<f32>; 2]) {
        let last = self.layers.len() - 1;
        let [a, b] = scratch;
        a.clear();
        a.extend_from_slice(x);
        for (k, layer) in self.layers.iter().enumerate() {
            b.resize(layer.n_out, 0.0);
            layer.forward(a, b);
            if k < last {
                for v in b.iter_mut() {
                    *v = tanh_f32(*v);
                }
            }
            std::mem::swap(a, b);
        }
        out.copy_from_slice(&a[..out.len()]);
    }

    pub(super) fn check(&self, what: &str, n_in: usize, n_out: usize) -> Result<(), String> {
        if self.layers.is_empty() {
            return Err(format!("{what}: no layers"));
        }
        let mut width = n_in;
        for (k, l) in self.layers.iter().enumerate() {
            if l.n_in != width {
                return Err(format!(
                    "{what} layer {k}: input width {} after width {width}",
                    l.n_in
                ));
            }
            l.check(&format!("{what} layer {k}"))?;
            width = l.n_out;
        }
        if width != n_out {
            return Err(format!("{what}: output width {width}, expected {n_out}"));
        }
        Ok(())
    }
}
