//! Per-flight metrics (spec/env.md "Metrics"), the one place for training's and evaluation's:
//! [`HandoverCounter`] defines handovers and ping-pongs (the environment flags them with it,
//! evaluation recounts recorded flights with it); [`flight_metrics`] measures a recorded flight
//! ([`FlightMetrics`], what `dupac eval` reports); [`EpisodeAccumulator`] folds an episode's [`StepInfo`] records into an
//! [`EpisodeSummary`] (what rollouts report and the learner's rolling metrics read);
//! [`DomainStats`] aggregates a set of summaries (rates per episode, link measures weighted by
//! steps); [`put_domain`] writes them as metrics under one set of keys (`domain/…` for training
//! episodes, `eval/…` for the held-out evaluation: [`dupac_common::metric`]).

use crate::record::{FlightRecord, StepInfo};
use dupac_common::geometry::Point;
use dupac_common::metric::DomainKeys;
use dupac_common::msg::{EpisodeSummary, Outcome};
use dupac_radio::class::RsrpClass;
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

/// Metrics of one flight (spec/env.md "Metrics").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct FlightMetrics {
    pub outcome: Outcome,
    /// Flight distance L: the sum of step lengths (m).
    pub distance_m: f64,
    /// (L + remaining) / D − 1 against the shortest flyable path D (a success ends within the
    /// goal radius; the remainder is counted as flown, as in training's `distance_overhead`).
    pub overhead: f64,
    /// Mean serving RSRP over the steps (dBm).
    pub mean_rsrp_dbm: f64,
    /// Fraction of flight time (= of steps) in excellent / mediocre / poor RSRP.
    pub frac_class: [f64; 3],
    pub handovers: u32,
    pub ping_pongs: u32,
    /// Handovers per km flown.
    pub handovers_per_km: f64,
    pub mean_sinr_db: f64,
    /// Fraction of flight time with SINR < −6 dB (below which an LTE link is hardly usable).
    pub frac_sinr_below_m6db: f64,
    /// Mean site regret: best RSRP − serving RSRP over the steps (dB).
    pub mean_site_regret_db: f64,
    /// Fraction of flight time with site regret over the threshold (`env.site_regret_threshold_db`).
    pub frac_site_regret_high: f64,
    /// Fraction of flight time with class regret: the best site excellent, the serving one not.
    pub frac_class_regret: f64,
    /// Fraction of flight time the link is interrupted by handovers: each handover interrupts
    /// it for `radio.handover_interruption_ms` from the step it happens at (cut at the flight's
    /// end; a handover during an interruption starts a new one).
    pub frac_interrupted: f64,
    /// Fraction of flight time in excellent RSRP and not interrupted by a handover: the
    /// excellent time a user of the link has.
    pub frac_excellent_net: f64,
}

/// What the metrics of a recorded flight need from the configuration: kept in evaluation's
/// records files, so a report is computed from them alone.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, serde::Deserialize)]
pub struct MetricRules {
    /// `env.ping_pong_window_s` in steps.
    pub ping_pong_window_steps: u32,
    /// Site regret that counts as high (dB; `env.site_regret_threshold_db`).
    pub site_regret_threshold_db: f64,
    /// The link's interruption per handover, in steps (`radio.handover_interruption_ms` / Δt).
    pub interruption_steps: f64,
}

impl MetricRules {
    /// The rules of `cfg`.
    pub fn from_config(cfg: &dupac_common::config::Config) -> MetricRules {
        let dt_s = cfg.env.dt_s();
        MetricRules {
            ping_pong_window_steps: (cfg.env.ping_pong_window_s / dt_s).ceil().max(1.0) as u32,
            site_regret_threshold_db: cfg.env.site_regret_threshold_db,
            interruption_steps: cfg.radio.handover_interruption_ms / 1000.0 / dt_s,
        }
    }
}

/// The metrics of `r` under `rules`. Handovers are counted from `r.start_serving`, the site the
/// environment served before the first step.
pub fn flight_metrics(r: &FlightRecord, rules: &MetricRules) -> FlightMetrics {
    let start_serving = r.start_serving;
    let (ping_pong_window_steps, site_regret_threshold_db) =
        (rules.ping_pong_window_steps, rules.site_regret_threshold_db);
    let n = r.steps.len().max(1) as f64;
    let mut distance_m = 0.0;
    let mut prev = r.source_m;
    let mut frac_class = [0.0; 3];
    let (mut rsrp, mut sinr, mut low_sinr) = (0.0, 0.0, 0.0);
    let (mut regret, mut regret_high, mut class_regret) = (0.0, 0.0, 0.0);
    // Link time lost to handover interruptions (steps), and the excellent time outside them.
    let (mut interrupted, mut excellent_net, mut interruption_left) = (0.0, 0.0, 0.0f64);
    let mut serving = Vec::with_capacity(r.steps.len() + 1);
    serving.push(start_serving);
    for s in &r.steps {
        if s.serving != *serving.last().unwrap_or(&start_serving) {
            interruption_left = rules.interruption_steps;
        }
        let lost = interruption_left.min(1.0);
        interruption_left -= lost;
        interrupted += lost;
        if s.class == RsrpClass::Excellent {
            excellent_net += 1.0 - lost;
        }
        let p = Point::from(s.position_m.map(f64::from));
        distance_m += dupac_common::geometry::distance_m(p, prev);
        prev = p;
        frac_class[s.class.index()] += 1.0;
        rsrp += f64::from(s.serving_rsrp_dbm);
        sinr += f64::from(s.sinr_db);
        if s.sinr_db < -6.0 {
            low_sinr += 1.0;
        }
        let r_db = f64::from(s.best_rsrp_dbm - s.serving_rsrp_dbm).max(0.0);
        regret += r_db;
        if r_db > site_regret_threshold_db {
            regret_high += 1.0;
        }
        if s.best_class == RsrpClass::Excellent && s.class != RsrpClass::Excellent {
            class_regret += 1.0;
        }
        serving.push(s.serving);
    }
    let (handovers, ping_pongs) = count_handovers(&serving, ping_pong_window_steps);
    let (frac_class, rsrp, sinr, low_sinr) =
        (frac_class.map(|c| c / n), rsrp / n, sinr / n, low_sinr / n);
    FlightMetrics {
        outcome: r.outcome,
        distance_m,
        overhead: (distance_m + r.remaining_m) / r.shortest_m - 1.0,
        mean_rsrp_dbm: rsrp,
        frac_class,
        handovers,
        ping_pongs,
        handovers_per_km: if distance_m > 0.0 {
            f64::from(handovers) / (distance_m / 1000.0)
        } else {
            0.0
        },
        mean_sinr_db: sinr,
        frac_sinr_below_m6db: low_sinr,
        mean_site_regret_db: regret / n,
        frac_site_regret_high: regret_high / n,
        frac_class_regret: class_regret / n,
        frac_interrupted: interrupted / n,
        frac_excellent_net: excellent_net / n,
    }
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
    use crate::record::{FlightRecord, StepRecord};
    use dupac_common::geometry::Point;
    use dupac_common::msg::Outcome;
    use dupac_radio::class::RsrpClass;

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
}
