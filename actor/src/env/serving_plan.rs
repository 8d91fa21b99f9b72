//! The serving plan of a route: the serving site of every step of a known sequence of RSRP rows
//! that keeps the least site regret for its handovers, by dynamic programming. The hindsight
//! association (`dupac eval --hindsight`, rows of the true field along a flown route) and the
//! predictive association (rows predicted along the route ahead, [`super::route_ahead`]) both
//! plan with it.

/// The serving site of every row that minimises Σ_t (best RSRP_t − RSRP_t(site_t)) +
/// `handover_cost_db` × handovers (dB·rows per handover: the site-regret and handover terms of
/// the reward with κ_s = 1, `env.reward`), subject to a minimum time of stay: a handover at
/// least `min_stay_steps` rows after the previous one (0: none; the ping-pong window + 1 forbids
/// every ping-pong of [`crate::metrics::count_handovers`]). Exact dynamic programme over (site,
/// rows since the last handover ≤ `min_stay_steps`), O(T · M · (min_stay_steps + 1)); ties keep
/// the lower site index. `rsrp_dbm` is row-major, one row of the `m` sites' RSRP (dBm) per
/// step; `start` is the site serving before the first row (it has just been selected, so the
/// stay counts as complete). A site that cannot be measured (non-finite) costs the reward's
/// largest regret, [`super::MAX_REGRET_DB`].
pub fn serving_plan(
    rsrp_dbm: &[f64],
    m: usize,
    start: u16,
    handover_cost_db: f64,
    min_stay_steps: u32,
) -> Vec<u16> {
    if m == 0 {
        return Vec::new();
    }
    let t_len = rsrp_dbm.len() / m;
    let d = min_stay_steps as usize; // states e = 0..=d: steps since the last handover, capped
    let ns = m * (d + 1);
    let idx = |k: usize, e: usize| k * (d + 1) + e;
    let mut v = vec![f64::INFINITY; ns];
    v[idx(usize::from(start).min(m - 1), d)] = 0.0;
    let mut back = vec![0u32; t_len * ns]; // the previous state of each state, per step
    let mut nv = vec![f64::INFINITY; ns];
    // A site that cannot be measured costs the reward's largest regret.
    let cost = |best: f64, r: f64| {
        if r.is_finite() && best.is_finite() {
            (best - r).max(0.0)
        } else {
            super::MAX_REGRET_DB
        }
    };
    for t in 0..t_len {
        let row = &rsrp_dbm[t * m..(t + 1) * m];
        let best = row
            .iter()
            .copied()
            .filter(|x| x.is_finite())
            .fold(f64::NEG_INFINITY, f64::max);
        // The two cheapest states a handover may leave (e + 1 ≥ d), on different sites.
        let (mut b1, mut b2) = ((f64::INFINITY, usize::MAX), (f64::INFINITY, usize::MAX));
        for k in 0..m {
            let (mut bk, mut sk) = (f64::INFINITY, usize::MAX);
            for e in d.saturating_sub(1)..=d {
                let s = idx(k, e);
                if v[s] < bk {
                    (bk, sk) = (v[s], s);
                }
            }
            if bk < b1.0 {
                b2 = b1;
                b1 = (bk, sk);
            } else if bk < b2.0 {
                b2 = (bk, sk);
            }
        }
        let bt = &mut back[t * ns..(t + 1) * ns];
        nv.fill(f64::INFINITY);
        for (j, &r) in row.iter().enumerate() {
            let c = cost(best, r);
            // Stay on j: e → min(e + 1, d).
            for e in 0..=d {
                let s = idx(j, e);
                if !v[s].is_finite() {
                    continue;
                }
                let to = idx(j, (e + 1).min(d));
                if v[s] + c < nv[to] {
                    nv[to] = v[s] + c;
                    bt[to] = s as u32;
                }
            }
            // Hand over to j from the cheapest other site whose stay is complete: e → 0
            // (with d = 0 the state is both "just handed over" and "free").
            let from = if b1.1 != usize::MAX && b1.1 / (d + 1) != j {
                b1
            } else {
                b2
            };
            if from.1 != usize::MAX {
                let to = idx(j, 0);
                let x = from.0 + handover_cost_db + c;
                if x < nv[to] {
                    nv[to] = x;
                    bt[to] = from.1 as u32;
                }
            }
        }
        std::mem::swap(&mut v, &mut nv);
    }
    let mut s = (0..ns).fold(0, |a, s| if v[s] < v[a] { s } else { a });
    let mut sites = vec![0u16; t_len];
    for t in (0..t_len).rev() {
        sites[t] = (s / (d + 1)) as u16;
        s = back[t * ns + s] as usize;
    }
    sites
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::count_handovers;

    /// Cost of `sites` under `hindsight_association`'s objective, or None when a handover comes
    /// sooner than `min_stay` steps after the previous one.
    fn hindsight_cost(
        rows: &[f64],
        m: usize,
        start: u16,
        cost: f64,
        min_stay: u32,
        sites: &[u16],
    ) -> Option<f64> {
        let (mut total, mut prev, mut since) = (0.0, start, min_stay as usize);
        for (t, &k) in sites.iter().enumerate() {
            let row = &rows[t * m..(t + 1) * m];
            let best = row.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if k != prev {
                if since + 1 < min_stay as usize {
                    return None;
                }
                total += cost;
                since = 0;
            } else {
                since = (since + 1).min(min_stay as usize);
            }
            total += best - row[usize::from(k)];
            prev = k;
        }
        Some(total)
    }

    #[test]
    fn serving_plan_is_the_exhaustive_optimum() {
        // Every sequence of 3 sites over 7 steps (2 187), on random rows, with and without a
        // minimum stay: the dynamic programme finds a feasible sequence of the least cost.
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let (m, t_len) = (3usize, 7usize);
        for case in 0..40 {
            let rows: Vec<f64> = (0..m * t_len)
                .map(|_| -70.0 + rng.random_range(-6.0..6.0))
                .collect();
            let start = (case % m) as u16;
            let cost = [0.0, 2.0, 5.0, 20.0][case % 4];
            for min_stay in [0u32, 1, 2, 3] {
                let got = serving_plan(&rows, m, start, cost, min_stay);
                assert_eq!(got.len(), t_len);
                let got_cost = hindsight_cost(&rows, m, start, cost, min_stay, &got)
                    .expect("the programme's sequence respects the minimum stay");
                let mut best = f64::INFINITY;
                for code in 0..m.pow(t_len as u32) {
                    let seq: Vec<u16> = (0..t_len)
                        .map(|i| ((code / m.pow(i as u32)) % m) as u16)
                        .collect();
                    if let Some(c) = hindsight_cost(&rows, m, start, cost, min_stay, &seq) {
                        best = best.min(c);
                    }
                }
                assert!(
                    (got_cost - best).abs() < 1e-9,
                    "case {case} stay {min_stay}: {got_cost} vs {best}"
                );
            }
        }
    }

    #[test]
    fn serving_plan_trades_regret_for_handovers() {
        // Two sites that trade a 1 dB lead every step: without a cost the best site every step
        // (a handover each step); with a cost of 3 dB·steps a handover never pays; a minimum stay
        // of the ping-pong window + 1 leaves no ping-pong even at no cost.
        let rows: Vec<f64> = (0..40)
            .flat_map(|t| {
                if t % 2 == 0 {
                    [-70.0, -71.0]
                } else {
                    [-71.0, -70.0]
                }
            })
            .collect();
        let free = serving_plan(&rows, 2, 0, 0.0, 0);
        assert_eq!(free, (0..40).map(|t| (t % 2) as u16).collect::<Vec<_>>());
        let sticky = serving_plan(&rows, 2, 0, 3.0, 0);
        assert!(sticky.iter().all(|&k| k == 0), "{sticky:?}");
        let mut serving = vec![0u16];
        let window = 4;
        serving.extend(serving_plan(&rows, 2, 0, 0.0, window + 1));
        let (handovers, ping_pongs) = count_handovers(&serving, window);
        assert!(handovers > 0);
        assert_eq!(ping_pongs, 0, "{serving:?}");
    }
}
