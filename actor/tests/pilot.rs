//! The planners, the collision model and the environment agree: a scripted pilot flying the
//! shortest flyable path of every held-out evaluation pair of Midtown (the real data, the default
//! seed and K = 50 per bin) reaches the goal without a collision.

use dupac_actor::env::Env;
use dupac_actor::pairs::eval_pairs;
use dupac_actor::pilot::{fly_waypoints, replay_positions};
use dupac_actor::planner::Planner;
use dupac_common::config::{Association, Config, RadioMode};
use dupac_common::geometry::Point;
use dupac_common::msg::Outcome;
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use rayon::prelude::*;
use std::sync::Arc;

/// RSRP does not matter here: a constant field keeps the test about geometry.
struct Flat(usize);

impl RsrpSource for Flat {
    fn num_sites(&self) -> usize {
        self.0
    }
    fn rsrp_all_dbm(&self, _: Point, out: &mut [f64]) {
        out[..self.0].fill(-70.0);
    }
}

#[test]
fn scripted_pilot_reaches_the_goal_on_every_evaluation_pair() {
    let root = concat!(env!("CARGO_MANIFEST_DIR"), "/..");
    let mut cfg = Config::load(
        None,
        &[
            format!("scenario.buildings_file=\"{root}/data/nyc_midtown_buildings.geojson\""),
            format!("scenario.cells_file=\"{root}/data/nyc_midtown_cells.csv\""),
        ],
    )
    .expect("config");
    cfg.env.association = Association::A3;
    cfg.env.radio_mode = RadioMode::Exact;
    let world = Arc::new(RadioWorld::build(&cfg).expect("Midtown"));
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let pairs = eval_pairs(&planner, &cfg.pairs, &cfg.env, &|_| {});
    assert_eq!(pairs.len(), 7 * 50, "K = 50 pairs in each of the 7 bins");
    let rsrp: Arc<dyn RsrpSource + Send + Sync> = Arc::new(Flat(world.num_sites()));
    let failures: Vec<String> = pairs
        .par_iter()
        .filter_map(|p| {
            let mut env = Env::new(&cfg, world.clone(), rsrp.clone()).expect("env");
            let path = match planner.shortest(p.source_m, p.destination_m) {
                Ok(path) => path,
                Err(e) => return Some(format!("pair {}: {e}", p.id)),
            };
            let ep = p.episode(false, dupac_radio::channel::FieldSplit::Eval);
            match fly_waypoints(&mut env, p.id, ep.clone(), &path.waypoints_m, |e| {
                e.serving()
            }) {
                Ok(f) if f.outcome == Outcome::Goal => {
                    // The flight follows the plan: flown + the last < 10 m equals the plan.
                    let last = f.steps.last().map(|s| s.distance_to_goal_m).unwrap_or(0.0);
                    let gap = (f.distance_m() + last - path.length_m).abs();
                    if gap > 10.0 {
                        return Some(format!("pair {}: flew {gap:.1} m off the plan", p.id));
                    }
                    // Replaying the flight's positions as `dupac eval` records them (f32)
                    // reproduces it: the same steps, end and positions.
                    let pos: Vec<Point> = f
                        .steps
                        .iter()
                        .map(|s| s.position_m.map(|v| f64::from(v as f32)))
                        .collect();
                    let r = replay_positions(&mut env, p.id, ep, &pos, |e| e.serving())
                        .expect("replay");
                    let dev = r
                        .steps
                        .iter()
                        .zip(&f.steps)
                        .flat_map(|(a, b)| {
                            (0..3).map(move |k| (a.position_m[k] - b.position_m[k]).abs())
                        })
                        .fold(0.0, f64::max);
                    (r.steps.len() != f.steps.len() || r.outcome != f.outcome || dev > 1e-3).then(
                        || {
                            format!(
                                "pair {}: replay {} steps {:?} (flight {} {:?}), {dev:.2e} m apart",
                                p.id,
                                r.steps.len(),
                                r.outcome,
                                f.steps.len(),
                                f.outcome
                            )
                        },
                    )
                }
                Ok(f) => Some(format!(
                    "pair {}: {:?} after {} steps",
                    p.id,
                    f.outcome,
                    f.steps.len()
                )),
                Err(e) => Some(format!("pair {}: {e}", p.id)),
            }
        })
        .collect();
    assert!(
        failures.is_empty(),
        "{} failures: {failures:?}",
        failures.len()
    );
}
