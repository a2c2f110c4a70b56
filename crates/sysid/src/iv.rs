//! Recursive instrumental variables (`--method iv`): a recursive estimator that stays unbiased when
//! white noise enters at the output, for online use.
//!
//! LS regresses y(k) on past *measured* outputs, which carry the noise, so E[φ(k) e(k)] ≠ 0 and the
//! estimate is biased. IV replaces φ by an instrument vector z(k) correlated with φ but not with the
//! noise: the same regressor built from the noise-free simulated output ŷ_aux of an auxiliary model
//! (Young's auxiliary-model instruments; Söderström & Stoica, *Instrumental Variable Methods*, 1983).
//!
//! ```text
//! ε(k) = y(k) − φᵀ(k) θ̂(k−1)
//! L(k) = P(k−1) z(k) / (ρ + φᵀ(k) P(k−1) z(k))
//! θ̂(k) = θ̂(k−1) + L(k) ε(k)
//! P(k) = [P(k−1) − L(k) φᵀ(k) P(k−1)] / ρ
//! ```
//!
//! θ̂(N) solves Σ ρ^(N−k) z(k) (y(k) − φᵀ(k) θ) = 0 up to the P(0) regularisation. The auxiliary model is
//! first the least-squares estimate (key-term separation for Hammerstein), then each IV stage's own result
//! (`iv_stages` stages; for Hammerstein the switching functions and x̂ of a stage use the auxiliary
//! model's deadzone, as in later RLS passes).

use nalgebra::{DMatrix, DVector};

use sysid_core::{Dataset, Deadzone, Structure, SysidError};

/// The result of one recursive IV pass.
#[derive(Debug, Clone)]
pub struct IvPass {
    /// θ̂ over the free entries.
    pub theta: DVector<f64>,
    /// Σ z φᵀ over the pass (free entries).
    pub zphi: DMatrix<f64>,
    /// Σ z zᵀ over the pass (free entries).
    pub zz: DMatrix<f64>,
}

/// One pass of recursive IV over `data`. `y_aux` is the auxiliary model's simulated output, `dz` the
/// deadzone giving h_r, h_l and x̂ (ignored for ARX), `free` the estimated entries of θ (key-term layout),
/// `theta0` the start (free entries).
#[allow(clippy::too_many_arguments)]
pub fn pass(
    data: &Dataset,
    s: &Structure,
    dz: &Deadzone,
    y_aux: &[f64],
    free: &[bool],
    theta0: &DVector<f64>,
    forgetting: f64,
    p0: f64,
) -> Result<IvPass, SysidError> {
    crate::rls::check_settings(forgetting, p0)?;
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let p = idx.len();
    let k0 = s.orders.k0();
    let mut theta = theta0.clone();
    let mut pm = DMatrix::<f64>::identity(p, p) * p0;
    let mut full_phi = vec![0.0; free.len()];
    let mut full_z = vec![0.0; free.len()];
    let mut phi = DVector::<f64>::zeros(p);
    let mut z = DVector::<f64>::zeros(p);
    let mut zphi = DMatrix::<f64>::zeros(p, p);
    let mut zz = DMatrix::<f64>::zeros(p, p);
    for k in k0..data.len() {
        s.fill_row(&data.u, &data.y, k, dz, &mut full_phi);
        s.fill_row(&data.u, y_aux, k, dz, &mut full_z);
        for (q, &i) in idx.iter().enumerate() {
            phi[q] = full_phi[i];
            z[q] = full_z[i];
        }
        let eps = s.target(&data.y, k) - phi.dot(&theta);
        let pz = &pm * &z;
        let phip = pm.tr_mul(&phi); // (φᵀ P)ᵀ
        let den = forgetting + phi.dot(&pz);
        if !(den.is_finite() && den.abs() > 1e-300 && eps.is_finite()) {
            return Err(SysidError::Numerical(format!(
                "{}: recursive IV met a singular or non-finite update at sample {k} (ρ + φᵀPz = {den})",
                data.name
            )));
        }
        theta.axpy(eps / den, &pz, 1.0);
        pm.ger(-1.0 / den, &pz, &phip, 1.0);
        if forgetting < 1.0 {
            pm.unscale_mut(forgetting);
        }
        zphi.ger(1.0, &z, &phi, 1.0);
        zz.ger(1.0, &z, &z, 1.0);
    }
    if theta.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::Numerical(format!(
            "{}: recursive IV produced a non-finite estimate",
            data.name
        )));
    }
    Ok(IvPass { theta, zphi, zz })
}

/// Asymptotic covariance of the basic IV estimate, σ² (ZᵀΦ)⁻¹ ZᵀZ (ΦᵀZ)⁻¹, or `None` when ZᵀΦ is
/// singular.
pub fn covariance(pass: &IvPass, sigma2: f64) -> Option<DMatrix<f64>> {
    let inv = pass.zphi.clone().try_inverse()?;
    let c = &inv * &pass.zz * inv.transpose() * sigma2;
    c.iter().all(|v| v.is_finite()).then_some(c)
}
