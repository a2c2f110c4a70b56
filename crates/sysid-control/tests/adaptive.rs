//! Adaptive deadzone compensation (`sysid_control::adaptive`) on the paper's model whose deadzone widens by
//! Δ = 20 counts on each side at t = 30 s ([`control::Widened`]), against the fixed compensator built
//! from the paper's deadzone. Set-point: 20 and 40 mm alternately, 10 s each, 100 s.
//!
//! Steady state of the loop by hand. The paper's A(1) = 1 − 1.869 + 0.9976 − 0.1284 = 2e-4 (a slow leak
//! towards y = 0), so holding y = r − e needs x = A(1) (r − e) > 0, on the right branch whichever way
//! the set-point was approached. With the compensator's breakpoint b̂_r the command is
//! u = b̂_r + Kp e (shift mode; Ki = 0), and the valve gives x = m_r (u − b_r,true):
//!
//! - b̂_r = b_r,true (no change, or an adapted compensator): A(1)(r − e) = m_r Kp e,
//!   e = A(1) r / (A(1) + m_r Kp);
//! - fixed b̂_r = b_r,true − Δ after the change: A(1)(r − e) = m_r (Kp e − Δ),
//!   e = (A(1) r + m_r Δ) / (A(1) + m_r Kp) — about Δ/Kp = 1.43 mm more.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic
#![allow(clippy::needless_range_loop)] // hold numbers index both runs and the set-point

use control::{
    closed_loop, DeadzoneChange, DeadzoneCompensator, PiSettings, Profile, SlopeMode, Trace,
    Widened,
};
use sysid_control::{run_adaptive, AdaptiveSettings};
use sysid_core::{Model, ModelPlant};

const HOLD_S: f64 = 10.0;
const CHANGE: DeadzoneChange = DeadzoneChange {
    at_s: 30.0,
    widen_counts: 20.0,
};
const A1: f64 = 1.0 - 1.869 + 0.9976 - 0.1284;
const M_R: f64 = 2.38 * 15.67e-4;
const KP: f64 = 14.0;

/// Mean |r − y| over the last second of each hold.
fn hold_errors(trace: &Trace) -> Vec<f64> {
    let n_holds = (trace.t.last().unwrap() / HOLD_S + 1e-9).floor() as usize;
    (0..n_holds)
        .map(|h| {
            let end = (h + 1) as f64 * HOLD_S;
            let e: Vec<f64> = (0..trace.len())
                .filter(|&k| trace.t[k] >= end - 1.0 - 1e-9 && trace.t[k] < end - 1e-9)
                .map(|k| (trace.r[k] - trace.y[k]).abs())
                .collect();
            e.iter().sum::<f64>() / e.len() as f64
        })
        .collect()
}

/// (fixed compensator, adaptive compensator) runs with gains Kp = 14 and `ki`.
fn runs(ki: f64) -> (Trace, sysid_control::AdaptiveRun) {
    let profile = Profile::parse("staircase:20,40,20,40,20,40,20,40,20,40@10").unwrap();
    let comp =
        DeadzoneCompensator::new(*Model::paper().deadzone().unwrap(), SlopeMode::Shift, 255.0)
            .unwrap();
    let plant = || {
        Widened::new(
            Box::new(ModelPlant::new(Model::paper(), "paper").unwrap()),
            CHANGE,
        )
    };
    let mut pi = PiSettings::new(KP, ki).build(0.01).unwrap();
    let fixed = closed_loop::run(&mut plant(), &mut pi, Some(&comp), &profile, 100.0, 0.0).unwrap();
    let mut pi = PiSettings::new(KP, ki).build(0.01).unwrap();
    let adaptive = run_adaptive(
        &mut plant(),
        &mut pi,
        comp,
        &AdaptiveSettings::default(),
        &profile,
        100.0,
        0.0,
    )
    .unwrap();
    (fixed, adaptive)
}

// Kp only: the fixed compensator keeps the extra error m_r Δ / (A(1) + m_r Kp) ≈ 1.42 mm in every hold
// after the change; the adaptive one is back at the no-change error once it has seen both branches.
#[test]
fn with_proportional_control_the_fixed_compensator_keeps_the_deadzone_error_and_the_adaptive_one_does_not(
) {
    let (fixed, adaptive) = runs(0.0);
    let (ef, ea) = (hold_errors(&fixed), hold_errors(&adaptive.trace));
    let r = |h: usize| if h % 2 == 0 { 20.0 } else { 40.0 };
    let matched = |h: usize| A1 * r(h) / (A1 + M_R * KP);
    let mismatched = |h: usize| (A1 * r(h) + M_R * CHANGE.widen_counts) / (A1 + M_R * KP);
    for h in 0..3 {
        assert!(
            (ef[h] - matched(h)).abs() < 2e-3,
            "hold {h}: {} vs {}",
            ef[h],
            matched(h)
        );
    }
    for h in 3..10 {
        assert!(
            (ef[h] - mismatched(h)).abs() < 0.01,
            "fixed, hold {h}: {} vs {}",
            ef[h],
            mismatched(h)
        );
        assert!(ef[h] > 1.4, "fixed, hold {h}: {}", ef[h]);
    }
    for h in 6..10 {
        assert!(
            (ea[h] - matched(h)).abs() < 0.01,
            "adaptive, hold {h}: {} vs {}",
            ea[h],
            matched(h)
        );
    }
    // The tracker flagged the change within a second of it, and the compensator's final deadzone is
    // the widened one (b_r + Δ, b_l − Δ).
    let k_change = (CHANGE.at_s / 0.01).round() as usize;
    assert!(adaptive
        .change_points
        .first()
        .is_some_and(|&k| (k_change..k_change + 100).contains(&k)));
    let last = adaptive.deadzones.last().unwrap();
    assert!((last.b_r - (1.41 + 20.0)).abs() < 0.05, "{last:?}");
    assert!((last.b_l - (-1.50 - 20.0)).abs() < 0.05, "{last:?}");
}

// The paper's PI (Kp = 14, Ki = 1 /s): the integral also removes the extra error, but only as fast as
// it can wind up by Δ: near the set-point Kp e + I ≈ Δ and dI/dt = Ki e give
// e(t) ≈ (Δ/Kp) exp(−Ki t / Kp), ≈ 0.7 mm at the end of the first 10-s hold after the change (time
// constant Kp/Ki = 14 s). The adaptive compensator removes the offset instead.
#[test]
fn with_the_papers_pi_the_adaptive_compensator_recovers_much_faster() {
    let ki = 1.0;
    let (fixed, adaptive) = runs(ki);
    let (ef, ea) = (hold_errors(&fixed), hold_errors(&adaptive.trace));
    let first = CHANGE.widen_counts / KP * (-ki * 9.0 / KP).exp();
    assert!(
        ef[3] > 0.6 * first,
        "fixed, first hold after the change: {}",
        ef[3]
    );
    assert!(ea[3] < 0.2 * first, "adaptive: {}", ea[3]);
    for h in 3..7 {
        assert!(
            ea[h] < 0.5 * ef[h],
            "hold {h}: adaptive {} fixed {}",
            ea[h],
            ef[h]
        );
    }
}

// A gate no estimate can pass (breakpoint deviation at most 1e-9 counts): both branches stay frozen, so
// the adaptive loop is the fixed one sample for sample, and the run says that neither branch followed.
#[test]
fn a_gate_no_estimate_passes_keeps_the_start_compensator_and_says_so() {
    let profile = Profile::parse("staircase:20,40,20,40@10").unwrap();
    let comp =
        DeadzoneCompensator::new(*Model::paper().deadzone().unwrap(), SlopeMode::Shift, 255.0)
            .unwrap();
    let plant = || {
        Widened::new(
            Box::new(ModelPlant::new(Model::paper(), "paper").unwrap()),
            CHANGE,
        )
    };
    let mut pi = PiSettings::paper().build(0.01).unwrap();
    let fixed = closed_loop::run(&mut plant(), &mut pi, Some(&comp), &profile, 40.0, 0.0).unwrap();
    let settings = AdaptiveSettings {
        max_breakpoint_sd_counts: 1e-9,
        ..AdaptiveSettings::default()
    };
    let mut pi = PiSettings::paper().build(0.01).unwrap();
    let a = run_adaptive(&mut plant(), &mut pi, comp, &settings, &profile, 40.0, 0.0).unwrap();
    assert_eq!(a.trace, fixed);
    assert!(a.deadzones.iter().all(|d| *d == comp.deadzone));
    assert_eq!((a.right.following, a.left.following), (0, 0));
    for side in ["right (b_r, m_r)", "left (b_l, m_l)"] {
        assert!(
            a.warnings()
                .iter()
                .any(|w| w.contains(side) && w.contains("never followed")),
            "{:?}",
            a.warnings()
        );
    }
    // Out-of-range settings are an error, not a silent default.
    let bad = AdaptiveSettings {
        slope_factor: 0.5,
        ..AdaptiveSettings::default()
    };
    let mut pi = PiSettings::paper().build(0.01).unwrap();
    assert!(run_adaptive(&mut plant(), &mut pi, comp, &bad, &profile, 1.0, 0.0).is_err());
}
