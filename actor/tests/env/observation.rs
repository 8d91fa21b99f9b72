//! The observation: its layout as documented, the goal direction, the area's edge as a sensed
//! wall, the path guide (direction along the planned path, the progress paid along it) and the
//! path offset.

use super::*;

#[test]
fn observation_layout_holds_what_it_documents() {
    // The spec's sensors (linear scale, c_t from the fan) for the values below; the defaults'
    // exact nearest surface and log scale are checked at the end.
    let mut cfg = unguided();
    cfg.env.observation.sensor_scale = dupac_common::config::SensorScale::Linear;
    cfg.env.observation.nearest_obstacle = dupac_common::config::NearestObstacle::Fan;
    let mut e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
    e.reset(
        1,
        ep(Point::new(45.0, 0.0, 70.0), Point::new(45.0, 80.0, 70.0)),
    )
    .expect("reset");
    let l = e.layout().clone();
    assert_eq!(e.observation().len(), l.len());
    let o = e.observation().to_vec();
    let get = |name: &str| o[l.range(name).expect(name)].to_vec();
    // Position: x/200, y/200, (z − 70)/50.
    assert_eq!(get(field::POSITION), vec![45.0 / 200.0, 0.0, 0.0]);
    assert_eq!(get(field::GOAL_VECTOR), vec![0.0, 80.0 / 800.0, 0.0]);
    assert_eq!(get(field::GOAL_DISTANCE), vec![0.1]);
    assert_eq!(get(field::GOAL_DIRECTION), vec![0.0, 1.0, 0.0]);
    assert_eq!(get(field::SERVING_ONE_HOT), vec![1.0, 0.0]);
    // RSRP: (−70 + 90) / 30 and (−95 + 90) / 30.
    let r = get(field::RSRP_ALL);
    assert!((r[0] - 20.0 / 30.0).abs() < 1e-6 && (r[1] + 5.0 / 30.0).abs() < 1e-6);
    // The 60 m block starts 5 m east; from 70 m the ray (1, 0, −1)/√2 meets its roof after
    // 10·√2 = 14.1 m, nearer than any other ray (straight down is 70 m, out of range).
    let c = get(field::OBSTACLE_DISTANCE)[0];
    assert!((c - (10.0 * 2f32.sqrt() / 50.0)).abs() < 1e-3, "c_t = {c}");
    let d = get(field::OBSTACLE_DIRECTION);
    assert!(
        (d[0] - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-3
            && d[1].abs() < 1e-6
            && (d[2] + std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-3,
        "{d:?}"
    );
    let s = e.step(&mv(0.0, 0.5, 0.0, 1)).expect("step");
    assert!(s.info.handover);
    let o = e.observation().to_vec();
    // The velocity in 16-bit fixed point (dupac_common::compact::code::signed): 0 exact.
    let v = o[l.range(field::VELOCITY).expect("v")].to_vec();
    assert!(
        v[0] == 0.0 && (v[1] - 0.5).abs() < 3.1e-5 && v[2] == 0.0,
        "{v:?}"
    );
    assert_eq!(
        o[l.range(field::SERVING_ONE_HOT).expect("one-hot")].to_vec(),
        vec![0.0, 1.0]
    );
    // Defaults: c_t and θ_t of the true nearest surface point, the block's roof edge at
    // (50, 0, 60), √125 m away (nearer than the 14.1 m the fan sees), on the log scale.
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(45.0, 0.0, 70.0), Point::new(45.0, 80.0, 70.0)),
    )
    .expect("reset");
    let o = e.observation().to_vec();
    let d_m = 125f64.sqrt();
    let c = o[l.range(field::OBSTACLE_DISTANCE).expect("c_t")][0];
    let want = ((1.0 + d_m).ln() / 51f64.ln()) as f32;
    assert!((c - want).abs() < 1e-4, "c_t = {c}, want {want}");
    let d = o[l.range(field::OBSTACLE_DIRECTION).expect("θ_t")].to_vec();
    let u = Vector::new(5.0 / d_m, 0.0, -10.0 / d_m);
    for k in 0..3 {
        assert!((f64::from(d[k]) - u[k]).abs() < 1e-3, "{d:?}");
    }
}

#[test]
fn goal_direction_is_the_unit_vector_to_the_destination() {
    let mut cfg = unguided();
    cfg.env.observation.goal_direction = true;
    let mut e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
    e.reset(
        1,
        ep(
            Point::new(0.0, -150.0, 70.0),
            Point::new(30.0, -110.0, 70.0),
        ),
    )
    .expect("reset");
    let l = e.layout().clone();
    let r = l.range(field::GOAL_DIRECTION).expect("goal_direction");
    assert_eq!(e.observation()[r.clone()].to_vec(), vec![0.6, 0.8, 0.0]);
    // It follows the UAV: after 1 m north the destination lies at (30, 39, 0) / |·|.
    e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step");
    let n = (30f64 * 30.0 + 39.0 * 39.0).sqrt();
    let got = e.observation()[r].to_vec();
    assert!(
        (f64::from(got[0]) - 30.0 / n).abs() < 1e-6 && (f64::from(got[1]) - 39.0 / n).abs() < 1e-6
    );
    // On by default; off gives the spec's observation, three values shorter.
    assert!(
        env_with(Association::Learned, EXCELLENT)
            .layout()
            .range(field::GOAL_DIRECTION)
            .is_some()
    );
    cfg.env.observation.goal_direction = false;
    let d = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
    assert!(d.layout().range(field::GOAL_DIRECTION).is_none());
    assert_eq!(d.layout().len() + 3, l.len());
}

#[test]
fn geofence_makes_the_area_edge_a_sensed_wall() {
    use dupac_common::config::NearestObstacle;
    use dupac_common::obs::SENSOR_DIRECTIONS;
    let sensed = |fence: bool, nearest: NearestObstacle| {
        let mut cfg = unguided();
        cfg.env.observation.geofence = fence;
        cfg.env.observation.nearest_obstacle = nearest;
        cfg.env.observation.sensor_scale = dupac_common::config::SensorScale::Linear;
        let mut e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
        // 10 m south of the north edge (y = 200), far from both buildings.
        e.reset(
            1,
            ep(
                Point::new(-120.0, 190.0, 70.0),
                Point::new(-120.0, 100.0, 70.0),
            ),
        )
        .expect("reset");
        let l = e.layout().clone();
        let o = e.observation().to_vec();
        let ray = |dir: [i8; 3]| {
            let i = SENSOR_DIRECTIONS
                .iter()
                .position(|d| *d == dir)
                .expect("direction");
            o[l.range(field::SENSOR_FAN).expect("fan").start + i]
        };
        let c_t = o[l.range(field::OBSTACLE_DISTANCE).expect("c_t").start];
        let theta = o[l.range(field::OBSTACLE_DIRECTION).expect("θ_t")].to_vec();
        (ray([0, 1, 0]), ray([0, 1, 1]), ray([0, -1, 0]), c_t, theta)
    };
    // Linear scale over 50 m: the edge straight north at 10 m reads 0.2, up-north at 10·√2 m
    // (in 16-bit fixed point, dupac_common::compact::code::unit: within 7.7·10⁻⁶).
    for nearest in [NearestObstacle::Fan, NearestObstacle::Exact] {
        let (north, up_north, south, c_t, theta) = sensed(true, nearest);
        assert!((north - 0.2).abs() < 8e-6, "{north}");
        assert!((up_north - 0.2 * 2f32.sqrt()).abs() < 8e-6, "{up_north}");
        assert_eq!(south, 1.0);
        assert!((c_t - 0.2).abs() < 8e-6, "{nearest:?}: {c_t}");
        assert_eq!(theta, vec![0.0, 1.0, 0.0]);
    }
    // Off (the spec): the edge is invisible.
    let (north, _, _, c_t, _) = sensed(false, NearestObstacle::Exact);
    assert_eq!((north, c_t), (1.0, 1.0));
}

/// The path guide (docs/env.md "Path guide"): the observation points along the
/// episode's planned path, `env.reward.progress = "path"` pays the distance made good along it
/// (not the straight-line gain), and an episode without a path, or with another pair's, is
/// refused.
#[test]
fn the_path_guide_points_along_the_planned_path_and_pays_its_progress() {
    use dupac_actor::env::PathGuide;
    use dupac_common::config::Progress;
    let mut cfg = unguided();
    cfg.env.association = Association::A3;
    paper_reward(&mut cfg);
    cfg.env.observation.path_guide = true;
    cfg.env.reward.progress = Progress::Path;
    let (src, dst) = (Point::new(0.0, -150.0, 70.0), Point::new(0.0, 150.0, 70.0));
    let mut e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
    assert_eq!(e.reset(1, ep(src, dst)).unwrap_err(), EnvError::NoGuide);
    // A detour east of the straight line: 100 + 300 + 100 = 500 m.
    let (c1, c2) = (
        Point::new(100.0, -150.0, 70.0),
        Point::new(100.0, 150.0, 70.0),
    );
    let detour = Arc::new(PathGuide::new(&[src, c1, c2, dst]).expect("path"));
    let wrong = Episode {
        guide: Some(Arc::new(PathGuide::new(&[src, c1]).expect("path"))),
        ..ep(src, dst)
    };
    assert!(matches!(
        e.reset(1, wrong),
        Err(EnvError::GuideMismatch { .. })
    ));
    let guided = Episode {
        guide: Some(detour),
        ..ep(src, dst)
    };
    let obs = e.reset(1, guided.clone()).expect("reset").to_vec();
    let r = e.layout().range(field::PATH_GUIDE).expect("the field");
    let scale = cfg.env.observation.goal_scale_m;
    let close = |a: f32, b: f64| (f64::from(a) - b).abs() < 1e-5;
    // The look-ahead point on the first leg: due east, though the goal is due north.
    assert!(
        close(obs[r.start], 1.0) && close(obs[r.start + 1], 0.0),
        "{obs:?}"
    );
    assert!(close(obs[r.start + 3], 500.0 / scale));
    let east = Action {
        move_: Vector::new(1.0, 0.0, 0.0),
        site: SiteId(0),
    };
    let s = e.step(&east).expect("step");
    let step_m = cfg.env.max_step_m;
    let mu1 = cfg.env.reward.mu1;
    assert!((s.reward - mu1 * step_m).abs() < 1e-9, "{}", s.reward);
    // The same move under the paper's straight progress pays the straight-line change (< 0).
    let mut straight_cfg = cfg.clone();
    straight_cfg.env.reward.progress = Progress::Straight;
    let mut f = Env::new(&straight_cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
    f.reset(1, guided).expect("reset");
    let t = f.step(&east).expect("step");
    let straight_gain = 300.0 - (step_m * step_m + 300.0 * 300.0).sqrt();
    assert!(
        (t.reward - mu1 * straight_gain).abs() < 1e-9,
        "{}",
        t.reward
    );
    // Without the guide the layout has no such field.
    assert!(
        env_with(Association::A3, EXCELLENT)
            .layout()
            .range(field::PATH_GUIDE)
            .is_none()
    );
}

/// The path offset (`env.observation.path_offset`): the vector from the UAV to its tracked place
/// on the planned path, / 10 m, clipped to ±3 — zero on the path, pointing back to it beside it.
#[test]
fn the_path_offset_points_from_the_uav_back_to_its_place_on_the_path() {
    use dupac_actor::env::PathGuide;
    let mut cfg = unguided();
    cfg.env.association = Association::A3;
    paper_reward(&mut cfg);
    cfg.env.observation.path_guide = true;
    cfg.env.observation.path_offset = true;
    // A path due north along x = 0; the episode starts on it.
    let (src, dst) = (Point::new(0.0, -150.0, 70.0), Point::new(0.0, 150.0, 70.0));
    let guided = Episode {
        guide: Some(Arc::new(PathGuide::new(&[src, dst]).expect("path"))),
        ..ep(src, dst)
    };
    let mut e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
    let obs = e.reset(1, guided).expect("reset").to_vec();
    let r = e.layout().range(field::PATH_OFFSET).expect("the field");
    assert_eq!(r.len(), 3);
    assert!(obs[r.clone()].iter().all(|v| v.abs() < 1e-6), "{obs:?}");
    // Two moves due east: the tracked place stays at the path's nearest point (x = 0), the
    // offset points west by the distance flown, / 10 m.
    let east = Action {
        move_: Vector::new(1.0, 0.0, 0.0),
        site: SiteId(0),
    };
    let mut flown_m = 0.0;
    for _ in 0..2 {
        e.step(&east).expect("step");
        flown_m += cfg.env.max_step_m;
        let o = &e.observation()[r.clone()];
        assert!(
            (f64::from(o[0]) + flown_m / 10.0).abs() < 1e-5
                && o[1].abs() < 1e-5
                && o[2].abs() < 1e-5,
            "{flown_m} m east: {o:?}"
        );
    }
    // Off by default: the layout has no such field.
    cfg.env.observation.path_offset = false;
    let f = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
    assert!(f.layout().range(field::PATH_OFFSET).is_none());
}
