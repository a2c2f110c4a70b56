//! Model validation (paper section II-D): fit %, RMSE, loss function, FPE and AIC of a model on a record.
//!
//! All sums run over the scored rows k >= max(K, k0), k0 = max(na, nk + nb − 1) the model's largest lag
//! and K the caller's first scored sample (0 by default: from k0; [`first_scored`], the one place the
//! start is decided), N = number of those rows. K leaves a record's first samples out of every figure
//! (a benchmark's state-initialisation window, e.g. the 50 samples of `nonlinear_benchmarks`); the
//! simulations and predictions are the same whatever K (they run over the whole record, the estimated
//! initial outputs fitted to its rows k >= k0), only the rows scored change:
//! - fit % = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) (paper eq. 13, MATLAB `compare`), ȳ the mean over the same rows,
//!   for the free-run simulation (`fit_sim_percent`) and the one-step prediction (`fit_pred_percent`);
//! - RMSE = √(Σ (y − ŷ)² / N), both;
//! - loss V = (1/N) Σ ½ ε² over the one-step *equation-error* prediction errors ε (the ARX predictor
//!   from the measured outputs, paper eq. 14 — note the ½, which MATLAB's loss function does not have),
//!   for every model, so that models estimated by different methods compare in one column; an
//!   output-error model's own criterion, the simulation-error loss (1/N) Σ ½ (y − ŷ_sim)², is reported
//!   apart as `loss_sim` (for every model, from the estimated initial outputs);
//! - FPE = (N + p)/(N − p) · V (paper eq. 15);
//! - AIC = ln(2V) + 2p/N = ln(mean ε²) + 2p/N (the form of MATLAB's normalised AIC) over the same
//!   one-step equation-error ε as V and FPE, so that AIC, FPE and V of models estimated by different
//!   methods compare in one column;
//! - MATLAB's own figures for the model, from the model's *own* one-step prediction errors e (those of
//!   `rmse_pred`: the ARX predictor for an equation-error model, the simulation from the estimated
//!   initial outputs for an output-error or Wiener / Hammerstein–Wiener model): `loss_fcn` =
//!   mean e² (MATLAB's `sys.Report.Fit.LossFcn` and `MSE` with the default options, no ½),
//!   `fpe_matlab` = LossFcn (N + p)/(N − p) (MATLAB `fpe`), `aic_matlab` = ln(LossFcn) + 2p/N (MATLAB
//!   `aic(sys)`, the normalised AIC, `Report.Fit.nAIC`). For an equation-error model they are 2V, 2·FPE
//!   and AIC; for an output-error model they judge the simulation error;
//!
//! p = number of estimated parameters. A value that cannot be computed (constant output for fit, N <= p for
//! FPE, a simulation that diverges) is `None` (JSON `null`), never NaN.

use serde::{Deserialize, Serialize};

use crate::{Dataset, Model, SysidError};

/// Validation metrics of a model on one record.
///
/// The free-run simulation starts from initial outputs ŷ(0..k0−1) *estimated* to fit the record
/// (MATLAB `compare` with its default `InitialCondition = 'e'`, [`simulate_estimated_initial`]); the
/// `*_measured` values start from the measured y(0..k0−1) instead (`InitialCondition` given as data),
/// which for a lightly damped or integrating model carries the measurement noise of the first samples
/// through the whole record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Fit % of the free-run simulation (estimated initial outputs).
    pub fit_sim_percent: Option<f64>,
    /// Fit % of the one-step prediction.
    pub fit_pred_percent: Option<f64>,
    /// RMSE of the free-run simulation (estimated initial outputs; units of y).
    pub rmse_sim: Option<f64>,
    /// Fit % of the free-run simulation from the measured initial outputs.
    pub fit_sim_measured_percent: Option<f64>,
    /// RMSE of the free-run simulation from the measured initial outputs (units of y).
    pub rmse_sim_measured: Option<f64>,
    /// RMSE of the one-step prediction (units of y).
    pub rmse_pred: f64,
    /// Loss V = (1/N) Σ ½ ε² of the one-step equation-error prediction (paper eq. 14), whatever the
    /// model's noise model; `None` (n/a) for a model with an output nonlinearity (Wiener,
    /// Hammerstein–Wiener), whose linear block's output is not measured, so no equation error is
    /// defined (audit s17 M-a: it was the simulation loss under the same name). `note` says so.
    pub loss: Option<f64>,
    /// Simulation-error loss (1/N) Σ ½ (y − ŷ_sim)², ŷ_sim from the estimated initial outputs (what an
    /// output-error fit minimises); `None` when the simulation diverged.
    #[serde(default)]
    pub loss_sim: Option<f64>,
    /// FPE = (N + p)/(N − p) V (paper eq. 15); `None` with V.
    pub fpe: Option<f64>,
    /// Normalised AIC = ln(mean ε²) + 2p/N, ε the one-step equation-error prediction errors (as V).
    pub aic: Option<f64>,
    /// MATLAB's `LossFcn` (and `MSE`): mean e² of the model's own one-step prediction errors e, those
    /// of [`Metrics::rmse_pred`] (units of y²; no ½: `rmse_pred`²). For an equation-error model 2V; for
    /// an output-error or Wiener model the simulation error's. `None` only in files written before it.
    #[serde(default)]
    pub loss_fcn: Option<f64>,
    /// MATLAB's `fpe(sys)`: LossFcn (N + p)/(N − p); `None` when N <= p.
    #[serde(default)]
    pub fpe_matlab: Option<f64>,
    /// MATLAB's `aic(sys)` (the normalised AIC, `Report.Fit.nAIC`): ln(LossFcn) + 2p/N; `None` when
    /// LossFcn = 0.
    #[serde(default)]
    pub aic_matlab: Option<f64>,
    /// N: rows used (k >= max(K, k0), [`first_scored`]).
    pub n: usize,
    /// p: estimated parameters.
    pub p: usize,
    /// Why a free-run value is missing (e.g. the simulation diverged).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

impl Metrics {
    /// The same metrics counting `p` estimated parameters: FPE = (N + p)/(N − p) V and
    /// AIC = ln(2V) + 2p/N recomputed from V (2V = mean ε², the same number AIC was formed from). For a
    /// model whose estimator held some of its structure's parameters fixed (a deadzone branch the
    /// input never reached: audit s18 L-7), as MATLAB counts free parameters only.
    pub fn with_parameter_count(mut self, p: usize) -> Self {
        if p == self.p {
            return self;
        }
        let n = self.n;
        self.fpe = fpe_of(self.loss, n, p);
        self.aic = aic_of(self.loss.map(|v| 2.0 * v), n, p);
        self.fpe_matlab = fpe_of(self.loss_fcn, n, p);
        self.aic_matlab = aic_of(self.loss_fcn, n, p);
        self.p = p;
        self
    }
}

/// Akaike's final prediction error (N + p)/(N − p) · `loss` over N rows with p parameters (paper
/// eq. 15 with V, MATLAB `fpe` with LossFcn); `None` when N <= p or it is not finite.
pub fn fpe_of(loss: Option<f64>, n: usize, p: usize) -> Option<f64> {
    loss.filter(|_| n > p)
        .map(|v| (n + p) as f64 / (n - p) as f64 * v)
        .filter(|v| v.is_finite())
}

/// The normalised AIC ln(`mse`) + 2p/N of a mean squared error over N rows with p parameters (MATLAB
/// `aic(sys)`); `None` when N <= p (as [`fpe_of`]: no residual degree of freedom, the mse is the
/// parameters' own; audit s34 L-9: `validate --rows 0..2` printed nAIC from one scored sample and two
/// parameters), when mse <= 0 or when it is not finite.
pub fn aic_of(mse: Option<f64>, n: usize, p: usize) -> Option<f64> {
    mse.filter(|mse| *mse > 0.0 && n > p)
        .map(|mse| mse.ln() + 2.0 * p as f64 / n.max(1) as f64)
        .filter(|v| v.is_finite())
}

/// Fit % = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖), or `None` when y is constant.
pub fn fit_percent(y: &[f64], yhat: &[f64]) -> Option<f64> {
    let n = y.len().min(yhat.len());
    if n == 0 {
        return None;
    }
    let mean = y[..n].iter().sum::<f64>() / n as f64;
    let num: f64 = y
        .iter()
        .zip(yhat)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        .sqrt();
    let den: f64 = y[..n]
        .iter()
        .map(|a| (a - mean) * (a - mean))
        .sum::<f64>()
        .sqrt();
    let f = 100.0 * (1.0 - num / den);
    (den > 0.0 && f.is_finite()).then_some(f)
}

/// RMSE √(mean (y − ŷ)²).
pub fn rmse(y: &[f64], yhat: &[f64]) -> f64 {
    let n = y.len().min(yhat.len()).max(1);
    (y.iter()
        .zip(yhat)
        .map(|(a, b)| (a - b) * (a - b))
        .sum::<f64>()
        / n as f64)
        .sqrt()
}

/// The free-run simulation of `model` (one input record per model input) from the initial outputs
/// η = ŷ(0..k0−1) that fit the record best (MATLAB `compare` with `InitialCondition = 'e'`): η
/// minimises Σ_{k<k0} (y(k) − η_k)² + Σ_{k≥k0} (y(k) − ŷ(k; η))², a linear least-squares problem since
/// ŷ(k; η) = ŷ_m(k) + Σ_j s_j(k) (η_j − y(j)) with ŷ_m the simulation from the measured outputs and s_j
/// the free responses of 1/A(q) to a unit initial output j (A s_j = 0, s_j(i) = δ_ij for i < k0).
/// Returns the simulation and η. Fails when the simulation or a free response is not finite.
pub fn simulate_estimated_initial(
    model: &Model,
    data: &Dataset,
) -> Result<(Vec<f64>, Vec<f64>), SysidError> {
    simulate_estimated_initial_signals(model, &data.input_signals(), data.y())
}

/// [`simulate_estimated_initial`] from the signals (one input record per model input in `u`).
pub fn simulate_estimated_initial_signals(
    model: &Model,
    u: &[&[f64]],
    y: &[f64],
) -> Result<(Vec<f64>, Vec<f64>), SysidError> {
    estimate_initial_from(model, u, y, model.simulate(u, y)?, Vec::new())
}

/// The estimated-initial-output simulation from `base`, the simulation from the measured initial
/// outputs (see [`simulate_estimated_initial`]); `free`: the free responses computed beside it
/// ([`Model::simulate_with_free_responses`]), or empty.
fn estimate_initial_from(
    model: &Model,
    u: &[&[f64]],
    y: &[f64],
    base: Vec<f64>,
    free: Vec<f64>,
) -> Result<(Vec<f64>, Vec<f64>), SysidError> {
    let n = base.len();
    let k0 = model.k0().min(n);
    let y0: Vec<f64> = y[..k0].to_vec();
    if k0 == 0 || n <= k0 {
        return Ok((base, y0));
    }
    let phi = free_responses(model, n, k0, free)?;
    if let Some(g) = model.output_nonlinearity() {
        return estimate_initial_through_output(model, g, u, y, base, &phi);
    }
    let mut target = nalgebra::DVector::<f64>::zeros(n);
    for k in k0..n {
        target[k] = y[k] - base[k];
    }
    // A free response that is identically zero after k0 (a pole at 0) still has its unit row below
    // k0, so the problem is never rank deficient.
    // Numerically they can still be dependent when the model diverges (its free responses grow until
    // one swamps the others): say that, not the least squares' "input is not persistently exciting",
    // which would send the user to redesign a good experiment.
    let sol = crate::ls::solve(&phi, &target, &[]).map_err(|e| match e {
        SysidError::Data(_) => SysidError::Data(
            "the initial outputs that fit the record best cannot be estimated: the model's free \
             responses are numerically dependent over the record (a diverging, unstable model makes \
             them so), so only the fit from the measured initial outputs is defined"
                .into(),
        ),
        other => other,
    })?;
    let eta: Vec<f64> = (0..k0).map(|j| y0[j] + sol.theta[j]).collect();
    let mut out = base;
    // ŷ(k; η) = ŷ_m(k) + Σ_j s_j(k) (η_j − y(j)): the shift summed column after column (vectorised),
    // in the order of j as before, then added.
    let mut shift = vec![0.0; n];
    for (s, t) in phi.as_slice().chunks_exact(n).zip(sol.theta.iter()) {
        for (d, v) in shift.iter_mut().zip(s) {
            *d += v * t;
        }
    }
    for (o, d) in out.iter_mut().zip(&shift) {
        *o += d;
    }
    if out.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::Numerical(
            "simulation of the model became non-finite (unstable model?)".into(),
        ));
    }
    Ok((out, eta))
}

/// With an output nonlinearity y = g(v): v(η) = v_m + Φ δ is linear in the initial outputs (Φ the
/// free responses, v_m the linear block's simulation from the measured ones) but y is not, so δ
/// minimises Σ (y − g(v_m + Φ δ))² by Gauss–Newton (J = diag g'(v) Φ; at most 20 steps, each halved
/// until the loss falls). η is returned as the linear block's initial outputs v(0..k0−1).
fn estimate_initial_through_output(
    model: &Model,
    g: &crate::StaticNonlinearity,
    u: &[&[f64]],
    y: &[f64],
    base: Vec<f64>,
    phi: &nalgebra::DMatrix<f64>,
) -> Result<(Vec<f64>, Vec<f64>), SysidError> {
    let n = base.len();
    let k0 = phi.ncols();
    let y0 = model.operating_point().map_or(0.0, |o| o.y);
    let v_m = model.simulate_linear_part(u, y)?;
    let dy: Vec<f64> = y.iter().map(|v| v - y0).collect();
    let v_of = |d: &[f64]| -> Vec<f64> {
        (0..n)
            .map(|k| v_m[k] + (0..k0).map(|j| phi[(k, j)] * d[j]).sum::<f64>())
            .collect()
    };
    let loss = |v: &[f64]| -> f64 {
        // Every sample, the initial ones too, is y = g(v) (the initial outputs are v's, through g).
        (0..n).map(|k| (dy[k] - g.apply(v[k])).powi(2)).sum()
    };
    let mut delta = vec![0.0; k0];
    let mut v = v_of(&delta);
    let mut cost = loss(&v);
    for _ in 0..20 {
        let mut jac = phi.clone();
        let mut r = nalgebra::DVector::<f64>::zeros(n);
        for k in 0..n {
            let (yk, slope) = (g.apply(v[k]), g.slope(v[k]));
            r[k] = dy[k] - yk;
            for j in 0..k0 {
                jac[(k, j)] *= slope;
            }
        }
        let Ok(step) = crate::ls::solve(&jac, &r, &[]) else {
            break;
        };
        let mut scale = 1.0;
        let mut improved = false;
        while scale > 1e-4 {
            let trial: Vec<f64> = delta
                .iter()
                .zip(step.theta.iter())
                .map(|(d, s)| d + scale * s)
                .collect();
            let tv = v_of(&trial);
            let tc = loss(&tv);
            if tc < cost {
                let gain = (cost - tc) / cost.max(f64::MIN_POSITIVE);
                delta = trial;
                v = tv;
                cost = tc;
                improved = gain > 1e-12;
                break;
            }
            scale *= 0.5;
        }
        if !improved {
            break;
        }
    }
    let mut out = base;
    for (k, o) in out.iter_mut().enumerate().skip(k0) {
        *o = g.apply(v[k]) + y0;
    }
    if out.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::Numerical(
            "simulation of the model became non-finite (unstable model?)".into(),
        ));
    }
    Ok((out, v[..k0].iter().map(|v| v + y0).collect()))
}

/// The k0 free responses s_j of 1/A(q) to a unit initial output j (rows k = 0..n−1): `computed` when
/// the simulation computed them beside its own loop (n·k0 numbers,
/// [`Model::simulate_with_free_responses`]: the same numbers), else computed here.
fn free_responses(
    model: &Model,
    n: usize,
    k0: usize,
    computed: Vec<f64>,
) -> Result<nalgebra::DMatrix<f64>, SysidError> {
    let a = model.a();
    // Rows: k < k0 (the initial outputs themselves) then k ≥ k0; columns: the k0 free responses, by
    // columns (entry (k, j) at j·n + k). The k0 recursions are independent: advancing them side by side,
    // sample by sample, lets the processor overlap their chains of dependent operations.
    let given = computed.len() == n * k0;
    let mut phi = if given {
        nalgebra::DMatrix::<f64>::from_vec(n, k0, computed)
    } else {
        nalgebra::DMatrix::<f64>::zeros(n, k0)
    };
    let s = phi.as_mut_slice();
    for j in 0..k0 {
        s[j * n + j] = 1.0;
    }
    // The loop compiled per order for the usual na = k0 (the past of each response held in
    // registers); the same operations in the same order for every order.
    match (a.len(), k0) {
        _ if given => {}
        (1, 1) => advance_free_responses::<1, 1>(a, s, n),
        (2, 2) => advance_free_responses::<2, 2>(a, s, n),
        (3, 3) => advance_free_responses::<3, 3>(a, s, n),
        (4, 4) => advance_free_responses::<4, 4>(a, s, n),
        _ => {
            for k in k0..n {
                for j in 0..k0 {
                    let mut v = 0.0;
                    for (i, ai) in a.iter().enumerate() {
                        v -= ai * s[j * n + k - 1 - i];
                    }
                    s[j * n + k] = v;
                }
            }
        }
    }
    if !crate::ls::all_finite(s) {
        return Err(SysidError::Numerical(
            "the free response of the model is not finite (unstable model?)".into(),
        ));
    }
    Ok(phi)
}

/// Fills rows K0..n of the K0 free responses in `s` (by columns, entry (k, j) at j·n + k, rows < K0
/// set) for a model of NA = K0 poles `a`: s_j(k) = −Σ_i a_i s_j(k − 1 − i), the K0 recursions advanced
/// side by side with their last NA values in registers.
fn advance_free_responses<const NA: usize, const K0: usize>(a: &[f64], s: &mut [f64], n: usize) {
    let mut coef = [0.0; NA];
    coef.copy_from_slice(&a[..NA]);
    // past[j][i] = s_j(k − 1 − i).
    let mut past = [[0.0; NA]; K0];
    for (j, p) in past.iter_mut().enumerate() {
        for (i, v) in p.iter_mut().enumerate() {
            *v = s[j * n + K0 - 1 - i];
        }
    }
    let s = &mut s[..K0 * n];
    for k in K0..n {
        for j in 0..K0 {
            let mut v = 0.0;
            for i in 0..NA {
                v -= coef[i] * past[j][i];
            }
            for i in (1..NA).rev() {
                past[j][i] = past[j][i - 1];
            }
            past[j][0] = v;
            s[j * n + k] = v;
        }
    }
}

/// The one-step prediction ŷ(k|k−1) of `model` (MATLAB `predict(m, data, 1)` with estimated initial
/// conditions): for an equation-error model the ARX predictor from the measured outputs; for an
/// output-error model (H = 1) the simulation from the estimated initial outputs.
pub fn one_step_prediction(model: &Model, data: &Dataset) -> Result<Vec<f64>, SysidError> {
    let (u, y) = (data.input_signals(), data.y());
    match model.noise_model() {
        crate::NoiseModel::EquationError => model.predict_k(&u, y, 1),
        crate::NoiseModel::OutputError => {
            simulate_estimated_initial_signals(model, &u, y).map(|(s, _)| s)
        }
    }
}

/// Computes the validation metrics of `model` on `data` (every input of the record feeds the model's
/// input of the same position), over the rows k >= k0.
pub fn metrics(model: &Model, data: &Dataset) -> Result<Metrics, SysidError> {
    metrics_scored_from(model, data, 0)
}

/// [`metrics`] over the rows k >= max(K, k0) only, K = `score_from` (0-based row of `data`; checked by
/// [`check_scored`]): the same simulations and predictions, fewer rows scored.
pub fn metrics_scored_from(
    model: &Model,
    data: &Dataset,
    score_from: usize,
) -> Result<Metrics, SysidError> {
    metrics_from_sums(&record_sums(model, data, score_from)?, data.name())
}

/// The metrics of `model` over several records (merged experiments): every record's rows k ≥ k0
/// pooled, each record's output measured against its own mean ȳ_r (fit = 100 (1 − ‖y − ŷ‖ / √Σ_r ‖y_r −
/// ȳ_r‖²), as MATLAB's `compare` gives one fit per experiment: one mean over records at different
/// levels would count their gap as explained, audit s17 H-1; each record simulated from its own initial
/// outputs). For one record, [`metrics`].
pub fn pooled_metrics(model: &Model, records: &[Dataset]) -> Result<Metrics, SysidError> {
    let [first, rest @ ..] = records else {
        return Err(SysidError::Data("no record to judge the model on".into()));
    };
    if rest.is_empty() {
        return metrics(model, first);
    }
    let mut pooled = MetricSums {
        n: 0,
        p: model.parameter_count(),
        y_deviation: 0.0,
        sse_pred: 0.0,
        sse_equation: Some(0.0),
        sse_sim: Some(0.0),
        sse_sim_measured: Some(0.0),
        note: None,
    };
    for r in records {
        let s = record_sums(model, r, 0)?;
        pooled.n += s.n;
        // Each record's deviation from its own mean ȳ_r: records at different levels would otherwise
        // make Σ(y − ȳ)² over all of them large and flatter every fit (audit s17 H-1).
        pooled.y_deviation += s.y_deviation;
        pooled.sse_pred += s.sse_pred;
        pooled.sse_equation = pooled.sse_equation.zip(s.sse_equation).map(|(a, b)| a + b);
        pooled.sse_sim = pooled.sse_sim.zip(s.sse_sim).map(|(a, b)| a + b);
        pooled.sse_sim_measured = pooled
            .sse_sim_measured
            .zip(s.sse_sim_measured)
            .map(|(a, b)| a + b);
        pooled.note = pooled.note.or(s.note.map(|n| format!("{}: {n}", r.name())));
    }
    let names: Vec<&str> = records.iter().map(Dataset::name).collect();
    metrics_from_sums(&pooled, &names.join(" + "))
}

/// The first scored row of a record for a model whose largest lag is `k0` (its first predicted sample)
/// when the caller asks to score from sample `score_from` = K (0-based row of the record as read; 0:
/// from k0): max(K, k0). The one place where the start of every validation figure is decided (fit %,
/// RMSE, loss, FPE, AIC, MATLAB's LossFcn, FPE and nAIC, the K-step fit and the residual tests; in
/// memory, read in passes, linear and NARX models alike); [`check_scored`] checks a record against it.
pub fn first_scored(k0: usize, score_from: usize) -> usize {
    k0.max(score_from)
}

/// Checks that a record `name` of `len` samples leaves rows to score a model of largest lag `k0` and
/// `p` parameters from sample `score_from` ([`first_scored`]) and returns the first scored row. A
/// record no longer than k0 is refused as before (a data error); a K beyond k0 (the caller's choice)
/// that reaches the record's end, or leaves N = len − K <= p rows (too few for FPE and AIC, which
/// need N > p), is refused naming the setting [`Setting::ScoreFrom`](crate::Setting::ScoreFrom)
/// and the record's length.
pub fn check_scored(
    name: &str,
    len: usize,
    k0: usize,
    p: usize,
    score_from: usize,
) -> Result<usize, SysidError> {
    let first = first_scored(k0, score_from);
    if score_from > k0 {
        let refuse = |expected: String| {
            Err(SysidError::setting(
                crate::Setting::ScoreFrom,
                score_from,
                &expected,
            ))
        };
        if score_from >= len {
            return refuse(format!(
                "a first scored sample inside the record: {name} has {len} samples (0-based rows 0 to \
                 {})",
                len.saturating_sub(1)
            ));
        }
        if len - score_from <= p {
            return refuse(format!(
                "at most {}: {name} has {len} samples, and scoring from sample {score_from} leaves {} \
                 of them, not more than the model's {p} parameters (FPE and AIC need more scored \
                 samples than parameters)",
                len.saturating_sub(p + 1),
                len - score_from
            ));
        }
    }
    if len <= k0 {
        return Err(SysidError::Data(format!(
            "{name}: {len} samples are not enough to validate a model with k0 = {k0}"
        )));
    }
    Ok(first)
}

/// A record sampled at another Ts than the model's (within 0.1 %) cannot judge it: the model's
/// samples would not be the record's (audit s14 H-b: a 0.08 s model "validated" at 22.6 % on a
/// 0.16 s record).
/// `name` names the record, `ts` its sampling period (also a streamed record's, held nowhere whole).
/// [`check_sampling`] of a record whose reader's notes are `notes`: when the reader questioned a time
/// column in whole numbers read as seconds ([`crate::data::milliseconds_hint`]), the error names
/// `--time-unit ms` (audit s27 M-2: a record in ms against a 0.01 s model was told only to resample).
pub fn check_sampling_noted(
    name: &str,
    ts: f64,
    model_ts: f64,
    notes: &[String],
) -> Result<(), SysidError> {
    check_sampling(name, ts, model_ts).map_err(|e| match e {
        SysidError::Data(m) if notes.iter().any(|n| n.contains(crate::data::MS_ADVICE)) => {
            SysidError::Data(format!(
                "{m}; or, as the reader's note says, the time column may hold milliseconds ({}: \
                 Ts = {} s)",
                crate::data::MS_ADVICE,
                crate::format::Shortest(ts * 1e-3)
            ))
        }
        e => e,
    })
}

/// Refuses a record sampled at `ts` (s) for a model identified at `model_ts` (s).
pub fn check_sampling(name: &str, ts: f64, model_ts: f64) -> Result<(), SysidError> {
    if (ts - model_ts).abs() > 1e-3 * model_ts {
        return Err(SysidError::Data(format!(
            "{name}: the data are sampled at Ts = {} s but the model was identified at Ts = {} s; \
             resample the data onto the model's period (--resample {}) or pass the matching --ts",
            crate::format::Shortest(ts),
            crate::format::Shortest(model_ts),
            crate::format::Shortest(model_ts)
        )));
    }
    Ok(())
}

/// The sums of [`metrics`] over the rows k ≥ max(K, k0) of one record, K = `score_from`
/// ([`check_scored`]).
fn record_sums(model: &Model, data: &Dataset, score_from: usize) -> Result<MetricSums, SysidError> {
    check_sampling(data.name(), data.ts(), model.ts())?;
    let (u, y_all, name) = (&data.input_signals(), data.y(), data.name());
    let p = model.parameter_count();
    // ks: the first scored row. The simulations below run over the whole record whatever it is.
    let ks = check_scored(name, y_all.len(), model.k0(), p, score_from)?;
    let y = &y_all[ks..];
    let n = y.len();
    // One simulation from the measured initial outputs serves both simulation metrics (and the
    // output-error predictor); the free responses for the estimated initial outputs come beside it.
    let mut free = Vec::new();
    let measured = model.simulate_with_free_responses(u, y_all, &mut free);
    let estimated = match &measured {
        Ok(s) => estimate_initial_from(model, u, y_all, s.clone(), free).map_err(|e| e.to_string()),
        Err(e) => Err(e.to_string()),
    };
    let pred = match (model.noise_model(), &estimated) {
        (crate::NoiseModel::OutputError, Ok((s, _))) => s.clone(),
        // The equation-error predictor, or the output-error one's own failure (a diverging model).
        _ => one_step_prediction(model, data)?,
    };
    let pred = &pred[ks..];
    // The one-step equation-error prediction (the ARX predictor from the measured outputs) for the
    // loss V of every model; for an equation-error model it is `pred` itself.
    let sse_equation = match (model.output_nonlinearity(), model.noise_model()) {
        (Some(_), _) => None,
        (None, crate::NoiseModel::EquationError) => Some(sse(y, pred)),
        (None, crate::NoiseModel::OutputError) => {
            let eq = model
                .clone()
                .with_noise_model(crate::NoiseModel::EquationError)
                .predict_k(u, y_all, 1)?;
            Some(sse(y, &eq[ks..]))
        }
    };
    let (sim_measured, note) = match measured {
        Ok(s) => (Some(s), None),
        Err(e) => (None, Some(e.to_string())),
    };
    let (sim, note) = match estimated {
        Ok((s, _)) => (Some(s), note),
        Err(e) => (None, note.or(Some(e))),
    };
    let sums = MetricSums {
        n,
        p,
        y_deviation: deviation(y),
        sse_pred: sse(y, pred),
        sse_equation,
        sse_sim: sim.as_ref().map(|s| sse(y, &s[ks..])),
        sse_sim_measured: sim_measured.as_ref().map(|s| sse(y, &s[ks..])),
        note,
    };
    Ok(sums)
}

/// Σ (y − ŷ)² over the common length.
fn sse(y: &[f64], yhat: &[f64]) -> f64 {
    sum4(y, yhat, |a, b| (a - b) * (a - b))
}

/// Σ (y − ȳ)², ȳ the mean of `y`.
fn deviation(y: &[f64]) -> f64 {
    let mean = sum4(y, y, |a, _| a) / y.len() as f64;
    sum4(y, y, |a, _| (a - mean) * (a - mean))
}

/// Σ f(x_i, y_i) over the common length with four partial sums (vectorisable: the sums of every
/// metric run over the whole record; the order differs from a plain loop by rounding only).
#[inline]
fn sum4(x: &[f64], y: &[f64], f: impl Fn(f64, f64) -> f64) -> f64 {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let mut acc = [0.0; 4];
    let (xc, yc) = (x.chunks_exact(4), y.chunks_exact(4));
    let tail: f64 = xc
        .remainder()
        .iter()
        .zip(yc.remainder())
        .map(|(a, b)| f(*a, *b))
        .sum();
    for (a, b) in xc.zip(yc) {
        for i in 0..4 {
            acc[i] += f(a[i], b[i]);
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// The sums over the scored rows k ≥ max(K, k0) ([`first_scored`]) of a record from which its [`Metrics`] are made: by [`metrics`]
/// from the whole record, or pass by pass from a record too long to hold (`sysid::stream`).
#[derive(Debug, Clone, PartialEq)]
pub struct MetricSums {
    /// N: rows k ≥ max(K, k0).
    pub n: usize,
    /// p: estimated parameters.
    pub p: usize,
    /// Σ (y − ȳ)², ȳ the mean over the same rows.
    pub y_deviation: f64,
    /// Σ ε² of the one-step prediction errors (an output-error model predicts by simulation).
    pub sse_pred: f64,
    /// Σ ε² of the one-step equation-error prediction errors (the ARX predictor; for an
    /// equation-error model the same as `sse_pred`); `None` for a model with an output nonlinearity
    /// (not defined: see [`Metrics::loss`]).
    pub sse_equation: Option<f64>,
    /// Σ (y − ŷ_sim)² of the simulation from estimated initial outputs (`None`: it failed).
    pub sse_sim: Option<f64>,
    /// Σ (y − ŷ_sim)² of the simulation from the measured initial outputs (`None`: it failed).
    pub sse_sim_measured: Option<f64>,
    /// Why a simulation failed.
    pub note: Option<String>,
}

/// Fit % = 100 (1 − √sse / √deviation), or `None` when the output is constant.
fn fit_of(sse: f64, deviation: f64) -> Option<f64> {
    let den = deviation.sqrt();
    let f = 100.0 * (1.0 - sse.sqrt() / den);
    (den > 0.0 && f.is_finite()).then_some(f)
}

/// Why a model with an output nonlinearity has no loss V, FPE or AIC (audit s17 M-a).
pub const NO_EQUATION_ERROR: &str =
    "loss V, FPE and AIC are n/a: a model with an output nonlinearity \
     (Wiener, Hammerstein-Wiener) has no one-step equation error (its linear block's output is not \
     measured); compare it with other models by loss_sim and the simulation fits";

/// The [`Metrics`] of a record from its sums (`name` names the record in errors).
pub fn metrics_from_sums(s: &MetricSums, name: &str) -> Result<Metrics, SysidError> {
    let (n, p) = (s.n, s.p);
    if !s.sse_pred.is_finite() {
        return Err(SysidError::Numerical(format!(
            "{}: the squared prediction errors overflow f64 (values too large? rescale the data)",
            name
        )));
    }
    if s.sse_equation.is_some_and(|e| !e.is_finite()) {
        return Err(SysidError::Numerical(format!(
            "{}: the squared equation-error prediction errors overflow f64 (values too large? rescale \
             the data)",
            name
        )));
    }
    let nf = n.max(1) as f64;
    let mse = s.sse_pred / n as f64;
    let loss = s.sse_equation.map(|e| 0.5 * e / nf);
    let fpe = fpe_of(loss, n, p);
    let aic = aic_of(s.sse_equation.map(|e| e / nf), n, p);
    // MATLAB's figures: the model's own one-step prediction errors (those of rmse_pred).
    let loss_fcn = Some(mse).filter(|v| v.is_finite());
    // Said where the numbers are read (text and JSON), so that n/a is not taken for a failure.
    let note = match (s.sse_equation, &s.note) {
        (Some(_), n) => n.clone(),
        (None, n) => Some(
            n.iter()
                .cloned()
                .chain([format!(
                    "{NO_EQUATION_ERROR}, or by MATLAB's LossFcn, FPE and AIC (loss_fcn, fpe_matlab, \
                     aic_matlab: from its own prediction errors)"
                )])
                .collect::<Vec<_>>()
                .join("; "),
        ),
    };
    let rmse_of = |sse: f64| Some((sse / nf).sqrt()).filter(|v| v.is_finite());
    Ok(Metrics {
        fit_sim_percent: s.sse_sim.and_then(|e| fit_of(e, s.y_deviation)),
        fit_pred_percent: fit_of(s.sse_pred, s.y_deviation),
        rmse_sim: s.sse_sim.and_then(rmse_of),
        fit_sim_measured_percent: s.sse_sim_measured.and_then(|e| fit_of(e, s.y_deviation)),
        rmse_sim_measured: s.sse_sim_measured.and_then(rmse_of),
        rmse_pred: mse.sqrt(),
        loss,
        loss_sim: s.sse_sim.map(|e| 0.5 * e / nf).filter(|v| v.is_finite()),
        fpe,
        aic,
        loss_fcn,
        fpe_matlab: fpe_of(loss_fcn, n, p),
        aic_matlab: aic_of(loss_fcn, n, p),
        n,
        p,
        note,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    // FPE and AIC alike need N > p (audit s34 L-9): one scored sample and two parameters gave nAIC =
    // ln(2.42036e-5) + 2·2/1 = −6.629 by hand while FPE was null.
    #[test]
    fn aic_and_fpe_need_more_rows_than_parameters() {
        let mse = 2.42036e-5_f64;
        assert_eq!(aic_of(Some(mse), 1, 2), None);
        assert_eq!(aic_of(Some(mse), 2, 2), None);
        assert_eq!(fpe_of(Some(mse), 2, 2), None);
        let three = aic_of(Some(mse), 3, 2).unwrap();
        assert!((three - (mse.ln() + 4.0 / 3.0)).abs() < 1e-12);
        assert!((fpe_of(Some(mse), 3, 2).unwrap() - 5.0 * mse).abs() < 1e-18);
    }

    // y = (1, 2, 3), ȳ = 2, ‖y − ȳ‖ = √2; ŷ = (1, 2, 4): ‖y − ŷ‖ = 1 → fit = 100 (1 − 1/√2).
    #[test]
    fn fit_is_one_minus_error_norm_over_deviation_norm() {
        let f = fit_percent(&[1.0, 2.0, 3.0], &[1.0, 2.0, 4.0]).unwrap();
        assert!((f - 100.0 * (1.0 - 1.0 / 2f64.sqrt())).abs() < 1e-12);
    }

    #[test]
    fn fit_of_a_constant_output_is_undefined() {
        assert_eq!(fit_percent(&[2.0, 2.0], &[2.0, 2.0]), None);
    }

    fn bits(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    // The free responses that the simulation computes beside its own loop are, to the bit, those of
    // the plain recursion s_j(k) = −Σ_i a_i s_j(k − 1 − i) from the unit initial outputs (written out
    // here) and of `free_responses` alone, and the simulation is `simulate`'s; orders without a
    // compiled loop (na = 5) or with k0 > na (nk + nb − 1 > na) leave the buffer empty.
    #[test]
    fn free_responses_beside_the_simulation_are_the_plain_recursion() {
        let n = 300;
        let u: Vec<f64> = (0..n).map(|k| ((k * 7919) % 13) as f64 - 6.0).collect();
        let y: Vec<f64> = (0..n).map(|k| (k as f64 * 0.37).sin()).collect();
        let a_all = [-0.5, 0.2, -0.1, 0.05, 0.01];
        let mut fused = 0;
        for na in 1..=5 {
            for nb in 1..=2 {
                for nk in 1..=2 {
                    let a = a_all[..na].to_vec();
                    let m = Model::arx(1.0, a.clone(), [1.0, 0.5][..nb].to_vec(), nk, Some(0.3))
                        .unwrap();
                    let mut free = vec![7.0];
                    let sim = m
                        .simulate_with_free_responses(&[&u], &y, &mut free)
                        .unwrap();
                    assert_eq!(bits(&sim), bits(&m.simulate(&[&u], &y).unwrap()));
                    let k0 = m.k0();
                    if k0 != na || na > 4 {
                        assert!(free.is_empty(), "na {na} nb {nb} nk {nk}");
                        continue;
                    }
                    fused += 1;
                    let mut plain = vec![0.0; n * k0];
                    for j in 0..k0 {
                        plain[j * n + j] = 1.0;
                        for k in k0..n {
                            let mut v = 0.0;
                            for (i, ai) in a.iter().enumerate() {
                                v -= ai * plain[j * n + k - 1 - i];
                            }
                            plain[j * n + k] = v;
                        }
                    }
                    assert_eq!(bits(&free), bits(&plain), "na {na} nb {nb} nk {nk}");
                    let alone = free_responses(&m, n, k0, Vec::new()).unwrap();
                    assert_eq!(bits(alone.as_slice()), bits(&plain));
                }
            }
        }
        // k0 = na unless nk + nb − 1 > na: na = 1 once, na = 2 three times, na = 3 and 4 always.
        assert_eq!(fused, 1 + 3 + 4 + 4);
        // A diverging simulation leaves no free responses behind.
        let m = Model::arx(1.0, vec![-3.0], vec![1e300], 1, None).unwrap();
        let mut free = Vec::new();
        assert!(m
            .simulate_with_free_responses(&[&u], &y, &mut free)
            .is_err());
        assert!(free.is_empty());
    }
}

/// The outputs of a model on a record (`validate --out`): free-run simulation and K-step prediction.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelOutput {
    /// Free-run simulation ŷ_sim(k) from the estimated initial outputs (MATLAB `compare`'s default, as
    /// in [`Metrics::fit_sim_percent`]; its k < k0 entries are those initial outputs), `None` when it
    /// diverged.
    pub y_sim: Option<Vec<f64>>,
    /// Free-run simulation from the measured initial outputs (its k < k0 entries are y(k); the figure
    /// [`Metrics::fit_sim_measured_percent`] judges, the one to trust when the two fits differ: audit
    /// s24 M-2), `None` when it diverged.
    pub y_sim_measured: Option<Vec<f64>>,
    /// K-step-ahead prediction ŷ(k | k − K) (MATLAB `predict(m, z, K)`); entries k < k0 are the data.
    /// An output-error model predicts by simulation at every horizon: its `y_pred` is `y_sim`.
    pub y_pred: Vec<f64>,
    /// Fit % of `y_pred` over k >= max(K, k0) ([`first_scored`]).
    pub fit_pred_percent: Option<f64>,
}

/// Simulation and `horizon`-step prediction of `model` (horizon >= 1) from one input record per model
/// input and the measured output `y`.
pub fn model_output(
    model: &Model,
    u: &[&[f64]],
    y: &[f64],
    horizon: usize,
) -> Result<ModelOutput, SysidError> {
    model_output_scored_from(model, u, y, horizon, 0)
}

/// [`model_output`] with its fit % over the rows k >= max(K, k0) only, K = `score_from`
/// ([`first_scored`]; the record is checked by [`metrics_scored_from`]): every sample is simulated and
/// predicted all the same.
pub fn model_output_scored_from(
    model: &Model,
    u: &[&[f64]],
    y: &[f64],
    horizon: usize,
    score_from: usize,
) -> Result<ModelOutput, SysidError> {
    let y_sim_measured = model.simulate(u, y).ok();
    let y_sim = y_sim_measured
        .clone()
        .and_then(|base| estimate_initial_from(model, u, y, base, Vec::new()).ok())
        .map(|(s, _)| s);
    let y_pred = match (model.noise_model(), &y_sim) {
        (crate::NoiseModel::OutputError, Some(s)) => s.clone(),
        _ => model.predict_k(u, y, horizon)?,
    };
    let ks = first_scored(model.k0(), score_from).min(y_pred.len());
    let fit_pred_percent = fit_percent(&y[ks..y_pred.len()], &y_pred[ks..]);
    Ok(ModelOutput {
        y_sim,
        y_sim_measured,
        y_pred,
        fit_pred_percent,
    })
}

#[cfg(test)]
mod initial_tests {
    use super::*;
    use crate::data::Signals;

    // y(k) = 0.9 y(k−1) + u(k−1) from y(0) = 5 with u = 0: the free response 5·0.9^k. A record that
    // starts with a noisy y(0) = 4 is fitted exactly once η0 is estimated: η0 = 5 minimises
    // (4 − η0)² + Σ_{k≥1} (5·0.9^k − η0·0.9^k)² only approximately, so check against the closed form
    // η0 = (4 + 5 Σ 0.81^k) / (1 + Σ 0.81^k), k = 1..N−1.
    #[test]
    fn a_diverging_model_is_named_when_its_initial_outputs_cannot_be_estimated() {
        // Poles 1.2 and 1.1 (A = 1 − 2.3 q⁻¹ + 1.32 q⁻²) over 1000 samples: both free responses grow like
        // 1.2^k (10^79 at the end, still finite), their 1.1^k parts vanish beside it (ratio 10^-38), so
        // the two columns are parallel to rounding. The cause is the model, not the input.
        let n = 1000;
        let y: Vec<f64> = (0..n).map(|k| (k as f64 * 0.1).sin()).collect();
        let data = Dataset::new(Signals { u: y.clone(), y }, 1.0, "rec").unwrap();
        let m = Model::arx(1.0, vec![-2.3, 1.32], vec![1.0], 1, None).unwrap();
        let err = simulate_estimated_initial(&m, &data)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("free responses are numerically dependent"),
            "{err}"
        );
        assert!(!err.contains("persistently exciting"), "{err}");
    }

    // The free response s_j of 1/A(q) is the model's own simulation with zero input from the unit
    // initial outputs e_j: checked against `Model::simulate` for na = k0 = 1..=4 (the orders compiled
    // apart) and na = 5 (the general loop), with a pole close to the unit circle among them.
    #[test]
    fn free_responses_are_the_simulations_from_unit_initial_outputs() {
        let n = 300;
        for a in [
            vec![-0.9],
            vec![-1.5, 0.7],
            vec![-2.2, 1.65, -0.42],
            vec![-1.2, 0.5, -0.1, 0.02],
            vec![-0.5, 0.1, 0.05, -0.02, 0.01],
        ] {
            let m = Model::arx(1.0, a.clone(), vec![1.0], 1, None).unwrap();
            let k0 = m.k0();
            assert_eq!(k0, a.len());
            let phi = free_responses(&m, n, k0, Vec::new()).unwrap();
            let u = vec![0.0; n];
            for j in 0..k0 {
                let mut y = vec![0.0; n];
                y[j] = 1.0;
                let sim = m.simulate(&[&u], &y).unwrap();
                for k in 0..n {
                    assert_eq!(phi[(k, j)], sim[k], "na = {}, j = {j}, k = {k}", a.len());
                }
            }
        }
    }

    #[test]
    fn estimated_initial_output_is_the_least_squares_value() {
        let n = 40;
        let mut y: Vec<f64> = (0..n).map(|k| 5.0 * 0.9f64.powi(k as i32)).collect();
        y[0] = 4.0;
        let data = Dataset::new(Signals { u: vec![0.0; n], y }, 1.0, "free").unwrap();
        let m = Model::arx(1.0, vec![-0.9], vec![1.0], 1, None).unwrap();
        let (sim, eta) = simulate_estimated_initial(&m, &data).unwrap();
        let g: f64 = (1..n).map(|k| 0.81f64.powi(k as i32)).sum();
        let want = (4.0 + 5.0 * g) / (1.0 + g);
        assert!((eta[0] - want).abs() < 1e-12, "{} vs {want}", eta[0]);
        assert!((sim[3] - want * 0.9f64.powi(3)).abs() < 1e-12);
    }
}
