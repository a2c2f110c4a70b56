//! `validate --out` writes the record's own time (audit s16 L13): t0 + k·Ts, t0 the time column's value
//! on the judged record's first row, so the "to plot" series line up with the record (and with its
//! `--rows` window); a record without a time column starts at 0. Through the binary.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;

mod common;
use common::bin;

/// The first column of a CSV file with a header.
fn first_column(path: &Path) -> Vec<f64> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().parse().unwrap())
        .collect()
}

fn run(dir: &Path, args: &[&str]) {
    let o = bin().current_dir(dir).args(args).output().unwrap();
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

// A record simulated at Ts = 0.01 s with its time shifted to start at 100 s: validate --out starts at
// 100 s, and with --rows 50..150 at the record's t on row 50 (100.5 s); each row k of the output is at
// the record's own t (read back from the file written here, within rounding).
#[test]
fn validate_out_follows_the_records_time_column() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    run(p, &["simulate", "--samples", "400", "--out", "sim.csv"]);
    let text = std::fs::read_to_string(p.join("sim.csv")).unwrap();
    let mut lines = text.lines();
    let mut shifted = format!("{}\n", lines.next().unwrap());
    let mut times = Vec::new();
    for l in lines {
        let (t, rest) = l.split_once(',').unwrap();
        let t: f64 = t.parse::<f64>().unwrap() + 100.0;
        times.push(t);
        shifted.push_str(&format!("{t},{rest}\n"));
    }
    std::fs::write(p.join("rec.csv"), shifted).unwrap();
    run(
        p,
        &[
            "identify",
            "--data",
            "rec.csv",
            "--structure",
            "arx",
            "--method",
            "ls",
            "--save-model",
            "m.json",
        ],
    );
    for (rows, first) in [(None, 0), (Some("50..150"), 50)] {
        let mut args = vec![
            "validate", "--model", "m.json", "--data", "rec.csv", "--out", "fit.csv",
        ];
        if let Some(r) = rows {
            args.extend(["--rows", r]);
        }
        run(p, &args);
        let t = first_column(&p.join("fit.csv"));
        for (k, tk) in t.iter().enumerate() {
            let want = times[first + k];
            assert!((tk - want).abs() < 1e-9, "row {k}: {tk} vs {want}");
        }
    }
    // Without a time column (--ts), the output starts at 0.
    let no_t: String = text
        .lines()
        .map(|l| l.split_once(',').unwrap().1.to_string() + "\n")
        .collect();
    std::fs::write(p.join("no_t.csv"), no_t).unwrap();
    run(
        p,
        &[
            "validate", "--model", "m.json", "--data", "no_t.csv", "--ts", "0.01", "--out",
            "fit0.csv",
        ],
    );
    assert_eq!(first_column(&p.join("fit0.csv"))[0], 0.0);
}
