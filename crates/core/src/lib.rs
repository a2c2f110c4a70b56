//! `sysid-core`: what every part of ipa-sysid stands on — data records, model structures, their
//! parameterisation, simulation and prediction, validation metrics, and the [`Plant`] trait. No estimator lives here (crate `sysid`), and no application concern (files written
//! atomically, progress bars, parallelism, command-line flags).
//!
//! Data flows one way: [`data`] → model structure ([`structure`], [`nonlinearity`]) → (estimator, in
//! `sysid`) → fitted [`Model`] → [`metrics`] / simulation / [`plant`].
//!
//! Symbols follow the paper (Hammerstein model of the Intelligent Pneumatic Actuator): u is the valve
//! command in PWM counts (±255), y the position in mm, Ts the sampling period in s, x = f(u) the output
//! of the static nonlinearity (the valve deadzone b_l, b_r, m_l, m_r), A(q) y = B(q) x + c + e.

pub mod data;
pub mod detrend;
pub mod error;
pub mod format;
pub mod ls;
pub mod metrics;
pub mod model;
pub mod model_file;
pub mod narx;
pub mod nonlinearity;
pub mod param;
pub mod plant;
pub mod stability;
pub mod stop;
pub mod structure;

pub use data::Dataset;
pub use error::{ColumnOrigin, PlantError, Setting, SysidError};
pub use model::{
    DataRange, InputChannel, Model, ModelKind, ModelPlant, NoiseModel, Orders, Provenance,
    TermSizes,
};
pub use nonlinearity::{
    Deadzone, DeadzoneSaturation, PiecewiseLinear, Polynomial, Saturation, StaticNonlinearity,
};
pub use param::{ParamName, Parameterisation};
pub use plant::{run_open_loop, Plant};
pub use stability::Stability;
pub use stop::Stop;
pub use structure::Structure;
