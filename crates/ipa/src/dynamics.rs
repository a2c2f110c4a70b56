//! The equations of motion of the IPA: state, right-hand side, one classical RK4 step (the reference
//! integrator) and one Dormand–Prince 5(4) step with its error estimate and dense output (the production
//! integrator, see [`crate::plant`]).
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
    /// The state with every component zero.
    pub const ZERO: State = State {
        x_m: 0.0,
        v_m_s: 0.0,
        p_cap_pa: 0.0,
        p_rod_pa: 0.0,
    };

    /// self + h d, component by component.
    #[inline]
    pub fn axpy(&self, h: f64, d: &State) -> State {
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
    /// 1 / M, 1/kg.
    inv_mass: f64,
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
            inv_mass: 1.0 / cfg.load.moving_mass_kg,
            external_force_n: cfg.load.external_force_n,
            supply_pa: cfg.air.atmosphere_pa + cfg.air.supply_gauge_mpa * 1e6,
            atmosphere_pa: cfg.air.atmosphere_pa,
        }
    }

    /// F: net pneumatic and external force on the piston, N (+ extends).
    #[inline(always)]
    pub fn drive_force_n(&self, s: &State) -> f64 {
        let c = &self.cylinder;
        s.p_cap_pa * c.area_cap_m2
            - s.p_rod_pa * c.area_rod_side_m2
            - self.atmosphere_pa * (c.area_cap_m2 - c.area_rod_side_m2)
            + self.external_force_n
    }

    /// Net mass flow into a chamber at pressure `p_pa` through its valve (kg/s).
    #[inline(always)]
    pub fn chamber_inflow_kg_s(&self, p_pa: f64, open: bool) -> f64 {
        if open {
            self.supply_path.mass_flow_kg_s(self.supply_pa, p_pa)
        } else {
            -self.exhaust_path.mass_flow_kg_s(p_pa, self.atmosphere_pa)
        }
    }

    /// ds/dt in mode `mode` with valves `valves`.
    #[inline(always)]
    pub fn derivative(&self, s: &State, mode: Mode, valves: Valves) -> State {
        let c = &self.cylinder;
        let (v, a) = match mode {
            Mode::Stuck => (0.0, 0.0),
            Mode::Sliding(dir) => {
                let f = self.drive_force_n(s) - self.friction.sliding_n(dir, s.v_m_s);
                (s.v_m_s, f * self.inv_mass)
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

    /// One Dormand–Prince 5(4) step of length `h_s` from `s` (time derivative `k1` there, in the same
    /// mode and valve states): the fifth-order solution, the difference to the embedded fourth-order
    /// one (the local error estimate, same units as the state) and the stage derivatives kept for the
    /// dense output. `k7` (the derivative at the new state) is the next step's `k1` (FSAL).
    #[inline]
    pub fn dopri5(
        &self,
        s: &State,
        k1: &State,
        mode: Mode,
        valves: Valves,
        h_s: f64,
    ) -> Dopri5Step {
        let f = |y: State| self.derivative(&y, mode, valves);
        let k2 = f(s.axpy(h_s * A21, k1));
        let k3 = f(lin(s, h_s, &[(A31, k1), (A32, &k2)]));
        let k4 = f(lin(s, h_s, &[(A41, k1), (A42, &k2), (A43, &k3)]));
        let k5 = f(lin(
            s,
            h_s,
            &[(A51, k1), (A52, &k2), (A53, &k3), (A54, &k4)],
        ));
        let k6 = f(lin(
            s,
            h_s,
            &[(A61, k1), (A62, &k2), (A63, &k3), (A64, &k4), (A65, &k5)],
        ));
        let y = lin(
            s,
            h_s,
            &[(B1, k1), (B3, &k3), (B4, &k4), (B5, &k5), (B6, &k6)],
        );
        let k7 = f(y);
        let err = lin(
            &State::ZERO,
            h_s,
            &[
                (E1, k1),
                (E3, &k3),
                (E4, &k4),
                (E5, &k5),
                (E6, &k6),
                (E7, &k7),
            ],
        );
        Dopri5Step {
            y0: *s,
            y,
            err,
            k: [*k1, k3, k4, k5, k6, k7],
            h_s,
        }
    }
}

/// s + h sum_i a_i k_i.
#[inline]
fn lin(s: &State, h: f64, terms: &[(f64, &State)]) -> State {
    let mut r = *s;
    for &(a, k) in terms {
        r = r.axpy(h * a, k);
    }
    r
}

// Dormand & Prince (1980) coefficients (Hairer, Norsett & Wanner, Solving ODE I, table II.5.2).
const A21: f64 = 1.0 / 5.0;
const A31: f64 = 3.0 / 40.0;
const A32: f64 = 9.0 / 40.0;
const A41: f64 = 44.0 / 45.0;
const A42: f64 = -56.0 / 15.0;
const A43: f64 = 32.0 / 9.0;
const A51: f64 = 19372.0 / 6561.0;
const A52: f64 = -25360.0 / 2187.0;
const A53: f64 = 64448.0 / 6561.0;
const A54: f64 = -212.0 / 729.0;
const A61: f64 = 9017.0 / 3168.0;
const A62: f64 = -355.0 / 33.0;
const A63: f64 = 46732.0 / 5247.0;
const A64: f64 = 49.0 / 176.0;
const A65: f64 = -5103.0 / 18656.0;
const B1: f64 = 35.0 / 384.0;
const B3: f64 = 500.0 / 1113.0;
const B4: f64 = 125.0 / 192.0;
const B5: f64 = -2187.0 / 6784.0;
const B6: f64 = 11.0 / 84.0;
// Fifth-order minus fourth-order weights.
const E1: f64 = 71.0 / 57600.0;
const E3: f64 = -71.0 / 16695.0;
const E4: f64 = 71.0 / 1920.0;
const E5: f64 = -17253.0 / 339200.0;
const E6: f64 = 22.0 / 525.0;
const E7: f64 = -1.0 / 40.0;
// Dense output (Hairer's DOPRI5 code, CONTD5): fourth-order continuous extension.
const D1: f64 = -12715105075.0 / 11282082432.0;
const D3: f64 = 87487479700.0 / 32700410799.0;
const D4: f64 = -10690763975.0 / 1880347072.0;
const D5: f64 = 701980252875.0 / 199316789632.0;
const D6: f64 = -1453857185.0 / 822651844.0;
const D7: f64 = 69997945.0 / 29380423.0;

/// One Dormand–Prince step: start and end states, error estimate and what the dense output needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dopri5Step {
    /// The state at the start of the step.
    pub y0: State,
    /// The fifth-order state at the end of the step.
    pub y: State,
    /// Fifth- minus fourth-order solution: the local error estimate (m, m/s, Pa, Pa).
    pub err: State,
    /// Stage derivatives k1, k3, k4, k5, k6, k7 (k2 has zero weight in the solution and dense output).
    k: [State; 6],
    /// The step length, s.
    pub h_s: f64,
}

impl Dopri5Step {
    /// The derivative at the end of the step (k7), valid as the next step's k1.
    pub fn end_derivative(&self) -> State {
        self.k[5]
    }

    /// The coefficients m_0..m_4 (monomial basis in theta) of w . y(t + theta h) + c along the dense
    /// output of the step, for the linear function of the state with weights `w` = (x, v, p_a, p_b)
    /// and constant `c`: the same polynomial as [`Dopri5Step::dense`] gives, from scalar projections
    /// only (no full dense output needed to test a step for events).
    #[inline]
    pub fn quartic(&self, w: &[f64; 4], c: f64) -> [f64; 5] {
        let dot = |s: &State| w[0] * s.x_m + w[1] * s.v_m_s + w[2] * s.p_cap_pa + w[3] * s.p_rod_pa;
        let h = self.h_s;
        // Written out: `each_ref().map(dot)` compiled to an out-of-line array map (4 % of a simulation).
        let [k1, k3, k4, k5, k6, k7] = [
            dot(&self.k[0]),
            dot(&self.k[1]),
            dot(&self.k[2]),
            dot(&self.k[3]),
            dot(&self.k[4]),
            dot(&self.k[5]),
        ];
        let a = dot(&self.y0) + c;
        let b = dot(&self.y) - dot(&self.y0);
        let c3 = h * k1 - b;
        let d = b - h * k7 - c3;
        let e = h * (D1 * k1 + D3 * k3 + D4 * k4 + D5 * k5 + D6 * k6 + D7 * k7);
        // a + theta (b + (1 - theta)(c3 + theta (d + (1 - theta) e))), expanded.
        [a, b + c3, d + e - c3, -(d + 2.0 * e), e]
    }

    /// The fourth-order continuous extension of the step, for locating events inside it.
    pub fn dense(&self) -> Dense {
        let h = self.h_s;
        let [k1, k3, k4, k5, k6, k7] = &self.k;
        let r2 = self.y.axpy(-1.0, &self.y0);
        let r3 = lin(&State::ZERO, h, &[(1.0, k1)]).axpy(-1.0, &r2);
        let r4 = r2.axpy(-h, k7).axpy(-1.0, &r3);
        let r5 = lin(
            &State::ZERO,
            h,
            &[(D1, k1), (D3, k3), (D4, k4), (D5, k5), (D6, k6), (D7, k7)],
        );
        Dense {
            r: [self.y0, r2, r3, r4, r5],
        }
    }
}

/// The dense output of a Dormand–Prince step: y(t + theta h) for theta in [0, 1], fourth order.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dense {
    r: [State; 5],
}

impl Dense {
    /// The state at the fraction `theta` (0..=1) of the step.
    #[inline]
    pub fn at(&self, theta: f64) -> State {
        let t1 = 1.0 - theta;
        let [r1, r2, r3, r4, r5] = &self.r;
        // r1 + theta (r2 + t1 (r3 + theta (r4 + t1 r5)))
        let c = |a: f64, b: f64, c3: f64, d: f64, e: f64| {
            a + theta * (b + t1 * (c3 + theta * (d + t1 * e)))
        };
        State {
            x_m: c(r1.x_m, r2.x_m, r3.x_m, r4.x_m, r5.x_m),
            v_m_s: c(r1.v_m_s, r2.v_m_s, r3.v_m_s, r4.v_m_s, r5.v_m_s),
            p_cap_pa: c(
                r1.p_cap_pa,
                r2.p_cap_pa,
                r3.p_cap_pa,
                r4.p_cap_pa,
                r5.p_cap_pa,
            ),
            p_rod_pa: c(
                r1.p_rod_pa,
                r2.p_rod_pa,
                r3.p_rod_pa,
                r4.p_rod_pa,
                r5.p_rod_pa,
            ),
        }
    }
}
