//! Session 28, fixau (audit s27 M-2, L-7, L-8): the streamed reader says what the in-memory reader
//! says — the same reader notes (a time column in milliseconds, a `--ts` that contradicts the time
//! column, `--ts` over a column that is not uniform), the same in-sample warning for a validation file
//! that copies the estimation record, the same JSON keys, and so the same `--strict` verdict.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Output;

mod common;
use common::{arx_signals, bin, json, s, warnings, write_csv, write_mat};

fn out(args: &[&str]) -> Output {
    bin().args(args).output().unwrap()
}

fn ok(args: &[&str]) -> Output {
    let o = out(args);
    assert!(
        o.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

/// An ARX(2, 2) record of `n` samples whose input is a pseudo-random sequence: y(k) = 1.5 y(k−1) −
/// 0.7 y(k−2) + 0.5 u(k−1) + 0.2 u(k−2), plus a measurement noise of ±0.005 (so that the residual
/// tests are not decided by rounding).
fn signals(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut rng = common::lcg(7);
    let (u, y) = arx_signals(n, &[1.5, -0.7], &[0.5, 0.2], |_| rng.unit() - 0.5);
    let y = y.iter().map(|v| v + 0.01 * (rng.unit() - 0.5)).collect();
    (u, y)
}

/// Writes t,u,y with the times `t` (each row's time as written).
fn write_t(path: &Path, t: &[String], u: &[f64], y: &[f64]) {
    let mut text = String::from("t,u,y\n");
    for k in 0..u.len() {
        text.push_str(&format!("{},{},{}\n", t[k], u[k], y[k]));
    }
    std::fs::write(path, text).unwrap();
}

/// The keys of a JSON object.
fn keys(v: &serde_json::Value) -> BTreeSet<String> {
    v.as_object().unwrap().keys().cloned().collect()
}

/// Runs `args` with `--stream on` and `--stream off`, `--json` into `dir`; returns both documents after
/// checking that they carry the same warnings, `data_notes` and top-level keys.
fn both(dir: &Path, tag: &str, args: &[&str]) -> serde_json::Value {
    let mut docs = Vec::new();
    for mode in ["on", "off"] {
        let j = dir.join(format!("{tag}.{mode}.json"));
        let mut a = args.to_vec();
        a.extend(["--stream", mode, "--json", s(&j)]);
        ok(&a);
        docs.push(json(&j));
    }
    assert_eq!(warnings(&docs[0]), warnings(&docs[1]), "{tag}: warnings");
    assert_eq!(
        docs[0]["data_notes"], docs[1]["data_notes"],
        "{tag}: data_notes"
    );
    assert_eq!(keys(&docs[0]), keys(&docs[1]), "{tag}: JSON keys");
    docs.swap_remove(1)
}

/// `identify … --strict` exits 1 (a warning) with both readers.
fn strict_fails_in_both(args: &[&str]) {
    for mode in ["on", "off"] {
        let mut a = args.to_vec();
        a.extend(["--stream", mode, "--strict"]);
        let o = out(&a);
        assert_eq!(
            o.status.code(),
            Some(1),
            "{a:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
}

fn arx<'a>(data: &'a str, extra: &[&'a str]) -> Vec<&'a str> {
    let mut a = common::identify_arx_named(data, "2", "2", "ls");
    a.extend_from_slice(extra);
    a
}

// A time column in whole milliseconds read as seconds gives Ts = 10 s: both readers say so in the same
// note (s27 M-2: the stream said nothing), --strict fails in both, the saved model carries the warning,
// and validate against a model at 0.01 s names --time-unit ms in its refusal, streamed or not.
#[test]
fn a_time_column_in_milliseconds_is_noted_by_both_readers() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals(3000);
    let ms = dir.path().join("ms.csv");
    let t: Vec<String> = (0..u.len()).map(|k| (10 * k).to_string()).collect();
    write_t(&ms, &t, &u, &y);
    let doc = both(dir.path(), "ms", &arx(s(&ms), &[]));
    let w = warnings(&doc);
    assert!(
        w.iter().any(|w| w
            .starts_with("data: the time column t gives Ts = 10 s from whole numbers")
            && w.contains("pass --time-unit ms")),
        "{w:?}"
    );
    assert_eq!(doc["detrend"], "none");
    strict_fails_in_both(&arx(s(&ms), &[]));
    // The model saved by a streamed run carries the warning (validate repeats it).
    let saved = dir.path().join("ms.model.json");
    ok(&arx(s(&ms), &["--stream", "on", "--save-model", s(&saved)]));
    let m = json(&saved);
    let carried = m["model"]["identification"]["warnings"].to_string()
        + &m["identification"]["warnings"].to_string();
    assert!(carried.contains("--time-unit ms"), "{m}");
    // A model at Ts = 0.01 s and the record in ms: the refusal names --time-unit ms in both paths.
    let sec = dir.path().join("sec.csv");
    write_csv(&sec, "t,u,y", Some(0.01), &[&u, &y]);
    let model = dir.path().join("sec.model.json");
    ok(&arx(s(&sec), &["--save-model", s(&model)]));
    for mode in ["on", "off"] {
        let o = out(&[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&ms),
            "--stream",
            mode,
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains("Ts = 10 s")
                && err.contains("--time-unit ms")
                && err.contains("Ts = 0.01 s"),
            "{mode}: {err}"
        );
    }
}

// --ts 0.02 over a column stepping 0.01 s: the contradiction is noted by both readers (the stream did
// not read t under --ts), in identify and in validate.
#[test]
fn a_ts_that_contradicts_the_time_column_is_noted_by_both_readers() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals(3000);
    let rec = dir.path().join("rec.csv");
    write_csv(&rec, "t,u,y", Some(0.01), &[&u, &y]);
    let model = dir.path().join("m.json");
    let doc = both(
        dir.path(),
        "ts",
        &arx(s(&rec), &["--ts", "0.02", "--save-model", s(&model)]),
    );
    let note = "data: --ts 0.02 s contradicts the time column t (its typical step is 0.01 s)";
    assert!(warnings(&doc).iter().any(|w| w.starts_with(note)), "{doc}");
    strict_fails_in_both(&arx(s(&rec), &["--ts", "0.02"]));
    let v = both(
        dir.path(),
        "vts",
        &[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&rec),
            "--ts",
            "0.02",
        ],
    );
    assert!(warnings(&v).iter().any(|w| w.starts_with(note)), "{v}");
}

// A validation file holding the estimation record's samples (the same values, CRLF line ends and
// another number format): "in-sample, not held out" in both paths, identify --validation and validate.
#[test]
fn a_validation_copy_of_the_estimation_record_is_named_by_both_paths() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals(3000);
    let est = dir.path().join("est.csv");
    write_csv(&est, "t,u,y", Some(0.01), &[&u, &y]);
    let copy = dir.path().join("copy.csv");
    let mut text = String::from("t,u,y\r\n");
    for k in 0..u.len() {
        text.push_str(&format!("{:.2},{:e},{:e}\r\n", k as f64 * 0.01, u[k], y[k]));
    }
    std::fs::write(&copy, text).unwrap();
    let words = "holds the same samples as the estimation record";
    let model = dir.path().join("m.json");
    let doc = both(
        dir.path(),
        "cp",
        &arx(
            s(&est),
            &["--validation", s(&copy), "--save-model", s(&model)],
        ),
    );
    assert!(warnings(&doc).iter().any(|w| w.contains(words)), "{doc}");
    strict_fails_in_both(&arx(s(&est), &["--validation", s(&copy)]));
    let v = both(
        dir.path(),
        "vcp",
        &["validate", "--model", s(&model), "--data", s(&copy)],
    );
    let own = |w: &String| !w.starts_with("model: ") && w.contains(words);
    assert!(warnings(&v).iter().any(own), "{v}");
    // Another record of the same system (−u, −y: other samples) is not called a copy by either path.
    let other = dir.path().join("other.csv");
    let (nu, ny): (Vec<f64>, Vec<f64>) = (
        u.iter().map(|v| -v).collect(),
        y.iter().map(|v| -v).collect(),
    );
    write_csv(&other, "t,u,y", Some(0.01), &[&nu, &ny]);
    let v = both(
        dir.path(),
        "vo",
        &["validate", "--model", s(&model), "--data", s(&other)],
    );
    // (The model file repeats its identification's warning, prefixed "model: ".)
    let own = |w: &String| !w.starts_with("model: ") && w.contains(words);
    assert!(!warnings(&v).iter().any(own), "{v}");
}

// The MATLAB reader gives the same notes: t in ms (Ts = 10 s) and a --ts contradicting t.
#[test]
fn the_mat_reader_notes_a_time_column_in_ms_and_a_contradicting_ts() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals(2000);
    let tms: Vec<f64> = (0..u.len()).map(|k| 10.0 * k as f64).collect();
    let m = dir.path().join("tms.mat");
    write_mat(&m, &["t", "u", "y"], &[&tms, &u, &y]);
    let j = dir.path().join("tms.json");
    ok(&arx(s(&m), &["--json", s(&j)]));
    let w = warnings(&json(&j));
    assert!(
        w.iter()
            .any(|w| w.starts_with("data: the time column t gives Ts = 10 s from whole numbers")),
        "{w:?}"
    );
    let t: Vec<f64> = (0..u.len()).map(|k| 0.01 * k as f64).collect();
    let m = dir.path().join("t.mat");
    write_mat(&m, &["t", "u", "y"], &[&t, &u, &y]);
    ok(&arx(s(&m), &["--ts", "0.02", "--json", s(&j)]));
    let w = warnings(&json(&j));
    assert!(
        w.iter()
            .any(|w| w.starts_with("data: --ts 0.02 s contradicts the time column t")),
        "{w:?}"
    );
}

// --ts over a time column with gaps (s27 L-8): every 10th step of 0.01 s is 0.03 s, so 99 of the 999
// steps (9.9 %) lie more than 0.1 % off the median 0.01 s; both readers say so in the resample note's
// words, and that --ts treats the rows as equally spaced.
#[test]
fn ts_over_a_time_column_with_gaps_says_so_in_both_readers() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals(1000);
    let mut t = vec![0.0f64];
    for k in 1..u.len() {
        t.push(t[k - 1] + if k % 10 == 0 { 0.03 } else { 0.01 });
    }
    let gaps = dir.path().join("gaps.csv");
    let t: Vec<String> = t.iter().map(|v| format!("{v:.2}")).collect();
    write_t(&gaps, &t, &u, &y);
    let doc = both(dir.path(), "gaps", &arx(s(&gaps), &["--ts", "0.01"]));
    let want = "data: the time column t is not uniform: the time steps were 0.01 to 0.03 s (median \
                0.01 s), 9.9 % of them more than 0.1 % off the median: --ts 0.01 s treats the rows as \
                equally spaced";
    assert!(warnings(&doc).iter().any(|w| w.starts_with(want)), "{doc}");
    // A uniform column under the same --ts: no such note.
    let even = dir.path().join("even.csv");
    write_csv(&even, "t,u,y", Some(0.01), &[&u, &y]);
    let doc = both(dir.path(), "even", &arx(s(&even), &["--ts", "0.01"]));
    assert!(
        !warnings(&doc).iter().any(|w| w.contains("not uniform")),
        "{doc}"
    );
}

// A logger's jitter within 0.1 % of the median step (s27 L-7): steps of 0.01 s × (1 − 0.00099) for 45 %
// of them, 0.01 s for 50 %, × (1 + 0.00099) for 5 %. The median is 0.01 s and every step lies within
// 0.099 % of it: read in memory. The mean, 0.01 × (1 − 0.000396) s, lies 0.1386 % below the longest
// step: the stream refuses, and says that its rule differs and that --stream off may read the record.
#[test]
fn a_jitter_the_median_rule_accepts_is_refused_by_the_stream_with_the_way_out() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = signals(2001);
    let mut t = vec![0.0f64];
    for k in 1..u.len() {
        let f = match (k - 1) % 20 {
            0..=8 => 1.0 - 0.00099,
            9..=18 => 1.0,
            _ => 1.0 + 0.00099,
        };
        t.push(t[k - 1] + 0.01 * f);
    }
    let jit = dir.path().join("jitter.csv");
    let t: Vec<String> = t.iter().map(|v| format!("{v:.12}")).collect();
    write_t(&jit, &t, &u, &y);
    ok(&arx(s(&jit), &["--stream", "off"]));
    let o = out(&arx(s(&jit), &["--stream", "on"]));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("differs from the mean step")
            && err.contains("--stream off may read this record"),
        "{err}"
    );
}
