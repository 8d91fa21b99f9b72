//! The PPO maths against hand-computed values and closed forms: clipped objective at
//! the clip edges, clipped value loss, the hybrid distribution's log-probability and entropy,
//! global gradient-norm clipping, the burn model against the actors' plain forward pass, and
//! checkpoint round trips.

use burn::module::{Module, ModuleVisitor, Param};
use burn::optim::{AdamConfig, GradientsParams};
use burn::tensor::{Device, Int, Tensor, TensorData};
use dupac_common::normalize::{ObsNormalizer, RewardScaler};
use dupac_common::policy::{HALF_LN_2PI, MOVE_DIM, PolicyWeights, Scratch, SiteHead};
use dupac_learner::checkpoint::{
    CheckpointMeta, load_checkpoint, load_policy, save_checkpoint, save_policy,
};
use dupac_learner::model::{ActorCritic, init_plain, tensor_to_vec};
use dupac_learner::ppo::{
    Batch, Ppo, SITE_STEP_ROWS, all_sites_loss, clip_global_grad_norm, policy_loss,
    site_advantages, value_loss,
};
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

mod site_steps;

const OBS: usize = 7;
const SITES: usize = 4;

fn plain_policy(seed: u64, n_sites: usize, out_gain: f64) -> PolicyWeights {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let actor = init_plain(OBS, &[16, 16], MOVE_DIM + n_sites, out_gain, &mut rng);
    let critic = init_plain(OBS, &[16, 16], 1, 1.0, &mut rng);
    let mut obs_norm = ObsNormalizer::new(OBS, true, 10.0);
    for (k, (m, v)) in obs_norm
        .stats
        .mean
        .iter_mut()
        .zip(obs_norm.stats.var.iter_mut())
        .enumerate()
    {
        *m = 0.1 * k as f64;
        *v = 1.0 + 0.5 * k as f64;
    }
    PolicyWeights {
        version: 0,
        obs_version: dupac_common::obs::OBS_VERSION,
        obs_dim: OBS,
        n_sites,
        actor,
        critic,
        site_head: None,
        log_std: [-0.3, 0.1, 0.4],
        obs_norm,
        reward_scaler: RewardScaler::new(true, 0.95, 10.0),
        observation: None,
    }
}

fn model_of(p: &PolicyWeights, device: &Device) -> ActorCritic {
    ActorCritic::from_policy(p, device)
}

/// Features per site of the equivariant test policies.
const FEATS: usize = 3;

/// A policy with the equivariant site head: the MLPs read the first OBS values, the head the
/// SITES × FEATS after them.
fn equivariant_policy(seed: u64) -> PolicyWeights {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut p = plain_policy(seed, SITES, 1.0);
    p.actor = init_plain(OBS, &[16, 16], MOVE_DIM, 1.0, &mut rng);
    let embed = init_plain(16, &[], 5, 1.4, &mut rng).layers.remove(0);
    p.site_head = Some(SiteHead {
        features: FEATS,
        embed,
        mlp: init_plain(FEATS + 5, &[8], 1, 1.0, &mut rng),
    });
    p.obs_dim = OBS + SITES * FEATS;
    let mut norm = ObsNormalizer::new(p.obs_dim, true, 10.0);
    norm.stats.mean[..OBS].copy_from_slice(&p.obs_norm.stats.mean);
    norm.stats.var[..OBS].copy_from_slice(&p.obs_norm.stats.var);
    p.obs_norm = norm;
    p.validate().expect("valid equivariant policy");
    p
}

/// log-softmax of plain logits (the reference the burn model is compared with).
fn log_softmax(l: &[f32]) -> Vec<f32> {
    let max = l.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
    let lse = max + l.iter().map(|&v| (v - max).exp()).sum::<f32>().ln();
    l.iter().map(|&v| v - lse).collect()
}

fn t1(v: Vec<f32>, device: &Device) -> Tensor<1> {
    let n = v.len();
    Tensor::from_data(TensorData::new(v, [n]), device)
}

fn random_obs(rng: &mut ChaCha8Rng, n: usize) -> Vec<f32> {
    (0..n * OBS)
        .map(|_| rng.random_range(-3.0f32..3.0))
        .collect()
}

#[test]
fn clipped_surrogate_at_the_clip_edges() {
    let device = Device::flex().autodiff();
    // ratios 1.3, 0.7, 0.7, 1.1 with advantages +1, +1, −1, +2 (ε = 0.2):
    //  ρ=1.3, A>0: clipped at 1.2 → −1.2, no gradient;   ρ=0.7, A>0: unclipped → −0.7;
    //  ρ=0.7, A<0: clipped at 0.8 → +0.8, no gradient;   ρ=1.1: inside → −2.2.
    let ratios = [1.3f32, 0.7, 0.7, 1.1];
    let adv = vec![1.0f32, 1.0, -1.0, 2.0];
    let old = vec![0.0f32; 4];
    let new: Vec<f32> = ratios.iter().map(|r| r.ln()).collect();
    let new_t = t1(new, &device).require_grad();
    let (loss, ratio) = policy_loss(new_t.clone(), t1(old, &device), t1(adv, &device), 0.2);
    let want = (-1.2 - 0.7 + 0.8 - 2.2) / 4.0;
    let got = loss.clone().into_scalar::<f32>();
    assert!((got - want).abs() < 1e-5, "loss {got} vs {want}");
    let r = tensor_to_vec(ratio);
    for (a, b) in r.iter().zip(ratios) {
        assert!((a - b).abs() < 1e-5);
    }
    let grads = loss.backward();
    let g = tensor_to_vec(new_t.grad(&grads).expect("gradient"));
    // d/dlogπ of −A·ρ/4 = −A·ρ/4 where unclipped, 0 where the clipped branch is active.
    let want_g = [0.0, -0.7 / 4.0, 0.0, -2.0 * 1.1 / 4.0];
    for (a, b) in g.iter().zip(want_g) {
        assert!((a - b).abs() < 1e-5, "grad {g:?} vs {want_g:?}");
    }
}

#[test]
fn clipped_value_loss_takes_the_pessimistic_branch() {
    let device = Device::flex();
    // V_old = 0, R = 1: V = 0.5 (inside ε = 0.2 → clipped V = 0.2, (0.2−1)² = 0.64 > 0.25);
    // V = 1.5 (clipped 0.2 → 0.64 vs 0.25 → 0.64); V = −0.1 (inside → 1.21 both).
    let v = t1(vec![0.5, 1.5, -0.1], &device);
    let old = t1(vec![0.0; 3], &device);
    let ret = t1(vec![1.0; 3], &device);
    let clipped = value_loss(v.clone(), old.clone(), ret.clone(), Some(0.2)).into_scalar::<f32>();
    let want = 0.5 * (0.64 + 0.64 + 1.21) / 3.0;
    assert!((clipped - want).abs() < 1e-5, "{clipped} vs {want}");
    let plain = value_loss(v, old, ret, None).into_scalar::<f32>();
    let want = 0.5 * (0.25 + 0.25 + 1.21) / 3.0;
    assert!((plain - want).abs() < 1e-5, "{plain} vs {want}");
}

#[test]
fn hybrid_log_prob_and_entropy_match_closed_forms() {
    let device = Device::flex();
    let p = plain_policy(3, SITES, 1.0);
    let model = model_of(&p, &device);
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let n = 6;
    let raw = random_obs(&mut rng, n);
    let mut norm = vec![0.0f32; n * OBS];
    for (r, o) in raw.chunks(OBS).zip(norm.chunks_mut(OBS)) {
        p.obs_norm.apply(r, o);
    }
    let moves: Vec<f32> = (0..n * MOVE_DIM)
        .map(|_| rng.random_range(-2.0f32..2.0))
        .collect();
    let sites: Vec<i64> = (0..n).map(|k| (k % SITES) as i64).collect();
    let ev = model.evaluate(
        Tensor::from_data(TensorData::new(norm, [n, OBS]), &device),
        Tensor::from_data(TensorData::new(moves.clone(), [n, MOVE_DIM]), &device),
        Tensor::<1, Int>::from_data(TensorData::new(sites.clone(), [n]), &device),
    );
    let lp = tensor_to_vec(ev.logprob);
    let ent_site = tensor_to_vec(ev.entropy_site);
    let ent_move = tensor_to_vec(ev.entropy_move)[0];
    // Closed form of the Gaussian entropy: Σ (log σ + ½ ln(2πe)).
    let want_ent_move: f64 = p
        .log_std
        .iter()
        .map(|&l| f64::from(l) + 0.5 + HALF_LN_2PI)
        .sum();
    assert!((f64::from(ent_move) - want_ent_move).abs() < 1e-5);
    let mut s = Scratch::default();
    for k in 0..n {
        let (head, _) = p.forward(&raw[k * OBS..(k + 1) * OBS], &mut s);
        let mut want = 0.0f64;
        for a in 0..MOVE_DIM {
            let mu = f64::from(head[a]);
            let sd = f64::from(p.log_std[a]).exp();
            let x = f64::from(moves[k * MOVE_DIM + a]);
            want += -(x - mu).powi(2) / (2.0 * sd * sd)
                - sd.ln()
                - 0.5 * (2.0 * std::f64::consts::PI).ln();
        }
        let logits: Vec<f64> = head[MOVE_DIM..].iter().map(|&v| f64::from(v)).collect();
        let z: f64 = logits.iter().map(|l| l.exp()).sum();
        let probs: Vec<f64> = logits.iter().map(|l| l.exp() / z).collect();
        want += probs[sites[k] as usize].ln();
        assert!(
            (f64::from(lp[k]) - want).abs() < 1e-4,
            "sample {k}: {} vs {want}",
            lp[k]
        );
        let want_h: f64 = -probs.iter().map(|p| p * p.ln()).sum::<f64>();
        assert!((f64::from(ent_site[k]) - want_h).abs() < 1e-5);
    }
}

#[test]
fn burn_model_and_plain_forward_agree() {
    let device = Device::flex();
    for (seed, n_sites) in [(1, SITES), (2, 0)] {
        let p = plain_policy(seed, n_sites, 1.0);
        let model = model_of(&p, &device);
        let mut rng = ChaCha8Rng::seed_from_u64(seed + 10);
        let n = 64;
        let raw = random_obs(&mut rng, n);
        let mut norm = vec![0.0f32; n * OBS];
        for (r, o) in raw.chunks(OBS).zip(norm.chunks_mut(OBS)) {
            p.obs_norm.apply(r, o);
        }
        let x = Tensor::<2>::from_data(TensorData::new(norm, [n, OBS]), &device);
        let head = tensor_to_vec(model.actor.forward(x.clone()));
        let value = tensor_to_vec(model.value(x));
        let w = MOVE_DIM + n_sites;
        let mut s = Scratch::default();
        for k in 0..n {
            let (h, v) = p.forward(&raw[k * OBS..(k + 1) * OBS], &mut s);
            for j in 0..w {
                assert!(
                    (h[j] - head[k * w + j]).abs() < 1e-5,
                    "row {k} col {j}: {} vs {}",
                    h[j],
                    head[k * w + j]
                );
            }
            assert!((v - value[k]).abs() < 1e-5);
        }
    }
}

/// The equivariant site head: the burn model and the actors' plain forward give the
/// same log-probabilities of every site to 1e-5, and permuting the sites' features permutes the
/// logits (and nothing else: the move means and the value stay).
#[test]
fn equivariant_site_head_matches_plain_forward_and_permutes_with_the_sites() {
    let device = Device::flex();
    let p = equivariant_policy(4);
    let model = model_of(&p, &device);
    let d = p.obs_dim;
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let n = 32;
    let raw: Vec<f32> = (0..n * d).map(|_| rng.random_range(-2.0..2.0)).collect();
    let mut norm = vec![0.0f32; n * d];
    for (r, o) in raw.chunks(d).zip(norm.chunks_mut(d)) {
        p.obs_norm.apply(r, o);
        // The head reads its features raw (fixed scales), as the actors do.
        o[OBS..].copy_from_slice(&r[OBS..]);
    }
    let x = Tensor::<2>::from_data(TensorData::new(norm, [n, d]), &device);
    let moves = Tensor::<2>::zeros([n, MOVE_DIM], &device);
    let sites = Tensor::<1, Int>::zeros([n], &device);
    let ev = model.evaluate(x, moves, sites);
    let logp = tensor_to_vec(ev.site_logp.expect("site head"));
    let mut s = Scratch::default();
    for k in 0..n {
        let row = &raw[k * d..(k + 1) * d];
        let (h, v) = p.forward(row, &mut s);
        let lp = log_softmax(&h[MOVE_DIM..]);
        for j in 0..SITES {
            assert!(
                (lp[j] - logp[k * SITES + j]).abs() < 1e-5,
                "row {k} site {j}: plain {} burn {}",
                lp[j],
                logp[k * SITES + j]
            );
        }
        // Permute the sites: (0 1 2 3) → (2 0 3 1).
        let perm = [2usize, 0, 3, 1];
        let mut row2 = row.to_vec();
        for (to, &from) in perm.iter().enumerate() {
            row2[OBS + to * FEATS..OBS + (to + 1) * FEATS]
                .copy_from_slice(&row[OBS + from * FEATS..OBS + (from + 1) * FEATS]);
        }
        let (h2, v2) = p.forward(&row2, &mut s);
        assert_eq!(
            &h2[..MOVE_DIM],
            &h[..MOVE_DIM],
            "the move does not see the sites' order"
        );
        assert_eq!(v2, v);
        for (to, &from) in perm.iter().enumerate() {
            assert!(
                (h2[MOVE_DIM + to] - h[MOVE_DIM + from]).abs() < 1e-6,
                "logit of the site moved from {from} to {to}"
            );
        }
    }
}

/// The all-sites loss against a hand-computed case: its gradient in the logits is
/// −π_j (A_j − Σ_k π_k A_k) / B, and `site_advantages` subtracts each row's best and divides by
/// the root mean square.
#[test]
fn all_sites_gradient_matches_the_hand_computed_expectation() {
    let device = Device::flex().autodiff();
    // B = 2 rows, M = 3 sites.
    let logits = vec![0.0f32, 1.0, -1.0, 0.5, 0.5, 0.5];
    let rewards = vec![1.0f32, 3.0, 2.0, -4.0, -4.0, 2.0];
    let a = site_advantages(&rewards, &[0, 1], 3, false);
    assert_eq!(a, vec![-2.0, 0.0, -1.0, -6.0, -6.0, 0.0]);
    let an = site_advantages(&rewards, &[0, 1], 3, true);
    let rms = ((4.0 + 1.0 + 36.0 + 36.0) / 6.0f64).sqrt();
    assert!((f64::from(an[0]) - (-2.0 / rms)).abs() < 1e-6);
    // Only the listed rows, in their order.
    assert_eq!(
        site_advantages(&rewards, &[1], 3, false),
        vec![-6.0, -6.0, 0.0]
    );
    let lt =
        Tensor::<2>::from_data(TensorData::new(logits.clone(), [2, 3]), &device).require_grad();
    let at = Tensor::<2>::from_data(TensorData::new(a.clone(), [2, 3]), &device);
    let loss = all_sites_loss(burn::tensor::activation::log_softmax(lt.clone(), 1), at);
    let grads = loss.backward();
    let g = tensor_to_vec(lt.grad(&grads).expect("gradient"));
    for b in 0..2 {
        let row = &logits[b * 3..(b + 1) * 3];
        let z: f64 = row.iter().map(|&l| f64::from(l).exp()).sum();
        let pi: Vec<f64> = row.iter().map(|&l| f64::from(l).exp() / z).collect();
        let ab: Vec<f64> = a[b * 3..(b + 1) * 3]
            .iter()
            .map(|&x| f64::from(x))
            .collect();
        let mean: f64 = pi.iter().zip(&ab).map(|(p, a)| p * a).sum();
        for j in 0..3 {
            let want = -pi[j] * (ab[j] - mean) / 2.0;
            assert!(
                (f64::from(g[b * 3 + j]) - want).abs() < 1e-6,
                "row {b} site {j}: {} vs {want}",
                g[b * 3 + j]
            );
        }
    }
    // The best site's logit rises, the others fall (row 0: site 1 is the best).
    assert!(g[1] < 0.0 && g[0] > 0.0 && g[2] > 0.0);
}

/// Squared L2 norm of every gradient, visited independently of the code under test.
struct Collect<'a>(&'a GradientsParams, Vec<Vec<f32>>);
impl ModuleVisitor for Collect<'_> {
    fn visit_float<const D: usize>(&mut self, param: &Param<Tensor<D>>) {
        if let Some(g) = self.0.get::<D>(param.id) {
            self.1.push(tensor_to_vec(g));
        }
    }
}

#[test]
fn global_gradient_norm_clipping_scales_all_tensors_together() {
    let device = Device::flex().autodiff();
    let p = plain_policy(5, SITES, 1.0);
    let model = model_of(&p, &device);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let x = Tensor::<2>::from_data(
        TensorData::new(random_obs(&mut rng, 32), [32, OBS]),
        &device,
    );
    let loss = (model.actor.forward(x.clone()).square().sum() + model.value(x).sum())
        .mul_scalar(10.0)
        + model.log_std.val().sum().mul_scalar(3.0);
    let mut grads = GradientsParams::from_grads(loss.backward(), &model);
    let mut before = Collect(&grads, Vec::new());
    model.visit(&mut before);
    let before = before.1;
    assert_eq!(
        before.len(),
        2 * 3 * 2 + 1,
        "3 layers × (W, b) × 2 networks + log-std"
    );
    let norm: f64 = before
        .iter()
        .flatten()
        .map(|&g| f64::from(g).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(norm > 1.0, "the test needs a large gradient, got {norm}");
    let reported = clip_global_grad_norm(&model, &mut grads, 0.5);
    assert!((reported - norm).abs() / norm < 1e-5);
    let mut after = Collect(&grads, Vec::new());
    model.visit(&mut after);
    let after = after.1;
    let norm_after: f64 = after
        .iter()
        .flatten()
        .map(|&g| f64::from(g).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!((norm_after - 0.5).abs() < 1e-4, "clipped norm {norm_after}");
    // One common factor for every tensor (per-tensor clipping would give different ones).
    let factor = 0.5 / norm;
    for (b, a) in before.iter().zip(&after) {
        for (x, y) in b.iter().zip(a) {
            assert!(
                (f64::from(*x) * factor - f64::from(*y)).abs() < 1e-6 + 1e-4 * f64::from(x.abs())
            );
        }
    }
    // Below the threshold nothing changes.
    let again = clip_global_grad_norm(&model, &mut grads, 10.0);
    assert!((again - 0.5).abs() < 1e-4);
}

fn small_batch(seed: u64, n: usize) -> Batch {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Batch {
        obs_dim: OBS,
        obs: random_obs(&mut rng, n),
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
    }
}

#[test]
fn checkpoint_round_trip_gives_identical_actions_and_optimiser_state() {
    let device = Device::flex().autodiff();
    let p = plain_policy(6, SITES, 0.01);
    let mut cfg = dupac_common::config::PpoConfig {
        num_minibatches: 2,
        update_epochs: 2,
        ..Default::default()
    };
    cfg.hidden = vec![16, 16];
    let mut ppo = Ppo::new(cfg.clone(), model_of(&p, &device), device.clone());
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let stats = ppo.update(&small_batch(1, 64), 3e-4, &mut rng);
    assert_eq!(stats.minibatches, 4);
    let (actor, critic, log_std, _) = ppo.model.to_plain();
    let policy = PolicyWeights {
        actor,
        critic,
        log_std,
        version: 1,
        ..p.clone()
    };
    assert_ne!(policy.actor, p.actor, "the update moved the weights");
    let dir = tempfile::tempdir().expect("tempdir");
    let ck = dir.path().join("checkpoint.bin");
    let meta = CheckpointMeta {
        seed: 1,
        update: 1,
        global_step: 64,
        episodes: 0,
        train_seconds: 0.0,
        config_toml: String::new(),
        policy: policy.clone(),
        return_acc: vec![0.5],
    };
    save_checkpoint(&ck, &meta, &ppo.model, &ppo.optim).expect("save");
    let loaded = load_checkpoint(&ck).expect("load");
    assert_eq!(loaded.meta.policy, policy);
    let (model2, optim2) = loaded
        .restore(&device, AdamConfig::new().with_epsilon(1e-5).init())
        .expect("restore");
    let (a2, c2, l2, _) = model2.to_plain();
    assert_eq!(
        (a2, c2, l2),
        (policy.actor.clone(), policy.critic.clone(), policy.log_std)
    );
    // Same actions, bit for bit, from the exported policy file too.
    let pol = dir.path().join("policy.bin");
    save_policy(&pol, &policy).expect("save policy");
    let back = load_policy(&pol).expect("load policy");
    let from_ck = load_policy(&ck).expect("policy from checkpoint");
    let mut s = Scratch::default();
    let obs = random_obs(&mut ChaCha8Rng::seed_from_u64(2), 1);
    let a = policy.act_deterministic(&obs, &mut s);
    assert_eq!(back.act_deterministic(&obs, &mut s), a);
    assert_eq!(from_ck.act_deterministic(&obs, &mut s), a);
    // The Adam moments came back: one more identical update gives identical weights.
    let mut ppo2 = Ppo::new(cfg, model2, device.clone());
    ppo2.optim = optim2;
    let b = small_batch(2, 64);
    ppo.update(&b, 3e-4, &mut ChaCha8Rng::seed_from_u64(3));
    ppo2.update(&b, 3e-4, &mut ChaCha8Rng::seed_from_u64(3));
    assert_eq!(ppo.model.to_plain(), ppo2.model.to_plain());
}

#[test]
fn corrupt_checkpoint_is_a_clear_error() {
    let dir = tempfile::tempdir().expect("tempdir");
    let f = dir.path().join("bad.bin");
    std::fs::write(&f, b"DUPACCKP\x01\x00\x00\x00garbage").expect("write");
    let e = load_checkpoint(&f).err().expect("must fail").to_string();
    assert!(e.contains("bad.bin"), "{e}");
    std::fs::write(&f, b"not a policy at all").expect("write");
    let e = load_policy(&f).expect_err("must fail").to_string();
    assert!(e.contains("bad.bin") && e.contains("magic"), "{e}");
}

/// The weights limit an actor derives from its configuration admits the learner's
/// real weights (for both site heads and wider networks), so a tight limit never drops them.
#[test]
fn real_weights_fit_the_limits_derived_from_the_configuration() {
    use dupac_common::config::{Config, SiteHead};
    use dupac_common::msg::{Header, MsgLimits, WeightsMsg, decode_msg, encode_msg};
    use dupac_common::obs::ObsLayout;
    let device = Device::flex();
    for (head, hidden) in [
        (SiteHead::Equivariant, vec![64, 64]),
        (SiteHead::Slots, vec![64, 64]),
        (SiteHead::Equivariant, vec![256, 256, 256]),
    ] {
        let mut cfg = Config::default();
        cfg.ppo.site_head = head;
        cfg.ppo.hidden = hidden;
        let n_sites = 30;
        let obs_dim = ObsLayout::new(&cfg.env.observation, n_sites).len();
        let learner = dupac_learner::learner::Learner::new(cfg.clone(), obs_dim, n_sites, &device);
        let msg = WeightsMsg {
            header: Header::new("r", 1, dupac_common::ids::ActorId::LEARNER, 2),
            policy: learner.policy(),
        };
        let bytes = encode_msg(&msg).expect("encode");
        let limits = MsgLimits::weights(&cfg, obs_dim, n_sites);
        assert!(
            bytes.len() <= limits.bytes,
            "{head:?}: {} > {}",
            bytes.len(),
            limits.bytes
        );
        let back: WeightsMsg = decode_msg(&bytes, limits, "weights").expect("within budget");
        assert_eq!(back.policy.version, msg.policy.version);
        assert!(limits.bytes <= MsgLimits::run_max_bytes(&cfg, obs_dim, n_sites));
    }
}

/// An update's broadcast with the default configuration (30 sites, the default networks and
/// observation) is at most 0.4 MB: the dense layers travel in half precision, and the policy
/// an actor decodes is the learner's rounded to it (each weight within 2⁻¹¹ of itself).
#[test]
fn the_default_weights_message_is_at_most_0_4_mb() {
    use dupac_common::config::Config;
    use dupac_common::msg::{Header, MsgLimits, WeightsMsg, decode_msg, encode_msg};
    use dupac_common::obs::ObsLayout;
    let cfg = Config::default();
    let n_sites = 30;
    let obs_dim = ObsLayout::new(&cfg.env.observation, n_sites).len();
    let learner =
        dupac_learner::learner::Learner::new(cfg.clone(), obs_dim, n_sites, &Device::flex());
    let policy = learner.policy();
    let msg = WeightsMsg {
        header: Header::new("dupac", 1, dupac_common::ids::ActorId::LEARNER, 2),
        policy: policy.clone(),
    };
    let bytes = encode_msg(&msg).expect("encode");
    println!("default weights message: {} bytes", bytes.len());
    assert!(bytes.len() <= 400_000, "{} bytes", bytes.len());
    let back: WeightsMsg = decode_msg(
        &bytes,
        MsgLimits::weights(&cfg, obs_dim, n_sites),
        "weights",
    )
    .expect("decode");
    let pairs = policy.actor.layers.iter().zip(&back.policy.actor.layers);
    for (a, b) in pairs {
        assert_eq!(a.bias, b.bias, "biases in full precision");
        for (x, y) in a.weight.iter().zip(&b.weight) {
            assert!(
                (x - y).abs() <= x.abs() * 2f32.powi(-11) + 6.2e-8,
                "{x} vs {y}"
            );
        }
    }
    assert_eq!(back.policy.obs_norm, policy.obs_norm);
}

/// The hidden layers' tanh on the CPU: its values are the actors' `tanh_f32` (to one rounding
/// of the linearisation) and its gradient is exactly `1 − h²` of those values; against burn's
/// own `tanh`, values and gradients agree to 1e-6.
#[test]
fn the_cpu_tanh_has_the_actors_values_and_the_gradient_of_its_output() {
    use dupac_common::policy::mlp::tanh_f32;
    use dupac_learner::model::fast_tanh;
    let device = Device::flex().autodiff();
    let xs: Vec<f32> = (-1200..=1200).map(|i| i as f32 * 0.01).collect();
    let n = xs.len();
    let grad_of = |f: fn(Tensor<2>) -> Tensor<2>| {
        let x = Tensor::<2>::from_data(TensorData::new(xs.clone(), [1, n]), &device).require_grad();
        let y = f(x.clone());
        let values = tensor_to_vec(y.clone());
        let g = y.sum().backward();
        (values, tensor_to_vec(x.grad(&g).expect("gradient")))
    };
    let (h, dh) = grad_of(fast_tanh::<2>);
    let (h_burn, dh_burn) = grad_of(burn::tensor::activation::tanh::<2>);
    for (k, &x) in xs.iter().enumerate() {
        let want = tanh_f32(x);
        assert!((h[k] - want).abs() <= 6e-8, "x = {x}: {} vs {want}", h[k]);
        assert_eq!(
            dh[k],
            1.0 - want * want,
            "x = {x}: the derivative of the output"
        );
        assert!((h[k] - h_burn[k]).abs() < 1e-6, "x = {x}");
        assert!(
            (dh[k] - dh_burn[k]).abs() < 1e-6,
            "x = {x}: {} vs {}",
            dh[k],
            dh_burn[k]
        );
    }
}
