//! `sysid`: single-input single-output system identification for the Intelligent Pneumatic Actuator
//! (and any other SISO system with a CSV of input/output data).
//!
//! Data flows one way: [`data`] -> model structure ([`model`], [`deadzone`]) -> estimator
//! ([`estimate`]) -> fitted [`Model`] -> [`validation`] / simulation / [`plant`].

pub mod bench;
pub mod branches;
pub mod data;
pub mod deadzone;
pub mod error;
pub mod estimate;
pub mod fast_ls;
pub mod iv;
pub mod ls;
pub mod model;
pub mod model_file;
pub mod montecarlo;
pub mod oe;
pub mod order;
pub mod output;
pub mod plant;
pub mod regressor;
pub mod residuals;
pub mod rls;
pub mod rls_ud;
pub mod summary;
pub mod validation;
pub mod windup;

pub use data::Dataset;
pub use deadzone::Deadzone;
pub use error::SysidError;
pub use model::{Model, ModelKind, ModelPlant, Orders};
pub use plant::{run_open_loop, Plant};
