//! The audit of the shortest path, the denominator of every distance-overhead figure: over a set
//! of pairs, is [`Planner::shortest`] no longer than any coverage-aware path of the pair
//! ([`Planner::coverage_aware`], each λ asked), and how far is it above the [`LowerBound`]?

use super::{LowerBound, PlanError, Planner};
use dupac_common::geometry::Point;
use rayon::prelude::*;
use std::time::Instant;

/// One pair's figures.
#[derive(Debug, Clone, PartialEq)]
pub struct AuditRow {
    /// Length of [`Planner::shortest`] (m).
    pub shortest_m: f64,
    /// Length of [`Planner::coverage_aware`] for each λ asked, in order (m).
    pub lambda_m: Vec<f64>,
    /// [`LowerBound::lower_bound_m`] (m), searched within the ellipse of the shortest path's
    /// horizontal length.
    pub bound_m: f64,
    /// Wall time of planning the shortest path (s).
    pub shortest_s: f64,
}

impl AuditRow {
    /// The shortest of the coverage-aware paths (m); +∞ when no λ was asked.
    pub fn min_lambda_m(&self) -> f64 {
        self.lambda_m.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// How much shorter (m) than the shortest path the shortest coverage-aware path is; ≤ 0 when
    /// none is shorter.
    pub fn lambda_shorter_m(&self) -> f64 {
        self.shortest_m - self.min_lambda_m()
    }

    /// Gap of the shortest path above the lower bound (m).
    pub fn gap_m(&self) -> f64 {
        self.shortest_m - self.bound_m
    }

    /// [`AuditRow::gap_m`] relative to the bound (fraction).
    pub fn gap_rel(&self) -> f64 {
        self.gap_m() / self.bound_m
    }
}

/// A pair that could not be planned: its position in the input and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("audit of pair {index}: {cause}")]
pub struct AuditError {
    /// Position of the pair in the input.
    pub index: usize,
    /// The planner's error, part of this error's message.
    pub cause: PlanError,
}

/// Audits every `(source, destination)` pair (m) in parallel (rayon): the shortest path, the
/// coverage-aware path of each of `lambdas` (they need [`Planner::with_coverage`]), and the lower
/// bound of the band-blocking footprints of the planner's city and band. Rows in input order.
pub fn audit(
    planner: &Planner,
    endpoints: &[(Point, Point)],
    lambdas: &[f64],
) -> Result<Vec<AuditRow>, AuditError> {
    let bound = LowerBound::new(planner.city(), planner.free_space().band_m());
    endpoints
        .par_iter()
        .enumerate()
        .map(|(index, &(s, t))| {
            let fail = |cause| AuditError { index, cause };
            let t0 = Instant::now();
            let shortest = planner.shortest(s, t).map_err(fail)?;
            let shortest_s = t0.elapsed().as_secs_f64();
            let lambda_m = lambdas
                .iter()
                .map(|&l| planner.coverage_aware(s, t, l).map(|p| p.length_m))
                .collect::<Result<Vec<f64>, PlanError>>()
                .map_err(fail)?;
            let horizontal_m: f64 = shortest
                .waypoints_m
                .windows(2)
                .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
                .sum();
            Ok(AuditRow {
                shortest_m: shortest.length_m,
                lambda_m,
                bound_m: bound.lower_bound_m(s, t, Some(horizontal_m)),
                shortest_s,
            })
        })
        .collect()
}

/// What a set of [`AuditRow`]s says.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AuditSummary {
    /// Pairs audited.
    pub pairs: usize,
    /// Pairs whose shortest coverage-aware path is shorter than the shortest path by more than
    /// the tolerance given to [`AuditSummary::of`].
    pub lambda_shorter: usize,
    /// The most a coverage-aware path is shorter than the shortest path (m; ≤ 0: never).
    pub max_lambda_shorter_m: f64,
    /// Pairs whose shortest path is below the lower bound (a bug) by more than the tolerance.
    pub below_bound: usize,
    /// Largest, mean and 95th percentile (nearest rank) of the gap to the bound (m).
    pub gap_max_m: f64,
    pub gap_mean_m: f64,
    pub gap_p95_m: f64,
    /// The same, relative to the bound (fraction).
    pub gap_rel_max: f64,
    pub gap_rel_mean: f64,
    pub gap_rel_p95: f64,
    /// Total wall time of the shortest paths (s, summed over pairs).
    pub shortest_s: f64,
}

impl std::fmt::Display for AuditSummary {
    /// One line: the pairs, those with a shorter coverage-aware path (and by how much at most),
    /// those below the bound, and the gap to the bound (max / mean / p95, in m and %).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} pairs; a coverage-aware path shorter than the shortest: {} (by at most {:.3} m); \
             shortest below the bound: {}; gap to the bound max / mean / p95: {:.1} / {:.2} / \
             {:.1} m ({:.1} / {:.2} / {:.1} %)",
            self.pairs,
            self.lambda_shorter,
            self.max_lambda_shorter_m.max(0.0),
            self.below_bound,
            self.gap_max_m,
            self.gap_mean_m,
            self.gap_p95_m,
            100.0 * self.gap_rel_max,
            100.0 * self.gap_rel_mean,
            100.0 * self.gap_rel_p95,
        )
    }
}

impl AuditSummary {
    /// Summarises `rows`; `tolerance_m` (m) is the slack of both counts.
    pub fn of(rows: &[AuditRow], tolerance_m: f64) -> AuditSummary {
        let n = rows.len();
        let stats = |mut v: Vec<f64>| -> (f64, f64, f64) {
            if v.is_empty() {
                return (f64::NAN, f64::NAN, f64::NAN);
            }
            v.sort_by(f64::total_cmp);
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            let p95 = v[((0.95 * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1];
            (v[v.len() - 1], mean, p95)
        };
        let (gap_max_m, gap_mean_m, gap_p95_m) = stats(rows.iter().map(AuditRow::gap_m).collect());
        let (gap_rel_max, gap_rel_mean, gap_rel_p95) =
            stats(rows.iter().map(AuditRow::gap_rel).collect());
        AuditSummary {
            pairs: n,
            lambda_shorter: rows
                .iter()
                .filter(|r| r.lambda_shorter_m() > tolerance_m)
                .count(),
            max_lambda_shorter_m: rows
                .iter()
                .map(AuditRow::lambda_shorter_m)
                .fold(f64::NEG_INFINITY, f64::max),
            below_bound: rows.iter().filter(|r| r.gap_m() < -tolerance_m).count(),
            gap_max_m,
            gap_mean_m,
            gap_p95_m,
            gap_rel_max,
            gap_rel_mean,
            gap_rel_p95,
            shortest_s: rows.iter().map(|r| r.shortest_s).sum(),
        }
    }
}
