//! Arguments every training process shares (`dupac train`, `dupac learner`, `dupac actor`,
//! `dupac fly`), resolved into the one configuration.

use crate::GlobalArgs;
use anyhow::{Result, bail};
use clap::{Args, ValueEnum};
use dupac_common::Config;
use dupac_common::config::Association;
use dupac_common::metric;
use dupac_learner::MetricsRow;
use std::path::PathBuf;

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

/// The progress bar's message: return and success rate.
pub fn progress_message(row: &MetricsRow) -> String {
    format!(
        "ret {:.0} succ {:.0}%",
        row.get(metric::EPISODIC_RETURN)
            .copied()
            .unwrap_or(f64::NAN),
        100.0
            * row
                .get(metric::TRAIN.success_rate)
                .copied()
                .unwrap_or(f64::NAN)
    )
}

/// `dupac train`'s arguments (its own page runs `--single-process`; `commands::orchestrate`
/// the default, a learner and actor processes).
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
