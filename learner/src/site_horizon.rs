//! The horizon of the all-sites site advantage (issue 15, `ppo.site_horizon`).
//!
//! The environment reports, at each decision t, the reward every site k would have given
//! (`site_rewards[t·M + k]`, handover cost included against the site that served before t). With
//! `site_horizon = "decision"` the site head learns from these rows as they are: a myopic
//! estimator that sees the cost of a switch but not the cost of the switch back, so the learned
//! association ping-pongs whenever one site leads by more than the handover cost for a single
//! decision (docs/training.md "Site learning: what was measured").
//!
//! `site_horizon = "route"` adds to each site's decision reward the discounted value of the best
//! association over the rest of the recorded route, starting with that site serving. The site
//! does not change the flight, so that value is a dynamic programme over the segment's rows
//! (Viterbi with a switching cost):
//!
//! ```text
//! link_t(j)  = site_rewards[t, j] − h · [j ≠ prev_t]            (the row without its handover)
//! y_t(j)     = link_t(j) + γ · W_{t+1}(j)
//! W_t(k)     = max( y_t(k), h + max_j y_t(j) )                   (enter t with k serving)
//! row'_t(k)  = site_rewards[t, k] + γ · W_{t+1}(k)
//! ```
//!
//! with h = `env.reward.handover_reward` (≤ 0), `prev_t` the site serving before decision t,
//! W = 0 after the last decision of an episode or of the segment. W_t(k) − max W_t lies in
//! [h, 0], so the added term is bounded by one handover cost and a constant per row (which the
//! advantage's row-best subtraction removes) is dropped at each step. It is hindsight: the value
//! assumes the rest of the route as flown and the best association on it, not the policy's own
//! future site choices; the site head learns the association that is best given what the route
//! will bring, which the observation predicts only in part.

/// The all-sites rows of one segment (`n` decisions × `m` sites, time-ordered) with the route's
/// continuation value added (module docs). `prev[t]` is the site serving before decision t,
/// `done[t]` whether the episode ended at t; `gamma` the discount per decision, `handover` the
/// handover reward h (≤ 0, raw reward units, like the rows). Rows stay in raw reward units.
pub fn route_site_rewards(
    site_rewards: &[f64],
    prev: &[usize],
    done: &[bool],
    m: usize,
    gamma: f64,
    handover: f64,
) -> Vec<f64> {
    let n = prev.len();
    debug_assert_eq!(site_rewards.len(), n * m);
    debug_assert_eq!(done.len(), n);
    let mut out = site_rewards.to_vec();
    if m == 0 {
        return out;
    }
    // W_{t+1}(k) − max_k W_{t+1}(k) for the step after the current one.
    let mut w_next = vec![0.0f64; m];
    let mut y = vec![0.0f64; m];
    for t in (0..n).rev() {
        if done[t] {
            w_next.fill(0.0);
        }
        let row = &site_rewards[t * m..(t + 1) * m];
        let mut best_y = f64::NEG_INFINITY;
        let rows = out[t * m..(t + 1) * m].iter_mut().zip(row);
        for (j, ((o, &r), (yj, &w))) in rows.zip(y.iter_mut().zip(&w_next)).enumerate() {
            *o = r + gamma * w;
            let link = if j == prev[t] { r } else { r - handover };
            *yj = link + gamma * w;
            best_y = best_y.max(*yj);
        }
        // W_t(k) = max(y(k), h + max y); shifted so that its maximum (= max y) is 0.
        for (w, &yk) in w_next.iter_mut().zip(&y) {
            *w = yk.max(handover + best_y) - best_y;
        }
    }
    out
}

/// The site serving before each decision, read from the observation's `serving_one_hot` field
/// (`range` in an `obs_dim`-long row); the first hot index, 0 when none is hot.
pub fn serving_before(obs: &[f32], obs_dim: usize, range: std::ops::Range<usize>) -> Vec<usize> {
    obs.chunks_exact(obs_dim)
        .map(|row| {
            row[range.clone()]
                .iter()
                .position(|&v| v > 0.5)
                .unwrap_or(0)
        })
        .collect()
}
