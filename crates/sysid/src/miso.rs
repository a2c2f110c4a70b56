//! Several inputs, one output (MISO): least squares and recursive least squares for ARX with one B polynomial per input, and for the
//! Hammerstein model with a static deadzone per input (key-term separation per input, b1 = 1 for each
//! nonlinear input); an input can be declared linear (the IPA's two valves are the motivating case).
//!
//! y(k) = −Σ a_i y(k−i) + Σ_inputs Σ_j b_j^(m) x^(m)(k − nk_m − j + 1) + c, x^(m) = f_m(u^(m)).
//!
//! Regression θ: for each nonlinear input the key-term block [m_r, m_r b_r, m_l, m_l b_l] at
//! u^(m)(k − nk_m), then a1..a_na, then per input b1..b_nb (linear) or b2..b_nb (nonlinear, on the current
//! deadzone estimate), then c. The Hammerstein blocks are iterated as for one input (docs/paper.md): the
//! switching functions and x̂ are rebuilt from the current deadzones until θ changes by less than 1e-10
//! (relative) or `max_iterations`. Rows k ≥ k0 = max(na, nk_m + nb_m − 1 over the inputs).

use nalgebra::{DMatrix, DVector};

use crate::estimate::{Estimator, Note, OeVerdict};
use crate::oe::{miso_params, miso_vector, NamedParam};
use crate::warnings::Warning;
use sysid_core::param::deadzone_from_theta;
use sysid_core::{Deadzone, InputChannel, Model, ModelKind, StaticNonlinearity, SysidError};

/// One input of a MISO problem.
#[derive(Debug, Clone, PartialEq)]
pub struct MisoInput {
    /// Its name (the data column), kept in the model.
    pub name: String,
    /// u^(m)(k) (for the IPA: a valve command in PWM counts).
    pub u: Vec<f64>,
    /// nb_m: number of B coefficients (≥ 1).
    pub nb: usize,
    /// nk_m: delay in samples.
    pub nk: usize,
    /// A linear input (no static nonlinearity) in a Hammerstein model.
    pub linear: bool,
}

/// A fitted MISO model and how it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct MisoFit {
    /// The model (one `InputChannel` per input, in the given order).
    pub model: Model,
    /// The physical parameters in the layout of [`crate::oe::miso_vector`] (deadzones, a, B of each
    /// input with b1 = 1 fixed for a nonlinear one, c), with standard deviations: σ̂² (ΦᵀΦ)⁻¹ of the final
    /// regression for least squares and RLS (delta method for the breakpoints), σ̂² (JᵀJ)⁻¹ of the
    /// final simulation Jacobian for output error.
    pub params: Vec<NamedParam>,
    /// σ̂² = RSS / (N − p) of the final regression (LS, RLS) or of the simulation errors (OE).
    pub noise_variance: f64,
    /// Key-term iterations of least squares (1 for ARX or when every input is linear), passes of RLS, or
    /// Levenberg–Marquardt iterations of output error.
    pub iterations: usize,
    /// Whether the key-term iteration reached its fixed point (least squares), the RLS estimate
    /// settled over the passes, or the output-error search converged.
    pub converged: bool,
    /// Remarks (output error: the refinement and which candidate was kept).
    pub notes: Vec<Note>,
    /// Reasons not to trust the estimate (output error: the start kept instead of the refinement).
    pub warnings: Vec<Warning>,
}

/// The regression of a MISO problem (module docs): which inputs are nonlinear, k0, the rows and the
/// parameter names, and the map from θ back to a model.
struct Regression<'a> {
    inputs: &'a [MisoInput],
    nonlinear: Vec<bool>,
    y: &'a [f64],
    na: usize,
    offset: bool,
    /// First regression sample k0.
    k0: usize,
    /// Key-term entries (4 per nonlinear input).
    n_key: usize,
    names: Vec<String>,
}

impl<'a> Regression<'a> {
    /// Checks the inputs and lays out θ.
    fn new(
        inputs: &'a [MisoInput],
        y: &'a [f64],
        na: usize,
        kind: ModelKind,
        offset: bool,
    ) -> Result<Self, SysidError> {
        if inputs.is_empty() {
            return Err(SysidError::Data(
                "a MISO model needs at least one input".into(),
            ));
        }
        for m in inputs {
            if m.nb == 0 {
                return Err(SysidError::setting(
                    sysid_core::Setting::Nb,
                    format!("0 for input {}", m.name),
                    "at least one B coefficient per input",
                ));
            }
            if m.u.len() != y.len() {
                return Err(SysidError::Data(format!(
                    "input {} has {} samples but y has {}",
                    m.name,
                    m.u.len(),
                    y.len()
                )));
            }
        }
        let nonlinear: Vec<bool> = inputs
            .iter()
            .map(|m| kind == ModelKind::Hammerstein && !m.linear)
            .collect();
        let k0 = inputs.iter().map(|m| m.nk + m.nb - 1).fold(na, usize::max);
        let n_key = 4 * nonlinear.iter().filter(|&&v| v).count();
        let mut names = Vec::new();
        for (m, &nl) in inputs.iter().zip(&nonlinear) {
            if nl {
                for s in ["m_r", "m_r*b_r", "m_l", "m_l*b_l"] {
                    names.push(format!("{s} ({})", m.name));
                }
            }
        }
        names.extend((1..=na).map(|i| format!("a{i}")));
        for (m, &nl) in inputs.iter().zip(&nonlinear) {
            let from = if nl { 2 } else { 1 };
            names.extend((from..=m.nb).map(|j| format!("b{j} ({})", m.name)));
        }
        if offset {
            names.push("c".into());
        }
        let r = Regression {
            inputs,
            nonlinear,
            y,
            na,
            offset,
            k0,
            n_key,
            names,
        };
        let (n, p) = (r.rows(), r.len());
        if n <= p {
            return Err(SysidError::Data(format!(
                "{} samples leave {n} regression rows for {p} parameters; more data or lower orders are needed",
                y.len()
            )));
        }
        Ok(r)
    }

    /// Number of entries of θ.
    fn len(&self) -> usize {
        self.names.len()
    }

    /// Number of regression rows (k = k0..N−1).
    fn rows(&self) -> usize {
        self.y.len().saturating_sub(self.k0)
    }

    /// φ(k) with the deadzones `dz` (one per input).
    fn fill_row(&self, dz: &[Deadzone], k: usize, row: &mut [f64]) {
        self.fill_row_from(self.y, dz, k, row);
    }

    /// φ(k) built from the output sequence `ys` (the measured y, or an auxiliary simulation for the
    /// IV instruments) with the deadzones `dz`.
    fn fill_row_from(&self, ys: &[f64], dz: &[Deadzone], k: usize, row: &mut [f64]) {
        for (c, v) in row.iter_mut().enumerate() {
            *v = regressor(
                self.inputs,
                &self.nonlinear,
                dz,
                ys,
                self.na,
                self.offset,
                k,
                c,
            );
        }
    }

    /// The stacked regression matrix Φ (rows k0..N−1) with the deadzones `dz`.
    fn matrix(&self, dz: &[Deadzone]) -> DMatrix<f64> {
        let mut phi = DMatrix::zeros(self.rows(), self.len());
        let mut row = vec![0.0; self.len()];
        for r in 0..self.rows() {
            self.fill_row(dz, self.k0 + r, &mut row);
            for (c, v) in row.iter().enumerate() {
                phi[(r, c)] = *v;
            }
        }
        phi
    }

    /// The least-squares θ̂ with the deadzones `dz`.
    fn solve(&self, dz: &[Deadzone]) -> Result<Vec<f64>, SysidError> {
        solve_stacked(std::slice::from_ref(self), dz)
    }

    /// The deadzones `dz` updated from the key-term blocks of θ̂ (inputs without one keep theirs).
    fn update_deadzones(&self, theta: &[f64], dz: &mut [Deadzone]) {
        update_deadzones(&self.nonlinear, theta, dz);
    }

    /// The fit of θ̂ with the deadzones `dz` (Ts = `ts` s): its model and parameters with standard
    /// deviations ([`Regression::params`]).
    fn fit(
        &self,
        theta: &[f64],
        dz: &[Deadzone],
        ts: f64,
        iterations: usize,
        converged: bool,
    ) -> Result<MisoFit, SysidError> {
        fit_stacked(
            std::slice::from_ref(self),
            theta,
            dz,
            ts,
            iterations,
            converged,
        )
    }

    /// The model of θ̂ and the deadzones `dz` (Ts = `ts` s).
    fn model(&self, theta: &[f64], dz: &[Deadzone], ts: f64) -> Result<Model, SysidError> {
        let (n_key, na) = (self.n_key, self.na);
        let a = theta[n_key..n_key + na].to_vec();
        let mut i = n_key + na;
        let mut channels = Vec::with_capacity(self.inputs.len());
        for ((m, &nl), d) in self.inputs.iter().zip(&self.nonlinear).zip(dz) {
            let (b, f) = if nl {
                let mut b = vec![1.0];
                b.extend_from_slice(&theta[i..i + m.nb - 1]);
                i += m.nb - 1;
                (b, StaticNonlinearity::Deadzone(*d))
            } else {
                let b = theta[i..i + m.nb].to_vec();
                i += m.nb;
                (b, StaticNonlinearity::Linear)
            };
            channels.push(InputChannel::new(m.name.clone(), m.nk, b, f)?);
        }
        let c = self.offset.then(|| theta[i]);
        Model::new(ts, a, channels, c)
    }
}

/// A MISO estimation problem: the inputs, the output y (Ts = `ts` s), na, the structure and whether a
/// constant c is estimated. [`MisoProblem::least_squares`] and [`MisoProblem::recursive`] fit it.
#[derive(Debug, Clone, Copy)]
pub struct MisoProblem<'a> {
    /// The inputs with their orders (and which are linear).
    pub inputs: &'a [MisoInput],
    /// y(k) (for the IPA: the position in mm).
    pub y: &'a [f64],
    /// Ts in s.
    pub ts: f64,
    /// na: order of A, common to every input.
    pub na: usize,
    /// ARX, or Hammerstein with a deadzone on every input not declared linear.
    pub kind: ModelKind,
    /// Whether a constant term c is estimated.
    pub offset: bool,
}

impl MisoProblem<'_> {
    /// The regression of this problem (checks the inputs).
    fn regression(&self) -> Result<Regression<'_>, SysidError> {
        Regression::new(self.inputs, self.y, self.na, self.kind, self.offset)
    }

    /// Least squares (module docs): one solve for ARX; for Hammerstein the key-term iteration, at most
    /// `max_iterations` solves.
    pub fn least_squares(&self, max_iterations: usize) -> Result<MisoFit, SysidError> {
        let reg = self.regression()?;
        let (theta, dz, iterations, converged) =
            key_term_iteration(&reg.nonlinear, max_iterations, |dz| reg.solve(dz))?;
        reg.fit(&theta, &dz, self.ts, iterations, converged)
    }

    /// The fit by `settings.estimator` ([`MisoProblem::fit`]) with the safeguards of one input applied
    /// per input ([`MisoProblem::safeguard`]); `settings.fallback` substitutes the linear start.
    pub fn identify(
        &self,
        settings: &crate::Identification,
        name: &str,
    ) -> Result<MisoFit, SysidError> {
        let fit = self.fit(&settings.estimator, name)?;
        self.safeguard(fit, settings.estimator.method(), settings.fallback, name)
    }

    /// The safeguards of `estimate::identify` for a several-input Hammerstein fit (by `method`):
    /// an estimate whose estimation simulation diverges, that is unstable while the linear ARX start is
    /// not, or whose simulation fit trails the start's by more than
    /// [`crate::estimate::FALLBACK_FIT_MARGIN`] points gets a warning, or with `fallback` is replaced by
    /// the linear start (b_l = b_r = 0, m_l = m_r = b1 on each nonlinear input); then each estimated
    /// deadzone is checked against its own input ([`crate::warnings::deadzone_warnings`]: breakpoint on
    /// an input level or within 1 σ of one, not bracketed, not physical, too few levels), the warning
    /// naming the input, and a breakpoint whose standard deviation is not meaningful loses it. ARX and
    /// all-linear fits are returned unchanged.
    pub fn safeguard(
        &self,
        mut fit: MisoFit,
        method: crate::Method,
        fallback: bool,
        name: &str,
    ) -> Result<MisoFit, SysidError> {
        let reg = self.regression()?;
        if !reg.nonlinear.iter().any(|&v| v) {
            return Ok(fit);
        }
        let us: Vec<&[f64]> = self.inputs.iter().map(|m| m.u.as_slice()).collect();
        let fit_sim = |m: &Model| {
            sysid_core::metrics::metrics_miso(m, &us, self.y, name)
                .ok()
                .and_then(|m| m.fit_sim_percent)
        };
        if let Some((linear, linear_fit)) = self.linear_start(&reg).and_then(|l| {
            let f = fit_sim(&l.model)?;
            Some((l, f))
        }) {
            if let Some(why) = crate::estimate::hammerstein_guard(
                method,
                fit_sim(&fit.model),
                fit.model.is_stable(),
                linear.model.is_stable(),
                linear_fit,
            ) {
                if fallback {
                    let mut warnings = std::mem::take(&mut fit.warnings);
                    warnings.push(Warning::Fallback {
                        used: format!(
                            "{} on each nonlinear input",
                            crate::estimate::LINEAR_START_USED
                        ),
                        why,
                    });
                    // The fallback's breakpoints are fixed at 0 by construction: nothing to check.
                    return Ok(MisoFit {
                        warnings,
                        notes: fit.notes,
                        iterations: fit.iterations,
                        converged: fit.converged,
                        ..linear
                    });
                }
                fit.warnings.push(Warning::LinearStartBetter { why });
            }
        }
        for (ch, m) in fit.model.inputs().iter().zip(self.inputs) {
            let Some(d) = ch.deadzone() else { continue };
            let std = |n: &str| {
                let full = format!("{n} ({})", ch.name());
                fit.params
                    .iter()
                    .find(|q| q.name == full)
                    .and_then(|q| q.std)
            };
            let (w, no_std) =
                crate::warnings::deadzone_warnings(d, &m.u, (true, true), (std("b_l"), std("b_r")));
            for n in no_std {
                let full = format!("{n} ({})", ch.name());
                for q in fit.params.iter_mut().filter(|q| q.name == full) {
                    q.std = None;
                }
            }
            fit.warnings
                .extend(w.into_iter().map(|w| Warning::ForInput {
                    input: ch.name().to_string(),
                    warning: Box::new(w),
                }));
        }
        Ok(fit)
    }

    /// The linear ARX least-squares model of the same orders, written as a Hammerstein model (each
    /// nonlinear input: b_l = b_r = 0, m_l = m_r = b1, B/b1), with standard deviations where the ARX
    /// regression gives them (a, linear inputs' B, c; m_l and m_r from b1); `None` when it cannot be
    /// estimated or a nonlinear input's b1 is 0.
    fn linear_start(&self, reg: &Regression) -> Option<MisoFit> {
        let arx = MisoProblem {
            kind: ModelKind::Arx,
            ..*self
        }
        .least_squares(1)
        .ok()?;
        let m = &arx.model;
        let mut channels = Vec::with_capacity(m.inputs().len());
        for (ch, &nl) in m.inputs().iter().zip(&reg.nonlinear) {
            if !nl {
                channels.push(ch.clone());
                continue;
            }
            let b1 = *ch.b().first()?;
            if b1 == 0.0 || !b1.is_finite() {
                return None;
            }
            let d = Deadzone {
                b_l: 0.0,
                b_r: 0.0,
                m_l: b1,
                m_r: b1,
            };
            let b = ch.b().iter().map(|v| v / b1).collect();
            let f = StaticNonlinearity::Deadzone(d);
            channels.push(InputChannel::new(ch.name().to_string(), ch.nk(), b, f).ok()?);
        }
        let model = Model::new(m.ts(), m.a().to_vec(), channels, m.offset()).ok()?;
        let arx_std = |n: &str| arx.params.iter().find(|q| q.name == n).and_then(|q| q.std);
        let (values, names) = miso_vector(&model);
        let std = |i: usize| {
            let n: &str = &names[i];
            let (head, input) = n.split_once(' ').unwrap_or((n, ""));
            match head {
                "m_l" | "m_r" => arx_std(&format!("b1 {input}")),
                "b_l" | "b_r" => None,
                _ if reg.nonlinear.iter().any(|&v| v) && head.starts_with('b') => {
                    // B/b1 of a nonlinear input has no standard deviation of its own here.
                    let linear = self
                        .inputs
                        .iter()
                        .zip(&reg.nonlinear)
                        .any(|(mi, &nl)| !nl && input == format!("({})", mi.name));
                    if linear {
                        arx_std(n)
                    } else {
                        None
                    }
                }
                _ => arx_std(n),
            }
        };
        let params = miso_params(&model, &names, |i| values[i], std);
        Some(MisoFit {
            model,
            params,
            ..arx
        })
    }

    /// The fit by the estimator `settings` says: least squares, RLS, output error or instrumental
    /// variables (`name` names the record in errors).
    pub fn fit(
        &self,
        settings: &crate::EstimatorSettings,
        name: &str,
    ) -> Result<MisoFit, SysidError> {
        match settings {
            crate::EstimatorSettings::Ls(st) => self.least_squares(st.max_iterations),
            crate::EstimatorSettings::Rls(st) => self.recursive(st),
            crate::EstimatorSettings::Oe(st) => {
                self.output_error(st.start.max_iterations, st.max_iterations, name)
            }
            crate::EstimatorSettings::Iv(st) => self.instrumental(st, name),
        }
    }

    /// Output error (docs/estimators.md, [`crate::oe::refine_miso`]): every parameter refined by
    /// minimising the free-run simulation error, started from [`MisoProblem::least_squares`] (at most
    /// `ls_iterations` key-term solves), at most `max_iterations` Levenberg–Marquardt iterations,
    /// constrained to stable models. As for one input, the start and the refinement are judged on the
    /// estimation simulation RMSE with estimated initial outputs and the better stable one is kept; the
    /// notes say which, and a warning when it is the start. `name` names the record in errors.
    pub fn output_error(
        &self,
        ls_iterations: usize,
        max_iterations: usize,
        name: &str,
    ) -> Result<MisoFit, SysidError> {
        let start = self.least_squares(ls_iterations)?;
        let us: Vec<&[f64]> = self.inputs.iter().map(|m| m.u.as_slice()).collect();
        let fit = crate::oe::refine_miso(&us, self.y, &start.model, max_iterations, name)?;
        let rmse = |m: &Model| {
            if !m.is_stable() {
                return None;
            }
            sysid_core::metrics::metrics_miso(m, &us, self.y, name)
                .ok()
                .and_then(|m| crate::trust::guarded_rmse(&m))
        };
        let verdict = OeVerdict::judge(&fit, &start.notes, rmse(&fit.model), rmse(&start.model));
        let converged = verdict.termination.converged();
        if verdict.fallback.is_none() {
            return Ok(MisoFit {
                model: fit.model,
                params: fit.params,
                noise_variance: fit.noise_variance,
                iterations: fit.iterations,
                converged,
                notes: verdict.notes,
                warnings: crate::trust::std_warning(fit.std_unavailable.clone())
                    .into_iter()
                    .collect(),
            });
        }
        Ok(MisoFit {
            iterations: fit.iterations,
            converged,
            notes: verdict.notes,
            warnings: verdict.fallback.into_iter().collect(),
            ..start
        })
    }

    /// Recursive instrumental variables in stages ([`crate::iv::staged`], the same implementation as
    /// for one input) with the settings `st`: the first auxiliary model is [`MisoProblem::least_squares`]
    /// (at most `st.start.max_iterations` key-term solves); the instruments z(k) are the regressor built
    /// from the auxiliary model's noise-free simulation driven by every input (as MATLAB `iv4` for
    /// several inputs), with each input's switching functions and x̂ from the auxiliary model's deadzone.
    /// Standard deviations from σ̂² (ZᵀΦ)⁻¹ ZᵀZ (ΦᵀZ)⁻¹, σ̂² the equation-error residual variance of the
    /// kept model (delta method for the breakpoints). `iterations` counts the stages; `converged` says
    /// whether θ̂ settled. `name` names the record in errors.
    pub fn instrumental(
        &self,
        st: &crate::InstrumentalVariables,
        name: &str,
    ) -> Result<MisoFit, SysidError> {
        let reg = self.regression()?;
        let start = self.least_squares(st.start.max_iterations)?;
        let (theta_start, start_dz) = key_term_vector(&reg, &start.model);
        let free = vec![true; reg.len()];
        let r = crate::iv::IvRegression {
            rows: (),
            y: self.y,
            k0: reg.k0,
            free: &free,
            name,
        };
        let us: Vec<&[f64]> = self.inputs.iter().map(|m| m.u.as_slice()).collect();
        let reg_ref = &reg;
        let out = crate::iv::staged(
            &start.model,
            &theta_start,
            &us,
            &r,
            |aux: &Model| {
                let dz = deadzones_of(aux, &start_dz);
                move |ys: &[f64], k: usize, row: &mut [f64]| reg_ref.fill_row_from(ys, &dz, k, row)
            },
            |theta| {
                let mut dz = start_dz.clone();
                reg.update_deadzones(theta.as_slice(), &mut dz);
                reg.model(theta.as_slice(), &dz, self.ts)
                    .map_err(|e| SysidError::Numerical(format!("{name}: {e}")))
            },
            st.stages,
            st.forgetting,
            st.p0,
        )?;
        let dz = deadzones_of(&out.model, &start_dz);
        let (phi, target) = stacked(std::slice::from_ref(&reg), &dz);
        let rss = (&target - &phi * &out.theta).norm_squared();
        let sigma2 = rss / phi.nrows().saturating_sub(phi.ncols()).max(1) as f64;
        let cov = crate::iv::covariance(&out.pass, sigma2);
        let params = params_with_cov(&reg, out.theta.as_slice(), cov.as_ref(), &out.model);
        Ok(MisoFit {
            model: out.model,
            params,
            noise_variance: sigma2,
            iterations: out.stages,
            converged: out.converged,
            notes: out.notes,
            warnings: Vec::new(),
        })
    }

    /// Recursive least squares (paper eqs. 9–12) with the settings `st` (forgetting, P(0), passes,
    /// covariance form). ARX: the recursion on φ(k) of the module docs. Hammerstein: recursive key-term
    /// separation as for one input — in the first pass each input's switching functions and x̂ use the
    /// deadzone of the latest estimate; each later pass restarts P = p0 I, keeps θ̂ and uses the deadzones
    /// of the estimate the pass started from. `iterations` counts the passes; `converged` says whether the
    /// estimate settled (relative change between the ends of two passes below
    /// [`crate::estimate::PASSES_SETTLED`] with `passes auto`, below 1e-3 with a fixed number of passes).
    /// With ρ = 1 and no windup protection, data that cannot determine θ are refused as by least squares.
    pub fn recursive(&self, st: &crate::RecursiveLeastSquares) -> Result<MisoFit, SysidError> {
        let (y, inputs, ts) = (self.y, self.inputs, self.ts);
        let reg = self.regression()?;
        let np = reg.len();
        let mut est = crate::estimate::recursive_estimator(np, st)?;
        let mut dz = vec![START_DEADZONE; inputs.len()];
        if st.forgetting == 1.0 && st.windup == crate::windup::Windup::None {
            // Persistent excitation, as for one input: only the rank verdict of the solve matters.
            if let Err(e @ SysidError::Data(_)) = reg.solve(&dz) {
                return Err(e);
            }
        }
        let hammer = reg.nonlinear.iter().any(|&v| v);
        let mut row = vec![0.0; np];
        let mut pass_ends: Vec<Vec<f64>> = Vec::new();
        let mut settled = false;
        let rel = |a: &[f64], b: &[f64]| {
            let d = a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum::<f64>();
            let s = b.iter().map(|v| v * v).sum::<f64>();
            d.sqrt() / (1e-300 + s.sqrt())
        };
        for pass in 0..st.passes.max() {
            if pass > 0 {
                est.restart_covariance(st.p0);
                if hammer {
                    reg.update_deadzones(est.theta(), &mut dz);
                }
            }
            for (k, &yk) in y.iter().enumerate().skip(reg.k0) {
                if hammer && pass == 0 && k > reg.k0 {
                    let theta = est.theta().to_vec();
                    reg.update_deadzones(&theta, &mut dz);
                }
                reg.fill_row(&dz, k, &mut row);
                est.update(&row, yk, k)?;
            }
            let end = est.theta().to_vec();
            if let (crate::Passes::UntilSettled { .. }, Some(prev)) = (st.passes, pass_ends.last())
            {
                if rel(&end, prev) <= crate::estimate::PASSES_SETTLED {
                    settled = true;
                    pass_ends.push(end);
                    break;
                }
            }
            pass_ends.push(end);
        }
        let theta = est.theta().to_vec();
        let converged = match st.passes {
            crate::Passes::UntilSettled { .. } => settled,
            crate::Passes::Fixed(_) => {
                pass_ends.len() >= 2 && rel(&pass_ends[pass_ends.len() - 2], &theta) < 1e-3
            }
        };
        if hammer {
            reg.update_deadzones(&theta, &mut dz);
        }
        reg.fit(&theta, &dz, ts, pass_ends.len(), converged)
    }
}

/// Φ and y of the regressions `regs` stacked (records one after the other: no row spans two), with the
/// deadzones `dz`.
fn stacked(regs: &[Regression], dz: &[Deadzone]) -> (DMatrix<f64>, DVector<f64>) {
    let rows: usize = regs.iter().map(Regression::rows).sum();
    let p = regs.first().map_or(0, Regression::len);
    let mut phi = DMatrix::zeros(rows, p);
    let mut target = DVector::zeros(rows);
    let mut at = 0;
    for reg in regs {
        let m = reg.matrix(dz);
        phi.rows_mut(at, reg.rows()).copy_from(&m);
        for (i, v) in reg.y[reg.k0..].iter().enumerate() {
            target[at + i] = *v;
        }
        at += reg.rows();
    }
    (phi, target)
}

/// The least-squares θ̂ of the stacked regressions `regs` with the deadzones `dz`.
fn solve_stacked(regs: &[Regression], dz: &[Deadzone]) -> Result<Vec<f64>, SysidError> {
    let (phi, target) = stacked(regs, dz);
    let names = regs.first().map_or(&[][..], |r| &r.names[..]);
    Ok(crate::ls::solve(&phi, &target, names)?
        .theta
        .iter()
        .copied()
        .collect())
}

/// The physical parameters of `model` (fitted as θ̂ with the deadzones `dz` on the stacked regressions
/// `regs`) with standard deviations from Cov(θ̂) = σ̂² (ΦᵀΦ)⁻¹, σ̂² = ‖y − Φθ̂‖² / (N − p) over the
/// stacked rows; the breakpoints by the delta method. Returns them with σ̂².
fn params_stacked(
    regs: &[Regression],
    theta: &[f64],
    dz: &[Deadzone],
    model: &Model,
) -> (Vec<NamedParam>, f64) {
    let (phi, target) = stacked(regs, dz);
    let names = regs.first().map_or(&[][..], |r| &r.names[..]);
    let th = DVector::from_column_slice(theta);
    let rss = (&target - &phi * &th).norm_squared();
    let dof = phi.nrows().saturating_sub(phi.ncols()).max(1);
    let sigma2 = rss / dof as f64;
    let cov = crate::ls::solve(&phi, &target, names)
        .ok()
        .map(|sol| sol.inv_gram * sigma2);
    match regs.first() {
        Some(r) => (params_with_cov(r, theta, cov.as_ref(), model), sigma2),
        None => (Vec::new(), sigma2),
    }
}

/// The physical parameters of `model` (θ̂ in the key-term layout of `reg`) with standard deviations
/// from Cov(θ̂) = `cov` (the breakpoints by the delta method).
fn params_with_cov(
    reg: &Regression,
    theta: &[f64],
    cov: Option<&DMatrix<f64>>,
    model: &Model,
) -> Vec<NamedParam> {
    let n_key = reg.n_key;
    let sd = |i: usize| {
        cov.map(|c| c[(i, i)])
            .filter(|v| v.is_finite() && *v >= 0.0)
            .map(f64::sqrt)
    };
    // Physical and key-term layouts differ only inside each deadzone block:
    // [b_l, b_r, m_l, m_r] against [m_r, m_r b_r, m_l, m_l b_l].
    let std = |i: usize| {
        if i >= n_key {
            return sd(i);
        }
        let t = i - i % 4;
        match i % 4 {
            0 => crate::estimate::ratio_with_std(theta, cov, t + 2, t + 3).1,
            1 => crate::estimate::ratio_with_std(theta, cov, t, t + 1).1,
            2 => sd(t + 2),
            _ => sd(t),
        }
    };
    let (values, pnames) = miso_vector(model);
    miso_params(model, &pnames, |i| values[i], std)
}

/// The key-term θ of `model` in the layout of `reg` (module docs) and its deadzones (one per input;
/// [`START_DEADZONE`] for a linear one).
fn key_term_vector(reg: &Regression, model: &Model) -> (Vec<f64>, Vec<Deadzone>) {
    let dz = deadzones_of(model, &vec![START_DEADZONE; reg.inputs.len()]);
    let mut theta = Vec::with_capacity(reg.len());
    for (d, &nl) in dz.iter().zip(&reg.nonlinear) {
        if nl {
            theta.extend([d.m_r, d.m_r * d.b_r, d.m_l, d.m_l * d.b_l]);
        }
    }
    theta.extend_from_slice(model.a());
    for (ch, &nl) in model.inputs().iter().zip(&reg.nonlinear) {
        theta.extend_from_slice(&ch.b()[usize::from(nl)..]);
    }
    theta.extend(model.offset());
    (theta, dz)
}

/// The deadzone of each input of `model`, `default[m]` for an input without one.
fn deadzones_of(model: &Model, default: &[Deadzone]) -> Vec<Deadzone> {
    model
        .inputs()
        .iter()
        .zip(default)
        .map(|(ch, d)| ch.deadzone().copied().unwrap_or(*d))
        .collect()
}

/// Least squares on several records at once (MATLAB `merge`): `records[r]` are the inputs of record r
/// (same names and orders in every record) and `ys[r]` its output. Each record has its own first row
/// k0, so no regression row spans two records; the rows are stacked into one solve (ARX) or one
/// key-term iteration (Hammerstein, at most `max_iterations` solves). Ts = `ts` s.
pub fn least_squares_merged(
    records: &[Vec<MisoInput>],
    ys: &[&[f64]],
    ts: f64,
    na: usize,
    kind: ModelKind,
    offset: bool,
    max_iterations: usize,
) -> Result<MisoFit, SysidError> {
    if records.is_empty() || records.len() != ys.len() {
        return Err(SysidError::Data(
            "merged estimation needs one output per record and at least one record".into(),
        ));
    }
    let regs = records
        .iter()
        .zip(ys)
        .map(|(inputs, y)| Regression::new(inputs, y, na, kind, offset))
        .collect::<Result<Vec<_>, _>>()?;
    let first = &regs[0];
    if regs.iter().any(|r| r.names != first.names) {
        return Err(SysidError::Data(
            "merged records must have the same inputs, in the same order, with the same orders"
                .into(),
        ));
    }
    let (theta, dz, iterations, converged) =
        key_term_iteration(&first.nonlinear, max_iterations, |dz| {
            solve_stacked(&regs, dz)
        })?;
    fit_stacked(&regs, &theta, &dz, ts, iterations, converged)
}

/// The fit of θ̂ with the deadzones `dz` on the stacked regressions `regs` (Ts = `ts` s): its model and
/// parameters with standard deviations ([`params_stacked`]).
fn fit_stacked(
    regs: &[Regression],
    theta: &[f64],
    dz: &[Deadzone],
    ts: f64,
    iterations: usize,
    converged: bool,
) -> Result<MisoFit, SysidError> {
    let Some(first) = regs.first() else {
        return Err(SysidError::Data("no record to fit".into()));
    };
    let model = first.model(theta, dz, ts)?;
    let (params, noise_variance) = params_stacked(regs, theta, dz, &model);
    Ok(MisoFit {
        model,
        params,
        noise_variance,
        iterations,
        converged,
        notes: Vec::new(),
        warnings: Vec::new(),
    })
}

/// Start of the key-term iteration: breakpoints at 0 and unit slopes, so that x̂ = u in the b2.. columns of
/// the first solve.
pub const START_DEADZONE: Deadzone = Deadzone {
    b_l: 0.0,
    b_r: 0.0,
    m_l: 1.0,
    m_r: 1.0,
};

/// θ̂, the deadzones and the number of solves of the key-term iteration: `solve` gives θ̂ for given
/// deadzones (one per input; θ starts with a key-term block [m_r, m_r b_r, m_l, m_l b_l] per input whose
/// `nonlinear` entry is true), the deadzones are updated from θ̂, until θ̂ changes by less than 1e-10
/// (relative to its largest entry) or after `max_iterations` solves. Without a nonlinear input, one solve.
/// The last entry says whether it converged (always true without a nonlinear input).
pub(crate) fn key_term_iteration(
    nonlinear: &[bool],
    max_iterations: usize,
    solve: impl Fn(&[Deadzone]) -> Result<Vec<f64>, SysidError>,
) -> Result<(Vec<f64>, Vec<Deadzone>, usize, bool), SysidError> {
    let update = |theta: &[f64], dz: &mut [Deadzone]| update_deadzones(nonlinear, theta, dz);
    let mut dz = vec![START_DEADZONE; nonlinear.len()];
    let mut theta = solve(&dz)?;
    let mut iterations = 1;
    update(&theta, &mut dz);
    let mut converged = !nonlinear.iter().any(|&v| v);
    if !converged {
        while iterations < max_iterations.max(1) {
            let next = solve(&dz)?;
            iterations += 1;
            let change = next
                .iter()
                .zip(&theta)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            let scale = next.iter().fold(1e-300_f64, |m, v| m.max(v.abs()));
            theta = next;
            update(&theta, &mut dz);
            if change <= 1e-10 * scale {
                converged = true;
                break;
            }
        }
    }
    Ok((theta, dz, iterations, converged))
}

/// The deadzones `dz` updated from the key-term blocks [m_r, m_r b_r, m_l, m_l b_l] at the start of θ̂,
/// one block per input whose `nonlinear` entry is true (the others keep theirs).
fn update_deadzones(nonlinear: &[bool], theta: &[f64], dz: &mut [Deadzone]) {
    let mut i = 0;
    for (d, &nl) in dz.iter_mut().zip(nonlinear) {
        if nl {
            *d = deadzone_from_theta(&theta[i..i + 4], *d, f64::INFINITY);
            i += 4;
        }
    }
}

/// Entry `c` of the regressor φ(k) (module docs).
#[allow(clippy::too_many_arguments)]
fn regressor(
    inputs: &[MisoInput],
    nonlinear: &[bool],
    dz: &[Deadzone],
    y: &[f64],
    na: usize,
    offset: bool,
    k: usize,
    c: usize,
) -> f64 {
    let mut c = c;
    for ((m, &nl), d) in inputs.iter().zip(nonlinear).zip(dz) {
        if nl {
            if c < 4 {
                let uk = m.u[k - m.nk];
                let (hr, hl) = (d.h_r(uk), d.h_l(uk));
                return [hr * uk, -hr, hl * uk, -hl][c];
            }
            c -= 4;
        }
    }
    if c < na {
        return -y[k - 1 - c];
    }
    c -= na;
    for ((m, &nl), d) in inputs.iter().zip(nonlinear).zip(dz) {
        let (from, count) = if nl { (1, m.nb - 1) } else { (0, m.nb) };
        if c < count {
            let u = m.u[k - m.nk - (from + c)];
            return if nl { d.apply(u) } else { u };
        }
        c -= count;
    }
    if offset && c == 0 {
        1.0
    } else {
        0.0
    }
}
