//! Polynomial NARX identification: structure selection by orthogonal forward regression with the
//! error-reduction ratio (FROLS; Billings, *Nonlinear System Identification*, Wiley 2013, §3.2;
//! SysIdentPy's `FROLS`), an honest stopping rule, and an optional refinement of the selected terms on
//! the free-run simulation error.
//!
//! **FROLS.** With the candidate monomials p_m (columns over the rows k ≥ k0 of the record) and the
//! output y, step s picks, among the candidates not yet chosen, the one whose part orthogonal to the
//! chosen q_1..q_{s−1},
//! w_m = p_m − Σ_r (q_rᵀ p_m / q_rᵀ q_r) q_r,
//! explains most of y: the error-reduction ratio ERR_m = (w_mᵀ y)² / ((w_mᵀ w_m)(yᵀ y)). It becomes
//! q_s with g_s = q_sᵀ y / q_sᵀ q_s; Σ_s ERR_s is the fraction of yᵀy the first terms explain, and
//! the coefficients of the first n terms solve A_n θ = g_n with A the unit upper-triangular matrix of
//! the Gram–Schmidt coefficients (computed here by modified Gram–Schmidt).
//!
//! **Stopping.** FROLS orders the terms; how many to keep is decided without the validation record:
//! - an information criterion on the one-step residuals of the estimation record,
//!   AIC(n) = N ln(σ̂²_n) + 2n or BIC(n) = N ln(σ̂²_n) + n ln N, σ̂²_n = yᵀy (1 − Σ_{s ≤ n} ERR_s)/N
//!   (SysIdentPy's `info_criteria`);
//! - or the free-run simulation error on a **selection part** (the last fraction of the estimation
//!   record): the terms are ordered and fitted on the first part only, each n is simulated over the
//!   selection part from its measured initial outputs, the n of least RMSE wins, and the chosen terms
//!   are then fitted on the whole estimation record.
//!
//! **Refinement** (optional): Levenberg–Marquardt on V(θ) = Σ_k (y(k) − ŷ_sim(k, θ))² over the
//! estimation record, ŷ_sim the free run from the measured initial outputs, with the sensitivities
//! ∂ŷ(k)/∂θ_j = m_j(k) + Σ_l (Σ_i θ_i ∂m_i/∂y(k−l)) ∂ŷ(k−l)/∂θ_j computed alongside the simulation.
//! A trial point whose simulation blows up is rejected like any step that raises V.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use sysid_core::narx::{
    candidate_count, candidate_terms, Lagged, Monomials, NarxModel, Term, MAX_DEGREE,
};
use sysid_core::{DataRange, Dataset, Setting, Stop, SysidError};

use crate::warnings::{Record, Warning};

/// How many of the FROLS-ordered terms to keep.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum StopRule {
    /// Akaike's criterion N ln σ̂² + 2n on the estimation record's one-step residuals.
    Aic,
    /// Schwarz's criterion N ln σ̂² + n ln N (prefers fewer terms than AIC).
    Bic,
    /// Free-run simulation RMSE on the selection part (the last `selection` fraction of the estimation
    /// record; terms ordered and fitted on the rest).
    Sim,
}

impl std::fmt::Display for StopRule {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            StopRule::Aic => "aic",
            StopRule::Bic => "bic",
            StopRule::Sim => "sim",
        })
    }
}

/// Settings of a polynomial NARX identification.
#[derive(Debug, Clone, PartialEq)]
pub struct NarxSettings {
    /// na: output lags y(k−1)..y(k−na).
    pub na: usize,
    /// nb: input lags u(k−nk)..u(k−nk−nb+1).
    pub nb: usize,
    /// nk: input delay in samples.
    pub nk: usize,
    /// D: largest degree of a monomial (1..=5).
    pub degree: usize,
    /// Offer the constant term 1 to the selection (`--offset`).
    pub constant: bool,
    /// At most this many terms are ordered by FROLS.
    pub max_terms: usize,
    /// How many ordered terms to keep.
    pub stop: StopRule,
    /// Fraction of the estimation record (its end) used as the selection part of [`StopRule::Sim`].
    pub selection: f64,
    /// Refine the selected terms' coefficients on the free-run simulation error.
    pub refine: bool,
    /// Iteration cap of the refinement.
    pub max_iterations: usize,
    /// The most memory the identification's matrices may take ([`NarxSettings::memory_need`];
    /// default 4 GiB, [`sysid_core::ls::MAX_ESTIMATION_BYTES`]).
    pub max_memory: sysid_core::ls::MemoryBudget,
    /// The caller's stop check, polled at each FROLS candidate and term and each refinement iteration
    /// ([`Stop`]; default [`Stop::never`]): a stopped identification returns
    /// [`SysidError::Cancelled`]. No part of the settings' value (equal whatever it holds).
    pub cancel: Stop,
}

impl Default for NarxSettings {
    /// na = 2, nb = 2, nk = 1, D = 2, with a constant, up to 30 terms, stopped by the simulation error
    /// on the last third, refined.
    fn default() -> Self {
        NarxSettings {
            na: 2,
            nb: 2,
            nk: 1,
            degree: 2,
            constant: true,
            max_terms: 30,
            stop: StopRule::Sim,
            selection: 1.0 / 3.0,
            refine: true,
            max_iterations: 50,
            max_memory: sysid_core::ls::MemoryBudget::default(),
            cancel: Stop::never(),
        }
    }
}

/// Largest number of candidate monomials a selection accepts (C(na + nb + D, D)); bounds memory.
pub const MAX_CANDIDATES: usize = 2000;

impl NarxSettings {
    /// Refuses settings that cannot be run, naming the setting.
    pub fn check(&self) -> Result<(), SysidError> {
        if self.degree == 0 || self.degree > MAX_DEGREE {
            return Err(SysidError::setting(
                Setting::Other("--degree"),
                self.degree,
                &format!("a degree D in 1..={MAX_DEGREE}"),
            ));
        }
        if self.na + self.nb == 0 {
            return Err(SysidError::setting(
                Setting::Na,
                self.na,
                "na + nb >= 1 (a NARX model needs a lagged variable)",
            ));
        }
        let m = candidate_count(self.na, self.nb, self.degree, self.constant);
        if m > MAX_CANDIDATES {
            return Err(SysidError::setting(
                Setting::Other("--degree"),
                self.degree,
                &format!(
                    "at most {MAX_CANDIDATES} candidate terms; na = {}, nb = {}, D = {} give {m}: lower the lags or the degree",
                    self.na, self.nb, self.degree
                ),
            ));
        }
        if self.max_terms == 0 {
            return Err(SysidError::setting(
                Setting::Other("--max-terms"),
                0,
                "at least 1 term",
            ));
        }
        if !(self.selection > 0.05 && self.selection < 0.95) {
            return Err(SysidError::setting(
                Setting::Other("--selection"),
                self.selection,
                "a fraction of the estimation record in (0.05, 0.95)",
            ));
        }
        Ok(())
    }

    fn k0(&self) -> usize {
        self.na.max((self.nk + self.nb).saturating_sub(1))
    }

    /// The memory an identification of `data` with these settings needs at its peak: its N = len − k0
    /// regression rows, M candidate terms as p and [`numbers_per_row`] numbers each; checked by
    /// [`identify_narx`] before the candidates' columns are built (with infallible allocations).
    pub fn memory_need(&self, data: &Dataset) -> sysid_core::ls::MemoryNeed {
        let m = candidate_terms(self.na, self.nb, self.nk, self.degree, self.constant).len();
        sysid_core::ls::MemoryNeed {
            what: data.name().to_string(),
            rows: data.len().saturating_sub(self.k0()),
            p: m,
            per_row: numbers_per_row(m, self.max_terms),
        }
    }
}

/// One selected term with its coefficient, standard deviation and error-reduction ratio.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TermReport {
    /// The monomial, e.g. `y(k-1)^2*u(k-2)`.
    pub term: String,
    /// θ_i.
    pub coefficient: f64,
    /// Standard deviation of θ_i (σ̂ √[(ΦᵀΦ)⁻¹]_ii with Φ the regressors, or the simulation
    /// sensitivities after refinement); `None` when not determined.
    pub std: Option<f64>,
    /// ERR of the term when FROLS chose it (fraction of yᵀy it explains).
    pub err: f64,
}

/// The stopping rule's value for each number of terms n = 1, 2, ….
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StopCurve {
    /// The rule.
    pub rule: StopRule,
    /// Its value for n = 1..: the criterion, or the selection part's simulation RMSE (`None`: blew up).
    pub values: Vec<Option<f64>>,
    /// Rule `sim`: the selection part's simulation fit % for n = 1.. (empty for the criteria).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub fits: Vec<Option<f64>>,
    /// The chosen n.
    pub chosen: usize,
}

/// The refinement stops when an accepted step lowers V by less than this fraction.
pub const REFINE_TOLERANCE: f64 = 1e-7;

/// The stopping rule `sim` stops evaluating more terms after this many numbers of terms in a row
/// without a selection RMSE better than the best so far by more than [`SIM_TOLERANCE`].
pub const SIM_PATIENCE: usize = 6;

/// The stopping rule `sim` keeps the fewest terms whose selection RMSE is within this fraction of the
/// least one (parsimony: a gain below it is not worth a term).
pub const SIM_TOLERANCE: f64 = 2e-3;

/// What the simulation-error refinement did.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Refinement {
    /// Free-run RMSE of the estimation record before.
    pub rmse_before: f64,
    /// After.
    pub rmse_after: f64,
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
    /// True when the relative decrease of V fell below [`REFINE_TOLERANCE`] or no damped step lowered
    /// it (else the iteration cap stopped it).
    pub converged: bool,
}

/// A fitted polynomial NARX model with what its selection computed.
#[derive(Debug, Clone)]
pub struct NarxFit {
    /// The model.
    pub model: NarxModel,
    /// The selected terms in the order FROLS chose them.
    pub terms: Vec<TermReport>,
    /// Σ ERR of the selected terms (on the record FROLS ran on).
    pub err_sum: f64,
    /// The stopping rule's curve.
    pub stop: StopCurve,
    /// The refinement, when asked for and started.
    pub refinement: Option<Refinement>,
    /// Number of candidate monomials.
    pub candidates: usize,
    /// Warnings in words (a blow-up, a refinement that did not start or converge, a negative fit, a
    /// fit far below the linear baseline, no input term, …).
    pub warnings: Vec<String>,
    /// The first of the warnings that disqualifies the model from being recommended by `order
    /// --classes` ([`crate::order::disqualifies`]; a blow-up of the estimation record's free run).
    pub disqualified: Option<String>,
}

/// The candidate matrix over the rows k ≥ k0 of (u, y): one column per term, by columns.
fn columns(terms: &[Term], u: &[f64], y: &[f64], k0: usize) -> Vec<Vec<f64>> {
    terms
        .iter()
        .map(|t| {
            (k0..y.len())
                .map(|k| {
                    t.factors().iter().fold(1.0, |acc, v| {
                        acc * match *v {
                            Lagged::Y(l) => y[k - l],
                            Lagged::U(l) => u[k - l],
                        }
                    })
                })
                .collect()
        })
        .collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The result of FROLS: the chosen candidate indices in order, their ERR, and the triangular system
/// A θ = g (A[r][s] for r < s, unit diagonal) of the chosen terms.
#[derive(Debug, Clone)]
pub struct Frols {
    /// Indices of the chosen candidates, in the order chosen.
    pub order: Vec<usize>,
    /// ERR of each chosen term.
    pub err: Vec<f64>,
    /// A[r][s]: q_rᵀ p_s / q_rᵀ q_r for r < s.
    a: Vec<Vec<f64>>,
    /// g_s = q_sᵀ y / q_sᵀ q_s.
    g: Vec<f64>,
}

impl Frols {
    /// θ of the first `n` chosen terms (back substitution in A_n θ = g_n).
    pub fn theta(&self, n: usize) -> Vec<f64> {
        let mut th = vec![0.0; n];
        for s in (0..n).rev() {
            let tail: f64 = self.a[s][s + 1..n]
                .iter()
                .zip(&th[s + 1..n])
                .map(|(a, t)| a * t)
                .sum();
            th[s] = self.g[s] - tail;
        }
        th
    }
}

/// Orthogonal forward regression with the error-reduction ratio over the candidate columns `p` (each
/// of the length of `y`), choosing at most `max_terms`. A candidate whose orthogonal part is below
/// 1e-10 of its norm (dependent on the chosen ones) is never chosen. `cancel` is polled at each
/// candidate of each term and at each deflation ([`SysidError::Cancelled`]).
pub fn frols(
    p: &[Vec<f64>],
    y: &[f64],
    max_terms: usize,
    cancel: &Stop,
) -> Result<Frols, SysidError> {
    let yy = dot(y, y);
    let mut w: Vec<Vec<f64>> = p.to_vec();
    let norms: Vec<f64> = p.iter().map(|c| dot(c, c)).collect();
    let mut chosen = vec![false; p.len()];
    let mut out = Frols {
        order: Vec::new(),
        err: Vec::new(),
        a: Vec::new(),
        g: Vec::new(),
    };
    // coef[m][r]: the Gram–Schmidt coefficient of candidate m on q_r.
    let mut coef: Vec<Vec<f64>> = vec![Vec::new(); p.len()];
    let mut qs: Vec<Vec<f64>> = Vec::new();
    while out.order.len() < max_terms.min(p.len()) {
        let mut best: Option<(usize, f64)> = None;
        for m in 0..p.len() {
            cancel.check()?;
            if chosen[m] {
                continue;
            }
            let ww = dot(&w[m], &w[m]);
            // A NaN, a zero or a dependent column (orthogonal part below 1e-10 of its norm) is skipped.
            if ww.is_nan() || ww <= 1e-20 * norms[m] || ww == 0.0 || yy == 0.0 {
                continue;
            }
            let wy = dot(&w[m], y);
            let err = wy * wy / (ww * yy);
            if best.is_none_or(|(_, b)| err > b) {
                best = Some((m, err));
            }
        }
        let Some((m, err)) = best else { break };
        chosen[m] = true;
        let q = w[m].clone();
        let qq = dot(&q, &q);
        out.g.push(dot(&q, y) / qq);
        out.err.push(err);
        out.order.push(m);
        // Deflate the others by q (modified Gram–Schmidt), recording their coefficients.
        for (j, wj) in w.iter_mut().enumerate() {
            cancel.check()?;
            if chosen[j] {
                continue;
            }
            let c = dot(&q, wj) / qq;
            coef[j].push(c);
            wj.iter_mut().zip(&q).for_each(|(v, qv)| *v -= c * qv);
        }
        qs.push(q);
        // Row s of A over the chosen terms: coefficient of the s-th chosen term on every earlier q.
        let s = out.order.len() - 1;
        for (row, &v) in out.a.iter_mut().zip(&coef[m][..s]) {
            row.push(v);
        }
        out.a.push(vec![0.0; s + 1]);
        out.a[s][s] = 1.0;
    }
    // Make every row of A full width (s-th row holds entries 0..n).
    let n = out.order.len();
    for row in &mut out.a {
        row.resize(n, 0.0);
    }
    Ok(out)
}

/// Free-run simulation RMSE and fit % over rows k0.. of (u, y) of `model`; `None` on a blow-up.
fn sim_rmse_fit(model: &NarxModel, u: &[f64], y: &[f64]) -> Option<(f64, Option<f64>)> {
    let s = model.simulate(u, y).ok()?;
    if s.blew_up_at.is_some() {
        return None;
    }
    let k0 = model.k0().min(y.len());
    if y.len() == k0 {
        return None;
    }
    Some((
        sysid_core::metrics::rmse(&y[k0..], &s.y[k0..]),
        sysid_core::metrics::fit_percent(&y[k0..], &s.y[k0..]),
    ))
}

/// The numbers (f64) a NARX identification holds for each of its N regression rows at its peak, for M =
/// `candidates` candidate terms of which FROLS orders at most T = `max_terms`: the candidates' columns
/// P and their deflated copies W (M each), the orthogonal q_s (at most min(T, M)), and about four for
/// the record and the simulations. W and the q_s are freed when FROLS returns; what comes after (the
/// refinement's sensitivities, n ≤ min(T, M) columns, next to P with `--stop sim`; the chosen terms'
/// columns, Φ and the QR's [Φ | y], 3n + 1, once P is freed) is below this.
/// Checked against [`sysid_core::ls::MAX_ESTIMATION_BYTES`] by [`identify_narx`].
pub fn numbers_per_row(candidates: usize, max_terms: usize) -> usize {
    2 * candidates + candidates.min(max_terms) + 4
}

/// Identifies a polynomial NARX model of `data` (its first input) with `settings`.
pub fn identify_narx(data: &Dataset, settings: &NarxSettings) -> Result<NarxFit, SysidError> {
    settings.check()?;
    if data.inputs().len() != 1 {
        return Err(SysidError::Data(
            "polynomial NARX models have one input; choose it with --u-col".into(),
        ));
    }
    // A record whose output never moves determines no dynamics: y(k−1) = const explains it exactly,
    // whatever the input, as the linear classes' rank test refuses it (audit s17 L-i).
    if let Some(first) = data.y().first() {
        if data.y().iter().all(|v| v == first) {
            return Err(SysidError::Data(format!(
                "{}: the output never moves (every sample is {first}): no model can be identified from \
                 it; record an experiment whose commands move the output",
                data.name()
            )));
        }
    }
    // Signals whose squares underflow (audit s35 H-2), refused as every identification refuses them.
    if let Some(e) = crate::estimate::tiny_signal_of(data) {
        return Err(e);
    }
    let (u, y) = (data.u(), data.y());
    let s = settings;
    let k0 = s.k0();
    let cands = candidate_terms(s.na, s.nb, s.nk, s.degree, s.constant);
    let n_rows = y.len().saturating_sub(k0);
    // The candidates' columns are built below with infallible allocations: their size is checked
    // first, against the one budget of every estimation (the linear classes' in `identify`).
    s.memory_need(data).check(s.max_memory)?;
    if n_rows < 2 * cands.len().min(s.max_terms) + 10 {
        return Err(SysidError::Data(format!(
            "{} samples are too few for a NARX model with up to {} terms (k0 = {k0})",
            y.len(),
            cands.len().min(s.max_terms)
        )));
    }
    let model_of = |order: &[usize], theta: Vec<f64>| {
        NarxModel::new(
            data.ts(),
            s.na,
            s.nb,
            s.nk,
            s.degree,
            order.iter().map(|&i| cands[i].clone()).collect(),
            theta,
        )
    };
    let mut warnings = Vec::new();
    // Order the terms (on the fitting part for Sim, on the whole record otherwise) and choose n.
    let (frols_result, mut stop) = match s.stop {
        StopRule::Aic | StopRule::Bic => {
            let p = columns(&cands, u, y, k0);
            let f = frols(&p, &y[k0..], s.max_terms, &s.cancel)?;
            let yy = dot(&y[k0..], &y[k0..]);
            let nn = n_rows as f64;
            let mut err_sum = 0.0;
            let values: Vec<Option<f64>> = f
                .err
                .iter()
                .enumerate()
                .map(|(i, e)| {
                    err_sum += e;
                    // σ̂² is floored at 1e-14 of the output's mean square: below it the residual is
                    // rounding, and a criterion on rounding would keep adding terms to exact data.
                    let var = (yy * (1.0 - err_sum) / nn)
                        .max(1e-14 * yy / nn)
                        .max(f64::MIN_POSITIVE);
                    let pen = match s.stop {
                        StopRule::Aic => 2.0,
                        _ => nn.ln(),
                    };
                    Some(nn * var.ln() + pen * (i + 1) as f64)
                })
                .collect();
            let chosen = argmin(&values).map_or(0, |i| i + 1);
            (
                f,
                StopCurve {
                    rule: s.stop,
                    values,
                    fits: Vec::new(),
                    chosen,
                },
            )
        }
        StopRule::Sim => {
            let n = y.len();
            let split = ((n as f64) * (1.0 - s.selection)).round() as usize;
            let (u_fit, y_fit) = (&u[..split], &y[..split]);
            // The selection part starts k0 samples early: its initial outputs are measured ones.
            let start = split.saturating_sub(k0);
            let (u_sel, y_sel) = (&u[start..], &y[start..]);
            let p = columns(&cands, u_fit, y_fit, k0);
            let f = frols(&p, &y_fit[k0..], s.max_terms, &s.cancel)?;
            // The patience runs out no earlier than the first term with an input (the fallback of an
            // input-free choice needs its value).
            let first_input = f.order.iter().position(|&i| cands[i].has_input());
            let mut best = (f64::INFINITY, 0usize);
            let mut values: Vec<Option<f64>> = Vec::new();
            let mut fits: Vec<Option<f64>> = Vec::new();
            for n in 1..=f.order.len() {
                s.cancel.check()?;
                if best.1 > 0 && n > best.1 + SIM_PATIENCE && first_input.is_none_or(|i| n > i + 1)
                {
                    break;
                }
                let v = model_of(&f.order[..n], f.theta(n)).ok().and_then(|m| {
                    // With refinement the candidate is judged as it will be used: refined (on the
                    // fitting part only), then simulated over the selection part.
                    let m = if s.refine {
                        refine(&m, u_fit, y_fit, s.max_iterations, &s.cancel)
                            .map_or(m, |(r, _, _)| r)
                    } else {
                        m
                    };
                    sim_rmse_fit(&m, u_sel, y_sel)
                });
                let (v, fit) = (v.map(|x| x.0), v.and_then(|x| x.1));
                // Only a gain beyond the parsimony tolerance resets the patience.
                if let Some(x) = v.filter(|x| *x < best.0 * (1.0 - SIM_TOLERANCE)) {
                    best = (x, n);
                }
                values.push(v);
                fits.push(fit);
            }
            let chosen = sim_choice(&values, 0, y);
            (
                f,
                StopCurve {
                    rule: s.stop,
                    values,
                    fits,
                    chosen,
                },
            )
        }
    };
    if let Some(w) = input_fallback(&mut stop, &frols_result.order, &cands, y) {
        warnings.push(w);
    }
    if stop.chosen == 0 {
        return Err(SysidError::Numerical(format!(
            "no number of terms gave a usable model ({}); every simulation of the selection part blew up \
             — lower the degree or the lags",
            s.stop
        )));
    }
    if stop.chosen == frols_result.order.len() && frols_result.order.len() < cands.len() {
        warnings.push(format!(
            "the stopping rule ({}) chose the largest number of terms searched ({}): more terms may fit \
             better; raise --max-terms",
            s.stop, stop.chosen
        ));
    }
    let order = &frols_result.order[..stop.chosen];
    let errs = &frols_result.err[..stop.chosen];
    // Coefficients of the chosen terms on the whole estimation record, with standard deviations.
    let chosen_terms: Vec<Term> = order.iter().map(|&i| cands[i].clone()).collect();
    let p = columns(&chosen_terms, u, y, k0);
    let phi = DMatrix::from_fn(n_rows, p.len(), |r, c| p[c][r]);
    let target = DVector::from_column_slice(&y[k0..]);
    let names: Vec<String> = chosen_terms.iter().map(Term::to_string).collect();
    let sol = sysid_core::ls::solve(&phi, &target, &names)?;
    let sigma2 = sysid_core::ls::noise_variance(sol.rss, n_rows, p.len());
    let mut model = model_of(order, sol.theta.iter().copied().collect())?;
    let mut std: Vec<Option<f64>> = (0..p.len())
        .map(|i| {
            let v = sigma2 * sol.inv_gram[(i, i)];
            (v.is_finite() && v >= 0.0).then(|| v.sqrt())
        })
        .collect();
    let mut refinement = None;
    if s.refine {
        match refine(&model, u, y, s.max_iterations, &s.cancel) {
            Ok((m, r, st)) => {
                if !r.converged {
                    warnings.push(format!(
                        "the simulation-error refinement reached its iteration limit ({}) before it \
                         settled",
                        s.max_iterations
                    ));
                }
                model = m;
                std = st;
                refinement = Some(r);
            }
            Err(SysidError::Cancelled) => return Err(SysidError::Cancelled),
            Err(e) => warnings.push(format!(
                "the simulation-error refinement did not start: {e}; the one-step (least-squares) \
                 coefficients are kept"
            )),
        }
    }
    let est_metrics = narx_metrics(&model, data).ok();
    let mut disqualified = None;
    if let Some(k) = est_metrics.as_ref().and_then(|m| m.blew_up_at) {
        let w = blow_up_warning("estimation", data.name(), k);
        disqualified = Some(w.clone());
        warnings.push(w);
    }
    let mut trust: Vec<Warning> = no_input_warning(model.terms()).into_iter().collect();
    if let Some(m) = &est_metrics {
        trust.extend(narx_trust(
            Record::Estimation,
            &model,
            s.constant,
            data,
            data,
            m,
        ));
    }
    disqualified = disqualified.or_else(|| crate::order::disqualification(&trust));
    warnings.extend(trust.iter().map(ToString::to_string));
    warnings.extend(
        crate::trust::poorly_determined(
            "terms",
            chosen_terms
                .iter()
                .zip(model.theta())
                .zip(&std)
                .map(|((t, c), sd)| (t.to_string(), *c, *sd)),
        )
        .map(|w| w.to_string()),
    );
    let terms = chosen_terms
        .iter()
        .zip(model.theta())
        .zip(&std)
        .zip(errs)
        .map(|(((t, c), sd), e)| TermReport {
            term: t.to_string(),
            coefficient: *c,
            std: *sd,
            err: *e,
        })
        .collect();
    // The range of the data, for the extrapolation warnings of whatever drives the model (audit s17 M-d).
    let model = model.with_data_range(DataRange::of(std::slice::from_ref(data)))?;
    Ok(NarxFit {
        model,
        terms,
        err_sum: errs.iter().sum(),
        stop,
        refinement,
        candidates: cands.len(),
        warnings,
        disqualified,
    })
}

/// The trust warnings of the NARX `model` on the record `data` (its metrics `m`), as `identify
/// --structure arx|hammerstein` gives them ([`crate::trust`]): a negative simulation fit (a blow-up has
/// its own warning, [`blow_up_warning`]), and a simulation far below the plain linear least-squares
/// ARX of the same lags (na, nb, nk), with a constant when `constant`, estimated on `est`
/// ([`crate::trust::baseline_fit`]). A NARX free run starts from the measured initial outputs, so its
/// fit is the guarded fit.
pub fn narx_trust(
    record: Record,
    model: &NarxModel,
    constant: bool,
    est: &Dataset,
    data: &Dataset,
    m: &NarxMetrics,
) -> Vec<Warning> {
    if m.blew_up_at.is_some() {
        return Vec::new();
    }
    let orders = sysid_core::Orders {
        na: model.na(),
        nb: model.nb(),
        nk: model.nk(),
    };
    let baseline =
        crate::trust::baseline_fit(orders, &[], constant, std::slice::from_ref(est), data);
    Warning::if_poor_simulation(record, m.fit_sim_percent)
        .into_iter()
        .chain(crate::trust::below_baseline(
            record,
            m.fit_sim_percent,
            baseline,
        ))
        .collect()
}

/// [`Warning::NoInputTerm`] when none of `terms` has a lagged input.
pub fn no_input_warning(terms: &[Term]) -> Option<Warning> {
    (!terms.iter().any(Term::has_input)).then_some(Warning::NoInputTerm { terms: terms.len() })
}

/// Rule `sim`'s choice among n = from + 1.. terms: the fewest whose selection RMSE is within
/// [`SIM_TOLERANCE`] (plus rounding of the output's range of `y`) of the least one there (parsimony);
/// 0 when none has a value.
fn sim_choice(values: &[Option<f64>], from: usize, y: &[f64]) -> usize {
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let tail = values.get(from..).unwrap_or_default();
    let least = tail.iter().flatten().fold(f64::INFINITY, |a, &b| a.min(b));
    let tol = SIM_TOLERANCE * least + 1e-10 * (hi - lo);
    tail.iter()
        .position(|v| v.is_some_and(|x| x <= least + tol))
        .map_or(0, |i| from + i + 1)
}

/// When the stopping rule chose only terms without an input (the model could not respond to it) and
/// FROLS ordered a term with one: the choice among the numbers of terms that include it, by the same
/// rule (the least criterion, or rule `sim`'s parsimonious least RMSE), with the warning that says so;
/// when none of those has a value, the choice is kept and the warning says why.
fn input_fallback(
    stop: &mut StopCurve,
    order: &[usize],
    cands: &[Term],
    y: &[f64],
) -> Option<String> {
    if stop.chosen == 0 || order[..stop.chosen].iter().any(|&i| cands[i].has_input()) {
        return None;
    }
    let first = order.iter().position(|&i| cands[i].has_input())?;
    let n = match stop.rule {
        StopRule::Sim => sim_choice(&stop.values, first, y),
        StopRule::Aic | StopRule::Bic => stop
            .values
            .get(first..)
            .and_then(argmin)
            .map_or(0, |i| first + i + 1),
    };
    let rule = stop.rule;
    if n == 0 {
        return Some(format!(
            "the stopping rule ({rule}) chose {} term(s) without an input term, and no number of terms \
             that includes FROLS's first input term {} (term {}) gave a usable model ({})",
            stop.chosen,
            cands[order[first]],
            first + 1,
            if rule == StopRule::Sim {
                "every one blew up on the selection part"
            } else {
                "no finite criterion"
            }
        ));
    }
    let w = format!(
        "the stopping rule ({}) chose {} term(s) without an input term (a model that cannot respond \
         to the input); kept instead the {n} terms of the best {} among those that include FROLS's \
         first input term {} (term {})",
        rule,
        stop.chosen,
        if rule == StopRule::Sim {
            "selection RMSE"
        } else {
            "criterion"
        },
        cands[order[first]],
        first + 1
    );
    stop.chosen = n;
    Some(w)
}

/// The warning for a free run that blew up at sample `k` of record `name` (`which`: estimation,
/// validation).
pub fn blow_up_warning(which: &str, name: &str, k: usize) -> String {
    format!(
        "the free-run simulation of the NARX model blew up on the {which} record {name} at sample {k} \
         (output non-finite or beyond {} ranges of the data): its simulation metrics there are not \
         available; the polynomial feedback is unstable for this input — lower the degree or the lags",
        sysid_core::narx::BLOW_UP_SPANS
    )
}

fn argmin(v: &[Option<f64>]) -> Option<usize> {
    v.iter()
        .enumerate()
        .filter_map(|(i, x)| x.filter(|x| x.is_finite()).map(|x| (i, x)))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
}

/// g_l = Σ_i θ_i ∂m_i/∂y(k − l) of a model, compiled: for each term and each distinct output variable
/// y(k − l) in it (the terms in order, their factors in canonical order), θ_i times the power p of
/// y(k − l) in m_i (the power rule) and the slot, in the values of a [`Monomials`] table, of the
/// product of m_i's other factors. The entries are grouped by lag, in their order within a lag, so
/// that each g_l is summed in a register with the additions of a loop over the terms in the same
/// order: the same number, to the bit, as (θ_i p) · Π rest computed anew.
struct OutputDerivatives {
    /// (l, the entries of lag l in `coef` and `rest`).
    lags: Vec<(usize, std::ops::Range<usize>)>,
    coef: Vec<f64>,
    rest: Vec<usize>,
}

impl OutputDerivatives {
    /// The derivatives of `model`'s terms; the products they need are added to `table`.
    fn of(model: &NarxModel, table: &mut Monomials) -> Self {
        // (l, θ_i p, slot of the rest) in the terms' order.
        let mut entries: Vec<(usize, f64, usize)> = Vec::new();
        for (t, th) in model.terms().iter().zip(model.theta()) {
            let f = t.factors();
            for (i, v) in f.iter().enumerate() {
                if let Lagged::Y(l) = *v {
                    if i > 0 && f[i - 1] == *v {
                        continue;
                    }
                    let power = f.iter().filter(|w| *w == v).count();
                    let rest: Vec<usize> = f
                        .iter()
                        .enumerate()
                        .filter(|&(j, _)| j != i)
                        .map(|(_, &w)| model.variable_index(w))
                        .collect();
                    entries.push((l, th * power as f64, table.slot(&rest)));
                }
            }
        }
        // A stable sort: the order within a lag is kept.
        entries.sort_by_key(|e| e.0);
        let mut lags: Vec<(usize, std::ops::Range<usize>)> = Vec::new();
        for (at, e) in entries.iter().enumerate() {
            match lags.last_mut() {
                Some((l, r)) if *l == e.0 => r.end = at + 1,
                _ => lags.push((e.0, at..at + 1)),
            }
        }
        OutputDerivatives {
            lags,
            coef: entries.iter().map(|e| e.1).collect(),
            rest: entries.iter().map(|e| e.2).collect(),
        }
    }

    /// g (length na + 1, g[0] unused) from the values `v` of the table (after its eval).
    #[inline]
    fn fill(&self, v: &[f64], g: &mut [f64]) {
        g.iter_mut().for_each(|x| *x = 0.0);
        for (l, range) in &self.lags {
            let mut sum = 0.0;
            for (c, &s) in self.coef[range.clone()]
                .iter()
                .zip(&self.rest[range.clone()])
            {
                sum += c * v[s];
            }
            g[*l] = sum;
        }
    }
}

/// Rows of J accumulated into JᵀJ (its upper triangle) and Jᵀr: each entry Σ_k over the rows in their
/// order, one product added at a time, as a row-by-row loop adds them, so the sums are the same to the
/// bit. Each row is stored as [J_k | r_k] (Jᵀr is then the last column of [J | r]ᵀ[J | r]), padded with
/// zeros to a multiple of 4; the rows are taken in blocks of [`GRAM_BLOCK`] and the sums of a 4 × 4
/// tile kept in registers over a block: the loop is then bound by the multiplications, not by loading
/// and storing the sums once per row or by the latency of one chain of additions.
struct Gram {
    p: usize,
    stride: usize,
    acc: Vec<f64>,
    block: Vec<f64>,
    filled: usize,
}

/// Rows of J per block of [`Gram`].
const GRAM_BLOCK: usize = 16;

impl Gram {
    fn new(p: usize) -> Self {
        let stride = (p + 1).div_ceil(4) * 4;
        Gram {
            p,
            stride,
            acc: vec![0.0; stride * stride],
            block: vec![0.0; GRAM_BLOCK * stride],
            filled: 0,
        }
    }

    /// Adds the row `row` of J with its residual `r`.
    #[inline]
    fn push(&mut self, row: &[f64], r: f64) {
        let at = self.filled * self.stride;
        self.block[at..at + self.p].copy_from_slice(row);
        self.block[at + self.p] = r;
        self.filled += 1;
        if self.filled == GRAM_BLOCK {
            self.flush();
        }
    }

    fn flush(&mut self) {
        let (n, s) = (self.filled, self.stride);
        let block = &self.block[..n * s];
        for i0 in (0..self.p).step_by(4) {
            for j0 in (i0..s).step_by(4) {
                let mut t = [[0.0; 4]; 4];
                for (a, ta) in t.iter_mut().enumerate() {
                    let at = (i0 + a) * s + j0;
                    ta.copy_from_slice(&self.acc[at..at + 4]);
                }
                for row in block.chunks_exact(s) {
                    let ri = &row[i0..i0 + 4];
                    let rj = &row[j0..j0 + 4];
                    for (ta, &x) in t.iter_mut().zip(ri) {
                        ta[0] += x * rj[0];
                        ta[1] += x * rj[1];
                        ta[2] += x * rj[2];
                        ta[3] += x * rj[3];
                    }
                }
                for (a, ta) in t.iter().enumerate() {
                    let at = (i0 + a) * s + j0;
                    self.acc[at..at + 4].copy_from_slice(ta);
                }
            }
        }
        self.filled = 0;
    }

    /// The scaled normal equations of the rows pushed.
    fn finish(mut self) -> ScaledNormal {
        self.flush();
        let (p, s) = (self.p, self.stride);
        let jtj = DMatrix::from_fn(p, p, |i, j| {
            if j >= i {
                self.acc[i * s + j]
            } else {
                self.acc[j * s + i]
            }
        });
        let jtr: Vec<f64> = (0..p).map(|i| self.acc[i * s + p]).collect();
        ScaledNormal::of(jtj, &jtr)
    }
}

/// A free run with what a Gauss–Newton step needs: the residuals y − ŷ over rows k0.. and the scaled
/// normal equations of its sensitivities J = ∂ŷ/∂θ.
struct Run {
    resid: Vec<f64>,
    normal: ScaledNormal,
}

/// The free run of `model` on (u, y) with the normal equations of its sensitivities ∂ŷ(k)/∂θ over
/// rows k0.., computed along the run by the recursion of the module's doc and folded into [`Gram`]
/// row by row (only the last na rows of J are kept): one pass. `None` on a blow-up, or when a residual
/// or a sensitivity is not finite.
fn run_of(model: &NarxModel, u: &[f64], y: &[f64]) -> Option<Run> {
    let p = model.terms().len();
    let na = model.na();
    let mut table = Monomials::of(model);
    let derivs = OutputDerivatives::of(model, &mut table);
    // The rows k−na..k of J in a ring (row k in slot k mod (na + 1)); the rows before k0 are zero.
    let ring_len = na + 1;
    let mut ring = vec![0.0; ring_len * p];
    let mut gl = vec![0.0; na + 1];
    let mut gram = Gram::new(p);
    let mut resid = Vec::with_capacity(y.len().saturating_sub(model.k0()));
    let mut finite = true;
    let sim = model
        .simulate_each(u, y, &table, |k, vals, yh| {
            if !finite {
                return;
            }
            derivs.fill(vals, &mut gl);
            let slot = k % ring_len;
            let (before, rest) = ring.split_at_mut(slot * p);
            let (now, after) = rest.split_at_mut(p);
            // ∂ŷ(k)/∂θ_j = m_j(k) + Σ_l g_l ∂ŷ(k−l)/∂θ_j.
            table.fill(vals, now);
            for (l, g) in gl.iter().enumerate().skip(1) {
                if *g != 0.0 {
                    let prev_slot = (k + ring_len - l) % ring_len;
                    let prev = if prev_slot < slot {
                        &before[prev_slot * p..(prev_slot + 1) * p]
                    } else {
                        &after[(prev_slot - slot - 1) * p..(prev_slot - slot) * p]
                    };
                    now.iter_mut().zip(prev).for_each(|(r, s)| *r += g * s);
                }
            }
            let r = y[k] - yh;
            if !r.is_finite() || now.iter().any(|v| !v.is_finite()) {
                finite = false;
                return;
            }
            gram.push(now, r);
            resid.push(r);
        })
        .ok()?;
    (sim.blew_up_at.is_none() && finite).then(|| Run {
        resid,
        normal: gram.finish(),
    })
}

/// The normal equations of a Gauss–Newton step in Marquardt's scaling: S = D⁻¹ JᵀJ D⁻¹ (unit
/// diagonal, D = the column norms of J) and b = D⁻¹ Jᵀ r. Forming JᵀJ costs N p²/2 multiply-adds, a
/// quarter of a QR of J, which is what makes the refinement of long records (silverbox, N = 65 000)
/// affordable; the scaling keeps S well conditioned enough for a Cholesky factor of S + λ I.
struct ScaledNormal {
    s: DMatrix<f64>,
    b: DVector<f64>,
    d: Vec<f64>,
}

impl ScaledNormal {
    /// S and b of JᵀJ = `jtj` and Jᵀr = `jtr`.
    fn of(jtj: DMatrix<f64>, jtr: &[f64]) -> Self {
        let p = jtr.len();
        // A column that is zero over the record keeps the scale 1 (its step is then 0).
        let d: Vec<f64> = (0..p)
            .map(|i| {
                let v = jtj[(i, i)].sqrt();
                if v > 0.0 && v.is_finite() {
                    v
                } else {
                    1.0
                }
            })
            .collect();
        let s = DMatrix::from_fn(p, p, |i, j| jtj[(i, j)] / (d[i] * d[j]));
        let b = DVector::from_fn(p, |i, _| jtr[i] / d[i]);
        ScaledNormal { s, b, d }
    }

    /// δ = D⁻¹ (S + λ I)⁻¹ b, or `None` when the damped matrix is not positive definite.
    fn damped_step(&self, lambda: f64) -> Option<DVector<f64>> {
        let mut a = self.s.clone();
        for i in 0..a.nrows() {
            a[(i, i)] += lambda;
        }
        let w = a.cholesky()?.solve(&self.b);
        let delta = DVector::from_fn(w.len(), |i, _| w[i] / self.d[i]);
        delta.iter().all(|v| v.is_finite()).then_some(delta)
    }

    /// diag((JᵀJ)⁻¹) = diag(S⁻¹) / d², or `None` when S is singular.
    fn inverse_diagonal(&self) -> Option<Vec<f64>> {
        let inv = self.s.clone().cholesky()?.inverse();
        Some(
            (0..inv.nrows())
                .map(|i| inv[(i, i)] / (self.d[i] * self.d[i]))
                .collect(),
        )
    }
}

/// Levenberg–Marquardt on the free-run simulation error from `start`: the refined model, what it did,
/// and the standard deviations σ̂ √[(JᵀJ)⁻¹]_ii at the end. Fails when the start's simulation blows up,
/// and with [`SysidError::Cancelled`] when `cancel` (polled at each trial step) was requested.
pub fn refine(
    start: &NarxModel,
    u: &[f64],
    y: &[f64],
    max_iterations: usize,
    cancel: &Stop,
) -> Result<(NarxModel, Refinement, Vec<Option<f64>>), SysidError> {
    let mut run = run_of(start, u, y).ok_or_else(|| {
        SysidError::Numerical(
            "the least-squares model's free-run simulation blows up on the estimation record"
                .into(),
        )
    })?;
    let n = run.resid.len() as f64;
    let mut v = dot(&run.resid, &run.resid);
    let rmse_before = (v / n).sqrt();
    let mut model = start.clone();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    let mut converged = false;
    let p = model.terms().len();
    while iterations < max_iterations {
        iterations += 1;
        let mut improved = false;
        for _ in 0..12 {
            cancel.check()?;
            let Some(delta) = run.normal.damped_step(lambda) else {
                lambda *= 10.0;
                continue;
            };
            let theta: Vec<f64> = model
                .theta()
                .iter()
                .zip(delta.iter())
                .map(|(a, d)| a + d)
                .collect();
            let Ok(trial) = model.with_theta(theta) else {
                lambda *= 10.0;
                continue;
            };
            // The trial's free run with its sensitivities (nearly every step is taken: computing them
            // along the run saves a second simulation).
            let next = run_of(&trial, u, y).map(|r2| (dot(&r2.resid, &r2.resid), r2));
            match next.filter(|(v2, _)| *v2 < v) {
                Some((v2, r2)) => {
                    let rel = (v - v2) / v.max(f64::MIN_POSITIVE);
                    model = trial;
                    run = r2;
                    v = v2;
                    lambda = (lambda / 3.0).max(1e-12);
                    improved = true;
                    if rel < REFINE_TOLERANCE {
                        converged = true;
                    }
                    break;
                }
                _ => lambda *= 10.0,
            }
        }
        if !improved {
            // No step lowers V even heavily damped: a (local) minimum.
            converged = true;
        }
        if converged {
            break;
        }
    }
    let sigma2 = sysid_core::ls::noise_variance(v, run.resid.len(), p);
    let std = match run.normal.inverse_diagonal() {
        Some(d) => d
            .iter()
            .map(|g| {
                let s = sigma2 * g;
                (s.is_finite() && s >= 0.0).then(|| s.sqrt())
            })
            .collect(),
        None => vec![None; p],
    };
    Ok((
        model,
        Refinement {
            rmse_before,
            rmse_after: (v / n).sqrt(),
            iterations,
            converged,
        },
        std,
    ))
}

/// Metrics of a NARX model on one record: free run from the measured initial outputs and one-step
/// prediction, over the rows k ≥ max(K, k0) ([`narx_metrics_scored_from`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NarxMetrics {
    /// The record's name.
    pub data: String,
    /// Rows k ≥ max(K, k0) the metrics are over.
    pub n: usize,
    /// Free-run simulation RMSE (units of y), from the measured initial outputs; `None` after a blow-up.
    pub rmse_sim: Option<f64>,
    /// The same number: a NARX simulation always starts from the measured initial outputs (kept under
    /// this name so that tables of linear and NARX models read alike).
    pub rmse_sim_measured: Option<f64>,
    /// MATLAB `compare` fit % of the simulation.
    pub fit_sim_percent: Option<f64>,
    /// The same number again (measured initial outputs), under the name the linear and block-oriented
    /// models give their measured-start fit: a script comparing classes on it compares one start
    /// (audit s12).
    pub fit_sim_measured_percent: Option<f64>,
    /// One-step-ahead prediction RMSE.
    pub rmse_pred: f64,
    /// Fit % of the one-step prediction.
    pub fit_pred_percent: Option<f64>,
    /// MATLAB's `LossFcn`/`MSE`: mean e² of the one-step prediction errors (`rmse_pred`², units of y²),
    /// as the linear models' [`Metrics::loss_fcn`](sysid_core::metrics::Metrics::loss_fcn).
    pub loss_fcn: Option<f64>,
    /// MATLAB's `fpe(sys)`: LossFcn (N + p)/(N − p), p the number of terms; `None` when N <= p.
    pub fpe_matlab: Option<f64>,
    /// MATLAB's `aic(sys)` (normalised): ln(LossFcn) + 2p/N; `None` when LossFcn = 0.
    pub aic_matlab: Option<f64>,
    /// The sample at which the simulation blew up, if it did.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub blew_up_at: Option<usize>,
}

/// The metrics of `model` on `data` (its first input).
pub fn narx_metrics(model: &NarxModel, data: &Dataset) -> Result<NarxMetrics, SysidError> {
    narx_metrics_scored_from(model, data, 0)
}

/// [`narx_metrics`] over the rows k ≥ max(K, k0) only, K = `score_from`
/// ([`sysid_core::metrics::check_scored`], the rule of the linear models' figures): the same simulation
/// and prediction over the whole record, fewer rows scored. A record no longer than k0 (K = 0) keeps
/// the behaviour of [`narx_metrics`]: figures over no rows, not an error.
pub fn narx_metrics_scored_from(
    model: &NarxModel,
    data: &Dataset,
    score_from: usize,
) -> Result<NarxMetrics, SysidError> {
    sysid_core::metrics::check_sampling(data.name(), data.ts(), model.ts())?;
    let (u, y) = (data.u(), data.y());
    let k0 = if score_from > 0 {
        sysid_core::metrics::check_scored(
            data.name(),
            y.len(),
            model.k0(),
            model.terms().len(),
            score_from,
        )?
    } else {
        sysid_core::metrics::first_scored(model.k0(), 0).min(y.len())
    };
    let pred = model.predict(u, y)?;
    let sim = model.simulate(u, y)?;
    let (rmse_sim, fit_sim) = match sim.blew_up_at {
        Some(_) => (None, None),
        None => (
            Some(sysid_core::metrics::rmse(&y[k0..], &sim.y[k0..])),
            sysid_core::metrics::fit_percent(&y[k0..], &sim.y[k0..]),
        ),
    };
    let rmse_pred = sysid_core::metrics::rmse(&y[k0..], &pred[k0..]);
    if !rmse_pred.is_finite() {
        // As a linear model's (audit s32 L-4: "one-step RMSE inf", exit 0): a numerical failure that
        // names the coefficient to blame, or the data when no coefficient explains it.
        return Err(SysidError::Numerical(match model.overflowing_term(u, y) {
            Some(w) => format!(
                "{}: the one-step prediction's squared errors overflow f64: {w}",
                data.name()
            ),
            None => format!(
                "{}: the squared prediction errors overflow f64 (values too large? rescale the data)",
                data.name()
            ),
        }));
    }
    let n = y.len() - k0;
    let loss_fcn = Some(rmse_pred * rmse_pred).filter(|v| v.is_finite());
    let p = model.terms().len();
    Ok(NarxMetrics {
        data: data.name().to_string(),
        n,
        rmse_sim,
        rmse_sim_measured: rmse_sim,
        fit_sim_percent: fit_sim,
        fit_sim_measured_percent: fit_sim,
        rmse_pred,
        fit_pred_percent: sysid_core::metrics::fit_percent(&y[k0..], &pred[k0..]),
        loss_fcn,
        fpe_matlab: sysid_core::metrics::fpe_of(loss_fcn, n, p),
        aic_matlab: sysid_core::metrics::aic_of(loss_fcn, n, p),
        blew_up_at: sim.blew_up_at,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use sysid_core::data::Signals;

    // The blocked, tiled JᵀJ and Jᵀr are the row-by-row sums (each entry += J_ki J_kj in the rows'
    // order) to the bit, for a p that is not a multiple of 4 and a row count that is not one of the
    // block size.
    #[test]
    fn the_tiled_normal_equations_are_the_row_by_row_sums() {
        let (p, n) = (7, 37);
        let row = |k: usize| -> Vec<f64> {
            (0..p)
                .map(|j| ((k * 31 + j * 17) % 23) as f64 / 7.0 - 1.3)
                .collect()
        };
        let r = |k: usize| ((k * 13) % 11) as f64 / 3.0 - 1.1;
        let mut gram = Gram::new(p);
        let (mut jtj, mut jtr) = (vec![0.0; p * p], vec![0.0; p]);
        for k in 0..n {
            let x = row(k);
            gram.push(&x, r(k));
            for i in 0..p {
                jtr[i] += x[i] * r(k);
                for j in i..p {
                    jtj[i * p + j] += x[i] * x[j];
                }
            }
        }
        let normal = gram.finish();
        for i in 0..p {
            let d = jtj[i * p + i].sqrt();
            assert_eq!(normal.d[i].to_bits(), d.to_bits());
            assert_eq!(normal.b[i].to_bits(), (jtr[i] / d).to_bits());
            for j in i..p {
                let s = jtj[i * p + j] / (d * jtj[j * p + j].sqrt());
                assert_eq!(normal.s[(i, j)].to_bits(), s.to_bits(), "({i}, {j})");
                assert_eq!(normal.s[(j, i)].to_bits(), s.to_bits());
            }
        }
    }

    fn y1() -> Term {
        Term::new(vec![Lagged::Y(1)])
    }
    fn u1() -> Term {
        Term::new(vec![Lagged::U(1)])
    }
    fn y1sq() -> Term {
        Term::new(vec![Lagged::Y(1), Lagged::Y(1)])
    }

    fn curve(rule: StopRule, values: Vec<Option<f64>>, chosen: usize) -> StopCurve {
        StopCurve {
            rule,
            values,
            fits: Vec::new(),
            chosen,
        }
    }

    // FROLS ordered y(k−1), y(k−1)², u(k−1), y(k−1)·… : the criterion's minimum at n = 2 has no input;
    // among n >= 3 (the first input term is the third) the least value is at n = 4 (AIC 5.0 < 6.0).
    #[test]
    fn an_input_free_choice_falls_back_to_the_best_with_an_input() {
        let cands = vec![y1(), y1sq(), u1(), Term::constant()];
        let order = [0, 1, 2, 3];
        let mut stop = curve(
            StopRule::Aic,
            vec![Some(9.0), Some(4.0), Some(6.0), Some(5.0)],
            2,
        );
        let w = input_fallback(&mut stop, &order, &cands, &[0.0, 1.0]).unwrap();
        assert_eq!(stop.chosen, 4);
        assert!(w.contains("u(k-1)") && w.contains("term 3"), "{w}");
        // Rule sim: the fewest within 0.2 % of the least selection RMSE among n >= 3: n = 3
        // (1.001 <= 1.0 · 1.002).
        let mut stop = curve(
            StopRule::Sim,
            vec![Some(2.0), Some(0.5), Some(1.001), Some(1.0)],
            2,
        );
        input_fallback(&mut stop, &order, &cands, &[0.0, 1.0]).unwrap();
        assert_eq!(stop.chosen, 3);
        // A choice with an input term is left alone; so is one when no input term was ordered, and
        // when every n with the input blew up the choice is kept with a warning.
        let mut stop = curve(StopRule::Aic, vec![Some(1.0), Some(2.0), Some(0.5)], 3);
        assert!(input_fallback(&mut stop, &order, &cands, &[0.0]).is_none());
        let mut stop = curve(StopRule::Aic, vec![Some(1.0), Some(2.0)], 1);
        assert!(input_fallback(&mut stop, &[0, 1], &cands, &[0.0]).is_none());
        let mut stop = curve(StopRule::Sim, vec![Some(1.0), Some(2.0), None, None], 1);
        let w = input_fallback(&mut stop, &order, &cands, &[0.0, 1.0]).unwrap();
        assert_eq!(stop.chosen, 1);
        assert!(w.contains("blew up"), "{w}");
    }

    // y(k) = 0.95 y(k−1) + 0.05 u(k−1) with u a ±1 sequence: y(k−1) explains almost all of yᵀy, so with
    // one term allowed FROLS keeps y(k−1) alone — a model without an input, which must be said and
    // disqualify the model.
    #[test]
    fn a_model_without_an_input_term_is_warned_and_disqualified() {
        let n = 600;
        let u: Vec<f64> = (0..n)
            .map(|k| if (k * 7919 / 13) % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let mut y = vec![5.0; n];
        for k in 1..n {
            y[k] = 0.95 * y[k - 1] + 0.05 * u[k - 1];
        }
        let data = Dataset::new(Signals { u, y }, 1.0, "ar").unwrap();
        let s = NarxSettings {
            na: 1,
            nb: 1,
            nk: 1,
            degree: 1,
            constant: false,
            max_terms: 1,
            stop: StopRule::Aic,
            refine: false,
            ..NarxSettings::default()
        };
        let fit = identify_narx(&data, &s).unwrap();
        assert_eq!(fit.terms.len(), 1);
        assert_eq!(fit.terms[0].term, "y(k-1)");
        let said = Warning::NoInputTerm { terms: 1 }.to_string();
        assert!(fit.warnings.contains(&said), "{:?}", fit.warnings);
        assert!(fit.disqualified.is_some());
        // With two terms allowed the input term comes in and nothing is said about it.
        let fit = identify_narx(&data, &NarxSettings { max_terms: 2, ..s }).unwrap();
        assert!(
            fit.terms.iter().any(|t| t.term == "u(k-1)"),
            "{:?}",
            fit.terms
        );
        assert!(!fit.warnings.contains(&said));
    }

    // Data from the ARX y(k) = 0.5 y(k−1) + u(k−1); the NARX y(k) = −u(k−1) (wrong sign) simulates
    // ŷ(k) = −u(k−1). Its fit, computed here by the definition 100 (1 − ‖y − ŷ‖/‖y − ȳ‖), is negative,
    // and the least-squares ARX (1, 1, 1) reproduces the data (fit 100 %): both warnings.
    #[test]
    fn a_narx_model_with_a_negative_fit_far_below_the_linear_baseline_is_warned() {
        let n = 300;
        let u: Vec<f64> = (0..n).map(|k| ((k * 37 % 11) as f64 - 5.0) / 5.0).collect();
        let mut y = vec![0.0; n];
        for k in 1..n {
            y[k] = 0.5 * y[k - 1] + u[k - 1];
        }
        let data = Dataset::new(
            Signals {
                u: u.clone(),
                y: y.clone(),
            },
            1.0,
            "arx",
        )
        .unwrap();
        let model = NarxModel::new(1.0, 1, 1, 1, 1, vec![u1()], vec![-1.0]).unwrap();
        let m = narx_metrics(&model, &data).unwrap();
        let (num, den): (f64, f64) = {
            let tail = &y[1..];
            let mean = tail.iter().sum::<f64>() / tail.len() as f64;
            (
                (1..n)
                    .map(|k| (y[k] + u[k - 1]).powi(2))
                    .sum::<f64>()
                    .sqrt(),
                tail.iter().map(|v| (v - mean).powi(2)).sum::<f64>().sqrt(),
            )
        };
        let fit = 100.0 * (1.0 - num / den);
        assert!(fit < 0.0);
        assert!((m.fit_sim_percent.unwrap() - fit).abs() < 1e-9);
        let w = narx_trust(Record::Validation, &model, false, &data, &data, &m);
        assert!(
            w.contains(&Warning::PoorSimulation {
                record: Record::Validation,
                fit_percent: Some(m.fit_sim_percent.unwrap())
            }),
            "{w:?}"
        );
        assert!(
            w.iter().any(|w| matches!(
                w,
                Warning::Trust(crate::warnings::Concern::BelowBaseline { baseline, .. })
                    if *baseline > 99.999
            )),
            "{w:?}"
        );
        // The true structure itself draws neither.
        let truth = NarxModel::new(1.0, 1, 1, 1, 1, vec![y1(), u1()], vec![0.5, 1.0]).unwrap();
        let mt = narx_metrics(&truth, &data).unwrap();
        assert!(narx_trust(Record::Validation, &truth, false, &data, &data, &mt).is_empty());
    }
}
