//! `control`: closed-loop PI position control of the Intelligent Pneumatic Actuator (or any plant behind
//! [`sysid_core::Plant`]), set-point profiles and step-response metrics.
//!
//! Data flow: a [`Profile`] gives the set-point r(t); a [`PiController`] (built from [`PiSettings`]) turns
//! e = r - y into the command u, optionally passed through a [`DeadzoneCompensator`];
//! [`closed_loop::run`] drives the plant and records a [`Trace`]; [`StepMetrics`] summarise it as MATLAB
//! `stepinfo` would; [`tune`] searches a controller over closed-loop simulations of a plant and its
//! variants. [`Widened`] is a plant whose deadzone widens mid-run. What needs the estimators — `tune`'s
//! pipeline from a twin (its model by output error) and the adaptive compensator that follows the
//! online estimate — is in the crate `sysid-control`: this crate depends on `sysid-core`, not on
//! `sysid` (issue 10).
//!
//! ```
//! use control::{closed_loop, PiSettings, Profile, StepMetrics};
//! let mut plant = sysid_core::ModelPlant::new(sysid_core::Model::paper(), "paper model").unwrap();
//! let mut pi = PiSettings::paper().build(0.01).unwrap();
//! let profile = Profile::Fixed { setpoint_mm: 50.0 };
//! let trace = closed_loop::run(&mut plant, &mut pi, None, &profile, 10.0, 0.0).unwrap();
//! let m = StepMetrics::compute(&trace.t, &trace.y, trace.y[0], 50.0).unwrap();
//! assert!(m.overshoot_percent.unwrap() < 10.0);
//! ```

pub mod closed_loop;
pub mod compensator;
pub mod error;
pub mod metrics;
pub mod oracle;
pub mod pi;
pub mod position;
pub mod profile;
pub mod response;
pub mod trust;
pub mod tune;
pub mod widening;

pub use closed_loop::Controller;
pub use closed_loop::Trace;
pub use compensator::{DeadzoneCompensator, SlopeMode};
pub use error::{ControlError, ControlSetting};
pub use metrics::{
    metrics_for_steps, run_metrics, EssVerdict, RunMetrics, StepMetrics, StepSegment, Unsettled,
};
pub use pi::{AntiWindup, AntiWindupScheme, IntegralForm, PiController, PiSettings};
pub use position::{ControllerFile, ControllerSettings, PositionController};
pub use profile::Profile;
pub use trust::{loop_warnings, LoopFacts, Units};
pub use widening::{DeadzoneChange, Widened};
