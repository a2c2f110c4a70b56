//! The error type of the control library.

use std::path::PathBuf;

/// A setting of the control library, as named in [`ControlError::Setting`]; a command line maps each to
/// its flag ([`ControlError::render`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ControlSetting {
    /// Kp: proportional gain (counts/mm).
    Kp,
    /// Ki: integral gain (counts/(mm·s) or counts/(mm·sample)).
    Ki,
    /// u_max: saturation limit of the command (counts).
    UMax,
    /// Tt: tracking time constant of back-calculation (s).
    TrackingTime,
    /// Ts: sampling period of the controller (s).
    Ts,
    /// Length of a closed-loop run (s).
    Duration,
    /// y0: initial position (mm).
    Y0,
    /// The deadzone (b_l, b_r, m_l, m_r) a compensator inverts.
    Deadzone,
    /// The compensator's threshold (counts).
    CompensatorThreshold,
    /// Kd: derivative gain of the tuned controller (counts·s/mm).
    Kd,
    /// Tf: filter time constant of the derivative (s).
    DerivativeFilter,
    /// e_h: hold band of the tuned controller (mm).
    HoldBand,
    /// e_f: fine band of the tuned controller (mm).
    FineBand,
    /// The nudge mode of the tuned controller (band, ramp, start fraction, rest samples).
    Nudge,
    /// The approach with braking of the tuned controller (min step, switch, lead, strength, samples).
    Brake,
    /// The short-step approach of the tuned controller (max step, drive, ramp, switch, lead, brake).
    ShortApproach,
    /// The tuning specification (`--spec`).
    Spec,
    /// Plant variants a tuning searches over.
    Variants,
    /// Physics variants of a tuning's verification.
    PhysicsVariants,
    /// Cost evaluations a tuning may use.
    MaxEvaluations,
    /// The lowest frequency of a frequency response (Hz).
    FMin,
}

impl ControlSetting {
    /// The library's name of the setting (the field it sets).
    pub fn name(&self) -> &'static str {
        match self {
            ControlSetting::Kp => "kp",
            ControlSetting::Ki => "ki",
            ControlSetting::UMax => "u_max",
            ControlSetting::TrackingTime => "tt_s",
            ControlSetting::Ts => "ts",
            ControlSetting::Duration => "duration_s",
            ControlSetting::Y0 => "y0_mm",
            ControlSetting::Deadzone => "deadzone",
            ControlSetting::CompensatorThreshold => "threshold_counts",
            ControlSetting::Kd => "kd",
            ControlSetting::DerivativeFilter => "derivative_filter_s",
            ControlSetting::HoldBand => "hold_band_mm",
            ControlSetting::FineBand => "fine_band_mm",
            ControlSetting::Nudge => "nudge",
            ControlSetting::Brake => "brake",
            ControlSetting::ShortApproach => "short_approach",
            ControlSetting::Spec => "spec",
            ControlSetting::Variants => "variants",
            ControlSetting::PhysicsVariants => "physics_variants",
            ControlSetting::MaxEvaluations => "max_evaluations",
            ControlSetting::FMin => "f_min_hz",
        }
    }
}

impl std::fmt::Display for ControlSetting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Everything that can go wrong in `control`. Messages name the setting, profile or file at fault and
/// what was expected.
#[derive(Debug, thiserror::Error)]
pub enum ControlError {
    /// Bad settings that are not a single named setting (e.g. an inconsistent combination).
    #[error("{0}")]
    Config(String),
    /// A setting (controller gain, duration, ...) is outside its valid range.
    #[error("invalid setting {setting} = {value}: {expected}")]
    Setting {
        /// The setting.
        setting: ControlSetting,
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
    /// The caller asked the computation to stop ([`sysid_core::Stop`]: Ctrl-C in Python) before it
    /// finished; there is no result.
    #[error("stopped at the caller's request before the end (no result)")]
    Cancelled,
}

impl ControlError {
    /// True for numerical failures (exit code 1) rather than bad input (exit code 2).
    pub fn is_numerical(&self) -> bool {
        matches!(self, ControlError::Numerical(_))
    }

    /// The message with each setting named by `name` (a command line passes its flags); the
    /// `Display` form uses [`ControlSetting::name`].
    pub fn render(&self, name: &dyn Fn(ControlSetting) -> String) -> String {
        match self {
            ControlError::Setting {
                setting,
                value,
                expected,
            } => format!("invalid setting {} = {value}: {expected}", name(*setting)),
            other => other.to_string(),
        }
    }

    /// Shorthand for a [`ControlError::Setting`].
    pub fn setting(setting: ControlSetting, value: impl ToString, expected: &str) -> Self {
        ControlError::Setting {
            setting,
            value: sysid_core::error::shown_value(value),
            expected: expected.to_string(),
        }
    }
}

impl ControlSetting {
    /// The command-line flag of this setting (the Python package raises with the same words).
    pub fn flag(&self) -> &'static str {
        match self {
            ControlSetting::Kp => "--kp",
            ControlSetting::Ki => "--ki",
            ControlSetting::UMax => "--u-max",
            ControlSetting::TrackingTime => "--tracking-time",
            ControlSetting::Ts => "ts",
            ControlSetting::Duration => "--duration",
            ControlSetting::Y0 => "--y0",
            ControlSetting::Deadzone => "--compensate-deadzone",
            ControlSetting::CompensatorThreshold => "--compensator-threshold",
            ControlSetting::Kd => "kd (controller file)",
            ControlSetting::DerivativeFilter => "derivative_filter_s (controller file)",
            ControlSetting::HoldBand => "hold_band_mm (controller file)",
            ControlSetting::FineBand => "fine_band_mm (controller file)",
            ControlSetting::Nudge => "nudge (controller file)",
            ControlSetting::Brake => "brake (controller file)",
            ControlSetting::ShortApproach => "short_approach (controller file)",
            ControlSetting::Spec => "--spec",
            ControlSetting::Variants => "--variants",
            ControlSetting::PhysicsVariants => "--physics-variants",
            ControlSetting::MaxEvaluations => "--max-evaluations",
            ControlSetting::FMin => "--f-min",
        }
    }
}
