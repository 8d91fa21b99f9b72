//! Flying one episode with live weights (`dupac fly --follow`): a deterministic
//! flight whose policy is swapped, between steps, for the newest version a [`Follower`]
//! received, so a user watches a policy improve during training.

use crate::actor::{ActorError, Follower};
use dupac_actor::env::{Env, Episode};
use dupac_actor::metrics::EpisodeAccumulator;
use dupac_actor::record::StepInfo;
use dupac_actor::rollout::{SitePick, decide};
use dupac_common::msg::{EpisodeSummary, Outcome};
use dupac_common::policy::{PolicyWeights, Scratch};
use std::time::Duration;

/// Flies one episode deterministically with live weights: before every step the newest
/// version (if any arrived) replaces the one in use. Returns the version used at each step.
pub fn fly_following(
    env: &mut Env,
    mut policy: PolicyWeights,
    follower: &mut Follower,
    pair_id: u64,
    episode: Episode,
    step_ms: u64,
) -> Result<(EpisodeSummary, Vec<StepInfo>, Vec<u64>), ActorError> {
    let mut scratch = Scratch::default();
    let shortest_m = episode.shortest_m;
    let mut obs = env.reset(pair_id, episode)?.to_vec();
    let mut acc = EpisodeAccumulator::new(env.config());
    let (mut steps, mut versions) = (Vec::new(), Vec::new());
    loop {
        if let Some(p) = follower.newer()? {
            eprintln!("step {}: swapped to version {}", steps.len() + 1, p.version);
            policy = p;
        }
        let a = policy.act_deterministic(&obs, &mut scratch);
        let step = decide(env, &policy, &a, &mut scratch, SitePick::Argmax)?;
        for info in env.substeps() {
            acc.push(info);
            steps.push(*info);
            versions.push(policy.version);
        }
        if step.terminated || step.truncated {
            let outcome = step.info.outcome.unwrap_or(Outcome::TimeLimit);
            return Ok((acc.finish(pair_id, shortest_m, outcome), steps, versions));
        }
        obs.clear();
        obs.extend_from_slice(env.observation());
        if step_ms > 0 {
            std::thread::sleep(Duration::from_millis(step_ms));
        }
    }
}
