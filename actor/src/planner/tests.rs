use super::*;
use dupac_common::config::{CityKind, Config, ScenarioConfig};
use dupac_radio::city::Building;

/// A box building `[x0, x1] × [y0, y1] × [z0, z1]` (CCW ring).
pub(crate) fn boxb(id: &str, x0: f64, y0: f64, x1: f64, y1: f64, z0: f64, z1: f64) -> Building {
    Building {
        id: id.into(),
        outer_m: vec![[x0, y0], [x1, y0], [x1, y1], [x0, y1]],
        holes_m: vec![],
        z_min_m: z0,
        z_max_m: z1,
    }
}

/// A 200 m × 200 m city (area centred on the origin) with the given buildings.
pub(crate) fn city(buildings: Vec<Building>) -> City {
    City::from_buildings(
        "test",
        Bounds2::new(-100.0, -100.0, 100.0, 100.0),
        buildings,
        None,
    )
    .expect("test city")
}

/// A small building in a corner, out of the way (the mesh must not be empty).
fn corner() -> Building {
    boxb("corner", 80.0, 80.0, 90.0, 90.0, 0.0, 30.0)
}

fn planner(city: &City) -> Planner<'_> {
    let cfg = Config::default();
    Planner::new(city, &cfg.env, &cfg.planner)
}

/// Procedural city of `size_m` (seeded Manhattan grid).
pub(crate) fn procedural(size_m: f64) -> City {
    let mut sc = ScenarioConfig {
        city: CityKind::Procedural,
        name: "procedural".into(),
        ..ScenarioConfig::default()
    };
    sc.procedural.size_m = size_m;
    City::load(&sc).expect("procedural city")
}

/// Checks the invariants every planned path must satisfy and returns it.
fn check_path(p: &Planner, path: &Path, s: Point, t: Point) {
    let fs = p.free_space();
    assert_eq!(path.waypoints_m.first(), Some(&s));
    assert_eq!(path.waypoints_m.last(), Some(&t));
    let mut len = 0.0;
    for w in path.waypoints_m.windows(2) {
        assert!(
            fs.segment_clear(w[0], w[1]),
            "segment {:?} -> {:?} not clear",
            w[0],
            w[1]
        );
        len += dist(w[0], w[1]);
    }
    assert!((len - path.length_m).abs() < 1e-9);
    let [z0, z1] = fs.band_m();
    for w in &path.waypoints_m {
        assert!(w[2] >= z0 && w[2] <= z1, "waypoint {w:?} leaves the band");
        assert!(
            p.city().in_area(w[0], w[1]),
            "waypoint {w:?} leaves the area"
        );
    }
    assert!(path.length_m >= dist(s, t) - 1e-9);
}

/// Flies the path the way the environment does (moves of at most 1 m, a 0.5 m sphere swept
/// along each) and asserts no collision.
fn fly_like_env(city: &City, path: &Path) {
    let radius = Config::default().env.uav_radius_m;
    for w in path.waypoints_m.windows(2) {
        let n = dist(w[0], w[1]).ceil().max(1.0) as usize;
        let mut prev = w[0];
        for k in 1..=n {
            let f = k as f64 / n as f64;
            let p = w[0] + (w[1] - w[0]) * f;
            assert!(
                city.mesh.sphere_sweep(prev, p, radius).is_none(),
                "collision between {prev:?} and {p:?}"
            );
            prev = p;
        }
    }
}

#[test]
fn lattice_matches_area_and_band() {
    let c = city(vec![corner()]);
    let p = planner(&c);
    let fs = p.free_space();
    assert_eq!(fs.dims(), [41, 41, 21]);
    let f = fs.free_voxel_fraction();
    assert!(f > 0.95 && f < 1.0, "free fraction {f}");
    assert!(fs.is_free_point(Point::new(0.0, 0.0, 50.0)));
    assert!(
        !fs.is_free_point(Point::new(85.0, 85.0, 25.0)),
        "inside the building"
    );
    assert!(
        !fs.is_free_point(Point::new(85.0, 91.0, 25.0)),
        "1 m from a wall"
    );
    assert!(
        fs.is_free_point(Point::new(85.0, 85.0, 32.0)),
        "2 m above the roof"
    );
    assert!(
        !fs.is_free_point(Point::new(0.0, 0.0, 10.0)),
        "below the band"
    );
    assert!(!fs.is_free_point(Point::new(0.0, 0.0, f64::NAN)));
}

#[test]
fn straight_free_line_is_one_segment() {
    let c = city(vec![corner()]);
    let p = planner(&c);
    let s = Point::new(-50.0, -50.0, 50.0);
    let t = Point::new(50.0, 40.0, 60.0);
    let path = p.shortest(s, t).expect("path");
    assert_eq!(path.waypoints_m, vec![s, t]);
    assert_eq!(path.length_m, dist(s, t));
}

#[test]
fn low_wall_goes_over() {
    // A 70 m wall across the straight line; flying over (≈ 102.7 m) beats going around (≈ 149 m).
    let c = city(vec![boxb("wall", -2.0, -60.0, 2.0, 60.0, 0.0, 70.0)]);
    let p = planner(&c);
    let s = Point::new(-40.0, 0.0, 40.0);
    let t = Point::new(40.0, 0.0, 40.0);
    assert!(!p.free_space().segment_clear(s, t));
    let path = p.shortest(s, t).expect("path");
    check_path(&p, &path, s, t);
    fly_like_env(&c, &path);
    let over = 2.0 * (38f64.powi(2) + 31.5f64.powi(2)).sqrt() + 4.0;
    assert!(path.length_m > 80.0);
    assert!(
        path.length_m >= over - 0.5 && path.length_m <= over * 1.02,
        "length {} vs over-the-wall optimum {over}",
        path.length_m
    );
    assert!(path.waypoints_m.iter().any(|w| w[2] >= 71.0));
}

#[test]
fn full_height_wall_goes_through_the_gap() {
    // A wall above the band from the south edge to y = 60; the only way is the gap 60 < y ≤ 100.
    let c = city(vec![boxb("wall", -2.0, -120.0, 2.0, 60.0, 0.0, 200.0)]);
    let p = planner(&c);
    let s = Point::new(-40.0, 0.0, 50.0);
    let t = Point::new(40.0, 0.0, 50.0);
    let path = p.shortest(s, t).expect("path");
    check_path(&p, &path, s, t);
    fly_like_env(&c, &path);
    let around = 2.0 * (38f64.powi(2) + 61.5f64.powi(2)).sqrt() + 4.0;
    assert!(
        path.length_m >= around - 0.5 && path.length_m <= around * 1.02,
        "length {} vs optimum {around}",
        path.length_m
    );
    assert!(path.waypoints_m.iter().any(|w| w[1] > 61.0));
}

#[test]
fn enclosed_destination_is_an_error() {
    // A courtyard walled in above the band: the destination inside cannot be reached.
    let mut tower = boxb("court", -20.0, -20.0, 20.0, 20.0, 0.0, 200.0);
    tower.holes_m = vec![vec![
        [-10.0, -10.0],
        [-10.0, 10.0],
        [10.0, 10.0],
        [10.0, -10.0],
    ]];
    let c = city(vec![tower]);
    let p = planner(&c);
    let t = Point::new(0.0, 0.0, 60.0);
    assert!(p.free_space().is_free_point(t));
    let err = p
        .shortest(Point::new(-60.0, -60.0, 60.0), t)
        .expect_err("enclosed");
    assert!(matches!(err, PlanError::NoPath { .. }), "{err}");
    assert!(err.to_string().contains("destination"));
}

#[test]
fn bad_endpoints_are_named() {
    let c = city(vec![boxb("b", -10.0, -10.0, 10.0, 10.0, 0.0, 80.0)]);
    let p = planner(&c);
    let ok = Point::new(-60.0, -60.0, 50.0);
    let cases: [(Point, bool, &str); 6] = [
        (Point::new(0.0, 0.0, 50.0), true, "inside a building"),
        (Point::new(f64::NAN, 0.0, 50.0), false, "not a finite point"),
        (
            Point::new(150.0, 0.0, 50.0),
            true,
            "outside the flight area",
        ),
        (
            Point::new(-60.0, 0.0, 5.0),
            false,
            "outside the altitude band",
        ),
        (Point::new(11.0, 0.0, 50.0), true, "from a building"),
        (
            Point::new(0.0, f64::INFINITY, 50.0),
            true,
            "not a finite point",
        ),
    ];
    for (bad, as_source, reason) in cases {
        let (s, t, which) = if as_source {
            (bad, ok, "source")
        } else {
            (ok, bad, "destination")
        };
        let err = p.shortest(s, t).expect_err("bad endpoint");
        let msg = err.to_string();
        assert!(msg.starts_with(which), "{msg}");
        assert!(msg.contains(reason), "{msg}");
    }
}

/// RSRP: poor (−110 dBm) in the box |x| < 20, y < 30 (all altitudes), excellent (−70) elsewhere.
struct PoorPatch;

impl PoorPatch {
    fn poor(p: Point) -> bool {
        p[0].abs() < 20.0 && p[1] < 30.0
    }
}

impl RsrpSource for PoorPatch {
    fn num_sites(&self) -> usize {
        2
    }
    fn rsrp_all_dbm(&self, p_m: Point, out: &mut [f64]) {
        let v = if Self::poor(p_m) { -110.0 } else { -70.0 };
        out[0] = v;
        out[1] = v - 5.0;
    }
}

#[test]
fn coverage_aware_avoids_poor_region() {
    let c = city(vec![corner()]);
    let mut p = planner(&c);
    let s = Point::new(-80.0, 0.0, 50.0);
    let t = Point::new(80.0, 0.0, 50.0);
    assert_eq!(
        p.coverage_aware(s, t, 1.0).expect_err("no coverage yet"),
        PlanError::NoCoverage
    );
    p.with_coverage(&PoorPatch, RsrpThresholds::default());
    let fr = p.coverage_class_fractions().expect("fractions");
    assert!(fr[2] > 0.05 && fr[1] == 0.0, "{fr:?}");
    let shortest = p.shortest(s, t).expect("shortest");
    assert_eq!(shortest.waypoints_m, vec![s, t]);
    assert_eq!(p.coverage_aware(s, t, 0.0).expect("λ = 0"), shortest);
    assert!(matches!(
        p.coverage_aware(s, t, f64::NAN),
        Err(PlanError::BadLambda(_))
    ));
    let aware = p.coverage_aware(s, t, 10.0).expect("coverage-aware");
    check_path(&p, &aware, s, t);
    assert!(aware.length_m > shortest.length_m + 10.0, "{aware:?}");
    // No part of the path lies in the poor patch (one lattice step of slack for the classes
    // being those of the nearest lattice point).
    for w in aware.waypoints_m.windows(2) {
        let n = (dist(w[0], w[1]) / 0.5).ceil() as usize;
        for k in 0..=n {
            let f = k as f64 / n.max(1) as f64;
            let q = [0, 1, 2].map(|i| w[0][i] + f * (w[1][i] - w[0][i]));
            assert!(
                !(q[0].abs() < 15.0 && q[1] < 25.0),
                "point {q:?} of the coverage-aware path is in the poor patch"
            );
        }
    }
}

#[test]
fn coverage_aware_lambda_zero_equals_shortest_around_obstacles() {
    let c = city(vec![boxb("wall", -2.0, -60.0, 2.0, 60.0, 0.0, 70.0)]);
    let mut p = planner(&c);
    p.with_coverage(&PoorPatch, RsrpThresholds::default());
    let s = Point::new(-40.0, 0.0, 40.0);
    let t = Point::new(40.0, 10.0, 45.0);
    assert_eq!(
        p.coverage_aware(s, t, 0.0).expect("λ = 0"),
        p.shortest(s, t).expect("shortest")
    );
}

#[test]
fn coverage_aware_never_costs_more_than_shortest() {
    // A low wall across the line and the poor patch in front of it: whatever the weight, the
    // coverage-aware path's own cost is at most that of the shortest path.
    let c = city(vec![
        boxb("wall", 30.0, -60.0, 34.0, 60.0, 0.0, 70.0),
        corner(),
    ]);
    let mut p = planner(&c);
    p.with_coverage(&PoorPatch, RsrpThresholds::default());
    let (s, t) = (Point::new(-80.0, -5.0, 40.0), Point::new(80.0, 5.0, 45.0));
    let shortest = p.shortest(s, t).expect("shortest");
    for lambda in [0.1, 1.0, 5.0] {
        let aware = p.coverage_aware(s, t, lambda).expect("coverage-aware");
        check_path(&p, &aware, s, t);
        fly_like_env(&c, &aware);
        let classes = p.classes.as_deref().expect("classes").as_slice();
        let field = CostField::new(
            p.free_space(),
            Some((classes, p.penalties.map(|q| 1.0 + lambda * q))),
        );
        let cost = |path: &Path| -> f64 {
            path.waypoints_m
                .windows(2)
                .map(|w| field.segment(w[0], w[1]).0)
                .sum()
        };
        assert!(
            cost(&aware) <= cost(&shortest) + 1e-9,
            "λ = {lambda}: {} > {}",
            cost(&aware),
            cost(&shortest)
        );
    }
}

#[test]
fn procedural_city_paths_are_flyable() {
    use rand::{RngExt, SeedableRng};
    let c = procedural(400.0);
    let p = planner(&c);
    let fs = p.free_space();
    let a = c.area_m;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let mut free = || loop {
        let q = Point::new(
            rng.random_range(a.min_m.x..a.max_m.x),
            rng.random_range(a.min_m.y..a.max_m.y),
            rng.random_range(20.0..120.0),
        );
        if fs.is_free_point(q) {
            return q;
        }
    };
    let mut planned = 0;
    for _ in 0..12 {
        let (s, t) = (free(), free());
        match p.shortest(s, t) {
            Ok(path) => {
                check_path(&p, &path, s, t);
                fly_like_env(&c, &path);
                planned += 1;
            }
            Err(e) => panic!("{e}"),
        }
    }
    assert_eq!(planned, 12);
}

/// The guide's own clearance (`env.observation.path_guide_clearance_m`): a pair whose only way is
/// a gap narrower than twice the guide's clearance gets the path of the pairs' planner instead
/// (`plan_path` says so) and keeps it; without another planner the failure is the error; a pair
/// with room is guided along the guide planner's own path.
#[test]
fn a_guide_that_cannot_pass_a_gap_falls_back_to_the_pairs_clearance() {
    use crate::pairs::{Pair, plan_path};
    // Two full-height walls across x = 0 leave a 9 m gap at |y| < 4.5.
    let c = city(vec![
        boxb("south", -2.0, -120.0, 2.0, -4.5, 0.0, 200.0),
        boxb("north", -2.0, 4.5, 2.0, 120.0, 0.0, 200.0),
    ]);
    let pairs = planner(&c);
    let cfg = Config::default();
    let wide = PlannerConfig {
        clearance_m: 5.0,
        ..cfg.planner.clone()
    };
    let guide = Planner::new(&c, &cfg.env, &wide);
    let (s, t) = (Point::new(-40.0, 0.0, 50.0), Point::new(40.0, 0.0, 50.0));
    assert!(
        guide.shortest(s, t).is_err(),
        "a 9 m gap with 5 m clearance"
    );
    let through = pairs.shortest(s, t).expect("1.5 m passes the gap");
    let mut pair = Pair {
        id: 0,
        source_m: s,
        destination_m: t,
        shortest_m: through.length_m,
        straight_m: 80.0,
        bin_m: None,
        path: None,
        path_lambda: 0.0,
        path_clearance_m: 0.0,
    };
    assert!(plan_path(&guide, &pairs, &mut pair, 0.0).expect("falls back"));
    assert_eq!(pair.path_clearance_m, 5.0);
    let got = pair.path.as_ref().expect("a path").length_m();
    assert!((got - through.length_m).abs() < 1e-6, "{got}");
    assert!(!plan_path(&guide, &pairs, &mut pair, 0.0).expect("kept, not planned again"));
    let mut bare = Pair {
        path: None,
        ..pair.clone()
    };
    assert!(plan_path(&guide, &guide, &mut bare, 0.0).is_err());
    // A pair on one side of the walls has room for 5 m and gets the guide's own path.
    let (a, b) = (
        Point::new(-60.0, -40.0, 50.0),
        Point::new(-20.0, 40.0, 50.0),
    );
    let mut open = Pair {
        source_m: a,
        destination_m: b,
        path: None,
        ..pair.clone()
    };
    assert!(!plan_path(&guide, &pairs, &mut open, 0.0).expect("the guide plans it"));
    assert_eq!(open.path_clearance_m, 5.0);
    // A coverage-aware guide (λ = 1) falls back to a coverage-aware path, so the fallback
    // needs the classes too: without them the pair is an error, with them (shared) it is
    // guided through the gap.
    let mut pairs = pairs;
    let mut guide = guide;
    // A guide planner without the classes is an error, even where the fallback could plan.
    let mut ready = planner(&c);
    ready.with_coverage(&PoorPatch, RsrpThresholds::default());
    let mut unready = Pair {
        path: None,
        ..pair.clone()
    };
    assert_eq!(
        plan_path(&guide, &ready, &mut unready, 1.0).expect_err("the guide has no classes"),
        PlanError::NoCoverage
    );
    guide.with_coverage(&PoorPatch, RsrpThresholds::default());
    let mut aware = Pair {
        path: None,
        ..pair.clone()
    };
    assert_eq!(
        plan_path(&guide, &pairs, &mut aware, 1.0).expect_err("no classes on the fallback"),
        PlanError::NoCoverage
    );
    assert!(pairs.share_coverage(&guide));
    assert!(plan_path(&guide, &pairs, &mut aware, 1.0).expect("falls back, coverage-aware"));
    assert_eq!((aware.path_lambda, aware.path_clearance_m), (1.0, 5.0));
}

/// A guide planner of another clearance takes the coverage classes computed once by another on
/// the same lattice (`Planner::share_coverage`) and plans the same coverage-aware path as with
/// its own; a planner of another lattice (voxel) does not take them.
#[test]
fn coverage_classes_are_shared_between_clearances_of_one_lattice() {
    let c = city(vec![corner()]);
    let mut first = planner(&c);
    first.with_coverage(&PoorPatch, RsrpThresholds::default());
    let cfg = Config::default();
    let wide = PlannerConfig {
        clearance_m: 5.0,
        ..cfg.planner.clone()
    };
    let mut shared = Planner::new(&c, &cfg.env, &wide);
    assert!(!shared.has_coverage());
    assert!(shared.share_coverage(&first));
    let mut own = Planner::new(&c, &cfg.env, &wide);
    own.with_coverage(&PoorPatch, RsrpThresholds::default());
    let (s, t) = (Point::new(-80.0, 0.0, 50.0), Point::new(80.0, 0.0, 50.0));
    assert_eq!(
        shared.coverage_aware(s, t, 10.0).expect("shared classes"),
        own.coverage_aware(s, t, 10.0).expect("own classes")
    );
    let coarse = PlannerConfig {
        voxel_m: 10.0,
        ..cfg.planner.clone()
    };
    let mut other = Planner::new(&c, &cfg.env, &coarse);
    assert!(!other.share_coverage(&first));
    assert!(!other.has_coverage());
}

/// The edge cache answers a lattice edge the same whichever direction is asked first: parry's
/// swept sphere is not symmetric at the clearance (25 of the 600 m procedural world's 203 411
/// edges near buildings, 459 of Midtown's 1 060 919 answer differently from each end), and a
/// cache filled by whichever search came first made plans depend on what the process had
/// planned before (a held-out pair's shortest path 502.36 m in one process, 498.47 m in another).
#[test]
fn edge_cache_answers_do_not_depend_on_the_direction_asked_first() {
    let c = procedural(600.0);
    let cfg = Config::default();
    let fs = FreeSpace::build(&c, &cfg.env, &cfg.planner);
    let r = fs.clearance_m() + SMOOTHING_MARGIN_M;
    let mut found = 0;
    'scan: for u in 0..fs.num_voxels() as u32 {
        if !fs.is_free_voxel(u) {
            continue;
        }
        let tu = fs.triple(u);
        for d in 0..26 {
            let Some((v, _)) = fs.neighbour(tu, d) else {
                continue;
            };
            if v < u || !fs.is_free_voxel(v) {
                continue;
            }
            let (a, b) = (fs.centre_m(u), fs.centre_m(v));
            if c.mesh.sphere_sweep(a, b, r).is_none() == c.mesh.sphere_sweep(b, a, r).is_none() {
                continue;
            }
            // Fresh caches, asked from opposite ends first.
            let forward = FreeSpace::build(&c, &cfg.env, &cfg.planner);
            let backward = FreeSpace::build(&c, &cfg.env, &cfg.planner);
            let f = forward.edge_clear(u, d, v);
            let b = backward.edge_clear(v, 25 - d, u);
            assert_eq!(
                f, b,
                "edge {u} -> {v} (direction {d}): {f} asked forward, {b} backward"
            );
            assert_eq!(f, backward.edge_clear(u, d, v));
            found += 1;
            if found == 3 {
                break 'scan;
            }
        }
    }
    assert_eq!(
        found, 3,
        "the world has no direction-dependent edge left to test"
    );
}

mod midtown;
