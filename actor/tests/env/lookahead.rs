//! The route ahead: the look-ahead site features against the map at hand-picked points, and the
//! predictive association on a scripted flight (docs/env.md "Predictive association").

use super::*;
use dupac_actor::env::PathGuide;
use dupac_common::obs::{site_feature, site_features_per_site};

/// Along y = 0 east of x = 0, site 0 falls and site 1 rises 0.2 dB per metre (level at x = 50,
/// −80 dBm); west of x = 0 they stay at −70 and −90 dBm.
const CROSSING: fn(usize, Point) -> f64 = |s, p| {
    let x = p[0].max(0.0);
    if s == 0 {
        -70.0 - 0.2 * x
    } else {
        -90.0 + 0.2 * x
    }
};

/// An L-shaped planned path: 100 m north along x = 0, then 100 m east along y = 0, at 80 m
/// (above the test world's 60 m block). The straight line from its start to its end heads
/// north-east at once.
fn l_route() -> Vec<Point> {
    vec![
        Point::new(0.0, -100.0, 80.0),
        Point::new(0.0, 0.0, 80.0),
        Point::new(100.0, 0.0, 80.0),
    ]
}

fn guided(points: &[Point]) -> Episode {
    let (src, dst) = (points[0], points[points.len() - 1]);
    let mut e = ep(src, dst);
    e.guide = Some(Arc::new(PathGuide::new(points).expect("path")));
    e
}

fn lookahead_cfg() -> Config {
    let mut cfg = unguided();
    let o = &mut cfg.env.observation;
    o.site_lookahead_m = vec![10.0, 30.0, 60.0, 120.0];
    o.site_lookahead_stay = true;
    o.site_predictive_choice = true;
    cfg
}

/// The site features of site `k` in the current observation.
fn features(e: &Env, k: usize) -> Vec<f32> {
    let r = e
        .layout()
        .range(field::SITE_FEATURES)
        .expect("site features");
    let per = site_features_per_site(&e.config().observation);
    e.observation()[r][k * per..(k + 1) * per].to_vec()
}

#[test]
fn lookahead_features_read_the_map_along_the_planned_route() {
    let cfg = lookahead_cfg();
    let o = &cfg.env.observation;
    let mut e = Env::new(&cfg, world(), Arc::new(Field(CROSSING, 2))).expect("env");
    e.reset(1, guided(&l_route())).expect("reset");
    let ahead = site_feature::lookahead(o);
    let (f0, f1) = (features(&e, 0), features(&e, 1));
    // 10, 30 and 60 m ahead the route still runs north along x = 0: site 1 is 20 dB below the
    // best (−2 on the feature's 10 dB scale), site 0 is the best (0).
    for j in 0..3 {
        assert_eq!(
            f0[ahead.start + j],
            0.0,
            "site 0 at {}",
            o.site_lookahead_m[j]
        );
        assert!((f1[ahead.start + j] + 2.0).abs() < 1e-6, "{f1:?}");
    }
    // 120 m ahead the route has turned east to x = 20: −74 against −86 dBm.
    assert!((f1[ahead.start + 3] + 1.2).abs() < 1e-5, "{f1:?}");
    // Site 0 stays within 3 dB of the best until x > 57.5 (s > 157.5 m): the first sample
    // below is at 160 m, 0.8 of the 200 m horizon; site 1 is not within 3 dB here.
    let stay = site_feature::stay(o).expect("stay");
    assert!((f0[stay] - 0.8).abs() < 1e-6, "{f0:?}");
    assert_eq!(f1[stay], 0.0);
    // The predictive choice is the serving site 0 (the crossing is 150 m away).
    let c = site_feature::predictive_choice(o).expect("choice");
    assert_eq!((f0[c], f1[c]), (1.0, 0.0));

    // The same start flown towards the same destination without its planned path: the
    // features follow the straight line north-east instead (so they do read the route).
    let mut straight = Env::new(&cfg, world(), Arc::new(Field(CROSSING, 2))).expect("env");
    let route = l_route();
    straight.reset(1, ep(route[0], route[2])).expect("reset");
    let s1 = features(&straight, 1);
    assert!(
        (s1[ahead.start + 2] - f1[ahead.start + 2]).abs() > 0.3,
        "60 m ahead on the straight line x ≈ 42: {s1:?} vs {f1:?}"
    );

    // Past the crossing (x = 60 on the eastern leg) the choice is site 1.
    let late = [Point::new(60.0, 0.0, 80.0), Point::new(100.0, 0.0, 80.0)];
    e.reset(2, guided(&late)).expect("reset");
    assert_eq!(e.serving(), SiteId(1), "strongest at the source");
    let (g0, g1) = (features(&e, 0), features(&e, 1));
    assert_eq!((g0[c], g1[c]), (0.0, 1.0));
}

#[test]
fn the_predictive_association_hands_over_once_near_the_crossing() {
    let mut cfg = lookahead_cfg();
    cfg.env.association = Association::Predictive;
    cfg.env.observation.site_lookahead_m.clear();
    cfg.env.observation.site_lookahead_stay = false;
    cfg.env.observation.site_predictive_choice = false;
    let mut e = Env::new(&cfg, world(), Arc::new(Field(CROSSING, 2))).expect("env");
    assert_eq!(
        e.policy_shape().1,
        0,
        "the site is not the policy's to choose"
    );
    e.reset(1, guided(&l_route())).expect("reset");
    let mut handovers = Vec::new();
    for t in 0..200 {
        let a = if t < 100 {
            mv(0.0, 1.0, 0.0, 0)
        } else {
            mv(1.0, 0.0, 0.0, 0)
        };
        let s = e.step(&a).expect("step");
        if s.info.handover {
            handovers.push((s.info.position_m[0], s.info.serving));
        }
        if s.terminated || s.truncated {
            break;
        }
    }
    assert_eq!(handovers.len(), 1, "{handovers:?}");
    let (x, to) = handovers[0];
    assert_eq!(to, SiteId(1));
    // No later than 10 m past the crossing (a decision is 5 steps; the cost of 60 dB·m is
    // repaid within 25 m of a growing lead), and not before it.
    assert!((45.0..=60.0).contains(&x), "handed over at x = {x}");
}
