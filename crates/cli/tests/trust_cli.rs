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
    ipa_testdata::shared_data()
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
    assert!(
        fit >= baseline - 1e-9,
        "OE {fit} % against ARX LS {baseline} %"
    );
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

// Issue 22 item 5: on the ball-beam record the best delay is the largest tried and the runner-up is
// close; both warnings are given (only one used to be kept), in the text and the JSON.
#[test]
fn delay_on_the_ball_beam_keeps_every_warning() {
    let Some(dir) = data_dir() else { return };
    let doc = run_json(
        &dir,
        &[
            "delay",
            "--data",
            "ball_and_beam/ballbeam.csv",
            "--ts",
            "0.1",
            "--max-delay",
            "10",
        ],
    );
    // Recompute the argmin from the candidates' own losses.
    let best = doc["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|c| c["loss"].is_f64())
        .min_by(|a, b| {
            a["loss"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["loss"].as_f64().unwrap())
        })
        .unwrap()["nk"]
        .as_u64()
        .unwrap();
    assert_eq!(doc["nk"].as_u64().unwrap(), best);
    let w = warnings(&doc);
    if best == 10 {
        assert!(w.iter().any(|w| w.contains("largest one tried")), "{w:?}");
    }
}

/// `order ARGS --json`: the document.
fn order(dir: &Path, args: &[&str]) -> Value {
    let mut all = vec!["order"];
    all.extend(args);
    run_json(dir, &all)
}

// Issue 22 item 5: `order` never recommends a structure a warning disqualifies (unstable, negative or
// diverging fit), ranks on the worse of both initial states, and says when there is none.
#[test]
fn order_never_recommends_a_disqualified_structure_on_the_hydraulic_record() {
    let Some(dir) = data_dir() else { return };
    let doc = order(
        &dir,
        &[
            "--data",
            "hydraulic_actuator/actuator.csv",
            "--rows",
            "0..512",
            "--val-rows",
            "512..",
            "--y-col",
            "p",
            "--ts",
            "1",
            "--offset",
            "--method",
            "oe",
        ],
    );
    let cands = doc["candidates"].as_array().unwrap();
    for c in cands {
        // The ranking fit is a simulation fit on the selection record, never above the headline.
        if let (Some(r), Some(v)) = (c["ranking_fit"].as_f64(), c["fit_validation"].as_f64()) {
            assert!(r <= v + 1e-9, "{c}");
        }
    }
    match doc["test"].as_object() {
        Some(t) => {
            let o = &t["orders"];
            let chosen = cands.iter().find(|c| &c["orders"] == o).unwrap();
            assert!(chosen["stable"].as_bool().unwrap(), "{chosen}");
            assert!(chosen["ranking_fit"].as_f64().unwrap() >= 0.0, "{chosen}");
        }
        None => assert!(
            warnings(&doc)
                .iter()
                .any(|w| w.contains("none is recommended")),
            "{:?}",
            warnings(&doc)
        ),
    }
}

// Issue 22 item 5: on the flexible robot arm the best structure of na, nb in 1..10 is (10, 10, 0), on
// the grid's edge: said.
#[test]
fn order_says_when_the_optimum_is_on_the_edge_of_the_grid() {
    let Some(dir) = data_dir() else { return };
    let doc = order(
        &dir,
        &[
            "--data",
            "robot_arm_flexible/robot_arm.csv",
            "--ts",
            "1",
            "--na",
            "1..10",
            "--nb",
            "1..10",
            "--nk",
            "0",
            "--split",
            "0.5",
        ],
    );
    let o = &doc["test"]["orders"];
    let w = warnings(&doc);
    for name in ["na", "nb"] {
        if o[name].as_u64() == Some(10) {
            assert!(
                w.iter()
                    .any(|w| w.contains(&format!("recommended {name} = 10 is the largest"))),
                "{w:?}"
            );
        }
    }
}

/// `control ARGS --json -`: the JSON document and the text summary (standard error).
fn control(args: &[&str]) -> (Value, String) {
    let out = bin()
        .arg("control")
        .args(args)
        .args(["--json", "-"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    (
        serde_json::from_slice(&out.stdout).unwrap(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

// Issue 22 item 6: the physics plant at --setpoint 50 still creeps towards the set-point when the
// 10 s run ends (its position over the last second, from the trace, moves by more than the 2 % band
// would allow over the run): no settling time, a warning, text and JSON.
#[test]
fn control_says_when_the_step_has_not_settled() {
    let (doc, text) = control(&["--plant", "ipa", "--setpoint", "50"]);
    let t = &doc["steps"][0];
    let w = warnings(&doc);
    if t["metrics"]["settling_time_s"].is_null() {
        assert!(w.iter().any(|w| w.contains("has not settled")), "{w:?}");
        assert!(text.contains("not settled within"), "{text}");
    }
    // |e_ss| against 2 % of the step, from the JSON's own numbers.
    let ess = doc["metrics"]["steady_state_error_mm"].as_f64().unwrap();
    if ess.abs() >= 0.02 * 50.0 {
        assert!(w.iter().any(|w| w.contains("paper's acceptance")), "{w:?}");
    }
}

// Issue 22 item 6 (from issue 21 item 9): the stroke is 0..200 mm, so 300 mm cannot be reached, and the
// command then sits at its limit; both said.
#[test]
fn control_warns_about_an_unreachable_set_point_and_saturation() {
    let (doc, text) = control(&["--plant", "ipa", "--setpoint", "300", "--duration", "2"]);
    let w = warnings(&doc);
    assert!(
        w.iter().any(|w| w.contains("outside the reachable range")),
        "{w:?}"
    );
    assert!(text.contains("warning: set-point r = 300 mm"), "{text}");
    assert!(w.iter().any(|w| w.contains("saturated")), "{w:?}");
}

// Issue 22 item 6: an unstable model as the plant (pole 1.05 of y(k) = 1.05 y(k−1) + 0.01 u(k−1)) is
// said to be unstable, whatever its metrics look like.
#[test]
fn control_warns_about_an_unstable_model_plant() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("unstable.json");
    std::fs::write(
        &model,
        r#"{"format": "ipa-sysid-model", "version": 1, "model": {"kind": "arx", "ts": 0.01, "na": 1,
        "nb": 1, "nk": 1, "a": [-1.05], "b": [0.01], "offset": null}}"#,
    )
    .unwrap();
    let spec = format!("model:{}", model.display());
    let (doc, _) = control(&["--plant", &spec, "--setpoint", "50", "--duration", "2"]);
    let w = warnings(&doc);
    assert!(w.iter().any(|w| w.contains("unstable")), "{w:?}");
}
