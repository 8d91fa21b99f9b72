//! What the operator's map predicts along the route ahead (docs/env.md "Predictive
//! association"): the map (RSRP without shadowing) sampled along the planned route once per
//! episode ([`RouteMap`]), and each step a prediction of the route ahead ([`Ahead`]) — the map
//! from the UAV's place on the route, corrected by what the UAV measures now (each site's
//! measured − map offset, fading with the distance ahead at the shadowing's decorrelation
//! distance). The predictive association plans on it ([`Ahead::choice`]); the look-ahead site
//! features read it.

use super::PathGuide;
use super::serving_plan::serving_plan;
use dupac_common::ids::SiteId;
use dupac_radio::source::RsrpSource;

/// The operator's map along a planned route: every site's RSRP without shadowing (dBm) at every
/// `sample_m` of arc length from the route's start, and at its end.
#[derive(Debug, Clone)]
pub struct RouteMap {
    sample_m: f64,
    m: usize,
    length_m: f64,
    /// Row j: the sites' map RSRP (dBm) at arc length min(j · sample_m, length).
    rows_dbm: Vec<f64>,
}

impl RouteMap {
    /// Samples `map` (M sites) along `route` every `sample_m` (m, > 0).
    pub fn new(route: &PathGuide, map: &dyn RsrpSource, sample_m: f64) -> RouteMap {
        let m = map.num_sites();
        let length_m = route.length_m();
        let n = (length_m / sample_m).ceil().max(0.0) as usize + 1;
        let mut rows_dbm = vec![f64::NEG_INFINITY; n * m];
        for (j, row) in rows_dbm.chunks_mut(m.max(1)).enumerate().take(n) {
            let s = (j as f64 * sample_m).min(length_m);
            map.rsrp_all_dbm(route.point_at(s), row);
        }
        RouteMap {
            sample_m,
            m,
            length_m,
            rows_dbm,
        }
    }

    /// Route length (m).
    pub fn length_m(&self) -> f64 {
        self.length_m
    }

    /// The sites' map RSRP (dBm) at arc length `s_m` (clamped to the route), linear between
    /// samples, into `out[0..M]`.
    pub fn at(&self, s_m: f64, out: &mut [f64]) {
        let n = self.rows_dbm.len() / self.m.max(1);
        let x = (s_m.clamp(0.0, self.length_m) / self.sample_m).max(0.0);
        let j = (x.floor() as usize).min(n.saturating_sub(1));
        let j1 = (j + 1).min(n.saturating_sub(1));
        // The last interval may be shorter than a sample (the end row sits at the length).
        let s_j = j as f64 * self.sample_m;
        let s_j1 = (j1 as f64 * self.sample_m).min(self.length_m);
        let f = if s_j1 > s_j {
            ((s_m.clamp(0.0, self.length_m) - s_j) / (s_j1 - s_j)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, b) = (
            &self.rows_dbm[j * self.m..(j + 1) * self.m],
            &self.rows_dbm[j1 * self.m..(j1 + 1) * self.m],
        );
        for ((o, &x0), &x1) in out.iter_mut().zip(a).zip(b) {
            *o = if f == 0.0 { x0 } else { x0 + f * (x1 - x0) };
        }
    }
}

/// The prediction of the route ahead at one step: row j holds every site's predicted RSRP (dBm)
/// at `j · sample_m` ahead of the UAV's place on the route, j = 0 … ⌈horizon / sample_m⌉
/// (beyond the route's end, the end's).
#[derive(Debug, Clone, Default)]
pub struct Ahead {
    sample_m: f64,
    m: usize,
    rows_dbm: Vec<f64>,
    /// The best finite value of each row (dBm; −∞ when none).
    best_dbm: Vec<f64>,
}

impl Ahead {
    /// An empty prediction for `m` sites at `sample_m` (m) spacing.
    pub fn new(m: usize, sample_m: f64) -> Ahead {
        Ahead {
            sample_m,
            m,
            rows_dbm: Vec::new(),
            best_dbm: Vec::new(),
        }
    }

    /// Predicts from arc length `s_m` over `horizon_m`: row j = the map at `s_m + j·Δ` plus
    /// `offset_db[k] · exp(−j·Δ / decorrelation_m[k])` (dB; the site's measured − map offset
    /// at the UAV and its shadowing's decorrelation distance, m). A non-finite offset counts 0.
    pub fn predict(
        &mut self,
        map: &RouteMap,
        s_m: f64,
        horizon_m: f64,
        offset_db: &[f64],
        decorrelation_m: &[f64],
    ) {
        let n = (horizon_m / self.sample_m).ceil().max(0.0) as usize + 1;
        self.rows_dbm.resize(n * self.m, f64::NEG_INFINITY);
        self.best_dbm.resize(n, f64::NEG_INFINITY);
        for ((j, row), best) in self
            .rows_dbm
            .chunks_mut(self.m.max(1))
            .enumerate()
            .zip(&mut self.best_dbm)
        {
            let ahead_m = j as f64 * self.sample_m;
            map.at(s_m + ahead_m, row);
            for ((r, &o), &d) in row.iter_mut().zip(offset_db).zip(decorrelation_m) {
                if o.is_finite() && o != 0.0 {
                    *r += o * (-ahead_m / d.max(1e-3)).exp();
                }
            }
            *best = row
                .iter()
                .copied()
                .filter(|x| x.is_finite())
                .fold(f64::NEG_INFINITY, f64::max);
        }
    }

    /// The rows (row-major, M per row; dBm).
    pub fn rows_dbm(&self) -> &[f64] {
        &self.rows_dbm
    }

    /// Rows in the prediction.
    pub fn len(&self) -> usize {
        self.rows_dbm.len() / self.m.max(1)
    }

    /// Whether nothing has been predicted.
    pub fn is_empty(&self) -> bool {
        self.rows_dbm.is_empty()
    }

    /// Every site's predicted RSRP (dBm) at `ahead_m` ahead (linear between rows, the last
    /// row's beyond the horizon) into `out[0..M]`.
    pub fn at(&self, ahead_m: f64, out: &mut [f64]) {
        let n = self.len();
        if n == 0 {
            out.fill(f64::NEG_INFINITY);
            return;
        }
        let x = (ahead_m / self.sample_m).clamp(0.0, (n - 1) as f64);
        let j = x.floor() as usize;
        let j1 = (j + 1).min(n - 1);
        let f = x - j as f64;
        let m = self.m;
        for (k, o) in out.iter_mut().enumerate().take(m) {
            let (a, b) = (self.rows_dbm[j * m + k], self.rows_dbm[j1 * m + k]);
            *o = if f == 0.0 { a } else { a + f * (b - a) };
        }
    }

    /// How far ahead (m) site `k` is predicted to stay within `within_db` of the predicted best:
    /// the distance of the first row where it falls below (0 when it does at row 0), the last
    /// row's distance when it never does.
    pub fn stay_m(&self, k: usize, within_db: f64) -> f64 {
        for (j, row) in self.rows_dbm.chunks(self.m.max(1)).enumerate() {
            // A site that cannot be predicted (NaN) is not within reach either.
            if row[k].is_nan() || row[k] < self.best_dbm[j] - within_db {
                return j as f64 * self.sample_m;
            }
        }
        self.len().saturating_sub(1) as f64 * self.sample_m
    }

    /// The predictive association's choice: the first site of the serving plan over the rows
    /// ([`serving_plan`]) from `serving`, with `handover_cost_db_m` dB·m per handover (each row
    /// stands for `sample_m` metres of route, so the cost is `handover_cost_db_m / sample_m`
    /// rows of 1 dB regret).
    pub fn choice(&self, serving: SiteId, handover_cost_db_m: f64) -> SiteId {
        if self.is_empty() {
            return serving;
        }
        let plan = serving_plan(
            &self.rows_dbm,
            self.m,
            serving.0,
            handover_cost_db_m / self.sample_m,
            0,
        );
        plan.first().map_or(serving, |&k| SiteId(k))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use dupac_common::geometry::Point;

    /// Two sites along the x axis: site 0 falls 0.1 dB per metre from −70 dBm at x = 0, site 1
    /// rises 0.1 dB per metre from −80 dBm (they cross at x = 50 m).
    struct Ramp;
    impl RsrpSource for Ramp {
        fn num_sites(&self) -> usize {
            2
        }
        fn rsrp_all_dbm(&self, p: Point, out: &mut [f64]) {
            out[0] = -70.0 - 0.1 * p[0];
            out[1] = -80.0 + 0.1 * p[0];
        }
        fn los_all(&self, _: Point, _: &mut [f64]) -> bool {
            false
        }
    }

    fn route() -> PathGuide {
        PathGuide::new(&[Point::new(0.0, 0.0, 50.0), Point::new(200.0, 0.0, 50.0)]).expect("path")
    }

    #[test]
    fn the_prediction_reads_the_map_along_the_route_ahead() {
        let map = RouteMap::new(&route(), &Ramp, 10.0);
        let mut ahead = Ahead::new(2, 10.0);
        // At s = 20 m, no offset: 30 m ahead (x = 50) the sites are level at −75 dBm.
        ahead.predict(&map, 20.0, 200.0, &[0.0, 0.0], &[50.0, 50.0]);
        assert_eq!(ahead.len(), 21);
        let mut out = [0.0; 2];
        ahead.at(30.0, &mut out);
        assert!(
            (out[0] + 75.0).abs() < 1e-9 && (out[1] + 75.0).abs() < 1e-9,
            "{out:?}"
        );
        ahead.at(5.0, &mut out); // between rows: x = 25
        assert!((out[0] + 72.5).abs() < 1e-9, "{out:?}");
        // Beyond the route's end (s = 200) the end's values.
        ahead.at(195.0, &mut out);
        assert!((out[1] + 60.0).abs() < 1e-9, "{out:?}");
        // Site 0 stays within 3 dB of the best until x = 65 (−76.5 vs −73.5): the row at 50 m
        // ahead (x = 70) is the first below.
        assert_eq!(ahead.stay_m(0, 3.0), 50.0);
        // Site 1 is 6 dB below here (x = 20: −72 against −78 dBm): not within 3 dB at row 0.
        assert_eq!(ahead.stay_m(1, 3.0), 0.0);
    }

    #[test]
    fn a_measured_offset_fades_with_the_distance_ahead() {
        let map = RouteMap::new(&route(), &Ramp, 10.0);
        let mut ahead = Ahead::new(2, 10.0);
        // Site 1 measured 10 dB above its map value, decorrelating over 50 m.
        ahead.predict(&map, 0.0, 100.0, &[0.0, 10.0], &[50.0, 50.0]);
        let mut out = [0.0; 2];
        ahead.at(0.0, &mut out);
        assert!((out[1] + 70.0).abs() < 1e-9, "{out:?}");
        ahead.at(50.0, &mut out);
        let want = -75.0 + 10.0 * (-1.0f64).exp();
        assert!((out[1] - want).abs() < 1e-9, "{out:?} vs {want}");
    }

    #[test]
    fn the_choice_is_the_first_site_of_the_exhaustive_best_plan() {
        // The predictive choice against every serving sequence of a small prediction: 2 sites
        // over 6 rows (64 sequences), for several costs and places on the route.
        let map = RouteMap::new(&route(), &Ramp, 10.0);
        let mut ahead = Ahead::new(2, 10.0);
        for (s, cost) in [
            (0.0, 0.0),
            (10.0, 50.0),
            (20.0, 100.0),
            (30.0, 400.0),
            (40.0, 50.0),
        ] {
            ahead.predict(&map, s, 50.0, &[0.0, 0.0], &[50.0, 50.0]);
            let rows = ahead.rows_dbm();
            let t = ahead.len();
            let mut best = (f64::INFINITY, 0u16);
            for code in 0..(1u32 << t) {
                let seq: Vec<u16> = (0..t).map(|i| ((code >> i) & 1) as u16).collect();
                let mut c = 0.0;
                let mut prev = 0u16;
                for (j, &k) in seq.iter().enumerate() {
                    let row = &rows[j * 2..j * 2 + 2];
                    c += row[0].max(row[1]) - row[usize::from(k)];
                    if k != prev {
                        c += cost / 10.0;
                    }
                    prev = k;
                }
                if c < best.0 - 1e-12 {
                    best = (c, seq[0]);
                }
            }
            assert_eq!(
                ahead.choice(SiteId(0), cost),
                SiteId(best.1),
                "s = {s}, cost {cost}"
            );
        }
        // 2 m before the crossing (x = 48: site 0 ahead by 0.4 dB) the plan stays one more row
        // and hands over at the next (2 dB of cost either way, 0.4 dB less regret); 2 m after
        // it, site 1.
        ahead.predict(&map, 48.0, 200.0, &[0.0, 0.0], &[50.0, 50.0]);
        assert_eq!(ahead.choice(SiteId(0), 20.0), SiteId(0));
        ahead.predict(&map, 52.0, 200.0, &[0.0, 0.0], &[50.0, 50.0]);
        assert_eq!(ahead.choice(SiteId(0), 20.0), SiteId(1));
        // A measured offset moves the choice: site 1 measured 3 dB above its map at x = 48 is
        // the best now and (fading over 50 m) on every row ahead.
        ahead.predict(&map, 48.0, 200.0, &[0.0, 3.0], &[50.0, 50.0]);
        assert_eq!(ahead.choice(SiteId(0), 20.0), SiteId(1));
    }
}
