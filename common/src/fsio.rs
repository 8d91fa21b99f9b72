//! The one atomic file writer of DUPAC: every result, checkpoint, cache, pairs file
//! and figure is written through [`write_atomic_with`] ([`write_atomic`] for checkpoints and
//! policies, with a crash point; [`write_plain`] for the rest; [`write_atomic_via_path`] for
//! encoders that write a path of their own).
//!
//! A write goes to a temporary file in the target's directory (a unique random name holding
//! [`TMP_MARK`], so two processes on a shared volume never collide), is flushed and `fsync`ed,
//! given ordinary permissions (0644: tempfile creates 0600), renamed over the target, and the
//! directory is `fsync`ed so that the rename itself survives a power loss. A crash leaves the
//! old file or the new one, never a mix; a killed process may leave a temporary file, which
//! [`sweep_temporaries`] removes at the next start.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Part of every temporary file's name: `.<target name>.dupac-tmp.<random>`.
pub const TMP_MARK: &str = ".dupac-tmp.";

/// A failed file operation, naming the file and the step.
#[derive(Debug, thiserror::Error)]
#[error("{op} {path}: {cause}")]
pub struct FsError {
    pub op: &'static str,
    pub path: PathBuf,
    /// The OS error, part of this error's message (not its `source()`, so that a printed
    /// chain shows it once).
    pub cause: std::io::Error,
}

fn at<'a>(op: &'static str, path: &'a Path) -> impl FnOnce(std::io::Error) -> FsError + 'a {
    move |cause| FsError {
        op,
        path: path.to_path_buf(),
        cause,
    }
}

/// The directory a file of `path` lives in (`.` for a bare name).
fn parent(path: &Path) -> &Path {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Writes `bytes` to `path` atomically (see the module documentation).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), FsError> {
    write_atomic_with(path, |w| {
        let (first, second) = bytes.split_at(bytes.len() / 2);
        w.write_all(first)?;
        // Crash tests abort here, half-way through the content (`DUPAC_FAULT=atomic-write:n`).
        crate::fault::crash_point("atomic-write");
        w.write_all(second)
    })
}

/// Writes `bytes` to `path` atomically like [`write_atomic`], without its `atomic-write` crash
/// point, which the reliability tests count in checkpoints and policies only: what results,
/// tables, metrics rows and records are written with.
pub fn write_plain(path: &Path, bytes: &[u8]) -> Result<(), FsError> {
    write_atomic_with(path, |w| w.write_all(bytes))
}

/// Writes what `fill` produces to `path` atomically; parent directories are created.
pub fn write_atomic_with(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), FsError> {
    let mut tmp = temporary_beside(path, "")?;
    {
        let mut w = std::io::BufWriter::with_capacity(1 << 20, tmp.as_file_mut());
        fill(&mut w).map_err(at("writing", path))?;
        w.flush().map_err(at("writing", path))?;
    }
    commit(tmp, path)
}

/// Writes `path` atomically through a tool that can only write to a path of its own (an image
/// encoder): `draw` writes the temporary path it is given, which is then committed like
/// [`write_atomic_with`]'s.
pub fn write_atomic_via_path(
    path: &Path,
    draw: impl FnOnce(&Path) -> std::io::Result<()>,
) -> Result<(), FsError> {
    // Keep the extension last: encoders choose the format by it.
    let ext = path
        .extension()
        .map(|e| format!(".{}", e.to_string_lossy()))
        .unwrap_or_default();
    let tmp = temporary_beside(path, &ext)?;
    draw(tmp.path()).map_err(at("writing", path))?;
    commit(tmp, path)
}

/// A new temporary file in `path`'s directory (created), named `.<name>.dupac-tmp.<random><suffix>`.
fn temporary_beside(path: &Path, suffix: &str) -> Result<tempfile::NamedTempFile, FsError> {
    let dir = parent(path);
    std::fs::create_dir_all(dir).map_err(at("creating directory", dir))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "file".into());
    tempfile::Builder::new()
        .prefix(&format!(".{name}{TMP_MARK}"))
        .suffix(suffix)
        .tempfile_in(dir)
        .map_err(at("creating a temporary file in", dir))
}

/// Syncs the written temporary file (reopened by path: a tool may have replaced it), gives it
/// 0644 (tempfile creates 0600), renames it over `path` and syncs the directory.
fn commit(tmp: tempfile::NamedTempFile, path: &Path) -> Result<(), FsError> {
    std::fs::File::open(tmp.path())
        .and_then(|f| f.sync_all())
        .map_err(at("syncing", path))?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o644))
            .map_err(at("setting permissions of", path))?;
    }
    tmp.persist(path)
        .map_err(|e| at("renaming into", path)(e.error))?;
    let dir = parent(path);
    sync_dir(dir).map_err(at("syncing directory", dir))
}

/// `fsync` of a directory: makes a rename or a new file in it durable.
pub fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::fs::File::open(dir)?.sync_all()
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
        Ok(())
    }
}

/// Removes the temporary files of interrupted atomic writes in `dir` last modified more than
/// `min_age` ago (zero when the caller holds the directory's lock and is its only writer; more
/// where another process may be writing now). Returns the number removed; a missing directory
/// is none.
pub fn sweep_temporaries(dir: &Path, min_age: Duration) -> Result<usize, FsError> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(at("listing", dir)(e)),
    };
    let mut removed = 0;
    for e in entries.flatten() {
        let name = e.file_name();
        if !name.to_string_lossy().contains(TMP_MARK) {
            continue;
        }
        let old = e
            .metadata()
            .and_then(|m| m.modified())
            .ok()
            .and_then(|t| t.elapsed().ok())
            .is_some_and(|age| age >= min_age);
        if old && std::fs::remove_file(e.path()).is_ok() {
            tracing::info!(file = %e.path().display(), "removed the temporary file of an interrupted write");
            removed += 1;
        }
    }
    Ok(removed)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_replace_whole_files_with_readable_permissions() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("sub/out.txt");
        write_atomic(&p, b"first").expect("write");
        write_atomic(&p, b"second, longer").expect("write");
        assert_eq!(std::fs::read(&p).expect("read"), b"second, longer");
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&p).expect("meta").permissions().mode();
            assert_eq!(mode & 0o777, 0o644);
        }
        let names: Vec<String> = std::fs::read_dir(p.parent().expect("dir"))
            .expect("ls")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, vec!["out.txt".to_string()], "no temporary left");
    }

    #[test]
    fn a_failed_write_keeps_the_old_file_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("out.bin");
        write_atomic(&p, b"old").expect("write");
        let e = write_atomic_with(&p, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("disk on fire"))
        })
        .expect_err("fails");
        assert!(e.to_string().contains("out.bin") && e.to_string().contains("disk on fire"));
        assert_eq!(std::fs::read(&p).expect("read"), b"old");
        assert_eq!(std::fs::read_dir(dir.path()).expect("ls").count(), 1);
    }

    #[test]
    fn leftovers_are_swept_by_age_and_nothing_else() {
        let dir = tempfile::tempdir().expect("tmp");
        let keep = dir.path().join("checkpoint.bin");
        std::fs::write(&keep, b"x").expect("write");
        let left = dir.path().join(format!(".checkpoint.bin{TMP_MARK}a1b2c3"));
        std::fs::write(&left, b"half").expect("write");
        assert_eq!(
            sweep_temporaries(dir.path(), Duration::from_secs(3600)).expect("sweep"),
            0,
            "a fresh temporary may be another process's write in progress"
        );
        assert_eq!(
            sweep_temporaries(dir.path(), Duration::ZERO).expect("sweep"),
            1
        );
        assert!(keep.exists() && !left.exists());
        assert_eq!(
            sweep_temporaries(&dir.path().join("absent"), Duration::ZERO).expect("none"),
            0
        );
    }
}
