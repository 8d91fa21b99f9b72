//! Fronts on the same flights (`dupac eval --a3-front`, `--hindsight-front`, `--predictive-front`;
//! docs/results.md "How the fronts are measured"): a learned site choice trades excellent time for
//! handovers, and so does every association rule through its parameters (A3 through its offset,
//! hysteresis, time-to-trigger and filter; the predictive and the hindsight association through
//! their handover cost), so one operating point of each is not a comparison. Each setting of a rule
//! re-flies the recorded positions of a learned-site policy (its own moves, as `LABEL+a3` does with
//! `radio.a3`) and, for A3, of every planner flown with A3 (its path), giving the rule's front on
//! exactly those flights ([`FrontFile`], one per method, seed and rule); the report then compares a
//! policy with A3 at the policy's own handover rate ([`matched`]), on A3's envelope without the
//! settings that keep excellent time only by more ping-pongs ([`FrontRow::pp_marked`]).
//!
//! Files: `OUT/records/front/<method>__<rule>__seed<k>.bin` (the one codec, its own magic and
//! version), each setting's per-flight metrics; the report reads them with the records.

use crate::a3_setting::A3Setting;
use crate::error::{Context, EvalError};
use crate::method_data::is_planner;
use crate::metrics::{FlightMetrics, flight_metrics};
use crate::records::RecordsFile;
use crate::stats::{Grid, Headline, SeedFlights};
use dupac_common::codec;
use dupac_common::fsio::write_atomic_with;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Magic and version of a front file.
pub const FRONT_MAGIC: &[u8; 8] = b"DUPACFRT";
pub const FRONT_VERSION: u32 = 2;
/// The folder of the front files inside the records folder.
pub const FRONT_DIR: &str = "front";
/// How far (points of excellent time) a setting with fewer ping-pongs may fall short of an
/// envelope point's excellent time and still show that point's gain bought by ping-pongs
/// ([`FrontRow::pp_marked`]).
pub const PP_MARK_EXCELLENT_PCT: f64 = 0.1;

/// The association rule whose settings a front re-flies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum FrontRule {
    /// 3GPP A3 (offset, hysteresis, time-to-trigger, A3's own filter).
    A3,
    /// The predictive association (`env.predictive`) by its handover cost.
    Predictive,
    /// The hindsight association (perfect foresight of the true field: a bound) by its
    /// handover cost.
    Hindsight,
}

impl FrontRule {
    /// The rule's name in file names and `front.csv`.
    pub fn name(self) -> &'static str {
        match self {
            FrontRule::A3 => "a3",
            FrontRule::Predictive => "predictive",
            FrontRule::Hindsight => "hindsight",
        }
    }
}

/// One setting of a rule.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum FrontSetting {
    A3(A3Setting),
    /// `env.predictive.handover_cost_db_m` (dB·m per handover).
    Predictive {
        handover_cost_db_m: f64,
    },
    /// The hindsight association's cost per handover (dB·steps), no minimum stay.
    Hindsight {
        handover_cost_db: f64,
    },
}

impl FrontSetting {
    pub fn rule(&self) -> FrontRule {
        match self {
            FrontSetting::A3(_) => FrontRule::A3,
            FrontSetting::Predictive { .. } => FrontRule::Predictive,
            FrontSetting::Hindsight { .. } => FrontRule::Hindsight,
        }
    }

    /// The A3 setting, for an A3 front.
    pub fn a3(&self) -> Option<&A3Setting> {
        match self {
            FrontSetting::A3(s) => Some(s),
            _ => None,
        }
    }

    /// The handover cost of a predictive or hindsight setting (dB·m or dB·steps).
    pub fn cost(&self) -> Option<f64> {
        match *self {
            FrontSetting::A3(_) => None,
            FrontSetting::Predictive { handover_cost_db_m } => Some(handover_cost_db_m),
            FrontSetting::Hindsight { handover_cost_db } => Some(handover_cost_db),
        }
    }

    /// As the tables write it: A3's [`A3Setting::label`], `C = … dB·m` or `C = … dB·steps`.
    pub fn label(&self) -> String {
        match *self {
            FrontSetting::A3(s) => s.label(),
            FrontSetting::Predictive { handover_cost_db_m } => {
                format!("C = {handover_cost_db_m} dB·m")
            }
            FrontSetting::Hindsight { handover_cost_db } => {
                format!("C = {handover_cost_db} dB·steps")
            }
        }
    }
}

/// One method's (and training seed's) flights re-flown with every setting of one rule.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrontFile {
    /// The label of the flights re-flown (`dupac`, `shortest_a3`, `coverage_l1`, …).
    pub method: String,
    pub seed: u32,
    /// A learned-site policy's moves (a planner's path otherwise).
    pub learned_site: bool,
    /// The rule every point's setting is of.
    pub rule: FrontRule,
    pub points: Vec<FrontPoint>,
}

/// One setting's flights: `(pair id, metrics)` in the records' order.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct FrontPoint {
    pub setting: FrontSetting,
    pub flights: Vec<(u64, FlightMetrics)>,
}

/// Writes `f` into `records_dir/front/` (atomically).
pub fn write_front(records_dir: &Path, f: &FrontFile) -> Result<(), EvalError> {
    let dir = records_dir.join(FRONT_DIR);
    std::fs::create_dir_all(&dir).context_with(|| format!("creating {}", dir.display()))?;
    let bytes = codec::encode(FRONT_MAGIC, FRONT_VERSION, f, "front")?;
    Ok(dupac_common::fsio::write_plain(
        &dir.join(format!(
            "{}__{}__seed{}.bin",
            f.method,
            f.rule.name(),
            f.seed
        )),
        &bytes,
    )?)
}

/// Every front file of `records_dir/front/` in name order (none when the folder is absent); a
/// file whose points are not all of its rule is refused, naming it.
pub fn read_fronts(records_dir: &Path) -> Result<Vec<FrontFile>, EvalError> {
    let dir = records_dir.join(FRONT_DIR);
    if !dir.is_dir() {
        return Ok(Vec::new());
    }
    crate::records::bin_files(&dir)?
        .iter()
        .map(|p| {
            let bytes = codec::read_limited(p, codec::MAX_BLOB_BYTES)?;
            let f: FrontFile = codec::decode(
                FRONT_MAGIC,
                FRONT_VERSION,
                &bytes,
                codec::MAX_BLOB_BYTES,
                &p.display().to_string(),
            )?;
            if let Some(q) = f.points.iter().find(|q| q.setting.rule() != f.rule) {
                return Err(crate::error::refused!(
                    "{}: a {} front holds the setting {}",
                    p.display(),
                    f.rule.name(),
                    q.setting.label()
                ));
            }
            Ok(f)
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

/// One setting of a method's front of one rule, its flights pooled over the training seeds.
#[derive(Debug, Clone)]
pub struct FrontRow {
    pub method: String,
    pub rule: FrontRule,
    pub setting: FrontSetting,
    pub measures: FrontMeasures,
    /// On the upper envelope: no other setting of the method's front keeps more excellent time
    /// with no more handovers per km ([`upper_envelope`]).
    pub on_front: bool,
    /// On the envelope, and its excellent time bought by ping-pongs: another setting of the
    /// front has no more handovers per km, fewer ping-pongs per km and at least its excellent
    /// time less [`PP_MARK_EXCELLENT_PCT`] points ([`pp_dominated`]).
    pub pp_marked: bool,
    /// On the upper envelope of the settings that no other buys off in that way
    /// ([`clean_envelope`]): the envelope with ping-pongs as a third axis, which the matched
    /// comparison uses.
    pub on_clean_front: bool,
}

/// The methods the fronts are drawn for, in order, each with its own point: the policies of the
/// records (not their re-flights `LABEL+…`, nor the planners), then every other method with a
/// front; a method's own point is the front measures of its recorded flights, flown with its own
/// association (none without records).
pub fn own_points(
    files: &[RecordsFile],
    rows: &[FrontRow],
) -> Vec<(String, Option<FrontMeasures>)> {
    let mut methods: Vec<&str> = files
        .iter()
        .map(|f| f.method.as_str())
        .filter(|l| !l.contains('+') && !is_planner(l))
        .chain(rows.iter().map(|r| r.method.as_str()))
        .collect();
    let mut seen = std::collections::BTreeSet::new();
    methods.retain(|l| seen.insert(*l));
    methods
        .into_iter()
        .map(|l| {
            let m: Vec<FlightMetrics> = files
                .iter()
                .filter(|f| f.method == l)
                .flat_map(|f| f.flights.iter().map(|r| flight_metrics(r, &f.rules)))
                .collect();
            (
                l.to_string(),
                (!m.is_empty()).then(|| FrontMeasures::of(m.iter())),
            )
        })
        .collect()
}

/// Each method's front of each rule, settings in the order flown.
pub fn front_rows(files: &[FrontFile]) -> Vec<FrontRow> {
    type Points<'a> = BTreeMap<usize, (FrontSetting, Vec<&'a FlightMetrics>)>;
    let mut by: BTreeMap<(&str, FrontRule), Points> = BTreeMap::new();
    for f in files {
        let m = by.entry((f.method.as_str(), f.rule)).or_default();
        for (k, p) in f.points.iter().enumerate() {
            let e = m.entry(k).or_insert_with(|| (p.setting, Vec::new()));
            e.1.extend(p.flights.iter().map(|(_, fm)| fm));
        }
    }
    let mut rows = Vec::new();
    for ((method, rule), points) in by {
        let measures: Vec<(FrontSetting, FrontMeasures)> = points
            .into_values()
            .map(|(s, fl)| (s, FrontMeasures::of(fl.iter().copied())))
            .collect();
        let xyz: Vec<(f64, f64, f64)> = measures
            .iter()
            .map(|(_, m)| (m.handovers_per_km, m.excellent_pct, m.ping_pongs_per_km))
            .collect();
        let xy: Vec<(f64, f64)> = xyz.iter().map(|&(x, y, _)| (x, y)).collect();
        let envelope = upper_envelope(&xy);
        let clean = clean_envelope(&xyz);
        rows.extend(
            measures
                .into_iter()
                .enumerate()
                .map(|(k, (setting, m))| FrontRow {
                    method: method.to_string(),
                    rule,
                    setting,
                    measures: m,
                    on_front: envelope.contains(&k),
                    pp_marked: envelope.contains(&k) && pp_dominated(&xyz, k),
                    on_clean_front: clean.contains(&k),
                }),
        );
    }
    rows
}

/// Whether point `i` of `(handovers/km, excellent %, ping-pongs/km)` keeps its excellent time
/// only by more ping-pongs: some other point has no more handovers per km, fewer ping-pongs per
/// km, and excellent time at most [`PP_MARK_EXCELLENT_PCT`] points below point `i`'s (or
/// above). Points with a non-finite coordinate neither are nor make one.
pub fn pp_dominated(points: &[(f64, f64, f64)], i: usize) -> bool {
    let finite = |p: &(f64, f64, f64)| p.0.is_finite() && p.1.is_finite() && p.2.is_finite();
    let p = points[i];
    finite(&p)
        && points.iter().enumerate().any(|(j, q)| {
            j != i && finite(q) && q.0 <= p.0 && q.2 < p.2 && q.1 >= p.1 - PP_MARK_EXCELLENT_PCT
        })
}

/// The indices of the upper envelope ([`upper_envelope`] of handovers/km and excellent %) of the
/// points that are not [`pp_dominated`], in ascending handovers/km.
pub fn clean_envelope(points: &[(f64, f64, f64)]) -> Vec<usize> {
    let xy: Vec<(f64, f64)> = (0..points.len())
        .map(|i| {
            if pp_dominated(points, i) {
                (f64::NAN, f64::NAN)
            } else {
                (points[i].0, points[i].1)
            }
        })
        .collect();
    upper_envelope(&xy)
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

/// `front.csv`: every method's front of every rule, one row per setting (the columns of another
/// rule's setting empty; `margin_db` = offset + hysteresis, what A3's entering condition
/// depends on; `l3_filter_k` empty where A3 compares what the UAV holds).
pub fn write_front_csv(path: &Path, rows: &[FrontRow]) -> Result<(), EvalError> {
    Ok(write_atomic_with(path, |w| {
        writeln!(
            w,
            "method,rule,offset_db,hysteresis_db,margin_db,time_to_trigger_ms,l3_filter_k,handover_cost,pct_excellent,pct_excellent_net,handovers_per_km,ping_pongs_per_km,pct_sinr_below_m6db,on_front,pp_marked,on_clean_front"
        )?;
        for r in rows {
            let m = &r.measures;
            let a3 = match r.setting.a3() {
                Some(s) => format!(
                    "{},{},{},{},{}",
                    s.offset_db,
                    s.hysteresis_db,
                    s.margin_db(),
                    s.time_to_trigger_ms,
                    s.l3_filter_k.map_or(String::new(), |k| k.to_string())
                ),
                None => ",,,,".to_string(),
            };
            let cost = r.setting.cost().map_or(String::new(), |c| c.to_string());
            writeln!(
                w,
                "{},{},{a3},{cost},{},{},{},{},{},{},{},{}",
                r.method,
                r.rule.name(),
                m.excellent_pct,
                m.excellent_net_pct,
                m.handovers_per_km,
                m.ping_pongs_per_km,
                m.sinr_below_m6db_pct,
                r.on_front,
                r.pp_marked,
                r.on_clean_front
            )?;
        }
        Ok(())
    })?)
}

/// A3 at a learned policy's own handover rate, on its own moves: the two settings of A3's front
/// of `label`'s moves (pooled over seeds; its envelope without the settings whose excellent time
/// is bought by ping-pongs, [`FrontRow::on_clean_front`]) that bracket the policy's handovers
/// per km, `lower`
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
    let a3 = |f: &&FrontFile| f.rule == FrontRule::A3;
    let mut labels: Vec<&str> = fronts
        .iter()
        .filter(a3)
        .filter(|f| f.learned_site)
        .map(|f| f.method.as_str())
        .collect();
    labels.sort_unstable();
    labels.dedup();
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
            .filter(|r| r.method == label && r.rule == FrontRule::A3 && r.on_clean_front)
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
        let (Some((lo, lo_s)), Some((up, up_s))) = (
            lower.and_then(|r| Some((r, *r.setting.a3()?))),
            upper.and_then(|r| Some((r, *r.setting.a3()?))),
        ) else {
            continue;
        };
        let (hl, hu) = (lo.measures.handovers_per_km, up.measures.handovers_per_km);
        let alpha = ((rate - hl) / (hu - hl)).clamp(0.0, 1.0);
        let seeds: Vec<SeedFlights> = fronts
            .iter()
            .filter(a3)
            .filter(|f| f.method == label)
            .filter_map(|f| {
                let of = |s: &FrontSetting| f.points.iter().find(|p| p.setting == *s);
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
            lower: lo_s,
            upper: up_s,
            alpha,
            grid: Grid::new(&name, seeds),
        });
    }
    out
}

#[cfg(test)]
mod tests;
