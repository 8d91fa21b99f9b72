//! The evaluation's statistics and tables, from the records alone: per method (all seeds
//! together) success, collision and timeout rates with Wilson intervals, means with Student-t
//! intervals, per-km handovers and ping-pongs, SINR, site regret; `summary.csv`,
//! `fig3_fig4_bins.csv`, `failures.csv` and `report.md` with the paper's numbers beside ours.
//! The seed-aware statistics (bootstrap intervals over seeds and pairs, `per_seed.csv`,
//! `paired.csv`) are [`crate::stats_tables`]'.

use crate::error::EvalError;
use crate::front::{self, FrontFile};
use crate::interval::{MeanCi, Rate};
use crate::records::RecordsFile;
use crate::sinr::NOISE_PER_RE_DBM;
use crate::stats::Bootstrap;
use crate::stats_tables::{SeedStats, markdown, write_paired, write_per_seed};
use dupac_common::fsio::write_atomic_with;
use dupac_common::geometry::{Point, norm};
use dupac_common::msg::Outcome;
use std::fmt::Write as _;
use std::path::Path;

pub use crate::method_data::{MethodData, bins_of, gather, is_planner};

pub fn fmt_ci(c: MeanCi, scale: f64, digits: usize) -> String {
    if c.n == 0 {
        return "–".into();
    }
    if c.half_width.is_nan() {
        return format!("{:.*}", digits, c.mean * scale);
    }
    format!(
        "{:.*} ± {:.*}",
        digits,
        c.mean * scale,
        digits,
        c.half_width * scale
    )
}

pub fn fmt_rate(r: Rate) -> String {
    format!(
        "{:.1} % [{:.1}, {:.1}]",
        100.0 * r.rate,
        100.0 * r.lo,
        100.0 * r.hi
    )
}

/// The report's tables into `out` (`summary.csv`, `per_seed.csv`, `paired.csv`,
/// `fig3_fig4_bins.csv`, `failures.csv`, `report.md`, `dupac` and `base` being the labels
/// compared with the paper's methods and with each other, `boot` the seed-aware intervals'
/// bootstrap, `split` the `split: …` line of the records, [`crate::records::read_split`], `None`
/// for records that have none); returns the methods' data (association replays `LABEL+…` left
/// out: the figures show methods) and the distance bins, for the figures.
/// With A3 fronts (`fronts`, [`crate::front`]): `front.csv`, and each learned-site policy
/// compared with A3 at its own handover rate (`LABEL+a3_matched` in `paired.csv` and the
/// report). With `eval_fields` F (the real channel: pair `id` flies in field `id mod F`),
/// `paired_by_field.csv`: every paired difference within each field.
pub fn write_tables(
    out: &Path,
    files: &[RecordsFile],
    fronts: &[FrontFile],
    (dupac, base): (&str, &str),
    (boot, eval_fields): (Bootstrap, Option<u32>),
    split: Option<&str>,
) -> Result<(Vec<MethodData>, Vec<f64>), EvalError> {
    let data = gather(files);
    let bins = bins_of(&data);
    let mut seed_stats = SeedStats::compute(files, dupac, base, boot);
    let matched = front::matched(files, fronts);
    if !fronts.is_empty() {
        front::write_front_csv(&out.join("front.csv"), &front::front_rows(fronts))?;
        let grids = crate::stats::grids(files);
        for m in &matched {
            let Some(g) = grids.iter().find(|g| g.label == m.label) else {
                continue;
            };
            seed_stats.intervals.insert(
                m.grid.label.clone(),
                crate::stats::method_intervals(&m.grid, &boot),
            );
            seed_stats
                .comparisons
                .extend(crate::stats::paired(g, &m.grid, &boot));
        }
    }
    write_per_seed(&out.join("per_seed.csv"), &seed_stats)?;
    write_paired(&out.join("paired.csv"), &seed_stats)?;
    if let Some(f) = eval_fields.filter(|f| *f > 1) {
        write_paired_by_field(&out.join("paired_by_field.csv"), files, &seed_stats, f)?;
    }
    let split_line = split.unwrap_or("split: not recorded (records written before the split was)");
    // The split's name (`validation`, `test`, `file` for `--pairs`) for the CSV.
    let split_name = split_line
        .strip_prefix("split: ")
        .and_then(|r| r.split_whitespace().next())
        .filter(|_| split.is_some())
        .unwrap_or("unrecorded");
    // summary.csv
    write_atomic_with(&out.join("summary.csv"), |w| {
        writeln!(
            w,
            "method,seeds,flights,success,success_lo,success_hi,collision,out_of_bounds,timeout,overhead_mean,overhead_ci,mean_rsrp_dbm,mean_rsrp_ci,pct_excellent,pct_excellent_ci,handovers_per_km,ping_pongs_per_km,mean_sinr_db,pct_sinr_below_m6db,site_regret_db,pct_site_regret_high,pct_class_regret,pct_excellent_net,pct_interrupted{},split",
            SeedStats::summary_header()
        )?;
        for d in &data {
            let s = d.rate(Outcome::Goal);
            let ov = d.ci(None, |m| m.overhead);
            let rs = d.ci(None, |m| m.mean_rsrp_dbm);
            let ex = d.ci(None, |m| m.frac_class[0]);
            let (ho_km, pp_km) = d.per_km();
            writeln!(
                w,
                "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}{},{split_name}",
                d.label,
                d.seeds,
                d.flights.len(),
                s.rate,
                s.lo,
                s.hi,
                d.rate(Outcome::Collision).rate,
                d.rate(Outcome::OutOfBounds).rate,
                d.rate(Outcome::TimeLimit).rate,
                ov.mean,
                ov.half_width,
                rs.mean,
                rs.half_width,
                100.0 * ex.mean,
                100.0 * ex.half_width,
                ho_km,
                pp_km,
                d.all_ci(|m| m.mean_sinr_db).mean,
                100.0 * d.all_ci(|m| m.frac_sinr_below_m6db).mean,
                d.all_ci(|m| m.mean_site_regret_db).mean,
                100.0 * d.all_ci(|m| m.frac_site_regret_high).mean,
                100.0 * d.all_ci(|m| m.frac_class_regret).mean,
                100.0 * d.ci(None, |m| m.frac_excellent_net).mean,
                100.0 * d.all_ci(|m| m.frac_interrupted).mean,
                seed_stats.summary_columns(&d.label),
            )?;
        }
        Ok(())
    })?;
    // fig3.csv / fig4.csv: per method and bin, successful flights.
    write_atomic_with(&out.join("fig3_fig4_bins.csv"), |w| {
        writeln!(
            w,
            "method,bin_m,successes,distance_m,distance_ci,overhead,overhead_ci,mean_rsrp_dbm,rsrp_ci,frac_excellent,frac_mediocre,frac_poor"
        )?;
        for d in &data {
            for &b in &bins {
                let dist = d.ci(Some(b), |m| m.distance_m);
                let ov = d.ci(Some(b), |m| m.overhead);
                let rs = d.ci(Some(b), |m| m.mean_rsrp_dbm);
                let f = [0, 1, 2].map(|k| d.ci(Some(b), |m| m.frac_class[k]).mean);
                writeln!(
                    w,
                    "{},{b},{},{},{},{},{},{},{},{},{},{}",
                    d.label,
                    dist.n,
                    dist.mean,
                    dist.half_width,
                    ov.mean,
                    ov.half_width,
                    rs.mean,
                    rs.half_width,
                    f[0],
                    f[1],
                    f[2]
                )?;
            }
        }
        Ok(())
    })?;
    write_failures(&out.join("failures.csv"), files)?;
    // The figures show methods; the association replays (`LABEL+a3`, `LABEL+oracle`) are in the
    // tables only.
    let methods: Vec<MethodData> = data
        .iter()
        .filter(|d| !d.label.contains('+'))
        .cloned()
        .collect();
    dupac_common::fsio::write_plain(
        &out.join("report.md"),
        report_md(
            &data,
            dupac,
            base,
            regret_threshold_db(files),
            &seed_stats,
            split_line,
        )
        .as_bytes(),
    )?;
    if !matched.is_empty() {
        let mut md = format!(
            "# A3 at each learned policy's handover rate\n\nEach learned-site policy's own moves re-flown with every A3 setting of the grid (`front.csv`, rule `a3`); of that front's envelope without the settings whose excellent time is bought by ping-pongs (`on_clean_front`: another setting has no more handovers per km, fewer ping-pongs per km and at most {} point less excellent time; those envelope points are `pp_marked`), the two settings bracketing the policy's handovers per km, mixed flight by flight (a fixed hash of seed and pair) so that the mix has the policy's rate: `LABEL+a3_matched`, compared with the policy in `paired.csv` and report.md's paired differences.\n\n| policy | lower setting (offset dB / hysteresis dB / TTT / A3's filter k) | upper setting | share of the upper |\n|---|---|---|---:|\n",
            front::PP_MARK_EXCELLENT_PCT
        );
        for m in &matched {
            let _ = writeln!(
                md,
                "| {} | {} | {} | {:.3} |",
                m.label,
                m.lower.label(),
                m.upper.label(),
                m.alpha
            );
        }
        dupac_common::fsio::write_plain(&out.join("matched.md"), md.as_bytes())?;
    }
    Ok((methods, bins))
}

/// `paired_by_field.csv`: each of `st`'s comparisons within each of the `fields` evaluation
/// fields (pair `id` flies in field `id mod fields`), with its seed-aware interval over the
/// field's pairs: how much of a difference one shadow-fading realisation carries.
fn write_paired_by_field(
    path: &Path,
    files: &[RecordsFile],
    st: &SeedStats,
    fields: u32,
) -> Result<(), EvalError> {
    let grids = crate::stats::grids(files);
    let grid = |l: &str| grids.iter().find(|g| g.label == l);
    let f = u64::from(fields);
    let rows: Vec<(String, String, u64, crate::stats::Comparison)> = st
        .comparisons
        .iter()
        .filter_map(|c| Some((grid(&c.a)?, grid(&c.b)?)))
        .flat_map(|(a, b)| {
            (0..f).filter_map(move |k| {
                let keep = |id: u64| id % f == k;
                let c = crate::stats::paired(&a.restrict(keep), &b.restrict(keep), &st.boot)?;
                Some((a.label.clone(), b.label.clone(), k, c))
            })
        })
        .collect();
    Ok(write_atomic_with(path, |w| {
        writeln!(w, "method_a,method_b,field,metric,n,mean_diff,lo,hi")?;
        for (a, b, k, c) in &rows {
            for d in &c.diffs {
                writeln!(
                    w,
                    "{a},{b},{k},{},{},{},{},{}",
                    d.headline.name(),
                    d.n,
                    d.diff.value,
                    d.diff.lo,
                    d.diff.hi
                )?;
            }
        }
        Ok(())
    })?)
}

/// `failures.csv`: one row per flight that did not reach its goal, to see where and how policies
/// fail: how far along the straight line they got, the altitude, the last move, and the angle
/// between the last move and the direction to the destination (a collision flown head-on into
/// the goal direction reads ≈ 0°; one while sliding along a wall ≈ 45–90°).
fn write_failures(path: &Path, files: &[RecordsFile]) -> Result<(), EvalError> {
    write_atomic_with(path, |w| {
        writeln!(
            w,
            "method,seed,pair_id,bin_m,outcome,steps,straight_m,remaining_m,progress,x_m,y_m,z_m,last_move_x_m,last_move_y_m,last_move_z_m,angle_to_goal_deg"
        )?;
        // The association replays (`LABEL+a3`, `LABEL+oracle`) are the policy's own flights.
        let flights = files
            .iter()
            .filter(|r| !r.method.contains('+'))
            .flat_map(|r| &r.flights);
        for f in flights {
            if f.outcome == Outcome::Goal {
                continue;
            }
            let n = f.steps.len();
            let at = |i: usize| -> Point {
                if i == 0 {
                    f.source_m
                } else {
                    Point::from(f.steps[i - 1].position_m.map(f64::from))
                }
            };
            let end = at(n);
            let prev = at(n.saturating_sub(1));
            let mv = end - prev;
            let to_goal = f.destination_m - prev;
            let dot = mv.dot(&to_goal);
            let angle = (dot / (norm(mv) * norm(to_goal)).max(1e-12))
                .clamp(-1.0, 1.0)
                .acos()
                .to_degrees();
            writeln!(
                w,
                "{},{},{},{},{:?},{},{:.1},{:.1},{:.3},{:.1},{:.1},{:.1},{:.3},{:.3},{:.3},{:.1}",
                f.method,
                f.seed,
                f.pair_id,
                f.bin_m,
                f.outcome,
                n,
                f.straight_m,
                f.remaining_m,
                1.0 - f.remaining_m / f.straight_m.max(1e-9),
                end[0],
                end[1],
                end[2],
                mv[0],
                mv[1],
                mv[2],
                angle
            )?;
        }
        Ok(())
    })?;
    Ok(())
}

/// The site-regret threshold of the records (the first file's; every file of one evaluation
/// has the same).
fn regret_threshold_db(files: &[RecordsFile]) -> f64 {
    files
        .first()
        .map_or(3.0, |f| f.rules.site_regret_threshold_db)
}

fn report_md(
    data: &[MethodData],
    dupac: &str,
    base: &str,
    regret_db: f64,
    seed_stats: &SeedStats,
    split_line: &str,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "{split_line}\n\n# DUPAC evaluation report\n");
    let _ = writeln!(
        s,
        "Distance, overhead, RSRP and class fractions are over successful flights; rates over all flights. The intervals of this table are 95 % and count every flight as independent, all seeds together (Student t for means, Wilson for rates); \"Seed-aware intervals\" below gives 95 % bootstrap intervals over training seeds and pairs, \"Paired differences\" compares methods flight by flight. SINR: serving RSRP against all other sites as full-load co-channel interferers plus thermal noise per resource element ({NOISE_PER_RE_DBM:.1} dBm).\n"
    );
    let _ = writeln!(
        s,
        "| method | seeds | flights | success | collision | timeout | overhead (%) | mean RSRP (dBm) | excellent (%) | excellent net of interruptions (%) | interrupted (%) | handovers/km | ping-pongs/km | mean SINR (dB) | SINR < −6 dB (%) | site regret (dB) | regret > {regret_db} dB (%) | class regret (%) |"
    );
    let _ = writeln!(
        s,
        "|---|---:|---:|---|---:|---:|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for d in data {
        let (ho_km, pp_km) = d.per_km();
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.1} % | {:.1} % | {} | {} | {} | {} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} | {:.2} | {:.1} | {:.1} |",
            d.label,
            d.seeds,
            d.flights.len(),
            fmt_rate(d.rate(Outcome::Goal)),
            100.0 * d.rate(Outcome::Collision).rate,
            100.0 * d.rate(Outcome::TimeLimit).rate,
            fmt_ci(d.ci(None, |m| m.overhead), 100.0, 1),
            fmt_ci(d.ci(None, |m| m.mean_rsrp_dbm), 1.0, 1),
            fmt_ci(d.ci(None, |m| m.frac_class[0]), 100.0, 1),
            fmt_ci(d.ci(None, |m| m.frac_excellent_net), 100.0, 1),
            100.0 * d.all_ci(|m| m.frac_interrupted).mean,
            ho_km,
            pp_km,
            d.all_ci(|m| m.mean_sinr_db).mean,
            100.0 * d.all_ci(|m| m.frac_sinr_below_m6db).mean,
            d.all_ci(|m| m.mean_site_regret_db).mean,
            100.0 * d.all_ci(|m| m.frac_site_regret_high).mean,
            100.0 * d.all_ci(|m| m.frac_class_regret).mean,
        );
    }
    markdown(&mut s, data, seed_stats);
    route_or_association(&mut s, data);
    let find = |l: &str| data.iter().find(|d| d.label == l);
    let _ = writeln!(s, "\n## Against the paper\n");
    match (find(dupac), find(base)) {
        (Some(a), Some(b)) => {
            let (oa, ob) = (a.ci(None, |m| m.overhead), b.ci(None, |m| m.overhead));
            let (ra, rb) = (
                a.ci(None, |m| m.mean_rsrp_dbm),
                b.ci(None, |m| m.mean_rsrp_dbm),
            );
            let (ea, eb) = (
                a.ci(None, |m| m.frac_class[0]),
                b.ci(None, |m| m.frac_class[0]),
            );
            let gain = (rb.mean - ra.mean) / rb.mean.abs() * -100.0;
            let _ = writeln!(s, "| quantity | paper | ours |\n|---|---:|---:|");
            let _ = writeln!(
                s,
                "| distance overhead, DUPAC | ≈ 11 % | {} % |",
                fmt_ci(oa, 100.0, 1)
            );
            let _ = writeln!(
                s,
                "| distance overhead, base method | ≈ 9 % | {} % |",
                fmt_ci(ob, 100.0, 1)
            );
            let _ = writeln!(
                s,
                "| mean RSRP, DUPAC vs base (relative, + = DUPAC better) | ≈ +7.5 % | {gain:+.1} % ({:.1} vs {:.1} dBm) |",
                ra.mean, rb.mean
            );
            let _ = writeln!(
                s,
                "| time in excellent RSRP, DUPAC − base | ≈ +9 points | {:+.1} points ({:.1} vs {:.1} %) |",
                100.0 * (ea.mean - eb.mean),
                100.0 * ea.mean,
                100.0 * eb.mean
            );
            let _ = writeln!(
                s,
                "| success rate (not reported by the paper) | – | {} vs {} |",
                fmt_rate(a.rate(Outcome::Goal)),
                fmt_rate(b.rate(Outcome::Goal))
            );
            let agree = |ok: bool| {
                if ok {
                    "agrees with"
                } else {
                    "is the opposite of"
                }
            };
            let _ = writeln!(
                s,
                "\nIn direction: DUPAC's mean RSRP against the base method's {} the paper (paper: DUPAC better); its time in excellent RSRP {} the paper (paper: DUPAC more); DUPAC's distance overhead against the base method's {} the paper (paper: DUPAC flies a little longer). DUPAC hands over {:.1} times per km ({:.1} of them ping-pongs), the base method {:.1}. Flights that missed the goal, DUPAC / base: {:.1} / {:.1} % collisions, {:.1} / {:.1} % timeouts, {:.1} / {:.1} % out of bounds (where each ended: `failures.csv`). Discussion: docs/results.md, docs/training.md.",
                agree(ra.mean > rb.mean),
                agree(ea.mean > eb.mean),
                agree(oa.mean > ob.mean),
                a.per_km().0,
                a.per_km().1,
                b.per_km().0,
                100.0 * a.rate(Outcome::Collision).rate,
                100.0 * b.rate(Outcome::Collision).rate,
                100.0 * a.rate(Outcome::TimeLimit).rate,
                100.0 * b.rate(Outcome::TimeLimit).rate,
                100.0 * a.rate(Outcome::OutOfBounds).rate,
                100.0 * b.rate(Outcome::OutOfBounds).rate,
            );
        }
        _ => {
            let _ = writeln!(
                s,
                "(no `{dupac}` and `{base}` policies among the methods: give them with --policy {dupac}=FILE --policy {base}=FILE)"
            );
        }
    }
    let _ = writeln!(
        s,
        "\nFigures: `fig3.png` (Fig. 3: flight distance, overhead and mean RSRP against the shortest distance), `fig4.png` (Fig. 4: time per RSRP class per bin), `pareto.png` (overhead against time in excellent RSRP, every method). Data: `summary.csv`, `per_seed.csv`, `paired.csv`, `fig3_fig4_bins.csv`; every step: `records/*.bin` (`dupac eval --report-only --out DIR` recomputes this report from them)."
    );
    s
}

/// "Route or association": each learned-site policy beside its own moves re-flown with A3, the
/// best-RSRP oracle and the predictive association choosing the site (the replays `LABEL+a3`,
/// `LABEL+oracle`, `LABEL+predictive`).
fn route_or_association(s: &mut String, data: &[MethodData]) {
    let policies: Vec<&MethodData> = data
        .iter()
        .filter(|d| {
            data.iter()
                .any(|r| r.label == format!("{}+oracle", d.label))
        })
        .collect();
    if policies.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Route or association\n\nEach learned-site policy's own moves, re-flown with the A3 rule, the best-RSRP oracle and the predictive association (`env.predictive`) choosing the site. The route is the same in every row, so the oracle row is the best this route allows, and the gap from the policy's row to it is the association's alone; the gap between policies' oracle rows is the routes'. Excellent time over successful flights, the rest over all flights.\n"
    );
    let _ = writeln!(
        s,
        "| policy | site by | excellent (%) | excellent net (%) | mean RSRP (dBm) | SINR < −6 dB (%) | handovers/km | ping-pongs/km | site regret (dB) |\n|---|---|---|---|---|---:|---:|---:|---:|"
    );
    for p in policies {
        for (by, label) in [
            ("policy", p.label.clone()),
            ("A3", format!("{}+a3", p.label)),
            ("oracle", format!("{}+oracle", p.label)),
            ("predictive", format!("{}+predictive", p.label)),
        ] {
            let Some(d) = data.iter().find(|d| d.label == label) else {
                continue;
            };
            let (ho_km, pp_km) = d.per_km();
            let _ = writeln!(
                s,
                "| {} | {by} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.2} |",
                p.label,
                fmt_ci(d.ci(None, |m| m.frac_class[0]), 100.0, 1),
                fmt_ci(d.ci(None, |m| m.frac_excellent_net), 100.0, 1),
                fmt_ci(d.all_ci(|m| m.mean_rsrp_dbm), 1.0, 1),
                100.0 * d.all_ci(|m| m.frac_sinr_below_m6db).mean,
                ho_km,
                pp_km,
                d.all_ci(|m| m.mean_site_regret_db).mean,
            );
        }
    }
}
