//! `docs/spec_env.toml` restores the environment of docs/spec/env.md where the project's
//! defaults depart from it (docs/env.md): the file must load and say exactly that.

use dupac_common::config::{
    ActionClip, Config, NearestObstacle, Progress, SensorScale, SiteGradient, SiteHead,
};
use std::path::Path;

#[test]
fn spec_env_toml_is_the_spec_environment() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/spec_env.toml");
    let cfg = Config::load(Some(&path), &[]).expect("docs/spec_env.toml loads");
    let e = &cfg.env;
    assert_eq!(e.action_clip, ActionClip::Cube);
    assert_eq!(e.action_repeat, 1);
    assert_eq!(e.training_margin_m, 0.0);
    assert_eq!(e.max_step_m, 1.0);
    assert_eq!(e.reward.collision_reward, -100.0);
    assert_eq!(e.reward.out_of_bounds_reward, -100.0);
    let o = &e.observation;
    assert_eq!(o.sensor_scale, SensorScale::Linear);
    assert_eq!(o.nearest_obstacle, NearestObstacle::Fan);
    assert!(!o.geofence && !o.goal_direction);
    assert!(!o.path_guide && e.reward.progress == Progress::Straight);
    // Everything else is the default: the file changes only the departures.
    let mut spec = Config::default();
    spec.env.action_clip = ActionClip::Cube;
    spec.env.action_repeat = 1;
    spec.env.training_margin_m = 0.0;
    spec.env.reward.collision_reward = -100.0;
    spec.env.reward.out_of_bounds_reward = -100.0;
    spec.env.observation.sensor_scale = SensorScale::Linear;
    spec.env.observation.nearest_obstacle = NearestObstacle::Fan;
    spec.env.observation.geofence = false;
    spec.env.observation.goal_direction = false;
    spec.env.observation.path_guide = false;
    spec.env.observation.path_guide_lambda = 0.0;
    spec.env.observation.path_guide_clearance_m = 0.0;
    spec.env.observation.path_lookahead_m = 30.0;
    spec.env.reward.progress = Progress::Straight;
    assert_eq!(cfg, spec);
}

/// `docs/paper_dupac.toml` restores the paper's site learning: it must load, pass the
/// configuration's checks against the defaults (the site chosen every step is on by default
/// and needs the equivariant head: the file turns it off), and change only the site learning.
#[test]
fn paper_dupac_toml_is_the_papers_site_learning() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/paper_dupac.toml");
    let cfg = Config::load(Some(&path), &[]).expect("docs/paper_dupac.toml loads and validates");
    let mut paper = Config::default();
    paper.env.site_every_step = false;
    paper.env.reward.handover_reward = 0.0;
    paper.env.reward.ping_pong_reward = 0.0;
    paper.env.observation.site_ping_pong = false;
    paper.env.reward.site_regret_weight = 0.0;
    paper.env.reward.route_connectivity_weight = 0.0;
    paper.env.observation.site_features = false;
    paper.ppo.site_head = SiteHead::Slots;
    paper.ppo.site_gradient = SiteGradient::Sampled;
    // The path guide (a default) off: the paper's UAV has no map; λ and the clearance at 0.
    paper.env.observation.path_guide = false;
    paper.env.observation.path_guide_lambda = 0.0;
    paper.env.observation.path_guide_clearance_m = 0.0;
    paper.env.observation.path_lookahead_m = 30.0;
    paper.env.reward.progress = Progress::Straight;
    assert_eq!(cfg, paper);
}

/// `docs/foresight.toml` is the look-ahead design of docs/results.md: it must load and give
/// the environment every committed look-ahead policy (`results/foresight/{real,det}/dupac_s*`)
/// was trained with, apart from the channel and the seeds, so that `dupac train --config
/// docs/foresight.toml` trains the page's points.
#[test]
fn foresight_toml_is_the_committed_lookahead_policies_environment() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let cfg = Config::load(Some(&root.join("docs/foresight.toml")), &[])
        .expect("docs/foresight.toml loads and validates");
    let mut points = 0;
    for world in ["real", "det"] {
        let dir = root.join("results/foresight").join(world);
        for entry in std::fs::read_dir(&dir).expect("results/foresight/<world>") {
            let point = entry.expect("entry").path().join("config.toml");
            if !point.exists() {
                continue;
            }
            let trained = Config::load(Some(&point), &[]).expect("a committed point's config");
            assert_eq!(
                trained.env.observation,
                cfg.env.observation,
                "{}",
                point.display()
            );
            assert_eq!(trained.env.reward, cfg.env.reward, "{}", point.display());
            points += 1;
        }
    }
    assert!(points >= 2, "no committed look-ahead point found");
}
