//! The held-out evaluation during training: `pairs` flown with the deterministic policy, one
//! environment per task (spec/env.md "Metrics").

use crate::error::RunError;
use dupac_actor::env::Env;
use dupac_actor::pairs::Pair;
use dupac_actor::rollout::fly_policy;
use dupac_common::config::Config;
use dupac_common::msg::EpisodeSummary;
use dupac_common::policy::PolicyWeights;
use dupac_radio::world::RadioWorld;
use dupac_scenario::world::SharedRsrp;
use rayon::prelude::*;
use std::sync::Arc;

/// Flies `pairs` with the deterministic `policy` in parallel.
pub fn evaluate(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    policy: &PolicyWeights,
    pairs: &[Pair],
) -> Result<Vec<EpisodeSummary>, RunError> {
    pairs
        .par_iter()
        .map(|p| {
            let mut env = Env::new(cfg, world.clone(), rsrp.clone())?;
            // Held-out pairs fly in the validation's realisations.
            let ep = p.episode(false, dupac_radio::channel::FieldSplit::Eval);
            Ok(fly_policy(&mut env, policy, p.id, ep, p.id)?.0)
        })
        .collect()
}
