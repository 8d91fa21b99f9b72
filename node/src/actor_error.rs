//! The errors of an actor or a pilot, below both the actor's loop (`actor`) and its Zenoh side
//! (`wiring`).

use dupac_actor::env::EnvError;
use dupac_actor::rollout::RolloutError;

/// Errors of an actor.
#[derive(Debug, thiserror::Error)]
pub enum ActorError {
    #[error("zenoh: {0}")]
    Zenoh(String),
    #[error(transparent)]
    Env(#[from] EnvError),
    #[error(transparent)]
    Rollout(#[from] RolloutError),
    #[error(transparent)]
    Codec(#[from] dupac_common::codec::CodecError),
    #[error(
        "refusing to act for this learner: {0}. Start the actor with the learner's configuration (the same city, radio, environment and pairs settings)"
    )]
    Refused(String),
    #[error("cannot start the environment threads: {0}")]
    Threads(String),
}

pub(crate) fn z(e: impl std::fmt::Display) -> ActorError {
    ActorError::Zenoh(crate::net::zenoh_message(&e))
}
