//! `ipa-sysid tune`: tune the position controller on an identified model or on a calibrated twin,
//! verify it beside the paper's PI, and write CONTROLLER.json.
//!
//! Thin: flags -> `control::tune` (search, evaluation, margins) -> text, JSON and the controller file.
//! Method and definitions: docs/control.md, section "Tuning".

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context};
use control::tune::{self, Comparison, Evaluation, Margins, Spec, TuneSettings};
use control::{ControlError, ControllerFile, ControllerSettings};
use serde::Serialize;
use sysid::Plant;

/// Flags of `ipa-sysid tune`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Tune on this identified Hammerstein model (`identify --save-model`): the simulations run on it
    /// and on variants of its deadzone (gain and breakpoints ±30 %); its deadzone sets the compensator.
    #[arg(
        long,
        value_name = "M.json",
        required_unless_present = "plant_config",
        conflicts_with = "plant_config"
    )]
    pub model: Option<PathBuf>,
    /// Tune on this physics-plant TOML (a twin from `ipa-sysid calibrate`): the simulations run on the
    /// twin and its variants (±30 %); the compensator's deadzone comes from a Hammerstein model
    /// identified (output error) on a simulated record of the twin.
    #[arg(long, value_name = "TWIN.toml")]
    pub plant_config: Option<PathBuf>,
    /// Specification, `KEY=VALUE,...` over the defaults overshoot=1 (%), ess=0.02 (mm), limit-cycle=0.02
    /// (mm), u-max=255, steps=10/30/70/150 (mm, each up from `low` and down from `high`), low=25, high=175
    /// (mm), run=3 (s per step), settling=0.5 (s), ess-share=0.9, ess-all=0.05 (mm).
    #[arg(long, value_name = "SPEC", default_value = "")]
    pub spec: String,
    /// Write the tuned controller here (JSON; `control --controller` and the C interface read it).
    #[arg(long, value_name = "CONTROLLER.json")]
    pub out: PathBuf,
    /// Plant variants searched over (variant 0 is the nominal model or twin).
    #[arg(long, value_name = "N", default_value_t = 5)]
    pub variants: usize,
    /// Largest number of cost evaluations of the search (each simulates every variant and step).
    #[arg(long, value_name = "N", default_value_t = 150)]
    pub max_evaluations: usize,
    /// Also verify on the built-in physics plant (with --model: for a model identified on a record of
    /// it); with --plant-config the twin is always verified.
    #[arg(long)]
    pub check_physics: bool,
    /// Variants of the physics plant (±30 %, seeds 1..N) in the verification, beside the nominal one.
    #[arg(long, value_name = "N", default_value_t = 20)]
    pub physics_variants: usize,
    /// Write the results as JSON to this file (`-` = standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

/// Largest number of plant variants (bounds the work a flag can ask for).
const MAX_VARIANTS: usize = 200;
/// Largest number of evaluations.
const MAX_EVALUATIONS: usize = 10_000;
/// Spread of the plant variants: ±30 %.
const SPREAD: f64 = 0.3;

/// One verification: a plant set, the tuned controller and the paper's PI on it, and why the spec is missed.
#[derive(Debug, Serialize)]
struct Verification {
    plant: String,
    plants: usize,
    #[serde(flatten)]
    comparison: Comparison,
    warnings: Vec<String>,
}

#[derive(Debug, Serialize)]
struct TuneOut<'a> {
    source: String,
    spec: &'a Spec,
    search: &'a TuneSettings,
    evaluations: usize,
    seconds: f64,
    controller: &'a ControllerSettings,
    margins: Margins,
    on_model: &'a Verification,
    #[serde(skip_serializing_if = "Option::is_none")]
    on_physics: Option<&'a Verification>,
    controller_file: String,
    warnings: &'a [String],
}

/// Runs `ipa-sysid tune`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let spec = Spec::parse(&args.spec).context("invalid --spec")?;
    for (flag, v, max) in [
        ("--variants", args.variants, MAX_VARIANTS),
        ("--physics-variants", args.physics_variants, MAX_VARIANTS),
        ("--max-evaluations", args.max_evaluations, MAX_EVALUATIONS),
    ] {
        if v > max {
            bail!(sysid::SysidError::setting(
                sysid::Setting::Other(flag),
                v,
                &format!("at most {max}")
            ));
        }
    }
    if args.variants == 0 {
        bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--variants"),
            0,
            "at least 1 (the nominal plant)"
        ));
    }
    let inputs: Vec<&Path> = [args.model.as_deref(), args.plant_config.as_deref()]
        .into_iter()
        .flatten()
        .collect();
    sysid_io::check_writable(&args.out, "--out")?;
    sysid_io::refuse_overwrite_input(&args.out, &inputs, "--out")?;
    if let Some(j) = args.json.as_ref().filter(|j| j.as_os_str() != "-") {
        sysid_io::check_writable(j, "--json")?;
        sysid_io::refuse_overwrite_input(j, &inputs, "--json")?;
        if *j == args.out {
            bail!(sysid::SysidError::setting(
                sysid::Setting::Other("--json"),
                j.display(),
                "a path different from --out"
            ));
        }
    }

    let started = Instant::now();
    let search = TuneSettings {
        plants: args.variants,
        max_evaluations: args.max_evaluations,
    };
    // The model (for the compensator's deadzone and the margins) and the plants searched over.
    let (model, source, twin) = match (&args.model, &args.plant_config) {
        (Some(path), None) => {
            let m = sysid::model_file::read_model(path).context("cannot read --model")?;
            super::control::command_deadzone(&m, path, "--model")?;
            (m, format!("model {}", path.display()), None)
        }
        (None, Some(path)) => {
            let cfg =
                ipa::PlantConfig::from_toml_file(path).context("cannot read --plant-config")?;
            let m = twin_model(&cfg).with_context(|| {
                format!(
                    "cannot identify a Hammerstein model on a record of --plant-config {}",
                    path.display()
                )
            })?;
            (m, format!("twin {}", path.display()), Some(cfg))
        }
        _ => bail!("give exactly one of --model M.json or --plant-config TWIN.toml"),
    };
    let deadzone = match &args.model {
        Some(path) => super::control::command_deadzone(&model, path, "--model")?,
        None => *model
            .deadzone()
            .context("the twin's identified model has no deadzone")?,
    };
    let ts = model.ts();
    let model_plants = |i: usize| -> Result<Box<dyn Plant + Send>, ControlError> {
        let m = tune::model_variant(&model, i, SPREAD)?;
        Ok(Box::new(
            sysid::ModelPlant::new(m, format!("model variant {i}"))
                .map_err(|e| ControlError::Config(e.to_string()))?,
        ))
    };
    let physics_base = twin.clone().unwrap_or_default();
    let physics_plants = |i: usize| -> Result<Box<dyn Plant + Send>, ControlError> {
        let cfg = if i == 0 {
            physics_base.clone()
        } else {
            ipa::calibrate::study::perturbed_from(&physics_base, i as u64, SPREAD)
        };
        Ok(Box::new(
            ipa::Ipa::with_ts(cfg, ts).map_err(|e| ControlError::Config(e.to_string()))?,
        ))
    };
    let tuned = if twin.is_some() {
        tune::tune(&physics_plants, Some(deadzone), ts, &spec, &search)?
    } else {
        tune::tune(&model_plants, Some(deadzone), ts, &spec, &search)?
    };
    let settings = tuned.settings;
    let margins = tune::margins(&model, &settings);

    let on_model = verify(
        &format!("the model (nominal + {} variants)", args.variants - 1),
        args.variants,
        &model_plants,
        &settings,
        &spec,
    )?;
    let on_physics = if twin.is_some() || args.check_physics {
        let what = if twin.is_some() {
            "the twin"
        } else {
            "the physics plant"
        };
        Some(verify(
            &format!(
                "{what} (nominal + {} variants ±30 %)",
                args.physics_variants
            ),
            args.physics_variants + 1,
            &physics_plants,
            &settings,
            &spec,
        )?)
    } else {
        None
    };
    let seconds = started.elapsed().as_secs_f64();
    let mut warnings = Vec::new();
    if twin.is_none() && !args.check_physics {
        warnings.push(
            "verified on the model only: a model without the plant's static friction cannot show \
             stick-slip hunting; verify on the plant (--check-physics for the built-in one, or \
             `control --controller` on yours)"
                .to_string(),
        );
    }
    warnings.extend(on_model.warnings.iter().cloned());
    if let Some(p) = &on_physics {
        warnings.extend(p.warnings.iter().cloned());
    }
    if margins.phase_margin_deg.is_some_and(|pm| pm < 30.0) {
        warnings.push(format!(
            "the linear part's phase margin is {:.1}° (< 30°): the loop is close to oscillating",
            margins.phase_margin_deg.unwrap_or(f64::NAN)
        ));
    }

    let provenance = serde_json::json!({
        "tuned_by": "ipa-sysid tune",
        "source": source,
        "spec": spec,
        "meets_spec": warnings.iter().all(|w| !w.starts_with("not met")),
    });
    let file = ControllerFile::new(settings, Some(provenance));
    let text = serde_json::to_string_pretty(&file).context("serialising the controller")? + "\n";
    sysid_io::write_atomic(&args.out, text.as_bytes())?;

    let summary = summary_text(
        &spec,
        &source,
        &settings,
        &margins,
        &on_model,
        on_physics.as_ref(),
        tuned.evaluations,
        seconds,
        &args.out,
        &warnings,
    );
    let json_to_stdout = args.json.as_ref().is_some_and(|j| j.as_os_str() == "-");
    if let Some(json) = &args.json {
        let doc = TuneOut {
            source: source.clone(),
            spec: &spec,
            search: &search,
            evaluations: tuned.evaluations,
            seconds,
            controller: &settings,
            margins,
            on_model: &on_model,
            on_physics: on_physics.as_ref(),
            controller_file: args.out.display().to_string(),
            warnings: &warnings,
        };
        let text =
            serde_json::to_string_pretty(&doc).context("serialising the JSON output")? + "\n";
        if json_to_stdout {
            std::io::stdout()
                .write_all(text.as_bytes())
                .context("writing JSON to standard output")?;
        } else {
            sysid_io::write_atomic(json, text.as_bytes())?;
        }
    }
    if json_to_stdout {
        eprint!("{summary}");
    } else {
        print!("{summary}");
    }
    Ok(())
}

/// A Hammerstein model of a twin: output error, orders (3, 1, 1), on 3000 samples of the staircase
/// input simulated on it (seed 1, mid-stroke start), as a user would identify one from a record.
fn twin_model(cfg: &ipa::PlantConfig) -> anyhow::Result<sysid::Model> {
    let rec = ipa::calibrate::study::record(cfg, ipa::InputSpec::Staircase, 3000, 1)?;
    let data = sysid::Dataset::new(
        sysid::data::Signals {
            u: rec.u.clone(),
            y: rec.y.clone(),
        },
        rec.ts,
        "twin record",
    )?;
    let settings = sysid::Identification::default()
        .with_kind(sysid::ModelKind::Hammerstein)
        .with_orders(3, 1, 1)
        .with_estimator(sysid::EstimatorSettings::Oe(sysid::OutputError::default()));
    Ok(sysid::identify(&data, &settings)?.model)
}

fn verify(
    what: &str,
    plants: usize,
    make: &tune::PlantFactory,
    settings: &ControllerSettings,
    spec: &Spec,
) -> anyhow::Result<Verification> {
    let comparison = tune::compare(plants, make, settings, spec)?;
    let warnings = comparison.tuned.spec_warnings(spec, what);
    Ok(Verification {
        plant: what.to_string(),
        plants,
        comparison,
        warnings,
    })
}

fn f(v: Option<f64>, digits: usize) -> String {
    v.map_or("n/a".to_string(), |x| format!("{x:.digits$}"))
}

/// The Table V criteria of an evaluation: worst over its runs, and how many runs meet the spec.
fn rows(label: &str, e: &Evaluation) -> String {
    let w = e.worst;
    let n = e.runs.len();
    format!(
        "  {label:<16} {:>9} {:>8} {:>10} {:>8} {:>9} {:>9}   {:>3}/{n} {:>3}/{n} {:>3}/{n} {:>3}/{n}\n",
        f(w.and_then(|m| m.overshoot_mm), 3),
        f(w.and_then(|m| m.overshoot_percent), 2),
        f(w.and_then(|m| m.steady_state_error_mm).map(f64::abs), 3),
        f(w.and_then(|m| m.rise_time_s), 3),
        f(w.and_then(|m| m.settling_time_s), 3),
        format!("{:.3}", e.worst_limit_cycle_mm),
        e.overshoot_met,
        e.settling_met,
        e.ess_met,
        e.met,
    )
}

fn block(v: &Verification, spec: &Spec) -> String {
    let mut o = format!(
        "on {} ({} runs: {} steps × {} plants; worst over the runs):\n",
        v.plant,
        v.comparison.tuned.runs.len(),
        spec.cases().len(),
        v.plants
    );
    o += &format!(
        "  {:<16} {:>9} {:>8} {:>10} {:>8} {:>9} {:>9}   {:>5} {:>5} {:>5} {:>5}\n",
        "controller",
        "OS mm",
        "OS %",
        "|e_ss| mm",
        "t_r s",
        "t_s s",
        "cycle mm",
        "OS",
        "t_s",
        "e_ss",
        "all"
    );
    o += &rows("tuned", &v.comparison.tuned);
    o += &rows("paper PI 14/1", &v.comparison.paper_pi);
    o
}

#[allow(clippy::too_many_arguments)]
fn summary_text(
    spec: &Spec,
    source: &str,
    s: &ControllerSettings,
    m: &Margins,
    on_model: &Verification,
    on_physics: Option<&Verification>,
    evaluations: usize,
    seconds: f64,
    out: &Path,
    warnings: &[String],
) -> String {
    let mut o = format!("tuned on:     {source} ({evaluations} evaluations, {seconds:.2} s)\n");
    o += &format!("controller:   {}\n", super::control::tuned_line(s));
    o += &format!(
        "margins:      gain {} dB at {} rad/s, phase {}° at {} rad/s (linear part: model with the deadzone's slope)\n",
        f(m.gain_margin_db, 2),
        f(m.phase_crossover_rad_s, 2),
        f(m.phase_margin_deg, 1),
        f(m.gain_crossover_rad_s, 2)
    );
    o += &block(on_model, spec);
    if let Some(p) = on_physics {
        o += &block(p, spec);
    }
    o += "  (columns OS..all: steps meeting overshoot, settling-time target, |e_ss| and the whole spec)\n";
    o += &format!("wrote {}\n", out.display());
    for w in warnings {
        o += &format!("warning: {w}\n");
    }
    o
}
