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
//!
//! # One implementation
//!
//! The update of [`Rls`] for 1 ≤ n ≤ [`MAX_FIXED`] parameters, and of the array-backed [`RlsN`], is the
//! microcontroller crate's ([`ipa_embedded::Rls`], f64, capacity N = n: every loop has a constant trip
//! count, unrolled and vectorised, φ read one entry at a time so that a regressor built entry by entry
//! is forwarded from its stores). So `identify --method rls --passes 1`, `track` and the firmware's
//! estimator run the same code, and agree bit for bit. Larger n run a generic loop over heap storage
//! with the same operations in the same order, as the plain loop [`ReferenceRls`] (the textbook
//! reference the others are tested against, and timed against by `bench rls`):
//!
//! - P φ is summed row by row (P is symmetric, so row j of P is column j): every entry
//!   (P φ)_i still adds P_ij φ_j in the order j = 0, 1, …, n−1;
//! - with L̃ = P φ / (ρ + φᵀPφ), entry (i, j) of the new P for i ≤ j is (P_ij − (Pφ)_i L̃_j) / ρ, and the
//!   entry (j, i) below the diagonal gets the same value, computed from the same operands (P_ji = P_ij),
//!   so that P stays exactly symmetric;
//! - the division by ρ is skipped for ρ = 1 (x · 1 = x exactly).
//!
//! Flops per update for n parameters and ρ < 1, counting each multiplication, addition, subtraction and
//! division as one (see [`flops_per_update`]): ε: 2n; P φ: 2n²; ρ + φᵀPφ: 2n; 1/(ρ + φᵀPφ): 1;
//! L̃ = Pφ · (1/(ρ + φᵀPφ)): n; θ̂ += L̃ ε: 2n; the n(n+1)/2 distinct entries of P: 3 each (one
//! multiplication, one subtraction, one multiplication by 1/ρ), and 1/ρ: 1. Total 3.5 n² + 8.5 n + 2
//! (362 for n = 9). With ρ = 1 the scaling by 1/ρ drops out: 3 n² + 8 n + 1.

use nalgebra::{DMatrix, DVector};

use sysid_core::{Setting, SysidError};

/// Largest parameter count run by the microcontroller crate's update, compiled for a constant n
/// (larger n use the generic loop).
pub const MAX_FIXED: usize = 16;

/// The RLS estimator state (θ̂, P) and its settings, for any number of parameters.
///
/// P stays symmetric positive definite: only [`Rls::update`] and [`Rls::restart_covariance`] write it.
#[derive(Debug, Clone)]
pub struct Rls {
    state: State,
}

/// Generates [`State`] (one variant per constant n ≤ [`MAX_FIXED`], holding `ipa_embedded`'s estimator
/// of capacity n, and the heap loop for larger n) and `on_fixed!`, which runs an expression on the
/// embedded estimator of whichever size.
macro_rules! states {
    ($($v:ident $n:literal)*) => {
        /// The state of an [`Rls`]: the embedded estimator compiled for n, or the heap loop. Every
        /// variant is held inline (at most 2.2 kB, n = 16): the update reads it without an indirection.
        #[derive(Debug, Clone)]
        #[allow(clippy::large_enum_variant)]
        enum State {
            $(
                #[doc = concat!("n = ", stringify!($n), ".")]
                $v(ipa_embedded::Rls<f64, $n>),
            )*
            /// n > [`MAX_FIXED`] (or 0).
            Heap(Heap),
        }

        impl State {
            /// The embedded estimator of n parameters when 1 ≤ n ≤ [`MAX_FIXED`], the heap loop
            /// otherwise; θ̂(0) = 0, P(0) = p0 · I (settings already checked).
            fn new(n: usize, forgetting: f64, p0: f64) -> Result<State, SysidError> {
                let bad = |_| SysidError::Numerical(format!("RLS of {n} parameters: bad settings"));
                Ok(match n {
                    $($n => State::$v(ipa_embedded::Rls::new($n, forgetting, p0).map_err(bad)?),)*
                    _ => State::Heap(Heap::new(n, forgetting, p0)),
                })
            }
        }

        /// `on_fixed!(state, e => expr, heap => expr)`: `expr` with `e` the embedded estimator, or
        /// the second with the heap state.
        macro_rules! on_fixed {
            ($s:expr, $e:ident => $fixed:expr, $h:ident => $heap:expr) => {
                match $s {
                    $(State::$v($e) => $fixed,)*
                    State::Heap($h) => $heap,
                }
            };
        }
    };
}

states!(N1 1 N2 2 N3 3 N4 4 N5 5 N6 6 N7 7 N8 8 N9 9 N10 10 N11 11 N12 12 N13 13 N14 14 N15 15 N16 16);

/// The heap state of n > [`MAX_FIXED`] parameters: θ̂, P by columns (symmetric), ρ, P(0)'s scale and the
/// work vectors P φ and L̃.
#[derive(Debug, Clone)]
struct Heap {
    theta: DVector<f64>,
    p: DMatrix<f64>,
    forgetting: f64,
    pphi: DVector<f64>,
    gain: DVector<f64>,
}

impl Heap {
    fn new(n: usize, forgetting: f64, p0: f64) -> Heap {
        Heap {
            theta: DVector::zeros(n),
            p: DMatrix::identity(n, n) * p0,
            forgetting,
            pphi: DVector::zeros(n),
            gain: DVector::zeros(n),
        }
    }
}

/// One recursive least-squares update scheme (the paper's RLS, the fixed-size [`RlsN`], the
/// UD-factorised and windup-protected `rls_ud::RobustRls`): the estimators drive
/// them through this trait.
pub trait RecursiveUpdate {
    /// θ̂: the current estimate.
    fn theta(&self) -> &[f64];
    /// One update with regressor φ(k) and measurement y(k); returns the a-priori error ε(k). `sample`
    /// (k) names the sample in errors.
    fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError>;
    /// Restarts P at p0 · I, keeping θ̂.
    fn restart_covariance(&mut self, p0: f64);
    /// Restarts at θ̂ = `theta` (n entries) and P = p0 · I.
    fn restart_at(&mut self, theta: &[f64], p0: f64);
    /// P (times σ² the covariance of θ̂).
    fn covariance(&self) -> DMatrix<f64>;
    /// The restarts of P made to keep it positive definite (only the standard form with the trace
    /// bound makes them: `rls_ud::RobustRls::update`); `None` when there were none.
    fn covariance_resets(&self) -> Option<crate::rls_ud::CovarianceResets> {
        None
    }
}

impl RecursiveUpdate for Rls {
    fn theta(&self) -> &[f64] {
        Rls::theta(self)
    }
    fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        Rls::update(self, phi, y, sample)
    }
    fn restart_covariance(&mut self, p0: f64) {
        Rls::restart_covariance(self, p0)
    }
    fn restart_at(&mut self, theta: &[f64], p0: f64) {
        Rls::restart_at(self, theta, p0)
    }
    fn covariance(&self) -> DMatrix<f64> {
        self.p()
    }
}

impl<const N: usize> RecursiveUpdate for RlsN<N> {
    fn theta(&self) -> &[f64] {
        RlsN::theta(self)
    }
    fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        let phi: &[f64; N] = phi
            .try_into()
            .map_err(|_| shape_error(N, phi.len(), (N, N)))?;
        RlsN::update(self, phi, y, sample)
    }
    fn restart_covariance(&mut self, p0: f64) {
        RlsN::restart_covariance(self, p0)
    }
    fn restart_at(&mut self, theta: &[f64], p0: f64) {
        // θ̂ has N entries and p0 was checked when the estimator was made; a shorter θ̂ keeps the state.
        let _ = self.0.restart_at(theta, p0);
    }
    fn covariance(&self) -> DMatrix<f64> {
        DMatrix::from_fn(N, N, |i, j| self.p(i, j))
    }
}

impl Rls {
    /// A new estimator with θ̂(0) = 0 and P(0) = p0 · I.
    pub fn new(n_params: usize, forgetting: f64, p0: f64) -> Result<Self, SysidError> {
        check_settings(forgetting, p0)?;
        Ok(Rls {
            state: State::new(n_params, forgetting, p0)?,
        })
    }

    /// Number of parameters n.
    pub fn n_params(&self) -> usize {
        self.theta().len()
    }

    /// θ̂: the current estimate (n entries).
    pub fn theta(&self) -> &[f64] {
        on_fixed!(&self.state, e => e.theta().as_slice(), h => h.theta.as_slice())
    }

    /// ρ: the forgetting factor.
    pub fn forgetting(&self) -> f64 {
        on_fixed!(&self.state, e => e.forgetting(), h => h.forgetting)
    }

    /// P: the matrix proportional to the covariance of θ̂ (a copy).
    pub fn p(&self) -> DMatrix<f64> {
        let n = self.n_params();
        on_fixed!(&self.state, e => DMatrix::from_fn(n, n, |i, j| e.p(i, j)), h => h.p.clone())
    }

    /// Restarts the covariance at p0 · I while keeping θ̂ (a new pass over the data starts from the
    /// previous pass's estimate).
    pub fn restart_covariance(&mut self, p0: f64) {
        on_fixed!(&mut self.state, e => {
            let theta = *e.theta();
            // p0 is positive and finite (the callers' settings are checked) and θ̂ has n entries.
            let _ = e.restart_at(&theta, p0);
        }, h => {
            h.p.fill(0.0);
            h.p.fill_diagonal(p0);
        })
    }

    /// Restarts at θ̂ = `theta` (n entries; a shorter one leaves θ̂ as it is) and P = p0 · I.
    pub fn restart_at(&mut self, theta: &[f64], p0: f64) {
        on_fixed!(&mut self.state, e => {
            let _ = e.restart_at(theta, p0);
        }, h => {
            if theta.len() == h.theta.len() {
                h.theta.copy_from_slice(theta);
            }
            h.p.fill(0.0);
            h.p.fill_diagonal(p0);
        })
    }

    /// One update with regressor φ(k) and measurement y(k); returns the a-priori error ε(k).
    ///
    /// `sample` is used in the error message when P loses positive definiteness or a value is not
    /// finite; the state is left unchanged then.
    #[inline]
    pub fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        self.try_update(phi, y, sample).map_err(|e| match e {
            UpdateError::Shape(e) => e,
            UpdateError::Failure(f) => f.into_error(),
        })
    }

    /// [`Rls::update`] with a refused update kept as its numbers ([`RlsFailure`]), for a caller that
    /// words the advice in its own terms (the Python package's `Rls` names its own arguments, not the
    /// command line's flags); a regressor of the wrong length is [`UpdateError::Shape`].
    #[inline]
    pub fn try_update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, UpdateError> {
        let n = self.n_params();
        if phi.len() != n {
            return Err(UpdateError::Shape(shape_error(n, phi.len(), (n, n))));
        }
        on_fixed!(&mut self.state, e => {
            let rho = e.forgetting();
            e.update(phi, y).map_err(|_| {
                UpdateError::Failure(failure(sample, e.theta().as_slice(), |i, j| e.p(i, j), phi, y, rho))
            })
        }, h => {
            let rho = h.forgetting;
            update_heap(h, phi, y).map_err(|(denominator, error)| {
                UpdateError::Failure(RlsFailure { sample, denominator, error, forgetting: rho })
            })
        })
    }
}

/// Why [`Rls::try_update`] refused an update (the state unchanged).
#[derive(Debug)]
pub enum UpdateError {
    /// The regressor's length is not n.
    Shape(SysidError),
    /// P lost positive definiteness or a value was not finite.
    Failure(RlsFailure),
}

/// A refused RLS update, as numbers: what the update met and the forgetting factor that decides the
/// likely cause ([`RlsFailure::windup_likely`]). The command line's words are
/// [`RlsFailure::into_error`]; another surface words the advice in its own terms after
/// [`RlsFailure::what`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RlsFailure {
    /// The sample (update) number given to the update.
    pub sample: usize,
    /// The denominator ρ + φᵀPφ the update met.
    pub denominator: f64,
    /// The a-priori error ε = y − φᵀθ̂ it met.
    pub error: f64,
    /// ρ: the estimator's forgetting factor.
    pub forgetting: f64,
}

impl RlsFailure {
    /// What happened, with the numbers (no advice).
    pub fn what(&self) -> String {
        let (sample, denom, eps) = (self.sample, self.denominator, self.error);
        format!(
            "RLS lost positive definiteness or met a non-finite value at sample {sample} \
             (denominator ρ + φᵀPφ = {denom:e}, error ε = {eps:e})"
        )
    }

    /// Whether covariance windup is the likely cause: forgetting ρ < 1 ([`windup_advice`]).
    pub fn windup_likely(&self) -> bool {
        self.forgetting < 1.0
    }

    /// The error with the command line's advice (its flags).
    pub fn into_error(self) -> SysidError {
        numerical(self.sample, self.denominator, self.error, self.forgetting)
    }
}

/// The textbook loop of the update, with no specialisation: the reference that [`Rls`] is tested
/// against (the same operations in the same order, so the same numbers bit for bit), and that
/// `bench rls` times beside it.
#[derive(Debug, Clone)]
pub struct ReferenceRls {
    /// θ̂: current parameter estimate.
    pub theta: DVector<f64>,
    /// P (symmetric).
    pub p: DMatrix<f64>,
    /// ρ: forgetting factor in (0, 1].
    pub forgetting: f64,
    pphi: DVector<f64>,
}

impl ReferenceRls {
    /// A new estimator with θ̂(0) = 0 and P(0) = p0 · I.
    pub fn new(n_params: usize, forgetting: f64, p0: f64) -> Result<Self, SysidError> {
        check_settings(forgetting, p0)?;
        Ok(ReferenceRls {
            theta: DVector::zeros(n_params),
            p: DMatrix::identity(n_params, n_params) * p0,
            forgetting,
            pphi: DVector::zeros(n_params),
        })
    }

    /// One update (see [`Rls::update`]).
    #[allow(clippy::needless_range_loop)] // the textbook index loops are the point of the reference
    pub fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        let n = self.theta.len();
        if phi.len() != n {
            return Err(shape_error(n, phi.len(), self.p.shape()));
        }
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
        if !(denom.is_finite() && denom > 0.0 && eps.is_finite()) {
            return Err(numerical(sample, denom, eps, self.forgetting));
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

/// An RLS estimator for exactly `N` parameters with θ̂ and P in fixed-size arrays: no heap, no
/// allocation, the same numbers as [`Rls`] (the microcontroller crate's estimator, with `sysid`'s
/// errors).
///
/// ```
/// use sysid::rls::RlsN;
/// // y = 2 φ0 − φ1, noise-free: two independent regressors and a large P(0) give θ̂ ≈ (2, −1).
/// let mut est = RlsN::<2>::new(1.0, 1e8).unwrap();
/// est.update(&[1.0, 0.0], 2.0, 0).unwrap();
/// est.update(&[0.0, 1.0], -1.0, 1).unwrap();
/// assert!((est.theta()[0] - 2.0).abs() < 1e-6 && (est.theta()[1] + 1.0).abs() < 1e-6);
/// ```
#[derive(Debug, Clone, Copy)]
pub struct RlsN<const N: usize>(ipa_embedded::Rls<f64, N>);

impl<const N: usize> RlsN<N> {
    /// A new estimator with θ̂(0) = 0 and P(0) = p0 · I, forgetting factor ρ = `forgetting` (N ≥ 1).
    pub fn new(forgetting: f64, p0: f64) -> Result<Self, SysidError> {
        check_settings(forgetting, p0)?;
        ipa_embedded::Rls::new(N, forgetting, p0)
            .map(RlsN)
            .map_err(|_| shape_error(N, N, (N, N)))
    }

    /// One update with regressor φ(k) and measurement y(k); returns the a-priori error ε(k). On a
    /// numerical failure (P no longer positive definite, a non-finite value) the state is unchanged.
    #[inline]
    pub fn update(&mut self, phi: &[f64; N], y: f64, sample: usize) -> Result<f64, SysidError> {
        let est = &mut self.0;
        let rho = est.forgetting();
        est.update(phi, y)
            .map_err(|_| failure(sample, est.theta(), |i, j| est.p(i, j), phi, y, rho).into_error())
    }

    /// Restarts the covariance at p0 · I while keeping θ̂ (p0 positive and finite, else nothing changes).
    pub fn restart_covariance(&mut self, p0: f64) {
        let theta = *self.0.theta();
        let _ = self.0.restart_at(&theta, p0);
    }

    /// θ̂: the current estimate.
    pub fn theta(&self) -> &[f64; N] {
        self.0.theta()
    }

    /// P_ij.
    pub fn p(&self, i: usize, j: usize) -> f64 {
        self.0.p(i, j)
    }

    /// ρ: the forgetting factor.
    pub fn forgetting(&self) -> f64 {
        self.0.forgetting()
    }
}

/// Flops of one update for `n` parameters (each multiplication, addition, subtraction and division
/// counted as one; the symmetric update of P counted over its n(n+1)/2 distinct entries): 3.5 n² +
/// 8.5 n + 2 for ρ < 1 and 3 n² + 8 n + 1 for ρ = 1. See the module documentation for the breakdown.
pub fn flops_per_update(n: usize, forgetting: f64) -> f64 {
    let n = n as f64;
    let tri = n * (n + 1.0) / 2.0;
    let scale = if forgetting == 1.0 { 0.0 } else { tri + 1.0 };
    2.0 * n + 2.0 * n * n + 2.0 * n + 1.0 + n + 2.0 * n + 2.0 * tri + scale
}

/// The generic loop for n > [`MAX_FIXED`] parameters on the heap state (the operations of
/// `ipa_embedded::Rls::update` in the same order). Returns ε, or (ρ + φᵀPφ, ε) on failure with the
/// state unchanged.
fn update_heap(h: &mut Heap, phi: &[f64], y: f64) -> Result<f64, (f64, f64)> {
    let rho = h.forgetting;
    let (theta, p, pphi, gain) = (
        h.theta.as_mut_slice(),
        h.p.as_mut_slice(),
        h.pphi.as_mut_slice(),
        h.gain.as_mut_slice(),
    );
    let n = theta.len();
    let (p, phi, pphi, gain) = (&mut p[..n * n], &phi[..n], &mut pphi[..n], &mut gain[..n]);
    let mut eps = y;
    for (f, t) in phi.iter().zip(theta.iter()) {
        eps -= f * t;
    }
    pphi.fill(0.0);
    for (col, f) in p.chunks_exact(n).zip(phi) {
        for (acc, c) in pphi.iter_mut().zip(col) {
            *acc += c * f;
        }
    }
    let mut denom = rho;
    for (f, q) in phi.iter().zip(pphi.iter()) {
        denom += f * q;
    }
    if !(denom.is_finite() && denom > 0.0 && eps.is_finite()) {
        return Err((denom, eps));
    }
    let inv = 1.0 / denom;
    let inv_rho = 1.0 / rho;
    // θ̂ += L̃ ε with L̃ = Pφ / denom, computed as (Pφ · inv) · ε like the reference.
    for ((t, q), g) in theta.iter_mut().zip(pphi.iter()).zip(gain.iter_mut()) {
        *g = q * inv;
        *t += *g * eps;
    }
    for (j, col) in p.chunks_exact_mut(n).enumerate() {
        let (pj, gj) = (pphi[j], gain[j]);
        let (upper, lower) = col.split_at_mut(j + 1);
        // (x − a b) · 1/ρ; for ρ = 1 the multiplication by 1 is exact, so no branch is needed.
        for (c, q) in upper.iter_mut().zip(&pphi[..=j]) {
            *c = (*c - q * gj) * inv_rho;
        }
        for (c, g) in lower.iter_mut().zip(&gain[j + 1..]) {
            *c = (*c - pj * g) * inv_rho;
        }
    }
    Ok(eps)
}

/// The error of an update refused by the embedded estimator (its state unchanged), with the values it
/// met: ε = y − φᵀθ̂ and ρ + φᵀPφ recomputed from that state in the update's order.
fn failure(
    sample: usize,
    theta: &[f64],
    p: impl Fn(usize, usize) -> f64,
    phi: &[f64],
    y: f64,
    rho: f64,
) -> RlsFailure {
    let mut eps = y;
    for (f, t) in phi.iter().zip(theta) {
        eps -= f * t;
    }
    let mut denom = rho;
    for (i, fi) in phi.iter().enumerate() {
        let mut q = 0.0;
        for (j, fj) in phi.iter().enumerate() {
            q += p(i, j) * fj;
        }
        denom += fi * q;
    }
    RlsFailure {
        sample,
        denominator: denom,
        error: eps,
        forgetting: rho,
    }
}

fn numerical(sample: usize, denom: f64, eps: f64, rho: f64) -> SysidError {
    let what = RlsFailure {
        sample,
        denominator: denom,
        error: eps,
        forgetting: rho,
    }
    .what();
    SysidError::Numerical(if rho < 1.0 {
        format!("{what}; {}", windup_advice(rho))
    } else {
        format!(
            "{what}; this usually means P(0) is too large \
             for the signals' magnitude (large numbers, e.g. µm or Pa: the rounding of P − Pφφᵀ P/δ then \
             exceeds its smallest entries): try --rls-form ud (the factorised update stays positive \
             definite), a smaller --p0, rescaled signals, or --method ls"
        )
    })
}

/// Why an RLS with forgetting ρ < 1 most likely failed, and what helps (audit s33 L-6: the message
/// blamed P(0) and scaling, and its remedy, the UD form, fails the same way): covariance windup. While
/// the regressor does not excite a direction, P grows by 1/ρ per sample in it until it overflows, after
/// about ln(1e308/P(0))/ln(1/ρ) samples (34 000 at ρ = 0.98 from P(0) = 1e6), whatever P(0) or the
/// covariance form.
pub(crate) fn windup_advice(rho: f64) -> String {
    format!(
        "with forgetting ρ = {rho} < 1 the likely cause is covariance windup: while the input does not \
         excite (a rest, a constant command) P grows by 1/ρ per sample until it overflows, whatever P(0) or \
         the covariance form (a smaller P(0) only delays it); bound P (--windup trace, with --max-trace), \
         use ρ = 1 (--forgetting 1), or leave the unexciting stretch out of the record (Python Rls: \
         restart_covariance(p0) after a rest, or forgetting=1); if the input kept exciting, P(0) may be \
         too large for the signals' magnitude instead: a smaller --p0 (Python: p0), rescaled signals, or \
         --method ls"
    )
}

fn shape_error(n: usize, got: usize, p_shape: (usize, usize)) -> SysidError {
    SysidError::Numerical(format!(
        "RLS regressor has {got} entries but the estimator has {n} parameters (P is {}x{})",
        p_shape.0, p_shape.1
    ))
}

/// Checks ρ ∈ (0, 1] and P(0) > 0.
pub fn check_settings(forgetting: f64, p0: f64) -> Result<(), SysidError> {
    if !(forgetting > 0.0 && forgetting <= 1.0) {
        return Err(SysidError::setting(
            Setting::Forgetting,
            forgetting,
            "a forgetting factor in (0, 1]",
        ));
    }
    if !(p0.is_finite() && p0 > 0.0) {
        return Err(SysidError::setting(
            Setting::P0,
            p0,
            "a positive, finite initial covariance scale",
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Random regressors and outputs y = φᵀθ* + noise, with occasional exact zeros in φ.
    fn random_data(n: usize, samples: usize, seed: u64) -> Vec<(Vec<f64>, f64)> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let truth: Vec<f64> = (0..n).map(|_| rng.gen_range(-2.0..2.0)).collect();
        (0..samples)
            .map(|_| {
                let phi: Vec<f64> = (0..n)
                    .map(|_| {
                        if rng.gen_bool(0.1) {
                            0.0
                        } else {
                            rng.gen_range(-100.0..100.0)
                        }
                    })
                    .collect();
                let y = phi.iter().zip(&truth).map(|(a, b)| a * b).sum::<f64>()
                    + rng.gen_range(-0.5..0.5);
                (phi, y)
            })
            .collect()
    }

    // The embedded kernels (n ≤ 16) and the heap loop (n = 17, 23) do the reference's operations in the
    // same order: θ̂, P and every ε agree bit for bit, for ρ < 1 and ρ = 1, and P stays exactly
    // symmetric.
    #[test]
    fn fast_update_equals_reference_update_for_every_size() {
        for n in [1, 2, 3, 4, 5, 7, 9, 12, 16, 17, 23] {
            for rho in [1.0, 0.97] {
                let data = random_data(n, 300, n as u64);
                let mut fast = Rls::new(n, rho, 1e6).unwrap();
                let mut refr = ReferenceRls::new(n, rho, 1e6).unwrap();
                for (k, (phi, y)) in data.iter().enumerate() {
                    let ef = fast.update(phi, *y, k).unwrap();
                    let er = refr.update(phi, *y, k).unwrap();
                    assert_eq!(
                        ef.to_bits(),
                        er.to_bits(),
                        "n={n} rho={rho} k={k}: ε {ef} vs {er}"
                    );
                }
                let p = fast.p();
                for i in 0..n {
                    assert_eq!(
                        fast.theta()[i].to_bits(),
                        refr.theta[i].to_bits(),
                        "n={n} θ{i}"
                    );
                    for j in 0..n {
                        assert_eq!(
                            p[(i, j)].to_bits(),
                            refr.p[(i, j)].to_bits(),
                            "n={n} P{i}{j}"
                        );
                        assert_eq!(p[(i, j)], p[(j, i)], "P must stay exactly symmetric");
                    }
                }
            }
        }
    }

    // The array-backed RlsN<N> is the same estimator as the reference for N = 4, 9 and 16, and a pass
    // restarted at θ̂ with P = p0 I continues as the reference does.
    #[test]
    fn array_estimator_equals_reference_estimator() {
        fn check<const N: usize>() {
            let data = random_data(N, 200, 100 + N as u64);
            let mut fixed = RlsN::<N>::new(0.99, 1e4).unwrap();
            let mut refr = ReferenceRls::new(N, 0.99, 1e4).unwrap();
            for pass in 0..2 {
                if pass == 1 {
                    fixed.restart_covariance(1e4);
                    refr.p = DMatrix::identity(N, N) * 1e4;
                }
                for (k, (phi, y)) in data.iter().enumerate() {
                    let arr: [f64; N] = phi.as_slice().try_into().unwrap();
                    let ef = fixed.update(&arr, *y, k).unwrap();
                    let er = refr.update(phi, *y, k).unwrap();
                    assert_eq!(ef.to_bits(), er.to_bits());
                }
            }
            for i in 0..N {
                assert_eq!(fixed.theta()[i].to_bits(), refr.theta[i].to_bits());
                for j in 0..N {
                    assert_eq!(fixed.p(i, j).to_bits(), refr.p[(i, j)].to_bits());
                }
            }
        }
        check::<4>();
        check::<9>();
        check::<16>();
    }

    // One update from θ̂ = 0, P = p0 I with φ = (1, 2), y = 5, ρ = 1: φᵀPφ = 5 p0, so
    // θ̂ = p0 φ y / (1 + 5 p0) and P = p0 I − p0² φφᵀ / (1 + 5 p0). Hand-derived, p0 = 2.
    #[test]
    fn single_update_matches_the_hand_computed_rank_one_correction() {
        let mut est = RlsN::<2>::new(1.0, 2.0).unwrap();
        let eps = est.update(&[1.0, 2.0], 5.0, 0).unwrap();
        assert_eq!(eps, 5.0);
        let d = 1.0 + 5.0 * 2.0;
        assert!((est.theta()[0] - 2.0 * 5.0 / d).abs() < 1e-15);
        assert!((est.theta()[1] - 4.0 * 5.0 / d).abs() < 1e-15);
        assert!((est.p(0, 0) - (2.0 - 4.0 / d)).abs() < 1e-15);
        assert!((est.p(0, 1) - (-8.0 / d)).abs() < 1e-15);
        assert!((est.p(1, 1) - (2.0 - 16.0 / d)).abs() < 1e-15);
    }

    // A non-finite measurement is refused with the sample index and the state is left unchanged.
    #[test]
    fn non_finite_measurement_is_refused_without_changing_the_state() {
        let mut est = Rls::new(3, 1.0, 10.0).unwrap();
        est.update(&[1.0, 2.0, 3.0], 1.0, 0).unwrap();
        let before = est.clone();
        let e = est.update(&[1.0, 0.5, 0.0], f64::NAN, 7).unwrap_err();
        assert!(
            e.is_numerical() && e.to_string().contains("sample 7"),
            "{e}"
        );
        assert!(e.to_string().contains("ε = NaN"), "{e}");
        assert_eq!(est.theta(), before.theta());
        assert_eq!(est.p(), before.p());
        // A regressor that makes φᵀPφ overflow: the message gives the denominator the update met,
        // ρ + φᵀPφ = 1 + 10 · (1e200)² = +∞ (P = 10 I before any update).
        let mut fresh = Rls::new(2, 1.0, 10.0).unwrap();
        let e = fresh.update(&[1e200, 0.0], 0.0, 3).unwrap_err();
        assert!(e.to_string().contains("ρ + φᵀPφ = inf"), "{e}");
    }

    // A regressor of the wrong length is an error, not a panic.
    #[test]
    fn regressor_of_wrong_length_is_an_error() {
        let mut est = Rls::new(3, 1.0, 10.0).unwrap();
        assert!(est.update(&[1.0, 2.0], 1.0, 0).is_err());
    }

    // Flop count: n = 9, ρ < 1: 3.5·81 + 8.5·9 + 2 = 362; ρ = 1: 3·81 + 8·9 + 1 = 316.
    #[test]
    fn flop_count_follows_the_closed_form() {
        assert_eq!(flops_per_update(9, 0.99), 362.0);
        assert_eq!(flops_per_update(9, 1.0), 316.0);
    }
}
