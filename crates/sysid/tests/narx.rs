//! Polynomial NARX identification: FROLS on a hand-computed case and on exact data of a known NARX.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use sysid::data::Signals;
use sysid::narx::{frols, identify_narx, NarxSettings, StopRule};
use sysid::narx_model::{candidate_terms, NarxModel, Term};
use sysid::{Dataset, Stop};

// Hand computation: p1 = (1, 1, 0), p2 = (1, 0, 1), y = (2, 1, 0), yᵀy = 5.
// ERR(p1) = (p1ᵀy)²/(p1ᵀp1 · yᵀy) = 9/10, ERR(p2) = 4/10: p1 first. w2 = p2 − ½ p1 = (½, −½, 1),
// w2ᵀy = ½, w2ᵀw2 = 3/2: ERR = ¼ / (3/2 · 5) = 1/30. θ from the normal equations
// [2 1; 1 2] θ = (3, 2): θ = (4/3, 1/3).
#[test]
fn err_of_a_hand_computed_case() {
    let p = vec![vec![1.0, 1.0, 0.0], vec![1.0, 0.0, 1.0]];
    let y = [2.0, 1.0, 0.0];
    let f = frols(&p, &y, 2, &Stop::never()).unwrap();
    assert_eq!(f.order, vec![0, 1]);
    assert!((f.err[0] - 0.9).abs() < 1e-15);
    assert!((f.err[1] - 1.0 / 30.0).abs() < 1e-15);
    let th = f.theta(2);
    assert!((th[0] - 4.0 / 3.0).abs() < 1e-14);
    assert!((th[1] - 1.0 / 3.0).abs() < 1e-14);
    // One term: θ1 = p1ᵀy / p1ᵀp1 = 3/2.
    assert!((f.theta(1)[0] - 1.5).abs() < 1e-15);
}

/// SysIdentPy's example system (`get_siso_data`, its documentation's FROLS example), noise free:
/// y(k) = 0.2 y(k−1) + 0.1 y(k−1) u(k−1) + 0.9 u(k−2), u white.
fn known_narx(n: usize) -> Dataset {
    let u = ipa_testdata::white(n, 7);
    let mut y = vec![0.0; n];
    for k in 2..n {
        y[k] = 0.2 * y[k - 1] + 0.1 * y[k - 1] * u[k - 1] + 0.9 * u[k - 2];
    }
    Dataset::new(Signals { u, y }, 1.0, "known").unwrap()
}

fn truth() -> Vec<(Term, f64)> {
    [("y(k-1)", 0.2), ("y(k-1)*u(k-1)", 0.1), ("u(k-2)", 0.9)]
        .iter()
        .map(|(t, c)| (t.parse().unwrap(), *c))
        .collect()
}

fn assert_true_terms(model: &NarxModel) {
    let truth = truth();
    assert_eq!(model.terms().len(), truth.len(), "{:?}", model.terms());
    for (t, c) in truth {
        let i = model
            .terms()
            .iter()
            .position(|x| *x == t)
            .unwrap_or_else(|| panic!("{t} not selected: {:?}", model.terms()));
        assert!(
            (model.theta()[i] - c).abs() < 1e-8,
            "{t}: {}",
            model.theta()[i]
        );
    }
}

// On exact data FROLS orders the three true terms first and the rest explains nothing.
#[test]
fn frols_picks_exactly_the_true_terms() {
    let d = known_narx(600);
    let cands = candidate_terms(2, 2, 1, 2, true);
    let k0 = 2;
    let cols: Vec<Vec<f64>> = cands
        .iter()
        .map(|t| {
            (k0..d.len())
                .map(|k| {
                    t.factors()
                        .iter()
                        .map(|v| match *v {
                            sysid::narx_model::Lagged::Y(l) => d.y()[k - l],
                            sysid::narx_model::Lagged::U(l) => d.u()[k - l],
                        })
                        .product()
                })
                .collect()
        })
        .collect();
    let f = frols(&cols, &d.y()[k0..], 8, &Stop::never()).unwrap();
    let mut first: Vec<Term> = f.order[..3].iter().map(|&i| cands[i].clone()).collect();
    first.sort();
    let mut want: Vec<Term> = truth().into_iter().map(|(t, _)| t).collect();
    want.sort();
    assert_eq!(first, want);
    assert!((f.err[..3].iter().sum::<f64>() - 1.0).abs() < 1e-12);
    assert!(f.err[3..].iter().all(|e| *e < 1e-20), "{:?}", f.err);
}

// Every stopping rule keeps exactly the true terms on exact data, with the true coefficients, with
// and without the simulation-error refinement.
#[test]
fn every_stopping_rule_recovers_the_known_narx() {
    let d = known_narx(600);
    for stop in [StopRule::Aic, StopRule::Bic, StopRule::Sim] {
        for refine in [false, true] {
            let s = NarxSettings {
                na: 2,
                nb: 2,
                nk: 1,
                degree: 2,
                constant: true,
                max_terms: 12,
                stop,
                refine,
                ..NarxSettings::default()
            };
            let fit = identify_narx(&d, &s).unwrap();
            assert_true_terms(&fit.model);
            assert!(
                fit.warnings.is_empty(),
                "{stop} {refine}: {:?}",
                fit.warnings
            );
        }
    }
}

// The refinement moves a perturbed start back to the minimum of the simulation error: exact data,
// start 5 % off, every coefficient back to 1e-8.
#[test]
fn refinement_returns_to_the_true_coefficients() {
    let d = known_narx(600);
    let truth = truth();
    let terms: Vec<Term> = truth.iter().map(|(t, _)| t.clone()).collect();
    let theta: Vec<f64> = truth.iter().map(|(_, c)| c * 1.05).collect();
    let start = NarxModel::new(1.0, 2, 2, 1, 2, terms, theta).unwrap();
    let (m, r, _) = sysid::narx::refine(&start, d.u(), d.y(), 100, &Stop::never()).unwrap();
    assert!(r.rmse_after < 1e-9 && r.rmse_before > 1e-3, "{r:?}");
    assert_true_terms(&m);
}
