//! `sysid`: the estimators of ipa-sysid, behind one trait.
//!
//! Unfitted settings (one type per method: [`LeastSquares`], [`RecursiveLeastSquares`],
//! [`OutputError`], [`InstrumentalVariables`]) → [`Estimator::fit`] → a [`Fitted`] model that carries
//! its diagnostics (termination, notes), the same type whatever the method, so that the safeguards
//! against a wrongly trusted estimate live in one place ([`estimate::identify`]). One record or several
//! (merged experiments), one input or several: one path.
//!
//! Modules by concern:
//! - vocabulary: [`fitted`] (method, parameters, termination, notes, the fitted result), [`warnings`];
//! - structure: [`blocks`] (static nonlinearities as blocks of the estimation), [`regression`] (the one
//!   key-term regression over inputs and records);
//! - identification: [`problem`] (what is fitted, the [`Estimator`] trait), [`methods`] (each method's
//!   settings and fit), [`estimate`] ([`Identification`], [`identify`], the safeguards), [`oe`], [`iv`], [`rls`], [`rls_ud`], [`windup`];
//! - around it: [`order`], [`delay`], [`residuals`],
//!   [`stream`] (records read in passes), [`online`] (tracking).
//!
//! The model structures, data records, simulation and validation metrics are those of `sysid-core`,
//! re-exported here for convenience. Recursive updates share one abstraction ([`rls::RecursiveUpdate`]).

pub mod blocks;
pub mod delay;
pub mod estimate;
pub mod fitted;
pub mod iv;
pub use sysid_core::ls;
pub mod methods;
pub mod narx;
pub mod oe;
pub mod online;
pub mod options;
pub mod order;
pub mod problem;
pub mod regression;
pub mod residuals;
pub mod rls;
pub mod rls_ud;
pub mod search;
pub mod stream;
pub mod trust;
pub mod warnings;
pub mod wiener;
pub mod windup;

pub use blocks::NonlinearityKind;
pub use estimate::{
    identify, Estimator, EstimatorSettings, Identification, InputSpec, InstrumentalVariables,
    LeastSquares, OutputError, Passes, RecursiveLeastSquares,
};
pub use fitted::{EstimatorSetting, Fitted, Method, Note, Param, Termination};
pub use options::IdentifyOptions;
pub use sysid_core::{
    data, detrend, error, metrics, model, model_file, narx as narx_model, nonlinearity, param,
    plant, structure, ColumnOrigin, DataRange, Dataset, Deadzone, InputChannel, Model, ModelKind,
    ModelPlant, Orders, ParamName, Parameterisation, Plant, PlantError, Setting,
    StaticNonlinearity, Stop, Structure, SysidError, TermSizes,
};
pub use warnings::Warning;
