//! Flying the evaluation: every method over every pair in parallel, each flight recorded;
//! a learned site choice's moves re-flown with other associations (route against association).

use crate::a3_setting::A3Grid;
use crate::front::{FrontFile, FrontPoint, write_front};
use crate::hindsight::hindsight_association;
use crate::records::{RecordsFile, write_records, write_split};
use crate::sinr::{NOISE_PER_RE_DBM, sinr_db};
use crate::{EvalPlan, Hindsight, Kind, Method, methods, parse_hindsight, refused, select};
use dupac_actor::env::Env;
use dupac_actor::metrics::{MetricRules, flight_metrics};
use dupac_actor::pairs::{Pair, Split};
use dupac_actor::pilot::{fly_waypoints, replay_positions};
use dupac_actor::record::{FlightRecord, StepInfo, StepRecord};
use dupac_actor::rollout::fly_policy;
use dupac_common::config::{Association, Config, Knowledge};
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;
use dupac_radio::channel::FieldSplit;
use dupac_radio::world::RadioWorld;
use dupac_run::error::{Context, RunError};
use dupac_run::progress::progress_bar;
use dupac_run::scenario::{Planners, SharedRsrp, read_eval_pairs, world_and_cache};
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Flies every method of `args` and writes its records (and its replays') into `dir`.
pub fn fly_all(cfg: &Config, args: &EvalPlan, dir: &Path, quiet: bool) -> Result<(), RunError> {
    let methods = methods(args)?;
    let rules = MetricRules::from_config(cfg);
    let window = rules.ping_pong_window_steps;
    if args.no_replay && !args.hindsight.is_empty() {
        return Err(refused!(
            "--hindsight re-flies a policy's moves: it cannot go with --no-replay"
        ));
    }
    let hindsight = args
        .hindsight
        .iter()
        .map(|h| parse_hindsight(h, window))
        .collect::<Result<Vec<_>, RunError>>()?;
    let (world, rsrp) = world_and_cache(cfg, quiet)?;
    // Coverage classes for the coverage-aware planner; the guide planners of the policies'
    // flown configurations (a policy is flown guided as it was trained).
    let coverage = methods.iter().any(|m| matches!(m.kind, Kind::Coverage(..)));
    let flown: Vec<Config> = methods
        .iter()
        .filter_map(|m| match &m.kind {
            Kind::Policy(p) => p.configure(cfg).ok(),
            _ => None,
        })
        .collect();
    // The planner methods and the replays fly unguided (they observe nothing, their reward is
    // not reported); the pairs are guided once, as the first guided policy flies them (another
    // policy's guide, if different, is planned per flight: `scenario::episode`).
    let unguided_cfg = dupac_run::scenario::unguided(cfg);
    let planners =
        dupac_run::scenario::Planners::new(&unguided_cfg, &flown, &world, &rsrp, coverage);
    let planner = &planners.pairs;
    let guide_cfg = flown
        .iter()
        .find(|c| c.env.needs_path())
        .unwrap_or(&unguided_cfg);
    let (file, pairs) = read_eval_pairs(guide_cfg, args.pairs.as_ref(), args.split, &planners)?;
    let mut pairs = select(pairs, args.per_bin);
    if pairs.is_empty() {
        return Err(refused!("{}: no pairs", file.display()));
    }
    std::fs::create_dir_all(dir).context_with(|| format!("creating {}", dir.display()))?;
    let split_line = match &args.pairs {
        Some(f) => format!("split: file (--pairs {})", f.display()),
        None => args.split.describe(&cfg.pairs),
    };
    write_split(dir, &split_line, &file)?;
    // With knowledge of the true field, each evaluation field's planners plan on it.
    // The test split's pairs fly in realisations of their own (docs/env.md "Channel").
    let fs = match (&args.pairs, args.split) {
        (None, Split::Test) => FieldSplit::Test,
        _ => FieldSplit::Eval,
    };
    let field_planners =
        true_field_planners(cfg, &unguided_cfg, &flown, &world, &rsrp, fs, coverage);
    if let Some(fp) = &field_planners {
        for (k, planners) in fp.iter().enumerate() {
            let mut mine: Vec<Pair> = pairs
                .iter()
                .filter(|p| p.id % fp.len() as u64 == k as u64)
                .cloned()
                .collect();
            dupac_run::scenario::guide_pairs(guide_cfg, planners, &mut mine)?;
            for q in mine {
                if let Some(p) = pairs.iter_mut().find(|p| p.id == q.id) {
                    *p = q;
                }
            }
        }
    }
    let planners_of = |p: &Pair| match &field_planners {
        Some(fp) => &fp[(p.id % fp.len() as u64) as usize],
        None => &planners,
    };
    // The shortest paths once, shared by the A3 and oracle flights.
    let need_shortest = methods.iter().any(|m| matches!(m.kind, Kind::Shortest(_)));
    let shortest: Vec<Option<Vec<Point>>> = if need_shortest {
        let pb = progress_bar(pairs.len() as u64, "shortest paths", quiet);
        let v = pairs
            .par_iter()
            .map(|p| {
                let r = planner
                    .shortest(p.source_m, p.destination_m)
                    .ok()
                    .map(|x| x.waypoints_m);
                pb.inc(1);
                r
            })
            .collect();
        pb.finish_and_clear();
        v
    } else {
        vec![None; pairs.len()]
    };
    for method in &methods {
        let mut mcfg = match &method.kind {
            Kind::Policy(_) => cfg.clone(),
            _ => unguided_cfg.clone(),
        };
        mcfg.env.association = match &method.kind {
            Kind::Policy(p) if p.n_sites > 0 => Association::Learned,
            Kind::Policy(_) => Association::A3,
            Kind::Coverage(_, a) => *a,
            Kind::Shortest(a) | Kind::Replay(a) => *a,
            Kind::Hindsight(_) => Association::Learned,
        };
        if let Some(t) = &method.a3 {
            t.apply(&mut mcfg.radio.a3);
        }
        if let Kind::Policy(p) = &method.kind {
            if mcfg.env.site_every_step && p.site_head.is_none() {
                // Only the equivariant head scores the sites of a later step: a policy of the
                // paper's slot head (or without a site) is flown with the site held.
                mcfg.env.site_every_step = false;
                tracing::info!(
                    label = %method.label,
                    "env.site_every_step off for this policy: it has no equivariant site head"
                );
            }
            // Flown with the observation it was trained on, whatever this configuration's.
            mcfg = p
                .configure(&mcfg)
                .map_err(|e| refused!("policy {} (seed {}): {e}", method.label, method.seed))?;
            if let Some(w) = method.handover_weight {
                mcfg.env.reward.handover_weight = w;
            }
            let probe = Env::new(&mcfg, world.clone(), rsrp.clone())?;
            if probe.layout().len() != p.obs_dim {
                return Err(refused!(
                    "policy {} (seed {}): it expects {} observations, this configuration gives {} with its recorded observation: another number of sites (scenario.n_sites)?",
                    method.label,
                    method.seed,
                    p.obs_dim,
                    probe.layout().len(),
                ));
            }
        }
        let pb = progress_bar(
            pairs.len() as u64,
            &format!("{} seed {}", method.label, method.seed),
            quiet,
        );
        let flights: Vec<FlightRecord> = pairs
            .par_iter()
            .zip(&shortest)
            .map(|(p, sp)| {
                let r = fly_one(
                    &mcfg,
                    &world,
                    &rsrp,
                    planners_of(p),
                    fs,
                    method,
                    p,
                    sp.as_deref(),
                );
                pb.inc(1);
                r
            })
            .collect::<Result<_, RunError>>()?;
        pb.finish_and_clear();
        // A learned site choice: the same moves re-flown with the A3 rule and with the
        // best-RSRP oracle choosing the site, so the report separates route from association.
        let replays = match &method.kind {
            Kind::Policy(p) if p.n_sites > 0 && !args.no_replay => {
                let ctx = (cfg, &world, &rsrp, &planners, fs);
                replay_associations(ctx, method, &pairs, &flights, &hindsight)?
            }
            _ => Vec::new(),
        };
        let front_of = match &method.kind {
            Kind::Policy(p) if p.n_sites > 0 => Some(true),
            Kind::Shortest(Association::A3) | Kind::Coverage(_, Association::A3)
                if method.a3.is_none() =>
            {
                Some(false)
            }
            _ => None,
        };
        if let (true, Some(learned_site)) = (args.a3_front, front_of) {
            let ctx = (cfg, &world, &rsrp, &planners, fs);
            let points = a3_front(ctx, method, &pairs, &flights, &rules, quiet)?;
            write_front(
                dir,
                &FrontFile {
                    method: method.label.clone(),
                    seed: method.seed,
                    learned_site,
                    points,
                },
            )?;
        }
        for (label, flights) in std::iter::once((method.label.clone(), flights)).chain(replays) {
            let rec = RecordsFile {
                method: label,
                seed: method.seed,
                rules,
                flights,
            };
            write_records(dir, &rec)?;
        }
        eprintln!(
            "{} seed {}: {} flights recorded",
            method.label,
            method.seed,
            pairs.len()
        );
    }
    Ok(())
}

/// What a re-flight needs: the configuration, the world, its RSRP, the planners and the field
/// split the pairs fly in.
type FlyCtx<'a, 'w> = (
    &'a Config,
    &'a Arc<RadioWorld>,
    &'a SharedRsrp,
    &'a Planners<'w>,
    FieldSplit,
);

/// Every flight of `flights` (one per pair of `pairs`) re-flown through its recorded positions
/// under `rcfg` as `replay` ([`Kind::Replay`] or [`Kind::Hindsight`]), in parallel, in order.
fn refly(
    rcfg: &Config,
    (_, world, rsrp, planners, fs): FlyCtx,
    replay: &Method,
    pairs: &[Pair],
    flights: &[FlightRecord],
) -> Result<Vec<FlightRecord>, RunError> {
    pairs
        .par_iter()
        .zip(flights)
        .map(|(p, f)| {
            let w: Vec<Point> = f
                .steps
                .iter()
                .map(|s| Point::from(s.position_m.map(f64::from)))
                .collect();
            fly_one(rcfg, world, rsrp, planners, fs, replay, p, Some(&w))
        })
        .collect()
}

/// The positions of every flight of `method` re-flown with the A3 rule (`LABEL+a3`) and with
/// the best-RSRP oracle (`LABEL+oracle`) choosing the site: the same route, another association.
/// A replay takes one step to each recorded position in turn (`pilot::replay_positions`), so it
/// has the policy flight's steps and end; the positions are stored in f32 (within 0.1 mm).
/// With `hindsight`, also with each hindsight association (`LABEL+hindsight_…`).
fn replay_associations(
    ctx: FlyCtx,
    method: &Method,
    pairs: &[Pair],
    flights: &[FlightRecord],
    hindsight: &[(String, Hindsight)],
) -> Result<Vec<(String, Vec<FlightRecord>)>, RunError> {
    let rules = [
        (Kind::Replay(Association::A3), "a3".to_string()),
        (Kind::Replay(Association::BestRsrp), "oracle".to_string()),
    ];
    let hindsight = hindsight
        .iter()
        .map(|(l, h)| (Kind::Hindsight(*h), l.clone()));
    rules
        .into_iter()
        .chain(hindsight)
        .map(|(kind, suffix)| {
            let mut rcfg = dupac_run::scenario::unguided(ctx.0);
            rcfg.env.association = match kind {
                Kind::Replay(a) => a,
                _ => Association::Learned,
            };
            let label = format!("{}+{suffix}", method.label);
            let replay = Method {
                label: label.clone(),
                seed: method.seed,
                kind,
                a3: None,
                handover_weight: None,
            };
            Ok((label, refly(&rcfg, ctx, &replay, pairs, flights)?))
        })
        .collect()
}

/// The positions of every flight of `method` re-flown with A3 at each setting of the `dupac
/// tune-a3` grid ([`A3Grid`](crate::a3_setting::A3Grid)): each setting's per-flight metrics ([`crate::front`]).
fn a3_front(
    ctx: FlyCtx,
    method: &Method,
    pairs: &[Pair],
    flights: &[FlightRecord],
    rules: &MetricRules,
    quiet: bool,
) -> Result<Vec<FrontPoint>, RunError> {
    let settings = A3Grid::default().settings()?;
    let replay = Method {
        label: format!("{}+a3_front", method.label),
        seed: method.seed,
        kind: Kind::Replay(Association::A3),
        a3: None,
        handover_weight: None,
    };
    let pb = progress_bar(
        settings.len() as u64,
        &format!("{} seed {}: A3 front", method.label, method.seed),
        quiet,
    );
    let points = settings
        .iter()
        .map(|setting| {
            let mut rcfg = dupac_run::scenario::unguided(ctx.0);
            rcfg.env.association = Association::A3;
            setting.apply(&mut rcfg.radio.a3);
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
        .collect::<Result<Vec<_>, RunError>>();
    pb.finish_and_clear();
    points
}

#[allow(clippy::too_many_arguments)]
fn fly_one(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    planners: &Planners,
    fs: FieldSplit,
    method: &Method,
    p: &Pair,
    // The shortest path (`Kind::Shortest`) or the recorded positions (`Kind::Replay`).
    waypoints_m: Option<&[Point]>,
) -> Result<FlightRecord, RunError> {
    let mut env = Env::new(cfg, world.clone(), rsrp.clone())?;
    let episode = dupac_run::scenario::episode(cfg, planners, p, fs)?;
    let steps = match &method.kind {
        Kind::Policy(policy) => fly_policy(&mut env, policy, p.id, episode, p.id)?.1,
        Kind::Shortest(_) => {
            let w = waypoints_m.ok_or_else(|| refused!("pair {}: no shortest path", p.id))?;
            fly_waypoints(&mut env, p.id, episode, w, |e| e.serving())?.steps
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
            fly_waypoints(&mut env, p.id, episode, &path.waypoints_m, |e| e.serving())?.steps
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
pub(crate) fn flight_record(
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
    let remaining_m = steps.last().map_or(p.shortest_m, |s| s.distance_to_goal_m);
    let outcome = steps
        .last()
        .and_then(|s| s.outcome)
        .unwrap_or(Outcome::TimeLimit);
    let steps = steps
        .iter()
        .map(|s| {
            truth.rsrp_all_dbm(s.position_m, &mut all);
            StepRecord::from_info(s, sinr_db(&all, usize::from(s.serving.0), NOISE_PER_RE_DBM))
        })
        .collect();
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
        start_serving: start_serving.0,
        steps,
    }
}

/// The true RSRP pair `id` is flown in: field `id mod radio.channel.eval_fields` of `fs` (the
/// validation's or the test split's realisations) under the real channel
/// ([`dupac_run::scenario::true_source`]).
fn true_rsrp(world: &Arc<RadioWorld>, rsrp: &SharedRsrp, fs: FieldSplit, id: u64) -> SharedRsrp {
    dupac_run::scenario::true_source(world, rsrp, fs, id)
}

/// With `radio.channel.knowledge = "true_field"` under the real channel, one set of planners per
/// evaluation field, their coverage classes from that field's true RSRP: the guide and the
/// coverage-aware planner of a pair plan on the field it is flown in. `None` otherwise (they
/// plan on the model without shadowing, as an operator would).
fn true_field_planners<'w>(
    cfg: &Config,
    unguided_cfg: &Config,
    flown: &[Config],
    world: &'w Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    fs: FieldSplit,
    coverage: bool,
) -> Option<Vec<dupac_run::scenario::Planners<'w>>> {
    let c = &cfg.radio.channel;
    if world.channel.is_none() || c.knowledge != Knowledge::TrueField {
        return None;
    }
    Some(
        (0..u64::from(c.eval_fields))
            .map(|k| {
                let truth = true_rsrp(world, rsrp, fs, k);
                dupac_run::scenario::Planners::new(unguided_cfg, flown, world, &truth, coverage)
            })
            .collect(),
    )
}
