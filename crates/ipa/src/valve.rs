//! The on/off valves: ISO 6358 mass flow, PWM drive and switching delays.
//!
//! Each of the two valves is a 3/2 solenoid valve: energised, it connects its chamber to the supply;
//! de-energised, to the exhaust (atmosphere). A command u > 0 pulses the cap-side valve with duty
//! |u| / 255 while the rod-side valve stays de-energised (its chamber exhausts); u < 0 the reverse.
//!
//! Mass flow through a path (ISO 6358-1:2013 with subsonic index m = 0.5), upstream p1, T1, downstream p2:
//!
//! ```text
//! mdot = C p1 rho0 sqrt(T0 / T1)                                   r = p2/p1 <= b (choked)
//! mdot = C p1 rho0 sqrt(T0 / T1) sqrt(1 - ((r - b) / (1 - b))^2)    b < r < r_lam (subsonic)
//! mdot = mdot(r_lam) (1 - r) / (1 - r_lam)                          r >= r_lam (laminar)
//! ```
//!
//! with rho0 = 1.185 kg/m^3 and T0 = 293.15 K (ISO 8778 reference atmosphere). The laminar branch
//! (linear in p1 - p2) replaces the infinite slope of the subsonic formula at r -> 1.

use crate::config::ValveConfig;

/// ISO 8778 reference density rho0 of air, kg/m^3.
pub const RHO0_KG_M3: f64 = 1.185;
/// ISO 8778 reference temperature T0, K.
pub const T0_K: f64 = 293.15;

/// An ISO 6358 flow path.
#[derive(Debug, Clone, PartialEq)]
pub struct FlowPath {
    /// C rho0 sqrt(T0 / T): choked mass flow per Pa of upstream pressure, kg/(s Pa).
    choked_per_pa: f64,
    /// b: critical pressure ratio.
    b: f64,
    /// r_lam: pressure ratio where the laminar branch starts.
    r_lam: f64,
    /// sqrt(1 - ((r_lam - b)/(1 - b))^2) / (1 - r_lam): slope factor of the laminar branch.
    lam_factor: f64,
    /// 1 / (1 - b).
    inv_one_minus_b: f64,
}

impl FlowPath {
    /// A path of sonic conductance `c_dm3_s_bar` (dm^3/(s bar), ANR) with the critical and laminar
    /// pressure ratios of `cfg`, for upstream air at `temperature_k` (K).
    pub fn new(c_dm3_s_bar: f64, cfg: &ValveConfig, temperature_k: f64) -> Self {
        // C in dm^3/(s bar) -> m^3/(s Pa): 1e-3 / 1e5.
        let c_si = c_dm3_s_bar * 1e-8;
        let b = cfg.critical_pressure_ratio;
        let r_lam = cfg.laminar_pressure_ratio;
        let z = (r_lam - b) / (1.0 - b);
        FlowPath {
            choked_per_pa: c_si * RHO0_KG_M3 * (T0_K / temperature_k).sqrt(),
            b,
            r_lam,
            lam_factor: (1.0 - z * z).sqrt() / (1.0 - r_lam),
            inv_one_minus_b: 1.0 / (1.0 - b),
        }
    }

    /// Mass flow from `p1_pa` to `p2_pa`, kg/s; negative when p2 > p1 (the flow reverses).
    #[inline(always)]
    pub fn mass_flow_kg_s(&self, p1_pa: f64, p2_pa: f64) -> f64 {
        if p1_pa >= p2_pa {
            self.forward(p1_pa, p2_pa)
        } else {
            -self.forward(p2_pa, p1_pa)
        }
    }

    /// Forward flow (p_up >= p_down), written without divisions: with r = p_down / p_up,
    /// p_up sqrt(1 - z^2) = sqrt(p_up^2 - (p_up z)^2) and p_up z = (p_down - b p_up) / (1 - b).
    #[inline(always)]
    fn forward(&self, p_up: f64, p_down: f64) -> f64 {
        if p_up <= 0.0 {
            return 0.0;
        }
        if p_down <= self.b * p_up {
            self.choked_per_pa * p_up
        } else if p_down < self.r_lam * p_up {
            let pz = (p_down - self.b * p_up) * self.inv_one_minus_b;
            // p_up > pz here (r < r_lam < 1); max(0) guards the rounding.
            self.choked_per_pa * (p_up * p_up - pz * pz).max(0.0).sqrt()
        } else {
            self.choked_per_pa * self.lam_factor * (p_up - p_down)
        }
    }
}

/// A solenoid valve with an opening delay and a closing delay ("inertial" delays: a pulse shorter than
/// the opening delay does not open the valve, a gap shorter than the closing delay does not close it).
#[derive(Debug, Clone, PartialEq)]
pub struct Valve {
    /// Commanded (energised) state.
    commanded: bool,
    /// Time (s) of the last change of the commanded state.
    commanded_since_s: f64,
    /// Actual state of the spool: true = open to supply.
    open: bool,
    opening_delay_s: f64,
    closing_delay_s: f64,
}

impl Valve {
    /// A de-energised, closed valve.
    pub fn new(opening_delay_s: f64, closing_delay_s: f64) -> Self {
        Valve {
            commanded: false,
            commanded_since_s: f64::NEG_INFINITY,
            open: false,
            opening_delay_s,
            closing_delay_s,
        }
    }

    /// True when the valve connects its chamber to the supply.
    pub fn is_open(&self) -> bool {
        self.open
    }

    /// Back to de-energised and closed.
    pub fn reset(&mut self) {
        self.commanded = false;
        self.commanded_since_s = f64::NEG_INFINITY;
        self.open = false;
    }

    /// Applies the command changes `commands` (time s, energised?) in time order over [t0, t1) and
    /// appends the instants (time s, open?) at which the valve actually switches within [t0, t1).
    pub fn advance(
        &mut self,
        commands: &[(f64, bool)],
        t1_s: f64,
        switches: &mut Vec<(f64, bool)>,
    ) {
        let mut next = 0;
        loop {
            let delay = if self.commanded {
                self.opening_delay_s
            } else {
                self.closing_delay_s
            };
            let pending = (self.commanded != self.open).then_some(self.commanded_since_s + delay);
            let next_cmd = commands.get(next).map(|c| c.0).unwrap_or(f64::INFINITY);
            match pending {
                Some(tp) if tp <= next_cmd && tp < t1_s => {
                    self.open = self.commanded;
                    switches.push((tp, self.open));
                }
                _ if next < commands.len() => {
                    let (t, on) = commands[next];
                    if on != self.commanded {
                        self.commanded = on;
                        self.commanded_since_s = t;
                    }
                    next += 1;
                }
                _ => break,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path() -> FlowPath {
        FlowPath::new(
            1.0,
            &ValveConfig {
                critical_pressure_ratio: 0.5,
                ..ValveConfig::default()
            },
            T0_K,
        )
    }

    // Choked: mdot = C p1 rho0 = 1e-8 m^3/(s Pa) * 6e5 Pa * 1.185 kg/m^3 = 7.11e-3 kg/s, whatever p2 <= b p1.
    #[test]
    fn choked_flow_is_c_p1_rho0() {
        let f = path();
        assert!((f.mass_flow_kg_s(6e5, 1e5) - 7.11e-3).abs() < 1e-12);
        assert!((f.mass_flow_kg_s(6e5, 3e5) - 7.11e-3).abs() < 1e-12);
    }

    // Subsonic at r = 0.75, b = 0.5: factor sqrt(1 - 0.5^2) = 0.8660254.
    #[test]
    fn subsonic_flow_follows_the_iso_ellipse_and_reverses() {
        let f = path();
        let expect = 1e-8 * 4e5 * 1.185 * 0.75_f64.sqrt();
        assert!((f.mass_flow_kg_s(4e5, 3e5) - expect).abs() < 1e-15);
        assert!((f.mass_flow_kg_s(3e5, 4e5) + expect).abs() < 1e-15);
        assert_eq!(f.mass_flow_kg_s(2e5, 2e5), 0.0);
    }

    // The laminar branch meets the subsonic branch at r_lam (continuity).
    #[test]
    fn laminar_branch_is_continuous_at_r_lam() {
        let f = path();
        let r = f.r_lam;
        let z = (r - 0.5) / 0.5;
        let sub = 1e-8 * 1e5 * 1.185 * (1.0 - z * z).sqrt();
        assert!((f.mass_flow_kg_s(1e5, r * 1e5) - sub).abs() < 1e-15);
    }

    #[test]
    fn pulses_shorter_than_the_opening_delay_do_not_open_the_valve() {
        let mut v = Valve::new(1e-3, 0.5e-3);
        let mut sw = Vec::new();
        v.advance(&[(0.0, true), (0.8e-3, false)], 0.01, &mut sw);
        assert!(sw.is_empty() && !v.is_open());
        v.advance(&[(0.01, true), (0.013, false)], 0.02, &mut sw);
        assert_eq!(sw, vec![(0.011, true), (0.0135, false)]);
    }

    #[test]
    fn a_closing_delay_crosses_into_the_next_period() {
        let mut v = Valve::new(1e-3, 2e-3);
        let mut sw = Vec::new();
        v.advance(&[(0.0, true), (0.009, false)], 0.01, &mut sw);
        assert_eq!(sw, vec![(0.001, true)]);
        sw.clear();
        v.advance(&[], 0.02, &mut sw);
        assert_eq!(sw, vec![(0.011, false)]);
    }
}
