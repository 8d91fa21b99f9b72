//! Errors of the run layer: what failed, with the file or step it concerns.

/// Any error a lower layer reports, boxed.
pub type BoxError = Box<dyn std::error::Error + Send + Sync>;

/// Errors of the run layer.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// A step that failed, naming what it was doing (a file, a phase); the cause follows in the
    /// error chain.
    #[error("{what}")]
    Context {
        what: String,
        #[source]
        source: BoxError,
    },
    /// A refusal with its reason (a run directory in use, nothing to train on, …).
    #[error("{0}")]
    Refused(String),
    /// The learning curves' renderer ([`crate::run_dir::CurveRenderer`]) failed.
    #[error(transparent)]
    Plot(BoxError),
    #[error(transparent)]
    Train(#[from] dupac_learner::learner::TrainError),
    #[error(transparent)]
    Checkpoint(#[from] dupac_learner::checkpoint::CheckpointError),
    #[error(transparent)]
    Scenario(#[from] dupac_scenario::error::ScenarioError),
    #[error(transparent)]
    Radio(#[from] dupac_radio::error::RadioError),
    #[error(transparent)]
    Pairs(#[from] dupac_actor::pairs::PairsError),
    #[error(transparent)]
    Env(#[from] dupac_actor::env::EnvError),
    #[error(transparent)]
    Rollout(#[from] dupac_actor::rollout::RolloutError),
    #[error(transparent)]
    Fs(#[from] dupac_common::fsio::FsError),
    #[error(transparent)]
    Codec(#[from] dupac_common::codec::CodecError),
    #[error(transparent)]
    Plan(#[from] dupac_actor::planner::PlanError),
}

/// Adds what was being done to an error (anyhow's `with_context` for this library).
pub trait Context<T> {
    fn context_with(self, what: impl FnOnce() -> String) -> Result<T, RunError>;
    fn context(self, what: &str) -> Result<T, RunError>;
}

impl<T, E: Into<BoxError>> Context<T> for Result<T, E> {
    fn context_with(self, what: impl FnOnce() -> String) -> Result<T, RunError> {
        self.map_err(|e| RunError::Context {
            what: what(),
            source: e.into(),
        })
    }

    fn context(self, what: &str) -> Result<T, RunError> {
        self.context_with(|| what.to_string())
    }
}
