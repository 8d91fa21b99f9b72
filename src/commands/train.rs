//! `dupac train`: by default a learner and actor processes over Zenoh on this machine
//! (`commands::orchestrate`, issue 5); with `--single-process`, PPO in one process (issue 4):
//! vectorised environments on worker threads, the burn update. Both write the same run
//! directory (metrics JSONL + CSV + learning-curve PNG, periodic held-out evaluation, atomic
//! checkpoints, `--resume`), with the helpers here.

use crate::GlobalArgs;
use crate::io::{write_atomic, write_atomic_with};
use crate::metrics_table::MetricsTable;
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use dupac_actor::pairs::{Pair, eval_pairs, read_pairs_jsonl, training_pool, write_pairs_jsonl};
use dupac_actor::planner::Planner;
use dupac_common::Config;
use dupac_common::config::Association;
use dupac_learner::checkpoint::{LoadedCheckpoint, load_checkpoint, save_policy};
use dupac_learner::train::{Learner, MetricsRow, Trainer, domain_stats, put_domain};
use dupac_radio::cache::{GridSpec, RsrpCache, RsrpSource};
use dupac_radio::world::RadioWorld;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

/// Which association the policy trains with (`env.association`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AssociationArg {
    /// DUPAC: the policy chooses the serving site.
    Learned,
    /// The paper's base method: A3 handover chooses it.
    A3,
}

/// The compute device of the learner.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DeviceArg {
    /// burn's `flex` CPU backend (default; always available).
    Cpu,
    /// burn's CUDA backend (build with `--features cuda`).
    Cuda,
    /// burn's wgpu backend (build with `--features wgpu`).
    Wgpu,
}

/// What every training process (`dupac train`, `dupac learner`) takes.
#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// `learned` (DUPAC) or `a3` (base method); default `env.association`.
    #[arg(long, value_enum)]
    pub association: Option<AssociationArg>,
    /// Output directory (default `train.out_dir`).
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Continue the run in `--out` from its `checkpoint.bin` (or from `--checkpoint FILE`).
    #[arg(long)]
    pub resume: bool,
    /// The checkpoint `--resume` starts from (default `<out>/checkpoint.bin`).
    #[arg(long, value_name = "FILE", requires = "resume")]
    pub checkpoint: Option<PathBuf>,
    #[arg(long, value_enum, default_value = "cpu")]
    pub device: DeviceArg,
}

#[derive(Args, Debug)]
pub struct TrainArgs {
    #[command(flatten)]
    pub run: RunArgs,
    /// Actor processes to start (default `distributed.actors`; 0 there = one per core).
    #[arg(long, value_name = "N")]
    pub actors: Option<usize>,
    /// Train in this one process (environments on worker threads; bit-reproducible from
    /// `train.seed`) instead of a learner and actor processes over Zenoh.
    #[arg(long, conflicts_with = "actors")]
    pub single_process: bool,
}

/// The burn device for `--device`.
pub fn device(arg: DeviceArg) -> Result<burn::tensor::Device> {
    match arg {
        DeviceArg::Cpu => Ok(burn::tensor::Device::flex()),
        #[cfg(feature = "cuda")]
        DeviceArg::Cuda => Ok(burn::tensor::Device::cuda(0)),
        #[cfg(feature = "wgpu")]
        DeviceArg::Wgpu => Ok(burn::tensor::Device::wgpu(
            burn::tensor::DeviceKind::DefaultDevice,
        )),
        #[allow(unreachable_patterns)]
        other => bail!(
            "--device {other:?}: this build has no such backend; rebuild with `--features {}`",
            format!("{other:?}").to_lowercase()
        ),
    }
}

/// The radio world and its RSRP source: the cache (built, or opened when fresh), or the world
/// itself with `env.radio_mode = "exact"`.
pub fn world_and_cache(
    cfg: &Config,
    quiet: bool,
) -> Result<(Arc<RadioWorld>, Arc<dyn RsrpSource + Send + Sync>)> {
    let world = Arc::new(RadioWorld::build(cfg).context("building the radio world")?);
    if cfg.env.radio_mode == dupac_common::config::RadioMode::Exact {
        let exact: Arc<dyn RsrpSource + Send + Sync> = world.clone();
        return Ok((world, exact));
    }
    let rows = GridSpec::covering(world.city.area_m, &cfg.cache).ny;
    let pb = super::progress_bar(rows as u64, "RSRP cache", quiet);
    let (cache, _) = RsrpCache::open_or_build(&world, &cfg.cache, &|n| pb.inc(n))?;
    pb.finish_and_clear();
    Ok((world, Arc::new(cache)))
}

/// The held-out evaluation pairs: `pairs.eval_file` when it exists, else generated and written
/// there.
pub fn held_out_pairs(cfg: &Config, planner: &Planner, quiet: bool) -> Result<Vec<Pair>> {
    let file = &cfg.pairs.eval_file;
    if file.exists() {
        return Ok(read_pairs_jsonl(file, planner, &cfg.pairs)?);
    }
    let total = (cfg.pairs.eval_bins_m.len() * cfg.pairs.eval_per_bin) as u64;
    let pb = super::progress_bar(total, "evaluation pairs", quiet);
    let pairs = eval_pairs(planner, &cfg.pairs, &cfg.env, &|n| pb.inc(n));
    pb.finish_and_clear();
    write_pairs_jsonl(file, &pairs)?;
    eprintln!("wrote {} held-out pairs to {}", pairs.len(), file.display());
    Ok(pairs)
}

/// The pairs of `file` (default `pairs.eval_file`, the held-out set), with the file named in
/// errors: what `dupac fly` and `dupac eval` fly.
pub fn read_eval_pairs(
    cfg: &Config,
    file: Option<&PathBuf>,
    planner: &Planner,
) -> Result<(PathBuf, Vec<Pair>)> {
    let file = file.cloned().unwrap_or_else(|| cfg.pairs.eval_file.clone());
    let pairs = read_pairs_jsonl(&file, planner, &cfg.pairs).with_context(|| {
        format!(
            "reading pairs {} (make them with `dupac pairs`)",
            file.display()
        )
    })?;
    Ok((file, pairs))
}

/// `n` pairs spread evenly over `pairs` (all bins represented).
pub fn spread(pairs: &[Pair], n: usize) -> Vec<Pair> {
    if n >= pairs.len() {
        return pairs.to_vec();
    }
    (0..n).map(|k| pairs[k * pairs.len() / n].clone()).collect()
}

/// The configuration of a training run: `--association` and `--out` applied.
pub fn resolve_config(
    global: &GlobalArgs,
    association: Option<AssociationArg>,
    out: Option<&PathBuf>,
) -> Result<Config> {
    let mut cfg = global.config()?;
    if let Some(a) = association {
        cfg.env.association = match a {
            AssociationArg::Learned => Association::Learned,
            AssociationArg::A3 => Association::A3,
        };
    }
    if let Some(out) = out {
        cfg.train.out_dir = out.clone();
    }
    Ok(cfg)
}

/// The checkpoint to resume from (`--resume [--checkpoint FILE]`), or an error when a run
/// already lives in the output directory and `--resume` was not given.
pub fn checkpoint_to_resume(
    cfg: &Config,
    resume: bool,
    checkpoint: Option<&PathBuf>,
) -> Result<Option<LoadedCheckpoint>> {
    let ck_path = cfg.train.out_dir.join("checkpoint.bin");
    if resume {
        let p = checkpoint.cloned().unwrap_or(ck_path);
        return Ok(Some(
            load_checkpoint(&p).with_context(|| format!("--resume {}", p.display()))?,
        ));
    }
    if ck_path.exists() {
        bail!(
            "{} exists: continue it with --resume, or choose another --out",
            ck_path.display()
        );
    }
    Ok(None)
}

/// A human name of the method a configuration trains.
pub fn method_name(cfg: &Config) -> &'static str {
    match cfg.env.association {
        Association::Learned => "DUPAC (learned association)",
        _ => "base method (A3 association)",
    }
}

/// The run directory: `config.toml`, `metrics.jsonl` (+ CSV), `checkpoint.bin`, `policy.bin`,
/// `curves.png`. A resumed run keeps the rows up to its checkpoint and continues the curve.
pub struct RunOutput {
    pub out: PathBuf,
    pub ck_path: PathBuf,
    metrics_path: PathBuf,
    rows: MetricsTable,
    metrics: std::fs::File,
    title: String,
    /// `<out>/.lock`, held exclusively while the run directory is in use (issue 16: one
    /// learner per run directory); released when the process ends, however it ends.
    _lock: std::fs::File,
}

/// Takes the exclusive lock of run directory `out` (`<out>/.lock`, `flock`), or says who holds
/// it. The lock dies with its process, so a crashed learner never leaves a stale one.
fn lock_run_dir(out: &std::path::Path) -> Result<std::fs::File> {
    use std::io::{Read, Seek, Write};
    let path = out.join(".lock");
    let mut f = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .with_context(|| format!("opening {}", path.display()))?;
    match f.try_lock() {
        Ok(()) => {}
        Err(std::fs::TryLockError::WouldBlock) => {
            let mut holder = String::new();
            let _ = f.read_to_string(&mut holder);
            anyhow::bail!(
                "{} is in use by another learner ({}); give this run another --out",
                out.display(),
                match holder.trim() {
                    "" => "process unknown".to_string(),
                    h => h.to_string(),
                }
            );
        }
        Err(std::fs::TryLockError::Error(e)) => {
            return Err(e).with_context(|| format!("locking {}", path.display()));
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
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(f)
}

impl RunOutput {
    pub fn open(cfg: &Config, start_update: u64, title: String) -> Result<RunOutput> {
        let out = cfg.train.out_dir.clone();
        std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
        let lock = lock_run_dir(&out)?;
        // The only writer of the directory now: whatever temporary files are here are the
        // leftovers of a killed process.
        dupac_common::fsio::sweep_temporaries(&out, std::time::Duration::ZERO)?;
        write_atomic(&out.join("config.toml"), cfg.to_toml_string().as_bytes())?;
        let metrics_path = out.join("metrics.jsonl");
        let mut rows = read_rows(&metrics_path)?;
        rows.retain(|r| r.get("update").copied().unwrap_or(0.0) <= start_update as f64);
        write_rows(&metrics_path, &rows)?;
        let rows = MetricsTable::from_rows(&rows);
        let metrics = std::fs::OpenOptions::new()
            .append(true)
            .create(true)
            .open(&metrics_path)
            .with_context(|| format!("opening {}", metrics_path.display()))?;
        Ok(RunOutput {
            ck_path: out.join("checkpoint.bin"),
            out,
            metrics_path,
            rows,
            metrics,
            title,
            _lock: lock,
        })
    }

    /// Appends one metrics row.
    pub fn push(&mut self, row: MetricsRow) -> Result<()> {
        writeln!(self.metrics, "{}", serde_json::to_string(&row)?)
            .with_context(|| format!("writing {}", self.metrics_path.display()))?;
        self.rows.push(&row);
        Ok(())
    }

    /// Checkpoint, exported policy, CSV and curves, each written atomically.
    pub fn checkpoint(&mut self, learner: &Learner) -> Result<()> {
        self.metrics.flush().ok();
        learner.save(&self.ck_path)?;
        save_policy(&self.out.join("policy.bin"), &learner.policy())?;
        write_csv(&self.out.join("metrics.csv"), &self.rows)?;
        crate::curves::render_curves(&self.rows, &self.title, &self.out.join("curves.png"))?;
        Ok(())
    }

    pub fn last(&self) -> MetricsRow {
        self.rows.last()
    }
}

/// Is a held-out evaluation due after update `update`?
pub fn eval_due(cfg: &Config, update: u64, last: bool) -> bool {
    last || (cfg.train.eval_every > 0 && update.is_multiple_of(cfg.train.eval_every))
}

/// The closing line of a training run.
pub fn summary_line(learner: &Learner, last: &MetricsRow) -> String {
    let g = |k: &str| last.get(k).copied().unwrap_or(f64::NAN);
    format!(
        "done: {} updates, {} timesteps (decisions), {:.0} s; held-out: success {:.1} %, collisions {:.1} %, overhead {:.1} %, mean RSRP {:.1} dBm, excellent {:.1} %, site regret {:.2} dB",
        learner.update,
        learner.global_step,
        learner.train_seconds,
        100.0 * g("eval/success_rate"),
        100.0 * g("eval/collision_rate"),
        100.0 * g("eval/distance_overhead"),
        g("eval/mean_rsrp_dbm"),
        g("eval/pct_excellent"),
        g("eval/site_regret_db"),
    )
}

/// The training pool (`train.pool_size` pairs from `train.seed`).
pub fn make_pool(cfg: &Config, planner: &Planner, quiet: bool) -> Result<Vec<Pair>> {
    let pb = super::progress_bar(cfg.train.pool_size as u64, "training pairs", quiet);
    let pool = training_pool(
        planner,
        &cfg.pairs,
        &cfg.env,
        cfg.train.pool_size,
        cfg.train.seed,
        &|n| pb.inc(n),
    );
    pb.finish_and_clear();
    if pool.is_empty() {
        bail!("no training pairs could be drawn: the city has no free pairs of pairs.min_m..max_m");
    }
    Ok(pool)
}

pub fn run(global: &GlobalArgs, args: &TrainArgs) -> Result<ExitCode> {
    if !args.single_process {
        return super::orchestrate::run(global, args);
    }
    let run = &args.run;
    let cfg = resolve_config(global, run.association, run.out.as_ref())?;
    let checkpoint = checkpoint_to_resume(&cfg, run.resume, run.checkpoint.as_ref())?;
    let device = device(run.device)?;
    let (world, rsrp) = world_and_cache(&cfg, global.quiet)?;
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let held_out = held_out_pairs(&cfg, &planner, global.quiet)?;
    let eval_set = spread(&held_out, cfg.train.eval_pairs);
    let pool = Arc::new(make_pool(&cfg, &planner, global.quiet)?);

    let mut trainer = match &checkpoint {
        Some(ck) => {
            eprintln!(
                "resuming at update {} ({} timesteps)",
                ck.meta.update, ck.meta.global_step
            );
            Trainer::resume(cfg.clone(), world.clone(), rsrp.clone(), pool, &device, ck)?
        }
        None => Trainer::new(cfg.clone(), world.clone(), rsrp.clone(), pool, &device)?,
    };
    let method = method_name(&cfg);
    let mut out = RunOutput::open(
        &cfg,
        trainer.update,
        format!("{method}, seed {}: {}", cfg.train.seed, world.city.name),
    )?;
    let total = trainer.num_updates() * trainer.batch_size() as u64;
    let pb = super::progress_bar(total, "timesteps", global.quiet);
    pb.set_position(trainer.global_step);
    eprintln!(
        "training {method} in one process: {} updates × {} samples, {} envs, seed {}",
        trainer.num_updates(),
        trainer.batch_size(),
        cfg.train.num_envs,
        cfg.train.seed
    );
    // Ctrl-C (SIGINT; SIGTERM too, through the ctrlc crate's termination feature): finish the
    // update in progress, write a checkpoint, exit 0 (docs/reliability.md).
    let stop = super::net::stop_flag()?;
    while !trainer.done() {
        let report = trainer.iteration()?;
        let mut row = report.row;
        let last = trainer.done();
        if eval_due(&cfg, trainer.update, last) {
            let eps = trainer.evaluate(&eval_set)?;
            put_domain(&mut row, "eval", &domain_stats(&eps));
        }
        pb.set_position(trainer.global_step);
        pb.set_message(progress_message(&row));
        if global.quiet {
            tracing::info!(?row, "update");
        }
        out.push(row)?;
        let interrupted = stop.load(std::sync::atomic::Ordering::Relaxed);
        if trainer.update.is_multiple_of(cfg.train.checkpoint_every) || last || interrupted {
            out.checkpoint(&trainer.learner)?;
        }
        if interrupted {
            pb.finish_and_clear();
            eprintln!(
                "interrupted at update {}: checkpoint written to {}; continue with --resume",
                trainer.update,
                out.ck_path.display()
            );
            return Ok(ExitCode::SUCCESS);
        }
    }
    pb.finish_and_clear();
    println!("{}", summary_line(&trainer.learner, &out.last()));
    eprintln!("wrote {}", out.out.display());
    Ok(ExitCode::SUCCESS)
}

/// The progress bar's message: return and success rate.
pub fn progress_message(row: &MetricsRow) -> String {
    format!(
        "ret {:.0} succ {:.0}%",
        row.get("charts/episodic_return")
            .copied()
            .unwrap_or(f64::NAN),
        100.0 * row.get("domain/success_rate").copied().unwrap_or(f64::NAN)
    )
}

fn read_rows(path: &Path) -> Result<Vec<MetricsRow>> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let mut rows = Vec::new();
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
            Err(_) if i + 1 == text.lines().count() => {}
            Err(e) => bail!("{}:{}: {e}", path.display(), i + 1),
        }
    }
    Ok(rows)
}

fn write_rows(path: &Path, rows: &[MetricsRow]) -> Result<()> {
    let mut text = String::new();
    for r in rows {
        text.push_str(&serde_json::to_string(r)?);
        text.push('\n');
    }
    write_atomic(path, text.as_bytes())
}

fn write_csv(path: &Path, rows: &MetricsTable) -> Result<()> {
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
    })
}
