//! The recovery study of the calibration: plants whose parameters are drawn around the defaults (the
//! truth is known), a record of each simulated with the calibration design, calibration from the
//! default plant, and the free-run fit on a fresh record of a different input design (the staircase).
//!
//! Used by the test `tests/calibrate.rs` (a reduced study) and `ipa-sysid calibrate --study N` (full).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Calibrated, Calibration, CalibrationWarning, Parameter};
use crate::{Experiment, InputSpec, IpaError, PlantConfig, Record};

/// Settings of a study.
#[derive(Debug, Clone)]
pub struct Study {
    /// Number of plants.
    pub plants: usize,
    /// Relative half-width of the uniform draw around each default (0.3: ±30 %).
    pub spread: f64,
    /// Samples of the estimation record (calibration design).
    pub estimation_samples: usize,
    /// Samples of the validation record (staircase).
    pub validation_samples: usize,
    /// First seed (plant i uses seed + i).
    pub seed: u64,
    /// The calibration settings (the start is the default plant).
    pub calibration: Calibration,
}

impl Default for Study {
    fn default() -> Self {
        Study {
            plants: 20,
            spread: 0.3,
            estimation_samples: 3000,
            validation_samples: 2000,
            seed: 1,
            calibration: Calibration::default(),
        }
    }
}

/// One plant of a study.
#[derive(Debug, Clone)]
pub struct StudyCase {
    /// The seed of the plant and of its records.
    pub seed: u64,
    /// The true plant.
    pub truth: PlantConfig,
    /// The calibration.
    pub calibrated: Calibrated,
    /// Relative error |estimate − truth| / |truth| of every free parameter (external force: relative
    /// to the true static friction, as it may be near 0), in the order of the free set.
    pub relative_errors: Vec<f64>,
    /// Whether the calibration reported each free parameter as determined (no warning naming it, and
    /// no warning that the search stayed above the quantisation floor).
    pub determined: Vec<bool>,
    /// Wall-clock time of the calibration, s.
    pub seconds: f64,
}

/// A plant with the free parameters of the default drawn uniformly within ±spread of their defaults
/// (the external force, 0 by default, uniformly in ±10 spread N), F_c kept at most 0.95 F_s.
pub fn perturbed_plant(seed: u64, spread: f64) -> PlantConfig {
    perturbed_from(&PlantConfig::default(), seed, spread)
}

/// [`perturbed_plant`] around `base` instead of the defaults (a twin's variants for `ipa-sysid tune`):
/// each free parameter of `base` drawn uniformly within ±spread of its value, the external force
/// within ±10 spread N of it, F_c kept at most 0.95 F_s.
pub fn perturbed_from(base: &PlantConfig, seed: u64, spread: f64) -> PlantConfig {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut cfg = base.clone();
    for p in Parameter::ALL {
        if p == Parameter::ExternalForce {
            let f = p.get(&cfg) + rng.gen_range(-10.0 * spread..=10.0 * spread);
            p.set(&mut cfg, f);
        } else {
            let v = p.get(&cfg) * (1.0 + rng.gen_range(-spread..=spread));
            p.set(&mut cfg, v);
        }
    }
    cfg.friction.coulomb_n = cfg.friction.coulomb_n.min(0.95 * cfg.friction.static_n);
    cfg
}

/// Simulates `samples` of `input` on `cfg` with `seed` (mid-stroke start, encoder quantisation of
/// the plant, no added noise).
pub fn record(
    cfg: &PlantConfig,
    input: InputSpec,
    samples: usize,
    seed: u64,
) -> Result<Record, IpaError> {
    Experiment {
        input,
        samples: Some(samples),
        seed,
        ..Experiment::default()
    }
    .run_with_config(cfg.clone())
}

/// Relative error of an estimate (F_ext relative to the true F_s).
pub fn relative_error(p: Parameter, estimate: f64, truth: &PlantConfig) -> f64 {
    let t = p.get(truth);
    if p == Parameter::ExternalForce {
        (estimate - t).abs() / truth.friction.static_n
    } else {
        (estimate - t).abs() / t.abs()
    }
}

impl Study {
    /// Runs plant `i` of the study.
    pub fn case(&self, i: usize) -> Result<StudyCase, IpaError> {
        let seed = self.seed + i as u64;
        let truth = perturbed_plant(seed, self.spread);
        let est = record(
            &truth,
            InputSpec::Calibration,
            self.estimation_samples,
            seed,
        )?;
        let val = record(
            &truth,
            InputSpec::Staircase,
            self.validation_samples,
            seed + 1000,
        )?;
        let started = std::time::Instant::now();
        let calibrated = self.calibration.fit(&est, Some(&val))?;
        let seconds = started.elapsed().as_secs_f64();
        let relative_errors = calibrated
            .estimates
            .iter()
            .map(|e| relative_error(e.parameter, e.value, &truth))
            .collect();
        let determined = calibrated
            .estimates
            .iter()
            .map(|e| {
                !calibrated.warnings.iter().any(|w| match w {
                    CalibrationWarning::NotDetermined { parameter, .. }
                    | CalibrationWarning::AtBound { parameter } => *parameter == e.parameter,
                    CalibrationWarning::Correlated { a, b, .. } => {
                        *a == e.parameter || *b == e.parameter
                    }
                    CalibrationWarning::AboveFloor { .. }
                    | CalibrationWarning::PoorFit { .. }
                    | CalibrationWarning::NoBetterThanMean { .. } => true,
                    _ => false,
                })
            })
            .collect();
        Ok(StudyCase {
            seed,
            truth,
            calibrated,
            relative_errors,
            determined,
            seconds,
        })
    }

    /// Runs every plant of the study, in order.
    pub fn run(&self) -> Result<Vec<StudyCase>, IpaError> {
        (0..self.plants).map(|i| self.case(i)).collect()
    }
}
