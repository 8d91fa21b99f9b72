//! `Policy`: a trained DUPAC or base-method policy (`policy.bin` or `checkpoint.bin` of `dupac
//! train`) run on observations, and `fly`: one held-out pair flown with it exactly as `dupac fly`
//! flies it.

use crate::arrays::{Real, view1, view2};
use crate::errors::{runtime_error, value_error};
use crate::scenario::{Scenario, Split};
use dupac_actor::rollout::fly_policy;
use dupac_common::msg::EpisodeSummary;
use dupac_common::policy::{PolicyWeights, Scratch};
use dupac_eval::flight::policy_env;
use dupac_learner::checkpoint::load_policy;
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::path::PathBuf;

/// A trained policy, acted deterministically (the mean move, the arg-max site) as `dupac fly` and
/// `dupac eval` fly it. Build the scenario with `Scenario(policy=path)` so that its environments
/// give the observation the policy was trained with.
#[pyclass(module = "dupac._dupac", frozen)]
pub struct Policy {
    weights: PolicyWeights,
    path: PathBuf,
}

impl Policy {
    fn check_obs(&self, n: usize) -> PyResult<()> {
        if n != self.weights.obs_dim {
            return Err(value_error(format!(
                "{}: the policy expects {} observations, got {n}",
                self.path.display(),
                self.weights.obs_dim
            )));
        }
        Ok(())
    }
}

#[pymethods]
impl Policy {
    /// Loads `policy.bin` (or a checkpoint's policy); a file of another format is refused with
    /// a message naming both formats.
    #[new]
    fn new(path: PathBuf) -> PyResult<Policy> {
        let weights = load_policy(&path).map_err(value_error)?;
        Ok(Policy { weights, path })
    }

    /// Length of the observation the policy takes.
    #[getter]
    fn obs_dim(&self) -> usize {
        self.weights.obs_dim
    }

    /// M when the policy chooses the site (DUPAC), 0 for the base method (A3 chooses it).
    #[getter]
    fn n_sites(&self) -> usize {
        self.weights.n_sites
    }

    /// The learner's weight version (updates) the policy was exported at.
    #[getter]
    fn version(&self) -> u64 {
        self.weights.version
    }

    /// The deterministic action for one raw observation (float32, `obs_dim`): the move (3,)
    /// float32 (the mean, before the environment bounds it) and the site (int; 0 for the base
    /// method).
    fn act<'py>(
        &self,
        py: Python<'py>,
        obs: Real<'py, f32>,
    ) -> PyResult<(Bound<'py, PyArray1<f32>>, u32)> {
        let o = view1(&obs, "obs", None)?.to_vec();
        self.check_obs(o.len())?;
        let a = self.weights.act_deterministic(&o, &mut Scratch::default());
        Ok((PyArray1::from_slice(py, &a.move_raw), a.site))
    }

    /// [`Policy::act`] for a batch: `obs` (N, obs_dim) float32 → moves (N, 3) float32, sites (N,)
    /// int64, the GIL released.
    #[allow(clippy::type_complexity)]
    fn act_batch<'py>(
        &self,
        py: Python<'py>,
        obs: Real<'py, f32>,
    ) -> PyResult<(Bound<'py, PyArray2<f32>>, Bound<'py, PyArray1<i64>>)> {
        let v = view2(&obs, "obs", None)?;
        self.check_obs(v.ncols())?;
        let rows: Vec<Vec<f32>> = v.rows().into_iter().map(|r| r.to_vec()).collect();
        let w = &self.weights;
        let (moves, sites) = py.detach(|| {
            let mut s = Scratch::default();
            let mut moves = Vec::with_capacity(rows.len() * 3);
            let mut sites = Vec::with_capacity(rows.len());
            for r in &rows {
                let a = w.act_deterministic(r, &mut s);
                moves.extend_from_slice(&a.move_raw);
                sites.push(i64::from(a.site));
            }
            (moves, sites)
        });
        Ok((
            Array2::from_shape_vec((rows.len(), 3), moves)
                .map_err(value_error)?
                .into_pyarray(py),
            Array1::from_vec(sites).into_pyarray(py),
        ))
    }

    /// The critic's value of one raw observation (in the learner's scaled reward units).
    fn value(&self, obs: Real<'_, f32>) -> PyResult<f32> {
        let o = view1(&obs, "obs", None)?.to_vec();
        self.check_obs(o.len())?;
        Ok(self.weights.value(&o, &mut Scratch::default()))
    }

    fn __repr__(&self) -> String {
        format!(
            "Policy({:?}, obs_dim={}, n_sites={}, version={})",
            self.path.display().to_string(),
            self.weights.obs_dim,
            self.weights.n_sites,
            self.weights.version
        )
    }
}

/// Flies pair `pair` of `split` with `policy` deterministically, as `dupac fly` does (with
/// `env.site_every_step`, the site of every step from the site head): returns `(summary, steps)`,
/// the episode's summary (a dict: outcome, return, length, distance, RSRP and handover figures)
/// and every MDP step's record (a dict of arrays, as `Env.last_steps`). The scenario must give the
/// policy's observation (`Scenario(policy=path)`).
#[pyfunction]
#[pyo3(signature = (scenario, policy, pair=0, split="eval"))]
pub fn fly<'py>(
    py: Python<'py>,
    scenario: &Scenario,
    policy: &Policy,
    pair: usize,
    split: &str,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyDict>)> {
    let split = Split::parse(split)?;
    let sh = scenario.shared.clone();
    let w = &policy.weights;
    let (summary, steps) = py.detach(|| -> PyResult<_> {
        let pairs = sh.pairs(split)?;
        let p = pairs.get(pair).ok_or_else(|| {
            value_error(format!("pair {pair}: the split has {} pairs", pairs.len()))
        })?;
        let mut env = policy_env(&sh.cfg, &sh.world, &sh.rsrp, w).map_err(|e| {
            value_error(format!(
                "{}: {e}: build the scenario with Scenario(policy=…)",
                policy.path.display()
            ))
        })?;
        fly_policy(&mut env, w, p.id, p.episode(false, split.field()), p.id).map_err(runtime_error)
    })?;
    Ok((
        summary_dict(py, &summary)?,
        crate::env::steps_dict(py, &steps)?,
    ))
}

/// An episode's summary as a dict (its fields, the outcome by name).
pub(crate) fn summary_dict<'py>(
    py: Python<'py>,
    summary: &EpisodeSummary,
) -> PyResult<Bound<'py, PyAny>> {
    let mut json = serde_json::to_value(summary).map_err(runtime_error)?;
    if let Some(o) = json.as_object_mut() {
        o.insert("outcome".into(), summary.outcome.name().into());
    }
    py.import("json")?
        .call_method1("loads", (json.to_string(),))
}
