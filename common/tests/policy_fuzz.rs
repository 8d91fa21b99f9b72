//! Property tests of policies as files and weights messages carry them: a policy
//! with any one field set to a hostile value, or a weights message with bytes flipped, either
//! fails validation with a message or acts without a panic (e.g. a NaN `obs_norm.clip`, which
//! would panic every actor and pilot that received it).

use dupac_common::ids::ActorId;
use dupac_common::msg::{Header, MsgLimits, WeightsMsg, decode_msg, encode_msg};
use dupac_common::normalize::{ObsNormalizer, RewardScaler};
use dupac_common::obs::OBS_VERSION;
use dupac_common::policy::mlp::{Dense, Mlp};
use dupac_common::policy::{MOVE_DIM, PolicyWeights, Scratch};
use dupac_common::validate::{ChunkExpect, DropReason, SiteSteps, validate_weights};
use proptest::prelude::*;

const OBS: usize = 6;
const SITES: usize = 2;

fn dense(n_in: usize, n_out: usize, seed: f32) -> Dense {
    Dense {
        n_in,
        n_out,
        weight: (0..n_in * n_out)
            .map(|i| ((i as f32 + seed) * 0.37).sin() * 0.3)
            .collect(),
        bias: vec![0.01; n_out],
    }
}

/// A small valid slot-head policy: 6 observations, 2 sites, one hidden layer of 4.
fn policy() -> PolicyWeights {
    PolicyWeights {
        version: 3,
        obs_version: OBS_VERSION,
        obs_dim: OBS,
        n_sites: SITES,
        actor: Mlp {
            layers: vec![dense(OBS, 4, 1.0), dense(4, MOVE_DIM + SITES, 2.0)],
        },
        critic: Mlp {
            layers: vec![dense(OBS, 4, 3.0), dense(4, 1, 4.0)],
        },
        site_head: None,
        log_std: [-0.5; MOVE_DIM],
        obs_norm: ObsNormalizer::new(OBS, true, 5.0),
        reward_scaler: RewardScaler::new(true, 0.95, 10.0),
        // Too small for any observation layout to describe: records none.
        observation: None,
    }
}

const HOSTILE: &[f64] = &[
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    -1.0,
    0.0,
    1e308,
    -1e308,
    1e-308,
    4294967296.0,
];

/// Sets field `which` of `p` to `v` (numbers, lengths and shapes alike).
fn set_field(p: &mut PolicyWeights, which: usize, v: f64) {
    let n = |v: f64| {
        if v.is_finite() && v >= 0.0 {
            (v as usize).min(1 << 20)
        } else {
            0
        }
    };
    match which % 18 {
        0 => p.obs_norm.clip = v,
        1 => p.obs_norm.stats.mean[0] = v,
        2 => p.obs_norm.stats.var[1] = v,
        3 => p.obs_norm.stats.count = v,
        4 => p.reward_scaler.clip = v,
        5 => p.reward_scaler.gamma = v,
        6 => p.reward_scaler.stats.var[0] = v,
        7 => p.log_std[1] = v as f32,
        8 => p.actor.layers[0].weight[3] = v as f32,
        9 => p.critic.layers[1].bias[0] = v as f32,
        10 => p.obs_dim = n(v),
        11 => p.n_sites = n(v),
        12 => p.actor.layers[1].n_in = n(v),
        13 => p.actor.layers[0].weight.truncate(n(v)),
        14 => p.obs_norm.stats.mean.truncate(n(v)),
        15 => {
            p.observation
                .get_or_insert_with(Default::default)
                .rsrp_scale_db = v
        }
        16 => {
            p.observation
                .get_or_insert_with(Default::default)
                .sensor_range_m = v
        }
        _ => p.obs_version = n(v) as u32,
    }
}

/// What an actor does with a policy it accepted.
fn act(p: &PolicyWeights) {
    let mut s = Scratch::default();
    for obs in [
        vec![0.0f32; p.obs_dim],
        vec![1e30f32; p.obs_dim],
        vec![-3.0f32; p.obs_dim],
    ] {
        let a = p.act_deterministic(&obs, &mut s);
        let mut k = 0.0;
        let b = p.act_sample(&obs, &mut s, || {
            k += 0.37;
            k % 1.0
        });
        assert!((a.site as usize) < p.n_sites.max(1) && (b.site as usize) < p.n_sites.max(1));
        let _ = p.value(&obs, &mut s);
    }
}

fn expect() -> ChunkExpect {
    ChunkExpect {
        run_id: "r".into(),
        incarnation: 1,
        fingerprint: 2,
        obs_dim: OBS,
        n_sites: SITES,
        max_envs: 4,
        max_steps: 8,
        site_steps: None,
    }
}

/// With the site chosen every step (`env.site_every_step`), weights without the equivariant site
/// head over the run's features are refused as a dimension drop: an actor could not score a
/// later step with them (its rollout would stop with an error instead).
#[test]
fn weights_without_the_equivariant_head_are_refused_when_the_site_is_chosen_every_step() {
    let msg = WeightsMsg {
        header: Header::new("r", 1, ActorId::LEARNER, 2),
        policy: policy(),
    };
    assert_eq!(validate_weights(&msg, &expect()), Ok(()));
    let per_step = ChunkExpect {
        site_steps: Some(SiteSteps {
            per_decision: 5,
            features: 3,
        }),
        ..expect()
    };
    let r = validate_weights(&msg, &per_step).expect_err("slot head");
    assert_eq!(r.reason, DropReason::Dimensions);
    assert!(r.detail.contains("env.site_every_step"), "{r:?}");
}

#[test]
fn the_valid_policy_acts() {
    let p = policy();
    assert_eq!(p.validate(), Ok(()));
    act(&p);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    #[test]
    fn a_policy_with_a_hostile_field_is_refused_or_acts(
        which in 0usize..18,
        v in prop::sample::select(HOSTILE),
    ) {
        let mut p = policy();
        set_field(&mut p, which, v);
        if p.validate().is_ok() {
            act(&p);
        }
    }

    #[test]
    fn a_weights_message_with_flipped_bytes_is_refused_or_acts(
        flips in prop::collection::vec((any::<usize>(), any::<u8>()), 1..6),
    ) {
        let msg = WeightsMsg {
            header: Header::new("r", 1, ActorId::LEARNER, 2),
            policy: policy(),
        };
        let mut bytes = encode_msg(&msg).expect("encode");
        for (at, x) in flips {
            let i = 12 + at % (bytes.len() - 12);
            bytes[i] ^= x;
        }
        if let Ok(w) = decode_msg::<WeightsMsg>(&bytes, MsgLimits::both(1 << 20), "fuzz")
            && validate_weights(&w, &expect()).is_ok()
        {
            act(&w.policy);
        }
    }
}

/// The observation a policy records (scales and flags its weights' shapes do not
/// show) is what it is flown with, and what an actor or a resumed learner must share; a hostile
/// one is refused by key.
#[test]
fn a_policy_is_flown_with_the_observation_it_records() {
    use dupac_common::config::{Config, ObservationConfig};
    let cfg = Config::default();
    let mut other = ObservationConfig {
        rsrp_centre_dbm: -80.0,
        site_ping_pong: false,
        ..ObservationConfig::default()
    };
    let mut p = policy();
    p.observation = Some(other.clone());
    let flown = p.configure(&cfg).expect("flown");
    assert_eq!(flown.env.observation, other);
    assert_eq!(flown.env.site_every_step, cfg.env.site_every_step);
    let e = p
        .check_observation(&cfg.env.observation)
        .expect_err("another");
    assert!(
        e.contains("env.observation.site_ping_pong: false vs true")
            && e.contains("env.observation.rsrp_centre_dbm: -80"),
        "{e}"
    );
    assert_eq!(p.check_observation(&other), Ok(()));
    // One built in code without a record: not flown; its length is checked apart.
    p.observation = None;
    let e = p.configure(&cfg).expect_err("no record");
    assert!(e.contains("records no observation"), "{e}");
    assert_eq!(p.check_observation(&cfg.env.observation), Ok(()));
    // A hostile record is refused by its key, by validation and by `configure`.
    other.rsrp_scale_db = f64::NAN;
    p.observation = Some(other);
    let e = p.validate().expect_err("NaN scale");
    assert!(e.contains("env.observation.rsrp_scale_db"), "{e}");
    let e = p.configure(&cfg).expect_err("NaN scale");
    assert!(e.contains("env.observation.rsrp_scale_db"), "{e}");
}
