//! The time oracle (`control::oracle`) on frictionless linear plants, against hand-derived closed forms.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use control::oracle::{self, FamilySearch, StepRun};
use sysid_core::{Deadzone, Model, ModelPlant};

/// y(k) = −a1 y(k−1) + b f(u(k−1)), f the deadzone with b_r = 1, b_l = −1 and slopes 1/254, so
/// that f(±255) = ±1 exactly in exact arithmetic.
fn plant(a1: f64, b: f64) -> ModelPlant {
    let m = Model::hammerstein(
        0.01,
        vec![a1],
        vec![b],
        1,
        Deadzone {
            b_l: -1.0,
            b_r: 1.0,
            m_l: 1.0 / 254.0,
            m_r: 1.0 / 254.0,
        },
        None,
    )
    .unwrap();
    ModelPlant::new(m, "linear").unwrap()
}

const SEARCH: FamilySearch = FamilySearch {
    overshoot_percent: 1.0,
    ess_mm: 0.02,
    rest_samples: None,
    last_fractions: &[1.0],
    reverse_fractions: &[1.0],
    rise_below_s: None,
};

// An integrator moving 1 mm per sample at full command, 25 → 35 mm: y(k) = 25 + k. The band edge
// 34.8 mm is crossed between k = 9 (34) and k = 10 (35): t = 0.09 + 0.8 × 0.01 = 0.098 s. 10 % (26 mm)
// is reached at k = 1 (0.01 s), 90 % (34 mm) at k = 9 (0.09 s): rise 0.08 s. The family's best is
// T1 = 10, T2 = 0: y stops at 35 exactly (no overshoot, no error), settled at the bound 0.098 s; any
// reverse sample or longer T1 ends elsewhere or later.
#[test]
fn on_an_integrator_the_bound_is_the_hand_derived_crossing_and_the_family_reaches_it() {
    let p = plant(-1.0, 1.0);
    let run = StepRun {
        y0_mm: 25.0,
        r_mm: 35.0,
        u_max: 255.0,
        samples: 101,
    };
    let b = oracle::full_command_bound(&mut p.clone(), &run).unwrap();
    assert!((b.band_entry_s.unwrap() - 0.098).abs() < 1e-9, "{b:?}");
    assert!((b.rise_s.unwrap() - 0.08).abs() < 1e-9, "{b:?}");
    let f = oracle::bang_bang(&p, &run, &SEARCH).unwrap();
    for best in [f.any, f.overshoot_ok, f.landed] {
        let best = best.unwrap();
        assert_eq!((best.t1, best.t2), (10, 0));
        assert!((best.metrics.settling_time_s.unwrap() - 0.098).abs() < 1e-9);
    }
    assert!(f.earliest_entry_s.unwrap() >= b.band_entry_s.unwrap() - 1e-12);
    // Downwards the same, mirrored.
    let down = StepRun {
        y0_mm: 35.0,
        r_mm: 25.0,
        ..run
    };
    let b = oracle::full_command_bound(&mut p.clone(), &down).unwrap();
    assert!((b.band_entry_s.unwrap() - 0.098).abs() < 1e-9, "{b:?}");
}

// A first-order lag y(k) = 0.9 y(k−1) + 2 f(u(k−1)) from rest at 0: under full command
// y(k) = 20 (1 − 0.9^k). Step 0 → 10 mm: band edge 9.8, 10 % = 1, 90 % = 9 mm, each crossing
// interpolated linearly between the two samples around it (closed form per sample, not a simulation).
#[test]
fn on_a_first_order_lag_the_bound_is_the_closed_form_crossing() {
    let p = plant(-0.9, 2.0);
    let run = StepRun {
        y0_mm: 0.0,
        r_mm: 10.0,
        u_max: 255.0,
        samples: 101,
    };
    let y = |k: i32| 20.0 * (1.0 - 0.9f64.powi(k));
    let cross = |level: f64| {
        let k = (0..).find(|&k| y(k) >= level).unwrap();
        0.01 * (f64::from(k - 1) + (level - y(k - 1)) / (y(k) - y(k - 1)))
    };
    let b = oracle::full_command_bound(&mut p.clone(), &run).unwrap();
    assert!((b.band_entry_s.unwrap() - cross(9.8)).abs() < 1e-9, "{b:?}");
    assert!(
        (b.rise_s.unwrap() - (cross(9.0) - cross(1.0))).abs() < 1e-9,
        "{b:?}"
    );
    // Every sequence the family simulates enters the band no earlier. None ends in the band: with
    // the command at 0 this plant returns to 0 (y(k) = 0.9 y(k−1)), so nothing is achievable.
    let f = oracle::bang_bang(&p, &run, &SEARCH).unwrap();
    assert!(f.sequences > 10);
    assert!(f.earliest_entry_s.unwrap() >= cross(9.8) - 1e-9);
    assert_eq!(f.any, None);
}
