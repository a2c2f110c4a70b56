//! The equations of motion of the IPA: state, right-hand side and one RK4 step.
//!
//! State s = (x, v, p_a, p_b): piston position x (m, 0 = retracted), velocity v (m/s), cap-side and
//! rod-side absolute pressures (Pa). With both valve states fixed (between switching instants):
//!
//! ```text
//! F   = p_a A_a - p_b A_b - p_atm (A_a - A_b) + F_ext           (net driving force)
//! M dv/dt = F - F_f(v)        while sliding (dx/dt = v)
//! dv/dt = dx/dt = 0           while stuck (|F| <= F_s) or held at an end stop
//! dp_a/dt, dp_b/dt            from the chamber energy equation (see [`crate::cylinder`])
//! ```

use crate::config::PlantConfig;
use crate::cylinder::Cylinder;
use crate::friction::Friction;
use crate::valve::FlowPath;

/// The continuous state of the plant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct State {
    /// x: piston position from the retracted end, m.
    pub x_m: f64,
    /// v: piston velocity, m/s (positive extending).
    pub v_m_s: f64,
    /// p_a: cap-side chamber pressure (absolute), Pa.
    pub p_cap_pa: f64,
    /// p_b: rod-side chamber pressure (absolute), Pa.
    pub p_rod_pa: f64,
}

impl State {
    #[inline]
    fn axpy(&self, h: f64, d: &State) -> State {
        State {
            x_m: self.x_m + h * d.x_m,
            v_m_s: self.v_m_s + h * d.v_m_s,
            p_cap_pa: self.p_cap_pa + h * d.p_cap_pa,
            p_rod_pa: self.p_rod_pa + h * d.p_rod_pa,
        }
    }

    /// True when every component is finite and both pressures are positive.
    pub fn is_physical(&self) -> bool {
        self.x_m.is_finite()
            && self.v_m_s.is_finite()
            && self.p_cap_pa.is_finite()
            && self.p_rod_pa.is_finite()
            && self.p_cap_pa > 0.0
            && self.p_rod_pa > 0.0
    }
}

/// Mechanical mode: stuck (including held at an end stop) or sliding in a direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mode {
    /// v = 0, the friction (or an end stop) holds the piston.
    Stuck,
    /// Sliding in direction +1 (extending) or -1 (retracting); friction opposes that direction.
    Sliding(f64),
}

/// Which chamber each valve connects to the supply (true) or the exhaust (false).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Valves {
    /// Cap-side valve open to supply.
    pub cap: bool,
    /// Rod-side valve open to supply.
    pub rod: bool,
}

/// The constant parts of the model, in SI units.
#[derive(Debug, Clone)]
pub struct Dynamics {
    /// Cylinder geometry and chamber equation.
    pub cylinder: Cylinder,
    /// ISO 6358 flow path supply -> chamber (valve energised).
    pub supply_path: FlowPath,
    /// ISO 6358 flow path chamber -> exhaust (valve de-energised).
    pub exhaust_path: FlowPath,
    /// Seal friction.
    pub friction: Friction,
    /// M: moving mass, kg.
    pub mass_kg: f64,
    /// F_ext: external force, N (+ extends).
    pub external_force_n: f64,
    /// p_s: supply pressure (absolute), Pa.
    pub supply_pa: f64,
    /// p_atm: atmospheric pressure, Pa.
    pub atmosphere_pa: f64,
}

impl Dynamics {
    /// From a validated configuration.
    pub fn new(cfg: &PlantConfig) -> Self {
        Dynamics {
            cylinder: Cylinder::new(cfg),
            supply_path: FlowPath::new(
                cfg.valve.supply_conductance_dm3_s_bar,
                &cfg.valve,
                cfg.air.temperature_k,
            ),
            exhaust_path: FlowPath::new(
                cfg.valve.exhaust_conductance_dm3_s_bar,
                &cfg.valve,
                cfg.air.temperature_k,
            ),
            friction: Friction::new(&cfg.friction),
            mass_kg: cfg.load.moving_mass_kg,
            external_force_n: cfg.load.external_force_n,
            supply_pa: cfg.air.atmosphere_pa + cfg.air.supply_gauge_mpa * 1e6,
            atmosphere_pa: cfg.air.atmosphere_pa,
        }
    }

    /// F: net pneumatic and external force on the piston, N (+ extends).
    #[inline]
    pub fn drive_force_n(&self, s: &State) -> f64 {
        let c = &self.cylinder;
        s.p_cap_pa * c.area_cap_m2
            - s.p_rod_pa * c.area_rod_side_m2
            - self.atmosphere_pa * (c.area_cap_m2 - c.area_rod_side_m2)
            + self.external_force_n
    }

    /// Net mass flow into a chamber at pressure `p_pa` through its valve (kg/s).
    #[inline]
    pub fn chamber_inflow_kg_s(&self, p_pa: f64, open: bool) -> f64 {
        if open {
            self.supply_path.mass_flow_kg_s(self.supply_pa, p_pa)
        } else {
            -self.exhaust_path.mass_flow_kg_s(p_pa, self.atmosphere_pa)
        }
    }

    /// ds/dt in mode `mode` with valves `valves`.
    #[inline]
    pub fn derivative(&self, s: &State, mode: Mode, valves: Valves) -> State {
        let c = &self.cylinder;
        let (v, a) = match mode {
            Mode::Stuck => (0.0, 0.0),
            Mode::Sliding(dir) => {
                let f = self.drive_force_n(s) - self.friction.sliding_n(dir, s.v_m_s);
                (s.v_m_s, f / self.mass_kg)
            }
        };
        let mdot_a = self.chamber_inflow_kg_s(s.p_cap_pa, valves.cap);
        let mdot_b = self.chamber_inflow_kg_s(s.p_rod_pa, valves.rod);
        State {
            x_m: v,
            v_m_s: a,
            p_cap_pa: c.dp_dt(
                s.p_cap_pa,
                c.volume_cap_m3(s.x_m),
                mdot_a,
                c.area_cap_m2 * v,
            ),
            p_rod_pa: c.dp_dt(
                s.p_rod_pa,
                c.volume_rod_m3(s.x_m),
                mdot_b,
                -c.area_rod_side_m2 * v,
            ),
        }
    }

    /// One classical fourth-order Runge-Kutta step of length `h_s`.
    #[inline]
    pub fn rk4(&self, s: &State, mode: Mode, valves: Valves, h_s: f64) -> State {
        let k1 = self.derivative(s, mode, valves);
        let k2 = self.derivative(&s.axpy(0.5 * h_s, &k1), mode, valves);
        let k3 = self.derivative(&s.axpy(0.5 * h_s, &k2), mode, valves);
        let k4 = self.derivative(&s.axpy(h_s, &k3), mode, valves);
        let h6 = h_s / 6.0;
        State {
            x_m: s.x_m + h6 * (k1.x_m + 2.0 * (k2.x_m + k3.x_m) + k4.x_m),
            v_m_s: s.v_m_s + h6 * (k1.v_m_s + 2.0 * (k2.v_m_s + k3.v_m_s) + k4.v_m_s),
            p_cap_pa: s.p_cap_pa
                + h6 * (k1.p_cap_pa + 2.0 * (k2.p_cap_pa + k3.p_cap_pa) + k4.p_cap_pa),
            p_rod_pa: s.p_rod_pa
                + h6 * (k1.p_rod_pa + 2.0 * (k2.p_rod_pa + k3.p_rod_pa) + k4.p_rod_pa),
        }
    }
}
