//! Recursive instrumental variables (`--method iv`): a recursive estimator that stays unbiased when
//! white noise enters at the output, for online use.
//!
//! LS regresses y(k) on past *measured* outputs, which carry the noise, so E[φ(k) e(k)] ≠ 0 and the
//! estimate is biased. IV replaces φ by an instrument vector z(k) correlated with φ but not with the
//! noise: the same regressor built from the noise-free simulated output ŷ_aux of an auxiliary model
//! (Young's auxiliary-model instruments; Söderström & Stoica, *Instrumental Variable Methods*, 1983).
//!
//! ```text
//! ε(k) = y(k) − φᵀ(k) θ̂(k−1)
//! L(k) = P(k−1) z(k) / (ρ + φᵀ(k) P(k−1) z(k))
//! θ̂(k) = θ̂(k−1) + L(k) ε(k)
//! P(k) = [P(k−1) − L(k) φᵀ(k) P(k−1)] / ρ
//! ```
//!
//! θ̂(N) solves Σ ρ^(N−k) z(k) (y(k) − φᵀ(k) θ) = 0 up to the P(0) regularisation. The auxiliary model is
//! first the least-squares estimate (key-term separation for Hammerstein), then each IV stage's own result
//! (`iv_stages` stages; for Hammerstein the switching functions and x̂ of a stage use the auxiliary
//! model's deadzone, as in later RLS passes).

//! One implementation serves one input and several (MISO): [`pass`] takes the regressor as a function
//! of the output sequence it is built from (measured y for φ, ŷ_aux for z), and [`staged`] runs the
//! stages for any model, simulating the auxiliary model driven by every input (as MATLAB `iv4` does
//! for several inputs). A single input is one channel.

use nalgebra::{DMatrix, DVector};

use crate::fitted::{Note, Termination};
use sysid_core::{Model, SysidError};

/// The result of one recursive IV pass.
#[derive(Debug, Clone)]
pub struct IvPass {
    /// θ̂ over the free entries.
    pub theta: DVector<f64>,
    /// Σ z φᵀ over the pass (free entries).
    pub zphi: DMatrix<f64>,
    /// Σ z zᵀ over the pass (free entries).
    pub zz: DMatrix<f64>,
    /// Σ_k z(k) z(k−τ)ᵀ for τ = 1..=[`COV_LAGS`] (entry τ − 1; free entries): the instruments' lagged
    /// moments, for the covariance under a coloured equation error ([`covariance`]).
    pub zz_lagged: Vec<DMatrix<f64>>,
    /// The largest singular value of the pass's final P over p0: the share of the start P(0) = p0 I in
    /// the information of the estimate's weakest direction (≈ 1 when the regressors are too small
    /// for the data to move the estimate from its start; [`crate::trust::prior_warning`]).
    pub prior_share: f64,
}

/// The largest lag of the equation error's autocovariance [`covariance`] uses: white output noise e
/// makes the equation error A(q) e, a moving average of order n_a, so n_a lags (at most this many).
pub const COV_LAGS: usize = 10;

/// The regression an IV pass runs on: `rows(ys, k, row)` fills the full regressor at sample k built
/// from the output sequence `ys` (the measured y gives φ(k), the auxiliary simulation gives z(k));
/// `y` is the measured output (the target y(k)), rows k0..N−1 are used, `free` marks the estimated
/// entries of θ and `name` names the record in errors.
pub struct IvRegression<'a, F> {
    /// φ or z at sample k from an output sequence.
    pub rows: F,
    /// Measured output y(k).
    pub y: &'a [f64],
    /// First regression sample.
    pub k0: usize,
    /// Estimated entries of the full θ.
    pub free: &'a [bool],
    /// The record's name, for errors.
    pub name: &'a str,
}

/// One pass of recursive IV (module docs) on the regression `r`. `y_aux` is the auxiliary model's
/// simulated output, `theta0` the start (free entries), ρ = `forgetting`, P(0) = `p0` I.
pub fn pass<F: Fn(&[f64], usize, &mut [f64])>(
    r: &IvRegression<F>,
    y_aux: &[f64],
    theta0: &DVector<f64>,
    forgetting: f64,
    p0: f64,
) -> Result<IvPass, SysidError> {
    crate::rls::check_settings(forgetting, p0)?;
    let free = r.free;
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let p = idx.len();
    let mut theta = theta0.clone();
    let mut pm = DMatrix::<f64>::identity(p, p) * p0;
    let mut full_phi = vec![0.0; free.len()];
    let mut full_z = vec![0.0; free.len()];
    let mut phi = DVector::<f64>::zeros(p);
    let mut z = DVector::<f64>::zeros(p);
    let mut zphi = DMatrix::<f64>::zeros(p, p);
    let mut zz = DMatrix::<f64>::zeros(p, p);
    let mut zz_lagged = vec![DMatrix::<f64>::zeros(p, p); COV_LAGS];
    // The last COV_LAGS instrument vectors, newest first.
    let mut recent: std::collections::VecDeque<DVector<f64>> =
        std::collections::VecDeque::with_capacity(COV_LAGS + 1);
    for k in r.k0..r.y.len() {
        (r.rows)(r.y, k, &mut full_phi);
        (r.rows)(y_aux, k, &mut full_z);
        for (q, &i) in idx.iter().enumerate() {
            phi[q] = full_phi[i];
            z[q] = full_z[i];
        }
        let eps = r.y[k] - phi.dot(&theta);
        let pz = &pm * &z;
        let phip = pm.tr_mul(&phi); // (φᵀ P)ᵀ
        let den = forgetting + phi.dot(&pz);
        if !(den.is_finite() && den.abs() > 1e-300 && eps.is_finite()) {
            return Err(SysidError::Numerical(format!(
                "{}: recursive IV met a singular or non-finite update at sample {k} (ρ + φᵀPz = {den}): \
                 its instruments (simulated from the start model) have diverged or stopped exciting \
                 the regressors for this structure; use --method ls or --method oe on the same flags, \
                 or a lower order or another --nonlinearity",
                r.name
            )));
        }
        theta.axpy(eps / den, &pz, 1.0);
        pm.ger(-1.0 / den, &pz, &phip, 1.0);
        if forgetting < 1.0 {
            pm.unscale_mut(forgetting);
        }
        zphi.ger(1.0, &z, &phi, 1.0);
        zz.ger(1.0, &z, &z, 1.0);
        for (m, older) in zz_lagged.iter_mut().zip(&recent) {
            m.ger(1.0, &z, older, 1.0);
        }
        if COV_LAGS > 0 {
            if recent.len() == COV_LAGS {
                recent.pop_back();
            }
            recent.push_front(z.clone());
        }
    }
    if theta.iter().any(|v| !v.is_finite()) {
        return Err(SysidError::Numerical(format!(
            "{}: recursive IV produced a non-finite estimate",
            r.name
        )));
    }
    let prior_share = pm.singular_values().max() / p0;
    Ok(IvPass {
        theta,
        zphi,
        zz,
        zz_lagged,
        prior_share,
    })
}

pub use crate::fitted::IV_SETTLED;

/// The outcome of [`staged`].
#[derive(Debug, Clone)]
pub struct Staged {
    /// The kept stage's full θ̂ (fixed entries 0).
    pub theta: DVector<f64>,
    /// The kept stage's model.
    pub model: Model,
    /// The kept stage's pass (for the covariance).
    pub pass: IvPass,
    /// Stages run.
    pub stages: usize,
    /// Converged when θ̂ settled (relative change below [`IV_SETTLED`]), else not settled.
    pub termination: Termination,
    /// Unstable auxiliary models, the kept stage when not the last, unsettled stages.
    pub notes: Vec<Note>,
}

/// Recursive IV in at most `stages` stages on the regression `r` (one input or several): stage s
/// simulates the auxiliary model (first `start`, the least-squares estimate with full θ `theta_start`;
/// then stage s−1's model) driven by every input `u`, from rest at the mean of the first k0 outputs,
/// builds the instruments from that simulation (`rows_for(aux)` gives the regressor with the auxiliary
/// model's static nonlinearities) and runs one [`pass`]; `model_of` turns a full θ̂ into a model;
/// `cancel` is polled before each stage ([`SysidError::Cancelled`] when the caller asked to stop). The
/// stage whose model simulates the record best (from the same rest) is kept. An unstable auxiliary
/// model has its poles reflected into the unit circle first (a note says so).
#[allow(clippy::too_many_arguments)]
pub fn staged<F: Fn(&[f64], usize, &mut [f64])>(
    start: &Model,
    theta_start: &[f64],
    u: &[&[f64]],
    r: &IvRegression<()>,
    rows_for: impl Fn(&Model) -> F,
    model_of: impl Fn(&DVector<f64>) -> Result<Model, SysidError>,
    cancel: &sysid_core::Stop,
    stages: usize,
    forgetting: f64,
    p0: f64,
) -> Result<Staged, SysidError> {
    let (y, k0) = (r.y, r.k0);
    let gather = |full: &DVector<f64>| -> DVector<f64> {
        DVector::from_iterator(
            r.free.iter().filter(|f| **f).count(),
            full.iter()
                .zip(r.free)
                .filter(|(_, f)| **f)
                .map(|(v, _)| *v),
        )
    };
    let scatter = |sub: &DVector<f64>| -> DVector<f64> {
        let mut out = DVector::zeros(r.free.len());
        let free_entries = out.iter_mut().zip(r.free).filter(|(_, f)| **f);
        for ((o, _), v) in free_entries.zip(sub.iter()) {
            *o = *v;
        }
        out
    };
    let mut aux = start.clone();
    let mut theta_full = DVector::from_column_slice(theta_start);
    let mut best: Option<(f64, usize, DVector<f64>, Model, IvPass)> = None;
    let mut converged = false;
    let mut run = 0;
    let mut notes = Vec::new();
    // The auxiliary simulation starts at rest at the mean of the first k0 outputs: the measured initial
    // outputs carry noise, and for a near-integrator a noisy initial velocity makes the simulated output
    // drift away from the true one for the whole record (weak instruments).
    let mut y_init = y.to_vec();
    if k0 > 0 {
        let mean = y[..k0].iter().sum::<f64>() / k0 as f64;
        y_init[..k0].fill(mean);
    }
    for stage in 1..=stages {
        cancel.check()?;
        run = stage;
        let y_aux = match aux.simulate(u, &y_init) {
            Ok(ys) => ys,
            Err(_) => {
                let a = crate::oe::stabilise(aux.a());
                aux = aux.with_a(a)?;
                notes.push(Note::UnstableAuxiliary { stage });
                aux.simulate(u, &y_init)?
            }
        };
        let stage_r = IvRegression {
            rows: rows_for(&aux),
            y,
            k0,
            free: r.free,
            name: r.name,
        };
        let pass = pass(&stage_r, &y_aux, &gather(&theta_full), forgetting, p0)?;
        let next = scatter(&pass.theta);
        let change = (&next - &theta_full).norm() / (1e-300 + next.norm());
        theta_full = next;
        let model = model_of(&theta_full)?;
        // Keep the stage whose model simulates the record best (from rest, as the instruments do).
        let sim_rss = model.simulate(u, &y_init).ok().map_or(f64::INFINITY, |ys| {
            ys[k0..]
                .iter()
                .zip(&y[k0..])
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f64>()
        });
        if best.as_ref().is_none_or(|b| sim_rss < b.0) {
            best = Some((sim_rss, stage, theta_full.clone(), model.clone(), pass));
        }
        aux = model;
        if change < IV_SETTLED {
            converged = true;
            break;
        }
    }
    let Some((_, best_stage, theta, model, pass)) = best else {
        return Err(SysidError::Numerical("IV produced no estimate".into()));
    };
    if best_stage != run {
        notes.push(Note::KeptStage {
            kept: best_stage,
            of: run,
        });
    }
    if !converged {
        notes.push(Note::StagesNotSettled { stages: run });
    }
    Ok(Staged {
        theta,
        model,
        pass,
        stages: run,
        termination: if converged {
            Termination::Converged
        } else {
            Termination::NotSettled
        },
        notes,
    })
}

/// Asymptotic covariance of the basic IV estimate (Söderström & Stoica, *Instrumental Variable
/// Methods*, 1983, ch. 4; *System Identification*, 1989, eq. 8.30) for an equation error v(k) that is
/// not white:
///
/// ```text
/// Cov θ̂ = (ZᵀΦ)⁻¹ [ Σ_{|τ| ≤ L} r_v(τ) Σ_k z(k) z(k−τ)ᵀ ] (ΦᵀZ)⁻¹
/// ```
///
/// with r_v(τ) the equation error's autocovariance, `r_v[τ]` for τ = 0..=L (`r_v[0]` = σ̂²), and
/// L = `r_v.len() − 1` ≤ [`COV_LAGS`]. With `r_v = [σ̂²]` (white v) it is the textbook
/// σ² (ZᵀΦ)⁻¹ ZᵀZ (ΦᵀZ)⁻¹. Under white output noise e (IV's use case) v = A(q) e is a moving average
/// of order n_a with r_v(1) < 0 for a low-pass plant, so the white-v formula, with σ̂² = var v ≈
/// (1 + Σ a_i²) σ_e², overstates the spread (audit s18 M-6: 2× on the a-coefficients); with L = n_a the
/// sum is exact for that noise. When the lagged terms make a variance non-positive (a noise colour
/// beyond L lags), the white-v form is returned. `None` when ZᵀΦ is singular or the result not finite.
pub fn covariance(pass: &IvPass, r_v: &[f64]) -> Option<DMatrix<f64>> {
    let inv = pass.zphi.clone().try_inverse()?;
    let sigma2 = *r_v.first()?;
    let white = &inv * &pass.zz * inv.transpose() * sigma2;
    let mut middle = &pass.zz * sigma2;
    for (tau, r) in r_v.iter().enumerate().skip(1) {
        let m = pass.zz_lagged.get(tau - 1)?;
        middle += (m + m.transpose()) * *r;
    }
    let c = &inv * middle * inv.transpose();
    let c = if c.diagonal().iter().all(|d| *d > 0.0) {
        c
    } else {
        white
    };
    c.iter().all(|v| v.is_finite()).then_some(c)
}
