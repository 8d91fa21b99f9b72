//! The real channel (`radio.channel.model = "real"`, docs/env.md "Channel"): the shadow-fading
//! realisations a world's episodes fly in ([`Channel`]), and what the UAV measures of the RSRP
//! ([`Measurer`]: a measurement error per measurement period and the layer-3 filter of TS 36.331
//! §5.5.3.2).

use crate::pathloss::Scenario;
use crate::shadow::{FieldGrid, ShadowField};
use dupac_common::config::ChannelConfig;
use dupac_common::geometry::Bounds2;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use std::sync::{Arc, OnceLock};

/// Domain tag of the training realisations' streams ("sftrain").
pub const TRAIN_DOMAIN: u64 = 0x006e_6961_7274_6673;
/// Domain tag of the evaluation realisations' streams ("sfeval").
pub const EVAL_DOMAIN: u64 = 0x6c61_7665_6673;
/// Domain tag of the test split's realisations ("sftest").
pub const TEST_DOMAIN: u64 = 0x7473_6574_6673;
/// Domain tag of the measurement-error streams ("meas").
pub const MEASUREMENT_DOMAIN: u64 = 0x7361_656d;

/// Which realisations an episode draws from: training's, evaluation's on the validation pairs
/// (never trained in), or the test split's (used once, by the final evaluation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum FieldSplit {
    #[default]
    Train,
    Eval,
    Test,
}

impl FieldSplit {
    /// The split's domain tag ([`TRAIN_DOMAIN`], [`EVAL_DOMAIN`], [`TEST_DOMAIN`]).
    pub fn domain(self) -> u64 {
        match self {
            FieldSplit::Train => TRAIN_DOMAIN,
            FieldSplit::Eval => EVAL_DOMAIN,
            FieldSplit::Test => TEST_DOMAIN,
        }
    }
}

/// The shadow-fading realisations of a world, each drawn when first used and then shared.
pub struct Channel {
    cfg: ChannelConfig,
    grid: FieldGrid,
    scenarios: Vec<Scenario>,
    train: Vec<OnceLock<Arc<ShadowField>>>,
    eval: Vec<OnceLock<Arc<ShadowField>>>,
    test: Vec<OnceLock<Arc<ShadowField>>>,
}

impl std::fmt::Debug for Channel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Channel")
            .field("cfg", &self.cfg)
            .field("grid", &self.grid)
            .finish()
    }
}

impl Channel {
    /// The channel of `cfg` over `area_m` for sites of `scenarios`; `None` for the
    /// deterministic model.
    pub fn new(cfg: &ChannelConfig, area_m: Bounds2, scenarios: Vec<Scenario>) -> Option<Channel> {
        if !cfg.shadowing() {
            return None;
        }
        let slots = |n: u32| (0..n).map(|_| OnceLock::new()).collect();
        Some(Channel {
            cfg: cfg.clone(),
            grid: FieldGrid::covering(area_m, cfg.shadowing_grid_m),
            scenarios,
            train: slots(cfg.train_fields),
            eval: slots(cfg.eval_fields),
            test: slots(cfg.eval_fields),
        })
    }

    pub fn config(&self) -> &ChannelConfig {
        &self.cfg
    }

    /// Realisation `index` (modulo the split's count) of `split`.
    pub fn field(&self, split: FieldSplit, index: u64) -> Arc<ShadowField> {
        let slots = match split {
            FieldSplit::Train => &self.train,
            FieldSplit::Eval => &self.eval,
            FieldSplit::Test => &self.test,
        };
        let domain = split.domain();
        let i = (index % slots.len() as u64) as u32;
        slots[i as usize]
            .get_or_init(|| {
                let t = std::time::Instant::now();
                let f = ShadowField::generate(
                    self.grid,
                    &self.scenarios,
                    self.cfg.field_seed,
                    domain,
                    i,
                    self.cfg.inter_site_correlation,
                );
                tracing::debug!(
                    ?split,
                    index = i,
                    secs = t.elapsed().as_secs_f64(),
                    "shadow-fading field drawn"
                );
                Arc::new(f)
            })
            .clone()
    }

    /// The realisation an episode reset with `seed` flies in: in training one chosen by the
    /// seed's hash; in evaluation (validation or test), whose seed is the pair's id, field
    /// `id mod eval_fields`, so every method flies a pair in the same field.
    pub fn episode_field(&self, split: FieldSplit, seed: u64) -> Arc<ShadowField> {
        match split {
            FieldSplit::Train => self.field(
                split,
                dupac_common::seed::stream_seed(seed, TRAIN_DOMAIN, 0),
            ),
            FieldSplit::Eval | FieldSplit::Test => self.field(split, seed),
        }
    }
}

/// Layer-3 filter coefficient a per step of `dt_s` (s) for `filterCoefficient` k: a = 1/2^(k/4)
/// per 200 ms (TS 36.331 §5.5.3.2), adapted so that the filter's time constant is kept at
/// another input period (its note on other sample rates): a_step = 1 − (1 − a)^(dt/0.2 s).
/// k = 0 gives 1 (no filtering).
pub fn l3_coefficient(k: u32, dt_s: f64) -> f64 {
    let a = 0.5f64.powf(f64::from(k) / 4.0);
    1.0 - (1.0 - a).powf(dt_s / 0.2)
}

/// What the UAV measures of every site's RSRP: once per measurement period (TS 36.133 §8.1.2.2:
/// 200 ms for intra-frequency RSRP), the mean of the true RSRP over the period's steps (dB) plus
/// an N(0, σ²) error independent per site and period, layer-3 filtered in dB once per period
/// (TS 36.331 §5.5.3.2: F_n = (1 − a)·F_{n−1} + a·M_n, F_1 = M_1) and held until the next
/// period ends. The first measurement is made at the episode's first position, so the UAV has
/// one from the start. With σ per period and k = 4 the filtered error has σ·√(a/(2 − a)):
/// 1.15 dB for σ = 2 dB (a = 1/2).
#[derive(Debug, Clone)]
pub struct Measurer {
    sigma_db: f64,
    a: f64,
    /// Steps per measurement period (≥ 1).
    period_steps: u32,
    rng: ChaCha8Rng,
    filtered_dbm: Vec<f64>,
    /// Sum of the true RSRP over the current period's steps (dBm).
    sum_dbm: Vec<f64>,
    /// Steps in the current period so far.
    in_period: u32,
    started: bool,
    /// Whether the last [`Measurer::measure`] delivered a new measurement.
    fresh: bool,
    /// The last measurement before the layer-3 filter, M_n (dBm).
    raw_dbm: Vec<f64>,
}

impl Measurer {
    /// A measurer of `n_sites` sites with error σ `sigma_db` (dB per measurement), filter
    /// coefficient `filter_k`, a step period of `dt_s` (s) and a measurement period of
    /// `period_s` (s; rounded to whole steps, at least one). The filter's coefficient is
    /// TS 36.331's a = 1/2^(k/4) per 200 ms, adapted to the rounded period ([`l3_coefficient`]).
    pub fn new(n_sites: usize, sigma_db: f64, filter_k: u32, dt_s: f64, period_s: f64) -> Measurer {
        let period_steps = (period_s / dt_s).round().clamp(1.0, 1e6) as u32;
        Measurer {
            sigma_db,
            a: l3_coefficient(filter_k, f64::from(period_steps) * dt_s),
            period_steps,
            rng: ChaCha8Rng::seed_from_u64(0),
            filtered_dbm: vec![f64::NEG_INFINITY; n_sites],
            sum_dbm: vec![0.0; n_sites],
            in_period: 0,
            started: false,
            fresh: false,
            raw_dbm: vec![f64::NEG_INFINITY; n_sites],
        }
    }

    /// Whether the last [`Measurer::measure`] delivered a new measurement (the first step of an
    /// episode and the end of every period); between, the UAV holds the last one.
    pub fn fresh(&self) -> bool {
        self.fresh
    }

    /// The last measurement before the layer-3 filter, M_n (dBm; mean over the period plus the
    /// error): what a filter of another coefficient (A3's own, `radio.a3.l3_filter_k`) takes.
    pub fn raw_dbm(&self) -> &[f64] {
        &self.raw_dbm
    }

    /// The filter coefficient per measurement period.
    pub fn coefficient(&self) -> f64 {
        self.a
    }

    /// Steps per measurement period.
    pub fn period_steps(&self) -> u32 {
        self.period_steps
    }

    /// Starts an episode: the errors of an episode of `split` reset with `seed` are a stream of
    /// their own (validation pair k and test pair k do not share one).
    pub fn reset(&mut self, split: FieldSplit, seed: u64) {
        let mut key = [0u8; 32];
        key[..8].copy_from_slice(&seed.to_le_bytes());
        key[8..16].copy_from_slice(&MEASUREMENT_DOMAIN.to_le_bytes());
        key[16..24].copy_from_slice(&split.domain().to_le_bytes());
        self.rng = ChaCha8Rng::from_seed(key);
        self.sum_dbm.fill(0.0);
        self.in_period = 0;
        self.started = false;
    }

    /// One step: adds `true_dbm` (dBm) to the period's mean and writes what the UAV holds into
    /// `out` (dBm, filtered): a new measurement at the first step and at the end of every
    /// period, the last one between. A site that cannot be measured (−∞) restarts its filter.
    pub fn measure(&mut self, true_dbm: &[f64], out: &mut [f64]) {
        for (s, t) in self.sum_dbm.iter_mut().zip(true_dbm) {
            *s += t;
        }
        self.in_period += 1;
        self.fresh = !(self.started && self.in_period < self.period_steps);
        if !self.fresh {
            out.copy_from_slice(&self.filtered_dbm);
            return;
        }
        let n = f64::from(self.in_period);
        for (((s, f), o), r) in self
            .sum_dbm
            .iter_mut()
            .zip(&mut self.filtered_dbm)
            .zip(out)
            .zip(&mut self.raw_dbm)
        {
            let e: f64 = StandardNormal.sample(&mut self.rng);
            let m = *s / n + self.sigma_db * e;
            *r = m;
            *f = if self.started && f.is_finite() && m.is_finite() {
                (1.0 - self.a) * *f + self.a * m
            } else {
                m
            };
            *o = *f;
            *s = 0.0;
        }
        self.in_period = 0;
        self.started = true;
    }
}
