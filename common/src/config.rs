//! The one DUPAC configuration: a TOML file whose every key has a serde default, that rejects
//! unknown keys, and that `--set a.b=v` overrides from the command line.
//!
//! Defaults follow `spec/radio.md` (radio), `spec/env.md` (scenario) and issue 2 (maps, cache).
//! [`Config::load`] parses, applies overrides and validates once; everything downstream receives a
//! resolved, valid [`Config`].

use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Errors while reading, overriding or validating the configuration. Each names the file, the
/// override or the key at fault.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config file {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("config file {path}: {message}")]
    Parse { path: String, message: String },
    #[error("--set {arg:?}: {message}")]
    Override { arg: String, message: String },
    #[error("config key `{key}`: {message}")]
    Invalid { key: String, message: String },
    /// [`ConfigError::Invalid`] found in a file (`origin`, with its `--set` overrides if any).
    #[error("config file {origin}: key `{key}`: {message}")]
    InvalidIn {
        origin: String,
        key: String,
        message: String,
    },
}

/// The whole configuration of a DUPAC run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    pub scenario: ScenarioConfig,
    pub radio: RadioConfig,
    pub map: MapConfig,
    pub cache: CacheConfig,
    pub env: EnvConfig,
    pub pairs: PairsConfig,
    pub planner: PlannerConfig,
    pub ppo: PpoConfig,
    pub train: TrainConfig,
    pub distributed: DistributedConfig,
}

/// Which kind of city a scenario is built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CityKind {
    /// Real OpenStreetMap footprints with heights from `scenario.buildings_file`.
    Osm,
    /// Seeded procedural Manhattan grid (`scenario.procedural`).
    Procedural,
}

/// How OSM building outlines that have 3D `building_part`s are extruded.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BuildingDetail {
    /// Outlines with parts are replaced by their parts (each from `min_height_m` to `height_m`).
    Parts,
    /// Every outline is extruded from the ground to its roof (conservative, over-estimates set-backs).
    Outlines,
}

/// A lon/lat box (WGS84 degrees). Each bound defaults to the Midtown flight area's, so that one
/// bound can be set alone (`--set scenario.area.lat_max_deg=40.76`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LonLatBox {
    pub lon_min_deg: f64,
    pub lon_max_deg: f64,
    pub lat_min_deg: f64,
    pub lat_max_deg: f64,
}

impl Default for LonLatBox {
    fn default() -> Self {
        ScenarioConfig::default().area
    }
}

impl LonLatBox {
    /// Centre of the box, `(lon, lat)` in degrees: the origin of the local ENU frame.
    pub fn centre_deg(&self) -> (f64, f64) {
        (
            0.5 * (self.lon_min_deg + self.lon_max_deg),
            0.5 * (self.lat_min_deg + self.lat_max_deg),
        )
    }
}

/// The scenario: which city, which flight area, where the base stations are.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScenarioConfig {
    /// Name written into caches and reports.
    pub name: String,
    pub city: CityKind,
    /// GeoJSON of building footprints (OSM export format of `data/README.md`).
    pub buildings_file: PathBuf,
    pub detail: BuildingDetail,
    /// The flight area (spec/env.md "World"); its centre is the frame origin.
    pub area: LonLatBox,
    /// LTE cell-site estimates (CSV with `lat,lon,...,enb_id`), used when `sites_file` is unset.
    pub cells_file: PathBuf,
    /// Optional explicit sites (CSV or TOML), replacing the placement from `cells_file`.
    pub sites_file: Option<PathBuf>,
    /// M, the number of GBSs (paper: 30).
    pub n_sites: usize,
    /// Roof search radius for mounting a site on a building (m).
    pub roof_search_m: f64,
    /// Mast height above the roof for a rooftop site (m).
    pub roof_mast_m: f64,
    /// Antenna height of a street-pole site when no roof is within `roof_search_m` (m).
    pub pole_height_m: f64,
    /// Radius within which the median rooftop height decides macro vs micro (m).
    pub macro_radius_m: f64,
    pub procedural: ProceduralConfig,
}

impl Default for ScenarioConfig {
    fn default() -> Self {
        Self {
            name: "midtown".into(),
            city: CityKind::Osm,
            buildings_file: "data/nyc_midtown_buildings.geojson".into(),
            detail: BuildingDetail::Parts,
            area: LonLatBox {
                lon_min_deg: -73.9935,
                lon_max_deg: -73.9765,
                lat_min_deg: 40.7460,
                lat_max_deg: 40.7590,
            },
            cells_file: "data/nyc_midtown_cells.csv".into(),
            sites_file: None,
            n_sites: 30,
            roof_search_m: 50.0,
            roof_mast_m: 3.0,
            pole_height_m: 10.0,
            macro_radius_m: 150.0,
            procedural: ProceduralConfig::default(),
        }
    }
}

/// The seeded Manhattan-grid generator, calibrated on Midtown (`data/README.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ProceduralConfig {
    pub seed: u64,
    /// Size of the square area (m); the frame origin is its centre.
    pub size_m: f64,
    /// Grid rotation, degrees east of true north (Manhattan: 29°).
    pub rotation_deg: f64,
    /// Street pitch along the avenues, centre to centre (m).
    pub street_pitch_m: f64,
    pub street_width_m: f64,
    /// Avenue spacing, centre to centre (m).
    pub avenue_spacing_m: f64,
    pub avenue_width_m: f64,
    /// Building height distribution: log-normal with this median and 90th percentile (m).
    pub height_median_m: f64,
    pub height_p90_m: f64,
    pub height_min_m: f64,
    pub height_max_m: f64,
    /// Number of sites placed on a jittered lattice over the area.
    pub n_sites: usize,
}

impl Default for ProceduralConfig {
    fn default() -> Self {
        Self {
            seed: 7,
            size_m: 1400.0,
            rotation_deg: 29.0,
            street_pitch_m: 79.0,
            street_width_m: 18.0,
            avenue_spacing_m: 274.0,
            avenue_width_m: 30.0,
            height_median_m: 30.0,
            height_p90_m: 95.0,
            height_min_m: 6.0,
            height_max_m: 400.0,
            n_sites: 30,
        }
    }
}

/// Antenna model (spec/radio.md §2, TR 38.901 Table 7.3-1 + vertical ULA).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AntennaConfig {
    /// G_E,max (dBi).
    pub element_gain_max_dbi: f64,
    /// θ_3dB (deg).
    pub theta_3db_deg: f64,
    /// φ_3dB (deg).
    pub phi_3db_deg: f64,
    /// SLA_V (dB).
    pub sla_v_db: f64,
    /// A_m, front-to-back ratio (dB).
    pub a_max_db: f64,
    /// N, elements of the vertical uniform linear array.
    pub n_elements: u32,
    /// Element spacing in wavelengths.
    pub spacing_wavelengths: f64,
    /// Electrical downtilt (deg); the beam points at θ = 90° + tilt.
    pub electrical_tilt_deg: f64,
    /// Sector boresights (deg, CCW from east).
    pub boresights_deg: Vec<f64>,
    /// Floor of |AF|² in linear power, only to avoid log10(0).
    pub af_floor_linear: f64,
    /// Optional floor on the composite gain (dBi); off by default (spec §2).
    pub gain_floor_dbi: Option<f64>,
}

impl Default for AntennaConfig {
    fn default() -> Self {
        Self {
            element_gain_max_dbi: 8.0,
            theta_3db_deg: 65.0,
            phi_3db_deg: 65.0,
            sla_v_db: 30.0,
            a_max_db: 30.0,
            n_elements: 8,
            spacing_wavelengths: 0.5,
            electrical_tilt_deg: 10.0,
            boresights_deg: vec![30.0, 150.0, 270.0],
            af_floor_linear: 1e-12,
            gain_floor_dbi: None,
        }
    }
}

/// A3 handover (spec/radio.md §4, TS 36.331 §5.5.4.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct A3Config {
    /// a3-Offset (dB).
    pub offset_db: f64,
    /// Hysteresis (dB).
    pub hysteresis_db: f64,
    /// timeToTrigger (ms).
    pub time_to_trigger_ms: f64,
    /// Optional L3 filter coefficient k (F = (1 − a)F + aM, a = 1/2^(k/4)); off by default.
    pub l3_filter_k: Option<u32>,
}

impl Default for A3Config {
    fn default() -> Self {
        Self {
            offset_db: 3.0,
            hysteresis_db: 1.0,
            time_to_trigger_ms: 160.0,
            l3_filter_k: None,
        }
    }
}

/// The radio model (spec/radio.md), every parameter with the paper's default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RadioConfig {
    /// Carrier frequency f_c (GHz).
    pub fc_ghz: f64,
    /// Reference-signal power per RE, P (dBm).
    pub tx_power_dbm: f64,
    /// UE (UAV) antenna gain (dBi).
    pub ue_gain_dbi: f64,
    /// h_UT clamp, lower end (m) (D3).
    pub h_ut_min_m: f64,
    /// Terrestrial/aerial band split (m): h ≤ this is terrestrial (D4).
    pub h_ut_band_split_m: f64,
    /// h_UT clamp, upper end (m) (D3).
    pub h_ut_max_m: f64,
    /// Smallest d3D used in a log (m), a guard against log(0) only.
    pub d3d_min_m: f64,
    /// RSRP class C1 lower bound: excellent when RSRP ≥ this (dBm).
    pub rsrp_excellent_dbm: f64,
    /// RSRP class C2 lower bound: poor when RSRP < this (dBm).
    pub rsrp_poor_dbm: f64,
    pub antenna: AntennaConfig,
    pub a3: A3Config,
}

impl Default for RadioConfig {
    fn default() -> Self {
        Self {
            fc_ghz: 2.0,
            tx_power_dbm: 15.2,
            ue_gain_dbi: 0.0,
            h_ut_min_m: 1.5,
            h_ut_band_split_m: 22.5,
            h_ut_max_m: 300.0,
            d3d_min_m: 1.0,
            rsrp_excellent_dbm: -80.0,
            rsrp_poor_dbm: -100.0,
            antenna: AntennaConfig::default(),
            a3: A3Config::default(),
        }
    }
}

/// Coverage maps (`dupac map`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MapConfig {
    /// Altitudes of the horizontal slices (m above ground).
    pub altitudes_m: Vec<f64>,
    /// Grid resolution (m).
    pub resolution_m: f64,
    /// Output directory.
    pub out_dir: PathBuf,
}

impl Default for MapConfig {
    fn default() -> Self {
        Self {
            altitudes_m: vec![30.0, 60.0, 90.0, 120.0],
            resolution_m: 5.0,
            out_dir: "out/map".into(),
        }
    }
}

/// The per-site 3D RSRP cache used by the environment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CacheConfig {
    /// Horizontal grid step (m).
    pub horizontal_m: f64,
    /// Vertical grid step (m).
    pub vertical_m: f64,
    /// Lowest and highest altitude of the grid (m): the UAV altitude band of spec/env.md.
    pub z_min_m: f64,
    pub z_max_m: f64,
    /// Cache file; rebuilt when its header does not match the scenario and radio config.
    pub path: PathBuf,
}

impl Default for CacheConfig {
    fn default() -> Self {
        Self {
            horizontal_m: 5.0,
            vertical_m: 5.0,
            z_min_m: 20.0,
            z_max_m: 120.0,
            path: "out/cache/rsrp.bin".into(),
        }
    }
}

/// Scaling of obstacle-sensor distances into [0, 1] (see [`ObservationConfig::sensor_scale`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SensorScale {
    /// d / range (spec/env.md "Observation").
    Linear,
    /// ln(1 + d / 1 m) / ln(1 + range / 1 m).
    Log,
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NearestObstacle {
    /// The shortest ray of the sensor fan (spec/env.md "Observation").
    Fan,
    /// The nearest surface point of the building mesh.
    Exact,
}

/// How the action's move a ∈ ℝ³ becomes a displacement (see [`EnvConfig::action_clip`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Association {
    /// DUPAC: the action's discrete part picks the serving site.
    Learned,
    /// The paper's base method: the A3 rule of spec/radio.md §4.
    A3,
    /// Oracle (evaluation only): always the strongest site.
    BestRsrp,
}

/// The network that scores sites (see [`PpoConfig::site_head`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SiteHead {
    /// M logits of the actor MLP, one per slot (the paper).
    Slots,
    /// A per-site MLP shared by all sites over their own features and a state embedding.
    Equivariant,
}

/// The estimator of the site head's gradient (see [`PpoConfig::site_gradient`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SiteGradient {
    /// PPO on the sampled site, one joint ratio with the move (the paper).
    Sampled,
    /// Σ_k ∇π(k|s) · A_k over every site k, with A_k from each site's own decision reward.
    AllSites,
}

/// How far the all-sites site advantage looks (see [`PpoConfig::site_horizon`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SiteHorizon {
    /// Each site's reward of this decision alone (handover cost included): myopic.
    Decision,
    /// Plus the discounted value of the best association over the rest of the recorded route
    /// with that site serving (a dynamic programme with the handover cost; `learner/site_horizon.rs`).
    Route,
}

/// Where the environment gets RSRP from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RadioMode {
    /// The memory-mapped per-site grid (`cache.*`), trilinear interpolation.
    Cache,
    /// A line-of-sight ray cast per site per step (validation).
    Exact,
}

/// Reward of paper Eq. (8) plus the terminal terms of spec/env.md.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// Reward added per handover (the paper has none: 0). A departure by default (−3): the learned
    /// association has no hysteresis or time-to-trigger as A3 does, and without a cost a policy
    /// that is indifferent among sites switches freely. With `site_regret_weight` = 1 a switch
    /// pays within one decision (5 steps) when the new site is ≥ 0.6 dB stronger (docs/env.md,
    /// docs/results.md "w_s and the handover cost", issue 15).
    pub handover_reward: f64,
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
            handover_reward: -3.0,
            site_regret_weight: 1.0,
            route_connectivity_weight: 0.5,
        }
    }
}

/// Which parts of the observation are present (spec/env.md "Observation"); each addition to the
/// paper's state can be switched off for ablations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    pub rsrp_scale_db: f64,
    /// Per-site features for the permutation-equivariant site head (`ppo.site_head =
    /// "equivariant"`), [`crate::obs::SITE_FEATURES`] values per site on a fixed physical scale,
    /// at the end of the observation; the actor and critic MLPs do not read them. Written only
    /// under `env.association = "learned"` (zeros otherwise). A departure (issue 15).
    pub site_features: bool,
    /// One more site feature (with `site_features`): each site's RSRP change since the previous
    /// observation ([`crate::obs::site_feature::RSRP_TREND`]), a one-decision memory from which
    /// the site head can tell a rising site from a passing peak (A3 has its time-to-trigger for
    /// that). Off by default (issue 15; measured in docs/results.md "What any association can do").
    pub site_trend: bool,
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
            site_trend: false,
        }
    }
}

/// The UAV flight environment (spec/env.md).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EnvConfig {
    /// Lowest and highest flight altitude (m); moves are clamped to the band (FAA Part 107).
    pub z_min_m: f64,
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
    pub association: Association,
    pub radio_mode: RadioMode,
    /// A return to the previous site within this time is a ping-pong (s).
    pub ping_pong_window_s: f64,
    /// Minimum time of stay of the learned association (s): no handover within this time of the
    /// previous one (the step of the handover + ceil(T / Δt) steps, inclusive); the site chosen
    /// meanwhile is ignored and every site's reward is the serving one's, so the choice gets no
    /// gradient. 3GPP TR 36.839 calls a handover back within the minimum time of stay (1 s) a
    /// ping-pong; this makes the learned rule keep it, as A3's hysteresis and time-to-trigger
    /// do heuristically. 0 = off (the paper: a free choice every decision). Learned association
    /// only (issue 15; docs/env.md, docs/results.md "What any association can do").
    pub min_time_of_stay_s: f64,
    /// A step whose site regret (best RSRP − serving RSRP) exceeds this is counted in the
    /// metric `pct_site_regret_high` (dB; issue 15: a metric threshold, not part of the reward).
    pub site_regret_threshold_db: f64,
    pub reward: RewardConfig,
    pub observation: ObservationConfig,
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
            min_time_of_stay_s: 0.0,
            site_regret_threshold_db: 3.0,
            reward: RewardConfig::default(),
            observation: ObservationConfig::default(),
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

/// Source/destination pairs (spec/env.md "Episodes").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PairsConfig {
    /// Training pairs: shortest flyable path length uniform in [min_m, max_m].
    pub min_m: f64,
    pub max_m: f64,
    /// Endpoints keep at least this clearance from buildings (m).
    pub endpoint_clearance_m: f64,
    /// Held-out evaluation bins (shortest path, m), ± `bin_tolerance` (fraction).
    pub eval_bins_m: Vec<f64>,
    pub bin_tolerance: f64,
    /// Pairs per evaluation bin (K).
    pub eval_per_bin: usize,
    pub eval_seed: u64,
    /// Where `dupac pairs` writes the evaluation set.
    pub eval_file: PathBuf,
}

impl Default for PairsConfig {
    fn default() -> Self {
        Self {
            min_m: 200.0,
            max_m: 800.0,
            endpoint_clearance_m: 5.0,
            eval_bins_m: vec![200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0],
            bin_tolerance: 0.05,
            eval_per_bin: 50,
            eval_seed: 2024,
            eval_file: "out/pairs/eval_pairs.jsonl".into(),
        }
    }
}

/// The voxel planners (shortest flyable path, coverage-aware path).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PlannerConfig {
    /// Voxel edge (m).
    pub voxel_m: f64,
    /// Clearance kept from buildings (m); must be ≥ env.uav_radius_m.
    pub clearance_m: f64,
    /// λ of the coverage-aware planner: edge cost = length · (1 + λ · penalty(class)).
    pub lambda: f64,
    /// Penalty per metre by RSRP class of the best site (excellent is 0).
    pub penalty_mediocre: f64,
    pub penalty_poor: f64,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        Self {
            voxel_m: 5.0,
            clearance_m: 1.5,
            lambda: 1.0,
            penalty_mediocre: 1.0,
            penalty_poor: 10.0,
        }
    }
}

/// PPO hyperparameters (issue 4; paper Sec. IV-A for lr, γ, ε; the rest CleanRL's
/// `ppo_continuous_action.py` defaults unless noted).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PpoConfig {
    /// Adam learning rate (paper: 3e-4).
    pub learning_rate: f64,
    /// Linear annealing of the learning rate to 0 over the run.
    pub anneal_lr: bool,
    /// Discount γ (paper: 0.95).
    pub gamma: f64,
    /// GAE λ.
    pub gae_lambda: f64,
    /// Minibatches per epoch (minibatch = num_envs × num_steps / num_minibatches).
    pub num_minibatches: usize,
    /// Epochs over each batch.
    pub update_epochs: usize,
    /// Normalise advantages per minibatch.
    pub norm_adv: bool,
    /// Clip ε of the surrogate (paper: 0.2).
    pub clip_coef: f64,
    /// Clip the value loss like the surrogate.
    pub clip_vloss: bool,
    /// Entropy bonus of the move Gaussian.
    pub ent_coef_move: f64,
    /// Entropy bonus of the site categorical.
    pub ent_coef_site: f64,
    /// Weight of the value loss.
    pub vf_coef: f64,
    /// Global gradient-norm clip (over both networks and the log-std).
    pub max_grad_norm: f64,
    /// Stop the epochs of an update early when the approximate KL exceeds this (0 = off).
    pub target_kl: f64,
    /// Adam ε.
    pub adam_eps: f64,
    /// Hidden layer widths of both MLPs.
    pub hidden: Vec<usize>,
    /// The site head: `slots` = M logits of the actor MLP (the paper), `equivariant` = one small
    /// network shared by all sites scoring each from its own features (issue 15).
    pub site_head: SiteHead,
    /// How the site head learns: `sampled` = the paper's PPO on the sampled site (one joint ratio
    /// and clip with the move), `all_sites` = the exact expected gradient over every site's
    /// reward (the environment evaluates all of them), apart from the move's ratio and clip.
    pub site_gradient: SiteGradient,
    /// The all-sites advantage's horizon: `decision` = each site's decision reward (myopic: the
    /// cost of a switch is seen, not the cost of switching back), `route` = plus the best
    /// association's value over the rest of the recorded route from that site (issue 15,
    /// docs/training.md "Site learning"). Read only with `site_gradient = "all_sites"`.
    pub site_horizon: SiteHorizon,
    /// Width of the state embedding the equivariant head appends to each site's features.
    pub site_embed: usize,
    /// Hidden widths of the equivariant head's per-site MLP.
    pub site_hidden: Vec<usize>,
    /// Weight of the all-sites loss (`site_gradient = "all_sites"`).
    pub site_coef: f64,
    /// Initial log-std of the move Gaussian.
    pub init_log_std: f64,
    /// Normalise observations by running mean/variance, clipped to ±obs_clip.
    pub normalize_obs: bool,
    pub obs_clip: f64,
    /// Scale rewards by the running std of the discounted return, clipped to ±reward_clip.
    pub normalize_reward: bool,
    pub reward_clip: f64,
    /// Consecutive updates skipped for numerical faults (a non-finite observation, reward or
    /// value in the batch, or non-finite weights after the update) before the run stops with an
    /// error; 0 = never stop. A skipped update leaves the weights, optimiser and normalisers as
    /// they were (issue 7, docs/reliability.md).
    pub max_bad_updates: u32,
}

impl Default for PpoConfig {
    fn default() -> Self {
        Self {
            learning_rate: 3e-4,
            anneal_lr: true,
            gamma: 0.95,
            gae_lambda: 0.95,
            num_minibatches: 8,
            update_epochs: 4,
            norm_adv: true,
            clip_coef: 0.2,
            clip_vloss: true,
            ent_coef_move: 0.0,
            ent_coef_site: 0.001,
            vf_coef: 0.5,
            max_grad_norm: 0.5,
            target_kl: 0.0,
            adam_eps: 1e-5,
            hidden: vec![256, 256],
            site_head: SiteHead::Equivariant,
            site_gradient: SiteGradient::AllSites,
            site_horizon: SiteHorizon::Decision,
            site_embed: 16,
            site_hidden: vec![32],
            site_coef: 1.0,
            init_log_std: 0.0,
            normalize_obs: true,
            obs_clip: 10.0,
            normalize_reward: true,
            reward_clip: 10.0,
            max_bad_updates: 5,
        }
    }
}

/// The training run (`dupac train`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Seed of the run: network init, action sampling, episode pairs and resets.
    pub seed: u64,
    /// Total timesteps (samples): decisions of the policy, each `env.action_repeat` steps of the
    /// environment.
    pub total_timesteps: u64,
    /// Parallel environments (stepped on worker threads).
    pub num_envs: usize,
    /// Decisions per environment per rollout (batch = num_envs × num_steps).
    pub num_steps: usize,
    /// Training pairs in the pool episodes are drawn from (`pairs.min_m..max_m`).
    pub pool_size: usize,
    /// Output directory: checkpoints, metrics, curves, exported policy.
    pub out_dir: PathBuf,
    /// Write a checkpoint every this many updates (and at the end).
    pub checkpoint_every: u64,
    /// Evaluate the deterministic policy on `eval_pairs` held-out pairs every this many updates
    /// (0 = only at the end).
    pub eval_every: u64,
    pub eval_pairs: usize,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            seed: 1,
            total_timesteps: 4_000_000,
            num_envs: 16,
            num_steps: 256,
            pool_size: 2000,
            out_dir: "out/train".into(),
            checkpoint_every: 10,
            eval_every: 25,
            eval_pairs: 70,
        }
    }
}

/// The Zenoh actor/learner system (`dupac train`, `dupac learner`, `dupac actor`; issue 5).
/// The learner's batch is still `train.num_envs × train.num_steps` samples, whatever the number
/// of actors: it is filled with chunks of `actor_envs × chunk_steps` samples.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DistributedConfig {
    /// Run name: every key expression is `dupac/<run>/…` (letters, digits, `-`, `_`).
    pub run: String,
    /// Actor processes `dupac train` starts (0 = one per core).
    pub actors: usize,
    /// Environments each actor process steps (on its own threads).
    pub actor_envs: usize,
    /// Steps per environment in one trajectory chunk.
    pub chunk_steps: usize,
    /// Chunks an actor publishes per policy version before it waits for the next one (0 =
    /// its share of a learner batch: ⌈train.num_envs × train.num_steps / (actor_envs ×
    /// chunk_steps × actors alive)⌉). Actors faster than the learner would otherwise mostly
    /// produce data that is dropped as stale, on cores the learner needs. On dedicated actor
    /// hosts, one more than the share keeps actors busy during updates (that data arrives one
    /// version old and is trained with the decoupled correction).
    pub max_chunks_per_version: usize,
    /// Oldest policy accepted: data from version `v − max_policy_lag` or newer trains version
    /// `v`; older data is dropped and counted (`stale`).
    pub max_policy_lag: u64,
    /// Decoupled PPO (Hilton et al. 2021) for data from an older version: the clipped ratio is
    /// taken against the current (proximal) policy, and the advantage weighted by
    /// π_prox / π_behaviour, capped at `max_importance_weight`.
    pub decoupled_correction: bool,
    pub max_importance_weight: f64,
    /// Hard cap on any received message (MiB); larger ones are dropped unread.
    pub max_message_mib: f64,
    /// Chunks the learner's receive queue holds; when full the oldest is dropped (`overflow`).
    pub queue_chunks: usize,
    /// An actor that published nothing for this long is reported silent (s).
    pub silent_after_s: f64,
    /// An actor that has sent its share for the current version and still sees the learner at
    /// that version this many seconds after the swap sends another share: its chunks were lost
    /// (router restart, partition; delivery is at most once). Longer than a PPO update.
    pub resend_after_s: f64,
    /// Interval of the stats messages of learner and actors (s).
    pub stats_every_s: f64,
    /// Replies per second the learner's weights queryable gives at most (each copies the whole
    /// policy), with a burst of twice that: actors and pilots query once when they join, a
    /// flood of queries is left unanswered (issue 16).
    pub weights_replies_per_s: f64,
}

impl Default for DistributedConfig {
    fn default() -> Self {
        Self {
            run: "default".into(),
            actors: 0,
            actor_envs: 4,
            chunk_steps: 128,
            max_chunks_per_version: 0,
            max_policy_lag: 1,
            decoupled_correction: true,
            max_importance_weight: 2.0,
            max_message_mib: 64.0,
            queue_chunks: 256,
            silent_after_s: 10.0,
            resend_after_s: 5.0,
            stats_every_s: 1.0,
            weights_replies_per_s: 10.0,
        }
    }
}

impl DistributedConfig {
    /// [`DistributedConfig::max_chunks_per_version`] resolved for a learner batch of
    /// `batch_samples` shared by `actors` actors.
    pub fn chunks_per_version(&self, batch_samples: usize, actors: usize) -> usize {
        if self.max_chunks_per_version > 0 {
            return self.max_chunks_per_version;
        }
        let per_actor = (self.actor_envs * self.chunk_steps * actors.max(1)).max(1);
        batch_samples.div_ceil(per_actor)
    }

    /// The message size cap in bytes.
    pub fn max_message_bytes(&self) -> usize {
        (self.max_message_mib * 1024.0 * 1024.0) as usize
    }
}

/// Largest configuration file read (bytes): a real one is a few KiB.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

impl Config {
    /// The configuration training rollouts step their environments with: the UAV's sphere
    /// grown by `env.training_margin_m` (then 0, so it is never applied twice). Evaluation and
    /// flights use `self` unchanged.
    pub fn training(&self) -> Config {
        let mut c = self.clone();
        c.env.uav_radius_m += c.env.training_margin_m;
        c.env.training_margin_m = 0.0;
        c
    }

    /// Identifies everything that makes one process's environment steps and policy shapes
    /// differ from another's: the radio world (`world_fingerprint`: city, sites, RSRP
    /// parameters), the radio, cache, environment, pairs and planner sections and the network
    /// widths. Actors whose fingerprint differs from the learner's are refused (issue 5); the
    /// PPO hyperparameters, seeds and output paths do not count.
    pub fn env_fingerprint(&self, world_fingerprint: u64) -> u64 {
        let mut h = crate::fingerprint::Fnv64::new();
        h.write_u64(world_fingerprint);
        // File locations may differ between hosts; only contents count.
        let mut cache = self.cache.clone();
        cache.path = PathBuf::new();
        let mut pairs = self.pairs.clone();
        pairs.eval_file = PathBuf::new();
        for part in [
            serde_json::to_string(&self.radio),
            serde_json::to_string(&cache),
            serde_json::to_string(&self.env),
            serde_json::to_string(&pairs),
            serde_json::to_string(&self.planner),
            serde_json::to_string(&self.ppo.hidden),
        ] {
            h.write_str(&part.unwrap_or_default());
        }
        h.finish()
    }

    /// Parses a TOML string (`origin` names it in errors), applies `--set` overrides, validates.
    /// An error of the file names its line and key; one an override causes names the override.
    pub fn from_toml_str(text: &str, origin: &str, sets: &[String]) -> Result<Config, ConfigError> {
        let parse_err = |e: toml::de::Error| ConfigError::Parse {
            path: origin.to_string(),
            message: e.to_string(),
        };
        // Deserialised from the text itself (not from a parsed table) so that errors carry the
        // line and column.
        let mut config: Config = toml::from_str(text).map_err(parse_err)?;
        if !sets.is_empty() {
            let mut value: toml::Table = toml::from_str(text).map_err(parse_err)?;
            // The override after which the configuration stopped deserialising (and why); later
            // overrides may complete it again (e.g. the bounds of `scenario.area` one by one).
            let mut broken_by: Option<(&String, toml::de::Error)> = None;
            for arg in sets {
                apply_override(&mut value, arg)?;
                match Config::deserialize(toml::Value::Table(value.clone())) {
                    Ok(c) => {
                        config = c;
                        broken_by = None;
                    }
                    Err(e) => {
                        broken_by.get_or_insert((arg, e));
                    }
                }
            }
            if let Some((arg, e)) = broken_by {
                return Err(ConfigError::Override {
                    arg: arg.clone(),
                    message: e.to_string(),
                });
            }
        }
        config.validate().map_err(|e| match e {
            ConfigError::Invalid { key, message } => {
                // The last override that sets the key (or a table holding it) is to blame.
                let set_key = |arg: &String| {
                    arg.split_once('=').is_some_and(|(k, _)| {
                        let k = k.trim();
                        key == k || key.strip_prefix(k).is_some_and(|r| r.starts_with('.'))
                    })
                };
                match sets.iter().rev().find(|a| set_key(a)) {
                    Some(arg) => ConfigError::Override {
                        arg: arg.clone(),
                        message: format!("key `{key}`: {message}"),
                    },
                    None => ConfigError::InvalidIn {
                        origin: if sets.is_empty() {
                            origin.to_string()
                        } else {
                            format!("{origin} (with --set overrides)")
                        },
                        key,
                        message,
                    },
                }
            }
            other => other,
        })?;
        Ok(config)
    }

    /// Loads `path` (at most [`MAX_CONFIG_BYTES`]; the defaults when `None`), applies
    /// `--set a.b=v` overrides, validates.
    pub fn load(path: Option<&Path>, sets: &[String]) -> Result<Config, ConfigError> {
        match path {
            Some(p) => {
                let read = |source| ConfigError::Read {
                    path: p.to_path_buf(),
                    source,
                };
                let len = std::fs::metadata(p).map_err(read)?.len();
                if len > MAX_CONFIG_BYTES {
                    return Err(ConfigError::Parse {
                        path: p.display().to_string(),
                        message: format!(
                            "{len} bytes: a configuration file is at most {MAX_CONFIG_BYTES} bytes"
                        ),
                    });
                }
                let bytes = std::fs::read(p).map_err(read)?;
                let text = String::from_utf8(bytes).map_err(|e| ConfigError::Parse {
                    path: p.display().to_string(),
                    message: format!("not UTF-8 at byte {}", e.utf8_error().valid_up_to()),
                })?;
                Self::from_toml_str(&text, &p.display().to_string(), sets)
            }
            None => Self::from_toml_str("", "<defaults>", sets),
        }
    }

    /// The configuration as TOML (what a run records next to its outputs).
    pub fn to_toml_string(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_else(|e| format!("# cannot serialise config: {e}"))
    }

    /// Range checks that serde cannot express; each error names the key.
    pub fn validate(&self) -> Result<(), ConfigError> {
        fn bad(key: &str, message: impl Into<String>) -> ConfigError {
            ConfigError::Invalid {
                key: key.to_string(),
                message: message.into(),
            }
        }
        fn positive(key: &str, v: f64) -> Result<(), ConfigError> {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(bad(key, format!("must be a finite number > 0, got {v}")))
            }
        }
        fn finite(key: &str, v: f64) -> Result<(), ConfigError> {
            if v.is_finite() {
                Ok(())
            } else {
                Err(bad(key, format!("must be finite, got {v}")))
            }
        }
        let s = &self.scenario;
        let a = &s.area;
        for (k, v) in [
            ("scenario.area.lon_min_deg", a.lon_min_deg),
            ("scenario.area.lon_max_deg", a.lon_max_deg),
        ] {
            if !(v.is_finite() && (-180.0..=180.0).contains(&v)) {
                return Err(bad(
                    k,
                    format!("must be a longitude in [-180, 180], got {v}"),
                ));
            }
        }
        for (k, v) in [
            ("scenario.area.lat_min_deg", a.lat_min_deg),
            ("scenario.area.lat_max_deg", a.lat_max_deg),
        ] {
            if !(v.is_finite() && (-85.0..=85.0).contains(&v)) {
                return Err(bad(k, format!("must be a latitude in [-85, 85], got {v}")));
            }
        }
        if a.lon_min_deg >= a.lon_max_deg {
            return Err(bad("scenario.area.lon_max_deg", "must be > lon_min_deg"));
        }
        if a.lat_min_deg >= a.lat_max_deg {
            return Err(bad("scenario.area.lat_max_deg", "must be > lat_min_deg"));
        }
        if s.n_sites == 0 || s.n_sites > usize::from(u16::MAX) {
            return Err(bad("scenario.n_sites", "must be in 1..=65535"));
        }
        positive("scenario.roof_search_m", s.roof_search_m)?;
        finite("scenario.roof_mast_m", s.roof_mast_m)?;
        positive("scenario.pole_height_m", s.pole_height_m)?;
        positive("scenario.macro_radius_m", s.macro_radius_m)?;
        let p = &s.procedural;
        positive("scenario.procedural.size_m", p.size_m)?;
        finite("scenario.procedural.rotation_deg", p.rotation_deg)?;
        positive("scenario.procedural.street_pitch_m", p.street_pitch_m)?;
        positive("scenario.procedural.avenue_spacing_m", p.avenue_spacing_m)?;
        if !(p.street_width_m >= 0.0 && p.street_width_m < p.street_pitch_m) {
            return Err(bad(
                "scenario.procedural.street_width_m",
                "must be in [0, street_pitch_m)",
            ));
        }
        if !(p.avenue_width_m >= 0.0 && p.avenue_width_m < p.avenue_spacing_m) {
            return Err(bad(
                "scenario.procedural.avenue_width_m",
                "must be in [0, avenue_spacing_m)",
            ));
        }
        positive("scenario.procedural.height_median_m", p.height_median_m)?;
        if !(p.height_p90_m.is_finite() && p.height_p90_m > p.height_median_m) {
            return Err(bad(
                "scenario.procedural.height_p90_m",
                "must be > height_median_m",
            ));
        }
        positive("scenario.procedural.height_min_m", p.height_min_m)?;
        if !(p.height_max_m.is_finite() && p.height_max_m > p.height_min_m) {
            return Err(bad(
                "scenario.procedural.height_max_m",
                "must be > height_min_m",
            ));
        }
        if p.n_sites == 0 || p.n_sites > usize::from(u16::MAX) {
            return Err(bad("scenario.procedural.n_sites", "must be in 1..=65535"));
        }

        let r = &self.radio;
        positive("radio.fc_ghz", r.fc_ghz)?;
        finite("radio.tx_power_dbm", r.tx_power_dbm)?;
        finite("radio.ue_gain_dbi", r.ue_gain_dbi)?;
        positive("radio.h_ut_min_m", r.h_ut_min_m)?;
        if !(r.h_ut_min_m <= r.h_ut_band_split_m && r.h_ut_band_split_m <= r.h_ut_max_m) {
            return Err(bad(
                "radio.h_ut_band_split_m",
                "must satisfy h_ut_min_m <= h_ut_band_split_m <= h_ut_max_m",
            ));
        }
        positive("radio.d3d_min_m", r.d3d_min_m)?;
        finite("radio.rsrp_excellent_dbm", r.rsrp_excellent_dbm)?;
        if !(r.rsrp_poor_dbm.is_finite() && r.rsrp_poor_dbm < r.rsrp_excellent_dbm) {
            return Err(bad("radio.rsrp_poor_dbm", "must be < rsrp_excellent_dbm"));
        }
        let an = &r.antenna;
        finite(
            "radio.antenna.element_gain_max_dbi",
            an.element_gain_max_dbi,
        )?;
        positive("radio.antenna.theta_3db_deg", an.theta_3db_deg)?;
        positive("radio.antenna.phi_3db_deg", an.phi_3db_deg)?;
        positive("radio.antenna.sla_v_db", an.sla_v_db)?;
        positive("radio.antenna.a_max_db", an.a_max_db)?;
        if an.n_elements == 0 || an.n_elements > 1024 {
            return Err(bad("radio.antenna.n_elements", "must be in 1..=1024"));
        }
        positive("radio.antenna.spacing_wavelengths", an.spacing_wavelengths)?;
        if !(an.electrical_tilt_deg.is_finite() && (-90.0..=90.0).contains(&an.electrical_tilt_deg))
        {
            return Err(bad(
                "radio.antenna.electrical_tilt_deg",
                "must be in [-90, 90]",
            ));
        }
        if an.boresights_deg.is_empty() || an.boresights_deg.iter().any(|b| !b.is_finite()) {
            return Err(bad(
                "radio.antenna.boresights_deg",
                "must be a non-empty list of finite angles",
            ));
        }
        positive("radio.antenna.af_floor_linear", an.af_floor_linear)?;
        if let Some(g) = an.gain_floor_dbi {
            finite("radio.antenna.gain_floor_dbi", g)?;
        }
        let a3 = &r.a3;
        if !(a3.offset_db.is_finite() && (-15.0..=15.0).contains(&a3.offset_db)) {
            return Err(bad(
                "radio.a3.offset_db",
                "must be in [-15, 15] dB (TS 36.331)",
            ));
        }
        if !(a3.hysteresis_db.is_finite() && (0.0..=15.0).contains(&a3.hysteresis_db)) {
            return Err(bad(
                "radio.a3.hysteresis_db",
                "must be in [0, 15] dB (TS 36.331)",
            ));
        }
        if !(a3.time_to_trigger_ms.is_finite() && a3.time_to_trigger_ms >= 0.0) {
            return Err(bad("radio.a3.time_to_trigger_ms", "must be >= 0"));
        }
        if let Some(k) = a3.l3_filter_k
            && k > 19
        {
            return Err(bad("radio.a3.l3_filter_k", "must be in 0..=19 (TS 36.331)"));
        }

        let m = &self.map;
        if m.altitudes_m.is_empty() {
            return Err(bad("map.altitudes_m", "must list at least one altitude"));
        }
        for h in &m.altitudes_m {
            if !(h.is_finite() && *h >= 0.0 && *h <= 1000.0) {
                return Err(bad(
                    "map.altitudes_m",
                    format!("altitude {h} not in [0, 1000] m"),
                ));
            }
        }
        if !(m.resolution_m.is_finite() && m.resolution_m >= 0.5) {
            return Err(bad("map.resolution_m", "must be >= 0.5 m"));
        }
        let c = &self.cache;
        if !(c.horizontal_m.is_finite() && c.horizontal_m >= 0.5) {
            return Err(bad("cache.horizontal_m", "must be >= 0.5 m"));
        }
        if !(c.vertical_m.is_finite() && c.vertical_m >= 0.5) {
            return Err(bad("cache.vertical_m", "must be >= 0.5 m"));
        }
        finite("cache.z_min_m", c.z_min_m)?;
        if !(c.z_max_m.is_finite() && c.z_max_m > c.z_min_m) {
            return Err(bad("cache.z_max_m", "must be > cache.z_min_m"));
        }

        let e = &self.env;
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
        if !(e.min_time_of_stay_s.is_finite() && (0.0..=60.0).contains(&e.min_time_of_stay_s)) {
            return Err(bad("env.min_time_of_stay_s", "must be in [0, 60] s"));
        }
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
        let o = &e.observation;
        positive("env.observation.sensor_range_m", o.sensor_range_m)?;
        positive("env.observation.goal_scale_m", o.goal_scale_m)?;
        finite("env.observation.rsrp_centre_dbm", o.rsrp_centre_dbm)?;
        positive("env.observation.rsrp_scale_db", o.rsrp_scale_db)?;
        if e.radio_mode == RadioMode::Cache && (c.z_min_m > e.z_min_m || c.z_max_m < e.z_max_m) {
            return Err(bad(
                "cache.z_min_m",
                "the RSRP cache must span the flight band env.z_min_m..env.z_max_m",
            ));
        }

        let pr = &self.pairs;
        positive("pairs.min_m", pr.min_m)?;
        if !(pr.max_m.is_finite() && pr.max_m >= pr.min_m) {
            return Err(bad("pairs.max_m", "must be >= pairs.min_m"));
        }
        finite("pairs.endpoint_clearance_m", pr.endpoint_clearance_m)?;
        if pr.endpoint_clearance_m < e.uav_radius_m + e.training_margin_m {
            return Err(bad(
                "pairs.endpoint_clearance_m",
                "must be >= env.uav_radius_m + env.training_margin_m",
            ));
        }
        if pr.eval_bins_m.iter().any(|b| !(b.is_finite() && *b > 0.0)) {
            return Err(bad("pairs.eval_bins_m", "must be positive distances"));
        }
        if !(pr.bin_tolerance.is_finite() && pr.bin_tolerance > 0.0 && pr.bin_tolerance < 0.5) {
            return Err(bad("pairs.bin_tolerance", "must be in (0, 0.5)"));
        }

        let pl = &self.planner;
        positive("planner.voxel_m", pl.voxel_m)?;
        if !(pl.clearance_m.is_finite() && pl.clearance_m >= e.uav_radius_m) {
            return Err(bad("planner.clearance_m", "must be >= env.uav_radius_m"));
        }
        for (k, v) in [
            ("planner.lambda", pl.lambda),
            ("planner.penalty_mediocre", pl.penalty_mediocre),
            ("planner.penalty_poor", pl.penalty_poor),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(k, format!("must be a finite number >= 0, got {v}")));
            }
        }
        let pp = &self.ppo;
        positive("ppo.learning_rate", pp.learning_rate)?;
        for (k, v) in [("ppo.gamma", pp.gamma), ("ppo.gae_lambda", pp.gae_lambda)] {
            if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
                return Err(bad(k, format!("must be in [0, 1], got {v}")));
            }
        }
        if pp.num_minibatches == 0 {
            return Err(bad("ppo.num_minibatches", "must be >= 1"));
        }
        if pp.update_epochs == 0 {
            return Err(bad("ppo.update_epochs", "must be >= 1"));
        }
        positive("ppo.clip_coef", pp.clip_coef)?;
        for (k, v) in [
            ("ppo.ent_coef_move", pp.ent_coef_move),
            ("ppo.ent_coef_site", pp.ent_coef_site),
            ("ppo.vf_coef", pp.vf_coef),
            ("ppo.target_kl", pp.target_kl),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(k, format!("must be a finite number >= 0, got {v}")));
            }
        }
        positive("ppo.max_grad_norm", pp.max_grad_norm)?;
        positive("ppo.adam_eps", pp.adam_eps)?;
        if pp.hidden.is_empty() || pp.hidden.iter().any(|&h| h == 0 || h > 65_536) {
            return Err(bad("ppo.hidden", "must list 1 or more widths in 1..=65536"));
        }
        if pp.site_head == SiteHead::Equivariant
            && e.association == Association::Learned
            && !o.site_features
        {
            return Err(bad(
                "ppo.site_head",
                "\"equivariant\" scores sites from env.observation.site_features: set it to true, or use \"slots\"",
            ));
        }
        if o.site_trend && !o.site_features {
            return Err(bad(
                "env.observation.site_trend",
                "is a site feature: set env.observation.site_features to true too",
            ));
        }
        if !(1..=1024).contains(&pp.site_embed) {
            return Err(bad("ppo.site_embed", "must be in 1..=1024"));
        }
        if pp.site_hidden.is_empty() || pp.site_hidden.iter().any(|&h| h == 0 || h > 4096) {
            return Err(bad(
                "ppo.site_hidden",
                "must list 1 or more widths in 1..=4096",
            ));
        }
        if !(pp.site_coef.is_finite() && pp.site_coef >= 0.0) {
            return Err(bad("ppo.site_coef", "must be a finite number >= 0"));
        }
        finite("ppo.init_log_std", pp.init_log_std)?;
        positive("ppo.obs_clip", pp.obs_clip)?;
        positive("ppo.reward_clip", pp.reward_clip)?;

        let t = &self.train;
        if t.num_envs == 0 || t.num_envs > 4096 {
            return Err(bad("train.num_envs", "must be in 1..=4096"));
        }
        if t.num_steps == 0 {
            return Err(bad("train.num_steps", "must be >= 1"));
        }
        let Some(batch) = t.num_envs.checked_mul(t.num_steps) else {
            return Err(bad(
                "train.num_steps",
                "train.num_envs × train.num_steps overflows",
            ));
        };
        if !batch.is_multiple_of(pp.num_minibatches) || batch < pp.num_minibatches {
            return Err(bad(
                "ppo.num_minibatches",
                format!("must divide the batch train.num_envs × train.num_steps = {batch}"),
            ));
        }
        if t.pool_size == 0 {
            return Err(bad("train.pool_size", "must be >= 1"));
        }
        if t.checkpoint_every == 0 {
            return Err(bad("train.checkpoint_every", "must be >= 1"));
        }

        let d = &self.distributed;
        if d.run.is_empty()
            || d.run.len() > 64
            || !d
                .run
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_')
        {
            return Err(bad(
                "distributed.run",
                format!(
                    "must be 1 to 64 letters, digits, '-' or '_' (it is a key-expression chunk), got {:?}",
                    d.run
                ),
            ));
        }
        if d.actors > 1024 {
            return Err(bad("distributed.actors", "must be in 0..=1024"));
        }
        if d.actor_envs == 0 || d.actor_envs > 4096 {
            return Err(bad("distributed.actor_envs", "must be in 1..=4096"));
        }
        if d.chunk_steps == 0 || d.chunk_steps > 65_536 {
            return Err(bad("distributed.chunk_steps", "must be in 1..=65536"));
        }
        if d.max_importance_weight.is_nan() || d.max_importance_weight < 1.0 {
            return Err(bad("distributed.max_importance_weight", "must be >= 1"));
        }
        if !(d.max_message_mib.is_finite()
            && d.max_message_mib > 0.0
            && d.max_message_mib <= 1024.0)
        {
            return Err(bad("distributed.max_message_mib", "must be in (0, 1024]"));
        }
        if d.queue_chunks == 0 {
            return Err(bad("distributed.queue_chunks", "must be >= 1"));
        }
        positive("distributed.silent_after_s", d.silent_after_s)?;
        positive("distributed.resend_after_s", d.resend_after_s)?;
        positive("distributed.stats_every_s", d.stats_every_s)?;
        self.validate_bounds()
    }

    /// Upper bounds on every value that sizes memory or time (issue 16): a value that passes
    /// validation never panics a conversion (`Duration`, an allocation size) later. The bounds
    /// are far above any sensible run; each error names the key and the bound.
    fn validate_bounds(&self) -> Result<(), ConfigError> {
        fn within(key: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Result<(), ConfigError> {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(ConfigError::Invalid {
                    key: key.to_string(),
                    message: format!("must be in [{lo}, {hi}] {unit}, got {v}"),
                })
            }
        }
        fn at_most(key: &str, v: u64, hi: u64) -> Result<(), ConfigError> {
            if v <= hi {
                Ok(())
            } else {
                Err(ConfigError::Invalid {
                    key: key.to_string(),
                    message: format!("must be at most {hi}, got {v}"),
                })
            }
        }
        const DAY_S: f64 = 86_400.0;
        let d = &self.distributed;
        within(
            "distributed.silent_after_s",
            d.silent_after_s,
            0.0,
            DAY_S,
            "s",
        )?;
        within(
            "distributed.resend_after_s",
            d.resend_after_s,
            0.0,
            DAY_S,
            "s",
        )?;
        within(
            "distributed.stats_every_s",
            d.stats_every_s,
            0.0,
            3600.0,
            "s",
        )?;
        within(
            "distributed.weights_replies_per_s",
            d.weights_replies_per_s,
            0.01,
            10_000.0,
            "per s",
        )?;
        at_most("distributed.queue_chunks", d.queue_chunks as u64, 65_536)?;
        at_most("distributed.max_policy_lag", d.max_policy_lag, 1_000)?;
        at_most(
            "distributed.chunk_steps",
            (d.actor_envs * d.chunk_steps) as u64,
            1 << 22,
        )
        .map_err(|_| ConfigError::Invalid {
            key: "distributed.chunk_steps".into(),
            message: format!(
                "actor_envs × chunk_steps = {} samples per chunk, at most {}",
                d.actor_envs * d.chunk_steps,
                1 << 22
            ),
        })?;
        let t = &self.train;
        at_most("train.num_steps", t.num_steps as u64, 65_536)?;
        if t.num_envs * t.num_steps > 1 << 22 {
            return Err(ConfigError::Invalid {
                key: "train.num_steps".into(),
                message: format!(
                    "num_envs × num_steps = {} samples per batch, at most {}",
                    t.num_envs * t.num_steps,
                    1 << 22
                ),
            });
        }
        at_most("train.pool_size", t.pool_size as u64, 1_000_000)?;
        at_most("train.eval_pairs", t.eval_pairs as u64, 100_000)?;
        at_most(
            "train.total_timesteps",
            t.total_timesteps,
            1_000_000_000_000,
        )?;
        at_most(
            "pairs.eval_per_bin",
            self.pairs.eval_per_bin as u64,
            100_000,
        )?;
        at_most(
            "pairs.eval_bins_m",
            self.pairs.eval_bins_m.len() as u64,
            1_000,
        )?;
        if self.pairs.eval_bins_m.len() * self.pairs.eval_per_bin > 100_000 {
            return Err(ConfigError::Invalid {
                key: "pairs.eval_per_bin".into(),
                message: format!(
                    "{} bins × {} pairs: at most 100000 held-out pairs",
                    self.pairs.eval_bins_m.len(),
                    self.pairs.eval_per_bin
                ),
            });
        }
        at_most("map.altitudes_m", self.map.altitudes_m.len() as u64, 64)?;
        at_most(
            "radio.antenna.boresights_deg",
            self.radio.antenna.boresights_deg.len() as u64,
            16,
        )?;
        at_most("ppo.site_hidden", self.ppo.site_hidden.len() as u64, 16)?;
        // The observation holds 10 features per site; the paper has 30 sites.
        at_most("scenario.n_sites", self.scenario.n_sites as u64, 1_024)?;
        at_most(
            "scenario.procedural.n_sites",
            self.scenario.procedural.n_sites as u64,
            1_024,
        )?;
        let pp = &self.ppo;
        at_most("ppo.update_epochs", pp.update_epochs as u64, 1_000)?;
        at_most("ppo.hidden", pp.hidden.len() as u64, 16).map_err(|_| ConfigError::Invalid {
            key: "ppo.hidden".into(),
            message: format!("at most 16 layers, got {}", pp.hidden.len()),
        })?;
        if let Some(&h) = pp.hidden.iter().find(|&&h| h > 4096) {
            return Err(ConfigError::Invalid {
                key: "ppo.hidden".into(),
                message: format!("widths must be at most 4096, got {h}"),
            });
        }
        let weights: usize = pp.hidden.windows(2).map(|w| w[0] * w[1]).sum();
        if weights > 16 << 20 {
            return Err(ConfigError::Invalid {
                key: "ppo.hidden".into(),
                message: format!(
                    "{weights} hidden-to-hidden weights per network, at most {}",
                    16 << 20
                ),
            });
        }
        let r = &self.radio;
        // TR 38.901 §7.4 (the models TR 36.777 builds on) hold for 0.5–100 GHz.
        within("radio.fc_ghz", r.fc_ghz, 0.5, 100.0, "GHz")?;
        within("radio.tx_power_dbm", r.tx_power_dbm, -50.0, 80.0, "dBm")?;
        // TS 36.331 ReportConfigEUTRA: timeToTrigger ≤ 5120 ms.
        within(
            "radio.a3.time_to_trigger_ms",
            r.a3.time_to_trigger_ms,
            0.0,
            5120.0,
            "ms",
        )?;
        let sc = &self.scenario;
        // Search grids of 5 m around each site: these radii size their work.
        within(
            "scenario.roof_search_m",
            sc.roof_search_m,
            0.0,
            1_000.0,
            "m",
        )?;
        within(
            "scenario.macro_radius_m",
            sc.macro_radius_m,
            0.0,
            2_000.0,
            "m",
        )?;
        within(
            "scenario.pole_height_m",
            sc.pole_height_m,
            0.0,
            1_000.0,
            "m",
        )?;
        within("scenario.roof_mast_m", sc.roof_mast_m, -100.0, 100.0, "m")?;
        let pc = &sc.procedural;
        within("scenario.procedural.size_m", pc.size_m, 0.0, 20_000.0, "m")?;
        within(
            "scenario.procedural.street_pitch_m",
            pc.street_pitch_m,
            5.0,
            10_000.0,
            "m",
        )?;
        within(
            "scenario.procedural.avenue_spacing_m",
            pc.avenue_spacing_m,
            5.0,
            10_000.0,
            "m",
        )?;
        // The flight area: at most ≈ 50 km across (a city, not a country).
        within(
            "scenario.area.lon_max_deg",
            sc.area.lon_max_deg - sc.area.lon_min_deg,
            0.0,
            0.5,
            "degrees east of lon_min_deg",
        )?;
        within(
            "scenario.area.lat_max_deg",
            sc.area.lat_max_deg - sc.area.lat_min_deg,
            0.0,
            0.5,
            "degrees north of lat_min_deg",
        )?;
        within("planner.voxel_m", self.planner.voxel_m, 0.5, 1_000.0, "m")?;
        let e = &self.env;
        within("env.z_max_m", e.z_max_m, 0.0, 10_000.0, "m")?;
        within("env.speed_mps", e.speed_mps, 0.0, 1_000.0, "m/s")?;
        within(
            "env.observation.sensor_range_m",
            e.observation.sensor_range_m,
            0.0,
            10_000.0,
            "m",
        )?;
        at_most("env.action_repeat", u64::from(e.action_repeat), 1_000)?;
        within("pairs.max_m", self.pairs.max_m, 0.0, 100_000.0, "m")?;
        let c = &self.cache;
        within("cache.horizontal_m", c.horizontal_m, 0.5, 1_000.0, "m")?;
        within("cache.z_max_m", c.z_max_m, 0.0, 10_000.0, "m")?;
        within("cache.vertical_m", c.vertical_m, 0.5, 1_000.0, "m")?;
        within(
            "env.time_limit_factor",
            self.env.time_limit_factor,
            0.0,
            1_000.0,
            "",
        )?;
        Ok(())
    }
}

/// Applies one `a.b.c=value` override to a TOML table. The value is parsed as TOML (numbers,
/// booleans, arrays, quoted strings); anything that does not parse is taken as a bare string.
fn apply_override(root: &mut toml::Table, arg: &str) -> Result<(), ConfigError> {
    let err = |message: String| ConfigError::Override {
        arg: arg.to_string(),
        message,
    };
    let (key, raw) = arg
        .split_once('=')
        .ok_or_else(|| err("expected KEY=VALUE, e.g. map.resolution_m=10".into()))?;
    let key = key.trim();
    if key.is_empty() || key.split('.').any(|p| p.is_empty()) {
        return Err(err(format!("malformed key {key:?}")));
    }
    let raw = raw.trim();
    let value: toml::Value = match toml::from_str::<toml::Table>(&format!("v = {raw}")) {
        Ok(mut t) => t
            .remove("v")
            .unwrap_or(toml::Value::String(raw.to_string())),
        Err(_) => toml::Value::String(raw.to_string()),
    };
    let parts: Vec<&str> = key.split('.').collect();
    let (last, parents) = parts
        .split_last()
        .ok_or_else(|| err(format!("malformed key {key:?}")))?;
    let mut table = root;
    for (i, p) in parents.iter().enumerate() {
        let entry = table
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        table = entry.as_table_mut().ok_or_else(|| {
            err(format!(
                "`{}` is a value, not a section",
                parts[..=i].join(".")
            ))
        })?;
    }
    table.insert(last.to_string(), value);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sensor_scales_map_the_range_onto_unit_interval() {
        for scale in [SensorScale::Linear, SensorScale::Log] {
            assert_eq!(scale.scale(0.0, 50.0), 0.0);
            assert!((scale.scale(50.0, 50.0) - 1.0).abs() < 1e-12);
            assert!(
                (scale.scale(80.0, 50.0) - 1.0).abs() < 1e-12,
                "beyond range = free"
            );
            assert!(scale.scale(2.0, 50.0) < scale.scale(3.0, 50.0), "monotone");
        }
        assert!((SensorScale::Linear.scale(5.0, 50.0) - 0.1).abs() < 1e-12);
        // The log scale spends a quarter of [0, 1] on the first 2 m (linear: 4 %).
        let log2 = SensorScale::Log.scale(2.0, 50.0);
        assert!((log2 - 3f64.ln() / 51f64.ln()).abs() < 1e-12 && log2 > 0.25);
    }

    #[test]
    fn defaults_are_the_papers() {
        let c = Config::load(None, &[]).expect("defaults valid");
        assert_eq!(c.radio.fc_ghz, 2.0);
        assert_eq!(c.radio.tx_power_dbm, 15.2);
        assert_eq!(c.radio.antenna.boresights_deg, vec![30.0, 150.0, 270.0]);
        assert_eq!(c.scenario.n_sites, 30);
        assert_eq!(c.map.altitudes_m, vec![30.0, 60.0, 90.0, 120.0]);
    }

    #[test]
    fn unknown_key_is_rejected_and_named() {
        let e = Config::from_toml_str("[radio]\nfc_gz = 3.0\n", "x.toml", &[]).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("fc_gz"), "{msg}");
        assert!(msg.contains("x.toml"), "{msg}");
    }

    #[test]
    fn set_overrides_nested_keys_with_typed_values() {
        let sets = vec![
            "radio.fc_ghz=3.5".to_string(),
            "map.altitudes_m=[50, 100]".to_string(),
            "scenario.city=procedural".to_string(),
            "radio.antenna.gain_floor_dbi=-30".to_string(),
        ];
        let c = Config::load(None, &sets).expect("valid");
        assert_eq!(c.radio.fc_ghz, 3.5);
        assert_eq!(c.map.altitudes_m, vec![50.0, 100.0]);
        assert_eq!(c.scenario.city, CityKind::Procedural);
        assert_eq!(c.radio.antenna.gain_floor_dbi, Some(-30.0));
    }

    #[test]
    fn out_of_range_value_names_the_key() {
        let e = Config::load(None, &["radio.fc_ghz=-1".to_string()]).unwrap_err();
        assert!(e.to_string().contains("radio.fc_ghz"), "{e}");
        let e = Config::load(None, &["radio.a3.offset_db=20".to_string()]).unwrap_err();
        assert!(e.to_string().contains("radio.a3.offset_db"), "{e}");
        let e = Config::load(None, &["map.resolution_m".to_string()]).unwrap_err();
        assert!(e.to_string().contains("KEY=VALUE"), "{e}");
        let e = Config::load(None, &["radio.fc_ghz.x=1".to_string()]).unwrap_err();
        assert!(e.to_string().contains("radio.fc_ghz"), "{e}");
    }

    #[test]
    fn training_grows_the_sphere_once_and_checks_its_room() {
        let c = Config::load(None, &["env.training_margin_m=1".to_string()]).expect("valid");
        let t = c.training();
        assert_eq!(t.env.uav_radius_m, c.env.uav_radius_m + 1.0);
        assert_eq!(t.env.training_margin_m, 0.0);
        assert_eq!(t.training(), t, "applied once");
        // Everything else is the same configuration.
        let mut back = t.clone();
        back.env.uav_radius_m = c.env.uav_radius_m;
        back.env.training_margin_m = c.env.training_margin_m;
        assert_eq!(back, c);
        // The grown sphere must fit at every endpoint (5 m of clearance by default).
        let e = Config::load(None, &["env.training_margin_m=4.6".to_string()]).unwrap_err();
        assert!(e.to_string().contains("pairs.endpoint_clearance_m"), "{e}");
        let e = Config::load(None, &["env.training_margin_m=-1".to_string()]).unwrap_err();
        assert!(e.to_string().contains("env.training_margin_m"), "{e}");
    }

    #[test]
    fn round_trips_through_toml() {
        let c = Config::load(None, &["radio.a3.l3_filter_k=4".to_string()]).expect("valid");
        let text = c.to_toml_string();
        let back = Config::from_toml_str(&text, "roundtrip", &[]).expect("valid");
        assert_eq!(c, back);
    }
}
