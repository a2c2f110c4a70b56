//! Estimators: batch least squares (QR) and recursive least squares (paper eqs. 9–12) for ARX, and the
//! Hammerstein model by key-term separation (reading notes, eq. 8) — iterated batch LS or recursive.
//!
//! Unfitted settings ([`IdentifySettings`]) → [`identify`] → a fitted [`Identified`] holding the [`Model`].

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use crate::ls;
use crate::model::MAX_ORDER;
use crate::regressor::Structure;
use crate::rls::{self, Rls};
use crate::{Dataset, Deadzone, Model, ModelKind, Orders, SysidError};

/// Estimation method (`--method`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Batch least squares via QR; for Hammerstein, iterated key-term separation.
    Ls,
    /// Recursive least squares with forgetting (paper eqs. 9–12).
    Rls,
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Method::Ls => "ls",
            Method::Rls => "rls",
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
                return Err(SysidError::setting(name, v, &format!("an order of at most {MAX_ORDER}")));
            }
        }
        if self.kind == ModelKind::Hammerstein && o.nb == 0 {
            return Err(SysidError::setting("--nb", 0, "nb >= 1 for a Hammerstein model (b1 = 1 is the key term)"));
        }
        if self.method == Method::Rls {
            rls::check_settings(self.forgetting, self.p0)?;
            if self.passes == 0 || self.passes > 1000 {
                return Err(SysidError::setting("--passes", self.passes, "between 1 and 1000 passes"));
            }
        }
        if self.max_iterations == 0 || self.max_iterations > 100_000 {
            return Err(SysidError::setting("--max-iterations", self.max_iterations, "between 1 and 100000"));
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(SysidError::setting("tolerance", self.tolerance, "a positive number"));
        }
        let s = Structure { kind: self.kind, orders: o, offset: self.offset };
        if s.n_params() == 0 {
            return Err(SysidError::Data("the model has no parameter to estimate (na = nb = 0)".into()));
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
    /// Key-term iterations (LS) or passes (RLS).
    pub iterations: usize,
    /// LS key-term: reached a fixed point. RLS: the estimate settled (relative change below 1e-3 over the
    /// last 10 % of the final pass, or between the ends of the last two passes).
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
    match (s.kind, settings.method) {
        (ModelKind::Arx, Method::Ls) => arx_ls(data, &s),
        (ModelKind::Arx, Method::Rls) => recursive(data, &s, settings),
        (ModelKind::Hammerstein, Method::Ls) => hammerstein_ls(data, &s, settings),
        (ModelKind::Hammerstein, Method::Rls) => {
            input_range(data)?;
            recursive(data, &s, settings)
        }
    }
}

/// The range of the input that switches each branch: (largest negative u, smallest positive u,
/// most negative u, most positive u). Fails when one side of the deadzone is never excited.
fn input_range(data: &Dataset) -> Result<(f64, f64, f64, f64), SysidError> {
    let pos = data.u.iter().copied().filter(|&v| v > 0.0);
    let neg = data.u.iter().copied().filter(|&v| v < 0.0);
    let (min_pos, max_pos) = pos.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    let (max_neg, min_neg) = neg.fold((f64::NEG_INFINITY, f64::INFINITY), |(a, b), v| (a.max(v), b.min(v)));
    if !min_pos.is_finite() || !max_neg.is_finite() {
        return Err(SysidError::Data(format!(
            "{}: the input is never {}: a Hammerstein deadzone needs commands on both sides of zero \
             (not persistently exciting); use --model arx or richer data",
            data.name,
            if min_pos.is_finite() { "negative" } else { "positive" }
        )));
    }
    Ok((max_neg, min_pos, min_neg, max_pos))
}

/// Physical parameters and their covariance-based standard deviations from θ̂ and Cov(θ̂).
fn physical_params(s: &Structure, theta: &DVector<f64>, cov: Option<&DMatrix<f64>>) -> Vec<Param> {
    let sd = |i: usize| cov.map(|c| c[(i, i)]).filter(|v| v.is_finite() && *v >= 0.0).map(f64::sqrt);
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
        out.push(Param { name: "b_l".into(), value: bl, std: bl_sd });
        out.push(Param { name: "b_r".into(), value: br, std: br_sd });
        out.push(Param { name: "m_l".into(), value: theta[2], std: sd(2) });
        out.push(Param { name: "m_r".into(), value: theta[0], std: sd(0) });
        first = 4;
    }
    for (i, name) in names.iter().enumerate().skip(first) {
        if s.kind == ModelKind::Hammerstein && i == first + s.orders.na {
            out.push(Param { name: "b1".into(), value: 1.0, std: None });
        }
        out.push(Param { name: name.clone(), value: theta[i], std: sd(i) });
    }
    if s.kind == ModelKind::Hammerstein && names.len() == first + s.orders.na {
        out.push(Param { name: "b1".into(), value: 1.0, std: None });
    }
    out
}

/// Builds the fitted model from θ̂ (the deadzone breakpoints are the ratios θ2/θ1 and θ4/θ3).
fn model_from_theta(s: &Structure, theta: &DVector<f64>, ts: f64) -> Model {
    let o = s.orders;
    let mut i = 0;
    let deadzone = (s.kind == ModelKind::Hammerstein).then(|| {
        i = 4;
        deadzone_from_theta(theta.as_slice(), Deadzone { b_l: 0.0, b_r: 0.0, m_l: 0.0, m_r: 0.0 }, f64::INFINITY)
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
    Model { kind: s.kind, ts, na: o.na, nb: o.nb, nk: o.nk, a, b, offset, deadzone }
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
    let dz = Deadzone { b_l: 0.0, b_r: 0.0, m_l: 0.0, m_r: 0.0 };
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
    Ok(data.y[k0..].iter().zip(&yhat[k0..]).map(|(y, p)| (y - p) * (y - p)).sum())
}

fn hammerstein_ls(data: &Dataset, s: &Structure, st: &IdentifySettings) -> Result<Identified, SysidError> {
    let (max_neg, min_pos, min_neg, max_pos) = input_range(data)?;
    let limit = max_pos.max(-min_neg);
    // Initial switching: h_r = [u > 0], h_l = [u < 0].
    let mut dz = Deadzone { b_l: max_neg, b_r: min_pos, m_l: 1.0, m_r: 1.0 };
    let names = s.theta_names();
    let mut seen: Vec<DVector<f64>> = Vec::new();
    let mut best: Option<(f64, DVector<f64>, ls::LsSolution, usize)> = None;
    let mut converged = false;
    let mut cycle = false;
    let mut iterations = 0;
    for it in 1..=st.max_iterations {
        iterations = it;
        let (phi, y) = build_regression(data, s, &dz);
        let sol = ls::solve(&phi, &y, &names).map_err(|e| context(data, e))?;
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
        if seen.iter().rev().skip(1).any(|old| (&theta - old).norm() <= st.tolerance * scale) {
            cycle = true;
            break;
        }
        seen.push(theta.clone());
        dz = deadzone_from_theta(theta.as_slice(), dz, limit);
    }
    let Some((rss, theta, sol, best_it)) = best else {
        return Err(SysidError::Numerical("key-term iteration produced no estimate".into()));
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
    let sigma2 = rss / (rows.saturating_sub(s.n_params()).max(1)) as f64;
    let cov = &sol.inv_gram * sigma2;
    Ok(Identified {
        model: model_from_theta(s, &theta, data.ts),
        params: physical_params(s, &theta, Some(&cov)),
        method: Method::Ls,
        iterations,
        converged,
        note,
        noise_variance: sigma2,
        history: Vec::new(),
        history_samples: Vec::new(),
    })
}

/// RLS for ARX, and recursive key-term separation for Hammerstein. First pass (the paper's scheme):
/// switching functions and the internal x̂ are evaluated with the latest estimate at every sample.
/// Later passes restart P = p0 I, keep θ̂ and evaluate the switching functions and x̂ with the estimate
/// the pass started from, so each pass is the recursive solution of one key-term LS step regularised
/// towards the previous estimate; the passes converge to the batch key-term fixed point.
fn recursive(data: &Dataset, s: &Structure, st: &IdentifySettings) -> Result<Identified, SysidError> {
    let p = s.n_params();
    let k0 = s.orders.k0();
    let n = data.len();
    let mut est = Rls::new(p, st.forgetting, st.p0)?;
    let mut row = vec![0.0; p];
    let hammer = s.kind == ModelKind::Hammerstein;
    let (mut dz, limit) = if hammer {
        let (max_neg, min_pos, min_neg, max_pos) = input_range(data)?;
        (Deadzone { b_l: max_neg, b_r: min_pos, m_l: 1.0, m_r: 1.0 }, max_pos.max(-min_neg))
    } else {
        (Deadzone { b_l: 0.0, b_r: 0.0, m_l: 0.0, m_r: 0.0 }, 0.0)
    };
    let initial_dz = dz;
    let mut history = Vec::new();
    let mut history_samples = Vec::new();
    let mut pass_ends: Vec<DVector<f64>> = Vec::new();
    let tail_start = n - (n - k0) / 10;
    let mut theta_tail = est.theta.clone();
    for pass in 0..st.passes {
        if pass > 0 {
            est.restart_covariance(st.p0);
            if hammer {
                dz = deadzone_from_theta(est.theta.as_slice(), dz, limit);
            }
        }
        for k in k0..n {
            if k == tail_start {
                theta_tail.copy_from(&est.theta);
            }
            if hammer && pass == 0 && k > k0 {
                dz = deadzone_from_theta(est.theta.as_slice(), dz, limit);
                if est.theta[0] == 0.0 && est.theta[2] == 0.0 {
                    dz = initial_dz;
                }
            }
            s.fill_row(&data.u, &data.y, k, &dz, &mut row);
            est.update(&row, s.target(&data.y, k), k).map_err(|e| match e {
                SysidError::Numerical(m) => SysidError::Numerical(format!("{}: {m}", data.name)),
                other => other,
            })?;
            if st.record_history {
                history.push(physical_params(s, &est.theta, None).iter().map(|q| q.value).collect());
                history_samples.push(k);
            }
        }
        pass_ends.push(est.theta.clone());
    }
    let theta = est.theta.clone();
    let rel = |a: &DVector<f64>, b: &DVector<f64>| (a - b).norm() / (1e-300 + b.norm());
    let converged = if pass_ends.len() >= 2 {
        rel(&pass_ends[pass_ends.len() - 2], &theta) < 1e-3
    } else {
        rel(&theta_tail, &theta) < 1e-3
    };
    let model = model_from_theta(s, &theta, data.ts);
    let rss = prediction_rss(&model, data)?;
    let sigma2 = rss / (n - k0).saturating_sub(p).max(1) as f64;
    let cov = &est.p * sigma2;
    Ok(Identified {
        model,
        params: physical_params(s, &theta, Some(&cov)),
        method: Method::Rls,
        iterations: st.passes,
        converged,
        note: None,
        noise_variance: sigma2,
        history,
        history_samples,
    })
}
