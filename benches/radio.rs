//! Radio benchmarks on the default Midtown scenario (targets on the 2-core machine):
//! exact links (LoS ray cast + gain + path loss) per second, cache build, cached all-site queries.
//!
//! Run: `cargo bench --bench radio` (from the repository root, so `data/` resolves).

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use dupac_common::config::Config;
use dupac_common::geometry::Point;
use dupac_common::ids::SiteId;
use dupac_radio::cache::{GridSpec, RsrpCache};
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use rand::{RngExt, SeedableRng};
use std::hint::black_box;

fn world() -> (Config, RadioWorld) {
    let cfg = Config::load(None, &[]).expect("default config");
    let w = RadioWorld::build(&cfg).expect("Midtown world (run from the repository root)");
    (cfg, w)
}

/// Random UAV positions in free airspace (outside buildings) in the flight area and band.
fn free_points(w: &RadioWorld, n: usize, seed: u64) -> Vec<Point> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let a = w.city.area_m;
    let mut v = Vec::with_capacity(n);
    while v.len() < n {
        let p = Point::new(
            rng.random_range(a.min_m.x..a.max_m.x),
            rng.random_range(a.min_m.y..a.max_m.y),
            rng.random_range(20.0..120.0),
        );
        if !w.city.is_inside_building(p) {
            v.push(p);
        }
    }
    v
}

fn benches(c: &mut Criterion) {
    let (cfg, w) = world();
    let m = w.num_sites();
    let points = free_points(&w, 4096, 7);

    let mut g = c.benchmark_group("exact");
    g.throughput(Throughput::Elements(m as u64));
    g.bench_function("all_sites_link_rsrp", |b| {
        let mut out = vec![0.0; m];
        let mut i = 0;
        b.iter(|| {
            i = (i + 1) % points.len();
            w.rsrp_all_dbm(black_box(points[i]), &mut out);
            black_box(&out);
        })
    });
    g.throughput(Throughput::Elements(1));
    g.bench_function("los_segment_only", |b| {
        let mut i = 0;
        b.iter(|| {
            i = (i + 1) % points.len();
            black_box(w.los(SiteId((i % m) as u16), black_box(points[i])))
        })
    });
    g.finish();

    // Cache build on a strip of 10 grid rows of the default grid (the full build is timed with
    // `dupac cache build`, see BENCHMARKS.md).
    let full = GridSpec::covering(w.city.area_m, &cfg.cache);
    let strip = GridSpec { ny: 10, ..full };
    let mut g = c.benchmark_group("cache");
    g.sample_size(10);
    g.throughput(Throughput::Elements((strip.points() * m) as u64));
    g.bench_function("build_10_rows", |b| {
        b.iter_batched(
            || (),
            |_| black_box(RsrpCache::build(&w, strip, &|_| {})),
            BatchSize::PerIteration,
        )
    });
    g.finish();

    let dir = tempfile::tempdir().expect("tmp");
    let small = GridSpec { ny: 60, ..full };
    let path = dir.path().join("strip.bin");
    let built = RsrpCache::build(&w, small, &|_| {});
    built.save(&path).expect("save");
    let cache = match RsrpCache::open(&path, built.header()).expect("open") {
        dupac_radio::cache::Opened::Valid(c) => c,
        _ => panic!("cache does not read back"),
    };
    let qpoints = free_points(&w, 4096, 8);
    let mut g = c.benchmark_group("cached");
    g.throughput(Throughput::Elements(1));
    g.bench_function("all_sites_query", |b| {
        let mut out = vec![0.0; m];
        let mut i = 0;
        b.iter(|| {
            i = (i + 1) % qpoints.len();
            cache.rsrp_all_dbm(black_box(qpoints[i]), &mut out);
            black_box(&out);
        })
    });
    g.finish();
}

criterion_group!(radio, benches);
criterion_main!(radio);
