//! The scriptable link calculator behind `dupac radio link` (one JSON object per input line,
//! one JSON line per answer; radio.md §1–3) and the sites-file CSV of `dupac radio sites`.
//! Every line is bounded ([`MAX_LINE_BYTES`]); a bad line is refused with its line number and
//! the rest is still answered.

use crate::antenna::AntennaPattern;
use crate::city::City;
use crate::link::{LinkModel, Transmitter};
use crate::pathloss::Scenario;
use crate::world::RadioWorld;
use dupac_common::config::Config;
use dupac_common::geometry::Point;
use serde::Deserialize;
use std::io::{BufRead, Write};

/// One input line of `dupac radio link`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LinkRequest {
    #[serde(with = "dupac_common::geometry::serde_point")]
    bs_xyz: Point,
    #[serde(with = "dupac_common::geometry::serde_point")]
    uav_xyz: Point,
    scenario: Scenario,
    los: Option<bool>,
    boresights_deg: Option<Vec<f64>>,
    n: Option<u32>,
    spacing_wavelengths: Option<f64>,
    tilt_deg: Option<f64>,
    fc_ghz: Option<f64>,
    tx_power_dbm: Option<f64>,
    /// A standard-normal deviate of the link's shadow fading: the answer adds `shadow_db` = σ_SF·z
    /// and the shadowed RSRP (docs/env.md "Channel").
    sf_z: Option<f64>,
}

/// Processes JSON Lines from `input`; returns the number of failed lines.
pub fn link_stream(
    cfg: &Config,
    input: impl BufRead,
    out: &mut dyn Write,
    err: &mut dyn Write,
) -> std::io::Result<usize> {
    let mut city: Option<City> = None;
    let mut failed = 0usize;
    let mut input = input;
    let mut buf = Vec::new();
    let mut lineno = 0usize;
    loop {
        lineno += 1;
        buf.clear();
        // At most MAX_LINE_BYTES + 1 bytes of a line are kept; the rest is skipped.
        let n = std::io::Read::take(&mut input, MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|e| {
                std::io::Error::new(e.kind(), format!("reading input line {lineno}: {e}"))
            })?;
        if n == 0 {
            break;
        }
        let bad_line = |err: &mut dyn Write, what: String| writeln!(err, "line {lineno}: {what}");
        if buf.len() > MAX_LINE_BYTES && buf.last() != Some(&b'\n') {
            // Skip to the end of the over-long line.
            let mut rest = Vec::new();
            loop {
                rest.clear();
                let k = std::io::Read::take(&mut input, 1 << 16)
                    .read_until(b'\n', &mut rest)
                    .map_err(|e| {
                        std::io::Error::new(e.kind(), format!("reading input line {lineno}: {e}"))
                    })?;
                if k == 0 || rest.last() == Some(&b'\n') {
                    break;
                }
            }
            failed += 1;
            bad_line(err, format!("longer than {MAX_LINE_BYTES} bytes"))?;
            continue;
        }
        let line = match std::str::from_utf8(&buf) {
            Ok(l) => l,
            Err(e) => {
                failed += 1;
                bad_line(err, format!("not UTF-8 at byte {}", e.valid_up_to()))?;
                continue;
            }
        };
        if line.trim().is_empty() {
            continue;
        }
        match link_one(cfg, line, &mut city) {
            Ok(json) => writeln!(out, "{json}")?,
            Err(e) => {
                failed += 1;
                writeln!(err, "line {lineno}: {e}")?;
            }
        }
    }
    Ok(failed)
}

/// Longest input line of `dupac radio link` (bytes); a request is ≈ 200.
pub const MAX_LINE_BYTES: usize = 64 * 1024;
/// Farthest point from the scenario centre accepted (m): 100 km, far beyond any cell's reach.
const MAX_RANGE_M: f64 = 100_000.0;
/// Highest point accepted (m): 10 km, above any UAV airspace and any mast.
const MAX_HEIGHT_M: f64 = 10_000.0;

/// A position inside the physical range of the models: finite, within [`MAX_RANGE_M`]
/// horizontally, on or above the ground and below [`MAX_HEIGHT_M`].
fn check_position(name: &str, v: Point) -> Result<(), String> {
    if !v.iter().all(|x| x.is_finite()) {
        return Err(format!("field `{name}`: {v:?} is not finite"));
    }
    if v[0].abs() > MAX_RANGE_M || v[1].abs() > MAX_RANGE_M {
        return Err(format!(
            "field `{name}`: {v:?} is more than {MAX_RANGE_M} m from the scenario centre"
        ));
    }
    if !(0.0..=MAX_HEIGHT_M).contains(&v[2]) {
        return Err(format!(
            "field `{name}`: height {} m is not in [0, {MAX_HEIGHT_M}] m (heights are above the ground)",
            v[2]
        ));
    }
    Ok(())
}

fn link_one(cfg: &Config, line: &str, city: &mut Option<City>) -> Result<String, String> {
    let req: LinkRequest = serde_json::from_str(line).map_err(|e| e.to_string())?;
    check_position("bs_xyz", req.bs_xyz)?;
    check_position("uav_xyz", req.uav_xyz)?;
    let mut radio = cfg.radio.clone();
    if let Some(f) = req.fc_ghz {
        // TR 38.901 §7.4, which TR 36.777's models build on: 0.5–100 GHz.
        if !(f.is_finite() && (0.5..=100.0).contains(&f)) {
            return Err(format!("field `fc_ghz`: {f} must be in [0.5, 100] GHz"));
        }
        radio.fc_ghz = f;
    }
    let tx_power_dbm = match req.tx_power_dbm {
        Some(p) if !(p.is_finite() && (-50.0..=80.0).contains(&p)) => {
            return Err(format!(
                "field `tx_power_dbm`: {p} must be in [-50, 80] dBm"
            ));
        }
        Some(p) => p,
        None => radio.tx_power_dbm,
    };
    let n = req.n.unwrap_or(radio.antenna.n_elements);
    if n == 0 || n > 1024 {
        return Err(format!("field `n`: {n} must be in 1..=1024"));
    }
    let spacing = req
        .spacing_wavelengths
        .unwrap_or(radio.antenna.spacing_wavelengths);
    if !(spacing.is_finite() && spacing > 0.0) {
        return Err(format!(
            "field `spacing_wavelengths`: {spacing} must be > 0"
        ));
    }
    let tilt = req.tilt_deg.unwrap_or(radio.antenna.electrical_tilt_deg);
    if !(tilt.is_finite() && (-90.0..=90.0).contains(&tilt)) {
        return Err(format!("field `tilt_deg`: {tilt} must be in [-90, 90]"));
    }
    let boresights = req
        .boresights_deg
        .unwrap_or_else(|| radio.antenna.boresights_deg.clone());
    if boresights.is_empty() || boresights.iter().any(|b| !b.is_finite()) {
        return Err("field `boresights_deg`: must list finite angles".into());
    }
    let los = match req.los {
        Some(l) => l,
        None => {
            if city.is_none() {
                *city = Some(
                    City::load(&cfg.scenario)
                        .map_err(|e| format!("cannot load the city for geometric LoS: {e}"))?,
                );
            }
            let c = city.as_ref().ok_or("no city")?;
            for (name, p) in [("bs_xyz", req.bs_xyz), ("uav_xyz", req.uav_xyz)] {
                if !c.in_area(p[0], p[1]) {
                    let a = c.area_m;
                    return Err(format!(
                        "field `{name}`: {p:?} is outside the map ({a}); give `los` explicitly for points off the map"
                    ));
                }
            }
            !c.segment_blocked(req.bs_xyz, req.uav_xyz)
        }
    };
    let antenna = AntennaPattern::with_array(&radio.antenna, n, spacing, tilt);
    let model = LinkModel::from_config(&radio);
    let tx = Transmitter {
        position_m: req.bs_xyz,
        antenna: &antenna,
        boresights_deg: &boresights,
        scenario: req.scenario,
        tx_power_dbm,
    };
    let budget = model.evaluate(&tx, req.uav_xyz, los);
    let sigma_sf_db = crate::shadow::sigma_sf_db(req.scenario, los, req.uav_xyz[2]);
    let mut v = serde_json::json!({
        "d3d_m": budget.d3d_m,
        "d2d_m": budget.d2d_m,
        "theta_deg": budget.theta_deg,
        "best_sector": budget.best_sector,
        "gain_dbi": budget.gain_dbi,
        "pl_db": budget.pl_db,
        "rsrp_dbm": budget.rsrp_dbm,
        "class": budget.class,
        "los": budget.los,
        "sigma_sf_db": sigma_sf_db,
        "sf_decorrelation_m": crate::shadow::decorrelation_m(req.scenario, los),
    });
    if let Some(z) = req.sf_z {
        if !(z.is_finite() && z.abs() <= 10.0) {
            return Err(format!(
                "field `sf_z`: {z} must be a standard-normal deviate in [-10, 10]"
            ));
        }
        let shadow_db = sigma_sf_db * z;
        let rsrp = budget.rsrp_dbm - shadow_db;
        v["shadow_db"] = serde_json::json!(shadow_db);
        v["rsrp_shadowed_dbm"] = serde_json::json!(rsrp);
        v["class_shadowed"] = serde_json::json!(model.thresholds.classify(rsrp));
    }
    Ok(v.to_string())
}

/// The resolved sites as a sites-file CSV, loadable again with `scenario.sites_file`:
/// `name,x_m,y_m,z_m,kind,boresights_deg,tilt_deg,tx_power_dbm`.
pub fn write_sites_csv(world: &RadioWorld, w: &mut dyn Write) -> std::io::Result<()> {
    writeln!(
        w,
        "name,x_m,y_m,z_m,kind,boresights_deg,tilt_deg,tx_power_dbm"
    )?;
    for s in &world.sites {
        let kind = match s.kind {
            crate::sites::SiteKind::Macro => "macro",
            crate::sites::SiteKind::Micro => "micro",
        };
        let bores: Vec<String> = s.boresights_deg.iter().map(|b| format!("{b}")).collect();
        writeln!(
            w,
            "{},{:.2},{:.2},{:.2},{},{},{},{}",
            s.name,
            s.position_m[0],
            s.position_m[1],
            s.position_m[2],
            kind,
            bores.join(";"),
            s.electrical_tilt_deg,
            s.tx_power_dbm
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const GOOD: &str = r#"{"bs_xyz":[0,0,25],"uav_xyz":[100,0,50],"scenario":"uma","los":true}"#;

    fn cfg() -> Config {
        let mut c = Config::default();
        c.scenario.city = dupac_common::config::CityKind::Procedural;
        c.scenario.procedural.size_m = 300.0;
        c
    }

    /// Runs `input` through the link calculator: (answers, error lines, failed count).
    fn run(input: &[u8]) -> (usize, usize, usize) {
        let (mut out, mut err) = (Vec::new(), Vec::new());
        let failed = link_stream(&cfg(), input, &mut out, &mut err).expect("stream");
        let count = |b: &[u8]| b.iter().filter(|&&c| c == b'\n').count();
        (count(&out), count(&err), failed)
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        /// Any bytes, and a valid line with bytes flipped, never panic; every
        /// non-blank line is answered or refused with one error line, and good lines around
        /// it are still answered.
        #[test]
        fn any_line_is_answered_or_refused_never_a_panic(
            garbage in prop::collection::vec(any::<u8>(), 0..300),
            flips in prop::collection::vec((any::<usize>(), any::<u8>()), 0..6),
        ) {
            let mut line = GOOD.as_bytes().to_vec();
            for (at, x) in flips {
                let n = line.len();
                line[at % n] ^= x;
            }
            for bad in [&garbage, &line] {
                let bad: Vec<u8> = bad.iter().map(|&b| if b == b'\n' { b' ' } else { b }).collect();
                let mut input = format!("{GOOD}\n").into_bytes();
                input.extend_from_slice(&bad);
                input.extend_from_slice(format!("\n{GOOD}\n").as_bytes());
                let (answers, errors, failed) = run(&input);
                prop_assert_eq!(errors, failed);
                let blank = std::str::from_utf8(&bad).is_ok_and(|s| s.trim().is_empty());
                prop_assert_eq!(answers + errors, if blank { 2 } else { 3 });
                prop_assert!(answers >= 2);
            }
        }
    }
}
