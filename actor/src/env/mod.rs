//! The UAV flight environment: the paper's MDP (Sec. III) made exact (spec/env.md).
//!
//! `Env::reset(seed, pair)` starts an episode; `Env::step(&action)` moves the UAV by the clipped
//! action, checks the swept sphere against the building mesh, measures every site's RSRP,
//! applies the association rule, and returns the reward of paper Eq. (8) plus the terminal terms
//! of the spec, with termination and truncation kept apart. The observation layout is
//! [`dupac_common::obs::ObsLayout`] (version [`dupac_common::obs::OBS_VERSION`]).
//!
//! Deviations from the paper (all configurable) are listed in `docs/env.md`.

mod association;
mod guide;
mod info;
mod observe;
mod reward;

use crate::metrics::HandoverCounter;
pub use association::{Associator, argmax};
pub use guide::{GuideFix, PathGuide};
pub use info::StepInfo;
pub use reward::{MAX_REGRET_DB, RSRP_FLOOR_DBM, site_term, step_reward};

use dupac_common::config::{ActionClip, Association, Config, EnvConfig, Progress};
use dupac_common::geometry::{Point, Vector, distance_m as dist, norm};
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;
use dupac_common::obs::{ObsLayout, SENSOR_DIRECTIONS, field};
use dupac_radio::a3::A3Params;
use dupac_radio::cache::RsrpSource;
use dupac_radio::class::{RsrpClass, RsrpThresholds};
use dupac_radio::world::RadioWorld;
use std::ops::Range;
use std::sync::Arc;

/// Errors of `reset` and `step`: bad input never panics and never silently runs a wrong episode.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EnvError {
    /// The move as given, kept as an array so that the message reads `[x, y, z]`.
    #[error("action move {0:?} is not finite")]
    NonFiniteAction([f64; 3]),
    #[error("action site {site} is out of range: the scenario has {n_sites} sites")]
    SiteOutOfRange { site: u16, n_sites: usize },
    #[error("{which} {position:?}: {message}")]
    BadEndpoint {
        which: &'static str,
        position: Point,
        message: String,
    },
    #[error("pair shortest_m = {0} must be a finite length > 0")]
    BadShortest(f64),
    #[error("step called on a finished episode; call reset first")]
    EpisodeOver,
    #[error("the RSRP source has {got} sites, the world {want}")]
    SiteCountMismatch { got: usize, want: usize },
    #[error(
        "a site chosen every step needs env.site_every_step, the learned association and env.observation.site_features"
    )]
    SiteEveryStepUnavailable,
    /// `env.observation.path_guide` or `env.reward.progress = "path"` without a planned path.
    #[error(
        "env.observation.path_guide and env.reward.progress = \"path\" need the episode's planned path, and this episode has none"
    )]
    NoGuide,
    /// The planned path does not join the episode's endpoints.
    #[error("the episode's planned path runs from {from:?} to {to:?}, not between its endpoints")]
    GuideMismatch { from: Point, to: Point },
}

/// The hybrid action: a continuous move in [−1, 1]³ (clipped per axis; the unclipped value is
/// what the learner stores) and the chosen serving site (ignored unless `association = learned`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Action {
    /// The move in units of `env.max_step_m` per step, bounded to [−1, 1]³ or the unit ball per
    /// `env.action_clip` when flown.
    pub move_: Vector,
    pub site: SiteId,
}

/// An episode's endpoints and its shortest flyable path length (for the time limit).
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    pub source_m: Point,
    pub destination_m: Point,
    /// Shortest flyable path length D (m): T = ceil(time_limit_factor · D / max_step_m).
    pub shortest_m: f64,
    /// The planned path from source to destination (the shortest, or the coverage-aware one
    /// with `env.observation.path_guide_lambda` > 0, planned with
    /// `env.observation.path_guide_clearance_m` from the buildings), for
    /// `env.observation.path_guide` and `env.reward.progress = "path"` (required by them,
    /// unused otherwise).
    pub guide: Option<Arc<PathGuide>>,
}

impl Episode {
    /// An episode without a planned path.
    pub fn new(source_m: Point, destination_m: Point, shortest_m: f64) -> Episode {
        Episode {
            source_m,
            destination_m,
            shortest_m,
            guide: None,
        }
    }
}

/// Result of one step (the observation is read with [`Env::observation`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    pub reward: f64,
    /// A true terminal state (goal, collision, out of bounds): no bootstrapping.
    pub terminated: bool,
    /// Cut by the time limit: the learner bootstraps from the value of the final observation.
    pub truncated: bool,
    pub info: StepInfo,
}

/// Observation slices resolved once from the layout.
#[derive(Debug, Clone)]
struct Slots {
    position: Range<usize>,
    velocity: Range<usize>,
    goal_vector: Option<Range<usize>>,
    goal_distance: Option<Range<usize>>,
    goal_direction: Option<Range<usize>>,
    path_guide: Option<Range<usize>>,
    obstacle_distance: Range<usize>,
    obstacle_direction: Range<usize>,
    sensor_fan: Option<Range<usize>>,
    serving_one_hot: Range<usize>,
    rsrp_all: Option<Range<usize>>,
    rsrp_serving: Option<Range<usize>>,
    site_features: Option<Range<usize>>,
}

/// One UAV environment. Cheap to clone the shared parts (`Arc`), so many run in parallel.
pub struct Env {
    cfg: EnvConfig,
    world: Arc<RadioWorld>,
    rsrp: Arc<dyn RsrpSource + Send + Sync>,
    thresholds: RsrpThresholds,
    a3: A3Params,
    layout: ObsLayout,
    slots: Slots,
    sensor_dirs: [Vector; 26],
    /// The coverage-aware planner's per-metre penalties (mediocre, poor) for the route term.
    route_penalty: [f64; 2],
    // Episode state.
    episode: Option<Episode>,
    position_m: Point,
    /// The last step's displacement in units of `max_step_m` (unitless; the velocity of the
    /// observation).
    velocity_per_max_step: Vector,
    serving: SiteId,
    associator: Associator,
    rsrp_dbm: Vec<f64>,
    step: u32,
    time_limit: u32,
    distance_flown_m: f64,
    distance_to_goal_m: f64,
    /// Distance still to fly along the episode's planned path (m; [`PathGuide::fix`]); the
    /// straight distance when the episode has no path.
    path_to_go_m: f64,
    /// The UAV's tracked place on the planned path (arc length, m).
    path_s_m: f64,
    /// Handovers and ping-pongs (`env.ping_pong_window_s` in steps), and the last handover.
    handovers: HandoverCounter,
    done: bool,
    seed: u64,
    obs: Vec<f32>,
    /// Step records of the last `act`.
    substeps: Vec<StepInfo>,
    /// Every site's reward of the last `act` (learned association only; empty otherwise).
    site_rewards: Vec<f64>,
    /// Of the last [`Env::act_site_every_step`]: each step's site features (`M × features` per
    /// step) and every site's reward of that step (`M` per step).
    step_site_features: Vec<f32>,
    step_site_rewards: Vec<f64>,
}

impl Env {
    /// An environment over `world`, measuring RSRP with `rsrp` (the cache, or the world itself
    /// for exact mode).
    pub fn new(
        cfg: &Config,
        world: Arc<RadioWorld>,
        rsrp: Arc<dyn RsrpSource + Send + Sync>,
    ) -> Result<Env, EnvError> {
        let m = world.num_sites();
        if rsrp.num_sites() != m {
            return Err(EnvError::SiteCountMismatch {
                got: rsrp.num_sites(),
                want: m,
            });
        }
        let env = cfg.env.clone();
        let layout = ObsLayout::new(&env.observation, m);
        let req = |name: &str| layout.range(name).unwrap_or(0..0);
        let slots = Slots {
            position: req(field::POSITION),
            velocity: req(field::VELOCITY),
            goal_vector: layout.range(field::GOAL_VECTOR),
            goal_distance: layout.range(field::GOAL_DISTANCE),
            goal_direction: layout.range(field::GOAL_DIRECTION),
            path_guide: layout.range(field::PATH_GUIDE),
            obstacle_distance: req(field::OBSTACLE_DISTANCE),
            obstacle_direction: req(field::OBSTACLE_DIRECTION),
            sensor_fan: layout.range(field::SENSOR_FAN),
            serving_one_hot: req(field::SERVING_ONE_HOT),
            rsrp_all: layout.range(field::RSRP_ALL),
            rsrp_serving: layout.range(field::RSRP_SERVING),
            site_features: layout.range(field::SITE_FEATURES),
        };
        let mut sensor_dirs = [Vector::zeros(); 26];
        for (d, s) in sensor_dirs.iter_mut().zip(SENSOR_DIRECTIONS) {
            let v = Vector::new(f64::from(s[0]), f64::from(s[1]), f64::from(s[2]));
            *d = v / norm(v);
        }
        let dt = env.dt_s();
        let a3 = A3Params::from_config(&cfg.radio.a3, dt);
        let ping_pong_steps = (env.ping_pong_window_s / dt).ceil().max(1.0) as u32;
        let obs = vec![0.0; layout.len()];
        Ok(Env {
            thresholds: RsrpThresholds::from_config(&cfg.radio),
            a3,
            layout,
            slots,
            sensor_dirs,
            route_penalty: [cfg.planner.penalty_mediocre, cfg.planner.penalty_poor],
            episode: None,
            position_m: Point::origin(),
            velocity_per_max_step: Vector::zeros(),
            serving: SiteId(0),
            associator: Associator::Learned,
            rsrp_dbm: vec![f64::NEG_INFINITY; m],
            step: 0,
            time_limit: 0,
            distance_flown_m: 0.0,
            distance_to_goal_m: 0.0,
            path_to_go_m: 0.0,
            path_s_m: 0.0,
            handovers: HandoverCounter::new(ping_pong_steps),
            done: true,
            seed: 0,
            obs,
            substeps: Vec::new(),
            step_site_features: Vec::new(),
            step_site_rewards: Vec::new(),
            site_rewards: if env.association == Association::Learned {
                vec![0.0; m]
            } else {
                Vec::new()
            },
            cfg: env,
            world,
            rsrp,
        })
    }

    /// The observation layout (length, field ranges).
    pub fn layout(&self) -> &ObsLayout {
        &self.layout
    }

    /// M, the number of sites (size of the discrete action).
    pub fn num_sites(&self) -> usize {
        self.world.num_sites()
    }

    /// The policy's shape for this environment: observation length and site logits (M with
    /// `env.association = "learned"`, 0 otherwise: the site is not the policy's to choose).
    pub fn policy_shape(&self) -> (usize, usize) {
        let n_sites = match self.cfg.association {
            dupac_common::config::Association::Learned => self.num_sites(),
            dupac_common::config::Association::A3 | dupac_common::config::Association::BestRsrp => {
                0
            }
        };
        (self.layout.len(), n_sites)
    }

    /// The current observation.
    pub fn observation(&self) -> &[f32] {
        &self.obs
    }

    pub fn position_m(&self) -> Point {
        self.position_m
    }

    pub fn serving(&self) -> SiteId {
        self.serving
    }

    /// RSRP of every site at the current position (dBm).
    pub fn rsrp_dbm(&self) -> &[f64] {
        &self.rsrp_dbm
    }

    pub fn episode(&self) -> Option<&Episode> {
        self.episode.as_ref()
    }

    /// The seed the episode was reset with.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// Time limit T of the current episode (steps).
    pub fn time_limit(&self) -> u32 {
        self.time_limit
    }

    pub fn config(&self) -> &EnvConfig {
        &self.cfg
    }

    pub fn world(&self) -> &RadioWorld {
        &self.world
    }

    /// Checks an endpoint: finite, in the area and band, not inside a building.
    pub fn check_endpoint(&self, which: &'static str, p: Point) -> Result<(), EnvError> {
        let bad = |message: String| EnvError::BadEndpoint {
            which,
            position: p,
            message,
        };
        if p.iter().any(|v| !v.is_finite()) {
            return Err(bad("not finite".into()));
        }
        let a = self.world.city.area_m;
        if !self.world.city.in_area(p[0], p[1]) {
            return Err(bad(format!("outside the flight area {a}")));
        }
        if p[2] < self.cfg.z_min_m || p[2] > self.cfg.z_max_m {
            return Err(bad(format!(
                "altitude outside the band [{}, {}] m",
                self.cfg.z_min_m, self.cfg.z_max_m
            )));
        }
        if self.world.city.is_inside_building(p) {
            return Err(bad("inside a building".into()));
        }
        Ok(())
    }

    /// Starts an episode. The environment is deterministic: `seed` is recorded (for rollouts that
    /// derive their own randomness from it) and the same episode and actions give a bit-identical
    /// trajectory.
    pub fn reset(&mut self, seed: u64, episode: Episode) -> Result<&[f32], EnvError> {
        self.check_endpoint("source", episode.source_m)?;
        self.check_endpoint("destination", episode.destination_m)?;
        if !(episode.shortest_m.is_finite() && episode.shortest_m > 0.0) {
            return Err(EnvError::BadShortest(episode.shortest_m));
        }
        match &episode.guide {
            None if self.cfg.needs_path() => return Err(EnvError::NoGuide),
            Some(g) => {
                let (from, to) = g.ends_m();
                if dist(from, episode.source_m) > 1e-6 || dist(to, episode.destination_m) > 1e-6 {
                    return Err(EnvError::GuideMismatch { from, to });
                }
            }
            None => {}
        }
        self.seed = seed;
        self.position_m = episode.source_m;
        self.velocity_per_max_step = Vector::zeros();
        self.step = 0;
        self.time_limit = (self.cfg.time_limit_factor * episode.shortest_m / self.cfg.max_step_m)
            .ceil()
            .clamp(1.0, f64::from(u32::MAX)) as u32;
        self.distance_flown_m = 0.0;
        self.distance_to_goal_m = dist(self.position_m, episode.destination_m);
        self.path_s_m = 0.0;
        self.path_to_go_m = self.distance_to_goal_m;
        if let Some(g) = episode.guide.as_ref().filter(|_| self.cfg.needs_path()) {
            let fix = g.fix(self.position_m, 0.0, self.guide_window_m());
            (self.path_s_m, self.path_to_go_m) = (fix.s_m, fix.to_go_m);
        }
        self.episode = Some(episode);
        self.handovers.reset();
        self.substeps.clear();
        self.done = false;
        self.rsrp.rsrp_all_dbm(self.position_m, &mut self.rsrp_dbm);
        let (assoc, first) = Associator::start(self.cfg.association, self.a3, &self.rsrp_dbm);
        self.associator = assoc;
        self.serving = first;
        self.write_observation();
        Ok(&self.obs)
    }

    /// One step of the paper's MDP (Δt = max_step_m / speed): moves, measures, rewards, and
    /// writes the next observation.
    pub fn step(&mut self, action: &Action) -> Result<Step, EnvError> {
        self.site_rewards.fill(0.0);
        let s = self.advance(action, true)?;
        self.write_observation();
        Ok(s)
    }

    /// One decision of a policy: `action` applied for `env.action_repeat` steps, or until the
    /// episode ends (frame skip). The rewards of those steps add up (undiscounted, as in every
    /// frame-skip agent); `terminated`/`truncated` and `info` are the last step's; every step's
    /// record is in [`Env::substeps`]. The observation is written once, after the last step.
    /// With `action_repeat = 1` this is [`Env::step`].
    pub fn act(&mut self, action: &Action) -> Result<Step, EnvError> {
        self.substeps.clear();
        self.site_rewards.fill(0.0);
        self.step_site_features.clear();
        self.step_site_rewards.clear();
        self.decision(|env, k| env.advance(action, k == 0))
    }

    /// Runs the steps of one decision (`step(self, k)` for k = 0, 1, … up to
    /// `env.action_repeat` or the episode's end), records them, writes the observation once, and
    /// returns the summed reward with the last step's ends and info.
    fn decision(
        &mut self,
        mut step: impl FnMut(&mut Env, usize) -> Result<Step, EnvError>,
    ) -> Result<Step, EnvError> {
        let mut reward = 0.0;
        let mut last = None;
        for k in 0..self.cfg.action_repeat.max(1) as usize {
            let s = step(self, k)?;
            reward += s.reward;
            self.substeps.push(s.info);
            let end = s.terminated || s.truncated;
            last = Some(s);
            if end {
                break;
            }
        }
        self.write_observation();
        let last = last.ok_or(EnvError::EpisodeOver)?;
        Ok(Step { reward, ..last })
    }

    /// Whether the learned site is chosen at every step of a decision (`env.site_every_step`
    /// with the learned association and the site features observed): then a policy acts with
    /// [`Env::act_site_every_step`].
    pub fn site_every_step(&self) -> bool {
        self.cfg.site_every_step
            && !self.site_rewards.is_empty()
            && self.slots.site_features.is_some()
    }

    /// One decision whose move is held for `env.action_repeat` steps while the site is chosen at
    /// every step (`env.site_every_step`, issue 15): before step k of the decision
    /// `choose(k, features)` gets every site's features at the current state (`M × features`,
    /// [`dupac_common::obs::site_feature`]; at k = 0 the observation's own) and returns the site
    /// for that step. Each step is a choice. Every step's features and every site's reward of that step (the reward the step would
    /// have had with site k chosen at it, the serving site before it being the one actually
    /// serving) are kept: [`Env::step_site_features`], [`Env::step_site_rewards`]. Otherwise as
    /// [`Env::act`]; [`Env::site_rewards`] is left zero.
    pub fn act_site_every_step(
        &mut self,
        move_: Vector,
        mut choose: impl FnMut(usize, &[f32]) -> SiteId,
    ) -> Result<Step, EnvError> {
        self.substeps.clear();
        self.site_rewards.fill(0.0);
        self.step_site_features.clear();
        self.step_site_rewards.clear();
        let Some(range) = self
            .slots
            .site_features
            .clone()
            .filter(|_| self.site_every_step())
        else {
            return Err(EnvError::SiteEveryStepUnavailable);
        };
        let per_step = range.len();
        let step = self.decision(|env, k| {
            let at = k * per_step;
            if k == 0 {
                env.step_site_features
                    .extend_from_slice(&env.obs[range.clone()]);
            } else {
                let mut feats = std::mem::take(&mut env.step_site_features);
                feats.resize(at + per_step, 0.0);
                env.site_features_into(&mut feats[at..]);
                env.step_site_features = feats;
            }
            let site = choose(k, &env.step_site_features[at..]);
            env.site_rewards.fill(0.0);
            let s = env.advance(&Action { move_, site }, true)?;
            env.step_site_rewards.extend_from_slice(&env.site_rewards);
            Ok(s)
        });
        // The per-decision rewards mean nothing here (each step's are kept).
        self.site_rewards.fill(0.0);
        step
    }

    /// Every step's site features of the last [`Env::act_site_every_step`] (`M × features` per
    /// step, as many steps as [`Env::substeps`]).
    pub fn step_site_features(&self) -> &[f32] {
        &self.step_site_features
    }

    /// Every step's every-site reward of the last [`Env::act_site_every_step`] (`M` per step):
    /// entry `k·M + j` is what step k would have returned with site j chosen at it; the chosen
    /// site's entry is the step's reward.
    pub fn step_site_rewards(&self) -> &[f64] {
        &self.step_site_rewards
    }

    /// The records of every step of the last [`Env::act`], in order.
    pub fn substeps(&self) -> &[StepInfo] {
        &self.substeps
    }

    /// Every site's reward of the last [`Env::act`] (or [`Env::step`]): entry k is the reward
    /// the decision would have had with site k chosen, the flight being the same (the site does
    /// not move the UAV): the same Eq. (8), terminal and route terms, the site's own RSRP class
    /// and regret, and the handover cost if k is not the site serving before the decision (and
    /// `env.reward.ping_pong_reward` if serving k would be a ping-pong). The chosen site's entry equals the reward returned. Empty unless `env.association =
    /// "learned"` (issue 15: the site head learns from all of them).
    pub fn site_rewards(&self) -> &[f64] {
        &self.site_rewards
    }

    /// Arc length (m) within which the UAV's place on the planned path is sought each step
    /// ([`PathGuide::fix`]): two steps, so the place keeps up with a UAV flying beside the path.
    fn guide_window_m(&self) -> f64 {
        2.0 * self.cfg.max_step_m.max(0.5)
    }

    /// `step` without writing the observation; `first` = the first step of a decision (the
    /// only one at which a choice of site can be a handover).
    fn advance(&mut self, action: &Action, first: bool) -> Result<Step, EnvError> {
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
        self.step += 1;
        let from = self.position_m;
        let a = bounded_move(action.move_, self.cfg.action_clip);
        let mut to = from + a * self.cfg.max_step_m;
        // The altitude band is a clamp, not a failure (spec/env.md "UAV and motion").
        to[2] = to[2].clamp(self.cfg.z_min_m, self.cfg.z_max_m);

        let mut outcome = None;
        if let Some(t) = self
            .world
            .city
            .mesh
            .sphere_sweep(from, to, self.cfg.uav_radius_m)
        {
            // Stop at the contact point.
            to = from + (to - from) * t;
            outcome = Some(Outcome::Collision);
        } else if !self.world.city.in_area(to[0], to[1]) {
            outcome = Some(Outcome::OutOfBounds);
        }
        let step_length_m = dist(from, to);
        self.velocity_per_max_step = (to - from) / self.cfg.max_step_m;
        self.position_m = to;
        self.distance_flown_m += step_length_m;
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
        let progress_m = match self.cfg.reward.progress {
            Progress::Straight => d_prev - self.distance_to_goal_m,
            Progress::Path => path_prev - self.path_to_go_m,
        };

        // Radio: every site's RSRP at the new position, then the association rule.
        self.rsrp.rsrp_all_dbm(to, &mut self.rsrp_dbm);
        let before = self.serving;
        // The decision's choice takes effect at its first step (a handover only there).
        self.serving = self.associator.next(action.site, &self.rsrp_dbm);
        // The counter before this step: whether serving site k now would be a ping-pong.
        let counter = self.handovers;
        let (handover, ping_pong) = self.handovers.step(before.0, self.serving.0, self.step);
        let serving_rsrp_dbm = self.rsrp_dbm[self.serving.index()];
        let class = self.thresholds.classify(serving_rsrp_dbm);
        let best_site = argmax(&self.rsrp_dbm);

        let r = self.cfg.reward.clone();
        let thresholds = self.thresholds;
        let best_rsrp_dbm = self.rsrp_dbm[best_site.index()];
        // Site-independent terms: terminal rewards, the goal, the route's connectivity term.
        let crashed = outcome.is_some();
        let mut common = match outcome {
            Some(Outcome::Collision) => r.collision_reward,
            Some(Outcome::OutOfBounds) => r.out_of_bounds_reward,
            _ => 0.0,
        };
        if r.route_connectivity_weight > 0.0 {
            let penalty = match self.thresholds.classify(best_rsrp_dbm) {
                RsrpClass::Excellent => 0.0,
                RsrpClass::Mediocre => self.route_penalty[0],
                RsrpClass::Poor => self.route_penalty[1],
            };
            common -= r.mu1 * r.route_connectivity_weight * penalty * step_length_m;
        }
        if outcome.is_none() && self.distance_to_goal_m <= self.cfg.goal_radius_m {
            outcome = Some(Outcome::Goal);
            common += r.goal_reward;
        }
        let term = |rsrp: f64, handover: bool, ping_pong: bool| {
            site_term(
                &r,
                &thresholds,
                crashed,
                progress_m,
                rsrp,
                best_rsrp_dbm,
                handover,
                ping_pong,
            )
        };
        let reward = common + term(serving_rsrp_dbm, handover, ping_pong);
        if !self.site_rewards.is_empty() {
            // The counterfactual of site k serves k from the decision's first step on.
            for (k, acc) in self.site_rewards.iter_mut().enumerate() {
                let switch = first && k != before.index();
                let pp = switch && counter.would_ping_pong(before.0, k as u16, self.step);
                *acc += common + term(self.rsrp_dbm[k], switch, pp);
            }
        }
        let terminated = outcome.is_some();
        let truncated = !terminated && self.step >= self.time_limit;
        if truncated {
            outcome = Some(Outcome::TimeLimit);
        }
        self.done = terminated || truncated;
        let info = StepInfo {
            step: self.step,
            position_m: to,
            serving: self.serving,
            serving_rsrp_dbm,
            best_site,
            best_rsrp_dbm,
            class,
            best_class: self.thresholds.classify(best_rsrp_dbm),
            los: self.world.los(self.serving, to),
            handover,
            ping_pong,
            step_length_m,
            distance_flown_m: self.distance_flown_m,
            distance_to_goal_m: self.distance_to_goal_m,
            reward,
            outcome,
        };
        Ok(Step {
            reward,
            terminated,
            truncated,
            info,
        })
    }

    /// Whether the current episode has ended (terminated or truncated).
    pub fn is_done(&self) -> bool {
        self.done
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
