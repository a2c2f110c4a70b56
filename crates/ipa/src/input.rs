//! Input design: the command sequences u(k) (PWM counts) of identification experiments.
//!
//! [`InputSpec`] is parsed from the `--input` flag and [`generate`] turns it into N samples,
//! deterministically for a given seed (ChaCha8 random numbers).
//!
//! | spec          | signal |
//! |---------------|--------|
//! | `staircase`   | the paper's "continuous step signal": random integer levels in [-A, A] held 0.1..0.5 s, with the sign chosen by an experimenter's rule that keeps the piston inside the stroke (see [`staircase`]) |
//! | `calibration` | full, medium, small (5..60 counts, around the deadzone) and zero commands for calibrating the physics plant, kept inside the stroke by the staircase's rule (see [`calibration_experiment_observed`]) |
//! | `prbs`        | maximum-length PRBS (10-bit LFSR), levels +-A, clock 50 ms |
//! | `aprbs`       | amplitude-modulated PRBS: a new level uniform in [-A, A] at every switch of the PRBS |
//! | `multisine`   | sum of sines at the record's harmonics between 1 and 10 Hz, random phases, peak A |
//! | `step:LEVEL`  | 0 for the first 10 samples, then LEVEL (`step:LEVEL@K` starts at sample K) |
//! | `file:CSV`    | column `u` of a CSV file with a header row |

use std::path::{Path, PathBuf};
use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

use crate::{IpaError, IpaSetting};

/// An experiment's input signal, as given to `--input`.
#[derive(Debug, Clone, PartialEq)]
pub enum InputSpec {
    /// Random levels held for random durations, kept inside the stroke by an experimenter's rule.
    Staircase,
    /// The calibration design: full, medium, small (near the deadzone) and zero commands, kept inside
    /// the stroke by the staircase's rule ([`calibration_experiment_observed`]).
    Calibration,
    /// Maximum-length pseudo-random binary sequence, levels +-A.
    Prbs,
    /// Amplitude-modulated PRBS, levels uniform in [-A, A].
    Aprbs,
    /// Multisine with random phases, peak amplitude A.
    Multisine,
    /// u = 0 before sample `onset`, then u = `level` (counts); the amplitude is not used.
    Step {
        /// The step's level in counts.
        level: f64,
        /// First sample at the level.
        onset: usize,
    },
    /// Column `u` of a CSV file; the amplitude is not used.
    File(PathBuf),
    /// A `file:CSV` input once read ([`InputSpec::load`]): its column `u` and the Ts of its time column.
    Commands(CommandFile),
}

/// The commands of a CSV file, read once: the columns asked for and Ts (s) of its time column `t`
/// when it has one (by the reader's rule, [`sysid_core::data::uniform_time`]).
#[derive(Debug, Clone, PartialEq)]
pub struct CommandFile {
    /// The file, for messages and to refuse overwriting it.
    pub path: PathBuf,
    /// The columns asked for, in the order asked (commands, counts).
    pub columns: Vec<Vec<f64>>,
    /// Ts (s) from the time column `t`; `None` without one.
    pub ts: Option<f64>,
}

/// Sample at which `step:LEVEL` steps when no `@K` is given.
pub const DEFAULT_STEP_ONSET: usize = 10;

const SPEC_HELP: &str =
    "staircase, calibration, prbs, aprbs, multisine, step:LEVEL[@SAMPLE] or file:CSV";

impl FromStr for InputSpec {
    type Err = IpaError;

    fn from_str(s: &str) -> Result<Self, IpaError> {
        let bad = |why: &str| {
            IpaError::setting(
                IpaSetting::Input,
                format!("'{s}'"),
                format!("{why}; expected {SPEC_HELP}"),
            )
        };
        let t = s.trim();
        match t {
            "staircase" => return Ok(InputSpec::Staircase),
            "prbs" => return Ok(InputSpec::Prbs),
            "calibration" => return Ok(InputSpec::Calibration),
            "aprbs" => return Ok(InputSpec::Aprbs),
            "multisine" => return Ok(InputSpec::Multisine),
            _ => {}
        }
        if let Some(rest) = t.strip_prefix("step:") {
            let (lv, onset) = match rest.split_once('@') {
                Some((lv, k)) => {
                    let k = k
                        .trim()
                        .parse::<usize>()
                        .map_err(|_| bad("the step onset after '@' must be a sample index"))?;
                    (lv, k)
                }
                None => (rest, DEFAULT_STEP_ONSET),
            };
            let level: f64 = lv
                .trim()
                .parse()
                .map_err(|_| bad("the step level must be a number of counts"))?;
            if !level.is_finite() {
                return Err(bad("the step level must be finite"));
            }
            return Ok(InputSpec::Step { level, onset });
        }
        if let Some(rest) = t.strip_prefix("file:") {
            if rest.is_empty() {
                return Err(bad("no file name after 'file:'"));
            }
            return Ok(InputSpec::File(PathBuf::from(rest)));
        }
        Err(bad("unknown input"))
    }
}

impl std::fmt::Display for InputSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            InputSpec::Staircase => f.write_str("staircase"),
            InputSpec::Prbs => f.write_str("prbs"),
            InputSpec::Calibration => f.write_str("calibration"),
            InputSpec::Aprbs => f.write_str("aprbs"),
            InputSpec::Multisine => f.write_str("multisine"),
            InputSpec::Step { level, onset } => write!(f, "step:{level}@{onset}"),
            InputSpec::File(p) => write!(f, "file:{}", p.display()),
            InputSpec::Commands(c) => write!(f, "file:{}", c.path.display()),
        }
    }
}

impl InputSpec {
    /// The input file, for `file:CSV` (so that callers can refuse to overwrite it).
    pub fn file(&self) -> Option<&Path> {
        match self {
            InputSpec::File(p) => Some(p),
            InputSpec::Commands(c) => Some(&c.path),
            _ => None,
        }
    }

    /// The input with a `file:CSV` read once ([`read_command_file`]: column `u` and the Ts of its time
    /// column), so that neither its Ts nor its commands make the file be read again; any other input
    /// unchanged.
    pub fn load(self) -> Result<Self, IpaError> {
        match self {
            InputSpec::File(path) => Ok(InputSpec::Commands(read_command_file(&path, &["u"])?)),
            other => Ok(other),
        }
    }

    /// Ts (s) of the time column of a loaded `file:CSV` input ([`InputSpec::load`]); `None` for any
    /// other input, or a file without a time column.
    pub fn file_ts(&self) -> Option<f64> {
        match self {
            InputSpec::Commands(c) => c.ts,
            _ => None,
        }
    }

    /// The commands of a `file:CSV` input: those loaded, or read now (column `u`).
    pub(crate) fn file_commands(&self) -> Result<Option<std::borrow::Cow<'_, [f64]>>, IpaError> {
        Ok(match self {
            InputSpec::File(path) => Some(std::borrow::Cow::Owned(read_input_file(path)?)),
            InputSpec::Commands(c) => Some(std::borrow::Cow::Borrowed(
                c.columns.first().map_or(&[][..], Vec::as_slice),
            )),
            _ => None,
        })
    }
}

/// Generates `samples` commands u(0..N-1) in counts for `spec`, sampled every `ts_s` seconds, with
/// amplitude `amplitude` (counts, used by the random signals). The same seed gives the same sequence.
///
/// ```
/// use ipa::input::{generate, InputSpec};
/// let u = generate(&"step:100".parse().unwrap(), 20, 0.01, 255.0, 0).unwrap();
/// assert_eq!(u[9], 0.0);
/// assert_eq!(u[10], 100.0);
/// ```
pub fn generate(
    spec: &InputSpec,
    samples: usize,
    ts_s: f64,
    amplitude: f64,
    seed: u64,
) -> Result<Vec<f64>, IpaError> {
    check_settings(samples, ts_s, amplitude)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    Ok(match spec {
        InputSpec::Staircase => staircase(samples, ts_s, amplitude, seed)?,
        InputSpec::Calibration => {
            let mut nominal = crate::Ipa::with_ts(crate::PlantConfig::default(), ts_s)?;
            sysid_core::Plant::reset(&mut nominal, 0.5 * StaircaseDesign::default().stroke_mm);
            calibration_experiment_observed(&mut nominal, samples, amplitude, seed, |_| ())?.0
        }
        InputSpec::Prbs => prbs(samples, clock_samples(ts_s), seed)
            .into_iter()
            .map(|b| if b { amplitude } else { -amplitude })
            .collect(),
        InputSpec::Aprbs => aprbs(samples, ts_s, amplitude, seed, &mut rng),
        InputSpec::Multisine => multisine(samples, ts_s, amplitude, &mut rng)?,
        InputSpec::Step { level, onset } => {
            if *onset >= samples && *level != 0.0 {
                // The record would hold no step at all (audit s11). An onset left out is the default,
                // said as such, not echoed as if typed (audit s30 L-2).
                let (typed, default) = if *onset == DEFAULT_STEP_ONSET {
                    (
                        format!("step:{level}"),
                        format!(
                            " (the onset when no @K is given: step:{level}@K puts it at sample K)"
                        ),
                    )
                } else {
                    (format!("step:{level}@{onset}"), String::new())
                };
                return Err(IpaError::Config(format!(
                    "--input {typed}: the step comes at sample {onset}{default}, after the record's last \
                     sample ({samples} samples, 0..{last}); give an onset K from 0 to {last} \
                     (step:{level}@K) or more than {onset} --samples",
                    last = samples.saturating_sub(1)
                )));
            }
            (0..samples)
                .map(|k| if k >= *onset { *level } else { 0.0 })
                .collect()
        }
        InputSpec::File(path) | InputSpec::Commands(CommandFile { path, .. }) => {
            let u = spec.file_commands()?.unwrap_or_default();
            if u.len() < samples {
                return Err(IpaError::Config(format!(
                    "{}: has {} samples of u but {samples} were asked for (--samples)",
                    path.display(),
                    u.len()
                )));
            }
            u[..samples].to_vec()
        }
    })
}

/// y + white Gaussian measurement noise of standard deviation `std_mm` (`rand_distr::StandardNormal`
/// on ChaCha8 seeded with `seed`, stream 1, so that it is independent of the input's random numbers).
pub fn add_noise(y: &[f64], std_mm: f64, seed: u64) -> Vec<f64> {
    if std_mm == 0.0 {
        return y.to_vec();
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(1);
    y.iter()
        .map(|v| v + std_mm * rng.sample::<f64, _>(StandardNormal))
        .collect()
}

/// Checks a number of samples N (`--samples`) against the bound, before anything is allocated.
pub fn check_samples(samples: usize) -> Result<(), IpaError> {
    if samples == 0 || samples > sysid_core::data::MAX_SAMPLES {
        return Err(IpaError::setting(
            IpaSetting::Samples,
            samples,
            format!("expected 1..={}", sysid_core::data::MAX_SAMPLES),
        ));
    }
    Ok(())
}

fn check_settings(samples: usize, ts_s: f64, amplitude: f64) -> Result<(), IpaError> {
    check_samples(samples)?;
    if !(ts_s.is_finite() && ts_s > 0.0) {
        return Err(IpaError::setting(
            IpaSetting::Ts,
            ts_s,
            "expected a positive sampling period in s",
        ));
    }
    if !(amplitude.is_finite() && amplitude >= 0.0) {
        return Err(IpaError::setting(
            IpaSetting::Amplitude,
            amplitude,
            "expected a number of counts >= 0",
        ));
    }
    Ok(())
}

/// Reads column `u` of a CSV file (header row required), every cell a finite number.
pub fn read_input_file(path: &Path) -> Result<Vec<f64>, IpaError> {
    let mut cols = read_input_columns(path, &["u"])?;
    Ok(cols.pop().unwrap_or_default())
}

/// Reads the columns `names` of a CSV file (header row required), every cell a finite number: the
/// commands of a model with several inputs, one column per input.
pub fn read_input_columns(path: &Path, names: &[&str]) -> Result<Vec<Vec<f64>>, IpaError> {
    Ok(read_columns(path, names)?.1)
}

/// The table of a CSV input file and its columns `names` (one read).
fn read_columns(
    path: &Path,
    names: &[&str],
) -> Result<(sysid_core::data::Table, Vec<Vec<f64>>), IpaError> {
    let bytes = sysid_core::data::bounded::read_data_file(path, "an input file")?;
    let table = sysid_core::data::read_table(&bytes, &path.display().to_string())?;
    let mut cols = Vec::with_capacity(names.len());
    for name in names {
        let col = table.column_index(name, sysid_core::Setting::Other("--input file:CSV"))?;
        cols.push(table.numbers(col)?);
    }
    Ok((table, cols))
}

/// The file line and column (1-based) of data row `row` (0-based) of column `name` of a CSV input
/// file, read again: for an error about one of its values, named at `FILE:LINE:COL` as every reader
/// names a place (audit s30 L-11). `None` when the file no longer reads.
pub fn command_position(path: &Path, name: &str, row: usize) -> Option<(usize, usize)> {
    let (table, _) = read_columns(path, &[name]).ok()?;
    let col = table
        .column_index(name, sysid_core::Setting::Other("--input file:CSV"))
        .ok()?;
    Some((table.line_of(row), col + 1))
}

/// The columns `names` of a CSV input file and Ts (s) of its time column `t` (seconds) when it has
/// one, by the reader's rule (non-uniform time is refused at its line), in one read. `simulate --input
/// file:CSV` replays the commands at this Ts, or says that it does not (audit s16 L14).
pub fn read_command_file(path: &Path, names: &[&str]) -> Result<CommandFile, IpaError> {
    let (table, columns) = read_columns(path, names)?;
    let ts = match table.headers.iter().position(|h| h == "t") {
        Some(col) => Some(table.uniform_ts(col)?),
        None => None,
    };
    Ok(CommandFile {
        path: path.to_path_buf(),
        columns,
        ts,
    })
}

/// Clock period of the PRBS in samples: 50 ms, at least one sample.
fn clock_samples(ts_s: f64) -> usize {
    ((0.05 / ts_s).round() as usize).max(1)
}

/// The experimenter's rule behind `staircase` (the paper's "continuous step signal").
///
/// A real experimenter watches the piston and keeps it inside the stroke. Each new level has a magnitude
/// drawn uniformly from the integers 0..=A and a hold drawn uniformly from [hold_min_s, hold_max_s]; its
/// sign is + with probability (1 - (y - L/2) / band_mm) / 2, clamped to [0, 1], where y is the measured
/// position when the level starts (so the piston is pulled back towards mid-stroke), and a level is ended
/// early when it drives the piston to within `margin_mm` of the end stop it is moving towards.
///
/// [`staircase_experiment`] applies the rule to any plant. The open-loop [`generate`] applies it to the
/// default physics plant started at mid-stroke (the experimenter's nominal plant), so the sequence it
/// returns reproduces exactly on that plant and approximately on others.
#[derive(Debug, Clone, PartialEq)]
pub struct StaircaseDesign {
    /// Shortest hold of a level, s.
    pub hold_min_s: f64,
    /// Longest hold of a level, s.
    pub hold_max_s: f64,
    /// Stroke L, mm (end stops at 0 and L).
    pub stroke_mm: f64,
    /// Distance from mid-stroke (mm) at which the sign is always chosen back towards the middle.
    pub band_mm: f64,
    /// A level ends early once the piston is within this distance (mm) of the end stop it moves to.
    pub margin_mm: f64,
}

impl Default for StaircaseDesign {
    fn default() -> Self {
        StaircaseDesign {
            hold_min_s: 0.1,
            hold_max_s: 0.5,
            stroke_mm: 200.0,
            band_mm: 60.0,
            margin_mm: 25.0,
        }
    }
}

/// Runs the supervised staircase of `design` on `plant` from its current state for `samples` samples
/// with amplitude `amplitude` (counts) and returns (u, y) as a data logger records them: y(k) is the
/// output before u(k) is applied. The same seed and plant state give the same record.
pub fn staircase_experiment(
    plant: &mut dyn sysid_core::Plant,
    design: &StaircaseDesign,
    samples: usize,
    amplitude: f64,
    seed: u64,
) -> Result<(Vec<f64>, Vec<f64>), IpaError> {
    staircase_experiment_observed(plant, design, samples, amplitude, seed, |_| ())
}

/// [`staircase_experiment`] that also hands the plant to `observe` at every sample, just before u(k) is
/// applied (when y(k) is recorded): what else a logger records (the physics plant's pressures) comes
/// from the same run, so the plant need not be simulated a second time with the designed input.
pub fn staircase_experiment_observed<P: sysid_core::Plant + ?Sized>(
    plant: &mut P,
    design: &StaircaseDesign,
    samples: usize,
    amplitude: f64,
    seed: u64,
    observe: impl FnMut(&P),
) -> Result<(Vec<f64>, Vec<f64>), IpaError> {
    let ts_s = plant.ts();
    check_settings(samples, ts_s, amplitude)?;
    let a = amplitude.floor();
    let hold_max_s = design.hold_max_s.max(design.hold_min_s);
    supervised_experiment(plant, design, samples, seed, observe, |rng| {
        let magnitude = if a >= 1.0 {
            rng.gen_range(0..=a as u64) as f64
        } else {
            amplitude
        };
        let hold_s = rng.gen_range(design.hold_min_s..=hold_max_s);
        (magnitude, hold_s)
    })
}

/// The experimenter's loop shared by the supervised designs: `draw` gives each level's magnitude
/// (counts) and hold (s); the sign is + with probability (1 - (y - L/2)/band)/2 and a level ends
/// early within `margin_mm` of the end stop it moves towards (see [`StaircaseDesign`]).
fn supervised_experiment<P: sysid_core::Plant + ?Sized>(
    plant: &mut P,
    design: &StaircaseDesign,
    samples: usize,
    seed: u64,
    mut observe: impl FnMut(&P),
    mut draw: impl FnMut(&mut ChaCha8Rng) -> (f64, f64),
) -> Result<(Vec<f64>, Vec<f64>), IpaError> {
    let ts_s = plant.ts();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = Vec::with_capacity(samples);
    let mut y = Vec::with_capacity(samples);
    let mid = 0.5 * design.stroke_mm;
    while u.len() < samples {
        let (magnitude, hold_s) = draw(&mut rng);
        let hold = ((hold_s / ts_s).round() as usize).max(1);
        let p_plus = (0.5 - 0.5 * (plant.output() - mid) / design.band_mm).clamp(0.0, 1.0);
        let level = if rng.gen_bool(p_plus) {
            magnitude
        } else {
            -magnitude
        };
        for _ in 0..hold {
            let yk = plant.output();
            let near_end = (level > 0.0 && yk >= design.stroke_mm - design.margin_mm)
                || (level < 0.0 && yk <= design.margin_mm);
            if u.len() == samples || near_end {
                break;
            }
            u.push(level);
            y.push(yk);
            observe(plant);
            plant.step(level).map_err(|e| match e {
                sysid_core::PlantError::Diverged(m) => sysid_core::SysidError::Numerical(format!(
                    "{m} (while applying u({}) = {level})",
                    u.len() - 1
                )),
                sysid_core::PlantError::Cancelled => sysid_core::SysidError::Cancelled,
            })?;
        }
    }
    Ok((u, y))
}

/// The calibration design (`--input calibration`): the experimenter's loop of [`StaircaseDesign`]
/// (sign towards mid-stroke, a level ends 25 mm before an end stop, so the piston never stays at a
/// stop) with levels drawn to excite every parameter of the physics plant ([`crate::calibrate`]):
///
/// | share | level | hold | determines |
/// |---|---|---|---|
/// | 25 % | full command, 255 counts | 0.1..0.4 s | supply/exhaust conductances (speed), mass (hard starts and reversals) |
/// | 25 % | medium, 60..200 counts | 0.2..0.5 s | viscous friction (speeds between), conductances |
/// | 30 % | small, 5..60 counts (around the deadzone) | 0.3..0.6 s | valve delays, static/Coulomb friction, Stribeck velocity (breakaway and slow creep) |
/// | 20 % | rest, 0 counts | 0.2..0.4 s | rest states with exhausted chambers (segment starts), dead volumes (pressure decay) |
///
/// `amplitude` scales the full and medium levels (255 by default); the small levels stay in 5..60.
pub fn calibration_experiment_observed<P: sysid_core::Plant + ?Sized>(
    plant: &mut P,
    samples: usize,
    amplitude: f64,
    seed: u64,
    observe: impl FnMut(&P),
) -> Result<(Vec<f64>, Vec<f64>), IpaError> {
    check_settings(samples, plant.ts(), amplitude)?;
    let scale = (amplitude / U_MAX_COUNTS).min(1.0);
    supervised_experiment(
        plant,
        &StaircaseDesign::default(),
        samples,
        seed,
        observe,
        |rng| {
            let kind: f64 = rng.gen();
            if kind < 0.25 {
                ((U_MAX_COUNTS * scale).round(), rng.gen_range(0.1..=0.4))
            } else if kind < 0.5 {
                (
                    (rng.gen_range(60.0..=200.0) * scale).round(),
                    rng.gen_range(0.2..=0.5),
                )
            } else if kind < 0.8 {
                (rng.gen_range(5..=60) as f64, rng.gen_range(0.3..=0.6))
            } else {
                (0.0, rng.gen_range(0.2..=0.4))
            }
        },
    )
}

/// Full PWM command, counts.
const U_MAX_COUNTS: f64 = 255.0;

/// The open-loop staircase: [`staircase_experiment`] on the default physics plant at mid-stroke.
fn staircase(samples: usize, ts_s: f64, amplitude: f64, seed: u64) -> Result<Vec<f64>, IpaError> {
    let design = StaircaseDesign::default();
    let mut nominal = crate::Ipa::with_ts(crate::PlantConfig::default(), ts_s)?;
    sysid_core::Plant::reset(&mut nominal, 0.5 * design.stroke_mm);
    Ok(staircase_experiment(&mut nominal, &design, samples, amplitude, seed)?.0)
}

/// Maximum-length PRBS from a 10-bit Fibonacci LFSR (x^10 + x^7 + 1, period 1023), each bit held for
/// `clock` samples; the seed chooses the (nonzero) initial register.
pub fn prbs(samples: usize, clock: usize, seed: u64) -> Vec<bool> {
    let mut reg: u16 = (seed % 1023) as u16 + 1;
    let mut out = Vec::with_capacity(samples);
    let mut bit = reg & 1 == 1;
    for k in 0..samples {
        if k % clock == 0 {
            let fb = ((reg >> 9) ^ (reg >> 6)) & 1;
            reg = ((reg << 1) | fb) & 0x3ff;
            bit = fb == 1;
        }
        out.push(bit);
    }
    out
}

fn aprbs(samples: usize, ts_s: f64, amplitude: f64, seed: u64, rng: &mut ChaCha8Rng) -> Vec<f64> {
    let bits = prbs(samples, clock_samples(ts_s), seed);
    let mut level = rng.gen_range(-1.0..=1.0) * amplitude;
    let mut out = Vec::with_capacity(samples);
    for k in 0..samples {
        if k > 0 && bits[k] != bits[k - 1] {
            level = rng.gen_range(-1.0..=1.0) * amplitude;
        }
        out.push(level.round());
    }
    out
}

fn multisine(
    samples: usize,
    ts_s: f64,
    amplitude: f64,
    rng: &mut ChaCha8Rng,
) -> Result<Vec<f64>, IpaError> {
    let duration = samples as f64 * ts_s;
    let f_nyq = 0.5 / ts_s;
    let f_max = 10.0_f64.min(0.8 * f_nyq);
    let j_min = (1.0 * duration).ceil().max(1.0) as usize;
    let j_max = (f_max * duration).floor() as usize;
    // The band is the IPA's (1 Hz up to 10 Hz or 0.8 f_Nyquist): at a slow sampling period (a model of
    // a process sampled every second, audit s12 F4) it holds one harmonic at the sampling rate or none,
    // and the "multisine" would be a constant.
    if j_max < j_min + 1 {
        return Err(IpaError::Config(format!(
            "--input multisine excites 1 Hz .. {f_max} Hz (the IPA's band, at most 0.8 times the Nyquist frequency {f_nyq} Hz at Ts = {} s), which holds fewer than 2 harmonics of the record's 1 / ({samples} x {ts_s} s): the input would be a constant; use --input prbs, aprbs, staircase or file:CSV",
            sysid_core::format::Shortest(ts_s)
        )));
    }
    let harmonics: Vec<(f64, f64)> = (j_min..=j_max)
        .map(|j| {
            (
                j as f64 / duration,
                rng.gen_range(0.0..std::f64::consts::TAU),
            )
        })
        .collect();
    let s: Vec<f64> = (0..samples)
        .map(|k| {
            let t = k as f64 * ts_s;
            harmonics
                .iter()
                .map(|(f, ph)| (std::f64::consts::TAU * f * t + ph).sin())
                .sum()
        })
        .collect();
    let peak = s.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if peak == 0.0 {
        return Ok(vec![0.0; samples]);
    }
    Ok(s.iter().map(|v| (amplitude * v / peak).round()).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    // The added noise e = y_noisy − y has mean 0 and standard deviation σ: sample mean within 5 standard
    // errors (σ/√n) of 0, sample variance within 5 standard errors (σ²√(2/n)) of σ²; the same seed gives
    // the same noise, another seed other noise, σ = 0 none.
    #[test]
    fn added_noise_is_zero_mean_with_the_asked_standard_deviation() {
        let n = 20_000;
        let sigma = 0.3;
        let y: Vec<f64> = (0..n).map(|k| (k % 7) as f64).collect();
        let noisy = add_noise(&y, sigma, 5);
        let e: Vec<f64> = noisy.iter().zip(&y).map(|(a, b)| a - b).collect();
        let mean = e.iter().sum::<f64>() / n as f64;
        let var = e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
        assert!(mean.abs() < 5.0 * sigma / (n as f64).sqrt(), "{mean}");
        assert!(
            (var - sigma * sigma).abs() < 5.0 * sigma * sigma * (2.0 / n as f64).sqrt(),
            "{var}"
        );
        assert_eq!(noisy, add_noise(&y, sigma, 5));
        assert_ne!(noisy, add_noise(&y, sigma, 6));
        assert_eq!(add_noise(&y, 0.0, 5), y);
    }

    #[test]
    fn specs_parse_and_bad_specs_are_explained() {
        assert_eq!(
            "staircase".parse::<InputSpec>().unwrap(),
            InputSpec::Staircase
        );
        assert_eq!(
            "step:-40".parse::<InputSpec>().unwrap(),
            InputSpec::Step {
                level: -40.0,
                onset: 10
            }
        );
        assert_eq!(
            "step:40@0".parse::<InputSpec>().unwrap(),
            InputSpec::Step {
                level: 40.0,
                onset: 0
            }
        );
        assert_eq!(
            "file:a.csv".parse::<InputSpec>().unwrap(),
            InputSpec::File("a.csv".into())
        );
        for bad in ["stair", "step:", "step:x", "step:1@-2", "file:", "step:inf"] {
            let e = bad.parse::<InputSpec>().unwrap_err();
            assert!(
                matches!(
                    &e,
                    IpaError::Setting {
                        setting: IpaSetting::Input,
                        expected,
                        ..
                    } if expected.contains("staircase")
                ),
                "{bad}: {e}"
            );
        }
    }

    // A maximum-length 10-bit sequence has period 2^10 - 1 = 1023 with 512 ones and 511 zeros.
    #[test]
    fn prbs_has_period_1023_with_512_ones() {
        let b = prbs(2046, 1, 7);
        assert_eq!(&b[..1023], &b[1023..]);
        assert_eq!(b[..1023].iter().filter(|&&x| x).count(), 512);
        assert!((1..1023).all(|p| b[..1023] != b[p..p + 1023]));
    }

    #[test]
    fn same_seed_same_signal_other_seed_other_signal() {
        for spec in [
            InputSpec::Staircase,
            InputSpec::Prbs,
            InputSpec::Aprbs,
            InputSpec::Multisine,
        ] {
            let a = generate(&spec, 500, 0.01, 255.0, 3).unwrap();
            assert_eq!(a, generate(&spec, 500, 0.01, 255.0, 3).unwrap());
            assert_ne!(a, generate(&spec, 500, 0.01, 255.0, 4).unwrap(), "{spec}");
            assert!(a.iter().all(|v| v.abs() <= 255.0), "{spec}");
        }
    }

    #[test]
    fn staircase_levels_are_integers_within_the_amplitude_and_held() {
        let u = generate(&InputSpec::Staircase, 2000, 0.01, 200.0, 1).unwrap();
        assert!(u.iter().all(|v| v.fract() == 0.0 && v.abs() <= 200.0));
        let changes = u.windows(2).filter(|w| w[0] != w[1]).count();
        // Holds of 0.1..0.5 s (10..50 samples), some shortened: far fewer changes than samples.
        assert!(changes > 20 && changes < 400, "{changes}");
    }

    #[test]
    fn multisine_peak_is_the_amplitude() {
        let u = generate(&InputSpec::Multisine, 1000, 0.01, 100.0, 0).unwrap();
        let peak = u.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        assert_eq!(peak, 100.0);
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(generate(&InputSpec::Prbs, 0, 0.01, 1.0, 0).is_err());
        assert!(generate(&InputSpec::Prbs, 10, 0.0, 1.0, 0).is_err());
        assert!(generate(&InputSpec::Prbs, 10, 0.01, f64::NAN, 0).is_err());
        let e = generate(
            &InputSpec::File("/nonexistent/u.csv".into()),
            10,
            0.01,
            1.0,
            0,
        )
        .unwrap_err();
        assert!(e.to_string().contains("/nonexistent/u.csv"), "{e}");
    }
}
