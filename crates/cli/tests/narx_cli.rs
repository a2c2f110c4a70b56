//! Polynomial NARX end to end: `identify --structure narx`, the model file, `validate`, `simulate
//! --plant model:FILE`, and the blow-up warning.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::Path;

mod common;
use common::{bin, json};

/// y(k) = 0.2 y(k−1) + 0.1 y(k−1) u(k−1) + 0.9 u(k−2) (SysIdentPy's example system), noise free.
fn write_record(path: &Path, n: usize, seed: u64) {
    write_scaled_record(path, n, seed, 1.0);
}

/// [`write_record`] with the input multiplied by `scale`; returns u's [min, max].
fn write_scaled_record(path: &Path, n: usize, seed: u64, scale: f64) -> (f64, f64) {
    let u: Vec<f64> = ipa_testdata::white(n, seed)
        .iter()
        .map(|v| v * scale)
        .collect();
    let mut y = vec![0.0; n];
    for k in 2..n {
        y[k] = 0.2 * y[k - 1] + 0.1 * y[k - 1] * u[k - 1] + 0.9 * u[k - 2];
    }
    let mut text = String::from("t,u,y\n");
    for k in 0..n {
        text.push_str(&format!("{},{},{}\n", k as f64, u[k], y[k]));
    }
    std::fs::write(path, text).unwrap();
    u.iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        })
}

// A validation record whose input spans twice the estimation data's is said to be extrapolated, in
// the text and the JSON, as for every other class (audit s28 L-1: NARX said nothing); one within the
// estimation range gets no such warning.
#[test]
fn a_narx_validation_record_beyond_the_estimation_input_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (lo, hi) = write_scaled_record(&d.join("est.csv"), 600, 1, 1.0);
    let (vlo, vhi) = write_scaled_record(&d.join("wide.csv"), 400, 2, 2.0);
    write_scaled_record(&d.join("narrow.csv"), 400, 3, 0.5);
    let run = |val: &str| {
        let o = bin()
            .current_dir(d)
            .args(["identify", "--data", "est.csv", "--validation", val])
            .args(["--structure", "narx", "--degree", "2", "--na", "2"])
            .args(["--nb", "2", "--nk", "1", "--json", "fit.json"])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let words: Vec<String> = json(&d.join("fit.json"))["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|w| w.as_str().unwrap().to_string())
            .collect();
        (String::from_utf8_lossy(&o.stdout).to_string(), words)
    };
    let (text, words) = run("wide.csv");
    let want = format!(
        "validation: the record's input u spans [{vlo}, {vhi}] but the model's estimation data had \
         it in [{lo}, {hi}]: outside it the model extrapolates"
    );
    assert!(
        words.iter().any(|w| w.starts_with(&want)),
        "{want}\n{words:?}"
    );
    assert!(text.contains(&want), "{text}");
    let (_, words) = run("narrow.csv");
    assert!(
        !words.iter().any(|w| w.contains("extrapolates")),
        "{words:?}"
    );
}

// The known system's three terms and coefficients come back, the model file validates on a fresh record
// with a simulation error at rounding level, and the plant run matches the recursion by hand.
#[test]
fn narx_identifies_saves_validates_and_runs_as_a_plant() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_record(&d.join("est.csv"), 600, 1);
    write_record(&d.join("val.csv"), 400, 2);
    let o = bin()
        .current_dir(d)
        .args([
            "identify",
            "--data",
            "est.csv",
            "--validation",
            "val.csv",
            "--structure",
            "narx",
        ])
        .args([
            "--degree", "2", "--na", "2", "--nb", "2", "--nk", "1", "--offset",
        ])
        .args(["--json", "fit.json", "--save-model", "m.json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("Polynomial NARX"), "{text}");
    let j = json(&d.join("fit.json"));
    let terms = j["terms"].as_array().unwrap();
    let want = [("y(k-1)", 0.2), ("y(k-1)*u(k-1)", 0.1), ("u(k-2)", 0.9)];
    assert_eq!(terms.len(), 3, "{terms:?}");
    for (t, c) in want {
        let got = terms.iter().find(|x| x["term"] == t).unwrap();
        assert!(
            (got["coefficient"].as_f64().unwrap() - c).abs() < 1e-8,
            "{got}"
        );
        assert!(got["std"].is_number() || got["std"].is_null());
    }
    assert!(j["metrics"]["validation"]["rmse_sim"].as_f64().unwrap() < 1e-8);
    assert_eq!(
        j["warnings"].as_array().unwrap().len(),
        0,
        "{}",
        j["warnings"]
    );
    // validate the saved model on the fresh record.
    let o = bin()
        .current_dir(d)
        .args([
            "validate", "--model", "m.json", "--data", "val.csv", "--json", "v.json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v = json(&d.join("v.json"));
    assert!(
        v["metrics"]["validation"]["rmse_sim"].as_f64().unwrap() < 1e-8,
        "{v}"
    );
    // The model as a plant: y(0) = 0 at rest, y(k+1) = 0.2 y(k) + 0.1 y(k) u(k) + 0.9 u(k−1).
    let u: Vec<f64> = (0..50).map(|k| 0.5 * ((k as f64) * 0.3).sin()).collect();
    let mut input = String::from("u\n");
    for x in &u {
        input.push_str(&format!("{x}\n"));
    }
    std::fs::write(d.join("u.csv"), input).unwrap();
    let o = bin()
        .current_dir(d)
        .args([
            "simulate",
            "--plant",
            "model:m.json",
            "--input",
            "file:u.csv",
            "--y0",
            "0",
        ])
        .args(["--out", "sim.csv"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let sim = sysid::data::read_csv(&d.join("sim.csv"), &Default::default()).unwrap();
    let mut y = 0.0;
    let mut u_prev = 0.0;
    assert_eq!(sim.y().len(), u.len());
    for (k, (&uk, &yk)) in u.iter().zip(sim.y()).enumerate() {
        assert!((yk - y).abs() < 1e-8, "k = {k}: {yk} vs {y}");
        let next = 0.2 * y + 0.1 * y * uk + 0.9 * u_prev;
        u_prev = uk;
        y = next;
    }
}

// y(k) = y(k−1)² escapes from y(0) = 2: validate says so in words and in the JSON, with no RMSE.
#[test]
fn a_narx_simulation_that_blows_up_is_announced() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(
        d.join("m.json"),
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "narx", "ts": 1.0, "na": 1,
           "nb": 1, "nk": 1, "degree": 2, "terms": [{"term": "y(k-1)^2", "coefficient": 1.0}]}}"#,
    )
    .unwrap();
    let mut text = String::from("t,u,y\n");
    for k in 0..20 {
        text.push_str(&format!("{k},0,{}\n", if k == 0 { 2.0 } else { 1.0 }));
    }
    std::fs::write(d.join("rec.csv"), text).unwrap();
    let o = bin()
        .current_dir(d)
        .args([
            "validate", "--model", "m.json", "--data", "rec.csv", "--json", "v.json",
        ])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("blew up"), "{out}");
    let v = json(&d.join("v.json"));
    assert!(v["metrics"]["validation"]["rmse_sim"].is_null());
    assert!(v["warnings"][0].as_str().unwrap().contains("blew up"));
    // --strict turns the warning into exit code 1.
    let o = bin()
        .current_dir(d)
        .args([
            "validate", "--model", "m.json", "--data", "rec.csv", "--strict",
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
}

// The class search on data of a known degree-2 NARX ranks the NARX class first (its selection RMSE is at
// rounding level, an ARX model's cannot be), re-estimates it and simulates the test record exactly.
#[test]
fn the_class_search_finds_the_narx_class_of_narx_data() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_record(&d.join("est.csv"), 600, 3);
    write_record(&d.join("val.csv"), 300, 4);
    let o = bin()
        .current_dir(d)
        .args([
            "order",
            "--data",
            "est.csv",
            "--validation",
            "val.csv",
            "--offset",
        ])
        .args([
            "--classes",
            "arx,narx2",
            "--na",
            "2",
            "--nb",
            "2",
            "--nk",
            "1",
        ])
        .args(["--json", "o.json"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j = json(&d.join("o.json"));
    assert_eq!(j["candidates"].as_array().unwrap().len(), 2);
    assert_eq!(j["candidates"][0]["class"], "narx2");
    assert_eq!(j["candidates"][1]["class"], "arx");
    assert!(j["candidates"][0]["selection_rmse"].as_f64().unwrap() < 1e-8);
    assert!(j["candidates"][1]["selection_rmse"].as_f64().unwrap() > 1e-3);
    assert_eq!(j["chosen"]["class"], "narx2");
    assert!(j["chosen"]["rmse_sim"].as_f64().unwrap() < 1e-8);
}
