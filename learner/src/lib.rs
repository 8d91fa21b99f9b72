//! The DUPAC learner (issue 4): the actor-critic in burn, GAE, the PPO update, normalisers,
//! checkpoints and the synchronous training loop. The update does not care where trajectories
//! came from; the distributed learner (issue 5) wraps the same update.

pub mod checkpoint;
pub mod dist;
pub mod gae;
pub mod model;
pub mod ppo;
pub mod site_horizon;
pub mod train;
