//! `reproduce`: the paper end to end on a plant (the physics IPA by default).
//!
//! 1. Experiment: a staircase ("continuous step signal") of ±A counts, N samples at Ts, from mid-stroke; a
//!    second, independent record (next seed) for validation.
//! 2. Identification: the linear ARX baseline and the Hammerstein model by RLS (the paper's method,
//!    na = 3, nb = 1, nk = 1), plus the Hammerstein model by iterated key-term least squares (labelled as
//!    this project's addition).
//! 3. Tables III (estimates), IV (validation fit, loss, FPE), V (closed-loop metrics, model vs plant), with
//!    the paper's numbers beside ours.
//! 4. Figures (SVG and PNG) and `report.html`, `summary.json`, `data/*.csv`.

use std::path::PathBuf;
use std::time::Instant;

use control::{
    closed_loop, metrics_for_steps, DeadzoneCompensator, PiSettings, Profile, SlopeMode,
    StepMetrics, Trace,
};
use ipa::input::{generate, InputSpec};
use report::format::num;
use report::html::{Section, Table, Verdict};
use report::plot::{save_figure, Figure, Panel, Series};
use report::Report;
use serde_json::json;
use sysid::data::Signals;
use sysid::estimate::{
    identify, EstimatorSettings, Fitted as FittedModel, Identification, Method,
    RecursiveLeastSquares,
};
use sysid::metrics::{fit_percent, metrics};
use sysid::summary::IdentifyReport;
use sysid::{Dataset, Model, ModelKind, ModelPlant, ParamName, Plant};
use sysid_core::param::{Layout, Parameterisation};

pub mod error;
pub use error::ReproduceError;

/// Settings of a reproduction run.
#[derive(Debug, Clone)]
pub struct ReproduceSettings {
    /// Plant spec: `ipa` (physics, default), `paper` or `model:FILE`.
    pub plant: String,
    /// TOML file overriding the physics plant's parameters.
    pub plant_config: Option<PathBuf>,
    /// Seed of the experiment (validation record: seed + 1, open-loop test: seed + 2).
    pub seed: u64,
    /// Output folder.
    pub out_dir: PathBuf,
    /// Samples per record (paper: 2000).
    pub samples: usize,
    /// Staircase amplitude A, counts (paper: 255).
    pub amplitude_counts: f64,
    /// Where the experiments start, mm (mid-stroke).
    pub experiment_start_mm: f64,
    /// Fixed set-point test: start position and set-point, mm, and duration, s.
    pub fixed_start_mm: f64,
    /// Fixed set-point r, mm.
    pub fixed_setpoint_mm: f64,
    /// Duration of the fixed set-point test, s.
    pub fixed_duration_s: f64,
    /// Unfixed set-point profile (spec of [`Profile::parse`]).
    pub unfixed_profile: String,
    /// PI controller (paper: Kp = 14, Ki = 1, integral Ki·Ts·Σe).
    pub pi: PiSettings,
    /// RLS forgetting factor used for both models.
    pub forgetting: f64,
}

impl Default for ReproduceSettings {
    fn default() -> Self {
        ReproduceSettings {
            plant: "ipa".into(),
            plant_config: None,
            seed: 1,
            out_dir: PathBuf::from("reproduce-out"),
            samples: 2000,
            amplitude_counts: 255.0,
            experiment_start_mm: 100.0,
            fixed_start_mm: 0.0,
            fixed_setpoint_mm: 50.0,
            fixed_duration_s: 40.0,
            unfixed_profile: "staircase:50,120,80,150,30@4".into(),
            pi: PiSettings::paper(),
            forgetting: 1.0,
        }
    }
}

/// What a run produced.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The `summary.json` document.
    pub summary: serde_json::Value,
    /// Tables III–V as plain text, for the terminal.
    pub text: String,
    /// Path of `report.html`.
    pub report_path: PathBuf,
    /// Whether every acceptance criterion was met.
    pub accepted: bool,
}

/// The paper's numbers (Tables III–V), for the "paper" columns.
pub mod paper {
    /// Table III, estimated values as printed (b1 not normalised): b_r, b_l, m_r, m_l, a1, a2, a3, b1.
    pub const ESTIMATED: [(&str, f64); 8] = [
        ("b_r", 1.4120),
        ("b_l", -1.5010),
        ("m_r", 2.3810),
        ("m_l", 3.4710),
        ("a1", -1.8200),
        ("a2", 1.0010),
        ("a3", -0.1808),
        ("b1", 7.4980e-4),
    ];
    /// Table III, actual values as printed.
    pub const ACTUAL: [(&str, f64); 8] = [
        ("b_r", 1.4100),
        ("b_l", -1.5000),
        ("m_r", 2.3800),
        ("m_l", 3.4600),
        ("a1", -1.8690),
        ("a2", 0.9976),
        ("a3", -0.1284),
        ("b1", 15.67e-4),
    ];
    /// Table IV: (ARX, Hammerstein) best fit %, loss, FPE.
    pub const FIT: (f64, f64) = (87.3102, 92.9665);
    /// Table IV loss function.
    pub const LOSS: (f64, f64) = (4.4000e-3, 0.8510e-3);
    /// Table IV final prediction error.
    pub const FPE: (f64, f64) = (4.4000e-3, 0.8561e-3);
    /// Table V: (simulation, experiment) overshoot mm, e_ss mm, rise s, settling s.
    pub const CLOSED_LOOP: [(&str, f64, f64); 4] = [
        ("overshoot (mm)", 0.1173, 2.1849),
        ("steady-state error (mm)", 0.0037, 0.6800),
        ("rise time (s)", 0.2231, 0.6780),
        ("settling time (s)", 0.4194, 36.5939),
    ];
}

fn record(
    plant: &mut dyn Plant,
    u: Vec<f64>,
    start_mm: f64,
    name: &str,
) -> Result<Dataset, ReproduceError> {
    plant.reset(start_mm);
    let y = sysid::plant::run_open_loop(plant, &u)?;
    Ok(Dataset::new(Signals { u, y }, plant.ts(), name)?)
}

fn fmt_opt(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".into(), num)
}

fn param_cell(fit: &FittedModel, name: ParamName) -> String {
    match fit.params.iter().find(|p| p.name == name) {
        Some(p) => match p.std {
            Some(s) => format!("{} ± {}", num(p.value), num(s)),
            None => num(p.value),
        },
        None => "—".into(),
    }
}

/// The paper's Table III value of `name`, normalised to b1 = 1 (slopes times b1).
fn paper_normalised(table: &[(&str, f64); 8], name: ParamName) -> Option<f64> {
    let b1 = table[7].1;
    let v = table.iter().find(|(n, _)| name == *n)?.1;
    Some(match name {
        ParamName::MR | ParamName::ML => v * b1,
        ParamName::B(1) => 1.0,
        _ => v,
    })
}

fn closed_loop_pair(
    plant: &mut dyn Plant,
    model: &mut dyn Plant,
    pi: &PiSettings,
    profile: &Profile,
    duration_s: f64,
    y0_mm: f64,
) -> Result<(Trace, Trace), ReproduceError> {
    let mut c1 = pi.build(plant.ts())?;
    let tp = closed_loop::run(plant, &mut c1, None, profile, duration_s, y0_mm)?;
    let mut c2 = pi.build(model.ts())?;
    let tm = closed_loop::run(model, &mut c2, None, profile, duration_s, y0_mm)?;
    Ok((tp, tm))
}

/// The fixed set-point run on the plant with a deadzone-inverse compensator built from the key-term LS
/// deadzone; `Ok(Err(reason))` when that deadzone cannot be inverted (e.g. b_l > 0 or a slope <= 0).
fn compensated_run(
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

fn step_metrics(trace: &Trace, y0_mm: f64, r_mm: f64) -> Result<StepMetrics, ReproduceError> {
    Ok(StepMetrics::compute(&trace.t, &trace.y, y0_mm, r_mm)?)
}

fn unfixed_metrics(
    trace: &Trace,
) -> Result<(StepMetrics, Vec<control::StepSegment>), ReproduceError> {
    let steps = metrics_for_steps(trace)?;
    let worst = StepMetrics::worst(steps.iter().map(|s| &s.metrics)).unwrap_or(StepMetrics {
        overshoot_mm: None,
        overshoot_percent: None,
        steady_state_error_mm: None,
        rise_time_s: None,
        settling_time_s: None,
    });
    Ok((worst, steps))
}

/// One identified model of the run.
struct Fitted {
    /// Key in `summary.json` `models` and in `model_<key>.json`.
    key: &'static str,
    /// Label in tables and figures.
    label: &'static str,
    /// Column heading in the terminal tables.
    short: &'static str,
    fit: FittedModel,
    rep: IdentifyReport,
}

/// A closed-loop test on plant and model.
struct Loop {
    plant: Trace,
    model: Trace,
    m_plant: StepMetrics,
    m_model: StepMetrics,
}

/// Everything a run computed; the tables, figures, report and summary are views of it.
struct Study {
    plant_name: String,
    ts: f64,
    est: Dataset,
    val: Dataset,
    /// `[arx, hammerstein (RLS), hammerstein_ls, hammerstein_oe]`: the first two are the paper's.
    models: Vec<Fitted>,
    u_ol: Vec<f64>,
    y_ol_plant: Vec<f64>,
    y_ol_model: Vec<f64>,
    fit_ol: Option<f64>,
    fixed: Loop,
    compensated: Result<StepMetrics, String>,
    unfixed: Loop,
    steps_plant: Vec<control::StepSegment>,
    steps_model: Vec<control::StepSegment>,
    verdicts: Vec<(bool, String)>,
}

impl Study {
    fn arx(&self) -> &Fitted {
        &self.models[0]
    }
    fn ham(&self) -> &Fitted {
        &self.models[1]
    }
    fn hammersteins(&self) -> &[Fitted] {
        &self.models[1..]
    }
    fn model(&self, key: &str) -> Option<&Fitted> {
        self.models.iter().find(|m| m.key == key)
    }
}

fn validation_fit(r: &IdentifyReport) -> Option<f64> {
    r.metrics
        .validation
        .as_ref()
        .and_then(|m| m.fit_sim_percent)
}

fn pole_list(r: &IdentifyReport) -> String {
    r.poles
        .iter()
        .filter(|p| p.im >= 0.0)
        .map(|p| {
            if p.im.abs() < 1e-12 {
                num(p.re)
            } else {
                format!("{} ± {}i", num(p.re), num(p.im.abs()))
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// Runs the whole reproduction; `progress(step, fraction_done)` is called between stages.
pub fn run(
    s: &ReproduceSettings,
    progress: &mut dyn FnMut(&str, f64),
) -> Result<Outcome, ReproduceError> {
    let started = Instant::now();
    let out = &s.out_dir;
    let fig_dir = out.join("figures");
    let data_dir = out.join("data");
    for d in [out, &fig_dir, &data_dir] {
        std::fs::create_dir_all(d).map_err(|source| sysid::SysidError::Io {
            path: d.clone(),
            source,
        })?;
    }

    // 1. Experiments.
    progress("experiment on the plant", 0.0);
    let mut plant = ipa::plant_from_spec(&s.plant, s.plant_config.as_deref())?;
    let ts = plant.ts();
    let stair = InputSpec::Staircase;
    let u_est = generate(&stair, s.samples, ts, s.amplitude_counts, s.seed)?;
    let u_val = generate(
        &stair,
        s.samples,
        ts,
        s.amplitude_counts,
        s.seed.wrapping_add(1),
    )?;
    let est = record(
        plant.as_mut(),
        u_est,
        s.experiment_start_mm,
        "estimation record",
    )?;
    let val = record(
        plant.as_mut(),
        u_val,
        s.experiment_start_mm,
        "validation record",
    )?;
    let t_rec = sysid::data::sample_times(est.len(), ts);
    for (name, d) in [("estimation.csv", &est), ("validation.csv", &val)] {
        sysid_io::write_columns_csv(
            &data_dir.join(name),
            &["t", "u", "y"],
            &[&t_rec, &d.u, &d.y],
        )?;
    }

    // 2. Identification: the paper's two models, then this project's additions.
    progress(
        "identification (ARX and Hammerstein by RLS; key-term LS; output error)",
        0.2,
    );
    let rls = RecursiveLeastSquares {
        forgetting: s.forgetting,
        ..RecursiveLeastSquares::default()
    };
    let base = Identification::default().with_estimator(EstimatorSettings::Rls(rls));
    let plan: [(&str, &str, &str, Identification); 4] = [
        (
            "arx",
            "linear ARX (RLS)",
            "ARX RLS",
            base.clone().with_kind(ModelKind::Arx),
        ),
        (
            "hammerstein",
            "Hammerstein (RLS, paper's method)",
            "RLS (paper)",
            base.clone()
                .with_estimator(EstimatorSettings::Rls(RecursiveLeastSquares {
                    record_history: true,
                    ..rls
                })),
        ),
        (
            "hammerstein_ls",
            "Hammerstein (key-term LS, addition)",
            "key-term LS",
            base.clone().with_method(Method::Ls),
        ),
        (
            "hammerstein_oe",
            "Hammerstein (output error, addition)",
            "output error",
            base.clone().with_method(Method::Oe),
        ),
    ];
    let mut models = Vec::with_capacity(plan.len());
    for (key, label, short, set) in plan {
        let fit = identify(&est, &set)?;
        let e = metrics(&fit.model, &est)?;
        let v = metrics(&fit.model, &val)?;
        let rep = IdentifyReport::new(&fit, &set, e, Some(v));
        sysid_io::write_atomic(
            &out.join(format!("model_{key}.json")),
            sysid::model_file::to_json(&fit.model)?.as_bytes(),
        )?;
        models.push(Fitted {
            key,
            label,
            short,
            fit,
            rep,
        });
    }
    let ham_model = models[1].fit.model.clone();

    // Open-loop test (Fig. 6): a fresh staircase on plant and identified Hammerstein model.
    progress("open-loop test", 0.4);
    let u_ol = generate(
        &stair,
        s.samples / 2,
        ts,
        s.amplitude_counts,
        s.seed.wrapping_add(2),
    )?;
    let ol = record(
        plant.as_mut(),
        u_ol.clone(),
        s.experiment_start_mm,
        "open-loop test",
    )?;
    let mut model_plant = ModelPlant::new(ham_model, "identified Hammerstein model")?;
    model_plant.reset(s.experiment_start_mm);
    let y_ol_model = sysid::plant::run_open_loop(&mut model_plant, &u_ol)?;
    let fit_ol = fit_percent(&ol.y, &y_ol_model);
    let t_ol = sysid::data::sample_times(u_ol.len(), ts);
    sysid_io::write_columns_csv(
        &data_dir.join("open_loop.csv"),
        &["t", "u", "y_plant", "y_model"],
        &[&t_ol, &u_ol, &ol.y, &y_ol_model],
    )?;

    // 3. Closed loop, fixed and unfixed set-point, model vs plant.
    progress("closed-loop PI control", 0.55);
    let fixed_profile = Profile::Fixed {
        setpoint_mm: s.fixed_setpoint_mm,
    };
    let (fp, fm) = closed_loop_pair(
        plant.as_mut(),
        &mut model_plant,
        &s.pi,
        &fixed_profile,
        s.fixed_duration_s,
        s.fixed_start_mm,
    )?;
    let fixed = Loop {
        m_plant: step_metrics(&fp, s.fixed_start_mm, s.fixed_setpoint_mm)?,
        m_model: step_metrics(&fm, s.fixed_start_mm, s.fixed_setpoint_mm)?,
        plant: fp,
        model: fm,
    };
    // The paper's future work: the same PI followed by the inverse of the identified deadzone
    // (from the output-error model, whose breakpoints are the most accurate).
    let comp_source = &models[3].fit;
    let compensated = match compensated_run(
        plant.as_mut(),
        comp_source,
        &s.pi,
        &fixed_profile,
        s.fixed_duration_s,
        s.fixed_start_mm,
    )? {
        Ok(tr) => {
            sysid_io::write_columns_csv(
                &data_dir.join("closed_loop_fixed_plant_compensated.csv"),
                &Trace::COLUMNS,
                &tr.columns(),
            )?;
            Ok(step_metrics(&tr, s.fixed_start_mm, s.fixed_setpoint_mm)?)
        }
        Err(reason) => Err(reason),
    };
    let unfixed_profile = Profile::parse(&s.unfixed_profile)?;
    let uf_duration = unfixed_profile.natural_duration_s().unwrap_or(20.0);
    let (up, um) = closed_loop_pair(
        plant.as_mut(),
        &mut model_plant,
        &s.pi,
        &unfixed_profile,
        uf_duration,
        s.fixed_start_mm,
    )?;
    let (m_up, steps_plant) = unfixed_metrics(&up)?;
    let (m_um, steps_model) = unfixed_metrics(&um)?;
    let unfixed = Loop {
        plant: up,
        model: um,
        m_plant: m_up,
        m_model: m_um,
    };
    for (name, tr) in [
        ("closed_loop_fixed_plant.csv", &fixed.plant),
        ("closed_loop_fixed_model.csv", &fixed.model),
        ("closed_loop_unfixed_plant.csv", &unfixed.plant),
        ("closed_loop_unfixed_model.csv", &unfixed.model),
    ] {
        sysid_io::write_columns_csv(&data_dir.join(name), &Trace::COLUMNS, &tr.columns())?;
    }

    let mut study = Study {
        plant_name: plant.name(),
        ts,
        est,
        val,
        models,
        u_ol,
        y_ol_plant: ol.y,
        y_ol_model,
        fit_ol,
        fixed,
        compensated,
        unfixed,
        steps_plant,
        steps_model,
        verdicts: Vec::new(),
    };
    study.verdicts = verdicts(s, &study);
    let accepted = study.verdicts.iter().all(|v| v.0);

    // 4. Figures.
    progress("figures", 0.7);
    let figs = figures(s, &study);
    for (stem, fig, _) in &figs {
        save_figure(fig, &fig_dir, stem)?;
    }

    // 5. Summary and report.
    progress("report", 0.9);
    let summary = summary_json(s, &study, accepted, started.elapsed().as_secs_f64());
    let text = tables_text(s, &study);
    let report = build_report(s, &study, &figs)?;
    let report_path = out.join("report.html");
    report.save(&report_path)?;
    sysid_io::write_atomic(
        &out.join("summary.json"),
        (serde_json::to_string_pretty(&summary).unwrap_or_default() + "\n").as_bytes(),
    )?;
    progress("done", 1.0);
    Ok(Outcome {
        summary,
        text,
        report_path,
        accepted,
    })
}

/// The acceptance criteria of the paper (and the issue), each with whether it is met and why.
fn verdicts(s: &ReproduceSettings, st: &Study) -> Vec<(bool, String)> {
    let step = (s.fixed_setpoint_mm - s.fixed_start_mm).abs();
    let (fa, fh) = (validation_fit(&st.arx().rep), validation_fit(&st.ham().rep));
    let mut v = vec![(
        matches!((fa, fh), (Some(a), Some(h)) if h > a),
        format!(
            "Hammerstein (RLS, paper's method) fits the validation record better than the linear ARX: {} % vs {} % \
             (paper: {} % vs {} %)",
            fmt_opt(fh),
            fmt_opt(fa),
            paper::FIT.1,
            paper::FIT.0
        ),
    )];
    let ham = &st.ham().rep;
    let max_pole = ham.poles.iter().map(|p| p.abs).fold(0.0, f64::max);
    v.push((
        ham.stable,
        if ham.stable {
            format!("Hammerstein (RLS) poles inside the unit circle: {}", pole_list(ham))
        } else {
            format!(
                "Hammerstein (RLS) poles inside the unit circle: {} — the largest has |p| = {}. The plant integrates \
                 (position is the integral of velocity), so its true pole is at 1, and the equation-error estimate \
                 lands just outside; the output-error model (an addition of this project) does not have this bias",
                pole_list(ham),
                num(max_pole)
            )
        },
    ));
    if let Some(oe) = st.model("hammerstein_oe") {
        let fo = validation_fit(&oe.rep);
        v.push((
            oe.rep.stable && matches!((fa, fo), (Some(a), Some(o)) if o > a),
            format!(
                "Addition: Hammerstein by output error is {} and fits the validation record by {} % (linear ARX: {} %)",
                if oe.rep.stable { "stable" } else { "UNSTABLE" },
                fmt_opt(fo),
                fmt_opt(fa)
            ),
        ));
    }
    let os = st.fixed.m_plant.overshoot_percent;
    v.push((
        os.is_some_and(|x| x < 10.0),
        format!(
            "PI on the plant: overshoot {} % of the step (paper's acceptance: < 10 %)",
            fmt_opt(os)
        ),
    ));
    let ess = st.fixed.m_plant.steady_state_error_mm;
    v.push((
        ess.is_some_and(|e| e.abs() < 0.02 * step),
        format!(
            "PI on the plant: |steady-state error| {} mm, {} % of the {} mm step after {} s (paper's acceptance: < 2 %)",
            fmt_opt(ess.map(f64::abs)),
            fmt_opt(ess.map(|e| 100.0 * e.abs() / step.max(f64::MIN_POSITIVE))),
            num(step),
            num(s.fixed_duration_s)
        ),
    ));
    v
}

fn summary_json(
    s: &ReproduceSettings,
    st: &Study,
    accepted: bool,
    elapsed_s: f64,
) -> serde_json::Value {
    let mj = |m: &StepMetrics| serde_json::to_value(m).unwrap_or_default();
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
        "open_loop": { "fit_percent": st.fit_ol, "samples": st.u_ol.len() },
        "closed_loop": {
            "fixed": { "setpoint_mm": s.fixed_setpoint_mm, "y0_mm": s.fixed_start_mm,
                       "model": mj(&st.fixed.m_model), "plant": mj(&st.fixed.m_plant),
                       "plant_compensated": match &st.compensated {
                           Ok(m) => mj(m),
                           Err(reason) => json!({"not_applicable": reason}),
                       } },
            "unfixed": { "profile": s.unfixed_profile,
                         "model": mj(&st.unfixed.m_model), "plant": mj(&st.unfixed.m_plant),
                         "steps_model": st.steps_model, "steps_plant": st.steps_plant },
        },
        "acceptance": {
            "accepted": accepted,
            "criteria": st.verdicts.iter().map(|(ok, text)| json!({"met": ok, "criterion": text})).collect::<Vec<_>>(),
        },
        "elapsed_s": elapsed_s,
    })
}

type Fig = (&'static str, Figure, &'static str);

fn sim_or_nan(model: &Model, d: &Dataset) -> Vec<f64> {
    model
        .simulate(&d.u, &d.y)
        .unwrap_or_else(|_| vec![f64::NAN; d.len()])
}

fn figures(s: &ReproduceSettings, st: &Study) -> Vec<Fig> {
    let ts = st.ts;
    let t = sysid::data::sample_times(st.est.len(), ts);
    let mut figs: Vec<Fig> = Vec::new();
    figs.push((
        "fig2_experiment",
        Figure::new("Experiment: staircase input and measured position (paper's Fig. 2)")
            .panel(Panel::new("time (s)", "u (counts)").series(Series::step("u: PWM command", t.clone(), st.est.u.clone())))
            .panel(Panel::new("time (s)", "y (mm)").series(Series::line("y: position", t.clone(), st.est.y.clone()))),
        "The estimation record: the staircase command u (PWM counts) and the measured stroke position y (mm).",
    ));
    let us: Vec<f64> = (-255..=255).map(f64::from).collect();
    let mut dz_panel = Panel::new("u (counts)", "x (key-term units, b1 = 1)");
    for m in st.hammersteins() {
        dz_panel = dz_panel.series(Series::line(m.label, us.clone(), m.fit.model.internal(&us)));
    }
    if s.plant == "paper" {
        dz_panel = dz_panel.series(Series::dashed(
            "actual (paper model)",
            us.clone(),
            Model::paper().internal(&us),
        ));
    }
    figs.push((
        "fig4_deadzone",
        Figure::new("Identified valve deadzone x = f(u) (paper's Fig. 4)").panel(dz_panel),
        "The identified static nonlinearity: the valve deadzone between b_l and b_r and the slopes m_l, m_r.",
    ));
    let tv = sysid::data::sample_times(st.val.len(), ts);
    let mut fit_panel = Panel::new("time (s)", "y (mm)").series(Series::line(
        "measured",
        tv.clone(),
        st.val.y.clone(),
    ));
    for key in ["arx", "hammerstein", "hammerstein_oe"] {
        if let Some(m) = st.model(key) {
            fit_panel = fit_panel.series(Series::dashed(
                m.label,
                tv.clone(),
                sim_or_nan(&m.fit.model, &st.val),
            ));
        }
    }
    figs.push((
        "fig5_fit",
        Figure::new("Validation record: measured vs simulated output (paper's Fig. 5)").panel(fit_panel),
        "Free-run simulation of the models on the validation record (which was not used for estimation).",
    ));
    let t_ol = sysid::data::sample_times(st.u_ol.len(), ts);
    figs.push((
        "fig6_open_loop",
        Figure::new("Open-loop test: identified Hammerstein model vs plant (paper's Fig. 6)")
            .panel(Panel::new("time (s)", "u (counts)").series(Series::step(
                "u",
                t_ol.clone(),
                st.u_ol.clone(),
            )))
            .panel(
                Panel::new("time (s)", "y (mm)")
                    .series(Series::line("plant", t_ol.clone(), st.y_ol_plant.clone()))
                    .series(Series::dashed(
                        "Hammerstein model (RLS)",
                        t_ol,
                        st.y_ol_model.clone(),
                    )),
            ),
        "A fresh staircase applied to the plant and to the identified model from the same start.",
    ));
    for (stem, title, lp, cap) in [
        (
            "fig7a_closed_loop_fixed",
            "PI control, fixed set-point (paper's Fig. 7a)",
            &st.fixed,
            "PI (Kp = 14, Ki = 1) from rest to the fixed set-point: identified model (simulation) vs plant.",
        ),
        (
            "fig7b_closed_loop_unfixed",
            "PI control, changing set-point (paper's Fig. 7b)",
            &st.unfixed,
            "PI (Kp = 14, Ki = 1) following a staircase of set-points: identified model vs plant.",
        ),
    ] {
        let (p, m) = (&lp.plant, &lp.model);
        figs.push((
            stem,
            Figure::new(title)
                .panel(
                    Panel::new("time (s)", "y (mm)")
                        .series(Series::step("set-point r", p.t.clone(), p.r.clone()))
                        .series(Series::line("plant", p.t.clone(), p.y.clone()))
                        .series(Series::dashed("Hammerstein model", m.t.clone(), m.y.clone())),
                )
                .panel(
                    Panel::new("time (s)", "u (counts)")
                        .series(Series::step("u plant", p.t.clone(), p.u.clone()))
                        .series(Series::step("u model", m.t.clone(), m.u.clone())),
                ),
            cap,
        ));
    }
    let ham = &st.ham().fit;
    if !ham.history.is_empty() {
        let th: Vec<f64> = ham.history_samples.iter().map(|&k| k as f64 * ts).collect();
        let names: Vec<String> = ham.params.iter().map(|p| p.name.to_string()).collect();
        let col = |name: &str| -> Option<Vec<f64>> {
            let i = names.iter().position(|n| *n == name)?;
            Some(ham.history.iter().map(|h| h[i]).collect())
        };
        let mut panels = [
            Panel::new("time (s)", "breakpoints (counts)"),
            Panel::new("time (s)", "slopes"),
            Panel::new("time (s)", "A coefficients"),
        ];
        for (i, group) in [&["b_l", "b_r"][..], &["m_l", "m_r"], &["a1", "a2", "a3"]]
            .iter()
            .enumerate()
        {
            for n in group.iter() {
                if let Some(v) = col(n) {
                    let v = if i == 0 {
                        v.iter().map(|x| x.clamp(-255.0, 255.0)).collect()
                    } else {
                        v
                    };
                    panels[i] = panels[i].clone().series(Series::line(*n, th.clone(), v));
                }
            }
        }
        let [p1, p2, p3] = panels;
        figs.push((
            "rls_convergence",
            Figure::new("RLS parameter convergence (Hammerstein, paper's method)").panel(p1).panel(p2).panel(p3),
            "The recursive estimates after each sample of the estimation record (breakpoints clipped to ±255 for display).",
        ));
    }
    figs
}

/// The rows of Table III, in the paper's order.
const TABLE3_NAMES: [ParamName; 8] = [
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

fn table3(s: &ReproduceSettings, st: &Study) -> Table {
    let mut header: Vec<String> = vec!["parameter".into()];
    header.extend(
        st.hammersteins()
            .iter()
            .map(|m| format!("ours: {}", m.label)),
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
            row.push(fmt_opt(truth(s, name)));
        }
        row.push(fmt_opt(paper_normalised(&paper::ESTIMATED, name)));
        row.push(fmt_opt(paper_normalised(&paper::ACTUAL, name)));
        t.push_row(row);
    }
    t.caption(
        "The paper's Table III: Hammerstein parameter estimates (± one standard deviation), normalised to b1 = 1 \
         (the paper's slopes are multiplied by its b1 so that they compare; see docs/paper.md)",
    )
    .paper_column(ncols - 2)
    .paper_column(ncols - 1)
}

fn metrics_row(label: &str, rep: &IdentifyReport) -> [String; 5] {
    let v = rep.metrics.validation.as_ref();
    [
        label.to_string(),
        fmt_opt(v.and_then(|m| m.fit_sim_percent)),
        fmt_opt(v.map(|m| m.loss)),
        fmt_opt(v.and_then(|m| m.fpe)),
        if rep.stable {
            "stable".into()
        } else {
            "UNSTABLE".into()
        },
    ]
}

/// A Table V row: criterion, the paper's simulation and experiment values, ours on model and plant.
type ClosedLoopRow = (&'static str, f64, f64, Option<f64>, Option<f64>);

fn closed_loop_rows(lp: &Loop) -> [ClosedLoopRow; 4] {
    let [a, b, c, d] = paper::CLOSED_LOOP;
    let (m, p) = (&lp.m_model, &lp.m_plant);
    [
        (a.0, a.1, a.2, m.overshoot_mm, p.overshoot_mm),
        (
            b.0,
            b.1,
            b.2,
            m.steady_state_error_mm,
            p.steady_state_error_mm,
        ),
        (c.0, c.1, c.2, m.rise_time_s, p.rise_time_s),
        (d.0, d.1, d.2, m.settling_time_s, p.settling_time_s),
    ]
}

fn tables_text(s: &ReproduceSettings, st: &Study) -> String {
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
            fmt_opt(paper_normalised(&paper::ESTIMATED, name)),
            fmt_opt(paper_normalised(&paper::ACTUAL, name))
        );
    }
    let _ = writeln!(
        o,
        "\nTable IV — validation record (free-run fit %, loss V, FPE)"
    );
    let _ = writeln!(
        o,
        "{:<40}{:>10}{:>12}{:>12}{:>10}",
        "model", "fit %", "loss", "FPE", "poles"
    );
    for m in &st.models {
        let r = metrics_row(m.label, &m.rep);
        let _ = writeln!(
            o,
            "{:<40}{:>10}{:>12}{:>12}{:>10}",
            r[0], r[1], r[2], r[3], r[4]
        );
    }
    for (label, i) in [("paper: linear ARX", 0), ("paper: Hammerstein", 1)] {
        let pick = |p: (f64, f64)| if i == 0 { p.0 } else { p.1 };
        let _ = writeln!(
            o,
            "{label:<40}{:>10}{:>12}{:>12}",
            num(pick(paper::FIT)),
            num(pick(paper::LOSS)),
            num(pick(paper::FPE))
        );
    }
    let _ = writeln!(
        o,
        "\nTable V — PI (Kp = {}, Ki = {}) fixed set-point {} → {} mm, {} s",
        s.pi.kp, s.pi.ki, s.fixed_start_mm, s.fixed_setpoint_mm, s.fixed_duration_s
    );
    let _ = writeln!(
        o,
        "{:<26}{:>14}{:>14}{:>14}{:>14}",
        "criterion", "model (sim.)", "plant", "paper sim.", "paper exp."
    );
    for (label, ps, pe, a, b) in closed_loop_rows(&st.fixed) {
        let _ = writeln!(
            o,
            "{label:<26}{:>14}{:>14}{:>14}{:>14}",
            fmt_opt(a),
            fmt_opt(b),
            ps,
            pe
        );
    }
    let _ = writeln!(o, "\nAcceptance");
    for (ok, text) in &st.verdicts {
        let _ = writeln!(o, "  [{}] {text}", if *ok { "met" } else { "NOT met" });
    }
    o
}

fn build_report(s: &ReproduceSettings, st: &Study, figs: &[Fig]) -> Result<Report, ReproduceError> {
    let fig = |stem: &str| figs.iter().find(|f| f.0 == stem);
    let with_fig = |sec: Section, stem: &str| -> Result<Section, ReproduceError> {
        match fig(stem) {
            Some((_, f, cap)) => Ok(sec.figure_png(f, *cap)?),
            None => Ok(sec),
        }
    };
    let plant_text = match s.plant.as_str() {
        "ipa" => "the project's physics-based simulator of the IPA (40 mm bore, 16 mm rod, 200 mm stroke, 0.6 MPa, \
                  two PWM-driven on/off valves, friction, 0.01 mm encoder); it stands in for the real actuator, \
                  for which no data are published",
        "paper" => "the paper's own \"actual\" Hammerstein model (Table III), so the estimates can be compared with the truth",
        _ => "a saved model given on the command line",
    };
    let mut r = Report::new("Hammerstein model based RLS identification of an Intelligent Pneumatic Actuator — reproduction")
        .subtitle(format!("Plant: {}. Seed {}. Generated by ipa-sysid reproduce.", st.plant_name, s.seed))
        .intro(format!(
            "This report repeats the study of \"Hammerstein Model Based RLS Algorithm for Modeling the Intelligent \
             Pneumatic Actuator (IPA) System\" (IJASEIT 7(4), 2017) end to end. A pneumatic cylinder is driven by a \
             PWM command u (counts, ±255) and its position y (mm) is sampled every {} s. The Hammerstein model is a \
             static valve deadzone (breakpoints b_l, b_r, slopes m_l, m_r) followed by a linear ARX block \
             A(q) y = B(q) x (na = 3, nb = 1, nk = 1), estimated by recursive least squares. The plant here is {plant_text}. \
             Every number below was computed in this run; the paper's numbers are shown beside ours in shaded columns. \
             Models marked \"addition\" are this project's, not the paper's.",
            num(st.ts)
        ));
    let mut acc = Section::new("Verdict");
    for (ok, text) in &st.verdicts {
        acc = acc.callout(
            if *ok { Verdict::Pass } else { Verdict::Fail },
            text.clone(),
        );
    }
    r.push_section(acc);
    r.push_section(with_fig(
        Section::new("1. Experiment").paragraph(format!(
            "{} samples at Ts = {} s of a staircase command with random levels in ±{} counts held for random \
             durations, starting at {} mm (the experimenter steers the signs so that the piston stays inside the \
             stroke, as on a real rig); a second record with the next seed is used only for validation.",
            s.samples,
            num(st.ts),
            s.amplitude_counts,
            s.experiment_start_mm
        )),
        "fig2_experiment",
    )?);
    let arx = &st.arx().fit;
    let est_sec = Section::new("2. Estimated parameters")
        .paragraph(
            "Only products of the deadzone slopes with B are identifiable, so b1 = 1 and the slopes carry the gain. \
             The paper's slopes are converted to this normalisation (multiplied by its b1) so that the columns compare. \
             The linear ARX baseline is estimated by the same RLS. Key-term LS iterates batch least squares to a fixed \
             point; output error (OE) refines all parameters by minimising the free-run simulation error, which removes \
             the bias that equation-error methods (LS, RLS) have when the output is measured with noise or the model \
             is not exact.",
        )
        .table(table3(s, st))
        .paragraph(format!(
            "Linear ARX baseline: a = [{}], b1 = {}. Poles — {}.",
            arx.model.a().iter().map(|v| num(*v)).collect::<Vec<_>>().join(", "),
            num(arx.model.b()[0]),
            st.models.iter().map(|m| format!("{}: {}", m.label, pole_list(&m.rep))).collect::<Vec<_>>().join("; ")
        ));
    r.push_section(with_fig(
        with_fig(est_sec, "fig4_deadzone")?,
        "rls_convergence",
    )?);
    let mut t4 = Table::new(["model", "best fit (%)", "loss V", "FPE", "poles"]).caption(
        "The paper's Table IV: validation record, free-run fit % (eq. 13), loss V = (1/N) Σ ½ ε² (eq. 14) and FPE (eq. 15) of \
         the one-step errors",
    );
    for m in &st.models {
        t4.push_row(metrics_row(m.label, &m.rep));
    }
    t4.push_row([
        "paper: linear ARX".to_string(),
        num(paper::FIT.0),
        num(paper::LOSS.0),
        num(paper::FPE.0),
        "stable".into(),
    ]);
    t4.push_row([
        "paper: Hammerstein".to_string(),
        num(paper::FIT.1),
        num(paper::LOSS.1),
        num(paper::FPE.1),
        "stable".into(),
    ]);
    r.push_section(with_fig(
        Section::new("3. Validation")
            .paragraph(
                "The fit is computed on the validation record by free-run simulation (the model sees only u after \
                 its first na samples), as MATLAB's compare does; loss and FPE use the one-step prediction errors, as \
                 in the paper's equations. A free-run fit is demanding for a plant that integrates: a small error in a \
                 gain or in the integrating pole accumulates into a drift of the position.",
            )
            .table(t4),
        "fig5_fit",
    )?);
    r.push_section(with_fig(
        Section::new("4. Open-loop test").paragraph(format!(
            "The identified Hammerstein model (RLS) and the plant receive the same fresh staircase; the model's free-run \
             output fits the plant's by {} %.",
            fmt_opt(st.fit_ol)
        )),
        "fig6_open_loop",
    )?);
    let mut t5 = Table::new(["criterion", "model (simulation)", "plant", "paper: simulation", "paper: experiment"])
        .caption(format!(
            "The paper's Table V: PI control (Kp = {}, Ki = {}, u = Kp e + Ki Ts Σe, saturated at ±255) from {} mm to the fixed \
             set-point {} mm, {} s",
            s.pi.kp, s.pi.ki, s.fixed_start_mm, s.fixed_setpoint_mm, s.fixed_duration_s
        ))
        .paper_column(3)
        .paper_column(4);
    for (label, ps, pe, a, b) in closed_loop_rows(&st.fixed) {
        t5.push_row([label.to_string(), fmt_opt(a), fmt_opt(b), num(ps), num(pe)]);
    }
    t5.push_row([
        "overshoot (% of step)".to_string(),
        fmt_opt(st.fixed.m_model.overshoot_percent),
        fmt_opt(st.fixed.m_plant.overshoot_percent),
        "—".into(),
        "< 10 (acceptance)".into(),
    ]);
    let comp_text = match &st.compensated {
        Ok(m) => format!(
            "With the inverse of the identified (output-error) deadzone after the PI — the paper's suggested future \
             work — the plant gives: overshoot {} mm ({} %), steady-state error {} mm, rise time {} s, settling time \
             {} s (data/closed_loop_fixed_plant_compensated.csv).",
            fmt_opt(m.overshoot_mm),
            fmt_opt(m.overshoot_percent),
            fmt_opt(m.steady_state_error_mm),
            fmt_opt(m.rise_time_s),
            fmt_opt(m.settling_time_s)
        ),
        Err(reason) => format!("Deadzone compensation was not run: the identified deadzone cannot be inverted ({reason})."),
    };
    let cl = with_fig(
        Section::new("5. Closed-loop position control")
            .paragraph(
                "Metrics follow MATLAB stepinfo: overshoot beyond the final value, steady-state error = set-point − \
                 final value, rise time 10 % → 90 % of the step, settling time into a 2 % band. The paper does not \
                 state its step size; a step from the retracted end is used here. The model is the Hammerstein model \
                 identified by RLS (the paper's).",
            )
            .table(t5)
            .paragraph(comp_text),
        "fig7a_closed_loop_fixed",
    )?;
    let (up, um) = (&st.unfixed.m_plant, &st.unfixed.m_model);
    let cl = with_fig(
        cl.paragraph(format!(
            "Changing set-point ({}): worst step on the plant — overshoot {} mm, steady-state error {} mm, settling {} s; \
             on the model — overshoot {} mm, steady-state error {} mm, settling {} s.",
            s.unfixed_profile,
            fmt_opt(up.overshoot_mm),
            fmt_opt(up.steady_state_error_mm),
            fmt_opt(up.settling_time_s),
            fmt_opt(um.overshoot_mm),
            fmt_opt(um.steady_state_error_mm),
            fmt_opt(um.settling_time_s),
        )),
        "fig7b_closed_loop_unfixed",
    )?;
    r.push_section(cl);
    r.push_section(Section::new("6. Files").list([
        "summary.json — every number of this report, machine-readable".to_string(),
        format!(
            "{} — saved models (ipa-sysid validate --model …)",
            st.models.iter().map(|m| format!("model_{}.json", m.key)).collect::<Vec<_>>().join(", ")
        ),
        "data/estimation.csv, data/validation.csv, data/open_loop.csv, data/closed_loop_*.csv — the records".into(),
        "figures/*.svg, figures/*.png — the figures".into(),
    ]));
    Ok(r.footer(format!(
        "ipa-sysid {} — reproduce --plant {} --seed {}",
        env!("CARGO_PKG_VERSION"),
        s.plant,
        s.seed
    )))
}
