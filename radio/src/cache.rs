//! The per-site RSRP cache: a precomputed 3D grid of every site's RSRP over the flight area and
//! altitude band, saved once, memory-mapped by every process, and queried by trilinear
//! interpolation. [`RadioWorld`] is the exact mode (a ray cast per query) it is
//! validated against; both implement [`crate::source::RsrpSource`].
//!
//! File format (little-endian):
//! ```text
//! bytes 0..8    magic "DUPACRC\x01"
//! bytes 8..12   u32 header length H (bytes of JSON)
//! bytes 12..12+H  JSON [`CacheHeader`] (format version, world fingerprint, grid)
//! zero padding to the next multiple of 64 bytes
//! f32 RSRP (dBm) values, index ((iy·nx + ix)·nz + iz)·M + site
//! zero padding to the next multiple of 64 bytes
//! line of sight: ⌈M / 8⌉ bytes per grid point in the same point order, bit (site mod 8) of
//! byte (site / 8) set when the site sees the point (spec/radio.md D9)
//! ```
//! The layout keeps the M values of one grid point contiguous, so an all-site query reads
//! 8 runs of M floats. The line of sight is stored so that it can be observed at the cost of a
//! lookup ([`RsrpSource::los_all`]) instead of a ray cast per site and step. A header whose fingerprint differs from the world's marks the cache
//! stale; [`RsrpCache::open_or_build`] then rebuilds it (written to a temporary file, then
//! renamed, so a reader never sees a half-written cache).

use crate::error::RadioError;
use crate::source::RsrpSource;
use crate::world::RadioWorld;
use dupac_common::config::CacheConfig;
use dupac_common::geometry::{Bounds2, Point};
use dupac_common::ids::SiteId;
use memmap2::Mmap;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// File magic of the cache format.
pub const CACHE_MAGIC: &[u8; 8] = b"DUPACRC\x01";
/// Version of [`CacheHeader`] and the data layout (2: with the line-of-sight block).
pub const CACHE_FORMAT_VERSION: u32 = 2;
/// Alignment of the data block (bytes).
const DATA_ALIGN: usize = 64;

/// Largest RSRP cache built (bytes): 16 GiB, 4 × Manhattan at 2 m.
pub const MAX_CACHE_BYTES: usize = 16 << 30;

/// Regular 3D grid of sample points (grid points, not cells: point `i` is at `x0_m + i·dx_m`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GridSpec {
    pub x0_m: f64,
    pub y0_m: f64,
    pub z0_m: f64,
    /// Horizontal step (m).
    pub dxy_m: f64,
    /// Vertical step (m).
    pub dz_m: f64,
    pub nx: usize,
    pub ny: usize,
    pub nz: usize,
}

impl GridSpec {
    /// Grid covering `area_m` and `[z_min_m, z_max_m]` at the configured steps (the last point is
    /// at or beyond the far edge).
    pub fn covering(area_m: Bounds2, cfg: &CacheConfig) -> GridSpec {
        // `as` saturates: a degenerate step gives a huge count, refused by `check_size`.
        let n = |span: f64, step: f64| {
            ((span / step - 1e-9).ceil().max(1.0) as usize).saturating_add(1)
        };
        GridSpec {
            x0_m: area_m.min_m.x,
            y0_m: area_m.min_m.y,
            z0_m: cfg.z_min_m,
            dxy_m: cfg.horizontal_m,
            dz_m: cfg.vertical_m,
            nx: n(area_m.max_m.x - area_m.min_m.x, cfg.horizontal_m),
            ny: n(area_m.max_m.y - area_m.min_m.y, cfg.horizontal_m),
            nz: n(cfg.z_max_m - cfg.z_min_m, cfg.vertical_m),
        }
    }

    /// Number of grid points (saturating).
    pub fn points(&self) -> usize {
        self.nx.saturating_mul(self.ny).saturating_mul(self.nz)
    }

    /// Bytes of a cache of this grid for `n_sites` sites (saturating): the RSRP block, its
    /// padding and the line-of-sight block.
    pub fn bytes(&self, n_sites: usize) -> usize {
        self.rsrp_bytes(n_sites)
            .saturating_add(DATA_ALIGN)
            .saturating_add(self.points().saturating_mul(los_bytes_per_point(n_sites)))
    }

    /// Bytes of the RSRP block (saturating).
    fn rsrp_bytes(&self, n_sites: usize) -> usize {
        self.points()
            .saturating_mul(n_sites)
            .saturating_mul(size_of::<f32>())
    }

    /// Position of grid point `(ix, iy, iz)` (m).
    pub fn point_m(&self, ix: usize, iy: usize, iz: usize) -> Point {
        Point::new(
            self.x0_m + ix as f64 * self.dxy_m,
            self.y0_m + iy as f64 * self.dxy_m,
            self.z0_m + iz as f64 * self.dz_m,
        )
    }
}

/// What the cache file says about itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CacheHeader {
    pub format_version: u32,
    pub scenario: String,
    /// [`RadioWorld::fingerprint`] in hex: city, sites and RSRP-relevant radio parameters.
    pub world_fingerprint: String,
    pub n_sites: usize,
    pub grid: GridSpec,
    /// Human-readable layout note.
    pub layout: String,
}

/// Bytes of line-of-sight bits per grid point for `n_sites` sites.
pub fn los_bytes_per_point(n_sites: usize) -> usize {
    n_sites.div_ceil(8)
}

/// Offset of the line-of-sight block after an RSRP block of `rsrp_bytes` starting at the aligned
/// `data_offset`.
fn los_offset(data_offset: usize, rsrp_bytes: usize) -> usize {
    (data_offset + rsrp_bytes).div_ceil(DATA_ALIGN) * DATA_ALIGN
}

enum Storage {
    Mapped(Mmap),
    /// Built in memory, not yet saved (boxed: the mapped case is the common one).
    Owned(Box<(Vec<f32>, Vec<u8>)>),
}

/// A loaded (memory-mapped) RSRP cache.
pub struct RsrpCache {
    header: CacheHeader,
    storage: Storage,
    data_offset: usize,
    los_offset: usize,
    path: Option<PathBuf>,
}

impl std::fmt::Debug for RsrpCache {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RsrpCache")
            .field("header", &self.header)
            .field("path", &self.path)
            .finish()
    }
}

/// Result of [`RsrpCache::open`].
pub enum Opened {
    Valid(RsrpCache),
    /// The file exists but was built for another world or grid (reason given).
    Stale(String),
    Missing,
}

impl RsrpCache {
    /// The header expected for `world` on `grid`.
    pub fn expected_header(world: &RadioWorld, grid: GridSpec) -> CacheHeader {
        CacheHeader {
            format_version: CACHE_FORMAT_VERSION,
            scenario: world.city.name.clone(),
            world_fingerprint: format!("{:016x}", world.fingerprint()),
            n_sites: world.num_sites(),
            grid,
            layout: "f32 little-endian RSRP dBm, index ((iy*nx + ix)*nz + iz)*n_sites + site; \
                     then line of sight, ceil(n_sites/8) bytes per point, bit site%8 of byte site/8"
                .into(),
        }
    }

    /// Computes the cache in memory (exact mode at every grid point), rows in parallel;
    /// `progress(rows_done)` is called once per finished row of `nx·nz` points.
    pub fn build(world: &RadioWorld, grid: GridSpec, progress: &(dyn Fn(u64) + Sync)) -> RsrpCache {
        let m = world.num_sites();
        let lb = los_bytes_per_point(m);
        let row_points = grid.nx * grid.nz;
        let mut rsrp = vec![0f32; grid.points() * m];
        let mut los = vec![0u8; grid.points() * lb];
        rsrp.par_chunks_mut(row_points * m)
            .zip(los.par_chunks_mut(row_points * lb))
            .enumerate()
            .for_each(|(iy, (row, los_row))| {
                for ix in 0..grid.nx {
                    for iz in 0..grid.nz {
                        let p = grid.point_m(ix, iy, iz);
                        let at = ix * grid.nz + iz;
                        let bits = &mut los_row[at * lb..(at + 1) * lb];
                        for (s, o) in row[at * m..(at + 1) * m].iter_mut().enumerate() {
                            let (rsrp_dbm, site_los) = world.rsrp_los(SiteId(s as u16), p);
                            *o = rsrp_dbm as f32;
                            bits[s / 8] |= u8::from(site_los) << (s % 8);
                        }
                    }
                }
                progress(1);
            });
        RsrpCache {
            header: Self::expected_header(world, grid),
            storage: Storage::Owned(Box::new((rsrp, los))),
            data_offset: 0,
            los_offset: 0,
            path: None,
        }
    }

    /// Writes the cache to `path` atomically ([`dupac_common::fsio`]); temporary files of
    /// interrupted writes older than an hour are swept first (another process may be writing
    /// one now: the cache directory can be shared).
    pub fn save(&self, path: &Path) -> Result<(), RadioError> {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            let _ =
                dupac_common::fsio::sweep_temporaries(dir, std::time::Duration::from_secs(3600));
        }
        let header = serde_json::to_vec(&self.header).map_err(|e| RadioError::Cache {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        dupac_common::fsio::write_atomic_with(path, |w| {
            w.write_all(CACHE_MAGIC)?;
            w.write_all(&(header.len() as u32).to_le_bytes())?;
            w.write_all(&header)?;
            let used = CACHE_MAGIC.len() + 4 + header.len();
            let pad = (DATA_ALIGN - used % DATA_ALIGN) % DATA_ALIGN;
            w.write_all(&vec![0u8; pad])?;
            for chunk in self.values().chunks(1 << 16) {
                let mut bytes = Vec::with_capacity(chunk.len() * 4);
                for v in chunk {
                    bytes.extend_from_slice(&v.to_le_bytes());
                }
                w.write_all(&bytes)?;
            }
            let used = used + pad + self.values().len() * 4;
            w.write_all(&vec![0u8; (DATA_ALIGN - used % DATA_ALIGN) % DATA_ALIGN])?;
            w.write_all(self.los_bits())?;
            Ok(())
        })
        .map_err(|e| RadioError::io(path, std::io::Error::other(e.to_string())))
    }

    /// Opens `path` and checks it against `expected`.
    pub fn open(path: &Path, expected: &CacheHeader) -> Result<Opened, RadioError> {
        let bad = |message: String| RadioError::Cache {
            path: path.to_path_buf(),
            message,
        };
        if path.is_dir() {
            return Err(bad(
                "is a directory; cache.path names the cache file (e.g. data/cache/rsrp.bin)".into(),
            ));
        }
        let file = match std::fs::File::open(path) {
            Ok(f) => f,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Opened::Missing),
            Err(e) => return Err(RadioError::io(path, e)),
        };
        // SAFETY: the file is only ever replaced by rename (never written in place), so the
        // mapping's contents do not change under us.
        let mmap = unsafe { Mmap::map(&file) }.map_err(|e| RadioError::io(path, e))?;
        if mmap.len() < 12 || &mmap[..8] != CACHE_MAGIC {
            return Ok(Opened::Stale("not a DUPAC RSRP cache (bad magic)".into()));
        }
        let hlen = u32::from_le_bytes([mmap[8], mmap[9], mmap[10], mmap[11]]) as usize;
        if 12 + hlen > mmap.len() {
            return Err(bad(format!("header length {hlen} exceeds the file")));
        }
        let header: CacheHeader = match serde_json::from_slice(&mmap[12..12 + hlen]) {
            Ok(h) => h,
            Err(e) => return Ok(Opened::Stale(format!("unreadable header: {e}"))),
        };
        if header != *expected {
            let reason = if header.world_fingerprint != expected.world_fingerprint {
                "built for another city, site list or radio configuration"
            } else if header.grid != expected.grid {
                "built on another grid"
            } else {
                "header differs"
            };
            return Ok(Opened::Stale(reason.into()));
        }
        let data_offset = (12 + hlen).div_ceil(DATA_ALIGN) * DATA_ALIGN;
        let los_offset = los_offset(data_offset, header.grid.rsrp_bytes(header.n_sites));
        let want = los_offset + header.grid.points() * los_bytes_per_point(header.n_sites);
        if mmap.len() != want {
            return Err(bad(format!(
                "truncated or oversized: {} bytes, expected {want}",
                mmap.len(),
            )));
        }
        if cfg!(target_endian = "big") {
            return Err(bad("little-endian cache on a big-endian machine".into()));
        }
        bytemuck::try_cast_slice::<u8, f32>(&mmap[data_offset..los_offset])
            .map_err(|e| bad(format!("data block not 4-byte aligned: {e}")))?;
        Ok(Opened::Valid(RsrpCache {
            header,
            storage: Storage::Mapped(mmap),
            data_offset,
            los_offset,
            path: Some(path.to_path_buf()),
        }))
    }

    /// Opens the cache at `cfg.path` if it matches `world`, else builds it, saves it and maps it.
    /// Returns the cache and whether it was (re)built.
    pub fn open_or_build(
        world: &RadioWorld,
        cfg: &CacheConfig,
        progress: &(dyn Fn(u64) + Sync),
    ) -> Result<(RsrpCache, bool), RadioError> {
        let grid = GridSpec::covering(world.city.area_m, cfg);
        let bytes = grid.bytes(world.sites.len());
        if bytes > MAX_CACHE_BYTES {
            return Err(RadioError::Cache {
                path: cfg.path.clone(),
                message: format!(
                    "a {} × {} × {} grid for {} sites is {:.1} GiB, over the {} GiB limit: raise cache.horizontal_m or cache.vertical_m",
                    grid.nx,
                    grid.ny,
                    grid.nz,
                    world.sites.len(),
                    bytes as f64 / (1u64 << 30) as f64,
                    MAX_CACHE_BYTES >> 30
                ),
            });
        }
        let expected = Self::expected_header(world, grid);
        match Self::open(&cfg.path, &expected)? {
            Opened::Valid(c) => return Ok((c, false)),
            Opened::Stale(reason) => {
                tracing::warn!(path = %cfg.path.display(), %reason, "RSRP cache is stale, rebuilding")
            }
            Opened::Missing => {
                tracing::info!(path = %cfg.path.display(), "no RSRP cache yet, building")
            }
        }
        let built = Self::build(world, grid, progress);
        built.save(&cfg.path)?;
        match Self::open(&cfg.path, &expected)? {
            Opened::Valid(c) => Ok((c, true)),
            _ => Err(RadioError::Cache {
                path: cfg.path.clone(),
                message: "cache just written does not read back".into(),
            }),
        }
    }

    pub fn header(&self) -> &CacheHeader {
        &self.header
    }

    pub fn grid(&self) -> &GridSpec {
        &self.header.grid
    }

    /// All values (f32 dBm) in file order.
    pub fn values(&self) -> &[f32] {
        match &self.storage {
            Storage::Owned(o) => &o.0,
            // Alignment and length were checked in `open`.
            Storage::Mapped(m) => bytemuck::cast_slice(
                &m[self.data_offset
                    ..self.data_offset + self.header.grid.rsrp_bytes(self.header.n_sites)],
            ),
        }
    }

    /// The line-of-sight bits in file order (⌈M / 8⌉ bytes per grid point).
    fn los_bits(&self) -> &[u8] {
        match &self.storage {
            Storage::Owned(o) => &o.1,
            Storage::Mapped(m) => &m[self.los_offset..],
        }
    }

    /// Cell corner and weights of `p_m` along one axis: (index, fraction), clamped to the grid.
    #[inline(always)]
    fn axis(v: f64, v0: f64, step: f64, n: usize) -> (usize, f64) {
        if n < 2 {
            return (0, 0.0);
        }
        let f = ((v - v0) / step).clamp(0.0, (n - 1) as f64);
        let i = (f as usize).min(n - 2);
        (i, f - i as f64)
    }

    /// Trilinear interpolation of site `site`'s RSRP (dBm) at `p_m` (clamped to the grid).
    pub fn rsrp_dbm(&self, site: SiteId, p_m: Point) -> f64 {
        let g = &self.header.grid;
        let m = self.header.n_sites;
        let v = self.values();
        let (ix, tx) = Self::axis(p_m[0], g.x0_m, g.dxy_m, g.nx);
        let (iy, ty) = Self::axis(p_m[1], g.y0_m, g.dxy_m, g.ny);
        let (iz, tz) = Self::axis(p_m[2], g.z0_m, g.dz_m, g.nz);
        let s = site.index();
        let mut acc = 0.0;
        for (cy, wy) in [(iy, 1.0 - ty), ((iy + 1).min(g.ny - 1), ty)] {
            for (cx, wx) in [(ix, 1.0 - tx), ((ix + 1).min(g.nx - 1), tx)] {
                let base = (cy * g.nx + cx) * g.nz;
                for (cz, wz) in [(iz, 1.0 - tz), ((iz + 1).min(g.nz - 1), tz)] {
                    acc += wx * wy * wz * f64::from(v[(base + cz) * m + s]);
                }
            }
        }
        acc
    }

    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The 4 grid columns around `p_m` (clamped to the grid): the index of each column's first
    /// point (`(iy·nx + ix)·nz`) with its horizontal weight, and the two heights between which
    /// `p_m` lies with the upper one's weight `(iz, iz + 1, tz)`.
    #[inline(always)]
    fn columns(&self, p_m: Point) -> ([(usize, f64); 4], (usize, usize, f64)) {
        let g = &self.header.grid;
        let (ix, tx) = Self::axis(p_m[0], g.x0_m, g.dxy_m, g.nx);
        let (iy, ty) = Self::axis(p_m[1], g.y0_m, g.dxy_m, g.ny);
        let (iz, tz) = Self::axis(p_m[2], g.z0_m, g.dz_m, g.nz);
        let (iy1, ix1) = ((iy + 1).min(g.ny - 1), (ix + 1).min(g.nx - 1));
        let base = |cy: usize, cx: usize| (cy * g.nx + cx) * g.nz;
        (
            [
                (base(iy, ix), (1.0 - tx) * (1.0 - ty)),
                (base(iy, ix1), tx * (1.0 - ty)),
                (base(iy1, ix), (1.0 - tx) * ty),
                (base(iy1, ix1), tx * ty),
            ],
            (iz, (iz + 1).min(g.nz - 1), tz),
        )
    }
}

impl RsrpSource for RsrpCache {
    fn num_sites(&self) -> usize {
        self.header.n_sites
    }

    /// Trilinear interpolation of all sites at once (positions outside the grid are clamped).
    fn rsrp_all_dbm(&self, p_m: Point, out: &mut [f64]) {
        let m = self.header.n_sites;
        let v = self.values();
        let (columns, (iz, iz1, tz)) = self.columns(p_m);
        let out = &mut out[..m];
        out.fill(0.0);
        for (base, wxy) in columns {
            let w0 = (wxy * (1.0 - tz)) as f32;
            let w1 = (wxy * tz) as f32;
            let a = &v[(base + iz) * m..(base + iz) * m + m];
            let b = &v[(base + iz1) * m..(base + iz1) * m + m];
            for ((o, va), vb) in out.iter_mut().zip(a).zip(b) {
                *o += f64::from(w0 * va + w1 * vb);
            }
        }
    }

    /// The grid's line of sight (1 or 0 at each grid point) interpolated trilinearly like the
    /// RSRP: 1 or 0 where all 8 surrounding grid points agree, the weight of those that see the
    /// site otherwise.
    fn los_all(&self, p_m: Point, out: &mut [f64]) -> bool {
        let m = self.header.n_sites;
        let lb = los_bytes_per_point(m);
        let bits = self.los_bits();
        let (columns, (iz, iz1, tz)) = self.columns(p_m);
        let out = &mut out[..m];
        out.fill(0.0);
        for (base, wxy) in columns {
            for (cz, wz) in [(iz, 1.0 - tz), (iz1, tz)] {
                let w = wxy * wz;
                let b = &bits[(base + cz) * lb..(base + cz + 1) * lb];
                for (s, o) in out.iter_mut().enumerate() {
                    if b[s / 8] >> (s % 8) & 1 == 1 {
                        *o += w;
                    }
                }
            }
        }
        true
    }
}
