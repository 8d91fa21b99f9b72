//! Errors of the scenario setup: what failed, with the file or step it concerns.

/// Any error a lower layer reports, boxed.
pub type BoxError = Box<dyn std::error::Error + Send + Sync>;

/// Errors of the scenario setup.
#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    /// A step that failed, naming what it was doing (a file, a phase); the cause follows in the
    /// error chain.
    #[error("{what}")]
    Context {
        what: String,
        #[source]
        source: BoxError,
    },
    /// A refusal with its reason (no guide planner of a clearance, no training pairs, …).
    #[error("{0}")]
    Refused(String),
    #[error(transparent)]
    Radio(#[from] dupac_radio::error::RadioError),
    #[error(transparent)]
    Pairs(#[from] dupac_actor::pairs::PairsError),
}

/// Adds what was being done to an error (anyhow's `with_context` for this library).
pub trait Context<T> {
    fn context_with(self, what: impl FnOnce() -> String) -> Result<T, ScenarioError>;
    fn context(self, what: &str) -> Result<T, ScenarioError>;
}

impl<T, E: Into<BoxError>> Context<T> for Result<T, E> {
    fn context_with(self, what: impl FnOnce() -> String) -> Result<T, ScenarioError> {
        self.map_err(|e| ScenarioError::Context {
            what: what(),
            source: e.into(),
        })
    }

    fn context(self, what: &str) -> Result<T, ScenarioError> {
        self.context_with(|| what.to_string())
    }
}
