use super::*;

#[test]
fn the_upper_envelope_keeps_the_undominated_points() {
    // (handovers/km, excellent %)
    let p = [
        (10.0, 90.0),
        (12.0, 89.0), // dominated by (10, 90)
        (15.0, 93.0),
        (15.0, 92.0), // same x, less y
        (20.0, 93.0), // no gain for more handovers
        (25.0, 95.0),
        (f64::NAN, 99.0),
    ];
    assert_eq!(upper_envelope(&p), vec![0, 2, 5]);
}

/// The metrics of one successful 10 km flight with these rates (per km) and excellent time.
fn flight(handovers_per_km: f64, excellent_pct: f64, ping_pongs_per_km: f64) -> FlightMetrics {
    FlightMetrics {
        outcome: dupac_common::msg::Outcome::Goal,
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

fn a3(offset_db: f64, l3_filter_k: Option<u32>) -> FrontSetting {
    FrontSetting::A3(A3Setting {
        offset_db,
        hysteresis_db: 0.0,
        time_to_trigger_ms: 0.0,
        l3_filter_k,
    })
}

/// (setting, handovers/km, excellent %, ping-pongs/km): C is on the 2-D envelope only by
/// 0.08 point over B, which has fewer handovers and a quarter of C's ping-pongs; E is under
/// the envelope and bought off by B too.
const POINTS: [(f64, f64, f64, f64); 5] = [
    (10.0, 10.0, 90.0, 0.1), // A
    (8.0, 12.0, 91.0, 0.2),  // B
    (6.0, 13.0, 91.08, 0.9), // C
    (5.0, 14.0, 91.05, 0.3), // E
    (2.0, 16.0, 92.0, 1.5),  // D
];

fn a3_front(method: &str) -> FrontFile {
    FrontFile {
        method: method.into(),
        seed: 0,
        learned_site: true,
        rule: FrontRule::A3,
        points: POINTS
            .iter()
            .map(|&(o, h, e, p)| FrontPoint {
                setting: a3(o, Some(4)),
                flights: vec![(0, flight(h, e, p))],
            })
            .collect(),
    }
}

#[test]
fn an_envelope_point_bought_by_ping_pongs_is_marked_and_left_out_of_the_clean_envelope() {
    let xyz: Vec<(f64, f64, f64)> = POINTS.iter().map(|&(_, h, e, p)| (h, e, p)).collect();
    let marked: Vec<bool> = (0..xyz.len()).map(|i| pp_dominated(&xyz, i)).collect();
    assert_eq!(marked, [false, false, true, true, false]);
    assert_eq!(clean_envelope(&xyz), vec![0, 1, 4]);
    // 0.1 point is the tolerance: C 0.11 above B is its own.
    let mut wider = xyz.clone();
    wider[2].1 = 91.11;
    assert!(!pp_dominated(&wider, 2));
    let rows = front_rows(&[a3_front("dupac")]);
    let flags: Vec<(bool, bool, bool)> = rows
        .iter()
        .map(|r| (r.on_front, r.pp_marked, r.on_clean_front))
        .collect();
    assert_eq!(
        flags,
        [
            (true, false, true),
            (true, false, true),
            (true, true, false),
            (false, false, false),
            (true, false, true),
        ]
    );
    let dir = tempfile::tempdir().expect("tmp");
    let csv = dir.path().join("front.csv");
    write_front_csv(&csv, &rows).expect("front.csv");
    let text = std::fs::read_to_string(&csv).expect("read");
    assert!(
        text.lines()
            .next()
            .expect("header")
            .ends_with(",on_front,pp_marked,on_clean_front"),
        "{text}"
    );
    assert!(text.contains("\ndupac,a3,6,0,6,0,4,,"), "{text}");
    assert!(text.contains(",true,true,false\n"), "{text}");
}

#[test]
fn the_matched_a3_brackets_the_policy_on_the_envelope_without_marked_points() {
    // The policy's own flight: 2 km at 12.5 handovers/km, between B (12) and C (13) on the
    // 2-D envelope, between B and D (16) without the marked C.
    let step = |i: usize| crate::record::StepRecord {
        position_m: [i as f32, 0.0, 50.0],
        serving: u16::from(i / 80 % 2 == 1),
        serving_rsrp_dbm: -70.0,
        measured_serving_rsrp_dbm: -70.0,
        best_site: 0,
        best_rsrp_dbm: -70.0,
        sinr_db: 10.0,
        class: dupac_radio::class::RsrpClass::Excellent,
        best_class: dupac_radio::class::RsrpClass::Excellent,
        los: true,
        handover: false,
        ping_pong: false,
    };
    let record = crate::record::FlightRecord {
        method: "dupac".into(),
        seed: 0,
        pair_id: 0,
        bin_m: 2000.0,
        shortest_m: 2000.0,
        straight_m: 2000.0,
        outcome: dupac_common::msg::Outcome::Goal,
        source_m: dupac_common::geometry::Point::new(0.0, 0.0, 50.0),
        destination_m: dupac_common::geometry::Point::new(2000.0, 0.0, 50.0),
        remaining_m: 0.0,
        start_serving: 0,
        steps: (1..=2000).map(step).collect(),
    };
    let records = [RecordsFile {
        method: "dupac".into(),
        seed: 0,
        rules: crate::metrics::MetricRules {
            ping_pong_window_steps: 5,
            site_regret_threshold_db: 3.0,
            interruption_steps: 1.0,
        },
        flights: vec![record],
    }];
    let rate =
        FrontMeasures::of([flight_metrics(&records[0].flights[0], &records[0].rules)].iter())
            .handovers_per_km;
    assert!((rate - 12.5).abs() < 1e-9, "{rate}");
    let m = matched(&records, &[a3_front("dupac")]);
    assert_eq!(m.len(), 1);
    let off = |s: &A3Setting| s.offset_db;
    assert_eq!((off(&m[0].lower), off(&m[0].upper)), (8.0, 2.0));
    assert!((m[0].alpha - 0.125).abs() < 1e-9, "{}", m[0].alpha);
    // A front of another rule is not A3's.
    let mut other = a3_front("dupac");
    other.rule = FrontRule::Predictive;
    for p in &mut other.points {
        p.setting = FrontSetting::Predictive {
            handover_cost_db_m: 60.0,
        };
    }
    assert!(matched(&records, &[other]).is_empty());
}

#[test]
fn a_front_file_reads_back_with_its_rule_and_settings() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut f = a3_front("dupac");
    f.points[0].setting = a3(3.0, None);
    write_front(dir.path(), &f).expect("write");
    let h = FrontFile {
        rule: FrontRule::Hindsight,
        points: vec![FrontPoint {
            setting: FrontSetting::Hindsight {
                handover_cost_db: 60.0,
            },
            flights: vec![(0, flight(5.0, 95.0, 0.0))],
        }],
        ..a3_front("dupac")
    };
    write_front(dir.path(), &h).expect("write");
    let back = read_fronts(dir.path()).expect("read");
    assert_eq!(back.len(), 2);
    assert_eq!(back[0].rule, FrontRule::A3);
    let settings: Vec<FrontSetting> = back[0].points.iter().map(|p| p.setting).collect();
    let want: Vec<FrontSetting> = f.points.iter().map(|p| p.setting).collect();
    assert_eq!(settings, want);
    assert_eq!(back[1].points[0].setting, h.points[0].setting);
    // A file whose points are of another rule than it says is refused, naming it.
    let bad = FrontFile {
        rule: FrontRule::Predictive,
        ..h
    };
    write_front(dir.path(), &bad).expect("write");
    let e = read_fronts(dir.path()).unwrap_err().to_string();
    assert!(e.contains("dupac__predictive__seed0.bin"), "{e}");
}

#[test]
fn the_mix_takes_the_upper_setting_for_its_share_of_flights() {
    let n = 20_000u64;
    for alpha in [0.0, 0.25, 0.8, 1.0] {
        let k = (0..n).filter(|&p| takes_upper(3, p, alpha)).count() as f64;
        assert!((k / n as f64 - alpha).abs() < 0.015, "α {alpha}: {k}");
    }
    // A fixed function of (seed, pair).
    assert_eq!(takes_upper(1, 7, 0.5), takes_upper(1, 7, 0.5));
}
