//! Recursive least squares in a numerically robust form (Bierman's UD factorisation) and with
//! covariance-windup protection ([`Windup`]); `--rls-form ud`, `--windup`.
//!
//! The UD form keeps P = U D Uᵀ with U unit upper triangular and D diagonal, and updates the factors
//! instead of P (G. J. Bierman, *Factorization Methods for Discrete Sequential Estimation*, 1977). P is
//! then symmetric and positive semi-definite by construction, whatever the rounding: the ordinary update
//! (paper eq. 12) subtracts two nearly equal matrices and can lose definiteness when P is ill conditioned.
//!
//! Per sample (ρ the forgetting factor, φ the regressor, ε = y − φᵀθ̂):
//! - ordinary forgetting: Bierman's measurement update with measurement variance ρ gives
//!   L = Pφ/(ρ + φᵀPφ) and P − Pφφᵀ P/(ρ + φᵀPφ); then D ← D/ρ;
//! - directional forgetting: first P̃ = P + α ppᵀ with p = Pφ, α = (1 − ρ)/(ρ r), r = φᵀPφ (an Agee–Turner
//!   rank-one update of the factors, stable for α > 0), then Bierman's update with variance 1;
//!   see [`crate::windup`];
//! - bounded trace: D is scaled so that tr P = Σ_j d_j Σ_i U_ij² stays ≤ T.
//!
//! The same options exist in the standard (dense P) form, [`RlsForm::Standard`], for comparison.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::rls::check_settings;
use crate::windup::{directional_gamma, Windup, MIN_EXCITATION};
use sysid_core::{Setting, SysidError};

/// Representation of the RLS covariance (`--rls-form`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum RlsForm {
    /// Dense P updated by the paper's eq. 12 (symmetrised).
    #[default]
    Standard,
    /// Bierman's UD factorisation P = U D Uᵀ.
    Ud,
}

impl std::fmt::Display for RlsForm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            RlsForm::Standard => "standard",
            RlsForm::Ud => "ud",
        })
    }
}

/// An RLS estimator with a chosen covariance form and windup protection.
#[derive(Debug, Clone)]
pub struct RobustRls {
    /// θ̂: current estimate.
    pub theta: DVector<f64>,
    /// ρ: forgetting factor in (0, 1].
    pub forgetting: f64,
    form: RlsForm,
    windup: Windup,
    max_trace: f64,
    /// Standard form: P. UD form: U (unit upper triangular).
    m: DMatrix<f64>,
    /// UD form: the diagonal D.
    d: DVector<f64>,
    work: DVector<f64>,
    work2: DVector<f64>,
}

impl RobustRls {
    /// θ̂(0) = 0, P(0) = p0 I. `max_trace` (T for [`Windup::Trace`]) defaults to p0 · n.
    pub fn new(
        n_params: usize,
        forgetting: f64,
        p0: f64,
        form: RlsForm,
        windup: Windup,
        max_trace: Option<f64>,
    ) -> Result<Self, SysidError> {
        check_settings(forgetting, p0)?;
        let max_trace = max_trace.unwrap_or(p0 * n_params as f64);
        if !(max_trace.is_finite() && max_trace > 0.0) {
            return Err(SysidError::setting(
                Setting::MaxTrace,
                max_trace,
                "a positive, finite bound on tr P",
            ));
        }
        let n = n_params;
        let (m, d) = match form {
            RlsForm::Standard => (DMatrix::identity(n, n) * p0, DVector::zeros(0)),
            RlsForm::Ud => (DMatrix::identity(n, n), DVector::from_element(n, p0)),
        };
        Ok(RobustRls {
            theta: DVector::zeros(n),
            forgetting,
            form,
            windup,
            max_trace,
            m,
            d,
            work: DVector::zeros(n),
            work2: DVector::zeros(n),
        })
    }

    /// Restarts P = p0 I, keeping θ̂.
    pub fn restart_covariance(&mut self, p0: f64) {
        self.m.fill(0.0);
        match self.form {
            RlsForm::Standard => self.m.fill_diagonal(p0),
            RlsForm::Ud => {
                self.m.fill_diagonal(1.0);
                self.d.fill(p0);
            }
        }
    }

    /// P (for the UD form, U D Uᵀ).
    pub fn covariance(&self) -> DMatrix<f64> {
        match self.form {
            RlsForm::Standard => self.m.clone(),
            RlsForm::Ud => {
                let ud = &self.m * DMatrix::from_diagonal(&self.d);
                &ud * self.m.transpose()
            }
        }
    }

    /// tr P.
    pub fn trace(&self) -> f64 {
        match self.form {
            RlsForm::Standard => self.m.trace(),
            RlsForm::Ud => {
                let n = self.d.len();
                (0..n)
                    .map(|j| {
                        self.d[j]
                            * (0..=j)
                                .map(|i| self.m[(i, j)] * self.m[(i, j)])
                                .sum::<f64>()
                    })
                    .sum()
            }
        }
    }

    /// One update with regressor φ(k) and measurement y(k); returns the a-priori error ε(k).
    pub fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        let n = self.theta.len();
        debug_assert_eq!(phi.len(), n);
        let eps = y - phi
            .iter()
            .zip(self.theta.iter())
            .map(|(a, b)| a * b)
            .sum::<f64>();
        if !eps.is_finite() {
            return Err(SysidError::Numerical(format!(
                "RLS met a non-finite value at sample {sample} (error ε = {eps:e})"
            )));
        }
        match self.form {
            RlsForm::Standard => self.update_standard(phi, eps, sample)?,
            RlsForm::Ud => self.update_ud(phi, eps, sample)?,
        }
        if self.windup == Windup::Trace {
            let tr = self.trace();
            if tr > self.max_trace {
                let s = self.max_trace / tr;
                match self.form {
                    RlsForm::Standard => self.m.scale_mut(s),
                    RlsForm::Ud => self.d.scale_mut(s),
                }
            }
        }
        if self.theta.iter().any(|v| !v.is_finite()) {
            return Err(SysidError::Numerical(format!(
                "RLS estimate became non-finite at sample {sample}"
            )));
        }
        Ok(eps)
    }

    fn update_standard(&mut self, phi: &[f64], eps: f64, sample: usize) -> Result<(), SysidError> {
        let n = self.theta.len();
        let rho = self.forgetting;
        for i in 0..n {
            self.work[i] = (0..n).map(|j| self.m[(i, j)] * phi[j]).sum();
        }
        let r: f64 = (0..n).map(|i| phi[i] * self.work[i]).sum();
        let denom = rho + r;
        if !(denom.is_finite() && denom > 0.0 && r >= 0.0) {
            return Err(SysidError::Numerical(format!(
                "RLS lost positive definiteness or met a non-finite value at sample {sample} (φᵀPφ = {r:e})"
            )));
        }
        for i in 0..n {
            self.theta[i] += self.work[i] / denom * eps;
        }
        // P(k) = P − γ ppᵀ (divided by ρ for ordinary forgetting), upper triangle mirrored.
        let (gamma, scale) = match self.windup {
            Windup::Directional if r > MIN_EXCITATION => (directional_gamma(rho, r), 1.0),
            Windup::Directional => (1.0 / (1.0 + r), 1.0),
            _ => (1.0 / denom, 1.0 / rho),
        };
        for j in 0..n {
            for i in 0..=j {
                let v = (self.m[(i, j)] - gamma * self.work[i] * self.work[j]) * scale;
                self.m[(i, j)] = v;
                self.m[(j, i)] = v;
            }
        }
        Ok(())
    }

    /// Bierman's measurement update of (U, D) with measurement variance `var`; returns the unnormalised
    /// gain in `work` and α = var + φᵀPφ.
    fn bierman(&mut self, phi: &[f64], var: f64) -> f64 {
        let n = self.theta.len();
        // f = Uᵀ φ (work2), v = D f (work).
        for j in 0..n {
            self.work2[j] = (0..=j).map(|i| self.m[(i, j)] * phi[i]).sum();
        }
        for j in 0..n {
            self.work[j] = self.d[j] * self.work2[j];
        }
        let mut alpha = var;
        // b (the gain numerator) is built in place of v: after column j, work[0..=j] holds b.
        for j in 0..n {
            let f = self.work2[j];
            let v = self.work[j];
            let alpha_prev = alpha;
            alpha += f * v;
            self.d[j] *= alpha_prev / alpha;
            let lambda = -f / alpha_prev;
            for i in 0..j {
                let uij = self.m[(i, j)];
                self.m[(i, j)] = uij + self.work[i] * lambda;
                self.work[i] += uij * v;
            }
            // work[j] = v already.
        }
        alpha
    }

    /// Agee–Turner rank-one update U D Uᵀ + c a aᵀ (c > 0); `a` is destroyed.
    fn agee_turner(&mut self, mut c: f64, a: &mut DVector<f64>) {
        let n = self.d.len();
        for j in (0..n).rev() {
            let s = a[j];
            let d_new = self.d[j] + c * s * s;
            if d_new <= 0.0 || !d_new.is_finite() {
                continue;
            }
            let b = c * s / d_new;
            c *= self.d[j] / d_new;
            self.d[j] = d_new;
            for i in 0..j {
                a[i] -= s * self.m[(i, j)];
                self.m[(i, j)] += b * a[i];
            }
        }
    }

    fn update_ud(&mut self, phi: &[f64], eps: f64, sample: usize) -> Result<(), SysidError> {
        let n = self.theta.len();
        let rho = self.forgetting;
        let alpha = if self.windup == Windup::Directional {
            // p = Pφ = U D Uᵀ φ and r = φᵀPφ.
            let mut f = DVector::<f64>::zeros(n);
            for j in 0..n {
                f[j] = (0..=j).map(|i| self.m[(i, j)] * phi[i]).sum::<f64>() * self.d[j];
            }
            let mut p = DVector::<f64>::zeros(n);
            for i in 0..n {
                p[i] = (i..n).map(|j| self.m[(i, j)] * f[j]).sum();
            }
            let r: f64 = (0..n).map(|i| phi[i] * p[i]).sum();
            if r > MIN_EXCITATION && rho < 1.0 {
                let c = (1.0 - rho) / (rho * r);
                self.agee_turner(c, &mut p);
            }
            self.bierman(phi, 1.0)
        } else {
            let a = self.bierman(phi, rho);
            if rho < 1.0 {
                self.d.unscale_mut(rho);
            }
            a
        };
        if !(alpha.is_finite() && alpha > 0.0) || self.d.iter().any(|v| !v.is_finite() || *v < 0.0)
        {
            return Err(SysidError::Numerical(format!(
                "UD RLS met a non-finite or negative factor at sample {sample} (α = {alpha})"
            )));
        }
        for i in 0..n {
            self.theta[i] += self.work[i] / alpha * eps;
        }
        Ok(())
    }
}

impl crate::rls::RecursiveUpdate for RobustRls {
    fn theta(&self) -> &[f64] {
        self.theta.as_slice()
    }
    fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        RobustRls::update(self, phi, y, sample)
    }
    fn restart_covariance(&mut self, p0: f64) {
        RobustRls::restart_covariance(self, p0)
    }
    fn covariance(&self) -> DMatrix<f64> {
        RobustRls::covariance(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rls::Rls;

    fn regressors(n: usize, k: usize) -> (Vec<f64>, f64) {
        // A deterministic, exciting sequence.
        let phi: Vec<f64> = (0..n)
            .map(|i| ((k * 7 + i * 13) % 11) as f64 - 5.0 + 0.1 * i as f64)
            .collect();
        let y = phi
            .iter()
            .enumerate()
            .map(|(i, v)| v * (i as f64 - 1.5))
            .sum::<f64>()
            + ((k % 5) as f64 - 2.0) * 0.1;
        (phi, y)
    }

    // Bierman's UD update is an exact refactorisation of eq. 12: same θ̂ and P as the dense RLS, to rounding.
    #[test]
    fn ud_form_equals_the_standard_recursion() {
        for rho in [1.0, 0.95] {
            let mut a = Rls::new(4, rho, 100.0).unwrap();
            let mut b = RobustRls::new(4, rho, 100.0, RlsForm::Ud, Windup::None, None).unwrap();
            for k in 0..200 {
                let (phi, y) = regressors(4, k);
                a.update(&phi, y, k).unwrap();
                b.update(&phi, y, k).unwrap();
            }
            let pb = b.covariance();
            for i in 0..4 {
                assert!(
                    (a.theta[i] - b.theta[i]).abs() < 1e-9 * (1.0 + a.theta[i].abs()),
                    "rho {rho}"
                );
                for j in 0..4 {
                    assert!(
                        (a.p()[(i, j)] - pb[(i, j)]).abs() < 1e-9 * (1.0 + a.p()[(i, j)].abs()),
                        "rho {rho}"
                    );
                }
            }
        }
    }

    // Directional forgetting in UD form equals its dense covariance form P − γ ppᵀ.
    #[test]
    fn directional_forgetting_ud_equals_dense() {
        let mut a =
            RobustRls::new(3, 0.9, 10.0, RlsForm::Standard, Windup::Directional, None).unwrap();
        let mut b = RobustRls::new(3, 0.9, 10.0, RlsForm::Ud, Windup::Directional, None).unwrap();
        for k in 0..300 {
            let (phi, y) = regressors(3, k);
            a.update(&phi, y, k).unwrap();
            b.update(&phi, y, k).unwrap();
        }
        let (pa, pb) = (a.covariance(), b.covariance());
        for i in 0..3 {
            assert!((a.theta[i] - b.theta[i]).abs() < 1e-9 * (1.0 + a.theta[i].abs()));
            for j in 0..3 {
                assert!((pa[(i, j)] - pb[(i, j)]).abs() < 1e-9 * (1.0 + pa[(i, j)].abs()));
            }
        }
    }

    // Bounded trace: tr P never exceeds T after an update.
    #[test]
    fn bounded_trace_keeps_the_trace_below_the_bound() {
        for form in [RlsForm::Standard, RlsForm::Ud] {
            let mut e = RobustRls::new(2, 0.5, 1.0, form, Windup::Trace, Some(3.0)).unwrap();
            for k in 0..100 {
                e.update(&[1.0, 1.0], 1.0, k).unwrap();
                assert!(e.trace() <= 3.0 * (1.0 + 1e-12), "{form}: {}", e.trace());
            }
        }
    }
}
