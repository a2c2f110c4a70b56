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
    /// Whether the slope was estimated: `false` for a slope of exactly 0, the branch `identify` drops
    /// and fixes at m = 0, b = 0 when the record never drives u to that side (audit s21 L-A2: its
    /// "0 gain, −inf dB" was read as a measured figure).
    pub identified: bool,
    /// 20 log10 |slope|: add it to [`Bode::mag_db`] for the gain from u on this side, dB (`None`: the
    /// slope was not identified).
    pub offset_db: Option<f64>,
    /// DC gain from u on this side, slope · G(1), output units per input unit (`None`: the slope was
    /// not identified, or G(1) is not a finite steady-state gain, [`Response::dc_gain_note`]).
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
    /// DC gain G(1) = Σ b_i / (1 + Σ a_i) of the linear block, the level its unit step settles at
    /// (`None` when it settles at none: [`Response::dc_gain_note`] says why).
    pub dc_gain: Option<f64>,
    /// Why [`Response::dc_gain`] is `None`, in words: [`DC_INTEGRATOR`], [`DC_UNSTABLE`] or
    /// [`DC_BOUNDARY`] (`None` when there is a DC gain).
    pub dc_gain_note: Option<&'static str>,
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
    /// What the figures are not to be trusted for, in words (the `warnings` of `identify --json`):
    /// the linear block's stability verdict ([`Model::stability`]) in `identify`'s words
    /// ([`sysid::Warning::if_not_settling`]) and what it means for its DC gain and Bode
    /// table, the model file's own doubts as `validate` repeats them
    /// ([`sysid_core::model_file::load_warnings`], prefixed `model: `), a step response that has not
    /// settled within the samples, and figures that are not finite numbers.
    pub warnings: Vec<String>,
}

/// [`Response::dc_gain_note`] of a block whose stability verdict is an integrator
/// ([`sysid_core::Stability::Integrator`]: a pole within ε of z = 1, none beyond the circle): its step
/// ramps.
pub const DC_INTEGRATOR: &str = "infinite (integrator)";
/// [`Response::dc_gain_note`] of an unstable block ([`sysid_core::Stability::Unstable`]: a pole outside
/// the unit circle by more than ε): its step diverges, and Σ b / (1 + Σ a) is no steady-state gain (its
/// sign can be the opposite of the plant's).
pub const DC_UNSTABLE: &str = "not defined (unstable)";
/// [`Response::dc_gain_note`] of a block with a pole on the unit circle away from z = 1
/// ([`sysid_core::Stability::OnCircle`]): its step oscillates without decay.
pub const DC_BOUNDARY: &str = "not defined (a pole on the stability boundary)";

/// The DC-gain verdict of `model`'s linear block: `None` when its unit step settles, else the
/// [`Response::dc_gain_note`] and a sentence on what the verdict means for the figures, from its
/// stability verdict ([`Model::stability`], the one every command reports).
fn dc_verdict(model: &Model) -> Option<(&'static str, String)> {
    use sysid_core::Stability;
    Some(match model.stability() {
        Stability::Settles { .. } => return None,
        Stability::Unstable { .. } => (
            DC_UNSTABLE,
            "DC gain not defined: a pole outside the unit circle makes the step response diverge, so \
             G(1) = Σ b / (1 + Σ a) is no steady-state gain (its sign can be the opposite of the \
             plant's), and the Bode table is that of an unstable G (no steady sinusoidal response)"
                .to_string(),
        ),
        Stability::Integrator { .. } => (
            DC_INTEGRATOR,
            format!(
                "DC gain infinite: a pole at z = 1 (within {:e}) is an integrator, the step response \
                 ramps without settling and |G| grows without bound as f → 0",
                sysid_core::stability::MARGIN
            ),
        ),
        Stability::OnCircle { .. } => (
            DC_BOUNDARY,
            "DC gain not defined: a pole on the unit circle away from z = 1 makes the step response \
             oscillate without decay"
                .to_string(),
        ),
    })
}

/// An error naming the model file's field when the coefficients of `model`'s linear block are too
/// large for f64 (audit s21 M-B3: a = [1e308, 1e308] gave NaN poles, a NaN Bode table and exit 0):
/// Σ|a_i| or Σ|b_j| overflows, or the poles (roots of A) are not finite numbers.
fn check_coefficients(model: &Model) -> Result<(), ControlError> {
    let finite_poles = model
        .poles()
        .iter()
        .all(|p| p.re.is_finite() && p.im.is_finite());
    for (field, c) in [("a", model.a()), ("b", model.b())] {
        let size: f64 = c.iter().map(|v| v.abs()).sum();
        if !size.is_finite() || (field == "a" && !finite_poles) {
            let largest = c.iter().map(|v| v.abs()).fold(0.0, f64::max);
            return Err(ControlError::Numerical(format!(
                "the model's \"{field}\" coefficients (largest |{field}_i| = {largest:e}) are too large \
                 for f64: Σ|{field}_i| = {size:e}{}; the model file holds an absurd coefficient \
                 (hand-edited or damaged?)",
                if field == "a" && !finite_poles {
                    ", the poles are not finite numbers"
                } else {
                    ""
                }
            )));
        }
    }
    Ok(())
}

/// The warning for the figures of `r` that are not finite numbers (NaN, ±inf; `null` in JSON), naming
/// them; a magnitude of NaN dB with a finite phase is |G| = 0 (a zero on the unit circle), which
/// [`bode`] documents as a gap, not a failure.
fn non_finite(r: &Response) -> Option<String> {
    let first_bad = |v: &[f64]| v.iter().position(|x| !x.is_finite());
    let mut bad = Vec::new();
    if r.dc_gain.is_some_and(|g| !g.is_finite())
        || r.sides
            .iter()
            .any(|s| s.dc_gain.is_some_and(|g| !g.is_finite()))
    {
        bad.push("the DC gain".to_string());
    }
    if r.zeros
        .iter()
        .any(|z| !(z.0.is_finite() && z.1.is_finite()))
    {
        bad.push("the zeros".to_string());
    }
    let b = &r.bode;
    if let Some(i) =
        (0..b.f_hz.len()).find(|&i| !b.phase_deg[i].is_finite() || b.mag_db[i] == f64::INFINITY)
    {
        bad.push(format!("the Bode table from f = {} Hz", b.f_hz[i]));
    }
    for (name, v) in [("impulse", &r.impulse), ("step", &r.step)] {
        if let Some(k) = first_bad(v) {
            bad.push(format!("the {name} response from k = {k}"));
        }
    }
    (!bad.is_empty()).then(|| {
        format!(
            "figures that are not finite numbers (NaN or infinite; null in JSON): {}; do not use them",
            bad.join(", ")
        )
    })
}

/// The warning when the unit step of a block with a finite DC gain G(1) ≠ 0 is still more than 2 % of
/// G(1) away from it at the last sample: the table ends before the response settles (audit s21 H-A1).
fn unsettled(step: &[f64], dc_gain: Option<f64>) -> Option<String> {
    let g = dc_gain.filter(|g| *g != 0.0 && g.is_finite())?;
    let (k, last) = (step.len().checked_sub(1)?, *step.last()?);
    let off = (last - g).abs();
    (off > 0.02 * g.abs() || off.is_nan()).then(|| {
        format!(
            "the step response has not settled by k = {k}: s({k}) = {} against G(1) = {} ({} % of \
             it); more samples show the rest",
            sysid_core::format::sig(last, 6),
            sysid_core::format::sig(g, 6),
            sysid_core::format::sig(100.0 * last / g, 2)
        )
    })
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
        // The setting, not the model, is blamed (audit s28 L-7: `--f-min 0` named the model file).
        return Err(ControlError::setting(
            ControlSetting::FMin,
            sysid_core::format::Shortest(f_min_hz),
            &format!(
                "a frequency in Hz above 0 and below the model's Nyquist frequency {} Hz",
                sysid_core::format::Shortest(nyquist_hz)
            ),
        ));
    }
    check_coefficients(model)?;
    let (a, b) = (model.a(), model.b());
    let verdict = dc_verdict(model);
    let sum_a: f64 = 1.0 + a.iter().sum::<f64>();
    let scale_a: f64 = 1.0 + a.iter().map(|v| v.abs()).sum::<f64>();
    let dc_gain =
        (verdict.is_none() && sum_a.abs() > 1e-12 * scale_a).then(|| b.iter().sum::<f64>() / sum_a);
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
            let side = |name, breakpoint: f64, slope: f64| {
                let identified = slope != 0.0;
                Side {
                    side: name,
                    breakpoint,
                    slope,
                    identified,
                    offset_db: identified.then(|| 20.0 * slope.abs().log10()),
                    dc_gain: dc_gain.filter(|_| identified).map(|g| slope * g),
                }
            };
            let sides = vec![side("right", d.b_r, d.m_r), side("left", d.b_l, d.m_l)];
            // "m_r G = 0.0655 G for u > b_r = 0 (-23.67 dB)", or for a branch fixed at 0 by identify
            // "m_l not identified (fixed at 0: ...)".
            let words = |s: &Side, m: &str, b: &str, beyond: &str| match s.offset_db {
                Some(db) => format!(
                    "{m} G = {} G for u {beyond} {b} = {} ({db:+.2} dB)",
                    sysid_core::format::sig(s.slope, 6),
                    sysid_core::format::sig(s.breakpoint, 6),
                ),
                None => format!(
                    "{m} not identified for u {beyond} {b} = {} (fixed at 0: the record never \
                     drove u there; identify drops such a branch)",
                    sysid_core::format::sig(s.breakpoint, 6),
                ),
            };
            (
                format!(
                    "G = z^-nk B/A with b1 = 1 {}; the gain from u is {} and {}, 0 inside the deadzone",
                    input("the deadzone's output x"),
                    words(&sides[0], "m_r", "b_r", ">"),
                    words(&sides[1], "m_l", "b_l", "<"),
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
    let mut warnings: Vec<String> = model
        .not_settling()
        .map(|w| w.to_string())
        .into_iter()
        .chain(verdict.as_ref().map(|v| v.1.clone()))
        .chain(
            sysid_core::model_file::load_warnings(model)
                .into_iter()
                .map(|w| format!("model: {w}")),
        )
        .chain(unsettled(&step, dc_gain))
        // The loop's verdicts in `tune`'s words (one function): unstable, not computable, small or
        // negative margins.
        .chain(margins.iter().flat_map(crate::tune::linear_loop_warnings))
        .collect();
    let mut r = Response {
        ts_s: ts,
        nk: model.nk(),
        gain,
        dc_gain,
        dc_gain_note: verdict.map(|v| v.0),
        poles,
        zeros,
        bode: bode(model, 1.0, f_min_hz, s.points),
        sides,
        impulse,
        step,
        margins,
        warnings: Vec::new(),
    };
    warnings.extend(non_finite(&r));
    r.warnings = warnings;
    Ok(r)
}

/// The controller of a response's margins as the JSON document and Python's dict give it (audit s22
/// L-B7: a rounded text string): `{"file": FILE or null, "kp": Kp, "ki": Ki, "kd": Kd, "tf_s": Tf}`,
/// the gains as stored (counts/mm, counts/(mm·s), counts·s/mm; Tf in s). `file` names the controller
/// file, `None` for a PI given by its gains.
pub fn controller_json(c: &crate::ControllerSettings, file: Option<&str>) -> serde_json::Value {
    serde_json::json!({
        "file": file,
        "kp": c.kp,
        "ki": c.ki,
        "kd": c.kd,
        "tf_s": c.derivative_filter_s,
    })
}

/// Frequency response of a model's linear block, scaled by `gain`: the frequencies (Hz), |H| in dB
/// and the unwrapped phase in degrees, at `points` log-spaced frequencies from `f_min_hz` up to the
/// Nyquist frequency 1/(2 Ts). The first phase lies in [−180°, 180°) (−180° for H on the negative
/// real axis); each next one within 180° of the one before, a step of a half turn
/// (to [`PHASE_TIE_DEG`]) taken downwards, so that the same system gives the same sign whatever the
/// rounding at the Nyquist frequency.
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
        // A half turn is a tie (the negative real axis, or a step of 180° between two points, as at
        // the Nyquist frequency of a 2-point grid): rounding alone decides it, so it is resolved as a
        // lag, −180° (audit s21 L-B2: ±180° at Nyquist by the sign of a rounding error).
        match prev {
            None if ph > 180.0 - PHASE_TIE_DEG => ph -= 360.0,
            None => {}
            Some(p) => {
                while ph - p > 180.0 - PHASE_TIE_DEG {
                    ph -= 360.0;
                }
                while ph - p <= -180.0 - PHASE_TIE_DEG {
                    ph += 360.0;
                }
            }
        }
        if ph.is_finite() {
            prev = Some(ph);
        }
        out.phase_deg.push(ph);
    }
    out
}

/// How close to a half turn, degrees, a phase (or the phase step between two points of the grid) is
/// taken as the half turn itself, which [`bode`] reports as a lag: −180° rather than +180° (audit s21
/// L-B2). Far above the rounding of the phase (about 1e-13°), far below any step a grid resolves.
pub const PHASE_TIE_DEG: f64 = 1e-9;

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

    // A lowest frequency outside (0, Nyquist) is the setting's fault, named as such (audit s28 L-7:
    // `response --f-min 0` blamed the model file): Nyquist = 0.5 / Ts = 50 Hz at Ts = 0.01 s.
    #[test]
    fn a_lowest_frequency_outside_the_band_is_a_setting_error() {
        let m = first_order(0.9, 1.0, 0.01);
        for f in [0.0, -1.0, 50.0, 1e300] {
            let s = ResponseSettings {
                points: 10,
                f_min_hz: Some(f),
                samples: 100,
                controller: None,
            };
            match response(&m, &s) {
                Err(ControlError::Setting { setting, .. }) => {
                    assert_eq!(setting, ControlSetting::FMin, "{f}")
                }
                other => panic!("{f}: {other:?}"),
            }
        }
        let ok = ResponseSettings {
            points: 10,
            f_min_hz: Some(49.0),
            samples: 100,
            controller: None,
        };
        assert!(response(&m, &ok).is_ok());
    }

    // H = −1 at every frequency is a half turn: −180°, whether the minus sign is in b or in the gain
    // (the sign of a zero imaginary part gave +180° for b = −1 and −180° for gain −1).
    #[test]
    fn a_negative_real_response_has_phase_minus_180_however_its_sign_is_written() {
        let negative_b = Model::arx(0.1, vec![0.0], vec![-1.0], 0, None).unwrap();
        let positive_b = Model::arx(0.1, vec![0.0], vec![1.0], 0, None).unwrap();
        for b in [
            bode(&negative_b, 1.0, 0.01, 7),
            bode(&positive_b, -1.0, 0.01, 7),
        ] {
            for (i, ph) in b.phase_deg.iter().enumerate() {
                assert_eq!(*ph, -180.0, "point {i}: {b:?}");
            }
        }
    }

    // y(k) = 0.5 y(k−1) + u(k−1): arg G = −θ − atan2(0.5 sin θ, 1 − 0.5 cos θ), continuous from 0 at
    // θ = 0 to −180° at θ = π (the atan2 term is 0 there). On a 2-point grid the step to the Nyquist
    // point is a half turn to rounding (audit s21 L-B2: +180° on some grids); every grid gives −180°.
    #[test]
    fn the_phase_at_nyquist_is_minus_180_on_every_grid() {
        for ts in [
            0.01, 0.02, 0.03, 0.07, 0.11, 0.9, 1.0, 3.0, 7.0, 1e-6, 86_400.0,
        ] {
            let m = first_order(0.5, 1.0, ts);
            let nyquist = 0.5 / ts;
            for f_min in [1e-300, 1e-12 * nyquist, 1e-3 * nyquist, 0.5 * nyquist] {
                for points in [2, 3, 20] {
                    let b = bode(&m, 1.0, f_min, points);
                    let last = *b.phase_deg.last().unwrap();
                    assert!(
                        (last + 180.0).abs() < 1e-7,
                        "Ts {ts}, f_min {f_min}, {points} points: {last}"
                    );
                }
            }
        }
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

    // Audit s28 M-2: y(k) = 0.9 y(k−1) + 1e160 u(k−1) under a PI (Kp = Ki = 1): the loop polynomial
    // (1 − z⁻¹)(1 − 0.9 z⁻¹) + 1e160 (1.01 − z⁻¹) z⁻¹ has a root near −1e158 (unstable) that the
    // companion matrix does not give as a number. Its modulus is unknown and said so, never "0".
    // A loop of ordinary gains (b = 0.1) keeps its modulus and no such warning.
    #[test]
    fn a_loop_whose_poles_are_not_numbers_has_no_modulus_and_says_so() {
        let with = |b: f64| {
            let m = Model::arx(0.01, vec![-0.9], vec![b], 1, None).unwrap();
            let settings = ResponseSettings {
                controller: Some(ControllerSettings::pi(0.01, 1.0, 1.0)),
                ..ResponseSettings::default()
            };
            response(&m, &settings).unwrap()
        };
        let r = with(1e160);
        assert_eq!(r.margins.unwrap().closed_loop_max_pole_modulus, None);
        assert!(
            r.warnings
                .iter()
                .any(|w| w.contains("poles could not be computed")),
            "{:?}",
            r.warnings
        );
        let r = with(0.1);
        // 1 + (−1.9 + 0.101) z⁻¹ + (0.9 − 0.1) z⁻²: z² − 1.799 z + 0.8, |p|² = 0.8 for the complex pair.
        let p = r.margins.unwrap().closed_loop_max_pole_modulus.unwrap();
        let disc = 1.799f64 * 1.799 - 4.0 * 0.8;
        let want = if disc < 0.0 {
            0.8f64.sqrt()
        } else {
            (1.799 + disc.sqrt()) / 2.0
        };
        assert!((p - want).abs() < 1e-9, "{p} vs {want}");
        assert!(!r.warnings.iter().any(|w| w.contains("poles could not")));
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
        assert!((right.offset_db.unwrap() - 20.0 * 0.014f64.log10()).abs() < 1e-12);
        assert!((left.offset_db.unwrap() - 20.0 * 0.02f64.log10()).abs() < 1e-12);
        assert!(right.identified && left.identified);
        // G(1) = 1 / (1 − 0.9) = 10; from u: 0.14 mm/count on the right, 0.2 on the left.
        assert!((r.dc_gain.unwrap() - 10.0).abs() < 1e-12);
        assert!((right.dc_gain.unwrap() - 0.14).abs() < 1e-12);
        assert!((left.dc_gain.unwrap() - 0.2).abs() < 1e-12);
        assert!(r.gain.contains("b1 = 1") && r.gain.contains("m_r") && r.gain.contains("m_l"));
    }

    #[test]
    fn an_integrator_y_k_equals_y_k_minus_1_plus_u_k_minus_1_has_an_infinite_dc_gain() {
        // A = 1 − q⁻¹, B = 1, nk = 1: pole z = 1, G(1) = 1/0; the unit step ramps s(k) = k.
        let m = first_order(1.0, 1.0, 0.1);
        let r = response(&m, &ResponseSettings::default()).unwrap();
        assert_eq!(r.dc_gain, None);
        assert_eq!(r.dc_gain_note, Some(DC_INTEGRATOR));
        assert!(r.dc_gain_note.unwrap().contains("integrator"));
        for (k, s) in r.step.iter().enumerate() {
            assert_eq!(*s, k as f64);
        }
        // identify's own stability warning (the one verdict: a pole at z = 1 is an integrator, on the
        // stability boundary), then what it means for G(1).
        assert!(
            r.warnings[0].contains("a pole at z = 1 (modulus 1.0000000")
                && r.warnings[0].contains("on the stability boundary"),
            "{:?}",
            r.warnings
        );
        assert!(r.warnings[1].contains("integrator"), "{:?}", r.warnings);
    }

    #[test]
    fn a_near_integrator_within_the_margin_has_no_dc_gain_either() {
        // Pole 1 − 10⁻⁶, inside the stability band ε = sysid_core::stability::MARGIN = 10⁻⁵: G(1) = 1/10⁻⁶ would be a
        // number, but the step needs ~10⁶ samples to reach it.
        let r = response(
            &first_order(1.0 - 1e-6, 1.0, 0.1),
            &ResponseSettings::default(),
        )
        .unwrap();
        assert_eq!((r.dc_gain, r.dc_gain_note), (None, Some(DC_INTEGRATOR)));
        assert!(
            r.warnings[0].contains("on the stability boundary"),
            "{:?}",
            r.warnings
        );
    }

    #[test]
    fn an_unstable_pole_gives_no_dc_gain_not_the_wrong_signed_quotient() {
        // y(k) = 1.5 y(k−1) + u(k−1): Σb/(1+Σa) = 1/(1 − 1.5) = −2, but the step diverges:
        // s(k) = (1.5^k − 1)/0.5 > 0 and growing.
        let r = response(&first_order(1.5, 1.0, 0.1), &ResponseSettings::default()).unwrap();
        assert_eq!((r.dc_gain, r.dc_gain_note), (None, Some(DC_UNSTABLE)));
        assert!(
            r.warnings[0].starts_with("unstable model"),
            "{:?}",
            r.warnings
        );
        assert!(r.warnings[1].contains("not defined"), "{:?}", r.warnings);
        let k = 10;
        assert!((r.step[k] - (1.5f64.powi(k as i32) - 1.0) / 0.5).abs() < 1e-9);
        // A pole at −1 (on the circle, away from 1): oscillates, no DC gain.
        let r = response(&first_order(-1.0, 1.0, 0.1), &ResponseSettings::default()).unwrap();
        assert_eq!((r.dc_gain, r.dc_gain_note), (None, Some(DC_BOUNDARY)));
    }

    #[test]
    fn a_stable_settled_block_has_no_warning() {
        // Pole 0.5: after 20 samples the step is 2 (1 − 0.5^19) against G(1) = 2, within 2 %.
        let r = response(&first_order(0.5, 1.0, 0.1), &ResponseSettings::default()).unwrap();
        assert_eq!((r.dc_gain, r.dc_gain_note), (Some(2.0), None));
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
        // Five samples: s(4) = 2 (1 − 0.5^4) = 1.875, 93.75 % of G(1): not settled.
        let r = response(
            &first_order(0.5, 1.0, 0.1),
            &ResponseSettings {
                samples: 5,
                ..ResponseSettings::default()
            },
        )
        .unwrap();
        assert_eq!(r.warnings.len(), 1);
        assert!(r.warnings[0].contains("not settled by k = 4") && r.warnings[0].contains("94 %"));
    }

    #[test]
    fn coefficients_beyond_f64_are_an_error_naming_the_field() {
        // Σ|a_i| = 2e308 overflows: the poles would be NaN.
        let m = Model::arx(0.1, vec![1e308, 1e308], vec![1.0], 1, None).unwrap();
        let e = response(&m, &ResponseSettings::default()).unwrap_err();
        assert!(
            e.is_numerical() && e.to_string().contains("\"a\" coefficients"),
            "{e}"
        );
        let m = Model::arx(0.1, vec![-0.5], vec![1e308, 1e308], 1, None).unwrap();
        let e = response(&m, &ResponseSettings::default()).unwrap_err();
        assert!(e.to_string().contains("\"b\" coefficients"), "{e}");
    }

    #[test]
    fn a_deadzone_branch_fixed_at_zero_is_not_identified() {
        // identify's model of a one-sided input: m_l = b_l = 0 fixed. G(1) = 1/(1 − 0.9) = 10.
        let dz = Deadzone {
            b_l: 0.0,
            b_r: 0.0,
            m_l: 0.0,
            m_r: 0.05,
        };
        let m = Model::hammerstein(0.01, vec![-0.9], vec![1.0], 1, dz, None).unwrap();
        let r = response(
            &m,
            &ResponseSettings {
                samples: 200,
                ..ResponseSettings::default()
            },
        )
        .unwrap();
        let (right, left) = (&r.sides[0], &r.sides[1]);
        assert!(right.identified && !left.identified);
        assert!((right.dc_gain.unwrap() - 0.5).abs() < 1e-12);
        assert_eq!((left.offset_db, left.dc_gain), (None, None));
        assert!(r.gain.contains("m_l not identified"), "{}", r.gain);
        // The file's shape doubt (a zero slope) is repeated as validate repeats it.
        assert!(r
            .warnings
            .iter()
            .any(|w| w.starts_with("model: non-physical deadzone")));
    }
}
