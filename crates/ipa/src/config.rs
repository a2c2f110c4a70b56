//! Parameters of the physics IPA plant ([`PlantConfig`]), their defaults with sources, TOML reading and
//! the commented TOML printed by `ipa-sysid plant-config`.
//!
//! Every value has a unit in its key (`bore_mm`, `opening_delay_ms`). Sources: Table II of the paper
//! (bore, rod, stroke, supply pressure, temperature, k), ISO 6358 / ISO 8778 (reference density and
//! temperature), Richer & Hurmuzlu (2000) (polytropic exponents), and engineering estimates for what the
//! paper and the available catalogues do not give (valve conductance and delays, friction, dead volumes,
//! moving mass). The estimates are calibrated so that the simulated IPA extends at about 0.35 m/s and
//! retracts at about 0.45 m/s at full command (the paper's model: +0.37 / -0.53 m/s) and has a deadzone of
//! a few tens of counts. `docs/plant.md` gives the reasoning for each value.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::IpaError;

/// All parameters of the physics plant. Every section has defaults, so a TOML file only needs the keys
/// it changes; unknown keys are refused.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct PlantConfig {
    /// Cylinder geometry.
    pub cylinder: CylinderConfig,
    /// Air supply and gas properties.
    pub air: AirConfig,
    /// The two on/off valves and their PWM drive.
    pub valve: ValveConfig,
    /// Moving mass and external load.
    pub load: LoadConfig,
    /// Seal friction.
    pub friction: FrictionConfig,
    /// Position encoder.
    pub encoder: EncoderConfig,
    /// Numerical integration.
    pub integration: IntegrationConfig,
    /// What `ipa-sysid calibrate` said of this twin (the `[calibration]` table it writes; absent in
    /// `plant-config`'s output, in hand-written files and in twins written before it existed). The
    /// plant ignores it; `tune` and `control` repeat its warnings ([`PlantConfig::calibration_warnings`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration: Option<CalibrationNote>,
}

/// The verdict of `ipa-sysid calibrate` on the twin it wrote (the `[calibration]` table of the twin
/// TOML): the record, its sampling period Ts, the free-run fits and the warnings, so that a command
/// that later runs on the twin can say that its calibration was doubtful (audit s16 M8).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct CalibrationNote {
    /// The estimation record the twin was calibrated on (its path as given to `calibrate --data`).
    pub record: String,
    /// The record's sampling period Ts, s, at which the twin was fitted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ts_s: Option<f64>,
    /// Free-run fit of the twin on the estimation record, % (100 (1 - |y - y_sim| / |y - mean y|)).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_estimation_percent: Option<f64>,
    /// Free-run fit of the twin on the validation record, % (when one was given).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fit_validation_percent: Option<f64>,
    /// The calibration's warnings, as `calibrate` printed them.
    pub warnings: Vec<String>,
}

/// Double-acting cylinder (Koganei twin-port, Table I/II).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CylinderConfig {
    /// Bore (piston) diameter D in mm (Table II: 40 mm).
    pub bore_mm: f64,
    /// Rod diameter d in mm (Table II: 16 mm).
    pub rod_mm: f64,
    /// Stroke L in mm (Table II: 200 mm).
    pub stroke_mm: f64,
    /// Dead volume V_a0 of the cap-side chamber (end cap, port, tube to the valve) in cm^3.
    pub dead_volume_cap_cm3: f64,
    /// Dead volume V_b0 of the rod-side chamber in cm^3.
    pub dead_volume_rod_cm3: f64,
}

impl Default for CylinderConfig {
    fn default() -> Self {
        CylinderConfig {
            bore_mm: 40.0,
            rod_mm: 16.0,
            stroke_mm: 200.0,
            dead_volume_cap_cm3: 10.0,
            dead_volume_rod_cm3: 10.0,
        }
    }
}

/// Supply, atmosphere and gas properties.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AirConfig {
    /// Supply pressure above atmosphere in MPa (Table II: 0.6 MPa).
    pub supply_gauge_mpa: f64,
    /// Atmospheric (exhaust) pressure p_atm in Pa (standard atmosphere).
    pub atmosphere_pa: f64,
    /// Supply and chamber air temperature T in K (Table II: 294.5 K).
    pub temperature_k: f64,
    /// Specific heat ratio k of air (Table II: 1.4).
    pub heat_capacity_ratio: f64,
    /// Specific gas constant R of air in J/(kg K).
    pub gas_constant_j_kg_k: f64,
    /// Polytropic exponent alpha_in of charging (Richer & Hurmuzlu 2000: k, adiabatic).
    pub exponent_charging: f64,
    /// Polytropic exponent alpha_out of discharging (Richer & Hurmuzlu 2000: 1, isothermal).
    pub exponent_discharging: f64,
    /// Polytropic exponent alpha of the volume (work) term (Richer & Hurmuzlu 2000: 1.2).
    pub exponent_volume: f64,
}

impl Default for AirConfig {
    fn default() -> Self {
        AirConfig {
            supply_gauge_mpa: 0.6,
            atmosphere_pa: 101_325.0,
            temperature_k: 294.5,
            heat_capacity_ratio: 1.4,
            gas_constant_j_kg_k: 287.0,
            exponent_charging: 1.4,
            exponent_discharging: 1.0,
            exponent_volume: 1.2,
        }
    }
}

/// The two 3/2 on/off valves (Koganei EB10ES1-PS-6W, Table I) and their PWM drive. Energised, a valve
/// connects its chamber to the supply; de-energised, to the exhaust.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ValveConfig {
    /// Sonic conductance C (ISO 6358) of the supply-to-chamber path, in dm^3/(s bar) (ANR).
    pub supply_conductance_dm3_s_bar: f64,
    /// Sonic conductance C (ISO 6358) of the chamber-to-exhaust path, in dm^3/(s bar) (ANR).
    pub exhaust_conductance_dm3_s_bar: f64,
    /// Critical pressure ratio b (ISO 6358).
    pub critical_pressure_ratio: f64,
    /// Pressure ratio above which the flow is taken as laminar (linear in the pressure difference),
    /// which keeps the flow Lipschitz near equal pressures (as Simscape's pneumatic valves do).
    pub laminar_pressure_ratio: f64,
    /// PWM period in ms (one PWM period per default sampling period Ts = 10 ms).
    pub pwm_period_ms: f64,
    /// Opening delay in ms: a valve opens this long after it is energised; shorter pulses do not open it.
    pub opening_delay_ms: f64,
    /// Closing delay in ms: a valve closes this long after it is de-energised.
    pub closing_delay_ms: f64,
}

impl Default for ValveConfig {
    fn default() -> Self {
        ValveConfig {
            supply_conductance_dm3_s_bar: 0.1,
            exhaust_conductance_dm3_s_bar: 0.5,
            critical_pressure_ratio: 0.3,
            laminar_pressure_ratio: 0.995,
            pwm_period_ms: 10.0,
            opening_delay_ms: 0.4,
            closing_delay_ms: 0.4,
        }
    }
}

/// Moving mass and external load.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LoadConfig {
    /// Moving mass M of piston, rod and load in kg.
    pub moving_mass_kg: f64,
    /// Constant external force on the rod in N, positive in the extending direction (Table II: 0 N).
    pub external_force_n: f64,
}

impl Default for LoadConfig {
    fn default() -> Self {
        LoadConfig {
            moving_mass_kg: 0.6,
            external_force_n: 0.0,
        }
    }
}

/// Seal friction: stiction, Coulomb, Stribeck and viscous parts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FrictionConfig {
    /// Static (breakaway) friction F_s in N.
    pub static_n: f64,
    /// Coulomb (kinetic) friction F_c in N (at most F_s).
    pub coulomb_n: f64,
    /// Stribeck velocity v_s in mm/s.
    pub stribeck_velocity_mm_s: f64,
    /// Viscous friction coefficient sigma in N s/m.
    pub viscous_n_s_m: f64,
}

impl Default for FrictionConfig {
    fn default() -> Self {
        FrictionConfig {
            static_n: 8.0,
            coulomb_n: 5.0,
            stribeck_velocity_mm_s: 10.0,
            viscous_n_s_m: 30.0,
        }
    }
}

/// Optical encoder (AEDR-8300 with a linear strip, Table I).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EncoderConfig {
    /// Resolution in mm per count; the output y is the position rounded to a multiple of it.
    pub resolution_mm: f64,
}

impl Default for EncoderConfig {
    fn default() -> Self {
        EncoderConfig {
            resolution_mm: 0.01,
        }
    }
}

/// Numerical integration. The production integrator is the adaptive Dormand–Prince 5(4) pair with
/// `tolerance`; the substep settings apply to the classical RK4 reference integrator
/// ([`crate::plant::Integrator::Rk4`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IntegrationConfig {
    /// Local error tolerance of the adaptive Dormand–Prince steps (dimensionless): the error estimate
    /// of every accepted step is at most this times the stroke (position, m), 1 m/s × (1 + |v| / v_s)
    /// (velocity) and 0.2 × the absolute supply pressure (pressures, Pa). With 5e-9: 1 nm, 5 nm/s at
    /// rest, 0.7 mPa.
    pub tolerance: f64,
    /// Largest RK4 substep in ms (reference integrator); substeps are also cut at every valve
    /// switching instant.
    pub max_substep_ms: f64,
    /// Largest RK4 substep in ms while sliding slower than `slow_speed_mm_s` (reference integrator; the
    /// Stribeck region, where the friction changes on a time scale of v_s / acceleration).
    pub slow_substep_ms: f64,
    /// Speed in mm/s below which `slow_substep_ms` is used (reference integrator).
    pub slow_speed_mm_s: f64,
}

impl Default for IntegrationConfig {
    fn default() -> Self {
        IntegrationConfig {
            tolerance: 5e-9,
            max_substep_ms: 0.25,
            slow_substep_ms: 0.0625,
            slow_speed_mm_s: 40.0,
        }
    }
}

/// One documented parameter: TOML key, value, and the comment printed with it.
struct Entry {
    key: &'static str,
    value: f64,
    doc: &'static str,
    /// The plausible range [lo, hi] of the value (beyond it the physics means nothing, or the
    /// integration cannot follow it); the checks of [`PlantConfig::validate`] narrow some further.
    range: (f64, f64),
}

/// Upper bound on the size of a plant configuration file, checked as it is read (1 MiB; the default
/// configuration is about 3 KB).
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

impl PlantConfig {
    /// Reads a TOML file: keys not given keep their defaults, unknown keys are an error naming the key,
    /// and the values are checked with [`PlantConfig::validate`].
    pub fn from_toml_file(path: &Path) -> Result<Self, IpaError> {
        let text = sysid_core::data::bounded::read_bounded_text(
            path,
            MAX_CONFIG_BYTES,
            "a plant configuration",
            "expected a TOML file such as `ipa-sysid plant-config` prints",
        )
        .map_err(|e| match e {
            // A file that cannot be opened stays an I/O error, as for every input file (Python:
            // OSError, docs/python.md; audit s13 L9).
            sysid_core::SysidError::Io { .. } => IpaError::Sysid(e),
            e => IpaError::Config(format!("cannot read plant config: {e}")),
        })?;
        Self::from_toml_str(&text, &path.display().to_string())
    }

    /// Parses TOML text (`name` is used in messages) and validates it; a value out of range is reported
    /// at its line and column in the text (`name:LINE:COLUMN: invalid plant config load.moving_mass_kg
    /// = 1e308: expected ...`) when the key is written there.
    ///
    /// A text with no setting at all (empty, blank or comments only) is refused: keys left out keep
    /// their defaults, but a file with none is a failed copy or a cut-off write far more often than a
    /// request for the default plant, which leaving the configuration out gives (audit s35 M-1: an
    /// empty twin file was tuned on as "twin empty.toml", silently the default plant).
    pub fn from_toml_str(text: &str, name: &str) -> Result<Self, IpaError> {
        if text.lines().all(|l| {
            let t = l.trim();
            t.is_empty() || t.starts_with('#')
        }) {
            return Err(IpaError::Config(format!(
                "{name}: the file holds no setting (it is empty, blank or comments only): expected the \
                 TOML settings of the physics plant, as `ipa-sysid plant-config` or `ipa-sysid \
                 calibrate --out` write them (keys left out keep their defaults; for the default plant, \
                 give no plant configuration)"
            )));
        }
        let cfg: PlantConfig = toml::from_str(text).map_err(|e| {
            // A model file, controller file, JSON document or CSV record given as the plant
            // configuration is said as such, not as the TOML parser's complaint (the readers' one
            // sniffing helper; only when the text is not TOML, so a valid file is never refused).
            use sysid_core::data::Sniffed;
            let head = &text.as_bytes()[..text.len().min(4096)];
            match Sniffed::of(head) {
                Some(k) if k != Sniffed::Toml => IpaError::Config(format!(
                    "{name}: this is {}, not a plant configuration (the TOML that `ipa-sysid \
                     plant-config` prints)",
                    k.describe()
                )),
                // The parser's snippet quotes the file's line: printed through `visible_lines`.
                _ => IpaError::Config(format!(
                    "{name}: invalid plant config: {}",
                    sysid_core::format::visible_lines(&e.to_string())
                )),
            }
        })?;
        cfg.check().map_err(|e| {
            IpaError::Config(match locate(text, e.section, e.key) {
                Some((line, column)) => format!("{name}:{line}:{column}: {}", e.message),
                None => format!("{name}: {}", e.message),
            })
        })?;
        Ok(cfg)
    }

    /// The warnings of the calibration that wrote this twin ([`CalibrationNote::warnings`]), each
    /// prefixed by the record and the twin's free-run fit, for a command that runs on the twin to
    /// repeat (`tune --plant-config`, `control --plant-config`); empty for a configuration without a
    /// `[calibration]` table or whose calibration gave none.
    pub fn calibration_warnings(&self) -> Vec<String> {
        let Some(note) = &self.calibration else {
            return Vec::new();
        };
        let fit = |f: Option<f64>| f.map_or("-".to_string(), |f| format!("{f:.2} %"));
        let mut fits = format!("free-run fit {} on it", fit(note.fit_estimation_percent));
        if note.fit_validation_percent.is_some() {
            fits.push_str(&format!(
                ", {} on the validation record",
                fit(note.fit_validation_percent)
            ));
        }
        note.warnings
            .iter()
            .map(|w| {
                format!(
                    "this twin's calibration on {} ({fits}) warned: {}",
                    sysid_core::format::visible(&note.record),
                    sysid_core::format::visible(w)
                )
            })
            .collect()
    }

    /// The largest net pneumatic forces on the piston (N): extending, the supply's gauge pressure on the
    /// bore's area π d²/4 against atmosphere; retracting, on the annulus π (d² − d_rod²)/4 (MPa × mm² =
    /// N).
    pub fn supply_forces_n(&self) -> (f64, f64) {
        let (d, r) = (self.cylinder.bore_mm, self.cylinder.rod_mm);
        let p = self.air.supply_gauge_mpa;
        let quarter_pi = std::f64::consts::FRAC_PI_4;
        (p * quarter_pi * d * d, p * quarter_pi * (d * d - r * r))
    }

    /// The valves' deadzone in PWM counts: a command |u| ≤ U_MAX · t_open / T (T =
    /// `valve.pwm_period_ms`, t_open = `valve.opening_delay_ms`) energises its valve for a pulse
    /// |u|/U_MAX · T no longer than the opening delay, so the valve never opens (10.2 counts with the
    /// defaults, 0.4 ms of 10 ms).
    pub fn valve_deadzone_counts(&self) -> f64 {
        crate::plant::U_MAX * self.valve.opening_delay_ms / self.valve.pwm_period_ms
    }

    /// F(u): the largest net driving force (N, + extends; `Dynamics::drive_force_n`, with the external
    /// load) that the command `u` (counts), applied for good, puts on a piston held still at `x_mm`:
    /// the peak over one PWM period of the periodic steady state. The pulsed chamber (cap side for
    /// u > 0, rod side for u < 0; the other exhausts to p_atm) is open to the supply from t_open to
    /// |u|/U_MAX · T + t_close of each period T (never inside the deadzone, always once the closing
    /// runs into the next period), and its pressure follows the plant's own chamber equation and ISO
    /// 6358 flow paths (`Dynamics::derivative` with the piston stuck), integrated by RK4 in 100 steps
    /// per valve phase from atmospheric pressure until the period's peak changes by less than 10⁻⁹ of
    /// itself (at most 60 s). Static friction F_s holds the piston for good when F ≤ F_s.
    pub fn held_drive_force_n(&self, u: f64, x_mm: f64) -> f64 {
        use crate::dynamics::{Dynamics, Mode, State, Valves};
        let d = Dynamics::new(self);
        let period = self.valve.pwm_period_ms * 1e-3;
        let (t_open, t_close) = (
            self.valve.opening_delay_ms * 1e-3,
            self.valve.closing_delay_ms * 1e-3,
        );
        let pulse = (u.abs() / crate::plant::U_MAX).min(1.0) * period;
        // The valve's phases in one period: (length s, open?).
        let phases: Vec<(f64, bool)> = if u == 0.0 || pulse <= t_open {
            vec![(period, false)]
        } else if pulse + t_close >= period {
            vec![(period, true)]
        } else {
            vec![
                (t_open, false),
                (pulse + t_close - t_open, true),
                (period - pulse - t_close, false),
            ]
        };
        let valves = |open: bool| Valves {
            cap: open && u > 0.0,
            rod: open && u < 0.0,
        };
        let x_m = (x_mm * 1e-3).clamp(0.0, d.cylinder.stroke_m);
        let mut s = State {
            x_m,
            v_m_s: 0.0,
            p_cap_pa: d.atmosphere_pa,
            p_rod_pa: d.atmosphere_pa,
        };
        let sign = if u < 0.0 { -1.0 } else { 1.0 };
        let mut last_peak = f64::NEG_INFINITY;
        let periods = (60.0 / period).ceil().max(1.0) as usize;
        for _ in 0..periods {
            let mut peak = sign * d.drive_force_n(&s);
            for &(len, open) in &phases {
                let h = len / 100.0;
                for _ in 0..100 {
                    s = d.rk4(&s, Mode::Stuck, valves(open), h);
                    peak = peak.max(sign * d.drive_force_n(&s));
                }
            }
            if (peak - last_peak).abs() <= 1e-9 * peak.abs().max(1e-3) {
                return sign * peak;
            }
            last_peak = peak;
        }
        sign * last_peak
    }

    /// The largest forces the commands `u` (counts) build up on a piston held at `x_mm`
    /// ([`Self::held_drive_force_n`]): (extending, retracting), N, each ≥ 0 (0 when no command pushes
    /// that way). The force grows with the duty, so the largest command each way gives it.
    pub fn largest_held_forces_n(&self, u: &[f64], x_mm: f64) -> (f64, f64) {
        let (lo, hi) = u
            .iter()
            .filter(|v| v.is_finite())
            .fold((0.0_f64, 0.0_f64), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        let extend = if hi > 0.0 {
            self.held_drive_force_n(hi, x_mm).max(0.0)
        } else {
            0.0
        };
        let retract = if lo < 0.0 {
            (-self.held_drive_force_n(lo, x_mm)).max(0.0)
        } else {
            0.0
        };
        (extend, retract)
    }

    /// Checks every value; the error names the key (`section.key`), the value and what is accepted.
    pub fn validate(&self) -> Result<(), IpaError> {
        self.check().map_err(|e| IpaError::Config(e.message))
    }

    /// [`PlantConfig::validate`], keeping the key of the value refused.
    fn check(&self) -> Result<(), Invalid> {
        for (section, entries) in self.sections() {
            for e in entries {
                if !e.value.is_finite() {
                    return Err(bad(section, e.key, e.value, "a finite number"));
                }
                let (lo, hi) = e.range;
                if !(lo..=hi).contains(&e.value) {
                    return Err(bad(
                        section,
                        e.key,
                        e.value,
                        &format!("a value in the plausible range [{lo:?}, {hi:?}] (docs/plant.md)"),
                    ));
                }
            }
        }
        let c = &self.cylinder;
        pos("cylinder", "bore_mm", c.bore_mm)?;
        nonneg("cylinder", "rod_mm", c.rod_mm)?;
        if c.rod_mm >= c.bore_mm {
            return Err(bad(
                "cylinder",
                "rod_mm",
                c.rod_mm,
                "a rod diameter smaller than cylinder.bore_mm",
            ));
        }
        // A rod almost as wide as the bore leaves an annulus the retracting air cannot push on (audit
        // s23 L-B4: rod 39.999 mm in a 40 mm bore, a 0.06 mm² annulus, was accepted).
        if c.rod_mm > MAX_ROD_RATIO * c.bore_mm {
            return Err(bad(
                "cylinder",
                "rod_mm",
                c.rod_mm,
                &format!(
                    "a rod of at most {MAX_ROD_RATIO} × cylinder.bore_mm = {:.4} mm (an annulus of at \
                     least {:.0} % of the bore's area; ISO 15552 and ISO 6432 cylinders have rod/bore \
                     <= 0.5)",
                    MAX_ROD_RATIO * c.bore_mm,
                    100.0 * (1.0 - MAX_ROD_RATIO * MAX_ROD_RATIO)
                ),
            ));
        }
        pos("cylinder", "stroke_mm", c.stroke_mm)?;
        // The error tolerance and the volumes scale with the stroke and the bore: beyond any
        // pneumatic cylinder (rodless ones reach about 10 m) they stop meaning anything.
        if c.stroke_mm > MAX_STROKE_MM {
            return Err(bad(
                "cylinder",
                "stroke_mm",
                c.stroke_mm,
                &format!("a stroke of at most {MAX_STROKE_MM} mm"),
            ));
        }
        if c.bore_mm > MAX_BORE_MM {
            return Err(bad(
                "cylinder",
                "bore_mm",
                c.bore_mm,
                &format!("a bore of at most {MAX_BORE_MM} mm"),
            ));
        }
        pos("cylinder", "dead_volume_cap_cm3", c.dead_volume_cap_cm3)?;
        pos("cylinder", "dead_volume_rod_cm3", c.dead_volume_rod_cm3)?;
        let a = &self.air;
        pos("air", "supply_gauge_mpa", a.supply_gauge_mpa).map_err(|_| {
            bad(
                "air",
                "supply_gauge_mpa",
                a.supply_gauge_mpa,
                "a supply pressure above atmosphere (gauge > 0)",
            )
        })?;
        pos("air", "atmosphere_pa", a.atmosphere_pa)?;
        pos("air", "temperature_k", a.temperature_k)?;
        if !(a.heat_capacity_ratio > 1.0 && a.heat_capacity_ratio <= 5.0 / 3.0) {
            return Err(bad(
                "air",
                "heat_capacity_ratio",
                a.heat_capacity_ratio,
                "a value in (1, 5/3]",
            ));
        }
        pos("air", "gas_constant_j_kg_k", a.gas_constant_j_kg_k)?;
        for (key, v) in [
            ("exponent_charging", a.exponent_charging),
            ("exponent_discharging", a.exponent_discharging),
            ("exponent_volume", a.exponent_volume),
        ] {
            if !(1.0..=a.heat_capacity_ratio).contains(&v) {
                return Err(bad("air", key, v, "a polytropic exponent between 1 (isothermal) and air.heat_capacity_ratio (adiabatic)"));
            }
        }
        let v = &self.valve;
        nonneg(
            "valve",
            "supply_conductance_dm3_s_bar",
            v.supply_conductance_dm3_s_bar,
        )?;
        nonneg(
            "valve",
            "exhaust_conductance_dm3_s_bar",
            v.exhaust_conductance_dm3_s_bar,
        )?;
        if !(v.critical_pressure_ratio >= 0.0 && v.critical_pressure_ratio < 1.0) {
            return Err(bad(
                "valve",
                "critical_pressure_ratio",
                v.critical_pressure_ratio,
                "a ratio in [0, 1)",
            ));
        }
        if !(v.laminar_pressure_ratio > v.critical_pressure_ratio && v.laminar_pressure_ratio < 1.0)
        {
            return Err(bad(
                "valve",
                "laminar_pressure_ratio",
                v.laminar_pressure_ratio,
                "a ratio above valve.critical_pressure_ratio and below 1",
            ));
        }
        pos("valve", "pwm_period_ms", v.pwm_period_ms)?;
        nonneg("valve", "opening_delay_ms", v.opening_delay_ms)?;
        nonneg("valve", "closing_delay_ms", v.closing_delay_ms)?;
        for (key, d) in [
            ("opening_delay_ms", v.opening_delay_ms),
            ("closing_delay_ms", v.closing_delay_ms),
        ] {
            if d >= v.pwm_period_ms {
                return Err(bad(
                    "valve",
                    key,
                    d,
                    "a delay shorter than valve.pwm_period_ms",
                ));
            }
        }
        pos("load", "moving_mass_kg", self.load.moving_mass_kg)?;
        let f = &self.friction;
        nonneg("friction", "static_n", f.static_n)?;
        nonneg("friction", "coulomb_n", f.coulomb_n)?;
        if f.coulomb_n > f.static_n {
            return Err(bad(
                "friction",
                "coulomb_n",
                f.coulomb_n,
                "a Coulomb friction not above friction.static_n",
            ));
        }
        // Static friction the supply cannot overcome on either side: the piston never moves and every
        // later word would blame the command (audit s23 L-B4: 5000 N against 754 N).
        let (extend_n, retract_n) = self.supply_forces_n();
        if f.static_n >= retract_n.min(extend_n) {
            return Err(bad(
                "friction",
                "static_n",
                f.static_n,
                &format!(
                    "a static friction below the largest force the supply can put on the piston in \
                     each direction: air.supply_gauge_mpa = {} MPa on the bore (cylinder.bore_mm = {} \
                     mm) gives {extend_n:.1} N extending and on the annulus (cylinder.rod_mm = {} mm) \
                     {retract_n:.1} N retracting; with this friction the piston could not start to move",
                    a.supply_gauge_mpa, c.bore_mm, c.rod_mm
                ),
            ));
        }
        pos(
            "friction",
            "stribeck_velocity_mm_s",
            f.stribeck_velocity_mm_s,
        )?;
        nonneg("friction", "viscous_n_s_m", f.viscous_n_s_m)?;
        pos("encoder", "resolution_mm", self.encoder.resolution_mm)?;
        let tol = self.integration.tolerance;
        if !(1e-14..=1e-3).contains(&tol) {
            return Err(bad(
                "integration",
                "tolerance",
                tol,
                "a local error tolerance in [1e-14, 1e-3]",
            ));
        }
        let h = self.integration.max_substep_ms;
        if !(h > 0.0 && h <= v.pwm_period_ms) {
            return Err(bad(
                "integration",
                "max_substep_ms",
                h,
                "a positive step not longer than valve.pwm_period_ms",
            ));
        }
        let hs = self.integration.slow_substep_ms;
        if !(hs > 0.0 && hs <= h) {
            return Err(bad(
                "integration",
                "slow_substep_ms",
                hs,
                "a positive step not longer than integration.max_substep_ms",
            ));
        }
        nonneg(
            "integration",
            "slow_speed_mm_s",
            self.integration.slow_speed_mm_s,
        )?;
        Ok(())
    }

    /// The configuration as TOML with a comment on every key giving its unit and source (the output of
    /// `ipa-sysid plant-config`). Parsing it back gives the same configuration.
    pub fn to_commented_toml(&self) -> String {
        let mut s = String::from(
            "# Physics IPA plant parameters (ipa-sysid plant-config).\n\
             # Edit and pass with --plant-config FILE; keys left out keep their defaults, unknown keys are refused.\n\
             # Sources: paper Table I/II, ISO 6358, Richer & Hurmuzlu (2000); 'estimate' marks engineering\n\
             # estimates calibrated as explained in docs/plant.md.\n",
        );
        for (section, entries) in self.sections() {
            s.push_str(&format!("\n[{section}]\n"));
            for e in entries {
                s.push_str(&format!("{} = {:?}  # {}\n", e.key, e.value, e.doc));
            }
        }
        if let Some(note) = &self.calibration {
            #[derive(Serialize)]
            struct Table<'a> {
                calibration: &'a CalibrationNote,
            }
            // The toml crate quotes the record's path and the warnings; a note that cannot be
            // written (it always can: strings and finite numbers) is left out rather than corrupt.
            if let Ok(t) = toml::to_string(&Table { calibration: note }) {
                s.push_str(
                    "\n# What `ipa-sysid calibrate` said of this twin; tune and control repeat its warnings.\n",
                );
                s.push_str(&t);
            }
        }
        s
    }

    fn sections(&self) -> Vec<(&'static str, Vec<Entry>)> {
        let e = |key, value, doc, range| Entry {
            key,
            value,
            doc,
            range,
        };
        let c = &self.cylinder;
        let a = &self.air;
        let v = &self.valve;
        let f = &self.friction;
        vec![
            (
                "cylinder",
                vec![
                    e("bore_mm", c.bore_mm, "bore D, mm (paper Table II)", (1.0, MAX_BORE_MM)),
                    e("rod_mm", c.rod_mm, "rod diameter d, mm (Table II); rod side is the smaller area", (0.0, MAX_BORE_MM)),
                    e("stroke_mm", c.stroke_mm, "stroke L, mm (Table II); end stops at 0 and L", (1.0, MAX_STROKE_MM)),
                    e("dead_volume_cap_cm3", c.dead_volume_cap_cm3, "cap-side dead volume, cm^3 (estimate: end cap + port + 0.5 m of 4 mm tube)", (1e-3, 1e5)),
                    e("dead_volume_rod_cm3", c.dead_volume_rod_cm3, "rod-side dead volume, cm^3 (estimate, as cap side)", (1e-3, 1e5)),
                ],
            ),
            (
                "air",
                vec![
                    e("supply_gauge_mpa", a.supply_gauge_mpa, "supply pressure above atmosphere, MPa (Table II: 0.6 MPa)", (0.01, 10.0)),
                    e("atmosphere_pa", a.atmosphere_pa, "exhaust/atmospheric pressure, Pa (standard atmosphere)", (1e4, 2e5)),
                    e("temperature_k", a.temperature_k, "air temperature T, K (Table II, ISO 6358)", (150.0, 500.0)),
                    e("heat_capacity_ratio", a.heat_capacity_ratio, "specific heat ratio k (Table II)", (1.0, 5.0 / 3.0)),
                    e("gas_constant_j_kg_k", a.gas_constant_j_kg_k, "gas constant R of air, J/(kg K)", (50.0, 5000.0)),
                    e("exponent_charging", a.exponent_charging, "polytropic exponent of charging alpha_in (Richer & Hurmuzlu 2000: k)", (1.0, 5.0 / 3.0)),
                    e("exponent_discharging", a.exponent_discharging, "polytropic exponent of discharging alpha_out (Richer & Hurmuzlu 2000: 1)", (1.0, 5.0 / 3.0)),
                    e("exponent_volume", a.exponent_volume, "polytropic exponent of the volume term alpha (Richer & Hurmuzlu 2000: 1.2)", (1.0, 5.0 / 3.0)),
                ],
            ),
            (
                "valve",
                vec![
                    e("supply_conductance_dm3_s_bar", v.supply_conductance_dm3_s_bar, "ISO 6358 sonic conductance C supply -> chamber, dm^3/(s bar) ANR (estimate for a 10 mm wide solenoid valve, ~1 mm orifice; sets the full-command speed)", (0.0, 100.0)),
                    e("exhaust_conductance_dm3_s_bar", v.exhaust_conductance_dm3_s_bar, "ISO 6358 sonic conductance C chamber -> exhaust, dm^3/(s bar) ANR (estimate; larger than the supply path, which makes retracting faster than extending as in the paper's model)", (0.0, 100.0)),
                    e("critical_pressure_ratio", v.critical_pressure_ratio, "ISO 6358 critical pressure ratio b (estimate, typical of small solenoid valves)", (0.0, 1.0)),
                    e("laminar_pressure_ratio", v.laminar_pressure_ratio, "above this pressure ratio the flow is linear in the pressure difference (numerical regularisation)", (0.0, 1.0)),
                    e("pwm_period_ms", v.pwm_period_ms, "PWM period, ms (estimate: one period per sample Ts = 10 ms); duty = |u|/255, latched at each period start", (0.01, 1000.0)),
                    e("opening_delay_ms", v.opening_delay_ms, "valve opening delay, ms (estimate; with the PWM period it sets the deadzone)", (0.0, 1000.0)),
                    e("closing_delay_ms", v.closing_delay_ms, "valve closing delay, ms (estimate)", (0.0, 1000.0)),
                ],
            ),
            (
                "load",
                vec![
                    e("moving_mass_kg", self.load.moving_mass_kg, "piston + 16 mm steel rod + encoder strip, kg (estimate)", (1e-3, 1e4)),
                    e("external_force_n", self.load.external_force_n, "constant external force on the rod, N, + extends (Table II: ambient force 0 N)", (-1e6, 1e6)),
                ],
            ),
            (
                "friction",
                vec![
                    e("static_n", f.static_n, "breakaway (static) friction F_s, N (estimate for 40 mm bore seals)", (0.0, 1e5)),
                    e("coulomb_n", f.coulomb_n, "Coulomb friction F_c, N (estimate)", (0.0, 1e5)),
                    e("stribeck_velocity_mm_s", f.stribeck_velocity_mm_s, "Stribeck velocity v_s, mm/s (estimate)", (1e-3, 1e4)),
                    e("viscous_n_s_m", f.viscous_n_s_m, "viscous friction sigma, N s/m (estimate)", (0.0, 1e6)),
                ],
            ),
            ("encoder", vec![e("resolution_mm", self.encoder.resolution_mm, "encoder resolution, mm per count (issue 3: 0.01 mm)", (1e-6, 10.0))]),
            (
                "integration",
                vec![
                    e("tolerance", self.integration.tolerance, "local error tolerance of the adaptive Dormand-Prince steps, relative to stroke, 1 m/s (1 + |v|/v_s) and 0.2 supply pressure (tests/accuracy.rs)", (1e-14, 1e-3)),
                    e("max_substep_ms", self.integration.max_substep_ms, "largest substep of the RK4 reference integrator, ms (cut at valve switching instants)", (1e-6, 1000.0)),
                    e("slow_substep_ms", self.integration.slow_substep_ms, "largest RK4 reference substep while sliding slowly (Stribeck region), ms", (1e-6, 1000.0)),
                    e("slow_speed_mm_s", self.integration.slow_speed_mm_s, "speed below which slow_substep_ms applies, mm/s (4 Stribeck velocities)", (0.0, 1e5)),
                ],
            ),
        ]
    }
}

/// The longest stroke a plant configuration accepts, mm (10 m: beyond any pneumatic cylinder).
pub const MAX_STROKE_MM: f64 = 10_000.0;

/// The largest bore a plant configuration accepts, mm (1 m).
pub const MAX_BORE_MM: f64 = 1_000.0;

/// The widest rod accepted, as a fraction of the bore (an annulus of at least 19 % of the bore's area).
pub const MAX_ROD_RATIO: f64 = 0.9;

/// A value [`PlantConfig::check`] refuses: its section, key, and the message.
struct Invalid {
    section: &'static str,
    key: &'static str,
    message: String,
}

/// The refusal of `section.key = value`; the value is printed as Rust's `{:?}` does (shortest exact
/// digits, exponent form for very large or small values: `1e308`, not 309 digits).
fn bad(section: &'static str, key: &'static str, value: f64, expected: &str) -> Invalid {
    Invalid {
        section,
        key,
        message: format!("invalid plant config {section}.{key} = {value:?}: expected {expected}"),
    }
}

/// Line and column (1-based) of `key` of table `[section]` in TOML `text`: a `key =` line inside the
/// section's table, or a `section.key =` line before any table; `None` when the key is not written
/// (a default that another value made invalid) or is written in another form (an inline table).
fn locate(text: &str, section: &str, key: &str) -> Option<(usize, usize)> {
    let mut current: Option<String> = None;
    let dotted = format!("{section}.{key}");
    for (i, line) in text.lines().enumerate() {
        let t = line.trim_start();
        let column = line.len() - t.len() + 1;
        if let Some(rest) = t.strip_prefix('[') {
            current = rest.split(']').next().map(|h| h.trim().to_string());
            continue;
        }
        let lhs = match t.split_once('=') {
            Some((lhs, _)) => lhs.trim().trim_matches('"'),
            None => continue,
        };
        let hit = match current.as_deref() {
            Some(sec) => sec == section && lhs == key,
            None => lhs.replace(' ', "") == dotted,
        };
        if hit {
            return Some((i + 1, column));
        }
    }
    None
}

fn pos(section: &'static str, key: &'static str, value: f64) -> Result<(), Invalid> {
    if value > 0.0 {
        Ok(())
    } else {
        Err(bad(section, key, value, "a positive number"))
    }
}

fn nonneg(section: &'static str, key: &'static str, value: f64) -> Result<(), Invalid> {
    if value >= 0.0 {
        Ok(())
    } else {
        Err(bad(section, key, value, "a number >= 0"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Audit s22 M-B5: the TOML parser's error quotes the file's line; an ESC (a terminal escape that
    // clears the screen) and a right-to-left override in it are printed as visible escapes, the
    // message's own line breaks kept.
    #[test]
    fn the_toml_errors_snippet_line_is_printed_visibly() {
        let text = "[cylinder]\nbore_mm = \"a\u{1b}[2Jb\u{202e}\"\n";
        let e = PlantConfig::from_toml_str(text, "T3.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("T3.toml: invalid plant config"), "{e}");
        assert!(e.contains("a\\u{1b}[2Jb\\u{202e}"), "{e}");
        assert!(!e.contains('\u{1b}') && !e.contains('\u{202e}'), "{e}");
        assert!(e.lines().count() > 1, "{e}");
    }

    // Printing then parsing is the identity, also for non-default values (so every key is printed).
    #[test]
    fn commented_toml_parses_back_to_the_same_config() {
        let d = PlantConfig::default();
        assert_eq!(
            PlantConfig::from_toml_str(&d.to_commented_toml(), "t").unwrap(),
            d
        );
        let mut c = PlantConfig::default();
        c.cylinder.bore_mm = 50.0;
        c.cylinder.dead_volume_rod_cm3 = 3.5;
        c.air.exponent_volume = 1.3;
        c.valve.closing_delay_ms = 0.9;
        c.load.external_force_n = -12.0;
        c.friction.viscous_n_s_m = 7.0;
        c.encoder.resolution_mm = 0.005;
        c.integration.tolerance = 3e-9;
        c.integration.max_substep_ms = 0.2;
        c.integration.slow_substep_ms = 0.1;
        c.integration.slow_speed_mm_s = 12.0;
        assert_eq!(
            PlantConfig::from_toml_str(&c.to_commented_toml(), "t").unwrap(),
            c
        );
    }

    #[test]
    fn a_calibration_note_survives_the_round_trip_and_is_repeated() {
        let mut c = PlantConfig::default();
        assert!(c.calibration_warnings().is_empty());
        c.calibration = Some(CalibrationNote {
            record: "dir/a \"b\".csv".into(),
            ts_s: Some(0.01),
            fit_estimation_percent: Some(-3.5),
            fit_validation_percent: None,
            warnings: vec!["do not use it".into(), "second\nline".into()],
        });
        let back = PlantConfig::from_toml_str(&c.to_commented_toml(), "t").unwrap();
        assert_eq!(back, c);
        let w = back.calibration_warnings();
        assert_eq!(w.len(), 2);
        assert!(
            w[0].contains("-3.50 %") && w[0].ends_with("do not use it"),
            "{w:?}"
        );
        // A note with a key it does not know is refused like any section.
        for empty in ["", " \n\n \t\n", "# a comment\n\n#another\n"] {
            let e = PlantConfig::from_toml_str(empty, "twin.toml")
                .unwrap_err()
                .to_string();
            assert!(e.contains("twin.toml: the file holds no setting"), "{e}");
        }
        // One key is a configuration (the rest defaults).
        assert!(PlantConfig::from_toml_str("# c\n[load]\nmoving_mass_kg = 2.0\n", "t").is_ok());
        let e = PlantConfig::from_toml_str("[calibration]\nfit = 1.0\n", "t").unwrap_err();
        assert!(e.to_string().contains("fit"), "{e}");
    }

    #[test]
    fn a_partial_file_keeps_the_other_defaults() {
        let c = PlantConfig::from_toml_str("[load]\nmoving_mass_kg = 2.0\n", "t").unwrap();
        assert_eq!(c.load.moving_mass_kg, 2.0);
        assert_eq!(c.cylinder, CylinderConfig::default());
    }

    #[test]
    fn an_unknown_key_is_an_error_naming_it() {
        let e = PlantConfig::from_toml_str("[cylinder]\nbore_diameter = 40.0\n", "cfg.toml")
            .unwrap_err();
        let m = e.to_string();
        assert!(m.contains("bore_diameter") && m.contains("cfg.toml"), "{m}");
        let e = PlantConfig::from_toml_str("[pump]\nx = 1.0\n", "cfg.toml").unwrap_err();
        assert!(e.to_string().contains("pump"), "{e}");
    }

    #[test]
    fn invalid_values_are_refused_with_the_key() {
        for (toml, key) in [
            ("[load]\nmoving_mass_kg = -1.0\n", "load.moving_mass_kg"),
            ("[air]\nsupply_gauge_mpa = -0.05\n", "air.supply_gauge_mpa"),
            ("[cylinder]\nrod_mm = 45.0\n", "cylinder.rod_mm"),
            ("[friction]\ncoulomb_n = 40.0\n", "friction.coulomb_n"),
            (
                "[valve]\nopening_delay_ms = 12.0\n",
                "valve.opening_delay_ms",
            ),
            ("[air]\nexponent_volume = 2.0\n", "air.exponent_volume"),
            ("[encoder]\nresolution_mm = 0.0\n", "encoder.resolution_mm"),
            ("[cylinder]\nbore_mm = nan\n", "cylinder.bore_mm"),
            ("[integration]\ntolerance = 0.0\n", "integration.tolerance"),
            ("[integration]\ntolerance = 0.01\n", "integration.tolerance"),
            ("[cylinder]\nstroke_mm = 1e308\n", "cylinder.stroke_mm"),
            ("[cylinder]\nbore_mm = 2000.0\n", "cylinder.bore_mm"),
        ] {
            let e = PlantConfig::from_toml_str(toml, "t")
                .unwrap_err()
                .to_string();
            assert!(e.contains(key), "{toml}: {e}");
        }
        let e =
            PlantConfig::from_toml_str("[load]\nmoving_mass_kg = \"heavy\"\n", "t").unwrap_err();
        assert!(e.to_string().contains("moving_mass_kg"), "{e}");
    }
    // Audit s23 L-B4. The default cylinder (bore 40 mm, rod 16 mm, 0.6 MPa gauge) can push
    // 0.6 × π/4 × 40² = 753.98 N extending and 0.6 × π/4 × (40² − 16²) = 633.35 N retracting (by hand).
    // A static friction at or above the smaller force is refused, naming both keys and both figures;
    // just below it is accepted. A rod wider than 0.9 × the bore (36 mm) is refused; 36 mm is accepted.
    #[test]
    fn friction_beyond_the_supply_force_and_a_thin_annulus_are_refused() {
        let (ext, ret) = PlantConfig::default().supply_forces_n();
        assert!(
            (ext - 753.982).abs() < 1e-3 && (ret - 633.345).abs() < 1e-3,
            "{ext} {ret}"
        );
        for friction in ["static_n = 5000.0", "static_n = 700.0", "static_n = 633.4"] {
            let toml = format!("[friction]\n{friction}\n");
            let e = PlantConfig::from_toml_str(&toml, "t")
                .unwrap_err()
                .to_string();
            for needle in [
                "friction.static_n",
                "air.supply_gauge_mpa",
                "754.0 N",
                "633.3 N",
            ] {
                assert!(e.contains(needle), "{toml}: {e}");
            }
        }
        assert!(PlantConfig::from_toml_str("[friction]\nstatic_n = 633.0\n", "t").is_ok());
        let e = PlantConfig::from_toml_str("[cylinder]\nrod_mm = 39.999\n", "t")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("cylinder.rod_mm") && e.contains("36.0000 mm"),
            "{e}"
        );
        assert!(PlantConfig::from_toml_str("[cylinder]\nrod_mm = 36.0\n", "t").is_ok());
    }

    // Closed forms of the held force: a valve open all the time (|u| = 255) brings its chamber to
    // the supply, so F = p_gauge · A: 0.6 MPa · π/4 · 40² mm² = 753.98 N extending and · π/4 ·
    // (40² − 16²) = 633.35 N retracting (`supply_forces_n`); inside the deadzone (|u| ≤ 255 · 0.4 /
    // 10 = 10.2 counts) no valve opens and F = 0; between, F grows with |u| and stays inside.
    #[test]
    fn the_held_force_has_its_closed_forms_at_the_ends() {
        let cfg = PlantConfig::default();
        let q = std::f64::consts::FRAC_PI_4;
        let (ext, ret) = (0.6 * q * 1600.0, 0.6 * q * (1600.0 - 256.0));
        assert!((cfg.valve_deadzone_counts() - 10.2).abs() < 1e-12);
        let f = |u: f64| cfg.held_drive_force_n(u, 100.0);
        assert!((f(255.0) - ext).abs() < 1e-6 * ext, "{}", f(255.0));
        assert!((f(-255.0) + ret).abs() < 1e-6 * ret, "{}", f(-255.0));
        // Atmosphere on both sides: p_atm (A_a − A_b − (A_a − A_b)) = 0 to rounding (10⁻⁹ N).
        assert!(
            f(10.0).abs() < 1e-9 && f(-10.0).abs() < 1e-9,
            "{} {}",
            f(10.0),
            f(-10.0)
        );
        let mut last = 0.0;
        for u in [20.0, 60.0, 120.0, 200.0, 250.0] {
            assert!(f(u) > last && f(u) < ext, "{u}: {}", f(u));
            last = f(u);
        }
        assert_eq!(
            cfg.largest_held_forces_n(&[3.0, -40.0, 255.0], 100.0),
            (f(255.0), -f(-40.0))
        );
        assert_eq!(cfg.largest_held_forces_n(&[5.0, 7.0], 100.0).1, 0.0);
    }
}
