//! Warnings: when an estimate may not deserve trust, the tool says so in words (the `warnings` list of
//! `identify --json`, `warning: ...` lines in the text). Each [`Warning`] is typed; its `Display` is
//! the sentence users read. The checks of a static nonlinearity against its data are its block's
//! (module `blocks`).

use serde::{Serialize, Serializer};
use sysid_core::stability::NotSettling;
use sysid_core::{Model, ParamName};

/// Which record a warning is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Record {
    /// The estimation data.
    Estimation,
    /// The validation data.
    Validation,
    /// The selection part of the estimation data, on which `order` ranks its candidates.
    Selection,
    /// The test record of `order`, never used to choose.
    Test,
}

impl std::fmt::Display for Record {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Record::Estimation => "estimation",
            Record::Validation => "validation",
            Record::Selection => "selection",
            Record::Test => "test",
        })
    }
}

/// A deadzone branch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Branch {
    /// u <= b_l.
    Left,
    /// u >= b_r.
    Right,
}

impl std::fmt::Display for Branch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Branch::Left => "left",
            Branch::Right => "right",
        })
    }
}

/// A reason not to trust an estimate blindly.
#[derive(Debug, Clone, PartialEq)]
pub enum Warning {
    /// A pole beyond the unit circle ([`sysid_core::Stability::Unstable`]: |p| > 1 + ε, or a pole
    /// that is not a number).
    Unstable {
        /// Largest pole modulus (NaN for a pole that is not a number).
        max_pole_modulus: f64,
    },
    /// A pole at z = 1 within ε = [`sysid_core::stability::MARGIN`] ([`sysid_core::Stability::Integrator`]):
    /// over any practical record the model integrates, and the data rarely determine such a mode unless
    /// the plant integrates (an output-error search holds it at the stability boundary to imitate a
    /// level or a drift).
    NearIntegrator {
        /// Modulus of the pole at 1.
        max_pole_modulus: f64,
        /// The model already carries an output level (an offset or a removed operating point), so
        /// "add one" is not the advice.
        has_level: bool,
    },
    /// A pole on the unit circle away from z = 1 ([`sysid_core::Stability::OnCircle`]): the model
    /// oscillates without decay.
    OnCircle {
        /// Real part of the pole.
        re: f64,
        /// Imaginary part of the pole.
        im: f64,
    },
    /// The free-run simulation does no better than the mean of the record (fit <= 0 %), or diverges.
    PoorSimulation {
        /// Which record.
        record: Record,
        /// The fit % (`None`: the simulation diverged).
        fit_percent: Option<f64>,
    },
    /// The estimator stopped before its convergence criterion.
    NotConverged {
        /// How it stopped, in words.
        how: String,
    },
    /// The method's own Hammerstein estimate diverged or trails the linear ARX start, which was not
    /// substituted (fallback off).
    LinearStartBetter {
        /// What is wrong with the estimate.
        why: String,
    },
    /// Another estimate than the method's own result was returned.
    Fallback {
        /// What was returned.
        used: String,
        /// Why.
        why: String,
    },
    /// A breakpoint sits on one of the input's levels, or within its standard deviation of one: the
    /// loss has a kink there, so the quadratic approximation behind the standard deviation fails.
    BreakpointOnInputLevel {
        /// b_l or b_r.
        name: ParamName,
        /// Its value.
        value: f64,
        /// The level (counts).
        level: f64,
        /// The standard deviation the estimate had (withheld from the report), when the breakpoint is
        /// not on the level but within this standard deviation of it.
        std: Option<f64>,
    },
    /// A breakpoint outside the range of the input: no data on one side of it.
    BreakpointNotBracketed {
        /// b_l or b_r.
        name: ParamName,
        /// Its value.
        value: f64,
        /// Smallest input.
        u_min: f64,
        /// Largest input.
        u_max: f64,
    },
    /// b_l > b_r, or slopes of opposite sign.
    NonPhysicalDeadzone {
        /// What is wrong.
        why: String,
    },
    /// A deadzone that is no valve deadzone around u = 0 ([`ipa_embedded::Deadzone::is_physical`]:
    /// b_l ≤ 0 ≤ b_r and m_l, m_r > 0, in the command's units, breakpoints rounded as the compensators
    /// round them): a deadzone compensator (`control --compensate-deadzone`, `tune`, the C API) refuses
    /// it ([`Warning::if_deadzone_not_a_valve`]). For a record of another plant it may be right.
    DeadzoneNotAValve {
        /// b_l in the command's units (counts for the IPA).
        b_l: f64,
        /// b_r in the command's units.
        b_r: f64,
        /// m_l (x per unit of u).
        m_l: f64,
        /// m_r (x per unit of u).
        m_r: f64,
        /// The operating point's u0 added to the model's breakpoints (a detrended model), if not 0.
        u0: Option<f64>,
        /// The branch whose side of u = 0 the estimation record never drove (a one-sided input): its
        /// slope is held at 0, not estimated (fix34 leftover: it was called "does not respond").
        not_driven: Option<Branch>,
    },
    /// A check of an input nonlinearity other than the deadzone failed: a shape that is not physical
    /// (crossed limits, a non-monotone map), a segment without data.
    NonlinearityShape {
        /// The kind (`saturation`, `piecewise-linear`...).
        kind: &'static str,
        /// What is wrong.
        why: String,
    },
    /// A warning about the deadzone of one input of a several-input model.
    ForInput {
        /// The input's name.
        input: String,
        /// The warning (one of the deadzone checks).
        warning: Box<Warning>,
    },
    /// A deadzone branch with fewer than two distinct input levels beyond its breakpoint: its slope and
    /// breakpoint are not separately determined.
    FewInputLevels {
        /// Which branch.
        branch: Branch,
        /// Distinct levels beyond the breakpoint.
        levels: usize,
    },
    /// A polynomial NARX model whose terms contain no input: it cannot respond to the input, and its
    /// free run is only the decay of its initial outputs.
    NoInputTerm {
        /// Number of (output-only or constant) terms the model has.
        terms: usize,
    },
    /// A deadzone that holds every input level of the record: the input block's output is zero
    /// throughout, so the model cannot respond to the input.
    InputSwallowed {
        /// b_l, b_r of the deadzone.
        breakpoints: (f64, f64),
        /// The smallest and largest input of the record.
        range: (f64, f64),
    },
    /// The output-error search from the IV start ended lower than the one from the LS start by more
    /// than [`crate::methods::LOCAL_MINIMA_MARGIN`] (relative): the search from LS (the only one before
    /// session 34) stopped in a local minimum, and the criterion has several on this record, so the end
    /// kept (IV's) need not be the global minimum either (audit s34 H-1).
    LocalMinima {
        /// RSS at the end of the search from the LS start.
        rss_ls: f64,
        /// RSS at the end of the search from the IV start (the end kept).
        rss_iv: f64,
    },
    /// The recursive estimator's covariance lost its positive definiteness to rounding under the
    /// trace bound (standard form) and was restarted at P = (T/n) I, θ̂ kept
    /// (`rls_ud::RobustRls::update`; audit s35c).
    CovarianceReset(crate::rls_ud::CovarianceResets),
    /// A trust check (module `trust`: initial state, baseline, standard deviations).
    Trust(Concern),
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::Unstable { max_pole_modulus } => NotSettling::Unstable {
                max_pole_modulus: *max_pole_modulus,
            }
            .fmt(f),
            Warning::NearIntegrator {
                max_pole_modulus,
                has_level,
            } => NotSettling::Integrator {
                max_pole_modulus: *max_pole_modulus,
                has_level: *has_level,
            }
            .fmt(f),
            Warning::OnCircle { re, im } => NotSettling::OnCircle { re: *re, im: *im }.fmt(f),
            Warning::PoorSimulation {
                record,
                fit_percent: Some(fit),
            } if *fit < 0.0 => write!(
                f,
                "negative simulation fit on the {record} data ({fit:.2} %, the worse of estimated and \
                 measured initial outputs): the model simulates worse than the record's mean"
            ),
            Warning::PoorSimulation {
                record,
                fit_percent: Some(fit),
            } if *fit <= 0.0 => write!(
                f,
                "simulation fit of {fit:.2} % on the {record} data (the worse of estimated and measured \
                 initial outputs): the model simulates no better than the record's mean (a constant \
                 output)"
            ),
            Warning::PoorSimulation {
                record,
                fit_percent: Some(fit),
            } => write!(
                f,
                "simulation fit of {fit:.2} % on the {record} data (the worse of estimated and measured \
                 initial outputs), below {POOR_HELD_OUT_FIT} %: the model simulates hardly better than \
                 the record's mean (a constant output); it has not learned the input–output behaviour \
                 this record shows"
            ),
            Warning::PoorSimulation {
                record,
                fit_percent: None,
            } => write!(f, "the free-run simulation diverges on the {record} data"),
            Warning::NotConverged { how } => write!(f, "not converged: {how}"),
            Warning::Fallback { used, why } => write!(f, "fallback used: {used}, because {why}"),
            Warning::LinearStartBetter { why } => write!(
                f,
                "{why}; the linear ARX model of the same orders does better (the fallback option returns \
                 it as a Hammerstein model with b_l = b_r = 0)"
            ),
            Warning::BreakpointOnInputLevel {
                name,
                value,
                level,
                std: None,
            } => write!(
                f,
                "{name} = {value:.6} lies on the input level {level}: the criterion has a kink there, so \
                 its standard deviation is not meaningful (not reported)"
            ),
            Warning::BreakpointOnInputLevel {
                name,
                value,
                level,
                std: Some(std),
            } => write!(
                f,
                "{name} = {value:.6} is {} from the input level {level}, less than its standard deviation \
                 {}: the criterion has a kink within that uncertainty, so the standard deviation is not \
                 meaningful (not reported)",
                small(value - level),
                // A deviation of volts (5e-5) read "0.000" beside a distance of 2.2e-5 (audit s14 L-m).
                small(*std)
            ),
            Warning::BreakpointNotBracketed {
                name,
                value,
                u_min,
                u_max,
            } => write!(
                f,
                "{name} = {value:.6} is not bracketed by the data (input range {u_min} .. {u_max}): no \
                 samples on one side of it, so it is not determined and its standard deviation is not \
                 meaningful (not reported)"
            ),
            Warning::NonPhysicalDeadzone { why } => write!(f, "deadzone not physical: {why}"),
            Warning::DeadzoneNotAValve {
                b_l,
                b_r,
                m_l,
                m_r,
                u0,
                not_driven,
            } => {
                let v = |x: f64| sysid_core::format::sig(x, 6);
                let mut what = Vec::new();
                if ![b_l, b_r, m_l, m_r].iter().all(|x| x.is_finite()) {
                    what.push("a parameter is not a finite number".to_string());
                }
                if *b_l > 0.0 {
                    what.push(format!(
                        "b_l = {} > 0 (a small negative command already moves the output)",
                        v(*b_l)
                    ));
                }
                if *b_r < 0.0 {
                    what.push(format!(
                        "b_r = {} < 0 (a small positive command does not move the output, and a \
                         zero command drives it)",
                        v(*b_r)
                    ));
                }
                for (name, m, branch) in [("m_l", m_l, Branch::Left), ("m_r", m_r, Branch::Right)] {
                    if *m == 0.0 && *not_driven == Some(branch) {
                        continue; // said below, as the record's
                    }
                    if *m == 0.0 {
                        what.push(format!("{name} = 0 (that branch does not respond)"));
                    } else if *m < 0.0 {
                        what.push(format!(
                            "{name} = {} < 0 (a larger command on that side lowers the output)",
                            v(*m)
                        ));
                    }
                }
                let units = match u0 {
                    Some(u0) => format!(
                        " (breakpoints in the command's units: the model's plus its operating \
                         point u0 = {})",
                        v(*u0)
                    ),
                    None => String::new(),
                };
                if let Some(branch) = not_driven {
                    let (side, m) = match branch {
                        Branch::Left => ("u < 0", "m_l"),
                        Branch::Right => ("u > 0", "m_r"),
                    };
                    let also = if what.is_empty() {
                        String::new()
                    } else {
                        format!(" (and: {}{units})", what.join("; "))
                    };
                    return write!(
                        f,
                        "the record never drives the {branch} side of the deadzone ({side}): that \
                         branch is not estimated ({m} = 0 is held, not measured), so a deadzone \
                         compensator cannot use this deadzone (control --compensate-deadzone, tune \
                         and the C API refuse it){also}; record both sides of the command to identify \
                         one"
                    );
                }
                write!(
                    f,
                    "the deadzone is not a valve deadzone around u = 0 (b_l <= 0 <= b_r, slopes \
                     m_l, m_r > 0): {}{units}; a deadzone compensator will refuse it (control \
                     --compensate-deadzone, tune, the C API); for a plant without such a valve the \
                     fit itself may still be right",
                    what.join("; ")
                )
            }
            Warning::NonlinearityShape { kind, why } => write!(f, "{kind} nonlinearity: {why}"),
            Warning::ForInput { input, warning } => write!(f, "input {input}: {warning}"),
            Warning::FewInputLevels { branch, levels } => write!(
                f,
                "too few distinct input levels on the {branch} deadzone branch ({levels} beyond its \
                 breakpoint; at least 2 are needed to separate slope and breakpoint)"
            ),
            Warning::NoInputTerm { terms } => write!(
                f,
                "the model has no input term (its {terms} term(s) are lagged outputs or the constant): it \
                 cannot respond to the input and its simulation is only the decay of its initial outputs \
                 — do not use it; lower the degree, change the lags or the stopping rule"
            ),
            Warning::InputSwallowed {
                breakpoints: (b_l, b_r),
                range: (lo, hi),
            } => write!(
                f,
                "the deadzone [b_l, b_r] = [{b_l}, {b_r}] holds every input of the record ({lo} to {hi}): \
                 the model does not respond to the input and its simulation is only the decay of its \
                 initial outputs — do not use it; try other orders, --method ls or a linear input"
            ),
            Warning::LocalMinima { rss_ls, rss_iv } => write!(
                f,
                "the output-error criterion has several local minima on this record: the search from the \
                 LS start stopped in one (simulation RSS {rss_ls:.4e}), the search from the IV start went \
                 lower ({rss_iv:.4e}) and its end is kept, but it need not be the best model either: \
                 compare --method iv, and prefer a record that starts at rest with an input of more levels \
                 and a larger amplitude"
            ),
            Warning::CovarianceReset(r) => write!(
                f,
                "the RLS covariance P lost its positive definiteness to rounding {} (first at sample {}) \
                 under the trace bound (eq. 12 in the standard form, over a stretch without excitation) \
                 and was restarted at P = (T/n) I with tr P = T = {}, keeping θ̂: the estimate goes on, \
                 but what P had learnt was dropped there; directional forgetting (--windup \
                 directional) or the UD form (identify --rls-form ud) keeps P positive definite",
                if r.count == 1 {
                    "once".to_string()
                } else {
                    format!("{} times", r.count)
                },
                r.first_sample,
                sysid_core::format::shortest(r.bound)
            ),
            Warning::Trust(c) => c.fmt(f),
        }
    }
}

impl Warning {
    /// The record whose figures this warning judges, for the warnings made from a record's metrics
    /// (a poor simulation, a flattering initial state, a fit below the baseline); `None` for the others
    /// (they are about the model or the estimation itself).
    pub fn record(&self) -> Option<Record> {
        match self {
            Warning::PoorSimulation { record, .. }
            | Warning::Trust(Concern::InitialStateFlatters { record, .. })
            | Warning::Trust(Concern::BelowBaseline { record, .. })
            | Warning::Trust(Concern::InputDynamicsLeft { record, .. })
            | Warning::Trust(Concern::HeldOutDrop {
                held_out: record, ..
            }) => Some(*record),
            _ => None,
        }
    }

    /// Whether this warning already says why the parameter named `param` (as in a several-input
    /// parameter list: `b_l (u1)`) has no standard deviation: a breakpoint warning naming it, or the
    /// linear start returned by the fallback (its breakpoints are fixed at 0 and its B/b1 not estimated
    /// as such).
    pub fn explains_missing_std(&self, param: &str) -> bool {
        match self {
            Warning::Fallback { used, .. } => used.starts_with(LINEAR_START_USED),
            Warning::BreakpointOnInputLevel { name, .. }
            | Warning::BreakpointNotBracketed { name, .. } => *name == param,
            // `b_l (u1)`: the breakpoint warning of input u1 names `b_l`.
            Warning::ForInput { input, warning } => param
                .strip_suffix(&format!(" ({input})"))
                .is_some_and(|name| warning.explains_missing_std(name)),
            _ => false,
        }
    }

    /// The warning of `model`'s stability verdict ([`Model::stability`]): [`Warning::Unstable`],
    /// [`Warning::NearIntegrator`] or [`Warning::OnCircle`]; `None` when it settles.
    pub fn if_not_settling(model: &Model) -> Option<Warning> {
        model.not_settling().map(|why| match why {
            NotSettling::Unstable { max_pole_modulus } => Warning::Unstable { max_pole_modulus },
            NotSettling::Integrator {
                max_pole_modulus,
                has_level,
            } => Warning::NearIntegrator {
                max_pole_modulus,
                has_level,
            },
            NotSettling::OnCircle { re, im } => Warning::OnCircle { re, im },
        })
    }

    /// [`Warning::DeadzoneNotAValve`] for each input of `model` whose deadzone, in the command's units
    /// ([`Model::command_deadzone`]), is not a valve deadzone by the one rule the compensators apply:
    /// [`ipa_embedded::Deadzone::is_physical`] after [`ipa_embedded::deadzone::rounded_breakpoints`]
    /// with u_max the largest |u| of the model's estimation data (its `data_range`; 0 without one: no
    /// rounding), so that a breakpoint within 1e-9 · u_max of 0 counts as 0, as `control` takes it at
    /// its --u-max. Wrapped in [`Warning::ForInput`] for a several-input model. What `identify`
    /// (its report, in memory and read in passes) and `validate` (its report, Python `Model.metrics`)
    /// say of a deadzone that `control --compensate-deadzone`, `tune` and the C API refuse (audit s33
    /// L-5).
    pub fn if_deadzone_not_a_valve(model: &Model) -> Vec<Warning> {
        let several = model.inputs().len() > 1;
        let u0 = |i: usize| {
            model
                .operating_point()
                .and_then(|o| o.u.get(i).copied())
                .filter(|u0| *u0 != 0.0)
        };
        model
            .inputs()
            .iter()
            .enumerate()
            .filter_map(|(i, input)| {
                let d = model.command_deadzone(i)?;
                let u_max = model
                    .data_range()
                    .and_then(|r| r.u.get(i))
                    .map_or(0.0, |[lo, hi]| lo.abs().max(hi.abs()));
                let (b_l, b_r) = ipa_embedded::deadzone::rounded_breakpoints(d.b_l, d.b_r, u_max);
                let valve = ipa_embedded::Deadzone {
                    b_l,
                    b_r,
                    m_l: d.m_l,
                    m_r: d.m_r,
                };
                if valve.is_physical() {
                    return None;
                }
                // A branch held at slope 0 on a side of u = 0 the record never reached (a one-sided
                // input: its [min, max] in the command's units).
                let range = model.data_range().and_then(|r| r.u.get(i)).copied();
                let not_driven = match range {
                    Some([lo, _]) if d.m_l == 0.0 && lo >= 0.0 => Some(Branch::Left),
                    Some([_, hi]) if d.m_r == 0.0 && hi <= 0.0 => Some(Branch::Right),
                    _ => None,
                };
                let w = Warning::DeadzoneNotAValve {
                    b_l: d.b_l,
                    b_r: d.b_r,
                    m_l: d.m_l,
                    m_r: d.m_r,
                    u0: u0(i),
                    not_driven,
                };
                Some(if several {
                    Warning::ForInput {
                        input: input.name().to_string(),
                        warning: Box::new(w),
                    }
                } else {
                    w
                })
            })
            .collect()
    }

    /// [`Warning::PoorSimulation`] when the simulation fit % on `record` is at most 0 (no better than
    /// the record's mean), on a held-out record (validation, test) below [`POOR_HELD_OUT_FIT`] (hardly
    /// better than the mean), or missing (the simulation diverged).
    pub fn if_poor_simulation(record: Record, fit_percent: Option<f64>) -> Option<Warning> {
        match fit_percent {
            Some(f) if f >= poor_fit_level(record) && f > 0.0 => None,
            other => Some(Warning::PoorSimulation {
                record,
                fit_percent: other,
            }),
        }
    }
}

/// The words of the fallback warning: what replaced a Hammerstein estimate.
pub(crate) const LINEAR_START_USED: &str =
    "the linear ARX least-squares model, as a Hammerstein model with b_l = b_r = 0 and m_l = m_r = b1";

impl Serialize for Warning {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

/// A reason not to trust a figure, in words by `Display`.
#[derive(Debug, Clone, PartialEq)]
pub enum Concern {
    /// The fit from estimated initial outputs exceeds the fit from the measured ones by more than
    /// [`INITIAL_STATE_MARGIN`] points (or the other way round).
    InitialStateFlatters {
        /// Which record.
        record: Record,
        /// Fit % from estimated initial outputs (the headline).
        estimated: f64,
        /// Fit % from the measured initial outputs.
        measured: f64,
    },
    /// The model's guarded fit trails the linear least-squares ARX baseline by more than the margin.
    BelowBaseline {
        /// Which record.
        record: Record,
        /// The model's guarded fit %.
        fit: f64,
        /// The baseline's guarded fit %.
        baseline: f64,
    },
    /// Estimated parameters whose value lies within [`POORLY_DETERMINED_SIGMAS`] standard deviations of
    /// zero: the data do not tell them from 0 (MATLAB's `present` shows the same ± without a word).
    PoorlyDetermined {
        /// What they are: "parameters" (ARX, Hammerstein) or "terms" (NARX).
        noun: &'static str,
        /// Each as "name = value ± std".
        which: Vec<String>,
        /// How many were estimated with a standard deviation.
        of: usize,
    },
    /// No standard deviation could be computed.
    NoStandardDeviations {
        /// Why (a singular information matrix, a pole pinned on the stability boundary, ...).
        why: String,
    },
    /// The simulation fit on a held-out record (validation, test) trails the fit on the record the
    /// model was estimated on or chosen by (estimation, selection) by more than [`HELD_OUT_DROP`]
    /// points (audit s21 M-A1: the gas furnace's 92 % on its first half, 53 % on its second).
    HeldOutDrop {
        /// The record the model was fitted or chosen on.
        fitted: Record,
        /// Its fit % (the worse of estimated and measured initial outputs).
        fitted_fit: f64,
        /// The held-out record.
        held_out: Record,
        /// Its fit % (the same measure).
        held_out_fit: f64,
    },
    /// The residuals of a record are correlated with an earlier input beyond
    /// [`INPUT_CORRELATION_BANDS`] times the 99 % band and above [`INPUT_CORRELATION_LEVEL`]
    /// (`trust::input_dynamics_left`): input dynamics are left out of the model (audit s20 M-1).
    InputDynamicsLeft {
        /// Which record.
        record: Record,
        /// The input's name when the model has several; `None` for one.
        input: Option<String>,
        /// The lag τ ≥ 0 (samples) of the largest |r_εu(τ)|.
        lag: usize,
        /// r_εu(τ) there.
        r: f64,
        /// The per-lag 99 % band 2.58/√N.
        bound: f64,
    },
    /// An equation-error estimate (ls, rls) whose estimation residuals are not white and correlated at
    /// lag 1 below −[`OUTPUT_NOISE_LAG1`] (`trust::output_noise_bias`): white noise e on the measured
    /// output makes the equation error A(q) e, whose lag-1 correlation is negative (−0.69 for the
    /// paper's A), and biases the estimate (audit s34 M-2: a₁ −1.64 ± 0.011 against −1.869 at 0.05 mm of
    /// noise, b_r of the wrong sign in 20 of 20 seeds, with no warning).
    OutputNoiseBias {
        /// The method (`ls` or `rls`).
        method: &'static str,
        /// r_ε(1) of the estimation residuals.
        r1: f64,
    },
    /// A recursive estimate (iv, `track`'s rls with ρ = 1) whose final P still holds more than
    /// [`PRIOR_SHARE`] of its start P(0) = p0 I in some direction (`trust::prior_warning`): the
    /// recursion is least squares regularised by I / p0, and with regressors small against 1/p0 (signals
    /// in small units: y in metres, a sensor in volts) the regularisation pulls the estimate towards its
    /// start (audit s35 H-1, H-3: iv returned its LS start as "1 stage, converged" at y × 1e-7; `track`
    /// reported a₁ = −1.27 for −1.69 at y × 1e-4, both without a word).
    PriorWeighs {
        /// `iv` or `rls` (identify's), or `track` (`track`'s rls, whose advice is its own flags).
        method: &'static str,
        /// σ_max(P) / p0.
        share: f64,
        /// p0.
        p0: f64,
    },
}

/// The share σ_max(P) / p0 of a recursive estimate's start P(0) = p0 I left in its final P above which
/// [`Concern::PriorWeighs`] is said: 1e-3 (the start then weighs at least 0.1 % in the estimate's
/// weakest direction). Well-scaled records are far below it (the IPA's `est.csv` for iv: about 1e-9).
pub const PRIOR_SHARE: f64 = 1e-3;

/// The lag-1 residual correlation below whose negative an equation-error estimate with residuals that
/// are not white is warned of as biased by output noise ([`Concern::OutputNoiseBias`]): 0.3, as
/// [`INPUT_CORRELATION_LEVEL`] (9 % of the residual variance). Unmodelled dynamics leave positive lag-1
/// correlations; a negative one this large is the moving average A(q) e of output noise.
pub const OUTPUT_NOISE_LAG1: f64 = 0.3;

impl std::fmt::Display for Concern {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Concern::InitialStateFlatters {
                record,
                estimated,
                measured,
            } => write!(
                f,
                "the simulation fit on the {record} data depends on the initial state: {estimated:.2} % \
                 from estimated initial outputs against {measured:.2} % from the measured ones (more than \
                 {INITIAL_STATE_MARGIN} points apart; a slow or spurious mode is being fitted by the initial \
                 state): trust the lower figure"
            ),
            Concern::BelowBaseline {
                record,
                fit,
                baseline,
            } => write!(
                f,
                "the model simulates the {record} data far worse than the plain linear least-squares ARX of \
                 the same orders (fit {fit:.2} % against {baseline:.2} %, the worse of both initial states)"
            ),
            Concern::PoorlyDetermined { noun, which, of } => write!(
                f,
                "{} of {of} {noun} within {POORLY_DETERMINED_SIGMAS} standard deviations of zero \
                 (poorly determined: the data do not tell them from 0; fewer {noun}, a lower order or a \
                 richer input may help): {}",
                which.len(),
                which.join(", ")
            ),
            Concern::HeldOutDrop {
                fitted,
                fitted_fit,
                held_out,
                held_out_fit,
            } => write!(
                f,
                "the simulation fit falls from {fitted_fit:.2} % on the {fitted} data to \
                 {held_out_fit:.2} % on the {held_out} data ({:.1} points, more than {HELD_OUT_DROP}; \
                 free-run simulations, the worse of estimated and measured initial outputs where both \
                 are computed): the {fitted} fit flatters \
                 the model, the {held_out} figure is the one to trust; the records may differ (another \
                 operating point or input range) or the model may fit the {fitted} record's noise — \
                 compare the records, or try a lower order or other data to estimate on",
                fitted_fit - held_out_fit
            ),
            Concern::NoStandardDeviations { why } => {
                write!(f, "no standard deviation could be computed: {why}")
            }
            Concern::OutputNoiseBias { method, r1 } => write!(
                f,
                "the estimation residuals of this {method} estimate are not white and negatively \
                 correlated at lag 1 (r = {r1:.3}): the signature of noise on the measured output, under \
                 which {method} is biased (its equation error is then A(q)·e, not white; the ± do not \
                 cover the bias): estimate with --method oe or --method iv, which noise at the output \
                 does not bias"
            ),
            Concern::PriorWeighs { method, share, p0 } => write!(
                f,
                "the {} estimate is still pulled towards its start: the recursion's covariance \
                 keeps {:.1} % of its start P(0) = p0·I (p0 = {}) in its weakest excited direction, so \
                 the data did not outweigh the start there (regressors small against 1/p0: signals in \
                 small units such as metres or volts?); pass a larger --p0 or rescale the signals{}",
                if *method == "track" { "rls" } else { method },
                100.0 * share,
                sysid_core::format::shortest(*p0),
                if *method == "track" {
                    ""
                } else {
                    ", or use --method ls or oe, which have no such start"
                }
            ),
            Concern::InputDynamicsLeft {
                record,
                input,
                lag,
                r,
                bound,
            } => write!(
                f,
                "the {record} residuals are correlated with the input{} {lag} sample(s) earlier (r = \
                 {r:.3}, more than {INPUT_CORRELATION_BANDS} times the 99 % band ±{bound:.3} and above \
                 {INPUT_CORRELATION_LEVEL}): input dynamics are left out of the model (a wrong delay nk \
                 or too few b terms); find the delay with `ipa-sysid delay` and the orders with \
                 `ipa-sysid order`, or identify again with a larger --nk or --nb",
                input.as_ref().map_or(String::new(), |n| format!(" {n}"))
            ),
        }
    }
}

/// How many standard deviations from zero an estimated parameter must lie to count as determined
/// ([`Concern::PoorlyDetermined`]): |θ̂| < 2 σ̂ is, for a Gaussian estimate, a 95 % interval that holds 0.
pub const POORLY_DETERMINED_SIGMAS: f64 = 2.0;

/// How many times the per-lag 99 % band (2.58/√N) the largest input–residual correlation r_εu(τ),
/// τ ≥ 0, must exceed for [`Concern::InputDynamicsLeft`]. With [`INPUT_CORRELATION_LEVEL`]: on the
/// records of docs/real-data.md, 3× alone fires on long records for small correlations (EMPS r = 0.08
/// at 5× for N = 24 839, silverbox OE r = 0.10 at 5.7×), 0.3 alone on a short record whose test does
/// not even reject (coupled drives OE r = 0.35 at 1.6× for N = 144, p = 0.55).
pub const INPUT_CORRELATION_BANDS: f64 = 3.0;

/// The |r_εu(τ)| a [`Concern::InputDynamicsLeft`] needs besides [`INPUT_CORRELATION_BANDS`]: 0.3, an
/// input lag that explains 9 % of the residual variance on its own (the hair dryer with the default
/// nk = 1 shows r = 0.61 at lag 3, its delay).
pub const INPUT_CORRELATION_LEVEL: f64 = 0.3;

/// Percentage points by which the fits from estimated and from measured initial outputs may differ
/// before a warning says that the initial state flatters the headline.
pub const INITIAL_STATE_MARGIN: f64 = 5.0;

/// Percentage points by which the simulation fit on a held-out record (validation, test) may trail the
/// fit on the record the model was estimated on or chosen by before a warning says so
/// ([`Concern::HeldOutDrop`]). Ours: MATLAB's `compare` and SysIdentPy print both fits without a rule.
/// Chosen from the audit s21 sweep (9 real-record set-ups × 12 classes and methods, the worse of both
/// initial states, estimation fit positive): the held-out drops of the hair dryer (5.8–6.9 points),
/// the cascaded tanks (≤ 5.4), EMPS (≤ 13.3, its NARX 96.0 → 82.7 %) and the robot arm (≤ 1.6, and
/// 14.3 for a Hammerstein OE model that falls to −3.8 %, warned as negative) against the gas furnace's
/// halves (35–39) and the hydraulic actuator's (19–82); 15 lies in the gap between 14.3 and 19.2.
pub const HELD_OUT_DROP: f64 = 15.0;

/// The fit % below which a simulation on a held-out record (validation, test) is called hardly better
/// than the record's mean ([`Warning::PoorSimulation`]; on the estimation and selection records the
/// level is 0, where `order` disqualifies). At 5 % the simulation error's norm is 95 % of the output's
/// variation about its mean, ‖y − ŷ‖ / ‖y − ȳ‖ = 0.95: the model explains 1 − 0.95² ≈ 10 % of the
/// output's variance (audit s21 L-B3: a validation fit of 0.04 % was not warned).
pub const POOR_HELD_OUT_FIT: f64 = 5.0;

/// The fit % a simulation on `record` must reach for [`Warning::if_poor_simulation`] to stay silent
/// (and it must be above 0 on any record): [`POOR_HELD_OUT_FIT`] on a held-out record, 0 on the records
/// a model is fitted or chosen on.
fn poor_fit_level(record: Record) -> f64 {
    match record {
        Record::Validation | Record::Test => POOR_HELD_OUT_FIT,
        Record::Estimation | Record::Selection => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // A(q) = 1 − 0.9999995 q⁻¹: one pole at 0.9999995, within ε = sysid_core::stability::MARGIN of 1. Without an output
    // level the advice is to add one; with an offset c it must not repeat it.
    #[test]
    fn the_boundary_pole_advice_depends_on_whether_the_model_has_a_level() {
        let plain = Model::arx(1.0, vec![-0.9999995], vec![1.0], 1, None).unwrap();
        let levelled = Model::arx(1.0, vec![-0.9999995], vec![1.0], 1, Some(0.5)).unwrap();
        let w = Warning::if_not_settling(&plain).unwrap().to_string();
        assert!(w.contains("0.9999995") && w.contains("try --offset"), "{w}");
        let w = Warning::if_not_settling(&levelled).unwrap().to_string();
        assert!(w.contains("0.9999995") && !w.contains("--offset"), "{w}");
        assert!(w.contains("already has an output level"), "{w}");
        assert_eq!(Record::Selection.to_string(), "selection");
    }
}

/// |x| with three decimals, or in scientific notation below 1e-3 (where three decimals read as 0).
fn small(x: f64) -> String {
    let d = x.abs();
    if d >= 1e-3 {
        format!("{d:.3}")
    } else {
        format!("{d:.1e}")
    }
}

#[cfg(test)]
mod small_number_tests {
    use super::*;

    // The silverbox's breakpoint 2.2e-5 V from a level with σ 4.7e-5 V: both numbers shown, not "0.000".
    #[test]
    fn a_kink_warning_shows_small_deviations_in_scientific_notation() {
        let w = Warning::BreakpointOnInputLevel {
            name: crate::ParamName::BL,
            value: 0.005288,
            level: 0.0052659,
            std: Some(4.7e-5),
        };
        let text = w.to_string();
        assert!(
            text.contains(
                "is 2.2e-5 from the input level 0.0052659, less than its standard deviation 4.7e-5"
            ),
            "{text}"
        );
    }
}
