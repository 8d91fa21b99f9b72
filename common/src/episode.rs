//! What one episode amounted to: why it ended ([`Outcome`]) and its summary
//! ([`EpisodeSummary`], spec/env.md "Metrics"), as actors send them and the evaluation reads them.

use serde::{Deserialize, Serialize};

/// Why an episode ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Within `env.goal_radius_m` of the destination (terminated).
    Goal,
    /// The swept UAV sphere touched a building (terminated).
    Collision,
    /// Left the flight area laterally (terminated).
    OutOfBounds,
    /// Reached the time limit T (truncated: the learner bootstraps).
    TimeLimit,
}

impl Outcome {
    /// Lower-case name, as the evaluation's CSVs and the Python package write it: `"goal"`,
    /// `"collision"`, `"out_of_bounds"`, `"time_limit"`.
    pub fn name(self) -> &'static str {
        match self {
            Outcome::Goal => "goal",
            Outcome::Collision => "collision",
            Outcome::OutOfBounds => "out_of_bounds",
            Outcome::TimeLimit => "time_limit",
        }
    }

    /// Terminated (a true terminal state) rather than truncated.
    pub fn is_terminal(self) -> bool {
        !matches!(self, Outcome::TimeLimit)
    }
}

/// What one episode amounted to (spec/env.md "Metrics").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EpisodeSummary {
    /// Id of the pair in its pool or file.
    pub pair_id: u64,
    pub outcome: Outcome,
    /// Undiscounted sum of the raw rewards.
    pub episodic_return: f64,
    pub length: u32,
    /// Distance flown L (m).
    pub distance_flown_m: f64,
    /// Shortest flyable path D of the pair (m).
    pub shortest_m: f64,
    /// Distance left to the destination at the end (m).
    pub remaining_m: f64,
    /// Mean serving RSRP over the steps (dBm).
    pub mean_rsrp_dbm: f64,
    /// Fractions of steps (= flight time) per serving-RSRP class.
    pub frac_excellent: f64,
    pub frac_mediocre: f64,
    pub frac_poor: f64,
    pub handovers: u32,
    pub ping_pongs: u32,
    /// Mean site regret over the steps: best RSRP − serving RSRP (dB).
    pub mean_site_regret_db: f64,
    /// Fraction of steps whose site regret exceeds `env.site_regret_threshold_db`.
    pub frac_site_regret_high: f64,
    /// Fraction of steps with class regret: the best site is excellent, the serving one is not.
    pub frac_class_regret: f64,
}

impl EpisodeSummary {
    /// Distance overhead over the shortest path, (L + remaining) / D − 1 (for a successful
    /// episode remaining ≤ the goal radius).
    pub fn overhead(&self) -> f64 {
        (self.distance_flown_m + self.remaining_m) / self.shortest_m - 1.0
    }

    /// Every number of the summary is finite.
    pub(crate) fn is_finite(&self) -> bool {
        [
            self.episodic_return,
            self.distance_flown_m,
            self.shortest_m,
            self.remaining_m,
            self.mean_rsrp_dbm,
            self.frac_excellent,
            self.frac_mediocre,
            self.frac_poor,
            self.mean_site_regret_db,
            self.frac_site_regret_high,
            self.frac_class_regret,
        ]
        .iter()
        .all(|v| v.is_finite())
    }
}
