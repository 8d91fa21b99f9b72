//! Synthetic trajectories of the default shapes (observation layout, sites, per-step site rows
//! of `env.action_repeat` steps per decision) for the learner's benchmarks and tests: random
//! values, real sizes, so an update on them costs what an update on real data costs.

use dupac_common::config::Config;
use dupac_common::msg::EnvTrajectory;
use dupac_common::obs::{ObsLayout, site_features_per_site};
use dupac_common::policy::MOVE_DIM;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// The observation length and the learned sites of `cfg` over `n_sites` sites.
pub fn shapes(cfg: &Config, n_sites: usize) -> (usize, usize) {
    (ObsLayout::new(&cfg.env.observation, n_sites).len(), n_sites)
}

/// `envs` trajectories of `steps` decisions each, shaped by `cfg` (per-step site rows when
/// `env.site_every_step`), filled from `seed`.
pub fn trajectories(
    cfg: &Config,
    n_sites: usize,
    envs: usize,
    steps: usize,
    seed: u64,
) -> Vec<EnvTrajectory> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (obs_dim, m) = shapes(cfg, n_sites);
    let f = site_features_per_site(&cfg.env.observation);
    let repeat = cfg.env.action_repeat.max(1) as usize;
    let per_step = cfg.env.site_every_step;
    (0..envs)
        .map(|e| {
            let t = steps;
            let r = if per_step { t * repeat } else { 0 };
            let mut u = |n: usize, lo: f32, hi: f32| -> Vec<f32> {
                (0..n).map(|_| rng.random_range(lo..hi)).collect()
            };
            let obs = u(t * obs_dim, -2.0, 2.0);
            let moves = u(t * MOVE_DIM, -1.0, 1.0);
            let logprobs = u(t, -8.0, -4.0);
            let site_logprobs = u(t, -4.0, -0.1);
            let values = u(t, -1.0, 1.0);
            let rewards = u(t, -1.0, 1.0);
            let next_values = u(t, -1.0, 1.0);
            let bootstrap_obs = u(obs_dim, -2.0, 2.0);
            let step_site_features = u(r * m * f, -1.0, 1.0);
            let step_site_rewards = u(r * m, -1.0, 1.0);
            let sites = (0..t)
                .map(|_| rng.random_range(0..m.max(1) as u32))
                .collect();
            let terminated = (0..t).map(|k| k % 97 == 96).collect();
            EnvTrajectory {
                env: e as u32,
                obs_dim,
                obs,
                moves,
                sites,
                logprobs,
                site_logprobs,
                site_rewards: Vec::new(),
                decision_steps: if per_step {
                    vec![repeat as u16; t]
                } else {
                    Vec::new()
                },
                step_site_features,
                step_site_rewards,
                values,
                rewards,
                terminated,
                truncated: vec![false; t],
                next_values,
                bootstrap_obs,
                episodes: Vec::new(),
            }
        })
        .collect()
}
