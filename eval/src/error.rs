//! Errors of the evaluation: what failed, with the file, flag or step it concerns
//! ([`EvalError`], [`Context`]), and `refused!(…)`, a refusal with a formatted reason.

/// Any error a lower layer reports, boxed.
pub type BoxError = Box<dyn std::error::Error + Send + Sync>;

/// Errors of the evaluation.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A step that failed, naming what it was doing (a file, a phase); the cause follows in the
    /// error chain.
    #[error("{what}")]
    Context {
        what: String,
        #[source]
        source: BoxError,
    },
    /// A refusal with its reason (a bad flag value, a records file that does not hold, a policy
    /// of another observation, …).
    #[error("{0}")]
    Refused(String),
    #[error(transparent)]
    Scenario(#[from] dupac_scenario::error::ScenarioError),
    #[error(transparent)]
    Checkpoint(#[from] dupac_learner::checkpoint::CheckpointError),
    #[error(transparent)]
    Radio(#[from] dupac_radio::error::RadioError),
    #[error(transparent)]
    Pairs(#[from] dupac_actor::pairs::PairsError),
    #[error(transparent)]
    Env(#[from] dupac_actor::env::EnvError),
    #[error(transparent)]
    Rollout(#[from] dupac_actor::rollout::RolloutError),
    #[error(transparent)]
    Plan(#[from] dupac_actor::planner::PlanError),
    #[error(transparent)]
    Fs(#[from] dupac_common::fsio::FsError),
    #[error(transparent)]
    Codec(#[from] dupac_common::codec::CodecError),
}

/// Adds what was being done to an error (anyhow's `with_context` for this library).
pub trait Context<T> {
    fn context_with(self, what: impl FnOnce() -> String) -> Result<T, EvalError>;
    fn context(self, what: &str) -> Result<T, EvalError>;
}

impl<T, E: Into<BoxError>> Context<T> for Result<T, E> {
    fn context_with(self, what: impl FnOnce() -> String) -> Result<T, EvalError> {
        self.map_err(|e| EvalError::Context {
            what: what(),
            source: e.into(),
        })
    }

    fn context(self, what: &str) -> Result<T, EvalError> {
        self.context_with(|| what.to_string())
    }
}

/// A refusal with a formatted reason.
macro_rules! refused {
    ($($t:tt)*) => { $crate::error::EvalError::Refused(format!($($t)*)) };
}
pub(crate) use refused;
