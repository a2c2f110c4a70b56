//! Static nonlinearities x = f(u) of a Hammerstein model's inputs: the identity (a linear input) and the
//! asymmetric valve deadzone of paper eq. (1). To add one (saturation, backlash...), add a variant to
//! [`StaticNonlinearity`] and follow docs/architecture.md.

use serde::{Deserialize, Serialize};

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

/// The static nonlinearity f of one model input: x = f(u).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StaticNonlinearity {
    /// x = u: a linear input (ARX).
    Linear,
    /// The asymmetric deadzone of paper eq. (1).
    Deadzone(Deadzone),
}

impl StaticNonlinearity {
    /// x = f(u).
    #[inline]
    pub fn apply(&self, u: f64) -> f64 {
        match self {
            StaticNonlinearity::Linear => u,
            StaticNonlinearity::Deadzone(d) => d.apply(u),
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
            StaticNonlinearity::Linear => None,
        }
    }

    /// True when every parameter is finite.
    pub fn is_finite(&self) -> bool {
        match self {
            StaticNonlinearity::Linear => true,
            StaticNonlinearity::Deadzone(d) => d.is_finite(),
        }
    }
}
