//! Recursive least squares with a forgetting factor (paper eqs. 9–12).
//!
//! ```text
//! ε(k) = y(k) − φᵀ(k) θ̂(k−1)                         (11)
//! L(k) = P(k−1) φ(k) / (ρ + φᵀ(k) P(k−1) φ(k))        (10)
//! θ̂(k) = θ̂(k−1) + L(k) ε(k)                          (9)
//! P(k) = [P(k−1) − L(k) φᵀ(k) P(k−1)] / ρ             (12)
//! ```
//!
//! With θ̂(0) = θ₀ and P(0) = P₀, θ̂(N) is exactly the minimiser of
//! Σ_k ρ^(N−k) (y(k) − φᵀ(k)θ)² + ρ^N (θ − θ₀)ᵀ P₀⁻¹ (θ − θ₀).
//! The update allocates nothing: its work vectors are kept in the estimator.

use nalgebra::{DMatrix, DVector};

use crate::SysidError;

/// The RLS estimator state (θ̂, P) and its settings.
#[derive(Debug, Clone)]
pub struct Rls {
    /// θ̂: current parameter estimate.
    pub theta: DVector<f64>,
    /// P: the matrix proportional to the covariance of θ̂.
    pub p: DMatrix<f64>,
    /// ρ: forgetting factor in (0, 1].
    pub forgetting: f64,
    pphi: DVector<f64>,
}

impl Rls {
    /// A new estimator with θ̂(0) = 0 and P(0) = p0 · I.
    pub fn new(n_params: usize, forgetting: f64, p0: f64) -> Result<Self, SysidError> {
        check_settings(forgetting, p0)?;
        Ok(Rls {
            theta: DVector::zeros(n_params),
            p: DMatrix::identity(n_params, n_params) * p0,
            forgetting,
            pphi: DVector::zeros(n_params),
        })
    }

    /// Restarts the covariance at p0 · I while keeping θ̂ (a new pass over the data starts from the
    /// previous pass's estimate).
    pub fn restart_covariance(&mut self, p0: f64) {
        self.p.fill(0.0);
        self.p.fill_diagonal(p0);
    }

    /// One update with regressor φ(k) and measurement y(k); returns the a-priori error ε(k).
    ///
    /// `sample` is used in the error message when P loses positive definiteness or a value is not finite.
    pub fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        let n = self.theta.len();
        debug_assert_eq!(phi.len(), n);
        let mut eps = y;
        for i in 0..n {
            eps -= phi[i] * self.theta[i];
            let mut s = 0.0;
            for j in 0..n {
                s += self.p[(i, j)] * phi[j];
            }
            self.pphi[i] = s;
        }
        let mut denom = self.forgetting;
        for i in 0..n {
            denom += phi[i] * self.pphi[i];
        }
        if !(denom.is_finite() && denom > 0.0) || !eps.is_finite() {
            return Err(SysidError::Numerical(format!(
                "RLS lost positive definiteness or met a non-finite value at sample {sample} \
                 (denominator ρ + φᵀPφ = {denom}, error ε = {eps})"
            )));
        }
        let inv = 1.0 / denom;
        let inv_rho = 1.0 / self.forgetting;
        for i in 0..n {
            self.theta[i] += self.pphi[i] * inv * eps;
        }
        // Update the upper triangle and mirror it, so that P stays exactly symmetric in floating point.
        for j in 0..n {
            let vj = self.pphi[j] * inv;
            for i in 0..=j {
                let v = (self.p[(i, j)] - self.pphi[i] * vj) * inv_rho;
                self.p[(i, j)] = v;
                self.p[(j, i)] = v;
            }
        }
        Ok(eps)
    }
}

/// Checks ρ ∈ (0, 1] and P(0) > 0.
pub fn check_settings(forgetting: f64, p0: f64) -> Result<(), SysidError> {
    if !(forgetting > 0.0 && forgetting <= 1.0) {
        return Err(SysidError::setting("--forgetting", forgetting, "a forgetting factor in (0, 1]"));
    }
    if !(p0.is_finite() && p0 > 0.0) {
        return Err(SysidError::setting("--p0", p0, "a positive, finite initial covariance scale"));
    }
    Ok(())
}
