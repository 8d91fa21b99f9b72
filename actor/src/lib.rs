//! The actor side of DUPAC: the UAV flight environment (the paper's MDP, spec/env.md), the
//! planners (shortest flyable path, coverage-aware path) and the episode pairs.

pub mod env;
pub mod expand;
pub mod metrics;
pub mod pairs;
pub mod pilot;
pub mod planner;
pub mod record;
pub mod reward;
pub mod rollout;
