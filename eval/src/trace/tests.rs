use super::*;
use crate::refly::replay_one;
use crate::{Kind, Method};
use dupac_common::config::{ChannelModel, CityKind};
use dupac_scenario::planners::Planners;

/// The small procedural city (500 m, 8 sites) with exact radio, deterministic or under the real
/// channel (shadow fading, measurement error and the UAV's layer-3 filter).
fn world(real: bool) -> (Config, Arc<RadioWorld>, SharedRsrp) {
    let mut cfg = Config::default();
    cfg.scenario.city = CityKind::Procedural;
    cfg.scenario.procedural.size_m = 500.0;
    cfg.scenario.procedural.n_sites = 8;
    cfg.scenario.n_sites = 8;
    if real {
        cfg.radio.channel.model = ChannelModel::Real;
    }
    let cfg = dupac_scenario::planners::unguided(&cfg);
    let world = Arc::new(RadioWorld::build(&cfg).expect("radio world"));
    let rsrp: SharedRsrp = world.clone();
    (cfg, world, rsrp)
}

fn method(label: &str, kind: Kind) -> Method {
    Method {
        label: label.into(),
        seed: 0,
        kind,
        a3: None,
        predictive: false,
        handover_weight: None,
    }
}

/// Straight flights across the city at several altitudes and headings, flown by the pilot with
/// the configured A3 (`Kind::Shortest` through the two endpoints): every one whose endpoints are
/// free, with its pair.
fn flights(cfg: &Config, ctx: FlyCtxOwned) -> Vec<(Pair, FlightRecord)> {
    let (world, rsrp, planners) = ctx;
    let mut out = Vec::new();
    for (k, (deg, z_m)) in [
        (10.0, 110.0),
        (55.0, 95.0),
        (100.0, 80.0),
        (150.0, 118.0),
        (200.0, 90.0),
        (250.0, 105.0),
        (300.0, 25.0),
        (330.0, 22.0),
    ]
    .into_iter()
    .enumerate()
    {
        let a = f64::to_radians(deg);
        let s = Point::new(210.0 * a.cos(), 210.0 * a.sin(), z_m);
        let t = Point::new(-190.0 * a.cos(), -190.0 * a.sin(), z_m - 5.0);
        let d = (t - s).norm();
        let p = Pair {
            id: k as u64,
            source_m: s,
            destination_m: t,
            shortest_m: d,
            straight_m: d,
            bin_m: None,
            path: None,
            path_lambda: 0.0,
            path_clearance_m: 0.0,
        };
        let m = method("pilot", Kind::Shortest(Association::A3));
        let fs = FieldSplit::Eval;
        if let Ok(r) = crate::flight::fly_one(cfg, world, rsrp, planners, fs, &m, &p, Some(&[s, t]))
        {
            out.push((p, r));
        }
    }
    out
}

type FlyCtxOwned<'a, 'w> = (&'a Arc<RadioWorld>, &'a SharedRsrp, &'a Planners<'w>);

/// Settings that differ in every respect: margins from 0 to 12 dB, time-to-trigger from 0 to
/// 1 280 ms, without and with A3's own filter.
fn settings() -> Vec<A3Setting> {
    [
        (0.0, 0.0, 0.0, None),
        (3.0, 1.0, 160.0, None),
        (1.0, 0.5, 80.0, Some(4)),
        (2.0, 0.0, 320.0, Some(8)),
        (0.0, 0.0, 0.0, Some(0)),
        (12.0, 0.0, 1280.0, Some(4)),
        (6.0, 0.0, 640.0, None),
    ]
    .map(
        |(offset_db, hysteresis_db, time_to_trigger_ms, l3_filter_k)| A3Setting {
            offset_db,
            hysteresis_db,
            time_to_trigger_ms,
            l3_filter_k,
        },
    )
    .to_vec()
}

/// Every A3 setting re-associated from one trace per flight gives the record (and so the
/// metrics) of the flight re-flown through the environment with that setting, in both worlds,
/// for a replay (`eval --a3-front`) and for the pilot's waypoints (`tune-a3`).
#[test]
fn every_a3_setting_from_a_trace_is_the_flight_re_flown_through_the_environment() {
    for real in [false, true] {
        let (cfg, world, rsrp) = world(real);
        let planners = Planners::new(&cfg, &[], &world, &rsrp, false);
        let fs = FieldSplit::Eval;
        let ctx = (&cfg, &world, &rsrp, &planners, fs);
        let flown = flights(&cfg, (&world, &rsrp, &planners));
        assert!(flown.len() >= 5, "{} flights", flown.len());
        let rules = MetricRules::from_config(&cfg);
        let settings = settings();
        let mut handovers = std::collections::BTreeSet::new();
        for (p, recorded) in &flown {
            let episode = p.episode(false, fs);
            let trace =
                ReplayTrace::fly(&cfg, &world, &rsrp, fs, p, episode, Flown::Replay(recorded))
                    .expect("trace");
            let metrics = trace.a3_metrics(&settings, &rules);
            let waypoints = [p.source_m, p.destination_m];
            let piloted = ReplayTrace::fly(
                &cfg,
                &world,
                &rsrp,
                fs,
                p,
                p.episode(false, fs),
                Flown::Waypoints(&waypoints),
            )
            .expect("trace");
            for (s, m) in settings.iter().zip(&metrics) {
                let mut rcfg = cfg.clone();
                rcfg.env.association = Association::A3;
                s.apply(&mut rcfg.radio.a3);
                let replay = method("x", Kind::Replay(Association::A3));
                let env = replay_one(&rcfg, ctx, &replay, p, recorded).expect("replay");
                let from_trace = trace.record("x", 0, &trace.a3_serving(s));
                assert_eq!(from_trace, env, "real {real}, pair {}, {}", p.id, s.label());
                assert_eq!(*m, flight_metrics(&env, &rules));
                let pilot = method("x", Kind::Shortest(Association::A3));
                let env = crate::flight::fly_one(
                    &rcfg,
                    &world,
                    &rsrp,
                    &planners,
                    fs,
                    &pilot,
                    p,
                    Some(&waypoints),
                )
                .expect("pilot");
                let from_trace = piloted.record("x", 0, &piloted.a3_serving(s));
                assert_eq!(from_trace, env, "real {real}, pair {}, {}", p.id, s.label());
                handovers.insert((p.id, m.handovers));
            }
        }
        // The settings lead to different flights: the comparison is not of one sequence.
        let per_pair = |id: u64| handovers.iter().filter(|(p, _)| *p == id).count();
        assert!(
            flown.iter().any(|(p, _)| per_pair(p.id) >= 3),
            "real {real}: {handovers:?}"
        );
    }
}

/// A replay of a flight that ended in a collision ends as a collision: through the environment
/// (`LABEL+a3`) and from a trace (A3's front) alike, with the recorded flight's steps. The
/// flight: 22 m up along the x axis, into a building; its replay through the recorded (f32)
/// positions ends a hair short of the contact and would, by itself, run out of positions.
#[test]
fn a_replay_of_a_collision_ends_as_a_collision() {
    let (cfg, world, rsrp) = world(false);
    let planners = Planners::new(&cfg, &[], &world, &rsrp, false);
    let fs = FieldSplit::Eval;
    let ctx = (&cfg, &world, &rsrp, &planners, fs);
    let (s, t) = (Point::new(210.0, 0.0, 22.0), Point::new(-190.0, 0.0, 22.0));
    let p = Pair {
        id: 0,
        source_m: s,
        destination_m: t,
        shortest_m: 400.0,
        straight_m: 400.0,
        bin_m: None,
        path: None,
        path_lambda: 0.0,
        path_clearance_m: 0.0,
    };
    let pilot = method("pilot", Kind::Shortest(Association::A3));
    let recorded = crate::flight::fly_one(
        &cfg,
        &world,
        &rsrp,
        &planners,
        fs,
        &pilot,
        &p,
        Some(&[s, t]),
    )
    .expect("flight");
    assert_eq!(recorded.outcome, Outcome::Collision);
    let w: Vec<Point> = recorded
        .steps
        .iter()
        .map(|s| Point::from(s.position_m.map(f64::from)))
        .collect();
    let replay = method("x", Kind::Replay(Association::BestRsrp));
    let mut rcfg = cfg.clone();
    rcfg.env.association = Association::BestRsrp;
    let raw = crate::flight::fly_one(&rcfg, &world, &rsrp, &planners, fs, &replay, &p, Some(&w))
        .expect("raw replay");
    assert_eq!(
        (raw.outcome, raw.steps.len()),
        (Outcome::TimeLimit, recorded.steps.len()),
        "the positions alone end without the collision"
    );
    let env = replay_one(&rcfg, ctx, &replay, &p, &recorded).expect("replay");
    assert_eq!(env.outcome, Outcome::Collision);
    let trace = ReplayTrace::fly(
        &cfg,
        &world,
        &rsrp,
        fs,
        &p,
        p.episode(false, fs),
        Flown::Replay(&recorded),
    )
    .expect("trace");
    let r = trace.record("x", 0, &trace.a3_serving(&settings()[1]));
    assert_eq!(r.outcome, Outcome::Collision);
    // A replay that ended before the recording's end keeps its own outcome.
    assert_eq!(
        crate::flight::replay_outcome(&recorded, recorded.steps.len() - 1, Outcome::OutOfBounds),
        Outcome::OutOfBounds
    );
}
