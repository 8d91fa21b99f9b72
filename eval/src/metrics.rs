//! A recorded flight's metrics (spec/env.md "Metrics"), what `dupac eval` reports:
//! [`flight_metrics`] measures a [`FlightRecord`] under the [`MetricRules`] its records file
//! keeps ([`FlightMetrics`]: distance, overhead, class fractions, handovers counted from the
//! flight's start site with [`count_handovers`], SINR, site and class regret, excellent time net
//! of handover interruptions).

use crate::record::FlightRecord;
use dupac_actor::metrics::count_handovers;
use dupac_common::geometry::Point;
use dupac_common::msg::Outcome;
use dupac_radio::class::RsrpClass;
use serde::Serialize;

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
}
