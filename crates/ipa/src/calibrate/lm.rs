//! Levenberg–Marquardt with box bounds for a residual vector r(θ) that is only available by simulation.
//!
//! Minimises V(θ) = ½ ‖r(θ)‖² over lo <= θ <= hi (Moré 1978, Nocedal & Wright §10.3): the Jacobian J
//! by forward differences, one column per parameter, computed in parallel (rayon); the step solves
//! (JᵀJ + λ D) δ = −Jᵀr with D = diag(JᵀJ) (scale invariant, floored), is projected onto the box, and
//! is scaled so that no coordinate moves by more than `max_step`,
//! is accepted only when V decreases (λ / 3), else λ × 4 and the step is solved again with the same J.
//! A failed simulation (NaN, numerical error) counts as an infinite V. The returned θ is never worse
//! than the start.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Why the search stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Termination {
    /// The relative decrease of V over an accepted step fell below the tolerance.
    Converged,
    /// The projected step became negligible (θ changes by less than 1e-9).
    SmallStep,
    /// No step along the damped directions decreased V (λ reached its upper limit).
    NoDescent,
    /// The iteration limit was reached.
    MaxIterations,
    /// The residual could not be evaluated at the start.
    StartFailed,
}

impl std::fmt::Display for Termination {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Termination::Converged => "converged",
            Termination::SmallStep => "step below tolerance",
            Termination::NoDescent => "no further descent",
            Termination::MaxIterations => "iteration limit reached",
            Termination::StartFailed => "simulation failed at the start",
        })
    }
}

/// The result of [`minimise`].
#[derive(Debug, Clone)]
pub struct Solution {
    /// The estimate θ (never worse than the start).
    pub theta: Vec<f64>,
    /// V(θ) at the estimate.
    pub cost: f64,
    /// V at the start.
    pub start_cost: f64,
    /// Jacobian at `theta` (rows: residuals, columns: parameters); `None` when it could not be evaluated.
    pub jacobian: Option<DMatrix<f64>>,
    /// Number m of residuals.
    pub residual_len: usize,
    /// Iterations (Jacobians) taken.
    pub iterations: usize,
    /// Evaluations of the residual (simulations).
    pub evaluations: usize,
    /// Why the search stopped.
    pub termination: Termination,
}

/// Settings of the search.
#[derive(Debug, Clone, Copy)]
pub struct Settings {
    /// Largest number of iterations.
    pub max_iterations: usize,
    /// Relative decrease of V below which the search has converged.
    pub tolerance: f64,
    /// Forward-difference step in θ.
    pub fd_step: f64,
    /// Largest change of any coordinate of θ in one iteration.
    pub max_step: f64,
}

fn cost(r: &[f64]) -> f64 {
    0.5 * r.iter().map(|x| x * x).sum::<f64>()
}

/// Forward-difference Jacobian at θ with residual r0; columns whose simulations fail are tried
/// backwards, then left zero. Columns are computed in parallel.
pub fn jacobian<F>(f: &F, theta: &[f64], r0: &[f64], lo: &[f64], hi: &[f64], h: f64) -> DMatrix<f64>
where
    F: Fn(&[f64]) -> Option<Vec<f64>> + Sync,
{
    let n = r0.len();
    let cols: Vec<Vec<f64>> = (0..theta.len())
        .into_par_iter()
        .map(|j| {
            let mut column = vec![0.0; n];
            for sign in [1.0, -1.0] {
                let mut t = theta.to_vec();
                let step = if (sign > 0.0 && t[j] + h > hi[j]) || (sign < 0.0 && t[j] - h < lo[j]) {
                    continue;
                } else {
                    sign * h
                };
                t[j] += step;
                if let Some(r) = f(&t) {
                    if r.len() == n && r.iter().all(|x| x.is_finite()) {
                        for (c, (a, b)) in column.iter_mut().zip(r.iter().zip(r0)) {
                            *c = (a - b) / step;
                        }
                        break;
                    }
                }
            }
            column
        })
        .collect();
    DMatrix::from_fn(n, theta.len(), |i, j| cols[j][i])
}

/// Minimises ½‖f(θ)‖² from `theta0` within [lo, hi].
pub fn minimise<F>(f: &F, theta0: &[f64], lo: &[f64], hi: &[f64], s: &Settings) -> Solution
where
    F: Fn(&[f64]) -> Option<Vec<f64>> + Sync,
{
    let p = theta0.len();
    let mut theta: Vec<f64> = theta0
        .iter()
        .zip(lo.iter().zip(hi))
        .map(|(&t, (&l, &h))| t.clamp(l, h))
        .collect();
    let mut evaluations = 1;
    let Some(mut r) = f(&theta).filter(|r| r.iter().all(|x| x.is_finite())) else {
        return Solution {
            theta,
            cost: f64::INFINITY,
            start_cost: f64::INFINITY,
            jacobian: None,
            residual_len: 0,
            iterations: 0,
            evaluations,
            termination: Termination::StartFailed,
        };
    };
    let start_cost = cost(&r);
    let mut v = start_cost;
    let mut lambda = 1e-3;
    let mut termination = Termination::MaxIterations;
    let mut iterations = 0;
    let mut jac = None;
    if p == 0 {
        termination = Termination::Converged;
    }
    while p > 0 && iterations < s.max_iterations {
        iterations += 1;
        let j = jacobian(f, &theta, &r, lo, hi, s.fd_step);
        evaluations += p;
        let jt = j.transpose();
        let jtj = &jt * &j;
        let g = &jt * DVector::from_column_slice(&r);
        let dmax = (0..p).map(|i| jtj[(i, i)]).fold(0.0f64, f64::max);
        let d: Vec<f64> = (0..p)
            .map(|i| jtj[(i, i)].max(1e-9 * dmax).max(1e-300))
            .collect();
        jac = Some(j);
        let mut accepted = false;
        while lambda < 1e12 {
            let mut a = jtj.clone();
            for i in 0..p {
                a[(i, i)] += lambda * d[i];
            }
            let Some(mut delta) = a.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 4.0;
                continue;
            };
            // Trust region in θ: no coordinate moves by more than `max_step` in one iteration (a
            // step of 0.3 in ln is 35 %), so the search cannot jump into a far basin of the
            // stick-slip cost.
            let longest = delta.amax();
            if longest > s.max_step {
                delta *= s.max_step / longest;
            }
            let trial: Vec<f64> = (0..p)
                .map(|i| (theta[i] + delta[i]).clamp(lo[i], hi[i]))
                .collect();
            let step = (0..p)
                .map(|i| (trial[i] - theta[i]).abs())
                .fold(0.0, f64::max);
            if step < 1e-9 {
                termination = Termination::SmallStep;
                break;
            }
            evaluations += 1;
            let rt = f(&trial).filter(|r| r.iter().all(|x| x.is_finite()));
            let vt = rt.as_ref().map_or(f64::INFINITY, |r| cost(r));
            if vt < v {
                let decrease = (v - vt) / v.max(1e-300);
                theta = trial;
                r = rt.unwrap_or_default();
                v = vt;
                lambda = (lambda / 3.0).max(1e-9);
                accepted = true;
                if decrease < s.tolerance {
                    termination = Termination::Converged;
                }
                break;
            }
            lambda *= 4.0;
        }
        if !accepted {
            if termination != Termination::SmallStep {
                termination = Termination::NoDescent;
            }
            break;
        }
        if termination == Termination::Converged {
            break;
        }
    }
    // The Jacobian at the final θ, for the standard deviations (the last one was taken before the
    // last accepted step).
    if p > 0 && iterations > 0 {
        jac = Some(jacobian(f, &theta, &r, lo, hi, s.fd_step));
        evaluations += p;
    }
    Solution {
        theta,
        cost: v,
        start_cost,
        jacobian: jac,
        residual_len: r.len(),
        iterations,
        evaluations,
        termination,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Rosenbrock as least squares, r = (10 (θ2 − θ1²), 1 − θ1): minimum at (1, 1).
    #[test]
    fn finds_the_rosenbrock_minimum() {
        let f = |t: &[f64]| Some(vec![10.0 * (t[1] - t[0] * t[0]), 1.0 - t[0]]);
        let s = Settings {
            max_iterations: 200,
            tolerance: 1e-14,
            fd_step: 1e-7,
            max_step: 10.0,
        };
        let sol = minimise(&f, &[-1.2, 1.0], &[-5.0, -5.0], &[5.0, 5.0], &s);
        assert!(
            (sol.theta[0] - 1.0).abs() < 1e-4 && (sol.theta[1] - 1.0).abs() < 1e-4,
            "{sol:?}"
        );
    }

    // With the unconstrained minimum (3) outside the box [0, 2], the bounded minimum is the bound 2.
    #[test]
    fn stops_at_an_active_bound() {
        let f = |t: &[f64]| Some(vec![t[0] - 3.0]);
        let s = Settings {
            max_iterations: 50,
            tolerance: 1e-14,
            fd_step: 1e-7,
            max_step: 10.0,
        };
        let sol = minimise(&f, &[0.5], &[0.0], &[2.0], &s);
        assert!((sol.theta[0] - 2.0).abs() < 1e-12, "{sol:?}");
        assert!(sol.cost <= sol.start_cost);
    }
}
