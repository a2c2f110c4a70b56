//! Session 22's leftovers of session 21 (brief fixab): one floor, 1e-6 s, for every sampling period
//! (`--ts`, a time column), the one of model files and the controller.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;
use common::{arx_signals, run, stderr, write_csv};

/// The shortest sampling period of a model file and of the controller, s (docs/data.md): written here,
/// not read from the library, so that a change of the floor has to change this test too.
const FLOOR_S: f64 = 1e-6;

/// A stable first-order ARX record y(k) = 0.5 y(k−1) + u(k−1) under a square wave, 200 rows.
fn record(dir: &std::path::Path, ts_s: Option<f64>) -> std::path::PathBuf {
    let (u, y) = arx_signals(200, &[0.5], &[1.0], |k| {
        if (k / 10) % 2 == 0 {
            1.0
        } else {
            -1.0
        }
    });
    let path = dir.join(if ts_s.is_some() { "timed.csv" } else { "d.csv" });
    write_csv(
        &path,
        if ts_s.is_some() { "t,u,y" } else { "u,y" },
        ts_s,
        &[&u, &y],
    );
    path
}

// Half the floor is refused by every command that takes --ts, naming the flag and the range, with the
// usage exit code 2, before any work; the floor itself is accepted.
#[test]
fn a_ts_below_the_model_file_floor_is_refused_by_every_command_naming_ts() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), None);
    let d = data.to_str().unwrap();
    let model = dir.path().join("m.json");
    let m = model.to_str().unwrap();
    let floor = format!("{FLOOR_S}");
    let o = run(&[
        "identify",
        "--data",
        d,
        "--structure",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "--ts",
        &floor,
        "--save-model",
        m,
    ]);
    assert!(
        o.status.success(),
        "the floor itself is a Ts: {}",
        stderr(&o)
    );
    let below = format!("{}", FLOOR_S / 2.0);
    let out = dir.path().join("s.csv");
    let o_ = out.to_str().unwrap();
    for args in [
        vec![
            "identify",
            "--data",
            d,
            "--structure",
            "arx",
            "--na",
            "1",
            "--nb",
            "1",
            "--ts",
            &below,
        ],
        vec![
            "order", "--data", d, "--na", "1..2", "--nb", "1", "--ts", &below,
        ],
        vec!["validate", "--model", m, "--data", d, "--ts", &below],
        vec![
            "simulate",
            "--plant",
            "ipa",
            "--samples",
            "50",
            "--ts",
            &below,
            "--out",
            o_,
        ],
    ] {
        let o = run(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            // Echoed in exponent form below 1e-5 (docs/plant.md; audit s35b L-12).
            err.contains(&format!("invalid setting --ts = {:e}", FLOOR_S / 2.0))
                && err.contains("1e-6"),
            "{args:?}: {err}"
        );
        assert!(!out.exists(), "{args:?} wrote its output");
    }
}

// A time column stepping 5e-7 s gives that Ts: refused at the file's time column, with the floor.
#[test]
fn a_time_column_stepping_below_the_floor_is_refused_at_the_column() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), Some(FLOOR_S / 2.0));
    let o = run(&[
        "identify",
        "--data",
        data.to_str().unwrap(),
        "--structure",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
    ]);
    let err = stderr(&o);
    assert_ne!(o.status.code(), Some(0), "{err}");
    assert!(
        err.contains("timed.csv:3:1:") && err.contains("below 1e-6 s"),
        "{err}"
    );
}
