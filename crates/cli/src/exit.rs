//! The one place that turns errors into messages and exit codes.
//!
//! Exit codes: 0 success; 1 numerical failure (non-finite values, loss of positive definiteness, an
//! unstable simulation); 2 bad usage or bad input (files, flags) — clap also uses 2 for malformed flags.

use std::process::ExitCode;

/// Prints `error: ...` with its chain of causes to stderr and returns the exit code.
pub fn report(e: &anyhow::Error) -> ExitCode {
    eprintln!("error: {e}");
    for cause in e.chain().skip(1) {
        eprintln!("  caused by: {cause}");
    }
    ExitCode::from(code(e))
}

fn code(e: &anyhow::Error) -> u8 {
    let numerical = e.chain().any(|c| {
        c.downcast_ref::<sysid::SysidError>().is_some_and(|s| s.is_numerical())
            || c.downcast_ref::<ipa::IpaError>().is_some_and(|s| s.is_numerical())
            || c.downcast_ref::<control::ControlError>().is_some_and(|s| s.is_numerical())
    });
    if numerical {
        1
    } else {
        2
    }
}
