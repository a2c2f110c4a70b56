//! Plain-text reports printed by the command line (the libraries return data; printing is the
//! application's).

use report::format::num;
use sysid::metrics::Metrics;
use sysid::Method;
use sysid_summary::{IdentifyReport, ResidualEntry};

/// A row of the text metrics table: label and how to format the value from a [`Metrics`].
type MetricRow = (&'static str, fn(&Metrics) -> String);

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".into(), num)
}

/// A readable plain-text report of an identification (parameters ± std, poles, stability, metrics), as
/// `identify` prints it.
pub fn identify_report(r: &IdentifyReport) -> String {
    r.to_text()
}

trait ToText {
    fn to_text(&self) -> String;
}

impl ToText for IdentifyReport {
    fn to_text(&self) -> String {
        use std::fmt::Write;
        let mut s = String::new();
        header_text(self, &mut s);
        parameters_text(self, &mut s);
        poles_text(self, &mut s);
        metrics_text(self, &mut s);
        residuals_of(self, &mut s);
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
        }
        s
    }
}

/// The model, its orders, how it was estimated, each input, the estimator's note.
fn header_text(r: &IdentifyReport, s: &mut String) {
    use std::fmt::Write;
    let m = &r.model;
    let kind = match m.kind() {
        sysid::ModelKind::Arx => "Linear ARX".to_string(),
        sysid::ModelKind::Hammerstein if m.inputs().len() == 1 => format!(
            "Hammerstein ({} + ARX)",
            sysid::NonlinearityKind::of(m.input().nonlinearity())
        ),
        sysid::ModelKind::Hammerstein => "Hammerstein (static nonlinearities + ARX)".to_string(),
    };
    let kind = match m.output_nonlinearity() {
        Some(g) => format!("{kind} + output {}", sysid::NonlinearityKind::of(g)),
        None => kind,
    };
    let several = m.inputs().len() > 1;
    let orders = if several {
        format!("{} inputs, na = {}", m.inputs().len(), m.na())
    } else {
        format!("na = {} nb = {} nk = {}", m.na(), m.nb(), m.nk())
    };
    let _ = writeln!(
        s,
        "{kind} model, {orders}, Ts = {} s, estimated by {} ({} {}, {})",
        num(m.ts()),
        r.estimation.method,
        r.estimation.iterations,
        match r.estimation.method {
            Method::Ls | Method::Oe => "iteration(s)",
            Method::Rls => "pass(es)",
            Method::Iv => "stage(s)",
        },
        if r.estimation.converged {
            "converged"
        } else {
            "NOT converged"
        }
    );
    if let Some(returned) = &r.estimation.returned {
        let _ = writeln!(s, "returned: {returned} (see the fallback warning)");
    }
    if several {
        for ch in m.inputs() {
            let _ = writeln!(
                s,
                "  input {}: nb = {}, nk = {}, {}",
                ch.name(),
                ch.nb(),
                ch.nk(),
                sysid::NonlinearityKind::of(ch.nonlinearity())
            );
        }
    }
    if let Some(note) = &r.estimation.note {
        let _ = writeln!(s, "note: {note}");
    }
}

/// The parameters with their standard deviations (or why there is none).
fn parameters_text(r: &IdentifyReport, s: &mut String) {
    use std::fmt::Write;
    let m = &r.model;
    let _ = writeln!(s, "\nParameters (estimate ± standard deviation)");
    let several = m.inputs().len() > 1;
    let width = if several || m.output_nonlinearity().is_some() {
        14
    } else {
        6
    };
    for p in &r.parameters {
        // A parameter the tool held (b1 = 1 of a keyed input, the output map's gain, a dropped branch)
        // says why ([`sysid::Param::fixed`]).
        let sd = match (p.std, &p.fixed) {
            (Some(v), _) => format!("± {}", num(v)),
            (None, Some(why)) => format!("(fixed: {why})"),
            (None, None) => "± n/a".into(),
        };
        let _ = writeln!(s, "  {:<width$} = {:>14}  {sd}", p.label(), num(p.value));
    }
    // A detrended model's static maps take u − u0: say so, and where a deadzone's breakpoints lie in
    // the record's units (audit s14 L-c: tune printed those, unlabelled, beside identify's).
    if let Some(op) = m.operating_point() {
        for (c, u0) in m.inputs().iter().zip(&op.u) {
            if c.nonlinearity().is_linear() || *u0 == 0.0 {
                continue;
            }
            let which = if several {
                format!(" of {}", c.name())
            } else {
                String::new()
            };
            let in_record = match c.nonlinearity() {
                sysid::StaticNonlinearity::Deadzone(d) => format!(
                    "in the record's units its breakpoints are b_l = {}, b_r = {}",
                    num(d.b_l + u0),
                    num(d.b_r + u0)
                ),
                _ => "add u0 to its breakpoints for the record's units".to_string(),
            };
            let _ = writeln!(
                s,
                "  (the input nonlinearity{which} maps the detrended input u − u0, u0 = {}; {in_record})",
                num(*u0)
            );
        }
    }
}

/// A pole or zero p = re + im·i as the reports print it, each part with [`num`]'s 6 digits: `re` alone
/// when p is real — im = 0, or |im| below `real_below` (`identify` prints an imaginary part under
/// 1e-12 as rounding; `response` only an exact 0) — else `re ± |im|i`, followed by ` (|p| modulus)`
/// when `modulus` is set (`response`'s lists). The one formatter of `identify`'s poles and
/// `response`'s poles and zeros.
pub fn complex(re: f64, im: f64, real_below: f64, modulus: bool) -> String {
    if im == 0.0 || im.abs() < real_below {
        return num(re);
    }
    let p = format!(
        "{} {} {}i",
        num(re),
        if im < 0.0 { "-" } else { "+" },
        num(im.abs())
    );
    if modulus {
        format!("{p} (|p| {})", num(re.hypot(im)))
    } else {
        p
    }
}

/// The poles and the stability verdict.
fn poles_text(r: &IdentifyReport, s: &mut String) {
    use std::fmt::Write;
    let poles: Vec<String> = r
        .poles
        .iter()
        .map(|p| complex(p.re, p.im, 1e-12, false))
        .collect();
    // The verdict every command reports (`Model::stability`, with its band around the unit circle:
    // audit s20 H-1, a pole at exactly 1 computed as 0.99999999… was called "all inside").
    let verdict = r.model.stability();
    let _ = writeln!(
        s,
        "\nPoles: {}  → {verdict}",
        if poles.is_empty() {
            "none".to_string()
        } else {
            poles.join(", ")
        },
    );
}

/// The metrics table (estimation, validation), each record's fits, the metrics' notes.
fn metrics_text(r: &IdentifyReport, s: &mut String) {
    use std::fmt::Write;
    let val = r.metrics.validation.as_ref();
    let _ = writeln!(
        s,
        "\n{:<22}{:>16}{:>16}",
        "Metric",
        "estimation",
        if val.is_some() { "validation" } else { "" }
    );
    let rows: [MetricRow; 15] = [
        // Which initial outputs each simulation row starts from, in every row (audit s23 L-R2: the
        // estimated start's row read plain "simulation", 92.5 % on EMPS against 69.5 % measured).
        ("fit % (sim., y0 est.)", |m| opt(m.fit_sim_percent)),
        (
            "fit % (sim., y0 meas.)",
            |m| opt(m.fit_sim_measured_percent),
        ),
        ("fit % (1-step pred.)", |m| opt(m.fit_pred_percent)),
        ("RMSE (sim., y0 est.)", |m| opt(m.rmse_sim)),
        ("RMSE (sim., y0 meas.)", |m| opt(m.rmse_sim_measured)),
        ("RMSE (1-step pred.)", |m| num(m.rmse_pred)),
        ("loss V (eq. 14)", |m| opt(m.loss)),
        ("loss V_sim (sim.)", |m| opt(m.loss_sim)),
        ("FPE (eq. 15)", |m| opt(m.fpe)),
        ("AIC (eq. error)", |m| opt(m.aic)),
        // MATLAB's figures for this model: its own one-step prediction errors (audit s32 M-2).
        ("LossFcn (MATLAB)", |m| opt(m.loss_fcn)),
        ("FPE (MATLAB)", |m| opt(m.fpe_matlab)),
        ("nAIC (MATLAB aic)", |m| opt(m.aic_matlab)),
        ("N (rows used)", |m| m.n.to_string()),
        ("p (parameters)", |m| m.p.to_string()),
    ];
    for (label, f) in rows {
        let _ = writeln!(
            s,
            "{label:<22}{:>16}{:>16}",
            f(&r.metrics.estimation),
            val.map(f).unwrap_or_default()
        );
    }
    // Audit s18 L-3: two conventions side by side, said where the numbers are read.
    let _ = writeln!(
        s,
        "(sim., y0 est.: the simulation starts from initial outputs estimated to fit the record, MATLAB \
         compare's default, JSON fit_sim_percent and rmse_sim; y0 meas.: from the measured first \
         outputs, JSON *_measured. A gap between them is the initial state's doing.)"
    );
    let _ = writeln!(
        s,
        "(loss V = ½·mean ε², FPE = V (N+p)/(N−p) (the paper's eq. 14/15) and AIC = ln(mean ε²) + 2p/N \
         are the one-step equation error ε's (the ARX predictor) for every method, so that one column \
         compares models; MATLAB's LossFcn = mean e², FPE = LossFcn (N+p)/(N−p) and nAIC = ln(LossFcn) + \
         2p/N (what MATLAB's aic(sys) returns) are from the model's own one-step prediction errors e (those of RMSE \
         (1-step pred.): for an equation-error model 2V, 2·FPE and the same AIC; for an output-error \
         or Wiener model the simulation error's). An output-error model minimises the simulation \
         error: its criterion is loss V_sim.)"
    );
    if let Some(records) = &r.records {
        let _ = writeln!(
            s,
            "\nEstimation records (each simulated from its own initial outputs, estimated or measured, \
             and measured against its own mean; the estimation column above pools their rows)\n\
             {:<50} {:>8} {:>14} {:>16} {:>14}",
            "record", "N", "fit sim %", "fit sim y0 m. %", "fit pred %"
        );
        for r in records {
            let _ = writeln!(
                s,
                "{:<50} {:>8} {:>14} {:>16} {:>14}",
                r.data,
                r.metrics.n,
                opt(r.metrics.fit_sim_percent),
                opt(r.metrics.fit_sim_measured_percent),
                opt(r.metrics.fit_pred_percent)
            );
        }
    }
    for (which, mm) in [
        ("estimation", Some(&r.metrics.estimation)),
        ("validation", val),
    ] {
        if let Some(note) = mm.and_then(|m| m.note.as_ref()) {
            let _ = writeln!(s, "note ({which}): {note}");
        }
    }
}

/// The residual analysis of each record.
fn residuals_of(r: &IdentifyReport, s: &mut String) {
    let mut entries = match &r.records {
        Some(records) => records
            .iter()
            .map(|r| (r.data.as_str(), &r.residuals))
            .collect(),
        None => vec![("estimation", &r.residuals.estimation)],
    };
    entries.extend(r.residuals.validation.as_ref().map(|v| ("validation", v)));
    s.push_str(&residuals_text(&entries));
}

/// The residual analysis of each labelled record as text: verdicts, statistics and the worst lags.
pub fn residuals_text(entries: &[(&str, &ResidualEntry)]) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let mut header = false;
    for (which, entry) in entries {
        if !header {
            let _ = writeln!(
                s,
                "\nResidual analysis (one-step prediction errors, 99 % level)"
            );
            header = true;
        }
        match entry {
            ResidualEntry::Analysis(a) => {
                let worst = a.worst_lags();
                let _ = writeln!(
                    s,
                    "  {which:<11} whiteness: {} (Ljung-Box Q = {} for M = {}, p = {}; worst lag {}: r = {})",
                    if a.white { "white" } else { "NOT white" },
                    num(a.ljung_box_q),
                    a.max_lag,
                    num(a.ljung_box_p),
                    worst.autocorrelation.lag,
                    num(worst.autocorrelation.value)
                );
                let single = [sysid::residuals::InputCorrelation::of("", a)];
                let inputs = if a.inputs.is_empty() {
                    &single[..]
                } else {
                    &a.inputs[..]
                };
                for c in inputs {
                    let label = if c.name.is_empty() {
                        "input:".to_string()
                    } else {
                        format!("input {}:", c.name)
                    };
                    let _ = writeln!(
                        s,
                        "  {:<11} {label} {} (S = {}, p = {}; worst lag {}: r = {}; bound ±{}, joint ±{})",
                        "",
                        if c.independent {
                            "independent"
                        } else {
                            "NOT independent"
                        },
                        num(c.cross_statistic),
                        num(c.cross_p),
                        c.worst.lag,
                        num(c.worst.value),
                        num(a.bound),
                        num(a.joint_bound_independence)
                    );
                }
                if !a.portmanteau_can_reject() {
                    let way = match a.largest_decidable_lag() {
                        Some(m) => {
                            format!("pass --resid-lags {m} or fewer, or use a longer record")
                        }
                        None => "use a longer record".to_string(),
                    };
                    let _ = writeln!(
                        s,
                        "  {:<11} note: {} rows are too few for the independence statistic at M = {} \
                         (S <= N, and S must exceed {} to reject): the verdict rests on the per-lag \
                         check (any |r| beyond the joint band ±{}); {way}",
                        "",
                        a.n,
                        a.max_lag,
                        num(a.cross_statistic_critical),
                        num(a.joint_bound_independence)
                    );
                }
            }
            ResidualEntry::Unavailable { error } => {
                let _ = writeln!(s, "  {which:<11} not available: {error}");
            }
        }
    }
    s
}

#[cfg(test)]
mod tests {
    // Six significant digits, trailing zeros dropped: 0.01 → "0.01", 1.41 → "1.41", 1/3 → "0.333333".
    #[test]
    fn numbers_keep_six_significant_digits_without_trailing_zeros() {
        use report::format::num;
        assert_eq!(num(0.01), "0.01");
        assert_eq!(num(1.41), "1.41");
        assert_eq!(num(1.0 / 3.0), "0.333333");
        assert_eq!(num(-1234.5678), "-1234.57");
        assert_eq!(num(2.5e-4), "2.5e-4");
        assert_eq!(num(100.0), "100");
    }

    // p = 0.6 − 0.8i has |p| = 1 (a 3-4-5 triangle); a real p prints alone; an imaginary part under
    // `real_below` is rounding (identify's 1e-12), printed when only an exact 0 counts as real.
    #[test]
    fn a_complex_pole_prints_its_parts_and_on_request_its_modulus() {
        use super::complex;
        assert_eq!(complex(0.6, -0.8, 0.0, true), "0.6 - 0.8i (|p| 1)");
        assert_eq!(complex(0.6, -0.8, 1e-12, false), "0.6 - 0.8i");
        assert_eq!(complex(-0.25, 0.5, 1e-12, false), "-0.25 + 0.5i");
        assert_eq!(complex(0.5, 0.0, 0.0, true), "0.5");
        assert_eq!(complex(0.3, -1e-13, 1e-12, false), "0.3");
        assert_eq!(complex(0.3, -1e-13, 0.0, false), "0.3 - 1e-13i");
    }
}
