//! Recorded flights re-flown with other associations (route against association): a learned
//! site choice's moves with A3, the oracle, the predictive and the hindsight association
//! (`LABEL+a3`, `LABEL+oracle`, `LABEL+predictive`, `LABEL+hindsight_…`), and the fronts of
//! each rule on the same flights ([`crate::front`]): A3's grid re-associated from one flight per
//! pair ([`crate::trace`]), the predictive and the hindsight association re-flown per cost.
//!
//! A replay takes one step to each recorded position in turn (`pilot::replay_positions`), so it
//! has the recorded flight's steps and end ([`replay_outcome`]); the positions are stored in f32
//! (within 0.1 mm).

use crate::a3_setting::A3Setting;
use crate::error::EvalError;
use crate::flight::{FlyCtx, fly_one, replay_outcome};
use crate::front::{FrontFile, FrontPoint, FrontRule, FrontSetting};
use crate::metrics::{FlightMetrics, MetricRules, flight_metrics};
use crate::record::FlightRecord;
use crate::trace::{Flown, ReplayTrace};
use crate::{Hindsight, Kind, Method};
use dupac_actor::pairs::Pair;
use dupac_common::config::{Association, Config};
use dupac_common::geometry::Point;
use dupac_scenario::progress::progress_bar;
use rayon::prelude::*;

/// Pair `p`'s recorded flight `recorded` re-flown through its positions under `rcfg` as `replay`
/// ([`Kind::Replay`] or [`Kind::Hindsight`]), ending as the recording did ([`replay_outcome`]).
pub(crate) fn replay_one(
    rcfg: &Config,
    (_, world, rsrp, planners, fs): FlyCtx,
    replay: &Method,
    p: &Pair,
    recorded: &FlightRecord,
) -> Result<FlightRecord, EvalError> {
    let w: Vec<Point> = recorded
        .steps
        .iter()
        .map(|s| Point::from(s.position_m.map(f64::from)))
        .collect();
    let mut r = fly_one(rcfg, world, rsrp, planners, fs, replay, p, Some(&w))?;
    r.outcome = replay_outcome(recorded, r.steps.len(), r.outcome);
    Ok(r)
}

/// Every flight of `flights` (one per pair of `pairs`) re-flown under `rcfg` as `replay`
/// ([`replay_one`]), in parallel, in order.
fn refly(
    rcfg: &Config,
    ctx: FlyCtx,
    replay: &Method,
    pairs: &[Pair],
    flights: &[FlightRecord],
) -> Result<Vec<FlightRecord>, EvalError> {
    pairs
        .par_iter()
        .zip(flights)
        .map(|(p, f)| replay_one(rcfg, ctx, replay, p, f))
        .collect()
}

/// `ctx`'s configuration without the path guide, with `association` choosing the site.
fn replay_config(ctx: FlyCtx, association: Association) -> Config {
    let mut rcfg = dupac_scenario::planners::unguided(ctx.0);
    rcfg.env.association = association;
    rcfg
}

/// The method `label` (training `seed`) of a replay of `kind`.
fn replay_method(label: String, seed: u32, kind: Kind) -> Method {
    Method {
        label,
        seed,
        kind,
        a3: None,
        predictive: false,
        handover_weight: None,
    }
}

/// The positions of every flight of `method` re-flown with the A3 rule (`LABEL+a3`), the
/// best-RSRP oracle (`LABEL+oracle`) and the predictive association at the configured cost
/// (`LABEL+predictive`) choosing the site: the same route, another association. With
/// `hindsight`, also with each hindsight association (`LABEL+hindsight_…`).
pub(crate) fn replay_associations(
    ctx: FlyCtx,
    method: &Method,
    pairs: &[Pair],
    flights: &[FlightRecord],
    hindsight: &[(String, Hindsight)],
    quiet: bool,
) -> Result<Vec<(String, Vec<FlightRecord>)>, EvalError> {
    let rules = [
        (Association::A3, "a3"),
        (Association::BestRsrp, "oracle"),
        (Association::Predictive, "predictive"),
    ]
    .map(|(a, suffix)| (Kind::Replay(a), suffix.to_string()));
    let hindsight = hindsight
        .iter()
        .map(|(l, h)| (Kind::Hindsight(*h), l.clone()));
    let all: Vec<(Kind, String)> = rules.into_iter().chain(hindsight).collect();
    let pb = progress_bar(
        all.len() as u64,
        &format!("{} seed {}: replays", method.label, method.seed),
        quiet,
    );
    let out = all
        .into_iter()
        .map(|(kind, suffix)| {
            let rcfg = match kind {
                Kind::Replay(a) => replay_config(ctx, a),
                _ => replay_config(ctx, Association::Learned),
            };
            let label = format!("{}+{suffix}", method.label);
            let replay = replay_method(label.clone(), method.seed, kind);
            let r = refly(&rcfg, ctx, &replay, pairs, flights)?;
            pb.inc(1);
            Ok((label, r))
        })
        .collect();
    pb.finish_and_clear();
    out
}

/// The fronts to fly (`dupac eval --a3-front`, `--hindsight-front`, `--predictive-front`).
#[derive(Debug, Clone, Default)]
pub struct Fronts {
    /// A3's settings (empty: no A3 front).
    pub a3: Vec<A3Setting>,
    /// The hindsight association's costs (dB·steps per handover, no minimum stay).
    pub hindsight_costs_db: Vec<f64>,
    /// The predictive association's costs (dB·m per handover, `env.predictive`).
    pub predictive_costs_db_m: Vec<f64>,
}

/// The fronts of `method`'s flights: every rule of `fronts` on a learned-site policy's moves, A3's
/// on a planner's path flown with the configured A3 (its flights' setting is the grid's origin
/// of comparison); none on other methods.
pub(crate) fn fronts_of(
    ctx: FlyCtx,
    fronts: &Fronts,
    method: &Method,
    pairs: &[Pair],
    flights: &[FlightRecord],
    rules: &MetricRules,
    quiet: bool,
) -> Result<Vec<FrontFile>, EvalError> {
    let learned_site = match &method.kind {
        Kind::Policy(p) if p.n_sites > 0 => true,
        Kind::Shortest(Association::A3) | Kind::Coverage(_, Association::A3)
            if method.a3.is_none() =>
        {
            false
        }
        _ => return Ok(Vec::new()),
    };
    let file = |rule, points| FrontFile {
        method: method.label.clone(),
        seed: method.seed,
        learned_site,
        rule,
        points,
    };
    let mut out = Vec::new();
    if !fronts.a3.is_empty() {
        let points = a3_front(ctx, method, &fronts.a3, pairs, flights, rules, quiet)?;
        out.push(file(FrontRule::A3, points));
    }
    if !learned_site {
        return Ok(out);
    }
    let hindsight: Vec<FrontSetting> = fronts
        .hindsight_costs_db
        .iter()
        .map(|&c| FrontSetting::Hindsight {
            handover_cost_db: c,
        })
        .collect();
    let predictive: Vec<FrontSetting> = fronts
        .predictive_costs_db_m
        .iter()
        .map(|&c| FrontSetting::Predictive {
            handover_cost_db_m: c,
        })
        .collect();
    for (rule, settings) in [
        (FrontRule::Hindsight, hindsight),
        (FrontRule::Predictive, predictive),
    ] {
        if !settings.is_empty() {
            let points = env_front(ctx, method, &settings, pairs, flights, rules, quiet)?;
            out.push(file(rule, points));
        }
    }
    Ok(out)
}

/// The positions of every flight of `method` re-associated by A3 at each of `settings`, one
/// trace per flight ([`ReplayTrace`]): each setting's per-flight metrics, as the flight re-flown
/// through the environment with that setting would give them.
fn a3_front(
    ctx: FlyCtx,
    method: &Method,
    settings: &[A3Setting],
    pairs: &[Pair],
    flights: &[FlightRecord],
    rules: &MetricRules,
    quiet: bool,
) -> Result<Vec<FrontPoint>, EvalError> {
    let (_, world, rsrp, planners, fs) = ctx;
    let rcfg = replay_config(ctx, Association::A3);
    let pb = progress_bar(
        pairs.len() as u64,
        &format!(
            "{} seed {}: A3 front ({} settings)",
            method.label,
            method.seed,
            settings.len()
        ),
        quiet,
    );
    // metrics[flight][setting]
    let metrics: Vec<Vec<FlightMetrics>> = pairs
        .par_iter()
        .zip(flights)
        .map(|(p, f)| {
            let episode = dupac_scenario::pairs::episode(&rcfg, planners, p, fs)?;
            let trace = ReplayTrace::fly(&rcfg, world, rsrp, fs, p, episode, Flown::Replay(f))?;
            pb.inc(1);
            Ok(trace.a3_metrics(settings, rules))
        })
        .collect::<Result<_, EvalError>>()?;
    pb.finish_and_clear();
    Ok(settings
        .iter()
        .enumerate()
        .map(|(k, s)| FrontPoint {
            setting: FrontSetting::A3(*s),
            flights: pairs
                .iter()
                .zip(&metrics)
                .map(|(p, m)| (p.id, m[k]))
                .collect(),
        })
        .collect())
}

/// The positions of every flight of `method` re-flown through the environment with the
/// predictive or the hindsight association at each of `settings`' costs: each setting's
/// per-flight metrics.
fn env_front(
    ctx: FlyCtx,
    method: &Method,
    settings: &[FrontSetting],
    pairs: &[Pair],
    flights: &[FlightRecord],
    rules: &MetricRules,
    quiet: bool,
) -> Result<Vec<FrontPoint>, EvalError> {
    let pb = progress_bar(
        settings.len() as u64,
        &format!("{} seed {}: fronts", method.label, method.seed),
        quiet,
    );
    let points = settings
        .iter()
        .map(|setting| {
            let (rcfg, kind) = match *setting {
                FrontSetting::Predictive { handover_cost_db_m } => {
                    let mut c = replay_config(ctx, Association::Predictive);
                    c.env.predictive.handover_cost_db_m = handover_cost_db_m;
                    (c, Kind::Replay(Association::Predictive))
                }
                FrontSetting::Hindsight { handover_cost_db } => (
                    replay_config(ctx, Association::Learned),
                    Kind::Hindsight(Hindsight {
                        cost_db: handover_cost_db,
                        min_stay_steps: 0,
                    }),
                ),
                FrontSetting::A3(_) => {
                    return Err(EvalError::Refused(
                        "an A3 front is re-associated from traces, not re-flown".into(),
                    ));
                }
            };
            let replay = replay_method(
                format!("{}+{}_front", method.label, setting.rule().name()),
                method.seed,
                kind,
            );
            let v = refly(&rcfg, ctx, &replay, pairs, flights)?
                .iter()
                .map(|r| (r.pair_id, flight_metrics(r, rules)))
                .collect();
            pb.inc(1);
            Ok(FrontPoint {
                setting: *setting,
                flights: v,
            })
        })
        .collect::<Result<Vec<_>, EvalError>>();
    pb.finish_and_clear();
    points
}
