//! Coverage maps: best-server RSRP on horizontal slices (paper Fig. 2(b)).

use dupac_common::geometry::{Bounds2, Point};
use dupac_common::ids::SiteId;

/// One horizontal slice of the best-server map. Cell `(ix, iy)` has its centre at
/// `(x0_m + (ix + 0.5)·resolution_m, y0_m + (iy + 0.5)·resolution_m)`; arrays are row-major with
/// `iy` as the row (`i = iy·nx + ix`), rows from south (iy = 0) to north.
#[derive(Debug, Clone)]
pub struct CoverageSlice {
    /// Slice altitude above ground (m).
    pub altitude_m: f64,
    /// South-west corner of the grid (m).
    pub x0_m: f64,
    pub y0_m: f64,
    pub resolution_m: f64,
    pub nx: usize,
    pub ny: usize,
    /// Best-server RSRP (dBm); NaN where the cell centre is inside a building.
    pub rsrp_dbm: Vec<f32>,
    /// Serving (best) site; `None` inside buildings.
    pub serving: Vec<Option<SiteId>>,
    /// Whether the serving link is line of sight.
    pub los: Vec<bool>,
}

use crate::shadow::ShadowField;
use crate::world::RadioWorld;
use rayon::prelude::*;
use serde::Serialize;
use std::io::Write;

impl CoverageSlice {
    /// Centre of cell `(ix, iy)` (m).
    pub fn cell_centre_m(&self, ix: usize, iy: usize) -> [f64; 2] {
        [
            self.x0_m + (ix as f64 + 0.5) * self.resolution_m,
            self.y0_m + (iy as f64 + 0.5) * self.resolution_m,
        ]
    }
}

/// Which RSRP a slice shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Server {
    /// The strongest site at each cell (paper Fig. 2(b)).
    Best,
    /// One site everywhere: shows its shadows, back lobes and the antenna-null rings of
    /// spec/radio.md §2 that the best server hides.
    Site(SiteId),
}

/// Computes the slice at `altitude_m` over the flight area `area_m` with square
/// cells of `resolution_m`, rows in parallel (rayon), with the shadow fading of `shadow` when
/// given (the real channel, docs/env.md "Channel"). `progress(rows_done)` is called once per
/// finished row.
pub fn compute_slice(
    world: &RadioWorld,
    server: Server,
    shadow: Option<&ShadowField>,
    area_m: Bounds2,
    altitude_m: f64,
    resolution_m: f64,
    progress: &(dyn Fn(u64) + Sync),
) -> CoverageSlice {
    let nx = ((area_m.max_m.x - area_m.min_m.x) / resolution_m)
        .floor()
        .max(1.0) as usize;
    let ny = ((area_m.max_m.y - area_m.min_m.y) / resolution_m)
        .floor()
        .max(1.0) as usize;
    let mut slice = CoverageSlice {
        altitude_m,
        x0_m: area_m.min_m.x,
        y0_m: area_m.min_m.y,
        resolution_m,
        nx,
        ny,
        rsrp_dbm: vec![f32::NAN; nx * ny],
        serving: vec![None; nx * ny],
        los: vec![false; nx * ny],
    };
    let rows: Vec<Vec<(f32, Option<SiteId>, bool)>> = (0..ny)
        .into_par_iter()
        .map(|iy| {
            let row = (0..nx)
                .map(|ix| {
                    let [x, y] = slice.cell_centre_m(ix, iy);
                    let p = Point::new(x, y, altitude_m);
                    if world.city.is_inside_building(p) {
                        (f32::NAN, None, false)
                    } else {
                        let (id, rsrp, los) = match (server, shadow) {
                            (Server::Best, None) => world.best_server(p),
                            (Server::Site(id), None) => {
                                (id, world.rsrp_dbm(id, p), world.los(id, p))
                            }
                            (server, Some(f)) => {
                                let m = world.num_sites();
                                let (mut r, mut l) = (vec![0.0; m], vec![false; m]);
                                world.rsrp_all_shadowed(p, f, &mut r, &mut l);
                                let k = match server {
                                    Server::Best => r
                                        .iter()
                                        .enumerate()
                                        .fold(0, |b, (i, v)| if *v > r[b] { i } else { b }),
                                    Server::Site(id) => id.index(),
                                };
                                (SiteId(k as u16), r[k], l[k])
                            }
                        };
                        (rsrp as f32, Some(id), los)
                    }
                })
                .collect();
            progress(1);
            row
        })
        .collect();
    for (iy, row) in rows.into_iter().enumerate() {
        for (ix, (r, s, l)) in row.into_iter().enumerate() {
            let i = iy * nx + ix;
            slice.rsrp_dbm[i] = r;
            slice.serving[i] = s;
            slice.los[i] = l;
        }
    }
    slice
}

/// Summary of one slice over the cells outside buildings.
#[derive(Debug, Clone, Serialize)]
pub struct SliceSummary {
    pub altitude_m: f64,
    /// Cells outside buildings.
    pub cells: usize,
    pub mean_rsrp_dbm: f64,
    pub median_rsrp_dbm: f64,
    pub p10_rsrp_dbm: f64,
    pub p90_rsrp_dbm: f64,
    pub excellent_pct: f64,
    pub mediocre_pct: f64,
    pub poor_pct: f64,
    /// Share of cells whose best server is not in line of sight (%).
    pub nlos_pct: f64,
    /// Share of the area inside buildings at this altitude (%).
    pub inside_buildings_pct: f64,
}

/// Summarises a slice with the radio thresholds of `world`.
pub fn summarise(world: &RadioWorld, slice: &CoverageSlice) -> SliceSummary {
    let mut vals: Vec<f64> = Vec::with_capacity(slice.rsrp_dbm.len());
    let mut counts = [0usize; 3];
    let mut nlos = 0usize;
    for (i, r) in slice.rsrp_dbm.iter().enumerate() {
        if r.is_nan() {
            continue;
        }
        let r = f64::from(*r);
        vals.push(r);
        counts[world.link.thresholds.classify(r).index()] += 1;
        if !slice.los[i] {
            nlos += 1;
        }
    }
    let n = vals.len();
    vals.sort_by(f64::total_cmp);
    let pct = |k: usize| {
        if n == 0 {
            f64::NAN
        } else {
            100.0 * k as f64 / n as f64
        }
    };
    let quantile = |q: f64| {
        if n == 0 {
            f64::NAN
        } else {
            vals[((q * (n - 1) as f64).round() as usize).min(n - 1)]
        }
    };
    SliceSummary {
        altitude_m: slice.altitude_m,
        cells: n,
        mean_rsrp_dbm: if n == 0 {
            f64::NAN
        } else {
            vals.iter().sum::<f64>() / n as f64
        },
        median_rsrp_dbm: quantile(0.5),
        p10_rsrp_dbm: quantile(0.1),
        p90_rsrp_dbm: quantile(0.9),
        excellent_pct: pct(counts[0]),
        mediocre_pct: pct(counts[1]),
        poor_pct: pct(counts[2]),
        nlos_pct: pct(nlos),
        inside_buildings_pct: 100.0 * (slice.rsrp_dbm.len() - n) as f64
            / slice.rsrp_dbm.len().max(1) as f64,
    }
}

/// Writes the slice as CSV, one row per cell: `ix,iy,x_m,y_m,rsrp_dbm,serving,los`
/// (`rsrp_dbm` and `serving` empty inside buildings). The documented raw format of `dupac map`.
pub fn write_slice_csv(slice: &CoverageSlice, out: &mut dyn std::io::Write) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(out);
    writeln!(w, "ix,iy,x_m,y_m,rsrp_dbm,serving,los")?;
    for iy in 0..slice.ny {
        for ix in 0..slice.nx {
            let i = iy * slice.nx + ix;
            let [x, y] = slice.cell_centre_m(ix, iy);
            match slice.serving[i] {
                Some(s) => writeln!(
                    w,
                    "{ix},{iy},{x:.2},{y:.2},{:.3},{},{}",
                    slice.rsrp_dbm[i],
                    s.0,
                    u8::from(slice.los[i])
                )?,
                None => writeln!(w, "{ix},{iy},{x:.2},{y:.2},,,")?,
            }
        }
    }
    w.flush()
}
