//! DUPAC's figures, all in one style: coverage maps ([`coverage`], paper Fig. 2(b)), a pair's
//! flights over the city with their altitude and RSRP profiles ([`plan`]), the learning curves
//! of a run directory ([`curves`]) and the evaluation's figures ([`eval`], paper Fig. 3 and 4).
//! Every PNG is written atomically through [`dupac_common::fsio`]; RSRP classes are coloured
//! from the configured thresholds ([`class_bands`], [`style`]); the text is the bundled DejaVu Sans.

pub mod coverage;
pub mod curves;
pub(crate) mod draw;
pub mod error;
pub mod eval;
pub mod plan;
pub(crate) mod style;

pub use style::{class_bands, ensure_font};
