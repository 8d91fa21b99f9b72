//! `Planner`: the scenario's planners on NumPy arrays, the shortest flyable path and the
//! coverage-aware path (docs/env.md "Planners"), and `fly_path`, a planned path flown by the
//! scripted pilot with the A3 rule choosing the site (what `dupac eval` reports for the planners).

use crate::arrays::{Real, view1};
use crate::errors::{runtime_error, value_error};
use crate::policy::summary_dict;
use crate::scenario::{Scenario, Shared, Split};
use dupac_actor::planner::{Endpoint, Path, Planner as RustPlanner};
use dupac_common::geometry::Point;
use dupac_eval::flight::fly_path_with_a3;
use dupac_radio::class::RsrpThresholds;
use dupac_radio::world::RadioWorld;
use numpy::IntoPyArray;
use numpy::ndarray::Array2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;

self_cell::self_cell!(
    /// A planner over the city of a world it keeps alive (the Rust planner borrows the city).
    struct Planned {
        owner: Arc<RadioWorld>,
        #[covariant]
        dependent: RustPlanner,
    }
);

/// The planners of a scenario's city: the free space (`planner.clearance_m` from the buildings,
/// within the altitude band `env.z_min_m`..`env.z_max_m`) and, with `coverage=True`, every
/// lattice point's RSRP class (the coverage-aware planner needs them). Built once; thread-safe.
#[pyclass(module = "dupac._dupac", frozen)]
pub struct Planner {
    planned: Planned,
    shared: Arc<Shared>,
}

/// One point `(3,)` in metres.
fn point(a: &Real<'_, f64>, what: &str) -> PyResult<Point> {
    let v = view1(a, what, Some(3))?;
    Ok(Point::new(v[0], v[1], v[2]))
}

/// A path as `{"waypoints_m": (N, 3) array, "length_m": float}`.
fn path_dict<'py>(py: Python<'py>, p: &Path) -> PyResult<Bound<'py, PyDict>> {
    let flat: Vec<f64> = p
        .waypoints_m
        .iter()
        .flat_map(|w| [w[0], w[1], w[2]])
        .collect();
    let d = PyDict::new(py);
    d.set_item(
        "waypoints_m",
        Array2::from_shape_vec((p.waypoints_m.len(), 3), flat)
            .map_err(runtime_error)?
            .into_pyarray(py),
    )?;
    d.set_item("length_m", p.length_m)?;
    Ok(d)
}

#[pymethods]
impl Planner {
    /// Builds the free space of `scenario`'s city and, with `coverage` (default), the RSRP class
    /// of every lattice point from the scenario's RSRP source and thresholds. The GIL is released
    /// while it works.
    #[new]
    #[pyo3(signature = (scenario, coverage=true))]
    fn new(py: Python<'_>, scenario: &Scenario, coverage: bool) -> Planner {
        let shared = scenario.shared.clone();
        let planned = py.detach(|| {
            Planned::new(shared.world.clone(), |w| {
                let mut p = RustPlanner::new(&w.city, &shared.cfg.env, &shared.cfg.planner);
                if coverage {
                    p.with_coverage(
                        shared.rsrp.as_ref(),
                        RsrpThresholds::from_config(&shared.cfg.radio),
                    );
                }
                p
            })
        });
        Planner { planned, shared }
    }

    /// Whether the coverage classes were computed (`coverage=True`).
    #[getter]
    fn has_coverage(&self) -> bool {
        self.planned.borrow_dependent().has_coverage()
    }

    /// Checks a point as an endpoint: finite, in the area and the band, outside every building
    /// and at least the clearance from them. Raises `ValueError` naming the reason.
    fn check_point(&self, point_m: Real<'_, f64>) -> PyResult<()> {
        let p = point(&point_m, "point_m")?;
        self.planned
            .borrow_dependent()
            .check_point(Endpoint::Source, p)
            .map_err(value_error)
    }

    /// The shortest flyable path from `source_m` to `destination_m` (each `(3,)`, m):
    /// `{"waypoints_m": (N, 3), "length_m": float}`, the endpoints exactly as given.
    fn shortest<'py>(
        &self,
        py: Python<'py>,
        source_m: Real<'_, f64>,
        destination_m: Real<'_, f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (s, d) = (
            point(&source_m, "source_m")?,
            point(&destination_m, "destination_m")?,
        );
        let path = py
            .detach(|| self.planned.borrow_dependent().shortest(s, d))
            .map_err(value_error)?;
        path_dict(py, &path)
    }

    /// The coverage-aware path: the least Σ length · (1 + λ · penalty(class)), with the penalties
    /// `planner.penalty_mediocre` and `planner.penalty_poor` and `lam` λ (default
    /// `planner.lambda`); λ = 0 is the shortest path. Needs `coverage=True`.
    #[pyo3(signature = (source_m, destination_m, lam=None))]
    fn coverage_aware<'py>(
        &self,
        py: Python<'py>,
        source_m: Real<'_, f64>,
        destination_m: Real<'_, f64>,
        lam: Option<f64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let (s, d) = (
            point(&source_m, "source_m")?,
            point(&destination_m, "destination_m")?,
        );
        let lambda = lam.unwrap_or(self.shared.cfg.planner.lambda);
        let path = py
            .detach(|| self.planned.borrow_dependent().coverage_aware(s, d, lambda))
            .map_err(value_error)?;
        path_dict(py, &path)
    }

    fn __repr__(&self) -> String {
        format!(
            "Planner(city={:?}, coverage={})",
            self.shared.world.city.name,
            self.has_coverage()
        )
    }
}

/// Flies `waypoints_m` (`(N, 3)`, m; e.g. a `Planner` path's) from pair `pair` of `split` with
/// the scripted pilot, the A3 rule choosing the site, as `dupac eval` flies the planners:
/// returns `(summary, steps)` as `fly` does. The path should start at the pair's source; the
/// pilot flies to the pair's destination after the last waypoint.
#[pyfunction]
#[pyo3(signature = (scenario, waypoints_m, pair=0, split="eval"))]
pub fn fly_path<'py>(
    py: Python<'py>,
    scenario: &Scenario,
    waypoints_m: Real<'_, f64>,
    pair: usize,
    split: &str,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyDict>)> {
    let split = Split::parse(split)?;
    let w = crate::scenario::points(&waypoints_m, "waypoints_m")?;
    let sh = scenario.shared.clone();
    let flown = py.detach(|| -> PyResult<_> {
        let pairs = sh.pairs(split)?;
        let p = pairs.get(pair).ok_or_else(|| {
            value_error(format!("pair {pair}: the split has {} pairs", pairs.len()))
        })?;
        fly_path_with_a3(&sh.cfg, &sh.world, &sh.rsrp, &w, p, split.field()).map_err(runtime_error)
    })?;
    Ok((
        summary_dict(py, &flown.summary)?,
        crate::env::steps_dict(py, &flown.flight.steps)?,
    ))
}
