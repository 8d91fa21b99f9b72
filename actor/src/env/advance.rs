//! One step of the MDP (spec/env.md), as a sequence of named stages read top to bottom in
//! [`Env::advance`]: check the action → fly → collide → move → track the guide → associate →
//! arrive → reward → terminate → record. Each stage is one method below (associate in
//! `association.rs`; every reward term, each site's counterfactual included, in `reward.rs`).

use super::association::Link;
use super::reward::StepTerms;
use super::{Action, Env, EnvError, Step};
use crate::expand::StepRecord;
use crate::record::StepInfo;
use dupac_common::compact::code;
use dupac_common::config::{ActionClip, Association, Progress};
use dupac_common::geometry::{Point, Vector, distance_m as dist, norm};
use dupac_common::msg::Outcome;

impl Env {
    /// One step without writing the observation (a decision's record gets the step's progress,
    /// site-independent reward and, where it is not the next state's, the true RSRP after it).
    pub(super) fn advance(&mut self, action: &Action) -> Result<Step, EnvError> {
        let destination_m = self.check(action)?;
        self.step += 1;
        let from = self.position_m;
        let to = self.fly(from, action.move_);
        let (to, crash) = self.collide(from, to);
        let step_length_m = self.move_to(from, to);
        let progress_m = self.track(to, destination_m);
        let link = self.associate(to, action.site);
        let mut outcome = self.arrive(crash);
        let terms = StepTerms::new(
            &self.reward,
            &self.thresholds,
            self.route_penalty,
            outcome,
            step_length_m,
            progress_m,
            link.best_rsrp_dbm,
        );
        let reward = terms.reward(link.serving_rsrp_dbm, link.handover, link.ping_pong);
        if self.learned {
            self.record.steps.push(StepRecord {
                progress_m: progress_m as f32,
                common: terms.common() as f32,
            });
            if self.expander.shape().true_rsrp_every_step {
                self.record
                    .reward_rsrp
                    .extend(self.rsrp_dbm.iter().map(|&d| code::rsrp(d)));
            }
        }
        let (terminated, truncated) = self.terminate(&mut outcome);
        let info = self.record(to, step_length_m, &link, reward, outcome);
        Ok(Step {
            reward,
            terminated,
            truncated,
            info,
        })
    }

    /// Check the action: the episode is running, the move is finite and, under the learned
    /// association, the site is one of the scenario's. Returns the episode's destination (m).
    fn check(&self, action: &Action) -> Result<Point, EnvError> {
        if self.done {
            return Err(EnvError::EpisodeOver);
        }
        let destination_m = self
            .episode
            .as_ref()
            .ok_or(EnvError::EpisodeOver)?
            .destination_m;
        if action.move_.iter().any(|v| !v.is_finite()) {
            return Err(EnvError::NonFiniteAction(action.move_.into()));
        }
        let m = self.world.num_sites();
        if self.cfg.association == Association::Learned && action.site.index() >= m {
            return Err(EnvError::SiteOutOfRange {
                site: action.site.0,
                n_sites: m,
            });
        }
        Ok(destination_m)
    }

    /// Fly: where the move takes the UAV from `from` (m): the action bounded per
    /// `env.action_clip` ([`bounded_move`]) times `env.max_step_m`, the altitude clamped to the
    /// band (a clamp, not a failure: spec/env.md "UAV and motion").
    fn fly(&self, from: Point, move_: Vector) -> Point {
        let a = bounded_move(move_, self.cfg.action_clip);
        let mut to = from + a * self.cfg.max_step_m;
        to[2] = to[2].clamp(self.cfg.z_min_m, self.cfg.z_max_m);
        to
    }

    /// Collide: the UAV's sphere (`env.uav_radius_m`) swept from `from` to `to` against the
    /// building mesh stops at the contact point (a collision); otherwise a move that ends outside
    /// the flight area is out of bounds. Returns where the move ends (m) and that outcome.
    fn collide(&self, from: Point, to: Point) -> (Point, Option<Outcome>) {
        let city = &self.world.city;
        if let Some(t) = city.mesh.sphere_sweep(from, to, self.cfg.uav_radius_m) {
            (from + (to - from) * t, Some(Outcome::Collision))
        } else if !city.in_area(to[0], to[1]) {
            (to, Some(Outcome::OutOfBounds))
        } else {
            (to, None)
        }
    }

    /// Move: the UAV to `to` (m), with its velocity (the displacement in units of
    /// `env.max_step_m`) and the distance flown. Returns the step's length (m).
    fn move_to(&mut self, from: Point, to: Point) -> f64 {
        let step_length_m = dist(from, to);
        self.velocity_per_max_step = (to - from) / self.cfg.max_step_m;
        self.position_m = to;
        self.distance_flown_m += step_length_m;
        step_length_m
    }

    /// Track the guide: the distance still to go from `to` to `destination_m` (m), straight and,
    /// when the episode's planned path is used (`EnvConfig::needs_path`), along the path from
    /// the UAV's place on it ([`super::PathGuide::fix`] within [`Env::guide_window_m`]; without
    /// it the path distance is the straight one). Returns the step's progress (m): the drop of
    /// the straight or the path distance, per `env.reward.progress`.
    fn track(&mut self, to: Point, destination_m: Point) -> f64 {
        let d_prev = self.distance_to_goal_m;
        self.distance_to_goal_m = dist(to, destination_m);
        let path_prev = self.path_to_go_m;
        self.path_to_go_m = self.distance_to_goal_m;
        let window_m = self.guide_window_m();
        // Tracked only when used: pool pairs carry their shortest path whether guided or not.
        let guide = self.episode.as_ref().and_then(|e| e.guide.as_ref());
        if let Some(g) = guide.filter(|_| self.cfg.needs_path()) {
            let fix = g.fix(to, self.path_s_m, window_m);
            (self.path_s_m, self.path_to_go_m) = (fix.s_m, fix.to_go_m);
        }
        if let Some((g, _)) = &self.route {
            self.route_s_m = g.fix(to, self.route_s_m, window_m).s_m;
        }
        match self.cfg.reward.progress {
            Progress::Straight => d_prev - self.distance_to_goal_m,
            Progress::Path => path_prev - self.path_to_go_m,
        }
    }

    /// Arrive: a step that neither collided nor left the area (`crash`) and ends within
    /// `env.goal_radius_m` of the destination reaches the goal. Returns the step's outcome so far
    /// (the time limit is the terminate stage's).
    fn arrive(&self, crash: Option<Outcome>) -> Option<Outcome> {
        if crash.is_none() && self.distance_to_goal_m <= self.cfg.goal_radius_m {
            Some(Outcome::Goal)
        } else {
            crash
        }
    }

    /// Terminate: a step with an outcome ends the episode (terminated: no bootstrapping);
    /// otherwise the time limit may cut it (truncated, outcome `TimeLimit`). Returns
    /// (terminated, truncated).
    fn terminate(&mut self, outcome: &mut Option<Outcome>) -> (bool, bool) {
        let terminated = outcome.is_some();
        let truncated = !terminated && self.step >= self.time_limit;
        if truncated {
            *outcome = Some(Outcome::TimeLimit);
        }
        self.done = terminated || truncated;
        (terminated, truncated)
    }

    /// Record: the step's [`StepInfo`] from what the stages produced.
    fn record(
        &self,
        to: Point,
        step_length_m: f64,
        link: &Link,
        reward: f64,
        outcome: Option<Outcome>,
    ) -> StepInfo {
        StepInfo {
            step: self.step,
            position_m: to,
            serving: self.serving,
            serving_rsrp_dbm: link.serving_rsrp_dbm,
            measured_serving_rsrp_dbm: link.measured_serving_rsrp_dbm,
            best_site: link.best_site,
            best_rsrp_dbm: link.best_rsrp_dbm,
            class: link.class,
            best_class: self.thresholds.classify(link.best_rsrp_dbm),
            los: self.world.los(self.serving, to),
            handover: link.handover,
            ping_pong: link.ping_pong,
            step_length_m,
            distance_flown_m: self.distance_flown_m,
            distance_to_goal_m: self.distance_to_goal_m,
            reward,
            outcome,
        }
    }
}

/// The move actually flown, in units of max_step_m: the action bounded per
/// [`ActionClip`] (spec/env.md "UAV and motion" for `cube`).
pub fn bounded_move(a: Vector, clip: ActionClip) -> Vector {
    match clip {
        ActionClip::Cube => a.map(|v| v.clamp(-1.0, 1.0)),
        ActionClip::Ball => {
            let n = norm(a);
            if n > 1.0 { a / n } else { a }
        }
    }
}
