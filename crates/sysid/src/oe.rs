//! Output-error (prediction-error with an output-error noise model) refinement: minimise the free-run
//! simulation error V(θ) = ½ Σ_{k >= k0} (y(k) − ŷ(k; θ))² over every parameter of the model, by a
//! Levenberg–Marquardt search constrained to stable models, started from a least-squares estimate.
//!
//! Why: LS/RLS minimise the *equation* error, which is biased when noise enters at the output (an
//! encoder's quantisation and noise). The simulation error does not regress on noisy past outputs, so its
//! minimiser is consistent under white output noise (Ljung, *System Identification*, ch. 7–8).
//!
//! Parameter vector (the physical layout of [`Parameterisation`]):
//! - Hammerstein: θ = [b_l, b_r, m_l, m_r, a1..a_na, b2..b_nb, (c)], b1 = 1 fixed (normalisation);
//! - ARX: θ = [a1..a_na, b1..b_nb, (c)].
//!
//! The simulation is ŷ(k) = η_k for k < k0 and ŷ(k) = −Σ a_i ŷ(k−i) + Σ_j b_j x(k−nk−j+1) + c after,
//! x = f(u) the deadzone (paper eq. 1). The initial outputs η_0..η_{k0−1} are estimated with the model
//! (MATLAB `oe` with `InitialCondition = 'estimate'`), starting from the measured y(0..k0−1), and the
//! residuals run over every sample, y(k) − ŷ(k) for k = 0..N−1. Taking the *measured* initial outputs
//! instead (as [`Model::simulate`] does for validation) is fatal for a near-integrator under output noise:
//! the noise on y(1) − y(0) is an initial velocity error that the simulation integrates for the whole
//! record (with the paper's model, 0.01 mm of noise drifts by millimetres), and the optimiser then fits
//! the drift rather than the dynamics.
//!
//! Jacobian: analytic, by sensitivity filtering. For each parameter q the sensitivity s_q(k) = ∂ŷ(k)/∂q
//! obeys A(q⁻¹) s_q(k) = g_q(k) with s_q(k) = 0 for k < k0 (for η_j: s(j) = 1, g = 0), where
//! g = −ŷ(k−i) for a_i, x(k−nk−j+1) for b_j, 1 for c, and Σ_j b_j ∂x(k−nk−j+1)/∂q for the deadzone with
//! ∂x/∂m_r = h_r (u − b_r), ∂x/∂b_r = −m_r h_r, ∂x/∂m_l = h_l (u − b_l), ∂x/∂b_l = −m_l h_l
//! (h_r = [u ≥ b_r], h_l = [u ≤ b_l]). The deadzone is not differentiable at u = b: there the one-sided
//! derivative of the branch the sample lies on is used (the breakpoint's derivative is −m·h). Since the
//! commands take finitely many values, the kinks form a set of measure zero in parameter space and the
//! loss is smooth between them; a step that moves a breakpoint across a command level is judged by the
//! actual loss (the trust-region ratio), so the kink cannot mislead the optimiser into a worse point.
//!
//! Stability is enforced during the search, as MATLAB's `oe` does: an unstable start (an unstable LS
//! estimate) is first stabilised by reflecting the poles of A outside the unit circle into it
//! (p → 1/p̄), and a trial step whose A has a pole beyond [`MAX_POLE_MODULUS`] (Jury's test,
//! [`sysid_core::model::is_stable_polynomial_within`]) is halved until it stays inside (projected onto
//! that circle if 20 halvings do not suffice) before its loss is evaluated.
//! Without this, a finite record lets an unstable model fit well with estimated initial outputs that
//! cancel its unstable mode — and then diverge in any other use. An iterate whose simulation exceeds
//! 10⁶ (1 + max|y|) or becomes non-finite counts as an infinite loss (step rejected, damping raised).
//!
//! The search (Levenberg–Marquardt with Marquardt's scaling, Moré 1978): at θ with residuals r and
//! Jacobian J = ∂ŷ/∂θ, the step δ minimises ‖r − J δ‖² + λ ‖D δ‖² (D = the column norms of J), solved by
//! QR of the stacked matrix [J; √λ D] ([`crate::ls::solve`], never the normal equations). A step that
//! lowers the loss is taken and λ shrinks by 3; otherwise λ grows by 4 and the step is retried. It stops
//! when a taken step lowers the loss by less than 1.5e-8 relative or moves θ by less than 1.5e-8 relative
//! (√ε, MINPACK's defaults)
//! (converged), when λ exceeds 1e16 (no further improvement possible), or at the iteration cap.
//!
//! Standard deviations: σ̂² (JᵀJ)⁻¹ with J the final Jacobian and σ̂² = 2 V / (N − p).

use std::cell::Cell;

use nalgebra::{Complex, DMatrix, DVector};

use crate::estimate::Param;
use crate::ls;
use sysid_core::model::{is_stable_polynomial_within, poles_of};
use sysid_core::param::{Layout, Parameterisation};
use sysid_core::{
    Dataset, Deadzone, Model, ModelKind, NoiseModel, ParamName, Structure, SysidError,
};

/// The result of an output-error refinement.
#[derive(Debug, Clone)]
pub struct OeFit {
    /// The refined model.
    pub model: Model,
    /// Physical parameters with standard deviations from σ̂² (JᵀJ)⁻¹ (`None` for fixed ones).
    pub params: Vec<Param>,
    /// Number of Jacobian evaluations (Levenberg–Marquardt iterations).
    pub iterations: usize,
    /// Number of residual evaluations.
    pub evaluations: usize,
    /// How the search stopped.
    pub stop: OeStop,
    /// Trial steps whose A was unstable and that were projected into the stable region.
    pub projected_steps: usize,
    /// Σ (y − ŷ)² at the start and at the end.
    pub rss_start: f64,
    /// Σ (y − ŷ)² of the refined model.
    pub rss: f64,
    /// σ̂² = RSS / (N − p_free − k0).
    pub noise_variance: f64,
    /// The estimated initial outputs η_0..η_{k0−1}.
    pub initial_outputs: Vec<f64>,
    /// The start had to be stabilised.
    pub stabilised_start: bool,
}

/// Why the output-error search stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OeStop {
    /// A taken step lowered the loss by less than the relative tolerance.
    CostConverged,
    /// A taken step moved the parameters by less than the relative tolerance.
    StepConverged,
    /// The gradient vanished (the start is already a stationary point).
    GradientZero,
    /// No step lowers the loss any more (the damping exceeded its bound): a local minimum at the
    /// resolution of f64, or a kink of the deadzone loss.
    NoImprovement,
    /// The best model lies on the stability boundary (a pole held at |p| = [`MAX_POLE_MODULUS`]: an
    /// integrating plant); steps projected onto it no longer lower the loss noticeably.
    StabilityBoundary,
    /// The iteration cap was reached first.
    IterationLimit,
}

impl OeStop {
    /// True for the convergence criteria (not the cap).
    pub fn converged(&self) -> bool {
        !matches!(self, OeStop::IterationLimit)
    }
}

impl std::fmt::Display for OeStop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            OeStop::CostConverged => "converged (relative change of the cost below tolerance)",
            OeStop::StepConverged => "converged (relative change of the parameters below tolerance)",
            OeStop::GradientZero => "converged (gradient zero)",
            OeStop::NoImprovement => {
                "converged (no step lowers the cost further: a local minimum or a kink of the deadzone)"
            }
            OeStop::StabilityBoundary => {
                "converged on the stability boundary (a pole held at |p| = 1 - 1e-6: an integrating plant?)"
            }
            OeStop::IterationLimit => "stopped at the iteration limit (not converged)",
        })
    }
}

/// Reflects the roots of z^n + a1 z^(n−1) + ... + a_n outside the unit circle to 1/p̄ (and pulls roots on
/// the circle to modulus 0.999); returns the new coefficients a1..a_n.
pub fn stabilise(a: &[f64]) -> Vec<f64> {
    map_roots(a, |p| {
        let r = p.norm();
        if r >= 1.0 {
            let q = p / (r * r);
            if q.norm() > 0.999 {
                q * (0.999 / q.norm())
            } else {
                q
            }
        } else {
            p
        }
    })
}

/// Largest pole modulus the output-error search allows: strictly inside the unit circle by a margin
/// that the eigenvalue computation of the poles resolves, so that an integrating plant's pole settles
/// just inside 1 and the reported model is stable.
pub const MAX_POLE_MODULUS: f64 = 1.0 - 1e-6;

/// Reflects the roots of z^n + a1 z^(n−1) + ... + a_n outside the unit circle to 1/p̄ and pulls every
/// root whose modulus still exceeds `radius` onto that circle; returns the new coefficients.
pub fn stabilise_within(a: &[f64], radius: f64) -> Vec<f64> {
    map_roots(a, |p| {
        let r = p.norm();
        let q = if r >= 1.0 { p / (r * r) } else { p };
        if q.norm() > radius {
            q * (radius / q.norm())
        } else {
            q
        }
    })
}

/// The coefficients a1..a_n of Π (z − f(p_i)) over the roots p_i of z^n + a1 z^(n−1) + ... + a_n.
fn map_roots(a: &[f64], f: impl Fn(Complex<f64>) -> Complex<f64>) -> Vec<f64> {
    let roots: Vec<Complex<f64>> = poles_of(a).into_iter().map(f).collect();
    let mut c = vec![Complex::new(1.0, 0.0)];
    for p in roots {
        let mut next = vec![Complex::new(0.0, 0.0); c.len() + 1];
        for (i, ci) in c.iter().enumerate() {
            next[i] += ci;
            next[i + 1] -= ci * p;
        }
        c = next;
    }
    c.iter().skip(1).map(|v| v.re).collect()
}

struct Problem<'a> {
    u: &'a [f64],
    y: &'a [f64],
    s: Structure,
    full: Vec<f64>,
    free: Vec<usize>,
    bound: f64,
    jacobians: Cell<usize>,
}

struct Decoded {
    dz: Option<Deadzone>,
    a: Vec<f64>,
    b: Vec<f64>,
    c: f64,
    /// Index of a1 in the full vector.
    ia: usize,
    /// Index of the first free B coefficient and which b_j it is (0-based j).
    ib: usize,
    jb0: usize,
}

impl Problem<'_> {
    /// The parts of the model in the physical vector (no validation: an iterate may be non-finite,
    /// which the simulation then reports).
    fn decode(&self) -> Decoded {
        let o = self.s.orders;
        let v = &self.full;
        let hammer = self.s.kind == ModelKind::Hammerstein;
        let ia = if hammer { 4 } else { 0 };
        let ib = ia + o.na;
        let jb0 = usize::from(hammer);
        let mut b = Vec::with_capacity(o.nb);
        if hammer {
            b.push(1.0);
        }
        b.extend_from_slice(&v[ib..ib + o.nb - jb0]);
        Decoded {
            dz: hammer.then(|| Deadzone {
                b_l: v[0],
                b_r: v[1],
                m_l: v[2],
                m_r: v[3],
            }),
            a: v[ia..ib].to_vec(),
            b,
            c: if self.s.offset {
                v[ib + o.nb - jb0]
            } else {
                0.0
            },
            ia,
            ib,
            jb0,
        }
    }

    /// ŷ over the record and x = f(u); `None` when the simulation leaves ±bound or is not finite.
    fn simulate(&self, d: &Decoded) -> Option<(Vec<f64>, Vec<f64>)> {
        let n = self.u.len();
        let k0 = self.s.orders.k0();
        let nk = self.s.orders.nk;
        let x: Vec<f64> = match &d.dz {
            Some(dz) => self.u.iter().map(|&v| dz.apply(v)).collect(),
            None => self.u.to_vec(),
        };
        let np = self.s.n_params();
        let mut yh = self.full[np..np + k0].to_vec();
        yh.reserve(n.saturating_sub(k0));
        for k in k0..n {
            let mut v = d.c;
            for (i, ai) in d.a.iter().enumerate() {
                v -= ai * yh[k - 1 - i];
            }
            for (j, bj) in d.b.iter().enumerate() {
                v += bj * x[k - nk - j];
            }
            if !(v.is_finite() && v.abs() <= self.bound) {
                return None;
            }
            yh.push(v);
        }
        Some((yh, x))
    }
}

impl Problem<'_> {
    /// Residuals y − ŷ over every sample; `None` when the simulation diverges.
    fn residuals(&self) -> Option<DVector<f64>> {
        let m = self.u.len();
        let d = self.decode();
        let (yh, _) = self.simulate(&d)?;
        Some(DVector::from_iterator(m, (0..m).map(|k| self.y[k] - yh[k])))
    }

    /// Loss Σ r² (infinite when the simulation diverges).
    fn cost(&self) -> f64 {
        self.residuals().map_or(f64::INFINITY, |r| r.norm_squared())
    }

    /// ∂ŷ/∂θ for the free parameters, with the simulation it was computed on.
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        self.jacobians.set(self.jacobians.get() + 1);
        let d = self.decode();
        let (yh, x) = self.simulate(&d)?;
        Some(self.sensitivities(&d, &yh, &x))
    }

    /// Index of a1 in the full vector.
    fn ia(&self) -> usize {
        if self.s.kind == ModelKind::Hammerstein {
            4
        } else {
            0
        }
    }

    /// True when A of the current parameters is stable.
    fn stable(&self) -> bool {
        let ia = self.ia();
        is_stable_polynomial_within(&self.full[ia..ia + self.s.orders.na], MAX_POLE_MODULUS)
    }

    /// Reflects the unstable poles of A into the unit circle.
    fn project(&mut self) {
        let ia = self.ia();
        let na = self.s.orders.na;
        let a = stabilise_within(&self.full[ia..ia + na], MAX_POLE_MODULUS);
        self.full[ia..ia + na].copy_from_slice(&a);
    }

    fn free_values(&self) -> Vec<f64> {
        self.free.iter().map(|&i| self.full[i]).collect()
    }

    fn set_free(&mut self, v: &[f64]) {
        for (q, &i) in self.free.iter().enumerate() {
            self.full[i] = v[q];
        }
    }
}

/// Relative loss decrease and relative step below which the search has converged.
const FTOL: f64 = 1.5e-8;
const XTOL: f64 = 1.5e-8;
/// Relative loss decrease below which a step projected onto the stability boundary ends the search:
/// the constrained optimum has a pole on the boundary (an integrating plant) and projected steps creep
/// along it.
const FTOL_BOUNDARY: f64 = 1e-6;
/// Damping bound: beyond it no step lowers the loss.
const LAMBDA_MAX: f64 = 1e16;

/// The stability-constrained Levenberg–Marquardt search (module docs). Returns how it stopped, the
/// iterations and the loss evaluations.
fn search(
    problem: &mut Problem,
    max_iterations: usize,
) -> Result<(OeStop, usize, usize, usize), SysidError> {
    let mut cost = problem.cost();
    let mut evaluations = 1;
    let mut projected = 0;
    let mut lambda: f64 = 1e-3;
    let mut workspace = ls::LsWorkspace::new();
    for iteration in 1..=max_iterations {
        let (Some(jac), Some(r)) = (problem.jacobian(), problem.residuals()) else {
            return Err(SysidError::Numerical(
                "output-error search: the simulation of the current iterate diverged".into(),
            ));
        };
        let gradient = jac.transpose() * &r;
        let gmax = gradient.amax();
        if gmax == 0.0 || !gmax.is_finite() {
            return Ok((OeStop::GradientZero, iteration, evaluations, projected));
        }
        let theta = problem.free_values();
        // One Householder triangularisation of [J D⁻¹ | r] per iteration; every damped trial step is
        // then a small 2p × p problem (Triangular::damped_step).
        let Ok(tri) = workspace.triangularise(&jac, &r, &[], false) else {
            return Ok((OeStop::NoImprovement, iteration, evaluations, projected));
        };
        loop {
            let Ok(step) = tri.damped_step(lambda) else {
                lambda = (lambda * 4.0).max(1e-10);
                if lambda > LAMBDA_MAX {
                    problem.set_free(&theta);
                    return Ok((OeStop::NoImprovement, iteration, evaluations, projected));
                }
                continue;
            };
            // A step that leaves the stable region is shortened (halved) until it stays inside; one that
            // cannot be kept inside that way is projected (poles pulled onto the allowed circle).
            let mut scale = 1.0;
            let mut on_boundary = false;
            loop {
                let trial: Vec<f64> = theta
                    .iter()
                    .zip(step.iter())
                    .map(|(t, d)| t + scale * d)
                    .collect();
                problem.set_free(&trial);
                if problem.stable() {
                    break;
                }
                on_boundary = true;
                scale *= 0.5;
                if scale < 1e-6 {
                    problem.project();
                    break;
                }
            }
            if on_boundary {
                projected += 1;
            }
            let new_cost = problem.cost();
            evaluations += 1;
            if new_cost < cost {
                let moved = problem
                    .free_values()
                    .iter()
                    .zip(&theta)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
                    .sqrt();
                let size = theta.iter().map(|t| t * t).sum::<f64>().sqrt();
                let decrease = (cost - new_cost) / cost.max(f64::MIN_POSITIVE);
                cost = new_cost;
                // No floor: on ill-conditioned problems (a near-integrator's poles and its initial
                // outputs) any fixed damping would shorten the Gauss–Newton step along the weak
                // directions and slow the search to a crawl.
                lambda /= 3.0;
                if decrease < FTOL {
                    return Ok((OeStop::CostConverged, iteration, evaluations, projected));
                }
                if on_boundary && decrease < FTOL_BOUNDARY {
                    return Ok((OeStop::StabilityBoundary, iteration, evaluations, projected));
                }
                if moved <= XTOL * (size + XTOL) {
                    return Ok((OeStop::StepConverged, iteration, evaluations, projected));
                }
                break;
            }
            lambda = (lambda * 4.0).max(1e-10);
            if lambda > LAMBDA_MAX {
                problem.set_free(&theta);
                return Ok((OeStop::NoImprovement, iteration, evaluations, projected));
            }
        }
    }
    Ok((
        OeStop::IterationLimit,
        max_iterations,
        evaluations,
        projected,
    ))
}

impl Problem<'_> {
    /// ∂ŷ(k)/∂θ_q for every sample k (rows) and the free parameters q (columns).
    fn sensitivities(&self, d: &Decoded, yh: &[f64], x: &[f64]) -> DMatrix<f64> {
        let n = self.u.len();
        let o = self.s.orders;
        let k0 = o.k0();
        let np = self.s.n_params();
        let mut jac = DMatrix::<f64>::zeros(n, self.free.len());
        let mut g = vec![0.0; n];
        let mut s = vec![0.0; n];
        for (col, &q) in self.free.iter().enumerate() {
            s[..k0].fill(0.0);
            // Drive g(k), k >= k0.
            if q >= np {
                s[q - np] = 1.0;
                g[k0..n].fill(0.0);
            } else if let (Some(dz), true) = (&d.dz, q < 4) {
                let dx = |u: f64| -> f64 {
                    let hr = dz.h_r(u);
                    let hl = if hr > 0.0 { 0.0 } else { dz.h_l(u) };
                    match q {
                        0 => -dz.m_l * hl,
                        1 => -dz.m_r * hr,
                        2 => hl * (u - dz.b_l),
                        _ => hr * (u - dz.b_r),
                    }
                };
                let dxs: Vec<f64> = self.u.iter().map(|&v| dx(v)).collect();
                for k in k0..n {
                    g[k] =
                        d.b.iter()
                            .enumerate()
                            .map(|(j, bj)| bj * dxs[k - o.nk - j])
                            .sum();
                }
            } else if q >= d.ia && q < d.ib {
                let i = q - d.ia + 1;
                for k in k0..n {
                    g[k] = -yh[k - i];
                }
            } else if q >= d.ib && q < d.ib + o.nb - d.jb0 {
                let j = q - d.ib + d.jb0;
                for k in k0..n {
                    g[k] = x[k - o.nk - j];
                }
            } else {
                g[k0..n].fill(1.0);
            }
            // A(q⁻¹) s = g with s given before k0.
            for k in k0..n {
                let mut v = g[k];
                for (i, ai) in d.a.iter().enumerate() {
                    v -= ai * s[k - 1 - i];
                }
                s[k] = v;
            }
            for k in 0..n {
                jac[(k, col)] = s[k];
            }
        }
        jac
    }
}

/// Refines `start` by minimising the simulation error on `data`, over the free entries of `physical`
/// (a physical-layout parameterisation; fixed entries keep the start's value), in at most
/// `max_iterations` Levenberg–Marquardt iterations.
pub fn refine(
    data: &Dataset,
    physical: &Parameterisation,
    start: &Model,
    max_iterations: usize,
) -> Result<OeFit, SysidError> {
    let s = physical.structure();
    if physical.layout() != Layout::Physical {
        return Err(SysidError::Data(
            "output-error refinement works on the physical parameter layout".into(),
        ));
    }
    let k0 = s.orders.k0();
    let n = data.len();
    let np = s.n_params();
    let mut full = physical.vector_of(start);
    if full.len() != np || physical.len() != np {
        return Err(SysidError::Data(
            "output-error refinement: the start model does not match the structure".into(),
        ));
    }
    full.extend_from_slice(&data.y[..k0.min(n)]);
    let free_idx: Vec<usize> = physical
        .free_indices()
        .into_iter()
        .chain(np..np + k0)
        .collect();
    if n <= k0 || n <= free_idx.len() {
        return Err(SysidError::Data(format!(
            "{}: too few samples ({n}) for an output-error fit of {} parameters",
            data.name,
            free_idx.len()
        )));
    }
    let ymax = data.y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut problem = Problem {
        u: &data.u,
        y: &data.y,
        s: *s,
        full,
        free: free_idx.clone(),
        bound: 1e6 * (1.0 + ymax),
        jacobians: Cell::new(0),
    };
    let mut stabilised_start = false;
    if !problem.stable() || problem.simulate(&problem.decode()).is_none() {
        problem.full[np..np + k0].copy_from_slice(&data.y[..k0]);
        problem.project();
        stabilised_start = true;
        if problem.simulate(&problem.decode()).is_none() {
            return Err(SysidError::Numerical(format!(
                "{}: the simulation of the start model diverges even after stabilising its poles",
                data.name
            )));
        }
    }
    let rss_start = problem.cost();
    let (stop, iterations, evaluations, projected_steps) =
        search(&mut problem, max_iterations).map_err(|e| e.context(&data.name))?;
    let d = problem.decode();
    let (yh, x) = problem.simulate(&d).ok_or_else(|| {
        SysidError::Numerical(format!(
            "{}: output-error refinement ended on a diverging model",
            data.name
        ))
    })?;
    let resid = DVector::from_iterator(n, (0..n).map(|k| data.y[k] - yh[k]));
    let rss = resid.norm_squared();
    let jac = problem.sensitivities(&d, &yh, &x);
    let p = free_idx.len();
    let sigma2 = rss / (n - p) as f64;
    let names = physical.names();
    let free_names: Vec<String> = free_idx
        .iter()
        .map(|&i| {
            names
                .get(i)
                .map_or_else(|| format!("y0({})", i - np), ToString::to_string)
        })
        .collect();
    let cov = ls::solve(&jac, &resid, &free_names)
        .ok()
        .map(|sol| sol.inv_gram * sigma2);
    let mut params = Vec::new();
    for (i, name) in names.iter().enumerate() {
        if s.kind == ModelKind::Hammerstein && i == 4 + s.orders.na {
            params.push(Param {
                name: ParamName::B(1),
                value: 1.0,
                std: None,
            });
        }
        let std = free_idx.iter().position(|&f| f == i).and_then(|q| {
            let v = cov.as_ref()?[(q, q)];
            (v.is_finite() && v >= 0.0).then(|| v.sqrt())
        });
        params.push(Param {
            name: *name,
            value: problem.full[i],
            std,
        });
    }
    if s.kind == ModelKind::Hammerstein && names.len() == 4 + s.orders.na {
        params.push(Param {
            name: ParamName::B(1),
            value: 1.0,
            std: None,
        });
    }
    Ok(OeFit {
        model: physical
            .model_of(&problem.full[..np], data.ts)
            .map_err(|e| SysidError::Numerical(format!("{}: {e}", data.name)))?
            .with_noise_model(NoiseModel::OutputError),
        initial_outputs: problem.full[np..].to_vec(),
        params,
        iterations,
        evaluations,
        stop,
        projected_steps,
        rss_start,
        rss,
        noise_variance: sigma2,
        stabilised_start,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sysid_core::data::Signals;

    // (z − 2)(z − 0.5) = z² − 2.5 z + 1: the root 2 reflects to 0.5, giving (z − 0.5)² = z² − z + 0.25.
    #[test]
    fn stabilise_reflects_a_root_outside_the_unit_circle() {
        let a = stabilise(&[-2.5, 1.0]);
        assert!(
            (a[0] + 1.0).abs() < 1e-12 && (a[1] - 0.25).abs() < 1e-12,
            "{a:?}"
        );
    }

    // Finite differences of the simulation agree with the analytic sensitivities away from the kinks.
    #[test]
    fn analytic_jacobian_matches_central_differences() {
        let u: Vec<f64> = (0..200)
            .map(|k| ((k * 37) % 17) as f64 - 8.0 + 0.25)
            .collect();
        let y: Vec<f64> = (0..200).map(|k| (k as f64 * 0.05).sin()).collect();
        let data = Dataset::new(Signals { u, y }, 0.01, "t").unwrap();
        let s = Structure {
            kind: ModelKind::Hammerstein,
            orders: crate::Orders {
                na: 2,
                nb: 2,
                nk: 1,
            },
            offset: true,
        };
        // [b_l, b_r, m_l, m_r, a1, a2, b2, c, η0, η1]
        let full = vec![-1.4, 1.3, 0.02, 0.03, -1.2, 0.4, 0.5, 0.1, 0.3, -0.2];
        let mut p = Problem {
            u: &data.u,
            y: &data.y,
            s,
            full: full.clone(),
            free: (0..full.len()).collect(),
            bound: 1e9,
            jacobians: Cell::new(0),
        };
        let j = p.jacobian().unwrap();
        for q in 0..full.len() {
            let h = 1e-6 * (1.0 + full[q].abs());
            p.full = full.clone();
            p.full[q] += h;
            let rp = p.residuals().unwrap();
            p.full[q] -= 2.0 * h;
            let rm = p.residuals().unwrap();
            for row in 0..rp.len() {
                // r = y − ŷ, so ∂ŷ/∂θ = −∂r/∂θ.
                let fd = -(rp[row] - rm[row]) / (2.0 * h);
                assert!(
                    (fd - j[(row, q)]).abs() < 1e-5 * (1.0 + fd.abs()),
                    "param {q} row {row}: {fd} vs {}",
                    j[(row, q)]
                );
            }
        }
    }
}
