//! Environment steps per second per core on the default Midtown scenario with the cached radio
//! map and the full sensor fan (target ≥ 50 k steps/s/core, goal ≥ 100 k). Each episode
//! has its shortest flyable path as its guide (the path guide is on by default: the step
//! tracks the UAV's place on it and observes it).
//!
//! Run: `cargo bench --bench env` (from the repository root; builds `out/cache/rsrp.bin` once
//! if it is missing, ≈ 30 s).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use dupac_actor::env::{Action, Env, Episode, PathGuide};
use dupac_common::config::Config;
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_radio::cache::RsrpCache;
use dupac_radio::channel::FieldSplit;
use dupac_radio::world::RadioWorld;
use rand::{RngExt, SeedableRng};
use std::hint::black_box;
use std::sync::Arc;

fn benches(c: &mut Criterion) {
    let cfg = Config::load(None, &[]).expect("config");
    let world = Arc::new(RadioWorld::build(&cfg).expect("world"));
    let (cache, _) = RsrpCache::open_or_build(&world, &cfg.cache, &|_| {}).expect("cache");
    let cache = Arc::new(cache);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let a = world.city.area_m;
    let mut free = || loop {
        let p = Point::new(
            rng.random_range(a.min_m.x * 0.8..a.max_m.x * 0.8),
            rng.random_range(a.min_m.y * 0.8..a.max_m.y * 0.8),
            rng.random_range(30.0..110.0),
        );
        if !world.city.is_inside_building(p) && world.city.mesh.sphere_sweep(p, p, 5.0).is_none() {
            return p;
        }
    };
    let planner = dupac_actor::planner::Planner::new(&world.city, &cfg.env, &cfg.planner);
    let mut episodes: Vec<Episode> = Vec::new();
    while episodes.len() < 64 {
        let (s, d) = (free(), free());
        if let Ok(path) = planner.shortest(s, d) {
            episodes.push(Episode {
                guide: PathGuide::new(&path.waypoints_m).map(Arc::new),
                ..Episode::new(s, d, path.length_m, FieldSplit::Train)
            });
        }
    }
    drop(planner);

    for (name, radio) in [("cache", true), ("exact", false)] {
        let rsrp: Arc<dyn dupac_radio::source::RsrpSource + Send + Sync> =
            if radio { cache.clone() } else { world.clone() };
        let mut env = Env::new(&cfg, world.clone(), rsrp).expect("env");
        let mut k = 0usize;
        env.reset(0, episodes[0].clone()).expect("reset");
        let mut g = c.benchmark_group("env");
        g.throughput(Throughput::Elements(1));
        if !radio {
            g.sample_size(10);
        }
        g.bench_function(format!("step_{name}_full_fan"), |b| {
            b.iter(|| fly_on(&mut env, &mut k, &episodes, false))
        });
        if radio {
            // One decision of a policy: env.action_repeat (5) steps, one observation.
            g.throughput(Throughput::Elements(u64::from(cfg.env.action_repeat)));
            g.bench_function("act_cache_decision", |b| {
                b.iter(|| fly_on(&mut env, &mut k, &episodes, true))
            });
        }
        g.finish();
    }

    // The real channel (`radio.channel.model = "real"`): shadow fading from the episode's field
    // and the measurement error with its filter on top of the same cache, against the same
    // episodes above (its budget: at most 15 % more per cached step).
    let mut real_cfg = cfg.clone();
    real_cfg.radio.channel.model = dupac_common::config::ChannelModel::Real;
    let real_world = Arc::new(RadioWorld::from_parts(
        world.city.clone(),
        world.sites.clone(),
        &real_cfg.radio,
    ));
    let mut env = Env::new(&real_cfg, real_world, cache.clone()).expect("env");
    let mut k = 0usize;
    env.reset(0, episodes[0].clone()).expect("reset");
    let mut g = c.benchmark_group("env");
    g.throughput(Throughput::Elements(1));
    g.bench_function("step_cache_full_fan_real_channel", |b| {
        b.iter(|| fly_on(&mut env, &mut k, &episodes, false))
    });
    g.finish();

    // The peer in the same run: the same episodes without their path, the guide off and the
    // straight-line progress (the unguided settings).
    let mut unguided_cfg = cfg.clone();
    unguided_cfg.env.observation.path_guide = false;
    unguided_cfg.env.reward.progress = dupac_common::config::Progress::Straight;
    let unguided: Vec<Episode> = episodes
        .iter()
        .map(|e| Episode {
            guide: None,
            ..e.clone()
        })
        .collect();
    let mut env = Env::new(&unguided_cfg, world.clone(), cache.clone()).expect("env");
    let mut k = 0usize;
    env.reset(0, unguided[0].clone()).expect("reset");
    let mut g = c.benchmark_group("env");
    g.throughput(Throughput::Elements(1));
    g.bench_function("step_cache_full_fan_unguided", |b| {
        b.iter(|| fly_on(&mut env, &mut k, &unguided, false))
    });
    g.throughput(Throughput::Elements(u64::from(cfg.env.action_repeat)));
    g.bench_function("act_cache_decision_unguided", |b| {
        b.iter(|| fly_on(&mut env, &mut k, &unguided, true))
    });
    g.finish();
}

/// One step (or, with `decide`, one decision) straight at the goal, cycling through the sites;
/// a finished episode starts the next of `episodes`.
fn fly_on(env: &mut Env, k: &mut usize, episodes: &[Episode], decide: bool) {
    let p = env.position_m();
    let d = env.episode().map(|e| e.destination_m).unwrap_or(p);
    let v = d - p;
    let n = v.iter().map(|x| x.abs()).fold(1e-9, f64::max);
    let a = Action {
        move_: v / n,
        site: SiteId((*k % 30) as u16),
    };
    let s = if decide { env.act(&a) } else { env.step(&a) }.expect("step");
    if s.terminated || s.truncated {
        *k += 1;
        env.reset(*k as u64, episodes[*k % episodes.len()].clone())
            .expect("reset");
    }
    black_box(env.observation());
}

/// Planner time per pair: shortest flyable path of 20 evaluation-like pairs (warm edge cache).
fn planner(c: &mut Criterion) {
    let cfg = Config::load(None, &["pairs.eval_per_bin=3".to_string()]).expect("config");
    let world = RadioWorld::build(&cfg).expect("world");
    let planner = dupac_actor::planner::Planner::new(&world.city, &cfg.env, &cfg.planner);
    let pairs = dupac_actor::pairs::eval_pairs(&planner, &cfg.pairs, &cfg.env, &|_| {});
    let mut g = c.benchmark_group("planner");
    g.sample_size(10);
    g.throughput(Throughput::Elements(pairs.len() as u64));
    g.bench_function("shortest_per_pair", |b| {
        b.iter(|| {
            for p in &pairs {
                black_box(planner.shortest(p.source_m, p.destination_m).expect("path"));
            }
        })
    });
    g.finish();
}

criterion_group!(env, benches, planner);
criterion_main!(env);
