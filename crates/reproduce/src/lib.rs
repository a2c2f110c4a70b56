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
use report::format::{estimate, opt, pm};
use report::html::{Section, Table, Verdict};
use report::plot::{save_figure, Figure, Panel, Series, SeriesStyle};
use report::Report;
use serde_json::json;
use sysid::data::Signals;
use sysid::metrics::{fit_percent, metrics};
use sysid::summary::IdentifyReport;
use sysid::{
    identify, EstimatorSettings, Fitted as FittedModel, Identification, Method,
    RecursiveLeastSquares,
};
use sysid::{Dataset, Model, ModelKind, ModelPlant, ParamName, Plant};
use sysid_core::param::{Layout, Parameterisation};

pub mod analysis;
pub mod colours;
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

fn param_cell(fit: &FittedModel, name: ParamName) -> String {
    match fit.params.iter().find(|p| p.name == name) {
        Some(p) => pm(p.value, p.std),
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

/// The PI loop on the plant and, when there is a stable identified model, on that model.
fn closed_loop_pair(
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

/// A closed-loop test on the plant and on the stable identified model (none when no model is stable).
struct Loop {
    plant: Trace,
    model: Option<Trace>,
    m_plant: StepMetrics,
    m_model: Option<StepMetrics>,
}

/// An acceptance criterion: a stable `id` (the key tests and scripts use), whether it is met, and the
/// sentence that says what was compared.
struct Criterion {
    id: &'static str,
    met: bool,
    text: String,
}

/// Everything a run computed; the tables, figures, report and summary are views of it.
struct Study {
    plant_name: String,
    ts: f64,
    est: Dataset,
    val: Dataset,
    /// `[arx, hammerstein (RLS), hammerstein_ls, hammerstein_oe]`: the first two are the paper's.
    models: Vec<Fitted>,
    /// Index in `models` of the model used for the open-loop test and the simulated closed loops
    /// (see [`closed_loop_choice`]); `None` when no identified model is stable.
    cl_model: Option<usize>,
    u_ol: Vec<f64>,
    y_ol_plant: Vec<f64>,
    y_ol_model: Option<Vec<f64>>,
    fit_ol: Option<f64>,
    fixed: Loop,
    compensated: Result<StepMetrics, String>,
    unfixed: Loop,
    steps_plant: Vec<control::StepSegment>,
    steps_model: Vec<control::StepSegment>,
    paper_check: analysis::PaperCheck,
    residuals: Vec<analysis::ModelResiduals>,
    verdicts: Vec<Criterion>,
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
    /// The model the open-loop test and the simulated closed loops ran on.
    fn cl(&self) -> Option<&Fitted> {
        self.cl_model.and_then(|i| self.models.get(i))
    }
}

/// The rule that picks the model for the open-loop test and the simulated closed loops, in words.
pub const CLOSED_LOOP_RULE: &str = "the paper's model (Hammerstein by RLS) when all its poles are inside the unit circle; \
     otherwise the stable Hammerstein model with the best free-run fit on the validation record; otherwise the \
     linear ARX if it is stable; otherwise none (an unstable model is shown but never controlled)";

/// Applies [`CLOSED_LOOP_RULE`] to `models` (`[arx, hammerstein, ...]`).
fn closed_loop_choice(models: &[Fitted]) -> Option<usize> {
    if models.get(1).is_some_and(|m| m.rep.stable) {
        return Some(1);
    }
    let best = models
        .iter()
        .enumerate()
        .skip(1)
        .filter(|(_, m)| m.rep.stable)
        .max_by(|(_, a), (_, b)| {
            let f = |m: &Fitted| validation_fit(&m.rep).unwrap_or(f64::NEG_INFINITY);
            f(a).total_cmp(&f(b))
        })
        .map(|(i, _)| i);
    best.or_else(|| models.first().filter(|m| m.rep.stable).map(|_| 0))
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
                estimate(p.re)
            } else {
                format!("{} ± {}i", estimate(p.re), estimate(p.im.abs()))
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
            &[&t_rec, d.u(), d.y()],
        )?;
    }

    // 2. Identification: the paper's two models, then this project's additions.
    progress(
        "identification (ARX and Hammerstein by RLS; key-term LS; output error)",
        0.2,
    );
    // The paper's method: one RLS pass.
    let rls = RecursiveLeastSquares {
        forgetting: s.forgetting,
        passes: sysid::Passes::Fixed(1),
        ..RecursiveLeastSquares::default()
    };
    let base = Identification::default().with_estimator(EstimatorSettings::Rls(rls));
    let plan: [(&'static str, &'static str, &'static str, Identification); 4] = [
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
    for &(key, label, short, ref set) in &plan {
        let fit = identify(&est, set)?;
        let e = metrics(&fit.model, &est)?;
        let v = metrics(&fit.model, &val)?;
        let rep = IdentifyReport::new(&fit, set, e, Some(v));
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
    let cl_model = closed_loop_choice(&models);
    let mut model_plant = match cl_model.and_then(|i| models.get(i)) {
        Some(m) => Some(ModelPlant::new(m.fit.model.clone(), m.label)?),
        None => None,
    };

    // The paper's own model as the plant (known truth), with the paper's method.
    progress("the method on the paper's model", 0.3);
    let paper_check =
        analysis::paper_check(&plan[1].3, est.u(), val.u(), s.experiment_start_mm, s.seed)?;
    let residuals = models
        .iter()
        .map(|m| analysis::ModelResiduals {
            key: m.key,
            estimation: analysis::residuals(&m.fit.model, &est),
            validation: analysis::residuals(&m.fit.model, &val),
        })
        .collect();

    // Open-loop test (Fig. 6): a fresh staircase on plant and the stable identified model.
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
    let y_ol_model = match model_plant.as_mut() {
        Some(mp) => {
            mp.reset(s.experiment_start_mm);
            Some(sysid::plant::run_open_loop(mp, &u_ol)?)
        }
        None => None,
    };
    let fit_ol = y_ol_model.as_ref().and_then(|y| fit_percent(ol.y(), y));
    let t_ol = sysid::data::sample_times(u_ol.len(), ts);
    let nan = vec![f64::NAN; u_ol.len()];
    sysid_io::write_columns_csv(
        &data_dir.join("open_loop.csv"),
        &["t", "u", "y_plant", "y_model"],
        &[&t_ol, &u_ol, ol.y(), y_ol_model.as_ref().unwrap_or(&nan)],
    )?;

    // 3. Closed loop, fixed and unfixed set-point, model vs plant.
    progress("closed-loop PI control", 0.55);
    let fixed_profile = Profile::Fixed {
        setpoint_mm: s.fixed_setpoint_mm,
    };
    let (fp, fm) = closed_loop_pair(
        plant.as_mut(),
        model_plant.as_mut(),
        &s.pi,
        &fixed_profile,
        s.fixed_duration_s,
        s.fixed_start_mm,
    )?;
    let fixed = Loop {
        m_plant: step_metrics(&fp, s.fixed_start_mm, s.fixed_setpoint_mm)?,
        m_model: match &fm {
            Some(fm) => Some(step_metrics(fm, s.fixed_start_mm, s.fixed_setpoint_mm)?),
            None => None,
        },
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
        model_plant.as_mut(),
        &s.pi,
        &unfixed_profile,
        uf_duration,
        s.fixed_start_mm,
    )?;
    let (m_up, steps_plant) = unfixed_metrics(&up)?;
    let (m_um, steps_model) = match &um {
        Some(um) => {
            let (m, steps) = unfixed_metrics(um)?;
            (Some(m), steps)
        }
        None => (None, Vec::new()),
    };
    let unfixed = Loop {
        plant: up,
        model: um,
        m_plant: m_up,
        m_model: m_um,
    };
    for (name, tr) in [
        ("closed_loop_fixed_plant.csv", Some(&fixed.plant)),
        ("closed_loop_fixed_model.csv", fixed.model.as_ref()),
        ("closed_loop_unfixed_plant.csv", Some(&unfixed.plant)),
        ("closed_loop_unfixed_model.csv", unfixed.model.as_ref()),
    ] {
        if let Some(tr) = tr {
            sysid_io::write_columns_csv(&data_dir.join(name), &Trace::COLUMNS, &tr.columns())?;
        }
    }

    let mut study = Study {
        plant_name: plant.name(),
        ts,
        est,
        val,
        models,
        cl_model,
        u_ol,
        y_ol_plant: ol.y().to_vec(),
        y_ol_model,
        fit_ol,
        fixed,
        compensated,
        unfixed,
        steps_plant,
        steps_model,
        paper_check,
        residuals,
        verdicts: Vec::new(),
    };
    study.verdicts = verdicts(s, &study);
    let accepted = study.verdicts.iter().all(|v| v.met);

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

/// The words a fit comparison needs when a compared model is unstable: its simulation grows without
/// bound, so a fit over a finite record flatters it and says nothing about a longer one.
fn unstable_caveat(models: &[(&str, bool)]) -> String {
    let unstable: Vec<&str> = models.iter().filter(|m| !m.1).map(|m| m.0).collect();
    if unstable.is_empty() {
        return String::new();
    }
    format!(
        ". Caution: {} {} UNSTABLE, so {} simulation diverges and this comparison holds only over this record's \
         length",
        unstable.join(" and "),
        if unstable.len() == 1 { "is" } else { "are" },
        if unstable.len() == 1 { "its" } else { "their" }
    )
}

/// The acceptance criteria of the paper (and the issue), each with its id, whether it is met and why.
fn verdicts(s: &ReproduceSettings, st: &Study) -> Vec<Criterion> {
    let step = (s.fixed_setpoint_mm - s.fixed_start_mm).abs();
    let (fa, fh) = (validation_fit(&st.arx().rep), validation_fit(&st.ham().rep));
    // A fit ≤ 0 % is no better than the mean of the record: such a model beats nothing.
    let beats = matches!((fa, fh), (Some(a), Some(h)) if h > 0.0 && h > a);
    let mut v = vec![Criterion {
        id: "hammerstein_beats_arx",
        met: beats,
        text: format!(
            "Hammerstein (RLS, paper's method) fits the validation record with a positive fit, better than the \
             linear ARX: {} % vs {} % (paper: {} % vs {} %){}{}",
            opt(fh),
            opt(fa),
            estimate(paper::FIT.1),
            estimate(paper::FIT.0),
            match fh {
                Some(h) if h <= 0.0 => {
                    " — a fit of 0 % or less is no better than the record's mean, so neither model passes"
                }
                _ => "",
            },
            unstable_caveat(&[("Hammerstein (RLS)", st.ham().rep.stable), ("ARX", st.arx().rep.stable)]),
        ),
    }];
    let ham = &st.ham().rep;
    let max_pole = ham.poles.iter().map(|p| p.abs).fold(0.0, f64::max);
    v.push(Criterion {
        id: "hammerstein_stable",
        met: ham.stable,
        text: if ham.stable {
            format!("Hammerstein (RLS) poles inside the unit circle: {}", pole_list(ham))
        } else {
            format!(
                "Hammerstein (RLS) poles inside the unit circle: {} — the largest has |p| = {}. The plant integrates \
                 (position is the integral of velocity), so its true pole is at 1, and the equation-error estimate \
                 lands just outside. It is shown but not controlled: the open-loop test and the simulated closed \
                 loops use {}",
                pole_list(ham),
                estimate(max_pole),
                st.cl().map_or("no model (none is stable)", |m| m.label)
            )
        },
    });
    if let Some(oe) = st.model("hammerstein_oe") {
        let fo = validation_fit(&oe.rep);
        v.push(Criterion {
            id: "oe_stable_and_beats_arx",
            met: oe.rep.stable && matches!((fa, fo), (Some(a), Some(o)) if o > 0.0 && o > a),
            text: format!(
                "Addition: Hammerstein by output error is {} and fits the validation record by {} % (linear ARX: {} %)",
                if oe.rep.stable { "stable" } else { "UNSTABLE" },
                opt(fo),
                opt(fa)
            ),
        });
    }
    v.push(Criterion {
        id: "closed_loop_model_stable",
        met: st.cl().is_some(),
        text: match st.cl() {
            Some(m) => format!(
                "A stable identified model runs the open-loop test and the simulated closed loops: {} (rule: {})",
                m.label, CLOSED_LOOP_RULE
            ),
            None => format!(
                "No identified model is stable, so none was simulated in open or closed loop (rule: {CLOSED_LOOP_RULE})"
            ),
        },
    });
    let os = st.fixed.m_plant.overshoot_percent;
    v.push(Criterion {
        id: "pi_overshoot",
        met: os.is_some_and(|x| x < 10.0),
        text: format!(
            "PI on the plant: overshoot {} % of the step (paper's acceptance: < 10 %)",
            opt(os)
        ),
    });
    let ess = st.fixed.m_plant.steady_state_error_mm;
    v.push(Criterion {
        id: "pi_steady_state_error",
        met: ess.is_some_and(|e| e.abs() < 0.02 * step),
        text: format!(
            "PI on the plant: |steady-state error| {} mm, {} % of the {} mm step after {} s (paper's acceptance: < 2 %)",
            opt(ess.map(f64::abs)),
            opt(ess.map(|e| 100.0 * e.abs() / step.max(f64::MIN_POSITIVE))),
            estimate(step),
            estimate(s.fixed_duration_s)
        ),
    });
    v
}

/// A row of the "differences from the paper" table.
struct Difference {
    id: &'static str,
    /// Quantity and unit.
    quantity: &'static str,
    /// This run's values: (model label or "plant", value).
    plant: Vec<(String, Option<f64>)>,
    /// The paper's values: (which, value).
    paper: Vec<(&'static str, f64)>,
    /// Why they differ, where it is known.
    reason: &'static str,
}

fn param_value(fit: &FittedModel, name: ParamName) -> Option<f64> {
    fit.params.iter().find(|p| p.name == name).map(|p| p.value)
}

/// The side-by-side comparison of this run with the paper: deadzone, gains, dominant pole, fit, loss,
/// FPE, settling time.
fn differences(s: &ReproduceSettings, st: &Study) -> Vec<Difference> {
    let shown: Vec<&Fitted> = ["hammerstein", "hammerstein_oe"]
        .iter()
        .filter_map(|k| st.model(k))
        .collect();
    let per_model = |f: &dyn Fn(&Fitted) -> Option<f64>| -> Vec<(String, Option<f64>)> {
        shown.iter().map(|m| (m.short.to_string(), f(m))).collect()
    };
    let est = |name: ParamName| paper_normalised(&paper::ESTIMATED, name).unwrap_or(f64::NAN);
    let val = |m: &Fitted, f: &dyn Fn(&sysid_core::metrics::Metrics) -> Option<f64>| {
        m.rep.metrics.validation.as_ref().and_then(f)
    };
    let physics = s.plant == "ipa";
    let deadzone_reason = if physics {
        "the simulator's on/off valves open 0.4 ms after they are energised (no valve opens below 10.2 counts at a \
         10 ms PWM period) and the seals' static friction (stiction) holds the piston until the average chamber \
         pressure beats it: no motion for |u| ≤ 35 counts (docs/plant.md). 1.41 counts at the paper's 10 ms period \
         is a 0.055 ms pulse, far shorter than a solenoid valve opens, so the paper's deadzone leaves no room for \
         valve delay or stiction (docs/paper.md)"
    } else {
        "the plant is not the physics simulator: differences are estimation error"
    };
    vec![
        Difference {
            id: "b_r",
            quantity: "right breakpoint b_r (counts)",
            plant: per_model(&|m| param_value(&m.fit, ParamName::BR)),
            paper: vec![("estimated", est(ParamName::BR))],
            reason: deadzone_reason,
        },
        Difference {
            id: "b_l",
            quantity: "left breakpoint b_l (counts)",
            plant: per_model(&|m| param_value(&m.fit, ParamName::BL)),
            paper: vec![("estimated", est(ParamName::BL))],
            reason: if physics {
                "as for b_r"
            } else {
                deadzone_reason
            },
        },
        Difference {
            id: "m_r",
            quantity: "right gain m_r·b1 (mm per count and sample, b1 = 1)",
            plant: per_model(&|m| param_value(&m.fit, ParamName::MR)),
            paper: vec![("estimated", est(ParamName::MR))],
            reason: if physics {
                "beyond the deadzone the simulator's command-to-velocity curve is not a straight line (it bends up \
                 from creep at 40 counts to full speed), so one slope averages it; the paper's own estimated and \
                 actual gains differ by a factor 2.1 (docs/paper.md)"
            } else {
                "estimation error"
            },
        },
        Difference {
            id: "m_l",
            quantity: "left gain m_l·b1 (mm per count and sample, b1 = 1)",
            plant: per_model(&|m| param_value(&m.fit, ParamName::ML)),
            paper: vec![("estimated", est(ParamName::ML))],
            reason: if physics {
                "as for m_r; retracting is slower than extending (smaller rod-side area)"
            } else {
                "estimation error"
            },
        },
        Difference {
            id: "dominant_pole",
            quantity: "dominant pole, largest |p|",
            plant: per_model(&|m| m.rep.poles.iter().map(|p| p.abs).reduce(f64::max)),
            paper: vec![("estimated A(z)", 0.999445)],
            reason: "both plants integrate (position is the integral of velocity), so one pole belongs at 1; the \
                     equation-error estimates (RLS) of this integrating plant land just outside the unit circle, \
                     output error just inside. The paper's printed poles are those of its estimated A(z), not of \
                     its actual one (docs/paper.md)",
        },
        Difference {
            id: "fit",
            quantity: "validation fit (%)",
            plant: per_model(&|m| val(m, &|v| v.fit_sim_percent)),
            paper: vec![("Hammerstein", paper::FIT.1)],
            reason: "a free-run fit of an integrating plant accumulates every gain error into a drift of the \
                     position; the paper does not say whether its fit is free-run or one-step ahead, nor how long its \
                     validation record is. The paper's experiment was a \"continuous step signal with amplitude \
                     ±255\", i.e. mostly full-speed motion; the staircase here visits every level in ±255 counts, \
                     inside the deadzone too, where the piston sticks",
        },
        Difference {
            id: "loss",
            quantity: "loss V = (1/N) Σ ½ ε² (mm²)",
            plant: per_model(&|m| val(m, &|v| Some(v.loss))),
            paper: vec![("Hammerstein", paper::LOSS.1)],
            reason: "one-step errors grow with unmodelled dynamics: the simulator's pressure dynamics, friction and \
                     stick–slip are outside a 3rd-order Hammerstein model; the paper's V means a one-step RMS error of \
                     0.041 mm",
        },
        Difference {
            id: "fpe",
            quantity: "FPE (mm²)",
            plant: per_model(&|m| val(m, &|v| v.fpe)),
            paper: vec![("Hammerstein", paper::FPE.1)],
            reason: "as for the loss (FPE = V (1 + d/N)/(1 − d/N))",
        },
        Difference {
            id: "settling_time",
            quantity: "PI settling time into 2 %, fixed set-point (s)",
            plant: vec![
                ("plant".to_string(), st.fixed.m_plant.settling_time_s),
                (
                    st.cl().map_or("model".to_string(), |m| format!("{} (simulation)", m.short)),
                    st.fixed.m_model.as_ref().and_then(|m| m.settling_time_s),
                ),
            ],
            paper: vec![("simulation", paper::CLOSED_LOOP[3].1), ("experiment", paper::CLOSED_LOOP[3].2)],
            reason: if physics {
                "the piston stops where |Kp e + integral| falls inside the deadzone and the slow integral (Ki Ts = \
                 0.01 count per mm and sample) takes seconds to push it out; the paper's own experiment took 36.6 s, \
                 its 0.42 s is a simulation of its model"
            } else {
                "the paper does not state its step size or integral form (docs/paper.md)"
            },
        },
    ]
}

fn difference_cells(d: &Difference) -> [String; 4] {
    let join = |v: Vec<String>| v.join("; ");
    [
        d.quantity.to_string(),
        join(
            d.plant
                .iter()
                .map(|(l, v)| format!("{l}: {}", opt(*v)))
                .collect(),
        ),
        join(
            d.paper
                .iter()
                .map(|(l, v)| format!("{l}: {}", estimate(*v)))
                .collect(),
        ),
        d.reason.to_string(),
    ]
}

fn summary_json(
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
                       } },
            "unfixed": { "profile": s.unfixed_profile,
                         "model": mjo(&st.unfixed.m_model), "plant": mj(&st.unfixed.m_plant),
                         "steps_model": st.steps_model, "steps_plant": st.steps_plant },
        },
        "acceptance": {
            "accepted": accepted,
            "criteria": st.verdicts.iter().map(|c| json!({"id": c.id, "met": c.met, "criterion": c.text})).collect::<Vec<_>>(),
        },
        "elapsed_s": elapsed_s,
    })
}

type Fig = (&'static str, Figure, String);

fn sim_or_nan(model: &Model, d: &Dataset) -> Vec<f64> {
    model
        .simulate(&[d.u()], d.y())
        .unwrap_or_else(|_| vec![f64::NAN; d.len()])
}

/// A y range for `v` that ignores its first `skip` samples (the start-up transient of a recursive
/// estimate), padded by 10 % of the span (or of |value| for a constant).
fn settled_range(v: &[f64], skip: usize) -> Option<(f64, f64)> {
    let tail = v.get(skip..).filter(|t| !t.is_empty()).unwrap_or(v);
    let (lo, hi) = tail
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    if lo > hi {
        return None;
    }
    let pad = if hi > lo {
        0.1 * (hi - lo)
    } else {
        0.1 * lo.abs().max(1e-12)
    };
    Some((lo - pad, hi + pad))
}

/// Frequency responses of the linear blocks drawn in the Bode figure: (key, label, model, gain), the
/// Hammerstein blocks scaled by their mean deadzone slope (m_l + m_r)/2 so that all are in mm/count.
fn bode_models(st: &Study) -> Vec<(&'static str, String, Model, f64)> {
    let mean_slope = |m: &Model| m.deadzone().map_or(1.0, |d| 0.5 * (d.m_l + d.m_r));
    let mut v: Vec<(&'static str, String, Model, f64)> = st
        .models
        .iter()
        .map(|m| {
            (
                m.key,
                m.label.to_string(),
                m.fit.model.clone(),
                mean_slope(&m.fit.model),
            )
        })
        .collect();
    let paper = Model::paper();
    let g = mean_slope(&paper);
    v.push(("paper", "paper's actual model (Table III)".into(), paper, g));
    v
}

fn figures(s: &ReproduceSettings, st: &Study) -> Vec<Fig> {
    let ts = st.ts;
    let t = sysid::data::sample_times(st.est.len(), ts);
    let mut figs: Vec<Fig> = Vec::new();
    let plant_c = colours::PLANT;
    figs.push((
        "fig2_experiment",
        Figure::new("Experiment: staircase input and measured position (paper's Fig. 2)")
            .panel(Panel::new("time (s)", "u (counts)").series(Series::step("u: PWM command", t.clone(), st.est.u().to_vec()).colour(plant_c)))
            .panel(Panel::new("time (s)", "y (mm)").series(Series::line("y: position", t.clone(), st.est.y().to_vec()).colour(plant_c))),
        "The estimation record: the staircase command u (PWM counts) and the measured stroke position y (mm).".into(),
    ));

    // Deadzone: RLS solid, the others dashed on top so that coinciding curves stay visible.
    let us: Vec<f64> = (-255..=255).map(f64::from).collect();
    let mut dz_panel = Panel::new("u (counts)", "x (key-term units, b1 = 1)");
    for (i, m) in st.hammersteins().iter().enumerate() {
        let y = m.fit.model.internal(&us);
        let series = if i == 0 {
            Series::line(m.label, us.clone(), y)
        } else {
            Series::dashed(m.label, us.clone(), y)
        };
        dz_panel = dz_panel.series(series.colour(colours::model(m.key)));
    }
    dz_panel = dz_panel.series(
        Series::dashed(
            "paper's actual model (Table III)",
            us.clone(),
            Model::paper().internal(&us),
        )
        .colour(colours::PAPER),
    );
    let (rls, ls) = (st.model("hammerstein"), st.model("hammerstein_ls"));
    let coincide = match (rls, ls) {
        (Some(a), Some(b)) => {
            let (ya, yb) = (a.fit.model.internal(&us), b.fit.model.internal(&us));
            let scale = ya
                .iter()
                .map(|v| v.abs())
                .fold(0.0, f64::max)
                .max(f64::MIN_POSITIVE);
            let gap = ya
                .iter()
                .zip(&yb)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max);
            Some(100.0 * gap / scale)
        }
        _ => None,
    };
    figs.push((
        "fig4_deadzone",
        Figure::new("Identified valve deadzone x = f(u) (paper's Fig. 4)").panel(dz_panel),
        format!(
            "The identified static nonlinearity: the valve deadzone between b_l and b_r and the slopes m_l, m_r \
             (b1 = 1), with the paper's Table III actual deadzone (slopes times its b1). The RLS curve is solid, \
             the others dashed on top of it{}.",
            coincide.map_or(String::new(), |g| format!(
                "; the RLS and key-term LS curves differ by at most {} % of the largest |x|, so they overlap",
                estimate(g)
            ))
        ),
    ));

    let tv = sysid::data::sample_times(st.val.len(), ts);
    let mut fit_panel = Panel::new("time (s)", "y (mm)")
        .series(Series::line("measured", tv.clone(), st.val.y().to_vec()).colour(plant_c));
    for key in ["arx", "hammerstein", "hammerstein_oe"] {
        if let Some(m) = st.model(key) {
            fit_panel = fit_panel.series(
                Series::dashed(m.label, tv.clone(), sim_or_nan(&m.fit.model, &st.val))
                    .colour(colours::model(key)),
            );
        }
    }
    figs.push((
        "fig5_fit",
        Figure::new("Validation record: measured vs simulated output (paper's Fig. 5)").panel(fit_panel),
        "Free-run simulation of the models on the validation record (which was not used for estimation).".into(),
    ));

    let t_ol = sysid::data::sample_times(st.u_ol.len(), ts);
    let mut y_ol = Panel::new("time (s)", "y (mm)")
        .series(Series::line("plant", t_ol.clone(), st.y_ol_plant.clone()).colour(plant_c));
    if let (Some(m), Some(y)) = (st.cl(), &st.y_ol_model) {
        y_ol = y_ol
            .series(Series::dashed(m.label, t_ol.clone(), y.clone()).colour(colours::model(m.key)));
    }
    figs.push((
        "fig6_open_loop",
        Figure::new("Open-loop test: stable identified model vs plant (paper's Fig. 6)")
            .panel(Panel::new("time (s)", "u (counts)").series(
                Series::step("u", t_ol.clone(), st.u_ol.clone()).colour(plant_c),
            ))
            .panel(y_ol),
        match st.cl() {
            Some(m) => format!(
                "A fresh staircase applied to the plant and to {} (the stable model chosen by the stated rule) from the same start.",
                m.label
            ),
            None => "A fresh staircase applied to the plant; no identified model is stable, so none is simulated.".into(),
        },
    ));

    // Closed loops: y (and for the fixed set-point a zoom on the first second(s)), then u.
    let cl_label = st.cl().map_or("model", |m| m.label);
    let cl_colour = st.cl().map_or(plant_c, |m| colours::model(m.key));
    let y_panel = |lp: &Loop, until: f64| {
        let cut = |tr: &Trace, v: &[f64]| -> (Vec<f64>, Vec<f64>) {
            tr.t.iter()
                .zip(v)
                .filter(|(t, _)| **t <= until)
                .map(|(t, v)| (*t, *v))
                .unzip()
        };
        let (tp, r) = cut(&lp.plant, &lp.plant.r);
        let (_, yp) = cut(&lp.plant, &lp.plant.y);
        let mut p = Panel::new("time (s)", "y (mm)")
            .series(Series::step("set-point r", tp.clone(), r).colour(colours::SETPOINT))
            .series(Series::line("plant", tp, yp).colour(plant_c));
        if let Some(m) = &lp.model {
            let (tm, ym) = cut(m, &m.y);
            p = p
                .series(Series::dashed(format!("simulated: {cl_label}"), tm, ym).colour(cl_colour));
        }
        p
    };
    let u_panel = |lp: &Loop| {
        let mut p = Panel::new("time (s)", "u (counts)").series(
            Series::step("u: plant", lp.plant.t.clone(), lp.plant.u.clone()).colour(plant_c),
        );
        if let Some(m) = &lp.model {
            p = p.series(
                Series::step(format!("u: {cl_label}"), m.t.clone(), m.u.clone()).colour(cl_colour),
            );
        }
        p
    };
    let rise = [Some(&st.fixed.m_plant), st.fixed.m_model.as_ref()]
        .iter()
        .flatten()
        .filter_map(|m| m.rise_time_s)
        .fold(0.0, f64::max);
    let zoom = (10.0 * rise).clamp(1.0, s.fixed_duration_s);
    let sim_note = if st.cl().is_some() {
        format!("the simulated {cl_label} vs the plant")
    } else {
        "the plant only (no identified model is stable)".to_string()
    };
    figs.push((
        "fig7a_closed_loop_fixed",
        Figure::new("PI control, fixed set-point (paper's Fig. 7a)")
            .size(960, 1120)
            .panel(y_panel(&st.fixed, f64::INFINITY))
            .panel(y_panel(&st.fixed, zoom))
            .panel(u_panel(&st.fixed)),
        format!(
            "PI (Kp = {}, Ki = {}) from rest to the fixed set-point: {sim_note}. Top: the whole {} s; middle: the \
             first {} s, where the rise happens; bottom: the commands.",
            estimate(s.pi.kp),
            estimate(s.pi.ki),
            estimate(s.fixed_duration_s),
            estimate(zoom)
        ),
    ));
    figs.push((
        "fig7b_closed_loop_unfixed",
        Figure::new("PI control, changing set-point (paper's Fig. 7b)")
            .panel(y_panel(&st.unfixed, f64::INFINITY))
            .panel(u_panel(&st.unfixed)),
        format!(
            "PI (Kp = {}, Ki = {}) following a staircase of set-points: {sim_note}.",
            estimate(s.pi.kp),
            estimate(s.pi.ki)
        ),
    ));

    // RLS convergence: one panel per parameter, each scaled to its settled range.
    let ham = &st.ham().fit;
    if !ham.history.is_empty() {
        let th: Vec<f64> = ham.history_samples.iter().map(|&k| k as f64 * ts).collect();
        let skip = ham.history.len() / 10;
        let mut fig = Figure::new("RLS parameter convergence (Hammerstein, paper's method)");
        for (name, unit) in [
            ("b_r", "b_r (counts)"),
            ("b_l", "b_l (counts)"),
            ("m_r", "m_r"),
            ("m_l", "m_l"),
            ("a1", "a1"),
            ("a2", "a2"),
            ("a3", "a3"),
        ] {
            let Some(i) = ham.params.iter().position(|p| p.name == name) else {
                continue;
            };
            let v: Vec<f64> = ham
                .history
                .iter()
                .map(|h| h.get(i).copied().unwrap_or(f64::NAN))
                .collect();
            let mut panel = Panel::new("time (s)", unit).series(
                Series::line("", th.clone(), v.clone()).colour(colours::model("hammerstein")),
            );
            if let Some((lo, hi)) = settled_range(&v, skip) {
                panel = panel.y_range(lo, hi);
            }
            fig = fig.panel(panel);
        }
        let n = fig.panels.len() as u32;
        figs.push((
            "rls_convergence",
            fig.size(960, 120 + 190 * n),
            format!(
                "The recursive estimates after each sample of the estimation record, one panel per parameter. Each \
                 panel's y range is the range of the estimate after the first {} s (10 % of the record), so that \
                 the settling is visible; the start-up transient is clipped at the panel's edges.",
                estimate(skip as f64 * ts)
            ),
        ));
    }

    // Residual correlations on the validation record.
    let mut acf = Panel::new("lag τ (samples)", "autocorrelation r_ε(τ)");
    let mut ccf = Panel::new("lag τ (samples)", "cross-correlation r_εu(τ)");
    let mut bound = None;
    for r in &st.residuals {
        let Ok(a) = &r.validation else { continue };
        let label = st.model(r.key).map_or(r.key, |m| m.label);
        let lags: Vec<f64> = (1..=a.max_lag).map(|l| l as f64).collect();
        // Key-term LS nearly coincides with RLS: dashed on top so that both stay visible.
        let style = if r.key == "hammerstein_ls" {
            SeriesStyle::Dashed
        } else {
            SeriesStyle::Line
        };
        acf = acf.series(
            Series::new(label, lags, a.autocorrelation.clone(), style)
                .colour(colours::model(r.key)),
        );
        let m = a.max_lag as f64;
        let lags: Vec<f64> = (0..a.cross_correlation.len())
            .map(|i| i as f64 - m)
            .collect();
        ccf = ccf.series(
            Series::new(label, lags, a.cross_correlation.clone(), style)
                .colour(colours::model(r.key)),
        );
        bound = Some((a.bound, a.max_lag as f64));
    }
    if let Some((b, m)) = bound {
        let band = |panel: Panel, from: f64| {
            panel
                .series(
                    Series::dashed("99 % bound ±2.58/√N", vec![from, m], vec![b, b])
                        .colour(colours::BOUND),
                )
                .series(Series::dashed("", vec![from, m], vec![-b, -b]).colour(colours::BOUND))
        };
        acf = band(acf, 1.0);
        ccf = band(ccf, -m);
    }
    figs.push((
        "residuals",
        Figure::new("Residual analysis on the validation record (one-step prediction errors)")
            .panel(acf)
            .panel(ccf),
        "Autocorrelation of each model's one-step prediction residuals ε (top) and their cross-correlation with \
         the input u (bottom; ε(t) against u(t − τ)), on the validation record, with the 99 % bounds ±2.58/√N. A \
         model that has captured the dynamics leaves residuals inside both bands."
            .into(),
    ));

    // Bode plots of the linear blocks.
    let mut mag = Panel::new("frequency f (Hz, log scale)", "|G| (dB re 1 mm/count)").x_log10();
    let mut phase = Panel::new("frequency f (Hz, log scale)", "phase of G (degrees)").x_log10();
    for (i, (key, label, model, gain)) in bode_models(st).into_iter().enumerate() {
        let b = analysis::bode(&model, gain, 0.01, 300);
        let lf: Vec<f64> = b.f_hz.iter().map(|f| f.log10()).collect();
        let (sm, sp) = if i == 0 || key == "hammerstein" {
            (
                Series::line(label.clone(), lf.clone(), b.mag_db),
                Series::line(label, lf, b.phase_deg),
            )
        } else {
            (
                Series::dashed(label.clone(), lf.clone(), b.mag_db),
                Series::dashed(label, lf, b.phase_deg),
            )
        };
        mag = mag.series(sm.colour(colours::model(key)));
        phase = phase.series(sp.colour(colours::model(key)));
    }
    figs.push((
        "bode",
        Figure::new("Frequency response of the identified linear blocks").panel(mag).panel(phase),
        format!(
            "Bode magnitude and phase of G(e^(jωTs)) = m̄ B(e^(−jωTs))/A(e^(−jωTs)) from 0.01 Hz to the Nyquist \
             frequency {} Hz. The Hammerstein blocks have b1 = 1 (their static gain sits in the deadzone slopes), so \
             they are multiplied by the mean slope m̄ = (m_l + m_r)/2 to compare with the ARX (m̄ = 1) in mm per \
             count; the paper's actual model is scaled the same way.",
            estimate(0.5 / ts)
        ),
    ));
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

fn metrics_row(label: &str, rep: &IdentifyReport) -> [String; 5] {
    let v = rep.metrics.validation.as_ref();
    [
        label.to_string(),
        opt(v.and_then(|m| m.fit_sim_percent)),
        opt(v.map(|m| m.loss)),
        opt(v.and_then(|m| m.fpe)),
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
    let (m, p) = (lp.m_model.as_ref(), &lp.m_plant);
    [
        (
            a.0,
            a.1,
            a.2,
            m.and_then(|m| m.overshoot_mm),
            p.overshoot_mm,
        ),
        (
            b.0,
            b.1,
            b.2,
            m.and_then(|m| m.steady_state_error_mm),
            p.steady_state_error_mm,
        ),
        (c.0, c.1, c.2, m.and_then(|m| m.rise_time_s), p.rise_time_s),
        (
            d.0,
            d.1,
            d.2,
            m.and_then(|m| m.settling_time_s),
            p.settling_time_s,
        ),
    ]
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
            opt(paper_normalised(&paper::ESTIMATED, name)),
            opt(paper_normalised(&paper::ACTUAL, name))
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
            estimate(pick(paper::FIT)),
            estimate(pick(paper::LOSS)),
            estimate(pick(paper::FPE))
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
            opt(a),
            opt(b),
            estimate(ps),
            estimate(pe)
        );
    }
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
    let _ = writeln!(o, "\nResiduals (validation record, 99 % level)");
    for r in &st.residuals {
        let _ = writeln!(o, "  {:<38} {}", r.key, resid_verdict(&r.validation));
    }
    let _ = writeln!(o, "\nAcceptance");
    for c in &st.verdicts {
        let _ = writeln!(
            o,
            "  [{}] {}: {}",
            if c.met { "met" } else { "NOT met" },
            c.id,
            c.text
        );
    }
    o
}

/// Table of the known-truth check: the paper's actual values beside the estimates from its model.
fn paper_model_table(st: &Study) -> Table {
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

fn residual_table(st: &Study) -> Table {
    let n = st
        .residuals
        .iter()
        .find_map(|r| r.validation.as_ref().ok().map(|a| (a.n, a.max_lag)));
    let mut t = Table::new([
        "model",
        "record",
        "residual std (mm)",
        "lags outside ±2.58/√N (auto / cross)",
        "whiteness: Ljung–Box Q (p)",
        "independence of u: S (p)",
    ])
    .caption(format!(
        "Residual tests at the 1 % level on the one-step prediction errors{}: whiteness by Ljung–Box against \
         χ²(M), independence of the input by the input-whitened statistic against χ²(2M+1)",
        n.map_or(String::new(), |(n, m)| format!(" (N = {n} samples per record, M = {m} lags)"))
    ));
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
                        "{}: {} ({})",
                        if a.white { "white" } else { "NOT white" },
                        estimate(a.ljung_box_q),
                        report::format::sig(a.ljung_box_p, 2)
                    ),
                    format!(
                        "{}: {} ({})",
                        if a.independent {
                            "independent"
                        } else {
                            "NOT independent"
                        },
                        estimate(a.cross_statistic),
                        report::format::sig(a.cross_p, 2)
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

fn colour_key(st: &Study) -> String {
    let mut parts = vec![format!(
        "plant and measured signals: {}",
        colours::name(colours::PLANT)
    )];
    parts.extend(
        st.models
            .iter()
            .map(|m| format!("{}: {}", m.label, colours::name(colours::model(m.key)))),
    );
    parts.push(format!(
        "the paper's model: {}",
        colours::name(colours::PAPER)
    ));
    parts.push(format!("set-point: {}", colours::name(colours::SETPOINT)));
    parts.push(format!("99 % bounds: {}", colours::name(colours::BOUND)));
    format!(
        "Colours are the same in every figure — {}.",
        parts.join("; ")
    )
}

fn build_report(s: &ReproduceSettings, st: &Study, figs: &[Fig]) -> Result<Report, ReproduceError> {
    let fig = |stem: &str| figs.iter().find(|f| f.0 == stem);
    let with_fig = |sec: Section, stem: &str| -> Result<Section, ReproduceError> {
        match fig(stem) {
            Some((_, f, cap)) => Ok(sec.figure_png(f, cap.clone())?),
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
             A(q) y = B(q) x (na = 3, nb = 1, nk = 1), estimated by recursive least squares. The method is first run \
             on the paper's own model, where the truth is known; then on the plant, which here is {plant_text}. \
             Every number below was computed in this run (estimates to 4 significant digits, standard deviations \
             to 2); the paper's numbers are shown beside ours in shaded columns. Models marked \"addition\" are \
             this project's, not the paper's. docs/paper.md in the repository gives this project's account of the \
             paper, its equations and its inconsistencies.",
            estimate(st.ts)
        ))
        .intro(colour_key(st));
    let mut acc = Section::new("Verdict").id("verdict");
    for c in &st.verdicts {
        acc = acc.callout(
            if c.met { Verdict::Pass } else { Verdict::Fail },
            c.text.clone(),
        );
    }
    r.push_section(acc);

    let runs = &st.paper_check.runs;
    let worst_dev = |r: &analysis::PaperRun| {
        TABLE3_NAMES
            .iter()
            .filter_map(|n| {
                Some((
                    param_value(&r.fit, *n)?,
                    paper_normalised(&paper::ACTUAL, *n)?,
                ))
            })
            .map(|(e, a)| ((e - a) / a.abs().max(f64::MIN_POSITIVE)).abs() * 100.0)
            .fold(0.0, f64::max)
    };
    r.push_section(
        Section::new("The method on the paper's own model")
            .id("paper-model")
            .paragraph(format!(
                "Before the harder physics plant: the paper's Table III \"actual\" model is used as the plant, driven \
                 by the same staircase from the same start, and identified by the paper's method with the settings \
                 used for every run of this report. Without noise the estimates should equal the truth; with \
                 {} mm of white output noise (the encoder's resolution) the equation-error RLS is expected to be \
                 slightly biased. Largest relative deviation from the actual values: {}.",
                estimate(analysis::PAPER_NOISE_MM),
                runs.iter()
                    .map(|r| format!("{} % ({})", estimate(worst_dev(r)), r.label))
                    .collect::<Vec<_>>()
                    .join(", ")
            ))
            .table(paper_model_table(st)),
    );

    r.push_section(with_fig(
        Section::new("Experiment").id("experiment").paragraph(format!(
            "{} samples at Ts = {} s of a staircase command with random levels in ±{} counts held for random \
             durations, starting at {} mm (the experimenter steers the signs so that the piston stays inside the \
             stroke, as on a real rig); a second record with the next seed is used only for validation.",
            s.samples,
            estimate(st.ts),
            estimate(s.amplitude_counts),
            estimate(s.experiment_start_mm)
        )),
        "fig2_experiment",
    )?);
    let arx = &st.arx().fit;
    let est_sec = Section::new("Estimated parameters")
        .id("estimates")
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
            "Linear ARX baseline: a = [{}], b1 = {} mm/count. Poles — {}.",
            arx.model.a().iter().map(|v| estimate(*v)).collect::<Vec<_>>().join(", "),
            estimate(arx.model.b()[0]),
            st.models.iter().map(|m| format!("{}: {}", m.label, pole_list(&m.rep))).collect::<Vec<_>>().join("; ")
        ));
    r.push_section(with_fig(
        with_fig(est_sec, "fig4_deadzone")?,
        "rls_convergence",
    )?);
    let mut t4 = Table::new(["model", "best fit (%)", "loss V (mm²)", "FPE (mm²)", "poles"]).caption(
        "The paper's Table IV: validation record, free-run fit % (eq. 13), loss V = (1/N) Σ ½ ε² (eq. 14) and FPE (eq. 15) of \
         the one-step errors",
    );
    for m in &st.models {
        t4.push_row(metrics_row(m.label, &m.rep));
    }
    for (label, i) in [("paper: linear ARX", 0), ("paper: Hammerstein", 1)] {
        let pick = |p: (f64, f64)| if i == 0 { p.0 } else { p.1 };
        t4.push_row([
            label.to_string(),
            estimate(pick(paper::FIT)),
            estimate(pick(paper::LOSS)),
            estimate(pick(paper::FPE)),
            "stable".into(),
        ]);
    }
    r.push_section(with_fig(
        Section::new("Validation")
            .id("validation")
            .paragraph(
                "The fit is computed on the validation record by free-run simulation from initial outputs estimated \
                 to fit the record (the model sees only u after its first na samples), as MATLAB's compare does; \
                 loss and FPE use the one-step prediction errors, as in the paper's equations. The output-error \
                 model's predictor is its simulation (its noise model is white output error), so its loss and FPE \
                 are simulation errors and are not comparable with the equation-error losses of the other rows. A \
                 free-run fit is demanding for a plant that integrates: a small error in a gain or in the \
                 integrating pole accumulates into a drift of the position. A fit of 0 % or less is no better than \
                 the record's mean.",
            )
            .table(t4),
        "fig5_fit",
    )?);
    r.push_section(with_fig(
        Section::new("Residual analysis")
            .id("residuals")
            .paragraph(
                "A model that has captured the plant leaves one-step prediction residuals ε(k) = y(k) − ŷ(k|k−1) that \
                 are white (no autocorrelation) and independent of past inputs (no cross-correlation with u), as \
                 MATLAB's resid checks. Below, each model on both records: the number of lags outside the 99 % band \
                 and the two tests' verdicts.",
            )
            .table(residual_table(st)),
        "residuals",
    )?);
    r.push_section(with_fig(
        Section::new("Frequency response")
            .id("frequency-response")
            .paragraph(format!(
                "The identified linear blocks B(q)/A(q) as Bode plots up to the Nyquist frequency {} Hz. An integrating \
                 plant shows a magnitude falling at 20 dB per decade and a phase near −90° over most of the band. Below \
                 the corner frequency |1 − p|/(2π Ts) of the slow pole p, the phase of a stable pole (p < 1) returns \
                 toward 0° and that of an unstable one (p > 1) falls toward −180°: this is where the unstable models \
                 show themselves.",
                estimate(0.5 / st.ts)
            )),
        "bode",
    )?);
    r.push_section(with_fig(
        Section::new("Open-loop test").id("open-loop").paragraph(match st.cl() {
            Some(m) => format!(
                "The model for the open-loop test and the simulated closed loops is chosen by a stated rule: {CLOSED_LOOP_RULE}. \
                 Here it is {}. It and the plant receive the same fresh staircase; the model's free-run output fits \
                 the plant's by {} %.",
                m.label,
                opt(st.fit_ol)
            ),
            None => format!(
                "Rule for the model simulated in open and closed loop: {CLOSED_LOOP_RULE}. No identified model is \
                 stable, so only the plant is shown."
            ),
        }),
        "fig6_open_loop",
    )?);
    let model_col = format!(
        "model: {} (simulation)",
        st.cl().map_or("none stable", |m| m.short)
    );
    let mut t5 = Table::new(vec![
        "criterion".to_string(),
        model_col,
        "plant".into(),
        "paper: simulation".into(),
        "paper: experiment".into(),
    ])
    .caption(format!(
        "The paper's Table V: PI control (Kp = {}, Ki = {}, u = Kp e + Ki Ts Σe, saturated at ±255) from {} mm to the fixed \
         set-point {} mm, {} s",
        estimate(s.pi.kp),
        estimate(s.pi.ki),
        estimate(s.fixed_start_mm),
        estimate(s.fixed_setpoint_mm),
        estimate(s.fixed_duration_s)
    ))
    .paper_column(3)
    .paper_column(4);
    for (label, ps, pe, a, b) in closed_loop_rows(&st.fixed) {
        t5.push_row([
            label.to_string(),
            opt(a),
            opt(b),
            estimate(ps),
            estimate(pe),
        ]);
    }
    t5.push_row([
        "overshoot (% of step)".to_string(),
        opt(st.fixed.m_model.as_ref().and_then(|m| m.overshoot_percent)),
        opt(st.fixed.m_plant.overshoot_percent),
        "—".into(),
        "< 10 (acceptance)".into(),
    ]);
    let comp_text = match &st.compensated {
        Ok(m) => format!(
            "With the inverse of the identified (output-error) deadzone after the PI — the paper's suggested future \
             work — the plant gives: overshoot {} mm ({} %), steady-state error {} mm, rise time {} s, settling time \
             {} s (data/closed_loop_fixed_plant_compensated.csv).",
            opt(m.overshoot_mm),
            opt(m.overshoot_percent),
            opt(m.steady_state_error_mm),
            opt(m.rise_time_s),
            opt(m.settling_time_s)
        ),
        Err(reason) => format!("Deadzone compensation was not run: the identified deadzone cannot be inverted ({reason})."),
    };
    let cl = with_fig(
        Section::new("Closed-loop position control")
            .id("closed-loop")
            .paragraph(format!(
                "Metrics follow MATLAB stepinfo: overshoot beyond the final value, steady-state error = set-point − \
                 final value, rise time 10 % → 90 % of the step, settling time into a 2 % band. The paper does not \
                 state its step size; a step from the retracted end is used here. The simulated loop runs on {}, \
                 chosen by the rule stated in the open-loop section; an unstable model is never controlled.",
                st.cl().map_or("no model (none is stable)", |m| m.label)
            ))
            .table(t5)
            .paragraph(comp_text),
        "fig7a_closed_loop_fixed",
    )?;
    let up = &st.unfixed.m_plant;
    let um = st.unfixed.m_model.as_ref();
    let cl = with_fig(
        cl.paragraph(format!(
            "Changing set-point ({}): worst step on the plant — overshoot {} mm, steady-state error {} mm, settling {} s; \
             on the model — overshoot {} mm, steady-state error {} mm, settling {} s.",
            s.unfixed_profile,
            opt(up.overshoot_mm),
            opt(up.steady_state_error_mm),
            opt(up.settling_time_s),
            opt(um.and_then(|m| m.overshoot_mm)),
            opt(um.and_then(|m| m.steady_state_error_mm)),
            opt(um.and_then(|m| m.settling_time_s)),
        )),
        "fig7b_closed_loop_unfixed",
    )?;
    r.push_section(cl);
    let mut td = Table::new(["quantity (unit)", "this run", "paper", "why they differ (where known)"])
        .caption("This run beside the paper: RLS is the paper's method, output error this project's addition; the paper's values are its Table III–V")
        .paper_column(2);
    for d in differences(s, st) {
        td.push_row(difference_cells(&d));
    }
    r.push_section(
        Section::new("Differences from the paper")
            .id("differences")
            .paragraph(if s.plant == "ipa" {
                "The plant here is a physics simulator, not the paper's rig, and it was not tuned to the paper's \
                 numbers. The table sets the main quantities side by side with the reason for each difference where it \
                 is known; docs/plant.md and docs/paper.md in the repository give the details."
            } else {
                "The plant here is not the physics simulator; the reasons below refer to what is known of it."
            })
            .table(td),
    );
    r.push_section(Section::new("Files").id("files").list([
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
