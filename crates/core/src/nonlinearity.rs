//! Static nonlinearities x = f(u) of a Hammerstein model's inputs: the identity (a linear input) and the
//! asymmetric valve deadzone of paper eq. (1), saturation, deadzone with saturation, piecewise-linear and
//! polynomial maps (MATLAB `idnlhw`'s input nonlinearities). To add one, add a variant to
//! [`StaticNonlinearity`] and follow docs/architecture.md.

use serde::{Deserialize, Serialize};

use crate::SysidError;

/// Asymmetric deadzone x = f(u) (paper eq. 1):
///
/// ```text
/// x = m_l (u - b_l)   for u <= b_l
/// x = 0               for b_l < u < b_r
/// x = m_r (u - b_r)   for u >= b_r
/// ```
///
/// `u` is the valve command (PWM counts), `x` the internal variable that drives the linear block.
/// With the key-term normalisation b1 = 1 the slopes carry the static gain of the whole model.
///
/// ```
/// use sysid_core::Deadzone;
/// let dz = Deadzone { b_l: -1.5, b_r: 1.41, m_l: 2.0, m_r: 3.0 };
/// assert_eq!(dz.apply(0.0), 0.0);
/// assert!((dz.apply(2.41) - 3.0).abs() < 1e-12);
/// assert!((dz.apply(-2.5) + 2.0).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Deadzone {
    /// b_l: left breakpoint (counts), the most positive command that still moves the piston backwards.
    pub b_l: f64,
    /// b_r: right breakpoint (counts), the smallest command that moves the piston forwards.
    pub b_r: f64,
    /// m_l: slope of the left branch (units of x per count).
    pub m_l: f64,
    /// m_r: slope of the right branch (units of x per count).
    pub m_r: f64,
}

impl Deadzone {
    /// Evaluates x = f(u) (paper eq. 1); the sloped branches include their breakpoints.
    #[inline]
    pub fn apply(&self, u: f64) -> f64 {
        if u >= self.b_r {
            self.m_r * (u - self.b_r)
        } else if u <= self.b_l {
            self.m_l * (u - self.b_l)
        } else {
            0.0
        }
    }

    /// Switching function h_r(u) = [u >= b_r] (paper eq. 3).
    #[inline]
    pub fn h_r(&self, u: f64) -> f64 {
        if u >= self.b_r {
            1.0
        } else {
            0.0
        }
    }

    /// Switching function h_l(u) = [u <= b_l] (paper eq. 2).
    #[inline]
    pub fn h_l(&self, u: f64) -> f64 {
        if u <= self.b_l {
            1.0
        } else {
            0.0
        }
    }

    /// The smallest command u >= b_r that gives x (>= 0), or the largest u <= b_l that gives x (< 0):
    /// the deadzone inverse used by a compensating controller. Returns 0 for x = 0 and for a zero slope.
    pub fn inverse(&self, x: f64) -> f64 {
        if x > 0.0 && self.m_r > 0.0 {
            self.b_r + x / self.m_r
        } else if x < 0.0 && self.m_l > 0.0 {
            self.b_l + x / self.m_l
        } else {
            0.0
        }
    }
}

impl Deadzone {
    /// True when every parameter is a finite number.
    pub fn is_finite(&self) -> bool {
        [self.b_l, self.b_r, self.m_l, self.m_r]
            .iter()
            .all(|v| v.is_finite())
    }
}

/// The largest number of breakpoints K of a piecewise-linear nonlinearity (bounds what a file or flag
/// can make the tool allocate).
pub const MAX_BREAKPOINTS: usize = 8;

/// The largest degree D of a polynomial nonlinearity.
pub const MAX_DEGREE: usize = 8;

/// Asymmetric saturation x = m · clamp(u, s_l, s_r) (MATLAB `idSaturation` with gain m):
///
/// ```text
/// x = m s_l   for u <= s_l
/// x = m u     for s_l < u < s_r
/// x = m s_r   for u >= s_r
/// ```
///
/// ```
/// use sysid_core::Saturation;
/// let s = Saturation { s_l: -1.0, s_r: 2.0, m: 3.0 };
/// assert_eq!((s.apply(-5.0), s.apply(1.0), s.apply(7.0)), (-3.0, 3.0, 6.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Saturation {
    /// s_l: lower limit of the linear interval (units of u).
    pub s_l: f64,
    /// s_r: upper limit of the linear interval (units of u).
    pub s_r: f64,
    /// m: slope inside the interval (units of x per unit of u).
    pub m: f64,
}

impl Saturation {
    /// x = f(u).
    #[inline]
    pub fn apply(&self, u: f64) -> f64 {
        if u <= self.s_l {
            self.m * self.s_l
        } else if u >= self.s_r {
            self.m * self.s_r
        } else {
            self.m * u
        }
    }
    fn values(&self) -> [f64; 3] {
        [self.s_l, self.s_r, self.m]
    }
}

/// A valve that opens late and saturates: a deadzone (b_l, b_r) whose branches saturate at s_l < b_l
/// and s_r > b_r:
///
/// ```text
/// x = m_l (s_l − b_l)   for u <= s_l
/// x = m_l (u − b_l)     for s_l < u <= b_l
/// x = 0                 for b_l < u < b_r
/// x = m_r (u − b_r)     for b_r <= u < s_r
/// x = m_r (s_r − b_r)   for u >= s_r
/// ```
///
/// ```
/// use sysid_core::DeadzoneSaturation;
/// let d = DeadzoneSaturation { b_l: -1.0, b_r: 1.0, s_l: -3.0, s_r: 4.0, m_l: 2.0, m_r: 0.5 };
/// assert_eq!((d.apply(0.0), d.apply(3.0), d.apply(9.0)), (0.0, 1.0, 1.5));
/// assert_eq!((d.apply(-2.0), d.apply(-9.0)), (-2.0, -4.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DeadzoneSaturation {
    /// b_l: left deadzone breakpoint.
    pub b_l: f64,
    /// b_r: right deadzone breakpoint.
    pub b_r: f64,
    /// s_l: left saturation breakpoint (below b_l).
    pub s_l: f64,
    /// s_r: right saturation breakpoint (above b_r).
    pub s_r: f64,
    /// m_l: slope of the left branch.
    pub m_l: f64,
    /// m_r: slope of the right branch.
    pub m_r: f64,
}

impl DeadzoneSaturation {
    /// x = f(u); the sloped branches include their deadzone breakpoints, the saturated parts theirs.
    #[inline]
    pub fn apply(&self, u: f64) -> f64 {
        if u >= self.s_r {
            self.m_r * (self.s_r - self.b_r)
        } else if u >= self.b_r {
            self.m_r * (u - self.b_r)
        } else if u <= self.s_l {
            self.m_l * (self.s_l - self.b_l)
        } else if u <= self.b_l {
            self.m_l * (u - self.b_l)
        } else {
            0.0
        }
    }
    fn values(&self) -> [f64; 6] {
        [self.b_l, self.b_r, self.s_l, self.s_r, self.m_l, self.m_r]
    }
}

/// A continuous piecewise-linear map through the origin with K breakpoints p_1..p_K (MATLAB
/// `idPiecewiseLinear`, with f(0) = 0 since the offset c carries any constant): slope s_0 below p_1,
/// s_i between p_i and p_{i+1}, s_K above p_K:
///
/// ```text
/// x = s_0 u + Σ_i (s_i − s_{i−1}) [ (u − p_i)_+ − (−p_i)_+ ]
/// ```
///
/// ```
/// use sysid_core::PiecewiseLinear;
/// let f = PiecewiseLinear::new(&[1.0], &[2.0, 0.5]).unwrap();
/// assert_eq!((f.apply(0.5), f.apply(3.0), f.apply(-1.0)), (1.0, 3.0, -2.0));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PiecewiseLinear {
    k: usize,
    p: [f64; MAX_BREAKPOINTS],
    s: [f64; MAX_BREAKPOINTS + 1],
}

impl PiecewiseLinear {
    /// Breakpoints `p` (p_1 < … < p_K; an unsorted or repeated list is kept as given and named by
    /// [`StaticNonlinearity::shape_problems`]) and the K + 1 segment slopes `s`, the first left of p_1.
    /// Fails on K = 0, K above [`MAX_BREAKPOINTS`] or `s.len() != K + 1`.
    pub fn new(p: &[f64], s: &[f64]) -> Result<Self, SysidError> {
        let k = p.len();
        if k == 0 || k > MAX_BREAKPOINTS || s.len() != k + 1 {
            return Err(SysidError::Data(format!(
                "invalid model: a piecewise-linear nonlinearity needs 1 to {MAX_BREAKPOINTS} breakpoints and one \
                 slope more than breakpoints (got {k} breakpoints, {} slopes)",
                s.len()
            )));
        }
        let mut out = PiecewiseLinear {
            k,
            p: [0.0; MAX_BREAKPOINTS],
            s: [0.0; MAX_BREAKPOINTS + 1],
        };
        out.p[..k].copy_from_slice(p);
        out.s[..=k].copy_from_slice(s);
        Ok(out)
    }
    /// K: number of breakpoints.
    pub fn breakpoints(&self) -> &[f64] {
        &self.p[..self.k]
    }
    /// s_0..s_K: the segment slopes.
    pub fn slopes(&self) -> &[f64] {
        &self.s[..=self.k]
    }
    /// g_i(u) = (u − p_i)_+ − (−p_i)_+ (i from 1), the hinge through the origin.
    #[inline]
    pub fn hinge(&self, i: usize, u: f64) -> f64 {
        let p = self.p[i - 1];
        (u - p).max(0.0) - (-p).max(0.0)
    }
    /// x = f(u).
    #[inline]
    pub fn apply(&self, u: f64) -> f64 {
        let mut x = self.s[0] * u;
        for i in 1..=self.k {
            x += (self.s[i] - self.s[i - 1]) * self.hinge(i, u);
        }
        x
    }
}

/// A polynomial through the origin x = g_1 u + g_2 u² + … + g_D u^D (MATLAB `idPolynomial1D`; the
/// constant is the offset c's).
///
/// ```
/// use sysid_core::Polynomial;
/// let f = Polynomial::new(&[1.0, 0.0, -0.5]).unwrap();
/// assert_eq!(f.apply(2.0), 2.0 - 4.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Polynomial {
    d: usize,
    g: [f64; MAX_DEGREE],
}

impl Polynomial {
    /// Coefficients g_1..g_D; fails on D = 0 or D above [`MAX_DEGREE`].
    pub fn new(g: &[f64]) -> Result<Self, SysidError> {
        let d = g.len();
        if d == 0 || d > MAX_DEGREE {
            return Err(SysidError::Data(format!(
                "invalid model: a polynomial nonlinearity needs a degree from 1 to {MAX_DEGREE} (got {d})"
            )));
        }
        let mut out = Polynomial {
            d,
            g: [0.0; MAX_DEGREE],
        };
        out.g[..d].copy_from_slice(g);
        Ok(out)
    }
    /// g_1..g_D.
    pub fn coefficients(&self) -> &[f64] {
        &self.g[..self.d]
    }
    /// x = f(u) (Horner).
    #[inline]
    pub fn apply(&self, u: f64) -> f64 {
        self.coefficients()
            .iter()
            .rev()
            .fold(0.0, |acc, g| (acc + g) * u)
    }
}

/// The static nonlinearity f of one model input: x = f(u).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StaticNonlinearity {
    /// x = u: a linear input (ARX).
    Linear,
    /// The asymmetric deadzone of paper eq. (1).
    Deadzone(Deadzone),
    /// Asymmetric saturation.
    Saturation(Saturation),
    /// A deadzone whose branches saturate.
    DeadzoneSaturation(DeadzoneSaturation),
    /// A continuous piecewise-linear map with K breakpoints.
    PiecewiseLinear(PiecewiseLinear),
    /// A polynomial of degree D.
    Polynomial(Polynomial),
}

impl StaticNonlinearity {
    /// x = f(u).
    #[inline]
    pub fn apply(&self, u: f64) -> f64 {
        match self {
            StaticNonlinearity::Linear => u,
            StaticNonlinearity::Deadzone(d) => d.apply(u),
            StaticNonlinearity::Saturation(s) => s.apply(u),
            StaticNonlinearity::DeadzoneSaturation(d) => d.apply(u),
            StaticNonlinearity::PiecewiseLinear(p) => p.apply(u),
            StaticNonlinearity::Polynomial(p) => p.apply(u),
        }
    }

    /// x = f(u) for every sample of `u`: [`StaticNonlinearity::apply`] with the choice of map made once
    /// for the record instead of once per sample (the same numbers).
    pub fn apply_all(&self, u: &[f64]) -> Vec<f64> {
        match self {
            StaticNonlinearity::Linear => u.to_vec(),
            StaticNonlinearity::Deadzone(d) => u.iter().map(|&v| d.apply(v)).collect(),
            StaticNonlinearity::Saturation(s) => u.iter().map(|&v| s.apply(v)).collect(),
            StaticNonlinearity::DeadzoneSaturation(d) => u.iter().map(|&v| d.apply(v)).collect(),
            StaticNonlinearity::PiecewiseLinear(p) => u.iter().map(|&v| p.apply(v)).collect(),
            StaticNonlinearity::Polynomial(p) => u.iter().map(|&v| p.apply(v)).collect(),
        }
    }

    /// A u with f(u) = x, for an output nonlinearity y = g(v) whose linear block starts from measured
    /// outputs: v(k) = g⁻¹(y(k)) for k < k0 (audit s31 M-1: v(k) = y(k) started a Hammerstein–Wiener
    /// model's state 19 % off when g's gain was 1.19). Linear: x. Saturation: x / m clamped into
    /// [s_l, s_r] (an x beyond the limits maps to the nearest limit). Otherwise the root of f(u) = x
    /// nearest to u = x, found by stepping out from x by doubling steps (1e-6·(1 + |x|) up to 2⁶⁰ times
    /// that) on both sides until f − x changes sign, then bisecting (80 halvings); when no sign change
    /// is found (x outside f's range, or f flat), the probe where |f(u) − x| is smallest. Not finite
    /// x: x.
    pub fn preimage(&self, x: f64) -> f64 {
        if !x.is_finite() {
            return x;
        }
        match self {
            StaticNonlinearity::Linear => x,
            StaticNonlinearity::Saturation(s) if s.m != 0.0 && s.m.is_finite() => {
                (x / s.m).clamp(s.s_l.min(s.s_r), s.s_r.max(s.s_l))
            }
            _ => {
                let r = |u: f64| self.apply(u) - x;
                let r0 = r(x);
                if r0 == 0.0 {
                    return x;
                }
                let (mut best, mut best_r) = (x, r0.abs());
                let mut step = 1e-6 * (1.0 + x.abs());
                for _ in 0..=60 {
                    for u in [x - step, x + step] {
                        let ru = r(u);
                        if !ru.is_finite() {
                            continue;
                        }
                        if ru.abs() < best_r {
                            (best, best_r) = (u, ru.abs());
                        }
                        if ru == 0.0 {
                            return u;
                        }
                        if ru.signum() != r0.signum() {
                            // A root between x and u: bisect.
                            let (mut a, mut b) = (x, u);
                            for _ in 0..80 {
                                let m = 0.5 * (a + b);
                                let rm = r(m);
                                if rm == 0.0 || m == a || m == b {
                                    return m;
                                }
                                if rm.signum() == r0.signum() {
                                    a = m;
                                } else {
                                    b = m;
                                }
                            }
                            return 0.5 * (a + b);
                        }
                    }
                    step *= 2.0;
                }
                best
            }
        }
    }

    /// df/du at u (the derivative of the branch u lies on, as [`StaticNonlinearity::apply`] assigns a
    /// kink); used for an output nonlinearity's sensitivities and invertibility checks.
    pub fn slope(&self, u: f64) -> f64 {
        match self {
            StaticNonlinearity::Linear => 1.0,
            StaticNonlinearity::Deadzone(d) => {
                if u >= d.b_r {
                    d.m_r
                } else if u <= d.b_l {
                    d.m_l
                } else {
                    0.0
                }
            }
            StaticNonlinearity::Saturation(s) => {
                if u <= s.s_l || u >= s.s_r {
                    0.0
                } else {
                    s.m
                }
            }
            StaticNonlinearity::DeadzoneSaturation(d) => {
                if u >= d.s_r || u <= d.s_l {
                    0.0
                } else if u >= d.b_r {
                    d.m_r
                } else if u <= d.b_l {
                    d.m_l
                } else {
                    0.0
                }
            }
            StaticNonlinearity::PiecewiseLinear(p) => {
                let i = p.breakpoints().iter().filter(|b| u >= **b).count();
                p.slopes()[i]
            }
            StaticNonlinearity::Polynomial(p) => p
                .coefficients()
                .iter()
                .enumerate()
                .rev()
                .fold(0.0, |acc, (i, g)| acc * u + (i + 1) as f64 * g),
        }
    }

    /// True for the identity.
    pub fn is_linear(&self) -> bool {
        matches!(self, StaticNonlinearity::Linear)
    }

    /// The deadzone, if this is one.
    pub fn deadzone(&self) -> Option<&Deadzone> {
        match self {
            StaticNonlinearity::Deadzone(d) => Some(d),
            _ => None,
        }
    }

    /// The parameters of the nonlinearity (empty for the identity), in the order of its block's
    /// physical parameters.
    pub fn values(&self) -> Vec<f64> {
        match self {
            StaticNonlinearity::Linear => Vec::new(),
            StaticNonlinearity::Deadzone(d) => vec![d.b_l, d.b_r, d.m_l, d.m_r],
            StaticNonlinearity::Saturation(s) => s.values().to_vec(),
            StaticNonlinearity::DeadzoneSaturation(d) => d.values().to_vec(),
            StaticNonlinearity::PiecewiseLinear(p) => {
                p.breakpoints().iter().chain(p.slopes()).copied().collect()
            }
            StaticNonlinearity::Polynomial(p) => p.coefficients().to_vec(),
        }
    }

    /// Number of parameters (what an information criterion counts; b1 = 1 of the linear block is not
    /// one of them).
    pub fn parameter_count(&self) -> usize {
        self.values().len()
    }

    /// True when every parameter is finite.
    pub fn is_finite(&self) -> bool {
        self.values().iter().all(|v| v.is_finite())
    }

    /// What makes this map not the physical shape its kind names, whatever the data (each a phrase,
    /// empty when nothing does): a deadzone whose breakpoints cross (b_l > b_r), with a zero slope or
    /// slopes of opposite signs; a saturation without a linear interval (s_l ≥ s_r) or with m = 0; a
    /// deadzone–saturation whose branch saturates before it opens (s_l ≥ b_l or s_r ≤ b_r), whose
    /// breakpoints cross, or whose slopes are zero or of opposite signs; a piecewise-linear map or a
    /// polynomial that is zero everywhere. A model file's reader repeats these as warnings
    /// (`model_file::load_warnings`): such a model still simulates, but its input or output map is not
    /// what its kind says, so its results need care.
    pub fn shape_problems(&self) -> Vec<String> {
        let mut out = Vec::new();
        let slopes = |out: &mut Vec<String>, m_l: f64, m_r: f64| {
            if m_l == 0.0 || m_r == 0.0 {
                out.push(format!(
                    "a slope is zero (m_l = {m_l}, m_r = {m_r}), so it does not respond beyond that breakpoint \
                     (the model of a one-sided input, whose unexcited branch identify fixes at 0, is such a \
                     map: commands on that side do nothing in it)"
                ));
            } else if m_l * m_r < 0.0 {
                out.push(format!(
                    "the slopes have opposite signs (m_l = {m_l}, m_r = {m_r})"
                ));
            }
        };
        match self {
            StaticNonlinearity::Linear => {}
            StaticNonlinearity::Deadzone(d) => {
                if d.b_l > d.b_r {
                    out.push(format!(
                        "b_l = {} > b_r = {} (the breakpoints cross)",
                        d.b_l, d.b_r
                    ));
                }
                slopes(&mut out, d.m_l, d.m_r);
            }
            StaticNonlinearity::Saturation(s) => {
                if s.s_l >= s.s_r {
                    out.push(format!(
                        "s_l = {} >= s_r = {} (no linear interval: the limits cross)",
                        s.s_l, s.s_r
                    ));
                }
                if s.m == 0.0 {
                    out.push("its slope m is zero, so it does not respond at all".into());
                }
            }
            StaticNonlinearity::DeadzoneSaturation(d) => {
                if d.b_l > d.b_r {
                    out.push(format!(
                        "b_l = {} > b_r = {} (the breakpoints cross)",
                        d.b_l, d.b_r
                    ));
                }
                if d.s_l >= d.b_l {
                    out.push(format!(
                        "s_l = {} >= b_l = {} (the left branch saturates before it opens)",
                        d.s_l, d.b_l
                    ));
                }
                if d.s_r <= d.b_r {
                    out.push(format!(
                        "s_r = {} <= b_r = {} (the right branch saturates before it opens)",
                        d.s_r, d.b_r
                    ));
                }
                slopes(&mut out, d.m_l, d.m_r);
            }
            StaticNonlinearity::PiecewiseLinear(p) => {
                if p.slopes().iter().all(|s| *s == 0.0) {
                    out.push("every slope is zero, so it does not respond at all".into());
                }
                // Segment i lies between p_i and p_{i+1}: an unsorted or repeated list defines no map
                // (audit s17 L-c: a hand-edited [0.5, 0.06] was simulated without a word).
                if p.breakpoints().windows(2).any(|w| w[0] >= w[1]) {
                    out.push(format!(
                        "the breakpoints {:?} are not strictly increasing, so the segments between them \
                         are not defined (list each breakpoint once, in increasing order)",
                        p.breakpoints()
                    ));
                }
            }
            StaticNonlinearity::Polynomial(p) => {
                if p.coefficients().iter().all(|g| *g == 0.0) {
                    out.push("every coefficient is zero, so it does not respond at all".into());
                }
            }
        }
        out
    }

    /// The kind's name as the model file and `--nonlinearity` spell it.
    pub fn kind_name(&self) -> &'static str {
        match self {
            StaticNonlinearity::Linear => "linear",
            StaticNonlinearity::Deadzone(_) => "deadzone",
            StaticNonlinearity::Saturation(_) => "saturation",
            StaticNonlinearity::DeadzoneSaturation(_) => "deadzone-saturation",
            StaticNonlinearity::PiecewiseLinear(_) => "piecewise-linear",
            StaticNonlinearity::Polynomial(_) => "polynomial",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Each kind's physical shape gives no problem; each way of breaking it is named once, by the
    // parameter values it breaks with.
    #[test]
    fn shape_problems_name_each_broken_rule() {
        let dz = |b_l, b_r, m_l, m_r| StaticNonlinearity::Deadzone(Deadzone { b_l, b_r, m_l, m_r });
        assert!(dz(-5.0, 5.0, 1.0, 2.0).shape_problems().is_empty());
        let crossed = dz(5.0, -5.0, 1.0, 1.0).shape_problems();
        assert_eq!(crossed.len(), 1);
        assert!(crossed[0].contains("b_l = 5 > b_r = -5"), "{crossed:?}");
        assert!(dz(-5.0, 5.0, 1.0, -1.0).shape_problems()[0].contains("opposite signs"));
        assert!(dz(-5.0, 5.0, 0.0, 1.0).shape_problems()[0].contains("zero"));

        let sat = |s_l, s_r, m| StaticNonlinearity::Saturation(Saturation { s_l, s_r, m });
        assert!(sat(-1.0, 2.0, 3.0).shape_problems().is_empty());
        let p = sat(84.0, 49.0, 1.7).shape_problems();
        assert_eq!(p.len(), 1);
        assert!(p[0].contains("s_l = 84 >= s_r = 49"), "{p:?}");
        // Equal limits leave no linear interval either; a zero slope is a second problem.
        assert_eq!(sat(1.0, 1.0, 0.0).shape_problems().len(), 2);

        let ds = |b_l, b_r, s_l, s_r| {
            StaticNonlinearity::DeadzoneSaturation(DeadzoneSaturation {
                b_l,
                b_r,
                s_l,
                s_r,
                m_l: 2.0,
                m_r: 0.5,
            })
        };
        assert!(ds(-1.0, 1.0, -3.0, 4.0).shape_problems().is_empty());
        let p = ds(-1.0, 1.0, -0.5, 0.5).shape_problems();
        assert_eq!(p.len(), 2, "{p:?}");
        assert!(p[0].contains("s_l = -0.5 >= b_l = -1") && p[1].contains("s_r = 0.5 <= b_r = 1"));

        let pwl = PiecewiseLinear::new(&[1.0], &[0.0, 0.0]).unwrap();
        assert_eq!(
            StaticNonlinearity::PiecewiseLinear(pwl)
                .shape_problems()
                .len(),
            1
        );
        let pwl = PiecewiseLinear::new(&[1.0], &[0.0, 1.0]).unwrap();
        assert!(StaticNonlinearity::PiecewiseLinear(pwl)
            .shape_problems()
            .is_empty());
        let poly = Polynomial::new(&[0.0, 0.0]).unwrap();
        assert_eq!(
            StaticNonlinearity::Polynomial(poly).shape_problems().len(),
            1
        );
        assert!(StaticNonlinearity::Linear.shape_problems().is_empty());
    }
}
