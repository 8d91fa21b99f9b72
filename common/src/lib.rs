//! The contract shared by every DUPAC process: typed ids, the one TOML configuration, key
//! expressions, messages and their codecs (binary for data, JSON for stats and control), the
//! exported policy and the observation layout.
//!
//! Units are in names (`_m`, `_dbm`, `_deg`, `_ghz`) and the frame is east-north-up metres with
//! the origin at the scenario centre (x east, y north, z up = height above flat ground).

pub mod budget;
pub mod codec;
pub mod compact;
pub mod config;
pub mod dedup;
pub mod episode;
pub mod fault;
pub mod fingerprint;
pub mod fsio;
pub mod geometry;
pub mod ids;
pub mod jsonmsg;
pub mod keys;
pub mod metric;
pub mod msg;
pub mod normalize;
pub mod obs;
pub mod policy;
pub mod seed;
pub mod validate;
