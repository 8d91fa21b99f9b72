//! The hindsight association of a recorded route (`dupac eval --hindsight`): the least site
//! regret for a given cost per handover, knowing the whole route and the true field. A reference
//! for what any association could keep on a policy's own moves, not a realisable rule.

/// The hindsight association of a recorded route: the serving site of every step that minimises
/// Σ_t (best RSRP_t − RSRP_t(site_t)) + `handover_cost_db` × handovers (dB·steps per handover),
/// subject to a minimum time of stay of `min_stay_steps` steps
/// ([`dupac_actor::env::serving_plan`], whose tests check it against every sequence of a small
/// case). `rsrp_dbm` holds the true RSRP (dBm) of the `m` sites at every step, row-major;
/// `start` is the site serving before the first step. An evaluation reference that knows the
/// whole route and field in advance, not a realisable rule.
pub fn hindsight_association(
    rsrp_dbm: &[f64],
    m: usize,
    start: u16,
    handover_cost_db: f64,
    min_stay_steps: u32,
) -> Vec<u16> {
    dupac_actor::env::serving_plan(rsrp_dbm, m, start, handover_cost_db, min_stay_steps)
}
