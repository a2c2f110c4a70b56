//! Deadzone-inverse compensation (the paper's "future work"): a static map placed between the PI
//! controller and the valve that cancels the identified deadzone x = f(u) of paper eq. (1).
//!
//! The PI output u (counts) is read as the command the controller would give a valve *without* a deadzone.
//! With reference slope m_ref the wanted internal variable is x_d = m_ref u, and the compensator sends the
//! smallest command that produces it through the identified deadzone, f^{-1}(x_d)
//! ([`Deadzone::inverse`](sysid_core::Deadzone::inverse)):
//!
//! ```text
//! u_c = b_r + (m_ref / m_r) u    for u >  t
//! u_c = 0                        for |u| <= t
//! u_c = b_l + (m_ref / m_l) u    for u < -t
//! ```
//!
//! then clamped to ±u_max. t >= 0 is a small threshold (counts, default 0): inside it the valve is left
//! closed, which avoids chattering between b_l and b_r when the loop sits at its set-point.
//!
//! * [`SlopeMode::Shift`] (default): m_ref = m_r for u > 0 and m_ref = m_l for u < 0, i.e. u_c = u + b_r or
//!   u + b_l: the command is only shifted past the deadzone, the loop gain of each branch is unchanged.
//! * [`SlopeMode::Equalise`]: m_ref = (m_l + m_r) / 2 on both sides, which also cancels the asymmetry of the
//!   two slopes, so the loop has the same gain moving out and moving in.
//!
//! With an exact deadzone model, f(u_c) = m_ref u: the controller sees a linear valve.

use serde::{Deserialize, Serialize};
use sysid_core::{Deadzone, Model};

use crate::{ControlError, ControlSetting};

/// How the compensator treats the slopes m_l, m_r of the deadzone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum SlopeMode {
    /// Shift only: u_c = u + b_r (u > 0) or u + b_l (u < 0).
    #[default]
    Shift,
    /// Shift and rescale both branches to the mean slope (m_l + m_r) / 2.
    Equalise,
}

/// A deadzone-inverse compensator built from an identified [`Deadzone`].
///
/// ```
/// use control::{DeadzoneCompensator, SlopeMode};
/// use sysid_core::Deadzone;
/// let dz = Deadzone { b_l: -20.0, b_r: 30.0, m_l: 1.0, m_r: 1.0 };
/// let c = DeadzoneCompensator::new(dz, SlopeMode::Shift, 255.0).unwrap();
/// assert_eq!(c.apply(10.0), 40.0);   // 10 + b_r
/// assert_eq!(c.apply(-10.0), -30.0); // -10 + b_l
/// assert_eq!(c.apply(0.0), 0.0);
/// assert_eq!(c.apply(250.0), 255.0); // saturated
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DeadzoneCompensator {
    /// The identified deadzone (b_l, b_r in counts; m_l, m_r its slopes).
    pub deadzone: Deadzone,
    /// Shift only, or shift and equalise the slopes.
    pub slope_mode: SlopeMode,
    /// t: threshold in counts (>= 0) below which |u| gives u_c = 0.
    pub threshold_counts: f64,
    /// u_max: saturation limit of the compensated command in counts.
    pub u_max: f64,
}

/// The rounding tolerance of a deadzone's breakpoints, relative to the command limit u_max: a b_l > 0
/// or b_r < 0 within 1e-9 · u_max of 0 is taken as 0 by [`DeadzoneCompensator::new`] (a billionth of
/// the command range: far below one count of the IPA's ±255, far above the 1e-16 relative rounding of
/// an estimate whose true breakpoint is 0). The microcontroller's compensator's constant and rule
/// (`ipa_embedded::deadzone::rounded_breakpoints`), so a controller file loads alike in both.
pub const BREAKPOINT_ROUNDING: f64 = ipa_embedded::deadzone::BREAKPOINT_ROUNDING;

impl DeadzoneCompensator {
    /// Builds a compensator with threshold 0. Fails (naming [`ControlSetting::Deadzone`]) when the deadzone is not
    /// finite, has b_l > 0, b_r < 0 (beyond [`BREAKPOINT_ROUNDING`] · u_max, within it taken as 0), b_l > b_r, or a slope that is not > 0, or when u_max is not > 0.
    pub fn new(
        deadzone: Deadzone,
        slope_mode: SlopeMode,
        u_max: f64,
    ) -> Result<Self, ControlError> {
        // A breakpoint on the wrong side of 0 by at most BREAKPOINT_ROUNDING · u_max is an estimate's
        // rounding noise around a plant with no deadzone on that side (audit s32 L-8: a linear plant's
        // estimated b_l = +6e-18 counts refused the tuned controller): it is taken as 0.
        // One rule with the microcontroller's `Compensator::new`.
        let mut deadzone = deadzone;
        (deadzone.b_l, deadzone.b_r) =
            ipa_embedded::deadzone::rounded_breakpoints(deadzone.b_l, deadzone.b_r, u_max);
        let d = deadzone;
        let bad = |what: &str| {
            let v = sysid_core::format::shortest;
            Err(ControlError::setting(
                ControlSetting::Deadzone,
                format!(
                    "b_l = {}, b_r = {}, m_l = {}, m_r = {}",
                    v(d.b_l),
                    v(d.b_r),
                    v(d.m_l),
                    v(d.m_r)
                ),
                what,
            ))
        };
        if ![d.b_l, d.b_r, d.m_l, d.m_r].iter().all(|v| v.is_finite()) {
            return bad("a deadzone with finite breakpoints and slopes");
        }
        if d.b_l > 0.0 || d.b_r < 0.0 {
            return bad("a deadzone around u = 0 (b_l <= 0 <= b_r)");
        }
        if d.m_l == 0.0 || d.m_r == 0.0 {
            // identify fixes the branch of a one-sided input at 0 (Param.fixed "one-sided input").
            return bad(
                "both deadzone branches estimated (a slope of exactly 0 is the branch identify drops \
                 when the input never goes that way: a one-sided input; the deadzone inverse, and \
                 tune, are for an actuator driven both ways, like the IPA's valve pair)",
            );
        }
        if !(d.m_l > 0.0 && d.m_r > 0.0) {
            return bad(
                "positive slopes m_l, m_r (a valve whose output rises with its command; a plant of \
                 negative gain, both slopes < 0, is a plant the deadzone inverse and tune do not \
                 handle as it is: negate its output column (y -> -y), identify again, and give the \
                 set-points negated; audit s17 L-b)",
            );
        }
        if !(u_max.is_finite() && u_max > 0.0) {
            return Err(ControlError::setting(
                ControlSetting::UMax,
                u_max,
                "a finite number of counts > 0",
            ));
        }
        Ok(DeadzoneCompensator {
            deadzone,
            slope_mode,
            threshold_counts: 0.0,
            u_max,
        })
    }

    /// Sets the threshold t (counts, finite, >= 0).
    pub fn with_threshold(mut self, threshold_counts: f64) -> Result<Self, ControlError> {
        if !(threshold_counts.is_finite() && threshold_counts >= 0.0) {
            return Err(ControlError::setting(
                ControlSetting::CompensatorThreshold,
                threshold_counts,
                "a finite number of counts >= 0",
            ));
        }
        self.threshold_counts = threshold_counts;
        Ok(self)
    }

    /// The compensated command u_c (counts) for the PI output `u` (counts); see the module documentation.
    pub fn apply(&self, u: f64) -> f64 {
        let d = &self.deadzone;
        if u.abs() <= self.threshold_counts {
            return 0.0;
        }
        let m_ref = match self.slope_mode {
            SlopeMode::Shift => {
                if u > 0.0 {
                    d.m_r
                } else {
                    d.m_l
                }
            }
            SlopeMode::Equalise => 0.5 * (d.m_l + d.m_r),
        };
        d.inverse(m_ref * u).clamp(-self.u_max, self.u_max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Audit s32 L-8: a breakpoint on the wrong side of 0 by at most 1e-9 · u_max (255e-9 counts here)
    // is rounding noise, taken as 0; one beyond it (1e-6 counts) is refused as before.
    #[test]
    fn a_breakpoint_within_rounding_of_zero_is_taken_as_zero() {
        let noisy = Deadzone {
            b_l: 6.116393128355368e-18,
            b_r: -2e-7,
            m_l: 0.5,
            m_r: 0.5,
        };
        let c = DeadzoneCompensator::new(noisy, SlopeMode::Shift, 255.0).unwrap();
        assert_eq!((c.deadzone.b_l, c.deadzone.b_r), (0.0, 0.0));
        let beyond = Deadzone { b_l: 1e-6, ..noisy };
        let e = DeadzoneCompensator::new(beyond, SlopeMode::Shift, 255.0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("b_l = 1e-6") && e.contains("b_l <= 0 <= b_r"),
            "{e}"
        );
    }

    fn dz() -> Deadzone {
        Deadzone {
            b_l: -20.0,
            b_r: 30.0,
            m_l: 2.0,
            m_r: 1.0,
        }
    }

    #[test]
    fn shift_mode_cancels_the_deadzone_on_each_branch() {
        // f(u + b_r) = m_r u and f(u + b_l) = m_l u: the valve becomes linear with the branch slopes.
        let c = DeadzoneCompensator::new(dz(), SlopeMode::Shift, 255.0).unwrap();
        for u in [0.5, 3.0, 100.0] {
            assert!((c.apply(u) - (u + 30.0)).abs() < 1e-12);
            assert!((dz().apply(c.apply(u)) - 1.0 * u).abs() < 1e-12);
            assert!((c.apply(-u) - (-u - 20.0)).abs() < 1e-12);
            assert!((dz().apply(c.apply(-u)) + 2.0 * u).abs() < 1e-12);
        }
    }

    #[test]
    fn equalise_mode_gives_the_mean_slope_on_both_branches() {
        // f(u_c) = (m_l + m_r)/2 u = 1.5 u for both signs.
        let c = DeadzoneCompensator::new(dz(), SlopeMode::Equalise, 255.0).unwrap();
        for u in [-40.0, -1.0, 1.0, 40.0] {
            assert!((dz().apply(c.apply(u)) - 1.5 * u).abs() < 1e-12);
        }
        // u_c = b_r + 1.5 u / m_r = 30 + 1.5 * 10 = 45.
        assert!((c.apply(10.0) - 45.0).abs() < 1e-12);
    }

    #[test]
    fn threshold_and_saturation_bound_the_command() {
        // |u| <= t -> 0; u_c never exceeds u_max.
        let c = DeadzoneCompensator::new(dz(), SlopeMode::Shift, 255.0)
            .unwrap()
            .with_threshold(0.5)
            .unwrap();
        assert_eq!(c.apply(0.4), 0.0);
        assert_eq!(c.apply(-0.5), 0.0);
        assert_eq!(c.apply(240.0), 255.0);
        assert_eq!(c.apply(-250.0), -255.0);
    }

    #[test]
    fn rejects_deadzones_that_cannot_be_inverted() {
        // Zero slope, b_l > b_r around a nonzero centre, non-finite values: each names the flag.
        let mut d = dz();
        d.m_r = 0.0;
        assert!(matches!(
            DeadzoneCompensator::new(d, SlopeMode::Shift, 255.0).unwrap_err(),
            ControlError::Setting {
                setting: ControlSetting::Deadzone,
                ..
            }
        ));
        let d = Deadzone {
            b_l: 5.0,
            b_r: 10.0,
            m_l: 1.0,
            m_r: 1.0,
        };
        assert!(DeadzoneCompensator::new(d, SlopeMode::Shift, 255.0).is_err());
        let d = Deadzone {
            b_l: f64::NAN,
            ..dz()
        };
        assert!(DeadzoneCompensator::new(d, SlopeMode::Shift, 255.0).is_err());
        assert!(DeadzoneCompensator::new(dz(), SlopeMode::Shift, 255.0)
            .unwrap()
            .with_threshold(-1.0)
            .is_err());
    }
}

/// Why a model cannot give the controller's deadzone ([`command_deadzone`]).
#[derive(Debug, Clone, PartialEq)]
pub enum DeadzoneProblem {
    /// A model with several inputs (the controller drives one command).
    SeveralInputs(usize),
    /// A model whose input block is not a deadzone (ARX, or another input nonlinearity), in words.
    NoDeadzone(&'static str),
}

impl std::fmt::Display for DeadzoneProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DeadzoneProblem::SeveralInputs(n) => write!(
                f,
                "a single-input Hammerstein model file (this model has {n} inputs; the controller \
                 drives one command)"
            ),
            DeadzoneProblem::NoDeadzone(block) => write!(
                f,
                "a model with a deadzone input block (this model's input block is {block}; identify \
                 the record again with `--structure hammerstein` for one, or run this model as a \
                 plant under a PI: `control --plant model:FILE --kp KP --ki KI`)"
            ),
        }
    }
}

/// The deadzone of a single-input Hammerstein model in the command's units: a detrended model's
/// deadzone acts on u − u0, so its breakpoints are shifted by u0 (the slopes are unchanged).
pub fn command_deadzone(m: &Model) -> Result<Deadzone, DeadzoneProblem> {
    if m.inputs().len() > 1 {
        return Err(DeadzoneProblem::SeveralInputs(m.inputs().len()));
    }
    m.command_deadzone(0).ok_or_else(|| {
        use sysid_core::StaticNonlinearity as S;
        DeadzoneProblem::NoDeadzone(match m.inputs().first().map(|c| c.nonlinearity()) {
            Some(S::Saturation(_)) => "a saturation",
            Some(S::DeadzoneSaturation(_)) => "a deadzone whose branches saturate",
            Some(S::PiecewiseLinear(_)) => "piecewise-linear",
            Some(S::Polynomial(_)) => "a polynomial",
            _ => "linear: an ARX model",
        })
    })
}

/// How many times the estimation data's largest command, or its output span, the specification's command
/// limit or largest step may be before `tune`'s warning of a specification beyond the model's data
/// ([`crate::trust::extrapolation_warning`]) names the units as the likely cause.
pub const EXTRAPOLATION_FACTOR: f64 = 4.0;

/// A deadzone compensator taken from `model` for a loop whose command limit is `u_max`: a warning when
/// the model's estimation data never came near that limit (its largest |u| more than
/// [`EXTRAPOLATION_FACTOR`] times smaller), i.e. its deadzone is probably in another plant's command
/// units (audit s11: an EMPS model in volts compensating the IPA in PWM counts, silently).
pub fn compensator_scale_warning(model: &Model, u_max: f64) -> Option<String> {
    let u_data = model.data_range()?.u_magnitude(0).filter(|m| *m > 0.0)?;
    (u_max > EXTRAPOLATION_FACTOR * u_data).then(|| {
        format!(
            "the compensator's model was estimated on commands within ±{} while the loop commands up to \
             ±{u_max} ({} times more): its deadzone is probably in another plant's units; check that the \
             model is of this plant",
            crate::trust::fmt_value(u_data),
            crate::trust::fmt_value(u_max / u_data)
        )
    })
}
