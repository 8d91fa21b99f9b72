//! Projection of WGS84 lon/lat to the local east-north-up frame (spec/env.md "World").
//!
//! A local equirectangular projection about the scenario centre, with the WGS84 ellipsoid's
//! metres per degree at the centre latitude: accurate to centimetres over the 2 km Midtown area.

use dupac_common::config::LonLatBox;
use dupac_common::geometry::Bounds2;

/// Local tangent-plane projection about an origin (lon₀, lat₀).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LocalProjection {
    lon0_deg: f64,
    lat0_deg: f64,
    m_per_deg_lon: f64,
    m_per_deg_lat: f64,
}

impl LocalProjection {
    /// Projection with origin at `(lon0_deg, lat0_deg)`.
    pub fn new(lon0_deg: f64, lat0_deg: f64) -> Self {
        let phi = lat0_deg.to_radians();
        // Series for the WGS84 ellipsoid's metres per degree (NGA/NIMA TR 8350.2).
        let m_per_deg_lat = 111_132.92 - 559.82 * (2.0 * phi).cos() + 1.175 * (4.0 * phi).cos()
            - 0.0023 * (6.0 * phi).cos();
        let m_per_deg_lon =
            111_412.84 * phi.cos() - 93.5 * (3.0 * phi).cos() + 0.118 * (5.0 * phi).cos();
        Self {
            lon0_deg,
            lat0_deg,
            m_per_deg_lon,
            m_per_deg_lat,
        }
    }

    /// Projection about the centre of a lon/lat box.
    pub fn centred_on(area: &LonLatBox) -> Self {
        let (lon, lat) = area.centre_deg();
        Self::new(lon, lat)
    }

    /// `(lon, lat)` degrees → `[x_m, y_m]` east/north of the origin.
    #[inline]
    pub fn to_local_m(&self, lon_deg: f64, lat_deg: f64) -> [f64; 2] {
        [
            (lon_deg - self.lon0_deg) * self.m_per_deg_lon,
            (lat_deg - self.lat0_deg) * self.m_per_deg_lat,
        ]
    }

    /// `[x_m, y_m]` → `(lon, lat)` degrees.
    #[inline]
    pub fn to_lon_lat_deg(&self, xy_m: [f64; 2]) -> (f64, f64) {
        (
            self.lon0_deg + xy_m[0] / self.m_per_deg_lon,
            self.lat0_deg + xy_m[1] / self.m_per_deg_lat,
        )
    }

    /// The rectangle (m) of a lon/lat box in this projection.
    pub fn box_m(&self, area: &LonLatBox) -> Bounds2 {
        let sw = self.to_local_m(area.lon_min_deg, area.lat_min_deg);
        let ne = self.to_local_m(area.lon_max_deg, area.lat_max_deg);
        Bounds2::new(sw[0], sw[1], ne[0], ne[1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn midtown_box_has_the_documented_size() {
        let area = dupac_common::config::ScenarioConfig::default().area;
        let p = LocalProjection::centred_on(&area);
        let b = p.box_m(&area);
        let (w, h) = (b.max_m.x - b.min_m.x, b.max_m.y - b.min_m.y);
        // spec/env.md: ≈ 1.43 × 1.33 km, ≈ 1.91 km² (the north edge at 40.7580: data/README.md).
        assert!((w - 1432.0).abs() < 5.0, "width {w}");
        assert!((h - 1332.0).abs() < 5.0, "height {h}");
        assert!(
            (b.min_m.x + b.max_m.x).abs() < 1e-6 && (b.min_m.y + b.max_m.y).abs() < 1e-6,
            "centred"
        );
    }

    #[test]
    fn one_degree_of_latitude_is_about_111_km_and_round_trips() {
        let p = LocalProjection::new(-73.985, 40.7525);
        let north = p.to_local_m(-73.985, 40.7525 + 0.01);
        // 111 132.92 − 559.82 cos 2φ + 1.175 cos 4φ − 0.0023 cos 6φ = 111 049.10 m/°.
        assert!((north[1] - 1110.49).abs() < 0.01, "{north:?}");
        let east = p.to_local_m(-73.985 + 0.01, 40.7525);
        // WGS84 series at 40.7525°: 111 412.84 cos φ − 93.5 cos 3φ + 0.118 cos 5φ = 84 449.09 m/°
        // (a sphere's 111.32 km · cos φ would give 843.3 m per 0.01°).
        assert!((east[0] - 844.49).abs() < 0.01, "{east:?}");
        let (lon, lat) = p.to_lon_lat_deg([123.4, -567.8]);
        let back = p.to_local_m(lon, lat);
        assert!((back[0] - 123.4).abs() < 1e-9 && (back[1] + 567.8).abs() < 1e-9);
    }
}
