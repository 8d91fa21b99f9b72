//! The expansion of the compact trajectory ([`dupac_common::compact`]): one pure function of a
//! configuration, the scenario's site positions and the sent state, giving the observation
//! (spec/env.md "Observation", [`dupac_common::obs`]), every step's site features and every
//! site's counterfactual reward. The environment writes its observation and site features
//! through it ([`Expander::observation`], [`Expander::site_features`]), so an actor acts on the
//! expansion of what it sends; the learner expands the received trajectory with the same
//! function ([`Expander::trajectory`]) and trains on exactly what the actor saw.
//!
//! The counterfactual rewards are [`site_term`] of each site (the site-independent terms are
//! left out: the site head reads only `r_k − max_j r_j`, in which they cancel), scored with the
//! RSRP codes: the classes are exact, each value up to 0.5 dB low ([`code::rsrp`]).

use crate::reward::{RSRP_FLOOR_DBM, site_term};
use dupac_common::compact::{CompactShape, CompactTrajectory, StateRow, TrunkRow, code};
use dupac_common::config::{Association, Config, ObservationConfig, RewardConfig};
use dupac_common::geometry::{Bounds2, Point};
use dupac_common::msg::EnvTrajectory;
use dupac_common::obs::{ObsLayout, field, site_feature, site_features_per_site};
use dupac_radio::class::RsrpThresholds;
use dupac_radio::world::RadioWorld;
use std::ops::Range;

/// One step of a decision, for its site rows: what the step's every-site reward adds to
/// [`site_term`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepRecord {
    /// The step's progress towards the destination (m).
    pub progress_m: f32,
    /// The step's site-independent reward (terminal rewards, the route term, the goal).
    pub common: f32,
}

/// One decision of a learned site as the environment records it: the state each of its steps
/// chose a site in (the first is the observation's), each step's record, the true RSRP codes
/// its rewards score ([`CompactShape::true_rsrp_every_step`]: after every step, `M` per step;
/// otherwise after the last step, a step before it reading the next state's codes), and
/// whether its last step crashed (a collision or leaving the area).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct DecisionRecord {
    pub states: Vec<StateRow>,
    pub steps: Vec<StepRecord>,
    pub reward_rsrp: Vec<u8>,
    pub crashed: bool,
}

/// Why a compact trajectory cannot be expanded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExpandError {
    #[error("compact trajectory of the wrong shape: {0}")]
    Shape(String),
    #[error("compact trajectory with a non-finite number: {0}")]
    NonFinite(String),
    #[error("expanding {decisions} decisions needs {need} bytes, more than the budget of {budget}")]
    OverBudget {
        decisions: usize,
        need: usize,
        budget: usize,
    },
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
    path_offset: Option<Range<usize>>,
    handover_weight: Option<Range<usize>>,
    obstacle_distance: Range<usize>,
    obstacle_direction: Range<usize>,
    sensor_fan: Option<Range<usize>>,
    serving_one_hot: Range<usize>,
    rsrp_all: Option<Range<usize>>,
    rsrp_serving: Option<Range<usize>>,
    site_features: Option<Range<usize>>,
}

impl Slots {
    fn new(layout: &ObsLayout) -> Slots {
        let req = |name: &str| layout.range(name).unwrap_or(0..0);
        Slots {
            position: req(field::POSITION),
            velocity: req(field::VELOCITY),
            goal_vector: layout.range(field::GOAL_VECTOR),
            goal_distance: layout.range(field::GOAL_DISTANCE),
            goal_direction: layout.range(field::GOAL_DIRECTION),
            path_guide: layout.range(field::PATH_GUIDE),
            path_offset: layout.range(field::PATH_OFFSET),
            handover_weight: layout.range(field::HANDOVER_WEIGHT),
            obstacle_distance: req(field::OBSTACLE_DISTANCE),
            obstacle_direction: req(field::OBSTACLE_DIRECTION),
            sensor_fan: layout.range(field::SENSOR_FAN),
            serving_one_hot: req(field::SERVING_ONE_HOT),
            rsrp_all: layout.range(field::RSRP_ALL),
            rsrp_serving: layout.range(field::RSRP_SERVING),
            site_features: layout.range(field::SITE_FEATURES),
        }
    }
}

/// What the expansion reads of a configuration and a scenario.
#[derive(Debug, Clone)]
pub struct Expander {
    layout: ObsLayout,
    slots: Slots,
    shape: CompactShape,
    obs: ObservationConfig,
    /// `env.reward` at handover weight 1 (a decision's costs are these times its weight).
    reward: RewardConfig,
    thresholds: RsrpThresholds,
    area: Bounds2,
    /// Centre and half height of the altitude band (m).
    band_m: (f64, f64),
    /// The sites' positions (m), in `f32` as the site features compute with them.
    sites_f32: Vec<[f32; 3]>,
    /// Per RSRP code: the RSRP the site features and rewards score (dBm, floored at
    /// [`RSRP_FLOOR_DBM`]) and the site features' RSRP value.
    code_dbm: Box<[f64; 256]>,
    code_feature: Box<[f32; 256]>,
    /// Most steps of a decision (`env.action_repeat`).
    max_repeat: usize,
    /// The site chosen at every step (`env.site_every_step` with the learned association and
    /// the site features observed): per-step feature and reward rows, else per-decision rewards.
    every_step: bool,
}

impl Expander {
    /// The expansion of `cfg`'s environment over `world`'s sites and area.
    pub fn new(cfg: &Config, world: &RadioWorld) -> Expander {
        let sites_m: Vec<Point> = world.sites.iter().map(|s| s.position_m).collect();
        Expander::of_sites(cfg, world.city.area_m, sites_m)
    }

    /// The expansion of `cfg`'s environment over sites at `sites_m` in the flight area `area`.
    pub fn of_sites(cfg: &Config, area: Bounds2, sites_m: Vec<Point>) -> Expander {
        let e = &cfg.env;
        let o = &e.observation;
        let layout = ObsLayout::new(o, sites_m.len());
        let slots = Slots::new(&layout);
        let learned = e.association == Association::Learned;
        let shape = CompactShape {
            n_sites: sites_m.len(),
            path_guide: slots.path_guide.is_some(),
            path_offset: slots.path_offset.is_some(),
            sensor_fan: slots.sensor_fan.is_some(),
            learned,
            lookahead: o.site_lookahead_m.len(),
            stay: o.site_lookahead_stay,
            true_rsrp_every_step: cfg.radio.channel.measured(),
        };
        Expander {
            every_step: e.site_every_step && learned && slots.site_features.is_some(),
            layout,
            slots,
            shape,
            obs: o.clone(),
            reward: e.reward.clone(),
            thresholds: RsrpThresholds::from_config(&cfg.radio),
            area,
            band_m: (0.5 * (e.z_min_m + e.z_max_m), 0.5 * (e.z_max_m - e.z_min_m)),
            sites_f32: sites_m
                .iter()
                .map(|q| [q[0] as f32, q[1] as f32, q[2] as f32])
                .collect(),
            code_dbm: Box::new(std::array::from_fn(|c| {
                code::rsrp_dbm(c as u8).max(RSRP_FLOOR_DBM)
            })),
            code_feature: Box::new(std::array::from_fn(|c| {
                let w = code::rsrp_dbm(c as u8).max(RSRP_FLOOR_DBM);
                ((w - o.rsrp_centre_dbm) / o.rsrp_scale_db).clamp(-10.0, 10.0) as f32
            })),
            max_repeat: e.action_repeat.max(1) as usize,
        }
    }

    /// What the compact trajectory of this configuration carries.
    pub fn shape(&self) -> &CompactShape {
        &self.shape
    }

    /// The observation layout.
    pub fn layout(&self) -> &ObsLayout {
        &self.layout
    }

    /// Whether the site is chosen at every step (per-step site rows).
    pub fn every_step(&self) -> bool {
        self.every_step
    }

    /// The observation of the trunk row `t` and the state `s` into `out` (the layout's length):
    /// the trunk, then the site features (zeros when the site is not learned).
    pub fn observation(&self, t: &TrunkRow, s: &StateRow, out: &mut [f32]) {
        let sl = &self.slots;
        let o = &self.obs;
        let a = self.area;
        let (cx, cy) = (0.5 * (a.min_m.x + a.max_m.x), 0.5 * (a.min_m.y + a.max_m.y));
        let (hx, hy) = (0.5 * (a.max_m.x - a.min_m.x), 0.5 * (a.max_m.y - a.min_m.y));
        let (zc, hz) = self.band_m;
        let p = s.position_m.map(f64::from);
        let pos = [(p[0] - cx) / hx, (p[1] - cy) / hy, (p[2] - zc) / hz];
        for (k, v) in pos.iter().enumerate() {
            out[sl.position.start + k] = *v as f32;
        }
        let velocity = [s.velocity_xy[0], s.velocity_xy[1], t.velocity_z];
        for (k, c) in velocity.iter().enumerate() {
            out[sl.velocity.start + k] = code::signed_value(*c) as f32;
        }
        let dest = t.destination_m.map(f64::from);
        let to_goal = [dest[0] - p[0], dest[1] - p[1], dest[2] - p[2]];
        let d = to_goal.iter().map(|v| v * v).sum::<f64>().sqrt();
        if let (Some(gv), Some(gd)) = (&sl.goal_vector, &sl.goal_distance) {
            for k in 0..3 {
                out[gv.start + k] = (to_goal[k] / o.goal_scale_m) as f32;
            }
            out[gd.start] = (d / o.goal_scale_m) as f32;
            if let Some(u) = &sl.goal_direction {
                for k in 0..3 {
                    let v = if d > 1e-9 { to_goal[k] / d } else { 0.0 };
                    out[u.start + k] = v as f32;
                }
            }
        }
        if let Some(r) = &sl.path_guide {
            for k in 0..3 {
                out[r.start + k] = code::signed_value(t.path_direction[k]) as f32;
            }
            out[r.start + 3] = t.path_to_go;
        }
        if let Some(r) = &sl.path_offset {
            out[r.clone()].copy_from_slice(&t.path_offset);
        }
        if let Some(r) = &sl.handover_weight {
            out[r.start] = f64::from(t.handover_weight).ln_1p() as f32;
        }
        out[sl.obstacle_distance.start] = code::unit_value(t.obstacle_distance) as f32;
        for k in 0..3 {
            out[sl.obstacle_direction.start + k] =
                code::signed_value(t.obstacle_direction[k]) as f32;
        }
        if let Some(f) = &sl.sensor_fan {
            for (o, c) in out[f.clone()].iter_mut().zip(&t.sensor_fan) {
                *o = code::unit_value(*c) as f32;
            }
        }
        let rsrp_norm = |c: u8| {
            let x = (code::rsrp_dbm(c) - o.rsrp_centre_dbm) / o.rsrp_scale_db;
            // −∞ (a site that cannot be measured) is clipped.
            x.clamp(-10.0, 10.0) as f32
        };
        out[sl.serving_one_hot.clone()].fill(0.0);
        out[sl.serving_one_hot.start + usize::from(s.serving)] = 1.0;
        if let Some(r) = &sl.rsrp_all {
            for (o, c) in out[r.clone()].iter_mut().zip(&s.rsrp) {
                *o = rsrp_norm(*c);
            }
        }
        if let Some(r) = &sl.rsrp_serving {
            out[r.start] = rsrp_norm(s.rsrp[usize::from(s.serving)]);
        }
        if let Some(r) = &sl.site_features {
            if self.shape.learned {
                self.site_features(t.destination_m, s, &mut out[r.clone()]);
            } else {
                // Not a learned association: nothing reads them.
                out[r.clone()].fill(0.0);
            }
        }
    }

    /// Every site's features (obs::site_feature, `M × features`, site-major) at the state `s`
    /// of an episode flying to `destination_m` (m), into `out`: fixed physical scales, for the
    /// equivariant site head.
    pub fn site_features(&self, destination_m: [f32; 3], s: &StateRow, out: &mut [f32]) {
        let o = &self.obs;
        let p = s.position_m;
        // The codes are monotone in RSRP: the strongest site has the largest code.
        let dbm = |c: u8| self.code_dbm[usize::from(c)];
        let best = dbm(s.rsrp.iter().copied().max().unwrap_or(0));
        // The geometry in `f32` (what the features are): half the expansion's time in `f64`.
        let unit2 = |x: f32, y: f32| {
            let n = (x * x + y * y).sqrt();
            (n > 1e-9).then(|| [x / n, y / n])
        };
        let goal = unit2(destination_m[0] - p[0], destination_m[1] - p[1]);
        let [vx, vy] = s.velocity_xy.map(|c| code::signed_value(c) as f32);
        let heading = unit2(vx, vy).or(goal).unwrap_or([1.0, 0.0]);
        let goal = goal.unwrap_or(heading);
        let per_site = site_features_per_site(o);
        let ping_pong_at = site_feature::ping_pong(o);
        let lookahead_at = site_feature::lookahead(o);
        let stay_at = site_feature::stay(o);
        let choice_at = site_feature::predictive_choice(o);
        let n_ahead = lookahead_at.len();
        for (k, q) in self.sites_f32.iter().enumerate() {
            let f = &mut out[k * per_site..][..per_site];
            let code = usize::from(s.rsrp[k]);
            let w = self.code_dbm[code];
            let d = [q[0] - p[0], q[1] - p[1], q[2] - p[2]];
            let h2 = d[0] * d[0] + d[1] * d[1];
            let d3d = (h2 + d[2] * d[2]).sqrt().max(1e-3);
            // One division per site: the horizontal unit vector and the elevation by reciprocals.
            let h = h2.sqrt();
            let u = if h > 1e-9 {
                let inv = 1.0 / h;
                [d[0] * inv, d[1] * inv]
            } else {
                heading
            };
            let rel = |h: [f32; 2]| (h[0] * u[0] + h[1] * u[1], h[0] * u[1] - h[1] * u[0]);
            let (ch, sh) = rel(heading);
            let (cg, sg) = rel(goal);
            use site_feature::*;
            f[RSRP] = self.code_feature[code];
            f[RSRP_MINUS_BEST] = ((w - best) * 0.1).clamp(-6.0, 0.0) as f32;
            f[SERVING] = f32::from(u8::from(k == usize::from(s.serving)));
            // ln(1 + d / 100 m), d ≥ 1 mm.
            f[LOG_DISTANCE] = ln_at_least_one(1.0 + d3d * 0.01);
            f[SIN_ELEVATION] = d[2] * (1.0 / d3d);
            f[COS_BEARING_HEADING] = ch;
            f[SIN_BEARING_HEADING] = sh;
            f[COS_BEARING_GOAL] = cg;
            f[SIN_BEARING_GOAL] = sg;
            f[LOS] = f32::from(u8::from(s.los(k)));
            if let Some(i) = ping_pong_at {
                f[i] = f32::from(u8::from(k == usize::from(s.ping_pong)));
            }
            for (j, i) in lookahead_at.clone().enumerate() {
                f[i] = (-6.0 * code::byte_value(s.lookahead[k * n_ahead + j])) as f32;
            }
            if let Some(i) = stay_at {
                f[i] = code::byte_value(s.stay[k]) as f32;
            }
            if let Some(i) = choice_at {
                f[i] = f32::from(u8::from(k == usize::from(s.choice)));
            }
        }
    }

    /// Every site's reward of one step (appended to `out`, `M` values): the step's
    /// site-independent reward `common` plus [`site_term`] of the site with the episode's
    /// handover costs (`reward`, at the episode's weight), scored with every site's RSRP codes
    /// after the step, the site serving before it, the site that would be a ping-pong (M: none), and whether a change of site at
    /// it is a handover (`first`).
    #[allow(clippy::too_many_arguments)]
    fn step_site_rewards(
        &self,
        out: &mut [f64],
        reward: &RewardConfig,
        step: &StepRecord,
        crashed: bool,
        rsrp_after: &[u8],
        before: usize,
        ping_pong: usize,
        first: bool,
    ) {
        // The codes are monotone in RSRP.
        // (The table's values are floored as `site_term` floors them.)
        let best = self.code_dbm[usize::from(rsrp_after.iter().copied().max().unwrap_or(0))];
        for (k, out) in out.iter_mut().enumerate() {
            let handover = first && k != before;
            let pp = handover && k == ping_pong;
            *out += f64::from(step.common)
                + site_term(
                    reward,
                    &self.thresholds,
                    crashed,
                    f64::from(step.progress_m),
                    self.code_dbm[usize::from(rsrp_after[k])],
                    best,
                    handover,
                    pp,
                );
        }
    }

    /// The site rows of one decision of a learned site: with the site chosen every step
    /// (`every_step`, this configuration's [`Expander::every_step`] on the wire), each
    /// step's site features (appended to `features`, when given; the first step's copied from
    /// the observation's when that is given too) and every site's reward of that step
    /// (appended to `rewards`, `M` per step); otherwise every site's reward of the decision, had
    /// it served from the decision's first step on (`M` values).
    pub fn site_rows(
        &self,
        trunk: &TrunkRow,
        d: &DecisionRecord,
        every_step: bool,
        mut features: Option<(&mut Vec<f32>, Option<&[f32]>)>,
        rewards: &mut Vec<f64>,
    ) {
        let m = self.shape.n_sites;
        let per_site = site_features_per_site(&self.obs);
        let w = f64::from(trunk.handover_weight);
        let mut reward = self.reward.clone();
        reward.handover_reward *= w;
        reward.ping_pong_reward *= w;
        let n = d.states.len();
        if !every_step {
            rewards.resize(rewards.len() + m, 0.0);
        }
        for (k, (state, step)) in d.states.iter().zip(&d.steps).enumerate() {
            if every_step {
                if let Some((features, first)) = features.as_mut() {
                    let from = features.len();
                    match first.filter(|_| k == 0) {
                        Some(f) => features.extend_from_slice(f),
                        None => {
                            features.resize(from + m * per_site, 0.0);
                            self.site_features(trunk.destination_m, state, &mut features[from..]);
                        }
                    }
                }
                rewards.resize(rewards.len() + m, 0.0);
            }
            let after = if self.shape.true_rsrp_every_step {
                &d.reward_rsrp[k * m..(k + 1) * m]
            } else if k + 1 < n {
                &d.states[k + 1].rsrp[..]
            } else {
                &d.reward_rsrp[..]
            };
            let at = rewards.len() - m;
            self.step_site_rewards(
                &mut rewards[at..],
                &reward,
                step,
                d.crashed && k + 1 == n,
                after,
                usize::from(state.serving),
                usize::from(state.ping_pong),
                every_step || k == 0,
            );
        }
    }

    /// Bytes the expansion of `c` allocates (its observations, rows and records), from its
    /// decision and state counts.
    pub fn expanded_bytes(&self, c: &CompactTrajectory) -> usize {
        let t = c.len();
        let s = c.states();
        let f = size_of::<f32>();
        let m = self.shape.n_sites;
        let rows = if self.every_step {
            s * m * (site_features_per_site(&self.obs) + 1) * f + 2 * t
        } else if self.shape.learned {
            t * m * f
        } else {
            0
        };
        size_of::<EnvTrajectory>()
            + (t + 1) * self.layout.len() * f
            + t * (f * 9 + 2)
            + rows
            + c.episodes.len() * size_of::<dupac_common::msg::EpisodeSummary>()
    }

    /// The trajectory PPO trains on: every observation, site row and record of `c`, expanded
    /// within `budget_bytes` of allocation. Checks the columns' shape first (a peer's
    /// trajectory indexes nothing it does not hold).
    pub fn trajectory(
        &self,
        c: &CompactTrajectory,
        budget_bytes: usize,
    ) -> Result<EnvTrajectory, ExpandError> {
        let sh = &self.shape;
        if let Some(e) = c.shape_error(sh, self.max_repeat) {
            return Err(ExpandError::Shape(e));
        }
        if let Some(e) = c.first_non_finite() {
            return Err(ExpandError::NonFinite(e));
        }
        let need = self.expanded_bytes(c);
        if need > budget_bytes {
            return Err(ExpandError::OverBudget {
                decisions: c.len(),
                need,
                budget: budget_bytes,
            });
        }
        let n = c.len();
        let d = self.layout.len();
        let mut tr = EnvTrajectory {
            env: c.env,
            obs_dim: d,
            obs: vec![0.0; n * d],
            moves: c.moves.clone(),
            sites: c.sites.clone(),
            logprobs: c.logprobs.clone(),
            site_logprobs: c.site_logprobs.clone(),
            values: c.values.clone(),
            rewards: c.rewards.clone(),
            terminated: c.terminated.clone(),
            truncated: c.truncated.clone(),
            next_values: c.next_values.clone(),
            bootstrap_obs: vec![0.0; d],
            episodes: c.episodes.clone(),
            ..EnvTrajectory::default()
        };
        let mut at = 0;
        let mut rewards = Vec::new();
        let mut record = DecisionRecord::default();
        let m = sh.n_sites;
        let steps: usize = (0..n).map(|t| c.states_of(sh, t)).sum();
        if self.every_step {
            tr.step_site_features
                .reserve_exact(steps * m * site_features_per_site(&self.obs));
            tr.step_site_rewards.reserve_exact(steps * m);
        }
        let tail = self.slots.site_features.clone();
        for t in 0..n {
            let trunk = c.trunk(sh, t);
            let states = c.states_of(sh, t);
            record.states.resize_with(states, StateRow::default);
            for (k, s) in record.states.iter_mut().enumerate() {
                c.state_into(sh, at + k, s);
            }
            let obs = &mut tr.obs[t * d..(t + 1) * d];
            self.observation(&trunk, &record.states[0], obs);
            if sh.learned {
                let rows = if sh.true_rsrp_every_step {
                    at * m..(at + states) * m
                } else {
                    t * m..(t + 1) * m
                };
                record.steps.clear();
                record.steps.extend((at..at + states).map(|i| StepRecord {
                    progress_m: c.progress_m[i],
                    common: c.common_reward[i],
                }));
                record.reward_rsrp.clear();
                record
                    .reward_rsrp
                    .extend_from_slice(&c.reward_rsrp_codes[rows]);
                record.crashed = c.crashed[t];
                rewards.clear();
                // The first step's features are the observation's own.
                let first = tail
                    .as_ref()
                    .map(|r| &tr.obs[t * d..(t + 1) * d][r.clone()]);
                self.site_rows(
                    &trunk,
                    &record,
                    self.every_step,
                    Some((&mut tr.step_site_features, first)),
                    &mut rewards,
                );
                if self.every_step {
                    tr.decision_steps.push(c.decision_steps[t]);
                    tr.step_site_rewards
                        .extend(rewards.iter().map(|&r| r as f32));
                } else {
                    tr.site_rewards.extend(rewards.iter().map(|&r| r as f32));
                }
            }
            at += states;
        }
        let trunk = c.trunk(sh, n);
        self.observation(&trunk, &c.state(sh, at), &mut tr.bootstrap_obs);
        Ok(tr)
    }
}

impl Expander {
    /// A valid compact trajectory of this shape with `decisions` decisions of
    /// `env.action_repeat` steps and random states (seeded by `seed`): benchmarks, property tests
    /// and hostile-peer tests build on it.
    pub fn sample_trajectory(&self, decisions: usize, seed: u64) -> CompactTrajectory {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let sh = self.shape;
        let m = sh.n_sites;
        let per = if sh.learned { self.max_repeat } else { 1 };
        let t = decisions;
        let mut f = |n: usize, lo: f32, hi: f32| -> Vec<f32> {
            (0..n).map(|_| rng.random_range(lo..hi)).collect()
        };
        let mut c = CompactTrajectory {
            moves: f(3 * t, -1.5, 1.5),
            logprobs: f(t, -6.0, 0.0),
            site_logprobs: f(t, -3.0, 0.0),
            values: f(t, -5.0, 5.0),
            rewards: f(t, -5.0, 5.0),
            next_values: f(t, -5.0, 5.0),
            progress_m: f(t * per * usize::from(sh.learned), -1.0, 2.0),
            common_reward: f(t * per * usize::from(sh.learned), -1.0, 0.0),
            sites: (0..t).map(|k| (k % m.max(1)) as u32).collect(),
            terminated: vec![false; t],
            truncated: vec![false; t],
            decision_steps: vec![self.max_repeat as u16; t],
            crashed: vec![false; t],
            ..CompactTrajectory::default()
        };
        let rows = if sh.true_rsrp_every_step { t * per } else { t };
        c.reward_rsrp_codes = (0..rows * m * usize::from(sh.learned))
            .map(|_| rng.random_range(40..200))
            .collect();
        for _ in 0..=t {
            let mut trunk = TrunkRow {
                destination_m: [0, 1, 2].map(|_| rng.random_range(-400.0..400.0)),
                handover_weight: rng.random_range(0.0..3.0),
                velocity_z: rng.random(),
                path_direction: [0, 1, 2].map(|_| rng.random()),
                path_to_go: rng.random_range(0.0..1.0),
                path_offset: [0, 1, 2].map(|_| rng.random_range(-3.0..3.0)),
                obstacle_distance: rng.random(),
                obstacle_direction: [0, 1, 2].map(|_| rng.random()),
                ..TrunkRow::default()
            };
            trunk.sensor_fan = [0; 26].map(|_: u16| rng.random());
            c.push_trunk(&sh, &trunk);
        }
        for _ in 0..=t * per {
            let s = StateRow {
                position_m: [0, 1, 2].map(|k| rng.random_range(-400.0..400.0) * [1.0, 1.0, 0.2][k]),
                velocity_xy: [rng.random(), rng.random()],
                serving: rng.random_range(0..m as u16),
                ping_pong: rng.random_range(0..=m as u16),
                rsrp: (0..m).map(|_| rng.random_range(0..=255)).collect(),
                los: (0..sh.los_bytes()).map(|_| rng.random()).collect(),
                lookahead: (0..m * sh.lookahead).map(|_| rng.random()).collect(),
                stay: (0..if sh.stay { m } else { 0 })
                    .map(|_| rng.random())
                    .collect(),
                choice: rng.random_range(0..=m as u16),
            };
            c.push_state(&sh, &s);
        }
        c
    }
}

/// ln `x` for `x` ≥ 1 (finite), within 3 ulp of the exact logarithm: `x = 2^e·m` with `m` in
/// [√½, √2), `ln m = 2·atanh((m − 1)/(m + 1))` by its series to the 9th power (truncation
/// < 10⁻⁹). Inlined in the site features' loop, where libm's `logf` call was a tenth of the
/// learner's expansion; written here because the few-line series is all that loop needs.
#[inline]
fn ln_at_least_one(x: f32) -> f32 {
    let bits = x.to_bits();
    let mut e = ((bits >> 23) & 0xff) as i32 - 127;
    let mut m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    if m > std::f32::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let series = 1.0 + s2 * (1.0 / 3.0 + s2 * (1.0 / 5.0 + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0))));
    e as f32 * std::f32::consts::LN_2 + 2.0 * s * series
}

#[cfg(test)]
mod tests {
    use super::ln_at_least_one;

    /// Within 3 ulp of the exact logarithm from 1 to 10⁶ (the site features' distances, 1 mm to
    /// 100 km, are 1 to 1 001).
    #[test]
    fn the_logarithm_is_within_three_ulp() {
        let mut x = 1.0f32;
        let mut worst = 0.0f64;
        while x < 1e6 {
            let got = ln_at_least_one(x);
            let exact = f64::from(x).ln();
            let near = (exact as f32).abs();
            let ulp = f64::from(f32::from_bits(near.to_bits() + 1) - near);
            let err = (f64::from(got) - exact).abs() / ulp;
            worst = worst.max(err);
            assert!(err <= 3.0, "ln {x}: {got} against {exact} ({err:.2} ulp)");
            x = f32::from_bits(x.to_bits() + 997);
        }
        eprintln!("worst {worst:.2} ulp");
        assert!(worst > 0.0, "some rounding is seen");
    }
}
