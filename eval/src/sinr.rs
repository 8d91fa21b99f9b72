//! The SINR of a recorded step from every site's RSRP (spec/env.md "Metrics"): what
//! `dupac eval` records per step (`crate::record::StepRecord::sinr_db`).

/// Thermal noise per LTE resource element (dBm): −174 dBm/Hz + 10·log10(15 kHz) + a UE noise
/// figure of 9 dB. RSRP is a per-resource-element power, so SINR from RSRPs uses this noise.
pub const NOISE_PER_RE_DBM: f64 = -174.0 + 41.760_912_590_556_81 + 9.0;

/// SINR (dB) of `serving` with every other site as a co-channel interferer at full load:
/// S / (Σ_{j ≠ serving} I_j + N), all in linear mW from dBm. Sites with a NaN/−∞ RSRP add
/// nothing.
pub fn sinr_db(rsrp_all_dbm: &[f64], serving: usize, noise_dbm: f64) -> f64 {
    let mw = |dbm: f64| {
        if dbm.is_finite() {
            10f64.powf(dbm / 10.0)
        } else {
            0.0
        }
    };
    let s = rsrp_all_dbm.get(serving).copied().map(mw).unwrap_or(0.0);
    let i: f64 = rsrp_all_dbm
        .iter()
        .enumerate()
        .filter(|(j, _)| *j != serving)
        .map(|(_, v)| mw(*v))
        .sum();
    10.0 * (s / (i + mw(noise_dbm))).log10()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sinr_of_equal_interferers_and_noise() {
        // Serving −70 dBm, two interferers at −73 dBm (each half the power): SINR ≈ 0 dB.
        let s = sinr_db(&[-70.0, -73.0103, -73.0103], 0, -200.0);
        assert!(s.abs() < 1e-3, "{s}");
        // Alone above the noise: RSRP − N.
        let s = sinr_db(&[-100.0, f64::NEG_INFINITY], 0, NOISE_PER_RE_DBM);
        assert!((s - (-100.0 - NOISE_PER_RE_DBM)).abs() < 1e-9);
        assert!((NOISE_PER_RE_DBM - (-123.24)).abs() < 0.01);
    }
}
