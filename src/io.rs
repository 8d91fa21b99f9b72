//! Small file helpers shared by the subcommands: checks of the files and pairs a command is
//! given, before any work. Files are written through [`dupac_common::fsio`].

use anyhow::Result;
use std::path::Path;

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
