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

use crate::blocks::{BlockStart, NonlinearityKind};
use crate::fitted::{Fitted, Method, Param, Termination, LINEAR_START_USED};
use crate::methods;
use crate::regression::{Channel, Regression};
use crate::rls;
use crate::rls_ud::RlsForm;
use crate::warnings::{Record, Warning};
use crate::windup::Windup;
use sysid_core::data::SINGLE_INPUT;
use sysid_core::{
    Dataset, InputChannel, Model, ModelKind, Orders, ParamName, Setting, Structure, SysidError,
};

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

/// Settings of the output-error refinement, started from least squares.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutputError {
    /// The least-squares start.
    pub start: LeastSquares,
    /// Patience: the search stops after this many residual evaluations per free parameter (default
    /// 100, shared with the start's key-term iteration cap).
    pub max_iterations: usize,
}

impl Default for OutputError {
    fn default() -> Self {
        OutputError {
            start: LeastSquares::default(),
            max_iterations: 100,
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

/// One record or several (merged experiments, MATLAB `merge`): what [`identify`] accepts.
pub trait Records {
    /// The records.
    fn records(&self) -> &[Dataset];
}

impl Records for Dataset {
    fn records(&self) -> &[Dataset] {
        std::slice::from_ref(self)
    }
}

impl Records for [Dataset] {
    fn records(&self) -> &[Dataset] {
        self
    }
}

impl Records for Vec<Dataset> {
    fn records(&self) -> &[Dataset] {
        self
    }
}

/// What an estimator is fitted to: the records, the regression of the structure and, per input, what
/// the data determine of its static nonlinearity. Made by [`Problem::new`], which checks that the data
/// can support the structure.
#[derive(Debug, Clone)]
pub struct Problem<'a> {
    records: &'a [Dataset],
    regression: Regression,
    starts: Vec<BlockStart>,
    name: String,
}

impl<'a> Problem<'a> {
    /// Checks the structure of `settings` against `records` (same inputs and Ts in every record, enough
    /// rows) and finds what each input determines of its nonlinearity ([`crate::blocks::Block::start`]).
    pub fn new(records: &'a [Dataset], settings: &Identification) -> Result<Self, SysidError> {
        let Some(first) = records.first() else {
            return Err(SysidError::Data(
                "identification needs at least one record".into(),
            ));
        };
        let names: Vec<&str> = first.inputs().iter().map(|i| i.name()).collect();
        for r in records {
            if (r.ts() - first.ts()).abs() > 1e-3 * first.ts() {
                return Err(SysidError::Data(format!(
                    "{} is sampled at Ts = {} s but {} at Ts = {} s; merged records need the same Ts",
                    r.name(),
                    r.ts(),
                    first.name(),
                    first.ts()
                )));
            }
            if r.inputs()
                .iter()
                .map(|i| i.name())
                .ne(names.iter().copied())
            {
                return Err(SysidError::Data(format!(
                    "{} and {} have different inputs; merged records must have the same inputs, in the same order",
                    first.name(),
                    r.name()
                )));
            }
        }
        let regression = settings.regression(&names)?;
        let name = records
            .iter()
            .map(Dataset::name)
            .collect::<Vec<_>>()
            .join(" + ");
        let p = regression.len();
        let k0 = regression.k0();
        let rows = regression.rows(records);
        if records.len() == 1 {
            let n = first.len();
            if n <= k0 || n - k0 < p {
                let s = settings.structure;
                let list = |f: fn(&Channel) -> usize| {
                    regression
                        .channels()
                        .iter()
                        .map(|c| f(c).to_string())
                        .collect::<Vec<_>>()
                        .join(",")
                };
                return Err(SysidError::Data(format!(
                    "{}: {n} samples leave {} regression rows for {p} parameters (na = {}, nb = {}, nk = {}); \
                     more data or lower orders are needed",
                    first.name(),
                    n.saturating_sub(k0),
                    s.orders.na,
                    list(|c| c.nb),
                    list(|c| c.nk),
                )));
            }
        } else if rows <= p {
            return Err(SysidError::Data(format!(
                "the merged records give {rows} regression rows for {p} parameters; more data or lower orders"
            )));
        }
        let several = regression.channels().len() > 1;
        let mut starts = Vec::with_capacity(names.len());
        for (m, ch) in regression.channels().iter().enumerate() {
            let u: Vec<f64> = records
                .iter()
                .flat_map(|r| r.inputs()[m].u().iter().copied())
                .collect();
            let who = if several {
                format!("{} (input {})", name, ch.name)
            } else {
                name.clone()
            };
            starts.push(ch.kind.block().start(
                &u,
                regression.offset(),
                settings.drop_unexcited_branch,
                &who,
            )?);
        }
        Ok(Problem {
            records,
            regression,
            starts,
            name,
        })
    }

    /// The records.
    pub fn records(&self) -> &'a [Dataset] {
        self.records
    }
    /// The regression of the structure.
    pub fn regression(&self) -> &Regression {
        &self.regression
    }
    /// What the data determine of each input's nonlinearity.
    pub fn starts(&self) -> &[BlockStart] {
        &self.starts
    }
    /// The records' names, for messages.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Ts in s.
    pub fn ts(&self) -> f64 {
        self.records[0].ts()
    }
    /// The same problem with every input linear (the ARX structure of the same orders).
    pub(crate) fn linear(&self) -> Result<Problem<'a>, SysidError> {
        let regression = self.regression.linear()?;
        let starts = regression
            .channels()
            .iter()
            .map(|c| c.kind.block().start(&[], false, true, &self.name))
            .collect::<Result<_, _>>()?;
        Ok(Problem {
            records: self.records,
            regression,
            starts,
            name: self.name.clone(),
        })
    }
    /// Input m of every record, one after the other.
    fn input_samples(&self, m: usize) -> Vec<f64> {
        self.records
            .iter()
            .flat_map(|r| r.inputs()[m].u().iter().copied())
            .collect()
    }
    /// The remarks of the blocks' starts (a dropped branch...), naming the input when there are several.
    fn notes(&self) -> Vec<String> {
        let several = self.starts.len() > 1;
        self.regression
            .channels()
            .iter()
            .zip(&self.starts)
            .flat_map(|(c, s)| {
                s.notes.iter().map(move |n| {
                    if several {
                        format!("input {}: {n}", c.name)
                    } else {
                        n.clone()
                    }
                })
            })
            .collect()
    }

    /// Fit % of the free-run simulation (initial outputs estimated, as MATLAB `compare`) on the
    /// estimation records (pooled over several: every record's rows k ≥ k0 with one mean); `None` when
    /// the simulation diverges or the output is constant.
    pub(crate) fn simulation_fit(&self, model: &Model) -> Option<f64> {
        sysid_core::metrics::pooled_metrics(model, self.records)
            .ok()
            .and_then(|m| m.fit_sim_percent)
    }
}

/// An estimation method: checks its settings and fits a [`Problem`].
pub trait Estimator {
    /// Which method this is (reported in the fitted result).
    fn method(&self) -> Method;
    /// Checks the settings (each error names the [`Setting`] at fault).
    fn check(&self) -> Result<(), SysidError>;
    /// Fits the problem. Called by [`identify`], which checks the settings first and applies the common
    /// safeguards after.
    fn fit(&self, problem: &Problem) -> Result<Fitted, SysidError>;
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
        }
    }
}

impl Identification {
    /// Checks the structure and the estimator's settings, without data.
    pub fn check(&self) -> Result<(), SysidError> {
        let n = self.inputs.len().max(1);
        let names: Vec<String> = (1..=n).map(|i| format!("u{i}")).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        self.regression(&names)?;
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

    /// Builder: one input specification per input of the data.
    pub fn with_inputs(mut self, inputs: Vec<InputSpec>) -> Self {
        self.inputs = inputs;
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
    settings.check()?;
    let problem = Problem::new(records.records(), settings)?;
    let mut fit = settings.estimator.fit(&problem)?;
    let mut notes: Vec<crate::fitted::Note> = problem
        .notes()
        .into_iter()
        .map(crate::fitted::Note::Branches)
        .collect();
    notes.append(&mut fit.notes);
    fit.notes = notes;
    check_finite(problem.name(), &fit.params)?;
    safeguard(&problem, settings, fit)
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
    let mut fit_sim = p.simulation_fit(&fit.model);
    let mut fell_back = false;
    let several = p.regression.channels().len() > 1;
    if p.regression.nonlinear() {
        if let Some((linear, linear_fit)) = linear_start(p) {
            if let Some(why) = hammerstein_guard(
                fit.method,
                fit_sim,
                fit.model.is_stable(),
                linear.model.is_stable(),
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
                    fit_sim = Some(linear_fit);
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
    fit.warnings.extend(Warning::if_unstable(&fit.model));
    fit.warnings
        .extend(Warning::if_poor_simulation(Record::Estimation, fit_sim));
    // The fallback's nonlinearities are fixed by construction, not estimated: nothing to check.
    if !fell_back {
        for (m, ((ch, start), fitted)) in p
            .regression
            .channels()
            .iter()
            .zip(&p.starts)
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
    Ok(fit)
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
            .filter(|f| *f < linear_fit - FALLBACK_FIT_MARGIN)
            .map(|f| {
                format!(
                    "the {method} estimate simulates the estimation data far worse than the linear start \
                     (fit {f:.2} % against {linear_fit:.2} %)"
                )
            })
    }
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
            "the output-error search reached its iteration limit".into()
        }
        (Termination::IterationLimit, _) => "the iteration limit was reached".into(),
        (Termination::NotSettled, Method::Rls) => {
            "the recursive estimate was still moving at the end of the data (more passes or a \
             forgetting factor below 1 may settle it)"
                .into()
        }
        (Termination::NotSettled, _) => "the estimate had not settled".into(),
        (Termination::Converged, _) => "converged".into(),
    }
}

/// The linear ARX least-squares model of the same orders and offset, written with each nonlinear
/// input's linear equivalent (a deadzone with b_l = b_r = 0, m_l = m_r = b1, and B/b1), with its
/// estimation simulation fit; `None` when it cannot be estimated, a nonlinear input's b1 is 0, or its
/// simulation diverges. Standard deviations where the ARX regression gives them (a, linear inputs' B,
/// c; the slopes from b1).
fn linear_start(p: &Problem) -> Option<(Fitted, f64)> {
    let lp = p.linear().ok()?;
    let arx = methods::arx_ls(&lp).ok()?;
    let m = &arx.model;
    let reg = &p.regression;
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
        let input = several.then(|| ch.name.as_str());
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
    let fit_sim = p.simulation_fit(&model)?;
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
        fit_sim,
    ))
}

/// No silent NaN: an estimate the data do not determine in f64 (magnitudes whose squares underflow or
/// overflow) is a numerical failure, not a result.
pub(crate) fn check_finite(name: &str, params: &[Param]) -> Result<(), SysidError> {
    match params.iter().find(|p| !p.value.is_finite()) {
        Some(p) => Err(SysidError::Numerical(format!(
            "{}: the estimate of {} is {} (not finite): the data do not determine it in f64 arithmetic \
             (values too large or too small? rescale the data)",
            name,
            p.label(),
            p.value
        ))),
        None => Ok(()),
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
        methods::least_squares(p, self)
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
        methods::recursive(p, self)
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
        methods::output_error(p, self)
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
        methods::instrumental(p, self)
    }
}
