//! Fitted model structures: linear ARX(na, nb, nk) and Hammerstein (deadzone + ARX), with free-run
//! simulation, one-step prediction and poles.
//!
//! Conventions (MATLAB's `arx`):
//! A(q) y(k) = B(q) x(k) + c + e(k), A = 1 + a1 q^-1 + ... + a_na q^-na,
//! B = b1 q^-nk + ... + b_nb q^-(nk+nb-1); x = u for ARX, x = deadzone(u) for Hammerstein,
//! c the optional constant offset.

use nalgebra::{Complex, DMatrix};
use serde::{Deserialize, Serialize};

use crate::{Deadzone, SysidError};

/// Model orders: na poles, nb coefficients in B, nk samples of pure delay.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Orders {
    /// na: order of A(q) (number of poles).
    pub na: usize,
    /// nb: number of coefficients of B(q).
    pub nb: usize,
    /// nk: input delay in samples.
    pub nk: usize,
}

impl Orders {
    /// The paper's structure: na = 3, nb = 1, nk = 1.
    pub const PAPER: Orders = Orders {
        na: 3,
        nb: 1,
        nk: 1,
    };

    /// k0 = max(na, nk + nb - 1): the first sample at which every regressor exists in the data.
    pub fn k0(&self) -> usize {
        self.na.max((self.nk + self.nb).saturating_sub(1))
    }
}

/// Which model structure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    /// Linear ARX: x = u.
    Arx,
    /// Hammerstein: x = deadzone(u), then ARX on x, normalised b1 = 1.
    Hammerstein,
}

impl std::fmt::Display for ModelKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            ModelKind::Arx => "arx",
            ModelKind::Hammerstein => "hammerstein",
        })
    }
}

/// A fitted (or given) model: the JSON `model` object of `identify --json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// Structure.
    pub kind: ModelKind,
    /// Sampling period Ts in s.
    pub ts: f64,
    /// na: order of A.
    pub na: usize,
    /// nb: number of B coefficients.
    pub nb: usize,
    /// nk: input delay in samples.
    pub nk: usize,
    /// a1..a_na.
    pub a: Vec<f64>,
    /// b1..b_nb (b1 = 1 for a Hammerstein model).
    pub b: Vec<f64>,
    /// Constant term c of the linear block (mm), when estimated with `--offset`.
    pub offset: Option<f64>,
    /// Deadzone (Hammerstein only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deadzone: Option<Deadzone>,
}

/// Upper bound on model orders accepted anywhere (keeps allocations bounded for hostile inputs).
pub const MAX_ORDER: usize = 100;

impl Model {
    /// Orders (na, nb, nk).
    pub fn orders(&self) -> Orders {
        Orders {
            na: self.na,
            nb: self.nb,
            nk: self.nk,
        }
    }

    /// The paper's "actual" Hammerstein model (Table III), normalised to b1 = 1 (docs/paper.md):
    /// A = 1 - 1.869 q^-1 + 0.9976 q^-2 - 0.1284 q^-3, nk = 1, b_r = 1.41, b_l = -1.50,
    /// m_r = 2.38 * 15.67e-4, m_l = 3.46 * 15.67e-4, Ts = 0.01 s.
    pub fn paper() -> Model {
        let b1 = 15.67e-4;
        Model {
            kind: ModelKind::Hammerstein,
            ts: 0.01,
            na: 3,
            nb: 1,
            nk: 1,
            a: vec![-1.869, 0.9976, -0.1284],
            b: vec![1.0],
            offset: None,
            deadzone: Some(Deadzone {
                b_l: -1.50,
                b_r: 1.41,
                m_l: 3.46 * b1,
                m_r: 2.38 * b1,
            }),
        }
    }

    /// Checks that the model is internally consistent and finite (e.g. after reading a file).
    pub fn check(&self) -> Result<(), SysidError> {
        let bad = |m: String| Err(SysidError::Data(format!("invalid model: {m}")));
        if self.na > MAX_ORDER || self.nb > MAX_ORDER || self.nk > MAX_ORDER {
            return bad(format!("orders above {MAX_ORDER} are not supported"));
        }
        if self.a.len() != self.na {
            return bad(format!(
                "na = {} but a has {} coefficients",
                self.na,
                self.a.len()
            ));
        }
        if self.b.len() != self.nb {
            return bad(format!(
                "nb = {} but b has {} coefficients",
                self.nb,
                self.b.len()
            ));
        }
        if !(self.ts.is_finite() && self.ts > 0.0) {
            return bad(format!(
                "ts = {} must be a positive number of seconds",
                self.ts
            ));
        }
        let mut values: Vec<f64> = self.a.iter().chain(&self.b).copied().collect();
        values.extend(self.offset);
        match (self.kind, &self.deadzone) {
            (ModelKind::Hammerstein, None) => {
                return bad("a hammerstein model needs a deadzone".into())
            }
            (ModelKind::Arx, Some(_)) => return bad("an arx model has no deadzone".into()),
            (ModelKind::Hammerstein, Some(d)) => {
                if self.nb == 0 {
                    return bad("a hammerstein model needs nb >= 1".into());
                }
                values.extend([d.b_l, d.b_r, d.m_l, d.m_r]);
            }
            _ => {}
        }
        if values.iter().any(|v| !v.is_finite()) {
            return bad("a coefficient is NaN or infinite".into());
        }
        Ok(())
    }

    /// The static input map x = f(u): identity for ARX, the deadzone for Hammerstein.
    #[inline]
    pub fn input_map(&self, u: f64) -> f64 {
        match &self.deadzone {
            Some(d) => d.apply(u),
            None => u,
        }
    }

    /// x(k) = f(u(k)) for a whole record.
    pub fn internal(&self, u: &[f64]) -> Vec<f64> {
        u.iter().map(|&v| self.input_map(v)).collect()
    }

    /// Free-run simulation (MATLAB `sim`/`compare` with infinite horizon): y_hat(k) = y(k) for k < k0, then
    /// y_hat(k) = -sum a_i y_hat(k-i) + sum b_j x(k-nk-j+1) + c. Fails if the simulation becomes non-finite.
    pub fn simulate(&self, u: &[f64], y: &[f64]) -> Result<Vec<f64>, SysidError> {
        self.run(u, y, false)
    }

    /// One-step-ahead prediction (MATLAB `predict` with horizon 1): y_hat(k) uses measured y(k-i).
    /// Entries k < k0 are copies of the data.
    pub fn predict(&self, u: &[f64], y: &[f64]) -> Result<Vec<f64>, SysidError> {
        self.run(u, y, true)
    }

    fn run(&self, u: &[f64], y: &[f64], one_step: bool) -> Result<Vec<f64>, SysidError> {
        let n = u.len().min(y.len());
        let k0 = self.orders().k0();
        let x = self.internal(&u[..n]);
        let mut out: Vec<f64> = y[..n.min(k0)].to_vec();
        out.reserve(n.saturating_sub(k0));
        let c = self.offset.unwrap_or(0.0);
        for k in k0..n {
            let mut v = c;
            for (i, ai) in self.a.iter().enumerate() {
                let past = if one_step {
                    y[k - 1 - i]
                } else {
                    out[k - 1 - i]
                };
                v -= ai * past;
            }
            for (j, bj) in self.b.iter().enumerate() {
                v += bj * x[k - self.nk - j];
            }
            if !v.is_finite() {
                return Err(SysidError::Numerical(format!(
                    "{} of the model became non-finite at sample {k} (unstable model?)",
                    if one_step { "prediction" } else { "simulation" }
                )));
            }
            out.push(v);
        }
        Ok(out)
    }

    /// Poles: roots of z^na + a1 z^(na-1) + ... + a_na, as eigenvalues of the companion matrix.
    pub fn poles(&self) -> Vec<Complex<f64>> {
        poles_of(&self.a)
    }

    /// True when every pole lies strictly inside the unit circle.
    pub fn is_stable(&self) -> bool {
        self.poles().iter().all(|p| p.norm() < 1.0)
    }

    /// Number of estimated parameters p: na + nb (+1 with offset) for ARX;
    /// 4 + na + (nb - 1) (+1) for Hammerstein (b1 = 1 is fixed by normalisation).
    pub fn parameter_count(&self) -> usize {
        let lin = self.na + self.offset.map_or(0, |_| 1);
        match self.kind {
            ModelKind::Arx => lin + self.nb,
            ModelKind::Hammerstein => lin + 4 + self.nb.saturating_sub(1),
        }
    }
}

/// Roots of the monic polynomial z^n + c1 z^(n-1) + ... + c_n (n = c.len()), via the companion matrix.
///
/// Always terminates: trailing zero coefficients give exact roots at z = 0, and the Schur iteration is
/// bounded (nalgebra's unbounded `complex_eigenvalues` never returns for some companion matrices, e.g.
/// z^3, nalgebra issues #611/#1291); when it does not converge the roots come from a bounded
/// Durand–Kerner iteration instead.
pub fn poles_of(c: &[f64]) -> Vec<Complex<f64>> {
    // z^n + ... + c_m z^(n-m) with c_{m+1..n} = 0 has n - m roots at exactly 0.
    let m = c.iter().rposition(|&v| v != 0.0).map_or(0, |i| i + 1);
    let mut p = vec![Complex::new(0.0, 0.0); c.len() - m];
    let c = &c[..m];
    let n = c.len();
    if n > 0 {
        let mut comp = DMatrix::<f64>::zeros(n, n);
        for (j, cj) in c.iter().enumerate() {
            comp[(0, j)] = -cj;
        }
        for i in 1..n {
            comp[(i, i - 1)] = 1.0;
        }
        match nalgebra::linalg::Schur::try_new(comp, f64::EPSILON, 1000 + 100 * n) {
            Some(schur) => p.extend(schur.complex_eigenvalues().iter().copied()),
            None => p.extend(durand_kerner(c)),
        }
    }
    p.sort_by(|a, b| b.norm().total_cmp(&a.norm()).then(b.im.total_cmp(&a.im)));
    p
}

/// Roots of z^n + c1 z^(n-1) + ... + c_n by the Durand–Kerner (Weierstrass) iteration, at most 2000
/// sweeps, started on a circle of the Cauchy bound 1 + max |c_i|.
fn durand_kerner(c: &[f64]) -> Vec<Complex<f64>> {
    let n = c.len();
    let eval = |z: Complex<f64>| {
        c.iter()
            .fold(Complex::new(1.0, 0.0), |acc, &ci| acc * z + ci)
    };
    let radius = 1.0 + c.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let mut z: Vec<Complex<f64>> = (0..n)
        .map(|k| Complex::from_polar(radius, 0.4 + std::f64::consts::TAU * k as f64 / n as f64))
        .collect();
    for _ in 0..2000 {
        let mut moved = 0.0_f64;
        for i in 0..n {
            let mut den = Complex::new(1.0, 0.0);
            for j in 0..n {
                if j != i {
                    den *= z[i] - z[j];
                }
            }
            if den.norm() == 0.0 {
                continue;
            }
            let step = eval(z[i]) / den;
            z[i] -= step;
            moved = moved.max(step.norm() / z[i].norm().max(1.0));
        }
        if moved.is_nan() || moved <= 1e-15 {
            break;
        }
    }
    z
}

/// An identified (or given) model run as a [`Plant`](crate::Plant): state = past outputs and past x.
///
/// Starts at rest: every past output equal to y0 and every past x equal to 0.
#[derive(Debug, Clone)]
pub struct ModelPlant {
    model: Model,
    /// y(k), y(k-1), ..., newest first (length max(na, 1)).
    y_hist: Vec<f64>,
    /// x(k-1), x(k-2), ... newest first (length nk + nb - 1).
    x_hist: Vec<f64>,
    label: String,
}

impl ModelPlant {
    /// Wraps `model`; fails for nk = 0 (direct feed-through cannot be run sample by sample as a plant)
    /// or an inconsistent model.
    pub fn new(model: Model, label: impl Into<String>) -> Result<Self, SysidError> {
        model.check()?;
        if model.nk == 0 {
            return Err(SysidError::Data(
                "a model with nk = 0 (direct feed-through) cannot be used as a plant; nk >= 1 is needed".into(),
            ));
        }
        let y_hist = vec![0.0; model.na.max(1)];
        let x_hist = vec![0.0; model.nk + model.nb - 1];
        Ok(ModelPlant {
            model,
            y_hist,
            x_hist,
            label: label.into(),
        })
    }

    /// The wrapped model.
    pub fn model(&self) -> &Model {
        &self.model
    }
}

impl crate::Plant for ModelPlant {
    fn ts(&self) -> f64 {
        self.model.ts
    }

    fn output(&self) -> f64 {
        self.y_hist[0]
    }

    fn step(&mut self, u: f64) -> Result<f64, SysidError> {
        let m = &self.model;
        // x(k) enters the history; x_hist[i] = x(k - i) after the shift.
        if !self.x_hist.is_empty() {
            self.x_hist.rotate_right(1);
            self.x_hist[0] = m.input_map(u);
        }
        // y(k+1) = -sum a_i y(k+1-i) + sum b_j x(k+1-nk-(j-1)) + c; x(k+1-nk-j') = x_hist[nk-1+j'].
        let mut v = m.offset.unwrap_or(0.0);
        for (i, ai) in m.a.iter().enumerate() {
            v -= ai * self.y_hist[i];
        }
        for (j, bj) in m.b.iter().enumerate() {
            v += bj * self.x_hist[m.nk - 1 + j];
        }
        if !v.is_finite() {
            return Err(SysidError::Numerical(format!(
                "{} output became non-finite",
                self.label
            )));
        }
        self.y_hist.rotate_right(1);
        self.y_hist[0] = v;
        Ok(v)
    }

    fn reset(&mut self, y0_mm: f64) {
        self.y_hist.iter_mut().for_each(|v| *v = y0_mm);
        self.x_hist.iter_mut().for_each(|v| *v = 0.0);
    }

    fn name(&self) -> String {
        self.label.clone()
    }
}
