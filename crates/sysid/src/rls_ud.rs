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
//! - bounded trace: P is scaled so that tr P stays ≤ T after every update. In the dense form P itself is
//!   scaled. In the UD form (tr P = Σ_j d_j Σ_(i≤j) U_ij²) the scale c = T / tr P is left pending,
//!   P = c · U D Uᵀ, and the next update folds it in: Bierman's update of (U, D) with measurement variance
//!   ρ̃ = ρ / c gives the gain and the factors of the update of c · U D Uᵀ, and D ← D · (1/ρ̃) both applies
//!   c and divides by ρ. So the bound costs no pass over D; ρ̃ = tr P · (ρ / T) when it acts, ρ otherwise,
//!   and it acts when tr P · (ρ / T) > ρ (tr P > T up to the rounding of ρ̃; `ipa_embedded`'s test).
//!   tr P of the new factors is not summed at every update but kept: t(k) = (t(k−1) − bᵀb · (1/α)) ·
//!   (1/ρ̃) from Bierman's gain numerator b and α (bᵀb over even and odd i apart), with a reference
//!   R(k) = R(k−1) · (1/ρ̃) · g, g = [`ipa_embedded::rls::TRACE_DRIFT_GROWTH`]; when t < R/4 (or t or R
//!   is not finite) t is summed exactly (`ud_trace`: each column's Σ_(i<j) U_ij² over even and odd i apart)
//!   and R = t; construction and restarts sum it exactly. t is kept only while R > T/4: an update
//!   starting from R ≤ T/4 computes R alone, leaves t and sets nothing pending (R bounds tr P, so the
//!   bound cannot act), and sums t exactly when R is no longer ≤ T/4. The same operations and order as
//!   `ipa_embedded` (whose module documentation bounds the drift: ≈ 400 ε relative).
//!
//! The same options exist in the standard (dense P) form, [`RlsForm::Standard`], for comparison.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::rls::check_settings;
use crate::windup::{directional_gamma, Windup, MIN_EXCITATION};
use ipa_embedded::rls::TRACE_DRIFT_GROWTH;
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

/// The covariance P in the chosen form; which matrices exist follows from the form.
#[derive(Debug, Clone)]
enum Covariance {
    /// [`RlsForm::Standard`]: the dense, symmetric P.
    Dense(DMatrix<f64>),
    /// [`RlsForm::Ud`]: P = U D Uᵀ.
    Ud {
        /// U: unit upper triangular.
        u: DMatrix<f64>,
        /// The diagonal of D (≥ 0).
        d: DVector<f64>,
    },
}

/// An RLS estimator with a chosen covariance form and windup protection.
#[derive(Debug, Clone)]
pub struct RobustRls {
    /// θ̂: current estimate.
    pub theta: DVector<f64>,
    /// ρ: forgetting factor in (0, 1].
    pub forgetting: f64,
    windup: Windup,
    max_trace: f64,
    /// UD form with the trace bound: ρ̃ = ρ / c while the bound's scale c = T / tr P is pending
    /// (P = c · U D Uᵀ, module documentation); `None`: c = 1.
    pending_var: Option<f64>,
    /// UD form with the trace bound: t = tr (U D Uᵀ) of the factors (tr P = c t), kept by the rank-one
    /// formula t(k) = (t(k−1) − bᵀb / α) / ρ̃ while R > T/4 and summed exactly again when t < R/4 or
    /// when R leaves [0, T/4] with t not kept (module documentation).
    kept_trace: f64,
    /// R: t as it would be without the downdates since the last exact sum, grown by
    /// [`TRACE_DRIFT_GROWTH`] per update.
    trace_ref: f64,
    cov: Covariance,
    work: DVector<f64>,
    work2: DVector<f64>,
    /// Standard form with the trace bound: the restarts of P at (T/n) I after eq. 12 lost P's
    /// positive definiteness to rounding ([`RobustRls::update`]), and the sample of the first.
    resets: usize,
    first_reset: Option<usize>,
}

/// The restarts of P that [`RobustRls::update`] made (standard form with the trace bound): `count`
/// of them, the first at sample `first_sample`, each to P = (T/n) I with tr P = `bound` = T.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CovarianceResets {
    /// How many updates restarted P.
    pub count: usize,
    /// The sample k of the first.
    pub first_sample: usize,
    /// T, the trace bound (tr P after each restart).
    pub bound: f64,
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
        let derived = p0 * n_params as f64;
        if max_trace.is_none() && !derived.is_finite() {
            // The bound is derived from p0 (p0 · n): the user typed --p0, so --p0 is named (audit s32
            // L-11), with the derived bound that overflowed.
            return Err(SysidError::setting(
                Setting::P0,
                p0,
                &format!(
                    "a p0 whose default --max-trace (p0 × {n_params} parameters = {}) is finite; \
                     give a smaller --p0 or an explicit --max-trace",
                    sysid_core::format::shortest(derived)
                ),
            ));
        }
        let max_trace = max_trace.unwrap_or(derived);
        if !(max_trace.is_finite() && max_trace > 0.0) {
            return Err(SysidError::setting(
                Setting::MaxTrace,
                max_trace,
                "a positive, finite bound on tr P",
            ));
        }
        let n = n_params;
        let cov = match form {
            RlsForm::Standard => Covariance::Dense(DMatrix::identity(n, n) * p0),
            RlsForm::Ud => Covariance::Ud {
                u: DMatrix::identity(n, n),
                d: DVector::from_element(n, p0),
            },
        };
        let mut est = RobustRls {
            theta: DVector::zeros(n),
            forgetting,
            windup,
            max_trace,
            pending_var: None,
            kept_trace: 0.0,
            trace_ref: 0.0,
            cov,
            work: DVector::zeros(n),
            work2: DVector::zeros(n),
            resets: 0,
            first_reset: None,
        };
        est.sum_trace();
        Ok(est)
    }

    /// The covariance form.
    pub fn form(&self) -> RlsForm {
        match self.cov {
            Covariance::Dense(_) => RlsForm::Standard,
            Covariance::Ud { .. } => RlsForm::Ud,
        }
    }

    /// Restarts P = p0 I, keeping θ̂.
    pub fn restart_covariance(&mut self, p0: f64) {
        self.pending_var = None;
        match &mut self.cov {
            Covariance::Dense(p) => {
                p.fill(0.0);
                p.fill_diagonal(p0);
            }
            Covariance::Ud { u, d } => {
                u.fill(0.0);
                u.fill_diagonal(1.0);
                d.fill(p0);
            }
        }
        self.sum_trace();
    }

    /// The kept trace t and its reference R (UD form), both tr (U D Uᵀ) summed exactly.
    fn sum_trace(&mut self) {
        if let Covariance::Ud { u, d } = &self.cov {
            self.kept_trace = ud_trace(u, d);
            self.trace_ref = self.kept_trace;
        }
    }

    /// P (for the UD form, c · U D Uᵀ, c = 1 unless the trace bound's scale is pending).
    pub fn covariance(&self) -> DMatrix<f64> {
        match &self.cov {
            Covariance::Dense(p) => p.clone(),
            Covariance::Ud { u, d } => {
                let ud = u * DMatrix::from_diagonal(d);
                &ud * u.transpose() * self.pending_scale()
            }
        }
    }

    /// c in P = c · U D Uᵀ: ρ / ρ̃ while the trace bound's scale is pending, else 1.
    fn pending_scale(&self) -> f64 {
        self.pending_var.map_or(1.0, |var| self.forgetting / var)
    }

    /// tr P.
    pub fn trace(&self) -> f64 {
        match &self.cov {
            Covariance::Dense(p) => p.trace(),
            Covariance::Ud { u, d } => self.pending_scale() * ud_trace(u, d),
        }
    }

    /// The restarts of P the standard form with the trace bound made ([`RobustRls::update`]), `None`
    /// when there were none.
    pub fn covariance_resets(&self) -> Option<CovarianceResets> {
        self.first_reset.map(|first_sample| CovarianceResets {
            count: self.resets,
            first_sample,
            bound: self.max_trace,
        })
    }

    /// One update with regressor φ(k) and measurement y(k); returns the a-priori error ε(k).
    ///
    /// Standard form with the trace bound ([`Windup::Trace`]): the bound keeps tr P ≤ T, not P's
    /// condition. Over a long stretch without excitation (an actuator at rest after an experiment)
    /// forgetting grows P in the directions φ does not excite while each update shrinks it along φ and
    /// the bound scales the whole of P down, until eq. 12's rounding makes P indefinite (φᵀPφ < 0:
    /// audit s35c, the README's record followed by 100 000 samples at rest, ρ = 0.98, at sample
    /// 10 360). Then P is restarted at (T/n) I (tr P = T, θ̂ kept) and the update made again, so the
    /// estimator stays finite and bounded as the protection promises; the restarts are counted
    /// ([`RobustRls::covariance_resets`]) and the callers warn of them. (The UD form keeps P
    /// positive definite by construction and never restarts; without the bound the failure is the
    /// error it always was.) When the update fails again from the restarted P (a non-finite value),
    /// P is put back and the error returned: the state is unchanged.
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
        let var = self.pending_var.unwrap_or(self.forgetting);
        let step = Step {
            phi,
            eps,
            rho: self.forgetting,
            var,
            windup: self.windup,
            sample,
        };
        // 1/α of the UD update (unused in the dense form).
        let inv_alpha = match &mut self.cov {
            Covariance::Dense(p) => {
                if let Err(e) = update_standard(p, &mut self.theta, &mut self.work, &step) {
                    if self.windup != Windup::Trace {
                        return Err(e);
                    }
                    let saved = p.clone();
                    p.fill(0.0);
                    p.fill_diagonal(self.max_trace / n as f64);
                    if let Err(e) = update_standard(p, &mut self.theta, &mut self.work, &step) {
                        *p = saved;
                        return Err(e);
                    }
                    self.resets += 1;
                    self.first_reset.get_or_insert(sample);
                }
                0.0
            }
            Covariance::Ud { u, d } => {
                let mut f = Factors {
                    u,
                    d,
                    work: &mut self.work,
                    work2: &mut self.work2,
                };
                update_ud(&mut f, &mut self.theta, &step)?
            }
        };
        if self.windup == Windup::Trace {
            match &mut self.cov {
                Covariance::Dense(p) => {
                    let tr = p.trace();
                    if tr > self.max_trace {
                        p.scale_mut(self.max_trace / tr);
                    }
                }
                Covariance::Ud { u, d } => {
                    // The update consumed the pending scale: the new factors are P itself, whose
                    // trace is kept by the rank-one formula (b = work, the gain numerator) while
                    // R > T/4, summed exactly when t < R/4 or when R(k) leaves [0, T/4] with t not
                    // kept (`ipa_embedded`'s operations and order).
                    let inv_var = 1.0 / var;
                    let quarter_bound = self.max_trace * 0.25;
                    let keep_t = self.trace_ref > quarter_bound;
                    let mut tr_ref = self.trace_ref * inv_var * TRACE_DRIFT_GROWTH;
                    let mut tr = self.kept_trace;
                    let exact = if keep_t {
                        let (mut even, mut odd) = (-0.0, -0.0);
                        for (i, bi) in self.work.iter().enumerate() {
                            if i % 2 == 0 {
                                even += bi * bi;
                            } else {
                                odd += bi * bi;
                            }
                        }
                        let diff = self.kept_trace - (even + odd) * inv_alpha;
                        tr = diff * inv_var;
                        let quarter = tr_ref * 0.25;
                        tr < quarter || !(tr - quarter).is_finite()
                    } else {
                        // t not kept: t ≤ R(k−1) ≤ T/4 and R(k) bounds tr P (module documentation).
                        tr_ref > quarter_bound || !tr_ref.is_finite()
                    };
                    if exact {
                        tr = ud_trace(u, d);
                        tr_ref = tr;
                    }
                    self.kept_trace = tr;
                    self.trace_ref = tr_ref;
                    // When tr P > T, c = T / tr P is left pending as ρ̃ = ρ / c = tr P · (ρ / T); the
                    // test is ρ̃ > ρ, i.e. tr P > T up to the rounding of ρ̃ (`ipa_embedded`'s order:
                    // its update writes ρ̃ as max(tr P · (ρ / T), ρ), with no branch). With t not
                    // kept and no exact sum, tr P ≤ R ≤ T/4: nothing pending.
                    self.pending_var = if keep_t || exact {
                        let var = tr * (self.forgetting / self.max_trace);
                        (var > self.forgetting).then_some(var)
                    } else {
                        None
                    };
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
}

/// What one update needs besides the covariance: φ(k), ε(k), ρ, the UD form's measurement variance ρ̃
/// (ρ unless the trace bound's scale is pending), the windup protection and k (for messages).
struct Step<'a> {
    phi: &'a [f64],
    eps: f64,
    rho: f64,
    var: f64,
    windup: Windup,
    sample: usize,
}

/// The UD factors and two work vectors of length n, borrowed for one update.
struct Factors<'a> {
    u: &'a mut DMatrix<f64>,
    d: &'a mut DVector<f64>,
    work: &'a mut DVector<f64>,
    work2: &'a mut DVector<f64>,
}

/// The dense update (paper eq. 12, or its directional-forgetting form) of P and θ̂.
fn update_standard(
    p: &mut DMatrix<f64>,
    theta: &mut DVector<f64>,
    work: &mut DVector<f64>,
    st: &Step<'_>,
) -> Result<(), SysidError> {
    let n = theta.len();
    let (p, theta, work) = (p.as_mut_slice(), theta.as_mut_slice(), work.as_mut_slice());
    // The online tracker runs this for every sample: the common sizes get a copy of the body compiled
    // for their n (same operations in the same order, so the same numbers to the bit).
    macro_rules! sized {
        ($($k:literal)*) => {
            match n {
                $($k => standard_body($k, p, theta, work, st),)*
                _ => standard_body(n, p, theta, work, st),
            }
        };
    }
    sized!(1 2 3 4 5 6 7 8 9 10 11 12)
}

/// [`update_standard`] on plain slices: P by columns (entry (i, j) at i + j·n), θ̂ and the work
/// vector of n entries each.
#[inline(always)]
fn standard_body(
    n: usize,
    p: &mut [f64],
    theta: &mut [f64],
    work: &mut [f64],
    st: &Step<'_>,
) -> Result<(), SysidError> {
    let (phi, rho, sample) = (st.phi, st.rho, st.sample);
    let (p, theta, work, phi) = (&mut p[..n * n], &mut theta[..n], &mut work[..n], &phi[..n]);
    for (i, w) in work.iter_mut().enumerate() {
        *w = (0..n).map(|j| p[i + j * n] * phi[j]).sum();
    }
    let r: f64 = (0..n).map(|i| phi[i] * work[i]).sum();
    let denom = rho + r;
    if !(denom.is_finite() && denom > 0.0 && r >= 0.0) {
        let what = format!(
            "RLS lost positive definiteness or met a non-finite value at sample {sample} (φᵀPφ = {r:e})"
        );
        return Err(SysidError::Numerical(if rho < 1.0 {
            format!("{what}; {}", crate::rls::windup_advice(rho))
        } else {
            what
        }));
    }
    for i in 0..n {
        theta[i] += work[i] / denom * st.eps;
    }
    // P(k) = P − γ ppᵀ (divided by ρ for ordinary forgetting), upper triangle mirrored.
    let (gamma, scale) = match st.windup {
        Windup::Directional if r > MIN_EXCITATION => (directional_gamma(rho, r), 1.0),
        Windup::Directional => (1.0 / (1.0 + r), 1.0),
        _ => (1.0 / denom, 1.0 / rho),
    };
    for j in 0..n {
        for i in 0..=j {
            let v = (p[i + j * n] - gamma * work[i] * work[j]) * scale;
            p[i + j * n] = v;
            p[j + i * n] = v;
        }
    }
    Ok(())
}

/// Bierman's measurement update of (U, D) with measurement variance `var`; returns the unnormalised
/// gain in `work`, α = var + φᵀPφ and 1/α.
///
/// The prefix sums α_j = var + Σ_(i≤j) f_i v_i are a chain of additions only; each column's divisions
/// are one reciprocal 1/α_j, used as d_j ← d_j · (α_(j−1) · (1/α_j)) and λ_j = −f_j · (1/α_(j−1)). The
/// reciprocals hang off the chain instead of lengthening it, so they pipeline: n + 1 divisions per
/// update instead of 2n. `ipa_embedded::Rls` (UD form) runs the same operations in the same order, so
/// its f64 results equal these bit for bit.
fn bierman(f: &mut Factors<'_>, phi: &[f64], var: f64) -> (f64, f64) {
    let n = f.d.len();
    // f = Uᵀ φ (work2), v = D f (work).
    for j in 0..n {
        f.work2[j] = (0..=j).map(|i| f.u[(i, j)] * phi[i]).sum();
    }
    for j in 0..n {
        f.work[j] = f.d[j] * f.work2[j];
    }
    let mut alpha = var;
    let mut inv_prev = 1.0 / var;
    // b (the gain numerator) is built in place of v: after column j, work[0..=j] holds b.
    for j in 0..n {
        let fj = f.work2[j];
        let v = f.work[j];
        let alpha_prev = alpha;
        alpha += fj * v;
        let inv = 1.0 / alpha;
        f.d[j] *= alpha_prev * inv;
        let lambda = -fj * inv_prev;
        inv_prev = inv;
        for i in 0..j {
            let uij = f.u[(i, j)];
            f.u[(i, j)] = uij + f.work[i] * lambda;
            f.work[i] += uij * v;
        }
        // work[j] = v already.
    }
    (alpha, inv_prev)
}

/// tr (U D Uᵀ) = Σ_j d_j Σ_(i≤j) U_ij²: Σ_(i<j) U_ij² as (Σ over even i + Σ over odd i), each from −0,
/// then + U_jj² = 1; the terms d_j · (…) summed from −0 in the order j = 0, 1, … (`ipa_embedded` sums it
/// the same way; two partial sums halve its chain of dependent additions).
fn ud_trace(u: &DMatrix<f64>, d: &DVector<f64>) -> f64 {
    (0..d.len())
        .map(|j| {
            let (mut even, mut odd) = (-0.0, -0.0);
            for i in 0..j {
                let sq = u[(i, j)] * u[(i, j)];
                if i % 2 == 0 {
                    even += sq;
                } else {
                    odd += sq;
                }
            }
            d[j] * ((even + odd) + 1.0 * 1.0)
        })
        .sum()
}

/// Agee–Turner rank-one update U D Uᵀ + c a aᵀ (c > 0); `a` is destroyed.
fn agee_turner(u: &mut DMatrix<f64>, d: &mut DVector<f64>, mut c: f64, a: &mut DVector<f64>) {
    let n = d.len();
    for j in (0..n).rev() {
        let s = a[j];
        let d_new = d[j] + c * s * s;
        if d_new <= 0.0 || !d_new.is_finite() {
            continue;
        }
        let b = c * s / d_new;
        c *= d[j] / d_new;
        d[j] = d_new;
        for i in 0..j {
            a[i] -= s * u[(i, j)];
            u[(i, j)] += b * a[i];
        }
    }
}

/// The UD update of (U, D) and θ̂ (module documentation); returns 1/α, f.work holding the gain
/// numerator b.
fn update_ud(
    f: &mut Factors<'_>,
    theta: &mut DVector<f64>,
    st: &Step<'_>,
) -> Result<f64, SysidError> {
    let (phi, rho, sample) = (st.phi, st.rho, st.sample);
    let n = theta.len();
    let (alpha, inv_alpha) = if st.windup == Windup::Directional {
        // p = Pφ = U D Uᵀ φ and r = φᵀPφ.
        let mut g = DVector::<f64>::zeros(n);
        for j in 0..n {
            g[j] = (0..=j).map(|i| f.u[(i, j)] * phi[i]).sum::<f64>() * f.d[j];
        }
        let mut p = DVector::<f64>::zeros(n);
        for i in 0..n {
            p[i] = (i..n).map(|j| f.u[(i, j)] * g[j]).sum();
        }
        let r: f64 = (0..n).map(|i| phi[i] * p[i]).sum();
        if r > MIN_EXCITATION && rho < 1.0 {
            let c = (1.0 - rho) / (rho * r);
            agee_turner(f.u, f.d, c, &mut p);
        }
        bierman(f, phi, 1.0)
    } else {
        // ρ̃ = ρ / c: ρ unless the trace bound's scale c is pending.
        let var = st.var;
        let a = bierman(f, phi, var);
        if var != 1.0 {
            // D ← D · (1/ρ̃) = D · c / ρ: one division, the same operations as `ipa_embedded` (which
            // also multiplies by 1/ρ̃ = 1, exactly).
            f.d.scale_mut(1.0 / var);
        }
        a
    };
    if !(alpha.is_finite() && alpha > 0.0) || f.d.iter().any(|v| !v.is_finite() || *v < 0.0) {
        let what =
            format!("UD RLS met a non-finite or negative factor at sample {sample} (α = {alpha})");
        return Err(SysidError::Numerical(if rho < 1.0 {
            format!("{what}; {}", crate::rls::windup_advice(rho))
        } else {
            what
        }));
    }
    for i in 0..n {
        theta[i] += f.work[i] * inv_alpha * st.eps;
    }
    Ok(inv_alpha)
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
    fn restart_at(&mut self, theta: &[f64], p0: f64) {
        self.theta.copy_from_slice(theta);
        RobustRls::restart_covariance(self, p0)
    }
    fn covariance(&self) -> DMatrix<f64> {
        RobustRls::covariance(self)
    }
    fn covariance_resets(&self) -> Option<CovarianceResets> {
        RobustRls::covariance_resets(self)
    }
}

/// The recursive estimator `identify --method rls` uses for these settings: the plain RLS for the
/// standard form without windup protection, [`RobustRls`] otherwise.
pub fn recursive_estimator(
    n_params: usize,
    forgetting: f64,
    p0: f64,
    form: RlsForm,
    windup: Windup,
    max_trace: Option<f64>,
) -> Result<Box<dyn crate::rls::RecursiveUpdate>, SysidError> {
    Ok(if form == RlsForm::Standard && windup == Windup::None {
        Box::new(crate::rls::Rls::new(n_params, forgetting, p0)?)
    } else {
        Box::new(RobustRls::new(
            n_params, forgetting, p0, form, windup, max_trace,
        )?)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rls::Rls;

    /// The auditor's rest.csv (audit s33 L-6), made here: y = 1.5 y₋₁ − 0.7 y₋₂ + 0.5 u₋₁, a ±1 random
    /// input for 2000 samples, then 38 000 at rest (u = 0, y decays to 0). Regressors (−y₋₁, −y₋₂, u₋₁).
    fn rest_record() -> Vec<([f64; 3], f64)> {
        let mut state = 12345u64;
        let mut u = vec![0.0; 40_000];
        for v in u.iter_mut().take(2000) {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *v = if state >> 63 == 1 { 1.0 } else { -1.0 };
        }
        let mut y = vec![0.0; u.len()];
        for k in 2..u.len() {
            y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + 0.5 * u[k - 1];
        }
        (2..u.len())
            .map(|k| ([-y[k - 1], -y[k - 2], u[k - 1]], y[k]))
            .collect()
    }

    // At rest φ → 0, so P grows by 1/ρ per sample: from P(0) = 1e6 at ρ = 0.98 it overflows after about
    // ln(1e308 / 1e6) / ln(1/0.98) ≈ 34 400 samples of the 38 000 at rest (by hand), in the standard and
    // the UD form alike. Both fail, and the message names covariance windup and its remedies (not P(0)
    // and --rls-form ud); at ρ = 1 P does not grow and nothing fails.
    #[test]
    fn a_failure_under_forgetting_after_a_rest_names_covariance_windup() {
        let data = rest_record();
        let overflow_after = (1e308f64 / 1e6).ln() / (1.0f64 / 0.98).ln();
        assert!(overflow_after < 38_000.0 - 100.0);
        for form in [RlsForm::Standard, RlsForm::Ud] {
            let mut rls = RobustRls::new(3, 0.98, 1e6, form, Windup::None, None).unwrap();
            let e = data
                .iter()
                .enumerate()
                .find_map(|(k, (phi, y))| rls.update(phi, *y, k).err())
                .unwrap_or_else(|| panic!("{form}: no failure"));
            let m = e.to_string();
            assert!(
                m.contains("covariance windup")
                    && m.contains("--windup trace")
                    && m.contains("ρ = 1"),
                "{form}: {m}"
            );
            assert!(!m.contains("P(0) is too large"), "{form}: {m}");
            let mut rls = RobustRls::new(3, 1.0, 1e6, form, Windup::None, None).unwrap();
            for (k, (phi, y)) in data.iter().enumerate() {
                rls.update(phi, *y, k).unwrap();
            }
        }
        // The plain estimator (identify's standard form without a guard) says the same.
        let mut rls = Rls::new(3, 0.98, 1e6).unwrap();
        let m = data
            .iter()
            .enumerate()
            .find_map(|(k, (phi, y))| rls.update(phi, *y, k).err())
            .unwrap()
            .to_string();
        assert!(m.contains("covariance windup"), "{m}");
    }

    // Audit s35c: an actuator left at rest after an experiment. y = 1.5 y₋₁ − 0.7 y₋₂ + 0.5 u₋₁ + 20
    // (around 100) for 2000 samples of a ±1 input, then 100 000 at rest (u = 0, y held where the
    // experiment left it); regressors (−y₋₁, −y₋₂, u₋₁), ρ = 0.98, P(0) = 1e6 I, the trace
    // bound T = p0 · n; a Hammerstein-like regressor of 7 entries (three lags, the two branches and
    // their switching terms). Both forms stay finite with tr P ≤ T through the rest.
    #[test]
    fn the_trace_bound_keeps_the_standard_form_finite_through_a_long_rest_at_a_level() {
        let mut state = 4242u64;
        let n_rest = 100_000;
        let mut u = vec![0.0f64; 2000 + n_rest];
        for v in u.iter_mut().take(2000) {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            *v = if state >> 63 == 1 { 1.0 } else { -1.0 };
        }
        let mut y = vec![100.0; u.len()];
        for k in 2..2000 {
            y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2] + 0.5 * u[k - 1] + 20.0;
        }
        // At rest the position is held where the experiment left it (the valves closed; the
        // audit's record: y held at 106.42 mm).
        for k in 2000..u.len() {
            y[k] = y[1999];
        }
        let (p0, n) = (1e6, 7);
        for form in [RlsForm::Standard, RlsForm::Ud] {
            let mut rls = RobustRls::new(n, 0.98, p0, form, Windup::Trace, None).unwrap();
            for k in 3..u.len() {
                let (l, r) = (u[k - 1].min(0.0), u[k - 1].max(0.0));
                let phi = [
                    -y[k - 1],
                    -y[k - 2],
                    -y[k - 3],
                    l,
                    r,
                    f64::from(l < 0.0),
                    f64::from(r > 0.0),
                ];
                rls.update(&phi, y[k], k)
                    .unwrap_or_else(|e| panic!("{form}, sample {k}: {e}"));
                assert!(
                    rls.trace() <= p0 * n as f64 * (1.0 + 1e-9),
                    "{form}, sample {k}: tr P = {}",
                    rls.trace()
                );
            }
            assert!(rls.theta.iter().all(|v| v.is_finite()), "{form}");
            // Restarts only in the standard form, only in the rest (this record meets none; the
            // audit's record meets one: crates/cli/tests/s35_cli.rs).
            match (form, rls.covariance_resets()) {
                (RlsForm::Standard, Some(r)) => {
                    assert!(r.count >= 1 && r.first_sample > 2000, "{r:?}");
                    assert_eq!(r.bound, p0 * n as f64);
                }
                (_, None) => {}
                (f, r) => panic!("{f}: resets {r:?}"),
            }
        }
    }

    // Audit s32 L-11: the default bound p0 · n overflows for p0 = 1e308, n = 3: the error names p0 (the
    // setting given), not the derived max_trace; an explicit finite bound is accepted.
    #[test]
    fn an_overflowing_default_trace_bound_names_p0() {
        let e = RobustRls::new(3, 1.0, 1e308, RlsForm::Ud, Windup::Trace, None)
            .err()
            .unwrap();
        assert!(
            matches!(
                e,
                SysidError::Setting {
                    setting: Setting::P0,
                    ..
                }
            ),
            "{e}"
        );
        assert!(RobustRls::new(3, 1.0, 1e308, RlsForm::Ud, Windup::Trace, Some(1e9)).is_ok());
    }

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
                    (a.theta()[i] - b.theta[i]).abs() < 1e-9 * (1.0 + a.theta()[i].abs()),
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

    // The form asked for is the form kept, and a restart gives P = p0 I in either form; with the trace
    // bound (T = 30 = p0 n, reached as P grows by 1/ρ) the UD form's pending scale is dropped too.
    #[test]
    fn restart_gives_p0_times_identity_in_either_form() {
        let cases = [RlsForm::Standard, RlsForm::Ud]
            .into_iter()
            .flat_map(|f| [(f, Windup::None), (f, Windup::Trace)]);
        for (form, windup) in cases {
            let mut e = RobustRls::new(3, 0.9, 10.0, form, windup, None).unwrap();
            assert_eq!(e.form(), form);
            for k in 0..20 {
                let (phi, y) = regressors(3, k);
                e.update(&phi, y, k).unwrap();
            }
            e.restart_covariance(5.0);
            assert_eq!(e.covariance(), DMatrix::identity(3, 3) * 5.0, "{form}");
            assert_eq!(e.trace(), 15.0);
        }
    }

    // The bounded trace in the UD form (D's scale left pending, folded into the next update's variance
    // ρ̃) is the same recursion as the dense form's explicit scaling P ← P T / tr P: the same θ̂ and P to
    // rounding, with the bound acting (T = 5 against p0 n = 400).
    #[test]
    fn bounded_trace_ud_equals_the_dense_form() {
        for rho in [1.0, 0.95] {
            let mut a =
                RobustRls::new(4, rho, 100.0, RlsForm::Standard, Windup::Trace, Some(5.0)).unwrap();
            let mut b =
                RobustRls::new(4, rho, 100.0, RlsForm::Ud, Windup::Trace, Some(5.0)).unwrap();
            let mut acted = 0;
            for k in 0..200 {
                let (phi, y) = regressors(4, k);
                a.update(&phi, y, k).unwrap();
                b.update(&phi, y, k).unwrap();
                acted += usize::from(b.pending_var.is_some());
                assert!(
                    (a.trace() - b.trace()).abs() < 1e-9 * a.trace(),
                    "rho {rho} k {k}"
                );
            }
            assert!(acted > 0, "rho {rho}: the bound never acted");
            let (pa, pb) = (a.covariance(), b.covariance());
            for i in 0..4 {
                assert!((a.theta[i] - b.theta[i]).abs() < 1e-9 * (1.0 + a.theta[i].abs()));
                for j in 0..4 {
                    assert!((pa[(i, j)] - pb[(i, j)]).abs() < 1e-9 * (1.0 + pa[(i, j)].abs()));
                }
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
