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
//! # Speed
//!
//! An update allocates nothing. [`Rls`] (heap storage, any number of parameters n) runs every update
//! through a kernel compiled for a constant n when 1 ≤ n ≤ [`MAX_FIXED`] (the loops are fully unrolled
//! and vectorised) and through a generic loop otherwise. [`RlsN`] keeps θ̂ and P in fixed-size arrays
//! (no heap at all, for embedding one estimator per actuator). All paths do the same floating-point
//! operations in the same order as the plain loop [`Rls::update_reference`], so their results are
//! bit-for-bit equal to it:
//!
//! - P φ is summed column by column (P is symmetric, so column j of P is row j): every entry
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

/// Largest parameter count with a kernel compiled for a constant n (larger n use the generic loop).
pub const MAX_FIXED: usize = 16;

/// The RLS estimator state (θ̂, P) and its settings, with heap storage for any number of parameters.
///
/// P stays symmetric positive definite: only [`Rls::update`] and [`Rls::restart_covariance`] write it.
#[derive(Debug, Clone)]
pub struct Rls {
    /// θ̂: current parameter estimate.
    pub theta: DVector<f64>,
    /// P: the matrix proportional to the covariance of θ̂ (symmetric, positive definite; private so
    /// that only the update writes it).
    p: DMatrix<f64>,
    /// ρ: forgetting factor in (0, 1].
    pub forgetting: f64,
    /// Work vectors P φ and L̃ of the generic loop (n > MAX_FIXED).
    pphi: DVector<f64>,
    gain: DVector<f64>,
    /// The update kernel for n = θ̂.len(), chosen once in [`Rls::new`].
    kernel: Kernel,
}

/// An update kernel: (θ̂, P by columns, P φ work, L̃ work, φ, y, ρ) → ε, or (ρ + φᵀPφ, ε) on failure.
type Kernel =
    fn(&mut [f64], &mut [f64], &mut [f64], &mut [f64], &[f64], f64, f64) -> Result<f64, (f64, f64)>;

/// The kernel compiled for a constant n when n ≤ [`MAX_FIXED`], the generic loop otherwise.
fn kernel_for(n: usize) -> Kernel {
    fn fixed<const N: usize>(
        theta: &mut [f64],
        p: &mut [f64],
        _pphi: &mut [f64],
        _gain: &mut [f64],
        phi: &[f64],
        y: f64,
        rho: f64,
    ) -> Result<f64, (f64, f64)> {
        update_fixed::<N>(theta, p, phi, y, rho)
    }
    macro_rules! choose {
        ($($k:literal)*) => {
            match n {
                $($k => fixed::<$k> as Kernel,)*
                _ => update_dynamic as Kernel,
            }
        };
    }
    choose!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16)
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
}

impl RecursiveUpdate for Rls {
    fn theta(&self) -> &[f64] {
        self.theta.as_slice()
    }
    fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        Rls::update(self, phi, y, sample)
    }
    fn restart_covariance(&mut self, p0: f64) {
        Rls::restart_covariance(self, p0)
    }
    fn restart_at(&mut self, theta: &[f64], p0: f64) {
        self.theta.copy_from_slice(theta);
        Rls::restart_covariance(self, p0)
    }
    fn covariance(&self) -> DMatrix<f64> {
        self.p.clone()
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
        self.theta.copy_from_slice(theta);
        RlsN::restart_covariance(self, p0)
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
            theta: DVector::zeros(n_params),
            p: DMatrix::identity(n_params, n_params) * p0,
            forgetting,
            pphi: DVector::zeros(n_params),
            gain: DVector::zeros(n_params),
            kernel: kernel_for(n_params),
        })
    }

    /// Number of parameters n.
    pub fn n_params(&self) -> usize {
        self.theta.len()
    }

    /// P: the matrix proportional to the covariance of θ̂.
    pub fn p(&self) -> &DMatrix<f64> {
        &self.p
    }

    /// Restarts the covariance at p0 · I while keeping θ̂ (a new pass over the data starts from the
    /// previous pass's estimate).
    pub fn restart_covariance(&mut self, p0: f64) {
        self.p.fill(0.0);
        self.p.fill_diagonal(p0);
    }

    /// One update with regressor φ(k) and measurement y(k); returns the a-priori error ε(k).
    ///
    /// Uses the kernel compiled for n parameters when n ≤ [`MAX_FIXED`]. `sample` is used in the error
    /// message when P loses positive definiteness or a value is not finite; the state is left unchanged
    /// then.
    #[inline]
    pub fn update(&mut self, phi: &[f64], y: f64, sample: usize) -> Result<f64, SysidError> {
        let n = self.theta.len();
        let rho = self.forgetting;
        if phi.len() != n
            || self.p.nrows() != n
            || self.p.ncols() != n
            || self.pphi.len() != n
            || self.gain.len() != n
        {
            return Err(shape_error(n, phi.len(), self.p.shape()));
        }
        // The kernel was chosen for pphi.len() = n in `new`, and n is checked above.
        (self.kernel)(
            self.theta.as_mut_slice(),
            self.p.as_mut_slice(),
            self.pphi.as_mut_slice(),
            self.gain.as_mut_slice(),
            phi,
            y,
            rho,
        )
        .map_err(|(denom, eps)| numerical(sample, denom, eps))
    }

    /// The same update as [`Rls::update`], written as the plain textbook loop with no specialisation.
    /// Kept as the reference that the fast kernels are tested against, and for benchmarks.
    #[allow(clippy::needless_range_loop)] // the textbook index loops are the point of the reference
    pub fn update_reference(
        &mut self,
        phi: &[f64],
        y: f64,
        sample: usize,
    ) -> Result<f64, SysidError> {
        let n = self.theta.len();
        if phi.len() != n
            || self.p.nrows() != n
            || self.p.ncols() != n
            || self.pphi.len() != n
            || self.gain.len() != n
        {
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
            return Err(numerical(sample, denom, eps));
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
/// allocation, the same numbers as [`Rls`].
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
pub struct RlsN<const N: usize> {
    theta: [f64; N],
    /// P stored by columns: `p[j][i]` = P_ij (P is symmetric, so this is also P by rows).
    p: [[f64; N]; N],
    forgetting: f64,
}

impl<const N: usize> RlsN<N> {
    /// A new estimator with θ̂(0) = 0 and P(0) = p0 · I, forgetting factor ρ = `forgetting`.
    pub fn new(forgetting: f64, p0: f64) -> Result<Self, SysidError> {
        check_settings(forgetting, p0)?;
        let mut est = RlsN {
            theta: [0.0; N],
            p: [[0.0; N]; N],
            forgetting,
        };
        est.restart_covariance(p0);
        Ok(est)
    }

    /// One update with regressor φ(k) and measurement y(k); returns the a-priori error ε(k). On a
    /// numerical failure (P no longer positive definite, a non-finite value) the state is unchanged.
    #[inline]
    pub fn update(&mut self, phi: &[f64; N], y: f64, sample: usize) -> Result<f64, SysidError> {
        update_fixed::<N>(
            &mut self.theta,
            self.p.as_flattened_mut(),
            phi,
            y,
            self.forgetting,
        )
        .map_err(|(denom, eps)| numerical(sample, denom, eps))
    }

    /// Restarts the covariance at p0 · I while keeping θ̂.
    pub fn restart_covariance(&mut self, p0: f64) {
        for (j, col) in self.p.iter_mut().enumerate() {
            for (i, v) in col.iter_mut().enumerate() {
                *v = if i == j { p0 } else { 0.0 };
            }
        }
    }

    /// θ̂: the current estimate.
    pub fn theta(&self) -> &[f64; N] {
        &self.theta
    }

    /// P_ij.
    pub fn p(&self, i: usize, j: usize) -> f64 {
        self.p[j][i]
    }

    /// ρ: the forgetting factor.
    pub fn forgetting(&self) -> f64 {
        self.forgetting
    }

    /// The same state as a heap [`Rls`].
    pub fn to_dynamic(&self) -> Rls {
        Rls {
            theta: DVector::from_column_slice(&self.theta),
            p: DMatrix::from_column_slice(N, N, self.p.as_flattened()),
            forgetting: self.forgetting,
            pphi: DVector::zeros(N),
            gain: DVector::zeros(N),
            kernel: kernel_for(N),
        }
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

/// The kernel for a constant number of parameters N. `p` holds P by columns (N·N entries). Returns
/// ε, or (ρ + φᵀPφ, ε) when the update would lose positive definiteness or meet a non-finite value.
#[inline(always)]
fn update_fixed<const N: usize>(
    theta: &mut [f64],
    p: &mut [f64],
    phi: &[f64],
    y: f64,
    rho: f64,
) -> Result<f64, (f64, f64)> {
    // Fixed-length views: every index below is provably in bounds, so no check survives.
    let (theta, p, phi) = (&mut theta[..N], &mut p[..N * N], &phi[..N]);
    let mut eps = y;
    for i in 0..N {
        eps -= phi[i] * theta[i];
    }
    // (Pφ)_i = Σ_j P_ij φ_j in the order j = 0..N, accumulated column by column (vectorised over i).
    let mut pphi = [0.0; N];
    for j in 0..N {
        let col = &p[j * N..j * N + N];
        for i in 0..N {
            pphi[i] += col[i] * phi[j];
        }
    }
    let mut denom = rho;
    for i in 0..N {
        denom += phi[i] * pphi[i];
    }
    if !(denom.is_finite() && denom > 0.0 && eps.is_finite()) {
        return Err((denom, eps));
    }
    let inv = 1.0 / denom;
    let mut gain = [0.0; N];
    for i in 0..N {
        gain[i] = pphi[i] * inv;
        theta[i] += gain[i] * eps;
    }
    if rho == 1.0 {
        sym_update::<N, false>(p, &pphi, &gain, 1.0);
    } else {
        sym_update::<N, true>(p, &pphi, &gain, 1.0 / rho);
    }
    Ok(eps)
}

/// P ← (P − (Pφ) L̃ᵀ) / ρ with the upper-triangle operands for every entry: entry (i, j) is
/// (P_ij − (Pφ)_min(i,j) L̃_max(i,j)) · (1/ρ), so P stays exactly symmetric. Column j is contiguous:
/// rows i ≤ j use (Pφ)_i L̃_j, rows i > j use (Pφ)_j L̃_i.
#[inline(always)]
fn sym_update<const N: usize, const SCALE: bool>(
    p: &mut [f64],
    pphi: &[f64; N],
    gain: &[f64; N],
    inv_rho: f64,
) {
    for j in 0..N {
        let col = &mut p[j * N..j * N + N];
        let (upper, lower) = col.split_at_mut(j + 1);
        let (gj, pj) = (gain[j], pphi[j]);
        for (c, q) in upper.iter_mut().zip(&pphi[..=j]) {
            let v = *c - q * gj;
            *c = if SCALE { v * inv_rho } else { v };
        }
        for (c, g) in lower.iter_mut().zip(&gain[j + 1..]) {
            let v = *c - pj * g;
            *c = if SCALE { v * inv_rho } else { v };
        }
    }
}

/// The generic loop for any number of parameters (the same operations as [`update_fixed`]).
fn update_dynamic(
    theta: &mut [f64],
    p: &mut [f64],
    pphi: &mut [f64],
    gain: &mut [f64],
    phi: &[f64],
    y: f64,
    rho: f64,
) -> Result<f64, (f64, f64)> {
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

fn numerical(sample: usize, denom: f64, eps: f64) -> SysidError {
    SysidError::Numerical(format!(
        "RLS lost positive definiteness or met a non-finite value at sample {sample} \
         (denominator ρ + φᵀPφ = {denom:e}, error ε = {eps:e})"
    ))
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

    fn rel_diff(a: f64, b: f64) -> f64 {
        (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
    }

    // The fast kernels do the reference's operations in the same order: θ̂, P and every ε agree to 1e-12
    // relative (in fact bit for bit) for fixed-size n ≤ 16 and the generic loop (n = 17, 23), ρ < 1
    // and ρ = 1.
    #[test]
    fn fast_update_equals_reference_update_for_every_size() {
        for n in [1, 2, 3, 4, 5, 7, 9, 12, 16, 17, 23] {
            for rho in [1.0, 0.97] {
                let data = random_data(n, 300, n as u64);
                let mut fast = Rls::new(n, rho, 1e6).unwrap();
                let mut refr = Rls::new(n, rho, 1e6).unwrap();
                for (k, (phi, y)) in data.iter().enumerate() {
                    let ef = fast.update(phi, *y, k).unwrap();
                    let er = refr.update_reference(phi, *y, k).unwrap();
                    assert!(
                        rel_diff(ef, er) <= 1e-12,
                        "n={n} rho={rho} k={k}: ε {ef} vs {er}"
                    );
                }
                for i in 0..n {
                    assert!(
                        rel_diff(fast.theta[i], refr.theta[i]) <= 1e-12,
                        "n={n} θ{i}"
                    );
                    for j in 0..n {
                        assert!(
                            rel_diff(fast.p[(i, j)], refr.p[(i, j)]) <= 1e-12,
                            "n={n} P{i}{j}"
                        );
                        assert_eq!(
                            fast.p[(i, j)],
                            fast.p[(j, i)],
                            "P must stay exactly symmetric"
                        );
                    }
                }
            }
        }
    }

    // The array-backed RlsN<N> is the same estimator as the heap Rls for N = 4, 9, 16 and 20 (> MAX_FIXED).
    #[test]
    fn array_estimator_equals_reference_estimator() {
        fn check<const N: usize>() {
            let data = random_data(N, 200, 100 + N as u64);
            let mut fixed = RlsN::<N>::new(0.99, 1e4).unwrap();
            let mut refr = Rls::new(N, 0.99, 1e4).unwrap();
            for (k, (phi, y)) in data.iter().enumerate() {
                let arr: [f64; N] = phi.as_slice().try_into().unwrap();
                let ef = fixed.update(&arr, *y, k).unwrap();
                let er = refr.update_reference(phi, *y, k).unwrap();
                assert!(rel_diff(ef, er) <= 1e-12);
            }
            let dynamic = fixed.to_dynamic();
            for i in 0..N {
                assert!(rel_diff(fixed.theta()[i], refr.theta[i]) <= 1e-12);
                for j in 0..N {
                    assert!(rel_diff(dynamic.p[(i, j)], refr.p[(i, j)]) <= 1e-12);
                    assert_eq!(fixed.p(i, j), dynamic.p[(i, j)]);
                }
            }
        }
        check::<4>();
        check::<9>();
        check::<16>();
        check::<20>();
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
        assert_eq!(est.theta, before.theta);
        assert_eq!(est.p, before.p);
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
