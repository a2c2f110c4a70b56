//! The error type of the report library.

/// Everything that can go wrong while drawing figures or writing the report.
///
/// Messages name the figure, panel or series at fault (1-based indices, as a reader counts them) and
/// what was expected.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// A figure description cannot be drawn as given (zero size, `x` and `y` of different lengths...).
    #[error("figure \"{figure}\": {message}")]
    InvalidFigure {
        /// The figure's title.
        figure: String,
        /// What is wrong and what was expected.
        message: String,
    },
    /// The plotting backend failed while drawing (a bug or an unusable font, not bad data).
    #[error("figure \"{figure}\": drawing failed: {message}")]
    Render {
        /// The figure's title.
        figure: String,
        /// The backend's message.
        message: String,
    },
    /// Encoding the rendered pixels as PNG failed.
    #[error("figure \"{figure}\": PNG encoding failed: {message}")]
    Encode {
        /// The figure's title.
        figure: String,
        /// The encoder's message.
        message: String,
    },
    /// A failed (atomic) write of an output file.
    #[error(transparent)]
    Output(#[from] sysid_io::OutputError),
}

impl ReportError {
    /// Always false: drawing, encoding and writing never fail for numerical reasons (non-finite samples
    /// are skipped when plotting), so a report error is an input or output error (exit code 2).
    pub fn is_numerical(&self) -> bool {
        false
    }

    /// Shorthand for a [`ReportError::InvalidFigure`].
    pub(crate) fn invalid(figure: &str, message: impl Into<String>) -> Self {
        ReportError::InvalidFigure {
            figure: figure.to_string(),
            message: message.into(),
        }
    }

    /// Shorthand for a [`ReportError::Render`].
    pub(crate) fn render(figure: &str, message: impl ToString) -> Self {
        ReportError::Render {
            figure: figure.to_string(),
            message: message.to_string(),
        }
    }
}
