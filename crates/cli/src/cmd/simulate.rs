//! `ipa-sysid simulate`: runs a plant (physics IPA, the paper's model or a saved model) on a designed
//! input and writes the record `t,u,y` (plus the chamber pressures for the physics plant) as CSV.
//! `--fleet N` simulates a fleet of physics IPAs instead, some with wearing valves (`ipa::fleet`), and
//! writes a folder of Parquet files (module `simulate_fleet`).

use std::path::{Path, PathBuf};
use sysid_core::format::Shortest;

use ipa::{Experiment, Record};

/// Flags of `simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Plant: `ipa` (physics simulator), `paper` (the paper's Hammerstein model) or `model:FILE` (a model
    /// with several inputs runs on --input file:CSV and writes t, its inputs, y).
    #[arg(long, default_value = "ipa")]
    pub plant: String,
    /// TOML file overriding the physics plant's parameters (see `ipa-sysid plant-config`).
    #[arg(long, value_name = "FILE")]
    pub plant_config: Option<PathBuf>,
    /// Input: staircase, prbs, aprbs, multisine, step:LEVEL[@SAMPLE] or file:CSV (column u; for a model
    /// with several inputs, one column per input named as in the model).
    #[arg(long, default_value = "staircase")]
    pub input: String,
    /// Amplitude A of the random inputs, PWM counts.
    #[arg(long, default_value_t = 255.0)]
    pub amplitude: f64,
    /// Number of samples N (default 2000, or the length of a file: input).
    #[arg(long)]
    pub samples: Option<usize>,
    /// Sampling period Ts in s (default 0.01; a model plant uses its own Ts).
    #[arg(long)]
    pub ts: Option<f64>,
    /// Initial output y0 in mm (the plant starts at rest there; `--x0` is an older spelling). Default:
    /// 100 mm (mid-stroke) for `ipa`, `paper` and models without a resting level (an integrator or
    /// near-integrator such as an identified IPA position model, an unstable or NARX model); a stable model starts at its own resting level
    /// with the inputs at the operating point, so its record shows the response to the input and no
    /// decay from an arbitrary start. The IPA's mid-stroke differs from `control`'s 0 on purpose: an
    /// open-loop experiment must be able to move both ways, the paper's closed-loop test starts from the
    /// end of the stroke.
    #[arg(long = "y0", alias = "x0")]
    pub y0: Option<f64>,
    /// Seed of the random input and noise (the same seed gives a byte-identical file).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Standard deviation of white Gaussian noise added to y, mm.
    #[arg(long, default_value_t = 0.0)]
    pub noise_std: f64,
    /// Output CSV file (with --fleet: the output folder).
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Simulate a fleet of N physics IPAs drawn around the defaults instead (docs/fleet.md): --out is then
    /// a folder of Parquet files of long-format records (actuator_id, t, u, y) and truth.csv.
    #[arg(long, value_name = "N")]
    pub fleet: Option<usize>,
    /// With --fleet: the fraction of actuators whose valves wear (deadzone widening, slopes dropping).
    #[arg(long, value_name = "FRACTION", requires = "fleet", default_value_t = ipa::fleet::FleetDesign::default().worn_fraction)]
    pub worn: f64,
    /// With --fleet: monitoring windows per actuator (one staircase experiment of --samples each).
    #[arg(long, value_name = "W", requires = "fleet", default_value_t = ipa::fleet::FleetDesign::default().windows)]
    pub windows: usize,
    /// With --fleet: actuators per Parquet file (a partition holds whole actuators).
    #[arg(long, value_name = "K", requires = "fleet", default_value_t = 50)]
    pub per_file: usize,
    /// With --fleet: replace an existing --out folder written by an earlier --fleet run (refused
    /// otherwise, and always for a folder that holds anything else).
    #[arg(long, requires = "fleet")]
    pub overwrite: bool,
    /// Write what was simulated as JSON here (`-` for standard output): plant, input, samples, Ts, y0,
    /// the columns written, the output's range and the run's `warnings` (not with --fleet).
    #[arg(long, value_name = "OUT", conflicts_with = "fleet")]
    pub json: Option<PathBuf>,
    /// Exit with code 1 when the run carries warnings (they are printed either way), without writing
    /// --out or --json (an earlier file there is kept; not with --fleet).
    #[arg(long, conflicts_with = "fleet")]
    pub strict: bool,
    /// With --plant model:FILE: a record of N samples needs N × 16 × 8 bytes (the record, the
    /// simulation and their copies; `validate`'s budget), refused beyond it before it is simulated.
    #[command(flatten)]
    pub memory: super::common::MemoryArgs,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.fleet.is_some() {
        return super::simulate_fleet::run(&args);
    }
    let plant: ipa::spec::PlantSpec = args.plant.parse()?;
    let mut warnings = Warnings::default();
    if let ipa::spec::PlantSpec::ModelFile(path) = &plant {
        let model = match sysid::model_file::read_any_model(path)? {
            sysid::model_file::AnyModel::Linear(m) => m,
            sysid::model_file::AnyModel::Narx(m) => {
                check_time_span(
                    args.samples.unwrap_or(ipa::experiment::DEFAULT_SAMPLES),
                    m.ts(),
                )?;
                let p = m.parameter_count();
                return run_plant(&args, plant, None, (m.data_range(), Some(p)), warnings);
            }
        };
        // What validate would say of this model, said before it is simulated.
        for w in sysid_summary::simulation::model_file_warnings(&model) {
            warnings.say(format!("{}: {w}", path.display()));
        }
        check_time_span(
            args.samples.unwrap_or(ipa::experiment::DEFAULT_SAMPLES),
            model.ts(),
        )?;
        if model.inputs().len() > 1 {
            return run_miso(&args, &model, path, warnings);
        }
        let p = model.parameter_count();
        return run_plant(&args, plant, Some(&model), (None, Some(p)), warnings);
    }
    run_plant(&args, plant, None, (None, None), warnings)
}

/// The warnings of one run, kept for `--json` and `--strict`: those found before the simulation are
/// printed on standard error when found (`warning: …`, [`Warnings::say`]), those about the record after
/// the line that says what was written (pushed to `all`, printed by [`finish`]).
#[derive(Debug, Default)]
struct Warnings {
    all: Vec<String>,
    printed: usize,
}

impl Warnings {
    /// Prints `w` now and keeps it.
    fn say(&mut self, w: String) {
        eprintln!("warning: {w}");
        self.all.push(w);
        self.printed = self.all.len();
    }
}

/// The `simulate --json` document: what was simulated and the run's warnings.
#[derive(Debug, serde::Serialize)]
struct SimulateReport<'a> {
    /// `--plant` as given (`ipa`, `paper`, `model:FILE`).
    plant: &'a str,
    /// `--input` as given.
    input: &'a str,
    /// The CSV file of the record (`--out`).
    out: String,
    /// Its header.
    columns: Vec<String>,
    /// Number of samples N.
    samples: usize,
    /// Sampling period Ts in s.
    ts: f64,
    /// The level y0 held before the start (the plant's output units: mm for `ipa` and `paper`).
    y0: f64,
    /// Seed of the random input and noise (`--seed`).
    seed: u64,
    /// Smallest and largest simulated output [min, max] (null for an empty record).
    y_range: Option<[f64; 2]>,
    /// Everything printed as `warning:` (always present; empty when all is well).
    warnings: &'a [String],
}

/// A simulated record ready to be written: the CSV bytes of `--out`, its header, and the sentence
/// `wrote …` says of it (without the verb and the path).
struct Written<'a> {
    csv: Vec<u8>,
    columns: Vec<&'a str>,
    samples: usize,
    ts: f64,
    y0: f64,
    y: &'a [f64],
    words: String,
}

/// Writes `--out` and `--json` together (with `--strict` and warnings neither: exit 1, an earlier file
/// stays), then says what was written and prints the warnings not printed yet.
fn finish(
    args: &Args,
    inputs: &[&Path],
    rec: Written<'_>,
    warnings: Warnings,
) -> anyhow::Result<()> {
    let (lo, hi) = sysid_core::DataRange::extremes(rec.y);
    let report = SimulateReport {
        plant: &args.plant,
        input: &args.input,
        out: args.out.display().to_string(),
        columns: rec.columns.iter().map(|c| c.to_string()).collect(),
        samples: rec.samples,
        ts: rec.ts,
        y0: rec.y0,
        seed: args.seed,
        y_range: (!rec.y.is_empty()).then_some([lo, hi]),
        warnings: &warnings.all,
    };
    let json = match &args.json {
        Some(_) => Some(super::common::report_json(&report, true)? + "\n"),
        None => None,
    };
    let mut outputs: Vec<(&Path, &[u8], &str)> = vec![(&args.out, &rec.csv, "--out")];
    if let (Some(path), Some(text)) = (&args.json, &json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    let written = super::common::write_outputs(&outputs, inputs, args.strict, warnings.all.len());
    let refused = match &written {
        Ok(()) => false,
        Err(e) if e.downcast_ref::<crate::exit::StrictWarnings>().is_some() => true,
        Err(_) => return written,
    };
    if refused {
        eprintln!("simulated {}", rec.words);
    } else {
        eprintln!("wrote {}, to {}", rec.words, args.out.display());
    }
    for w in &warnings.all[warnings.printed..] {
        eprintln!("warning: {w}");
    }
    written
}

/// How the record starts, in words: the level held before the start and, for a model, what its
/// output does from there (its resting level when it has one and it differs; that a model without one
/// may drift; the output of a model with an output nonlinearity, whose linear part holds the level).
fn start_words(
    y0: f64,
    y_first: Option<f64>,
    model: Option<&sysid::Model>,
    chosen: bool,
) -> String {
    let Some(m) = model else {
        return format!("from rest at y0 = {y0}");
    };
    let mut s = if m.output_nonlinearity().is_some() {
        format!(
            "with the linear part held at {y0} before the start (the output nonlinearity makes \
             y(0) = {})",
            y_first.map_or("n/a".to_string(), |y| y.to_string())
        )
    } else {
        format!("from y0 = {y0} held before the start")
    };
    match m.rest_state() {
        Some(rest) if (rest - y0).abs() > 1e-9 * rest.abs().max(1.0) => s += &format!(
            "; the model rests at {rest} with the input at its operating point, so it moves towards \
             that level"
        ),
        Some(_) => s += ", the model's resting level",
        None if chosen => s += " (mid-stroke: the model has no resting level to start from, so its \
             output may drift before the input moves)",
        None => {}
    }
    s
}

/// Runs the plant of `--plant` (`model`: the model file it names, already read) on the designed
/// input and writes the record; `warnings` are those found before (the model file's). `model_file`:
/// a NARX model file's data range, and the parameter count of any model file (linear or NARX), whose
/// run is held to the record budget of `--max-memory`.
fn run_plant(
    args: &Args,
    plant: ipa::spec::PlantSpec,
    model: Option<&sysid::Model>,
    model_file: (Option<&sysid::DataRange>, Option<usize>),
    mut warnings: Warnings,
) -> anyhow::Result<()> {
    let (narx_range, model_params) = model_file;
    // A file input is read once, its commands with the Ts of its time column.
    let input = args.input.parse::<ipa::InputSpec>()?.load()?;
    // The commands of a file with a time column keep their recorded spacing: its Ts is the physics
    // plant's unless --ts says otherwise (a model plant runs at its own Ts); a Ts that differs is
    // said below (audit s16 L14: a 0.02 s command record replayed at 0.01 s without a word).
    let file_ts = input.file_ts();
    let ts = match (args.ts, file_ts, &plant) {
        (None, Some(f), ipa::spec::PlantSpec::Ipa) => Some(f),
        _ => args.ts,
    };
    let paper = matches!(plant, ipa::spec::PlantSpec::Paper);
    let physics = matches!(plant, ipa::spec::PlantSpec::Ipa);
    let exp = Experiment {
        plant,
        plant_config: args.plant_config.clone(),
        input,
        amplitude: args.amplitude,
        samples: args.samples,
        ts,
        x0: args.y0,
        seed: args.seed,
        noise_std: args.noise_std,
        // The command line's SIGINT ends the process.
        cancel: sysid_core::Stop::never(),
    };
    exp.check()?;
    // A model's run over N samples, bounded as `validate` bounds it, before anything is simulated
    // (session 26: a NARX model on a long `--input file:` had no budget).
    // The physics plants too (audit s36 H-1: 5 × 10^7 samples, an accepted --samples, took about
    // 4.6 GB and aborted on a failed allocation under a smaller memory limit).
    let (what, p) = match (model_params, &exp.plant) {
        (Some(p), ipa::spec::PlantSpec::ModelFile(path)) => {
            (format!("simulate --plant model:{}", path.display()), p)
        }
        _ => (format!("simulate --plant {}", args.plant), 0),
    };
    super::common::check_record_memory(
        what,
        exp.sample_count()?,
        p,
        args.memory.max_memory,
        "--samples N, or a part of the --input file",
    )?;
    // The start, resolved once (a model file is read for it) and passed on.
    let y0 = match exp.x0 {
        Some(v) => v,
        None => exp.plant.default_y0()?,
    };
    let exp = Experiment {
        x0: Some(y0),
        ..exp
    };
    let mut inputs: Vec<&Path> =
        ipa::spec::spec_input_files(&args.plant, args.plant_config.as_deref());
    if let Some(f) = exp.input.file() {
        inputs.push(f);
    }
    check_outputs(&args.out, args.json.as_ref(), &inputs)?;
    let rec = exp.run()?;
    let paper_model = matches!(exp.plant, ipa::spec::PlantSpec::Paper).then(sysid::Model::paper);
    let (csv, columns) = record_csv(&args.out, &rec)?;
    let file_words = match (file_ts, exp.input.file()) {
        (Some(f), Some(path)) if (f - rec.ts).abs() <= 1e-3 * f => {
            format!(", the time column t of {}", path.display())
        }
        _ => String::new(),
    };
    let words = format!(
        "{} samples (Ts = {} s{file_words}), {}",
        rec.u.len(),
        Shortest(rec.ts),
        // The paper's plant is a model too: its leak (a pole at 0.9992) moves y from y0 towards its
        // resting level, which "from rest" hid (audit s34 H-1: a record starting at 100 mm decays to
        // 48 mm over 20 s at ±8 counts).
        start_words(
            y0,
            rec.y.first().copied(),
            model.or(paper_model.as_ref()),
            args.y0.is_none()
        ),
    );
    // What holds the physics plant's piston when the run never moved.
    let hold = if physics {
        let cfg = match args.plant_config.as_deref() {
            Some(path) => ipa::PlantConfig::from_toml_file(path)?,
            None => ipa::PlantConfig::default(),
        };
        sysid_summary::simulation::PhysicsHold::of_run(&cfg, &rec.u, &rec.y, y0)
    } else {
        None
    };
    let run = sysid_summary::simulation::OpenLoopRun {
        model,
        narx_range,
        physics,
        hold,
        paper_stroke_mm: paper.then(|| ipa::PlantConfig::default().cylinder.stroke_mm),
        y0,
        y0_default: args.y0.is_none(),
        input_file: exp.input.file().map(|p| (p, file_ts)),
        ts_setting: args.ts,
    };
    warnings
        .all
        .extend(sysid_summary::simulation::record_warnings(
            &run, &rec.u, &rec.y, rec.ts,
        ));
    let written = Written {
        csv,
        columns,
        samples: rec.u.len(),
        ts: rec.ts,
        y0,
        y: &rec.y,
        words,
    };
    finish(args, &inputs, written, warnings)
}

/// Checks before the simulation that `--out` and `--json` can be written and name none of `inputs`
/// ([`super::common::check_outputs`]).
fn check_outputs(out: &Path, json: Option<&PathBuf>, inputs: &[&Path]) -> anyhow::Result<()> {
    super::common::check_outputs(
        &[
            (&Some(out.to_path_buf()), "--out"),
            (&json.cloned(), "--json"),
        ],
        inputs,
    )
}

/// Refuses a record whose last sample time (N - 1) Ts is not a finite number of seconds (a model with
/// Ts = 1.7e308 would write t = inf).
fn check_time_span(samples: usize, ts: f64) -> anyhow::Result<()> {
    let span = samples.saturating_sub(1) as f64 * ts;
    if !span.is_finite() {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Ts,
            ts,
            &format!(
                "a sampling period whose {samples} samples span a finite time (the last would be at t = \
                 {span} s)"
            )
        ));
    }
    Ok(())
}

/// The record as CSV (t, u, y in Rust's shortest round-trip decimals; pressures, when simulated, to
/// 0.1 Pa) and its header; `out` names the file in messages.
fn record_csv(out: &Path, rec: &Record) -> anyhow::Result<(Vec<u8>, Vec<&'static str>)> {
    use sysid_io::NumberFormat::{OneDecimal, Shortest};
    check_time_span(rec.u.len(), rec.ts)?;
    let times = sysid::data::sample_times(rec.u.len(), rec.ts);
    let mut header = vec!["t", "u", "y"];
    let mut columns: Vec<(&[f64], sysid_io::NumberFormat)> =
        vec![(&times, Shortest), (&rec.u, Shortest), (&rec.y, Shortest)];
    let pressures: Option<[Vec<f64>; 2]> = rec
        .pressures
        .as_ref()
        .map(|p| [0, 1].map(|i| p.iter().map(|pk| pk[i]).collect()));
    if let Some([pa, pb]) = &pressures {
        header.extend(["p_a_pa", "p_b_pa"]);
        columns.extend([(pa.as_slice(), OneDecimal), (pb.as_slice(), OneDecimal)]);
    }
    let csv = sysid_io::formatted_columns_csv(out, &header, &columns)?;
    Ok((csv, header))
}

/// Runs a model with several inputs open loop on recorded commands (`--input file:CSV` with one column per
/// model input, named as in the model) from rest at `--y0`, and writes `t,<inputs>,y`.
fn run_miso(
    args: &Args,
    model: &sysid::Model,
    model_path: &Path,
    mut warnings: Warnings,
) -> anyhow::Result<()> {
    let names: Vec<&str> = model.inputs().iter().map(|i| i.name()).collect();
    let input: ipa::InputSpec = args.input.parse()?;
    let Some(file) = input.file() else {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--input"),
            &args.input,
            &format!(
                "file:CSV with one column per model input ({}): a model with several inputs is simulated on \
                 recorded commands",
                names.join(", ")
            )
        ));
    };
    let refused = [
        (args.noise_std != 0.0, "--noise-std"),
        (args.plant_config.is_some(), "--plant-config"),
        (args.samples.is_some(), "--samples"),
    ];
    if let Some((_, flag)) = refused.iter().find(|(on, _)| *on) {
        anyhow::bail!(
            "{flag} is not available with a several-input model: it runs the commands of --input file:CSV \
             as they are, without noise"
        );
    }
    if let Some(ts) = args.ts {
        if (ts - model.ts()).abs() > 1e-9 * model.ts() {
            anyhow::bail!(sysid::SysidError::setting(
                sysid::Setting::Other("--ts"),
                ts,
                &format!("the model's own Ts ({} s), or no --ts", model.ts())
            ));
        }
    }
    let inputs: Vec<&Path> = vec![model_path, file];
    check_outputs(&args.out, args.json.as_ref(), &inputs)?;
    let u = ipa::input::read_input_columns(file, &names)?;
    let us: Vec<&[f64]> = u.iter().map(Vec::as_slice).collect();
    let y0 = match args.y0 {
        Some(v) if !v.is_finite() => anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--y0"),
            v,
            "a finite output level"
        )),
        Some(v) => v,
        None => ipa::spec::model_default_y0(model),
    };
    let y = sysid::model::run_from_rest(model, &us, y0)?;
    let mut header = vec!["t"];
    header.extend(&names);
    header.push("y");
    check_time_span(y.len(), model.ts())?;
    let times = sysid::data::sample_times(y.len(), model.ts());
    let rows = times.iter().enumerate().map(|(k, t)| {
        let mut row = vec![t.to_string()];
        row.extend(u.iter().map(|c| c[k].to_string()));
        row.push(y[k].to_string());
        row
    });
    let csv = sysid_io::csv_bytes(&args.out, &header, rows)?;
    let words = format!(
        "{} samples (Ts = {} s) of the {}-input model, {}",
        y.len(),
        Shortest(model.ts()),
        names.len(),
        start_words(y0, y.first().copied(), Some(model), args.y0.is_none()),
    );
    warnings
        .all
        .extend(sysid_summary::simulation::rest_outside_data(
            model,
            y0,
            args.y0.is_none(),
        ));
    let written = Written {
        csv,
        columns: header,
        samples: y.len(),
        ts: model.ts(),
        y0,
        y: &y,
        words,
    };
    finish(args, &inputs, written, warnings)
}
