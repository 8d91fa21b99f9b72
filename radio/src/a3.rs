//! The base method: 3GPP event-A3 handover with time-to-trigger (spec/radio.md §4, TS 36.331
//! §5.5.4.4 with all Of*/Oc* = 0, decision D15), evaluated as a UE does.
//!
//! The UE's measurement changes only when a new one arrives: once per measurement period under
//! the real channel (`radio.channel.measurement_period_ms`, 200 ms: 4 steps of 48 ms), every
//! step in the deterministic world. A3's own layer-3 filter `F = (1 − a) F + a M` (when
//! `radio.a3.l3_filter_k` is set, a = 1/2^(k/4) per 200 ms adapted to the period, TS 36.331
//! §5.5.3.2) runs once per new measurement. For each neighbour n ≠ s the entering condition
//! `F_n − Hys > F_s + Off` (strict) starts the neighbour's timeToTrigger timer at the step it
//! first holds and a step where it fails stops it; the UAV hands over at the first step at which
//! some timer has run for at least TTT — on the clock, as ns-3's `LteUeRrc` does (a timer
//! expires between measurements; the next measurement can stop it). So a TTT shorter than the
//! period only delays the handover: what it sees is one report. The handover goes to the
//! triggered neighbour with the highest value, and all timers stop.

use dupac_common::config::A3Config;
use dupac_common::ids::SiteId;

/// Sites addressable by a [`SiteId`] (`u16`): entries of a measurement slice beyond this are
/// ignored.
const MAX_SITES: usize = u16::MAX as usize + 1;

/// Relative tolerance when converting TTT to steps: a quotient within this of an integer is that
/// integer (float noise such as 0.16/0.04 must not round up to 5).
const TTT_STEP_TOL: f64 = 1e-9;

/// A3 parameters in simulator units (spec/radio.md §4, D15).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct A3Params {
    /// a3-Offset `Off` (dB), default 3.
    pub offset_db: f64,
    /// Hysteresis `Hys` (dB), default 1.
    pub hysteresis_db: f64,
    /// timeToTrigger in whole simulator steps, `⌈TTT/Δt⌉` (4 for 160 ms at Δt = 48 ms, 0 for
    /// TTT = 0): a timer that has run this many steps has run at least TTT.
    pub ttt_steps: u32,
    /// Optional L3 filter coefficient k of A3's own filter (`a = 1/2^(k/4)` per 200 ms);
    /// `None` = A3 compares the measurements as the UAV holds them (default).
    pub l3_filter_k: Option<u32>,
    /// The measurement period (s) the filter's coefficient is adapted to: the channel's period,
    /// or one step where every step is measured.
    pub measurement_period_s: f64,
}

impl A3Params {
    /// Converts the config (spec/radio.md §4): `ttt_steps = ⌈time_to_trigger_ms / 1000 /
    /// dt_s⌉`, `dt_s` the simulator step in seconds; `measurement_period_s` the period of the
    /// UAV's measurements (s). A quotient within a relative 1e−9 of an integer counts as that
    /// integer (160 ms / 40 ms = 4, not 5; 160 ms / 48 ms → 4). A non-finite or non-positive
    /// `dt_s`, or a non-finite TTT, gives 0 steps; huge quotients saturate at `u32::MAX`.
    pub fn from_config(cfg: &A3Config, dt_s: f64, measurement_period_s: f64) -> Self {
        Self {
            offset_db: cfg.offset_db,
            hysteresis_db: cfg.hysteresis_db,
            ttt_steps: ttt_steps(cfg.time_to_trigger_ms, dt_s),
            l3_filter_k: cfg.l3_filter_k,
            measurement_period_s,
        }
    }

    /// A3's own L3 filter weight a of the newest measurement (TS 36.331 §5.5.3.2: 1/2^(k/4) per
    /// 200 ms, adapted to the measurement period, [`crate::channel::l3_coefficient`]), `None`
    /// when A3 has no filter of its own. k = 4 at 200 ms gives 0.5, k = 0 gives 1 (no
    /// smoothing).
    pub fn l3_filter_weight(&self) -> Option<f64> {
        self.l3_filter_k
            .map(|k| crate::channel::l3_coefficient(k, self.measurement_period_s))
    }
}

/// `⌈ttt_ms / 1000 / dt_s⌉` with the float-noise guard of [`A3Params::from_config`].
fn ttt_steps(ttt_ms: f64, dt_s: f64) -> u32 {
    if !(dt_s.is_finite() && dt_s > 0.0 && ttt_ms.is_finite()) {
        return 0;
    }
    let x = ttt_ms / 1000.0 / dt_s;
    let r = x.round();
    let steps = if (x - r).abs() <= TTT_STEP_TOL * r.abs().max(1.0) {
        r
    } else {
        x.ceil()
    };
    // `as` saturates (negative → 0, huge → u32::MAX).
    steps as u32
}

/// A handover decided by [`A3State::step`] (spec/radio.md §4 item 3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Handover {
    /// Serving GBS before the step.
    pub from: SiteId,
    /// New serving GBS, effective at this step.
    pub to: SiteId,
}

/// A3 state of one UAV: serving GBS, per-neighbour timeToTrigger timers and the L3 filter state
/// (spec/radio.md §4). Buffers are allocated at construction; [`A3State::step`] does not
/// allocate unless the number of sites changes.
#[derive(Debug, Clone)]
pub struct A3State {
    params: A3Params,
    /// L3 filter weight a, `None` without filter.
    filter_a: Option<f64>,
    serving: usize,
    /// `cnt[n]`, consecutive steps with the entering condition, counting the step it first held
    /// (a timer that has run `cnt − 1` steps); always 0 for the serving site.
    counters: Vec<u32>,
    /// Filtered measurements F (dBm), only used with the L3 filter.
    filtered: Vec<f64>,
}

/// NaN counts as −∞ (never the best, never triggers).
#[inline]
fn sanitize(x: f64) -> f64 {
    if x.is_nan() { f64::NEG_INFINITY } else { x }
}

/// Index of the largest value (NaN = −∞), lowest index on ties; 0 for an empty slice.
fn argmax(values: &[f64]) -> usize {
    let mut best = 0usize;
    let mut best_v = f64::NEG_INFINITY;
    for (i, &v) in values.iter().enumerate().take(MAX_SITES) {
        let v = sanitize(v);
        if v > best_v {
            best_v = v;
            best = i;
        }
    }
    best
}

/// `SiteId` of an index below [`MAX_SITES`].
#[inline]
fn site_id(i: usize) -> SiteId {
    SiteId(u16::try_from(i).unwrap_or(u16::MAX))
}

impl A3State {
    /// Starts at t = 0 (spec/radio.md §4 item 1): serving GBS = argmax of `rsrp_dbm` (dBm, one
    /// entry per site indexed by [`SiteId`]; lowest index on ties; NaN counts as −∞), counters 0,
    /// L3 filter (if any) initialised to this first measurement. An empty slice gives serving
    /// `SiteId(0)` and no counters; it does not panic.
    pub fn new(params: A3Params, rsrp_dbm: &[f64]) -> Self {
        let mut s = Self {
            params,
            filter_a: params.l3_filter_weight(),
            serving: 0,
            counters: Vec::new(),
            filtered: Vec::new(),
        };
        s.reset(rsrp_dbm);
        s
    }

    /// Restarts as [`A3State::new`] with the same parameters (new episode), reusing the buffers.
    pub fn reset(&mut self, rsrp_dbm: &[f64]) {
        let n = rsrp_dbm.len().min(MAX_SITES);
        self.serving = argmax(rsrp_dbm);
        self.counters.clear();
        self.counters.resize(n, 0);
        self.filtered.clear();
        if self.filter_a.is_some() {
            self.filtered
                .extend(rsrp_dbm.iter().take(n).map(|&v| sanitize(v)));
        }
    }

    /// The parameters (spec/radio.md §4).
    pub fn params(&self) -> &A3Params {
        &self.params
    }

    /// Current serving GBS (spec/radio.md §4).
    pub fn serving(&self) -> SiteId {
        site_id(self.serving)
    }

    /// TTT counters `cnt[n]` per site: the steps the entering condition has held, counting the
    /// step it first held (spec/radio.md §4 item 2); the serving site's entry is always 0.
    pub fn counters(&self) -> &[u32] {
        &self.counters
    }

    /// One step (spec/radio.md §4 items 2–3) with `rsrp_dbm` = what the UAV holds of every
    /// site's RSRP (dBm, best sector), indexed by [`SiteId`]; `fresh` = a new measurement
    /// arrived at this step (between measurements the UAV holds the last one).
    ///
    /// With A3's own L3 filter a fresh measurement first updates `F = (1 − a) F + a M` (a filter
    /// that holds no finite value restarts from the next finite measurement) and F is used
    /// below; a step without a fresh measurement leaves F as it is. For each neighbour n ≠ s:
    /// `F_n − Hys > F_s + Off` (strict) → `cnt[n] += 1`, else `cnt[n] = 0`. If some
    /// `cnt[n] > ttt_steps` (its timer has run `cnt − 1 ≥ ⌈TTT/Δt⌉` steps), the serving site
    /// changes to the triggered neighbour with the highest (filtered) measurement (lowest index
    /// on ties), effective now, and every counter is reset; the handover is returned.
    ///
    /// NaN measurements count as −∞. If the slice length differs from the previous one, the
    /// buffers are resized once (new sites start with counter 0 and, with a filter, with this
    /// measurement); a serving site missing from a shorter slice is measured as −∞, so any
    /// neighbour with a finite measurement triggers. Entries beyond 65 536 sites are ignored.
    pub fn step(&mut self, rsrp_dbm: &[f64], fresh: bool) -> Option<Handover> {
        let n = rsrp_dbm.len().min(MAX_SITES);
        let meas = &rsrp_dbm[..n];
        if self.counters.len() != n {
            self.counters.resize(n, 0);
        }
        if let Some(a) = self.filter_a {
            if self.filtered.len() != n {
                let old = self.filtered.len().min(n);
                self.filtered.truncate(n);
                self.filtered
                    .extend(meas[old..].iter().map(|&v| sanitize(v)));
            }
            for (f, &m) in self.filtered.iter_mut().zip(meas).filter(|_| fresh) {
                let m = sanitize(m);
                *f = if f.is_finite() {
                    (1.0 - a) * *f + a * m
                } else {
                    m
                };
            }
        }
        let values: &[f64] = if self.filter_a.is_some() {
            &self.filtered
        } else {
            meas
        };

        let serving = self.serving;
        let serving_v = values
            .get(serving)
            .map_or(f64::NEG_INFINITY, |&v| sanitize(v));
        let threshold = serving_v + self.params.offset_db;
        let hys = self.params.hysteresis_db;
        let ttt = self.params.ttt_steps;
        let mut target: Option<(usize, f64)> = None;
        for (i, (cnt, &v)) in self.counters.iter_mut().zip(values).enumerate() {
            if i == serving {
                *cnt = 0;
                continue;
            }
            let v = sanitize(v);
            if v - hys > threshold {
                *cnt = cnt.saturating_add(1);
            } else {
                *cnt = 0;
            }
            if *cnt > ttt && target.is_none_or(|(_, best)| v > best) {
                target = Some((i, v));
            }
        }
        let (to, _) = target?;
        self.serving = to;
        self.counters.iter_mut().for_each(|c| *c = 0);
        Some(Handover {
            from: site_id(serving),
            to: site_id(to),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Hands over at the `trigger_at`-th consecutive step with the entering condition (a TTT of
    /// `trigger_at − 1` steps); measurements every 200 ms for the filter's coefficient.
    fn params(trigger_at: u32) -> A3Params {
        A3Params {
            offset_db: 3.0,
            hysteresis_db: 1.0,
            ttt_steps: trigger_at - 1,
            l3_filter_k: None,
            measurement_period_s: 0.2,
        }
    }

    fn cfg(ttt_ms: f64) -> A3Config {
        A3Config {
            time_to_trigger_ms: ttt_ms,
            ..A3Config::default()
        }
    }

    #[test]
    fn ttt_step_conversion() {
        let steps =
            |ttt_ms: f64, dt_s: f64| A3Params::from_config(&cfg(ttt_ms), dt_s, 0.2).ttt_steps;
        // 0.16 / 0.048 = 3.33 → 4
        assert_eq!(steps(160.0, 0.048), 4);
        // 0.16 / 0.04 = 4 (not 5 from float noise)
        assert_eq!(steps(160.0, 0.04), 4);
        // 0.16 / 1 = 0.16 → 1
        assert_eq!(steps(160.0, 1.0), 1);
        // TTT = 0 → 0: the step the condition first holds
        assert_eq!(steps(0.0, 0.048), 0);
        // 1.1 / 0.1 = 11.000000000000002 in f64 → 11, not 12
        assert_eq!(steps(1100.0, 0.1), 11);
        // 0.1 / 0.04 = 2.5 → 3;  0.16 / 0.05 = 3.1999999999999997 → 4;  1.28 / 0.064 = 20
        assert_eq!(steps(100.0, 0.04), 3);
        assert_eq!(steps(160.0, 0.05), 4);
        assert_eq!(steps(1280.0, 0.064), 20);
        // bad Δt → 0
        assert_eq!(steps(160.0, 0.0), 0);
        assert_eq!(steps(160.0, f64::NAN), 0);
        let p = A3Params::from_config(&A3Config::default(), 0.048, 0.2);
        assert_eq!(p, params(5));
    }

    #[test]
    fn l3_weight() {
        // a = 1/2^(k/4) per 200 ms: k=4 → 0.5, k=8 → 0.25, k=0 → 1
        let mut p = params(1);
        assert_eq!(p.l3_filter_weight(), None);
        p.l3_filter_k = Some(4);
        assert_eq!(p.l3_filter_weight(), Some(0.5));
        p.l3_filter_k = Some(8);
        assert_eq!(p.l3_filter_weight(), Some(0.25));
        p.l3_filter_k = Some(0);
        assert_eq!(p.l3_filter_weight(), Some(1.0));
        // per 400 ms at k = 4: 1 − (1 − 0.5)² = 0.75
        p.l3_filter_k = Some(4);
        p.measurement_period_s = 0.4;
        assert!((p.l3_filter_weight().expect("a filter") - 0.75).abs() < 1e-12);
    }

    /// Steps (0-based) at which A3 hands over from site 0 to site 1 on a hand-made series: one
    /// measurement every 4 steps of 50 ms (a 200 ms period); site 1 is 10 dB above the serving
    /// site from the measurement at step 0 and `then_dbm` from the measurement at step 4.
    fn handover_step(ttt_ms: f64, then_dbm: f64) -> Option<u32> {
        let a3 = A3Config {
            time_to_trigger_ms: ttt_ms,
            ..A3Config::default()
        };
        let p = A3Params::from_config(&a3, 0.05, 0.2);
        let mut s = A3State::new(p, &[-80.0, -90.0]);
        (0..12).find(|&t| {
            let m = if t < 4 {
                [-80.0, -70.0]
            } else {
                [-80.0, then_dbm]
            };
            s.step(&m, t % 4 == 0).is_some()
        })
    }

    #[test]
    fn ttt_runs_on_the_clock_between_measurements() {
        // The measurement at step 4 ends the entering condition (−78 − 1 > −77 is false): a TTT
        // shorter than the period expires before it, at the first step ≥ TTT after the
        // condition first held (40 ms → step 1, 64–100 ms → 2, 128 ms → 3); 160 ms and longer
        // would expire at or after step 4, which the new measurement stops.
        for (ttt, at) in [
            (0.0, Some(0)),
            (40.0, Some(1)),
            (64.0, Some(2)),
            (80.0, Some(2)),
            (100.0, Some(2)),
            (128.0, Some(3)),
            (160.0, None),
            (256.0, None),
            (320.0, None),
        ] {
            assert_eq!(handover_step(ttt, -78.0), at, "TTT {ttt} ms");
        }
        // When the measurement at step 4 still meets the condition, the timer runs on: 160 ms at
        // step 4, 256 ms (5.12 steps) at step 6, 320 ms (6.4) at step 7, 640 ms at step 13 —
        // past the series.
        for (ttt, at) in [
            (160.0, Some(4)),
            (256.0, Some(6)),
            (320.0, Some(7)),
            (640.0, None),
        ] {
            assert_eq!(handover_step(ttt, -70.0), at, "TTT {ttt} ms");
        }
    }

    #[test]
    fn a3_filters_once_per_measurement() {
        // k = 4 at a 200 ms period (a = 0.5), F = [−80, −85]. The neighbour jumps to −70 at the
        // measurement of step 0 and is held for the period's 4 steps: F1 = −77.5 (−78.5 > −77
        // fails) and stays there until the next measurement, F2 = −73.75 at step 4, which
        // meets the condition; TTT 0 hands over there. Filtering each held step again would
        // reach −73.75 at step 1.
        let a3 = A3Config {
            time_to_trigger_ms: 0.0,
            l3_filter_k: Some(4),
            ..A3Config::default()
        };
        let p = A3Params::from_config(&a3, 0.05, 0.2);
        let mut s = A3State::new(p, &[-80.0, -85.0]);
        let at = (0..8).find(|&t| s.step(&[-80.0, -70.0], t % 4 == 0).is_some());
        assert_eq!(at, Some(4));
    }

    #[test]
    fn initial_serving_is_argmax() {
        let s = A3State::new(params(4), &[-90.0, -70.0, -80.0]);
        assert_eq!(s.serving(), SiteId(1));
        assert_eq!(s.counters(), &[0, 0, 0]);
        // ties → lowest index; NaN = −∞
        assert_eq!(
            A3State::new(params(4), &[f64::NAN, -70.0, -70.0]).serving(),
            SiteId(1)
        );
        assert_eq!(
            A3State::new(params(4), &[f64::NAN, f64::NAN]).serving(),
            SiteId(0)
        );
        // empty → SiteId(0), no panic, no handover
        let mut e = A3State::new(params(4), &[]);
        assert_eq!(e.serving(), SiteId(0));
        assert!(e.counters().is_empty());
        assert_eq!(e.step(&[], true), None);
    }

    #[test]
    fn no_handover_below_offset_plus_hysteresis() {
        // Neighbour 3.9 dB better: −76.1 − 1 > −80 + 3 ⇔ −77.1 > −77 is false.
        let mut s = A3State::new(params(1), &[-80.0, -90.0]);
        for _ in 0..20 {
            assert_eq!(s.step(&[-80.0, -76.1], true), None);
            assert_eq!(s.counters(), &[0, 0]);
        }
        // Exactly 4 dB: −77 > −77 is false (strict).
        for _ in 0..20 {
            assert_eq!(s.step(&[-80.0, -76.0], true), None);
        }
        // 4.1 dB with TTT = 1 step: −76.9 > −77 → immediate handover.
        assert_eq!(
            s.step(&[-80.0, -75.9], true),
            Some(Handover {
                from: SiteId(0),
                to: SiteId(1)
            })
        );
        assert_eq!(s.serving(), SiteId(1));
    }

    #[test]
    fn exactly_ttt_steps_trigger_and_a_dip_resets() {
        let mut s = A3State::new(params(4), &[-80.0, -90.0]);
        let good = [-80.0, -70.0]; // −71 > −77
        let dip = [-80.0, -77.0]; // −78 > −77 false
        assert_eq!(s.step(&good, true), None);
        assert_eq!(s.counters(), &[0, 1]);
        assert_eq!(s.step(&good, true), None);
        assert_eq!(s.step(&good, true), None);
        assert_eq!(s.counters(), &[0, 3]);
        assert_eq!(s.step(&dip, true), None);
        assert_eq!(s.counters(), &[0, 0]);
        assert_eq!(s.step(&good, true), None);
        assert_eq!(s.step(&good, true), None);
        assert_eq!(s.step(&good, true), None);
        assert_eq!(s.serving(), SiteId(0));
        // 4th consecutive step → handover, effective now
        assert_eq!(
            s.step(&good, true),
            Some(Handover {
                from: SiteId(0),
                to: SiteId(1)
            })
        );
        assert_eq!(s.serving(), SiteId(1));
        assert_eq!(s.counters(), &[0, 0]);
        // new serving 1 at −70: site 0 at −80 does not trigger back
        assert_eq!(s.step(&good, true), None);
        assert_eq!(s.counters(), &[0, 0]);
    }

    #[test]
    fn highest_rsrp_wins_among_triggered() {
        // Sites 1 and 2 both trigger from the first step; site 3 is better but starts late.
        let mut s = A3State::new(params(2), &[-80.0, -90.0, -90.0, -90.0]);
        assert_eq!(s.step(&[-80.0, -72.0, -70.0, -90.0], true), None);
        assert_eq!(s.counters(), &[0, 1, 1, 0]);
        // step 2: cnt = [0, 2, 2, 1]; site 3 (−60) not yet at TTT → highest triggered is 2
        let ho = s.step(&[-80.0, -72.0, -70.0, -60.0], true);
        assert_eq!(
            ho,
            Some(Handover {
                from: SiteId(0),
                to: SiteId(2)
            })
        );
        // all counters reset after the handover
        assert_eq!(s.counters(), &[0, 0, 0, 0]);
        assert_eq!(s.serving(), SiteId(2));
    }

    #[test]
    fn tie_between_triggered_goes_to_lowest_index() {
        let mut s = A3State::new(params(1), &[-80.0, -90.0, -90.0]);
        let ho = s.step(&[-80.0, -70.0, -70.0], true);
        assert_eq!(ho.map(|h| h.to), Some(SiteId(1)));
    }

    #[test]
    fn counters_restart_after_handover() {
        let mut s = A3State::new(params(2), &[-80.0, -90.0, -90.0]);
        // site 2 counts one step, then site 1 hands over at step 2 while site 2 keeps triggering
        assert_eq!(s.step(&[-80.0, -70.0, -75.0], true), None);
        assert_eq!(s.counters(), &[0, 1, 1]);
        assert_eq!(
            s.step(&[-80.0, -70.0, -75.0], true).map(|h| h.to),
            Some(SiteId(1))
        );
        assert_eq!(s.counters(), &[0, 0, 0]);
        // site 2 now needs M2 − 1 > −70 + 3: at −60 it counts from 0 again
        assert_eq!(s.step(&[-80.0, -70.0, -60.0], true), None);
        assert_eq!(s.counters(), &[0, 0, 1]);
        assert_eq!(
            s.step(&[-80.0, -70.0, -60.0], true).map(|h| h.to),
            Some(SiteId(2))
        );
    }

    #[test]
    fn l3_filter_delays_the_handover() {
        // Serving −80, neighbour jumps −85 → −70 at step 1, TTT = 4 steps.
        let seq = [-80.0, -70.0];
        let mut plain = A3State::new(params(4), &[-80.0, -85.0]);
        let plain_at = (1..=20).find(|_| plain.step(&seq, true).is_some());
        // unfiltered: triggers at steps 1..4 → handover at step 4
        assert_eq!(plain_at, Some(4));

        // k = 4, a = 0.5, F initialised to [−80, −85]:
        //   F1 = −77.5   → −78.5 > −77? no  (cnt 0)
        //   F2 = −73.75  → yes (1); F3 = −71.875 (2); F4 = −70.9375 (3); F5 = −70.46875 (4)
        let mut p = params(4);
        p.l3_filter_k = Some(4);
        let mut filt = A3State::new(p, &[-80.0, -85.0]);
        assert_eq!(filt.step(&seq, true), None);
        assert_eq!(filt.counters(), &[0, 0]);
        let filt_at = (2..=20).find(|_| filt.step(&seq, true).is_some());
        assert_eq!(filt_at, Some(5));
    }

    #[test]
    fn nan_and_length_changes_do_not_panic() {
        let mut s = A3State::new(params(1), &[-80.0, -90.0]);
        // NaN neighbour never triggers
        assert_eq!(s.step(&[-80.0, f64::NAN], true), None);
        // a longer slice: site 2 appears and triggers
        assert_eq!(
            s.step(&[-80.0, -90.0, -70.0], true).map(|h| h.to),
            Some(SiteId(2))
        );
        assert_eq!(s.counters().len(), 3);
        // a shorter slice without the serving site 2: serving = −∞, site 0 takes over
        assert_eq!(
            s.step(&[-95.0, -99.0], true),
            Some(Handover {
                from: SiteId(2),
                to: SiteId(0)
            })
        );
        assert_eq!(s.counters().len(), 2);
        // NaN serving counts as −∞
        let mut s = A3State::new(params(1), &[-80.0, -90.0]);
        assert_eq!(
            s.step(&[f64::NAN, -90.0], true).map(|h| h.to),
            Some(SiteId(1))
        );
        // the same with an L3 filter
        let mut p = params(1);
        p.l3_filter_k = Some(4);
        let mut s = A3State::new(p, &[-80.0, f64::NAN]);
        assert_eq!(s.step(&[-80.0, f64::NAN], true), None);
        // filter of site 1 restarts from the first finite value: F1 = −60 → triggers
        assert_eq!(s.step(&[-80.0, -60.0], true).map(|h| h.to), Some(SiteId(1)));
        // two new sites appear (filters start at their measurement); both trigger, −40 wins
        assert_eq!(
            s.step(&[-80.0, -60.0, -50.0, -40.0], true).map(|h| h.to),
            Some(SiteId(3))
        );
    }

    #[test]
    fn reset_restarts_the_episode() {
        let mut s = A3State::new(params(4), &[-80.0, -90.0]);
        s.step(&[-80.0, -70.0], true);
        assert_eq!(s.counters(), &[0, 1]);
        s.reset(&[-90.0, -80.0, -85.0]);
        assert_eq!(s.serving(), SiteId(1));
        assert_eq!(s.counters(), &[0, 0, 0]);
        assert_eq!(s.params().ttt_steps, 3);
    }
}
