//! Session 36 (fix36a): audit s35's reader and numeric leftovers — the reader's notes before an
//! estimation error under `--stream on` (M-3), outputs so small their squares underflow (H-2), a record
//! cut inside its last number (M-2), an unquoted decimal comma in a file of quoted ones, and the LOW
//! items.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{bin, s, stderr, write_tuy};

/// u = 100 sin(k/10), y = 100 + 50 sin(k/7), k = 0..299, y(99) = `big`: line 101 of the file (the header
/// is line 1), column 3 (t, u, y).
fn one_huge_output(dir: &std::path::Path, name: &str, big: f64) -> std::path::PathBuf {
    let u: Vec<f64> = (0..300).map(|k| 100.0 * (k as f64 / 10.0).sin()).collect();
    let mut y: Vec<f64> = (0..300)
        .map(|k| 100.0 + 50.0 * (k as f64 / 7.0).sin())
        .collect();
    y[99] = big;
    write_tuy(dir, name, 0.01, &u, &y)
}

/// Audit s35 M-3, the rest: under `--stream on` one y of 1e200 overflowed least squares and the error
/// named no file and came without the reader's note naming the value (in memory both were said since
/// session 35). The record as estimation record and as validation record: the note (line 101, column 3,
/// the value) comes before the error, and the error names the file.
#[test]
fn a_streamed_estimation_that_fails_names_its_file_after_the_readers_note() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let big = one_huge_output(d, "big.csv", 1e200);
    let plain: Vec<f64> = (0..300).map(|k| 100.0 * (k as f64 / 10.0).sin()).collect();
    // A plain record (y a first-order response of u, plus a small deterministic disturbance so that
    // ARX(2, 2) is determined) for the estimation when big.csv validates.
    let mut y = vec![0.0; 300];
    for k in 1..300 {
        y[k] = 0.9 * y[k - 1] + 0.5 * plain[k - 1] + (1.3 * k as f64).sin();
    }
    let good = write_tuy(d, "good.csv", 0.01, &plain, &y);
    let arx = [
        "--structure",
        "arx",
        "--na",
        "2",
        "--nb",
        "2",
        "--method",
        "ls",
    ];
    for (data, val) in [(&big, None), (&good, Some(&big))] {
        for stream in ["on", "off"] {
            let mut cmd = bin();
            cmd.args(["identify", "--data", s(data)]).args(arx);
            if let Some(v) = val {
                cmd.args(["--validation", s(v)]);
            }
            let out = cmd.args(["--stream", stream]).output().unwrap();
            let e = stderr(&out);
            assert_eq!(out.status.code(), Some(1), "{stream}: {e}");
            let note = e
                .lines()
                .find(|l| l.starts_with("warning: data: ") && l.contains("big.csv:101:3:"))
                .unwrap_or_else(|| panic!("{stream}: no located note: {e}"));
            assert!(note.contains("1e200"), "{note}");
            let error = e.lines().find(|l| l.starts_with("error: ")).unwrap();
            assert!(
                error.contains("big.csv"),
                "{stream}: the error names no file: {e}"
            );
            assert!(e.find(note).unwrap() < e.find(error).unwrap(), "{e}");
        }
    }
}
