//! `sysid-control`: the control that needs the estimators, kept out of `control` so that `control`
//! (like `ipa`) depends on `sysid-core` alone (issue 10's layout; docs/architecture.md).
//!
//! - [`tuning`]: `ipa-sysid tune` / `ipa_sysid.tune` from end to end — the plants to tune over (an
//!   identified model and its variants, or a physics twin, whose Hammerstein model it identifies by
//!   output error, [`tuning::twin_model`]), the search ([`control::tune::tune`]), the margins and the
//!   verification beside the paper's PI.
//! - [`adaptive`]: `control --adaptive`, the deadzone inverse following the online recursive
//!   Hammerstein estimate ([`sysid::online::Tracker`]) where that estimate deserves it.
//!
//! ```
//! use control::{DeadzoneChange, DeadzoneCompensator, PiSettings, Profile, SlopeMode, Widened};
//! use sysid_control::{run_adaptive, AdaptiveSettings};
//! use sysid_core::{Model, ModelPlant};
//! let model = Model::paper();
//! let change = DeadzoneChange { at_s: 5.0, widen_counts: 10.0 };
//! let mut plant = Widened::new(Box::new(ModelPlant::new(model.clone(), "paper").unwrap()), change);
//! let comp = DeadzoneCompensator::new(*model.deadzone().unwrap(), SlopeMode::Shift, 255.0).unwrap();
//! let mut pi = PiSettings::paper().build(0.01).unwrap();
//! let profile = Profile::Fixed { setpoint_mm: 50.0 };
//! let settings = AdaptiveSettings::default();
//! let run = run_adaptive(&mut plant, &mut pi, comp, &settings, &profile, 10.0, 0.0).unwrap();
//! assert_eq!(run.trace.y.len(), run.deadzones.len());
//! ```

pub mod adaptive;
pub mod tuning;

pub use adaptive::{run_adaptive, AdaptiveRun, AdaptiveSettings, BranchCounts};
