//! The compact trajectory an actor sends ([`CompactTrajectory`], in
//! [`crate::msg::TrajectoryChunk`]): the state the policy's inputs are computed from, not the
//! inputs. Per decision the policy's outputs, the trunk's own quantities ([`TrunkRow`]) and one
//! [`StateRow`] per state a site is chosen in (each site's measured RSRP and line of sight, the
//! serving and ping-pong sites, the UAV's place and heading); per step the progress and the RSRP
//! the step's reward scores. One pure function (`dupac_actor::expand`) turns it into the
//! observation, every step's site features and every site's counterfactual reward; the actor
//! acts on that expansion of what it sends, so the learner trains on exactly what it saw.
//!
//! Quantisation ([`code`]): RSRP on a 0.5 dB grid through the class thresholds (rounded down,
//! so every RSRP class is exact), values in [0, 1] and [−1, 1] as 16-bit fixed point, the
//! look-ahead features as 8-bit fixed point; positions, progress, the planned path's distance
//! and the handover weight in `f32` as before.

use crate::episode::EpisodeSummary;
use serde::{Deserialize, Serialize};

/// The fixed-point codes of the compact trajectory.
pub mod code {
    /// RSRP grid step (dB).
    pub const RSRP_STEP_DB: f64 = 0.5;
    /// RSRP of code 1 (dBm): everything measurable below it is sent as it.
    pub const RSRP_BOTTOM_DBM: f64 = -152.0;
    /// RSRP of code 255 (dBm): everything above it is sent as it.
    pub const RSRP_TOP_DBM: f64 = RSRP_BOTTOM_DBM + 254.0 * RSRP_STEP_DB;
    /// Code of a site that cannot be measured (−∞ dBm).
    pub const RSRP_UNMEASURED: u8 = 0;

    /// The code of `dbm`: the grid value at or below it (−80 and −100 dBm are grid values, so
    /// the class of the code's RSRP is the class of `dbm`), saturated to
    /// [`RSRP_BOTTOM_DBM`, `RSRP_TOP_DBM`]; −∞ and NaN are [`RSRP_UNMEASURED`].
    #[inline]
    pub fn rsrp(dbm: f64) -> u8 {
        if dbm.is_nan() || dbm == f64::NEG_INFINITY {
            return RSRP_UNMEASURED;
        }
        let k = ((dbm - RSRP_BOTTOM_DBM) / RSRP_STEP_DB).floor();
        (k.clamp(0.0, 254.0) as u8) + 1
    }

    /// The RSRP (dBm) of a code (−∞ for [`RSRP_UNMEASURED`]).
    #[inline]
    pub fn rsrp_dbm(c: u8) -> f64 {
        if c == RSRP_UNMEASURED {
            f64::NEG_INFINITY
        } else {
            RSRP_BOTTOM_DBM + f64::from(c - 1) * RSRP_STEP_DB
        }
    }

    /// A value in [0, 1] (clamped) as a 16-bit code (resolution 1.5·10⁻⁵).
    #[inline]
    pub fn unit(v: f64) -> u16 {
        (v.clamp(0.0, 1.0) * 65535.0).round() as u16
    }

    #[inline]
    pub fn unit_value(c: u16) -> f64 {
        f64::from(c) / 65535.0
    }

    /// Code of 0 in [`signed`]: −1, 0 and 1 are exact.
    const SIGNED_ZERO: f64 = 32767.0;

    /// A value in [−1, 1] (clamped) as a 16-bit code (resolution 3.1·10⁻⁵; −1, 0 and 1
    /// exact).
    #[inline]
    pub fn signed(v: f64) -> u16 {
        (v.clamp(-1.0, 1.0) * SIGNED_ZERO + SIGNED_ZERO).round() as u16
    }

    /// The value of a [`signed`] code (65535, never written, reads as 1).
    #[inline]
    pub fn signed_value(c: u16) -> f64 {
        ((f64::from(c) - SIGNED_ZERO) / SIGNED_ZERO).min(1.0)
    }

    /// A value in [0, 1] (clamped) as an 8-bit code (resolution 0.004).
    #[inline]
    pub fn byte(v: f64) -> u8 {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }

    #[inline]
    pub fn byte_value(c: u8) -> f64 {
        f64::from(c) / 255.0
    }
}

/// Which optional parts a configuration's compact trajectory carries (from the observation
/// layout and the association; the expansion computes it, sender and receiver alike).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CompactShape {
    /// M, the scenario's sites.
    pub n_sites: usize,
    pub path_guide: bool,
    pub path_offset: bool,
    pub sensor_fan: bool,
    /// The site is learned: one state per step of a decision (its site features and rewards),
    /// the steps' progress and rewards' RSRP; otherwise one state per decision.
    pub learned: bool,
    /// Look-ahead distances per site ([`crate::config::ObservationConfig::site_lookahead_m`]).
    pub lookahead: usize,
    pub stay: bool,
    /// The RSRP a step's reward scores is not what the next state measured (a measured
    /// channel): sent for every step, not only for each decision's last.
    pub true_rsrp_every_step: bool,
}

impl CompactShape {
    /// `f32` values of a trunk row beyond the destination and the handover weight.
    pub fn trunk_f32(&self) -> usize {
        usize::from(self.path_guide) + 3 * usize::from(self.path_offset)
    }

    /// 16-bit codes of a trunk row.
    pub fn trunk_codes(&self) -> usize {
        1 + 3 * usize::from(self.path_guide) + 4 + 26 * usize::from(self.sensor_fan)
    }

    /// Bytes of a state's line-of-sight bits.
    pub fn los_bytes(&self) -> usize {
        self.n_sites.div_ceil(8)
    }
}

/// The trunk's own quantities at one observation (the rest of the trunk follows from the
/// state): codes per [`code`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TrunkRow {
    /// The episode's destination (m).
    pub destination_m: [f32; 3],
    /// The episode's handover weight w.
    pub handover_weight: f32,
    /// Vertical velocity (last displacement / max step), signed code.
    pub velocity_z: u16,
    /// Unit direction to the planned path's look-ahead point, signed codes.
    pub path_direction: [u16; 3],
    /// Path distance to go / goal_scale_m.
    pub path_to_go: f32,
    /// (tracked place on the path − position) / PATH_OFFSET_SCALE_M, clipped to ±3.
    pub path_offset: [f32; 3],
    /// c_t, unit code.
    pub obstacle_distance: u16,
    /// θ_t, signed codes.
    pub obstacle_direction: [u16; 3],
    /// The sensor fan, unit codes.
    pub sensor_fan: [u16; 26],
}

/// One state a site is chosen in: what every site's features are computed from.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StateRow {
    /// The UAV's position (m).
    pub position_m: [f32; 3],
    /// Horizontal velocity (last displacement / max step), signed codes.
    pub velocity_xy: [u16; 2],
    /// The serving site.
    pub serving: u16,
    /// The site whose serving at the next step would be a ping-pong (M: none).
    pub ping_pong: u16,
    /// Each site's measured RSRP, [`code::rsrp`].
    pub rsrp: Vec<u8>,
    /// Each site's geometric line of sight, one bit per site (site k: byte k / 8, bit k % 8;
    /// the RSRP cache's value, interpolated near a shadow edge, rounded).
    pub los: Vec<u8>,
    /// Per site (site-major) each look-ahead distance's predicted RSRP minus the predicted best
    /// (/ 10 dB in [−6, 0]), [`code::byte`] of its negation / 6.
    pub lookahead: Vec<u8>,
    /// Per site the stay fraction, [`code::byte`].
    pub stay: Vec<u8>,
    /// The predictive association's choice (M: none observed).
    pub choice: u16,
}

impl StateRow {
    /// Line of sight of site `k`.
    pub fn los(&self, k: usize) -> bool {
        self.los.get(k / 8).is_some_and(|b| b & (1 << (k % 8)) != 0)
    }
}

/// One environment's decisions of a rollout in compact form (columns, time-ordered).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompactTrajectory {
    /// Environment (stream) index within its actor.
    pub env: u32,
    /// Per decision \[T\]: unclipped moves \[T × 3\], sites, log-probs (all, site alone), V(s),
    /// raw rewards, ends, V(s') and the steps each decision ran; whether it ended in a collision
    /// or out of the area.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub moves: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub sites: Vec<u32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub logprobs: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub site_logprobs: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub values: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub rewards: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub terminated: Vec<bool>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub truncated: Vec<bool>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub next_values: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub decision_steps: Vec<u16>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub crashed: Vec<bool>,
    /// Per observation \[T + 1\] (each decision's, then the bootstrap state's): the
    /// [`TrunkRow`] in columns.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub destination_m: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub handover_weight: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub trunk_f32: Vec<f32>,
    /// 16-bit codes, little-endian (bincode writes a `u16` of 251 or more in 3 bytes).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub trunk_codes: Vec<u8>,
    /// Per state \[S + 1\] (each decision's first, then one per later step when the site is
    /// learned; the bootstrap state last): the [`StateRow`] in columns.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub position_m: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub velocity_codes: Vec<u8>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub serving: Vec<u16>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub ping_pong: Vec<u16>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub rsrp_codes: Vec<u8>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub los_bits: Vec<u8>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub lookahead_codes: Vec<u8>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub stay_codes: Vec<u8>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub choice: Vec<u16>,
    /// Per step of a learned site \[S\]: the step's progress (m) and its site-independent
    /// reward (terminal rewards, the route term, the goal).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub progress_m: Vec<f32>,
    #[serde(deserialize_with = "crate::budget::vec")]
    pub common_reward: Vec<f32>,
    /// The true RSRP codes the rewards score: after each decision's last step \[T × M\], or,
    /// with [`CompactShape::true_rsrp_every_step`], after every step \[S × M\] (a step's other
    /// rewards read the next state's measured codes).
    #[serde(deserialize_with = "crate::budget::vec")]
    pub reward_rsrp_codes: Vec<u8>,
    /// Episodes that ended during this rollout.
    #[serde(deserialize_with = "crate::budget::vec")]
    pub episodes: Vec<EpisodeSummary>,
}

fn push_codes(out: &mut Vec<u8>, codes: &[u16]) {
    for c in codes {
        out.extend_from_slice(&c.to_le_bytes());
    }
}

fn read_codes<const N: usize>(bytes: &[u8], at: &mut usize) -> [u16; N] {
    let mut out = [0u16; N];
    for c in &mut out {
        *c = u16::from_le_bytes([bytes[*at], bytes[*at + 1]]);
        *at += 2;
    }
    out
}

impl CompactTrajectory {
    /// Decisions in the trajectory.
    pub fn len(&self) -> usize {
        self.rewards.len()
    }

    pub fn is_empty(&self) -> bool {
        self.rewards.is_empty()
    }

    /// Observations (trunk rows) recorded.
    pub fn observations(&self) -> usize {
        self.handover_weight.len()
    }

    /// States recorded.
    pub fn states(&self) -> usize {
        self.serving.len()
    }

    /// Appends one observation's trunk row.
    pub fn push_trunk(&mut self, shape: &CompactShape, r: &TrunkRow) {
        self.destination_m.extend_from_slice(&r.destination_m);
        self.handover_weight.push(r.handover_weight);
        if shape.path_guide {
            self.trunk_f32.push(r.path_to_go);
        }
        if shape.path_offset {
            self.trunk_f32.extend_from_slice(&r.path_offset);
        }
        push_codes(&mut self.trunk_codes, &[r.velocity_z]);
        if shape.path_guide {
            push_codes(&mut self.trunk_codes, &r.path_direction);
        }
        push_codes(&mut self.trunk_codes, &[r.obstacle_distance]);
        push_codes(&mut self.trunk_codes, &r.obstacle_direction);
        if shape.sensor_fan {
            push_codes(&mut self.trunk_codes, &r.sensor_fan);
        }
    }

    /// Trunk row `i`; the columns must hold it ([`CompactTrajectory::shape_error`]).
    pub fn trunk(&self, shape: &CompactShape, i: usize) -> TrunkRow {
        let mut r = TrunkRow::default();
        r.destination_m
            .copy_from_slice(&self.destination_m[3 * i..3 * i + 3]);
        r.handover_weight = self.handover_weight[i];
        let f = &self.trunk_f32[i * shape.trunk_f32()..(i + 1) * shape.trunk_f32()];
        let mut at = 0;
        if shape.path_guide {
            r.path_to_go = f[0];
            at = 1;
        }
        if shape.path_offset {
            r.path_offset.copy_from_slice(&f[at..at + 3]);
        }
        let n = 2 * shape.trunk_codes();
        let codes = &self.trunk_codes[i * n..(i + 1) * n];
        let mut at = 0;
        [r.velocity_z] = read_codes(codes, &mut at);
        if shape.path_guide {
            r.path_direction = read_codes(codes, &mut at);
        }
        [r.obstacle_distance] = read_codes(codes, &mut at);
        r.obstacle_direction = read_codes(codes, &mut at);
        if shape.sensor_fan {
            r.sensor_fan = read_codes(codes, &mut at);
        }
        r
    }

    /// Appends one state.
    pub fn push_state(&mut self, shape: &CompactShape, s: &StateRow) {
        self.position_m.extend_from_slice(&s.position_m);
        push_codes(&mut self.velocity_codes, &s.velocity_xy);
        self.serving.push(s.serving);
        self.ping_pong.push(s.ping_pong);
        self.rsrp_codes.extend_from_slice(&s.rsrp);
        if shape.learned {
            self.los_bits.extend_from_slice(&s.los);
            self.lookahead_codes.extend_from_slice(&s.lookahead);
            if shape.stay {
                self.stay_codes.extend_from_slice(&s.stay);
            }
            self.choice.push(s.choice);
        }
    }

    /// State `i`; the columns must hold it ([`CompactTrajectory::shape_error`]).
    pub fn state(&self, shape: &CompactShape, i: usize) -> StateRow {
        let mut s = StateRow::default();
        self.state_into(shape, i, &mut s);
        s
    }

    /// State `i` into `s`, reusing its buffers.
    pub fn state_into(&self, shape: &CompactShape, i: usize, s: &mut StateRow) {
        let m = shape.n_sites;
        s.position_m
            .copy_from_slice(&self.position_m[3 * i..3 * i + 3]);
        s.velocity_xy = read_codes(&self.velocity_codes, &mut (4 * i));
        s.serving = self.serving[i];
        s.ping_pong = self.ping_pong[i];
        let fill = |v: &mut Vec<u8>, from: &[u8]| {
            v.clear();
            v.extend_from_slice(from);
        };
        fill(&mut s.rsrp, &self.rsrp_codes[i * m..(i + 1) * m]);
        if shape.learned {
            let lb = shape.los_bytes();
            fill(&mut s.los, &self.los_bits[i * lb..(i + 1) * lb]);
            let l = m * shape.lookahead;
            fill(&mut s.lookahead, &self.lookahead_codes[i * l..(i + 1) * l]);
            let st = m * usize::from(shape.stay);
            fill(&mut s.stay, &self.stay_codes[i * st..(i + 1) * st]);
            s.choice = self.choice[i];
        } else {
            s.los.clear();
            s.los.resize(shape.los_bytes(), 0);
            s.lookahead.clear();
            s.stay.clear();
            s.choice = m as u16;
        }
    }

    /// States of decision `t` (`decision_steps[t]` with a learned site, else 1).
    pub fn states_of(&self, shape: &CompactShape, t: usize) -> usize {
        if shape.learned {
            usize::from(self.decision_steps[t])
        } else {
            1
        }
    }

    /// Why the columns do not hold a trajectory of `shape` (with at most `max_repeat` steps per
    /// decision), or `None`: every column's length follows from the decisions' count and steps,
    /// every site index is below M + 1. The expansion indexes only what this admits.
    pub fn shape_error(&self, shape: &CompactShape, max_repeat: usize) -> Option<String> {
        let t = self.len();
        let m = shape.n_sites;
        let per_decision = [
            ("moves", self.moves.len(), 3 * t),
            ("sites", self.sites.len(), t),
            ("logprobs", self.logprobs.len(), t),
            ("site_logprobs", self.site_logprobs.len(), t),
            ("values", self.values.len(), t),
            ("terminated", self.terminated.len(), t),
            ("truncated", self.truncated.len(), t),
            ("next_values", self.next_values.len(), t),
            ("decision_steps", self.decision_steps.len(), t),
            ("crashed", self.crashed.len(), t),
        ];
        for (name, got, want) in per_decision {
            if got != want {
                return Some(format!(
                    "{name}: {got} values for {t} decisions (want {want})"
                ));
            }
        }
        if let Some(k) = self
            .decision_steps
            .iter()
            .position(|&k| k == 0 || usize::from(k) > max_repeat)
        {
            return Some(format!(
                "decision_steps[{k}] = {} (want 1..={max_repeat})",
                self.decision_steps[k]
            ));
        }
        let o = t + 1;
        let s = (0..t).map(|i| self.states_of(shape, i)).sum::<usize>();
        let learned = usize::from(shape.learned);
        let rewards_rows = if shape.true_rsrp_every_step { s } else { t };
        let columns = [
            ("destination_m", self.destination_m.len(), 3 * o),
            ("handover_weight", self.handover_weight.len(), o),
            ("trunk_f32", self.trunk_f32.len(), o * shape.trunk_f32()),
            (
                "trunk_codes",
                self.trunk_codes.len(),
                2 * o * shape.trunk_codes(),
            ),
            ("position_m", self.position_m.len(), 3 * (s + 1)),
            ("velocity_codes", self.velocity_codes.len(), 4 * (s + 1)),
            ("serving", self.serving.len(), s + 1),
            ("ping_pong", self.ping_pong.len(), s + 1),
            ("rsrp_codes", self.rsrp_codes.len(), m * (s + 1)),
            (
                "los_bits",
                self.los_bits.len(),
                learned * shape.los_bytes() * (s + 1),
            ),
            (
                "lookahead_codes",
                self.lookahead_codes.len(),
                learned * m * shape.lookahead * (s + 1),
            ),
            (
                "stay_codes",
                self.stay_codes.len(),
                learned * usize::from(shape.stay) * m * (s + 1),
            ),
            ("choice", self.choice.len(), learned * (s + 1)),
            ("progress_m", self.progress_m.len(), learned * s),
            ("common_reward", self.common_reward.len(), learned * s),
            (
                "reward_rsrp_codes",
                self.reward_rsrp_codes.len(),
                learned * m * rewards_rows,
            ),
        ];
        for (name, got, want) in columns {
            if got != want {
                return Some(format!(
                    "{name}: {got} values for {t} decisions and {s} states (want {want})"
                ));
            }
        }
        let too_far = |v: &[u16]| v.iter().position(|&k| usize::from(k) > m);
        // The serving site must be a site (below); the others may say "none" (M).
        for (name, v) in [("ping_pong", &self.ping_pong), ("choice", &self.choice)] {
            if let Some(i) = too_far(v) {
                return Some(format!("{name}[{i}] = {} (M = {m})", v[i]));
            }
        }
        if let Some(i) = self.serving.iter().position(|&k| usize::from(k) >= m) {
            return Some(format!("serving[{i}] = {} (M = {m})", self.serving[i]));
        }
        None
    }

    /// The first non-finite number, named, or `None`.
    pub fn first_non_finite(&self) -> Option<String> {
        let fields = [
            ("moves", &self.moves),
            ("logprobs", &self.logprobs),
            ("site_logprobs", &self.site_logprobs),
            ("values", &self.values),
            ("rewards", &self.rewards),
            ("next_values", &self.next_values),
            ("destination_m", &self.destination_m),
            ("handover_weight", &self.handover_weight),
            ("trunk_f32", &self.trunk_f32),
            ("position_m", &self.position_m),
            ("progress_m", &self.progress_m),
            ("common_reward", &self.common_reward),
        ];
        for (name, v) in fields {
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return Some(format!("{name}[{i}] = {}", v[i]));
            }
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rsrp_codes_keep_every_class_and_round_down() {
        for (dbm, want) in [
            (-80.0, -80.0),
            (-80.01, -80.5),
            (-79.99, -80.0),
            (-100.0, -100.0),
            (-100.2, -100.5),
            (-63.26, -63.5),
        ] {
            assert_eq!(code::rsrp_dbm(code::rsrp(dbm)), want, "{dbm}");
        }
        assert_eq!(code::rsrp_dbm(code::rsrp(-500.0)), code::RSRP_BOTTOM_DBM);
        assert_eq!(code::rsrp_dbm(code::rsrp(0.0)), code::RSRP_TOP_DBM);
        assert_eq!(code::rsrp(f64::NEG_INFINITY), code::RSRP_UNMEASURED);
        assert_eq!(code::rsrp_dbm(0), f64::NEG_INFINITY);
        // Every value within 0.5 dB below, over the whole range.
        let mut dbm = code::RSRP_BOTTOM_DBM;
        while dbm < code::RSRP_TOP_DBM {
            let back = code::rsrp_dbm(code::rsrp(dbm));
            assert!(
                back <= dbm && dbm - back < code::RSRP_STEP_DB,
                "{dbm} → {back}"
            );
            dbm += 0.137;
        }
    }

    #[test]
    fn fixed_point_codes_round_trip_within_their_resolution() {
        for v in [-1.0, 0.0, 1.0] {
            assert_eq!(code::signed_value(code::signed(v)), v);
        }
        for v in [-1.0, -0.3333, 0.0, 0.5, 0.99999, 1.0] {
            assert!(
                (code::signed_value(code::signed(v)) - v).abs() <= 1.6e-5,
                "{v}"
            );
            let u = 0.5 * (v + 1.0);
            assert!((code::unit_value(code::unit(u)) - u).abs() <= 7.7e-6, "{u}");
            assert!((code::byte_value(code::byte(u)) - u).abs() <= 0.002, "{u}");
        }
    }

    fn shape() -> CompactShape {
        CompactShape {
            n_sites: 3,
            path_guide: true,
            path_offset: false,
            sensor_fan: true,
            learned: true,
            lookahead: 0,
            stay: false,
            true_rsrp_every_step: false,
        }
    }

    #[test]
    fn rows_read_back_as_pushed() {
        let sh = shape();
        let mut c = CompactTrajectory::default();
        let mut trunk = TrunkRow {
            destination_m: [1.0, 2.0, 3.0],
            handover_weight: 1.5,
            velocity_z: 7,
            path_direction: [1, 2, 65535],
            path_to_go: 0.25,
            obstacle_distance: 300,
            obstacle_direction: [4, 5, 6],
            ..TrunkRow::default()
        };
        trunk.sensor_fan[25] = 999;
        let state = StateRow {
            position_m: [10.0, -20.0, 80.0],
            velocity_xy: [1, 65000],
            serving: 2,
            ping_pong: 3,
            rsrp: vec![0, 100, 255],
            los: vec![0b101],
            lookahead: vec![],
            stay: vec![],
            choice: 3,
        };
        c.push_trunk(&sh, &trunk);
        c.push_state(&sh, &state);
        assert_eq!(c.trunk(&sh, 0), trunk);
        assert_eq!(c.state(&sh, 0), state);
        assert!(state.los(0) && !state.los(1) && state.los(2));
        // No decision yet: one observation and one state, the bootstrap's.
        assert_eq!(c.shape_error(&sh, 5), None);
        c.serving[0] = 3;
        assert!(c.shape_error(&sh, 5).unwrap().contains("serving[0] = 3"));
    }
}
