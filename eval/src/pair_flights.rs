//! One pair's flights as `dupac plan` and `dupac fly` report them: the summary table of its
//! flights ([`summary_md`], from each flight's [`EpisodeSummary`]: the one per-flight summary
//! of an environment's episode), the policy version of each step of a flight with live weights
//! (`versions.csv`, [`versions_md`]), the best RSRP at a point and a file-name-safe label. Each
//! flight's steps are written in the records' per-step layout
//! ([`crate::records::write_steps_csv`]).

use crate::error::EvalError;
use dupac_actor::record::StepInfo;
use dupac_common::geometry::Point;
use dupac_common::msg::EpisodeSummary;
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use std::fmt::Write as _;
use std::path::Path;

/// One row of [`summary_md`]: a flight's label, the length of the path it was planned along (m;
/// `None` for a policy's flight) and its episode's summary.
pub type SummaryRow<'a> = (&'a str, Option<f64>, &'a EpisodeSummary);

/// The Markdown table of `rows` under `title`, `note` below it (what `dupac plan` and `dupac fly`
/// print and write as `summary.md`): per flight the planned length, the outcome, the distance
/// flown, the overhead against the pair's shortest flyable path, the mean serving RSRP, the
/// share of steps in each RSRP class, the handovers and the return.
pub fn summary_md(title: &str, rows: &[SummaryRow], note: &str) -> String {
    let mut md = String::new();
    let _ = writeln!(md, "{title}\n");
    let _ = writeln!(
        md,
        "| flight | planned (m) | outcome | flown (m) | overhead (%) ¹ | mean RSRP (dBm) | excellent (%) | mediocre (%) | poor (%) | handovers | return |"
    );
    let _ = writeln!(md, "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (label, planned_m, s) in rows {
        let planned = planned_m.map_or_else(|| "—".to_string(), |m| format!("{m:.1}"));
        let _ = writeln!(
            md,
            "| {label} | {planned} | {:?} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {} | {:.1} |",
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
    let _ = writeln!(
        md,
        "\n¹ (flown + distance left to the destination when the episode ends) / shortest flyable \
         path − 1. {note}"
    );
    md
}

/// The best RSRP over all sites at `p` (dBm).
pub fn best_rsrp_at(rsrp: &dyn RsrpSource, world: &RadioWorld, p: Point) -> f64 {
    let mut all = vec![0.0; world.num_sites()];
    rsrp.rsrp_all_dbm(p, &mut all);
    all.iter().copied().fold(f64::NEG_INFINITY, f64::max)
}

/// A file-name-safe form of a label (`coverage-aware λ=1` → `coverage_aware_lambda_1`).
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

/// Writes `versions.csv`: the policy version that chose each step's action (`step,
/// policy_version`, one row per step of `steps`; `versions[i]` is step `i`'s), atomically.
pub fn write_versions_csv(
    path: &Path,
    steps: &[StepInfo],
    versions: &[u64],
) -> Result<(), EvalError> {
    let mut csv = String::from("step,policy_version\n");
    for (s, v) in steps.iter().zip(versions) {
        let _ = writeln!(csv, "{},{v}", s.step);
    }
    Ok(dupac_common::fsio::write_plain(path, csv.as_bytes())?)
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

    #[test]
    fn slugs_are_file_names() {
        assert_eq!(slug("coverage-aware λ=1"), "coverage_aware_lambda_1");
        assert_eq!(slug("shortest"), "shortest");
    }
}
