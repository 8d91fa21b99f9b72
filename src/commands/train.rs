//! `dupac train`: PPO in one process (issue 4): vectorised environments on worker threads, the
//! burn update, metrics (JSONL + CSV + learning-curve PNG), periodic held-out evaluation,
//! atomic checkpoints, `--resume`.

use crate::GlobalArgs;
use crate::io::{write_atomic, write_atomic_with};
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use dupac_actor::pairs::{Pair, eval_pairs, read_pairs_jsonl, training_pool, write_pairs_jsonl};
use dupac_actor::planner::Planner;
use dupac_common::Config;
use dupac_common::config::Association;
use dupac_learner::checkpoint::{load_checkpoint, save_policy};
use dupac_learner::train::{MetricsRow, Trainer, domain_stats, put_domain};
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

#[derive(Args, Debug)]
pub struct TrainArgs {
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

/// `n` pairs spread evenly over `pairs` (all bins represented).
pub fn spread(pairs: &[Pair], n: usize) -> Vec<Pair> {
    if n >= pairs.len() {
        return pairs.to_vec();
    }
    (0..n).map(|k| pairs[k * pairs.len() / n].clone()).collect()
}

pub fn run(global: &GlobalArgs, args: &TrainArgs) -> Result<ExitCode> {
    let mut cfg = global.config()?;
    if let Some(a) = args.association {
        cfg.env.association = match a {
            AssociationArg::Learned => Association::Learned,
            AssociationArg::A3 => Association::A3,
        };
    }
    if let Some(out) = &args.out {
        cfg.train.out_dir = out.clone();
    }
    let out = cfg.train.out_dir.clone();
    let ck_path = out.join("checkpoint.bin");
    let resume_from = args
        .resume
        .then(|| args.checkpoint.clone().unwrap_or_else(|| ck_path.clone()));
    let checkpoint = match &resume_from {
        Some(p) => Some(load_checkpoint(p).with_context(|| format!("--resume {}", p.display()))?),
        None => None,
    };
    if checkpoint.is_none() && ck_path.exists() {
        bail!(
            "{} exists: continue it with --resume, or choose another --out",
            ck_path.display()
        );
    }
    let device = device(args.device)?;
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    write_atomic(&out.join("config.toml"), cfg.to_toml_string().as_bytes())?;

    let (world, rsrp) = world_and_cache(&cfg, global.quiet)?;
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let held_out = held_out_pairs(&cfg, &planner, global.quiet)?;
    let eval_set = spread(&held_out, cfg.train.eval_pairs);
    let pb = super::progress_bar(cfg.train.pool_size as u64, "training pairs", global.quiet);
    let pool = training_pool(
        &planner,
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
    let pool = Arc::new(pool);

    let mut trainer = match &checkpoint {
        Some(ck) => {
            eprintln!(
                "resuming at update {} ({} env steps)",
                ck.meta.update, ck.meta.global_step
            );
            Trainer::resume(cfg.clone(), world.clone(), rsrp.clone(), pool, &device, ck)?
        }
        None => Trainer::new(cfg.clone(), world.clone(), rsrp.clone(), pool, &device)?,
    };
    // Metrics: a resumed run keeps the rows up to its checkpoint and continues the curve.
    let metrics_path = out.join("metrics.jsonl");
    let mut rows = read_rows(&metrics_path)?;
    rows.retain(|r| r.get("update").copied().unwrap_or(0.0) <= trainer.update as f64);
    write_rows(&metrics_path, &rows)?;
    let mut metrics = std::fs::OpenOptions::new()
        .append(true)
        .create(true)
        .open(&metrics_path)
        .with_context(|| format!("opening {}", metrics_path.display()))?;

    let total = trainer.num_updates() * trainer.batch_size() as u64;
    let pb = super::progress_bar(total, "env steps", global.quiet);
    pb.set_position(trainer.global_step);
    let method = match cfg.env.association {
        Association::Learned => "DUPAC (learned association)",
        _ => "base method (A3 association)",
    };
    eprintln!(
        "training {method}: {} updates × {} samples, {} envs, seed {}",
        trainer.num_updates(),
        trainer.batch_size(),
        cfg.train.num_envs,
        cfg.train.seed
    );
    while !trainer.done() {
        let report = trainer.iteration()?;
        let mut row = report.row;
        let last = trainer.done();
        let eval_due =
            cfg.train.eval_every > 0 && trainer.update.is_multiple_of(cfg.train.eval_every);
        if eval_due || last {
            let eps = trainer.evaluate(&eval_set)?;
            put_domain(&mut row, "eval", &domain_stats(&eps));
        }
        writeln!(metrics, "{}", serde_json::to_string(&row)?)
            .with_context(|| format!("writing {}", metrics_path.display()))?;
        pb.set_position(trainer.global_step);
        pb.set_message(format!(
            "ret {:.0} succ {:.0}%",
            row.get("charts/episodic_return")
                .copied()
                .unwrap_or(f64::NAN),
            100.0 * row.get("domain/success_rate").copied().unwrap_or(f64::NAN)
        ));
        rows.push(row.clone());
        if global.quiet {
            tracing::info!(?row, "update");
        }
        if trainer.update.is_multiple_of(cfg.train.checkpoint_every) || last {
            metrics.flush().ok();
            trainer.save(&ck_path)?;
            save_policy(&out.join("policy.bin"), &trainer.policy())?;
            write_csv(&out.join("metrics.csv"), &rows)?;
            crate::curves::render_curves(
                &rows,
                &format!("{method}, seed {}: {}", cfg.train.seed, world.city.name),
                &out.join("curves.png"),
            )?;
        }
    }
    pb.finish_and_clear();
    let last = rows.last().cloned().unwrap_or_default();
    let g = |k: &str| last.get(k).copied().unwrap_or(f64::NAN);
    println!(
        "done: {} updates, {} env steps, {:.0} s; held-out: success {:.1} %, collisions {:.1} %, overhead {:.1} %, mean RSRP {:.1} dBm, excellent {:.1} %",
        trainer.update,
        trainer.global_step,
        trainer.train_seconds,
        100.0 * g("eval/success_rate"),
        100.0 * g("eval/collision_rate"),
        100.0 * g("eval/distance_overhead"),
        g("eval/mean_rsrp_dbm"),
        g("eval/pct_excellent"),
    );
    eprintln!("wrote {}", out.display());
    Ok(ExitCode::SUCCESS)
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

fn write_csv(path: &Path, rows: &[MetricsRow]) -> Result<()> {
    let mut keys: Vec<&String> = rows.iter().flat_map(|r| r.keys()).collect();
    keys.sort();
    keys.dedup();
    write_atomic_with(path, |w| {
        let mut c = csv::Writer::from_writer(w);
        c.write_record(keys.iter().map(|k| k.as_str()))?;
        for r in rows {
            c.write_record(
                keys.iter()
                    .map(|k| r.get(*k).map(|v| format!("{v}")).unwrap_or_default()),
            )?;
        }
        c.flush()
    })
}
