//! Frequency, impulse and step response of an identified model's linear block, its DC gain, poles and
//! zeros, and the gain and phase margins of a PI loop around it: what MATLAB's `bode`, `dcgain`,
//! `pole`, `zero`, `impulse`, `step` and `margin` give for one's own model (audit s20 M-2). Behind
//! `ipa-sysid response` and Python's `Model.frequency_response`; the report's Bode figure uses [`bode`].
//!
//! The linear block is G(z) = z^{-nk} B(z⁻¹)/A(z⁻¹), B = b_1 + b_2 z⁻¹ + …, A = 1 + a_1 z⁻¹ + …, from
//! the input nonlinearity's output x = f(u) to the output y (MATLAB `idpoly` conventions). For an ARX
//! model x = u. For a Hammerstein model b_1 = 1 and the gain lives in the deadzone's slopes: a change
//! of u beyond b_r moves x by m_r per count, below b_l by m_l per count, inside [b_l, b_r] not at all,
//! so the gain from u is m_r · G on the right and m_l · G on the left ([`Response::sides`]); G alone
//! is 20 log10(1/m) dB away from either (+37 dB for the README's model with m_r ≈ 0.014 mm/count).

use serde::Serialize;
use sysid_core::{Model, StaticNonlinearity};

use crate::position::ControllerSettings;
use crate::tune::{margins, Margins};
use crate::{ControlError, ControlSetting};

/// What to compute: the frequency grid, how many samples of the impulse and step responses, and an
/// optional controller for the loop's margins (a PI C = Kp + Ki Ts/(1 − z⁻¹), or a tuned controller
/// with its derivative term).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResponseSettings {
    /// Number of log-spaced frequencies (at least 2).
    pub points: usize,
    /// Lowest frequency, Hz (> 0, below the Nyquist frequency 1/(2 Ts)); `None`: 1e-3 × Nyquist.
    pub f_min_hz: Option<f64>,
    /// Samples of the impulse and step responses, k = 0 … samples − 1 (at least 1).
    pub samples: usize,
    /// The controller of the loop's margins, as `tune` reports them ([`margins`]: Kp, Ki, Kd and Tf;
    /// the deadzone replaced by its mean slope (m_l + m_r)/2): a tuned controller file's
    /// [`ControllerSettings`], or [`ControllerSettings::pi`] for a PI of Kp counts per output unit and
    /// Ki counts per output unit · s. Its Ts must be the model's; `None`: no margins.
    pub controller: Option<ControllerSettings>,
}

impl Default for ResponseSettings {
    fn default() -> Self {
        ResponseSettings {
            points: 20,
            f_min_hz: None,
            samples: 20,
            controller: None,
        }
    }
}

/// One side of a Hammerstein model's deadzone: the gain from u to y there is `slope` · G.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Side {
    /// `right` (u > b_r) or `left` (u < b_l).
    pub side: &'static str,
    /// The breakpoint b_r or b_l, input units (counts).
    pub breakpoint: f64,
    /// The slope m_r or m_l, units of x per input unit.
    pub slope: f64,
    /// 20 log10 |slope|: add it to [`Bode::mag_db`] for the gain from u on this side, dB.
    pub offset_db: f64,
    /// DC gain from u on this side, slope · G(1), output units per input unit (`None`: G(1) is
    /// infinite, a pole at z = 1).
    pub dc_gain: Option<f64>,
}

/// The responses of one model's linear block (see the module documentation).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Response {
    /// Ts, s.
    pub ts_s: f64,
    /// The input delay nk, samples.
    pub nk: usize,
    /// Which gain the figures use, in words (the module documentation's convention for this model).
    pub gain: String,
    /// DC gain G(1) = Σ b_i / (1 + Σ a_i) of the linear block (`None`: a pole at z = 1, an integrator).
    pub dc_gain: Option<f64>,
    /// Poles: roots of z^na + a_1 z^(na−1) + … + a_na, as (re, im).
    pub poles: Vec<(f64, f64)>,
    /// Finite zeros: roots of b_1 z^(nb−1) + … + b_nb (leading zero coefficients dropped), as (re, im).
    pub zeros: Vec<(f64, f64)>,
    /// G(e^{jωTs}) on the log grid up to the Nyquist frequency.
    pub bode: Bode,
    /// For a Hammerstein model, the gain from u on each side of the deadzone; empty otherwise.
    pub sides: Vec<Side>,
    /// Impulse response of G, g(k) at t = k Ts, k = 0 … samples − 1 (x(0) = 1, x(k) = 0 after).
    pub impulse: Vec<f64>,
    /// Unit-step response of G, s(k) = Σ_{j ≤ k} g(j).
    pub step: Vec<f64>,
    /// Margins of the loop with [`ResponseSettings::controller`], as `tune` computes them ([`margins`]).
    pub margins: Option<Margins>,
}

/// The output y(k) of A(q) y = q^{-nk} B(q) x for k = 0 … n − 1 from rest, x given by `x(k)`.
fn filter(model: &Model, n: usize, x: impl Fn(usize) -> f64) -> Vec<f64> {
    let (a, b, nk) = (model.a(), model.b(), model.nk());
    let mut y = Vec::with_capacity(n);
    for k in 0..n {
        let mut v = 0.0;
        for (j, bj) in b.iter().enumerate() {
            if let Some(i) = k.checked_sub(nk + j) {
                v += bj * x(i);
            }
        }
        for (i, ai) in a.iter().enumerate() {
            if let Some(p) = k.checked_sub(i + 1) {
                v -= ai * y[p];
            }
        }
        y.push(v);
    }
    y
}

/// Frequency, impulse and step response, DC gain, poles and zeros of `model`'s linear block, and the
/// margins of a PI loop around it (see the module documentation for the gain convention).
///
/// ```
/// use control::response::{response, ResponseSettings};
/// // y(k) = 0.5 y(k−1) + 2 u(k−1): DC gain 2 / (1 − 0.5) = 4, impulse 0, 2, 1, 0.5, …
/// let m = sysid_core::Model::arx(0.1, vec![-0.5], vec![2.0], 1, None).unwrap();
/// let r = response(&m, &ResponseSettings::default()).unwrap();
/// assert_eq!(r.dc_gain, Some(4.0));
/// assert_eq!(&r.impulse[..4], &[0.0, 2.0, 1.0, 0.5]);
/// ```
pub fn response(model: &Model, s: &ResponseSettings) -> Result<Response, ControlError> {
    if model.inputs().len() != 1 {
        return Err(ControlError::Config(format!(
            "the model has {} inputs: a response is computed for a single-input model",
            model.inputs().len()
        )));
    }
    let ts = model.ts();
    if let Some(c) = &s.controller {
        // The margins are those of C(z) G(z) on one sampling grid: a controller tuned at another Ts
        // has other poles and zeros in z.
        if (c.ts_s - ts).abs() > 1e-9 * ts {
            return Err(ControlError::setting(
                ControlSetting::Ts,
                c.ts_s,
                &format!(
                    "the model's Ts = {} s (a controller runs at the sampling period it was tuned for)",
                    sysid_core::format::Shortest(ts)
                ),
            ));
        }
    }
    let nyquist_hz = 0.5 / ts;
    let f_min_hz = s.f_min_hz.unwrap_or(1e-3 * nyquist_hz);
    if !(f_min_hz > 0.0 && f_min_hz < nyquist_hz) {
        return Err(ControlError::Config(format!(
            "the lowest frequency {f_min_hz} Hz must be above 0 and below the Nyquist frequency {nyquist_hz} Hz"
        )));
    }
    let (a, b) = (model.a(), model.b());
    let sum_a: f64 = 1.0 + a.iter().sum::<f64>();
    let scale_a: f64 = 1.0 + a.iter().map(|v| v.abs()).sum::<f64>();
    let dc_gain = (sum_a.abs() > 1e-12 * scale_a).then(|| b.iter().sum::<f64>() / sum_a);
    let poles = model.poles().iter().map(|c| (c.re, c.im)).collect();
    let zeros = match b.iter().position(|&v| v != 0.0) {
        Some(i) => {
            let lead = b[i];
            let c: Vec<f64> = b[i + 1..].iter().map(|v| v / lead).collect();
            sysid_core::model::poles_of(&c)
                .iter()
                .map(|c| (c.re, c.im))
                .collect()
        }
        None => Vec::new(),
    };
    let input = |u: &str| format!("from {u} to y (output units per unit of {u})");
    let (mut gain, sides) = match model.input().nonlinearity() {
        StaticNonlinearity::Linear => (format!("G = z^-nk B/A {}", input("u")), Vec::new()),
        StaticNonlinearity::Deadzone(d) => {
            let side = |name, breakpoint: f64, slope: f64| Side {
                side: name,
                breakpoint,
                slope,
                offset_db: 20.0 * slope.abs().log10(),
                dc_gain: dc_gain.map(|g| slope * g),
            };
            let sides = vec![side("right", d.b_r, d.m_r), side("left", d.b_l, d.m_l)];
            (
                format!(
                    "G = z^-nk B/A with b1 = 1 {}; the gain from u is m_r G = {} G for u > b_r = {} ({:+.2} dB) \
                     and m_l G = {} G for u < b_l = {} ({:+.2} dB), 0 inside the deadzone",
                    input("the deadzone's output x"),
                    sysid_core::format::sig(d.m_r, 6),
                    sysid_core::format::sig(d.b_r, 6),
                    sides[0].offset_db,
                    sysid_core::format::sig(d.m_l, 6),
                    sysid_core::format::sig(d.b_l, 6),
                    sides[1].offset_db,
                ),
                sides,
            )
        }
        other => (
            format!(
                "G = z^-nk B/A {}: the input nonlinearity x = f(u) ({}) is not included",
                input("x = f(u)"),
                other.kind_name()
            ),
            Vec::new(),
        ),
    };
    if model.output_nonlinearity().is_some() {
        gain.push_str(
            "; the output nonlinearity y = g(v) is not included (the figures are those of v)",
        );
    }
    let impulse = filter(model, s.samples.max(1), |k| if k == 0 { 1.0 } else { 0.0 });
    let step = filter(model, s.samples.max(1), |_| 1.0);
    let margins = s.controller.map(|c| margins(model, &c));
    Ok(Response {
        ts_s: ts,
        nk: model.nk(),
        gain,
        dc_gain,
        poles,
        zeros,
        bode: bode(model, 1.0, f_min_hz, s.points),
        sides,
        impulse,
        step,
        margins,
    })
}

/// Frequency response of a model's linear block, scaled by `gain`: the frequencies (Hz), |H| in dB
/// and the unwrapped phase in degrees, at `points` log-spaced frequencies from `f_min_hz` up to the
/// Nyquist frequency 1/(2 Ts).
///
/// H(e^{jω Ts}) = gain · Σ_i b_i e^{−jω Ts (nk+i−1)} / (1 + Σ_i a_i e^{−jω Ts i}). A zero |H| gives
/// NaN dB (a gap in the plot).
pub fn bode(model: &Model, gain: f64, f_min_hz: f64, points: usize) -> Bode {
    let ts = model.ts();
    let nyquist = 0.5 / ts;
    let points = points.max(2);
    let (lo, hi) = (f_min_hz.log10(), nyquist.log10());
    let mut out = Bode {
        f_hz: Vec::with_capacity(points),
        mag_db: Vec::with_capacity(points),
        phase_deg: Vec::with_capacity(points),
    };
    let mut prev: Option<f64> = None;
    for i in 0..points {
        let f = 10f64.powf(lo + (hi - lo) * i as f64 / (points - 1) as f64);
        let w = 2.0 * std::f64::consts::PI * f * ts;
        let (mut nr, mut ni) = (0.0, 0.0);
        for (i, b) in model.b().iter().enumerate() {
            let d = (model.nk() + i) as f64 * w;
            nr += b * d.cos();
            ni -= b * d.sin();
        }
        let (mut dr, mut di) = (1.0, 0.0);
        for (i, a) in model.a().iter().enumerate() {
            let d = (i + 1) as f64 * w;
            dr += a * d.cos();
            di -= a * d.sin();
        }
        let den = dr * dr + di * di;
        let (hr, hi_) = if den > 0.0 {
            (
                gain * (nr * dr + ni * di) / den,
                gain * (ni * dr - nr * di) / den,
            )
        } else {
            (f64::NAN, f64::NAN)
        };
        let mag = hr.hypot(hi_);
        out.f_hz.push(f);
        out.mag_db.push(if mag > 0.0 {
            20.0 * mag.log10()
        } else {
            f64::NAN
        });
        let mut ph = hi_.atan2(hr).to_degrees();
        if let Some(p) = prev {
            while ph - p > 180.0 {
                ph -= 360.0;
            }
            while ph - p < -180.0 {
                ph += 360.0;
            }
        }
        if ph.is_finite() {
            prev = Some(ph);
        }
        out.phase_deg.push(ph);
    }
    out
}

/// A frequency response (see [`bode`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Bode {
    /// Frequencies f, Hz.
    pub f_hz: Vec<f64>,
    /// Magnitude 20 log10 |H|, dB.
    pub mag_db: Vec<f64>,
    /// Phase arg H, degrees, unwrapped.
    pub phase_deg: Vec<f64>,
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use std::f64::consts::PI;
    use sysid_core::nonlinearity::Deadzone;

    /// y(k) = α y(k−1) + β u(k−1), i.e. A = 1 − α q⁻¹, B = β, nk = 1.
    fn first_order(alpha: f64, beta: f64, ts: f64) -> Model {
        Model::arx(ts, vec![-alpha], vec![beta], 1, None).unwrap()
    }

    #[test]
    fn first_order_bode_is_b_over_one_minus_a_e_to_the_minus_j_omega_ts() {
        // G(e^{jθ}) = β e^{−jθ} / (1 − α e^{−jθ}), θ = ωTs: |G| = |β| / √(1 − 2α cos θ + α²),
        // arg G = −θ − atan2(α sin θ, 1 − α cos θ).
        let (alpha, beta, ts) = (0.8, 0.3, 0.05);
        let r = response(
            &first_order(alpha, beta, ts),
            &ResponseSettings {
                points: 40,
                f_min_hz: Some(0.01),
                ..ResponseSettings::default()
            },
        )
        .unwrap();
        assert_eq!(r.bode.f_hz.len(), 40);
        assert!((r.bode.f_hz[0] - 0.01).abs() < 1e-12);
        assert!(
            (r.bode.f_hz[39] - 0.5 / ts).abs() < 1e-9,
            "last point at Nyquist"
        );
        for i in 0..40 {
            let th = 2.0 * PI * r.bode.f_hz[i] * ts;
            let mag = beta / (1.0 - 2.0 * alpha * th.cos() + alpha * alpha).sqrt();
            let phase = -th - (alpha * th.sin()).atan2(1.0 - alpha * th.cos());
            assert!((r.bode.mag_db[i] - 20.0 * mag.log10()).abs() < 1e-9, "{i}");
            assert!(
                (r.bode.phase_deg[i] - phase.to_degrees()).abs() < 1e-7,
                "{i}"
            );
        }
        // DC gain β / (1 − α); pole α; no finite zero.
        assert!((r.dc_gain.unwrap() - beta / (1.0 - alpha)).abs() < 1e-12);
        assert_eq!(r.poles.len(), 1);
        assert!((r.poles[0].0 - alpha).abs() < 1e-12 && r.poles[0].1 == 0.0);
        assert!(r.zeros.is_empty());
        assert!(r.sides.is_empty() && r.margins.is_none());
    }

    #[test]
    fn first_order_impulse_is_b_a_to_the_k_minus_1_and_step_its_running_sum() {
        let (alpha, beta) = (-0.6, 1.7);
        let r = response(
            &first_order(alpha, beta, 0.1),
            &ResponseSettings {
                samples: 12,
                ..ResponseSettings::default()
            },
        )
        .unwrap();
        assert_eq!(r.impulse.len(), 12);
        assert_eq!(r.impulse[0], 0.0, "nk = 1: nothing at k = 0");
        let mut sum = 0.0;
        for k in 1..12 {
            let h = beta * alpha.powi(k as i32 - 1);
            assert!((r.impulse[k] - h).abs() < 1e-12 * h.abs().max(1.0), "{k}");
            sum += h;
            // s(k) = β (1 − α^k) / (1 − α)
            let s = beta * (1.0 - alpha.powi(k as i32)) / (1.0 - alpha);
            assert!((r.step[k] - s).abs() < 1e-12 && (r.step[k] - sum).abs() < 1e-12);
        }
    }

    #[test]
    fn an_integrator_has_no_dc_gain_and_zeros_are_the_roots_of_b() {
        // A = 1 − q⁻¹ (pole at 1); B = 2 − 1 q⁻¹: zero at z = 0.5.
        let m = Model::arx(0.01, vec![-1.0], vec![2.0, -1.0], 2, None).unwrap();
        let r = response(&m, &ResponseSettings::default()).unwrap();
        assert_eq!(r.dc_gain, None);
        assert_eq!(r.zeros.len(), 1);
        assert!((r.zeros[0].0 - 0.5).abs() < 1e-12 && r.zeros[0].1 == 0.0);
        assert_eq!(&r.impulse[..4], &[0.0, 0.0, 2.0, 1.0]);
    }

    #[test]
    fn margins_of_a_first_order_loop_are_the_hand_derived_ones() {
        // L = K β z⁻¹ / (1 − α z⁻¹) with K = Kp (Ki = 0), α = 0.5, K β = 1:
        // |L| = 1 where cos θ = (1 + α² − (Kβ)²) / (2α) = 0.25; PM = 180° + arg L there;
        // at z = −1, L = −Kβ / (1 + α): GM = 20 log10 1.5 dB at ω = π / Ts.
        let (alpha, beta, ts) = (0.5, 0.25, 0.01);
        let r = response(
            &first_order(alpha, beta, ts),
            &ResponseSettings {
                controller: Some(ControllerSettings::pi(ts, 4.0, 0.0)),
                ..ResponseSettings::default()
            },
        )
        .unwrap();
        let m = r.margins.unwrap();
        let th = 0.25f64.acos();
        let pm = 180.0 + (-th - (alpha * th.sin()).atan2(1.0 - alpha * th.cos())).to_degrees();
        assert!(
            (m.phase_margin_deg.unwrap() - pm).abs() < 0.01,
            "{m:?} vs {pm}"
        );
        assert!((m.gain_crossover_rad_s.unwrap() - th / ts).abs() < 1e-3 * th / ts);
        assert!(
            (m.gain_margin_db.unwrap() - 20.0 * 1.5f64.log10()).abs() < 1e-6,
            "{m:?}"
        );
        assert!((m.phase_crossover_rad_s.unwrap() - PI / ts).abs() < 1e-6 * PI / ts);
    }

    #[test]
    fn a_tuned_controllers_derivative_enters_the_margins() {
        // G = 0.25 z⁻¹ / (1 − 0.5 z⁻¹); C = Kp + Kd (1 − z⁻¹)/Ts with Kp = 1, Kd/Ts = 1 (Tf = 0):
        // C = 2 − z⁻¹ = 2 (1 − 0.5 z⁻¹) cancels the pole, L = C G = 0.5 z⁻¹: |L| = 0.5 everywhere (no
        // gain crossover), L(−1) = −0.5 (GM = 20 log10 2 at ω = π/Ts), closed loop 1 + 0.5 z⁻¹: the
        // poles −0.5 and the cancelled 0.5, |p| <= 0.5. A PI with the same Kp alone has another GM.
        let ts = 0.01;
        let c = ControllerSettings {
            kd: 0.01,
            ..ControllerSettings::pi(ts, 1.0, 0.0)
        };
        let r = response(
            &first_order(0.5, 0.25, ts),
            &ResponseSettings {
                controller: Some(c),
                ..ResponseSettings::default()
            },
        )
        .unwrap();
        let m = r.margins.unwrap();
        assert!(
            (m.gain_margin_db.unwrap() - 20.0 * 2f64.log10()).abs() < 1e-9,
            "{m:?}"
        );
        assert!((m.phase_crossover_rad_s.unwrap() - PI / ts).abs() < 1e-6 * PI / ts);
        assert_eq!((m.phase_margin_deg, m.gain_crossovers), (None, 0), "{m:?}");
        assert!((m.closed_loop_max_pole_modulus.unwrap() - 0.5).abs() < 1e-9);
    }

    #[test]
    fn a_controller_tuned_at_another_ts_is_refused() {
        // The model at Ts = 0.01 s, the controller at 0.02 s: C(z) G(z) would mix two grids.
        let e = response(
            &first_order(0.5, 0.25, 0.01),
            &ResponseSettings {
                controller: Some(ControllerSettings::pi(0.02, 1.0, 0.0)),
                ..ResponseSettings::default()
            },
        )
        .unwrap_err();
        let text = e.to_string();
        assert!(
            text.starts_with("invalid setting") && text.contains("0.02") && text.contains("0.01 s"),
            "{text}"
        );
    }

    #[test]
    fn a_hammerstein_model_states_its_slopes_per_side() {
        let dz = Deadzone {
            b_l: -20.0,
            b_r: 30.0,
            m_l: 0.02,
            m_r: 0.014,
        };
        let m = Model::hammerstein(0.01, vec![-0.9], vec![1.0], 1, dz, None).unwrap();
        let r = response(&m, &ResponseSettings::default()).unwrap();
        assert_eq!(r.sides.len(), 2);
        let (right, left) = (&r.sides[0], &r.sides[1]);
        assert_eq!((right.side, left.side), ("right", "left"));
        assert!((right.offset_db - 20.0 * 0.014f64.log10()).abs() < 1e-12);
        assert!((left.offset_db - 20.0 * 0.02f64.log10()).abs() < 1e-12);
        // G(1) = 1 / (1 − 0.9) = 10; from u: 0.14 mm/count on the right, 0.2 on the left.
        assert!((r.dc_gain.unwrap() - 10.0).abs() < 1e-12);
        assert!((right.dc_gain.unwrap() - 0.14).abs() < 1e-12);
        assert!((left.dc_gain.unwrap() - 0.2).abs() < 1e-12);
        assert!(r.gain.contains("b1 = 1") && r.gain.contains("m_r") && r.gain.contains("m_l"));
    }
}
