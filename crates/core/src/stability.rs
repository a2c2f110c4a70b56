//! The stability verdict of a model's linear block: one classification of its poles p_i (the roots of
//! A(z) = z^na + a_1 z^(na−1) + … + a_na), from which every command and API derives its words
//! (`identify`'s "Poles: … →" line and warning, `simulate`'s, `validate`'s, `response`'s DC gain,
//! `tune`'s margins, `control`'s plant check, `track`, `order`, Python's `stable`), so that two of
//! them cannot disagree about one model.
//!
//! The unit circle |z| = 1 is a line that rounding cannot place a pole on: a pole at exactly z = 1
//! (an actuator's position integrating its velocity) comes out of the companion-matrix eigenvalues as
//! 0.99999999… or 1.00000001…, a double root at 1 within about √ε_mach ≈ 1.5·10⁻⁸ of it and a
//! triple root within ∛ε_mach ≈ 6·10⁻⁶. A verdict with the circle as its edge would call the same
//! model stable or unstable by the last bit. The verdict therefore has a band of half-width
//! [`MARGIN`] = ε = 10⁻⁵ around the circle:
//!
//! | verdict | poles | what the output does |
//! |---|---|---|
//! | [`Stability::Settles`] | every \|p_i\| < 1 − ε | settles (slowest time constant below 1/ε = 10⁵ samples) |
//! | [`Stability::Integrator`] | every pole with \|p_i\| ≥ 1 − ε within ε of z = 1, none beyond | ramps under any net input |
//! | [`Stability::OnCircle`] | a pole with 1 − ε ≤ \|p_i\| ≤ 1 + ε away from z = 1 | oscillates without decay |
//! | [`Stability::Unstable`] | a pole with \|p_i\| > 1 + ε, or one that is not a finite number | diverges |
//!
//! Why ε = 10⁻⁵: it covers the rounding of up to a triple root at 1 (6·10⁻⁶); a pole 1 − ε has the
//! time constant −1/ln(1 − ε) ≈ 10⁵ samples (1000 s at the IPA's Ts = 0.01 s, 17 times the longest
//! run `tune` simulates), so over any practical record it integrates; the output-error search holds
//! its poles at 1 − 10⁻⁶, inside the band (it imitates a level with an integrator). A genuinely slow
//! settling mode stays outside it: an identified IPA position model's slowest pole, about 0.9995
//! (τ ≈ 2000 samples, 20 s), settles.

use nalgebra::Complex;

/// ε: the half-width of the band around the unit circle |z| = 1 within which a pole is on the circle
/// (an integrator when it is within ε of z = 1). See the module documentation for the choice.
pub const MARGIN: f64 = 1e-5;

/// The stability verdict of a linear block from its poles p_i (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Stability {
    /// Every pole strictly inside the circle of radius 1 − ε: the output settles.
    Settles {
        /// max |p_i| (0 for a block without poles).
        radius: f64,
    },
    /// Every pole on the circle (|p| ≥ 1 − ε) is within ε of z = 1, and none is beyond 1 + ε: the
    /// block integrates, its step ramps.
    Integrator {
        /// The pole of largest modulus (within ε of 1).
        pole: Complex<f64>,
        /// How many poles are within ε of z = 1 (2: a double integrator, whose step grows as k²).
        count: usize,
    },
    /// A pole within ε of the unit circle away from z = 1 (none beyond 1 + ε): the block oscillates
    /// without decay (a pole at −1: at the Nyquist frequency).
    OnCircle {
        /// The pole on the circle farthest from z = 1.
        pole: Complex<f64>,
    },
    /// A pole with |p| > 1 + ε, or a pole that is not a finite number (NaN or infinite coefficients):
    /// the block diverges.
    Unstable {
        /// The pole of largest modulus (NaN when one is not a number).
        pole: Complex<f64>,
    },
}

impl Stability {
    /// The verdict on the poles `poles` (the roots of A, in any order).
    pub fn of_poles(poles: &[Complex<f64>]) -> Stability {
        let finite = |p: &&Complex<f64>| p.re.is_finite() && p.im.is_finite();
        if let Some(bad) = poles.iter().find(|p| !finite(p)) {
            return Stability::Unstable { pole: *bad };
        }
        let largest = |it: &mut dyn Iterator<Item = &Complex<f64>>| {
            it.copied().max_by(|a, b| a.norm().total_cmp(&b.norm()))
        };
        if let Some(pole) = largest(&mut poles.iter().filter(|p| p.norm() > 1.0 + MARGIN)) {
            return Stability::Unstable { pole };
        }
        let on: Vec<Complex<f64>> = poles
            .iter()
            .copied()
            .filter(|p| p.norm() >= 1.0 - MARGIN)
            .collect();
        let at_one = |p: &Complex<f64>| (p - 1.0).norm() <= MARGIN;
        if let Some(pole) = on
            .iter()
            .copied()
            .filter(|p| !at_one(p))
            .max_by(|a, b| (a - 1.0).norm().total_cmp(&(b - 1.0).norm()))
        {
            return Stability::OnCircle { pole };
        }
        match largest(&mut on.iter()) {
            Some(pole) => Stability::Integrator {
                pole,
                count: on.len(),
            },
            None => Stability::Settles {
                radius: poles.iter().map(|p| p.norm()).fold(0.0, f64::max),
            },
        }
    }

    /// True for [`Stability::Settles`]: the block is asymptotically stable (the `stable` of the JSON
    /// documents and of Python).
    pub fn settles(&self) -> bool {
        matches!(self, Stability::Settles { .. })
    }

    /// True for [`Stability::Unstable`].
    pub fn is_unstable(&self) -> bool {
        matches!(self, Stability::Unstable { .. })
    }

    /// The verdict's name in JSON documents: `settles`, `integrator`, `on_circle` or `unstable`.
    pub fn name(&self) -> &'static str {
        match self {
            Stability::Settles { .. } => "settles",
            Stability::Integrator { .. } => "integrator",
            Stability::OnCircle { .. } => "on_circle",
            Stability::Unstable { .. } => "unstable",
        }
    }

    /// The verdict in a word or three, for summary lines and tables (`stable` is only
    /// [`Stability::Settles`]): `stable`, `an integrator`, `on the stability boundary` or `UNSTABLE`.
    /// The one short wording of `validate`'s summary line and `reproduce`'s tables (audit s27 L-10:
    /// validate called an integrator "UNSTABLE" where identify and the JSON said "integrator").
    pub fn word(&self) -> &'static str {
        match self {
            Stability::Settles { .. } => "stable",
            Stability::Integrator { .. } => "an integrator",
            Stability::OnCircle { .. } => "on the stability boundary",
            Stability::Unstable { .. } => "UNSTABLE",
        }
    }

    /// max |p_i| for [`Stability::Settles`], |p| of the verdict's pole otherwise (NaN for a pole that
    /// is not a number).
    pub fn modulus(&self) -> f64 {
        match self {
            Stability::Settles { radius } => *radius,
            Stability::Integrator { pole, .. }
            | Stability::OnCircle { pole }
            | Stability::Unstable { pole } => {
                if pole.re.is_nan() || pole.im.is_nan() {
                    f64::NAN
                } else {
                    pole.norm()
                }
            }
        }
    }
}

impl std::fmt::Display for Stability {
    /// The verdict in a few words, with its pole: what `identify`'s "Poles: … →" line says.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Stability::Settles { .. } => write!(
                f,
                "stable (all inside the unit circle, by more than {MARGIN:e})"
            ),
            Stability::Integrator { count, .. } => write!(
                f,
                "an integrator ({} at z = 1 within {MARGIN:e}, |p| = {:.7}): on the stability boundary, \
                 not a stable mode",
                if *count == 1 {
                    "a pole".to_string()
                } else {
                    format!("{count} poles")
                },
                self.modulus()
            ),
            Stability::OnCircle { pole } => write!(
                f,
                "on the stability boundary (a pole at {:.6} {} {:.6}i, |p| = {:.7}, on the unit circle \
                 away from z = 1: an undamped oscillation)",
                pole.re,
                if pole.im < 0.0 { "-" } else { "+" },
                pole.im.abs(),
                self.modulus()
            ),
            Stability::Unstable { .. } if !self.modulus().is_finite() => {
                f.write_str("UNSTABLE (a pole is not a finite number)")
            }
            Stability::Unstable { .. } => write!(
                f,
                "UNSTABLE (a pole has modulus {} > 1 + {MARGIN:e})",
                crate::format::Modulus(self.modulus())
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::poles_of;

    /// The verdict on A(z) = Π (z − p_i) for the hand-placed poles `p` (complex ones in conjugate
    /// pairs), through the companion-matrix roots every command uses.
    fn verdict_of(p: &[Complex<f64>]) -> Stability {
        // Coefficients of Π (z − p_i), highest power first (monic): c_k of z^(n−k).
        let mut c = vec![Complex::new(1.0, 0.0)];
        for pi in p {
            let mut next = vec![Complex::new(0.0, 0.0); c.len() + 1];
            for (k, ck) in c.iter().enumerate() {
                next[k] += ck;
                next[k + 1] -= ck * pi;
            }
            c = next;
        }
        let a: Vec<f64> = c[1..].iter().map(|v| v.re).collect();
        Stability::of_poles(&poles_of(&a))
    }

    fn real(x: f64) -> Complex<f64> {
        Complex::new(x, 0.0)
    }

    // The brief's table: the verdict named by where the poles were put, not by the program.
    #[test]
    fn the_verdict_follows_where_the_poles_are() {
        let e = std::f64::consts::FRAC_PI_3;
        let (c, s) = (e.cos(), e.sin());
        let cases: [(&str, Vec<Complex<f64>>, &str); 11] = [
            ("0.5", vec![real(0.5)], "settles"),
            ("0.9995 (IPA position)", vec![real(0.9995)], "settles"),
            ("1 - 1e-12", vec![real(1.0 - 1e-12)], "integrator"),
            ("1", vec![real(1.0)], "integrator"),
            ("1 + 1e-12", vec![real(1.0 + 1e-12)], "integrator"),
            ("1 and 0.5", vec![real(1.0), real(0.5)], "integrator"),
            ("double 1", vec![real(1.0), real(1.0)], "integrator"),
            ("1 + 1e-3", vec![real(1.0 + 1e-3)], "unstable"),
            ("-1", vec![real(-1.0)], "on_circle"),
            (
                "e^{±iπ/3}",
                vec![Complex::new(c, s), Complex::new(c, -s)],
                "on_circle",
            ),
            ("1 and -1", vec![real(1.0), real(-1.0)], "on_circle"),
        ];
        for (what, p, want) in cases {
            assert_eq!(verdict_of(&p).name(), want, "poles {what}");
        }
    }

    // A NaN coefficient gives NaN roots: not a number is not a stable mode.
    #[test]
    fn a_pole_that_is_not_a_number_is_unstable() {
        let v = Stability::of_poles(&poles_of(&[f64::NAN, 0.25]));
        assert!(v.is_unstable(), "{v:?}");
        assert!(v.modulus().is_nan());
        assert!(Stability::of_poles(&[real(0.5), Complex::new(f64::INFINITY, 0.0)]).is_unstable());
    }

    // A block without poles (FIR, na = 0) settles at once: radius 0.
    #[test]
    fn no_poles_settles_with_radius_zero() {
        assert_eq!(Stability::of_poles(&[]), Stability::Settles { radius: 0.0 });
    }

    // The band's edges: 1 − 2ε settles, 1 + 2ε is unstable, −1 + 2ε settles.
    #[test]
    fn the_band_is_margin_wide_on_each_side() {
        assert!(Stability::of_poles(&[real(1.0 - 2.0 * MARGIN)]).settles());
        assert!(Stability::of_poles(&[real(1.0 + 2.0 * MARGIN)]).is_unstable());
        assert!(Stability::of_poles(&[real(-1.0 + 2.0 * MARGIN)]).settles());
        assert_eq!(
            Stability::of_poles(&[real(-1.0 - MARGIN / 2.0)]).name(),
            "on_circle"
        );
    }

    // The integrator's count: Π (z − 1)² has two poles at 1.
    #[test]
    fn a_double_pole_at_one_counts_two() {
        match verdict_of(&[real(1.0), real(1.0), real(0.3)]) {
            Stability::Integrator { count, .. } => assert_eq!(count, 2),
            other => panic!("{other:?}"),
        }
    }
}

/// Why a model's output does not settle, with the figures its warning names: the one wording of the
/// stability warning every command and API gives (`identify`, `validate`, `simulate` through
/// `sysid::Warning`; `response` and `tune` through [`crate::Model::not_settling`]), kept here so that
/// the control crate, which does not depend on the estimators, says it in the same words (issue 10).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NotSettling {
    /// [`Stability::Unstable`]: the largest pole modulus (NaN for a pole that is not a number).
    Unstable {
        /// Largest pole modulus.
        max_pole_modulus: f64,
    },
    /// [`Stability::Integrator`]: the modulus of the pole at 1, and whether the model already carries
    /// an output level (an offset or a removed operating point: then "add one" is not the advice).
    Integrator {
        /// Modulus of the pole at 1.
        max_pole_modulus: f64,
        /// The model has an offset or an operating point.
        has_level: bool,
    },
    /// [`Stability::OnCircle`]: the pole on the circle.
    OnCircle {
        /// Real part of the pole.
        re: f64,
        /// Imaginary part of the pole.
        im: f64,
    },
}

impl NotSettling {
    /// The verdict's reason, or `None` for [`Stability::Settles`]; `has_level` as in
    /// [`NotSettling::Integrator`].
    pub fn of(stability: Stability, has_level: bool) -> Option<NotSettling> {
        match stability {
            Stability::Settles { .. } => None,
            s @ Stability::Unstable { .. } => Some(NotSettling::Unstable {
                max_pole_modulus: s.modulus(),
            }),
            s @ Stability::Integrator { .. } => Some(NotSettling::Integrator {
                max_pole_modulus: s.modulus(),
                has_level,
            }),
            Stability::OnCircle { pole } => Some(NotSettling::OnCircle {
                re: pole.re,
                im: pole.im,
            }),
        }
    }
}

impl std::fmt::Display for NotSettling {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NotSettling::Unstable { max_pole_modulus } if !max_pole_modulus.is_finite() => f
                .write_str(
                    "unstable model: a pole is not a finite number (coefficients beyond f64); its \
                     simulation diverges (do not use it for simulation or control)",
                ),
            NotSettling::Unstable { max_pole_modulus } => write!(
                f,
                "unstable model: a pole has modulus {} > 1; its simulation diverges \
                 (do not use it for simulation or control)",
                crate::format::Modulus(*max_pole_modulus)
            ),
            NotSettling::Integrator {
                max_pole_modulus,
                has_level,
            } => write!(
                f,
                "a pole at z = 1 (modulus {max_pole_modulus:.7}, within {:e} of 1), on the stability \
                 boundary: the model integrates ({}); unless the plant integrates (a position driven by \
                 a velocity), this is a spurious mode the data do not determine, so the static gain and \
                 long simulations are not to be trusted ({})",
                MARGIN,
                if *max_pole_modulus < 1.0 {
                    format!("time constant {:.1e} samples", -1.0 / max_pole_modulus.ln())
                } else {
                    "no decay".to_string()
                },
                if *has_level {
                    "the model already has an output level, so a drift, a record too short for a slow \
                     mode, or too high an order is the likelier cause: try a longer record, --detrend \
                     linear or a lower na"
                } else {
                    "an output level the model cannot represent is the usual cause: try --offset or \
                     --detrend mean"
                }
            ),
            NotSettling::OnCircle { re, im } => write!(
                f,
                "a pole at {re:.6} {} {:.6}i (modulus {:.7}) on the unit circle away from z = 1: the \
                 model oscillates without decay, so its simulation, static gain and frequency response \
                 are not to be trusted (too high an order is the usual cause: try a lower na)",
                if *im < 0.0 { "-" } else { "+" },
                im.abs(),
                re.hypot(*im)
            ),
        }
    }
}
