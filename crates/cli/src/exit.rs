//! The one place that turns errors into messages and exit codes.
//!
//! Exit codes (documented in `--help` and docs/reliability.md):
//! - 0: success;
//! - 1: numerical failure — non-finite values, loss of positive definiteness in RLS, an unstable
//!   simulation: the input was well-formed but the computation could not produce finite numbers;
//! - 2: bad usage or bad input — a malformed or missing file, a flag out of range, data that cannot
//!   support the estimate (too short, not persistently exciting). clap also uses 2 for malformed flags.
//!
//! Every library error type says which kind it is through `is_numerical()`: [`sysid::SysidError`],
//! [`ipa::IpaError`], [`control::ControlError`] and [`report::ReportError`](::report::ReportError). Any other error (I/O at the
//! binary's edge, `anyhow::bail!` in a subcommand) is a usage/input error.

use std::process::ExitCode;

/// Exit code of a numerical failure.
pub const NUMERICAL: u8 = 1;
/// Exit code of bad usage or bad input.
pub const USAGE: u8 = 2;

/// Prints `error: ...` with its chain of causes to stderr and returns the exit code.
///
/// A cause whose text is already part of the message above it (e.g. the operating system's error after
/// `file: error`) is not repeated.
pub fn report(e: &anyhow::Error) -> ExitCode {
    eprintln!("error: {}", render(e.as_ref()));
    let mut shown = render(e.as_ref());
    for cause in e.chain().skip(1) {
        let text = render(cause);
        if !shown.contains(&text) {
            eprintln!("  caused by: {text}");
        }
        shown = text;
    }
    ExitCode::from(code(e))
}

/// `--strict` was given and the result carries warnings; the output files it did not write.
#[derive(Debug)]
pub struct StrictWarnings {
    /// How many warnings.
    pub warnings: usize,
    /// The output files left unwritten (flag and path), so that an earlier one stays.
    pub not_written: Vec<String>,
}

impl std::fmt::Display for StrictWarnings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} warning(s) and --strict: the result is not to be trusted without review",
            self.warnings
        )?;
        if !self.not_written.is_empty() {
            write!(
                f,
                "; not written (any earlier file there is unchanged): {}",
                self.not_written.join(", ")
            )?;
        }
        Ok(())
    }
}

impl std::error::Error for StrictWarnings {}

/// With `--strict`, turns warnings into an error (exit code 1); otherwise Ok (for a command without
/// output files; the others use `common::write_outputs`).
pub fn strict(strict: bool, warnings: usize) -> anyhow::Result<()> {
    if strict && warnings > 0 {
        return Err(StrictWarnings {
            warnings,
            not_written: Vec::new(),
        }
        .into());
    }
    Ok(())
}

/// The message of one error, with the library's settings named by their flags.
pub fn render(e: &(dyn std::error::Error + 'static)) -> String {
    // Every error the program prints passes here: what it echoes of the input is capped once
    // (`sysid::error::clip`: a 200 kB TOML line, a 309-digit number).
    sysid::error::clip(&render_whole(e))
}

/// [`render`] before the cap.
fn render_whole(e: &(dyn std::error::Error + 'static)) -> String {
    if let Some(s) = e.downcast_ref::<sysid::SysidError>() {
        return s.render_flags();
    }
    if let Some(c) = e.downcast_ref::<control::ControlError>() {
        return c.render(&|setting| setting.flag().to_string());
    }
    if let Some(i) = e.downcast_ref::<ipa::IpaError>() {
        return i.render(&|setting| setting.flag().to_string());
    }
    e.to_string()
}

/// The whole chain of `e` on one line, as `{e:#}` prints it, with settings named by their flags.
pub fn render_chain(e: &anyhow::Error) -> String {
    e.chain().map(render).collect::<Vec<_>>().join(": ")
}

/// The exit code of `e`: [`NUMERICAL`] when any error in its chain is a numerical failure of one of
/// the libraries, [`USAGE`] otherwise.
pub fn code(e: &anyhow::Error) -> u8 {
    if e.chain().any(is_numerical) {
        NUMERICAL
    } else {
        USAGE
    }
}

fn is_numerical(c: &(dyn std::error::Error + 'static)) -> bool {
    if c.downcast_ref::<StrictWarnings>().is_some() {
        return true;
    }
    if let Some(s) = c.downcast_ref::<sysid::SysidError>() {
        return s.is_numerical();
    }
    if let Some(s) = c.downcast_ref::<ipa::IpaError>() {
        return s.is_numerical();
    }
    if let Some(s) = c.downcast_ref::<control::ControlError>() {
        return s.is_numerical();
    }
    if let Some(s) = c.downcast_ref::<::report::ReportError>() {
        return s.is_numerical();
    }
    if let Some(s) = c.downcast_ref::<ipa_reproduce::ReproduceError>() {
        return s.is_numerical();
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    // Numerical failures of every library map to 1, whatever context is added around them.
    #[test]
    fn numerical_errors_of_every_library_exit_1() {
        let errs: Vec<anyhow::Error> = vec![
            sysid::SysidError::Numerical("x".into()).into(),
            ipa::IpaError::Numerical("x".into()).into(),
            control::ControlError::Numerical("x".into()).into(),
            ipa_reproduce::ReproduceError::Sysid(sysid::SysidError::Numerical("x".into())).into(),
            ipa_reproduce::ReproduceError::Control(control::ControlError::Numerical("x".into()))
                .into(),
            anyhow::Error::from(ipa::IpaError::Numerical("x".into())).context("while simulating"),
        ];
        for e in &errs {
            assert_eq!(code(e), NUMERICAL, "{e:#}");
        }
    }

    // Input and usage errors of every library, and plain messages, map to 2.
    #[test]
    fn input_errors_of_every_library_exit_2() {
        let errs: Vec<anyhow::Error> = vec![
            sysid::SysidError::setting(sysid::Setting::Other("--p0"), 0, "a positive number")
                .into(),
            sysid::SysidError::Data("too short".into()).into(),
            ipa::IpaError::Config("bad".into()).into(),
            control::ControlError::setting(
                control::ControlSetting::Kp,
                f64::NAN,
                "a finite number",
            )
            .into(),
            ipa_reproduce::ReproduceError::Sysid(sysid::SysidError::Data("x".into())).into(),
            ipa_reproduce::ReproduceError::Ipa(ipa::IpaError::Config("x".into())).into(),
            anyhow::anyhow!("--out x: is a file"),
        ];
        for e in &errs {
            assert_eq!(code(e), USAGE, "{e:#}");
        }
    }
}

#[cfg(test)]
mod render_tests {
    use super::*;

    // A library setting error reads with the flag the user typed, not the library's name.
    #[test]
    fn setting_errors_name_the_flag() {
        let e: anyhow::Error =
            sysid::SysidError::setting(sysid::Setting::Na, 200, "an order of at most 100").into();
        assert_eq!(
            render(e.as_ref()),
            "invalid setting --na = 200: an order of at most 100"
        );
        assert_eq!(
            e.to_string(),
            "invalid setting na = 200: an order of at most 100"
        );
        let c = control::ControlError::setting(control::ControlSetting::UMax, 0, "> 0");
        let e = anyhow::Error::from(c).context("cannot build the controller");
        assert_eq!(
            render_chain(&e),
            "cannot build the controller: invalid setting --u-max = 0: > 0"
        );
    }
}
