//! The identification: unfitted settings, one type per method ([`LeastSquares`],
//! [`RecursiveLeastSquares`], [`OutputError`], [`InstrumentalVariables`]) → [`Estimator::fit`] on a
//! [`Problem`] → a [`Fitted`] model with its diagnostics. [`identify`] is the one entry point, for one
//! input, several inputs and several records alike: it checks the settings and the data, runs an
//! estimator and applies the safeguards common to every method.
//!
//! The estimators themselves are in [`crate::methods`] (batch and recursive least squares of the paper,
//! eqs. 9–12, by key-term separation, docs/paper.md eq. 8; output-error refinement, [`crate::oe`];
//! recursive instrumental variables, [`crate::iv`]); they see a [`Regression`] and the nonlinearity
//! [`crate::blocks`], never a deadzone.

use crate::blocks::{NonlinearityKind, AUTO_BREAKPOINTS, MAX_AUTO_BREAKPOINTS};
use crate::fitted::{check_finite, Fitted, Method, Param, Termination};
use crate::methods;
pub use crate::methods::{
    InstrumentalVariables, LeastSquares, OutputError, Passes, RecursiveLeastSquares, PASSES_SETTLED,
};
pub use crate::problem::{Estimator, Problem, Records};
use crate::regression::{Channel, Regression};
use crate::warnings::{Record, Warning, LINEAR_START_USED};
use sysid_core::data::SINGLE_INPUT;
use sysid_core::ls::{MemoryBudget, MemoryNeed};
use sysid_core::metrics::Metrics;
use sysid_core::{
    Dataset, InputChannel, Model, ModelKind, Orders, ParamName, Stop, Structure, SysidError,
};

/// One input's part of a structure with several inputs: orders and static nonlinearity.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InputSpec {
    /// nb: number of B coefficients (b1 = 1 included for a nonlinear input).
    pub nb: usize,
    /// nk: delay in samples.
    pub nk: usize,
    /// The input's static nonlinearity.
    pub nonlinearity: NonlinearityKind,
}

/// One method's settings, for callers that choose the method at run time (the command line).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EstimatorSettings {
    /// Least squares.
    Ls(LeastSquares),
    /// Recursive least squares.
    Rls(RecursiveLeastSquares),
    /// Output error.
    Oe(OutputError),
    /// Instrumental variables.
    Iv(InstrumentalVariables),
}

impl EstimatorSettings {
    fn inner(&self) -> &dyn Estimator {
        match self {
            EstimatorSettings::Ls(e) => e,
            EstimatorSettings::Rls(e) => e,
            EstimatorSettings::Oe(e) => e,
            EstimatorSettings::Iv(e) => e,
        }
    }
}

impl Estimator for EstimatorSettings {
    fn method(&self) -> Method {
        self.inner().method()
    }
    fn check(&self) -> Result<(), SysidError> {
        self.inner().check()
    }
    fn fit(&self, problem: &Problem) -> Result<Fitted, SysidError> {
        self.inner().fit(problem)
    }
}

/// A whole identification: the structure, the estimator and how to treat a one-sided input.
#[derive(Debug, Clone, PartialEq)]
pub struct Identification {
    /// The model structure: na and the offset; for every input not in `inputs`, nb, nk and (ARX:
    /// linear, Hammerstein: deadzone) its static nonlinearity.
    pub structure: Structure,
    /// One entry per input of the data, overriding `structure`'s nb, nk and nonlinearity (empty: every
    /// input takes them from `structure`).
    pub inputs: Vec<InputSpec>,
    /// The estimator and its settings.
    pub estimator: EstimatorSettings,
    /// Hammerstein on an input that never goes below (above) zero: drop the unexcited deadzone branch
    /// (fix m_l = b_l = 0) instead of refusing the data. Default `false` (refuse, as the paper's method
    /// cannot estimate it); the command line turns it on.
    pub drop_unexcited_branch: bool,
    /// Replace a Hammerstein estimate that diverged (non-finite or unstable simulation) or simulates far
    /// worse than the linear ARX start by that linear model, written as a Hammerstein model with
    /// b_l = b_r = 0 (a warning says so). Default `false`: the method's own estimate is returned and a
    /// warning says that the linear start is better.
    pub fallback: bool,
    /// The output nonlinearity y = g(v) (saturation, piecewise-linear, polynomial; `None`: y = v),
    /// fitted by output error from the method's model ([`crate::wiener`]).
    pub output: Option<NonlinearityKind>,
    /// The most memory the estimation's matrices may take ([`Identification::check_memory`]; default
    /// 4 GiB, [`sysid_core::ls::MAX_ESTIMATION_BYTES`]).
    pub max_memory: MemoryBudget,
    /// The caller's stop check, polled at each iteration, pass and stage ([`Stop`]; default
    /// [`Stop::never`]): a stopped identification returns [`SysidError::Cancelled`]. No part of the
    /// settings' value (equal whatever it holds; absent from reports and model files).
    pub cancel: Stop,
}

impl Default for Identification {
    /// The paper's identification: Hammerstein (3, 1, 1) by one pass of RLS with ρ = 1.
    fn default() -> Self {
        Identification {
            structure: Structure {
                kind: ModelKind::Hammerstein,
                orders: Orders::PAPER,
                offset: false,
            },
            inputs: Vec::new(),
            estimator: EstimatorSettings::Rls(RecursiveLeastSquares::default()),
            drop_unexcited_branch: false,
            fallback: false,
            output: None,
            max_memory: MemoryBudget::default(),
            cancel: Stop::never(),
        }
    }
}

impl Identification {
    /// Checks the structure and the estimator's settings, without data (several inputs named by their
    /// position: "input 2").
    pub fn check(&self) -> Result<(), SysidError> {
        let n = self.inputs.len().max(1);
        let names: Vec<String> = (1..=n).map(|i| i.to_string()).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        self.check_for(&names)
    }

    /// [`Identification::check`] for inputs named `names` (the data's columns), so that an error about
    /// one input names its column (audit s14 L-o: "for input u2" named the second of u1,u3 by position).
    pub fn check_for(&self, names: &[&str]) -> Result<(), SysidError> {
        self.regression(names)?;
        if let Some(kind) = self.output {
            crate::wiener::check_output_kind(kind)?;
        }
        self.estimator.check()
    }

    /// The static nonlinearity `structure` gives every input not in `inputs`.
    pub fn default_nonlinearity(&self) -> NonlinearityKind {
        match self.structure.kind {
            ModelKind::Arx => NonlinearityKind::Linear,
            ModelKind::Hammerstein => NonlinearityKind::Deadzone,
        }
    }

    /// The regression of this structure on data with the inputs `names` (one input: named "u" in the
    /// model, as every single-input model is).
    pub fn regression(&self, names: &[&str]) -> Result<Regression, SysidError> {
        if !self.inputs.is_empty() && self.inputs.len() != names.len() {
            return Err(SysidError::Data(format!(
                "the structure has {} inputs but the data have {} ({})",
                self.inputs.len(),
                names.len(),
                names.join(", ")
            )));
        }
        let o = self.structure.orders;
        let channels = names
            .iter()
            .enumerate()
            .map(|(m, name)| {
                let spec = self.inputs.get(m).copied().unwrap_or(InputSpec {
                    nb: o.nb,
                    nk: o.nk,
                    nonlinearity: self.default_nonlinearity(),
                });
                Channel {
                    name: if names.len() == 1 {
                        SINGLE_INPUT.to_string()
                    } else {
                        name.to_string()
                    },
                    nb: spec.nb,
                    nk: spec.nk,
                    kind: spec.nonlinearity,
                }
            })
            .collect();
        Regression::new(o.na, self.structure.offset, channels)
    }

    /// The problem of this identification on `records` (their inputs named by the first record).
    pub fn problem<'a>(&self, records: &'a [Dataset]) -> Result<Problem<'a>, SysidError> {
        let names: Vec<&str> = records
            .first()
            .map(|r| r.inputs().iter().map(|i| i.name()).collect())
            .unwrap_or_default();
        if names.is_empty() {
            return Err(SysidError::Data(
                "identification needs at least one record".into(),
            ));
        }
        Ok(Problem::new(
            records,
            self.regression(&names)?,
            self.drop_unexcited_branch,
        )?
        .with_cancel(self.cancel.clone()))
    }

    /// Numbers (f64) per regression row this identification holds at its peak, for `p` parameters:
    /// Φ (N × p) and the QR's [Φ | y] (N × (p + 1)) for least squares without key terms, RLS (its rank
    /// test and closed-form passes) and the linear start of the safeguards; one more Φ for the
    /// key-term iteration (the previous iterate's, kept to spot a repeat) and for IV (whose start it
    /// is); the sensitivities and the start's matrices for output error (and an output
    /// nonlinearity); plus about four numbers per sample for the record, its inputs and the
    /// simulations. Measured against `/usr/bin/time -v` on 5 M samples within 10 %
    /// (docs/reliability.md, "Resource bounds").
    pub fn numbers_per_row(&self, p: usize, key_terms: bool) -> usize {
        let ls = if key_terms { 3 * p + 4 } else { 2 * p + 4 };
        let method = match self.estimator {
            EstimatorSettings::Ls(_) | EstimatorSettings::Iv(_) => ls,
            EstimatorSettings::Rls(_) => 2 * p + 4,
            EstimatorSettings::Oe(_) => 5 * p + 4,
        };
        if self.output.is_some() {
            method.max(5 * p + 4)
        } else {
            method
        }
    }

    /// Refuses, before any N × p matrix is allocated, an identification of `records` whose matrices
    /// would need more than [`Identification::max_memory`] ([`Identification::numbers_per_row`]
    /// numbers for each of the N regression rows of the structure's p parameters): the one bound of
    /// every estimation's memory (the command line and the Python package alike; `order` checks its
    /// largest structure with it before the search).
    pub fn check_memory(&self, records: &[Dataset]) -> Result<(), SysidError> {
        self.check_memory_at_once(records, 1)
    }

    /// [`Identification::check_memory`] for `at_once` fits of this structure held in memory
    /// together (`order`'s structures fitted at once, one per worker thread): the numbers per row
    /// times `at_once`, and the count named in the refusal when it is more than one
    /// ([`sysid_core::ls::MemoryNeed::at_once`]).
    pub fn check_memory_at_once(
        &self,
        records: &[Dataset],
        at_once: usize,
    ) -> Result<(), SysidError> {
        match self.memory_need(records)? {
            Some(need) => need.at_once(at_once).check(self.max_memory),
            None => Ok(()),
        }
    }

    /// The memory an identification of `records` needs at its peak: the N regression rows of the
    /// structure's p parameters, [`Identification::numbers_per_row`] numbers each (`None` without a
    /// record).
    pub fn memory_need(&self, records: &[Dataset]) -> Result<Option<MemoryNeed>, SysidError> {
        let Some(first) = records.first() else {
            return Ok(None);
        };
        let names: Vec<&str> = first.inputs().iter().map(|i| i.name()).collect();
        let reg = self.regression(&names)?;
        let p = reg.len();
        Ok(Some(MemoryNeed {
            what: records
                .iter()
                .map(Dataset::name)
                .collect::<Vec<_>>()
                .join(" + "),
            rows: reg.rows(records),
            p,
            per_row: self.numbers_per_row(p, reg.nonlinear()),
        }))
    }

    /// Builder: one input specification per input of the data.
    pub fn with_inputs(mut self, inputs: Vec<InputSpec>) -> Self {
        self.inputs = inputs;
        self
    }

    /// True when a piecewise-linear block has `--breakpoints auto` (K to be chosen).
    pub fn auto_breakpoints(&self) -> bool {
        let auto = |k: &NonlinearityKind| {
            *k == NonlinearityKind::PiecewiseLinear {
                breakpoints: AUTO_BREAKPOINTS,
            }
        };
        self.inputs.iter().any(|i| auto(&i.nonlinearity)) || self.output.as_ref().is_some_and(auto)
    }

    /// The same with K breakpoints in every piecewise-linear block (inputs and output).
    pub fn with_breakpoints(&self, k: usize) -> Identification {
        let mut s = self.clone();
        for i in &mut s.inputs {
            i.nonlinearity = i.nonlinearity.with_breakpoints(k);
        }
        s.output = s.output.map(|o| o.with_breakpoints(k));
        s
    }

    /// Builder: the output nonlinearity y = g(v).
    pub fn with_output_nonlinearity(mut self, output: Option<NonlinearityKind>) -> Self {
        self.output = output;
        self
    }

    /// Builder: the model structure.
    pub fn with_kind(mut self, kind: ModelKind) -> Self {
        self.structure.kind = kind;
        self
    }
    /// Builder: orders.
    pub fn with_orders(mut self, na: usize, nb: usize, nk: usize) -> Self {
        self.structure.orders = Orders { na, nb, nk };
        self
    }
    /// Builder: estimate the offset c.
    pub fn with_offset(mut self, offset: bool) -> Self {
        self.structure.offset = offset;
        self
    }
    /// Builder: the estimator.
    pub fn with_estimator(mut self, estimator: EstimatorSettings) -> Self {
        self.estimator = estimator;
        self
    }
    /// Builder: RLS passes over the data; no effect on the other methods.
    pub fn with_passes(mut self, passes: Passes) -> Self {
        if let EstimatorSettings::Rls(r) = &mut self.estimator {
            r.passes = passes;
        }
        self
    }

    /// Builder: switch to `method`, keeping the settings methods share (ρ and P(0) of the recursive
    /// methods, the least-squares start and its iteration cap) and defaults for the rest.
    pub fn with_method(self, method: Method) -> Self {
        let rec = RecursiveLeastSquares::default();
        let (forgetting, p0, start) = match self.estimator {
            EstimatorSettings::Ls(l) => (rec.forgetting, rec.p0, l),
            EstimatorSettings::Rls(r) => (r.forgetting, r.p0, LeastSquares::default()),
            EstimatorSettings::Oe(o) => (rec.forgetting, rec.p0, o.start),
            EstimatorSettings::Iv(i) => (i.forgetting, i.p0, i.start),
        };
        self.with_estimator(match method {
            Method::Ls => EstimatorSettings::Ls(start),
            Method::Rls => EstimatorSettings::Rls(RecursiveLeastSquares {
                forgetting,
                p0,
                ..rec
            }),
            Method::Oe => EstimatorSettings::Oe(OutputError {
                start,
                max_iterations: start.max_iterations,
                ..OutputError::default()
            }),
            Method::Iv => EstimatorSettings::Iv(InstrumentalVariables {
                start,
                forgetting,
                p0,
                ..InstrumentalVariables::default()
            }),
        })
    }
}

/// Identifies a model from one record or several (`records`: a [`Dataset`], or a slice of them for
/// merged experiments, where no regression row spans two records), with one input or several: checks
/// the settings and the data, fits, and applies the safeguards common to every method (no non-finite
/// estimate is returned as a result).
///
/// ```
/// use sysid::data::Signals;
/// use sysid::{identify, Dataset, Identification, Method, ModelKind};
/// // y(k) = 0.5 y(k-1) + 2 u(k-1), noise-free: LS recovers a1 = -0.5, b1 = 2.
/// let u: Vec<f64> = (0..50).map(|k| ((k * 7919) % 13) as f64 - 6.0).collect();
/// let mut y = vec![0.0; 50];
/// for k in 1..50 { y[k] = 0.5 * y[k - 1] + 2.0 * u[k - 1]; }
/// let data = Dataset::new(Signals { u, y }, 0.01, "doc").unwrap();
/// let s = Identification::default().with_kind(ModelKind::Arx).with_orders(1, 1, 1).with_method(Method::Ls);
/// let fit = identify(&data, &s).unwrap();
/// assert!((fit.model.a()[0] + 0.5).abs() < 1e-10 && (fit.model.b()[0] - 2.0).abs() < 1e-10);
/// ```
pub fn identify<R: Records + ?Sized>(
    records: &R,
    settings: &Identification,
) -> Result<Fitted, SysidError> {
    match records.records().first() {
        Some(r) => {
            let names: Vec<&str> = r.inputs().iter().map(|i| i.name()).collect();
            settings.check_for(&names)?;
        }
        None => settings.check()?,
    }
    if settings.auto_breakpoints() {
        return identify_breakpoints(records, settings);
    }
    settings.check_memory(records.records())?;
    let problem = settings.problem(records.records())?;
    // The records' range: the constant-input check here, the model's data range at the end.
    let range = crate::DataRange::of(records.records());
    if let (Some(r), Some(first)) = (&range, records.records().first()) {
        let names: Vec<&str> = first.inputs().iter().map(|i| i.name()).collect();
        if let Some(e) =
            constant_input(r, &names, first.name()).or_else(|| tiny_signal(r, &names, first.name()))
        {
            return Err(e);
        }
    }
    // A numerical failure names the record it happened on (once).
    let named = |e: SysidError| e.naming(problem.name());
    let level = range.as_ref().and_then(level_hint);
    let mut fit = settings
        .estimator
        .fit(&problem)
        .map_err(|e| with_level_hint(named(e), level.as_deref()))?;
    if let Some(kind) = settings.output {
        let max_iterations = match settings.estimator {
            EstimatorSettings::Oe(st) => st.max_iterations,
            _ => OutputError::default().max_iterations,
        };
        fit = crate::wiener::refine(&problem, kind, fit, max_iterations).map_err(named)?;
    }
    let mut notes: Vec<crate::fitted::Note> = problem
        .notes()
        .into_iter()
        .map(crate::fitted::Note::Branches)
        .collect();
    notes.append(&mut fit.notes);
    fit.notes = notes;
    problem
        .regression()
        .mark_fixed(problem.starts(), &mut fit.params);
    check_finite(problem.name(), &fit.params)?;
    // The data the model was estimated on (a caller that detrended first puts back its own range).
    let fit = safeguard(&problem, settings, fit)
        .map_err(named)?
        .with_data_range(range)?
        .with_fixed_parameters()?;
    // A stop requested while a step swallowed a failure (a restarted search, a fallback) still
    // leaves no result.
    settings.cancel.check()?;
    Ok(fit)
}

/// The refusal of an input that holds one value over every sample of the records whose range is
/// `range` (inputs named `names`, the first record `record`): audit s32 M-1: with nb = 1 and no offset
/// its regressor is a column of one value, which least squares fits — b then only absorbs the output's
/// level, and the "gain" it implies was printed with exit 0; with an offset or nb ≥ 2 the rank test
/// refused it, as docs/reliability.md promises for every structure. The one check of the in-memory
/// identification and of the streamed one (whose pass widens the same [`crate::DataRange`]). `None`
/// when every input changes somewhere.
pub fn constant_input(
    range: &crate::DataRange,
    names: &[&str],
    record: &str,
) -> Option<SysidError> {
    range.u.iter().zip(names).find_map(|(&[lo, hi], name)| {
        (lo == hi).then(|| {
            SysidError::Data(format!(
                "{record}: the input {name} is {} at every sample: a constant input is not \
                 persistently exciting — it cannot show its effect on the output, and its b \
                 coefficients would only absorb the output's level (for a level, --offset); record \
                 the plant's response to an input that changes",
                sysid_core::format::Shortest(lo)
            ))
        })
    })
}

/// The words added to a refusal of linearly dependent regressors when the output of the records whose
/// range is `range` sits on a level at least 1e8 times its motion (its [min, max] of one sign): f64
/// keeps about 16 digits, so the motion keeps fewer than 8 of them and the lagged outputs lose their
/// independence (audit s35 L-6: y + 1e12 was called "not persistently exciting … or the output never
/// moves"). `None` otherwise.
pub fn level_hint(range: &crate::DataRange) -> Option<String> {
    let [lo, hi] = range.y;
    let (level, motion) = (lo.abs().min(hi.abs()), hi - lo);
    (lo.signum() == hi.signum() && motion > 0.0 && level > 1e8 * motion).then(|| {
        format!(
            "; here the output y moves over {motion:.3e} on a level of {level:.3e}: f64 keeps about 16 \
             digits, so its motion keeps fewer than 8 of them; remove the level first (--detrend mean, \
             or subtract it from the column)"
        )
    })
}

/// `e` with [`level_hint`]'s words `hint` added when it is a refusal of linearly dependent regressors.
fn with_level_hint(e: SysidError, hint: Option<&str>) -> SysidError {
    match (e, hint) {
        (SysidError::Data(m), Some(h)) if m.contains("linearly dependent") => {
            SysidError::Data(m + h)
        }
        (e, _) => e,
    }
}

/// The smallest largest-magnitude a signal may have: at this scale its squares (1e-280) and those of
/// residuals down to 1e-14 of it (about f64's rounding of the signal itself, 2.2e-16 relative) stay
/// above f64's smallest normal number (2.2e-308). Below it the
/// sums of squares every estimator, standard deviation and fit figure rests on lose digits or vanish
/// (audit s35 H-2: y ~ 1e-168 made RLS return a1 = a2 = 0 with RMSE 0, loss 0, every fit n/a and no
/// warning; at 1e-158 OE's estimate was off in the third digit, silently). Estimates scale with the
/// signals, so rescaling loses nothing.
pub const SMALLEST_SIGNAL: f64 = 1e-140;

/// The refusal of a signal (an input named in `names`, or the output) whose largest magnitude over the
/// records whose range is `range` is above 0 and below [`SMALLEST_SIGNAL`], with the factor that
/// rescales it to order 1. The one check of the in-memory identification and of the streamed one, next
/// to [`constant_input`]. `None` when every signal is large enough (or 0: the constant checks say
/// that).
pub fn tiny_signal(range: &crate::DataRange, names: &[&str], record: &str) -> Option<SysidError> {
    let largest = |[lo, hi]: [f64; 2]| lo.abs().max(hi.abs());
    let signals = range
        .u
        .iter()
        .zip(names)
        .map(|(r, name)| (largest(*r), format!("input {name}")))
        .chain(std::iter::once((largest(range.y), "output y".to_string())));
    signals
        .filter(|(m, _)| *m > 0.0 && *m < SMALLEST_SIGNAL)
        .map(|(m, what)| {
            let factor = -m.log10().floor();
            SysidError::Numerical(format!(
                "{record}: the {what} is at most {m:.3e} in magnitude: at this scale f64 loses the sums \
                 of squares every estimator, standard deviation and fit figure needs (their terms fall \
                 below 1e-280, near f64's smallest normal number 2.2e-308), so the results would be \
                 wrong or empty; rescale it (multiply it by 1e{factor:.0}: the estimates scale with it)"
            ))
        })
        .next()
}

/// [`tiny_signal`] of one record (the delay search, NARX).
pub fn tiny_signal_of(data: &Dataset) -> Option<SysidError> {
    let range = crate::DataRange::of(std::slice::from_ref(data))?;
    let names: Vec<&str> = data.inputs().iter().map(|i| i.name()).collect();
    tiny_signal(&range, &names, data.name())
}

/// `--breakpoints auto`: the identification with K = 1..=[`MAX_AUTO_BREAKPOINTS`] breakpoints in every
/// piecewise-linear block, the one with the smallest AIC on the estimation data kept (a note lists
/// them all).
fn identify_breakpoints<R: Records + ?Sized>(
    records: &R,
    settings: &Identification,
) -> Result<Fitted, SysidError> {
    let mut best: Option<(f64, usize, Fitted)> = None;
    let mut candidates = Vec::with_capacity(MAX_AUTO_BREAKPOINTS);
    let mut first_error = None;
    for k in 1..=MAX_AUTO_BREAKPOINTS {
        let s = settings.with_breakpoints(k);
        let aic = match identify(records, &s) {
            Ok(fit) => {
                let aic = s
                    .problem(records.records())
                    .ok()
                    .and_then(|p| p.metrics(&fit.model))
                    .and_then(|m| m.aic)
                    .filter(|a| a.is_finite());
                if let Some(a) = aic {
                    if best.as_ref().is_none_or(|b| a < b.0) {
                        best = Some((a, k, fit));
                    }
                }
                aic
            }
            Err(SysidError::Cancelled) => return Err(SysidError::Cancelled),
            Err(e) => {
                first_error.get_or_insert(e);
                None
            }
        };
        candidates.push((k, aic));
    }
    let Some((_, k, mut fit)) = best else {
        return Err(first_error.unwrap_or_else(|| {
            SysidError::Numerical(format!(
                "--breakpoints auto: no K from 1 to {MAX_AUTO_BREAKPOINTS} gave a model with a finite AIC"
            ))
        }));
    };
    fit.notes
        .push(crate::fitted::Note::BreakpointsChosen { k, candidates });
    Ok(fit)
}

/// Percentage points of estimation simulation fit by which a Hammerstein estimate may trail the linear
/// ARX start before the linear model replaces it.
pub const FALLBACK_FIT_MARGIN: f64 = 10.0;

/// The safeguards common to every method: an estimate with a static nonlinearity that diverged or
/// simulates far worse than the linear start is replaced by it (when `settings.fallback`), and every
/// reason not to trust the result becomes a [`Warning`] (the checks of each input's nonlinearity
/// against its own input name the input when there are several).
pub fn safeguard(
    p: &Problem,
    settings: &Identification,
    mut fit: Fitted,
) -> Result<Fitted, SysidError> {
    let mut est = p.metrics(&fit.model);
    let fit_sim = est.as_ref().and_then(|m| m.fit_sim_percent);
    let mut fell_back = false;
    let several = p.regression().channels().len() > 1;
    // The plain linear least-squares ARX of the same orders on the same data: the guard's start and
    // every model's baseline (not computed for the baseline itself, nor when no start could change
    // the result: `start_can_matter`).
    let nonlinear = p.regression().nonlinear();
    let start = ((nonlinear || fit.method != Method::Ls)
        && start_can_matter(
            nonlinear,
            est.as_ref(),
            fit.model.poles_inside_unit_circle(),
        ))
    .then(|| linear_start(p))
    .flatten();
    let baseline = start
        .as_ref()
        .filter(|(l, _)| l.model.poles_inside_unit_circle())
        .map(|(_, m)| crate::trust::guarded_fit(m));
    if nonlinear {
        if let Some((linear, linear_metrics)) = start {
            let linear_fit = linear_metrics.fit_sim_percent.unwrap_or(f64::NAN);
            if let Some(why) = hammerstein_guard(
                fit.method,
                fit_sim,
                fit.model.poles_inside_unit_circle(),
                linear.model.poles_inside_unit_circle(),
                linear_fit,
            ) {
                if settings.fallback {
                    let mut warnings = std::mem::take(&mut fit.warnings);
                    let used = if several {
                        format!("{LINEAR_START_USED} on each nonlinear input")
                    } else {
                        LINEAR_START_USED.into()
                    };
                    warnings.push(Warning::Fallback { used, why });
                    fit = Fitted {
                        warnings,
                        notes: fit.notes,
                        method: fit.method,
                        iterations: fit.iterations,
                        termination: fit.termination,
                        ..linear
                    };
                    est = Some(linear_metrics);
                    fell_back = true;
                } else {
                    fit.warnings.push(Warning::LinearStartBetter { why });
                }
            }
        }
    }
    if !fit.converged() {
        fit.warnings.push(Warning::NotConverged {
            how: termination_words(&fit.termination, fit.method),
        });
    }
    fit.warnings.extend(Warning::if_not_settling(&fit.model));
    match &est {
        Some(m) => {
            fit.warnings
                .extend(crate::trust::metric_warnings(Record::Estimation, m));
            // The Hammerstein guard has already said it (against the same baseline).
            let said = fit
                .warnings
                .iter()
                .any(|w| matches!(w, Warning::LinearStartBetter { .. }));
            if !fell_back && !said {
                fit.warnings.extend(crate::trust::below_baseline(
                    Record::Estimation,
                    crate::trust::guarded_fit(m),
                    baseline.flatten(),
                ));
            }
        }
        None => fit
            .warnings
            .extend(Warning::if_poor_simulation(Record::Estimation, None)),
    }
    // The fallback's nonlinearities are fixed by construction, not estimated: nothing to check.
    if !fell_back {
        for (m, ((ch, start), fitted)) in p
            .regression()
            .channels()
            .iter()
            .zip(p.starts())
            .zip(fit.model.inputs().to_vec())
            .enumerate()
        {
            let block = ch.kind.block();
            let input = several.then(|| ch.name.clone());
            let std: Vec<Option<f64>> = block
                .physical_names()
                .iter()
                .map(|n| std_of(&fit.params, *n, input.as_deref()))
                .collect();
            let (w, no_std) =
                block.warnings(fitted.nonlinearity(), &p.input_samples(m), start, &std);
            for q in fit.params.iter_mut() {
                if no_std.contains(&q.name) && q.input == input {
                    q.std = None;
                }
            }
            fit.warnings.extend(w.into_iter().map(|w| match &input {
                Some(input) => Warning::ForInput {
                    input: input.clone(),
                    warning: Box::new(w),
                },
                None => w,
            }));
        }
    }
    std_warnings(&mut fit);
    // The report needs the same metrics: computed once, here.
    if let Some(m) = est {
        fit.keep_metrics(p.records(), m);
    }
    Ok(fit)
}

/// The doubts a fit's standard deviations raise, added to its warnings: zeros withheld
/// ([`zero_std`]), missing ones nobody explained ([`unexplained_missing_std`]), and estimated parameters
/// within two standard deviations of zero ([`crate::trust::poorly_determined`]). For every fit, in
/// memory or read in passes (`stream::identify_checked`).
pub(crate) fn std_warnings(fit: &mut Fitted) {
    let zero = zero_std(fit);
    fit.warnings.extend(zero);
    fit.warnings.extend(unexplained_missing_std(fit));
    fit.warnings.extend(crate::trust::poorly_determined(
        "parameters",
        fit.params
            .iter()
            .filter(|q| q.fixed.is_none())
            .map(|q| (q.label(), q.value, q.std)),
    ));
}

/// A standard deviation of exactly 0 from residuals that are not zero claims a certainty no data give:
/// the covariance σ̂² (ΦᵀΦ)⁻¹ underflowed (an input or output many orders of magnitude from the others:
/// one sample of 1e308 made b ≈ 1e-309 "± 0", audit s10) or is degenerate. Such standard deviations are
/// withheld, with the reason in a warning.
///
/// With windup protection (`--windup trace|directional`) P is not the inverse information matrix
/// (its recursion is altered to keep it from shrinking or growing), so σ̂² P of exactly 0 is no
/// certainty either, whatever the residuals (audit s20 H-1): withheld as well.
fn zero_std(fit: &mut Fitted) -> Option<Warning> {
    let windup = fit.notes.iter().any(|n| {
        matches!(n, crate::fitted::Note::RlsForm { windup, .. } if *windup != crate::windup::Windup::None)
    });
    let residuals = !(fit.noise_variance.is_nan() || fit.noise_variance <= 0.0);
    if !(residuals || windup) {
        return None;
    }
    let zero = sysid_core::param::withhold_zero_stds(
        fit.params.iter_mut().map(|q| (q.label(), &mut q.std)),
    );
    if zero.is_empty() {
        return None;
    }
    let why = if residuals {
        "although the residuals are not zero: the covariance underflowed or is degenerate (data many \
         orders of magnitude apart: rescale the signals)"
    } else {
        "from the windup-protected P (residuals exactly 0): windup protection keeps P from being the \
         inverse information matrix, so a zero there is no certainty"
    };
    crate::trust::std_warning(Some(format!(
        "the standard deviations of {} of {} parameters ({}) came out exactly 0 {why}, so they are not \
         reported",
        zero.len(),
        fit.params.len(),
        zero.join(", ")
    )))
}

/// A [`Concern::NoStandardDeviations`](crate::warnings::Concern) naming the estimated parameters
/// that have no standard deviation while no warning says why (b1 = 1 of a keyed input is fixed, not
/// estimated); `None` when every one is explained or a warning already speaks of them (LS, RLS and IV:
/// the output-error search gives its own reason).
fn unexplained_missing_std(fit: &Fitted) -> Option<Warning> {
    // The output-error search (and the Wiener refinement, which ends in one) says why itself, and fixes
    // parameters of its own (the output nonlinearity's unit gain).
    if fit.method == Method::Oe {
        return None;
    }
    let said = fit.warnings.iter().any(|w| {
        matches!(
            w,
            Warning::Trust(crate::warnings::Concern::NoStandardDeviations { .. })
                | Warning::Fallback { .. }
        )
    });
    if said {
        return None;
    }
    let missing: Vec<String> = fit
        .params
        .iter()
        .filter(|q| q.std.is_none() && q.fixed.is_none())
        .map(|q| q.label())
        .filter(|l| !fit.warnings.iter().any(|w| w.explains_missing_std(l)))
        .collect();
    if missing.is_empty() {
        return None;
    }
    if fit.noise_variance.is_nan() {
        // N ≤ p: σ̂² undetermined (sysid_core::ls::noise_variance), every standard deviation with it.
        return crate::trust::std_warning(Some(sysid_core::ls::NO_RESIDUAL_DOF.to_string()));
    }
    crate::trust::std_warning(Some(format!(
        "{} of {} parameters have none ({}): the covariance gives them no positive finite variance (a \
         singular or ill-conditioned information matrix: parameters the data do not separate)",
        missing.len(),
        fit.params.len(),
        missing.join(", ")
    )))
}

/// Why an estimate with a static nonlinearity by `method` should give way to the linear ARX start:
/// its estimation simulation diverges (`fit_sim` = `None`), it is unstable while the start is not, or
/// its simulation fit trails the start's `linear_fit` by more than [`FALLBACK_FIT_MARGIN`] points;
/// `None` when none of these holds.
fn hammerstein_guard(
    method: Method,
    fit_sim: Option<f64>,
    stable: bool,
    linear_stable: bool,
    linear_fit: f64,
) -> Option<String> {
    if fit_sim.is_none() {
        Some(format!(
            "the {method} estimate's simulation diverges on the estimation data"
        ))
    } else if !stable && linear_stable {
        Some(format!(
            "the {method} estimate is unstable and the linear start is not"
        ))
    } else {
        fit_sim
            .filter(|f| crate::trust::trails(Some(*f), linear_fit, FALLBACK_FIT_MARGIN))
            .map(|f| {
                format!(
                    "the {method} estimate simulates the estimation data far worse than the linear start \
                     (fit {f:.2} % against {linear_fit:.2} %)"
                )
            })
    }
}

/// Whether the linear start (and the baseline it gives) could change what [`safeguard`] returns for
/// an estimate with estimation metrics `est` (`None`: they could not be computed), stability `stable`
/// and a static nonlinearity (`nonlinear`, the case where [`hammerstein_guard`] runs). When `false`,
/// the start need not be computed: the result and every warning are the same without it.
///
/// The argument: every simulation fit is at most 100 % (fit = 100 (1 − ‖y − ŷ‖/‖y − ȳ‖) with a
/// norm ratio ≥ 0; `metrics_from_sums` keeps only finite fits), so the start's fit f_l and its guarded
/// fit g_l are ≤ 100, and, rounding being monotone, f_l − [`FALLBACK_FIT_MARGIN`] ≤
/// 100 − [`FALLBACK_FIT_MARGIN`] (likewise for [`BASELINE_MARGIN`](crate::trust::BASELINE_MARGIN)).
/// - [`hammerstein_guard`] fires when the estimate's fit is `None`, when it is unstable (and the start
///   is not), or when its fit f < f_l − [`FALLBACK_FIT_MARGIN`]. A stable estimate with
///   f ≥ 100 − [`FALLBACK_FIT_MARGIN`] can therefore never trail any start.
/// - [`below_baseline`](crate::trust::below_baseline) fires only when the estimate's guarded fit g is
///   known and g < g_l − [`BASELINE_MARGIN`](crate::trust::BASELINE_MARGIN); g ≥ 100 −
///   [`BASELINE_MARGIN`](crate::trust::BASELINE_MARGIN) can never trail, and without g there is no
///   check.
///
/// Comparisons are written so that a NaN fit counts as "can matter" (the start is then computed).
fn start_can_matter(nonlinear: bool, est: Option<&Metrics>, stable: bool) -> bool {
    let safe = |fit: Option<f64>, margin: f64| fit.is_some_and(|f| f >= 100.0 - margin);
    let guard =
        nonlinear && !(stable && safe(est.and_then(|m| m.fit_sim_percent), FALLBACK_FIT_MARGIN));
    let guarded = est.and_then(crate::trust::guarded_fit);
    let baseline = guarded.is_some() && !safe(guarded, crate::trust::BASELINE_MARGIN);
    guard || baseline
}

/// The standard deviation of parameter `name` of `input` in `params`, if it is there and has one.
fn std_of(params: &[Param], name: ParamName, input: Option<&str>) -> Option<f64> {
    params
        .iter()
        .find(|q| q.name == name && q.input.as_deref() == input)
        .and_then(|q| q.std)
}

/// How an estimator stopped, in words, for the not-converged warning.
fn termination_words(t: &Termination, method: Method) -> String {
    match (t, method) {
        (Termination::LimitCycle, _) => "the key-term iteration entered a limit cycle".into(),
        (Termination::IterationLimit, Method::Oe) => {
            "the output-error search reached its iteration limit (raise it with --max-iterations; \
             max_iterations= in Python)"
                .into()
        }
        (Termination::IterationLimit, _) => {
            "the iteration limit was reached (raise it with --max-iterations; max_iterations= in Python)"
                .into()
        }
        (Termination::NotSettled, Method::Rls) => {
            "the recursive estimate was still moving at the end of the data (more passes may \
             settle it, or, for a plant that changes, a forgetting factor below 1; with forgetting \
             the estimate follows the latest data and moves by design)"
                .into()
        }
        (Termination::NotSettled, _) => "the estimate had not settled".into(),
        (Termination::NotStationary, _) => {
            "the output-error search stopped on a tolerance while its Gauss-Newton model still predicts \
             a decrease of more than 1 % of the cost, and the restarted searches were still lowering it \
             when they ran out of rounds or iterations (raise --max-iterations; max_iterations= in \
             Python) or the breakpoints still cross (a jump of the criterion)"
                .into()
        }
        (Termination::Converged, _) => "converged".into(),
    }
}

/// The linear ARX least-squares model of the same orders and offset, written with each nonlinear
/// input's linear equivalent (a deadzone with b_l = b_r = 0, m_l = m_r = b1, and B/b1), with its
/// estimation metrics (pooled over several records); `None` when it cannot be estimated, a nonlinear input's b1 is 0, or its
/// simulation diverges. Standard deviations where the ARX regression gives them (a, linear inputs' B,
/// c; the slopes from b1).
fn linear_start(p: &Problem) -> Option<(Fitted, Metrics)> {
    let lp = p.linear().ok()?;
    let arx = methods::arx_ls(&lp).ok()?;
    if !p.regression().nonlinear() {
        let m = p.metrics(&arx.model)?;
        m.fit_sim_percent?;
        return Some((arx, m));
    }
    let m = &arx.model;
    let reg = p.regression();
    let several = reg.channels().len() > 1;
    let mut channels = Vec::with_capacity(m.inputs().len());
    // (value, std) of each entry of the physical layout: blocks first, then a, B, c.
    let (mut blocks, mut tail) = (Vec::new(), Vec::new());
    for (ch, mi) in reg.channels().iter().zip(m.inputs()) {
        let input = several.then(|| ch.name.clone());
        let arx_std = |n: ParamName| std_of(&arx.params, n, input.as_deref());
        let block = ch.kind.block();
        if block.key_names().is_empty() {
            channels.push(mi.clone());
            continue;
        }
        let b1 = *mi.b().first()?;
        if b1 == 0.0 || !b1.is_finite() {
            return None;
        }
        let (f, stds) = block.linear_equivalent(b1, arx_std(ParamName::B(1)));
        blocks.extend(block.physical(&f).into_iter().zip(stds));
        let b: Vec<f64> = mi.b().iter().map(|v| v / b1).collect();
        channels.push(InputChannel::new(ch.name.clone(), ch.nk, b, f).ok()?);
    }
    let model = Model::new(m.ts(), m.a().to_vec(), channels, m.offset()).ok()?;
    for (i, a) in model.a().iter().enumerate() {
        tail.push((*a, std_of(&arx.params, ParamName::A(i + 1), None)));
    }
    for (ch, mi) in reg.channels().iter().zip(model.inputs()) {
        let input = several.then_some(ch.name.as_str());
        let keyed = !ch.kind.block().key_names().is_empty();
        for (j, v) in mi.b().iter().enumerate().skip(usize::from(keyed)) {
            let std = (!keyed)
                .then(|| std_of(&arx.params, ParamName::B(j + 1), input))
                .flatten();
            tail.push((*v, std));
        }
    }
    if let Some(c) = model.offset() {
        tail.push((c, std_of(&arx.params, ParamName::C, None)));
    }
    let metrics = p.metrics(&model)?;
    metrics.fit_sim_percent?;
    let n_blocks = blocks.len();
    let params = reg.params_from(|i| {
        if i < n_blocks {
            blocks[i]
        } else {
            tail[i - n_blocks]
        }
    });
    Some((
        Fitted {
            params,
            ..Fitted::new(model, Vec::new(), Method::Ls, arx.noise_variance)
        },
        metrics,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trust::{below_baseline, guarded_fit, BASELINE_MARGIN};

    /// Hand-built estimation metrics: simulation fits from estimated (`fit`) and measured (`measured`)
    /// initial outputs; the rest is irrelevant to the guards.
    fn metrics(fit: Option<f64>, measured: Option<f64>) -> Metrics {
        Metrics {
            fit_sim_percent: fit,
            fit_pred_percent: Some(99.0),
            rmse_sim: fit.map(|_| 1.0),
            fit_sim_measured_percent: measured,
            rmse_sim_measured: measured.map(|_| 1.0),
            rmse_pred: 0.1,
            loss: Some(0.005),
            loss_sim: fit.map(|_| 0.5),
            fpe: Some(0.005),
            aic: Some(-5.0),
            loss_fcn: Some(0.01),
            fpe_matlab: Some(0.01),
            aic_matlab: Some(-5.0),
            n: 100,
            p: 4,
            note: None,
        }
    }

    // The margins are 10 points (guard) and 20 (baseline) and no fit exceeds 100 %: the start is
    // skipped exactly from 90 % (stable Hammerstein estimate) and 80 % (guarded fit) up.
    #[test]
    fn the_linear_start_is_skipped_only_where_no_start_can_beat_the_estimate() {
        assert_eq!((FALLBACK_FIT_MARGIN, BASELINE_MARGIN), (10.0, 20.0));
        let below = |x: f64| x.next_down();
        let m = |f: f64, g: f64| metrics(Some(f), Some(g));
        // Hammerstein, stable: fit 90 % (both initial states) cannot trail a start of ≤ 100 %.
        assert!(!start_can_matter(true, Some(&m(90.0, 90.0)), true));
        assert!(!start_can_matter(true, Some(&m(100.0, 100.0)), true));
        // Just below 90 %, a start of 100 % would be more than 10 points better.
        assert!(start_can_matter(true, Some(&m(below(90.0), 99.0)), true));
        // Unstable: the start decides (is it stable?), whatever the fit.
        assert!(start_can_matter(true, Some(&m(99.0, 99.0)), false));
        // Diverging simulation (no fit) or no metrics at all: the guard fires on the start.
        assert!(start_can_matter(true, Some(&metrics(None, None)), true));
        assert!(start_can_matter(true, None, true));
        // NaN is never "safe".
        assert!(start_can_matter(true, Some(&m(f64::NAN, 99.0)), true));
        assert!(start_can_matter(false, Some(&m(f64::NAN, f64::NAN)), true));
        // The baseline: the guarded fit (the worse of both) from 80 % up cannot trail by > 20 points.
        assert!(!start_can_matter(false, Some(&m(99.0, 80.0)), true));
        assert!(start_can_matter(false, Some(&m(99.0, below(80.0))), true));
        assert!(start_can_matter(false, Some(&m(below(80.0), 99.0)), true));
        // A Hammerstein estimate above 90 % from the estimated initial outputs but below 80 % from the
        // measured ones may still be far below the baseline.
        assert!(start_can_matter(true, Some(&m(95.0, 70.0)), true));
        // Linear models: stability and a missing fit do not involve the start (no guard), and without a
        // guarded fit there is no baseline check.
        assert!(!start_can_matter(false, Some(&m(85.0, 85.0)), false));
        assert!(!start_can_matter(
            false,
            Some(&metrics(Some(10.0), None)),
            true
        ));
        assert!(!start_can_matter(false, None, false));
    }

    // The guards themselves, run against every start on a grid of fits up to 100 % (stable or not):
    // whenever `start_can_matter` says no, neither the Hammerstein guard nor the baseline check fires,
    // and the grid has cases where the start does matter and a guard fires (the test can fail).
    #[test]
    fn no_start_changes_the_result_where_the_start_is_skipped() {
        let fits = [
            None,
            Some(f64::NAN),
            Some(-1e3),
            Some(0.0),
            Some(50.0),
            Some(79.9),
            Some(80.0_f64.next_down()),
            Some(80.0),
            Some(85.0),
            Some(90.0_f64.next_down()),
            Some(90.0),
            Some(95.0),
            Some(100.0_f64.next_down()),
            Some(100.0),
        ];
        let (mut skipped, mut fired) = (0, 0);
        for nonlinear in [false, true] {
            for stable in [false, true] {
                for &f in &fits {
                    for &g in &fits {
                        let est = metrics(f, g);
                        let can = start_can_matter(nonlinear, Some(&est), stable);
                        for &lf in fits.iter().flatten().filter(|v| !v.is_nan()) {
                            for &lg in fits.iter().flatten().filter(|v| !v.is_nan()) {
                                for linear_stable in [false, true] {
                                    let guard = nonlinear
                                        && hammerstein_guard(
                                            Method::Rls,
                                            f,
                                            stable,
                                            linear_stable,
                                            lf,
                                        )
                                        .is_some();
                                    let start = metrics(Some(lf), Some(lg));
                                    let baseline = below_baseline(
                                        Record::Estimation,
                                        guarded_fit(&est),
                                        linear_stable.then(|| guarded_fit(&start)).flatten(),
                                    )
                                    .is_some();
                                    if !can {
                                        skipped += 1;
                                        assert!(
                                            !guard && !baseline,
                                            "fits {f:?}/{g:?} stable {stable}, start {lf}/{lg} \
                                             stable {linear_stable}"
                                        );
                                    } else if guard || baseline {
                                        fired += 1;
                                    }
                                }
                            }
                        }
                    }
                }
            }
        }
        assert!(skipped > 0 && fired > 0, "{skipped} {fired}");
    }
}

#[cfg(test)]
mod zero_std_tests {
    use super::*;
    use crate::fitted::Note;
    use crate::rls_ud::RlsForm;
    use crate::windup::Windup;
    use sysid_core::param::ParamName;

    fn fit(noise_variance: f64, windup: Windup) -> Fitted {
        let params = (1..=3)
            .map(|i| Param {
                name: ParamName::A(i),
                input: None,
                value: -0.1,
                std: Some(0.0),
                fixed: None,
            })
            .collect();
        let mut f = Fitted::new(Model::paper(), params, Method::Rls, noise_variance);
        f.notes.push(Note::RlsForm {
            form: RlsForm::Standard,
            windup,
        });
        f
    }

    // σ̂² P with P altered by windup protection is no covariance: a 0 from it is withheld (audit s20
    // H-1), whatever the residuals; without windup protection and with residuals exactly 0 it stays.
    #[test]
    fn a_zero_std_from_a_windup_protected_p_is_withheld_with_a_warning() {
        for windup in [Windup::Trace, Windup::Directional] {
            let mut f = fit(0.0, windup);
            let w = zero_std(&mut f).expect("a warning");
            assert!(f.params.iter().all(|q| q.std.is_none()));
            assert!(w.to_string().contains("windup-protected P"), "{w}");
        }
        let mut f = fit(0.0, Windup::None);
        assert!(zero_std(&mut f).is_none());
        assert!(f.params.iter().all(|q| q.std == Some(0.0)));
    }
}
