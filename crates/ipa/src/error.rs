//! The error type of the plant crate.

/// Everything that can go wrong in `ipa`: a bad configuration or input specification (exit code 2), or a
/// numerical failure of the integration (exit code 1). Messages name the setting or file at fault and what
/// was expected.
#[derive(Debug, thiserror::Error)]
pub enum IpaError {
    /// Bad configuration, plant or input specification (names the key/flag and what is accepted).
    #[error("{0}")]
    Config(String),
    /// A setting is outside its valid range or malformed.
    #[error("invalid setting {setting} = {value}: {expected}")]
    Setting {
        /// The setting.
        setting: IpaSetting,
        /// The value given, as written in messages (quoted where it is text).
        value: String,
        /// What is wrong and what is accepted.
        expected: String,
    },
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
            IpaError::Config(_) | IpaError::Setting { .. } => false,
        }
    }
}

impl IpaError {
    /// The message with each setting named by `name` (a command line passes its flags); the `Display`
    /// form uses [`IpaSetting::name`].
    pub fn render(&self, name: &dyn Fn(IpaSetting) -> String) -> String {
        match self {
            IpaError::Setting {
                setting,
                value,
                expected,
            } => format!("invalid setting {} = {value}: {expected}", name(*setting)),
            // A data or model error of the identification library names its settings by their flags.
            IpaError::Sysid(e) => e.render_flags(),
            other => other.to_string(),
        }
    }

    /// Shorthand for an [`IpaError::Setting`].
    pub fn setting(setting: IpaSetting, value: impl ToString, expected: impl Into<String>) -> Self {
        IpaError::Setting {
            setting,
            value: sysid_core::error::shown_value(value),
            expected: expected.into(),
        }
    }
}

/// A setting of the plant library, as named in [`IpaError::Setting`]; a command line maps each to its
/// flag ([`IpaError::render`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum IpaSetting {
    /// Number of samples N of an experiment.
    Samples,
    /// Ts: sampling period (s).
    Ts,
    /// Amplitude of an input design (counts).
    Amplitude,
    /// The input design specification (`staircase`, `prbs`, ...).
    Input,
    /// The plant specification (`ipa`, `paper`, `model:FILE`).
    Plant,
    /// The physics plant's configuration file (TOML; `ipa` only).
    PlantConfig,
}

impl IpaSetting {
    /// The library's name of the setting.
    pub fn name(&self) -> &'static str {
        match self {
            IpaSetting::Samples => "samples",
            IpaSetting::Ts => "ts_s",
            IpaSetting::Amplitude => "amplitude_counts",
            IpaSetting::Input => "input",
            IpaSetting::Plant => "plant",
            IpaSetting::PlantConfig => "plant_config",
        }
    }
}

impl std::fmt::Display for IpaSetting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl IpaSetting {
    /// The command-line flag of this setting (the Python package raises with the same words).
    pub fn flag(&self) -> &'static str {
        match self {
            IpaSetting::Samples => "--samples",
            IpaSetting::Ts => "--ts",
            IpaSetting::Amplitude => "--amplitude",
            IpaSetting::Input => "--input",
            IpaSetting::Plant => "--plant",
            IpaSetting::PlantConfig => "--plant-config",
        }
    }
}
