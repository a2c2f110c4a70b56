//! Adaptive deadzone compensation (`control --adaptive`): the deadzone inverse between the PI controller
//! and the valve follows the online recursive Hammerstein estimate ([`sysid::online::Tracker`]) during
//! the run.
//!
//! At each sample k the PI output u_pi(k) goes through the current compensator (its deadzone as in
//! [`DeadzoneCompensator`]), the command u(k) is applied, and the pair (u(k), y(k)) — the same pairing
//! as an identification record — is pushed into the tracker. Once the tracker has made
//! [`AdaptiveSettings::min_updates`] updates since its start (or since its last detected change), its
//! deadzone estimate replaces the compensator's from the next sample on, provided it can be inverted
//! (b_l ≤ 0 ≤ b_r, positive slopes; an estimate that cannot is counted in [`AdaptiveRun::rejected`] and
//! the previous compensator is kept). A change detected by the tracker restarts its covariance, so the
//! estimate follows a valve whose deadzone has changed; until it has made `min_updates` new updates the
//! compensator keeps its last deadzone.

use sysid_core::Deadzone;

use crate::closed_loop::{run_with, Trace};
use crate::{ControlError, DeadzoneCompensator, PiController, Profile};
use sysid::online::{DeadzoneStart, TrackSettings, Tracker};
use sysid_core::Plant;

/// Settings of the adaptation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveSettings {
    /// The online estimator (its structure must be Hammerstein; its start deadzone is replaced by the
    /// initial compensator's when that one has b_l < 0 < b_r).
    pub tracker: TrackSettings,
    /// Estimator updates (since its start or its last detected change) before its deadzone is used.
    pub min_updates: usize,
}

impl Default for AdaptiveSettings {
    /// The paper's structure with forgetting ρ = 0.995 (a memory of about 200 samples, 2 s at 100 Hz)
    /// and the trace windup guard, the default change detector, and 200 updates before an estimate is
    /// used.
    fn default() -> Self {
        AdaptiveSettings {
            tracker: TrackSettings {
                forgetting: 0.995,
                ..TrackSettings::default()
            },
            min_updates: 200,
        }
    }
}

/// A closed-loop run with adaptive compensation.
#[derive(Debug, Clone)]
pub struct AdaptiveRun {
    /// The run (t, r, u, y).
    pub trace: Trace,
    /// The compensator's deadzone at every sample (the one that made u(k)).
    pub deadzones: Vec<Deadzone>,
    /// Samples at which the tracker detected a change.
    pub change_points: Vec<usize>,
    /// Samples at which an estimate could not be inverted and the previous compensator was kept.
    pub rejected: usize,
}

/// Runs the loop as [`crate::closed_loop::run`] does, with the compensator `initial` adapted during the
/// run (see the module documentation).
pub fn run_adaptive(
    plant: &mut dyn Plant,
    controller: &mut PiController,
    initial: DeadzoneCompensator,
    settings: &AdaptiveSettings,
    profile: &Profile,
    duration_s: f64,
    y0_mm: f64,
) -> Result<AdaptiveRun, ControlError> {
    let ts = plant.ts();
    let mut tracker_settings = settings.tracker;
    let d0 = initial.deadzone;
    if d0.b_l < 0.0 && d0.b_r > 0.0 {
        tracker_settings.start = DeadzoneStart {
            b_l0: d0.b_l,
            b_r0: d0.b_r,
            limit: initial.u_max,
        };
    }
    let mut tracker = Tracker::new(tracker_settings)
        .map_err(|e| ControlError::Config(format!("adaptive compensation: {e}")))?;
    let mut comp = initial;
    let mut deadzones = Vec::new();
    let mut rejected = 0;
    let trace = run_with(
        plant,
        controller,
        profile,
        duration_s,
        y0_mm,
        &mut |k, u_pi, y| {
            let u = comp.apply(u_pi);
            deadzones.push(comp.deadzone);
            tracker.push(u, y).map_err(|e| {
                ControlError::Numerical(format!("sample {k}: the online estimate: {e}"))
            })?;
            if tracker.updates_since_restart() >= settings.min_updates {
                let estimate = tracker.model(ts).ok().and_then(|m| m.deadzone().copied());
                match estimate.map(|d| DeadzoneCompensator::new(d, comp.slope_mode, comp.u_max)) {
                    Some(Ok(c)) => {
                        comp = DeadzoneCompensator {
                            threshold_counts: comp.threshold_counts,
                            ..c
                        }
                    }
                    _ => rejected += 1,
                }
            }
            Ok(u)
        },
    )?;
    Ok(AdaptiveRun {
        trace,
        deadzones,
        change_points: tracker.change_points().to_vec(),
        rejected,
    })
}
