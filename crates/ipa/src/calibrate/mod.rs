//! Calibration of the physics plant to a measured record (grey-box identification, MATLAB's
//! `nlgreyest` for this one model): a *digital twin* of the user's actuator.
//!
//! Given a record of the command u(k) (counts), the position y(k) (mm) and, when measured, the chamber
//! pressures p_a(k), p_b(k) (Pa), [`Calibration::fit`] estimates the free [`Parameter`]s θ of the
//! [`PlantConfig`] by minimising the simulation error
//!
//! ```text
//! V(θ) = ½ Σ_segments Σ_k [ ((x̂_k(θ) − y_k) / s_y)² + ((p̂_a,k(θ) − p_a,k) / s_p)² + ((p̂_b,k(θ) − p_b,k) / s_p)² ]
//! ```
//!
//! where x̂ is the simulated (unquantised) position and s_y, s_p are scales (0.01 mm, 5 kPa).
//!
//! **Segments (multiple shooting from measured states).** A free run of a stick-slip plant over a long
//! record is a very nonlinear function of θ: a breakaway that happens one sample late shifts every
//! later sample. The record is therefore cut into segments of about `segment_s` seconds, each started
//! where the piston is measured at rest (y unchanged over the previous two samples), from the measured
//! state: position y_k, velocity 0 and the measured pressures (without pressure columns, a segment can
//! only start where u has been 0 long enough for both chambers to have exhausted to p_atm, or at the
//! start of the record, taken at rest at p_atm like `simulate`). Errors cannot accumulate beyond a
//! segment, so V is smooth enough in θ for a local search from the plant's defaults.
//!
//! **Start.** The start plant (defaults or `--plant-config`), with the supply conductance scaled by the
//! ratio of the measured to the simulated speed at full command (the choked flow through the supply
//! path sets that speed, proportional to C_s).
//!
//! **Search.** Levenberg–Marquardt with box bounds ([`lm`]) in log coordinates (Coulomb friction as the
//! ratio F_c / F_s in (0, 1]), forward-difference Jacobian with columns in parallel.
//!
//! **Uncertainty.** cov θ ≈ σ² (JᵀJ)⁺ with σ² = 2V / (m − p) (m residuals), mapped to the physical
//! values by the derivative of the coordinates; the correlation matrix from it. A parameter with a
//! relative standard deviation above `determined_rel_std`, strongly correlated with another
//! (|ρ| > 0.99) or at a bound gets a warning naming the experiment that would determine it.
//!
//! **Never worse without saying so.** The search only accepts steps that lower V, so the twin is never
//! worse than its start on the estimation segments; the free-run fit of start and twin are also
//! compared on the whole estimation record and, when given, on a validation record, and a warning says
//! when the twin is worse on either.

pub mod lm;
pub mod parameter;
pub mod study;

use std::path::Path;

use nalgebra::DMatrix;
use rayon::prelude::*;

pub use lm::Termination;
use parameter::Coordinates;
pub use parameter::{free_parameters, parse_list, Parameter};

use crate::{Ipa, IpaError, PlantConfig, Record};

/// Parameters of the first stage of plan C: those that set speeds, forces and pressures.
const CORE_PARAMETERS: [Parameter; 6] = [
    Parameter::SupplyConductance,
    Parameter::ExhaustConductance,
    Parameter::MovingMass,
    Parameter::DeadVolumeCap,
    Parameter::DeadVolumeRod,
    Parameter::ExternalForce,
];

/// V above this many quantisation floors starts the restarts (plans B, C) and, at the end, a warning.
const RESTART_FLOOR_RATIO: f64 = 3.0;

/// RMS position error over the segments, in encoder counts, above which the fit is called poor.
const POOR_FIT_COUNTS: f64 = 10.0;

/// Parameters held at their start in the first stage of the search.
const SHAPE_PARAMETERS: [Parameter; 3] = [
    Parameter::StribeckVelocity,
    Parameter::OpeningDelay,
    Parameter::ClosingDelay,
];

/// Fewest samples a record must have for calibration.
pub const MIN_SAMPLES: usize = 50;

/// Reads a record with the reader every command uses (`sysid_core::data::read_record` with `opts`: a
/// `.mat` file or CSV, `--no-header`, `--rows`, `--time-unit`, `--resample`; Ts from `opts.ts`, else a
/// uniform time column, else `opts.fallback_ts`; without any of them the record is refused as
/// `identify` refuses it, "no time column 't' and no --ts"; a non-uniform column is refused at its
/// line): u and y from `opts.u_col`, `opts.y_col`, and the chamber pressures p_a, p_b (Pa, absolute)
/// from the columns `pressures` names, or the plant's own `p_a_pa`, `p_b_pa` when the file has both
/// (a CSV's header, a MAT-file's vectors).
/// The pressures are read as two more columns of the same record, so `--rows` and `--resample` cut and interpolate them with u and y.
/// Returns the record and the reader's notes (for example a `--ts` that contradicts the time column),
/// which a caller shows as warnings ([`CalibrationWarning::Reader`]).
pub fn read_record(
    path: &Path,
    opts: &sysid_core::data::CsvOptions,
    pressures: Option<&(String, String)>,
) -> Result<(Record, Vec<String>), IpaError> {
    let name = path.display().to_string();
    // The file is read once: its bytes give the pressure columns (a CSV header) and the record.
    let bytes = sysid_core::data::bounded::read_data_file(path, "a calibration record")?;
    let is_mat = sysid_core::data::mat::has_mat_name(path) || sysid_core::data::mat::is_mat(&bytes);
    // The pressure columns: named, or found in a CSV header (checked here, so that a missing one is
    // named by the flag that chose it).
    // A MAT-file read with the plant's own pressure vectors (below), kept as the record.
    let mut read_with_pressures = None;
    let pressures = if is_mat {
        // A MAT-file's variables, as a CSV's header: the plant's own p_a_pa, p_b_pa when it holds both
        // as vectors that read beside u and y (audit s37 M-4: they were ignored without a word).
        pressures.cloned().or_else(|| {
            let mut with = opts.clone();
            with.u_col = format!("{},p_a_pa,p_b_pa", opts.u_col);
            let read = sysid_core::data::mat::read_mat_bytes(&bytes, &name, &with).ok()?;
            read_with_pressures = Some(read);
            Some(("p_a_pa".to_string(), "p_b_pa".to_string()))
        })
    } else {
        let table = sysid_core::data::read_table_for(&bytes, &name, opts)?;
        let has = |c: &str| !opts.no_header && table.headers.iter().any(|h| h == c);
        let pressures = pressures.cloned().or_else(|| {
            (has("p_a_pa") && has("p_b_pa")).then(|| ("p_a_pa".to_string(), "p_b_pa".to_string()))
        });
        if let Some((a, b)) = &pressures {
            table.column_index(a, sysid_core::Setting::Other("--pa-col"))?;
            table.column_index(b, sysid_core::Setting::Other("--pb-col"))?;
        }
        pressures
    };
    let mut read_opts = opts.clone();
    if let Some((a, b)) = &pressures {
        read_opts.u_col = format!("{},{a},{b}", opts.u_col);
    }
    let read = if let Some(read) = read_with_pressures {
        read
    } else if is_mat {
        sysid_core::data::mat::read_mat_bytes(&bytes, &name, &read_opts)?
    } else {
        sysid_core::data::read_record_bytes(&bytes, &name, &read_opts)?
    };
    let columns = read.data.input_signals();
    let (u, y, ts) = (
        columns.first().map(|c| c.to_vec()).unwrap_or_default(),
        read.data.y().to_vec(),
        read.data.ts(),
    );
    // The record's Ts is at least MIN_TS_S (the reader checks it, `sysid_core::data::check_ts`); the
    // plant's own range caps it.
    if ts > 10.0 {
        return Err(IpaError::Config(format!(
            "{name}: sampling period {ts} s (from the time column or --ts): expected a value in [{:e}, 10] s",
            sysid_core::model::MIN_TS_S
        )));
    }
    if u.len() < MIN_SAMPLES {
        return Err(IpaError::Config(format!(
            "{name}: {} samples: calibration needs at least {MIN_SAMPLES}",
            u.len()
        )));
    }
    let pressures = match (columns.get(1), columns.get(2)) {
        (Some(a), Some(b)) => {
            if let Some(k) = a
                .iter()
                .chain(b.iter())
                .position(|p| p.is_nan() || *p <= 0.0)
            {
                return Err(IpaError::Config(format!(
                    "{name}: data row {}: a chamber pressure must be an absolute pressure > 0 Pa",
                    k % a.len() + 1
                )));
            }
            Some(a.iter().zip(b.iter()).map(|(a, b)| [*a, *b]).collect())
        }
        _ => None,
    };
    Ok((
        Record {
            u,
            y,
            pressures,
            ts,
        },
        read.notes,
    ))
}

/// The estimation record `data` and the optional validation record `validation` (its file and its
/// reader options: its own columns), read by [`read_record`], with the reader's notes on both as warnings (a validation record's prefixed by its
/// name), for [`Calibrated::warnings`]: what the command line and the Python package both do.
pub fn read_records(
    data: &Path,
    validation: Option<(&Path, &sysid_core::data::CsvOptions)>,
    opts: &sysid_core::data::CsvOptions,
    pressures: Option<&(String, String)>,
) -> Result<(Record, Option<Record>, Vec<CalibrationWarning>), IpaError> {
    let (est, mut notes) = read_record(data, opts, pressures)?;
    let val = match validation {
        Some((v, val_opts)) => {
            let (val, val_notes) = read_record(v, val_opts, pressures)?;
            notes.extend(
                val_notes
                    .into_iter()
                    .map(|n| format!("{}: {n}", v.display())),
            );
            Some(val)
        }
        None => None,
    };
    let notes = notes
        .into_iter()
        .map(|note| CalibrationWarning::Reader { note })
        .collect();
    Ok((est, val, notes))
}

/// Settings of a calibration (unfitted); [`Calibration::fit`] returns a [`Calibrated`] twin.
#[derive(Debug, Clone)]
pub struct Calibration {
    /// The start plant; its non-free parameters are kept.
    pub start: PlantConfig,
    /// The parameters to estimate (default: [`Parameter::ALL`]).
    pub free: Vec<Parameter>,
    /// Nominal length of a shooting segment, s (default 0.5 s); 0: one free run over the whole record.
    pub segment_s: f64,
    /// Scale s_y of the position error, mm (default 0.01, one encoder count).
    pub position_scale_mm: f64,
    /// Scale s_p of the pressure errors, Pa (default 5000).
    pub pressure_scale_pa: f64,
    /// Largest Levenberg–Marquardt iterations of one search (default 40; a calibration runs several,
    /// [`most_iterations`] in all).
    pub max_iterations: usize,
    /// Relative standard deviation above which a parameter is reported as not determined (default 0.05).
    pub determined_rel_std: f64,
    /// Scale the supply conductance by the full-command speed ratio before the search (default true).
    pub physical_start: bool,
    /// The caller's stop check, polled at each simulation of the record (each evaluation of the
    /// search; [`sysid_core::Stop`], default never): a stopped calibration returns
    /// `IpaError::Sysid(SysidError::Cancelled)`.
    pub cancel: sysid_core::Stop,
}

/// The most Levenberg–Marquardt iterations a calibration of `max_iterations` per search runs in all
/// ([`Calibration::fit`]): up to four plans, A (a stage of ⌈m/2⌉, then m), B (m), C (two stages of ⌈m/2⌉,
/// then m) and D (A on other segments, then m), so 4⌈m/2⌉ + 5m: 280 at the default m = 40. The banner
/// and the report speak of the same count (audit s28 L-5: "up to 40 iterations", then "280 iterations").
pub fn most_iterations(max_iterations: usize) -> usize {
    4 * max_iterations.div_ceil(2) + 5 * max_iterations
}

/// The largest [`Calibration::max_iterations`] accepted (each iteration simulates the record a few
/// times: 10 000 is hours on a long record).
pub const MAX_ITERATIONS: usize = 10_000;

impl Default for Calibration {
    fn default() -> Self {
        Calibration {
            start: PlantConfig::default(),
            free: Parameter::ALL.to_vec(),
            segment_s: 0.5,
            position_scale_mm: 0.01,
            pressure_scale_pa: 5000.0,
            max_iterations: 40,
            determined_rel_std: 0.05,
            physical_start: true,
            cancel: sysid_core::Stop::never(),
        }
    }
}

/// One estimated parameter.
#[derive(Debug, Clone, PartialEq)]
pub struct Estimate {
    /// Which parameter.
    pub parameter: Parameter,
    /// Value at the start of the search (after the physical start estimate).
    pub start: f64,
    /// Estimated value.
    pub value: f64,
    /// Standard deviation from the Jacobian (`None` when J is not available).
    pub std: Option<f64>,
    /// True when the estimate sits at a bound of the search box.
    pub at_bound: bool,
}

/// Free-run fit points (%) by which the twin must simulate a record worse than its start before it is
/// warned about (`WorseThanStart`): a search that lowers its segment cost may move the whole-record fit
/// by less, either way (audit s18 L-1: "do not use it" on 99.99217 % against 99.99275 %, a
/// 0.0006-point difference, after the cost fell from 20.5 to 16.6). 0.1 point is a chosen tolerance
/// (a tenth of a fit point), not a derived one.
pub const WORSE_THAN_START_POINTS: f64 = 0.1;

/// A reason not to trust (part of) a calibration.
#[derive(Debug, Clone, PartialEq)]
pub enum CalibrationWarning {
    /// The record does not determine the parameter (relative standard deviation above the limit, or
    /// no standard deviation).
    NotDetermined {
        /// The parameter.
        parameter: Parameter,
        /// Its relative standard deviation (None: not computable).
        relative_std: Option<f64>,
    },
    /// Two estimates are so correlated that the record determines only a combination of them.
    Correlated {
        /// First parameter.
        a: Parameter,
        /// Second parameter.
        b: Parameter,
        /// Correlation coefficient.
        rho: f64,
    },
    /// An estimate sits at a bound of the search box.
    AtBound {
        /// The parameter.
        parameter: Parameter,
    },
    /// The search stopped before converging.
    NotConverged {
        /// Why it stopped.
        termination: Termination,
    },
    /// What the reader said about a record (a `--ts` that contradicts its time column, ...), as every
    /// command's reader says it.
    Reader {
        /// The reader's words.
        note: String,
    },
    /// The twin simulates a record worse than the start plant did, by more than
    /// [`WORSE_THAN_START_POINTS`] of free-run fit.
    WorseThanStart {
        /// Which record (`estimation` or `validation`).
        record: &'static str,
        /// Free-run fit % of the start plant.
        start_fit: f64,
        /// Free-run fit % of the twin.
        twin_fit: f64,
    },
    /// The twin simulates a record no better than the record's mean (free-run fit ≤ 0 %).
    NoBetterThanMean {
        /// Which record.
        record: &'static str,
        /// Free-run fit % of the twin.
        twin_fit: f64,
        /// max |u| of the record, counts.
        largest_command: f64,
        /// The record's positions [min, max] when every one of them would fit the stroke in metres
        /// (|y| ≤ 1.25 × stroke / 1000): the record may be in metres where mm are read (audit s28 L-5).
        metres: Option<(f64, f64)>,
    },
    /// The free run of the twin failed on a record.
    SimulationFailed {
        /// Which record.
        record: &'static str,
        /// The error.
        message: String,
    },
    /// The comparison model beside the twin (the command line's best Hammerstein output-error model of
    /// a few orders) could not be identified on the record: the twin stands without it.
    NoComparison {
        /// Why (the first identification's error, which names the record).
        message: String,
    },
    /// Without pressures the record could not be cut into segments: one free run over the record.
    SingleSegment,
    /// Standard deviations that came out exactly 0 (withheld: the record does not determine them).
    ZeroStd {
        /// The parameters whose standard deviation was withheld.
        parameters: Vec<String>,
        /// How many parameters were estimated.
        of: usize,
    },
    /// V stayed above 3 times the quantisation floor after the restarts: measurement noise, a mechanism
    /// the plant lacks, or a local minimum; the standard deviations are then optimistic.
    AboveFloor {
        /// V / floor.
        ratio: f64,
    },
    /// V reached the quantisation floor (at most 3 times it): the residuals are then mostly the
    /// encoder's rounding, a deterministic function of the motion rather than independent noise, so the
    /// Jacobian's standard deviations understate the error (audit s11: 4 to 26 times on a plant of known
    /// truth); they are lower bounds.
    AtFloor {
        /// V / floor.
        ratio: f64,
    },
    /// The twin's position error over the segments is far above the encoder resolution: the plant
    /// does not reproduce the record (model mismatch, or the search stopped in a local minimum).
    PoorFit {
        /// RMS position error over the segments, mm.
        rmse_mm: f64,
        /// Encoder resolution, mm.
        resolution_mm: f64,
    },
}

impl std::fmt::Display for CalibrationWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            CalibrationWarning::NotDetermined { parameter, relative_std } => write!(
                f,
                "{parameter} is not determined by this record ({}); it keeps an uncertain value. \
                 Experiment that determines it: {}",
                relative_std.map_or("no standard deviation".to_string(), |r| format!(
                    "relative standard deviation {:.1} %",
                    100.0 * r
                )),
                parameter.experiment()
            ),
            CalibrationWarning::Correlated { a, b, rho } => {
                write!(
                    f,
                    "{a} and {b} are correlated (rho = {rho:.3}): the record determines a combination of \
                     them, not each. Experiment that separates them: {}",
                    a.experiment()
                )?;
                if b.experiment() != a.experiment() {
                    write!(f, "; {}", b.experiment())?;
                }
                Ok(())
            }
            CalibrationWarning::AtBound { parameter } => write!(
                f,
                "{parameter} stopped at a bound of its physical range ({}); the record may not determine it \
                 or the plant may not fit the record",
                parameter.key()
            ),
            CalibrationWarning::NotConverged { termination } => {
                write!(f, "the search did not converge ({termination})")
            }
            CalibrationWarning::WorseThanStart { record, start_fit, twin_fit } => {
                // Enough decimals for the two fits to differ in print (audit s18 L-1: "99.99 % vs 99.99 %").
                let d = (2..=12)
                    .find(|&d| format!("{twin_fit:.d$}") != format!("{start_fit:.d$}"))
                    .unwrap_or(12);
                write!(
                    f,
                    "the twin simulates the {record} record WORSE than its start (free-run fit {twin_fit:.d$} % \
                     vs {start_fit:.d$} %): do not use it without checking"
                )
            }
            CalibrationWarning::Reader { note } => f.write_str(note),
            CalibrationWarning::NoBetterThanMean {
                record,
                twin_fit,
                largest_command,
                metres,
            } => {
                write!(
                    f,
                    "the twin simulates the {record} record worse than its mean (free-run fit \
                     {twin_fit:.2} %): it does not follow this record, so do not use it as a model of \
                     the plant that produced it"
                )?;
                if *largest_command < 30.0 {
                    write!(
                        f,
                        "; the record's commands stay within ±{largest_command:.3} counts, inside the \
                         valves' deadzone (the twin is a pneumatic IPA driven by PWM counts up to \
                         ±255: is this record of such a plant, in counts?)"
                    )?;
                }
                if let Some((lo, hi)) = metres {
                    write!(
                        f,
                        "; the record's positions y stay within [{}, {}], which would fit the stroke if \
                         they were metres: is y in metres? calibrate reads positions in mm (multiply \
                         by 1000)",
                        sysid_core::format::Shortest(*lo),
                        sysid_core::format::Shortest(*hi)
                    )?;
                }
                Ok(())
            }
            CalibrationWarning::NoComparison { message } => write!(
                f,
                "no Hammerstein model could be identified for the comparison ({message}): the twin is \
                 reported without it"
            ),
            CalibrationWarning::SimulationFailed { record, message } => {
                write!(f, "the twin's free run on the {record} record failed: {message}")
            }
            CalibrationWarning::AboveFloor { ratio } => write!(
                f,
                "the simulation error is {ratio:.1} times what encoder quantisation alone gives: measurement \
                 noise, a mechanism the plant lacks, or a local minimum of the search; the standard \
                 deviations are optimistic"
            ),
            CalibrationWarning::AtFloor { ratio } => write!(
                f,
                "the simulation error is at the encoder's quantisation floor ({ratio:.2} times what rounding \
                 to the encoder's resolution alone gives): the residuals are then that rounding, which \
                 follows the motion and is not independent noise, so the standard deviations (±) are lower \
                 bounds, often ten or more times too small (4 to 42 times on plants of known truth: \
                 docs/twin.md): do not read them as confidence intervals; judge the twin by its \
                 validation fit"
            ),
            CalibrationWarning::PoorFit { rmse_mm, resolution_mm } => write!(
                f,
                "the twin's RMS position error over the segments is {rmse_mm:.3} mm, more than {POOR_FIT_COUNTS} \
                 encoder counts ({resolution_mm} mm): the plant does not reproduce the record (a mechanism the \
                 model lacks, wrong fixed parameters, or a local minimum: start closer with --plant-config); \
                 the standard deviations assume the model fits"
            ),
            CalibrationWarning::ZeroStd { parameters, of } => write!(
                f,
                "the standard deviations of {} of {of} parameters ({}) came out exactly 0: the record \
                 carries no information on them (a record without motion gives a zero Jacobian) or the \
                 covariance underflowed, so they are not reported",
                parameters.len(),
                parameters.join(", ")
            ),
            CalibrationWarning::SingleSegment => f.write_str(
                "no rest states to start segments from (a rest is y unchanged within half an encoder \
                 count over two samples, which noise on y never gives, and without pressure columns \
                 0.3 s of u = 0 before it): calibrated on one free run, which is less robust",
            ),
        }
    }
}

/// The free-run simulation of a plant on a record from its first sample.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeRun {
    /// Simulated position (unquantised), mm, at every sample.
    pub y_mm: Vec<f64>,
    /// Fit % = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) of the position (`None` for a constant record).
    pub fit_percent: Option<f64>,
    /// RMS position error, mm.
    pub rmse_mm: f64,
}

impl FreeRun {
    /// This free run's figures under `identify`'s names for the same quantities (a free run from the
    /// measured initial state is its `fit_sim_measured_percent` and `rmse_sim_measured`).
    pub fn metrics(&self) -> FreeRunMetrics {
        FreeRunMetrics {
            fit_sim_measured_percent: self.fit_percent,
            rmse_sim_measured: self.rmse_mm.is_finite().then_some(self.rmse_mm),
        }
    }
}

/// The figures of one free run ([`FreeRun::metrics`]), keyed as `identify --json`'s
/// `metrics.estimation` / `metrics.validation` objects key them.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FreeRunMetrics {
    /// Fit % = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) of the simulation from the measured initial state
    /// (`None` for a constant record).
    pub fit_sim_measured_percent: Option<f64>,
    /// RMS error of that simulation, in y's units (mm); `None` when not finite.
    pub rmse_sim_measured: Option<f64>,
}

/// A plant's free runs on the records of a calibration ([`Calibrated::metrics`],
/// [`Calibrated::start_metrics`]): `identify --json`'s `metrics` object, with the same record keys.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RecordMetrics {
    /// On the estimation record (`None` when its free run failed).
    pub estimation: Option<FreeRunMetrics>,
    /// On the validation record, when one was given (absent from the JSON otherwise, as in
    /// `identify`'s).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub validation: Option<FreeRunMetrics>,
}

/// A calibrated twin with its report.
#[derive(Debug, Clone)]
pub struct Calibrated {
    /// The calibrated plant (start plant with the estimates).
    pub config: PlantConfig,
    /// The start of the search (start plant after the physical start estimate).
    pub start_config: PlantConfig,
    /// The estimates, in the order of the free set.
    pub estimates: Vec<Estimate>,
    /// Correlation matrix of the estimates (rows and columns in the order of `estimates`).
    pub correlation: Vec<Vec<f64>>,
    /// Number of shooting segments.
    pub segments: usize,
    /// Whether the pressures were used.
    pub used_pressures: bool,
    /// V at the start and at the estimate.
    pub cost_start: f64,
    /// V at the estimate.
    pub cost: f64,
    /// V of a twin that reproduces the record up to the encoder quantisation alone.
    pub cost_floor: f64,
    /// RMS position error over the segments at the estimate, mm.
    pub segment_rmse_mm: f64,
    /// Levenberg–Marquardt iterations and simulations of the record.
    pub iterations: usize,
    /// Simulations of the (segmented) record.
    pub evaluations: usize,
    /// Why the search stopped.
    pub termination: Termination,
    /// Free run of the start plant and of the twin on the estimation record.
    pub estimation_start: Option<FreeRun>,
    /// Free run of the twin on the estimation record.
    pub estimation: Option<FreeRun>,
    /// Free run of the start and of the twin on the validation record, when given.
    pub validation_start: Option<FreeRun>,
    /// Free run of the twin on the validation record.
    pub validation: Option<FreeRun>,
    /// Every reason not to trust the result.
    pub warnings: Vec<CalibrationWarning>,
}

impl Calibrated {
    /// The twin's free runs on the estimation and validation records, named as `identify`'s metrics.
    pub fn metrics(&self) -> RecordMetrics {
        RecordMetrics {
            estimation: self.estimation.as_ref().map(FreeRun::metrics),
            validation: self.validation.as_ref().map(FreeRun::metrics),
        }
    }

    /// The start plant's free runs (before the search), as [`Calibrated::metrics`].
    pub fn start_metrics(&self) -> RecordMetrics {
        RecordMetrics {
            estimation: self.estimation_start.as_ref().map(FreeRun::metrics),
            validation: self.validation_start.as_ref().map(FreeRun::metrics),
        }
    }

    /// The twin as the plant-config TOML `calibrate` writes: a comment naming the record, the
    /// parameters ([`PlantConfig::to_commented_toml`]) and a `[calibration]` table with the record,
    /// its Ts (s), the free-run fits (%) and every warning ([`crate::config::CalibrationNote`]), which
    /// `tune` and `control` repeat when they run on the twin (audit s16 M8). `record` names the
    /// estimation record, `ts_s` is its sampling period.
    pub fn twin_toml(&self, record: &str, ts_s: f64) -> String {
        let fit = |r: &Option<FreeRun>| r.as_ref().and_then(|r| r.fit_percent);
        let config = PlantConfig {
            calibration: Some(crate::config::CalibrationNote {
                record: record.to_string(),
                ts_s: Some(ts_s),
                fit_estimation_percent: fit(&self.estimation),
                fit_validation_percent: fit(&self.validation),
                warnings: self.warnings.iter().map(ToString::to_string).collect(),
            }),
            ..self.config.clone()
        };
        format!(
            "# Digital twin calibrated by `ipa-sysid calibrate` on {record} (Ts = {} s).\n{}",
            sysid_core::format::Shortest(ts_s),
            config.to_commented_toml()
        )
    }
}

/// Simulates `cfg` on samples start..end of `rec` from the measured state at `start` (at rest at
/// y_start; pressures measured, or p_atm), calling `out(k, x_mm, [p_a, p_b])` for every sample k in
/// start..end before u_k is applied.
fn simulate_segment(
    cfg: &PlantConfig,
    rec: &Record,
    start: usize,
    end: usize,
    mut out: impl FnMut(usize, f64, [f64; 2]),
) -> Result<(), IpaError> {
    let mut plant = Ipa::with_ts(cfg.clone(), rec.ts)?;
    let patm = cfg.air.atmosphere_pa;
    let [pa, pb] = rec.pressures.as_ref().map_or([patm, patm], |p| p[start]);
    plant.set_state(rec.y[start], pa, pb);
    for k in start..end {
        out(k, plant.position_mm(), plant.pressures_pa());
        plant.advance(rec.u[k]).map_err(|e| match e {
            IpaError::Numerical(m) => IpaError::Numerical(format!("sample {k}: {m}")),
            other => other,
        })?;
    }
    Ok(())
}

/// The free run of `cfg` over the whole record from its first sample (at rest at y_0, the measured
/// pressures or p_atm).
pub fn free_run(cfg: &PlantConfig, rec: &Record) -> Result<FreeRun, IpaError> {
    let mut y_mm = vec![0.0; rec.u.len()];
    simulate_segment(cfg, rec, 0, rec.u.len(), |k, x, _| y_mm[k] = x)?;
    let fit_percent = sysid_core::metrics::fit_percent(&rec.y, &y_mm);
    let rmse_mm = sysid_core::metrics::rmse(&rec.y, &y_mm);
    Ok(FreeRun {
        y_mm,
        fit_percent,
        rmse_mm,
    })
}

/// A segment can start at sample k when the piston rests there as [`Ipa::set_state`] restarts it:
/// y unchanged (within `band_mm`, half an encoder count) over the last two samples, and, unless the
/// valves were closed over the last sample (u(k−1) = 0), still unchanged at the next sample. An
/// unchanged encoder alone is not rest: in the sample after a full command the piston may already
/// slide at several mm/s without having moved half a count, and a segment restarted there at v = 0,
/// stuck, with the valves de-energised, breaks loose late; on a record of the built-in plant that one
/// start made the cost at the TRUE parameters 123 times the quantisation floor (its 50 samples' RMS
/// error 0.21 mm; the other 37 starts 0.003 mm, the floor). A piston that is still at k + 1 had not
/// broken loose at k (it cannot stop again within one sample after a breakaway).
fn at_rest(rec: &Record, k: usize, band_mm: f64) -> bool {
    let steady = |a: usize, b: usize| (rec.y[a] - rec.y[b]).abs() <= band_mm;
    let valves_closed = k >= 1 && rec.u[k - 1] == 0.0;
    k >= 2
        && steady(k, k - 1)
        && steady(k - 1, k - 2)
        && (valves_closed || (k + 1 < rec.y.len() && steady(k + 1, k)))
}

/// Samples with u = 0 before a start without pressures (both chambers exhausted to p_atm).
const EXHAUSTED_SAMPLES: usize = 30;

/// Cuts the record into shooting segments [start, end) of about `nominal` samples, each starting at a
/// measured rest state with known pressures.
fn segments(rec: &Record, nominal: usize, band_mm: f64) -> Vec<(usize, usize)> {
    let n = rec.u.len();
    if nominal == 0 || nominal >= n {
        return vec![(0, n)];
    }
    let known = |k: usize| {
        rec.pressures.is_some()
            || (k >= EXHAUSTED_SAMPLES && rec.u[k - EXHAUSTED_SAMPLES..k].iter().all(|&u| u == 0.0))
    };
    let mut out = Vec::new();
    let mut start = 0;
    let mut k = nominal;
    while k < n {
        if at_rest(rec, k, band_mm) && known(k) {
            out.push((start, k));
            start = k;
            k += nominal;
        } else {
            k += 1;
        }
    }
    out.push((start, n));
    out
}

/// Median of the magnitude of the speed (mm/s) over samples held at full command (|u| >= 250 for the
/// last 5 samples, 10 mm away from the end stops) in direction `dir`; `None` with fewer than 5 such samples.
fn full_command_speed(u: &[f64], y: &[f64], ts: f64, stroke_mm: f64, dir: f64) -> Option<f64> {
    let mut v: Vec<f64> = (5..y.len().saturating_sub(1))
        .filter(|&k| u[k - 5..=k].iter().all(|&uk| dir * uk >= 250.0))
        .filter(|&k| y[k] > 10.0 && y[k] < stroke_mm - 10.0)
        .map(|k| dir * (y[k + 1] - y[k - 1]) / (2.0 * ts))
        .filter(|v| *v > 0.0)
        .collect();
    if v.len() < 5 {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

impl Calibration {
    /// The twin: estimates the free parameters on `estimation` and, when given, reports the free-run fit
    /// on `validation`.
    pub fn fit(
        &self,
        estimation: &Record,
        validation: Option<&Record>,
    ) -> Result<Calibrated, IpaError> {
        self.check(estimation)?;
        if let Some(v) = validation {
            self.check(v)?;
        }
        let rec = estimation;
        let nominal = (self.segment_s / rec.ts).round() as usize;
        let band = 0.5 * self.start.encoder.resolution_mm;
        let segs = segments(rec, nominal, band);
        let mut warnings = Vec::new();
        if segs.len() == 1 && nominal > 0 && nominal < rec.u.len() {
            warnings.push(CalibrationWarning::SingleSegment);
        }
        let mut start = self.start.clone();
        if self.physical_start && self.free.contains(&Parameter::SupplyConductance) {
            start = self.scale_supply_conductance(start, rec, &segs);
        }
        // Plan A. Stage 1: the friction shape (Stribeck velocity) and the valve delays stay at the
        // start while the parameters that set speeds, forces and pressures settle; stage 2: every
        // free parameter. The shape parameters matter only near rest, and moving them first lets the
        // search run into a basin where a wrong breakaway force is compensated by a wrong shape.
        // When the cost stays above 3 times the quantisation floor (a local minimum, or a plant
        // that does not fit), plan B restarts from the best point with the shape parameters back at
        // their start, and plan C stages from the start again with first only the conductances,
        // mass, dead volumes and external force. The lowest cost wins.
        let without_shape: Vec<Parameter> = self
            .free
            .iter()
            .copied()
            .filter(|p| !SHAPE_PARAMETERS.contains(p))
            .collect();
        let core: Vec<Parameter> = self
            .free
            .iter()
            .copied()
            .filter(|p| CORE_PARAMETERS.contains(p))
            .collect();
        let floor = self.cost_floor(&segs);
        let (mut iterations, mut evaluations) = (0, 0);
        // Runs the stages `first` (each skipped when empty or the whole free set), then one search
        // over every free parameter; V at the plan's start is kept as start_cost.
        let mut run_plan =
            |first: &[&[Parameter]], from: &PlantConfig, segs: &[(usize, usize)]| -> lm::Solution {
                let mut cfg = from.clone();
                let mut first_cost = None;
                for stage in first {
                    if stage.is_empty() || stage.len() == self.free.len() {
                        continue;
                    }
                    let (c, sol) =
                        self.search(stage, &cfg, rec, segs, self.max_iterations.div_ceil(2));
                    iterations += sol.iterations;
                    evaluations += sol.evaluations;
                    first_cost.get_or_insert(sol.start_cost);
                    cfg = c.config(&cfg, &sol.theta);
                }
                let (_, mut sol) = self.search(&self.free, &cfg, rec, segs, self.max_iterations);
                iterations += sol.iterations;
                evaluations += sol.evaluations;
                sol.start_cost = first_cost.unwrap_or(sol.start_cost);
                sol
            };
        let mut sol = run_plan(&[&without_shape], &start, &segs);
        let start_cost = sol.start_cost;
        if sol.termination != Termination::StartFailed && sol.cost > RESTART_FLOOR_RATIO * floor {
            let coords = Coordinates::new(&self.free, &start);
            let mut from = coords.config(&start, &sol.theta);
            for p in SHAPE_PARAMETERS.iter().filter(|p| self.free.contains(p)) {
                p.set(&mut from, p.get(&start));
            }
            from.friction.coulomb_n = from.friction.coulomb_n.min(from.friction.static_n);
            let b = run_plan(&[], &from, &segs);
            if b.cost < sol.cost {
                sol = b;
            }
        }
        if sol.termination != Termination::StartFailed && sol.cost > RESTART_FLOOR_RATIO * floor {
            let c = run_plan(&[&core, &without_shape], &start, &segs);
            if c.cost < sol.cost {
                sol = c;
            }
        }
        // Plan D: plan A on segments cut 0.8 times as long (other rest states start them: where the
        // segments start shapes a stick-slip plant's cost landscape), then polished on the record's
        // own segments, so that its cost compares with the other plans'. In the study it took plant
        // 18 from 12.6 floors to 0.8 (plant 10 stays at 8.8).
        if sol.termination != Termination::StartFailed && sol.cost > RESTART_FLOOR_RATIO * floor {
            let other = segments(rec, (nominal * 4 / 5).max(1), band);
            if other.len() > 1 && other != segs {
                let d = run_plan(&[&without_shape], &start, &other);
                if d.termination != Termination::StartFailed {
                    let from = Coordinates::new(&self.free, &start).config(&start, &d.theta);
                    let d = run_plan(&[], &from, &segs);
                    if d.cost < sol.cost {
                        sol = d;
                    }
                }
            }
        }
        sol.start_cost = start_cost;
        sol.iterations = iterations;
        sol.evaluations = evaluations;
        self.cancel.check()?;
        let coords = Coordinates::new(&self.free, &start);
        let stage_start = start.clone();
        let start_values_from = start.clone();
        let start = stage_start;
        if sol.termination == Termination::StartFailed {
            return Err(IpaError::Numerical(
                "the start plant cannot be simulated on the record (check the columns, units and --plant-config)"
                    .into(),
            ));
        }
        let config = coords.config(&start, &sol.theta);
        if !sol.cost.is_finite() {
            return Err(IpaError::Numerical(format!(
                "the calibration cost is {} (the record's values overflow the simulation error: check the \
                 columns and their units); no twin is written",
                sol.cost
            )));
        }
        let (mut estimates, correlation) = self.uncertainty(&coords, &start, &sol);
        // A standard deviation of exactly 0 (a still record: J = 0) claims a certainty the record does
        // not give: withheld (the parameter is then "not determined" below), and said.
        let zero = sysid_core::param::withhold_zero_stds(
            estimates
                .iter_mut()
                .map(|e| (e.parameter.name().to_string(), &mut e.std)),
        );
        if !zero.is_empty() {
            warnings.push(CalibrationWarning::ZeroStd {
                parameters: zero,
                of: estimates.len(),
            });
        }
        for e in &mut estimates {
            e.start = e.parameter.get(&start_values_from);
        }
        let start = start_values_from;
        let per_sample = if rec.pressures.is_some() { 3 } else { 1 };
        let segment_rmse_mm = self
            .residuals(&config, rec, &segs)
            .map(|r| {
                let pos: Vec<f64> = r.iter().step_by(per_sample).copied().collect();
                self.position_scale_mm
                    * (pos.iter().map(|x| x * x).sum::<f64>() / pos.len().max(1) as f64).sqrt()
            })
            .unwrap_or(f64::NAN);
        if sol.cost > RESTART_FLOOR_RATIO * floor {
            warnings.push(CalibrationWarning::AboveFloor {
                ratio: sol.cost / floor.max(1e-300),
            });
        } else if sol.cost.is_finite() && floor > 0.0 {
            warnings.push(CalibrationWarning::AtFloor {
                ratio: sol.cost / floor,
            });
        }
        let resolution_mm = config.encoder.resolution_mm;
        if segment_rmse_mm.is_nan() || segment_rmse_mm > POOR_FIT_COUNTS * resolution_mm {
            warnings.push(CalibrationWarning::PoorFit {
                rmse_mm: segment_rmse_mm,
                resolution_mm,
            });
        }
        // Warnings on the estimates.
        for e in &estimates {
            let rel = e.std.map(|s| s / e.value.abs().max(1e-12));
            let rel = if e.parameter == Parameter::ExternalForce {
                // F_ext may be 0: relative to the friction scale instead.
                e.std.map(|s| s / config.friction.static_n.max(1.0))
            } else {
                rel
            };
            if rel.is_none_or(|r| r.is_nan() || r > self.determined_rel_std) {
                warnings.push(CalibrationWarning::NotDetermined {
                    parameter: e.parameter,
                    relative_std: rel,
                });
            }
            if e.at_bound {
                warnings.push(CalibrationWarning::AtBound {
                    parameter: e.parameter,
                });
            }
        }
        for i in 0..correlation.len() {
            for j in i + 1..correlation.len() {
                let rho = correlation[i][j];
                if rho.abs() > 0.99 {
                    warnings.push(CalibrationWarning::Correlated {
                        a: estimates[i].parameter,
                        b: estimates[j].parameter,
                        rho,
                    });
                }
            }
        }
        if matches!(sol.termination, Termination::MaxIterations) {
            warnings.push(CalibrationWarning::NotConverged {
                termination: sol.termination,
            });
        }
        let mut compare = |name: &'static str, r: &Record| -> (Option<FreeRun>, Option<FreeRun>) {
            let s = free_run(&start, r).ok();
            let t = match free_run(&config, r) {
                Ok(t) => Some(t),
                Err(e) => {
                    warnings.push(CalibrationWarning::SimulationFailed {
                        record: name,
                        message: e.to_string(),
                    });
                    None
                }
            };
            if let (Some(sf), Some(tf)) = (
                s.as_ref().and_then(|s| s.fit_percent),
                t.as_ref().and_then(|t| t.fit_percent),
            ) {
                if tf < sf - WORSE_THAN_START_POINTS {
                    warnings.push(CalibrationWarning::WorseThanStart {
                        record: name,
                        start_fit: sf,
                        twin_fit: tf,
                    });
                }
            }
            // A twin that simulates the record no better than its mean does not follow it, whatever it
            // did against its start (audit s14 M-b: fits of −1.5 % and 0.0 % were written silently).
            if let Some(tf) = t.as_ref().and_then(|t| t.fit_percent).filter(|f| *f <= 0.0) {
                let u_max = r.u.iter().fold(0.0f64, |m, u| m.max(u.abs()));
                let (lo, hi) = sysid_core::DataRange::extremes(&r.y);
                let metres_bound = 1.25 * start.cylinder.stroke_mm / 1000.0;
                warnings.push(CalibrationWarning::NoBetterThanMean {
                    record: name,
                    twin_fit: tf,
                    largest_command: u_max,
                    metres: (lo.abs().max(hi.abs()) <= metres_bound).then_some((lo, hi)),
                });
            }
            (s, t)
        };
        let (estimation_start, estimation_twin) = compare("estimation", rec);
        let (validation_start, validation_twin) = match validation {
            Some(v) => compare("validation", v),
            None => (None, None),
        };
        Ok(Calibrated {
            config,
            start_config: start,
            estimates,
            correlation,
            segments: segs.len(),
            used_pressures: rec.pressures.is_some(),
            cost_start: sol.start_cost,
            cost: sol.cost,
            cost_floor: floor,
            segment_rmse_mm,
            iterations: sol.iterations,
            evaluations: sol.evaluations,
            termination: sol.termination,
            estimation_start,
            estimation: estimation_twin,
            validation_start,
            validation: validation_twin,
            warnings,
        })
    }

    /// V of a plant that reproduces the record up to the encoder quantisation alone: ½ Σ (q²/12) / s_y²
    /// over the position residuals (pressure noise unknown, not counted).
    fn cost_floor(&self, segs: &[(usize, usize)]) -> f64 {
        let m: usize = segs.iter().map(|(a, b)| b - a - 1).sum();
        let q = self.start.encoder.resolution_mm / self.position_scale_mm;
        0.5 * m as f64 * q * q / 12.0
    }

    /// One Levenberg–Marquardt search over `free` from `start`.
    fn search(
        &self,
        free: &[Parameter],
        start: &PlantConfig,
        rec: &Record,
        segs: &[(usize, usize)],
        max_iterations: usize,
    ) -> (Coordinates, lm::Solution) {
        let coords = Coordinates::new(free, start);
        let theta0 = coords.theta(start);
        let residual = |theta: &[f64]| -> Option<Vec<f64>> {
            // A stop makes every evaluation fail at once: the search ends in a few cheap steps and
            // `fit` returns Cancelled.
            if self.cancel.requested() {
                return None;
            }
            let cfg = coords.config(start, theta);
            cfg.validate().ok()?;
            self.residuals(&cfg, rec, segs).ok()
        };
        let sol = lm::minimise(
            &residual,
            &theta0,
            &coords.lo,
            &coords.hi,
            &lm::Settings {
                max_iterations,
                tolerance: 1e-9,
                fd_step: 1e-5,
                max_step: 0.3,
            },
        );
        (coords, sol)
    }

    fn check(&self, rec: &Record) -> Result<(), IpaError> {
        self.start.validate()?;
        let n = rec.u.len();
        if n < MIN_SAMPLES {
            return Err(IpaError::Config(format!(
                "{n} samples: calibration needs at least {MIN_SAMPLES}"
            )));
        }
        if rec.y.len() != n || rec.pressures.as_ref().is_some_and(|p| p.len() != n) {
            return Err(IpaError::Config(
                "u, y and the pressures must have the same length".into(),
            ));
        }
        if let Some(k) = rec.u.iter().chain(&rec.y).position(|x| !x.is_finite()) {
            return Err(IpaError::Config(format!(
                "sample {}: u and y must be finite",
                k % n
            )));
        }
        if !(self.segment_s >= 0.0 && self.segment_s.is_finite()) {
            return Err(IpaError::Config(format!(
                "segment length {} s: expected a finite length >= 0",
                self.segment_s
            )));
        }
        if !(self.position_scale_mm > 0.0 && self.pressure_scale_pa > 0.0) {
            return Err(IpaError::Config("error scales must be positive".into()));
        }
        if self.free.is_empty() {
            return Err(IpaError::Config("no free parameter to calibrate".into()));
        }
        if !(1..=MAX_ITERATIONS).contains(&self.max_iterations) {
            return Err(IpaError::Config(format!(
                "max_iterations = {}: expected 1..={MAX_ITERATIONS} Levenberg–Marquardt iterations",
                self.max_iterations
            )));
        }
        Ok(())
    }

    /// Scaled residuals of `cfg` on the segments (position, then the pressures, per sample).
    fn residuals(
        &self,
        cfg: &PlantConfig,
        rec: &Record,
        segs: &[(usize, usize)],
    ) -> Result<Vec<f64>, IpaError> {
        let parts: Vec<Result<Vec<f64>, IpaError>> = segs
            .par_iter()
            .map(|&(a, b)| {
                // The caller's stop, polled at each segment (one atomic load): an evaluation is a free
                // run of the whole record, about 1–2 s for 300 000 samples on a loaded 2-core machine,
                // which Ctrl-C waited for (audit s36 L-7: 2.1–2.5 s with the release build).
                self.cancel.check()?;
                let mut r = Vec::with_capacity(3 * (b - a));
                simulate_segment(cfg, rec, a, b, |k, x, p| {
                    if k == a {
                        return;
                    }
                    r.push((x - rec.y[k]) / self.position_scale_mm);
                    if let Some(pm) = &rec.pressures {
                        r.push((p[0] - pm[k][0]) / self.pressure_scale_pa);
                        r.push((p[1] - pm[k][1]) / self.pressure_scale_pa);
                    }
                })?;
                Ok(r)
            })
            .collect();
        let mut out = Vec::new();
        for p in parts {
            out.extend(p?);
        }
        Ok(out)
    }

    /// The start plant with C_s scaled by the ratio of measured to simulated full-command speeds
    /// (geometric mean over the directions both records have), the ratio clamped to [1/3, 3].
    fn scale_supply_conductance(
        &self,
        cfg: PlantConfig,
        rec: &Record,
        segs: &[(usize, usize)],
    ) -> PlantConfig {
        let mut sim = vec![f64::NAN; rec.u.len()];
        for &(a, b) in segs {
            // A stop leaves the start as it is (`fit` then ends with Cancelled after its search,
            // whose evaluations fail at once).
            if self.cancel.requested() {
                return cfg;
            }
            if simulate_segment(&cfg, rec, a, b, |k, x, _| sim[k] = x).is_err() {
                return cfg;
            }
        }
        let stroke = cfg.cylinder.stroke_mm;
        let mut log_ratio = Vec::new();
        for dir in [1.0, -1.0] {
            let m = full_command_speed(&rec.u, &rec.y, rec.ts, stroke, dir);
            let s = full_command_speed(&rec.u, &sim, rec.ts, stroke, dir);
            if let (Some(m), Some(s)) = (m, s) {
                log_ratio.push((m / s).ln());
            }
        }
        if log_ratio.is_empty() {
            return cfg;
        }
        let ratio = (log_ratio.iter().sum::<f64>() / log_ratio.len() as f64)
            .exp()
            .clamp(1.0 / 3.0, 3.0);
        let mut out = cfg;
        out.valve.supply_conductance_dm3_s_bar *= ratio;
        out
    }

    /// Estimates with standard deviations, and the correlation matrix.
    fn uncertainty(
        &self,
        coords: &Coordinates,
        start: &PlantConfig,
        sol: &lm::Solution,
    ) -> (Vec<Estimate>, Vec<Vec<f64>>) {
        let p = coords.free.len();
        let values = coords.values(start, &sol.theta);
        let start_values = coords.values(start, &coords.theta(start));
        let cov_theta = sol.jacobian.as_ref().and_then(|j| {
            let m = j.nrows();
            if m <= p {
                return None;
            }
            let sigma2 = 2.0 * sol.cost / (m - p) as f64;
            let jtj = j.transpose() * j;
            let eps = 1e-14 * jtj.norm();
            let inv = jtj.pseudo_inverse(eps).ok()?;
            Some(inv * sigma2)
        });
        // G = d(values)/dθ by central differences of the coordinate map (no simulation).
        let g = DMatrix::from_fn(p, p, |i, j| {
            let h = 1e-6;
            let mut tp = sol.theta.clone();
            let mut tm = sol.theta.clone();
            tp[j] += h;
            tm[j] -= h;
            (coords.values(start, &tp)[i] - coords.values(start, &tm)[i]) / (2.0 * h)
        });
        let cov = cov_theta.map(|c| &g * c * g.transpose());
        let estimates = (0..p)
            .map(|i| Estimate {
                parameter: coords.free[i],
                start: start_values[i],
                value: values[i],
                std: cov
                    .as_ref()
                    .map(|c| c[(i, i)].max(0.0).sqrt())
                    .filter(|s| s.is_finite()),
                at_bound: {
                    let w = (coords.hi[i] - coords.lo[i]) * 1e-6;
                    sol.theta[i] <= coords.lo[i] + w || sol.theta[i] >= coords.hi[i] - w
                },
            })
            .collect();
        let correlation = (0..p)
            .map(|i| {
                (0..p)
                    .map(|j| match &cov {
                        Some(c) => {
                            let d = (c[(i, i)] * c[(j, j)]).sqrt();
                            if d > 0.0 && d.is_finite() {
                                c[(i, j)] / d
                            } else if i == j {
                                1.0
                            } else {
                                0.0
                            }
                        }
                        None => f64::NAN,
                    })
                    .collect()
            })
            .collect();
        (estimates, correlation)
    }
}
