//! Tuning the base method's A3 parameters on the validation split (`dupac tune-a3`,
//! docs/results.md "A fair A3: `dupac tune-a3`"): the guide path every guided policy gets (the
//! coverage-aware planner's path, λ = `lambda`, with the guide's clearance) of every validation
//! pair, flown by the scripted pilot once and re-associated by A3 at every setting of a grid of
//! a3-Offset × Hysteresis × timeToTrigger × A3's own filter coefficient (TS 36.331 values,
//! docs/spec/radio.md §4; [`crate::trace`]: what the flight through the environment with that
//! setting gives); per setting the excellent-RSRP time, handovers and ping-pongs per km and the
//! time below −6 dB SINR ([`crate::metrics::flight_metrics`]); the chosen setting
//! ([`choose`]): the most excellent time among those with no more ping-pongs per km than the
//! reference (`radio.a3`, 3 dB / 1 dB / 160 ms by default), ties to fewer handovers per km.
//!
//! Deterministic: every flight is a function of the pair and the setting, the pairs are flown in
//! parallel and gathered in order, so the same inputs give a byte-identical `a3_grid.csv`.

use crate::error::{Context, EvalError};
use crate::metrics::FlightMetrics;
use crate::trace::{Flown, ReplayTrace};
use dupac_actor::pairs::Split;
use dupac_common::config::Config;
use dupac_common::msg::Outcome;
use dupac_radio::channel::FieldSplit;
use dupac_scenario::pairs::{guide_pairs_cached, split_unguided};
use dupac_scenario::planners::unguided;
use dupac_scenario::progress::progress_bar;
use dupac_scenario::world::world_and_cache;
use rayon::prelude::*;
use serde::Deserialize;
use std::fmt::Write as _;
use std::path::Path;

pub use crate::a3_setting::{A3Grid, A3Setting, TTT_VALUES_MS};

/// What [`tune_a3`] measured: one result per setting, and the validation pairs' file (the
/// configured `pairs.eval_file`, its `{city}` resolved for this world).
#[derive(Debug, Clone)]
pub struct Tuning {
    pub results: Vec<SettingResult>,
    pub pairs_file: std::path::PathBuf,
}

/// One setting's measures over the validation flights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SettingResult {
    pub setting: A3Setting,
    /// Whether it is the reference (`radio.a3` of the configuration).
    pub reference: bool,
    pub flights: usize,
    /// Flights that reached the goal (%).
    pub success_pct: f64,
    /// Time in excellent RSRP (%, the mean over flights of each flight's fraction).
    pub excellent_pct: f64,
    /// Handovers per km flown (all flights' handovers over all their kilometres).
    pub handovers_per_km: f64,
    /// Ping-pongs per km flown (the same way).
    pub ping_pongs_per_km: f64,
    /// Time with SINR < −6 dB (%, the mean over flights).
    pub sinr_below_m6db_pct: f64,
}

impl SettingResult {
    fn of(setting: A3Setting, reference: bool, m: &[FlightMetrics]) -> SettingResult {
        let n = m.len().max(1) as f64;
        let km: f64 = m
            .iter()
            .map(|f| f.distance_m / 1000.0)
            .sum::<f64>()
            .max(1e-9);
        let sum = |f: &dyn Fn(&FlightMetrics) -> f64| m.iter().map(f).sum::<f64>();
        SettingResult {
            setting,
            reference,
            flights: m.len(),
            success_pct: 100.0 * sum(&|f| f64::from(u8::from(f.outcome == Outcome::Goal))) / n,
            excellent_pct: 100.0 * sum(&|f| f.frac_class[0]) / n,
            handovers_per_km: sum(&|f| f64::from(f.handovers)) / km,
            ping_pongs_per_km: sum(&|f| f64::from(f.ping_pongs)) / km,
            sinr_below_m6db_pct: 100.0 * sum(&|f| f.frac_sinr_below_m6db) / n,
        }
    }
}

/// Flies the validation pairs' guide paths (λ = `lambda`, the guide's clearance
/// `env.observation.path_guide_clearance_m`) with every setting of `grid` and with the reference
/// (`radio.a3`, added when the grid lacks it); one result per setting, in grid order, the
/// reference last when it was added.
pub fn tune_a3(cfg: &Config, grid: &A3Grid, lambda: f64, quiet: bool) -> Result<Tuning, EvalError> {
    if !(lambda.is_finite() && lambda > 0.0) {
        return Err(EvalError::Refused(format!(
            "--lambda {lambda}: must be a finite number > 0 (the coverage-aware guide path)"
        )));
    }
    let reference = A3Setting::of(&cfg.radio.a3);
    let mut settings = grid.settings()?;
    if !settings.contains(&reference) {
        settings.push(reference);
    }
    let (world, rsrp) = world_and_cache(cfg, quiet)?;
    // The pairs (drawn with the pairs' planner, as every command draws them) and their guide
    // paths, as a guided policy of λ = `lambda` gets them (from the guide cache when there).
    let flight_cfg = unguided(cfg);
    let planner =
        dupac_actor::planner::Planner::new(&world.city, &flight_cfg.env, &flight_cfg.planner);
    let mut pairs = split_unguided(&flight_cfg, &planner, Split::Validation, quiet)?;
    let pairs_file = Split::Validation.file(&cfg.pairs, &world.city);
    drop(planner);
    let mut guide_cfg = cfg.clone();
    guide_cfg.env.observation.path_guide = true;
    guide_cfg.env.observation.path_guide_lambda = lambda;
    guide_pairs_cached(&guide_cfg, &world, &rsrp, &mut pairs, quiet)?;
    let rules = crate::metrics::MetricRules::from_config(cfg);
    let pb = progress_bar(pairs.len() as u64, "A3 settings × pairs", quiet);
    // metrics[pair][setting]: each pair's guide path flown once, re-associated by every setting.
    let metrics: Vec<Vec<FlightMetrics>> = pairs
        .par_iter()
        .map(|p| {
            let path = p
                .path
                .as_ref()
                .ok_or_else(|| EvalError::Refused(format!("pair {}: no guide path", p.id)))?;
            let episode = p.episode(false, FieldSplit::Eval);
            let flown = Flown::Waypoints(path.points_m());
            let trace = ReplayTrace::fly(
                &flight_cfg,
                &world,
                &rsrp,
                FieldSplit::Eval,
                p,
                episode,
                flown,
            )?;
            pb.inc(1);
            Ok(trace.a3_metrics(&settings, &rules))
        })
        .collect::<Result<_, EvalError>>()?;
    pb.finish_and_clear();
    let results = settings
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let m: Vec<FlightMetrics> = metrics.iter().map(|row| row[k]).collect();
            SettingResult::of(*s, *s == reference, &m)
        })
        .collect();
    Ok(Tuning {
        results,
        pairs_file,
    })
}

/// The chosen setting: the most excellent time among the settings with no more ping-pongs per
/// km than the reference's; ties (within 1e−9) to fewer handovers per km, then to the first in
/// grid order. The reference itself qualifies, so the choice is never worse than it on either
/// measure of the rule.
pub fn choose(results: &[SettingResult]) -> Result<&SettingResult, EvalError> {
    let reference = results
        .iter()
        .find(|r| r.reference)
        .ok_or_else(|| EvalError::Refused("no reference setting among the results".into()))?;
    let mut best = reference;
    for r in results {
        if r.ping_pongs_per_km > reference.ping_pongs_per_km + 1e-9 {
            continue;
        }
        let better = r.excellent_pct > best.excellent_pct + 1e-9
            || ((r.excellent_pct - best.excellent_pct).abs() <= 1e-9
                && r.handovers_per_km < best.handovers_per_km - 1e-9);
        if better {
            best = r;
        }
    }
    Ok(best)
}

/// `a3_grid.csv`: one row per setting, in grid order; `chosen` marks [`choose`]'s. `margin_db`
/// is offset + hysteresis (what A3's entering condition depends on); `l3_filter_k` is empty
/// where A3 compares what the UAV holds.
pub fn grid_csv(results: &[SettingResult], chosen: &SettingResult) -> String {
    let mut s = String::from(
        "offset_db,hysteresis_db,margin_db,time_to_trigger_ms,l3_filter_k,flights,success_pct,excellent_pct,handovers_per_km,ping_pongs_per_km,sinr_below_m6db_pct,reference,chosen\n",
    );
    for r in results {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{:.6},{:.6},{:.6},{:.6},{:.6},{},{}",
            r.setting.offset_db,
            r.setting.hysteresis_db,
            r.setting.margin_db(),
            r.setting.time_to_trigger_ms,
            r.setting
                .l3_filter_k
                .map_or(String::new(), |k| k.to_string()),
            r.flights,
            r.success_pct,
            r.excellent_pct,
            r.handovers_per_km,
            r.ping_pongs_per_km,
            r.sinr_below_m6db_pct,
            u8::from(r.reference),
            u8::from(r.setting == chosen.setting),
        );
    }
    s
}

/// `tuned_a3.toml`: `[radio.a3]` with the chosen setting's keys (`l3_filter_k` when it has A3's
/// own filter), a configuration file of its own (`--config tuned_a3.toml`), with a comment that
/// says where it came from (the pairs file, the guide path's λ, the chosen and the reference
/// setting's measures) and the same setting as `--set` options.
pub fn tuned_toml(
    chosen: &SettingResult,
    reference: &SettingResult,
    pairs_file: &Path,
    lambda: f64,
) -> String {
    let c = chosen.setting;
    let filter_key = c
        .l3_filter_k
        .map_or(String::new(), |k| format!("l3_filter_k = {k}\n"));
    format!(
        "# A3 tuned by `dupac tune-a3` on the validation split ({}), {} flights of the\n\
         # λ = {lambda} guide path: excellent {:.2} %, {:.3} handovers/km, {:.3} ping-pongs/km\n\
         # (reference {}: {:.2} %, {:.3}, {:.3}).\n\
         # Use: `dupac train --association a3 --config THIS_FILE`, or with a configuration of your\n\
         # own: {}\n\
         [radio.a3]\n\
         offset_db = {:?}\n\
         hysteresis_db = {:?}\n\
         time_to_trigger_ms = {:?}\n\
         {filter_key}",
        pairs_file.display(),
        chosen.flights,
        chosen.excellent_pct,
        chosen.handovers_per_km,
        chosen.ping_pongs_per_km,
        reference.setting.label(),
        reference.excellent_pct,
        reference.handovers_per_km,
        reference.ping_pongs_per_km,
        set_options(&c),
        c.offset_db,
        c.hysteresis_db,
        c.time_to_trigger_ms,
    )
}

/// `setting` as the `--set` options of `radio.a3` (`l3_filter_k` only with A3's own filter).
pub fn set_options(setting: &A3Setting) -> String {
    let mut s = format!(
        "--set radio.a3.offset_db={} --set radio.a3.hysteresis_db={} --set radio.a3.time_to_trigger_ms={}",
        setting.offset_db, setting.hysteresis_db, setting.time_to_trigger_ms
    );
    if let Some(k) = setting.l3_filter_k {
        s.push_str(&format!(" --set radio.a3.l3_filter_k={k}"));
    }
    s
}

/// Reads a `tuned_a3.toml` (`dupac eval --a3-tuned FILE`): `[radio.a3]` with exactly
/// `offset_db`, `hysteresis_db`, `time_to_trigger_ms` and optionally `l3_filter_k`, TS 36.331
/// values; every error names the file.
pub fn read_tuned(path: &Path) -> Result<A3Setting, EvalError> {
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct File {
        radio: Radio,
    }
    #[derive(Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Radio {
        a3: A3Setting,
    }
    let bad = |m: String| EvalError::Refused(format!("--a3-tuned {}: {m}", path.display()));
    let meta = std::fs::metadata(path).context_with(|| format!("--a3-tuned {}", path.display()))?;
    if meta.len() > 64 * 1024 {
        return Err(bad("over 64 KiB: not a tuned_a3.toml".into()));
    }
    let text =
        std::fs::read_to_string(path).context_with(|| format!("--a3-tuned {}", path.display()))?;
    let f: File = toml::from_str(&text).map_err(|e| {
        bad(format!(
            "expected [radio.a3] with offset_db, hysteresis_db, time_to_trigger_ms and optionally l3_filter_k only: {e}"
        ))
    })?;
    f.radio.a3.check_legal().map_err(bad)?;
    Ok(f.radio.a3)
}

#[cfg(test)]
mod tests;
