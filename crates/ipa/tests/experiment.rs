//! `Experiment::run` on the physics plant with the staircase designs the input and records the
//! experiment in one run of the plant; the record must be the one a second, separate run of the plant
//! with the designed input gives (how it was produced before: design on a copy, then replay).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use ipa::input::{staircase_experiment, StaircaseDesign};
use ipa::{Experiment, Ipa, PlantConfig};
use sysid_core::Plant;

// The plant is deterministic, so replaying the designed input on a fresh plant from the same state
// reproduces the designed run sample for sample: y and both pressures bit for bit.
#[test]
fn one_run_staircase_record_equals_a_replay_of_its_input() {
    let exp = Experiment {
        samples: Some(3000),
        seed: 7,
        ..Experiment::default()
    };
    let rec = exp.run().unwrap();

    let mut plant = Ipa::new(PlantConfig::default()).unwrap();
    plant.reset(exp.x0.unwrap_or(ipa::spec::MID_STROKE_Y0_MM));
    let mut copy = plant.clone();
    let (u, _) = staircase_experiment(
        &mut copy,
        &StaircaseDesign::default(),
        3000,
        exp.amplitude,
        exp.seed,
    )
    .unwrap();
    let mut y = Vec::new();
    let mut p = Vec::new();
    for &uk in &u {
        y.push(plant.output());
        p.push(plant.pressures_pa());
        plant.step(uk).unwrap();
    }
    assert_eq!(rec.u, u);
    assert_eq!(rec.y, y);
    assert_eq!(rec.pressures.unwrap(), p);
    // The staircase moves the piston: the record is not trivially constant.
    let span = y.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
        - y.iter().cloned().fold(f64::INFINITY, f64::min);
    assert!(span > 50.0, "span {span} mm");
}

// A file input is read once (`InputSpec::load`): its commands and the Ts of its time column come from
// that one read, so the experiment runs on them after the file is gone (before, `simulate` read the
// file for its Ts, for its length and for its commands). Ts 0.02 s is the time column's step.
#[test]
fn a_loaded_file_input_runs_without_reading_the_file_again() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("u.csv");
    let u: Vec<f64> = (0..40).map(|k| [0.0, 120.0, -90.0, 60.0][k / 10]).collect();
    let mut text = String::from("t,u\n");
    for (k, v) in u.iter().enumerate() {
        text.push_str(&format!("{},{v}\n", k as f64 * 0.02));
    }
    std::fs::write(&path, text).unwrap();
    let spec = format!("file:{}", path.display())
        .parse::<ipa::InputSpec>()
        .unwrap()
        .load()
        .unwrap();
    std::fs::remove_file(&path).unwrap();
    assert_eq!(spec.file_ts(), Some(0.02));
    assert_eq!(spec.file(), Some(path.as_path()));
    let exp = Experiment {
        input: spec.clone(),
        ts: spec.file_ts(),
        ..Experiment::default()
    };
    let rec = exp.run().unwrap();
    assert_eq!(rec.u, u);
    assert_eq!(rec.ts, 0.02);
    // Not loaded, the same file is read when the experiment runs: gone, it is an error.
    let unloaded = Experiment {
        input: format!("file:{}", path.display()).parse().unwrap(),
        ..Experiment::default()
    };
    assert!(unloaded.run().is_err());
}

// A stop requested before the run ends every kind of run at its first poll (sample 0) with
// `Cancelled`, and no record leaves: the physics plant's supervised staircase and calibration design,
// its designed input (`record_input`), and the paper model's staircase and designed input
// (`run_open_loop`). The same experiment with a stop never requested gives the record of one
// without a stop, sample for sample (the poll changes nothing else).
#[test]
fn a_requested_stop_ends_every_kind_of_experiment_with_cancelled() {
    use ipa::{InputSpec, IpaError, PlantSpec};
    use sysid_core::{Stop, SysidError};
    let requested = Stop::new();
    requested.request();
    for (plant, input) in [
        (PlantSpec::Ipa, InputSpec::Staircase),
        (PlantSpec::Ipa, InputSpec::Calibration),
        (PlantSpec::Ipa, InputSpec::Prbs),
        (PlantSpec::Paper, InputSpec::Staircase),
        (PlantSpec::Paper, InputSpec::Prbs),
    ] {
        let exp = Experiment {
            plant,
            input,
            samples: Some(3000),
            seed: 5,
            ..Experiment::default()
        };
        let what = format!("{:?} {:?}", exp.plant, exp.input);
        let stopped = Experiment {
            cancel: requested.clone(),
            ..exp.clone()
        }
        .run();
        assert!(
            matches!(stopped, Err(IpaError::Sysid(SysidError::Cancelled))),
            "{what}: {stopped:?}"
        );
        let unrequested = Experiment {
            cancel: Stop::new(),
            ..exp.clone()
        }
        .run()
        .unwrap();
        assert_eq!(unrequested, exp.run().unwrap(), "{what}");
        assert_eq!(unrequested.u.len(), 3000, "{what}");
    }
}
