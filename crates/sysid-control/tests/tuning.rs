//! `tune`'s pipeline (`sysid_control::tuning::run`): what does not need a twin or the physics plant.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use control::tune::{Spec, TuneSettings};
use control::ControlError;
use sysid_core::{Deadzone, Model};

/// y(k) = y(k−1) + f(u(k−nk)): A = 1 − z⁻¹, B = 1, deadzone slopes m.
fn integrator(nk: usize, m: f64, dz: (f64, f64)) -> Model {
    Model::hammerstein(
        0.01,
        vec![-1.0],
        vec![1.0],
        nk,
        Deadzone {
            b_l: dz.0,
            b_r: dz.1,
            m_l: m,
            m_r: m,
        },
        None,
    )
    .unwrap()
}

// A stop requested before the call: `tuning::run` builds no plant for any simulation and returns
// Cancelled, never a report (the hook of the Python binding's Ctrl-C; crates/core/src/stop.rs).
#[test]
fn a_requested_stop_cancels_the_tuning() {
    let cancel = sysid_core::Stop::new();
    cancel.request();
    let model = integrator(1, 0.002, (-30.0, 30.0));
    let deadzone = *model.deadzone().unwrap();
    let req = sysid_control::tuning::Request {
        source: sysid_control::tuning::Source::Model {
            model,
            deadzone,
            label: "integrator".into(),
        },
        spec: Spec::default(),
        search: TuneSettings {
            plants: 2,
            max_evaluations: 40,
        },
        check_physics: false,
        physics_variants: 0,
        cancel,
    };
    match sysid_control::tuning::run(&req) {
        Err(ControlError::Cancelled) => {}
        other => panic!("expected Cancelled, got {:?}", other.map(|r| r.controller)),
    }
}
