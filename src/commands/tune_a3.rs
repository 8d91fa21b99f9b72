//! `dupac tune-a3`: the base method's A3 parameters tuned on the validation split
//! (`dupac_eval::tune_a3`): the guide path of every validation pair flown with A3 at every
//! setting of an offset × hysteresis × time-to-trigger × A3's filter grid (the flags of
//! [`A3GridArgs`]); `OUT/a3_grid.csv` (every setting's
//! excellent time, handovers, ping-pongs and low-SINR time) and `OUT/tuned_a3.toml` (the chosen
//! setting as `[radio.a3]`, a configuration file of its own).

use super::front_args::A3GridArgs;
use crate::global_args::GlobalArgs;
use anyhow::Result;
use clap::Args;
use dupac_eval::tune_a3::{Tuning, choose, grid_csv, set_options, tune_a3, tuned_toml};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct TuneA3Args {
    #[command(flatten)]
    pub grid: A3GridArgs,
    /// λ of the coverage-aware guide path flown (`env.observation.path_guide_lambda` of a
    /// guided policy).
    #[arg(long, value_name = "L", default_value_t = 1.0)]
    pub lambda: f64,
    /// Output directory: `a3_grid.csv`, `tuned_a3.toml`.
    #[arg(long, default_value = "out/tune_a3")]
    pub out: PathBuf,
}

pub fn run(global: &GlobalArgs, args: &TuneA3Args) -> Result<ExitCode> {
    let cfg = global.config()?;
    let grid = args.grid.grid();
    // Illegal values are refused before the world is built.
    let n = grid.settings()?.len();
    eprintln!(
        "tune-a3: {n} settings on the validation split, guide path λ = {}",
        args.lambda
    );
    let Tuning {
        results,
        pairs_file,
    } = tune_a3(&cfg, &grid, args.lambda, global.no_progress())?;
    eprintln!("tune-a3: validation pairs {}", pairs_file.display());
    let chosen = choose(&results)?;
    let reference = results.iter().find(|r| r.reference).unwrap_or(chosen);
    std::fs::create_dir_all(&args.out)
        .map_err(|e| anyhow::anyhow!("--out {}: cannot create: {e}", args.out.display()))?;
    let grid_file = args.out.join("a3_grid.csv");
    dupac_common::fsio::write_plain(&grid_file, grid_csv(&results, chosen).as_bytes())?;
    let tuned_file = args.out.join("tuned_a3.toml");
    dupac_common::fsio::write_plain(
        &tuned_file,
        tuned_toml(chosen, reference, &pairs_file, args.lambda).as_bytes(),
    )?;
    println!(
        "| setting (offset dB / hysteresis dB / TTT ms / A3's filter k) | excellent (%) | handovers/km | ping-pongs/km | SINR < −6 dB (%) |"
    );
    println!("|---|---:|---:|---:|---:|");
    for (what, r) in [("reference", reference), ("chosen", chosen)] {
        println!(
            "| {what}: {} | {:.2} | {:.3} | {:.3} | {:.2} |",
            r.setting.label(),
            r.excellent_pct,
            r.handovers_per_km,
            r.ping_pongs_per_km,
            r.sinr_below_m6db_pct
        );
    }
    eprintln!(
        "wrote {} and {}\nuse it: dupac train --association a3 --config {}\n   or: {}\n   and: dupac eval --a3-tuned {}",
        grid_file.display(),
        tuned_file.display(),
        tuned_file.display(),
        set_options(&chosen.setting),
        tuned_file.display()
    );
    Ok(ExitCode::SUCCESS)
}
