//! Covariance windup: excitation, a quiet stretch, excitation again (issue 28). With ρ = 0.98 and a
//! quiet stretch in which φ is constant (a held command, the output settled), P grows like ρ^(−k) in
//! the directions φ does not excite: 6 000 quiet samples are a factor 0.98^(−6000) ≈ 1e53, beyond the
//! f32 range (3.4e38). With the trace guard tr P stays ≤ T at every sample, no update fails, no value
//! is NaN, and the estimate recovers once the excitation returns; without it the same record winds
//! P up by dozens of orders of magnitude (or, in f32, ends in a refused update).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use ipa_embedded::{Error, Float, Form, Rls};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// y(t) = 1.5 y(t−1) − 0.7 y(t−2) + u(t−1) + 0.5 u(t−2) + 0.01 e(t): θ for φ = [−y(t−1), −y(t−2),
/// u(t−1), u(t−2)].
const TRUTH: [f64; 4] = [-1.5, 0.7, 1.0, 0.5];
const EXCITED: usize = 2_000;
const QUIET: usize = 6_000;

/// (u, y): white N(0, 1) input for `EXCITED` samples, u = 1 held for `QUIET` samples (no noise: the
/// output settles at 7.5 and φ becomes constant), white input again for `EXCITED` samples.
fn record() -> (Vec<f64>, Vec<f64>) {
    let mut rng = ChaCha8Rng::seed_from_u64(2028);
    let len = 2 * EXCITED + QUIET;
    let mut u = vec![0.0; len];
    let mut y = vec![0.0; len];
    for t in 0..len {
        let quiet = (EXCITED..EXCITED + QUIET).contains(&t);
        u[t] = if quiet {
            1.0
        } else {
            StandardNormal.sample(&mut rng)
        };
        let e: f64 = StandardNormal.sample(&mut rng);
        if t >= 2 {
            y[t] = 1.5 * y[t - 1] - 0.7 * y[t - 2] + u[t - 1] + 0.5 * u[t - 2];
            if !quiet {
                y[t] += 0.01 * e;
            }
        }
    }
    (u, y)
}

/// Runs the record through `est`; returns (largest tr P after an update, refused updates, whether
/// any θ̂ entry was ever NaN).
fn run<F: Float>(est: &mut Rls<F, 4>, u: &[f64], y: &[f64]) -> (f64, usize, bool) {
    let (mut max_tr, mut refused, mut nan) = (0.0f64, 0, false);
    for t in 2..u.len() {
        let phi = [-y[t - 1], -y[t - 2], u[t - 1], u[t - 2]].map(F::from_f64);
        match est.update(&phi, F::from_f64(y[t])) {
            Ok(_) => {}
            Err(Error::Numerical) => refused += 1,
            // Eq. 12 only: P wound up by many orders of magnitude (tr P ≈ 5e13 in f64) loses its
            // positive definiteness to rounding, in f64 too.
            Err(Error::Indefinite) if est.form() == Form::Standard => refused += 1,
            Err(e) => panic!("unexpected {e:?}"),
        }
        max_tr = max_tr.max(est.trace().to_f64());
        nan |= est.theta().iter().any(|v| v.to_f64().is_nan());
    }
    (max_tr, refused, nan)
}

fn windup_case<F: Float>(form: Form, tol: f64) {
    let (u, y) = record();
    let (rho, p0) = (F::from_f64(0.98), F::from_f64(1000.0));
    let t_max = 4000.0; // p0 · n, `identify --windup trace`'s default
    let mut guarded = Rls::<F, 4>::new(4, rho, p0)
        .unwrap()
        .with_form(form)
        .with_max_trace(F::from_f64(t_max))
        .unwrap();
    let (max_tr, refused, nan) = run(&mut guarded, &u, &y);
    let what = format!("{} {form:?}", core::any::type_name::<F>());
    assert!(
        max_tr <= t_max * (1.0 + 1e-5),
        "{what}: tr P reached {max_tr:e} > T"
    );
    assert_eq!(refused, 0, "{what}: the guarded estimator refused updates");
    assert!(!nan, "{what}: NaN in θ̂");
    for (got, want) in guarded.theta().iter().zip(TRUTH) {
        assert!(
            (got.to_f64() - want).abs() < tol,
            "{what}: θ̂ {:?} vs {TRUTH:?}",
            guarded.theta()
        );
    }
    // The same record without the guard winds P up (the scenario is real): tr P beyond 1e30 or, when
    // that overflows the type or (eq. 12) rounding makes so large a P indefinite, refused updates;
    // never a NaN estimate.
    let mut free = Rls::<F, 4>::new(4, rho, p0).unwrap().with_form(form);
    let (max_tr, refused, nan) = run(&mut free, &u, &y);
    assert!(
        max_tr > 1e30 || refused > 0,
        "{what}: no windup without the guard (max tr P {max_tr:e})"
    );
    assert!(!nan, "{what}: NaN in θ̂ without the guard");
}

#[test]
fn guard_bounds_the_trace_through_a_quiet_stretch_in_f64() {
    windup_case::<f64>(Form::Standard, 1e-2);
    windup_case::<f64>(Form::Ud, 1e-2);
}

#[test]
fn guard_bounds_the_trace_through_a_quiet_stretch_in_f32() {
    windup_case::<f32>(Form::Standard, 2e-2);
    windup_case::<f32>(Form::Ud, 2e-2);
}
