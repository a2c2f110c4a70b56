//! The [`Plant`] trait: anything that takes a command u(k) and returns a measured position y(k).
//!
//! The physics IPA simulator (crate `ipa`), the paper's model and any identified [`Model`](crate::Model)
//! all sit behind this trait, so that experiments, open-loop tests and closed-loop control run on any of them.
//!
//! Timing convention (the same as a data logger's): at sample k the plant's output y(k) is read, then the
//! command u(k) is applied for one sampling period Ts, after which y(k+1) is read. A data record therefore
//! has y(k+1) depend on u(k): a pure delay nk >= 1 in ARX terms.

use crate::{PlantError, Stop, SysidError};

/// A sampled single-input single-output plant: command u (PWM counts, [-255, 255] for the IPA) in,
/// position y (mm) out, one call per sampling period Ts.
pub trait Plant {
    /// Sampling period Ts in s.
    fn ts(&self) -> f64;

    /// The output y(k) at the current sample, in mm (for the IPA: the encoder reading).
    fn output(&self) -> f64;

    /// Applies the command u(k) for one sampling period and returns the next output y(k+1) in mm.
    ///
    /// Fails when the plant's state becomes non-finite (for example an unstable identified model).
    fn step(&mut self, u: f64) -> Result<f64, PlantError>;

    /// Puts the plant back at rest with its output at `y0_mm` (clamped to what the plant can reach).
    fn reset(&mut self, y0_mm: f64);

    /// A short human-readable name for reports ("physics IPA", "paper model", ...).
    fn name(&self) -> String;
}

/// Runs `plant` open loop over the commands `u` and returns the outputs y(0..=N-1) that a data logger
/// would record beside them: y(0) is the output before u(0) is applied. A numerical failure of the plant
/// names the sample at which it happened.
pub fn run_open_loop(plant: &mut dyn Plant, u: &[f64]) -> Result<Vec<f64>, SysidError> {
    let mut y = Vec::with_capacity(u.len());
    for (k, &uk) in u.iter().enumerate() {
        y.push(plant.output());
        plant.step(uk).map_err(|e| match e {
            PlantError::Diverged(m) => {
                SysidError::Numerical(format!("{m} (while applying u({k}) = {uk})"))
            }
            PlantError::Cancelled => SysidError::Cancelled,
        })?;
    }
    Ok(y)
}

/// A plant whose steps poll a [`Stop`]: any run of it (open loop, a designed experiment, a closed
/// loop) ends with [`PlantError::Cancelled`] within [`crate::stop::SAMPLES_PER_POLL`] samples of the
/// caller's [`Stop::request`] (the Python binding's Ctrl-C). Everything else is the wrapped plant's.
///
/// ```
/// use sysid_core::{plant::Stoppable, Model, ModelPlant, Plant, PlantError, Stop};
/// let mut model = ModelPlant::new(Model::paper(), "paper").unwrap();
/// let stop = Stop::new();
/// let u = vec![10.0; 10_000];
/// let y = sysid_core::run_open_loop(&mut Stoppable::new(&mut model, &stop), &u).unwrap();
/// assert_eq!(y.len(), 10_000);
/// stop.request(); // from another thread, in practice
/// let mut plant = Stoppable::new(&mut model, &stop);
/// assert_eq!(plant.step(10.0), Err(PlantError::Cancelled));
/// ```
pub struct Stoppable<'a, P: Plant + ?Sized> {
    plant: &'a mut P,
    stop: &'a Stop,
    /// Steps taken through this wrapper (the poll's counter).
    steps: usize,
}

impl<'a, P: Plant + ?Sized> Stoppable<'a, P> {
    /// `plant` stepped under `stop`.
    pub fn new(plant: &'a mut P, stop: &'a Stop) -> Self {
        Stoppable {
            plant,
            stop,
            steps: 0,
        }
    }

    /// The wrapped plant (what else it measures: the physics plant's pressures).
    pub fn inner(&self) -> &P {
        self.plant
    }
}

impl<P: Plant + ?Sized> Plant for Stoppable<'_, P> {
    fn ts(&self) -> f64 {
        self.plant.ts()
    }
    fn output(&self) -> f64 {
        self.plant.output()
    }
    /// Polls the stop every [`crate::stop::SAMPLES_PER_POLL`]-th step (the first included), then
    /// steps the plant.
    fn step(&mut self, u: f64) -> Result<f64, PlantError> {
        let k = self.steps;
        self.steps += 1;
        self.stop.every(k).map_err(|_| PlantError::Cancelled)?;
        self.plant.step(u)
    }
    fn reset(&mut self, y0_mm: f64) {
        self.plant.reset(y0_mm)
    }
    fn name(&self) -> String {
        self.plant.name()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stop::SAMPLES_PER_POLL;
    use crate::{Model, ModelPlant};

    // A stop requested before the run ends it at its first step; one requested during the run ends
    // it within SAMPLES_PER_POLL steps (the poll is a counter: step k polls when k % period == 0).
    #[test]
    fn a_stoppable_run_ends_within_one_poll_period_of_the_request() {
        let mut model = ModelPlant::new(Model::paper(), "paper").unwrap();
        let stop = Stop::new();
        stop.request();
        let mut plant = Stoppable::new(&mut model, &stop);
        let u = vec![10.0; 3 * SAMPLES_PER_POLL];
        assert!(matches!(
            run_open_loop(&mut plant, &u),
            Err(SysidError::Cancelled)
        ));

        let stop = Stop::new();
        let mut plant = Stoppable::new(&mut model, &stop);
        for _ in 0..SAMPLES_PER_POLL + 5 {
            plant.step(1.0).unwrap();
        }
        stop.request();
        // Steps SAMPLES_PER_POLL + 5 .. 2 SAMPLES_PER_POLL - 1 do not poll; step 2 SAMPLES_PER_POLL does.
        for _ in SAMPLES_PER_POLL + 5..2 * SAMPLES_PER_POLL {
            plant.step(1.0).unwrap();
        }
        assert_eq!(plant.step(1.0), Err(PlantError::Cancelled));
    }

    // Never requested, the wrapper is the plant: the same outputs step for step.
    #[test]
    fn a_stoppable_plant_never_stopped_gives_the_plants_outputs() {
        let u: Vec<f64> = (0..500)
            .map(|k| ((k / 50) % 2) as f64 * 40.0 - 20.0)
            .collect();
        let mut a = ModelPlant::new(Model::paper(), "paper").unwrap();
        let mut b = ModelPlant::new(Model::paper(), "paper").unwrap();
        let stop = Stop::new();
        let direct = run_open_loop(&mut a, &u).unwrap();
        let wrapped = run_open_loop(&mut Stoppable::new(&mut b, &stop), &u).unwrap();
        assert_eq!(direct, wrapped);
    }
}
