//! Audit s21 through the binary: `response` says in words when the linear block is unstable or an
//! integrator (H-A1, M-B4), refuses coefficients beyond f64 naming the field (M-B3), repeats the model
//! file's doubts (M-B4) and calls a dropped deadzone branch "not identified" (L-A2). Expectations are
//! computed here from the model's coefficients, never copied from output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};

mod common;
use common::{run as ipa_sysid, s, stderr};

/// A version-2 ARX model file with these A and B coefficients, nk = 1, Ts = 0.1 s.
fn arx_file(dir: &Path, name: &str, a: &[f64], b: &[f64]) -> PathBuf {
    let path = dir.join(name);
    let model = serde_json::json!({
        "kind": "arx", "ts": 0.1, "na": a.len(), "nb": b.len(), "nk": 1,
        "a": a, "b": b, "offset": null, "noise_model": "equation-error"
    });
    let doc = serde_json::json!({"format": "ipa-sysid-model", "version": 2, "model": model});
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

/// `response --model FILE --json -`: (the JSON, the text on stderr).
fn response_json(model: &Path) -> (serde_json::Value, String) {
    let o = ipa_sysid(&["response", "--model", s(model), "--json", "-"]);
    assert!(o.status.success(), "{}", stderr(&o));
    (serde_json::from_slice(&o.stdout).unwrap(), stderr(&o))
}

fn strings(v: &serde_json::Value) -> Vec<String> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_str().unwrap().to_string())
        .collect()
}

// y(k) = y(k−1) + u(k−1): A = 1 − q⁻¹, pole z = 1, G(1) = 1/0: no finite DC gain.
#[test]
fn an_integrator_has_an_infinite_dc_gain_in_text_and_json() {
    let dir = tempfile::tempdir().unwrap();
    let m = arx_file(dir.path(), "int.json", &[-1.0], &[1.0]);
    let (j, text) = response_json(&m);
    assert!(j["dc_gain"].is_null());
    assert_eq!(j["dc_gain_note"], "infinite (integrator)");
    assert!(
        text.contains("DC gain:  G(1) = infinite (integrator)"),
        "{text}"
    );
    let w = strings(&j["warnings"]);
    assert!(w.iter().any(|w| w.contains("integrator")), "{w:?}");
    // Every JSON warning is a `warning:` line of the text.
    for w in &w {
        assert!(text.contains(&format!("warning: {w}")), "{w}");
    }
}

// y(k) = 1.5 y(k−1) + u(k−1): Σb/(1+Σa) = 1/(1 − 1.5) = −2, a wrong-signed "gain" of a diverging step.
#[test]
fn an_unstable_block_has_no_dc_gain_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let m = arx_file(dir.path(), "unstable.json", &[-1.5], &[1.0]);
    let (j, text) = response_json(&m);
    assert!(j["dc_gain"].is_null());
    assert_eq!(j["dc_gain_note"], "not defined (unstable)");
    assert!(!text.contains("-2\n") && text.contains("G(1) = not defined (unstable)"));
    assert!(strings(&j["warnings"])[0].starts_with("unstable model: a pole has modulus 1.500000"));
}

// y(k) = 0.5 y(k−1) + u(k−1): G(1) = 1/(1 − 0.5) = 2, settled within 2 % after 20 samples (0.5^19).
#[test]
fn a_stable_block_keeps_its_dc_gain_and_has_no_warning() {
    let dir = tempfile::tempdir().unwrap();
    let m = arx_file(dir.path(), "stable.json", &[-0.5], &[1.0]);
    let (j, text) = response_json(&m);
    assert_eq!(j["dc_gain"].as_f64().unwrap(), 1.0 / (1.0 - 0.5));
    assert!(j["dc_gain_note"].is_null());
    assert!(strings(&j["warnings"]).is_empty());
    assert!(!text.contains("warning:"), "{text}");
}

// a = [1e308, 1e308]: Σ|a_i| overflows and the poles are NaN; an error naming "a", exit code 1.
#[test]
fn coefficients_beyond_f64_are_refused_naming_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let m = arx_file(dir.path(), "huge.json", &[1e308, 1e308], &[1.0]);
    let o = ipa_sysid(&["response", "--model", s(&m)]);
    assert_eq!(o.status.code(), Some(1));
    assert!(stderr(&o).contains("\"a\" coefficients"), "{}", stderr(&o));
}

// identify's model of a one-sided input: m_l = b_l = 0 fixed. Its left side is "not identified",
// not a measured 0 / −inf dB; the file's shape doubt is repeated; no deadzone words for an ARX loop.
#[test]
fn a_dropped_deadzone_branch_is_not_identified() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ham.json");
    let model = serde_json::json!({
        "kind": "hammerstein", "ts": 0.1, "na": 1, "nb": 1, "nk": 1, "a": [-0.5], "b": [1.0],
        "offset": null, "noise_model": "output-error",
        "deadzone": {"b_l": 0.0, "b_r": 0.0, "m_l": 0.0, "m_r": 0.05}
    });
    let doc = serde_json::json!({"format": "ipa-sysid-model", "version": 2, "model": model});
    std::fs::write(&path, doc.to_string()).unwrap();
    let (j, text) = response_json(&path);
    let left = &j["sides"][1];
    assert_eq!(left["side"], "left");
    assert_eq!(left["identified"], false);
    assert!(left["dc_gain"].is_null() && left["offset_db"].is_null());
    // Right: m_r G(1) = 0.05 · 1/(1 − 0.5) = 0.1.
    assert!((j["sides"][0]["dc_gain"].as_f64().unwrap() - 0.1).abs() < 1e-12);
    assert!(
        text.contains("left: not identified") && !text.contains("-inf"),
        "{text}"
    );
    assert!(
        text.contains("warning: model: non-physical deadzone"),
        "{text}"
    );
    let arx = arx_file(dir.path(), "arx.json", &[-0.5], &[1.0]);
    let o = ipa_sysid(&["response", "--model", s(&arx), "--kp", "1"]);
    assert!(!String::from_utf8_lossy(&o.stdout).contains("deadzone"));
}

/// A version-3 model file (y(k) = 0.5 y(k−1) + u(k−1)) whose identification record holds `record` and
/// `warnings`.
fn provenance_file(dir: &Path, name: &str, record: &str, warnings: &[String]) -> PathBuf {
    let path = dir.join(name);
    let model = serde_json::json!({
        "kind": "arx", "ts": 0.1, "na": 1, "nb": 1, "nk": 1, "a": [-0.5], "b": [1.0],
        "offset": null, "noise_model": "equation-error",
        "identification": {"record": record, "fit_estimation_percent": 90.0, "warnings": warnings}
    });
    let doc = serde_json::json!({"format": "ipa-sysid-model", "version": 3, "model": model});
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

// M-B1: ESC (clear screen, colour, OSC window title), BEL, CR, NUL and BS from the file reach the
// terminal as visible escapes, in simulate's and response's warning lines and response's JSON.
#[test]
fn control_characters_of_a_model_file_are_printed_as_escapes() {
    let dir = tempfile::tempdir().unwrap();
    let hostile = "\u{1b}[2J\u{1b}[31mRED\u{1b}]0;pwned\u{7}\r\0\u{8}do not use";
    let m = provenance_file(
        dir.path(),
        "esc.json",
        "rec\u{1b}[8m.csv",
        &[hostile.to_string()],
    );
    let out = dir.path().join("s.csv");
    let o = ipa_sysid(&[
        "simulate",
        "--plant",
        &format!("model:{}", s(&m)),
        "--samples",
        "10",
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let shown = "\\u{1b}[2J\\u{1b}[31mRED\\u{1b}]0;pwned\\u{7}\\r\\u{0}\\u{8}do not use";
    assert!(
        err.contains(shown) && err.contains("rec\\u{1b}[8m.csv"),
        "{err}"
    );
    for c in ['\u{1b}', '\u{7}', '\r', '\0', '\u{8}'] {
        assert!(!err.contains(c), "{c:?} reached the terminal");
    }
    let (j, text) = response_json(&m);
    assert!(text.contains(shown) && !text.contains('\u{1b}'));
    assert!(strings(&j["warnings"]).iter().any(|w| w.ends_with(shown)));
}

// M-B2: 101 warnings (one more than identify could write) or a 4097-character record name: the file
// is refused, naming the field, its size and the limit.
#[test]
fn oversized_identification_fields_are_refused_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let many: Vec<String> = (0..101).map(|i| format!("warning {i}")).collect();
    let m = provenance_file(dir.path(), "many.json", "rec.csv", &many);
    let o = ipa_sysid(&["response", "--model", s(&m)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("identification.warnings has 101 items, at most 100"),
        "{}",
        stderr(&o)
    );
    let m = provenance_file(dir.path(), "rec.json", &"r".repeat(4097), &[]);
    let o = ipa_sysid(&["response", "--model", s(&m)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("identification.record has 4097 characters, at most 4096"));
    // At the limits the file loads.
    let m = provenance_file(dir.path(), "ok.json", &"r".repeat(4096), &many[..100]);
    assert!(ipa_sysid(&["response", "--model", s(&m)]).status.success());
}

// L-B2 / L-B1: a model file's Ts below 1e-6 s (the controller's floor) is refused naming ts — not
// blamed on --f-min — and identify does not save a file that would not load again.
#[test]
fn a_model_file_ts_below_one_microsecond_is_refused_naming_ts() {
    let dir = tempfile::tempdir().unwrap();
    let m = arx_file(dir.path(), "ts.json", &[-0.5], &[1.0]);
    let text = std::fs::read_to_string(&m)
        .unwrap()
        .replace("\"ts\":0.1", "\"ts\":1e-320");
    std::fs::write(&m, text).unwrap();
    let o = ipa_sysid(&["response", "--model", s(&m)]);
    assert_eq!(o.status.code(), Some(2));
    let err = stderr(&o);
    assert!(
        err.contains("ts = 1e-320 s is below 1e-6 s") && !err.contains("--f-min"),
        "{err}"
    );
    // identify --ts 1e-7 --save-model: refused at the argument since session 22 (before: at the
    // save), nothing written.
    let csv = dir.path().join("d.csv");
    let rows: String = (0..200)
        .map(|k| format!("{},{}\n", (k % 7) as f64, ((k * 3) % 11) as f64))
        .collect();
    std::fs::write(&csv, format!("u,y\n{rows}")).unwrap();
    let saved = dir.path().join("m.json");
    let o = ipa_sysid(&[
        "identify",
        "--data",
        s(&csv),
        "--ts",
        "1e-7",
        "--structure",
        "arx",
        "--method",
        "ls",
        "--save-model",
        s(&saved),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o)
            .contains("invalid setting --ts = 1e-7: a finite sampling period of at least 1e-6 s"),
        "{}",
        stderr(&o)
    );
    assert!(!saved.exists());
}
