//! What `dupac train --single-process` and `dupac learner` share around the one training loop
//! (`dupac_run::train_loop`): the configuration, the world, the held-out set, the learner
//! (fresh or resumed) and the locked run directory; then the loop with a progress bar and the
//! closing lines. They differ only in their trajectory source.

use super::run_args::{HeldOutSeen, RunArgs, device, progress_message, resolve_config};
use crate::global_args::GlobalArgs;
use anyhow::Result;
use dupac_actor::env::Env;
use dupac_actor::pairs::Pair;
use dupac_common::config::Config;
use dupac_common::metric;
use dupac_learner::learner::Learner;
use dupac_learner::source::TrajectorySource;
use dupac_plot::curves::render_curves;
use dupac_radio::world::RadioWorld;
use dupac_run::held_out::evaluate;
use dupac_run::local::LocalWorkers;
use dupac_run::run_dir::{CurveRenderer, RunOutput, checkpoint_to_resume};
use dupac_run::train_loop::{self, Finish, method_name, summary_line};
use dupac_scenario::pairs::{guide_sets_cached, held_out_pairs, make_pool, spread};
use dupac_scenario::progress::progress_bar;
use dupac_scenario::world::{SharedRsrp, world_and_cache};
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

/// A training run ready to start.
pub struct Training {
    pub cfg: Config,
    pub world: Arc<RadioWorld>,
    pub rsrp: SharedRsrp,
    /// Rollout workers in this process, when asked for (`--single-process`).
    pub local: Option<LocalWorkers>,
    pub learner: Learner,
    pub out: RunOutput,
    pub method: &'static str,
    eval_set: Vec<Pair>,
}

impl Training {
    /// Resolves the configuration, builds the world, reads (or makes) the held-out pairs,
    /// with `local` draws the training pool and starts rollout workers on it, creates or resumes
    /// the learner, and only then locks and opens the run directory (a failure before leaves it
    /// as it was); `how` ends the curves' title.
    pub fn prepare(global: &GlobalArgs, run: &RunArgs, how: &str, local: bool) -> Result<Training> {
        let cfg = resolve_config(global, run.association, run.out.as_ref())?;
        let checkpoint = checkpoint_to_resume(&cfg, run.resume, run.checkpoint.as_ref())?;
        let device = device(run.device)?;
        let (world, rsrp) = world_and_cache(&cfg, global.no_progress())?;
        let (obs_dim, n_sites) = Env::new(&cfg, world.clone(), rsrp.clone())?.policy_shape();
        // The pairs with a planner of their clearance (no coverage classes); the guide paths of
        // the evaluated ones and of the pool through the host's guide cache.
        let unguided = dupac_scenario::planners::unguided(&cfg);
        let planners =
            dupac_scenario::planners::Planners::new(&unguided, &[], &world, &rsrp, false);
        let mut eval_set = spread(
            &held_out_pairs(&unguided, &planners, global.no_progress())?,
            cfg.train.eval_pairs,
        );
        let pool = match local {
            true => Some(make_pool(&unguided, &planners, global.no_progress())?),
            false => None,
        };
        drop(planners);
        let mut pool = pool.unwrap_or_default();
        guide_sets_cached(
            &cfg,
            &world,
            &rsrp,
            &mut [&mut eval_set, &mut pool],
            global.no_progress(),
        )?;
        let local = match local {
            true => Some(LocalWorkers::new(&cfg, &world, &rsrp, &Arc::new(pool))?),
            false => None,
        };
        let mut learner = Learner::new(cfg.clone(), obs_dim, n_sites, &device);
        if let Some(ck) = &checkpoint {
            learner.restore(&device, ck)?;
            eprintln!(
                "resuming at update {} ({} timesteps)",
                ck.meta.update, ck.meta.global_step
            );
        }
        let method = method_name(&cfg);
        let title = format!(
            "{method}, seed {}: {}{how}",
            cfg.train.seed, world.city.name
        );
        let curves: CurveRenderer = Box::new(move |rows, path| {
            let points = |key: &str| rows.points(metric::GLOBAL_STEP, key);
            Ok(render_curves(&points, &title, path)?)
        });
        let out = RunOutput::open(&cfg, learner.update, curves)?;
        Ok(Training {
            cfg,
            world,
            rsrp,
            local,
            learner,
            out,
            method,
            eval_set,
        })
    }

    /// The training loop on `source` until done or stopped, with a progress bar; prints the
    /// summary (or where the checkpoint is) like every training command.
    pub fn run(
        mut self,
        global: &GlobalArgs,
        source: &mut dyn TrajectorySource,
        stop: &AtomicBool,
    ) -> Result<ExitCode> {
        let learner = &mut self.learner;
        let total = learner.num_updates() * learner.batch_size() as u64;
        let pb = progress_bar(total, "timesteps", global.no_progress());
        let mut held_out = HeldOutSeen::default();
        pb.set_position(learner.global_step);
        let (cfg, world, rsrp, eval_set) = (&self.cfg, &self.world, &self.rsrp, &self.eval_set);
        let eval = |p: &_| evaluate(cfg, world, rsrp, p, eval_set);
        let finish = train_loop::train(
            learner,
            source,
            &mut self.out,
            &eval,
            stop,
            &mut |l, row| {
                pb.set_position(l.global_step);
                held_out.see(row);
                pb.set_message(format!("{}{}", progress_message(row), held_out.suffix()));
                if global.no_progress() {
                    // Without a progress bar (the children of `dupac train`, services): one
                    // line per update.
                    tracing::info!(
                        update = l.update,
                        global_step = l.global_step,
                        "{}",
                        progress_message(row)
                    );
                }
            },
        )?;
        pb.finish_and_clear();
        match finish {
            Finish::Interrupted => eprintln!(
                "interrupted at update {}: checkpoint written to {}; continue with --resume",
                learner.update,
                self.out.ck_path.display()
            ),
            Finish::Completed => println!("{}", summary_line(learner, &self.out.last())),
        }
        eprintln!("wrote {}", self.out.out.display());
        Ok(ExitCode::SUCCESS)
    }
}
