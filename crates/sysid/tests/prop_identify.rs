//! Property tests of the identification pipeline: for arbitrary finite data and arbitrary orders,
//! `identify` never panics or hangs, and either returns finite numbers (model, parameters, metrics) or
//! a clear error. Also: poles of any polynomial are found (the root finder terminates and satisfies
//! Vieta's formula for the sum of the roots).
//!
//! Case counts are modest so that the debug-mode run stays within a few seconds.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use proptest::prelude::*;
use sysid::data::Signals;
use sysid::metrics::metrics;
use sysid::Structure;
use sysid::{identify, Identification, Method};
use sysid::{Dataset, ModelKind, Orders, SysidError};
use sysid::{
    EstimatorSettings, InstrumentalVariables, LeastSquares, OutputError, RecursiveLeastSquares,
};

/// Any finite f64, weighted towards ordinary magnitudes but with extremes, subnormals and zeros.
fn finite() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -300.0..300.0f64,
        1 => any::<f64>().prop_filter("finite", |v| v.is_finite()),
        1 => Just(0.0),
        1 => prop_oneof![Just(1e300), Just(-1e-300), Just(5e-324), Just(f64::MAX)],
    ]
}

/// A record: either arbitrary samples, or a staircase (held levels, as an experiment would use) scaled
/// by an arbitrary factor, with an arbitrary output.
fn record() -> impl Strategy<Value = (Vec<f64>, Vec<f64>)> {
    let arbitrary = (0usize..120).prop_flat_map(|n| {
        (
            prop::collection::vec(finite(), n),
            prop::collection::vec(finite(), n),
        )
    });
    let staircase = (
        prop::collection::vec(-255.0..255.0f64, 1..12),
        1usize..15,
        10usize..120,
        prop_oneof![Just(1.0), Just(1e-200), Just(1e150), -1e3..1e3f64],
        prop::collection::vec(-50.0..50.0f64, 120),
    )
        .prop_map(|(levels, hold, n, scale, y)| {
            let u: Vec<f64> = (0..n)
                .map(|k| scale * levels[(k / hold) % levels.len()])
                .collect();
            let y: Vec<f64> = y[..n].iter().map(|v| v * scale).collect();
            (u, y)
        });
    prop_oneof![arbitrary, staircase]
}

fn settings(
    kind: ModelKind,
    (na, nb, nk): (usize, usize, usize),
    method: Method,
    offset: bool,
) -> Identification {
    let start = LeastSquares {
        max_iterations: 30,
        ..LeastSquares::default()
    };
    let estimator = match method {
        Method::Ls => EstimatorSettings::Ls(start),
        Method::Rls => EstimatorSettings::Rls(RecursiveLeastSquares::default()),
        Method::Oe => EstimatorSettings::Oe(OutputError {
            start,
            max_iterations: 30,
            ..OutputError::default()
        }),
        Method::Iv => EstimatorSettings::Iv(InstrumentalVariables {
            start,
            stages: 2,
            ..InstrumentalVariables::default()
        }),
    };
    Identification {
        structure: Structure {
            kind,
            orders: Orders { na, nb, nk },
            offset,
        },
        inputs: Vec::new(),
        estimator,
        drop_unexcited_branch: true,
        fallback: true,
        output: None,
        max_memory: Default::default(),
        cancel: Default::default(),
    }
}

/// The contract: Ok holds a consistent, finite model with finite parameters and metrics that are
/// finite or absent (never NaN); Err is a non-empty message.
fn check_outcome(data: &Dataset, s: &Identification) -> Result<(), TestCaseError> {
    match identify(data, s) {
        Ok(fit) => {
            // The model survives its own file format, whose reader validates every field.
            let text = sysid::model_file::to_json(&fit.model).unwrap();
            let back = sysid::model_file::parse_model(text.as_bytes(), "prop");
            prop_assert!(back.is_ok(), "{:?}: {:?}", fit.model, back);
            for p in &fit.params {
                prop_assert!(p.value.is_finite(), "{} = {}", p.name, p.value);
                prop_assert!(
                    p.std.is_none_or(|v| v.is_finite()),
                    "std {} = {:?}",
                    p.name,
                    p.std
                );
            }
            let _ = fit.model.poles();
            match metrics(&fit.model, data) {
                Ok(m) => {
                    let opt = [
                        m.fit_sim_percent,
                        m.fit_pred_percent,
                        m.rmse_sim,
                        m.fpe,
                        m.aic,
                    ];
                    prop_assert!(opt.iter().all(|v| v.is_none_or(f64::is_finite)), "{m:?}");
                    prop_assert!(
                        m.rmse_pred.is_finite() && m.loss.is_some_and(f64::is_finite),
                        "{m:?}"
                    );
                }
                Err(e) => prop_assert!(!e.to_string().is_empty()),
            }
        }
        Err(e) => {
            let m = e.to_string();
            prop_assert!(!m.is_empty());
            if let SysidError::Data(_) = e {
                prop_assert!(m.len() > 10, "{m}");
            }
        }
    }
    Ok(())
}

fn kind() -> impl Strategy<Value = ModelKind> {
    prop_oneof![Just(ModelKind::Arx), Just(ModelKind::Hammerstein)]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 192, ..ProptestConfig::default() })]

    // LS and RLS on arbitrary finite data with arbitrary orders: never a panic, never a silent NaN.
    #[test]
    fn ls_and_rls_return_finite_numbers_or_a_clear_error(
        (u, y) in record(),
        kind in kind(),
        orders in (0usize..6, 0usize..4, 0usize..4),
        method in prop_oneof![Just(Method::Ls), Just(Method::Rls)],
        offset in any::<bool>(),
    ) {
        let data = Dataset::new(Signals { u, y }, 0.01, "prop").expect("finite record");
        check_outcome(&data, &settings(kind, orders, method, offset))?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, ..ProptestConfig::default() })]

    // The slower estimators (instrumental variables, output-error refinement) obey the same contract.
    #[test]
    fn iv_and_oe_return_finite_numbers_or_a_clear_error(
        (u, y) in record(),
        kind in kind(),
        orders in (0usize..4, 0usize..3, 0usize..3),
        method in prop_oneof![Just(Method::Iv), Just(Method::Oe)],
    ) {
        let data = Dataset::new(Signals { u, y }, 0.01, "prop").expect("finite record");
        check_outcome(&data, &settings(kind, orders, method, false))?;
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    // Roots of z^n + c1 z^(n-1) + ... + c_n, zeros included (z^3 used to hang the eigen-solver): n roots
    // whose sum is -c1 (Vieta).
    #[test]
    fn poles_of_any_polynomial_sum_to_minus_c1(
        c in prop::collection::vec(prop_oneof![2 => Just(0.0), 3 => -10.0..10.0f64], 0..13),
    ) {
        let p = sysid::model::poles_of(&c);
        prop_assert_eq!(p.len(), c.len());
        if let Some(&c1) = c.first() {
            let sum = p.iter().fold(nalgebra::Complex::new(0.0, 0.0), |s, z| s + z);
            let scale = 1.0 + c.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            prop_assert!((sum.re + c1).abs() < 1e-6 * scale * c.len() as f64, "sum {sum} vs -c1 = {}", -c1);
            prop_assert!(sum.im.abs() < 1e-6 * scale * c.len() as f64, "sum {sum}");
        }
    }
}
