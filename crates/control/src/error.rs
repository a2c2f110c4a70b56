//! The error type of the control library.

use std::path::PathBuf;

/// Everything that can go wrong in `control`. Messages name the setting, profile or file at fault and
/// what was expected.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// Bad settings that are not a single named setting (e.g. an inconsistent combination).
    #[error("{0}")]
    Config(String),
    /// A setting (controller gain, duration, ...) is outside its valid range.
    #[error("invalid setting {name} = {value}: {expected}")]
    Setting {
        /// The setting's name as the user sees it (e.g. `--kp`).
        name: String,
        /// The value given.
        value: String,
        /// What is accepted.
        expected: String,
    },
    /// A set-point profile specification (or the file it names) is malformed.
    #[error("set-point profile `{spec}`: {message}")]
    Profile {
        /// The specification as given (e.g. `staircase:20,60@3`).
        spec: String,
        /// What is wrong and what was expected (with file:line:column for a profile file).
        message: String,
    },
    /// A profile file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// Numerical failure: the plant's output or the controller became non-finite (says at which sample).
    #[error("numerical failure: {0}")]
    Numerical(String),
}

impl ControlError {
    /// True for numerical failures (exit code 1) rather than bad input (exit code 2).
    pub fn is_numerical(&self) -> bool {
        matches!(self, ControlError::Numerical(_))
    }

    /// Shorthand for a [`ControlError::Setting`].
    pub fn setting(name: &str, value: impl ToString, expected: &str) -> Self {
        ControlError::Setting {
            name: name.to_string(),
            value: value.to_string(),
            expected: expected.to_string(),
        }
    }
}
