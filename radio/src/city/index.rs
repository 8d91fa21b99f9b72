//! A uniform 2D bucket grid over building footprints: which buildings contain a point `(x, y)`.
//! Used for point-in-building tests (coverage maps, samplers) and rooftop heights (site mounting).

use super::building::Building;

/// Bucket side (m). Midtown footprints have a median of ≈ 390 m², so a 25 m bucket holds a few.
const BUCKET_M: f64 = 25.0;

/// Bucket grid of building indices by footprint bounding box.
#[derive(Debug, Clone)]
pub struct FootprintIndex {
    x0_m: f64,
    y0_m: f64,
    nx: usize,
    ny: usize,
    buckets: Vec<Vec<u32>>,
}

impl FootprintIndex {
    pub fn build(buildings: &[Building]) -> FootprintIndex {
        let mut lo = [f64::INFINITY; 2];
        let mut hi = [f64::NEG_INFINITY; 2];
        for b in buildings {
            let bb = b.bounds_m();
            lo = [lo[0].min(bb.min_m.x), lo[1].min(bb.min_m.y)];
            hi = [hi[0].max(bb.max_m.x), hi[1].max(bb.max_m.y)];
        }
        if buildings.is_empty() {
            lo = [0.0; 2];
            hi = [0.0; 2];
        }
        let nx = (((hi[0] - lo[0]) / BUCKET_M).floor() as usize + 1).max(1);
        let ny = (((hi[1] - lo[1]) / BUCKET_M).floor() as usize + 1).max(1);
        let mut idx = FootprintIndex {
            x0_m: lo[0],
            y0_m: lo[1],
            nx,
            ny,
            buckets: vec![Vec::new(); nx * ny],
        };
        for (i, b) in buildings.iter().enumerate() {
            let bb = b.bounds_m();
            let (ix0, iy0) = idx.cell(bb.min_m.x, bb.min_m.y);
            let (ix1, iy1) = idx.cell(bb.max_m.x, bb.max_m.y);
            for iy in iy0..=iy1 {
                for ix in ix0..=ix1 {
                    idx.buckets[iy * nx + ix].push(i as u32);
                }
            }
        }
        idx
    }

    fn cell(&self, x: f64, y: f64) -> (usize, usize) {
        let ix = ((x - self.x0_m) / BUCKET_M)
            .floor()
            .clamp(0.0, (self.nx - 1) as f64) as usize;
        let iy = ((y - self.y0_m) / BUCKET_M)
            .floor()
            .clamp(0.0, (self.ny - 1) as f64) as usize;
        (ix, iy)
    }

    /// Buildings whose footprint contains `(x, y)`.
    pub fn containing<'a>(
        &'a self,
        buildings: &'a [Building],
        x_m: f64,
        y_m: f64,
    ) -> impl Iterator<Item = &'a Building> + 'a {
        let outside = !(x_m.is_finite() && y_m.is_finite())
            || x_m < self.x0_m
            || y_m < self.y0_m
            || x_m > self.x0_m + self.nx as f64 * BUCKET_M
            || y_m > self.y0_m + self.ny as f64 * BUCKET_M;
        let bucket: &[u32] = if outside {
            &[]
        } else {
            let (ix, iy) = self.cell(x_m, y_m);
            &self.buckets[iy * self.nx + ix]
        };
        bucket
            .iter()
            .filter_map(move |&i| buildings.get(i as usize))
            .filter(move |b| b.contains_xy(x_m, y_m))
    }

    /// Buildings whose footprint bounding box comes within `radius_m` of `(x, y)` (candidates for
    /// a nearest-building search; the caller measures the exact distance).
    pub fn near(&self, x_m: f64, y_m: f64, radius_m: f64) -> Vec<u32> {
        let (ix0, iy0) = self.cell(x_m - radius_m, y_m - radius_m);
        let (ix1, iy1) = self.cell(x_m + radius_m, y_m + radius_m);
        let mut out = Vec::new();
        for iy in iy0..=iy1 {
            for ix in ix0..=ix1 {
                out.extend_from_slice(&self.buckets[iy * self.nx + ix]);
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}
