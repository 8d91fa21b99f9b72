//! Log-normal shadow fading (docs/spec/radio.md §1 "Shadow fading"): its standard deviation
//! (TR 36.777 Table B-3 above 22.5 m, TR 38.901 Table 7.4.1-1 at and below), its decorrelation
//! distance (TR 38.901 Table 7.5-6) and one realisation of it over the flight area
//! ([`ShadowField`]): per site, a LoS and an NLoS unit-variance Gaussian field over the
//! horizontal plane with the exponential autocorrelation exp(−d/d_corr), drawn exactly on a grid
//! by circulant embedding and interpolated between grid points bilinearly, then rescaled to unit
//! variance (a bilinear mix of correlated unit values has a variance below 1: down to 0.67 in the
//! middle of a 5 m cell at UMi's 10 m decorrelation; the rescaling keeps σ exact everywhere).
//!
//! The shadow fading of a link is σ(LoS, h)·Z with Z the site's field of the link's LoS state
//! (TR 38.901 §7.5 draws LoS and NLoS large-scale parameters apart); it adds to the path loss,
//! so RSRP drops by it. Fields of different sites are independent by default (TR 38.901 §7.5:
//! co-sited sectors share one, distinct sites do not); `radio.channel.inter_site_correlation` ρ
//! mixes a field shared by the sites of one scenario and LoS state into each:
//! Z = √ρ·Z_shared + √(1 − ρ)·Z_own. The field does not vary with height: neither TR gives a
//! vertical decorrelation distance for aerial UEs; σ does (Table B-3).

use crate::pathloss::Scenario;
use dupac_common::geometry::{Bounds2, Point};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};
use std::sync::Arc;

/// UAV heights above which TR 36.777's aerial σ applies (m); TR 38.901's terrestrial one at and
/// below.
pub const AERIAL_FROM_M: f64 = 22.5;

/// Shadow-fading standard deviation σ_SF (dB) of a link of `scenario` in the LoS state `los` to
/// a UAV `h_ut_m` above ground. TR 36.777 Table B-3 for h > 22.5 m (UMa-AV: LoS 4.64·e^(−0.0066h),
/// NLoS 6, stated to 100 m and kept above; UMi-AV: LoS max(5·e^(−0.01h), 2), NLoS 8); TR 38.901
/// Table 7.4.1-1 at and below (UMa 4 / 6, UMi street canyon 4 / 7.82).
pub fn sigma_sf_db(scenario: Scenario, los: bool, h_ut_m: f64) -> f64 {
    let aerial = h_ut_m > AERIAL_FROM_M;
    match (scenario, los, aerial) {
        (Scenario::Uma, true, true) => 4.64 * (-0.0066 * h_ut_m).exp(),
        (Scenario::Uma, false, true) => 6.0,
        (Scenario::Umi, true, true) => (5.0 * (-0.01 * h_ut_m).exp()).max(2.0),
        (Scenario::Umi, false, true) => 8.0,
        (Scenario::Uma, true, false) => 4.0,
        (Scenario::Uma, false, false) => 6.0,
        (Scenario::Umi, true, false) => 4.0,
        (Scenario::Umi, false, false) => 7.82,
    }
}

/// Shadow-fading decorrelation distance (m), TR 38.901 Table 7.5-6: UMa LoS 37, NLoS 50; UMi
/// street canyon LoS 10, NLoS 13. TR 36.777 gives no aerial value and refers to TR 38.901.
pub fn decorrelation_m(scenario: Scenario, los: bool) -> f64 {
    match (scenario, los) {
        (Scenario::Uma, true) => 37.0,
        (Scenario::Uma, false) => 50.0,
        (Scenario::Umi, true) => 10.0,
        (Scenario::Umi, false) => 13.0,
    }
}

/// The horizontal grid a field is drawn on: point `(ix, iy)` at `(x0_m + ix·step_m,
/// y0_m + iy·step_m)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FieldGrid {
    pub x0_m: f64,
    pub y0_m: f64,
    pub step_m: f64,
    pub nx: usize,
    pub ny: usize,
}

impl FieldGrid {
    /// The grid covering `area_m` at `step_m` (the last point at or beyond the far edge).
    pub fn covering(area_m: Bounds2, step_m: f64) -> FieldGrid {
        let n = |span: f64| ((span / step_m - 1e-9).ceil().max(1.0) as usize) + 1;
        FieldGrid {
            x0_m: area_m.min_m.x,
            y0_m: area_m.min_m.y,
            step_m,
            nx: n(area_m.max_m.x - area_m.min_m.x),
            ny: n(area_m.max_m.y - area_m.min_m.y),
        }
    }

    pub fn points(&self) -> usize {
        self.nx * self.ny
    }

    /// The four grid points around `(x_m, y_m)` (clamped to the grid) with their bilinear
    /// weights.
    fn corners(&self, x_m: f64, y_m: f64) -> [(usize, f64); 4] {
        let fx = ((x_m - self.x0_m) / self.step_m).clamp(0.0, (self.nx - 1) as f64);
        let fy = ((y_m - self.y0_m) / self.step_m).clamp(0.0, (self.ny - 1) as f64);
        let (ix, iy) = (
            (fx as usize).min(self.nx - 1),
            (fy as usize).min(self.ny - 1),
        );
        let (ix1, iy1) = ((ix + 1).min(self.nx - 1), (iy + 1).min(self.ny - 1));
        let (tx, ty) = (fx - ix as f64, fy - iy as f64);
        [
            (iy * self.nx + ix, (1.0 - tx) * (1.0 - ty)),
            (iy * self.nx + ix1, tx * (1.0 - ty)),
            (iy1 * self.nx + ix, (1.0 - tx) * ty),
            (iy1 * self.nx + ix1, tx * ty),
        ]
    }
}

/// The circulant embedding of an exponential covariance on a grid (Dietrich & Newsam 1997):
/// the covariance on the doubled periodic grid, diagonalised by the 2D DFT; its square-rooted
/// eigenvalues shape white noise into fields with exactly that covariance on the grid.
struct Embedding {
    mx: usize,
    my: usize,
    /// √(λ_k / (mx·my)) in the transposed layout `kx·my + ky` (negative λ, from the periodic
    /// wrap, set to 0).
    sqrt_lambda: Vec<f64>,
    fft_x: Arc<dyn Fft<f64>>,
    fft_y: Arc<dyn Fft<f64>>,
}

impl Embedding {
    fn new(grid: &FieldGrid, d_corr_m: f64) -> Embedding {
        let (mx, my) = (2 * grid.nx, 2 * grid.ny);
        let mut planner = FftPlanner::new();
        let (fft_x, fft_y) = (planner.plan_fft_forward(mx), planner.plan_fft_forward(my));
        let mut c = vec![Complex::new(0.0, 0.0); mx * my];
        for iy in 0..my {
            let dy = iy.min(my - iy) as f64 * grid.step_m;
            for ix in 0..mx {
                let dx = ix.min(mx - ix) as f64 * grid.step_m;
                c[iy * mx + ix].re = (-dx.hypot(dy) / d_corr_m).exp();
            }
        }
        let lambda = fft2(&c, mx, my, fft_x.as_ref(), fft_y.as_ref());
        let n = (mx * my) as f64;
        let sqrt_lambda = lambda.iter().map(|l| (l.re.max(0.0) / n).sqrt()).collect();
        Embedding {
            mx,
            my,
            sqrt_lambda,
            fft_x,
            fft_y,
        }
    }

    /// Two independent unit-variance fields on the grid's first `nx × ny` points (row-major,
    /// `iy·nx + ix`): the real and imaginary parts of one shaped complex noise.
    fn draw_pair(&self, grid: &FieldGrid, rng: &mut ChaCha8Rng) -> [Vec<f32>; 2] {
        // The noise lives in the transposed layout of `sqrt_lambda`.
        let noise: Vec<Complex<f64>> = self
            .sqrt_lambda
            .iter()
            .map(|s| {
                let (a, b): (f64, f64) = (StandardNormal.sample(rng), StandardNormal.sample(rng));
                Complex::new(s * a, s * b)
            })
            .collect();
        // Rows of length my first, then of length mx: the output is in the layout iy·mx + ix.
        let z = fft2(
            &noise,
            self.my,
            self.mx,
            self.fft_y.as_ref(),
            self.fft_x.as_ref(),
        );
        let mut out = [
            Vec::with_capacity(grid.points()),
            Vec::with_capacity(grid.points()),
        ];
        for iy in 0..grid.ny {
            for ix in 0..grid.nx {
                let v = z[iy * self.mx + ix];
                out[0].push(v.re as f32);
                out[1].push(v.im as f32);
            }
        }
        out
    }
}

/// The 2D DFT of `a` (rows of length `n_row`, `n_col` rows) returned transposed (rows of length
/// `n_col`).
fn fft2(
    a: &[Complex<f64>],
    n_row: usize,
    n_col: usize,
    fft_row: &dyn Fft<f64>,
    fft_col: &dyn Fft<f64>,
) -> Vec<Complex<f64>> {
    let mut rows = a.to_vec();
    fft_row.process(&mut rows);
    let mut t = vec![Complex::new(0.0, 0.0); rows.len()];
    for r in 0..n_col {
        for c in 0..n_row {
            t[c * n_col + r] = rows[r * n_row + c];
        }
    }
    fft_col.process(&mut t);
    t
}

/// Which stream a realisation's noise comes from: (field seed, domain, realisation index) form
/// the ChaCha8 key and the (scenario, LoS) group the stream, so realisations and groups never
/// share numbers and a realisation does not depend on how many others exist.
fn stream(seed: u64, domain: u64, index: u32, group: u64) -> ChaCha8Rng {
    let mut key = [0u8; 32];
    key[..8].copy_from_slice(&seed.to_le_bytes());
    key[8..16].copy_from_slice(&domain.to_le_bytes());
    key[16..20].copy_from_slice(&index.to_le_bytes());
    let mut rng = ChaCha8Rng::from_seed(key);
    rng.set_stream(group);
    rng
}

/// The variance of Σ w_i·Z_i for the bilinear weights `w` of [`FieldGrid::corners`] (corner
/// order (ix, iy), (ix+1, iy), (ix, iy+1), (ix+1, iy+1)) of a unit field whose correlation is
/// `rho_side` between neighbours along an axis and `rho_diagonal` across the cell.
fn bilinear_variance(w: [f64; 4], rho_side: f64, rho_diagonal: f64) -> f64 {
    let [a, b, c, d] = w;
    a * a
        + b * b
        + c * c
        + d * d
        + 2.0 * rho_side * (a * b + c * d + a * c + b * d)
        + 2.0 * rho_diagonal * (a * d + b * c)
}

/// One realisation of every site's shadow fading over the flight area.
#[derive(Debug, Clone)]
pub struct ShadowField {
    grid: FieldGrid,
    scenarios: Vec<Scenario>,
    /// Unit-variance values, index `(iy·nx + ix)·2M + 2·site + s` with s = 0 for the LoS field
    /// and 1 for the NLoS field: the 2M values of a grid point are contiguous.
    z: Vec<f32>,
}

impl ShadowField {
    /// Realisation `index` of stream `(seed, domain)` for sites of `scenarios` on `grid`, with
    /// correlation `inter_site_rho` ∈ [0, 1) between sites of one scenario (0: independent; the
    /// sites' own fields are the same for every ρ, the shared one is drawn after them).
    pub fn generate(
        grid: FieldGrid,
        scenarios: &[Scenario],
        seed: u64,
        domain: u64,
        index: u32,
        inter_site_rho: f64,
    ) -> ShadowField {
        let m = scenarios.len();
        let mut z = vec![0f32; grid.points() * 2 * m];
        let groups = [
            (Scenario::Uma, true),
            (Scenario::Uma, false),
            (Scenario::Umi, true),
            (Scenario::Umi, false),
        ];
        for (g, &(scenario, los)) in groups.iter().enumerate() {
            let slots: Vec<usize> = (0..m)
                .filter(|&s| scenarios[s] == scenario)
                .map(|s| 2 * s + usize::from(!los))
                .collect();
            if slots.is_empty() {
                continue;
            }
            let emb = Embedding::new(&grid, decorrelation_m(scenario, los));
            let mut rng = stream(seed, domain, index, g as u64);
            for chunk in slots.chunks(2) {
                let fields = emb.draw_pair(&grid, &mut rng);
                for (slot, field) in chunk.iter().zip(fields) {
                    for (p, v) in field.into_iter().enumerate() {
                        z[p * 2 * m + slot] = v;
                    }
                }
            }
            if inter_site_rho > 0.0 {
                let [shared, _] = emb.draw_pair(&grid, &mut rng);
                let (c, o) = (inter_site_rho.sqrt(), (1.0 - inter_site_rho).sqrt());
                for (p, v) in shared.into_iter().enumerate() {
                    for &slot in &slots {
                        let at = p * 2 * m + slot;
                        z[at] = (c * f64::from(v) + o * f64::from(z[at])) as f32;
                    }
                }
            }
        }
        ShadowField {
            grid,
            scenarios: scenarios.to_vec(),
            z,
        }
    }

    pub fn grid(&self) -> &FieldGrid {
        &self.grid
    }

    pub fn num_sites(&self) -> usize {
        self.scenarios.len()
    }

    /// The unit-variance value of `site`'s LoS (`los`) or NLoS field at grid point `(ix, iy)`.
    pub fn unit_at_grid(&self, site: usize, los: bool, ix: usize, iy: usize) -> f32 {
        let m = self.scenarios.len();
        self.z[(iy * self.grid.nx + ix) * 2 * m + 2 * site + usize::from(!los)]
    }

    /// Every site's shadow fading (dB, ≥ 0 is a loss) at `p_m`, into `out[0..M]`, given each
    /// site's line of sight there (`los[i]` ∈ [0, 1]: 1 LoS, 0 NLoS, between where the RSRP
    /// source interpolates it): σ_LoS·Z_LoS·los + σ_NLoS·Z_NLoS·(1 − los), Z bilinear and
    /// rescaled to unit variance (module doc).
    pub fn shadow_db(&self, p_m: Point, los: &[f64], out: &mut [f64]) {
        let m = self.scenarios.len();
        let corners = self.grid.corners(p_m[0], p_m[1]);
        let w = corners.map(|(_, w)| w);
        // 1/σ of the bilinear mix per (scenario, LoS state): exp(−d/d_corr) at the cell's side
        // and diagonal.
        let h_step = self.grid.step_m;
        let rescale = |sc: Scenario, los: bool| {
            let d = decorrelation_m(sc, los);
            let v = bilinear_variance(
                w,
                (-h_step / d).exp(),
                (-h_step * std::f64::consts::SQRT_2 / d).exp(),
            );
            1.0 / v.max(1e-12).sqrt()
        };
        let k = [Scenario::Uma, Scenario::Umi].map(|sc| [rescale(sc, true), rescale(sc, false)]);
        let h = p_m[2];
        for (s, o) in out.iter_mut().enumerate().take(m) {
            let (mut zl, mut zn) = (0.0f64, 0.0f64);
            for &(i, w) in &corners {
                zl += w * f64::from(self.z[i * 2 * m + 2 * s]);
                zn += w * f64::from(self.z[i * 2 * m + 2 * s + 1]);
            }
            let l = los[s].clamp(0.0, 1.0);
            let sc = self.scenarios[s];
            let [kl, kn] = k[usize::from(sc == Scenario::Umi)];
            *o = l * sigma_sf_db(sc, true, h) * kl * zl
                + (1.0 - l) * sigma_sf_db(sc, false, h) * kn * zn;
        }
    }

    /// Applies the shadow fading at `p_m` to every site's RSRP (dBm) in `rsrp_dbm`, given each
    /// link's line of sight `los` ([`ShadowField::shadow_db`]); `scratch_db` holds the M values.
    pub fn apply(&self, p_m: Point, los: &[f64], rsrp_dbm: &mut [f64], scratch_db: &mut [f64]) {
        self.shadow_db(p_m, los, scratch_db);
        for (r, s) in rsrp_dbm.iter_mut().zip(scratch_db.iter()) {
            *r -= s;
        }
    }
}
