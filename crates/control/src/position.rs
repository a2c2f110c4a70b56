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
//! The step (and the nudge mode, docs/control.md) is implemented once, in `ipa_embedded::PositionController`
//! (no_std, behind the C API); this module holds the settings, their validation and the file format, and
//! runs that implementation in f64.
//! Units: Kp counts/mm, Ki counts/(mm·s), Kd counts·s/mm, Tf s, e_h mm, u counts.

use serde::{Deserialize, Serialize};

use crate::closed_loop::Controller;
use crate::{ControlError, ControlSetting, DeadzoneCompensator};

/// The ranges a controller file's settings are checked against: the embedded controller's own (one
/// range for a file and for `ipa_ctl_init`, audit s28 L-4).
pub use ipa_embedded::position::{
    MAX_COMMAND, MAX_GAIN, MAX_LENGTH_MM, MAX_RAMP_COUNTS_S, MAX_TIME_S,
};

/// The format name written in a controller file's `format` field.
pub const CONTROLLER_FORMAT: &str = "ipa-sysid-controller";
/// The version of the controller file format.
pub const CONTROLLER_VERSION: u32 = 1;

/// Settings of the tuned position controller (see the module documentation); the `controller` object
/// of CONTROLLER.json.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControllerSettings {
    /// Ts: sampling period in s (≥ `ipa_embedded::position::MIN_TS_S` = 1e-6 s); the controller runs
    /// only on a plant with the same Ts.
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
    /// The approach with braking for large steps (module documentation); `None` = off (a file
    /// written before it existed runs as then).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub brake: Option<Brake>,
    /// The short-step approach for small steps (issue 25, session 17); `None` = off (a file written
    /// before it existed runs as then; not written when off).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub short_approach: Option<ShortApproach>,
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
    /// e_c: ramp-and-cut band, mm (>= 0; 0 = off, as in a file written before it existed): a nudge
    /// that starts at |e_0| <= e_c ramps at a(side) |e_0| clamped to [ρ_min, ρ] and ends at the first
    /// encoder count towards r; the rate per mm a(side) (ρ / e_c at first) is learnt from the moves
    /// (docs/control.md).
    #[serde(default)]
    pub cut_band_mm: f64,
    /// ρ_min: ramp-and-cut's slowest ramp, counts/s (0 < ρ_min <= ρ when e_c > 0).
    #[serde(default)]
    pub min_ramp_counts_s: f64,
    /// e_v: ramp-and-cut's creep limit, mm per sample (>= 0; 0 = off, as in a file written before
    /// it existed, and not written then): a ramp-and-cut nudge holds its command while the piston
    /// creeps towards r by at most e_v per sample, ramps on while it rests, and ends when it moves
    /// more than e_v in one sample (a slip beginning), crosses r or reaches the hold band
    /// (issue 25, session 18; docs/control.md).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub creep_step_mm: f64,
    /// a_p: the slip brake's command as a fraction of u_max (0 <= a_p <= 1; 0 = off, as in a file
    /// written before it existed, and not written then): when a nudge ends at a sample in which the
    /// piston moved towards r by more than e_v (e_h without a creep limit), a slip under way, the
    /// valves are reversed (u = −side a_p u_max) until the piston no longer moves towards r, for at
    /// most T_p samples (issue 25, session 19; docs/control.md).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub slip_brake_fraction: f64,
    /// T_p: the slip brake's longest pulse, samples (0..=1000; 0 = off, not written then).
    #[serde(default, skip_serializing_if = "is_zero_u32")]
    pub slip_brake_samples: u32,
    /// Relearn the breakaway command (false = off, as in a file written before it existed, and not
    /// written then): a creeping nudge whose first motion is already a slip learns u_b there, a held
    /// nudge whose piston rests N_r samples after its first count ramps on, and the slip brake lasts
    /// while the piston slips, not while it moves at all (issue 25, session 20; docs/control.md).
    #[serde(default, skip_serializing_if = "is_false")]
    pub relearn: bool,
    /// Learn the held nudge's cut fraction per side, γ(side) = g(side) γ (false = off, as in a file
    /// written before it existed, and not written then): at the rest after a held nudge, a move
    /// short of half its error doubles g(side) (up to 1/γ), a move past r by more than e_h halves
    /// it (down to 1) (issue 25, session 23; docs/control.md).
    #[serde(default, skip_serializing_if = "is_false")]
    pub cut_learn: bool,
}

/// The approach with braking (issue 25, session 14): for a step of at least e_a, the full command
/// towards r until side e ≤ e_s + τ_b v (v: speed towards r, mm/s), then −a_b u_max for T_b samples,
/// then the valves closed until y has rested N_b samples, then the law from a fresh start (the time
/// oracle's open-loop family made a feedback rule; docs/control.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Brake {
    /// e_a: smallest step approached this way, mm (>= 0): |r − y| when r is set or changes.
    pub min_step_mm: f64,
    /// e_s: the full command ends at side e <= e_s + τ_b v, mm (>= 0).
    pub switch_mm: f64,
    /// τ_b: stopping lead per mm/s of speed towards r, s (>= 0).
    pub lead_s: f64,
    /// a_b: braking command as a fraction of u_max, in (0, 1].
    pub strength: f64,
    /// T_b: samples of braking (1 to 1000).
    pub samples: u32,
    /// N_b: samples of unchanged y that end the hold after the brake (1 to 1000).
    pub rest_samples: u32,
    /// κ_b: the lead learnt per direction, in [0, 1] (0 = off, as in a file written before it
    /// existed; issue 25, session 15): at the rest that ends each hold, τ̂ = D / v_sw (D the travel
    /// after the switch, v_sw the speed towards r there) and τ_b(side) moves by κ_b towards
    /// min(τ̂, τ_max), so that the next move that way rests e_s short of r.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub learn: f64,
    /// τ_max: the largest learnt lead, s (>= lead_s when learn > 0; 0 when absent).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub lead_max_s: f64,
    /// T_r: samples over which the braking command falls linearly to 0 after the T_b samples, 0 to
    /// 1000 (0 = at once, as in a file written before it existed; session 15): closed at once, the
    /// valves let the chamber that drove the piston, still at pressure, push it on by several mm.
    #[serde(default, skip_serializing_if = "is_zero_u32")]
    pub release_samples: u32,
    /// Re-brake (issue 25, session 19; false when absent, as in a file written before it existed,
    /// and not written then): during the release and the hold, a sample in which the piston moved
    /// towards r gives the braking command −a_b u_max again, so that a piston resting short of r
    /// under the brake, its driving chamber still at pressure, does not slide past r when the brake
    /// is released.
    #[serde(default, skip_serializing_if = "is_false")]
    pub rebrake: bool,
    /// Preview (issue 25, session 20; false when absent, as in a file written before it existed,
    /// and not written then): the full command ends at the sample whose next one would pass the
    /// switch (side e − v Ts ≤ e_s + τ_b v), with that last sample at the fraction (side e − e_s −
    /// τ_b v)/(v Ts) of u_max: the switch then falls within a sample instead of up to v Ts late.
    #[serde(default, skip_serializing_if = "is_false")]
    pub preview: bool,
}

/// The short-step approach (issue 25, session 17): for a step e_s' < |r − y| ≤ e_m, a drive at U u_max
/// towards r that rises by ρ_a Ts per sample until the piston first moves, until side e ≤ e_s' + τ_s v
/// (v: speed towards r, mm/s), then −a_s u_max for T_s samples, then the valves closed until y has
/// rested N_s samples, then the law from a fresh start. The approach with braking ([`Brake`]) drives
/// the full command, too fast to stop within the 2 % band of a 10 or 30 mm step (docs/control.md).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShortApproach {
    /// e_m: largest step approached this way, mm (> 0): |r − y| when r is set or changes.
    pub max_step_mm: f64,
    /// U: the drive's fraction of u_max, in (0, 1].
    pub drive_fraction: f64,
    /// ρ_a: guard ramp, counts/s (>= 0): the drive rises by ρ_a Ts per sample while the piston has
    /// not moved from where the step began, then is held.
    pub ramp_counts_s: f64,
    /// e_s': the drive ends at side e <= e_s' + τ_s v, mm (>= 0).
    pub switch_mm: f64,
    /// τ_s: stopping lead per mm/s of speed towards r, s (>= 0).
    pub lead_s: f64,
    /// a_s: braking command as a fraction of u_max, in (0, 1].
    pub brake_strength: f64,
    /// T_s: samples of braking (1 to 1000).
    pub brake_samples: u32,
    /// N_s: samples of unchanged y that end the hold after the brake (1 to 1000).
    pub rest_samples: u32,
    /// Preview (issue 25, session 20; false when absent, as before, and not written then): as
    /// [`Brake::preview`], with the drive's command.
    #[serde(default, skip_serializing_if = "is_false")]
    pub preview: bool,
    /// κ_s: breakaway seed (in [0, 1]; issue 25, session 23; 0 when absent, as before, and not
    /// written then): at the drive's switch, where the speed towards r is at most v_s, the nudge's
    /// learnt breakaway u_b(side) is raised to at least κ_s × the drive's held command.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub breakaway_seed: f64,
    /// v_s: the seed only where the speed at the switch is at most v_s, mm/s (>= 0; 0: any speed;
    /// not written when 0).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub seed_speed_mm_s: f64,
}

/// The largest speed a controller file may name, mm/s (a corrupt file, not a controller, beyond).
const MAX_SPEED_MM_S: f64 = 1e6;

impl ShortApproach {
    /// Checks every field; errors name [`ControlSetting::ShortApproach`].
    pub fn validate(&self) -> Result<(), ControlError> {
        let bad = |what: &str, v: String| {
            Err(ControlError::setting(
                ControlSetting::ShortApproach,
                v,
                what,
            ))
        };
        let fmt = crate::trust::fmt_value;
        if !(self.max_step_mm.is_finite()
            && self.max_step_mm > 0.0
            && self.max_step_mm <= MAX_LENGTH_MM)
        {
            return bad(
                &format!("a short_approach max_step_mm > 0 and at most {MAX_LENGTH_MM:e} mm"),
                fmt(self.max_step_mm),
            );
        }
        for (name, v) in [
            ("drive_fraction", self.drive_fraction),
            ("brake_strength", self.brake_strength),
        ] {
            if !(v > 0.0 && v <= 1.0) {
                return bad(&format!("a short_approach {name} in (0, 1]"), fmt(v));
            }
        }
        if !(self.ramp_counts_s.is_finite()
            && (0.0..=MAX_RAMP_COUNTS_S).contains(&self.ramp_counts_s))
        {
            return bad(
                &format!("a short_approach ramp_counts_s from 0 to {MAX_RAMP_COUNTS_S:e}"),
                fmt(self.ramp_counts_s),
            );
        }
        if !(self.switch_mm.is_finite() && (0.0..=MAX_LENGTH_MM).contains(&self.switch_mm)) {
            return bad(
                &format!("a short_approach switch_mm from 0 to {MAX_LENGTH_MM:e} mm"),
                fmt(self.switch_mm),
            );
        }
        if !(self.lead_s.is_finite() && (0.0..=MAX_TIME_S).contains(&self.lead_s)) {
            return bad(
                &format!("a short_approach lead_s from 0 to {MAX_TIME_S:e} s"),
                fmt(self.lead_s),
            );
        }
        if !(0.0..=1.0).contains(&self.breakaway_seed) {
            return bad(
                "a short_approach breakaway_seed in [0, 1]",
                fmt(self.breakaway_seed),
            );
        }
        if !(self.seed_speed_mm_s.is_finite()
            && (0.0..=MAX_SPEED_MM_S).contains(&self.seed_speed_mm_s))
        {
            return bad(
                &format!("a short_approach seed_speed_mm_s from 0 to {MAX_SPEED_MM_S:e} mm/s"),
                fmt(self.seed_speed_mm_s),
            );
        }
        for (name, n) in [
            ("brake_samples", self.brake_samples),
            ("rest_samples", self.rest_samples),
        ] {
            if !(1..=1000).contains(&n) {
                return bad(
                    &format!("short_approach {name} from 1 to 1000"),
                    n.to_string(),
                );
            }
        }
        Ok(())
    }
}

/// Whether an optional number is absent from a file (written as 0 = off).
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Whether an optional switch is absent from a file (written as false = off).
fn is_false(v: &bool) -> bool {
    !*v
}

/// Whether an optional count is absent from a file (written as 0 = off).
fn is_zero_u32(v: &u32) -> bool {
    *v == 0
}

impl Brake {
    /// Checks every field; errors name [`ControlSetting::Brake`].
    pub fn validate(&self) -> Result<(), ControlError> {
        let bad =
            |what: &str, v: String| Err(ControlError::setting(ControlSetting::Brake, v, what));
        let fmt = crate::trust::fmt_value;
        for (name, v) in [
            ("min_step_mm", self.min_step_mm),
            ("switch_mm", self.switch_mm),
        ] {
            if !(v.is_finite() && (0.0..=MAX_LENGTH_MM).contains(&v)) {
                return bad(
                    &format!("a brake {name} from 0 to {MAX_LENGTH_MM:e} mm"),
                    fmt(v),
                );
            }
        }
        if !(self.lead_s.is_finite() && (0.0..=MAX_TIME_S).contains(&self.lead_s)) {
            return bad(
                &format!("a brake lead_s from 0 to {MAX_TIME_S:e} s"),
                fmt(self.lead_s),
            );
        }
        if !(self.strength > 0.0 && self.strength <= 1.0) {
            return bad("a brake strength in (0, 1]", fmt(self.strength));
        }
        if self.release_samples > 1000 {
            return bad(
                "brake release_samples from 0 to 1000",
                self.release_samples.to_string(),
            );
        }
        if !(self.learn.is_finite() && (0.0..=1.0).contains(&self.learn)) {
            return bad("a brake learn in [0, 1] (0 = off)", fmt(self.learn));
        }
        if self.learn > 0.0
            && !(self.lead_max_s.is_finite()
                && self.lead_max_s >= self.lead_s
                && self.lead_max_s <= MAX_TIME_S)
        {
            return bad(
                &format!(
                    "a brake lead_max_s from lead_s ({}) to {MAX_TIME_S:e} s when learn > 0",
                    fmt(self.lead_s)
                ),
                fmt(self.lead_max_s),
            );
        }
        for (name, n) in [
            ("samples", self.samples),
            ("rest_samples", self.rest_samples),
        ] {
            if !(1..=1000).contains(&n) {
                return bad(&format!("brake {name} from 1 to 1000"), n.to_string());
            }
        }
        Ok(())
    }
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
        if !(self.cut_band_mm.is_finite() && (0.0..=MAX_LENGTH_MM).contains(&self.cut_band_mm)) {
            return bad(
                &format!("a nudge cut_band_mm from 0 to {MAX_LENGTH_MM:e} mm"),
                self.cut_band_mm,
            );
        }
        let min_ok = if self.cut_band_mm > 0.0 {
            self.min_ramp_counts_s > 0.0
        } else {
            self.min_ramp_counts_s >= 0.0
        };
        if !(self.min_ramp_counts_s.is_finite()
            && min_ok
            && self.min_ramp_counts_s <= self.ramp_counts_s)
        {
            return bad(
                "a nudge min_ramp_counts_s <= ramp_counts_s, and > 0 when cut_band_mm > 0",
                self.min_ramp_counts_s,
            );
        }
        if !(self.creep_step_mm.is_finite() && (0.0..=MAX_LENGTH_MM).contains(&self.creep_step_mm))
        {
            return bad(
                &format!("a nudge creep_step_mm from 0 to {MAX_LENGTH_MM:e} mm"),
                self.creep_step_mm,
            );
        }
        if !(self.slip_brake_fraction.is_finite()
            && (0.0..=1.0).contains(&self.slip_brake_fraction))
        {
            return bad(
                "a nudge slip_brake_fraction from 0 to 1",
                self.slip_brake_fraction,
            );
        }
        if self.slip_brake_samples > 1000 {
            return bad(
                "a nudge slip_brake_samples from 0 to 1000",
                f64::from(self.slip_brake_samples),
            );
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
            brake: None,
            short_approach: None,
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
        // The range is the embedded controller's (one check, one range): below it the velocity
        // term overflows (audit s19 M-1), above it the integral (audit s21 L-B1).
        let (min_ts, max_ts) = (ipa_embedded::position::MIN_TS_S, ipa_embedded::MAX_TS_S);
        if !ipa_embedded::ts_in_range(self.ts_s) {
            // A tiny Ts as given (1e-310), not fmt_value's "0.0000".
            let shown = if self.ts_s != 0.0 && self.ts_s.abs() < 1e-4 {
                format!("{:e}", self.ts_s)
            } else {
                crate::trust::fmt_value(self.ts_s)
            };
            return Err(ControlError::setting(
                ControlSetting::Ts,
                shown,
                &format!("a sampling period in s from {min_ts:e} to {max_ts:e}"),
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
        if let Some(b) = &self.brake {
            b.validate()?;
        }
        if let Some(a) = &self.short_approach {
            a.validate()?;
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
        let inner =
            ipa_embedded::PositionController::new(self.embedded(), self.embedded_compensator()?)
                .map_err(|e| {
                    ControlError::Config(format!(
                        "the controller settings were refused by the embedded controller: {e:?}"
                    ))
                })?;
        Ok(PositionController {
            settings: self,
            inner,
        })
    }

    /// The same settings for the one implementation of the step, `ipa_embedded::PositionController`
    /// (the controller the firmware and the C API run).
    pub fn embedded(&self) -> ipa_embedded::PositionSettings<f64> {
        ipa_embedded::PositionSettings {
            ts: self.ts_s,
            kp: self.kp,
            ki: self.ki,
            kd: self.kd,
            tf: self.derivative_filter_s,
            u_max: self.u_max,
            hold_band: self.hold_band_mm,
            fine_band: self.fine_band_mm,
            reset_on_crossing: self.reset_on_crossing,
            nudge: self.nudge.map(|n| ipa_embedded::position::NudgeSettings {
                band: n.band_mm,
                ramp: n.ramp_counts_s,
                start_fraction: n.start_fraction,
                rest_samples: n.rest_samples,
                cut_fraction: n.cut_fraction,
                rest_band: n.rest_band_mm,
                cut_band: n.cut_band_mm,
                min_ramp: n.min_ramp_counts_s,
                creep_step: n.creep_step_mm,
                slip_brake: n.slip_brake_fraction,
                slip_brake_samples: n.slip_brake_samples,
                relearn: n.relearn,
                cut_learn: n.cut_learn,
            }),
            brake: self.brake.map(|b| ipa_embedded::position::BrakeSettings {
                min_step: b.min_step_mm,
                switch: b.switch_mm,
                lead: b.lead_s,
                strength: b.strength,
                samples: b.samples,
                rest_samples: b.rest_samples,
                learn: b.learn,
                lead_max: b.lead_max_s,
                release: b.release_samples,
                rebrake: b.rebrake,
                preview: b.preview,
            }),
            short: self
                .short_approach
                .map(|a| ipa_embedded::ShortApproachSettings {
                    max_step: a.max_step_mm,
                    drive_fraction: a.drive_fraction,
                    ramp: a.ramp_counts_s,
                    switch: a.switch_mm,
                    lead: a.lead_s,
                    strength: a.brake_strength,
                    samples: a.brake_samples,
                    rest_samples: a.rest_samples,
                    preview: a.preview,
                    seed: a.breakaway_seed,
                    seed_speed: a.seed_speed_mm_s,
                }),
        }
    }

    /// The deadzone inverse as the embedded controller takes it (the same map as
    /// [`DeadzoneCompensator::apply`]).
    fn embedded_compensator(&self) -> Result<Option<ipa_embedded::Compensator<f64>>, ControlError> {
        let Some(c) = &self.compensator else {
            return Ok(None);
        };
        let d = c.deadzone;
        let mode = match c.slope_mode {
            crate::SlopeMode::Shift => ipa_embedded::SlopeMode::Shift,
            crate::SlopeMode::Equalise => ipa_embedded::SlopeMode::Equalise,
        };
        ipa_embedded::Compensator::new(
            ipa_embedded::Deadzone {
                b_l: d.b_l,
                b_r: d.b_r,
                m_l: d.m_l,
                m_r: d.m_r,
            },
            mode,
            c.threshold_counts,
            c.u_max,
        )
        .map(Some)
        .map_err(|e| {
            ControlError::Config(format!(
                "the deadzone inverse was refused by the embedded controller: {e:?}"
            ))
        })
    }
}

/// A running tuned position controller: the settings and the one implementation of its step,
/// `ipa_embedded::PositionController<f64>` (states: the integral I, the filtered derivative D, the
/// previous measurement and error, the samples at rest, the nudge under way, the learnt breakaway
/// commands and coasts). The firmware, the C API and `control` run the same code.
#[derive(Debug, Clone)]
pub struct PositionController {
    settings: ControllerSettings,
    inner: ipa_embedded::PositionController<f64>,
}

impl PositionController {
    /// The settings it was built from.
    pub fn settings(&self) -> &ControllerSettings {
        &self.settings
    }

    /// I(k) in counts after the last step.
    pub fn integral_counts(&self) -> f64 {
        self.inner.integral()
    }

    /// The learnt breakaway commands u_b (left, right), counts.
    pub fn breakaway_counts(&self) -> [f64; 2] {
        self.inner.breakaway()
    }

    /// The learnt coasts τ_c (left, right): distance coasted after a cut per mm/s of speed at the
    /// cut, s; −1 = not learnt.
    pub fn coast_s(&self) -> [f64; 2] {
        self.inner.coast()
    }

    /// The approach's leads τ_b (left, right), s: as set, or learnt (`brake.learn`).
    pub fn brake_lead_s(&self) -> [f64; 2] {
        self.inner.brake_lead()
    }
}

impl Controller for PositionController {
    fn ts_s(&self) -> f64 {
        self.settings.ts_s
    }

    fn reset(&mut self) {
        self.inner.reset();
    }

    fn restart(&mut self) {
        self.inner.restart();
    }

    /// One sample; a non-finite r or y, or a command that would not be finite, gives NaN (and leaves
    /// the state unchanged).
    fn step(&mut self, r_mm: f64, y_mm: f64) -> f64 {
        self.inner.step(r_mm, y_mm).unwrap_or(f64::NAN)
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
        Self::parse_file(text, name).map(|f| f.controller)
    }

    /// [`ControllerFile::parse`], keeping the file's provenance (what `tune` said of the controller).
    pub fn parse_file(text: &str, name: &str) -> Result<ControllerFile, ControlError> {
        // A model file or a CSV record given as the controller is said as such (audit s26 L-1: "unknown
        // field `model`"), by the readers' one sniffing helper.
        use sysid_core::data::Sniffed;
        let head = &text.as_bytes()[..text.len().min(4096)];
        if let Some(k @ (Sniffed::ModelFile | Sniffed::Csv | Sniffed::Toml | Sniffed::Mat)) =
            Sniffed::of(head)
        {
            return Err(ControlError::Config(format!(
                "{name}: this is {}, not a controller file (the JSON that `ipa-sysid tune --out` writes)",
                k.describe()
            )));
        }
        let f: ControllerFile = serde_json::from_str(text).map_err(|e| {
            // serde's message quotes the file (an unknown field's name): printed through `visible`.
            ControlError::Config(format!(
                "{name}:{}:{}: not a controller file: {} (expected the JSON that `ipa-sysid tune --out` writes)",
                e.line(),
                e.column(),
                sysid_core::format::visible(&e.to_string())
            ))
        })?;
        if f.format != CONTROLLER_FORMAT {
            return Err(ControlError::Config(format!(
                "{name}: format `{}` is not `{CONTROLLER_FORMAT}`",
                sysid_core::format::visible(&f.format)
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
        Ok(f)
    }

    /// Reads and parses a controller file (at most [`MAX_CONTROLLER_BYTES`], counted as read, so that
    /// a device such as `/dev/zero` is refused, not read until memory runs out); errors name the file.
    pub fn read(path: &std::path::Path) -> Result<ControllerSettings, ControlError> {
        Self::read_file(path).map(|f| f.controller)
    }

    /// [`ControllerFile::read`], keeping the file's provenance.
    pub fn read_file(path: &std::path::Path) -> Result<ControllerFile, ControlError> {
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
        Self::parse_file(&text, &name)
    }

    /// What of a present provenance cannot be read, in one warning naming each part ignored (audit s32
    /// L-1): the provenance is optional and free-form by design (a hand-written controller has none;
    /// docs/control.md), so a malformed one does not refuse the controller, but the parts the tool reads
    /// — `meets_spec` (true/false), `met` ({steps, of: whole numbers, on: text}), `source` (text),
    /// `spec` (an object, its `ess_all_mm` a number ≥ 0) — of another type, a provenance that is not an
    /// object, and keys `tune` never writes are said, not dropped without a word. `None` for a
    /// provenance `tune` wrote, or none at all.
    pub fn provenance_unread(&self) -> Option<String> {
        use serde_json::Value;
        let p = self.provenance.as_ref()?;
        let Some(obj) = p.as_object() else {
            return Some(format!(
                "the controller file's provenance is not a JSON object but {}: ignored (nothing \
                 of where the controller was tuned or of its specification is checked)",
                json_kind(p)
            ));
        };
        let mut bad: Vec<String> = Vec::new();
        let mut unknown: Vec<String> = Vec::new();
        for (key, v) in obj {
            let shown = sysid_core::format::visible(key);
            let ok = match key.as_str() {
                "meets_spec" => v.is_boolean(),
                "source" | "tuned_by" => v.is_string(),
                "met" => v.as_object().is_some_and(|m| {
                    m.get("steps").is_some_and(Value::is_u64)
                        && m.get("of").is_some_and(Value::is_u64)
                        && m.get("on").is_some_and(Value::is_string)
                }),
                "spec" => v.as_object().is_some_and(|s| {
                    s.get("ess_all_mm")
                        .is_none_or(|e| e.as_f64().is_some_and(|e| e.is_finite() && e >= 0.0))
                }),
                _ => {
                    unknown.push(format!("`{shown}`"));
                    continue;
                }
            };
            if !ok {
                let expected = match key.as_str() {
                    "meets_spec" => "true or false",
                    "source" | "tuned_by" => "text",
                    "met" => "{\"steps\": N, \"of\": N, \"on\": \"...\"}",
                    _ => "an object whose ess_all_mm is a number >= 0",
                };
                bad.push(format!(
                    "`{shown}` is {} (expected {expected})",
                    json_kind(v)
                ));
            }
        }
        if bad.is_empty() && unknown.is_empty() {
            return None;
        }
        let mut parts = bad;
        if !unknown.is_empty() {
            parts.push(format!(
                "{} {} not written by `tune`",
                unknown.join(", "),
                if unknown.len() == 1 { "is" } else { "are" }
            ));
        }
        Some(format!(
            "the controller file's provenance cannot be read in part: {}; ignored (the checks of \
             where the controller was tuned and of the specification it was tuned for use only what \
             is readable)",
            parts.join("; ")
        ))
    }

    /// What the provenance says against the controller, in words (audit s17 L-m): `tune` wrote
    /// `"meets_spec": false`, with the steps that met the whole specification when it recorded them
    /// (the record's name through [`sysid_core::format::visible`]: audit s22 M-B5).
    /// `None` when it met it, or the file has no such provenance (a hand-written controller).
    pub fn provenance_warning(&self) -> Option<String> {
        let p = self.provenance.as_ref()?;
        if p.get("meets_spec")?.as_bool()? {
            return None;
        }
        let met = p
            .get("met")
            .and_then(|m| {
                Some(format!(
                    "; the whole specification met in {} of {} steps on {}",
                    m.get("steps")?.as_u64()?,
                    m.get("of")?.as_u64()?,
                    sysid_core::format::visible(m.get("on")?.as_str()?)
                ))
            })
            .unwrap_or_default();
        Some(format!(
            "the controller file says it does not meet the specification it was tuned for \
             (provenance meets_spec = false{met}); see the warnings of the `tune` that wrote it"
        ))
    }
}

/// A JSON value's kind in words, with a short value (for [`ControllerFile::provenance_unread`]).
fn json_kind(v: &serde_json::Value) -> String {
    use serde_json::Value;
    match v {
        Value::Null => "null".into(),
        Value::Bool(b) => format!("the boolean {b}"),
        Value::Number(n) => format!("the number {n}"),
        Value::String(t) => format!(
            "the text \"{}\"",
            sysid_core::format::visible(
                &sysid_core::error::cut_chars(t, 40).unwrap_or_else(|| t.clone())
            )
        ),
        Value::Array(a) => format!("an array of {} values", a.len()),
        Value::Object(_) => "an object".into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::SlopeMode;
    use sysid_core::Deadzone;

    // Audit s22 M-B5: strings of a controller file (the record its provenance names, an unknown key,
    // its format) are printed as visible escapes, never as the raw ESC / BEL that would clear the
    // terminal or ring it.
    #[test]
    fn a_controller_files_strings_are_printed_visibly() {
        let file = ControllerFile::new(
            plain(1.0, 0.0),
            Some(serde_json::json!({
                "meets_spec": false,
                "met": {"steps": 0, "of": 8, "on": "X\u{1b}[2J\u{7}"}
            })),
        );
        let w = file.provenance_warning().unwrap();
        assert!(
            w.contains("met in 0 of 8 steps on X\\u{1b}[2J\\u{7}"),
            "{w}"
        );
        assert!(!w.contains('\u{1b}') && !w.contains('\u{7}'), "{w}");
        let text = serde_json::to_string(&file).unwrap();
        let renamed = text.replacen("\"provenance\"", "\"prov\\u001b[2J\"", 1);
        let e = ControllerFile::parse_file(&renamed, "c.json")
            .unwrap_err()
            .to_string();
        assert!(e.contains("prov\\u{1b}[2J") && !e.contains('\u{1b}'), "{e}");
        let other = text.replacen(CONTROLLER_FORMAT, "x\\u001b[2J", 1);
        let e = ControllerFile::parse_file(&other, "c.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("format `x\\u{1b}[2J`") && !e.contains('\u{1b}'),
            "{e}"
        );
    }

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
            cut_band_mm: 0.0,
            min_ramp_counts_s: 0.0,
            creep_step_mm: 0.0,
            slip_brake_fraction: 0.0,
            slip_brake_samples: 0,
            relearn: false,
            cut_learn: false,
        });
        s
    }

    // The step itself is `ipa_embedded::PositionController`'s (its tests derive the nudge mode, the
    // rest band and the learnt coast by hand); here: the settings reach it. The nudge case of those
    // tests (deadzone b_l = −20, b_r = 30, e_n = 1 mm, ρ Ts = 1 count, β = 0.5, N_r = 2): closed until
    // y has rested 2 samples, then 15, 16 counts; the learnt breakaway and reset come back through
    // this wrapper.
    #[test]
    fn the_nudge_settings_reach_the_embedded_step() {
        let mut c = nudging().build().unwrap();
        let u: Vec<f64> = [0.5, 0.5, 0.5, 0.5, 0.6]
            .iter()
            .map(|&y| c.step(1.0, y))
            .collect();
        assert_eq!(u, [0.0, 0.0, 15.0, 16.0, 16.0]);
        assert_eq!(c.breakaway_counts(), [20.0, 16.0]);
        assert_eq!(c.coast_s(), [-1.0, -1.0]);
        assert!(c.step(f64::NAN, 0.6).is_nan());
        c.reset();
        assert_eq!(c.breakaway_counts(), [20.0, 30.0]);
    }

    #[test]
    fn a_file_without_a_rest_band_reads_with_e_r_zero() {
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

    // The creep limit e_v reaches the embedded step (whose test derives it by hand): ramp-and-cut
    // within e_c = 0.5 mm, a = ρ / e_c = 200 counts/(s·mm), e_0 = 0.4 mm: ρ_n = 80 counts/s from
    // β |b_r| = 15: 15, 15.8, 16.6; the first count is held with e_v = 0.015 mm (16.6) and cut
    // without it (0). Written only when set; a negative one is refused by name.
    #[test]
    fn the_creep_limit_reaches_the_embedded_step_and_round_trips() {
        let with = |creep_step_mm: f64| {
            let mut s = nudging();
            let n = s.nudge.as_mut().unwrap();
            (n.cut_band_mm, n.min_ramp_counts_s, n.creep_step_mm) = (0.5, 20.0, creep_step_mm);
            s
        };
        for (creep, last) in [(0.015, 16.6), (0.0, 0.0)] {
            let mut c = with(creep).build().unwrap();
            let u: Vec<f64> = [0.6, 0.6, 0.6, 0.6, 0.6, 0.61]
                .iter()
                .map(|&y| c.step(1.0, y))
                .collect();
            let want = [0.0, 0.0, 15.0, 15.8, 16.6, last];
            for (k, (g, w)) in u.iter().zip(want).enumerate() {
                assert!((g - w).abs() < 1e-9, "e_v {creep}, sample {k}: {g} != {w}");
            }
        }
        let text = serde_json::to_string_pretty(&ControllerFile::new(with(0.015), None)).unwrap();
        assert!(text.contains("\"creep_step_mm\": 0.015"), "{text}");
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), with(0.015));
        let bad = text.replace("\"creep_step_mm\": 0.015", "\"creep_step_mm\": -1.0");
        let e = ControllerFile::parse(&bad, "c.json").unwrap_err();
        assert!(e.to_string().contains("creep_step_mm"), "{e}");
        // Off (every file before session 18): not written, and read as 0.
        let off = serde_json::to_string(&ControllerFile::new(with(0.0), None)).unwrap();
        assert!(!off.contains("creep"));
        assert_eq!(ControllerFile::parse(&off, "c.json").unwrap(), with(0.0));
    }

    // The slip brake reaches the embedded step (whose test derives it by hand): a held nudge
    // (γ = 0.5, β = 0.5, ρ = 100, N_r = 2) from 0.6 towards 1 starts at β |b_r| = 15, ramps to 16,
    // holds at the first count (0.65) and is cut at 0.85 (a move of 0.2 mm in that sample, above
    // e_h = 0.02): u = −a_p u_max = −0.2 × 255 = −51 with the slip brake, 0 without. Written only
    // when set; a_p above 1 and T_p above 1000 are refused by name.
    #[test]
    fn the_slip_brake_reaches_the_embedded_step_and_round_trips() {
        let with = |a_p: f64, t_p: u32| {
            let mut s = nudging();
            let n = s.nudge.as_mut().unwrap();
            (n.slip_brake_fraction, n.slip_brake_samples) = (a_p, t_p);
            s
        };
        for ((a_p, t_p), last) in [((0.2, 3), -51.0), ((0.0, 0), 0.0)] {
            let mut c = with(a_p, t_p).build().unwrap();
            let u: Vec<f64> = [0.6, 0.6, 0.6, 0.6, 0.65, 0.85]
                .iter()
                .map(|&y| c.step(1.0, y))
                .collect();
            let want = [0.0, 0.0, 15.0, 16.0, 16.0, last];
            for (k, (g, w)) in u.iter().zip(want).enumerate() {
                assert!((g - w).abs() < 1e-9, "a_p {a_p}, sample {k}: {g} != {w}");
            }
        }
        let text = serde_json::to_string_pretty(&ControllerFile::new(with(0.2, 3), None)).unwrap();
        assert!(text.contains("\"slip_brake_fraction\": 0.2"), "{text}");
        assert!(text.contains("\"slip_brake_samples\": 3"), "{text}");
        assert_eq!(
            ControllerFile::parse(&text, "c.json").unwrap(),
            with(0.2, 3)
        );
        for (from, to, name) in [
            (
                "\"slip_brake_fraction\": 0.2",
                "\"slip_brake_fraction\": 1.5",
                "slip_brake_fraction",
            ),
            (
                "\"slip_brake_samples\": 3",
                "\"slip_brake_samples\": 1001",
                "slip_brake_samples",
            ),
        ] {
            let e = ControllerFile::parse(&text.replace(from, to), "c.json").unwrap_err();
            assert!(e.to_string().contains(name), "{e}");
        }
        // Off (every file before session 19): not written, and read as 0.
        let off = serde_json::to_string(&ControllerFile::new(with(0.0, 0), None)).unwrap();
        assert!(!off.contains("slip"));
        assert_eq!(ControllerFile::parse(&off, "c.json").unwrap(), with(0.0, 0));
    }

    // The relearning reaches the embedded step (whose tests derive it by hand): the held nudge of
    // the slip brake's test from 0.6 towards 1 (β |b_r| = 15, 16, the first count at 0.61 learns
    // u_b = 16) sticks at 0.61; with the relearning, at rest for more than N_r = 2 samples after the
    // count, it ramps on to 17, 18; without it, it holds 16. Written only when on (`"relearn":
    // true`), read as off from a file without it; a value that is not a bool is refused at its line.
    #[test]
    fn the_relearning_reaches_the_embedded_step_and_round_trips() {
        let with = |relearn: bool| {
            let mut s = nudging();
            s.nudge.as_mut().unwrap().relearn = relearn;
            s
        };
        let ys = [0.6, 0.6, 0.6, 0.6, 0.61, 0.61, 0.61, 0.61, 0.61];
        for (relearn, tail) in [(true, [17.0, 18.0]), (false, [16.0, 16.0])] {
            let mut c = with(relearn).build().unwrap();
            let u: Vec<f64> = ys.iter().map(|&y| c.step(1.0, y)).collect();
            let want = [0.0, 0.0, 15.0, 16.0, 16.0, 16.0, 16.0, tail[0], tail[1]];
            for (k, (g, w)) in u.iter().zip(want).enumerate() {
                assert!(
                    (g - w).abs() < 1e-9,
                    "relearn {relearn}, sample {k}: {g} != {w}"
                );
            }
        }
        let text = serde_json::to_string_pretty(&ControllerFile::new(with(true), None)).unwrap();
        assert!(text.contains("\"relearn\": true"), "{text}");
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), with(true));
        let bad = text.replace("\"relearn\": true", "\"relearn\": 1");
        let e = ControllerFile::parse(&bad, "c.json").unwrap_err();
        let line = 1 + bad.lines().position(|l| l.contains("relearn")).unwrap();
        assert!(
            e.to_string().contains(&format!("c.json:{line}:")) && e.to_string().contains("boolean"),
            "{e}"
        );
        // Off (every file before session 20): not written, and read as off.
        let off = serde_json::to_string(&ControllerFile::new(with(false), None)).unwrap();
        assert!(!off.contains("relearn"));
        assert_eq!(ControllerFile::parse(&off, "c.json").unwrap(), with(false));
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

    fn with_brake(switch_mm: f64) -> ControllerSettings {
        ControllerSettings {
            brake: Some(Brake {
                min_step_mm: 10.0,
                switch_mm,
                lead_s: 0.0,
                strength: 0.5,
                samples: 1,
                rest_samples: 1,
                learn: 0.0,
                lead_max_s: 0.0,
                release_samples: 0,
                rebrake: false,
                preview: false,
            }),
            ..plain(1.0, 0.0)
        }
    }

    // The brake's fields reach the embedded step: r = 20 from y = 0 with the switch at e_s = 1000 mm
    // brakes at once, −a_b u_max = −127.5; with e_s = 1 mm the first command is the full +255.
    #[test]
    fn the_brake_settings_reach_the_embedded_step() {
        let mut c = with_brake(1000.0).build().unwrap();
        assert_eq!(c.step(20.0, 0.0), -127.5);
        let mut c = with_brake(1.0).build().unwrap();
        assert_eq!(c.step(20.0, 0.0), 255.0);
    }

    // The re-brake reaches the embedded step: r = 20 from y = 0 with e_s = 1000 mm brakes at once
    // (−127.5, T_b = 1), then the hold (N_b = 3: y unchanged once, 0); a count towards r there
    // (y = 0.01) gives −127.5 again with the re-brake, 0 without it.
    #[test]
    fn the_rebrake_reaches_the_embedded_step() {
        let mut s = with_brake(1000.0);
        s.brake.as_mut().unwrap().rest_samples = 3;
        for (rebrake, want) in [(true, -127.5), (false, 0.0)] {
            s.brake.as_mut().unwrap().rebrake = rebrake;
            let mut c = s.build().unwrap();
            assert_eq!(c.step(20.0, 0.0), -127.5);
            assert_eq!(c.step(20.0, 0.0), 0.0);
            assert_eq!(c.step(20.0, 0.01), want, "rebrake {rebrake}");
        }
    }

    // Off (every file before session 19): `rebrake` not written, read as false; on: written as true
    // and read back; a number instead of a boolean is refused at its line.
    #[test]
    fn a_rebrake_round_trips_and_is_not_written_when_off() {
        let s = with_brake(1.0);
        let text = serde_json::to_string_pretty(&ControllerFile::new(s, None)).unwrap();
        assert!(!text.contains("rebrake"));
        assert!(
            !ControllerFile::parse(&text, "c.json")
                .unwrap()
                .brake
                .unwrap()
                .rebrake
        );
        let mut on = s;
        on.brake.as_mut().unwrap().rebrake = true;
        let text = serde_json::to_string_pretty(&ControllerFile::new(on, None)).unwrap();
        assert!(text.contains("\"rebrake\": true"));
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), on);
        let bad = text.replace("\"rebrake\": true", "\"rebrake\": 1");
        let line = 1 + bad.lines().position(|l| l.contains("rebrake")).unwrap();
        let e = ControllerFile::parse(&bad, "c.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("c.json:{line}:")) && e.contains("boolean"),
            "{e}"
        );
    }

    // Off (every file before session 20): `preview` written in neither approach, read as false; on:
    // written as true in each and read back; a number instead of a boolean is refused at its line.
    // Through the embedded step: r = 20 from y = 0, 1, 2, 3.5 (v = 150 mm/s, e = 16.5 > e_s + τ_b v
    // = 1 + 0.1 × 150 = 16 ≥ 16.5 − 1.5): with the preview the last full-command sample is (16.5 −
    // 16)/1.5 = 1/3 of 255, 85 counts; without it 255.
    #[test]
    fn a_preview_round_trips_is_not_written_when_off_and_reaches_the_embedded_step() {
        let mut s = with_brake(1.0);
        s.brake.as_mut().unwrap().lead_s = 0.1;
        s.short_approach = with_short(5.0).short_approach;
        let text = serde_json::to_string_pretty(&ControllerFile::new(s, None)).unwrap();
        assert!(!text.contains("preview"));
        let read = ControllerFile::parse(&text, "c.json").unwrap();
        assert!(!read.brake.unwrap().preview && !read.short_approach.unwrap().preview);
        let mut on = s;
        on.brake.as_mut().unwrap().preview = true;
        on.short_approach.as_mut().unwrap().preview = true;
        let text = serde_json::to_string_pretty(&ControllerFile::new(on, None)).unwrap();
        assert_eq!(text.matches("\"preview\": true").count(), 2);
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), on);
        let bad = text.replacen("\"preview\": true", "\"preview\": 1", 1);
        let line = 1 + bad
            .lines()
            .position(|l| l.contains("\"preview\": 1"))
            .unwrap();
        let e = ControllerFile::parse(&bad, "c.json")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(&format!("c.json:{line}:")) && e.contains("boolean"),
            "{e}"
        );
        for (settings, want) in [(on, 85.0), (s, 255.0)] {
            let mut c = settings.build().unwrap();
            let u: Vec<f64> = [0.0, 1.0, 2.0, 3.5]
                .iter()
                .map(|&y| c.step(20.0, y))
                .collect();
            assert_eq!(&u[..3], &[255.0; 3]);
            assert!((u[3] - want).abs() < 1e-9, "{u:?}");
        }
    }

    #[test]
    fn a_brake_round_trips_and_a_bad_one_is_refused_by_name() {
        let s = with_brake(1.0);
        let text = serde_json::to_string_pretty(&ControllerFile::new(s, None)).unwrap();
        assert!(text.contains("\"brake\""));
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), s);
        let bad = text.replace("\"strength\": 0.5", "\"strength\": 2.0");
        let e = ControllerFile::parse(&bad, "c.json").unwrap_err();
        assert!(e.to_string().contains("brake"), "{e}");
        let bad = text.replace("\"samples\": 1,", "\"samples\": 1, \"extra\": 1,");
        assert!(ControllerFile::parse(&bad, "c.json").is_err());
        // Session 14's brake (no learn, no lead_max_s) reads with the learning off and writes as it
        // was read; learn outside [0, 1], or lead_max_s below lead_s while learning, are refused.
        assert!(!text.contains("learn") && !text.contains("lead_max_s"));
        let learning = text.replace(
            "\"rest_samples\": 1\n",
            "\"rest_samples\": 1, \"learn\": 0.5, \"lead_max_s\": 0.1\n",
        );
        let read = ControllerFile::parse(&learning, "c.json").unwrap();
        let b = read.brake.unwrap();
        assert_eq!((b.learn, b.lead_max_s), (0.5, 0.1));
        let again = serde_json::to_string(&ControllerFile::new(read, None)).unwrap();
        assert!(again.contains("\"learn\":0.5") && again.contains("\"lead_max_s\":0.1"));
        let released = text.replace(
            "\"rest_samples\": 1\n",
            "\"rest_samples\": 1, \"release_samples\": 10\n",
        );
        assert_eq!(
            ControllerFile::parse(&released, "c.json")
                .unwrap()
                .brake
                .unwrap()
                .release_samples,
            10
        );
        for bad in [
            "\"release_samples\": 1001",
            "\"learn\": 1.5, \"lead_max_s\": 0.1",
            "\"learn\": 0.5, \"lead_max_s\": -0.1",
        ] {
            let text = text.replace(
                "\"rest_samples\": 1\n",
                &format!("\"rest_samples\": 1, {bad}\n"),
            );
            let e = ControllerFile::parse(&text, "c.json").unwrap_err();
            assert!(e.to_string().contains("brake"), "{e}");
        }
        // A file without one (every file before session 14) reads as none.
        assert!(
            !serde_json::to_string(&ControllerFile::new(plain(1.0, 0.0), None))
                .unwrap()
                .contains("brake")
        );
    }

    fn with_short(max_step_mm: f64) -> ControllerSettings {
        ControllerSettings {
            short_approach: Some(ShortApproach {
                max_step_mm,
                drive_fraction: 0.4,
                ramp_counts_s: 500.0,
                switch_mm: 0.5,
                lead_s: 0.01,
                brake_strength: 0.25,
                brake_samples: 3,
                rest_samples: 2,
                preview: false,
                breakaway_seed: 0.0,
                seed_speed_mm_s: 0.0,
            }),
            ..plain(1.0, 0.0)
        }
    }

    // The short-step approach's fields reach the embedded step: r = 10 from y = 0 (<= e_m = 40 mm)
    // starts with U u_max = 0.4 × 255 = 102 and, y unchanged, rises by ρ_a Ts = 5 (107); with e_m =
    // 5 mm the same step is the law's, Kp e = 10.
    #[test]
    fn the_short_step_settings_reach_the_embedded_step() {
        let mut c = with_short(40.0).build().unwrap();
        assert_eq!(c.step(10.0, 0.0), 102.0);
        assert_eq!(c.step(10.0, 0.0), 107.0);
        let mut c = with_short(5.0).build().unwrap();
        assert_eq!(c.step(10.0, 0.0), 10.0);
    }

    #[test]
    fn a_short_step_approach_round_trips_and_a_bad_one_is_refused_by_name() {
        let s = with_short(40.0);
        let text = serde_json::to_string_pretty(&ControllerFile::new(s, None)).unwrap();
        assert!(text.contains("\"short_approach\""));
        assert_eq!(ControllerFile::parse(&text, "c.json").unwrap(), s);
        for (good, bad) in [
            ("\"drive_fraction\": 0.4", "\"drive_fraction\": 0.0"),
            ("\"max_step_mm\": 40.0", "\"max_step_mm\": -1.0"),
            ("\"brake_samples\": 3", "\"brake_samples\": 0"),
            ("\"ramp_counts_s\": 500.0", "\"ramp_counts_s\": -5.0"),
        ] {
            assert!(text.contains(good), "{good}");
            let e = ControllerFile::parse(&text.replace(good, bad), "c.json").unwrap_err();
            assert!(e.to_string().contains("short_approach"), "{e}");
        }
        let extra = text.replace("\"rest_samples\": 2", "\"rest_samples\": 2, \"extra\": 1");
        assert!(ControllerFile::parse(&extra, "c.json").is_err());
        // Off (every file before session 17): not written, and read as none.
        let plain_text =
            serde_json::to_string(&ControllerFile::new(plain(1.0, 0.0), None)).unwrap();
        assert!(!plain_text.contains("short"));
        assert_eq!(
            ControllerFile::parse(&plain_text, "c.json")
                .unwrap()
                .short_approach,
            None
        );
    }
}
