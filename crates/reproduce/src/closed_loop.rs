//! Stage 3: the closed-loop PI tests on the plant and on the chosen identified model, fixed and unfixed
//! set-point, and the deadzone-compensated run.

use control::{
    closed_loop, loop_warnings, metrics_for_steps, DeadzoneCompensator, LoopFacts, PiSettings,
    Profile, SlopeMode, StepMetrics, Trace,
};
use sysid::Fitted as FittedModel;
use sysid::{ModelPlant, Plant};

use crate::ReproduceError;

/// The PI loop on the plant and, when there is a stable identified model, on that model.
pub(crate) fn closed_loop_pair(
    plant: &mut dyn Plant,
    model: Option<&mut ModelPlant>,
    pi: &PiSettings,
    profile: &Profile,
    duration_s: f64,
    y0_mm: f64,
) -> Result<(Trace, Option<Trace>), ReproduceError> {
    let mut c1 = pi.build(plant.ts())?;
    let tp = closed_loop::run(plant, &mut c1, None, profile, duration_s, y0_mm)?;
    let tm = match model {
        Some(model) => {
            let mut c2 = pi.build(model.ts())?;
            Some(closed_loop::run(
                model, &mut c2, None, profile, duration_s, y0_mm,
            )?)
        }
        None => None,
    };
    Ok((tp, tm))
}

/// The fixed set-point run on the plant with a deadzone-inverse compensator built from the key-term LS
/// deadzone; `Ok(Err(reason))` when that deadzone cannot be inverted (e.g. b_l > 0 or a slope <= 0).
pub(crate) fn compensated_run(
    plant: &mut dyn Plant,
    fit: &FittedModel,
    pi: &PiSettings,
    profile: &Profile,
    duration_s: f64,
    y0_mm: f64,
) -> Result<Result<Trace, String>, ReproduceError> {
    let Some(&dz) = fit.model.deadzone() else {
        return Ok(Err("the model has no deadzone".into()));
    };
    let comp = match DeadzoneCompensator::new(dz, SlopeMode::Shift, pi.u_max) {
        Ok(c) => c,
        Err(e) => return Ok(Err(e.to_string())),
    };
    let mut c = pi.build(plant.ts())?;
    Ok(Ok(closed_loop::run(
        plant,
        &mut c,
        Some(&comp),
        profile,
        duration_s,
        y0_mm,
    )?))
}

/// The tuned controller's settings, tune's verdict, and its runs on the plant and on the model.
pub(crate) type TunedRun = (control::ControllerSettings, TuneVerdict, Trace, Trace);

/// The tuned controller (issue 25) of the fixed set-point test: tuned on the identified model `fit`
/// (a small search: 3 variants, 40 evaluations, so that `reproduce` stays quick), then run on the plant
/// and on the model; `Ok(Err(reason))` when the model cannot be tuned on. With the runs, tune's own
/// verdict ([`TuneVerdict`]: whether it met its specification and every reason it gave not to trust the
/// controller), so that reproduce says what `tune` says (audit s23 M-R2).
pub(crate) fn tuned_run(
    plant: &mut dyn Plant,
    fit: &FittedModel,
    profile: &Profile,
    duration_s: f64,
    y0_mm: f64,
) -> Result<Result<TunedRun, String>, ReproduceError> {
    let deadzone = match control::compensator::command_deadzone(&fit.model) {
        Ok(d) => d,
        Err(p) => return Ok(Err(p.to_string())),
    };
    let req = sysid_control::tuning::Request {
        source: sysid_control::tuning::Source::Model {
            model: fit.model.clone(),
            deadzone,
            label: "output-error model".into(),
        },
        spec: control::tune::Spec::default(),
        search: control::tune::TuneSettings {
            plants: 3,
            max_evaluations: 40,
        },
        check_physics: false,
        physics_variants: 0,
        cancel: sysid_core::Stop::never(),
    };
    let report = match sysid_control::tuning::run(&req) {
        Ok(r) => r,
        Err(e) if !e.is_numerical() => return Ok(Err(e.to_string())),
        Err(e) => return Err(e.into()),
    };
    let s = report.controller;
    let last = report.on_physics.as_ref().unwrap_or(&report.on_model);
    let verdict = TuneVerdict {
        meets_spec: report.meets_spec(),
        steps_met: last.comparison.tuned.met,
        steps: last.comparison.tuned.runs.len(),
        on: last.plant.clone(),
        warnings: report.warnings.clone(),
    };
    let mut c = s.build()?;
    let on_plant = closed_loop::run(plant, &mut c, None, profile, duration_s, y0_mm)?;
    let mut model = ModelPlant::new(fit.model.clone(), "output-error model")?;
    let on_model = closed_loop::run(&mut model, &mut c, None, profile, duration_s, y0_mm)?;
    Ok(Ok((s, verdict, on_plant, on_model)))
}

/// `tune`'s verdict on the controller it found ([`sysid_control::tuning::TuneReport`]): the same figures
/// the controller file's provenance carries (`meets_spec`, `met`), and its warnings.
#[derive(Debug, Clone)]
pub(crate) struct TuneVerdict {
    /// No verification missed the specification ([`sysid_control::tuning::TuneReport::meets_spec`]).
    pub(crate) meets_spec: bool,
    /// Steps of the last verification that met the whole specification.
    pub(crate) steps_met: usize,
    /// Steps of the last verification.
    pub(crate) steps: usize,
    /// The plants of the last verification, in words.
    pub(crate) on: String,
    /// Every reason `tune` gave not to trust the controller ("not met on ...", limit cycles, ...).
    pub(crate) warnings: Vec<String>,
}

pub(crate) fn step_metrics(
    trace: &Trace,
    y0_mm: f64,
    r_mm: f64,
) -> Result<StepMetrics, ReproduceError> {
    Ok(StepMetrics::of_loop(
        &trace.t,
        &trace.y,
        Some(&trace.u),
        y0_mm,
        r_mm,
    )?)
}

pub(crate) fn unfixed_metrics(
    trace: &Trace,
) -> Result<(StepMetrics, Vec<control::StepSegment>), ReproduceError> {
    let steps = metrics_for_steps(trace)?;
    let worst = StepMetrics::worst(steps.iter().map(|s| &s.metrics)).unwrap_or(StepMetrics {
        overshoot_mm: None,
        overshoot_percent: None,
        overshoot_past_setpoint_mm: None,
        overshoot_past_setpoint_percent: None,
        undershoot_mm: None,
        undershoot_percent: None,
        steady_state_error_mm: None,
        rise_time_s: None,
        settling_time_s: None,
    });
    Ok((worst, steps))
}

/// The doubts about one closed-loop run on the plant, in words, each headed by `label` (which run):
/// [`control::loop_warnings`] with the plant's limits (`control` gives the same on the same plant; audit
/// s14 M-e). The paper's acceptance is judged by the report's criteria, not repeated here.
pub(crate) fn run_warnings(
    label: &str,
    trace: &Trace,
    limits: &ipa::PlantLimits,
    u_max: f64,
) -> Result<Vec<String>, ReproduceError> {
    let steps = metrics_for_steps(trace)?;
    let facts = LoopFacts {
        u_max,
        range_mm: limits.range_mm,
        plant_stability: limits.stability,
        judge_steps: false,
        data_u_range: limits.data_u_range,
        data_y_range: limits.data_y_range,
        duration_setting: None,
        start_setting: None,
        // A model plant's own units (its estimation record's), the IPA's otherwise: as `control` says.
        units: control::Units::of(limits.model_units()),
    };
    Ok(loop_warnings(trace, &steps, &facts)
        .into_iter()
        .map(|w| format!("{label}: {w}"))
        .collect())
}

/// The experiments' commands against a model plant's estimation data: one warning when any record's
/// commands leave the data's command range (the records, and every model identified from them, then
/// describe the model's extrapolation, not the plant it was fitted to).
pub(crate) fn experiment_warning(records: &[&[f64]], limits: &ipa::PlantLimits) -> Option<String> {
    let (lo, hi) = limits.data_u_range?;
    let extremes = sysid_core::DataRange::extremes(records.iter().flat_map(|u| u.iter()));
    let (u_min, u_max) = sysid_core::DataRange::excursion_of(extremes, (lo, hi))?;
    Some(format!(
        "the experiments' commands span [{u_min}, {u_max}] {u} but the plant model's estimation data had \
         u in [{lo}, {hi}]: outside it the model extrapolates, so the records, the models identified from \
         them and the closed loops describe the equations' guess, not the plant (reproduce's experiments \
         drive ±255 {u}: give it a model estimated on commands that large)",
        u = control::Units::of(limits.model_units()).u
    ))
}
