//! A horizontal axis-aligned rectangle: the scenario's area, a building's footprint box, a
//! figure's view.

use super::Point2;

/// An axis-aligned rectangle in the horizontal plane (m): `min_m` is its south-west corner,
/// `max_m` its north-east corner. Not checked to be ordered: an empty or inverted rectangle
/// contains nothing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds2 {
    /// South-west corner (m).
    pub min_m: Point2,
    /// North-east corner (m).
    pub max_m: Point2,
}

impl Bounds2 {
    /// The rectangle `[x0, x1] × [y0, y1]` (m).
    pub const fn new(x0_m: f64, y0_m: f64, x1_m: f64, y1_m: f64) -> Self {
        Bounds2 {
            min_m: Point2::new(x0_m, y0_m),
            max_m: Point2::new(x1_m, y1_m),
        }
    }

    /// The empty rectangle (min +∞, max −∞): the start of a fold with [`Bounds2::including`].
    pub const fn empty() -> Self {
        Bounds2::new(
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        )
    }

    /// The smallest rectangle holding this one and `(x, y)` (m).
    #[inline]
    pub fn including(self, x_m: f64, y_m: f64) -> Self {
        Bounds2::new(
            self.min_m.x.min(x_m),
            self.min_m.y.min(y_m),
            self.max_m.x.max(x_m),
            self.max_m.y.max(y_m),
        )
    }

    /// This rectangle grown by `margin_m` on every side (m).
    pub fn expanded(self, margin_m: f64) -> Self {
        Bounds2::new(
            self.min_m.x - margin_m,
            self.min_m.y - margin_m,
            self.max_m.x + margin_m,
            self.max_m.y + margin_m,
        )
    }

    /// Extent along x (m).
    #[inline]
    pub fn width_m(&self) -> f64 {
        self.max_m.x - self.min_m.x
    }

    /// Extent along y (m).
    #[inline]
    pub fn height_m(&self) -> f64 {
        self.max_m.y - self.min_m.y
    }

    /// Whether `(x, y)` lies in the closed rectangle.
    #[inline]
    pub fn contains(&self, x_m: f64, y_m: f64) -> bool {
        x_m >= self.min_m.x && x_m <= self.max_m.x && y_m >= self.min_m.y && y_m <= self.max_m.y
    }

    /// The corners as `[x0, y0, x1, y1]` (m): the order of [`Bounds2::new`], for fingerprints
    /// and array maths.
    pub fn to_array(&self) -> [f64; 4] {
        [self.min_m.x, self.min_m.y, self.max_m.x, self.max_m.y]
    }
}

/// `x ∈ [x0, x1] m, y ∈ [y0, y1] m`, one decimal unless a precision is given: the form every
/// message about the flight area uses.
impl std::fmt::Display for Bounds2 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = f.precision().unwrap_or(1);
        write!(
            f,
            "x ∈ [{:.p$}, {:.p$}] m, y ∈ [{:.p$}, {:.p$}] m",
            self.min_m.x, self.max_m.x, self.min_m.y, self.max_m.y
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contains_is_closed_and_the_fold_holds_every_point() {
        let a = Bounds2::new(0.0, 0.0, 2.0, 1.0);
        assert!(a.contains(0.0, 0.0) && a.contains(2.0, 1.0) && a.contains(1.0, 0.5));
        assert!(!a.contains(2.1, 0.5) && !a.contains(1.0, -0.1));
        assert_eq!((a.width_m(), a.height_m()), (2.0, 1.0));
        let folded = [(1.0, 2.0), (-1.0, 5.0)]
            .into_iter()
            .fold(Bounds2::empty(), |b, (x, y)| b.including(x, y));
        assert_eq!(folded.to_array(), [-1.0, 2.0, 1.0, 5.0]);
        assert!(!Bounds2::empty().contains(0.0, 0.0));
        assert_eq!(a.expanded(1.0).to_array(), [-1.0, -1.0, 3.0, 2.0]);
        assert_eq!(a.to_string(), "x ∈ [0.0, 2.0] m, y ∈ [0.0, 1.0] m");
        assert_eq!(format!("{a:.0}"), "x ∈ [0, 2] m, y ∈ [0, 1] m");
    }
}
