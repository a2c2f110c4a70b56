//! [`Ipa`]: the physics simulator of the Intelligent Pneumatic Actuator behind the [`sysid_core::Plant`] trait.
//!
//! Each sampling period Ts the command u (counts, clamped to [-255, 255]) is latched by the PWM at the
//! start of every PWM period: u > 0 energises the cap-side valve for |u|/255 of the period, u < 0 the
//! rod-side valve. The valves switch after their opening/closing delays; between switching instants the
//! state is integrated by classical RK4 with substeps no longer than `integration.max_substep_ms`.
//! Sticking, breakaway and end-stop contact are located events (Illinois root finding on the RK4 step
//! length), so the trajectory converges at the integrator's order.

use crate::config::PlantConfig;
use crate::dynamics::{Dynamics, Mode, State, Valves};
use crate::encoder::Encoder;
use crate::valve::Valve;
use crate::{IpaError, IpaSetting};

/// Largest PWM command magnitude (counts): duty = |u| / U_MAX.
pub const U_MAX: f64 = 255.0;

/// Upper bound on located events within one sampling period (guards against chattering).
const MAX_EVENTS_PER_SAMPLE: usize = 10_000;

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
}

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
        if !(ts_s.is_finite() && ts_s > 0.0 && ts_s <= 10.0) {
            return Err(IpaError::setting(
                IpaSetting::Ts,
                ts_s,
                "expected a sampling period in (0, 10] s",
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
        self.mode = Mode::Stuck;
        self.settle();
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

    /// Integrates over [ta, tb] with the valves fixed: equal RK4 substeps no longer than the maximum,
    /// events located within a substep.
    fn integrate(
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
                    let (theta, s) = self.locate(ev, valves, h);
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
    /// length theta h (Illinois method, bisection when stuck at a bracket end), and returns the state
    /// just after the crossing.
    fn locate(&self, ev: Event, valves: Valves, h: f64) -> (f64, State) {
        let at = |theta: f64| {
            let s = self.dynamics.rk4(&self.state, self.mode, valves, theta * h);
            (self.event_value(ev, &s), s)
        };
        let (mut lo, mut g_lo) = (0.0, self.event_value(ev, &self.state));
        let (mut hi, (mut g_hi, mut s_hi)) = (1.0, at(1.0));
        let tol = 1e-13 * self.ts_s / h;
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
