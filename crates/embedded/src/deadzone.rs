//! The valve deadzone x = f(u) of paper eq. (1), its switching functions (eqs. 2–3) and its inverse,
//! the compensator placed between the PI controller and the valve.

use crate::{Error, Float};

/// Asymmetric deadzone (paper eq. 1), u in PWM counts:
///
/// ```text
/// x = m_l (u − b_l)   for u ≤ b_l
/// x = 0               for b_l < u < b_r
/// x = m_r (u − b_r)   for u ≥ b_r
/// ```
///
/// Size: 4 · `size_of::<F>()` (32 bytes for f64, 16 for f32). Cost: [`Deadzone::apply`] 2 flops.
///
/// ```
/// use ipa_embedded::Deadzone;
/// let dz = Deadzone { b_l: -1.5f64, b_r: 1.41, m_l: 2.0, m_r: 3.0 };
/// assert_eq!(dz.apply(0.0), 0.0);
/// assert!((dz.apply(2.41) - 3.0).abs() < 1e-12);
/// assert!((dz.apply(-2.5) + 2.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deadzone<F: Float> {
    /// b_l: left breakpoint in counts.
    pub b_l: F,
    /// b_r: right breakpoint in counts.
    pub b_r: F,
    /// m_l: slope of the left branch (x per count).
    pub m_l: F,
    /// m_r: slope of the right branch (x per count).
    pub m_r: F,
}

impl<F: Float> Deadzone<F> {
    /// True when this is a valve deadzone (paper eq. 1): every parameter finite, the breakpoints on
    /// either side of zero (b_l ≤ 0 ≤ b_r, counts) and both slopes positive (m_l, m_r > 0). An estimate
    /// from too few or too poorly exciting samples may be none (audit s28 L-8): it is then no model of
    /// the valve, and [`Compensator::new`] refuses it.
    pub fn is_physical(&self) -> bool {
        let finite = self.b_l.is_finite()
            && self.b_r.is_finite()
            && self.m_l.is_finite()
            && self.m_r.is_finite();
        finite
            && self.b_l <= F::ZERO
            && self.b_r >= F::ZERO
            && self.m_l > F::ZERO
            && self.m_r > F::ZERO
    }

    /// x = f(u) (paper eq. 1); the sloped branches include their breakpoints.
    #[inline]
    pub fn apply(&self, u: F) -> F {
        if u >= self.b_r {
            self.m_r * (u - self.b_r)
        } else if u <= self.b_l {
            self.m_l * (u - self.b_l)
        } else {
            F::ZERO
        }
    }

    /// Switching function h_r(u) = [u ≥ b_r] (paper eq. 3).
    #[inline]
    pub fn h_r(&self, u: F) -> F {
        if u >= self.b_r {
            F::ONE
        } else {
            F::ZERO
        }
    }

    /// Switching function h_l(u) = [u ≤ b_l] (paper eq. 2).
    #[inline]
    pub fn h_l(&self, u: F) -> F {
        if u <= self.b_l {
            F::ONE
        } else {
            F::ZERO
        }
    }

    /// The deadzone inverse: the smallest command u ≥ b_r giving x > 0 (u = b_r + x / m_r), or the
    /// largest u ≤ b_l giving x < 0 (u = b_l + x / m_l); 0 for x = 0 or a slope that is not positive.
    /// 2 flops.
    #[inline]
    pub fn inverse(&self, x: F) -> F {
        if x > F::ZERO && self.m_r > F::ZERO {
            self.b_r + x / self.m_r
        } else if x < F::ZERO && self.m_l > F::ZERO {
            self.b_l + x / self.m_l
        } else {
            F::ZERO
        }
    }
}

/// The rounding tolerance of a deadzone's breakpoints, relative to the command limit u_max: a b_l > 0
/// or b_r < 0 within 1e-9 · u_max of 0 is taken as 0 ([`rounded_breakpoints`]) by [`Compensator::new`]
/// and `control::DeadzoneCompensator::new` alike (a billionth of the command range: far below one count
/// of the IPA's ±255, far above the 1e-16 relative rounding of an estimate whose true breakpoint is 0,
/// e.g. b_l = +6e-18 counts from `tune` on a linear plant; audit s32 L-8).
pub const BREAKPOINT_ROUNDING: f64 = 1e-9;

/// (b_l, b_r) with a breakpoint on the wrong side of 0 by at most [`BREAKPOINT_ROUNDING`] · u_max set to
/// 0: b_l ∈ (0, tol] → 0, b_r ∈ [−tol, 0) → 0, tol = 1e-9 · u_max (0 when u_max is not finite and
/// positive); anything else unchanged (a breakpoint beyond the tolerance stays, for the caller to
/// refuse). The one rule of the compensators of this crate and of `control` (1 flop).
pub fn rounded_breakpoints<F: Float>(b_l: F, b_r: F, u_max: F) -> (F, F) {
    let tol = if u_max.is_finite() && u_max > F::ZERO {
        F::from_f64(BREAKPOINT_ROUNDING) * u_max
    } else {
        F::ZERO
    };
    let b_l = if b_l > F::ZERO && b_l <= tol {
        F::ZERO
    } else {
        b_l
    };
    let b_r = if b_r < F::ZERO && b_r >= -tol {
        F::ZERO
    } else {
        b_r
    };
    (b_l, b_r)
}

/// How the [`Compensator`] treats the slopes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlopeMode {
    /// m_ref = m_r for u > 0, m_l for u < 0: u_c = u + b_r or u + b_l (shift only).
    Shift,
    /// m_ref = (m_l + m_r) / 2 on both sides: the asymmetry of the slopes is cancelled too.
    Equalise,
}

/// Deadzone-inverse compensator: the PI output u (counts, the command for a valve without deadzone) is
/// mapped to u_c = f⁻¹(m_ref u), clamped to ±u_max; |u| ≤ t gives u_c = 0 (valve closed at rest).
/// The same map as `control::DeadzoneCompensator::apply`.
///
/// Size: 6 floats and the slope-mode byte: 56 bytes for f64, 28 for f32. Cost: at most 5 flops.
///
/// ```
/// use ipa_embedded::{Compensator, Deadzone, SlopeMode};
/// let dz = Deadzone { b_l: -20.0, b_r: 30.0, m_l: 1.0, m_r: 1.0 };
/// let c = Compensator::new(dz, SlopeMode::Shift, 0.0, 255.0).unwrap();
/// assert_eq!(c.apply(10.0), 40.0);   // 10 + b_r
/// assert_eq!(c.apply(-10.0), -30.0); // −10 + b_l
/// assert_eq!(c.apply(250.0), 255.0); // saturated
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compensator<F: Float> {
    deadzone: Deadzone<F>,
    mode: SlopeMode,
    threshold: F,
    u_max: F,
}

impl<F: Float> Compensator<F> {
    /// A compensator for an identified deadzone (finite, b_l ≤ 0 ≤ b_r, m_l > 0, m_r > 0), threshold
    /// t ≥ 0 counts and saturation u_max > 0 counts; otherwise [`Error::Setting`]. A breakpoint on the
    /// wrong side of 0 by at most [`BREAKPOINT_ROUNDING`] · u_max is an estimate's rounding and taken as
    /// 0 ([`rounded_breakpoints`], the rule of `control::DeadzoneCompensator::new`): b_l = +1e-12 · u_max
    /// is accepted as 0, b_l = +1e-3 counts (at u_max = 255) refused.
    pub fn new(
        deadzone: Deadzone<F>,
        mode: SlopeMode,
        threshold: F,
        u_max: F,
    ) -> Result<Self, Error> {
        let (b_l, b_r) = rounded_breakpoints(deadzone.b_l, deadzone.b_r, u_max);
        let deadzone = Deadzone {
            b_l,
            b_r,
            ..deadzone
        };
        if !deadzone.is_physical() {
            return Err(Error::Setting);
        }
        if !(threshold.is_finite() && threshold >= F::ZERO && u_max.is_finite() && u_max > F::ZERO)
        {
            return Err(Error::Setting);
        }
        Ok(Compensator {
            deadzone,
            mode,
            threshold,
            u_max,
        })
    }

    /// The deadzone it inverts (breakpoints within rounding of 0 taken as 0).
    pub fn deadzone(&self) -> Deadzone<F> {
        self.deadzone
    }

    /// The compensated valve command u_c (counts) for the controller output u (counts). A NaN u gives
    /// 0 (no comparison holds: the valve closed), ±∞ gives ±u_max; `ipa_dz_compensate` refuses both.
    #[inline]
    pub fn apply(&self, u: F) -> F {
        let d = &self.deadzone;
        if u.abs() <= self.threshold {
            return F::ZERO;
        }
        let m_ref = match self.mode {
            SlopeMode::Shift => {
                if u > F::ZERO {
                    d.m_r
                } else {
                    d.m_l
                }
            }
            SlopeMode::Equalise => F::from_f64(0.5) * (d.m_l + d.m_r),
        };
        d.inverse(m_ref * u).clamp_to(-self.u_max, self.u_max)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn dz() -> Deadzone<f64> {
        Deadzone {
            b_l: -20.0,
            b_r: 30.0,
            m_l: 2.0,
            m_r: 1.0,
        }
    }

    #[test]
    fn a_valve_deadzone_is_told_from_an_estimate_that_is_none() {
        assert!(dz().is_physical());
        // Zero-width deadzone (b_l = b_r = 0) is still a valve's.
        assert!(Deadzone {
            b_l: 0.0,
            b_r: 0.0,
            ..dz()
        }
        .is_physical());
        for d in [
            Deadzone { b_l: 5.0, ..dz() },  // left breakpoint right of zero
            Deadzone { b_r: -1.0, ..dz() }, // right breakpoint left of zero
            Deadzone { m_l: 0.0, ..dz() },  // an unexcited branch (slope 0)
            Deadzone { m_r: -0.5, ..dz() }, // a negative slope
            Deadzone {
                b_r: f64::NAN,
                ..dz()
            }, // not finite
            Deadzone {
                m_l: f64::INFINITY,
                ..dz()
            },
        ] {
            assert!(!d.is_physical(), "{d:?}");
            assert_eq!(
                Compensator::new(d, SlopeMode::Shift, 0.0, 255.0).err(),
                Some(Error::Setting),
                "{d:?}"
            );
        }
    }

    // The rounding rule: tol = 1e-9 · u_max; a wrong-side breakpoint up to tol (included) becomes 0,
    // the next float beyond it stays (for `Compensator::new` to refuse); a right-side breakpoint
    // never moves; u_max not finite and positive gives tol = 0 (nothing moves). f32 likewise.
    #[test]
    fn breakpoints_within_rounding_of_zero_become_zero() {
        let tol: f64 = 1e-9 * 255.0;
        let beyond = f64::from_bits(tol.to_bits() + 1);
        assert_eq!(rounded_breakpoints(tol, -tol, 255.0), (0.0, 0.0));
        assert_eq!(
            rounded_breakpoints(beyond, -beyond, 255.0),
            (beyond, -beyond)
        );
        assert_eq!(rounded_breakpoints(-tol, tol, 255.0), (-tol, tol));
        for u_max in [0.0, -255.0, f64::INFINITY, f64::NAN] {
            assert_eq!(
                rounded_breakpoints(1e-300, -1e-300, u_max),
                (1e-300, -1e-300)
            );
        }
        assert_eq!(rounded_breakpoints(1e-10f32, -1e-10, 255.0), (0.0, 0.0));
        assert_eq!(rounded_breakpoints(1e-3f32, -1e-3, 255.0), (1e-3, -1e-3));
    }

    // f(f⁻¹(x)) = x on both branches (closed form: m (b + x/m − b) = x).
    #[test]
    fn inverse_undoes_the_deadzone() {
        for x in [-50.0, -0.5, 0.25, 7.0] {
            assert!((dz().apply(dz().inverse(x)) - x).abs() < 1e-12);
        }
        assert_eq!(dz().inverse(0.0), 0.0);
    }

    // Equalise: m_ref = 1.5, so f(u_c) = 1.5 u; u = 10 → u_c = 30 + 15 = 45.
    #[test]
    fn equalise_mode_gives_the_mean_slope_on_both_branches() {
        let c = Compensator::new(dz(), SlopeMode::Equalise, 0.0, 255.0).unwrap();
        for u in [-40.0, -1.0, 1.0, 40.0] {
            assert!((dz().apply(c.apply(u)) - 1.5 * u).abs() < 1e-12);
        }
        assert_eq!(c.apply(10.0), 45.0);
    }

    #[test]
    fn threshold_closes_the_valve_and_bad_deadzones_are_refused() {
        let c = Compensator::new(dz(), SlopeMode::Shift, 2.0, 255.0).unwrap();
        assert_eq!(c.apply(1.5), 0.0);
        assert_eq!(c.apply(-2.0), 0.0);
        assert_eq!(c.apply(2.5), 32.5);
        let bad = Deadzone { m_r: 0.0, ..dz() };
        assert_eq!(
            Compensator::new(bad, SlopeMode::Shift, 0.0, 255.0).unwrap_err(),
            Error::Setting
        );
        let bad = Deadzone { b_l: 1.0, ..dz() };
        assert!(Compensator::new(bad, SlopeMode::Shift, 0.0, 255.0).is_err());
        assert!(Compensator::new(dz(), SlopeMode::Shift, -1.0, 255.0).is_err());
    }
}
