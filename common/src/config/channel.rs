//! `[radio.channel]`: what the radio world adds to the deterministic RSRP of spec/radio.md §3 —
//! log-normal shadow fading, the UAV's measurement error and its layer-3 filter — and what the
//! planners know of it (docs/env.md "Channel", docs/spec/radio.md §1 and §4).

use super::ConfigError;
use super::check::*;
use serde::{Deserialize, Serialize};

/// Which world the UAV flies in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ChannelModel {
    /// The paper's world: RSRP is the deterministic value of spec/radio.md §3, measured exactly.
    Deterministic,
    /// Shadow fading on every link (TR 36.777 Table B-3 σ, TR 38.901 Table 7.5-6 decorrelation),
    /// and the UAV observes noisy, layer-3-filtered measurements of it.
    Real,
}

/// What the UAV and its planners know of the real channel (`model = "real"` only).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Knowledge {
    /// What an operator has: the guide and the coverage-aware planner plan on the model without
    /// shadowing; the UAV observes noisy, filtered measurements.
    Operator,
    /// The true shadowed field: the planners plan on the episode's field and the UAV observes
    /// the true RSRP (a bound on what better knowledge can buy; evaluation only).
    TrueField,
}

/// `[radio.channel]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct ChannelConfig {
    /// `deterministic` (the paper's) or `real`.
    pub model: ChannelModel,
    /// Horizontal step of the shadow-fading field's grid (m); the field is bilinear between
    /// grid points.
    pub shadowing_grid_m: f64,
    /// Seed of every shadow-fading field; training and evaluation draw from disjoint streams.
    pub field_seed: u64,
    /// Shadow-fading realisations training draws from (one per episode, chosen by its seed).
    pub train_fields: u32,
    /// Shadow-fading realisations evaluation uses (pair `id` flies in field `id mod
    /// eval_fields`), never seen in training; the test split has as many of its own.
    pub eval_fields: u32,
    /// Standard deviation of one measurement's RSRP error (dB), independent per site and
    /// measurement period: TS 36.133 §9.1.2 intra-frequency relative RSRP accuracy ±2 dB, which
    /// applies to a measurement over the period below, taken as σ. 0: exact.
    pub measurement_sigma_db: f64,
    /// Measurement period (ms): the UAV's physical layer delivers one RSRP measurement per site
    /// this often (the mean over the period plus the error above), and the layer-3 filter runs
    /// once per measurement. TS 36.133 §8.1.2.2: 200 ms for intra-frequency RSRP in
    /// RRC_CONNECTED without DRX. Rounded to whole steps (4 of 48 ms). One step's worth gives a
    /// fresh, independent error every step (σ after the k = 4 filter then ≈ 0.6 dB, not 1.2).
    pub measurement_period_ms: f64,
    /// Layer-3 filter coefficient k of TS 36.331 §5.5.3.2 (`filterCoefficient`, default fc4):
    /// F = (1 − a)·F + a·M with a = 1/2^(k/4) per 200 ms (adapted to the measurement period).
    /// 0: no filter.
    pub l3_filter_k: u32,
    /// Correlation ρ of the shadow fading between two sites (same line-of-sight state): each
    /// site's field is √ρ·(a field shared by all sites) + √(1 − ρ)·(its own). 0 (default):
    /// independent sites, as TR 36.777 / TR 38.901 leave inter-site correlation unspecified for
    /// this model; TR 36.873 Table 8.3-1 (3D-UMa/UMi) and ITU-R M.2135 use 0.5 between sites.
    /// Independent fields give any strongest-site chooser a selection-diversity gain that
    /// correlated ones shrink (docs/env.md "Channel").
    pub inter_site_correlation: f64,
    /// What the planners and the UAV know of the channel.
    pub knowledge: Knowledge,
}

impl Default for ChannelConfig {
    fn default() -> Self {
        Self {
            model: ChannelModel::Deterministic,
            shadowing_grid_m: 5.0,
            field_seed: 1,
            train_fields: 8,
            eval_fields: 8,
            measurement_sigma_db: 2.0,
            measurement_period_ms: 200.0,
            l3_filter_k: 4,
            inter_site_correlation: 0.0,
            knowledge: Knowledge::Operator,
        }
    }
}

impl ChannelConfig {
    /// Whether RSRP has shadow fading.
    pub fn shadowing(&self) -> bool {
        self.model == ChannelModel::Real
    }

    /// Whether the UAV observes noisy, filtered measurements instead of the true RSRP.
    pub fn measured(&self) -> bool {
        self.model == ChannelModel::Real
            && self.knowledge == Knowledge::Operator
            && (self.measurement_sigma_db > 0.0 || self.l3_filter_k > 0)
    }

    /// Checks `[radio.channel]`.
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        let c = self;
        within(
            "radio.channel.shadowing_grid_m",
            c.shadowing_grid_m,
            0.5,
            100.0,
            "m",
        )?;
        within(
            "radio.channel.measurement_sigma_db",
            c.measurement_sigma_db,
            0.0,
            20.0,
            "dB",
        )?;
        within(
            "radio.channel.measurement_period_ms",
            c.measurement_period_ms,
            1.0,
            10_000.0,
            "ms",
        )?;
        within(
            "radio.channel.inter_site_correlation",
            c.inter_site_correlation,
            0.0,
            0.99,
            "",
        )?;
        // TS 36.331 FilterCoefficient: fc0 … fc19.
        at_most("radio.channel.l3_filter_k", u64::from(c.l3_filter_k), 19)?;
        for (key, n) in [
            ("radio.channel.train_fields", c.train_fields),
            ("radio.channel.eval_fields", c.eval_fields),
        ] {
            if !(1..=256).contains(&n) {
                return Err(bad(key, format!("must be in [1, 256], got {n}")));
            }
        }
        Ok(())
    }
}
