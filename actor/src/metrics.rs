//! An episode's metrics (spec/env.md "Metrics"): [`HandoverCounter`] defines handovers and
//! ping-pongs (the environment flags them with it, evaluation recounts recorded flights with
//! [`count_handovers`]); [`EpisodeAccumulator`] folds an episode's [`StepInfo`] records into an
//! [`EpisodeSummary`] (what rollouts report and the learner's rolling metrics read);
//! [`DomainStats`] aggregates a set of summaries (rates per episode, link measures weighted by
//! steps); [`put_domain`] writes them as metrics under one set of keys (`domain/…` for training
//! episodes, `eval/…` for the held-out evaluation: [`dupac_common::metric`]).

use crate::record::StepInfo;
use dupac_common::metric::DomainKeys;
use dupac_common::msg::{EpisodeSummary, Outcome};
use serde::Serialize;
use std::collections::BTreeMap;

/// Accumulates [`StepInfo`] records into an [`EpisodeSummary`].
#[derive(Debug, Clone, Default)]
pub struct EpisodeAccumulator {
    steps: u32,
    rsrp_sum_dbm: f64,
    class_counts: [u32; 3],
    handovers: u32,
    ping_pongs: u32,
    distance_flown_m: f64,
    remaining_m: f64,
    episodic_return: f64,
    regret_sum_db: f64,
    regret_high: u32,
    class_regret: u32,
    /// `env.site_regret_threshold_db`.
    regret_threshold_db: f64,
}

impl EpisodeAccumulator {
    /// An empty accumulator with the metric thresholds of `env`.
    pub fn new(env: &dupac_common::config::EnvConfig) -> EpisodeAccumulator {
        EpisodeAccumulator {
            regret_threshold_db: env.site_regret_threshold_db,
            ..EpisodeAccumulator::default()
        }
    }

    pub fn push(&mut self, info: &StepInfo) {
        let regret_db = info.site_regret_db();
        self.regret_sum_db += regret_db;
        self.regret_high += u32::from(regret_db > self.regret_threshold_db);
        self.class_regret += u32::from(info.class_regret());
        self.steps += 1;
        self.rsrp_sum_dbm += info.serving_rsrp_dbm;
        self.class_counts[info.class.index()] += 1;
        self.handovers += u32::from(info.handover);
        self.ping_pongs += u32::from(info.ping_pong);
        self.distance_flown_m = info.distance_flown_m;
        self.remaining_m = info.distance_to_goal_m;
        self.episodic_return += info.reward;
    }

    pub fn finish(&mut self, pair_id: u64, shortest_m: f64, outcome: Outcome) -> EpisodeSummary {
        let n = f64::from(self.steps.max(1));
        let s = EpisodeSummary {
            pair_id,
            outcome,
            episodic_return: self.episodic_return,
            length: self.steps,
            distance_flown_m: self.distance_flown_m,
            shortest_m,
            remaining_m: self.remaining_m,
            mean_rsrp_dbm: self.rsrp_sum_dbm / n,
            frac_excellent: f64::from(self.class_counts[0]) / n,
            frac_mediocre: f64::from(self.class_counts[1]) / n,
            frac_poor: f64::from(self.class_counts[2]) / n,
            handovers: self.handovers,
            ping_pongs: self.ping_pongs,
            mean_site_regret_db: self.regret_sum_db / n,
            frac_site_regret_high: f64::from(self.regret_high) / n,
            frac_class_regret: f64::from(self.class_regret) / n,
        };
        *self = EpisodeAccumulator {
            regret_threshold_db: self.regret_threshold_db,
            ..EpisodeAccumulator::default()
        };
        s
    }
}

/// Handovers and ping-pongs of a serving-site sequence, one step at a time (spec/env.md
/// "Metrics"): a handover is a change of the serving site; a ping-pong is a handover back to
/// the site the previous handover left, within `window_steps` steps of it. The one definition:
/// the environment's per-step flags (what training's [`EpisodeAccumulator`] counts) and
/// evaluation's recount from recorded serving sites ([`count_handovers`]) both use it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct HandoverCounter {
    window_steps: u32,
    /// The site the last handover left and the step it happened at.
    last: Option<(u16, u32)>,
}

impl HandoverCounter {
    pub fn new(window_steps: u32) -> HandoverCounter {
        HandoverCounter {
            window_steps,
            last: None,
        }
    }

    /// Forgets the last handover (a new episode).
    pub fn reset(&mut self) {
        self.last = None;
    }

    /// The site the last handover left and its step.
    pub fn last(&self) -> Option<(u16, u32)> {
        self.last
    }

    /// Whether a handover from `before` to `now` at step `step` would be a ping-pong (without
    /// recording it).
    pub fn would_ping_pong(&self, before: u16, now: u16, step: u32) -> bool {
        before != now
            && self.last.is_some_and(|(left, at)| {
                left == now && step.saturating_sub(at) <= self.window_steps
            })
    }

    /// The serving site went from `before` to `now` at step `step` (counted from 1):
    /// (handover, ping-pong).
    pub fn step(&mut self, before: u16, now: u16, step: u32) -> (bool, bool) {
        if before == now {
            return (false, false);
        }
        let ping_pong = self.would_ping_pong(before, now, step);
        self.last = Some((before, step));
        (true, ping_pong)
    }
}

/// Handovers and ping-pongs ([`HandoverCounter`]) of a serving-site sequence; the first element
/// is the site at the start (before the first step), as in the environment.
pub fn count_handovers(serving: &[u16], window_steps: u32) -> (u32, u32) {
    let mut counter = HandoverCounter::new(window_steps);
    let (mut handovers, mut ping_pongs) = (0u32, 0u32);
    for (t, w) in serving.windows(2).enumerate() {
        let (h, p) = counter.step(w[0], w[1], t as u32 + 1);
        handovers += u32::from(h);
        ping_pongs += u32::from(p);
    }
    (handovers, ping_pongs)
}

/// Domain metrics over a set of episodes (spec/env.md "Metrics").
#[derive(Debug, Clone, Default, Serialize)]
pub struct DomainStats {
    pub episodes: usize,
    pub success_rate: f64,
    pub collision_rate: f64,
    pub out_of_bounds_rate: f64,
    pub timeout_rate: f64,
    pub episodic_return: f64,
    pub episodic_length: f64,
    /// Mean serving RSRP over all steps (dBm).
    pub mean_rsrp_dbm: f64,
    /// Percent of flight time per class, over all steps.
    pub pct_excellent: f64,
    pub pct_mediocre: f64,
    pub pct_poor: f64,
    /// Handovers per km flown.
    pub handovers_per_km: f64,
    /// Mean distance overhead over the shortest path of the successful episodes (fraction).
    pub distance_overhead: f64,
    /// Mean site regret over all steps: best − serving RSRP (dB).
    pub site_regret_db: f64,
    /// Percent of steps with site regret over `env.site_regret_threshold_db`.
    pub pct_site_regret_high: f64,
    /// Percent of steps with class regret (best site excellent, serving one not).
    pub pct_class_regret: f64,
}

/// Aggregates episode summaries (step-weighted for RSRP and classes).
pub fn domain_stats(eps: &[EpisodeSummary]) -> DomainStats {
    let n = eps.len();
    if n == 0 {
        return DomainStats::default();
    }
    let nf = n as f64;
    let rate = |o: Outcome| eps.iter().filter(|e| e.outcome == o).count() as f64 / nf;
    let steps: f64 = eps
        .iter()
        .map(|e| f64::from(e.length))
        .sum::<f64>()
        .max(1.0);
    let w = |f: &dyn Fn(&EpisodeSummary) -> f64| {
        eps.iter().map(|e| f(e) * f64::from(e.length)).sum::<f64>() / steps
    };
    let km: f64 = eps.iter().map(|e| e.distance_flown_m).sum::<f64>() / 1000.0;
    let ho: f64 = eps.iter().map(|e| f64::from(e.handovers)).sum();
    let ok: Vec<&EpisodeSummary> = eps.iter().filter(|e| e.outcome == Outcome::Goal).collect();
    DomainStats {
        episodes: n,
        success_rate: rate(Outcome::Goal),
        collision_rate: rate(Outcome::Collision),
        out_of_bounds_rate: rate(Outcome::OutOfBounds),
        timeout_rate: rate(Outcome::TimeLimit),
        episodic_return: eps.iter().map(|e| e.episodic_return).sum::<f64>() / nf,
        episodic_length: eps.iter().map(|e| f64::from(e.length)).sum::<f64>() / nf,
        mean_rsrp_dbm: w(&|e| e.mean_rsrp_dbm),
        pct_excellent: 100.0 * w(&|e| e.frac_excellent),
        pct_mediocre: 100.0 * w(&|e| e.frac_mediocre),
        pct_poor: 100.0 * w(&|e| e.frac_poor),
        handovers_per_km: if km > 0.0 { ho / km } else { 0.0 },
        distance_overhead: if ok.is_empty() {
            f64::NAN
        } else {
            ok.iter().map(|e| e.overhead()).sum::<f64>() / ok.len() as f64
        },
        site_regret_db: w(&|e| e.mean_site_regret_db),
        pct_site_regret_high: 100.0 * w(&|e| e.frac_site_regret_high),
        pct_class_regret: 100.0 * w(&|e| e.frac_class_regret),
    }
}

/// Adds the domain statistics under `keys` ([`dupac_common::metric::TRAIN`] or `EVAL`).
pub fn put_domain(row: &mut BTreeMap<String, f64>, keys: &DomainKeys, d: &DomainStats) {
    let mut put = |k: &str, v: f64| {
        row.insert(k.to_string(), v);
    };
    put(keys.episodes, d.episodes as f64);
    put(keys.success_rate, d.success_rate);
    put(keys.collision_rate, d.collision_rate);
    put(keys.out_of_bounds_rate, d.out_of_bounds_rate);
    put(keys.timeout_rate, d.timeout_rate);
    put(keys.mean_rsrp_dbm, d.mean_rsrp_dbm);
    put(keys.pct_excellent, d.pct_excellent);
    put(keys.pct_mediocre, d.pct_mediocre);
    put(keys.pct_poor, d.pct_poor);
    put(keys.handovers_per_km, d.handovers_per_km);
    put(keys.distance_overhead, d.distance_overhead);
    put(keys.site_regret_db, d.site_regret_db);
    put(keys.pct_site_regret_high, d.pct_site_regret_high);
    put(keys.pct_class_regret, d.pct_class_regret);
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
