//! `ipa-sysid simulate`: runs a plant (physics IPA, the paper's model or a saved model) on a designed
//! input and writes the record `t,u,y` (plus the chamber pressures for the physics plant) as CSV.

use std::path::{Path, PathBuf};

use anyhow::Context;
use ipa::input::{staircase_experiment, InputSpec, StaircaseDesign};
use ipa::{Ipa, PlantConfig};
use sysid::Plant;

/// Flags of `simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Plant: `ipa` (physics simulator), `paper` (the paper's Hammerstein model) or `model:FILE`.
    #[arg(long, default_value = "ipa")]
    pub plant: String,
    /// TOML file overriding the physics plant's parameters (see `ipa-sysid plant-config`).
    #[arg(long, value_name = "FILE")]
    pub plant_config: Option<PathBuf>,
    /// Input: staircase, prbs, aprbs, multisine, step:LEVEL[@SAMPLE] or file:CSV (column u).
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
    /// Initial position y0 in mm (the piston starts at rest there; `--x0` is an older spelling).
    #[arg(long = "y0", alias = "x0", default_value_t = 100.0)]
    pub y0: f64,
    /// Seed of the random input and noise (the same seed gives a byte-identical file).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Standard deviation of white Gaussian noise added to y, mm.
    #[arg(long, default_value_t = 0.0)]
    pub noise_std: f64,
    /// Output CSV file.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

/// The simulated record.
struct Record {
    u: Vec<f64>,
    y: Vec<f64>,
    pressures: Option<Vec<[f64; 2]>>,
    ts: f64,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let spec: InputSpec = args.input.parse()?;
    if !args.y0.is_finite() {
        return Err(sysid::SysidError::setting(
            sysid::Setting::Other("--y0"),
            args.y0,
            "a finite position in mm",
        )
        .into());
    }
    if !(args.noise_std.is_finite() && args.noise_std >= 0.0) {
        return Err(sysid::SysidError::setting(
            sysid::Setting::Other("--noise-std"),
            args.noise_std,
            "a standard deviation >= 0 in mm",
        )
        .into());
    }
    let mut inputs: Vec<&Path> =
        ipa::spec::spec_input_files(&args.plant, args.plant_config.as_deref());
    if let Some(f) = spec.file() {
        inputs.push(f);
    }
    sysid_io::check_writable(&args.out, "--out")?;
    sysid_io::refuse_overwrite_input(&args.out, &inputs, "--out")?;
    let samples = match (args.samples, spec.file()) {
        (Some(n), _) => n,
        (None, Some(f)) => ipa::input::read_input_file(f)?.len(),
        (None, None) => 2000,
    };
    let rec = if args.plant.trim() == "ipa" {
        let cfg = match &args.plant_config {
            Some(p) => PlantConfig::from_toml_file(p)?,
            None => PlantConfig::default(),
        };
        let mut plant = Ipa::with_ts(cfg, args.ts.unwrap_or(ipa::DEFAULT_TS_S))?;
        plant.reset(args.y0);
        let u = match spec {
            InputSpec::Staircase => {
                // The experimenter's rule watches the plant: design on a copy, then record.
                let mut copy = plant.clone();
                staircase_experiment(
                    &mut copy,
                    &StaircaseDesign::default(),
                    samples,
                    args.amplitude,
                    args.seed,
                )?
                .0
            }
            _ => ipa::generate(&spec, samples, plant.ts(), args.amplitude, args.seed)?,
        };
        let mut y = Vec::with_capacity(u.len());
        let mut p = Vec::with_capacity(u.len());
        for (k, &uk) in u.iter().enumerate() {
            y.push(plant.output());
            p.push(plant.pressures_pa());
            plant
                .step(uk)
                .with_context(|| format!("simulating sample {k}"))?;
        }
        Record {
            u,
            y,
            pressures: Some(p),
            ts: plant.ts(),
        }
    } else {
        let mut plant =
            ipa::plant_from_spec_with_ts(&args.plant, args.plant_config.as_deref(), args.ts)?;
        plant.reset(args.y0);
        let ts = plant.ts();
        let (u, y) = match spec {
            InputSpec::Staircase => staircase_experiment(
                plant.as_mut(),
                &StaircaseDesign::default(),
                samples,
                args.amplitude,
                args.seed,
            )?,
            _ => {
                let u = ipa::generate(&spec, samples, ts, args.amplitude, args.seed)?;
                let y = sysid::plant::run_open_loop(plant.as_mut(), &u)?;
                (u, y)
            }
        };
        Record {
            u,
            y,
            pressures: None,
            ts,
        }
    };
    let y = ipa::input::add_noise(&rec.y, args.noise_std, args.seed);
    write_csv(&args.out, &rec, &y)?;
    eprintln!(
        "wrote {} samples (Ts = {} s) to {}",
        rec.u.len(),
        rec.ts,
        args.out.display()
    );
    Ok(())
}

/// Writes the record as CSV (t, u, y in Rust's shortest round-trip decimals; pressures, when simulated,
/// to 0.1 Pa).
fn write_csv(out: &Path, rec: &Record, y: &[f64]) -> anyhow::Result<()> {
    let header: &[&str] = if rec.pressures.is_some() {
        &["t", "u", "y", "p_a_pa", "p_b_pa"]
    } else {
        &["t", "u", "y"]
    };
    let times = sysid::data::sample_times(rec.u.len(), rec.ts);
    let rows = times.iter().enumerate().map(|(k, t)| {
        let mut row = vec![t.to_string(), rec.u[k].to_string(), y[k].to_string()];
        if let Some(p) = &rec.pressures {
            row.extend([format!("{:.1}", p[k][0]), format!("{:.1}", p[k][1])]);
        }
        row
    });
    Ok(sysid_io::write_csv(out, header, rows)?)
}
