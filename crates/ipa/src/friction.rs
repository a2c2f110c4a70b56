//! Seal friction: stiction, Coulomb, Stribeck and viscous parts.
//!
//! While sliding in direction s = +-1 at velocity v:
//!
//! ```text
//! F_f(v) = s (F_c + (F_s - F_c) exp(-(v / v_s)^2)) + sigma v
//! ```
//!
//! At rest the piston sticks while the net driving force stays within +-F_s (Karnopp's model); the
//! plant's integrator handles the switching between sticking and sliding as located events.

use crate::config::FrictionConfig;

/// Friction parameters in SI units.
#[derive(Debug, Clone, PartialEq)]
pub struct Friction {
    /// F_s: breakaway force, N.
    pub static_n: f64,
    /// F_c: Coulomb force, N.
    pub coulomb_n: f64,
    /// 1 / v_s^2, (s/m)^2.
    inv_vs2: f64,
    /// sigma: viscous coefficient, N s/m.
    pub viscous_n_s_m: f64,
}

impl Friction {
    /// From the configuration (v_s in mm/s there).
    pub fn new(cfg: &FrictionConfig) -> Self {
        let vs = cfg.stribeck_velocity_mm_s * 1e-3;
        Friction {
            static_n: cfg.static_n,
            coulomb_n: cfg.coulomb_n,
            inv_vs2: 1.0 / (vs * vs),
            viscous_n_s_m: cfg.viscous_n_s_m,
        }
    }

    /// Friction force (N, opposing the motion) while sliding in direction `dir` (+-1) at velocity `v_m_s`.
    #[inline(always)]
    pub fn sliding_n(&self, dir: f64, v_m_s: f64) -> f64 {
        let q = v_m_s * v_m_s * self.inv_vs2;
        // exp(-q) < 1e-19 beyond q = 44: below the last bit of F_c, so the exponential is skipped.
        let stribeck = if q < 44.0 {
            (self.static_n - self.coulomb_n) * (-q).exp()
        } else {
            0.0
        };
        dir * (self.coulomb_n + stribeck) + self.viscous_n_s_m * v_m_s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // F_f(0) = F_s, F_f(v_s) = F_c + (F_s - F_c)/e + sigma v_s, F_f -> F_c + sigma v for v >> v_s.
    #[test]
    fn stribeck_curve_runs_from_static_to_coulomb_plus_viscous() {
        let f = Friction::new(&FrictionConfig {
            static_n: 30.0,
            coulomb_n: 20.0,
            stribeck_velocity_mm_s: 10.0,
            viscous_n_s_m: 50.0,
        });
        assert_eq!(f.sliding_n(1.0, 0.0), 30.0);
        assert!((f.sliding_n(1.0, 0.01) - (20.0 + 10.0 / std::f64::consts::E + 0.5)).abs() < 1e-12);
        assert!((f.sliding_n(-1.0, -0.5) - (-20.0 - 25.0)).abs() < 1e-9);
    }
}
