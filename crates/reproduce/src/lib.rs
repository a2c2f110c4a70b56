//! `reproduce`: the paper end to end on a plant (the physics IPA by default).
//!
//! 1. Experiment: a staircase ("continuous step signal") of ±A counts, N samples at Ts, from mid-stroke; a
//!    second, independent record (next seed) for validation.
//! 2. Identification: the linear ARX baseline and the Hammerstein model by RLS (the paper's method,
//!    na = 3, nb = 1, nk = 1), plus the Hammerstein model by iterated key-term least squares (labelled as
//!    this project's addition).
//! 3. Tables III (estimates), IV (validation fit, loss, FPE), V (closed-loop metrics, model vs plant), with
//!    the paper's numbers beside ours.
//! 4. On the physics plant, the calibrated twin (`twin.rs`, docs/twin.md) beside the paper's model class.
//! 5. Figures (SVG and PNG) and `report.html`, `summary.json`, `data/*.csv`.

use std::path::PathBuf;
use std::time::Instant;

use control::{PiSettings, Profile, Trace};
use ipa::input::{generate, InputSpec};
use report::plot::save_figure;
use sysid::metrics::metrics;
use sysid::{identify, EstimatorSettings, Identification, Method, RecursiveLeastSquares};
use sysid::{ModelKind, ModelPlant};
use sysid_summary::IdentifyReport;

mod acceptance;
pub mod analysis;
mod closed_loop;
pub mod colours;
mod differences;
pub mod error;
mod experiment;
mod figures;
mod page;
pub mod paper;
mod study;
mod summary;
mod tables;
mod twin;
pub use error::ReproduceError;
pub use study::CLOSED_LOOP_RULE;

use closed_loop::{
    closed_loop_pair, compensated_run, experiment_warning, run_warnings, step_metrics, tuned_run,
    unfixed_metrics,
};
use experiment::record;
use study::{closed_loop_choice, Fitted, Loop, Study};

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
    let spec: ipa::PlantSpec = s.plant.parse()?;
    let limits = spec.limits(s.plant_config.as_deref())?;
    let mut plant = spec.build(s.plant_config.as_deref(), None)?;
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
    // From the measured initial outputs, as `validate` simulates (MATLAB `compare` with 'InitialCondition'
    // 'z'): a user re-checking the figure with `validate --data data/open_loop.csv` gets the same number.
    let (y_ol_model, fit_ol) = match cl_model.and_then(|i| models.get(i)) {
        Some(m) => (
            Some(m.fit.model.simulate(&[&u_ol], ol.y())?),
            metrics(&m.fit.model, &ol)?.fit_sim_measured_percent,
        ),
        None => (None, None),
    };
    let t_ol = sysid::data::sample_times(u_ol.len(), ts);
    let nan = vec![f64::NAN; u_ol.len()];
    sysid_io::write_columns_csv(
        &data_dir.join("open_loop.csv"),
        &["t", "u", "y_plant", "y_model"],
        &[&t_ol, &u_ol, ol.y(), y_ol_model.as_ref().unwrap_or(&nan)],
    )?;

    // The calibrated twin on the same records (physics plant only).
    progress("calibrated twin", 0.5);
    let twin = twin::calibrated_twin(s, ts, [est.u(), val.u(), &u_ol], &models);

    // The plant's own doubts (a model file's), then each run's, as `control` gives them (audit s14 M-e).
    let mut warnings: Vec<String> = limits
        .model_warnings
        .iter()
        .map(|w| format!("the plant model: {w}"))
        .collect();
    warnings.extend(experiment_warning(&[est.u(), val.u(), &u_ol], &limits));

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
    warnings.extend(run_warnings(
        "PI on the plant, fixed set-point",
        &fp,
        &limits,
        s.pi.u_max,
    )?);
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
            warnings.extend(run_warnings(
                "PI with the deadzone compensator on the plant, fixed set-point",
                &tr,
                &limits,
                s.pi.u_max,
            )?);
            sysid_io::write_columns_csv(
                &data_dir.join("closed_loop_fixed_plant_compensated.csv"),
                &Trace::COLUMNS,
                &tr.columns(),
            )?;
            Ok(step_metrics(&tr, s.fixed_start_mm, s.fixed_setpoint_mm)?)
        }
        Err(reason) => Err(reason),
    };
    // Issue 25: the controller tuned on the same output-error model, on the plant and on the model.
    let tuned = match tuned_run(
        plant.as_mut(),
        comp_source,
        &fixed_profile,
        s.fixed_duration_s,
        s.fixed_start_mm,
    )? {
        Ok((settings, verdict, on_plant, on_model)) => {
            // tune's own verdict, as `tune` prints it, then the doubts about both runs (the model's
            // included: an unsettled step whose e_ss is not final; audit s23 M-R2).
            warnings.extend(
                verdict
                    .warnings
                    .iter()
                    .map(|w| format!("the tuned controller (tune's verdict): {w}")),
            );
            warnings.extend(run_warnings(
                "the tuned controller on the plant, fixed set-point",
                &on_plant,
                &limits,
                settings.u_max,
            )?);
            warnings.extend(run_warnings(
                "the tuned controller on the output-error model, fixed set-point",
                &on_model,
                &limits,
                settings.u_max,
            )?);
            sysid_io::write_columns_csv(
                &data_dir.join("closed_loop_fixed_plant_tuned.csv"),
                &Trace::COLUMNS,
                &on_plant.columns(),
            )?;
            Ok(study::Tuned {
                settings,
                verdict,
                m_plant: step_metrics(&on_plant, s.fixed_start_mm, s.fixed_setpoint_mm)?,
                m_model: step_metrics(&on_model, s.fixed_start_mm, s.fixed_setpoint_mm)?,
            })
        }
        Err(reason) => Err(reason),
    };
    let unfixed_profile = Profile::parse(&s.unfixed_profile)?;
    let uf_duration = unfixed_profile
        .natural_duration_checked(ts)?
        .unwrap_or(20.0);
    let (up, um) = closed_loop_pair(
        plant.as_mut(),
        model_plant.as_mut(),
        &s.pi,
        &unfixed_profile,
        uf_duration,
        s.fixed_start_mm,
    )?;
    warnings.extend(run_warnings(
        "PI on the plant, changing set-point",
        &up,
        &limits,
        s.pi.u_max,
    )?);
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
        units: control::Units::of(limits.model_units()),
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
        tuned,
        unfixed,
        steps_plant,
        steps_model,
        paper_check,
        residuals,
        twin,
        warnings,
        verdicts: Vec::new(),
        checks: Vec::new(),
    };
    study.verdicts = acceptance::verdicts(s, &study);
    study.checks = acceptance::process_checks(&study);
    let accepted = study.verdicts.iter().all(|v| v.judged && v.met);

    // 4. Figures.
    progress("figures", 0.7);
    let figs = figures::figures(s, &study);
    for (stem, fig, _) in &figs {
        save_figure(fig, &fig_dir, stem)?;
    }

    // 5. Summary and report.
    progress("report", 0.9);
    let summary = summary::summary_json(s, &study, accepted, started.elapsed().as_secs_f64());
    let text = tables::tables_text(s, &study);
    let report = page::build_report(s, &study, &figs)?;
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
