//! Model validation (paper section II-D): fit %, RMSE, loss function, FPE and AIC of a model on a record.
//!
//! All sums run over rows k >= k0 = max(na, nk + nb − 1) (N = number of those rows):
//! - fit % = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) (paper eq. 13, MATLAB `compare`), ȳ the mean over the same rows,
//!   for the free-run simulation (`fit_sim_percent`) and the one-step prediction (`fit_pred_percent`);
//! - RMSE = √(Σ (y − ŷ)² / N), both;
//! - loss V = (1/N) Σ ½ ε² over the one-step prediction errors ε (paper eq. 14 — note the ½, which MATLAB's
//!   loss function does not have);
//! - FPE = (N + p)/(N − p) · V (paper eq. 15);
//! - AIC = ln(mean ε²) + 2p/N (MATLAB's normalised AIC);
//!
//! p = number of estimated parameters. A value that cannot be computed (constant output for fit, N <= p for
//! FPE, a simulation that diverges) is `None` (JSON `null`), never NaN.

use serde::{Deserialize, Serialize};

use crate::{Dataset, Model, SysidError};

/// Validation metrics of a model on one record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Fit % of the free-run simulation.
    pub fit_sim_percent: Option<f64>,
    /// Fit % of the one-step prediction.
    pub fit_pred_percent: Option<f64>,
    /// RMSE of the free-run simulation (units of y).
    pub rmse_sim: Option<f64>,
    /// RMSE of the one-step prediction (units of y).
    pub rmse_pred: f64,
    /// Loss V = (1/N) Σ ½ ε² (paper eq. 14).
    pub loss: f64,
    /// FPE = (N + p)/(N − p) V (paper eq. 15).
    pub fpe: Option<f64>,
    /// Normalised AIC = ln(mean ε²) + 2p/N.
    pub aic: Option<f64>,
    /// N: rows used (k >= k0).
    pub n: usize,
    /// p: estimated parameters.
    pub p: usize,
    /// Why a free-run value is missing (e.g. the simulation diverged).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// Fit % = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖), or `None` when y is constant.
pub fn fit_percent(y: &[f64], yhat: &[f64]) -> Option<f64> {
    let n = y.len().min(yhat.len());
    if n == 0 {
        return None;
    }
    let mean = y[..n].iter().sum::<f64>() / n as f64;
    let num: f64 = y
        .iter()
        .zip(yhat)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt();
    let den: f64 = y[..n]
        .iter()
        .map(|a| (a - mean) * (a - mean))
        .sum::<f64>()
        .sqrt();
    let f = 100.0 * (1.0 - num / den);
    (den > 0.0 && f.is_finite()).then_some(f)
}

/// RMSE √(mean (y − ŷ)²).
pub fn rmse(y: &[f64], yhat: &[f64]) -> f64 {
    let n = y.len().min(yhat.len()).max(1);
    (y.iter()
        .zip(yhat)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / n as f64)
        .sqrt()
}

/// Computes the validation metrics of `model` on `data`.
pub fn metrics(model: &Model, data: &Dataset) -> Result<Metrics, SysidError> {
    metrics_miso(model, &[&data.u], &data.y, &data.name)
}

/// [`metrics`] of a model with one input record per model input (MISO); `name` names the record.
pub fn metrics_miso(
    model: &Model,
    u: &[&[f64]],
    y_all: &[f64],
    name: &str,
) -> Result<Metrics, SysidError> {
    let k0 = model.k0();
    let p = model.parameter_count();
    if y_all.len() <= k0 {
        return Err(SysidError::Data(format!(
            "{name}: {} samples are not enough to validate a model with k0 = {k0}",
            y_all.len()
        )));
    }
    let y = &y_all[k0..];
    let n = y.len();
    let pred = model.predict_k(u, y_all, 1)?;
    let pred = &pred[k0..];
    let (sim, note) = match model.simulate_miso(u, y_all) {
        Ok(s) => (Some(s), None),
        Err(e) => (None, Some(e.to_string())),
    };
    let sse: f64 = y.iter().zip(pred).map(|(a, b)| (a - b) * (a - b)).sum();
    if !sse.is_finite() {
        return Err(SysidError::Numerical(format!(
            "{}: the squared prediction errors overflow f64 (values too large? rescale the data)",
            name
        )));
    }
    let mse = sse / n as f64;
    let loss = 0.5 * mse;
    let fpe = (n > p)
        .then(|| (n + p) as f64 / (n - p) as f64 * loss)
        .filter(|v| v.is_finite());
    let aic = (mse > 0.0)
        .then(|| mse.ln() + 2.0 * p as f64 / n as f64)
        .filter(|v| v.is_finite());
    Ok(Metrics {
        fit_sim_percent: sim.as_ref().and_then(|s| fit_percent(y, &s[k0..])),
        fit_pred_percent: fit_percent(y, pred),
        rmse_sim: sim
            .as_ref()
            .map(|s| rmse(y, &s[k0..]))
            .filter(|v| v.is_finite()),
        rmse_pred: mse.sqrt(),
        loss,
        fpe,
        aic,
        n,
        p,
        note,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    // y = (1, 2, 3), ȳ = 2, ‖y − ȳ‖ = √2; ŷ = (1, 2, 4): ‖y − ŷ‖ = 1 → fit = 100 (1 − 1/√2).
    #[test]
    fn fit_is_one_minus_error_norm_over_deviation_norm() {
        let f = fit_percent(&[1.0, 2.0, 3.0], &[1.0, 2.0, 4.0]).unwrap();
        assert!((f - 100.0 * (1.0 - 1.0 / 2f64.sqrt())).abs() < 1e-12);
    }

    #[test]
    fn fit_of_a_constant_output_is_undefined() {
        assert_eq!(fit_percent(&[2.0, 2.0], &[2.0, 2.0]), None);
    }
}

/// The outputs of a model on a record (`validate --out`): free-run simulation and K-step prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelOutput {
    /// Free-run simulation ŷ_sim(k) (MATLAB `compare`), `None` when it diverged.
    pub y_sim: Option<Vec<f64>>,
    /// K-step-ahead prediction ŷ(k | k − K) (MATLAB `predict(m, z, K)`); entries k < k0 are the data.
    pub y_pred: Vec<f64>,
    /// Fit % of `y_pred` over k >= k0.
    pub fit_pred_percent: Option<f64>,
}

/// Simulation and `horizon`-step prediction of `model` (horizon >= 1) from one input record per model
/// input and the measured output `y`.
pub fn model_output(
    model: &Model,
    u: &[&[f64]],
    y: &[f64],
    horizon: usize,
) -> Result<ModelOutput, SysidError> {
    let y_pred = model.predict_k(u, y, horizon)?;
    let k0 = model.k0().min(y_pred.len());
    let y_sim = model.simulate_miso(u, y).ok();
    let fit_pred_percent = fit_percent(&y[k0..y_pred.len()], &y_pred[k0..]);
    Ok(ModelOutput {
        y_sim,
        y_pred,
        fit_pred_percent,
    })
}
