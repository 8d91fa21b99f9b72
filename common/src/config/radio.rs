//! `[radio]` (path loss, antenna, A3; spec/radio.md), `[map]` and `[cache]`.

use super::ConfigError;
#[allow(unused_imports)]
use super::check::*;
use serde::{Deserialize, Serialize};
#[allow(unused_imports)]
use std::path::PathBuf;

/// Antenna model (spec/radio.md §2, TR 38.901 Table 7.3-1 + vertical ULA).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
    /// The sites' antenna arrays.
    pub antenna: AntennaConfig,
    /// The A3 handover rule of the base method.
    pub a3: A3Config,
    /// Shadow fading, measurement error and filter (`model = "deterministic"`: none).
    pub channel: super::ChannelConfig,
    /// How long a handover interrupts the link (ms), for the metrics' time in excellent RSRP net
    /// of interruptions: TS 36.133 §5.1.2.1's intra-frequency interruption T_interrupt =
    /// T_search + T_IU + 20 ms with a known target cell (T_search = 0) and T_IU up to 30 ms:
    /// 50 ms. ITU-R M.2134's IMT-Advanced requirement is 27.5 ms. Metrics only: the
    /// environment and its rewards do not model the interruption.
    pub handover_interruption_ms: f64,
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
            channel: super::ChannelConfig::default(),
            handover_interruption_ms: 50.0,
        }
    }
}

/// Coverage maps (`dupac map`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
pub struct CacheConfig {
    /// Horizontal grid step (m).
    pub horizontal_m: f64,
    /// Vertical grid step (m).
    pub vertical_m: f64,
    /// Lowest altitude of the grid (m): the UAV altitude band of spec/env.md.
    pub z_min_m: f64,
    /// Highest altitude of the grid (m).
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

impl RadioConfig {
    /// Checks `[radio]`.
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        let r = self;
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
        r.channel.validate()?;
        within(
            "radio.handover_interruption_ms",
            r.handover_interruption_ms,
            0.0,
            10_000.0,
            "ms",
        )?;
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
        Ok(())
    }

    /// Upper bounds of `[radio]` values that size time or memory.
    pub(crate) fn validate_bounds(&self) -> Result<(), ConfigError> {
        let r = self;
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
        Ok(())
    }
}

impl MapConfig {
    /// Checks `[map]`.
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        let m = self;
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
        Ok(())
    }
}

impl CacheConfig {
    /// Checks `[cache]`.
    pub(crate) fn validate(&self) -> Result<(), ConfigError> {
        let c = self;
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
        Ok(())
    }
}
