//! Physics-based simulator of the Intelligent Pneumatic Actuator (placeholder being written).

/// Errors of the plant crate.
#[derive(Debug, thiserror::Error)]
pub enum IpaError {
    /// Bad configuration or input specification.
    #[error("{0}")]
    Config(String),
    /// Numerical failure of the integration.
    #[error("numerical failure: {0}")]
    Numerical(String),
}

impl IpaError {
    /// True for numerical failures (exit code 1).
    pub fn is_numerical(&self) -> bool {
        matches!(self, IpaError::Numerical(_))
    }
}
