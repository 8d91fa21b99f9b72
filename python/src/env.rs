//! `Env`: the UAV environment (spec/env.md) one at a time. A step is one decision of a policy
//! ([`dupac_actor::env::Env::act`]): the move applied for `env.action_repeat` MDP steps with the
//! site held, the rewards summed. Episodes are drawn from a scenario's pairs exactly as the
//! trainer's rollout workers draw them (`env_core.rs`).

use crate::arrays::{Real, view1};
use crate::env_core::{Core, outcome_code};
use crate::errors::value_error;
use crate::scenario::{Scenario, Split};
use dupac_actor::env::Step;
use dupac_actor::record::StepInfo;
use dupac_common::msg::Outcome;
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1};
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn move_of(a: &[f64]) -> PyResult<[f64; 3]> {
    match a {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(value_error(format!(
            "action move: expected 3 values (x, y, z in units of env.max_step_m), got {}",
            a.len()
        ))),
    }
}

/// The records of `steps` as a dict of arrays (one row per MDP step).
pub(crate) fn steps_dict<'py>(py: Python<'py>, steps: &[StepInfo]) -> PyResult<Bound<'py, PyDict>> {
    let d = PyDict::new(py);
    let n = steps.len();
    let col = |f: &dyn Fn(&StepInfo) -> f64| Array1::from_iter(steps.iter().map(f));
    d.set_item(
        "step",
        Array1::from_iter(steps.iter().map(|s| s.step)).into_pyarray(py),
    )?;
    d.set_item(
        "position_m",
        Array2::from_shape_fn((n, 3), |(i, k)| steps[i].position_m[k]).into_pyarray(py),
    )?;
    d.set_item(
        "serving",
        Array1::from_iter(steps.iter().map(|s| i64::from(s.serving.0))).into_pyarray(py),
    )?;
    d.set_item(
        "serving_rsrp_dbm",
        col(&|s| s.serving_rsrp_dbm).into_pyarray(py),
    )?;
    d.set_item(
        "best_site",
        Array1::from_iter(steps.iter().map(|s| i64::from(s.best_site.0))).into_pyarray(py),
    )?;
    d.set_item("best_rsrp_dbm", col(&|s| s.best_rsrp_dbm).into_pyarray(py))?;
    d.set_item(
        "rsrp_class",
        Array1::from_iter(steps.iter().map(|s| s.class.index() as i8)).into_pyarray(py),
    )?;
    for (name, f) in [
        ("los", (|s: &StepInfo| s.los) as fn(&StepInfo) -> bool),
        ("handover", |s| s.handover),
        ("ping_pong", |s| s.ping_pong),
    ] {
        d.set_item(
            name,
            Array1::from_iter(steps.iter().map(f)).into_pyarray(py),
        )?;
    }
    d.set_item("step_length_m", col(&|s| s.step_length_m).into_pyarray(py))?;
    d.set_item(
        "distance_flown_m",
        col(&|s| s.distance_flown_m).into_pyarray(py),
    )?;
    d.set_item(
        "distance_to_goal_m",
        col(&|s| s.distance_to_goal_m).into_pyarray(py),
    )?;
    d.set_item("reward", col(&|s| s.reward).into_pyarray(py))?;
    d.set_item(
        "outcome",
        Array1::from_iter(steps.iter().map(|s| outcome_code(s.outcome))).into_pyarray(py),
    )?;
    Ok(d)
}

/// The info of a decision: its last step's record.
fn info_dict<'py>(py: Python<'py>, s: &Step, pair_id: u64) -> PyResult<Bound<'py, PyDict>> {
    let i = &s.info;
    let d = PyDict::new(py);
    d.set_item("pair_id", pair_id)?;
    d.set_item("outcome", i.outcome.map(Outcome::name))?;
    d.set_item(
        "position_m",
        Array1::from_iter(i.position_m.iter().copied()).into_pyarray(py),
    )?;
    d.set_item("serving", i.serving.0)?;
    d.set_item("serving_rsrp_dbm", i.serving_rsrp_dbm)?;
    d.set_item("best_site", i.best_site.0)?;
    d.set_item("best_rsrp_dbm", i.best_rsrp_dbm)?;
    d.set_item("rsrp_class", i.class.name())?;
    d.set_item("los", i.los)?;
    d.set_item("handover", i.handover)?;
    d.set_item("ping_pong", i.ping_pong)?;
    d.set_item("distance_flown_m", i.distance_flown_m)?;
    d.set_item("distance_to_goal_m", i.distance_to_goal_m)?;
    Ok(d)
}

/// The DUPAC environment (spec/env.md): one UAV flying one pair at a time. `step` takes one
/// decision of a policy; use `dupac.gym.DupacEnv` for the Gymnasium interface.
#[pyclass(module = "dupac._dupac")]
pub struct Env {
    core: Core,
}

#[pymethods]
impl Env {
    /// An environment of `scenario` flying the pairs of `split` (`"train"` or `"eval"`), its RNG
    /// seeded with `seed` (`reset(seed=…)` reseeds it).
    #[new]
    #[pyo3(signature = (scenario, split="train", seed=0))]
    fn new(py: Python<'_>, scenario: &Scenario, split: &str, seed: u64) -> PyResult<Env> {
        let split = Split::parse(split)?;
        let shared = scenario.shared.clone();
        let core = py.detach(move || Core::new(shared, split, seed))?;
        Ok(Env { core })
    }

    /// Length of the observation vector.
    #[getter]
    fn obs_dim(&self) -> usize {
        self.core.env.layout().len()
    }

    /// M, the number of sites (the size of the discrete site action).
    #[getter]
    fn num_sites(&self) -> usize {
        self.core.env.num_sites()
    }

    /// Whether the site is the policy's to choose (`env.association = "learned"`).
    #[getter]
    fn learned_site(&self) -> bool {
        self.core.env.policy_shape().1 > 0
    }

    /// MDP steps per decision (`env.action_repeat`).
    #[getter]
    fn action_repeat(&self) -> u32 {
        self.core.shared.cfg.env.action_repeat.max(1)
    }

    /// The episode's time limit T in MDP steps (spec/env.md; 0 before the first reset).
    #[getter]
    fn time_limit(&self) -> u32 {
        self.core.env.time_limit()
    }

    /// Number of pairs in this environment's split.
    #[getter]
    fn num_pairs(&self) -> usize {
        self.core.pairs.len()
    }

    /// The observation's fields in order: `(name, start, end, meaning)` (`obs[start:end]`).
    fn observation_fields(&self) -> Vec<(String, usize, usize, String)> {
        self.core
            .env
            .layout()
            .fields()
            .iter()
            .map(|f| {
                (
                    f.name.to_string(),
                    f.range.start,
                    f.range.end,
                    f.meaning.to_string(),
                )
            })
            .collect()
    }

    /// Starts an episode and returns its first observation (float32). `seed` reseeds the RNG
    /// first; `pair` (index in the split) and `reversed` choose the episode, else they are drawn.
    #[pyo3(signature = (seed=None, pair=None, reversed=None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: Option<u64>,
        pair: Option<usize>,
        reversed: Option<bool>,
    ) -> PyResult<Bound<'py, PyArray1<f32>>> {
        self.core.reset(seed, pair, reversed)?;
        Ok(PyArray1::from_slice(py, self.core.env.observation()))
    }

    /// One decision: `move` (3 values in units of `env.max_step_m`, bounded per
    /// `env.action_clip`) for `env.action_repeat` steps with `site` serving (ignored unless the
    /// site is learned). Returns `(obs, reward, terminated, truncated, info)`.
    #[pyo3(signature = (r#move, site=0))]
    #[allow(clippy::type_complexity)]
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        r#move: Real<'py, f64>,
        site: i64,
    ) -> PyResult<(
        Bound<'py, PyArray1<f32>>,
        f64,
        bool,
        bool,
        Bound<'py, PyDict>,
    )> {
        let m = move_of(&view1(&r#move, "move", Some(3))?.to_vec())?;
        let s = self.core.act(m, site)?;
        Ok((
            PyArray1::from_slice(py, self.core.env.observation()),
            s.reward,
            s.terminated,
            s.truncated,
            info_dict(py, &s, self.core.pair_id)?,
        ))
    }

    /// Every MDP step of the last decision as a dict of arrays (one row per step): `step`,
    /// `position_m` (k, 3), `serving`, `serving_rsrp_dbm`, `best_site`, `best_rsrp_dbm`,
    /// `rsrp_class` (0 excellent, 1 mediocre, 2 poor), `los`, `handover`, `ping_pong`,
    /// `step_length_m`, `distance_flown_m`, `distance_to_goal_m`, `reward`, `outcome` (−1 none,
    /// 0 goal, 1 collision, 2 out of bounds, 3 time limit).
    fn last_steps<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        steps_dict(py, self.core.env.substeps())
    }

    /// The current observation (float32).
    fn observation<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f32>> {
        PyArray1::from_slice(py, self.core.env.observation())
    }
}
