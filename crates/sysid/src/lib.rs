//! `sysid`: the estimators of ipa-sysid, behind one trait.
//!
//! Unfitted settings (one type per method: [`LeastSquares`], [`RecursiveLeastSquares`],
//! [`OutputError`], [`InstrumentalVariables`]) → [`Estimator::fit`] → a [`Fitted`] model that carries
//! its diagnostics (termination, notes), the same type whatever the method, so that the safeguards
//! against a wrongly trusted estimate live in one place ([`estimate::identify`]).
//!
//! The model structures, data records, simulation and validation metrics are those of `sysid-core`,
//! re-exported here for convenience. Recursive updates share one abstraction ([`rls::RecursiveUpdate`]).

pub mod branches;
pub mod delay;
pub mod estimate;
pub mod iv;
pub use sysid_core::ls;
pub mod merge;
pub mod miso;
pub mod oe;
pub mod online;
pub mod options;
pub mod order;
pub mod residuals;
pub mod rls;
pub mod rls_ud;
pub mod stream;
pub mod summary;
pub mod trust;
pub mod warnings;
pub mod windup;

pub use estimate::{
    identify, Estimator, EstimatorSettings, Fitted, Identification, InstrumentalVariables,
    LeastSquares, Method, Note, OutputError, Param, Passes, RecursiveLeastSquares, Termination,
};
pub use options::IdentifyOptions;
pub use sysid_core::{
    data, detrend, metrics, model, model_file, nonlinearity, param, plant, structure, Dataset,
    Deadzone, InputChannel, Model, ModelKind, ModelPlant, Orders, ParamName, Parameterisation,
    Plant, PlantError, Setting, StaticNonlinearity, Structure, SysidError,
};
pub use warnings::Warning;
