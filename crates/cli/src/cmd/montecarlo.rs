//! `ipa-sysid montecarlo`: bias and spread of every parameter per estimator under white output noise.
//! The study is `sysid_studies::montecarlo::study` (parallel, deterministic per seed); this file wires the plants
//! (`ipa::plant_from_spec`) and the input design (`ipa::input::generate`) into it.

use std::path::{Path, PathBuf};

use anyhow::Context;
use ipa::input::{generate, InputSpec};
use sysid::{Identification, Method};
use sysid::{Model, ModelKind, Orders};
use sysid_studies::montecarlo::{study, truth_of, StudySettings};

use super::common::{check_outputs, progress_bar, write_output, write_outputs};

/// Flags of `montecarlo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Plant: `ipa` (physics simulator), `paper` (the paper's model) or `model:FILE` (a saved model);
    /// the default is `ipa`, as in every command (bias against known parameters needs `paper` or a model).
    #[arg(long, default_value = "ipa")]
    pub plant: String,
    /// TOML parameters of the physics plant (`--plant ipa` only).
    #[arg(long, value_name = "FILE")]
    pub plant_config: Option<PathBuf>,
    /// Standard deviation of the white noise added to the output (units of y, mm).
    #[arg(long, default_value_t = 0.01)]
    pub noise_std: f64,
    /// Number of runs.
    #[arg(long, default_value_t = 100)]
    pub runs: usize,
    /// Estimators to compare, comma separated: ls, rls, iv, oe.
    #[arg(long, default_value = "ls,rls,iv,oe", value_delimiter = ',')]
    pub method: Vec<String>,
    /// Input signal (staircase, prbs, aprbs, multisine, step:LEVEL, file:CSV).
    #[arg(long, default_value = "staircase")]
    pub input: String,
    /// Input amplitude in counts.
    #[arg(long, default_value_t = 255.0)]
    pub amplitude: f64,
    /// Samples per run.
    #[arg(long, default_value_t = 2000)]
    pub samples: usize,
    /// Study seed (run r uses a seed derived from (seed, r)).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Model structure to estimate (default: the plant model's own; hammerstein for `ipa`; `--model` is
    /// an older spelling).
    #[arg(
        long = "structure",
        alias = "model",
        value_name = "STRUCTURE",
        value_enum
    )]
    pub model: Option<ModelKind>,
    /// na (default: the plant model's; 3 for `ipa`).
    #[arg(long)]
    pub na: Option<usize>,
    /// nb (default: the plant model's; 1 for `ipa`).
    #[arg(long)]
    pub nb: Option<usize>,
    /// nk (default: the plant model's; 1 for `ipa`).
    #[arg(long)]
    pub nk: Option<usize>,
    /// Estimate an offset c (default: when the plant model has one).
    #[arg(long)]
    pub offset: bool,
    /// RLS forgetting factor.
    #[arg(long, default_value_t = 1.0)]
    pub forgetting: f64,
    /// Write the study as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Largest total work accepted, in samples estimated: runs x samples x methods (raise it for a
    /// study that is meant to run for hours).
    #[arg(long, value_name = "SAMPLES", default_value_t = DEFAULT_MAX_WORK)]
    pub max_work: u64,
    /// Exit with code 1 when the study carries warnings (they are printed either way), without writing
    /// --json (an earlier file there is kept).
    #[arg(long)]
    pub strict: bool,
    #[command(flatten)]
    pub memory: super::common::MemoryArgs,
}

/// Default bound on runs x samples x methods: 10^9 samples estimated (about an hour on one core with
/// the default estimators; the default study is 8 x 10^5).
pub const DEFAULT_MAX_WORK: u64 = 1_000_000_000;

fn parse_method(m: &str) -> anyhow::Result<Method> {
    Ok(match m.trim() {
        "ls" => Method::Ls,
        "rls" => Method::Rls,
        "iv" => Method::Iv,
        "oe" => Method::Oe,
        other => anyhow::bail!(
            "invalid --method '{other}': expected a comma-separated list of ls, rls, iv, oe"
        ),
    })
}

/// Runs `montecarlo`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let methods = args
        .method
        .iter()
        .map(|m| parse_method(m))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let spec: InputSpec = args.input.parse()?;
    let mut inputs: Vec<&Path> =
        ipa::spec::spec_input_files(&args.plant, args.plant_config.as_deref());
    inputs.extend(spec.file());
    check_outputs(&[(&args.json, "--json")], &inputs)?;
    // The truth (known for model plants) and the sampling period.
    let plant_spec = args.plant.trim().to_string();
    let truth_model: Option<Model> = if plant_spec == "paper" {
        Some(Model::paper())
    } else if let Some(file) = plant_spec.strip_prefix("model:") {
        Some(sysid::model_file::read_model(Path::new(file))?)
    } else {
        None
    };
    // Building one plant checks the spec and the config before any run.
    let probe = ipa::plant_from_spec(&plant_spec, args.plant_config.as_deref())?;
    let ts_s = probe.ts();
    drop(probe);
    ipa::input::check_samples(args.samples)?;
    check_work(&args, methods.len())?;
    // The runs in flight at once (one per worker thread) each hold a record and its estimation's
    // numbers: bounded before any run (audit s36 H-1: 5 × 10^7 samples aborted on a failed allocation).
    let at_once = rayon::current_num_threads().clamp(1, args.runs.max(1));
    if let Err((need, fit)) =
        sysid::ls::record_budget(args.samples, at_once, args.memory.max_memory)
    {
        anyhow::bail!(sysid::SysidError::Data(format!(
            "montecarlo: {at_once} run(s) at once (one per worker thread) of {} samples each need about \
             {} GB ({} numbers of 8 bytes per sample: the record, its simulation and the estimation's \
             copies), more than the budget of {} GiB ({} GB, --max-memory); use at most {fit} samples \
             (--samples N), or raise --max-memory if this machine has the memory",
            args.samples,
            sysid::ls::format_gb(need),
            super::common::RECORD_NUMBERS_PER_SAMPLE,
            args.memory.max_memory,
            sysid::ls::format_gb(args.memory.max_memory.bytes())
        )));
    }
    // Check the input design (samples, amplitude, file) once, before any run: a bad flag is an error,
    // not a study in which every run failed.
    let design = generate(&spec, args.samples, ts_s, args.amplitude, args.seed)?;
    // A model plant driven beyond its estimation data extrapolates in every run (audit s16 L5; the
    // warning `simulate --plant model:` gives on the same design).
    let extrapolation = plant_spec
        .starts_with("model:")
        .then(|| {
            truth_model
                .as_ref()
                .and_then(|m| sysid_summary::input_outside_data(m, &design))
        })
        .flatten()
        .map(|w| {
            format!(
                "{w}: every run's record is the model's extrapolation, not the plant it was fitted to \
                 (--amplitude sets the design's span)"
            )
        });
    let base = base_identification(&args, truth_model.as_ref());
    let (kind, orders) = (base.structure.kind, base.structure.orders);
    // The truth is comparable only when the estimated structure is the plant model's own.
    let truth = truth_model
        .as_ref()
        .filter(|m| {
            m.kind() == kind
                && m.orders() == orders
                && m.offset().is_some() == base.structure.offset
        })
        .map(truth_of);
    let settings = StudySettings {
        runs: args.runs,
        seed: args.seed,
        noise_std: args.noise_std,
        methods,
        base,
        ts_s,
    };
    let config = args.plant_config.clone();
    let (samples, amplitude) = (args.samples, args.amplitude);
    let spec_run = spec.clone();
    let experiment = move |_run: usize, seed: u64| -> Result<(Vec<f64>, Vec<f64>), String> {
        let u = generate(&spec_run, samples, ts_s, amplitude, seed)
            .map_err(|e| crate::exit::render(&e))?;
        let mut plant = ipa::plant_from_spec(&plant_spec, config.as_deref())
            .map_err(|e| crate::exit::render(&e))?;
        let y = sysid::plant::run_open_loop(plant.as_mut(), &u).map_err(|e| e.to_string())?;
        Ok((u, y))
    };
    let bar = progress_bar(
        args.runs as u64,
        "{bar:40} {pos}/{len} runs {elapsed} elapsed, about {eta} left",
    );
    let mut report = study(&settings, truth.as_deref(), &experiment, &|| bar.inc(1))
        .context("Monte Carlo study")?;
    report.warnings.splice(0..0, extrapolation);
    report.experiment = Some(sysid_studies::montecarlo::StudyExperiment {
        plant: args.plant.clone(),
        input: args.input.clone(),
        amplitude: args.amplitude,
        samples: args.samples,
        ts_s,
        structure: kind.to_string(),
        na: orders.na,
        nb: orders.nb,
        nk: orders.nk,
        offset: settings.base.structure.offset,
    });
    bar.finish_and_clear();
    let header = format!(
        "Plant: {}; input {} ±{} counts, {} samples, Ts = {} s; estimated structure {} na = {} nb = {} nk = {}{}{}\n",
        args.plant,
        args.input,
        args.amplitude,
        args.samples,
        sysid_core::format::Shortest(ts_s),
        kind,
        orders.na,
        orders.nb,
        orders.nk,
        if settings.base.structure.offset { " with offset" } else { "" },
        if truth.is_none() { " (truth unknown or a different structure: spread only)" } else { "" }
    );
    let text = header + &report.to_text();
    let json_to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    super::common::print_report(&text, &[args.json.as_deref()])?;
    // A study in which a method never succeeded has no statistics for it: an error, not a result.
    let failed: Vec<String> = report
        .methods
        .iter()
        .filter(|m| m.ok_runs == 0)
        .map(|m| {
            format!(
                "{} ({})",
                m.method,
                m.first_error.as_deref().unwrap_or("no run")
            )
        })
        .collect();
    if !failed.is_empty() {
        if let Some(path) = &args.json {
            // A failed study does not replace the user's file with a failure report (the table above
            // and the error below say what failed); standard output still gets the JSON.
            if json_to_stdout {
                let json = super::common::report_json(&report, true)? + "\n";
                write_output(path, json.as_bytes(), &inputs, "--json")?;
            } else {
                eprintln!(
                    "{}: not written: the study failed (an existing file is left as it was)",
                    path.display()
                );
            }
        }
        anyhow::bail!(sysid::SysidError::Numerical(format!(
            "every run failed for {}: the study has no estimates for {}",
            failed.join("; "),
            if failed.len() == 1 { "it" } else { "them" }
        )));
    }
    let json = match &args.json {
        Some(_) => Some(super::common::report_json(&report, true)? + "\n"),
        None => None,
    };
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(path), Some(text)) = (&args.json, &json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    // With --strict and warnings, --json is not written (an earlier file stays) and the exit code is 1.
    write_outputs(&outputs, &inputs, args.strict, report.warnings.len())
}

/// The total work runs × samples × methods, bounded before anything runs (10 000 runs of 5 × 10^7
/// samples would take days).
fn check_work(args: &Args, methods: usize) -> anyhow::Result<()> {
    let work = (args.runs as u128) * (args.samples as u128) * (methods as u128);
    if work > u128::from(args.max_work) {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--runs"),
            args.runs,
            &format!(
                "runs x samples x methods ({} x {} x {} = {work}) at most --max-work \
                 {}; fewer runs or samples, or raise --max-work for a study meant to run that long",
                args.runs, args.samples, methods, args.max_work
            )
        ));
    }
    Ok(())
}

/// The estimated structure: the model plant's own (its kind, orders, offset) unless overridden by
/// the flags; the paper's Hammerstein orders for the physics plant. RLS with the given forgetting.
fn base_identification(args: &Args, truth_model: Option<&Model>) -> Identification {
    let (kind, orders, offset) = match truth_model {
        Some(m) => (m.kind(), m.orders(), m.offset().is_some()),
        None => (ModelKind::Hammerstein, Orders::PAPER, false),
    };
    let kind = match args.model {
        Some(k) => k,
        None => kind,
    };
    let orders = Orders {
        na: args.na.unwrap_or(orders.na),
        nb: args.nb.unwrap_or(orders.nb),
        nk: args.nk.unwrap_or(orders.nk),
    };
    Identification {
        structure: sysid::Structure {
            kind,
            orders,
            offset: offset || args.offset,
        },
        inputs: Vec::new(),
        estimator: sysid::EstimatorSettings::Rls(sysid::RecursiveLeastSquares {
            forgetting: args.forgetting,
            ..sysid::RecursiveLeastSquares::default()
        }),
        drop_unexcited_branch: true,
        output: None,
        max_memory: args.memory.max_memory,
        // A study of the estimators' bias and spread looks at their own estimates, never a fallback.
        fallback: false,
        cancel: sysid::Stop::never(),
    }
}
