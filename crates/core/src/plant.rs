//! The [`Plant`] trait: anything that takes a command u(k) and returns a measured position y(k).
//!
//! The physics IPA simulator (crate `ipa`), the paper's model and any identified [`Model`](crate::Model)
//! all sit behind this trait, so that experiments, open-loop tests and closed-loop control run on any of them.
//!
//! Timing convention (the same as a data logger's): at sample k the plant's output y(k) is read, then the
//! command u(k) is applied for one sampling period Ts, after which y(k+1) is read. A data record therefore
//! has y(k+1) depend on u(k): a pure delay nk >= 1 in ARX terms.

use crate::{PlantError, SysidError};

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
        })?;
    }
    Ok(y)
}
