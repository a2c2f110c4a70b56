//! Covariance windup: 100 000 samples without excitation at forgetting ρ = 0.98.
//!
//! Without excitation (u = 0, y constant) the ARX regressor φ = [−y, −y, 0] is constant, so every
//! direction of P orthogonal to φ is divided by ρ at each sample: tr P ≥ p0 ρ^(−k), which overflows
//! f64 (1.8e308) once k > ln(1.8e308 / p0) / ln(1/ρ) ≈ 34 400 for p0 = 10^6.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use sysid::data::Signals;
use sysid::rls_ud::{RlsForm, RobustRls};
use sysid::windup::Windup;
use sysid::{identify, Identification};
use sysid::{Dataset, ModelKind};
use sysid::{EstimatorSettings, RecursiveLeastSquares};

const N: usize = 100_000;

fn quiet_data() -> Dataset {
    Dataset::new(
        Signals {
            u: vec![0.0; N],
            y: vec![1.0; N],
        },
        0.01,
        "no excitation",
    )
    .unwrap()
}

fn settings(form: RlsForm, windup: Windup) -> Identification {
    Identification::default()
        .with_kind(ModelKind::Arx)
        .with_orders(2, 1, 1)
        .with_estimator(EstimatorSettings::Rls(RecursiveLeastSquares {
            forgetting: 0.98,
            form,
            windup,
            ..RecursiveLeastSquares::default()
        }))
}

// The paper's RLS winds up: P overflows (tr P ≥ 10^6 · 0.98^(−k)) and the estimator reports a numerical failure.
#[test]
fn standard_rls_without_protection_winds_up_to_a_numerical_failure() {
    let e = identify(&quiet_data(), &settings(RlsForm::Standard, Windup::None)).unwrap_err();
    assert!(e.is_numerical(), "{e}");
}

// With protection (either form) the estimate and P stay finite over 100 000 quiet samples, and the trace of
// P stays bounded: directional forgetting never divides an unexcited direction by ρ, so tr P ≤ tr P(0);
// the bounded-trace variant keeps tr P ≤ T = p0 · n.
#[test]
fn protected_rls_stays_finite_and_bounded_without_excitation() {
    for form in [RlsForm::Standard, RlsForm::Ud] {
        for windup in [Windup::Directional, Windup::Trace] {
            let fit = identify(&quiet_data(), &settings(form, windup))
                .unwrap_or_else(|e| panic!("{form} {windup}: {e}"));
            assert!(
                fit.params.iter().all(|p| p.value.is_finite()),
                "{form} {windup}"
            );
            let mut est = RobustRls::new(3, 0.98, 1e6, form, windup, None).unwrap();
            let mut max_trace: f64 = 0.0;
            for k in 0..N {
                est.update(&[-1.0, -1.0, 0.0], 1.0, k).unwrap();
                max_trace = max_trace.max(est.trace());
            }
            assert!(
                max_trace <= 3e6 * (1.0 + 1e-9),
                "{form} {windup}: max tr P = {max_trace}"
            );
            assert!(est.theta.iter().all(|v| v.is_finite()));
        }
    }
}
