//! Rollouts: one [`Worker`] owns an environment, its RNG and the episode in progress, and steps
//! it with an exported policy ([`PolicyWeights`], no burn), recording what PPO needs. Workers
//! are independent, so many run on worker threads; a worker's randomness comes only from its own
//! seeded RNG, so a rollout is reproducible whatever the thread count (EnvPool's rule).
//! Episode summaries come from [`crate::metrics::EpisodeAccumulator`].

use crate::env::{Action, Env, EnvError, Episode, Step};
use crate::metrics::EpisodeAccumulator;
use crate::pairs::Pair;
use crate::record::StepInfo;
use dupac_common::geometry::Vector;
use dupac_common::ids::SiteId;
use dupac_common::msg::{EnvTrajectory, EpisodeSummary, Outcome};
use dupac_common::policy::{
    ActionSample, MOVE_DIM, PolicyWeights, Scratch, argmax, sample_categorical,
};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

/// Errors of a worker.
#[derive(Debug, thiserror::Error)]
pub enum RolloutError {
    #[error(transparent)]
    Env(#[from] EnvError),
    #[error("the episode pool is empty")]
    EmptyPool,
    #[error("the policy expects observations of {policy}, the environment gives {env}")]
    ObsMismatch { policy: usize, env: usize },
    #[error("the policy has {policy} site logits, the scenario {env} sites")]
    SiteMismatch { policy: usize, env: usize },
    #[error("the policy was {0}")]
    ObservationMismatch(String),
    #[error(
        "env.site_every_step (on by default) needs a policy with the equivariant site head (ppo.site_head = \"equivariant\"); fly a policy of the paper's slot head with --set env.site_every_step=false, or with the configuration it was trained with (docs/paper_dupac.toml)"
    )]
    SiteEveryStepNeedsHead,
}

/// How the site of each later step of a decision is picked from the site head's scores
/// (`env.site_every_step`).
pub enum SitePick<'a> {
    /// The highest score (flying and evaluating).
    Argmax,
    /// A draw from the softmax with one uniform number in [0, 1) from the closure (rollouts).
    Sample(&'a mut dyn FnMut() -> f64),
}

/// One decision of `policy` on `env`: the action `a` (just acted on `s` by the policy) applied
/// for `env.action_repeat` steps ([`Env::act`]). With `env.site_every_step`, the move is held
/// and the site of every later step of the decision is picked (`pick`) from the site head's
/// scores of that step's features with the decision's state embedding
/// ([`PolicyWeights::step_site_logits`]; [`Env::act_site_every_step`]).
pub fn decide(
    env: &mut Env,
    policy: &PolicyWeights,
    a: &ActionSample,
    s: &mut Scratch,
    mut pick: SitePick<'_>,
) -> Result<Step, RolloutError> {
    let move_ = Vector::from(a.move_raw.map(f64::from));
    if !env.site_every_step() {
        return Ok(env.act(&Action {
            move_,
            site: SiteId(a.site as u16),
        })?);
    }
    if policy.site_head.is_none() {
        return Err(RolloutError::SiteEveryStepNeedsHead);
    }
    let first = SiteId(a.site as u16);
    Ok(env.act_site_every_step(move_, |k, feats| {
        if k == 0 {
            return first;
        }
        let logits = policy.step_site_logits(feats, s);
        let site = match &mut pick {
            SitePick::Argmax => argmax(logits),
            SitePick::Sample(u) => sample_categorical(logits, u()),
        };
        SiteId(site as u16)
    })?)
}

/// An environment with its own RNG and the episode in progress.
pub struct Worker {
    index: u32,
    env: Env,
    pool: Arc<Vec<Pair>>,
    rng: ChaCha8Rng,
    scratch: Scratch,
    obs: Vec<f32>,
    acc: EpisodeAccumulator,
    pair_id: u64,
    shortest_m: f64,
}

impl Worker {
    /// A worker over `env` drawing episodes from `pool` (each pair flown in either direction),
    /// seeded with `seed`; starts its first episode.
    pub fn new(
        index: u32,
        env: Env,
        pool: Arc<Vec<Pair>>,
        seed: u64,
    ) -> Result<Worker, RolloutError> {
        if pool.is_empty() {
            return Err(RolloutError::EmptyPool);
        }
        let acc = EpisodeAccumulator::new(env.config());
        let mut w = Worker {
            index,
            env,
            pool,
            rng: ChaCha8Rng::seed_from_u64(seed),
            scratch: Scratch::default(),
            obs: Vec::new(),
            acc,
            pair_id: 0,
            shortest_m: 1.0,
        };
        w.new_episode()?;
        Ok(w)
    }

    /// Replaces the RNG (a rollout round derives it from the run seed, so a resumed run draws
    /// the same numbers as an uninterrupted one from that round on).
    pub fn reseed(&mut self, seed: u64) {
        self.rng = ChaCha8Rng::seed_from_u64(seed);
    }

    pub fn env(&self) -> &Env {
        &self.env
    }

    fn new_episode(&mut self) -> Result<(), RolloutError> {
        let k = self.rng.random_range(0..self.pool.len());
        let p = &self.pool[k];
        // The training pool flies in training's realisations.
        let episode = p.episode(
            !self.rng.random::<bool>(),
            dupac_radio::channel::FieldSplit::Train,
        );
        let reset_seed = self.rng.random::<u64>();
        self.pair_id = p.id;
        self.shortest_m = p.shortest_m;
        let obs = self.env.reset(reset_seed, episode)?;
        self.obs.clear();
        self.obs.extend_from_slice(obs);
        self.acc = EpisodeAccumulator::new(self.env.config());
        Ok(())
    }

    /// Steps the environment `steps` times with actions sampled from `policy`, starting new
    /// episodes as they end.
    pub fn collect(
        &mut self,
        policy: &PolicyWeights,
        steps: usize,
    ) -> Result<EnvTrajectory, RolloutError> {
        let d = self.env.layout().len();
        if policy.obs_dim != d {
            return Err(RolloutError::ObsMismatch {
                policy: policy.obs_dim,
                env: d,
            });
        }
        if policy.n_sites != 0 && policy.n_sites != self.env.num_sites() {
            return Err(RolloutError::SiteMismatch {
                policy: policy.n_sites,
                env: self.env.num_sites(),
            });
        }
        policy
            .check_observation(&self.env.config().observation)
            .map_err(RolloutError::ObservationMismatch)?;
        let mut tr = EnvTrajectory {
            env: self.index,
            obs_dim: d,
            obs: Vec::with_capacity(steps * d),
            moves: Vec::with_capacity(steps * MOVE_DIM),
            ..EnvTrajectory::default()
        };
        for _ in 0..steps {
            tr.obs.extend_from_slice(&self.obs);
            let rng = &mut self.rng;
            let a = policy.act_sample(&self.obs, &mut self.scratch, || rng.random::<f64>());
            // One decision: `env.action_repeat` steps of the environment.
            let mut u = || rng.random::<f64>();
            let step = decide(
                &mut self.env,
                policy,
                &a,
                &mut self.scratch,
                SitePick::Sample(&mut u),
            )?;
            for info in self.env.substeps() {
                self.acc.push(info);
            }
            tr.moves.extend_from_slice(&a.move_raw);
            tr.sites.push(a.site);
            tr.logprobs.push(a.logprob);
            tr.site_logprobs.push(a.site_logprob);
            // Every site's reward, for the all-sites site gradient (learned association only):
            // of the decision, or of each of its steps when the site is chosen every step.
            if self.env.site_every_step() {
                // At most env.action_repeat ≤ 1000 steps (config).
                tr.decision_steps.push(self.env.substeps().len() as u16);
                tr.step_site_features
                    .extend_from_slice(self.env.step_site_features());
                tr.step_site_rewards
                    .extend(self.env.step_site_rewards().iter().map(|&r| r as f32));
            } else if policy.n_sites != 0 {
                tr.site_rewards
                    .extend(self.env.site_rewards().iter().map(|&r| r as f32));
            }
            tr.values.push(a.value);
            tr.rewards.push(step.reward as f32);
            tr.terminated.push(step.terminated);
            tr.truncated.push(step.truncated);
            if step.terminated || step.truncated {
                let next_v = if step.truncated {
                    policy.value(self.env.observation(), &mut self.scratch)
                } else {
                    0.0
                };
                tr.next_values.push(next_v);
                let outcome = step.info.outcome.unwrap_or(Outcome::TimeLimit);
                tr.episodes
                    .push(self.acc.finish(self.pair_id, self.shortest_m, outcome));
                self.new_episode()?;
            } else {
                self.obs.clear();
                self.obs.extend_from_slice(self.env.observation());
                tr.next_values.push(f32::NAN); // filled below
            }
        }
        // Within an episode, V(s_{t+1}) is the value recorded at t + 1; the last step bootstraps
        // from the current observation.
        let n = tr.len();
        for t in 0..n {
            if tr.next_values[t].is_nan() {
                tr.next_values[t] = if t + 1 < n {
                    tr.values[t + 1]
                } else {
                    policy.value(&self.obs, &mut self.scratch)
                };
            }
        }
        tr.bootstrap_obs = self.obs.clone();
        Ok(tr)
    }
}

/// Flies one episode with the deterministic policy (mean move, arg-max site; one decision per
/// `env.action_repeat` steps), returning the summary and every step's record.
pub fn fly_policy(
    env: &mut Env,
    policy: &PolicyWeights,
    pair_id: u64,
    episode: Episode,
    seed: u64,
) -> Result<(EpisodeSummary, Vec<StepInfo>), RolloutError> {
    let mut scratch = Scratch::default();
    let shortest_m = episode.shortest_m;
    let mut obs = env.reset(seed, episode)?.to_vec();
    let mut acc = EpisodeAccumulator::new(env.config());
    let mut steps = Vec::new();
    loop {
        let a = policy.act_deterministic(&obs, &mut scratch);
        let step = decide(env, policy, &a, &mut scratch, SitePick::Argmax)?;
        for info in env.substeps() {
            acc.push(info);
            steps.push(*info);
        }
        if step.terminated || step.truncated {
            let outcome = step.info.outcome.unwrap_or(Outcome::TimeLimit);
            return Ok((acc.finish(pair_id, shortest_m, outcome), steps));
        }
        obs.clear();
        obs.extend_from_slice(env.observation());
    }
}
