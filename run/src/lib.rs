//! The run layer of DUPAC: what the commands share, above the simulation (`dupac-actor`), the
//! learner and the network. Scenario setup ([`scenario`]: world, RSRP cache, pairs), the run
//! directory and its metrics ([`run_dir`], [`metrics_table`]), local rollout workers as a
//! trajectory source ([`local`]), training's periodic held-out check ([`held_out`]) and the one
//! training loop ([`train_loop`]) that `dupac train --single-process` and `dupac learner` both
//! run. Evaluation (`dupac eval`, `dupac tune-a3`) is `dupac-eval`, above this crate.

pub mod error;
pub mod export;
pub mod guide_cache;
pub mod held_out;
pub mod local;
pub mod metrics_table;
pub mod monitor;
pub mod progress;
pub mod run_dir;
pub mod scenario;
pub mod tensorboard;
pub mod train_loop;
