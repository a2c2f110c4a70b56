//! `identify --nonlinearity KIND` with the kinds beyond the deadzone, through the binary: the words,
//! `--breakpoints`/`--degree`, several inputs, and the model file read back by `validate`.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;

mod common;
use common::{run, s};

/// Noise-free y(k) = 0.6 y(k−1) + f1(u1(k−1)) − 0.8 u2(k−1), f1 = 2 clamp(u1, −0.5, 0.6) (saturation)
/// or f1 = piecewise-linear with one breakpoint at 0.2 (slopes 1, 3); written with columns t,u1,u2,y.
fn record(path: &Path, f1: fn(f64) -> f64) {
    let n = 600;
    let (u1, u2) = (ipa_testdata::white(n, 3), ipa_testdata::white(n, 5));
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.6 * y[k - 1] + f1(u1[k - 1]) - 0.8 * u2[k - 1];
    }
    write_record(path, &u1, &u2, &y);
}

/// Writes t,u1,u2,y at Ts = 0.1 s.
fn write_record(path: &Path, u1: &[f64], u2: &[f64], y: &[f64]) {
    let mut text = String::from("t,u1,u2,y\n");
    for k in 0..y.len() {
        text.push_str(&format!(
            "{},{},{},{}\n",
            k as f64 * 0.1,
            u1[k],
            u2[k],
            y[k]
        ));
    }
    std::fs::write(path, text).unwrap();
}

fn params(doc: &serde_json::Value) -> Vec<(String, f64)> {
    doc["parameters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            (
                p["name"].as_str().unwrap().to_string(),
                p["value"].as_f64().unwrap(),
            )
        })
        .collect()
}

#[test]
fn saturation_and_piecewise_inputs_through_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let sat = dir.path().join("sat.csv");
    let range = {
        let u = ipa_testdata::white(600, 3);
        (
            u.iter().cloned().fold(f64::MAX, f64::min),
            u.iter().cloned().fold(f64::MIN, f64::max),
        )
    };
    assert!(
        range.0 < -0.5 && range.1 > 0.6,
        "the record must saturate on both sides: {range:?}"
    );
    record(&sat, |u| 2.0 * u.clamp(-0.5, 0.6));
    let out = dir.path().join("sat.json");
    let model = dir.path().join("sat.model.json");
    let o = run(&[
        "identify",
        "--data",
        s(&sat),
        "--u-col",
        "u1,u2",
        "--na",
        "1",
        "--method",
        "ls",
        "--nonlinearity",
        "u1=saturation,u2=linear",
        "--json",
        s(&out),
        "--save-model",
        s(&model),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let want = [
        ("s_l", -0.5),
        ("s_r", 0.6),
        ("m", 2.0),
        ("a1", -0.6),
        ("b1", 1.0),
        ("b1", -0.8),
    ];
    let got = params(&doc);
    for ((name, value), (wn, wv)) in got.iter().zip(want) {
        assert_eq!(name, wn);
        assert!((value - wv).abs() < 1e-8, "{got:?}");
    }
    assert_eq!(
        doc["model"]["inputs"][0]["nonlinearity"]["kind"],
        "saturation"
    );
    let o = run(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&sat),
        "--u-col",
        "u1,u2",
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && text.contains("fit 100.00 %"),
        "{text}"
    );

    let pwl = dir.path().join("pwl.csv");
    record(&pwl, |u| if u < 0.2 { u } else { 0.2 + 3.0 * (u - 0.2) });
    let out = dir.path().join("pwl.json");
    let o = run(&[
        "identify",
        "--data",
        s(&pwl),
        "--u-col",
        "u1,u2",
        "--na",
        "1",
        "--method",
        "ls",
        "--nonlinearity",
        "u1=piecewise-linear,u2=linear",
        "--breakpoints",
        "1",
        "--json",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let got = params(&doc);
    let want = [("p1", 0.2), ("s0", 1.0), ("s1", 3.0), ("a1", -0.6)];
    for ((name, value), (wn, wv)) in got.iter().zip(want) {
        assert_eq!(name, wn);
        assert!((value - wv).abs() < 1e-8, "{got:?}");
    }
}

#[test]
fn breakpoints_without_a_piecewise_input_and_out_of_range_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("sat.csv");
    record(&f, |u| u);
    for flags in [
        &["--nonlinearity", "saturation", "--breakpoints", "3"][..],
        &["--nonlinearity", "piecewise-linear", "--breakpoints", "9"][..],
        &["--nonlinearity", "piecewise-linear", "--breakpoints", "0"][..],
        &["--nonlinearity", "polynomial", "--degree", "0"][..],
        &["--nonlinearity", "sigmoid"][..],
    ] {
        let mut args = vec!["identify", "--data", s(&f), "--u-col", "u1"];
        args.extend_from_slice(flags);
        let o = run(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{flags:?}: {err}");
        let flag = if flags.len() > 2 {
            flags[2]
        } else {
            "saturation, deadzone-saturation"
        };
        assert!(err.contains(flag), "{flags:?}: {err}");
    }
}

// --output-nonlinearity: a Wiener record (y = clamp(v, −0.4, 0.5) of v(k) = 0.6 v(k−1) + u1(k−1) −
// 0.8 u2(k−1)) identified with the saturation on the output; the JSON and the model file carry it,
// `validate` and `simulate --plant model:FILE` run it.
#[test]
fn an_output_saturation_through_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let n = 600;
    let (u1, u2) = (ipa_testdata::white(n, 3), ipa_testdata::white(n, 5));
    let mut v = vec![0.0; n];
    for k in 1..n {
        v[k] = 0.6 * v[k - 1] + u1[k - 1] - 0.8 * u2[k - 1];
    }
    assert!(v.iter().any(|x| *x < -0.4) && v.iter().any(|x| *x > 0.5));
    let y: Vec<f64> = v.iter().map(|v| v.clamp(-0.4, 0.5)).collect();
    let data = dir.path().join("w.csv");
    write_record(&data, &u1, &u2, &y);
    let (out, model) = (dir.path().join("w.json"), dir.path().join("w.model.json"));
    let o = run(&[
        "identify",
        "--data",
        s(&data),
        "--u-col",
        "u1,u2",
        "--structure",
        "arx",
        "--na",
        "1",
        "--method",
        "ls",
        "--output-nonlinearity",
        "saturation",
        "--json",
        s(&out),
        "--save-model",
        s(&model),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let g = &doc["model"]["output_nonlinearity"];
    assert_eq!(g["kind"], "saturation");
    // Scale-free: m·s_l and m·s_r are the limits of y.
    let m = g["m"].as_f64().unwrap();
    assert!((m * g["s_l"].as_f64().unwrap() + 0.4).abs() < 1e-8, "{g}");
    assert!((m * g["s_r"].as_f64().unwrap() - 0.5).abs() < 1e-8, "{g}");
    assert_eq!(
        doc["warnings"].as_array().unwrap().len(),
        0,
        "{}",
        doc["warnings"]
    );
    let o = run(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--u-col",
        "u1,u2",
    ]);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && text.contains("fit 100.00 %"),
        "{text}"
    );
    let inputs = dir.path().join("in.csv");
    std::fs::write(
        &inputs,
        "u1,u2\n1,0\n1,0\n1,0\n1,0\n1,0\n1,0\n1,0\n1,0\n1,0\n1,0\n",
    )
    .unwrap();
    let sim = dir.path().join("sim.csv");
    let o = run(&[
        "simulate",
        "--plant",
        &format!("model:{}", s(&model)),
        "--input",
        &format!("file:{}", s(&inputs)),
        "--out",
        s(&sim),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // v → 1/(1 − 0.6) = 2.5 under u1 = 1: the output settles at the upper limit 0.5.
    let last = std::fs::read_to_string(&sim).unwrap();
    let y: f64 = last
        .lines()
        .last()
        .unwrap()
        .rsplit(',')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    assert!((y - 0.5).abs() < 1e-8, "{last}");
}
