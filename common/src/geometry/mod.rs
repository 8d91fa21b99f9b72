//! Geometry of the simulation's maths: small f64 value types from nalgebra instead of bare arrays.
//!
//! Positions are east-north-up metres (x east, y north, z up = height above flat ground, origin at
//! the scenario centre; `docs/spec/radio.md` §1). The radio model, the environment and the
//! planners compute in these types; the building mesh converts to parry's `f32` glam types at its
//! own boundary (`radio::city::mesh`), and files and messages keep `[x, y, z]` arrays
//! ([`serde_point`]), so no stored or sent format depends on nalgebra.
//!
//! One concept per file, as parry does: [`Point`]/[`Vector`] here, [`Bounds2`] in `bounds.rs`.

mod bounds;
pub mod serde_point;

pub use bounds::Bounds2;

/// A position (m), east-north-up.
pub type Point = nalgebra::Point3<f64>;
/// A displacement or direction (m, or unitless when normalised), east-north-up.
pub type Vector = nalgebra::Vector3<f64>;
/// A horizontal position (m), east-north.
pub type Point2 = nalgebra::Point2<f64>;

/// Euclidean distance between two positions (m): the one definition of a 3D distance (the
/// environment's progress and goal, the pilot's and evaluation's flown distance, the planners).
///
/// Written out rather than as `nalgebra::distance` so that the operations (and so every committed
/// result) stay those of the `[f64; 3]` code it replaced: `√((ax−bx)² + (ay−by)² + (az−bz)²)`.
#[inline]
pub fn distance_m(a: Point, b: Point) -> f64 {
    ((a.x - b.x).powi(2) + (a.y - b.y).powi(2) + (a.z - b.z).powi(2)).sqrt()
}

/// Euclidean norm of a vector (in its unit): `√(x·x + y·y + z·z)`, the operations of the code it
/// replaced.
#[inline]
pub fn norm(v: Vector) -> f64 {
    (v.x * v.x + v.y * v.y + v.z * v.z).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distance_is_symmetric_and_exact_on_a_pythagorean_triple() {
        let a = Point::new(1.0, 2.0, 3.0);
        let b = Point::new(4.0, 6.0, 15.0);
        assert_eq!(distance_m(a, b), 13.0);
        assert_eq!(distance_m(b, a), 13.0);
        assert_eq!(norm(b - a), 13.0);
    }
}
