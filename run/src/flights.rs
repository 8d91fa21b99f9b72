//! One scripted flight's record, as `dupac plan` and `dupac fly` report it: its summary
//! against the shortest path ([`FlightSummary`], the Markdown table), the per-step CSV
//! (`steps.csv`, the columns evaluation re-plots from), the policy version of each step of a
//! flight with live weights (`versions.csv`) and the best RSRP at a point.

use crate::error::RunError;
use crate::scenario::SharedRsrp;
use dupac_actor::env::Env;
use dupac_actor::metrics::EpisodeAccumulator;
use dupac_actor::pairs::Pair;
use dupac_actor::pilot::{Flight, fly_waypoints};
use dupac_actor::planner::Planner;
use dupac_actor::record::StepInfo;
use dupac_common::config::{Association, Config};
use dupac_common::fsio::write_atomic_with;
use dupac_common::geometry::Point;
use dupac_common::msg::{EpisodeSummary, Outcome};
use dupac_radio::channel::FieldSplit;
use dupac_radio::class::RsrpClass;
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use std::fmt::Write as _;
use std::sync::Arc;

/// Statistics of one flight.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FlightSummary {
    pub label: String,
    pub planned_m: f64,
    pub flown_m: f64,
    pub overhead_pct: f64,
    pub mean_rsrp_dbm: f64,
    pub excellent_pct: f64,
    pub mediocre_pct: f64,
    pub poor_pct: f64,
    pub handovers: usize,
    pub outcome: Outcome,
    pub steps: usize,
    pub episodic_return: f64,
}

/// The summary of `f`, flown along a plan of `planned_m` (the pair's shortest: `shortest_m`).
pub fn summarise(label: &str, planned_m: f64, shortest_m: f64, f: &Flight) -> FlightSummary {
    let n = f.steps.len().max(1) as f64;
    let remaining = f.steps.last().map(|s| s.distance_to_goal_m).unwrap_or(0.0);
    let count = |c: RsrpClass| f.steps.iter().filter(|s| s.class == c).count() as f64;
    FlightSummary {
        label: label.to_string(),
        planned_m,
        flown_m: f.distance_m(),
        // Flown distance plus what is left to the destination (the episode ends within
        // `env.goal_radius_m`), against the shortest flyable path.
        overhead_pct: 100.0 * ((f.distance_m() + remaining) / shortest_m - 1.0),
        mean_rsrp_dbm: f.steps.iter().map(|s| s.serving_rsrp_dbm).sum::<f64>() / n,
        excellent_pct: 100.0 * count(RsrpClass::Excellent) / n,
        mediocre_pct: 100.0 * count(RsrpClass::Mediocre) / n,
        poor_pct: 100.0 * count(RsrpClass::Poor) / n,
        handovers: f.steps.iter().filter(|s| s.handover).count(),
        outcome: f.outcome,
        steps: f.steps.len(),
        episodic_return: f.episodic_return,
    }
}

/// The Markdown table of `rows` under `title` (the summary `dupac plan` prints and writes).
pub fn summary_md(title: &str, rows: &[FlightSummary]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "{title}\n");
    let _ = writeln!(
        md,
        "| path | planned (m) | flown (m) | overhead vs shortest (%) ¹ | mean RSRP (dBm) | excellent (%) | mediocre (%) | poor (%) | handovers | outcome | return |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|");
    for r in rows {
        let _ = writeln!(
            md,
            "| {} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:?} | {:.1} |",
            r.label,
            r.planned_m,
            r.flown_m,
            r.overhead_pct,
            r.mean_rsrp_dbm,
            r.excellent_pct,
            r.mediocre_pct,
            r.poor_pct,
            r.handovers,
            r.outcome,
            r.episodic_return
        );
    }
    let _ = writeln!(
        md,
        "\n¹ (flown + distance left to the destination when the episode ends) / shortest − 1; \
         every path is flown by the scripted pilot through the environment with A3 association."
    );
    md
}

/// The best RSRP over all sites at `p` (dBm).
pub fn env_rsrp_at(rsrp: &dyn RsrpSource, world: &RadioWorld, p: Point) -> f64 {
    let mut all = vec![0.0; world.num_sites()];
    rsrp.rsrp_all_dbm(p, &mut all);
    all.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

/// A file-name-safe form of a label.
pub fn slug(s: &str) -> String {
    s.replace('λ', "lambda")
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Writes one row per step record (the columns evaluation re-plots from), atomically.
pub fn write_steps_csv(path: &std::path::Path, steps: &[StepInfo]) -> Result<(), RunError> {
    write_atomic_with(path, |w| {
        let mut c = csv::Writer::from_writer(w);
        c.write_record([
            "step",
            "x_m",
            "y_m",
            "z_m",
            "serving",
            "serving_rsrp_dbm",
            "best_site",
            "best_rsrp_dbm",
            "class",
            "los",
            "handover",
            "ping_pong",
            "distance_flown_m",
            "reward",
        ])?;
        for s in steps {
            c.write_record([
                s.step.to_string(),
                format!("{:.3}", s.position_m[0]),
                format!("{:.3}", s.position_m[1]),
                format!("{:.3}", s.position_m[2]),
                s.serving.0.to_string(),
                format!("{:.3}", s.serving_rsrp_dbm),
                s.best_site.0.to_string(),
                format!("{:.3}", s.best_rsrp_dbm),
                s.class.name().to_string(),
                u8::from(s.los).to_string(),
                u8::from(s.handover).to_string(),
                u8::from(s.ping_pong).to_string(),
                format!("{:.3}", s.distance_flown_m),
                format!("{:.5}", s.reward),
            ])?;
        }
        c.flush()
    })?;
    Ok(())
}

/// Writes `versions.csv`: the policy version that chose each step's action (`step,
/// policy_version`, one row per step of `steps`; `versions[i]` is step `i`'s), atomically.
pub fn write_versions_csv(
    path: &std::path::Path,
    steps: &[StepInfo],
    versions: &[u64],
) -> Result<(), RunError> {
    let mut csv = String::from("step,policy_version\n");
    for (s, v) in steps.iter().zip(versions) {
        let _ = writeln!(csv, "{},{v}", s.step);
    }
    write_atomic_with(path, |w| w.write_all(csv.as_bytes()))?;
    Ok(())
}

/// The line a flight with live weights adds to its summary: the distinct policy versions that
/// acted (ascending) and how many times the version changed between steps.
pub fn versions_md(versions: &[u64]) -> String {
    let distinct: std::collections::BTreeSet<u64> = versions.iter().copied().collect();
    format!(
        "\npolicy versions used: {} ({} swaps mid-flight; per step in versions.csv)\n",
        distinct
            .iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        versions.windows(2).filter(|w| w[0] != w[1]).count()
    )
}

/// The Markdown table of episode summaries `rows` (label, summary) under `title` (what `dupac
/// fly` prints and writes).
pub fn episodes_md(title: &str, rows: &[(&str, &EpisodeSummary)]) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "{title}\n");
    let _ = writeln!(
        md,
        "| flight | outcome | flown (m) | overhead (%) | mean RSRP (dBm) | excellent (%) | mediocre (%) | poor (%) | handovers | return |"
    );
    let _ = writeln!(md, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (label, s) in rows {
        let _ = writeln!(
            md,
            "| {label} | {:?} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.1} |",
            s.outcome,
            s.distance_flown_m,
            100.0 * s.overhead(),
            s.mean_rsrp_dbm,
            100.0 * s.frac_excellent,
            100.0 * s.frac_mediocre,
            100.0 * s.frac_poor,
            s.handovers,
            s.episodic_return
        );
    }
    md
}

/// Pair `p`'s shortest flyable path flown by the scripted pilot with A3 choosing the site (the
/// reference `dupac fly` draws beside a policy's flight), in `field`'s realisations, with its
/// episode summary.
pub fn shortest_with_a3(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    planner: &Planner,
    p: &Pair,
    field: FieldSplit,
) -> Result<(Flight, EpisodeSummary), RunError> {
    let shortest = planner.shortest(p.source_m, p.destination_m)?;
    fly_path_with_a3(cfg, world, rsrp, &shortest.waypoints_m, p, field)
}

/// `waypoints_m` (m) flown from pair `p`'s source by the scripted pilot with A3 choosing the
/// site (as `dupac eval` flies the planners' paths), in `field`'s realisations, with its
/// episode summary.
pub fn fly_path_with_a3(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &SharedRsrp,
    waypoints_m: &[Point],
    p: &Pair,
    field: FieldSplit,
) -> Result<(Flight, EpisodeSummary), RunError> {
    let mut a3_cfg = cfg.clone();
    a3_cfg.env.association = Association::A3;
    let mut env = Env::new(&a3_cfg, world.clone(), rsrp.clone())?;
    let episode = p.episode(false, field);
    let flight = fly_waypoints(&mut env, p.id, episode, waypoints_m, |e| e.serving())?;
    let mut acc = EpisodeAccumulator::new(&a3_cfg.env);
    flight.steps.iter().for_each(|s| acc.push(s));
    let summary = acc.finish(p.id, p.shortest_m, flight.outcome);
    Ok((flight, summary))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn versions_md_lists_the_distinct_versions_and_counts_the_swaps() {
        assert_eq!(
            versions_md(&[3, 3, 5, 5, 3]),
            "\npolicy versions used: 3, 5 (2 swaps mid-flight; per step in versions.csv)\n"
        );
    }
}
