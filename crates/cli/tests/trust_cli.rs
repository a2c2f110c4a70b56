//! Trust on the measured records of `../shared/data`, through the binary (issue 22): no flattering
//! headline, no silent failure, no lost good model. Each test skips, saying so, when the folder is
//! absent. Expectations come from separate runs of the binary (the plain ARX least-squares baseline)
//! or from the JSON's own figures (both initial states), never from a copied output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;

use std::path::{Path, PathBuf};

use common::{bin, identify_arx, run_json, warnings};
use serde_json::Value;

fn data_dir() -> Option<PathBuf> {
    ipa_testdata::shared_data()
}

/// The same `identify` flags with the structure and method replaced by ARX least squares (the
/// recursive estimators' settings dropped): the plain baseline.
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
            // The recursive estimators' settings: least squares has none (identify refuses them).
            "--forgetting" | "--passes" | "--p0" | "--rls-form" | "--windup" | "--max-trace"
            | "--iv-stages" => i += 2,
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

// Issue 22 item 9 keeps the linear start (ARX LS of the same orders + its metrics) out of the
// identifications where no start could change the result; where one can, its warnings remain, judged
// against a separate ARX LS run of the binary:
// - hydraulic p, ARX RLS (5, 5, 1) with ρ = 0.95 and one pass ends on an estimate fitted to the last
//   samples: its guarded fit trails the baseline by more than 20 points → "far worse than the plain
//   linear least-squares ARX";
// - robot arm, Hammerstein LS (8, 7, 1) with offset simulates more than 10 points worse than the
//   linear start → "linear start better"; with `--fallback` the result is that linear model (the
//   baseline's fit).
#[test]
fn the_linear_start_still_judges_the_estimates_it_can_beat() {
    let Some(dir) = data_dir() else { return };
    let hydraulic = [
        identify_arx(
            Path::new("hydraulic_actuator/actuator.csv"),
            "5",
            "5",
            "rls",
        ),
        vec![
            "--u-col",
            "u",
            "--y-col",
            "p",
            "--ts",
            "1",
            "--nk",
            "1",
            "--forgetting",
            "0.95",
            "--passes",
            "1",
        ],
    ]
    .concat();
    let doc = run_json(&dir, &hydraulic);
    let base = run_json(&dir, &baseline_args(&hydraulic));
    let fit = guarded(&doc["metrics"]["estimation"]).unwrap();
    let baseline = guarded(&base["metrics"]["estimation"]).unwrap();
    assert!(fit < baseline - 20.0, "{fit} % against {baseline} %");
    let said = format!(
        "simulates the estimation data far worse than the plain linear least-squares ARX of the same \
         orders (fit {fit:.2} % against {baseline:.2} %"
    );
    assert!(
        warnings(&doc).iter().any(|w| w.contains(&said)),
        "{said}: {:?}",
        warnings(&doc)
    );

    let robot = [
        "identify",
        "--data",
        "robot_arm_flexible/robot_arm.csv",
        "--ts",
        "1",
        "--structure",
        "hammerstein",
        "--method",
        "ls",
        "--na",
        "8",
        "--nb",
        "7",
        "--nk",
        "1",
        "--offset",
    ];
    let doc = run_json(&dir, &robot);
    let base = run_json(&dir, &baseline_args(&robot));
    let fit = doc["metrics"]["estimation"]["fit_sim_percent"]
        .as_f64()
        .unwrap();
    let linear = base["metrics"]["estimation"]["fit_sim_percent"]
        .as_f64()
        .unwrap();
    assert!(fit < linear - 10.0, "{fit} % against {linear} %");
    assert!(
        warnings(&doc)
            .iter()
            .any(|w| w.contains("far worse than the linear start")),
        "{:?}",
        warnings(&doc)
    );
    let mut with_fallback = robot.to_vec();
    with_fallback.push("--fallback");
    let fb = run_json(&dir, &with_fallback);
    assert!(
        warnings(&fb)
            .iter()
            .any(|w| w.starts_with("fallback used: the linear ARX least-squares model")),
        "{:?}",
        warnings(&fb)
    );
    let fb_fit = fb["metrics"]["estimation"]["fit_sim_percent"]
        .as_f64()
        .unwrap();
    assert!(
        (fb_fit - linear).abs() < 1e-6,
        "{fb_fit} % against {linear} %"
    );
}

// Issue 22 item 1: the hair dryer's OE (5, 6, 3) refinement bought a 91 % headline with a slow pole
// (41 % from the measured outputs). The kept model is judged on both initial states, so the headline
// is never more than 5 points above the measured-start fit without a warning, and the result is not
// worse than the plain ARX least squares on the worse of both fits.
#[test]
fn hair_dryer_output_error_is_not_flattered_by_its_initial_state() {
    let Some(dir) = data_dir() else { return };
    let args = [
        identify_arx(Path::new("hair_dryer_pt326/dryer.csv"), "5", "6", "oe"),
        vec!["--ts", "0.08", "--nk", "3", "--offset"],
    ]
    .concat();
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

// Audit s10 F1: with `--detrend linear` the figures are reported on the record in the user's units
// (the model carries the means, not the drift), but the warnings were judged on the detrended record:
// a dryer Hammerstein OE printed 84.41 % against −19.97 % from the measured outputs with neither the
// initial-state nor the negative-fit warning, and warnings quoted figures that were not printed. Every
// warning about the estimation figures is now judged on the printed ones (checked from the JSON).
#[test]
fn detrended_records_are_judged_on_the_figures_reported() {
    let Some(dir) = data_dir() else { return };
    for (orders, rows) in [(["2", "4", "3"], "0..500"), (["4", "3", "3"], "0..500")] {
        let args = [
            "identify",
            "--data",
            "hair_dryer_pt326/dryer.csv",
            "--ts",
            "0.08",
            "--structure",
            "hammerstein",
            "--method",
            "oe",
            "--na",
            orders[0],
            "--nb",
            orders[1],
            "--nk",
            orders[2],
            "--detrend",
            "linear",
            "--rows",
            rows,
        ];
        let doc = run_json(&dir, &args);
        let what = format!("dryer Hammerstein OE {orders:?} --detrend linear");
        assert_headline_not_flattered_silently(&doc, &what);
        let m = &doc["metrics"]["estimation"];
        let (e, s) = (
            m["fit_sim_percent"].as_f64().unwrap(),
            m["fit_sim_measured_percent"].as_f64().unwrap(),
        );
        let said = warnings(&doc);
        if e.min(s) < 0.0 {
            assert!(
                said.iter()
                    .any(|w| w.contains("negative simulation fit on the estimation data")),
                "{what}: {e} / {s} %: {said:?}"
            );
        }
        for w in said
            .iter()
            .filter(|w| w.contains("on the estimation data depends on the initial state"))
        {
            assert!(
                w.contains(&format!("{e:.2} %")) && w.contains(&format!("{s:.2} %")),
                "{what}: the warning quotes other figures than {e} / {s}: {w}"
            );
        }
    }
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

// Audit of session 6, finding 1: on 148 samples of the gas furnace, output error of ARX(2,2,3) holds a
// pole at the stability boundary to imitate the output's level (no offset). The poles are recomputed
// here from the JSON's a1, a2 by the quadratic formula; a pole within 1e-5 of the unit circle must be
// warned about (its static gain is not determined), and the search must not call that plain convergence.
#[test]
fn a_pole_held_on_the_stability_boundary_is_warned() {
    let Some(dir) = data_dir() else { return };
    let doc = run_json(
        &dir,
        &[
            identify_arx(
                Path::new("gas_furnace_box_jenkins/gas_furnace.csv"),
                "2",
                "2",
                "oe",
            ),
            vec![
                "--ts",
                "9",
                "--u-col",
                "InputGasRate",
                "--y-col",
                "CO2",
                "--nk",
                "3",
                "--rows",
                "0..148",
            ],
        ]
        .concat(),
    );
    let a = doc["model"]["a"].as_array().unwrap();
    let (a1, a2) = (a[0].as_f64().unwrap(), a[1].as_f64().unwrap());
    // z² + a1 z + a2 = 0.
    let disc = a1 * a1 - 4.0 * a2;
    let largest = if disc >= 0.0 {
        ((-a1).abs() + disc.sqrt()) / 2.0
    } else {
        a2.abs().sqrt()
    };
    let w = warnings(&doc);
    if (1.0 - 1e-5..1.0).contains(&largest) {
        assert!(
            w.iter().any(|w| w.contains("on the stability boundary")),
            "pole {largest}: {w:?}"
        );
        let notes = doc["estimation"].to_string();
        assert!(
            !notes.contains("relative change of the parameters below tolerance"),
            "{notes}"
        );
    } else {
        assert!(
            !w.iter().any(|w| w.contains("on the stability boundary")),
            "pole {largest}: {w:?}"
        );
    }
}

// Audit finding 5: the physics plant at --setpoint 50 creeps into the set-point's 2 % band. Its settling
// time is the last time the trace is outside [49, 51] mm, recomputed here from the 40 s run's CSV; the
// 20 s and 40 s runs must both report it (it used to depend on the run's length), or no settling time.
#[test]
fn settling_time_of_a_creeping_step_does_not_depend_on_the_run_length() {
    // 50 mm creeps up (friction) at 20 and 40 s; 150 mm creeps down from an overshoot and ends inside
    // the set-point's band at 40, 60 and 80 s (re-audit finding D: 7.11, 8.17, 8.39 s before).
    // Re-audit s8 F1: the 5 s and 10 s runs of 150 mm said 0.374 s and nothing (a creep passed off as rest).
    for (r, runs) in [
        (50.0, &[40.0, 20.0, 10.0, 5.0][..]),
        (150.0, &[80.0, 60.0, 40.0, 10.0, 5.0][..]),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let csv = tmp.path().join("c.csv");
        let longest = format!("{}", runs[0]);
        let r_arg = format!("{r}");
        control(&[
            "--plant",
            "ipa",
            "--setpoint",
            &r_arg,
            "--duration",
            &longest,
            "--out",
            csv.to_str().unwrap(),
        ]);
        let rows = trace_rows(&csv);
        // The set-point's 2 % band (the run starts at rest at y(0)).
        let band = 0.02 * (r - rows[0].2).abs();
        let outside = rows
            .iter()
            .rposition(|&(_, _, y)| (y - r).abs() > band)
            .unwrap();
        // The crossing lies between the last sample outside and the next one.
        let (lo, hi) = (rows[outside].0, rows[outside + 1].0);
        assert!(
            hi < runs[0] - 5.0,
            "the longest run must enter the band well before its end"
        );
        for &run in runs {
            let d = format!("{run}");
            let (doc, _) = control(&["--plant", "ipa", "--setpoint", &r_arg, "--duration", &d]);
            let ts = &doc["steps"][0]["metrics"]["settling_time_s"];
            let w = warnings(&doc);
            if hi <= run * 0.8 {
                let ts = ts
                    .as_f64()
                    .unwrap_or_else(|| panic!("{r} mm, {run} s: {w:?}"));
                assert!(
                    ts >= lo - 1e-9 && ts <= hi + 1e-9,
                    "{r} mm, {run} s: {ts} not in [{lo}, {hi}]"
                );
            } else {
                assert!(ts.is_null(), "{r} mm, {run} s: {ts}");
            }
        }
    }
}

// Re-audit s8 F2 and F3. A PI with Kp = 60, Ki = 10 hunts around 50 mm; its 8 s run ended on a sample
// that fell on r, which gave "settling 7.998 s" and "|e_ss| < 2 % of the step: yes". A staircase step of
// 2 mm that the piston never follows (friction) was left out of the worst step. Seen from the traces:
// the last fifth of the hunting run swings across the whole band; the held step's output never moves.
#[test]
fn a_hunting_loop_and_a_step_without_response_have_not_settled() {
    let tmp = tempfile::tempdir().unwrap();
    let csv = tmp.path().join("h.csv");
    let args = [
        "--plant",
        "ipa",
        "--setpoint",
        "50",
        "--kp",
        "60",
        "--ki",
        "10",
        "--duration",
        "8",
    ];
    let mut with_out = args.to_vec();
    with_out.extend(["--out", csv.to_str().unwrap()]);
    let (doc, _) = control(&with_out);
    let rows = trace_rows(&csv);
    let tail = &rows[rows.len() - rows.len() / 5..];
    let (lo, hi) = tail
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| {
            (a.min(r.2), b.max(r.2))
        });
    assert!(
        lo < 49.0 && hi > 51.0,
        "the case is gone: the tail spans {lo}..{hi}"
    );
    assert!(
        doc["metrics"]["settling_time_s"].is_null(),
        "{}",
        doc["metrics"]
    );
    let w = warnings(&doc);
    assert!(w.iter().any(|w| w.contains("oscillates")), "{w:?}");
    let text = bin().arg("control").args(args).output().unwrap();
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(!text.contains("of the step: yes"), "{text}");

    let csv = tmp.path().join("s.csv");
    let (doc, _) = control(&[
        "--plant",
        "ipa",
        "--profile",
        "staircase:100,98,100@5",
        "--out",
        csv.to_str().unwrap(),
    ]);
    let held: Vec<f64> = trace_rows(&csv)
        .iter()
        .filter(|r| r.0 >= 5.0 && r.0 < 10.0)
        .map(|r| r.2)
        .collect();
    assert!(
        held.iter().all(|&y| y == held[0]) && (held[0] - 98.0).abs() > 1.0,
        "the case is gone: {:?}",
        &held[..3]
    );
    assert!(
        doc["metrics"]["settling_time_s"].is_null(),
        "{}",
        doc["metrics"]
    );
    let w = warnings(&doc);
    assert!(
        w.iter()
            .any(|w| w.contains("r = 98 mm") && w.contains("no response")),
        "{w:?}"
    );
    // Lengths as a person writes them, not 2.5900000000000034.
    assert!(w.iter().all(|w| !w.contains("0000000")), "{w:?}");
}

/// The rows (t, u, y) of a `control --out` trace.
// Audit s10 F3: `control --plant paper --setpoint 150 --duration 0.1` (11 samples, the piston still
// rising 3.5 mm per sample, 122 mm short) reported "settling 0.0984 s"; short staircase holds the same.
// A step of fewer than 20 samples has only its error (read from the trace here), with a warning.
#[test]
fn a_step_too_short_to_judge_has_no_rise_or_settling_time() {
    let tmp = tempfile::tempdir().unwrap();
    let csv = tmp.path().join("c.csv");
    let (doc, _) = control(&[
        "--plant",
        "paper",
        "--setpoint",
        "150",
        "--duration",
        "0.1",
        "--out",
        csv.to_str().unwrap(),
    ]);
    let rows = trace_rows(&csv);
    assert!(rows.len() < 20, "{} samples", rows.len());
    let m = &doc["metrics"];
    for k in ["rise_time_s", "settling_time_s", "overshoot_percent"] {
        assert!(m[k].is_null(), "{k}: {m}");
    }
    let e = 150.0 - rows.last().unwrap().2;
    assert!(
        (m["steady_state_error_mm"].as_f64().unwrap() - e).abs() < 1e-9,
        "{m} vs {e}"
    );
    let w = warnings(&doc);
    assert!(w.iter().any(|w| w.contains("too short to judge")), "{w:?}");
    let (doc, _) = control(&["--plant", "paper", "--profile", "staircase:50,150,60@0.1"]);
    let steps = doc["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 3, "{}", doc["steps"]);
    for st in steps {
        assert!(st["metrics"]["settling_time_s"].is_null(), "{st}");
    }
    assert!(
        doc["metrics"]["settling_time_s"].is_null(),
        "{}",
        doc["metrics"]
    );
}

/// A folder with `ms.csv`: 400 samples of y(k+1) = 0.9 y(k) + 0.01 u(k), u a ±square wave, and a time
/// column in milliseconds (t = 0, 10, 20, ...).
fn ms_record() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    let mut csv = String::from("t,u,y\n");
    let mut y = 0.0;
    for k in 0..400 {
        let u = if (k / 25) % 2 == 0 { 100.0 } else { -80.0 };
        csv.push_str(&format!("{},{u},{y}\n", k * 10));
        y = 0.9 * y + 0.01 * u;
    }
    std::fs::write(tmp.path().join("ms.csv"), csv).unwrap();
    tmp
}

// Audit s10 F5: a time column in milliseconds read as seconds (t = 0, 10, 20, ...) silently gave
// Ts = 10 s, and every time figure after it (rise and settling times of `control` on the model) was
// 1000 times too large. The reader now says so; with `--time-unit ms` Ts is 0.01 s and nothing is said.
#[test]
fn a_time_column_in_milliseconds_read_as_seconds_is_pointed_out() {
    let tmp = ms_record();
    let run = |extra: &[&str]| {
        let mut args: Vec<&str> =
            "identify --data ms.csv --structure arx --method ls --na 1 --nb 1 --nk 1"
                .split(' ')
                .collect();
        args.extend(extra);
        run_json(tmp.path(), &args)
    };
    let doc = run(&[]);
    assert_eq!(doc["model"]["ts"].as_f64(), Some(10.0));
    assert!(
        warnings(&doc).iter().any(|w| w.contains("--time-unit ms")),
        "{:?}",
        warnings(&doc)
    );
    let doc = run(&["--time-unit", "ms"]);
    assert_eq!(doc["model"]["ts"].as_f64(), Some(0.01));
    assert!(
        !warnings(&doc).iter().any(|w| w.contains("--time-unit")),
        "{:?}",
        warnings(&doc)
    );
}

// Audit s13 M6: `--ts` that contradicts the record's time column was used without a word (a model of
// a 0.01 s record saved at Ts = 0.02 s). It still wins, and the reader says so, naming both; a --ts
// equal to the column's step (to 0.1 %), or in the column's unit (--time-unit ms), says nothing.
#[test]
fn a_ts_that_contradicts_the_time_column_is_pointed_out() {
    let tmp = ms_record();
    let run = |extra: &[&str]| {
        let mut args: Vec<&str> =
            "identify --data ms.csv --structure arx --method ls --na 1 --nb 1 --nk 1 --time-unit ms"
                .split(' ')
                .collect();
        args.extend(extra);
        run_json(tmp.path(), &args)
    };
    let said = |doc: &serde_json::Value| {
        warnings(doc).iter().any(|w| {
            w.contains("--ts 0.02 s contradicts the time column t (its typical step is 0.01 s)")
        })
    };
    let doc = run(&["--ts", "0.02"]);
    assert_eq!(doc["model"]["ts"].as_f64(), Some(0.02));
    assert!(said(&doc), "{:?}", warnings(&doc));
    for agreeing in ["0.01", "0.010005"] {
        let doc = run(&["--ts", agreeing]);
        assert!(
            !warnings(&doc).iter().any(|w| w.contains("contradicts")),
            "{agreeing}: {:?}",
            warnings(&doc)
        );
    }
}

// Audit s10 F4: one input sample of 1e308 (finite, accepted) made the covariance underflow: b1 and b2
// were reported "± 0", the strongest claim a tool can make, about parameters the data no longer
// determine. A standard deviation of exactly 0 from residuals that are not zero is withheld and said.
#[test]
fn an_underflowing_covariance_is_not_reported_as_certainty() {
    let tmp = tempfile::tempdir().unwrap();
    let mut csv = String::from("t,u,y\n");
    let mut y = 0.0;
    for k in 0..300 {
        let u = if k == 150 {
            1e308
        } else {
            ((k * 37) % 11) as f64 - 5.0
        };
        let e = ((k * 53) % 7) as f64 * 0.01 - 0.03;
        csv.push_str(&format!("{},{u:e},{:?}\n", k as f64 * 0.08, y + e));
        y = 0.5 * y + 0.1 * if k == 150 { 0.0 } else { u };
    }
    std::fs::write(tmp.path().join("outlier.csv"), csv).unwrap();
    let args: Vec<&str> =
        "identify --data outlier.csv --structure arx --method ls --na 1 --nb 2 --nk 1"
            .split(' ')
            .collect();
    let doc = run_json(tmp.path(), &args);
    assert!(doc["estimation"]["noise_variance"].as_f64().unwrap() > 0.0);
    let zero: Vec<&Value> = doc["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["std"].as_f64() == Some(0.0))
        .collect();
    assert!(zero.is_empty(), "{zero:?}");
    assert!(
        warnings(&doc)
            .iter()
            .any(|w| w.contains("came out exactly 0")),
        "{:?}",
        warnings(&doc)
    );
}

fn trace_rows(csv: &Path) -> Vec<(f64, f64, f64)> {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (it, iu, iy) = (col("t"), col("u"), col("y"));
    lines
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|v| v.parse().unwrap()).collect();
            (f[it], f[iu], f[iy])
        })
        .collect()
}

// Re-audit finding C: friction holds the piston 2.14 mm short of 50 mm from 0.1 s on while the PI's
// integrator winds the command up; that flat output used to get a settling time of 0.10 s (and, in a
// staircase, no word at all). Seen from the trace: the last second's output is flat, outside the
// set-point's band, while the command still rises; then there is no settling time, and a warning.
#[test]
fn a_step_held_by_friction_short_of_the_set_point_has_not_settled() {
    for profile in [
        &["--setpoint", "50", "--duration", "5"][..],
        &["--profile", "staircase:50,100@5"][..],
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let csv = tmp.path().join("c.csv");
        let mut args = vec!["--plant", "ipa", "--out", csv.to_str().unwrap()];
        args.extend_from_slice(profile);
        let (doc, _) = control(&args);
        let rows: Vec<(f64, f64, f64)> = trace_rows(&csv)
            .into_iter()
            .filter(|&(t, _, _)| t < 5.0 - 1e-9)
            .collect();
        let last_second: Vec<&(f64, f64, f64)> =
            rows.iter().filter(|&&(t, _, _)| t >= 4.0 - 1e-9).collect();
        let (first, last) = (last_second[0], last_second[last_second.len() - 1]);
        assert!(
            (last.2 - first.2).abs() <= 0.1 && (50.0 - last.2).abs() > 1.0 && last.1 > first.1,
            "{profile:?}: the case this test is about (held short, command rising) is gone: {first:?} {last:?}"
        );
        let step = &doc["steps"][0];
        assert!(
            step["metrics"]["settling_time_s"].is_null(),
            "{profile:?}: {step}"
        );
        if profile[0] == "--profile" {
            assert!(
                doc["metrics"]["settling_time_s"].is_null(),
                "{profile:?}: the worst step's settling time must be null: {}",
                doc["metrics"]
            );
        }
        let w = warnings(&doc);
        assert!(
            w.iter()
                .any(|w| w.contains("r = 50 mm") && w.contains("has not settled")),
            "{profile:?}: {w:?}"
        );
        assert!(
            w.iter()
                .any(|w| w.contains("misses the paper's acceptance")),
            "{profile:?}: {w:?}"
        );
    }
}

// Audit finding 7: instrumental variables on the ball-beam record, ARX(5,6,1) with an offset: every
// parameter without a standard deviation must be explained by a warning.
#[test]
fn instrumental_variables_say_why_standard_deviations_are_missing() {
    let Some(dir) = data_dir() else { return };
    let doc = run_json(
        &dir,
        &[
            identify_arx(Path::new("ball_and_beam/ballbeam.csv"), "5", "6", "iv"),
            vec!["--ts", "0.1", "--nk", "1", "--offset"],
        ]
        .concat(),
    );
    let missing = doc["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["std"].is_null())
        .count();
    if missing > 0 {
        let w = warnings(&doc);
        assert!(
            w.iter().any(|w| w.contains("no standard deviation")),
            "{missing} missing: {w:?}"
        );
    }
}

// Audit finding 8: ARX(2,2,1) with an offset on 250 samples of the coupled drives: the fit from the
// measured initial outputs is negative (the JSON's own two fits; the worse one is what every decision
// uses), so the model is no better than the mean, and that must be said.
#[test]
fn a_negative_fit_from_the_measured_start_is_called_negative() {
    let Some(dir) = data_dir() else { return };
    let doc = run_json(
        &dir,
        &[
            identify_arx(
                Path::new("coupled_electric_drives_prbs/DATAPRBS.csv"),
                "2",
                "2",
                "ls",
            ),
            vec![
                "--ts", "0.02", "--u-col", "u1", "--y-col", "z1", "--nk", "1", "--offset",
                "--rows", "0..250",
            ],
        ]
        .concat(),
    );
    let guarded = guarded(&doc["metrics"]["estimation"]);
    let w = warnings(&doc);
    let said = w.iter().any(|w| w.contains("negative simulation fit"));
    assert_eq!(guarded.is_some_and(|g| g < 0.0), said, "{guarded:?}: {w:?}");
}

// Audit finding 9: the coupled drives' input u1 takes two levels (counted here from the CSV); a
// deadzone cannot be determined from two points, and the error must say so, not blame a regressor.
#[test]
fn a_nonlinearity_on_a_two_level_input_is_refused_with_the_reason() {
    let Some(dir) = data_dir() else { return };
    let file = dir.join("coupled_electric_drives_prbs/DATAPRBS.csv");
    let text = std::fs::read_to_string(&file).unwrap();
    let mut levels: Vec<f64> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().trim().parse().unwrap())
        .collect();
    levels.sort_by(f64::total_cmp);
    levels.dedup();
    let out = bin()
        .args(["identify", "--data"])
        .arg(&file)
        .args([
            "--ts",
            "0.02",
            "--u-col",
            "u1",
            "--y-col",
            "z1",
            "--structure",
            "hammerstein",
            "--method",
            "ls",
            "--na",
            "2",
            "--nb",
            "2",
            "--nk",
            "1",
        ])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    if levels.len() == 2 {
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains("only 2 distinct levels"), "{err}");
        assert!(err.contains("DATAPRBS.csv"), "{err}");
    }
}

// Re-audit finding B: `identify --stream on` (automatic from 64 MiB) judged its estimation record on
// the headline alone, so the initial-state and negative-fit warnings of the in-memory path were
// missing (gas furnace ARX(2,2,3): 45.35 % against 0.82 % from the measured outputs, `warnings: []`).
// Both paths must now give the same warnings, and the rules hold on the streamed JSON's own figures.
#[test]
fn streamed_identification_warns_like_the_in_memory_path() {
    let Some(dir) = data_dir() else { return };
    let gas = |nk: &'static str| {
        vec![
            "--data",
            "gas_furnace_box_jenkins/gas_furnace.csv",
            "--ts",
            "9",
            "--u-col",
            "InputGasRate",
            "--y-col",
            "CO2",
            "--na",
            "2",
            "--nb",
            "2",
            "--nk",
            nk,
        ]
    };
    let drives = vec![
        "--data",
        "coupled_electric_drives_prbs/DATAPRBS.csv",
        "--ts",
        "0.02",
        "--u-col",
        "u1",
        "--y-col",
        "z1",
        "--na",
        "2",
        "--nb",
        "2",
        "--nk",
        "1",
        "--offset",
        "--rows",
        "0..250",
        "--val-rows",
        "250..500",
    ];
    let cases = [gas("3"), gas("1"), drives];
    for case in &cases {
        let mut docs = Vec::new();
        for mode in ["off", "on"] {
            let mut args = vec!["identify", "--structure", "arx", "--method", "ls"];
            args.extend_from_slice(case);
            args.extend(["--stream", mode]);
            docs.push(run_json(&dir, &args));
        }
        let (memory, streamed) = (&docs[0], &docs[1]);
        assert_headline_not_flattered_silently(streamed, &format!("{case:?} streamed"));
        let guarded = guarded(&streamed["metrics"]["estimation"]).unwrap();
        let w = warnings(streamed);
        let negative = w
            .iter()
            .find(|w| w.contains("negative simulation fit on the estimation data"));
        if guarded < 0.0 {
            // The figure quoted is the worse of the two fits, to the two decimals printed.
            let quoted = format!("{guarded:.2} %");
            assert!(
                negative.is_some_and(|w| w.contains(&quoted)),
                "{case:?}: guarded fit {quoted}: {w:?}"
            );
        } else {
            assert!(negative.is_none(), "{case:?}: {w:?}");
        }
        assert_eq!(w, warnings(memory), "{case:?}: streamed vs in memory");
    }
}

// Re-audit s8 H1: a Hammerstein model file with absurd deadzone slopes. With m = 1e300 the closed loop
// reaches |y| ~ 1e303 mm: the run must say that it diverges and print its numbers in a readable form
// (not 300 digits); a zero slope makes a model that cannot respond, which `simulate` must say.
#[test]
fn a_model_with_absurd_deadzone_slopes_is_called_what_it_is() {
    // The longest run of digits and points in a text: a number printed in full.
    fn longest_number(text: &str) -> usize {
        text.split(|c: char| !(c.is_ascii_digit() || c == '.'))
            .map(str::len)
            .max()
            .unwrap_or(0)
    }
    let tmp = tempfile::tempdir().unwrap();
    let model = |name: &str, m: &str| {
        let p = tmp.path().join(name);
        std::fs::write(
            &p,
            format!(
                r#"{{"format": "ipa-sysid-model", "version": 2, "model": {{"kind": "hammerstein", "ts": 0.01,
                "na": 1, "nb": 1, "nk": 1, "a": [-0.9], "b": [1.0], "offset": null,
                "deadzone": {{"b_l": -40.0, "b_r": 40.0, "m_l": {m}, "m_r": {m}}}}}}}"#
            ),
        )
        .unwrap();
        format!("model:{}", p.display())
    };
    let huge = model("huge.json", "1e300");
    let args = ["--plant", &huge, "--setpoint", "50", "--duration", "2"];
    let (doc, _) = control(&args);
    let w = warnings(&doc);
    assert!(w.iter().any(|w| w.contains("diverges")), "{w:?}");
    let text = bin().arg("control").args(args).output().unwrap();
    let text = String::from_utf8_lossy(&text.stdout).into_owned();
    let longest = longest_number(&text);
    assert!(longest < 30, "a number of {longest} characters: {text}");
    // `tune` on that model says its loop diverges.
    let tuned = bin()
        .args([
            "tune",
            "--max-evaluations",
            "8",
            "--variants",
            "1",
            "--model",
        ])
        .arg(huge.trim_start_matches("model:"))
        .arg("--out")
        .arg(tmp.path().join("c.json"))
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&tuned.stdout).into_owned()
        + &String::from_utf8_lossy(&tuned.stderr);
    assert!(said.contains("the closed loop diverges"), "{said}");
    // ... and its table prints the diverged figures in scientific notation, not 300 digits.
    assert!(longest_number(&said) < 30, "{said}");

    let zero = model("zero.json", "0.0");
    let out = bin()
        .args(["simulate", "--plant", &zero, "--samples", "50", "--out"])
        .arg(tmp.path().join("s.csv"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("a slope is zero"), "{err}");
}

// Re-audit s8 H2/H3: an input of magnitude 1e300 overflows the residual test's lagged sums (its
// message used to say the input "does not excite" the lags), and numbers of 1e306 overflow the
// estimation itself, whose error must name the file.
#[test]
fn overflowing_records_are_called_overflowing_and_named() {
    let tmp = tempfile::tempdir().unwrap();
    let write = |name: &str, scale: f64, y_scale: f64| {
        let mut text = String::from("t,u,y\n");
        for k in 0..400 {
            let u = scale * (1.7 * k as f64).sin();
            let y = y_scale * ((1.7 * (k as f64 - 1.0)).sin() + 0.1 * (0.3 * k as f64).cos());
            text += &format!("{},{u:e},{y}\n", k as f64 * 0.01);
        }
        let p = tmp.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    };
    let big = write("big.csv", 1e300, 1.0);
    let out = bin()
        .args(["identify", "--structure", "arx", "--method", "ls", "--data"])
        .arg(&big)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(!text.contains("does not excite"), "{text}");
    assert!(text.contains("overflow"), "{text}");

    let huge = write("huge.csv", 1e307, 1e307);
    let out = bin()
        .args(["identify", "--structure", "arx", "--method", "ls", "--data"])
        .arg(&huge)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(err.contains("huge.csv"), "{err}");
}

/// A tuned controller file (as `tune --out` writes it) with a slow integrator Ki = 0.1 and the
/// deadzone inverse of an identified IPA model (audit s9 T1).
const SLOW_INTEGRATOR: &str = r#"{"format": "ipa-sysid-controller", "version": 1, "controller": {
  "ts_s": 0.01, "kp": 10.234389230084679, "ki": 0.10025884372280375, "kd": 0.6542214768665386,
  "derivative_filter_s": 0.02, "u_max": 255.0, "hold_band_mm": 0.02, "fine_band_mm": 3.1774078170190947,
  "reset_on_crossing": true,
  "nudge": {"band_mm": 0.1911648568142366, "ramp_counts_s": 670.9814613425362, "start_fraction": 0.8,
            "rest_samples": 3, "cut_fraction": 0.4084372940142852, "rest_band_mm": 0.19810037930232854},
  "compensator": {"deadzone": {"b_l": -47.31713551774844, "b_r": 37.07152419349243,
                               "m_l": 0.005427574015182067, "m_r": 0.005569272710158329},
                  "slope_mode": "shift", "threshold_counts": 0.0, "u_max": 255.0}}}"#;

// Audit s9 T1: friction holds the piston 1.5 mm short of 165 mm (outside the 0.2 mm band) while
// the slow integrator winds the command at ~0.15 counts/s; over a 3 s run's last fifth that is under
// 1 % of the command, so the step was called settled in 0.13 s (and `tune` counted such stalls as
// met). Seen from the trace: the command's drift over the tail, carried over the run's length,
// exceeds 1 % of its magnitude (the rule of docs/control.md, re-derived here): no settling time.
#[test]
fn a_stall_with_a_slowly_winding_integrator_has_not_settled() {
    let tmp = tempfile::tempdir().unwrap();
    let c = tmp.path().join("c.json");
    std::fs::write(&c, SLOW_INTEGRATOR).unwrap();
    let csv = tmp.path().join("t.csv");
    let (doc, _) = control(&[
        "--plant",
        "ipa",
        "--controller",
        c.to_str().unwrap(),
        "--y0",
        "175",
        "--setpoint",
        "165",
        "--duration",
        "3",
        "--out",
        csv.to_str().unwrap(),
    ]);
    let rows = trace_rows(&csv);
    let n = rows.len();
    let m = (n as f64 * 0.2) as usize;
    let tail: Vec<f64> = rows[n - m..].iter().map(|r| r.1).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let drift = 2.0 * (mean(&tail[m / 2..]) - mean(&tail[..m / 2])).abs();
    let scale = tail.iter().fold(0.0_f64, |a, u| a.max(u.abs()));
    let y_f = rows[n - 1].2;
    assert!(
        (165.0 - y_f).abs() > 0.2 && drift < 0.01 * scale && drift * n as f64 / m as f64 > 0.01 * scale,
        "the case this test is about (a stall outside the band, the command drifting slowly) is gone: \
         y_f {y_f}, drift {drift}, scale {scale}"
    );
    assert!(
        doc["metrics"]["settling_time_s"].is_null(),
        "{}",
        doc["metrics"]
    );
    let w = warnings(&doc);
    assert!(w.iter().any(|w| w.contains("integrator winds up")), "{w:?}");
}

/// `tune ARGS` in `dir`: exit status, standard output + error.
fn tune(dir: &Path, args: &[&str]) -> (bool, String) {
    let out = bin()
        .current_dir(dir)
        .arg("tune")
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr),
    )
}

/// A one-pole Hammerstein model with the identified IPA deadzone: y(k) = a y(k−1) + f(u(k−1)).
fn one_pole_model(dir: &Path, name: &str, a1: f64) {
    std::fs::write(
        dir.join(name),
        format!(
            r#"{{"format": "ipa-sysid-model", "version": 2, "model": {{"kind": "hammerstein", "ts": 0.01,
            "na": 1, "nb": 1, "nk": 1, "a": [{a1}], "b": [1.0], "offset": null,
            "deadzone": {{"b_l": -48.0, "b_r": 37.6, "m_l": 0.0054, "m_r": 0.0056}}}}}}"#
        ),
    )
    .unwrap();
}

// Audit s9 T10: `tune`'s defaults are the IPA's units (±255 counts, steps up to 150 mm). A model
// identified on a plant in volts and metres records its data's range, and `tune` says when the
// specification lies far outside it (the ratios recomputed here from the record), and not once the
// specification is given in the model's units.
#[test]
fn tune_says_when_the_specification_is_far_outside_the_models_data() {
    let tmp = tempfile::tempdir().unwrap();
    // y(k) = y(k−1) + f(u(k−1)), f a deadzone ±0.5 V with slopes 0.002 m/V per sample; u a sine of ±4 V.
    let n = 600;
    let u: Vec<f64> = (0..n)
        .map(|k| {
            4.0 * (2.0 * std::f64::consts::PI * k as f64 / 80.0).sin()
                + 0.3 * ((k * 7) % 5) as f64 / 4.0
        })
        .collect();
    let f = |v: f64| {
        if v > 0.5 {
            0.002 * (v - 0.5)
        } else if v < -0.5 {
            0.002 * (v + 0.5)
        } else {
            0.0
        }
    };
    let mut y = vec![0.1; n];
    for k in 1..n {
        y[k] = y[k - 1] + f(u[k - 1]);
    }
    let mut csv = String::from("t,u,y\n");
    for k in 0..n {
        csv.push_str(&format!("{},{:?},{:?}\n", k as f64 * 0.01, u[k], y[k]));
    }
    std::fs::write(tmp.path().join("volts.csv"), csv).unwrap();
    let o = bin()
        .current_dir(tmp.path())
        .args(
            "identify --data volts.csv --structure hammerstein --method ls --na 1 --nb 1 --nk 1 \
             --save-model m.json"
                .split_whitespace(),
        )
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("m.json")).unwrap()).unwrap();
    let min_max = |s: &[f64]| {
        let lo = s.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = s.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    };
    let ((ulo, uhi), (ylo, yhi)) = (min_max(&u), min_max(&y));
    let range = &doc["model"]["data_range"];
    assert_eq!(range["u"][0][0].as_f64(), Some(ulo), "{range}");
    assert_eq!(range["u"][0][1].as_f64(), Some(uhi), "{range}");
    assert_eq!(range["y"][0].as_f64(), Some(ylo), "{range}");
    assert_eq!(range["y"][1].as_f64(), Some(yhi), "{range}");
    let base: Vec<&str> = "--model m.json --out c.json --variants 1 --max-evaluations 16"
        .split_whitespace()
        .collect();
    let (ok, said) = tune(tmp.path(), &base);
    assert!(ok, "{said}");
    let u_ratio = 255.0 / ulo.abs().max(uhi.abs());
    let y_ratio = 150.0 / (yhi - ylo);
    // One warning per fact (session 23): the limit's factor and the steps' are said in the warning of
    // the commands and of the set-points beyond the data, each once.
    let lines = |needle: &str| -> Vec<String> {
        said.lines()
            .filter(|l| l.contains(needle))
            .map(str::to_string)
            .collect()
    };
    let u_lines = lines("command limit u_max = 255 is");
    assert_eq!(u_lines.len(), 1, "{said}");
    assert!(
        u_lines[0].contains(&format!("{u_ratio:.4} times"))
            && u_lines[0].contains("the commands (|u| <= u_max) span")
            && u_lines[0].contains("extrapolates"),
        "{said}"
    );
    let y_lines = lines("steps (up to 150");
    assert_eq!(y_lines.len(), 1, "{said}");
    assert!(
        y_lines[0].contains(&format!("{y_ratio:.4} times"))
            && y_lines[0].contains("the set-points (low .. high) span")
            && y_lines[0].contains("extrapolates"),
        "{said}"
    );
    assert_eq!(lines("extrapolates").len(), 2, "{said}");
    let mut args = base.to_vec();
    args.extend(["--spec", "u-max=4,steps=0.05/0.1,low=0.12,high=0.3"]);
    let (ok, said) = tune(tmp.path(), &args);
    assert!(ok, "{said}");
    assert!(
        !said.contains("extrapolates") && !said.contains("times the largest |u|"),
        "{said}"
    );
}

// Audit s9 T6/T7/T4: a specification the plants cannot run is refused, naming --spec and what was
// expected, and no controller is written: runs of fewer than 20 samples, set-points beyond the
// physics plant's 200 mm stroke, a key given twice, a share above 1, a settling target as long as the
// run, set-points where a step is lost in rounding.
#[test]
fn tune_refuses_a_specification_its_plants_cannot_run() {
    let tmp = tempfile::tempdir().unwrap();
    one_pole_model(tmp.path(), "m.json", -1.0);
    for (spec, physics, expected) in [
        ("run=0.1", false, "at least 20 samples"),
        ("high=500", true, "within the plant's stroke 0..200 mm"),
        ("ess=0.1,ess=0.2", false, "ess is given twice"),
        ("ess-share=2", false, "in (0, 1]"),
        // Audit s21 L-B4: a target no run can miss, and set-points where a step rounds to 0
        // (-1e308 + 10 = -1e308 in f64).
        (
            "settling=10,run=3",
            false,
            "settling target shorter than each step's run",
        ),
        ("low=-1e308", false, "lost in rounding"),
        ("high=1e300,low=0", false, "lost in rounding"),
    ] {
        let mut args = vec!["--model", "m.json", "--out", "c.json", "--spec", spec];
        if physics {
            args.push("--check-physics");
        }
        let (ok, said) = tune(tmp.path(), &args);
        assert!(!ok, "{spec}: {said}");
        assert!(
            said.contains("--spec") && said.contains(expected),
            "{spec}: {said}"
        );
        assert!(!tmp.path().join("c.json").exists(), "{spec}");
    }
}

// Audit s9 T2/T8: a = −0.5 makes a model whose output can rest only within ±m·(255 − b)/(1 − 0.5)
// ≈ ±2.4 mm, far from the 25..175 mm set-points. From 25 mm towards 35 its output falls towards
// 2.4 mm: the step moved away. Such a run has no overshoot, rise or settling time and is not counted
// as meeting the overshoot target; the tool says the model cannot hold the set-points. Expectations
// from the JSON's own runs: a run moved away when |e_ss| > |r − y0|.
#[test]
fn tune_on_a_model_that_cannot_reach_its_set_points_says_so() {
    let tmp = tempfile::tempdir().unwrap();
    one_pole_model(tmp.path(), "m.json", -0.5);
    let (ok, said) = tune(
        tmp.path(),
        &[
            "--model",
            "m.json",
            "--out",
            "c.json",
            "--json",
            "r.json",
            "--variants",
            "1",
            "--max-evaluations",
            "16",
        ],
    );
    assert!(ok, "{said}");
    let hi = 0.0056 * (255.0 - 37.6) / 0.5;
    assert!(
        said.contains("the model cannot hold the set-points") && said.contains(&format!("{hi:.4}")),
        "{said}"
    );
    let doc: Value =
        serde_json::from_str(&std::fs::read_to_string(tmp.path().join("r.json")).unwrap()).unwrap();
    let tuned = &doc["on_model"]["tuned"];
    let runs = tuned["runs"].as_array().unwrap();
    let mut away = 0;
    let mut os_met = 0;
    for r in runs {
        let (y0, r_mm) = (
            r["case"]["y0_mm"].as_f64().unwrap(),
            r["case"]["r_mm"].as_f64().unwrap(),
        );
        let m = &r["metrics"];
        let e = m["steady_state_error_mm"].as_f64().unwrap();
        if e.abs() > (r_mm - y0).abs() {
            away += 1;
            for k in ["overshoot_percent", "rise_time_s", "settling_time_s"] {
                assert!(m[k].is_null(), "{k}: {r}");
            }
        } else if m["overshoot_past_setpoint_percent"]
            .as_f64()
            .or(m["overshoot_percent"].as_f64())
            .is_none_or(|os| os <= 1.0)
        {
            // The overshoot tune judges: the peak past r when there is a set-point step (audit
            // s17 M-b), else stepinfo(y, t)'s.
            os_met += 1;
        }
    }
    assert!(
        away > 0,
        "the case this test is about (a step moving away) is gone"
    );
    assert_eq!(tuned["overshoot_met"].as_u64(), Some(os_met), "{tuned}");
    assert!(said.contains("moved away from the set-point"), "{said}");
    // Audit s9 T8: whether the tuned controller beats the paper's PI on these runs is said from the
    // JSON's own counts and costs (fewer steps meeting the spec, or as many at a higher cost J: does
    // not beat; more steps at a higher J: its runs miss by more on average; else nothing).
    let pi = &doc["on_model"]["paper_pi"];
    let (met, met_pi) = (tuned["met"].as_u64().unwrap(), pi["met"].as_u64().unwrap());
    let (j, j_pi) = (
        tuned["cost"].as_f64().unwrap(),
        pi["cost"].as_f64().unwrap(),
    );
    let loses = met < met_pi || (met == met_pi && j > j_pi);
    assert_eq!(
        said.contains("does not beat the paper's PI"),
        loses,
        "{said}"
    );
    assert_eq!(
        said.contains("its runs miss by more on average"),
        !loses && j > j_pi,
        "{said}"
    );
}

// Audit s9 T9, H1–H3: beside --controller the flags it overrides are refused (they were ignored);
// a controller file with an unknown top-level field, a gain of 1e308, a compensator whose command
// limit differs from the controller's, or a device is refused, naming the file, without printing a
// 300-digit number.
#[test]
fn controller_files_and_their_flags_are_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let good = tmp.path().join("c.json");
    std::fs::write(&good, SLOW_INTEGRATOR).unwrap();
    let run = |args: &[&str]| {
        let out = bin().arg("control").args(args).output().unwrap();
        (
            out.status.code(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let c = good.to_str().unwrap();
    for flag in [
        &["--kp", "30"][..],
        &["--u-max", "100"],
        &["--compensator-threshold", "5"],
    ] {
        let mut args = vec!["--controller", c, "--setpoint", "50", "--duration", "1"];
        args.extend_from_slice(flag);
        let (code, err) = run(&args);
        assert_eq!(code, Some(2), "{flag:?}: {err}");
        assert!(err.contains("cannot be used with"), "{flag:?}: {err}");
    }
    let variants = [
        (
            "extra",
            SLOW_INTEGRATOR.replacen("\"version\": 1,", "\"version\": 1, \"extra\": 1,", 1),
            "unknown field",
        ),
        (
            "kp",
            SLOW_INTEGRATOR.replacen("\"kp\": 10.234389230084679", "\"kp\": 1e308", 1),
            "from 0 to 1e6",
        ),
        (
            "u_max",
            SLOW_INTEGRATOR.replacen(
                "\"threshold_counts\": 0.0, \"u_max\": 255.0",
                "\"threshold_counts\": 0.0, \"u_max\": 100.0",
                1,
            ),
            "the same command limit",
        ),
    ];
    for (what, text, expected) in variants {
        assert_ne!(text, SLOW_INTEGRATOR, "{what}: the edit did not apply");
        let p = tmp.path().join(format!("{what}.json"));
        std::fs::write(&p, &text).unwrap();
        let (code, err) = run(&[
            "--controller",
            p.to_str().unwrap(),
            "--setpoint",
            "50",
            "--duration",
            "1",
        ]);
        assert_eq!(code, Some(2), "{what}: {err}");
        assert!(
            err.contains(&format!("{what}.json")) && err.contains(expected),
            "{what}: {err}"
        );
        let longest = err
            .split(|c: char| !(c.is_ascii_digit() || c == '.'))
            .map(str::len)
            .max()
            .unwrap_or(0);
        assert!(longest < 30, "{what}: {err}");
    }
    if Path::new("/dev/zero").exists() {
        let (code, err) = run(&[
            "--controller",
            "/dev/zero",
            "--setpoint",
            "50",
            "--duration",
            "1",
        ]);
        assert_eq!(code, Some(2), "{err}");
        assert!(
            err.contains("/dev/zero") && err.contains("not a regular file"),
            "{err}"
        );
    } else {
        eprintln!("SKIPPED: /dev/zero is absent on this machine");
    }
}

// Audit s9 T4: a model whose deadzone breakpoint b_r = 300 counts lies beyond the command limit
// u_max = 255 cannot be moved up by any command; `tune` says so (b_l = −40 is within reach: no word).
#[test]
fn tune_says_when_a_deadzone_breakpoint_is_beyond_the_command_limit() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(
        tmp.path().join("m.json"),
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "hammerstein", "ts": 0.01,
        "na": 1, "nb": 1, "nk": 1, "a": [-1.0], "b": [1.0], "offset": null,
        "deadzone": {"b_l": -40.0, "b_r": 300.0, "m_l": 0.0054, "m_r": 0.0056}}}"#,
    )
    .unwrap();
    let (ok, said) = tune(
        tmp.path(),
        &[
            "--model",
            "m.json",
            "--out",
            "c.json",
            "--variants",
            "1",
            "--max-evaluations",
            "8",
        ],
    );
    assert!(ok, "{said}");
    assert!(
        said.contains(
            "deadzone b_r = 300.0000 counts is at or beyond the command limit u_max = 255"
        ) && said.contains("no command moves the model up"),
        "{said}"
    );
    assert!(!said.contains("deadzone b_l = "), "{said}");
}

// Audit s12: one parameter the output-error simulation does not depend on withheld EVERY standard
// deviation (133 of 196 Hammerstein–Wiener fits). Gas furnace, piecewise-linear input (2 breakpoints)
// + polynomial output by output error: a breakpoint beyond the estimation rows' input range (computed
// here from the CSV) has a zero Jacobian column, and so has the slope beyond it. Those two are named
// in the warning and have no standard deviation; the others still have theirs.
#[test]
fn a_parameter_the_data_do_not_reach_withholds_only_its_own_standard_deviation() {
    let Some(dir) = data_dir() else { return };
    let doc = run_json(
        &dir,
        &[
            "identify",
            "--data",
            "gas_furnace_box_jenkins/gas_furnace.csv",
            "--u-col",
            "InputGasRate",
            "--y-col",
            "CO2",
            "--ts",
            "9",
            "--rows",
            "0..148",
            "--na",
            "3",
            "--nb",
            "1",
            "--nk",
            "0",
            "--nonlinearity",
            "piecewise-linear",
            "--breakpoints",
            "2",
            "--method",
            "oe",
            "--output-nonlinearity",
            "polynomial",
            "--degree",
            "3",
        ],
    );
    let text =
        std::fs::read_to_string(dir.join("gas_furnace_box_jenkins/gas_furnace.csv")).unwrap();
    let u: Vec<f64> = text
        .lines()
        .skip(1)
        .take(148)
        .map(|l| l.split(',').next().unwrap().trim().parse().unwrap())
        .collect();
    let (lo, hi) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let params = doc["parameters"].as_array().unwrap();
    let value = |n: &str| params.iter().find(|p| p["name"] == n).unwrap();
    let outside: Vec<&str> = ["p1", "p2"]
        .into_iter()
        .filter(|n| {
            let p = value(n)["value"].as_f64().unwrap();
            p < lo || p > hi
        })
        .collect();
    assert!(
        !outside.is_empty(),
        "the case needs a breakpoint outside [{lo}, {hi}]"
    );
    let w = warnings(&doc);
    let said = w
        .iter()
        .find(|w| w.contains("the output-error simulation does not depend on"))
        .unwrap_or_else(|| panic!("{w:?}"));
    for n in &outside {
        assert!(said.contains(n), "{n}: {said}");
        assert!(value(n)["std"].is_null());
    }
    let with_std = params.iter().filter(|p| p["std"].is_number()).count();
    assert!(
        with_std >= params.len() / 2,
        "{with_std} of {}: {w:?}",
        params.len()
    );
}

/// The free-run fit a held-out judgement compares: the worse of both initial states, or the one fit
/// a NARX free run has when only one is given.
fn held_fit(m: &Value) -> Option<f64> {
    guarded(m).or_else(|| m["fit_sim_percent"].as_f64())
}

/// Whether a warning says the fit falls from a fitted record to a held-out one.
fn drop_said(doc: &Value) -> bool {
    warnings(doc)
        .iter()
        .any(|w| w.contains("the simulation fit falls from"))
}

// Audit s21 M-A1: the gas furnace's halves differ (a 39-point drop from estimation to validation) and
// the hair dryer's do not (7 points); the drop is said exactly when the JSON's own figures (the worse
// of both initial states) are more than 15 points apart, the estimation fit positive. NARX and OE
// included (they printed no warning at all before).
#[test]
fn a_validation_fit_far_below_the_estimation_fit_is_said() {
    let Some(dir) = data_dir() else { return };
    let gas = [
        "--data",
        "gas_furnace_box_jenkins/gas_furnace.csv",
        "--u-col",
        "InputGasRate",
        "--y-col",
        "CO2",
        "--ts",
        "9",
        "--offset",
        "--split",
        "0.5",
        "--nk",
        "3",
    ];
    let dryer = [
        "--data",
        "hair_dryer_pt326/dryer.csv",
        "--ts",
        "0.08",
        "--offset",
        "--split",
        "0.6",
        "--nk",
        "3",
    ];
    let classes: [&[&str]; 3] = [
        &["--structure", "arx", "--method", "oe"],
        &["--structure", "narx", "--na", "2", "--nb", "2"],
        &["--structure", "arx", "--method", "ls"],
    ];
    let mut said_somewhere = [false, false];
    for (k, record) in [&gas[..], &dryer[..]].into_iter().enumerate() {
        for class in classes {
            let mut args = vec!["identify"];
            args.extend(record);
            args.extend(class);
            let doc = run_json(&dir, &args);
            let (est, val) = (
                held_fit(&doc["metrics"]["estimation"]).unwrap(),
                held_fit(&doc["metrics"]["validation"]).unwrap(),
            );
            let expected = est > 0.0 && est - val > 15.0;
            assert_eq!(drop_said(&doc), expected, "{args:?}: {est} → {val}");
            said_somewhere[k] |= expected;
        }
    }
    // The records do what this test is about: the gas furnace drops, the hair dryer does not.
    assert_eq!(said_somewhere, [true, false]);
}

// Audit s21 M-A1 and L-A1 on `order`: the gas furnace chosen on its selection part (94.8 %) falls on
// the test half; the drop is said, and `test.fit_sim_percent` is the text's headline (the worse of
// both initial states, as ranked), the estimated-initial-output fit under its own name.
#[test]
fn order_says_when_the_test_fit_falls_far_below_the_selection_fit() {
    let Some(dir) = data_dir() else { return };
    let doc = order(
        &dir,
        &[
            "--data",
            "gas_furnace_box_jenkins/gas_furnace.csv",
            "--u-col",
            "InputGasRate",
            "--y-col",
            "CO2",
            "--ts",
            "9",
            "--offset",
            "--split",
            "0.5",
        ],
    );
    let t = &doc["test"];
    let m = &t["metrics"];
    assert_eq!(t["fit_sim_percent"].as_f64(), guarded(m), "{t}");
    assert_eq!(t["fit_sim_estimated_percent"], m["fit_sim_percent"], "{t}");
    let chosen = doc["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["orders"] == t["orders"])
        .unwrap();
    let sel = chosen["ranking_fit"].as_f64().unwrap();
    let test = guarded(m).unwrap();
    assert!(
        sel - test > 15.0,
        "the record no longer shows the drop: {sel} → {test}"
    );
    assert!(
        warnings(&doc)
            .iter()
            .any(|w| w.starts_with("test record: the simulation fit falls from")),
        "{:?}",
        warnings(&doc)
    );
}

// Audit s21 M-A2 and M-A1 on `validate`: a model saved from the gas furnace's rows 0..148, validated on
// those rows (in-sample, said), on rows 100..200 (148 − 100 = 48 of 100 rows in-sample) and on rows
// 148..296 (held out: no in-sample word; the fall from the file's estimation fit said when the record's
// worse fit is more than 15 points below it).
#[test]
fn validate_says_when_it_is_given_the_estimation_rows() {
    let Some(dir) = data_dir() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("gas.json");
    let gas = "gas_furnace_box_jenkins/gas_furnace.csv";
    let mut args = vec![
        "identify",
        "--data",
        gas,
        "--u-col",
        "InputGasRate",
        "--y-col",
        "CO2",
        "--ts",
        "9",
        "--offset",
        "--rows",
        "0..148",
        "--na",
        "2",
        "--nb",
        "2",
        "--nk",
        "3",
        "--save-model",
    ];
    args.push(model.to_str().unwrap());
    run_json(&dir, &args);
    let file: Value = serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let est_fit = file["model"]["identification"]["fit_estimation_percent"]
        .as_f64()
        .unwrap();
    let validate = |rows: &str| {
        run_json(
            &dir,
            &[
                "validate",
                "--model",
                model.to_str().unwrap(),
                "--data",
                gas,
                "--rows",
                rows,
            ],
        )
    };
    let in_sample = |doc: &Value, words: &str| warnings(doc).iter().any(|w| w.starts_with(words));
    let same = validate("0..148");
    assert!(
        in_sample(&same, "this is the data the model was estimated on"),
        "{same}"
    );
    let part = validate("100..200");
    assert!(in_sample(&part, "48 of the 100 rows of"), "{part}");
    let held = validate("148..296");
    assert!(!in_sample(&held, "this is the data") && !in_sample(&held, "148 of"));
    let val = guarded(&held["metrics"]["validation"]).unwrap();
    assert_eq!(drop_said(&held), est_fit - val > 15.0, "{est_fit} → {val}");
    assert!(
        drop_said(&held),
        "the record no longer shows the drop: {est_fit} → {val}"
    );
}

// Audit s21 L-B3: a validation fit of 0.04 % (the pneumatic cylinder at 1 bar, ARX by least squares)
// is hardly better than the mean: warned below 5 %, as the JSON's own worse fit says.
#[test]
fn a_validation_fit_below_five_percent_is_warned() {
    let Some(dir) = data_dir() else { return };
    let doc = run_json(
        &dir,
        &[
            "identify",
            "--data",
            "pneumatic_cylinder_friction_tudelft/NAPN_1bar.csv",
            "--no-header",
            "--t-col",
            "1",
            "--u-col",
            "6",
            "--y-col",
            "5",
            "--time-unit",
            "ms",
            "--resample",
            "0.01",
            "--structure",
            "arx",
            "--method",
            "ls",
            "--split",
            "0.5",
        ],
    );
    let val = guarded(&doc["metrics"]["validation"]).unwrap();
    let said = warnings(&doc)
        .iter()
        .any(|w| w.contains("on the validation data") && w.contains("hardly better than"));
    assert_eq!(
        said,
        (0.0..5.0).contains(&val),
        "{val}: {:?}",
        warnings(&doc)
    );
    assert!(said, "the record no longer shows a fit below 5 %: {val}");
}

// Audit s34 H-1: output error on records of the paper's model with small commands from a start that is
// not rest (simulate's y0 = 100 mm, decaying) stopped in a local minimum from the LS start (a1 ≈ −1.0
// to −1.2 against the paper's −1.869, "converged", at times no warning). Now the search also starts from
// IV: every run either recovers a1 within 0.1 of the paper's value or warns of the local minima, and a
// warned run kept the lower end (its simulation RSS, re-computed here from the JSON's own RMSE, is the
// IV start's, below the LS start's as the warning quotes them). Truth: the paper's a1 = −1.869
// (docs/paper.md, Table III), not a figure of this program.
#[test]
fn output_error_on_small_commands_recovers_the_paper_model_or_warns() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut recovered = 0;
    for (amplitude, seed) in [("8", "1"), ("8", "2"), ("20", "1"), ("20", "2")] {
        let out = bin()
            .current_dir(d)
            .args([
                "simulate",
                "--plant",
                "paper",
                "--input",
                "staircase",
                "--amplitude",
            ])
            .args([
                amplitude,
                "--noise-std",
                "0.01",
                "--seed",
                seed,
                "--out",
                "r.csv",
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let doc = run_json(d, &["identify", "--data", "r.csv", "--method", "oe"]);
        let a1 = doc["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == "a1")
            .and_then(|p| p["value"].as_f64())
            .unwrap();
        let words = warnings(&doc);
        let local = words.iter().find(|w| w.contains("several local minima"));
        let what = format!("amplitude {amplitude}, seed {seed}: a1 = {a1}, warnings {words:?}");
        if (a1 + 1.869).abs() < 0.1 {
            recovered += 1;
        } else {
            assert!(local.is_some(), "wrong without a word: {what}");
        }
        if let Some(w) = local {
            // "… stopped in one (simulation RSS A), the search from the IV start went lower (B) …"
            let num = |after: &str| -> f64 {
                let rest = &w[w.find(after).unwrap() + after.len()..];
                rest[..rest.find(')').unwrap()].parse().unwrap()
            };
            let (rss_ls, rss_iv) = (num("(simulation RSS "), num("went lower ("));
            assert!(rss_iv < rss_ls * 0.99, "{what}");
            // The kept model's own simulation RSS (estimated initial outputs) is the IV end's.
            let est = &doc["metrics"]["estimation"];
            let rmse = est["rmse_sim"].as_f64().unwrap();
            let rows = 2000.0;
            let rss = rmse * rmse * rows;
            assert!(
                (rss - rss_iv).abs() <= 0.02 * rss_iv,
                "{what}: kept RSS {rss} is not the IV end's {rss_iv}"
            );
        }
    }
    // Before the second start, 1 of these 4 was recovered (amplitude 20, seed 2).
    assert!(recovered >= 3, "only {recovered} of 4 recovered");
}

// Audit s34 M-2: least squares on a record of the paper's model with 0.05 mm of white output noise is
// biased (a1 ≈ −1.64 against the paper's −1.869, many of its own ± away) and said nothing. Now the
// warning names output noise, quoting the lag-1 correlation of the estimation residuals, which is
// computed here from `validate --out`'s one-step residuals (k ≥ k0 = 3, mean removed); output error
// on the same record, not biased by it, gets no such warning.
#[test]
fn least_squares_under_output_noise_is_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |args: &[&str]| {
        let out = bin().current_dir(d).args(args).output().unwrap();
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    run(&[
        "simulate",
        "--plant",
        "paper",
        "--noise-std",
        "0.05",
        "--seed",
        "7",
        "--out",
        "n.csv",
    ]);
    let ls = run_json(
        d,
        &[
            "identify",
            "--data",
            "n.csv",
            "--method",
            "ls",
            "--save-model",
            "ls.json",
        ],
    );
    let a1 = ls["model"]["a"][0].as_f64().unwrap();
    assert!(
        (a1 + 1.869).abs() > 0.1,
        "a1 = {a1}: the record no longer biases ls"
    );
    let words = warnings(&ls);
    let w = words
        .iter()
        .find(|w| w.contains("negatively correlated at lag 1"))
        .unwrap_or_else(|| panic!("no output-noise warning: {words:?}"));
    assert!(w.contains("--method oe") && w.contains("biased"), "{w}");
    let quoted: f64 = {
        let rest = &w[w.find("(r = ").unwrap() + 5..];
        rest[..rest.find(')').unwrap()].parse().unwrap()
    };
    run(&[
        "validate", "--model", "ls.json", "--data", "n.csv", "--out", "v.csv",
    ]);
    let text = std::fs::read_to_string(d.join("v.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "residual").unwrap();
    let e: Vec<f64> = lines
        .skip(3)
        .map(|l| l.split(',').nth(col).unwrap().parse().unwrap())
        .collect();
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    let c = |lag: usize| -> f64 {
        e.iter()
            .skip(lag)
            .zip(&e)
            .map(|(a, b)| (a - mean) * (b - mean))
            .sum()
    };
    let r1 = c(1) / c(0);
    assert!(r1 < -0.3, "r1 = {r1}");
    assert!((r1 - quoted).abs() < 1e-3, "quoted {quoted}, computed {r1}");
    let oe = run_json(d, &["identify", "--data", "n.csv", "--method", "oe"]);
    assert!(
        !warnings(&oe)
            .iter()
            .any(|w| w.contains("negatively correlated at lag 1")),
        "{:?}",
        warnings(&oe)
    );
}
