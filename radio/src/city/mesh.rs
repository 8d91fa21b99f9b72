//! The building mesh: every prism triangulated into one parry3d [`TriMesh`], whose BVH answers the
//! geometric line-of-sight test of spec/radio.md D9 (segment GBS antenna → UAV against buildings)
//! and the distance queries of the environment.
//!
//! parry3d ≥ 0.26 speaks glam `f32`; this is the only module that converts. Coordinates stay
//! within a few km of the origin, so `f32` resolves them to better than 0.5 mm.

use super::building::Building;
use crate::error::RadioError;
use dupac_common::geometry::{Point, Vector, norm};
use parry3d::math::Vec3;
use parry3d::partitioning::TraversalAction;
use parry3d::query::Ray;
use parry3d::shape::TriMesh;

/// Triangulated buildings with a BVH.
#[derive(Clone)]
pub struct CityMesh {
    trimesh: TriMesh,
    /// Per triangle: `v0`, `e1 = v1 − v0`, `e2 = v2 − v0` for a Möller–Trumbore test that needs no
    /// index chasing.
    tris: Vec<[Vec3; 3]>,
}

impl std::fmt::Debug for CityMesh {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CityMesh")
            .field("triangles", &self.tris.len())
            .finish()
    }
}

/// Relative tolerance on the segment parameter: hits within this fraction of either end do not
/// block (an antenna mounted on a roof does not see its own roof as an obstacle at t = 0).
const SEGMENT_END_EPS: f32 = 1e-6;

impl CityMesh {
    /// Triangulates the buildings: roof (ear clipping with holes), walls, and a floor only for
    /// floating parts (`z_min_m > 0`; a floor on the ground cannot be crossed from above ground).
    pub fn build(buildings: &[Building]) -> Result<CityMesh, RadioError> {
        let mut vertices: Vec<Vec3> = Vec::new();
        let mut indices: Vec<[u32; 3]> = Vec::new();
        for b in buildings {
            add_prism(b, &mut vertices, &mut indices)?;
        }
        if indices.is_empty() {
            return Err(RadioError::Mesh("no triangles: the city is empty".into()));
        }
        let trimesh = TriMesh::new(vertices, indices)
            .map_err(|e| RadioError::Mesh(format!("cannot build the triangle mesh: {e:?}")))?;
        let tris = trimesh
            .triangles()
            .map(|t| [t.a, t.b - t.a, t.c - t.a])
            .collect();
        Ok(CityMesh { trimesh, tris })
    }

    /// The parry3d mesh (for shape casts and other queries).
    pub fn trimesh(&self) -> &TriMesh {
        &self.trimesh
    }

    /// Number of triangles.
    pub fn num_triangles(&self) -> usize {
        self.tris.len()
    }

    /// Whether the open segment `a_m → b_m` crosses any building surface (any-hit query over the
    /// BVH, exits at the first hit). `true` means NLoS (spec/radio.md D9).
    pub fn segment_blocked(&self, a_m: Point, b_m: Point) -> bool {
        let origin = to_vec3(a_m);
        let dir = to_vec3(b_m) - origin;
        let ray = Ray::new(origin, dir);
        let mut hit = false;
        self.trimesh.bvh().traverse(|node| {
            if node.cast_ray(&ray, 1.0) == f32::MAX || hit {
                return TraversalAction::Prune;
            }
            if let Some(leaf) = node.leaf_data() {
                if let Some(t) = self.tris.get(leaf as usize)
                    && let Some(s) = ray_triangle(origin, dir, t)
                    && s > SEGMENT_END_EPS
                    && s < 1.0 - SEGMENT_END_EPS
                {
                    hit = true;
                    return TraversalAction::EarlyExit;
                }
                return TraversalAction::Prune;
            }
            TraversalAction::Continue
        });
        hit
    }

    /// Distance (m) along the direction `dir` (any length) from `origin_m` to the first building
    /// surface within `max_m`, or `None` when the ray is free for `max_m` metres. Closest-hit
    /// traversal of the BVH that prunes nodes farther than the best hit so far.
    pub fn ray_distance_m(&self, origin_m: Point, dir: Vector, max_m: f64) -> Option<f64> {
        let n = norm(dir);
        if n.is_nan() || n <= 0.0 || max_m.is_nan() || max_m <= 0.0 {
            return None;
        }
        let origin = to_vec3(origin_m);
        let unit = Vec3::new(
            (dir[0] / n) as f32,
            (dir[1] / n) as f32,
            (dir[2] / n) as f32,
        );
        let ray = Ray::new(origin, unit);
        let mut best = max_m as f32;
        let mut hit = false;
        self.trimesh.bvh().traverse(|node| {
            if node.cast_ray(&ray, best) == f32::MAX {
                return TraversalAction::Prune;
            }
            if let Some(leaf) = node.leaf_data() {
                if let Some(t) = self.tris.get(leaf as usize)
                    && let Some(s) = ray_triangle(origin, unit, t)
                    && s >= 0.0
                    && s <= best
                {
                    best = s;
                    hit = true;
                }
                return TraversalAction::Prune;
            }
            TraversalAction::Continue
        });
        hit.then_some(f64::from(best))
    }

    /// The nearest building surface point within `max_m` of `p_m`: its distance (m) and the unit
    /// direction from `p_m` towards it, or `None` when no surface is that close. The exact
    /// "distance c_t and direction θ_t to the nearest obstacle" of the paper's state (a BVH
    /// best-first projection onto the mesh; a point inside a building projects onto its surface).
    pub fn nearest_surface_m(&self, p_m: Point, max_m: f64) -> Option<(f64, Vector)> {
        use parry3d::query::PointQuery;
        if max_m.is_nan() || max_m <= 0.0 || p_m.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let p = to_vec3(p_m);
        let proj = self
            .trimesh
            .project_local_point_with_max_dist(p, false, max_m as f32)?;
        let d = proj.point - p;
        let n = d.length();
        if !n.is_finite() {
            return None;
        }
        let dir = if n > 0.0 {
            Vector::new(f64::from(d.x / n), f64::from(d.y / n), f64::from(d.z / n))
        } else {
            Vector::zeros()
        };
        Some((f64::from(n), dir))
    }

    /// Swept-sphere collision: the fraction `t ∈ [0, 1]` of the move `a_m → b_m` at which a
    /// sphere of `radius_m` first touches a building surface, or `None` if the whole move is
    /// free. A broad phase on the BVH (the move's swept box) skips the exact cast in open air.
    pub fn sphere_sweep(&self, a_m: Point, b_m: Point, radius_m: f64) -> Option<f64> {
        let (a, b) = (to_vec3(a_m), to_vec3(b_m));
        let r = radius_m as f32;
        let swept = parry3d::bounding_volume::Aabb::new(
            a.min(b) - Vec3::splat(r),
            a.max(b) + Vec3::splat(r),
        );
        // Broad phase: no triangle box near the swept box, no contact.
        self.trimesh.bvh().intersect_aabb(&swept).next()?;
        let ball = parry3d::shape::Ball::new(r);
        let options = parry3d::query::ShapeCastOptions {
            max_time_of_impact: 1.0,
            ..parry3d::query::ShapeCastOptions::default()
        };
        match parry3d::query::cast_shapes(
            &parry3d::math::Pose::from_translation(a),
            b - a,
            &ball,
            &parry3d::math::Pose::IDENTITY,
            Vec3::ZERO,
            &self.trimesh,
            options,
        ) {
            Ok(Some(hit)) => Some(f64::from(hit.time_of_impact.clamp(0.0, 1.0))),
            Ok(None) => None,
            // Ball vs TriMesh is supported by parry's dispatcher; treat the impossible as a hit
            // (never fly through a building).
            Err(_) => Some(0.0),
        }
    }
}

/// `Point` metres → glam `Vec3` (the geometry boundary).
#[inline]
pub fn to_vec3(p: Point) -> Vec3 {
    Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32)
}

/// Two-sided Möller–Trumbore: the ray parameter `t` of the hit (in units of `dir`), if any.
#[inline(always)]
fn ray_triangle(origin: Vec3, dir: Vec3, tri: &[Vec3; 3]) -> Option<f32> {
    let [v0, e1, e2] = *tri;
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() < 1e-12 {
        return None;
    }
    let inv = 1.0 / det;
    let s = origin - v0;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    Some(e2.dot(q) * inv)
}

fn add_prism(
    b: &Building,
    vertices: &mut Vec<Vec3>,
    indices: &mut Vec<[u32; 3]>,
) -> Result<(), RadioError> {
    let z0 = b.z_min_m as f32;
    let z1 = b.z_max_m as f32;
    // Flattened rings for earcut: outer first, then holes.
    let mut flat: Vec<f64> = Vec::new();
    let mut hole_starts: Vec<usize> = Vec::new();
    let mut ring_ranges: Vec<(usize, usize)> = Vec::new();
    for (r, ring) in std::iter::once(&b.outer_m)
        .chain(b.holes_m.iter())
        .enumerate()
    {
        let start = flat.len() / 2;
        if r > 0 {
            hole_starts.push(start);
        }
        for p in ring {
            flat.push(p[0]);
            flat.push(p[1]);
        }
        ring_ranges.push((start, ring.len()));
    }
    let n = flat.len() / 2;
    let base = u32::try_from(vertices.len())
        .map_err(|_| RadioError::Mesh("more than 2^32 vertices".into()))?;
    // Vertices: bottom ring set [base, base+n), top ring set [base+n, base+2n).
    for z in [z0, z1] {
        for i in 0..n {
            vertices.push(Vec3::new(flat[2 * i] as f32, flat[2 * i + 1] as f32, z));
        }
    }
    let bottom = |i: usize| base + i as u32;
    let top = |i: usize| base + (n + i) as u32;
    // Roof (and floor of a floating part).
    let tri = earcutr::earcut(&flat, &hole_starts, 2)
        .map_err(|e| RadioError::Mesh(format!("building {}: triangulation failed: {e:?}", b.id)))?;
    if tri.len() < 3 {
        return Err(RadioError::Mesh(format!(
            "building {}: footprint triangulates to nothing",
            b.id
        )));
    }
    for t in tri.chunks_exact(3) {
        indices.push([top(t[0]), top(t[1]), top(t[2])]);
        if b.z_min_m > 0.0 {
            indices.push([bottom(t[0]), bottom(t[2]), bottom(t[1])]);
        }
    }
    // Walls.
    for (start, len) in ring_ranges {
        for k in 0..len {
            let i = start + k;
            let j = start + (k + 1) % len;
            indices.push([bottom(i), bottom(j), top(j)]);
            indices.push([bottom(i), top(j), top(i)]);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An L-shaped (non-convex) building, 30 m tall, plus a floating slab 50–60 m.
    fn scene() -> CityMesh {
        let l_shape = Building {
            id: "L".into(),
            outer_m: vec![
                [0.0, 0.0],
                [20.0, 0.0],
                [20.0, 10.0],
                [10.0, 10.0],
                [10.0, 20.0],
                [0.0, 20.0],
            ],
            holes_m: vec![],
            z_min_m: 0.0,
            z_max_m: 30.0,
        };
        let slab = Building {
            id: "slab".into(),
            outer_m: vec![[100.0, 0.0], [110.0, 0.0], [110.0, 10.0], [100.0, 10.0]],
            holes_m: vec![],
            z_min_m: 50.0,
            z_max_m: 60.0,
        };
        let courtyard = Building {
            id: "court".into(),
            outer_m: vec![[200.0, 0.0], [240.0, 0.0], [240.0, 40.0], [200.0, 40.0]],
            holes_m: vec![vec![
                [210.0, 10.0],
                [210.0, 30.0],
                [230.0, 30.0],
                [230.0, 10.0],
            ]],
            z_min_m: 0.0,
            z_max_m: 20.0,
        };
        CityMesh::build(&[l_shape, slab, courtyard]).expect("mesh")
    }

    #[test]
    fn segment_through_the_l_is_blocked_but_the_notch_is_free() {
        let m = scene();
        // Through the solid arm at 10 m height.
        assert!(m.segment_blocked(Point::new(-10.0, 5.0, 10.0), Point::new(30.0, 5.0, 10.0)));
        // Through the notch of the L (x, y ∈ (10, 20)): free.
        assert!(!m.segment_blocked(Point::new(15.0, 25.0, 10.0), Point::new(25.0, 15.0, 10.0)));
        // Above the roof: free; grazing below it: blocked.
        assert!(!m.segment_blocked(Point::new(-10.0, 5.0, 31.0), Point::new(30.0, 5.0, 31.0)));
        assert!(m.segment_blocked(Point::new(-10.0, 5.0, 29.0), Point::new(30.0, 5.0, 29.0)));
        // Diagonal from a roof-level antenna to a low UAV behind the building.
        assert!(m.segment_blocked(Point::new(-5.0, 5.0, 40.0), Point::new(40.0, 5.0, 1.0)));
    }

    #[test]
    fn segment_stopping_short_of_a_wall_is_free() {
        let m = scene();
        assert!(!m.segment_blocked(Point::new(-10.0, 5.0, 10.0), Point::new(-0.5, 5.0, 10.0)));
    }

    #[test]
    fn floating_part_blocks_only_its_own_height_band() {
        let m = scene();
        assert!(m.segment_blocked(Point::new(90.0, 5.0, 55.0), Point::new(120.0, 5.0, 55.0)));
        assert!(
            !m.segment_blocked(Point::new(90.0, 5.0, 40.0), Point::new(120.0, 5.0, 40.0)),
            "under the slab"
        );
        assert!(
            m.segment_blocked(Point::new(105.0, 5.0, 40.0), Point::new(105.0, 5.0, 70.0)),
            "vertical through its floor"
        );
    }

    #[test]
    fn courtyard_hole_is_open_from_above() {
        let m = scene();
        assert!(!m.segment_blocked(Point::new(220.0, 20.0, 100.0), Point::new(220.0, 20.0, 5.0)));
        assert!(m.segment_blocked(Point::new(205.0, 20.0, 100.0), Point::new(205.0, 20.0, 5.0)));
    }

    #[test]
    fn sphere_sweep_touches_walls_roofs_and_thin_parts() {
        let m = scene();
        // Towards the L's west wall (x = 0) from x = −2: the 0.5 m sphere touches at x = −0.5.
        let t = m
            .sphere_sweep(
                Point::new(-2.0, 5.0, 10.0),
                Point::new(-0.0, 5.0, 10.0),
                0.5,
            )
            .expect("wall");
        assert!((t - 0.75).abs() < 1e-3, "{t}");
        // Parallel to the wall at 0.6 m: free.
        assert!(
            m.sphere_sweep(
                Point::new(-0.6, 1.0, 10.0),
                Point::new(-0.6, 9.0, 10.0),
                0.5
            )
            .is_none()
        );
        // Down onto the roof (30 m): touches when the centre is at 30.5 m.
        let t = m
            .sphere_sweep(Point::new(5.0, 5.0, 31.0), Point::new(5.0, 5.0, 30.0), 0.5)
            .expect("roof");
        assert!((t - 0.5).abs() < 1e-3, "{t}");
        // Up into the floating slab's floor (50 m) from below.
        assert!(
            m.sphere_sweep(
                Point::new(105.0, 5.0, 48.0),
                Point::new(105.0, 5.0, 49.8),
                0.5
            )
            .is_some()
        );
        // Far away in open air: free (broad phase).
        assert!(
            m.sphere_sweep(
                Point::new(500.0, 500.0, 50.0),
                Point::new(501.0, 501.0, 51.0),
                0.5
            )
            .is_none()
        );
    }

    #[test]
    fn nearest_surface_sees_a_corner_between_the_sensor_rays() {
        let m = scene();
        // Beside the L's outer corner (20, 10): the exact nearest point is the corner edge,
        // √(3² + 2²) m away; the closest of the 26 grid rays only hits the wall at 3√2 m.
        let p = Point::new(23.0, 12.0, 10.0);
        let (d, dir) = m.nearest_surface_m(p, 50.0).expect("a surface");
        assert!((d - 13f64.sqrt()).abs() < 1e-3, "{d}");
        assert!(
            (dir[0] + 3.0 / 13f64.sqrt()).abs() < 1e-3
                && (dir[1] + 2.0 / 13f64.sqrt()).abs() < 1e-3
        );
        assert!(dir[2].abs() < 1e-6);
        let fan_min = crate_fan_min(&m, p);
        assert!(fan_min > d + 0.5, "fan {fan_min} vs exact {d}");
        // Over the roof: straight down.
        let (d, dir) = m
            .nearest_surface_m(Point::new(5.0, 5.0, 34.0), 50.0)
            .expect("roof");
        assert!((d - 4.0).abs() < 1e-3 && (dir[2] + 1.0).abs() < 1e-6);
        // Nothing within the range.
        assert!(
            m.nearest_surface_m(Point::new(500.0, 500.0, 10.0), 50.0)
                .is_none()
        );
        assert!(
            m.nearest_surface_m(Point::new(f64::NAN, 0.0, 0.0), 50.0)
                .is_none()
        );
    }

    fn crate_fan_min(m: &CityMesh, p: Point) -> f64 {
        let mut best = f64::INFINITY;
        for x in -1..=1 {
            for y in -1..=1 {
                for z in -1..=1 {
                    if (x, y, z) != (0, 0, 0)
                        && let Some(t) = m.ray_distance_m(
                            p,
                            Vector::new(f64::from(x), f64::from(y), f64::from(z)),
                            50.0,
                        )
                    {
                        best = best.min(t);
                    }
                }
            }
        }
        best
    }

    #[test]
    fn ray_distance_finds_the_nearest_wall() {
        let m = scene();
        let d = m
            .ray_distance_m(
                Point::new(-10.0, 5.0, 10.0),
                Vector::new(1.0, 0.0, 0.0),
                50.0,
            )
            .expect("hit");
        assert!((d - 10.0).abs() < 1e-3, "{d}");
        assert!(
            m.ray_distance_m(
                Point::new(-10.0, 5.0, 10.0),
                Vector::new(-1.0, 0.0, 0.0),
                50.0
            )
            .is_none()
        );
        let down = m
            .ray_distance_m(
                Point::new(5.0, 5.0, 100.0),
                Vector::new(0.0, 0.0, -1.0),
                200.0,
            )
            .expect("roof");
        assert!((down - 70.0).abs() < 1e-3, "{down}");
    }
}
