//! `Env` and `VecEnv`: the UAV environment (spec/env.md) one at a time and N at a time. A step
//! is one decision of a policy ([`dupac_actor::env::Env::act`]): the move applied for
//! `env.action_repeat` MDP steps with the site held, the rewards summed. Episodes are drawn from
//! a scenario's pairs exactly as the trainer's rollout workers draw them
//! ([`dupac_actor::rollout::Worker`]): a pair uniformly from the pool, flown either way.

use crate::scenario::{Scenario, Shared, Split};
use crate::{runtime_error, value_error};
use dupac_actor::env::{Action, Env as RustEnv, EnvError, Step};
use dupac_actor::pairs::Pair;
use dupac_actor::record::StepInfo;
use dupac_common::geometry::Vector;
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

/// `outcome` as a code for arrays: −1 none (the episode goes on), 0 goal, 1 collision, 2 out of
/// bounds, 3 time limit.
fn outcome_code(o: Option<Outcome>) -> i8 {
    match o {
        None => -1,
        Some(Outcome::Goal) => 0,
        Some(Outcome::Collision) => 1,
        Some(Outcome::OutOfBounds) => 2,
        Some(Outcome::TimeLimit) => 3,
    }
}

fn env_error(e: EnvError) -> PyErr {
    value_error(e)
}

/// One environment with the pairs it draws from and its own RNG.
struct Core {
    env: RustEnv,
    shared: Arc<Shared>,
    pairs: Arc<Vec<Pair>>,
    split: Split,
    rng: ChaCha8Rng,
    pair_id: u64,
}

impl Core {
    fn new(shared: Arc<Shared>, split: Split, seed: u64) -> PyResult<Core> {
        let mut env = RustEnv::new(&shared.cfg, shared.world.clone(), shared.rsrp.clone())
            .map_err(env_error)?;
        // The held-out pairs fly in the validation's shadow-fading realisations, as `dupac fly`
        // and `dupac eval` fly them.
        if split == Split::Eval {
            env.set_field_split(dupac_radio::channel::FieldSplit::Eval);
        }
        let pairs = shared.pairs(split)?;
        if pairs.is_empty() {
            return Err(runtime_error("the scenario has no pairs to fly"));
        }
        Ok(Core {
            env,
            shared,
            pairs,
            split,
            rng: ChaCha8Rng::seed_from_u64(seed),
            pair_id: 0,
        })
    }

    /// Starts an episode: with `seed`, the RNG is seeded first; `pair` picks the pair (index in
    /// the split) and `reversed` its direction, else both are drawn as the trainer draws them.
    fn reset(
        &mut self,
        seed: Option<u64>,
        pair: Option<usize>,
        reversed: Option<bool>,
    ) -> PyResult<()> {
        if let Some(s) = seed {
            self.rng = ChaCha8Rng::seed_from_u64(s);
        }
        let k = match pair {
            Some(k) if k >= self.pairs.len() => {
                return Err(value_error(format!(
                    "pair {k}: the {} split has {} pairs",
                    match self.split {
                        Split::Train => "train",
                        Split::Eval => "eval",
                    },
                    self.pairs.len()
                )));
            }
            Some(k) => k,
            None => self.rng.random_range(0..self.pairs.len()),
        };
        // The same draws in the same order as the rollout worker's, whatever was given.
        let drawn_reversed = !self.rng.random::<bool>();
        let reset_seed = self.rng.random::<u64>();
        let p = &self.pairs[k];
        self.pair_id = p.id;
        // A held-out pair's episode is seeded by its id (its field and measurement errors), as
        // evaluation seeds it.
        let reset_seed = match self.split {
            Split::Train => reset_seed,
            Split::Eval => p.id,
        };
        self.env
            .reset(reset_seed, p.episode(reversed.unwrap_or(drawn_reversed)))
            .map_err(env_error)?;
        Ok(())
    }

    fn act(&mut self, move_: [f64; 3], site: i64) -> PyResult<Step> {
        let site = u16::try_from(site)
            .map_err(|_| value_error(format!("action site {site} is out of range")))?;
        self.env
            .act(&Action {
                move_: Vector::new(move_[0], move_[1], move_[2]),
                site: SiteId(site),
            })
            .map_err(env_error)
    }
}

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
        r#move: PyReadonlyArray1<'py, f64>,
        site: i64,
    ) -> PyResult<(
        Bound<'py, PyArray1<f32>>,
        f64,
        bool,
        bool,
        Bound<'py, PyDict>,
    )> {
        let m = move_of(r#move.as_slice()?)?;
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

/// N environments of one scenario stepped together in Rust, the GIL released: arrays in, arrays
/// out. An environment whose episode ends is reset at once (its next episode drawn from its own
/// RNG); its last observation is returned in `final_obs`.
#[pyclass(module = "dupac._dupac")]
pub struct VecEnv {
    cores: Vec<Core>,
    obs_dim: usize,
}

type StepArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<i8>>,
);

#[pymethods]
impl VecEnv {
    /// `num_envs` environments of `scenario` over the pairs of `split`; environment i's RNG is
    /// seeded with `seed + i`.
    #[new]
    #[pyo3(signature = (scenario, num_envs, split="train", seed=0))]
    fn new(
        py: Python<'_>,
        scenario: &Scenario,
        num_envs: usize,
        split: &str,
        seed: u64,
    ) -> PyResult<VecEnv> {
        if num_envs == 0 || num_envs > 65_536 {
            return Err(value_error(format!(
                "num_envs = {num_envs}: expected 1 … 65536"
            )));
        }
        let split = Split::parse(split)?;
        let shared = scenario.shared.clone();
        let cores = py.detach(move || {
            (0..num_envs)
                .map(|i| Core::new(shared.clone(), split, seed.wrapping_add(i as u64)))
                .collect::<PyResult<Vec<_>>>()
        })?;
        let obs_dim = cores[0].env.layout().len();
        Ok(VecEnv { cores, obs_dim })
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.cores.len()
    }

    #[getter]
    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// Resets every environment (with `seed`, environment i's RNG is seeded with `seed + i`
    /// first) and returns the observations (N, obs_dim) float32.
    #[pyo3(signature = (seed=None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: Option<u64>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let d = self.obs_dim;
        let cores = &mut self.cores;
        let obs = py.detach(|| -> PyResult<Vec<f32>> {
            let mut obs = Vec::with_capacity(cores.len() * d);
            for (i, c) in cores.iter_mut().enumerate() {
                c.reset(seed.map(|s| s.wrapping_add(i as u64)), None, None)?;
                obs.extend_from_slice(c.env.observation());
            }
            Ok(obs)
        })?;
        Ok(Array2::from_shape_vec((self.cores.len(), d), obs)
            .map_err(value_error)?
            .into_pyarray(py))
    }

    /// `moves.shape[0]` decisions in every environment in one call, as that many calls of
    /// [`VecEnv::step`] would make them (`moves` (T, N, 3), `sites` (T, N)); returns the summed
    /// reward and the number of episodes that ended. For benchmarks: the same work without
    /// Python between the decisions (python/benches/vec_env.py).
    fn _step_many(
        &mut self,
        py: Python<'_>,
        moves: numpy::PyReadonlyArray3<'_, f64>,
        sites: PyReadonlyArray2<'_, i64>,
    ) -> PyResult<(f64, u64)> {
        let n = self.cores.len();
        let (mv, st) = (moves.as_array(), sites.as_array());
        let t = mv.dim().0;
        if mv.dim() != (t, n, 3) || st.dim() != (t, n) {
            return Err(value_error(format!(
                "expected moves of shape (T, {n}, 3) and sites of shape (T, {n}), got {:?} and {:?}",
                mv.dim(),
                st.dim()
            )));
        }
        let cores = &mut self.cores;
        py.detach(move || -> PyResult<(f64, u64)> {
            let (mut total, mut ended) = (0.0, 0u64);
            for k in 0..t {
                for (i, c) in cores.iter_mut().enumerate() {
                    let s = c.act([mv[[k, i, 0]], mv[[k, i, 1]], mv[[k, i, 2]]], st[[k, i]])?;
                    total += s.reward;
                    if s.terminated || s.truncated {
                        ended += 1;
                        c.reset(None, None, None)?;
                    }
                }
            }
            Ok((total, ended))
        })
    }

    /// One decision in every environment: `moves` (N, 3) float64, `sites` (N,) int64. Returns
    /// `(obs, reward, terminated, truncated, final_obs, outcome)`: the observations (N, obs_dim)
    /// after any reset, the summed rewards, the ends, the last observation of each episode that
    /// ended (zeros elsewhere), and how it ended (−1 none, 0 goal, 1 collision, 2 out of bounds,
    /// 3 time limit).
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        moves: PyReadonlyArray2<'py, f64>,
        sites: PyReadonlyArray1<'py, i64>,
    ) -> PyResult<StepArrays<'py>> {
        let n = self.cores.len();
        let (mv, st) = (moves.as_array(), sites.as_array());
        if mv.dim() != (n, 3) || st.len() != n {
            return Err(value_error(format!(
                "expected moves of shape ({n}, 3) and sites of shape ({n},), got {:?} and ({},)",
                mv.dim(),
                st.len()
            )));
        }
        let mv: Vec<[f64; 3]> = mv.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
        let st: Vec<i64> = st.to_vec();
        let d = self.obs_dim;
        let cores = &mut self.cores;
        let out = py.detach(move || -> PyResult<_> {
            let mut obs = vec![0f32; n * d];
            let mut fin = vec![0f32; n * d];
            let mut rew = vec![0f64; n];
            let mut term = vec![false; n];
            let mut trunc = vec![false; n];
            let mut outc = vec![-1i8; n];
            for (i, c) in cores.iter_mut().enumerate() {
                let s = c.act(mv[i], st[i])?;
                rew[i] = s.reward;
                term[i] = s.terminated;
                trunc[i] = s.truncated;
                let row = i * d..(i + 1) * d;
                if s.terminated || s.truncated {
                    outc[i] = outcome_code(Some(s.info.outcome.unwrap_or(Outcome::TimeLimit)));
                    fin[row.clone()].copy_from_slice(c.env.observation());
                    c.reset(None, None, None)?;
                }
                obs[row].copy_from_slice(c.env.observation());
            }
            Ok((obs, rew, term, trunc, fin, outc))
        })?;
        let (obs, rew, term, trunc, fin, outc) = out;
        Ok((
            Array2::from_shape_vec((n, d), obs)
                .map_err(value_error)?
                .into_pyarray(py),
            rew.into_pyarray(py),
            term.into_pyarray(py),
            trunc.into_pyarray(py),
            Array2::from_shape_vec((n, d), fin)
                .map_err(value_error)?
                .into_pyarray(py),
            outc.into_pyarray(py),
        ))
    }
}
