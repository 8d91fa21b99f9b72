//! One-off measurements on the real Midtown city (and a procedural one), ignored by default:
//! the planner's timing, the audit of the held-out pairs on disk, the lattice edges whose
//! swept-sphere test depends on the direction. Each says how to run it.

use super::*;

/// One-off timing on the real Midtown city (run with
/// `cargo test --release -p dupac-actor --lib midtown_timing -- --ignored --nocapture`):
/// free-space build, 10 pairs of ≈ 790 m (cold, then warm edge cache) with a 2.5 m lattice as a
/// reference for the length, and a coverage-aware plan with a synthetic RSRP field.
#[test]
#[ignore]
fn midtown_timing() {
    use rand::{RngExt, SeedableRng};
    use std::time::Instant;
    let mut cfg = Config::default();
    cfg.scenario.buildings_file = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../data/nyc_midtown_buildings.geojson"
    )
    .into();
    let t0 = Instant::now();
    let c = City::load(&cfg.scenario).expect("midtown");
    println!(
        "city: {} buildings, {} triangles, {:.2} s",
        c.buildings.len(),
        c.mesh.num_triangles(),
        t0.elapsed().as_secs_f64()
    );
    let t0 = Instant::now();
    let mut p = Planner::new(&c, &cfg.env, &cfg.planner);
    println!(
        "free space {:?}: {:.2} s, free fraction {:.3}, {} threads",
        p.free_space().dims(),
        t0.elapsed().as_secs_f64(),
        p.free_space().free_voxel_fraction(),
        rayon::current_num_threads()
    );
    let fine_cfg = PlannerConfig {
        voxel_m: 2.5,
        ..cfg.planner.clone()
    };
    let t0 = Instant::now();
    let fine = Planner::new(&c, &cfg.env, &fine_cfg);
    println!(
        "reference free space {:?}: {:.2} s",
        fine.free_space().dims(),
        t0.elapsed().as_secs_f64()
    );
    let a = c.area_m;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let mut pairs = Vec::new();
    while pairs.len() < 10 {
        let s = Point::new(
            rng.random_range(a.min_m.x..a.max_m.x),
            rng.random_range(a.min_m.y..a.max_m.y),
            rng.random_range(20.0..120.0),
        );
        let ang: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let t = Point::new(
            s[0] + 790.0 * ang.cos(),
            s[1] + 790.0 * ang.sin(),
            rng.random_range(20.0..120.0),
        );
        if p.free_space().is_free_point(s) && p.free_space().is_free_point(t) {
            pairs.push((s, t));
        }
    }
    for &(s, t) in &pairs {
        let t0 = Instant::now();
        let path = p.shortest(s, t).expect("path");
        let cold = t0.elapsed().as_secs_f64() * 1e3;
        let t0 = Instant::now();
        let again = p.shortest(s, t).expect("path");
        let warm = t0.elapsed().as_secs_f64() * 1e3;
        assert_eq!(again, path);
        check_path(&p, &path, s, t);
        let reference = fine.shortest(s, t).map(|p| p.length_m).unwrap_or(f64::NAN);
        println!(
            "straight {:6.1} m  shortest {:6.1} m ({:2} waypoints)  2.5 m lattice {:6.1} m  \
             {:6.1} ms cold {:6.1} ms warm",
            dist(s, t),
            path.length_m,
            path.waypoints_m.len(),
            reference,
            cold,
            warm
        );
    }
    // Coverage from the real RSRP cache when one matching this world is on disk.
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    cfg.scenario.cells_file = format!("{root}/data/nyc_midtown_cells.csv").into();
    let world = dupac_radio::world::RadioWorld::build(&cfg).expect("radio world");
    let grid = dupac_radio::cache::GridSpec::covering(world.city.area_m, &cfg.cache);
    let expected = dupac_radio::cache::RsrpCache::expected_header(&world, grid);
    let cache_path = std::path::PathBuf::from(format!("{root}/out/cache/rsrp.bin"));
    match dupac_radio::cache::RsrpCache::open(&cache_path, &expected) {
        Ok(dupac_radio::cache::Opened::Valid(cache)) => {
            let t0 = Instant::now();
            p.with_coverage(&cache, RsrpThresholds::from_config(&cfg.radio));
            println!(
                "with_coverage (RSRP cache): {:.2} s, free voxels by class {:?}",
                t0.elapsed().as_secs_f64(),
                p.coverage_class_fractions()
            );
        }
        _ => {
            println!(
                "no matching RSRP cache at {}; synthetic coverage",
                cache_path.display()
            );
            p.with_coverage(&PoorPatch, RsrpThresholds::default());
        }
    }
    for &(s, t) in pairs.iter().take(5) {
        let shortest = p.shortest(s, t).expect("path").length_m;
        let t0 = Instant::now();
        let r = p.coverage_aware(s, t, cfg.planner.lambda);
        println!(
            "coverage-aware λ={}: {:.1} m (shortest {shortest:.1} m), {:.1} ms",
            cfg.planner.lambda,
            r.map(|p| p.length_m).unwrap_or(f64::NAN),
            t0.elapsed().as_secs_f64() * 1e3
        );
    }
    let pcfg = dupac_common::config::PairsConfig {
        eval_per_bin: 10,
        ..cfg.pairs.clone()
    };
    let t0 = Instant::now();
    let eval = crate::pairs::eval_pairs(&p, &pcfg, &cfg.env, &|_| {});
    println!(
        "eval_pairs, 7 bins x 10: {} pairs in {:.2} s",
        eval.len(),
        t0.elapsed().as_secs_f64()
    );
}

/// The audit of the held-out pairs on disk (`out/pairs/{eval,test}_pairs.jsonl`, Midtown, the RSRP
/// cache of out/cache): every pair's shortest path against its coverage-aware paths (λ = 0.5, 1,
/// 2, 4) and the bound; prints the summary and the pairs with a shorter coverage-aware path (run
/// with `cargo test --release -p dupac-actor --lib midtown_audit_files -- --ignored --nocapture`).
#[test]
#[ignore]
fn midtown_audit_files() {
    use std::time::Instant;
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let mut cfg = Config::default();
    cfg.scenario.buildings_file = format!("{root}/data/nyc_midtown_buildings.geojson").into();
    cfg.scenario.cells_file = format!("{root}/data/nyc_midtown_cells.csv").into();
    let world = dupac_radio::world::RadioWorld::build(&cfg).expect("radio world");
    let mut p = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let grid = dupac_radio::cache::GridSpec::covering(world.city.area_m, &cfg.cache);
    let expected = dupac_radio::cache::RsrpCache::expected_header(&world, grid);
    let cache_path = std::path::PathBuf::from(format!("{root}/out/cache/rsrp.bin"));
    let Ok(dupac_radio::cache::Opened::Valid(cache)) =
        dupac_radio::cache::RsrpCache::open(&cache_path, &expected)
    else {
        panic!("no matching RSRP cache at {}", cache_path.display());
    };
    p.with_coverage(&cache, RsrpThresholds::from_config(&cfg.radio));
    for name in ["eval_pairs", "test_pairs"] {
        let path = std::path::PathBuf::from(format!("{root}/out/pairs/{name}.jsonl"));
        let pairs = crate::pairs::read_pairs_jsonl(&path, &p, &cfg.pairs).expect("pairs");
        let ends: Vec<_> = pairs
            .iter()
            .map(|q| (q.source_m, q.destination_m))
            .collect();
        let t0 = Instant::now();
        let rows = audit(&p, &ends, &[0.5, 1.0, 2.0, 4.0]).expect("audit");
        println!(
            "{name}: {} ({:.1} s)",
            AuditSummary::of(&rows, 1e-6),
            t0.elapsed().as_secs_f64()
        );
        for (q, r) in pairs.iter().zip(&rows) {
            if r.lambda_shorter_m() > 1e-6 {
                println!(
                    "  pair {}: shortest {:.3} m (file {:.3}), λ {:?}",
                    q.id, r.shortest_m, q.shortest_m, r.lambda_m
                );
            }
        }
    }
}

/// Counts the lattice edges whose swept-sphere test answers differently in the two directions
/// (run with `cargo test --release -p dupac-actor --lib edge_asymmetry -- --ignored --nocapture`).
#[test]
#[ignore]
fn edge_asymmetry() {
    let mut cfg = Config::default();
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    cfg.scenario.buildings_file = format!("{root}/data/nyc_midtown_buildings.geojson").into();
    for c in [
        procedural(600.0),
        City::load(&cfg.scenario).expect("midtown"),
    ] {
        let p = Planner::new(&c, &cfg.env, &cfg.planner);
        let fs = p.free_space();
        let r = fs.clearance_m() + SMOOTHING_MARGIN_M;
        let (mut tried, mut asym) = (0usize, Vec::new());
        for u in 0..fs.num_voxels() as u32 {
            if !fs.is_free_voxel(u) {
                continue;
            }
            let tu = fs.triple(u);
            for d in 0..26 {
                let Some((v, _)) = fs.neighbour(tu, d) else {
                    continue;
                };
                if v < u || !fs.is_free_voxel(v) {
                    continue;
                }
                let (a, b) = (fs.centre_m(u), fs.centre_m(v));
                if fs.mesh_distance_capped_m(a, 20.0) + fs.mesh_distance_capped_m(b, 20.0)
                    >= dist(a, b) + 2.0 * r + 1e-3
                {
                    continue;
                }
                tried += 1;
                let ab = c.mesh.sphere_sweep(a, b, r).is_none();
                let ba = c.mesh.sphere_sweep(b, a, r).is_none();
                if ab != ba {
                    asym.push((u, d, v));
                }
            }
        }
        println!(
            "{}: {} edges swept, {} asymmetric {:?}",
            c.name,
            tried,
            asym.len(),
            &asym[..asym.len().min(5)]
        );
    }
}
