//! One module per subcommand.

pub mod actor;
pub mod cache;
pub mod children;
pub mod config;
pub mod eval;
pub mod export;
pub mod fly;
pub mod front_args;
pub mod learner;
pub mod map;
pub mod monitor;
pub mod net;
pub mod orchestrate;
pub mod pairs;
pub mod plan;
pub mod radio;
pub mod relay;
pub mod run_args;
pub mod scenario;
pub mod shell;
pub mod train;
pub mod training;
pub mod tune_a3;
