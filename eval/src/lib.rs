//! DUPAC's evaluation, in one place: every evaluation pair flown with trained policies (several
//! training seeds per method) and with the planners (shortest path with A3 and with the
//! best-RSRP oracle, coverage-aware paths over a λ sweep); every step recorded ([`records`]); a
//! learned site choice's moves re-flown with A3, the oracle and the hindsight association
//! ([`fly`], [`hindsight`]; each step's SINR [`sinr`]); A3's settings tuned on the validation
//! split ([`tune_a3`], [`a3_setting`]) and the fronts of excellent time against handovers
//! ([`front`]; every A3 setting re-associated from one flight: [`trace`]); the statistics and the report's
//! tables from the records alone ([`report`]; per-method data [`method_data`]; intervals
//! [`interval`]; seed-aware bootstrap, per-seed rows and paired differences: [`stats`],
//! [`stats_tables`]). What `plot` draws is this crate's data: records, fronts, per-method data.
//! The figures are `dupac-plot`'s; training's periodic held-out check is `dupac_run::held_out`.
//! Over the scenario (`dupac-scenario`: world, planners, pairs), beside `dupac-run`; errors as
//! [`error::EvalError`].

pub mod a3_setting;
pub mod error;
pub mod flight;
pub mod fly;
pub mod front;
pub mod hindsight;
pub mod interval;
pub mod method_data;
pub mod metrics;
pub mod pair_flights;
pub mod record;
pub mod records;
pub mod refly;
pub mod report;
pub mod sinr;
pub mod stats;
pub mod stats_tables;
pub mod trace;
pub mod tune_a3;

use crate::a3_setting::{A3Grid, A3Setting};
use crate::error::refused;
use crate::error::{Context, EvalError};
use dupac_actor::pairs::{Pair, Split};
use dupac_common::config::Association;
use dupac_common::policy::PolicyWeights;
use dupac_learner::checkpoint::load_policy;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The largest `--handover-weight` (the bound `env.reward.handover_weight` has).
const MAX_HANDOVER_WEIGHT: f64 = 100.0;

/// The largest handover cost of `--hindsight-front` and `--predictive-front` (the bound of
/// `--hindsight` and of `env.predictive.handover_cost_db_m`).
const MAX_HANDOVER_COST: f64 = 1e6;

/// What to evaluate (the options of `dupac eval`, validated here).
#[derive(Debug, Clone, Default)]
pub struct EvalPlan {
    /// `LABEL=FILE`, one per training seed of a label.
    pub policies: Vec<String>,
    /// λ of the coverage-aware planner (empty: 0.5, 1, 2, 4).
    pub lambdas: Vec<f64>,
    pub no_planners: bool,
    /// Pairs file (default: the file of `split`).
    pub pairs: Option<PathBuf>,
    /// The held-out split flown without `pairs` (default validation).
    pub split: Split,
    /// A tuned A3 setting (`dupac tune-a3`'s `tuned_a3.toml`): the planners are flown with it
    /// too (`shortest_a3tuned`, `coverage_l<λ>+a3tuned`).
    pub a3_tuned: Option<A3Setting>,
    /// Labels whose policies are flown with `a3_tuned` (a base method trained with the tuned
    /// A3: a policy records its observation, not its A3 setting).
    pub tuned_labels: Vec<String>,
    /// Labels whose policies (base methods: no site head) are flown with the predictive
    /// association (`env.predictive`) instead of A3.
    pub predictive_labels: Vec<String>,
    /// The first K pairs of every bin.
    pub per_bin: Option<usize>,
    /// No `LABEL+a3` / `LABEL+oracle` replays.
    pub no_replay: bool,
    /// `C` or `C:mts` hindsight associations.
    pub hindsight: Vec<String>,
    /// Re-fly every learned-site policy's moves and every planner's A3 path with each setting of
    /// `a3_grid` ([`front`]).
    pub a3_front: bool,
    /// The A3 settings of `a3_front` (the flags `--offset-db`, `--hysteresis-db`, `--ttt-ms`,
    /// `--l3-filter-k`; by default [`A3Grid::default`]).
    pub a3_grid: A3Grid,
    /// Handover costs C (dB·steps per handover) at which every learned-site policy's moves are
    /// re-flown with the hindsight association (no minimum stay): its front ([`front`]).
    pub hindsight_front: Vec<f64>,
    /// Handover costs C (dB·m per handover, `env.predictive.handover_cost_db_m`) at which every
    /// learned-site policy's moves are re-flown with the predictive association: its front.
    pub predictive_front: Vec<f64>,
    /// Handover weights (`env.reward.handover_weight`, docs/env.md "Handover weight") at which
    /// every policy that observes the weight is flown, each as its own method `LABEL_w<W>`
    /// (empty: once, at the configuration's weight).
    pub handover_weights: Vec<f64>,
}

/// A `--hindsight` value: handover cost (dB·steps) and the minimum stay (steps).
#[derive(Debug, Clone, Copy)]
pub struct Hindsight {
    pub cost_db: f64,
    pub min_stay_steps: u32,
}

pub fn parse_hindsight(spec: &str, window_steps: u32) -> Result<(String, Hindsight), EvalError> {
    let (c, mts) = match spec.split_once(':') {
        Some((c, "mts")) => (c, true),
        Some(_) => return Err(refused!("--hindsight {spec}: expected C or C:mts")),
        None => (spec, false),
    };
    let cost_db: f64 = c
        .parse()
        .ok()
        .filter(|x: &f64| x.is_finite() && (0.0..=1e6).contains(x))
        .ok_or_else(|| refused!("--hindsight {spec}: C must be a number in [0, 1e6] (dB·steps)"))?;
    let label = format!("hindsight_{cost_db}{}", if mts { "_mts" } else { "" });
    Ok((
        label,
        Hindsight {
            cost_db,
            min_stay_steps: if mts { window_steps + 1 } else { 0 },
        },
    ))
}

/// How a method's flights are flown.
pub enum Kind {
    Policy(Box<PolicyWeights>),
    Shortest(Association),
    /// A recorded flight's positions re-flown with this association (`replay_associations`).
    Replay(Association),
    /// A recorded flight's positions re-flown with the hindsight association.
    Hindsight(Hindsight),
    /// The coverage-aware planner's path (λ) flown with this association.
    Coverage(f64, Association),
}

/// One method and training seed to fly.
pub struct Method {
    pub label: String,
    pub seed: u32,
    pub kind: Kind,
    /// The A3 parameters it is flown with instead of `radio.a3` (the `+a3tuned` rows).
    pub a3: Option<A3Setting>,
    /// A base-method policy flown with the predictive association instead of A3
    /// (`--predictive-label`).
    pub predictive: bool,
    /// The handover weight it is flown at instead of `env.reward.handover_weight` (a policy
    /// that observes it, flown at each `--handover-weight`).
    pub handover_weight: Option<f64>,
}

/// The methods of `plan`: its policies (seeds numbered per label in order), then the planners.
pub fn methods(args: &EvalPlan) -> Result<Vec<Method>, EvalError> {
    if let Some(w) = args
        .handover_weights
        .iter()
        .find(|w| !(w.is_finite() && (0.0..=MAX_HANDOVER_WEIGHT).contains(*w)))
    {
        return Err(refused!(
            "--handover-weight {w}: must be a number in [0, {MAX_HANDOVER_WEIGHT}]"
        ));
    }
    for (flag, costs, unit) in [
        ("--hindsight-front", &args.hindsight_front, "dB·steps"),
        ("--predictive-front", &args.predictive_front, "dB·m"),
    ] {
        if let Some(c) = costs
            .iter()
            .find(|c| !(c.is_finite() && (0.0..=MAX_HANDOVER_COST).contains(*c)))
        {
            return Err(refused!(
                "{flag} {c}: a handover cost must be a number in [0, {MAX_HANDOVER_COST}] ({unit})"
            ));
        }
    }
    let mut out = Vec::new();
    let mut seeds: BTreeMap<String, u32> = BTreeMap::new();
    let mut per_weight: BTreeMap<String, u32> = BTreeMap::new();
    for spec in &args.policies {
        let (label, file) = spec
            .split_once('=')
            .ok_or_else(|| refused!("--policy {spec}: expected LABEL=FILE"))?;
        if label.is_empty()
            || !label
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
        {
            return Err(refused!(
                "--policy {spec}: the label must be letters, digits, '-', '_' or '.'"
            ));
        }
        let p = load_policy(Path::new(file)).context_with(|| format!("--policy {spec}"))?;
        let a3 = match (args.tuned_labels.iter().any(|t| t == label), args.a3_tuned) {
            (false, _) => None,
            (true, Some(t)) => Some(t),
            (true, None) => {
                return Err(refused!(
                    "--tuned-label {label}: flies its policies with the --a3-tuned setting; give --a3-tuned FILE"
                ));
            }
        };
        let predictive = args.predictive_labels.iter().any(|t| t == label);
        if predictive && p.n_sites > 0 {
            return Err(refused!(
                "--predictive-label {label}: its policy {file} chooses the site itself (a site head); the predictive association flies base-method policies"
            ));
        }
        if predictive && a3.is_some() {
            return Err(refused!(
                "--predictive-label {label}: the label is a --tuned-label too; a policy is flown with one association"
            ));
        }
        // One method per weight (`LABEL_w<W>`) for a policy that observes it; one at the
        // configuration's weight otherwise (the weight would change only its reward).
        let observes_weight = p.observation.as_ref().is_some_and(|o| o.handover_weight);
        let weights: Vec<Option<f64>> = if args.handover_weights.is_empty() || !observes_weight {
            vec![None]
        } else {
            args.handover_weights.iter().copied().map(Some).collect()
        };
        seeds.entry(label.to_string()).or_insert(0);
        for w in weights {
            let flown = match w {
                Some(w) => format!("{label}_w{w}"),
                None => label.to_string(),
            };
            let seed = per_weight.entry(flown.clone()).or_insert(0);
            out.push(Method {
                label: flown,
                seed: *seed,
                kind: Kind::Policy(Box::new(p.clone())),
                a3,
                predictive,
                handover_weight: w,
            });
            *seed += 1;
        }
    }
    if let Some(t) = args.tuned_labels.iter().find(|t| !seeds.contains_key(*t)) {
        return Err(refused!("--tuned-label {t}: no --policy has this label"));
    }
    if let Some(t) = args
        .predictive_labels
        .iter()
        .find(|t| !seeds.contains_key(*t))
    {
        return Err(refused!(
            "--predictive-label {t}: no --policy has this label"
        ));
    }
    if args.no_planners && args.a3_tuned.is_some() {
        return Err(refused!(
            "--a3-tuned flies the planners with the tuned A3: it cannot go with --no-planners"
        ));
    }
    if !args.no_planners {
        let lambdas = if args.lambdas.is_empty() {
            vec![0.5, 1.0, 2.0, 4.0]
        } else {
            args.lambdas.clone()
        };
        if let Some(l) = lambdas.iter().find(|l| !(l.is_finite() && **l >= 0.0)) {
            return Err(refused!("--lambda {l}: must be a finite number >= 0"));
        }
        let planner = |label: String, kind: Kind, a3: Option<A3Setting>| Method {
            label,
            seed: 0,
            kind,
            a3,
            predictive: false,
            handover_weight: None,
        };
        out.push(planner(
            "shortest_a3".into(),
            Kind::Shortest(Association::A3),
            None,
        ));
        out.push(planner(
            "shortest_oracle".into(),
            Kind::Shortest(Association::BestRsrp),
            None,
        ));
        // The predictive association on the route it flies (docs/env.md "Predictive association").
        out.push(planner(
            "shortest_predictive".into(),
            Kind::Shortest(Association::Predictive),
            None,
        ));
        for &l in &lambdas {
            out.push(planner(
                format!("coverage_l{l}"),
                Kind::Coverage(l, Association::A3),
                None,
            ));
            out.push(planner(
                format!("coverage_l{l}+oracle"),
                Kind::Coverage(l, Association::BestRsrp),
                None,
            ));
        }
        // The same planners' routes with the tuned A3 choosing the site.
        if let Some(t) = args.a3_tuned {
            out.push(planner(
                "shortest_a3tuned".into(),
                Kind::Shortest(Association::A3),
                Some(t),
            ));
            for &l in &lambdas {
                out.push(planner(
                    format!("coverage_l{l}+a3tuned"),
                    Kind::Coverage(l, Association::A3),
                    Some(t),
                ));
            }
        }
    }
    if out.is_empty() {
        return Err(refused!(
            "nothing to evaluate: give --policy LABEL=FILE, or drop --no-planners"
        ));
    }
    Ok(out)
}

/// The first `k` pairs of every bin, in file order.
pub fn select(pairs: Vec<Pair>, k: Option<usize>) -> Vec<Pair> {
    let Some(k) = k else { return pairs };
    let mut taken: BTreeMap<u64, usize> = BTreeMap::new();
    pairs
        .into_iter()
        .filter(|p| {
            let n = taken.entry(p.bin_m.unwrap_or(0.0).to_bits()).or_insert(0);
            *n += 1;
            *n <= k
        })
        .collect()
}

pub fn argmax(v: &[f64]) -> u16 {
    let mut best = (0usize, f64::NEG_INFINITY);
    for (i, &x) in v.iter().enumerate() {
        if x > best.1 {
            best = (i, x);
        }
    }
    best.0 as u16
}
