//! One environment of a scenario with the pairs it draws from and its own RNG, as `Env` and
//! each environment of `VecEnv` hold it: episodes drawn exactly as the trainer's rollout workers
//! draw them ([`dupac_actor::rollout::Worker`]): a pair uniformly from the pool, flown either way.

use crate::errors::{runtime_error, value_error};
use crate::scenario::{Shared, Split};
use dupac_actor::env::{Action, Env as RustEnv, EnvError, Step};
use dupac_actor::pairs::Pair;
use dupac_common::geometry::Vector;
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;
use pyo3::prelude::*;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

/// `outcome` as a code for arrays: −1 none (the episode goes on), 0 goal, 1 collision, 2 out of
/// bounds, 3 time limit.
pub(crate) fn outcome_code(o: Option<Outcome>) -> i8 {
    match o {
        None => -1,
        Some(Outcome::Goal) => 0,
        Some(Outcome::Collision) => 1,
        Some(Outcome::OutOfBounds) => 2,
        Some(Outcome::TimeLimit) => 3,
    }
}

/// An environment's refusal (a bad action, an episode that cannot start) as a `ValueError`.
pub(crate) fn env_error(e: EnvError) -> PyErr {
    value_error(e)
}

/// One environment with the pairs it draws from and its own RNG.
pub(crate) struct Core {
    pub(crate) env: RustEnv,
    pub(crate) shared: Arc<Shared>,
    pub(crate) pairs: Arc<Vec<Pair>>,
    split: Split,
    rng: ChaCha8Rng,
    pub(crate) pair_id: u64,
    /// The episode's rewards summed so far, and its decisions.
    pub(crate) episode_return: f64,
    pub(crate) episode_length: u32,
}

impl Core {
    pub(crate) fn new(shared: Arc<Shared>, split: Split, seed: u64) -> PyResult<Core> {
        let env = RustEnv::new(&shared.cfg, shared.world.clone(), shared.rsrp.clone())
            .map_err(env_error)?;
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
            episode_return: 0.0,
            episode_length: 0,
        })
    }

    /// Starts an episode: with `seed`, the RNG is seeded first; `pair` picks the pair (index in
    /// the split) and `reversed` its direction, else both are drawn as the trainer draws them.
    pub(crate) fn reset(
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
        self.episode_return = 0.0;
        self.episode_length = 0;
        // A held-out pair's episode is seeded by its id (its field and measurement errors), as
        // evaluation seeds it.
        let reset_seed = match self.split {
            Split::Train => reset_seed,
            Split::Eval => p.id,
        };
        self.env
            .reset(
                reset_seed,
                p.episode(reversed.unwrap_or(drawn_reversed), self.split.field()),
            )
            .map_err(env_error)?;
        Ok(())
    }

    pub(crate) fn act(&mut self, move_: [f64; 3], site: i64) -> PyResult<Step> {
        let site = u16::try_from(site)
            .map_err(|_| value_error(format!("action site {site} is out of range")))?;
        let s = self
            .env
            .act(&Action {
                move_: Vector::new(move_[0], move_[1], move_[2]),
                site: SiteId(site),
            })
            .map_err(env_error)?;
        self.episode_return += s.reward;
        self.episode_length = self.episode_length.saturating_add(1);
        Ok(s)
    }
}
