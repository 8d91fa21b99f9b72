//! The per-site rewards and the departures' terms: each site's counterfactual reward, the
//! handover, ping-pong, site-regret and route terms, and a site chosen every step.

use super::*;

/// A field where the sites trade places along y: site 0 falls from excellent to poor, site 1
/// rises from poor to excellent.
const CROSSING: fn(usize, Point) -> f64 = |s, p| {
    if s == 0 {
        -70.0 - 0.5 * p[1]
    } else {
        -105.0 + 0.5 * p[1]
    }
};

/// `Env::site_rewards` holds, for every site k, the reward the decision would have had
/// with k chosen: replaying the same decisions with k chosen at decision t gives exactly that
/// reward, and the chosen site's entry is the reward returned. The departures' terms (handover
/// and ping-pong costs, site regret, route connectivity) are on, as by default; then without the
/// ping-pong cost and its feature.
#[test]
fn site_rewards_are_what_each_site_would_have_given() {
    let mut cfg = unguided();
    cfg.env.association = Association::Learned;
    assert!(cfg.env.reward.ping_pong_reward < 0.0 && cfg.env.observation.site_ping_pong);
    site_rewards_match_their_counterfactuals(&cfg);
    cfg.env.reward.ping_pong_reward = 0.0;
    cfg.env.observation.site_ping_pong = false;
    site_rewards_match_their_counterfactuals(&cfg);
}

fn site_rewards_match_their_counterfactuals(cfg: &Config) {
    assert!(cfg.env.reward.handover_reward < 0.0 && cfg.env.reward.site_regret_weight > 0.0);
    assert!(cfg.env.reward.route_connectivity_weight > 0.0);
    let make = || Env::new(cfg, world(), Arc::new(Field(CROSSING, 2))).expect("env");
    let episode = ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 120.0, 50.0));
    // A scripted flight that switches sites now and then.
    let plan: Vec<Action> = (0..16)
        .map(|t| mv(0.0, 1.0, 0.0, [0, 0, 1, 1, 0, 1, 1, 1][t % 8]))
        .collect();
    let mut main = make();
    main.reset(1, episode.clone()).expect("reset");
    let mut classes = std::collections::HashSet::new();
    for (t, a) in plan.iter().enumerate() {
        let s = main.act(a).expect("act");
        let sr = main.site_rewards().to_vec();
        assert_eq!(sr.len(), 2);
        assert!(
            (sr[a.site.index()] - s.reward).abs() < 1e-9,
            "decision {t}: chosen site's entry {} vs reward {}",
            sr[a.site.index()],
            s.reward
        );
        for (k, want) in sr.iter().enumerate() {
            let mut alt = make();
            alt.reset(1, episode.clone()).expect("reset");
            for b in &plan[..t] {
                alt.act(b).expect("replay");
            }
            let got = alt.act(&mv(0.0, 1.0, 0.0, k as u16)).expect("alt").reward;
            assert!(
                (got - want).abs() < 1e-9,
                "decision {t} site {k}: counterfactual {got} vs recorded {want}"
            );
        }
        classes.insert(format!("{:?}", s.info.class));
        if s.terminated || s.truncated {
            break;
        }
    }
    assert!(
        classes.len() >= 2,
        "the flight crossed classes: {classes:?}"
    );
}

/// The departures' reward terms, each on its own: the handover cost once per handover, the site
/// regret −κ_s·(best − serving) per step, the route term −μ1·κ_r·penalty(best class)·metres.
#[test]
fn handover_cost_site_regret_and_route_terms() {
    let make = |f: fn(&mut Config)| {
        let mut cfg = unguided();
        cfg.env.association = Association::Learned;
        paper_reward(&mut cfg);
        f(&mut cfg);
        let mut e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
        e.reset(
            1,
            ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0)),
        )
        .expect("reset");
        e
    };
    // Handover to site 1 (mediocre, −95): Eq. (8) 10 − 0.95, plus −2 once.
    let mut e = make(|c| c.env.reward.handover_reward = -2.0);
    let r = e.step(&mv(0.0, 1.0, 0.0, 1)).expect("step").reward;
    assert!((r - (10.0 - 0.95 - 2.0)).abs() < 1e-9, "{r}");
    let r = e.step(&mv(0.0, 1.0, 0.0, 1)).expect("step").reward;
    assert!(
        (r - (10.0 - 0.95)).abs() < 1e-9,
        "no handover, no cost: {r}"
    );
    // Site regret: serving −95 where −70 is best: −0.1 · 25 dB.
    let mut e = make(|c| c.env.reward.site_regret_weight = 0.1);
    let r = e.step(&mv(0.0, 1.0, 0.0, 1)).expect("step").reward;
    assert!((r - (10.0 - 0.95 - 2.5)).abs() < 1e-9, "{r}");
    let r = e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step").reward;
    assert!((r - 10.0).abs() < 1e-9, "the best site has no regret: {r}");
    // Route term: the best site is excellent here, so nothing; under a field whose best is
    // mediocre, −μ1 · κ_r · penalty_mediocre (1) per metre.
    let mut e = make(|c| c.env.reward.route_connectivity_weight = 0.5);
    let r = e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step").reward;
    assert!((r - 10.0).abs() < 1e-9, "{r}");
    let mut cfg = unguided();
    cfg.env.association = Association::Learned;
    paper_reward(&mut cfg);
    cfg.env.reward.route_connectivity_weight = 0.5;
    let mut e = Env::new(&cfg, world(), Arc::new(Field(|_, _| -90.0, 2))).expect("env");
    e.reset(
        1,
        ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0)),
    )
    .expect("reset");
    let r = e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step").reward;
    assert!((r - (10.0 - 0.9 - 5.0)).abs() < 1e-9, "{r}");
}

/// One definition of handovers and ping-pongs. The environment's per-step flags (what
/// training counts) and evaluation's recount of the recorded serving sites (`dupac eval`) agree
/// on a flight whose learned choice jumps between sites at pseudo-random steps.
#[test]
fn the_environment_flags_and_the_evaluation_recount_agree() {
    let cfg = {
        let mut c = unguided();
        c.env.association = Association::Learned;
        c
    };
    let window = (cfg.env.ping_pong_window_s / cfg.env.dt_s())
        .ceil()
        .max(1.0) as u32;
    let mut e = env_with(Association::Learned, EXCELLENT);
    e.reset(
        1,
        ep(Point::new(0.0, -90.0, 50.0), Point::new(0.0, 100.0, 50.0)),
    )
    .expect("reset");
    let mut serving = vec![e.serving().0];
    let (mut handovers, mut ping_pongs) = (0u32, 0u32);
    let mut x = 12345u64;
    for _ in 0..150 {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let site = ((x >> 33) % 7).min(1) as u16; // mostly site 1, now and then site 0
        let st = e.step(&mv(0.0, 0.5, 0.0, site)).expect("step");
        serving.push(st.info.serving.0);
        handovers += u32::from(st.info.handover);
        ping_pongs += u32::from(st.info.ping_pong);
        if st.terminated || st.truncated {
            break;
        }
    }
    assert!(
        handovers >= 10 && ping_pongs >= 2,
        "{handovers} {ping_pongs}"
    );
    assert_eq!(
        dupac_actor::metrics::count_handovers(&serving, window),
        (handovers, ping_pongs)
    );
}

/// `env.site_every_step`: a decision holds its move for `action_repeat` steps while a
/// site is chosen at every step. Each step's site features are the observation's site features
/// at that state, and each step's every-site reward is what that step would have returned with
/// that site chosen at it: replaying the same steps one at a time with [`Env::step`] (a decision
/// every step) and site j at step t gives exactly the recorded entry; the chosen site's entry
/// is the step's reward.
fn step_site_rewards_match_their_counterfactuals(cfg: &Config, min_handovers: usize) {
    let make = || Env::new(cfg, world(), Arc::new(Field(CROSSING, 2))).expect("env");
    let episode = ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 120.0, 50.0));
    let seq = |t: usize| SiteId([0u16, 1, 1, 0, 1, 0, 0, 1, 1, 1, 0][t % 11]);
    let mut main = make();
    main.reset(1, episode.clone()).expect("reset");
    assert!(main.site_every_step());
    let tail = main
        .layout()
        .range(field::SITE_FEATURES)
        .expect("site features");
    let (mut t0, mut switches) = (0usize, 0);
    for d in 0..10 {
        let obs_tail = main.observation()[tail.clone()].to_vec();
        let mut asked = Vec::new();
        let s = main
            .act_site_every_step(Vector::new(0.0, 1.0, 0.0), |k, feats| {
                asked.push((k, feats.to_vec()));
                seq(t0 + k)
            })
            .expect("act");
        let steps = main.substeps().to_vec();
        assert_eq!(asked.len(), steps.len());
        assert_eq!(
            asked[0].1, obs_tail,
            "decision {d}: step 0 reads the observation"
        );
        let feats = main.step_site_features().to_vec();
        let rewards = main.step_site_rewards().to_vec();
        assert_eq!(feats.len(), steps.len() * tail.len());
        assert_eq!(rewards.len(), steps.len() * 2);
        let total: f64 = steps.iter().map(|i| i.reward).sum();
        assert!((total - s.reward).abs() < 1e-9);
        for (k, info) in steps.iter().enumerate() {
            assert_eq!(asked[k].1, feats[k * tail.len()..(k + 1) * tail.len()]);
            let chosen = seq(t0 + k).index();
            assert!(
                (rewards[k * 2 + chosen] - info.reward).abs() < 1e-9,
                "step {}: chosen site's entry {} vs reward {}",
                t0 + k,
                rewards[k * 2 + chosen],
                info.reward
            );
            switches += usize::from(info.handover);
            for j in 0..2 {
                let mut alt = make();
                alt.reset(1, episode.clone()).expect("reset");
                for u in 0..t0 + k {
                    alt.step(&Action {
                        move_: Vector::new(0.0, 1.0, 0.0),
                        site: seq(u),
                    })
                    .expect("replay");
                }
                assert_eq!(
                    alt.observation()[tail.clone()],
                    feats[k * tail.len()..(k + 1) * tail.len()],
                    "step {}: the features of the state it was chosen in",
                    t0 + k
                );
                let got = alt.step(&mv(0.0, 1.0, 0.0, j as u16)).expect("alt").reward;
                let want = rewards[k * 2 + j];
                assert!(
                    (got - want).abs() < 1e-9,
                    "step {} site {j}: counterfactual {got} vs recorded {want}",
                    t0 + k
                );
            }
        }
        t0 += steps.len();
        if s.terminated || s.truncated {
            break;
        }
    }
    assert!(
        switches >= min_handovers,
        "the flight changed sites inside decisions: {switches}"
    );
}

#[test]
fn a_site_chosen_every_step_gets_every_steps_counterfactual_rewards() {
    let mut cfg = unguided();
    cfg.env.association = Association::Learned;
    cfg.env.site_every_step = true;
    // Without the ping-pong cost and its feature first (the default has both: last below).
    cfg.env.reward.ping_pong_reward = 0.0;
    cfg.env.observation.site_ping_pong = false;
    step_site_rewards_match_their_counterfactuals(&cfg, 10);
    // A ping-pong cost and its site feature: each step's every-site reward charges it where
    // serving that site would be a ping-pong, and the features say which (the replay's own).
    cfg.env.reward.ping_pong_reward = -4.0;
    cfg.env.observation.site_ping_pong = true;
    step_site_rewards_match_their_counterfactuals(&cfg, 10);
}

/// `env.reward.ping_pong_reward`: a handover back to the site the last handover left,
/// within `env.ping_pong_window_s` (21 steps), costs that reward on top of the handover cost,
/// and `env.observation.site_ping_pong` marks that site in the features beforehand, until the
/// window has passed.
#[test]
fn a_ping_pong_is_charged_and_marked_in_the_site_features() {
    use dupac_common::obs::site_feature;
    let episode = ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 120.0, 50.0));
    // Site 0 serves at the start; 1, back to 0 (a ping-pong), then 0 held past the window.
    let seq: Vec<u16> = [1, 0].into_iter().chain([0; 25]).collect();
    let run = |ping_pong_reward: f64| {
        let mut cfg = unguided();
        cfg.env.association = Association::Learned;
        cfg.env.observation.site_ping_pong = true;
        cfg.env.reward.ping_pong_reward = ping_pong_reward;
        let mut e = Env::new(&cfg, world(), Arc::new(Field(CROSSING, 2))).expect("env");
        e.reset(1, episode.clone()).expect("reset");
        let tail = e
            .layout()
            .range(field::SITE_FEATURES)
            .expect("site features");
        let per_site = tail.len() / 2;
        let at = site_feature::ping_pong(&cfg.env.observation).expect("the feature");
        let mut out = Vec::new();
        for &site in &seq {
            let flags = [0, 1].map(|k| e.observation()[tail.start + k * per_site + at]);
            let st = e.step(&mv(0.0, 1.0, 0.0, site)).expect("step");
            assert!(
                (e.site_rewards()[usize::from(site)] - st.reward).abs() < 1e-9,
                "the chosen site's entry is the reward"
            );
            out.push((flags, st.info.handover, st.info.ping_pong, st.reward));
        }
        out
    };
    let (charged, free) = (run(-4.0), run(0.0));
    assert_eq!(
        (charged[0].0, charged[0].1, charged[0].2),
        ([0.0, 0.0], true, false)
    );
    assert_eq!(
        (charged[1].0, charged[1].1, charged[1].2),
        ([1.0, 0.0], true, true),
        "before the switch back, site 0 is marked; the switch back is a ping-pong"
    );
    for (k, (flags, handover, _, _)) in charged.iter().enumerate().skip(2) {
        assert!(!handover);
        // Before step n = k + 1, site 1 (left at step 2) is marked while n − 2 ≤ 21.
        let marked = k < 23;
        assert_eq!(*flags, [0.0, f32::from(u8::from(marked))], "step {}", k + 1);
    }
    for (k, (c, f)) in charged.iter().zip(&free).enumerate() {
        let want = if k == 1 { f.3 - 4.0 } else { f.3 };
        assert!(
            (c.3 - want).abs() < 1e-9,
            "step {}: {} vs {want}",
            k + 1,
            c.3
        );
    }
}

/// Without `env.site_every_step` (or without the learned association) a per-step decision is
/// refused rather than run with a held site.
#[test]
fn a_site_every_step_decision_needs_the_key_and_the_learned_association() {
    let episode = ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 120.0, 50.0));
    for (every, assoc) in [(false, Association::Learned), (true, Association::A3)] {
        let mut cfg = unguided();
        cfg.env.association = assoc;
        cfg.env.site_every_step = every;
        let mut e = Env::new(&cfg, world(), Arc::new(Field(CROSSING, 2))).expect("env");
        e.reset(1, episode.clone()).expect("reset");
        assert!(!e.site_every_step());
        assert_eq!(
            e.act_site_every_step(Vector::new(0.0, 1.0, 0.0), |_, _| SiteId(0)),
            Err(EnvError::SiteEveryStepUnavailable)
        );
    }
}

/// The handover weight w (docs/env.md "Handover weight"): the handover and ping-pong costs are
/// the configured ones times w; training draws w per episode from [0, handover_weight_max],
/// evaluation uses handover_weight; the observation carries ln(1 + w), so a policy conditioned
/// on it can tell the cost it is charged.
#[test]
fn the_handover_weight_scales_the_costs_and_is_observed() {
    use dupac_radio::channel::FieldSplit;
    let make = |weight: f64, max: f64, split: FieldSplit| {
        let mut cfg = unguided();
        cfg.env.association = Association::Learned;
        paper_reward(&mut cfg);
        cfg.env.reward.handover_reward = -2.0;
        cfg.env.observation.handover_weight = true;
        cfg.env.reward.handover_weight = weight;
        cfg.env.reward.handover_weight_max = max;
        cfg.validate().expect("valid");
        let e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
        (e, split)
    };
    let in_field = |split: FieldSplit| {
        let mut e = ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0));
        e.field = split;
        e
    };
    let observed = |e: &Env| {
        let r = e.layout().range(field::HANDOVER_WEIGHT).expect("field");
        e.observation()[r.start]
    };
    // A handover to site 1 (mediocre, −95): Eq. (8) 10 − 0.95, plus w · (−2).
    for w in [0.0, 1.0, 3.0] {
        let (mut e, split) = make(w, 0.0, FieldSplit::Eval);
        e.reset(1, in_field(split)).expect("reset");
        assert_eq!(e.handover_weight(), w);
        assert!((observed(&e) - (w as f32).ln_1p()).abs() < 1e-6);
        let r = e.step(&mv(0.0, 1.0, 0.0, 1)).expect("step").reward;
        assert!((r - (10.0 - 0.95 - 2.0 * w)).abs() < 1e-9, "w {w}: {r}");
    }
    // Training draws it per episode, uniformly in [0, 6], the same for one seed; evaluation
    // keeps the configured weight whatever the maximum.
    let (mut e, split) = make(1.0, 6.0, FieldSplit::Train);
    let episode = in_field(split);
    let draws: Vec<f64> = (0..400u64)
        .map(|seed| {
            e.reset(seed, episode.clone()).expect("reset");
            assert!((observed(&e) - (e.handover_weight() as f32).ln_1p()).abs() < 1e-6);
            e.handover_weight()
        })
        .collect();
    assert!(draws.iter().all(|w| (0.0..=6.0).contains(w)));
    let mean = draws.iter().sum::<f64>() / draws.len() as f64;
    assert!((mean - 3.0).abs() < 0.3, "mean draw {mean}");
    assert!(draws.iter().any(|w| *w < 1.0) && draws.iter().any(|w| *w > 5.0));
    e.reset(7, episode.clone()).expect("reset");
    let again = e.handover_weight();
    e.reset(7, episode.clone()).expect("reset");
    assert_eq!(e.handover_weight(), again);
    let (mut e, split) = make(1.0, 6.0, FieldSplit::Eval);
    for seed in 0..20 {
        e.reset(seed, in_field(split)).expect("reset");
        assert_eq!(e.handover_weight(), 1.0);
    }
    // A draw needs the observation.
    let mut cfg = unguided();
    cfg.env.reward.handover_weight_max = 6.0;
    let err = cfg
        .validate()
        .expect_err("a drawn weight the policy cannot see");
    assert!(
        err.to_string().contains("env.observation.handover_weight"),
        "{err}"
    );
}

/// `env.reward.handover_weight_draw = "log"`: training draws ln(1 + w) uniformly from
/// [0, ln(1 + handover_weight_max)], so a wide range keeps its share of small weights.
#[test]
fn a_log_draw_is_uniform_in_the_observed_weight() {
    use dupac_common::config::WeightDraw;
    use dupac_radio::channel::FieldSplit;
    let mut cfg = unguided();
    cfg.env.association = Association::Learned;
    cfg.env.observation.handover_weight = true;
    cfg.env.reward.handover_weight_max = 30.0;
    cfg.env.reward.handover_weight_draw = WeightDraw::Log;
    cfg.validate().expect("valid");
    let mut e = Env::new(&cfg, world(), Arc::new(Field(EXCELLENT, 2))).expect("env");
    let episode = ep(Point::new(0.0, 0.0, 50.0), Point::new(0.0, 100.0, 50.0));
    assert_eq!(episode.field, FieldSplit::Train);
    let logs: Vec<f64> = (0..2000u64)
        .map(|seed| {
            e.reset(seed, episode.clone()).expect("reset");
            let w = e.handover_weight();
            assert!((0.0..=30.0).contains(&w), "{w}");
            w.ln_1p()
        })
        .collect();
    let top = 31f64.ln();
    let mean = logs.iter().sum::<f64>() / logs.len() as f64;
    assert!(
        (mean - top / 2.0).abs() < 0.05 * top,
        "mean ln(1 + w) {mean}"
    );
    // A uniform draw in w would put 10 % of the episodes at w ≤ 3; this one puts 40 %.
    let low = logs.iter().filter(|&&l| l <= 4f64.ln()).count() as f64 / logs.len() as f64;
    assert!(
        (low - 4f64.ln() / top).abs() < 0.04,
        "share at w ≤ 3: {low}"
    );
}
