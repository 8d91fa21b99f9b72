//! How the serving GBS is chosen each step (spec/env.md "Association"): the rule
//! ([`Associator`]) and the step's associate stage ([`Env::associate`]).

use super::Env;
use dupac_common::config::Association;
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_radio::a3::{A3Params, A3State};
use dupac_radio::class::RsrpClass;
use dupac_radio::source::RsrpSource;

/// Association state of one episode.
#[derive(Debug, Clone)]
pub enum Associator {
    /// DUPAC: the agent's discrete action is the serving site.
    Learned,
    /// The base method: 3GPP A3 with time-to-trigger.
    A3(A3State),
    /// Oracle: the strongest site every step.
    BestRsrp,
    /// The predictive association: the environment plans each decision's site on the route
    /// ahead ([`super::Ahead::choice`]) and passes it as the choice.
    Predictive,
}

/// Index of the largest finite value (lowest index on ties; `SiteId(0)` if none).
pub fn argmax(rsrp_dbm: &[f64]) -> SiteId {
    let mut best = (0usize, f64::NEG_INFINITY);
    for (i, v) in rsrp_dbm.iter().enumerate() {
        if *v > best.1 {
            best = (i, *v);
        }
    }
    SiteId(best.0 as u16)
}

impl Associator {
    /// Start of an episode: the serving site is the strongest at the source.
    pub fn start(mode: Association, a3: A3Params, rsrp_dbm: &[f64]) -> (Associator, SiteId) {
        let first = argmax(rsrp_dbm);
        let a = match mode {
            Association::Learned => Associator::Learned,
            Association::A3 => Associator::A3(A3State::new(a3, rsrp_dbm)),
            Association::BestRsrp => Associator::BestRsrp,
            Association::Predictive => Associator::Predictive,
        };
        (a, first)
    }

    /// The serving site after a step, given the choice (the agent's under `Learned`, the
    /// environment's plan under `Predictive`, unused otherwise): A3
    /// compares what the UAV measures ([`Measured`]), the oracle knows the true RSRP
    /// (`true_dbm`, dBm).
    pub fn next(&mut self, chosen: SiteId, measured: Measured, true_dbm: &[f64]) -> SiteId {
        match self {
            Associator::Learned | Associator::Predictive => chosen,
            Associator::A3(state) => {
                // A3's own filter takes the unfiltered measurements; without one, A3 compares
                // what the UAV holds.
                let m = if state.params().l3_filter_k.is_some() {
                    measured.raw_dbm
                } else {
                    measured.held_dbm
                };
                state.step(m, measured.fresh);
                state.serving()
            }
            Associator::BestRsrp => argmax(true_dbm),
        }
    }
}

/// What the UAV measures at a step: what it holds (dBm, layer-3 filtered), the last
/// measurement before the filter (dBm), and whether that measurement is new at this step.
#[derive(Debug, Clone, Copy)]
pub struct Measured<'a> {
    pub held_dbm: &'a [f64],
    pub raw_dbm: &'a [f64],
    pub fresh: bool,
}

/// What the associate stage produced: the serving site's link and the strongest site's after
/// the step, whether the step was a handover (and a ping-pong).
#[derive(Debug, Clone, Copy)]
pub(super) struct Link {
    pub handover: bool,
    pub ping_pong: bool,
    /// RSRP (dBm) and class of the site serving after the step.
    pub serving_rsrp_dbm: f64,
    pub class: RsrpClass,
    /// What the UAV measured of the serving site's RSRP (dBm).
    pub measured_serving_rsrp_dbm: f64,
    /// The strongest site at the new position and its RSRP (dBm).
    pub best_site: SiteId,
    pub best_rsrp_dbm: f64,
}

impl Env {
    /// Associate: every site's RSRP at `to` (dBm, [`Env::measure`]), then the serving site by
    /// the association rule (`site`, the policy's choice, under the learned association: a
    /// decision's choice takes effect at its first step, so a handover only there; A3 or the
    /// strongest site otherwise), the handover and ping-pong counted.
    pub(super) fn associate(&mut self, to: Point, site: SiteId) -> Link {
        self.measure(to);
        let before = self.serving;
        let site = if matches!(self.associator, Associator::Predictive) {
            // Planned at each decision's first step, kept until the next.
            if (self.step.max(1) - 1).is_multiple_of(self.cfg.action_repeat.max(1)) {
                self.predictive_site = self
                    .ahead
                    .choice(before, self.cfg.predictive.handover_cost_db_m);
            }
            self.predictive_site
        } else {
            site
        };
        let measured = match &self.measurer {
            Some(m) => Measured {
                held_dbm: &self.measured_dbm,
                raw_dbm: m.raw_dbm(),
                fresh: m.fresh(),
            },
            None => Measured {
                held_dbm: &self.measured_dbm,
                raw_dbm: &self.measured_dbm,
                fresh: true,
            },
        };
        self.serving = self.associator.next(site, measured, &self.rsrp_dbm);
        let (handover, ping_pong) = self.handovers.step(before.0, self.serving.0, self.step);
        let serving_rsrp_dbm = self.rsrp_dbm[self.serving.index()];
        let class = self.thresholds.classify(serving_rsrp_dbm);
        let best_site = argmax(&self.rsrp_dbm);
        Link {
            measured_serving_rsrp_dbm: self.measured_dbm[self.serving.index()],
            handover,
            ping_pong,
            serving_rsrp_dbm,
            class,
            best_site,
            best_rsrp_dbm: self.rsrp_dbm[best_site.index()],
        }
    }
}

impl Env {
    /// Measure: every site's true RSRP at `p_m` (dBm): the RSRP source's, less the episode's
    /// shadow fading in each link's line-of-sight state; then what the UAV measures of it.
    /// With a route prediction, the prediction of the route ahead from what is measured here
    /// ([`Env::predict_ahead`]).
    pub(super) fn measure(&mut self, p_m: Point) {
        self.rsrp.rsrp_all_dbm(p_m, &mut self.rsrp_dbm);
        if self.route.is_some() {
            self.map_offset_db.copy_from_slice(&self.rsrp_dbm);
        }
        if let Some(field) = &self.field {
            if !self.rsrp.los_all(p_m, &mut self.los_scratch) {
                RsrpSource::los_all(self.world.as_ref(), p_m, &mut self.los_scratch);
            }
            field.apply(
                p_m,
                &self.los_scratch,
                &mut self.rsrp_dbm,
                &mut self.shadow_scratch_db,
            );
        }
        match self.measurer.as_mut() {
            Some(m) => m.measure(&self.rsrp_dbm, &mut self.measured_dbm),
            None => self.measured_dbm.copy_from_slice(&self.rsrp_dbm),
        }
        self.predict_ahead();
    }

    /// Predict: with a route, every site's RSRP over `env.predictive.horizon_m` of the route ahead
    /// of the UAV's place on it ([`super::Ahead::predict`]): the operator's map, plus each site's
    /// measured − map offset here fading at the site's decorrelation distance in its present
    /// line-of-sight state (only the real channel has an offset).
    fn predict_ahead(&mut self) {
        let (Some((_, map)), Some(p)) = (&self.route, self.cfg.route_prediction()) else {
            return;
        };
        for (k, d) in self.decorrelation_scratch_m.iter_mut().enumerate() {
            let los = self.field.is_some() && self.los_scratch[k] >= 0.5;
            *d = self.decorrelation_m[usize::from(!los)][k];
        }
        // The offset in the map's scratch: measured − map.
        for (o, &w) in self.map_offset_db.iter_mut().zip(&self.measured_dbm) {
            *o = if o.is_finite() && w.is_finite() {
                w - *o
            } else {
                0.0
            };
        }
        self.ahead.predict(
            map,
            self.route_s_m,
            p.horizon_m,
            &self.map_offset_db,
            &self.decorrelation_scratch_m,
        );
    }
}
