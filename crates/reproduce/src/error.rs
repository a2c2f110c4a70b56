//! The error type of the reproduction pipeline.

/// Everything that can go wrong while reproducing the paper: a failure of one of the libraries it
/// drives, or of writing its outputs.
#[derive(Debug, thiserror::Error)]
pub enum ReproduceError {
    /// Identification, data or model error.
    #[error(transparent)]
    Sysid(#[from] sysid::SysidError),
    /// A failure of the plant simulator.
    #[error(transparent)]
    Ipa(#[from] ipa::IpaError),
    /// A failure of the control layer.
    #[error(transparent)]
    Control(#[from] control::ControlError),
    /// A figure or the report could not be drawn or written.
    #[error(transparent)]
    Report(#[from] report::ReportError),
    /// An output file could not be written.
    #[error(transparent)]
    Output(#[from] sysid_io::OutputError),
}

impl ReproduceError {
    /// True for failures of the numerics (exit code 1) rather than of the input or outputs (2).
    pub fn is_numerical(&self) -> bool {
        match self {
            ReproduceError::Sysid(e) => e.is_numerical(),
            ReproduceError::Ipa(e) => e.is_numerical(),
            ReproduceError::Control(e) => e.is_numerical(),
            ReproduceError::Report(e) => e.is_numerical(),
            ReproduceError::Output(_) => false,
        }
    }
}
