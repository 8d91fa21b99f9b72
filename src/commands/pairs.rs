//! `dupac pairs`: the held-out pairs (spec/env.md "Episodes"), binned by shortest flyable
//! distance, seeded, written as JSON Lines: both splits (validation, `pairs.eval_seed` →
//! `pairs.eval_file`; test, `pairs.test_seed` → `pairs.test_file`), or the one `--split` names.

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};
use dupac_actor::pairs::{Pair, Split, split_pairs, write_pairs_jsonl};
use dupac_actor::planner::{AuditSummary, Planner, audit};
use dupac_radio::class::RsrpThresholds;
use dupac_radio::world::RadioWorld;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

/// A held-out split on the command line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SplitArg {
    /// `pairs.eval_seed` → `pairs.eval_file`: the set training evaluates on and the design was
    /// chosen on.
    Validation,
    /// `pairs.test_seed` → `pairs.test_file`: for the final report only.
    Test,
}

impl SplitArg {
    pub fn split(self) -> Split {
        match self {
            SplitArg::Validation => Split::Validation,
            SplitArg::Test => Split::Test,
        }
    }
}

#[derive(Args, Debug)]
pub struct PairsArgs {
    /// Only this split (default: both, each to its file).
    #[arg(long, value_enum, value_name = "validation|test")]
    pub split: Option<SplitArg>,
    /// Output file of the one split `--split` names (default its file, `pairs.eval_file` or
    /// `pairs.test_file`).
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Also audit the shortest path of every pair drawn: no coverage-aware path (λ = 0.5, 1, 2,
    /// 4) may be shorter, and its gap above a lower bound (the 2D shortest path around the
    /// footprints that span the flight band, with the vertical difference); a table and
    /// `<pairs file>.audit.csv` (one row per pair).
    #[arg(long)]
    pub audit: bool,
}

/// λ of the coverage-aware paths the audit compares the shortest path with (`dupac eval`'s).
const AUDIT_LAMBDAS: [f64; 4] = [0.5, 1.0, 2.0, 4.0];

/// `--audit`: the shortest path of every pair against its coverage-aware paths and the bound.
fn audit_pairs(planner: &Planner, pairs: &[Pair], out: &std::path::Path) -> Result<()> {
    let ends: Vec<_> = pairs
        .iter()
        .map(|p| (p.source_m, p.destination_m))
        .collect();
    let rows = audit(planner, &ends, &AUDIT_LAMBDAS)?;
    let csv_path = PathBuf::from(format!("{}.audit.csv", out.display()));
    let mut csv = String::from(
        "pair_id,shortest_m,lambda_0.5_m,lambda_1_m,lambda_2_m,lambda_4_m,bound_m,gap_m\n",
    );
    for (p, r) in pairs.iter().zip(&rows) {
        let l: Vec<String> = r.lambda_m.iter().map(|x| x.to_string()).collect();
        csv.push_str(&format!(
            "{},{},{},{},{}\n",
            p.id,
            r.shortest_m,
            l.join(","),
            r.bound_m,
            r.gap_m()
        ));
    }
    dupac_common::fsio::write_plain(&csv_path, csv.as_bytes())?;
    // 1 µm: what the paths' f64 sums agree to.
    let s = AuditSummary::of(&rows, 1e-6);
    println!("audit: {s}; {}", csv_path.display());
    Ok(())
}

pub fn run(global: &GlobalArgs, args: &PairsArgs) -> Result<ExitCode> {
    let cfg = global.config()?;
    if args.out.is_some() && args.split.is_none() {
        bail!(
            "--out names one file: give --split validation or --split test with it (without \
             --out, both splits are written to pairs.eval_file and pairs.test_file)"
        );
    }
    let splits: Vec<Split> = match args.split {
        Some(s) => vec![s.split()],
        None => Split::ALL.to_vec(),
    };
    let t = Instant::now();
    // The audit's coverage-aware paths need the RSRP cache (built if missing); the pairs alone
    // need the world.
    let (world, rsrp) = if args.audit {
        let (w, r) = dupac_scenario::world::world_and_cache(&cfg, global.no_progress())?;
        (w, Some(r))
    } else {
        let w = RadioWorld::build(&cfg).context("building the radio world")?;
        (std::sync::Arc::new(w), None)
    };
    let mut planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    if let Some(r) = &rsrp {
        planner.with_coverage(r.as_ref(), RsrpThresholds::from_config(&cfg.radio));
    }
    eprintln!(
        "free airspace: {:.1} % of voxels ({:.1} s)",
        100.0 * planner.free_space().free_voxel_fraction(),
        t.elapsed().as_secs_f64()
    );
    for split in splits {
        let out = args
            .out
            .clone()
            .unwrap_or_else(|| split.file(&cfg.pairs, planner.city()));
        let total = (cfg.pairs.eval_bins_m.len() * cfg.pairs.eval_per_bin) as u64;
        let label = format!("{} pairs", split.name());
        let pb = dupac_scenario::progress::progress_bar(total, &label, global.no_progress());
        let pairs = split_pairs(&planner, &cfg.pairs, &cfg.env, split, &|n| pb.inc(n));
        pb.finish_and_clear();
        write_pairs_jsonl(&out, &pairs)?;
        if args.audit {
            audit_pairs(&planner, &pairs, &out)?;
        }
        println!("{}\n", split.describe(&cfg.pairs));
        println!(
            "| bin (m) | pairs | mean shortest (m) | mean straight (m) | shortest / straight |"
        );
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
        println!();
        eprintln!(
            "wrote {} {} pairs to {} in {:.1} s ({} = {})",
            pairs.len(),
            split.name(),
            out.display(),
            t.elapsed().as_secs_f64(),
            split.seed_key(),
            split.seed(&cfg.pairs)
        );
    }
    Ok(ExitCode::SUCCESS)
}
