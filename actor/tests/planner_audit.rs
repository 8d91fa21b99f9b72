//! The shortest path is the shortest: on the held-out pairs of both splits, no coverage-aware
//! path (λ of `dupac eval`'s sweep) is shorter than [`Planner::shortest`], and the shortest path
//! is never below the lower bound of the band-blocking footprints ([`audit`]).
//!
//! The fast test runs on a small procedural world with an RSRP cache coarse enough to build in a
//! debug test; the ignored ones print the audit of a full world
//! (`cargo test -p dupac-actor --release -- --ignored audit --nocapture`).

use dupac_actor::pairs::{Split, split_pairs};
use dupac_actor::planner::{AuditRow, AuditSummary, Planner, audit};
use dupac_common::config::{CityKind, Config, PairsConfig};
use dupac_radio::cache::RsrpCache;
use dupac_radio::class::RsrpThresholds;
use dupac_radio::world::RadioWorld;
use std::path::Path;
use std::time::Instant;

/// λ of `dupac eval`'s coverage-aware sweep.
const LAMBDAS: [f64; 4] = [0.5, 1.0, 2.0, 4.0];

/// Wall times (s) of one audit: drawing the pairs of both splits (one shortest path per
/// candidate tried), and the shortest paths of the pairs again, one after another on one thread.
struct Times {
    pairs_s: f64,
    shortest_s: f64,
}

/// The audit of both held-out splits of `cfg`'s world with `pairs` (the cache built into
/// `cache_dir` when not there): the rows with their split and pair id, validation first.
fn audit_splits(mut cfg: Config, cache_dir: &Path) -> (Vec<(Split, u64, AuditRow)>, Times) {
    cfg.cache.path = cache_dir.join(format!("rsrp-{}.bin", cfg.scenario.name));
    let world = RadioWorld::build(&cfg).expect("radio world");
    let (cache, _) = RsrpCache::open_or_build(&world, &cfg.cache, &|_| {}).expect("RSRP cache");
    let mut planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    planner.with_coverage(&cache, RsrpThresholds::from_config(&cfg.radio));
    let mut out = Vec::new();
    let mut times = Times {
        pairs_s: 0.0,
        shortest_s: 0.0,
    };
    for split in Split::ALL {
        let t0 = Instant::now();
        let pairs = split_pairs(&planner, &cfg.pairs, &cfg.env, split, &|_| {});
        times.pairs_s += t0.elapsed().as_secs_f64();
        assert!(!pairs.is_empty(), "{} split is empty", split.name());
        let ends: Vec<_> = pairs
            .iter()
            .map(|p| (p.source_m, p.destination_m))
            .collect();
        let rows = audit(&planner, &ends, &LAMBDAS).expect("audit");
        let t0 = Instant::now();
        for &(s, t) in &ends {
            planner.shortest(s, t).expect("shortest");
        }
        times.shortest_s += t0.elapsed().as_secs_f64();
        out.extend(pairs.iter().zip(rows).map(|(p, r)| (split, p.id, r)));
    }
    (out, times)
}

/// Asserts the two properties on every row, naming the pair.
fn assert_shortest(rows: &[(Split, u64, AuditRow)]) {
    for (split, id, r) in rows {
        assert!(
            r.min_lambda_m() >= r.shortest_m,
            "{} pair {id}: a coverage-aware path {:?} m is shorter than the shortest {} m",
            split.name(),
            r.lambda_m,
            r.shortest_m
        );
        assert!(
            r.shortest_m >= r.bound_m - 1e-9,
            "{} pair {id}: shortest {} m below the lower bound {} m",
            split.name(),
            r.shortest_m,
            r.bound_m
        );
    }
}

/// A 500 m procedural world (8 sites, a 10 m RSRP cache) with short held-out pairs.
fn small_world() -> Config {
    let mut cfg = Config::default();
    cfg.scenario.city = CityKind::Procedural;
    cfg.scenario.name = "procedural-500".into();
    cfg.scenario.procedural.size_m = 500.0;
    cfg.scenario.procedural.n_sites = 8;
    cfg.scenario.n_sites = 8;
    cfg.cache.horizontal_m = 10.0;
    cfg.cache.vertical_m = 10.0;
    cfg.pairs = PairsConfig {
        eval_bins_m: vec![150.0, 250.0],
        eval_per_bin: 6,
        ..PairsConfig::default()
    };
    cfg
}

#[test]
fn no_coverage_aware_path_is_shorter_than_the_shortest_on_either_split() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (rows, _) = audit_splits(small_world(), dir.path());
    assert!(rows.iter().any(|r| r.0 == Split::Test));
    assert_shortest(&rows);
}

/// Prints the audit of both splits (350 + 350 pairs with the default `pairs`) of a full world.
fn print_audit(cfg: Config) {
    let dir = std::env::var_os("DUPAC_AUDIT_CACHE_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(std::env::temp_dir);
    let t0 = Instant::now();
    let (rows, times) = audit_splits(cfg, &dir);
    let wall = t0.elapsed().as_secs_f64();
    for (split, id, r) in &rows {
        if r.lambda_shorter_m() > 1e-6 {
            println!(
                "{} pair {id}: shortest {:.3} m, coverage-aware {:.3?} m",
                split.name(),
                r.shortest_m,
                r.lambda_m
            );
        }
    }
    let plain: Vec<AuditRow> = rows.iter().map(|r| r.2.clone()).collect();
    let s = AuditSummary::of(&plain, 1e-6);
    println!("{s:#?}");
    println!(
        "{s}; shortest paths {:.2} s in the audit ({:.2} s one after another, warm), drawing the pairs {:.1} s, audit {wall:.1} s wall",
        s.shortest_s, times.shortest_s, times.pairs_s
    );
}

#[test]
#[ignore]
fn audit_midtown() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let mut cfg = Config::default();
    cfg.scenario.buildings_file = format!("{root}/data/nyc_midtown_buildings.geojson").into();
    cfg.scenario.cells_file = format!("{root}/data/nyc_midtown_cells.csv").into();
    print_audit(cfg);
}

#[test]
#[ignore]
fn audit_procedural() {
    let mut cfg = Config::default();
    cfg.scenario.city = CityKind::Procedural;
    cfg.scenario.name = "procedural".into();
    print_audit(cfg);
}
