//! Non-learning planners over the free airspace (spec/env.md "Episodes": the paper's "manually
//! calculated shortest distance", and a coverage-aware baseline).
//!
//! * [`FreeSpace`]: the voxel lattice over the flight area × altitude band (points every
//!   `planner.voxel_m`), each point's distance to the building mesh, exact free-point and
//!   swept-sphere segment tests.
//! * [`Planner::shortest`]: a clear straight line if there is one; else the shorter of two routes,
//!   each smoothed and then polished: Lazy Theta* (any-angle A* on true Euclidean lengths, line of
//!   sight by a conservative distance-field test, lattice edges checked by swept sphere) and A* on
//!   the 26-connected lattice with plain lengths, both from the free lattice points a clear move
//!   reaches from the source to those that reach the destination. Smoothing uses the exact
//!   swept-sphere test: greedy string pulling, then a waypoint relaxation that slides waypoints
//!   towards the chord of their neighbours and cuts corners, pulling the path taut around
//!   buildings at the clearance (off the lattice); the polish repeats both with finer moves
//!   (smooth.rs). Why two routes: smoothing only tightens a path within its route, never moves it
//!   to the other side of a building or over another roof, and each search picks one route among
//!   near-equal ones (Theta*'s weighted heuristic and parent choices; the lattice's ties). With
//!   Theta* alone, 42 of Midtown's 700 held-out pairs (both splits) and 50 of the procedural
//!   world's had a coverage-aware path shorter than the "shortest" one (up to 1.7 m and 4.9 m: the
//!   coverage-aware planner's lattice A* found a better route, or its smoothing stopped nearer
//!   taut); with both routes polished, 7 (≤ 0.49 m) and 3 (≤ 3 cm), at about 4× the planning time
//!   (Midtown, warm: ≈ 4 ms → 17 ms a pair). On Midtown the result is within about 0.5 % of the
//!   same planner on a 2.5 m lattice; [`audit`] measures it against the coverage-aware paths and
//!   the [`LowerBound`] of the footprints that span the band (mean gap 3.1 m, 0.7 %).
//! * [`Planner::coverage_aware`]: A* on the 26-connected lattice with edge cost
//!   `length · (1 + λ · penalty(class))`, the class being that of the best site's RSRP at the
//!   edge's end point (spec/radio.md §3) and the heuristic the lattice distance; smoothing then only
//!   accepts a replacement whose cost (sampled every `voxel_m`) is not higher and whose worst class
//!   is not worse than the part of the path it replaces. The any-angle vertices smoothed under the
//!   same rule and the shortest path are candidates too; the cheapest under the cost field is
//!   kept, so the coverage-aware path never costs more than the shortest one. λ = 0 is exactly
//!   [`Planner::shortest`].
//!
//! Every segment of a returned path passes [`FreeSpace::segment_clear`] (clearance
//! `planner.clearance_m` ≥ the UAV radius), so the environment's swept-sphere collision test can
//! never fire along it.

mod audit;
mod bound;
mod free_space;
mod search;
mod smooth;

pub use audit::{AuditError, AuditRow, AuditSummary, audit};
pub use bound::LowerBound;
pub use free_space::{FreeSpace, SMOOTHING_MARGIN_M};

use dupac_common::config::{EnvConfig, PlannerConfig};
pub(crate) use dupac_common::geometry::distance_m as dist;
use dupac_common::geometry::{Bounds2, Point};
use dupac_radio::city::City;
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use dupac_radio::source::RsrpSource;
use rayon::prelude::*;
use search::{Scratch, SearchSpec};
use smooth::CostField;
use std::sync::{Arc, Mutex};

/// A flyable path: straight segments between waypoints (m, local ENU frame).
#[derive(Debug, Clone, PartialEq)]
pub struct Path {
    /// Waypoints, the source first and the destination last, both exactly as requested.
    pub waypoints_m: Vec<Point>,
    /// Sum of the segment lengths (m).
    pub length_m: f64,
}

impl Path {
    /// Builds a path and computes its length (m) as the sum of its segment lengths.
    pub fn from_waypoints(waypoints_m: Vec<Point>) -> Path {
        let length_m = waypoints_m.windows(2).map(|w| dist(w[0], w[1])).sum();
        Path {
            waypoints_m,
            length_m,
        }
    }
}

/// Which end of a planning request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Endpoint {
    Source,
    Destination,
}

impl std::fmt::Display for Endpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Endpoint::Source => "source",
            Endpoint::Destination => "destination",
        })
    }
}

/// Why a path could not be planned. Every message names the endpoint and its position (m).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    /// A coordinate is NaN or infinite.
    #[error("{which} {position_m:?} is not a finite point")]
    NotFinite { which: Endpoint, position_m: Point },
    /// Outside the flight area (m).
    #[error("{which} {position_m:?} is outside the flight area {area_m}")]
    OutsideArea {
        which: Endpoint,
        position_m: Point,
        area_m: Bounds2,
    },
    /// Outside the altitude band (m), spec/env.md.
    #[error("{which} {position_m:?} is outside the altitude band [{z_min_m}, {z_max_m}] m")]
    OutsideBand {
        which: Endpoint,
        position_m: Point,
        z_min_m: f64,
        z_max_m: f64,
    },
    /// Inside a building.
    #[error("{which} {position_m:?} is inside a building")]
    InsideBuilding { which: Endpoint, position_m: Point },
    /// Closer to a building surface than the planner's clearance.
    #[error(
        "{which} {position_m:?} is {distance_m:.2} m from a building, less than the clearance {clearance_m} m"
    )]
    TooCloseToBuilding {
        which: Endpoint,
        position_m: Point,
        distance_m: f64,
        clearance_m: f64,
    },
    /// No free lattice point near the endpoint can be reached by a clear straight move.
    #[error("{which} {position_m:?} cannot be connected to the free-space lattice (walled in)")]
    NotConnected { which: Endpoint, position_m: Point },
    /// The free airspace does not connect the two endpoints.
    #[error("no flyable path from source {source_m:?} to destination {destination_m:?}")]
    NoPath {
        source_m: Point,
        destination_m: Point,
    },
    /// [`Planner::coverage_aware`] before [`Planner::with_coverage`].
    #[error("coverage-aware planning needs the per-voxel RSRP classes: call with_coverage first")]
    NoCoverage,
    /// λ must be a finite number ≥ 0.
    #[error("coverage weight lambda must be a finite number >= 0, got {0}")]
    BadLambda(f64),
}

/// Class code stored per voxel: 0 excellent, 1 mediocre, 2 poor.
fn class_code(c: RsrpClass) -> u8 {
    c.index() as u8
}

/// The planners of one city: the free space, the optional per-voxel RSRP classes, and a pool of
/// search buffers reused across calls (one per concurrent search). `Sync`: plan from many threads.
pub struct Planner<'a> {
    city: &'a City,
    free: FreeSpace,
    /// Per-voxel class code of the best site's RSRP (see [`Planner::with_coverage`]).
    classes: Option<Arc<Vec<u8>>>,
    /// Penalty per metre by class code (excellent 0, `penalty_mediocre`, `penalty_poor`).
    penalties: [f64; 3],
    scratch: Mutex<Vec<Scratch>>,
}

impl std::fmt::Debug for Planner<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Planner")
            .field("city", &self.city.name)
            .field("free", &self.free)
            .field("coverage", &self.classes.is_some())
            .field("penalties", &self.penalties)
            .finish()
    }
}

impl<'a> Planner<'a> {
    /// Builds the free space of `city` (see [`FreeSpace::build`]) and takes the class penalties
    /// from `planner` (negative or non-finite penalties count as 0).
    pub fn new(city: &'a City, env: &EnvConfig, planner: &PlannerConfig) -> Planner<'a> {
        let pen = |v: f64| if v.is_finite() && v > 0.0 { v } else { 0.0 };
        Planner {
            city,
            free: FreeSpace::build(city, env, planner),
            classes: None,
            penalties: [
                0.0,
                pen(planner.penalty_mediocre),
                pen(planner.penalty_poor),
            ],
            scratch: Mutex::new(Vec::new()),
        }
    }

    /// The city this planner plans in.
    pub fn city(&self) -> &'a City {
        self.city
    }

    /// The free airspace (lattice and exact tests).
    pub fn free_space(&self) -> &FreeSpace {
        &self.free
    }

    /// Checks one endpoint: finite, in the area and the band, not inside a building, at least the
    /// planner clearance from the mesh. The error names the endpoint and the reason.
    pub fn check_point(&self, which: Endpoint, p_m: Point) -> Result<(), PlanError> {
        let fs = &self.free;
        if !p_m.iter().all(|v| v.is_finite()) {
            return Err(PlanError::NotFinite {
                which,
                position_m: p_m,
            });
        }
        if !self.city.in_area(p_m[0], p_m[1]) {
            return Err(PlanError::OutsideArea {
                which,
                position_m: p_m,
                area_m: fs.area_m(),
            });
        }
        let [z_min_m, z_max_m] = fs.band_m();
        if !(p_m[2] >= z_min_m && p_m[2] <= z_max_m) {
            return Err(PlanError::OutsideBand {
                which,
                position_m: p_m,
                z_min_m,
                z_max_m,
            });
        }
        if self.city.is_inside_building(p_m) {
            return Err(PlanError::InsideBuilding {
                which,
                position_m: p_m,
            });
        }
        let c = fs.clearance_m();
        let d = fs.mesh_distance_capped_m(p_m, c);
        if d < c {
            return Err(PlanError::TooCloseToBuilding {
                which,
                position_m: p_m,
                distance_m: d,
                clearance_m: c,
            });
        }
        Ok(())
    }

    /// The shortest flyable path (m) from `source_m` to `destination_m` within the altitude band
    /// (spec/env.md "Episodes": the 3D shortest flyable path; compare with the straight line).
    /// Both endpoints must be free points ([`FreeSpace::is_free_point`]). Every segment of the
    /// result passes [`FreeSpace::segment_clear`].
    pub fn shortest(&self, source_m: Point, destination_m: Point) -> Result<Path, PlanError> {
        self.plan(source_m, destination_m, None)
    }

    /// Precomputes, for every lattice point, the class (spec/radio.md §3, `thresholds`) of the
    /// best site's RSRP from `rsrp` (the cache or exact mode), in parallel. Needed by
    /// [`Planner::coverage_aware`].
    pub fn with_coverage(&mut self, rsrp: &dyn RsrpSource, thresholds: RsrpThresholds) {
        let fs = &self.free;
        let nx = fs.dims()[0].max(1);
        let m = rsrp.num_sites();
        let mut classes = vec![class_code(RsrpClass::Poor); fs.num_voxels()];
        classes
            .par_chunks_mut(nx)
            .enumerate()
            .for_each(|(row, out)| {
                let mut all = vec![f64::NAN; m];
                for (k, o) in out.iter_mut().enumerate() {
                    let p = fs.centre_m((row * nx + k) as u32);
                    rsrp.rsrp_all_dbm(p, &mut all);
                    let best = all
                        .iter()
                        .copied()
                        .filter(|v| !v.is_nan())
                        .fold(f64::NEG_INFINITY, f64::max);
                    *o = class_code(thresholds.classify(best));
                }
            });
        self.classes = Some(Arc::new(classes));
    }

    /// Takes `other`'s coverage classes ([`Planner::with_coverage`]) without computing them again
    /// when both planners share one lattice (the same city, band and voxel: the lattice does not
    /// depend on the clearance); `false` (nothing taken) otherwise or when `other` has none.
    pub fn share_coverage(&mut self, other: &Planner) -> bool {
        let (a, b) = (&self.free, &other.free);
        let n = a.num_voxels();
        let same = a.dims() == b.dims()
            && n == b.num_voxels()
            && n > 0
            && a.centre_m(0) == b.centre_m(0)
            && a.centre_m((n - 1) as u32) == b.centre_m((n - 1) as u32);
        match &other.classes {
            Some(c) if same => {
                self.classes = Some(c.clone());
                true
            }
            _ => false,
        }
    }

    /// Whether the coverage classes are here ([`Planner::with_coverage`]).
    pub fn has_coverage(&self) -> bool {
        self.classes.is_some()
    }

    /// Fractions of lattice points per class `[excellent, mediocre, poor]` among the free ones,
    /// or `None` before [`Planner::with_coverage`].
    pub fn coverage_class_fractions(&self) -> Option<[f64; 3]> {
        let classes = self.classes.as_ref()?;
        let mut n = [0usize; 3];
        for (i, &c) in classes.iter().enumerate() {
            if self.free.is_free_voxel(i as u32) {
                n[usize::from(c.min(2))] += 1;
            }
        }
        let total = (n[0] + n[1] + n[2]).max(1) as f64;
        Some(n.map(|v| v as f64 / total))
    }

    /// The coverage-aware path: minimises Σ length · (1 + λ · penalty(class)) over the lattice
    /// (penalties `planner.penalty_mediocre`, `planner.penalty_poor`, excellent 0), then smooths
    /// without ever raising that cost or crossing a worse class than the part replaced. λ = 0 gives
    /// [`Planner::shortest`]. Errors with [`PlanError::NoCoverage`] before
    /// [`Planner::with_coverage`].
    pub fn coverage_aware(
        &self,
        source_m: Point,
        destination_m: Point,
        lambda: f64,
    ) -> Result<Path, PlanError> {
        if !(lambda.is_finite() && lambda >= 0.0) {
            return Err(PlanError::BadLambda(lambda));
        }
        let classes = self
            .classes
            .as_deref()
            .map(Vec::as_slice)
            .ok_or(PlanError::NoCoverage)?;
        if lambda == 0.0 {
            return self.plan(source_m, destination_m, None);
        }
        let mult = self.penalties.map(|p| 1.0 + lambda * p);
        self.plan(source_m, destination_m, Some((classes, mult)))
    }

    /// Common planner: `coverage` = per-voxel classes and the cost multiplier per class.
    fn plan(
        &self,
        s: Point,
        t: Point,
        coverage: Option<(&[u8], [f64; 3])>,
    ) -> Result<Path, PlanError> {
        self.check_point(Endpoint::Source, s)?;
        self.check_point(Endpoint::Destination, t)?;
        let fs = &self.free;
        let field = CostField::new(fs, coverage);
        // A clear straight segment is optimal when it is all excellent (cost = length).
        if fs.segment_clear(s, t) && field.segment(s, t).1 == 0 {
            return Ok(Path::from_waypoints(vec![s, t]));
        }
        let starts = search::connect(fs, s).ok_or(PlanError::NotConnected {
            which: Endpoint::Source,
            position_m: s,
        })?;
        let goals = search::connect(fs, t).ok_or(PlanError::NotConnected {
            which: Endpoint::Destination,
            position_m: t,
        })?;
        let spec = SearchSpec {
            fs,
            field: &field,
            target_m: t,
            starts: &starts,
            goals: &goals,
        };
        // Any-angle search on true lengths (Lazy Theta*), smoothed under the cost field. Both
        // searches use the same lattice edges, so when this one finds nothing neither would A*.
        let vertices =
            self.with_scratch(|sc| search::theta(&spec, s, sc))
                .ok_or(PlanError::NoPath {
                    source_m: s,
                    destination_m: t,
                })?;
        // Every segment comes from a proven test (distance-field bound or swept sphere with a
        // margin); check with the exact test anyway and fall back to the lattice search (all
        // edges swept-sphere checked) should it ever fail.
        let verified = |path: Path| -> Option<Path> {
            let ok = path
                .waypoints_m
                .windows(2)
                .all(|w| fs.segment_clear(w[0], w[1]));
            if !ok {
                // The designed fallback (it happens a few times per thousand plans): not a
                // warning.
                tracing::debug!(
                    source_m = ?s,
                    destination_m = ?t,
                    "any-angle path failed the exact clearance check; using the lattice search"
                );
            }
            ok.then_some(path)
        };
        // The shortest path: the any-angle route and the lattice A* route on plain lengths (the
        // two searches may pass different sides of a building, or different ways over it), each
        // smoothed and polished; the shorter wins.
        let plain = CostField::new(fs, None);
        let plain_spec = SearchSpec {
            field: &plain,
            ..spec
        };
        let taut = |vertices: &[u32]| -> Option<Path> {
            let smoothed = self.finish(&plain, s, vertices, t);
            verified(Path::from_waypoints(smooth::polish(
                fs,
                &plain,
                smoothed.waypoints_m,
            )))
        };
        let lattice = self.with_scratch(|sc| search::astar(&plain_spec, sc));
        let shortest = [Some(vertices.as_slice()), lattice.as_deref()]
            .into_iter()
            .flatten()
            .filter_map(taut)
            .reduce(|best, next| {
                if next.length_m < best.length_m {
                    next
                } else {
                    best
                }
            });
        if coverage.is_none()
            && let Some(path) = shortest
        {
            return Ok(path);
        }
        // With coverage: the any-angle vertices smoothed under the cost field, the lattice A* on
        // the cost, and the shortest path itself; the cheapest under the cost field wins (so the
        // coverage-aware path never costs more than the shortest one).
        let mut candidates = Vec::with_capacity(3);
        if coverage.is_some() {
            candidates.extend(verified(self.finish(&field, s, &vertices, t)));
        }
        candidates.extend(
            self.with_scratch(|sc| search::astar(&spec, sc))
                .map(|vertices| self.finish(&field, s, &vertices, t)),
        );
        candidates.extend(shortest);
        let cost = |p: &Path| -> f64 {
            p.waypoints_m
                .windows(2)
                .map(|w| field.segment(w[0], w[1]).0)
                .sum()
        };
        candidates
            .into_iter()
            .map(|p| (cost(&p), p))
            .reduce(|best, next| if next.0 < best.0 { next } else { best })
            .map(|(_, p)| p)
            .ok_or(PlanError::NoPath {
                source_m: s,
                destination_m: t,
            })
    }

    /// Runs `f` with a search buffer from the pool (a fresh one when the pool is empty).
    fn with_scratch<R>(&self, f: impl FnOnce(&mut Scratch) -> R) -> R {
        let mut scratch = self
            .scratch
            .lock()
            .ok()
            .and_then(|mut pool| pool.pop())
            .unwrap_or_default();
        let out = f(&mut scratch);
        if let Ok(mut pool) = self.scratch.lock() {
            pool.push(scratch);
        }
        out
    }

    /// Source, lattice vertices, destination → smoothed path.
    fn finish(&self, field: &CostField, s: Point, vertices: &[u32], t: Point) -> Path {
        let fs = &self.free;
        let mut raw = Vec::with_capacity(vertices.len() + 2);
        raw.push(s);
        raw.extend(vertices.iter().map(|&v| fs.centre_m(v)));
        raw.push(t);
        Path::from_waypoints(smooth::smooth(fs, field, raw))
    }
}

#[cfg(test)]
mod tests;
