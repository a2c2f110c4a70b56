//! The double-acting cylinder: piston areas, chamber volumes and the chamber pressure equation.
//!
//! Chamber a (cap side) fills to extend (x grows), chamber b (rod side) to retract. With the position x in
//! [0, L] measured from the retracted end:
//!
//! ```text
//! V_a = V_a0 + A_a x           A_a = pi D^2 / 4
//! V_b = V_b0 + A_b (L - x)     A_b = pi (D^2 - d^2) / 4
//! ```
//!
//! Energy equation with polytropic charging and discharging (Richer & Hurmuzlu 2000, eq. 11), chamber
//! temperature taken equal to the supply temperature T:
//!
//! ```text
//! dp/dt = (R T / V) (alpha_in mdot_in - alpha_out mdot_out) - alpha (p / V) dV/dt
//! ```

use crate::config::PlantConfig;

/// Geometry and gas constants of the cylinder, in SI units (m, m^2, m^3, Pa, K).
#[derive(Debug, Clone, PartialEq)]
pub struct Cylinder {
    /// A_a: cap-side piston area, m^2.
    pub area_cap_m2: f64,
    /// A_b: rod-side (annular) piston area, m^2.
    pub area_rod_side_m2: f64,
    /// L: stroke, m.
    pub stroke_m: f64,
    /// V_a0: cap-side dead volume, m^3.
    pub dead_cap_m3: f64,
    /// V_b0: rod-side dead volume, m^3.
    pub dead_rod_m3: f64,
    /// R T: gas constant times temperature, J/kg.
    pub rt: f64,
    /// alpha_in: polytropic exponent of charging.
    pub alpha_in: f64,
    /// alpha_out: polytropic exponent of discharging.
    pub alpha_out: f64,
    /// alpha: polytropic exponent of the volume term.
    pub alpha: f64,
}

impl Cylinder {
    /// From a (validated) configuration.
    pub fn new(cfg: &PlantConfig) -> Self {
        let d = cfg.cylinder.bore_mm * 1e-3;
        let r = cfg.cylinder.rod_mm * 1e-3;
        let quarter_pi = std::f64::consts::FRAC_PI_4;
        Cylinder {
            area_cap_m2: quarter_pi * d * d,
            area_rod_side_m2: quarter_pi * (d * d - r * r),
            stroke_m: cfg.cylinder.stroke_mm * 1e-3,
            dead_cap_m3: cfg.cylinder.dead_volume_cap_cm3 * 1e-6,
            dead_rod_m3: cfg.cylinder.dead_volume_rod_cm3 * 1e-6,
            rt: cfg.air.gas_constant_j_kg_k * cfg.air.temperature_k,
            alpha_in: cfg.air.exponent_charging,
            alpha_out: cfg.air.exponent_discharging,
            alpha: cfg.air.exponent_volume,
        }
    }

    /// V_a(x), m^3.
    #[inline(always)]
    pub fn volume_cap_m3(&self, x_m: f64) -> f64 {
        self.dead_cap_m3 + self.area_cap_m2 * x_m
    }

    /// V_b(x), m^3.
    #[inline(always)]
    pub fn volume_rod_m3(&self, x_m: f64) -> f64 {
        self.dead_rod_m3 + self.area_rod_side_m2 * (self.stroke_m - x_m)
    }

    /// dp/dt of a chamber (Pa/s) at pressure `p_pa` and volume `v_m3`, with net mass flow `mdot_kg_s`
    /// into it (negative: out of it) and volume rate `dv_m3_s`.
    #[inline(always)]
    pub fn dp_dt(&self, p_pa: f64, v_m3: f64, mdot_kg_s: f64, dv_m3_s: f64) -> f64 {
        let exponent = if mdot_kg_s >= 0.0 {
            self.alpha_in
        } else {
            self.alpha_out
        };
        // Times 1/V rather than divided by V: the division depends on x only and runs while the flow
        // is computed, instead of after it.
        let inv_v = 1.0 / v_m3;
        (self.rt * exponent * mdot_kg_s - self.alpha * p_pa * dv_m3_s) * inv_v
    }
}
