//! Change detection on the estimator's normalised prediction errors (issue 15 part 4): a one-sided
//! CUSUM on z(k) = ε(k)² / σ̂².
//!
//! While the valve and the cylinder do not change, the a-priori errors ε(k) of a converged estimator
//! ([`crate::HammersteinRls::update`] with ρ = 1) are close to white noise of variance σ², so z(k) is
//! χ²₁-distributed with mean 1. When the deadzone or a slope changes, the model no longer predicts the
//! position and ε grows (a bias m Δb on the affected branch): z has a larger mean. The detector
//!
//! ```text
//! g(0) = 0,   g(k) = max(0, g(k−1) + z(k) − ν),   alarm when g(k) > h
//! ```
//!
//! (Page's CUSUM; ν the drift, h the threshold) accumulates that excess. σ̂² is the mean of ε² over a
//! calibration window after a warm-up (or given). Per sample: 4 flops (ε², × 1/σ̂², + , −) and a
//! comparison; size 8 floats/usizes (see [`Cusum`]).
//!
//! # False alarms and detection delay (χ²₁ statistic, white Gaussian ε, σ̂² = σ²)
//!
//! Average run length (ARL, samples to an alarm) from the Markov-chain approximation of Brook & Evans
//! (300 states; the test `run_length_matches_the_markov_chain` checks the method against simulation at
//! ν = 2, h = 6, where the ARL is 131):
//!
//! | ν | h | ARL without change | ARL at 2× error variance | at 4× | at 10× |
//! |---|---|---|---|---|---|
//! | 3 | 25 | 2.6 · 10⁶ | 621 | 22.6 | 5.6 |
//! | **3** | **30** (default) | **2.8 · 10⁷** (77 h at Ts = 0.01 s) | 1.3 · 10³ | 27.3 | 6.3 |
//! | 3 | 35 | 2.9 · 10⁸ | 2.8 · 10³ | 32.2 | 7.0 |
//!
//! So at the default a 50 000-sample record (8.3 min at 100 Hz) raises a false alarm with probability
//! about 50 000 / 2.8·10⁷ ≈ 0.2 %. An error of σ̂ misestimated by a factor c acts like a variance ratio
//! c² on both rows: calibrate on at least a few thousand samples (relative error √(2/M) of σ̂²).

use crate::{Error, Float};

/// What the detector did with a sample.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CusumStatus<F: Float> {
    /// In the warm-up: the error is ignored (the estimator is still converging).
    WarmUp,
    /// In the calibration window: ε² is accumulated into σ̂².
    Calibrating,
    /// Monitoring, no alarm: the current statistic g(k).
    Monitoring(F),
    /// g(k) > h at this sample or before (latched until [`Cusum::rearm`]): the statistic.
    Alarm(F),
}

/// Page's CUSUM on squared normalised prediction errors. Size: 5 floats and 3 `usize` (64 bytes for
/// f64 on a 64-bit target, 32 for f32 on a 32-bit one).
///
/// ```
/// use ipa_embedded::cusum::{Cusum, CusumStatus};
/// // σ² = 1 given, ν = 3, h = 30: errors of 4σ add 16 − 3 = 13 per sample and alarm at the third.
/// let mut d = Cusum::with_variance(1.0, 3.0, 30.0).unwrap();
/// assert_eq!(d.update(4.0).unwrap(), CusumStatus::Monitoring(13.0));
/// assert_eq!(d.update(4.0).unwrap(), CusumStatus::Monitoring(26.0));
/// assert_eq!(d.update(4.0).unwrap(), CusumStatus::Alarm(39.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cusum<F: Float> {
    drift: F,
    threshold: F,
    /// 1/σ̂² (0 until calibrated).
    inv_var: F,
    sum_sq: F,
    g: F,
    warmup: usize,
    calibration: usize,
    seen: usize,
}

impl<F: Float> Cusum<F> {
    /// Default drift ν = 3 and threshold h = 30 (ARL ≈ 2.8 · 10⁷ samples without change).
    pub const DEFAULT_DRIFT: f64 = 3.0;
    /// See [`Cusum::DEFAULT_DRIFT`].
    pub const DEFAULT_THRESHOLD: f64 = 30.0;

    /// A detector that ignores the first `warmup` errors, estimates σ̂² as the mean of ε² over the next
    /// `calibration` (≥ 1) errors, then monitors with drift ν > 1 and threshold h > 0.
    pub fn new(warmup: usize, calibration: usize, drift: F, threshold: F) -> Result<Self, Error> {
        check(drift, threshold)?;
        if calibration == 0 {
            return Err(Error::Setting);
        }
        Ok(Cusum {
            drift,
            threshold,
            inv_var: F::ZERO,
            sum_sq: F::ZERO,
            g: F::ZERO,
            warmup,
            calibration,
            seen: 0,
        })
    }

    /// A detector with a known error variance σ² (mm², > 0) that monitors from the first sample.
    pub fn with_variance(variance: F, drift: F, threshold: F) -> Result<Self, Error> {
        check(drift, threshold)?;
        if !(variance.is_finite() && variance > F::ZERO) {
            return Err(Error::Setting);
        }
        Ok(Cusum {
            drift,
            threshold,
            inv_var: F::ONE / variance,
            sum_sq: F::ZERO,
            g: F::ZERO,
            warmup: 0,
            calibration: 0,
            seen: 0,
        })
    }

    /// Feeds the prediction error ε(k) (mm). A non-finite ε gives [`Error::NotFinite`] and changes
    /// nothing.
    pub fn update(&mut self, eps: F) -> Result<CusumStatus<F>, Error> {
        if !eps.is_finite() {
            return Err(Error::NotFinite);
        }
        let sq = eps * eps;
        if self.inv_var == F::ZERO {
            // Warm-up and calibration (only for `new`).
            let k = self.seen;
            self.seen = self.seen.saturating_add(1);
            if k < self.warmup {
                return Ok(CusumStatus::WarmUp);
            }
            self.sum_sq += sq;
            if k + 1 - self.warmup < self.calibration {
                return Ok(CusumStatus::Calibrating);
            }
            let var = self.sum_sq / F::from_f64(self.calibration as f64);
            // An all-zero calibration (noise-free data) leaves the detector calibrating.
            if var > F::ZERO && var.is_finite() {
                self.inv_var = F::ONE / var;
            } else {
                self.sum_sq = F::ZERO;
                self.seen = self.warmup;
            }
            return Ok(CusumStatus::Calibrating);
        }
        if self.g > self.threshold {
            return Ok(CusumStatus::Alarm(self.g));
        }
        let g = self.g + sq * self.inv_var - self.drift;
        self.g = if g > F::ZERO { g } else { F::ZERO };
        Ok(if self.g > self.threshold {
            CusumStatus::Alarm(self.g)
        } else {
            CusumStatus::Monitoring(self.g)
        })
    }

    /// The statistic g(k).
    pub fn statistic(&self) -> F {
        self.g
    }

    /// σ̂² in mm² (`None` while calibrating).
    pub fn variance(&self) -> Option<F> {
        (self.inv_var > F::ZERO).then(|| F::ONE / self.inv_var)
    }

    /// Clears an alarm (g = 0) and keeps σ̂², e.g. after the estimator was restarted on the new valve.
    pub fn rearm(&mut self) {
        self.g = F::ZERO;
    }
}

fn check<F: Float>(drift: F, threshold: F) -> Result<(), Error> {
    if drift.is_finite() && drift > F::ONE && threshold.is_finite() && threshold > F::ZERO {
        Ok(())
    } else {
        Err(Error::Setting)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    // Warm-up 2, calibration 2 with ε = ±2 → σ̂² = 4; then ε = 6 gives z = 9, g = 9 − 3 = 6.
    #[test]
    fn calibrates_then_accumulates_the_excess_of_the_normalised_square() {
        let mut d = Cusum::new(2, 2, 3.0, 30.0).unwrap();
        assert_eq!(d.update(100.0).unwrap(), CusumStatus::WarmUp);
        assert_eq!(d.update(-100.0).unwrap(), CusumStatus::WarmUp);
        assert_eq!(d.update(2.0).unwrap(), CusumStatus::Calibrating);
        assert_eq!(d.variance(), None);
        assert_eq!(d.update(-2.0).unwrap(), CusumStatus::Calibrating);
        assert_eq!(d.variance(), Some(4.0));
        assert_eq!(d.update(6.0).unwrap(), CusumStatus::Monitoring(6.0));
        assert_eq!(d.update(0.0).unwrap(), CusumStatus::Monitoring(3.0));
        assert_eq!(d.update(0.0).unwrap(), CusumStatus::Monitoring(0.0));
        assert_eq!(
            d.update(0.0).unwrap(),
            CusumStatus::Monitoring(0.0),
            "g never goes below 0"
        );
        assert_eq!(d.update(f64::NAN).unwrap_err(), Error::NotFinite);
    }

    #[test]
    fn alarm_latches_until_rearmed_and_bad_settings_are_refused() {
        let mut d = Cusum::with_variance(1.0f32, 3.0, 10.0).unwrap();
        assert!(matches!(d.update(4.0).unwrap(), CusumStatus::Alarm(_)));
        assert!(matches!(d.update(0.0).unwrap(), CusumStatus::Alarm(_)));
        d.rearm();
        assert_eq!(d.update(0.0).unwrap(), CusumStatus::Monitoring(0.0));
        assert!(
            Cusum::with_variance(1.0, 1.0, 10.0).is_err(),
            "ν ≤ 1 alarms on noise alone"
        );
        assert!(Cusum::with_variance(0.0, 3.0, 10.0).is_err());
        assert!(Cusum::<f64>::new(0, 0, 3.0, 10.0).is_err());
    }
}
