//! Flying the evaluation: every method over every pair in parallel, each flight recorded; a
//! learned site choice's moves re-flown with other associations and the fronts of every rule
//! ([`crate::refly`]: route against association).

use crate::error::refused;
use crate::error::{Context, EvalError};
use crate::flight::{fly_one, policy_env, true_rsrp};
use crate::front::write_front;
use crate::metrics::MetricRules;
use crate::record::FlightRecord;
use crate::records::{RecordsFile, write_records, write_split};
use crate::refly::{Fronts, fronts_of, replay_associations};
use crate::{EvalPlan, Kind, methods, parse_hindsight, select};
use dupac_actor::pairs::{Pair, Split};
use dupac_common::config::{Association, Config, Knowledge};
use dupac_common::geometry::Point;
use dupac_radio::channel::FieldSplit;
use dupac_radio::world::RadioWorld;
use dupac_scenario::pairs::read_eval_pairs;
use dupac_scenario::progress::progress_bar;
use dupac_scenario::world::{SharedRsrp, world_and_cache};
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Flies every method of `args` and writes its records (and its replays') into `dir`.
pub fn fly_all(cfg: &Config, args: &EvalPlan, dir: &Path, quiet: bool) -> Result<(), EvalError> {
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
        .collect::<Result<Vec<_>, EvalError>>()?;
    let learned_site = methods
        .iter()
        .any(|m| matches!(&m.kind, Kind::Policy(p) if p.n_sites > 0));
    for (flag, given) in [
        ("--hindsight-front", !args.hindsight_front.is_empty()),
        ("--predictive-front", !args.predictive_front.is_empty()),
    ] {
        if given && !learned_site {
            return Err(refused!(
                "{flag} re-flies the moves of learned-site policies: give a --policy whose policy chooses the site"
            ));
        }
    }
    let fronts = Fronts {
        a3: if args.a3_front {
            args.a3_grid.settings()?
        } else {
            Vec::new()
        },
        hindsight_costs_db: args.hindsight_front.clone(),
        predictive_costs_db_m: args.predictive_front.clone(),
    };
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
    let unguided_cfg = dupac_scenario::planners::unguided(cfg);
    let planners =
        dupac_scenario::planners::Planners::new(&unguided_cfg, &flown, &world, &rsrp, coverage);
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
            dupac_scenario::pairs::guide_pairs(guide_cfg, planners, &mut mine)?;
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
            Kind::Policy(_) if method.predictive => Association::Predictive,
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
            policy_env(&mcfg, &world, &rsrp, p)
                .map_err(|e| refused!("policy {} (seed {}): {e}", method.label, method.seed))?;
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
            .collect::<Result<_, EvalError>>()?;
        pb.finish_and_clear();
        // A learned site choice: the same moves re-flown with the A3 rule and with the
        // best-RSRP oracle choosing the site, so the report separates route from association.
        let replays = match &method.kind {
            Kind::Policy(p) if p.n_sites > 0 && !args.no_replay => {
                let ctx = (cfg, &world, &rsrp, &planners, fs);
                replay_associations(ctx, method, &pairs, &flights, &hindsight, quiet)?
            }
            _ => Vec::new(),
        };
        let ctx = (cfg, &world, &rsrp, &planners, fs);
        for f in fronts_of(ctx, &fronts, method, &pairs, &flights, &rules, quiet)? {
            write_front(dir, &f)?;
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
) -> Option<Vec<dupac_scenario::planners::Planners<'w>>> {
    let c = &cfg.radio.channel;
    if world.channel.is_none() || c.knowledge != Knowledge::TrueField {
        return None;
    }
    Some(
        (0..u64::from(c.eval_fields))
            .map(|k| {
                let truth = true_rsrp(world, rsrp, fs, k);
                dupac_scenario::planners::Planners::new(
                    unguided_cfg,
                    flown,
                    world,
                    &truth,
                    coverage,
                )
            })
            .collect(),
    )
}
