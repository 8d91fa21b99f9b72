//! The UAV flight environment: the paper's MDP (Sec. III) made exact (spec/env.md).
//!
//! `Env::reset(seed, pair)` starts an episode; `Env::step(&action)` moves the UAV by the clipped
//! action, checks the swept sphere against the building mesh, measures every site's RSRP,
//! applies the association rule, and returns the reward of paper Eq. (8) plus the terminal terms
//! of the spec, with termination and truncation kept apart. The observation layout is
//! [`dupac_common::obs::ObsLayout`] (version [`dupac_common::obs::OBS_VERSION`]).
//!
//! One concept per file: this one holds the environment's types, its construction and `reset`;
//! `decision.rs` a policy's decision (steps, records); `advance.rs` one step as its stages, read
//! top to bottom; `association.rs` the association rule and stage; `reward.rs` every reward term;
//! `observe.rs` the observation; `guide.rs` the planned path.
//!
//! Deviations from the paper (all configurable) are listed in `docs/env.md`.

mod advance;
mod association;
mod decision;
mod guide;
mod observe;
mod reward;
mod route_ahead;
mod serving_plan;

use crate::expand::{DecisionRecord, Expander};
use crate::metrics::HandoverCounter;
use crate::record::StepInfo;
pub use crate::reward::{MAX_REGRET_DB, RSRP_FLOOR_DBM, site_term, step_reward};
pub use advance::bounded_move;
pub use association::{Associator, argmax};
pub use guide::{GuideFix, PathGuide};
pub use route_ahead::{Ahead, RouteMap};
pub use serving_plan::serving_plan;

use dupac_common::compact::{StateRow, TrunkRow};
use dupac_common::config::{Association, Config, EnvConfig, RewardConfig, WeightDraw};
use dupac_common::geometry::{Point, Vector, distance_m as dist, norm};
use dupac_common::ids::SiteId;
use dupac_common::obs::{ObsLayout, SENSOR_DIRECTIONS};
use dupac_radio::a3::A3Params;
use dupac_radio::channel::{FieldSplit, Measurer};
use dupac_radio::class::RsrpThresholds;
use dupac_radio::shadow::ShadowField;
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use std::sync::Arc;

/// Stream index of a training episode's handover weight draw ("howeight").
const HANDOVER_WEIGHT_DOMAIN: u64 = 0x7468_6769_6577_6f68;

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

/// An episode: its endpoints, its shortest flyable path length (for the time limit), the
/// shadow-fading realisations it flies in, and its guide path.
#[derive(Debug, Clone, PartialEq)]
pub struct Episode {
    pub source_m: Point,
    pub destination_m: Point,
    /// Which shadow-fading realisations (and measurement-error streams) the episode draws from
    /// (docs/env.md "Channel"): training's for a training pool's pair, the validation's for a
    /// validation pair or a pair of the user's file, the test's for a test pair. Part of the
    /// episode, so that no caller can fly a held-out pair in a training field by forgetting it.
    pub field: FieldSplit,
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
    /// An episode without a planned path, in `field`'s realisations.
    pub fn new(
        source_m: Point,
        destination_m: Point,
        shortest_m: f64,
        field: FieldSplit,
    ) -> Episode {
        Episode {
            source_m,
            destination_m,
            field,
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

/// One UAV environment. Cheap to clone the shared parts (`Arc`), so many run in parallel.
pub struct Env {
    cfg: EnvConfig,
    world: Arc<RadioWorld>,
    rsrp: Arc<dyn RsrpSource + Send + Sync>,
    thresholds: RsrpThresholds,
    a3: A3Params,
    /// The observation's expansion from the state ([`crate::expand`]).
    expander: Expander,
    /// The site is the policy's (`env.association = "learned"`): decisions keep their record.
    learned: bool,
    sensor_dirs: [Vector; 26],
    /// The coverage-aware planner's per-metre penalties (mediocre, poor) for the route term.
    route_penalty: [f64; 2],
    // Episode state.
    episode: Option<Episode>,
    /// The episode's handover weight w (`env.reward.handover_weight`, or drawn in training).
    handover_weight: f64,
    /// The episode's reward terms: `env.reward` with its handover and ping-pong costs
    /// (`handover_reward`, `ping_pong_reward`, configured at weight 1) times `handover_weight`.
    reward: RewardConfig,
    position_m: Point,
    /// The last step's displacement in units of `max_step_m` (unitless; the velocity of the
    /// observation).
    velocity_per_max_step: Vector,
    serving: SiteId,
    /// The site that served before the episode's first step.
    start_serving: SiteId,
    associator: Associator,
    /// Every site's true RSRP at the UAV (dBm): the deterministic value less the episode's
    /// shadow fading. Rewards and metrics score it.
    rsrp_dbm: Vec<f64>,
    /// What the UAV measures of it (dBm; `radio.channel`): observed by the policy and compared by
    /// A3. The true RSRP where the channel is measured exactly.
    measured_dbm: Vec<f64>,
    /// The episode's shadow-fading realisation (`radio.channel.model = "real"`).
    field: Option<Arc<ShadowField>>,
    /// Which realisations the current episode draws from ([`Episode::field`]).
    field_split: FieldSplit,
    /// The measurement error and layer-3 filter (`radio.channel`, operator knowledge).
    measurer: Option<Measurer>,
    /// Scratch: every site's line of sight and shadow fading at the UAV.
    los_scratch: Vec<f64>,
    /// With a route prediction (`EnvConfig::predicts_route`): the route (the episode's planned
    /// path, or the straight line to the destination) and the operator's map along it.
    route: Option<(Arc<PathGuide>, RouteMap)>,
    /// The UAV's tracked place on the route (arc length, m).
    route_s_m: f64,
    /// Scratch: every site's map RSRP at the UAV (dBm, without shadowing), then its measured −
    /// map offset (dB).
    map_offset_db: Vec<f64>,
    /// Each site's shadowing decorrelation distance (m, TR 38.901 Table 7.5-6) in line of sight
    /// and out of it.
    decorrelation_m: [Vec<f64>; 2],
    /// Scratch: the decorrelation distance of each site at the UAV (m).
    decorrelation_scratch_m: Vec<f64>,
    /// The prediction of the route ahead at the current step.
    ahead: Ahead,
    /// The predictive association's choice, kept from one decision to the next.
    predictive_site: SiteId,
    shadow_scratch_db: Vec<f64>,
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
    /// The rows `obs` is the expansion of.
    obs_trunk: TrunkRow,
    obs_state: StateRow,
    /// Step records of the last `act`.
    substeps: Vec<StepInfo>,
    /// The compact record of the last decision (learned association only).
    record: DecisionRecord,
    /// The last decision chose the site at every step ([`Env::act_site_every_step`]).
    record_every_step: bool,
    /// Every site's reward of the last decision (learned association only): `M` values, or `M`
    /// per step when the site is chosen every step.
    site_rewards: Vec<f64>,
    /// Of the last [`Env::act_site_every_step`]: each step's site features (`M × features` per
    /// step).
    step_site_features: Vec<f32>,
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
        let expander = Expander::new(cfg, &world);
        let layout = expander.layout();
        let mut sensor_dirs = [Vector::zeros(); 26];
        for (d, s) in sensor_dirs.iter_mut().zip(SENSOR_DIRECTIONS) {
            let v = Vector::new(f64::from(s[0]), f64::from(s[1]), f64::from(s[2]));
            *d = v / norm(v);
        }
        let dt = env.dt_s();
        let measurer = cfg.radio.channel.measured().then(|| {
            let c = &cfg.radio.channel;
            Measurer::new(
                m,
                c.measurement_sigma_db,
                c.l3_filter_k,
                dt,
                c.measurement_period_ms / 1000.0,
            )
        });
        // The period of what the UAV measures: the channel's, or every step.
        let period_s = measurer
            .as_ref()
            .map_or(dt, |m| f64::from(m.period_steps()) * dt);
        let a3 = A3Params::from_config(&cfg.radio.a3, dt, period_s);
        let ping_pong_steps = (env.ping_pong_window_s / dt).ceil().max(1.0) as u32;
        let obs = vec![0.0; layout.len()];
        Ok(Env {
            learned: env.association == Association::Learned,
            thresholds: RsrpThresholds::from_config(&cfg.radio),
            a3,
            expander,
            sensor_dirs,
            route_penalty: [cfg.planner.penalty_mediocre, cfg.planner.penalty_poor],
            episode: None,
            handover_weight: env.reward.handover_weight,
            reward: env.reward.clone(),
            position_m: Point::origin(),
            velocity_per_max_step: Vector::zeros(),
            serving: SiteId(0),
            start_serving: SiteId(0),
            associator: Associator::Learned,
            rsrp_dbm: vec![f64::NEG_INFINITY; m],
            measured_dbm: vec![f64::NEG_INFINITY; m],
            field: None,
            field_split: FieldSplit::Train,
            measurer,
            route: None,
            route_s_m: 0.0,
            map_offset_db: vec![f64::NEG_INFINITY; m],
            decorrelation_m: [true, false].map(|los| {
                world
                    .sites
                    .iter()
                    .map(|s| dupac_radio::shadow::decorrelation_m(s.kind.scenario(), los))
                    .collect()
            }),
            decorrelation_scratch_m: vec![0.0; m],
            ahead: Ahead::new(m, env.route_prediction().map_or(1.0, |p| p.sample_m)),
            predictive_site: SiteId(0),
            los_scratch: vec![0.0; m],
            shadow_scratch_db: vec![0.0; m],
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
            obs_trunk: TrunkRow::default(),
            obs_state: StateRow::default(),
            substeps: Vec::new(),
            record: DecisionRecord::default(),
            record_every_step: false,
            step_site_features: Vec::new(),
            site_rewards: Vec::new(),
            cfg: env,
            world,
            rsrp,
        })
    }

    /// The observation layout (length, field ranges).
    pub fn layout(&self) -> &ObsLayout {
        self.expander.layout()
    }

    /// The expansion this environment's observation is written with (and the learner expands
    /// its compact trajectories with).
    pub fn expander(&self) -> &Expander {
        &self.expander
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
            dupac_common::config::Association::A3
            | dupac_common::config::Association::BestRsrp
            | dupac_common::config::Association::Predictive => 0,
        };
        (self.layout().len(), n_sites)
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

    /// The site that served before the episode's first step: the strongest the UAV measured at
    /// the source (its handovers are counted from it).
    pub fn start_serving(&self) -> SiteId {
        self.start_serving
    }

    /// True RSRP of every site at the current position (dBm; with the episode's shadow fading
    /// under the real channel).
    pub fn rsrp_dbm(&self) -> &[f64] {
        &self.rsrp_dbm
    }

    /// What the UAV measures of every site's RSRP at the current position (dBm): noisy and
    /// layer-3 filtered under the real channel with operator knowledge, the true RSRP otherwise.
    pub fn measured_dbm(&self) -> &[f64] {
        &self.measured_dbm
    }

    /// What measures the UAV's RSRP under the real channel (its unfiltered sample, whether this
    /// step brought a new measurement, the measurement period); `None` where the UAV measures
    /// the true RSRP every step.
    pub fn measurer(&self) -> Option<&Measurer> {
        self.measurer.as_ref()
    }

    /// The current episode's shadow-fading realisation (none in the deterministic world).
    pub fn field(&self) -> Option<&Arc<ShadowField>> {
        self.field.as_ref()
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
        // First: the handover weight and the field both depend on the episode's split.
        self.field_split = episode.field;
        self.set_handover_weight(seed);
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
        self.route = self.cfg.route_prediction().map(|p| {
            let g = episode.guide.clone().unwrap_or_else(|| {
                let straight = [episode.source_m, episode.destination_m];
                Arc::new(PathGuide::new(&straight).expect("checked finite endpoints"))
            });
            let map = RouteMap::new(&g, self.rsrp.as_ref(), p.sample_m);
            (g, map)
        });
        self.route_s_m = match &self.route {
            Some((g, _)) => g.fix(self.position_m, 0.0, self.guide_window_m()).s_m,
            None => 0.0,
        };
        self.episode = Some(episode);
        self.handovers.reset();
        self.substeps.clear();
        self.done = false;
        self.field = self
            .world
            .channel
            .as_ref()
            .map(|c| c.episode_field(self.field_split, seed));
        if let Some(m) = self.measurer.as_mut() {
            m.reset(self.field_split, seed);
        }
        self.measure(self.position_m);
        let (assoc, first) = Associator::start(self.cfg.association, self.a3, &self.measured_dbm);
        self.associator = assoc;
        self.serving = first;
        self.start_serving = first;
        self.predictive_site = first;
        self.write_observation();
        Ok(&self.obs)
    }

    /// The episode's handover weight w: drawn from [0, `env.reward.handover_weight_max`] by the
    /// episode's seed in training (a stream of its own; uniform in w, or in ln(1 + w) with
    /// `env.reward.handover_weight_draw = "log"`), `env.reward.handover_weight` otherwise; the
    /// episode's handover and ping-pong rewards (`self.reward`) are the configured ones times w.
    fn set_handover_weight(&mut self, seed: u64) {
        let r = &self.cfg.reward;
        self.handover_weight =
            if r.handover_weight_max > 0.0 && self.field_split == FieldSplit::Train {
                let u = dupac_common::seed::stream_seed(seed, HANDOVER_WEIGHT_DOMAIN, 0) >> 11;
                let u = u as f64 / (1u64 << 53) as f64;
                match r.handover_weight_draw {
                    WeightDraw::Uniform => r.handover_weight_max * u,
                    WeightDraw::Log => (u * r.handover_weight_max.ln_1p()).exp_m1(),
                }
            } else {
                r.handover_weight
            };
        self.reward.handover_reward = r.handover_reward * self.handover_weight;
        self.reward.ping_pong_reward = r.ping_pong_reward * self.handover_weight;
    }

    /// The current episode's handover weight w (`env.reward.handover_weight`).
    pub fn handover_weight(&self) -> f64 {
        self.handover_weight
    }

    /// Arc length (m) within which the UAV's place on the planned path is sought each step
    /// ([`PathGuide::fix`]): two steps, so the place keeps up with a UAV flying beside the path.
    pub(super) fn guide_window_m(&self) -> f64 {
        2.0 * self.cfg.max_step_m.max(0.5)
    }

    /// Whether the current episode has ended (terminated or truncated).
    pub fn is_done(&self) -> bool {
        self.done
    }
}
