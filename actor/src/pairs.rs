//! Source/destination pairs (spec/env.md "Episodes"): the held-out sets (distance bins of the
//! shortest flyable path; two splits, [`Split`]: validation, which chose the design, and test,
//! used once), the training pool (shortest path ~ uniform in `[min_m, max_m]`), and their
//! JSON-lines files.
//!
//! # Determinism
//! Every candidate pair has its own ChaCha8 stream: key = (seed, domain) packed into the 32-byte
//! ChaCha key (`seed` little-endian in bytes 0..8, a domain tag in bytes 8..16), stream id = the
//! candidate's index (`bin_index << 32 | k` for evaluation, `k` for training). Candidates are
//! evaluated in parallel in fixed batches of [`BATCH`] and accepted strictly in index order, so
//! the result depends on the seed only, never on the number of threads.
//!
//! The validation set uses domain [`EVAL_DOMAIN`] with `pairs.eval_seed`, the test set domain
//! [`TEST_DOMAIN`] with `pairs.test_seed`, the training pool domain [`TRAIN_DOMAIN`] with its own
//! seed: no two of them share a ChaCha key, even for equal seeds, so no pair of one repeats a
//! pair of another (their coordinates come from independent streams of continuous draws).
//!
//! # Sampling one candidate for a target length D (m)
//! Up to [`TRIES_PER_CANDIDATE`] times: a source uniform in area × band, rejected until
//! [`check_endpoint`] passes; a destination at straight distance r ~ U[D/1.5, D] from it, with an
//! altitude uniform in the band and a uniform azimuth, rejected the same way; plan the shortest
//! path; accept when |shortest − D| ≤ `bin_tolerance`·D. The target D is drawn once per candidate
//! (training) so accepted lengths follow the target distribution, not the acceptance rate.
//!
//! # Files
//! One JSON object per line ([`Pair`]); blank lines are skipped. User files may omit `id` (the
//! pair's 0-based position in the file is used), `shortest_m` (computed with the planner) and
//! `straight_m` (computed from the endpoints); when given, `straight_m` must match the endpoints
//! and `shortest_m` must be ≥ `straight_m` and > 0. Every error names the file and line.

use crate::env::{Episode, PathGuide};
use crate::planner::{PlanError, Planner, dist};
use dupac_common::config::{EnvConfig, PairsConfig};
use dupac_common::geometry::Point;
use dupac_radio::channel::FieldSplit;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::io::BufRead;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Domain tag of the evaluation set's random streams ("eval").
pub const EVAL_DOMAIN: u64 = 0x6c61_7665;
/// Domain tag of the training pool's random streams ("train").
pub const TRAIN_DOMAIN: u64 = 0x6e_6961_7274;
/// Domain tag of the test set's random streams ("test").
pub const TEST_DOMAIN: u64 = 0x7473_6574;

mod split;
pub use split::Split;

/// Candidates evaluated per parallel batch (fixed: the result must not depend on threads).
pub const BATCH: usize = 64;
/// Attempts (source, destination, plan) per candidate before it is given up.
pub const TRIES_PER_CANDIDATE: usize = 100;
/// Attempts to draw one free endpoint.
const ENDPOINT_TRIES: usize = 1000;
/// Attempts to draw a destination for one source.
const DESTINATION_TRIES: usize = 32;

/// One episode's endpoints (spec/env.md "Episodes"), local ENU metres.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pair {
    /// Position in its set (evaluation: across bins in order; training: in the pool).
    pub id: u64,
    /// Source (m).
    #[serde(with = "dupac_common::geometry::serde_point")]
    pub source_m: Point,
    /// Destination (m).
    #[serde(with = "dupac_common::geometry::serde_point")]
    pub destination_m: Point,
    /// Length of the shortest flyable path within the band (m), [`Planner::shortest`].
    pub shortest_m: f64,
    /// Straight-line distance between the endpoints (m).
    pub straight_m: f64,
    /// Evaluation bin (m) the pair belongs to; absent for training pairs.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bin_m: Option<f64>,
    /// The planned path from source to destination, the episode's guide ([`Pair::episode`]):
    /// the shortest path of the sampler, or another from [`attach_paths`]. Not written to files.
    #[serde(skip)]
    pub path: Option<Arc<PathGuide>>,
    /// λ of the coverage-aware planner that planned `path` (0: the shortest path).
    #[serde(skip)]
    pub path_lambda: f64,
    /// Clearance (m) `path` was asked for: the planner's that planned it, or the guide
    /// planner's whose attempt fell back ([`plan_path`]).
    #[serde(skip)]
    pub path_clearance_m: f64,
}

impl Pair {
    /// The episode of this pair, flown from source to destination or, `reversed`, back, in
    /// `field`'s shadow-fading realisations (the split the pair belongs to: [`Episode::field`]);
    /// with the planned path as its guide when the pair has one.
    pub fn episode(&self, reversed: bool, field: FieldSplit) -> Episode {
        let (source_m, destination_m) = if reversed {
            (self.destination_m, self.source_m)
        } else {
            (self.source_m, self.destination_m)
        };
        Episode {
            source_m,
            destination_m,
            field,
            shortest_m: self.shortest_m,
            guide: self.path.as_ref().map(|g| {
                if reversed {
                    Arc::new(g.reversed())
                } else {
                    g.clone()
                }
            }),
        }
    }
}

/// Plans `pair`'s guide path with `guide` unless it has one of `lambda` and `guide`'s clearance
/// already: the shortest path (`lambda` = 0) or the coverage-aware one
/// ([`Planner::coverage_aware`], which needs [`Planner::with_coverage`]). When `guide` finds
/// none (its clearance closes a gap the pair's own path passes), `fallback` — the planner that
/// drew and checked the pair — plans it instead; returns whether it did.
pub fn plan_path(
    guide: &Planner,
    fallback: &Planner,
    pair: &mut Pair,
    lambda: f64,
) -> Result<bool, PlanError> {
    let clearance_m = guide.free_space().clearance_m();
    if pair.path.is_some() && pair.path_lambda == lambda && pair.path_clearance_m == clearance_m {
        return Ok(false);
    }
    let plan = |planner: &Planner| {
        if lambda > 0.0 {
            planner.coverage_aware(pair.source_m, pair.destination_m, lambda)
        } else {
            planner.shortest(pair.source_m, pair.destination_m)
        }
    };
    let (path, fell_back) = match plan(guide) {
        Ok(p) => (p, false),
        // Only a path the guide's clearance cannot fly falls back: a guide planner built wrong
        // (no coverage classes, a bad λ) is an error, not a pair to count.
        Err(e @ (PlanError::NoCoverage | PlanError::BadLambda(_))) => return Err(e),
        Err(e) if std::ptr::eq(guide, fallback) => return Err(e),
        Err(_) => (plan(fallback)?, true),
    };
    pair.path = PathGuide::new(&path.waypoints_m).map(Arc::new);
    pair.path_lambda = lambda;
    pair.path_clearance_m = clearance_m;
    Ok(fell_back)
}

/// [`plan_path`] for every pair, in parallel: the number of pairs `fallback` planned; a failure
/// (one of them, if several) names its pair. `progress(1)` is called after each pair.
pub fn attach_paths(
    guide: &Planner,
    fallback: &Planner,
    pairs: &mut [Pair],
    lambda: f64,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<usize, String> {
    pairs
        .par_iter_mut()
        .map(|p| {
            let planned = plan_path(guide, fallback, p, lambda)
                .map(usize::from)
                .map_err(|e| format!("pair {}: {e}", p.id));
            progress(1);
            planned
        })
        .try_reduce(|| 0, |a, b| Ok(a + b))
}

/// What a user's pairs file may contain: [`Pair`] with `id`, `shortest_m` and `straight_m`
/// optional.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PairInput {
    id: Option<u64>,
    #[serde(with = "dupac_common::geometry::serde_point")]
    source_m: Point,
    #[serde(with = "dupac_common::geometry::serde_point")]
    destination_m: Point,
    shortest_m: Option<f64>,
    straight_m: Option<f64>,
    bin_m: Option<f64>,
}

/// Errors reading or writing pairs files; each names the file (and the line).
#[derive(Debug, thiserror::Error)]
pub enum PairsError {
    #[error("cannot read pairs file {path}: {cause}")]
    Read {
        path: PathBuf,
        /// The OS error, part of this error's message (not its `source()`, so that a printed
        /// chain shows it once).
        cause: std::io::Error,
    },
    #[error("cannot write pairs file {path}: {cause}")]
    Write {
        path: PathBuf,
        /// The OS error, part of this error's message (not its `source()`, so that a printed
        /// chain shows it once).
        cause: std::io::Error,
    },
    /// A bad line: `FILE:LINE: message` (lines count from 1).
    #[error("{}:{line}: {message}", path.display())]
    Line {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{}: no pairs", path.display())]
    Empty { path: PathBuf },
}

/// Checks an endpoint (also those of user files): finite, inside the flight area, inside
/// `[env.z_min_m, env.z_max_m]` (the planner's band), not inside a building, and at least
/// `clearance_m` (m; `pairs.endpoint_clearance_m`, spec/env.md: 5 m) from every building surface.
/// The error says why, with the position.
pub fn check_endpoint(planner: &Planner, p_m: Point, clearance_m: f64) -> Result<(), String> {
    let fs = planner.free_space();
    let city = planner.city();
    if !p_m.iter().all(|v| v.is_finite()) {
        return Err(format!("{p_m:?} is not a finite point"));
    }
    if !city.in_area(p_m[0], p_m[1]) {
        let area = city.area_m;
        return Err(format!("{p_m:?} is outside the flight area {area}"));
    }
    let [z0, z1] = fs.band_m();
    if !(p_m[2] >= z0 && p_m[2] <= z1) {
        return Err(format!(
            "{p_m:?} is outside the altitude band [{z0}, {z1}] m"
        ));
    }
    if city.is_inside_building(p_m) {
        return Err(format!("{p_m:?} is inside a building"));
    }
    let d = fs.mesh_distance_capped_m(p_m, clearance_m);
    if d < clearance_m {
        return Err(format!(
            "{p_m:?} is {d:.2} m from a building, less than the endpoint clearance {clearance_m} m"
        ));
    }
    Ok(())
}

/// Warns when `env`'s altitude band is not the one the planner was built with.
fn warn_band(planner: &Planner, env: &EnvConfig) {
    let band = planner.free_space().band_m();
    if band != [env.z_min_m, env.z_max_m] {
        tracing::warn!(
            planner_band_m = ?band,
            env_band_m = ?[env.z_min_m, env.z_max_m],
            "pairs: the planner was built for another altitude band; using the planner's"
        );
    }
}

/// The random stream of one candidate (see the module documentation).
fn stream(seed: u64, domain: u64, index: u64) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&domain.to_le_bytes());
    let mut rng = ChaCha8Rng::from_seed(key);
    rng.set_stream(index);
    rng
}

/// A uniform point of area × band that passes [`check_endpoint`], or `None` after
/// [`ENDPOINT_TRIES`] draws.
fn free_endpoint(planner: &Planner, clearance_m: f64, rng: &mut ChaCha8Rng) -> Option<Point> {
    let a = planner.city().area_m;
    let [z0, z1] = planner.free_space().band_m();
    if !(a.min_m.x < a.max_m.x && a.min_m.y < a.max_m.y && z0 <= z1) {
        return None;
    }
    for _ in 0..ENDPOINT_TRIES {
        let p = Point::new(
            rng.random_range(a.min_m.x..=a.max_m.x),
            rng.random_range(a.min_m.y..=a.max_m.y),
            rng.random_range(z0..=z1),
        );
        if check_endpoint(planner, p, clearance_m).is_ok() {
            return Some(p);
        }
    }
    None
}

/// A destination at straight distance r ~ U[D/1.5, D] from `source`, altitude uniform in the band,
/// uniform azimuth, passing [`check_endpoint`].
fn destination_near(
    planner: &Planner,
    clearance_m: f64,
    source: Point,
    target_m: f64,
    rng: &mut ChaCha8Rng,
) -> Option<Point> {
    let [z0, z1] = planner.free_space().band_m();
    for _ in 0..DESTINATION_TRIES {
        let r = rng.random_range(target_m / 1.5..=target_m);
        let z = rng.random_range(z0..=z1);
        let dz = z - source[2];
        if dz.abs() >= r {
            continue;
        }
        let h = (r * r - dz * dz).sqrt();
        let azimuth = rng.random_range(0.0..std::f64::consts::TAU);
        let p = Point::new(
            source[0] + h * azimuth.cos(),
            source[1] + h * azimuth.sin(),
            z,
        );
        if check_endpoint(planner, p, clearance_m).is_ok() {
            return Some(p);
        }
    }
    None
}

/// One candidate: a pair whose shortest path is within `bin_tolerance` of `target_m`, or `None`
/// after [`TRIES_PER_CANDIDATE`] attempts. The id is set by the caller.
fn candidate(
    planner: &Planner,
    cfg: &PairsConfig,
    target_m: f64,
    bin_m: Option<f64>,
    rng: &mut ChaCha8Rng,
) -> Option<Pair> {
    if !(target_m.is_finite() && target_m > 0.0) {
        return None;
    }
    let clearance_m = cfg.endpoint_clearance_m;
    let tolerance_m = cfg.bin_tolerance * target_m;
    for _ in 0..TRIES_PER_CANDIDATE {
        let source = free_endpoint(planner, clearance_m, rng)?;
        let Some(destination) = destination_near(planner, clearance_m, source, target_m, rng)
        else {
            continue;
        };
        let Ok(path) = planner.shortest(source, destination) else {
            continue;
        };
        if (path.length_m - target_m).abs() <= tolerance_m {
            return Some(Pair {
                id: 0,
                source_m: source,
                destination_m: destination,
                shortest_m: path.length_m,
                straight_m: dist(source, destination),
                bin_m,
                path: PathGuide::new(&path.waypoints_m).map(Arc::new),
                path_lambda: 0.0,
                path_clearance_m: planner.free_space().clearance_m(),
            });
        }
    }
    None
}

/// Takes candidates `0, 1, 2, …` (built by `make(k)`, in parallel batches of [`BATCH`]) in index
/// order until `n` are accepted; stops early when a whole batch yields nothing. Calls
/// `progress(accepted_in_batch)` after each batch.
fn collect(
    n: usize,
    progress: &(dyn Fn(u64) + Sync),
    make: impl Fn(u64) -> Option<Pair> + Sync,
) -> Vec<Pair> {
    let mut out = Vec::with_capacity(n);
    let mut next = 0u64;
    while out.len() < n {
        let batch: Vec<Option<Pair>> = (next..next + BATCH as u64)
            .into_par_iter()
            .map(&make)
            .collect();
        next += BATCH as u64;
        let before = out.len();
        for p in batch.into_iter().flatten() {
            if out.len() < n {
                out.push(p);
            }
        }
        let added = out.len() - before;
        if added == 0 {
            break;
        }
        progress(added as u64);
    }
    out
}

/// The held-out validation set (spec/env.md "Episodes"): [`split_pairs`] of
/// [`Split::Validation`] (`cfg.eval_seed`, domain [`EVAL_DOMAIN`]).
pub fn eval_pairs(
    planner: &Planner,
    cfg: &PairsConfig,
    env: &EnvConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> Vec<Pair> {
    split_pairs(planner, cfg, env, Split::Validation, progress)
}

/// A held-out split (spec/env.md "Episodes"): for each bin D of `cfg.eval_bins_m` (m, in
/// order), `cfg.eval_per_bin` pairs whose shortest flyable path is within `cfg.bin_tolerance`·D
/// of D, drawn with the split's seed and domain ([`Split::seed`], [`Split::domain`]); ids count
/// from 0 across bins. Deterministic for a seed regardless of the thread count. A bin that cannot
/// be filled (the city is too small) is returned short, with a warning. `progress(n)` is called
/// with the number of pairs newly accepted. `env` must be the configuration the planner was built
/// with (its band is the planner's).
pub fn split_pairs(
    planner: &Planner,
    cfg: &PairsConfig,
    env: &EnvConfig,
    split: Split,
    progress: &(dyn Fn(u64) + Sync),
) -> Vec<Pair> {
    warn_band(planner, env);
    let (seed, domain) = (split.seed(cfg), split.domain());
    let mut out = Vec::new();
    for (b, &bin_m) in cfg.eval_bins_m.iter().enumerate() {
        let got = collect(cfg.eval_per_bin, progress, |k| {
            let mut rng = stream(seed, domain, ((b as u64) << 32) | k);
            candidate(planner, cfg, bin_m, Some(bin_m), &mut rng)
        });
        if got.len() < cfg.eval_per_bin {
            tracing::warn!(
                split = split.name(),
                bin_m,
                got = got.len(),
                wanted = cfg.eval_per_bin,
                "held-out bin could not be filled"
            );
        }
        out.extend(got);
    }
    for (i, p) in out.iter_mut().enumerate() {
        p.id = i as u64;
    }
    out
}

/// The training pool (spec/env.md "Episodes"): `n` pairs whose shortest flyable path is within
/// `cfg.bin_tolerance`·D of a target D ~ U[`cfg.min_m`, `cfg.max_m`] (m) drawn per candidate,
/// from `seed` (domain [`TRAIN_DOMAIN`], so never an evaluation pair); ids `0..n`, no bin.
/// Deterministic for a seed regardless of the thread count; returned short (with a warning) when
/// the city cannot hold such pairs. `progress(n)` is called with the number newly accepted.
pub fn training_pool(
    planner: &Planner,
    cfg: &PairsConfig,
    env: &EnvConfig,
    n: usize,
    seed: u64,
    progress: &(dyn Fn(u64) + Sync),
) -> Vec<Pair> {
    warn_band(planner, env);
    let (lo, hi) = (cfg.min_m.min(cfg.max_m), cfg.max_m.max(cfg.min_m));
    let finite = lo.is_finite() && hi.is_finite();
    let mut out = collect(n, progress, |k| {
        let mut rng = stream(seed, TRAIN_DOMAIN, k);
        let target_m = if !finite {
            f64::NAN
        } else if hi > lo {
            rng.random_range(lo..=hi)
        } else {
            lo
        };
        candidate(planner, cfg, target_m, None, &mut rng)
    });
    if out.len() < n {
        tracing::warn!(
            got = out.len(),
            wanted = n,
            "training pool could not be filled"
        );
    }
    for (i, p) in out.iter_mut().enumerate() {
        p.id = i as u64;
    }
    out
}

/// Writes one JSON object per line, atomically ([`dupac_common::fsio`]; parent directories are
/// created).
pub fn write_pairs_jsonl(path: &Path, pairs: &[Pair]) -> Result<(), PairsError> {
    let err = |cause: std::io::Error| PairsError::Write {
        path: path.to_path_buf(),
        cause,
    };
    dupac_common::fsio::write_atomic_with(path, |w| {
        for p in pairs {
            let line = serde_json::to_string(p).map_err(std::io::Error::other)?;
            w.write_all(line.as_bytes())?;
            w.write_all(b"\n")?;
        }
        Ok(())
    })
    .map_err(|e| err(std::io::Error::other(e.to_string())))
}

/// Reads and validates a pairs file (ours or a user's; see the module documentation for the
/// optional fields). Each line must be a JSON object with finite numbers; both endpoints must pass
/// [`check_endpoint`] with `cfg.endpoint_clearance_m`; `shortest_m` > 0 (computed with `planner`
/// when absent, which also proves the pair flyable); ids must be unique. Errors are
/// `FILE:LINE: message`. A pair whose `shortest_m` was computed keeps that path as its guide
/// ([`attach_paths`] gives the others one).
pub fn read_pairs_jsonl(
    path: &Path,
    planner: &Planner,
    cfg: &PairsConfig,
) -> Result<Vec<Pair>, PairsError> {
    let file = std::fs::File::open(path).map_err(|cause| PairsError::Read {
        path: path.to_path_buf(),
        cause,
    })?;
    let reader = std::io::BufReader::new(file);
    let mut out: Vec<Pair> = Vec::new();
    let mut seen: std::collections::HashMap<u64, usize> = std::collections::HashMap::new();
    for (i, line) in reader.lines().enumerate() {
        let line_no = i + 1;
        let bad = |message: String| PairsError::Line {
            path: path.to_path_buf(),
            line: line_no,
            message,
        };
        let line = line.map_err(|e| bad(format!("cannot read: {e}")))?;
        if line.trim().is_empty() {
            continue;
        }
        let input: PairInput = serde_json::from_str(&line).map_err(|e| bad(json_error(&e)))?;
        let pair = validate(input, out.len() as u64, planner, cfg).map_err(bad)?;
        if let Some(first) = seen.insert(pair.id, line_no) {
            return Err(bad(format!(
                "duplicate id {} (first on line {first})",
                pair.id
            )));
        }
        out.push(pair);
    }
    if out.is_empty() {
        return Err(PairsError::Empty {
            path: path.to_path_buf(),
        });
    }
    Ok(out)
}

/// A JSON error of one line, located by its column: serde_json's own "at line 1 column N" would
/// name line 1 of the line, not of the file.
fn json_error(e: &serde_json::Error) -> String {
    let text = e.to_string();
    let position = format!(" at line {} column {}", e.line(), e.column());
    match text.strip_suffix(&position) {
        Some(message) if e.line() == 1 => {
            format!("invalid pair (column {}): {message}", e.column())
        }
        _ => format!("invalid pair: {text}"),
    }
}

/// Validates one input line and fills in what it left out.
fn validate(
    input: PairInput,
    default_id: u64,
    planner: &Planner,
    cfg: &PairsConfig,
) -> Result<Pair, String> {
    let clearance_m = cfg.endpoint_clearance_m;
    check_endpoint(planner, input.source_m, clearance_m).map_err(|e| format!("source {e}"))?;
    check_endpoint(planner, input.destination_m, clearance_m)
        .map_err(|e| format!("destination {e}"))?;
    let straight = dist(input.source_m, input.destination_m);
    if let Some(s) = input.straight_m
        && !(s.is_finite() && (s - straight).abs() <= 1e-6 * straight.max(1.0))
    {
        return Err(format!(
            "straight_m {s} does not match the endpoints' distance {straight} m"
        ));
    }
    let mut planned = None;
    let shortest_m = match input.shortest_m {
        Some(v) => {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("shortest_m must be a finite number > 0, got {v}"));
            }
            if v < straight - 1e-6 * straight.max(1.0) {
                return Err(format!(
                    "shortest_m {v} is shorter than the straight line {straight} m"
                ));
            }
            v
        }
        None => {
            let path = planner
                .shortest(input.source_m, input.destination_m)
                .map_err(|e| format!("cannot compute shortest_m: {e}"))?;
            if path.length_m <= 0.0 {
                return Err("source and destination coincide".into());
            }
            planned = PathGuide::new(&path.waypoints_m).map(Arc::new);
            path.length_m
        }
    };
    if let Some(b) = input.bin_m
        && !(b.is_finite() && b > 0.0)
    {
        return Err(format!("bin_m must be a finite number > 0, got {b}"));
    }
    Ok(Pair {
        id: input.id.unwrap_or(default_id),
        source_m: input.source_m,
        destination_m: input.destination_m,
        shortest_m,
        straight_m: input.straight_m.unwrap_or(straight),
        bin_m: input.bin_m,
        path: planned,
        path_lambda: 0.0,
        path_clearance_m: planner.free_space().clearance_m(),
    })
}

#[cfg(test)]
mod tests;
