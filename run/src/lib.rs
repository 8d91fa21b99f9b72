//! The run layer of DUPAC: what the commands share, above the simulation (`dupac-actor`), the
//! scenario (`dupac-scenario`: world, RSRP cache, pairs) and the learner. The run
//! directory and its metrics ([`run_dir`], [`metrics_table`]), local rollout workers as a
//! trajectory source ([`local`]), training's periodic held-out check ([`held_out`]) and the one
//! training loop ([`train_loop`]) that `dupac train --single-process` and `dupac learner` both
//! run. Evaluation (`dupac eval`, `dupac tune-a3`) is `dupac-eval`, beside this crate on the scenario.

pub mod error;
pub mod export;
pub mod held_out;
pub mod local;
pub mod metrics_table;
pub mod monitor;
pub mod run_dir;
pub mod tensorboard;
pub mod train_loop;
