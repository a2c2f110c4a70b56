//! The vocabulary every estimator shares: the [`Method`], a [`Param`] with its standard deviation,
//! how an estimator stopped ([`Termination`]), remarks ([`Note`]) and the fitted result ([`Fitted`]).
//! Small types in their own module, so that the estimators, the warnings and the online tracker can all
//! use them without importing each other.

use serde::{Deserialize, Serialize};

use crate::rls_ud::RlsForm;
use crate::warnings::Warning;
use crate::windup::Windup;
use sysid_core::metrics::Metrics;
use sysid_core::{Dataset, Model, ParamName};

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
    /// started from the LS estimate (and, for a model with an input nonlinearity, from the IV estimate too,
    /// keeping the lower end). Unbiased under white output (measurement) noise; batch. Also with
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

/// A setting of one family of estimators that the other methods do not use (`identify --forgetting`,
/// Python `identify(forgetting=...)`): the command line and the Python module refuse each where its
/// method is not chosen, by this one table ([`EstimatorSetting::unused_by`]; audit s19 L-5: Python
/// accepted `method="ls", forgetting=nan`, which the command line refuses).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EstimatorSetting {
    /// Passes over the record (RLS).
    Passes,
    /// The RLS update's form (standard, Joseph, Bierman UD).
    RlsForm,
    /// The guard against covariance wind-up (RLS).
    Windup,
    /// The bound on trace P (RLS).
    MaxTrace,
    /// The forgetting factor λ (RLS, IV).
    Forgetting,
    /// The initial covariance P(0) = p0 I (RLS, IV).
    P0,
    /// The instrumental-variable stages (IV).
    IvStages,
}

impl EstimatorSetting {
    /// Every setting, in the order the command line checks them.
    pub const ALL: [EstimatorSetting; 7] = [
        EstimatorSetting::Passes,
        EstimatorSetting::RlsForm,
        EstimatorSetting::Windup,
        EstimatorSetting::MaxTrace,
        EstimatorSetting::Forgetting,
        EstimatorSetting::P0,
        EstimatorSetting::IvStages,
    ];

    /// Its Python keyword (`max_trace`); the command-line flag is `--` and the id with `-` for `_`.
    pub fn id(self) -> &'static str {
        match self {
            EstimatorSetting::Passes => "passes",
            EstimatorSetting::RlsForm => "rls_form",
            EstimatorSetting::Windup => "windup",
            EstimatorSetting::MaxTrace => "max_trace",
            EstimatorSetting::Forgetting => "forgetting",
            EstimatorSetting::P0 => "p0",
            EstimatorSetting::IvStages => "iv_stages",
        }
    }

    /// The methods that use it.
    pub fn methods(self) -> &'static [Method] {
        match self {
            EstimatorSetting::Passes
            | EstimatorSetting::RlsForm
            | EstimatorSetting::Windup
            | EstimatorSetting::MaxTrace => &[Method::Rls],
            EstimatorSetting::Forgetting | EstimatorSetting::P0 => &[Method::Rls, Method::Iv],
            EstimatorSetting::IvStages => &[Method::Iv],
        }
    }

    /// Those methods in words ("the recursive estimators"), for "a setting of ...".
    pub fn whose(self) -> &'static str {
        match self.methods() {
            [Method::Rls] => "recursive least squares",
            [Method::Iv] => "instrumental variables",
            _ => "the recursive estimators",
        }
    }

    /// The first setting that `given` says was given and `method` does not use.
    pub fn unused_by(method: Method, given: impl Fn(EstimatorSetting) -> bool) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|&s| given(s) && !s.methods().contains(&method))
    }
}

/// One physical parameter with its standard deviation (MATLAB `present`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Param {
    /// Name: b_l, b_r, m_l, m_r, a1.., b1.., c.
    pub name: ParamName,
    /// The input the parameter belongs to (its static nonlinearity or B polynomial), named only when the
    /// model has several inputs.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub input: Option<String>,
    /// Estimate.
    pub value: f64,
    /// Standard deviation from the covariance (delta method for ratios); `None` for fixed parameters (b1 = 1
    /// of a Hammerstein model) or when it cannot be computed.
    pub std: Option<f64>,
    /// Why the tool held the parameter at its value instead of estimating it ([`FIXED_NORMALISATION`],
    /// [`FIXED_ONE_SIDED`]); `None` for an estimated parameter.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub fixed: Option<String>,
}

/// How many of the model structure's parameters the estimator held at a value instead of estimating
/// them ([`FIXED_ONE_SIDED`]; the normalisation b1 = 1 is not a parameter of the structure's count).
pub fn held_fixed(params: &[Param]) -> usize {
    params
        .iter()
        .filter(|q| q.fixed.as_deref() == Some(FIXED_ONE_SIDED))
        .count()
}

/// [`Param::fixed`] of b1 = 1 of an input with a static nonlinearity: the key-term normalisation.
pub const FIXED_NORMALISATION: &str = "normalisation";
/// [`Param::fixed`] of a deadzone parameter a one-sided input does not determine (a dropped branch, a
/// breakpoint not separable from the offset; the note says which).
pub const FIXED_ONE_SIDED: &str = "one-sided input";

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
    /// The output-error search stopped on a tolerance where its Gauss–Newton model still predicted a
    /// decrease, and its restarts were still lowering the loss when they ran out.
    NotStationary,
}

impl Termination {
    /// True for [`Termination::Converged`].
    pub fn converged(&self) -> bool {
        matches!(self, Termination::Converged)
    }
}

/// [`Note::KeptCandidate::criterion`] of the RMSE pooled over both initial states,
/// √((RMSE_est² + RMSE_meas²)/2) ([`crate::trust::pooled_rmse`]).
pub const POOLED_CRITERION: &str = "pooled over estimated and measured initial outputs";

/// A remark on an estimate, in words by `Display`.
#[derive(Debug, Clone, PartialEq)]
pub enum Note {
    /// A one-sided input: a deadzone branch was dropped or a breakpoint fixed (the words of
    /// `Branches::notes`).
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
        /// Its estimation simulation RMSE on `criterion`.
        rmse: f64,
        /// How the RMSE combines the two initial states: [`POOLED_CRITERION`].
        criterion: &'static str,
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
    /// The output-error search also ran from the IV estimate (`methods::second_start`): the simulation
    /// RSS each search ended at, and which end was kept.
    SecondStart {
        /// RSS at the end of the search from the LS start.
        rss_ls: f64,
        /// RSS at the end of the search from the IV start (`None`: IV or its search failed, `why`).
        rss_iv: Option<f64>,
        /// Whether the IV start's end was kept.
        kept_iv: bool,
        /// Why there is no second end.
        why: Option<String>,
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
    /// `--breakpoints auto`: K of the piecewise-linear blocks chosen by the smallest AIC on the
    /// estimation data.
    BreakpointsChosen {
        /// The K kept.
        k: usize,
        /// Every K tried with its AIC (`None`: the fit failed or its AIC is not finite).
        candidates: Vec<(usize, Option<f64>)>,
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
            Note::KeptCandidate {
                kept,
                rmse,
                criterion,
                others,
            } => {
                write!(
                    f,
                    "kept the {kept} (estimation simulation RMSE {rmse:.6e}, {criterion}"
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
            Note::SecondStart {
                rss_ls,
                rss_iv: Some(rss_iv),
                kept_iv,
                ..
            } => write!(
                f,
                "output-error search from two starts (LS, biased under output noise, and IV): simulation RSS \
                 {rss_ls:.6e} from the LS start, {rss_iv:.6e} from the IV start; kept the {} start's end{}",
                if *kept_iv { "IV" } else { "LS" },
                if *kept_iv {
                    " (the search from LS stopped in a local minimum)"
                } else {
                    ""
                }
            ),
            Note::SecondStart {
                rss_ls, why, ..
            } => write!(
                f,
                "output-error search from the LS start only (simulation RSS {rss_ls:.6e}): the second \
                 start, from IV, failed: {}",
                why.as_deref().unwrap_or("no reason given")
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
                IV_SETTLED
            ),
            Note::BreakpointsChosen { k, candidates } => {
                let list: Vec<String> = candidates
                    .iter()
                    .map(|(k, aic)| match aic {
                        Some(a) => format!("K = {k}: {a:.4}"),
                        None => format!("K = {k}: failed"),
                    })
                    .collect();
                write!(
                    f,
                    "piecewise-linear breakpoints K = {k} chosen by the smallest AIC on the estimation data ({})",
                    list.join(", ")
                )
            }
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
    /// σ̂²: residual variance of the one-step prediction errors, RSS / (N − p)
    /// ([`sysid_core::ls::noise_variance`]); NaN when N ≤ p (no residual degrees of freedom).
    pub noise_variance: f64,
    /// RLS only, when requested: the physical parameters (order of `params`) after each update.
    pub history: Vec<Vec<f64>>,
    /// Sample index of each `history` entry (pass-major, so passes > 1 repeat indices).
    pub history_samples: Vec<usize>,
    /// The metrics of `model` on the estimation records, as the safeguards of
    /// [`identify`](crate::identify) computed them (read through [`Fitted::estimation_metrics`]).
    pub(crate) kept_metrics: Option<Box<KeptMetrics>>,
}

/// Metrics kept with the model and the records they were computed on.
#[derive(Debug, Clone)]
pub(crate) struct KeptMetrics {
    model: Model,
    records: RecordsKey,
    metrics: Metrics,
}

/// What identifies a list of records: each one's name, Ts, length and the bits of every sample of its
/// inputs and output, hashed (four independent FNV-style lanes over the 64-bit patterns).
#[derive(Debug, Clone, PartialEq)]
struct RecordsKey {
    records: Vec<(String, u64, usize)>,
    hash: [u64; 4],
}

impl RecordsKey {
    fn of(records: &[Dataset]) -> Self {
        const PRIME: u64 = 0x0000_0100_0000_01b3;
        let mut hash = [0xcbf2_9ce4_8422_2325u64; 4];
        let mut mix = |x: &[f64]| {
            let mut chunks = x.chunks_exact(4);
            for c in &mut chunks {
                for i in 0..4 {
                    hash[i] = (hash[i] ^ c[i].to_bits()).wrapping_mul(PRIME);
                }
            }
            for (i, v) in chunks.remainder().iter().enumerate() {
                hash[i] = (hash[i] ^ v.to_bits()).wrapping_mul(PRIME);
            }
            // The length separates one signal from the next.
            hash[0] = (hash[0] ^ x.len() as u64).wrapping_mul(PRIME);
        };
        for r in records {
            for input in r.inputs() {
                mix(input.u());
            }
            mix(r.y());
        }
        RecordsKey {
            records: records
                .iter()
                .map(|r| (r.name().to_string(), r.ts().to_bits(), r.len()))
                .collect(),
            hash,
        }
    }
}

impl Param {
    /// The name as users read it: `b_l`, or `b_l (u1)` for a parameter of input u1.
    pub fn label(&self) -> String {
        match &self.input {
            Some(i) => format!("{} ({i})", self.name),
            None => self.name.to_string(),
        }
    }
}

impl Fitted {
    /// p: the parameters the estimator estimated — the model's count, which excludes those it held
    /// fixed (a deadzone branch a one-sided input never reached, [`held_fixed`], recorded in the model
    /// by [`identify`](crate::identify): [`Model::fixed_parameters`]), as MATLAB counts free parameters
    /// (audit s18 L-7).
    pub fn estimated_parameter_count(&self) -> usize {
        self.model.parameter_count()
    }

    /// `m` (metrics of this fit's model) with p, FPE and AIC of the estimated parameters only
    /// ([`Fitted::estimated_parameter_count`]): the one count of `identify`, `order` and `validate`
    /// (audit s30 H-1: `order` counted the fixed ones, so a Hammerstein candidate on a one-sided input
    /// ranked below the ARX model it equals; audit s33 H-1: `validate` did).
    pub fn estimated_metrics(
        &self,
        m: sysid_core::metrics::Metrics,
    ) -> sysid_core::metrics::Metrics {
        m.with_parameter_count(self.estimated_parameter_count())
    }

    /// The same fit with the parameters its `params` mark as held fixed ([`held_fixed`]) recorded in
    /// its model ([`Model::with_fixed_parameters`]), and the kept metrics counted again.
    pub(crate) fn with_fixed_parameters(mut self) -> Result<Self, sysid_core::SysidError> {
        let n = held_fixed(&self.params);
        self.model = self.model.with_fixed_parameters(n)?;
        if let Some(kept) = self.kept_metrics.as_mut() {
            kept.model = kept.model.clone().with_fixed_parameters(n)?;
            kept.metrics = kept
                .metrics
                .clone()
                .with_parameter_count(kept.model.parameter_count());
        }
        Ok(self)
    }

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

    /// The metrics of the fitted model on the estimation records (pooled over several, as
    /// [`sysid_core::metrics::pooled_metrics`] gives them), computed once by the safeguards of
    /// [`identify`](crate::identify); `None` when none were kept, or when the model has been changed since
    /// or `records` are not the records it was estimated on (same names, Ts, lengths and samples). A
    /// report then computes them itself.
    pub fn estimation_metrics(&self, records: &[Dataset]) -> Option<&Metrics> {
        let kept = self.kept_metrics.as_ref()?;
        (kept.model == self.model && kept.records == RecordsKey::of(records))
            .then_some(&kept.metrics)
    }

    /// Keeps `metrics`, the metrics of the current model on `records` (see
    /// [`Fitted::estimation_metrics`]).
    pub(crate) fn keep_metrics(&mut self, records: &[Dataset], metrics: Metrics) {
        self.kept_metrics = Some(Box::new(KeptMetrics {
            model: self.model.clone(),
            records: RecordsKey::of(records),
            metrics,
        }));
    }

    /// The same fit with the estimation data's range recorded in its model
    /// ([`Model::with_data_range`]); the range changes no metric, so metrics kept for the model stay kept.
    pub(crate) fn with_data_range(
        mut self,
        range: Option<sysid_core::DataRange>,
    ) -> Result<Self, sysid_core::SysidError> {
        self.model = self.model.with_data_range(range.clone())?;
        if let Some(kept) = self.kept_metrics.as_mut() {
            kept.model = kept.model.clone().with_data_range(range)?;
        }
        Ok(self)
    }

    pub(crate) fn with_method(mut self, method: Method) -> Self {
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
            kept_metrics: None,
        }
    }
}

/// Relative change of θ̂ between IV stages below which the stages have settled.
pub const IV_SETTLED: f64 = 1e-6;

/// No silent NaN: an estimate the data do not determine in f64 (magnitudes whose squares underflow or
/// overflow) is a numerical failure, not a result.
pub(crate) fn check_finite(name: &str, params: &[Param]) -> Result<(), sysid_core::SysidError> {
    match params.iter().find(|p| !p.value.is_finite()) {
        Some(p) => Err(sysid_core::SysidError::Numerical(format!(
            "{}: the estimate of {} is {} (not finite): the data do not determine it in f64 arithmetic \
             (values too large or too small? rescale the data)",
            name,
            p.label(),
            p.value
        ))),
        None => Ok(()),
    }
}
