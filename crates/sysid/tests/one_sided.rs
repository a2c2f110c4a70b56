//! Hammerstein models on one-sided inputs (a pump or heater voltage never goes negative): the unexcited
//! deadzone branch is dropped, the rest is recovered exactly from noise-free data.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::Signals;
use sysid::Dataset;
use sysid::{identify, Identification, Method};

/// Levels in [0, 10] (a few exactly 0 and inside the deadzone) held 5..30 samples.
fn positive_levels(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = Vec::new();
    while u.len() < n {
        let l = if rng.gen_bool(0.15) {
            0.0
        } else {
            rng.gen_range(0.0..10.0)
        };
        let hold = rng.gen_range(5..30);
        u.resize(u.len() + hold, l);
    }
    u.truncate(n);
    u
}

/// y(k) = 1.5 y(k−1) − 0.6 y(k−2) + x(k−1) + 0.4 x(k−2) + c, x = m_r (u − b_r) for u ≥ b_r, else 0.
fn simulate(u: &[f64], b_r: f64, m_r: f64, c: f64) -> Vec<f64> {
    let x: Vec<f64> = u
        .iter()
        .map(|&v| if v >= b_r { m_r * (v - b_r) } else { 0.0 })
        .collect();
    let mut y = vec![0.0; u.len()];
    for k in 2..u.len() {
        y[k] = 1.5 * y[k - 1] - 0.6 * y[k - 2] + x[k - 1] + 0.4 * x[k - 2] + c;
    }
    y
}

fn settings(method: Method) -> Identification {
    let mut s = Identification::default()
        .with_orders(2, 2, 1)
        .with_method(method);
    s.drop_unexcited_branch = true;
    s
}

// Noise-free, u ≥ 0 with commands inside the deadzone: b_r = 2.5, m_r = 0.03, A and B exactly; m_l = 0 fixed.
#[test]
fn positive_input_recovers_the_right_branch_exactly() {
    let u = positive_levels(1500, 3);
    let y = simulate(&u, 2.5, 0.03, 0.0);
    let data = Dataset::new(Signals { u, y }, 1.0, "pump").unwrap();
    for method in [Method::Ls, Method::Oe, Method::Iv] {
        let fit = identify(&data, &settings(method)).unwrap_or_else(|e| panic!("{method}: {e}"));
        let d = fit.model.deadzone().copied().unwrap();
        let msg = format!("{method}: {:?}", fit.model);
        assert!(
            (d.b_r - 2.5).abs() < 1e-6 && (d.m_r - 0.03).abs() < 1e-8,
            "{msg}"
        );
        assert_eq!((d.m_l, d.b_l), (0.0, 0.0), "{msg}");
        for (g, w) in fit
            .model
            .a()
            .iter()
            .zip([-1.5, 0.6])
            .chain(fit.model.b().iter().zip([1.0, 0.4]))
        {
            assert!((g - w).abs() < 1e-6, "{msg}");
        }
        assert!(
            fit.note()
                .as_deref()
                .is_some_and(|n| n.contains("left deadzone branch")),
            "{msg}"
        );
        let m_l = fit.params.iter().find(|p| p.name == "m_l").unwrap();
        assert!(
            m_l.std.is_none(),
            "a fixed parameter has no standard deviation"
        );
    }
}

// Every u > 0 with an offset: −m_r b_r h_r is a constant like c, so b_r = 0 is fixed and c absorbs
// −m_r b_r: with b_r = 1, m_r = 0.05, c = 0.2 the fit is c' = c − m_r b_r (1 + 0.4) = 0.13.
#[test]
fn with_an_offset_the_breakpoint_below_every_sample_is_absorbed_by_c() {
    let u: Vec<f64> = positive_levels(1500, 5).iter().map(|v| v + 1.5).collect();
    let y = simulate(&u, 1.0, 0.05, 0.2);
    let data = Dataset::new(Signals { u, y }, 1.0, "heater").unwrap();
    let fit = identify(&data, &settings(Method::Ls).with_offset(true)).unwrap();
    let d = fit.model.deadzone().copied().unwrap();
    assert_eq!(d.b_r, 0.0);
    assert!((d.m_r - 0.05).abs() < 1e-8, "{:?}", fit.model);
    assert!(
        (fit.model.offset().unwrap() - (0.2 - 0.05 * 1.0 * 1.4)).abs() < 1e-8,
        "{:?}",
        fit.model
    );
    assert!(fit
        .note()
        .unwrap()
        .contains("cannot be separated from the offset"));
}
