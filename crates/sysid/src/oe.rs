//! Output-error (prediction-error with an output-error noise model) refinement: minimise the free-run
//! simulation error V(θ) = ½ Σ_{k >= k0} (y(k) − ŷ(k; θ))² over every parameter of the model, by a
//! Levenberg–Marquardt search constrained to stable models, started from a least-squares estimate.
//!
//! Why: LS/RLS minimise the *equation* error, which is biased when noise enters at the output (an
//! encoder's quantisation and noise). The simulation error does not regress on noisy past outputs, so its
//! minimiser is consistent under white output noise (Ljung, *System Identification*, ch. 7–8).
//!
//! Parameter vector (the physical layout of [`Regression`]; with one input that of `sysid_core::param`):
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
//! A stop on these tolerances is checked to first order before it is called convergence: at a minimum
//! of a smooth criterion the residuals are (nearly) orthogonal to the sensitivities, so the undamped
//! Gauss–Newton step of the last iteration predicts (almost) no decrease. When it still predicts more
//! than [`STATIONARY`] of the cost, the search crept towards a kink or a jump of the criterion with a
//! growing λ (a deadzone breakpoint on an input level; with crossed breakpoints b_l > b_r the deadzone
//! jumps at b_r). Such a stop restarts the same search with λ reset from the end point with the
//! breakpoints held (the criterion is smooth in every other parameter), and any end with crossed
//! breakpoints restarts from each way of putting them in order ([`restart`]); the end with the lowest
//! loss on the worse of both initial states is kept. A stop that is still predicted to fall is "not
//! converged" ([`OeStop::NotStationary`]) when the restarts were still lowering the loss when they ran
//! out or the breakpoints still cross, "converged at a kink" ([`OeStop::AtKink`]) when a restart from
//! it found nothing lower. A stop whose last step met the stability constraint is not judged so (a
//! constrained optimum has a non-zero gradient).
//!
//! Standard deviations: σ̂² (JᵀJ)⁻¹ with J the final Jacobian and σ̂² = 2 V / (N − p).

use std::cell::Cell;

use nalgebra::{Complex, DMatrix, DVector};

use crate::blocks::Block;
use crate::fitted::{Param, Termination};
use crate::ls;
use crate::regression::Regression;
use sysid_core::model::{is_stable_polynomial_within, poles_of};
use sysid_core::{Dataset, Model, NoiseModel, ParamName, StaticNonlinearity, Stop, SysidError};

/// The `input` label of the output nonlinearity's parameters (`s_r (output)`).
pub const OUTPUT: &str = "output";

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
    /// Why no standard deviation could be computed (`None` when they were).
    pub std_unavailable: Option<String>,
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
    /// The search stopped on a tolerance where the Gauss–Newton model still predicted a decrease of
    /// more than [`STATIONARY`] of the cost, and the restarts were still lowering the loss when they
    /// ran out (of rounds or iterations), or the breakpoints still cross: not converged.
    NotStationary,
    /// The search stopped on a tolerance where the Gauss–Newton model still predicted a decrease of
    /// more than [`STATIONARY`] of the cost, and a fresh search from that point (its breakpoints held)
    /// found nothing lower: a local minimum at a kink of the criterion (a breakpoint on an input
    /// level) or where the linear model of the loss is poor.
    AtKink,
}

impl OeStop {
    /// True for the convergence criteria (not the cap, not a stop away from a stationary point).
    pub fn converged(&self) -> bool {
        !matches!(self, OeStop::IterationLimit | OeStop::NotStationary)
    }

    /// The estimator's [`Termination`] for this stop.
    pub fn termination(&self) -> Termination {
        match self {
            OeStop::IterationLimit => Termination::IterationLimit,
            OeStop::NotStationary => Termination::NotStationary,
            _ => Termination::Converged,
        }
    }

    /// A stop of the search on one of its tolerances, which a first-order test may overrule.
    fn on_tolerance(&self) -> bool {
        matches!(
            self,
            OeStop::CostConverged | OeStop::StepConverged | OeStop::NoImprovement
        )
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
                "converged on the stability boundary (a pole held at |p| = 1 - 1e-6: see the warnings)"
            }
            OeStop::IterationLimit => "stopped at the iteration limit (not converged)",
            OeStop::NotStationary => {
                "not converged (the Gauss-Newton model still predicts a decrease of more than 1 %, and the \
                 restarted searches were still lowering the cost when they ran out or the deadzone's \
                 breakpoints still cross)"
            }
            OeStop::AtKink => {
                "converged at a kink (the Gauss-Newton model predicts a decrease of more than 1 %, but a \
                 restarted search from this point finds nothing lower: a breakpoint on an input level \
                 or a strongly curved valley)"
            }
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

/// One input of the output-error problem: its record, orders and static nonlinearity block.
#[derive(Clone, Copy)]
struct Channel<'a> {
    u: &'a [f64],
    nb: usize,
    nk: usize,
    block: &'static dyn Block,
}

impl Channel<'_> {
    /// Number of the block's physical parameters.
    fn n_block(&self) -> usize {
        self.block.physical_names().len()
    }
    /// 1 when b1 = 1 is fixed by the key-term normalisation.
    fn b_from(&self) -> usize {
        usize::from(self.n_block() > 0)
    }
}

/// The output-error problem over one or several inputs. `full` holds the model parameters in the
/// physical layout of [`Regression`] — each input's block parameters, then a1..a_na, then per input
/// b1..b_nb (b2..b_nb for a nonlinear input, b1 = 1), then c — followed by the estimated initial
/// outputs η_0..η_{k0−1}.
struct Problem<'a> {
    channels: Vec<Channel<'a>>,
    /// The output nonlinearity's block (y = g(v)); its parameters follow c in `full`.
    output: Option<&'static dyn Block>,
    y: &'a [f64],
    na: usize,
    offset: bool,
    k0: usize,
    full: Vec<f64>,
    free: Vec<usize>,
    bound: f64,
    jacobians: Cell<usize>,
}

/// What entry q of the full vector is.
#[derive(Debug, Clone, Copy)]
enum Role {
    /// Physical parameter `which` of input `ch`'s static nonlinearity.
    Block { ch: usize, which: usize },
    /// a_(i+1).
    A(usize),
    /// The B coefficient of input `ch` at lag j (0-based: b_(j+1)).
    B { ch: usize, j: usize },
    /// The constant c.
    C,
    /// Parameter `which` of the output nonlinearity.
    Out(usize),
    /// The initial output η_j.
    Eta(usize),
}

struct Decoded {
    /// One static nonlinearity per input.
    f: Vec<StaticNonlinearity>,
    a: Vec<f64>,
    /// The whole B of each input (b1 = 1 included for a nonlinear one).
    b: Vec<Vec<f64>>,
    c: f64,
    /// The output nonlinearity g (y = g(v)).
    g: Option<StaticNonlinearity>,
}

impl Problem<'_> {
    /// Index of a1 in the full vector (after the nonlinearity blocks).
    fn ia(&self) -> usize {
        self.channels.iter().map(Channel::n_block).sum()
    }

    /// Number of model parameters (the initial outputs follow them in `full`).
    fn n_params(&self) -> usize {
        let nb: usize = self.channels.iter().map(|c| c.nb - c.b_from()).sum();
        self.ia() + self.na + nb + usize::from(self.offset) + self.n_out()
    }

    /// Number of the output nonlinearity's parameters.
    fn n_out(&self) -> usize {
        self.output.map_or(0, |b| b.physical_names().len())
    }

    /// The role of entry `q` of the full vector.
    fn role(&self, q: usize) -> Role {
        let mut i = q;
        for (ch, c) in self.channels.iter().enumerate() {
            if i < c.n_block() {
                return Role::Block { ch, which: i };
            }
            i -= c.n_block();
        }
        if i < self.na {
            return Role::A(i);
        }
        i -= self.na;
        for (ch, c) in self.channels.iter().enumerate() {
            let from = c.b_from();
            if i < c.nb - from {
                return Role::B { ch, j: i + from };
            }
            i -= c.nb - from;
        }
        if self.offset {
            if i == 0 {
                return Role::C;
            }
            i -= 1;
        }
        if i < self.n_out() {
            return Role::Out(i);
        }
        Role::Eta(i - self.n_out())
    }

    /// The parts of the model in the full vector (no validation: an iterate may be non-finite, which the
    /// simulation then reports).
    fn decode(&self) -> Decoded {
        let v = &self.full;
        let mut i = 0;
        let mut f = Vec::with_capacity(self.channels.len());
        for c in &self.channels {
            f.push(c.block.of_physical(&v[i..i + c.n_block()]));
            i += c.n_block();
        }
        let a = v[i..i + self.na].to_vec();
        i += self.na;
        let mut b = Vec::with_capacity(self.channels.len());
        for c in &self.channels {
            let mut bc = Vec::with_capacity(c.nb);
            if c.b_from() == 1 {
                bc.push(1.0);
            }
            let count = c.nb - c.b_from();
            bc.extend_from_slice(&v[i..i + count]);
            i += count;
            b.push(bc);
        }
        let c = if self.offset { v[i] } else { 0.0 };
        i += usize::from(self.offset);
        let g = self
            .output
            .map(|block| block.of_physical(&v[i..i + self.n_out()]));
        Decoded { f, a, b, c, g }
    }

    /// ŷ over the record and x = f(u) of each input; `None` when the simulation leaves ±bound or is not
    /// finite.
    #[allow(clippy::type_complexity)]
    fn simulate(&self, d: &Decoded) -> Option<(Vec<f64>, Vec<Vec<f64>>)> {
        let n = self.y.len();
        let k0 = self.k0;
        let x: Vec<Vec<f64>> = self
            .channels
            .iter()
            .zip(&d.f)
            .map(|(c, f)| c.u.iter().map(|&v| f.apply(v)).collect())
            .collect();
        let np = self.n_params();
        let mut yh = self.full[np..np + k0].to_vec();
        yh.reserve(n.saturating_sub(k0));
        for k in k0..n {
            let mut v = d.c;
            for (i, ai) in d.a.iter().enumerate() {
                v -= ai * yh[k - 1 - i];
            }
            for ((c, b), x) in self.channels.iter().zip(&d.b).zip(&x) {
                for (j, bj) in b.iter().enumerate() {
                    v += bj * x[k - c.nk - j];
                }
            }
            if !(v.is_finite() && v.abs() <= self.bound) {
                return None;
            }
            yh.push(v);
        }
        Some((yh, x))
    }

    /// Residuals y − ŷ over every sample (ŷ = g(v) after k0 with an output nonlinearity); `None`
    /// when the simulation diverges.
    fn residuals(&self) -> Option<DVector<f64>> {
        let d = self.decode();
        let (yh, _) = self.simulate(&d)?;
        Some(self.residuals_of(&d, &yh))
    }

    /// y − ŷ of the linear block's simulation `v`.
    fn residuals_of(&self, d: &Decoded, v: &[f64]) -> DVector<f64> {
        let m = self.y.len();
        DVector::from_iterator(
            m,
            (0..m).map(|k| match &d.g {
                Some(g) if k >= self.k0 => self.y[k] - g.apply(v[k]),
                _ => self.y[k] - v[k],
            }),
        )
    }

    /// Loss Σ r² (infinite when the simulation diverges).
    fn cost(&self) -> f64 {
        self.residuals().map_or(f64::INFINITY, |r| r.norm_squared())
    }

    /// The free entries without the input nonlinearities' breakpoints (b_l, b_r, s_l, s_r, p_i): the
    /// parameters the criterion is smooth in (a breakpoint crossing an input level is a kink).
    fn smooth_free(&self) -> Vec<usize> {
        self.free
            .iter()
            .copied()
            .filter(|&q| match self.role(q) {
                Role::Block { ch, which } => !matches!(
                    self.channels[ch].block.physical_names()[which],
                    ParamName::BL
                        | ParamName::BR
                        | ParamName::SL
                        | ParamName::SR
                        | ParamName::Knot(_)
                ),
                _ => true,
            })
            .collect()
    }

    /// The larger of the loss with the estimated initial outputs and the loss with the measured ones
    /// (η = y(0..k0−1)): the ends of restarted searches are compared on it, as the kept model is judged
    /// on the worse of both initial states, so that a restart cannot buy a lower loss with the initial
    /// state alone.
    fn guarded_cost(&self) -> f64 {
        let np = self.n_params();
        let mut measured = Problem {
            full: self.full.clone(),
            free: Vec::new(),
            jacobians: Cell::new(0),
            channels: self.channels.clone(),
            ..*self
        };
        measured.full[np..np + self.k0].copy_from_slice(&self.y[..self.k0]);
        self.cost().max(measured.cost())
    }

    /// ∂ŷ/∂θ for the free parameters, with the simulation it was computed on.
    fn jacobian(&self) -> Option<DMatrix<f64>> {
        self.jacobians.set(self.jacobians.get() + 1);
        let d = self.decode();
        let (yh, x) = self.simulate(&d)?;
        Some(self.sensitivities(&d, &yh, &x))
    }

    /// True when A of the current parameters is stable.
    fn stable(&self) -> bool {
        let ia = self.ia();
        is_stable_polynomial_within(&self.full[ia..ia + self.na], MAX_POLE_MODULUS)
    }

    /// True when a pole of A is held at the stability boundary ([`MAX_POLE_MODULUS`], to rounding).
    fn pinned(&self) -> bool {
        let ia = self.ia();
        poles_of(&self.full[ia..ia + self.na])
            .iter()
            .any(|p| p.norm() >= MAX_POLE_MODULUS - 1e-9)
    }

    /// Full vectors with one input nonlinearity's crossed breakpoints put in order, one for each way
    /// [`Block::ordered`] lists (every input with crossed breakpoints); empty when none cross.
    fn ordered(&self) -> Vec<Vec<f64>> {
        let mut out = Vec::new();
        let mut i = 0;
        for c in &self.channels {
            let n = c.n_block();
            for v in c.block.ordered(&self.full[i..i + n]) {
                let mut full = self.full.clone();
                full[i..i + n].copy_from_slice(&v);
                out.push(full);
            }
            i += n;
        }
        out
    }

    /// Reflects the unstable poles of A into the unit circle.
    fn project(&mut self) {
        let ia = self.ia();
        let na = self.na;
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
/// Relative decrease predicted by the last Gauss–Newton model above which a stop on a tolerance is no
/// convergence ([`restart`]): at a minimum of a smooth criterion the residuals are (nearly) orthogonal
/// to the sensitivities and the prediction is about the last decrease; a search that creeps to a kink
/// with a growing damping still sees a large predicted decrease (0.04–0.9 on the audit's cases).
const STATIONARY: f64 = 1e-2;
/// How many times [`restart`] may restart the search (each restart must lower the cost).
const RESTARTS: usize = 4;
/// Damping bound: beyond it no step lowers the loss.
const LAMBDA_MAX: f64 = 1e16;

/// How one run of [`search`] ended.
#[derive(Debug, Clone, Copy)]
struct SearchEnd {
    stop: OeStop,
    iterations: usize,
    evaluations: usize,
    projected: usize,
    /// The decrease the Gauss–Newton step of the last iteration predicted, relative to the cost:
    /// (‖r‖² − min_δ ‖r − J δ‖²) / ‖r‖², the squared cosine between the residuals and the span of the
    /// sensitivities (0 at a stationary point).
    explained: f64,
    /// A trial step of the last iteration left the stable region (shortened or projected): the
    /// stability constraint is active, where the unconstrained prediction says nothing about
    /// stationarity.
    constrained: bool,
}

impl SearchEnd {
    /// The search stopped with `stop` at iteration `iteration`.
    fn stopped(self, stop: OeStop, iteration: usize) -> Self {
        SearchEnd {
            stop,
            iterations: iteration,
            ..self
        }
    }
}

/// The stability-constrained Levenberg–Marquardt search (module docs): how it stopped, the
/// iterations, the loss evaluations and the projected steps. `cancel` is polled before each iteration and
/// each trial step ([`SysidError::Cancelled`]).
fn search(
    problem: &mut Problem,
    max_iterations: usize,
    cancel: &Stop,
) -> Result<SearchEnd, SysidError> {
    let mut cost = problem.cost();
    // A loss at the rounding level of the data (a noise-free record fitted exactly) has no meaningful
    // relative prediction: the first-order test is skipped there.
    let floor = f64::EPSILON * problem.y.iter().map(|v| v * v).sum::<f64>();
    let mut lambda: f64 = 1e-3;
    let mut workspace = ls::LsWorkspace::new();
    let mut at = SearchEnd {
        stop: OeStop::IterationLimit,
        iterations: max_iterations,
        evaluations: 1,
        projected: 0,
        explained: 0.0,
        constrained: false,
    };
    for iteration in 1..=max_iterations {
        cancel.check()?;
        let (Some(jac), Some(r)) = (problem.jacobian(), problem.residuals()) else {
            return Err(SysidError::Numerical(
                "output-error search: the simulation of the current iterate diverged".into(),
            ));
        };
        let gradient = jac.transpose() * &r;
        let gmax = gradient.amax();
        if gmax == 0.0 || !gmax.is_finite() {
            return Ok(at.stopped(OeStop::GradientZero, iteration));
        }
        let theta = problem.free_values();
        cancel.check()?;
        // One Householder triangularisation of [J D⁻¹ | r] per iteration; every damped trial step is
        // then a small 2p × p problem (Triangular::damped_step).
        let Ok(tri) = workspace.triangularise(&jac, &r, &[], false) else {
            return Ok(at.stopped(OeStop::NoImprovement, iteration));
        };
        at.explained = if cost > floor && cost.is_finite() {
            ((cost - tri.rss()) / cost).clamp(0.0, 1.0)
        } else {
            0.0
        };
        at.constrained = false;
        loop {
            cancel.check()?;
            let Ok(step) = tri.damped_step(lambda) else {
                lambda = (lambda * 4.0).max(1e-10);
                if lambda > LAMBDA_MAX {
                    problem.set_free(&theta);
                    return Ok(at.stopped(OeStop::NoImprovement, iteration));
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
                at.projected += 1;
                at.constrained = true;
            }
            let new_cost = problem.cost();
            at.evaluations += 1;
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
                // MINPACK's test: the cost has converged only when the linear model also predicts
                // no further decrease for this step; a heavily damped step that gains little while
                // much more is predicted is not convergence.
                let taken: Vec<f64> = problem
                    .free_values()
                    .iter()
                    .zip(&theta)
                    .map(|(a, b)| a - b)
                    .collect();
                let predicted = tri.predicted_reduction(&taken) / cost.max(f64::MIN_POSITIVE);
                cost = new_cost;
                // No floor: on ill-conditioned problems (a near-integrator's poles and its initial
                // outputs) any fixed damping would shorten the Gauss–Newton step along the weak
                // directions and slow the search to a crawl.
                lambda /= 3.0;
                // A pole held at the boundary makes the tiny projected steps look like convergence:
                // say where the search ended instead (the warnings then name the pole).
                let converged = |stop| {
                    if problem.pinned() {
                        OeStop::StabilityBoundary
                    } else {
                        stop
                    }
                };
                if decrease < FTOL && predicted <= FTOL {
                    let stop = converged(OeStop::CostConverged);
                    return Ok(at.stopped(stop, iteration));
                }
                if on_boundary && decrease < FTOL_BOUNDARY {
                    return Ok(at.stopped(OeStop::StabilityBoundary, iteration));
                }
                if moved <= XTOL * (size + XTOL) {
                    let stop = converged(OeStop::StepConverged);
                    return Ok(at.stopped(stop, iteration));
                }
                break;
            }
            lambda = (lambda * 4.0).max(1e-10);
            if lambda > LAMBDA_MAX {
                problem.set_free(&theta);
                return Ok(at.stopped(OeStop::NoImprovement, iteration));
            }
        }
    }
    Ok(at)
}

impl Problem<'_> {
    /// ∂ŷ(k)/∂θ_q for every sample k (rows) and the free parameters q (columns).
    fn sensitivities(&self, d: &Decoded, yh: &[f64], x: &[Vec<f64>]) -> DMatrix<f64> {
        let n = self.y.len();
        let k0 = self.k0;
        let mut jac = DMatrix::<f64>::zeros(n, self.free.len());
        let mut g = vec![0.0; n];
        let mut s = vec![0.0; n];
        for (col, &q) in self.free.iter().enumerate() {
            s[..k0].fill(0.0);
            // Drive g(k), k >= k0.
            match self.role(q) {
                Role::Eta(j) => {
                    s[j] = 1.0;
                    g[k0..n].fill(0.0);
                }
                Role::Block { ch, which } => {
                    let c = &self.channels[ch];
                    let f = &d.f[ch];
                    let dxs: Vec<f64> =
                        c.u.iter()
                            .map(|&v| c.block.derivative(f, which, v))
                            .collect();
                    for k in k0..n {
                        g[k] = d.b[ch]
                            .iter()
                            .enumerate()
                            .map(|(j, bj)| bj * dxs[k - c.nk - j])
                            .sum();
                    }
                }
                Role::A(i) => {
                    for k in k0..n {
                        g[k] = -yh[k - 1 - i];
                    }
                }
                Role::B { ch, j } => {
                    let nk = self.channels[ch].nk;
                    for k in k0..n {
                        g[k] = x[ch][k - nk - j];
                    }
                }
                Role::C => g[k0..n].fill(1.0),
                Role::Out(which) => {
                    // ∂ŷ/∂p = ∂g/∂p at v(k), no dynamics.
                    let (Some(block), Some(gf)) = (self.output, &d.g) else {
                        continue;
                    };
                    for k in 0..n {
                        jac[(k, col)] = if k < k0 {
                            0.0
                        } else {
                            block.derivative(gf, which, yh[k])
                        };
                    }
                    continue;
                }
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
                // ∂g(v)/∂q = g'(v) ∂v/∂q after k0.
                let slope = match &d.g {
                    Some(gf) if k >= k0 => gf.slope(yh[k]),
                    _ => 1.0,
                };
                jac[(k, col)] = slope * s[k];
            }
        }
        jac
    }
}

/// What the search leaves for the wrappers: the final parameters, their covariance over the free
/// entries, and the statistics of [`OeFit`].
struct Searched {
    full: Vec<f64>,
    free: Vec<usize>,
    /// n_params: where the initial outputs start in `full`.
    np: usize,
    cov: Option<DMatrix<f64>>,
    std_unavailable: Option<String>,
    stop: OeStop,
    iterations: usize,
    evaluations: usize,
    projected_steps: usize,
    rss_start: f64,
    rss: f64,
    noise_variance: f64,
    stabilised_start: bool,
}

/// Stabilises the start if needed, runs the search and computes σ̂² (JᵀJ)⁻¹ at its end. `model_part`
/// is the start's parameter vector (without initial outputs), `model_free` its free entries; `names`
/// labels the columns in errors.
fn run(
    mut problem: Problem,
    model_part: Vec<f64>,
    model_free: Vec<usize>,
    max_iterations: usize,
    name: &str,
    param_names: &[String],
    cancel: &Stop,
) -> Result<Searched, SysidError> {
    let (n, k0, np) = (problem.y.len(), problem.k0, problem.n_params());
    if model_part.len() != np {
        return Err(SysidError::Data(
            "output-error refinement: the start model does not match the structure".into(),
        ));
    }
    let free: Vec<usize> = model_free.into_iter().chain(np..np + k0).collect();
    if n <= k0 || n <= free.len() {
        return Err(SysidError::Data(format!(
            "{name}: too few samples ({n}) for an output-error fit of {} parameters",
            free.len()
        )));
    }
    problem.full = model_part;
    problem.full.extend_from_slice(&problem.y[..k0]);
    problem.free = free.clone();
    let mut stabilised_start = false;
    if !problem.stable() || problem.simulate(&problem.decode()).is_none() {
        problem.project();
        stabilised_start = true;
        if problem.simulate(&problem.decode()).is_none() {
            return Err(SysidError::Numerical(format!(
                "{name}: the simulation of the start model diverges even after stabilising its poles"
            )));
        }
    }
    let rss_start = problem.cost();
    let mut end = search(&mut problem, max_iterations, cancel).map_err(|e| e.context(name))?;
    restart(&mut problem, &mut end, max_iterations, cancel)?;
    let (stop, iterations, evaluations, projected_steps) =
        (end.stop, end.iterations, end.evaluations, end.projected);
    let d = problem.decode();
    let (yh, x) = problem.simulate(&d).ok_or_else(|| {
        SysidError::Numerical(format!(
            "{name}: output-error refinement ended on a diverging model"
        ))
    })?;
    let resid = problem.residuals_of(&d, &yh);
    let rss = resid.norm_squared();
    let jac = problem.sensitivities(&d, &yh, &x);
    let sigma2 = ls::noise_variance(rss, n, free.len());
    // Columns named as the parameters they belong to (η_j: the initial output y0(j)).
    let columns: Vec<String> = free
        .iter()
        .map(|&i| {
            param_names
                .get(i)
                .cloned()
                .unwrap_or_else(|| format!("y0({})", i.saturating_sub(np)))
        })
        .collect();
    let (cov, std_unavailable) = match ls::solve(&jac, &resid, &columns) {
        _ if sigma2.is_nan() => (None, Some(ls::NO_RESIDUAL_DOF.to_string())),
        Ok(sol) => (Some(sol.inv_gram * sigma2), None),
        Err(e) => match covariance_without_zero_columns(&jac, &resid, &columns, sigma2) {
            Some((cov, why)) => (Some(cov), Some(why)),
            None => (None, Some(why_no_covariance(&problem, &e))),
        },
    };
    Ok(Searched {
        full: problem.full,
        free,
        np,
        cov,
        std_unavailable,
        stop,
        iterations,
        evaluations,
        projected_steps,
        rss_start,
        rss,
        noise_variance: sigma2,
        stabilised_start,
    })
}

/// The search once more, with its damping reset, when it stopped on a tolerance at a point that may
/// be no minimum: the last Gauss–Newton model still predicted a decrease of more than [`STATIONARY`]
/// of the cost (the steps crept towards a kink or jump of the criterion, the damping growing), or a
/// nonlinearity's breakpoints cross (a deadzone with b_l > b_r jumps at b_r, a discontinuity the
/// one-sided derivative cannot see across). With crossed breakpoints the search restarts from each way
/// of putting them in order ([`Block::ordered`]: different valleys of a rugged criterion), otherwise
/// from the end point with the breakpoints held ([`Problem::smooth_free`]); the end with the lowest
/// loss is kept — the loss being the worse of the estimated and the measured initial outputs
/// ([`Problem::guarded_cost`]) — and this repeats (at most [`RESTARTS`] rounds) while a round lowers
/// it. Each restarted search may take the iterations the first one left of `max_iterations`; the
/// counts reported add up every search. A stop still predicted to fall becomes
/// [`OeStop::NotStationary`] (not converged) when the last round was still lowering the loss or the
/// breakpoints still cross, else [`OeStop::AtKink`]. A restarted search's failure leaves the end as it
/// was, except [`SysidError::Cancelled`] (the caller's `cancel`), which is returned.
fn restart(
    problem: &mut Problem,
    end: &mut SearchEnd,
    max_iterations: usize,
    cancel: &Stop,
) -> Result<(), SysidError> {
    let stalled =
        |e: &SearchEnd| e.stop.on_tolerance() && !e.constrained && e.explained > STATIONARY;
    // Each restarted search may take the iterations the first one left.
    let remaining = max_iterations.saturating_sub(end.iterations);
    let all = problem.free.clone();
    let smooth = problem.smooth_free();
    // Whether the last round lowered the loss (the search was still making progress when it ended).
    let mut progressing = remaining == 0;
    for _ in 0..RESTARTS {
        // (start, the free entries): ordered breakpoints move; a stall restarts with them held.
        let mut starts: Vec<(Vec<f64>, &[usize])> = problem
            .ordered()
            .into_iter()
            .map(|f| (f, all.as_slice()))
            .collect();
        if starts.is_empty() && stalled(end) {
            starts.push((problem.full.clone(), smooth.as_slice()));
        }
        if starts.is_empty() || remaining == 0 {
            break;
        }
        let (mut best, mut best_cost) = (problem.full.clone(), problem.guarded_cost());
        let mut improved = false;
        for (start, free) in starts {
            problem.full = start;
            problem.free = free.to_vec();
            let again = match search(problem, remaining, cancel) {
                Err(SysidError::Cancelled) => return Err(SysidError::Cancelled),
                again => again.ok(),
            };
            problem.free = all.clone();
            end.iterations += again.map_or(0, |a| a.iterations);
            end.evaluations += again.map_or(0, |a| a.evaluations) + 2;
            end.projected += again.map_or(0, |a| a.projected);
            let cost = problem.guarded_cost();
            if let Some(a) = again.filter(|_| cost < best_cost) {
                (best, best_cost, improved) = (problem.full.clone(), cost, true);
                end.stop = a.stop;
                end.explained = a.explained;
                end.constrained = a.constrained;
            }
        }
        problem.full = best;
        progressing = improved;
        if !improved {
            break;
        }
    }
    if stalled(end) {
        // Still predicted to fall: not converged while the restarts were still lowering the loss
        // when they ran out, or at crossed breakpoints (a jump, not a kink); a local minimum at a
        // kink (or where the linear model is poor) when a fresh search from the end point found
        // nothing lower.
        end.stop = if progressing || !problem.ordered().is_empty() {
            OeStop::NotStationary
        } else {
            OeStop::AtKink
        };
    }
    Ok(())
}

/// σ̂² (JᵀJ)⁻¹ over the Jacobian's non-zero columns when the whole JᵀJ is singular only because some
/// columns are zero (the simulation does not depend on those parameters at the estimate: an output
/// limit beyond the range of the linear block's output, a breakpoint no sample reaches), with NaN in
/// the rows and columns of the zero ones, and the reason their standard deviations are missing. One
/// such parameter withheld every standard deviation before (audit s12: 133 of 196 Hammerstein–Wiener
/// fits), where the least-squares path withholds only the affected ones. `None` when no column is zero
/// or the rest is singular too.
fn covariance_without_zero_columns(
    jac: &DMatrix<f64>,
    resid: &DVector<f64>,
    columns: &[String],
    sigma2: f64,
) -> Option<(DMatrix<f64>, String)> {
    let norms: Vec<f64> = jac.column_iter().map(|c| c.norm()).collect();
    let largest = norms.iter().copied().fold(0.0, f64::max);
    let kept: Vec<usize> = (0..norms.len())
        .filter(|&j| norms[j] > 1e-12 * largest)
        .collect();
    if kept.is_empty() || kept.len() == norms.len() {
        return None;
    }
    let reduced = jac.select_columns(kept.iter());
    let names: Vec<String> = kept.iter().map(|&j| columns[j].clone()).collect();
    let sol = ls::solve(&reduced, resid, &names).ok()?;
    let mut cov = DMatrix::from_element(norms.len(), norms.len(), f64::NAN);
    for (a, &i) in kept.iter().enumerate() {
        for (b, &j) in kept.iter().enumerate() {
            cov[(i, j)] = sol.inv_gram[(a, b)] * sigma2;
        }
    }
    let dropped: Vec<&str> = (0..norms.len())
        .filter(|j| !kept.contains(j))
        .map(|j| columns[j].as_str())
        .collect();
    let parameters = columns.iter().filter(|c| !c.starts_with("y0(")).count();
    let why = format!(
        "{} of {parameters} estimated parameters have none ({}): the output-error simulation does not depend on \
         them at the estimate (their columns of the Jacobian are zero: a limit beyond the range of the \
         signal it acts on, or a breakpoint no sample reaches), so the data do not determine them; the \
         others' come from the remaining columns",
        dropped.len(),
        dropped.join(", ")
    );
    Some((cov, why))
}

/// Why σ̂² (JᵀJ)⁻¹ could not be formed at the end of the search, in words: the solver's reason (a
/// Jacobian column that is zero or dependent on the others: a singular information matrix JᵀJ) and,
/// when a pole sits on the stability boundary the search holds it to, that pinned pole.
fn why_no_covariance(problem: &Problem, e: &SysidError) -> String {
    let ia = problem.ia();
    let pinned = poles_of(&problem.full[ia..ia + problem.na])
        .iter()
        .map(|p| p.norm())
        .fold(0.0, f64::max);
    let mut why = format!("the information matrix JᵀJ of the output-error fit is singular ({e})");
    if pinned >= MAX_POLE_MODULUS - 1e-7 {
        why.push_str(&format!(
            "; a pole is pinned on the stability boundary (|p| = {pinned:.7}), where the loss is not \
             quadratic"
        ));
    }
    why
}

impl Searched {
    /// The standard deviation of entry `i` of the full vector (`None` when fixed or not computable).
    fn std(&self, i: usize) -> Option<f64> {
        self.free.iter().position(|&f| f == i).and_then(|q| {
            let v = self.cov.as_ref()?[(q, q)];
            (v.is_finite() && v >= 0.0).then(|| v.sqrt())
        })
    }

    /// The fit with the model `model` and the parameters `params`.
    fn into_fit(self, model: Model, params: Vec<Param>) -> OeFit {
        OeFit {
            model: model.with_noise_model(NoiseModel::OutputError),
            initial_outputs: self.full[self.np..].to_vec(),
            params,
            iterations: self.iterations,
            evaluations: self.evaluations,
            stop: self.stop,
            projected_steps: self.projected_steps,
            rss_start: self.rss_start,
            rss: self.rss,
            noise_variance: self.noise_variance,
            stabilised_start: self.stabilised_start,
            std_unavailable: self.std_unavailable,
        }
    }
}

/// A problem over `channels` with the output `y` (its vectors filled in by [`run`]).
fn problem<'a>(channels: Vec<Channel<'a>>, y: &'a [f64], na: usize, offset: bool) -> Problem<'a> {
    let k0 = channels
        .iter()
        .map(|c| (c.nk + c.nb).saturating_sub(1))
        .fold(na, usize::max);
    let ymax = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    Problem {
        channels,
        output: None,
        y,
        na,
        offset,
        k0,
        full: Vec::new(),
        free: Vec::new(),
        bound: 1e6 * (1.0 + ymax),
        jacobians: Cell::new(0),
    }
}

/// Refines `start` (a model of the structure `reg`) by minimising the simulation error on `data`, over
/// the entries of `reg`'s physical layout marked in `free` (fixed entries keep the start's value), in at
/// most `max_iterations` Levenberg–Marquardt iterations, polling `cancel` before each iteration and trial
/// step ([`SysidError::Cancelled`]). The parameters come in the reported order of
/// [`Regression::params_from`].
pub fn refine(
    data: &Dataset,
    reg: &Regression,
    free: &[bool],
    start: &Model,
    max_iterations: usize,
    cancel: &Stop,
) -> Result<OeFit, SysidError> {
    refine_with_output(data, reg, free, start, None, max_iterations, cancel)
}

/// The output nonlinearity y = g(v) of an output-error problem: its block, its start and which of its
/// physical parameters are moved (one is held fixed: the scale normalisation against the linear block).
#[derive(Clone, Copy)]
pub struct OutputStart<'s> {
    /// The block of g's kind.
    pub block: &'static dyn Block,
    /// g at the start.
    pub start: StaticNonlinearity,
    /// Which of g's physical parameters the search moves.
    pub free: &'s [bool],
}

/// [`refine`] of a model with the output nonlinearity `output` (Wiener / Hammerstein–Wiener): the
/// simulation is ŷ = g(v) with v the linear block's output, the sensitivities g'(v) ∂v/∂θ and ∂g/∂p.
/// The parameters of g follow the model's in the reported list, marked with the input name `output`.
pub fn refine_with_output(
    data: &Dataset,
    reg: &Regression,
    free: &[bool],
    start: &Model,
    output: Option<OutputStart>,
    max_iterations: usize,
    cancel: &Stop,
) -> Result<OeFit, SysidError> {
    let name = data.name();
    let u = data.input_signals();
    if u.len() != reg.channels().len() || start.inputs().len() != u.len() {
        return Err(SysidError::Data(format!(
            "{name}: output-error refinement needs one record per model input ({})",
            reg.channels().len()
        )));
    }
    let channels = reg
        .channels()
        .iter()
        .zip(&u)
        .map(|(c, u)| Channel {
            u,
            nb: c.nb,
            nk: c.nk,
            block: c.kind.block(),
        })
        .collect();
    let full = reg.physical_vector(start);
    if free.len() != full.len() {
        return Err(SysidError::Data(
            "output-error refinement: the start model does not match the structure".into(),
        ));
    }
    let mut problem = problem(channels, data.y(), reg.na(), reg.offset());
    let n_model = full.len();
    let mut full = full;
    let mut model_free: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let mut labels = reg.physical_labels();
    if let Some(o) = &output {
        problem.output = Some(o.block);
        full.extend(o.block.physical(&o.start));
        model_free.extend(
            (0..o.free.len())
                .filter(|&i| o.free[i])
                .map(|i| n_model + i),
        );
        labels.extend(
            o.block
                .physical_names()
                .iter()
                .map(|n| format!("{n} (output)")),
        );
    }
    let found = run(
        problem,
        full,
        model_free,
        max_iterations,
        name,
        &labels,
        cancel,
    )?;
    let mut params = reg.params_from(|i| (found.full[i], found.std(i)));
    let mut model = reg
        .model_of_physical(&found.full[..n_model], data.ts())
        .map_err(|e| SysidError::Numerical(format!("{name}: {e}")))?;
    if let Some(o) = &output {
        let v = &found.full[n_model..found.np];
        model = model
            .with_output_nonlinearity(Some(o.block.of_physical(v)))
            .map_err(|e| SysidError::Numerical(format!("{name}: {e}")))?;
        for (i, n) in o.block.physical_names().iter().enumerate() {
            params.push(Param {
                name: *n,
                input: Some(OUTPUT.to_string()),
                value: v[i],
                std: found.std(n_model + i),
                // The output map's gain is held against the linear block's scale.
                fixed: (!o.free[i]).then(|| crate::fitted::FIXED_NORMALISATION.to_string()),
            });
        }
    }
    Ok(found.into_fit(model, params))
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

    /// The analytic Jacobian of `p` at `full` (every entry free) against central differences of the
    /// residuals, entry by entry.
    fn assert_jacobian_matches_central_differences(p: &mut Problem, full: &[f64]) {
        p.full = full.to_vec();
        p.free = (0..full.len()).collect();
        let j = p.jacobian().unwrap();
        for q in 0..full.len() {
            let h = 1e-6 * (1.0 + full[q].abs());
            p.full = full.to_vec();
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

    // Finite differences of the simulation agree with the analytic sensitivities away from the kinks.
    #[test]
    fn analytic_jacobian_matches_central_differences() {
        let u: Vec<f64> = (0..200)
            .map(|k| ((k * 37) % 17) as f64 - 8.0 + 0.25)
            .collect();
        let y: Vec<f64> = (0..200).map(|k| (k as f64 * 0.05).sin()).collect();
        let data = Dataset::new(Signals { u, y }, 0.01, "t").unwrap();
        let channel = Channel {
            u: data.u(),
            nb: 2,
            nk: 1,
            block: &crate::blocks::DeadzoneBlock,
        };
        // [b_l, b_r, m_l, m_r, a1, a2, b2, c, η0, η1]
        let full = vec![-1.4, 1.3, 0.02, 0.03, -1.2, 0.4, 0.5, 0.1, 0.3, -0.2];
        let mut p = problem(vec![channel], data.y(), 2, true);
        assert_jacobian_matches_central_differences(&mut p, &full);
    }

    // Two inputs (a deadzone on the first, nb = 2, nk = 1; the second linear, nb = 2, nk = 2) and c:
    // the analytic sensitivities of every entry, initial outputs included, match central differences.
    #[test]
    fn analytic_jacobian_with_two_inputs_matches_central_differences() {
        let u1: Vec<f64> = (0..150)
            .map(|k| ((k * 37) % 17) as f64 - 8.0 + 0.25)
            .collect();
        let u2: Vec<f64> = (0..150).map(|k| (k as f64 * 0.7).cos()).collect();
        let y: Vec<f64> = (0..150).map(|k| (k as f64 * 0.05).sin()).collect();
        let channels = vec![
            Channel {
                u: &u1,
                nb: 2,
                nk: 1,
                block: &crate::blocks::DeadzoneBlock,
            },
            Channel {
                u: &u2,
                nb: 2,
                nk: 2,
                block: &crate::blocks::LinearBlock,
            },
        ];
        let mut p = problem(channels, &y, 2, true);
        assert_eq!((p.k0, p.n_params()), (3, 10));
        // [b_l, b_r, m_l, m_r, a1, a2, b2(u1), b1(u2), b2(u2), c, η0, η1, η2]
        let full = vec![
            -1.4, 1.3, 0.02, 0.03, -1.2, 0.4, 0.5, 0.3, -0.2, 0.1, 0.3, -0.2, 0.1,
        ];
        assert_jacobian_matches_central_differences(&mut p, &full);
    }

    // An output nonlinearity y = g(v) (a polynomial, smooth; a piecewise-linear map away from its
    // breakpoints): the sensitivities g'(v) ∂v/∂θ and ∂g/∂p match central differences.
    #[test]
    fn analytic_jacobian_with_an_output_nonlinearity_matches_central_differences() {
        let u: Vec<f64> = (0..120)
            .map(|k| ((k * 37) % 17) as f64 * 0.1 - 0.8 + 0.025)
            .collect();
        let y: Vec<f64> = (0..120).map(|k| (k as f64 * 0.05).sin()).collect();
        let channel = Channel {
            u: &u,
            nb: 2,
            nk: 1,
            block: &crate::blocks::LinearBlock,
        };
        let poly = crate::blocks::NonlinearityKind::Polynomial { degree: 3 }.block();
        let mut p = problem(vec![channel], &y, 2, true);
        p.output = Some(poly);
        assert_eq!((p.k0, p.n_params()), (2, 8));
        // [a1, a2, b1, b2, c, g1, g2, g3, η0, η1]
        let full = vec![-1.2, 0.4, 0.5, 0.2, 0.1, 1.1, 0.3, -0.05, 0.3, -0.2];
        assert_jacobian_matches_central_differences(&mut p, &full);
        let pwl = crate::blocks::NonlinearityKind::PiecewiseLinear { breakpoints: 1 }.block();
        let channel = Channel {
            u: &u,
            nb: 2,
            nk: 1,
            block: &crate::blocks::LinearBlock,
        };
        let mut p = problem(vec![channel], &y, 2, true);
        p.output = Some(pwl);
        // [a1, a2, b1, b2, c, p1, s0, s1, η0, η1]; the breakpoint 0.613 is away from every v(k) by
        // more than the finite-difference step.
        let full = vec![-1.2, 0.4, 0.5, 0.2, 0.1, 0.613, 1.0, 0.4, 0.3, -0.2];
        p.full = full.clone();
        let d = p.decode();
        let (v, _) = p.simulate(&d).unwrap();
        assert!(
            v.iter().all(|x| (x - 0.613).abs() > 1e-4),
            "a v(k) near the breakpoint"
        );
        assert!(v.iter().any(|x| *x > 0.613) && v.iter().any(|x| *x < 0.613));
        assert_jacobian_matches_central_differences(&mut p, &full);
    }
}
