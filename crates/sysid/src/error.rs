//! The error type of the identification library.

use std::path::PathBuf;

/// Everything that can go wrong in `sysid`. Messages name the file, line and column (1-based) or the
/// setting at fault, and what was expected.
#[derive(Debug, thiserror::Error)]
pub enum SysidError {
    /// A data or model file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A file's content is malformed at a known place.
    #[error("{file}:{line}:{column}: {message}")]
    Parse {
        /// The file (or `<stdin>` / `<memory>`).
        file: String,
        /// 1-based line number.
        line: usize,
        /// 1-based column number (field index for CSV).
        column: usize,
        /// What was found and what was expected.
        message: String,
    },
    /// A file is malformed as a whole (missing column, too few rows, wrong schema...).
    #[error("{file}: {message}")]
    File {
        /// The file concerned.
        file: String,
        /// What is wrong and what was expected.
        message: String,
    },
    /// A setting (flag) is outside its valid range.
    #[error("invalid setting {name} = {value}: {expected}")]
    Setting {
        /// The setting's name as the user sees it (e.g. `--forgetting`).
        name: String,
        /// The value given.
        value: String,
        /// What is accepted.
        expected: String,
    },
    /// The data cannot support the requested estimate (too short, not persistently exciting...).
    #[error("{0}")]
    Data(String),
    /// A numerical failure: non-finite values, loss of positive definiteness, singular problem.
    #[error("numerical failure: {0}")]
    Numerical(String),
}

impl SysidError {
    /// True for failures of the numerics (exit code 1) rather than of the input (exit code 2).
    pub fn is_numerical(&self) -> bool {
        matches!(self, SysidError::Numerical(_))
    }

    /// Shorthand for a [`SysidError::Setting`].
    pub fn setting(name: &str, value: impl ToString, expected: &str) -> Self {
        SysidError::Setting {
            name: name.to_string(),
            value: value.to_string(),
            expected: expected.to_string(),
        }
    }
}
