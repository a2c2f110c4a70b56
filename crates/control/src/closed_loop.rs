//! The closed loop: PI controller (and optional deadzone compensator) around any [`Plant`].
//!
//! Timing (the plant's convention, [`sysid_core::plant`]): at sample k, t_k = k Ts, the position y(k) is read,
//! the set-point r(k) = r(t_k) taken from the profile, the command u(k) computed and applied for one Ts.
//! The trace records (t_k, r(k), u(k), y(k)) for k = 0..N-1 with N = floor(duration / Ts) + 1, so that
//! the last sample is at t = duration (to within one Ts).

use serde::Serialize;
use sysid_core::{Plant, PlantError};

use crate::{ControlError, ControlSetting, DeadzoneCompensator, PiController, Profile};

/// A sampled position controller: from the set-point r(k) and the measured position y(k) (mm) it gives
/// the command u(k) (counts) once per sampling period. The paper's PI ([`PiController`]) and the tuned
/// controller ([`crate::PositionController`]) both run in the one loop [`run`] / [`run_with`].
pub trait Controller {
    /// Ts: the sampling period in s it was built for.
    fn ts_s(&self) -> f64;
    /// Back to rest (integral, filter and memory states to 0).
    fn reset(&mut self);
    /// The next move from rest, keeping what the controller learnt on line (the tuned controller's
    /// u_b, τ_c, a(side), τ_b(side)), as on a machine that repeats its moves; a controller that
    /// learns nothing resets.
    fn restart(&mut self) {
        self.reset();
    }
    /// One sample: r(k), y(k) in mm -> u(k) in counts.
    fn step(&mut self, r_mm: f64, y_mm: f64) -> f64;
}

impl Controller for PiController {
    fn ts_s(&self) -> f64 {
        PiController::ts_s(self)
    }
    fn reset(&mut self) {
        PiController::reset(self)
    }
    fn step(&mut self, r_mm: f64, y_mm: f64) -> f64 {
        PiController::step(self, r_mm, y_mm)
    }
}

/// Upper bound on the number of samples of one run (10^7: 27.8 hours at Ts = 0.01 s), so that a typo in a
/// duration cannot exhaust memory: the trace holds 32 bytes per sample and a written run more (10^8
/// samples needed over 5 GB and aborted on a failed allocation under a 6 GB limit; audit s13 M8).
pub const MAX_SAMPLES: usize = 10_000_000;

/// The number of samples of a run of `duration_s` (s) at `ts` (s): k = 0, 1, … while k·Ts ≤ duration (a
/// duration within 1e-9 of a whole number of periods counts that period); `None` when the run would take
/// [`MAX_SAMPLES`] steps or more, or the quotient is not a number. The one rule of [`run`] and of a
/// profile's own length ([`crate::profile::Profile::natural_duration_checked`]).
pub fn run_samples(duration_s: f64, ts: f64) -> Option<usize> {
    let steps = (duration_s / ts + 1e-9).floor();
    // NaN fails the first comparison.
    (steps >= 0.0 && steps < MAX_SAMPLES as f64).then(|| steps as usize + 1)
}

/// A recorded closed-loop run: one entry per sample k.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Trace {
    /// t_k = k Ts in s.
    pub t: Vec<f64>,
    /// r(k): set-point in mm.
    pub r: Vec<f64>,
    /// u(k): command applied to the plant in counts (after saturation and compensation).
    pub u: Vec<f64>,
    /// y(k): measured position in mm, read before u(k) is applied.
    pub y: Vec<f64>,
}

impl Trace {
    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// True when there is no sample.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Column names of the trace as a table: `t,r,u,y` (the order of [`Trace::columns`]).
    pub const COLUMNS: [&'static str; 4] = ["t", "r", "u", "y"];

    /// The columns t, r, u, y (s, mm, counts, mm), for writing the trace as a table.
    pub fn columns(&self) -> [&[f64]; 4] {
        [&self.t, &self.r, &self.u, &self.y]
    }
}

/// Runs the loop for `duration_s` seconds from rest at `y0_mm`: resets the plant (to `y0_mm`) and the
/// controller, then at each sample reads y(k), computes u(k) = PI(r(k), y(k)), passes it through the
/// compensator if any, records and applies it.
///
/// The controller must have been built for the plant's sampling period (checked). Fails with
/// [`ControlError::Numerical`] (naming the sample) if the plant's output becomes NaN or infinite or the
/// plant reports a numerical failure.
///
/// ```
/// use control::{closed_loop, PiSettings, Profile};
/// let mut plant = sysid_core::ModelPlant::new(sysid_core::Model::paper(), "paper").unwrap();
/// let mut pi = PiSettings::paper().build(0.01).unwrap();
/// let trace = closed_loop::run(&mut plant, &mut pi, None, &Profile::Fixed { setpoint_mm: 50.0 }, 2.0, 0.0).unwrap();
/// assert_eq!(trace.len(), 201);
/// assert!((trace.y[200] - 50.0).abs() < 1.0);
/// ```
pub fn run(
    plant: &mut dyn Plant,
    controller: &mut dyn Controller,
    compensator: Option<&DeadzoneCompensator>,
    profile: &Profile,
    duration_s: f64,
    y0_mm: f64,
) -> Result<Trace, ControlError> {
    run_with(
        plant,
        controller,
        profile,
        duration_s,
        y0_mm,
        &mut |_, u, _| Ok(compensator.map_or(u, |c| c.apply(u))),
    )
}

/// [`run`] with the command applied at sample k given by `command(k, u_pi, y)` from the PI output u_pi
/// and the measured y(k) (a compensator, possibly one that adapts; see [`crate::adaptive`]).
pub fn run_with(
    plant: &mut dyn Plant,
    controller: &mut dyn Controller,
    profile: &Profile,
    duration_s: f64,
    y0_mm: f64,
    command: &mut dyn FnMut(usize, f64, f64) -> Result<f64, ControlError>,
) -> Result<Trace, ControlError> {
    let ts = plant.ts();
    if !(ts.is_finite() && ts > 0.0) {
        return Err(ControlError::Config(format!(
            "plant {} has an invalid sampling period Ts = {} s",
            plant.name(),
            sysid_core::format::Shortest(ts)
        )));
    }
    if (controller.ts_s() - ts).abs() > 1e-12 * ts {
        return Err(ControlError::Config(format!(
            "the controller was built for Ts = {} s but plant {} samples at Ts = {} s",
            sysid_core::format::Shortest(controller.ts_s()),
            plant.name(),
            sysid_core::format::Shortest(ts)
        )));
    }
    profile.check_sampling(ts)?;
    if !(duration_s.is_finite() && duration_s >= 0.0) {
        return Err(ControlError::setting(
            ControlSetting::Duration,
            duration_s,
            "a finite number of seconds >= 0",
        ));
    }
    if !y0_mm.is_finite() {
        return Err(ControlError::setting(
            ControlSetting::Y0,
            y0_mm,
            "a finite position in mm",
        ));
    }
    profile.validate()?;
    let n = run_samples(duration_s, ts).ok_or_else(|| {
        ControlError::setting(
            ControlSetting::Duration,
            duration_s,
            &format!("at most {} samples of Ts = {ts} s", MAX_SAMPLES),
        )
    })?;

    plant.reset(y0_mm);
    controller.reset();
    let mut trace = Trace {
        t: Vec::with_capacity(n),
        r: Vec::with_capacity(n),
        u: Vec::with_capacity(n),
        y: Vec::with_capacity(n),
    };
    for k in 0..n {
        let t = k as f64 * ts;
        let y = plant.output();
        if !y.is_finite() {
            return Err(ControlError::Numerical(format!(
                "the output of {} is {y} at sample {k} (t = {t} s)",
                plant.name()
            )));
        }
        let r = profile.r_at(t);
        let u = command(k, controller.step(r, y), y)?;
        if !u.is_finite() {
            return Err(ControlError::Numerical(format!(
                "the command became {u} at sample {k} (t = {t} s)"
            )));
        }
        trace.t.push(t);
        trace.r.push(r);
        trace.u.push(u);
        trace.y.push(y);
        plant.step(u).map_err(|e| match e {
            // The outer error already says "numerical failure"; keep only the plant's own words.
            PlantError::Diverged(m) => {
                ControlError::Numerical(format!("sample {k} (t = {t} s): {m}"))
            }
            PlantError::Cancelled => ControlError::Cancelled,
        })?;
    }
    Ok(trace)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{IntegralForm, PiSettings};
    use sysid_core::{Model, ModelPlant};

    #[test]
    fn a_run_has_one_sample_per_period_up_to_the_bound() {
        // Samples at t = 0, Ts, …, ⌊d/Ts⌋·Ts: by hand.
        assert_eq!(run_samples(1.0, 0.01), Some(101));
        assert_eq!(run_samples(0.0, 0.01), Some(1));
        assert_eq!(run_samples(0.035, 0.01), Some(4));
        // 0.3 / 0.1 is 2.9999999999999996 in f64: within 1e-9 of 3 periods, which count.
        assert_eq!(run_samples(0.3, 0.1), Some(4));
        // 1e7 steps is the bound: 99999.99 s at 0.01 s has 9999999 steps and 1e7 samples; 1e5 s has not.
        assert_eq!(run_samples(99_999.99, 0.01), Some(MAX_SAMPLES));
        assert_eq!(run_samples(100_000.0, 0.01), None);
        assert_eq!(run_samples(f64::INFINITY, 0.01), None);
        assert_eq!(run_samples(f64::NAN, 0.01), None);
    }

    fn paper_plant() -> ModelPlant {
        ModelPlant::new(Model::paper(), "paper").unwrap()
    }

    // A loop on a plant whose stop is requested ends with `Cancelled` (no trace), at its first step;
    // never requested, the wrapped plant gives the bare plant's trace sample for sample.
    #[test]
    fn a_loop_on_a_stoppable_plant_ends_with_cancelled_when_asked() {
        use sysid_core::{plant::Stoppable, Stop};
        let fixed = Profile::Fixed { setpoint_mm: 50.0 };
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        let mut plant = paper_plant();
        let stop = Stop::new();
        stop.request();
        let stopped = run(
            &mut Stoppable::new(&mut plant, &stop),
            &mut pi,
            None,
            &fixed,
            100.0,
            0.0,
        );
        assert!(
            matches!(stopped, Err(ControlError::Cancelled)),
            "{stopped:?}"
        );
        let bare = run(&mut paper_plant(), &mut pi, None, &fixed, 100.0, 0.0).unwrap();
        let wrapped = run(
            &mut Stoppable::new(&mut plant, &Stop::new()),
            &mut pi,
            None,
            &fixed,
            100.0,
            0.0,
        )
        .unwrap();
        assert_eq!(bare, wrapped);
    }

    #[test]
    fn first_samples_match_the_hand_computed_saturated_response() {
        // r = 50 mm from rest: e >= 18.2 mm keeps u = +255 (Kp e > 255), so with x = m_r (255 - b_r):
        // y(1) = x, y(2) = 1.869 y(1) + x, y(3) = 1.869 y(2) - 0.9976 y(1) + x.
        let mut plant = paper_plant();
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        let trace = run(
            &mut plant,
            &mut pi,
            None,
            &Profile::Fixed { setpoint_mm: 50.0 },
            0.03,
            0.0,
        )
        .unwrap();
        let x = 2.38 * 15.67e-4 * (255.0 - 1.41);
        let y1 = x;
        let y2 = 1.869 * y1 + x;
        let y3 = 1.869 * y2 - 0.9976 * y1 + x;
        assert_eq!(trace.t.len(), 4);
        assert_eq!(trace.y[0], 0.0);
        for (k, want) in [(1, y1), (2, y2), (3, y3)] {
            assert!(
                (trace.y[k] - want).abs() < 1e-12,
                "y({k}) = {} != {want}",
                trace.y[k]
            );
        }
        assert!(trace.u.iter().all(|&u| u == 255.0));
        // The same by hand (calculator, 5 digits): x = 0.94575, y(2) = 2.7134, y(3) = 5.0736.
        assert!((trace.y[1] - 0.94575).abs() < 1e-4);
        assert!((trace.y[2] - 2.7134).abs() < 1e-4);
        assert!((trace.y[3] - 5.0736).abs() < 1e-4);
    }

    #[test]
    fn unsaturated_first_samples_distinguish_the_integral_forms() {
        // r = 1 mm from rest: u(0) = Kp e + g e with g = Ki Ts = 0.01 (scaled) or Ki = 1 (per sample);
        // y(1) = m_r (u(0) - b_r); u(1) = Kp e(1) + g (e(0) + e(1)), e(1) = 1 - y(1).
        let m_r = 2.38 * 15.67e-4;
        for (form, g) in [(IntegralForm::Scaled, 0.01), (IntegralForm::PerSample, 1.0)] {
            let mut plant = paper_plant();
            let mut pi = PiSettings::paper().with_integral(form).build(0.01).unwrap();
            let trace = run(
                &mut plant,
                &mut pi,
                None,
                &Profile::Fixed { setpoint_mm: 1.0 },
                0.01,
                0.0,
            )
            .unwrap();
            let u0 = 14.0 + g;
            let y1 = m_r * (u0 - 1.41);
            let e1 = 1.0 - y1;
            let u1 = 14.0 * e1 + g * (1.0 + e1);
            assert!((trace.u[0] - u0).abs() < 1e-12);
            assert!((trace.y[1] - y1).abs() < 1e-12);
            assert!(
                (trace.u[1] - u1).abs() < 1e-12,
                "{form}: {} vs {u1}",
                trace.u[1]
            );
        }
    }

    #[test]
    fn trace_has_one_sample_per_ts_including_the_end() {
        // N = floor(duration / Ts) + 1; t_k = k Ts.
        let mut plant = paper_plant();
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        let trace = run(
            &mut plant,
            &mut pi,
            None,
            &Profile::Fixed { setpoint_mm: 5.0 },
            1.0,
            0.0,
        )
        .unwrap();
        assert_eq!(trace.len(), 101);
        assert!((trace.t[100] - 1.0).abs() < 1e-12);
        let [t, r, u, y] = trace.columns();
        assert_eq!((t.len(), r.len(), u.len(), y.len()), (101, 101, 101, 101));
        assert_eq!((t[0], r[0]), (0.0, 5.0));
    }

    #[test]
    fn loop_starts_at_y0() {
        // Reset at y0 = 30 mm with r = 30 mm: y(0) = 30, e(0) = 0, u(0) = 0.
        let mut plant = paper_plant();
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        let trace = run(
            &mut plant,
            &mut pi,
            None,
            &Profile::Fixed { setpoint_mm: 30.0 },
            0.1,
            30.0,
        )
        .unwrap();
        assert_eq!(trace.y[0], 30.0);
        assert_eq!(trace.u[0], 0.0);
    }

    /// A plant that fails numerically at its third step.
    struct Diverging(usize);
    impl Plant for Diverging {
        fn ts(&self) -> f64 {
            0.01
        }
        fn output(&self) -> f64 {
            0.0
        }
        fn step(&mut self, _u: f64) -> Result<f64, sysid_core::PlantError> {
            self.0 += 1;
            if self.0 == 3 {
                Err(sysid_core::PlantError::Diverged("state blew up".into()))
            } else {
                Ok(0.0)
            }
        }
        fn reset(&mut self, _y0_mm: f64) {
            self.0 = 0;
        }
        fn name(&self) -> String {
            "diverging".into()
        }
    }

    #[test]
    fn plant_numerical_failure_is_reported_with_its_sample() {
        // The third call to step is at sample k = 2.
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        let e = run(
            &mut Diverging(0),
            &mut pi,
            None,
            &Profile::Fixed { setpoint_mm: 1.0 },
            1.0,
            0.0,
        )
        .unwrap_err();
        assert!(e.is_numerical());
        assert!(e.to_string().contains("sample 2"), "{e}");
    }

    #[test]
    fn mismatched_sampling_period_and_bad_duration_are_rejected() {
        // Controller built for Ts = 0.02 on a Ts = 0.01 plant; negative or NaN duration.
        let mut plant = paper_plant();
        let p = Profile::Fixed { setpoint_mm: 1.0 };
        let mut pi = PiSettings::paper().build(0.02).unwrap();
        assert!(run(&mut plant, &mut pi, None, &p, 1.0, 0.0).is_err());
        let mut pi = PiSettings::paper().build(0.01).unwrap();
        for d in [-1.0, f64::NAN, 1e12] {
            let e = run(&mut plant, &mut pi, None, &p, d, 0.0).unwrap_err();
            assert!(
                matches!(
                    e,
                    ControlError::Setting {
                        setting: ControlSetting::Duration,
                        ..
                    }
                ),
                "{e}"
            );
        }
    }
}
