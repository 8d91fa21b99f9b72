use super::*;
use crate::interval::mean_ci95;
use crate::record::{FlightRecord, StepRecord};
use crate::stats_tables::{SeedStats, comparisons, write_paired, write_per_seed};
use dupac_common::geometry::Point;
use dupac_radio::class::RsrpClass;

/// A flight's metrics: `ok` reached the goal, with this overhead and mean RSRP; 500 m, two
/// handovers.
fn fm(ok: bool, overhead: f64, rsrp: f64) -> FlightMetrics {
    FlightMetrics {
        outcome: if ok {
            Outcome::Goal
        } else {
            Outcome::Collision
        },
        distance_m: 500.0,
        overhead,
        mean_rsrp_dbm: rsrp,
        frac_class: [0.9, 0.1, 0.0],
        handovers: 2,
        ping_pongs: 0,
        handovers_per_km: 4.0,
        mean_sinr_db: 5.0,
        frac_sinr_below_m6db: 0.01,
        mean_site_regret_db: 0.1,
        frac_site_regret_high: 0.0,
        frac_class_regret: 0.0,
        frac_interrupted: 0.0,
        frac_excellent_net: 0.9,
    }
}

fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// The interval of `h` in `ci`.
fn of(ci: &[BootCi], h: Headline) -> BootCi {
    ci[HEADLINES.iter().position(|&x| x == h).expect("headline")]
}

fn boot(resamples: usize) -> Bootstrap {
    Bootstrap {
        resamples,
        seed: BOOTSTRAP_SEED,
    }
}

#[test]
fn percentile_interpolates_between_order_statistics() {
    assert_eq!(percentile(&[1.0, 2.0, 3.0, 4.0], 0.5), 2.5);
    assert_eq!(percentile(&[1.0, 2.0, 3.0, 4.0], 0.0), 1.0);
    assert_eq!(percentile(&[1.0, 2.0, 3.0, 4.0], 1.0), 4.0);
    assert!((percentile(&[0.0, 10.0], 0.025) - 0.25).abs() < 1e-12);
    assert_eq!(percentile(&[7.0], 0.975), 7.0);
    assert!(percentile(&[], 0.5).is_nan());
}

#[test]
fn the_resamples_are_refused_outside_their_range() {
    assert!(Bootstrap::with_resamples(0).is_err());
    assert!(Bootstrap::with_resamples(MAX_RESAMPLES + 1).is_err());
    assert_eq!(
        Bootstrap::with_resamples(DEFAULT_RESAMPLES).expect("default"),
        Bootstrap::default()
    );
}

/// Three seeds whose flights all have the overhead 0, 0.3 and 0.6: the bootstrap's statistic is
/// the mean of three seeds drawn with replacement (the pairs add nothing), all three the lowest
/// seed with probability 1/27 = 3.7 % > 2.5 %, so the interval is exactly [0, 0.6]; the pooled
/// t interval of the 150 flights as independent is about ± 0.04.
#[test]
fn seeds_with_different_means_widen_the_interval_past_the_pooled_t() {
    let seeds = (0..3u32)
        .map(|s| {
            let flights = (0..50u64)
                .map(|p| (p, fm(true, 0.3 * f64::from(s), -70.0)))
                .collect();
            (s, flights)
        })
        .collect();
    let g = Grid::new("m", seeds);
    let ci = method_intervals(&g, &boot(2000));
    let ov = of(&ci, Headline::Overhead);
    assert!((ov.value - 0.3).abs() < 1e-12, "{ov:?}");
    assert!(ov.lo.abs() < 1e-12 && (ov.hi - 0.6).abs() < 1e-12, "{ov:?}");
    let pooled: Vec<f64> = (0..3)
        .flat_map(|s| (0..50).map(move |_| 0.3 * f64::from(s)))
        .collect();
    let t = mean_ci95(&pooled);
    assert!((t.half_width - 0.0397).abs() < 1e-3, "{t:?}");
    assert!(ov.hi - ov.lo > 5.0 * 2.0 * t.half_width);
}

/// One seed of 400 independent flights: the bootstrap interval of the mean RSRP is the pooled t
/// interval within 10 % (both estimate 1.96 standard errors).
#[test]
fn one_seed_of_independent_flights_gives_the_t_interval() {
    let mut r = rng(11);
    let flights: Vec<(u64, FlightMetrics)> = (0..400u64)
        .map(|p| (p, fm(true, 0.02, -70.0 + r.random_range(-8.0..8.0))))
        .collect();
    let t = mean_ci95(
        &flights
            .iter()
            .map(|f| f.1.mean_rsrp_dbm)
            .collect::<Vec<_>>(),
    );
    let ci = method_intervals(&Grid::new("m", vec![(0, flights)]), &boot(4000));
    let rs = of(&ci, Headline::MeanRsrp);
    assert!((rs.value - t.mean).abs() < 1e-9);
    let ratio = (rs.hi - rs.lo) / (2.0 * t.half_width);
    assert!((0.9..1.1).contains(&ratio), "{rs:?} {t:?} ratio {ratio}");
    assert!(rs.lo < rs.value && rs.value < rs.hi);
}

/// Three seeds of random flights, 30 pairs, some failed.
fn random_grid(seed: u64) -> Vec<SeedFlights> {
    let mut r = rng(seed);
    (0..3u32)
        .map(|s| {
            let flights = (0..30u64)
                .map(|p| {
                    let ok = r.random_range(0.0..1.0) < 0.8;
                    let m = fm(ok, r.random_range(0.0..0.2), r.random_range(-90.0..-60.0));
                    (p, m)
                })
                .collect();
            (s + 1, flights)
        })
        .collect()
}

#[test]
fn a_method_against_itself_differs_by_exactly_zero() {
    let g = Grid::new("a", random_grid(3));
    let c = paired(&g, &g, &boot(500)).expect("shared flights");
    assert_eq!(c.seed_indices, 3);
    for d in &c.diffs {
        assert_eq!(
            (d.diff.value, d.diff.lo, d.diff.hi),
            (0.0, 0.0, 0.0),
            "{d:?}"
        );
        let expect = if d.headline.successes_only() {
            (0..3)
                .flat_map(|s| (0..30).map(move |p| (s, p)))
                .filter(|&(s, p)| g.flights(s, p)[0].outcome == Outcome::Goal)
                .count()
        } else {
            90
        };
        assert_eq!(d.n, expect, "{d:?}");
    }
}

/// B is A with every flight 1 dB weaker and 0.01 less overhead: the pairs vary by 30 dB, so each
/// method's own interval is wide, but the paired difference is 1 dB in every resample.
#[test]
fn pairing_removes_the_variance_the_methods_share() {
    let a = random_grid(5);
    let b: Vec<_> = a
        .iter()
        .map(|(s, f)| {
            let f = f
                .iter()
                .map(|&(p, m)| {
                    (
                        p,
                        fm(
                            m.outcome == Outcome::Goal,
                            m.overhead - 0.01,
                            m.mean_rsrp_dbm - 1.0,
                        ),
                    )
                })
                .collect();
            (*s, f)
        })
        .collect();
    let (ga, gb) = (Grid::new("a", a), Grid::new("b", b));
    let own = of(&method_intervals(&ga, &boot(500)), Headline::MeanRsrp);
    assert!(own.hi - own.lo > 2.0, "{own:?}");
    let c = paired(&ga, &gb, &boot(500)).expect("shared");
    let d = c
        .diffs
        .iter()
        .find(|d| d.headline == Headline::MeanRsrp)
        .expect("rsrp");
    assert!((d.diff.value - 1.0).abs() < 1e-9, "{d:?}");
    assert!(d.diff.hi - d.diff.lo < 1e-9, "{d:?}");
    assert!(excludes(d.diff));
    let s = c
        .diffs
        .iter()
        .find(|d| d.headline == Headline::Success)
        .expect("success");
    assert_eq!((s.diff.value, s.diff.lo, s.diff.hi), (0.0, 0.0, 0.0));
}

fn excludes(c: BootCi) -> bool {
    c.lo > 0.0 || c.hi < 0.0
}

/// A planner (one seed) pairs with every seed of the policy; a success-only statistic counts
/// the pairs both completed.
#[test]
fn a_planner_pairs_with_every_seed_and_success_only_counts_both() {
    let a = Grid::new("a", random_grid(8));
    // The planner fails pairs 0..10 and flies the rest with 2 dB more.
    let planner = Grid::new(
        "shortest_a3",
        vec![(
            0,
            (0..30u64).map(|p| (p, fm(p >= 10, 0.01, -70.0))).collect(),
        )],
    );
    let c = paired(&a, &planner, &boot(200)).expect("shared");
    assert_eq!(c.seed_indices, 3);
    let n = |h: Headline| c.diffs.iter().find(|d| d.headline == h).expect("h").n;
    assert_eq!(n(Headline::Success), 90);
    let both = (0..3)
        .flat_map(|s| (10..30).map(move |p| (s, p)))
        .filter(|&(s, p)| a.flights(s, p)[0].outcome == Outcome::Goal)
        .count();
    assert_eq!(n(Headline::MeanRsrp), both);
    // Three seeds against two: the first two seed indices.
    let two = Grid::new("b", random_grid(9).into_iter().take(2).collect());
    assert_eq!(paired(&a, &two, &boot(10)).expect("shared").seed_indices, 2);
}

#[test]
fn pairing_follows_pair_ids_not_flight_order() {
    let a = random_grid(21);
    let b = random_grid(22);
    let mut shuffled = b.clone();
    for (i, (_, f)) in shuffled.iter_mut().enumerate() {
        f.reverse();
        f.rotate_left(7 * i + 3);
    }
    shuffled.reverse();
    let ga = Grid::new("a", a);
    let one = paired(&ga, &Grid::new("b", b), &boot(300)).expect("shared");
    let two = paired(&ga, &Grid::new("b", shuffled), &boot(300)).expect("shared");
    assert_eq!(format!("{one:?}"), format!("{two:?}"));
    // A different pairing (pair ids shifted by one) gives another difference.
    let shifted: Vec<_> = random_grid(22)
        .into_iter()
        .map(|(s, f)| (s, f.into_iter().map(|(p, m)| ((p + 1) % 30, m)).collect()))
        .collect();
    let three = paired(&ga, &Grid::new("b", shifted), &boot(300)).expect("shared");
    assert_ne!(format!("{one:?}"), format!("{three:?}"));
}

/// B flew pairs 10..40, A pairs 0..30: only 10..30 are matched, as if A had flown those alone.
#[test]
fn only_the_pair_ids_both_flew_are_matched() {
    let a = random_grid(31);
    let b: Vec<_> = random_grid(32)
        .into_iter()
        .map(|(s, f)| (s, f.into_iter().map(|(p, m)| (p + 10, m)).collect()))
        .collect();
    let a_shared: Vec<_> = a
        .iter()
        .map(|(s, f)| (*s, f.iter().copied().filter(|(p, _)| *p >= 10).collect()))
        .collect();
    let gb = Grid::new("b", b);
    let c = paired(&Grid::new("a", a), &gb, &boot(300)).expect("shared");
    let n = |c: &Comparison| {
        c.diffs
            .iter()
            .find(|d| d.headline == Headline::Success)
            .expect("s")
            .n
    };
    assert_eq!(n(&c), 3 * 20);
    let alone = paired(&Grid::new("a", a_shared), &gb, &boot(300)).expect("shared");
    assert_eq!(format!("{:?}", c.diffs), format!("{:?}", alone.diffs));
}

#[test]
fn the_report_compares_dupac_with_base_then_each_planner() {
    let labels = ["base", "dupac", "dupac+a3", "coverage_l1", "shortest_a3"];
    let c = comparisons(&labels, "dupac", "base");
    let want = [
        ("dupac", "base"),
        ("dupac", "coverage_l1"),
        ("dupac", "shortest_a3"),
    ];
    assert_eq!(
        c,
        want.map(|(a, b)| (a.to_string(), b.to_string())).to_vec()
    );
    assert!(comparisons(&labels, "other", "base").is_empty());
    assert_eq!(
        comparisons(&["dupac", "shortest_a3"], "dupac", "base").len(),
        1
    );
}

/// One records file: 12 pairs, flights of 4–7 steps along x at 50 m with RSRP drawn from `rng`
/// and a handover in the middle; a flight fails with probability 0.2.
fn records_file(method: &str, seed: u32, r: &mut ChaCha8Rng) -> RecordsFile {
    let flights: Vec<FlightRecord> = (0..12u64)
        .map(|pair| {
            let n = 4 + (pair % 4) as usize;
            let steps = (0..n)
                .map(|i| {
                    let rsrp: f32 = r.random_range(-100.0..-65.0);
                    let class = if rsrp > -80.0 {
                        RsrpClass::Excellent
                    } else {
                        RsrpClass::Mediocre
                    };
                    let serving = u16::from(i >= n / 2);
                    StepRecord {
                        position_m: [10.0 * (i + 1) as f32, 0.0, 50.0],
                        serving,
                        serving_rsrp_dbm: rsrp,
                        measured_serving_rsrp_dbm: rsrp,
                        best_site: serving,
                        best_rsrp_dbm: rsrp,
                        sinr_db: r.random_range(-10.0..10.0),
                        class,
                        best_class: class,
                        los: true,
                        handover: i == n / 2,
                        ping_pong: false,
                    }
                })
                .collect();
            let ok = r.random_range(0.0..1.0) < 0.8;
            FlightRecord {
                method: method.into(),
                seed,
                pair_id: 100 + pair,
                bin_m: 200.0,
                shortest_m: 10.0 * n as f64 - 1.0,
                straight_m: 10.0 * n as f64 - 1.0,
                outcome: if ok {
                    Outcome::Goal
                } else {
                    Outcome::TimeLimit
                },
                source_m: Point::new(0.0, 0.0, 50.0),
                destination_m: Point::new(10.0 * n as f64, 0.0, 50.0),
                remaining_m: 1.0,
                start_serving: 0,
                steps,
            }
        })
        .collect();
    RecordsFile {
        method: method.into(),
        seed,
        rules: crate::metrics::MetricRules {
            ping_pong_window_steps: 5,
            site_regret_threshold_db: 3.0,
            interruption_steps: 1.0,
        },
        flights,
    }
}

fn evaluation() -> Vec<RecordsFile> {
    let mut r = rng(42);
    let mut files = Vec::new();
    for seed in 0..3 {
        files.push(records_file("dupac", seed, &mut r));
        files.push(records_file("base", seed, &mut r));
    }
    files.push(records_file("shortest_a3", 0, &mut r));
    files
}

/// paired.csv and per_seed.csv written from `files` into a fresh directory.
fn tables(files: &[RecordsFile]) -> (String, String) {
    let dir = tempfile::tempdir().expect("tmp");
    let st = SeedStats::compute(files, "dupac", "base", boot(400));
    write_paired(&dir.path().join("paired.csv"), &st).expect("paired.csv");
    write_per_seed(&dir.path().join("per_seed.csv"), &st).expect("per_seed.csv");
    let read = |f: &str| std::fs::read_to_string(dir.path().join(f)).expect(f);
    (read("paired.csv"), read("per_seed.csv"))
}

/// The same records give byte-identical tables; paired.csv is the same with the files in
/// another order and each file's flights shuffled (per_seed.csv's rows are in method and seed
/// order too, its means summed in the file's flight order).
#[test]
fn the_tables_are_a_function_of_the_records_whatever_their_order() {
    let files = evaluation();
    let (paired_csv, per_seed_csv) = tables(&files);
    assert_eq!(
        tables(&evaluation()),
        (paired_csv.clone(), per_seed_csv.clone())
    );
    let mut lines = paired_csv.lines();
    assert_eq!(
        lines.next(),
        Some("method_a,method_b,metric,n,mean_diff,lo,hi,excludes_zero")
    );
    // dupac − base and dupac − shortest_a3, 8 metrics each; 3 seed indices × 12 pairs.
    assert_eq!(lines.clone().count(), 16, "{paired_csv}");
    assert!(
        lines
            .next()
            .expect("row")
            .starts_with("dupac,base,success,36,")
    );
    // per_seed.csv: base 0..2, dupac 0..2, then the planner.
    let rows: Vec<String> = per_seed_csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').take(3).collect::<Vec<_>>().join(","))
        .collect();
    assert_eq!(
        rows,
        [
            "base,0,12",
            "base,1,12",
            "base,2,12",
            "dupac,0,12",
            "dupac,1,12",
            "dupac,2,12",
            "shortest_a3,0,12"
        ]
    );
    // The files in another order, each file's flights (with their start sites) shuffled.
    let mut shuffled = evaluation();
    shuffled.reverse();
    for (i, f) in shuffled.iter_mut().enumerate() {
        f.flights.rotate_left(i + 5);
        f.flights.swap(0, 3);
    }
    let (paired_again, per_seed_again) = tables(&shuffled);
    assert_eq!(paired_again, paired_csv);
    let firsts = |t: &str| -> Vec<String> {
        t.lines()
            .map(|l| l.split(',').take(4).collect::<Vec<_>>().join(","))
            .collect()
    };
    assert_eq!(firsts(&per_seed_again), firsts(&per_seed_csv));
}
