//! The calibrated parameters of the physics plant ([`Parameter`]): their TOML keys, physical bounds and
//! the coordinates the search works in.
//!
//! The search works in coordinates θ in which the bounds are a box and a step of 0.01 means about 1 %:
//! ln of every positive quantity (conductances, delays, friction, mass, volumes), the ratio F_c / F_s
//! for the Coulomb friction (so 0 < F_c <= F_s holds by the box), and F_ext / 1 N for the external
//! force (of either sign).

use std::str::FromStr;

use crate::config::PlantConfig;
use crate::IpaError;

/// A parameter of the physics plant that calibration can estimate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Parameter {
    /// C_s: sonic conductance of the supply-to-chamber path, dm^3/(s bar) (`valve.supply_conductance_dm3_s_bar`).
    SupplyConductance,
    /// C_e: sonic conductance of the chamber-to-exhaust path, dm^3/(s bar) (`valve.exhaust_conductance_dm3_s_bar`).
    ExhaustConductance,
    /// Valve opening delay, ms (`valve.opening_delay_ms`); with the PWM period it sets the smallest pulse
    /// that opens a valve (part of the deadzone).
    OpeningDelay,
    /// Valve closing delay, ms (`valve.closing_delay_ms`).
    ClosingDelay,
    /// F_s: static (breakaway) friction, N (`friction.static_n`).
    StaticFriction,
    /// F_c: Coulomb friction, N (`friction.coulomb_n`), at most F_s.
    CoulombFriction,
    /// v_s: Stribeck velocity, mm/s (`friction.stribeck_velocity_mm_s`).
    StribeckVelocity,
    /// sigma: viscous friction coefficient, N s/m (`friction.viscous_n_s_m`).
    ViscousFriction,
    /// M: moving mass, kg (`load.moving_mass_kg`).
    MovingMass,
    /// V_a0: cap-side dead volume, cm^3 (`cylinder.dead_volume_cap_cm3`).
    DeadVolumeCap,
    /// V_b0: rod-side dead volume, cm^3 (`cylinder.dead_volume_rod_cm3`).
    DeadVolumeRod,
    /// F_ext: constant external force, N, + extends (`load.external_force_n`).
    ExternalForce,
}

/// How a parameter is mapped to the search coordinate θ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Coordinate {
    /// θ = ln(value).
    Log,
    /// θ = F_c / F_s.
    CoulombRatio,
    /// θ = value (in its unit).
    Linear,
}

impl Parameter {
    /// Every parameter, in report order: the default free set.
    pub const ALL: [Parameter; 12] = [
        Parameter::SupplyConductance,
        Parameter::ExhaustConductance,
        Parameter::OpeningDelay,
        Parameter::ClosingDelay,
        Parameter::StaticFriction,
        Parameter::CoulombFriction,
        Parameter::StribeckVelocity,
        Parameter::ViscousFriction,
        Parameter::MovingMass,
        Parameter::DeadVolumeCap,
        Parameter::DeadVolumeRod,
        Parameter::ExternalForce,
    ];

    /// Short name used by `--free` / `--fixed` and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Parameter::SupplyConductance => "supply_conductance",
            Parameter::ExhaustConductance => "exhaust_conductance",
            Parameter::OpeningDelay => "opening_delay",
            Parameter::ClosingDelay => "closing_delay",
            Parameter::StaticFriction => "static_friction",
            Parameter::CoulombFriction => "coulomb_friction",
            Parameter::StribeckVelocity => "stribeck_velocity",
            Parameter::ViscousFriction => "viscous_friction",
            Parameter::MovingMass => "moving_mass",
            Parameter::DeadVolumeCap => "dead_volume_cap",
            Parameter::DeadVolumeRod => "dead_volume_rod",
            Parameter::ExternalForce => "external_force",
        }
    }

    /// The plant-config TOML key (`section.key`) that holds the parameter.
    pub fn key(self) -> &'static str {
        match self {
            Parameter::SupplyConductance => "valve.supply_conductance_dm3_s_bar",
            Parameter::ExhaustConductance => "valve.exhaust_conductance_dm3_s_bar",
            Parameter::OpeningDelay => "valve.opening_delay_ms",
            Parameter::ClosingDelay => "valve.closing_delay_ms",
            Parameter::StaticFriction => "friction.static_n",
            Parameter::CoulombFriction => "friction.coulomb_n",
            Parameter::StribeckVelocity => "friction.stribeck_velocity_mm_s",
            Parameter::ViscousFriction => "friction.viscous_n_s_m",
            Parameter::MovingMass => "load.moving_mass_kg",
            Parameter::DeadVolumeCap => "cylinder.dead_volume_cap_cm3",
            Parameter::DeadVolumeRod => "cylinder.dead_volume_rod_cm3",
            Parameter::ExternalForce => "load.external_force_n",
        }
    }

    /// Unit of the physical value.
    pub fn unit(self) -> &'static str {
        match self {
            Parameter::SupplyConductance | Parameter::ExhaustConductance => "dm^3/(s bar)",
            Parameter::OpeningDelay | Parameter::ClosingDelay => "ms",
            Parameter::StaticFriction | Parameter::CoulombFriction | Parameter::ExternalForce => {
                "N"
            }
            Parameter::StribeckVelocity => "mm/s",
            Parameter::ViscousFriction => "N s/m",
            Parameter::MovingMass => "kg",
            Parameter::DeadVolumeCap | Parameter::DeadVolumeRod => "cm^3",
        }
    }

    /// The experiment that determines the parameter (for the warning when a record does not).
    pub fn experiment(self) -> &'static str {
        match self {
            Parameter::SupplyConductance => {
                "full-command moves (|u| = 255) over at least 50 mm in both directions"
            }
            Parameter::ExhaustConductance => {
                "full-command moves and fast reversals in both directions (the exhausting chamber brakes the piston)"
            }
            Parameter::OpeningDelay | Parameter::ClosingDelay => {
                "small commands near the deadzone (|u| = 5..60 counts) held 0.2..0.5 s, with the chamber pressures recorded"
            }
            Parameter::StaticFriction => "repeated starts from rest with commands just above the deadzone",
            Parameter::CoulombFriction => "slow motion: commands just above the deadzone in both directions",
            Parameter::StribeckVelocity => "motion at several slow speeds (below ~30 mm/s) in both directions",
            Parameter::ViscousFriction => "motion at several speeds up to full command in both directions",
            Parameter::MovingMass => "hard accelerations: steps from rest to full command and fast reversals",
            Parameter::DeadVolumeCap | Parameter::DeadVolumeRod => {
                "the chamber pressures recorded (p_a_pa, p_b_pa), with moves near both end stops"
            }
            Parameter::ExternalForce => "motion in both directions at the same commands",
        }
    }

    pub(crate) fn coordinate(self) -> Coordinate {
        match self {
            Parameter::CoulombFriction => Coordinate::CoulombRatio,
            Parameter::ExternalForce => Coordinate::Linear,
            _ => Coordinate::Log,
        }
    }

    /// The physical value in `cfg`.
    pub fn get(self, cfg: &PlantConfig) -> f64 {
        match self {
            Parameter::SupplyConductance => cfg.valve.supply_conductance_dm3_s_bar,
            Parameter::ExhaustConductance => cfg.valve.exhaust_conductance_dm3_s_bar,
            Parameter::OpeningDelay => cfg.valve.opening_delay_ms,
            Parameter::ClosingDelay => cfg.valve.closing_delay_ms,
            Parameter::StaticFriction => cfg.friction.static_n,
            Parameter::CoulombFriction => cfg.friction.coulomb_n,
            Parameter::StribeckVelocity => cfg.friction.stribeck_velocity_mm_s,
            Parameter::ViscousFriction => cfg.friction.viscous_n_s_m,
            Parameter::MovingMass => cfg.load.moving_mass_kg,
            Parameter::DeadVolumeCap => cfg.cylinder.dead_volume_cap_cm3,
            Parameter::DeadVolumeRod => cfg.cylinder.dead_volume_rod_cm3,
            Parameter::ExternalForce => cfg.load.external_force_n,
        }
    }

    /// Sets the physical value in `cfg`.
    pub fn set(self, cfg: &mut PlantConfig, value: f64) {
        let slot = match self {
            Parameter::SupplyConductance => &mut cfg.valve.supply_conductance_dm3_s_bar,
            Parameter::ExhaustConductance => &mut cfg.valve.exhaust_conductance_dm3_s_bar,
            Parameter::OpeningDelay => &mut cfg.valve.opening_delay_ms,
            Parameter::ClosingDelay => &mut cfg.valve.closing_delay_ms,
            Parameter::StaticFriction => &mut cfg.friction.static_n,
            Parameter::CoulombFriction => &mut cfg.friction.coulomb_n,
            Parameter::StribeckVelocity => &mut cfg.friction.stribeck_velocity_mm_s,
            Parameter::ViscousFriction => &mut cfg.friction.viscous_n_s_m,
            Parameter::MovingMass => &mut cfg.load.moving_mass_kg,
            Parameter::DeadVolumeCap => &mut cfg.cylinder.dead_volume_cap_cm3,
            Parameter::DeadVolumeRod => &mut cfg.cylinder.dead_volume_rod_cm3,
            Parameter::ExternalForce => &mut cfg.load.external_force_n,
        };
        *slot = value;
    }

    /// Bounds [lo, hi] of the search coordinate θ for the plant `cfg` (the delays must stay below the
    /// PWM period).
    pub(crate) fn bounds(self, cfg: &PlantConfig) -> (f64, f64) {
        let ln = |lo: f64, hi: f64| (lo.ln(), hi.ln());
        match self {
            Parameter::SupplyConductance | Parameter::ExhaustConductance => ln(1e-3, 10.0),
            Parameter::OpeningDelay | Parameter::ClosingDelay => {
                ln(1e-3, 0.9 * cfg.valve.pwm_period_ms)
            }
            Parameter::StaticFriction => ln(1e-2, 1e3),
            Parameter::CoulombFriction => (1e-3, 1.0),
            Parameter::StribeckVelocity => ln(1e-2, 1e3),
            Parameter::ViscousFriction => ln(1e-2, 1e4),
            Parameter::MovingMass => ln(1e-3, 1e3),
            Parameter::DeadVolumeCap | Parameter::DeadVolumeRod => ln(1e-2, 1e4),
            Parameter::ExternalForce => (-1e4, 1e4),
        }
    }
}

impl std::fmt::Display for Parameter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Parameter {
    type Err = IpaError;

    /// Parses a short name (`moving_mass`) or the TOML key (`load.moving_mass_kg`).
    fn from_str(s: &str) -> Result<Self, IpaError> {
        let t = s.trim();
        Parameter::ALL
            .into_iter()
            .find(|p| p.name() == t || p.key() == t)
            .ok_or_else(|| {
                IpaError::Config(format!(
                    "unknown calibration parameter '{t}': expected one of {}",
                    Parameter::ALL.map(Parameter::name).join(", ")
                ))
            })
    }
}

/// Parses a comma-separated list of parameter names (`--free`, `--fixed`); `all` means every one.
pub fn parse_list(s: &str) -> Result<Vec<Parameter>, IpaError> {
    if s.trim() == "all" {
        return Ok(Parameter::ALL.to_vec());
    }
    let mut out = Vec::new();
    for part in s.split(',').filter(|p| !p.trim().is_empty()) {
        let p: Parameter = part.parse()?;
        if out.contains(&p) {
            return Err(IpaError::Config(format!(
                "parameter list '{s}' names {} twice: expected each parameter once",
                p.name()
            )));
        }
        out.push(p);
    }
    if out.is_empty() {
        return Err(IpaError::Config(format!(
            "empty parameter list '{s}': expected names separated by commas ({})",
            Parameter::ALL.map(Parameter::name).join(", ")
        )));
    }
    Ok(out)
}

/// The free parameters from `--free` (default: all) without `--fixed`: each list parsed by
/// [`parse_list`]; a parameter named in both lists, or lists that leave none free, is an error.
pub fn free_parameters(
    free: Option<&str>,
    fixed: Option<&str>,
) -> Result<Vec<Parameter>, IpaError> {
    let mut out = match free {
        Some(l) => parse_list(l)?,
        None => Parameter::ALL.to_vec(),
    };
    if let Some(l) = fixed {
        let fixed = parse_list(l)?;
        if let (Some(_), Some(p)) = (free, fixed.iter().find(|p| out.contains(p))) {
            return Err(IpaError::Config(format!(
                "{} is named both free and fixed: expected each parameter in one list",
                p.name()
            )));
        }
        out.retain(|p| !fixed.contains(p));
    }
    if out.is_empty() {
        return Err(IpaError::Config(
            "the free and fixed lists leave no parameter to calibrate".into(),
        ));
    }
    Ok(out)
}

/// The map between the free parameters' physical values in a [`PlantConfig`] and the search vector θ.
#[derive(Debug, Clone)]
pub(crate) struct Coordinates {
    pub free: Vec<Parameter>,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
}

impl Coordinates {
    pub fn new(free: &[Parameter], cfg: &PlantConfig) -> Self {
        let (lo, hi) = free.iter().map(|p| p.bounds(cfg)).unzip();
        Coordinates {
            free: free.to_vec(),
            lo,
            hi,
        }
    }

    /// θ of `cfg`, clamped into the box.
    pub fn theta(&self, cfg: &PlantConfig) -> Vec<f64> {
        self.free
            .iter()
            .zip(self.lo.iter().zip(&self.hi))
            .map(|(&p, (&lo, &hi))| {
                let v = p.get(cfg);
                let t = match p.coordinate() {
                    Coordinate::Log => v.max(1e-300).ln(),
                    Coordinate::CoulombRatio => {
                        let fs = cfg.friction.static_n;
                        if fs > 0.0 {
                            v / fs
                        } else {
                            1.0
                        }
                    }
                    Coordinate::Linear => v,
                };
                t.clamp(lo, hi)
            })
            .collect()
    }

    /// `base` with the free parameters set from θ (the Coulomb ratio applied after F_s).
    pub fn config(&self, base: &PlantConfig, theta: &[f64]) -> PlantConfig {
        let mut cfg = base.clone();
        let mut ratio = None;
        for (&p, &t) in self.free.iter().zip(theta) {
            match p.coordinate() {
                Coordinate::Log => p.set(&mut cfg, t.exp()),
                Coordinate::CoulombRatio => ratio = Some(t),
                Coordinate::Linear => p.set(&mut cfg, t),
            }
        }
        match ratio {
            Some(r) => cfg.friction.coulomb_n = r * cfg.friction.static_n,
            // F_s free and F_c fixed: keep F_c <= F_s.
            None => cfg.friction.coulomb_n = cfg.friction.coulomb_n.min(cfg.friction.static_n),
        }
        cfg
    }

    /// Physical values of the free parameters at θ.
    pub fn values(&self, base: &PlantConfig, theta: &[f64]) -> Vec<f64> {
        let cfg = self.config(base, theta);
        self.free.iter().map(|p| p.get(&cfg)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // θ(config(θ)) = θ inside the box: the coordinates are a bijection.
    #[test]
    fn coordinates_round_trip() {
        let base = PlantConfig::default();
        let c = Coordinates::new(&Parameter::ALL, &base);
        let t = c.theta(&base);
        let cfg = c.config(&base, &t);
        for p in Parameter::ALL {
            assert!((p.get(&cfg) - p.get(&base)).abs() <= 1e-12 * p.get(&base).abs().max(1.0));
        }
        assert_eq!(c.theta(&cfg).len(), 12);
    }

    #[test]
    fn names_and_keys_parse() {
        assert_eq!(
            parse_list("moving_mass, friction.static_n").unwrap(),
            vec![Parameter::MovingMass, Parameter::StaticFriction]
        );
        let e = parse_list("mass").unwrap_err().to_string();
        assert!(e.contains("mass") && e.contains("moving_mass"), "{e}");
        // Named twice, by name or by key (audit s13 L4).
        let e = parse_list("moving_mass,load.moving_mass_kg")
            .unwrap_err()
            .to_string();
        assert!(e.contains("names moving_mass twice"), "{e}");
    }

    #[test]
    fn free_minus_fixed_refuses_contradictions_and_empty_sets() {
        let all = free_parameters(None, None).unwrap();
        assert_eq!(all, Parameter::ALL.to_vec());
        let f = free_parameters(None, Some("moving_mass")).unwrap();
        assert_eq!(f.len(), Parameter::ALL.len() - 1);
        assert!(!f.contains(&Parameter::MovingMass));
        let e = free_parameters(Some("moving_mass,friction.static_n"), Some("moving_mass"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("moving_mass is named both free and fixed"),
            "{e}"
        );
        let e = free_parameters(None, Some("all")).unwrap_err().to_string();
        assert!(e.contains("leave no parameter"), "{e}");
    }
}
