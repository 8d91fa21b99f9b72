//! Generalised advantage estimation (Schulman et al. 2016) with termination and truncation kept
//! apart.
//!
//! For one environment's steps in time order, with `next_value[t]` = V(s_{t+1}) of the state the
//! step actually reached (the final observation when the episode ended there):
//!
//! ```text
//! δ_t = r_t + γ · (1 − terminated_t) · V(s_{t+1}) − V(s_t)
//! A_t = δ_t + γ λ · (1 − (terminated_t ∨ truncated_t)) · A_{t+1}
//! R_t = A_t + V(s_t)
//! ```
//!
//! A truncated step (time limit) bootstraps from the value of its final observation; a terminated
//! one (goal, collision, out of bounds) does not. Either ends the λ-chain: the next step belongs
//! to a new episode.

/// One environment's rollout, time-ordered.
#[derive(Debug, Clone, Copy)]
pub struct Trajectory<'a> {
    pub rewards: &'a [f32],
    pub values: &'a [f32],
    pub next_values: &'a [f32],
    pub terminated: &'a [bool],
    pub truncated: &'a [bool],
}

/// Advantages and returns `(A_t, R_t)` of one trajectory.
pub fn gae(tr: Trajectory<'_>, gamma: f64, lambda: f64) -> (Vec<f32>, Vec<f32>) {
    let n = tr.rewards.len();
    let mut adv = vec![0.0f32; n];
    let mut next_adv = 0.0f64;
    for t in (0..n).rev() {
        let term = tr.terminated[t];
        let end = term || tr.truncated[t];
        let bootstrap = if term {
            0.0
        } else {
            gamma * f64::from(tr.next_values[t])
        };
        let delta = f64::from(tr.rewards[t]) + bootstrap - f64::from(tr.values[t]);
        let carry = if end { 0.0 } else { gamma * lambda * next_adv };
        next_adv = delta + carry;
        adv[t] = next_adv as f32;
    }
    let ret = adv.iter().zip(tr.values).map(|(a, v)| a + v).collect();
    (adv, ret)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition, summed forward: A_t = Σ_k (γλ)^k δ_{t+k} until the episode ends.
    fn naive(tr: Trajectory<'_>, gamma: f64, lambda: f64) -> Vec<f64> {
        let n = tr.rewards.len();
        let delta: Vec<f64> = (0..n)
            .map(|t| {
                let boot = if tr.terminated[t] {
                    0.0
                } else {
                    gamma * f64::from(tr.next_values[t])
                };
                f64::from(tr.rewards[t]) + boot - f64::from(tr.values[t])
            })
            .collect();
        (0..n)
            .map(|t| {
                let mut sum = 0.0;
                let mut w = 1.0;
                for (k, d) in delta.iter().enumerate().skip(t) {
                    sum += w * d;
                    if tr.terminated[k] || tr.truncated[k] {
                        break;
                    }
                    w *= gamma * lambda;
                }
                sum
            })
            .collect()
    }

    #[test]
    fn matches_the_naive_sum_with_termination_and_truncation() {
        let rewards = [1.0, -0.5, 2.0, 0.25, 3.0, -1.0, 0.5, 1.5];
        let values = [0.3, 0.1, -0.2, 0.7, 0.0, 0.4, -0.6, 0.9];
        // Step 2 terminates (goal), step 5 is truncated with V(final obs) = 5.0, the rollout
        // ends mid-episode at step 7 with V(s_8) = -0.25.
        let terminated = [false, false, true, false, false, false, false, false];
        let truncated = [false, false, false, false, false, true, false, false];
        let next_values = [0.1, -0.2, 123.0, 0.0, 0.4, 5.0, 0.9, -0.25];
        let tr = Trajectory {
            rewards: &rewards,
            values: &values,
            next_values: &next_values,
            terminated: &terminated,
            truncated: &truncated,
        };
        let (adv, ret) = gae(tr, 0.95, 0.9);
        let want = naive(tr, 0.95, 0.9);
        for t in 0..rewards.len() {
            assert!((f64::from(adv[t]) - want[t]).abs() < 1e-5, "t={t}");
            assert!((ret[t] - adv[t] - values[t]).abs() < 1e-6);
        }
        // Hand-computed corner cases: the terminal step ignores its (bogus) next value ...
        assert!((adv[2] - (2.0 - (-0.2))).abs() < 1e-6);
        // ... the truncated step bootstraps from V(final obs) and does not chain to step 6.
        assert!((adv[5] - (-1.0 + 0.95 * 5.0 - 0.4)).abs() < 1e-6);
        // The last step of the rollout bootstraps from V(s_8).
        assert!((adv[7] - (1.5 + 0.95 * -0.25 - 0.9)).abs() < 1e-6);
    }

    #[test]
    fn truncation_and_termination_differ_only_by_the_bootstrap() {
        let rewards = [1.0f32];
        let values = [0.0f32];
        let next = [10.0f32];
        let mk = |term: bool| {
            let t = [term];
            let u = [!term];
            gae(
                Trajectory {
                    rewards: &rewards,
                    values: &values,
                    next_values: &next,
                    terminated: &t,
                    truncated: &u,
                },
                0.5,
                0.95,
            )
            .0[0]
        };
        assert_eq!(mk(true), 1.0);
        assert_eq!(mk(false), 6.0);
    }
}
