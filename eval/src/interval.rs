//! The statistics across flights: means with 95 % Student t intervals (the t quantile from
//! statrs) and rates with 95 % Wilson score intervals.

use serde::Serialize;

/// A mean with its 95 % confidence interval (Student t, n − 1 degrees of freedom).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeanCi {
    pub n: usize,
    pub mean: f64,
    /// Half-width of the interval (NaN for n < 2).
    pub half_width: f64,
}

/// Mean and 95 % t interval of the finite values of `xs`.
pub fn mean_ci95(xs: &[f64]) -> MeanCi {
    let v: Vec<f64> = xs.iter().copied().filter(|x| x.is_finite()).collect();
    let n = v.len();
    if n == 0 {
        return MeanCi {
            n,
            mean: f64::NAN,
            half_width: f64::NAN,
        };
    }
    let mean = v.iter().sum::<f64>() / n as f64;
    if n < 2 {
        return MeanCi {
            n,
            mean,
            half_width: f64::NAN,
        };
    }
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    MeanCi {
        n,
        mean,
        half_width: t975(n - 1) * (var / n as f64).sqrt(),
    }
}

/// Degrees of freedom past which [`t975`] is the normal quantile: statrs' t inverse (through
/// the inverse regularised beta function) loses digits past about 10⁶ degrees of freedom and does
/// not return past about 10⁸, while past 10⁵ the normal quantile is within 3 · 10⁻⁵ of t's.
pub const T_NORMAL_PAST_DOF: usize = 100_000;

/// The 0.975 quantile of Student's t with `dof` degrees of freedom (statrs' inverse CDF; the
/// normal's past [`T_NORMAL_PAST_DOF`]; NaN for 0 degrees of freedom).
pub fn t975(dof: usize) -> f64 {
    use statrs::distribution::{ContinuousCDF, Normal, StudentsT};
    match dof {
        0 => f64::NAN,
        d if d > T_NORMAL_PAST_DOF => Normal::standard().inverse_cdf(0.975),
        d => StudentsT::new(0.0, 1.0, d as f64).map_or(f64::NAN, |t| t.inverse_cdf(0.975)),
    }
}

/// A rate with its 95 % Wilson score interval.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Rate {
    pub k: usize,
    pub n: usize,
    pub rate: f64,
    pub lo: f64,
    pub hi: f64,
}

/// `k` successes out of `n`, with the Wilson interval (z = 1.96).
pub fn wilson95(k: usize, n: usize) -> Rate {
    if n == 0 {
        return Rate {
            k,
            n,
            rate: f64::NAN,
            lo: f64::NAN,
            hi: f64::NAN,
        };
    }
    let z = 1.959_963_985f64;
    let (kf, nf) = (k as f64, n as f64);
    let p = kf / nf;
    let denom = 1.0 + z * z / nf;
    let centre = (p + z * z / (2.0 * nf)) / denom;
    let half = z * (p * (1.0 - p) / nf + z * z / (4.0 * nf * nf)).sqrt() / denom;
    Rate {
        k,
        n,
        rate: p,
        lo: (centre - half).max(0.0),
        hi: (centre + half).min(1.0),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn confidence_intervals_against_hand_computed_values() {
        // 1..=5: mean 3, s = √2.5, t(4) = 2.776445 → half-width 2.776445 · √(2.5 / 5).
        let c = mean_ci95(&[1.0, 2.0, 3.0, 4.0, 5.0, f64::NAN]);
        assert_eq!(c.n, 5);
        assert!((c.mean - 3.0).abs() < 1e-12);
        assert!((c.half_width - 2.776_445 * 0.5f64.sqrt()).abs() < 1e-6);
        assert!(mean_ci95(&[4.0]).half_width.is_nan());
        assert!(mean_ci95(&[]).mean.is_nan());
        // Tabulated quantiles: t(1) = 12.7062, t(10) = 2.2281, t(31) = 2.0395, t(120) = 1.9799;
        // t(∞) → 1.95996.
        for (dof, t) in [(1, 12.7062), (10, 2.2281), (31, 2.0395), (120, 1.9799)] {
            assert!((t975(dof) - t).abs() < 1e-4, "t({dof}) = {}", t975(dof));
        }
        // Past statrs' range, the normal quantile (t(10⁶) = 1.959966).
        assert!((t975(T_NORMAL_PAST_DOF) - 1.959_988).abs() < 1e-5);
        assert!((t975(1_000_000) - 1.959_966).abs() < 1e-5);
        assert!((t975(usize::MAX) - 1.959_964).abs() < 1e-6);
        assert!(t975(0).is_nan());
        // Wilson: 8 of 10 → [0.490, 0.943] (z = 1.96).
        let w = wilson95(8, 10);
        assert!((w.rate - 0.8).abs() < 1e-12);
        assert!(
            (w.lo - 0.4902).abs() < 1e-3 && (w.hi - 0.9433).abs() < 1e-3,
            "{w:?}"
        );
        let w0 = wilson95(0, 50);
        assert_eq!(w0.lo, 0.0);
        assert!((w0.hi - 0.0713).abs() < 1e-3);
    }
}
