//! The report's seed-aware tables, from the records alone: `per_seed.csv` (each method's
//! statistics per training seed), the bootstrap intervals of each method's headline statistics
//! (columns of `summary.csv`), `paired.csv` (paired differences between the compared methods)
//! and their sections of `report.md`. The statistics are [`crate::stats`]'.

use crate::error::EvalError;
use crate::method_data::{MethodData, gather, is_planner};
use crate::records::RecordsFile;
use crate::stats::{
    BootCi, Bootstrap, Comparison, HEADLINES, Headline, grids, method_intervals, paired,
};
use dupac_common::fsio::write_atomic_with;
use dupac_common::msg::Outcome;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

/// Everything seed-aware the report shows.
pub struct SeedStats {
    pub boot: Bootstrap,
    /// Each method's headline statistics with their bootstrap intervals, by label.
    pub intervals: BTreeMap<String, [BootCi; HEADLINES.len()]>,
    /// Each records file's statistics, `(seed, data)`, in the summary's method order then by
    /// seed.
    pub per_seed: Vec<(u32, MethodData)>,
    /// The compared methods' paired differences, in [`comparisons`]' order.
    pub comparisons: Vec<Comparison>,
}

/// The pairs of methods the report compares, among `labels`: `dupac` against `base`, then
/// `dupac` against each planner (in `labels`' order); none without `dupac`.
pub fn comparisons(labels: &[&str], dupac: &str, base: &str) -> Vec<(String, String)> {
    if !labels.contains(&dupac) {
        return Vec::new();
    }
    let base = labels.contains(&base).then_some(base);
    base.into_iter()
        .chain(labels.iter().copied().filter(|l| is_planner(l)))
        .map(|b| (dupac.to_string(), b.to_string()))
        .collect()
}

impl SeedStats {
    /// The seed-aware statistics of `files`, comparing `dupac` with `base` and the planners.
    pub fn compute(files: &[RecordsFile], dupac: &str, base: &str, boot: Bootstrap) -> SeedStats {
        let grids = grids(files);
        let intervals = grids
            .par_iter()
            .map(|g| (g.label.clone(), method_intervals(g, &boot)))
            .collect();
        let mut sorted: Vec<&RecordsFile> = files.iter().collect();
        sorted.sort_by_key(|f| (is_planner(&f.method), f.method.clone(), f.seed));
        let per_seed = sorted
            .into_iter()
            .filter_map(|f| Some((f.seed, gather(std::iter::once(f)).pop()?)))
            .collect();
        let mut labels: Vec<&str> = grids.iter().map(|g| g.label.as_str()).collect();
        labels.sort_by_key(|l| (is_planner(l), *l));
        let grid = |l: &str| grids.iter().find(|g| g.label == l);
        let comparisons = comparisons(&labels, dupac, base)
            .par_iter()
            .filter_map(|(a, b)| paired(grid(a)?, grid(b)?, &boot))
            .collect();
        SeedStats {
            boot,
            intervals,
            per_seed,
            comparisons,
        }
    }

    /// The bootstrap columns' header of `summary.csv`, with its leading comma.
    pub fn summary_header() -> String {
        HEADLINES
            .iter()
            .map(|h| format!(",{0}_boot_lo,{0}_boot_hi", h.name()))
            .collect()
    }

    /// `label`'s bootstrap columns of `summary.csv`, with its leading comma (in each headline's
    /// unit: `success` and `overhead` as fractions, `pct_*` in %, RSRP in dBm).
    pub fn summary_columns(&self, label: &str) -> String {
        let nan = [BootCi {
            value: f64::NAN,
            lo: f64::NAN,
            hi: f64::NAN,
        }; HEADLINES.len()];
        self.intervals
            .get(label)
            .unwrap_or(&nan)
            .iter()
            .map(|c| format!(",{},{}", c.lo, c.hi))
            .collect()
    }
}

/// `per_seed.csv`: one row per method and training seed, summary.csv's columns over that seed's
/// flights.
pub fn write_per_seed(path: &Path, st: &SeedStats) -> Result<(), EvalError> {
    write_atomic_with(path, |w| {
        writeln!(
            w,
            "method,seed,flights,success,collision,out_of_bounds,timeout,overhead_mean,mean_rsrp_dbm,pct_excellent,handovers_per_km,ping_pongs_per_km,mean_sinr_db,pct_sinr_below_m6db,site_regret_db,pct_site_regret_high,pct_class_regret"
        )?;
        for (seed, d) in &st.per_seed {
            let (ho_km, pp_km) = d.per_km();
            writeln!(
                w,
                "{},{seed},{},{},{},{},{},{},{},{},{ho_km},{pp_km},{},{},{},{},{}",
                d.label,
                d.flights.len(),
                d.rate(Outcome::Goal).rate,
                d.rate(Outcome::Collision).rate,
                d.rate(Outcome::OutOfBounds).rate,
                d.rate(Outcome::TimeLimit).rate,
                d.ci(None, |m| m.overhead).mean,
                d.ci(None, |m| m.mean_rsrp_dbm).mean,
                100.0 * d.ci(None, |m| m.frac_class[0]).mean,
                d.all_ci(|m| m.mean_sinr_db).mean,
                100.0 * d.all_ci(|m| m.frac_sinr_below_m6db).mean,
                d.all_ci(|m| m.mean_site_regret_db).mean,
                100.0 * d.all_ci(|m| m.frac_site_regret_high).mean,
                100.0 * d.all_ci(|m| m.frac_class_regret).mean,
            )?;
        }
        Ok(())
    })?;
    Ok(())
}

/// `paired.csv`: one row per compared pair of methods and headline: the matched flights
/// counted, A − B and its 95 % bootstrap interval (in the headline's unit), whether the
/// interval excludes 0.
pub fn write_paired(path: &Path, st: &SeedStats) -> Result<(), EvalError> {
    write_atomic_with(path, |w| {
        writeln!(
            w,
            "method_a,method_b,metric,n,mean_diff,lo,hi,excludes_zero"
        )?;
        for c in &st.comparisons {
            for d in &c.diffs {
                writeln!(
                    w,
                    "{},{},{},{},{},{},{},{}",
                    c.a,
                    c.b,
                    d.headline.name(),
                    d.n,
                    d.diff.value,
                    d.diff.lo,
                    d.diff.hi,
                    excludes_zero(d.diff)
                )?;
            }
        }
        Ok(())
    })?;
    Ok(())
}

fn excludes_zero(c: BootCi) -> bool {
    c.lo > 0.0 || c.hi < 0.0
}

/// How a headline is shown in report.md: scale, digits, column title, title of a difference.
fn shown(h: Headline) -> (f64, usize, &'static str, &'static str) {
    match h {
        Headline::Success => (100.0, 1, "success (%)", "success (points)"),
        Headline::Overhead => (100.0, 1, "overhead (%)", "overhead (points)"),
        Headline::Excellent => (1.0, 1, "excellent (%)", "excellent (points)"),
        Headline::ExcellentNet => (
            1.0,
            1,
            "excellent net of interruptions (%)",
            "excellent net (points)",
        ),
        Headline::MeanRsrp => (1.0, 1, "mean RSRP (dBm)", "mean RSRP (dB)"),
        Headline::SinrLow => (1.0, 2, "SINR < −6 dB (%)", "SINR < −6 dB (points)"),
        Headline::HandoversPerKm => (1.0, 2, "handovers/km", "handovers/km"),
        Headline::PingPongsPerKm => (1.0, 2, "ping-pongs/km", "ping-pongs/km"),
    }
}

fn fmt_boot(c: BootCi, h: Headline, sign: bool) -> String {
    let (scale, d, _, _) = shown(h);
    if c.value.is_nan() {
        return "–".into();
    }
    let v = if sign {
        format!("{:+.*}", d, c.value * scale)
    } else {
        format!("{:.*}", d, c.value * scale)
    };
    if c.lo.is_nan() {
        return v;
    }
    format!("{v} [{:.*}, {:.*}]", d, c.lo * scale, d, c.hi * scale)
}

/// The seed-aware sections of report.md: the bootstrap intervals of every method in `data`'s
/// order, the rows per seed, the paired differences.
pub fn markdown(s: &mut String, data: &[MethodData], st: &SeedStats) {
    let b = st.boot.resamples;
    let _ = writeln!(
        s,
        "\n## Seed-aware intervals\n\nThe headline statistics over all flights of each method with a 95 % interval that counts the variance between training seeds: the 2.5 and 97.5 percentiles of {b} bootstrap resamples (ChaCha8, seed {}), each drawing the training seeds with replacement and the pairs (by pair id, the same draw for every seed) with replacement. Overhead, excellent time and RSRP over successful flights; the rest over all flights; handovers and ping-pongs per km as total count over total distance. A planner is deterministic: its interval is the pairs' alone.\n",
        st.boot.seed
    );
    let titles: Vec<&str> = HEADLINES.iter().map(|&h| shown(h).2).collect();
    let _ = writeln!(
        s,
        "| method | seeds | flights | {} |\n|---|---:|---:|{}",
        titles.join(" | "),
        "---|".repeat(HEADLINES.len())
    );
    for d in data {
        let Some(ci) = st.intervals.get(&d.label) else {
            continue;
        };
        let cells: Vec<String> = HEADLINES
            .iter()
            .zip(ci)
            .map(|(&h, &c)| fmt_boot(c, h, false))
            .collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} |",
            d.label,
            d.seeds,
            d.flights.len(),
            cells.join(" | ")
        );
    }
    let _ = writeln!(
        s,
        "\n## Per seed\n\nEach training seed's flights alone (`per_seed.csv`); overhead, excellent time and RSRP over successful flights.\n\n| method | seed | flights | success (%) | collision (%) | timeout (%) | overhead (%) | mean RSRP (dBm) | excellent (%) | SINR < −6 dB (%) | handovers/km | ping-pongs/km |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for (seed, d) in &st.per_seed {
        let (ho_km, pp_km) = d.per_km();
        let cells = [
            (100.0 * d.rate(Outcome::Goal).rate, 1),
            (100.0 * d.rate(Outcome::Collision).rate, 1),
            (100.0 * d.rate(Outcome::TimeLimit).rate, 1),
            (100.0 * d.ci(None, |m| m.overhead).mean, 1),
            (d.ci(None, |m| m.mean_rsrp_dbm).mean, 1),
            (100.0 * d.ci(None, |m| m.frac_class[0]).mean, 1),
            (100.0 * d.all_ci(|m| m.frac_sinr_below_m6db).mean, 2),
            (ho_km, 2),
            (pp_km, 2),
        ]
        .map(|(v, digits)| {
            if v.is_nan() {
                "–".to_string()
            } else {
                format!("{v:.digits$}")
            }
        });
        let _ = writeln!(
            s,
            "| {} | {seed} | {} | {} |",
            d.label,
            d.flights.len(),
            cells.join(" | ")
        );
    }
    if st.comparisons.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Paired differences\n\nA − B over the flights both methods flew (`paired.csv`): training seed index i of A (seeds in ascending order) with seed index i of B, on the same pair id; a planner (one deterministic flight per pair) pairs with every seed of A. Overhead, excellent time and RSRP over the matched flights where both succeeded (n counts them), the rest over all matched flights; handovers and ping-pongs as the difference of the per-km rates. 95 % interval: the same bootstrap ({b} resamples), drawing seed indices and pair ids once for both methods. * : the interval excludes 0.\n\n| A − B | seed indices | metric | n | difference [95 %] |\n|---|---:|---|---:|---|"
    );
    for c in &st.comparisons {
        for d in &c.diffs {
            let _ = writeln!(
                s,
                "| {} − {} | {} | {} | {} | {}{} |",
                c.a,
                c.b,
                c.seed_indices,
                shown(d.headline).3,
                d.n,
                fmt_boot(d.diff, d.headline, true),
                if excludes_zero(d.diff) { " *" } else { "" }
            );
        }
    }
}
