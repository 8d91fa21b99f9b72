use super::*;
use crate::planner::Planner;
use dupac_common::config::{CityKind, Config, ScenarioConfig};
use dupac_radio::city::City;
use std::sync::atomic::{AtomicU64, Ordering};

fn procedural(size_m: f64) -> City {
    let mut sc = ScenarioConfig {
        city: CityKind::Procedural,
        name: "procedural".into(),
        ..ScenarioConfig::default()
    };
    sc.procedural.size_m = size_m;
    City::load(&sc).expect("procedural city")
}

/// Small bins that fit a 400 m city.
fn small_cfg() -> PairsConfig {
    PairsConfig {
        eval_bins_m: vec![100.0, 200.0],
        eval_per_bin: 6,
        min_m: 80.0,
        max_m: 250.0,
        ..PairsConfig::default()
    }
}

fn assert_valid(planner: &Planner, cfg: &PairsConfig, pairs: &[Pair]) {
    for p in pairs {
        for e in [p.source_m, p.destination_m] {
            check_endpoint(planner, e, cfg.endpoint_clearance_m).expect("valid endpoint");
        }
        assert!((p.straight_m - dist(p.source_m, p.destination_m)).abs() < 1e-9);
        assert!(p.shortest_m >= p.straight_m - 1e-9);
    }
}

#[test]
fn eval_pairs_are_deterministic_and_binned() {
    let city = procedural(400.0);
    let c = Config::default();
    let planner = Planner::new(&city, &c.env, &c.planner);
    let cfg = small_cfg();
    let count = AtomicU64::new(0);
    let a = eval_pairs(&planner, &cfg, &c.env, &|n| {
        count.fetch_add(n, Ordering::Relaxed);
    });
    assert_eq!(a.len(), 12);
    assert_eq!(count.load(Ordering::Relaxed), 12);
    assert_valid(&planner, &cfg, &a);
    for (i, p) in a.iter().enumerate() {
        assert_eq!(p.id, i as u64);
        let bin = p.bin_m.expect("bin");
        assert_eq!(bin, cfg.eval_bins_m[i / 6]);
        assert!((p.shortest_m - bin).abs() <= cfg.bin_tolerance * bin + 1e-9);
    }
    // Same seed on a one-thread pool: identical. Other seed: different.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let b = pool.install(|| eval_pairs(&planner, &cfg, &c.env, &|_| {}));
    assert_eq!(a, b);
    let other = PairsConfig {
        eval_seed: cfg.eval_seed + 1,
        ..cfg.clone()
    };
    let d = eval_pairs(&planner, &other, &c.env, &|_| {});
    assert_eq!(d.len(), a.len());
    assert_ne!(a, d);
}

#[test]
fn training_pool_is_deterministic_uniformish_and_disjoint_from_eval() {
    let city = procedural(400.0);
    let c = Config::default();
    let planner = Planner::new(&city, &c.env, &c.planner);
    let cfg = small_cfg();
    let a = training_pool(&planner, &cfg, &c.env, 20, 7, &|_| {});
    assert_eq!(a.len(), 20);
    assert_valid(&planner, &cfg, &a);
    for (i, p) in a.iter().enumerate() {
        assert_eq!(p.id, i as u64);
        assert_eq!(p.bin_m, None);
        let tol = 1.0 + cfg.bin_tolerance;
        assert!(p.shortest_m >= cfg.min_m / tol && p.shortest_m <= cfg.max_m * tol);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .expect("pool");
    let b = pool.install(|| training_pool(&planner, &cfg, &c.env, 20, 7, &|_| {}));
    assert_eq!(a, b);
    let d = training_pool(&planner, &cfg, &c.env, 20, 8, &|_| {});
    assert_ne!(a, d);
    // Same numeric seed as the evaluation set: still other pairs (other domain).
    let e = eval_pairs(&planner, &cfg, &c.env, &|_| {});
    let t = training_pool(&planner, &cfg, &c.env, 20, cfg.eval_seed, &|_| {});
    for p in &t {
        assert!(
            e.iter()
                .all(|q| q.source_m != p.source_m && q.destination_m != p.destination_m)
        );
    }
}

#[test]
fn impossible_bins_come_back_short() {
    let city = procedural(400.0);
    let c = Config::default();
    let planner = Planner::new(&city, &c.env, &c.planner);
    let cfg = PairsConfig {
        eval_bins_m: vec![5000.0],
        eval_per_bin: 2,
        ..PairsConfig::default()
    };
    assert!(eval_pairs(&planner, &cfg, &c.env, &|_| {}).is_empty());
}

#[test]
fn jsonl_round_trip_and_user_files() {
    let city = procedural(400.0);
    let c = Config::default();
    let planner = Planner::new(&city, &c.env, &c.planner);
    let cfg = small_cfg();
    let pairs = training_pool(&planner, &cfg, &c.env, 5, 1, &|_| {});
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("sub/pairs.jsonl");
    write_pairs_jsonl(&path, &pairs).expect("write");
    let back = read_pairs_jsonl(&path, &planner, &cfg).expect("read");
    assert_eq!(back.len(), pairs.len());
    // Bit for bit: the planner's path can change by metres when an endpoint moves by one ulp,
    // and serde_json without its `float_roundtrip` feature reads about 9 % of such coordinates
    // one ulp off.
    for (a, b) in pairs.iter().zip(&back) {
        assert_eq!(a.id, b.id);
        assert_eq!(a.bin_m, b.bin_m);
        assert_eq!(a.source_m, b.source_m);
        assert_eq!(a.destination_m, b.destination_m);
        assert_eq!(a.shortest_m.to_bits(), b.shortest_m.to_bits());
        assert_eq!(a.straight_m.to_bits(), b.straight_m.to_bits());
    }
    // No temporary file is left behind.
    let names: Vec<_> = std::fs::read_dir(dir.path().join("sub"))
        .expect("dir")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(names.len(), 1);

    // A user file with only the endpoints: shortest and straight are computed.
    let (s, t): ([f64; 3], [f64; 3]) = (pairs[0].source_m.into(), pairs[0].destination_m.into());
    let user = dir.path().join("user.jsonl");
    std::fs::write(
        &user,
        format!(
            "{}\n\n{}\n",
            serde_json::json!({"source_m": s, "destination_m": t}),
            serde_json::json!({"id": 9, "source_m": t, "destination_m": s, "bin_m": 100.0})
        ),
    )
    .expect("write user file");
    let got = read_pairs_jsonl(&user, &planner, &cfg).expect("user file");
    assert_eq!(got.len(), 2);
    assert_eq!(got[0].id, 0);
    assert_eq!(got[1].id, 9);
    assert!((got[0].shortest_m - pairs[0].shortest_m).abs() < 1e-6);
    assert!((got[0].straight_m - pairs[0].straight_m).abs() < 1e-9);
}

#[test]
fn bad_lines_name_file_and_line() {
    let city = procedural(400.0);
    let c = Config::default();
    let planner = Planner::new(&city, &c.env, &c.planner);
    let cfg = small_cfg();
    let good = training_pool(&planner, &cfg, &c.env, 1, 3, &|_| {})
        .pop()
        .expect("one pair");
    let good_line = serde_json::to_string(&good).expect("json");
    // A point inside a building of the procedural city.
    let inside = city
        .buildings
        .iter()
        .find(|b| {
            b.z_max_m > 40.0 && city.in_area(b.vertex_centroid_m()[0], b.vertex_centroid_m()[1])
        })
        .map(|b| {
            let c = b.vertex_centroid_m();
            [c[0], c[1], 30.0]
        })
        .expect("a tall building");
    assert!(city.is_inside_building(Point::from(inside)));
    let s: [f64; 3] = good.source_m.into();
    let d: [f64; 3] = good.destination_m.into();
    let cases: Vec<(String, &str)> = vec![
        ("{not json".into(), "invalid pair"),
        (
            good_line.replacen("\"shortest_m\":", "\"shortest_m\":NaN,\"x\":", 1),
            "invalid pair",
        ),
        (
            serde_json::json!({"source_m": inside, "destination_m": s}).to_string(),
            "source",
        ),
        (
            serde_json::json!({"source_m": s, "destination_m": [1.0e4, 0.0, 50.0]}).to_string(),
            "outside the flight area",
        ),
        (
            serde_json::json!({"source_m": s, "destination_m": [s[0], s[1], 5.0]}).to_string(),
            "outside the altitude band",
        ),
        (
            good_line.replacen("\"shortest_m\":", "\"shortest_m\":-1,\"y\":", 1),
            "invalid pair",
        ),
        (
            serde_json::json!({"source_m": s, "destination_m": d, "shortest_m": 0.0}).to_string(),
            "shortest_m must be",
        ),
        (
            serde_json::json!({"source_m": s, "destination_m": d, "extra": 1}).to_string(),
            "unknown field",
        ),
        (good_line.clone(), "duplicate id"),
    ];
    let dir = tempfile::tempdir().expect("tempdir");
    for (k, (bad, reason)) in cases.iter().enumerate() {
        let path = dir.path().join(format!("bad{k}.jsonl"));
        std::fs::write(&path, format!("{good_line}\n\n{bad}\n")).expect("write");
        let err = read_pairs_jsonl(&path, &planner, &cfg).expect_err(reason);
        let msg = err.to_string();
        let want = format!("{}:3: ", path.display());
        assert!(msg.starts_with(&want), "{msg}");
        assert!(msg.contains(reason), "{msg} (wanted {reason})");
    }
    let empty = dir.path().join("empty.jsonl");
    std::fs::write(&empty, "\n").expect("write");
    assert!(matches!(
        read_pairs_jsonl(&empty, &planner, &cfg),
        Err(PairsError::Empty { .. })
    ));
    assert!(matches!(
        read_pairs_jsonl(&dir.path().join("missing.jsonl"), &planner, &cfg),
        Err(PairsError::Read { .. })
    ));
}

/// The smallest distance (m) between an endpoint (source or destination) of a pair of `a` and
/// one of a pair of `b`.
fn closest_endpoints_m(a: &[Pair], b: &[Pair]) -> f64 {
    let ends = |v: &[Pair]| -> Vec<Point> {
        v.iter()
            .flat_map(|p| [p.source_m, p.destination_m])
            .collect()
    };
    let (ea, eb) = (ends(a), ends(b));
    ea.iter()
        .flat_map(|x| eb.iter().map(move |y| dist(*x, *y)))
        .fold(f64::INFINITY, f64::min)
}

/// The test split has the validation split's bins and counts, is a function of its seed, and
/// shares no endpoint (within 1e-6 m, source or destination, either way round) with the
/// validation split or a training pool, even when all three are drawn from the same number.
#[test]
fn the_test_split_is_binned_like_validation_and_shares_no_endpoint() {
    let city = procedural(400.0);
    let c = Config::default();
    let planner = Planner::new(&city, &c.env, &c.planner);
    let cfg = small_cfg();
    let same = PairsConfig {
        test_seed: cfg.eval_seed,
        ..cfg.clone()
    };
    for cfg in [cfg, same] {
        let val = split_pairs(&planner, &cfg, &c.env, Split::Validation, &|_| {});
        let test = split_pairs(&planner, &cfg, &c.env, Split::Test, &|_| {});
        assert_eq!(val, eval_pairs(&planner, &cfg, &c.env, &|_| {}));
        assert_eq!(test.len(), val.len());
        assert_valid(&planner, &cfg, &test);
        let bins = |v: &[Pair]| v.iter().map(|p| p.bin_m).collect::<Vec<_>>();
        assert_eq!(bins(&test), bins(&val));
        for p in &test {
            let bin = p.bin_m.expect("bin");
            assert!((p.shortest_m - bin).abs() <= cfg.bin_tolerance * bin + 1e-9);
        }
        let pool = training_pool(&planner, &cfg, &c.env, 40, cfg.test_seed, &|_| {});
        for (other, what) in [(&val, "validation"), (&pool, "training")] {
            let d = closest_endpoints_m(&test, other);
            assert!(
                d > 1e-6,
                "a test endpoint within {d} m of a {what} endpoint"
            );
        }
        // A function of the seed: the same on one thread; another seed, other pairs.
        let one = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .expect("pool");
        let again = one.install(|| split_pairs(&planner, &cfg, &c.env, Split::Test, &|_| {}));
        assert_eq!(again, test);
        let other = PairsConfig {
            test_seed: cfg.test_seed + 1,
            ..cfg.clone()
        };
        assert_ne!(
            split_pairs(&planner, &other, &c.env, Split::Test, &|_| {}),
            test
        );
    }
    assert_eq!(Split::from_name("test"), Some(Split::Test));
    assert_ne!(TEST_DOMAIN, EVAL_DOMAIN);
    assert_ne!(TEST_DOMAIN, TRAIN_DOMAIN);
}
