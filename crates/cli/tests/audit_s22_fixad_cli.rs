//! Audit s22 (helper fixad) through the binary: `validate`'s in-sample rule compares columns and
//! samples, not file names (M-R2); `order` without a test record warns the chosen structure's fall
//! from its estimation fit to its selection fit (M-R1); `tune` and `control` say when the loop leaves
//! the model's data (M-B1); a controller tuned for another model is warned (M-B6); `response --json`
//! gives the controller as numbers (L-B7) and takes --strict (L-B11); `control --json` names its units
//! (L-B8); `tune --spec` refuses a vanishing u-max and subnormal tolerances (L-B2). Records and model
//! files are generated here; expectations are worked out by hand from them, never copied from the
//! program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};

mod common;
use common::{
    arx_signals, identify_arx, lcg, run as ipa_sysid, run_json_code, s, stderr, warnings, write_csv,
};

/// `dir/two.csv` with two experiments side by side: u,y from y(k) = 0.5 y(k−1) + u(k−1) and u2,y2
/// from y(k) = 0.8 y(k−1) + 0.3 u(k−1), each with its own random input in [−1, 1] (600 rows, Ts =
/// 0.1 s by --ts).
fn two_experiments(dir: &Path) -> PathBuf {
    let mut r1 = lcg(1);
    let mut r2 = lcg(2);
    let (u, y) = arx_signals(600, &[0.5], &[1.0], |_| 2.0 * r1.unit() - 1.0);
    let (u2, y2) = arx_signals(600, &[0.8], &[0.3], |_| 2.0 * r2.unit() - 1.0);
    let path = dir.join("two.csv");
    write_csv(&path, "u,y,u2,y2", None, &[&u, &y, &u2, &y2]);
    path
}

fn in_sample(w: &[String]) -> Vec<&String> {
    w.iter().filter(|w| w.contains("in-sample")).collect()
}

// M-R2: a model estimated on u,y of two.csv. Validated on u2,y2 of the same file (the other
// experiment): held out, no in-sample word. On u,y again: in-sample. On a copy of two.csv under
// another name, in the estimation columns: the same samples, in-sample.
#[test]
fn validate_judges_in_sample_by_columns_and_samples_not_names() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_experiments(dir.path());
    let model = dir.path().join("m.json");
    let mut args = common::identify_arx(&data, "1", "1", "ls");
    args.extend(["--ts", "0.1", "--save-model", s(&model)]);
    let o = ipa_sysid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let validate = |file: &Path, cols: &[&str]| {
        let mut a = vec!["validate", "--model", s(&model), "--data", s(file)];
        a.extend(cols);
        run_json_code(dir.path(), &a).1
    };
    let other = validate(&data, &["--u-col", "u2", "--y-col", "y2"]);
    assert!(in_sample(&warnings(&other)).is_empty(), "{other}");
    let same = validate(&data, &[]);
    let w = warnings(&same);
    assert!(
        in_sample(&w)
            .iter()
            .any(|w| w.starts_with("this is the data the model was estimated on")),
        "{w:?}"
    );
    let copy = dir.path().join("copy.csv");
    std::fs::copy(&data, &copy).unwrap();
    let copied = validate(&copy, &[]);
    let w = warnings(&copied);
    assert!(
        in_sample(&w)
            .iter()
            .any(|w| w.contains("holds the same samples as the estimation record")),
        "{w:?}"
    );
    // --strict: the copy's in-sample fit is a warning, so it exits 1.
    let o = ipa_sysid(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&copy),
        "--strict",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

// M-R2 on the measured record: the cascaded tanks' file holds the estimation (uEst, yEst) and the
// test (uVal, yVal) experiments; validating on the test columns is held out.
#[test]
fn the_cascaded_tanks_test_columns_are_held_out() {
    let Some(root) = ipa_testdata::shared_data() else {
        return;
    };
    let d = root.join("cascaded_tanks/dataBenchmark.csv");
    if !d.is_file() {
        eprintln!("SKIPPED: {} is absent", d.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("ct.json");
    let o = ipa_sysid(
        &[
            identify_arx(&d, "2", "2", "ls"),
            vec![
                "--u-col",
                "uEst",
                "--y-col",
                "yEst",
                "--ts",
                "4",
                "--offset",
                "--save-model",
                s(&model),
            ],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, doc) = run_json_code(
        dir.path(),
        &[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&d),
            "--u-col",
            "uVal",
            "--y-col",
            "yVal",
            "--ts",
            "4",
        ],
    );
    assert!(in_sample(&warnings(&doc)).is_empty(), "{doc}");
    let (_, doc) = run_json_code(
        dir.path(),
        &[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&d),
            "--ts",
            "4",
        ],
    );
    assert!(!in_sample(&warnings(&doc)).is_empty(), "{doc}");
}

/// Hand-derived fit % of the first-order model y(k) = a y(k−1) + b u(k−1) simulated on (u, y) from
/// the measured y(0): 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖).
fn fit_first_order(a: f64, b: f64, u: &[f64], y: &[f64]) -> f64 {
    let mut yh = vec![y[0]];
    for k in 1..y.len() {
        yh.push(a * yh[k - 1] + b * u[k - 1]);
    }
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let e: f64 = y.iter().zip(&yh).map(|(y, h)| (y - h).powi(2)).sum();
    let d: f64 = y.iter().map(|y| (y - mean).powi(2)).sum();
    100.0 * (1.0 - (e / d).sqrt())
}

// M-R1: 600 rows, y(k) = 0.5 y(k−1) + b u(k−1) with b = 1 for k < 400 and b = 0.6 after. order's
// default split estimates on rows 0..400 (exact: fit 100 %) and ranks on rows 400..600, where the
// model's gain is 1/0.6 times the plant's: the fit there is about 100 (1 − 0.67) ≈ 33 %, a fall of
// more than 15 points that identify would warn. Without a test record order must warn it too.
#[test]
fn order_without_a_test_record_warns_the_fall_to_the_selection_fit() {
    let dir = tempfile::tempdir().unwrap();
    let mut r = lcg(3);
    let n = 600;
    let u: Vec<f64> = (0..n).map(|_| 2.0 * r.unit() - 1.0).collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        let b = if k - 1 < 400 { 1.0 } else { 0.6 };
        y[k] = 0.5 * y[k - 1] + b * u[k - 1];
    }
    let sel = fit_first_order(0.5, 1.0, &u[400..], &y[400..]);
    assert!(sel < 85.0 - 1.0, "the hand-derived selection fit {sel}");
    let data = dir.path().join("g.csv");
    write_csv(&data, "u,y", None, &[&u, &y]);
    let args = [
        "order",
        "--data",
        s(&data),
        "--ts",
        "0.1",
        "--na",
        "1..2",
        "--nb",
        "1..2",
        "--nk",
        "1..1",
    ];
    let (code, doc) = run_json_code(dir.path(), &args);
    assert_eq!(code, 0, "{doc}");
    let w = warnings(&doc);
    assert!(
        w.iter().any(|w| w.contains("falls from")
            && w.contains("on the estimation data")
            && w.contains("on the selection data")),
        "{w:?}"
    );
    let mut strict = args.to_vec();
    strict.push("--strict");
    let o = ipa_sysid(&strict);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    // The same plant throughout (b = 1): no fall, no such warning.
    let (u1, y1) = arx_signals(n, &[0.5], &[1.0], |k| u[k]);
    write_csv(&data, "u,y", None, &[&u1, &y1]);
    let (_, doc) = run_json_code(dir.path(), &args);
    assert!(
        !warnings(&doc).iter().any(|w| w.contains("falls from")),
        "{doc}"
    );
}

/// A Hammerstein model file (the README's worked example's coefficients, Ts = 0.01 s) whose
/// estimation data had u in [−253, 251] counts and y in [0, 195.38] mm.
fn hammerstein_file(dir: &Path) -> PathBuf {
    let path = dir.join("model.json");
    let model = serde_json::json!({
        "kind": "hammerstein", "ts": 0.01, "na": 3, "nb": 1, "nk": 1,
        "a": [-0.7916759814724423, -0.7377846247551252, 0.5299710616130193], "b": [1.0],
        "offset": null,
        "deadzone": {"b_l": -48.0, "b_r": 37.6, "m_l": 0.01328, "m_r": 0.01365},
        "noise_model": "output-error",
        "data_range": {"u": [[-253.0, 251.0]], "y": [0.0, 195.38]}
    });
    let doc = serde_json::json!({"format": "ipa-sysid-model", "version": 3, "model": model});
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

fn extrapolates<'a>(w: &'a [String], what: &str) -> Vec<&'a String> {
    w.iter()
        .filter(|w| w.starts_with(&format!("the {what}")) && w.contains("extrapolates"))
        .collect()
}

// M-B1: a tenth of the data's span beyond it is the limit (u: 251 + 50.4 = 301.4; y: 195.38 + 19.5
// = 214.9). tune's default ±255 counts and set-points 25..175 mm stay inside; u-max = 1000 and
// set-points 300..600 leave it, and --strict then fails.
#[test]
fn tune_warns_commands_and_set_points_beyond_the_models_data() {
    let dir = tempfile::tempdir().unwrap();
    let model = hammerstein_file(dir.path());
    let quick = ["--max-evaluations", "8", "--variants", "1"];
    let t = common::tune(dir.path(), &model, &quick);
    let w = warnings(&t.report);
    assert!(extrapolates(&w, "commands").is_empty(), "{w:?}");
    assert!(extrapolates(&w, "set-points").is_empty(), "{w:?}");
    let mut args = quick.to_vec();
    args.extend(["--spec", "u-max=1000"]);
    let w = warnings(&common::tune(dir.path(), &model, &args).report);
    let c = extrapolates(&w, "commands");
    assert!(
        c.len() == 1
            && c[0].contains("[-1000.000000, 1000.000000]")
            && c[0].contains("[-253, 251]"),
        "{w:?}"
    );
    let mut args = quick.to_vec();
    args.extend(["--spec", "low=300,high=600,steps=100"]);
    let t = common::tune(dir.path(), &model, &args);
    let w = warnings(&t.report);
    let r = extrapolates(&w, "set-points");
    assert!(
        r.len() == 1
            && r[0].contains("[300.000000, 600.000000]")
            && r[0].contains("y in [0, 195.38]"),
        "{w:?}"
    );
    assert!(t.text.contains(r[0].as_str()), "{}", t.text);
    let mut strict = vec!["tune", "--model", s(&model), "--out"];
    let out = dir.path().join("strict.json");
    strict.extend([s(&out), "--strict"]);
    strict.extend(&args);
    let o = ipa_sysid(&strict);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

// M-B1: control's set-point against the model's output range, as its commands are.
#[test]
fn control_warns_a_set_point_beyond_the_models_data() {
    let dir = tempfile::tempdir().unwrap();
    let model = hammerstein_file(dir.path());
    let plant = format!("model:{}", s(&model));
    let run = |r: &str| {
        let args = [
            "control",
            "--plant",
            &plant,
            "--setpoint",
            r,
            "--duration",
            "2",
        ];
        run_json_code(dir.path(), &args).1
    };
    let w = warnings(&run("500"));
    let r = extrapolates(&w, "set-points");
    assert!(
        r.len() == 1
            && r[0].contains("[500.000000, 500.000000]")
            && r[0].contains("y in [0, 195.38]"),
        "{w:?}"
    );
    let w = warnings(&run("50"));
    assert!(extrapolates(&w, "set-points").is_empty(), "{w:?}");
}

/// A first-order ARX model file y(k) = 0.9 y(k−1) + 0.1 u(k−1), Ts = 0.01 s: linear, no deadzone.
fn arx_file(dir: &Path) -> PathBuf {
    let path = dir.join("arx.json");
    let model = serde_json::json!({
        "kind": "arx", "ts": 0.01, "na": 1, "nb": 1, "nk": 1,
        "a": [-0.9], "b": [0.1], "offset": null, "noise_model": "equation-error"
    });
    let doc = serde_json::json!({"format": "ipa-sysid-model", "version": 2, "model": model});
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

// M-B6, L-B7, L-B11, L-B8: a controller tuned on the Hammerstein model (its compensator inverts
// b_l = −48, b_r = 37.6) analysed and run on a linear ARX model is warned in response and control;
// on its own model it is not. response's JSON gives the controller as the file's numbers; response
// --strict exits 1 and writes no JSON; control's JSON names its units.
#[test]
fn a_controller_tuned_for_another_model_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let model = hammerstein_file(dir.path());
    let arx = arx_file(dir.path());
    let t = common::tune(
        dir.path(),
        &model,
        &["--max-evaluations", "8", "--variants", "1"],
    );
    let c = s(&t.controller);
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&t.controller).unwrap()).unwrap();
    let response = |m: &Path| {
        run_json_code(
            dir.path(),
            &["response", "--model", s(m), "--controller", c],
        )
        .1
    };
    let on_arx = response(&arx);
    let w = warnings(&on_arx);
    let other: Vec<&String> = w
        .iter()
        .filter(|w| w.starts_with("controller: the controller"))
        .collect();
    assert!(
        other.iter().any(|w| w.contains("inverts a deadzone")
            && w.contains("b_l = -48.0000")
            && w.contains("does not have")),
        "{w:?}"
    );
    assert!(
        other.iter().any(|w| w.contains("was tuned on the model")),
        "{w:?}"
    );
    // L-B7: the controller of the margins as the file's numbers.
    let j = &on_arx["controller"];
    assert_eq!(j["file"], c);
    for (k, f) in [
        ("kp", "kp"),
        ("ki", "ki"),
        ("kd", "kd"),
        ("tf_s", "derivative_filter_s"),
    ] {
        assert_eq!(j[k].as_f64(), file["controller"][f].as_f64(), "{k}");
    }
    let own = response(&model);
    assert!(
        !warnings(&own)
            .iter()
            .any(|w| w.contains("compensator inverts") || w.contains("was tuned on the model")),
        "{own}"
    );
    // L-B11: --strict with those warnings exits 1 and writes no JSON.
    let out = dir.path().join("r.json");
    let o = ipa_sysid(&[
        "response",
        "--model",
        s(&arx),
        "--controller",
        c,
        "--json",
        s(&out),
        "--strict",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!out.exists());
    // control on the ARX model: the same warnings, and the model plant's units named (L-B8).
    let plant = format!("model:{}", s(&arx));
    let (_, doc) = run_json_code(
        dir.path(),
        &[
            "control",
            "--plant",
            &plant,
            "--controller",
            c,
            "--setpoint",
            "0.5",
            "--duration",
            "1",
        ],
    );
    let w = warnings(&doc);
    assert!(w.iter().any(|w| w.contains("inverts a deadzone")), "{w:?}");
    assert_eq!(doc["units"]["y"], "(y's units)");
    let (_, doc) = run_json_code(
        dir.path(),
        &["control", "--setpoint", "50", "--duration", "1"],
    );
    assert_eq!(doc["units"]["y"], "mm");
    assert_eq!(doc["units"]["u"], "counts");
}

// L-B2: a command limit below 1e-6 and a subnormal tolerance are refused, naming the key and the
// number in exponent form.
#[test]
fn tune_refuses_a_vanishing_command_limit_and_subnormal_tolerances() {
    let dir = tempfile::tempdir().unwrap();
    let model = hammerstein_file(dir.path());
    for (spec, shown) in [
        ("u-max=1e-300", "u-max=1e-300"),
        ("ess=1e-320", "ess=1e-320"),
    ] {
        let out = dir.path().join("c.json");
        let o = ipa_sysid(&[
            "tune",
            "--model",
            s(&model),
            "--spec",
            spec,
            "--max-evaluations",
            "8",
            "--variants",
            "1",
            "--out",
            s(&out),
        ]);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert!(e.contains(shown) && e.contains("at least"), "{e}");
        assert!(!out.exists());
    }
}
