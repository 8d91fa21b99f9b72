//! The compact trajectory and its expansion (`dupac_actor::expand`): what an actor sends
//! expands to exactly the observations, site features and counterfactual rewards the
//! environment gave it; a hostile trajectory never panics the expansion.

use super::*;
use dupac_actor::expand::Expander;
use dupac_actor::rollout::{record_decision, record_observation};
use dupac_common::compact::{CompactTrajectory, code};
use proptest::prelude::*;

/// The sites trade places along y, off the RSRP codes' 0.5 dB grid (−70.13 dBm …).
const OFF_GRID: fn(usize, Point) -> f64 = |s, p| {
    if s == 0 {
        -70.13 - 0.37 * p[1]
    } else {
        -104.91 + 0.41 * p[1]
    }
};

/// Flies `decisions` decisions of a learned site (chosen at every step with the default
/// `env.site_every_step`, or once per decision without) and records them as a rollout does.
/// Returns the trajectory sent, the expansion, and what the environment gave: every
/// observation, the features each choice was made on, and every site's reward.
fn fly(
    cfg: &Config,
    decisions: usize,
) -> (CompactTrajectory, Env, Vec<Vec<f32>>, Vec<f32>, Vec<f64>) {
    let mut e = Env::new(cfg, world(), Arc::new(Field(OFF_GRID, 2))).expect("env");
    e.reset(
        3,
        ep(Point::new(0.0, -100.0, 50.0), Point::new(0.0, 150.0, 50.0)),
    )
    .expect("reset");
    let mut c = CompactTrajectory::default();
    let (mut seen, mut feats, mut rewards) = (Vec::new(), Vec::new(), Vec::new());
    let seq = |t: usize| SiteId([0u16, 1, 1, 0, 1, 0, 0, 1, 1, 1, 0][t % 11]);
    let mut t0 = 0;
    for _ in 0..decisions {
        record_observation(&mut c, &e);
        seen.push(e.observation().to_vec());
        let move_ = Vector::new(0.1, 1.0, 0.05);
        let s = if e.site_every_step() {
            e.act_site_every_step(move_, |k, f| {
                feats.extend_from_slice(f);
                seq(t0 + k)
            })
            .expect("act")
        } else {
            e.act(&Action {
                move_,
                site: seq(t0),
            })
            .expect("act")
        };
        rewards.extend_from_slice(if e.site_every_step() {
            e.step_site_rewards()
        } else {
            e.site_rewards()
        });
        t0 += e.substeps().len();
        record_decision(&mut c, &e);
        c.moves.extend_from_slice(&[0.1, 1.0, 0.05]);
        c.sites.push(0);
        c.logprobs.push(-1.0);
        c.site_logprobs.push(-0.5);
        c.values.push(0.0);
        c.rewards.push(s.reward as f32);
        c.terminated.push(s.terminated);
        c.truncated.push(s.truncated);
        c.next_values.push(0.0);
        assert!(
            !(s.terminated || s.truncated),
            "the flight outlasts the test"
        );
    }
    record_observation(&mut c, &e);
    (c, e, seen, feats, rewards)
}

/// The learner's expansion of what the actor sends is what the actor acted on, bit for bit:
/// every observation, the site features of every step's choice, the bootstrap observation;
/// every site's reward is the environment's own. With the RSRP off the codes' grid, the chosen
/// site's entry is the step's reward within the codes' resolution (classes exact). Checked to
/// fail with the actor acting on its exact RSRP instead of the codes.
#[test]
fn the_expansion_of_what_an_actor_sends_is_what_it_acted_on() {
    let mut cfg = unguided();
    cfg.env.association = Association::Learned;
    assert!(cfg.env.site_every_step);
    for every_step in [true, false] {
        cfg.env.site_every_step = every_step;
        let (c, e, seen, feats, rewards) = fly(&cfg, 12);
        let x = Expander::new(&cfg, e.world());
        assert_eq!(c.shape_error(x.shape(), 5), None);
        let tr = x.trajectory(&c, usize::MAX).expect("expands");
        let d = e.layout().len();
        for (t, obs) in seen.iter().enumerate() {
            assert_eq!(&tr.obs[t * d..(t + 1) * d], &obs[..], "observation {t}");
        }
        assert_eq!(tr.bootstrap_obs, e.observation());
        let got = if every_step {
            assert_eq!(tr.step_site_features, feats, "every choice's features");
            &tr.step_site_rewards
        } else {
            assert!(tr.step_site_features.is_empty());
            &tr.site_rewards
        };
        let want: Vec<f32> = rewards.iter().map(|&r| r as f32).collect();
        assert_eq!(got, &want, "every site's rewards");
    }
    // Off the grid: the chosen site's entry against the step's reward. The codes round RSRP
    // down by < 0.5 dB: the regret term (weight κ) and Eq. (8)'s mediocre and poor terms
    // (μ2, μ3 per dB) move by less than 0.5·(κ + |μ2| + |μ3|).
    cfg.env.site_every_step = true;
    let r = &cfg.env.reward;
    let bound = 0.5 * (r.site_regret_weight + r.mu2.abs() + r.mu3.abs());
    let mut e = Env::new(&cfg, world(), Arc::new(Field(OFF_GRID, 2))).expect("env");
    e.reset(
        3,
        ep(Point::new(0.0, -100.0, 50.0), Point::new(0.0, 150.0, 50.0)),
    )
    .expect("reset");
    let mut worst = 0.0f64;
    for _ in 0..12 {
        e.act_site_every_step(Vector::new(0.0, 1.0, 0.0), |_, _| SiteId(1))
            .expect("act");
        for (k, info) in e.substeps().iter().enumerate() {
            let entry = e.step_site_rewards()[2 * k + 1];
            worst = worst.max((entry - info.reward).abs());
        }
    }
    assert!(worst > 0.0 && worst < bound, "{worst} vs {bound}");
}

/// The RSRP classes the rewards score are exact under the codes: every class boundary is a
/// grid value and the codes round down.
#[test]
fn the_rsrp_codes_keep_every_class() {
    let t = dupac_radio::class::RsrpThresholds::default();
    let mut dbm = -150.0;
    while dbm < -30.0 {
        assert_eq!(
            t.classify(code::rsrp_dbm(code::rsrp(dbm))),
            t.classify(dbm),
            "{dbm}"
        );
        dbm += 0.01;
    }
}

/// A mutated column (one value too many or too few, a site index past M, NaN) of a valid
/// trajectory.
fn mutate(c: &mut CompactTrajectory, which: usize, how: u8) {
    fn set<T>(v: &mut [T], how: u8, x: T) {
        if !v.is_empty() {
            let k = usize::from(how) % v.len();
            v[k] = x;
        }
    }
    match which % 12 {
        0 if how.is_multiple_of(2) => c.rsrp_codes.push(how),
        0 => drop(c.rsrp_codes.pop()),
        1 => set(&mut c.serving, how, u16::from(how) + 2),
        2 => set(&mut c.ping_pong, how, u16::MAX),
        3 => drop(c.position_m.pop()),
        4 => set(&mut c.decision_steps, how, u16::from(how)),
        5 => drop(c.trunk_codes.pop()),
        6 => c.progress_m.push(1.0),
        7 => drop(c.reward_rsrp_codes.pop()),
        8 => set(&mut c.position_m, how, f32::NAN),
        9 => drop(c.los_bits.pop()),
        10 => c.velocity_codes.push(how),
        _ => drop(c.crashed.pop()),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Whatever a peer sends, the expansion returns a trajectory or an error, never panics,
    /// and an accepted trajectory has the documented shape.
    #[test]
    fn a_mutated_trajectory_never_panics_the_expansion(
        muts in proptest::collection::vec((any::<usize>(), any::<u8>()), 1..4),
        seed in any::<u64>(),
    ) {
        let mut cfg = unguided();
        cfg.env.association = Association::Learned;
        let x = Expander::new(&cfg, &world());
        let mut c = x.sample_trajectory(6, seed);
        for (which, how) in muts {
            mutate(&mut c, which, how);
        }
        if let Ok(tr) = x.trajectory(&c, usize::MAX) {
            prop_assert_eq!(tr.obs.len(), 6 * x.layout().len());
        }
    }
}
