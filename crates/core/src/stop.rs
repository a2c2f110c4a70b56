//! A caller's request to stop a long computation ([`Stop`]): the one cancellation hook of the
//! identification, NARX term selection, fleet windows, tuning, calibration and a plant's simulation
//! (an open-loop experiment, a closed loop).
//!
//! The computation polls [`Stop::check`] at its natural boundaries (each output-error or IV iteration,
//! each RLS pass and every few thousand samples of a pass, each FROLS term, each window, each tuning or
//! calibration evaluation, every few thousand steps of a plant wrapped in
//! [`crate::plant::Stoppable`]); a poll is one relaxed atomic load. When the caller has asked it to stop
//! ([`Stop::request`], from another thread: the Python binding's signal watcher), the next poll returns
//! [`SysidError::Cancelled`] and the computation ends with it: no partial result leaves the library.
//! The command line passes [`Stop::never`] (its SIGINT ends the process).

use crate::SysidError;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// Whether the caller wants a long computation to stop, shared between the computation (which polls it)
/// and whoever asks it to stop (another thread). Cloning shares the same request. [`Stop::never`] (the
/// default) is never requested and costs one branch per poll.
///
/// A stop check is no part of the settings' value: two [`Stop`]s compare equal, are skipped by
/// model files and reports, and `Debug` shows only whether a stop was requested.
#[derive(Clone, Default)]
pub struct Stop(Option<Arc<AtomicBool>>);

/// How many samples a per-sample loop runs between two polls of its [`Stop`] (a counter, not a clock:
/// 4096 samples of RLS or simulation are well under a millisecond).
pub const SAMPLES_PER_POLL: usize = 4096;

impl Stop {
    /// A stop nobody can request (the command line's, and the default).
    pub fn never() -> Self {
        Stop(None)
    }

    /// A stop that [`Stop::request`] on any clone of it sets.
    pub fn new() -> Self {
        Stop(Some(Arc::new(AtomicBool::new(false))))
    }

    /// Asks the computations polling this stop (or a clone of it) to end with
    /// [`SysidError::Cancelled`]; the request stays (a later poll sees it too).
    pub fn request(&self) {
        if let Some(flag) = &self.0 {
            flag.store(true, Ordering::Relaxed);
        }
    }

    /// True once [`Stop::request`] was called on this stop or a clone of it.
    pub fn requested(&self) -> bool {
        self.0.as_ref().is_some_and(|f| f.load(Ordering::Relaxed))
    }

    /// `Err(`[`SysidError::Cancelled`]`)` when a stop was requested: `stop.check()?` at a loop's
    /// boundary ends the computation there.
    pub fn check(&self) -> Result<(), SysidError> {
        if self.requested() {
            Err(SysidError::Cancelled)
        } else {
            Ok(())
        }
    }

    /// [`Stop::check`] every [`SAMPLES_PER_POLL`]-th value of the counter `k` (a per-sample loop's
    /// index): `stop.every(k)?`.
    pub fn every(&self, k: usize) -> Result<(), SysidError> {
        if k % SAMPLES_PER_POLL == 0 {
            self.check()
        } else {
            Ok(())
        }
    }
}

impl PartialEq for Stop {
    /// Always true: a stop check is no part of the settings it travels with.
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl std::fmt::Debug for Stop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.0 {
            None => f.write_str("Stop::never()"),
            Some(_) => write!(f, "Stop {{ requested: {} }}", self.requested()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_request_on_a_clone_is_seen_by_the_original_and_stays() {
        let stop = Stop::new();
        assert!(stop.check().is_ok());
        stop.clone().request();
        assert!(matches!(stop.check(), Err(SysidError::Cancelled)));
        assert!(matches!(stop.check(), Err(SysidError::Cancelled)));
    }

    #[test]
    fn never_cannot_be_requested() {
        let stop = Stop::never();
        stop.request();
        assert!(!stop.requested());
        assert!(stop.check().is_ok());
    }

    #[test]
    fn every_polls_only_at_multiples_of_the_period() {
        let stop = Stop::new();
        stop.request();
        assert!(stop.every(1).is_ok());
        assert!(stop.every(SAMPLES_PER_POLL - 1).is_ok());
        assert!(stop.every(0).is_err());
        assert!(stop.every(3 * SAMPLES_PER_POLL).is_err());
    }
}
