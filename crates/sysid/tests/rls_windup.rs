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

// The paper's RLS winds up: P overflows (tr P ≥ 10^6 · 0.98^(−k)) and the estimator reports a numerical
// failure. Driven sample by sample: `identify` refuses the record before the recursion runs (below).
#[test]
fn standard_rls_without_protection_winds_up_to_a_numerical_failure() {
    let mut est = sysid::rls::Rls::new(3, 0.98, 1e6).unwrap();
    let failed = (0..N).find_map(|k| est.update(&[-1.0, -1.0, 0.0], 1.0, k).err());
    let e = failed.expect("the recursion must fail before 100 000 samples");
    assert!(e.is_numerical(), "{e}");
}

// A record without excitation determines no θ, whatever the recursion's protection: `identify` refuses
// it as not persistently exciting for every form and windup protection, as plain RLS and LS do (audit
// s20 H-1: the protected forms returned one point of the line of solutions with every std 0).
#[test]
fn identify_refuses_a_record_without_excitation_whatever_the_protection() {
    for form in [RlsForm::Standard, RlsForm::Ud] {
        for windup in [Windup::None, Windup::Directional, Windup::Trace] {
            let e = identify(&quiet_data(), &settings(form, windup)).unwrap_err();
            assert!(
                e.to_string().contains("not persistently exciting"),
                "{form} {windup}: {e}"
            );
        }
    }
}

// With protection (either form) the estimate and P of the recursion stay finite over 100 000 quiet samples
// (driven sample by sample: `identify` refuses such a record, above), and the trace of
// P stays bounded: directional forgetting never divides an unexcited direction by ρ, so tr P ≤ tr P(0);
// the bounded-trace variant keeps tr P ≤ T = p0 · n.
#[test]
fn protected_rls_stays_finite_and_bounded_without_excitation() {
    for form in [RlsForm::Standard, RlsForm::Ud] {
        for windup in [Windup::Directional, Windup::Trace] {
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
