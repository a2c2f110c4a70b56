//! Adaptive deadzone compensation on the physics plant (`ipa::Ipa` with its default parameters) whose
//! deadzone widens by Δ = 20 counts on each side at t = 20 s ([`control::Widened`]), against the fixed
//! compensator it starts from: the paper's Table III deadzone (b_l = −1.50, b_r = 1.41 counts), which
//! does not match the physics plant (`control --compensate-deadzone paper`, the case of issue 15).
//! Set-point 20 and 40 mm alternately, 10 s each, 60 s, the paper's PI (Kp = 14, Ki = 1 /s).
//!
//! The true deadzone of the physics plant, independently of the estimator:
//!
//! - from the valve parameters: a PWM pulse of duty |u|/255 over a period T_pwm opens the valve only if
//!   it is longer than the opening delay t_o, so no valve ever opens for |u| ≤ 255 t_o / T_pwm
//!   (= 255 · 0.4 / 10 = 10.2 counts with the defaults), i.e. ≤ 30.2 counts after the widening: a lower
//!   bound on the true |b|;
//! - from the plant itself, open loop: the smallest |u| on a 5-count grid that moves the piston by more
//!   than 1 mm in 3 s from rest mid-stroke (friction keeps it stuck below; docs/plant.md reports
//!   "no motion for |u| <= 35 counts ... full motion from about ±50"), plus Δ: an upper bound.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use control::{
    closed_loop, DeadzoneChange, DeadzoneCompensator, PiSettings, Profile, SlopeMode, Trace,
    Widened,
};
use ipa::{Ipa, PlantConfig};
use sysid_control::{run_adaptive, AdaptiveRun, AdaptiveSettings};
use sysid_core::{Model, Plant};

const HOLD_S: f64 = 10.0;
const DURATION_S: f64 = 60.0;
const CHANGE: DeadzoneChange = DeadzoneChange {
    at_s: 20.0,
    widen_counts: 20.0,
};

fn physics() -> Ipa {
    Ipa::new(PlantConfig::default()).unwrap()
}

/// Mean |r − y| over the last second of each 10-s hold.
fn hold_errors(trace: &Trace) -> Vec<f64> {
    let n_holds = (DURATION_S / HOLD_S).round() as usize;
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

/// (fixed, adaptive) runs from the paper's compensator.
fn runs() -> (Trace, AdaptiveRun, DeadzoneCompensator) {
    let profile = Profile::parse("staircase:20,40,20,40,20,40@10").unwrap();
    let comp =
        DeadzoneCompensator::new(*Model::paper().deadzone().unwrap(), SlopeMode::Shift, 255.0)
            .unwrap();
    let plant = || Widened::new(Box::new(physics()), CHANGE);
    let mut pi = PiSettings::paper().build(0.01).unwrap();
    let fixed = closed_loop::run(
        &mut plant(),
        &mut pi,
        Some(&comp),
        &profile,
        DURATION_S,
        0.0,
    )
    .unwrap();
    let mut pi = PiSettings::paper().build(0.01).unwrap();
    let adaptive = run_adaptive(
        &mut plant(),
        &mut pi,
        comp,
        &AdaptiveSettings::default(),
        &profile,
        DURATION_S,
        0.0,
    )
    .unwrap();
    (fixed, adaptive, comp)
}

/// The smallest |u| (5-count grid, `sign` ±1) that moves the un-widened plant by more than 1 mm in 3 s
/// from rest at 100 mm.
fn breakaway_counts(sign: f64) -> f64 {
    let mut p = physics();
    for c in (5..=40).map(|i| 5.0 * f64::from(i)) {
        p.reset(100.0);
        for _ in 0..300 {
            p.step(sign * c).unwrap();
        }
        if (p.output() - 100.0).abs() > 1.0 {
            return c;
        }
    }
    panic!("the plant never moved for |u| <= 200 counts");
}

// The paper's b_r = 1.41 counts is far below the physics plant's deadzone (≥ 10.2 counts where no valve
// opens, and ≈ 35–50 counts of friction breakaway, more than 50 after the widening): with the fixed
// compensator only the integral (Ki Ts = 0.01 count per mm and sample) pushes the command through it,
// so the piston sticks short of or past the set-point by up to ~1.4 mm (measured: 0.30, 1.00, 1.37,
// 0.72 mm at the ends of the holds after the change, `steady_state_error_mm` of `control --json`). The
// adaptive compensator moves b_r to the breakaway the estimate sees, so the PI output needs far less
// winding up (measured: mean of the last-second errors 0.85 mm fixed against 0.24 mm adaptive; under
// stick-slip the per-hold values are erratic, so only the mean over the four holds is compared).
#[test]
fn on_the_physics_plant_the_adaptive_compensator_is_no_worse_than_the_fixed_one_after_the_widening()
{
    let (fixed, adaptive, _) = runs();
    let (ef, ea) = (hold_errors(&fixed), hold_errors(&adaptive.trace));
    let after = |e: &[f64]| e[2..].iter().sum::<f64>() / 4.0;
    eprintln!("fixed {ef:?}\nadaptive {ea:?}");
    eprintln!(
        "mean after the change: fixed {} adaptive {}",
        after(&ef),
        after(&ea)
    );
    assert!(after(&ea) <= after(&ef), "adaptive {ea:?} fixed {ef:?}");
}

// Every compensator the loop used was plausible (breakpoints on their side of zero within half of
// u_max = 255, slopes within a factor 3 of the start: the default gate), and the final right breakpoint
// — the branch the holds at 20 → 40 mm exercise — lies between the valve-opening bound and the
// measured breakaway, both widened by Δ. A branch that never followed the estimate is named in the
// warnings instead of being reported silently.
#[test]
fn on_the_physics_plant_the_final_compensator_deadzone_is_physical_or_the_run_says_so() {
    let (_, adaptive, start) = runs();
    let cfg = PlantConfig::default();
    let opening = 255.0 * cfg.valve.opening_delay_ms / cfg.valve.pwm_period_ms;
    assert!((opening - 10.2).abs() < 1e-12);
    let d = CHANGE.widen_counts;
    for dz in &adaptive.deadzones {
        assert!(
            (0.0..=127.5).contains(&dz.b_r) && (-127.5..=0.0).contains(&dz.b_l),
            "{dz:?}"
        );
        let s = start.deadzone;
        assert!(dz.m_r >= s.m_r / 3.0 && dz.m_r <= 3.0 * s.m_r, "{dz:?}");
        assert!(dz.m_l >= s.m_l / 3.0 && dz.m_l <= 3.0 * s.m_l, "{dz:?}");
    }
    // The rate limit: 100 counts/s at Ts = 0.01 s is at most 1 count per sample.
    for w in adaptive.deadzones.windows(2) {
        assert!((w[1].b_r - w[0].b_r).abs() <= 1.0 + 1e-9, "{w:?}");
        assert!((w[1].b_l - w[0].b_l).abs() <= 1.0 + 1e-9, "{w:?}");
    }
    let last = adaptive.deadzones.last().unwrap();
    let (right, left) = (breakaway_counts(1.0), breakaway_counts(-1.0));
    eprintln!("breakaway +{right} / -{left} counts; final compensator {last:?}");
    eprintln!(
        "{:?} {:?}\n{:#?}",
        adaptive.right,
        adaptive.left,
        adaptive.warnings()
    );
    assert!(
        last.b_r >= opening + d && last.b_r <= right + d,
        "b_r = {} not within [{}, {}]",
        last.b_r,
        opening + d,
        right + d
    );
    if adaptive.left.following_since_change > 0 {
        assert!(
            last.b_l <= -(opening + d) && last.b_l >= -(left + d),
            "b_l = {}",
            last.b_l
        );
    } else {
        assert!(
            adaptive
                .warnings()
                .iter()
                .any(|w| w.contains("left (b_l, m_l) branch")
                    && (w.contains("never followed") || w.contains("did not follow"))),
            "{:?}",
            adaptive.warnings()
        );
    }
    // The raw estimate the old loop applied wandered off (issue 15: b_r = 105, m_l = 9e-5); whatever it
    // does now, an implausible final estimate is said in words.
    if let Some(e) = adaptive.final_estimate {
        let m0 = start.deadzone.m_r;
        let plausible_right =
            (0.0..=127.5).contains(&e.b_r) && e.m_r >= m0 / 3.0 && e.m_r <= 3.0 * m0;
        if !plausible_right {
            assert!(adaptive
                .warnings()
                .iter()
                .any(|w| w.contains("final online estimate of the right")));
        }
    }
}
