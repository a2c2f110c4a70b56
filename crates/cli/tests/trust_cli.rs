//! Trust on the measured records of `../shared/data`, through the binary (issue 22): no flattering
//! headline, no silent failure, no lost good model. Each test skips, saying so, when the folder is
//! absent. Expectations come from separate runs of the binary (the plain ARX least-squares baseline)
//! or from the JSON's own figures (both initial states), never from a copied output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
}

fn data_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        println!(
            "SKIPPED: the shared data folder {} is absent",
            dir.display()
        );
        None
    }
}

/// Runs `ipa-sysid ARGS --json F` in `dir` and returns the JSON document (the command must succeed).
fn run_json(dir: &Path, args: &[&str]) -> Value {
    let tmp = tempfile::tempdir().unwrap();
    let json = tmp.path().join("out.json");
    let out = bin()
        .current_dir(dir)
        .args(args)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

fn warnings(doc: &Value) -> Vec<String> {
    doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect()
}

/// The same `identify` flags with the structure and method replaced by ARX least squares: the plain
/// baseline.
fn baseline_args<'a>(args: &[&'a str]) -> Vec<&'a str> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < args.len() {
        match args[i] {
            "--structure" => {
                out.extend(["--structure", "arx"]);
                i += 2;
            }
            "--method" => {
                out.extend(["--method", "ls"]);
                i += 2;
            }
            a => {
                out.push(a);
                i += 1;
            }
        }
    }
    out
}

/// The simulation fit that neither initial state flatters: min(estimated, measured).
fn guarded(m: &Value) -> Option<f64> {
    Some(
        m["fit_sim_percent"]
            .as_f64()?
            .min(m["fit_sim_measured_percent"].as_f64()?),
    )
}

/// The estimation headline either agrees with the fit from the measured initial outputs to within
/// 5 points, or a warning says that it does not.
fn assert_headline_not_flattered_silently(doc: &Value, what: &str) {
    let m = &doc["metrics"]["estimation"];
    let (est, meas) = (
        m["fit_sim_percent"].as_f64(),
        m["fit_sim_measured_percent"].as_f64(),
    );
    if let (Some(e), Some(s)) = (est, meas) {
        if (e - s).abs() > 5.0 {
            assert!(
                warnings(doc)
                    .iter()
                    .any(|w| w.contains("depends on the initial state")),
                "{what}: fit {e} % against {s} % from measured outputs without a warning: {:?}",
                warnings(doc)
            );
        }
    }
}

const PNEUMATIC: [&str; 11] = [
    "--no-header",
    "--t-col",
    "1",
    "--time-unit",
    "ms",
    "--resample",
    "0.01",
    "--u-col",
    "5",
    "--y-col",
    "7",
];

// Issue 22 item 2: a breakpoint estimate beyond every command makes a Jacobian column zero; the
// output-error search used to give up at its first iteration ("converged" after 1 evaluation, RMSE
// 684 N against the linear least-squares model's 67 % fit). It must iterate and beat that baseline
// (computed by a separate ARX LS run of the binary).
#[test]
fn hammerstein_output_error_iterates_when_a_breakpoint_leaves_the_data() {
    let Some(dir) = data_dir() else { return };
    let mut args = vec![
        "identify",
        "--data",
        "pneumatic_cylinder_friction_tudelft/NAPN_1bar.csv",
    ];
    args.extend(PNEUMATIC);
    args.extend([
        "--structure",
        "hammerstein",
        "--method",
        "oe",
        "--na",
        "1",
        "--nb",
        "2",
        "--nk",
        "2",
        "--offset",
    ]);
    let oe = run_json(&dir, &args);
    let base = run_json(&dir, &baseline_args(&args));
    assert!(
        oe["estimation"]["iterations"].as_u64().unwrap() > 1,
        "{}",
        oe["estimation"]["note"]
    );
    let fit = guarded(&oe["metrics"]["estimation"]).unwrap();
    let baseline = guarded(&base["metrics"]["estimation"]).unwrap();
    assert!(fit > baseline, "OE {fit} % against ARX LS {baseline} %");
    assert_headline_not_flattered_silently(&oe, "pneumatic 1 bar Hammerstein OE");
    // The standard deviations cannot be computed (the left breakpoint is beyond the data): said.
    let params = oe["parameters"].as_array().unwrap();
    if params.iter().all(|p| p["std"].is_null()) {
        assert!(
            warnings(&oe)
                .iter()
                .any(|w| w.contains("standard deviation")),
            "{:?}",
            warnings(&oe)
        );
    }
}

// Issue 22 item 1: the hair dryer's OE (5, 6, 3) refinement bought a 91 % headline with a slow pole
// (41 % from the measured outputs). The kept model is judged on both initial states, so the headline
// is never more than 5 points above the measured-start fit without a warning, and the result is not
// worse than the plain ARX least squares on the worse of both fits.
#[test]
fn hair_dryer_output_error_is_not_flattered_by_its_initial_state() {
    let Some(dir) = data_dir() else { return };
    let args = [
        "identify",
        "--data",
        "hair_dryer_pt326/dryer.csv",
        "--ts",
        "0.08",
        "--structure",
        "arx",
        "--method",
        "oe",
        "--na",
        "5",
        "--nb",
        "6",
        "--nk",
        "3",
        "--offset",
    ];
    let oe = run_json(&dir, &args);
    let base = run_json(&dir, &baseline_args(&args));
    assert_headline_not_flattered_silently(&oe, "dryer OE (5,6,3)");
    let fit = guarded(&oe["metrics"]["estimation"]).unwrap();
    let baseline = guarded(&base["metrics"]["estimation"]).unwrap();
    assert!(fit >= baseline - 1e-9, "OE {fit} % against ARX LS {baseline} %");
}

// Issue 22 item 1: the pneumatic 5 bar OE (8, 9, 0) headline was 91 % against −214 % from the measured
// outputs, without a word.
#[test]
fn pneumatic_5_bar_output_error_headline_is_not_flattered_silently() {
    let Some(dir) = data_dir() else { return };
    let mut args = vec![
        "identify",
        "--data",
        "pneumatic_cylinder_friction_tudelft/NAPN_5bar.csv",
    ];
    args.extend(PNEUMATIC);
    args.extend([
        "--structure",
        "arx",
        "--method",
        "oe",
        "--na",
        "8",
        "--nb",
        "9",
        "--nk",
        "0",
    ]);
    let oe = run_json(&dir, &args);
    assert_headline_not_flattered_silently(&oe, "pneumatic 5 bar OE (8,9,0)");
}
