//! The errors of the figures: what could not be drawn or written, naming the file.

use dupac_common::fsio::FsError;

/// Any error a drawing backend reports, boxed.
pub type BoxError = Box<dyn std::error::Error + Send + Sync>;

/// The result of drawing a figure.
pub type Result<T, E = PlotError> = std::result::Result<T, E>;

/// Errors of the figures.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Inputs that cannot be drawn (an empty or non-finite area, series of different lengths,
    /// non-finite values); the message names the output file and what is wrong.
    #[error("{0}")]
    Invalid(String),
    /// The bundled font (`assets/DejaVuSans.ttf`) could not be registered with plotters.
    #[error("cannot register the bundled font assets/DejaVuSans.ttf")]
    Font,
    /// A drawing operation of plotters failed, with its message.
    #[error("drawing failed: {0}")]
    Draw(String),
    /// A chart of plotters (built, meshed, drawn) failed.
    #[error(transparent)]
    Chart(BoxError),
    /// A figure or its data file that could not be written, naming it; the cause follows in
    /// the error chain.
    #[error("{what}")]
    Context {
        what: String,
        #[source]
        source: Box<PlotError>,
    },
    /// The atomic writer failed.
    #[error(transparent)]
    Fs(#[from] FsError),
}

impl<E: std::error::Error + Send + Sync + 'static> From<plotters::drawing::DrawingAreaErrorKind<E>>
    for PlotError
{
    fn from(e: plotters::drawing::DrawingAreaErrorKind<E>) -> Self {
        PlotError::Chart(Box::new(e))
    }
}

/// Adds what was being written to an error.
pub(crate) trait Context<T> {
    fn with_context(self, what: impl FnOnce() -> String) -> Result<T>;
}

impl<T, E: Into<PlotError>> Context<T> for std::result::Result<T, E> {
    fn with_context(self, what: impl FnOnce() -> String) -> Result<T> {
        self.map_err(|e| PlotError::Context {
            what: what(),
            source: Box::new(e.into()),
        })
    }
}

/// Plotters' errors carry the backend type; flatten them into [`PlotError::Draw`] with their
/// message.
pub(crate) fn pe<E: std::fmt::Display>(e: E) -> PlotError {
    PlotError::Draw(e.to_string())
}
