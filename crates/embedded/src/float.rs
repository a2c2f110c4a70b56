//! The floating-point type of every state: `f64` (bit-for-bit with the `sysid` crate) or `f32`
//! (half the memory, for microcontrollers with a single-precision FPU).

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// The arithmetic the embedded routines need: IEEE 754 `+ − × ÷`, comparisons and a few constants.
/// Implemented for `f32` and `f64`; every operation is the hardware one (no `libm`).
pub trait Float:
    Copy
    + Debug
    + PartialOrd
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    /// 0.
    const ZERO: Self;
    /// 1.
    const ONE: Self;
    /// +∞.
    const INFINITY: Self;
    /// Whether the estimators add in exactly `sysid`'s order (f64: bit-for-bit agreement). `false`
    /// (f32, which has nothing to agree with) lets [`crate::Rls`] split its long sums in two halves
    /// so that the chain of dependent operations through P is shorter. Default `true`.
    const SYSID_ORDER: bool = true;
    /// Whether the value is neither infinite nor NaN.
    fn is_finite(self) -> bool;
    /// The nearest value of this type to `v` (exact for f64).
    fn from_f64(v: f64) -> Self;
    /// The value as f64 (exact).
    fn to_f64(self) -> f64;
    /// |x| (by comparison; NaN stays NaN).
    #[inline]
    fn abs(self) -> Self {
        if self < Self::ZERO {
            -self
        } else {
            self
        }
    }
    /// `self` limited to [lo, hi] (lo ≤ hi assumed; never panics): the same result as `f64::clamp`.
    #[inline]
    fn clamp_to(self, lo: Self, hi: Self) -> Self {
        let mut v = self;
        if v < lo {
            v = lo;
        }
        if v > hi {
            v = hi;
        }
        v
    }
}

impl Float for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const INFINITY: Self = f64::INFINITY;
    #[inline]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
    #[inline]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
}

impl Float for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const INFINITY: Self = f32::INFINITY;
    const SYSID_ORDER: bool = false;
    #[inline]
    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }
    #[inline]
    fn from_f64(v: f64) -> Self {
        v as f32
    }
    #[inline]
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
}
