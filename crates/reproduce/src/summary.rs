//! Stage 5: `summary.json`, every number of the run, machine-readable.

use control::StepMetrics;
use serde_json::json;

use crate::analysis;
use crate::differences::differences;
use crate::paper::{self, paper_normalised};
use crate::study::{Study, CLOSED_LOOP_RULE};
use crate::tables::TABLE3_NAMES;
use crate::ReproduceSettings;

pub(crate) fn summary_json(
    s: &ReproduceSettings,
    st: &Study,
    accepted: bool,
    elapsed_s: f64,
) -> serde_json::Value {
    let mj = |m: &StepMetrics| serde_json::to_value(m).unwrap_or_default();
    let mjo = |m: &Option<StepMetrics>| match m {
        Some(m) => mj(m),
        None => json!({"not_run": "no identified model is stable"}),
    };
    let resid = |r: &Result<sysid::residuals::ResidualAnalysis, String>| match r {
        Ok(a) => serde_json::to_value(a).unwrap_or_default(),
        Err(e) => json!({"error": e}),
    };
    let models: serde_json::Map<String, serde_json::Value> = st
        .models
        .iter()
        .map(|m| {
            let mut v = serde_json::to_value(&m.rep).unwrap_or_default();
            v["label"] = json!(m.label);
            (m.key.to_string(), v)
        })
        .collect();
    json!({
        "plant": st.plant_name,
        "settings": {
            "plant": s.plant, "seed": s.seed, "samples": s.samples, "ts": st.ts,
            "amplitude_counts": s.amplitude_counts, "experiment_start_mm": s.experiment_start_mm,
            "fixed_start_mm": s.fixed_start_mm, "fixed_setpoint_mm": s.fixed_setpoint_mm,
            "fixed_duration_s": s.fixed_duration_s, "unfixed_profile": s.unfixed_profile,
            "pi": {"kp": s.pi.kp, "ki": s.pi.ki, "integral": s.pi.integral.to_string(),
                   "anti_windup": s.pi.anti_windup.to_string()},
            "forgetting": s.forgetting,
        },
        "models": models,
        "paper_model": {
            "description": "the paper's method on the paper's Table III actual model as the plant (b1 = 1 normalisation)",
            "actual": TABLE3_NAMES.iter().map(|n| (n.to_string(), json!(paper_normalised(&paper::ACTUAL, *n)))).collect::<serde_json::Map<_, _>>(),
            "runs": st.paper_check.runs.iter().map(|r| json!({
                "record": r.label,
                "output_noise_std_mm": if r.label == "noise-free" { 0.0 } else { analysis::PAPER_NOISE_MM },
                "params": r.fit.params.iter().map(|p| json!({"name": p.name, "value": p.value, "std": p.std})).collect::<Vec<_>>(),
                "validation_fit_percent": r.fit_val,
            })).collect::<Vec<_>>(),
        },
        "residuals": st.residuals.iter().map(|r| (r.key.to_string(), json!({
            "estimation": resid(&r.estimation), "validation": resid(&r.validation),
        }))).collect::<serde_json::Map<_, _>>(),
        "differences": differences(s, st).iter().map(|d| json!({
            "id": d.id, "quantity": d.quantity,
            "plant": d.plant.iter().map(|(l, v)| (l.clone(), json!(v))).collect::<serde_json::Map<_, _>>(),
            "paper": d.paper.iter().map(|(l, v)| (l.to_string(), json!(v))).collect::<serde_json::Map<_, _>>(),
            "reason": d.reason,
        })).collect::<Vec<_>>(),
        "twin": crate::twin::json(&st.twin),
        "open_loop": { "fit_percent": st.fit_ol, "samples": st.u_ol.len(),
                       "model": st.cl().map(|m| m.key) },
        "closed_loop": {
            "model": st.cl().map(|m| m.key),
            "model_rule": CLOSED_LOOP_RULE,
            "fixed": { "setpoint_mm": s.fixed_setpoint_mm, "y0_mm": s.fixed_start_mm,
                       "model": mjo(&st.fixed.m_model), "plant": mj(&st.fixed.m_plant),
                       "plant_compensated": match &st.compensated {
                           Ok(m) => mj(m),
                           Err(reason) => json!({"not_applicable": reason}),
                       },
                       "tuned": match &st.tuned {
                           Ok(t) => json!({"controller": t.settings, "tune_verdict": {
                                               "meets_spec": t.verdict.meets_spec,
                                               "steps_met": t.verdict.steps_met,
                                               "steps": t.verdict.steps, "on": t.verdict.on,
                                               "warnings": t.verdict.warnings},
                                           "model": mj(&t.m_model),
                                           "plant": mj(&t.m_plant)}),
                           Err(reason) => json!({"not_applicable": reason}),
                       } },
            "unfixed": { "profile": s.unfixed_profile,
                         "model": mjo(&st.unfixed.m_model), "plant": mj(&st.unfixed.m_plant),
                         "steps_model": st.steps_model, "steps_plant": st.steps_plant },
        },
        "acceptance": {
            "accepted": accepted,
            "criteria": st.verdicts.iter().map(|c| json!({"id": c.id, "met": c.met, "status": c.status(), "criterion": c.text})).collect::<Vec<_>>(),
            "process_checks": st.checks.iter().map(|c| json!({"id": c.id, "met": c.met, "check": c.text})).collect::<Vec<_>>(),
        },
        "warnings": st.warnings,
        "elapsed_s": elapsed_s,
    })
}
