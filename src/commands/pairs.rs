//! `dupac pairs`: the held-out evaluation pairs (spec/env.md "Episodes"), binned by shortest
//! flyable distance, seeded, written as JSON Lines.

use crate::GlobalArgs;
use anyhow::{Context, Result};
use clap::Args;
use dupac_actor::pairs::{eval_pairs, write_pairs_jsonl};
use dupac_actor::planner::Planner;
use dupac_radio::world::RadioWorld;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct PairsArgs {
    /// Output file (default `pairs.eval_file`, `out/pairs/eval_pairs.jsonl`).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

pub fn run(global: &GlobalArgs, args: &PairsArgs) -> Result<ExitCode> {
    let cfg = global.config()?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| cfg.pairs.eval_file.clone());
    let t = Instant::now();
    let world = RadioWorld::build(&cfg).context("building the radio world")?;
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    eprintln!(
        "free airspace: {:.1} % of voxels ({:.1} s)",
        100.0 * planner.free_space().free_voxel_fraction(),
        t.elapsed().as_secs_f64()
    );
    let total = (cfg.pairs.eval_bins_m.len() * cfg.pairs.eval_per_bin) as u64;
    let pb = dupac_run::progress::progress_bar(total, "evaluation pairs", global.no_progress());
    let pairs = eval_pairs(&planner, &cfg.pairs, &cfg.env, &|n| pb.inc(n));
    pb.finish_and_clear();
    write_pairs_jsonl(&out, &pairs)?;
    println!("| bin (m) | pairs | mean shortest (m) | mean straight (m) | shortest / straight |");
    println!("|---:|---:|---:|---:|---:|");
    for bin in &cfg.pairs.eval_bins_m {
        let b: Vec<_> = pairs.iter().filter(|p| p.bin_m == Some(*bin)).collect();
        let n = b.len().max(1) as f64;
        let sh = b.iter().map(|p| p.shortest_m).sum::<f64>() / n;
        let st = b.iter().map(|p| p.straight_m).sum::<f64>() / n;
        println!(
            "| {bin:.0} | {} | {sh:.1} | {st:.1} | {:.3} |",
            b.len(),
            sh / st
        );
    }
    eprintln!(
        "wrote {} pairs to {} in {:.1} s (seed {})",
        pairs.len(),
        out.display(),
        t.elapsed().as_secs_f64(),
        cfg.pairs.eval_seed
    );
    Ok(ExitCode::SUCCESS)
}
