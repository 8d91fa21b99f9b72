//! A scripted pilot that flies a list of waypoints through [`Env::step`]: the bridge between the
//! planners and the environment (a planned path flown with the same collisions, radio and
//! association rule as a learned policy), and the check that they agree.

use crate::env::{Action, Env, EnvError, Episode};
use crate::record::StepInfo;
use dupac_common::geometry::{Point, Vector, distance_m as dist};
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;

/// A flown episode.
#[derive(Debug, Clone)]
pub struct Flight {
    /// One record per step.
    pub steps: Vec<StepInfo>,
    /// How the episode ended.
    pub outcome: Outcome,
    /// Undiscounted sum of rewards.
    pub episodic_return: f64,
}

impl Flight {
    /// Distance flown (m).
    pub fn distance_m(&self) -> f64 {
        self.steps.last().map(|s| s.distance_flown_m).unwrap_or(0.0)
    }
}

/// Flies `waypoints_m` (the first is normally the source) from `episode.source_m`, moving
/// straight at full speed towards the next waypoint each step (the action is the direction to
/// it scaled to length ≤ 1, so every step is at most `max_step_m` long, exactly along the
/// segment, under either `env.action_clip`), until the episode ends.
/// `site(env)` gives the site action (only used with `association = "learned"`).
pub fn fly_waypoints(
    env: &mut Env,
    seed: u64,
    episode: Episode,
    waypoints_m: &[Point],
    site: impl FnMut(&Env) -> SiteId,
) -> Result<Flight, EnvError> {
    let destination_m = episode.destination_m;
    env.reset(seed, episode)?;
    let max_step = env.config().max_step_m;
    let mut next = 0usize;
    fly(env, site, |env| {
        let p = env.position_m();
        // Skip waypoints already reached.
        while next < waypoints_m.len() && dist(p, waypoints_m[next]) < 1e-6 {
            next += 1;
        }
        let target = waypoints_m.get(next).copied().unwrap_or(destination_m);
        let scale = dist(target, p).max(max_step);
        Some((target - p) / scale)
    })
}

/// Steps `env` (already reset) with the moves of `next_move` until the episode ends, or until
/// `next_move` has none left (the flight then ends as `TimeLimit`).
fn fly(
    env: &mut Env,
    mut site: impl FnMut(&Env) -> SiteId,
    mut next_move: impl FnMut(&Env) -> Option<Vector>,
) -> Result<Flight, EnvError> {
    let (mut steps, mut episodic_return) = (Vec::new(), 0.0);
    while let Some(move_) = next_move(env) {
        // Nothing here reads the observation: the step without it (`Env::step_unobserved`).
        let s = env.step_unobserved(&Action {
            move_,
            site: site(env),
        })?;
        episodic_return += s.reward;
        steps.push(s.info);
        if let Some(outcome) = s.info.outcome {
            return Ok(Flight {
                steps,
                outcome,
                episodic_return,
            });
        }
    }
    Ok(Flight {
        steps,
        outcome: Outcome::TimeLimit,
        episodic_return,
    })
}

/// Re-flies a recorded flight: one step per recorded position, each the move from where the UAV
/// is to that position (a position the flight held is a zero move), so the replay has the
/// recording's steps, time limit and end, with `env`'s association choosing the site (what
/// `dupac eval` uses to fly a policy's moves with A3 or the oracle). Stops when the episode ends
/// or the positions run out; `Flight::outcome` is then the episode's, or `TimeLimit` when the
/// positions ran out first.
pub fn replay_positions(
    env: &mut Env,
    seed: u64,
    episode: Episode,
    positions_m: &[Point],
    site: impl FnMut(&Env) -> SiteId,
) -> Result<Flight, EnvError> {
    env.reset(seed, episode)?;
    let max_step = env.config().max_step_m;
    let mut targets = positions_m.iter();
    fly(env, site, |env| {
        let p = env.position_m();
        targets.next().map(|&t| (t - p) / max_step)
    })
}
