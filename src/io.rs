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

/// Refuses, before any work, a file named by the option `flag` that cannot be opened for
/// reading (missing, a directory, no permission).
pub fn check_readable(flag: &str, path: &Path) -> Result<()> {
    let refuse = |why: String| anyhow::anyhow!("{flag} {}: {why}", path.display());
    if path.is_dir() {
        return Err(refuse("is a directory, not a file".into()));
    }
    std::fs::File::open(path).map_err(|e| refuse(format!("cannot read: {e}")))?;
    Ok(())
}

/// Refuses, before any work, `--pair INDEX` past the end of the pairs file `path` (one pair a
/// non-blank line, counted from 0); the file's contents are judged when it is read. With
/// `held_out` (the default held-out file, drawn when missing), a missing `path` holds that
/// configuration's `pairs.eval_bins_m × pairs.eval_per_bin` pairs.
pub fn check_pair_index(
    path: &Path,
    index: usize,
    held_out: Option<&dupac_common::config::Config>,
) -> Result<()> {
    use std::io::BufRead;
    if let Some(cfg) = held_out.filter(|_| !path.exists()) {
        let n = cfg.pairs.eval_bins_m.len() * cfg.pairs.eval_per_bin;
        if index >= n {
            anyhow::bail!(
                "--pair {index}: the held-out set ({}, drawn on first use) has {n} pairs",
                path.display()
            );
        }
        return Ok(());
    }
    let file = std::fs::File::open(path).map_err(|e| {
        anyhow::anyhow!(
            "cannot read pairs file {}: {e} (make one with `dupac pairs`)",
            path.display()
        )
    })?;
    let mut pairs = 0usize;
    for line in std::io::BufReader::new(file).split(b'\n') {
        let line = line.map_err(|e| anyhow::anyhow!("reading {}: {e}", path.display()))?;
        if !line.trim_ascii().is_empty() {
            pairs += 1;
            if pairs > index {
                return Ok(());
            }
        }
    }
    anyhow::bail!(
        "{}: --pair {index} but the file has {pairs} pairs (--pair counts from 0)",
        path.display()
    )
}
