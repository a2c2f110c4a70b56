//! `ipa-embedded`: the paper's recursive Hammerstein estimator, the plain RLS, the deadzone inverse
//! (compensator) and the PI position controller for microcontroller firmware.
//!
//! `#![no_std]`, no `alloc`, no heap: every state is a fixed-size value whose capacity is a const
//! generic, generic over `f64` and `f32` ([`Float`]). No panic is reachable from the API: every
//! failure is an [`Error`] (a C return code in [`ffi`]); the crate denies `unwrap`, `expect`, `panic!`
//! and slice indexing.
//!
//! | item | what | paper |
//! |---|---|---|
//! | [`rls::Rls`] | RLS with forgetting ρ (P itself, or its UD factors) and an optional trace bound on P | eqs. 9–12 |
//! | [`hammerstein::HammersteinRls`] | deadzone key-term regressor + RLS, switching functions from the latest θ̂ every sample | eqs. 1–12, eq. 8 as reconstructed in docs/paper.md §2.3 |
//! | [`deadzone::Deadzone`], [`deadzone::Compensator`] | the deadzone x = f(u) and its inverse | eq. 1 |
//! | [`pi::Pi`] | u = Kp e + Ki Ts Σe, saturated at ±u_max, with anti-windup | Table V controller |
//! | [`cusum::Cusum`] | change detection on normalised prediction errors | issue 15 part 4 |
//! | [`ffi`] | `extern "C"` functions with caller-provided storage (`include/ipa_embedded.h`) | — |
//!
//! Units: u is the valve command in PWM counts (±255), y the stroke position in mm, Ts the sampling
//! period in s. State sizes (bytes, checked by tests) and flops per sample are stated on each type and
//! in `docs/embedded.md`.
//!
//! The f64 estimator does the same floating-point operations in the same order as the `sysid` crate's
//! first RLS pass (`identify --method rls --passes 1`), so its estimates are bit-for-bit equal to
//! them (tests `tests/verify_sysid.rs` and the C example's test in the CLI crate).
#![no_std]
#![deny(missing_docs)]
#![deny(
    clippy::panic,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

#[cfg(feature = "std")]
extern crate std;

pub mod cusum;
pub mod deadzone;
pub mod ffi;
pub mod float;
pub mod hammerstein;
pub mod pi;
pub mod position;
pub mod rls;

pub use deadzone::{Compensator, Deadzone, SlopeMode};
pub use float::Float;
pub use hammerstein::{HammersteinRls, HammersteinSettings, Implausible};
pub use pi::{AntiWindup, Pi};
pub use position::{PositionController, PositionSettings, ShortApproachSettings};
pub use rls::{Form, Rls};

/// Largest sampling period Ts of the tuned position controller, s: with
/// [`position::MIN_TS_S`] (1e-6 s) the one range of Ts, checked by `ipa_ctl_init` and by `control`'s
/// controller files alike (audit s21 L-1: the C interface took Ts = 1e308 s, after which the integral
/// Ki·Ts·Σe overflowed at every step in the fine band). Model files take the same floor.
pub const MAX_TS_S: f64 = 1e4;

/// True when `ts` (s) is a sampling period the tuned position controller takes:
/// [`position::MIN_TS_S`] ≤ Ts ≤ [`MAX_TS_S`] (false for NaN).
pub fn ts_in_range(ts: f64) -> bool {
    (position::MIN_TS_S..=MAX_TS_S).contains(&ts)
}

/// A failure of an embedded routine. In the C interface each is a negative return code
/// ([`Error::code`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(i32)]
pub enum Error {
    /// A setting is out of range (ρ not in (0, 1], P(0) not positive and finite, a gain not finite, ...).
    Setting = -1,
    /// The model orders do not fit the state's fixed capacity (or nb = 0 for a Hammerstein model).
    Capacity = -2,
    /// An input sample (u, y, r) is not a finite number; the state is unchanged.
    NotFinite = -3,
    /// The update would meet a non-finite value (ρ + φᵀPφ or ε not finite: P or θ̂ overflowed, e.g. P
    /// wound up without the windup guard), or a controller step's command would not be finite
    /// ([`Pi::step`], [`PositionController::step`]); the state is unchanged. (P found indefinite with
    /// finite values is [`Error::Indefinite`].)
    Numerical = -4,
    /// A regressor or output buffer is shorter than the number of parameters / coefficients.
    Length = -5,
    /// C interface: a null pointer.
    Null = -6,
    /// C interface: the storage is too small or not aligned for the state.
    Storage = -7,
    /// C interface: the storage does not hold an initialised state.
    NotInitialised = -8,
    /// A controller sample whose set-point r or position y is outside the plausibility range the
    /// caller set ([`Pi::with_range`], [`PositionController::with_range`]), or an estimator sample
    /// whose position y is outside it or whose command |u| exceeds its `limit`
    /// ([`HammersteinRls::with_range`]): a wild sample (an encoder glitch, a unit slip) refused; the
    /// state is unchanged.
    OutOfRange = -9,
    /// The RLS update in the covariance form (eq. 12, [`Form::Standard`]) found ρ + φᵀPφ ≤ 0 with finite
    /// values: P is no longer positive definite. Rounding does this to eq. 12 when P's condition number
    /// outgrows the type's 1/ε: in f32 (1/ε ≈ 1.7 · 10⁷) on IPA records, whose lagged outputs are
    /// nearly collinear (docs/embedded.md "f32"), and in f64 too when P winds up without the windup
    /// guard (a long stretch without excitation, `tests/windup.rs`). The state is unchanged, but P does not recover by
    /// itself: later updates are mostly refused the same way, and θ̂ may have drifted in the updates
    /// between the loss and this first refusal. Remedy: the UD form ([`Form::Ud`], which keeps P
    /// positive semi-definite whatever the rounding, and never returns this error) in f32, or f64, and
    /// against windup the guard ([`Rls::with_max_trace`]). A
    /// restart of the covariance ([`Rls::restart_covariance`]) is no remedy: on the record of
    /// `tests/indefinite.rs` eq. 12 in f32 was refused again 14 samples after it.
    Indefinite = -10,
}

impl Error {
    /// The C return code (negative).
    pub fn code(self) -> i32 {
        self as i32
    }
}

#[cfg(all(feature = "panic-halt", not(feature = "std"), not(test)))]
#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // No panic is reachable from the API; this only satisfies the linker of a `std`-free static library.
    loop {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::mem::size_of;

    /// `n` rounded up to a multiple of `align`.
    fn round(n: usize, align: usize) -> usize {
        n.div_ceil(align) * align
    }

    // The sizes stated in the rustdoc and docs/embedded.md, from the field lists (f floats, w = usize).
    #[test]
    fn state_sizes() {
        let w = size_of::<usize>();
        // Rls<F, N>: N + N² + 6 floats (θ̂, P or its UD factors, ρ, T, p0, ρ̃, the UD guard's kept
        // trace t and its reference R), one usize, the one-byte form.
        let rls = |f: usize, n: usize| round((n + n * n + 6) * f + w + 1, f.max(w));
        assert_eq!(size_of::<Rls<f64, 7>>(), rls(8, 7));
        assert_eq!(size_of::<Rls<f32, 7>>(), rls(4, 7));
        // HammersteinRls<F, N, D>: the Rls, 2 D + 11 floats (9 and the plausibility range), five
        // usize.
        let hrls =
            |f: usize, n: usize, d: usize| round(rls(f, n) + (2 * d + 11) * f + 5 * w, f.max(w));
        assert_eq!(size_of::<hammerstein::PaperHrls<f64>>(), hrls(8, 7, 3));
        assert_eq!(size_of::<hammerstein::PaperHrls<f32>>(), hrls(4, 7, 3));
        assert_eq!(size_of::<HammersteinRls<f64, 19, 15>>(), hrls(8, 19, 15));
        // Pi: seven floats (Kp, Ki Ts, Ts, u_max, I and the range y_min, y_max) and the anti-windup
        // enum (a tag and Tt).
        assert_eq!(size_of::<Pi<f64>>(), 7 * 8 + 16);
        assert_eq!(size_of::<Pi<f32>>(), 7 * 4 + 8);
        // Deadzone: four floats; Compensator: six floats and the slope-mode byte.
        assert_eq!(size_of::<Deadzone<f64>>(), 32);
        assert_eq!(size_of::<Compensator<f64>>(), round(6 * 8 + 1, 8));
        assert_eq!(size_of::<Compensator<f32>>(), round(6 * 4 + 1, 4));
        // PositionController: settings (eight floats, a bool, the optional nudge settings: nine floats,
        // two u32 and the `None` tag), the optional compensator (the slope mode's spare values hold the
        // `None`), 13 floats (α, I, D, y(k−1), e(k−1), two breakaway commands, two learnt coasts, the
        // last nudge's y_0 and e_0, two ramp-and-cut rates per mm), the optional nudge under way (four
        // floats and three bools, whose spare values hold the `None`), the optional last cut (two
        // floats and a bool, whose spare values hold the `None`), a u32 and two bools; and (the
        // approach with braking) the optional brake settings (six floats, three u32 and, since session
        // 19, a bool; before it, padded, then a tag: an `Option` cannot use its settings' trailing
        // padding), its
        // phase (a tag, a bool and a u32: 8 bytes), r(k−1) and a bool; and (the learnt lead) two
        // floats τ_b(left), τ_b(right) and the optional last switch (two floats and a bool, whose
        // spare values hold the `None`); and (the short-step approach, session 17) the optional
        // short-step settings (six floats and two u32, then a tag, as the brake's), the phase grown
        // to a tag, two bools, a u32 and a float (the short drive's y_0): 576 bytes for f64 on a
        // 64-bit host (504 before it); 584 since the nudge's creep limit e_v (session 18); in session
        // 19 the brake's re-brake (a bool after the three u32, whose spare values hold the `None` of
        // the optional brake settings, so that their tag is gone) and the nudge's slip brake (a_p and
        // T_p in the nudge settings, and the brake under way, a bool and a u32 whose bool's spare
        // values hold the `None`); in session 20 the nudge's relearning (a bool after its two u32,
        // whose spare values hold the `None` of the optional nudge settings: the same size) and the
        // previews (a second bool in the brake settings, within their padding; a bool in the
        // short-step settings that takes the place of their `None` tag): the same sizes; in session
        // 23 the short-step approach's breakaway seed (two floats κ_s, v_s in its settings): 608;
        // and the held nudge's learnt cut fraction (a second bool in the nudge settings, within
        // their padding, and two floats g(left), g(right)): 624 bytes with both (session 24); 640
        // with the plausibility range (session 32).
        let a = |f: usize| f.max(4);
        let nudge = |f: usize| round(9 * f + 8 + 2, a(f));
        let brake = |f: usize| round(6 * f + 12 + 2, a(f));
        let short = |f: usize| round(round(8 * f + 8, a(f)) + 1, a(f));
        let settings = |f: usize| round(8 * f + 1 + nudge(f) + brake(f) + short(f), f);
        let nudging = |f: usize| round(4 * f + 3, f);
        let cut = |f: usize| round(2 * f + 1, f);
        let phase = |f: usize| round(f + 4 + 3, a(f));
        let ctl = |f: usize| {
            round(
                settings(f)
                    + round(6 * f + 1, f)
                    + 13 * f
                    + nudging(f)
                    + cut(f)
                    + 4
                    + 2
                    + phase(f)
                    + f
                    + 1
                    + 2 * f
                    + cut(f)
                    + 8
                    + 2 * f,
                f.max(4),
            )
        };
        // Since session 32 (audit s31 M-6) also the plausibility range: two floats y_min, y_max.
        let ranged = |f: usize| round(ctl(f) + 2 * f, f.max(4));
        assert_eq!(size_of::<PositionController<f64>>(), ranged(8));
        assert_eq!(size_of::<PositionController<f32>>(), ranged(4));
        if w == 8 {
            assert_eq!(ctl(8), 624);
            assert_eq!(ctl(4), 340);
            assert_eq!(ranged(8), 640);
            assert_eq!(ranged(4), 348);
        }
        assert!(ffi::ipa_ctl_state_size() <= ffi::IPA_CTL_STATE_BYTES);
        if w == 8 {
            // The numbers quoted in the documentation for a 64-bit host.
            assert_eq!(size_of::<Rls<f64, 7>>(), 512);
            assert_eq!(size_of::<Rls<f64, 9>>(), 784);
            assert_eq!(size_of::<Rls<f32, 7>>(), 264);
            assert_eq!(size_of::<Rls<f32, 9>>(), 400);
            assert_eq!(size_of::<hammerstein::PaperHrls<f64>>(), 688);
            assert_eq!(size_of::<hammerstein::PaperHrls<f32>>(), 376);
            assert_eq!(ffi::ipa_hrls_state_size(), 3480);
        }
        // Cusum: five floats and three usize.
        assert_eq!(size_of::<cusum::Cusum<f64>>(), 5 * 8 + 3 * w);
        assert_eq!(size_of::<cusum::Cusum<f32>>(), round(5 * 4 + 3 * w, w));
        assert!(ffi::ipa_hrls_state_size() <= ffi::IPA_HRLS_STATE_BYTES);
        assert!(ffi::ipa_pi_state_size() <= ffi::IPA_PI_STATE_BYTES);
    }
}
