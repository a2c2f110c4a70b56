//! The caller's stop check ([`sysid::Stop`]): a stop requested before the call makes every hooked
//! computation return `SysidError::Cancelled` — never a result — while the same settings with a stop
//! that is never requested give the result of settings without one, bit for bit.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use sysid::data::Signals;
use sysid::narx::{frols, identify_narx, NarxSettings, StopRule};
use sysid::{identify, Dataset, Identification, Method, NonlinearityKind, Stop, SysidError};

/// A requested stop.
fn requested() -> Stop {
    let stop = Stop::new();
    stop.request();
    stop
}

/// y(k) = 1.5 y(k−1) − 0.6 y(k−2) + x(k−1) + 0.4 x(k−2) with x the deadzone b_l = −2, b_r = 3,
/// m_l = 0.05, m_r = 0.04 of u (white, ±10), and a small deterministic disturbance.
fn hammerstein_record() -> Dataset {
    let u: Vec<f64> = ipa_testdata::white(3000, 11)
        .iter()
        .map(|v| 10.0 * v)
        .collect();
    let x: Vec<f64> = u
        .iter()
        .map(|&v| {
            if v > 3.0 {
                0.04 * (v - 3.0)
            } else if v < -2.0 {
                0.05 * (v + 2.0)
            } else {
                0.0
            }
        })
        .collect();
    let mut y = vec![0.0; u.len()];
    for k in 2..u.len() {
        y[k] = 1.5 * y[k - 1] - 0.6 * y[k - 2]
            + x[k - 1]
            + 0.4 * x[k - 2]
            + 1e-3 * ((k * 7919) % 13) as f64 / 13.0;
    }
    Dataset::new(Signals { u, y }, 0.01, "hammerstein").unwrap()
}

/// Every method, Hammerstein and ARX, with and without an output nonlinearity (Wiener refinement).
fn every_identification() -> Vec<(String, Identification)> {
    let mut out = Vec::new();
    for method in [Method::Ls, Method::Rls, Method::Oe, Method::Iv] {
        for kind in [sysid::ModelKind::Hammerstein, sysid::ModelKind::Arx] {
            let s = Identification::default()
                .with_kind(kind)
                .with_orders(2, 2, 1)
                .with_method(method);
            out.push((format!("{method} {kind:?}"), s.clone()));
            out.push((
                format!("{method} {kind:?} + output saturation"),
                s.with_output_nonlinearity(Some(NonlinearityKind::Saturation)),
            ));
        }
    }
    out
}

#[test]
fn a_requested_stop_cancels_every_identification() {
    let data = hammerstein_record();
    for (name, settings) in every_identification() {
        let stopped = Identification {
            cancel: requested(),
            ..settings
        };
        match identify(&data, &stopped) {
            Err(SysidError::Cancelled) => {}
            other => panic!("{name}: expected Cancelled, got {other:?}"),
        }
    }
}

#[test]
fn a_stop_never_requested_changes_nothing() {
    let data = hammerstein_record();
    for (name, settings) in every_identification() {
        let watched = Identification {
            cancel: Stop::new(),
            ..settings.clone()
        };
        let plain = identify(&data, &settings);
        let with_stop = identify(&data, &watched);
        match (plain, with_stop) {
            (Ok(a), Ok(b)) => {
                assert_eq!(a.model, b.model, "{name}");
                assert_eq!(a.params, b.params, "{name}");
            }
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "{name}"),
            (a, b) => panic!("{name}: {a:?} against {b:?}"),
        }
    }
}

#[test]
fn a_requested_stop_cancels_the_narx_search_under_every_stopping_rule() {
    let u = ipa_testdata::white(2000, 7);
    let mut y = vec![0.0; u.len()];
    for k in 2..u.len() {
        y[k] = 0.2 * y[k - 1] + 0.1 * y[k - 1] * u[k - 1] + 0.9 * u[k - 2];
    }
    let data = Dataset::new(Signals { u, y }, 1.0, "narx").unwrap();
    for rule in [StopRule::Aic, StopRule::Bic, StopRule::Sim] {
        for refine in [false, true] {
            let settings = NarxSettings {
                stop: rule,
                refine,
                ..NarxSettings::default()
            };
            assert!(identify_narx(&data, &settings).is_ok(), "{rule} {refine}");
            let stopped = NarxSettings {
                cancel: requested(),
                ..settings
            };
            assert!(
                matches!(identify_narx(&data, &stopped), Err(SysidError::Cancelled)),
                "{rule} refine={refine}"
            );
        }
    }
}

// FROLS on the hand case of tests/narx.rs (p1 = (1, 1, 0), p2 = (1, 0, 1), y = (2, 1, 0)): chosen
// order (p1, p2) with a stop never requested, Cancelled with one requested.
#[test]
fn a_requested_stop_cancels_frols() {
    let p = vec![vec![1.0, 1.0, 0.0], vec![1.0, 0.0, 1.0]];
    let y = [2.0, 1.0, 0.0];
    assert_eq!(frols(&p, &y, 2, &Stop::new()).unwrap().order, vec![0, 1]);
    assert!(matches!(
        frols(&p, &y, 2, &requested()),
        Err(SysidError::Cancelled)
    ));
}
