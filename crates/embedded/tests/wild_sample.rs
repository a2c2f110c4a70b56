//! Audit s31 M-6: one finite but wild position sample (an encoder glitch, a unit slip) winds the
//! back-calculation PI for minutes to hours. The auditor's scenario: Kp = 14 counts/mm, Ki = 1
//! counts/(mm·s), Ts = 0.01 s, u_max = 255, back-calculation with Tt = 14 s; 100 samples at r = 50 mm,
//! y = 49.9 mm, then one sample y = −1e6 mm, then y = 49.9 mm again. With a plausibility range the
//! wild sample is refused and the run goes on as if it had not been given; without one today's law
//! holds (checked against the value derived by hand below). The tuned controller
//! (`PositionController`, clamping anti-windup) is not wound through its integral, but its filtered
//! derivative carries the glitch: it takes the same range.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use ipa_embedded::{AntiWindup, Error, Float, Pi, PositionController, PositionSettings};

/// The auditor's controller, without a range.
fn auditors_pi<F: Float>() -> Pi<F> {
    let bc = AntiWindup::BackCalculation {
        tt_s: F::from_f64(14.0),
    };
    let f = F::from_f64;
    Pi::new(f(14.0), f(1.0), f(0.01), f(255.0), bc).unwrap()
}

/// `n` samples at r = 50 mm, y = 49.9 mm; the commands.
fn settle<F: Float>(pi: &mut Pi<F>, n: usize) -> Vec<F> {
    (0..n)
        .map(|_| pi.step(F::from_f64(50.0), F::from_f64(49.9)).unwrap())
        .collect()
}

// With the range [0, 200] mm the glitch y = −1e6 mm (and −1e10, −1e300) is refused with OutOfRange and
// the state is unchanged (the whole struct); the 1000 commands after it are bit for bit those of a
// controller without a range that never saw the glitch (the law itself is untouched by the range).
fn glitch_is_refused<F: Float>() {
    for glitch in [-1e6, -1e10, -1e300_f64] {
        let glitch = F::from_f64(glitch);
        if !glitch.is_finite() {
            continue; // f32: −1e300 is −∞, refused as NotFinite, not a finite wild sample
        }
        let mut ranged = auditors_pi::<F>()
            .with_range(F::from_f64(0.0), F::from_f64(200.0))
            .unwrap();
        let mut clean = auditors_pi::<F>();
        assert_eq!(settle(&mut ranged, 100), settle(&mut clean, 100));
        let before = ranged;
        assert_eq!(
            ranged.step(F::from_f64(50.0), glitch),
            Err(Error::OutOfRange)
        );
        assert_eq!(
            ranged, before,
            "a refused sample leaves the state unchanged"
        );
        let after: Vec<F> = settle(&mut ranged, 1000);
        let want: Vec<F> = settle(&mut clean, 1000);
        let bits = |v: &[F]| v.iter().map(|x| x.to_f64().to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&after), bits(&want), "glitch {glitch:?}");
        // e = 0.1 mm all along: the command stays positive (Kp e = 1.4 plus a growing integral).
        assert!(after.iter().all(|&u| u > F::ZERO));
    }
}

#[test]
fn a_wild_position_sample_is_refused_by_the_range_in_f64() {
    glitch_is_refused::<f64>();
}

#[test]
fn a_wild_position_sample_is_refused_by_the_range_in_f32() {
    glitch_is_refused::<f32>();
}

// The range is inclusive and applies to r as well as y; every refusal leaves the state unchanged,
// and a plausible sample after the refusals is taken.
fn set_point_and_bounds<F: Float>() {
    let f = F::from_f64;
    let mut pi = auditors_pi::<F>().with_range(f(0.0), f(200.0)).unwrap();
    assert_eq!(pi.range(), Some((f(0.0), f(200.0))));
    settle(&mut pi, 10);
    let before = pi;
    for (r, y) in [(250.0, 49.9), (-0.5, 49.9), (50.0, 200.5), (50.0, -0.5)] {
        assert_eq!(pi.step(f(r), f(y)), Err(Error::OutOfRange), "r {r}, y {y}");
        assert_eq!(pi, before);
    }
    // Non-finite is still NotFinite (checked first).
    assert_eq!(pi.step(f(50.0), -F::INFINITY), Err(Error::NotFinite));
    // The bounds themselves are plausible: e = 200 − 0 = 200 mm saturates at +255.
    assert_eq!(pi.step(f(200.0), f(0.0)), Ok(f(255.0)));
    assert_eq!(pi.step(f(0.0), f(200.0)), Ok(f(-255.0)));
}

#[test]
fn the_range_refuses_a_set_point_outside_it_and_keeps_its_bounds() {
    set_point_and_bounds::<f64>();
    set_point_and_bounds::<f32>();
}

// A range needs finite y_min < y_max: crossed, empty, NaN or infinite bounds are a Setting error.
#[test]
fn a_range_that_is_crossed_empty_or_not_finite_is_refused() {
    let pi = auditors_pi::<f64>();
    assert_eq!(pi.range(), None);
    for (lo, hi) in [
        (200.0, 0.0),
        (5.0, 5.0),
        (f64::NAN, 200.0),
        (0.0, f64::NAN),
        (f64::NEG_INFINITY, 200.0),
        (0.0, f64::INFINITY),
    ] {
        assert_eq!(pi.with_range(lo, hi), Err(Error::Setting), "[{lo}, {hi}]");
    }
    assert_eq!(
        auditors_pi::<f32>().with_range(1.0, -1.0),
        Err(Error::Setting)
    );
    assert!(pi.with_range(-5.0, 205.0).is_ok());
}

// Without a range the glitch is taken (today's law, kept bit for bit). By hand, with g = Ki Ts = 0.01,
// a = Ts/Tt = 1/1400: 100 samples at e = 0.1 mm are unsaturated (|v| ≤ 1.4 + 0.1 + 0.001), so the
// tracking term is 0 and I_100 = 100 × 0.001 = 0.1. The glitch: e = 50 + 1e6 = 1 000 050 mm,
// Kp e = 14 000 700, I_100 + g e = 10 000.6, v saturates (u = 255), and
// I = (I_100 + g e) + a (u − v) = (1 − a)(10 000.6) + a (255 − 14 000 700) = −9 605.6 / 1400
// = −6.861 142 857… counts. The next command is Kp 0.1 + I + g 0.1 = 1.4 − 6.8611… + 0.001 < 0: the
// controller now pushes away from r, and (unsaturated, tracking term 0) I climbs back by 0.001 per
// sample: the command stays negative for about (6.8611 − 1.401) / 0.001 ≈ 5 460 samples (the
// auditor measured 5 461).
fn glitch_without_range<F: Float>(tol: f64) {
    let f = F::from_f64;
    let mut pi = auditors_pi::<F>();
    settle(&mut pi, 100);
    assert!((pi.integral().to_f64() - 0.1).abs() < tol / 100.0);
    assert_eq!(pi.step(f(50.0), f(-1e6)), Ok(f(255.0)));
    let want = -9605.6 / 1400.0;
    let got = pi.integral().to_f64();
    assert!((got - want).abs() < tol, "I = {got}, by hand {want}");
    let next = pi.step(f(50.0), f(49.9)).unwrap().to_f64();
    let want_next = 1.4 + want + 0.001;
    assert!((next - want_next).abs() < tol, "{next} vs {want_next}");
    let mut negative = 1;
    while pi.step(f(50.0), f(49.9)).unwrap() < F::ZERO {
        negative += 1;
        assert!(negative < 10_000);
    }
    let by_hand = (-want_next) / 0.001;
    assert!(
        (negative as f64 - by_hand).abs() <= 2.0 + tol * 1e4,
        "{negative} samples negative, by hand {by_hand}"
    );
}

#[test]
fn without_a_range_the_glitch_winds_the_integral_as_derived_by_hand() {
    glitch_without_range::<f64>(1e-9);
    // f32: the glitch's terms are ~1.4e7 (one ulp = 1) divided by 1400, and 10 000.6 (ulp 1e-3).
    glitch_without_range::<f32>(1e-2);
}

/// A PID of the tuned controller's kind (Kp, Ki, Kd, Tf of crates/control/tests/data/s13_b_controller.json,
/// rounded): Ts = 0.01 s, hold band 0.02 mm, no fine band, compensator, nudge or approach.
fn tuned<F: Float>() -> PositionController<F> {
    let f = F::from_f64;
    let s = PositionSettings {
        ts: f(0.01),
        kp: f(8.55),
        ki: f(19.67),
        kd: f(0.24),
        tf: f(0.02),
        u_max: f(255.0),
        hold_band: f(0.02),
        fine_band: f(0.0),
        reset_on_crossing: true,
        nudge: None,
        brake: None,
        short: None,
    };
    PositionController::new(s, None).unwrap()
}

fn ctl_settle<F: Float>(c: &mut PositionController<F>, n: usize) -> Vec<u64> {
    (0..n)
        .map(|_| {
            let u = c.step(F::from_f64(50.0), F::from_f64(49.9)).unwrap();
            u.to_f64().to_bits()
        })
        .collect()
}

// The tuned controller with the range [0, 200]: the glitch y = −1e6 mm (and r = 250 mm) is refused,
// the state unchanged, and the commands after it are bit for bit those of a controller without a
// range that never saw the glitch. A bad range is a Setting error; the range survives `reset`.
fn tuned_glitch_is_refused<F: Float>() {
    let f = F::from_f64;
    let mut ranged = tuned::<F>().with_range(f(0.0), f(200.0)).unwrap();
    let mut clean = tuned::<F>();
    assert_eq!(clean.range(), None);
    assert_eq!(ranged.range(), Some((f(0.0), f(200.0))));
    assert_eq!(ctl_settle(&mut ranged, 100), ctl_settle(&mut clean, 100));
    let before = ranged;
    assert_eq!(ranged.step(f(50.0), f(-1e6)), Err(Error::OutOfRange));
    assert_eq!(ranged.step(f(250.0), f(49.9)), Err(Error::OutOfRange));
    assert_eq!(ranged, before);
    assert_eq!(ctl_settle(&mut ranged, 500), ctl_settle(&mut clean, 500));
    for (lo, hi) in [
        (1.0, 1.0),
        (200.0, 0.0),
        (f64::NAN, 1.0),
        (0.0, f64::INFINITY),
    ] {
        assert_eq!(
            tuned::<F>().with_range(f(lo), f(hi)),
            Err(Error::Setting),
            "[{lo}, {hi}]"
        );
    }
    ranged.reset();
    assert_eq!(ranged.range(), Some((f(0.0), f(200.0))));
}

#[test]
fn the_tuned_controller_refuses_a_wild_sample_outside_its_range() {
    tuned_glitch_is_refused::<f64>();
    tuned_glitch_is_refused::<f32>();
}

// Without a range the tuned controller takes the glitch: its clamping integral is held at the glitch
// (v saturates with e v > 0), but the filtered derivative, α = Tf/(Tf + Ts) = 2/3, carries it. By
// hand: D = 0 while y rests; the glitch gives D_g = (1 − α)(G + 49.9)/Ts, the return
// D_1 = α D_g − (1 − α)(G + 49.9)/Ts = −(1 − α)² (G + 49.9)/Ts, then D_n = α^(n−1) D_1. Meanwhile
// the PI part (e = 0.1 mm, unsaturated) is u_PI(n) = Kp 0.1 + I_100 + n Ki Ts 0.1 with
// I_100 = 100 Ki Ts 0.1 and the glitch adding nothing. The command u = sat(u_PI + Kd D) is negative
// (pushing away from r) while u_PI(n) + Kd D_n < 0: counted here from these formulas.
#[test]
fn without_a_range_the_tuned_controllers_derivative_carries_the_glitch() {
    for g in [1e6, 1e300] {
        let mut c = tuned::<f64>();
        ctl_settle(&mut c, 100);
        let i_100 = c.integral();
        assert!((i_100 - 100.0 * 19.67 * 0.01 * 0.1).abs() < 1e-9, "{i_100}");
        assert_eq!(c.step(50.0, -g), Ok(255.0));
        assert_eq!(c.integral(), i_100, "the clamping integral is held");
        let mut negative = 0;
        while c.step(50.0, 49.9).unwrap() < 0.0 {
            negative += 1;
            assert!(negative < 100_000);
        }
        let (alpha, ge) = (2.0 / 3.0, 19.67 * 0.01 * 0.1);
        let d_1 = -(1.0 - alpha) * (1.0 - alpha) * (g + 49.9) / 0.01;
        let mut by_hand = 0;
        let mut d = d_1;
        while 8.55 * 0.1 + i_100 + (by_hand + 1) as f64 * ge + 0.24 * d < 0.0 {
            by_hand += 1;
            d *= alpha;
        }
        assert!(
            (negative - by_hand as i64).abs() <= 1,
            "G {g:e}: {negative} samples negative, by hand {by_hand}"
        );
        assert!(negative >= if g > 1e10 { 1_000 } else { 30 });
    }
}
