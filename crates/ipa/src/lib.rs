//! `ipa`: a physics-based simulator of the Intelligent Pneumatic Actuator (IPA) of the paper, and the
//! design of identification experiments.
//!
//! - [`Ipa`] (module [`plant`]): double-acting cylinder ([`cylinder`]) with two PWM-driven on/off valves
//!   ([`valve`]), seal friction with stiction ([`friction`]), end stops, an optical encoder ([`encoder`]);
//!   integrated by adaptive Dormand–Prince 5(4) steps with located events ([`dynamics`], [`plant`]; the
//!   earlier classical RK4 is kept as the reference). Parameters in [`PlantConfig`] ([`config`], TOML).
//! - [`spec::plant_from_spec`]: `ipa`, `paper` or `model:FILE` behind [`sysid_core::Plant`].
//! - [`experiment`]: one open-loop experiment (input design, plant, noise) as `simulate` runs it.
//! - [`fleet`]: a fleet of actuators drawn around the defaults, some with wearing valves (`simulate --fleet`).
//! - [`calibrate`]: the physics plant fitted to a measured record (a digital twin, `ipa-sysid calibrate`).
//! - [`input`]: staircase, PRBS, APRBS, multisine, step and file inputs.
//!
//! See `docs/plant.md` for the equations, the parameters and their sources.

pub mod calibrate;
pub mod config;
pub mod cylinder;
pub mod dynamics;
pub mod encoder;
pub mod error;
pub mod experiment;
pub mod fleet;
pub mod friction;
pub mod input;
pub mod plant;
pub mod spec;
pub mod valve;

pub use config::PlantConfig;
pub use error::{IpaError, IpaSetting};
pub use experiment::{Experiment, Record};
pub use input::{generate, InputSpec};
pub use plant::Ipa;
pub use spec::{plant_from_spec, plant_from_spec_with_ts, PlantLimits, PlantSpec, DEFAULT_TS_S};
