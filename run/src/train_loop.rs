//! The one training loop, for `dupac train --single-process` (local workers), `dupac learner`
//! (chunks over Zenoh) and so `dupac train` (which runs a learner process): the only code that
//! decides when to evaluate, log and checkpoint.
//!
//! Each iteration: [`Learner::iterate`] (a batch from the source, the PPO update, the new
//! weights back to the source); the rolling training-episode metrics (`charts/episodic_*`,
//! `domain/…`, the last [`RECENT_EPISODES`]); the held-out evaluation when due (`eval/…`); the
//! row appended to the run directory and reported to the source; a checkpoint every
//! `train.checkpoint_every` updates, at the end and when stopped (Ctrl-C).

use crate::error::RunError;
use crate::run_dir::RunOutput;
use dupac_actor::metrics::{domain_stats, put_domain};
use dupac_common::config::{Association, Config};
use dupac_common::metric;
use dupac_common::msg::EpisodeSummary;
use dupac_common::policy::PolicyWeights;
use dupac_learner::learner::{Learner, MetricsRow};
use dupac_learner::source::TrajectorySource;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};

/// Training episodes kept for the rolling metrics.
pub const RECENT_EPISODES: usize = 100;

/// Flies the held-out pairs with a policy (the deterministic evaluation).
pub type Evaluator<'a> = &'a dyn Fn(&PolicyWeights) -> Result<Vec<EpisodeSummary>, RunError>;

/// How a run ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Finish {
    /// Every update of `train.total_timesteps` done.
    Completed,
    /// Stopped early (Ctrl-C, or the source stopped); the checkpoint holds the last update.
    Interrupted,
}

/// Is a held-out evaluation due after update `update`?
pub fn eval_due(cfg: &Config, update: u64, last: bool) -> bool {
    last || (cfg.train.eval_every > 0 && update.is_multiple_of(cfg.train.eval_every))
}

/// Trains `learner` on `source` until its last update or until `stop` is set, writing `out`;
/// `on_row` sees each row once it is complete (a progress bar).
pub fn train(
    learner: &mut Learner,
    source: &mut dyn TrajectorySource,
    out: &mut RunOutput,
    evaluate: Evaluator<'_>,
    stop: &AtomicBool,
    on_row: &mut dyn FnMut(&Learner, &MetricsRow),
) -> Result<Finish, RunError> {
    let cfg = learner.cfg.clone();
    let mut recent: VecDeque<EpisodeSummary> = VecDeque::with_capacity(RECENT_EPISODES);
    let mut checkpointed_at = None;
    while !learner.done() {
        let Some(report) = learner.iterate(source)? else {
            break;
        };
        let mut row = report.row;
        for e in report.episodes {
            if recent.len() == RECENT_EPISODES {
                recent.pop_front();
            }
            recent.push_back(e);
        }
        let d = domain_stats(recent.make_contiguous());
        row.insert(metric::EPISODIC_RETURN.into(), d.episodic_return);
        row.insert(metric::EPISODIC_LENGTH.into(), d.episodic_length);
        put_domain(&mut row, &metric::TRAIN, &d);
        let last = learner.done();
        if eval_due(&cfg, learner.update, last) {
            let eps = evaluate(&learner.policy())?;
            put_domain(&mut row, &metric::EVAL, &domain_stats(&eps));
        }
        on_row(learner, &row);
        tracing::debug!(?row, "update");
        out.push(row.clone())?;
        let interrupted = stop.load(Ordering::Relaxed);
        if learner.update.is_multiple_of(cfg.train.checkpoint_every) || last || interrupted {
            out.checkpoint(learner)?;
            checkpointed_at = Some(learner.update);
        }
        source
            .report(&row, &learner.progress(), last)
            .map_err(dupac_learner::learner::TrainError::Source)?;
        if interrupted {
            break;
        }
    }
    // Always leave a checkpoint of the last update behind, also when stopped while waiting.
    if checkpointed_at != Some(learner.update) {
        out.checkpoint(learner)?;
    }
    let finish = if learner.done() {
        Finish::Completed
    } else {
        Finish::Interrupted
    };
    source
        .finish(&learner.progress(), finish == Finish::Completed)
        .map_err(dupac_learner::learner::TrainError::Source)?;
    Ok(finish)
}

/// A human name of the method a configuration trains.
pub fn method_name(cfg: &Config) -> &'static str {
    match cfg.env.association {
        Association::Learned => "DUPAC (learned association)",
        _ => "base method (A3 association)",
    }
}

/// The closing line of a training run.
pub fn summary_line(learner: &Learner, last: &MetricsRow) -> String {
    let g = |k: &str| last.get(k).copied().unwrap_or(f64::NAN);
    format!(
        "done: {} updates, {} timesteps (decisions), {:.0} s; held-out: success {:.1} %, collisions {:.1} %, overhead {:.1} %, mean RSRP {:.1} dBm, excellent {:.1} %, site regret {:.2} dB",
        learner.update,
        learner.global_step,
        learner.train_seconds,
        100.0 * g(metric::EVAL.success_rate),
        100.0 * g(metric::EVAL.collision_rate),
        100.0 * g(metric::EVAL.distance_overhead),
        g(metric::EVAL.mean_rsrp_dbm),
        g(metric::EVAL.pct_excellent),
        g(metric::EVAL.site_regret_db),
    )
}
