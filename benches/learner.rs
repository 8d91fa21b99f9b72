//! Learner throughput: PPO update samples/s at the default sizes (obs 101, 2 × 256
//! tanh, 3 move + 30 site outputs, minibatch 512, global grad-norm clip, Adam) on burn's `flex`
//! CPU backend, and the actors' policy inference calls/s at batch 1 and 64 (the hand-written
//! forward pass over exported weights, and burn's forward at batch 64 for comparison).
//!
//! Run: `cargo bench --bench learner`.

use burn::tensor::{Device, Tensor, TensorData};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use dupac_common::normalize::{ObsNormalizer, RewardScaler};
use dupac_common::policy::{MOVE_DIM, PolicyWeights, Scratch};
use dupac_learner::model::{ActorCritic, init_plain};
use dupac_learner::ppo::{Batch, Ppo};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::hint::black_box;

/// The allocator of the `dupac` binary (src/main.rs), so the update costs what it costs there.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

const OBS: usize = 101;
const SITES: usize = 30;

fn policy() -> PolicyWeights {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    PolicyWeights {
        version: 0,
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
    }
}

fn benches(c: &mut Criterion) {
    let p = policy();
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let obs: Vec<f32> = (0..64 * OBS)
        .map(|_| rng.random_range(-2.0f32..2.0))
        .collect();

    let mut g = c.benchmark_group("inference");
    g.throughput(Throughput::Elements(1));
    let mut s = Scratch::default();
    g.bench_function("plain_sample_batch1", |b| {
        let mut r = ChaCha8Rng::seed_from_u64(3);
        b.iter(|| black_box(p.act_sample(black_box(&obs[..OBS]), &mut s, || r.random::<f64>())))
    });
    g.throughput(Throughput::Elements(1));
    g.bench_function("plain_sample_batch64_per_call", |b| {
        let mut r = ChaCha8Rng::seed_from_u64(3);
        b.iter(|| {
            for row in obs.chunks(OBS) {
                black_box(p.act_sample(row, &mut s, || r.random::<f64>()));
            }
        })
    });
    let device = Device::flex();
    let model = ActorCritic::from_plain(&p.actor, &p.critic, p.log_std, None, SITES, &device);
    g.bench_function("burn_forward_batch1", |b| {
        b.iter(|| {
            let x = Tensor::<2>::from_data(TensorData::new(obs[..OBS].to_vec(), [1, OBS]), &device);
            let h = model.actor.forward(x.clone());
            let v = model.value(x);
            black_box((h.into_data(), v.into_data()))
        })
    });
    g.bench_function("burn_forward_batch64_per_call", |b| {
        b.iter(|| {
            let x = Tensor::<2>::from_data(TensorData::new(obs.clone(), [64, OBS]), &device);
            let h = model.actor.forward(x.clone());
            let v = model.value(x);
            black_box((h.into_data(), v.into_data()))
        })
    });
    g.finish();

    // One epoch over a 4096-sample batch in 8 minibatches of 512 = 8 gradient steps.
    let n = 4096;
    let batch = Batch {
        obs_dim: OBS,
        obs: (0..n * OBS)
            .map(|_| rng.random_range(-2.0f32..2.0))
            .collect(),
        moves: (0..n * MOVE_DIM)
            .map(|_| rng.random_range(-1.0f32..1.0))
            .collect(),
        sites: (0..n).map(|_| rng.random_range(0..SITES as i64)).collect(),
        logprobs: (0..n).map(|_| rng.random_range(-8.0f32..-4.0)).collect(),
        site_rewards: Vec::new(),
        n_sites: SITES,
        values: (0..n).map(|_| rng.random_range(-1.0f32..1.0)).collect(),
        advantages: (0..n).map(|_| rng.random_range(-1.0f32..1.0)).collect(),
        returns: (0..n).map(|_| rng.random_range(-1.0f32..1.0)).collect(),
        is_weights: Vec::new(),
        ..Batch::default()
    };
    let cfg = dupac_common::config::PpoConfig {
        update_epochs: 1,
        num_minibatches: 8,
        ..Default::default()
    };
    let ad = Device::flex().autodiff();
    let mut ppo = Ppo::new(
        cfg,
        ActorCritic::from_plain(&p.actor, &p.critic, p.log_std, None, SITES, &ad),
        ad,
    );
    let mut g = c.benchmark_group("ppo_update");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("epoch_4096_minibatch_512", |b| {
        let mut r = ChaCha8Rng::seed_from_u64(4);
        b.iter(|| black_box(ppo.update(&batch, 3e-4, &mut r)))
    });
    g.finish();
}

/// One whole update of the defaults (`Config::default()`: the 438-value observation, the
/// equivariant site head over 30 sites, the all-sites gradient over per-step site rows,
/// 4 epochs × 8 minibatches of 512) on 16 × 256 synthetic decisions, batch assembly included.
fn default_update(c: &mut Criterion) {
    let cfg = dupac_common::config::Config::default();
    let (obs_dim, m) = dupac_learner::synthetic::shapes(&cfg, SITES);
    let trajs = dupac_learner::synthetic::trajectories(&cfg, m, 16, 256, 7);
    let mut l = dupac_learner::learner::Learner::new(cfg, obs_dim, m, &Device::flex());
    let n: usize = trajs.iter().map(|t| t.len()).sum();
    let mut g = c.benchmark_group("ppo_update_default");
    g.sample_size(10);
    g.throughput(Throughput::Elements(n as u64));
    g.bench_function("update_4096", |b| {
        b.iter(|| {
            let p = l.policy();
            let segs: Vec<dupac_learner::batch::Segment<'_>> = trajs
                .iter()
                .map(|t| dupac_learner::batch::Segment {
                    actor: dupac_common::ids::ActorId(0),
                    behaviour_version: p.version,
                    traj: t,
                })
                .collect();
            black_box(
                l.learn(&p, &segs, dupac_learner::learner::Timings::default())
                    .expect("finite"),
            )
        })
    });
    g.finish();
}

criterion_group!(learner, benches);
criterion_group!(default_update_group, default_update);
criterion_main!(learner, default_update_group);
