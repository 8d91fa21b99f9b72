//! Geometry shared by the simulation's maths: positions are east-north-up metres (x east, y
//! north, z up = height above flat ground, origin at the scenario centre).

/// Euclidean distance between two positions (m): the one definition of a 3D distance (the
/// environment's progress and goal, the pilot's and evaluation's flown distance, the planners).
#[inline]
pub fn distance_m(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
