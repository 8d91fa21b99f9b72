//! The default (Midtown) scenario's data files, built into the binary: a process started in
//! any directory, with the default `scenario.buildings_file` and `scenario.cells_file`, finds
//! the city without the repository's `data/` folder.
//!
//! [`read`] reads a scenario file from disk; only when the path is one of the default paths
//! ([`MIDTOWN_BUILDINGS_FILE`], [`MIDTOWN_CELLS_FILE`], relative to the working directory) and
//! no file is there does it return the built-in copy, logging so at `info`. A file that exists
//! is always read, also at a default path, and any other path that cannot be read is an error
//! naming it. Both ways give the same world fingerprint when the files are the same, so hosts
//! that use the built-in copy and hosts that read `data/` train together; a changed file gives
//! another fingerprint (and the actors of another world are refused).
//!
//! The copies are `data/nyc_midtown_buildings.geojson` (© OpenStreetMap contributors, ODbL
//! 1.0) and `data/nyc_midtown_cells.csv` (radiocells.org, ODbL) as of the build: see
//! `data/ATTRIBUTION.md`.

use crate::error::RadioError;
use dupac_common::config::{MIDTOWN_BUILDINGS_FILE, MIDTOWN_CELLS_FILE};
use std::borrow::Cow;
use std::path::Path;

/// `data/nyc_midtown_buildings.geojson` as of the build (2.3 MB).
static MIDTOWN_BUILDINGS: &[u8] = include_bytes!("../../data/nyc_midtown_buildings.geojson");
/// `data/nyc_midtown_cells.csv` as of the build (5 KB).
static MIDTOWN_CELLS: &[u8] = include_bytes!("../../data/nyc_midtown_cells.csv");

/// Where a scenario file's bytes came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// The file on disk at the configured path.
    Disk,
    /// The copy built into the binary (the default path, no file there).
    BuiltIn,
}

/// The built-in copy of the file a default scenario path names, if `path` is one.
pub fn builtin(path: &Path) -> Option<&'static [u8]> {
    if path == Path::new(MIDTOWN_BUILDINGS_FILE) {
        Some(MIDTOWN_BUILDINGS)
    } else if path == Path::new(MIDTOWN_CELLS_FILE) {
        Some(MIDTOWN_CELLS)
    } else {
        None
    }
}

/// Reads the scenario file at `path` (relative to the working directory, as every path of the
/// configuration); when it does not exist and `path` is a default scenario path, the built-in
/// copy. Errors name the file.
pub fn read(path: &Path) -> Result<(Cow<'static, [u8]>, Source), RadioError> {
    match std::fs::read(path) {
        Ok(bytes) => Ok((Cow::Owned(bytes), Source::Disk)),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => match builtin(path) {
            Some(bytes) => {
                let cwd = std::env::current_dir()
                    .map(|d| d.display().to_string())
                    .unwrap_or_else(|_| "?".into());
                tracing::info!(
                    "no {} in {cwd}: using the copy built into this binary ({} bytes)",
                    path.display(),
                    bytes.len()
                );
                Ok((Cow::Borrowed(bytes), Source::BuiltIn))
            }
            None => Err(RadioError::io(path, e)),
        },
        Err(e) => Err(RadioError::io(path, e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_paths_fall_back_to_the_built_in_copies_and_others_do_not() {
        let dir = tempfile::tempdir().unwrap();
        // Paths that do not exist in the test's working directory (the crate's folder).
        let absent = dir.path().join(MIDTOWN_BUILDINGS_FILE);
        assert!(matches!(read(&absent), Err(RadioError::Io { .. })));
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        assert!(!root.join(MIDTOWN_BUILDINGS_FILE).exists());
        let (b, src) = read(Path::new(MIDTOWN_BUILDINGS_FILE)).unwrap();
        assert_eq!(src, Source::BuiltIn);
        let on_disk = std::fs::read(root.join("..").join(MIDTOWN_BUILDINGS_FILE)).unwrap();
        assert_eq!(b.as_ref(), on_disk.as_slice());
        let (c, src) = read(Path::new(MIDTOWN_CELLS_FILE)).unwrap();
        assert_eq!(src, Source::BuiltIn);
        let on_disk = std::fs::read(root.join("..").join(MIDTOWN_CELLS_FILE)).unwrap();
        assert_eq!(c.as_ref(), on_disk.as_slice());
        // `./data/…` is another spelling, not the default path: no fallback.
        let dotted = Path::new(".").join(MIDTOWN_CELLS_FILE);
        let err = read(&dotted).unwrap_err().to_string();
        assert!(err.contains("nyc_midtown_cells.csv"), "{err}");
    }
}
