//! The radio world of DUPAC: the city the UAV flies through (for line of sight), the 3GPP
//! TR 36.777 / TR 38.901 path loss, the TR 38.901 sector antenna with a vertical array, RSRP,
//! coverage maps, the per-site RSRP cache and the A3 handover rule.
//!
//! Everything implements `spec/radio.md` (copied into `docs/spec/radio.md`); section numbers in
//! doc comments refer to it. Frame: east-north-up metres, x east, y north, z = height above flat
//! ground, origin at the scenario centre. Radio maths is `f64`; the building mesh is `f32`
//! (parry3d) and converted at the geometry boundary ([`city::CityMesh`]).

pub mod a3;
pub mod antenna;
pub mod bundled;
pub mod cache;
pub mod channel;
pub mod city;
pub mod class;
pub mod coverage;
pub mod error;
pub mod geo;
pub mod import;
pub mod link;
pub mod link_calc;
pub mod pathloss;
pub mod shadow;
pub mod sites;
pub mod source;
pub mod world;
