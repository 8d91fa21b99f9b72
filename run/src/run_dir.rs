//! The run directory of a training run: `config.toml`, `metrics.jsonl` (+ `metrics.csv`),
//! `checkpoint.bin`, `policy.bin`, `curves.png`, and `.lock`. Every file is written through the
//! one atomic writer ([`dupac_common::fsio`]); a resumed run keeps the rows up to its checkpoint
//! and continues the curves.

use crate::error::{BoxError, Context, RunError};
use crate::metrics_table::MetricsTable;
use dupac_common::config::Config;
use dupac_common::fsio::{write_atomic_with, write_plain};
use dupac_common::metric;
use dupac_learner::checkpoint::{LoadedCheckpoint, load_checkpoint, save_policy};
use dupac_learner::learner::{Learner, MetricsRow};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Draws the learning curves of a run's rows into a PNG (`dupac_plot::curves::render_curves`,
/// passed in by the binary: neither crate depends on the other).
pub type CurveRenderer = Box<dyn Fn(&MetricsTable, &Path) -> Result<(), BoxError>>;

/// The checkpoint to resume from (`--resume [--checkpoint FILE]`), or an error when a run
/// already lives in the output directory and `--resume` was not given.
pub fn checkpoint_to_resume(
    cfg: &Config,
    resume: bool,
    checkpoint: Option<&PathBuf>,
) -> Result<Option<LoadedCheckpoint>, RunError> {
    let ck_path = cfg.train.out_dir.join("checkpoint.bin");
    if resume {
        let p = checkpoint.cloned().unwrap_or(ck_path);
        return Ok(Some(
            load_checkpoint(&p).context_with(|| format!("--resume {}", p.display()))?,
        ));
    }
    if ck_path.exists() {
        return Err(RunError::Refused(format!(
            "{} exists: continue it with --resume, or choose another --out",
            ck_path.display()
        )));
    }
    Ok(None)
}

/// An open run directory (see the module documentation).
pub struct RunOutput {
    pub out: PathBuf,
    pub ck_path: PathBuf,
    metrics_path: PathBuf,
    rows: MetricsTable,
    metrics: std::fs::File,
    /// The same rows as TensorBoard events (`events.out.tfevents.dupac`).
    events: crate::tensorboard::EventFile,
    curves: CurveRenderer,
    /// `<out>/.lock`, held exclusively while the run directory is in use (one
    /// learner per run directory); released when the process ends, however it ends.
    _lock: std::fs::File,
}

/// Fails, naming the holder, when a live learner holds run directory `out`'s lock; takes and
/// releases it otherwise. For a process that writes into the directory before its learner
/// starts (`dupac train` writes `config.toml` and the pool for its children), so that it never
/// overwrites a running run's files. Two such processes started at the same instant can both
/// pass; the learner's own lock still keeps one of them.
pub fn ensure_free(out: &Path) -> Result<(), RunError> {
    if out.is_dir() {
        lock_run_dir(out)?;
    }
    Ok(())
}

/// Takes the exclusive lock of run directory `out` (`<out>/.lock`, `flock`), or says who holds
/// it. The lock dies with its process, so a crashed learner never leaves a stale one.
fn lock_run_dir(out: &Path) -> Result<std::fs::File, RunError> {
    use std::io::{Read, Seek, Write};
    let path = out.join(".lock");
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .context_with(|| format!("opening {}", path.display()))?;
    match f.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => {
            let mut holder = String::new();
            let _ = f.read_to_string(&mut holder);
            return Err(RunError::Refused(format!(
                "{} is in use by another learner ({}); give this run another --out",
                out.display(),
                match holder.trim() {
                    "" => "process unknown".to_string(),
                    h => h.to_string(),
                }
            )));
        }
        Err(std::fs::TryLockError::Error(e)) => {
            return Err(e).context_with(|| format!("locking {}", path.display()));
        }
    }
    let me = format!(
        "pid {} on {}",
        std::process::id(),
        std::fs::read_to_string("/proc/sys/kernel/hostname")
            .map(|h| h.trim().to_string())
            .unwrap_or_else(|_| "this host".into())
    );
    f.set_len(0)
        .and_then(|()| f.rewind())
        .and_then(|()| f.write_all(me.as_bytes()))
        .context_with(|| format!("writing {}", path.display()))?;
    Ok(f)
}

impl RunOutput {
    /// Opens (creates, locks, sweeps) `train.out_dir` for a run at update `start_update`;
    /// `curves` draws `curves.png` at each checkpoint.
    pub fn open(
        cfg: &Config,
        start_update: u64,
        curves: CurveRenderer,
    ) -> Result<RunOutput, RunError> {
        let out = cfg.train.out_dir.clone();
        std::fs::create_dir_all(&out).context_with(|| format!("creating {}", out.display()))?;
        let lock = lock_run_dir(&out)?;
        // The only writer of the directory now: whatever temporary files are here are the
        // leftovers of a killed process.
        dupac_common::fsio::sweep_temporaries(&out, std::time::Duration::ZERO)?;
        write_plain(&out.join("config.toml"), cfg.to_toml_string().as_bytes())?;
        let metrics_path = out.join("metrics.jsonl");
        let mut rows = read_rows(&metrics_path)?;
        rows.retain(|r| r.get(metric::UPDATE).copied().unwrap_or(0.0) <= start_update as f64);
        write_rows(&metrics_path, &rows)?;
        let events = crate::tensorboard::EventFile::create(&out, &rows)?;
        let rows = MetricsTable::from_rows(&rows);
        let metrics = std::fs::OpenOptions::new()
            .append(true)
            .create(true)
            .open(&metrics_path)
            .context_with(|| format!("opening {}", metrics_path.display()))?;
        Ok(RunOutput {
            ck_path: out.join("checkpoint.bin"),
            out,
            metrics_path,
            rows,
            metrics,
            events,
            curves,
            _lock: lock,
        })
    }

    /// Appends one metrics row.
    pub fn push(&mut self, row: MetricsRow) -> Result<(), RunError> {
        let line = serde_json::to_string(&row).context("encoding a metrics row")?;
        writeln!(self.metrics, "{line}")
            .context_with(|| format!("writing {}", self.metrics_path.display()))?;
        self.events.push(&row)?;
        self.rows.push(&row);
        Ok(())
    }

    /// Checkpoint, exported policy, CSV and curves, each written atomically.
    pub fn checkpoint(&mut self, learner: &Learner) -> Result<(), RunError> {
        self.metrics.flush().ok();
        self.events.flush();
        learner.save(&self.ck_path)?;
        save_policy(&self.out.join("policy.bin"), &learner.policy())?;
        write_csv(&self.out.join("metrics.csv"), &self.rows)?;
        (self.curves)(&self.rows, &self.out.join("curves.png")).map_err(RunError::Plot)?;
        Ok(())
    }

    pub fn last(&self) -> MetricsRow {
        self.rows.last()
    }
}

fn read_rows(path: &Path) -> Result<Vec<MetricsRow>, RunError> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text =
        std::fs::read_to_string(path).context_with(|| format!("reading {}", path.display()))?;
    let mut rows = Vec::new();
    let n = text.lines().count();
    for (i, line) in text.lines().enumerate() {
        if line.trim().is_empty() {
            continue;
        }
        // Non-finite values are written as `null` by serde_json (NaN has no JSON form).
        match serde_json::from_str::<std::collections::BTreeMap<String, Option<f64>>>(line) {
            Ok(r) => rows.push(
                r.into_iter()
                    .map(|(k, v)| (k, v.unwrap_or(f64::NAN)))
                    .collect(),
            ),
            // A line cut by a crash is dropped; anything else is an error.
            Err(_) if i + 1 == n => {}
            Err(e) => {
                return Err(RunError::Refused(format!(
                    "{}:{}: {e}",
                    path.display(),
                    i + 1
                )));
            }
        }
    }
    Ok(rows)
}

fn write_rows(path: &Path, rows: &[MetricsRow]) -> Result<(), RunError> {
    let mut text = String::new();
    for r in rows {
        text.push_str(&serde_json::to_string(r).context("encoding a metrics row")?);
        text.push('\n');
    }
    Ok(write_plain(path, text.as_bytes())?)
}

fn write_csv(path: &Path, rows: &MetricsTable) -> Result<(), RunError> {
    let keys = rows.columns_sorted();
    write_atomic_with(path, |w| {
        let mut c = csv::Writer::from_writer(w);
        c.write_record(&keys)?;
        for i in 0..rows.len() {
            c.write_record(keys.iter().map(|k| {
                let v = rows.get(i, k);
                if v.is_nan() {
                    String::new()
                } else {
                    format!("{v}")
                }
            }))?;
        }
        c.flush()
    })?;
    Ok(())
}
