//! Seed-aware statistics of an evaluation, from the records alone: each method's flights on a
//! grid of training seeds × pairs ([`Grid`]), a two-level bootstrap of its headline statistics
//! over seeds and pairs ([`method_intervals`]), and paired differences between two methods over
//! the flights they share ([`paired`]: the same seed index, the same pair id).
//!
//! The bootstrap is crossed: a resample draws the training seeds with replacement and, once for
//! all of them, the pair ids with replacement, and recomputes the statistic over every (drawn
//! seed, drawn pair) flight. Every seed flies the same pairs, so a pair's difficulty is shared
//! by the seeds and is resampled as one unit; the interval then holds the variance between
//! seeds, between pairs and of the flights. The 95 % interval is the 2.5 and 97.5 percentiles
//! of the resamples' statistics (linear interpolation between order statistics); a resample
//! whose statistic is undefined (no successful flight drawn) is left out.

use crate::error::EvalError;
use crate::metrics::{FlightMetrics, flight_metrics};
use crate::records::RecordsFile;
use dupac_common::msg::Outcome;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::collections::BTreeMap;

/// How many resamples the report's bootstrap draws by default.
pub const DEFAULT_RESAMPLES: usize = 2000;
/// The most resamples accepted (the report's time grows with them).
pub const MAX_RESAMPLES: usize = 1_000_000;
/// Seed of the bootstrap's ChaCha8 stream. Every method and every comparison draws from a stream
/// of its own started from this seed, so the report is deterministic and a method's interval
/// does not depend on which other methods were evaluated.
pub const BOOTSTRAP_SEED: u64 = 2024;

/// The bootstrap's settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bootstrap {
    /// Resamples drawn (B).
    pub resamples: usize,
    /// Seed of the ChaCha8 stream.
    pub seed: u64,
}

impl Default for Bootstrap {
    fn default() -> Self {
        Bootstrap {
            resamples: DEFAULT_RESAMPLES,
            seed: BOOTSTRAP_SEED,
        }
    }
}

impl Bootstrap {
    /// `resamples` draws from [`BOOTSTRAP_SEED`]; refused outside 1..=[`MAX_RESAMPLES`].
    pub fn with_resamples(resamples: usize) -> Result<Bootstrap, EvalError> {
        if !(1..=MAX_RESAMPLES).contains(&resamples) {
            return Err(EvalError::Refused(format!(
                "--bootstrap {resamples}: the resamples must be between 1 and {MAX_RESAMPLES}"
            )));
        }
        Ok(Bootstrap {
            resamples,
            seed: BOOTSTRAP_SEED,
        })
    }
}

/// The headline statistics of a method, each a ratio of sums over its flights.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Headline {
    /// Fraction of flights that reached the goal (0–1).
    Success,
    /// Mean distance overhead of successful flights (fraction of the shortest path).
    Overhead,
    /// Mean time in excellent RSRP of successful flights (%).
    Excellent,
    /// The same, net of the link's handover interruptions (`radio.handover_interruption_ms`).
    ExcellentNet,
    /// Mean serving RSRP of successful flights (dBm).
    MeanRsrp,
    /// Mean time with SINR < −6 dB over all flights (%).
    SinrLow,
    /// Handovers over all flights per km flown by them.
    HandoversPerKm,
    /// Ping-pongs over all flights per km flown by them.
    PingPongsPerKm,
}

/// Every headline, in the tables' order.
pub const HEADLINES: [Headline; 8] = [
    Headline::Success,
    Headline::Overhead,
    Headline::Excellent,
    Headline::ExcellentNet,
    Headline::MeanRsrp,
    Headline::SinrLow,
    Headline::HandoversPerKm,
    Headline::PingPongsPerKm,
];
const K: usize = HEADLINES.len();

impl Headline {
    /// The name in the CSVs (summary.csv's column of the same quantity and unit).
    pub fn name(self) -> &'static str {
        match self {
            Headline::Success => "success",
            Headline::Overhead => "overhead",
            Headline::Excellent => "pct_excellent",
            Headline::ExcellentNet => "pct_excellent_net",
            Headline::MeanRsrp => "mean_rsrp_dbm",
            Headline::SinrLow => "pct_sinr_below_m6db",
            Headline::HandoversPerKm => "handovers_per_km",
            Headline::PingPongsPerKm => "ping_pongs_per_km",
        }
    }

    /// Whether only successful flights count (a difference: flights where both succeeded).
    pub fn successes_only(self) -> bool {
        matches!(
            self,
            Headline::Overhead | Headline::Excellent | Headline::ExcellentNet | Headline::MeanRsrp
        )
    }

    /// One flight's numerator and denominator, None when the flight does not count (a failed
    /// flight for a success-only statistic, a value that is not finite).
    pub fn term(self, m: &FlightMetrics) -> Option<(f64, f64)> {
        let goal = m.outcome == Outcome::Goal;
        if self.successes_only() && !goal {
            return None;
        }
        let (num, den) = match self {
            Headline::Success => (f64::from(u8::from(goal)), 1.0),
            Headline::Overhead => (m.overhead, 1.0),
            Headline::Excellent => (100.0 * m.frac_class[0], 1.0),
            Headline::ExcellentNet => (100.0 * m.frac_excellent_net, 1.0),
            Headline::MeanRsrp => (m.mean_rsrp_dbm, 1.0),
            Headline::SinrLow => (100.0 * m.frac_sinr_below_m6db, 1.0),
            Headline::HandoversPerKm => (f64::from(m.handovers), m.distance_m / 1000.0),
            Headline::PingPongsPerKm => (f64::from(m.ping_pongs), m.distance_m / 1000.0),
        };
        (num.is_finite() && den.is_finite()).then_some((num, den))
    }
}

/// One training seed's flights: the seed and each flight's pair id with its metrics.
pub type SeedFlights = (u32, Vec<(u64, FlightMetrics)>);

/// A method's flights by training seed and pair: `flights(s, p)` are seed `seeds[s]`'s flights
/// over pair `pair_ids[p]` (one, unless a records file repeats a pair), in records order.
#[derive(Debug, Clone)]
pub struct Grid {
    pub label: String,
    /// Training seeds, ascending.
    pub seeds: Vec<u32>,
    /// Every pair id flown by some seed, ascending.
    pub pair_ids: Vec<u64>,
    cells: Vec<Vec<Vec<FlightMetrics>>>,
}

impl Grid {
    /// The grid of `label` from its seeds' flights, `(seed, [(pair id, metrics)])`.
    pub fn new(label: &str, seeds: Vec<SeedFlights>) -> Grid {
        let mut by_seed: BTreeMap<u32, BTreeMap<u64, Vec<FlightMetrics>>> = BTreeMap::new();
        for (seed, flights) in seeds {
            let cells = by_seed.entry(seed).or_default();
            for (pair, m) in flights {
                cells.entry(pair).or_default().push(m);
            }
        }
        let mut pair_ids: Vec<u64> = by_seed.values().flat_map(|c| c.keys().copied()).collect();
        pair_ids.sort_unstable();
        pair_ids.dedup();
        let cells = by_seed
            .values_mut()
            .map(|c| {
                pair_ids
                    .iter()
                    .map(|p| c.remove(p).unwrap_or_default())
                    .collect()
            })
            .collect();
        Grid {
            label: label.to_string(),
            seeds: by_seed.into_keys().collect(),
            pair_ids,
            cells,
        }
    }

    /// Seed index `s`'s flights over the pair at index `p`.
    pub fn flights(&self, s: usize, p: usize) -> &[FlightMetrics] {
        &self.cells[s][p]
    }

    /// The grid of the pairs `keep` accepts (by pair id), with the same seeds.
    pub fn restrict(&self, keep: impl Fn(u64) -> bool) -> Grid {
        let kept: Vec<usize> = (0..self.pair_ids.len())
            .filter(|&p| keep(self.pair_ids[p]))
            .collect();
        Grid {
            label: self.label.clone(),
            seeds: self.seeds.clone(),
            pair_ids: kept.iter().map(|&p| self.pair_ids[p]).collect(),
            cells: self
                .cells
                .iter()
                .map(|c| kept.iter().map(|&p| c[p].clone()).collect())
                .collect(),
        }
    }
}

/// Every method's grid from the records, in label order.
pub fn grids(files: &[RecordsFile]) -> Vec<Grid> {
    let mut by: BTreeMap<&str, Vec<SeedFlights>> = BTreeMap::new();
    for f in files {
        let flights = f
            .flights
            .iter()
            .map(|r| (r.pair_id, flight_metrics(r, &f.rules)))
            .collect();
        by.entry(f.method.as_str())
            .or_default()
            .push((f.seed, flights));
    }
    by.into_iter().map(|(l, s)| Grid::new(l, s)).collect()
}

/// A statistic over all flights with its 95 % bootstrap interval (NaN where undefined).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BootCi {
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
}

/// The sums of one cell (or of a resample) per headline: numerator and denominator of method A,
/// then of method B (zero for a single method).
#[derive(Debug, Clone, Copy, Default)]
struct Sums([[f64; 4]; K]);

impl Sums {
    fn add(&mut self, o: &Sums, w: f64) {
        for (a, b) in self.0.iter_mut().zip(&o.0) {
            for (x, y) in a.iter_mut().zip(b) {
                *x += w * y;
            }
        }
    }

    /// A's ratio per headline, or A's minus B's.
    fn value(&self, diff: bool) -> [f64; K] {
        self.0.map(|[na, da, nb, db]| {
            let a = na / da;
            if diff { a - nb / db } else { a }
        })
    }
}

/// The sums over every cell, each weighted 1.
fn total(cells: &[Vec<Sums>]) -> Sums {
    let mut t = Sums::default();
    for row in cells {
        for c in row {
            t.add(c, 1.0);
        }
    }
    t
}

/// The 95 % percentile interval of each headline over `boot.resamples` crossed resamples of
/// `cells` (rows: seed indices; columns: pairs).
fn bootstrap(cells: &[Vec<Sums>], diff: bool, boot: &Bootstrap) -> [(f64, f64); K] {
    let (n_seeds, n_pairs) = (cells.len(), cells.first().map_or(0, Vec::len));
    if n_seeds == 0 || n_pairs == 0 {
        return [(f64::NAN, f64::NAN); K];
    }
    let mut rng = ChaCha8Rng::seed_from_u64(boot.seed);
    let mut reps: [Vec<f64>; K] = Default::default();
    let (mut ws, mut wp) = (vec![0.0; n_seeds], vec![0.0; n_pairs]);
    for _ in 0..boot.resamples {
        ws.fill(0.0);
        for _ in 0..n_seeds {
            ws[rng.random_range(0..n_seeds)] += 1.0;
        }
        wp.fill(0.0);
        for _ in 0..n_pairs {
            wp[rng.random_range(0..n_pairs)] += 1.0;
        }
        let mut t = Sums::default();
        for (row, &w) in cells.iter().zip(&ws) {
            if w == 0.0 {
                continue;
            }
            let mut r = Sums::default();
            for (c, &v) in row.iter().zip(&wp) {
                if v != 0.0 {
                    r.add(c, v);
                }
            }
            t.add(&r, w);
        }
        for (rep, v) in reps.iter_mut().zip(t.value(diff)) {
            if v.is_finite() {
                rep.push(v);
            }
        }
    }
    reps.map(|mut r| {
        r.sort_by(f64::total_cmp);
        (percentile(&r, 0.025), percentile(&r, 0.975))
    })
}

/// The `q` quantile of sorted `v` (linear interpolation between order statistics, Hyndman and
/// Fan's type 7; NaN for no values).
pub fn percentile(v: &[f64], q: f64) -> f64 {
    match v.len() {
        0 => f64::NAN,
        n => {
            let h = (n - 1) as f64 * q.clamp(0.0, 1.0);
            let (i, f) = (h.floor() as usize, h - h.floor());
            match v.get(i + 1) {
                Some(&next) if f > 0.0 => v[i] + f * (next - v[i]),
                _ => v[i],
            }
        }
    }
}

/// One method's headline statistics over all its flights, each with its 95 % two-level
/// bootstrap interval, in [`HEADLINES`] order.
pub fn method_intervals(g: &Grid, boot: &Bootstrap) -> [BootCi; K] {
    let cells: Vec<Vec<Sums>> = (0..g.seeds.len())
        .map(|s| {
            (0..g.pair_ids.len())
                .map(|p| {
                    let mut c = Sums::default();
                    for m in g.flights(s, p) {
                        for (k, h) in HEADLINES.iter().enumerate() {
                            if let Some((num, den)) = h.term(m) {
                                c.0[k][0] += num;
                                c.0[k][1] += den;
                            }
                        }
                    }
                    c
                })
                .collect()
        })
        .collect();
    let value = total(&cells).value(false);
    let ci = bootstrap(&cells, false, boot);
    std::array::from_fn(|k| BootCi {
        value: value[k],
        lo: ci[k].0,
        hi: ci[k].1,
    })
}

/// The paired difference A − B of one headline over the flights both methods share.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairedDiff {
    pub headline: Headline,
    /// Matched flights counted (for a success-only statistic, those where both succeeded).
    pub n: usize,
    /// A's statistic minus B's over those flights: for a mean, the mean difference; for a rate
    /// per km, the difference of the two rates (handovers over km flown).
    pub diff: BootCi,
}

/// A comparison of two methods over their shared flights.
#[derive(Debug, Clone)]
pub struct Comparison {
    pub a: String,
    pub b: String,
    /// Seed indices matched (see [`paired`]).
    pub seed_indices: usize,
    pub diffs: Vec<PairedDiff>,
}

/// The seed of `g` matched with seed index `i`: a method with one seed (a planner, which is
/// deterministic) pairs it with every seed index of the other.
fn seed_at(g: &Grid, i: usize) -> usize {
    if g.seeds.len() == 1 { 0 } else { i }
}

/// The paired differences A − B of every headline: seed index i of A (ascending seed order) with
/// seed index i of B, over the first min(S_A, S_B) seed indices (a method with one seed pairs
/// with each of the other's), on the same pair id; flights of a pair that one of the two did not
/// fly are left out (a records file that repeats a pair matches its k-th flight with the other's
/// k-th). The interval resamples seed indices and pair ids jointly for both methods. None when
/// the two share no seed index or pair.
pub fn paired(a: &Grid, b: &Grid, boot: &Bootstrap) -> Option<Comparison> {
    let (sa, sb) = (a.seeds.len(), b.seeds.len());
    let seed_indices = if sa == 1 || sb == 1 {
        sa.max(sb)
    } else {
        sa.min(sb)
    };
    let shared: Vec<(usize, usize)> = a
        .pair_ids
        .iter()
        .enumerate()
        .filter_map(|(i, p)| b.pair_ids.binary_search(p).ok().map(|j| (i, j)))
        .collect();
    if sa == 0 || sb == 0 || shared.is_empty() {
        return None;
    }
    let mut n = [0usize; K];
    let cells: Vec<Vec<Sums>> = (0..seed_indices)
        .map(|i| {
            shared
                .iter()
                .map(|&(pa, pb)| {
                    let mut c = Sums::default();
                    let fa = a.flights(seed_at(a, i), pa);
                    let fb = b.flights(seed_at(b, i), pb);
                    for (x, y) in fa.iter().zip(fb) {
                        for (k, h) in HEADLINES.iter().enumerate() {
                            if let (Some((na, da)), Some((nb, db))) = (h.term(x), h.term(y)) {
                                c.0[k][0] += na;
                                c.0[k][1] += da;
                                c.0[k][2] += nb;
                                c.0[k][3] += db;
                                n[k] += 1;
                            }
                        }
                    }
                    c
                })
                .collect()
        })
        .collect();
    let value = total(&cells).value(true);
    let ci = bootstrap(&cells, true, boot);
    let diffs = HEADLINES
        .iter()
        .enumerate()
        .map(|(k, &headline)| PairedDiff {
            headline,
            n: n[k],
            diff: BootCi {
                value: value[k],
                lo: ci[k].0,
                hi: ci[k].1,
            },
        })
        .collect();
    Some(Comparison {
        a: a.label.clone(),
        b: b.label.clone(),
        seed_indices,
        diffs,
    })
}

#[cfg(test)]
mod tests;
