//! Free airspace as a voxel lattice over the flight area and the altitude band (spec/env.md
//! "World", "UAV and motion"), plus the exact geometric tests the planners are built on: a free
//! point (clearance from the building mesh) and a clear straight move (swept sphere).
//!
//! The lattice is a set of points ("voxel centres") every `planner.voxel_m` metres, centred in the
//! flight area and the band: `n = floor(span / voxel_m) + 1` points per axis, the leftover span
//! split evenly between both sides. On Midtown (1430 m × 1445 m × 100 m, 5 m) that is
//! 287 × 289 × 21 points, the band's two limits included.

use dupac_common::config::{EnvConfig, PlannerConfig};
use dupac_common::geometry::{Bounds2, Point};
use dupac_radio::city::{City, to_vec3};
use parry3d::query::PointQuery;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// The 26 neighbour offsets of the lattice, in lexicographic order of `(dx, dy, dz)` with the
/// centre left out, so that the opposite of direction `d` is `25 − d`.
pub(crate) const NEIGHBOURS: [[i32; 3]; 26] = {
    let mut out = [[0i32; 3]; 26];
    let mut k = 0;
    let mut dx = -1;
    while dx <= 1 {
        let mut dy = -1;
        while dy <= 1 {
            let mut dz = -1;
            while dz <= 1 {
                if !(dx == 0 && dy == 0 && dz == 0) {
                    out[k] = [dx, dy, dz];
                    k += 1;
                }
                dz += 1;
            }
            dy += 1;
        }
        dx += 1;
    }
    out
};

/// Length of neighbour step `d` in voxel edges (1, √2 or √3).
pub(crate) fn step_len(d: usize) -> f64 {
    let o = NEIGHBOURS[d];
    f64::from(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt()
}

/// Extra clearance (m) of the segments created by smoothing and of the free lattice points over
/// the exact [`FreeSpace::segment_clear`] / [`FreeSpace::is_free_point`] clearance, so that the
/// planned path passes the exact tests with room for `f32` rounding.
pub const SMOOTHING_MARGIN_M: f64 = 0.05;

/// Largest lattice the planner accepts (indices are `u32`, one value is reserved).
const MAX_VOXELS: usize = (u32::MAX - 1) as usize;

/// Free airspace of one city for one UAV clearance: the voxel lattice, each point's distance to
/// the building mesh (capped), and a lazily filled, thread-safe cache of which lattice edges are
/// flyable. Owns a copy of the city geometry so that it can answer exact queries on its own.
pub struct FreeSpace {
    city: City,
    /// The flight area (m).
    area_m: Bounds2,
    /// Altitude band `[z_min, z_max]` (m above ground), spec/env.md.
    band_m: [f64; 2],
    /// Lattice spacing (m).
    voxel_m: f64,
    /// Clearance kept from every building surface (m).
    clearance_m: f64,
    /// Lattice point `(0, 0, 0)` (m).
    origin_m: Point,
    /// Points per axis `[nx, ny, nz]`.
    dims: [usize; 3],
    /// Distance (m) from each lattice point to the mesh, capped at max(√3·voxel + clearance + 0.5, 4·voxel); −1 inside a
    /// building. Index `(iz·ny + iy)·nx + ix`.
    dist_m: Vec<f32>,
    /// Per lattice point, two bits per neighbour direction `d`: bit `2d` = known, `2d+1` = clear.
    edges: Vec<AtomicU64>,
    n_free: usize,
}

impl std::fmt::Debug for FreeSpace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FreeSpace")
            .field("dims", &self.dims)
            .field("voxel_m", &self.voxel_m)
            .field("clearance_m", &self.clearance_m)
            .field("free", &self.n_free)
            .finish()
    }
}

/// `(n, first)`: lattice points along `[lo, hi]` every `step`, centred in the span.
fn axis(lo: f64, hi: f64, step: f64) -> (usize, f64) {
    let span = hi - lo;
    if !(span.is_finite() && span >= 0.0) {
        return (0, lo);
    }
    let n = (span / step + 1e-9).floor() as usize + 1;
    let first = lo + 0.5 * (span - (n - 1) as f64 * step);
    (n, first.max(lo))
}

impl FreeSpace {
    /// Builds the lattice over `city.area_m` × `[env.z_min_m, env.z_max_m]` with edge
    /// `planner.voxel_m` (m) and marks a point free when it is outside every building and at least
    /// `planner.clearance_m` (m) from the building mesh (spec/env.md: the UAV is a 0.5 m sphere;
    /// the clearance must be ≥ `env.uav_radius_m`). Parallel over horizontal layers (rayon).
    ///
    /// Expects a validated configuration; a non-finite or non-positive voxel edge is replaced by
    /// 5 m, a lattice above 2³² points is coarsened, and a clearance below the UAV radius is raised
    /// to it (each with a warning) instead of panicking.
    pub fn build(city: &City, env: &EnvConfig, planner: &PlannerConfig) -> FreeSpace {
        let mut voxel_m = planner.voxel_m;
        if !(voxel_m.is_finite() && voxel_m > 0.0) {
            tracing::warn!(
                voxel_m,
                "planner.voxel_m is not a positive number; using 5 m"
            );
            voxel_m = 5.0;
        }
        let mut clearance_m = planner.clearance_m;
        let uav_radius_m = if env.uav_radius_m.is_finite() {
            env.uav_radius_m.max(0.0)
        } else {
            0.0
        };
        if !(clearance_m.is_finite() && clearance_m >= uav_radius_m) {
            tracing::warn!(
                clearance_m,
                uav_radius_m,
                "planner.clearance_m is below the UAV radius; using the radius"
            );
            clearance_m = uav_radius_m;
        }
        let area_m = city.area_m;
        let band_m = [env.z_min_m, env.z_max_m];
        let (dims, origin_m) = loop {
            let (nx, x0) = axis(area_m.min_m.x, area_m.max_m.x, voxel_m);
            let (ny, y0) = axis(area_m.min_m.y, area_m.max_m.y, voxel_m);
            let (nz, z0) = axis(band_m[0], band_m[1], voxel_m);
            let total = nx.checked_mul(ny).and_then(|v| v.checked_mul(nz));
            match total {
                Some(t) if t <= MAX_VOXELS => break ([nx, ny, nz], Point::new(x0, y0, z0)),
                _ => {
                    tracing::warn!(
                        voxel_m,
                        "planner lattice too large; doubling the voxel edge"
                    );
                    voxel_m *= 2.0;
                }
            }
        };
        // Long enough that a point this far from the mesh has all 26 edges clear, and that the
        // distance-field line of sight can take long steps in open air.
        let dist_cap_m = (3f64.sqrt() * voxel_m + clearance_m + 0.5).max(4.0 * voxel_m);
        let [nx, ny, nz] = dims;
        let n = nx * ny * nz;
        let mut dist_m = vec![0f32; n];
        let mut fs = FreeSpace {
            city: city.clone(),
            area_m,
            band_m,
            voxel_m,
            clearance_m,
            origin_m,
            dims,
            dist_m: Vec::new(),
            edges: Vec::new(),
            n_free: 0,
        };
        if n > 0 {
            dist_m
                .par_chunks_mut(nx)
                .enumerate()
                .for_each(|(row, out)| {
                    let iz = row / ny;
                    let iy = row % ny;
                    for (ix, o) in out.iter_mut().enumerate() {
                        let p = fs.point_m([ix, iy, iz]);
                        *o = if fs.city.is_inside_building(p) {
                            -1.0
                        } else {
                            fs.mesh_distance_capped_m(p, dist_cap_m) as f32
                        };
                    }
                });
        }
        let clearance = (clearance_m + SMOOTHING_MARGIN_M) as f32;
        fs.n_free = dist_m.par_iter().filter(|&&d| d >= clearance).count();
        fs.dist_m = dist_m;
        fs.edges = (0..n).map(|_| AtomicU64::new(0)).collect();
        fs
    }

    /// The city geometry this free space was built from.
    pub fn city(&self) -> &City {
        &self.city
    }

    /// Lattice spacing (m).
    pub fn voxel_m(&self) -> f64 {
        self.voxel_m
    }

    /// Clearance from buildings (m) that free points and clear segments keep.
    pub fn clearance_m(&self) -> f64 {
        self.clearance_m
    }

    /// Altitude band `[z_min, z_max]` (m above ground).
    pub fn band_m(&self) -> [f64; 2] {
        self.band_m
    }

    /// The flight area (m).
    pub fn area_m(&self) -> Bounds2 {
        self.area_m
    }

    /// Lattice points per axis `[nx, ny, nz]`.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Number of lattice points.
    pub fn num_voxels(&self) -> usize {
        self.dist_m.len()
    }

    /// Fraction of lattice points that are free (outside buildings, at least the clearance plus
    /// [`SMOOTHING_MARGIN_M`] from the mesh).
    pub fn free_voxel_fraction(&self) -> f64 {
        if self.dist_m.is_empty() {
            0.0
        } else {
            self.n_free as f64 / self.dist_m.len() as f64
        }
    }

    /// Distance (m) from `p_m` to the building mesh, or `cap_m` when it is farther than that.
    pub fn mesh_distance_capped_m(&self, p_m: Point, cap_m: f64) -> f64 {
        match self.city.mesh.trimesh().project_local_point_with_max_dist(
            to_vec3(p_m),
            false,
            cap_m as f32,
        ) {
            Some(proj) => f64::from((proj.point - to_vec3(p_m)).length()).min(cap_m),
            None => cap_m,
        }
    }

    /// Whether `p_m` is finite, inside the flight area (inclusive) and inside the altitude band
    /// (inclusive).
    pub fn in_bounds(&self, p_m: Point) -> bool {
        p_m.iter().all(|v| v.is_finite())
            && self.city.in_area(p_m[0], p_m[1])
            && p_m[2] >= self.band_m[0]
            && p_m[2] <= self.band_m[1]
    }

    /// Exact free-point test: finite, in the area and the band, not inside a building, and at
    /// least `clearance_m` from the building mesh.
    pub fn is_free_point(&self, p_m: Point) -> bool {
        self.in_bounds(p_m)
            && !self.city.is_inside_building(p_m)
            && self.mesh_distance_capped_m(p_m, self.clearance_m) >= self.clearance_m
    }

    /// Exact test that the straight move `a_m → b_m` is flyable with `clearance_m` to spare: both
    /// ends in the area and the band (both convex, so the whole segment is), the start outside
    /// every building, and a sphere of radius `clearance_m` swept from `a_m` to `b_m` never
    /// touches the building mesh (parry3d shape cast, the environment's collision test with a
    /// larger radius). A path whose segments all pass this cannot collide in the environment.
    pub fn segment_clear(&self, a_m: Point, b_m: Point) -> bool {
        self.in_bounds(a_m)
            && self.in_bounds(b_m)
            && !self.city.is_inside_building(a_m)
            && self
                .city
                .mesh
                .sphere_sweep(a_m, b_m, self.clearance_m)
                .is_none()
    }

    /// [`FreeSpace::segment_clear`] with the clearance enlarged by [`SMOOTHING_MARGIN_M`]: used for
    /// every segment the smoothing creates.
    pub(crate) fn segment_clear_smoothing(&self, a_m: Point, b_m: Point) -> bool {
        self.in_bounds(a_m)
            && self.in_bounds(b_m)
            && !self.city.is_inside_building(a_m)
            && self
                .city
                .mesh
                .sphere_sweep(a_m, b_m, self.clearance_m + SMOOTHING_MARGIN_M)
                .is_none()
    }

    /// Lattice point of index triple `[ix, iy, iz]` (m).
    #[inline]
    pub(crate) fn point_m(&self, i: [usize; 3]) -> Point {
        Point::new(
            self.origin_m[0] + i[0] as f64 * self.voxel_m,
            self.origin_m[1] + i[1] as f64 * self.voxel_m,
            self.origin_m[2] + i[2] as f64 * self.voxel_m,
        )
    }

    /// Flat index of `[ix, iy, iz]`.
    #[inline]
    pub(crate) fn index(&self, i: [usize; 3]) -> u32 {
        ((i[2] * self.dims[1] + i[1]) * self.dims[0] + i[0]) as u32
    }

    /// Index triple of a flat index.
    #[inline]
    pub(crate) fn triple(&self, idx: u32) -> [usize; 3] {
        let idx = idx as usize;
        let [nx, ny, _] = self.dims;
        [idx % nx, (idx / nx) % ny, idx / (nx * ny)]
    }

    /// Lattice point of a flat index (m).
    #[inline]
    pub(crate) fn centre_m(&self, idx: u32) -> Point {
        self.point_m(self.triple(idx))
    }

    /// Whether lattice point `idx` is free (at least `clearance_m` + [`SMOOTHING_MARGIN_M`] from
    /// the mesh, outside buildings).
    #[inline]
    pub(crate) fn is_free_voxel(&self, idx: u32) -> bool {
        self.dist_m
            .get(idx as usize)
            .is_some_and(|&d| d >= (self.clearance_m + SMOOTHING_MARGIN_M) as f32)
    }

    /// Index triple of the lattice point nearest to `p_m` (clamped to the lattice), or `None` for
    /// a non-finite point or an empty lattice.
    pub(crate) fn nearest_triple(&self, p_m: Point) -> Option<[usize; 3]> {
        if self.dist_m.is_empty() || !p_m.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut out = [0usize; 3];
        for k in 0..3 {
            let f = ((p_m[k] - self.origin_m[k]) / self.voxel_m).round();
            out[k] = f.clamp(0.0, (self.dims[k] - 1) as f64) as usize;
        }
        Some(out)
    }

    /// Flat index of the neighbour of `i` in direction `d`, if inside the lattice.
    #[inline]
    pub(crate) fn neighbour(&self, i: [usize; 3], d: usize) -> Option<(u32, [usize; 3])> {
        let o = NEIGHBOURS[d];
        let mut j = [0usize; 3];
        for k in 0..3 {
            let v = i[k] as i64 + i64::from(o[k]);
            if v < 0 || v >= self.dims[k] as i64 {
                return None;
            }
            j[k] = v as usize;
        }
        Some((self.index(j), j))
    }

    /// Whether the lattice edge `u → v` (direction `d`, both ends free) is flyable. Exact: a cheap
    /// sufficient test on the stored distances (every point of the edge is at least
    /// `(d_u + d_v − L) / 2` from the mesh), else the swept sphere (from the lower index to the
    /// higher), cached for both directions.
    pub(crate) fn edge_clear(&self, u: u32, d: usize, v: u32) -> bool {
        let (du, dv) = match (self.dist_m.get(u as usize), self.dist_m.get(v as usize)) {
            (Some(&a), Some(&b)) => (f64::from(a), f64::from(b)),
            _ => return false,
        };
        let len = step_len(d) * self.voxel_m;
        let r = self.clearance_m + SMOOTHING_MARGIN_M;
        if du + dv >= len + 2.0 * r + 1e-3 {
            return true;
        }
        let (Some(eu), Some(ev)) = (self.edges.get(u as usize), self.edges.get(v as usize)) else {
            return false;
        };
        let word = eu.load(Ordering::Relaxed);
        if word & (1u64 << (2 * d)) != 0 {
            return word & (1u64 << (2 * d + 1)) != 0;
        }
        // Swept from the lower index to the higher, so that the cached answer (shared by both
        // directions) does not depend on which direction a search asked first: plans stay a
        // function of their endpoints, whatever was planned before in the process.
        let (a, b) = if u < v { (u, v) } else { (v, u) };
        let clear = self
            .city
            .mesh
            .sphere_sweep(self.centre_m(a), self.centre_m(b), r)
            .is_none();
        let bits = |d: usize| (1u64 << (2 * d)) | (u64::from(clear) << (2 * d + 1));
        eu.fetch_or(bits(d), Ordering::Relaxed);
        ev.fetch_or(bits(25 - d), Ordering::Relaxed);
        clear
    }

    /// A lower bound (m) on the distance from `p_m` to the building mesh, from the stored
    /// distances of the 8 lattice points around it: `max_c (d(c) − |p − c|)` over corners `c`
    /// outside buildings (a ball of radius `d(c)` around an outside point holds no surface, so it
    /// is all outside). Negative when nothing is known.
    #[inline]
    fn clearance_lower_bound_m(&self, p_m: Point) -> f64 {
        let mut lo = [0usize; 3];
        let mut hi = [0usize; 3];
        for k in 0..3 {
            let n = self.dims[k];
            let f = ((p_m[k] - self.origin_m[k]) / self.voxel_m).floor();
            let i = if f.is_finite() {
                f.clamp(0.0, n.saturating_sub(2) as f64) as usize
            } else {
                0
            };
            lo[k] = i;
            hi[k] = (i + 1).min(n - 1);
        }
        let mut best = f64::NEG_INFINITY;
        for iz in [lo[2], hi[2]] {
            for iy in [lo[1], hi[1]] {
                for ix in [lo[0], hi[0]] {
                    let i = [ix, iy, iz];
                    let d = f64::from(self.dist_m[self.index(i) as usize]);
                    if d >= 0.0 {
                        best = best.max(d - super::dist(p_m, self.point_m(i)));
                    }
                }
            }
        }
        best
    }

    /// Conservative line-of-sight test on the distance field (sphere tracing): `true` only if
    /// every point of `a_m → b_m` is at least the clearance plus [`SMOOTHING_MARGIN_M`] from the
    /// mesh and outside buildings, as bounded by [`Self::clearance_lower_bound_m`]. It may answer
    /// `false` for a clear segment that runs within a few metres of a wall (the bound is loose
    /// there); it never answers `true` for a blocked one. Both ends must be in the area and band.
    pub(crate) fn field_clear(&self, a_m: Point, b_m: Point) -> bool {
        if self.dist_m.is_empty() || !self.in_bounds(a_m) || !self.in_bounds(b_m) {
            return false;
        }
        let need = self.clearance_m + SMOOTHING_MARGIN_M + 1e-3;
        let len = super::dist(a_m, b_m);
        let min_step = 0.02 * self.voxel_m;
        let mut s = 0.0;
        loop {
            let f = if len > 0.0 { s / len } else { 0.0 };
            let p = Point::new(
                a_m[0] + f * (b_m[0] - a_m[0]),
                a_m[1] + f * (b_m[1] - a_m[1]),
                a_m[2] + f * (b_m[2] - a_m[2]),
            );
            let free = self.clearance_lower_bound_m(p) - need;
            if free < 0.0 {
                return false;
            }
            if s >= len {
                return true;
            }
            if free < min_step {
                return false;
            }
            s = (s + free).min(len);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn neighbour_table_is_symmetric() {
        for d in 0..26 {
            let a = NEIGHBOURS[d];
            let b = NEIGHBOURS[25 - d];
            assert_eq!([a[0] + b[0], a[1] + b[1], a[2] + b[2]], [0, 0, 0]);
        }
    }

    #[test]
    fn axis_is_centred_and_inclusive() {
        assert_eq!(axis(0.0, 100.0, 5.0), (21, 0.0));
        let (n, first) = axis(0.0, 12.0, 5.0);
        assert_eq!(n, 3);
        assert!((first - 1.0).abs() < 1e-12);
        assert_eq!(axis(10.0, 5.0, 5.0).0, 0);
    }
}
