//! `dupac export`: a trained policy in open formats, `policy.safetensors` (its tensors) and
//! `policy.json` (the observation layout, the normaliser's constants, the networks' shapes and
//! the forward pass in words), for NumPy, PyTorch or any safetensors reader.

use anyhow::{Context, Result};
use clap::Args;
use dupac_learner::checkpoint::load_policy;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Exported policy (`policy.bin`) or checkpoint (`checkpoint.bin`) of `dupac train`.
    #[arg(long, value_name = "FILE")]
    pub policy: PathBuf,
    /// Output directory (`policy.safetensors`, `policy.json`).
    #[arg(long, default_value = "out/export", value_name = "DIR")]
    pub out: PathBuf,
}

pub fn run(args: &ExportArgs) -> Result<ExitCode> {
    let policy = load_policy(&args.policy)?;
    let source = args.policy.display().to_string();
    let (st, js) = dupac_run::export::export_policy(&policy, &source, &args.out)
        .with_context(|| format!("exporting {source}"))?;
    eprintln!("wrote {} and {}", st.display(), js.display());
    Ok(ExitCode::SUCCESS)
}
