//! The JSON summary of an identification (`identify --json`), also embedded by `reproduce` in
//! `summary.json` (`models.arx`, `models.hammerstein`).

use serde::{Deserialize, Serialize};

use crate::estimate::{EstimatorSettings, Fitted, Identification, Method, Param};
use sysid_core::metrics::Metrics;
use sysid_core::{Model, SysidError};

/// A pole p = re + i·im of the linear block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pole {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
    /// Modulus |p| (stable when < 1).
    pub abs: f64,
}

/// How the model was estimated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EstimationInfo {
    /// `ls` or `rls`.
    pub method: Method,
    /// Key-term iterations (LS) or passes (RLS).
    pub iterations: usize,
    /// See [`Fitted::converged`].
    pub converged: bool,
    /// RLS forgetting factor ρ (RLS only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub forgetting: Option<f64>,
    /// RLS P(0) scale (RLS only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub p0: Option<f64>,
    /// σ̂² of the one-step prediction errors.
    pub noise_variance: f64,
    /// Remarks (limit cycle, best iterate kept...).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub note: Option<String>,
}

/// Metrics on the estimation record and, when given, on the validation record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetricsPair {
    /// On the estimation data.
    pub estimation: Metrics,
    /// On the `--validation` data.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub validation: Option<Metrics>,
}

/// The whole `identify --json` document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifyReport {
    /// The fitted model (the same object a model file holds).
    pub model: Model,
    /// Physical parameters with standard deviations.
    pub parameters: Vec<Param>,
    /// Poles of the linear block, largest modulus first.
    pub poles: Vec<Pole>,
    /// All poles strictly inside the unit circle.
    pub stable: bool,
    /// Estimation record.
    pub estimation: EstimationInfo,
    /// Validation metrics.
    pub metrics: MetricsPair,
}

impl IdentifyReport {
    /// Assembles the report of a fit.
    pub fn new(
        fit: &Fitted,
        settings: &Identification,
        est: Metrics,
        val: Option<Metrics>,
    ) -> Self {
        let rls = match settings.estimator {
            EstimatorSettings::Rls(r) if fit.method == Method::Rls => Some(r),
            _ => None,
        };
        IdentifyReport {
            model: fit.model.clone(),
            parameters: fit.params.clone(),
            poles: poles(&fit.model),
            stable: fit.model.is_stable(),
            estimation: EstimationInfo {
                method: fit.method,
                iterations: fit.iterations,
                converged: fit.converged(),
                forgetting: rls.map(|r| r.forgetting),
                p0: rls.map(|r| r.p0),
                noise_variance: fit.noise_variance,
                note: fit.note(),
            },
            metrics: MetricsPair {
                estimation: est,
                validation: val,
            },
        }
    }

    /// Pretty JSON text (ending with a newline).
    pub fn to_json(&self) -> Result<String, SysidError> {
        serde_json::to_string_pretty(self)
            .map(|s| s + "\n")
            .map_err(|e| SysidError::Numerical(format!("the summary could not be serialised: {e}")))
    }
}

/// The poles of a model as JSON-friendly values.
pub fn poles(model: &Model) -> Vec<Pole> {
    model
        .poles()
        .iter()
        .map(|p| Pole {
            re: p.re,
            im: p.im,
            abs: p.norm(),
        })
        .collect()
}
