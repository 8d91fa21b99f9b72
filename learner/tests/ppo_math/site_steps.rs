//! `env.site_every_step`: a later step's site scores, the site head learning from per-step rows,
//! and the per-step site loss against the actors' plain forward.

use super::*;

/// `env.site_every_step`: a later step of a decision is scored with the decision's
/// state embedding and that step's own site features. The actors' `step_site_logits` equal the
/// plain forward of an observation with the decision's trunk and the step's features, and the
/// burn model's `step_site_logp` over the decision's actor hidden activation gives the same
/// log-probabilities to 1e-5.
#[test]
fn a_later_steps_site_scores_hold_the_decisions_embedding() {
    let device = Device::flex();
    let p = equivariant_policy(4);
    let model = model_of(&p, &device);
    let d = p.obs_dim;
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut s = Scratch::default();
    for _ in 0..16 {
        let row: Vec<f32> = (0..d).map(|_| rng.random_range(-2.0..2.0)).collect();
        let feats: Vec<f32> = (0..SITES * FEATS)
            .map(|_| rng.random_range(-2.0..2.0))
            .collect();
        p.act_deterministic(&row, &mut s);
        let step = p.step_site_logits(&feats, &mut s).to_vec();
        let mut later = row.clone();
        later[OBS..].copy_from_slice(&feats);
        let (h, _) = p.forward(&later, &mut s);
        for j in 0..SITES {
            assert!((step[j] - h[MOVE_DIM + j]).abs() < 1e-6, "site {j}");
        }
        // burn: the decision row's hidden activation with the step's features.
        let mut norm = vec![0.0f32; d];
        p.obs_norm.apply(&row, &mut norm);
        norm[OBS..].copy_from_slice(&row[OBS..]);
        let x = Tensor::<2>::from_data(TensorData::new(norm, [1, d]), &device);
        let ev = model.evaluate(
            x,
            Tensor::<2>::zeros([1, MOVE_DIM], &device),
            Tensor::<1, Int>::zeros([1], &device),
        );
        let hidden = ev.actor_hidden.expect("equivariant head");
        let f = Tensor::<2>::from_data(TensorData::new(feats.clone(), [1, SITES * FEATS]), &device);
        let parent = Tensor::<1, Int>::zeros([1], &device);
        let lp = tensor_to_vec(model.step_site_logp(hidden, parent, f));
        let want = log_softmax(&step);
        for j in 0..SITES {
            assert!(
                (lp[j] - want[j]).abs() < 1e-5,
                "site {j}: {} vs {}",
                lp[j],
                want[j]
            );
        }
    }
}

/// `env.site_every_step`: the site head learns from the per-step rows alone (no decision-level
/// site rewards in the batch). Each step's every-site reward is its site's first feature, so the
/// best site of a step is the one whose first feature is largest; after a few updates the
/// per-step scores pick it on fresh steps far more often than at the start (chance: 1 in 4).
#[test]
fn the_site_head_learns_from_every_steps_site_rewards() {
    let device = Device::flex().autodiff();
    let p = equivariant_policy(5);
    let mut rng = ChaCha8Rng::seed_from_u64(21);
    let (n, per) = (64usize, 3usize);
    let make_steps = |rng: &mut ChaCha8Rng, rows: usize| -> (Vec<f32>, Vec<f32>) {
        let feats: Vec<f32> = (0..rows * SITES * FEATS)
            .map(|_| rng.random_range(-1.0f32..1.0))
            .collect();
        let rewards = (0..rows * SITES).map(|k| feats[k * FEATS]).collect();
        (feats, rewards)
    };
    let accuracy = |p: &PolicyWeights, rng: &mut ChaCha8Rng| {
        let mut s = Scratch::default();
        let mut hits = 0;
        for _ in 0..200 {
            let row: Vec<f32> = (0..p.obs_dim)
                .map(|_| rng.random_range(-1.0..1.0))
                .collect();
            p.act_deterministic(&row, &mut s);
            let (f, r) = make_steps(rng, 1);
            let l = p.step_site_logits(&f, &mut s).to_vec();
            let pick = dupac_common::policy::argmax(&l);
            let best = dupac_common::policy::argmax(&r);
            hits += usize::from(pick == best);
        }
        hits as f64 / 200.0
    };
    let before = accuracy(&p, &mut ChaCha8Rng::seed_from_u64(3));
    let mut batch = small_batch(6, n);
    batch.obs_dim = p.obs_dim;
    batch.obs = (0..n * p.obs_dim)
        .map(|_| rng.random_range(-1.0f32..1.0))
        .collect();
    let (feats, rewards) = make_steps(&mut rng, n * per);
    batch.step_site_features = feats;
    batch.step_site_rewards = rewards;
    batch.step_offsets = (0..=n).map(|i| i * per).collect();
    assert!(batch.per_step_rows(FEATS));
    // One step of each decision per minibatch (`ppo::SITE_STEP_ROWS`).
    let cfg = dupac_common::config::PpoConfig {
        num_minibatches: 2,
        update_epochs: 4,
        ..Default::default()
    };
    let mut ppo = Ppo::new(cfg, ActorCritic::from_policy(&p, &device), device.clone());
    for _ in 0..15 {
        let stats = ppo.update(&batch, 3e-3, &mut rng);
        assert!(stats.site_loss.is_finite());
    }
    let (actor, critic, log_std, site) = ppo.model.valid().to_plain();
    let learned = PolicyWeights {
        actor,
        critic,
        log_std,
        site_head: site,
        ..p.clone()
    };
    let after = accuracy(&learned, &mut ChaCha8Rng::seed_from_u64(3));
    assert!(
        after > 0.8 && after > before + 0.3,
        "picks the best site on {after} of fresh steps (before: {before})"
    );
}

/// `env.site_every_step`: the learner's per-step site loss against the actors' plain forward on
/// a shuffled minibatch of decisions with uneven step counts (3, 1, 5, 2): each step read
/// ([`SITE_STEP_ROWS`] of each decision, drawn with the update's RNG) is scored with its own
/// decision's embedding and its own features, against its own every-site rewards, and the loss
/// is `−mean_r Σ_k π(k|r) Â_{r,k}` over the steps read.
#[test]
fn the_per_step_site_loss_reads_each_step_with_its_own_decision() {
    let device = Device::flex().autodiff();
    let p = equivariant_policy(7);
    let d = p.obs_dim;
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let steps = [3usize, 1, 5, 2];
    let n = steps.len();
    let raw: Vec<f32> = (0..n * d).map(|_| rng.random_range(-2.0..2.0)).collect();
    let mut batch = small_batch(1, n);
    batch.obs_dim = d;
    batch.obs = vec![0.0; n * d];
    for (r, o) in raw.chunks(d).zip(batch.obs.chunks_mut(d)) {
        p.obs_norm.apply(r, o);
        o[OBS..].copy_from_slice(&r[OBS..]);
    }
    batch.step_offsets = std::iter::once(0)
        .chain(steps.iter().scan(0, |acc, &k| {
            *acc += k;
            Some(*acc)
        }))
        .collect();
    let total_rows: usize = steps.iter().sum();
    let fw = SITES * FEATS;
    batch.step_site_features = (0..total_rows * fw)
        .map(|_| rng.random_range(-2.0f32..2.0))
        .collect();
    batch.step_site_rewards = (0..total_rows * SITES)
        .map(|_| rng.random_range(-3.0f32..1.0))
        .collect();
    assert!(batch.per_step_rows(FEATS));
    let cfg = dupac_common::config::PpoConfig::default();
    let norm_adv = cfg.norm_adv;
    let ppo = Ppo::new(cfg, model_of(&p, &device), device.clone());
    let idx = [2usize, 0, 3, 1];
    let obs: Vec<f32> = idx
        .iter()
        .flat_map(|&i| batch.obs[i * d..(i + 1) * d].to_vec())
        .collect();
    let ev = ppo.model.evaluate(
        Tensor::<2>::from_data(TensorData::new(obs, [n, d]), &device),
        Tensor::<2>::zeros([n, MOVE_DIM], &device),
        Tensor::<1, Int>::zeros([n], &device),
    );
    let hidden = ev.actor_hidden.expect("equivariant head");
    // The steps the loss reads: the same draws from a copy of its RNG.
    let mut draws = rng.clone();
    let rows: Vec<(usize, usize)> = idx
        .iter()
        .flat_map(|&i| {
            let mut steps: Vec<usize> =
                (batch.step_offsets[i]..batch.step_offsets[i + 1]).collect();
            if steps.len() > SITE_STEP_ROWS {
                steps = steps.partial_shuffle(&mut draws, SITE_STEP_ROWS).0.to_vec();
            }
            steps.into_iter().map(move |r| (i, r))
        })
        .collect();
    assert_eq!(rows.len(), idx.len() * SITE_STEP_ROWS);
    let got = ppo
        .step_site_loss(&batch, &idx, hidden, &mut rng)
        .0
        .into_scalar::<f32>();
    // By hand: the rows in the minibatch's order, each through the plain forward.
    let adv = site_advantages(
        &batch.step_site_rewards,
        &rows.iter().map(|&(_, r)| r).collect::<Vec<_>>(),
        SITES,
        norm_adv,
    );
    let mut s = Scratch::default();
    let mut sum = 0.0f64;
    for (q, &(i, r)) in rows.iter().enumerate() {
        p.act_deterministic(&raw[i * d..(i + 1) * d], &mut s);
        let l = p.step_site_logits(&batch.step_site_features[r * fw..(r + 1) * fw], &mut s);
        let max = l.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
        let z: f64 = l.iter().map(|&v| f64::from(v - max).exp()).sum();
        for k in 0..SITES {
            let pi = f64::from(l[k] - max).exp() / z;
            sum += pi * f64::from(adv[q * SITES + k]);
        }
    }
    let want = -sum / rows.len() as f64;
    assert!(
        (f64::from(got) - want).abs() < 1e-5,
        "loss {got} vs by hand {want}"
    );
}
