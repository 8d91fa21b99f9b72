//! A flight flown once, re-associated by every A3 setting (`dupac eval --a3-front`, `dupac
//! tune-a3`). A flight's moves do not depend on which site serves it: its positions, every
//! site's true RSRP, what the UAV measures of each site (held, and the unfiltered measurement
//! with its fresh flag) and each site's SINR and line of sight are the same for every setting.
//! [`ReplayTrace::fly`] flies the flight once through [`Env`] and keeps them per step;
//! [`ReplayTrace::a3_serving`] runs A3's own state machine ([`A3State`], as `Env` runs it) over
//! them, and [`ReplayTrace::record`] writes the flight's record as `Env` would have flown it with
//! that serving sequence (handovers and ping-pongs by [`HandoverCounter`], SINR by
//! [`crate::sinr`]). The tests below check, on real flights in both worlds, that every setting
//! gives the `FlightMetrics` of the flight re-flown through `Env` with that setting.

use crate::a3_setting::A3Setting;
use crate::error::EvalError;
use crate::flight::{flight_end, record_of, replay_outcome, true_rsrp};
use crate::metrics::{FlightMetrics, MetricRules, flight_metrics};
use crate::record::{FlightRecord, StepRecord};
use crate::sinr::{NOISE_PER_RE_DBM, sinr_db};
use dupac_actor::env::{Env, Episode};
use dupac_actor::metrics::HandoverCounter;
use dupac_actor::pairs::Pair;
use dupac_actor::pilot::{fly_waypoints, replay_positions};
use dupac_actor::record::StepInfo;
use dupac_common::config::{A3Config, Association, Config};
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;
use dupac_radio::a3::{A3Params, A3State};
use dupac_radio::channel::FieldSplit;
use dupac_radio::class::RsrpThresholds;
use dupac_radio::world::RadioWorld;
use dupac_scenario::world::SharedRsrp;
use std::sync::Arc;

/// How the traced flight moves.
#[derive(Debug, Clone, Copy)]
pub enum Flown<'a> {
    /// The scripted pilot along these waypoints (m; [`fly_waypoints`]).
    Waypoints(&'a [Point]),
    /// Through this recorded flight's positions ([`replay_positions`]), ending as it ended
    /// ([`replay_outcome`]).
    Replay(&'a FlightRecord),
}

/// One flight's association-independent record, per step (module doc).
#[derive(Debug, Clone)]
pub struct ReplayTrace {
    pair: Pair,
    /// M, the number of sites.
    m: usize,
    /// The traced flight's steps: positions, the strongest site, the end (what no association
    /// changes).
    steps: Vec<StepInfo>,
    /// What the UAV held of every site (dBm), at the source (row 0) and after each step
    /// ((n + 1) × M, row-major).
    held_dbm: Vec<f64>,
    /// The newest unfiltered measurement of every site (dBm; what A3's own layer-3 filter takes),
    /// the same rows.
    raw_dbm: Vec<f64>,
    /// Whether a new measurement arrived at the source (row 0) and at each step.
    fresh: Vec<bool>,
    /// Every site's true RSRP (dBm; the environment's), the same rows.
    true_dbm: Vec<f64>,
    /// Each site's SINR (dB) as the serving site after each step (n × M): the records' SINR.
    sinr_db: Vec<f64>,
    /// Each site's geometric line of sight after each step (n × M).
    los: Vec<bool>,
    /// The site serving before the first step (the strongest the UAV measured at the source).
    start_serving: u16,
    outcome: Outcome,
    remaining_m: f64,
    /// The configuration's `radio.a3` (what a setting does not set stays as configured).
    a3: A3Config,
    /// The simulator step (s) and the period of the UAV's measurements (s).
    dt_s: f64,
    measurement_period_s: f64,
    thresholds: RsrpThresholds,
    /// `env.ping_pong_window_s` in steps.
    ping_pong_window_steps: u32,
}

/// What the UAV measures, read from the environment after each of its measurements.
struct Capture {
    m: usize,
    held_dbm: Vec<f64>,
    raw_dbm: Vec<f64>,
    fresh: Vec<bool>,
    true_dbm: Vec<f64>,
}

impl Capture {
    fn take(&mut self, e: &Env) {
        self.true_dbm.extend_from_slice(e.rsrp_dbm());
        self.held_dbm.extend_from_slice(e.measured_dbm());
        match e.measurer() {
            Some(me) => {
                self.raw_dbm.extend_from_slice(me.raw_dbm());
                self.fresh.push(me.fresh());
            }
            None => {
                self.raw_dbm.extend_from_slice(e.measured_dbm());
                self.fresh.push(true);
            }
        }
        debug_assert_eq!(self.true_dbm.len(), self.fresh.len() * self.m);
    }
}

impl ReplayTrace {
    /// Flies pair `p`'s `episode` once as `flown` says under `cfg` (its association aside: the
    /// moves do not depend on it), in the pair's true field of `fs` for the SINR, and keeps what
    /// every A3 setting's flight needs.
    pub fn fly(
        cfg: &Config,
        world: &Arc<RadioWorld>,
        rsrp: &SharedRsrp,
        fs: FieldSplit,
        p: &Pair,
        episode: Episode,
        flown: Flown,
    ) -> Result<ReplayTrace, EvalError> {
        let mut fcfg = cfg.clone();
        fcfg.env.association = Association::A3;
        let mut env = Env::new(&fcfg, world.clone(), rsrp.clone())?;
        let m = world.num_sites();
        let dt_s = cfg.env.dt_s();
        let measurement_period_s = env
            .measurer()
            .map_or(dt_s, |me| f64::from(me.period_steps()) * dt_s);
        let mut cap = Capture {
            m,
            held_dbm: Vec::new(),
            raw_dbm: Vec::new(),
            fresh: Vec::new(),
            true_dbm: Vec::new(),
        };
        // The site closure runs before every step: it sees the source, then each step but the
        // last; the last is read after the flight.
        let mut site = |e: &Env| {
            cap.take(e);
            e.serving()
        };
        let (steps, outcome) = match flown {
            Flown::Waypoints(w) => {
                let f = fly_waypoints(&mut env, p.id, episode, w, &mut site)?;
                let end = flight_end(p, &f.steps).0;
                (f.steps, end)
            }
            Flown::Replay(r) => {
                let w: Vec<Point> = r
                    .steps
                    .iter()
                    .map(|s| Point::from(s.position_m.map(f64::from)))
                    .collect();
                let f = replay_positions(&mut env, p.id, episode, &w, &mut site)?;
                let end = replay_outcome(r, f.steps.len(), flight_end(p, &f.steps).0);
                (f.steps, end)
            }
        };
        cap.take(&env);
        let n = steps.len();
        let truth = true_rsrp(world, rsrp, fs, p.id);
        let mut all = vec![f64::NAN; m];
        let (mut sinr, mut los) = (Vec::with_capacity(n * m), Vec::with_capacity(n * m));
        for s in &steps {
            truth.rsrp_all_dbm(s.position_m, &mut all);
            for k in 0..m {
                sinr.push(sinr_db(&all, k, NOISE_PER_RE_DBM));
                los.push(world.los(SiteId(k as u16), s.position_m));
            }
        }
        Ok(ReplayTrace {
            pair: p.clone(),
            m,
            remaining_m: flight_end(p, &steps).1,
            outcome,
            steps,
            held_dbm: cap.held_dbm,
            raw_dbm: cap.raw_dbm,
            fresh: cap.fresh,
            true_dbm: cap.true_dbm,
            sinr_db: sinr,
            los,
            start_serving: env.start_serving().0,
            a3: cfg.radio.a3.clone(),
            dt_s,
            measurement_period_s,
            thresholds: RsrpThresholds::from_config(&cfg.radio),
            ping_pong_window_steps: MetricRules::from_config(cfg).ping_pong_window_steps,
        })
    }

    /// Row `t` (0: the source, t: after step t) of a (n + 1) × M table.
    fn row<'a>(&self, table: &'a [f64], t: usize) -> &'a [f64] {
        &table[t * self.m..(t + 1) * self.m]
    }

    /// The serving site after each step under A3 with `setting` (the rest of `radio.a3` as
    /// configured): A3 starts from what the UAV held at the source and steps once per step on
    /// what it holds or, with A3's own filter, on the unfiltered measurements, as the
    /// environment's association does.
    pub fn a3_serving(&self, setting: &A3Setting) -> Vec<u16> {
        let mut a3 = self.a3.clone();
        setting.apply(&mut a3);
        let params = A3Params::from_config(&a3, self.dt_s, self.measurement_period_s);
        let mut state = A3State::new(params, self.row(&self.held_dbm, 0));
        let own_filter = params.l3_filter_k.is_some();
        (1..=self.steps.len())
            .map(|t| {
                let m = if own_filter {
                    self.row(&self.raw_dbm, t)
                } else {
                    self.row(&self.held_dbm, t)
                };
                state.step(m, self.fresh[t]);
                state.serving().0
            })
            .collect()
    }

    /// The record of this flight with `serving` the site after each step (as many as steps), as
    /// `label` (training `seed`) would have flown it through the environment.
    pub fn record(&self, label: &str, seed: u32, serving: &[u16]) -> FlightRecord {
        let m = self.m;
        let mut counter = HandoverCounter::new(self.ping_pong_window_steps);
        let mut before = self.start_serving;
        let steps: Vec<StepRecord> = self
            .steps
            .iter()
            .zip(serving)
            .enumerate()
            .map(|(t, (s, &now))| {
                let k = usize::from(now);
                let (handover, ping_pong) = counter.step(before, now, s.step);
                before = now;
                let serving_rsrp_dbm = self.true_dbm[(t + 1) * m + k];
                let info = StepInfo {
                    serving: SiteId(now),
                    serving_rsrp_dbm,
                    measured_serving_rsrp_dbm: self.held_dbm[(t + 1) * m + k],
                    class: self.thresholds.classify(serving_rsrp_dbm),
                    los: self.los[t * m + k],
                    handover,
                    ping_pong,
                    ..*s
                };
                StepRecord::from_info(&info, self.sinr_db[t * m + k])
            })
            .collect();
        record_of(
            label,
            seed,
            &self.pair,
            self.start_serving,
            (self.outcome, self.remaining_m),
            steps,
        )
    }

    /// Each setting's flight metrics of this flight, in the order of `settings`.
    pub fn a3_metrics(&self, settings: &[A3Setting], rules: &MetricRules) -> Vec<FlightMetrics> {
        settings
            .iter()
            .map(|s| flight_metrics(&self.record("a3", 0, &self.a3_serving(s)), rules))
            .collect()
    }
}

#[cfg(test)]
mod tests;
