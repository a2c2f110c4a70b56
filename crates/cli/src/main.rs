//! `ipa-sysid`: the command-line front end. Thin by design: it parses flags, reads and writes files and
//! prints; all logic lives in the library crates `sysid`, `ipa`, `control` and `report`.

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

mod cmd;
mod exit;
mod text;

/// Model, identify, validate and control an Intelligent Pneumatic Actuator (IPA).
#[derive(Debug, Parser)]
#[command(name = "ipa-sysid", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Replace an existing output file even when it holds another kind of file (a model by a CSV, say),
    /// and write through a symbolic link to its file. Without it an existing file is replaced only by the
    /// same kind (a model file by a model file, a CSV by a CSV with the same header row).
    #[arg(long, global = true)]
    force: bool,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Identify a model from a CSV or MAT record of input/output data: ARX, Hammerstein (the paper's),
    /// Wiener / Hammerstein–Wiener, polynomial NARX (MATLAB `arx`, `oe`, `iv4`, `idnlhw`, `nlarx`).
    Identify(cmd::identify::Args),
    /// Metrics of a saved model on new data, with the residual tests (MATLAB `compare`, `resid`).
    #[command(visible_aliases = ["compare", "resid"])]
    Validate(cmd::validate::Args),
    /// Simulate a plant (physics IPA, the paper's model, or a saved model) and write t,u,y to CSV.
    Simulate(cmd::simulate::Args),
    /// Calibrate the physics plant to a measured record (a digital twin, MATLAB `nlgreyest`): writes a
    /// plant-config TOML.
    Calibrate(cmd::calibrate::Args),
    /// Print the physics plant's default parameters as TOML (edit and pass with --plant-config).
    PlantConfig(cmd::plant_config::Args),
    /// Closed-loop PI position control on a plant, with step metrics (MATLAB `stepinfo`).
    Control(cmd::control::Args),
    /// Tune the position controller (PID, deadzone inverse, hold band) on an identified model or a
    /// calibrated twin against a specification; verify it beside the paper's PI; write CONTROLLER.json
    /// (MATLAB `pidtune`).
    #[command(visible_alias = "pidtune")]
    Tune(cmd::tune::Args),
    /// Reproduce the paper end to end: experiment, identification, validation, control, report.
    Reproduce(cmd::reproduce::Args),
    /// Rank model orders and delays by free-run fit on a selection part of the estimation record (never the
    /// test record), with AIC and FPE; the chosen structure is then re-estimated and its test fit printed.
    Order(cmd::order::Args),
    /// Estimate the input delay nk by comparing ARX fits over nk (MATLAB `delayest`).
    Delay(cmd::delay::Args),
    /// Frequency response (Bode), DC gain, poles, zeros, impulse and step response of a model file's
    /// linear block, and a PI loop's gain and phase margins (MATLAB `bode`, `margin`, `impulse`, `step`).
    Response(cmd::response::Args),
    /// Monte Carlo study of estimator bias and spread under output noise (parallel).
    Montecarlo(cmd::montecarlo::Args),
    /// Track a model online: recursive estimation of samples as they arrive (stdin, a growing file, a
    /// serial port), JSON lines, change detection.
    Track(cmd::track::Args),
    /// Benchmarks: RLS throughput, identification time, plant real-time factor.
    Bench(cmd::bench::Args),
}

/// Shown at the end of every `--help`.
const EXIT_CODES: &str = "Exit codes: 0 success; 1 numerical failure (non-finite values, RLS lost positive \
definiteness, unstable simulation); 2 bad usage or bad input (malformed or missing file, flag out of range, \
data that cannot support the estimate). Errors name the file:line:column or the flag, and what was expected. \
See docs/reliability.md.";

/// Negative numbers are values, not flags, in every (nested) subcommand (`--p0 -1` is refused by
/// range, not by the parser), and every `--help` ends with the exit codes.
fn configure(c: clap::Command) -> clap::Command {
    c.allow_negative_numbers(true)
        .after_help(EXIT_CODES)
        .mut_subcommands(configure)
}

/// The ids (field names, e.g. `max_terms`) of the arguments typed on the command line.
fn given_flags(m: &clap::ArgMatches) -> Vec<String> {
    m.ids()
        .filter(|id| m.value_source(id.as_str()) == Some(clap::parser::ValueSource::CommandLine))
        .map(|id| id.as_str().to_string())
        .collect()
}

/// MATLAB names that are not commands here, with the command that does the job (audit s22 L-N4); the
/// names that are (`compare`, `resid`, `pidtune`) are aliases of their commands.
const MATLAB_HINTS: &[(&str, &str)] = &[
    (
        "stepinfo",
        "the step metrics (overshoot, rise and settling time, e_ss) of a closed-loop run are printed by \
         `ipa-sysid control` (e.g. control --plant model:M.json --setpoint 150)",
    ),
    (
        "arx",
        "an ARX model is identified by `ipa-sysid identify --structure arx --na NA --nb NB --nk NK`",
    ),
    (
        "delayest",
        "the input delay nk is estimated by `ipa-sysid delay`",
    ),
    (
        "bode",
        "the frequency response of a model file is printed by `ipa-sysid response`",
    ),
    (
        "idnlhw",
        "a Hammerstein model (input nonlinearity, then ARX) is identified by `ipa-sysid identify \
         --structure hammerstein` (--nonlinearity deadzone|saturation|deadzone-saturation|piecewise-linear|polynomial; \
         --output-nonlinearity KIND adds the output block of a Hammerstein-Wiener model)",
    ),
    (
        "nlarx",
        "a polynomial NARX model is identified by `ipa-sysid identify --structure narx --degree D`",
    ),
    (
        "nlgreyest",
        "the grey-box twin (the physics plant's parameters fitted to a record) is estimated by \
         `ipa-sysid calibrate --data REC.csv --out twin.toml`",
    ),
    (
        "oe",
        "an output-error model is identified by `ipa-sysid identify --method oe` (ARX or Hammerstein \
         structure)",
    ),
    (
        "tfest",
        "transfer-function and state-space estimation are not model classes here: the linear classes are \
         ARX (`ipa-sysid identify --structure arx`, --method ls|rls|iv) and output error (--method oe), \
         whose B/A is the transfer function; `ipa-sysid response` prints its poles and Bode table",
    ),
    (
        "ssest",
        "state-space estimation is not a model class here: the linear classes are ARX (`ipa-sysid \
         identify --structure arx`, --method ls|rls|iv) and output error (--method oe)",
    ),
    (
        "n4sid",
        "subspace (state-space) estimation is not a model class here: the linear classes are ARX (`ipa-sysid \
         identify --structure arx`, --method ls|rls|iv) and output error (--method oe)",
    ),
    (
        "armax",
        "ARMAX (a noise model C(q)) is not a model class here: the linear classes are ARX (`ipa-sysid \
         identify --structure arx`, --method ls|rls) and output error (--method oe); under coloured noise \
         --method iv gives consistent ARX estimates",
    ),
    (
        "bj",
        "Box-Jenkins (noise models C/D) is not a model class here: the linear classes are ARX (`ipa-sysid \
         identify --structure arx`, --method ls|rls|iv) and output error (--method oe), whose B/F is the \
         Box-Jenkins model's input part",
    ),
    (
        "pem",
        "the prediction-error refinement of an ARX or Hammerstein model is `ipa-sysid identify --method \
         oe` (output error, started from least squares and, for a model with an input nonlinearity, \
         from instrumental variables too: the lower end is kept)",
    ),
    (
        "iddata",
        "records are CSV files (a column each for t, u, y: `ipa-sysid identify --data REC.csv --u-col U \
         --y-col Y`) or MATLAB .mat files holding the vectors (from an iddata z: `u = z.InputData; y = \
         z.OutputData; save('rec.mat', 'u', 'y')`, then `--data rec.mat --ts TS`); docs/data.md",
    ),
    (
        "lsim",
        "a model file or plant is simulated on an input by `ipa-sysid simulate --plant model:M.json --input \
         file:U.csv`",
    ),
    (
        "idinput",
        "excitation signals are made by `ipa-sysid simulate --input prbs|aprbs|multisine|staircase` (the \
         record's u column)",
    ),
    (
        "margin",
        "a PI loop's gain and phase margins are printed by `ipa-sysid response --model M.json --kp KP \
         --ki KI` (or --controller C.json)",
    ),
    (
        "impulse",
        "the impulse and step responses of a model file are printed by `ipa-sysid response`",
    ),
    (
        "step",
        "the step response of a model file is printed by `ipa-sysid response`; a closed-loop step by \
         `ipa-sysid control`",
    ),
    (
        "predict",
        "k-step-ahead prediction of a model on a record is `ipa-sysid validate --horizon K`",
    ),
    (
        "sim",
        "a model file or plant is simulated by `ipa-sysid simulate --plant model:M.json --input …`",
    ),
];

/// For an unknown command that is a MATLAB name ([`MATLAB_HINTS`]), the command that does its job.
fn matlab_hint(e: &clap::Error) -> Option<String> {
    if e.kind() != clap::error::ErrorKind::InvalidSubcommand {
        return None;
    }
    let clap::error::ContextValue::String(name) =
        e.get(clap::error::ContextKind::InvalidSubcommand)?
    else {
        return None;
    };
    let (matlab, hint) = MATLAB_HINTS.iter().find(|(m, _)| m == name)?;
    Some(format!(
        "error: `{matlab}` is a MATLAB name, not an ipa-sysid command: {hint}; see ipa-sysid --help"
    ))
}

/// clap's own output (help, version, a usage error) and its exit code; a help text that cannot be
/// written (standard output on a full disk) is an error (exit 2), where `Error::exit` would exit 0. A
/// reader that stopped early (`ipa-sysid --help | head`, a closed pipe) is not an error.
fn clap_exit(e: &clap::Error) -> ExitCode {
    let failed = e
        .print()
        .err()
        .filter(|io| io.kind() != std::io::ErrorKind::BrokenPipe);
    if let Some(io) = failed {
        eprintln!("error: cannot write to standard output: {io}");
        return ExitCode::from(2);
    }
    ExitCode::from(u8::try_from(e.exit_code()).unwrap_or(2))
}

fn main() -> ExitCode {
    let command = Cli::command()
        .after_help(EXIT_CODES)
        .mut_subcommands(configure);
    let parsed = match command
        .try_get_matches()
        .and_then(|m| Cli::from_arg_matches(&m).map(|cli| (cli, m)))
    {
        Ok(parsed) => parsed,
        Err(e) => {
            if let Some(hint) = matlab_hint(&e) {
                eprintln!("{hint}");
                return ExitCode::from(2);
            }
            return clap_exit(&e);
        }
    };
    let (mut cli, matches) = parsed;
    // `identify` and `order` refuse flags their structure, method or classes would ignore: they need
    // to know which were typed (a flag given at its default value counts).
    match (&mut cli.command, matches.subcommand()) {
        (Command::Identify(a), Some((_, m))) => a.given = given_flags(m),
        (Command::Order(a), Some((_, m))) => a.given = given_flags(m),
        // `validate` reads a model file's stored columns only for --u-col / --y-col not typed.
        (Command::Validate(a), Some((_, m))) => a.given = given_flags(m),
        _ => {}
    }
    sysid_io::set_force(cli.force);
    // An interrupted write (Ctrl-C, SIGTERM) leaves no `.ipa-sysid-*.tmp` file behind.
    if let Err(e) = sysid_io::remove_temporaries_on_signals() {
        eprintln!("warning: cannot watch for signals ({e}); an interrupted write may leave a temporary file");
    }
    let result = match cli.command {
        Command::Identify(a) => cmd::identify::run(a),
        Command::Validate(a) => cmd::validate::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::PlantConfig(a) => cmd::plant_config::run(a),
        Command::Calibrate(a) => cmd::calibrate::run(a),
        Command::Control(a) => cmd::control::run(a),
        Command::Tune(a) => cmd::tune::run(a),
        Command::Reproduce(a) => cmd::reproduce::run(a),
        Command::Order(a) => cmd::order::run(a),
        Command::Delay(a) => cmd::delay::run(a),
        Command::Response(a) => cmd::response::run(a),
        Command::Montecarlo(a) => cmd::montecarlo::run(a),
        Command::Track(a) => cmd::track::run(a),
        Command::Bench(a) => cmd::bench::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        // One rule for every command (audit s36 L-2): a reader of standard output that stopped early
        // (`| head`) is not an error, as for clap's help ([`clap_exit`]): the run ends there, quietly,
        // with exit 0. Outputs not yet written then are not written (an earlier file stays).
        Err(e) if reader_stopped(&e) => ExitCode::SUCCESS,
        Err(e) => exit::report(&e),
    }
}

/// Whether `e` is a broken pipe on standard output: a `BrokenPipe` error in its chain while standard
/// output's reader is gone ([`sysid_io::stdout_reader_gone`]). A FIFO output whose reader closed
/// stays an error (standard output is then still read).
fn reader_stopped(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
    }) && sysid_io::stdout_reader_gone()
}
