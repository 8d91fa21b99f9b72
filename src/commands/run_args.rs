//! Arguments every training process shares (`dupac train`, `dupac learner`, `dupac actor`,
//! `dupac fly`), resolved into the one configuration.

use crate::global_args::GlobalArgs;
use anyhow::{Result, bail};
use clap::{Args, ValueEnum};
use dupac_common::config::{Association, Config};
use dupac_common::metric;
use dupac_learner::learner::MetricsRow;
use std::path::PathBuf;

/// Which association the policy trains with (`env.association`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AssociationArg {
    /// DUPAC: the policy chooses the serving site.
    Learned,
    /// The paper's base method: A3 handover chooses it.
    A3,
    /// The predictive association (`env.predictive`): planned on the map along the route ahead.
    Predictive,
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
#[command(next_help_heading = "Training run")]
pub struct RunArgs {
    /// `learned` (DUPAC), `a3` (base method) or `predictive` (the base method's move with the
    /// predictive association); default `env.association`.
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
    /// Compute device of the learner's updates.
    #[arg(long, value_enum, default_value = "cpu")]
    pub device: DeviceArg,
}

/// The burn device for `--device`: refused with a clear error when this build has no such
/// backend (`--features cuda` / `wgpu`) or the machine has no such device, before anything runs.
pub fn device(arg: DeviceArg) -> Result<burn::tensor::Device> {
    match arg {
        DeviceArg::Cpu => Ok(burn::tensor::Device::flex()),
        #[cfg(feature = "cuda")]
        DeviceArg::Cuda => first_of(burn::tensor::DeviceType::Cuda, "cuda", "a CUDA GPU"),
        #[cfg(feature = "wgpu")]
        DeviceArg::Wgpu => first_of(
            burn::tensor::DeviceType::Wgpu,
            "wgpu",
            "a GPU that wgpu can drive (Vulkan, Metal, DirectX)",
        ),
        #[allow(unreachable_patterns)]
        other => {
            let name = format!("{other:?}").to_lowercase();
            bail!(
                "--device {name}: this build has no such backend; rebuild with `--features {name}`"
            )
        }
    }
}

/// The first device burn finds of `kind`, or an error naming what is missing.
#[cfg(any(feature = "cuda", feature = "wgpu"))]
fn first_of(
    kind: burn::tensor::DeviceType,
    flag: &str,
    what: &str,
) -> Result<burn::tensor::Device> {
    burn::tensor::Device::enumerate(kind)
        .into_iter()
        .next()
        .ok_or_else(|| anyhow::anyhow!("--device {flag}: no {what} found on this machine"))
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
            AssociationArg::Predictive => Association::Predictive,
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

/// The newest held-out evaluation a run has measured, as the progress bar shows it beside the
/// training figures: `held-out 97% exc 91.6%` (success rate, time in excellent RSRP).
#[derive(Debug, Default, Clone)]
pub struct HeldOutSeen(Option<(f64, f64)>);

impl HeldOutSeen {
    /// Takes the evaluation of `row`, when it has one.
    pub fn see(&mut self, row: &MetricsRow) {
        if let (Some(&s), Some(&e)) = (
            row.get(metric::EVAL.success_rate),
            row.get(metric::EVAL.pct_excellent),
        ) {
            self.0 = Some((s, e));
        }
    }

    /// Takes the evaluations of the complete JSON lines in `text` (a metrics.jsonl's new part).
    pub fn see_jsonl(&mut self, text: &str) {
        for line in text.lines() {
            let Ok(serde_json::Value::Object(m)) = serde_json::from_str(line) else {
                continue;
            };
            let num = |k: &str| m.get(k).and_then(serde_json::Value::as_f64);
            if let (Some(s), Some(e)) = (
                num(metric::EVAL.success_rate),
                num(metric::EVAL.pct_excellent),
            ) {
                self.0 = Some((s, e));
            }
        }
    }

    /// Takes the evaluations of the complete lines of the file `path` after byte `from`;
    /// returns the bytes consumed (0 when the file cannot be read: the next call tries again).
    pub fn see_new_lines(&mut self, path: &std::path::Path, from: u64) -> u64 {
        use std::io::{Read, Seek, SeekFrom};
        let mut text = String::new();
        let read = std::fs::File::open(path).and_then(|mut f| {
            f.seek(SeekFrom::Start(from))?;
            f.take(64 << 20).read_to_string(&mut text)
        });
        if read.is_err() {
            return 0;
        }
        let complete = text.rfind('\n').map_or(0, |k| k + 1);
        self.see_jsonl(&text[..complete]);
        complete as u64
    }

    /// ` held-out 97% exc 91.6%`, or nothing before the first evaluation.
    pub fn suffix(&self) -> String {
        self.0
            .map(|(s, e)| format!(" held-out {:.0}% exc {e:.1}%", 100.0 * s))
            .unwrap_or_default()
    }
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
