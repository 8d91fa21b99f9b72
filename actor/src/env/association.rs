//! How the serving GBS is chosen each step (spec/env.md "Association").

use dupac_common::config::Association;
use dupac_common::ids::SiteId;
use dupac_radio::a3::{A3Params, A3State};

/// Association state of one episode.
#[derive(Debug, Clone)]
pub enum Associator {
    /// DUPAC: the agent's discrete action is the serving site.
    Learned,
    /// The base method: 3GPP A3 with time-to-trigger.
    A3(A3State),
    /// Oracle: the strongest site every step.
    BestRsrp,
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
        };
        (a, first)
    }

    /// The serving site after a step, given the agent's choice (used only by `Learned`).
    pub fn next(&mut self, chosen: SiteId, rsrp_dbm: &[f64]) -> SiteId {
        match self {
            Associator::Learned => chosen,
            Associator::A3(state) => {
                state.step(rsrp_dbm);
                state.serving()
            }
            Associator::BestRsrp => argmax(rsrp_dbm),
        }
    }
}
