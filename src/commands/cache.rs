//! `dupac cache build|check`: the per-site 3D RSRP cache and its interpolation error.

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use dupac_common::geometry::Point;
use dupac_radio::cache::{GridSpec, RsrpCache};
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use rand::{RngExt, SeedableRng};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Subcommand, Debug)]
pub enum CacheCommand {
    /// Build the cache at `cache.path` unless a valid one is there (`--force` rebuilds).
    Build {
        #[arg(long)]
        force: bool,
    },
    /// Compare cached (trilinear) RSRP against exact mode at random free-airspace points.
    Check(CheckArgs),
}

#[derive(Args, Debug)]
pub struct CheckArgs {
    /// Number of random points.
    #[arg(long, default_value_t = 20_000)]
    pub samples: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

pub fn run(global: &GlobalArgs, cmd: &CacheCommand) -> Result<ExitCode> {
    let cfg = global.config()?;
    let world = RadioWorld::build(&cfg).context("building the radio world")?;
    let grid = GridSpec::covering(world.city.area_m, &cfg.cache);
    let pb =
        dupac_scenario::progress::progress_bar(grid.ny as u64, "RSRP cache", global.no_progress());
    match cmd {
        CacheCommand::Build { force } => {
            if *force && cfg.cache.path.exists() {
                std::fs::remove_file(&cfg.cache.path)
                    .with_context(|| format!("removing {}", cfg.cache.path.display()))?;
            }
            let t = Instant::now();
            let (cache, built) = RsrpCache::open_or_build(&world, &cfg.cache, &|n| pb.inc(n))?;
            pb.finish_and_clear();
            let g = cache.grid();
            println!(
                "{} {}: {} x {} x {} points x {} sites ({:.0} MB) {} in {:.1} s",
                if built { "built" } else { "valid" },
                cfg.cache.path.display(),
                g.nx,
                g.ny,
                g.nz,
                cache.num_sites(),
                (g.points() * cache.num_sites() * 4) as f64 / 1e6,
                if built { "computed" } else { "checked" },
                t.elapsed().as_secs_f64()
            );
        }
        CacheCommand::Check(a) => {
            let (cache, _) = RsrpCache::open_or_build(&world, &cfg.cache, &|n| pb.inc(n))?;
            pb.finish_and_clear();
            let r = check(
                &world,
                &cache,
                a.samples,
                a.seed,
                cfg.cache.z_min_m,
                cfg.cache.z_max_m,
            );
            println!("{}", serde_json::to_string_pretty(&r)?);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Interpolation error of the cache against exact mode.
#[derive(Debug, serde::Serialize)]
pub struct CheckReport {
    pub points: usize,
    pub site_links: usize,
    pub mean_abs_err_db: f64,
    pub p50_abs_err_db: f64,
    pub p95_abs_err_db: f64,
    pub p99_abs_err_db: f64,
    pub max_abs_err_db: f64,
    /// Share of site links off by more than 1 dB / 3 dB (%).
    pub over_1db_pct: f64,
    pub over_3db_pct: f64,
    /// Share of points whose best site is the same in both modes (%).
    pub same_best_site_pct: f64,
    /// Mean |error| of the best site's RSRP (dB).
    pub best_rsrp_mean_abs_err_db: f64,
}

/// Samples `samples` random points outside buildings in the area and altitude band.
pub fn check(
    world: &RadioWorld,
    cache: &RsrpCache,
    samples: usize,
    seed: u64,
    z_min_m: f64,
    z_max_m: f64,
) -> CheckReport {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let a = world.city.area_m;
    let m = world.num_sites();
    let mut exact = vec![0.0; m];
    let mut cached = vec![0.0; m];
    let mut errs = Vec::with_capacity(samples * m);
    let mut same_best = 0usize;
    let mut best_err = 0.0;
    let mut points = 0usize;
    while points < samples {
        let p = Point::new(
            rng.random_range(a.min_m.x..a.max_m.x),
            rng.random_range(a.min_m.y..a.max_m.y),
            rng.random_range(z_min_m..z_max_m),
        );
        if world.city.is_inside_building(p) {
            continue;
        }
        points += 1;
        world.rsrp_all_dbm(p, &mut exact);
        cache.rsrp_all_dbm(p, &mut cached);
        for (e, c) in exact.iter().zip(&cached) {
            errs.push((e - c).abs());
        }
        let arg = |v: &[f64]| {
            v.iter()
                .enumerate()
                .max_by(|x, y| x.1.total_cmp(y.1))
                .map(|(i, _)| i)
                .unwrap_or(0)
        };
        let (be, bc) = (arg(&exact), arg(&cached));
        same_best += usize::from(be == bc);
        best_err += (exact[be] - cached[bc]).abs();
    }
    errs.sort_by(f64::total_cmp);
    let n = errs.len().max(1);
    let q = |p: f64| {
        errs.get(((p * (n - 1) as f64).round()) as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    CheckReport {
        points,
        site_links: errs.len(),
        mean_abs_err_db: errs.iter().sum::<f64>() / n as f64,
        p50_abs_err_db: q(0.5),
        p95_abs_err_db: q(0.95),
        p99_abs_err_db: q(0.99),
        max_abs_err_db: errs.last().copied().unwrap_or(f64::NAN),
        over_1db_pct: 100.0 * errs.iter().filter(|e| **e > 1.0).count() as f64 / n as f64,
        over_3db_pct: 100.0 * errs.iter().filter(|e| **e > 3.0).count() as f64 / n as f64,
        same_best_site_pct: 100.0 * same_best as f64 / points.max(1) as f64,
        best_rsrp_mean_abs_err_db: best_err / points.max(1) as f64,
    }
}
