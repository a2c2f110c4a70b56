//! Poles and validation metrics on hand-checkable cases.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use sysid::data::Signals;
use sysid::metrics::metrics;
use sysid::{Dataset, Model};

fn arx(a: Vec<f64>, b: Vec<f64>, nk: usize) -> Model {
    Model::arx(1.0, a, b, nk, None).unwrap()
}

// docs/paper.md: the paper's actual A has real poles 0.999227, 0.681112, 0.188661.
#[test]
fn paper_actual_polynomial_has_three_real_poles_inside_the_unit_circle() {
    let p = Model::paper().poles();
    let want = [0.999227, 0.681112, 0.188661];
    for (pi, w) in p.iter().zip(want) {
        assert!((pi.re - w).abs() < 5e-6 && pi.im.abs() < 1e-9, "{p:?}");
    }
    assert!(Model::paper().stability().settles());
}

// docs/paper.md, 3.2: the estimated A = 1 - 1.82 z^-1 + 1.001 z^-2 - 0.1808 z^-3 has poles 0.9994, 0.4103 ± 0.1121i.
#[test]
fn paper_estimated_polynomial_has_the_reported_poles() {
    let p = sysid::model::poles_of(&[-1.82, 1.001, -0.1808]);
    assert!(
        (p[0].re - 0.9994).abs() < 1e-4 && p[0].im.abs() < 1e-12,
        "{p:?}"
    );
    for q in &p[1..] {
        assert!(
            (q.re - 0.4103).abs() < 1e-4 && (q.im.abs() - 0.1121).abs() < 1e-4,
            "{p:?}"
        );
    }
}

// z² + 0 z + 1.21 has poles ±1.1i: outside the unit circle, so unstable.
#[test]
fn poles_outside_the_unit_circle_are_unstable() {
    let m = arx(vec![0.0, 1.21], vec![1.0], 1);
    let p = m.poles();
    assert!(p
        .iter()
        .all(|q| (q.norm() - 1.1).abs() < 1e-12 && q.re.abs() < 1e-12));
    assert!(m.stability().is_unstable());
}

// Model y(k) = 0.5 u(k-1) (na = 0) on data whose one-step errors are known:
// y = (0, 1, 0, 2), u = (2, 2, 2, 2) → ŷ(k≥1) = 1, ε = (0, -1, 1), mean ε² = 2/3, loss = 1/3,
// p = 1, N = 3: FPE = (4/2)(1/3), AIC = ln(2/3) + 2/3, ȳ = 1, fit = 100 (1 − √2/√2) = 0.
#[test]
fn loss_fpe_aic_and_fit_on_a_hand_checked_record() {
    let m = arx(vec![], vec![0.5], 1);
    let d = Dataset::new(
        Signals {
            u: vec![2.0; 4],
            y: vec![0.0, 1.0, 0.0, 2.0],
        },
        1.0,
        "hand",
    )
    .unwrap();
    let v = metrics(&m, &d).unwrap();
    assert_eq!((v.n, v.p), (3, 1));
    assert!((v.loss.unwrap() - 1.0 / 3.0).abs() < 1e-12);
    assert!((v.fpe.unwrap() - 2.0 / 3.0).abs() < 1e-12);
    assert!((v.aic.unwrap() - ((2.0f64 / 3.0).ln() + 2.0 / 3.0)).abs() < 1e-12);
    // MATLAB's from the model's own (here the ARX) prediction errors: LossFcn = mean ε² = 2/3 = 2V,
    // FPE = (4/2)(2/3), nAIC = the same AIC.
    assert!((v.loss_fcn.unwrap() - 2.0 / 3.0).abs() < 1e-12);
    assert!((v.fpe_matlab.unwrap() - 4.0 / 3.0).abs() < 1e-12);
    assert!((v.aic_matlab.unwrap() - ((2.0f64 / 3.0).ln() + 2.0 / 3.0)).abs() < 1e-12);
    assert!(v.fit_pred_percent.unwrap().abs() < 1e-12);
    assert!((v.rmse_pred - (2.0f64 / 3.0).sqrt()).abs() < 1e-12);
    // With na = 0 simulation and prediction coincide.
    assert_eq!(v.fit_sim_percent, v.fit_pred_percent);
}

// Free-run simulation of y(k) = 0.5 y(k-1) + u(k-1) from y(0) taken from data, u = 1: 0→1→1.5→1.75.
#[test]
fn simulation_starts_from_data_and_runs_free() {
    let m = arx(vec![-0.5], vec![1.0], 1);
    let s = m.simulate(&[&[1.0; 4]], &[0.0, 9.0, 9.0, 9.0]).unwrap();
    assert_eq!(s, vec![0.0, 1.0, 1.5, 1.75]);
    let p = m.predict(&[1.0; 4], &[0.0, 9.0, 9.0, 9.0]).unwrap();
    assert_eq!(p, vec![0.0, 1.0, 5.5, 5.5]);
}
