//! The error type of the plant crate.

/// Everything that can go wrong in `ipa`: a bad configuration or input specification (exit code 2), or a
/// numerical failure of the integration (exit code 1). Messages name the setting or file at fault and what
/// was expected.
#[derive(Debug, thiserror::Error)]
pub enum IpaError {
    /// Bad configuration, plant or input specification (names the key/flag and what is accepted).
    #[error("{0}")]
    Config(String),
    /// A file could not be read, or its content is invalid.
    #[error(transparent)]
    Sysid(#[from] sysid_core::SysidError),
    /// Numerical failure of the integration (non-finite or non-physical state).
    #[error("numerical failure: {0}")]
    Numerical(String),
}

impl IpaError {
    /// True for numerical failures (exit code 1) rather than bad input (exit code 2).
    pub fn is_numerical(&self) -> bool {
        match self {
            IpaError::Numerical(_) => true,
            IpaError::Sysid(e) => e.is_numerical(),
            IpaError::Config(_) => false,
        }
    }
}
