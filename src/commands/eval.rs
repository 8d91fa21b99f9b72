//! `dupac eval`: flies every evaluation pair with trained policies (several training seeds per
//! method) and with the planners (shortest path with A3 and with the best-RSRP oracle,
//! coverage-aware paths over a λ sweep), records every step, and writes a report directory:
//! the paper's Fig. 3 and Fig. 4 data and figures, success/collision/timeout rates, handovers and
//! ping-pongs, SINR, a Pareto plot of distance overhead against time in excellent RSRP, CSVs of
//! every figure, and `report.md` with the paper's numbers beside ours. `--report-only`
//! recomputes the report from the saved step records without flying. Flying, records and
//! statistics live in `dupac_eval`; the figures in `dupac_plot::eval`.

use crate::global_args::GlobalArgs;
use anyhow::{Context, Result, bail};
use clap::Args;
use dupac_actor::pairs::Split;
use dupac_eval::EvalPlan;
use dupac_eval::fly::fly_all;
use dupac_eval::front::read_fronts;
use dupac_eval::records::{read_records, read_split};
use dupac_eval::report::write_tables;
use dupac_eval::stats::{Bootstrap, DEFAULT_RESAMPLES};
use dupac_eval::tune_a3::read_tuned;
use dupac_plot::eval::{draw_examples, draw_fig3, draw_fig4, draw_fronts, draw_pareto};
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct EvalArgs {
    /// A trained policy as `LABEL=FILE` (`policy.bin` or `checkpoint.bin`); repeat a label once
    /// per training seed (`--policy dupac=s1/policy.bin --policy dupac=s2/policy.bin`).
    #[arg(long = "policy", value_name = "LABEL=FILE")]
    pub policies: Vec<String>,
    /// λ of the coverage-aware planner, flown with A3 (repeatable; default 0.5, 1, 2, 4).
    #[arg(long = "lambda", value_name = "L")]
    pub lambdas: Vec<f64>,
    /// Leave the planners out (shortest path with A3 and with the oracle, coverage-aware).
    #[arg(long)]
    pub no_planners: bool,
    /// Pairs file (default: the file of `--split`).
    #[arg(long, value_name = "FILE", conflicts_with = "split")]
    pub pairs: Option<PathBuf>,
    /// The held-out split to fly: `validation` (`pairs.eval_file`, the default: the set the
    /// design was chosen on) or `test` (`pairs.test_file`, for the final report only); a
    /// missing file is drawn from its seed and written. The report names it.
    #[arg(long, value_enum, value_name = "validation|test")]
    pub split: Option<super::pairs::SplitArg>,
    /// A tuned A3 setting (`dupac tune-a3`'s `tuned_a3.toml`): the planners are flown with it
    /// too, as `shortest_a3tuned` and `coverage_l<λ>+a3tuned`.
    #[arg(long, value_name = "FILE")]
    pub a3_tuned: Option<PathBuf>,
    /// The policies of this label are flown with the `--a3-tuned` setting (a base method
    /// trained with it; repeatable).
    #[arg(long, value_name = "LABEL")]
    pub tuned_label: Vec<String>,
    /// The policies of this label (base methods: no site head) are flown with the predictive
    /// association (`env.predictive`) instead of A3 (repeatable).
    #[arg(long, value_name = "LABEL")]
    pub predictive_label: Vec<String>,
    /// Pairs per distance bin: the first K of each bin (default: all).
    #[arg(long, value_name = "K")]
    pub per_bin: Option<usize>,
    /// Report directory.
    #[arg(long, default_value = "out/eval")]
    pub out: PathBuf,
    /// Recompute the report from `OUT/records/*.bin` without flying.
    #[arg(long)]
    pub report_only: bool,
    /// Also render the paper's Fig. 2(b) (best-server coverage per altitude and its summary
    /// table, as `dupac map`) into `OUT/fig2b/`.
    #[arg(long)]
    pub maps: bool,
    /// Labels compared with the paper's DUPAC and base method.
    #[arg(long, default_value = "dupac")]
    pub dupac_label: String,
    #[arg(long, default_value = "base")]
    pub base_label: String,
    /// Do not re-fly a learned-site policy's moves with A3 and the oracle (`LABEL+a3`,
    /// `LABEL+oracle`, the report's "Route or association").
    #[arg(long)]
    pub no_replay: bool,
    /// Also re-fly a learned-site policy's moves with the hindsight association
    /// (`LABEL+hindsight_C`): the sites that minimise the site regret plus C dB·steps per
    /// handover over the whole recorded route; `C:mts` also forbids a handover sooner than
    /// `env.ping_pong_window_s` after the previous one (no ping-pongs). An evaluation reference
    /// that knows the route in advance (repeatable; docs/archive.md "What any association can do
    /// on DUPAC's moves").
    #[arg(long = "hindsight", value_name = "C[:mts]")]
    pub hindsight: Vec<String>,
    #[command(flatten)]
    pub fronts: super::front_args::FrontArgs,
    /// Fly every policy that observes the handover weight (`env.observation.handover_weight`)
    /// at each of these weights (`env.reward.handover_weight`), each as its own method
    /// `LABEL_w<W>`: one conditioned policy's front in one evaluation (repeatable, or
    /// comma-separated: `--handover-weight 0,1,3,6`; docs/env.md "Handover weight"). Other
    /// policies are flown once, under their own label.
    #[arg(long = "handover-weight", value_name = "W", value_delimiter = ',')]
    pub handover_weights: Vec<f64>,
    /// Resamples of the report's bootstrap over training seeds and pairs (its seed-aware
    /// intervals and paired differences; drawn from a fixed seed, so the report is the same on
    /// every run).
    #[arg(long, value_name = "B", default_value_t = DEFAULT_RESAMPLES)]
    pub bootstrap: usize,
}

impl EvalArgs {
    /// The split flown (validation unless `--split` says otherwise).
    fn split(&self) -> Split {
        self.split.map_or(Split::Validation, |s| s.split())
    }

    /// What to fly, for the run layer.
    fn plan(&self) -> Result<EvalPlan> {
        let a3_tuned = self.a3_tuned.as_deref().map(read_tuned).transpose()?;
        let f = &self.fronts;
        Ok(EvalPlan {
            policies: self.policies.clone(),
            lambdas: self.lambdas.clone(),
            no_planners: self.no_planners,
            pairs: self.pairs.clone(),
            split: self.split(),
            a3_tuned,
            tuned_labels: self.tuned_label.clone(),
            per_bin: self.per_bin,
            no_replay: self.no_replay,
            hindsight: self.hindsight.clone(),
            predictive_labels: self.predictive_label.clone(),
            a3_front: f.a3_front,
            a3_grid: f.a3_grid()?,
            hindsight_front: f.hindsight_front.clone(),
            predictive_front: f.predictive_front.clone(),
            handover_weights: self.handover_weights.clone(),
        })
    }
}

pub fn run(global: &GlobalArgs, args: &EvalArgs) -> Result<ExitCode> {
    let cfg = global.config()?;
    let records_dir = args.out.join("records");
    let boot = Bootstrap::with_resamples(args.bootstrap)?;
    if !args.report_only {
        // The files named by arguments before the world is built.
        // Without --pairs, a missing split file is drawn and written (from the split's seed).
        let split = args.split();
        match &args.pairs {
            Some(p) => crate::io::check_readable("--pairs", p)?,
            None if split.configured_file(&cfg.pairs).exists() => {
                crate::io::check_readable(split.file_key(), split.configured_file(&cfg.pairs))?
            }
            None => {}
        }
        for p in &args.policies {
            if let Some((_, file)) = p.split_once('=') {
                crate::io::check_readable("--policy", std::path::Path::new(file))?;
            }
        }
        let plan = args.plan()?;
        fly_all(&cfg, &plan, &records_dir, global.no_progress())?;
    }
    let files = read_records(&records_dir)?;
    if files.is_empty() {
        bail!("{}: no records to report on", records_dir.display());
    }
    dupac_plot::ensure_font()?;
    let split = read_split(&records_dir);
    let fronts = read_fronts(&records_dir)?;
    let (methods, bins) = write_tables(
        &args.out,
        &files,
        &fronts,
        (&args.dupac_label, &args.base_label),
        (
            boot,
            cfg.radio
                .channel
                .shadowing()
                .then_some(cfg.radio.channel.eval_fields),
        ),
        split.as_deref(),
    )?;
    if !fronts.is_empty() {
        draw_fronts(&args.out, &files, &fronts)?;
    }
    draw_fig3(&args.out, &methods, &bins)?;
    draw_fig4(&args.out, &methods, &bins)?;
    draw_pareto(&args.out, &methods)?;
    let world = dupac_radio::world::RadioWorld::build(&cfg).context("building the radio world")?;
    draw_examples(&args.out, &world, &files, &cfg.radio)?;
    if args.maps {
        super::map::run(
            global,
            &super::map::MapArgs {
                out: Some(args.out.join("fig2b")),
                site: None,
                field: 0,
            },
        )?;
    }
    println!("wrote {}", args.out.display());
    Ok(ExitCode::SUCCESS)
}
