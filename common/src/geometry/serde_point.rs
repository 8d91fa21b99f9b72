//! Serde for a [`Point`] as the `[x, y, z]` array that files and messages have always held
//! (`#[serde(with = "dupac_common::geometry::serde_point")]`): the formats do not depend on how
//! nalgebra serialises.

use super::Point;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

pub fn serialize<S: Serializer>(p: &Point, s: S) -> Result<S::Ok, S::Error> {
    [p.x, p.y, p.z].serialize(s)
}

pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Point, D::Error> {
    <[f64; 3]>::deserialize(d).map(Point::from)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize, Deserialize, PartialEq, Debug)]
    struct Holder {
        #[serde(with = "super")]
        p: Point,
    }

    #[test]
    fn a_point_is_stored_as_the_array_it_was() {
        let h = Holder {
            p: Point::new(1.5, -2.0, 30.0),
        };
        let json = serde_json::to_string(&h).unwrap();
        assert_eq!(json, r#"{"p":[1.5,-2.0,30.0]}"#);
        #[derive(Serialize)]
        struct Old {
            p: [f64; 3],
        }
        let old = Old {
            p: [1.5, -2.0, 30.0],
        };
        let cfg = bincode::config::standard();
        assert_eq!(
            bincode::serde::encode_to_vec(&h, cfg).unwrap(),
            bincode::serde::encode_to_vec(&old, cfg).unwrap()
        );
        assert_eq!(serde_json::from_str::<Holder>(&json).unwrap(), h);
    }
}
