//! The paper's PI position controller: e(k) = r(k) - y(k), u(k) = Kp e(k) + I(k), saturated to ±u_max.
//!
//! The paper gives Kp = 14 and Ki = 1 but not the form of the integral. Two forms are offered:
//!
//! * [`IntegralForm::Scaled`] (default): I(k) = Ki Ts Σ_{j<=k} e(j), the backward-Euler (rectangle, current
//!   sample included) discretisation of the continuous PI u = Kp e + Ki ∫ e dt. Ki is in counts/(mm·s).
//! * [`IntegralForm::PerSample`]: I(k) = Ki Σ_{j<=k} e(j), Ki in counts/(mm·sample) — 1/Ts = 100 times
//!   stronger at Ts = 0.01 s.
//!
//! e is in mm, u in PWM counts. On the paper's "actual" model and a 50 mm step from rest the scaled form
//! gives about 3.65 % overshoot and the per-sample form about 56 % (docs/control.md); the paper's Table V
//! (overshoot 0.12 mm) is only compatible with the scaled form.
//!
//! Saturation: the applied command is u(k) = sat(v(k)) with v(k) = Kp e(k) + I(k) and sat clamping to
//! [-u_max, u_max] (u_max = 255 counts, the PWM range). Without anti-windup (the paper's controller, as far
//! as one can tell) the integral keeps accumulating while the command is saturated.

use serde::{Deserialize, Serialize};

use crate::{ControlError, ControlSetting};

/// How the integral term is scaled (the paper does not say; see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum IntegralForm {
    /// I(k) = Ki Ts Σ_{j<=k} e(j): Ki in counts/(mm·s) (the discretised continuous PI). Default.
    #[default]
    Scaled,
    /// I(k) = Ki Σ_{j<=k} e(j): Ki in counts/(mm·sample).
    PerSample,
}

impl std::fmt::Display for IntegralForm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            IntegralForm::Scaled => "scaled",
            IntegralForm::PerSample => "per-sample",
        })
    }
}

/// What the integral does while the command is saturated.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum AntiWindup {
    /// The integral always accumulates (the paper's plain PI). Default.
    #[default]
    None,
    /// Conditional integration: e(k) is not added to the integral when v(k) = Kp e(k) + I(k-1) + ΔI would
    /// saturate and e(k) has the sign of v(k) (integrating would drive the command further into saturation).
    Clamping,
    /// Back-calculation (Åström & Hägglund): after the usual update the integral is corrected by
    /// (Ts / Tt) (sat(v) - v), pulling v back towards the saturation limit with tracking time constant Tt.
    BackCalculation {
        /// Tt: tracking time constant in s (> 0). Tt = Ts resets v onto the limit at every sample.
        tt_s: f64,
    },
}

/// The anti-windup schemes by name, without their settings (what a command line's `--anti-windup`
/// chooses; [`AntiWindup`] carries the tracking time Tt of back-calculation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "kebab-case")]
pub enum AntiWindupScheme {
    /// The integral always accumulates (the paper's plain PI); the default.
    #[default]
    None,
    /// Conditional integration: no integration while saturated in the direction of the error.
    Clamping,
    /// Back-calculation with tracking time constant Tt (s).
    BackCalculation,
}

impl AntiWindup {
    /// The scheme, without its settings.
    pub fn scheme(&self) -> AntiWindupScheme {
        match self {
            AntiWindup::None => AntiWindupScheme::None,
            AntiWindup::Clamping => AntiWindupScheme::Clamping,
            AntiWindup::BackCalculation { .. } => AntiWindupScheme::BackCalculation,
        }
    }
}

impl std::fmt::Display for AntiWindup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            AntiWindup::None => f.write_str("none"),
            AntiWindup::Clamping => f.write_str("clamping"),
            AntiWindup::BackCalculation { tt_s } => write!(f, "back-calculation (Tt = {tt_s} s)"),
        }
    }
}

/// Settings of a PI controller (unfitted: validated and turned into a [`PiController`] by [`PiSettings::build`]).
///
/// ```
/// use control::{AntiWindup, IntegralForm, PiSettings};
/// let pi = PiSettings::paper().with_anti_windup(AntiWindup::Clamping).build(0.01).unwrap();
/// assert_eq!(pi.settings().kp, 14.0);
/// assert_eq!(pi.settings().integral, IntegralForm::Scaled);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PiSettings {
    /// Kp: proportional gain in counts/mm.
    pub kp: f64,
    /// Ki: integral gain, counts/(mm·s) for [`IntegralForm::Scaled`], counts/(mm·sample) for
    /// [`IntegralForm::PerSample`].
    pub ki: f64,
    /// Form of the integral term.
    pub integral: IntegralForm,
    /// Anti-windup scheme.
    pub anti_windup: AntiWindup,
    /// u_max: saturation limit of the command in counts (> 0); 255 for the IPA's PWM.
    pub u_max: f64,
}

impl Default for PiSettings {
    fn default() -> Self {
        PiSettings::paper()
    }
}

impl PiSettings {
    /// The PWM range of the IPA: ±255 counts.
    pub const U_MAX_PWM: f64 = 255.0;

    /// The paper's controller: Kp = 14, Ki = 1, scaled integral, no anti-windup, u_max = 255.
    pub fn paper() -> Self {
        PiSettings::new(14.0, 1.0)
    }

    /// Kp and Ki with the defaults for the rest (scaled integral, no anti-windup, u_max = 255).
    pub fn new(kp: f64, ki: f64) -> Self {
        PiSettings {
            kp,
            ki,
            integral: IntegralForm::Scaled,
            anti_windup: AntiWindup::None,
            u_max: Self::U_MAX_PWM,
        }
    }

    /// Sets the integral form.
    pub fn with_integral(mut self, integral: IntegralForm) -> Self {
        self.integral = integral;
        self
    }

    /// Sets the anti-windup scheme.
    pub fn with_anti_windup(mut self, anti_windup: AntiWindup) -> Self {
        self.anti_windup = anti_windup;
        self
    }

    /// Sets the saturation limit u_max (counts).
    pub fn with_u_max(mut self, u_max: f64) -> Self {
        self.u_max = u_max;
        self
    }

    /// Checks the settings: finite gains, u_max finite and > 0, Tt finite and > 0.
    /// Errors name the [`ControlSetting`] at fault.
    pub fn validate(&self) -> Result<(), ControlError> {
        if !self.kp.is_finite() {
            return Err(ControlError::setting(
                ControlSetting::Kp,
                self.kp,
                "a finite number (counts/mm)",
            ));
        }
        if !self.ki.is_finite() {
            return Err(ControlError::setting(
                ControlSetting::Ki,
                self.ki,
                "a finite number",
            ));
        }
        if !(self.u_max.is_finite() && self.u_max > 0.0) {
            return Err(ControlError::setting(
                ControlSetting::UMax,
                self.u_max,
                "a finite number of counts > 0",
            ));
        }
        if let AntiWindup::BackCalculation { tt_s } = self.anti_windup {
            if !(tt_s.is_finite() && tt_s > 0.0) {
                return Err(ControlError::setting(
                    ControlSetting::TrackingTime,
                    tt_s,
                    "a finite number of seconds > 0",
                ));
            }
        }
        Ok(())
    }

    /// Ti = |Kp / Ki| in s, the integral time of the PI sampled at `ts_s` (s): Ki is in counts/(mm·s) for
    /// the scaled form, Ki / Ts for the per-sample form. `None` when Kp or Ki (per second) is 0. The usual
    /// default tracking time Tt of back-calculation ([`PiSettings::validate`] refuses it when not finite).
    pub fn integral_time_s(&self, ts_s: f64) -> Option<f64> {
        let ki_per_s = match self.integral {
            IntegralForm::Scaled => self.ki,
            IntegralForm::PerSample => self.ki / ts_s,
        };
        if ki_per_s == 0.0 || self.kp == 0.0 {
            return None;
        }
        Some((self.kp / ki_per_s).abs())
    }

    /// The gain g that multiplies e(k) in the integral update I(k) = I(k-1) + g e(k):
    /// Ki Ts for the scaled form, Ki for the per-sample form.
    pub fn integral_gain(&self, ts_s: f64) -> f64 {
        match self.integral {
            IntegralForm::Scaled => self.ki * ts_s,
            IntegralForm::PerSample => self.ki,
        }
    }

    /// Validates the settings and builds a controller running at sampling period `ts_s` (s, finite, > 0).
    pub fn build(self, ts_s: f64) -> Result<PiController, ControlError> {
        self.validate()?;
        if !(ts_s.is_finite() && ts_s > 0.0) {
            return Err(ControlError::setting(
                ControlSetting::Ts,
                ts_s,
                "a finite sampling period in s > 0",
            ));
        }
        // In saturation the back-calculation update is I(k) = (1 − Ts/Tt) I(k−1) + …, which grows
        // without bound for Ts/Tt >= 2 (audit s14 L-l: Tt = 1e-300 s ended in NaN at sample 3).
        if let AntiWindup::BackCalculation { tt_s } = self.anti_windup {
            if tt_s <= ts_s / 2.0 {
                return Err(ControlError::setting(
                    ControlSetting::TrackingTime,
                    tt_s,
                    &format!(
                        "more than half the sampling period ({} s): with Ts/Tt >= 2 the \
                         back-calculation diverges",
                        ts_s / 2.0
                    ),
                ));
            }
        }
        Ok(PiController {
            settings: self,
            ts_s,
            integral: 0.0,
        })
    }
}

/// A running PI controller: holds the integral state I(k) (counts).
#[derive(Debug, Clone)]
pub struct PiController {
    settings: PiSettings,
    ts_s: f64,
    /// I(k-1) in counts (already multiplied by the integral gain).
    integral: f64,
}

impl PiController {
    /// The settings it was built from.
    pub fn settings(&self) -> &PiSettings {
        &self.settings
    }

    /// Sampling period Ts in s.
    pub fn ts_s(&self) -> f64 {
        self.ts_s
    }

    /// The integral term I(k) in counts after the last [`step`](Self::step) (0 after a reset).
    pub fn integral_counts(&self) -> f64 {
        self.integral
    }

    /// Back to rest: I = 0.
    pub fn reset(&mut self) {
        self.integral = 0.0;
    }

    /// One sample: from the set-point r(k) and the measured position y(k) (both mm) computes the saturated
    /// command u(k) in counts and updates the integral. Non-finite inputs give a non-finite command (the
    /// closed loop checks its inputs before calling).
    pub fn step(&mut self, r_mm: f64, y_mm: f64) -> f64 {
        let s = &self.settings;
        let e = r_mm - y_mm;
        let g = s.integral_gain(self.ts_s);
        let proportional = s.kp * e;
        let integrated = self.integral + g * e;
        let v = proportional + integrated;
        let u = v.clamp(-s.u_max, s.u_max);
        match s.anti_windup {
            AntiWindup::None => {
                self.integral = integrated;
                u
            }
            AntiWindup::Clamping => {
                if u != v && e * v > 0.0 {
                    // Saturated and the error pushes v further out: hold I(k) = I(k-1).
                    (proportional + self.integral).clamp(-s.u_max, s.u_max)
                } else {
                    self.integral = integrated;
                    u
                }
            }
            AntiWindup::BackCalculation { tt_s } => {
                self.integral = integrated + (self.ts_s / tt_s) * (u - v);
                u
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Ti = Kp/Ki: Kp = 14, Ki = 2 counts/(mm·s) gives 7 s; per sample at Ts = 0.01 s, Ki = 0.02 is
    // 2 per second, the same 7 s; Ki = 0 has no Ti.
    #[test]
    fn integral_time_is_kp_over_ki_per_second() {
        assert_eq!(PiSettings::new(14.0, 2.0).integral_time_s(0.01), Some(7.0));
        let per_sample = PiSettings::new(-14.0, 0.02).with_integral(IntegralForm::PerSample);
        let ti = per_sample.integral_time_s(0.01).unwrap();
        assert!((ti - 7.0).abs() < 1e-12, "{ti}");
        assert_eq!(PiSettings::new(14.0, 0.0).integral_time_s(0.01), None);
        assert_eq!(PiSettings::new(0.0, 1.0).integral_time_s(0.01), None);
    }

    #[test]
    fn anti_windup_names_its_scheme() {
        assert_eq!(AntiWindup::None.scheme(), AntiWindupScheme::None);
        assert_eq!(AntiWindup::Clamping.scheme(), AntiWindupScheme::Clamping);
        let bc = AntiWindup::BackCalculation { tt_s: 0.5 };
        assert_eq!(bc.scheme(), AntiWindupScheme::BackCalculation);
    }

    #[test]
    fn scaled_integral_adds_ki_ts_times_error() {
        // u(0) = Kp e + Ki Ts e; u(1) = Kp e + Ki Ts (e + e) with e = 1 mm, Kp = 14, Ki = 1, Ts = 0.01.
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        assert!((pi.step(1.0, 0.0) - 14.01).abs() < 1e-12);
        assert!((pi.step(1.0, 0.0) - 14.02).abs() < 1e-12);
        assert!((pi.integral_counts() - 0.02).abs() < 1e-15);
    }

    #[test]
    fn per_sample_integral_adds_ki_times_error() {
        // u(0) = Kp e + Ki e = 14 + 1; u(1) = 14 + 2.
        let mut pi = PiSettings::paper()
            .with_integral(IntegralForm::PerSample)
            .build(0.01)
            .unwrap();
        assert_eq!(pi.step(1.0, 0.0), 15.0);
        assert_eq!(pi.step(1.0, 0.0), 16.0);
    }

    #[test]
    fn command_is_clamped_to_u_max() {
        // Kp e = 14 * 100 = 1400 > 255 -> 255; -1400 -> -255.
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        assert_eq!(pi.step(100.0, 0.0), 255.0);
        pi.reset();
        assert_eq!(pi.step(-100.0, 0.0), -255.0);
    }

    #[test]
    fn without_anti_windup_the_integral_grows_while_saturated() {
        // I(k) = Ki Ts Σ e = 0.01 * 100 * 10 = 10 after 10 saturated samples.
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        for _ in 0..10 {
            pi.step(100.0, 0.0);
        }
        assert!((pi.integral_counts() - 10.0).abs() < 1e-9);
    }

    #[test]
    fn clamping_holds_the_integral_while_saturated_in_the_error_direction() {
        // Saturated at +255 with e > 0: no integration; then e < 0 (unsaturated): integrates again.
        let mut pi = PiSettings::paper()
            .with_anti_windup(AntiWindup::Clamping)
            .build(0.01)
            .unwrap();
        for _ in 0..10 {
            assert_eq!(pi.step(100.0, 0.0), 255.0);
        }
        assert_eq!(pi.integral_counts(), 0.0);
        let u = pi.step(0.0, 1.0);
        assert!((u - (-14.0 - 0.01)).abs() < 1e-12);
        assert!((pi.integral_counts() + 0.01).abs() < 1e-15);
    }

    #[test]
    fn clamping_integrates_when_the_error_pulls_out_of_saturation() {
        // Per-sample form, Kp = 0, Ki = 1, u_max = 1: I = 0.5; then e = 1 -> v = 1.5 saturated and e v > 0:
        // hold I = 0.5 and u = sat(Kp e + 0.5) = 0.5. Then e = -0.25 -> v = 0.25 unsaturated: I = 0.25.
        let s = PiSettings::new(0.0, 1.0)
            .with_integral(IntegralForm::PerSample)
            .with_anti_windup(AntiWindup::Clamping)
            .with_u_max(1.0);
        let mut pi = s.build(0.01).unwrap();
        assert_eq!(pi.step(0.5, 0.0), 0.5);
        assert_eq!(pi.step(1.0, 0.0), 0.5);
        assert_eq!(pi.integral_counts(), 0.5);
        assert_eq!(pi.step(-0.25, 0.0), 0.25);
        assert_eq!(pi.integral_counts(), 0.25);
    }

    #[test]
    fn back_calculation_with_tt_equal_ts_puts_v_on_the_limit() {
        // Tt = Ts: I <- I + g e + (u - v) so that Kp e + I = u: I = 255 - 14*100 = -1145.
        let s = PiSettings::paper().with_anti_windup(AntiWindup::BackCalculation { tt_s: 0.01 });
        let mut pi = s.build(0.01).unwrap();
        assert_eq!(pi.step(100.0, 0.0), 255.0);
        assert!((pi.integral_counts() - (255.0 - 1400.0)).abs() < 1e-9);
    }

    #[test]
    fn settings_reject_non_finite_gains_and_non_positive_limits() {
        // Each invalid setting is named in the error.
        let named = |s: PiSettings| match s.validate().unwrap_err() {
            ControlError::Setting { setting, .. } => setting,
            e => panic!("not a setting error: {e}"),
        };
        assert_eq!(named(PiSettings::new(f64::NAN, 1.0)), ControlSetting::Kp);
        assert_eq!(
            named(PiSettings::new(1.0, f64::INFINITY)),
            ControlSetting::Ki
        );
        assert_eq!(
            named(PiSettings::paper().with_u_max(0.0)),
            ControlSetting::UMax
        );
        let bc = AntiWindup::BackCalculation { tt_s: -1.0 };
        assert_eq!(
            named(PiSettings::paper().with_anti_windup(bc)),
            ControlSetting::TrackingTime
        );
        assert_eq!(
            PiSettings::new(f64::NAN, 1.0)
                .validate()
                .unwrap_err()
                .to_string(),
            "invalid setting kp = NaN: a finite number (counts/mm)"
        );
        assert!(PiSettings::paper().build(0.0).is_err());
        // Tt = Ts/2 at Ts = 0.01 s: the saturated update I(k) = −I(k−1) + … never decays; refused by
        // name at build (validate has no Ts); Tt just above is built.
        let bc = |tt_s| PiSettings::paper().with_anti_windup(AntiWindup::BackCalculation { tt_s });
        let e = bc(0.005).build(0.01).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("invalid setting tt_s = 0.005: more than half the sampling period"),
            "{e}"
        );
        assert!(bc(0.0051).build(0.01).is_ok());
    }
}
