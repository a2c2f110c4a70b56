//! Estimators behind one trait: batch least squares (QR) and recursive least squares (paper eqs. 9–12)
//! for ARX, and the Hammerstein model by key-term separation (docs/paper.md, eq. 8) — iterated batch LS
//! or recursive; beyond the paper: output-error refinement ([`crate::oe`]), recursive instrumental
//! variables ([`crate::iv`]), a UD-factorised RLS with windup protection ([`crate::rls_ud`],
//! [`crate::windup`]), and Hammerstein models on one-sided inputs ([`crate::branches`]).
//!
//! Unfitted settings, one type per method ([`LeastSquares`], [`RecursiveLeastSquares`],
//! [`OutputError`], [`InstrumentalVariables`]) → [`Estimator::fit`] on a [`Problem`] → a [`Fitted`]
//! model with its diagnostics. [`identify`] is the one entry point that checks the problem, runs an
//! estimator and applies the safeguards common to every method.

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::branches::Branches;
use crate::ls;
use crate::rls;
use crate::rls_ud::RlsForm;
use crate::warnings::{deadzone_warnings, Record, Warning};
use crate::windup::Windup;
use crate::{iv, oe};
use sysid_core::param::{deadzone_from_theta, Layout, Parameterisation, ZERO_DEADZONE};
use sysid_core::{Dataset, Model, ModelKind, Orders, ParamName, Setting, Structure, SysidError};

/// Estimation method (the JSON `method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Batch least squares via QR; for Hammerstein, iterated key-term separation.
    Ls,
    /// Recursive least squares with forgetting (paper eqs. 9–12).
    Rls,
    /// Output-error refinement of every parameter (Levenberg–Marquardt on the free-run simulation error),
    /// started from the LS estimate. Unbiased under white output (measurement) noise; batch. Also with
    /// several inputs.
    Oe,
    /// Recursive instrumental variables with instruments from an auxiliary model's simulated output.
    /// Unbiased under output noise; recursive (online). Also with several inputs.
    Iv,
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Method::Ls => "ls",
            Method::Rls => "rls",
            Method::Oe => "oe",
            Method::Iv => "iv",
        })
    }
}

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

/// What an estimator is fitted to: the data, the model structure and the deadzone branches the data
/// excite. Made by [`Problem::new`], which checks that the data can support the structure.
#[derive(Debug, Clone)]
pub struct Problem<'a> {
    data: &'a Dataset,
    structure: Structure,
    branches: Branches,
}

impl<'a> Problem<'a> {
    /// Checks `structure` against `data` and finds the branches the input excites. With
    /// `drop_unexcited_branch`, a Hammerstein model on a one-sided input drops the unexcited branch
    /// instead of refusing the data.
    pub fn new(
        data: &'a Dataset,
        structure: Structure,
        drop_unexcited_branch: bool,
    ) -> Result<Self, SysidError> {
        structure.check()?;
        let k0 = structure.orders.k0();
        let p = structure.n_params();
        let n = data.len();
        if n <= k0 || n - k0 < p {
            return Err(SysidError::Data(format!(
                "{}: {n} samples leave {} regression rows for {p} parameters (na = {}, nb = {}, nk = {}); \
                 more data or lower orders are needed",
                data.name,
                n.saturating_sub(k0),
                structure.orders.na,
                structure.orders.nb,
                structure.orders.nk
            )));
        }
        let branches = match structure.kind {
            ModelKind::Hammerstein => Branches::of(data, structure.offset, drop_unexcited_branch)?,
            ModelKind::Arx => Branches::all(0.0, 0.0, 0.0),
        };
        Ok(Problem {
            data,
            structure,
            branches,
        })
    }

    /// The data.
    pub fn data(&self) -> &Dataset {
        self.data
    }
    /// The structure.
    pub fn structure(&self) -> &Structure {
        &self.structure
    }
    /// The deadzone branches the data excite.
    pub fn branches(&self) -> &Branches {
        &self.branches
    }
    /// The key-term parameterisation with the entries the data determine marked free.
    fn key_term(&self) -> Parameterisation {
        self.branches
            .parameterisation(&self.structure, Layout::KeyTerm)
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
    /// The model structure.
    pub structure: Structure,
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
            estimator: EstimatorSettings::Rls(RecursiveLeastSquares::default()),
            drop_unexcited_branch: false,
            fallback: false,
        }
    }
}

impl Identification {
    /// Checks the structure and the estimator's settings, without data.
    pub fn check(&self) -> Result<(), SysidError> {
        self.structure.check()?;
        self.estimator.check()
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
    /// Builder: forgetting factor ρ of a recursive method (RLS, IV); no effect on the batch methods.
    pub fn with_forgetting(mut self, rho: f64) -> Self {
        match &mut self.estimator {
            EstimatorSettings::Rls(r) => r.forgetting = rho,
            EstimatorSettings::Iv(i) => i.forgetting = rho,
            _ => {}
        }
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

/// One physical parameter with its standard deviation (MATLAB `present`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Param {
    /// Name: b_l, b_r, m_l, m_r, a1.., b1.., c.
    pub name: ParamName,
    /// Estimate.
    pub value: f64,
    /// Standard deviation from the covariance (delta method for ratios); `None` for fixed parameters (b1 = 1
    /// of a Hammerstein model) or when it cannot be computed.
    pub std: Option<f64>,
}

/// How an estimator stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum Termination {
    /// It met its convergence criterion: LS key-term iteration at a fixed point; RLS estimate settled
    /// (relative change below 1e-3 over the last 10 % of the final pass, or between the ends of the last
    /// two passes); OE optimiser on its ftol/xtol/gtol criterion; IV stages settled.
    Converged,
    /// The key-term iteration entered a limit cycle.
    LimitCycle,
    /// An iteration or evaluation cap was reached first.
    IterationLimit,
    /// The recursive estimate was still moving at the end of the data.
    NotSettled,
    /// The optimiser stopped for another reason (its words).
    Stopped(String),
}

impl Termination {
    /// True for [`Termination::Converged`].
    pub fn converged(&self) -> bool {
        matches!(self, Termination::Converged)
    }
}

/// A remark on an estimate, in words by `Display`.
#[derive(Debug, Clone, PartialEq)]
pub enum Note {
    /// A one-sided input: a deadzone branch was dropped or a breakpoint fixed (the words of
    /// [`Branches::notes`]).
    Branches(String),
    /// The key-term iteration cycled; the iterate with the smallest self-consistent residual was kept.
    KeyTermLimitCycle {
        /// Iterations run.
        iterations: usize,
        /// The iterate kept.
        kept: usize,
    },
    /// The key-term iteration hit its cap; the best iterate was kept.
    KeyTermNotConverged {
        /// Iterations run.
        iterations: usize,
        /// The iterate kept.
        kept: usize,
    },
    /// A recursive estimator other than the paper's plain RLS ran.
    RlsForm {
        /// Covariance form.
        form: RlsForm,
        /// Windup protection.
        windup: Windup,
    },
    /// RLS ran passes until the estimate settled (the paper's method is a single pass).
    PassesUntilSettled {
        /// Passes run.
        passes: usize,
        /// Whether it settled before the cap.
        settled: bool,
        /// The cap.
        max: usize,
    },
    /// Which candidate an iterative method returned, on the reported criterion.
    KeptCandidate {
        /// The candidate kept.
        kept: &'static str,
        /// Its estimation simulation RMSE, the worse of estimated and measured initial outputs
        /// ([`crate::trust::guarded_rmse`]).
        rmse: f64,
        /// The other candidates and their RMSE (`None`: the simulation diverged or the model is unstable).
        others: Vec<(&'static str, Option<f64>)>,
    },
    /// A remark on the least-squares start of an iterative method.
    Start(Box<Note>),
    /// The LS start simulated unstably; its poles were reflected into the unit circle.
    StabilisedStart,
    /// The output-error search: simulation RSS before and after.
    Refinement {
        /// RSS of the start.
        rss_start: f64,
        /// RSS of the result.
        rss: f64,
        /// Jacobian evaluations.
        iterations: usize,
        /// Residual evaluations.
        evaluations: usize,
        /// The optimiser's termination, in words.
        stopped: String,
    },
    /// An IV stage's auxiliary model was unstable; its poles were reflected.
    UnstableAuxiliary {
        /// The stage.
        stage: usize,
    },
    /// IV kept an earlier stage, the one whose model simulates the record best.
    KeptStage {
        /// The stage kept.
        kept: usize,
        /// Stages run.
        of: usize,
    },
    /// IV stages had not settled.
    StagesNotSettled {
        /// Stages run.
        stages: usize,
    },
}

impl std::fmt::Display for Note {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Note::Branches(words) => f.write_str(words),
            Note::KeyTermLimitCycle { iterations, kept } => write!(
                f,
                "key-term iteration entered a limit cycle after {iterations} iterations; kept iterate {kept}, \
                 the one with the smallest self-consistent residual"
            ),
            Note::KeyTermNotConverged { iterations, kept } => write!(
                f,
                "key-term iteration did not converge in {iterations} iterations; kept iterate {kept}, the one \
                 with the smallest self-consistent residual"
            ),
            Note::RlsForm { form, windup } => {
                write!(f, "RLS form {form}, windup protection {windup}")
            }
            Note::PassesUntilSettled {
                passes,
                settled: true,
                ..
            } => write!(
                f,
                "RLS passes repeated until the estimate settled: {passes} passes (the paper's method is a \
                 single pass)"
            ),
            Note::PassesUntilSettled {
                passes,
                settled: false,
                max,
            } => write!(
                f,
                "RLS passes repeated until the estimate settles: still moving after {passes} of at most \
                 {max} passes"
            ),
            Note::KeptCandidate { kept, rmse, others } => {
                write!(
                    f,
                    "kept the {kept} (estimation simulation RMSE {rmse:.6e}, the worse of estimated and \
                     measured initial outputs"
                )?;
                for (name, r) in others {
                    match r {
                        Some(r) => write!(f, "; {name}: {r:.6e}")?,
                        None => write!(f, "; {name}: unstable or diverging")?,
                    }
                }
                f.write_str(")")
            }
            Note::Start(n) => write!(f, "start (LS): {n}"),
            Note::StabilisedStart => f.write_str(
                "the LS start was unstable in simulation; its poles were reflected into the unit circle",
            ),
            Note::Refinement {
                rss_start,
                rss,
                iterations,
                evaluations,
                stopped,
            } => write!(
                f,
                "output-error refinement: simulation RSS {rss_start:.6e} -> {rss:.6e} in {iterations} iterations \
                 ({evaluations} evaluations), stopped: {stopped}"
            ),
            Note::UnstableAuxiliary { stage } => write!(
                f,
                "stage {stage}: the auxiliary model was unstable; its poles were reflected"
            ),
            Note::KeptStage { kept, of } => write!(
                f,
                "kept stage {kept} of {of}, the one whose model simulates the record best"
            ),
            Note::StagesNotSettled { stages } => write!(
                f,
                "IV stages had not settled after {stages} stages (relative change >= {:e})",
                iv::IV_SETTLED
            ),
        }
    }
}

/// A fitted model with its estimation record: the same type whatever the method.
#[derive(Debug, Clone)]
pub struct Fitted {
    /// The fitted model.
    pub model: Model,
    /// Physical parameters with standard deviations.
    pub params: Vec<Param>,
    /// Method used.
    pub method: Method,
    /// Key-term iterations (LS), passes (RLS), Levenberg–Marquardt iterations (OE) or stages (IV).
    pub iterations: usize,
    /// How the estimator stopped.
    pub termination: Termination,
    /// Remarks, in the order they arose.
    pub notes: Vec<Note>,
    /// Reasons not to trust the estimate blindly (empty when all is well).
    pub warnings: Vec<Warning>,
    /// σ̂²: residual variance of the one-step prediction errors, RSS / (N − p).
    pub noise_variance: f64,
    /// RLS only, when requested: the physical parameters (order of `params`) after each update.
    pub history: Vec<Vec<f64>>,
    /// Sample index of each `history` entry (pass-major, so passes > 1 repeat indices).
    pub history_samples: Vec<usize>,
}

impl Fitted {
    /// True when the estimator met its convergence criterion.
    pub fn converged(&self) -> bool {
        self.termination.converged()
    }

    /// The notes in words, joined by "; " (`None` without notes).
    pub fn note(&self) -> Option<String> {
        (!self.notes.is_empty()).then(|| {
            self.notes
                .iter()
                .map(ToString::to_string)
                .collect::<Vec<_>>()
                .join("; ")
        })
    }

    fn with_method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }

    pub(crate) fn new(
        model: Model,
        params: Vec<Param>,
        method: Method,
        noise_variance: f64,
    ) -> Self {
        Fitted {
            model,
            params,
            method,
            iterations: 1,
            termination: Termination::Converged,
            notes: Vec::new(),
            warnings: Vec::new(),
            noise_variance,
            history: Vec::new(),
            history_samples: Vec::new(),
        }
    }
}

/// Identifies a model from `data`: checks the settings and the data, fits, and applies the safeguards
/// common to every method (no non-finite estimate is returned as a result).
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
pub fn identify(data: &Dataset, settings: &Identification) -> Result<Fitted, SysidError> {
    settings.check()?;
    let problem = Problem::new(data, settings.structure, settings.drop_unexcited_branch)?;
    let mut fit = settings.estimator.fit(&problem)?;
    let mut notes: Vec<Note> = problem
        .branches
        .notes()
        .into_iter()
        .map(Note::Branches)
        .collect();
    notes.append(&mut fit.notes);
    fit.notes = notes;
    check_finite(&data.name, &fit.params)?;
    safeguard(&problem, settings, fit)
}

/// Percentage points of estimation simulation fit by which a Hammerstein estimate may trail the linear
/// ARX start before the linear model replaces it.
pub const FALLBACK_FIT_MARGIN: f64 = 10.0;

/// The safeguards common to every method: a Hammerstein estimate that diverged or simulates far worse
/// than the linear start is replaced by it (when `settings.fallback`), and every reason not to trust
/// the result becomes a [`Warning`].
fn safeguard(
    p: &Problem,
    settings: &Identification,
    mut fit: Fitted,
) -> Result<Fitted, SysidError> {
    let data = p.data;
    let s = &p.structure;
    let mut est = sysid_core::metrics::metrics(&fit.model, data).ok();
    let fit_sim = est.as_ref().and_then(|m| m.fit_sim_percent);
    let mut fell_back = false;
    // The plain linear least-squares ARX of the same orders on the same data: the Hammerstein guard's
    // start and every model's baseline (not computed for the baseline itself).
    let start = (s.kind == ModelKind::Hammerstein || fit.method != Method::Ls)
        .then(|| linear_start(p))
        .flatten();
    let baseline = start
        .as_ref()
        .filter(|(l, _)| l.model.is_stable())
        .map(|(_, m)| crate::trust::guarded_fit(m));
    if s.kind == ModelKind::Hammerstein {
        if let Some((linear, linear_metrics)) = start {
            let linear_fit = linear_metrics.fit_sim_percent.unwrap_or(f64::NAN);
            if let Some(why) = hammerstein_guard(
                fit.method,
                fit_sim,
                fit.model.is_stable(),
                linear.model.is_stable(),
                linear_fit,
            ) {
                if settings.fallback {
                    let mut warnings = std::mem::take(&mut fit.warnings);
                    warnings.push(Warning::Fallback {
                        used: LINEAR_START_USED.into(),
                        why,
                    });
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
    fit.warnings.extend(Warning::if_unstable(&fit.model));
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
    // The fallback's breakpoints are fixed at 0 by construction, not estimated: nothing to check.
    if let (Some(d), false) = (fit.model.deadzone().copied(), fell_back) {
        let br = &p.branches;
        let (w, no_std) = deadzone_warnings(
            &d,
            &data.u,
            (br.left, br.right),
            (
                std_of(&fit.params, ParamName::BL),
                std_of(&fit.params, ParamName::BR),
            ),
        );
        for q in fit.params.iter_mut() {
            if no_std.contains(&q.name) {
                q.std = None;
            }
        }
        fit.warnings.extend(w);
    }
    Ok(fit)
}

/// Why a Hammerstein estimate by `method` should give way to the linear ARX start (one input or
/// several): its estimation simulation diverges (`fit_sim` = `None`), it is unstable while the start
/// is not, or its simulation fit trails the start's `linear_fit` by more than
/// [`FALLBACK_FIT_MARGIN`] points; `None` when none of these holds.
pub(crate) fn hammerstein_guard(
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

/// The words of the fallback warning: what replaced the Hammerstein estimate.
pub(crate) const LINEAR_START_USED: &str =
    "the linear ARX least-squares model, as a Hammerstein model with b_l = b_r = 0 and m_l = m_r = b1";

/// The standard deviation of parameter `name` in `params`, if it is there and has one.
fn std_of(params: &[Param], name: ParamName) -> Option<f64> {
    params.iter().find(|q| q.name == name).and_then(|q| q.std)
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
        (Termination::Stopped(w), _) => w.clone(),
        (Termination::Converged, _) => "converged".into(),
    }
}

/// The linear ARX least-squares model of the same orders and offset, written as a Hammerstein model
/// (b_l = b_r = 0, m_l = m_r = b1, B/b1) when the structure is Hammerstein, with its estimation
/// metrics; `None` when it cannot be estimated, b1 = 0, or its simulation diverges.
fn linear_start(p: &Problem) -> Option<(Fitted, sysid_core::metrics::Metrics)> {
    let s = Structure {
        kind: ModelKind::Arx,
        ..p.structure
    };
    let lp = Problem::new(p.data, s, true).ok()?;
    let arx = arx_ls(&lp).ok()?;
    if p.structure.kind == ModelKind::Arx {
        let m = sysid_core::metrics::metrics(&arx.model, p.data).ok()?;
        m.fit_sim_percent?;
        return Some((arx, m));
    }
    let m = &arx.model;
    let b1 = *m.b().first()?;
    if b1 == 0.0 || !b1.is_finite() {
        return None;
    }
    let b: Vec<f64> = m.b().iter().map(|v| v / b1).collect();
    let d = sysid_core::Deadzone {
        b_l: 0.0,
        b_r: 0.0,
        m_l: b1,
        m_r: b1,
    };
    let model = Model::hammerstein(m.ts(), m.a().to_vec(), b, m.nk(), d, m.offset()).ok()?;
    let metrics = sysid_core::metrics::metrics(&model, p.data).ok()?;
    metrics.fit_sim_percent?;
    let mut params = vec![
        Param {
            name: ParamName::BL,
            value: 0.0,
            std: None,
        },
        Param {
            name: ParamName::BR,
            value: 0.0,
            std: None,
        },
        Param {
            name: ParamName::ML,
            value: b1,
            std: std_of(&arx.params, ParamName::B(1)),
        },
        Param {
            name: ParamName::MR,
            value: b1,
            std: std_of(&arx.params, ParamName::B(1)),
        },
    ];
    params.extend(m.a().iter().enumerate().map(|(i, v)| Param {
        name: ParamName::A(i + 1),
        value: *v,
        std: std_of(&arx.params, ParamName::A(i + 1)),
    }));
    params.extend(model.b().iter().enumerate().map(|(j, v)| Param {
        name: ParamName::B(j + 1),
        value: *v,
        std: None,
    }));
    if let Some(c) = m.offset() {
        params.push(Param {
            name: ParamName::C,
            value: c,
            std: std_of(&arx.params, ParamName::C),
        });
    }
    Some((
        Fitted {
            params,
            ..Fitted::new(model, Vec::new(), Method::Ls, arx.noise_variance)
        },
        metrics,
    ))
}

/// No silent NaN: an estimate the data do not determine in f64 (magnitudes whose squares underflow or
/// overflow) is a numerical failure, not a result.
pub(crate) fn check_finite(name: &str, params: &[Param]) -> Result<(), SysidError> {
    match params.iter().find(|p| !p.value.is_finite()) {
        Some(p) => Err(SysidError::Numerical(format!(
            "{}: the estimate of {} is {} (not finite): the data do not determine it in f64 arithmetic \
             (values too large or too small? rescale the data)",
            name, p.name, p.value
        ))),
        None => Ok(()),
    }
}

/// The model of structure `s` from the full key-term θ̂, with the branches' fixed parts imposed; a
/// non-finite θ̂ is a numerical failure naming the data.
fn model_from_theta(
    data: &Dataset,
    key: &Parameterisation,
    br: &Branches,
    theta: &DVector<f64>,
) -> Result<Model, SysidError> {
    key.model_of(theta.as_slice(), data.ts)
        .and_then(|m| m.map_deadzone(|d| br.impose(d)))
        .map_err(|e| {
            let params = physical_params(key.structure(), theta, None);
            check_finite(&data.name, &params)
                .err()
                .unwrap_or_else(|| SysidError::Numerical(format!("{}: {e}", data.name)))
        })
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
        match p.structure.kind {
            ModelKind::Arx => arx_ls(p),
            ModelKind::Hammerstein => hammerstein_ls(p, self),
        }
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

/// LS start of the iterative methods: plain ARX or the key-term iteration.
fn least_squares(p: &Problem, st: &LeastSquares) -> Result<Fitted, SysidError> {
    st.fit(p)
}

/// Least squares over the free columns of Φ; θ and (ΦᵀΦ)⁻¹ are returned at full size with zeros for
/// the fixed entries.
fn solve_free(
    phi: &DMatrix<f64>,
    y: &DVector<f64>,
    key: &Parameterisation,
) -> Result<ls::LsSolution, SysidError> {
    let names = key.name_strings();
    if key.all_free() {
        return ls::solve(phi, y, &names);
    }
    let idx = key.free_indices();
    let sub = phi.select_columns(idx.iter());
    let sub_names: Vec<String> = idx.iter().map(|&i| names[i].clone()).collect();
    let sol = ls::solve(&sub, y, &sub_names)?;
    let zeros = vec![0.0; key.len()];
    Ok(ls::LsSolution {
        theta: DVector::from_vec(key.scatter(sol.theta.as_slice(), &zeros)),
        inv_gram: key.scatter_matrix(&sol.inv_gram),
        rss: sol.rss,
    })
}

/// Physical parameters, with the fixed deadzone entries set from the model and without a standard deviation.
fn params_with_branches(
    p: &Problem,
    theta: &DVector<f64>,
    cov: Option<&DMatrix<f64>>,
    model: &Model,
) -> Vec<Param> {
    let s = &p.structure;
    let mut params = physical_params(s, theta, cov);
    if let (ModelKind::Hammerstein, Some(d)) = (s.kind, model.deadzone()) {
        let free = p.branches.parameterisation(s, Layout::Physical);
        let values = [d.b_l, d.b_r, d.m_l, d.m_r];
        for i in 0..4 {
            if !free.free()[i] {
                params[i].value = values[i];
                params[i].std = None;
            }
        }
    }
    params
}

/// The criterion an output-error search's candidates are judged on: the RMSE of the free-run
/// simulation that the initial state cannot flatter ([`crate::trust::guarded_rmse`]: the larger of
/// the RMSEs from estimated and from measured initial outputs), `None` when the model is unstable or
/// its simulation diverges.
fn reported_rmse(model: &Model, data: &Dataset) -> Option<f64> {
    if !model.is_stable() {
        return None;
    }
    sysid_core::metrics::metrics(model, data)
        .ok()
        .and_then(|m| crate::trust::guarded_rmse(&m))
}

/// Output-error refinement from the LS (key-term) estimate. The search minimises the simulation error
/// with estimated initial outputs, the criterion the tool reports. Both candidates (the LS start and
/// the refined model) are judged on it and the better stable one is returned, with a note saying which
/// (and a warning when it is not the refined model).
fn output_error(p: &Problem, st: &OutputError) -> Result<Fitted, SysidError> {
    let start = least_squares(p, &st.start)?;
    let physical = p.branches.parameterisation(&p.structure, Layout::Physical);
    let fit = oe::refine(p.data, &physical, &start.model, st.max_iterations)?;
    let verdict = OeVerdict::judge(
        &fit,
        &start.notes,
        reported_rmse(&fit.model, p.data),
        reported_rmse(&start.model, p.data),
    );
    if verdict.fallback.is_none() {
        return Ok(Fitted {
            iterations: fit.iterations,
            termination: verdict.termination,
            notes: verdict.notes,
            warnings: crate::trust::std_warning(fit.std_unavailable.clone())
                .into_iter()
                .collect(),
            ..Fitted::new(fit.model, fit.params, Method::Oe, fit.noise_variance)
        });
    }
    Ok(Fitted {
        iterations: fit.iterations,
        termination: verdict.termination,
        notes: verdict.notes,
        warnings: verdict.fallback.into_iter().collect(),
        ..start
    }
    .with_method(Method::Oe))
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
    /// Judges both candidates on the guarded criterion (the estimation simulation RMSE, the worse of
    /// estimated and measured initial outputs, `None` for an unstable or diverging model): the better stable one is kept; when
    /// neither simulates stably the refinement (stable by construction) is kept and the warnings say
    /// what is wrong.
    pub fn judge<P>(
        fit: &oe::OeFit<P>,
        start_notes: &[Note],
        refined_rmse: Option<f64>,
        start_rmse: Option<f64>,
    ) -> Self {
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
        let refined_better = match (refined_rmse, start_rmse) {
            (Some(r), Some(s)) => r <= s,
            (Some(_), None) => true,
            (None, Some(_)) => false,
            (None, None) => true,
        };
        let termination = if fit.stop.converged() {
            Termination::Converged
        } else {
            Termination::IterationLimit
        };
        if refined_better {
            if let (Some(r), true) = (refined_rmse, start_rmse.is_some() || fit.stabilised_start) {
                notes.push(Note::KeptCandidate {
                    kept: "output-error refinement",
                    rmse: r,
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
            others: vec![("output-error refinement", refined_rmse)],
        });
        let why = format!(
            "the refined model simulates the estimation data worse (RMSE {refined_text} against {kept_rmse:.6e} \
             for the start)"
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

/// Recursive IV in stages ([`iv::staged`]), the first stage's instruments from the LS (key-term) estimate.
fn instrumental(p: &Problem, st: &InstrumentalVariables) -> Result<Fitted, SysidError> {
    let (data, s) = (p.data, &p.structure);
    let start = least_squares(p, &st.start)?;
    let key = p.key_term();
    let k0 = s.orders.k0();
    let r = iv::IvRegression {
        rows: (),
        y: &data.y,
        k0,
        free: key.free(),
        name: &data.name,
    };
    let out = iv::staged(
        &start.model,
        &key.vector_of(&start.model),
        &[&data.u],
        &r,
        |aux: &Model| {
            let dz = aux.deadzone().copied().unwrap_or(ZERO_DEADZONE);
            move |ys: &[f64], k: usize, row: &mut [f64]| s.fill_row(&data.u, ys, k, &dz, row)
        },
        |theta| model_from_theta(data, &key, &p.branches, theta),
        st.stages,
        st.forgetting,
        st.p0,
    )?;
    let rss = prediction_rss(&out.model, data)?;
    let sigma2 = rss / (data.len() - k0).saturating_sub(key.n_free()).max(1) as f64;
    let cov = iv::covariance(&out.pass, sigma2).map(|c| key.scatter_matrix(&c));
    Ok(Fitted {
        params: params_with_branches(p, &out.theta, cov.as_ref(), &out.model),
        iterations: out.stages,
        termination: if out.converged {
            Termination::Converged
        } else {
            Termination::NotSettled
        },
        notes: out.notes,
        ..Fitted::new(out.model, Vec::new(), Method::Iv, sigma2)
    })
}

/// The ratio b = θ_j / θ_i (a breakpoint from its key-term product and slope) and its standard deviation
/// by the delta method (gradient (−θ_j/θ_i², 1/θ_i)) from Cov(θ̂); NaN and `None` when θ_i = 0.
pub(crate) fn ratio_with_std(
    theta: &[f64],
    cov: Option<&DMatrix<f64>>,
    i: usize,
    j: usize,
) -> (f64, Option<f64>) {
    let (ti, tj) = (theta[i], theta[j]);
    let value = if ti != 0.0 { tj / ti } else { f64::NAN };
    let std = cov.and_then(|c| {
        if ti == 0.0 {
            return None;
        }
        let (gi, gj) = (-tj / (ti * ti), 1.0 / ti);
        let v = gi * gi * c[(i, i)] + 2.0 * gi * gj * c[(i, j)] + gj * gj * c[(j, j)];
        (v.is_finite() && v >= 0.0).then(|| v.sqrt())
    });
    (value, std)
}

/// Physical parameters and their covariance-based standard deviations from θ̂ and Cov(θ̂).
pub(crate) fn physical_params(
    s: &Structure,
    theta: &DVector<f64>,
    cov: Option<&DMatrix<f64>>,
) -> Vec<Param> {
    let sd = |i: usize| {
        cov.map(|c| c[(i, i)])
            .filter(|v| v.is_finite() && *v >= 0.0)
            .map(f64::sqrt)
    };
    let names = Parameterisation::new(*s, Layout::KeyTerm).names();
    let mut out = Vec::new();
    let mut first = 0;
    let b1 = || Param {
        name: ParamName::B(1),
        value: 1.0,
        std: None,
    };
    if s.kind == ModelKind::Hammerstein {
        let ratio = |i: usize, j: usize| ratio_with_std(theta.as_slice(), cov, i, j);
        let (bl, bl_sd) = ratio(2, 3);
        let (br, br_sd) = ratio(0, 1);
        out.push(Param {
            name: ParamName::BL,
            value: bl,
            std: bl_sd,
        });
        out.push(Param {
            name: ParamName::BR,
            value: br,
            std: br_sd,
        });
        out.push(Param {
            name: ParamName::ML,
            value: theta[2],
            std: sd(2),
        });
        out.push(Param {
            name: ParamName::MR,
            value: theta[0],
            std: sd(0),
        });
        first = 4;
    }
    for (i, name) in names.iter().enumerate().skip(first) {
        if s.kind == ModelKind::Hammerstein && i == first + s.orders.na {
            out.push(b1());
        }
        out.push(Param {
            name: *name,
            value: theta[i],
            std: sd(i),
        });
    }
    if s.kind == ModelKind::Hammerstein && names.len() == first + s.orders.na {
        out.push(b1());
    }
    out
}

fn build_regression(
    data: &Dataset,
    s: &Structure,
    dz: &sysid_core::Deadzone,
) -> (DMatrix<f64>, DVector<f64>) {
    let k0 = s.orders.k0();
    let rows = data.len() - k0;
    let p = s.n_params();
    let mut phi = DMatrix::<f64>::zeros(rows, p);
    let mut row = vec![0.0; p];
    let mut y = DVector::<f64>::zeros(rows);
    for k in k0..data.len() {
        s.fill_row(&data.u, &data.y, k, dz, &mut row);
        for (j, v) in row.iter().enumerate() {
            phi[(k - k0, j)] = *v;
        }
        y[k - k0] = s.target(&data.y, k);
    }
    (phi, y)
}

fn arx_ls(p: &Problem) -> Result<Fitted, SysidError> {
    let (data, s) = (p.data, &p.structure);
    let (phi, y) = build_regression(data, s, &ZERO_DEADZONE);
    let key = p.key_term();
    let sol = ls::solve(&phi, &y, &key.name_strings()).map_err(|e| context(data, e))?;
    let dof = (phi.nrows() - phi.ncols()).max(1) as f64;
    let sigma2 = sol.rss / dof;
    let cov = &sol.inv_gram * sigma2;
    let params = physical_params(s, &sol.theta, Some(&cov));
    let model = model_from_theta(data, &key, &p.branches, &sol.theta)?;
    Ok(Fitted::new(model, params, Method::Ls, sigma2))
}

fn context(data: &Dataset, e: SysidError) -> SysidError {
    match e {
        SysidError::Data(m) => SysidError::Data(format!("{}: {m}", data.name)),
        other => other,
    }
}

/// Sum of squared one-step prediction errors of `model` over rows k >= k0 (the self-consistent residual:
/// switching functions and x from the model itself).
fn prediction_rss(model: &Model, data: &Dataset) -> Result<f64, SysidError> {
    let k0 = model.k0();
    let yhat = model.predict_equation_error(&data.u, &data.y)?;
    Ok(data.y[k0..]
        .iter()
        .zip(&yhat[k0..])
        .map(|(y, p)| (y - p) * (y - p))
        .sum())
}

fn hammerstein_ls(p: &Problem, st: &LeastSquares) -> Result<Fitted, SysidError> {
    let (data, s, br) = (p.data, &p.structure, &p.branches);
    let limit = br.limit;
    // Initial switching: h_r = [u > 0], h_l = [u < 0] (breakpoints at the smallest commands).
    let mut dz = br.initial_deadzone();
    let key = p.key_term();
    let mut seen: Vec<DVector<f64>> = Vec::new();
    let mut best: Option<(f64, DVector<f64>, ls::LsSolution, usize)> = None;
    let mut converged = false;
    let mut cycle = false;
    let mut iterations = 0;
    for it in 1..=st.max_iterations {
        iterations = it;
        let (phi, y) = build_regression(data, s, &dz);
        let sol = match solve_free(&phi, &y, &key) {
            Ok(sol) => sol,
            // A later iterate's breakpoints can leave a branch with too few distinct commands: stop and keep
            // the best iterate so far (reported in the note as not converged).
            Err(SysidError::Data(_)) if best.is_some() => break,
            Err(e) => return Err(context(data, e)),
        };
        let theta = sol.theta.clone();
        let rss = model_from_theta(data, &key, br, &theta)
            .and_then(|m| prediction_rss(&m, data))
            .unwrap_or(f64::INFINITY);
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
        dz = deadzone_from_theta(theta.as_slice(), dz, limit);
        br.impose(&mut dz);
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
    let rows = data.len() - s.orders.k0();
    let sigma2 = rss / (rows.saturating_sub(key.n_free()).max(1)) as f64;
    let cov = &sol.inv_gram * sigma2;
    let model = model_from_theta(data, &key, br, &theta)?;
    Ok(Fitted {
        params: params_with_branches(p, &theta, Some(&cov), &model),
        iterations,
        termination,
        notes,
        ..Fitted::new(model, Vec::new(), Method::Ls, sigma2)
    })
}

/// The recursive estimator of `np` parameters that `st` describes: the paper's RLS for the standard form
/// without windup protection, `RobustRls` otherwise.
pub(crate) fn recursive_estimator(
    np: usize,
    st: &RecursiveLeastSquares,
) -> Result<Box<dyn rls::RecursiveUpdate>, SysidError> {
    crate::online::recursive_estimator(np, st.forgetting, st.p0, st.form, st.windup, st.max_trace)
}

/// RLS for ARX, and recursive key-term separation for Hammerstein. First pass (the paper's scheme):
/// switching functions and the internal x̂ are evaluated with the latest estimate at every sample.
/// Later passes restart P = p0 I, keep θ̂ and evaluate the switching functions and x̂ with the estimate
/// the pass started from, so each pass is the recursive solution of one key-term LS step regularised
/// towards the previous estimate; the passes converge to the batch key-term fixed point.
fn recursive(p: &Problem, st: &RecursiveLeastSquares) -> Result<Fitted, SysidError> {
    let (data, s, br) = (p.data, &p.structure, &p.branches);
    let k0 = s.orders.k0();
    let n = data.len();
    let key = p.key_term();
    let idx = key.free_indices();
    let np = idx.len();
    let mut est = recursive_estimator(np, st)?;
    let mut full_row = vec![0.0; s.n_params()];
    let mut row = vec![0.0; np];
    let hammer = s.kind == ModelKind::Hammerstein;
    let mut dz = if hammer {
        br.initial_deadzone()
    } else {
        ZERO_DEADZONE
    };
    let limit = br.limit;
    let initial_dz = dz;
    // Persistent excitation: the recursion never fails on data that cannot determine θ (P merely stays
    // large in the unexcited directions), so for identification proper (ρ = 1, no windup protection:
    // every sample weighs the same) the regressor matrix of the first pass is rank-tested first, as the
    // batch methods do, and such data are refused with the same message. With forgetting ρ < 1 or windup
    // protection the estimator is being used as a tracker, where spells without excitation are expected.
    if st.forgetting == 1.0 && st.windup == Windup::None && data.len() - k0 >= np {
        let (phi, y) = build_regression(data, s, &dz);
        // Only the rank verdict matters here; numerical trouble (overflow) is left to the recursion,
        // which reports the sample where it happens.
        if let Err(e @ SysidError::Data(_)) = solve_free(&phi, &y, &key) {
            return Err(context(data, e));
        }
    }
    let zeros = vec![0.0; key.len()];
    let expand = |t: &[f64]| DVector::from_vec(key.scatter(t, &zeros));
    let mut history = Vec::new();
    let mut history_samples = Vec::new();
    let mut pass_ends: Vec<DVector<f64>> = Vec::new();
    let tail_start = n - (n - k0) / 10;
    let mut theta_tail = DVector::from_column_slice(est.theta());
    let mut settled = false;
    for pass in 0..st.passes.max() {
        if pass > 0 {
            est.restart_covariance(st.p0);
            if hammer {
                dz = deadzone_from_theta(expand(est.theta()).as_slice(), dz, limit);
                br.impose(&mut dz);
            }
        }
        for k in k0..n {
            if k == tail_start {
                theta_tail.copy_from_slice(est.theta());
            }
            if hammer && pass == 0 && k > k0 {
                let full = expand(est.theta());
                dz = deadzone_from_theta(full.as_slice(), dz, limit);
                br.impose(&mut dz);
                if full[0] == 0.0 && full[2] == 0.0 {
                    dz = initial_dz;
                }
            }
            s.fill_row(&data.u, &data.y, k, &dz, &mut full_row);
            for (q, &i) in idx.iter().enumerate() {
                row[q] = full_row[i];
            }
            est.update(&row, s.target(&data.y, k), k)
                .map_err(|e| e.context(&data.name))?;
            if st.record_history {
                history.push(
                    physical_params(s, &expand(est.theta()), None)
                        .iter()
                        .map(|q| q.value)
                        .collect(),
                );
                history_samples.push(k);
            }
        }
        let end = DVector::from_column_slice(est.theta());
        if let (Passes::UntilSettled { .. }, Some(prev)) = (st.passes, pass_ends.last()) {
            if (&end - prev).norm() <= PASSES_SETTLED * (1e-300 + end.norm()) {
                settled = true;
                pass_ends.push(end);
                break;
            }
        }
        pass_ends.push(end);
    }
    let passes_run = pass_ends.len();
    let theta = DVector::from_column_slice(est.theta());
    let rel = |a: &DVector<f64>, b: &DVector<f64>| (a - b).norm() / (1e-300 + b.norm());
    let converged = match st.passes {
        Passes::UntilSettled { .. } => settled,
        Passes::Fixed(_) if pass_ends.len() >= 2 => {
            rel(&pass_ends[pass_ends.len() - 2], &theta) < 1e-3
        }
        Passes::Fixed(_) => rel(&theta_tail, &theta) < 1e-3,
    };
    let theta_full = expand(theta.as_slice());
    let model = model_from_theta(data, &key, br, &theta_full)?;
    let rss = prediction_rss(&model, data)?;
    let sigma2 = rss / (n - k0).saturating_sub(np).max(1) as f64;
    let cov = key.scatter_matrix(&(est.covariance() * sigma2));
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
        params: params_with_branches(p, &theta_full, Some(&cov), &model),
        iterations: passes_run,
        termination: if converged {
            Termination::Converged
        } else {
            Termination::NotSettled
        },
        notes,
        history,
        history_samples,
        ..Fitted::new(model, Vec::new(), Method::Rls, sigma2)
    })
}
