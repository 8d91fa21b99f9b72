//! Learning is proven, not assumed: on a small procedural Manhattan grid with short
//! pairs, a fixed seed and a bounded budget, PPO's deterministic policy reaches the goal far more
//! often than a uniformly random policy and than itself at initialisation.

use dupac_actor::env::{Action, Env};
use dupac_actor::metrics::domain_stats;
use dupac_actor::pairs::{Pair, eval_pairs, training_pool};
use dupac_actor::planner::Planner;
use dupac_actor::rollout::fly_policy;
use dupac_common::config::{Association, CityKind, Config, RadioMode};
use dupac_common::geometry::Vector;
use dupac_common::ids::SiteId;
use dupac_common::msg::Outcome;
use dupac_learner::learner::Learner;
use dupac_radio::channel::FieldSplit;
use dupac_radio::source::RsrpSource;
use dupac_radio::world::RadioWorld;
use dupac_run::held_out::evaluate;
use dupac_run::local::LocalWorkers;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;

fn config(association: Association, updates: u64) -> Config {
    let mut cfg = Config::default();
    cfg.scenario.city = CityKind::Procedural;
    cfg.scenario.procedural.size_m = 500.0;
    cfg.scenario.procedural.n_sites = 6;
    cfg.scenario.n_sites = 6;
    cfg.env.radio_mode = RadioMode::Exact;
    cfg.env.association = association;
    cfg.pairs.min_m = 40.0;
    cfg.pairs.max_m = 70.0;
    cfg.pairs.eval_bins_m = vec![50.0, 60.0];
    cfg.pairs.eval_per_bin = 15;
    cfg.pairs.bin_tolerance = 0.1;
    cfg.train.seed = 3;
    cfg.train.num_envs = 8;
    cfg.train.num_steps = 128;
    cfg.train.total_timesteps = 8 * 128 * updates;
    cfg.train.pool_size = 200;
    cfg.ppo.num_minibatches = 4;
    cfg.ppo.hidden = vec![64, 64];
    // Unguided (the path guide, a default, off; the paper's straight-line
    // progress): the bounds below were measured so, and the pool's pairs here carry only the
    // sampler's shortest paths. A guided run is trained by tests/it `train.rs`
    // (`a_run_guided_along_the_coverage_aware_path_trains_and_is_flown_guided`).
    cfg.env.observation.path_guide = false;
    cfg.env.reward.progress = dupac_common::config::Progress::Straight;
    cfg.validate().expect("valid test config");
    cfg
}

fn random_policy_success(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &Arc<dyn RsrpSource + Send + Sync>,
    pairs: &[Pair],
) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut ok = 0;
    for p in pairs {
        let mut env = Env::new(cfg, world.clone(), rsrp.clone()).expect("env");
        env.reset(p.id, p.episode(false, FieldSplit::Eval))
            .expect("reset");
        loop {
            let a = Action {
                move_: Vector::new(
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                    rng.random_range(-1.0..1.0),
                ),
                site: SiteId(rng.random_range(0..6)),
            };
            let s = env.act(&a).expect("act");
            if s.terminated || s.truncated {
                ok += usize::from(s.info.outcome == Some(Outcome::Goal));
                break;
            }
        }
    }
    ok as f64 / pairs.len() as f64
}

/// Budget (PPO updates) of the learning runs.
const UPDATES: u64 = 150;
/// Budget of the run with the site chosen every step (the default), where the learned site
/// must beat A3: at 150 updates it ties or trails A3; at 800 it is ahead on every seed tried
/// (seeds 3, 4, 5 with a ping-pong cost of −8: 0.363/0.352/0.301 against 0.549/0.578/0.569 dB
/// site regret).
const UPDATES_SITE_EVERY_STEP: u64 = 800;

fn learns(association: Association, site_every_step: bool) {
    let updates = if site_every_step {
        UPDATES_SITE_EVERY_STEP
    } else {
        UPDATES
    };
    let mut cfg = config(association, updates);
    cfg.env.site_every_step = site_every_step;
    cfg.validate().expect("valid test config");
    let world = Arc::new(RadioWorld::build(&cfg).expect("procedural world"));
    let rsrp: Arc<dyn RsrpSource + Send + Sync> = world.clone();
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let pool = training_pool(
        &planner,
        &cfg.pairs,
        &cfg.env,
        cfg.train.pool_size,
        cfg.train.seed,
        &|_| {},
    );
    let held_out = eval_pairs(&planner, &cfg.pairs, &cfg.env, &|_| {});
    assert!(
        pool.len() >= 100 && held_out.len() >= 20,
        "pool {} held-out {}",
        pool.len(),
        held_out.len()
    );

    let random = random_policy_success(&cfg, &world, &rsrp, &held_out);
    let (mut trainer, mut workers) = trainer(&cfg, &world, &rsrp, pool);
    let fly = |l: &Learner| evaluate(&cfg, &world, &rsrp, &l.policy(), &held_out).expect("eval");
    let init_stats = domain_stats(&fly(&trainer));
    let init = init_stats.success_rate;
    while !trainer.done() {
        let r = trainer
            .iterate(&mut workers)
            .expect("iteration")
            .expect("a batch");
        assert_eq!(r.stats.skipped_nonfinite, 0);
        if site_every_step {
            // The per-step rows reached the site head (the loss is 0 when none did).
            assert!(r.stats.site_loss > 0.0, "site loss {}", r.stats.site_loss);
        }
    }
    let trained = domain_stats(&fly(&trainer));
    eprintln!(
        "success: random {random:.2}, init {init:.2}, trained {:.2} (collisions {:.2}) after {} steps",
        trained.success_rate, trained.collision_rate, trainer.global_step
    );
    assert!(
        trained.success_rate >= 0.5,
        "trained success {:.2}",
        trained.success_rate
    );
    assert!(trained.success_rate >= random + 0.3, "random {random:.2}");
    assert!(trained.success_rate >= init + 0.3, "init {init:.2}");
    if association == Association::Learned {
        // The learned site choice keeps the site regret (best − serving RSRP) under
        // 1 dB on the held-out pairs, from the several dB of the untrained head; with the site
        // chosen every step (the default, 800 updates) it beats A3's regret on the same
        // policy flown with A3 choosing the site.
        let policy = trainer.policy();
        let regret = |assoc: Association| {
            let mut c = cfg.clone();
            c.env.association = assoc;
            let (mut sum, mut n) = (0.0, 0usize);
            for p in &held_out {
                let mut env = Env::new(&c, world.clone(), rsrp.clone()).expect("env");
                let ep = p.episode(false, FieldSplit::Eval);
                let (_, steps) = fly_policy(&mut env, &policy, p.id, ep, p.id).expect("fly");
                for s in &steps {
                    sum += s.site_regret_db();
                    n += 1;
                }
            }
            sum / n.max(1) as f64
        };
        let (learned, a3) = (regret(Association::Learned), regret(Association::A3));
        eprintln!(
            "mean site regret: untrained {:.2} dB, learned {learned:.3} dB (metrics: {:.2} dB), A3 on the same policy {a3:.3} dB",
            init_stats.site_regret_db, trained.site_regret_db
        );
        assert!((learned - trained.site_regret_db).abs() < 1e-9);
        // At 150 updates the site held per decision trails A3 here (0.590 against 0.556 dB with
        // the default rewards): only the bound is asserted for it.
        assert!(
            learned <= 1.0 && learned < 0.5 * init_stats.site_regret_db,
            "learned site regret {learned:.2} dB (untrained {:.2} dB)",
            init_stats.site_regret_db
        );
        if site_every_step {
            // Measured 0.53–0.66 × A3's on three seeds; 0.8 leaves room for other float paths.
            assert!(
                learned < 0.8 * a3,
                "learned site regret {learned:.3} dB does not beat A3's {a3:.3} dB with the same policy"
            );
        }
    }
}

/// The learner and the local workers of a one-process run (what `dupac train
/// --single-process` builds).
fn trainer(
    cfg: &Config,
    world: &Arc<RadioWorld>,
    rsrp: &Arc<dyn RsrpSource + Send + Sync>,
    pool: Vec<Pair>,
) -> (Learner, LocalWorkers) {
    let workers = LocalWorkers::new(cfg, world, rsrp, &Arc::new(pool)).expect("workers");
    let probe = Env::new(cfg, world.clone(), rsrp.clone()).expect("env");
    let (obs_dim, n_sites) = probe.policy_shape();
    let learner = Learner::new(cfg.clone(), obs_dim, n_sites, &burn::tensor::Device::flex());
    (learner, workers)
}

#[test]
fn ppo_learns_to_reach_the_goal_on_a_small_procedural_city() {
    learns(Association::Learned, false);
}

/// `env.site_every_step` (the default; the test above turns it off):
/// the same learning run with the site chosen at every step, at 800 updates, learns to reach the
/// goal and keeps a lower site regret than the same policy flown with A3 (the per-step rows
/// through the learner, the per-step choice through the actors). ≈ 60 s on the 2-core machine
/// (the other runs of this file: 10–15 s).
#[test]
fn a_site_chosen_every_step_learns_and_beats_a3_on_site_regret() {
    learns(Association::Learned, true);
}

#[test]
fn the_base_method_learns_with_a3_association() {
    learns(Association::A3, false);
}

#[test]
fn same_seed_same_run_different_seed_different_run() {
    let run = |seed: u64| {
        let mut cfg = config(Association::Learned, UPDATES);
        cfg.train.seed = seed;
        cfg.train.total_timesteps = 8 * 128 * 2;
        let world = Arc::new(RadioWorld::build(&cfg).expect("world"));
        let rsrp: Arc<dyn RsrpSource + Send + Sync> = world.clone();
        let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
        let pool = training_pool(&planner, &cfg.pairs, &cfg.env, 50, 1, &|_| {});
        let (mut t, mut workers) = trainer(&cfg, &world, &rsrp, pool);
        let mut returns = Vec::new();
        while !t.done() {
            let r = t
                .iterate(&mut workers)
                .expect("iteration")
                .expect("a batch");
            returns.push(
                r.row
                    .get("losses/value_loss")
                    .copied()
                    .unwrap_or(f64::NAN)
                    .to_bits(),
            );
        }
        (t.policy(), returns)
    };
    let (a, ra) = run(5);
    let (b, rb) = run(5);
    let (c, _) = run(6);
    assert_eq!(a, b, "same seed, same weights and normalisers");
    assert_eq!(ra, rb);
    assert_ne!(a.actor, c.actor, "another seed, another run");
}

/// Actors fly only weights of their own observation: the observation a policy records is
/// checked before each rollout (another RSRP scale, or another flag of the same layout length,
/// would otherwise be misread silently).
#[test]
fn workers_refuse_weights_of_another_observation() {
    use dupac_learner::source::TrajectorySource;
    let cfg = config(Association::Learned, 1);
    let world = Arc::new(RadioWorld::build(&cfg).expect("world"));
    let rsrp: Arc<dyn RsrpSource + Send + Sync> = world.clone();
    let planner = Planner::new(&world.city, &cfg.env, &cfg.planner);
    let pool = training_pool(&planner, &cfg.pairs, &cfg.env, 20, 1, &|_| {});
    let (t, mut workers) = trainer(&cfg, &world, &rsrp, pool);
    let mut p = t.policy();
    let samples = t.batch_size();
    assert!(workers.collect(&p, samples, &t.progress()).is_ok());
    p.observation.as_mut().expect("recorded").rsrp_centre_dbm -= 10.0;
    let Err(e) = workers.collect(&p, samples, &t.progress()) else {
        panic!("weights of another observation were flown");
    };
    let e = e.to_string();
    assert!(e.contains("env.observation.rsrp_centre_dbm"), "{e}");
}
