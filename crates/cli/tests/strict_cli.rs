//! `--strict` on `order`, `delay`, `track`, `simulate` and `montecarlo`, and `simulate --json` (audit
//! s17 L-d), through the binary. The records are generated here from a known ARX system, so whether a
//! run deserves a warning follows from the system (a delay beyond the searched range, an order at the
//! grid's edge, a detector that cannot arm on a short record), and `simulate --json`'s figures are
//! recomputed from the CSV it wrote.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;

mod common;
use common::{bin, identify_arx, run_json_code, stderr, warnings};

/// A record of y(k) = 0.5 y(k−1) + u(k−3) + 0.3 u(k−4) + e(k): na = 1, nb = 2, nk = 3 (a stable pole
/// at 0.5), u = ±1 from a linear congruential generator, e uniform in ±`noise`; Ts = 0.1 s.
fn arx_record(path: &Path, n: usize, noise: f64) {
    let mut rng = common::lcg(12345);
    let mut next = || rng.unit();
    let mut u = vec![0.0; n];
    let mut y = vec![0.0; n];
    let mut text = String::from("t,u,y\n");
    for k in 0..n {
        u[k] = if next() < 0.5 { -1.0 } else { 1.0 };
        let e = noise * (2.0 * next() - 1.0);
        let past = |v: &[f64], i: usize| if k >= i { v[k - i] } else { 0.0 };
        y[k] = 0.5 * past(&y, 1) + past(&u, 3) + 0.3 * past(&u, 4) + e;
        text.push_str(&format!("{},{},{}\n", k as f64 * 0.1, u[k], y[k]));
    }
    std::fs::write(path, text).unwrap();
}

/// Runs `args` once without `--strict` (its `--json` document says whether the run warns), then with
/// `--strict` over an earlier `--json` file: exit 1 and the earlier file unchanged when the document
/// had warnings, exit 0 and the same document written when it had none. Returns the warnings.
fn strict_agrees_with_the_warnings(dir: &Path, args: &[&str]) -> Vec<String> {
    let (code, doc) = run_json_code(dir, args);
    assert_eq!(code, 0, "{args:?}");
    let said = warnings(&doc);
    let json = dir.join("earlier.json");
    // An earlier JSON report, marked as the run marks it (audit s22 M-B9; s32 H-1).
    let earlier = "{\"format\": \"ipa-sysid-report\", \"earlier\": true}\n";
    std::fs::write(&json, earlier).unwrap();
    let o = bin()
        .current_dir(dir)
        .args(args)
        .arg("--strict")
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let written = std::fs::read_to_string(&json).unwrap();
    if said.is_empty() {
        assert_eq!(o.status.code(), Some(0), "{args:?}: {}", stderr(&o));
        let again: serde_json::Value = serde_json::from_str(&written).unwrap();
        assert_eq!(warnings(&again), said);
    } else {
        assert_eq!(o.status.code(), Some(1), "{args:?}: {}", stderr(&o));
        assert_eq!(written, earlier, "{args:?}");
        let e = stderr(&o);
        assert!(
            e.contains(&format!("{} warning(s) and --strict", said.len()))
                && e.contains("not written"),
            "{args:?}: {e}"
        );
    }
    said
}

// delay: the system's delay is 3 samples, so a search of 0..=1 ends at its edge (the documented
// warning); a search of 0..=10 on the noise-free record finds 3 clearly, without a warning.
#[test]
fn delay_strict_fails_exactly_when_the_estimate_warns() {
    let dir = tempfile::tempdir().unwrap();
    arx_record(&dir.path().join("arx.csv"), 400, 0.0);
    let edge = strict_agrees_with_the_warnings(
        dir.path(),
        &["delay", "--data", "arx.csv", "--max-delay", "1"],
    );
    assert!(
        edge.iter().any(|w| w.contains("largest one tried")),
        "{edge:?}"
    );
    let clean = strict_agrees_with_the_warnings(dir.path(), &["delay", "--data", "arx.csv"]);
    assert!(clean.is_empty(), "{clean:?}");
}

// order: nb = 2 is the system's, so a grid nb 1..2 recommends its edge (a warning) and nb 1..3 does
// not; na 1..2 holds the true na = 1 inside.
#[test]
fn order_strict_fails_exactly_when_the_ranking_warns() {
    let dir = tempfile::tempdir().unwrap();
    arx_record(&dir.path().join("arx.csv"), 400, 0.0);
    let grid = |nb: &'static str| {
        [
            "order", "--data", "arx.csv", "--model", "arx", "--na", "1..2", "--nb", nb, "--nk", "3",
        ]
    };
    let edge = strict_agrees_with_the_warnings(dir.path(), &grid("1..2"));
    assert!(edge.iter().any(|w| w.contains("widen --nb")), "{edge:?}");
    let clean = strict_agrees_with_the_warnings(dir.path(), &grid("1..3"));
    assert!(clean.is_empty(), "{clean:?}");
}

// track: the change detector needs k0 + warm-up + calibration = 3 + 500 + 2000 samples to arm, so a
// 1000-sample record warns that it never armed; 3000 samples of the stable ARX system do not warn.
#[test]
fn track_strict_fails_exactly_when_the_summary_warns() {
    let dir = tempfile::tempdir().unwrap();
    arx_record(&dir.path().join("short.csv"), 1000, 0.01);
    arx_record(&dir.path().join("long.csv"), 3000, 0.01);
    let track = |data: &'static str| {
        [
            "track", "--data", data, "--model", "arx", "--na", "1", "--nb", "2", "--nk", "3",
        ]
    };
    let short = strict_agrees_with_the_warnings(dir.path(), &track("short.csv"));
    assert!(short.iter().any(|w| w.contains("never armed")), "{short:?}");
    let long = strict_agrees_with_the_warnings(dir.path(), &track("long.csv"));
    assert!(long.is_empty(), "{long:?}");
}

// montecarlo: least squares on the paper's Hammerstein plant with a 1000-sample staircase leaves a
// deadzone parameter poorly determined in some runs (a warning the study repeats); on the ARX model
// identified from the known system, driven inside its data (±1), no run warns.
#[test]
fn montecarlo_strict_fails_exactly_when_the_study_warns() {
    let dir = tempfile::tempdir().unwrap();
    arx_record(&dir.path().join("arx.csv"), 3000, 0.01);
    let o = bin()
        .current_dir(dir.path())
        .args(
            [
                identify_arx(Path::new("arx.csv"), "1", "2", "ls"),
                vec!["--nk", "3", "--save-model", "arx.json"],
            ]
            .concat(),
        )
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let study = |plant: &'static str, input: &'static str, amplitude: &'static str| {
        [
            "montecarlo",
            "--plant",
            plant,
            "--input",
            input,
            "--amplitude",
            amplitude,
            "--runs",
            "8",
            "--method",
            "ls",
            "--samples",
            "1000",
        ]
    };
    let paper = strict_agrees_with_the_warnings(dir.path(), &study("paper", "staircase", "255"));
    assert!(!paper.is_empty());
    let arx = strict_agrees_with_the_warnings(dir.path(), &study("model:arx.json", "prbs", "1"));
    assert!(arx.is_empty(), "{arx:?}");
}

/// The columns of a CSV file with a header: (header, columns).
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let mut columns = vec![Vec::new(); header.len()];
    for l in lines {
        for (c, x) in columns.iter_mut().zip(l.split(',')) {
            c.push(x.parse().unwrap());
        }
    }
    (header, columns)
}

// simulate --json: the document describes the CSV written beside it (header, rows, Ts from the time
// column, the output's range); the paper's model has no end stops, so an APRBS record that leaves
// 0..200 mm carries the stroke warning, and with --strict neither file is written.
#[test]
fn simulate_json_describes_the_record_and_strict_keeps_earlier_files() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, json) = (dir.path().join("p.csv"), dir.path().join("p.json"));
    let args = [
        "simulate",
        "--plant",
        "paper",
        "--input",
        "aprbs",
        "--samples",
        "3000",
        "--seed",
        "4",
        "--out",
        csv.to_str().unwrap(),
    ];
    let o = bin().args(args).arg("--json").arg(&json).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let (header, cols) = read_csv(&csv);
    let shown: Vec<&str> = doc["columns"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_str().unwrap())
        .collect();
    assert_eq!(shown, header);
    assert_eq!(doc["samples"].as_u64().unwrap() as usize, cols[0].len());
    let ts = cols[0][1] - cols[0][0];
    assert!((doc["ts"].as_f64().unwrap() - ts).abs() < 1e-12);
    let y = &cols[header.iter().position(|h| h == "y").unwrap()];
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    assert_eq!(doc["y_range"][0].as_f64().unwrap(), lo);
    assert_eq!(doc["y_range"][1].as_f64().unwrap(), hi);
    let said = warnings(&doc);
    let beyond = lo < 0.0 || hi > 200.0;
    assert!(beyond, "the seed was chosen for a record beyond the stroke");
    assert!(
        said.iter().any(|w| w.contains("beyond the IPA's stroke")),
        "{said:?}"
    );
    // The same warnings in the text.
    for w in &said {
        assert!(stderr(&o).contains(&format!("warning: {w}")), "{w}");
    }
    // --strict: exit 1, neither file replaced, no "wrote" line.
    std::fs::write(&csv, "earlier csv\n").unwrap();
    std::fs::write(&json, "earlier json\n").unwrap();
    let o = bin()
        .args(args)
        .args(["--json", json.to_str().unwrap(), "--strict"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!stderr(&o).contains("wrote "), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), "earlier csv\n");
    assert_eq!(std::fs::read_to_string(&json).unwrap(), "earlier json\n");
}

// simulate --strict on a run without warnings (the physics plant's default staircase) writes both
// files and exits 0; the document's warnings are empty and its samples are the CSV's rows.
#[test]
fn simulate_strict_without_warnings_writes_the_record() {
    let dir = tempfile::tempdir().unwrap();
    let (csv, json) = (dir.path().join("s.csv"), dir.path().join("s.json"));
    let o = bin()
        .args([
            "simulate",
            "--samples",
            "300",
            "--strict",
            "--out",
            csv.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(warnings(&doc).is_empty());
    assert_eq!(read_csv(&csv).1[0].len(), 300);
    assert_eq!(doc["samples"].as_u64(), Some(300));
}
