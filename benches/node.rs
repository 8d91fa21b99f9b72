//! The wire: encode, decode and validate a trajectory chunk of the default size
//! (`distributed.actor_envs` 4 × `chunk_steps` 128 steps, 101 observations, 30 sites) and a
//! weights message of the default network (2 × 256 tanh actor and critic).
//!
//! Run: `cargo bench --bench node`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use dupac_common::ids::ActorId;
use dupac_common::msg::{
    EnvTrajectory, Header, TrajectoryChunk, WeightsMsg, decode_msg, encode_msg,
};
use dupac_common::normalize::{ObsNormalizer, RewardScaler};
use dupac_common::policy::{MOVE_DIM, PolicyWeights};
use dupac_common::validate::{ChunkExpect, validate_chunk};
use dupac_learner::model::init_plain;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

const OBS: usize = 101;
const SITES: usize = 30;
const ENVS: usize = 4;
const STEPS: usize = 128;

fn chunk() -> TrajectoryChunk {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut f = |n: usize| -> Vec<f32> { (0..n).map(|_| rng.random_range(-2.0f32..2.0)).collect() };
    let trajectories = (0..ENVS)
        .map(|k| EnvTrajectory {
            env: k as u32,
            obs_dim: OBS,
            obs: f(STEPS * OBS),
            moves: f(STEPS * MOVE_DIM),
            sites: (0..STEPS as u32).map(|t| t % SITES as u32).collect(),
            logprobs: f(STEPS),
            site_logprobs: f(STEPS),
            site_rewards: f(STEPS * SITES),
            decision_steps: vec![],
            step_site_features: vec![],
            step_site_rewards: vec![],
            values: f(STEPS),
            rewards: f(STEPS),
            terminated: vec![false; STEPS],
            truncated: vec![false; STEPS],
            next_values: f(STEPS),
            bootstrap_obs: f(OBS),
            episodes: vec![],
        })
        .collect();
    TrajectoryChunk {
        header: Header::new("bench", 1, ActorId(0), 2),
        trajectories,
    }
}

fn benches(c: &mut Criterion) {
    let ch = chunk();
    let bytes = encode_msg(&ch).expect("encode");
    let expect = ChunkExpect {
        run_id: "bench".into(),
        incarnation: 1,
        fingerprint: 2,
        obs_dim: OBS,
        n_sites: SITES,
        max_envs: ENVS,
        max_steps: STEPS,
        site_steps: None,
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
    g.bench_function("decode_and_validate", |b| {
        b.iter(|| {
            let c = decode_msg::<TrajectoryChunk>(
                black_box(&bytes),
                dupac_common::msg::MsgLimits::both(1 << 26),
                "bench",
            )
            .expect("decode");
            validate_chunk(&c, &expect).expect("valid");
            c
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
