//! The real channel in the environment: the true RSRP has the episode's shadow fading, the UAV
//! observes and A3 compares the measured one, both are recorded, and the metrics score the true.

use super::*;
use dupac_actor::metrics::{EpisodeAccumulator, count_handovers};
use dupac_common::compact::code;
use dupac_common::config::ChannelModel;
use dupac_radio::channel::FieldSplit;

const FLAT: fn(usize, Point) -> f64 = |s, _| if s == 0 { -75.0 } else { -78.0 };

/// An environment of the real channel and the field split its episodes fly in.
fn real_env(assoc: Association, split: FieldSplit) -> (Env, FieldSplit) {
    let mut cfg = unguided();
    cfg.env.association = assoc;
    cfg.radio.channel.model = ChannelModel::Real;
    let w = world();
    // The world's channel comes from the configuration it was built with.
    let w = Arc::new(RadioWorld::from_parts(
        w.city.clone(),
        w.sites.clone(),
        &cfg.radio,
    ));
    let e = Env::new(&cfg, w, Arc::new(Field(FLAT, 2))).expect("env");
    (e, split)
}

/// Flies 40 steps north from (0, −60, 50) in `split`'s realisations and returns every step's
/// info.
fn fly_in(e: &mut Env, split: FieldSplit, seed: u64) -> Vec<dupac_actor::record::StepInfo> {
    let mut episode = ep(Point::new(0.0, -60.0, 50.0), Point::new(0.0, 60.0, 50.0));
    episode.field = split;
    e.reset(seed, episode).expect("reset");
    (0..40)
        .map(|_| e.step(&mv(0.0, 1.0, 0.0, 0)).expect("step").info)
        .collect()
}

#[test]
fn true_rsrp_has_the_fields_shadowing_and_the_uav_observes_the_measured() {
    let (mut e, split) = real_env(Association::A3, FieldSplit::Train);
    let steps = fly_in(&mut e, split, 9);
    let field = e.field().expect("a real channel draws a field").clone();
    let w = e.world();
    let mut measured_differs = 0;
    for s in &steps {
        let p = s.position_m;
        let los: Vec<f64> = (0..2)
            .map(|k| f64::from(u8::from(w.los(SiteId(k as u16), p))))
            .collect();
        let mut sf = [0.0; 2];
        field.shadow_db(p, &los, &mut sf);
        let k = s.serving.index();
        let want = FLAT(k, p) - sf[k];
        assert!(
            (s.serving_rsrp_dbm - want).abs() < 1e-9,
            "true RSRP {} is the model's less the field's shadowing {}",
            s.serving_rsrp_dbm,
            want
        );
        assert!(sf[k].abs() > 1e-6, "the field shadows");
        if (s.measured_serving_rsrp_dbm - s.serving_rsrp_dbm).abs() > 1e-3 {
            measured_differs += 1;
        }
    }
    assert!(measured_differs > 30, "measured ≠ true on most steps");
    // The same seed flies the same field and the same errors; evaluation draws other fields.
    let (mut again, split) = real_env(Association::A3, FieldSplit::Train);
    assert_eq!(fly_in(&mut again, split, 9), steps);
    let (mut eval, split) = real_env(Association::A3, FieldSplit::Eval);
    assert_ne!(fly_in(&mut eval, split, 9), steps);
    // The observation carries the measured RSRP, not the true one (its code: the 0.5 dB grid
    // value at or below it).
    let o = e.observation();
    let r = e.layout().range(field::RSRP_ALL);
    if let Some(r) = r {
        let c = e.config().observation.rsrp_centre_dbm;
        let sc = e.config().observation.rsrp_scale_db;
        for k in 0..2 {
            let coded = code::rsrp_dbm(code::rsrp(e.measured_dbm()[k]));
            let want = ((coded - c) / sc) as f32;
            assert!((o[r.start + k] - want).abs() < 1e-5);
        }
    }
}

/// The episode's metrics score the true RSRP, not the measured one; the handovers recounted from
/// the site the environment started with are the environment's. (Evaluation's records keep
/// both RSRPs: `dupac_eval::record`'s test.)
#[test]
fn metrics_score_the_true_rsrp_and_count_the_environments_handovers() {
    let (mut e, split) = real_env(Association::A3, FieldSplit::Eval);
    let steps = fly_in(&mut e, split, 3);
    let mut acc = EpisodeAccumulator::new(e.config());
    steps.iter().for_each(|s| acc.push(s));
    let summary = acc.finish(0, 120.0, dupac_common::msg::Outcome::TimeLimit);
    let serving: Vec<u16> = std::iter::once(e.start_serving().0)
        .chain(steps.iter().map(|s| s.serving.0))
        .collect();
    let flagged = steps.iter().filter(|s| s.handover).count() as u32;
    assert_eq!(count_handovers(&serving, 20).0, flagged);
    assert_eq!(summary.handovers, flagged);
    let n = steps.len() as f64;
    let true_mean = steps.iter().map(|s| s.serving_rsrp_dbm).sum::<f64>() / n;
    let measured_mean = steps
        .iter()
        .map(|s| s.measured_serving_rsrp_dbm)
        .sum::<f64>()
        / n;
    assert!(
        (summary.mean_rsrp_dbm - true_mean).abs() < 1e-9,
        "{} vs {true_mean}",
        summary.mean_rsrp_dbm
    );
    assert!((summary.mean_rsrp_dbm - measured_mean).abs() > 1e-3);
}

#[test]
fn the_deterministic_world_measures_exactly() {
    let mut e = env_with(Association::A3, FLAT);
    let steps = fly_in(&mut e, FieldSplit::Train, 9);
    assert!(e.field().is_none());
    for s in &steps {
        assert_eq!(s.serving_rsrp_dbm, FLAT(s.serving.index(), s.position_m));
        assert_eq!(s.measured_serving_rsrp_dbm, s.serving_rsrp_dbm);
    }
}
