//! The options of one identification as a user gives them (the flags of `ipa-sysid identify`, the
//! keyword arguments of the Python `ipa_sysid.identify`), turned into an [`Identification`] in one place.

use crate::estimate::{
    EstimatorSettings, Identification, InstrumentalVariables, LeastSquares, OutputError, Passes,
    RecursiveLeastSquares,
};
use crate::fitted::Method;
use crate::rls_ud::RlsForm;
use crate::windup::Windup;
use sysid_core::{ModelKind, Orders, Structure};

/// The user-facing options of an identification; each field is the flag (and keyword) of that name.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdentifyOptions {
    /// Model structure (`hammerstein` or `arx`).
    pub model: ModelKind,
    /// na: number of poles (order of A(q)).
    pub na: usize,
    /// nb: number of B(q) coefficients.
    pub nb: usize,
    /// nk: input delay in samples.
    pub nk: usize,
    /// The estimator.
    pub method: Method,
    /// ρ: RLS (and IV) forgetting factor in (0, 1].
    pub forgetting: f64,
    /// P(0) = p0 · I: RLS (and IV) initial covariance scale.
    pub p0: f64,
    /// RLS passes over the data: until settled (`auto`, the default) or a fixed number (1 = the
    /// paper's single pass).
    pub passes: Passes,
    /// Iteration cap of the key-term LS and output-error iterations.
    pub max_iterations: usize,
    /// RLS covariance form.
    pub rls_form: RlsForm,
    /// RLS covariance-windup protection.
    pub windup: Windup,
    /// Bound T on tr P for `windup = trace` (default p0 · number of parameters).
    pub max_trace: Option<f64>,
    /// IV stages.
    pub iv_stages: usize,
    /// Estimate a constant term c in the linear block.
    pub offset: bool,
    /// Replace a diverging or far worse Hammerstein estimate by the linear start (see
    /// [`Identification::fallback`]).
    pub fallback: bool,
    /// The most memory the estimation's matrices may take (`--max-memory`, `max_memory_gb`).
    pub max_memory: sysid_core::ls::MemoryBudget,
}

impl Default for IdentifyOptions {
    /// The command line's defaults: Hammerstein, na = 3, nb = 1, nk = 1, RLS with ρ = 1, p0 = 1e6,
    /// passes until the estimate settles.
    fn default() -> Self {
        IdentifyOptions {
            model: ModelKind::Hammerstein,
            na: 3,
            nb: 1,
            nk: 1,
            method: Method::Rls,
            forgetting: 1.0,
            p0: 1e6,
            passes: Passes::AUTO,
            max_iterations: 100,
            rls_form: RlsForm::default(),
            windup: Windup::default(),
            max_trace: None,
            iv_stages: 10,
            offset: false,
            fallback: false,
            max_memory: sysid_core::ls::MemoryBudget::default(),
        }
    }
}

impl IdentifyOptions {
    /// The identification these options describe (not yet checked: see [`Identification::check`]).
    pub fn settings(&self) -> Identification {
        let start = LeastSquares {
            max_iterations: self.max_iterations,
            ..LeastSquares::default()
        };
        let estimator = match self.method {
            Method::Ls => EstimatorSettings::Ls(start),
            Method::Rls => EstimatorSettings::Rls(RecursiveLeastSquares {
                forgetting: self.forgetting,
                p0: self.p0,
                passes: self.passes,
                form: self.rls_form,
                windup: self.windup,
                max_trace: self.max_trace,
                record_history: false,
            }),
            Method::Oe => EstimatorSettings::Oe(OutputError {
                start,
                max_iterations: self.max_iterations,
                ..OutputError::default()
            }),
            Method::Iv => EstimatorSettings::Iv(InstrumentalVariables {
                start,
                forgetting: self.forgetting,
                p0: self.p0,
                stages: self.iv_stages,
            }),
        };
        Identification {
            structure: Structure {
                kind: self.model,
                orders: Orders {
                    na: self.na,
                    nb: self.nb,
                    nk: self.nk,
                },
                offset: self.offset,
            },
            inputs: Vec::new(),
            estimator,
            // A one-sided input (never negative or never positive) drops the unexcited deadzone branch
            // and says so in the report's note.
            drop_unexcited_branch: true,
            fallback: self.fallback,
            output: None,
            max_memory: self.max_memory,
            cancel: sysid_core::Stop::never(),
        }
    }
}
