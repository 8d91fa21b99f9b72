//! `VecEnv`: N environments of one scenario (`env_core.rs`) stepped together in Rust, arrays in and
//! out, the GIL released while Rust steps.

use crate::arrays::{Real, view1, view2};
use crate::env_core::{Core, outcome_code};
use crate::errors::{runtime_error, value_error};
use crate::scenario::{Scenario, Split};
use crate::threads::{MAX_THREADS, Threads};
use dupac_common::msg::Outcome;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::sync::Arc;

/// What one decision left in one environment of a [`VecEnv`] (a row of the step's arrays).
#[derive(Debug, Clone, Copy, Default)]
struct Row {
    reward: f64,
    terminated: bool,
    truncated: bool,
    /// How the episode ended (−1 none: it goes on).
    outcome: i8,
    /// The ended episode's pair, return (summed rewards), length (decisions), distance flown
    /// and distance left to the destination (m); meaningful where `outcome >= 0`.
    pair_id: u64,
    episode_return: f64,
    episode_length: u32,
    distance_flown_m: f64,
    distance_to_goal_m: f64,
}

/// One field of every environment's [`Row`] as a NumPy array.
fn column<'py, T: numpy::Element>(
    py: Python<'py>,
    rows: &[Row],
    f: impl Fn(&Row) -> T,
) -> Bound<'py, PyArray1<T>> {
    rows.iter().map(f).collect::<Vec<T>>().into_pyarray(py)
}

/// One decision of every environment: observations after any reset `[N × obs_dim]`, the last
/// observations of the episodes that ended (zeros elsewhere) and a row per environment.
struct Batch {
    obs: Vec<f32>,
    final_obs: Vec<f32>,
    rows: Vec<Row>,
}

/// One decision in each environment, on `threads`: environment i acts `moves[i]` with
/// `sites[i]`, and is reset from its own RNG when its episode ends. Each environment draws
/// only from its own RNG, so the result does not depend on the number of threads.
fn step_all(
    threads: &Threads,
    cores: &mut [Core],
    moves: &[[f64; 3]],
    sites: &[i64],
    obs_dim: usize,
) -> PyResult<Batch> {
    let n = cores.len();
    let mut b = Batch {
        obs: vec![0f32; n * obs_dim],
        final_obs: vec![0f32; n * obs_dim],
        rows: vec![Row::default(); n],
    };
    let mut work: Vec<_> = cores
        .iter_mut()
        .zip(b.obs.chunks_mut(obs_dim))
        .zip(b.final_obs.chunks_mut(obs_dim))
        .zip(b.rows.iter_mut())
        .zip(moves.iter().zip(sites))
        .collect();
    threads.for_each(&mut work, |((((c, obs), fin), row), (m, site))| {
        let s = c.act(**m, **site)?;
        **row = Row {
            reward: s.reward,
            terminated: s.terminated,
            truncated: s.truncated,
            outcome: -1,
            ..Row::default()
        };
        if s.terminated || s.truncated {
            row.outcome = outcome_code(Some(s.info.outcome.unwrap_or(Outcome::TimeLimit)));
            row.pair_id = c.pair_id;
            row.episode_return = c.episode_return;
            row.episode_length = c.episode_length;
            row.distance_flown_m = s.info.distance_flown_m;
            row.distance_to_goal_m = s.info.distance_to_goal_m;
            fin.copy_from_slice(c.env.observation());
            c.reset(None, None, None)?;
        }
        obs.copy_from_slice(c.env.observation());
        Ok(())
    })?;
    drop(work);
    Ok(b)
}

/// How a [`VecEnv::reset`] treats environment i.
#[derive(Debug, Clone, Copy)]
struct ResetOf {
    reset: bool,
    seed: Option<u64>,
    pair: Option<usize>,
    reversed: Option<bool>,
}

/// The value of a per-environment argument for environment i: absent, one for all, or one each.
fn per_env<T: Copy>(v: &Option<Vec<T>>, i: usize) -> Option<T> {
    match v.as_deref() {
        None | Some([]) => None,
        Some([one]) => Some(*one),
        Some(each) => each.get(i).copied(),
    }
}

/// The values of an optional array argument (a scalar is one value).
fn values<T: numpy::Element + Copy>(a: Option<Real<'_, T>>) -> Option<Vec<T>> {
    a.map(|a| a.as_array().iter().copied().collect())
}

/// Checks that a per-environment argument has 0, 1 or `n` values.
fn check_len<T>(name: &str, v: &Option<Vec<T>>, n: usize) -> PyResult<()> {
    match v {
        Some(v) if v.len() > 1 && v.len() != n => Err(value_error(format!(
            "{name}: {} values for {n} environments (expected one, or one per environment)",
            v.len()
        ))),
        _ => Ok(()),
    }
}

/// N environments of one scenario stepped together in Rust on the calling thread and a pool of
/// others ([`Threads`]), the GIL released: arrays in, arrays out. An environment whose episode ends is reset at once (its next
/// episode drawn from its own RNG); its last observation is returned in `final_obs`.
/// `send`/`recv` split a step in two: the step runs on its own threads while Python does other
/// work.
#[pyclass(module = "dupac._dupac")]
pub struct VecEnv {
    /// The environments; `None` while a step sent with `send` is in flight.
    cores: Option<Vec<Core>>,
    num_envs: usize,
    obs_dim: usize,
    threads: Arc<Threads>,
    /// The step in flight (`send`): its thread returns the environments and the result.
    pending: Option<std::thread::JoinHandle<(Vec<Core>, PyResult<Batch>)>>,
}

type StepArrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyDict>,
);

impl VecEnv {
    fn cores_mut(&mut self) -> PyResult<&mut Vec<Core>> {
        if self.pending.is_some() {
            return Err(runtime_error(
                "a step is in flight: call recv() before stepping or resetting again",
            ));
        }
        self.cores.as_mut().ok_or_else(|| {
            runtime_error("the environments were lost in a failed step: create a new VecEnv")
        })
    }

    /// `moves` (N, 3) and `sites` (N,) as one action per environment, shapes checked.
    fn actions(
        &self,
        moves: &Real<'_, f64>,
        sites: &Real<'_, i64>,
    ) -> PyResult<(Vec<[f64; 3]>, Vec<i64>)> {
        let n = self.num_envs;
        let mv = view2(moves, "moves", Some(3))?;
        let st = view1(sites, "sites", Some(n))?;
        if mv.nrows() != n {
            return Err(value_error(format!(
                "moves: expected an array of shape ({n}, 3), got shape ({}, 3)",
                mv.nrows()
            )));
        }
        Ok((
            mv.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect(),
            st.to_vec(),
        ))
    }

    /// The step's arrays for Python: `(obs, reward, terminated, truncated, final_obs,
    /// final_info)`, `final_info` a dict of arrays (rows where an episode ended).
    fn arrays<'py>(&self, py: Python<'py>, b: Batch) -> PyResult<StepArrays<'py>> {
        let (n, d) = (self.num_envs, self.obs_dim);
        let info = PyDict::new(py);
        info.set_item("outcome", column(py, &b.rows, |r| r.outcome))?;
        info.set_item("pair_id", column(py, &b.rows, |r| r.pair_id))?;
        info.set_item("episode_return", column(py, &b.rows, |r| r.episode_return))?;
        info.set_item("episode_length", column(py, &b.rows, |r| r.episode_length))?;
        info.set_item(
            "distance_flown_m",
            column(py, &b.rows, |r| r.distance_flown_m),
        )?;
        info.set_item(
            "distance_to_goal_m",
            column(py, &b.rows, |r| r.distance_to_goal_m),
        )?;
        Ok((
            Array2::from_shape_vec((n, d), b.obs)
                .map_err(value_error)?
                .into_pyarray(py),
            column(py, &b.rows, |r| r.reward),
            column(py, &b.rows, |r| r.terminated),
            column(py, &b.rows, |r| r.truncated),
            Array2::from_shape_vec((n, d), b.final_obs)
                .map_err(value_error)?
                .into_pyarray(py),
            info,
        ))
    }
}

#[pymethods]
impl VecEnv {
    /// `num_envs` environments of `scenario` over the pairs of `split`; environment i's RNG is
    /// seeded with `seed + i`. They are stepped on `num_threads` threads (0: the default,
    /// `RAYON_NUM_THREADS` or one per core).
    #[new]
    #[pyo3(signature = (scenario, num_envs, split="train", seed=0, num_threads=0))]
    fn new(
        py: Python<'_>,
        scenario: &Scenario,
        num_envs: usize,
        split: &str,
        seed: u64,
        num_threads: usize,
    ) -> PyResult<VecEnv> {
        if num_envs == 0 || num_envs > 65_536 {
            return Err(value_error(format!(
                "num_envs = {num_envs}: expected 1 … 65536"
            )));
        }
        if num_threads > MAX_THREADS {
            return Err(value_error(format!(
                "num_threads = {num_threads}: expected 0 (the default) … {MAX_THREADS}"
            )));
        }
        let split = Split::parse(split)?;
        let shared = scenario.shared.clone();
        let threads = Threads::new(num_threads)?;
        let cores = py.detach(|| {
            let mut made: Vec<(usize, Option<Core>)> = (0..num_envs).map(|i| (i, None)).collect();
            threads.for_each(&mut made, |(i, c)| {
                *c = Some(Core::new(
                    shared.clone(),
                    split,
                    seed.wrapping_add(*i as u64),
                )?);
                Ok(())
            })?;
            Ok::<_, PyErr>(made.into_iter().filter_map(|(_, c)| c).collect::<Vec<_>>())
        })?;
        let obs_dim = cores[0].env.layout().len();
        Ok(VecEnv {
            cores: Some(cores),
            num_envs,
            obs_dim,
            threads: Arc::new(threads),
            pending: None,
        })
    }

    #[getter]
    fn num_envs(&self) -> usize {
        self.num_envs
    }

    #[getter]
    fn obs_dim(&self) -> usize {
        self.obs_dim
    }

    /// Threads the environments are stepped on.
    #[getter]
    fn num_threads(&self) -> usize {
        self.threads.count()
    }

    /// Resets the environments and returns the observations (N, obs_dim) float32 (of every
    /// environment; those not reset keep theirs). Each argument is absent, one value for all, or
    /// one per environment: `seed` (environment i's RNG is seeded with `seed + i` for one value,
    /// with its own for one each), `pair` (index in the split; −1 or absent: drawn), `reversed`
    /// (−1 or absent: drawn, 0 forward, 1 reversed), `mask` (only these environments reset).
    #[pyo3(signature = (seed=None, pair=None, reversed=None, mask=None))]
    fn reset<'py>(
        &mut self,
        py: Python<'py>,
        seed: Option<Real<'py, u64>>,
        pair: Option<Real<'py, i64>>,
        reversed: Option<Real<'py, i8>>,
        mask: Option<Real<'py, bool>>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (n, d) = (self.num_envs, self.obs_dim);
        let (seed, pair) = (values(seed), values(pair));
        let (reversed, mask) = (values(reversed), values(mask));
        check_len("seed", &seed, n)?;
        check_len("pair", &pair, n)?;
        check_len("reversed", &reversed, n)?;
        check_len("mask", &mask, n)?;
        let one_seed = seed.as_ref().is_some_and(|s| s.len() == 1);
        let of: Vec<ResetOf> = (0..n)
            .map(|i| ResetOf {
                reset: per_env(&mask, i).unwrap_or(true),
                seed: per_env(&seed, i).map(|s| {
                    if one_seed {
                        s.wrapping_add(i as u64)
                    } else {
                        s
                    }
                }),
                pair: per_env(&pair, i).and_then(|k| usize::try_from(k).ok()),
                reversed: per_env(&reversed, i).and_then(|r| (r >= 0).then_some(r > 0)),
            })
            .collect();
        let threads = self.threads.clone();
        let cores = self.cores_mut()?;
        let obs = py.detach(|| -> PyResult<Vec<f32>> {
            let mut obs = vec![0f32; n * d];
            let mut work: Vec<_> = cores.iter_mut().zip(obs.chunks_mut(d)).zip(&of).collect();
            threads.for_each(&mut work, |((c, row), r)| {
                if r.reset {
                    c.reset(r.seed, r.pair, r.reversed)?;
                }
                row.copy_from_slice(c.env.observation());
                Ok(())
            })?;
            drop(work);
            Ok(obs)
        })?;
        Ok(Array2::from_shape_vec((n, d), obs)
            .map_err(value_error)?
            .into_pyarray(py))
    }

    /// `moves.shape[0]` decisions in every environment in one call, as that many calls of
    /// [`VecEnv::step`] would make them, in the same order (`moves` (T, N, 3), `sites` (T, N)),
    /// on the pool's threads; returns the summed reward and the number of episodes that ended. For benchmarks:
    /// the same work without Python between the decisions (python/benches/vec_env.py).
    fn _step_many(
        &mut self,
        py: Python<'_>,
        moves: Real<'_, f64>,
        sites: Real<'_, i64>,
    ) -> PyResult<(f64, u64)> {
        let n = self.num_envs;
        let mv = moves
            .as_array()
            .into_dimensionality::<numpy::ndarray::Ix3>()
            .map_err(value_error)?;
        let st = view2(&sites, "sites", Some(n))?;
        let t = mv.dim().0;
        if mv.dim() != (t, n, 3) || st.dim() != (t, n) {
            return Err(value_error(format!(
                "expected moves of shape (T, {n}, 3) and sites of shape (T, {n}), got {:?} and {:?}",
                mv.dim(),
                st.dim()
            )));
        }
        let threads = self.threads.clone();
        let cores = self.cores_mut()?;
        py.detach(move || -> PyResult<(f64, u64)> {
            let mut rows: Vec<(usize, &mut Core, f64, u64)> = cores
                .iter_mut()
                .enumerate()
                .map(|(i, c)| (i, c, 0.0, 0))
                .collect();
            for k in 0..t {
                threads.for_each(&mut rows, |(i, c, total, ended)| {
                    let s = c.act(
                        [mv[[k, *i, 0]], mv[[k, *i, 1]], mv[[k, *i, 2]]],
                        st[[k, *i]],
                    )?;
                    *total += s.reward;
                    if s.terminated || s.truncated {
                        *ended += 1;
                        c.reset(None, None, None)?;
                    }
                    Ok(())
                })?;
            }
            Ok(rows
                .iter()
                .fold((0.0, 0), |(r, e), row| (r + row.2, e + row.3)))
        })
    }

    /// One decision in every environment: `moves` (N, 3) float64, `sites` (N,) int64. Returns
    /// `(obs, reward, terminated, truncated, final_obs, final_info)`: the observations
    /// (N, obs_dim) after any reset, the summed rewards, the ends, the last observation of each
    /// episode that ended (zeros elsewhere), and a dict of arrays about the episodes that ended
    /// (`outcome`: −1 none, 0 goal, 1 collision, 2 out of bounds, 3 time limit; `pair_id`,
    /// `episode_return`, `episode_length` in decisions, `distance_flown_m`,
    /// `distance_to_goal_m`, meaningful where `outcome >= 0`).
    fn step<'py>(
        &mut self,
        py: Python<'py>,
        moves: Real<'py, f64>,
        sites: Real<'py, i64>,
    ) -> PyResult<StepArrays<'py>> {
        let (mv, st) = self.actions(&moves, &sites)?;
        let (threads, d) = (self.threads.clone(), self.obs_dim);
        let cores = self.cores_mut()?;
        let b = py.detach(move || step_all(&threads, cores, &mv, &st, d))?;
        self.arrays(py, b)
    }

    /// Starts one decision in every environment (as [`VecEnv::step`]) and returns at once: the
    /// step runs on the pool's threads while Python goes on; [`VecEnv::recv`] returns its
    /// result. Stepping or resetting before `recv` is an error.
    fn send(&mut self, moves: Real<'_, f64>, sites: Real<'_, i64>) -> PyResult<()> {
        let (mv, st) = self.actions(&moves, &sites)?;
        self.cores_mut()?;
        let Some(mut cores) = self.cores.take() else {
            return Err(runtime_error("no environments"));
        };
        let (threads, d) = (self.threads.clone(), self.obs_dim);
        let handle = std::thread::Builder::new()
            .name("dupac-vecenv-send".into())
            .spawn(move || {
                let r = step_all(&threads, &mut cores, &mv, &st, d);
                (cores, r)
            })
            .map_err(runtime_error)?;
        self.pending = Some(handle);
        Ok(())
    }

    /// The result of the step started by [`VecEnv::send`] (waiting for it with the GIL
    /// released), as [`VecEnv::step`] returns it.
    fn recv<'py>(&mut self, py: Python<'py>) -> PyResult<StepArrays<'py>> {
        let rx = self
            .pending
            .take()
            .ok_or_else(|| runtime_error("recv() without a send(): nothing in flight"))?;
        let (cores, r) = py.detach(move || rx.join()).map_err(|_| {
            runtime_error(
                "the step in flight failed: the environments are lost; create a new VecEnv",
            )
        })?;
        self.cores = Some(cores);
        let b = r?;
        self.arrays(py, b)
    }
}
