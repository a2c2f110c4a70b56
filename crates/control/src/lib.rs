//! PI position control (placeholder being written).

/// Errors of the control crate.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// Bad settings or profile.
    #[error("{0}")]
    Config(String),
    /// Numerical failure (the plant diverged).
    #[error("numerical failure: {0}")]
    Numerical(String),
}

impl ControlError {
    /// True for numerical failures (exit code 1).
    pub fn is_numerical(&self) -> bool {
        matches!(self, ControlError::Numerical(_))
    }
}
