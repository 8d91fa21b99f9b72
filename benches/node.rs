//! The wire: encode, decode, validate and expand a compact trajectory chunk of the default size
//! (`distributed.actor_envs` 4 × `chunk_steps` 128 decisions of 5 steps, 30 sites, random
//! states) and a weights message of a 2 × 256 network over 101 observations.
//!
//! Run: `cargo bench --bench node`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use dupac_actor::expand::Expander;
use dupac_common::config::Config;
use dupac_common::geometry::{Bounds2, Point, Point2};
use dupac_common::ids::ActorId;
use dupac_common::msg::{
    ExpandedChunk, Header, TrajectoryChunk, WeightsMsg, decode_msg, encode_msg,
};
use dupac_common::normalize::{ObsNormalizer, RewardScaler};
use dupac_common::policy::{MOVE_DIM, PolicyWeights};
use dupac_common::validate::{ChunkExpect, SiteSteps, validate_chunk, validate_compact};
use dupac_learner::model::init_plain;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

const OBS: usize = 101;
const SITES: usize = 30;
const ENVS: usize = 4;
const STEPS: usize = 128;

/// The default scenario's shape (30 sites, a site chosen at each of a decision's 5 steps, the
/// path guide and the sensor fan) over 30 random sites in a 2 km square.
fn expander() -> Expander {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let sites = (0..SITES)
        .map(|_| {
            Point::new(
                rng.random_range(-1000.0..1000.0),
                rng.random_range(-1000.0..1000.0),
                rng.random_range(20.0..60.0),
            )
        })
        .collect();
    let area = Bounds2 {
        min_m: Point2::new(-1000.0, -1000.0),
        max_m: Point2::new(1000.0, 1000.0),
    };
    Expander::of_sites(&Config::default(), area, sites)
}

fn chunk(x: &Expander) -> TrajectoryChunk {
    TrajectoryChunk {
        header: Header::new("bench", 1, ActorId(0), 2),
        trajectories: (0..ENVS)
            .map(|k| {
                let mut tr = x.sample_trajectory(STEPS, k as u64);
                tr.env = k as u32;
                tr
            })
            .collect(),
    }
}

fn benches(c: &mut Criterion) {
    let x = expander();
    let ch = chunk(&x);
    let bytes = encode_msg(&ch).expect("encode");
    let expect = ChunkExpect {
        run_id: "bench".into(),
        incarnation: 1,
        fingerprint: 2,
        obs_dim: x.layout().len(),
        n_sites: SITES,
        max_envs: ENVS,
        max_steps: STEPS,
        site_steps: SiteSteps::of(&Config::default()),
    };
    let mut g = c.benchmark_group("chunk_4x128");
    g.throughput(Throughput::Bytes(bytes.len() as u64));
    g.bench_function("encode", |b| {
        b.iter(|| encode_msg(black_box(&ch)).expect("encode"))
    });
    g.bench_function("decode", |b| {
        b.iter(|| {
            decode_msg::<TrajectoryChunk>(
                black_box(&bytes),
                dupac_common::msg::MsgLimits::both(1 << 26),
                "bench",
            )
            .expect("decode")
        })
    });
    g.bench_function("decode_validate_expand", |b| {
        b.iter(|| {
            let c = decode_msg::<TrajectoryChunk>(
                black_box(&bytes),
                dupac_common::msg::MsgLimits::both(1 << 26),
                "bench",
            )
            .expect("decode");
            validate_compact(&c, &expect).expect("valid");
            let e = ExpandedChunk {
                header: c.header.clone(),
                trajectories: c
                    .trajectories
                    .iter()
                    .map(|t| x.trajectory(t, usize::MAX).expect("expands"))
                    .collect(),
            };
            validate_chunk(&e, &expect).expect("valid");
            e
        })
    });
    g.finish();

    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let w = WeightsMsg {
        header: Header::new("bench", 1, ActorId::LEARNER, 2),
        policy: PolicyWeights {
            version: 1,
            obs_version: dupac_common::obs::OBS_VERSION,
            obs_dim: OBS,
            n_sites: SITES,
            actor: init_plain(OBS, &[256, 256], MOVE_DIM + SITES, 0.01, &mut rng),
            critic: init_plain(OBS, &[256, 256], 1, 1.0, &mut rng),
            site_head: None,
            log_std: [0.0; 3],
            obs_norm: ObsNormalizer::new(OBS, true, 10.0),
            reward_scaler: RewardScaler::new(true, 0.95, 10.0),
            observation: None,
        },
    };
    let wb = encode_msg(&w).expect("encode");
    let mut g = c.benchmark_group("weights_2x256");
    g.throughput(Throughput::Bytes(wb.len() as u64));
    g.bench_function("encode", |b| {
        b.iter(|| encode_msg(black_box(&w)).expect("encode"))
    });
    g.bench_function("decode", |b| {
        b.iter(|| {
            decode_msg::<WeightsMsg>(
                black_box(&wb),
                dupac_common::msg::MsgLimits::both(1 << 26),
                "bench",
            )
            .expect("decode")
        })
    });
    g.finish();
    eprintln!("chunk {} bytes, weights {} bytes", bytes.len(), wb.len());
}

criterion_group!(node, benches);
criterion_main!(node);
