use super::*;
use dupac_eval::a3_setting::A3Setting;
use dupac_eval::front::{FrontPoint, FrontSetting};

/// One successful 10 km flight with these rates (per km) and excellent time (%).
fn flight(handovers_per_km: f64, excellent_pct: f64, ping_pongs_per_km: f64) -> FlightMetrics {
    FlightMetrics {
        outcome: Outcome::Goal,
        distance_m: 10_000.0,
        overhead: 0.0,
        mean_rsrp_dbm: -80.0,
        frac_class: [excellent_pct / 100.0, 1.0 - excellent_pct / 100.0, 0.0],
        handovers: (10.0 * handovers_per_km).round() as u32,
        ping_pongs: (10.0 * ping_pongs_per_km).round() as u32,
        handovers_per_km,
        mean_sinr_db: 0.0,
        frac_sinr_below_m6db: 0.0,
        mean_site_regret_db: 0.0,
        frac_site_regret_high: 0.0,
        frac_class_regret: 0.0,
        frac_interrupted: 0.0,
        frac_excellent_net: excellent_pct / 100.0,
    }
}

fn file(rule: FrontRule, points: Vec<(FrontSetting, f64, f64, f64)>) -> FrontFile {
    FrontFile {
        method: "dupac".into(),
        seed: 0,
        learned_site: true,
        rule,
        points: points
            .into_iter()
            .map(|(setting, h, e, p)| FrontPoint {
                setting,
                flights: vec![(0, flight(h, e, p))],
            })
            .collect(),
    }
}

/// A3's front (the point at 13/km with `c_ping_pongs_per_km`: above B's 0.2, its 0.08 point over
/// B is bought by ping-pongs), the predictive and the hindsight association's fronts.
fn fronts(c_ping_pongs_per_km: f64) -> Vec<FrontFile> {
    let a3 = |offset_db: f64| {
        FrontSetting::A3(A3Setting {
            offset_db,
            hysteresis_db: 0.0,
            time_to_trigger_ms: 0.0,
            l3_filter_k: Some(4),
        })
    };
    let cost = |c: f64| FrontSetting::Predictive {
        handover_cost_db_m: c,
    };
    let bound = |c: f64| FrontSetting::Hindsight {
        handover_cost_db: c,
    };
    vec![
        file(
            FrontRule::A3,
            vec![
                (a3(10.0), 10.0, 90.0, 0.1),
                (a3(8.0), 12.0, 91.0, 0.2),
                (a3(6.0), 13.0, 91.08, c_ping_pongs_per_km),
                (a3(2.0), 16.0, 92.0, 1.5),
            ],
        ),
        file(
            FrontRule::Predictive,
            vec![(cost(150.0), 8.0, 90.5, 0.0), (cost(30.0), 14.0, 91.5, 0.5)],
        ),
        file(
            FrontRule::Hindsight,
            vec![
                (bound(150.0), 7.0, 93.0, 0.0),
                (bound(30.0), 15.0, 96.0, 0.5),
            ],
        ),
    ]
}

fn drawn(dir: &Path, name: &str, fronts: &[FrontFile]) -> Vec<u8> {
    let out = dir.join(name);
    std::fs::create_dir_all(&out).expect("dir");
    draw_fronts(&out, &[], fronts).expect("fronts.png");
    let png = std::fs::read(out.join("fronts.png")).expect("read");
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    png
}

/// The A3 point bought by ping-pongs is drawn apart (the same front with that point's
/// ping-pongs below its neighbour's draws another image), and the predictive and the hindsight
/// fronts are drawn (without them, another image).
#[test]
fn fronts_draw_every_rule_and_ring_the_points_bought_by_ping_pongs() {
    crate::ensure_font().expect("font");
    let dir = tempfile::tempdir().expect("tmp");
    let marked = fronts(0.9);
    let unmarked = fronts(0.1);
    let rows = |f: &[FrontFile]| front_rows(f).iter().filter(|r| r.pp_marked).count();
    assert_eq!((rows(&marked), rows(&unmarked)), (1, 0));
    let with = drawn(dir.path(), "marked", &marked);
    let unmarked_png = drawn(dir.path(), "unmarked", &unmarked);
    assert!(with != unmarked_png, "the ring is not drawn");
    let a3_only = drawn(dir.path(), "a3_only", &marked[..1]);
    assert!(
        with != a3_only,
        "the predictive and hindsight fronts are not drawn"
    );
}

/// A policy flown at several handover weights is one family in `fronts.png` (one colour, one
/// legend entry per rule); any other label, a planner's or one whose `_w` is not a weight, is
/// its own.
#[test]
fn a_policys_weights_are_one_family() {
    assert_eq!(family("look_w1.5"), "look");
    assert_eq!(family("look_w0"), "look");
    assert_eq!(family("my_wide_policy"), "my_wide_policy");
    assert_eq!(family("shortest_a3"), "shortest_a3");
    assert_eq!(family("base"), "base");
}
