//! `dupac tune-a3`: the base method's A3 parameters tuned on the validation split
//! (`dupac_eval::tune_a3`): the guide path of every validation pair flown with A3 once per
//! setting of an offset × hysteresis × time-to-trigger grid; `OUT/a3_grid.csv` (every setting's
//! excellent time, handovers, ping-pongs and low-SINR time) and `OUT/tuned_a3.toml` (the chosen
//! setting as `[radio.a3]`, a configuration file of its own).

use crate::GlobalArgs;
use anyhow::Result;
use clap::Args;
use dupac_eval::tune_a3::{A3Grid, Tuning, choose, grid_csv, tune_a3, tuned_toml};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct TuneA3Args {
    /// a3-Offset values (dB; TS 36.331: −15…15 in 0.5 dB steps). Default 0 1 2 3 4.
    #[arg(long, value_name = "DB", num_args = 1.., allow_negative_numbers = true)]
    pub offset_db: Vec<f64>,
    /// Hysteresis values (dB; TS 36.331: 0…15 in 0.5 dB steps). Default 0 0.5 1 2.
    #[arg(long, value_name = "DB", num_args = 1.., allow_negative_numbers = true)]
    pub hysteresis_db: Vec<f64>,
    /// timeToTrigger values (ms; TS 36.331: 0, 40, 64, 80, 100, 128, 160, 256, 320, 480, 512,
    /// 640, 1024, 1280, 2560, 5120). Default 0 40 80 160 320.
    #[arg(long, value_name = "MS", num_args = 1.., allow_negative_numbers = true)]
    pub ttt_ms: Vec<f64>,
    /// λ of the coverage-aware guide path flown (`env.observation.path_guide_lambda` of a
    /// guided policy).
    #[arg(long, value_name = "L", default_value_t = 1.0)]
    pub lambda: f64,
    /// Output directory: `a3_grid.csv`, `tuned_a3.toml`.
    #[arg(long, default_value = "out/tune_a3")]
    pub out: PathBuf,
}

impl TuneA3Args {
    /// The grid: each flag's values, or the default's.
    fn grid(&self) -> A3Grid {
        let d = A3Grid::default();
        let or = |v: &Vec<f64>, d: Vec<f64>| if v.is_empty() { d } else { v.clone() };
        A3Grid {
            offsets_db: or(&self.offset_db, d.offsets_db),
            hysteresis_db: or(&self.hysteresis_db, d.hysteresis_db),
            ttt_ms: or(&self.ttt_ms, d.ttt_ms),
        }
    }
}

pub fn run(global: &GlobalArgs, args: &TuneA3Args) -> Result<ExitCode> {
    let cfg = global.config()?;
    let grid = args.grid();
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
    crate::io::write_atomic(&grid_file, grid_csv(&results, chosen).as_bytes())?;
    let tuned_file = args.out.join("tuned_a3.toml");
    crate::io::write_atomic(
        &tuned_file,
        tuned_toml(chosen, reference, &pairs_file, args.lambda).as_bytes(),
    )?;
    println!(
        "| setting (offset dB / hysteresis dB / TTT ms) | excellent (%) | handovers/km | ping-pongs/km | SINR < −6 dB (%) |"
    );
    println!("|---|---:|---:|---:|---:|");
    for (what, r) in [("reference", reference), ("chosen", chosen)] {
        let s = r.setting;
        println!(
            "| {what}: {} / {} / {} | {:.2} | {:.3} | {:.3} | {:.2} |",
            s.offset_db,
            s.hysteresis_db,
            s.time_to_trigger_ms,
            r.excellent_pct,
            r.handovers_per_km,
            r.ping_pongs_per_km,
            r.sinr_below_m6db_pct
        );
    }
    let s = chosen.setting;
    eprintln!(
        "wrote {} and {}\nuse it: dupac train --association a3 --config {}\n   or: --set radio.a3.offset_db={} --set radio.a3.hysteresis_db={} --set radio.a3.time_to_trigger_ms={}\n   and: dupac eval --a3-tuned {}",
        grid_file.display(),
        tuned_file.display(),
        tuned_file.display(),
        s.offset_db,
        s.hysteresis_db,
        s.time_to_trigger_ms,
        tuned_file.display()
    );
    Ok(ExitCode::SUCCESS)
}
