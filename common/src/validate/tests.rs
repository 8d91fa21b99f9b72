use super::*;
use crate::compact::{CompactShape, CompactTrajectory, StateRow, TrunkRow};
use crate::ids::ActorId;
use crate::msg::{
    Command, ControlMsg, EnvTrajectory, EpisodeSummary, Outcome, decode_msg, encode_msg,
};

fn lim(bytes: usize) -> MsgLimits {
    MsgLimits {
        bytes,
        budget_bytes: bytes,
    }
}

fn expect() -> ChunkExpect {
    ChunkExpect {
        run_id: "r".into(),
        incarnation: 7,
        fingerprint: 9,
        obs_dim: 2,
        n_sites: 3,
        max_envs: 4,
        max_steps: 8,
        site_steps: None,
    }
}

/// A compact chunk of two decisions, one state each (no learned site).
fn wire() -> TrajectoryChunk {
    let mut h = Header::new("r", 7, ActorId(1), 9);
    h.policy_version = 3;
    let shape = CompactShape {
        n_sites: 3,
        path_guide: false,
        path_offset: false,
        sensor_fan: false,
        learned: false,
        lookahead: 0,
        stay: false,
        true_rsrp_every_step: false,
    };
    let mut tr = CompactTrajectory {
        moves: vec![0.0; 6],
        sites: vec![0, 2],
        logprobs: vec![-1.0; 2],
        site_logprobs: vec![0.0; 2],
        values: vec![0.5; 2],
        rewards: vec![1.0; 2],
        terminated: vec![false, true],
        truncated: vec![false; 2],
        next_values: vec![0.5, 0.0],
        decision_steps: vec![1, 1],
        crashed: vec![false; 2],
        ..CompactTrajectory::default()
    };
    let state = StateRow {
        rsrp: vec![100, 0, 255],
        los: vec![0],
        ..StateRow::default()
    };
    for _ in 0..3 {
        tr.push_trunk(&shape, &TrunkRow::default());
        tr.push_state(&shape, &state);
    }
    assert_eq!(tr.shape_error(&shape, 1), None);
    TrajectoryChunk {
        header: h,
        trajectories: vec![tr],
    }
}

fn chunk() -> ExpandedChunk {
    let mut h = Header::new("r", 7, ActorId(1), 9);
    h.policy_version = 3;
    ExpandedChunk {
        header: h,
        trajectories: vec![EnvTrajectory {
            env: 0,
            obs_dim: 2,
            obs: vec![0.0; 4],
            moves: vec![0.0; 6],
            sites: vec![0, 2],
            logprobs: vec![-1.0; 2],
            site_logprobs: vec![0.0; 2],
            site_rewards: vec![],
            decision_steps: vec![],
            step_site_features: vec![],
            step_site_rewards: vec![],
            values: vec![0.5; 2],
            rewards: vec![1.0; 2],
            terminated: vec![false, true],
            truncated: vec![false; 2],
            next_values: vec![0.5, 0.0],
            bootstrap_obs: vec![0.0; 2],
            episodes: vec![],
        }],
    }
}

#[test]
fn a_valid_chunk_round_trips_and_passes() {
    let c = wire();
    let bytes = encode_msg(&c).expect("encode");
    let d: TrajectoryChunk = decode_msg(&bytes, lim(1 << 20), "k").expect("decode");
    assert_eq!(d, c);
    assert_eq!(validate_compact(&d, &expect()), Ok(()));
    assert_eq!(validate_chunk(&chunk(), &expect()), Ok(()));
}

/// Each defect of a chunk's header has its reason, whatever the chunk (`reason` validates
/// one with the header changed by its argument).
/// A validation of a chunk whose header its argument changes.
type HeaderCase<'a> = &'a dyn Fn(&dyn Fn(&mut Header)) -> Result<(), DropReason>;

fn header_defects(reason: HeaderCase<'_>) {
    assert_eq!(
        reason(&|h| h.run_id = "x".into()),
        Err(DropReason::WrongRun)
    );
    assert_eq!(reason(&|h| h.schema_version = 0), Err(DropReason::Schema));
    assert_eq!(
        reason(&|h| h.config_fingerprint = 1),
        Err(DropReason::Fingerprint)
    );
    assert_eq!(
        reason(&|h| h.learner_incarnation = 1),
        Err(DropReason::Incarnation)
    );
}

#[test]
fn every_defect_of_a_compact_chunk_has_its_reason() {
    let x = expect();
    let reason = |f: &dyn Fn(&mut TrajectoryChunk)| {
        let mut c = wire();
        f(&mut c);
        validate_compact(&c, &x).map_err(|r| r.reason)
    };
    assert_eq!(reason(&|_| {}), Ok(()));
    header_defects(&|f| reason(&|c| f(&mut c.header)));
    assert_eq!(
        reason(&|c| c.trajectories[0].sites[1] = 3),
        Err(DropReason::Dimensions)
    );
    assert_eq!(
        reason(&|c| c.trajectories = vec![c.trajectories[0].clone(); 5]),
        Err(DropReason::Dimensions)
    );
    assert_eq!(
        reason(&|c| c.trajectories[0].env = 4),
        Err(DropReason::Dimensions)
    );
    assert_eq!(
        reason(&|c| c.trajectories[0].rewards = vec![0.0; 9]),
        Err(DropReason::Dimensions)
    );
}

#[test]
fn every_defect_has_its_reason() {
    let x = expect();
    let reason = |f: &dyn Fn(&mut ExpandedChunk)| {
        let mut c = chunk();
        f(&mut c);
        validate_chunk(&c, &x).map_err(|r| r.reason)
    };
    header_defects(&|f| reason(&|c| f(&mut c.header)));
    assert_eq!(
        reason(&|c| c.trajectories[0].obs.push(0.0)),
        Err(DropReason::Dimensions)
    );
    assert_eq!(
        reason(&|c| c.trajectories[0].sites[1] = 3),
        Err(DropReason::Dimensions)
    );
    assert_eq!(
        reason(&|c| c.trajectories[0].obs_dim = 3),
        Err(DropReason::Dimensions)
    );
    assert_eq!(
        reason(&|c| c.trajectories = vec![c.trajectories[0].clone(); 5]),
        Err(DropReason::Dimensions)
    );
    assert_eq!(
        reason(&|c| c.trajectories[0].env = 4),
        Err(DropReason::Dimensions)
    );
    assert_eq!(
        reason(&|c| c.trajectories[0].rewards[0] = f32::NAN),
        Err(DropReason::NonFinite)
    );
    assert_eq!(
        reason(&|c| c.trajectories[0].bootstrap_obs[1] = f32::INFINITY),
        Err(DropReason::NonFinite)
    );
}

#[test]
fn decoding_names_garbage_schema_and_size() {
    let bytes = encode_msg(&wire()).expect("encode");
    let e = decode_msg::<TrajectoryChunk>(b"not a message at all", lim(1 << 20), "k")
        .expect_err("garbage");
    assert_eq!(DropReason::of_codec(&e), DropReason::Garbage);
    let mut old = bytes.clone();
    old[8..12].copy_from_slice(&0u32.to_le_bytes());
    let e = decode_msg::<TrajectoryChunk>(&old, lim(1 << 20), "k").expect_err("schema");
    assert_eq!(DropReason::of_codec(&e), DropReason::Schema);
    let e = decode_msg::<TrajectoryChunk>(&bytes, lim(16), "k").expect_err("size");
    assert_eq!(DropReason::of_codec(&e), DropReason::TooLarge);
    let mut cut = bytes.clone();
    cut.truncate(bytes.len() - 3);
    let e = decode_msg::<TrajectoryChunk>(&cut, lim(1 << 20), "k").expect_err("cut");
    assert_eq!(DropReason::of_codec(&e), DropReason::Garbage);
    // A message of another kind (a JSON control message) is not a chunk.
    let w = crate::jsonmsg::encode_json(&ControlMsg {
        header: Header::new("r", 7, ActorId::LEARNER, 9),
        command: Command::Stop,
    })
    .expect("encode");
    let e = decode_msg::<TrajectoryChunk>(&w, lim(1 << 20), "k").expect_err("kind");
    assert_eq!(DropReason::of_codec(&e), DropReason::Garbage);
}

/// A compact chunk with every vector at its largest for `shape`: `max_envs × max_steps`
/// decisions of `env.action_repeat` steps, one episode per decision.
fn maximal(x: &ChunkExpect, shape: &CompactShape, repeat: u16) -> TrajectoryChunk {
    let t = x.max_steps;
    let summary = EpisodeSummary {
        pair_id: u64::MAX,
        outcome: Outcome::TimeLimit,
        episodic_return: 1.0,
        length: u32::MAX,
        distance_flown_m: 1.0,
        shortest_m: 1.0,
        remaining_m: 1.0,
        mean_rsrp_dbm: -70.0,
        frac_excellent: 1.0,
        frac_mediocre: 0.0,
        frac_poor: 0.0,
        handovers: u32::MAX,
        ping_pongs: u32::MAX,
        mean_site_regret_db: 0.0,
        frac_site_regret_high: 0.0,
        frac_class_regret: 0.0,
    };
    let mut h = Header::new(&"r".repeat(64), u64::MAX, ActorId(u32::MAX), u64::MAX);
    h.seq = u64::MAX;
    h.sender_incarnation = u64::MAX;
    let m = shape.n_sites;
    let state = StateRow {
        position_m: [1.0; 3],
        velocity_xy: [u16::MAX; 2],
        serving: m as u16 - 1,
        ping_pong: m as u16,
        rsrp: vec![255; m],
        los: vec![255; shape.los_bytes()],
        lookahead: vec![255; m * shape.lookahead],
        stay: vec![255; if shape.stay { m } else { 0 }],
        choice: m as u16,
    };
    let trunk = TrunkRow {
        velocity_z: u16::MAX,
        ..TrunkRow::default()
    };
    let per = usize::from(repeat);
    // Steps with site rows: every decision's, when the site is learned.
    let rows = if shape.learned { t * per } else { 0 };
    let states = if shape.learned { t * per } else { t };
    TrajectoryChunk {
        header: h,
        trajectories: (0..x.max_envs)
            .map(|k| {
                let mut tr = CompactTrajectory {
                    env: k as u32,
                    moves: vec![1.0; t * MOVE_DIM],
                    sites: vec![x.n_sites.max(1) as u32 - 1; t],
                    logprobs: vec![1.0; t],
                    site_logprobs: vec![1.0; t],
                    values: vec![1.0; t],
                    rewards: vec![1.0; t],
                    terminated: vec![true; t],
                    truncated: vec![false; t],
                    next_values: vec![1.0; t],
                    decision_steps: vec![repeat; t],
                    crashed: vec![true; t],
                    progress_m: vec![1.0; rows],
                    common_reward: vec![1.0; rows],
                    reward_rsrp_codes: vec![255; rows * m],
                    episodes: vec![summary.clone(); t],
                    ..CompactTrajectory::default()
                };
                for _ in 0..=t {
                    tr.push_trunk(shape, &trunk);
                }
                for _ in 0..=states {
                    tr.push_state(shape, &state);
                }
                assert_eq!(tr.shape_error(shape, per), None);
                tr
            })
            .collect(),
    }
}

/// The budget derived from the expected shape ([`ChunkExpect::budget_bytes`], which also
/// bounds the expansion) admits the largest valid compact chunk, on the wire and decoded:
/// the default scenario's 30 sites, 5 steps per decision, three look-ahead distances, the
/// stay fractions and the true RSRP of every step (the largest per-state columns).
#[test]
fn the_largest_valid_chunk_fits_its_derived_limits() {
    let x = ChunkExpect {
        run_id: "r".repeat(64),
        obs_dim: 108 + 30 * 15,
        n_sites: 30,
        max_envs: 4,
        max_steps: 128,
        site_steps: Some(SiteSteps {
            per_decision: 5,
            features: 15,
        }),
        ..expect()
    };
    let shape = CompactShape {
        n_sites: 30,
        path_guide: true,
        path_offset: true,
        sensor_fan: true,
        learned: true,
        lookahead: 3,
        stay: true,
        true_rsrp_every_step: true,
    };
    let c = maximal(&x, &shape, 5);
    let bytes = encode_msg(&c).expect("encode");
    let need = x.budget_bytes();
    assert!(bytes.len() <= need, "{} > {need}", bytes.len());
    let d: TrajectoryChunk =
        decode_msg(&bytes, MsgLimits::both(need), "k").expect("fits its budget");
    assert_eq!(d, c);
    assert_eq!(d.samples(), 4 * 128);
    // The base method's: one state per decision, no site rows.
    let base = ChunkExpect {
        obs_dim: 108 + 30 * 11,
        n_sites: 0,
        site_steps: None,
        ..x.clone()
    };
    let shape = CompactShape {
        learned: false,
        lookahead: 0,
        stay: false,
        ..shape
    };
    let c = maximal(&base, &shape, 5);
    let bytes = encode_msg(&c).expect("encode");
    let need = base.budget_bytes();
    assert!(bytes.len() <= need, "{} > {need}", bytes.len());
    decode_msg::<TrajectoryChunk>(&bytes, MsgLimits::both(need), "k").expect("fits");
}

/// The per-step site fields (`env.site_every_step`) are checked against their shape: each
/// defect is refused with a message naming the field, and none is accepted when the run
/// does not choose the site every step.
#[test]
fn per_step_site_fields_are_checked_against_their_shape() {
    let x = ChunkExpect {
        site_steps: Some(SiteSteps {
            per_decision: 2,
            features: 4,
        }),
        ..expect()
    };
    let good = |c: &mut ExpandedChunk| {
        let tr = &mut c.trajectories[0];
        tr.decision_steps = vec![2, 1];
        tr.step_site_features = vec![0.5; 3 * 3 * 4];
        tr.step_site_rewards = vec![-1.0; 3 * 3];
    };
    let mut c = chunk();
    good(&mut c);
    assert_eq!(validate_chunk(&c, &x), Ok(()));
    let message = |f: &dyn Fn(&mut EnvTrajectory)| {
        let mut c = chunk();
        good(&mut c);
        f(&mut c.trajectories[0]);
        validate_chunk(&c, &x).map(|_| ()).map_err(|r| {
            assert_eq!(r.reason, DropReason::Dimensions);
            r.detail
        })
    };
    let err = |f: &dyn Fn(&mut EnvTrajectory), want: &str| {
        let e = message(f).expect_err(want);
        assert!(e.contains(want), "{e:?} should name {want}");
    };
    err(
        &|t| t.decision_steps = vec![2],
        "decision_steps has 1 values",
    );
    err(&|t| t.decision_steps = vec![3, 0], "a decision of 3 steps");
    err(&|t| t.decision_steps = vec![0, 2], "a decision of 0 steps");
    err(
        &|t| {
            t.step_site_features.pop();
        },
        "step_site_features",
    );
    err(&|t| t.step_site_rewards.push(0.0), "step_site_rewards");
    err(
        &|t| t.site_rewards = vec![0.0; 6],
        "site_rewards with per-step",
    );
    let mut nan = chunk();
    good(&mut nan);
    nan.trajectories[0].step_site_rewards[4] = f32::NAN;
    assert_eq!(
        validate_chunk(&nan, &x).map_err(|r| r.reason),
        Err(DropReason::NonFinite)
    );
    // A run without per-step sites refuses them.
    let r = validate_chunk(&c, &expect()).expect_err("not expected");
    assert!(r.detail.contains("env.site_every_step is off"), "{r:?}");
}

#[test]
fn an_amplifying_chunk_is_refused_while_decoding() {
    // 200 000 empty trajectories: ≈ 6 MB on the wire, ≈ 150 MB decoded. Under a byte
    // limit that admits it, the budget of a 4 × 128-step chunk refuses it.
    let x = expect();
    let mut c = wire();
    c.trajectories = vec![CompactTrajectory::default(); 200_000];
    let bytes = encode_msg(&c).expect("encode");
    let limits = MsgLimits {
        bytes: 64 << 20,
        budget_bytes: x.budget_bytes(),
    };
    let e = decode_msg::<TrajectoryChunk>(&bytes, limits, "k").expect_err("amplifying");
    assert!(e.to_string().contains("budget"), "{e}");
    assert_eq!(DropReason::of_codec(&e), DropReason::TooLarge);
}
