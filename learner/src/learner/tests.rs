//! The learner's own tests: non-finite input and updates, stale data's proximal log-probs and
//! importance weights.

use super::*;
use dupac_common::msg::EnvTrajectory;
use dupac_common::policy::Scratch;

const OBS: usize = 5;
const SITES: usize = 4;

fn learner() -> Learner {
    let mut cfg = Config::default();
    cfg.ppo.hidden = vec![8];
    cfg.ppo.normalize_reward = false;
    cfg.ppo.normalize_obs = false;
    Learner::new(cfg, OBS, SITES, &burn::tensor::Device::flex())
}

/// A 3-step trajectory acted with `policy`, behaviour log-probs shifted by `lp_shift`.
fn traj(policy: &PolicyWeights, lp_shift: f32) -> EnvTrajectory {
    let t = 3;
    let obs: Vec<f32> = (0..t * OBS).map(|i| (i as f32 * 0.37).sin()).collect();
    let moves: Vec<f32> = (0..t * MOVE_DIM).map(|i| (i as f32 * 0.11).cos()).collect();
    let sites = vec![0, 3, 1];
    let mut s = Scratch::default();
    let logprobs = (0..t)
        .map(|k| {
            let mut m = [0.0; MOVE_DIM];
            m.copy_from_slice(&moves[k * MOVE_DIM..(k + 1) * MOVE_DIM]);
            policy.logprob(&obs[k * OBS..(k + 1) * OBS], &m, sites[k], &mut s) + lp_shift
        })
        .collect();
    EnvTrajectory {
        env: 0,
        obs_dim: OBS,
        obs,
        moves,
        sites,
        logprobs,
        site_logprobs: vec![0.0; t],
        site_rewards: vec![],
        decision_steps: vec![],
        step_site_features: vec![],
        step_site_rewards: vec![],
        values: vec![0.5, 0.25, 0.125],
        rewards: vec![1.0, -1.0, 2.0],
        terminated: vec![false; t],
        truncated: vec![false; t],
        // The actor's last bootstrap is deliberately wrong: the learner re-evaluates it.
        next_values: vec![0.25, 0.125, 123.0],
        bootstrap_obs: vec![0.3; OBS],
        episodes: vec![],
    }
}

fn seg(tr: &EnvTrajectory, version: u64) -> Segment<'_> {
    Segment {
        actor: ActorId(0),
        behaviour_version: version,
        traj: tr,
    }
}

/// A NaN or inf anywhere in the batch skips the update whole: weights, normalisers and
/// return accumulators as they were, the skip counted; `ppo.max_bad_updates` in a row stop
/// the run with an error naming the fault; a good update in between resets the streak.
#[test]
fn non_finite_input_never_reaches_the_weights() {
    let mut l = learner();
    l.cfg.ppo.max_bad_updates = 3;
    l.obs_norm.enabled = true;
    let p0 = l.policy();
    let good = traj(&p0, 0.0);
    let mut bad = good.clone();
    bad.rewards[1] = f32::NAN;
    let mut inf_obs = good.clone();
    inf_obs.obs[4] = f32::INFINITY;
    let t = Timings { collect_s: 0.0 };
    for (i, tr) in [&bad, &inf_obs].into_iter().enumerate() {
        let r = l
            .learn(&l.policy(), &[seg(tr, l.update)], t)
            .expect("below the limit");
        assert_eq!(r.row["numerics/skipped_update"], 1.0);
        assert_eq!(r.row["numerics/skipped_updates"], (i + 1) as f64);
        assert!(r.row["losses/policy_loss"].is_nan());
        let p = l.policy();
        assert_eq!(
            (p.actor, p.critic, p.log_std),
            (p0.actor.clone(), p0.critic.clone(), p0.log_std)
        );
        assert_eq!(p.obs_norm, p0.obs_norm, "the normaliser never saw the inf");
        assert!(
            l.return_acc.is_empty(),
            "no return accumulated from a NaN reward"
        );
    }
    // A good update resets the streak and changes the weights.
    let r = l
        .learn(&l.policy(), &[seg(&good, l.update)], t)
        .expect("good");
    assert_eq!(r.row["numerics/skipped_update"], 0.0);
    assert_ne!(l.policy().actor, p0.actor);
    let last_good = l.policy();
    for _ in 0..2 {
        l.learn(&l.policy(), &[seg(&bad, l.update)], t)
            .expect("below the limit");
    }
    let e = l
        .learn(&l.policy(), &[seg(&bad, l.update)], t)
        .expect_err("3 in a row");
    let msg = e.to_string();
    assert!(
        msg.contains("3 consecutive updates") && msg.contains("rewards[1] = NaN"),
        "{msg}"
    );
    assert_eq!(
        l.policy().actor,
        last_good.actor,
        "the last good weights stay"
    );
}

/// An update whose weights come out non-finite (here: a learning rate that overflows f32)
/// is undone: weights, Adam state and normalisers are the last good ones.
#[test]
fn an_update_that_makes_weights_non_finite_is_undone() {
    let mut l = learner();
    l.cfg.ppo.learning_rate = 1e39;
    l.cfg.ppo.anneal_lr = false;
    l.cfg.ppo.max_bad_updates = 0;
    let p0 = l.policy();
    let tr = traj(&p0, 0.0);
    let r = l
        .learn(&p0, &[seg(&tr, p0.version)], Timings { collect_s: 0.0 })
        .expect("max_bad_updates = 0 never stops");
    assert_eq!(r.row["numerics/skipped_update"], 1.0);
    let p = l.policy();
    assert!(p.actor.all_finite() && p.critic.all_finite());
    assert_eq!(
        (p.actor, p.critic, p.log_std),
        (p0.actor, p0.critic, p0.log_std)
    );
    assert_eq!(
        l.update, 1,
        "the skipped update still counts as an iteration"
    );
    // With a sane learning rate the same learner trains on.
    l.cfg.ppo.learning_rate = 3e-4;
    let r = l
        .learn(
            &l.policy(),
            &[seg(&tr, l.update)],
            Timings { collect_s: 0.0 },
        )
        .expect("good");
    assert_eq!(r.row["numerics/skipped_update"], 0.0);
    assert!(l.policy().actor.all_finite());
}

#[test]
fn data_of_the_current_version_is_plain_ppo() {
    let mut l = learner();
    let p = l.policy();
    let tr = traj(&p, 0.0);
    let b = l.assemble(
        &p,
        &[Segment {
            actor: ActorId(0),
            behaviour_version: p.version,
            traj: &tr,
        }],
    );
    assert_eq!(
        b.logprobs, tr.logprobs,
        "behaviour log-probs are the old ones"
    );
    assert!(b.is_weights.is_empty(), "no importance weights");
    // The last step bootstraps from V(bootstrap_obs) of the current critic.
    let v_boot = p.value(&tr.bootstrap_obs, &mut Scratch::default());
    let gamma = l.cfg.ppo.gamma as f32;
    let delta_last = 2.0 + gamma * v_boot - 0.125;
    assert!(
        (b.advantages[2] - delta_last).abs() < 1e-5,
        "{} vs {delta_last}",
        b.advantages[2]
    );
    assert!((b.returns[2] - (delta_last + 0.125)).abs() < 1e-5);
}

#[test]
fn older_data_gets_proximal_log_probs_and_capped_importance_weights() {
    let mut l = learner();
    let mut p = l.policy();
    p.version = 7;
    // μ = π_prox · e^−0.5 → weight e^0.5; μ = π_prox · e^−3 → e^3 capped at 2.
    let (near, far) = (traj(&p, -0.5), traj(&p, -3.0));
    let seg = |traj| Segment {
        actor: ActorId(1),
        behaviour_version: 6,
        traj,
    };
    let b = l.assemble(&p, &[seg(&near), seg(&far)]);
    for k in 0..3 {
        assert!(
            (b.logprobs[k] - (near.logprobs[k] + 0.5)).abs() < 1e-5,
            "proximal log-prob"
        );
        assert!(
            (b.is_weights[k] - 0.5f32.exp()).abs() < 1e-4,
            "{}",
            b.is_weights[k]
        );
        assert!(
            (b.is_weights[3 + k] - 2.0).abs() < 1e-6,
            "capped: {}",
            b.is_weights[3 + k]
        );
    }
    assert_eq!(l.off_policy_samples, 6);
}
