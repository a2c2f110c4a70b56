//! `ipa-sysid control` end to end on the paper's model (`--plant paper`, fast): outputs, their consistency
//! with each other (metrics recomputed here from the trace CSV, by independent code), and bad flags.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::process::{Command, Output};

mod common;
use common::{read_trace, stderr};

fn ipa_sysid(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .arg("control")
        .args(args)
        .output()
        .expect("run ipa-sysid")
}

/// First time y crosses `level` going up, linearly interpolated (independent of the library's code).
fn crossing_up(t: &[f64], y: &[f64], level: f64) -> f64 {
    for k in 1..y.len() {
        if y[k - 1] < level && y[k] >= level {
            return t[k - 1] + (level - y[k - 1]) / (y[k] - y[k - 1]) * (t[k] - t[k - 1]);
        }
    }
    panic!("never crosses {level}");
}

#[test]
fn fixed_setpoint_json_matches_metrics_recomputed_from_the_trace() {
    // From the CSV: y_f = last y; OS = max y - y_f; OS % = 100 OS / (y_f - y0); e_ss = 50 - y_f;
    // t_r = t(90 %) - t(10 %) of y_f - y0 (the response rises monotonically to the first peak).
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("m.json");
    let csv = dir.path().join("trace.csv");
    let o = ipa_sysid(&[
        "--plant",
        "paper",
        "--setpoint",
        "50",
        "--duration",
        "5",
        "--json",
        json.to_str().unwrap(),
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains("overshoot") && stdout.contains("settling time"),
        "{stdout}"
    );

    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let m = &v["metrics"];
    for key in [
        "overshoot_mm",
        "overshoot_percent",
        "steady_state_error_mm",
        "rise_time_s",
        "settling_time_s",
    ] {
        assert!(
            m[key].is_f64(),
            "metrics.{key} missing or not a number: {m}"
        );
    }
    assert_eq!(v["settings"]["controller"]["kp"], 14.0);
    assert_eq!(v["settings"]["controller"]["integral"], "scaled");
    assert_eq!(v["plant"]["spec"], "paper");
    assert_eq!(v["samples"], 501);

    let (t, r, u, y) = read_trace(&csv);
    assert_eq!(t.len(), 501);
    assert!((t[500] - 5.0).abs() < 1e-9 && (t[1] - 0.01).abs() < 1e-12);
    assert!(r.iter().all(|&r| r == 50.0));
    assert!(u.iter().all(|&u| u.abs() <= 255.0));
    assert_eq!(u[0], 255.0); // Kp e(0) = 700 saturates.
    let (y0, yf) = (y[0], *y.last().unwrap());
    let peak = y.iter().copied().fold(f64::MIN, f64::max);
    let os = (peak - yf).max(0.0);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * (1.0 + b.abs());
    assert!(
        close(m["overshoot_mm"].as_f64().unwrap(), os),
        "{m} vs OS {os}"
    );
    assert!(close(
        m["overshoot_percent"].as_f64().unwrap(),
        100.0 * os / (yf - y0)
    ));
    assert!(close(
        m["steady_state_error_mm"].as_f64().unwrap(),
        50.0 - yf
    ));
    let rise =
        crossing_up(&t, &y, y0 + 0.9 * (yf - y0)) - crossing_up(&t, &y, y0 + 0.1 * (yf - y0));
    assert!(
        close(m["rise_time_s"].as_f64().unwrap(), rise),
        "{m} vs t_r {rise}"
    );
    // Settling: every sample after t_s is within 2 % of the step; the sample before it is not.
    let ts = m["settling_time_s"].as_f64().unwrap();
    let band = 0.02 * (yf - y0);
    assert!(t
        .iter()
        .zip(&y)
        .filter(|(t, _)| **t > ts + 1e-12)
        .all(|(_, y)| (y - yf).abs() <= band));
    let before = t.iter().rposition(|&tk| tk < ts).unwrap();
    assert!((y[before] - yf).abs() > band);
}

#[test]
fn json_to_stdout_is_clean_json_and_the_summary_goes_to_stderr() {
    // `--json -`: stdout parses as JSON; the human summary is on stderr.
    let o = ipa_sysid(&[
        "--plant",
        "paper",
        "--setpoint",
        "20",
        "--duration",
        "2",
        "--json",
        "-",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("stdout is JSON");
    assert_eq!(v["metrics_kind"], "fixed");
    assert!(stderr(&o).contains("rise time"));
}

#[test]
fn staircase_profile_reports_one_step_per_level() {
    // staircase:10,30,20@1 over its natural 3 s: 3 segments starting at 0, 1, 2 s with set-points 10, 30, 20.
    let o = ipa_sysid(&[
        "--plant",
        "paper",
        "--profile",
        "staircase:10,30,20@1",
        "--json",
        "-",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let steps = v["steps"].as_array().unwrap();
    assert_eq!(steps.len(), 3);
    for (s, (start, r)) in steps.iter().zip([(0.0, 10.0), (1.0, 30.0), (2.0, 20.0)]) {
        assert!((s["start_s"].as_f64().unwrap() - start).abs() < 1e-9);
        assert_eq!(s["setpoint_mm"], r);
    }
    assert_eq!(v["metrics_kind"], "worst-step");
    assert_eq!(v["samples"], 301);
}

#[test]
fn per_sample_integral_overshoots_more_than_scaled() {
    // Ki per sample is 1/Ts = 100 times stronger: a 50 mm step overshoots ~56 % instead of ~3.7 %.
    let os = |form: &str| {
        let o = ipa_sysid(&[
            "--plant",
            "paper",
            "--setpoint",
            "50",
            "--integral",
            form,
            "--json",
            "-",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        v["metrics"]["overshoot_percent"].as_f64().unwrap()
    };
    let (scaled, per_sample) = (os("scaled"), os("per-sample"));
    assert!(scaled < 10.0 && per_sample > 40.0, "{scaled} {per_sample}");
}

#[test]
fn deadzone_compensator_is_recorded_in_the_settings() {
    // --compensate-deadzone paper: the compensator object carries the paper's b_r = 1.41.
    let o = ipa_sysid(&[
        "--plant",
        "paper",
        "--setpoint",
        "5",
        "--duration",
        "2",
        "--compensate-deadzone",
        "paper",
        "--json",
        "-",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["settings"]["compensator"]["deadzone"]["b_r"], 1.41);
}

/// Runs with `args`, expects exit code 2 and every needle in stderr, and no panic.
fn expect_usage_error(args: &[&str], needles: &[&str]) {
    let o = ipa_sysid(args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "args {args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "args {args:?}: stderr lacks {n:?}: {err}");
    }
}

#[test]
fn bad_flags_exit_2_with_a_message_naming_the_flag() {
    // Each malformed flag is named in the message; exit code 2 (bad input).
    expect_usage_error(
        &["--plant", "paper", "--setpoint", "50", "--kp", "abc"],
        &["--kp"],
    );
    expect_usage_error(
        &["--plant", "paper", "--setpoint", "50", "--kp", "nan"],
        &["--kp"],
    );
    expect_usage_error(
        &["--plant", "paper", "--setpoint", "50", "--u-max", "0"],
        &["--u-max"],
    );
    expect_usage_error(
        &["--plant", "paper", "--setpoint", "50", "--duration", "-1"],
        &["--duration"],
    );
    expect_usage_error(&["--plant", "paper", "--setpoint", "inf"], &["--setpoint"]);
    expect_usage_error(&["--plant", "paper"], &["--setpoint"]);
    expect_usage_error(
        &[
            "--plant",
            "paper",
            "--setpoint",
            "5",
            "--profile",
            "fixed:5",
        ],
        &["--profile"],
    );
    expect_usage_error(
        &["--plant", "paper", "--profile", "staircase:20,x@3"],
        &["staircase:20,x@3", "not a number"],
    );
    expect_usage_error(
        &[
            "--plant",
            "paper",
            "--setpoint",
            "5",
            "--integral",
            "trapezoid",
        ],
        &["--integral"],
    );
    expect_usage_error(
        &[
            "--plant",
            "paper",
            "--setpoint",
            "5",
            "--tracking-time",
            "1",
        ],
        &["--tracking-time"],
    );
    expect_usage_error(&["--plant", "nonsense", "--setpoint", "5"], &["--plant"]);
    expect_usage_error(
        &[
            "--plant",
            "paper",
            "--setpoint",
            "5",
            "--compensate-deadzone",
            "/nonexistent/m.json",
        ],
        &["--compensate-deadzone", "/nonexistent/m.json"],
    );
}

#[test]
fn refuses_to_write_the_trace_over_the_profile_file() {
    // --out equal to the profile file given with --profile file:PATH: exit 2, file untouched.
    let dir = tempfile::tempdir().unwrap();
    let prof = dir.path().join("r.csv");
    std::fs::write(&prof, "t,r\n0,10\n1,20\n").unwrap();
    let spec = format!("file:{}", prof.display());
    expect_usage_error(
        &[
            "--plant",
            "paper",
            "--profile",
            &spec,
            "--out",
            prof.to_str().unwrap(),
        ],
        &["--out", "refusing"],
    );
    assert_eq!(std::fs::read_to_string(&prof).unwrap(), "t,r\n0,10\n1,20\n");
    // The same profile with a separate output works, and the trace follows the file's set-points.
    let csv = dir.path().join("trace.csv");
    let o = ipa_sysid(&[
        "--plant",
        "paper",
        "--profile",
        &spec,
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (t, r, _, _) = read_trace(&csv);
    assert_eq!(t.len(), 101);
    assert_eq!((r[0], r[99], r[100]), (10.0, 10.0, 20.0));
}

#[test]
fn a_profile_too_long_for_a_run_is_blamed_on_its_file() {
    // No --duration: the file's last time (1e308 s, line 3, column 1) sets the run's length, beyond
    // the 1e7 samples a run may have; the error names the file's cell, not --duration (audit s28 L-7).
    let dir = tempfile::tempdir().unwrap();
    let prof = dir.path().join("big.csv");
    std::fs::write(&prof, "t,r\n0,10\n1e308,20\n").unwrap();
    let spec = format!("file:{}", prof.display());
    let o = ipa_sysid(&["--plant", "paper", "--profile", &spec]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains("big.csv:3:1: the last time t = 1e308 s") && !e.contains("invalid setting"),
        "{e}"
    );
    // With --duration the run's length is the flag's, and the same file runs.
    let o = ipa_sysid(&["--plant", "paper", "--profile", &spec, "--duration", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

/// The `warnings` of a 1 s run of the paper's plant to 5 mm with `extra` flags (JSON on standard output).
fn paper_step_warnings(extra: &[&str]) -> Vec<String> {
    let args = [
        &["--plant", "paper", "--setpoint", "5", "--duration", "1"][..],
        extra,
        &["--json", "-"],
    ]
    .concat();
    let o = ipa_sysid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    v["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect()
}

/// A compensator whose model was estimated on commands far smaller than the loop's limit (a deadzone in
/// another plant's units, e.g. volts on the IPA's PWM counts) is used with a warning that says by how
/// much (audit s11): its data reached |u| ≤ 4.3 against u_max = 255, 255 / 4.3 ≈ 59.30 times.
#[test]
fn a_compensator_from_another_plants_units_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let model = |name: &str, u: &str| {
        let path = dir.path().join(name);
        std::fs::write(
            &path,
            format!(
                r#"{{"format": "ipa-sysid-model", "version": 2, "model": {{"kind": "hammerstein", "ts": 0.01,
                "na": 1, "nb": 1, "nk": 1, "a": [-0.9], "b": [1.0], "offset": null,
                "deadzone": {{"b_l": -0.2, "b_r": 0.1, "m_l": 0.01, "m_r": 0.01}},
                "data_range": {{"u": [{u}], "y": [0.0, 0.25]}}}}}}"#
            ),
        )
        .unwrap();
        path.display().to_string()
    };
    let warnings = |path: &str| paper_step_warnings(&["--compensate-deadzone", path]);
    let volts = warnings(&model("volts.json", "[-4.3, 2.0]"));
    let w = volts
        .iter()
        .find(|w| w.contains("compensator's model was estimated on commands within ±4.3"))
        .unwrap_or_else(|| panic!("{volts:?}"));
    assert!(w.contains(&format!("({:.2}", 255.0 / 4.3)), "{w}");
    let counts = warnings(&model("counts.json", "[-250.0, 240.0]"));
    assert!(
        !counts.iter().any(|w| w.contains("compensator's model")),
        "{counts:?}"
    );
}

/// A `--deadzone-change` at or after the run's end never acts, and the run says so (audit s11): 1 s run,
/// change at 5 s → warned; change at 0.5 s → not.
#[test]
fn a_deadzone_change_after_the_run_is_warned() {
    let warned = |at: &str| {
        paper_step_warnings(&["--deadzone-change", &format!("{at}:20")])
            .iter()
            .any(|w| w.contains("the plant never changes in this run"))
    };
    assert!(warned("5"));
    assert!(!warned("0.5"));
}

// Audit s14 L-l and L-p. A model plant (a first-order model estimated on a tank's volts) has no
// stroke: a start of 1e300 is refused, not run and reported as a diverging loop; its summary names
// the model's own units, not the IPA's mm and counts. Back-calculation with Tt <= Ts/2 diverges (the
// saturated update multiplies I by 1 − Ts/Tt <= −1): refused. A tiny command limit prints as a number.
#[test]
fn control_refuses_nonsense_starts_and_speaks_a_model_plants_units() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("tank.json");
    std::fs::write(
        &model,
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "arx", "ts": 1.0,
        "na": 1, "nb": 1, "nk": 1, "a": [-0.9], "b": [0.05], "offset": null}}"#,
    )
    .unwrap();
    let plant = format!("model:{}", model.display());
    let o = ipa_sysid(&["--plant", &plant, "--setpoint", "6", "--y0", "1e300"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("invalid setting --y0 = 1e300: a finite start within ±1000000"));
    let o = ipa_sysid(&[
        "--plant",
        &plant,
        "--setpoint",
        "6",
        "--y0",
        "4",
        "--duration",
        "200",
        "--kp",
        "2",
        "--ki",
        "0.1",
        "--u-max",
        "10",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
    assert!(text.contains("|u| <= 10 (u's units)"), "{text}");
    assert!(
        text.contains("set-point:    fixed set-point 6 (y's units) from y0 = 4 (y's units)"),
        "{text}"
    );
    assert!(!text.contains(" mm") && !text.contains("counts"), "{text}");
    let o = ipa_sysid(&[
        "--plant",
        "ipa",
        "--setpoint",
        "50",
        "--duration",
        "1",
        "--anti-windup",
        "back-calculation",
        "--tracking-time",
        "0.005",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o)
            .contains("--tracking-time = 0.005: more than half the sampling period (0.005 s)"),
        "{}",
        stderr(&o)
    );
    let o = ipa_sysid(&[
        "--plant",
        "ipa",
        "--setpoint",
        "50",
        "--duration",
        "1",
        "--u-max",
        "1e-300",
    ]);
    let text = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
    assert!(text.contains("|u| <= 1e-300 counts"), "{text}");
}

/// Audit s27 L-6: a model plant identified on a record whose y stayed in about [85, 115] and run from the
/// default y0 = 0 says that the start is outside its data, naming --y0; started inside, it does not.
#[test]
fn a_model_plant_started_outside_its_data_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // y(k) = 0.9 y(k−1) + 10 + 0.01 u(k−1) from y = 100, u a staircase of ±120 (no noise).
    let (mut y, mut u) = (vec![100.0f64], vec![0.0f64]);
    for k in 1..2000 {
        y.push(0.9 * y[k - 1] + 10.0 + 0.01 * u[k - 1]);
        u.push(if (k / 50) % 3 == 0 {
            120.0
        } else if (k / 50) % 3 == 1 {
            -120.0
        } else {
            40.0
        });
    }
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| {
            (l.min(v), h.max(v))
        });
    assert!(lo > 80.0 && hi < 120.0, "{lo} {hi}");
    let data = common::write_tuy(d, "r.csv", 0.01, &u, &y);
    let model = d.join("m.json");
    let fit = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args([
            "identify",
            "--data",
            data.to_str().unwrap(),
            "--structure",
            "arx",
        ])
        .args([
            "--method",
            "ls",
            "--offset",
            "--save-model",
            model.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    assert!(fit.status.success(), "{}", stderr(&fit));
    let plant = format!("model:{}", model.display());
    let run = |y0: &str| {
        let json = d.join(format!("c{y0}.json"));
        let o = ipa_sysid(&[
            "--plant",
            &plant,
            "--setpoint",
            "100",
            "--duration",
            "3",
            "--y0",
            y0,
            "--json",
            json.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let words: Vec<String> = v["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|w| w.as_str().unwrap().to_string())
            .collect();
        (
            String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o),
            words,
        )
    };
    let (text, json) = run("0");
    let said = "the run starts at y0 = 0 (y's units), outside the plant model's estimation data";
    assert!(text.contains(said), "{text}");
    assert!(
        json.iter().any(|w| w.contains(said) && w.contains("--y0")),
        "{json:?}"
    );
    let (text, json) = run("100");
    assert!(!text.contains("the run starts at"), "{text}");
    assert!(
        !json.iter().any(|w| w.contains("the run starts at")),
        "{json:?}"
    );
}
