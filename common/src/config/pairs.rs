//! `[pairs]` (the training pool and the held-out splits' pairs, spec/env.md "Episodes") and
//! `[planner]` (the voxel planners), each checked against `[env]`'s flight band.

use super::ConfigError;
use super::EnvConfig;
use super::check::*;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// Source/destination pairs (spec/env.md "Episodes").
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct PairsConfig {
    /// Training pairs: shortest flyable path length uniform in [min_m, max_m] (m); the shortest.
    pub min_m: f64,
    /// The longest shortest flyable path of a training pair (m).
    pub max_m: f64,
    /// Endpoints keep at least this clearance from buildings (m).
    pub endpoint_clearance_m: f64,
    /// Held-out evaluation bins (shortest path, m), ± `bin_tolerance` (fraction).
    pub eval_bins_m: Vec<f64>,
    /// Half-width of an evaluation bin, as a fraction of its length (0.05 = ± 5 %).
    pub bin_tolerance: f64,
    /// Pairs per held-out bin (K), in each split (validation and test).
    pub eval_per_bin: usize,
    /// Seed of the validation split: the held-out pairs training evaluates on and the design
    /// was chosen on (`dupac eval --split validation`, the default).
    pub eval_seed: u64,
    /// Where `dupac pairs` writes the validation split (JSON Lines; read when present).
    /// `{city}` in the path stands for the city's fingerprint (16 hex digits): with the default,
    /// each city (Midtown, a procedural one, an import) has its own pairs, as it has its own
    /// caches, and switching the scenario needs no path.
    pub eval_file: PathBuf,
    /// Seed of the test split: the same bins and count as the validation split, drawn from its
    /// own random streams (never a validation or training pair); for the final report only
    /// (`dupac eval --split test`). Not part of the environment fingerprint. 8117 since the
    /// look-ahead design (5171 and 4049, the earlier test splits, were each flown for a report).
    pub test_seed: u64,
    /// Where `dupac pairs` writes the test split (JSON Lines; read when present; `{city}` as in
    /// `eval_file`). Not part of the environment fingerprint.
    pub test_file: PathBuf,
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
            eval_file: "out/pairs/{city}/eval_pairs.jsonl".into(),
            test_seed: 8117,
            test_file: "out/pairs/{city}/test_pairs.jsonl".into(),
        }
    }
}

/// The voxel planners (shortest flyable path, coverage-aware path).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
    /// Penalty per metre where the best site's RSRP is poor.
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

impl PairsConfig {
    /// The section as the environment fingerprint hashes it: without the test split
    /// (`test_seed`, `test_file`), which no training or validation episode reads, and with
    /// `eval_file` emptied (file locations may differ between hosts) — the JSON the section had
    /// before the test split was added, so fingerprints and guide caches stay valid.
    pub fn fingerprint_json(&self) -> String {
        #[derive(Serialize)]
        struct Hashed<'a> {
            min_m: f64,
            max_m: f64,
            endpoint_clearance_m: f64,
            eval_bins_m: &'a [f64],
            bin_tolerance: f64,
            eval_per_bin: usize,
            eval_seed: u64,
            eval_file: &'a str,
        }
        serde_json::to_string(&Hashed {
            min_m: self.min_m,
            max_m: self.max_m,
            endpoint_clearance_m: self.endpoint_clearance_m,
            eval_bins_m: &self.eval_bins_m,
            bin_tolerance: self.bin_tolerance,
            eval_per_bin: self.eval_per_bin,
            eval_seed: self.eval_seed,
            eval_file: "",
        })
        .unwrap_or_default()
    }

    /// Checks `[pairs]` against the flight band of `[env]`.
    pub(crate) fn validate(&self, e: &EnvConfig) -> Result<(), ConfigError> {
        let pr = self;
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
        if pr.test_file == pr.eval_file {
            return Err(bad(
                "pairs.test_file",
                "must differ from pairs.eval_file (the test split has its own file)",
            ));
        }
        Ok(())
    }
}

impl PlannerConfig {
    /// Checks `[planner]` against `[env]`.
    pub(crate) fn validate(&self, e: &EnvConfig) -> Result<(), ConfigError> {
        let pl = self;
        positive("planner.voxel_m", pl.voxel_m)?;
        if !(pl.clearance_m.is_finite() && pl.clearance_m >= e.uav_radius_m) {
            return Err(bad("planner.clearance_m", "must be >= env.uav_radius_m"));
        }
        let g = e.observation.path_guide_clearance_m;
        if g != 0.0 && g < e.uav_radius_m {
            return Err(bad(
                "env.observation.path_guide_clearance_m",
                "must be 0 (planner.clearance_m) or >= env.uav_radius_m",
            ));
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
        Ok(())
    }
}
