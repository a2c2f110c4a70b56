//! Warnings about a closed-loop run: when its step metrics may not deserve trust, say so in words
//! (the `warnings` list of `ipa-sysid control --json`, `warning:` lines in the text, Python's
//! `control()`).
//!
//! - a step that has not settled within the run, with the reason ([`crate::metrics::Unsettled`]): the
//!   output still moves ([`crate::metrics::still_moving`]), it is held outside the set-point's band
//!   while the command still moves ([`crate::metrics::command_still_moving`]), it oscillates, it entered
//!   its band only in the run's last fifth, or it never moved although the set-point did;
//! - a command saturated at ±u_max for more than [`SATURATION_WARN`] of the samples (the loop is not
//!   in its linear range: the metrics describe a saturated response);
//! - a set-point outside the plant's reachable range (the IPA's stroke, 0..L mm);
//! - an unstable plant model (its metrics describe a diverging simulation);
//! - a step (of a fixed set-point or a staircase) that misses the paper's acceptance (overshoot < 10 %,
//!   judged by the peak past r, OS_r, as `tune` judges it; |e_ss| < 2 % of the step);
//! - a step that first moves the wrong way by [`UNDERSHOOT_WARN_PERCENT`] of the step or more (MATLAB
//!   `stepinfo` Undershoot; not one of the paper's criteria, so said beside them).

use crate::metrics::{still_moving, StepSegment, Unsettled, SETTLING_BAND, TAIL_FRACTION};
use crate::Trace;

/// |y| beyond which a closed loop is reported as diverging, mm (a kilometre: beyond any actuator's
/// stroke; a model plant has no stroke to check against); also the largest start of a model plant
/// (`ipa::spec::MAX_START_ABS`).
pub const DIVERGED_MM: f64 = 1e6;

/// Undershoot (the wrong-way excursion from y0, % of the step) from which a step is warned about: the
/// paper's overshoot limit, 10 %, mirrored below y0 (audit s18 L-4: a 10.4 % dip passed silently).
pub const UNDERSHOOT_WARN_PERCENT: f64 = 10.0;

/// A value with 4 decimals, in scientific notation beyond 1e9 in magnitude (a diverging loop's
/// numbers would otherwise print hundreds of digits).
pub fn fmt_value(v: f64) -> String {
    if v.abs() >= 1e9 {
        format!("{v:.4e}")
    } else {
        format!("{v:.4}")
    }
}

/// A length in mm as a person writes it: at most 4 decimals, trailing zeros dropped (a step of
/// 100 − 97.41 mm is "2.59", not "2.5900000000000034").
fn fmt_mm(v: f64) -> String {
    if v.abs() >= 1e9 {
        return fmt_value(v);
    }
    if v != 0.0 && v.abs() < 5e-5 {
        // A drift of 1e-8 is not "0" (audit s17 M-f: "went 0 … from y0").
        return format!("{v:.3e}");
    }
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" {
        "0".to_string()
    } else {
        s.to_string()
    }
}

/// Fraction of samples at the command limit above which the run is reported as saturated.
pub const SATURATION_WARN: f64 = 0.2;

/// The units a run's words name: the IPA's, or a model plant's own, which are its estimation
/// record's (a tank's volts, a motor's radians). Serialised as `control --json`'s and Python
/// `control()`'s `units` (audit s22 L-B8): the metrics' keys keep their `_mm` names for the JSON's
/// readers, and hold values in `units.y`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct Units {
    /// Of the command u.
    pub u: &'static str,
    /// Of the output y, the set-point and the errors.
    pub y: &'static str,
}

impl Units {
    /// The IPA's: the command in PWM counts, lengths in mm.
    pub const IPA: Units = Units {
        u: "counts",
        y: "mm",
    };
    /// A model plant's: its estimation record's, which the model does not name.
    pub const MODEL: Units = Units {
        u: "(u's units)",
        y: "(y's units)",
    };

    /// [`Units::MODEL`] for a model plant (`ipa::PlantLimits::model_units`), else [`Units::IPA`].
    pub fn of(model_plant: bool) -> Units {
        if model_plant {
            Units::MODEL
        } else {
            Units::IPA
        }
    }
}

impl Default for Units {
    fn default() -> Units {
        Units::IPA
    }
}

/// What the caller knows about the plant beyond the trace.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LoopFacts {
    /// |u| <= u_max: the command limit in counts.
    pub u_max: f64,
    /// The outputs the plant can reach, in mm (the IPA: 0..stroke); `None` when unknown.
    pub range_mm: Option<(f64, f64)>,
    /// The stability verdict of a model plant's poles ([`sysid_core::Stability`], `ipa::PlantLimits::stability`):
    /// an on-circle or unstable plant is warned of ([`plant_stability_warning`]); `None` for a plant
    /// without poles (the physics IPA, a NARX model).
    pub plant_stability: Option<sysid_core::Stability>,
    /// True for a fixed set-point or a staircase: each step is judged against the paper's acceptance
    /// (a profile read from samples may change r every sample, which has no step to judge).
    pub judge_steps: bool,
    /// The commands [min, max] of a model plant's estimation data (`PlantLimits::data_u_range`): a run
    /// whose commands leave them by more than a tenth of their span is warned (the model extrapolates
    /// there; audit s13 L10); `None`: not checked.
    pub data_u_range: Option<(f64, f64)>,
    /// The outputs [min, max] of a model plant's estimation data (`PlantLimits::data_y_range`): a
    /// set-point that leaves them by more than a tenth of their span is warned as the commands are
    /// (audit s22 M-B1); `None`: not checked.
    pub data_y_range: Option<(f64, f64)>,
    /// The units the warnings name: the IPA's mm and counts, or a model plant's own
    /// ([`Units::MODEL`]: its signals are in its estimation record's units).
    pub units: Units,
    /// How the caller sets the run's length (`--duration` on the command line, `duration=` in Python):
    /// the warnings then say how to run longer; `None` for a run of fixed length (`reproduce`'s tests),
    /// which says nothing the user cannot do.
    pub duration_setting: Option<&'static str>,
    /// How the caller sets the start y0 (`--y0`, `y0=`): named when a model plant's run starts outside
    /// its estimation data (audit s27 L-6); `None`: not named.
    pub start_setting: Option<&'static str>,
}

/// A warning when the `what` of a loop on a model plant ("commands", "set-points"), whose [min, max]
/// is `extremes`, leave the model's estimation data's `signal` range `range` ("u" or "y", [lo, hi]) by
/// more than a tenth of its span (`sysid_core::DataRange::excursion_of`): outside it the model
/// extrapolates. The one rule of `control` (the run's commands and set-points) and `tune` (±u_max and
/// the specification's set-points low..high, audit s22 M-B1).
pub fn extrapolation_warning(
    what: &str,
    signal: &str,
    extremes: (f64, f64),
    range: (f64, f64),
) -> Option<String> {
    let (min, max) = sysid_core::DataRange::excursion_of(extremes, range)?;
    let (lo, hi) = range;
    Some(format!(
        "the {what} span [{min:.6}, {max:.6}] but the plant model's estimation data had {signal} in \
         [{lo}, {hi}]: outside it the model extrapolates, so the loop's response there is the \
         equations' guess, not the plant's"
    ))
}

/// The warning for a plant model with the stability verdict `s` ([`sysid_core::Stability`], the one
/// `identify` reports), or `None`:
/// - settles: none;
/// - an integrator (poles within ε = 10⁻⁵ of z = 1): none — a position actuator integrates its
///   velocity, so a model of it may have its pole at z = 1 (the paper's IPA model has its slowest at
///   0.99923, which settles), and a loop closed around such a plant is the normal case, not a doubt;
///   `identify`, `simulate` and `tune` already say what the pole means for the model, and whether the
///   loop settles is judged from the run itself (the warnings below);
/// - on the circle away from z = 1 (|p| within ε of 1, an undamped oscillation): the plant model rings
///   for ever at that pole's frequency, which an actuator does not;
/// - unstable (|p| > 1 + ε, or a pole that is not a number): the plant model diverges.
pub fn plant_stability_warning(s: sysid_core::Stability) -> Option<String> {
    use sysid_core::Stability;
    match s {
        Stability::Settles { .. } | Stability::Integrator { .. } => None,
        Stability::OnCircle { pole } => Some(format!(
            "the plant model has a pole on the unit circle away from z = 1 (at {:.6} {} {:.6}i, modulus \
             {:.7}, within {:e} of 1): it oscillates without decay (at {:.4} of the sampling frequency), \
             so its closed-loop response describes an undamped oscillating model, not the actuator",
            pole.re,
            if pole.im < 0.0 { "-" } else { "+" },
            pole.im.abs(),
            s.modulus(),
            sysid_core::stability::MARGIN,
            pole.im.abs().atan2(pole.re) / std::f64::consts::TAU,
        )),
        Stability::Unstable { .. } if !s.modulus().is_finite() => Some(
            "the plant model is unstable (a pole is not a finite number): its closed-loop response \
             describes a diverging model, not the actuator"
                .to_string(),
        ),
        Stability::Unstable { .. } => Some(format!(
            "the plant model is unstable (a pole has modulus {} > 1 + {:e}): its closed-loop \
             response describes a diverging model, not the actuator",
            sysid_core::format::Modulus(s.modulus()),
            sysid_core::stability::MARGIN,
        )),
    }
}

/// The warnings of a run `trace` with its `steps` (from [`crate::metrics_for_steps`]).
pub fn loop_warnings(trace: &Trace, steps: &[StepSegment], facts: &LoopFacts) -> Vec<String> {
    let mut w = Vec::new();
    let Units {
        u: u_unit,
        y: y_unit,
    } = facts.units;
    w.extend(facts.plant_stability.and_then(plant_stability_warning));
    // Set-point segments of one sample have no response to measure and are not among `steps`
    // (`metrics_for_steps` needs two samples): said, with their set-points (audit s31 L-5: a model
    // sampled every 4 s ran a 4-s staircase, four of its five steps vanished and the run said "1 of 1
    // steps").
    let n = trace.r.len();
    let single: Vec<f64> = (0..n)
        .filter(|&k| {
            let starts = k == 0 || trace.r[k] != trace.r[k - 1];
            let ends = k + 1 == n || trace.r[k + 1] != trace.r[k];
            starts && ends
        })
        .map(|k| trace.r[k])
        .collect();
    if !single.is_empty() {
        let shown: Vec<String> = single
            .iter()
            .take(5)
            .map(|r| sysid_core::format::Shortest(*r).to_string())
            .collect();
        w.push(format!(
            "{} set-point step(s) lasted one sample (r = {}{} {y_unit}) and are not measured (a step \
             needs two samples): the profile changes faster than the plant is sampled; hold each \
             set-point longer than one sampling period",
            single.len(),
            shown.join(", "),
            if single.len() > 5 { ", …" } else { "" }
        ));
    }
    if let Some((lo, hi)) = facts.range_mm {
        let outside: Vec<f64> = steps
            .iter()
            .map(|s| s.setpoint_mm)
            .filter(|r| *r < lo || *r > hi)
            .collect();
        if let Some(r) = outside.first() {
            w.push(format!(
                "set-point r = {} {y_unit} is outside the reachable range {lo}..{hi} {y_unit} (the stroke): the \
                 piston cannot follow it, and the step metrics describe the end stop",
                sysid_core::format::Shortest(*r)
            ));
        }
    }
    if let Some(range) = facts.data_y_range {
        w.extend(extrapolation_warning(
            "set-points",
            "y",
            sysid_core::DataRange::extremes(&trace.r),
            range,
        ));
        // The start, by the same rule (audit s27 L-6: a model plant started at y0 = 0, far below a
        // record that never went there, and nothing said so).
        if let Some(&y0) = trace.y.first() {
            if sysid_core::DataRange::excursion_of((y0, y0), range).is_some() {
                let (lo, hi) = range;
                let how = facts
                    .start_setting
                    .map_or(String::new(), |s| format!(" (start inside them: {s})"));
                w.push(format!(
                    "the run starts at y0 = {} {y_unit}, outside the plant model's estimation data, which \
                     had y in [{lo}, {hi}]: until the loop brings y there, the response is the equations' \
                     guess, not the plant's{how}",
                    sysid_core::format::Shortest(y0)
                ));
            }
        }
    }
    if let Some(range) = facts.data_u_range {
        w.extend(extrapolation_warning(
            "commands",
            "u",
            sysid_core::DataRange::extremes(&trace.u),
            range,
        ));
    }
    let longer = |or_hold: bool| match facts.duration_setting {
        Some(d) if or_hold => format!(" (run longer: {d}, or hold each set-point longer)"),
        Some(d) => format!(" (run longer: {d})"),
        None => String::new(),
    };
    let n = trace.len();
    if let Some(peak) = trace
        .y
        .iter()
        .map(|y| y.abs())
        .reduce(f64::max)
        .filter(|p| *p > DIVERGED_MM)
    {
        w.push(format!(
            "the closed loop diverges: the output reached |y| = {} {y_unit}, beyond any actuator's stroke, \
             so the step metrics describe a diverging loop (check the plant model's gains)",
            fmt_value(peak)
        ));
    }
    if n > 0 && facts.u_max > 0.0 {
        let at_limit = trace
            .u
            .iter()
            .filter(|u| u.abs() >= facts.u_max * (1.0 - 1e-9))
            .count();
        let fraction = at_limit as f64 / n as f64;
        if fraction > SATURATION_WARN {
            w.push(format!(
                "the command is saturated at ±{} {u_unit} for {:.1} % of the samples ({at_limit} of {n}): \
                 the loop is not in its linear range, so the step metrics describe a saturated response",
                // Shortest: 1e-320 in exponent form, not 320 zeros (audit s35 L-3).
                sysid_core::format::Shortest(facts.u_max),
                100.0 * fraction
            ));
        }
    }
    for s in steps {
        // The step's metrics and, when it has not settled, why (metrics_for_steps).
        let (m, why) = (s.metrics, s.unsettled);
        let head = format!(
            "the step to r = {} {y_unit} at t = {:.3} s",
            sysid_core::format::Shortest(s.setpoint_mm),
            s.start_s
        );
        let ess = fmt_value(m.steady_state_error_mm.unwrap_or(f64::NAN));
        let within = s.end_s - s.start_s;
        let tail_s = TAIL_FRACTION * within;
        // The step's samples (t increases: two binary searches).
        let first = trace.t.partition_point(|&t| t < s.start_s);
        let last = trace.t.partition_point(|&t| t <= s.end_s).max(first);
        let (t, y, u) = (
            &trace.t[first..last],
            &trace.y[first..last],
            &trace.u[first..last.min(trace.u.len())],
        );
        // A set-point step under a command that stayed 0 throughout: the controller never acted, and
        // whatever the output did is the plant's own drift (audit s17 M-f: "moved away … farther than
        // it started" for a loop that never moved).
        if s.setpoint_mm != s.y0_mm && !u.is_empty() && u.iter().all(|u| *u == 0.0) {
            let drift = y.last().copied().unwrap_or(s.y0_mm) - s.y0_mm;
            w.push(format!(
                "{head}: the command was identically 0 over the step ({} samples): the controller never acted, so the output {} on the plant's own dynamics and the step's metrics describe no control (a controller whose bands are wider than the set-point's step holds still: check its hold, fine and nudge bands against the step of {} {y_unit})",
                u.len(),
                if drift == 0.0 {
                    format!("stayed at y0 = {} {y_unit}", fmt_mm(s.y0_mm))
                } else {
                    format!("drifted {} {y_unit} from y0 = {} {y_unit}", fmt_mm(drift), fmt_mm(s.y0_mm))
                },
                fmt_mm((s.setpoint_mm - s.y0_mm).abs())
            ));
            continue;
        }
        // A step judged (it has an overshoot) that has not settled: its overshoot beyond the last
        // sample is not final, and how far it went past r is (audit s17 M-b).
        let not_final_os = match (why, m.overshoot_percent) {
            (Some(_), Some(os)) => {
                let past = m.overshoot_past_setpoint_mm.map_or(String::new(), |p| {
                    if p == 0.0 {
                        return "; the output has not gone past the set-point".to_string();
                    }
                    format!(
                        "; the output went {} {y_unit} ({:.2} % of the step) past the set-point (the peak past r)",
                        fmt_mm(p),
                        m.overshoot_past_setpoint_percent.unwrap_or(f64::NAN)
                    )
                });
                format!(
                    "; its overshoot of {os:.2} % (beyond the last sample) is not final either{past}"
                )
            }
            _ => String::new(),
        };
        // Not settled and never 90 % of the way to r: no rise time (metrics::StepMetrics::assess).
        if why.is_some() && m.overshoot_mm.is_some() && m.rise_time_s.is_none() {
            let r_step = s.setpoint_mm - s.y0_mm;
            let reached = y
                .iter()
                .map(|y| (y - s.y0_mm) * r_step.signum())
                .fold(0.0_f64, f64::max);
            w.push(format!(
                "{head} reached at most {:.1} % of the way from y0 = {} {y_unit} to r within the run (less than 90 %), so it has no 10-90 % rise time (null); the set-point may be beyond the plant's reach within the run{}",
                100.0 * reached / r_step.abs(),
                fmt_mm(s.y0_mm),
                longer(false)
            ));
        }
        match why {
            None => {
                let Some(ts) = m.settling_time_s else {
                    continue;
                };
                // Settled against the set-point's band: does the output still creep?
                let step = (y.last().copied().unwrap_or(s.y0_mm) - s.y0_mm).abs();
                if still_moving(t, y, SETTLING_BAND * step) {
                    w.push(format!(
                        "{head} still creeps at the end of the run: its settling time ({ts:.3} s) is \
                         measured against the set-point's 2 % band, and its steady-state error of \
                         {ess} {y_unit} is not final{}",
                        longer(false)
                    ));
                }
            }
            Some(Unsettled::Moving) => w.push(format!(
                "{head} has not settled within {within:.3} s: the output is still moving at the end of \
                 the run, so its settling time is unknown (null) and its steady-state error of {ess} \
                 {y_unit} is not final{not_final_os}{}",
                longer(false)
            )),
            Some(Unsettled::CommandMoving) => {
                // e_ss = r − y_f: of the step's sign when short of r, of the other sign when past it.
                let e = m.steady_state_error_mm.unwrap_or(f64::NAN);
                let side = if e * (s.setpoint_mm - s.y0_mm) < 0.0 {
                    "past"
                } else {
                    "short of"
                };
                w.push(format!(
                    "{head} has not settled within {within:.3} s: the output stopped {} {y_unit} {side} \
                     the set-point, outside its 2 % band, while the command still changes (friction \
                     holds the piston while the integrator winds up), so its settling time is unknown \
                     (null) and its steady-state error is not final{not_final_os}",
                    fmt_value(e.abs())
                ))
            }
            Some(Unsettled::Oscillating { peak_to_peak_mm }) => w.push(format!(
                "{head} has not settled within {within:.3} s: the output oscillates, swinging \
                 {peak_to_peak_mm:.4} {y_unit} peak to peak over the run's last {tail_s:.3} s (a limit \
                 cycle), so it has no settling time (null) and its steady-state error of {ess} {y_unit} is \
                 only where the last sample fell{not_final_os}"
            )),
            Some(Unsettled::LateEntry { at_s }) => w.push(format!(
                "{head} has not settled within {within:.3} s: the output entered its 2 % band for good \
                 only {at_s:.3} s after the step, within the run's last {tail_s:.3} s, too late to tell \
                 that it stays, so its settling time is unknown (null){not_final_os}{}",
                longer(false)
            )),
            Some(Unsettled::MovedAway { moved_mm }) => w.push(format!(
                "{head} moved away from its set-point: the output went {} {y_unit} from y0 = {} {y_unit} and \
                 ended {} {y_unit} from r, farther than it started ({} {y_unit}), so the step has no rise, \
                 overshoot or settling time (null); the set-point may be beyond the plant's reach, or \
                 the loop's sign is wrong",
                fmt_mm(moved_mm),
                fmt_mm(s.y0_mm),
                fmt_value(m.steady_state_error_mm.unwrap_or(f64::NAN).abs()),
                fmt_mm((s.setpoint_mm - s.y0_mm).abs())
            )),
            Some(Unsettled::TooShort { samples }) => w.push(format!(
                "{head} is too short to judge: {samples} samples (at least {} are needed), so it has \
                 no rise, overshoot or settling time (null) and its error of {ess} {y_unit} is where the \
                 run stopped, not a steady state{}",
                crate::metrics::MIN_STEP_SAMPLES,
                longer(true)
            )),
            Some(Unsettled::NoResponse) => {
                // A command that pushed away from r for most of the step held the output at an end
                // stop: the loop's sign, not friction (audit s30 M-4: `--kp -14` sat at −255 and was
                // called "friction or a command too small").
                let toward = (s.setpoint_mm - s.y0_mm).signum();
                let away = u.iter().filter(|u| **u * toward < 0.0).count();
                let cause = if !u.is_empty() && 10 * away >= 9 * u.len() {
                    format!(
                        "the command pushed the other way for {away} of its {} samples (u of the \
                         opposite sign to r − y0, up to {} {u_unit}): the loop's sign is wrong (a negative \
                         gain, or a plant that moves the other way), and the output was held at an end \
                         stop",
                        u.len(),
                        fmt_value(u.iter().fold(0.0_f64, |m, v| m.max(v.abs())))
                    )
                } else {
                    "friction holds the piston, or the command is too small to open a valve".to_string()
                };
                w.push(format!(
                    "{head} had no response: the output stayed at y0 = {} {y_unit} while the set-point \
                     moved {} {y_unit} away ({cause}), so the step has no metrics but its error of {ess} \
                     {y_unit}",
                    fmt_mm(s.y0_mm),
                    fmt_mm((s.setpoint_mm - s.y0_mm).abs())
                ))
            }
        }
    }
    if facts.judge_steps {
        for s in steps {
            let step = (s.setpoint_mm - s.y0_mm).abs();
            // The overshoot is judged by the peak past r (OS_r), as `tune` judges it: the overshoot
            // beyond the last sample is not final while a step has not settled (audit s17 M-b).
            let (os, ess) = (
                s.metrics.overshoot_judged_percent(),
                s.metrics.steady_state_error_mm,
            );
            let mut missed = Vec::new();
            if let Some(os) = os.filter(|os| *os >= 10.0) {
                missed.push(format!("overshoot past r {os:.2} % >= 10 %"));
            }
            if let Some(e) = ess.filter(|e| step > 0.0 && e.abs() >= 0.02 * step) {
                missed.push(format!(
                    "|e_ss| = {} {y_unit} >= 2 % of the {} {y_unit} step ({} {y_unit})",
                    fmt_value(e.abs()),
                    fmt_mm(step),
                    fmt_value(0.02 * step)
                ));
            }
            let which = if steps.len() == 1 {
                "the step".to_string()
            } else {
                format!(
                    "the step to r = {} {y_unit} at t = {:.3} s",
                    sysid_core::format::Shortest(s.setpoint_mm),
                    s.start_s
                )
            };
            if let (Some(us), Some(pc)) = (
                s.metrics.undershoot_mm,
                s.metrics
                    .undershoot_percent
                    .filter(|p| *p >= UNDERSHOOT_WARN_PERCENT),
            ) {
                w.push(format!(
                    "{which} first moves {} {y_unit} the wrong way ({} % of the step, MATLAB stepinfo's \
                     Undershoot) before it moves towards r: the paper's acceptance (overshoot, e_ss) does not judge \
                     this dip",
                    fmt_value(us),
                    fmt_value(pc)
                ));
            }
            if !missed.is_empty() {
                w.push(format!(
                    "{which} misses the paper's acceptance: {}",
                    missed.join("; ")
                ));
            }
        }
    }
    w
}

/// The warnings of a closed-loop run that come before its loop's own ([`loop_warnings`]), in the
/// order `ipa-sysid control` prints them: the plant model file's doubts, what a controller file's
/// provenance says against it ([`crate::ControllerFile::provenance_warning`]), the deadzone
/// compensator's scale ([`crate::compensator::compensator_scale_warning`]) and a profile row the run never
/// reaches ([`crate::Profile::last_row_warning`]). One list for the command line and the Python
/// package's `control` (audit s18 M-4: the provenance warning was the command line's only).
pub fn setup_warnings(
    model_warnings: &[String],
    controller_file: Option<&crate::ControllerFile>,
    compensator_warning: Option<String>,
    profile: &crate::Profile,
    duration_s: f64,
) -> Vec<String> {
    let mut w = model_warnings.to_vec();
    w.extend(controller_file.and_then(|f| f.provenance_unread()));
    w.extend(controller_file.and_then(|f| f.provenance_warning()));
    w.extend(compensator_warning);
    w.extend(profile.last_row_warning(duration_s));
    w
}

fn deadzone_words(d: &sysid_core::Deadzone) -> String {
    format!(
        "b_l = {}, b_r = {}, m_l = {}, m_r = {}",
        fmt_value(d.b_l),
        fmt_value(d.b_r),
        fmt_value(d.m_l),
        fmt_value(d.m_r)
    )
}

/// The plant a controller file is run or analysed on, as its provenance ([`provenance_warning`]) can be
/// compared with it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RunPlant<'a> {
    /// A model read from this file (its name as given).
    ModelFile(&'a str),
    /// A model given in memory (Python's `Model`): no file to compare.
    ModelInMemory,
    /// The physics IPA with the plant configuration (a twin) read from this file, or the built-in one.
    Physics(Option<&'a str>),
    /// The paper's model (`--plant paper`).
    Paper,
}

impl RunPlant<'_> {
    fn words(&self) -> String {
        match self {
            RunPlant::ModelFile(name) => format!("the model {}", sysid_core::format::visible(name)),
            RunPlant::ModelInMemory => "this model".into(),
            RunPlant::Physics(Some(name)) => {
                format!("the physics plant of {}", sysid_core::format::visible(name))
            }
            RunPlant::Physics(None) => "the built-in physics IPA".into(),
            RunPlant::Paper => "the paper's model".into(),
        }
    }
}

/// True when the paths `a` and `b` name the same file: the same path, file name or canonical path (a
/// path given from another folder is the same file), or two regular files of at most 16 MiB with the same
/// bytes (a copy of the model or twin).
fn same_file(a: &str, b: &str) -> bool {
    let (a, b) = (std::path::Path::new(a), std::path::Path::new(b));
    let small =
        |p: &std::path::Path| std::fs::metadata(p).is_ok_and(|m| m.is_file() && m.len() <= 1 << 24);
    a == b
        || a.file_name() == b.file_name()
        || matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
        || (small(a)
            && small(b)
            && matches!((std::fs::read(a), std::fs::read(b)), (Ok(x), Ok(y)) if x == y))
}

/// The warning of a controller file whose provenance (`"source"`, written by `tune`: `model FILE`,
/// `twin FILE`, or `model (Python)` for a model given in memory) names another plant than `plant`, the
/// one it is run or analysed on (audit s22 M-B6 for two model files; audit s28 L-6: a controller tuned
/// on a twin and run on a model, or on another twin, said nothing). Files are compared by
/// [`same_file`]; a source or a plant given in memory is compared by kind only (a model is not a twin);
/// `None` when they agree, or the source is not one `tune` writes.
pub fn provenance_warning(file: &crate::ControllerFile, plant: RunPlant<'_>) -> Option<String> {
    let source = file.provenance.as_ref()?.get("source")?.as_str()?;
    let (kind, path) = source.split_once(' ')?;
    let in_memory = path.starts_with('(');
    let same = match (kind, plant) {
        ("model", RunPlant::ModelFile(name)) => in_memory || same_file(path, name),
        ("model", RunPlant::ModelInMemory) => true, // nothing to compare
        ("twin", RunPlant::Physics(Some(name))) => in_memory || same_file(path, name),
        ("model" | "twin", _) => false,
        _ => return None,
    };
    (!same).then(|| {
        format!(
            "the controller file was tuned on the {kind} {} (its provenance), not on {}: its gains and \
             compensator are that {kind}'s; check it here before trusting it",
            sysid_core::format::visible(path),
            plant.words()
        )
    })
}

/// The run of a controller file against the steady-state part of the specification it was tuned for
/// (its provenance's `spec`: |e_ss| ≤ `ess_all_mm` in every step): each settled step whose |e_ss| misses
/// it, in one warning with the worst, and when that error sits where the file's nudges act (its nudge
/// band, or its rest band once the piston rests), that the nudge and hold logic is what holds it (audit s30 M-5: a
/// controller tuned on a model parked 0.44–0.48 mm short on `--plant paper`, 10 times its 0.05 mm
/// specification, with only the file's generic "does not meet the specification" warning). Nothing for a
/// file without a specification (hand-written) or steps not settled (their own warnings say so).
pub fn spec_warnings(file: &crate::ControllerFile, steps: &[StepSegment]) -> Vec<String> {
    let Some(limit) = file
        .provenance
        .as_ref()
        .and_then(|p| p.get("spec"))
        .and_then(|s| s.get("ess_all_mm"))
        .and_then(serde_json::Value::as_f64)
        .filter(|l| l.is_finite() && *l >= 0.0)
    else {
        return Vec::new();
    };
    // The rounding tune allows (`crate::tune`'s ROUNDING_MM).
    let tol = 1e-9;
    let settled: Vec<&StepSegment> = steps
        .iter()
        .filter(|s| s.metrics.settling_time_s.is_some() && !s.too_short())
        .collect();
    let missed: Vec<(f64, f64)> = settled
        .iter()
        .filter_map(|s| {
            let e = s.metrics.steady_state_error_mm?.abs();
            (e > limit + tol).then_some((s.setpoint_mm, e))
        })
        .collect();
    let Some(&(r, worst)) = missed.iter().max_by(|a, b| a.1.total_cmp(&b.1)) else {
        return Vec::new();
    };
    // Where the nudges act: the nudge band e_n, and the rest band e_r once the piston rests.
    let why = match file.controller.nudge.as_ref() {
        Some(n) if worst <= n.band_mm.max(n.rest_band_mm) + tol => format!(
            ": the error sits where the nudges act (nudge band e_n = {} mm{}), and their pulses do not \
             move this plant (a nudge and hold design tuned on another plant); tune on this plant, or run \
             without the controller file",
            sysid_core::format::sig(n.band_mm, 4),
            if n.rest_band_mm > n.band_mm {
                format!(
                    ", rest band e_r = {} mm once the piston rests",
                    sysid_core::format::sig(n.rest_band_mm, 4)
                )
            } else {
                String::new()
            }
        ),
        _ => String::new(),
    };
    vec![format!(
        "{} of {} settled step(s) miss the controller file's steady-state specification (|e_ss| ≤ {} mm in \
         every step, its provenance's spec): the worst |e_ss| = {} mm at r = {} mm{why}",
        missed.len(),
        settled.len(),
        sysid_core::format::Shortest(limit),
        sysid_core::format::sig(worst, 4),
        sysid_core::format::Shortest(r),
    )]
}

/// What a controller file says against the plant of a `--plant` specification `spec` (with
/// `plant_config`, the physics plant's `--plant-config`): a model file read from its path gets
/// [`controller_model_warnings`] when it is a linear-block model, every other plant the provenance check
/// ([`provenance_warning`]). The one mapping of `control --controller` and Python's `control(plant=...)`.
pub fn controller_plant_warnings(
    file: &crate::ControllerFile,
    spec: &ipa::PlantSpec,
    plant_config: Option<&std::path::Path>,
) -> Vec<String> {
    let config = plant_config.map(|p| p.display().to_string());
    match spec {
        ipa::PlantSpec::ModelFile(path) => {
            let name = path.display().to_string();
            match sysid_core::model_file::read_any_model(path) {
                Ok(sysid_core::model_file::AnyModel::Linear(m)) => {
                    controller_model_warnings(file, &m, Some(&name))
                }
                _ => provenance_warning(file, RunPlant::ModelFile(&name))
                    .into_iter()
                    .collect(),
            }
        }
        ipa::PlantSpec::Ipa => provenance_warning(file, RunPlant::Physics(config.as_deref()))
            .into_iter()
            .collect(),
        ipa::PlantSpec::Paper => provenance_warning(file, RunPlant::Paper)
            .into_iter()
            .collect(),
    }
}

/// What a controller file says against the plant model `model` (read from `model_name`) it is run or
/// analysed on (audit s22 M-B6: a controller tuned on a Hammerstein model, run on a linear ARX model,
/// stepped its command by 38..48 counts at every sign change of the error without a word): its
/// compensator inverts a deadzone the model does not have (tune sets the compensator's own breakpoints,
/// so one that differs from the model's is not a sign of another model); its provenance names another
/// plant ([`provenance_warning`]). The one check of `control --controller` on a model plant and `response
/// --controller`, and of Python's `control` and `Model.frequency_response`.
pub fn controller_model_warnings(
    file: &crate::ControllerFile,
    model: &sysid_core::Model,
    model_name: Option<&str>,
) -> Vec<String> {
    let mut w = Vec::new();
    let named = model_name.map_or(String::new(), |n| {
        format!(" {}", sysid_core::format::visible(n))
    });
    if let (Some(c), None) = (&file.controller.compensator, model.deadzone()) {
        w.push(format!(
            "the controller's compensator inverts a deadzone ({}) that the plant model{named} \
                 does not have (its input map is linear): the controller steps its \
                 command by b_l or b_r at every sign change of the error, and its margins are \
                 computed with the compensator's slope; tune a controller on this model",
            deadzone_words(&c.deadzone)
        ));
    }
    w.extend(provenance_warning(
        file,
        model_name.map_or(RunPlant::ModelInMemory, RunPlant::ModelFile),
    ));
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics_for_steps;
    use sysid_core::Stability;

    fn trace(y: Vec<f64>, u: Vec<f64>, r: f64) -> Trace {
        let n = y.len();
        Trace {
            t: (0..n).map(|k| k as f64 * 0.01).collect(),
            r: vec![r; n],
            u,
            y,
        }
    }

    // y = 50 (1 − e^{−t/τ}) with τ = 5 s over 2 s: at the end it still climbs 50/5 e^{−0.4} ≈ 6.7 mm/s,
    // 1.3 mm over the last 0.2 s, i.e. 13 mm over the run ≫ the 2 % band: not settled, and said.
    #[test]
    fn a_creeping_response_has_no_settling_time_and_a_warning() {
        let y: Vec<f64> = (0..201)
            .map(|k| 50.0 * (1.0 - (-(k as f64 * 0.01) / 5.0).exp()))
            .collect();
        let tr = trace(y, vec![10.0; 201], 50.0);
        let steps = metrics_for_steps(&tr).unwrap();
        assert_eq!(steps[0].metrics.settling_time_s, None);
        let w = loop_warnings(
            &tr,
            &steps,
            &LoopFacts {
                u_max: 255.0,
                ..LoopFacts::default()
            },
        );
        assert!(w.iter().any(|w| w.contains("has not settled")), "{w:?}");
    }

    // Commands −255..3 against a model estimated on u in [−100, 100]: 255 is beyond 100 + 20, warned;
    // within [−110, 110] they are not.
    #[test]
    fn commands_beyond_a_model_plants_data_are_warned() {
        let mut u = vec![-255.0; 101];
        u[0] = 3.0;
        let tr = trace(vec![0.0; 101], u, 10.0);
        let steps = metrics_for_steps(&tr).unwrap();
        let facts = |range| LoopFacts {
            u_max: 255.0,
            data_u_range: Some(range),
            data_y_range: None,
            ..LoopFacts::default()
        };
        let w = loop_warnings(&tr, &steps, &facts((-100.0, 100.0)));
        assert!(
            w.iter()
                .any(|w| w.contains("the commands span [-255.000000, 3.000000]")
                    && w.contains("u in [-100, 100]")),
            "{w:?}"
        );
        let w = loop_warnings(&tr, &steps, &facts((-240.0, 240.0)));
        assert!(!w.iter().any(|w| w.contains("the commands span")), "{w:?}");
    }

    // Audit s30 L-3: a set-point of 1e300 is printed as 1e300, not as its 301 digits.
    #[test]
    fn a_huge_set_point_is_printed_short() {
        let tr = trace(vec![0.0; 101], vec![255.0; 101], 1e300);
        let steps = metrics_for_steps(&tr).unwrap();
        let w = loop_warnings(
            &tr,
            &steps,
            &LoopFacts {
                u_max: 255.0,
                ..LoopFacts::default()
            },
        );
        assert!(
            w.iter().any(|w| w.contains("the step to r = 1e300 ")),
            "{w:?}"
        );
        assert!(
            w.iter().all(|w| !w.contains("100000000000000000000")),
            "{w:?}"
        );
    }

    // Audit s30 M-4: the set-point 50 above y0 = 0, the output held at 0 while u = −255 (the other way)
    // throughout: the loop's sign is named, not friction; with u = +3 (too small) friction is.
    #[test]
    fn a_step_held_by_a_command_the_wrong_way_names_the_loops_sign() {
        let run = |u: f64| {
            let tr = trace(vec![0.0; 101], vec![u; 101], 50.0);
            let steps = metrics_for_steps(&tr).unwrap();
            loop_warnings(
                &tr,
                &steps,
                &LoopFacts {
                    u_max: 255.0,
                    ..LoopFacts::default()
                },
            )
        };
        let w = run(-255.0);
        assert!(
            w.iter().any(|w| w.contains("had no response")
                && w.contains("pushed the other way for 101 of its 101 samples")
                && w.contains("the loop's sign is wrong")),
            "{w:?}"
        );
        let w = run(3.0);
        assert!(
            w.iter()
                .any(|w| w.contains("had no response") && w.contains("friction holds")),
            "{w:?}"
        );
    }

    // A model estimated on y in [80, 120]: a start at 0 is 80 below it, beyond a tenth of its span (4),
    // warned with the setting to move it; a start at 78 (2 below) is not.
    #[test]
    fn a_start_outside_a_model_plants_data_is_warned() {
        let facts = LoopFacts {
            u_max: 255.0,
            data_y_range: Some((80.0, 120.0)),
            start_setting: Some("--y0"),
            units: Units::MODEL,
            ..LoopFacts::default()
        };
        let run = |y0: f64| {
            let mut y = vec![100.0; 101];
            y[0] = y0;
            let tr = trace(y, vec![0.0; 101], 100.0);
            let steps = metrics_for_steps(&tr).unwrap();
            loop_warnings(&tr, &steps, &facts)
        };
        let w = run(0.0);
        assert!(
            w.iter()
                .any(|w| w.contains("the run starts at y0 = 0 (y's units)")
                    && w.contains("y in [80, 120]")
                    && w.contains("--y0")),
            "{w:?}"
        );
        assert!(!run(78.0).iter().any(|w| w.contains("the run starts")));
    }

    // 1000 of 1001 samples at −255: 99.9 % saturated; r = 300 mm beyond a 200 mm stroke.
    #[test]
    fn saturation_and_an_unreachable_set_point_are_warned() {
        let mut u = vec![-255.0; 1001];
        u[0] = 3.0;
        let tr = trace(vec![0.0; 1001], u, 300.0);
        let steps = metrics_for_steps(&tr).unwrap();
        let w = loop_warnings(
            &tr,
            &steps,
            &LoopFacts {
                u_max: 255.0,
                range_mm: Some((0.0, 200.0)),
                // A(z) = z − 1.02: one pole at 1.02.
                plant_stability: Some(sysid_core::Stability::of_poles(
                    &sysid_core::model::poles_of(&[-1.02]),
                )),
                judge_steps: true,
                data_u_range: None,
                data_y_range: None,
                duration_setting: Some("--duration"),
                start_setting: Some("--y0"),
                units: Units::IPA,
            },
        );
        assert!(w.iter().any(|w| w.contains("99.9 %")), "{w:?}");
        assert!(w.iter().any(|w| w.contains("outside the reachable range")));
        assert!(w.iter().any(|w| w.contains("unstable")));
    }

    // The same run on a model plant: every warning names the record's units, none the IPA's.
    #[test]
    fn a_model_plants_warnings_name_its_units_not_the_ipas() {
        let mut u = vec![-255.0; 1001];
        u[0] = 3.0;
        let mut y = vec![0.0; 1001];
        y[1000] = 2e6; // diverged
        let tr = trace(y, u, 300.0);
        let steps = metrics_for_steps(&tr).unwrap();
        let w = loop_warnings(
            &tr,
            &steps,
            &LoopFacts {
                u_max: 255.0,
                range_mm: Some((0.0, 200.0)),
                judge_steps: true,
                units: Units::MODEL,
                ..LoopFacts::default()
            },
        );
        assert!(w.len() >= 4, "{w:?}");
        assert!(w.iter().any(|w| w.contains("±255 (u's units)")), "{w:?}");
        assert!(w.iter().any(|w| w.contains("r = 300 (y's units)")), "{w:?}");
        for m in &w {
            assert!(!m.contains(" mm") && !m.contains("counts"), "{m}");
        }
    }

    #[test]
    fn the_plant_check_words_an_on_circle_or_unstable_model_and_not_an_integrator() {
        let verdict = |a: &[f64]| Stability::of_poles(&sysid_core::model::poles_of(a));
        // A(z) = z² − 2 cos(w) z + 1 has its poles e^{±iw}: with w = 2π · 0.1, an undamped
        // oscillation at a tenth of the sampling frequency.
        let w = std::f64::consts::TAU * 0.1;
        let on = plant_stability_warning(verdict(&[-2.0 * w.cos(), 1.0])).unwrap();
        assert!(on.contains("on the unit circle away from z = 1"), "{on}");
        assert!(on.contains("at 0.1000 of the sampling frequency"), "{on}");
        // A(z) = z − 1.02: unstable, with its modulus.
        let un = plant_stability_warning(verdict(&[-1.02])).unwrap();
        assert!(un.contains("unstable (a pole has modulus 1.020000"), "{un}");
        // A(z) = (z − 1)(z − 0.5) = z² − 1.5 z + 0.5: an integrator, a position actuator's own
        // dynamics; A(z) = z − 0.5 settles.
        assert_eq!(plant_stability_warning(verdict(&[-1.5, 0.5])), None);
        assert_eq!(plant_stability_warning(verdict(&[-0.5])), None);
    }
}
