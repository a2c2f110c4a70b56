//! Several inputs, one output (MISO): least squares for ARX with one B polynomial per input, and for the
//! Hammerstein model with a static deadzone per input (key-term separation per input, b1 = 1 for each
//! nonlinear input); an input can be declared linear (the IPA's two valves are the motivating case).
//!
//! y(k) = −Σ a_i y(k−i) + Σ_inputs Σ_j b_j^(m) x^(m)(k − nk_m − j + 1) + c, x^(m) = f_m(u^(m)).
//!
//! Regression θ: for each nonlinear input the key-term block [m_r, m_r b_r, m_l, m_l b_l] at
//! u^(m)(k − nk_m), then a1..a_na, then per input b1..b_nb (linear) or b2..b_nb (nonlinear, on the current
//! deadzone estimate), then c. The Hammerstein blocks are iterated as for one input (docs/paper.md): the
//! switching functions and x̂ are rebuilt from the current deadzones until θ changes by less than 1e-10
//! (relative) or `max_iterations`. Rows k ≥ k0 = max(na, nk_m + nb_m − 1 over the inputs).

use nalgebra::{DMatrix, DVector};

use sysid_core::param::deadzone_from_theta;
use sysid_core::{Deadzone, InputChannel, Model, ModelKind, StaticNonlinearity, SysidError};

/// One input of a MISO problem.
#[derive(Debug, Clone, PartialEq)]
pub struct MisoInput {
    /// Its name (the data column), kept in the model.
    pub name: String,
    /// u^(m)(k) (for the IPA: a valve command in PWM counts).
    pub u: Vec<f64>,
    /// nb_m: number of B coefficients (≥ 1).
    pub nb: usize,
    /// nk_m: delay in samples.
    pub nk: usize,
    /// A linear input (no static nonlinearity) in a Hammerstein model.
    pub linear: bool,
}

/// A fitted MISO model and how it was found.
#[derive(Debug, Clone, PartialEq)]
pub struct MisoFit {
    /// The model (one `InputChannel` per input, in the given order).
    pub model: Model,
    /// Key-term iterations (1 for ARX or when every input is linear).
    pub iterations: usize,
}

/// Estimates a MISO model of `kind` from `inputs` and `y` (Ts = `ts` s) by least squares (module docs).
pub fn identify_miso(
    inputs: &[MisoInput],
    y: &[f64],
    ts: f64,
    na: usize,
    kind: ModelKind,
    offset: bool,
    max_iterations: usize,
) -> Result<MisoFit, SysidError> {
    if inputs.is_empty() {
        return Err(SysidError::Data(
            "a MISO model needs at least one input".into(),
        ));
    }
    for m in inputs {
        if m.nb == 0 {
            return Err(SysidError::setting(
                sysid_core::Setting::Nb,
                format!("0 for input {}", m.name),
                "at least one B coefficient per input",
            ));
        }
        if m.u.len() != y.len() {
            return Err(SysidError::Data(format!(
                "input {} has {} samples but y has {}",
                m.name,
                m.u.len(),
                y.len()
            )));
        }
    }
    let nonlinear: Vec<bool> = inputs
        .iter()
        .map(|m| kind == ModelKind::Hammerstein && !m.linear)
        .collect();
    let k0 = inputs.iter().map(|m| m.nk + m.nb - 1).fold(na, usize::max);
    let n = y.len().saturating_sub(k0);
    let n_key = 4 * nonlinear.iter().filter(|&&v| v).count();
    let n_b: usize = inputs
        .iter()
        .zip(&nonlinear)
        .map(|(m, &nl)| if nl { m.nb - 1 } else { m.nb })
        .sum();
    let p = n_key + na + n_b + usize::from(offset);
    if n <= p {
        return Err(SysidError::Data(format!(
            "{} samples leave {n} regression rows for {p} parameters; more data or lower orders are needed",
            y.len()
        )));
    }
    let mut names = Vec::with_capacity(p);
    for (m, &nl) in inputs.iter().zip(&nonlinear) {
        if nl {
            for s in ["m_r", "m_r*b_r", "m_l", "m_l*b_l"] {
                names.push(format!("{s} ({})", m.name));
            }
        }
    }
    names.extend((1..=na).map(|i| format!("a{i}")));
    for (m, &nl) in inputs.iter().zip(&nonlinear) {
        let from = if nl { 2 } else { 1 };
        names.extend((from..=m.nb).map(|j| format!("b{j} ({})", m.name)));
    }
    if offset {
        names.push("c".into());
    }
    let target = DVector::from_iterator(n, y[k0..].iter().copied());
    let solve = |dz: &[Deadzone]| -> Result<Vec<f64>, SysidError> {
        let phi = DMatrix::from_fn(n, p, |r, c| {
            regressor(inputs, &nonlinear, dz, y, na, offset, k0 + r, c)
        });
        Ok(crate::ls::solve(&phi, &target, &names)?
            .theta
            .iter()
            .copied()
            .collect())
    };
    let (theta, dz, iterations) = key_term_iteration(&nonlinear, max_iterations, solve)?;
    // θ back to the model.
    let a = theta[n_key..n_key + na].to_vec();
    let mut i = n_key + na;
    let mut channels = Vec::with_capacity(inputs.len());
    for ((m, &nl), d) in inputs.iter().zip(&nonlinear).zip(&dz) {
        let (b, f) = if nl {
            let mut b = vec![1.0];
            b.extend_from_slice(&theta[i..i + m.nb - 1]);
            i += m.nb - 1;
            (b, StaticNonlinearity::Deadzone(*d))
        } else {
            let b = theta[i..i + m.nb].to_vec();
            i += m.nb;
            (b, StaticNonlinearity::Linear)
        };
        channels.push(InputChannel::new(m.name.clone(), m.nk, b, f)?);
    }
    let c = offset.then(|| theta[i]);
    Ok(MisoFit {
        model: Model::new(ts, a, channels, c)?,
        iterations,
    })
}

/// Start of the key-term iteration: breakpoints at 0 and unit slopes, so that x̂ = u in the b2.. columns of
/// the first solve.
pub const START_DEADZONE: Deadzone = Deadzone {
    b_l: 0.0,
    b_r: 0.0,
    m_l: 1.0,
    m_r: 1.0,
};

/// θ̂, the deadzones and the number of solves of the key-term iteration: `solve` gives θ̂ for given
/// deadzones (one per input; θ starts with a key-term block [m_r, m_r b_r, m_l, m_l b_l] per input whose
/// `nonlinear` entry is true), the deadzones are updated from θ̂, until θ̂ changes by less than 1e-10
/// (relative to its largest entry) or after `max_iterations` solves. Without a nonlinear input, one solve.
pub(crate) fn key_term_iteration(
    nonlinear: &[bool],
    max_iterations: usize,
    solve: impl Fn(&[Deadzone]) -> Result<Vec<f64>, SysidError>,
) -> Result<(Vec<f64>, Vec<Deadzone>, usize), SysidError> {
    let update = |theta: &[f64], dz: &mut [Deadzone]| {
        let mut i = 0;
        for (d, &nl) in dz.iter_mut().zip(nonlinear) {
            if nl {
                *d = deadzone_from_theta(&theta[i..i + 4], *d, f64::INFINITY);
                i += 4;
            }
        }
    };
    let mut dz = vec![START_DEADZONE; nonlinear.len()];
    let mut theta = solve(&dz)?;
    let mut iterations = 1;
    update(&theta, &mut dz);
    if nonlinear.iter().any(|&v| v) {
        while iterations < max_iterations.max(1) {
            let next = solve(&dz)?;
            iterations += 1;
            let change = next
                .iter()
                .zip(&theta)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            let scale = next.iter().fold(1e-300_f64, |m, v| m.max(v.abs()));
            theta = next;
            update(&theta, &mut dz);
            if change <= 1e-10 * scale {
                break;
            }
        }
    }
    Ok((theta, dz, iterations))
}

/// Entry `c` of the regressor φ(k) (module docs).
#[allow(clippy::too_many_arguments)]
fn regressor(
    inputs: &[MisoInput],
    nonlinear: &[bool],
    dz: &[Deadzone],
    y: &[f64],
    na: usize,
    offset: bool,
    k: usize,
    c: usize,
) -> f64 {
    let mut c = c;
    for ((m, &nl), d) in inputs.iter().zip(nonlinear).zip(dz) {
        if nl {
            if c < 4 {
                let uk = m.u[k - m.nk];
                let (hr, hl) = (d.h_r(uk), d.h_l(uk));
                return [hr * uk, -hr, hl * uk, -hl][c];
            }
            c -= 4;
        }
    }
    if c < na {
        return -y[k - 1 - c];
    }
    c -= na;
    for ((m, &nl), d) in inputs.iter().zip(nonlinear).zip(dz) {
        let (from, count) = if nl { (1, m.nb - 1) } else { (0, m.nb) };
        if c < count {
            let u = m.u[k - m.nk - (from + c)];
            return if nl { d.apply(u) } else { u };
        }
        c -= count;
    }
    if offset && c == 0 {
        1.0
    } else {
        0.0
    }
}
