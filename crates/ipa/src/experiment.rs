//! One open-loop experiment on a plant (`ipa-sysid simulate`, the Python `simulate_plant`): a designed
//! input u(k) (PWM counts) applied to the physics IPA, the paper's model or a saved model, recording the
//! position y(k) (mm, with optional white measurement noise) and, for the physics plant, the chamber
//! pressures p_a, p_b (Pa).

use std::path::PathBuf;

use sysid_core::plant::Stoppable;
use sysid_core::{Plant, Setting, Stop, SysidError};

use crate::input::{
    calibration_experiment_observed, staircase_experiment, staircase_experiment_observed,
    InputSpec, StaircaseDesign,
};
use crate::{Ipa, IpaError, PlantConfig, PlantSpec};

/// Default number of samples N of an experiment.
pub const DEFAULT_SAMPLES: usize = 2000;

/// What to run: the settings of `ipa-sysid simulate` (each field is the flag of the same name).
#[derive(Debug, Clone, PartialEq)]
pub struct Experiment {
    /// The plant (`--plant`).
    pub plant: PlantSpec,
    /// TOML file overriding the physics plant's parameters (`--plant-config`, `ipa` only).
    pub plant_config: Option<PathBuf>,
    /// The input design (`--input`).
    pub input: InputSpec,
    /// Amplitude A of the random inputs, PWM counts (`--amplitude`).
    pub amplitude: f64,
    /// Number of samples N (`--samples`); `None`: the length of a file input, else [`DEFAULT_SAMPLES`].
    pub samples: Option<usize>,
    /// Sampling period Ts in s (`--ts`); `None`: 0.01 s, or a model plant's own Ts.
    pub ts: Option<f64>,
    /// Initial output y0 in mm, the plant at rest there (`--y0`); `None`: the plant's own default
    /// ([`PlantSpec::default_y0`]: mid-stroke for the IPA, a stable model's resting level).
    pub x0: Option<f64>,
    /// Seed of the random input and of the noise (`--seed`).
    pub seed: u64,
    /// Standard deviation of white Gaussian noise added to y, mm (`--noise-std`).
    pub noise_std: f64,
    /// The caller's request to stop the run (the Python binding's Ctrl-C): the plant polls it every
    /// [`sysid_core::stop::SAMPLES_PER_POLL`] samples ([`Stoppable`]) and the run ends with
    /// `IpaError::Sysid(SysidError::Cancelled)`. [`Stop::never`] by default (the command line's
    /// SIGINT ends the process).
    pub cancel: Stop,
}

impl Default for Experiment {
    fn default() -> Self {
        Experiment {
            plant: PlantSpec::Ipa,
            plant_config: None,
            input: InputSpec::Staircase,
            amplitude: 255.0,
            samples: None,
            ts: None,
            x0: None,
            seed: 0,
            noise_std: 0.0,
            cancel: Stop::never(),
        }
    }
}

/// The recorded experiment.
#[derive(Debug, Clone, PartialEq)]
pub struct Record {
    /// Input u(k), PWM counts.
    pub u: Vec<f64>,
    /// Output y(k), mm (noise included).
    pub y: Vec<f64>,
    /// Chamber pressures [p_a, p_b] in Pa at each sample (physics plant only).
    pub pressures: Option<Vec<[f64; 2]>>,
    /// Sampling period Ts in s.
    pub ts: f64,
}

impl Experiment {
    /// Checks the settings that do not need the plant (samples, x0, noise), before anything is
    /// allocated.
    pub fn check(&self) -> Result<(), IpaError> {
        if let Some(n) = self.samples {
            crate::input::check_samples(n)?;
        }
        if let Some(x0) = self.x0.filter(|v| !v.is_finite()) {
            return Err(
                SysidError::setting(Setting::Other("--y0"), x0, "a finite position in mm").into(),
            );
        }
        if !(self.noise_std.is_finite() && self.noise_std >= 0.0) {
            return Err(SysidError::setting(
                Setting::Other("--noise-std"),
                self.noise_std,
                "a standard deviation >= 0 in mm",
            )
            .into());
        }
        Ok(())
    }

    /// Runs the experiment: y(k) is the plant's output before u(k) is applied. A `file:CSV` input not
    /// yet loaded is read once here ([`InputSpec::load`]).
    pub fn run(&self) -> Result<Record, IpaError> {
        if let InputSpec::File(_) = self.input {
            return Experiment {
                input: self.input.clone().load()?,
                ..self.clone()
            }
            .run();
        }
        self.check()?;
        let samples = self.sample_count()?;
        if self.plant == PlantSpec::Ipa {
            let cfg = match &self.plant_config {
                Some(p) => PlantConfig::from_toml_file(p)?,
                None => PlantConfig::default(),
            };
            return self.run_ipa(cfg, samples);
        }
        let rec = {
            let x0 = match self.x0 {
                Some(v) => v,
                None => self.plant.default_y0()?,
            };
            // The paper's IPA takes the same ±255 PWM commands as the physics plant (audit s13 L18).
            let paper = self.plant == PlantSpec::Paper;
            if paper {
                self.check_applied(None)?;
            }
            let mut built = self.plant.build(self.plant_config.as_deref(), self.ts)?;
            built.reset(x0);
            let mut plant = Stoppable::new(built.as_mut(), &self.cancel);
            let ts = plant.ts();
            let (u, y) = match self.input {
                InputSpec::Staircase => staircase_experiment(
                    &mut plant,
                    &StaircaseDesign::default(),
                    samples,
                    self.amplitude,
                    self.seed,
                )?,
                _ => {
                    let u = crate::generate(&self.input, samples, ts, self.amplitude, self.seed)?;
                    if paper {
                        self.check_applied(Some(&u))?;
                    }
                    let y = sysid_core::plant::run_open_loop(&mut plant, &u)?;
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
        Ok(Record {
            y: crate::input::add_noise(&rec.y, self.noise_std, self.seed),
            ..rec
        })
    }

    /// Runs the experiment on the physics plant with the configuration `cfg` in memory (the plant
    /// and `plant_config` fields are not used): what [`Experiment::run`] does for `--plant ipa`.
    pub fn run_with_config(&self, cfg: PlantConfig) -> Result<Record, IpaError> {
        if let InputSpec::File(_) = self.input {
            return Experiment {
                input: self.input.clone().load()?,
                ..self.clone()
            }
            .run_with_config(cfg);
        }
        self.check()?;
        let samples = self.sample_count()?;
        self.run_ipa(cfg, samples)
    }

    /// Refuses a command the IPA (physics or the paper's) would not apply: its valves saturate at ±[`crate::plant::U_MAX`]
    /// counts, so a larger u in the record would not be the command the plant received (audit s11: a
    /// record written with `--amplitude 1000` identified b_l = +520). `u` is the designed input (`None`:
    /// before it is designed, the amplitude alone).
    fn check_applied(&self, u: Option<&[f64]>) -> Result<(), IpaError> {
        const WHY: &str =
            "the IPA's valves saturate at ±255 PWM counts, the paper's command range and the physics \
             plant's, so a larger u in the record would not be the command the plant received";
        let uses_amplitude = !matches!(
            self.input,
            InputSpec::Step { .. } | InputSpec::File(_) | InputSpec::Commands(_)
        );
        if uses_amplitude && self.amplitude > crate::plant::U_MAX {
            return Err(SysidError::setting(
                Setting::Other("--amplitude"),
                self.amplitude,
                &format!("at most {} counts ({WHY})", crate::plant::U_MAX),
            )
            .into());
        }
        let Some((k, v)) = u
            .unwrap_or_default()
            .iter()
            .enumerate()
            .find(|(_, v)| v.abs() > crate::plant::U_MAX)
        else {
            return Ok(());
        };
        Err(match self.input.file() {
            Some(f) => match crate::input::command_position(f, "u", k) {
                Some((line, column)) => SysidError::Parse {
                    file: f.display().to_string(),
                    line,
                    column,
                    message: format!(
                        "u = {} is beyond ±{} counts ({WHY}); scale the commands",
                        sysid_core::format::Shortest(*v),
                        crate::plant::U_MAX
                    ),
                },
                None => SysidError::File {
                    file: f.display().to_string(),
                    message: format!(
                        "column u, data row {}: u = {} is beyond ±{} counts ({WHY}); scale the \
                         commands",
                        k + 1,
                        sysid_core::format::Shortest(*v),
                        crate::plant::U_MAX
                    ),
                },
            },
            None => SysidError::setting(
                Setting::Other("--input step:LEVEL"),
                *v,
                &format!("a level within ±{} counts ({WHY})", crate::plant::U_MAX),
            ),
        }
        .into())
    }

    /// N: `--samples`, else the length of a file input, else [`DEFAULT_SAMPLES`].
    pub fn sample_count(&self) -> Result<usize, IpaError> {
        Ok(match (self.samples, self.input.file_commands()?) {
            (Some(n), _) => n,
            (None, Some(u)) => u.len(),
            (None, None) => DEFAULT_SAMPLES,
        })
    }

    fn run_ipa(&self, cfg: PlantConfig, samples: usize) -> Result<Record, IpaError> {
        let y0 = self.x0.unwrap_or(crate::spec::MID_STROKE_Y0_MM);
        crate::PlantLimits::of_ipa(&cfg).check_start(y0)?;
        self.check_applied(None)?;
        let rec = {
            let mut ipa = Ipa::with_ts(cfg, self.ts.unwrap_or(crate::DEFAULT_TS_S))?;
            ipa.reset(y0);
            let ts = ipa.ts();
            let mut p = Vec::with_capacity(samples);
            let (u, y) = match self.input {
                // The experimenter's rule watches the plant: the designed input and the record come from
                // one run, the pressures observed at each sample before its command is applied.
                InputSpec::Staircase => staircase_experiment_observed(
                    &mut Stoppable::new(&mut ipa, &self.cancel),
                    &StaircaseDesign::default(),
                    samples,
                    self.amplitude,
                    self.seed,
                    |s: &Stoppable<Ipa>| p.push(s.inner().pressures_pa()),
                )?,
                InputSpec::Calibration => calibration_experiment_observed(
                    &mut Stoppable::new(&mut ipa, &self.cancel),
                    samples,
                    self.amplitude,
                    self.seed,
                    |s: &Stoppable<Ipa>| p.push(s.inner().pressures_pa()),
                )?,
                _ => {
                    let u = crate::generate(&self.input, samples, ts, self.amplitude, self.seed)?;
                    self.check_applied(Some(&u))?;
                    let rec = record_input(&mut ipa, u, &self.cancel)?;
                    p = rec.pressures.unwrap_or_default();
                    (rec.u, rec.y)
                }
            };
            Record {
                u,
                y,
                pressures: Some(p),
                ts,
            }
        };
        Ok(Record {
            y: crate::input::add_noise(&rec.y, self.noise_std, self.seed),
            ..rec
        })
    }
}

/// Applies the command u(k) to the physics plant from its current state, recording the position y(k)
/// (mm, encoder-quantised) and the chamber pressures [p_a, p_b] (Pa) at each sample before u(k) is
/// applied: one open-loop run with everything the IPA measures (`simulate`, the calibrated twin of
/// `reproduce`). The run polls `cancel` ([`Stoppable`]) and ends with
/// `IpaError::Sysid(SysidError::Cancelled)` once it is requested.
pub fn record_input(plant: &mut Ipa, u: Vec<f64>, cancel: &Stop) -> Result<Record, IpaError> {
    let mut plant = Stoppable::new(plant, cancel);
    let mut y = Vec::with_capacity(u.len());
    let mut p = Vec::with_capacity(u.len());
    for (k, &uk) in u.iter().enumerate() {
        y.push(plant.output());
        p.push(plant.inner().pressures_pa());
        plant.step(uk).map_err(|e| {
            IpaError::Sysid(SysidError::from(e).context(&format!("simulating sample {k}")))
        })?;
    }
    Ok(Record {
        u,
        y,
        pressures: Some(p),
        ts: plant.ts(),
    })
}
