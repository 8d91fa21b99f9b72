//! Errors of the radio crate. Every variant names the file, line, feature or field at fault.

use dupac_common::geometry::Point;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum RadioError {
    #[error("cannot read {path}: {cause}")]
    Io {
        path: PathBuf,
        /// The OS error, part of this error's message (not its `source()`, so that a printed
        /// chain shows it once).
        cause: std::io::Error,
    },
    #[error("{path}: not valid GeoJSON: {message}")]
    GeoJson { path: PathBuf, message: String },
    #[error("{path}: feature {index} ({id}): {message}")]
    Feature {
        path: PathBuf,
        index: usize,
        id: String,
        message: String,
    },
    /// A raw OpenStreetMap file (PBF, XML, Overpass JSON) that cannot be read; `at` is the
    /// line and column, the element (`way/12`) or the PBF blob.
    #[error("{path}: {at}: {message}")]
    OsmFile {
        path: PathBuf,
        at: String,
        message: String,
    },
    #[error("{path}: no usable buildings inside the scenario area")]
    NoBuildings { path: PathBuf },
    #[error("{path}:{line}: {message}")]
    Table {
        path: PathBuf,
        line: u64,
        message: String,
    },
    #[error("{path}: {message}")]
    Sites { path: PathBuf, message: String },
    #[error("building mesh: {0}")]
    Mesh(String),
    #[error("position {what} = {value:?} is {message}")]
    Position {
        what: &'static str,
        value: Point,
        message: String,
    },
    #[error("cache {path}: {message}")]
    Cache { path: PathBuf, message: String },
    #[error("scenario import: {message}")]
    Import { message: String },
    #[error(transparent)]
    Write(#[from] dupac_common::fsio::FsError),
}

impl RadioError {
    pub(crate) fn io(path: impl Into<PathBuf>, cause: std::io::Error) -> Self {
        RadioError::Io {
            path: path.into(),
            cause,
        }
    }
}
