//! The one integration-test binary of the `dupac` command (ripgrep's layout): end-to-end tests of
//! real processes, the real Midtown data and real files, one module per area, all built on
//! [`support::dupac_cmd`]. Run one area with `cargo test --test it cli::` (or `train::`, `eval::`,
//! `deploy::`, `distributed::`, `faults::`, `fronts::`, `hotspots::`, `netns::`, `scenario::`, `security::`, `soak::`,
//! `splits::`, `tune::`,
//! `usage::`).

mod cli;
mod deploy;
mod distributed;
mod eval;
mod faults;
mod fronts;
mod hotspots;
mod netns;
mod scenario;
mod security;
mod soak;
mod splits;
mod support;
mod train;
mod tune;
mod usage;
