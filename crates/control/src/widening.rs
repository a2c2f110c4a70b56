//! A plant whose valve deadzone widens during a run (`control --deadzone-change AT_S:WIDEN`), to show
//! what a fixed deadzone compensator leaves and what an adaptive one recovers.
//!
//! From time `at_s` on, the command u passes through an extra deadzone of half-width Δ = `widen_counts`
//! with unit slope before it reaches the plant:
//!
//! ```text
//! u' = u − Δ  for u > Δ,     u' = 0  for |u| ≤ Δ,     u' = u + Δ  for u < −Δ
//! ```
//!
//! For a plant whose valve is the deadzone (b_l, b_r, m_l, m_r) of paper eq. (1) this is exactly the
//! deadzone (b_l − Δ, b_r + Δ, m_l, m_r): f(u') = m_r (u − Δ − b_r) for u ≥ b_r + Δ. The plant's state
//! (positions, pressures) carries over: only its input map changes.

use std::str::FromStr;

use sysid_core::{Plant, PlantError};

/// When and by how much the deadzone widens.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DeadzoneChange {
    /// Time of the change, s (from the start of the run).
    pub at_s: f64,
    /// Δ: counts added to each breakpoint (b_r + Δ, b_l − Δ), ≥ 0.
    pub widen_counts: f64,
}

impl FromStr for DeadzoneChange {
    type Err = String;
    /// `AT_S:WIDEN_COUNTS`, e.g. `30:20` (at 30 s, 20 counts wider on each side).
    fn from_str(s: &str) -> Result<Self, String> {
        let expected =
            "expected AT_S:WIDEN_COUNTS, e.g. 30:20 (at t = 30 s the deadzone gets 20 counts \
                        wider on each side; both finite and >= 0)";
        let (a, w) = s.split_once(':').ok_or_else(|| expected.to_string())?;
        let at_s: f64 = a.trim().parse().map_err(|_| expected.to_string())?;
        let widen_counts: f64 = w.trim().parse().map_err(|_| expected.to_string())?;
        if !(at_s.is_finite() && at_s >= 0.0 && widen_counts.is_finite() && widen_counts >= 0.0) {
            return Err(expected.to_string());
        }
        Ok(DeadzoneChange { at_s, widen_counts })
    }
}

/// `inner` with the deadzone change applied to its input (see the module documentation).
pub struct Widened {
    inner: Box<dyn Plant + Send>,
    change: DeadzoneChange,
    /// Samples stepped since the last reset.
    k: usize,
}

impl Widened {
    /// Wraps `inner`.
    pub fn new(inner: Box<dyn Plant + Send>, change: DeadzoneChange) -> Self {
        Widened {
            inner,
            change,
            k: 0,
        }
    }

    /// The extra input map u → u' at sample k.
    pub fn input_map(&self, k: usize, u: f64) -> f64 {
        let d = self.change.widen_counts;
        if (k as f64) * self.inner.ts() + 1e-9 < self.change.at_s {
            u
        } else if u > d {
            u - d
        } else if u < -d {
            u + d
        } else {
            0.0
        }
    }
}

impl Plant for Widened {
    fn ts(&self) -> f64 {
        self.inner.ts()
    }
    fn output(&self) -> f64 {
        self.inner.output()
    }
    fn step(&mut self, u: f64) -> Result<f64, PlantError> {
        let v = self.input_map(self.k, u);
        self.k += 1;
        self.inner.step(v)
    }
    fn reset(&mut self, y0_mm: f64) {
        self.k = 0;
        self.inner.reset(y0_mm);
    }
    fn name(&self) -> String {
        format!(
            "{} (deadzone {} counts wider from t = {} s)",
            self.inner.name(),
            // %g form: a 1e300 widening is not 300 digits (audit s32 L-6).
            sysid_core::format::Shortest(self.change.widen_counts),
            sysid_core::format::Shortest(self.change.at_s)
        )
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use sysid_core::{Model, ModelPlant};

    // Before the change the plant is untouched; after it, u = 30 through Δ = 20 reaches the paper's valve
    // as 10 counts: x = m_r (10 − 1.41) = 2.38 · 15.67e-4 · 8.59, the first output step from rest.
    #[test]
    fn after_the_change_the_command_loses_the_extra_width() {
        let change: DeadzoneChange = "0.02:20".parse().unwrap();
        let inner = ModelPlant::new(Model::paper(), "paper").unwrap();
        let mut p = Widened::new(Box::new(inner), change);
        assert_eq!(p.input_map(1, 30.0), 30.0);
        assert_eq!(p.input_map(2, 30.0), 10.0);
        assert_eq!(p.input_map(2, -15.0), 0.0);
        assert_eq!(p.input_map(2, -25.0), -5.0);
        p.reset(0.0);
        p.step(0.0).unwrap();
        p.step(0.0).unwrap();
        let y = p.step(30.0).unwrap(); // k = 2: after the change
        assert!((y - 2.38 * 15.67e-4 * 8.59).abs() < 1e-12, "{y}");
        assert!("x:1".parse::<DeadzoneChange>().is_err());
        assert!("1:-1".parse::<DeadzoneChange>().is_err());
    }
}
