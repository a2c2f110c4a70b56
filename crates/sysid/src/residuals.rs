//! Residual analysis of a fitted model, as MATLAB's `resid` (Ljung, *System Identification*, 2nd ed.,
//! section 16.6 "Model validation: residual analysis").
//!
//! Given the one-step prediction residuals ε(k) of a model on some data and the input u(k) of the same
//! rows (k = 1..N), [`analyze`] computes
//!
//! * the residual autocorrelation r_ε(τ), τ = 1..M, and its **whiteness** test (Ljung–Box);
//! * the residual–input cross-correlation r_εu(τ), τ = −M..M, and its **independence** test;
//! * the 99 % per-lag band ±2.58/√N used to draw both plots.
//!
//! A model passes when its residuals are white (what is left is unpredictable noise) and independent
//! of the input (no input dynamics are left unexplained).
//!
//! # Definitions
//!
//! With the centred signals e(k) = ε(k) − ε̄ and v(k) = u(k) − ū (see *Mean removal* below):
//!
//! ```text
//! R_e(τ)  = (1/N) Σ_{k=τ+1..N} e(k) e(k−τ)                       (biased, 1/N, as MATLAB covf)
//! R_ev(τ) = (1/N) Σ_{k: 1 ≤ k ≤ N, 1 ≤ k−τ ≤ N} e(k) v(k−τ)
//! r_ε(τ)  = R_e(τ) / R_e(0)                                       τ = 1..M
//! r_εu(τ) = R_ev(τ) / √(R_e(0) R_v(0))                            τ = −M..M
//! ```
//!
//! **Sign convention of the cross-correlation**: r_εu(τ) correlates ε(t) with u(t−τ), as on MATLAB's
//! `resid` plot. Positive lags τ > 0 pair the residual with *past* inputs: a peak there means that
//! the output's response to u(t−τ) is not described by the model. Negative lags pair it with future
//! inputs; a peak there usually means output feedback (closed loop), not a wrong model.
//! [`ResidualAnalysis::cross_correlation`] holds lag −M first, lag +M last.
//!
//! # Tests (both at the 1 % level, [`SIGNIFICANCE`])
//!
//! * Whiteness, Ljung–Box: Q = N(N+2) Σ_{τ=1..M} r_ε(τ)² / (N−τ), compared with χ²(M). No degrees of
//!   freedom are subtracted for the estimated parameters (as in Ljung's book and MATLAB; for ARX with
//!   n_a + n_b ≪ M the difference is small and on the lenient side).
//! * Independence: the 2M+1 cross-correlations c = (r_εu(−M), …, r_εu(M)) are, under the hypothesis
//!   "ε white and independent of u", approximately normal with covariance G/N given u, where
//!   G_ij = (1/(N R_v(0))) Σ_{k=1..N} v(k−τ_i) v(k−τ_j) (τ_i = i − M, v taken as 0 outside 1..N) is
//!   the Gram matrix of the lagged inputs; G is the input's normalised autocorrelation matrix
//!   r_v(i−j) up to end effects of order M/N (Ljung's R̂_u, eq. 16.65–16.67). The statistic is
//!   S = N cᵀ G⁻¹ c, compared with χ²(2M+1). It equals N·R² of the least-squares regression of
//!   e(k) on v(k+M), …, v(k−M), so it needs no estimate of the input spectrum. For a white input
//!   G ≈ I and S reduces to the textbook N Σ r_εu(τ)², which is also reported
//!   ([`ResidualAnalysis::cross_statistic_plain`]). The plain sum is *not* used for the decision:
//!   with a coloured input (slow PWM steps, filtered noise) neighbouring lags are strongly
//!   correlated and N Σ r² rejects far more often than 1 % for a perfect model (see the tests).
//!
//! * Per-lag check (MATLAB `resid`'s rule, made a test): a model also fails when any single lag lies
//!   outside a **joint** 99 % band, z_K/√N with z_K the two-sided normal point at α/K for the K lags
//!   shown (K = M for r_ε, 2M+1 for r_εu; Bonferroni). Each r(τ) of a white, independent residual is
//!   about N(0, 1/N), so MATLAB's per-lag band 2.58/√N ([`ResidualAnalysis::bound`], still reported
//!   with the count of lags beyond it) is crossed somewhere among 51 lags in ~40 % of records from a
//!   correct model; the joint band (3.72/√N for 51 lags) keeps that below α. Like S, the band assumes
//!   the hypothesis "ε white and independent of u": with a coloured residual (an output-error model's)
//!   and a coloured input r_εu(τ) spreads by √P, P = Σ_k r_ε(k) r_u(k) (Bartlett), so either check
//!   can then call "NOT independent" a residual that is merely coloured; read it with the whiteness
//!   verdict. (A band widened by an estimated P was tried: on a short record the unexplained input
//!   dynamics colour the residual and inflate P, and the audit's wrong delay passed again.) A verdict is "white" /
//!   "independent" only when both its portmanteau statistic and its per-lag check accept, so the
//!   false-rejection rate of a correct model is at most 2α (the tests measure it).
//! * Why the per-lag check: S = N·R² ≤ N, so S can never exceed the 1 % point of χ²(2M+1)
//!   ([`ResidualAnalysis::cross_statistic_critical`], 77.4 for M = 25) on N ≤ 77 samples: on a short
//!   record the portmanteau alone would call any residual independent (audit s18 H-1, a wrong delay
//!   with r = 0.68 at lag 4 on 59 rows). [`ResidualAnalysis::portmanteau_can_reject`] tells when this
//!   is the case and [`ResidualAnalysis::largest_decidable_lag`] the largest M for which it is not.
//!
//! # Mean removal (the constant term)
//!
//! MATLAB's `resid` computes the covariances with `covf`, which does **not** subtract means; MATLAB
//! expects the data to have been detrended (`detrend`) before estimation. Here the sample means are
//! **subtracted by default** ([`ResidOptions::remove_mean`]), because this toolkit works on raw logger
//! data with large offsets (PWM commands around a working point): with mean μ_u ≫ σ_u the raw
//! normalisation R_u(0) ≈ μ_u² makes every r_εu(τ) ≈ ε̄ μ_u / √((ε̄² + σ_ε²)(μ_u² + σ_u²)) ≈
//! ε̄/√(ε̄² + σ_ε²): a flat line (near ±1 when the residual bias dominates) that measures the offsets,
//! not the dynamics, and fails both tests for signals that are white and independent (see the
//! tests); without a residual bias the true correlations are shrunk by σ_u/μ_u and the test loses
//! its power, and G becomes ill-conditioned. The residual mean is not lost: it is reported as
//! [`ResidualAnalysis::residual_mean`], so the application can flag a biased model.
//! `remove_mean: false` gives MATLAB's `covf` normalisation; on zero-mean data the two coincide.
//!
//! # Errors
//!
//! [`ResidError`]: M = 0, N < 2(M+1), lengths differ, a non-finite value (with its index), a residual
//! or input with zero variance (R(0) = 0: the correlation is undefined), or an input whose lagged
//! Gram matrix G is numerically singular (some lags carry no input at all, e.g. an input that is
//! zero except in its last M samples, uncentred).

#![deny(missing_docs)]
#![cfg_attr(
    not(test),
    deny(clippy::unwrap_used, clippy::expect_used, clippy::panic)
)]

use nalgebra::{linalg::Cholesky, DMatrix, DVector};
use serde::{Deserialize, Serialize};
use std::fmt;

/// MATLAB's default maximum lag M.
pub const DEFAULT_MAX_LAG: usize = 25;

/// The largest maximum lag M accepted. The independence statistic S forms and factors the
/// (2M+1)×(2M+1) Gram matrix G of the lagged inputs: memory 8(2M+1)² bytes (three copies while it
/// is factored) and time O(M³). M = 1000 is 32 MB per copy and about 2 s; M = 2000 took 30 s and
/// 520 MB, M = 20 000 asked for 12.8 GB and aborted (audit s27 M-4). MATLAB's `resid` defaults to
/// M = 25 and documents no upper bound; a maximum lag of 1000 is far beyond any model's memory, so
/// a larger M is refused with this bound named (and near `usize::MAX` its sizes wrapped around;
/// audit s14 H-c).
pub const MAX_LAG: usize = 1000;

/// M checked: at least 1, at most [`MAX_LAG`].
pub fn check_max_lag(m: usize) -> Result<(), ResidError> {
    match m {
        0 => Err(ResidError::ZeroMaxLag),
        m if m > MAX_LAG => Err(ResidError::MaxLagTooLarge { max_lag: m }),
        _ => Ok(()),
    }
}

/// The two-sided 99 % point of the standard normal distribution as MATLAB rounds it (2.5758… → 2.58).
pub const Z_99: f64 = 2.58;

/// Significance level α of both tests: a hypothesis is rejected when its p-value is below α.
pub const SIGNIFICANCE: f64 = 0.01;

/// Smallest Cholesky pivot of the lagged-input Gram matrix G (whose diagonal is at most 1) accepted
/// before the input is declared not exciting enough. A pivot is the fraction of the input's energy
/// at one lag not explained linearly by the other lags.
pub const MIN_PIVOT: f64 = 1e-10;

/// Settings of [`analyze`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ResidOptions {
    /// Maximum lag M ≥ 1 (MATLAB's default: [`DEFAULT_MAX_LAG`] = 25).
    pub max_lag: usize,
    /// Subtract the sample means of ε and u before computing covariances (default `true`; `false`
    /// is MATLAB's `covf`). See the module documentation.
    pub remove_mean: bool,
}

impl Default for ResidOptions {
    fn default() -> Self {
        Self {
            max_lag: DEFAULT_MAX_LAG,
            remove_mean: true,
        }
    }
}

/// Which of the two signals an error refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Signal {
    /// The prediction residuals ε.
    Residual,
    /// The input u.
    Input,
}

impl fmt::Display for Signal {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Signal::Residual => "residual",
            Signal::Input => "input",
        })
    }
}

/// Why a residual analysis cannot be computed.
#[derive(Debug, Clone, PartialEq)]
pub enum ResidError {
    /// The maximum lag M is 0.
    ZeroMaxLag,
    /// The maximum lag M is above [`MAX_LAG`].
    MaxLagTooLarge {
        /// M as asked for.
        max_lag: usize,
    },
    /// The (2M+1)² Gram matrix could not be allocated.
    OutOfMemory {
        /// Bytes asked for, 8(2M+1)².
        bytes: usize,
    },
    /// ε and u have different lengths.
    LengthMismatch {
        /// Number of residuals.
        residuals: usize,
        /// Number of inputs.
        input: usize,
    },
    /// Too few samples for the maximum lag: N ≥ 2(M+1) is required.
    TooShort {
        /// Number of samples N.
        n: usize,
        /// Requested maximum lag M.
        max_lag: usize,
        /// Smallest acceptable N, 2(M+1).
        required: usize,
    },
    /// A NaN or infinite value.
    NonFinite {
        /// Which signal.
        signal: Signal,
        /// 0-based index of the first non-finite value.
        index: usize,
        /// The value itself.
        value: f64,
    },
    /// R(0) = 0 (a constant signal, after mean removal if enabled): correlations are undefined.
    ZeroVariance {
        /// Which signal.
        signal: Signal,
    },
    /// The Gram matrix G of the lagged inputs (order 2M+1) is numerically singular, so the
    /// independence statistic cannot be formed.
    InputNotExciting {
        /// Order 2M+1 of G.
        order: usize,
        /// 0-based lag index (lag = index − M) at which the Cholesky pivot fell below [`MIN_PIVOT`].
        at: usize,
        /// That pivot.
        pivot: f64,
    },
}

impl fmt::Display for ResidError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ResidError::ZeroMaxLag => write!(f, "residual analysis: the maximum lag must be at least 1"),
            ResidError::MaxLagTooLarge { max_lag } => write!(
                f,
                "residual analysis: maximum lag {max_lag} is above {MAX_LAG} (the independence test \
                 factors a (2M+1)² matrix: O(M²) memory, O(M³) time; MATLAB's default is 25)"
            ),
            ResidError::OutOfMemory { bytes } => write!(
                f,
                "residual analysis: the lagged-input Gram matrix needs {bytes} bytes and the memory \
                 could not be allocated (lower the maximum lag)"
            ),
            ResidError::LengthMismatch { residuals, input } => write!(
                f,
                "residual analysis: {residuals} residuals but {input} input samples (must be equal)"
            ),
            ResidError::TooShort { n, max_lag, required } => write!(
                f,
                "residual analysis: {n} samples are too few for maximum lag {max_lag} \
                 (need at least {required} = 2(M+1); lower the maximum lag or use more data)"
            ),
            ResidError::NonFinite { signal, index, value } => write!(
                f,
                "residual analysis: {signal} sample {index} (0-based) is {value}, not a finite number"
            ),
            ResidError::ZeroVariance { signal } => write!(
                f,
                "residual analysis: the {signal} is constant (zero variance), so its correlations \
                 are undefined"
            ),
            // A non-finite pivot is an overflow of the input's lagged sums (|u| ~ 1e154 or more),
            // not a lack of excitation.
            ResidError::InputNotExciting { order, at, pivot } if !pivot.is_finite() => write!(
                f,
                "residual analysis: the input's lagged sums overflow (values too large: lagged-input \
                 matrix of the {order}-lag independence test not finite at lag index {at}, pivot \
                 {pivot}); rescale the input"
            ),
            ResidError::InputNotExciting { order, at, pivot } => write!(
                f,
                "residual analysis: the input does not excite all {order} lags of the \
                 independence test (lagged-input matrix singular at lag index {at}, pivot \
                 {pivot:.3e}); lower the maximum lag"
            ),
        }
    }
}

impl std::error::Error for ResidError {}

/// One lag and its correlation coefficient.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LagValue {
    /// The lag τ (for the cross-correlation: ε(t) against u(t−τ)).
    pub lag: i64,
    /// The correlation coefficient at that lag.
    pub value: f64,
}

/// The largest correlations in absolute value, for printing.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WorstLags {
    /// arg max_{τ=1..M} |r_ε(τ)| and its value.
    pub autocorrelation: LagValue,
    /// arg max_{τ=−M..M} |r_εu(τ)| and its value.
    pub cross_correlation: LagValue,
}

/// Result of [`analyze`]. Serialises with the field names below as JSON keys.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResidualAnalysis {
    /// Number of samples N.
    pub n: usize,
    /// Maximum lag M.
    pub max_lag: usize,
    /// Whether the sample means were subtracted ([`ResidOptions::remove_mean`]).
    pub mean_removed: bool,
    /// Sample mean ε̄ of the residuals (always reported; a bias the correlations may not show).
    pub residual_mean: f64,
    /// Sample standard deviation √R_e(0) of the residuals (1/N, about ε̄ when the mean is removed).
    pub residual_std: f64,
    /// Sample mean ū of the input.
    pub input_mean: f64,
    /// Per-lag 99 % band for plotting both correlations: [`Z_99`]/√N.
    pub bound: f64,
    /// r_ε(τ) for τ = 1..M (M values; r_ε(0) = 1 is left out).
    pub autocorrelation: Vec<f64>,
    /// r_εu(τ) for τ = −M..M (2M+1 values, lag −M first; index i is lag i − M).
    pub cross_correlation: Vec<f64>,
    /// Ljung–Box Q = N(N+2) Σ_{τ=1..M} r_ε(τ)²/(N−τ).
    pub ljung_box_q: f64,
    /// P(χ²(M) ≥ Q).
    pub ljung_box_p: f64,
    /// Degrees of freedom of the whiteness test, M.
    pub dof_whiteness: usize,
    /// Whiteness accepted: `ljung_box_p` ≥ [`SIGNIFICANCE`] and every |r_ε(τ)| within
    /// `joint_bound_whiteness`.
    pub white: bool,
    /// Independence statistic S = N cᵀ G⁻¹ c (input-whitened, see the module documentation).
    pub cross_statistic: f64,
    /// P(χ²(2M+1) ≥ S).
    pub cross_p: f64,
    /// Plain N Σ_{τ=−M..M} r_εu(τ)², valid against χ²(2M+1) only for a white input; informative.
    pub cross_statistic_plain: f64,
    /// P(χ²(2M+1) ≥ plain statistic); informative, not used for `independent`.
    pub cross_p_plain: f64,
    /// Degrees of freedom of the independence test, 2M+1.
    pub dof_independence: usize,
    /// Independence accepted: `cross_p` ≥ [`SIGNIFICANCE`] and every |r_εu(τ)| within
    /// `joint_bound_independence`.
    pub independent: bool,
    /// Joint 99 % band of the whiteness test's per-lag check: z/√N with z the two-sided normal point
    /// at α/M (Bonferroni over the M lags), so that a white residual has all M lags inside with
    /// probability ≥ 1 − α. `white` is false when any |r_ε(τ)| exceeds it, whatever Q says.
    #[serde(default)]
    pub joint_bound_whiteness: f64,
    /// Joint 99 % band of the independence test's per-lag check: z/√N at α/(2M+1) over the 2M+1 lags.
    /// `independent` is false when any |r_εu(τ)| exceeds it, whatever S says.
    #[serde(default)]
    pub joint_bound_independence: f64,
    /// The 1 − α point of χ²(2M+1) that S must exceed to reject. S ≤ N always (S = N·R²), so for
    /// N ≤ this value the portmanteau S cannot reject and the independence verdict rests on the
    /// per-lag check alone ([`ResidualAnalysis::portmanteau_can_reject`]).
    #[serde(default)]
    pub cross_statistic_critical: f64,
    /// Number of lags τ = 1..M with |r_ε(τ)| > `bound`.
    pub autocorrelation_outside: usize,
    /// Number of lags τ = −M..M with |r_εu(τ)| > `bound`.
    pub cross_correlation_outside: usize,
    /// A several-input model: the cross-correlation and independence test with every input, in the
    /// model's order (the first repeats the fields above). Empty (and absent from JSON) for one input.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub inputs: Vec<InputCorrelation>,
}

impl ResidualAnalysis {
    /// r_ε(τ) for 1 ≤ τ ≤ M, else `None`.
    pub fn autocorrelation_at(&self, lag: usize) -> Option<f64> {
        lag.checked_sub(1)
            .and_then(|i| self.autocorrelation.get(i))
            .copied()
    }

    /// r_εu(τ) (ε(t) against u(t−τ)) for −M ≤ τ ≤ M, else `None`.
    pub fn cross_correlation_at(&self, lag: i64) -> Option<f64> {
        let i = lag.checked_add(i64::try_from(self.max_lag).ok()?)?;
        usize::try_from(i)
            .ok()
            .and_then(|i| self.cross_correlation.get(i))
            .copied()
    }

    /// Whether the portmanteau independence statistic S can reject at all on this record: S = N·R² ≤ N
    /// (see the module documentation), so it can exceed the critical value
    /// [`ResidualAnalysis::cross_statistic_critical`] only when N does (audit s18 H-1: at M = 25 the 1 %
    /// point of χ²(51) is 77.4, and a 59-row record could never be called dependent by S).
    pub fn portmanteau_can_reject(&self) -> bool {
        (self.n as f64) > self.cross_statistic_critical
    }

    /// The largest maximum lag M′ ≤ M at which the portmanteau S can reject on N samples (N above the
    /// 1 − α point of χ²(2M′+1)), or `None` when not even M′ = 1 can (N ≤ 11.3).
    pub fn largest_decidable_lag(&self) -> Option<usize> {
        let nf = self.n as f64;
        (1..=self.max_lag)
            .rev()
            .find(|&m| chi2_isf(SIGNIFICANCE, (2 * m + 1) as f64) < nf)
    }

    /// The lag of largest |r_ε(τ)| over τ = 1..M and of largest |r_εu(τ)| over τ = −M..M (the
    /// smallest such lag on ties), with the signed coefficients.
    pub fn worst_lags(&self) -> WorstLags {
        WorstLags {
            autocorrelation: arg_max_abs(&self.autocorrelation, 1),
            cross_correlation: arg_max_abs(&self.cross_correlation, -(self.max_lag as i64)),
        }
    }
}

fn arg_max_abs(values: &[f64], first_lag: i64) -> LagValue {
    let mut best = LagValue {
        lag: first_lag,
        value: 0.0,
    };
    for (i, &v) in values.iter().enumerate() {
        if i == 0 || v.abs() > best.value.abs() {
            best = LagValue {
                lag: first_lag + i as i64,
                value: v,
            };
        }
    }
    best
}

/// Residual analysis with the default options (M = 25, means removed). See [`analyze`].
pub fn analyze_default(residuals: &[f64], input: &[f64]) -> Result<ResidualAnalysis, ResidError> {
    analyze(residuals, input, &ResidOptions::default())
}

/// Residual analysis of the residuals ε(k) of a model against the input u(k) (same rows, same
/// length N): auto- and cross-correlations up to lag M and the whiteness and independence tests.
/// All definitions are in the module documentation. Cost O(N·M + M³).
pub fn analyze(
    residuals: &[f64],
    input: &[f64],
    options: &ResidOptions,
) -> Result<ResidualAnalysis, ResidError> {
    let m = options.max_lag;
    check_max_lag(m)?;
    if residuals.len() != input.len() {
        return Err(ResidError::LengthMismatch {
            residuals: residuals.len(),
            input: input.len(),
        });
    }
    let n = residuals.len();
    let required = 2 * (m + 1);
    if n < required {
        return Err(ResidError::TooShort {
            n,
            max_lag: m,
            required,
        });
    }
    check_finite(residuals, Signal::Residual)?;
    check_finite(input, Signal::Input)?;

    let nf = n as f64;
    let residual_mean = residuals.iter().sum::<f64>() / nf;
    let input_mean = input.iter().sum::<f64>() / nf;
    let (e, v): (Vec<f64>, Vec<f64>) = if options.remove_mean {
        (
            residuals.iter().map(|x| x - residual_mean).collect(),
            input.iter().map(|x| x - input_mean).collect(),
        )
    } else {
        (residuals.to_vec(), input.to_vec())
    };
    let (ee, ev, ve, vv) = (
        lagged_sums(&e, &e, m),
        lagged_sums(&e, &v, m),
        lagged_sums(&v, &e, m),
        lagged_sums(&v, &v, 2 * m),
    );
    let peak = |x: &[f64]| x.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
    let (head, tail) = CovarianceSums::ends(n, m);
    finish(&CovarianceSums {
        n,
        max_lag: m,
        remove_mean: options.remove_mean,
        residual_mean,
        input_mean,
        ee,
        ev,
        ve,
        vv,
        head: v[..head].to_vec(),
        tail: v[n - tail..].to_vec(),
        residual_peak: peak(residuals),
        input_peak: peak(input),
    })
}

/// The sums a residual analysis is made of (see the module documentation), with e and v the centred
/// (or, without mean removal, raw) residual and input: by [`analyze`] from whole signals, or sample by
/// sample by a [`CovarianceAccumulator`] from a record too long to hold.
#[derive(Debug, Clone, PartialEq)]
pub struct CovarianceSums {
    /// N.
    pub n: usize,
    /// M.
    pub max_lag: usize,
    /// Whether ε̄ and ū were subtracted.
    pub remove_mean: bool,
    /// ε̄.
    pub residual_mean: f64,
    /// ū.
    pub input_mean: f64,
    /// Σ_k e(k) e(k−τ), τ = 0..M.
    pub ee: Vec<f64>,
    /// Σ_k e(k) v(k−τ), τ = 0..M.
    pub ev: Vec<f64>,
    /// Σ_k v(k) e(k−τ), τ = 0..M.
    pub ve: Vec<f64>,
    /// Σ_k v(k) v(k−s), s = 0..2M.
    pub vv: Vec<f64>,
    /// v(0..h), the first samples (see [`CovarianceSums::ends`]).
    pub head: Vec<f64>,
    /// v(N−t..N), the last samples.
    pub tail: Vec<f64>,
    /// max |ε(k)| of the raw residuals.
    pub residual_peak: f64,
    /// max |u(k)| of the raw input.
    pub input_peak: f64,
}

impl CovarianceSums {
    /// How many of the first and last input samples the end corrections of the lagged Gram matrix read:
    /// the terms v(a) v(a + s) left out at the start have a, a + s < −min(τ_i, τ_j) ≤ M, those at the
    /// end a, a + s ≥ N − max(τ_i, τ_j) ≥ N − M (see [`lagged_gram`]); so (M, M), at most N.
    pub fn ends(n: usize, m: usize) -> (usize, usize) {
        (m.min(n), m.min(n))
    }

    /// v(i) for an index the end corrections read.
    fn v_at(&self, i: usize) -> f64 {
        if i < self.head.len() {
            self.head[i]
        } else {
            let from = self.n - self.tail.len();
            self.tail.get(i.wrapping_sub(from)).copied().unwrap_or(0.0)
        }
    }
}

/// Σ_{k ≥ τ} a(k) b(k − τ) for τ = 0..=`max_lag`, each sum added in ascending k from 0.0 (the order
/// [`CovarianceAccumulator`] adds them in, so both give the same numbers bit for bit). [`LAG_BLOCK`] lags
/// at a time in registers: that many independent chains of additions, enough to keep the adders busy,
/// instead of one sum after the other, each waiting on its previous addition.
fn lagged_sums(a: &[f64], b: &[f64], max_lag: usize) -> Vec<f64> {
    const W: usize = LAG_BLOCK;
    let n = a.len().min(b.len());
    let mut out = vec![0.0; max_lag + 1];
    for t0 in (0..=max_lag).step_by(W) {
        let w = (max_lag + 1 - t0).min(W);
        let mut acc = [0.0f64; W];
        // k < t0 + w − 1: only the lags τ ≤ k have a term yet.
        let full = (t0 + w - 1).min(n);
        for k in t0..full {
            for (i, s) in acc.iter_mut().enumerate().take(w) {
                if k >= t0 + i {
                    *s += a[k] * b[k - t0 - i];
                }
            }
        }
        if w == W {
            for k in full..n {
                let (ak, back) = (a[k], &b[k - t0 + 1 - W..=k - t0]);
                for (s, bv) in acc.iter_mut().zip(back.iter().rev()) {
                    *s += ak * bv;
                }
            }
        } else {
            for k in full..n {
                for (i, s) in acc.iter_mut().enumerate().take(w) {
                    *s += a[k] * b[k - t0 - i];
                }
            }
        }
        out[t0..t0 + w].copy_from_slice(&acc[..w]);
    }
    out
}

/// Lags summed side by side in [`lagged_sums`].
const LAG_BLOCK: usize = 8;

/// The sums of a residual analysis accumulated sample by sample, for a record too long to hold: the
/// means ε̄ and ū (when removed) come from an earlier pass. The sums are added in the order [`analyze`]
/// adds them, so both give the same numbers bit for bit on the same signals.
#[derive(Debug, Clone)]
pub struct CovarianceAccumulator {
    sums: CovarianceSums,
    /// The last 2M + 1 values of e and v, each stored twice, at k mod (2M + 1) and 2M + 1 positions
    /// later, so that the values back from k are one contiguous slice (no division per product).
    e: Vec<f64>,
    v: Vec<f64>,
    /// k mod (2M + 1) for the next sample.
    at: usize,
    bad: Option<ResidError>,
}

impl CovarianceAccumulator {
    /// An empty accumulator for M = `options.max_lag` lags; `residual_mean` and `input_mean` are ε̄ and ū
    /// of the whole record (subtracted when `options.remove_mean`).
    pub fn new(options: &ResidOptions, residual_mean: f64, input_mean: f64) -> Self {
        // An M beyond [`MAX_LAG`] is refused by `finish`; nothing of its size is allocated.
        let refused = check_max_lag(options.max_lag).err();
        let m = if refused.is_some() {
            0
        } else {
            options.max_lag
        };
        CovarianceAccumulator {
            sums: CovarianceSums {
                n: 0,
                max_lag: m,
                remove_mean: options.remove_mean,
                residual_mean,
                input_mean,
                ee: vec![0.0; m + 1],
                ev: vec![0.0; m + 1],
                ve: vec![0.0; m + 1],
                vv: vec![0.0; 2 * m + 1],
                head: Vec::with_capacity(m),
                tail: Vec::new(),
                residual_peak: 0.0,
                input_peak: 0.0,
            },
            e: vec![0.0; 2 * (2 * m + 1)],
            v: vec![0.0; 2 * (2 * m + 1)],
            at: 0,
            bad: refused,
        }
    }

    /// Adds the next residual ε(k) and input u(k).
    #[inline]
    pub fn push(&mut self, residual: f64, input: f64) {
        let s = &mut self.sums;
        let k = s.n;
        s.n += 1;
        for (x, signal) in [(residual, Signal::Residual), (input, Signal::Input)] {
            if !x.is_finite() && self.bad.is_none() {
                self.bad = Some(ResidError::NonFinite {
                    signal,
                    index: k,
                    value: x,
                });
            }
        }
        s.residual_peak = s.residual_peak.max(residual.abs());
        s.input_peak = s.input_peak.max(input.abs());
        let (e, v) = if s.remove_mean {
            (residual - s.residual_mean, input - s.input_mean)
        } else {
            (residual, input)
        };
        let r = self.e.len() / 2;
        let at = self.at;
        self.at = if at + 1 == r { 0 } else { at + 1 };
        for (buf, x) in [(&mut self.e, e), (&mut self.v, v)] {
            buf[at] = x;
            buf[at + r] = x;
        }
        if s.head.len() < s.max_lag {
            s.head.push(v);
        }
        // e(k − τ) = e[at + r − τ]: the window of the last values, newest last.
        let lags = k.min(s.max_lag);
        let (ew, vw) = (
            &self.e[at + r - lags..=at + r],
            &self.v[at + r - lags..=at + r],
        );
        for (tau, (ej, vj)) in ew.iter().rev().zip(vw.iter().rev()).enumerate() {
            s.ee[tau] += e * ej;
            s.ev[tau] += e * vj;
            s.ve[tau] += v * ej;
        }
        let lags = k.min(2 * s.max_lag);
        for (lag, vj) in self.v[at + r - lags..=at + r].iter().rev().enumerate() {
            s.vv[lag] += v * vj;
        }
    }

    /// The analysis (the errors of [`analyze`]).
    pub fn finish(mut self) -> Result<ResidualAnalysis, ResidError> {
        let (n, m) = (self.sums.n, self.sums.max_lag);
        if let Some(e @ (ResidError::MaxLagTooLarge { .. } | ResidError::ZeroMaxLag)) = &self.bad {
            return Err(e.clone());
        }
        let required = 2 * (m + 1);
        if n < required {
            return Err(ResidError::TooShort {
                n,
                max_lag: m,
                required,
            });
        }
        if let Some(e) = self.bad {
            return Err(e);
        }
        let (_, tail) = CovarianceSums::ends(n, m);
        let r = self.v.len() / 2;
        self.sums.tail = (n - tail..n).map(|k| self.v[k % r]).collect();
        finish(&self.sums)
    }
}

/// The residual analysis from its sums (the checks of [`analyze`] that need them).
pub fn finish(s: &CovarianceSums) -> Result<ResidualAnalysis, ResidError> {
    let (n, m) = (s.n, s.max_lag);
    let nf = n as f64;
    // Covariances R(τ) = (1/N) Σ_k a(k) b(k−τ), τ ≥ 0.
    let re0 = s.ee[0] / nf;
    let rv0 = s.vv[0] / nf;
    check_variance(re0, s.residual_peak, Signal::Residual)?;
    check_variance(rv0, s.input_peak, Signal::Input)?;

    let autocorrelation: Vec<f64> = (1..=m).map(|tau| s.ee[tau] / nf / re0).collect();
    let scale = (re0 * rv0).sqrt();
    // Lag τ < 0: Σ_k e(k) v(k+|τ|) = Σ_j v(j) e(j−|τ|), the covariance of v against e at |τ|.
    let cross_correlation: Vec<f64> = (0..=2 * m)
        .map(|i| {
            if i < m {
                s.ve[m - i] / nf / scale
            } else {
                s.ev[i - m] / nf / scale
            }
        })
        .collect();
    // Whiteness: Ljung–Box.
    let ljung_box_q = nf
        * (nf + 2.0)
        * autocorrelation
            .iter()
            .enumerate()
            .map(|(i, r)| r * r / (nf - (i + 1) as f64))
            .sum::<f64>();
    let ljung_box_p = chi2_sf(ljung_box_q, m as f64);

    // Independence: S = N cᵀ G⁻¹ c with G the Gram matrix of the lagged inputs.
    let order = 2 * m + 1;
    let gram = lagged_gram(s, nf * rv0)?;
    let cross_statistic = nf * quadratic_form_inverse(&gram, &cross_correlation)?;
    let cross_p = chi2_sf(cross_statistic, order as f64);
    let cross_statistic_plain = nf * cross_correlation.iter().map(|r| r * r).sum::<f64>();
    let cross_p_plain = chi2_sf(cross_statistic_plain, order as f64);

    let bound = Z_99 / nf.sqrt();
    let joint_bound_whiteness = normal_two_sided_point(SIGNIFICANCE / m as f64) / nf.sqrt();
    // Under the hypothesis of both tests, "ε white and independent of u", each r_εu(τ) has variance
    // about 1/N whatever the input's colour (the statistic S has the same hypothesis).
    let joint_bound_independence = normal_two_sided_point(SIGNIFICANCE / order as f64) / nf.sqrt();
    let peak_abs = |r: &[f64]| r.iter().fold(0.0_f64, |a, r| a.max(r.abs()));
    let lags_white = peak_abs(&autocorrelation) <= joint_bound_whiteness;
    let lags_independent = peak_abs(&cross_correlation) <= joint_bound_independence;
    Ok(ResidualAnalysis {
        n,
        max_lag: m,
        mean_removed: s.remove_mean,
        residual_mean: s.residual_mean,
        residual_std: re0.sqrt(),
        input_mean: s.input_mean,
        bound,
        autocorrelation_outside: autocorrelation.iter().filter(|r| r.abs() > bound).count(),
        cross_correlation_outside: cross_correlation.iter().filter(|r| r.abs() > bound).count(),
        autocorrelation,
        cross_correlation,
        ljung_box_q,
        ljung_box_p,
        dof_whiteness: m,
        white: ljung_box_p >= SIGNIFICANCE && lags_white,
        cross_statistic,
        cross_p,
        cross_statistic_plain,
        cross_p_plain,
        dof_independence: order,
        independent: cross_p >= SIGNIFICANCE && lags_independent,
        joint_bound_whiteness,
        joint_bound_independence,
        cross_statistic_critical: chi2_isf(SIGNIFICANCE, order as f64),
        inputs: Vec::new(),
    })
}

/// The residuals against one input of a several-input model: the cross-correlation and the
/// independence test of [`analyze`] with that input.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputCorrelation {
    /// The input's name (its data column).
    pub name: String,
    /// Sample mean of the input.
    pub input_mean: f64,
    /// r_εu(τ) for τ = −M..M (lag −M first).
    pub cross_correlation: Vec<f64>,
    /// Independence statistic S (input-whitened).
    pub cross_statistic: f64,
    /// P(χ²(2M+1) ≥ S).
    pub cross_p: f64,
    /// Independence accepted: `cross_p` ≥ [`SIGNIFICANCE`] and every |r_εu(τ)| within the joint band.
    pub independent: bool,
    /// Number of lags with |r_εu(τ)| beyond the 99 % band.
    pub cross_correlation_outside: usize,
    /// arg max_τ |r_εu(τ)| and its value.
    pub worst: LagValue,
}

impl InputCorrelation {
    /// The input part of `a`, an analysis of the residuals against the input `name`.
    pub fn of(name: &str, a: &ResidualAnalysis) -> Self {
        InputCorrelation {
            name: name.to_string(),
            input_mean: a.input_mean,
            worst: a.worst_lags().cross_correlation,
            cross_correlation: a.cross_correlation.clone(),
            cross_statistic: a.cross_statistic,
            cross_p: a.cross_p,
            independent: a.independent,
            cross_correlation_outside: a.cross_correlation_outside,
        }
    }
}

fn check_finite(x: &[f64], signal: Signal) -> Result<(), ResidError> {
    match x.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(ResidError::NonFinite {
            signal,
            index,
            value: x[index],
        }),
        None => Ok(()),
    }
}

/// R(0) is "zero" when √R(0) is below 1e-12 of the signal's largest magnitude: after mean removal
/// of a constant signal only rounding noise of that order is left.
fn check_variance(r0: f64, peak: f64, signal: Signal) -> Result<(), ResidError> {
    if r0 <= 0.0 || r0.sqrt() <= 1e-12 * peak {
        Err(ResidError::ZeroVariance { signal })
    } else {
        Ok(())
    }
}

/// G_ij = (1/scale) Σ_{k=0..N−1} v(k−τ_i) v(k−τ_j), τ_i = i − M, with v = 0 outside 0..N−1, as a
/// row-major (2M+1)² matrix. With s = τ_i − τ_j the sum runs over a = k − τ_i in
/// [max(0, −τ_i, −s), min(N, N−τ_i, N−s)) of v(a) v(a+s): the full lag-s sum T(s) (a in
/// [max(0, −s), min(N, N−s))) minus at most M terms at each end. Cost O(N·M + M³). The matrix is
/// allocated fallibly ([`ResidError::OutOfMemory`]); M ≤ [`MAX_LAG`] keeps it at most 32 MB.
fn lagged_gram(sums: &CovarianceSums, scale: f64) -> Result<Vec<f64>, ResidError> {
    let m = sums.max_lag;
    let n = sums.n as i64;
    let mi = m as i64;
    let p = 2 * m + 1;
    // T(s) for s = 0..=2M; T(−s) = T(s).
    let full = &sums.vv;
    let term = |a: i64, s: i64| sums.v_at(a as usize) * sums.v_at((a + s) as usize);
    let oom = || ResidError::OutOfMemory {
        bytes: p
            .saturating_mul(p)
            .saturating_mul(std::mem::size_of::<f64>()),
    };
    let mut g: Vec<f64> = Vec::new();
    g.try_reserve_exact(p.checked_mul(p).ok_or_else(oom)?)
        .map_err(|_| oom())?;
    g.resize(p * p, 0.0);
    for i in 0..p {
        for j in 0..=i {
            let (ti, tj) = (i as i64 - mi, j as i64 - mi);
            let s = ti - tj;
            let (full_lo, full_hi) = (0.max(-s), n.min(n - s));
            let lo = full_lo.max(-ti);
            let hi = full_hi.min(n - ti);
            // N ≥ 2(M+1) keeps [lo, hi) non-empty (k in [max(0, τ_i, τ_j), N − max(0, −τ_i, −τ_j))).
            let sum = if hi > lo {
                let head: f64 = (full_lo..lo).map(|a| term(a, s)).sum();
                let tail: f64 = (hi..full_hi).map(|a| term(a, s)).sum();
                full[s.unsigned_abs() as usize] - head - tail
            } else {
                0.0
            };
            g[i * p + j] = sum / scale;
            g[j * p + i] = sum / scale;
        }
    }
    Ok(g)
}

/// cᵀ G⁻¹ c for a symmetric positive definite row-major G, by nalgebra's Cholesky G = L Lᵀ and forward
/// substitution L y = c: cᵀ G⁻¹ c = |y|². A pivot d_j = G_jj − Σ_{k<j} L_jk² (= L_jj²) below
/// [`MIN_PIVOT`] is an error.
fn quadratic_form_inverse(g: &[f64], c: &[f64]) -> Result<f64, ResidError> {
    let p = c.len();
    let g = DMatrix::from_row_slice(p, p, g);
    // Unchecked: a failed pivot is found below, with its value, instead of a bare `None`.
    let l = Cholesky::new_unchecked(g.clone()).l_dirty().clone_owned();
    for j in 0..p {
        let d = g[(j, j)] - l.view((j, 0), (1, j)).norm_squared();
        if d.is_nan() || d <= MIN_PIVOT {
            return Err(ResidError::InputNotExciting {
                order: p,
                at: j,
                pivot: d,
            });
        }
    }
    let y = l
        .solve_lower_triangular(&DVector::from_column_slice(c))
        .ok_or(ResidError::InputNotExciting {
            order: p,
            at: 0,
            pivot: f64::NAN,
        })?;
    Ok(y.norm_squared())
}

/// Survival function of the χ² distribution with `dof` degrees of freedom:
/// P(X ≥ x) = Q(dof/2, x/2), with Q the regularised upper incomplete gamma function
/// ([`gamma_q`]). Returns 1 for x ≤ 0 and NaN when `dof` ≤ 0 or an argument is NaN.
pub fn chi2_sf(x: f64, dof: f64) -> f64 {
    if x.is_nan() || dof.is_nan() || dof <= 0.0 {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 1.0;
    }
    gamma_q(0.5 * dof, 0.5 * x)
}

/// The x with P(χ²(`dof`) ≥ x) = `p` (0 < p < 1), by bisection on [`chi2_sf`] to a relative 1e-12:
/// the 1 − p point of χ²(dof). NaN outside the domain.
pub fn chi2_isf(p: f64, dof: f64) -> f64 {
    if !(p > 0.0 && p < 1.0) || dof.is_nan() || dof <= 0.0 {
        return f64::NAN;
    }
    let mut hi = dof.max(1.0);
    while chi2_sf(hi, dof) > p {
        hi *= 2.0;
        if !hi.is_finite() {
            return f64::NAN;
        }
    }
    let mut lo = 0.0;
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi2_sf(mid, dof) > p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// The z > 0 with P(|Z| ≥ z) = `p` for a standard normal Z: |Z|² is χ²(1), so z = √(χ²(1) 1 − p point).
pub fn normal_two_sided_point(p: f64) -> f64 {
    chi2_isf(p, 1.0).sqrt()
}

/// Regularised upper incomplete gamma function
/// Q(a, x) = Γ(a, x)/Γ(a) = (1/Γ(a)) ∫_x^∞ t^(a−1) e^(−t) dt, for a > 0, x ≥ 0.
///
/// For x < a + 1 by the series P(a, x) = e^(−x) x^a Σ_{n≥0} x^n / Γ(a+n+1), Q = 1 − P; otherwise by
/// the continued fraction Q = e^(−x) x^a / Γ(a) · 1/(x+1−a− 1·(1−a)/(x+3−a− 2·(2−a)/(x+5−a− …)))
/// evaluated with the modified Lentz method (Numerical Recipes, 3rd ed., §6.2). Relative accuracy
/// about 1e-14 for moderate a. Returns NaN outside the domain.
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if a.is_nan() || a <= 0.0 || a.is_infinite() || x.is_nan() || x < 0.0 {
        return f64::NAN;
    }
    if x == 0.0 {
        return 1.0;
    }
    if x.is_infinite() {
        return 0.0;
    }
    const MAX_ITER: usize = 100_000;
    let log_prefactor = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        let mut ap = a;
        let mut term = 1.0 / a;
        let mut sum = term;
        for _ in 0..MAX_ITER {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * f64::EPSILON {
                break;
            }
        }
        (1.0 - sum * log_prefactor.exp()).clamp(0.0, 1.0)
    } else {
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..MAX_ITER {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < f64::EPSILON {
                break;
            }
        }
        (log_prefactor.exp() * h).clamp(0.0, 1.0)
    }
}

/// ln Γ(x) for x > 0 by the Lanczos approximation (g = 7, 9 coefficients; relative error ~1e-15),
/// with the reflection formula below 1/2.
fn ln_gamma(x: f64) -> f64 {
    const G: f64 = 7.0;
    const COEF: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        // Γ(x) Γ(1−x) = π / sin(πx)
        let pi = std::f64::consts::PI;
        return (pi / (pi * x).sin()).abs().ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let mut s = COEF[0];
    for (i, c) in COEF.iter().enumerate().skip(1) {
        s += c / (x + i as f64);
    }
    let t = x + G + 0.5;
    0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + s.ln()
}

/// The residual analysis of `model` on `data`: the one-step prediction residuals
/// ε(k) = y(k) − ŷ(k|k−1) (the model's own predictor: equation error for ARX-type estimates, output
/// error for the output-error method), rows k ≥ k0, analysed against the input of the same rows with
/// `max_lag` lags ([`analyze`]). The top-level cross-correlation is with the first input; with several
/// inputs `inputs` holds the cross-correlation and independence test with each input. `Err` says why
/// there is none (record too short for the lags, constant residuals...).
pub fn residual_analysis(
    model: &sysid_core::Model,
    data: &sysid_core::Dataset,
    max_lag: usize,
) -> Result<ResidualAnalysis, String> {
    residual_analysis_scored_from(model, data, max_lag, 0)
}

/// [`residual_analysis`] of the rows k ≥ max(K, k0) only, K = `score_from`
/// ([`sysid_core::metrics::first_scored`], the rows every validation figure is scored on): the
/// residuals and the input of those rows, the same predictions.
pub fn residual_analysis_scored_from(
    model: &sysid_core::Model,
    data: &sysid_core::Dataset,
    max_lag: usize,
    score_from: usize,
) -> Result<ResidualAnalysis, String> {
    let ks = sysid_core::metrics::first_scored(model.k0(), score_from).min(data.len());
    let options = ResidOptions {
        max_lag,
        ..ResidOptions::default()
    };
    let (u, y) = (data.input_signals(), data.y());
    let pred = sysid_core::metrics::one_step_prediction(model, data).map_err(|e| e.to_string())?;
    let eps: Vec<f64> = y[ks..]
        .iter()
        .zip(&pred[ks..])
        .map(|(y, p)| y - p)
        .collect();
    let u0 = u.first().map_or(&[][..], |u| &u[ks..]);
    let mut a = analyze(&eps, u0, &options).map_err(|e| e.to_string())?;
    if u.len() > 1 {
        for (ui, ch) in u.iter().zip(model.inputs()) {
            let ai = analyze(&eps, &ui[ks..], &options)
                .map_err(|e| format!("input {}: {e}", ch.name()))?;
            a.inputs.push(InputCorrelation::of(ch.name(), &ai));
        }
    }
    Ok(a)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Standard normal sample (rand_distr, a test-only dependency).
    fn gauss(rng: &mut ChaCha8Rng) -> f64 {
        rng.sample(rand_distr::StandardNormal)
    }

    fn white(rng: &mut ChaCha8Rng, n: usize) -> Vec<f64> {
        (0..n).map(|_| gauss(rng)).collect()
    }

    /// x(k) = a x(k−1) + w(k), started at 0 after a burn-in of 200 samples.
    fn ar1(rng: &mut ChaCha8Rng, n: usize, a: f64) -> Vec<f64> {
        let mut x = 0.0;
        let mut out = Vec::with_capacity(n);
        for k in 0..n + 200 {
            x = a * x + gauss(rng);
            if k >= 200 {
                out.push(x);
            }
        }
        out
    }

    fn opts(max_lag: usize, remove_mean: bool) -> ResidOptions {
        ResidOptions {
            max_lag,
            remove_mean,
        }
    }

    fn rel_close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * b.abs().max(1.0)
    }

    // ---------- hand-computed case ----------

    // G = [[2, 1], [1, 2]] has G⁻¹ = (1/3) [[2, −1], [−1, 2]], so cᵀ G⁻¹ c = (2 − 1 − 1 + 2)/3 = 2/3 for
    // c = (1, 1); [[1, 1], [1, 1]] has the pivot 1 − 1² = 0 at index 1 and [[1, 2], [2, 1]] the pivot
    // 1 − 2² = −3 there.
    #[test]
    fn quadratic_form_of_the_inverse_by_hand_and_its_failed_pivots() {
        let q = quadratic_form_inverse(&[2.0, 1.0, 1.0, 2.0], &[1.0, 1.0]).unwrap();
        assert!((q - 2.0 / 3.0).abs() < 1e-15, "{q}");
        for (g, pivot) in [([1.0, 1.0, 1.0, 1.0], 0.0), ([1.0, 2.0, 2.0, 1.0], -3.0)] {
            let e = quadratic_form_inverse(&g, &[1.0, 1.0]).unwrap_err();
            assert_eq!(
                e,
                ResidError::InputNotExciting {
                    order: 2,
                    at: 1,
                    pivot
                }
            );
        }
    }

    #[test]
    fn alternating_residual_against_impulse_input_by_hand() {
        // ε = 1, −1, 1, … (N = 12, mean exactly 0); u = unit impulse at k = 5; raw covariances.
        let n = 12;
        let eps: Vec<f64> = (0..n)
            .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let mut u = vec![0.0; n];
        u[5] = 1.0;
        let a = analyze(&eps, &u, &opts(3, false)).unwrap();
        // R_ε(0) = 1, R_ε(τ) = (−1)^τ (N−τ)/N.
        assert_eq!(a.autocorrelation.len(), 3);
        assert!((a.autocorrelation[0] - (-11.0 / 12.0)).abs() < 1e-15);
        assert!((a.autocorrelation[1] - (10.0 / 12.0)).abs() < 1e-15);
        assert!((a.autocorrelation[2] - (-9.0 / 12.0)).abs() < 1e-15);
        // Q = N(N+2) Σ ((N−τ)/N)²/(N−τ) = (N+2)/N Σ (N−τ) = 14/12 · (11+10+9) = 35.
        assert!((a.ljung_box_q - 35.0).abs() < 1e-12, "{}", a.ljung_box_q);
        // χ²(3) survival in closed form: erfc(√(x/2)) + √(2x/π) e^(−x/2); at 35 it is ~1.2e-7.
        assert!(!a.white);
        // R_εu(τ) = ε(5+τ)/N, R_u(0) = 1/N: r_εu(τ) = ε(5+τ)/√N = (−1)^(5+τ)/√12.
        for (i, r) in a.cross_correlation.iter().enumerate() {
            let tau = i as i64 - 3;
            let sign = if (5 + tau) % 2 == 0 { 1.0 } else { -1.0 };
            assert!((r - sign / 12f64.sqrt()).abs() < 1e-15, "lag {tau}: {r}");
        }
        // The lagged copies of the impulse are distinct unit vectors: G = I/(N R_u(0)) = I, and
        // S = N Σ r² = 7 · N/12 = 7 = plain statistic.
        assert!((a.cross_statistic - 7.0).abs() < 1e-12);
        assert!((a.cross_statistic_plain - 7.0).abs() < 1e-12);
        assert_eq!(a.dof_independence, 7);
        assert!(a.independent);
        assert_eq!(a.bound, 2.58 / 12f64.sqrt());
        // The mean of ε is 0 and centring changes the input: centred impulse v = δ − 1/12.
        let c = analyze(&eps, &u, &opts(3, true)).unwrap();
        assert_eq!(c.autocorrelation, a.autocorrelation);
        assert_eq!(c.residual_mean, 0.0);
        assert!((c.input_mean - 1.0 / 12.0).abs() < 1e-16);
    }

    #[test]
    fn hand_ljung_box_for_general_alternating_length() {
        // For ε = ±1 alternating of even length N: r(τ) = (−1)^τ (N−τ)/N, Q = (N+2)/N Σ_τ (N−τ).
        for &(n, m) in &[(8usize, 3usize), (20, 5), (50, 10)] {
            let eps: Vec<f64> = (0..n)
                .map(|k| if k % 2 == 0 { 1.0 } else { -1.0 })
                .collect();
            let u: Vec<f64> = (0..n).map(|k| ((k * 7) % 5) as f64).collect();
            let a = analyze(&eps, &u, &opts(m, true)).unwrap();
            let nf = n as f64;
            assert!((a.autocorrelation[0] + (nf - 1.0) / nf).abs() < 1e-14);
            let q: f64 = (1..=m).map(|t| nf - t as f64).sum::<f64>() * (nf + 2.0) / nf;
            assert!(
                rel_close(a.ljung_box_q, q, 1e-13),
                "{} vs {q}",
                a.ljung_box_q
            );
        }
    }

    // ---------- independent naive implementation ----------

    /// Naive: explicit double sums over all index pairs (i, j) with i − j = τ; the whitened
    /// statistic from the explicit N×(2M+1) matrix U of zero-padded lagged inputs, G = UᵀU/(N R_u(0))
    /// by dot products of its columns, solved by Gauss–Jordan elimination with partial pivoting.
    #[allow(clippy::needless_range_loop)] // index arithmetic is the point of this version
    fn naive(
        eps: &[f64],
        u: &[f64],
        m: usize,
        remove_mean: bool,
    ) -> (Vec<f64>, Vec<f64>, f64, f64, f64) {
        let n = eps.len();
        let (me, mu) = if remove_mean {
            (
                eps.iter().sum::<f64>() / n as f64,
                u.iter().sum::<f64>() / n as f64,
            )
        } else {
            (0.0, 0.0)
        };
        let big_r = |x: &[f64], mx: f64, y: &[f64], my: f64, tau: i64| -> f64 {
            let mut s = 0.0;
            for i in 0..n {
                for j in 0..n {
                    if i as i64 - j as i64 == tau {
                        s += (x[i] - mx) * (y[j] - my);
                    }
                }
            }
            s / n as f64
        };
        let re0 = big_r(eps, me, eps, me, 0);
        let ru0 = big_r(u, mu, u, mu, 0);
        let auto: Vec<f64> = (1..=m as i64)
            .map(|t| big_r(eps, me, eps, me, t) / re0)
            .collect();
        let cross: Vec<f64> = (-(m as i64)..=m as i64)
            .map(|t| big_r(eps, me, u, mu, t) / (re0 * ru0).sqrt())
            .collect();
        let nf = n as f64;
        let mut q = 0.0;
        for (k, r) in auto.iter().enumerate() {
            q += r * r / (nf - (k + 1) as f64);
        }
        q *= nf * (nf + 2.0);
        let p = 2 * m + 1;
        let cols: Vec<Vec<f64>> = (0..p)
            .map(|i| {
                let tau = i as i64 - m as i64;
                (0..n as i64)
                    .map(|k| {
                        if (0..n as i64).contains(&(k - tau)) {
                            u[(k - tau) as usize] - mu
                        } else {
                            0.0
                        }
                    })
                    .collect()
            })
            .collect();
        let mut a = vec![vec![0.0; p + 1]; p];
        for i in 0..p {
            for j in 0..p {
                a[i][j] = cols[i]
                    .iter()
                    .zip(&cols[j])
                    .map(|(x, y)| x * y)
                    .sum::<f64>()
                    / (nf * ru0);
            }
            a[i][p] = cross[i];
        }
        for col in 0..p {
            let piv = (col..p)
                .max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))
                .unwrap();
            a.swap(col, piv);
            for row in 0..p {
                if row != col {
                    let f = a[row][col] / a[col][col];
                    for k in col..=p {
                        a[row][k] -= f * a[col][k];
                    }
                }
            }
        }
        let s: f64 = (0..p).map(|i| cross[i] * a[i][p] / a[i][i]).sum::<f64>() * nf;
        let plain = nf * cross.iter().map(|r| r * r).sum::<f64>();
        (auto, cross, q, s, plain)
    }

    #[test]
    fn matches_naive_double_sums() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for &(n, m, remove_mean) in &[
            (120usize, 8usize, true),
            (120, 8, false),
            (61, 5, true),
            (300, 25, true),
        ] {
            let u: Vec<f64> = ar1(&mut rng, n, 0.7).iter().map(|x| 3.0 + x).collect();
            let w = white(&mut rng, n);
            let eps: Vec<f64> = (0..n)
                .map(|k| w[k] + 0.1 + if k >= 2 { 0.3 * u[k - 2] } else { 0.0 })
                .collect();
            let a = analyze(&eps, &u, &opts(m, remove_mean)).unwrap();
            let (auto, cross, q, s, plain) = naive(&eps, &u, m, remove_mean);
            assert_eq!(a.autocorrelation.len(), m);
            assert_eq!(a.cross_correlation.len(), 2 * m + 1);
            for (x, y) in a.autocorrelation.iter().zip(&auto) {
                assert!((x - y).abs() < 1e-12, "{x} vs {y}");
            }
            for (x, y) in a.cross_correlation.iter().zip(&cross) {
                assert!((x - y).abs() < 1e-12, "{x} vs {y}");
            }
            assert!(
                rel_close(a.ljung_box_q, q, 1e-12),
                "{} vs {q}",
                a.ljung_box_q
            );
            assert!(
                rel_close(a.cross_statistic, s, 1e-10),
                "{} vs {s}",
                a.cross_statistic
            );
            assert!(rel_close(a.cross_statistic_plain, plain, 1e-12));
            assert_eq!(a.n, n);
            assert_eq!(a.dof_whiteness, m);
        }
    }

    // ---------- χ² survival function ----------

    #[test]
    fn chi2_upper_one_percent_points() {
        // Quantiles computed with mpmath 1.3 (30 digits, findroot on gammainc(k/2, x/2, inf)); the
        // printed tables give 6.635, 44.314 and 77.386.
        for &(dof, x) in &[
            (1.0, 6.634_896_601_021_215),
            (25.0, 44.314_104_896_219_17),
            (51.0, 77.385_962_016_137_26),
            (10.0, 23.209_251_158_954_36),
            (100.0, 135.806_723_171_026_8),
        ] {
            let p = chi2_sf(x, dof);
            assert!((p - 0.01).abs() < 1e-12, "dof {dof}: {p}");
        }
        // The 3-decimal table values, within the rounding of the table.
        assert!((chi2_sf(44.314, 25.0) - 0.01).abs() < 1e-6);
        assert!((chi2_sf(77.386, 51.0) - 0.01).abs() < 1e-6);
        assert!((chi2_sf(6.635, 1.0) - 0.01).abs() < 1e-6);
    }

    #[test]
    fn chi2_other_values_from_mpmath() {
        for &(dof, x, q) in &[
            (25.0, 10.0, 0.996_652_640_733_739),
            (51.0, 120.0, 1.728_891_860_823_370_2e-7),
            (3.0, 0.5, 0.918_891_411_654_675_8),
            (7.0, 30.0, 9.495_972_508_134_183e-5),
            (101.0, 60.0, 0.999_605_863_704_472_2),
            (1.0, 0.01, 0.920_344_325_445_942),
        ] {
            assert!(
                rel_close(chi2_sf(x, dof), q, 1e-11) && (chi2_sf(x, dof) / q - 1.0).abs() < 1e-10,
                "dof {dof}, x {x}: {} vs {q}",
                chi2_sf(x, dof)
            );
        }
    }

    #[test]
    fn chi2_even_dof_closed_form() {
        // dof = 2m: P(X ≥ x) = e^(−x/2) Σ_{j<m} (x/2)^j / j!  (Poisson tail), both algorithm branches.
        for m in [1usize, 2, 5, 13, 25, 26] {
            for &x in &[0.1, 1.0, 3.0, 10.0, 2.0 * m as f64, 40.0, 77.0, 150.0] {
                let h = x / 2.0;
                let mut term = 1.0;
                let mut sum = 1.0;
                for j in 1..m {
                    term *= h / j as f64;
                    sum += term;
                }
                let exact = (-h).exp() * sum;
                let got = chi2_sf(x, 2.0 * m as f64);
                assert!(
                    (got / exact - 1.0).abs() < 1e-11,
                    "dof {}, x {x}: {got} vs {exact}",
                    2 * m
                );
            }
        }
        assert!((chi2_sf(3.0, 2.0) - (-1.5f64).exp()).abs() < 1e-15);
    }

    #[test]
    fn chi2_edges_and_ln_gamma() {
        assert_eq!(chi2_sf(0.0, 5.0), 1.0);
        assert_eq!(chi2_sf(-1.0, 5.0), 1.0);
        assert!(chi2_sf(1.0, 0.0).is_nan());
        assert!(chi2_sf(f64::NAN, 3.0).is_nan());
        assert_eq!(chi2_sf(f64::INFINITY, 3.0), 0.0);
        assert!(gamma_q(-1.0, 1.0).is_nan());
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-14);
        let mut fact = 1.0f64;
        for k in 1..30 {
            // Γ(k) = (k−1)!
            assert!(
                (ln_gamma(k as f64) - fact.ln()).abs() < 1e-13 * fact.ln().max(1.0),
                "k {k}"
            );
            fact *= k as f64;
        }
        // Γ(0.25) = 3.625609908221908311930685…
        assert!((ln_gamma(0.25) - 3.625_609_908_221_908_f64.ln()).abs() < 1e-14);
    }

    // ---------- statistical behaviour ----------

    #[test]
    fn white_noise_passes_in_most_seeds() {
        let (n, mut white_ok, mut indep_ok) = (1000, 0, 0);
        for seed in 0..100 {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 + seed);
            let eps = white(&mut rng, n);
            let u: Vec<f64> = white(&mut rng, n).iter().map(|x| 50.0 + 10.0 * x).collect();
            let a = analyze_default(&eps, &u).unwrap();
            white_ok += a.white as usize;
            indep_ok += a.independent as usize;
            // For a white input whitened and plain statistics nearly coincide.
            assert!((a.cross_statistic / a.cross_statistic_plain - 1.0).abs() < 0.25);
        }
        // Each test rejects a true hypothesis with probability 1 %: ≥ 95 of 100 fails with
        // probability < 1e-3 per test.
        assert!(white_ok >= 95, "white in {white_ok}/100");
        assert!(indep_ok >= 95, "independent in {indep_ok}/100");
    }

    // χ²(2) has P(X ≥ x) = e^(−x/2), so its 1 − p point is −2 ln p; χ²(1) is Z², so its 1 % point is
    // 2.5758293035489² (normal table); χ²(51) at 1 % is 77.385962 (Wilson–Hilferty gives 77.39; scipy
    // chi2.isf 77.38596201613733).
    #[test]
    fn chi_square_points_match_closed_forms_and_tables() {
        for p in [0.5, 0.1, 0.01, 1e-6] {
            let x = chi2_isf(p, 2.0);
            assert!(rel_close(x, -2.0 * f64::ln(p), 1e-10), "p {p}: {x}");
        }
        assert!((normal_two_sided_point(0.01) - 2.575_829_303_548_9).abs() < 1e-9);
        assert!((chi2_isf(0.01, 51.0) - 77.385_962_016).abs() < 1e-6);
        assert!(chi2_isf(0.0, 3.0).is_nan() && chi2_isf(0.5, 0.0).is_nan());
    }

    // Audit s18 H-1. S = N·R² ≤ N, and the 1 % point of χ²(51) is 77.39: on N = 59 rows with M = 25 the
    // portmanteau cannot reject, whatever the residual. A wrong delay leaves ε(k) = w(k) + 0.9 u(k−4)
    // (u, w white, unit variance): r_εu(4) ≈ 0.9/√1.81 = 0.67, far outside the joint band
    // 3.724/√59 = 0.485 (normal point at 0.01/51, two-sided), so the per-lag check rejects.
    #[test]
    fn short_record_wrong_delay_is_not_independent_although_s_cannot_reject() {
        let n = 59;
        let mut rejected = 0;
        for seed in 0..20 {
            let mut rng = ChaCha8Rng::seed_from_u64(4200 + seed);
            let u = white(&mut rng, n);
            let w = white(&mut rng, n);
            let eps: Vec<f64> = (0..n)
                .map(|k| w[k] + if k >= 4 { 0.9 * u[k - 4] } else { 0.0 })
                .collect();
            let a = analyze_default(&eps, &u).unwrap();
            assert!(a.cross_statistic <= n as f64 * (1.0 + 1e-12));
            assert!(
                a.cross_p >= SIGNIFICANCE,
                "S = {} alone rejects",
                a.cross_statistic
            );
            assert!(!a.portmanteau_can_reject());
            assert!((a.cross_statistic_critical - 77.385_962).abs() < 1e-5);
            assert!((a.joint_bound_independence - 3.724_016 / (n as f64).sqrt()).abs() < 1e-6);
            // 57.34 (M = 17) < 59 < 59.89 (M = 18): scipy chi2.isf(0.01, 35) and (0.01, 37).
            assert_eq!(a.largest_decidable_lag(), Some(17));
            rejected += (!a.independent) as usize;
        }
        // |r_εu(4)| has mean ≈ 0.67 and sd ≈ 0.1 at N = 59: below 0.485 in a few % of records at most
        // (before the per-lag check: in every record, S ≤ N).
        assert!(rejected >= 17, "rejected in {rejected}/20");
    }

    // The per-lag check must not make a correct model fail more often: with a white ε independent of
    // u (white, or AR(1) with pole 0.9), short and long records, the joint bands (Bonferroni) keep each
    // verdict's false rejections near α = 1 %; 400 records with 1 % have P(≥ 13 rejections) < 1e-3.
    #[test]
    fn per_lag_checks_keep_the_level_of_a_correct_model() {
        for (n, coloured) in [(60, false), (60, true), (400, true)] {
            let (mut not_white, mut not_indep) = (0, 0);
            for seed in 0..400 {
                let mut rng = ChaCha8Rng::seed_from_u64(9000 + seed);
                let eps = white(&mut rng, n);
                let u = if coloured {
                    ar1(&mut rng, n, 0.9)
                } else {
                    white(&mut rng, n)
                };
                let a = analyze_default(&eps, &u).unwrap();
                not_white += (!a.white) as usize;
                not_indep += (!a.independent) as usize;
            }
            assert!(not_white <= 12, "N {n}: not white in {not_white}/400");
            assert!(not_indep <= 12, "N {n}: not independent in {not_indep}/400");
        }
    }

    #[test]
    fn coloured_input_needs_the_whitened_statistic() {
        // ε white, u an AR(1) with pole 0.9 independent of ε: the whitened S keeps its 1 % level,
        // the plain N Σ r² does not (its variance is 2 tr(P²) instead of 2(2M+1)).
        let (n, mut indep_ok, mut plain_rejects) = (1000, 0, 0);
        for seed in 0..100 {
            let mut rng = ChaCha8Rng::seed_from_u64(5000 + seed);
            let eps = white(&mut rng, n);
            let u = ar1(&mut rng, n, 0.9);
            let a = analyze_default(&eps, &u).unwrap();
            indep_ok += a.independent as usize;
            plain_rejects += (a.cross_p_plain < SIGNIFICANCE) as usize;
        }
        assert!(indep_ok >= 95, "independent in {indep_ok}/100");
        // A calibrated 1 % test reaches 5 rejections in 100 with probability 0.3 %.
        assert!(
            plain_rejects >= 5,
            "plain statistic rejected only {plain_rejects}/100"
        );
    }

    #[test]
    fn square_wave_pwm_input_keeps_the_level() {
        // A PWM-like square wave (period 40, random phase, offset 500) independent of a white ε:
        // strongly coloured and nearly periodic, yet S stays calibrated.
        let (n, mut indep_ok, mut plain_rejects) = (1000, 0, 0);
        for seed in 0..100 {
            let mut rng = ChaCha8Rng::seed_from_u64(7000 + seed);
            let eps = white(&mut rng, n);
            let phase = rng.gen_range(0..40);
            let u: Vec<f64> = (0..n)
                .map(|k| if (k + phase) % 40 < 20 { 520.0 } else { 480.0 })
                .collect();
            let a = analyze_default(&eps, &u).unwrap();
            indep_ok += a.independent as usize;
            plain_rejects += (a.cross_p_plain < SIGNIFICANCE) as usize;
        }
        assert!(indep_ok >= 95, "independent in {indep_ok}/100");
        // A calibrated 1 % test reaches 5 rejections in 100 with probability 0.3 %.
        assert!(
            plain_rejects >= 5,
            "plain statistic rejected only {plain_rejects}/100"
        );
    }

    // The accumulator adds the same products in the same order as `analyze` (itself checked against the
    // naive double sums above), so both give identical analyses, at the shortest allowed record
    // (N = 2(M+1), where the first and last M samples overlap) and on a long one, with and without
    // mean removal; and the accumulator refuses a short record as `analyze` does.
    #[test]
    fn accumulated_sums_give_the_same_analysis_as_the_whole_signals() {
        let mut rng = ChaCha8Rng::seed_from_u64(77);
        for (n, m, remove_mean) in [(12, 5, true), (3000, 25, true), (500, 7, false)] {
            let eps: Vec<f64> = ar1(&mut rng, n, 0.3).iter().map(|e| e + 0.2).collect();
            let u: Vec<f64> = ar1(&mut rng, n, 0.8).iter().map(|x| 100.0 + x).collect();
            let o = opts(m, remove_mean);
            let want = analyze(&eps, &u, &o).unwrap();
            let mean = |x: &[f64]| x.iter().sum::<f64>() / n as f64;
            let mut acc = CovarianceAccumulator::new(&o, mean(&eps), mean(&u));
            for (e, x) in eps.iter().zip(&u) {
                acc.push(*e, *x);
            }
            assert_eq!(acc.finish().unwrap(), want, "n = {n}, M = {m}");
        }
        let mut acc = CovarianceAccumulator::new(&opts(5, true), 0.0, 0.0);
        for k in 0..11 {
            acc.push(k as f64, (k * k) as f64);
        }
        assert!(matches!(
            acc.finish(),
            Err(ResidError::TooShort { n: 11, .. })
        ));
    }

    #[test]
    fn ar1_residual_is_not_white() {
        for seed in 0..10 {
            let mut rng = ChaCha8Rng::seed_from_u64(200 + seed);
            let eps = ar1(&mut rng, 1000, 0.5);
            let u = white(&mut rng, 1000);
            let a = analyze_default(&eps, &u).unwrap();
            assert!(!a.white, "seed {seed}: Q = {}", a.ljung_box_q);
            assert!(a.ljung_box_p < 1e-10);
            let worst = a.worst_lags().autocorrelation;
            assert_eq!(worst.lag, 1);
            assert!((worst.value - 0.5).abs() < 0.1, "{}", worst.value);
        }
    }

    #[test]
    fn residual_with_filtered_input_is_not_independent() {
        for seed in 0..10 {
            let mut rng = ChaCha8Rng::seed_from_u64(300 + seed);
            let n = 1000;
            let u = white(&mut rng, n);
            let w = white(&mut rng, n);
            // ε(k) = w(k) + 0.3 (u(k−3) + 0.5 u(k−4)): unmodelled dynamics from u to y.
            let eps: Vec<f64> = (0..n)
                .map(|k| {
                    w[k] + if k >= 4 {
                        0.3 * (u[k - 3] + 0.5 * u[k - 4])
                    } else {
                        0.0
                    }
                })
                .collect();
            let a = analyze_default(&eps, &u).unwrap();
            assert!(!a.independent, "seed {seed}: S = {}", a.cross_statistic);
            // Sign convention: ε(t) against u(t−τ): the peak is at the positive lag +3.
            let worst = a.worst_lags().cross_correlation;
            assert_eq!(worst.lag, 3);
            assert!(worst.value > 0.2);
            assert_eq!(a.cross_correlation_at(3), Some(worst.value));
            assert!(a.cross_correlation_at(4).unwrap() > a.bound);
        }
    }

    #[test]
    fn future_input_shows_at_negative_lag() {
        let mut rng = ChaCha8Rng::seed_from_u64(77);
        let n = 500;
        let u = white(&mut rng, n);
        let w = white(&mut rng, n);
        // ε(t) = w(t) − 0.5 u(t+2): correlation with u(t−τ) at τ = −2, negative.
        let eps: Vec<f64> = (0..n)
            .map(|k| w[k] - if k + 2 < n { 0.5 * u[k + 2] } else { 0.0 })
            .collect();
        let a = analyze(&eps, &u, &opts(5, true)).unwrap();
        let worst = a.worst_lags().cross_correlation;
        assert_eq!(worst.lag, -2);
        assert!(worst.value < -0.3);
        assert_eq!(a.cross_correlation[3], worst.value); // index i = lag + M
        assert_eq!(a.cross_correlation_at(-6), None);
        assert_eq!(a.cross_correlation_at(6), None);
        assert_eq!(a.autocorrelation_at(0), None);
        assert_eq!(a.autocorrelation_at(1), Some(a.autocorrelation[0]));
        assert_eq!(a.autocorrelation_at(6), None);
        assert_eq!(
            a.cross_correlation_outside,
            a.cross_correlation
                .iter()
                .filter(|r| r.abs() > a.bound)
                .count()
        );
        assert!(a.cross_correlation_outside >= 1);
    }

    #[test]
    fn offsets_make_raw_cross_correlation_flat_and_centring_fixes_it() {
        // PWM-like input around 1000 and a residual with bias 0.5, independent of each other.
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let n = 2000;
        let u: Vec<f64> = white(&mut rng, n)
            .iter()
            .map(|x| 1000.0 + 20.0 * x)
            .collect();
        let eps: Vec<f64> = white(&mut rng, n).iter().map(|x| 0.5 + x).collect();
        let centred = analyze_default(&eps, &u).unwrap();
        assert!(centred.white && centred.independent);
        assert!((centred.residual_mean - 0.5).abs() < 0.1);
        assert!((centred.input_mean - 1000.0).abs() < 2.0);
        assert!(centred
            .cross_correlation
            .iter()
            .all(|r| r.abs() < centred.bound));
        // Raw (MATLAB covf) normalisation: every lag ≈ ε̄ μ_u / √((ε̄²+σ²)(μ_u²+σ_u²)) ≈ 0.447.
        let raw = analyze(&eps, &u, &opts(25, false)).unwrap();
        assert!(raw
            .cross_correlation
            .iter()
            .all(|r| (r - 0.447).abs() < 0.05));
        assert!(raw.autocorrelation.iter().all(|r| r.abs() > 0.1)); // the bias, again
                                                                    // ... and both tests "fail" for signals that are in fact white and independent.
        assert!(!raw.white && !raw.independent);
    }

    #[test]
    fn json_keys() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let a = analyze(&white(&mut rng, 100), &white(&mut rng, 100), &opts(4, true)).unwrap();
        let v = serde_json::to_value(&a).unwrap();
        for key in [
            "max_lag",
            "bound",
            "autocorrelation",
            "cross_correlation",
            "white",
            "independent",
            "ljung_box_q",
            "ljung_box_p",
            "cross_statistic",
            "cross_p",
            "dof_whiteness",
            "dof_independence",
            "n",
        ] {
            assert!(v.get(key).is_some(), "missing {key}");
        }
        assert_eq!(v["autocorrelation"].as_array().unwrap().len(), 4);
        assert_eq!(v["cross_correlation"].as_array().unwrap().len(), 9);
        assert_eq!(v["dof_independence"], 9);
        let back: ResidualAnalysis = serde_json::from_value(v).unwrap();
        assert_eq!(back, a);
    }

    // ---------- errors ----------

    #[test]
    fn error_cases() {
        let ok: Vec<f64> = (0..60).map(|k| ((k * 37) % 11) as f64).collect();
        let ok2: Vec<f64> = (0..60).map(|k| ((k * 13) % 7) as f64).collect();
        assert_eq!(
            analyze(&ok, &ok2, &opts(0, true)),
            Err(ResidError::ZeroMaxLag)
        );
        // M near the integer limit: refused, its sizes never computed (audit s14 H-c), by the
        // accumulator too (nothing of its size allocated).
        // The bound is 1000 lags (audit s27 M-4: M = 20 000 on 100 000 samples asked for 12.8 GB):
        // on 2100 samples, enough for M = 1001 by N ≥ 2(M+1), 1001 is refused and 1000 computed.
        let mut state = 12345_u64;
        let mut draw = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let long_u: Vec<f64> = (0..2100).map(|_| draw()).collect();
        let long_e: Vec<f64> = (0..2100).map(|_| draw()).collect();
        assert_eq!(
            analyze(&long_e, &long_u, &opts(1001, true)),
            Err(ResidError::MaxLagTooLarge { max_lag: 1001 })
        );
        assert_eq!(
            analyze(&long_e, &long_u, &opts(1000, true)).map(|a| a.max_lag),
            Ok(1000)
        );
        for m in [MAX_LAG + 1, usize::MAX / 2, usize::MAX] {
            assert_eq!(
                analyze(&ok, &ok2, &opts(m, true)),
                Err(ResidError::MaxLagTooLarge { max_lag: m })
            );
            let mut acc = CovarianceAccumulator::new(&opts(m, true), 0.0, 0.0);
            for (e, u) in ok.iter().zip(&ok2) {
                acc.push(*e, *u);
            }
            assert_eq!(acc.finish(), Err(ResidError::MaxLagTooLarge { max_lag: m }));
        }
        assert_eq!(
            analyze(&ok, &ok2[..59], &opts(5, true)),
            Err(ResidError::LengthMismatch {
                residuals: 60,
                input: 59
            })
        );
        // N = 60 allows M = 29 (2·30 = 60) but not M = 30.
        assert!(analyze(&ok, &ok2, &opts(29, true)).is_ok());
        assert_eq!(
            analyze(&ok, &ok2, &opts(30, true)),
            Err(ResidError::TooShort {
                n: 60,
                max_lag: 30,
                required: 62
            })
        );
        assert!(matches!(
            analyze(&[], &[], &ResidOptions::default()),
            Err(ResidError::TooShort { n: 0, .. })
        ));
        let mut bad = ok.clone();
        bad[17] = f64::NAN;
        assert!(matches!(
            analyze(&bad, &ok2, &opts(5, true)),
            Err(ResidError::NonFinite {
                signal: Signal::Residual,
                index: 17,
                ..
            })
        ));
        let mut bad_u = ok2.clone();
        bad_u[42] = f64::NEG_INFINITY;
        let err = analyze(&ok, &bad_u, &opts(5, true)).unwrap_err();
        assert_eq!(
            err,
            ResidError::NonFinite {
                signal: Signal::Input,
                index: 42,
                value: f64::NEG_INFINITY
            }
        );
        assert!(err.to_string().contains("input sample 42"), "{err}");
        // Constant signals: zero variance after centring (0.1 is not exact in binary: rounding noise).
        let constant = vec![0.1; 60];
        assert_eq!(
            analyze(&constant, &ok2, &opts(5, true)),
            Err(ResidError::ZeroVariance {
                signal: Signal::Residual
            })
        );
        assert_eq!(
            analyze(&ok, &constant, &opts(5, true)),
            Err(ResidError::ZeroVariance {
                signal: Signal::Input
            })
        );
        // All-zero signals have zero variance even without centring.
        let zeros = vec![0.0; 60];
        assert_eq!(
            analyze(&zeros, &ok2, &opts(5, false)),
            Err(ResidError::ZeroVariance {
                signal: Signal::Residual
            })
        );
        // Without centring a nonzero constant is a valid (if odd) signal.
        assert!(analyze(&constant, &ok2, &opts(5, false)).is_ok());
        assert!(ResidError::ZeroVariance {
            signal: Signal::Input
        }
        .to_string()
        .contains("input is constant"));
    }

    #[test]
    fn input_missing_at_some_lags_is_an_error() {
        // Uncentred input that is zero except at its last sample: u(k−τ) is 0 on every row for
        // τ > 0, so the independence test has nothing to test at those lags.
        let n = 100;
        let mut u = vec![0.0; n];
        u[n - 1] = 1.0;
        let mut rng = ChaCha8Rng::seed_from_u64(4);
        let eps = white(&mut rng, n);
        let r = analyze(&eps, &u, &opts(5, false));
        // Lags −5..0 (indices 0..5) are fine; index 6 (lag +1) is the first empty column.
        assert!(
            matches!(
                r,
                Err(ResidError::InputNotExciting {
                    order: 11,
                    at: 6,
                    ..
                })
            ),
            "{r:?}"
        );
        // Centred, the same input is −1/N elsewhere and every lag sees it.
        assert!(analyze(&eps, &u, &opts(5, true)).is_ok());
    }
}
