//! [`Ipa`]: the physics simulator of the Intelligent Pneumatic Actuator behind the [`sysid_core::Plant`] trait.
//!
//! Each sampling period Ts the command u (counts, clamped to [-255, 255]) is latched by the PWM at the
//! start of every PWM period: u > 0 energises the cap-side valve for |u|/255 of the period, u < 0 the
//! rod-side valve. The valves switch after their opening/closing delays; between switching instants the
//! state is integrated by the adaptive Dormand–Prince 5(4) pair ([`Integrator::DormandPrince`], local
//! error tolerance `integration.tolerance`), or by the reference integrator, classical RK4 with substeps
//! no longer than `integration.max_substep_ms` ([`Integrator::Rk4`]). Sticking, breakaway and end-stop
//! contact are located events (Illinois root finding on the Dormand–Prince dense output, or on the RK4
//! step length), so the trajectory converges at the integrator's order.

use crate::config::PlantConfig;
use crate::dynamics::{Dense, Dopri5Step, Dynamics, Mode, State, Valves};
use crate::encoder::Encoder;
use crate::valve::Valve;
use crate::{IpaError, IpaSetting};

/// Largest PWM command magnitude (counts): duty = |u| / U_MAX.
pub const U_MAX: f64 = 255.0;

/// Upper bound on located events within one sampling period (guards against chattering).
const MAX_EVENTS_PER_SAMPLE: usize = 10_000;

/// A step is stretched to the end of the interval when that is at most this times the proposed step.
const STRETCH: f64 = 1.1;

/// Largest factor by which a rejected step is shortened; with [`STRETCH`] below its inverse, a step
/// rejected at the end of an interval is retried strictly shorter (no endless retry of the same step).
const MAX_SHRINK: f64 = 0.9;
const _: () = assert!(STRETCH * MAX_SHRINK < 1.0);

/// Velocity scale of the step-size control at rest, m/s; it grows as 1 + |v| / v_s with the speed
/// (relative control of the velocity error outside the Stribeck region, absolute inside it, where the
/// negative friction slope amplifies errors).
const VELOCITY_SCALE_M_S: f64 = 1.0;

/// Pressure scale of the step-size control, as a fraction of the supply pressure. The breakaway time
/// is set by the pressure force crossing F_s, so pressure errors shift the motion after every
/// breakaway: 0.2 (rather than 1) cut the largest position error over 2000 s of the default staircase
/// from 8e-4 to 1e-4 mm for 10 % more derivative evaluations.
const PRESSURE_SCALE: f64 = 0.2;

/// The numerical integrator of the plant's continuous state between valve switching instants.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Integrator {
    /// Adaptive Dormand–Prince 5(4) with local error control (`integration.tolerance`), FSAL and
    /// events located on its dense output: the production integrator.
    #[default]
    DormandPrince,
    /// Classical RK4 with fixed substeps (`integration.max_substep_ms`, `slow_substep_ms`): the
    /// integrator used before, kept as the reference for accuracy tests and benchmarks.
    Rk4,
}

/// The PWM period currently running: its start (s), which valve it drives (+1 cap, -1 rod, 0 none) and
/// the duty in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq)]
struct PwmPeriod {
    start_s: f64,
    side: i8,
    duty: f64,
}

/// The physics IPA plant.
///
/// ```
/// use sysid_core::Plant;
/// let mut ipa = ipa::Ipa::new(ipa::PlantConfig::default()).unwrap();
/// ipa.reset(100.0);
/// for _ in 0..30 {
///     ipa.step(255.0).unwrap();
/// }
/// assert!(ipa.output() > 105.0); // full command extends the piston
/// ```
#[derive(Debug, Clone)]
pub struct Ipa {
    config: PlantConfig,
    dynamics: Dynamics,
    encoder: Encoder,
    ts_s: f64,
    pwm_period_s: f64,
    max_substep_s: f64,
    slow_substep_s: f64,
    slow_speed_m_s: f64,
    integrator: Integrator,
    /// 1 / (tolerance * scale) for x, v (at rest) and the pressures: weights of the local error norm.
    err_weight: [f64; 3],
    /// 1 / v_s: the velocity scale grows as 1 + |v| / v_s, s/m.
    inv_stribeck_m_s: f64,
    /// Proposed length of the next Dormand–Prince step for each valve state (index 2 cap + rod), s:
    /// the dynamics change abruptly when a valve switches, and the step that suited the same valve
    /// state in the previous PWM period is a better guess than the one of the last segment.
    h_next_s: [f64; 4],
    /// Proposed length of the first step after a valve switches to each valve state, s: the chamber
    /// that has just been connected changes fastest then, and the first step that suited the same
    /// switch in the previous PWM period is the best guess.
    h_first_s: [f64; 4],
    /// The derivative at the current state, with the valve states and mode it was computed for (FSAL).
    fsal: Option<(Valves, Mode, State)>,
    state: State,
    mode: Mode,
    valve_cap: Valve,
    valve_rod: Valve,
    pwm: Option<PwmPeriod>,
    sample: u64,
    // Scratch buffers (kept to avoid allocation per sample).
    cmd_cap: Vec<(f64, bool)>,
    cmd_rod: Vec<(f64, bool)>,
    switches: Vec<(f64, bool, bool)>,
    sw_tmp: Vec<(f64, bool)>,
    events: u64,
    stats: IntegrationStats,
}

/// Work done by the integrator since the last reset (for benchmarks and the documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct IntegrationStats {
    /// Accepted steps (Dormand–Prince) or substeps (RK4), event-location trials not included.
    pub steps: u64,
    /// Rejected Dormand–Prince steps (error estimate above the tolerance); 0 for RK4.
    pub rejected_steps: u64,
    /// Evaluations of the right-hand side ds/dt, event location included.
    pub derivative_evaluations: u64,
}

/// An event function as a linear function w . s + c of the state: weights w for (x, v, p_a, p_b)
/// and the constant c.
type EventLine = ([f64; 4], f64);

/// What ended an RK4 step early.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Event {
    /// Velocity reached zero while sliding.
    Stop,
    /// Position reached an end stop (0 or L).
    EndStop,
    /// The driving force exceeded the breakaway force while stuck.
    Breakaway,
}

impl Ipa {
    /// The plant with configuration `config` and the default sampling period (10 ms), at rest at
    /// mid-stroke with both chambers at atmospheric pressure.
    pub fn new(config: PlantConfig) -> Result<Self, IpaError> {
        Self::with_ts(config, crate::DEFAULT_TS_S)
    }

    /// The plant with sampling period `ts_s` (s).
    pub fn with_ts(config: PlantConfig, ts_s: f64) -> Result<Self, IpaError> {
        config.validate()?;
        // The floor is the one of every Ts (`sysid_core::data::check_ts`: a model file's, the
        // controller's): `simulate --ts 1e-9` ran and wrote a record no model could be saved from.
        let min = sysid_core::model::MIN_TS_S;
        if !(ts_s.is_finite() && (min..=10.0).contains(&ts_s)) {
            return Err(IpaError::setting(
                IpaSetting::Ts,
                ts_s,
                format!(
                    "expected a sampling period in [{min:e}, 10] s ({min:e} s: the shortest a model \
                     file and the controller take)"
                ),
            ));
        }
        let dynamics = Dynamics::new(&config);
        let v = &config.valve;
        let mut ipa = Ipa {
            encoder: Encoder::new(config.encoder.resolution_mm),
            ts_s,
            pwm_period_s: v.pwm_period_ms * 1e-3,
            max_substep_s: config.integration.max_substep_ms * 1e-3,
            slow_substep_s: config.integration.slow_substep_ms * 1e-3,
            slow_speed_m_s: config.integration.slow_speed_mm_s * 1e-3,
            integrator: Integrator::DormandPrince,
            err_weight: {
                let tol = config.integration.tolerance;
                [
                    1.0 / (tol * dynamics.cylinder.stroke_m),
                    1.0 / (tol * VELOCITY_SCALE_M_S),
                    1.0 / (tol * PRESSURE_SCALE * dynamics.supply_pa),
                ]
            },
            inv_stribeck_m_s: 1.0 / (config.friction.stribeck_velocity_mm_s * 1e-3),
            h_next_s: [0.0; 4],
            h_first_s: [0.0; 4],
            fsal: None,
            state: State {
                x_m: 0.0,
                v_m_s: 0.0,
                p_cap_pa: 0.0,
                p_rod_pa: 0.0,
            },
            mode: Mode::Stuck,
            valve_cap: Valve::new(v.opening_delay_ms * 1e-3, v.closing_delay_ms * 1e-3),
            valve_rod: Valve::new(v.opening_delay_ms * 1e-3, v.closing_delay_ms * 1e-3),
            pwm: None,
            sample: 0,
            cmd_cap: Vec::new(),
            cmd_rod: Vec::new(),
            switches: Vec::new(),
            sw_tmp: Vec::new(),
            events: 0,
            stats: IntegrationStats::default(),
            dynamics,
            config,
        };
        let mid = 0.5 * ipa.config.cylinder.stroke_mm;
        sysid_core::Plant::reset(&mut ipa, mid);
        Ok(ipa)
    }

    /// The configuration.
    pub fn config(&self) -> &PlantConfig {
        &self.config
    }

    /// The model's constant parts (areas, flow path, friction...), for analyses and tests.
    pub fn dynamics(&self) -> &Dynamics {
        &self.dynamics
    }

    /// True piston position (not quantised), mm.
    pub fn position_mm(&self) -> f64 {
        self.state.x_m * 1e3
    }

    /// Piston velocity, mm/s.
    pub fn velocity_mm_s(&self) -> f64 {
        self.state.v_m_s * 1e3
    }

    /// Absolute chamber pressures [p_a (cap side), p_b (rod side)], Pa.
    pub fn pressures_pa(&self) -> [f64; 2] {
        [self.state.p_cap_pa, self.state.p_rod_pa]
    }

    /// The full continuous state.
    pub fn state(&self) -> State {
        self.state
    }

    /// Time since the last reset, s.
    pub fn time_s(&self) -> f64 {
        self.sample as f64 * self.ts_s
    }

    /// True when the piston is at rest (stuck by friction or held at an end stop).
    pub fn is_stuck(&self) -> bool {
        self.mode == Mode::Stuck
    }

    /// The integrator in use ([`Integrator::DormandPrince`] unless changed by [`Ipa::set_integrator`]).
    pub fn integrator(&self) -> Integrator {
        self.integrator
    }

    /// Chooses the integrator (for reference runs; the state is kept).
    pub fn set_integrator(&mut self, integrator: Integrator) {
        self.integrator = integrator;
        self.fsal = None;
    }

    /// Steps, rejected steps and right-hand-side evaluations since the last reset.
    pub fn integration_stats(&self) -> IntegrationStats {
        self.stats
    }

    /// Number of located events (stops, breakaways, end-stop contacts) since the last reset.
    pub fn event_count(&self) -> u64 {
        self.events
    }

    /// Puts the piston at rest at `x_mm` (clamped to the stroke) with chamber pressures `p_cap_pa`,
    /// `p_rod_pa` (absolute), valves de-energised; for tests and special experiments.
    pub fn set_state(&mut self, x_mm: f64, p_cap_pa: f64, p_rod_pa: f64) {
        let stroke = self.dynamics.cylinder.stroke_m;
        let x = if x_mm.is_finite() {
            (x_mm * 1e-3).clamp(0.0, stroke)
        } else {
            0.5 * stroke
        };
        self.state = State {
            x_m: x,
            v_m_s: 0.0,
            p_cap_pa,
            p_rod_pa,
        };
        self.valve_cap.reset();
        self.valve_rod.reset();
        self.pwm = None;
        self.sample = 0;
        self.events = 0;
        self.stats = IntegrationStats::default();
        self.mode = Mode::Stuck;
        self.h_next_s = [self.initial_step_s(); 4];
        self.h_first_s = [self.initial_step_s(); 4];
        self.fsal = None;
        self.settle();
    }

    /// The first Dormand–Prince step tried after a reset: a tenth of a PWM period (the step control
    /// adapts it within a few steps).
    fn initial_step_s(&self) -> f64 {
        0.1 * self.pwm_period_s.min(self.ts_s)
    }

    /// Applies u for one sampling period (like [`sysid_core::Plant::step`]) with the crate's error type.
    pub fn advance(&mut self, u: f64) -> Result<(), IpaError> {
        if !u.is_finite() {
            return Err(IpaError::Numerical(format!(
                "command u = {u} at t = {} s is not finite",
                self.time_s()
            )));
        }
        let u = u.clamp(-U_MAX, U_MAX);
        let t0 = self.sample as f64 * self.ts_s;
        let t1 = (self.sample + 1) as f64 * self.ts_s;
        self.pwm_commands(u, t0, t1);
        // Valve switching instants within [t0, t1).
        self.switches.clear();
        self.sw_tmp.clear();
        self.valve_cap.advance(&self.cmd_cap, t1, &mut self.sw_tmp);
        self.switches
            .extend(self.sw_tmp.iter().map(|&(t, open)| (t, true, open)));
        self.sw_tmp.clear();
        self.valve_rod.advance(&self.cmd_rod, t1, &mut self.sw_tmp);
        self.switches
            .extend(self.sw_tmp.iter().map(|&(t, open)| (t, false, open)));
        self.switches.sort_by(|a, b| a.0.total_cmp(&b.0));
        // Valve states at t0 = the states before the first switch of each valve.
        let mut valves = Valves {
            cap: self.valve_cap.is_open(),
            rod: self.valve_rod.is_open(),
        };
        for &(_, cap, open) in self.switches.iter().rev() {
            if cap {
                valves.cap = !open;
            } else {
                valves.rod = !open;
            }
        }
        let mut t = t0;
        let mut events = 0usize;
        for i in 0..=self.switches.len() {
            let t_end = if i < self.switches.len() {
                self.switches[i].0.clamp(t0, t1)
            } else {
                t1
            };
            if t_end > t {
                self.integrate(t, t_end, valves, &mut events)?;
                t = t_end;
            }
            if i < self.switches.len() {
                let (_, cap, open) = self.switches[i];
                if cap {
                    valves.cap = open;
                } else {
                    valves.rod = open;
                }
            }
        }
        self.sample += 1;
        Ok(())
    }

    /// Command edges of both valves within [t0, t1) from the PWM.
    fn pwm_commands(&mut self, u: f64, t0: f64, t1: f64) {
        self.cmd_cap.clear();
        self.cmd_rod.clear();
        let tp = self.pwm_period_s;
        let eps = 1e-9 * tp.min(self.ts_s);
        // Off edge of the period already running at t0.
        if let Some(p) = self.pwm {
            let off = p.start_s + p.duty * tp;
            if p.side != 0 && p.duty < 1.0 && off >= t0 - eps && off < t1 - eps {
                let list = if p.side > 0 {
                    &mut self.cmd_cap
                } else {
                    &mut self.cmd_rod
                };
                list.push((off.max(t0), false));
            }
        }
        let duty = u.abs() / U_MAX;
        let side: i8 = if u > 0.0 {
            1
        } else if u < 0.0 {
            -1
        } else {
            0
        };
        let mut n = ((t0 - eps) / tp).ceil();
        loop {
            let start = n * tp;
            if start >= t1 - eps {
                break;
            }
            let start = start.max(t0);
            self.cmd_cap.push((start, side > 0));
            self.cmd_rod.push((start, side < 0));
            if side != 0 && duty < 1.0 {
                let off = start + duty * tp;
                if off < t1 - eps {
                    let list = if side > 0 {
                        &mut self.cmd_cap
                    } else {
                        &mut self.cmd_rod
                    };
                    list.push((off, false));
                }
            }
            self.pwm = Some(PwmPeriod {
                start_s: start,
                side,
                duty,
            });
            n += 1.0;
        }
    }

    /// Integrates over [ta, tb] with the valves fixed, with the chosen integrator.
    fn integrate(
        &mut self,
        ta: f64,
        tb: f64,
        valves: Valves,
        events: &mut usize,
    ) -> Result<(), IpaError> {
        match self.integrator {
            Integrator::DormandPrince => self.integrate_dopri5(ta, tb, valves, events),
            Integrator::Rk4 => self.integrate_rk4(ta, tb, valves, events),
        }
    }

    /// Counts a located event; an error when a sample has too many (chattering).
    fn count_event(&mut self, events: &mut usize, t: f64) -> Result<(), IpaError> {
        *events += 1;
        self.events += 1;
        if *events > MAX_EVENTS_PER_SAMPLE {
            return Err(IpaError::Numerical(format!(
                "more than {MAX_EVENTS_PER_SAMPLE} stick/slip events within one sample at t = {t} s (chattering)"
            )));
        }
        Ok(())
    }

    /// The error for a non-physical state at time `t` (s); `hint` says which setting to change.
    fn non_physical(&self, s: &State, t: f64, hint: &str) -> IpaError {
        IpaError::Numerical(format!(
            "the state became non-physical at t = {t:.6} s (sample {}; x = {} m, v = {} m/s, p_a = {} Pa, p_b = {} Pa); \
             {hint}",
            self.sample, s.x_m, s.v_m_s, s.p_cap_pa, s.p_rod_pa
        ))
    }

    /// Weighted maximum norm of a Dormand–Prince error estimate `e` of a step whose largest speed at
    /// its ends is `v_abs` (m/s): <= 1 means within the tolerance.
    #[inline]
    fn error_norm(&self, e: &State, v_abs: f64) -> f64 {
        let [wx, wv, wp] = self.err_weight;
        let wv = wv / (1.0 + v_abs * self.inv_stribeck_m_s);
        (e.x_m.abs() * wx)
            .max(e.v_m_s.abs() * wv)
            .max(e.p_cap_pa.abs() * wp)
            .max(e.p_rod_pa.abs() * wp)
    }

    /// Integrates over [ta, tb] with the valves fixed by adaptive Dormand–Prince 5(4) steps (local error
    /// control on the weighted maximum norm, FSAL); events are detected on the dense output of every
    /// accepted step and located on it.
    fn integrate_dopri5(
        &mut self,
        ta: f64,
        tb: f64,
        valves: Valves,
        events: &mut usize,
    ) -> Result<(), IpaError> {
        let mut t = ta;
        let iv = 2 * usize::from(valves.cap) + usize::from(valves.rod);
        let tiny = 1e-12 * self.ts_s;
        let h_min = 1e-9 * self.ts_s;
        // Fresh: the valves have just switched (or the plant was reset); the first step uses h_first_s.
        let (mut k1, mut fresh) = match self.fsal {
            Some((v, m, k)) if v == valves && m == self.mode => (k, false),
            _ => {
                self.stats.derivative_evaluations += 1;
                (
                    self.dynamics.derivative(&self.state, self.mode, valves),
                    true,
                )
            }
        };
        while tb - t > tiny {
            let rest = tb - t;
            // Take the rest of the interval when it is at most STRETCH times the proposed step.
            let h_prop = if fresh {
                self.h_first_s[iv]
            } else {
                self.h_next_s[iv]
            };
            let to_end = h_prop * STRETCH >= rest;
            let h = if to_end { rest } else { h_prop };
            let step = self.dynamics.dopri5(&self.state, &k1, self.mode, valves, h);
            self.stats.derivative_evaluations += 6;
            let en = if step.y.is_physical() {
                let v_abs = step.y.v_m_s.abs().max(self.state.v_m_s.abs());
                self.error_norm(&step.err, v_abs)
            } else {
                f64::INFINITY
            };
            if en.is_nan() || en > 1.0 {
                // Rejected (NaN or inf included): shorter step.
                self.stats.rejected_steps += 1;
                let fac = if en.is_finite() {
                    (0.9 * inv_fifth_root(en)).clamp(0.2, MAX_SHRINK)
                } else {
                    0.2
                };
                let h_retry = h * fac;
                if fresh {
                    self.h_first_s[iv] = h_retry;
                } else {
                    self.h_next_s[iv] = h_retry;
                }
                if h_retry < h_min {
                    let hint = format!(
                        "the adaptive step fell below {h_min:e} s; loosen or tighten integration.tolerance"
                    );
                    return Err(self.non_physical(&step.y, t + h, &hint));
                }
                continue;
            }
            // en^(-1/5) > 5.6 for en < 1.9e-4: the clamp applies, no root needed.
            let fac = if en > 1.8e-4 {
                (0.9 * inv_fifth_root(en)).clamp(0.2, 5.0)
            } else {
                5.0
            };
            let proposal = h * fac;
            // A step shortened to end the interval does not shorten the next one.
            let keep = |old: f64| if to_end { proposal.max(old) } else { proposal };
            if fresh {
                self.h_first_s[iv] = keep(self.h_first_s[iv]);
                fresh = false;
            }
            self.h_next_s[iv] = keep(self.h_next_s[iv]);
            self.stats.steps += 1;
            match self.detect_dense(&step) {
                None => {
                    self.state = step.y;
                    k1 = step.end_derivative();
                    t = if to_end { tb } else { t + h };
                }
                Some((ev, theta_dense, s_dense, line)) => {
                    self.count_event(events, t)?;
                    let (theta, s) =
                        self.refine_event(ev, line, &step, k1, valves, theta_dense, s_dense);
                    self.state = s;
                    t += theta * h;
                    self.apply_event(ev);
                    if !self.state.is_physical() {
                        return Err(self.non_physical(
                            &self.state,
                            t,
                            "tighten integration.tolerance",
                        ));
                    }
                    self.stats.derivative_evaluations += 1;
                    k1 = self.dynamics.derivative(&self.state, self.mode, valves);
                }
            }
        }
        self.fsal = Some((valves, self.mode, k1));
        Ok(())
    }

    /// The event functions of the current mode as linear functions w . s + c of the state (at most
    /// two): their maximum is [`Ipa::event_value`] (the breakaway margin is the larger of the two
    /// directions; the direction into an end stop is left out, x being constant while stuck).
    fn event_lines(&self) -> [Option<(Event, EventLine)>; 2] {
        let d = &self.dynamics;
        let stroke = d.cylinder.stroke_m;
        match self.mode {
            Mode::Stuck => {
                // F = A_a p_a - A_b p_b + (F_ext - p_atm (A_a - A_b)).
                let (aa, ab) = (d.cylinder.area_cap_m2, d.cylinder.area_rod_side_m2);
                let f0 = d.external_force_n - d.atmosphere_pa * (aa - ab);
                let fs = d.friction.static_n;
                let up = (self.state.x_m < stroke)
                    .then_some((Event::Breakaway, ([0.0, 0.0, aa, -ab], f0 - fs)));
                let down = (self.state.x_m > 0.0)
                    .then_some((Event::Breakaway, ([0.0, 0.0, -aa, ab], -f0 - fs)));
                [up, down]
            }
            // End stop first: on a tie it wins (the position crossed while still moving).
            Mode::Sliding(dir) => [
                Some(if dir > 0.0 {
                    (Event::EndStop, ([1.0, 0.0, 0.0, 0.0], -stroke))
                } else {
                    (Event::EndStop, ([-1.0, 0.0, 0.0, 0.0], 0.0))
                }),
                Some((Event::Stop, ([0.0, -dir, 0.0, 0.0], 0.0))),
            ],
        }
    }

    /// The first event inside an accepted Dormand–Prince step, located on its dense output: the kind,
    /// the fraction theta of the step and the state just after the crossing.
    ///
    /// Along the step each event function is a quartic polynomial in theta. Its Bernstein
    /// coefficients bound it: when none is positive, no event happens in the step (the usual case,
    /// a few flops). Otherwise the step is halved (de Casteljau) down to 2^-12 of its length to find
    /// the first sub-interval where the polynomial becomes positive, so that even an event that
    /// happens and reverts within one step (a grazing stop or breakaway) is seen; Illinois root
    /// finding on the dense output then locates it.
    fn detect_dense(&self, step: &Dopri5Step) -> Option<(Event, f64, State, EventLine)> {
        let mut first: Option<(Event, f64, f64, EventLine)> = None;
        for (ev, (w, c)) in self.event_lines().into_iter().flatten() {
            let beta = bernstein(&step.quartic(&w, c));
            if beta.iter().all(|&b| b <= 0.0) {
                continue;
            }
            if let Some((lo, hi)) = first_positive(&beta, 0.0, 1.0, 12) {
                if first.is_none_or(|f| hi < f.2) {
                    first = Some((ev, lo, hi, (w, c)));
                }
            }
        }
        let (ev, lo, hi, line) = first?;
        let dense = step.dense();
        let s_hi = dense.at(hi);
        if self.event_value(ev, &s_hi) <= 0.0 {
            // Positive on the polynomial, not on the state (rounding at a grazing contact): no event.
            return None;
        }
        let (theta, s) = self.locate_dense(ev, &dense, lo, hi, s_hi, step.h_s);
        Some((ev, theta, s, line))
    }

    /// Sharpens an event located on the dense output (fraction `theta_dense` of `step`, state
    /// `s_dense`): Newton iterations on the event time with true Dormand–Prince steps from the step's
    /// start (the dense output is one order less accurate than the steps, and an error in the time of
    /// a breakaway shifts all the motion after it), using the derivative at the end of each trial step
    /// (FSAL) for the slope of the event function `line`. Returns the fraction of the step and the
    /// state just after the crossing (event function > 0); the dense result when the iterations do
    /// not give one.
    #[allow(clippy::too_many_arguments)]
    fn refine_event(
        &mut self,
        ev: Event,
        line: EventLine,
        step: &Dopri5Step,
        k1: State,
        valves: Valves,
        theta_dense: f64,
        s_dense: State,
    ) -> (f64, State) {
        let (w, c) = line;
        let dot = |s: &State| w[0] * s.x_m + w[1] * s.v_m_s + w[2] * s.p_cap_pa + w[3] * s.p_rod_pa;
        let h = step.h_s;
        // 1e-10 s in time.
        let tol = 1e-10 / h;
        let mut best: Option<(f64, State)> = None;
        let mut theta = theta_dense;
        for _ in 0..4 {
            if !(theta > 0.0 && theta <= 1.0) {
                break;
            }
            let trial = self
                .dynamics
                .dopri5(&step.y0, &k1, self.mode, valves, theta * h);
            self.stats.derivative_evaluations += 6;
            let g = dot(&trial.y) + c;
            let crossed = g > 0.0 && self.event_value(ev, &trial.y) > 0.0 && trial.y.is_physical();
            if crossed && best.is_none_or(|b| theta < b.0) {
                best = Some((theta, trial.y));
            }
            let slope = dot(&trial.end_derivative()) * h;
            if slope.is_nan() || slope <= 0.0 {
                break;
            }
            let next = theta - g / slope;
            if (next - theta).abs() <= tol {
                if crossed {
                    break;
                }
                // Converged from below: one more step just past the root.
                theta = next + tol;
            } else {
                theta = next;
            }
        }
        best.unwrap_or((theta_dense, s_dense))
    }

    /// Finds theta in (lo, hi] where the event function of `ev` crosses zero on the dense output
    /// (Illinois method, bisection when stuck at a bracket end); `s_hi` is the state at hi (event
    /// function > 0). Returns theta and the state just after the crossing.
    fn locate_dense(
        &self,
        ev: Event,
        dense: &Dense,
        lo: f64,
        hi: f64,
        s_hi: State,
        dense_step_s: f64,
    ) -> (f64, State) {
        let at = |theta: f64| {
            let s = dense.at(theta);
            (self.event_value(ev, &s), s)
        };
        let g_lo = at(lo).0;
        let g_hi = self.event_value(ev, &s_hi);
        // 1e-13 Ts in time, as the RK4 reference.
        let tol = 1e-13 * self.ts_s / dense_step_s;
        illinois(lo, g_lo, hi, g_hi, s_hi, tol, at)
    }

    /// Integrates over [ta, tb] with the valves fixed: equal RK4 substeps no longer than the maximum,
    /// events located within a substep (the reference integrator).
    fn integrate_rk4(
        &mut self,
        ta: f64,
        tb: f64,
        valves: Valves,
        events: &mut usize,
    ) -> Result<(), IpaError> {
        let n = ((tb - ta) / self.max_substep_s).ceil().max(1.0);
        let h_nom = (tb - ta) / n;
        let mut t = ta;
        let tiny = 1e-12 * self.ts_s;
        while tb - t > tiny {
            // Finer substeps through the Stribeck region, whose time scale v_s / a is short.
            let slow = match self.mode {
                Mode::Sliding(_) => self.state.v_m_s.abs() < self.slow_speed_m_s,
                Mode::Stuck => false,
            };
            let h = if slow {
                h_nom.min(self.slow_substep_s)
            } else {
                h_nom
            }
            .min(tb - t);
            let next = self.dynamics.rk4(&self.state, self.mode, valves, h);
            self.stats.steps += 1;
            self.stats.derivative_evaluations += 4;
            match self.detect(&next) {
                None => {
                    self.state = next;
                    t += h;
                }
                Some(ev) => {
                    *events += 1;
                    self.events += 1;
                    if *events > MAX_EVENTS_PER_SAMPLE {
                        return Err(IpaError::Numerical(format!(
                            "more than {MAX_EVENTS_PER_SAMPLE} stick/slip events within one sample at t = {t} s (chattering)"
                        )));
                    }
                    let (theta, s, trials) = self.locate(ev, valves, h);
                    self.stats.derivative_evaluations += 4 * trials;
                    self.state = s;
                    t += theta * h;
                    self.apply_event(ev);
                }
            }
            if !self.state.is_physical() {
                return Err(IpaError::Numerical(format!(
                    "the state became non-physical at t = {t:.6} s (x = {} m, v = {} m/s, p_a = {} Pa, p_b = {} Pa); \
                     reduce integration.max_substep_ms",
                    self.state.x_m, self.state.v_m_s, self.state.p_cap_pa, self.state.p_rod_pa
                )));
            }
        }
        Ok(())
    }

    /// Event function: <= 0 before the event, > 0 after it.
    fn event_value(&self, ev: Event, s: &State) -> f64 {
        match (ev, self.mode) {
            (Event::Stop, Mode::Sliding(dir)) => -dir * s.v_m_s,
            (Event::EndStop, Mode::Sliding(dir)) => {
                if dir > 0.0 {
                    s.x_m - self.dynamics.cylinder.stroke_m
                } else {
                    -s.x_m
                }
            }
            (Event::Breakaway, Mode::Stuck) => self.breakaway_margin_n(s),
            _ => f64::NEG_INFINITY,
        }
    }

    /// The earliest kind of event that happened between the current state and `next`, if any.
    fn detect(&self, next: &State) -> Option<Event> {
        match self.mode {
            Mode::Stuck => {
                (self.event_value(Event::Breakaway, next) > 0.0).then_some(Event::Breakaway)
            }
            Mode::Sliding(_) => {
                let stop = self.event_value(Event::Stop, next) > 0.0;
                let end = self.event_value(Event::EndStop, next) > 0.0;
                match (stop, end) {
                    (false, false) => None,
                    (true, false) => Some(Event::Stop),
                    (false, true) => Some(Event::EndStop),
                    // Both: the end stop is reached first when the position crossed while still moving.
                    (true, true) => Some(Event::EndStop),
                }
            }
        }
    }

    /// Finds theta in (0, 1] where the event function of `ev` crosses zero along an RK4 step of
    /// length theta h (Illinois method, bisection when stuck at a bracket end), and returns it, the
    /// state just after the crossing and the number of RK4 trial steps taken.
    fn locate(&self, ev: Event, valves: Valves, h: f64) -> (f64, State, u64) {
        let trials = std::cell::Cell::new(0u64);
        let at = |theta: f64| {
            trials.set(trials.get() + 1);
            let s = self.dynamics.rk4(&self.state, self.mode, valves, theta * h);
            (self.event_value(ev, &s), s)
        };
        let g_lo = self.event_value(ev, &self.state);
        let (g_hi, s_hi) = at(1.0);
        let (theta, s) = illinois(0.0, g_lo, 1.0, g_hi, s_hi, 1e-13 * self.ts_s / h, at);
        (theta, s, trials.get())
    }

    /// Changes the mode after a located event.
    fn apply_event(&mut self, ev: Event) {
        match ev {
            Event::Stop => {
                self.state.v_m_s = 0.0;
                self.mode = Mode::Stuck;
                self.settle();
            }
            Event::EndStop => {
                let stroke = self.dynamics.cylinder.stroke_m;
                self.state.x_m = if self.state.x_m >= 0.5 * stroke {
                    stroke
                } else {
                    0.0
                };
                self.state.v_m_s = 0.0;
                self.mode = Mode::Stuck;
                self.settle();
            }
            Event::Breakaway => self.settle(),
        }
    }

    /// Largest dir F - F_s over the directions the piston may move in (not into an end stop), N.
    fn breakaway_margin_n(&self, s: &State) -> f64 {
        let f = self.dynamics.drive_force_n(s);
        let fs = self.dynamics.friction.static_n;
        let stroke = self.dynamics.cylinder.stroke_m;
        let up = if s.x_m < stroke {
            f - fs
        } else {
            f64::NEG_INFINITY
        };
        let down = if s.x_m > 0.0 {
            -f - fs
        } else {
            f64::NEG_INFINITY
        };
        up.max(down)
    }

    /// At rest (v = 0): stays stuck unless the driving force breaks away (not into an end stop).
    fn settle(&mut self) {
        let f = self.dynamics.drive_force_n(&self.state);
        self.mode = if self.breakaway_margin_n(&self.state) > 0.0 {
            Mode::Sliding(if f > 0.0 { 1.0 } else { -1.0 })
        } else {
            Mode::Stuck
        };
    }
}

/// Bernstein coefficients on [0, 1] of the quartic with monomial coefficients `m`: the polynomial
/// lies between their minimum and maximum on [0, 1] and equals the first and last at 0 and 1.
#[inline]
fn bernstein(m: &[f64; 5]) -> [f64; 5] {
    [
        m[0],
        m[0] + 0.25 * m[1],
        m[0] + 0.5 * m[1] + m[2] / 6.0,
        m[0] + 0.75 * m[1] + 0.5 * m[2] + 0.25 * m[3],
        m[0] + m[1] + m[2] + m[3] + m[4],
    ]
}

/// The first sub-interval [lo, hi] of [a, b] (a halving of it, at most `depth` deep) where the
/// quartic with Bernstein coefficients `beta` on [a, b] goes from <= 0 at lo to > 0 at hi; None when
/// it stays <= 0 (a positive excursion narrower than the finest halving that is <= 0 at both of its
/// ends is ignored).
fn first_positive(beta: &[f64; 5], a: f64, b: f64, depth: u32) -> Option<(f64, f64)> {
    if beta.iter().all(|&v| v <= 0.0) {
        return None;
    }
    if beta[0] > 0.0 {
        // Positive at the start (only possible at theta = 0: the left halves were <= 0 at their ends).
        return Some((a, a));
    }
    if depth == 0 {
        return (beta[4] > 0.0).then_some((a, b));
    }
    // de Casteljau at the midpoint: the left half's coefficients are the first entries of each
    // level, the right half's the last ones.
    let mut left = [0.0; 5];
    let mut right = [0.0; 5];
    let mut level = *beta;
    for k in 0..5 {
        left[k] = level[0];
        right[4 - k] = level[4 - k];
        for i in 0..4 - k {
            level[i] = 0.5 * (level[i] + level[i + 1]);
        }
    }
    let mid = 0.5 * (a + b);
    first_positive(&left, a, mid, depth - 1).or_else(|| first_positive(&right, mid, b, depth - 1))
}

/// x^(-1/5) for x in about [1e-4, 1e6], to 1e-3 relative (for the step-size factor, which needs no
/// more): a first guess from the exponent bits, then two Newton steps on y^-5 = x.
#[inline]
fn inv_fifth_root(x: f64) -> f64 {
    // bits(y) ~ 1.2 bits(1) - 0.2 bits(x): the logarithm scaled by -1/5, read from the bit pattern.
    let one = 1.0f64.to_bits() as f64;
    let mut y = f64::from_bits((1.2 * one - 0.2 * x.to_bits() as f64) as u64);
    for _ in 0..2 {
        let y2 = y * y;
        y *= (6.0 - x * y2 * y2 * y) * 0.2;
    }
    y
}

/// Illinois root finding of g(theta) on [lo, hi] with g(lo) <= 0 < g(hi) (bisection when the secant
/// falls outside the bracket), until the bracket is at most `tol` wide: theta and the state at the upper
/// end of the final bracket (where g > 0).
fn illinois(
    mut lo: f64,
    mut g_lo: f64,
    mut hi: f64,
    mut g_hi: f64,
    mut s_hi: State,
    tol: f64,
    mut at: impl FnMut(f64) -> (f64, State),
) -> (f64, State) {
    let mut side = 0i8;
    for _ in 0..60 {
        if hi - lo <= tol {
            break;
        }
        let theta = if g_lo < 0.0 && g_hi > 0.0 {
            let th = (lo * g_hi - hi * g_lo) / (g_hi - g_lo);
            if th > lo && th < hi {
                th
            } else {
                0.5 * (lo + hi)
            }
        } else {
            0.5 * (lo + hi)
        };
        let (g, s) = at(theta);
        if g > 0.0 {
            hi = theta;
            g_hi = g;
            s_hi = s;
            if side == 1 {
                g_lo *= 0.5;
            }
            side = 1;
        } else {
            lo = theta;
            g_lo = g;
            if side == -1 {
                g_hi *= 0.5;
            }
            side = -1;
        }
    }
    (hi, s_hi)
}

impl sysid_core::Plant for Ipa {
    fn ts(&self) -> f64 {
        self.ts_s
    }

    /// The encoder reading: the position rounded to the encoder resolution, mm.
    fn output(&self) -> f64 {
        self.encoder.read_mm(self.state.x_m * 1e3)
    }

    fn step(&mut self, u: f64) -> Result<f64, sysid_core::PlantError> {
        self.advance(u)
            .map_err(|e| sysid_core::PlantError::Diverged(format!("physics IPA: {e}")))?;
        Ok(self.output())
    }

    /// At rest at `y0_mm` (clamped to [0, L]) with both chambers exhausted to atmospheric pressure: the
    /// equilibrium of the de-energised valves (p_a A_a - p_b A_b - p_atm (A_a - A_b) = 0).
    fn reset(&mut self, y0_mm: f64) {
        let p = self.dynamics.atmosphere_pa;
        self.set_state(y0_mm, p, p);
    }

    fn name(&self) -> String {
        "physics IPA".into()
    }
}
