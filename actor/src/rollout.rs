//! Rollouts: one [`Worker`] owns an environment, its RNG and the episode in progress, and steps
//! it with an exported policy ([`PolicyWeights`], no burn), recording what PPO needs. Workers
//! are independent, so many run on worker threads; a worker's randomness comes only from its own
//! seeded RNG, so a rollout is reproducible whatever the thread count (EnvPool's rule).
//! Episode summaries come from [`crate::metrics::EpisodeAccumulator`].

use crate::env::{Action, Env, EnvError, Episode, Step};
use crate::metrics::EpisodeAccumulator;
use crate::pairs::Pair;
use crate::record::StepInfo;
use dupac_common::compact::CompactTrajectory;
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
    #[error(transparent)]
    Expand(#[from] crate::expand::ExpandError),
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

    /// [`Worker::collect`] expanded: the trajectory PPO trains on (a trainer without a wire).
    pub fn collect_expanded(
        &mut self,
        policy: &PolicyWeights,
        steps: usize,
    ) -> Result<EnvTrajectory, RolloutError> {
        let c = self.collect(policy, steps)?;
        Ok(self.env.expander().trajectory(&c, usize::MAX)?)
    }

    /// Steps the environment `steps` times with actions sampled from `policy`, starting new
    /// episodes as they end; returns the compact trajectory (what an actor sends; its
    /// expansion, [`crate::expand::Expander::trajectory`], is what the policy acted on).
    pub fn collect(
        &mut self,
        policy: &PolicyWeights,
        steps: usize,
    ) -> Result<CompactTrajectory, RolloutError> {
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
        let mut tr = CompactTrajectory {
            env: self.index,
            moves: Vec::with_capacity(steps * MOVE_DIM),
            ..CompactTrajectory::default()
        };
        for _ in 0..steps {
            record_observation(&mut tr, &self.env);
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
            record_decision(&mut tr, &self.env);
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
        record_observation(&mut tr, &self.env);
        Ok(tr)
    }
}

/// Appends to `c` the rows `env`'s current observation is the expansion of (before a decision,
/// or the bootstrap state after the last).
pub fn record_observation(c: &mut CompactTrajectory, env: &Env) {
    let shape = env.expander().shape();
    let (trunk, state) = env.observed_rows();
    c.push_trunk(shape, trunk);
    c.push_state(shape, state);
}

/// Appends to `c` what `env`'s last decision recorded beyond its observation: its steps,
/// whether it crashed and, with a learned site, its later states, each step's progress and
/// site-independent reward, and the RSRP codes its rewards score (the policy's outputs are the
/// caller's).
pub fn record_decision(c: &mut CompactTrajectory, env: &Env) {
    let shape = env.expander().shape();
    // At most env.action_repeat ≤ 1000 steps (config).
    c.decision_steps.push(env.substeps().len() as u16);
    let record = env.decision_record();
    c.crashed.push(record.crashed);
    if shape.learned {
        for state in record.states.iter().skip(1) {
            c.push_state(shape, state);
        }
        for s in &record.steps {
            c.progress_m.push(s.progress_m);
            c.common_reward.push(s.common);
        }
        c.reward_rsrp_codes.extend_from_slice(&record.reward_rsrp);
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
