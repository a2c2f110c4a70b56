//! Estimators: batch least squares (QR) and recursive least squares (paper eqs. 9–12) for ARX, and the
//! Hammerstein model by key-term separation (docs/paper.md, eq. 8) — iterated batch LS or recursive;
//! beyond the paper: output-error refinement ([`crate::oe`]), recursive instrumental variables
//! ([`crate::iv`]), a UD-factorised RLS with windup protection ([`crate::rls_ud`], [`crate::windup`]), and
//! Hammerstein models on one-sided inputs ([`crate::branches`]).
//!
//! Unfitted settings ([`IdentifySettings`]) → [`identify`] → a fitted [`Identified`] holding the [`Model`].

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::branches::Branches;
use crate::fast_ls as ls; // the same API as crate::ls (Householder QR), without forming Q
use crate::model::MAX_ORDER;
use crate::regressor::Structure;
use crate::rls::{self, Rls};
use crate::rls_ud::{RlsForm, RobustRls};
use crate::windup::Windup;
use crate::{iv, oe};
use crate::{Dataset, Deadzone, Model, ModelKind, Orders, SysidError};

/// Estimation method (`--method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Batch least squares via QR; for Hammerstein, iterated key-term separation.
    Ls,
    /// Recursive least squares with forgetting (paper eqs. 9–12).
    Rls,
    /// Output-error refinement of every parameter (Levenberg–Marquardt on the free-run simulation error),
    /// started from the LS estimate. Unbiased under white output (measurement) noise; batch.
    Oe,
    /// Recursive instrumental variables with instruments from an auxiliary model's simulated output.
    /// Unbiased under output noise; recursive (online).
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

/// Unfitted settings of an identification.
#[derive(Debug, Clone, PartialEq)]
pub struct IdentifySettings {
    /// ARX or Hammerstein.
    pub kind: ModelKind,
    /// na, nb, nk.
    pub orders: Orders,
    /// LS or RLS.
    pub method: Method,
    /// ρ: RLS forgetting factor in (0, 1] (`--forgetting`, default 1).
    pub forgetting: f64,
    /// P(0) = p0 · I for RLS (`--p0`, default 1e6).
    pub p0: f64,
    /// Estimate a constant term c in the linear block (`--offset`).
    pub offset: bool,
    /// RLS passes over the data (`--passes`, default 1 as in the paper). Each new pass restarts
    /// P = p0 · I and keeps θ̂, so the P(0) regularisation pulls towards the previous pass's estimate and
    /// vanishes geometrically: with noise-free data a few passes reach the exact solution.
    pub passes: usize,
    /// Maximum key-term iterations for Hammerstein LS (`--max-iterations`, default 100).
    pub max_iterations: usize,
    /// Relative change of θ̂ below which the key-term iteration has converged (default 1e-10).
    pub tolerance: f64,
    /// Keep the RLS parameter trajectory (for convergence plots).
    pub record_history: bool,
    /// RLS covariance form (`--rls-form`, default standard: the paper's eq. 12). IV always uses the
    /// dense form.
    pub rls_form: RlsForm,
    /// RLS covariance-windup protection (`--windup`, default none).
    pub windup: Windup,
    /// Bound T on tr P for `--windup trace` (`--max-trace`); `None`: p0 times the number of parameters.
    pub max_trace: Option<f64>,
    /// Hammerstein on an input that never goes below (above) zero: drop the unexcited deadzone branch
    /// (fix m_l = b_l = 0) instead of refusing the data. Default `false` (refuse, as the paper's method
    /// cannot estimate it); the command line turns it on.
    pub drop_unexcited_branch: bool,
    /// IV: number of stages, each rebuilding the instruments from the previous stage's model (default 10).
    pub iv_stages: usize,
}

impl Default for IdentifySettings {
    fn default() -> Self {
        IdentifySettings {
            kind: ModelKind::Hammerstein,
            orders: Orders::PAPER,
            method: Method::Rls,
            forgetting: 1.0,
            p0: 1e6,
            offset: false,
            passes: 1,
            max_iterations: 100,
            tolerance: 1e-10,
            record_history: false,
            rls_form: RlsForm::Standard,
            windup: Windup::None,
            max_trace: None,
            drop_unexcited_branch: false,
            iv_stages: 10,
        }
    }
}

impl IdentifySettings {
    /// Builder: the model structure.
    pub fn with_kind(mut self, kind: ModelKind) -> Self {
        self.kind = kind;
        self
    }
    /// Builder: orders.
    pub fn with_orders(mut self, na: usize, nb: usize, nk: usize) -> Self {
        self.orders = Orders { na, nb, nk };
        self
    }
    /// Builder: method.
    pub fn with_method(mut self, method: Method) -> Self {
        self.method = method;
        self
    }
    /// Builder: forgetting factor ρ.
    pub fn with_forgetting(mut self, rho: f64) -> Self {
        self.forgetting = rho;
        self
    }
    /// Builder: estimate the offset c.
    pub fn with_offset(mut self, offset: bool) -> Self {
        self.offset = offset;
        self
    }
    /// Builder: RLS passes.
    pub fn with_passes(mut self, passes: usize) -> Self {
        self.passes = passes;
        self
    }

    /// Checks every setting and returns the regression structure.
    pub fn structure(&self) -> Result<Structure, SysidError> {
        let o = self.orders;
        for (name, v) in [("--na", o.na), ("--nb", o.nb), ("--nk", o.nk)] {
            if v > MAX_ORDER {
                return Err(SysidError::setting(
                    name,
                    v,
                    &format!("an order of at most {MAX_ORDER}"),
                ));
            }
        }
        if self.kind == ModelKind::Hammerstein && o.nb == 0 {
            return Err(SysidError::setting(
                "--nb",
                0,
                "nb >= 1 for a Hammerstein model (b1 = 1 is the key term)",
            ));
        }
        if matches!(self.method, Method::Rls | Method::Iv) {
            rls::check_settings(self.forgetting, self.p0)?;
            if self.passes == 0 || self.passes > 1000 {
                return Err(SysidError::setting(
                    "--passes",
                    self.passes,
                    "between 1 and 1000 passes",
                ));
            }
        }
        if let Some(t) = self.max_trace {
            if !(t.is_finite() && t > 0.0) {
                return Err(SysidError::setting(
                    "--max-trace",
                    t,
                    "a positive, finite bound on tr P",
                ));
            }
        }
        if self.iv_stages == 0 || self.iv_stages > 1000 {
            return Err(SysidError::setting(
                "--iv-stages",
                self.iv_stages,
                "between 1 and 1000 stages",
            ));
        }
        if self.max_iterations == 0 || self.max_iterations > 100_000 {
            return Err(SysidError::setting(
                "--max-iterations",
                self.max_iterations,
                "between 1 and 100000",
            ));
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(SysidError::setting(
                "tolerance",
                self.tolerance,
                "a positive number",
            ));
        }
        let s = Structure {
            kind: self.kind,
            orders: o,
            offset: self.offset,
        };
        if s.n_params() == 0 {
            return Err(SysidError::Data(
                "the model has no parameter to estimate (na = nb = 0)".into(),
            ));
        }
        Ok(s)
    }
}

/// One physical parameter with its standard deviation (MATLAB `present`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Param {
    /// Name: b_l, b_r, m_l, m_r, a1.., b1.., c.
    pub name: String,
    /// Estimate.
    pub value: f64,
    /// Standard deviation from the covariance (delta method for ratios); `None` for fixed parameters (b1 = 1
    /// of a Hammerstein model) or when it cannot be computed.
    pub std: Option<f64>,
}

/// A fitted model with its estimation record.
#[derive(Debug, Clone)]
pub struct Identified {
    /// The fitted model.
    pub model: Model,
    /// Physical parameters with standard deviations.
    pub params: Vec<Param>,
    /// Method used.
    pub method: Method,
    /// Key-term iterations (LS), passes (RLS), Levenberg–Marquardt iterations (OE) or stages (IV).
    pub iterations: usize,
    /// LS key-term: reached a fixed point. RLS: the estimate settled (relative change below 1e-3 over the
    /// last 10 % of the final pass, or between the ends of the last two passes). OE: the optimiser stopped
    /// on its ftol/xtol/gtol criterion. IV: the stages settled (relative change below 1e-6).
    pub converged: bool,
    /// Human-readable remark (limit cycle detected, best iterate kept, ...).
    pub note: Option<String>,
    /// σ̂²: residual variance of the one-step prediction errors, RSS / (N − p).
    pub noise_variance: f64,
    /// RLS only, when requested: the physical parameters (order of `params`) after each update.
    pub history: Vec<Vec<f64>>,
    /// Sample index of each `history` entry (pass-major, so passes > 1 repeat indices).
    pub history_samples: Vec<usize>,
}

/// Identifies a model from `data` with `settings`.
///
/// ```
/// use sysid::{Dataset, ModelKind};
/// use sysid::estimate::{identify, IdentifySettings, Method};
/// // y(k) = 0.5 y(k-1) + 2 u(k-1), noise-free: LS recovers a1 = -0.5, b1 = 2.
/// let u: Vec<f64> = (0..50).map(|k| ((k * 7919) % 13) as f64 - 6.0).collect();
/// let mut y = vec![0.0; 50];
/// for k in 1..50 { y[k] = 0.5 * y[k - 1] + 2.0 * u[k - 1]; }
/// let data = Dataset::new(u, y, 0.01, "doc").unwrap();
/// let s = IdentifySettings::default().with_kind(ModelKind::Arx).with_orders(1, 1, 1).with_method(Method::Ls);
/// let fit = identify(&data, &s).unwrap();
/// assert!((fit.model.a[0] + 0.5).abs() < 1e-10 && (fit.model.b[0] - 2.0).abs() < 1e-10);
/// ```
pub fn identify(data: &Dataset, settings: &IdentifySettings) -> Result<Identified, SysidError> {
    let s = settings.structure()?;
    let k0 = s.orders.k0();
    let p = s.n_params();
    let n = data.len();
    if n <= k0 || n - k0 < p {
        return Err(SysidError::Data(format!(
            "{}: {n} samples leave {} regression rows for {p} parameters (na = {}, nb = {}, nk = {}); \
             more data or lower orders are needed",
            data.name,
            n.saturating_sub(k0),
            s.orders.na,
            s.orders.nb,
            s.orders.nk
        )));
    }
    let branches = match s.kind {
        ModelKind::Hammerstein => Branches::of(data, s.offset, settings.drop_unexcited_branch)?,
        ModelKind::Arx => Branches::all(0.0, 0.0, 0.0),
    };
    let mut fit = match settings.method {
        Method::Ls => least_squares(data, &s, settings, &branches)?,
        Method::Rls => recursive(data, &s, settings, &branches)?,
        Method::Oe => output_error(data, &s, settings, &branches)?,
        Method::Iv => instrumental(data, &s, settings, &branches)?,
    };
    if let Some(extra) = branches.note() {
        fit.note = Some(match fit.note.take() {
            Some(n) => format!("{extra}; {n}"),
            None => extra,
        });
    }
    // No silent NaN: an estimate the data do not determine in f64 (magnitudes whose squares underflow
    // or overflow) is a numerical failure, not a result.
    if let Some(p) = fit.params.iter().find(|p| !p.value.is_finite()) {
        return Err(SysidError::Numerical(format!(
            "{}: the estimate of {} is {} (not finite): the data do not determine it in f64 arithmetic \
             (values too large or too small? rescale the data)",
            data.name, p.name, p.value
        )));
    }
    fit.model
        .check()
        .map_err(|e| SysidError::Numerical(format!("{}: {e}", data.name)))?;
    Ok(fit)
}

/// LS: plain ARX, or the iterated key-term separation for Hammerstein.
fn least_squares(
    data: &Dataset,
    s: &Structure,
    st: &IdentifySettings,
    br: &Branches,
) -> Result<Identified, SysidError> {
    match s.kind {
        ModelKind::Arx => arx_ls(data, s),
        ModelKind::Hammerstein => hammerstein_ls(data, s, st, br),
    }
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
    let p = free.len();
    let mut theta = DVector::zeros(p);
    let mut inv_gram = DMatrix::zeros(p, p);
    for (a, &i) in idx.iter().enumerate() {
        theta[i] = sol.theta[a];
        for (b, &j) in idx.iter().enumerate() {
            inv_gram[(i, j)] = sol.inv_gram[(a, b)];
        }
    }
    Ok(ls::LsSolution {
        theta,
        inv_gram,
        rss: sol.rss,
    })
}

/// Physical parameters, with the fixed deadzone entries set from the model and without a standard deviation.
fn params_with_branches(
    s: &Structure,
    theta: &DVector<f64>,
    cov: Option<&DMatrix<f64>>,
    model: &Model,
    br: &Branches,
) -> Vec<Param> {
    let mut params = physical_params(s, theta, cov);
    if let (ModelKind::Hammerstein, Some(d)) = (s.kind, model.deadzone.as_ref()) {
        let free = br.free_physical(s);
        let values = [d.b_l, d.b_r, d.m_l, d.m_r];
        for i in 0..4 {
            if !free[i] {
                params[i].value = values[i];
                params[i].std = None;
            }
        }
    }
    params
}

/// The key-term θ = [m_r, m_r b_r, m_l, m_l b_l, a.., b2.., c] (ARX: [a.., b.., c]) of a model.
fn theta_of_model(m: &Model) -> DVector<f64> {
    let mut v = Vec::new();
    let skip = match &m.deadzone {
        Some(d) => {
            v.extend([d.m_r, d.m_r * d.b_r, d.m_l, d.m_l * d.b_l]);
            1
        }
        None => 0,
    };
    v.extend_from_slice(&m.a);
    v.extend(m.b.iter().skip(skip));
    v.extend(m.offset);
    DVector::from_vec(v)
}

/// Output-error refinement from the LS (key-term) estimate.
fn output_error(
    data: &Dataset,
    s: &Structure,
    st: &IdentifySettings,
    br: &Branches,
) -> Result<Identified, SysidError> {
    let start = least_squares(data, s, st, br)?;
    let free = br.free_physical(s);
    let fit = oe::refine(data, s, &free, &start.model, st.max_iterations)?;
    let mut notes = Vec::new();
    if let Some(n) = &start.note {
        notes.push(format!("start (LS): {n}"));
    }
    if fit.stabilised_start {
        notes.push("the LS start was unstable in simulation; its poles were reflected into the unit circle".into());
    }
    notes.push(format!(
        "output-error refinement: simulation RSS {:.6e} -> {:.6e} in {} iterations ({} evaluations), stopped: {}",
        fit.rss_start, fit.rss, fit.iterations, fit.evaluations, fit.termination
    ));
    Ok(Identified {
        model: fit.model,
        params: fit.params,
        method: Method::Oe,
        iterations: fit.iterations,
        converged: fit.converged,
        note: Some(notes.join("; ")),
        noise_variance: fit.noise_variance,
        history: Vec::new(),
        history_samples: Vec::new(),
    })
}

/// Relative change of θ̂ between IV stages below which the stages have settled.
const IV_SETTLED: f64 = 1e-6;

/// Recursive IV in stages, the first stage's instruments from the LS (key-term) estimate.
fn instrumental(
    data: &Dataset,
    s: &Structure,
    st: &IdentifySettings,
    br: &Branches,
) -> Result<Identified, SysidError> {
    let start = least_squares(data, s, st, br)?;
    let free = br.free_theta(s);
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let mut aux = start.model.clone();
    let mut theta_full = theta_of_model(&aux);
    let mut best = None;
    let mut converged = false;
    let mut stages = 0;
    let mut notes = Vec::new();
    // The auxiliary simulation starts at rest at the mean of the first k0 outputs: the measured initial
    // outputs carry noise, and for a near-integrator a noisy initial velocity makes the simulated output
    // drift away from the true one for the whole record (weak instruments).
    let k0 = s.orders.k0();
    let mut y_init = data.y.clone();
    if k0 > 0 {
        let mean = data.y[..k0].iter().sum::<f64>() / k0 as f64;
        y_init[..k0].fill(mean);
    }
    for stage in 1..=st.iv_stages {
        stages = stage;
        let y_aux = match aux.simulate(&data.u, &y_init) {
            Ok(y) => y,
            Err(_) => {
                aux.a = oe::stabilise(&aux.a);
                notes.push(format!(
                    "stage {stage}: the auxiliary model was unstable; its poles were reflected"
                ));
                aux.simulate(&data.u, &y_init)?
            }
        };
        let dz = aux.deadzone.unwrap_or(Deadzone {
            b_l: 0.0,
            b_r: 0.0,
            m_l: 0.0,
            m_r: 0.0,
        });
        let theta0 = DVector::from_iterator(idx.len(), idx.iter().map(|&i| theta_full[i]));
        let pass = iv::pass(data, s, &dz, &y_aux, &free, &theta0, st.forgetting, st.p0)?;
        let mut next = DVector::zeros(free.len());
        for (q, &i) in idx.iter().enumerate() {
            next[i] = pass.theta[q];
        }
        let change = (&next - &theta_full).norm() / (1e-300 + next.norm());
        theta_full = next;
        let mut model = model_from_theta(s, &theta_full, data.ts);
        if let Some(d) = model.deadzone.as_mut() {
            br.impose(d);
        }
        // Keep the stage whose model simulates the record best (from rest, as the instruments do).
        let sim_rss = model
            .simulate(&data.u, &y_init)
            .ok()
            .map_or(f64::INFINITY, |ys| {
                ys[k0..]
                    .iter()
                    .zip(&data.y[k0..])
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
            });
        if best
            .as_ref()
            .is_none_or(|b: &(f64, usize, DVector<f64>, Model, iv::IvPass)| sim_rss < b.0)
        {
            best = Some((sim_rss, stage, theta_full.clone(), model.clone(), pass));
        }
        aux = model;
        if change < IV_SETTLED {
            converged = true;
            break;
        }
    }
    let Some((_, best_stage, theta_full, aux, pass)) = best else {
        return Err(SysidError::Numerical("IV produced no estimate".into()));
    };
    if best_stage != stages {
        notes.push(format!(
            "kept stage {best_stage} of {stages}, the one whose model simulates the record best"
        ));
    }
    let rss = prediction_rss(&aux, data)?;
    let sigma2 = rss / (data.len() - k0).saturating_sub(idx.len()).max(1) as f64;
    let cov = iv::covariance(&pass, sigma2).map(|c| {
        let mut full = DMatrix::zeros(free.len(), free.len());
        for (a, &i) in idx.iter().enumerate() {
            for (b, &j) in idx.iter().enumerate() {
                full[(i, j)] = c[(a, b)];
            }
        }
        full
    });
    if !converged {
        notes.push(format!(
            "IV stages had not settled after {stages} stages (relative change >= {IV_SETTLED:e})"
        ));
    }
    Ok(Identified {
        params: params_with_branches(s, &theta_full, cov.as_ref(), &aux, br),
        model: aux,
        method: Method::Iv,
        iterations: stages,
        converged,
        note: (!notes.is_empty()).then(|| notes.join("; ")),
        noise_variance: sigma2,
        history: Vec::new(),
        history_samples: Vec::new(),
    })
}

/// Physical parameters and their covariance-based standard deviations from θ̂ and Cov(θ̂).
fn physical_params(s: &Structure, theta: &DVector<f64>, cov: Option<&DMatrix<f64>>) -> Vec<Param> {
    let sd = |i: usize| {
        cov.map(|c| c[(i, i)])
            .filter(|v| v.is_finite() && *v >= 0.0)
            .map(f64::sqrt)
    };
    let names = s.theta_names();
    let mut out = Vec::new();
    let mut first = 0;
    if s.kind == ModelKind::Hammerstein {
        // b = θ_j / θ_i; gradient (−θ_j/θ_i², 1/θ_i).
        let ratio = |i: usize, j: usize| {
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
        };
        let (bl, bl_sd) = ratio(2, 3);
        let (br, br_sd) = ratio(0, 1);
        out.push(Param {
            name: "b_l".into(),
            value: bl,
            std: bl_sd,
        });
        out.push(Param {
            name: "b_r".into(),
            value: br,
            std: br_sd,
        });
        out.push(Param {
            name: "m_l".into(),
            value: theta[2],
            std: sd(2),
        });
        out.push(Param {
            name: "m_r".into(),
            value: theta[0],
            std: sd(0),
        });
        first = 4;
    }
    for (i, name) in names.iter().enumerate().skip(first) {
        if s.kind == ModelKind::Hammerstein && i == first + s.orders.na {
            out.push(Param {
                name: "b1".into(),
                value: 1.0,
                std: None,
            });
        }
        out.push(Param {
            name: name.clone(),
            value: theta[i],
            std: sd(i),
        });
    }
    if s.kind == ModelKind::Hammerstein && names.len() == first + s.orders.na {
        out.push(Param {
            name: "b1".into(),
            value: 1.0,
            std: None,
        });
    }
    out
}

/// Builds the fitted model from θ̂ (the deadzone breakpoints are the ratios θ2/θ1 and θ4/θ3).
fn model_from_theta(s: &Structure, theta: &DVector<f64>, ts: f64) -> Model {
    let o = s.orders;
    let mut i = 0;
    let deadzone = (s.kind == ModelKind::Hammerstein).then(|| {
        i = 4;
        deadzone_from_theta(
            theta.as_slice(),
            Deadzone {
                b_l: 0.0,
                b_r: 0.0,
                m_l: 0.0,
                m_r: 0.0,
            },
            f64::INFINITY,
        )
    });
    let a: Vec<f64> = theta.as_slice()[i..i + o.na].to_vec();
    i += o.na;
    let b: Vec<f64> = match s.kind {
        ModelKind::Arx => {
            let b = theta.as_slice()[i..i + o.nb].to_vec();
            i += o.nb;
            b
        }
        ModelKind::Hammerstein => {
            let mut b = vec![1.0];
            b.extend_from_slice(&theta.as_slice()[i..i + o.nb - 1]);
            i += o.nb - 1;
            b
        }
    };
    let offset = s.offset.then(|| theta[i]);
    Model {
        kind: s.kind,
        ts,
        na: o.na,
        nb: o.nb,
        nk: o.nk,
        a,
        b,
        offset,
        deadzone,
    }
}

/// Deadzone from θ = [m_r, m_r b_r, m_l, m_l b_l, ...]. A breakpoint whose ratio is not finite (slope
/// 0) keeps its `prev` value; breakpoints are clamped to ±`limit` so that a wild early estimate cannot
/// switch a branch off for the whole record.
fn deadzone_from_theta(theta: &[f64], prev: Deadzone, limit: f64) -> Deadzone {
    let ratio = |num: f64, den: f64, prev: f64| {
        let r = num / den;
        if r.is_finite() {
            r.clamp(-limit, limit)
        } else {
            prev
        }
    };
    Deadzone {
        b_r: ratio(theta[1], theta[0], prev.b_r),
        b_l: ratio(theta[3], theta[2], prev.b_l),
        m_r: theta[0],
        m_l: theta[2],
    }
}

fn build_regression(data: &Dataset, s: &Structure, dz: &Deadzone) -> (DMatrix<f64>, DVector<f64>) {
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

fn arx_ls(data: &Dataset, s: &Structure) -> Result<Identified, SysidError> {
    let dz = Deadzone {
        b_l: 0.0,
        b_r: 0.0,
        m_l: 0.0,
        m_r: 0.0,
    };
    let (phi, y) = build_regression(data, s, &dz);
    let sol = ls::solve(&phi, &y, &s.theta_names()).map_err(|e| context(data, e))?;
    let dof = (phi.nrows() - phi.ncols()).max(1) as f64;
    let sigma2 = sol.rss / dof;
    let cov = &sol.inv_gram * sigma2;
    Ok(Identified {
        model: model_from_theta(s, &sol.theta, data.ts),
        params: physical_params(s, &sol.theta, Some(&cov)),
        method: Method::Ls,
        iterations: 1,
        converged: true,
        note: None,
        noise_variance: sigma2,
        history: Vec::new(),
        history_samples: Vec::new(),
    })
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
    let k0 = model.orders().k0();
    let yhat = model.predict(&data.u, &data.y)?;
    Ok(data.y[k0..]
        .iter()
        .zip(&yhat[k0..])
        .map(|(y, p)| (y - p) * (y - p))
        .sum())
}

fn hammerstein_ls(
    data: &Dataset,
    s: &Structure,
    st: &IdentifySettings,
    br: &Branches,
) -> Result<Identified, SysidError> {
    let limit = br.limit;
    // Initial switching: h_r = [u > 0], h_l = [u < 0] (breakpoints at the smallest commands).
    let mut dz = br.initial_deadzone();
    let free = br.free_theta(s);
    let names = s.theta_names();
    let mut seen: Vec<DVector<f64>> = Vec::new();
    let mut best: Option<(f64, DVector<f64>, ls::LsSolution, usize)> = None;
    let mut converged = false;
    let mut cycle = false;
    let mut iterations = 0;
    for it in 1..=st.max_iterations {
        iterations = it;
        let (phi, y) = build_regression(data, s, &dz);
        let sol = match solve_free(&phi, &y, &free, &names) {
            Ok(sol) => sol,
            // A later iterate's breakpoints can leave a branch with too few distinct commands: stop and keep
            // the best iterate so far (reported in the note as not converged).
            Err(SysidError::Data(_)) if best.is_some() => break,
            Err(e) => return Err(context(data, e)),
        };
        let theta = sol.theta.clone();
        let model = model_from_theta(s, &theta, data.ts);
        let rss = prediction_rss(&model, data).unwrap_or(f64::INFINITY);
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
    let note = if converged {
        None
    } else if cycle {
        Some(format!(
            "key-term iteration entered a limit cycle after {iterations} iterations; kept iterate {best_it}, \
             the one with the smallest self-consistent residual"
        ))
    } else {
        Some(format!(
            "key-term iteration did not converge in {iterations} iterations; kept iterate {best_it}, the one \
             with the smallest self-consistent residual"
        ))
    };
    let rows = data.len() - s.orders.k0();
    let n_free = free.iter().filter(|f| **f).count();
    let sigma2 = rss / (rows.saturating_sub(n_free).max(1)) as f64;
    let cov = &sol.inv_gram * sigma2;
    let mut model = model_from_theta(s, &theta, data.ts);
    if let Some(d) = model.deadzone.as_mut() {
        br.impose(d);
    }
    Ok(Identified {
        params: params_with_branches(s, &theta, Some(&cov), &model, br),
        model,
        method: Method::Ls,
        iterations,
        converged,
        note,
        noise_variance: sigma2,
        history: Vec::new(),
        history_samples: Vec::new(),
    })
}

/// The recursive estimator behind `--method rls`: the paper's RLS ([`Rls`]) when no robust option is
/// asked for, otherwise [`RobustRls`].
enum Recursive {
    Paper(Rls),
    Robust(RobustRls),
}

impl Recursive {
    fn theta(&self) -> &DVector<f64> {
        match self {
            Recursive::Paper(r) => &r.theta,
            Recursive::Robust(r) => &r.theta,
        }
    }
    fn update(&mut self, phi: &[f64], y: f64, k: usize) -> Result<f64, SysidError> {
        match self {
            Recursive::Paper(r) => r.update(phi, y, k),
            Recursive::Robust(r) => r.update(phi, y, k),
        }
    }
    fn restart_covariance(&mut self, p0: f64) {
        match self {
            Recursive::Paper(r) => r.restart_covariance(p0),
            Recursive::Robust(r) => r.restart_covariance(p0),
        }
    }
    fn covariance(&self) -> DMatrix<f64> {
        match self {
            Recursive::Paper(r) => r.p.clone(),
            Recursive::Robust(r) => r.covariance(),
        }
    }
}

/// RLS for ARX, and recursive key-term separation for Hammerstein. First pass (the paper's scheme):
/// switching functions and the internal x̂ are evaluated with the latest estimate at every sample.
/// Later passes restart P = p0 I, keep θ̂ and evaluate the switching functions and x̂ with the estimate
/// the pass started from, so each pass is the recursive solution of one key-term LS step regularised
/// towards the previous estimate; the passes converge to the batch key-term fixed point.
fn recursive(
    data: &Dataset,
    s: &Structure,
    st: &IdentifySettings,
    br: &Branches,
) -> Result<Identified, SysidError> {
    let k0 = s.orders.k0();
    let n = data.len();
    let free = br.free_theta(s);
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let p = idx.len();
    let mut est = if st.rls_form == RlsForm::Standard && st.windup == Windup::None {
        Recursive::Paper(Rls::new(p, st.forgetting, st.p0)?)
    } else {
        Recursive::Robust(RobustRls::new(
            p,
            st.forgetting,
            st.p0,
            st.rls_form,
            st.windup,
            st.max_trace,
        )?)
    };
    let mut full_row = vec![0.0; s.n_params()];
    let mut row = vec![0.0; p];
    let hammer = s.kind == ModelKind::Hammerstein;
    let mut dz = if hammer {
        br.initial_deadzone()
    } else {
        Deadzone {
            b_l: 0.0,
            b_r: 0.0,
            m_l: 0.0,
            m_r: 0.0,
        }
    };
    let limit = br.limit;
    let initial_dz = dz;
    // Persistent excitation: the recursion never fails on data that cannot determine θ (P merely stays
    // large in the unexcited directions), so for identification proper (ρ = 1, no windup protection:
    // every sample weighs the same) the regressor matrix of the first pass is rank-tested first, as the
    // batch methods do, and such data are refused with the same message. With forgetting ρ < 1 or windup
    // protection the estimator is being used as a tracker, where spells without excitation are expected.
    if st.forgetting == 1.0 && st.windup == Windup::None && data.len() - k0 >= p {
        let (phi, y) = build_regression(data, s, &dz);
        // Only the rank verdict matters here; numerical trouble (overflow) is left to the recursion,
        // which reports the sample where it happens.
        if let Err(e @ SysidError::Data(_)) = solve_free(&phi, &y, &free, &s.theta_names()) {
            return Err(context(data, e));
        }
    }
    let expand = |t: &DVector<f64>| {
        let mut full = DVector::zeros(free.len());
        for (q, &i) in idx.iter().enumerate() {
            full[i] = t[q];
        }
        full
    };
    let mut history = Vec::new();
    let mut history_samples = Vec::new();
    let mut pass_ends: Vec<DVector<f64>> = Vec::new();
    let tail_start = n - (n - k0) / 10;
    let mut theta_tail = est.theta().clone();
    for pass in 0..st.passes {
        if pass > 0 {
            est.restart_covariance(st.p0);
            if hammer {
                dz = deadzone_from_theta(expand(est.theta()).as_slice(), dz, limit);
                br.impose(&mut dz);
            }
        }
        for k in k0..n {
            if k == tail_start {
                theta_tail.copy_from(est.theta());
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
                .map_err(|e| match e {
                    SysidError::Numerical(m) => {
                        SysidError::Numerical(format!("{}: {m}", data.name))
                    }
                    other => other,
                })?;
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
        pass_ends.push(est.theta().clone());
    }
    let theta = est.theta().clone();
    let rel = |a: &DVector<f64>, b: &DVector<f64>| (a - b).norm() / (1e-300 + b.norm());
    let converged = if pass_ends.len() >= 2 {
        rel(&pass_ends[pass_ends.len() - 2], &theta) < 1e-3
    } else {
        rel(&theta_tail, &theta) < 1e-3
    };
    let theta_full = expand(&theta);
    let mut model = model_from_theta(s, &theta_full, data.ts);
    if let Some(d) = model.deadzone.as_mut() {
        br.impose(d);
    }
    let rss = prediction_rss(&model, data)?;
    let sigma2 = rss / (n - k0).saturating_sub(p).max(1) as f64;
    let pc = est.covariance() * sigma2;
    let mut cov = DMatrix::zeros(free.len(), free.len());
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate() {
            cov[(i, j)] = pc[(a, b)];
        }
    }
    let mut note = None;
    if st.rls_form != RlsForm::Standard || st.windup != Windup::None {
        note = Some(format!(
            "RLS form {}, windup protection {}",
            st.rls_form, st.windup
        ));
    }
    Ok(Identified {
        params: params_with_branches(s, &theta_full, Some(&cov), &model, br),
        model,
        method: Method::Rls,
        iterations: st.passes,
        converged,
        note,
        noise_variance: sigma2,
        history,
        history_samples,
    })
}
