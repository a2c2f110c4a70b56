//! Audit s19 M-1, L-1, L-2: settings and samples the embedded routines (and their C interface) must
//! refuse instead of returning a NaN command or silently dropping a value. Each expectation is derived
//! by hand in the comment above it.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use core::ffi::c_void;

use ipa_embedded::ffi::*;
use ipa_embedded::hammerstein::PaperHrls;
use ipa_embedded::position::MIN_TS_S;
use ipa_embedded::{
    AntiWindup, Error, HammersteinSettings, Pi, PositionController, PositionSettings,
};

/// A plain P controller: Kp = 3 counts/mm, Ki = Kd = 0, Tf = 0, u_max = 255, no bands, no modes.
fn p_only(ts: f64) -> PositionSettings<f64> {
    PositionSettings {
        ts,
        kp: 3.0,
        ki: 0.0,
        kd: 0.0,
        tf: 0.0,
        u_max: 255.0,
        hold_band: 0.0,
        fine_band: 0.0,
        reset_on_crossing: false,
        nudge: None,
        brake: None,
        short: None,
    }
}

// The floor is 1 µs: a subnormal Ts (the audit's 1e-310 s) and one just below the floor are refused,
// the floor itself is kept, by the embedded controller and by `control`'s controller settings alike.
#[test]
fn a_sampling_period_below_one_microsecond_is_refused_by_the_controller_and_by_control() {
    assert_eq!(MIN_TS_S, 1e-6);
    for ts in [1e-310, f64::MIN_POSITIVE, 0.99e-6] {
        assert_eq!(
            PositionController::new(p_only(ts), None).unwrap_err(),
            Error::Setting,
            "Ts = {ts:e}"
        );
        let e = control::ControllerSettings::pi(ts, 3.0, 0.0)
            .build()
            .unwrap_err();
        // The value as given (not "0.0000"): 1e-310, 2.2250738585072014e-308, 9.9e-7.
        let shown = format!("ts = {ts:e}");
        assert!(e.to_string().contains(&shown), "{e}");
    }
    assert!(PositionController::new(p_only(1e-6), None).is_ok());
    assert!(control::ControllerSettings::pi(1e-6, 3.0, 0.0)
        .build()
        .is_ok());
}

// Ts = 0.01 s, r = 50 mm. y = 0: u = 3 × 50 = 150. y = 1e308: the velocity (1e308 − 0) / 0.01 = 1e310
// overflows to +∞, D = −∞ and Kd D = 0 × (−∞) = NaN: refused, state unchanged. y = 1: u = 3 × 49 =
// 147, and the controller equals one that never saw the refused sample.
#[test]
fn a_command_that_would_be_nan_is_refused_and_the_state_kept() {
    let mut c = PositionController::new(p_only(0.01), None).unwrap();
    assert_eq!(c.step(50.0, 0.0).unwrap(), 150.0);
    let reference = c;
    assert_eq!(c.step(50.0, 1e308).unwrap_err(), Error::Numerical);
    assert_eq!(c, reference);
    assert_eq!(c.step(50.0, 1.0).unwrap(), 147.0);
}

// Kd = 1 counts·s/mm: at y = 1e308 the command is clamped to −255 (Kp e = −∞, D = −∞), but D itself is
// −∞ and would stay there with Tf > 0: refused. Then y = 1: D = −(1 − 0) / 0.01 = −100 and u = 3 × 49
// − 100 = 47.
#[test]
fn a_derivative_that_would_be_infinite_is_refused_even_when_the_clamp_hides_it() {
    let mut c = PositionController::new(
        PositionSettings {
            kd: 1.0,
            ..p_only(0.01)
        },
        None,
    )
    .unwrap();
    assert_eq!(c.step(50.0, 0.0).unwrap(), 150.0);
    let reference = c;
    assert_eq!(c.step(50.0, 1e308).unwrap_err(), Error::Numerical);
    assert_eq!(c, reference);
    assert_eq!(c.step(50.0, 1.0).unwrap(), 47.0);
}

// PI with Kp = 0, Ki = 1: r = 1e308, y = −1e308 gives e = 2e308 = +∞ and Kp e = 0 × ∞ = NaN: refused, I
// stays 0; then e = 1 gives u = Ki Ts e = 0.01. With Ki = 1e6 (the largest gain `Pi::new` takes), Ts = 1:
// I = 1e6 × ∞ = ∞ while u is clamped to 255: refused too.
#[test]
fn the_pi_step_refuses_a_nan_command_or_an_infinite_integral() {
    let mut pi = Pi::new(0.0, 1.0, 0.01, 255.0, AntiWindup::None).unwrap();
    assert_eq!(pi.step(1e308, -1e308).unwrap_err(), Error::Numerical);
    assert_eq!(pi.integral(), 0.0);
    assert_eq!(pi.step(1.0, 0.0).unwrap(), 0.01);
    let mut pi = Pi::new(1.0, 1e6, 1.0, 255.0, AntiWindup::None).unwrap();
    assert_eq!(pi.step(1e308, -1e308).unwrap_err(), Error::Numerical);
    assert_eq!(pi.integral(), 0.0);
}

// The documented domain b_l0 ≤ 0 ≤ b_r0: b_l0 = +1, b_r0 = −1, the crossed pair (+∞, −∞) and NaN are
// refused; the one-sided record's (−∞, +∞) and the boundary (0, 0) are kept.
#[test]
fn initial_breakpoints_outside_bl0_le_0_le_br0_are_refused() {
    let with = |b_l0: f64, b_r0: f64| {
        PaperHrls::new(HammersteinSettings {
            b_l0,
            b_r0,
            ..HammersteinSettings::paper()
        })
        .map(|_| ())
    };
    for (b_l0, b_r0) in [
        (1.0, 1.0),
        (-1.0, -1.0),
        (f64::INFINITY, f64::NEG_INFINITY),
        (f64::INFINITY, f64::INFINITY),
        (f64::NAN, 1.0),
    ] {
        assert_eq!(with(b_l0, b_r0), Err(Error::Setting), "{b_l0}, {b_r0}");
    }
    assert_eq!(with(f64::NEG_INFINITY, f64::INFINITY), Ok(()));
    assert_eq!(with(0.0, 0.0), Ok(()));
}

/// The C controller settings of [`p_only`] (every other field zero: no deadzone, nudge, brake or
/// short-step approach).
fn c_p_only(ts: f64) -> IpaController {
    // SAFETY: every field is an f64, i32, u32 or a struct of f64: all-zero bytes are a valid value.
    let mut c: IpaController = unsafe { core::mem::zeroed() };
    c.ts = ts;
    c.kp = 3.0;
    c.u_max = 255.0;
    c
}

// Through the C interface: the same refusals with their codes, the output never written on an error.
#[test]
fn the_c_interface_reports_the_refusals_with_their_codes() {
    let mut ctl = [0u64; IPA_CTL_STATE_BYTES / 8];
    let p = ctl.as_mut_ptr() as *mut c_void;
    let mut u = 42.0;
    unsafe {
        assert_eq!(
            ipa_ctl_init(p, IPA_CTL_STATE_BYTES, &c_p_only(1e-310)),
            IPA_ERR_SETTING
        );
        assert_eq!(ipa_ctl_step(p, 50.0, 0.0, &mut u), IPA_ERR_NOT_INITIALISED);
        assert_eq!(
            ipa_ctl_init(p, IPA_CTL_STATE_BYTES, &c_p_only(0.01)),
            IPA_OK
        );
        assert_eq!(ipa_ctl_step(p, 50.0, 0.0, &mut u), IPA_OK);
        assert_eq!(u, 150.0);
        u = 42.0;
        assert_eq!(ipa_ctl_step(p, 50.0, 1e308, &mut u), IPA_ERR_NUMERICAL);
        assert_eq!(u, 42.0);
        assert_eq!(ipa_ctl_step(p, 50.0, 1.0, &mut u), IPA_OK);
        assert_eq!(u, 147.0);
        // Audit s31 M-6: with the range [0, 200] mm y = −1e6 is refused (u untouched), a crossed range
        // too, and y = 2 then gives 3 × 48 = 144.
        assert_eq!(ipa_ctl_set_range(p, 200.0, 0.0), IPA_ERR_SETTING);
        assert_eq!(ipa_ctl_set_range(p, 0.0, 200.0), IPA_OK);
        u = 42.0;
        assert_eq!(ipa_ctl_step(p, 50.0, -1e6, &mut u), IPA_ERR_RANGE);
        assert_eq!(u, 42.0);
        assert_eq!(ipa_ctl_step(p, 50.0, 2.0, &mut u), IPA_OK);
        assert_eq!(u, 144.0);

        let mut pi = [0u64; IPA_PI_STATE_BYTES / 8];
        let q = pi.as_mut_ptr() as *mut c_void;
        assert_eq!(
            ipa_pi_init(q, IPA_PI_STATE_BYTES, 0.0, 1.0, 0.01, 255.0, 0, 0.0),
            IPA_OK
        );
        u = 42.0;
        assert_eq!(ipa_pi_step(q, 1e308, -1e308, &mut u), IPA_ERR_NUMERICAL);
        assert_eq!(u, 42.0);

        // The deadzone inverse: a NaN or ±∞ controller output is refused (a bad deadzone first).
        let dz = IpaDeadzone {
            b_l: -10.0,
            b_r: 10.0,
            m_l: 0.5,
            m_r: 0.5,
        };
        for v in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            u = 42.0;
            assert_eq!(
                ipa_dz_compensate(&dz, 0, 0.0, 255.0, v, &mut u),
                IPA_ERR_NOT_FINITE
            );
            assert_eq!(u, 42.0);
        }
        let bad = IpaDeadzone { b_l: 1.0, ..dz };
        assert_eq!(
            ipa_dz_compensate(&bad, 0, 0.0, 255.0, f64::NAN, &mut u),
            IPA_ERR_SETTING
        );
        // u = 5: f⁻¹(m_r u) = b_r + m_r u / m_r = 10 + 5 = 15.
        assert_eq!(ipa_dz_compensate(&dz, 0, 0.0, 255.0, 5.0, &mut u), IPA_OK);
        assert_eq!(u, 15.0);

        // The record start: a NaN or ±∞ command is reported, the outputs left alone; a finite record
        // gives the largest negative (−7), the smallest positive (12) and max |u| (100).
        let (mut bl, mut br, mut lim) = (42.0, 42.0, 42.0);
        for bad in [
            [f64::NAN, 1.0, -1.0],
            [f64::INFINITY, -0.0, 2.0],
            [1.0, 2.0, f64::NEG_INFINITY],
        ] {
            assert_eq!(
                ipa_hrls_record_start(bad.as_ptr(), 3, &mut bl, &mut br, &mut lim),
                IPA_ERR_NOT_FINITE
            );
            assert_eq!((bl, br, lim), (42.0, 42.0, 42.0));
        }
        let record = [0.0, 30.0, -7.0, 12.0, -100.0];
        assert_eq!(
            ipa_hrls_record_start(record.as_ptr(), 5, &mut bl, &mut br, &mut lim),
            IPA_OK
        );
        assert_eq!((bl, br, lim), (-7.0, 12.0, 100.0));

        // The estimator's initial breakpoints.
        let mut h = [0u64; IPA_HRLS_STATE_BYTES / 8];
        let r = h.as_mut_ptr() as *mut c_void;
        let init = |b_l0, b_r0| {
            ipa_hrls_init(
                r,
                IPA_HRLS_STATE_BYTES,
                3,
                1,
                1,
                1.0,
                1e6,
                b_l0,
                b_r0,
                255.0,
                0.0,
                IPA_FORM_STANDARD,
            )
        };
        assert_eq!(init(1.0, 1.0), IPA_ERR_SETTING);
        assert_eq!(init(f64::INFINITY, f64::NEG_INFINITY), IPA_ERR_SETTING);
        assert_eq!(init(f64::NEG_INFINITY, f64::INFINITY), IPA_OK);
    }
}

// Audit s21 L-B1: the range of Ts is 1e-6 to 1e4 s for the C interface as for a controller file
// (Ts = 1e308 s was taken by ipa_ctl_init, then Ki·Ts·Σe overflowed at every step). The ends are kept;
// just beyond either, 1e308, +∞ and NaN are refused with IPA_ERR_SETTING and by `control` naming ts.
// Model files take the same floor.
#[test]
fn a_sampling_period_outside_one_microsecond_to_1e4_s_is_refused_by_c_and_by_control() {
    assert_eq!((MIN_TS_S, ipa_embedded::MAX_TS_S), (1e-6, 1e4));
    assert_eq!(sysid::model::MIN_TS_S, MIN_TS_S);
    let mut ctl = [0u64; IPA_CTL_STATE_BYTES / 8];
    let p = ctl.as_mut_ptr() as *mut c_void;
    for ts in [1.0001e4, 1e6, 1e308, f64::INFINITY, f64::NAN, 0.99e-6] {
        let code = unsafe { ipa_ctl_init(p, IPA_CTL_STATE_BYTES, &c_p_only(ts)) };
        assert_eq!(code, IPA_ERR_SETTING, "Ts = {ts:e}");
        let e = control::ControllerSettings::pi(ts, 3.0, 0.0)
            .build()
            .unwrap_err();
        assert!(e.to_string().contains("from 1e-6 to 1e4"), "{e}");
    }
    for ts in [1e-6, 0.01, 3600.0, 1e4] {
        let code = unsafe { ipa_ctl_init(p, IPA_CTL_STATE_BYTES, &c_p_only(ts)) };
        assert_eq!(code, IPA_OK, "Ts = {ts:e}");
        assert!(control::ControllerSettings::pi(ts, 3.0, 0.0)
            .build()
            .is_ok());
    }
}

// One rule for a breakpoint on the wrong side of 0 (audit s32 L-8, issue 28ac): within 1e-9 · u_max
// (u_max = 255: 2.55e-7 counts) it is an estimate's rounding, taken as 0; beyond, refused. So
// b_l = +1e-12 · 255 = 2.55e-10 and b_r = −2.55e-10 are accepted as 0 and b_l = +1e-3, b_r = −1e-3
// refused, alike by `ipa_embedded::Compensator::new`, `control::DeadzoneCompensator::new`, the C
// deadzone inverse `ipa_dz_compensate` and the C controller's `ipa_ctl_init`. With b_l taken as 0,
// m_l = 0.5, shift mode, u = −10 gives x = 0.5 · (−10) = −5 and u_c = 0 + (−5)/0.5 = −10 exactly
// (−10 + 2.55e-10 had b_l been kept).
#[test]
fn a_breakpoint_within_rounding_of_zero_loads_alike_in_every_compensator() {
    use ipa_embedded::{Compensator, Deadzone, SlopeMode};
    let u_max = 255.0;
    let tiny = 1e-12 * u_max;
    for (b_l, b_r, accepted) in [
        (tiny, 10.0, true),
        (-10.0, -tiny, true),
        (tiny, -tiny, true),
        (1e-9 * u_max, 10.0, true),
        (1e-3, 10.0, false),
        (-10.0, -1e-3, false),
    ] {
        let case = format!("b_l {b_l:e}, b_r {b_r:e}");
        let dz = Deadzone {
            b_l,
            b_r,
            m_l: 0.5,
            m_r: 0.5,
        };
        let ours = Compensator::new(dz, SlopeMode::Shift, 0.0, u_max);
        let theirs = control::DeadzoneCompensator::new(
            sysid::Deadzone {
                b_l,
                b_r,
                m_l: 0.5,
                m_r: 0.5,
            },
            control::SlopeMode::Shift,
            u_max,
        );
        assert_eq!(ours.is_ok(), accepted, "{case}: {ours:?}");
        assert_eq!(theirs.is_ok(), accepted, "{case}: {theirs:?}");
        if let (Ok(o), Ok(t)) = (&ours, &theirs) {
            let want = (b_l.min(0.0), b_r.max(0.0));
            assert_eq!((o.deadzone().b_l, o.deadzone().b_r), want, "{case}");
            assert_eq!((t.deadzone.b_l, t.deadzone.b_r), want, "{case}");
        } else {
            assert_eq!(ours.unwrap_err(), Error::Setting, "{case}");
        }
        let c_dz = IpaDeadzone {
            b_l,
            b_r,
            m_l: 0.5,
            m_r: 0.5,
        };
        let mut u_c = 42.0;
        let rc = unsafe { ipa_dz_compensate(&c_dz, 0, 0.0, u_max, -10.0, &mut u_c) };
        if accepted {
            assert_eq!(rc, IPA_OK, "{case}");
            let want = if b_l > -10.0 { -10.0 } else { b_l - 10.0 };
            assert_eq!(u_c, want, "{case}");
        } else {
            assert_eq!((rc, u_c), (IPA_ERR_SETTING, 42.0), "{case}");
        }
        let mut c = c_p_only(0.01);
        c.has_deadzone = 1;
        c.deadzone = c_dz;
        let mut ctl = [0u64; IPA_CTL_STATE_BYTES / 8];
        let p = ctl.as_mut_ptr() as *mut c_void;
        let rc = unsafe { ipa_ctl_init(p, IPA_CTL_STATE_BYTES, &c) };
        assert_eq!(
            rc,
            if accepted { IPA_OK } else { IPA_ERR_SETTING },
            "{case}"
        );
    }
}
