//! The paper's PI position controller with saturation and anti-windup:
//! e(k) = r(k) − y(k) (mm), v(k) = Kp e(k) + I(k−1) + Ki Ts e(k), u(k) = sat(v(k)) to ±u_max counts.
//!
//! The integral is the backward-Euler form I(k) = Ki Ts Σ_{j≤k} e(j) (Ki in counts/(mm·s); the form
//! `control`'s `IntegralForm::Scaled` uses and the one the paper's Table V is compatible with, see
//! docs/control.md). The same operations as `control::PiController::step`, so f64 results are equal to
//! it bit for bit.

use crate::{Error, Float};

/// What the integral does while the command is saturated.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum AntiWindup<F: Float> {
    /// The integral always accumulates (the paper's plain PI).
    None,
    /// Conditional integration: e(k) is not integrated when v(k) saturates and e(k) v(k) > 0.
    Clamping,
    /// Back-calculation: I(k) = I(k−1) + Ki Ts e(k) + (Ts / Tt)(u(k) − v(k)), Tt in s (> 0).
    BackCalculation {
        /// Tt: tracking time constant in s.
        tt_s: F,
    },
}

/// A PI controller: settings and the integral state I (counts).
///
/// Size: 7 floats (the 5 below and the plausibility range [y_min, y_max]) and the anti-windup enum
/// (tag and Tt): 72 bytes for f64, 36 for f32 (test `state_sizes`; 56 and 28 before the range).
/// Cost per sample: 6 flops (+3 for back-calculation), one clamp, four comparisons for the range.
///
/// ```
/// use ipa_embedded::{AntiWindup, Pi};
/// // Kp = 14, Ki = 1, Ts = 0.01 s: u(0) = 14·1 + 1·0.01·1 = 14.01 counts for e = 1 mm.
/// let mut pi = Pi::new(14.0f64, 1.0, 0.01, 255.0, AntiWindup::Clamping).unwrap();
/// assert!((pi.step(1.0, 0.0).unwrap() - 14.01).abs() < 1e-12);
/// ```
///
/// # A wild sample and the plausibility range
///
/// With back-calculation, one finite but wild position sample y (an encoder glitch, a unit slip)
/// winds the integral: the update adds (Ts/Tt)(u − v) with v ≈ Kp (r − y), so a glitch at a
/// distance G mm (G ≫ |r|, e ≈ G) moves I by about (Ts/Tt)(Ki Tt − Ki Ts − Kp) G counts. From there
/// it recovers in two phases: while the command is saturated I decays towards the limit by
/// (1 − Ts/Tt) per sample (about Tt ln(|I|/u_max) s), then it climbs back by Ki Ts |e| per sample
/// (up to u_max/(Ki |e|) s for a remaining error e). Audit s31 M-6 (Kp = 14, Ki = 1, Tt = 14 s,
/// Ts = 0.01 s, y held 0.1 mm short of r): a reverse command for 54.6 s after G = 1e6 mm, 45 min
/// after 1e10 mm, 3.3 h after 1e300 mm. [`with_range`](Self::with_range)
/// sets a plausibility range (the stroke, with a margin): a sample with r or y outside it is refused
/// with [`Error::OutOfRange`] and leaves the state unchanged, so the caller holds its previous
/// command (or goes to its safe state) and the next plausible sample runs as if the wild one had not
/// been given. Without a range every finite sample is taken (the law of the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pi<F: Float> {
    kp: F,
    /// g = Ki Ts: the gain that multiplies e(k) in the integral update.
    g: F,
    ts: F,
    u_max: F,
    anti_windup: AntiWindup<F>,
    integral: F,
    /// The plausible r and y ([`with_range`](Self::with_range); none by default).
    range: Range<F>,
}

/// A plausibility range [y_min, y_max] (mm) for a controller's set-point r and measured position y
/// (audit s31 M-6) and the estimator's position samples (audit s33 H-2): the one check of
/// [`Pi::with_range`], [`PositionController::with_range`](crate::PositionController::with_range) and
/// [`HammersteinRls::with_range`](crate::HammersteinRls::with_range). Unbounded (±∞) when none was
/// set, which lets every finite sample through.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Range<F> {
    /// y_min: the smallest plausible r or y, mm (−∞: no range).
    lo: F,
    /// y_max: the largest plausible r or y, mm (+∞: no range).
    hi: F,
}

impl<F: Float> Range<F> {
    /// No range: every finite sample is plausible.
    pub(crate) fn none() -> Self {
        Range {
            lo: -F::INFINITY,
            hi: F::INFINITY,
        }
    }

    /// [y_min, y_max]; not finite, or y_min ≥ y_max, gives [`Error::Setting`].
    pub(crate) fn new(y_min_mm: F, y_max_mm: F) -> Result<Self, Error> {
        if !(y_min_mm.is_finite() && y_max_mm.is_finite() && y_min_mm < y_max_mm) {
            return Err(Error::Setting);
        }
        Ok(Range {
            lo: y_min_mm,
            hi: y_max_mm,
        })
    }

    /// The range set, `None` when none was.
    pub(crate) fn get(&self) -> Option<(F, F)> {
        self.lo.is_finite().then_some((self.lo, self.hi))
    }

    /// True when y_min ≤ v ≤ y_max (always for a finite v without a range).
    pub(crate) fn contains(&self, v: F) -> bool {
        self.lo <= v && v <= self.hi
    }

    /// y_max − y_min (mm), `None` when no range was set.
    pub(crate) fn span(&self) -> Option<F> {
        self.get().map(|(lo, hi)| hi - lo)
    }

    /// [`Error::OutOfRange`] when r or y lies outside (bounds included as plausible).
    pub(crate) fn check(&self, r_mm: F, y_mm: F) -> Result<(), Error> {
        if self.contains(r_mm) && self.contains(y_mm) {
            Ok(())
        } else {
            Err(Error::OutOfRange)
        }
    }
}

impl<F: Float> Pi<F> {
    /// A controller with Kp (counts/mm), Ki (counts/(mm·s)), Ts (s, > 0), u_max (counts, > 0; 255
    /// for the IPA's PWM) and an anti-windup scheme. Gains beyond ±[`MAX_GAIN`](crate::position::MAX_GAIN)
    /// (or not finite), Ts outside [`MIN_TS_S`](crate::position::MIN_TS_S) to
    /// [`MAX_TS_S`](crate::MAX_TS_S) (the tuned controller's range: a subnormal Ts or one of 1e300 s
    /// was taken here, audit s28 L-4), u_max ≤ 0 or beyond [`MAX_COMMAND`](crate::position::MAX_COMMAND),
    /// or Tt ≤ Ts/2 (the back-calculation would diverge) give [`Error::Setting`].
    pub fn new(kp: F, ki: F, ts: F, u_max: F, anti_windup: AntiWindup<F>) -> Result<Self, Error> {
        use crate::position::{MAX_COMMAND, MAX_GAIN, MIN_TS_S};
        let positive = |v: F| v.is_finite() && v > F::ZERO;
        let gain = |v: F| v.is_finite() && v.abs() <= F::from_f64(MAX_GAIN);
        if !(gain(kp)
            && gain(ki)
            && positive(ts)
            && ts >= F::from_f64(MIN_TS_S)
            && ts <= F::from_f64(crate::MAX_TS_S)
            && positive(u_max)
            && u_max <= F::from_f64(MAX_COMMAND))
        {
            return Err(Error::Setting);
        }
        // Tt <= Ts/2 makes the saturated back-calculation update I(k) = (1 − Ts/Tt) I(k−1) + … grow
        // without bound (as `control::PiSettings::build` refuses it).
        if let AntiWindup::BackCalculation { tt_s } = anti_windup {
            if !positive(tt_s) || tt_s + tt_s <= ts {
                return Err(Error::Setting);
            }
        }
        Ok(Pi {
            kp,
            g: ki * ts,
            ts,
            u_max,
            anti_windup,
            integral: F::ZERO,
            range: Range::none(),
        })
    }

    /// The same controller with a plausibility range [y_min, y_max] (mm) for the set-point r and the
    /// measured position y: from then on [`step`](Self::step) refuses a sample with r or y outside it
    /// with [`Error::OutOfRange`], the state unchanged (the struct documentation says why: one wild
    /// sample winds the back-calculation integral for minutes to hours). Typically the stroke with a
    /// margin for the sensor's noise, e.g. [−5, 205] mm for a 200 mm stroke. The integral is kept.
    /// y_min or y_max not finite, or y_min ≥ y_max, gives [`Error::Setting`].
    ///
    /// ```
    /// use ipa_embedded::{AntiWindup, Error, Pi};
    /// let bc = AntiWindup::BackCalculation { tt_s: 14.0 };
    /// let mut pi = Pi::new(14.0f64, 1.0, 0.01, 255.0, bc).unwrap().with_range(0.0, 200.0).unwrap();
    /// assert_eq!(pi.step(50.0, -1e6), Err(Error::OutOfRange)); // a glitch: refused
    /// assert_eq!(pi.integral(), 0.0);                          // and the state unchanged
    /// assert!(pi.step(50.0, 49.9).unwrap() > 0.0);
    /// ```
    pub fn with_range(self, y_min_mm: F, y_max_mm: F) -> Result<Self, Error> {
        Ok(Pi {
            range: Range::new(y_min_mm, y_max_mm)?,
            ..self
        })
    }

    /// The plausibility range [y_min, y_max] in mm, `None` when none was set
    /// ([`with_range`](Self::with_range)).
    pub fn range(&self) -> Option<(F, F)> {
        self.range.get()
    }

    /// One sample: set-point r(k) and measured position y(k) in mm → saturated command u(k) in counts.
    /// Non-finite inputs give [`Error::NotFinite`]; with a plausibility range
    /// ([`with_range`](Self::with_range)), r or y outside it gives [`Error::OutOfRange`]; a command
    /// u(k) or integral I(k) that would not be finite (finite but extreme inputs: e = r − y, Kp e or
    /// Ki Ts e overflowing, e.g. 0 · ∞ with Kp = 0) gives [`Error::Numerical`] (a guard of last
    /// resort: audit s19 M-1). Each leaves the integral unchanged: the caller holds its previous
    /// command or goes to its safe state.
    pub fn step(&mut self, r_mm: F, y_mm: F) -> Result<F, Error> {
        if !(r_mm.is_finite() && y_mm.is_finite()) {
            return Err(Error::NotFinite);
        }
        self.range.check(r_mm, y_mm)?;
        let before = self.integral;
        let u = self.law(r_mm, y_mm);
        if !(u.is_finite() && self.integral.is_finite()) {
            self.integral = before;
            return Err(Error::Numerical);
        }
        Ok(u)
    }

    /// [`step`](Self::step) for finite r and y, without the guard.
    fn law(&mut self, r_mm: F, y_mm: F) -> F {
        let e = r_mm - y_mm;
        let proportional = self.kp * e;
        let integrated = self.integral + self.g * e;
        let v = proportional + integrated;
        let u = v.clamp_to(-self.u_max, self.u_max);
        match self.anti_windup {
            AntiWindup::None => {
                self.integral = integrated;
                u
            }
            AntiWindup::Clamping => {
                if u != v && e * v > F::ZERO {
                    (proportional + self.integral).clamp_to(-self.u_max, self.u_max)
                } else {
                    self.integral = integrated;
                    u
                }
            }
            AntiWindup::BackCalculation { tt_s } => {
                self.integral = integrated + (self.ts / tt_s) * (u - v);
                u
            }
        }
    }

    /// The integral term I(k) in counts.
    pub fn integral(&self) -> F {
        self.integral
    }

    /// Back to rest: I = 0.
    pub fn reset(&mut self) {
        self.integral = F::ZERO;
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    // u(0) = Kp e + Ki Ts e; u(1) = Kp e + 2 Ki Ts e with e = 1 mm, Kp = 14, Ki = 1, Ts = 0.01.
    #[test]
    fn scaled_integral_adds_ki_ts_times_error() {
        let mut pi = Pi::new(14.0, 1.0, 0.01, 255.0, AntiWindup::None).unwrap();
        assert!((pi.step(1.0, 0.0).unwrap() - 14.01).abs() < 1e-12);
        assert!((pi.step(1.0, 0.0).unwrap() - 14.02).abs() < 1e-12);
    }

    // Without anti-windup 10 saturated samples at e = 100 mm integrate 0.01·100·10 = 10 counts; with
    // clamping nothing; with back-calculation Tt = Ts the integral puts v on the limit: 255 − 1400.
    #[test]
    fn anti_windup_schemes_limit_the_integral() {
        let mut plain = Pi::new(14.0, 1.0, 0.01, 255.0, AntiWindup::None).unwrap();
        let mut clamp = Pi::new(14.0, 1.0, 0.01, 255.0, AntiWindup::Clamping).unwrap();
        for _ in 0..10 {
            assert_eq!(plain.step(100.0, 0.0).unwrap(), 255.0);
            assert_eq!(clamp.step(100.0, 0.0).unwrap(), 255.0);
        }
        assert!((plain.integral() - 10.0).abs() < 1e-9);
        assert_eq!(clamp.integral(), 0.0);
        let bc = AntiWindup::BackCalculation { tt_s: 0.01 };
        let mut back = Pi::new(14.0f32, 1.0, 0.01, 255.0, bc).unwrap();
        assert_eq!(back.step(100.0, 0.0).unwrap(), 255.0);
        assert!((back.integral() - (255.0 - 1400.0)).abs() < 1e-3);
    }

    #[test]
    fn bad_settings_and_inputs_are_errors() {
        assert!(Pi::new(f64::NAN, 1.0, 0.01, 255.0, AntiWindup::None).is_err());
        assert!(Pi::new(1.0, 1.0, 0.0, 255.0, AntiWindup::None).is_err());
        assert!(Pi::new(
            1.0,
            1.0,
            0.01,
            255.0,
            AntiWindup::BackCalculation { tt_s: -1.0 }
        )
        .is_err());
        // Ts/Tt = 2: the saturated update I(k) = −I(k−1) + … no longer decays; just above Ts/2 is kept.
        let bc = |tt_s| AntiWindup::BackCalculation { tt_s };
        assert!(Pi::new(1.0, 1.0, 0.01, 255.0, bc(0.005)).is_err());
        assert!(Pi::new(1.0, 1.0, 0.01, 255.0, bc(0.0051)).is_ok());
        // Audit s28 L-4: the tuned controller's ranges (Ts 1e-6 to 1e4 s, |gains| ≤ 1e6, u_max ≤ 1e6).
        let none = AntiWindup::None;
        for ts in [1e-320, 9e-7, 1e300, 1.1e4] {
            assert_eq!(
                Pi::new(14.0, 1.0, ts, 255.0, none),
                Err(Error::Setting),
                "Ts {ts}"
            );
        }
        assert!(Pi::new(14.0, 1.0, 1e-6, 255.0, none).is_ok());
        assert!(Pi::new(14.0, 1.0, 1e4, 255.0, none).is_ok());
        assert!(Pi::new(1e308, 1.0, 0.01, 255.0, none).is_err());
        assert!(Pi::new(1.0, -2e6, 0.01, 255.0, none).is_err());
        assert!(Pi::new(-1e6, 1e6, 0.01, 1e6, none).is_ok());
        assert!(Pi::new(1.0, 1.0, 0.01, 2e6, none).is_err());
        let mut pi = Pi::new(14.0, 1.0, 0.01, 255.0, AntiWindup::None).unwrap();
        assert_eq!(pi.step(f64::INFINITY, 0.0).unwrap_err(), Error::NotFinite);
        assert_eq!(pi.integral(), 0.0);
    }
}
