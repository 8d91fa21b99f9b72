//! `dupac scenario import`: raw OpenStreetMap buildings and an OpenCelliD cell table, cut to a
//! lon/lat box, into a scenario directory the loaders read (`docs/scenario.md`).

pub mod opencellid;
pub mod osm;
pub mod osm_raw;
pub mod scenario;
pub mod tags;
