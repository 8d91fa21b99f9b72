//! The guide cache: the pool's guide paths planned once are loaded, equal, by the next process;
//! a file of other pairs or a damaged one is never used (planned again, and rewritten).

use dupac_actor::pairs::{Pair, training_pool};
use dupac_actor::planner::Planner;
use dupac_common::config::{CityKind, Config, RadioMode};
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use dupac_run::guide_cache::GuideCache;
use dupac_run::scenario::guide_pairs_cached;
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
    let loaded = guide_pairs_cached(&cfg, &world, &rsrp, &mut first).expect("planned");
    assert!(!loaded, "nothing cached yet: planned");
    let file = GuideCache::new(&cfg, world.fingerprint(), &first)
        .path()
        .to_path_buf();
    assert!(file.exists(), "{} written", file.display());

    let mut second = fresh();
    assert!(guide_pairs_cached(&cfg, &world, &rsrp, &mut second).expect("loaded"));
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
    assert!(!guide_pairs_cached(&cfg, &world, &rsrp, &mut fewer).expect("planned"));
    // Another λ: another key.
    let mut other = cfg.clone();
    other.env.observation.path_guide_lambda = 2.0;
    assert!(!guide_pairs_cached(&other, &world, &rsrp, &mut fresh()).expect("planned"));

    // A damaged file is not used: planned again, equal, and the file rewritten.
    let bytes = std::fs::read(&file).expect("read");
    std::fs::write(&file, &bytes[..bytes.len() / 2]).expect("truncate");
    let mut third = fresh();
    assert!(!guide_pairs_cached(&cfg, &world, &rsrp, &mut third).expect("planned again"));
    assert_eq!(paths(&third), paths(&first));
    assert_eq!(std::fs::read(&file).expect("rewritten"), bytes);
}
