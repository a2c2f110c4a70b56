//! Audit s23 M-R1 through the binary: the operating-point check of every structure and method without
//! a constant term. Each expectation comes from the generating recursion written here (a constant
//! term c = 3 the model needs, or none for an integrator), never from the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};

mod common;

/// y(k) = 0.6 y(k−1) + 0.4 u(k−1) + 3 with u in 4..10 (noise-free): the output rests about
/// (0.4 ū + 3)/0.4 ≈ 14.5, an operating point only a constant term c = 3 reproduces. ARX (1, 1, 1)
/// with c is this recursion, so its fit is 100 %.
fn offset_record(dir: &Path, name: &str, phase: usize) -> PathBuf {
    offset_record_of(dir, name, phase, 500)
}

/// [`offset_record`] with `n` samples.
fn offset_record_of(dir: &Path, name: &str, phase: usize, n: usize) -> PathBuf {
    let u: Vec<f64> = (0..n)
        .map(|k| 4.0 + ((((k / 9 + phase) * 7919) % 13) as f64) / 2.0)
        .collect();
    let mut y = vec![10.0; n];
    for k in 1..n {
        y[k] = 0.6 * y[k - 1] + 0.4 * u[k - 1] + 3.0;
    }
    write(dir, name, &u, &y)
}

/// y(k) = y(k−1) + 0.05 u(k−1) from 100 with u a ±1 square wave (noise-free): a position integrator
/// sitting around 100 with u about 0, as the IPA's records do. ARX (1, 1, 1) without c is this
/// recursion exactly, so c cannot improve it: its level is not an operating point.
fn integrator_record(dir: &Path, name: &str, period: usize) -> PathBuf {
    let n = 500;
    let u: Vec<f64> = (0..n)
        .map(|k| if (k / period) % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let mut y = vec![100.0; n];
    for k in 1..n {
        y[k] = y[k - 1] + 0.05 * u[k - 1];
    }
    write(dir, name, &u, &y)
}

fn write(dir: &Path, name: &str, u: &[f64], y: &[f64]) -> PathBuf {
    let mut s = String::from("t,u,y\n");
    for k in 0..u.len() {
        s += &format!("{},{},{}\n", k as f64 * 0.1, u[k], y[k]);
    }
    let p = dir.join(name);
    std::fs::write(&p, s).unwrap();
    p
}

/// The two figures of the hint ("... fits the selection part by X % instead of Y %"), if any.
fn hint(warnings: &[String]) -> Option<(f64, f64)> {
    let w = warnings
        .iter()
        .find(|w| w.contains("non-zero operating point"))?;
    let rest = w.split("fits the selection part by ").nth(1)?;
    let with: f64 = rest.split(" %").next()?.parse().ok()?;
    let without: f64 = rest
        .split("instead of ")
        .nth(1)?
        .split(" %")
        .next()?
        .parse()
        .ok()?;
    Some((with, without))
}

fn identify(dir: &Path, est: &Path, val: Option<&Path>, extra: &[&str]) -> Vec<String> {
    let mut args = vec![
        "identify",
        "--data",
        est.to_str().unwrap(),
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
    ];
    if let Some(v) = val {
        args.extend(["--validation", v.to_str().unwrap()]);
    }
    args.extend(extra);
    let (_, doc) = common::run_json_code(dir, &args);
    common::warnings(&doc)
}

// Every method and structure without c, with or without a validation record, gets the hint with the
// figure c gives (100 %: c is the data's own term), and the text says the same.
#[test]
fn every_structure_without_a_constant_hears_of_the_operating_point() {
    let dir = tempfile::tempdir().unwrap();
    let est = offset_record(dir.path(), "est.csv", 0);
    let val = offset_record(dir.path(), "val.csv", 5);
    for (extra, v) in [
        (
            &["--structure", "arx", "--method", "ls"][..],
            Some(val.as_path()),
        ),
        (
            &["--structure", "arx", "--method", "rls"][..],
            Some(val.as_path()),
        ),
        (
            &["--structure", "arx", "--method", "oe"][..],
            Some(val.as_path()),
        ),
        (&["--structure", "arx", "--method", "ls"][..], None),
        // Read in passes: the same check from the records read again (audit s23 M-R1 redone).
        (
            &["--structure", "arx", "--method", "ls", "--stream"][..],
            Some(val.as_path()),
        ),
        (
            &["--structure", "arx", "--method", "ls", "--stream"][..],
            None,
        ),
        // Not Hammerstein: its deadzone's offset (b_r = −7.5 outside the input range 4..10 here) carries
        // the level as a constant would, so its own fit is high and the check rightly stays silent.
    ] {
        let w = identify(dir.path(), &est, v, extra);
        let (with, without) = hint(&w).unwrap_or_else(|| panic!("{extra:?} {v:?}: no hint: {w:?}"));
        assert!(
            with > 99.9 && with > without + 5.0,
            "{extra:?}: {with} {without}"
        );
        assert!(w.iter().any(|w| w.contains("--offset")), "{w:?}");
        // One operating-point word, not two.
        assert_eq!(
            w.iter()
                .filter(|w| w.contains("far from zero") || w.contains("operating point"))
                .count(),
            1,
            "{w:?}"
        );
    }
    let out = common::run(&[
        "identify",
        "--data",
        est.to_str().unwrap(),
        "--validation",
        val.to_str().unwrap(),
        "--structure",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
    ]);
    let text = String::from_utf8_lossy(&out.stdout).into_owned() + &common::stderr(&out);
    assert!(text.contains("non-zero operating point"), "{text}");
}

// With a constant term or a removed operating point there is nothing to say; nor on an integrator
// whose level is its state, not an operating point.
#[test]
fn offset_detrend_and_an_integrator_get_no_operating_point_hint() {
    let dir = tempfile::tempdir().unwrap();
    let est = offset_record(dir.path(), "est.csv", 0);
    let val = offset_record(dir.path(), "val.csv", 5);
    for extra in [&["--offset"][..], &["--detrend", "mean"][..]] {
        let w = identify(dir.path(), &est, Some(&val), extra);
        assert_eq!(hint(&w), None, "{extra:?}: {w:?}");
    }
    let est = integrator_record(dir.path(), "iest.csv", 25);
    let val = integrator_record(dir.path(), "ival.csv", 40);
    for v in [Some(val.as_path()), None] {
        let w = identify(dir.path(), &est, v, &["--structure", "arx"]);
        assert!(
            !w.iter()
                .any(|w| w.contains("operating point") || w.contains("far from zero")),
            "{w:?}"
        );
    }
}

// The streamed identification and the one in memory say the same words about the operating point,
// figures included (one function decides and words it: `sysid::order::offset_hint_of`).
#[test]
fn streamed_and_in_memory_identification_give_the_same_operating_point_hint() {
    let dir = tempfile::tempdir().unwrap();
    let est = offset_record(dir.path(), "est.csv", 0);
    let val = offset_record(dir.path(), "val.csv", 5);
    for v in [Some(val.as_path()), None] {
        let mem = identify(
            dir.path(),
            &est,
            v,
            &["--structure", "arx", "--method", "ls"],
        );
        let streamed = identify(
            dir.path(),
            &est,
            v,
            &["--structure", "arx", "--method", "ls", "--stream"],
        );
        assert_eq!(said(&mem).len(), 1, "{mem:?}");
        assert_eq!(said(&mem), said(&streamed), "{v:?}");
    }
}

// A record longer than the check reads (sysid_summary::OPERATING_POINT_MAX_ROWS = 100 000 samples): the
// check reads the first 100 000 samples of each record, in memory and read in passes alike (session 25:
// read in passes it read the whole file about 11 more times), says so, and still finds what c gives
// (100 %: the data's own term, in any part of the record).
#[test]
fn a_long_record_is_checked_on_its_first_samples_alike_in_memory_and_streamed() {
    let dir = tempfile::tempdir().unwrap();
    let est = offset_record_of(dir.path(), "est.csv", 0, 150_000);
    let val = offset_record_of(dir.path(), "val.csv", 5, 120_000);
    for (v, part) in [
        (
            Some(val.as_path()),
            "the selection part here: the validation record's first 100000 samples, estimated on the estimation \
             record's first 100000",
        ),
        (
            None,
            "the selection part here: the last third of the estimation record's first 100000 samples, estimated on \
             the rest of them",
        ),
    ] {
        let arx = ["--structure", "arx", "--method", "ls"];
        let mem = identify(dir.path(), &est, v, &arx);
        let streamed = identify(dir.path(), &est, v, &[&arx[..], &["--stream"]].concat());
        assert_eq!(said(&mem).len(), 1, "{mem:?}");
        assert!(said(&mem)[0].contains(part), "{mem:?}");
        assert_eq!(hint(&mem).map(|(with, _)| with), Some(100.0), "{mem:?}");
        assert_eq!(said(&mem), said(&streamed), "{v:?}");
    }
}

/// The warnings about the operating point.
fn said(warnings: &[String]) -> Vec<String> {
    warnings
        .iter()
        .filter(|w| w.contains("operating point"))
        .cloned()
        .collect()
}
