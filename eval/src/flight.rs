//! One flight: what flying a pair needs ([`FlyCtx`]), the one way a planned path is flown
//! ([`fly_path`], with A3: [`fly_path_with_a3`]), the one check of a policy against the
//! environment it flies in ([`policy_env`]), a method flown over one pair ([`fly_one`]), its
//! record ([`flight_record`], [`record_of`]) and how a replay of a recorded flight ends
//! ([`replay_outcome`]). Below `fly` (every method over every pair), `refly` (the re-flights),
//! `trace` (A3 re-run from one recorded trace), `dupac plan`, `dupac fly` and the Python
//! package, which all use it.

use crate::error::refused;
use crate::error::{Context, EvalError};
use crate::hindsight::hindsight_association;
use crate::record::{FlightRecord, StepRecord};
use crate::sinr::{NOISE_PER_RE_DBM, sinr_db};
use crate::{Kind, Method};
use dupac_actor::env::{Env, Episode, PathGuide};
use dupac_actor::metrics::EpisodeAccumulator;
use dupac_actor::pairs::Pair;
use dupac_actor::pilot::{Flight, fly_waypoints, replay_positions};
use dupac_actor::record::StepInfo;
use dupac_actor::rollout::fly_policy;
use dupac_common::config::{Association, Config};
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_common::msg::{EpisodeSummary, Outcome};
use dupac_common::policy::PolicyWeights;
use dupac_radio::channel::FieldSplit;
use dupac_radio::world::RadioWorld;
use dupac_scenario::planners::Planners;
use dupac_scenario::world::SharedRsrp;
use std::sync::Arc;

/// What a re-flight needs: the configuration, the world, its RSRP, the planners and the field
/// split the pairs fly in.
pub(crate) type FlyCtx<'a, 'w> = (
    &'a Config,
    &'a Arc<RadioWorld>,
    &'a SharedRsrp,
    &'a Planners<'w>,
    FieldSplit,
);

/// A planned path flown by the scripted pilot: the flight, the site that served before its
/// first step (handovers are counted from it) and the episode's summary.
#[derive(Debug, Clone)]
pub struct FlownPath {
    pub flight: Flight,
    pub start_serving: SiteId,
    pub summary: EpisodeSummary,
}

/// `waypoints_m` (m) flown from `episode`'s source by the scripted pilot in `env`, episode `id`
/// (its seed), the environment's association choosing the site: the one way a planned path is
/// flown (`dupac eval`'s planners with A3, the oracle or the predictive association; `dupac
/// plan`, `dupac fly`'s reference and Python's `fly_path` with A3, [`fly_path_with_a3`]).
pub fn fly_path(
    env: &mut Env,
    id: u64,
    episode: Episode,
    waypoints_m: &[Point],
) -> Result<FlownPath, EvalError> {
    let shortest_m = episode.shortest_m;
    let flight = fly_waypoints(env, id, episode, waypoints_m, |e| e.serving())?;
    let mut acc = EpisodeAccumulator::new(env.config());
    flight.steps.iter().for_each(|s| acc.push(s));
    let summary = acc.finish(id, shortest_m, flight.outcome);
    Ok(FlownPath {
        start_serving: env.start_serving(),
        flight,
        summary,
    })
}

/// [`fly_path`] with A3 choosing the site, in an environment of `cfg` over `world` and `rsrp`:
/// pair `p`'s episode (from its source, with its guide) in `field`'s realisations.
pub fn fly_path_with_a3(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    waypoints_m: &[Point],
    p: &Pair,
    field: FieldSplit,
) -> Result<FlownPath, EvalError> {
    let mut a3_cfg = cfg.clone();
    a3_cfg.env.association = Association::A3;
    let mut env = Env::new(&a3_cfg, world.clone(), rsrp.clone())?;
    fly_path(&mut env, p.id, p.episode(false, field), waypoints_m)
}

/// An environment of `cfg` over `world` and `rsrp` for `policy` to fly in, refused when it gives
/// another number of observations than the policy takes: the one check of a policy against its
/// environment (`dupac eval`, `dupac fly`, Python's `fly`). `cfg` is the policy's own
/// ([`PolicyWeights::configure`]: the observation it was trained on).
pub fn policy_env(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    policy: &PolicyWeights,
) -> Result<Env, EvalError> {
    let env = Env::new(cfg, world.clone(), rsrp.clone())?;
    let given = env.layout().len();
    if given != policy.obs_dim {
        return Err(refused!(
            "the policy expects {} observations, this configuration gives {given} with the observation the policy records: another number of sites (scenario.n_sites)?",
            policy.obs_dim
        ));
    }
    Ok(env)
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn fly_one(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    planners: &Planners,
    fs: FieldSplit,
    method: &Method,
    p: &Pair,
    // The shortest path (`Kind::Shortest`) or the recorded positions (`Kind::Replay`).
    waypoints_m: Option<&[Point]>,
) -> Result<FlightRecord, EvalError> {
    let mut env = Env::new(cfg, world.clone(), rsrp.clone())?;
    let mut episode = dupac_scenario::pairs::episode(cfg, planners, p, fs)?;
    let steps = match &method.kind {
        Kind::Policy(policy) => fly_policy(&mut env, policy, p.id, episode, p.id)?.1,
        Kind::Shortest(a) => {
            let w = waypoints_m.ok_or_else(|| refused!("pair {}: no shortest path", p.id))?;
            if *a == Association::Predictive {
                // The route the predictive association reads ahead is the path flown.
                episode.guide = PathGuide::new(w).map(Arc::new);
            }
            fly_path(&mut env, p.id, episode, w)?.flight.steps
        }
        Kind::Replay(_) => {
            let w = waypoints_m.ok_or_else(|| refused!("pair {}: no positions to replay", p.id))?;
            replay_positions(&mut env, p.id, episode, w, |e| e.serving())?.steps
        }
        Kind::Hindsight(h) => {
            let w = waypoints_m.ok_or_else(|| refused!("pair {}: no positions to replay", p.id))?;
            let m = world.num_sites();
            let truth = true_rsrp(world, rsrp, fs, p.id);
            let mut rows = vec![f64::NAN; w.len() * m];
            for (row, pos) in rows.chunks_mut(m).zip(w) {
                truth.rsrp_all_dbm(*pos, row);
            }
            // From the site the environment starts with (what the UAV measured at the source).
            env.reset(p.id, episode.clone())?;
            let start = env.start_serving().0;
            let sites = hindsight_association(&rows, m, start, h.cost_db, h.min_stay_steps);
            let mut next = sites.into_iter().map(SiteId);
            replay_positions(&mut env, p.id, episode, w, |e| {
                next.next().unwrap_or_else(|| e.serving())
            })?
            .steps
        }
        Kind::Coverage(l, _) => {
            let path = planners
                .pairs
                .coverage_aware(p.source_m, p.destination_m, *l)
                .context_with(|| format!("pair {}: coverage-aware path (λ = {l})", p.id))?;
            fly_path(&mut env, p.id, episode, &path.waypoints_m)?
                .flight
                .steps
        }
    };
    Ok(flight_record(
        world,
        rsrp,
        fs,
        &method.label,
        method.seed,
        p,
        (env.start_serving(), &steps),
    ))
}

/// The record of pair `p`'s flight `steps` from the site `start_serving` served before its
/// first step (its SINR per step from every site's true RSRP in the pair's field of `fs`), as
/// `method` (`label`, training `seed`) flew it.
pub fn flight_record(
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    fs: FieldSplit,
    label: &str,
    seed: u32,
    p: &Pair,
    (start_serving, steps): (SiteId, &[StepInfo]),
) -> FlightRecord {
    let mut all = vec![f64::NAN; world.num_sites()];
    let truth = true_rsrp(world, rsrp, fs, p.id);
    let records = steps
        .iter()
        .map(|s| {
            truth.rsrp_all_dbm(s.position_m, &mut all);
            StepRecord::from_info(s, sinr_db(&all, usize::from(s.serving.0), NOISE_PER_RE_DBM))
        })
        .collect();
    record_of(
        label,
        seed,
        p,
        start_serving.0,
        flight_end(p, steps),
        records,
    )
}

/// How pair `p`'s flight `steps` ended and the distance left to its destination (m): the last
/// step's outcome (`TimeLimit` when the steps ran out first) and distance to the goal.
pub(crate) fn flight_end(p: &Pair, steps: &[StepInfo]) -> (Outcome, f64) {
    let outcome = steps
        .last()
        .and_then(|s| s.outcome)
        .unwrap_or(Outcome::TimeLimit);
    (
        outcome,
        steps.last().map_or(p.shortest_m, |s| s.distance_to_goal_m),
    )
}

/// The record of pair `p`'s flight by `label` (training `seed`): its `steps`, the site that
/// served before the first, how it ended and the distance left (m).
pub(crate) fn record_of(
    label: &str,
    seed: u32,
    p: &Pair,
    start_serving: u16,
    (outcome, remaining_m): (Outcome, f64),
    steps: Vec<StepRecord>,
) -> FlightRecord {
    FlightRecord {
        method: label.to_string(),
        seed,
        pair_id: p.id,
        bin_m: p.bin_m.unwrap_or(p.shortest_m),
        shortest_m: p.shortest_m,
        straight_m: p.straight_m,
        outcome,
        source_m: p.source_m,
        destination_m: p.destination_m,
        remaining_m,
        start_serving,
        steps,
    }
}

/// The true RSRP pair `id` is flown in: field `id mod radio.channel.eval_fields` of `fs` (the
/// validation's or the test split's realisations) under the real channel
/// ([`dupac_scenario::world::true_source`]).
pub(crate) fn true_rsrp(
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    fs: FieldSplit,
    id: u64,
) -> SharedRsrp {
    dupac_scenario::world::true_source(world, rsrp, fs, id)
}

/// How a replay of `recorded` that took `replay_steps` steps ends: as the recorded flight ended
/// when it flew every recorded position (the moves are the recording's, so is their end: a
/// collision's last position is where the UAV touched the building, which a replay reaches
/// without touching it), as it ended itself (`replayed`) otherwise.
pub fn replay_outcome(recorded: &FlightRecord, replay_steps: usize, replayed: Outcome) -> Outcome {
    if replay_steps == recorded.steps.len() {
        recorded.outcome
    } else {
        replayed
    }
}
