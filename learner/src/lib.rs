//! The DUPAC learner: the actor-critic on burn, GAE, the PPO update, checkpoints and policy
//! files, and [`learner::Learner`], the update fed by a [`source::TrajectorySource`]. It depends on the contract
//! (`dupac-common`) and burn only: no environment, no radio, no network.

pub mod batch;
pub mod checkpoint;
pub mod gae;
pub mod learner;
pub mod model;
pub mod ppo;
pub mod source;
pub mod synthetic;
