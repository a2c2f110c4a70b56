//! `montecarlo` through the binary: a small study on the paper's model, deterministic per seed.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;
use common::bin;

fn run(dir: &std::path::Path, name: &str, seed: &str) -> serde_json::Value {
    let json = dir.join(name);
    let out = bin()
        .args([
            "montecarlo",
            "--plant",
            "paper",
            "--noise-std",
            "0.01",
            "--runs",
            "3",
            "--method",
            "ls,oe",
            "--amplitude",
            "8",
            "--samples",
            "1500",
            "--seed",
            seed,
            "--json",
        ])
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap()
}

// Same seed → identical report; the truth column holds the paper's a1 = −1.869 and OE's mean a1 is within
// 0.05 of it at ±8 counts and 0.01 mm noise.
#[test]
fn montecarlo_on_the_paper_model_is_deterministic_and_reports_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let a = run(dir.path(), "a.json", "4");
    let b = run(dir.path(), "b.json", "4");
    assert_eq!(a, b);
    let methods = a["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 2);
    let oe = &methods[1];
    assert_eq!(oe["method"], "oe");
    assert_eq!(oe["ok_runs"], 3);
    let a1 = oe["params"]
        .as_array()
        .unwrap()
        .iter()
        .find(|p| p["name"] == "a1")
        .unwrap();
    assert_eq!(a1["truth"].as_f64(), Some(-1.869));
    assert!((a1["mean"].as_f64().unwrap() + 1.869).abs() < 0.05, "{a1}");
}

#[test]
fn an_unknown_method_is_refused() {
    let out = bin()
        .args(["montecarlo", "--runs", "1", "--method", "ls,magic"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("magic"));
}

// A model plant estimated on commands within [−1, 1] driven by the default ±255-count design: every run
// extrapolates, said in the text and the JSON (audit s16 L5); within its data (--amplitude 1) nothing
// is said of it.
#[test]
fn a_model_plant_driven_beyond_its_data_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json");
    std::fs::write(
        &model,
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "arx", "ts": 0.01,
        "na": 1, "nb": 1, "nk": 1, "a": [-0.5], "b": [0.1], "offset": null,
        "data_range": {"u": [[-1.0, 1.0]], "y": [-0.2, 0.2]}}}"#,
    )
    .unwrap();
    for (amplitude, warned) in [("255", true), ("1", false)] {
        let json = dir.path().join("mc.json");
        let out = bin()
            .args(["montecarlo", "--plant"])
            .arg(format!("model:{}", model.display()))
            .args([
                "--noise-std",
                "0.01",
                "--runs",
                "2",
                "--method",
                "ls",
                "--samples",
                "500",
                "--amplitude",
                amplitude,
                "--json",
            ])
            .arg(&json)
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&out.stdout).into_owned()
            + &String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{text}");
        let doc: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let in_json = doc["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("the model extrapolates"));
        assert_eq!(in_json, warned, "{amplitude}: {}", doc["warnings"]);
        assert_eq!(text.contains("the model extrapolates"), warned, "{text}");
    }
}
