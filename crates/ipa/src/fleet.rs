//! A simulated fleet of actuators for fleet monitoring (`ipa-sysid simulate --fleet N --worn FRACTION`):
//! N physics IPAs whose parameters are drawn around the defaults, each recording one identification
//! experiment per monitoring window, a chosen fraction of them with valves that wear from window to
//! window.
//!
//! - **Actuators.** Actuator i is the plant [`perturbed_plant`] draws with its own seed, within
//!   ±[`FleetDesign::spread`] (default ±10 %) of every default parameter of the calibration's free set
//!   (valve conductances and delays, friction, mass, dead volumes, external force): nominally identical
//!   axes with the scatter of a production run.
//! - **Windows.** Each actuator records [`FleetDesign::windows`] windows of
//!   [`FleetDesign::samples_per_window`] samples (a periodic diagnostic run: the staircase experiment of
//!   `simulate`, a new random staircase each window, from rest at mid-stroke y0 = 100 mm, Ts = 10 ms).
//!   Times run on across windows: window w, sample k is at t = (w N_w + k) Ts.
//! - **Wear.** A worn actuator's valves change linearly with the window index w = 0 … W − 1, reaching at
//!   the last window: the opening delay lengthened by [`Wear::delay_added_ms`] (default +1 ms on
//!   0.4 ms, a spool that sticks: the shortest pulse that opens the valve grows and every pulse is
//!   shortened by it, so the identified deadzone widens, by about 65 counts per ms) and both sonic conductances reduced by the fraction
//!   [`Wear::conductance_loss`] (default 40 %: a clogged, sticking spool; the identified slopes m_l,
//!   m_r drop). Wear is slow beside a window (days against 20 s), so it is constant within a window. A
//!   healthy actuator keeps its parameters in every window.
//! - **Which are worn.** Exactly round(N · fraction) actuators, chosen by a seeded shuffle.
//!
//! Everything is a function of the seed: the same [`FleetDesign`] gives bit-identical records.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use sysid_core::{Setting, SysidError};

use crate::calibrate::study::perturbed_plant;
use crate::{Experiment, InputSpec, IpaError, PlantConfig, Record};

/// Largest fleet the simulator accepts (records are kept in memory one actuator at a time, but the
/// output grows with N × windows × samples).
pub const MAX_ACTUATORS: usize = 100_000;
/// Largest number of windows per actuator.
pub const MAX_WINDOWS: usize = 1000;
/// Largest fleet record, N × windows × samples (about 5 GB of Parquet, 5 bytes a sample measured, and
/// two hours of two cores at the plant's speed; audit s12: 100 000 × 1000 × 2000 = 2·10¹¹ samples
/// started without a word).
pub const MAX_FLEET_SAMPLES: u64 = 1_000_000_000;
/// Fewest samples of a window: one monitoring identification of the deadzone + ARX model (7
/// parameters) needs far more rows than parameters (a window of 1 sample cannot be identified).
pub const MIN_WINDOW_SAMPLES: usize = 100;

/// How a worn valve changes by the last window (linearly in the window index from none at window 0).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Wear {
    /// Added to the opening delay at the last window, ms.
    pub delay_added_ms: f64,
    /// Fraction by which both sonic conductances have dropped at the last window, in [0, 1).
    pub conductance_loss: f64,
}

impl Default for Wear {
    fn default() -> Self {
        Wear {
            delay_added_ms: 1.0,
            conductance_loss: 0.4,
        }
    }
}

/// The fleet to simulate (the flags of `simulate --fleet`).
#[derive(Debug, Clone, PartialEq)]
pub struct FleetDesign {
    /// N: number of actuators (`--fleet`).
    pub actuators: usize,
    /// Fraction of actuators with wearing valves, in [0, 1] (`--worn`).
    pub worn_fraction: f64,
    /// Windows per actuator (`--windows`, ≥ 3 so that a trend has a residual).
    pub windows: usize,
    /// Samples per window (`--samples`).
    pub samples_per_window: usize,
    /// Relative spread of the drawn parameters around the defaults.
    pub spread: f64,
    /// The wear of a worn actuator.
    pub wear: Wear,
    /// Seed of everything random (`--seed`).
    pub seed: u64,
}

impl Default for FleetDesign {
    fn default() -> Self {
        FleetDesign {
            actuators: 100,
            worn_fraction: 0.05,
            windows: 10,
            samples_per_window: crate::experiment::DEFAULT_SAMPLES,
            spread: 0.1,
            wear: Wear::default(),
            seed: 0,
        }
    }
}

/// One window of one actuator.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetWindow {
    /// The actuator, 0 … N − 1.
    pub actuator_id: usize,
    /// The window, 0 … W − 1.
    pub window: usize,
    /// Time of the window's first sample, s.
    pub t0_s: f64,
    /// The recorded experiment.
    pub record: Record,
}

fn bad(flag: &'static str, value: impl std::fmt::Display, expected: &str) -> IpaError {
    IpaError::Sysid(SysidError::setting(Setting::Other(flag), value, expected))
}

/// SplitMix64's finaliser: a seed for stream `a`, sub-stream `b` of the fleet seed.
fn mix(seed: u64, a: u64, b: u64) -> u64 {
    let mut z = seed
        .wrapping_add(a.wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add(b.wrapping_mul(0xD1B5_4A32_D192_ED03));
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl FleetDesign {
    /// Checks every setting before anything is simulated; errors name the flag.
    pub fn check(&self) -> Result<(), IpaError> {
        if self.actuators == 0 || self.actuators > MAX_ACTUATORS {
            return Err(bad(
                "--fleet",
                self.actuators,
                &format!("1..={MAX_ACTUATORS} actuators"),
            ));
        }
        if !(self.worn_fraction.is_finite() && (0.0..=1.0).contains(&self.worn_fraction)) {
            return Err(bad(
                "--worn",
                self.worn_fraction,
                "a fraction of the fleet in [0, 1]",
            ));
        }
        if self.windows < 3 || self.windows > MAX_WINDOWS {
            return Err(bad(
                "--windows",
                self.windows,
                &format!("3..={MAX_WINDOWS} windows per actuator (a trend needs a residual)"),
            ));
        }
        crate::input::check_samples(self.samples_per_window)?;
        if self.samples_per_window < MIN_WINDOW_SAMPLES {
            return Err(bad(
                "--samples",
                self.samples_per_window,
                &format!(
                    "at least {MIN_WINDOW_SAMPLES} samples per window (each window is one monitoring \
                     identification)"
                ),
            ));
        }
        let total = (self.actuators as u64)
            .saturating_mul(self.windows as u64)
            .saturating_mul(self.samples_per_window as u64);
        if total > MAX_FLEET_SAMPLES {
            return Err(bad(
                "--fleet × --windows × --samples",
                total,
                &format!(
                    "at most {MAX_FLEET_SAMPLES} samples in all (about 5 bytes of Parquet each; fewer \
                     actuators, windows or samples per window)"
                ),
            ));
        }
        if !(self.spread.is_finite() && (0.0..0.5).contains(&self.spread)) {
            return Err(bad("spread", self.spread, "a relative spread in [0, 0.5)"));
        }
        let w = self.wear;
        if !(w.delay_added_ms.is_finite() && (0.0..=5.0).contains(&w.delay_added_ms)) {
            return Err(bad("wear delay", w.delay_added_ms, "0..=5 ms"));
        }
        if !(w.conductance_loss.is_finite() && (0.0..0.9).contains(&w.conductance_loss)) {
            return Err(bad(
                "wear conductance loss",
                w.conductance_loss,
                "a fraction in [0, 0.9)",
            ));
        }
        Ok(())
    }

    /// Whether each actuator is worn: exactly round(N · fraction) of them, chosen by a shuffle seeded
    /// by the fleet seed.
    pub fn worn(&self) -> Vec<bool> {
        let n = self.actuators;
        let k = ((n as f64) * self.worn_fraction).round() as usize;
        let mut ids: Vec<usize> = (0..n).collect();
        ids.shuffle(&mut ChaCha8Rng::seed_from_u64(mix(self.seed, u64::MAX, 0)));
        let mut worn = vec![false; n];
        for &i in ids.iter().take(k.min(n)) {
            worn[i] = true;
        }
        worn
    }

    /// The plant of actuator `id` in window `window` (worn or not).
    pub fn config(&self, id: usize, window: usize, worn: bool) -> PlantConfig {
        let mut cfg = perturbed_plant(mix(self.seed, id as u64, 0), self.spread);
        if worn {
            let x = window as f64 / (self.windows - 1).max(1) as f64;
            let v = &mut cfg.valve;
            v.opening_delay_ms += x * self.wear.delay_added_ms;
            let keep = 1.0 - x * self.wear.conductance_loss;
            v.supply_conductance_dm3_s_bar *= keep;
            v.exhaust_conductance_dm3_s_bar *= keep;
        }
        cfg
    }

    /// The windows of actuator `id` (worn or not), in time order.
    pub fn actuator(&self, id: usize, worn: bool) -> Result<Vec<FleetWindow>, IpaError> {
        self.check()?;
        (0..self.windows)
            .map(|w| {
                let exp = Experiment {
                    input: InputSpec::Staircase,
                    samples: Some(self.samples_per_window),
                    seed: mix(self.seed, id as u64, 1 + w as u64),
                    ..Experiment::default()
                };
                let record = exp.run_with_config(self.config(id, w, worn))?;
                let t0_s = (w * self.samples_per_window) as f64 * record.ts; // t = (w N_w + k) Ts
                Ok(FleetWindow {
                    actuator_id: id,
                    window: w,
                    t0_s,
                    record,
                })
            })
            .collect()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    // round(20 · 0.25) = 5 worn, whatever the seed; the same seed chooses the same ones.
    #[test]
    fn exactly_round_n_times_fraction_are_worn() {
        for seed in 0..5 {
            let d = FleetDesign {
                actuators: 20,
                worn_fraction: 0.25,
                seed,
                ..FleetDesign::default()
            };
            assert_eq!(d.worn().iter().filter(|w| **w).count(), 5);
            assert_eq!(d.worn(), d.worn());
        }
    }

    // A worn valve reaches the full wear at the last window and none at the first; a healthy one never
    // changes.
    #[test]
    fn wear_is_linear_from_none_to_full() {
        let d = FleetDesign::default();
        let (first, last) = (d.config(3, 0, true), d.config(3, d.windows - 1, true));
        let healthy = d.config(3, d.windows - 1, false);
        assert_eq!(first, healthy);
        let dv = last.valve.opening_delay_ms - first.valve.opening_delay_ms;
        assert!((dv - 1.0).abs() < 1e-12);
        let ratio =
            last.valve.supply_conductance_dm3_s_bar / first.valve.supply_conductance_dm3_s_bar;
        assert!((ratio - 0.6).abs() < 1e-12);
    }

    #[test]
    fn settings_out_of_range_name_their_flag() {
        let e = FleetDesign {
            worn_fraction: 1.5,
            ..FleetDesign::default()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("--worn"), "{e}");
        let e = FleetDesign {
            actuators: 0,
            ..FleetDesign::default()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(e.contains("--fleet"), "{e}");
        // Audit s12: windows too short to identify, and a fleet record of 2·10¹¹ samples.
        let e = FleetDesign {
            samples_per_window: 1,
            ..FleetDesign::default()
        }
        .check()
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("--samples = 1") && e.contains("at least 100"),
            "{e}"
        );
        let big = FleetDesign {
            actuators: MAX_ACTUATORS,
            windows: MAX_WINDOWS,
            samples_per_window: 2000,
            ..FleetDesign::default()
        };
        let e = big.check().unwrap_err().to_string();
        assert!(
            e.contains("200000000000") && e.contains("at most 1000000000"),
            "{e}"
        );
        // The bound itself is allowed: 500 000 000 samples.
        assert!(FleetDesign {
            actuators: 500,
            windows: 500,
            samples_per_window: 2000,
            ..FleetDesign::default()
        }
        .check()
        .is_ok());
    }
}
