//! The real channel: the shadow-fading field has the configured σ and exponential
//! autocorrelation, is reproducible from its seed, and the layer-3 filter matches hand-computed
//! values.

use dupac_common::config::ChannelConfig;
use dupac_common::geometry::{Bounds2, Point};
use dupac_radio::channel::{Channel, FieldSplit, Measurer, l3_coefficient};
use dupac_radio::pathloss::Scenario;
use dupac_radio::shadow::{FieldGrid, ShadowField, decorrelation_m, sigma_sf_db};

/// A 1.2 km square at 5 m, as the Midtown area.
fn grid() -> FieldGrid {
    FieldGrid::covering(Bounds2::new(0.0, 0.0, 1200.0, 1200.0), 5.0)
}

/// Sample mean, variance and the correlation at a lag of `lag` grid steps along x and along y
/// of one unit field (`site`, `los`) over the whole grid.
fn stats(f: &ShadowField, site: usize, los: bool, lag: usize) -> (f64, f64, f64) {
    let g = *f.grid();
    let v = |ix: usize, iy: usize| f64::from(f.unit_at_grid(site, los, ix, iy));
    let n = (g.nx * g.ny) as f64;
    let mean = (0..g.ny)
        .flat_map(|iy| (0..g.nx).map(move |ix| (ix, iy)))
        .map(|(ix, iy)| v(ix, iy))
        .sum::<f64>()
        / n;
    let var = (0..g.ny)
        .flat_map(|iy| (0..g.nx).map(move |ix| (ix, iy)))
        .map(|(ix, iy)| (v(ix, iy) - mean).powi(2))
        .sum::<f64>()
        / n;
    let (mut c, mut k) = (0.0, 0usize);
    for iy in 0..g.ny - lag {
        for ix in 0..g.nx - lag {
            c += (v(ix, iy) - mean) * (v(ix + lag, iy) - mean);
            c += (v(ix, iy) - mean) * (v(ix, iy + lag) - mean);
            k += 2;
        }
    }
    (mean, var, c / k as f64 / var)
}

#[test]
fn the_field_has_unit_variance_and_the_exponential_autocorrelation() {
    let scen = vec![Scenario::Uma; 8];
    // Averaged over 8 sites × 2 states × 3 realisations: 48 fields of 241² points each.
    for los in [true, false] {
        let d = decorrelation_m(Scenario::Uma, los);
        for lag in [1usize, 4, 10, 20] {
            let (mut var, mut rho) = (0.0, 0.0);
            let mut n = 0.0;
            for r in 0..3 {
                let f = ShadowField::generate(grid(), &scen, 7, 1, r, 0.0);
                for s in 0..8 {
                    let (_, v, c) = stats(&f, s, los, lag);
                    var += v;
                    rho += c;
                    n += 1.0;
                }
            }
            let (var, rho) = (var / n, rho / n);
            let want = (-(lag as f64) * 5.0 / d).exp();
            // The sample variance of a correlated field over a finite area is low by about
            // the field's mean correlation over the area (≈ 2π d² / area ≈ 1–2 %), and each of the
            // 48 fields' values carry ≈ 1 000 independent cells' worth of information.
            assert!((var - 1.0).abs() < 0.06, "los {los}: variance {var}");
            assert!(
                (rho - want).abs() < 0.05,
                "los {los}, lag {} m: correlation {rho}, want exp(-d/{d}) = {want}",
                lag * 5
            );
        }
    }
}

#[test]
fn shadow_fading_has_the_tables_sigma_at_grid_points() {
    let scen = vec![Scenario::Uma, Scenario::Umi];
    let f = ShadowField::generate(grid(), &scen, 3, 1, 0, 0.0);
    let g = *f.grid();
    for (los, h) in [(true, 50.0), (false, 50.0), (true, 10.0), (false, 10.0)] {
        let mut sum2 = [0.0f64; 2];
        let mut n = 0.0;
        for iy in (0..g.ny).step_by(2) {
            for ix in (0..g.nx).step_by(2) {
                let p = Point::new(
                    g.x0_m + ix as f64 * g.step_m,
                    g.y0_m + iy as f64 * g.step_m,
                    h,
                );
                let mut out = [0.0; 2];
                f.shadow_db(p, &[f64::from(u8::from(los)); 2], &mut out);
                sum2[0] += out[0] * out[0];
                sum2[1] += out[1] * out[1];
                n += 1.0;
            }
        }
        for (k, sc) in scen.iter().enumerate() {
            let got = (sum2[k] / n).sqrt();
            let want = sigma_sf_db(*sc, los, h);
            // One field per check: about 1 000 independent cells at UMa's 37–50 m.
            assert!(
                (got / want - 1.0).abs() < 0.08,
                "{sc:?} los {los} h {h}: σ {got:.3} dB, want {want:.3} dB"
            );
        }
    }
    // The table's values themselves (TR 36.777 Table B-3, TR 38.901 Table 7.4.1-1).
    assert!((sigma_sf_db(Scenario::Uma, true, 100.0) - 4.64 * (-0.66f64).exp()).abs() < 1e-12);
    assert_eq!(sigma_sf_db(Scenario::Uma, false, 60.0), 6.0);
    assert_eq!(sigma_sf_db(Scenario::Umi, true, 250.0), 2.0);
    assert_eq!(sigma_sf_db(Scenario::Umi, false, 22.5), 7.82);
}

#[test]
fn one_seed_one_field_and_the_splits_differ() {
    let scen = vec![Scenario::Uma; 3];
    let g = FieldGrid::covering(Bounds2::new(0.0, 0.0, 300.0, 200.0), 5.0);
    let a = ShadowField::generate(g, &scen, 11, 1, 2, 0.0);
    let b = ShadowField::generate(g, &scen, 11, 1, 2, 0.0);
    let other_seed = ShadowField::generate(g, &scen, 12, 1, 2, 0.0);
    let other_index = ShadowField::generate(g, &scen, 11, 1, 3, 0.0);
    let other_domain = ShadowField::generate(g, &scen, 11, 2, 2, 0.0);
    let values = |f: &ShadowField| -> Vec<f32> {
        (0..3)
            .flat_map(|s| [true, false].map(|l| f.unit_at_grid(s, l, 17, 9)))
            .collect()
    };
    assert_eq!(values(&a), values(&b));
    for o in [&other_seed, &other_index, &other_domain] {
        assert!(values(&a).iter().zip(values(o)).all(|(x, y)| *x != y));
    }
    // Through the channel: training and evaluation realisations are never the same.
    let cfg = ChannelConfig {
        model: dupac_common::config::ChannelModel::Real,
        ..ChannelConfig::default()
    };
    let area = Bounds2::new(-150.0, -100.0, 150.0, 100.0);
    let ch = Channel::new(&cfg, area, scen.clone()).expect("a real channel");
    let p = Point::new(10.0, 20.0, 60.0);
    let shadow = |f: &ShadowField| {
        let mut o = [0.0; 3];
        f.shadow_db(p, &[1.0, 0.0, 0.5], &mut o);
        o
    };
    let all = |split| {
        (0..8u64)
            .map(|i| shadow(&ch.field(split, i)))
            .collect::<Vec<_>>()
    };
    let (train, eval, test) = (
        all(FieldSplit::Train),
        all(FieldSplit::Eval),
        all(FieldSplit::Test),
    );
    for (a, b) in [(&train, &eval), (&train, &test), (&eval, &test)] {
        for x in a {
            assert!(b.iter().all(|y| y != x), "a realisation is in two splits");
        }
    }
    // Evaluation flies pair id k in field k mod eval_fields: the same for every method.
    let k = 13u64;
    assert_eq!(
        shadow(&ch.episode_field(FieldSplit::Eval, k)),
        shadow(&ch.field(FieldSplit::Eval, k % u64::from(cfg.eval_fields)))
    );
    let deterministic = ChannelConfig::default();
    assert!(Channel::new(&deterministic, area, scen).is_none());
}

#[test]
fn the_layer3_filter_matches_a_hand_computed_sequence() {
    // k = 4 at the 200 ms period of TS 36.331: a = 1/2 exactly.
    assert!((l3_coefficient(4, 0.2) - 0.5).abs() < 1e-15);
    assert_eq!(l3_coefficient(0, 0.05), 1.0);
    // At a 50 ms period the time constant is kept: (1 − a_step)^4 = 1 − a.
    let a = l3_coefficient(4, 0.05);
    assert!(((1.0 - a).powi(4) - 0.5).abs() < 1e-12);
    // No error: F1 = M1, then F = M/2 + F/2.
    let mut m = Measurer::new(2, 0.0, 4, 0.2, 0.2);
    m.reset(FieldSplit::Eval, 5);
    let seq = [
        [-80.0, -100.0],
        [-90.0, -100.0],
        [-70.0, f64::NEG_INFINITY],
        [-70.0, -60.0],
    ];
    let want = [
        [-80.0, -100.0],
        [-85.0, -100.0],
        [-77.5, f64::NEG_INFINITY],
        [-73.75, -60.0],
    ];
    for (x, w) in seq.iter().zip(want) {
        let mut out = [0.0; 2];
        m.measure(x, &mut out);
        assert_eq!(out, w);
    }
    // With error σ: the unfiltered measurement's error has that σ, and one seed one sequence.
    let draw = |seed: u64| {
        let mut m = Measurer::new(1, 2.0, 0, 0.05, 0.05);
        m.reset(FieldSplit::Eval, seed);
        (0..20_000)
            .map(|_| {
                let mut o = [0.0];
                m.measure(&[-80.0], &mut o);
                o[0] + 80.0
            })
            .collect::<Vec<f64>>()
    };
    let e = draw(1);
    let sd = (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
    assert!((sd - 2.0).abs() < 0.05, "measurement σ {sd}");
    assert_eq!(e, draw(1));
    assert_ne!(e, draw(2));
}

#[test]
fn the_link_calculator_gives_the_links_shadow_fading() {
    let cfg = dupac_common::config::Config::default();
    let line = |z: &str| {
        format!(
            "{{\"bs_xyz\":[0,0,25],\"uav_xyz\":[200,0,50],\"scenario\":\"uma\",\"los\":true{z}}}\n"
        )
    };
    let input = format!(
        "{}{}{}",
        line(""),
        line(",\"sf_z\":1.5"),
        line(",\"sf_z\":1e9")
    );
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let failed = dupac_radio::link_calc::link_stream(&cfg, input.as_bytes(), &mut out, &mut err)
        .expect("stream");
    assert_eq!(failed, 1, "{}", String::from_utf8_lossy(&err));
    assert!(String::from_utf8_lossy(&err).starts_with("line 3: field `sf_z`"));
    let rows: Vec<serde_json::Value> = String::from_utf8(out)
        .expect("utf8")
        .lines()
        .map(|l| serde_json::from_str(l).expect("json"))
        .collect();
    let sigma = sigma_sf_db(Scenario::Uma, true, 50.0);
    assert_eq!(rows[0]["sigma_sf_db"].as_f64(), Some(sigma));
    assert_eq!(rows[0]["sf_decorrelation_m"].as_f64(), Some(37.0));
    assert!(rows[0].get("shadow_db").is_none());
    let rsrp = rows[1]["rsrp_dbm"].as_f64().expect("rsrp");
    let shadowed = rows[1]["rsrp_shadowed_dbm"].as_f64().expect("shadowed");
    assert!((rsrp - shadowed - 1.5 * sigma).abs() < 1e-9);
}

/// Of the measurement error after the filter over a long flight at a constant true RSRP: the
/// sample σ and the lag-1 (one step) autocorrelation.
fn filtered_error(m: &mut Measurer, steps: usize) -> (f64, f64) {
    let e: Vec<f64> = (0..steps)
        .map(|_| {
            let mut o = [0.0];
            m.measure(&[-80.0], &mut o);
            o[0] + 80.0
        })
        .collect();
    let sd = (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
    let c1 = e.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / (e.len() - 1) as f64;
    (sd, c1 / (sd * sd))
}

#[test]
fn one_measurement_per_period_gives_ts_36133s_accuracy_after_the_filter() {
    // 48 ms steps, 200 ms period → 4 steps; k = 4 → a = 1/2 per period (exactly, at 192 ms:
    // l3_coefficient(4, 0.192)). Filtered σ = 2·√(a/(2 − a)) ≈ 1.15 dB.
    let mut m = Measurer::new(1, 2.0, 4, 0.048, 0.2);
    assert_eq!(m.period_steps(), 4);
    m.reset(FieldSplit::Train, 3);
    let a = m.coefficient();
    let (sd, rho1) = filtered_error(&mut m, 400_000);
    let want = 2.0 * (a / (2.0 - a)).sqrt();
    assert!((sd - want).abs() < 0.03, "filtered σ {sd}, want {want}");
    assert!(
        sd > 1.0,
        "filtered σ {sd}: the error is drawn per period, not per step"
    );
    // Held between measurements: 3 of 4 step pairs repeat the value.
    assert!(rho1 > 0.85, "lag-1 correlation {rho1}");
    // A fresh error every step (a one-step period) filters to about half that σ.
    let mut per_step = Measurer::new(1, 2.0, 4, 0.048, 0.048);
    per_step.reset(FieldSplit::Train, 3);
    let (sd_step, _) = filtered_error(&mut per_step, 400_000);
    assert!(sd_step < 0.7, "per-step σ {sd_step}");
}

#[test]
fn a_period_measures_the_mean_of_its_steps_and_holds_it() {
    // No error, no filter (k = 0): the first step measures at once, then each 4-step period's
    // mean is delivered at its last step and held.
    let mut m = Measurer::new(1, 0.0, 0, 0.05, 0.2);
    m.reset(FieldSplit::Eval, 1);
    let input = [
        -70.0, -80.0, -82.0, -84.0, -86.0, -90.0, -90.0, -90.0, -90.0,
    ];
    let want = [
        -70.0, -70.0, -70.0, -70.0, -83.0, -83.0, -83.0, -83.0, -90.0,
    ];
    for (x, w) in input.iter().zip(want) {
        let mut o = [0.0];
        m.measure(&[*x], &mut o);
        assert_eq!(o[0], w);
    }
}

#[test]
fn the_measurement_noise_of_a_pair_differs_between_splits() {
    let run = |split: FieldSplit| {
        let mut m = Measurer::new(1, 2.0, 0, 0.05, 0.05);
        m.reset(split, 7);
        (0..50)
            .map(|_| {
                let mut o = [0.0];
                m.measure(&[-80.0], &mut o);
                o[0]
            })
            .collect::<Vec<f64>>()
    };
    assert_eq!(run(FieldSplit::Test), run(FieldSplit::Test));
    assert_ne!(run(FieldSplit::Eval), run(FieldSplit::Test));
    assert_ne!(run(FieldSplit::Eval), run(FieldSplit::Train));
}

#[test]
fn interpolation_keeps_sigma_between_grid_points() {
    // UMi NLoS (13 m) and LoS (10 m) on a 5 m grid: at the middle of every cell a plain bilinear
    // mix has σ ≈ 0.85 and 0.82 of the table's; the rescaled field has the table's σ.
    let scen = vec![Scenario::Umi; 4];
    let g = FieldGrid::covering(Bounds2::new(0.0, 0.0, 600.0, 600.0), 5.0);
    for los in [true, false] {
        let (mut sum2, mut n) = (0.0, 0.0);
        for r in 0..4 {
            let f = ShadowField::generate(g, &scen, 5, 1, r, 0.0);
            for iy in (0..g.ny - 1).step_by(3) {
                for ix in (0..g.nx - 1).step_by(3) {
                    let p = Point::new(
                        g.x0_m + (ix as f64 + 0.5) * g.step_m,
                        g.y0_m + (iy as f64 + 0.5) * g.step_m,
                        50.0,
                    );
                    let mut out = [0.0; 4];
                    f.shadow_db(p, &[f64::from(u8::from(los)); 4], &mut out);
                    sum2 += out.iter().map(|x| x * x).sum::<f64>();
                    n += 4.0;
                }
            }
        }
        let got = (sum2 / n).sqrt();
        let want = sigma_sf_db(Scenario::Umi, los, 50.0);
        assert!(
            (got / want - 1.0).abs() < 0.05,
            "UMi los {los}: σ mid-cell {got:.3} dB, want {want:.3} dB"
        );
    }
}

#[test]
fn inter_site_correlation_mixes_a_shared_field_into_each_site() {
    // Averaged over 4 realisations × 3 site pairs: one pair's sample correlation over a
    // 1.2 km field at 50 m decorrelation has a standard deviation of ≈ 0.1 by itself.
    let scen = vec![Scenario::Uma; 6];
    let g = FieldGrid::covering(Bounds2::new(0.0, 0.0, 1200.0, 1200.0), 5.0);
    let stats = |rho: f64| {
        let (mut corr, mut var, mut n) = (0.0, 0.0, 0.0);
        for r in 0..4 {
            let f = ShadowField::generate(g, &scen, 9, 1, r, rho);
            for (s0, s1) in [(0, 1), (2, 3), (4, 5)] {
                let (mut c, mut v0, mut v1) = (0.0, 0.0, 0.0);
                for iy in 0..g.ny {
                    for ix in 0..g.nx {
                        let a = f64::from(f.unit_at_grid(s0, false, ix, iy));
                        let b = f64::from(f.unit_at_grid(s1, false, ix, iy));
                        c += a * b;
                        v0 += a * a;
                        v1 += b * b;
                    }
                }
                corr += c / (v0 * v1).sqrt();
                var += 0.5 * (v0 + v1) / (g.nx * g.ny) as f64;
                n += 1.0;
            }
        }
        (corr / n, var / n)
    };
    let (r0, var0) = stats(0.0);
    let (r5, var5) = stats(0.5);
    assert!(r0.abs() < 0.1, "independent sites: correlation {r0}");
    assert!((r5 - 0.5).abs() < 0.1, "ρ = 0.5: correlation {r5}");
    for v in [var0, var5] {
        assert!((v - 1.0).abs() < 0.12, "variance {v}");
    }
}
