//! Covariance windup and its protection for recursive least squares with forgetting.
//!
//! With exponential forgetting ρ < 1 the RLS covariance obeys P(k) = [P − Pφφᵀ P/(ρ + φᵀPφ)]/ρ. In a
//! direction that φ(k) does not excite, only the division by ρ acts: P grows like ρ^(−k) and overflows
//! after about ln(10^308 / p0) / ln(1/ρ) samples (≈ 34 400 samples at ρ = 0.98, p0 = 10^6), after which the
//! estimator returns NaN. This happens whenever the input stops exciting the plant (a controller holding a
//! set-point, a stopped machine). Two protections are offered (`--windup`):
//!
//! - `trace`: after every update, if tr P > T (`--max-trace`, default p0 · n, the initial trace), P is scaled
//!   by T / tr P. Simple and always bounded, but it also shrinks the directions that are excited.
//! - `directional` (Kulhavý's directional forgetting): forgetting acts only along the direction being
//!   measured. With r = φᵀPφ > 0 the information matrix R = P⁻¹ is first reduced along φ,
//!   R̃ = R − (1 − ρ) φφᵀ / r (so that the variance of φᵀθ grows from r to r/ρ, and nothing changes in the
//!   P-orthogonal directions), then the measurement is added, R(k) = R̃ + φφᵀ. In covariance form
//!   (Sherman–Morrison twice), with p = Pφ:
//!   ```text
//!   L(k) = p / (ρ + r)                                (the same gain as ordinary RLS)
//!   P(k) = P − γ p pᵀ,  γ = (ρ − 1 + r) / (r (ρ + r))
//!   ```
//!   Without excitation (φ = 0) nothing changes; with a constant φ the information along φ converges to a
//!   finite level and P stays bounded.

use serde::{Deserialize, Serialize};

/// Windup protection (`--windup`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Windup {
    /// Ordinary exponential forgetting (the paper's eq. 12).
    #[default]
    None,
    /// Bounded trace: P is scaled down whenever tr P exceeds `--max-trace`.
    Trace,
    /// Directional forgetting (Kulhavý): forget only along the measured direction φ.
    Directional,
}

impl std::fmt::Display for Windup {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Windup::None => "none",
            Windup::Trace => "trace",
            Windup::Directional => "directional",
        })
    }
}

/// Below this value of r = φᵀPφ no directional forgetting is applied (φ is numerically zero).
pub const MIN_EXCITATION: f64 = 1e-200;

/// γ of the directional-forgetting covariance update P(k) = P − γ p pᵀ (see the module docs), for
/// forgetting ρ and r = φᵀPφ > 0.
#[inline]
pub fn directional_gamma(rho: f64, r: f64) -> f64 {
    (rho - 1.0 + r) / (r * (rho + r))
}

#[cfg(test)]
mod tests {
    use super::*;

    // One-dimensional check: P = 2, φ = 1, ρ = 0.5. R = 0.5; R̃ = R − (1 − ρ)/r = 0.5 − 0.5/2 = 0.25;
    // R(k) = 1.25 → P(k) = 0.8 = P − γ p² with p = 2, so γ = (2 − 0.8) / 4 = 0.3.
    #[test]
    fn directional_gamma_matches_the_information_form_in_one_dimension() {
        let g = directional_gamma(0.5, 2.0);
        assert!((g - 0.3).abs() < 1e-15, "{g}");
    }
}
