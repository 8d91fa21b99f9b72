//! `dupac eval`: flies every evaluation pair with trained policies (several training seeds per
//! method) and with the planners (shortest path with A3 and with the best-RSRP oracle,
//! coverage-aware paths over a λ sweep), records every step, and writes a report directory:
//! the paper's Fig. 3 and Fig. 4 data and figures, success/collision/timeout rates, handovers and
//! ping-pongs, SINR, a Pareto plot of distance overhead against time in excellent RSRP, CSVs of
//! every figure, and `report.md` with the paper's numbers beside ours (issue 6). `--report-only`
//! recomputes the report from the saved step records without flying.

use crate::GlobalArgs;
use crate::io::{write_atomic, write_atomic_with};
use crate::plan_plot::{FlightTrace, render_plan_png};
use anyhow::{Context, Result, anyhow, bail};
use clap::Args;
use dupac_actor::env::{Env, Episode, Outcome};
use dupac_actor::eval::{
    FlightMetrics, FlightRecord, MeanCi, NOISE_PER_RE_DBM, Rate, StepRecord, flight_metrics,
    hindsight_association, mean_ci95, sinr_db, wilson95,
};
use dupac_actor::pairs::Pair;
use dupac_actor::pilot::{fly_waypoints, replay_positions};
use dupac_actor::planner::Planner;
use dupac_actor::rollout::fly_policy;
use dupac_common::SiteId;
use dupac_common::codec;
use dupac_common::config::{Association, Config};
use dupac_common::policy::PolicyWeights;
use dupac_learner::checkpoint::load_policy;
use dupac_radio::cache::RsrpSource;
use dupac_radio::class::RsrpThresholds;
use dupac_run::scenario::world_and_cache;
use plotters::prelude::*;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// A trained policy as `LABEL=FILE` (`policy.bin` or `checkpoint.bin`); repeat a label once
    /// per training seed (`--policy dupac=s1/policy.bin --policy dupac=s2/policy.bin`).
    #[arg(long = "policy", value_name = "LABEL=FILE")]
    pub policies: Vec<String>,
    /// λ of the coverage-aware planner, flown with A3 (repeatable; default 0.5, 1, 2, 4).
    #[arg(long = "lambda", value_name = "L")]
    pub lambdas: Vec<f64>,
    /// Leave the planners out (shortest path with A3 and with the oracle, coverage-aware).
    #[arg(long)]
    pub no_planners: bool,
    /// Pairs file (default `pairs.eval_file`, the held-out set).
    #[arg(long, value_name = "FILE")]
    pub pairs: Option<PathBuf>,
    /// Pairs per distance bin: the first K of each bin (default: all).
    #[arg(long, value_name = "K")]
    pub per_bin: Option<usize>,
    /// Report directory.
    #[arg(long, default_value = "out/eval")]
    pub out: PathBuf,
    /// Recompute the report from `OUT/records/*.bin` without flying.
    #[arg(long)]
    pub report_only: bool,
    /// Also render the paper's Fig. 2(b) (best-server coverage per altitude and its summary
    /// table, as `dupac map`) into `OUT/fig2b/`.
    #[arg(long)]
    pub maps: bool,
    /// Labels compared with the paper's DUPAC and base method.
    #[arg(long, default_value = "dupac")]
    pub dupac_label: String,
    #[arg(long, default_value = "base")]
    pub base_label: String,
    /// Do not re-fly a learned-site policy's moves with A3 and the oracle (`LABEL+a3`,
    /// `LABEL+oracle`, the report's "Route or association").
    #[arg(long)]
    pub no_replay: bool,
    /// Also re-fly a learned-site policy's moves with the hindsight association
    /// (`LABEL+hindsight_C`): the sites that minimise the site regret plus C dB·steps per
    /// handover over the whole recorded route; `C:mts` also forbids a handover sooner than
    /// `env.ping_pong_window_s` after the previous one (no ping-pongs). An evaluation reference
    /// that knows the route in advance (repeatable; docs/results.md "What any association can do").
    #[arg(long = "hindsight", value_name = "C[:mts]")]
    pub hindsight: Vec<String>,
}

/// A `--hindsight` value: handover cost (dB·steps) and the minimum stay (steps).
#[derive(Debug, Clone, Copy)]
struct Hindsight {
    cost_db: f64,
    min_stay_steps: u32,
}

fn parse_hindsight(spec: &str, window_steps: u32) -> Result<(String, Hindsight)> {
    let (c, mts) = match spec.split_once(':') {
        Some((c, "mts")) => (c, true),
        Some(_) => bail!("--hindsight {spec}: expected C or C:mts"),
        None => (spec, false),
    };
    let cost_db: f64 = c
        .parse()
        .ok()
        .filter(|x: &f64| x.is_finite() && (0.0..=1e6).contains(x))
        .ok_or_else(|| anyhow!("--hindsight {spec}: C must be a number in [0, 1e6] (dB·steps)"))?;
    let label = format!("hindsight_{cost_db}{}", if mts { "_mts" } else { "" });
    Ok((
        label,
        Hindsight {
            cost_db,
            min_stay_steps: if mts { window_steps + 1 } else { 0 },
        },
    ))
}

/// Magic and version of a records file (`OUT/records/<method>__seed<k>.bin`).
const RECORDS_MAGIC: &[u8; 8] = b"DUPACEVR";
const RECORDS_VERSION: u32 = 3;

/// The records of one method and seed, with what the metrics need from the configuration.
#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct RecordsFile {
    method: String,
    seed: u32,
    ping_pong_window_steps: u32,
    /// `env.site_regret_threshold_db` of the run (dB).
    site_regret_threshold_db: f64,
    /// Serving site before the first step, per flight (same order as `flights`).
    start_serving: Vec<u16>,
    flights: Vec<FlightRecord>,
}

enum Kind {
    Policy(Box<PolicyWeights>),
    Shortest(Association),
    /// A recorded flight's positions re-flown with this association (`replay_associations`).
    Replay(Association),
    /// A recorded flight's positions re-flown with the hindsight association.
    Hindsight(Hindsight),
    Coverage(f64),
}

struct Method {
    label: String,
    seed: u32,
    kind: Kind,
}

pub fn run(global: &GlobalArgs, args: &EvalArgs) -> Result<ExitCode> {
    let cfg = global.config()?;
    let records_dir = args.out.join("records");
    if !args.report_only {
        fly_all(global, &cfg, args, &records_dir)?;
    }
    let files = read_records(&records_dir)?;
    if files.is_empty() {
        bail!("{}: no records to report on", records_dir.display());
    }
    write_report(&args.out, &files, &args.dupac_label, &args.base_label)?;
    let world = dupac_radio::world::RadioWorld::build(&cfg).context("building the radio world")?;
    draw_examples(
        &args.out,
        &world,
        &files,
        &RsrpThresholds::from_config(&cfg.radio),
    )?;
    if args.maps {
        super::map::run(
            global,
            &super::map::MapArgs {
                out: Some(args.out.join("fig2b")),
                site: None,
            },
        )?;
    }
    println!("wrote {}", args.out.display());
    Ok(ExitCode::SUCCESS)
}

fn methods(args: &EvalArgs) -> Result<Vec<Method>> {
    let mut out = Vec::new();
    let mut seeds: BTreeMap<String, u32> = BTreeMap::new();
    for spec in &args.policies {
        let (label, file) = spec
            .split_once('=')
            .ok_or_else(|| anyhow!("--policy {spec}: expected LABEL=FILE"))?;
        if label.is_empty()
            || !label
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
        {
            bail!("--policy {spec}: the label must be letters, digits, '-', '_' or '.'");
        }
        let p = load_policy(Path::new(file)).with_context(|| format!("--policy {spec}"))?;
        let seed = seeds.entry(label.to_string()).or_insert(0);
        out.push(Method {
            label: label.to_string(),
            seed: *seed,
            kind: Kind::Policy(Box::new(p)),
        });
        *seed += 1;
    }
    if !args.no_planners {
        out.push(Method {
            label: "shortest_a3".into(),
            seed: 0,
            kind: Kind::Shortest(Association::A3),
        });
        out.push(Method {
            label: "shortest_oracle".into(),
            seed: 0,
            kind: Kind::Shortest(Association::BestRsrp),
        });
        let lambdas = if args.lambdas.is_empty() {
            vec![0.5, 1.0, 2.0, 4.0]
        } else {
            args.lambdas.clone()
        };
        for l in lambdas {
            if !(l.is_finite() && l >= 0.0) {
                bail!("--lambda {l}: must be a finite number >= 0");
            }
            out.push(Method {
                label: format!("coverage_l{l}"),
                seed: 0,
                kind: Kind::Coverage(l),
            });
        }
    }
    if out.is_empty() {
        bail!("nothing to evaluate: give --policy LABEL=FILE, or drop --no-planners");
    }
    Ok(out)
}

/// The first `k` pairs of every bin, in file order.
fn select(pairs: Vec<Pair>, k: Option<usize>) -> Vec<Pair> {
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

fn argmax(v: &[f64]) -> u16 {
    let mut best = (0usize, f64::NEG_INFINITY);
    for (i, &x) in v.iter().enumerate() {
        if x > best.1 {
            best = (i, x);
        }
    }
    best.0 as u16
}

fn fly_all(global: &GlobalArgs, cfg: &Config, args: &EvalArgs, dir: &Path) -> Result<()> {
    let methods = methods(args)?;
    let window = (cfg.env.ping_pong_window_s / cfg.env.dt_s())
        .ceil()
        .max(1.0) as u32;
    if args.no_replay && !args.hindsight.is_empty() {
        bail!("--hindsight re-flies a policy's moves: it cannot go with --no-replay");
    }
    let hindsight = args
        .hindsight
        .iter()
        .map(|h| parse_hindsight(h, window))
        .collect::<Result<Vec<_>>>()?;
    let (world, rsrp) = world_and_cache(cfg, global.quiet)?;
    let mut planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    if methods.iter().any(|m| matches!(m.kind, Kind::Coverage(_))) {
        planner.with_coverage(rsrp.as_ref(), RsrpThresholds::from_config(&cfg.radio));
    }
    let (file, pairs) = dupac_run::scenario::read_eval_pairs(cfg, args.pairs.as_ref(), &planner)?;
    let pairs = select(pairs, args.per_bin);
    if pairs.is_empty() {
        bail!("{}: no pairs", file.display());
    }
    let m = world.num_sites();
    let start_serving: Vec<u16> = pairs
        .iter()
        .map(|p| {
            let mut all = vec![f64::NAN; m];
            rsrp.rsrp_all_dbm(p.source_m, &mut all);
            argmax(&all)
        })
        .collect();
    // The shortest paths once, shared by the A3 and oracle flights.
    let need_shortest = methods.iter().any(|m| matches!(m.kind, Kind::Shortest(_)));
    let shortest: Vec<Option<Vec<[f64; 3]>>> = if need_shortest {
        let pb = super::progress_bar(pairs.len() as u64, "shortest paths", global.quiet);
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
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for method in &methods {
        let mut mcfg = cfg.clone();
        mcfg.env.association = match &method.kind {
            Kind::Policy(p) if p.n_sites > 0 => Association::Learned,
            Kind::Policy(_) | Kind::Coverage(_) => Association::A3,
            Kind::Shortest(a) | Kind::Replay(a) => *a,
            Kind::Hindsight(_) => Association::Learned,
        };
        if let Kind::Policy(p) = &method.kind {
            let mut probe = Env::new(&mcfg, world.clone(), rsrp.clone())?;
            if probe.layout().len() != p.obs_dim && p.site_head.is_none() {
                // A policy of the paper's slot head may have been trained without the per-site
                // features (docs/paper_dupac.toml): fly it with the layout it was trained on.
                let o = &mut mcfg.env.observation;
                o.site_features = !o.site_features;
                probe = Env::new(&mcfg, world.clone(), rsrp.clone())?;
                if probe.layout().len() != p.obs_dim {
                    mcfg.env.observation.site_features = cfg.env.observation.site_features;
                } else {
                    tracing::info!(
                        label = %method.label,
                        site_features = mcfg.env.observation.site_features,
                        "flying the policy with the observation layout it was trained on"
                    );
                }
            }
            if probe.layout().len() != p.obs_dim {
                bail!(
                    "policy {} (seed {}): it expects {} observations, this configuration gives {} (evaluate with the configuration it was trained with)",
                    method.label,
                    method.seed,
                    p.obs_dim,
                    probe.layout().len()
                );
            }
        }
        let pb = super::progress_bar(
            pairs.len() as u64,
            &format!("{} seed {}", method.label, method.seed),
            global.quiet,
        );
        let flights: Vec<FlightRecord> = pairs
            .par_iter()
            .zip(&shortest)
            .map(|(p, sp)| {
                let r = fly_one(&mcfg, &world, &rsrp, &planner, method, p, sp.as_deref());
                pb.inc(1);
                r
            })
            .collect::<Result<_>>()?;
        pb.finish_and_clear();
        // A learned site choice: the same moves re-flown with the A3 rule and with the
        // best-RSRP oracle choosing the site, so the report separates route from association.
        let replays = match &method.kind {
            Kind::Policy(p) if p.n_sites > 0 && !args.no_replay => {
                let ctx = (cfg, &world, &rsrp, &planner);
                replay_associations(ctx, method, &pairs, &flights, &hindsight)?
            }
            _ => Vec::new(),
        };
        for (label, flights) in std::iter::once((method.label.clone(), flights)).chain(replays) {
            let rec = RecordsFile {
                method: label,
                seed: method.seed,
                ping_pong_window_steps: window,
                site_regret_threshold_db: cfg.env.site_regret_threshold_db,
                start_serving: start_serving.clone(),
                flights,
            };
            let bytes = codec::encode(RECORDS_MAGIC, RECORDS_VERSION, &rec, "eval records")?;
            write_atomic(
                &dir.join(format!("{}__seed{}.bin", rec.method, rec.seed)),
                &bytes,
            )?;
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

/// The positions of every flight of `method` re-flown with the A3 rule (`LABEL+a3`) and with
/// the best-RSRP oracle (`LABEL+oracle`) choosing the site: the same route, another association.
/// A replay takes one step to each recorded position in turn (`pilot::replay_positions`), so it
/// has the policy flight's steps and end; the positions are stored in f32 (within 0.1 mm).
/// With `hindsight`, also with each hindsight association (`LABEL+hindsight_…`).
fn replay_associations(
    (cfg, world, rsrp, planner): (
        &Config,
        &Arc<dupac_radio::world::RadioWorld>,
        &Arc<dyn RsrpSource + Send + Sync>,
        &Planner,
    ),
    method: &Method,
    pairs: &[Pair],
    flights: &[FlightRecord],
    hindsight: &[(String, Hindsight)],
) -> Result<Vec<(String, Vec<FlightRecord>)>> {
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
            let mut rcfg = cfg.clone();
            rcfg.env.association = match kind {
                Kind::Replay(a) => a,
                _ => Association::Learned,
            };
            // The hindsight programme keeps its own minimum stay.
            rcfg.env.min_time_of_stay_s = 0.0;
            let label = format!("{}+{suffix}", method.label);
            let replay = Method {
                label: label.clone(),
                seed: method.seed,
                kind,
            };
            let v = pairs
                .par_iter()
                .zip(flights)
                .map(|(p, f)| {
                    let w: Vec<[f64; 3]> = f
                        .steps
                        .iter()
                        .map(|s| s.position_m.map(f64::from))
                        .collect();
                    fly_one(&rcfg, world, rsrp, planner, &replay, p, Some(&w))
                })
                .collect::<Result<Vec<_>>>()?;
            Ok((label, v))
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn fly_one(
    cfg: &Config,
    world: &Arc<dupac_radio::world::RadioWorld>,
    rsrp: &Arc<dyn RsrpSource + Send + Sync>,
    planner: &Planner,
    method: &Method,
    p: &Pair,
    // The shortest path (`Kind::Shortest`) or the recorded positions (`Kind::Replay`).
    waypoints_m: Option<&[[f64; 3]]>,
) -> Result<FlightRecord> {
    let mut env = Env::new(cfg, world.clone(), rsrp.clone())?;
    let episode = Episode {
        source_m: p.source_m,
        destination_m: p.destination_m,
        shortest_m: p.shortest_m,
    };
    let steps = match &method.kind {
        Kind::Policy(policy) => fly_policy(&mut env, policy, p.id, episode, p.id)?.1,
        Kind::Shortest(_) => {
            let w = waypoints_m.ok_or_else(|| anyhow!("pair {}: no shortest path", p.id))?;
            fly_waypoints(&mut env, p.id, episode, w, |e| e.serving())?.steps
        }
        Kind::Replay(_) => {
            let w = waypoints_m.ok_or_else(|| anyhow!("pair {}: no positions to replay", p.id))?;
            replay_positions(&mut env, p.id, episode, w, |e| e.serving())?.steps
        }
        Kind::Hindsight(h) => {
            let w = waypoints_m.ok_or_else(|| anyhow!("pair {}: no positions to replay", p.id))?;
            let m = world.num_sites();
            let mut rows = vec![f64::NAN; w.len() * m];
            for (row, pos) in rows.chunks_mut(m).zip(w) {
                rsrp.rsrp_all_dbm(*pos, row);
            }
            let mut start = vec![f64::NAN; m];
            rsrp.rsrp_all_dbm(p.source_m, &mut start);
            let sites =
                hindsight_association(&rows, m, argmax(&start), h.cost_db, h.min_stay_steps);
            let mut next = sites.into_iter().map(SiteId);
            replay_positions(&mut env, p.id, episode, w, |e| {
                next.next().unwrap_or_else(|| e.serving())
            })?
            .steps
        }
        Kind::Coverage(l) => {
            let path = planner
                .coverage_aware(p.source_m, p.destination_m, *l)
                .with_context(|| format!("pair {}: coverage-aware path (λ = {l})", p.id))?;
            fly_waypoints(&mut env, p.id, episode, &path.waypoints_m, |e| e.serving())?.steps
        }
    };
    let mut all = vec![f64::NAN; world.num_sites()];
    let remaining_m = steps.last().map_or(p.shortest_m, |s| s.distance_to_goal_m);
    let outcome = steps
        .last()
        .and_then(|s| s.outcome)
        .unwrap_or(Outcome::TimeLimit);
    let steps = steps
        .iter()
        .map(|s| {
            rsrp.rsrp_all_dbm(s.position_m, &mut all);
            StepRecord::from_info(s, sinr_db(&all, usize::from(s.serving.0), NOISE_PER_RE_DBM))
        })
        .collect();
    Ok(FlightRecord {
        method: method.label.clone(),
        seed: method.seed,
        pair_id: p.id,
        bin_m: p.bin_m.unwrap_or(p.shortest_m),
        shortest_m: p.shortest_m,
        straight_m: p.straight_m,
        outcome,
        source_m: p.source_m,
        destination_m: p.destination_m,
        remaining_m,
        steps,
    })
}

fn read_records(dir: &Path) -> Result<Vec<RecordsFile>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "bin"))
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|p| {
            let bytes = codec::read_limited(p, codec::MAX_BLOB_BYTES)?;
            let r: RecordsFile = codec::decode(
                RECORDS_MAGIC,
                RECORDS_VERSION,
                &bytes,
                codec::MAX_BLOB_BYTES,
                &p.display().to_string(),
            )?;
            if r.start_serving.len() != r.flights.len() {
                bail!(
                    "{}: {} start sites for {} flights",
                    p.display(),
                    r.start_serving.len(),
                    r.flights.len()
                );
            }
            Ok(r)
        })
        .collect()
}

/// The metrics of every flight of a method, all seeds together.
#[derive(Clone)]
struct MethodData {
    label: String,
    seeds: u32,
    flights: Vec<(f64, FlightMetrics)>, // (bin_m, metrics)
}

impl MethodData {
    fn successes(&self) -> impl Iterator<Item = &(f64, FlightMetrics)> {
        self.flights
            .iter()
            .filter(|(_, m)| m.outcome == Outcome::Goal)
    }
    /// Handovers and ping-pongs per km flown, over all flights.
    fn per_km(&self) -> (f64, f64) {
        let km: f64 = self
            .flights
            .iter()
            .map(|(_, m)| m.distance_m / 1000.0)
            .sum();
        let ho: f64 = self
            .flights
            .iter()
            .map(|(_, m)| f64::from(m.handovers))
            .sum();
        let pp: f64 = self
            .flights
            .iter()
            .map(|(_, m)| f64::from(m.ping_pongs))
            .sum();
        (ho / km.max(1e-9), pp / km.max(1e-9))
    }
    fn rate(&self, o: Outcome) -> Rate {
        let k = self.flights.iter().filter(|(_, m)| m.outcome == o).count();
        wilson95(k, self.flights.len())
    }
    fn ci(&self, bin: Option<f64>, f: impl Fn(&FlightMetrics) -> f64) -> MeanCi {
        let v: Vec<f64> = self
            .successes()
            .filter(|(b, _)| bin.is_none_or(|x| (x - b).abs() < 1e-6))
            .map(|(_, m)| f(m))
            .collect();
        mean_ci95(&v)
    }
    fn all_ci(&self, f: impl Fn(&FlightMetrics) -> f64) -> MeanCi {
        mean_ci95(&self.flights.iter().map(|(_, m)| f(m)).collect::<Vec<_>>())
    }
}

fn gather(files: &[RecordsFile]) -> Vec<MethodData> {
    let mut by: BTreeMap<String, MethodData> = BTreeMap::new();
    for f in files {
        let d = by.entry(f.method.clone()).or_insert_with(|| MethodData {
            label: f.method.clone(),
            seeds: 0,
            flights: Vec::new(),
        });
        d.seeds += 1;
        for (r, &s0) in f.flights.iter().zip(&f.start_serving) {
            d.flights.push((
                r.bin_m,
                flight_metrics(r, s0, f.ping_pong_window_steps, f.site_regret_threshold_db),
            ));
        }
    }
    // Policies first (as given), planners after.
    let mut v: Vec<MethodData> = by.into_values().collect();
    v.sort_by_key(|d| (is_planner(&d.label), d.label.clone()));
    v
}

fn is_planner(label: &str) -> bool {
    label.starts_with("shortest_") || label.starts_with("coverage_l")
}

fn bins_of(data: &[MethodData]) -> Vec<f64> {
    let mut b: Vec<f64> = data
        .iter()
        .flat_map(|d| d.flights.iter().map(|f| f.0))
        .collect();
    b.sort_by(f64::total_cmp);
    b.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    b
}

fn fmt_ci(c: MeanCi, scale: f64, digits: usize) -> String {
    if c.n == 0 {
        return "–".into();
    }
    if c.half_width.is_nan() {
        return format!("{:.*}", digits, c.mean * scale);
    }
    format!(
        "{:.*} ± {:.*}",
        digits,
        c.mean * scale,
        digits,
        c.half_width * scale
    )
}

fn fmt_rate(r: Rate) -> String {
    format!(
        "{:.1} % [{:.1}, {:.1}]",
        100.0 * r.rate,
        100.0 * r.lo,
        100.0 * r.hi
    )
}

fn write_report(out: &Path, files: &[RecordsFile], dupac: &str, base: &str) -> Result<()> {
    crate::plot::ensure_font()?;
    let data = gather(files);
    let bins = bins_of(&data);
    // summary.csv
    write_atomic_with(&out.join("summary.csv"), |w| {
        writeln!(
            w,
            "method,seeds,flights,success,success_lo,success_hi,collision,out_of_bounds,timeout,overhead_mean,overhead_ci,mean_rsrp_dbm,mean_rsrp_ci,pct_excellent,pct_excellent_ci,handovers_per_km,ping_pongs_per_km,mean_sinr_db,pct_sinr_below_m6db,site_regret_db,pct_site_regret_high,pct_class_regret"
        )?;
        for d in &data {
            let s = d.rate(Outcome::Goal);
            let ov = d.ci(None, |m| m.overhead);
            let rs = d.ci(None, |m| m.mean_rsrp_dbm);
            let ex = d.ci(None, |m| m.frac_class[0]);
            let (ho_km, pp_km) = d.per_km();
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
                d.label,
                d.seeds,
                d.flights.len(),
                s.rate,
                s.lo,
                s.hi,
                d.rate(Outcome::Collision).rate,
                d.rate(Outcome::OutOfBounds).rate,
                d.rate(Outcome::TimeLimit).rate,
                ov.mean,
                ov.half_width,
                rs.mean,
                rs.half_width,
                100.0 * ex.mean,
                100.0 * ex.half_width,
                ho_km,
                pp_km,
                d.all_ci(|m| m.mean_sinr_db).mean,
                100.0 * d.all_ci(|m| m.frac_sinr_below_m6db).mean,
                d.all_ci(|m| m.mean_site_regret_db).mean,
                100.0 * d.all_ci(|m| m.frac_site_regret_high).mean,
                100.0 * d.all_ci(|m| m.frac_class_regret).mean,
            )?;
        }
        Ok(())
    })?;
    // fig3.csv / fig4.csv: per method and bin, successful flights.
    write_atomic_with(&out.join("fig3_fig4_bins.csv"), |w| {
        writeln!(
            w,
            "method,bin_m,successes,distance_m,distance_ci,overhead,overhead_ci,mean_rsrp_dbm,rsrp_ci,frac_excellent,frac_mediocre,frac_poor"
        )?;
        for d in &data {
            for &b in &bins {
                let dist = d.ci(Some(b), |m| m.distance_m);
                let ov = d.ci(Some(b), |m| m.overhead);
                let rs = d.ci(Some(b), |m| m.mean_rsrp_dbm);
                let f = [0, 1, 2].map(|k| d.ci(Some(b), |m| m.frac_class[k]).mean);
                writeln!(
                    w,
                    "{},{b},{},{},{},{},{},{},{},{},{},{}",
                    d.label,
                    dist.n,
                    dist.mean,
                    dist.half_width,
                    ov.mean,
                    ov.half_width,
                    rs.mean,
                    rs.half_width,
                    f[0],
                    f[1],
                    f[2]
                )?;
            }
        }
        Ok(())
    })?;
    write_failures(&out.join("failures.csv"), files)?;
    // The figures show methods; the association replays (`LABEL+a3`, `LABEL+oracle`) are in the
    // tables only.
    let methods: Vec<MethodData> = data
        .iter()
        .filter(|d| !d.label.contains('+'))
        .cloned()
        .collect();
    draw_fig3(out, &methods, &bins)?;
    draw_fig4(out, &methods, &bins)?;
    draw_pareto(out, &methods)?;
    write_atomic(
        &out.join("report.md"),
        report_md(&data, dupac, base, regret_threshold_db(files)).as_bytes(),
    )?;
    Ok(())
}

/// `failures.csv`: one row per flight that did not reach its goal, to see where and how policies
/// fail: how far along the straight line they got, the altitude, the last move, and the angle
/// between the last move and the direction to the destination (a collision flown head-on into
/// the goal direction reads ≈ 0°; one while sliding along a wall ≈ 45–90°).
fn write_failures(path: &Path, files: &[RecordsFile]) -> Result<()> {
    write_atomic_with(path, |w| {
        writeln!(
            w,
            "method,seed,pair_id,bin_m,outcome,steps,straight_m,remaining_m,progress,x_m,y_m,z_m,last_move_x_m,last_move_y_m,last_move_z_m,angle_to_goal_deg"
        )?;
        // The association replays (`LABEL+a3`, `LABEL+oracle`) are the policy's own flights.
        let flights = files
            .iter()
            .filter(|r| !r.method.contains('+'))
            .flat_map(|r| &r.flights);
        for f in flights {
            if f.outcome == Outcome::Goal {
                continue;
            }
            let n = f.steps.len();
            let at = |i: usize| -> [f64; 3] {
                if i == 0 {
                    f.source_m
                } else {
                    f.steps[i - 1].position_m.map(f64::from)
                }
            };
            let end = at(n);
            let prev = at(n.saturating_sub(1));
            let mv = [end[0] - prev[0], end[1] - prev[1], end[2] - prev[2]];
            let to_goal = [
                f.destination_m[0] - prev[0],
                f.destination_m[1] - prev[1],
                f.destination_m[2] - prev[2],
            ];
            let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            let dot = mv[0] * to_goal[0] + mv[1] * to_goal[1] + mv[2] * to_goal[2];
            let angle = (dot / (norm(mv) * norm(to_goal)).max(1e-12))
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            writeln!(
                w,
                "{},{},{},{},{:?},{},{:.1},{:.1},{:.3},{:.1},{:.1},{:.1},{:.3},{:.3},{:.3},{:.1}",
                f.method,
                f.seed,
                f.pair_id,
                f.bin_m,
                f.outcome,
                n,
                f.straight_m,
                f.remaining_m,
                1.0 - f.remaining_m / f.straight_m.max(1e-9),
                end[0],
                end[1],
                end[2],
                mv[0],
                mv[1],
                mv[2],
                angle
            )?;
        }
        Ok(())
    })
}

/// The site-regret threshold of the records (the first file's; every file of one evaluation
/// has the same).
fn regret_threshold_db(files: &[RecordsFile]) -> f64 {
    files.first().map_or(3.0, |f| f.site_regret_threshold_db)
}

fn report_md(data: &[MethodData], dupac: &str, base: &str, regret_db: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# DUPAC evaluation report\n");
    let _ = writeln!(
        s,
        "Distance, overhead, RSRP and class fractions are over successful flights; rates over all flights; intervals are 95 % (Student t for means across seeds and pairs, Wilson for rates). SINR: serving RSRP against all other sites as full-load co-channel interferers plus thermal noise per resource element ({NOISE_PER_RE_DBM:.1} dBm).\n"
    );
    let _ = writeln!(
        s,
        "| method | seeds | flights | success | collision | timeout | overhead (%) | mean RSRP (dBm) | excellent (%) | handovers/km | ping-pongs/km | mean SINR (dB) | SINR < −6 dB (%) | site regret (dB) | regret > {regret_db} dB (%) | class regret (%) |"
    );
    let _ = writeln!(
        s,
        "|---|---:|---:|---|---:|---:|---|---|---|---:|---:|---:|---:|---:|---:|---:|"
    );
    for d in data {
        let (ho_km, pp_km) = d.per_km();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.1} % | {:.1} % | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {:.1} | {:.1} |",
            d.label,
            d.seeds,
            d.flights.len(),
            fmt_rate(d.rate(Outcome::Goal)),
            100.0 * d.rate(Outcome::Collision).rate,
            100.0 * d.rate(Outcome::TimeLimit).rate,
            fmt_ci(d.ci(None, |m| m.overhead), 100.0, 1),
            fmt_ci(d.ci(None, |m| m.mean_rsrp_dbm), 1.0, 1),
            fmt_ci(d.ci(None, |m| m.frac_class[0]), 100.0, 1),
            ho_km,
            pp_km,
            d.all_ci(|m| m.mean_sinr_db).mean,
            100.0 * d.all_ci(|m| m.frac_sinr_below_m6db).mean,
            d.all_ci(|m| m.mean_site_regret_db).mean,
            100.0 * d.all_ci(|m| m.frac_site_regret_high).mean,
            100.0 * d.all_ci(|m| m.frac_class_regret).mean,
        );
    }
    route_or_association(&mut s, data);
    let find = |l: &str| data.iter().find(|d| d.label == l);
    let _ = writeln!(s, "\n## Against the paper\n");
    match (find(dupac), find(base)) {
        (Some(a), Some(b)) => {
            let (oa, ob) = (a.ci(None, |m| m.overhead), b.ci(None, |m| m.overhead));
            let (ra, rb) = (
                a.ci(None, |m| m.mean_rsrp_dbm),
                b.ci(None, |m| m.mean_rsrp_dbm),
            );
            let (ea, eb) = (
                a.ci(None, |m| m.frac_class[0]),
                b.ci(None, |m| m.frac_class[0]),
            );
            let gain = (rb.mean - ra.mean) / rb.mean.abs() * -100.0;
            let _ = writeln!(s, "| quantity | paper | ours |\n|---|---:|---:|");
            let _ = writeln!(
                s,
                "| distance overhead, DUPAC | ≈ 11 % | {} % |",
                fmt_ci(oa, 100.0, 1)
            );
            let _ = writeln!(
                s,
                "| distance overhead, base method | ≈ 9 % | {} % |",
                fmt_ci(ob, 100.0, 1)
            );
            let _ = writeln!(
                s,
                "| mean RSRP, DUPAC vs base (relative, + = DUPAC better) | ≈ +7.5 % | {gain:+.1} % ({:.1} vs {:.1} dBm) |",
                ra.mean, rb.mean
            );
            let _ = writeln!(
                s,
                "| time in excellent RSRP, DUPAC − base | ≈ +9 points | {:+.1} points ({:.1} vs {:.1} %) |",
                100.0 * (ea.mean - eb.mean),
                100.0 * ea.mean,
                100.0 * eb.mean
            );
            let _ = writeln!(
                s,
                "| success rate (not reported by the paper) | – | {} vs {} |",
                fmt_rate(a.rate(Outcome::Goal)),
                fmt_rate(b.rate(Outcome::Goal))
            );
            let agree = |ok: bool| {
                if ok {
                    "agrees with"
                } else {
                    "is the opposite of"
                }
            };
            let _ = writeln!(
                s,
                "\nIn direction: DUPAC's mean RSRP against the base method's {} the paper (paper: DUPAC better); its time in excellent RSRP {} the paper (paper: DUPAC more); DUPAC's distance overhead against the base method's {} the paper (paper: DUPAC flies a little longer). DUPAC hands over {:.1} times per km ({:.1} of them ping-pongs), the base method {:.1}. Flights that missed the goal, DUPAC / base: {:.1} / {:.1} % collisions, {:.1} / {:.1} % timeouts, {:.1} / {:.1} % out of bounds (where each ended: `failures.csv`). Discussion: docs/results.md, docs/training.md.",
                agree(ra.mean > rb.mean),
                agree(ea.mean > eb.mean),
                agree(oa.mean > ob.mean),
                a.per_km().0,
                a.per_km().1,
                b.per_km().0,
                100.0 * a.rate(Outcome::Collision).rate,
                100.0 * b.rate(Outcome::Collision).rate,
                100.0 * a.rate(Outcome::TimeLimit).rate,
                100.0 * b.rate(Outcome::TimeLimit).rate,
                100.0 * a.rate(Outcome::OutOfBounds).rate,
                100.0 * b.rate(Outcome::OutOfBounds).rate,
            );
        }
        _ => {
            let _ = writeln!(
                s,
                "(no `{dupac}` and `{base}` policies among the methods: give them with --policy {dupac}=FILE --policy {base}=FILE)"
            );
        }
    }
    let _ = writeln!(
        s,
        "\nFigures: `fig3.png` (Fig. 3: flight distance, overhead and mean RSRP against the shortest distance), `fig4.png` (Fig. 4: time per RSRP class per bin), `pareto.png` (overhead against time in excellent RSRP, every method). Data: `summary.csv`, `fig3_fig4_bins.csv`; every step: `records/*.bin` (`dupac eval --report-only --out DIR` recomputes this report from them)."
    );
    s
}

/// "Route or association": each learned-site policy beside its own moves re-flown with A3 and
/// with the best-RSRP oracle choosing the site (the replays `LABEL+a3`, `LABEL+oracle`).
fn route_or_association(s: &mut String, data: &[MethodData]) {
    let policies: Vec<&MethodData> = data
        .iter()
        .filter(|d| {
            data.iter()
                .any(|r| r.label == format!("{}+oracle", d.label))
        })
        .collect();
    if policies.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Route or association\n\nEach learned-site policy's own moves, re-flown with the A3 rule and with the best-RSRP oracle choosing the site. The route is the same in the three rows, so the oracle row is the best this route allows, and the gap from the policy's row to it is the association's alone; the gap between policies' oracle rows is the routes'. Excellent time over successful flights, the rest over all flights.\n"
    );
    let _ = writeln!(
        s,
        "| policy | site by | excellent (%) | mean RSRP (dBm) | SINR < −6 dB (%) | handovers/km | ping-pongs/km | site regret (dB) |\n|---|---|---|---|---:|---:|---:|---:|"
    );
    for p in policies {
        for (by, label) in [
            ("policy", p.label.clone()),
            ("A3", format!("{}+a3", p.label)),
            ("oracle", format!("{}+oracle", p.label)),
        ] {
            let Some(d) = data.iter().find(|d| d.label == label) else {
                continue;
            };
            let (ho_km, pp_km) = d.per_km();
            let _ = writeln!(
                s,
                "| {} | {by} | {} | {} | {:.1} | {:.1} | {:.1} | {:.2} |",
                p.label,
                fmt_ci(d.ci(None, |m| m.frac_class[0]), 100.0, 1),
                fmt_ci(d.all_ci(|m| m.mean_rsrp_dbm), 1.0, 1),
                100.0 * d.all_ci(|m| m.frac_sinr_below_m6db).mean,
                ho_km,
                pp_km,
                d.all_ci(|m| m.mean_site_regret_db).mean,
            );
        }
    }
}

const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

fn draw_fig3(out: &Path, data: &[MethodData], bins: &[f64]) -> Result<()> {
    let path = out.join("fig3.png");
    crate::plot::write_png_atomic(&path, |tmp| {
        let root = BitMapBackend::new(tmp, (1800, 620)).into_drawing_area();
        root.fill(&WHITE)?;
        let panels = root.split_evenly((1, 3));
        type Pick = fn(&FlightMetrics) -> f64;
        let specs: [(&str, Pick, f64); 3] = [
            ("flight distance (m)", |m| m.distance_m, 1.0),
            (
                "distance overhead over the shortest path (%)",
                |m| m.overhead,
                100.0,
            ),
            ("mean serving RSRP (dBm)", |m| m.mean_rsrp_dbm, 1.0),
        ];
        let (x0, x1) = (
            bins.first().copied().unwrap_or(0.0) - 50.0,
            bins.last().copied().unwrap_or(1.0) + 50.0,
        );
        for (panel, (title, pick, scale)) in panels.iter().zip(specs) {
            let series: Vec<(String, Vec<(f64, MeanCi)>)> = data
                .iter()
                .map(|d| {
                    (
                        d.label.clone(),
                        bins.iter().map(|&b| (b, d.ci(Some(b), pick))).collect(),
                    )
                })
                .collect();
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for (_, pts) in &series {
                for (_, c) in pts.iter().filter(|(_, c)| c.n > 0) {
                    let h = if c.half_width.is_nan() {
                        0.0
                    } else {
                        c.half_width
                    };
                    lo = lo.min((c.mean - h) * scale);
                    hi = hi.max((c.mean + h) * scale);
                }
            }
            if !lo.is_finite() {
                (lo, hi) = (0.0, 1.0);
            }
            let pad = 0.05 * (hi - lo).max(1e-6);
            let mut chart = ChartBuilder::on(panel)
                .caption(title, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(x0..x1, (lo - pad)..(hi + pad))?;
            chart
                .configure_mesh()
                .x_desc("shortest flyable distance D (m)")
                .label_style(("sans-serif", 14))
                .draw()?;
            for (k, (label, pts)) in series.iter().enumerate() {
                let c = COLORS[k % COLORS.len()];
                let dx = (k as f64 - series.len() as f64 / 2.0) * 4.0;
                let good: Vec<(f64, MeanCi)> =
                    pts.iter().copied().filter(|(_, c)| c.n > 0).collect();
                chart
                    .draw_series(LineSeries::new(
                        good.iter().map(|(b, m)| (b + dx, m.mean * scale)),
                        c.stroke_width(2),
                    ))?
                    .label(label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(3))
                    });
                chart.draw_series(good.iter().filter(|(_, m)| m.half_width.is_finite()).map(
                    |(b, m)| {
                        vbar(
                            b + dx,
                            (m.mean - m.half_width) * scale,
                            (m.mean + m.half_width) * scale,
                            c.filled(),
                        )
                    },
                ))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 13))
                .position(SeriesLabelPosition::UpperLeft)
                .draw()?;
        }
        root.present()?;
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))
}

fn draw_fig4(out: &Path, data: &[MethodData], bins: &[f64]) -> Result<()> {
    let path = out.join("fig4.png");
    crate::plot::write_png_atomic(&path, |tmp| {
        let root = BitMapBackend::new(tmp, (1800, 700)).into_drawing_area();
        root.fill(&WHITE)?;
        let nm = data.len().max(1) as f64;
        let group = nm + 1.0;
        // One group's width of room on the right for the legend.
        let x_max = (bins.len() as f64 + 1.7) * group;
        let mut chart = ChartBuilder::on(&root)
            .caption("Fig. 4: fraction of flight time per RSRP class (successful flights); bars per method, groups per distance bin", ("sans-serif", 20))
            .margin(14)
            .x_label_area_size(70)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..x_max, 0.0..106.0)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .y_desc("flight time (%)")
            .x_desc("groups of bars: one per distance bin (labelled above), one bar per method")
            .x_labels(0)
            .label_style(("sans-serif", 14))
            .draw()?;
        let class_colors = [RGBColor(46, 160, 67), RGBColor(240, 180, 40), RGBColor(200, 40, 40)];
        for (bi, &b) in bins.iter().enumerate() {
            chart.draw_series(std::iter::once(Text::new(
                format!("D ≈ {b:.0} m"),
                (bi as f64 * group + 0.5, 104.5),
                ("sans-serif", 15),
            )))?;
            for (mi, d) in data.iter().enumerate() {
                let x = bi as f64 * group + mi as f64 + 0.5;
                let f = [0, 1, 2].map(|k| d.ci(Some(b), |m| m.frac_class[k]).mean);
                if f.iter().any(|v| v.is_nan()) {
                    continue;
                }
                let mut y = 0.0;
                for (k, v) in f.iter().enumerate() {
                    let top = y + 100.0 * v;
                    chart.draw_series(std::iter::once(Rectangle::new([(x, y), (x + 0.9, top)], class_colors[k].filled())))?;
                    y = top;
                }
                // Method marker under each bar: its colour.
                chart.draw_series(std::iter::once(Rectangle::new([(x, 0.0), (x + 0.9, 1.5)], COLORS[mi % COLORS.len()].filled())))?;
            }
        }
        for (k, name) in ["excellent (≥ −80 dBm)", "mediocre", "poor (< −100 dBm)"].iter().enumerate() {
            let c = class_colors[k];
            chart
                .draw_series(std::iter::once(Rectangle::new([(0.0, 0.0), (0.0, 0.0)], c.filled())))?
                .label(*name)
                .legend(move |(x, y)| Rectangle::new([(x, y - 6), (x + 14, y + 6)], c.filled()));
        }
        for (mi, d) in data.iter().enumerate() {
            let c = COLORS[mi % COLORS.len()];
            chart
                .draw_series(std::iter::once(Rectangle::new([(0.0, 0.0), (0.0, 0.0)], c.filled())))?
                .label(format!("bar {}: {}", mi + 1, d.label))
                .legend(move |(x, y)| Rectangle::new([(x, y - 3), (x + 14, y + 3)], c.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 13))
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;
        root.present()?;
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))
}

fn draw_pareto(out: &Path, data: &[MethodData]) -> Result<()> {
    let path = out.join("pareto.png");
    let pts: Vec<(String, MeanCi, MeanCi)> = data
        .iter()
        .map(|d| {
            (
                d.label.clone(),
                d.ci(None, |m| m.overhead),
                d.ci(None, |m| m.frac_class[0]),
            )
        })
        .filter(|(_, o, e)| o.n > 0 && e.n > 0)
        .collect();
    write_atomic_with(&out.join("pareto.csv"), |w| {
        writeln!(
            w,
            "method,overhead_pct,overhead_ci_pct,pct_excellent,pct_excellent_ci"
        )?;
        for (l, o, e) in &pts {
            writeln!(
                w,
                "{l},{},{},{},{}",
                100.0 * o.mean,
                100.0 * o.half_width,
                100.0 * e.mean,
                100.0 * e.half_width
            )?;
        }
        Ok(())
    })?;
    crate::plot::write_png_atomic(&path, |tmp| {
        let root = BitMapBackend::new(tmp, (1100, 800)).into_drawing_area();
        root.fill(&WHITE)?;
        let hw = |c: &MeanCi| {
            if c.half_width.is_finite() {
                c.half_width
            } else {
                0.0
            }
        };
        let x_hi = pts
            .iter()
            .map(|(_, o, _)| 100.0 * (o.mean + hw(o)))
            .fold(1.0, f64::max)
            * 1.1;
        let x_lo = pts
            .iter()
            .map(|(_, o, _)| 100.0 * (o.mean - hw(o)))
            .fold(0.0, f64::min)
            - 0.04 * x_hi;
        let y_lo = pts
            .iter()
            .map(|(_, _, e)| 100.0 * (e.mean - hw(e)))
            .fold(100.0, f64::min)
            .max(0.0)
            - 5.0;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                "Distance overhead against time in excellent RSRP (successful flights, 95 % CI)",
                ("sans-serif", 20),
            )
            .margin(16)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(x_lo..x_hi, y_lo.max(0.0)..100.0)?;
        chart
            .configure_mesh()
            .x_desc("distance overhead over the shortest path (%)")
            .y_desc("flight time in excellent RSRP (%)")
            .label_style(("sans-serif", 14))
            .draw()?;
        for (k, (label, o, e)) in pts.iter().enumerate() {
            let c = COLORS[k % COLORS.len()];
            let (x, y) = (100.0 * o.mean, 100.0 * e.mean);
            chart.draw_series(std::iter::once(hbar(
                y,
                x - 100.0 * hw(o),
                x + 100.0 * hw(o),
                c.filled(),
            )))?;
            chart.draw_series(std::iter::once(vbar(
                x,
                y - 100.0 * hw(e),
                y + 100.0 * hw(e),
                c.filled(),
            )))?;
            chart
                .draw_series(std::iter::once(Circle::new((x, y), 7, c.filled())))?
                .label(label.as_str())
                .legend(move |(x, y)| Circle::new((x + 7, y), 6, c.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;
        root.present()?;
        Ok(())
    })
    .with_context(|| format!("writing {}", path.display()))
}

/// A vertical error bar at `x` from `lo` to `hi` (data units).
fn vbar(x: f64, lo: f64, hi: f64, style: ShapeStyle) -> PathElement<(f64, f64)> {
    PathElement::new(vec![(x, lo), (x, hi)], style.stroke_width(2))
}

/// A horizontal error bar at `y` from `lo` to `hi` (data units).
fn hbar(y: f64, lo: f64, hi: f64, style: ShapeStyle) -> PathElement<(f64, f64)> {
    PathElement::new(vec![(lo, y), (hi, y)], style.stroke_width(2))
}

/// Example flights over the city (top view, altitude profile, RSRP along the way, coloured by
/// class): for the shortest, a middle and the longest bin, the first pair of that bin, every
/// method's seed-0 flight, the coverage-aware planner at λ = 1 only (`example_pair<ID>.png`).
fn draw_examples(
    out: &Path,
    world: &dupac_radio::world::RadioWorld,
    files: &[RecordsFile],
    thresholds: &RsrpThresholds,
) -> Result<()> {
    // Seed 0 of every method; of the coverage-aware sweep only λ = 1 (readability).
    let seed0: Vec<&RecordsFile> = files
        .iter()
        .filter(|f| {
            f.seed == 0 && (!f.method.starts_with("coverage_l") || f.method == "coverage_l1")
        })
        .collect();
    let Some(first) = seed0.first() else {
        return Ok(());
    };
    let mut bins: Vec<f64> = first.flights.iter().map(|f| f.bin_m).collect();
    bins.sort_by(f64::total_cmp);
    bins.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    let mut picks: Vec<f64> = [0, bins.len() / 2, bins.len().saturating_sub(1)]
        .iter()
        .filter_map(|&i| bins.get(i).copied())
        .collect();
    picks.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    for b in picks {
        let Some(pair) = first.flights.iter().find(|f| (f.bin_m - b).abs() < 1e-6) else {
            continue;
        };
        let mut traces = Vec::new();
        for f in &seed0 {
            let Some(r) = f.flights.iter().find(|r| r.pair_id == pair.pair_id) else {
                continue;
            };
            if r.steps.is_empty() {
                continue;
            }
            let mut t = FlightTrace {
                label: format!("{} ({:?})", r.method, r.outcome).to_lowercase(),
                points_m: vec![r.source_m],
                serving_rsrp_dbm: vec![],
                class: vec![],
                reached: r.outcome == Outcome::Goal,
            };
            // At the source: the first step's values (one step away at most).
            t.serving_rsrp_dbm
                .push(f64::from(r.steps[0].serving_rsrp_dbm));
            t.class.push(r.steps[0].class);
            for s in &r.steps {
                t.points_m.push(s.position_m.map(f64::from));
                t.serving_rsrp_dbm.push(f64::from(s.serving_rsrp_dbm));
                t.class.push(s.class);
            }
            if t.serving_rsrp_dbm.iter().all(|v| v.is_finite()) {
                traces.push(t);
            }
        }
        if traces.is_empty() {
            continue;
        }
        let title = format!(
            "held-out pair {} (bin {:.0} m): shortest flyable {:.0} m, straight {:.0} m; colour = RSRP class",
            pair.pair_id, pair.bin_m, pair.shortest_m, pair.straight_m
        );
        render_plan_png(
            &world.city.buildings,
            &world.sites,
            world.city.area_m,
            &traces,
            thresholds,
            &title,
            &out.join(format!("example_pair{}.png", pair.pair_id)),
        )?;
    }
    Ok(())
}
