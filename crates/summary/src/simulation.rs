//! What `simulate` says of an open-loop record it made, in words: one list for the command line's
//! `warning:` lines and the Python package's `simulate_plant` (its `IpaSysidWarning`s), so that the two
//! cannot drift apart (audit s18 M-2: `simulate_plant("model:FILE")` extrapolated without a word where
//! `simulate --plant model:FILE` gave three warnings).

use std::path::Path;

use sysid_core::{DataRange, Model};

/// What the warnings of an open-loop run are computed from: the plant (a model file's model or NARX
/// data range; the physics plant's or the paper model's stroke), how the run started and how its
/// command file was timed.
#[derive(Debug, Clone, Copy, Default)]
pub struct OpenLoopRun<'a> {
    /// The linear model of a `model:FILE` plant, if that is the plant.
    pub model: Option<&'a Model>,
    /// The estimation data range of a NARX `model:FILE` plant, if that is the plant.
    pub narx_range: Option<&'a DataRange>,
    /// The physics plant (`ipa`): its output should move when the commands leave the valves' deadzone.
    pub physics: bool,
    /// What holds a physics plant's piston (its deadzone, static friction and the forces the run's
    /// commands can give: [`PhysicsHold`]); `None`: the words of a flat record name the deadzone only.
    pub hold: Option<PhysicsHold>,
    /// The stroke 0..L (mm) of the paper's model (`paper`), which has no end stops of its own.
    pub paper_stroke_mm: Option<f64>,
    /// y0: the level held before the start.
    pub y0: f64,
    /// y0 was the plant's default (no `--y0` / `x0`).
    pub y0_default: bool,
    /// The command file (`--input file:CSV`) and the step of its time column t, s, if it has one.
    pub input_file: Option<(&'a Path, Option<f64>)>,
    /// `--ts` (Python `ts=`), if given.
    pub ts_setting: Option<f64>,
}

/// What can hold the physics plant's piston still through a run, computed by the caller from the plant's
/// configuration (`ipa::PlantConfig::valve_deadzone_counts`, `held_drive_force_n`) and the run's commands.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhysicsHold {
    /// The valves' deadzone, counts: a command within ± it never opens a valve.
    pub deadzone_counts: f64,
    /// F_s: the static friction, N (`friction.static_n`).
    pub static_friction_n: f64,
    /// The largest net force the run's commands build up on a held piston extending (N, ≥ 0; 0 when
    /// no command extends).
    pub extend_n: f64,
    /// The same retracting (N, ≥ 0).
    pub retract_n: f64,
    /// The stroke L, mm (the end stops at 0 and L).
    pub stroke_mm: f64,
}

impl PhysicsHold {
    /// For a physics run that never moved (every y(k) equal): what can hold its piston, from the
    /// plant's configuration `cfg` and the run's commands `u` with the piston at `y0` (mm); `None` for a
    /// run that moved (the one the no-motion warning explains: `record_warnings`). `simulate` and
    /// Python's `simulate_plant` alike.
    pub fn of_run(cfg: &ipa::PlantConfig, u: &[f64], y: &[f64], y0: f64) -> Option<PhysicsHold> {
        if !y.windows(2).all(|w| w[0] == w[1]) {
            return None;
        }
        let (extend_n, retract_n) = cfg.largest_held_forces_n(u, y0);
        Some(PhysicsHold {
            deadzone_counts: cfg.valve_deadzone_counts(),
            static_friction_n: cfg.friction.static_n,
            extend_n,
            retract_n,
            stroke_mm: cfg.cylinder.stroke_mm,
        })
    }
}

/// What a model file's model says before it is simulated: its file's doubts
/// ([`sysid_core::model_file::load_warnings`], what `validate` says) and [`stability_words`].
pub fn model_file_warnings(model: &Model) -> Vec<String> {
    let mut w = sysid_core::model_file::load_warnings(model);
    w.extend(stability_words(model));
    w
}

/// What a model's poles mean for its simulation, when it does not simply settle: the words of its
/// stability verdict ([`Model::stability`], the one every command reports): unstable (a pole beyond
/// the unit circle: it diverges), an integrator (a pole at z = 1: its output ramps under any net
/// input, as an actuator's position does), or a pole elsewhere on the circle (it oscillates without
/// decay).
pub fn stability_words(model: &Model) -> Option<String> {
    use sysid_core::Stability;
    let s = model.stability();
    Some(match s {
        Stability::Settles { .. } => return None,
        Stability::Unstable { .. } if !s.modulus().is_finite() => "unstable model (a pole is not a \
             finite number: the coefficients are beyond f64): its simulation diverges"
            .to_string(),
        Stability::Unstable { .. } => format!(
            "unstable model (a pole has modulus {} > 1): its simulation diverges",
            sysid_core::format::Modulus(s.modulus())
        ),
        Stability::Integrator { .. } => {
            "the model has a pole at 1 (an integrator): its output ramps under any net input, as an \
             actuator's position does, and rests only where the input is at its operating point"
                .to_string()
        }
        Stability::OnCircle { .. } => "the model has a pole on the unit circle away from 1: its \
             simulation oscillates without decaying"
            .to_string(),
    })
}

/// A warning when a model without an operating point (identified with `--offset`, not `--detrend`)
/// starts at its rest for every past command 0 while its estimation data never had u = 0 (audit s11:
/// the dryer's `--offset` model starts at 0.26 against data in 3.2..6.3 and its record opens with a
/// transient larger than the data's span). `None` when the start was chosen (`--y0`) or is inside.
pub fn rest_outside_data(model: &Model, y0: f64, y0_default: bool) -> Option<String> {
    if !y0_default || model.operating_point().is_some() {
        return None;
    }
    let range = model.data_range()?;
    let (i, [lo, hi]) = range
        .u
        .iter()
        .enumerate()
        .find(|(_, [lo, hi])| !(*lo..=*hi).contains(&0.0))?;
    let name = model.inputs().get(i).map_or("u", |c| c.name());
    Some(format!(
        "the model starts at its rest y0 = {y0} for every past command 0, but its estimation data had {name} \
         in [{lo}, {hi}] (no operating point is stored: identified without --detrend mean, with or \
         without --offset), so the record opens with a transient from a state the data never showed \
         (its output was in [{}, {}]); identify with --detrend mean instead, whose model stores the \
         operating point and rests there",
        range.y[0], range.y[1]
    ))
}

/// Advice added to an input-range warning: the designed inputs are the IPA's.
const DESIGNED_INPUTS: &str =
    "; the designed inputs are the IPA's (whole counts within ±--amplitude \
     around 0): give the model an input in its own units with --input file:CSV";

/// The warnings of an open-loop run that made the record `u`, `y` at Ts = `ts` s, in the command line's
/// order: the command file's timing, a model's start and ranges (input, output), a flat physics
/// record, a NARX model's ranges, the paper model beyond the stroke.
pub fn record_warnings(run: &OpenLoopRun, u: &[f64], y: &[f64], ts: f64) -> Vec<String> {
    let mut w = Vec::new();
    if let Some((path, Some(f))) = run.input_file {
        let note = match run.ts_setting {
            // The reader's words for a --ts against a time column (identify, calibrate, track).
            Some(setting) => sysid_core::data::ts_contradiction_note(setting, "t", f)
                .map(|n| format!("{}: {n}", path.display())),
            None => ((f - ts).abs() > 1e-3 * f).then(|| {
                format!(
                    "{}: its time column t steps {} s, but the plant runs at its own Ts = {} s: the \
                     commands are replayed {} times as far apart as recorded",
                    path.display(),
                    sysid_core::format::Shortest(f),
                    sysid_core::format::Shortest(ts),
                    // 6 significant digits: 0.2, not the quotient's 0.19999999999999998 (audit s32 L-8).
                    sysid_core::format::sig(ts / f, 6)
                )
            }),
        };
        w.extend(note);
    }
    if let Some(m) = run.model {
        w.extend(rest_outside_data(m, run.y0, run.y0_default));
        w.extend(crate::input_outside_data(m, u).map(|s| s + DESIGNED_INPUTS));
        w.extend(crate::output_outside_data(m, y));
    }
    if run.physics {
        // A command record that never opens a valve leaves a flat record (audit s17 L-l: a ball and
        // beam's ±0.03 commands replayed in PWM counts), which calibrate warns of.
        let (lo, hi) = DataRange::extremes(y);
        let largest = u.iter().fold(0.0_f64, |m, u| m.max(u.abs()));
        if lo == hi && largest > 0.0 {
            w.push(flat_physics_words(run, largest, y[0]));
        }
    }
    // A NARX model's range, as a linear model's (audit s17 M-d).
    if let Some(range) = run.narx_range {
        w.extend(crate::input_outside_range(range, "u", u).map(|s| s + DESIGNED_INPUTS));
        w.extend(crate::output_outside_range(range, y));
    }
    if let Some(stroke) = run.paper_stroke_mm {
        // The paper's model is linear past its deadzone and has no end stops (audit s16 L3: an APRBS
        // record of it reached −966 mm).
        let (lo, hi) = DataRange::extremes(y);
        if lo < 0.0 || hi > stroke {
            w.push(format!(
                "the simulated output spans [{lo:.2}, {hi:.2}] mm, beyond the IPA's stroke 0..{stroke} \
                 mm: the paper's model has no end stops, so this record holds positions the actuator \
                 cannot take (the physics plant, --plant ipa, stops at its ends)"
            ));
        }
    }
    w
}

/// Why a physics record never moved from y0 = `run.y0` under commands up to ±`largest` counts
/// (`y_first`: its one output value): inside the valves' deadzone (or without [`PhysicsHold`]) the
/// command record's scale is the doubt (audit s17 L-l); beyond it, the static friction that the forces
/// the commands can give do not overcome (audit s23 L-B4: the old words blamed the command's scale), or,
/// when they do exceed it, the run ended before the chamber's pressure built up to them.
fn flat_physics_words(run: &OpenLoopRun, largest: f64, y_first: f64) -> String {
    let scale = format!(
        "the output never moved from y0 = {} mm: the commands stay within ±{} counts, inside \
         the valves' deadzone (the physics plant is a pneumatic IPA driven by PWM counts up to \
         ±255: is this command record of such a plant, in counts?)",
        run.y0,
        fmt4(largest)
    );
    let Some(h) = run.hold else { return scale };
    if largest <= h.deadzone_counts {
        return scale;
    }
    // A direction the piston cannot take from where it is (against its end stop) gives no motion.
    let extend = if y_first < h.stroke_mm {
        h.extend_n
    } else {
        0.0
    };
    let retract = if y_first > 0.0 { h.retract_n } else { 0.0 };
    let forces = format!(
        "the largest force those commands build up on the held piston is {:.1} N extending and {:.1} N \
         retracting (the peak of the periodic pressure of a chamber pulsed at their duty, piston held, from the \
         plant's chamber and valve model, with the external load)",
        h.extend_n, h.retract_n
    );
    let head = format!(
        "the output never moved from y0 = {} mm although the commands reached ±{} counts, beyond the \
         valves' deadzone (±{} counts)",
        run.y0,
        fmt4(largest),
        fmt4(h.deadzone_counts)
    );
    if extend.max(retract) <= h.static_friction_n {
        format!(
            "{head}: static friction holds the piston — friction.static_n = {:.1} N, while {forces}{}; \
             larger commands, or a smaller friction.static_n in the plant config, move it",
            h.static_friction_n,
            if (extend, retract) != (h.extend_n, h.retract_n) {
                " (the other direction pushes into the end stop)"
            } else {
                ""
            }
        )
    } else {
        format!(
            "{head}: {forces}, above the static friction friction.static_n = {:.1} N, but the piston \
             did not break away within the run: the chamber's pressure had not built up (a longer run, \
             or commands held longer, would move it)",
            h.static_friction_n
        )
    }
}

/// A value with 4 decimals, in scientific notation beyond 1e9 in magnitude (`control::trust::fmt_value`).
fn fmt4(v: f64) -> String {
    if v.abs() >= 1e9 {
        format!("{v:.4e}")
    } else {
        format!("{v:.4}")
    }
}
