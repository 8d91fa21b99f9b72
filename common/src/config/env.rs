//! `[env]`: the flight environment, its reward and observation (spec/env.md, docs/env.md).

use super::ConfigError;
#[allow(unused_imports)]
use super::check::*;
use serde::{Deserialize, Serialize};

use super::CacheConfig;

/// Scaling of obstacle-sensor distances into [0, 1] (see [`ObservationConfig::sensor_scale`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SensorScale {
    /// d / range (spec/env.md "Observation").
    Linear,
    /// ln(1 + d / 1 m) / ln(1 + range / 1 m).
    Log,
}

/// Where each site's line-of-sight feature comes from (see [`ObservationConfig::site_los`]).
#[derive(
    Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case")]
pub enum SiteLos {
    /// A ray from each site to the UAV at every observation (spec/radio.md D9): exact, 0 or 1.
    Ray,
    /// From the RSRP source: under the RSRP cache, its grid's line of sight interpolated
    /// trilinearly like its RSRP (a value in [0, 1]); in exact mode, the ray.
    #[default]
    Cache,
}

impl SensorScale {
    /// Scales a sensed distance `d_m` (≤ `range_m`) into [0, 1]; 1 = nothing in range.
    pub fn scale(self, d_m: f64, range_m: f64) -> f64 {
        let d = d_m.clamp(0.0, range_m);
        match self {
            SensorScale::Linear => d / range_m,
            SensorScale::Log => (1.0 + d).ln() / (1.0 + range_m).ln(),
        }
    }
}

/// Source of c_t and θ_t (see [`ObservationConfig::nearest_obstacle`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum NearestObstacle {
    /// The shortest ray of the sensor fan (spec/env.md "Observation").
    Fan,
    /// The nearest surface point of the building mesh.
    Exact,
}

/// How the action's move a ∈ ℝ³ becomes a displacement (see [`EnvConfig::action_clip`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ActionClip {
    /// Each axis clipped to [−1, 1] (spec/env.md "UAV and motion"): a diagonal move is up to
    /// √3 × max_step_m long.
    Cube,
    /// a scaled onto the unit ball when |a| > 1: every move is at most max_step_m long, so the
    /// UAV never exceeds the paper's speed in any direction.
    Ball,
}

/// How the serving GBS is chosen (spec/env.md "Association").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Association {
    /// DUPAC: the action's discrete part picks the serving site.
    Learned,
    /// The paper's base method: the A3 rule of spec/radio.md §4.
    A3,
    /// Oracle (evaluation only): always the strongest site.
    BestRsrp,
    /// A rule from what an operator and the UAV know (`env.predictive`, docs/env.md
    /// "Predictive association"): every decision, the serving sequence over the planned route
    /// ahead that keeps the most map-predicted RSRP for its handovers, by dynamic programming;
    /// the first choice is kept until the next decision.
    Predictive,
}
/// Where the environment gets RSRP from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum RadioMode {
    /// The memory-mapped per-site grid (`cache.*`), trilinear interpolation.
    Cache,
    /// A line-of-sight ray cast per site per step (validation).
    Exact,
}

/// Reward of paper Eq. (8) plus the terminal terms of spec/env.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct RewardConfig {
    /// μ1, weight of the progress Δd (per metre).
    pub mu1: f64,
    /// μ2, weight of the RSRP (dBm) in the mediocre class.
    pub mu2: f64,
    /// μ3, weight of the RSRP (dBm) in the poor class.
    pub mu3: f64,
    /// Reward for reaching the goal (terminated).
    pub goal_reward: f64,
    /// Reward for a collision (terminated).
    pub collision_reward: f64,
    /// Reward for leaving the flight area (terminated).
    pub out_of_bounds_reward: f64,
    /// Reward added per handover (the paper has none: 0). A departure by default (−2): the learned
    /// association has no hysteresis or time-to-trigger as A3 does, and without a cost a policy
    /// that is indifferent among sites switches freely. With `site_regret_weight` = 1 and the
    /// site chosen every step (`env.site_every_step`, the default) a switch pays when the new
    /// site is ≥ 2 dB stronger at that step; with the site held for a decision (5 steps), ≥ 0.4 dB
    /// (docs/env.md).
    pub handover_reward: f64,
    /// Reward added per *ping-pong* (≤ 0; 0 = off; default −8): a handover back to the site the
    /// previous handover left within `env.ping_pong_window_s`, on top of `handover_reward`. A
    /// departure: a hysteresis on returns, since the myopic all-sites estimator never charges a
    /// switch the switch back that undoes it (docs/training.md "Site learning"). Needs
    /// `env.observation.site_ping_pong` with the learned association.
    pub ping_pong_reward: f64,
    /// w, the handover weight: `handover_reward` and `ping_pong_reward` are multiplied by it
    /// (1, the default: as written). Training draws it per episode when `handover_weight_max` >
    /// 0; evaluation, flights and training's held-out evaluation use this value. With a policy
    /// conditioned on it (`env.observation.handover_weight`) it is the operator's trade-off of
    /// excellent time against handovers at flight time, without retraining (docs/env.md
    /// "Handover weight").
    pub handover_weight: f64,
    /// Training draws each episode's handover weight w from [0, this] (0, the default:
    /// every episode has `handover_weight`), as `handover_weight_draw` says. Needs
    /// `env.observation.handover_weight`: a policy must see the cost it is charged.
    pub handover_weight_max: f64,
    /// How training draws w from [0, `handover_weight_max`]: `uniform` in w (the default), or
    /// `log` — uniform in ln(1 + w), the value the policy observes, so that a wide range (the
    /// low handover rates need w ≫ 6) keeps as many episodes at w ≤ 3 as at the top
    /// (docs/env.md "Handover weight").
    pub handover_weight_draw: WeightDraw,
    /// κ_s, reward per dB of *site regret* per step: −κ_s · (best RSRP − serving RSRP), ≤ 0.
    /// Eq. (8) is indifferent among sites that are all excellent, yet serving from a weaker one
    /// costs SINR against the stronger interferer; this term prefers the stronger site
    /// (a departure, 0 in the paper; default 1 per dB; docs/env.md). Regret is capped at 60 dB.
    pub site_regret_weight: f64,
    /// κ_r, the route's connectivity weight: per metre flown, −μ1 · κ_r · penalty(class of the
    /// *best* site here), with the coverage-aware planner's penalties
    /// (`planner.penalty_mediocre`, `planner.penalty_poor`; excellent 0), so κ_r plays the role
    /// of the planner's λ. It depends on where the UAV flies, not on the site it serves (the site
    /// choice has its own terms). 0 = the paper's Eq. (8) alone, under which a metre in mediocre
    /// costs ≈ 0.9 while a metre of detour costs ≈ μ1 (a departure; docs/env.md).
    pub route_connectivity_weight: f64,
    /// What the progress Δd of Eq. (8) measures: `straight` = the decrease of the straight-line
    /// distance to the destination (the paper), `path` = the decrease of the distance still to
    /// fly along the episode's planned path (`env.observation.path_guide_lambda`): the distance
    /// to the UAV's tracked place on it plus the path beyond, which does not pay for flying into
    /// a courtyard that points at the goal. A departure (docs/env.md "Path guide").
    /// Over an episode that reaches the goal, `straight` sums to the straight-line distance and
    /// `path` to about the planned path's length.
    pub progress: Progress,
}

/// How training draws each episode's handover weight ([`RewardConfig::handover_weight_draw`]).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema, Default,
)]
#[serde(rename_all = "snake_case")]
pub enum WeightDraw {
    /// Uniform in w.
    #[default]
    Uniform,
    /// Uniform in ln(1 + w).
    Log,
}

/// The distance whose decrease is the progress Δd of Eq. (8) ([`RewardConfig::progress`]).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema, Default,
)]
#[serde(rename_all = "snake_case")]
pub enum Progress {
    /// Straight-line distance to the destination (paper Eq. 8).
    Straight,
    /// Distance still to fly along the episode's planned path (the default).
    #[default]
    Path,
}

impl Default for RewardConfig {
    fn default() -> Self {
        Self {
            mu1: 10.0,
            mu2: 0.01,
            mu3: 0.1,
            goal_reward: 100.0,
            collision_reward: -1000.0,
            out_of_bounds_reward: -1000.0,
            handover_reward: -2.0,
            ping_pong_reward: -8.0,
            handover_weight: 1.0,
            handover_weight_max: 0.0,
            handover_weight_draw: WeightDraw::Uniform,
            site_regret_weight: 1.0,
            route_connectivity_weight: 0.5,
            progress: Progress::Path,
        }
    }
}

/// Scale (m) of the `path_offset` observation ([`ObservationConfig::path_offset`]): offsets of
/// a few metres, the range where a corner's wall comes within the collision sphere, read ≈ 0.1–0.5.
pub const PATH_OFFSET_SCALE_M: f64 = 10.0;

/// Which parts of the observation are present (spec/env.md "Observation"); each addition to the
/// paper's state can be switched off for ablations.
///
/// Every policy records the one it was trained on ([`crate::policy::PolicyWeights::observation`]),
/// so this struct is part of the policy and checkpoint file formats (learner `checkpoint.rs`)
/// and of the weights message ([`crate::msg::SCHEMA_VERSION`]): adding or removing a field
/// means bumping those versions (a file of another format is then refused, naming it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ObservationConfig {
    /// Goal vector and its norm.
    pub goal: bool,
    /// The full 26-ray obstacle-sensor fan (c_t and θ_t are always present).
    pub sensor_fan: bool,
    /// Measured RSRP of every site.
    pub rsrp_all: bool,
    /// RSRP of the serving site.
    pub rsrp_serving: bool,
    /// Obstacle sensor range (m).
    pub sensor_range_m: f64,
    /// How a sensed distance d is scaled into [0, 1] (c_t and the fan): `linear` = d / range
    /// (spec/env.md), `log` = ln(1 + d / 1 m) / ln(1 + range / 1 m), which resolves the last
    /// metres before a wall (a departure from the spec, the default: docs/env.md).
    pub sensor_scale: SensorScale,
    /// Where c_t and θ_t come from: `fan` = the shortest of the 26 rays and its direction
    /// (spec/env.md), `exact` = the true nearest building surface point within the sensor range
    /// (the paper's "distance and direction to the nearest obstacle"; it also sees corners that
    /// fall between the rays).
    pub nearest_obstacle: NearestObstacle,
    /// The flight area's lateral edge is sensed like a wall, by the sensor fan and by c_t/θ_t
    /// (leaving the area ends an episode as a collision does, and without this only the
    /// normalised position tells where the edge is; a departure from the spec, whose sensors see
    /// buildings only).
    pub geofence: bool,
    /// Scale of distances to the goal (m): goal vector / this.
    pub goal_scale_m: f64,
    /// Also observe the unit direction to the destination (with `goal`): the goal vector alone
    /// shrinks towards 0 on the final approach, where the network must divide by a tiny norm to
    /// find the direction (a departure from the spec, the default: docs/env.md).
    pub goal_direction: bool,
    /// RSRP normalisation: (RSRP − centre) / scale.
    pub rsrp_centre_dbm: f64,
    /// Scale of the RSRP normalisation (dB; see `rsrp_centre_dbm`).
    pub rsrp_scale_db: f64,
    /// Per-site features for the permutation-equivariant site head (`ppo.site_head =
    /// "equivariant"`), [`crate::obs::SITE_FEATURES`] values per site on a fixed physical scale,
    /// at the end of the observation; the actor and critic MLPs do not read them. Written only
    /// under `env.association = "learned"` (zeros otherwise). A departure.
    pub site_features: bool,
    /// One more site feature (with `site_features`): 1 for the site that serving next would be a
    /// ping-pong (the site the last handover left, within `env.ping_pong_window_s`), else 0
    /// ([`crate::obs::site_feature::ping_pong`]). On by default; needed by
    /// `env.reward.ping_pong_reward`.
    pub site_ping_pong: bool,
    /// Look-ahead site features (with `site_features`, after `site_ping_pong`): at each of these
    /// distances (m) along the planned path ahead of the UAV's place on it, the site's predicted
    /// RSRP minus the predicted best (/ 10 dB, clipped to [−6, 0]). The prediction is the
    /// operator's map (RSRP without shadowing) sampled along the path every
    /// `env.predictive.sample_m`, plus the site's measured − map offset at the UAV fading with the
    /// distance ahead at the shadowing's decorrelation distance (TR 38.901 Table 7.5-6).
    /// Empty (the default): none. Needs the episode's planned path. A departure (map knowledge
    /// of the route ahead; docs/env.md "Look-ahead").
    pub site_lookahead_m: Vec<f64>,
    /// One more site feature (after the look-ahead distances): how far ahead along the planned
    /// path the site is predicted to stay within `site_stay_within_db` of the predicted best, as a
    /// fraction of `env.predictive.horizon_m` (0: not within it here; 1: the whole horizon).
    pub site_lookahead_stay: bool,
    /// The margin of `site_lookahead_stay` (dB).
    pub site_stay_within_db: f64,
    /// One more site feature (last): 1 for the site the predictive association would serve
    /// next (its plan at `site_prediction.handover_cost_db_m` times the episode's handover
    /// weight), else 0.
    pub site_predictive_choice: bool,
    /// The route prediction the look-ahead features read (the settings of `env.predictive`,
    /// recorded here so that a policy is flown with the prediction it was trained on whatever
    /// `env.predictive` says; `env.predictive` is the predictive association's).
    pub site_prediction: PredictiveConfig,
    /// Observe the episode's planned path (`path_guide`, 4 values after the goal fields): the
    /// unit direction to the point `path_lookahead_m` further along the planned path
    /// (`path_guide_lambda`) than the UAV's tracked place on it, and the path distance still to
    /// fly / `goal_scale_m`.
    /// Map knowledge the paper's UAV does not have (its sensors see 50 m): a departure against
    /// the timeouts of a reactive policy stuck behind a building (docs/env.md "Path
    /// guide"). On by default; `docs/paper_dupac.toml` turns it off.
    pub path_guide: bool,
    /// How far along the planned path the guide's direction points (m; default 10): a chord
    /// between points L/2 before and after a right-angle corner of the path passes L/(2√2)
    /// inside it, 3.5 m for L = 10, what the guide's 5 m clearance leaves the 1.5 m training
    /// sphere (docs/env.md "Path guide"). Recorded in the policy, which is flown with its own.
    pub path_lookahead_m: f64,
    /// Also observe how far off the planned path the UAV flies (`path_offset`, 3 values after
    /// `path_guide`, with it): (the UAV's tracked place on the path − its position) /
    /// [`PATH_OFFSET_SCALE_M`], each clipped to ±3. The guide's direction alone points at a place
    /// ahead on the path and does not say how far beside the path the UAV is; at a convex corner
    /// of a path planned `path_guide_clearance_m` from the buildings a UAV a few metres inside
    /// the chord is within the collision sphere of the corner (docs/env.md "Path guide"). Off by
    /// default (the default run is trained without it); recorded in the policy.
    pub path_offset: bool,
    /// The planned path of the guide (and of `env.reward.progress = "path"`): 0 = the shortest
    /// flyable path; λ > 0 = the coverage-aware planner's path with this λ (`planner.penalty_*`),
    /// so the guide leads through coverage as the planner would (map and coverage knowledge: a
    /// further departure; docs/env.md "Path guide"). Default 1.
    pub path_guide_lambda: f64,
    /// Clearance (m) from the building mesh of the guide's planned path: the planner is built
    /// with this clearance for the guide alone (`planner.clearance_m`, 1.5 m, keeps drawing the
    /// pairs and planning the planner methods). 0 = `planner.clearance_m`. A pair whose guide cannot be planned with it
    /// is guided along the path planned with `planner.clearance_m` instead (counted in the log).
    /// Default 5 m: paths that pass buildings at 1.5 m taught the policy to squeeze past them
    /// and doubled the collisions (docs/env.md "Path guide").
    pub path_guide_clearance_m: f64,
    /// Observe the episode's handover weight w (`env.reward.handover_weight`, drawn per episode
    /// in training with `env.reward.handover_weight_max`) as ln(1 + w), one value after the path
    /// guide: one policy then covers the trade-off of excellent time against handovers, set at
    /// flight time (a departure; docs/env.md "Handover weight"). Off by default.
    pub handover_weight: bool,
    /// Where each site's line-of-sight site feature comes from: `ray` = a ray cast from every
    /// site at every step (150 per decision with the site chosen every step: over half of an
    /// actor's time), `cache` = the RSRP cache's grid line of sight, interpolated like the RSRP
    /// the UAV observes beside it (it differs from the ray only within one grid cell of a
    /// shadow edge; docs/env.md "Observation"). Recorded in the policy: one trained with `ray` is
    /// flown with it.
    pub site_los: SiteLos,
}

impl EnvConfig {
    /// Whether each episode needs its planned path (`env.observation.path_guide` or
    /// `env.reward.progress = "path"`).
    pub fn needs_path(&self) -> bool {
        self.observation.path_guide || self.reward.progress == Progress::Path
    }

    /// The route prediction the environment makes, if any: the predictive association's
    /// (`env.predictive`), or the look-ahead site features' (`env.observation.site_prediction`)
    /// under the learned association (the only one whose site features are written). Both read
    /// the planned path when the episode has one, the straight line to the destination
    /// otherwise.
    pub fn route_prediction(&self) -> Option<&PredictiveConfig> {
        let o = &self.observation;
        match self.association {
            Association::Predictive => Some(&self.predictive),
            Association::Learned
                if o.site_features
                    && (!o.site_lookahead_m.is_empty()
                        || o.site_lookahead_stay
                        || o.site_predictive_choice) =>
            {
                Some(&o.site_prediction)
            }
            _ => None,
        }
    }

    /// Whether the environment predicts the route ahead ([`EnvConfig::route_prediction`]).
    pub fn predicts_route(&self) -> bool {
        self.route_prediction().is_some()
    }
}

impl Default for ObservationConfig {
    fn default() -> Self {
        Self {
            goal: true,
            sensor_fan: true,
            rsrp_all: true,
            rsrp_serving: true,
            sensor_range_m: 50.0,
            sensor_scale: SensorScale::Log,
            nearest_obstacle: NearestObstacle::Exact,
            geofence: true,
            goal_scale_m: 800.0,
            goal_direction: true,
            rsrp_centre_dbm: -90.0,
            rsrp_scale_db: 30.0,
            site_features: true,
            site_ping_pong: true,
            site_lookahead_m: Vec::new(),
            site_lookahead_stay: false,
            site_stay_within_db: 3.0,
            site_predictive_choice: false,
            site_prediction: PredictiveConfig::default(),
            path_guide: true,
            path_lookahead_m: 10.0,
            path_offset: false,
            path_guide_lambda: 1.0,
            path_guide_clearance_m: 5.0,
            handover_weight: false,
            site_los: SiteLos::Cache,
        }
    }
}

/// The UAV flight environment (spec/env.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct EnvConfig {
    /// Lowest flight altitude (m); moves are clamped to the band [z_min_m, z_max_m].
    pub z_min_m: f64,
    /// Highest flight altitude (m; 120 m: FAA Part 107).
    pub z_max_m: f64,
    /// UAV radius for collisions (m).
    pub uav_radius_m: f64,
    /// Training only: the UAV's sphere is this much larger in training rollouts (m), so a
    /// collision in training is coming within `uav_radius_m + training_margin_m` of a building and
    /// the policy learns to keep that margin; evaluation, flights and planners use `uav_radius_m`
    /// (see [`Config::training`]). 0 = train on the true sphere (the spec).
    pub training_margin_m: f64,
    /// Displacement per unit of the bounded action (m): the longest move of one step under
    /// `ball`, per axis under `cube`.
    pub max_step_m: f64,
    /// How the move is bounded: `cube` = per axis to [−1, 1] (spec/env.md), `ball` = onto the
    /// unit ball, so no move is longer than max_step_m (the speed of spec/env.md "Time" holds in
    /// every direction; under `cube` a policy gains up to √3 × the progress per step by flying
    /// the cube's diagonals, and its deterministic moves snap to those 26 directions).
    pub action_clip: ActionClip,
    /// Steps of the environment one decision of a policy lasts (frame skip, "action repeat" in
    /// dm_control's words): the policy observes and acts every `action_repeat` steps, the move
    /// and site it chose are applied to each, and their rewards add up. The environment itself,
    /// its metrics, the A3 rule and the planners keep the paper's 1 m step; 1 = the paper's
    /// decision every step (a departure for learning: at 1 m per decision γ = 0.95 sees 20 m
    /// ahead; docs/env.md "Where the defaults depart from spec/env.md").
    pub action_repeat: u32,
    /// Flight speed (m/s) fixing the step interval Δt = max_step_m / speed_mps.
    pub speed_mps: f64,
    /// Goal reached within this distance of the destination (m).
    pub goal_radius_m: f64,
    /// Time limit T = ceil(time_limit_factor × shortest path / max_step_m) steps.
    pub time_limit_factor: f64,
    /// How the serving site is chosen.
    pub association: Association,
    /// Where the environment gets RSRP from.
    pub radio_mode: RadioMode,
    /// A return to the previous site within this time is a ping-pong (s).
    pub ping_pong_window_s: f64,
    /// The learned site is chosen at every step of a decision, the move every `action_repeat`
    /// steps (a departure: the paper's hybrid action holds both for the decision).
    /// The site head scores the sites from their features at each step with the state
    /// embedding of the decision's observation, and every site's reward is recorded per step
    /// (`Env::step_site_rewards`). Why:
    /// held for 5 steps (240 ms) the choice loses SINR that A3 and the oracle, acting every
    /// step, keep (docs/training.md "Site learning"). Needs `ppo.site_head = "equivariant"` and
    /// `ppo.site_gradient = "all_sites"`. Default true; false = the paper.
    /// Learned association only.
    pub site_every_step: bool,
    /// A step whose site regret (best RSRP − serving RSRP) exceeds this is counted in the
    /// metric `pct_site_regret_high` (dB; a metric threshold, not part of the reward).
    pub site_regret_threshold_db: f64,
    /// The reward's terms and weights.
    pub reward: RewardConfig,
    /// What the policy observes.
    pub observation: ObservationConfig,
    /// The predictive association and the look-ahead site features' route prediction.
    pub predictive: PredictiveConfig,
}

/// A route prediction and plan (docs/env.md "Predictive association"): `[env.predictive]` for the
/// predictive association (`env.association = "predictive"`), `[env.observation.site_prediction]`
/// for the look-ahead site features.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PredictiveConfig {
    /// How far along the planned route ahead the rule plans (m; default 200).
    pub horizon_m: f64,
    /// Spacing of the route samples the prediction is made at (m; default 10).
    pub sample_m: f64,
    /// C, the cost of a handover in site regret (dB·m: a handover pays when it gains 1 dB over
    /// C metres of route, the hindsight association's dB·steps at 1 m steps); default 60. The
    /// look-ahead feature `site_predictive_choice` uses C times the episode's handover weight.
    pub handover_cost_db_m: f64,
}

impl Default for PredictiveConfig {
    fn default() -> Self {
        Self {
            horizon_m: 200.0,
            sample_m: 10.0,
            handover_cost_db_m: 60.0,
        }
    }
}

impl PredictiveConfig {
    /// Checks the section at `key` (`env.predictive` or `env.observation.site_prediction`).
    pub fn validate(&self, key: &str) -> Result<(), ConfigError> {
        within(&format!("{key}.sample_m"), self.sample_m, 0.5, 100.0, "m")?;
        within(
            &format!("{key}.horizon_m"),
            self.horizon_m,
            0.0,
            2_000.0,
            "m",
        )?;
        if self.horizon_m < self.sample_m {
            return Err(bad(
                &format!("{key}.horizon_m"),
                format!("must be at least {key}.sample_m"),
            ));
        }
        within(
            &format!("{key}.handover_cost_db_m"),
            self.handover_cost_db_m,
            0.0,
            1.0e6,
            "dB·m",
        )
    }
}

impl Default for EnvConfig {
    fn default() -> Self {
        Self {
            z_min_m: 20.0,
            z_max_m: 120.0,
            uav_radius_m: 0.5,
            training_margin_m: 1.0,
            max_step_m: 1.0,
            action_clip: ActionClip::Ball,
            action_repeat: 5,
            speed_mps: 75.0 / 3.6,
            goal_radius_m: 10.0,
            time_limit_factor: 3.0,
            association: Association::Learned,
            radio_mode: RadioMode::Cache,
            ping_pong_window_s: 1.0,
            site_every_step: true,
            site_regret_threshold_db: 3.0,
            reward: RewardConfig::default(),
            observation: ObservationConfig::default(),
            predictive: PredictiveConfig::default(),
        }
    }
}

impl EnvConfig {
    /// Step interval Δt (s) = max_step_m / speed_mps (spec/env.md "Time"); a decision of a
    /// policy lasts `action_repeat` of them.
    pub fn dt_s(&self) -> f64 {
        self.max_step_m / self.speed_mps
    }
}
impl EnvConfig {
    /// Checks `[env]` (the cache's vertical range bounds the flight band).
    pub(crate) fn validate(&self, c: &CacheConfig) -> Result<(), ConfigError> {
        let e = self;
        positive("env.z_min_m", e.z_min_m)?;
        if !(e.z_max_m.is_finite() && e.z_max_m > e.z_min_m) {
            return Err(bad("env.z_max_m", "must be > env.z_min_m"));
        }
        positive("env.uav_radius_m", e.uav_radius_m)?;
        if !(e.training_margin_m.is_finite() && e.training_margin_m >= 0.0) {
            return Err(bad("env.training_margin_m", "must be >= 0 m"));
        }
        positive("env.max_step_m", e.max_step_m)?;
        if !(1..=1000).contains(&e.action_repeat) {
            return Err(bad("env.action_repeat", "must be in 1..=1000 steps"));
        }
        positive("env.speed_mps", e.speed_mps)?;
        positive("env.goal_radius_m", e.goal_radius_m)?;
        positive("env.time_limit_factor", e.time_limit_factor)?;
        positive("env.ping_pong_window_s", e.ping_pong_window_s)?;
        positive("env.site_regret_threshold_db", e.site_regret_threshold_db)?;
        let rw = &e.reward;
        for (k, v) in [
            ("env.reward.mu1", rw.mu1),
            ("env.reward.mu2", rw.mu2),
            ("env.reward.mu3", rw.mu3),
            ("env.reward.goal_reward", rw.goal_reward),
            ("env.reward.collision_reward", rw.collision_reward),
            ("env.reward.out_of_bounds_reward", rw.out_of_bounds_reward),
            ("env.reward.handover_reward", rw.handover_reward),
        ] {
            finite(k, v)?;
        }
        for (k, v) in [
            ("env.reward.site_regret_weight", rw.site_regret_weight),
            (
                "env.reward.route_connectivity_weight",
                rw.route_connectivity_weight,
            ),
        ] {
            if !(v.is_finite() && (0.0..=1e3).contains(&v)) {
                return Err(bad(k, format!("must be in [0, 1000], got {v}")));
            }
        }
        if !(rw.ping_pong_reward.is_finite() && (-1e3..=0.0).contains(&rw.ping_pong_reward)) {
            return Err(bad(
                "env.reward.ping_pong_reward",
                format!("must be in [-1000, 0], got {}", rw.ping_pong_reward),
            ));
        }
        for (k, v) in [
            ("env.reward.handover_weight", rw.handover_weight),
            ("env.reward.handover_weight_max", rw.handover_weight_max),
        ] {
            within(k, v, 0.0, 100.0, "")?;
        }
        if rw.handover_weight_max > 0.0 && !e.observation.handover_weight {
            return Err(bad(
                "env.reward.handover_weight_max",
                "draws each episode's handover weight: set env.observation.handover_weight = true \
                 too, so the policy sees the cost it is charged (or this to 0)",
            ));
        }
        e.observation.validate()?;
        e.predictive.validate("env.predictive")?;
        if e.radio_mode == RadioMode::Cache && (c.z_min_m > e.z_min_m || c.z_max_m < e.z_max_m) {
            return Err(bad(
                "cache.z_min_m",
                "the RSRP cache must span the flight band env.z_min_m..env.z_max_m",
            ));
        }
        Ok(())
    }
}

impl ObservationConfig {
    /// Checks `[env.observation]` on its own (also what a policy's recorded observation must
    /// pass: [`crate::policy::PolicyWeights::configure`]).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let o = self;
        positive("env.observation.sensor_range_m", o.sensor_range_m)?;
        // Bounds the sensor's ray casts (also for a range a policy file records).
        within(
            "env.observation.sensor_range_m",
            o.sensor_range_m,
            0.0,
            10_000.0,
            "m",
        )?;
        positive("env.observation.goal_scale_m", o.goal_scale_m)?;
        finite("env.observation.rsrp_centre_dbm", o.rsrp_centre_dbm)?;
        positive("env.observation.rsrp_scale_db", o.rsrp_scale_db)?;
        if o.site_ping_pong && !o.site_features {
            return Err(bad(
                "env.observation.site_ping_pong",
                "is a site feature (on by default): set env.observation.site_features to true too, or this to false (and env.reward.ping_pong_reward to 0)",
            ));
        }
        if (!o.site_lookahead_m.is_empty() || o.site_lookahead_stay || o.site_predictive_choice)
            && !o.site_features
        {
            return Err(bad(
                "env.observation.site_lookahead_m",
                "look-ahead features (site_lookahead_m, site_lookahead_stay, site_predictive_choice) are site features: set env.observation.site_features to true",
            ));
        }
        if o.site_lookahead_m.len() > 16 {
            return Err(bad(
                "env.observation.site_lookahead_m",
                "at most 16 distances",
            ));
        }
        for &d in &o.site_lookahead_m {
            within("env.observation.site_lookahead_m", d, 0.0, 2_000.0, "m")?;
        }
        o.site_prediction
            .validate("env.observation.site_prediction")?;
        within(
            "env.observation.site_stay_within_db",
            o.site_stay_within_db,
            0.0,
            60.0,
            "dB",
        )?;
        positive("env.observation.path_lookahead_m", o.path_lookahead_m)?;
        within(
            "env.observation.path_guide_lambda",
            o.path_guide_lambda,
            0.0,
            1_000.0,
            "",
        )?;
        within(
            "env.observation.path_guide_clearance_m",
            o.path_guide_clearance_m,
            0.0,
            100.0,
            "m (0 = planner.clearance_m)",
        )?;
        within(
            "env.observation.path_lookahead_m",
            o.path_lookahead_m,
            0.0,
            10_000.0,
            "m",
        )?;
        Ok(())
    }
}
