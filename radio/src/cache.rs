//! The per-site RSRP cache: a precomputed 3D grid of every site's RSRP over the flight area and
//! altitude band, saved once, memory-mapped by every process, and queried by trilinear
//! interpolation (issue 2). [`RadioWorld`] is the exact mode (a ray cast per query) it is
//! validated against; both implement [`RsrpSource`].
//!
//! File format (little-endian):
//! ```text
//! bytes 0..8    magic "DUPACRC\x01"
//! bytes 8..12   u32 header length H (bytes of JSON)
//! bytes 12..12+H  JSON [`CacheHeader`] (format version, world fingerprint, grid)
//! zero padding to the next multiple of 64 bytes
//! f32 RSRP (dBm) values, index ((iy·nx + ix)·nz + iz)·M + site
//! ```
//! The layout keeps the M values of one grid point contiguous, so an all-site query reads
//! 8 runs of M floats. A header whose fingerprint differs from the world's marks the cache
//! stale; [`RsrpCache::open_or_build`] then rebuilds it (written to a temporary file, then
//! renamed, so a reader never sees a half-written cache).

use crate::error::RadioError;
use crate::world::RadioWorld;
use dupac_common::SiteId;
use dupac_common::config::CacheConfig;
use dupac_common::geometry::{Bounds2, Point};
use memmap2::Mmap;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// File magic of the cache format.
pub const CACHE_MAGIC: &[u8; 8] = b"DUPACRC\x01";
/// Version of [`CacheHeader`] and the data layout.
pub const CACHE_FORMAT_VERSION: u32 = 1;
/// Alignment of the data block (bytes).
const DATA_ALIGN: usize = 64;

/// Anything that can tell the RSRP of every site at a point: exact ray casting or the cache.
pub trait RsrpSource: Sync {
    /// M, the number of sites.
    fn num_sites(&self) -> usize;
    /// RSRP (dBm) of every site at `p_m`, into `out[0..M]`.
    fn rsrp_all_dbm(&self, p_m: Point, out: &mut [f64]);
}

impl RsrpSource for RadioWorld {
    fn num_sites(&self) -> usize {
        RadioWorld::num_sites(self)
    }
    fn rsrp_all_dbm(&self, p_m: Point, out: &mut [f64]) {
        RadioWorld::rsrp_all_dbm(self, p_m, out)
    }
}

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

    /// Bytes of a cache of this grid for `n_sites` sites (saturating).
    pub fn bytes(&self, n_sites: usize) -> usize {
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

enum Storage {
    Mapped(Mmap),
    Owned(Vec<f32>),
}

/// A loaded (memory-mapped) RSRP cache.
pub struct RsrpCache {
    header: CacheHeader,
    storage: Storage,
    data_offset: usize,
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
            layout: "f32 little-endian RSRP dBm, index ((iy*nx + ix)*nz + iz)*n_sites + site"
                .into(),
        }
    }

    /// Computes the cache in memory (exact mode at every grid point), rows in parallel;
    /// `progress(rows_done)` is called once per finished row of `nx·nz` points.
    pub fn build(world: &RadioWorld, grid: GridSpec, progress: &(dyn Fn(u64) + Sync)) -> RsrpCache {
        let m = world.num_sites();
        let row_len = grid.nx * grid.nz * m;
        let mut data = vec![0f32; grid.points() * m];
        data.par_chunks_mut(row_len)
            .enumerate()
            .for_each(|(iy, row)| {
                let mut all = vec![0f64; m];
                for ix in 0..grid.nx {
                    for iz in 0..grid.nz {
                        world.rsrp_all_dbm(grid.point_m(ix, iy, iz), &mut all);
                        let at = (ix * grid.nz + iz) * m;
                        for (o, v) in row[at..at + m].iter_mut().zip(&all) {
                            *o = *v as f32;
                        }
                    }
                }
                progress(1);
            });
        RsrpCache {
            header: Self::expected_header(world, grid),
            storage: Storage::Owned(data),
            data_offset: 0,
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
        let want = header.grid.points() * header.n_sites * 4;
        if mmap.len() != data_offset + want {
            return Err(bad(format!(
                "truncated or oversized: {} bytes, expected {}",
                mmap.len(),
                data_offset + want
            )));
        }
        if cfg!(target_endian = "big") {
            return Err(bad("little-endian cache on a big-endian machine".into()));
        }
        bytemuck::try_cast_slice::<u8, f32>(&mmap[data_offset..])
            .map_err(|e| bad(format!("data block not 4-byte aligned: {e}")))?;
        Ok(Opened::Valid(RsrpCache {
            header,
            storage: Storage::Mapped(mmap),
            data_offset,
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
            Storage::Owned(v) => v,
            // Alignment and length were checked in `open`.
            Storage::Mapped(m) => bytemuck::cast_slice(&m[self.data_offset..]),
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
}

impl RsrpSource for RsrpCache {
    fn num_sites(&self) -> usize {
        self.header.n_sites
    }

    /// Trilinear interpolation of all sites at once (positions outside the grid are clamped).
    fn rsrp_all_dbm(&self, p_m: Point, out: &mut [f64]) {
        let g = &self.header.grid;
        let m = self.header.n_sites;
        let v = self.values();
        let (ix, tx) = Self::axis(p_m[0], g.x0_m, g.dxy_m, g.nx);
        let (iy, ty) = Self::axis(p_m[1], g.y0_m, g.dxy_m, g.ny);
        let (iz, tz) = Self::axis(p_m[2], g.z0_m, g.dz_m, g.nz);
        let out = &mut out[..m];
        out.fill(0.0);
        let iz1 = (iz + 1).min(g.nz - 1);
        for (cy, wy) in [(iy, 1.0 - ty), ((iy + 1).min(g.ny - 1), ty)] {
            for (cx, wx) in [(ix, 1.0 - tx), ((ix + 1).min(g.nx - 1), tx)] {
                let base = (cy * g.nx + cx) * g.nz;
                let w0 = (wx * wy * (1.0 - tz)) as f32;
                let w1 = (wx * wy * tz) as f32;
                let a = &v[(base + iz) * m..(base + iz) * m + m];
                let b = &v[(base + iz1) * m..(base + iz1) * m + m];
                for ((o, va), vb) in out.iter_mut().zip(a).zip(b) {
                    *o += f64::from(w0 * va + w1 * vb);
                }
            }
        }
    }
}
