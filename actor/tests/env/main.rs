//! Environment tests on hand-built geometry with a scripted RSRP field.

use dupac_actor::env::{Action, Env, EnvError, Episode};
use dupac_common::config::{ActionClip, Association, Config};
use dupac_common::geometry::{Bounds2, Point, Vector};
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;
use dupac_common::obs::field;
use dupac_radio::city::{Building, City};
use dupac_radio::class::RsrpClass;
use dupac_radio::sites::{Mount, Site, SiteKind};
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use std::sync::Arc;

mod channel;
mod lookahead;
mod observation;
mod sites;
mod wire;

/// A scripted RSRP field: site `s` gives `f(s, p)`.
struct Field(fn(usize, Point) -> f64, usize);

impl RsrpSource for Field {
    fn num_sites(&self) -> usize {
        self.1
    }
    fn rsrp_all_dbm(&self, p: Point, out: &mut [f64]) {
        for (s, o) in out.iter_mut().enumerate().take(self.1) {
            *o = (self.0)(s, p);
        }
    }
}

fn block(id: &str, x0: f64, y0: f64, x1: f64, y1: f64, z0: f64, z1: f64) -> Building {
    Building {
        id: id.into(),
        outer_m: vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
        holes_m: vec![],
        z_min_m: z0,
        z_max_m: z1,
    }
}

fn site(id: u16, xyz: Point) -> Site {
    Site {
        id: SiteId(id),
        name: format!("s{id}"),
        position_m: xyz,
        kind: SiteKind::Macro,
        boresights_deg: vec![30.0, 150.0, 270.0],
        electrical_tilt_deg: 10.0,
        tx_power_dbm: 15.2,
        mount: Mount::User,
    }
}

/// Today's defaults with the path guide off and the paper's straight-line progress: these tests
/// fly hand-made episodes without a planned path (the guide has its own test below).
fn unguided() -> Config {
    let mut cfg = Config::default();
    cfg.env.observation.path_guide = false;
    cfg.env.reward.progress = dupac_common::config::Progress::Straight;
    cfg
}

/// 400 m square; a 60 m block at x ∈ [50, 70]; a 1 m thin part at x ∈ [−50, −49], y ∈ [−20, 20],
/// 0–100 m; two sites.
fn world() -> Arc<RadioWorld> {
    let cfg = unguided();
    let city = City::from_buildings(
        "test",
        Bounds2::new(-200.0, -200.0, 200.0, 200.0),
        vec![
            block("block", 50.0, -100.0, 70.0, 100.0, 0.0, 60.0),
            block("thin", -50.0, -20.0, -49.0, 20.0, 0.0, 100.0),
        ],
        None,
    )
    .expect("city");
    Arc::new(RadioWorld::from_parts(
        city,
        vec![
            site(0, Point::new(-150.0, 0.0, 25.0)),
            site(1, Point::new(150.0, 150.0, 25.0)),
        ],
        &cfg.radio,
    ))
}

/// The paper's reward, Eq. (8) alone: no handover or ping-pong cost, site-regret or route term (the
/// departures from the paper, tested on their own below).
fn paper_reward(cfg: &mut Config) {
    cfg.env.reward.handover_reward = 0.0;
    cfg.env.reward.ping_pong_reward = 0.0;
    cfg.env.reward.site_regret_weight = 0.0;
    cfg.env.reward.route_connectivity_weight = 0.0;
}

fn env_with(assoc: Association, f: fn(usize, Point) -> f64) -> Env {
    let mut cfg = unguided();
    cfg.env.association = assoc;
    paper_reward(&mut cfg);
    Env::new(&cfg, world(), Arc::new(Field(f, 2))).expect("env")
}

fn ep(src: Point, dst: Point) -> Episode {
    let d =
        ((src[0] - dst[0]).powi(2) + (src[1] - dst[1]).powi(2) + (src[2] - dst[2]).powi(2)).sqrt();
    Episode::new(src, dst, d, dupac_radio::channel::FieldSplit::Train)
}

fn mv(x: f64, y: f64, z: f64, s: u16) -> Action {
    Action {
        move_: Vector::new(x, y, z),
        site: SiteId(s),
    }
}

const EXCELLENT: fn(usize, Point) -> f64 = |s, _| if s == 0 { -70.0 } else { -95.0 };

#[test]
fn reward_follows_the_class_of_the_serving_site() {
    // Site 0 is excellent (−70), site 1 mediocre (−95); learned association.
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0)),
    )
    .expect("reset");
    assert_eq!(e.serving(), SiteId(0), "starts on the strongest site");
    let s = e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step");
    assert!(
        (s.reward - 10.0).abs() < 1e-9,
        "excellent: μ1·Δd = 10, got {}",
        s.reward
    );
    assert_eq!(s.info.class, RsrpClass::Excellent);
    let s = e.step(&mv(0.0, 1.0, 0.0, 1)).expect("step");
    assert!(s.info.handover);
    assert!(
        (s.reward - (10.0 - 0.95)).abs() < 1e-9,
        "mediocre: 10·1 + 0.01·(−95)"
    );
    // Poor: a field at −105 dBm for site 1.
    let mut e = env_with(
        Association::Learned,
        |s, _| if s == 0 { -70.0 } else { -105.0 },
    );
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0)),
    )
    .expect("reset");
    let s = e.step(&mv(0.0, 1.0, 0.0, 1)).expect("step");
    assert_eq!(s.info.class, RsrpClass::Poor);
    assert!(
        (s.reward - (-10.5)).abs() < 1e-9,
        "poor: 0.1·(−105), no progress term"
    );
    // Moving away in excellent RSRP is penalised by −μ1.
    let s = e.step(&mv(0.0, -1.0, 0.0, 0)).expect("step");
    assert!((s.reward - (-10.0)).abs() < 1e-9, "{}", s.reward);
}

#[test]
fn collision_with_a_wall_stops_at_contact_and_terminates() {
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(45.0, 0.0, 30.0), Point::new(45.0, 150.0, 30.0)),
    )
    .expect("reset");
    let mut last = None;
    for _ in 0..10 {
        let s = e.step(&mv(1.0, 0.0, 0.0, 0)).expect("step");
        if s.terminated {
            last = Some(s);
            break;
        }
    }
    let s = last.expect("must hit the wall at x = 50");
    assert_eq!(s.info.outcome, Some(Outcome::Collision));
    assert!(!s.truncated);
    assert_eq!(s.reward, unguided().env.reward.collision_reward);
    assert!(
        (s.info.position_m[0] - 49.5).abs() < 1e-3,
        "{:?}",
        s.info.position_m
    );
    assert!(matches!(
        e.step(&mv(0.0, 0.0, 0.0, 0)),
        Err(EnvError::EpisodeOver)
    ));
}

#[test]
fn collision_with_a_roof_and_with_a_thin_part() {
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(60.0, 0.0, 62.0), Point::new(0.0, 0.0, 62.0)),
    )
    .expect("reset");
    let s1 = e.step(&mv(0.0, 0.0, -1.0, 0)).expect("step");
    assert!(!s1.terminated, "61 m: 0.5 m above the roof plus margin");
    let s2 = e.step(&mv(0.0, 0.0, -1.0, 0)).expect("step");
    assert_eq!(s2.info.outcome, Some(Outcome::Collision), "roof at 60 m");
    // The 1 m thick part: diagonal moves must not tunnel through it.
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(-52.0, 0.0, 50.0), Point::new(-30.0, 0.0, 50.0)),
    )
    .expect("reset");
    let mut hit = false;
    for _ in 0..5 {
        let s = e.step(&mv(1.0, 1.0, 1.0, 0)).expect("step");
        if s.info.outcome == Some(Outcome::Collision) {
            hit = true;
            break;
        }
    }
    assert!(hit, "diagonal move through a thin part collides");
}

#[test]
fn altitude_band_is_a_clamp_and_leaving_the_area_terminates() {
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 119.5), Point::new(0.0, 100.0, 100.0)),
    )
    .expect("reset");
    let s = e.step(&mv(0.0, 0.0, 1.0, 0)).expect("step");
    assert_eq!(s.info.position_m[2], 120.0);
    assert!(!s.terminated);
    let s = e.step(&mv(0.0, 0.0, 5.0, 0)).expect("step");
    assert_eq!(
        s.info.position_m[2], 120.0,
        "clipped action, clamped altitude"
    );
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(
            Point::new(-199.5, 150.0, 30.0),
            Point::new(0.0, 150.0, 30.0),
        ),
    )
    .expect("reset");
    let s = e.step(&mv(-1.0, 0.0, 0.0, 0)).expect("step");
    assert_eq!(s.info.outcome, Some(Outcome::OutOfBounds));
    assert!(s.terminated);
    assert_eq!(s.reward, unguided().env.reward.out_of_bounds_reward);
}

#[test]
fn goal_terminates_and_time_limit_truncates() {
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 12.0, 50.0)),
    )
    .expect("reset");
    let s = e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step");
    assert!(!s.terminated);
    let s = e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step");
    assert_eq!(s.info.outcome, Some(Outcome::Goal), "within 10 m");
    assert!(s.terminated && !s.truncated);
    assert!((s.reward - 110.0).abs() < 1e-9, "progress 10 + goal 100");

    // T = ceil(3 · 12 / 1) = 36 steps of hovering: truncated on step 36, not terminated.
    e.reset(
        2,
        ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 12.0, 50.0)),
    )
    .expect("reset");
    assert_eq!(e.time_limit(), 36);
    for i in 1..=36 {
        let s = e.step(&mv(0.0, 0.0, 0.0, 0)).expect("step");
        assert_eq!(s.truncated, i == 36);
        assert!(!s.terminated);
        if i == 36 {
            assert_eq!(s.info.outcome, Some(Outcome::TimeLimit));
        }
    }
}

#[test]
fn a3_hands_over_after_time_to_trigger_and_ignores_the_action() {
    // Site 1 is 6 dB stronger than site 0 for y ≥ 5 (> Off + Hys = 4 dB), weaker before.
    let f: fn(usize, Point) -> f64 = |s, p| match (s, p[1] >= 5.0) {
        (0, _) => -80.0,
        (_, true) => -74.0,
        (_, false) => -90.0,
    };
    let mut e = env_with(Association::A3, f);
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0)),
    )
    .expect("reset");
    assert_eq!(e.serving(), SiteId(0));
    // TTT 160 ms at Δt = 1 m / 20.83 m/s = 48 ms → 4 steps. y = 5 is reached on step 5, where
    // the condition first holds (the deterministic world measures every step); the timer has
    // run 4 steps (192 ms ≥ 160 ms) on step 9 → handover on step 9.
    let mut handover_step = None;
    for i in 1..=12 {
        // The action asks for site 0 every time; A3 ignores it.
        let s = e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step");
        if s.info.handover {
            handover_step = Some(i);
            assert_eq!(s.info.serving, SiteId(1));
        }
    }
    assert_eq!(handover_step, Some(9));
    // The oracle switches at once.
    let mut e = env_with(Association::BestRsrp, f);
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0)),
    )
    .expect("reset");
    let mut first = None;
    for i in 1..=8 {
        if e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step").info.handover && first.is_none() {
            first = Some(i);
        }
    }
    assert_eq!(first, Some(5));
}

#[test]
fn handovers_and_ping_pongs_are_counted() {
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0)),
    )
    .expect("reset");
    let sites = [1, 0, 0, 1];
    let mut flags = Vec::new();
    for s in sites {
        let st = e.step(&mv(0.0, 1.0, 0.0, s)).expect("step");
        flags.push((st.info.handover, st.info.ping_pong));
    }
    // 0→1 (handover), 1→0 within 1 s (ping-pong back to the previous site), stay, 0→1 again
    // within 1 s of the last handover from 1 (ping-pong).
    assert_eq!(
        flags,
        vec![(true, false), (true, true), (false, false), (true, true)]
    );
}

#[test]
fn same_episode_and_actions_give_a_bit_identical_trajectory() {
    let w = world();
    let cfg = unguided();
    let run = |src: Point| {
        let mut e = Env::new(&cfg, w.clone(), w.clone()).expect("env");
        e.reset(7, ep(src, Point::new(0.0, 150.0, 60.0)))
            .expect("reset");
        let mut trace: Vec<Vec<f32>> = vec![e.observation().to_vec()];
        let mut rewards = Vec::new();
        for i in 0..40 {
            let a = mv(
                ((i as f64) * 0.7).sin(),
                0.9,
                ((i as f64) * 0.3).cos() * 0.5,
                (i % 2) as u16,
            );
            let s = e.step(&a).expect("step");
            trace.push(e.observation().to_vec());
            rewards.push(s.reward.to_bits());
            if s.terminated || s.truncated {
                break;
            }
        }
        (trace, rewards)
    };
    let a = run(Point::new(0.0, 0.0, 50.0));
    let b = run(Point::new(0.0, 0.0, 50.0));
    assert_eq!(a, b, "bit-identical");
    let c = run(Point::new(10.0, 0.0, 50.0));
    assert_ne!(a.0, c.0, "a different episode differs");
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let mut e = env_with(Association::Learned, EXCELLENT);
    let inside = e
        .reset(
            1,
            ep(Point::new(60.0, 0.0, 30.0), Point::new(0.0, 0.0, 30.0)),
        )
        .unwrap_err();
    assert!(
        inside.to_string().contains("source") && inside.to_string().contains("inside a building"),
        "{inside}"
    );
    let outside = e
        .reset(
            1,
            ep(Point::new(0.0, 0.0, 30.0), Point::new(500.0, 0.0, 30.0)),
        )
        .unwrap_err();
    assert!(
        outside.to_string().contains("destination") && outside.to_string().contains("outside"),
        "{outside}"
    );
    let low = e
        .reset(
            1,
            ep(Point::new(0.0, 0.0, 5.0), Point::new(0.0, 50.0, 30.0)),
        )
        .unwrap_err();
    assert!(low.to_string().contains("band"), "{low}");
    let nan = e
        .reset(
            1,
            ep(Point::new(f64::NAN, 0.0, 30.0), Point::new(0.0, 50.0, 30.0)),
        )
        .unwrap_err();
    assert!(nan.to_string().contains("not finite"));
    assert!(matches!(
        e.step(&mv(0.0, 0.0, 0.0, 0)),
        Err(EnvError::EpisodeOver)
    ));
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 30.0), Point::new(0.0, 50.0, 30.0)),
    )
    .expect("reset");
    assert!(matches!(
        e.step(&mv(f64::NAN, 0.0, 0.0, 0)),
        Err(EnvError::NonFiniteAction(_))
    ));
    assert!(matches!(
        e.step(&mv(0.0, f64::INFINITY, 0.0, 0)),
        Err(EnvError::NonFiniteAction(_))
    ));
    assert!(matches!(
        e.step(&mv(0.0, 1.0, 0.0, 2)),
        Err(EnvError::SiteOutOfRange {
            site: 2,
            n_sites: 2
        })
    ));
    // The rejected actions did not advance the episode.
    let s = e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step");
    assert_eq!(s.info.step, 1);
}

#[test]
fn ball_clip_caps_every_move_at_max_step_while_cube_clips_per_axis() {
    let run = |clip: ActionClip, a: Vector| {
        let mut cfg = unguided();
        cfg.env.action_clip = clip;
        let mut e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
        e.reset(
            1,
            ep(Point::new(0.0, -150.0, 70.0), Point::new(0.0, 150.0, 70.0)),
        )
        .expect("reset");
        e.step(&mv(a[0], a[1], a[2], 0)).expect("step").info
    };
    // Cube: the diagonal (3, 3, 3) is clipped to (1, 1, 1): √3 m in one step.
    let cube = run(ActionClip::Cube, Vector::new(3.0, 3.0, 3.0));
    assert!((cube.step_length_m - 3f64.sqrt()).abs() < 1e-9);
    // Ball: the same action flies 1 m along the same direction.
    let ball = run(ActionClip::Ball, Vector::new(3.0, 3.0, 3.0));
    assert!(
        (ball.step_length_m - 1.0).abs() < 1e-9,
        "{}",
        ball.step_length_m
    );
    let u = 1.0 / 3f64.sqrt();
    for (k, want) in [0.0 + u, -150.0 + u, 70.0 + u].iter().enumerate() {
        assert!((ball.position_m[k] - want).abs() < 1e-9);
    }
    // Inside the ball nothing changes: (0.3, −0.4, 0) flies 0.5 m under both.
    for clip in [ActionClip::Cube, ActionClip::Ball] {
        let s = run(clip, Vector::new(0.3, -0.4, 0.0));
        assert!((s.step_length_m - 0.5).abs() < 1e-9, "{clip:?}");
    }
}

#[test]
fn one_decision_is_action_repeat_steps_and_ends_with_the_episode() {
    let make = |repeat: u32| {
        let mut cfg = unguided();
        cfg.env.action_repeat = repeat;
        cfg.env.action_clip = ActionClip::Ball;
        Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env")
    };
    // Five steps one at a time and one decision of five give the same flight, step for step.
    let pair = ep(Point::new(0.0, -150.0, 70.0), Point::new(0.0, 150.0, 70.0));
    let mut single = make(1);
    single.reset(3, pair.clone()).expect("reset");
    let a = mv(0.6, 0.8, 0.0, 1);
    let mut rewards = 0.0;
    let mut infos = Vec::new();
    for _ in 0..5 {
        let s = single.step(&a).expect("step");
        rewards += s.reward;
        infos.push(s.info);
    }
    let mut five = make(5);
    five.reset(3, pair.clone()).expect("reset");
    let s = five.act(&a).expect("act");
    assert_eq!(five.substeps(), &infos[..]);
    assert_eq!(s.info, infos[4]);
    assert!(
        (s.reward - rewards).abs() < 1e-9,
        "{} vs {rewards}",
        s.reward
    );
    assert_eq!(five.position_m(), single.position_m());
    assert_eq!(five.observation(), single.observation());
    // The handover of the decision's site happens at its first step, not five times.
    assert_eq!(five.substeps().iter().filter(|i| i.handover).count(), 1);
    // A decision stops at the step that ends the episode: the goal 12 m ahead (radius 10 m) is
    // reached at the 2nd of 5 steps, and the decision's reward includes the goal reward.
    let mut e = make(5);
    e.reset(
        3,
        ep(Point::new(0.0, -150.0, 70.0), Point::new(0.0, -138.0, 70.0)),
    )
    .expect("reset");
    let s = e.act(&mv(0.0, 1.0, 0.0, 0)).expect("act");
    assert!(s.terminated && !s.truncated);
    assert_eq!(e.substeps().len(), 2);
    assert_eq!(s.info.outcome, Some(Outcome::Goal));
    assert!(
        (s.reward - (2.0 * 10.0 + 100.0)).abs() < 1e-9,
        "{}",
        s.reward
    );
    assert_eq!(e.act(&mv(0.0, 1.0, 0.0, 0)), Err(EnvError::EpisodeOver));
    // The time limit cuts a decision too: T = ⌈3 · 12 / 1⌉ = 36 steps, flown sideways.
    e.reset(
        3,
        ep(Point::new(0.0, -150.0, 70.0), Point::new(0.0, -138.0, 70.0)),
    )
    .expect("reset");
    let mut steps = 0;
    let last = loop {
        let s = e.act(&mv(0.0, 0.0, 0.0, 0)).expect("act");
        steps += e.substeps().len();
        if s.terminated || s.truncated {
            break s;
        }
    };
    assert!(last.truncated && !last.terminated);
    assert_eq!(steps, 36);
    assert_eq!(e.substeps().len(), 1, "36 = 7 × 5 + 1");
}
