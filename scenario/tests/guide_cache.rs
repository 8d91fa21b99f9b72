//! The guide cache: the pool's guide paths planned once are loaded, equal, by the next process;
//! a file of other pairs or a damaged one is never used (planned again, and rewritten).

use dupac_actor::pairs::{Pair, training_pool};
use dupac_actor::planner::Planner;
use dupac_common::config::{CityKind, Config, RadioMode};
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use dupac_scenario::guide_cache::GuideCache;
use dupac_scenario::pairs::guide_pairs_cached;
use std::sync::Arc;

fn config(dir: &std::path::Path) -> Config {
    let mut cfg = Config::default();
    cfg.scenario.city = CityKind::Procedural;
    cfg.scenario.procedural.size_m = 500.0;
    cfg.scenario.procedural.n_sites = 6;
    cfg.scenario.n_sites = 6;
    cfg.env.radio_mode = RadioMode::Exact;
    cfg.pairs.min_m = 40.0;
    cfg.pairs.max_m = 70.0;
    cfg.cache.path = dir.join("rsrp.bin");
    // Today's guide: coverage-aware (λ = 1), 5 m from the buildings.
    assert!(cfg.env.needs_path() && cfg.env.observation.path_guide_lambda > 0.0);
    cfg.validate().expect("valid test config");
    cfg
}

fn paths(pairs: &[Pair]) -> Vec<Vec<[f64; 3]>> {
    pairs
        .iter()
        .map(|p| {
            p.path
                .as_ref()
                .expect("guided")
                .points_m()
                .iter()
                .map(|q| [q.x, q.y, q.z])
                .collect()
        })
        .collect()
}

#[test]
fn guide_paths_planned_once_are_loaded_equal_and_a_bad_file_is_planned_again() {
    let dir = tempfile::tempdir().expect("temp dir");
    let cfg = config(dir.path());
    let world = Arc::new(RadioWorld::build(&cfg).expect("procedural world"));
    let rsrp: Arc<dyn RsrpSource + Send + Sync> = world.clone();
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let unguided = training_pool(&planner, &cfg.pairs, &cfg.env, 12, 5, &|_| {});
    assert!(unguided.len() >= 10, "{} pairs", unguided.len());
    let fresh = || -> Vec<Pair> {
        let mut p = unguided.clone();
        p.iter_mut().for_each(|q| q.path = None);
        p
    };

    let mut first = fresh();
    let loaded = guide_pairs_cached(&cfg, &world, &rsrp, &mut first, true).expect("planned");
    assert!(!loaded, "nothing cached yet: planned");
    let file = GuideCache::new(&cfg, world.fingerprint(), &first)
        .path()
        .to_path_buf();
    assert!(file.exists(), "{} written", file.display());

    let mut second = fresh();
    assert!(guide_pairs_cached(&cfg, &world, &rsrp, &mut second, true).expect("loaded"));
    assert_eq!(
        paths(&second),
        paths(&first),
        "the cached paths are the planned ones"
    );
    assert!(
        second
            .iter()
            .all(|p| p.path_lambda == 1.0 && p.path_clearance_m == 5.0)
    );

    // Other pairs (one fewer) have another key: planned, not given the first set's paths.
    let mut fewer = fresh();
    fewer.pop();
    assert!(!guide_pairs_cached(&cfg, &world, &rsrp, &mut fewer, true).expect("planned"));
    // Another λ: another key.
    let mut other = cfg.clone();
    other.env.observation.path_guide_lambda = 2.0;
    assert!(!guide_pairs_cached(&other, &world, &rsrp, &mut fresh(), true).expect("planned"));

    // A damaged file is not used: planned again, equal, and the file rewritten.
    let bytes = std::fs::read(&file).expect("read");
    std::fs::write(&file, &bytes[..bytes.len() / 2]).expect("truncate");
    let mut third = fresh();
    assert!(!guide_pairs_cached(&cfg, &world, &rsrp, &mut third, true).expect("planned again"));
    assert_eq!(paths(&third), paths(&first));
    assert_eq!(std::fs::read(&file).expect("rewritten"), bytes);
}

/// The training pool drawn once is read back, equal, from the host's pool file by the next
/// process; another seed is another file; a damaged file is drawn again and rewritten.
#[test]
fn the_pool_drawn_once_is_read_back_equal_and_a_bad_file_is_drawn_again() {
    use dupac_scenario::pairs::{pool_cached, pool_file};
    use dupac_scenario::planners::{Planners, unguided};
    let dir = tempfile::tempdir().expect("temp dir");
    let mut cfg = unguided(&config(dir.path()));
    cfg.train.pool_size = 8;
    let world = Arc::new(RadioWorld::build(&cfg).expect("procedural world"));
    let rsrp: Arc<dyn RsrpSource + Send + Sync> = world.clone();
    let planners = Planners::new(&cfg, &[], &world, &rsrp, false);
    let file = pool_file(&cfg, world.fingerprint());
    let ends = |pool: &[Pair]| -> Vec<(u64, [f64; 6])> {
        pool.iter()
            .map(|p| {
                let (s, d) = (p.source_m, p.destination_m);
                (p.id, [s.x, s.y, s.z, d.x, d.y, d.z])
            })
            .collect()
    };

    let drawn = pool_cached(&cfg, &world, &planners, true).expect("drawn");
    assert_eq!(drawn.len(), 8);
    assert!(file.exists(), "the pool is written to {}", file.display());
    let written = std::fs::metadata(&file).expect("pool file").modified().ok();
    let read = pool_cached(&cfg, &world, &planners, true).expect("read");
    assert_eq!(ends(&read), ends(&drawn));
    assert_eq!(
        std::fs::metadata(&file).expect("pool file").modified().ok(),
        written
    );

    let mut other = cfg.clone();
    other.train.seed += 1;
    assert_ne!(pool_file(&other, world.fingerprint()), file);

    std::fs::write(&file, "{not a pair\n").expect("damage the file");
    let again = pool_cached(&cfg, &world, &planners, true).expect("drawn again");
    assert_eq!(ends(&again), ends(&drawn));
    let text = std::fs::read_to_string(&file).expect("rewritten");
    assert_eq!(text.lines().count(), 8);
}
