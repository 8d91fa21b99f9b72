//! A3's front on the same flights (`dupac eval --a3-front`, docs/results.md "Fronts"): a
//! learned site choice trades excellent time for handovers, and so does A3 through its offset,
//! hysteresis and time-to-trigger, so one operating point of each is not a comparison. Every
//! setting of the `dupac tune-a3` grid ([`A3Grid`](crate::a3_setting::A3Grid)) re-flies the recorded positions of a
//! learned-site policy (its own moves, as `LABEL+a3` does with `radio.a3`) and of every planner
//! flown with A3 (its path), giving A3's front on exactly those flights; the report then
//! compares a policy with A3 at the policy's own handover rate ([`matched`]).
//!
//! Files: `OUT/records/front/<method>__seed<k>.bin` (the one codec, its own magic and version),
//! each setting's per-flight metrics; the report reads them with the records.

use crate::a3_setting::A3Setting;
use crate::records::RecordsFile;
use crate::stats::{Grid, Headline, SeedFlights};
use dupac_actor::metrics::{FlightMetrics, flight_metrics};
use dupac_common::codec;
use dupac_common::fsio::write_atomic_with;
use dupac_run::error::{Context, RunError};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Magic and version of a front file.
pub const FRONT_MAGIC: &[u8; 8] = b"DUPACFRT";
pub const FRONT_VERSION: u32 = 1;
/// The folder of the front files inside the records folder.
pub const FRONT_DIR: &str = "front";

/// One method's (and training seed's) flights re-flown with every A3 setting.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrontFile {
    /// The label of the flights re-flown (`dupac`, `shortest_a3`, `coverage_l1`, …).
    pub method: String,
    pub seed: u32,
    /// A learned-site policy's moves (a planner's path otherwise).
    pub learned_site: bool,
    pub points: Vec<FrontPoint>,
}

/// One A3 setting's flights: `(pair id, metrics)` in the records' order.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrontPoint {
    pub setting: A3Setting,
    pub flights: Vec<(u64, FlightMetrics)>,
}

/// Writes `f` into `records_dir/front/` (atomically).
pub fn write_front(records_dir: &Path, f: &FrontFile) -> Result<(), RunError> {
    let dir = records_dir.join(FRONT_DIR);
    std::fs::create_dir_all(&dir).context_with(|| format!("creating {}", dir.display()))?;
    let bytes = codec::encode(FRONT_MAGIC, FRONT_VERSION, f, "A3 front")?;
    dupac_run::run_dir::write_plain(
        &dir.join(format!("{}__seed{}.bin", f.method, f.seed)),
        &bytes,
    )
}

/// Every front file of `records_dir/front/` in name order (none when the folder is absent).
pub fn read_fronts(records_dir: &Path) -> Result<Vec<FrontFile>, RunError> {
    let dir = records_dir.join(FRONT_DIR);
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    crate::records::bin_files(&dir)?
        .iter()
        .map(|p| {
            let bytes = codec::read_limited(p, codec::MAX_BLOB_BYTES)?;
            Ok(codec::decode(
                FRONT_MAGIC,
                FRONT_VERSION,
                &bytes,
                codec::MAX_BLOB_BYTES,
                &p.display().to_string(),
            )?)
        })
        .collect()
}

/// What a front's point (or a method) keeps over a set of flights: the report's measures, each
/// a ratio of sums as the headline statistics are ([`Headline::term`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrontMeasures {
    pub excellent_pct: f64,
    pub excellent_net_pct: f64,
    pub handovers_per_km: f64,
    pub ping_pongs_per_km: f64,
    pub sinr_below_m6db_pct: f64,
}

impl FrontMeasures {
    /// The measures of `flights`.
    pub fn of<'a>(flights: impl IntoIterator<Item = &'a FlightMetrics> + Clone) -> FrontMeasures {
        let ratio = |h: Headline| {
            let (n, d) = flights
                .clone()
                .into_iter()
                .filter_map(|m| h.term(m))
                .fold((0.0, 0.0), |(n, d), (x, y)| (n + x, d + y));
            if d > 0.0 { n / d } else { f64::NAN }
        };
        FrontMeasures {
            excellent_pct: ratio(Headline::Excellent),
            excellent_net_pct: ratio(Headline::ExcellentNet),
            handovers_per_km: ratio(Headline::HandoversPerKm),
            ping_pongs_per_km: ratio(Headline::PingPongsPerKm),
            sinr_below_m6db_pct: ratio(Headline::SinrLow),
        }
    }
}

/// One setting of a method's front, its flights pooled over the training seeds.
#[derive(Debug, Clone)]
pub struct FrontRow {
    pub method: String,
    pub setting: A3Setting,
    pub measures: FrontMeasures,
    /// On the upper envelope: no other setting of the method keeps more excellent time with no
    /// more handovers per km.
    pub on_front: bool,
}

/// Each method's front, settings in grid order.
pub fn front_rows(files: &[FrontFile]) -> Vec<FrontRow> {
    let mut by: BTreeMap<&str, BTreeMap<usize, (A3Setting, Vec<&FlightMetrics>)>> = BTreeMap::new();
    for f in files {
        let m = by.entry(f.method.as_str()).or_default();
        for (k, p) in f.points.iter().enumerate() {
            let e = m.entry(k).or_insert_with(|| (p.setting, Vec::new()));
            e.1.extend(p.flights.iter().map(|(_, fm)| fm));
        }
    }
    let mut rows = Vec::new();
    for (method, points) in by {
        let measures: Vec<(A3Setting, FrontMeasures)> = points
            .into_values()
            .map(|(s, fl)| (s, FrontMeasures::of(fl.iter().copied())))
            .collect();
        let xy: Vec<(f64, f64)> = measures
            .iter()
            .map(|(_, m)| (m.handovers_per_km, m.excellent_pct))
            .collect();
        let envelope = upper_envelope(&xy);
        rows.extend(
            measures
                .into_iter()
                .enumerate()
                .map(|(k, (setting, m))| FrontRow {
                    method: method.to_string(),
                    setting,
                    measures: m,
                    on_front: envelope.contains(&k),
                }),
        );
    }
    rows
}

/// The indices of the points `(x, y)` no other point dominates (x no higher and y higher, or x
/// lower and y no lower), in ascending x: the upper envelope of "more y for less x". Points
/// with a non-finite coordinate are left out.
pub fn upper_envelope(points: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len())
        .filter(|&i| points[i].0.is_finite() && points[i].1.is_finite())
        .collect();
    // Ascending x, and for one x the highest y first.
    order.sort_by(|&a, &b| {
        points[a]
            .0
            .total_cmp(&points[b].0)
            .then(points[b].1.total_cmp(&points[a].1))
    });
    let mut out = Vec::new();
    let mut best = f64::NEG_INFINITY;
    for i in order {
        if points[i].1 > best {
            best = points[i].1;
            out.push(i);
        }
    }
    out
}

/// `front.csv`: every method's front, one row per setting.
pub fn write_front_csv(path: &Path, rows: &[FrontRow]) -> Result<(), RunError> {
    Ok(write_atomic_with(path, |w| {
        writeln!(
            w,
            "method,offset_db,hysteresis_db,time_to_trigger_ms,pct_excellent,pct_excellent_net,handovers_per_km,ping_pongs_per_km,pct_sinr_below_m6db,on_front"
        )?;
        for r in rows {
            let (s, m) = (&r.setting, &r.measures);
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{}",
                r.method,
                s.offset_db,
                s.hysteresis_db,
                s.time_to_trigger_ms,
                m.excellent_pct,
                m.excellent_net_pct,
                m.handovers_per_km,
                m.ping_pongs_per_km,
                m.sinr_below_m6db_pct,
                r.on_front
            )?;
        }
        Ok(())
    })?)
}

/// A3 at a learned policy's own handover rate, on its own moves: the two settings of the front
/// of `label`'s moves (pooled over seeds) that bracket the policy's handovers per km, `lower`
/// (fewer handovers) and `upper`, and the share `alpha` of flights flown with `upper` so that
/// the mix has the policy's rate: each flight (seed, pair) takes `upper` when a fixed hash of
/// the two is below `alpha` ([`takes_upper`]). A mix of two A3 settings is an A3 operating
/// point an operator can run (one setting for some UAVs, the other for the rest).
#[derive(Debug, Clone)]
pub struct Matched {
    pub label: String,
    pub lower: A3Setting,
    pub upper: A3Setting,
    pub alpha: f64,
    /// The flights, as a method `LABEL+a3_matched` ([`Grid`]).
    pub grid: Grid,
}

/// Round of the matched mix's hash ("matched").
const MIX_ROUND: u64 = 0x0064_6568_6374_616d;

/// Whether flight (seed, pair) takes the upper setting of a mix with share `alpha`: a SplitMix64
/// hash of the two, as a uniform number in [0, 1), below `alpha`.
pub fn takes_upper(seed: u32, pair_id: u64, alpha: f64) -> bool {
    let h = dupac_common::seed::stream_seed(pair_id, u64::from(seed), MIX_ROUND);
    ((h >> 11) as f64 / (1u64 << 53) as f64) < alpha
}

/// The matched A3 of every learned-site policy of `records` whose moves have a front in
/// `fronts`; none for a policy whose rate lies outside its front.
pub fn matched(records: &[RecordsFile], fronts: &[FrontFile]) -> Vec<Matched> {
    let rows = front_rows(fronts);
    let mut out = Vec::new();
    let labels: Vec<&str> = {
        let mut l: Vec<&str> = fronts
            .iter()
            .filter(|f| f.learned_site)
            .map(|f| f.method.as_str())
            .collect();
        l.dedup();
        l
    };
    for label in labels {
        let own: Vec<&RecordsFile> = records.iter().filter(|r| r.method == label).collect();
        if own.is_empty() {
            continue;
        }
        let metrics: Vec<FlightMetrics> = own
            .iter()
            .flat_map(|r| r.flights.iter().map(|f| flight_metrics(f, &r.rules)))
            .collect();
        let rate = FrontMeasures::of(metrics.iter()).handovers_per_km;
        let env: Vec<&FrontRow> = rows
            .iter()
            .filter(|r| r.method == label && r.on_front)
            .collect();
        let lower = env
            .iter()
            .filter(|r| r.measures.handovers_per_km <= rate)
            .max_by(|a, b| {
                a.measures
                    .handovers_per_km
                    .total_cmp(&b.measures.handovers_per_km)
            });
        let upper = env
            .iter()
            .filter(|r| r.measures.handovers_per_km > rate)
            .min_by(|a, b| {
                a.measures
                    .handovers_per_km
                    .total_cmp(&b.measures.handovers_per_km)
            });
        let (Some(lo), Some(up)) = (lower, upper) else {
            continue;
        };
        let (hl, hu) = (lo.measures.handovers_per_km, up.measures.handovers_per_km);
        let alpha = ((rate - hl) / (hu - hl)).clamp(0.0, 1.0);
        let seeds: Vec<SeedFlights> = fronts
            .iter()
            .filter(|f| f.method == label)
            .filter_map(|f| {
                let of = |s: &A3Setting| f.points.iter().find(|p| p.setting == *s);
                let (pl, pu) = (of(&lo.setting)?, of(&up.setting)?);
                let flights = pl
                    .flights
                    .iter()
                    .zip(&pu.flights)
                    .map(|(a, b)| {
                        if takes_upper(f.seed, a.0, alpha) {
                            *b
                        } else {
                            *a
                        }
                    })
                    .collect();
                Some((f.seed, flights))
            })
            .collect();
        let name = format!("{label}+a3_matched");
        out.push(Matched {
            label: label.to_string(),
            lower: lo.setting,
            upper: up.setting,
            alpha,
            grid: Grid::new(&name, seeds),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_upper_envelope_keeps_the_undominated_points() {
        // (handovers/km, excellent %)
        let p = [
            (10.0, 90.0),
            (12.0, 89.0), // dominated by (10, 90)
            (15.0, 93.0),
            (15.0, 92.0), // same x, less y
            (20.0, 93.0), // no gain for more handovers
            (25.0, 95.0),
            (f64::NAN, 99.0),
        ];
        assert_eq!(upper_envelope(&p), vec![0, 2, 5]);
    }

    #[test]
    fn the_mix_takes_the_upper_setting_for_its_share_of_flights() {
        let n = 20_000u64;
        for alpha in [0.0, 0.25, 0.8, 1.0] {
            let k = (0..n).filter(|&p| takes_upper(3, p, alpha)).count() as f64;
            assert!((k / n as f64 - alpha).abs() < 0.015, "α {alpha}: {k}");
        }
        // A fixed function of (seed, pair).
        assert_eq!(takes_upper(1, 7, 0.5), takes_upper(1, 7, 0.5));
    }
}
