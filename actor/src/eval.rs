//! Evaluation's computations over recorded flights (spec/env.md "Metrics"; the records are
//! [`crate::record`], the per-flight metrics [`crate::metrics`]): the SINR of a step, the
//! hindsight association of a recorded route, and the statistics across flights (means with
//! 95 % t intervals, the t quantile from statrs; Wilson intervals for rates). Pure functions over
//! plain data: the report of `dupac eval` is computed from saved records without flying again.

use serde::Serialize;

/// Thermal noise per LTE resource element (dBm): −174 dBm/Hz + 10·log10(15 kHz) + a UE noise
/// figure of 9 dB. RSRP is a per-resource-element power, so SINR from RSRPs uses this noise.
pub const NOISE_PER_RE_DBM: f64 = -174.0 + 41.760_912_590_556_81 + 9.0;

/// SINR (dB) of `serving` with every other site as a co-channel interferer at full load:
/// S / (Σ_{j ≠ serving} I_j + N), all in linear mW from dBm. Sites with a NaN/−∞ RSRP add
/// nothing.
pub fn sinr_db(rsrp_all_dbm: &[f64], serving: usize, noise_dbm: f64) -> f64 {
    let mw = |dbm: f64| {
        if dbm.is_finite() {
            10f64.powf(dbm / 10.0)
        } else {
            0.0
        }
    };
    let s = rsrp_all_dbm.get(serving).copied().map(mw).unwrap_or(0.0);
    let i: f64 = rsrp_all_dbm
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != serving)
        .map(|(_, v)| mw(*v))
        .sum();
    10.0 * (s / (i + mw(noise_dbm))).log10()
}

/// The hindsight association of a recorded route: the serving site of every step that minimises
/// Σ_t (best RSRP_t − RSRP_t(site_t)) + `handover_cost_db` × handovers (dB·steps per handover,
/// the site-regret and handover terms of the reward with κ_s = 1, `env.reward`), subject to a
/// minimum time of stay: a handover at least `min_stay_steps` steps after the previous one (0:
/// none; the ping-pong window + 1 forbids every ping-pong of
/// [`crate::metrics::count_handovers`]). Exact dynamic programme over (site, steps since the
/// last handover ≤ `min_stay_steps`), O(T · M · (min_stay_steps + 1)); ties keep the lower site
/// index.
/// `rsrp_dbm` is row-major, one row of the `m` sites' RSRP (dBm) per step; `start` is the site
/// serving before the first step (it has just been selected, so the stay counts as complete).
/// An evaluation reference that knows the whole route in advance, not a realisable rule: it
/// gives, on a policy's own moves, the best link any association with that many handovers can
/// keep (`dupac eval --hindsight`).
pub fn hindsight_association(
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
            crate::env::MAX_REGRET_DB
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
    use crate::metrics::{MetricRules, count_handovers, flight_metrics};
    use crate::record::{FlightRecord, StepRecord};
    use dupac_common::geometry::Point;
    use dupac_common::msg::Outcome;
    use dupac_radio::class::RsrpClass;

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
    fn hindsight_association_is_the_exhaustive_optimum() {
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
                let got = hindsight_association(&rows, m, start, cost, min_stay);
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
    fn hindsight_association_trades_regret_for_handovers() {
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
        let free = hindsight_association(&rows, 2, 0, 0.0, 0);
        assert_eq!(free, (0..40).map(|t| (t % 2) as u16).collect::<Vec<_>>());
        let sticky = hindsight_association(&rows, 2, 0, 3.0, 0);
        assert!(sticky.iter().all(|&k| k == 0), "{sticky:?}");
        let mut serving = vec![0u16];
        let window = 4;
        serving.extend(hindsight_association(&rows, 2, 0, 0.0, window + 1));
        let (handovers, ping_pongs) = count_handovers(&serving, window);
        assert!(handovers > 0);
        assert_eq!(ping_pongs, 0, "{serving:?}");
    }

    fn step(x: f32, serving: u16, rsrp: f32, class: RsrpClass, sinr: f32) -> StepRecord {
        StepRecord {
            position_m: [x, 0.0, 50.0],
            serving,
            serving_rsrp_dbm: rsrp,
            measured_serving_rsrp_dbm: rsrp,
            best_site: serving,
            best_rsrp_dbm: rsrp,
            sinr_db: sinr,
            class,
            best_class: class,
            los: true,
            handover: false,
            ping_pong: false,
        }
    }

    /// A hand-built flight: 4 steps of 1 m then 1 step of 2 m (L = 6 m) over D = 5 m.
    fn flight() -> FlightRecord {
        use RsrpClass::*;
        FlightRecord {
            method: "m".into(),
            seed: 0,
            pair_id: 1,
            bin_m: 200.0,
            shortest_m: 5.0,
            straight_m: 5.0,
            outcome: Outcome::Goal,
            source_m: Point::new(0.0, 0.0, 50.0),
            destination_m: Point::new(5.0, 0.0, 50.0),
            remaining_m: 0.5,
            start_serving: 3,
            steps: vec![
                step(1.0, 3, -70.0, Excellent, 10.0),
                step(2.0, 4, -85.0, Mediocre, -7.0),
                step(3.0, 3, -75.0, Excellent, 3.0),
                step(4.0, 3, -105.0, Poor, -10.0),
                step(6.0, 5, -80.0, Excellent, 0.0),
            ],
        }
    }

    #[test]
    fn class_fractions_distance_overhead_and_rsrp_of_a_hand_built_flight() {
        let mut f = flight();
        // Step 2 served at −85 dBm (mediocre) where site 7 gave −72 (excellent): 13 dB of site
        // regret and class regret; step 4 at −105 where −103 was best: 2 dB, under the 3 dB
        // threshold, no class regret (the best is poor too).
        f.steps[1].best_site = 7;
        f.steps[1].best_rsrp_dbm = -72.0;
        f.steps[1].best_class = RsrpClass::Excellent;
        f.steps[3].best_rsrp_dbm = -103.0;
        let m = flight_metrics(&f, &rules(100, 0.0));
        assert!((m.mean_site_regret_db - 15.0 / 5.0).abs() < 1e-9);
        assert!((m.frac_site_regret_high - 0.2).abs() < 1e-9);
        assert!((m.frac_class_regret - 0.2).abs() < 1e-9);
        assert!((m.distance_m - 6.0).abs() < 1e-9);
        assert!((m.overhead - 0.3).abs() < 1e-9, "(6 + 0.5) / 5 − 1");
        assert_eq!(m.frac_class, [0.6, 0.2, 0.2]);
        assert!((m.mean_rsrp_dbm - (-83.0)).abs() < 1e-9);
        assert!((m.mean_sinr_db - (-0.8)).abs() < 1e-6);
        assert!((m.frac_sinr_below_m6db - 0.4).abs() < 1e-9);
        // 3 → 4 → 3 (back within 1 step: ping-pong) → 5.
        assert_eq!((m.handovers, m.ping_pongs), (3, 1));
        assert!((m.handovers_per_km - 500.0).abs() < 1e-9);
    }

    fn rules(ping_pong_window_steps: u32, interruption_steps: f64) -> MetricRules {
        MetricRules {
            ping_pong_window_steps,
            site_regret_threshold_db: 3.0,
            interruption_steps,
        }
    }

    #[test]
    fn handover_interruptions_are_taken_from_the_excellent_time() {
        // Classes E M E P E, handovers at steps 2 (3 → 4), 3 (4 → 3) and 5 (3 → 5).
        let f = flight();
        // No interruption: the net excellent time is the excellent time.
        let m = flight_metrics(&f, &rules(100, 0.0));
        assert_eq!((m.frac_interrupted, m.frac_excellent_net), (0.0, 0.6));
        // Half a step each: steps 2, 3 and 5 lose half; of them 3 and 5 are excellent.
        let m = flight_metrics(&f, &rules(100, 0.5));
        assert!((m.frac_interrupted - 1.5 / 5.0).abs() < 1e-12);
        assert!((m.frac_excellent_net - 2.0 / 5.0).abs() < 1e-12);
        // 1.5 steps: step 2's interruption is cut short by step 3's handover, which starts a new
        // one (all of step 3, half of step 4); step 5's is cut at the flight's end: 1 + 1 + 0.5
        // + 1 = 3.5 steps interrupted; of the excellent steps 1, 3 and 5 only step 1 is kept.
        let m = flight_metrics(&f, &rules(100, 1.5));
        assert!((m.frac_interrupted - 3.5 / 5.0).abs() < 1e-12, "{m:?}");
        assert!((m.frac_excellent_net - 1.0 / 5.0).abs() < 1e-12, "{m:?}");
        // The start site counts: from site 4, step 1 (site 3) is a handover too.
        let mut g = flight();
        g.start_serving = 4;
        let m = flight_metrics(&g, &rules(100, 0.5));
        assert_eq!(m.handovers, 4);
        assert!((m.frac_excellent_net - 1.5 / 5.0).abs() < 1e-12);
    }

    #[test]
    fn handovers_and_ping_pongs_follow_the_window() {
        // 0 → 1 at step 1, 1 → 0 at step 3: a ping-pong if the window is ≥ 2 steps.
        let s = [0, 1, 1, 0, 0, 2];
        assert_eq!(count_handovers(&s, 2), (3, 1));
        assert_eq!(count_handovers(&s, 1), (3, 0));
        // A → B → C → B: returning to B is not back to the site of the *last* handover (C←B
        // left B, so C → B is a ping-pong).
        assert_eq!(count_handovers(&[0, 1, 2, 1], 5), (3, 1));
        assert_eq!(count_handovers(&[0, 1, 2, 0], 5), (3, 0));
        assert_eq!(count_handovers(&[7; 10], 5), (0, 0));
        assert_eq!(count_handovers(&[], 5), (0, 0));
    }

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

    #[test]
    fn sinr_of_equal_interferers_and_noise() {
        // Serving −70 dBm, two interferers at −73 dBm (each half the power): SINR ≈ 0 dB.
        let s = sinr_db(&[-70.0, -73.0103, -73.0103], 0, -200.0);
        assert!(s.abs() < 1e-3, "{s}");
        // Alone above the noise: RSRP − N.
        let s = sinr_db(&[-100.0, f64::NEG_INFINITY], 0, NOISE_PER_RE_DBM);
        assert!((s - (-100.0 - NOISE_PER_RE_DBM)).abs() < 1e-9);
        assert!((NOISE_PER_RE_DBM - (-123.24)).abs() < 0.01);
    }
}
