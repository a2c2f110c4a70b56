//! Audit s20, findings H-1, M-3, M-1, L-2 and L-7 through the binary. Each expectation is derived from
//! the record written here (a constant input determines no input term; a pole of the generating
//! recursion; the rule stated in the code's docs), never copied from the output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};
use std::process::Stdio;

mod common;
use common::{bin, run as ipa_sysid, stderr};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The audit's records q2.csv and q5.csv (docs/estimators.md:214): `t,u,y` of 20 000 rows at
/// Ts = 0.01 s with the input held at `u` and the output at 1.
fn constant_record(dir: &Path, u: f64) -> PathBuf {
    let path = dir.join(format!("q{u}.csv"));
    let mut text = String::from("t,u,y\n");
    for k in 0..20_000 {
        text.push_str(&format!("{},{u},1\n", k as f64 * 0.01));
    }
    std::fs::write(&path, text).unwrap();
    path
}

// H-1: a constant (q5) or zero (q2) input determines no input term: y = 1 throughout fits
// y(k) = −a1 − a2 + b1 u for every (a1 + a2, b1) on a line, so no method may return one point of it.
// Plain RLS refuses both; every windup protection and forgetting factor must refuse them the same way
// (exit code 2: the data cannot support the estimate) and name the reason.
#[test]
fn a_constant_or_zero_input_is_refused_by_rls_whatever_the_windup_protection() {
    let dir = tempfile::tempdir().unwrap();
    for u in [0.0, 5.0] {
        let data = constant_record(dir.path(), u);
        for extra in [
            &[][..],
            &["--windup", "trace"][..],
            &["--windup", "directional"][..],
            &["--windup", "trace", "--forgetting", "0.99"][..],
            &["--forgetting", "0.99"][..],
            &["--rls-form", "ud", "--windup", "trace"][..],
        ] {
            let mut args = vec![
                "identify",
                "--data",
                s(&data),
                "--structure",
                "arx",
                "--na",
                "2",
                "--nb",
                "1",
                "--method",
                "rls",
            ];
            args.extend_from_slice(extra);
            let out = ipa_sysid(&args);
            let err = stderr(&out);
            assert_eq!(out.status.code(), Some(2), "u = {u} {extra:?}: {err}");
            assert!(
                err.contains("not persistently exciting"),
                "u = {u} {extra:?}: {err}"
            );
            assert!(!err.contains("± 0"), "{err}");
        }
    }
}

// H-1: `track` (trace windup by default) cannot refuse a stream, so it says that a constant input
// left the input terms undetermined, in the text and in the JSON summary's warnings.
#[test]
fn track_says_a_constant_input_does_not_excite_an_arx_model() {
    let dir = tempfile::tempdir().unwrap();
    let data = constant_record(dir.path(), 5.0);
    let text = std::fs::read(&data).unwrap();
    let run = |json: bool| {
        let mut cmd = bin();
        cmd.args([
            "track",
            "--data",
            "-",
            "--structure",
            "arx",
            "--na",
            "2",
            "--nb",
            "1",
        ]);
        if json {
            cmd.args(["--json", "-"]);
        }
        let mut child = cmd
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        use std::io::Write;
        child.stdin.take().unwrap().write_all(&text).unwrap();
        child.wait_with_output().unwrap()
    };
    let out = run(false);
    assert!(
        stderr(&out).contains("warning: the input took only 1 distinct level (5)"),
        "{}",
        stderr(&out)
    );
    let out = run(true);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let summary: serde_json::Value = serde_json::from_str(stdout.lines().last().unwrap()).unwrap();
    let w = common::warnings(&summary);
    assert!(
        w.iter()
            .any(|w| w.contains("1 distinct level (5)") && w.contains("not persistently exciting")),
        "{w:?}"
    );
}

// H-1: a varying input still passes under every windup protection (the test is over the whole record).
#[test]
fn an_exciting_input_is_still_accepted_with_trace_windup() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.csv");
    let mut text = String::from("t,u,y\n");
    let (mut y1, mut y2, mut u1) = (0.0f64, 0.0f64, 0.0f64);
    let mut g = common::lcg(7);
    for k in 0..4000 {
        let u = if g.unit() < 0.5 { -1.0 } else { 1.0 };
        // y(k) = 1.2 y(k−1) − 0.5 y(k−2) + 0.3 u(k−1)
        let y = 1.2 * y1 - 0.5 * y2 + 0.3 * u1;
        text.push_str(&format!("{},{u},{y}\n", k as f64 * 0.01));
        (y2, y1, u1) = (y1, y, u);
    }
    std::fs::write(&path, text).unwrap();
    let out = ipa_sysid(&[
        "identify",
        "--data",
        s(&path),
        "--structure",
        "arx",
        "--na",
        "2",
        "--nb",
        "1",
        "--method",
        "rls",
        "--windup",
        "trace",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
}

// H-1: the poles line does not call a pole within the integrator margin (1e-5) of the unit circle
// "inside": noise-free y(k) = 0.999999 y(k−1) + u(k−1) has its pole at 0.999999, 1e-6 from the circle.
#[test]
fn a_pole_on_the_unit_circle_to_rounding_is_not_called_inside() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("i.csv");
    let mut text = String::from("t,u,y\n");
    let (mut y1, mut u1) = (0.0f64, 0.0f64);
    let mut g = common::lcg(11);
    for k in 0..2000 {
        let u = g.unit() - 0.5;
        let y = 0.999999 * y1 + u1;
        text.push_str(&format!("{},{u},{y}\n", k as f64 * 0.01));
        (y1, u1) = (y, u);
    }
    std::fs::write(&path, text).unwrap();
    let out = ipa_sysid(&[
        "identify",
        "--data",
        s(&path),
        "--structure",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "--method",
        "ls",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let poles = stdout.lines().find(|l| l.starts_with("Poles:")).unwrap();
    assert!(!poles.contains("all inside"), "{poles}");
    assert!(poles.contains("on the stability boundary"), "{poles}");
}
