//! Accuracy of the production integrator (adaptive Dormand–Prince 5(4), default tolerance) against a
//! 16×-refined reference.
//!
//! **The 16×-refined reference** is the classical RK4 integrator the plant used before
//! ([`Integrator::Rk4`]: fixed substeps cut at every valve switching instant, events located by Illinois
//! root finding on the substep length) with both of its substep limits divided by 16: 0.25 ms / 16 =
//! 15.6 µs, and 0.0625 ms / 16 = 3.9 µs in the Stribeck region. It shares only the right-hand side
//! (the plant equations) with the production integrator: its step control, event detection and event
//! location are separate code. (`physics.rs` checks that the reference itself has converged: refining
//! the default RK4 substeps 16 times changes the position by less than 1e-6 mm.)
//!
//! The comparison is on the true, unquantised position (`Ipa::position_mm`, before the 0.01 mm
//! encoder), at every sample, over the whole record.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use ipa::plant::Integrator;
use ipa::{Ipa, PlantConfig};
use sysid_core::Plant;

/// Largest allowed position difference to the reference, mm (issue 16).
const BOUND_MM: f64 = 1e-3;

/// Position (mm) after each sample, the number of samples that end stuck (friction or end stop) and
/// the number that end at an end stop, for the commands `u` from rest at 100 mm.
fn run(integrator: Integrator, refine: f64, u: &[f64]) -> (Vec<f64>, usize, usize) {
    let mut cfg = PlantConfig::default();
    cfg.integration.max_substep_ms /= refine;
    cfg.integration.slow_substep_ms /= refine;
    let mut p = Ipa::new(cfg).unwrap();
    p.set_integrator(integrator);
    assert_eq!(p.integrator(), integrator);
    p.reset(100.0);
    let (mut stuck, mut at_end) = (0, 0);
    let x = u
        .iter()
        .map(|&uk| {
            p.step(uk).unwrap();
            let x = p.position_mm();
            stuck += usize::from(p.is_stuck());
            at_end += usize::from(x <= 0.0 || x >= 200.0);
            x
        })
        .collect();
    (x, stuck, at_end)
}

/// The production integrator stays within BOUND_MM of the reference over the record; returns the
/// largest difference (mm) and the reference's stuck and end-stop sample counts.
fn check(name: &str, u: &[f64]) -> (f64, usize, usize) {
    let (reference, stuck, at_end) = run(Integrator::Rk4, 16.0, u);
    let (production, _, _) = run(Integrator::DormandPrince, 1.0, u);
    let (k, err) = production
        .iter()
        .zip(&reference)
        .map(|(a, b)| (a - b).abs())
        .enumerate()
        .fold((0, 0.0_f64), |m, (k, e)| if e > m.1 { (k, e) } else { m });
    println!(
        "{name}: max |x - x_ref| = {err:.3e} mm at sample {k} of {}; {stuck} samples stuck, {at_end} at an end stop",
        u.len()
    );
    assert!(
        err < BOUND_MM,
        "{name}: position differs from the 16x-refined RK4 reference by {err} mm at sample {k}"
    );
    (err, stuck, at_end)
}

// The default staircase experiment (open-loop sequence of `ipa::generate`, A = 255 counts, seed 0), 40 s.
#[test]
fn default_staircase_matches_the_refined_reference() {
    let u = ipa::generate(&ipa::InputSpec::Staircase, 4000, 0.01, 255.0, 0).unwrap();
    let (_, stuck, at_end) = check("staircase", &u);
    assert!(
        stuck > 100,
        "the record must include sticking phases: {stuck}"
    );
    assert!(at_end > 0, "the record must reach an end stop");
}

// Full-amplitude PRBS (±255 counts, 50 ms bit clock), 20 s: many end-stop hits and breakaways.
#[test]
fn full_amplitude_prbs_matches_the_refined_reference() {
    let u = ipa::generate(&ipa::InputSpec::Prbs, 2000, 0.01, 255.0, 1).unwrap();
    let (_, stuck, at_end) = check("prbs", &u);
    assert!(
        stuck > 100 && at_end > 50,
        "stuck {stuck}, at an end stop {at_end}"
    );
}

// Small commands around the deadzone (APRBS within ±60 counts), 20 s: slow creep and stick-slip, where
// the negative slope of the Stribeck friction amplifies integration errors.
#[test]
fn creeping_near_the_deadzone_matches_the_refined_reference() {
    let u = ipa::generate(&ipa::InputSpec::Aprbs, 2000, 0.01, 60.0, 3).unwrap();
    let (_, stuck, _) = check("aprbs 60", &u);
    assert!(
        stuck > 100,
        "the record must include sticking phases: {stuck}"
    );
}
