//! The tuned position controller (`ipa-sysid tune`, CONTROLLER.json): a PID with clamping anti-windup,
//! a deadzone inverse from the model's deadzone, and a hold band against stick-slip hunting.
//!
//! At sample k (Ts s), with e(k) = r(k) − y(k) in mm:
//!
//! ```text
//! D(k)  = α D(k−1) − (1 − α) (y(k) − y(k−1)) / Ts,   α = Tf / (Tf + Ts)   (filtered −dy/dt, mm/s; D(0) = 0)
//! |e(k)| ≤ e_h:  u(k) = 0, I(k) = I(k−1)                                    (hold: valve closed, integral frozen)
//! otherwise:     v = Kp e + I(k−1) + Ki Ts e + Kd D(k)
//!                I(k) = I(k−1) + Ki Ts e unless sat(v) ≠ v and e v > 0       (clamping anti-windup)
//!                u_pi = sat(Kp e + I(k) + Kd D(k)) to ±u_max
//!                u(k) = compensator(u_pi)                                    (deadzone inverse, docs/control.md)
//! ```
//!
//! and, when the error changes sign outside the hold band, the integral restarts from 0
//! (`reset_on_crossing`): after a stick-slip jump past the set-point the integral that broke the piston
//! loose would otherwise push it further away while it unwinds.
//!
//! Why the hold band: a pneumatic piston with static friction cannot move by less than a stick-slip jump;
//! a PI that integrates every residual error then hunts around the set-point in a limit cycle. Inside
//! e_h the valves are closed (both chambers exhaust) and the piston stays where static friction holds it,
//! so |e_ss| ≤ e_h once the band is reached. e_h = 0 turns the hold off.
//!
//! Derivative on the measurement (not on the error), so that a set-point step gives no derivative kick.
//! Units: Kp counts/mm, Ki counts/(mm·s), Kd counts·s/mm, Tf s, e_h mm, u counts.

use serde::{Deserialize, Serialize};

use crate::closed_loop::Controller;
use crate::{ControlError, ControlSetting, DeadzoneCompensator};

/// Largest Kp, Ki, Kd a controller file may hold (counts per mm, per mm·s, s/mm).
pub const MAX_GAIN: f64 = 1e6;
/// Largest band (hold, fine, nudge, rest) a controller file may hold, mm (10 m).
pub const MAX_LENGTH_MM: f64 = 1e4;
/// Largest time constant a controller file may hold, s.
pub const MAX_TIME_S: f64 = 1e4;
/// Largest command limit u_max, counts.
pub const MAX_COMMAND: f64 = 1e6;
/// Largest nudge ramp rate, counts/s.
pub const MAX_RAMP_COUNTS_S: f64 = 1e9;

/// The format name written in a controller file's `format` field.
pub const CONTROLLER_FORMAT: &str = "ipa-sysid-controller";
/// The version of the controller file format.
pub const CONTROLLER_VERSION: u32 = 1;

/// Settings of the tuned position controller (see the module documentation); the `controller` object
/// of CONTROLLER.json.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerSettings {
    /// Ts: sampling period in s (> 0); the controller runs only on a plant with the same Ts.
    pub ts_s: f64,
    /// Kp: proportional gain, counts/mm (>= 0).
    pub kp: f64,
    /// Ki: integral gain, counts/(mm·s) (>= 0); I(k) = I(k−1) + Ki Ts e(k).
    pub ki: f64,
    /// Kd: derivative gain on the measured velocity, counts·s/mm (>= 0).
    pub kd: f64,
    /// Tf: time constant of the first-order filter on the derivative, s (>= 0; 0 = unfiltered).
    pub derivative_filter_s: f64,
    /// u_max: limit of the command, counts (> 0; 255 for the IPA's PWM).
    pub u_max: f64,
    /// e_h: hold band in mm (>= 0): |e| <= e_h closes the valves and freezes the integral.
    pub hold_band_mm: f64,
    /// e_f: fine band in mm (>= 0): for |e| < e_f the compensator's shift is scaled by |e|/e_f, so that
    /// the command is continuous through e = 0 (no jump from b_l to b_r) and the last millimetres are
    /// approached by the integral (0 = the full shift everywhere).
    pub fine_band_mm: f64,
    /// Restart the integral from 0 when e changes sign outside the hold band.
    pub reset_on_crossing: bool,
    /// The nudge mode near the set-point (module documentation); `None` = off (a version-1 file
    /// without the field).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nudge: Option<Nudge>,
    /// The deadzone inverse between the PID and the valve (from the model's deadzone), if any.
    pub compensator: Option<DeadzoneCompensator>,
}

/// The nudge mode: how the controller finishes a move against static friction (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Nudge {
    /// e_n: nudge band, mm (> e_h): for e_h < |e| <= e_n the PID is replaced by nudges.
    pub band_mm: f64,
    /// ρ: ramp rate of a nudge's command, counts/s (> 0).
    pub ramp_counts_s: f64,
    /// β: a nudge starts at β times the last breakaway command of its direction (0 <= β <= 1).
    pub start_fraction: f64,
    /// N_r: samples of unchanged y that count as rest (>= 1); a nudge starts only at rest.
    pub rest_samples: u32,
    /// γ: a nudge ends (valve closed) once the piston has covered γ |e_0| of the error e_0 it started
    /// with, or the error left is at most the learnt coast τ_c |dy/dt| + e_h, or e changed sign
    /// (0 < γ <= 1; the piston coasts on after the valve closes).
    pub cut_fraction: f64,
    /// e_r: rest band, mm: for e_n < |e| <= e_r the nudge mode also acts once the piston has rested
    /// N_r samples (and until the nudge it starts, and the coast after its cut, have ended), so that a
    /// stop short of the nudge band is finished by nudges rather than by a PID whose integral would
    /// take seconds to reach the breakaway command. e_r <= e_n (0 in a file written before it
    /// existed): the nudge band alone, as then.
    #[serde(default)]
    pub rest_band_mm: f64,
}

impl Nudge {
    /// Checks every field; errors name [`ControlSetting::Nudge`].
    pub fn validate(&self, hold_band_mm: f64) -> Result<(), ControlError> {
        let bad = |what: &str, v: f64| {
            Err(ControlError::setting(
                ControlSetting::Nudge,
                crate::trust::fmt_value(v),
                what,
            ))
        };
        if !(self.band_mm.is_finite()
            && self.band_mm > hold_band_mm
            && self.band_mm <= MAX_LENGTH_MM)
        {
            return bad(
                &format!(
                    "a nudge band_mm > hold_band_mm ({}) and at most {MAX_LENGTH_MM:e} mm",
                    crate::trust::fmt_value(hold_band_mm)
                ),
                self.band_mm,
            );
        }
        if !(self.ramp_counts_s.is_finite()
            && self.ramp_counts_s > 0.0
            && self.ramp_counts_s <= MAX_RAMP_COUNTS_S)
        {
            return bad(
                &format!("a nudge ramp_counts_s > 0 and at most {MAX_RAMP_COUNTS_S:e}"),
                self.ramp_counts_s,
            );
        }
        if !(self.start_fraction.is_finite() && (0.0..=1.0).contains(&self.start_fraction)) {
            return bad("a nudge start_fraction in [0, 1]", self.start_fraction);
        }
        if !(self.cut_fraction.is_finite() && self.cut_fraction > 0.0 && self.cut_fraction <= 1.0) {
            return bad("a nudge cut_fraction in (0, 1]", self.cut_fraction);
        }
        if !(self.rest_band_mm.is_finite() && (0.0..=MAX_LENGTH_MM).contains(&self.rest_band_mm)) {
            return bad(
                &format!("a nudge rest_band_mm from 0 to {MAX_LENGTH_MM:e} mm"),
                self.rest_band_mm,
            );
        }
        if self.rest_samples == 0 || self.rest_samples > 1000 {
            return bad(
                "nudge rest_samples from 1 to 1000",
                f64::from(self.rest_samples),
            );
        }
        Ok(())
    }
}

impl ControllerSettings {
    /// A plain PI with clamping anti-windup at Ts = `ts_s`: Kp, Ki, no derivative, u_max = 255 counts, no
    /// hold or fine band, no integral reset, no compensator (the other fields are public to set).
    pub fn pi(ts_s: f64, kp: f64, ki: f64) -> Self {
        ControllerSettings {
            ts_s,
            kp,
            ki,
            kd: 0.0,
            derivative_filter_s: 0.0,
            u_max: crate::PiSettings::U_MAX_PWM,
            hold_band_mm: 0.0,
            fine_band_mm: 0.0,
            reset_on_crossing: false,
            nudge: None,
            compensator: None,
        }
    }

    /// Checks every field; errors name the [`ControlSetting`] at fault. Besides the signs, each
    /// magnitude is bounded far above any actuator's ([`MAX_GAIN`], [`MAX_LENGTH_MM`],
    /// [`MAX_COMMAND`]): a gain of 1e308 is a corrupt file, not a controller.
    pub fn validate(&self) -> Result<(), ControlError> {
        let nonneg = |setting: ControlSetting, v: f64, unit: &str| {
            let max = match unit {
                "mm" => MAX_LENGTH_MM,
                "s" => MAX_TIME_S,
                _ => MAX_GAIN,
            };
            if v.is_finite() && (0.0..=max).contains(&v) {
                Ok(())
            } else {
                Err(ControlError::setting(
                    setting,
                    crate::trust::fmt_value(v),
                    &format!("a number from 0 to {max:e} ({unit})"),
                ))
            }
        };
        if !(self.ts_s.is_finite() && self.ts_s > 0.0 && self.ts_s <= MAX_TIME_S) {
            return Err(ControlError::setting(
                ControlSetting::Ts,
                crate::trust::fmt_value(self.ts_s),
                &format!("a sampling period in s > 0 and at most {MAX_TIME_S:e}"),
            ));
        }
        nonneg(ControlSetting::Kp, self.kp, "counts/mm")?;
        nonneg(ControlSetting::Ki, self.ki, "counts/(mm·s)")?;
        nonneg(ControlSetting::Kd, self.kd, "counts·s/mm")?;
        nonneg(
            ControlSetting::DerivativeFilter,
            self.derivative_filter_s,
            "s",
        )?;
        nonneg(ControlSetting::HoldBand, self.hold_band_mm, "mm")?;
        nonneg(ControlSetting::FineBand, self.fine_band_mm, "mm")?;
        if !(self.u_max.is_finite() && self.u_max > 0.0 && self.u_max <= MAX_COMMAND) {
            return Err(ControlError::setting(
                ControlSetting::UMax,
                crate::trust::fmt_value(self.u_max),
                &format!("a number of counts > 0 and at most {MAX_COMMAND:e}"),
            ));
        }
        if let Some(n) = &self.nudge {
            n.validate(self.hold_band_mm)?;
        }
        if let Some(c) = self.compensator.as_ref().filter(|c| c.u_max != self.u_max) {
            return Err(ControlError::setting(
                ControlSetting::UMax,
                format!("{} (compensator) and {} (controller)", c.u_max, self.u_max),
                "the same command limit in the compensator and the controller",
            ));
        }
        if let Some(c) = &self.compensator {
            // The breakpoints are commands: bounded like u_max (the slopes are checked where the
            // model is read, and only scale the inverse's shift).
            let d = &c.deadzone;
            if !(d.b_l.abs() <= MAX_COMMAND && d.b_r.abs() <= MAX_COMMAND) {
                return Err(ControlError::setting(
                    ControlSetting::Deadzone,
                    format!(
                        "b_l = {}, b_r = {}",
                        crate::trust::fmt_value(d.b_l),
                        crate::trust::fmt_value(d.b_r)
                    ),
                    &format!("breakpoints within ±{MAX_COMMAND:e} counts"),
                ));
            }
            // Rebuilding checks the deadzone and the threshold as `DeadzoneCompensator::new` does.
            DeadzoneCompensator::new(c.deadzone, c.slope_mode, c.u_max)?
                .with_threshold(c.threshold_counts)?;
        }
        Ok(())
    }

    /// Validates the settings and builds the running controller.
    pub fn build(self) -> Result<PositionController, ControlError> {
        self.validate()?;
        let alpha = self.derivative_filter_s / (self.derivative_filter_s + self.ts_s);
        let breakaway = initial_breakaway(&self);
        Ok(PositionController {
            settings: self,
            alpha,
            integral: 0.0,
            derivative: 0.0,
            y_prev: None,
            e_prev: 0.0,
            still: 0,
            nudging: None,
            breakaway,
            cut: None,
            coast: [-1.0, -1.0],
        })
    }
}

/// The breakaway commands (left, right) a controller starts with: |b_l|, |b_r| of its compensator's
/// deadzone (the model's deadzone is where the valve starts to move the piston), 0 without one.
fn initial_breakaway(s: &ControllerSettings) -> [f64; 2] {
    s.compensator
        .as_ref()
        .map_or([0.0, 0.0], |c| [c.deadzone.b_l.abs(), c.deadzone.b_r.abs()])
}

/// A nudge under way: its direction (0 = left, u < 0; 1 = right), the position and error it started
/// from, its command's magnitude u_n, and whether the piston has broken loose.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Nudging {
    side: usize,
    y0_mm: f64,
    e0_mm: f64,
    u_mag: f64,
    moving: bool,
}

/// A running tuned position controller (states: the integral I, the filtered derivative D, the previous
/// measurement and error, the samples at rest, the nudge under way and the learnt breakaway commands).
#[derive(Debug, Clone)]
pub struct PositionController {
    settings: ControllerSettings,
    /// α = Tf / (Tf + Ts).
    alpha: f64,
    /// I(k−1), counts.
    integral: f64,
    /// D(k−1), mm/s.
    derivative: f64,
    /// y(k−1), mm; `None` before the first sample.
    y_prev: Option<f64>,
    /// e(k−1), mm (0 before the first sample).
    e_prev: f64,
    /// Consecutive samples with y(k) = y(k−1).
    still: u32,
    /// The nudge under way, if any.
    nudging: Option<Nudging>,
    /// u_b: the last breakaway command in each direction (left, right), counts.
    breakaway: [f64; 2],
    /// The last nudge's direction, the position where its valve closed and |dy/dt| there (mm/s),
    /// until the piston rests.
    cut: Option<(usize, f64, f64)>,
    /// τ_c: how far the piston coasted on after the last cut in each direction (left, right) per
    /// mm/s of its speed at the cut, s; −1 = not learnt yet.
    coast: [f64; 2],
}

impl PositionController {
    /// The settings it was built from.
    pub fn settings(&self) -> &ControllerSettings {
        &self.settings
    }

    /// I(k) in counts after the last step.
    pub fn integral_counts(&self) -> f64 {
        self.integral
    }

    /// The learnt breakaway commands u_b (left, right), counts.
    pub fn breakaway_counts(&self) -> [f64; 2] {
        self.breakaway
    }

    /// The learnt coasts τ_c (left, right): distance coasted after a cut per mm/s of speed at the
    /// cut, s; −1 = not learnt.
    pub fn coast_s(&self) -> [f64; 2] {
        self.coast
    }

    /// The nudge mode's command at |e| in (e_h, e_n] (module documentation).
    fn nudge(&mut self, n: &Nudge, e: f64, y_mm: f64, dy: f64) -> f64 {
        self.integral = 0.0;
        let s = &self.settings;
        let g = match self.nudging {
            Some(g) => {
                if e * g.e0_mm <= 0.0 || (y_mm != g.y0_mm && self.cut_now(n, &g, e, y_mm, dy)) {
                    self.nudging = None;
                    self.cut = Some((g.side, y_mm, dy.abs()));
                    return 0.0;
                }
                if g.moving {
                    g
                } else if y_mm != g.y0_mm {
                    // The piston broke loose: remember the command that did it and hold it.
                    self.breakaway[g.side] = g.u_mag;
                    Nudging { moving: true, ..g }
                } else {
                    // The same comparison as the no_std controller (bit for bit).
                    let up = g.u_mag + n.ramp_counts_s * s.ts_s;
                    Nudging {
                        u_mag: if up < s.u_max { up } else { s.u_max },
                        ..g
                    }
                }
            }
            None if self.still < n.rest_samples => return 0.0,
            None => {
                if let Some((side, y_cut, v_cut)) = self.cut.take() {
                    // At rest after a cut: how far the piston coasted on with the valve closed,
                    // per mm/s of the speed at the cut.
                    let moved = if side == 1 {
                        y_mm - y_cut
                    } else {
                        y_cut - y_mm
                    };
                    if v_cut > 0.0 {
                        self.coast[side] = if moved > 0.0 { moved / v_cut } else { 0.0 };
                    }
                }
                let side = usize::from(e > 0.0);
                let start = n.start_fraction * self.breakaway[side];
                Nudging {
                    side,
                    y0_mm: y_mm,
                    e0_mm: e,
                    u_mag: if start < s.u_max { start } else { s.u_max },
                    moving: false,
                }
            }
        };
        self.nudging = Some(g);
        if g.side == 1 {
            g.u_mag
        } else {
            -g.u_mag
        }
    }

    /// Whether a nudge that has moved the piston ends now: once it has covered γ |e_0|, or once the
    /// error left is at most τ_c(side) |dy/dt| + e_h, the distance it is expected to coast on
    /// (τ_c learnt after the last cut in its direction; the γ rule alone until then).
    fn cut_now(&self, n: &Nudge, g: &Nudging, e: f64, y_mm: f64, dy: f64) -> bool {
        let coast = self.coast[g.side];
        let left = if g.side == 1 { e } else { -e };
        (y_mm - g.y0_mm).abs() >= n.cut_fraction * g.e0_mm.abs()
            || (coast >= 0.0 && left <= coast * dy.abs() + self.settings.hold_band_mm)
    }
}

impl Controller for PositionController {
    fn ts_s(&self) -> f64 {
        self.settings.ts_s
    }

    fn reset(&mut self) {
        self.integral = 0.0;
        self.derivative = 0.0;
        self.y_prev = None;
        self.e_prev = 0.0;
        self.still = 0;
        self.nudging = None;
        self.breakaway = initial_breakaway(&self.settings);
        self.cut = None;
        self.coast = [-1.0, -1.0];
    }

    fn step(&mut self, r_mm: f64, y_mm: f64) -> f64 {
        let s = &self.settings;
        let e = r_mm - y_mm;
        let dy = match self.y_prev {
            Some(prev) => (y_mm - prev) / s.ts_s,
            None => 0.0,
        };
        self.still = match self.y_prev {
            Some(prev) if prev == y_mm => self.still.saturating_add(1),
            _ => 0,
        };
        self.y_prev = Some(y_mm);
        self.derivative = self.alpha * self.derivative - (1.0 - self.alpha) * dy;
        if e.abs() <= s.hold_band_mm {
            self.e_prev = e;
            if let Some(g) = self.nudging.take() {
                self.cut = Some((g.side, y_mm, dy.abs()));
            }
            return 0.0;
        }
        let resting = self.nudging.is_some() || self.cut.is_some();
        if let Some(n) = s.nudge.filter(|n| {
            e.abs() <= n.band_mm
                || (e.abs() <= n.rest_band_mm && (resting || self.still >= n.rest_samples))
        }) {
            self.e_prev = e;
            return self.nudge(&n, e, y_mm, dy);
        }
        self.nudging = None;
        self.cut = None;
        if s.reset_on_crossing && e * self.e_prev < 0.0 {
            self.integral = 0.0;
        }
        self.e_prev = e;
        let proportional = s.kp * e;
        let integrated = self.integral + s.ki * s.ts_s * e;
        let v = proportional + integrated;
        let u = v.clamp(-s.u_max, s.u_max);
        let u_pi = if u != v && e * v > 0.0 {
            (proportional + self.integral).clamp(-s.u_max, s.u_max)
        } else {
            self.integral = integrated;
            u
        };
        let compensated = match &s.compensator {
            Some(c) if e.abs() < s.fine_band_mm => {
                let w = e.abs() / s.fine_band_mm;
                u_pi + w * (c.apply(u_pi) - u_pi)
            }
            Some(c) => c.apply(u_pi),
            None => u_pi,
        };
        (compensated + s.kd * self.derivative).clamp(-s.u_max, s.u_max)
    }
}

/// Largest controller file read, bytes (one `tune` writes is about 1–2 kB, its provenance included).
pub const MAX_CONTROLLER_BYTES: u64 = 1 << 20;

/// The contents of a controller file (CONTROLLER.json): format, version, the settings, and what the
/// tuning knew (free-form provenance, not read back). Unknown fields are refused at every level (a
/// misspelt key must not be ignored).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerFile {
    /// Always [`CONTROLLER_FORMAT`].
    pub format: String,
    /// [`CONTROLLER_VERSION`].
    pub version: u32,
    /// The controller.
    pub controller: ControllerSettings,
    /// Where it came from (the tuning's source, specification and worst case); ignored when read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provenance: Option<serde_json::Value>,
}

impl ControllerFile {
    /// A file holding `controller` (with optional provenance).
    pub fn new(controller: ControllerSettings, provenance: Option<serde_json::Value>) -> Self {
        ControllerFile {
            format: CONTROLLER_FORMAT.to_string(),
            version: CONTROLLER_VERSION,
            controller,
            provenance,
        }
    }

    /// Parses the JSON text of a controller file named `name` (for messages): errors give the line and
    /// column, a wrong format or version, or the setting out of range.
    pub fn parse(text: &str, name: &str) -> Result<ControllerSettings, ControlError> {
        let f: ControllerFile = serde_json::from_str(text).map_err(|e| {
            ControlError::Config(format!(
                "{name}:{}:{}: not a controller file: {e} (expected the JSON that `ipa-sysid tune --out` writes)",
                e.line(),
                e.column()
            ))
        })?;
        if f.format != CONTROLLER_FORMAT {
            return Err(ControlError::Config(format!(
                "{name}: format `{}` is not `{CONTROLLER_FORMAT}`",
                f.format
            )));
        }
        if f.version != CONTROLLER_VERSION {
            return Err(ControlError::Config(format!(
                "{name}: controller file version {} (this program reads version {CONTROLLER_VERSION})",
                f.version
            )));
        }
        f.controller
            .validate()
            .map_err(|e| ControlError::Config(format!("{name}: {e}")))?;
        Ok(f.controller)
    }

    /// Reads and parses a controller file (at most [`MAX_CONTROLLER_BYTES`], counted as read, so that
    /// a device such as `/dev/zero` is refused, not read until memory runs out); errors name the file.
    pub fn read(path: &std::path::Path) -> Result<ControllerSettings, ControlError> {
        let name = path.display().to_string();
        let text = sysid_core::data::bounded::read_bounded_text(
            path,
            MAX_CONTROLLER_BYTES,
            "a controller file",
            "expected the JSON that `ipa-sysid tune --out` writes (about a kilobyte)",
        )
        .map_err(|e| match e {
            sysid_core::SysidError::Io { path, source } => ControlError::Io { path, source },
            other => ControlError::Config(other.to_string()),
        })?;
        Self::parse(&text, &name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SlopeMode;
    use sysid_core::Deadzone;

    fn plain(kp: f64, ki: f64) -> ControllerSettings {
        ControllerSettings::pi(0.01, kp, ki)
    }

    // Without D, hold or compensator it is the PI with clamping: u(0) = Kp e + Ki Ts e.
    #[test]
    fn without_extras_it_is_the_clamped_pi() {
        let mut c = plain(14.0, 1.0).build().unwrap();
        let mut pi = crate::PiSettings::paper()
            .with_anti_windup(crate::AntiWindup::Clamping)
            .build(0.01)
            .unwrap();
        for (r, y) in [(1.0, 0.0), (1.0, 0.2), (50.0, 0.3), (50.0, 1.0), (0.0, 3.0)] {
            assert_eq!(c.step(r, y), pi.step(r, y));
        }
    }

    // Inside the band: u = 0 and I unchanged; a crossing outside it restarts I.
    #[test]
    fn hold_band_closes_the_valve_and_freezes_the_integral() {
        let mut s = plain(10.0, 100.0);
        s.hold_band_mm = 0.02;
        s.reset_on_crossing = true;
        let mut c = s.build().unwrap();
        // e = 1: I = 100 * 0.01 * 1 = 1, u = 10 + 1.
        assert_eq!(c.step(1.0, 0.0), 11.0);
        assert_eq!(c.step(1.0, 0.99), 0.0);
        assert_eq!(c.integral_counts(), 1.0);
        // e = -0.5 (crossed): I restarts at 0, then -0.5: u = -5 - 0.5.
        assert_eq!(c.step(1.0, 1.5), -5.5);
    }

    // D(k) = α D(k-1) - (1-α) Δy/Ts with α = Tf/(Tf+Ts) = 0.5 at Tf = Ts; Δy = 0.1 mm: -5 mm/s.
    #[test]
    fn derivative_acts_on_the_filtered_measured_velocity() {
        let mut s = plain(0.0, 0.0);
        s.kd = 2.0;
        s.derivative_filter_s = 0.01;
        let mut c = s.build().unwrap();
        assert_eq!(c.step(10.0, 0.0), 0.0);
        assert_eq!(c.step(10.0, 0.1), 2.0 * -5.0);
        // Next: D = 0.5 * -5 - 0.5 * 0 = -2.5.
        assert_eq!(c.step(10.0, 0.1), 2.0 * -2.5);
    }

    #[test]
    fn compensator_shifts_the_command_past_the_deadzone() {
        let mut s = plain(1.0, 0.0);
        let dz = Deadzone {
            b_l: -20.0,
            b_r: 30.0,
            m_l: 1.0,
            m_r: 1.0,
        };
        s.compensator = Some(DeadzoneCompensator::new(dz, SlopeMode::Shift, 255.0).unwrap());
        let mut c = s.build().unwrap();
        assert_eq!(c.step(5.0, 0.0), 35.0);
        assert_eq!(c.step(0.0, 5.0), -25.0);
    }

    fn nudging() -> ControllerSettings {
        let mut s = plain(10.0, 0.0);
        s.hold_band_mm = 0.02;
        s.compensator = Some(
            DeadzoneCompensator::new(
                Deadzone {
                    b_l: -20.0,
                    b_r: 30.0,
                    m_l: 1.0,
                    m_r: 1.0,
                },
                SlopeMode::Shift,
                255.0,
            )
            .unwrap(),
        );
        s.nudge = Some(Nudge {
            band_mm: 1.0,
            ramp_counts_s: 100.0,
            start_fraction: 0.5,
            rest_samples: 2,
            cut_fraction: 0.5,
            rest_band_mm: 0.0,
        });
        s
    }

    // e = 0.5 mm is inside the nudge band (1 mm): the valve stays closed until y has been unchanged for
    // N_r = 2 samples; the nudge then starts at β |b_r| = 0.5 * 30 = 15 counts and ramps by
    // ρ Ts = 100 * 0.01 = 1 count per sample (15, 16, 17); y moves at 17 counts: u_b(right) = 17 is
    // learnt and held; once y has covered γ |e_0| = 0.25 mm the valve closes. The next nudge starts
    // at β u_b = 8.5 counts. Outside the band the PID and the inverse act: 10 e + b_r.
    #[test]
    fn nudge_ramps_from_the_last_breakaway_learns_it_and_cuts() {
        let mut c = nudging().build().unwrap();
        let r = 1.0;
        assert_eq!(c.step(r, 0.5), 0.0); // first sample: not known to be at rest
        assert_eq!(c.step(r, 0.5), 0.0); // at rest 1 sample
        assert_eq!(c.step(r, 0.5), 15.0); // at rest 2 samples: the nudge starts
        assert_eq!(c.step(r, 0.5), 16.0);
        assert_eq!(c.step(r, 0.5), 17.0);
        assert_eq!(c.step(r, 0.6), 17.0); // moved 0.1 < 0.25: held
        assert_eq!(c.breakaway_counts(), [20.0, 17.0]);
        assert_eq!(c.step(r, 0.8), 0.0); // moved 0.3 >= 0.25: cut
        assert_eq!(c.step(r, 0.8), 0.0);
        assert_eq!(c.step(r, 0.8), 8.5);
        assert_eq!(c.step(r, 0.99), 0.0); // hold band
                                          // Past the set-point: a nudge to the left from β |b_l| = 10 counts.
        assert_eq!(c.step(r, 1.3), 0.0);
        assert_eq!(c.step(r, 1.3), 0.0);
        assert_eq!(c.step(r, 1.3), -10.0);
        // e changes sign during a nudge: it ends.
        assert_eq!(c.step(r, 0.9), 0.0);
        // Outside the band: u = Kp e + b_r = 10 * 2 + 30.
        assert_eq!(c.step(3.0, 1.0), 50.0);
        c.reset();
        assert_eq!(c.breakaway_counts(), [20.0, 30.0]);
    }

    // The rest band by hand: e_r = 3 mm, r = 3, y = 0.5 (e = 2.5 mm, outside e_n = 1): the PID acts
    // (10 × 2.5 + b_r = 55) until y has rested N_r = 2 samples, then a nudge starts at β |b_r| = 15,
    // ramps to 16, breaks loose (u_b = 16, held) and is cut at y = 1.8 (moved 1.3 ≥ γ |e_0| = 1.25);
    // while the piston coasts (e = 1.1–1.2 mm) the valve stays closed, and after 2 samples of rest
    // the next nudge starts at β u_b = 8, having learnt τ_c = 0.1 mm / 30 mm/s. Beyond e_r the PID
    // acts again: 10 × 8 + 30. With e_r = 0 (a file without it) the PID acts at every sample.
    #[test]
    fn a_stop_short_of_the_nudge_band_is_finished_by_nudges_in_the_rest_band() {
        let steps = [
            (3.0, 0.5, 55.0, 55.0),
            (3.0, 0.5, 55.0, 55.0),
            (3.0, 0.5, 15.0, 55.0),
            (3.0, 0.5, 16.0, 55.0),
            (3.0, 0.6, 16.0, 54.0),
            (3.0, 1.5, 16.0, 45.0),
            (3.0, 1.8, 0.0, 42.0),
            (3.0, 1.9, 0.0, 41.0),
            (3.0, 1.9, 0.0, 41.0),
            (3.0, 1.9, 8.0, 41.0),
            (10.0, 2.0, 110.0, 110.0),
        ];
        for (e_r, col) in [(3.0, 0), (0.0, 1)] {
            let mut s = nudging();
            s.nudge.as_mut().unwrap().rest_band_mm = e_r;
            let mut c = s.build().unwrap();
            for (k, &(r, y, u_band, u_pid)) in steps.iter().enumerate() {
                let want = if col == 0 { u_band } else { u_pid };
                let u = c.step(r, y);
                assert!(
                    (u - want).abs() < 1e-9,
                    "e_r {e_r}, sample {k}: {u} != {want}"
                );
            }
            if col == 0 {
                assert_eq!(c.breakaway_counts(), [20.0, 16.0]);
                assert_eq!(c.coast_s()[1], (1.9 - 1.8) / ((1.8 - 1.5) / 0.01));
            }
        }
        let mut s = nudging();
        s.nudge.as_mut().unwrap().rest_band_mm = -1.0;
        assert!(s.build().is_err());
        // A file written before the rest band existed reads with e_r = 0.
        let text = serde_json::to_string(&ControllerFile::new(nudging(), None))
            .unwrap()
            .replace(",\"rest_band_mm\":0.0", "");
        assert!(!text.contains("rest_band"));
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), nudging());
    }

    // The learnt coast, by hand (γ = 1, so only the coast rule can end a nudge early): a nudge from
    // y = 0.25 to r = 1 reaches the hold band at 50 mm/s (cut there), coasts on to 1.25 and rests:
    // τ_c(right) = 0.25 mm / 50 mm/s. Then r = 2: the left nudge under way ends (e changed sign; its
    // speed 0 teaches nothing) and a right nudge starts at β u_b = 7.5; at y = 1.875 (37.5 mm/s) the
    // error left, 0.125 mm, is below τ_c × 37.5 + e_h = 0.2075 mm: cut, although the γ rule would
    // hold on (moved 0.625 < 0.75 mm).
    #[test]
    fn a_nudge_ends_where_the_learnt_coast_would_carry_the_piston() {
        let mut s = nudging();
        s.nudge.as_mut().unwrap().cut_fraction = 1.0;
        let mut c = s.build().unwrap();
        let steps = [
            (1.0, 0.25, 0.0),
            (1.0, 0.25, 0.0),
            (1.0, 0.25, 15.0),
            (1.0, 0.5, 15.0),
            (1.0, 1.0, 0.0),
            (1.0, 1.25, 0.0),
            (1.0, 1.25, 0.0),
            (1.0, 1.25, -10.0),
            (2.0, 1.25, 0.0),
            (2.0, 1.25, 7.5),
            (2.0, 1.5, 7.5),
            (2.0, 1.875, 0.0),
        ];
        for (k, (r, y, u)) in steps.into_iter().enumerate() {
            assert_eq!(c.step(r, y), u, "sample {k}");
        }
        assert_eq!(c.coast_s()[1], 0.25 / ((1.0 - 0.5) / 0.01));
        assert_eq!(c.coast_s()[0], -1.0);
        c.reset();
        assert_eq!(c.coast_s(), [-1.0, -1.0]);
    }

    #[test]
    fn a_nudge_band_inside_the_hold_band_is_refused() {
        let mut s = nudging();
        s.nudge.as_mut().unwrap().band_mm = 0.01;
        let e = s.build().unwrap_err();
        assert!(e.to_string().contains("nudge"), "{e}");
        let mut s = nudging();
        s.nudge.as_mut().unwrap().cut_fraction = 0.0;
        assert!(s.build().is_err());
    }

    // A version-1 file written before the nudge mode existed (no `nudge` field) still reads, without it.
    #[test]
    fn a_file_without_a_nudge_reads_as_none() {
        let text = serde_json::to_string(&ControllerFile::new(plain(14.0, 1.0), None)).unwrap();
        assert!(!text.contains("nudge"));
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap().nudge, None);
        let s = nudging();
        let text = serde_json::to_string(&ControllerFile::new(s, None)).unwrap();
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), s);
    }

    #[test]
    fn file_round_trips_and_bad_files_name_the_problem() {
        let s = plain(14.0, 1.0);
        let text = serde_json::to_string_pretty(&ControllerFile::new(s, None)).unwrap();
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), s);
        let e = ControllerFile::parse("{\n  \"format\": 3\n}", "c.json").unwrap_err();
        assert!(e.to_string().contains("c.json:2:"), "{e}");
        let bad = text.replace("\"kp\": 14.0", "\"kp\": -1.0");
        let e = ControllerFile::parse(&bad, "c.json").unwrap_err();
        assert!(e.to_string().contains("kp"), "{e}");
    }
}
