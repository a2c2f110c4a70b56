//! The tuned position controller of `ipa-sysid tune` (CONTROLLER.json) for firmware: PID with clamping
//! anti-windup, a deadzone inverse scaled in a fine band, and a hold band against stick-slip hunting.
//!
//! The one implementation of the step: `control::PositionController` (what `ipa-sysid control` and
//! `tune` run) delegates to `PositionController<f64>`, so the firmware, the C API and the host run the
//! same code (docs/control.md, section "The tuned controller"):
//!
//! ```text
//! D(k) = α D(k−1) − (1 − α) (y(k) − y(k−1)) / Ts          α = Tf / (Tf + Ts), D = 0 at the first sample
//! |e| ≤ e_h:  u = 0, I held                                  e = r − y
//! otherwise:  I = 0 if reset_on_crossing and e e(k−1) < 0
//!             v = Kp e + (I + Ki Ts e);  I += Ki Ts e unless sat(v) ≠ v and e v > 0 (then u_pi = sat(Kp e + I))
//!             u_c = compensator(u_pi), or u_pi + (|e|/e_f)(compensator(u_pi) − u_pi) for |e| < e_f
//!             u = sat(u_c + Kd D)
//! e_h < |e| ≤ e_n (nudge mode, when set): I = 0; at rest (y unchanged for N_r samples) a nudge starts
//!             at u_n = β u_b(side) towards r, ramps by ρ Ts per sample until y changes (u_b(side) = u_n,
//!             then u_n is held), and ends (u = 0) once y has moved and |y − y_0| ≥ γ |e_0| or the error
//!             left is ≤ τ_c(side) |dy/dt| + e_h, or e changes sign; at the next rest τ_c(side) = the
//!             distance coasted since the cut / |dy/dt| at the cut (learnt on line, −1 = not yet)
//! e_n < |e| ≤ e_r (rest band): the nudge mode too once y has been unchanged for N_r samples, and while
//!             the nudge it starts, or the coast after its cut, is under way
//! ramp-and-cut (|e_0| ≤ e_c): the ramp ρ_n = a(side) |e_0| clamped to [ρ_min, ρ], the nudge ends at the
//!             first count towards r; with the creep limit e_v > 0 (session 18) it holds u_n while
//!             0 < side (y(k) − y(k−1)) ≤ e_v, ramps on while y rests, and ends once
//!             side (y(k) − y(k−1)) > e_v, e changes sign or |e| ≤ e_h
//! approach with braking (when set; issue 25, session 14), armed at the first sample and whenever r
//!             changes, for a step |r − y| ≥ e_a, side = sign(r − y), v = side (y(k) − y(k−1))/Ts:
//!             approach: u = side u_max while side e > e_s + τ_b max(v, 0); then
//!             brake:    u = −side a_b u_max for T_b samples (from the sample the approach ends); then
//!             release:  u = −side a_b u_max (T_r − j)/(T_r + 1) at its j-th sample, j = 0..T_r−1; then
//!             hold:     u = 0 (valves closed) until y has been unchanged for N_b samples; then the law
//!                       above from a fresh start (I, D, y(k−1), e(k−1), the nudge under way and the
//!                       rest count cleared; the learnt u_b, τ_c and a(side) kept)
//!             re-brake (when set; session 19): in the release and the hold, a sample with
//!                       side (y(k) − y(k−1)) > 0 gives u = −side a_b u_max (the release's j does not
//!                       advance, the hold's count restarts)
//! short-step approach (when set; issue 25, session 17), armed instead for a step e_s' < |r − y| ≤ e_m:
//!             drive:    u = side min(U u_max + ρ_a Ts (j − 1), u_max) while side e > e_s' + τ_s max(v, 0),
//!                       j the samples so far at the start position (frozen once the piston moves:
//!                       a guard ramp against a drive below the breakaway); then
//!             brake:    u = −side a_s u_max for T_s samples; then
//!             hold:     u = 0 until y has been unchanged for N_s samples; then the law from a fresh start
//! ```

use crate::deadzone::Compensator;
use crate::{Error, Float};

/// The nudge mode of a [`PositionController`] (`controller.nudge` of CONTROLLER.json).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NudgeSettings<F: Float> {
    /// e_n: nudge band, mm (> e_h).
    pub band: F,
    /// ρ: ramp rate, counts/s (> 0).
    pub ramp: F,
    /// β: start fraction of the last breakaway command, in [0, 1].
    pub start_fraction: F,
    /// N_r: samples of unchanged y that count as rest (1..=1000).
    pub rest_samples: u32,
    /// γ: cut fraction of the starting error, in (0, 1].
    pub cut_fraction: F,
    /// e_r: rest band, mm (≥ 0): for e_n < |e| ≤ e_r the nudge mode acts too once y has rested N_r
    /// samples, and until that nudge and the coast after its cut end (e_r ≤ e_n: no effect).
    pub rest_band: F,
    /// e_c: ramp-and-cut band, mm (≥ 0; 0 = off): a nudge that starts at |e_0| ≤ e_c ramps at
    /// ρ_n = a(side) |e_0| clamped to [ρ_min, ρ] and ends at the first encoder count towards r; the
    /// rate per mm a(side) starts at ρ / e_c and is learnt from each such move (module documentation).
    pub cut_band: F,
    /// ρ_min: ramp-and-cut's slowest ramp, counts/s (> 0 and ≤ ρ when e_c > 0).
    pub min_ramp: F,
    /// e_v: ramp-and-cut's creep limit, mm per sample (≥ 0; 0 = off: the nudge ends at the first
    /// count towards r, as in a file written before it existed). With e_v > 0 a ramp-and-cut nudge
    /// holds its command while the piston moves towards r by at most e_v per sample (creeps), ramps
    /// on while it rests, and ends when it moves more than e_v in one sample (a slip beginning), r
    /// is crossed, or the hold band is reached; a(side) is then only slowed, never sped up
    /// (issue 25, session 18).
    pub creep_step: F,
    /// a_p: the slip brake's command as a fraction of u_max, in [0, 1] (0 = off, as in a file
    /// written before it existed). When a nudge ends at a sample in which the piston moved towards r
    /// by more than e_v (e_h without a creep limit) — a slip under way — the valves are reversed,
    /// u = −side a_p u_max, from that sample until the piston no longer moves towards r, for at
    /// most T_p samples (issue 25, session 19).
    pub slip_brake: F,
    /// T_p: the slip brake's longest pulse, samples (0..=1000; 0 = off).
    pub slip_brake_samples: u32,
    /// Relearn the breakaway (issue 25, session 20; `false`: as in a file written before it
    /// existed). Three rules of the finish:
    /// - a ramp-and-cut nudge with the creep limit whose first motion is already a slip (more than
    ///   e_v in one sample) learns u_b(side) = u_n there, so that the next nudge that way starts at
    ///   β u_n instead of β |c b| (without it, on plants whose first count is a slip, every nudge
    ///   ramped again from the bottom: 0.3–0.6 s each);
    /// - a held nudge whose piston rests N_r samples after its first count ramps on from its
    ///   command, as a nudge that has not broken loose (the next count learns u_b again; without it
    ///   the command was held, below the breakaway, to the end of the run);
    /// - the slip brake lasts while the piston still slips (moves more than the slip threshold, e_v
    ///   or e_h, per sample), not while it moves at all: braked on through a one-count creep, the
    ///   reverse command drove the piston back 0.1 mm.
    pub relearn: bool,
    /// Learn the held nudge's cut fraction per side (issue 25, session 23; `false`: as in a file
    /// written before it existed): γ(side) = g(side) γ, g starting at 1. At the rest after a held
    /// nudge (not ramp-and-cut) the move d = side (y − y_0) against |e_0|: short of half the error
    /// and not past r (d < |e_0| / 2) doubles g(side), up to 1/γ (the nudge then runs to r);
    /// past r by more than e_h (d > |e_0| + e_h) halves it, down to 1. On a plant whose breakaway
    /// is above the learnt one each held nudge, cut at γ |e_0| with γ small, moved 0.1–0.2 mm and a
    /// rest 1 mm short took ten nudges (the whole run).
    pub cut_learn: bool,
}

/// The approach with braking of a [`PositionController`] (`controller.brake` of CONTROLLER.json):
/// for a large step, the full command towards r, then a long weak reverse command, then the valves
/// closed until the piston rests (the time oracle's open-loop family, docs/control.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrakeSettings<F: Float> {
    /// e_a: smallest step that is approached this way, mm (≥ 0): |r − y| when r is set or changes.
    pub min_step: F,
    /// e_s: the approach ends at side e ≤ e_s + τ_b max(v, 0), mm (≥ 0).
    pub switch: F,
    /// τ_b: stopping lead per mm/s of speed towards r, s (≥ 0).
    pub lead: F,
    /// a_b: braking command as a fraction of u_max, in (0, 1].
    pub strength: F,
    /// T_b: samples of braking (1..=1000).
    pub samples: u32,
    /// N_b: samples of unchanged y that end the hold after the brake (1..=1000).
    pub rest_samples: u32,
    /// κ_b: how far the lead moves towards the one the last braked move measured, per move, in
    /// [0, 1] (0 = off: τ_b stays as set, as in a file written before it existed). At the rest that
    /// ends the hold, τ̂ = D / v_sw (D = side (y_rest − y_sw), the travel after the switch; v_sw the
    /// speed towards r at the switch) and τ_b(side) ← τ_b(side) + κ_b (min(τ̂, τ_max) − τ_b(side)),
    /// so that the next move in that direction at that speed rests e_s short of r.
    pub learn: F,
    /// τ_max: the largest learnt lead, s (≥ τ_b when κ_b > 0; unused when κ_b = 0).
    pub lead_max: F,
    /// T_r: samples over which the braking command falls linearly to 0 after the brake, 0..=1000
    /// (0 = at once, as in a file written before it existed): closing the valves at once lets the
    /// chamber that drove the piston, still at pressure, push it on by several mm.
    pub release: u32,
    /// Re-brake (issue 25, session 19; `false`: as in a file written before it existed): during the
    /// release and the hold, a sample in which the piston moved towards r (side (y(k) − y(k−1)) > 0)
    /// gives −side a_b u_max again (the release does not advance; the hold's rest count restarts).
    /// The piston that rests under the brake short of r with its driving chamber still at pressure
    /// breaks loose when the brake is released and, where Coulomb friction is far below static
    /// friction, slides 5–15 mm past r; braked at its first count it stays within the band.
    pub rebrake: bool,
    /// Preview (issue 25, session 20; `false`: as in a file written before it existed): the drive
    /// ends at the sample whose next one would pass the switch, with a last sample of the
    /// fraction f = (side e − e_s − τ_b v)/(v Ts) of the full command.
    pub preview: bool,
}

/// The short-step approach of a [`PositionController`] (`controller.short_approach` of
/// CONTROLLER.json; issue 25, session 17): for a step of at most e_m, a drive at a fraction U of
/// u_max (rising by ρ_a Ts per sample until the piston first moves), a brief brake, then the valves
/// closed until the piston rests. The approach with braking ([`BrakeSettings`]) drives the full
/// command, which on a 10 or 30 mm step arrives too fast to stop within the 2 % band.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShortApproachSettings<F: Float> {
    /// e_m: largest step approached this way, mm (> 0): e_s' < |r − y| ≤ e_m when r is set or
    /// changes (such a step is not approached with braking).
    pub max_step: F,
    /// U: the drive's fraction of u_max, in (0, 1].
    pub drive_fraction: F,
    /// ρ_a: guard ramp, counts/s (≥ 0): the drive rises by ρ_a Ts per sample while the piston has
    /// not moved from where the step began (a drive below the breakaway would otherwise never move
    /// it), and is held from the first motion.
    pub ramp: F,
    /// e_s': the drive ends at side e ≤ e_s' + τ_s max(v, 0), mm (≥ 0).
    pub switch: F,
    /// τ_s: stopping lead per mm/s of speed towards r, s (≥ 0).
    pub lead: F,
    /// a_s: braking command as a fraction of u_max, in (0, 1].
    pub strength: F,
    /// T_s: samples of braking (1..=1000).
    pub samples: u32,
    /// N_s: samples of unchanged y that end the hold after the brake (1..=1000).
    pub rest_samples: u32,
    /// Preview (issue 25, session 20; `false`: as before): as [`BrakeSettings::preview`], with the
    /// drive's command.
    pub preview: bool,
    /// κ_s: the breakaway seed, in [0, 1] (issue 25, session 23; 0: as before): at the drive's
    /// switch the nudge's learnt breakaway u_b(side) is raised to at least κ_s × the drive's held
    /// command (U u_max plus its guard ramp), where the speed towards r is at most v_s. A drive
    /// that moves a slow plant at most v_s has a command near that plant's breakaway, so the
    /// finish's first nudge starts near it instead of ramping up from β |c b|.
    pub seed: F,
    /// v_s: the seed only where the speed towards r at the switch is at most v_s, mm/s (≥ 0; 0: at
    /// any speed).
    pub seed_speed: F,
}

/// Where the approach with braking is (`right`: towards larger y).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Approach<F: Float> {
    /// Not approaching: the law runs.
    Off,
    /// Full command towards r.
    Drive { right: bool },
    /// Braking: samples given so far.
    Brake { right: bool, given: u32 },
    /// Releasing the brake: samples given so far.
    Release { right: bool, given: u32 },
    /// Valves closed after the brake: samples of unchanged y so far, the side of the move.
    Hold { still: u32, right: bool },
    /// Short-step drive: y_0 where the step began, j the samples at y_0 so far, whether the piston
    /// has moved from it.
    ShortDrive {
        right: bool,
        y0: F,
        stuck: u32,
        moved: bool,
    },
    /// Short-step brake: samples given so far.
    ShortBrake { right: bool, given: u32 },
    /// Valves closed after the short-step brake: samples of unchanged y so far.
    ShortHold { still: u32 },
}

/// The switch of the last braked move, until the rest that ends its hold (τ_b learning).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Switch<F: Float> {
    /// Towards larger y.
    right: bool,
    /// y_sw: position at the switch, mm.
    y: F,
    /// v_sw: speed towards r at the switch, mm/s.
    v: F,
}

/// A nudge under way (`right`: u > 0).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Nudging<F: Float> {
    right: bool,
    y0: F,
    e0: F,
    u_mag: F,
    moving: bool,
    /// ρ_n: this nudge's ramp rate, counts/s.
    ramp: F,
    /// Ramp-and-cut: the nudge ends at the first count towards r.
    and_cut: bool,
}

/// The smallest sampling period Ts a [`PositionController`] accepts, s (1 µs: a 1 MHz loop, far
/// faster than any valve's). Below it the velocity (y(k) − y(k−1)) / Ts overflows for position
/// changes of a few mm (a subnormal Ts of 1e-310 s turned a 0.1 mm move into a NaN command: audit
/// s19 M-1). `control` checks controller files against the same floor.
pub const MIN_TS_S: f64 = 1e-6;

/// Largest Kp, Ki, Kd a [`PositionController`] (and a controller file) takes, counts per mm, per
/// mm·s, s/mm: a gain of 1e308 is a corrupt setting, not a controller (audit s28 L-4).
pub const MAX_GAIN: f64 = 1e6;
/// Largest band (hold, fine, nudge, rest) a [`PositionController`] takes, mm (10 m).
pub const MAX_LENGTH_MM: f64 = 1e4;
/// Largest time constant (Tf) a [`PositionController`] takes, s.
pub const MAX_TIME_S: f64 = 1e4;
/// Largest command limit u_max, counts.
pub const MAX_COMMAND: f64 = 1e6;
/// Largest nudge ramp rate a controller file may hold, counts/s.
pub const MAX_RAMP_COUNTS_S: f64 = 1e9;

/// Whether a set-point or position v (mm) is within the controller's reach: 64 |v| max(1, Kp, Ki Ts,
/// (1 + Kd)/Ts) finite. Every term of a later step that a stored sample enters (the velocity
/// (y(k) − y(k−1))/Ts and Kd times it, Kp e, Ki Ts e) is then at most 1/32 of the largest float, so
/// an accepted sample can never make every later ordinary sample overflow (audit s28 M-1: one
/// position of 2e306 mm was accepted, and every later step returned [`Error::Numerical`] until a
/// reset, because the refused steps kept the stored position). Far beyond any actuator: about
/// 2.8e304 mm in f64 and 5.3e33 mm in f32 at Ts = 0.01 s, Kp = 14.
fn within_reach<F: Float>(s: &PositionSettings<F>, v: F) -> bool {
    let per_ts = (F::ONE + s.kd) / s.ts;
    let mut m = F::ONE;
    for k in [s.kp, s.ki * s.ts, per_ts] {
        if k > m {
            m = k;
        }
    }
    (v.abs() * F::from_f64(64.0) * m).is_finite()
}

/// The settings of a [`PositionController`] (the `controller` object of CONTROLLER.json).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionSettings<F: Float> {
    /// Ts: sampling period, s (≥ [`MIN_TS_S`]).
    pub ts: F,
    /// Kp, counts/mm (≥ 0).
    pub kp: F,
    /// Ki, counts/(mm·s) (≥ 0).
    pub ki: F,
    /// Kd, counts·s/mm (≥ 0), on the measured velocity.
    pub kd: F,
    /// Tf: derivative filter time constant, s (≥ 0).
    pub tf: F,
    /// u_max: command limit, counts (> 0).
    pub u_max: F,
    /// e_h: hold band, mm (≥ 0).
    pub hold_band: F,
    /// e_f: fine band, mm (≥ 0).
    pub fine_band: F,
    /// Restart the integral when e changes sign outside the hold band.
    pub reset_on_crossing: bool,
    /// The nudge mode, if any.
    pub nudge: Option<NudgeSettings<F>>,
    /// The approach with braking for large steps, if any (`None`: as before it existed).
    pub brake: Option<BrakeSettings<F>>,
    /// The short-step approach, if any (`None`: as before it existed).
    pub short: Option<ShortApproachSettings<F>>,
}

/// A running tuned controller: settings, the optional deadzone inverse and the states (I, D, y(k−1),
/// e(k−1)). No allocation; `Copy`. Cost per sample: at most about 25 flops.
///
/// ```
/// use ipa_embedded::{PositionController, PositionSettings};
/// let s = PositionSettings { ts: 0.01, kp: 10.0, ki: 100.0, kd: 0.0, tf: 0.0, u_max: 255.0,
///                            hold_band: 0.02, fine_band: 0.0, reset_on_crossing: true, nudge: None,
///                            brake: None, short: None };
/// let mut c = PositionController::new(s, None).unwrap();
/// assert_eq!(c.step(1.0, 0.0).unwrap(), 11.0);  // Kp e + Ki Ts e
/// assert_eq!(c.step(1.0, 0.99).unwrap(), 0.0);  // inside the hold band
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionController<F: Float> {
    s: PositionSettings<F>,
    compensator: Option<Compensator<F>>,
    alpha: F,
    integral: F,
    derivative: F,
    y_prev: F,
    started: bool,
    e_prev: F,
    still: u32,
    nudging: Option<Nudging<F>>,
    breakaway_left: F,
    breakaway_right: F,
    /// The last nudge's direction (`true`: right) and the position where its valve closed, until the
    /// piston rests.
    cut: Option<(bool, F, F)>,
    /// τ_c: the coast after the last cut to the left per mm/s of speed at the cut, s (−1 = not learnt).
    coast_left: F,
    /// τ_c: the same to the right, s (−1 = not learnt).
    coast_right: F,
    /// y_0 and e_0 of the last nudge that ended, until the piston rests (ramp-and-cut learning).
    last_start: (F, F),
    /// a(left), a(right): ramp-and-cut rate per mm of error, counts/(s·mm).
    rate_per_mm: [F; 2],
    /// Whether the last nudge that ended was a ramp-and-cut (its move teaches a(side)).
    last_learns: bool,
    /// The approach with braking's (or the short-step approach's) phase.
    approach: Approach<F>,
    /// r at the previous sample (a change re-arms the approach).
    r_prev: F,
    /// Whether r_prev holds a set-point (false until the first sample and after `reset`).
    r_seen: bool,
    /// τ_b(left), τ_b(right): the approach's lead, s (learnt when κ_b > 0, else τ_b as set).
    lead: [F; 2],
    /// The last braked move's switch, until its hold ends.
    switched: Option<Switch<F>>,
    /// The slip brake under way after a nudge's cut: its direction (`true`: the nudge was to the
    /// right, the brake is to the left) and the samples given so far.
    slip_brake: Option<(bool, u32)>,
    /// g(left), g(right): the held nudge's learnt cut fraction over γ ([`NudgeSettings::cut_learn`]).
    cut_gain: [F; 2],
    /// The plausible r and y ([`PositionController::with_range`]; none by default).
    range: crate::pi::Range<F>,
}

/// The direction's sign: +1 towards larger y (`right`, the valve side of u > 0), −1 the other way;
/// the one conversion of an approach's side into the sign of its command and of its motion.
fn side<F: Float>(right: bool) -> F {
    if right {
        F::ONE
    } else {
        -F::ONE
    }
}

/// The preview's last drive sample (issue 25, session 20): with the distance to go d = side e,
/// the switch distance d_s = e_s + τ v and the speed towards r v > 0, a drive whose next sample
/// would pass the switch (d − v Ts ≤ d_s < d) ends now with the fraction f = (d − d_s)/(v Ts) in
/// (0, 1] of its command; `None` when off, at rest or not yet within one sample of the switch.
fn preview_fraction<F: Float>(on: bool, d: F, d_s: F, v: F, ts: F) -> Option<F> {
    let step = v * ts;
    if !on || v <= F::ZERO || d - step > d_s {
        return None;
    }
    Some((d - d_s) / step)
}

/// τ_b at the start, both directions (0 without a brake).
fn initial_lead<F: Float>(b: &Option<BrakeSettings<F>>) -> [F; 2] {
    match b {
        Some(b) => [b.lead, b.lead],
        None => [F::ZERO, F::ZERO],
    }
}

/// a(side) at the start: ρ / e_c, so that a nudge from the edge of the ramp-and-cut band ramps at ρ
/// (0 without one).
fn initial_rate_per_mm<F: Float>(n: &Option<NudgeSettings<F>>) -> [F; 2] {
    match n {
        Some(n) if n.cut_band > F::ZERO => [n.ramp / n.cut_band, n.ramp / n.cut_band],
        _ => [F::ZERO, F::ZERO],
    }
}

/// |b_l|, |b_r| of the compensator's deadzone, 0 without one.
fn initial_breakaway<F: Float>(c: &Option<Compensator<F>>) -> (F, F) {
    match c {
        Some(c) => (c.deadzone().b_l.abs(), c.deadzone().b_r.abs()),
        None => (F::ZERO, F::ZERO),
    }
}

impl<F: Float> PositionController<F> {
    /// A controller at rest; settings out of range (Ts < [`MIN_TS_S`] among them) give
    /// [`Error::Setting`].
    pub fn new(s: PositionSettings<F>, compensator: Option<Compensator<F>>) -> Result<Self, Error> {
        let nonneg = |v: F| v.is_finite() && v >= F::ZERO;
        let positive = |v: F| v.is_finite() && v > F::ZERO;
        let at_most = |v: F, max: f64| nonneg(v) && v <= F::from_f64(max);
        if !(positive(s.ts)
            && s.ts >= F::from_f64(MIN_TS_S)
            && s.ts <= F::from_f64(crate::MAX_TS_S)
            && positive(s.u_max)
            && s.u_max <= F::from_f64(MAX_COMMAND)
            && at_most(s.kp, MAX_GAIN)
            && at_most(s.ki, MAX_GAIN)
            && at_most(s.kd, MAX_GAIN)
            && at_most(s.tf, MAX_TIME_S)
            && at_most(s.hold_band, MAX_LENGTH_MM)
            && at_most(s.fine_band, MAX_LENGTH_MM))
        {
            return Err(Error::Setting);
        }
        if let Some(n) = s.nudge {
            let fraction_ok = n.start_fraction >= F::ZERO && n.start_fraction <= F::ONE;
            let cut_ok = n.cut_fraction > F::ZERO && n.cut_fraction <= F::ONE;
            if !(n.band.is_finite()
                && n.band > s.hold_band
                && positive(n.ramp)
                && fraction_ok
                && cut_ok
                && nonneg(n.rest_band)
                && nonneg(n.cut_band)
                && nonneg(n.min_ramp)
                && nonneg(n.creep_step)
                && nonneg(n.slip_brake)
                && n.slip_brake <= F::ONE
                && n.slip_brake_samples <= 1000
                && n.min_ramp <= n.ramp
                && (n.cut_band == F::ZERO || n.min_ramp > F::ZERO)
                && (1..=1000).contains(&n.rest_samples))
            {
                return Err(Error::Setting);
            }
        }
        if let Some(b) = s.brake {
            if !(nonneg(b.min_step)
                && nonneg(b.switch)
                && nonneg(b.lead)
                && positive(b.strength)
                && b.strength <= F::ONE
                && (1..=1000).contains(&b.samples)
                && (1..=1000).contains(&b.rest_samples)
                && b.release <= 1000
                && nonneg(b.learn)
                && b.learn <= F::ONE
                && (b.learn == F::ZERO || (b.lead_max.is_finite() && b.lead_max >= b.lead)))
            {
                return Err(Error::Setting);
            }
        }
        if let Some(a) = s.short {
            if !(positive(a.max_step)
                && positive(a.drive_fraction)
                && a.drive_fraction <= F::ONE
                && nonneg(a.ramp)
                && nonneg(a.switch)
                && nonneg(a.lead)
                && positive(a.strength)
                && a.strength <= F::ONE
                && (1..=1000).contains(&a.samples)
                && (1..=1000).contains(&a.rest_samples)
                && nonneg(a.seed)
                && nonneg(a.seed_speed)
                && a.seed <= F::ONE)
            {
                return Err(Error::Setting);
            }
        }
        Ok(PositionController {
            s,
            compensator,
            alpha: s.tf / (s.tf + s.ts),
            integral: F::ZERO,
            derivative: F::ZERO,
            y_prev: F::ZERO,
            started: false,
            e_prev: F::ZERO,
            still: 0,
            nudging: None,
            breakaway_left: initial_breakaway(&compensator).0,
            breakaway_right: initial_breakaway(&compensator).1,
            cut: None,
            coast_left: -F::ONE,
            coast_right: -F::ONE,
            last_start: (F::ZERO, F::ZERO),
            rate_per_mm: initial_rate_per_mm(&s.nudge),
            last_learns: false,
            approach: Approach::Off,
            r_prev: F::ZERO,
            r_seen: false,
            lead: initial_lead(&s.brake),
            switched: None,
            slip_brake: None,
            cut_gain: [F::ONE, F::ONE],
            range: crate::pi::Range::none(),
        })
    }

    /// The same controller with a plausibility range [y_min, y_max] (mm) for the set-point r and the
    /// measured position y: from then on [`step`](Self::step) refuses a sample with r or y outside it
    /// with [`Error::OutOfRange`], the state unchanged (the caller holds its previous command or goes
    /// to its safe state; the next plausible sample runs as if the wild one had not been given).
    /// Typically the stroke with a margin for the sensor's noise. Without one, a finite wild sample
    /// (an encoder glitch y = −G mm) is taken: the clamping integral shrugs it off, but the filtered
    /// derivative D carries it: after its jump out and back,
    /// Kd D = −Kd (Tf/(Tf + Ts))^n Ts G/(Tf + Ts)² counts n samples later, a reverse command until it falls below the PI part u_PI: about
    /// ln(Kd Ts G/((Tf + Ts)² |u_PI|)) / ln(1 + Ts/Tf) samples (with y held 0.1 mm short of r,
    /// Kp = 8.55, Ki = 19.67, Kd = 0.24 counts·s/mm, Tf = 0.02 s, Ts = 0.01 s: 34 samples after
    /// G = 1e6 mm, 1 698 after 1e300 mm, tests/wild_sample.rs); and a glitch may teach the nudge and
    /// the approach's learnt values. The range keeps all of it away.
    /// y_min or y_max not finite, or y_min ≥ y_max, gives [`Error::Setting`]. The learnt values
    /// and the state are kept.
    pub fn with_range(self, y_min_mm: F, y_max_mm: F) -> Result<Self, Error> {
        Ok(PositionController {
            range: crate::pi::Range::new(y_min_mm, y_max_mm)?,
            ..self
        })
    }

    /// The plausibility range [y_min, y_max] in mm, `None` when none was set
    /// ([`with_range`](Self::with_range)).
    pub fn range(&self) -> Option<(F, F)> {
        self.range.get()
    }

    /// One sample: set-point r and position y (mm) → command u (counts). Non-finite inputs give
    /// [`Error::NotFinite`]; with a plausibility range ([`with_range`](Self::with_range)), r or y
    /// outside it gives [`Error::OutOfRange`]; finite r or y beyond the controller's reach
    /// (64 |v| max(1, Kp, Ki Ts, (1 + Kd)/Ts) not finite: about 1e304 mm in f64 at Ts = 0.01 s) give [`Error::Numerical`], as
    /// does a command u, integral I or derivative D that would not be finite (a guard of last resort:
    /// audit s19 M-1). Either leaves the state unchanged, and the next sample runs as if this one had
    /// not been given.
    pub fn step(&mut self, r: F, y: F) -> Result<F, Error> {
        if !(r.is_finite() && y.is_finite()) {
            return Err(Error::NotFinite);
        }
        self.range.check(r, y)?;
        if !(within_reach(&self.s, r) && within_reach(&self.s, y)) {
            return Err(Error::Numerical);
        }
        let before = *self;
        let u = self.law_step(r, y)?;
        if !(u.is_finite() && self.integral.is_finite() && self.derivative.is_finite()) {
            *self = before;
            return Err(Error::Numerical);
        }
        Ok(u)
    }

    /// [`step`](Self::step) for finite r and y, without the guard: the approach, the hold band, the
    /// nudge mode or the law (module documentation).
    fn law_step(&mut self, r: F, y: F) -> Result<F, Error> {
        if let Some(u) = self.approach_step(r, y) {
            return Ok(u);
        }
        let s = self.s;
        let e = r - y;
        let dy = if self.started {
            (y - self.y_prev) / s.ts
        } else {
            F::ZERO
        };
        self.still = if self.started && self.y_prev == y {
            self.still.saturating_add(1)
        } else {
            0
        };
        self.started = true;
        self.y_prev = y;
        self.derivative = self.alpha * self.derivative - (F::ONE - self.alpha) * dy;
        if let Some(u) = self.slip_braking(dy) {
            self.e_prev = e;
            return Ok(u);
        }
        if e.abs() <= s.hold_band {
            self.e_prev = e;
            if let Some(g) = self.nudging.take() {
                return Ok(self.end_nudge(&g, y, dy));
            }
            return Ok(F::ZERO);
        }
        if let Some(n) = s.nudge {
            let resting = self.nudging.is_some() || self.cut.is_some();
            if e.abs() <= n.band
                || (e.abs() <= n.rest_band && (resting || self.still >= n.rest_samples))
            {
                self.e_prev = e;
                return Ok(self.nudge(&n, e, y, dy));
            }
        }
        self.nudging = None;
        self.cut = None;
        if s.reset_on_crossing && e * self.e_prev < F::ZERO {
            self.integral = F::ZERO;
        }
        self.e_prev = e;
        let proportional = s.kp * e;
        let integrated = self.integral + s.ki * s.ts * e;
        let v = proportional + integrated;
        let u = v.clamp_to(-s.u_max, s.u_max);
        let u_pi = if u != v && e * v > F::ZERO {
            (proportional + self.integral).clamp_to(-s.u_max, s.u_max)
        } else {
            self.integral = integrated;
            u
        };
        let compensated = match &self.compensator {
            Some(c) if e.abs() < s.fine_band => {
                let w = e.abs() / s.fine_band;
                u_pi + w * (c.apply(u_pi) - u_pi)
            }
            Some(c) => c.apply(u_pi),
            None => u_pi,
        };
        Ok((compensated + s.kd * self.derivative).clamp_to(-s.u_max, s.u_max))
    }

    /// The approach with braking (module documentation): `Some(u)` while it commands, `None` when
    /// the law runs. At the end of the hold the law's transient state restarts (as at the first
    /// sample), so that neither its derivative nor a nudge sees the brake.
    fn approach_step(&mut self, r: F, y: F) -> Option<F> {
        if self.s.brake.is_none() && self.s.short.is_none() {
            return None;
        }
        let first = !self.r_seen || r != self.r_prev;
        let moved = self.started && y != self.y_prev;
        let dy = if self.started {
            (y - self.y_prev) / self.s.ts
        } else {
            F::ZERO
        };
        let e = r - y;
        self.r_prev = r;
        self.r_seen = true;
        if first {
            self.approach = match (self.s.short, self.s.brake) {
                (Some(a), _) if e.abs() > a.switch && e.abs() <= a.max_step => {
                    Approach::ShortDrive {
                        right: e > F::ZERO,
                        y0: y,
                        stuck: 0,
                        moved: false,
                    }
                }
                (_, Some(b)) if e.abs() >= b.min_step && e != F::ZERO => {
                    Approach::Drive { right: e > F::ZERO }
                }
                _ => Approach::Off,
            };
        }
        if let Some(a) = self.s.short {
            if let Some(u) = self.short_step(&a, e, y, dy, moved) {
                return Some(u);
            }
        }
        let b = self.s.brake?;
        if let Approach::Drive { right } = self.approach {
            let v = side::<F>(right) * dy;
            let [tau_left, tau_right] = self.lead;
            let tau = if right { tau_right } else { tau_left };
            let lead = if v > F::ZERO { tau * v } else { F::ZERO };
            if side::<F>(right) * e > b.switch + lead {
                self.started = true;
                self.y_prev = y;
                if let Some(f) = preview_fraction(
                    b.preview,
                    side::<F>(right) * e,
                    b.switch + lead,
                    v,
                    self.s.ts,
                ) {
                    self.approach = Approach::Brake { right, given: 0 };
                    self.switched = Some(Switch { right, y, v });
                    return Some(side::<F>(right) * self.s.u_max * f);
                }
                return Some(side::<F>(right) * self.s.u_max);
            }
            self.approach = Approach::Brake { right, given: 0 };
            self.switched = Some(Switch { right, y, v });
        }
        if let Approach::Brake { right, given } = self.approach {
            if given < b.samples {
                self.approach = Approach::Brake {
                    right,
                    given: given + 1,
                };
                self.started = true;
                self.y_prev = y;
                return Some(-side::<F>(right) * b.strength * self.s.u_max);
            }
            self.approach = Approach::Release { right, given: 0 };
        }
        if b.rebrake {
            if let Approach::Release { right, .. } | Approach::Hold { right, .. } = self.approach {
                if side::<F>(right) * (y - self.y_prev) > F::ZERO {
                    if let Approach::Hold { right, .. } = self.approach {
                        self.approach = Approach::Hold { still: 0, right };
                    }
                    self.started = true;
                    self.y_prev = y;
                    return Some(-side::<F>(right) * b.strength * self.s.u_max);
                }
            }
        }
        if let Approach::Release { right, given } = self.approach {
            if given < b.release {
                self.approach = Approach::Release {
                    right,
                    given: given + 1,
                };
                self.started = true;
                self.y_prev = y;
                let n = F::from_f64(f64::from(b.release) + 1.0);
                let left = F::from_f64(f64::from(b.release - given)) / n;
                return Some(-side::<F>(right) * b.strength * self.s.u_max * left);
            }
            self.approach = Approach::Hold { still: 0, right };
        }
        if let Approach::Hold { still, right } = self.approach {
            let still = if moved { 0 } else { still + 1 };
            if still < b.rest_samples {
                self.approach = Approach::Hold { still, right };
                self.started = true;
                self.y_prev = y;
                return Some(F::ZERO);
            }
            self.approach = Approach::Off;
            self.learn_lead(&b, y);
            self.restart_law();
        }
        None
    }

    /// The short-step approach (module documentation; [`ShortApproachSettings`]): `Some(u)` while it
    /// commands; at the end of its hold the law restarts as after the approach with braking and
    /// `None` is returned.
    fn short_step(
        &mut self,
        a: &ShortApproachSettings<F>,
        e: F,
        y: F,
        dy: F,
        moved_now: bool,
    ) -> Option<F> {
        if let Approach::ShortDrive {
            right,
            y0,
            stuck,
            moved,
        } = self.approach
        {
            let v = side::<F>(right) * dy;
            let lead = if v > F::ZERO { a.lead * v } else { F::ZERO };
            if side::<F>(right) * e > a.switch + lead {
                let moved = moved || y != y0;
                let stuck = if moved {
                    stuck
                } else {
                    stuck.saturating_add(1)
                };
                let rise = a.ramp * self.s.ts * F::from_f64(f64::from(stuck.saturating_sub(1)));
                let u = a.drive_fraction * self.s.u_max + rise;
                self.approach = Approach::ShortDrive {
                    right,
                    y0,
                    stuck,
                    moved,
                };
                self.started = true;
                self.y_prev = y;
                let u = if u < self.s.u_max { u } else { self.s.u_max };
                if let Some(f) = preview_fraction(
                    a.preview,
                    side::<F>(right) * e,
                    a.switch + lead,
                    v,
                    self.s.ts,
                ) {
                    self.seed_breakaway(a, right, u, v);
                    self.approach = Approach::ShortBrake { right, given: 0 };
                    return Some(side::<F>(right) * u * f);
                }
                return Some(side::<F>(right) * u);
            }
            let held = a.drive_fraction * self.s.u_max
                + a.ramp * self.s.ts * F::from_f64(f64::from(stuck.saturating_sub(1)));
            let held = if held < self.s.u_max {
                held
            } else {
                self.s.u_max
            };
            self.seed_breakaway(a, right, held, v);
            self.approach = Approach::ShortBrake { right, given: 0 };
        }
        if let Approach::ShortBrake { right, given } = self.approach {
            if given < a.samples {
                self.approach = Approach::ShortBrake {
                    right,
                    given: given + 1,
                };
                self.started = true;
                self.y_prev = y;
                return Some(-side::<F>(right) * a.strength * self.s.u_max);
            }
            self.approach = Approach::ShortHold { still: 0 };
        }
        if let Approach::ShortHold { still } = self.approach {
            let still = if moved_now { 0 } else { still + 1 };
            if still < a.rest_samples {
                self.approach = Approach::ShortHold { still };
                self.started = true;
                self.y_prev = y;
                return Some(F::ZERO);
            }
            self.approach = Approach::Off;
            self.restart_law();
        }
        None
    }

    /// The breakaway seed (κ_s > 0; [`ShortApproachSettings::seed`]) at the drive's switch: with the
    /// drive's held command u_d and the speed towards r v ≤ v_s (a slow plant: its breakaway is
    /// near the drive's command), u_b(side) ← max(u_b(side), κ_s u_d).
    fn seed_breakaway(&mut self, a: &ShortApproachSettings<F>, right: bool, u: F, v: F) {
        if a.seed <= F::ZERO || (a.seed_speed > F::ZERO && v > a.seed_speed) {
            return;
        }
        let slot = if right {
            &mut self.breakaway_right
        } else {
            &mut self.breakaway_left
        };
        let seeded = a.seed * u;
        if seeded > *slot {
            *slot = seeded;
        }
    }

    /// τ_b learning at the rest y that ends a hold (κ_b > 0; [`BrakeSettings::learn`]): τ̂ = D / v_sw
    /// bounded to [0, τ_max], τ_b(side) moved by κ_b towards it. No speed towards r at the switch
    /// (v_sw ≤ 0: the step began within the lead) teaches nothing.
    fn learn_lead(&mut self, b: &BrakeSettings<F>, y: F) {
        let Some(sw) = self.switched.take() else {
            return;
        };
        if b.learn == F::ZERO || sw.v <= F::ZERO {
            return;
        }
        let travel = if sw.right { y - sw.y } else { sw.y - y };
        let measured = (travel / sw.v).clamp_to(F::ZERO, b.lead_max);
        let [tau_left, tau_right] = &mut self.lead;
        let slot = if sw.right { tau_right } else { tau_left };
        *slot = *slot + b.learn * (measured - *slot);
    }

    /// The law's transient state back to a first sample (the learnt u_b, τ_c, a(side) kept).
    fn restart_law(&mut self) {
        self.slip_brake = None;
        self.integral = F::ZERO;
        self.derivative = F::ZERO;
        self.y_prev = F::ZERO;
        self.started = false;
        self.e_prev = F::ZERO;
        self.still = 0;
        self.nudging = None;
        self.cut = None;
    }

    /// The nudge mode's command (module documentation).
    fn nudge(&mut self, n: &NudgeSettings<F>, e: F, y: F, dy: F) -> F {
        self.integral = F::ZERO;
        let s = self.s;
        let g = match self.nudging {
            Some(g) => {
                let towards = if g.right { y > g.y0 } else { y < g.y0 };
                if g.and_cut && n.creep_step > F::ZERO && e * g.e0 > F::ZERO {
                    return self.creep(n, g, y, dy);
                }
                let first_count = !g.moving && towards && g.and_cut;
                if e * g.e0 <= F::ZERO
                    || (y != g.y0 && self.cut_now(n, &g, e, y, dy))
                    || first_count
                {
                    if first_count {
                        self.learn_breakaway(&g);
                    }
                    self.nudging = None;
                    return self.end_nudge(&g, y, dy);
                }
                if g.moving && n.relearn && self.still > n.rest_samples {
                    // At rest for more than N_r samples after its first count: a nudge at rest again.
                    let up = g.u_mag + g.ramp * s.ts;
                    Nudging {
                        u_mag: if up < s.u_max { up } else { s.u_max },
                        y0: y,
                        moving: false,
                        ..g
                    }
                } else if g.moving {
                    g
                } else if towards {
                    self.learn_breakaway(&g);
                    Nudging { moving: true, ..g }
                } else {
                    // Still stuck, or a count away from r (the piston settling back): ramp on from
                    // where it is now.
                    let up = g.u_mag + g.ramp * s.ts;
                    Nudging {
                        u_mag: if up < s.u_max { up } else { s.u_max },
                        y0: y,
                        ..g
                    }
                }
            }
            None if self.still < n.rest_samples => return F::ZERO,
            None => {
                if let Some((right, y_cut, v_cut)) = self.cut.take() {
                    let moved = if right { y - y_cut } else { y_cut - y };
                    if v_cut > F::ZERO {
                        let coast = if moved > F::ZERO {
                            moved / v_cut
                        } else {
                            F::ZERO
                        };
                        if right {
                            self.coast_right = coast;
                        } else {
                            self.coast_left = coast;
                        }
                    }
                    if self.last_learns {
                        self.learn_rate(n, right, y);
                    } else if n.cut_learn {
                        self.learn_cut(n, right, y);
                    }
                }
                let right = e > F::ZERO;
                let last = if right {
                    self.breakaway_right
                } else {
                    self.breakaway_left
                };
                let start = n.start_fraction * last;
                let and_cut = e.abs() <= n.cut_band;
                let ramp = if and_cut {
                    let [left, right_rate] = self.rate_per_mm;
                    let a = if right { right_rate } else { left } * e.abs();
                    a.clamp_to(n.min_ramp, n.ramp)
                } else {
                    n.ramp
                };
                Nudging {
                    right,
                    y0: y,
                    e0: e,
                    u_mag: if start < s.u_max { start } else { s.u_max },
                    moving: false,
                    ramp,
                    and_cut,
                }
            }
        };
        self.nudging = Some(g);
        if g.right {
            g.u_mag
        } else {
            -g.u_mag
        }
    }

    /// A ramp-and-cut nudge with the creep limit e_v > 0 ([`NudgeSettings::creep_step`]), e not yet
    /// past r: the move of this sample towards r, d = side (y(k) − y(k−1)) = side dy Ts, ends the
    /// nudge when d > e_v (the piston speeds up: a slip begins; nothing is learnt of u_b then);
    /// d > 0 holds the command (the first such sample learns u_b); d ≤ 0 (at rest, or settling
    /// back) ramps on by ρ_n Ts (before the first motion from where the piston is now, as a ramp
    /// that has not broken loose).
    fn creep(&mut self, n: &NudgeSettings<F>, g: Nudging<F>, y: F, dy: F) -> F {
        let s = self.s;
        let d = if g.right { dy } else { -dy } * s.ts;
        if d > n.creep_step {
            if n.relearn && !g.moving {
                self.learn_breakaway(&g);
            }
            self.nudging = None;
            return self.end_nudge(&g, y, dy);
        }
        let g = if d > F::ZERO {
            if !g.moving {
                self.learn_breakaway(&g);
            }
            Nudging { moving: true, ..g }
        } else {
            let up = g.u_mag + g.ramp * s.ts;
            Nudging {
                u_mag: if up < s.u_max { up } else { s.u_max },
                y0: if g.moving { g.y0 } else { y },
                ..g
            }
        };
        self.nudging = Some(g);
        if g.right {
            g.u_mag
        } else {
            -g.u_mag
        }
    }

    /// u_b(side) = the command of a nudge whose piston broke loose.
    fn learn_breakaway(&mut self, g: &Nudging<F>) {
        if g.right {
            self.breakaway_right = g.u_mag;
        } else {
            self.breakaway_left = g.u_mag;
        }
    }

    /// A nudge ends at y (speed dy): remember the cut (learnt coast) and where it started. Returns
    /// the command of this sample: 0 (the valves closed), or the slip brake's first sample when the
    /// piston moved towards r by more than e_v (e_h without a creep limit) in this sample
    /// ([`NudgeSettings::slip_brake`]).
    fn end_nudge(&mut self, g: &Nudging<F>, y: F, dy: F) -> F {
        self.cut = Some((g.right, y, dy.abs()));
        self.last_start = (g.y0, g.e0);
        self.last_learns = g.and_cut;
        let Some(n) = self.s.nudge else {
            return F::ZERO;
        };
        if n.slip_brake == F::ZERO || n.slip_brake_samples == 0 {
            return F::ZERO;
        }
        let d = if g.right { dy } else { -dy } * self.s.ts;
        if d <= self.slip_threshold(&n) {
            return F::ZERO;
        }
        self.slip_brake = Some((g.right, 1));
        self.slip_brake_command(g.right, &n)
    }

    /// The move per sample towards r that is a slip: e_v, or e_h without a creep limit, mm.
    fn slip_threshold(&self, n: &NudgeSettings<F>) -> F {
        if n.creep_step > F::ZERO {
            n.creep_step
        } else {
            self.s.hold_band
        }
    }

    /// −side a_p u_max: the slip brake against a nudge to the right (`right`) or to the left.
    fn slip_brake_command(&self, right: bool, n: &NudgeSettings<F>) -> F {
        let u = n.slip_brake * self.s.u_max;
        if right {
            -u
        } else {
            u
        }
    }

    /// The slip brake after its first sample ([`NudgeSettings::slip_brake`]): `Some(u)` while the
    /// piston still moves towards r (d = side dy Ts > 0) and fewer than T_p samples were given;
    /// otherwise it ends and `None` lets the law run.
    fn slip_braking(&mut self, dy: F) -> Option<F> {
        let (right, given) = self.slip_brake?;
        let n = self.s.nudge?;
        let d = if right { dy } else { -dy } * self.s.ts;
        let slipping = if n.relearn {
            self.slip_threshold(&n)
        } else {
            F::ZERO
        };
        if given < n.slip_brake_samples && d > slipping {
            self.slip_brake = Some((right, given + 1));
            return Some(self.slip_brake_command(right, &n));
        }
        self.slip_brake = None;
        None
    }

    /// Ramp-and-cut learning at the rest after a cut: the move d = side (y − y_0) against the error
    /// |e_0| it was for. Past r by more than e_h (d > |e_0| + e_h): a(side) × max(1/4, |e_0| / d)
    /// (slower: the move grows with the rate); short of half the error (d < |e_0| / 2): a(side) × 5/4,
    /// except with the creep limit e_v > 0 (such a nudge ended short because the piston sped up: a
    /// faster ramp would make that worse); a(side) stays within [ρ_min / e_c, ρ / max(e_h, 0.001 mm)].
    fn learn_rate(&mut self, n: &NudgeSettings<F>, right: bool, y: F) {
        let (y0, e0) = self.last_start;
        let moved = if right { y - y0 } else { y0 - y };
        let err = e0.abs();
        let [left, right_rate] = &mut self.rate_per_mm;
        let slot = if right { right_rate } else { left };
        let mut a = *slot;
        if moved > err + self.s.hold_band {
            let f = err / moved;
            a *= if f > F::from_f64(0.25) {
                f
            } else {
                F::from_f64(0.25)
            };
        } else if moved < F::from_f64(0.5) * err && n.creep_step == F::ZERO {
            a *= F::from_f64(1.25);
        }
        let floor = F::from_f64(1e-3);
        let h = if self.s.hold_band > floor {
            self.s.hold_band
        } else {
            floor
        };
        *slot = a.clamp_to(n.min_ramp / n.cut_band, n.ramp / h);
    }

    /// The held nudge's cut fraction learning at the rest after it ([`NudgeSettings::cut_learn`]):
    /// the move d = side (y − y_0) against |e_0|; d < |e_0| / 2: g(side) × 2 (at most 1/γ);
    /// d > |e_0| + e_h: g(side) / 2 (at least 1).
    fn learn_cut(&mut self, n: &NudgeSettings<F>, right: bool, y: F) {
        let (y0, e0) = self.last_start;
        let moved = if right { y - y0 } else { y0 - y };
        let err = e0.abs();
        let [left, right_gain] = &mut self.cut_gain;
        let slot = if right { right_gain } else { left };
        let two = F::from_f64(2.0);
        if moved < err / two {
            let top = if n.cut_fraction > F::ZERO {
                F::ONE / n.cut_fraction
            } else {
                F::ONE
            };
            let up = *slot * two;
            *slot = if up < top { up } else { top };
        } else if moved > err + self.s.hold_band {
            let down = *slot / two;
            *slot = if down > F::ONE { down } else { F::ONE };
        }
    }

    /// Whether a nudge that has moved the piston ends now: once it has covered γ |e_0| (γ(side) =
    /// g(side) γ for a held nudge with [`NudgeSettings::cut_learn`]), or once the error left is at
    /// most τ_c(side) |dy/dt| + e_h (τ_c learnt after the last cut in its direction).
    fn cut_now(&self, n: &NudgeSettings<F>, g: &Nudging<F>, e: F, y: F, dy: F) -> bool {
        let coast = if g.right {
            self.coast_right
        } else {
            self.coast_left
        };
        let left = if g.right { e } else { -e };
        let gamma = if n.cut_learn && !g.and_cut {
            let [left, right] = self.cut_gain;
            let v = if g.right { right } else { left } * n.cut_fraction;
            if v < F::ONE {
                v
            } else {
                F::ONE
            }
        } else {
            n.cut_fraction
        };
        (y - g.y0).abs() >= gamma * g.e0.abs()
            || (coast >= F::ZERO && left <= coast * dy.abs() + self.s.hold_band)
    }

    /// The integral term I in counts.
    pub fn integral(&self) -> F {
        self.integral
    }

    /// The learnt breakaway commands u_b (left, right), counts.
    pub fn breakaway(&self) -> [F; 2] {
        [self.breakaway_left, self.breakaway_right]
    }

    /// The learnt coasts τ_c (left, right): distance coasted after a cut per mm/s of speed at the
    /// cut, s; −1 = not learnt.
    pub fn coast(&self) -> [F; 2] {
        [self.coast_left, self.coast_right]
    }

    /// Back to rest.
    pub fn reset(&mut self) {
        // The law's transient state, then what it learnt.
        self.restart_law();
        (self.breakaway_left, self.breakaway_right) = initial_breakaway(&self.compensator);
        self.coast_left = -F::ONE;
        self.coast_right = -F::ONE;
        self.last_start = (F::ZERO, F::ZERO);
        self.rate_per_mm = initial_rate_per_mm(&self.s.nudge);
        self.last_learns = false;
        self.approach = Approach::Off;
        self.r_prev = F::ZERO;
        self.r_seen = false;
        self.lead = initial_lead(&self.s.brake);
        self.switched = None;
        self.cut_gain = [F::ONE, F::ONE];
    }

    /// The next move from rest, keeping what was learnt (u_b, τ_c, a(side), τ_b(side)): the law's
    /// transient state and the approach restart as at the first sample, as on a machine that
    /// repeats its moves. [`reset`](Self::reset) forgets the learnt values too.
    pub fn restart(&mut self) {
        self.restart_law();
        self.last_start = (F::ZERO, F::ZERO);
        self.last_learns = false;
        self.approach = Approach::Off;
        self.r_prev = F::ZERO;
        self.r_seen = false;
        self.switched = None;
    }

    /// The approach's leads τ_b (left, right), s: as set, or learnt ([`BrakeSettings::learn`]).
    pub fn brake_lead(&self) -> [F; 2] {
        self.lead
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::{Deadzone, SlopeMode};

    fn s() -> PositionSettings<f64> {
        PositionSettings {
            ts: 0.01,
            kp: 10.0,
            ki: 100.0,
            kd: 0.0,
            tf: 0.0,
            u_max: 255.0,
            hold_band: 0.02,
            fine_band: 0.0,
            reset_on_crossing: true,
            nudge: None,
            brake: None,
            short: None,
        }
    }

    // e = 1: u = 10 + 1; inside the band 0; crossing to e = -0.5 restarts I: -5 - 0.5.
    #[test]
    fn hold_band_and_reset_on_crossing() {
        let mut c = PositionController::new(s(), None).unwrap();
        assert_eq!(c.step(1.0, 0.0).unwrap(), 11.0);
        assert_eq!(c.step(1.0, 0.99).unwrap(), 0.0);
        assert_eq!(c.integral(), 1.0);
        assert_eq!(c.step(1.0, 1.5).unwrap(), -5.5);
    }

    // D(k) = α D(k−1) − (1 − α) Δy/Ts with α = Tf/(Tf + Ts) = 0.5 at Tf = Ts; Δy = 0.1 mm: −5 mm/s,
    // then D = 0.5 × (−5) − 0.5 × 0 = −2.5 (Kp = Ki = 0, Kd = 2).
    #[test]
    fn derivative_acts_on_the_filtered_measured_velocity() {
        let mut settings = s();
        (settings.kp, settings.ki, settings.kd, settings.tf) = (0.0, 0.0, 2.0, 0.01);
        let mut c = PositionController::new(settings, None).unwrap();
        assert_eq!(c.step(10.0, 0.0).unwrap(), 0.0);
        assert_eq!(c.step(10.0, 0.1).unwrap(), 2.0 * -5.0);
        assert_eq!(c.step(10.0, 0.1).unwrap(), 2.0 * -2.5);
    }

    // Audit s28 M-1: one finite but extreme position (a garbage encoder read) must not wedge the
    // controller. With Kp = 4, Ki = 5, Kd = 0.25, Tf = 0.02 s, Ts = 0.01 s the reach is
    // 1.8e308 / (64 (1 + Kd)/Ts) ≈ 2.2e304 mm: 1e308, 5e306 and 2e306 are refused (state unchanged),
    // and the samples after them give the commands of a controller that never saw them.
    #[test]
    fn an_extreme_sample_is_refused_and_the_next_runs_as_if_it_had_not_been_given() {
        let mut settings = s();
        (settings.kp, settings.ki, settings.kd, settings.tf) = (4.0, 5.0, 0.25, 0.02);
        let samples = [
            (10.0, 0.0),
            (10.0, 0.5),
            (10.0, 1.2),
            (10.0, 9.9),
            (10.0, 9.95),
        ];
        let mut clean = PositionController::new(settings, None).unwrap();
        let want = samples.map(|(r, y)| clean.step(r, y).unwrap());
        for bad in [
            (1e308, -1e308),
            (0.0, 1e308),
            (10.0, -5e306),
            (10.0, 2e306),
            (3e305, 0.0),
        ] {
            for at in 0..samples.len() {
                let mut c = PositionController::new(settings, None).unwrap();
                let mut got = [0.0; 5];
                for (k, (&(r, y), out)) in samples.iter().zip(got.iter_mut()).enumerate() {
                    if k == at {
                        let before = c;
                        assert_eq!(
                            c.step(bad.0, bad.1),
                            Err(Error::Numerical),
                            "{bad:?} at {at}"
                        );
                        assert_eq!(c, before, "a refused sample leaves the state unchanged");
                    }
                    *out = c.step(r, y).unwrap();
                }
                assert_eq!(got, want, "{bad:?} at {at}");
            }
        }
        // Within the reach an extreme but representable sample is taken (a derivative kick).
        let mut c = PositionController::new(settings, None).unwrap();
        c.step(10.0, 0.0).unwrap();
        assert!(c.step(10.0, 1e300).is_ok());
        assert!(c.step(10.0, 0.0).is_ok());
    }

    // Audit s28 L-4: the magnitudes a controller file may not hold, the embedded controller refuses
    // too (one range).
    #[test]
    fn settings_beyond_the_file_ranges_are_refused() {
        type Set = fn(&mut PositionSettings<f64>);
        let cases: [(&str, Set); 8] = [
            ("kp", |s| s.kp = 1e308),
            ("ki", |s| s.ki = MAX_GAIN * 2.0),
            ("kd", |s| s.kd = 1e7),
            ("tf", |s| s.tf = 1e5),
            ("hold band", |s| s.hold_band = 1e308),
            ("fine band", |s| s.fine_band = 2e4),
            ("u_max", |s| s.u_max = 1e7),
            ("ts", |s| s.ts = 1e5),
        ];
        for (name, set) in cases {
            let mut settings = s();
            set(&mut settings);
            assert_eq!(
                PositionController::new(settings, None).err(),
                Some(Error::Setting),
                "{name}"
            );
        }
        let mut at_bounds = s();
        (at_bounds.kp, at_bounds.hold_band, at_bounds.u_max) =
            (MAX_GAIN, MAX_LENGTH_MM, MAX_COMMAND);
        assert!(PositionController::new(at_bounds, None).is_ok());
    }

    /// The shift inverse of the deadzone b_l = −20, b_r = 30 (unit slopes).
    fn shift_inverse() -> Compensator<f64> {
        let dz = Deadzone {
            b_l: -20.0,
            b_r: 30.0,
            m_l: 1.0,
            m_r: 1.0,
        };
        Compensator::new(dz, SlopeMode::Shift, 0.0, 255.0).unwrap()
    }

    // In the fine band e_f = 2 mm, e = 1 mm: the shift b_r = 30 is halved: u = 11 + 15.
    #[test]
    fn fine_band_scales_the_deadzone_shift() {
        let comp = shift_inverse();
        let mut settings = s();
        settings.fine_band = 2.0;
        let mut c = PositionController::new(settings, Some(comp)).unwrap();
        assert_eq!(c.step(1.0, 0.0).unwrap(), 26.0);
    }

    /// A P controller (Kp = 10) with the nudge mode: band 1 mm, ρ = 100 counts/s, β = 0.5, N_r = 2,
    /// cut fraction γ.
    fn nudging(cut_fraction: f64) -> PositionSettings<f64> {
        let mut settings = s();
        settings.ki = 0.0;
        settings.nudge = Some(NudgeSettings {
            band: 1.0,
            ramp: 100.0,
            start_fraction: 0.5,
            rest_samples: 2,
            cut_fraction,
            rest_band: 0.0,
            cut_band: 0.0,
            min_ramp: 0.0,
            creep_step: 0.0,
            slip_brake: 0.0,
            slip_brake_samples: 0,
            relearn: false,
            cut_learn: false,
        });
        settings
    }

    // The rest band by hand: e_r = 3 mm, r = 3, y = 0.5
    // (e = 2.5 mm, outside e_n = 1): the PID acts (10 × 2.5 + b_r = 55) until y has rested N_r = 2
    // samples, then a nudge starts at β |b_r| = 15, ramps to 16, breaks loose (u_b = 16, held) and is
    // cut at y = 1.8 (moved 1.3 ≥ γ |e_0| = 1.25); while the piston coasts (e = 1.1–1.2 mm) the
    // valve stays closed, and after 2 samples of rest the next nudge starts at β u_b = 8, having
    // learnt τ_c = 0.1 mm / 30 mm/s. Beyond e_r the PID acts again: 10 × 8 + 30. With e_r = 0 the PID
    // acts at every one of these samples.
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
            let mut settings = nudging(0.5);
            settings.nudge.as_mut().unwrap().rest_band = e_r;
            let mut c = PositionController::new(settings, Some(shift_inverse())).unwrap();
            for (k, &(r, y, u_band, u_pid)) in steps.iter().enumerate() {
                let want = if col == 0 { u_band } else { u_pid };
                let u = c.step(r, y).unwrap();
                assert!(
                    (u - want).abs() < 1e-9,
                    "e_r {e_r}, sample {k}: {u} != {want}"
                );
            }
            if col == 0 {
                assert_eq!(c.breakaway(), [20.0, 16.0]);
                assert_eq!(c.coast_right, (1.9 - 1.8) / ((1.8 - 1.5) / 0.01));
            }
        }
        let mut settings = nudging(0.5);
        settings.nudge.as_mut().unwrap().rest_band = -1.0;
        assert!(PositionController::new(settings, None).is_err());
    }

    // N_r, the rest that starts a nudge (`tune` chooses it among 3, 2, 1 since session 16), by hand:
    // r = 1, y = 0.5 held (e = 0.5 mm, inside the 1 mm band). The first sample has no previous y
    // (still = 0); each later one adds a sample of rest; the nudge starts once still ≥ N_r at β |b_r|
    // = 15 counts and ramps by ρ Ts = 1 count per sample: N_r = 1 → 0, 15, 16, 17, 18;
    // N_r = 2 → 0, 0, 15, 16, 17; N_r = 3 → 0, 0, 0, 15, 16.
    #[test]
    fn a_nudge_starts_after_n_r_samples_at_rest() {
        for (n_r, want) in [
            (1, [0.0, 15.0, 16.0, 17.0, 18.0]),
            (2, [0.0, 0.0, 15.0, 16.0, 17.0]),
            (3, [0.0, 0.0, 0.0, 15.0, 16.0]),
        ] {
            let mut settings = nudging(0.5);
            settings.nudge.as_mut().unwrap().rest_samples = n_r;
            let mut c = PositionController::new(settings, Some(shift_inverse())).unwrap();
            let got: [f64; 5] = core::array::from_fn(|_| c.step(1.0, 0.5).unwrap());
            assert_eq!(got, want, "N_r = {n_r}");
        }
    }

    // The nudge mode by hand: deadzone b_l = −20, b_r = 30,
    // band 1 mm, ρ Ts = 1 count per sample, β = 0.5, N_r = 2, γ = 0.5, e = 0.5 mm: closed until y has
    // been still for 2 samples, then 15, 16, 17 counts; y moves at 17 (learnt, held) and the valve closes
    // once y has covered 0.25 mm; the next nudge starts at 0.5 × 17.
    #[test]
    fn nudge_ramps_from_the_last_breakaway_learns_it_and_cuts() {
        let comp = shift_inverse();
        let settings = nudging(0.5);
        let mut c = PositionController::new(settings, Some(comp)).unwrap();
        let u: [f64; 10] = core::array::from_fn(|_| 0.0);
        let ys = [0.5, 0.5, 0.5, 0.5, 0.5, 0.6, 0.8, 0.8, 0.8, 0.99];
        let want = [0.0, 0.0, 15.0, 16.0, 17.0, 17.0, 0.0, 0.0, 8.5, 0.0];
        let mut got = u;
        for (g, y) in got.iter_mut().zip(ys) {
            *g = c.step(1.0, y).unwrap();
        }
        assert_eq!(got, want);
        assert_eq!(c.breakaway(), [20.0, 17.0]);
        // Past the set-point: a nudge to the left from β |b_l| = 10 counts; e changes sign during it:
        // it ends; outside the band u = Kp e + b_r = 10 × 2 + 30; reset restores |b_l|, |b_r|.
        for (r, y, u) in [
            (1.0, 1.3, 0.0),
            (1.0, 1.3, 0.0),
            (1.0, 1.3, -10.0),
            (1.0, 0.9, 0.0),
            (3.0, 1.0, 50.0),
        ] {
            assert_eq!(c.step(r, y).unwrap(), u);
        }
        c.reset();
        assert_eq!(c.breakaway(), [20.0, 30.0]);
        let mut bad = settings;
        bad.nudge = Some(NudgeSettings {
            band: 0.01,
            ..settings.nudge.unwrap()
        });
        assert_eq!(
            PositionController::new(bad, Some(comp)).unwrap_err(),
            Error::Setting
        );
    }

    // The learnt coast by hand: γ = 1; the first right
    // nudge is cut in the hold band at 50 mm/s and coasts 0.25 mm; the next right nudge is cut at
    // y = 1.875 because the 0.125 mm left is below τ_c × 37.5 mm/s + e_h.
    #[test]
    fn a_nudge_ends_where_the_learnt_coast_would_carry_the_piston() {
        let mut c = PositionController::new(nudging(1.0), Some(shift_inverse())).unwrap();
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
            assert_eq!(c.step(r, y).unwrap(), u, "sample {k}");
        }
        assert_eq!(c.coast(), [-1.0, 0.25 / ((1.0 - 0.5) / 0.01)]);
        c.reset();
        assert_eq!(c.coast(), [-1.0, -1.0]);
    }

    // A count away from r during the ramp (the piston settling back) is not a breakaway: the ramp goes
    // on from there (before this, the nudge took it for one, held its 16 counts, below the breakaway,
    // and waited for γ |e_0| of motion that never came). r = 1, y = 0.5: 15, 16; y = 0.49 (away):
    // 17, 18; y = 0.6 (towards): u_b = 18, held; y = 0.8 (0.31 ≥ γ |e_0| = 0.25 from 0.49): cut.
    #[test]
    fn a_count_away_from_the_set_point_is_not_a_breakaway() {
        let mut c = PositionController::new(nudging(0.5), Some(shift_inverse())).unwrap();
        let ys = [0.5, 0.5, 0.5, 0.5, 0.49, 0.49, 0.6, 0.6, 0.8];
        let want = [0.0, 0.0, 15.0, 16.0, 17.0, 18.0, 18.0, 18.0, 0.0];
        for (k, (y, u)) in ys.into_iter().zip(want).enumerate() {
            let got = c.step(1.0, y).unwrap();
            assert!((got - u).abs() < 1e-9, "sample {k}: {got} != {u}");
        }
        assert_eq!(c.breakaway(), [20.0, 18.0]);
    }

    // Ramp-and-cut by hand: e_c = 0.5 mm, ρ_min = 20, ρ = 100 counts/s, so a(side) = ρ / e_c = 200
    // counts/(s·mm) at first. r = 1, y = 0.6 (e_0 = 0.4): ρ_n = 200 × 0.4 = 80 counts/s (0.8 per
    // sample) from β |b_r| = 15: 15, 15.8, 16.6; the first count towards r (y = 0.61) cuts at once
    // (u_b = 16.6). The piston coasts to 0.62 and rests: it moved 0.02 < e_0 / 2, so a(right) =
    // 200 × 5/4 = 250; next nudge (e_0 = 0.38): ρ_n = 95 from β u_b = 8.3: 8.3, 9.25; it jumps past r
    // to y = 1.1 (e changes sign: cut; u_b = 9.25) and rests there: it moved 0.48 > 0.38 + e_h, so
    // a(right) = 250 × 0.38 / 0.48; the nudge back (e_0 = −0.1) ramps at max(200 × 0.1, ρ_min) = 20
    // counts/s from β |b_l| = 10. With e_c = 0 (a file without it) the first count does not cut.
    #[test]
    fn ramp_and_cut_ends_at_the_first_count_and_learns_its_rate() {
        let mut settings = nudging(0.5);
        let n = settings.nudge.as_mut().unwrap();
        (n.cut_band, n.min_ramp) = (0.5, 20.0);
        let mut c = PositionController::new(settings, Some(shift_inverse())).unwrap();
        let steps = [
            (0.6, 0.0),
            (0.6, 0.0),
            (0.6, 15.0),
            (0.6, 15.8),
            (0.6, 16.6),
            (0.61, 0.0),
            (0.62, 0.0),
            (0.62, 0.0),
            (0.62, 8.3),
            (0.62, 9.25),
            (1.1, 0.0),
            (1.1, 0.0),
            (1.1, -10.0),
            (1.1, -10.2),
        ];
        for (k, (y, u)) in steps.into_iter().enumerate() {
            let got = c.step(1.0, y).unwrap();
            assert!((got - u).abs() < 1e-9, "sample {k}: {got} != {u}");
        }
        assert!((c.breakaway()[1] - 9.25).abs() < 1e-9);
        let [a_left, a_right] = c.rate_per_mm;
        assert_eq!(a_left, 200.0);
        assert!((a_right - 250.0 * 0.38 / 0.48).abs() < 1e-9);
        // The learnt coast after the jump's cut: it stopped where it was cut.
        assert_eq!(c.coast()[1], 0.0);
        c.reset();
        assert_eq!(c.rate_per_mm, [200.0, 200.0]);
        // Without the band: the first count is a breakaway, the command is held.
        let mut c = PositionController::new(nudging(0.5), Some(shift_inverse())).unwrap();
        let ys = [0.6, 0.6, 0.6, 0.6, 0.6, 0.61];
        let got = ys.map(|y| c.step(1.0, y).unwrap());
        assert_eq!(got, [0.0, 0.0, 15.0, 16.0, 17.0, 17.0]);
        // ρ_min must be > 0 with a band, and ≤ ρ.
        let mut bad = nudging(0.5);
        bad.nudge.as_mut().unwrap().cut_band = 0.5;
        assert!(PositionController::new(bad, None).is_err());
        bad.nudge.as_mut().unwrap().min_ramp = 200.0;
        assert!(PositionController::new(bad, None).is_err());
    }

    // The creep by hand: ramp-and-cut as above (e_c = 0.5 mm, ρ_min = 20, ρ = 100, a = 200
    // counts/(s·mm)) with the creep limit e_v = 0.015 mm per sample. r = 1, y = 0.6 (e_0 = 0.4):
    // ρ_n = 80 counts/s from β |b_r| = 15: 15, 15.8, 16.6; the first count (0.61, a move of 0.01 ≤ e_v)
    // holds 16.6 (u_b = 16.6) instead of cutting, as does the next (0.62); at rest (0.62 again) it
    // ramps on to 17.4, holds at 0.63, and a move of 0.03 > e_v (0.66) cuts. It coasts to 0.67 and
    // rests: the move 0.07 < e_0 / 2 does not speed a(right) up (it stays 200, where the cut at the
    // first count makes it 250); the learnt coast is 0.01 mm / 3 mm/s. Next nudge (e_0 = 0.33):
    // ρ_n = 66 from β u_b = 8.3: 8.3, 8.96, held at 0.68; r = 0.70 puts y in the hold band: u = 0.
    #[test]
    fn a_creeping_ramp_and_cut_nudge_holds_while_the_piston_creeps_and_cuts_when_it_speeds_up() {
        let mut settings = nudging(0.5);
        let n = settings.nudge.as_mut().unwrap();
        (n.cut_band, n.min_ramp, n.creep_step) = (0.5, 20.0, 0.015);
        let mut c = PositionController::new(settings, Some(shift_inverse())).unwrap();
        let steps = [
            (1.0, 0.6, 0.0),
            (1.0, 0.6, 0.0),
            (1.0, 0.6, 15.0),
            (1.0, 0.6, 15.8),
            (1.0, 0.6, 16.6),
            (1.0, 0.61, 16.6),
            (1.0, 0.62, 16.6),
            (1.0, 0.62, 17.4),
            (1.0, 0.63, 17.4),
            (1.0, 0.66, 0.0),
            (1.0, 0.67, 0.0),
            (1.0, 0.67, 0.0),
            (1.0, 0.67, 8.3),
            (1.0, 0.67, 8.96),
            (1.0, 0.68, 8.96),
            (0.70, 0.68, 0.0),
        ];
        for (k, (r, y, u)) in steps.into_iter().enumerate() {
            let got = c.step(r, y).unwrap();
            assert!((got - u).abs() < 1e-9, "sample {k}: {got} != {u}");
            if k == 9 {
                assert!((c.breakaway()[1] - 16.6).abs() < 1e-9);
            }
        }
        assert!((c.breakaway()[1] - 8.96).abs() < 1e-9);
        assert_eq!(c.rate_per_mm, [200.0, 200.0]);
        assert!((c.coast()[1] - 0.01 / 3.0).abs() < 1e-9);
        // Down the same way: a creep to the left holds −u_n, and a move of 0.02 > e_v cuts.
        let mut c = PositionController::new(settings, Some(shift_inverse())).unwrap();
        let ys = [0.4, 0.4, 0.4, 0.39, 0.37];
        let got = ys.map(|y| c.step(0.0, y).unwrap());
        let want = [0.0, 0.0, -10.0, -10.0, 0.0];
        for (k, (g, w)) in got.iter().zip(want).enumerate() {
            assert!((g - w).abs() < 1e-9, "sample {k}: {g} != {w}");
        }
        // A negative creep limit is refused.
        settings.nudge.as_mut().unwrap().creep_step = -0.01;
        assert!(PositionController::new(settings, None).is_err());
    }

    // The slip brake by hand: a held nudge (γ = 0.5, e_n = 1, ρ = 100, β = 0.5, N_r = 2, no creep
    // limit, so a slip is a move of more than e_h = 0.02 mm in a sample) with a_p = 0.2, T_p = 3.
    // r = 1, y = 0.6 (e_0 = 0.4): at rest after 2 samples the nudge starts at β |b_r| = 15, ramps to
    // 16, the first count (0.65) learns u_b = 16 and holds it; at 0.85 the piston has covered
    // 0.25 ≥ γ e_0 = 0.2: cut, and it moved 0.2 mm in that sample (> e_h): u = −a_p u_max = −51
    // from that sample; 0.9 (still moving towards r): −51; 0.9 again (stopped): the brake ends, the
    // law's rest count is 1 < N_r: 0; rest at the next sample: the coast learnt 0.05 mm / 20 mm/s,
    // and the next nudge starts at β u_b = 8. With T_p = 2 the brake ends after two samples although
    // the piston still moves (0.93). Without it (a_p = 0) the cut gives 0, as before.
    #[test]
    fn a_nudge_cut_during_a_slip_reverses_the_valves_until_the_piston_stops() {
        let with = |a_p: f64, t_p: u32| {
            let mut settings = nudging(0.5);
            let n = settings.nudge.as_mut().unwrap();
            (n.slip_brake, n.slip_brake_samples) = (a_p, t_p);
            PositionController::new(settings, Some(shift_inverse())).unwrap()
        };
        let mut c = with(0.2, 3);
        let ys = [0.6, 0.6, 0.6, 0.6, 0.65, 0.85, 0.9, 0.9, 0.9];
        let got = ys.map(|y| c.step(1.0, y).unwrap());
        let want = [0.0, 0.0, 15.0, 16.0, 16.0, -51.0, -51.0, 0.0, 8.0];
        for (k, (g, w)) in got.iter().zip(want).enumerate() {
            assert!((g - w).abs() < 1e-9, "sample {k}: {g} != {w}");
        }
        assert!((c.coast()[1] - 0.05 / 20.0).abs() < 1e-9);
        // T_p = 2: two samples, then the law (e = 0.07: a nudge, but not yet at rest).
        let mut c = with(0.2, 2);
        let ys = [0.6, 0.6, 0.6, 0.6, 0.65, 0.85, 0.9, 0.93];
        let got = ys.map(|y| c.step(1.0, y).unwrap());
        assert_eq!(got[5..], [-51.0, -51.0, 0.0]);
        // Off: the cut closes the valves.
        let mut c = with(0.0, 3);
        let got = ys.map(|y| c.step(1.0, y).unwrap());
        assert_eq!(got[5..], [0.0, 0.0, 0.0]);
        // To the left (β |b_l| = 10, 11, u_b = 11 at 0.35; 0.15 cuts at a move of 0.2): +51.
        let mut c = with(0.2, 3);
        let ys = [0.4, 0.4, 0.4, 0.4, 0.35, 0.15, 0.1, 0.1];
        let got = ys.map(|y| c.step(0.0, y).unwrap());
        let want = [0.0, 0.0, -10.0, -11.0, -11.0, 51.0, 51.0, 0.0];
        for (k, (g, w)) in got.iter().zip(want).enumerate() {
            assert!((g - w).abs() < 1e-9, "left, sample {k}: {g} != {w}");
        }
        // A cut at a move of one count (0.01 ≤ e_h) is no slip: from 0.97 (e_0 = 0.03) the nudge
        // starts at 15, its first count (0.98) holds it, and reaching the hold band at 0.99 closes
        // the valves.
        let mut c = with(0.2, 3);
        let ys = [0.97, 0.97, 0.97, 0.98, 0.99];
        let got = ys.map(|y| c.step(1.0, y).unwrap());
        assert_eq!(got, [0.0, 0.0, 15.0, 15.0, 0.0]);
        // a_p above 1 and T_p above 1000 are refused.
        for (a_p, t_p) in [(1.5, 3), (0.2, 1001), (-0.1, 3)] {
            let mut settings = nudging(0.5);
            let n = settings.nudge.as_mut().unwrap();
            (n.slip_brake, n.slip_brake_samples) = (a_p, t_p);
            assert!(PositionController::new(settings, None).is_err());
        }
    }

    /// [`nudging`] (γ = 0.5, e_n = 1, ρ Ts = 1 count per sample, β = 0.5, N_r = 2, b_r = 30) with the
    /// relearning on or off.
    fn relearning(relearn: bool) -> PositionSettings<f64> {
        let mut settings = nudging(0.5);
        settings.nudge.as_mut().unwrap().relearn = relearn;
        settings
    }

    // The stall (session 19's doubt, issue 25 session 20), by hand: a held nudge (no ramp-and-cut
    // band) from y = 0.6 to r = 1 (e_0 = 0.4, γ e_0 = 0.2) starts at β |b_r| = 15 after N_r = 2
    // samples at rest, ramps to 16, and its first count (0.61) learns u_b = 16 and holds it. The
    // piston then sticks at 0.61. Without the relearning the nudge holds 16 for ever. With it, at
    // rest for more than N_r samples after the count (the third sample at 0.61) it ramps on, 17, 18,
    // and the next count (0.62) learns u_b = 18 and holds it.
    #[test]
    fn a_held_nudge_that_stalls_after_its_first_count_ramps_on_when_it_relearns() {
        let ys = [0.6, 0.6, 0.6, 0.6, 0.61, 0.61, 0.61, 0.61, 0.61, 0.62, 0.62];
        let mut c = PositionController::new(relearning(false), Some(shift_inverse())).unwrap();
        let got = ys.map(|y| c.step(1.0, y).unwrap());
        let held = [
            0.0, 0.0, 15.0, 16.0, 16.0, 16.0, 16.0, 16.0, 16.0, 16.0, 16.0,
        ];
        assert_eq!(got, held);
        assert_eq!(c.breakaway(), [20.0, 16.0]);
        let mut c = PositionController::new(relearning(true), Some(shift_inverse())).unwrap();
        let got = ys.map(|y| c.step(1.0, y).unwrap());
        let ramped = [
            0.0, 0.0, 15.0, 16.0, 16.0, 16.0, 16.0, 17.0, 18.0, 18.0, 18.0,
        ];
        assert_eq!(got, ramped);
        assert_eq!(c.breakaway(), [20.0, 18.0]);
    }

    // The breakaway learnt at a slip, by hand: ramp-and-cut band e_c = 0.5 with the creep limit
    // e_v = 0.015 and ρ_min = 20; from y = 0.5 to r = 1 (e_0 = 0.5 = e_c: ρ_n = (ρ / e_c) e_0 = 100
    // counts/s, 1 per sample) the nudge starts at β |b_r| = 15 and ramps 16, 17; its first motion
    // (0.55, 0.05 > e_v in one sample) is a slip: the nudge ends (u = 0). The piston comes to rest at
    // 0.6 and after N_r = 2 samples the next nudge starts at β u_b: 0.5 × 17 = 8.5 with the
    // relearning (u_b = 17 learnt at the slip), 0.5 × 30 = 15 without (nothing learnt).
    #[test]
    fn a_creeping_nudge_whose_first_motion_is_a_slip_learns_the_breakaway_when_it_relearns() {
        let ys = [0.5, 0.5, 0.5, 0.5, 0.5, 0.55, 0.6, 0.6, 0.6];
        for (relearn, next, u_b) in [(false, 15.0, 30.0), (true, 8.5, 17.0)] {
            let mut settings = relearning(relearn);
            let n = settings.nudge.as_mut().unwrap();
            (n.cut_band, n.min_ramp, n.creep_step) = (0.5, 20.0, 0.015);
            let mut c = PositionController::new(settings, Some(shift_inverse())).unwrap();
            let got = ys.map(|y| c.step(1.0, y).unwrap());
            let want = [0.0, 0.0, 15.0, 16.0, 17.0, 0.0, 0.0, 0.0, next];
            for (k, (g, w)) in got.iter().zip(want).enumerate() {
                assert!(
                    (g - w).abs() < 1e-9,
                    "relearn {relearn}, sample {k}: {g} != {w}"
                );
            }
            assert!((c.breakaway()[1] - u_b).abs() < 1e-9, "{:?}", c.breakaway());
        }
    }

    // The slip brake with the relearning lasts while the piston slips: the held nudge of the slip
    // brake's test (a_p = 0.2, T_p = 3; no creep limit, so the slip threshold is e_h = 0.02) is cut
    // at 0.85 during a 0.2 mm move: −51; the next sample moves one count (0.86, 0.01 ≤ e_h). Without
    // the relearning the brake goes on (−51, the piston still moves towards r); with it the brake
    // ends and the law, not yet at rest, closes the valves (0).
    #[test]
    fn with_the_relearning_the_slip_brake_ends_when_the_piston_no_longer_slips() {
        let ys = [0.6, 0.6, 0.6, 0.6, 0.65, 0.85, 0.86, 0.86];
        for (relearn, after) in [(false, [-51.0, 0.0]), (true, [0.0, 0.0])] {
            let mut settings = relearning(relearn);
            let n = settings.nudge.as_mut().unwrap();
            (n.slip_brake, n.slip_brake_samples) = (0.2, 3);
            let mut c = PositionController::new(settings, Some(shift_inverse())).unwrap();
            let got = ys.map(|y| c.step(1.0, y).unwrap());
            let want = [0.0, 0.0, 15.0, 16.0, 16.0, -51.0, after[0], after[1]];
            for (k, (g, w)) in got.iter().zip(want).enumerate() {
                assert!(
                    (g - w).abs() < 1e-9,
                    "relearn {relearn}, sample {k}: {g} != {w}"
                );
            }
        }
    }

    #[test]
    fn bad_settings_and_inputs_are_errors() {
        let mut bad = s();
        bad.kp = -1.0;
        assert_eq!(
            PositionController::new(bad, None).unwrap_err(),
            Error::Setting
        );
        let mut c = PositionController::new(s(), None).unwrap();
        assert_eq!(c.step(f64::NAN, 0.0).unwrap_err(), Error::NotFinite);
        assert_eq!(c.integral(), 0.0);
    }

    fn braking() -> PositionSettings<f64> {
        PositionSettings {
            kp: 1.0,
            ki: 0.0,
            brake: Some(BrakeSettings {
                min_step: 10.0,
                switch: 1.0,
                lead: 0.1,
                strength: 0.5,
                samples: 2,
                rest_samples: 2,
                learn: 0.0,
                lead_max: 0.0,
                release: 0,
                rebrake: false,
                preview: false,
            }),
            ..s()
        }
    }

    // r = 20 from y = 0 (a step >= e_a = 10): full command while e > e_s + τ_b v = 1 + 0.1 v:
    // k = 0: v = 0, e = 20; k = 1, 2: v = 100 mm/s, e = 19, 18 > 11; k = 3: v = 800, e = 10 <= 81 →
    // the brake −a_b u_max = −127.5 at k = 3 and 4 (T_b = 2); k = 5: y moved → hold, u = 0;
    // k = 6: unchanged once (1 < N_b = 2), u = 0; k = 7: unchanged twice → the law from a fresh
    // start: Kp e = 7; k = 8: Kp e = 6.5.
    #[test]
    fn the_brake_engages_at_the_sample_where_the_error_falls_within_the_lead() {
        let mut c = PositionController::new(braking(), None).unwrap();
        let y = [0.0, 1.0, 2.0, 10.0, 12.0, 13.0, 13.0, 13.0, 13.5];
        let u = y.map(|y| c.step(20.0, y).unwrap());
        assert_eq!(u, [255.0, 255.0, 255.0, -127.5, -127.5, 0.0, 0.0, 7.0, 6.5]);
        // A new set-point 26.5 mm away re-arms the approach; one 5 mm away does not (< e_a).
        assert_eq!(c.step(40.0, 13.5).unwrap(), 255.0);
        let mut c = PositionController::new(braking(), None).unwrap();
        assert_eq!(c.step(5.0, 0.0).unwrap(), 5.0);
    }

    // Downwards the same rule with the signs turned: r = 0 from y = 20, v = −100 mm/s towards r.
    #[test]
    fn the_brake_acts_the_same_way_down() {
        let mut c = PositionController::new(braking(), None).unwrap();
        let y = [20.0, 19.0, 18.0, 10.0, 8.0];
        let u = y.map(|y| c.step(0.0, y).unwrap());
        assert_eq!(u, [-255.0, -255.0, -255.0, 127.5, 127.5]);
    }

    /// [`braking`] with the lead learnt at rate κ_b up to τ_max.
    fn learning(learn: f64, lead_max: f64) -> PositionSettings<f64> {
        let mut s = braking();
        let b = s.brake.as_mut().unwrap();
        (b.learn, b.lead_max) = (learn, lead_max);
        s
    }

    // The scripted move of the test above: the switch at y_sw = 10 mm with v_sw = (10 − 2)/0.01 =
    // 800 mm/s, the rest that ends the hold at y = 13 mm: D = 3 mm, τ̂ = 3/800 = 0.00375 s; with
    // κ_b = 0.5: τ_b(right) = 0.1 + 0.5 (0.00375 − 0.1) = 0.051875 s, τ_b(left) still 0.1. The
    // commands are those of the brake without learning. The next move up (restart: kept) at
    // 100 mm/s brakes at e ≤ 1 + 0.051875 × 100 = 6.1875 mm, no longer at e ≤ 11 mm: at y = 9 mm
    // (e = 11) it drives on, where a controller reset (lead 0.1 s again) brakes.
    #[test]
    fn the_lead_learnt_after_one_braked_move_is_the_measured_travel_per_speed() {
        let mut c = PositionController::new(learning(0.5, 0.5), None).unwrap();
        let y = [0.0, 1.0, 2.0, 10.0, 12.0, 13.0, 13.0, 13.0, 13.5];
        let u = y.map(|y| c.step(20.0, y).unwrap());
        assert_eq!(u, [255.0, 255.0, 255.0, -127.5, -127.5, 0.0, 0.0, 7.0, 6.5]);
        let [left, right] = c.brake_lead();
        assert_eq!(left, 0.1);
        assert!((right - 0.051875).abs() < 1e-15, "{right}");
        c.restart();
        assert!((c.brake_lead()[1] - 0.051875).abs() < 1e-15);
        let y: [f64; 10] = core::array::from_fn(|k| k as f64);
        let u = y.map(|y| c.step(20.0, y).unwrap());
        assert_eq!(u, [255.0; 10]);
        c.reset();
        assert_eq!(c.brake_lead(), [0.1, 0.1]);
        let u = y.map(|y| c.step(20.0, y).unwrap());
        assert_eq!(u[9], -127.5);
        assert_eq!(u[8], 255.0);
        // κ_b = 0 (a file without it): the same commands, the lead as set.
        let mut c = PositionController::new(braking(), None).unwrap();
        for y in [0.0, 1.0, 2.0, 10.0, 12.0, 13.0, 13.0, 13.0] {
            c.step(20.0, y).unwrap();
        }
        assert_eq!(c.brake_lead(), [0.1, 0.1]);
    }

    // Bounds, κ_b = 1 (τ_b = the bounded τ̂ at once), downwards: switch at y_sw = 10 from 18 (v_sw =
    // 800 mm/s towards r = 0); a rest at y = −190 mm (D = 200 mm, τ̂ = 0.25 s) gives τ_max = 0.2 s; a
    // rest back behind the switch (y = 11 mm, D = −1 mm) gives 0.
    #[test]
    fn the_learnt_lead_stays_within_zero_and_its_largest_value() {
        for (rest, want) in [(-190.0, 0.2), (11.0, 0.0)] {
            let mut c = PositionController::new(learning(1.0, 0.2), None).unwrap();
            for y in [20.0, 19.0, 18.0, 10.0, 9.0, rest, rest, rest] {
                c.step(0.0, y).unwrap();
            }
            assert_eq!(c.brake_lead(), [want, 0.1], "rest at {rest}");
        }
        // κ_b outside [0, 1], or τ_max below τ_b while learning: refused; τ_max unused at κ_b = 0.
        for (learn, lead_max) in [(1.5, 0.2), (-0.1, 0.2), (0.5, 0.05), (f64::NAN, 0.2)] {
            assert_eq!(
                PositionController::new(learning(learn, lead_max), None).unwrap_err(),
                Error::Setting
            );
        }
        assert!(PositionController::new(learning(0.0, 0.0), None).is_ok());
    }

    // The release by hand: T_r = 3 after the T_b = 2 samples of −127.5 of the test above: −127.5 ×
    // 3/4, × 2/4, × 1/4 = −95.625, −63.75, −31.875, then the hold (y moved: 0), and the law after
    // N_b = 2 samples at rest (Kp e = 7).
    #[test]
    fn the_release_lowers_the_braking_command_to_zero_in_equal_steps() {
        let mut s = braking();
        s.brake.as_mut().unwrap().release = 3;
        let mut c = PositionController::new(s, None).unwrap();
        let y = [
            0.0, 1.0, 2.0, 10.0, 12.0, 12.5, 12.8, 12.9, 13.0, 13.0, 13.0,
        ];
        let u = y.map(|y| c.step(20.0, y).unwrap());
        assert_eq!(
            u,
            [255.0, 255.0, 255.0, -127.5, -127.5, -95.625, -63.75, -31.875, 0.0, 0.0, 7.0]
        );
        s.brake.as_mut().unwrap().release = 1001;
        assert!(PositionController::new(s, None).is_err());
    }

    // The re-brake by hand, on the brake above with T_r = 3: full command at k = 0..2, −127.5 at k = 3,
    // 4 (T_b = 2); k = 5: y moved 0.5 mm towards r in the release → −127.5 again, the release not
    // advanced; k = 6, 7, 8: the release −127.5 × 3/4, 2/4, 1/4 = −95.625, −63.75, −31.875; k = 9:
    // the hold, y unchanged (count 1): 0; k = 10: a count towards r (12.5 → 12.75) → −127.5, the
    // count restarts; k = 11: a move away from r (12.5) is no slip towards r: 0 (count 0);
    // k = 12: unchanged once: 0; k = 13: twice (N_b = 2) → the law from a fresh start, Kp e = 7.5.
    // Without the re-brake the same positions give the release at k = 5..7, the hold at k = 8 and
    // the law at k = 9 (Kp e = 7.5, 7.25, 7.5, ...).
    #[test]
    fn the_rebrake_brakes_a_count_towards_r_in_the_release_and_the_hold() {
        let mut s = braking();
        s.brake.as_mut().unwrap().release = 3;
        s.brake.as_mut().unwrap().rebrake = true;
        let y = [
            0.0, 1.0, 2.0, 10.0, 12.0, 12.5, 12.5, 12.5, 12.5, 12.5, 12.75, 12.5, 12.5, 12.5,
        ];
        let mut c = PositionController::new(s, None).unwrap();
        let u = y.map(|y| c.step(20.0, y).unwrap());
        #[rustfmt::skip]
        let want = [255.0, 255.0, 255.0, -127.5, -127.5, -127.5, -95.625, -63.75, -31.875, 0.0,
                    -127.5, 0.0, 0.0, 7.5];
        assert_eq!(u, want);
        s.brake.as_mut().unwrap().rebrake = false;
        let mut c = PositionController::new(s, None).unwrap();
        let u = y.map(|y| c.step(20.0, y).unwrap());
        #[rustfmt::skip]
        let want = [255.0, 255.0, 255.0, -127.5, -127.5, -95.625, -63.75, -31.875, 0.0, 7.5,
                    7.25, 7.5, 7.5, 7.5];
        assert_eq!(u, want);
        // Down, with the signs turned: a count towards r = 0 in the hold re-brakes at +127.5.
        s.brake.as_mut().unwrap().rebrake = true;
        let mut c = PositionController::new(s, None).unwrap();
        let y = y.map(|y| 20.0 - y);
        let u = y.map(|y| c.step(0.0, y).unwrap());
        assert_eq!(u[5], 127.5);
        assert_eq!(u[10], 127.5);
        assert_eq!(u[13], -7.5);
    }

    // The preview (session 20), r = 20 from y = 0 with `braking`'s e_s = 1 mm, τ_b = 0.1 s: k = 1, 2
    // (v = 100 mm/s, e = 19, 18): the next sample's e − v Ts = 18, 17 > 1 + 0.1 × 100 = 11, full
    // command; k = 3 (y = 3.5, v = 150, e = 16.5 > 1 + 15 = 16, but 16.5 − 1.5 = 15 <= 16): the
    // last drive sample at f = (16.5 − 16)/1.5 = 1/3 of u_max, 85; then −127.5 for T_b = 2
    // samples, the hold (y moved, then unchanged once), the law at the second rest: Kp e = 14.
    // Without the preview k = 3 drives 255 and the brake starts at k = 4 (e = 15 <= 16). Down, the
    // same with the signs turned.
    #[test]
    fn the_preview_ends_the_full_command_with_the_fraction_that_reaches_the_switch() {
        let mut s = braking();
        s.brake.as_mut().unwrap().preview = true;
        let y = [0.0, 1.0, 2.0, 3.5, 5.0, 5.5, 6.0, 6.0, 6.0];
        let want = [255.0, 255.0, 255.0, 85.0, -127.5, -127.5, 0.0, 0.0, 14.0];
        for (settings, want, sign) in [
            (s, want, 1.0),
            (s, want.map(|u| -u), -1.0),
            (
                braking(),
                [255.0, 255.0, 255.0, 255.0, -127.5, -127.5, 0.0, 0.0, 14.0],
                1.0,
            ),
        ] {
            let mut c = PositionController::new(settings, None).unwrap();
            let u = y.map(|y| c.step(sign * 20.0, sign * y).unwrap());
            for (k, (u, w)) in u.iter().zip(want).enumerate() {
                assert!((u - w).abs() < 1e-9, "k = {k}: {u} against {w}");
            }
        }
    }

    // The short-step approach's preview: r = 6.9 from y = 0 (`short_stepping`: 51, 56, 61 while y
    // stays at 0); y = 0.5 (v = 50 mm/s, e = 6.4 > 1 + 0.1 × 50 = 6, but 6.4 − 0.5 = 5.9 <= 6): the
    // last drive sample at f = 0.4/0.5 = 0.8 of the drive's 61, 48.8; then −127.5 for T_s = 2
    // samples, the hold (y moved, then unchanged once), the law at the second rest (Kp e = 5.6).
    // Without the preview y = 0.5 drives 61.
    #[test]
    fn the_short_step_preview_ends_the_drive_with_the_fraction_that_reaches_the_switch() {
        let mut s = short_stepping();
        s.short.as_mut().unwrap().preview = true;
        let y = [0.0, 0.0, 0.0, 0.5, 1.0, 1.3, 1.3, 1.3];
        for (settings, at_switch, sign) in [
            (s, 48.8, 1.0),
            (s, 48.8, -1.0),
            (short_stepping(), 61.0, 1.0),
        ] {
            let mut c = PositionController::new(settings, None).unwrap();
            let u = y.map(|y| c.step(sign * 6.9, sign * y).unwrap());
            let want = [51.0, 56.0, 61.0, at_switch, -127.5, -127.5, 0.0, 5.6];
            for (k, (u, w)) in u.iter().zip(want).enumerate() {
                if settings.short.unwrap().preview || k < 4 {
                    assert!((u - sign * w).abs() < 1e-9, "k = {k}: {u} against {w}");
                }
            }
        }
    }

    /// Kp = 1, Ki = 0 and the short-step approach: e_m = 20 mm, U = 0.2 (U u_max = 51 counts), ρ_a =
    /// 500 counts/s (5 counts per sample), e_s' = 1 mm, τ_s = 0.1 s, a_s = 0.5, T_s = 2, N_s = 2.
    fn short_stepping() -> PositionSettings<f64> {
        PositionSettings {
            kp: 1.0,
            ki: 0.0,
            short: Some(ShortApproachSettings {
                max_step: 20.0,
                drive_fraction: 0.2,
                ramp: 500.0,
                switch: 1.0,
                lead: 0.1,
                strength: 0.5,
                samples: 2,
                rest_samples: 2,
                preview: false,
                seed: 0.0,
                seed_speed: 0.0,
            }),
            ..s()
        }
    }

    // r = 10 from y = 0 (e_s' = 1 < 10 <= e_m = 20), by hand: the drive starts at U u_max = 51 and
    // rises by ρ_a Ts = 5 per sample while y stays at 0 (51, 56, 61); y = 0.5 (first motion): held
    // at 61 (v = 50 mm/s, e = 9.5 > 1 + 0.1 × 50 = 6); y = 2 (v = 150, e = 8 <= 1 + 15): the brake
    // −a_s u_max = −127.5 for T_s = 2 samples; y = 3.5 moved: hold 0, then unchanged once (0) and
    // twice (N_s = 2): the law from a fresh start, Kp e = 6.5. Down, the same with the signs turned.
    #[test]
    fn the_short_step_drive_rises_until_the_piston_moves_then_brakes_and_holds() {
        let mut c = PositionController::new(short_stepping(), None).unwrap();
        let y = [0.0, 0.0, 0.0, 0.5, 2.0, 3.0, 3.5, 3.5, 3.5, 3.5];
        let u = y.map(|y| c.step(10.0, y).unwrap());
        let want = [51.0, 56.0, 61.0, 61.0, -127.5, -127.5, 0.0, 0.0, 6.5, 6.5];
        assert_eq!(u, want);
        let mut c = PositionController::new(short_stepping(), None).unwrap();
        let u = y.map(|y| c.step(-10.0, -y).unwrap());
        assert_eq!(u, want.map(|u| -u));
        // A new set-point 3.5 mm below re-arms it (left, from 51 again).
        let mut c = PositionController::new(short_stepping(), None).unwrap();
        for y in y {
            c.step(10.0, y).unwrap();
        }
        assert_eq!(c.step(0.0, 3.5).unwrap(), -51.0);
    }

    // The breakaway seed (session 23), by hand on `short_stepping`'s drive (held at 61 from the
    // first motion; the switch at y = 2 with v = 150 mm/s): κ_s = 0.8 raises u_b(side) from 0 (no
    // compensator) to 0.8 × 61 = 48.8 where v_s is 0 (any speed) or at least 150, and leaves it at 0
    // where v_s = 100 < 150; to the left the same on u_b(left). With the preview the switch is at y
    // = 0.5 (v = 50): seeded from the held 61, not from the last sample's 48.8 (the fraction f = 0.8).
    // A seed below the learnt u_b does not lower it (a deadzone b_r = 55 counts: u_b(right) = 55).
    #[test]
    fn the_breakaway_seed_raises_the_learnt_breakaway_at_the_switch_of_a_slow_drive() {
        let y = [0.0, 0.0, 0.0, 0.5, 2.0, 3.0];
        for (seed_speed, sign, want) in [
            (0.0, 1.0, [0.0, 48.8]),
            (150.0, 1.0, [0.0, 48.8]),
            (100.0, 1.0, [0.0, 0.0]),
            (0.0, -1.0, [48.8, 0.0]),
            (100.0, -1.0, [0.0, 0.0]),
        ] {
            let mut s = short_stepping();
            let a = s.short.as_mut().unwrap();
            (a.seed, a.seed_speed) = (0.8, seed_speed);
            let mut c = PositionController::new(s, None).unwrap();
            for y in y {
                c.step(sign * 10.0, sign * y).unwrap();
            }
            let got = c.breakaway();
            assert!(
                (got[0] - want[0]).abs() < 1e-9 && (got[1] - want[1]).abs() < 1e-9,
                "v_s {seed_speed}, side {sign}: {got:?} against {want:?}"
            );
        }
        let mut s = short_stepping();
        let a = s.short.as_mut().unwrap();
        (a.seed, a.seed_speed, a.preview) = (0.8, 50.0, true);
        let mut c = PositionController::new(s, None).unwrap();
        let u = [0.0, 0.0, 0.0, 0.5].map(|y| c.step(6.9, y).unwrap());
        assert!((u[3] - 48.8).abs() < 1e-9, "{u:?}");
        assert!((c.breakaway()[1] - 48.8).abs() < 1e-9);
        let mut s = short_stepping();
        s.short.as_mut().unwrap().seed = 0.8;
        let dz = Deadzone {
            b_l: -55.0,
            b_r: 55.0,
            m_l: 1.0,
            m_r: 1.0,
        };
        let comp = Compensator::new(dz, SlopeMode::Shift, 0.0, 255.0).unwrap();
        let mut c = PositionController::new(s, Some(comp)).unwrap();
        for y in y {
            c.step(10.0, y).unwrap();
        }
        assert_eq!(c.breakaway(), [55.0, 55.0]);
    }

    // The guard ramp stops at the first motion and does not resume when the piston comes back to
    // where the step began (51, 56, then 56 held); it never exceeds u_max (U = 0.9: 229.5, then
    // min(229.5 + 50, 255) = 255 with ρ_a Ts = 50).
    #[test]
    fn the_guard_ramp_ends_at_the_first_motion_and_stays_within_u_max() {
        let mut c = PositionController::new(short_stepping(), None).unwrap();
        let u = [0.0, 0.0, 0.01, 0.0].map(|y| c.step(10.0, y).unwrap());
        assert_eq!(u, [51.0, 56.0, 56.0, 56.0]);
        let mut s = short_stepping();
        let a = s.short.as_mut().unwrap();
        (a.drive_fraction, a.ramp) = (0.9, 5000.0);
        let mut c = PositionController::new(s, None).unwrap();
        let u = [0.0, 0.0, 0.0].map(|y| c.step(10.0, y).unwrap());
        assert_eq!(u, [229.5, 255.0, 255.0]);
    }

    // Which approach a step gets: |e| <= e_s' (0.5 mm) or > e_m (30 mm) not the short one (the law:
    // Kp e = 0.5, 30); with the brake of `braking` too (e_a = 10 mm), a 15 mm step is a short step
    // (51) and a 30 mm step is braked (full command 255).
    #[test]
    fn the_short_step_approach_takes_the_steps_within_its_range_before_the_brake() {
        for (r, want) in [(0.5, 0.5), (30.0, 30.0), (10.0, 51.0)] {
            let mut c = PositionController::new(short_stepping(), None).unwrap();
            assert_eq!(c.step(r, 0.0).unwrap(), want, "r = {r}");
        }
        let both = PositionSettings {
            brake: braking().brake,
            ..short_stepping()
        };
        for (r, want) in [(15.0, 51.0), (30.0, 255.0), (5.0, 51.0)] {
            let mut c = PositionController::new(both, None).unwrap();
            assert_eq!(c.step(r, 0.0).unwrap(), want, "r = {r}");
        }
    }

    #[test]
    fn short_step_settings_out_of_range_are_refused() {
        for f in [
            |a: &mut ShortApproachSettings<f64>| a.max_step = 0.0,
            |a: &mut ShortApproachSettings<f64>| a.drive_fraction = 0.0,
            |a: &mut ShortApproachSettings<f64>| a.drive_fraction = 1.5,
            |a: &mut ShortApproachSettings<f64>| a.ramp = -1.0,
            |a: &mut ShortApproachSettings<f64>| a.switch = f64::NAN,
            |a: &mut ShortApproachSettings<f64>| a.lead = -0.1,
            |a: &mut ShortApproachSettings<f64>| a.strength = 0.0,
            |a: &mut ShortApproachSettings<f64>| a.samples = 0,
            |a: &mut ShortApproachSettings<f64>| a.rest_samples = 1001,
            |a: &mut ShortApproachSettings<f64>| a.seed = 1.5,
            |a: &mut ShortApproachSettings<f64>| a.seed = -0.1,
            |a: &mut ShortApproachSettings<f64>| a.seed_speed = f64::INFINITY,
        ] {
            let mut s = short_stepping();
            f(s.short.as_mut().unwrap());
            assert_eq!(
                PositionController::new(s, None).unwrap_err(),
                Error::Setting
            );
        }
    }

    #[test]
    fn brake_settings_out_of_range_are_refused() {
        for f in [
            |b: &mut BrakeSettings<f64>| b.strength = 0.0,
            |b: &mut BrakeSettings<f64>| b.strength = 1.5,
            |b: &mut BrakeSettings<f64>| b.samples = 0,
            |b: &mut BrakeSettings<f64>| b.rest_samples = 1001,
            |b: &mut BrakeSettings<f64>| b.lead = -1.0,
            |b: &mut BrakeSettings<f64>| b.min_step = f64::NAN,
        ] {
            let mut s = braking();
            f(s.brake.as_mut().unwrap());
            assert_eq!(
                PositionController::new(s, None).unwrap_err(),
                Error::Setting
            );
        }
    }

    // The learnt cut fraction (issue 25, session 23), by hand: held nudges (no ramp-and-cut band,
    // γ = 0.25, e_n = 1, ρ Ts = 1 count per sample, β = 0.5, N_r = 2, b_r = 30) from y = 0.2 to
    // r = 1 (e_0 = 0.8): the nudge starts at 15 after N_r samples at rest, ramps to 16, its first
    // count (0.21) learns u_b = 16, and it is cut at 0.42 (moved 0.22 ≥ γ e_0 = 0.2). At rest at 0.45
    // it has moved 0.25 < e_0 / 2 = 0.4: g(right) = 2 with the rule. The next nudge (e_0 = 0.55)
    // starts at β u_b = 8, its first count (0.46) learns 9; at 0.60 it has moved 0.15 ≥ γ e_0 =
    // 0.1375, cut without the rule, held with it (< 2 γ e_0 = 0.275; the coast rule, τ_c = 0.03 /
    // 7 s, cuts only at e ≤ 0.04 mm here); at 0.74 (0.29) the rule cuts too. Resting at 1.10, past r
    // by 0.10 > e_h, that nudge moved 0.65 > e_0 + e_h = 0.57: g(right) halves back to 1, and a
    // nudge to the left starts at β |b_l| = 10. Without the rule g stays 1.
    #[test]
    fn a_held_nudge_that_stops_short_learns_a_larger_cut_fraction() {
        let ys = [
            0.2, 0.2, 0.2, 0.2, 0.21, 0.35, 0.42, 0.45, 0.45, 0.45, 0.45, 0.46, 0.55, 0.60, 0.74,
            1.10, 1.10, 1.10,
        ];
        let on = [
            0.0, 0.0, 15.0, 16.0, 16.0, 16.0, 0.0, 0.0, 0.0, 8.0, 9.0, 9.0, 9.0, 9.0, 0.0, 0.0,
            0.0, -10.0,
        ];
        for cut_learn in [true, false] {
            let mut settings = nudging(0.25);
            settings.nudge.as_mut().unwrap().cut_learn = cut_learn;
            let mut c = PositionController::new(settings, Some(shift_inverse())).unwrap();
            for (k, (&y, &w)) in ys.iter().zip(on.iter()).enumerate() {
                // Without the rule the second nudge is cut at 0.60; the piston is then at rest
                // (0.74, 1.10) only from 1.10 on, as with it.
                let w = if !cut_learn && k == 13 { 0.0 } else { w };
                let u = c.step(1.0, y).unwrap();
                assert!(
                    (u - w).abs() < 1e-9,
                    "cut_learn {cut_learn}, sample {k}: {u} != {w}"
                );
                if k == 9 {
                    let g = if cut_learn { 2.0 } else { 1.0 };
                    assert_eq!(c.cut_gain, [1.0, g], "cut_learn {cut_learn}");
                }
            }
            assert_eq!(c.cut_gain, [1.0, 1.0], "cut_learn {cut_learn}");
        }
        // g(side) grows to 1/γ at most: three moves short of half the error from 1 give 2, 4, 4.
        let mut settings = nudging(0.25);
        settings.nudge.as_mut().unwrap().cut_learn = true;
        let n = settings.nudge.unwrap();
        let mut c = PositionController::new(settings, None).unwrap();
        for want in [2.0, 4.0, 4.0] {
            c.last_start = (0.0, 1.0);
            c.learn_cut(&n, true, 0.1);
            assert_eq!(c.cut_gain[1], want);
        }
        c.reset();
        assert_eq!(c.cut_gain, [1.0, 1.0]);
    }
}
