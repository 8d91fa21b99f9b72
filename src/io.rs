//! Small file helpers shared by the subcommands: the one atomic writer
//! ([`dupac_common::fsio`]) with `anyhow` errors.

use anyhow::Result;
use std::io::Write;
use std::path::Path;

/// Writes `bytes` to `path` atomically ([`dupac_common::fsio::write_atomic_with`]: temporary
/// file, fsync, 0644, rename, directory fsync), so an interrupted run never leaves a truncated
/// file behind.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Like [`write_atomic`], with the content produced by a writer callback.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    Ok(dupac_common::fsio::write_atomic_with(path, fill)?)
}
