//! The estimators, each over the one [`Regression`](crate::regression::Regression) of a [`Problem`] (one or several inputs, one or
//! several records) and the nonlinearity blocks of its inputs ([`crate::blocks`]):
//! - least squares: one QR solve without key terms (ARX); otherwise the key-term iteration
//!   (docs/paper.md, eq. 8): the switching and x̂ of every input rebuilt from the current estimate, the
//!   regression solved, until θ̂ moves less than the tolerance, with limit-cycle detection and the
//!   iterate of smallest self-consistent residual kept;
//! - recursive least squares (paper eqs. 9–12), the recursive key-term separation, in passes;
//! - output error ([`crate::oe`]) and recursive instrumental variables ([`crate::iv`]), started from
//!   least squares.
//!
//! Each method has its settings type (a small builder with defaults) and implements
//! [`Estimator`]; the safeguards common to every method are `estimate::identify`'s, not theirs.

use nalgebra::{DMatrix, DVector};

use crate::fitted::{Fitted, Method, Note, Termination};
use crate::problem::{Estimator, Problem};
use crate::regression::{scatter, scatter_into, scatter_matrix};
use crate::rls_ud::RlsForm;
use crate::warnings::Warning;
use crate::windup::Windup;
use crate::{iv, ls, oe, rls};
use sysid_core::{Dataset, Model, Setting, StaticNonlinearity, SysidError};

/// Settings of batch least squares (and of the key-term iteration for Hammerstein models).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LeastSquares {
    /// Maximum key-term iterations for Hammerstein LS (default 100).
    pub max_iterations: usize,
    /// Relative change of θ̂ below which the key-term iteration has converged (default 1e-10).
    pub tolerance: f64,
}

impl Default for LeastSquares {
    fn default() -> Self {
        LeastSquares {
            max_iterations: 100,
            tolerance: 1e-10,
        }
    }
}

/// How many passes of recursive least squares run over the data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Passes {
    /// Exactly this many passes (the paper: 1).
    Fixed(usize),
    /// Passes until the estimate settles (relative change between the ends of two passes below
    /// [`PASSES_SETTLED`]), at most `max`.
    UntilSettled {
        /// The cap.
        max: usize,
    },
}

impl Passes {
    /// The default: repeat until settled, at most 100 passes.
    pub const AUTO: Passes = Passes::UntilSettled { max: 100 };

    /// The largest number of passes that may run.
    pub fn max(&self) -> usize {
        match self {
            Passes::Fixed(n) => *n,
            Passes::UntilSettled { max } => *max,
        }
    }
}

/// Relative change of θ̂ between the ends of two passes below which repeated passes have settled.
pub const PASSES_SETTLED: f64 = 1e-10;

/// Settings of recursive least squares (paper eqs. 9–12).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RecursiveLeastSquares {
    /// ρ: forgetting factor in (0, 1] (default 1).
    pub forgetting: f64,
    /// P(0) = p0 · I (default 1e6).
    pub p0: f64,
    /// Passes over the data (default: until the estimate settles; the paper's method is one pass). Each
    /// new pass restarts P = p0 · I and keeps θ̂, so the P(0) regularisation pulls towards the previous
    /// pass's estimate and vanishes geometrically: with noise-free data a few passes reach the exact
    /// solution.
    pub passes: Passes,
    /// Covariance form (default standard: the paper's eq. 12).
    pub form: RlsForm,
    /// Covariance-windup protection (default none).
    pub windup: Windup,
    /// Bound T on tr P for [`Windup::Trace`]; `None`: p0 times the number of parameters.
    pub max_trace: Option<f64>,
    /// Keep the parameter trajectory (for convergence plots).
    pub record_history: bool,
}

impl Default for RecursiveLeastSquares {
    fn default() -> Self {
        RecursiveLeastSquares {
            forgetting: 1.0,
            p0: 1e6,
            passes: Passes::AUTO,
            form: RlsForm::Standard,
            windup: Windup::None,
            max_trace: None,
            record_history: false,
        }
    }
}

/// Settings of the output-error refinement, started from least squares (and, for a model with an
/// input nonlinearity, from instrumental variables too: [`OutputError::second_start`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputError {
    /// The least-squares start.
    pub start: LeastSquares,
    /// Patience: the search stops after this many residual evaluations per free parameter (default
    /// 100, shared with the start's key-term iteration cap).
    pub max_iterations: usize,
    /// For a model with an input nonlinearity, search from the IV estimate too and keep the lower end
    /// ([`second_start`]; default true, what `identify --method oe` does). `false` searches from the
    /// LS start alone, as before session 34: `sysid_control::tuning::twin_model` (docs/control.md, "The
    /// twin's model and the second start").
    pub second_start: bool,
}

impl Default for OutputError {
    fn default() -> Self {
        OutputError {
            start: LeastSquares::default(),
            max_iterations: 100,
            second_start: true,
        }
    }
}

/// Settings of recursive instrumental variables, started from least squares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InstrumentalVariables {
    /// The least-squares start (first auxiliary model).
    pub start: LeastSquares,
    /// ρ: forgetting factor in (0, 1].
    pub forgetting: f64,
    /// P(0) = p0 · I.
    pub p0: f64,
    /// Number of stages, each rebuilding the instruments from the previous stage's model (default 10).
    pub stages: usize,
}

impl Default for InstrumentalVariables {
    fn default() -> Self {
        InstrumentalVariables {
            start: LeastSquares::default(),
            forgetting: 1.0,
            p0: 1e6,
            stages: 10,
        }
    }
}

fn check_key_term(ls: &LeastSquares) -> Result<(), SysidError> {
    if ls.max_iterations == 0 || ls.max_iterations > 100_000 {
        return Err(SysidError::setting(
            Setting::MaxIterations,
            ls.max_iterations,
            "between 1 and 100000",
        ));
    }
    if !(ls.tolerance.is_finite() && ls.tolerance > 0.0) {
        return Err(SysidError::setting(
            Setting::Tolerance,
            ls.tolerance,
            "a positive number",
        ));
    }
    Ok(())
}

impl Estimator for LeastSquares {
    fn method(&self) -> Method {
        Method::Ls
    }
    fn check(&self) -> Result<(), SysidError> {
        check_key_term(self)
    }
    fn fit(&self, p: &Problem) -> Result<Fitted, SysidError> {
        least_squares(p, self)
    }
}

fn check_recursive(forgetting: f64, p0: f64, passes: Passes) -> Result<(), SysidError> {
    let passes = passes.max();
    rls::check_settings(forgetting, p0)?;
    if passes == 0 || passes > 1000 {
        return Err(SysidError::setting(
            Setting::Passes,
            passes,
            "between 1 and 1000 passes",
        ));
    }
    Ok(())
}

impl Estimator for RecursiveLeastSquares {
    fn method(&self) -> Method {
        Method::Rls
    }
    fn check(&self) -> Result<(), SysidError> {
        check_recursive(self.forgetting, self.p0, self.passes)?;
        if let Some(t) = self.max_trace {
            if !(t.is_finite() && t > 0.0) {
                return Err(SysidError::setting(
                    Setting::MaxTrace,
                    t,
                    "a positive, finite bound on tr P",
                ));
            }
        }
        Ok(())
    }
    fn fit(&self, p: &Problem) -> Result<Fitted, SysidError> {
        recursive(p, self)
    }
}

impl Estimator for OutputError {
    fn method(&self) -> Method {
        Method::Oe
    }
    fn check(&self) -> Result<(), SysidError> {
        check_key_term(&self.start)?;
        check_key_term(&LeastSquares {
            max_iterations: self.max_iterations,
            tolerance: 1.0,
        })
    }
    fn fit(&self, p: &Problem) -> Result<Fitted, SysidError> {
        output_error(p, self)
    }
}

impl Estimator for InstrumentalVariables {
    fn method(&self) -> Method {
        Method::Iv
    }
    fn check(&self) -> Result<(), SysidError> {
        check_key_term(&self.start)?;
        check_recursive(self.forgetting, self.p0, Passes::Fixed(1))?;
        if self.stages == 0 || self.stages > 1000 {
            return Err(SysidError::setting(
                Setting::IvStages,
                self.stages,
                "between 1 and 1000 stages",
            ));
        }
        Ok(())
    }
    fn fit(&self, p: &Problem) -> Result<Fitted, SysidError> {
        instrumental(p, self)
    }
}

/// A data error prefixed with the records' name.
fn context(p: &Problem, e: SysidError) -> SysidError {
    match e {
        SysidError::Data(m) => SysidError::Data(format!("{}: {m}", p.name())),
        other => other,
    }
}

/// Sum of squared one-step prediction errors of `model` over every record's rows k >= k0 (the
/// self-consistent residual: switching functions and x from the model itself).
fn prediction_rss(model: &Model, records: &[Dataset]) -> Result<f64, SysidError> {
    let k0 = model.k0();
    let mut rss = 0.0;
    for r in records {
        let yhat = model.predict_equation_error(&r.input_signals(), r.y())?;
        rss += r.y()[k0..]
            .iter()
            .zip(&yhat[k0..])
            .map(|(y, p)| (y - p) * (y - p))
            .sum::<f64>();
    }
    Ok(rss)
}

/// The model of the full key-term θ̂ with the blocks' fixed parts imposed; a non-finite θ̂ is a
/// numerical failure naming the data.
fn model_from_theta(p: &Problem, theta: &DVector<f64>) -> Result<Model, SysidError> {
    let reg = p.regression();
    reg.model_of(theta.as_slice(), p.starts(), p.ts())
        .map_err(|e| {
            let params = reg.params_of_theta(theta.as_slice(), None);
            crate::fitted::check_finite(p.name(), &params)
                .err()
                .unwrap_or_else(|| SysidError::Numerical(format!("{}: {e}", p.name())))
        })
}

/// Least squares over the free columns of Φ; θ and (ΦᵀΦ)⁻¹ are returned at full size with zeros for
/// the fixed entries.
fn solve_free(
    phi: &DMatrix<f64>,
    y: &DVector<f64>,
    free: &[bool],
    names: &[String],
) -> Result<ls::LsSolution, SysidError> {
    if free.iter().all(|f| *f) {
        return ls::solve(phi, y, names);
    }
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let sub = phi.select_columns(idx.iter());
    let sub_names: Vec<String> = idx.iter().map(|&i| names[i].clone()).collect();
    let sol = ls::solve(&sub, y, &sub_names)?;
    let zeros = vec![0.0; free.len()];
    Ok(ls::LsSolution {
        theta: DVector::from_vec(scatter(free, sol.theta.as_slice(), &zeros)),
        inv_gram: scatter_matrix(free, &sol.inv_gram),
        rss: sol.rss,
    })
}

/// True when `a` and `b` hold the same numbers bit for bit.
fn same_bits(a: &[f64], b: &[f64]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The nonlinearities the estimators start from (each block's start).
fn initial(p: &Problem) -> Vec<StaticNonlinearity> {
    p.starts().iter().map(|s| s.initial).collect()
}

/// Least squares without key terms: one solve of the linear regression.
pub(crate) fn arx_ls(p: &Problem) -> Result<Fitted, SysidError> {
    let reg = p.regression();
    let (phi, y) = reg
        .stacked(p.records(), &initial(p))
        .map_err(|e| context(p, e))?;
    let sol = ls::solve(&phi, &y, &reg.names()).map_err(|e| context(p, e))?;
    let sigma2 = ls::noise_variance(sol.rss, phi.nrows(), phi.ncols());
    let cov = &sol.inv_gram * sigma2;
    let params = reg.params_of_theta(sol.theta.as_slice(), Some(&cov));
    let model = model_from_theta(p, &sol.theta)?;
    Ok(Fitted::new(model, params, Method::Ls, sigma2))
}

/// Least squares (module docs): [`arx_ls`] without key terms, else the key-term iteration.
pub(crate) fn least_squares(p: &Problem, st: &LeastSquares) -> Result<Fitted, SysidError> {
    if !p.regression().nonlinear() {
        return arx_ls(p);
    }
    let reg = p.regression();
    let names = reg.names();
    let free = reg.free_key(p.starts());
    let n_free = free.iter().filter(|f| **f).count();
    // Initial switching: each block's start (a deadzone: breakpoints at the smallest commands).
    let mut f = initial(p);
    let mut seen: Vec<DVector<f64>> = Vec::new();
    let mut best: Option<(f64, DVector<f64>, ls::LsSolution, usize)> = None;
    let mut converged = false;
    let mut cycle = false;
    let mut iterations = 0;
    // The previous iterate's Φ, solution and loss.
    let mut last: Option<(DMatrix<f64>, ls::LsSolution, f64)> = None;
    for it in 1..=st.max_iterations {
        p.cancel().check()?;
        iterations = it;
        let (phi, y) = reg.stacked(p.records(), &f).map_err(|e| context(p, e))?;
        let (sol, rss) = match last.take() {
            // The switching functions did not change (typically the iterate that confirms convergence):
            // Φ is the previous one to the bit, and so are θ̂ and its loss; not computed twice.
            Some((prev, sol, rss)) if same_bits(prev.as_slice(), phi.as_slice()) => (sol, rss),
            _ => {
                let sol = match solve_free(&phi, &y, &free, &names) {
                    Ok(sol) => sol,
                    // A later iterate's breakpoints can leave a branch with too few distinct commands:
                    // stop and keep the best iterate so far (reported in the note as not converged).
                    Err(SysidError::Data(_)) if best.is_some() => break,
                    Err(e) => return Err(context(p, e)),
                };
                let rss = model_from_theta(p, &sol.theta)
                    .and_then(|m| prediction_rss(&m, p.records()))
                    .unwrap_or(f64::INFINITY);
                (sol, rss)
            }
        };
        last = Some((phi, sol.clone(), rss));
        let theta = sol.theta.clone();
        if best.as_ref().is_none_or(|b| rss < b.0) {
            best = Some((rss, theta.clone(), sol, it));
        }
        let scale = 1.0 + theta.norm();
        if let Some(prev) = seen.last() {
            if (&theta - prev).norm() <= st.tolerance * scale {
                converged = true;
                break;
            }
        }
        if seen
            .iter()
            .rev()
            .skip(1)
            .any(|old| (&theta - old).norm() <= st.tolerance * scale)
        {
            cycle = true;
            break;
        }
        seen.push(theta.clone());
        reg.update(theta.as_slice(), &mut f, p.starts());
    }
    let Some((rss, theta, sol, best_it)) = best else {
        return Err(SysidError::Numerical(
            "key-term iteration produced no estimate".into(),
        ));
    };
    let (termination, notes) = if converged {
        (Termination::Converged, Vec::new())
    } else if cycle {
        (
            Termination::LimitCycle,
            vec![Note::KeyTermLimitCycle {
                iterations,
                kept: best_it,
            }],
        )
    } else {
        (
            Termination::IterationLimit,
            vec![Note::KeyTermNotConverged {
                iterations,
                kept: best_it,
            }],
        )
    };
    let rows = reg.rows(p.records());
    let sigma2 = ls::noise_variance(rss, rows, n_free);
    let cov = &sol.inv_gram * sigma2;
    let model = model_from_theta(p, &theta)?;
    Ok(Fitted {
        params: reg.params(theta.as_slice(), Some(&cov), &model, p.starts()),
        iterations,
        termination,
        notes,
        ..Fitted::new(model, Vec::new(), Method::Ls, sigma2)
    })
}

/// The recursive estimator of `np` parameters that `st` describes: the paper's RLS for the standard form
/// without windup protection, `RobustRls` otherwise.
fn recursive_estimator(
    np: usize,
    st: &RecursiveLeastSquares,
) -> Result<Box<dyn rls::RecursiveUpdate>, SysidError> {
    crate::rls_ud::recursive_estimator(np, st.forgetting, st.p0, st.form, st.windup, st.max_trace)
}

/// RLS, the recursive key-term separation. First pass (the paper's scheme): each input's switching and
/// x̂ are evaluated with the latest estimate at every sample. Later passes restart P = p0 I, keep θ̂ and
/// evaluate them with the estimate the pass started from, so each pass is the recursive solution of one
/// key-term LS step regularised towards the previous estimate; the passes converge to the batch
/// key-term fixed point. Several records run one after the other in each pass; no regressor spans two.
pub(crate) fn recursive(p: &Problem, st: &RecursiveLeastSquares) -> Result<Fitted, SysidError> {
    let reg = p.regression();
    let records = p.records();
    let k0 = reg.k0();
    let free = reg.free_key(p.starts());
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let np = idx.len();
    // Every entry free (the usual case): θ̂ and φ need no scatter to the full layout and back.
    let all_free = np == reg.len();
    let mut est = recursive_estimator(np, st)?;
    let mut full_row = vec![0.0; reg.len()];
    let mut row = vec![0.0; np];
    let hammer = reg.nonlinear();
    let mut f = initial(p);
    let initial_f = f.clone();
    // Persistent excitation: the recursion never fails on data that cannot determine θ (P merely stays
    // large in the unexcited directions), so the regressor matrix of the first pass is rank-tested
    // first, as the batch methods do, and such data are refused with the same message — for every
    // forgetting factor and windup protection alike (audit s20 H-1: `--windup trace` accepted a
    // constant input and printed every parameter "± 0"). Spells without excitation inside a record
    // (what forgetting and windup protection are for) pass: the test is over the whole record; a record
    // that excites θ nowhere is refused, as no estimator can determine θ from it.
    let total_rows = reg.rows(records);
    // A later pass of the plain recursion (standard form, ρ = 1, no windup protection, no history,
    // every entry of θ free) is the regularised least squares `regularised_pass` solves in closed form;
    // the recursion runs otherwise, and when that solve fails.
    let closed_form = st.form == RlsForm::Standard
        && st.windup == Windup::None
        && st.forgetting == 1.0
        && !st.record_history
        && all_free;
    let names = reg.names();
    // The closed-form passes' buffer of N + p rows, Φ built into its first N.
    let mut aug: Option<Buffers> = None;
    if total_rows >= np {
        // Only the rank verdict matters here; numerical trouble (overflow) is left to the recursion,
        // which reports the sample where it happens.
        let verdict = if closed_form {
            // Built into the closed-form passes' buffer: its p prior rows are still 0, which add only
            // zeros to the QR's sums (the same R as Φ alone up to the order of summation, so the same
            // verdict except within rounding of the rank tolerance).
            let (mut a, mut b) = buffers(total_rows + np, np).map_err(|e| context(p, e))?;
            reg.stacked_into::<false>(records, &f, &mut a, &mut b);
            // The solve's verdict without its target column or solution (the records' y is finite).
            let verdict = ls::rank_test(&a, &names);
            aug = Some((a, b));
            verdict
        } else {
            reg.stacked(records, &f)
                .and_then(|(phi, y)| solve_free(&phi, &y, &free, &names).map(|_| ()))
        };
        if let Err(e @ SysidError::Data(_)) = verdict {
            return Err(context(p, e));
        }
    }
    let zeros = vec![0.0; reg.len()];
    let expand = |t: &[f64]| DVector::from_vec(scatter(&free, t, &zeros));
    let mut full_theta = zeros.clone();
    let mut history = Vec::new();
    let mut history_samples = Vec::new();
    let mut pass_ends: Vec<DVector<f64>> = Vec::new();
    let tail_start = total_rows - total_rows / 10;
    let mut theta_tail = DVector::from_column_slice(est.theta());
    let mut settled = false;
    // θ̂ at the end of the last pass, and P there when that pass was solved in closed form (otherwise
    // the estimator's).
    let mut theta = DVector::from_column_slice(est.theta());
    let mut closed: Option<ClosedPass> = None;
    for pass in 0..st.passes.max() {
        p.cancel().check()?;
        if pass > 0 {
            if hammer {
                reg.update(expand(theta.as_slice()).as_slice(), &mut f, p.starts());
            }
            if closed_form {
                let prev = closed.take();
                let rows = FreeRows {
                    reg,
                    records,
                    names: &names,
                };
                let buf = match aug.as_mut() {
                    Some(buf) => buf,
                    None => aug.insert(buffers(total_rows + np, np).map_err(|e| context(p, e))?),
                };
                if let Ok(pass) = regularised_pass(&rows, &f, &theta, st.p0, prev, buf) {
                    theta.copy_from(&pass.sol.theta);
                    closed = Some(pass);
                    if pass_end(st.passes, &mut pass_ends, &theta) {
                        settled = true;
                        break;
                    }
                    continue;
                }
            }
            est.restart_at(theta.as_slice(), st.p0);
        }
        let mut at = 0;
        for r in records {
            let u = r.input_signals();
            for k in k0..r.len() {
                p.cancel().every(at)?;
                if at == tail_start {
                    theta_tail.copy_from_slice(est.theta());
                }
                if hammer && pass == 0 && at > 0 {
                    if all_free {
                        reg.update(est.theta(), &mut f, p.starts());
                    } else {
                        // θ̂ at full size in a buffer kept across samples (no allocation per sample).
                        scatter_into(&free, est.theta(), &zeros, &mut full_theta);
                        reg.update(&full_theta, &mut f, p.starts());
                    }
                    for ((fm, start), ch) in f.iter_mut().zip(&initial_f).zip(reg.channels()) {
                        if ch.kind.block().is_degenerate(fm) {
                            *fm = *start;
                        }
                    }
                }
                if all_free {
                    reg.fill_row(&u, r.y(), &f, k, &mut row);
                } else {
                    reg.fill_row(&u, r.y(), &f, k, &mut full_row);
                    for (q, &i) in idx.iter().enumerate() {
                        row[q] = full_row[i];
                    }
                }
                est.update(&row, r.y()[k], k)
                    .map_err(|e| e.context(r.name()))?;
                if st.record_history {
                    history.push(
                        reg.params_of_theta(expand(est.theta()).as_slice(), None)
                            .iter()
                            .map(|q| q.value)
                            .collect(),
                    );
                    history_samples.push(k);
                }
                at += 1;
            }
        }
        theta.copy_from_slice(est.theta());
        if pass_end(st.passes, &mut pass_ends, &theta) {
            settled = true;
            break;
        }
    }
    let passes_run = pass_ends.len();
    let rel = |a: &DVector<f64>, b: &DVector<f64>| (a - b).norm() / (1e-300 + b.norm());
    let converged = match st.passes {
        Passes::UntilSettled { .. } => settled,
        Passes::Fixed(_) if pass_ends.len() >= 2 => {
            rel(&pass_ends[pass_ends.len() - 2], &theta) < 1e-3
        }
        Passes::Fixed(_) => rel(&theta_tail, &theta) < 1e-3,
    };
    let theta_full = expand(theta.as_slice());
    let model = model_from_theta(p, &theta_full)?;
    let rss = prediction_rss(&model, records)?;
    let sigma2 = ls::noise_variance(rss, total_rows, np);
    // P at the end: the closed-form pass's when the last pass was one (a recursive pass after a
    // closed-form one clears it).
    let p_end = closed.map_or_else(|| est.covariance(), |c| c.sol.inv_gram);
    // Without forgetting the last pass is least squares regularised by I / p0 towards the estimate it
    // started from (θ̂ = 0 on the first). Passes repeated until they settled reach the fixed point,
    // where that pull is gone; otherwise, with regressors small against 1/p0 (signals in µ-units), the
    // start holds the estimate (audit s37 M-2: the hair dryer × 1e-6 fit 2.9 % for 88.9 %, warned only
    // "not converged, more passes may settle it"; `--p0 1e15` gives 88.95 %). Said as for iv and track.
    let prior = (st.forgetting == 1.0
        && !(matches!(st.passes, Passes::UntilSettled { .. }) && settled))
        .then(|| crate::trust::prior_warning("rls", p_end.singular_values().max() / st.p0, st.p0))
        .flatten();
    // With forgetting ρ < 1 the last pass is the exponentially weighted LS
    // θ̂ = P Σ_k ρ^(N−k) φ(k) y(k), P = (Σ_k ρ^(N−k) φ(k)φ(k)ᵀ + ρ^N P0⁻¹)⁻¹, so with white noise of
    // variance σ² and the regressors taken as given, Cov θ̂ = σ² P (Σ_k ρ^(2(N−k)) φ(k)φ(k)ᵀ) P (the
    // prior's share, ρ^N, is left out). σ²P alone is too large by about (1 + ρ) in variance for a
    // stationary regressor (P ≈ (1 − ρ) R⁻¹, the middle sum ≈ R/(1 − ρ²)): audit s18 M-5 measured
    // the ± 1.45–1.66× the real spread. Windup protection changes P's recursion, so there σ²P is kept.
    let p_cov = if st.forgetting < 1.0 && st.windup == Windup::None {
        let mut mid = DMatrix::<f64>::zeros(np, np);
        let ln_rho = st.forgetting.ln();
        let mut at = 0usize;
        for r in records {
            let u = r.input_signals();
            for k in k0..r.len() {
                let w = (2.0 * (total_rows - 1 - at) as f64 * ln_rho).exp();
                at += 1;
                if w == 0.0 {
                    continue;
                }
                if all_free {
                    reg.fill_row(&u, r.y(), &f, k, &mut row);
                } else {
                    reg.fill_row(&u, r.y(), &f, k, &mut full_row);
                    for (q, &i) in idx.iter().enumerate() {
                        row[q] = full_row[i];
                    }
                }
                for i in 0..np {
                    for j in 0..np {
                        mid[(i, j)] += w * row[i] * row[j];
                    }
                }
            }
        }
        &p_end * mid * &p_end
    } else {
        p_end
    };
    let cov = scatter_matrix(&free, &(p_cov * sigma2));
    let mut notes = Vec::new();
    if let Passes::UntilSettled { max } = st.passes {
        notes.push(Note::PassesUntilSettled {
            passes: passes_run,
            settled,
            max,
        });
    }
    if st.form != RlsForm::Standard || st.windup != Windup::None {
        notes.push(Note::RlsForm {
            form: st.form,
            windup: st.windup,
        });
    }
    Ok(Fitted {
        params: reg.params(theta_full.as_slice(), Some(&cov), &model, p.starts()),
        iterations: passes_run,
        termination: if converged {
            Termination::Converged
        } else {
            Termination::NotSettled
        },
        notes,
        history,
        history_samples,
        warnings: est
            .covariance_resets()
            .map(Warning::CovarianceReset)
            .into_iter()
            .chain(prior)
            .collect(),
        ..Fitted::new(model, Vec::new(), Method::Rls, sigma2)
    })
}

/// Records θ̂ = `end` at the end of a pass; true when the passes have settled (with
/// [`Passes::UntilSettled`], the change since the previous pass's end is below [`PASSES_SETTLED`]
/// relative).
fn pass_end(passes: Passes, pass_ends: &mut Vec<DVector<f64>>, end: &DVector<f64>) -> bool {
    let settled = match (passes, pass_ends.last()) {
        (Passes::UntilSettled { .. }, Some(prev)) => {
            (end - prev).norm() <= PASSES_SETTLED * (1e-300 + end.norm())
        }
        _ => false,
    };
    pass_ends.push(end.clone());
    settled
}

/// The regression of a problem's records (its entries named `names`).
struct FreeRows<'a> {
    reg: &'a crate::regression::Regression,
    records: &'a [Dataset],
    names: &'a [String],
}

/// The augmented matrix [Φ; w I] and target [y; w θ_prev] of the closed-form passes (w = 1/√p0), one
/// buffer built into again by every pass.
type Buffers = (DMatrix<f64>, DVector<f64>);

/// The closed-form passes' buffers of `rows` rows and `np` columns, allocated fallibly (a failed
/// allocation is an error, not an abort).
fn buffers(rows: usize, np: usize) -> Result<Buffers, SysidError> {
    Ok((
        ls::try_matrix(rows, np, "the regression matrix")?,
        DVector::from_vec(ls::try_zeros(rows, "the regression targets")?),
    ))
}

/// What a closed-form RLS pass leaves for the next ([`regularised_pass`]).
struct ClosedPass {
    /// θ_prev, the estimate the pass started from.
    start: DVector<f64>,
    /// θ̂_N and P_N = (ΦᵀΦ + I/p0)⁻¹ (as `inv_gram`).
    sol: ls::LsSolution,
}

/// One later RLS pass in closed form, every entry of θ free. Such a pass restarts P(0) = p0 I at
/// θ̂(0) = θ_prev and keeps the nonlinearities `f` of its start, so with ρ = 1 the recursion (paper
/// eqs. 9–12) is exact recursive least squares with the prior θ_prev of weight I/p0: after the N rows
/// φ_k of the records,
///
/// ```text
/// P_N = (Σ φ_k φ_kᵀ + I/p0)⁻¹,   θ̂_N = P_N (Σ φ_k y_k + θ_prev/p0),
/// ```
///
/// i.e. the least-squares solution of the rows [φ_kᵀ | y_k] augmented by the p rows
/// [w e_iᵀ | w θ_prev,i], w = 1/√p0, solved by Householder QR of that augmented matrix ([`ls::solve`],
/// never the normal equations): the same numbers as the recursion up to rounding. When Φ repeats the
/// previous closed-form pass's to the bit (no switching changed: the usual last pass, which confirms the
/// settling), P_N and Σ φ y are that pass's too, and θ̂_N = θ̂' + P_N (θ_prev − θ'_prev)/p0 from its
/// θ̂' and start θ'_prev, without a second factorisation. `buf` holds (N + p) rows: Φ of the last
/// build (a previous pass's, or the rank test's) above, overwritten here.
fn regularised_pass(
    rows: &FreeRows,
    f: &[StaticNonlinearity],
    theta_prev: &DVector<f64>,
    p0: f64,
    prev: Option<ClosedPass>,
    buf: &mut Buffers,
) -> Result<ClosedPass, SysidError> {
    let (a, b) = buf;
    let np = a.ncols();
    let m = a.nrows() - np;
    let repeats = rows.reg.stacked_into::<true>(rows.records, f, a, b);
    let w = 1.0 / p0.sqrt();
    for (q, col) in a.as_mut_slice().chunks_exact_mut(m + np).enumerate() {
        col[m..].fill(0.0);
        col[m + q] = w;
    }
    for (q, t) in theta_prev.iter().enumerate() {
        b[m + q] = w * t;
    }
    let start = theta_prev.clone();
    match prev {
        Some(prev) if repeats => {
            let step = &prev.sol.inv_gram * ((theta_prev - &prev.start) / p0);
            let theta = &prev.sol.theta + step;
            if !theta.iter().all(|v| v.is_finite()) {
                return Err(SysidError::Numerical(
                    "a repeated RLS pass gave a non-finite estimate".into(),
                ));
            }
            let sol = ls::LsSolution { theta, ..prev.sol };
            Ok(ClosedPass { start, sol })
        }
        _ => {
            let sol = solve_augmented(a, b, rows.names)?;
            Ok(ClosedPass { start, sol })
        }
    }
}

/// The least squares of a closed-form pass's augmented rows.
fn solve_augmented(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    names: &[String],
) -> Result<ls::LsSolution, SysidError> {
    // With the rank test of every solve: the prior rows make the columns independent, but a column of
    // norm above ~1e7 √p0 scales them below its tolerance; the caller then runs the recursion.
    ls::solve(a, b, names)
}

/// The one record of `p`, or an error naming `method` for merged records.
fn one_record<'a>(p: &Problem<'a>, method: &str) -> Result<&'a Dataset, SysidError> {
    match p.records() {
        [one] => Ok(one),
        _ => Err(SysidError::setting(
            sysid_core::Setting::Other("--method"),
            method,
            "ls or rls with several records (--merge): output error and instrumental variables work on one record",
        )),
    }
}

/// Recursive IV in stages ([`iv::staged`]), the first stage's instruments from the LS (key-term)
/// estimate; the instruments use each input's nonlinearity of the auxiliary model.
pub(crate) fn instrumental(p: &Problem, st: &InstrumentalVariables) -> Result<Fitted, SysidError> {
    instrumental_from(p, st, &least_squares(p, &st.start)?)
}

/// [`instrumental`] from a least-squares (key-term) `start` already computed with `st.start`'s
/// settings (output error's second start reuses its own LS start: [`second_start`]).
fn instrumental_from(
    p: &Problem,
    st: &InstrumentalVariables,
    start: &Fitted,
) -> Result<Fitted, SysidError> {
    let data = one_record(p, "iv")?;
    let reg = p.regression();
    let free = reg.free_key(p.starts());
    let n_free = free.iter().filter(|f| **f).count();
    let k0 = reg.k0();
    let u = data.input_signals();
    let r = iv::IvRegression {
        rows: (),
        y: data.y(),
        k0,
        free: &free,
        name: data.name(),
    };
    let out = iv::staged(
        &start.model,
        &reg.key_vector(&start.model),
        &u,
        &r,
        |aux: &Model| {
            let f: Vec<StaticNonlinearity> =
                aux.inputs().iter().map(|c| *c.nonlinearity()).collect();
            let u = &u;
            move |ys: &[f64], k: usize, row: &mut [f64]| reg.fill_row(u, ys, &f, k, row)
        },
        |theta| model_from_theta(p, theta),
        p.cancel(),
        st.stages,
        st.forgetting,
        st.p0,
    )?;
    let rss = prediction_rss(&out.model, p.records())?;
    let rows = data.len() - k0;
    let sigma2 = ls::noise_variance(rss, rows, n_free);
    // The autocovariances' divisor, N − p as σ̂²'s (unused when σ̂² is NaN: no covariance then).
    let dof = rows.saturating_sub(n_free).max(1) as f64;
    // The equation error's autocovariance r_v(τ), τ = 0..=n_a (at most iv::COV_LAGS), from the kept
    // model's one-step (equation-error) residuals, with the same divisor as σ̂²: white output noise
    // makes v = A(q) e a moving average of order n_a (see `iv::covariance`).
    let lags = out.model.a().len().min(iv::COV_LAGS);
    let r_v: Vec<f64> = match out.model.predict_equation_error(&u, data.y()) {
        Ok(pred) => {
            let v: Vec<f64> = data.y()[k0..]
                .iter()
                .zip(&pred[k0..])
                .map(|(y, p)| y - p)
                .collect();
            (0..=lags)
                .map(|tau| {
                    if tau == 0 {
                        sigma2
                    } else {
                        v.iter().skip(tau).zip(&v).map(|(a, b)| a * b).sum::<f64>() / dof
                    }
                })
                .collect()
        }
        Err(_) => vec![sigma2],
    };
    let cov = iv::covariance(&out.pass, &r_v).map(|c| scatter_matrix(&free, &c));
    let why = cov.is_none().then(|| {
        if sigma2.is_nan() {
            return ls::NO_RESIDUAL_DOF.to_string();
        }
        "the instrument cross-moment matrix ZᵀΦ of the kept IV stage is singular (or its covariance \
         (ZᵀΦ)⁻¹ [Σ_τ r_v(τ) Σ z(k) z(k−τ)ᵀ] (ΦᵀZ)⁻¹ is not finite): the instruments do not determine \
         every parameter"
            .to_string()
    });
    Ok(Fitted {
        params: reg.params(out.theta.as_slice(), cov.as_ref(), &out.model, p.starts()),
        iterations: out.stages,
        termination: out.termination,
        notes: out.notes,
        warnings: crate::trust::std_warning(why)
            .into_iter()
            .chain(crate::trust::prior_warning(
                "iv",
                out.pass.prior_share,
                st.p0,
            ))
            .collect(),
        ..Fitted::new(out.model, Vec::new(), Method::Iv, sigma2)
    })
}

/// The simulation RMSEs of a stable `model` on `data` from estimated and from measured initial outputs
/// (`None` for an unstable model or a failed simulation).
pub(crate) fn simulation_rmses(model: &Model, data: &Dataset) -> Option<SimulationRmse> {
    if !model.poles_inside_unit_circle() {
        return None;
    }
    let m = sysid_core::metrics::metrics(model, data).ok()?;
    Some(SimulationRmse {
        estimated: m.rmse_sim?,
        measured: m.rmse_sim_measured,
        pooled: crate::trust::pooled_rmse(&m)?,
    })
}

/// A candidate's free-run simulation RMSEs on the estimation record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulationRmse {
    /// From estimated initial outputs (the output-error criterion).
    pub estimated: f64,
    /// From the measured initial outputs y(0..k0−1), when computed.
    pub measured: Option<f64>,
    /// Pooled over both ([`crate::trust::pooled_rmse`]): what the verdict compares.
    pub pooled: f64,
}

/// Output-error refinement from the LS (key-term) estimate. The search minimises the simulation error
/// with estimated initial outputs. Both candidates (the LS start and the refined model) are judged on
/// the RMSE pooled over estimated and measured initial outputs ([`OeVerdict::judge`]) and the better
/// stable one is returned, with a note saying which (and a warning when it is not the refined model).
pub(crate) fn output_error(p: &Problem, st: &OutputError) -> Result<Fitted, SysidError> {
    let data = one_record(p, "oe")?;
    let start = least_squares(p, &st.start)?;
    let reg = p.regression();
    let free = reg.free_physical(p.starts());
    let fit = oe::refine(
        data,
        reg,
        &free,
        &start.model,
        st.max_iterations,
        p.cancel(),
    )?;
    // The second start only where the input block has kinks or curvature (every input not linear):
    // the deadzone's breakpoints on input levels are what stopped the search from LS in a local
    // minimum (audit s34 H-1). A linear (ARX) search keeps its one start: the second would triple its
    // time (`ipa-sysid bench oe`: EMPS 0.18 → 0.67 s, silverbox 1.09 → 3.40 s, beyond issue 16's 0.5 s
    // and 2 s) for records where no second minimum was met.
    let nonlinear = start
        .model
        .inputs()
        .iter()
        .any(|c| !c.nonlinearity().is_linear());
    let (fit, second, local_minima) = if nonlinear && st.second_start {
        second_start(p, st, data, &free, &start, fit)?
    } else {
        (fit, None, None)
    };
    let verdict = OeVerdict::judge(
        &fit,
        &start.notes,
        simulation_rmses(&fit.model, data),
        simulation_rmses(&start.model, data),
    );
    let verdict = OeVerdict {
        notes: verdict.notes.into_iter().chain(second).collect(),
        ..verdict
    };
    if verdict.fallback.is_none() {
        return Ok(Fitted {
            iterations: fit.iterations,
            termination: verdict.termination,
            notes: verdict.notes,
            warnings: crate::trust::std_warning(fit.std_unavailable.clone())
                .into_iter()
                .chain(local_minima)
                .collect(),
            ..Fitted::new(fit.model, fit.params, Method::Oe, fit.noise_variance)
        });
    }
    Ok(Fitted {
        iterations: fit.iterations,
        termination: verdict.termination,
        notes: verdict.notes,
        warnings: verdict.fallback.into_iter().chain(local_minima).collect(),
        ..start
    }
    .with_method(Method::Oe))
}

/// Relative margin by which the output-error search from the IV start must end lower than the one
/// from the LS start to be kept ([`second_start`]). Two searches that reach the same minimum end within
/// the search's tolerance (1.5e-8 relative), or, at a kink of the deadzone (a breakpoint on an input
/// level), a little apart: the README's worked example ends 1.5e-4 apart (RSS 5.1035e4 from LS,
/// 5.1027e4 from IV, b_l 4e-5 and 1e-5 from the level −48, validation fit 75.47 and 75.52 %), the same
/// minimum for any use. Below 0.1 % the LS start's end (the one documented figures come from) stays.
pub const SECOND_START_MARGIN: f64 = 1e-3;

/// The output-error search again from the IV estimate, and the end with the lower simulation RSS (the
/// search's own criterion, estimated initial outputs) by more than [`SECOND_START_MARGIN`]; the note
/// says what both searches reached.
///
/// Why (audit s34 H-1): from the LS start, which output noise biases, the search stopped in a local
/// minimum on records of the paper's plant with small commands (`simulate --plant paper --input
/// staircase --amplitude 20 --noise-std 0.01 --seed 1`: a₁ = −1.198 against the truth −1.869, RSS twice
/// the true model's, "converged", no warning; 9 of 10 seeds wrong at amplitude 8), where IV (consistent
/// under output noise) starts near the truth. MATLAB's `oe` likewise starts from an IV estimate. An IV
/// estimate that fails (or whose search fails) leaves the LS start's end, and the note says why; a stop
/// asked for is passed on.
fn second_start(
    p: &Problem,
    st: &OutputError,
    data: &Dataset,
    free: &[bool],
    ls_start: &Fitted,
    first: oe::OeFit,
) -> Result<(oe::OeFit, Option<Note>, Option<Warning>), SysidError> {
    let iv = InstrumentalVariables {
        start: st.start,
        ..InstrumentalVariables::default()
    };
    let search = |start: &Model| {
        oe::refine(
            data,
            p.regression(),
            free,
            start,
            st.max_iterations,
            p.cancel(),
        )
    };
    let refined = instrumental_from(p, &iv, ls_start).and_then(|iv| search(&iv.model));
    let second = match refined {
        Ok(f) => f,
        Err(SysidError::Cancelled) => return Err(SysidError::Cancelled),
        Err(e) => {
            let note = Note::SecondStart {
                rss_ls: first.rss,
                rss_iv: None,
                kept_iv: false,
                why: Some(e.to_string()),
            };
            return Ok((first, Some(note), None));
        }
    };
    // Differences at the level of rounding (a noise-free record fitted exactly: RSS 1e-21 against
    // 1e-22) are no other minimum: 1e-12 of the output's sum of squares about its mean.
    let y = data.y();
    let mean = y.iter().sum::<f64>() / y.len().max(1) as f64;
    let floor = 1e-12 * y.iter().map(|v| (v - mean).powi(2)).sum::<f64>();
    let lower = |a: f64, b: f64, margin: f64| {
        a.is_finite() && (!b.is_finite() || a < b - (margin * b).max(floor))
    };
    // The lower end is kept even when its search stopped at the iteration cap (then reported "not
    // converged"): on `simulate --plant paper --input staircase --amplitude 8 --noise-std 0.01 --seed 2`
    // the search from IV crept to RSS 0.200 (the noise's own: 2000 · 0.01²) at its cap, the one from LS
    // converged at 5.37 (a₁ −1.02 against −1.869).
    let kept_iv = lower(second.rss, first.rss, SECOND_START_MARGIN);
    let note = Note::SecondStart {
        rss_ls: first.rss,
        rss_iv: Some(second.rss),
        kept_iv,
        why: None,
    };
    // Only when the end from IV is the lower one: an IV estimate far off (an outlier run) whose search
    // ends high says nothing against the LS start's end.
    let apart = lower(second.rss, first.rss, LOCAL_MINIMA_MARGIN).then_some(Warning::LocalMinima {
        rss_ls: first.rss,
        rss_iv: second.rss,
    });
    Ok((if kept_iv { second } else { first }, Some(note), apart))
}

/// Relative margin by which the output-error search from the IV start must end below the one from the LS
/// start ([`second_start`]) for [`Warning::LocalMinima`] to say that the criterion has several local
/// minima on the record.
pub const LOCAL_MINIMA_MARGIN: f64 = 0.01;

/// Relative margin by which the start's pooled RMSE must beat the refinement's for the start to be
/// kept: a refinement no worse than its start within 1 % is kept (a difference that small is no reason
/// to return another model than the method asked for), except a refinement held on the stability
/// boundary against a stable start, which must be no worse at all ([`OeVerdict::judge`]; ball and beam
/// (2, 2, 1), rows 0–499: an integrator at 0.05918 against the stable start's 0.05881, 0.6 %, was kept
/// until session 35).
pub const OE_VERDICT_TOLERANCE: f64 = 0.01;

/// Whether an output-error refinement is kept over the start it began from (the least-squares start
/// of `--method oe`, [`OeVerdict::judge`]; the model without output nonlinearity of a Wiener fit,
/// `wiener::refine`): judged on the estimation simulation RMSE pooled over estimated and measured
/// initial outputs ([`SimulationRmse::pooled`], [`crate::trust::pooled_rmse`]; `None` for an unstable
/// or diverging model), the refinement is kept unless the start's is lower by more than
/// [`OE_VERDICT_TOLERANCE`] (relative); a candidate that simulates stably beats one that does not.
/// `None` when neither simulates stably (the caller decides). Why pooled: [`OeVerdict::judge`].
pub fn refinement_kept(
    refined: Option<SimulationRmse>,
    start: Option<SimulationRmse>,
) -> Option<bool> {
    match (refined.map(|r| r.pooled), start.map(|s| s.pooled)) {
        (Some(r), Some(s)) => Some(r <= s * (1.0 + OE_VERDICT_TOLERANCE)),
        (Some(_), None) => Some(true),
        (None, Some(_)) => Some(false),
        (None, None) => None,
    }
}

/// The two simulation RMSEs of a candidate in words, for a fallback warning.
pub(crate) fn both_rmses(c: Option<SimulationRmse>) -> String {
    match c {
        Some(SimulationRmse {
            estimated,
            measured: Some(m),
            ..
        }) => format!("{estimated:.6e} from estimated, {m:.6e} from measured initial outputs"),
        Some(c) => format!("{:.6e} from estimated initial outputs", c.estimated),
        None => "diverges".to_string(),
    }
}

/// Which of the least-squares start and the output-error refinement to keep, and the notes that say so
/// (one input or several).
#[derive(Debug, Clone, PartialEq)]
pub struct OeVerdict {
    /// The start's notes, the stabilisation, the refinement and the kept candidate.
    pub notes: Vec<Note>,
    /// Converged or stopped at the iteration cap.
    pub termination: Termination,
    /// `None` when the refinement is kept; else the warning that the start was kept instead.
    pub fallback: Option<Warning>,
}

impl OeVerdict {
    /// Judges both candidates on the estimation simulation RMSE pooled over estimated and measured
    /// initial outputs ([`crate::trust::pooled_rmse`]; `None` for an unstable or diverging model): the
    /// refinement is kept unless the start's pooled RMSE is lower by more than [`OE_VERDICT_TOLERANCE`]
    /// (relative); when neither simulates stably the refinement (stable by construction) is kept and
    /// the warnings say what is wrong.
    ///
    /// Why pooled (audit s18 M-7): the worse of the two RMSEs let the measured initial outputs decide,
    /// and with a pole near 1 their noise drifts through the whole simulation — on a record of the
    /// paper's plant with 0.2 mm noise even the true plant scored worse than the biased LS start (97.87
    /// against 98.10 %), so a refinement at the noise level (RMSE 0.201 from estimated initial outputs
    /// against the start's 0.78) was thrown away. The estimated initial outputs alone would let a slow
    /// pole buy a headline fit with the initial state (issue 22: the dryer OE (5, 6, 3), 0.072 against
    /// 0.49 from measured outputs); pooled, that refinement (0.35) still loses to its start (0.094).
    pub fn judge(
        fit: &oe::OeFit,
        start_notes: &[Note],
        refined: Option<SimulationRmse>,
        start: Option<SimulationRmse>,
    ) -> Self {
        let (refined_rmse, start_rmse) = (refined.map(|r| r.pooled), start.map(|s| s.pooled));
        let mut notes: Vec<Note> = start_notes
            .iter()
            .cloned()
            .map(|n| Note::Start(Box::new(n)))
            .collect();
        if fit.stabilised_start {
            notes.push(Note::StabilisedStart);
        }
        notes.push(Note::Refinement {
            rss_start: fit.rss_start,
            rss: fit.rss,
            iterations: fit.iterations,
            evaluations: fit.evaluations,
            stopped: fit.stop.to_string(),
        });
        // Neither simulates stably: the refinement (stable by construction) is kept, with warnings.
        // A refinement held on the stability boundary (an integrator the search's constraint made)
        // against a start that simulates stably is kept only when it is no worse at all: the 1 %
        // tolerance is for two models of the same kind, not for trading a stable start for an
        // integrator that simulates worse (audit s35c, issue 11: ball and beam (2, 2, 1), rows 0–499,
        // kept an integrator 0.6 % worse than its stable start).
        let on_boundary = matches!(fit.stop, oe::OeStop::StabilityBoundary);
        let refined_better = match (on_boundary, refined_rmse, start_rmse) {
            (true, Some(r), Some(s)) => r <= s,
            _ => refinement_kept(refined, start).unwrap_or(true),
        };
        let termination = fit.stop.termination();
        if refined_better {
            if let (Some(r), true) = (refined_rmse, start_rmse.is_some() || fit.stabilised_start) {
                notes.push(Note::KeptCandidate {
                    kept: "output-error refinement",
                    rmse: r,
                    criterion: crate::fitted::POOLED_CRITERION,
                    others: vec![("least-squares start", start_rmse)],
                });
            }
            return OeVerdict {
                notes,
                termination,
                fallback: None,
            };
        }
        let (kept_rmse, refined_text) = (
            start_rmse.unwrap_or(f64::NAN),
            refined_rmse.map_or_else(|| "diverges".to_string(), |r| format!("{r:.6e}")),
        );
        notes.push(Note::KeptCandidate {
            kept: "least-squares start",
            rmse: kept_rmse,
            criterion: crate::fitted::POOLED_CRITERION,
            others: vec![("output-error refinement", refined_rmse)],
        });
        let why = format!(
            "the refined model simulates the estimation data worse from both initial states together \
             (pooled RMSE {refined_text} against {kept_rmse:.6e} for the start; refinement {}, start {})",
            both_rmses(refined),
            both_rmses(start)
        );
        OeVerdict {
            notes,
            termination,
            fallback: Some(Warning::Fallback {
                used: "the least-squares start instead of the output-error refinement".into(),
                why,
            }),
        }
    }
}

#[cfg(test)]
mod verdict_tests {
    use super::*;

    fn rmse(estimated: f64, measured: f64) -> Option<SimulationRmse> {
        Some(SimulationRmse {
            estimated,
            measured: Some(measured),
            pooled: ((estimated * estimated + measured * measured) / 2.0).sqrt(),
        })
    }

    // A refinement with RMSE 0.05 from estimated and 0.40 from measured initial outputs against a start
    // with 0.30 from both: the worse of the two (0.40 > 0.30) would keep the start; pooled,
    // √((0.0025 + 0.16)/2) = 0.28504 < 0.30, the refinement is kept (OE and Wiener alike).
    #[test]
    fn the_pooled_rmse_not_the_worse_one_decides() {
        assert_eq!(
            refinement_kept(rmse(0.05, 0.40), rmse(0.30, 0.30)),
            Some(true)
        );
        // Reversed roles: the start is better pooled by 5 %, more than the 1 % tolerance.
        assert_eq!(
            refinement_kept(rmse(0.30, 0.30), rmse(0.05, 0.40)),
            Some(false)
        );
    }

    // Within the tolerance the refinement stays: 0.302 ≤ 0.30 · 1.01 = 0.303 (kept), 0.304 not.
    #[test]
    fn a_refinement_within_one_percent_of_its_start_is_kept() {
        assert_eq!(
            refinement_kept(rmse(0.302, 0.302), rmse(0.30, 0.30)),
            Some(true)
        );
        assert_eq!(
            refinement_kept(rmse(0.304, 0.304), rmse(0.30, 0.30)),
            Some(false)
        );
    }

    // A candidate that simulates stably beats one that does not; neither: the caller decides.
    #[test]
    fn a_diverging_candidate_loses() {
        assert_eq!(refinement_kept(None, rmse(1.0, 1.0)), Some(false));
        assert_eq!(refinement_kept(rmse(1.0, 1.0), None), Some(true));
        assert_eq!(refinement_kept(None, None), None);
    }
}
