//! Stage 5: the paper's Tables III–V (and the known-truth and residual tables), as HTML tables and as
//! plain text for the terminal.

use report::format::{estimate, opt, pm};
use report::html::Table;
use sysid::Fitted as FittedModel;
use sysid::{Model, ParamName};
use sysid_core::param::{Layout, Parameterisation};
use sysid_summary::IdentifyReport;

use crate::paper::{self, paper_normalised};
use crate::study::{Loop, Study, CLOSED_LOOP_RULE};
use crate::ReproduceSettings;

pub(crate) fn param_cell(fit: &FittedModel, name: ParamName) -> String {
    match fit.params.iter().find(|p| p.name == name) {
        Some(p) => pm(p.value, p.std),
        None => "—".into(),
    }
}

/// The rows of Table III, in the paper's order.
pub(crate) const TABLE3_NAMES: [ParamName; 8] = [
    ParamName::BR,
    ParamName::BL,
    ParamName::MR,
    ParamName::ML,
    ParamName::A(1),
    ParamName::A(2),
    ParamName::A(3),
    ParamName::B(1),
];

/// The plant's true value of a parameter when the plant is the paper's model (b1 = 1: the model is
/// normalised), from the physical parameterisation of [`Model::paper`].
fn truth(s: &ReproduceSettings, name: ParamName) -> Option<f64> {
    if s.plant != "paper" {
        return None;
    }
    if name == ParamName::B(1) {
        return Some(1.0);
    }
    let m = Model::paper();
    Parameterisation::of_model(&m, Layout::Physical)
        .named_vector_of(&m)
        .into_iter()
        .find_map(|(n, v)| (n == name).then_some(v))
}

pub(crate) fn table3(s: &ReproduceSettings, st: &Study) -> Table {
    let mut header: Vec<String> = vec!["parameter".into()];
    header.extend(
        st.hammersteins()
            .iter()
            .map(|m| format!("ours: {}", m.short)),
    );
    if s.plant == "paper" {
        header.push("this plant's actual value".into());
    }
    header.extend(["paper: estimated".to_string(), "paper: actual".to_string()]);
    let ncols = header.len();
    let mut t = Table::new(header);
    for name in TABLE3_NAMES {
        let mut row = vec![name.to_string()];
        row.extend(st.hammersteins().iter().map(|m| param_cell(&m.fit, name)));
        if s.plant == "paper" {
            row.push(opt(truth(s, name)));
        }
        row.push(opt(paper_normalised(&paper::ESTIMATED, name)));
        row.push(opt(paper_normalised(&paper::ACTUAL, name)));
        t.push_row(row);
    }
    t.caption(
        "The paper's Table III: Hammerstein parameter estimates (± one standard deviation), normalised to b1 = 1 \
         (the paper's slopes are multiplied by its b1 so that they compare; see docs/paper.md)",
    )
    .paper_column(ncols - 2)
    .paper_column(ncols - 1)
}

pub(crate) fn metrics_row(label: &str, rep: &IdentifyReport) -> [String; 6] {
    let v = rep.metrics.validation.as_ref();
    // The fit and the simulation-error loss of one simulation: the worse of estimated and measured
    // initial outputs, which one marked (audit s33 M-5: the loss was always the estimated one's).
    let sim = v.and_then(sysid::trust::guarded_simulation);
    [
        label.to_string(),
        sim.map_or_else(
            || "n/a".to_string(),
            |g| format!("{} ({})", estimate(g.fit_percent), initial_mark(g.initial)),
        ),
        opt(v.and_then(|m| m.loss)),
        opt(sim.and_then(|g| g.loss_sim)),
        opt(v.and_then(|m| m.fpe)),
        crate::study::stability_word(rep).into(),
    ]
}

/// How a Table IV cell marks the initial outputs of its simulation: "est." or "meas.".
pub(crate) fn initial_mark(i: sysid::trust::InitialOutputs) -> &'static str {
    match i {
        sysid::trust::InitialOutputs::Estimated => "est.",
        sysid::trust::InitialOutputs::Measured => "meas.",
    }
}

/// A Table V row: criterion, the paper's simulation and experiment values, ours on model and plant.
pub(crate) type ClosedLoopRow = (String, f64, f64, String, String);

/// A settling-time cell: the time, "not settled" for a step that moved but had not settled within
/// the run (the rule of docs/control.md), "n/a" when there is no step (or no model run).
pub(crate) fn settling_cell(m: Option<&control::StepMetrics>) -> String {
    match m {
        Some(m)
            if m.settling_time_s.is_none() && m.steady_state_error_mm.is_some_and(|e| e != 0.0) =>
        {
            "not settled".into()
        }
        m => opt(m.and_then(|m| m.settling_time_s)),
    }
}

/// How a cell marks a steady-state error that is not final ([`ess_cell`]).
pub(crate) const NOT_FINAL_MARK: &str = "(n.f.)";

/// The note under a table with a [`NOT_FINAL_MARK`] cell.
pub(crate) const NOT_FINAL_NOTE: &str = "(n.f.) not final: the step had not settled, so its e_ss is the \
     error at the last sample, not a steady-state error (as `control` says: \"not final: not settled\").";

/// The e_ss cell: the figure, marked [`NOT_FINAL_MARK`] when the step has not settled
/// ([`settling_cell`] "not settled"; audit s23 M-R2: the tuned loop on the model printed 0.6116 as if
/// final).
pub(crate) fn ess_cell(m: Option<&control::StepMetrics>) -> String {
    let v = opt(m.and_then(|m| m.steady_state_error_mm));
    if settling_cell(m) == "not settled" {
        format!("{v} {NOT_FINAL_MARK}")
    } else {
        v
    }
}

/// The rows of Table V for the loop `lp` of a plant whose y is in `y_unit` (the paper's columns are
/// in mm: a model plant's row names both, audit s28 L-9).
pub(crate) fn closed_loop_rows(lp: &Loop, y_unit: &str) -> [ClosedLoopRow; 4] {
    let [a, b, c, d] = paper::CLOSED_LOOP;
    let (m, p) = (lp.m_model.as_ref(), &lp.m_plant);
    let label = |l: &str| {
        if y_unit == "mm" {
            l.to_string()
        } else {
            l.replace("(mm)", &format!("({y_unit}; the paper's: mm)"))
        }
    };
    [
        (
            label(a.0),
            a.1,
            a.2,
            opt(m.and_then(|m| m.overshoot_mm)),
            opt(p.overshoot_mm),
        ),
        (label(b.0), b.1, b.2, ess_cell(m), ess_cell(Some(p))),
        (
            c.0.to_string(),
            c.1,
            c.2,
            opt(m.and_then(|m| m.rise_time_s)),
            opt(p.rise_time_s),
        ),
        (
            d.0.to_string(),
            d.1,
            d.2,
            settling_cell(m),
            settling_cell(Some(p)),
        ),
    ]
}

/// The "tuned controller" rows of Table V (issue 25): each criterion of the tuned controller on the
/// model and on the plant, as cells (the paper has no such column).
pub(crate) fn tuned_rows(st: &Study) -> Vec<(String, String, String)> {
    let Ok(t) = &st.tuned else {
        return Vec::new();
    };
    let (m, p) = (&t.m_model, &t.m_plant);
    vec![
        (
            format!("tuned: overshoot ({})", st.y_unit()),
            opt(m.overshoot_mm),
            opt(p.overshoot_mm),
        ),
        (
            format!("tuned: e_ss ({})", st.y_unit()),
            ess_cell(Some(m)),
            ess_cell(Some(p)),
        ),
        (
            "tuned: rise time (s)".into(),
            opt(m.rise_time_s),
            opt(p.rise_time_s),
        ),
        (
            "tuned: settling time (s)".into(),
            settling_cell(Some(m)),
            settling_cell(Some(p)),
        ),
    ]
}

/// The tuned controller in words (settings, or why it was not run).
pub(crate) fn tuned_text(st: &Study) -> String {
    match &st.tuned {
        Ok(t) => {
            let s = &t.settings;
            let yu = st.y_unit();
            format!(
                "Tuned controller (ipa-sysid tune on the output-error model, 3 variants, 40 evaluations; \
                 docs/control.md): Kp = {}, Ki = {}, Kd = {}, deadzone inverse with fine band {} {yu}, hold \
                 band {} {yu} (data/closed_loop_fixed_plant_tuned.csv).",
                report::format::sig(s.kp, 4),
                report::format::sig(s.ki, 4),
                report::format::sig(s.kd, 3),
                report::format::sig(s.fine_band_mm, 3),
                s.hold_band_mm
            ) + &tuned_verdict(&t.verdict)
        }
        Err(reason) => format!("The tuned controller was not run: {reason}."),
    }
}

/// `tune`'s verdict in a sentence: whether the controller met its specification, with the count of
/// steps (as `control --controller` repeats it from the controller file); the reasons are in the
/// warnings.
fn tuned_verdict(v: &crate::closed_loop::TuneVerdict) -> String {
    if v.meets_spec {
        format!(
            " tune found it meets its specification on {} ({} of {} steps).",
            v.on, v.steps_met, v.steps
        )
    } else {
        format!(
            " NOT MET: tune found it does not meet its specification on {} ({} of {} steps meet \
             all of it; see the warnings \"the tuned controller (tune's verdict)\"): do not take its \
             rows as a tuned result.",
            v.on, v.steps_met, v.steps
        )
    }
}

/// The whiteness and independence verdicts of a residual analysis, in words.
fn resid_verdict(r: &Result<sysid::residuals::ResidualAnalysis, String>) -> String {
    match r {
        Ok(a) => format!(
            "{} (Ljung–Box p = {}), {} (p = {})",
            if a.white { "white" } else { "NOT white" },
            report::format::sig(a.ljung_box_p, 2),
            if a.independent {
                "independent of u"
            } else {
                "NOT independent of u"
            },
            report::format::sig(a.cross_p, 2)
        ),
        Err(e) => format!("not computed: {e}"),
    }
}

pub(crate) fn tables_text(s: &ReproduceSettings, st: &Study) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let hs = st.hammersteins();
    let _ = writeln!(o, "Table III — Hammerstein estimates (normalised b1 = 1): RLS (paper's method), key-term LS, output error");
    let _ = write!(o, "{:<6}", "param");
    for m in hs {
        let _ = write!(o, "{:>26}", m.short);
    }
    let _ = writeln!(o, "{:>13}{:>13}", "paper est.", "paper act.");
    for name in TABLE3_NAMES {
        let _ = write!(o, "{name:<6}");
        for m in hs {
            let _ = write!(o, "{:>26}", param_cell(&m.fit, name));
        }
        let _ = writeln!(
            o,
            "{:>13}{:>13}",
            opt(paper_normalised(&paper::ESTIMATED, name)),
            opt(paper_normalised(&paper::ACTUAL, name))
        );
    }
    let _ = writeln!(
        o,
        "\nTable IV — validation record (worst-case free-run fit %: the worse of estimated and measured \
         initial outputs, the paper's \"best fit\"; loss V of the one-step equation errors; simulation-error \
         loss of the same simulation as the fit; FPE)"
    );
    let _ = writeln!(
        o,
        "{:<40}{:>18}{:>12}{:>12}{:>12}  poles",
        "model", "worst-case fit %", "loss V", "sim. loss", "FPE"
    );
    for m in &st.models {
        let r = metrics_row(m.label, &m.rep);
        let _ = writeln!(
            o,
            // The verdict word last, after two spaces (audit s34: "an integrator" ran into the FPE
            // figure in a column of 10).
            "{:<40}{:>18}{:>12}{:>12}{:>12}  {}",
            r[0], r[1], r[2], r[3], r[4], r[5]
        );
    }
    for (label, i) in [("paper: linear ARX", 0), ("paper: Hammerstein", 1)] {
        let pick = |p: (f64, f64)| if i == 0 { p.0 } else { p.1 };
        let _ = writeln!(
            o,
            "{label:<40}{:>18}{:>12}{:>12}{:>12}",
            estimate(pick(paper::FIT)),
            estimate(pick(paper::LOSS)),
            "n/a",
            estimate(pick(paper::FPE))
        );
    }
    let _ = writeln!(
        o,
        "\nTable V — PI (Kp = {}, Ki = {}) fixed set-point {} → {} {}, {} s",
        s.pi.kp,
        s.pi.ki,
        s.fixed_start_mm,
        s.fixed_setpoint_mm,
        st.y_unit(),
        s.fixed_duration_s
    );
    let _ = writeln!(
        o,
        "{:<26}{:>14}{:>14}{:>14}{:>14}",
        "criterion", "model (sim.)", "plant", "paper sim.", "paper exp."
    );
    for (label, ps, pe, a, b) in closed_loop_rows(&st.fixed, st.y_unit()) {
        let _ = writeln!(
            o,
            "{label:<26}{a:>14}{b:>14}{:>14}{:>14}",
            estimate(ps),
            estimate(pe)
        );
    }
    let mut not_final = closed_loop_rows(&st.fixed, st.y_unit())
        .iter()
        .any(|r| r.3.ends_with(NOT_FINAL_MARK) || r.4.ends_with(NOT_FINAL_MARK));
    for (label, a, b) in tuned_rows(st) {
        not_final |= a.ends_with(NOT_FINAL_MARK) || b.ends_with(NOT_FINAL_MARK);
        let _ = writeln!(o, "{label:<26}{a:>14}{b:>14}{:>14}{:>14}", "—", "—");
    }
    if not_final {
        let _ = writeln!(o, "{NOT_FINAL_NOTE}");
    }
    let _ = writeln!(o, "{}", tuned_text(st));
    let _ = writeln!(
        o,
        "Model simulated: {} (rule: {CLOSED_LOOP_RULE})",
        st.cl()
            .map_or("none (no identified model is stable)", |m| m.label)
    );
    let _ = writeln!(
        o,
        "\nThe method on the paper's model (known truth, b1 = 1): parameter, actual, then each record's estimate"
    );
    let _ = write!(o, "{:<6}{:>13}", "param", "actual");
    for r in &st.paper_check.runs {
        let _ = write!(o, "{:>24}", r.label);
    }
    let _ = writeln!(o);
    for name in TABLE3_NAMES {
        let _ = write!(
            o,
            "{name:<6}{:>13}",
            opt(paper_normalised(&paper::ACTUAL, name))
        );
        for r in &st.paper_check.runs {
            let _ = write!(o, "{:>24}", param_cell(&r.fit, name));
        }
        let _ = writeln!(o);
    }
    let _ = writeln!(o, "\nCalibrated twin: {}", crate::twin::paragraph(&st.twin));
    if let Ok(t) = &st.twin {
        let rows = crate::twin::fit_rows(t);
        // As wide as the longest label ("… — unstable" rows ran past 40 and pushed their figures
        // out of the columns).
        let w = rows
            .iter()
            .map(|[label, ..]| label.chars().count() + 2)
            .max()
            .unwrap_or(0)
            .max(40);
        let _ = writeln!(
            o,
            "{:<w$}{:>14}{:>14}",
            "free-run fit %", "validation", "open loop"
        );
        for [label, v, ol] in rows {
            let _ = writeln!(o, "{label:<w$}{v:>14}{ol:>14}");
        }
        for w in crate::twin::warnings(t) {
            let _ = writeln!(o, "  warning: {w}");
        }
    }
    let _ = writeln!(o, "\nResiduals (validation record, 99 % level)");
    for r in &st.residuals {
        let _ = writeln!(o, "  {:<38} {}", r.key, resid_verdict(&r.validation));
    }
    let _ = writeln!(o, "\nAcceptance");
    for c in &st.verdicts {
        let _ = writeln!(o, "  [{}] {}: {}", c.status(), c.id, c.text);
    }
    if !st.warnings.is_empty() {
        let _ = writeln!(o, "\nWarnings (the plant and its runs)");
        for w in &st.warnings {
            let _ = writeln!(o, "  warning: {w}");
        }
    }
    let _ = writeln!(o, "\nProcess checks");
    for c in &st.checks {
        let _ = writeln!(
            o,
            "  [{}] {}: {}",
            if c.met { "ok" } else { "NO" },
            c.id,
            c.text
        );
    }
    o
}

/// Table of the known-truth check: the paper's actual values beside the estimates from its model.
pub(crate) fn paper_model_table(st: &Study) -> Table {
    let mut header = vec![
        "parameter".to_string(),
        "paper: actual (the plant here)".to_string(),
    ];
    header.extend(
        st.paper_check
            .runs
            .iter()
            .map(|r| format!("RLS estimate, {}", r.label)),
    );
    header.push("paper: its estimate".into());
    let n = header.len();
    let mut t = Table::new(header)
        .caption(
            "The paper's method (Hammerstein RLS, na = 3, nb = 1, nk = 1, the same settings and input as below) run \
             on the paper's Table III actual model as the plant; estimates ± one standard deviation, normalised to \
             b1 = 1 (slopes in mm per count and sample)",
        )
        .paper_column(1)
        .paper_column(n - 1);
    for name in TABLE3_NAMES {
        let mut row = vec![
            name.to_string(),
            opt(paper_normalised(&paper::ACTUAL, name)),
        ];
        row.extend(st.paper_check.runs.iter().map(|r| param_cell(&r.fit, name)));
        row.push(opt(paper_normalised(&paper::ESTIMATED, name)));
        t.push_row(row);
    }
    let mut row = vec!["validation fit (%)".to_string(), "100".to_string()];
    row.extend(st.paper_check.runs.iter().map(|r| opt(r.fit_val)));
    row.push(estimate(paper::FIT.1));
    t.push_row(row);
    t
}

pub(crate) fn residual_table(st: &Study) -> Table {
    let n = st
        .residuals
        .iter()
        .find_map(|r| r.validation.as_ref().ok().map(|a| (a.n, a.max_lag)));
    let mut t = Table::new([
        "model",
        "record",
        &format!("residual std ({})", st.y_unit()),
        "lags outside ±2.58/√N (auto / cross)",
        "whiteness: Ljung–Box Q (p)",
        "independence of u: S (p)",
    ])
    .caption(format!(
        "Residual tests at the 1 % level on the one-step prediction errors{} (validate's: an output-error \
         model's from the estimated initial outputs): whiteness by Ljung–Box against χ²(M), independence of \
         the input by the input-whitened statistic against χ²(2M+1); each also needs every lag's \
         correlation within the joint 99 % band (z/√N over the lags), so a test with p ≥ 0.01 can fail \
         by one lag (\"a lag beyond the joint band\")",
        n.map_or(String::new(), |(n, m)| format!(" (N = {n} samples per record, M = {m} lags)"))
    ));
    // A test failed with p ≥ 1 %: failed by a lag beyond the joint band (audit s31 L-4).
    let by_a_lag = |passed: bool, p: f64| {
        if !passed && p >= sysid::residuals::SIGNIFICANCE {
            ", a lag beyond the joint band"
        } else {
            ""
        }
    };
    for r in &st.residuals {
        let label = st.model(r.key).map_or(r.key, |m| m.label);
        for (record, res) in [("estimation", &r.estimation), ("validation", &r.validation)] {
            match res {
                Ok(a) => t.push_row([
                    label.to_string(),
                    record.to_string(),
                    estimate(a.residual_std),
                    format!(
                        "{} / {}",
                        a.autocorrelation_outside, a.cross_correlation_outside
                    ),
                    format!(
                        "{}: {} ({}){}",
                        if a.white { "white" } else { "NOT white" },
                        estimate(a.ljung_box_q),
                        report::format::sig(a.ljung_box_p, 2),
                        by_a_lag(a.white, a.ljung_box_p)
                    ),
                    format!(
                        "{}: {} ({}){}",
                        if a.independent {
                            "independent"
                        } else {
                            "NOT independent"
                        },
                        estimate(a.cross_statistic),
                        report::format::sig(a.cross_p, 2),
                        by_a_lag(a.independent, a.cross_p)
                    ),
                ]),
                Err(e) => t.push_row([
                    label.to_string(),
                    record.to_string(),
                    format!("not computed: {e}"),
                ]),
            }
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn metrics(settling: Option<f64>, ess: f64) -> control::StepMetrics {
        control::StepMetrics {
            overshoot_mm: Some(0.2),
            overshoot_percent: Some(0.4),
            overshoot_past_setpoint_mm: Some(0.2),
            overshoot_past_setpoint_percent: Some(0.4),
            undershoot_mm: None,
            undershoot_percent: None,
            steady_state_error_mm: Some(ess),
            rise_time_s: Some(0.26),
            settling_time_s: settling,
        }
    }

    // A step that moved and has no settling time reads "not settled" (the tuned loop on the model
    // printed "n/a", as if there were no step); a step without a set-point change reads "n/a".
    #[test]
    fn an_unsettled_step_reads_not_settled() {
        assert_eq!(settling_cell(Some(&metrics(None, 0.61))), "not settled");
        assert_eq!(settling_cell(Some(&metrics(Some(0.3517), 0.0))), "0.3517");
        assert_eq!(settling_cell(Some(&metrics(None, 0.0))), "n/a");
        assert_eq!(settling_cell(None), "n/a");
    }

    // Audit s23 M-R2: an unsettled step's e_ss is marked not final (the tuned loop on the model printed
    // 0.6116 as a result); a settled step's, and a step without a set-point change's, are not.
    #[test]
    fn an_unsettled_steps_error_is_marked_not_final() {
        let c = ess_cell(Some(&metrics(None, 0.6116)));
        assert!(
            c.starts_with("0.6116") && c.ends_with(NOT_FINAL_MARK),
            "{c}"
        );
        assert!(c.len() <= 14, "{c}: wider than the text table's column");
        assert!(!ess_cell(Some(&metrics(Some(0.3517), 0.02))).contains(NOT_FINAL_MARK));
        assert!(!ess_cell(Some(&metrics(None, 0.0))).contains(NOT_FINAL_MARK));
        assert!(!ess_cell(None).contains(NOT_FINAL_MARK));
    }

    // tune's verdict in words: a controller that met none of its steps says NOT MET with the count;
    // one that met them all says so.
    #[test]
    fn the_tuned_controllers_verdict_is_said() {
        let mut v = crate::closed_loop::TuneVerdict {
            meets_spec: false,
            steps_met: 0,
            steps: 24,
            on: "the output-error model and 2 variants".into(),
            warnings: vec!["not met on the model: |e_ss| <= 0.05 mm in every step".into()],
        };
        let t = tuned_verdict(&v);
        assert!(t.contains("NOT MET") && t.contains("0 of 24 steps"), "{t}");
        v.meets_spec = true;
        v.steps_met = 24;
        v.warnings.clear();
        let t = tuned_verdict(&v);
        assert!(!t.contains("NOT") && t.contains("24 of 24 steps"), "{t}");
    }
}
