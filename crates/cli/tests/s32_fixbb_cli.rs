//! Session 32, fixbb (audit s32 LOW findings L-11, L-12, L-1, L-2, L-3, L-4, L-6, L-8): each expectation
//! from a hand-made file, a value computed here, or the words of the rule every other command uses.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

mod common;
use common::{bin, paper_record, run, s, stderr, stdout, write_tuy};

/// A short record of the paper plant (t, u, y at Ts = 0.01 s), 400 samples.
fn record(dir: &Path) -> PathBuf {
    let (u, y) = paper_record(400, 0);
    write_tuy(dir, "rec.csv", 0.01, &u, &y)
}

// ---------------------------------------------------------------------------------------------------
// L-11: `track --ts` by the one rule of every Ts; `--p0` named for its derived --max-trace.

// 1e-300 s is below the 1e-6 s floor of every Ts: track refuses it with identify's own words (the one
// rule), the value in %g form (1e-300, not 300 digits).
#[test]
fn track_refuses_a_ts_below_the_floor_with_identifys_words() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path());
    let t = run(&["track", "--data", s(&data), "--ts", "1e-300"]);
    let i = run(&["identify", "--data", s(&data), "--ts", "1e-300"]);
    let (te, ie) = (stderr(&t), stderr(&i));
    assert!(!t.status.success(), "{te}");
    assert!(!i.status.success(), "{ie}");
    let words = |e: &str| {
        let at = e.find("invalid setting --ts = 1e-300: ").expect(e);
        e[at..].lines().next().unwrap().to_string()
    };
    assert_eq!(words(&te), words(&ie));
    assert!(te.contains("at least 1e-6 s"), "{te}");
    assert!(!te.contains("0.000000000"), "{te}");
    // 1e-3 s is within the rule: accepted.
    let ok = run(&["track", "--data", s(&data), "--ts", "0.01"]);
    assert!(ok.status.success(), "{}", stderr(&ok));
}

// --max-trace defaults to p0 · n; p0 = 1e308 times n >= 2 parameters is inf: the error names --p0,
// the flag the user typed, and says the derived bound is what overflowed.
#[test]
fn track_names_p0_when_its_derived_max_trace_overflows() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path());
    let o = run(&["track", "--data", s(&data), "--p0", "1e308"]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(e.contains("invalid setting --p0 = 1e308"), "{e}");
    assert!(e.contains("--max-trace") && e.contains("= inf"), "{e}");
    assert!(!e.contains("invalid setting --max-trace"), "{e}");
}

// ---------------------------------------------------------------------------------------------------
// L-12: a MAT-file where a model, a controller or a plant configuration goes.

/// A Level 5 MAT-file's 128-byte header (116 bytes of text, subsystem offset, version, endian mark)
/// followed by binary bytes that are not UTF-8: what MATLAB's `save` writes first.
fn mat_file(dir: &Path) -> PathBuf {
    let mut bytes = format!(
        "{:<116}",
        "MATLAB 5.0 MAT-file, Platform: GLNXA64, Created on: Sun Nov 29 05:00:00 2026"
    )
    .into_bytes();
    bytes.extend_from_slice(&[0; 8]);
    bytes.extend_from_slice(&[0x00, 0x01, b'I', b'M']);
    bytes.extend_from_slice(&[0x0f, 0, 0, 0, 0xff, 0xfe, 0x80, 0x81]);
    let p = dir.join("rec.mat");
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn a_mat_file_as_model_controller_or_plant_config_is_named_a_matlab_record() {
    let dir = tempfile::tempdir().unwrap();
    let mat = mat_file(dir.path());
    let data = record(dir.path());
    for args in [
        vec!["validate", "--model", s(&mat), "--data", s(&data)],
        vec![
            "control",
            "--plant",
            "paper",
            "--controller",
            s(&mat),
            "--setpoint",
            "50",
            "--duration",
            "1",
        ],
        vec![
            "control",
            "--plant",
            "ipa",
            "--plant-config",
            s(&mat),
            "--setpoint",
            "50",
            "--duration",
            "1",
        ],
    ] {
        let o = run(&args);
        let e = stderr(&o);
        assert!(!o.status.success(), "{args:?}: {e}");
        assert!(
            e.contains("MATLAB .mat record") && e.contains("give it to --data"),
            "{args:?}: {e}"
        );
        assert!(
            !e.contains("CSV text") && !e.contains("not UTF-8"),
            "{args:?}: {e}"
        );
    }
}

// ---------------------------------------------------------------------------------------------------
// L-1: a controller file's provenance that cannot be read.

/// A controller file (trust_cli's slow integrator) with `provenance` as given (`None`: none).
fn controller(dir: &Path, name: &str, provenance: Option<&str>) -> PathBuf {
    let mut text = String::from(
        r#"{"format": "ipa-sysid-controller", "version": 1, "controller": {
  "ts_s": 0.01, "kp": 10.234389230084679, "ki": 0.10025884372280375, "kd": 0.6542214768665386,
  "derivative_filter_s": 0.02, "u_max": 255.0, "hold_band_mm": 0.02, "fine_band_mm": 3.1774078170190947,
  "reset_on_crossing": true,
  "nudge": {"band_mm": 0.1911648568142366, "ramp_counts_s": 670.9814613425362, "start_fraction": 0.8,
            "rest_samples": 3, "cut_fraction": 0.4084372940142852, "rest_band_mm": 0.19810037930232854},
  "compensator": {"deadzone": {"b_l": -47.31713551774844, "b_r": 37.07152419349243,
                               "m_l": 0.005427574015182067, "m_r": 0.005569272710158329},
                  "slope_mode": "shift", "threshold_counts": 0.0, "u_max": 255.0}}"#,
    );
    if let Some(p) = provenance {
        text.push_str(&format!(",\n \"provenance\": {p}"));
    }
    text.push_str("}\n");
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// The warnings `control --plant paper --controller FILE` prints (it must succeed).
fn control_warnings(file: &Path) -> String {
    let o = run(&[
        "control",
        "--plant",
        "paper",
        "--controller",
        s(file),
        "--setpoint",
        "50",
        "--duration",
        "1",
    ]);
    let e = format!("{}{}", stdout(&o), stderr(&o));
    assert!(o.status.success(), "{e}");
    e
}

// Provenance is optional and free-form (docs/control.md): a wrong-typed meets_spec and a key tune never
// writes are named in one warning, not dropped without a word; a provenance as tune writes it, or none,
// gives no such warning.
#[test]
fn a_malformed_provenance_is_named_in_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let bad = controller(
        dir.path(),
        "bad.json",
        Some(r#"{"meets_spec": "maybe", "x": [1e308, 1e308]}"#),
    );
    let e = control_warnings(&bad);
    assert!(e.contains("provenance cannot be read"), "{e}");
    assert!(
        e.contains("`meets_spec` is the text \"maybe\" (expected true or false)"),
        "{e}"
    );
    assert!(e.contains("`x` is not written by `tune`"), "{e}");
    let not_object = controller(dir.path(), "arr.json", Some("[1, 2]"));
    let e = control_warnings(&not_object);
    assert!(
        e.contains("provenance is not a JSON object but an array of 2 values"),
        "{e}"
    );
    for (name, p) in [
        (
            "good.json",
            Some(
                r#"{"meets_spec": true, "source": "plant paper", "tuned_by": "ipa-sysid tune",
                    "met": {"steps": 4, "of": 4, "on": "the paper plant"},
                    "spec": {"ess_all_mm": 0.05, "ess_mm": 0.02}}"#,
            ),
        ),
        ("none.json", None),
    ] {
        let e = control_warnings(&controller(dir.path(), name, p));
        assert!(!e.contains("provenance cannot be read"), "{name}: {e}");
        assert!(!e.contains("provenance is not"), "{name}: {e}");
    }
}

// ---------------------------------------------------------------------------------------------------
// L-2: `bench narx|oe --peer`: the peer checked before any work; a late failure keeps our results.

/// An executable shell script `dir/name` with `body`.
#[cfg(unix)]
fn script(dir: &Path, name: &str, body: &str) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let p = dir.join(name);
    std::fs::write(&p, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o755)).unwrap();
    p
}

// A missing interpreter, a missing script and a Python without the peer's module are each named, at
// once (an empty data folder: no work would be done anyway; the check comes first).
#[cfg(unix)]
#[test]
fn the_peer_is_checked_before_any_work_naming_what_failed() {
    let dir = tempfile::tempdir().unwrap();
    let data_dir = dir.path().join("data");
    std::fs::create_dir(&data_dir).unwrap();
    let peer_script = dir.path().join("peer.py");
    std::fs::write(&peer_script, "print('{}')\n").unwrap();
    let no_module = script(
        dir.path(),
        "py_without",
        "echo \"ModuleNotFoundError: No module named 'sysidentpy'\" >&2; exit 1",
    );
    let with_module = script(dir.path(), "py_with", "exit 0");
    let missing_python = dir.path().join("no_such_python");
    let missing_script = dir.path().join("no_such_script.py");
    for bench in ["narx", "oe"] {
        let cases: [(&Path, &Path, &[&str], &[&str]); 3] = [
            (
                &missing_python,
                &peer_script,
                &["the interpreter cannot be run"],
                &["script"],
            ),
            (
                &with_module,
                &missing_script,
                &["--peer-script", "is not there"],
                &["interpreter", "import"],
            ),
            (
                &no_module,
                &peer_script,
                &["cannot import sysidentpy", "No module named 'sysidentpy'"],
                &["script", "interpreter cannot"],
            ),
        ];
        for (python, peer, words, never) in cases {
            let o = run(&[
                "bench",
                bench,
                "--repetitions",
                "1",
                "--data-dir",
                s(&data_dir),
                "--peer",
                s(python),
                "--peer-script",
                s(peer),
            ]);
            let e = stderr(&o);
            assert!(!o.status.success(), "{bench}: {e}");
            for w in words {
                assert!(e.contains(w), "{bench} {python:?}: no {w:?} in {e}");
            }
            for w in never {
                assert!(!e.contains(w), "{bench} {python:?}: {w:?} in {e}");
            }
            assert!(stdout(&o).is_empty(), "{bench}: {}", stdout(&o));
        }
    }
}

// A peer that passes the check but fails on its run: our own case's result is printed, the peer's
// failure follows as a warning, --json keeps both, and the exit is non-zero.
#[cfg(unix)]
#[test]
fn a_peer_failing_after_our_work_leaves_our_results_printed() {
    let dir = tempfile::tempdir().unwrap();
    let data_dir = dir.path().join("data");
    std::fs::create_dir_all(data_dir.join("emps")).unwrap();
    // A first-order plant y(k) = 0.9 y(k−1) + 0.1 u(k−1) under a pseudo-random input in [−1, 1),
    // measured with noise of ±0.005 (without it the (6,5,0) regressors are exactly dependent), in the
    // columns of bench oe's EMPS case (t, qm = y, vir = u; Ts = 1 ms).
    let n = 600;
    let mut rng = common::lcg(7);
    let u: Vec<f64> = (0..n).map(|_| 2.0 * rng.unit() - 1.0).collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.9 * y[k - 1] + 0.1 * u[k - 1];
    }
    let mut text = String::from("t,qm,vir\n");
    for k in 0..n {
        let noise = 0.01 * (rng.unit() - 0.5);
        text += &format!("{},{},{}\n", k as f64 * 1e-3, y[k] + noise, u[k]);
    }
    std::fs::write(data_dir.join("emps/DATA_EMPS.csv"), text).unwrap();
    let peer_script = dir.path().join("peer.py");
    std::fs::write(&peer_script, "").unwrap();
    let python = script(
        dir.path(),
        "py",
        "if [ \"$1\" = \"-c\" ]; then exit 0; fi; echo 'peer crashed' >&2; exit 3",
    );
    let json = dir.path().join("b.json");
    let o = run(&[
        "bench",
        "oe",
        "--repetitions",
        "1",
        "--data-dir",
        s(&data_dir),
        "--peer",
        s(&python),
        "--peer-script",
        s(&peer_script),
        "--json",
        s(&json),
    ]);
    let (out, err) = (stdout(&o), stderr(&o));
    assert!(!o.status.success(), "{out}\n{err}");
    assert!(out.contains("emps") && out.contains("600 samples"), "{out}");
    assert!(
        out.contains("warning: the peer failed") && out.contains("peer crashed"),
        "{out}"
    );
    assert!(err.contains("the peer failed"), "{err}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(
        v["peer_failure"].as_str().unwrap().contains("peer crashed"),
        "{v}"
    );
    assert!(v["cases"][0]["output_error"].is_object(), "{v}");
}

// ---------------------------------------------------------------------------------------------------
// L-3: `track --serial` whose other end hangs up.

// A pseudo-terminal pair stands in for the cable; 30 samples, then the master side closes (a USB
// adapter unplugged). No --idle-timeout: the hang-up alone ends the run, with the summary of the 30
// samples, the note, and exit 0 (as a run ended by --idle-timeout).
#[cfg(unix)]
#[test]
fn a_serial_port_that_hangs_up_ends_the_run_with_its_summary() {
    use serialport::SerialPort;
    use std::io::Write;
    use std::os::unix::io::AsRawFd;
    let (mut master, slave) = serialport::TTYPort::pair().unwrap();
    // The master must not be inherited by track (it would then never see the other end close).
    for fd in [master.as_raw_fd(), slave.as_raw_fd()] {
        // SAFETY: fcntl on descriptors this test owns, setting only FD_CLOEXEC.
        assert_eq!(
            unsafe { libc::fcntl(fd, libc::F_SETFD, libc::FD_CLOEXEC) },
            0
        );
    }
    let name = slave.name().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("s.json");
    let mut child = bin()
        .args([
            "track", "--serial", &name, "--baud", "115200", "--every", "10",
        ])
        .args(["--no-detect", "--json", s(&summary)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(400));
    let (u, y) = paper_record(30, 0);
    let mut text = String::from("t,u,y\n");
    for k in 0..30 {
        text += &format!("{},{},{}\n", k as f64 * 0.01, u[k], y[k]);
    }
    master.write_all(text.as_bytes()).unwrap();
    master.flush().unwrap();
    std::thread::sleep(Duration::from_millis(400));
    drop(master);
    drop(slave);
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(20) {
            child.kill().unwrap();
            panic!("track still running 20 s after the hang-up");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let o = child.wait_with_output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{e}");
    assert!(
        e.contains("the serial port hung up after 30 samples"),
        "{e}"
    );
    assert!(e.contains("30 samples, "), "{e}");
    assert!(!e.contains("Broken pipe") && !e.contains("error"), "{e}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(v["samples"].as_u64(), Some(30), "{v}");
    assert!(v["model"].is_object(), "{v}");
}

// ---------------------------------------------------------------------------------------------------
// L-4: a NARX model whose one-step prediction overflows; `validate --out` cells; a lag too long.

/// A NARX model file with the terms `(term, coefficient)` (na = nb = 1, nk = 1, degree 1, Ts 0.01 s).
fn narx_file(dir: &Path, name: &str, terms: &[(&str, &str)]) -> PathBuf {
    let terms: Vec<String> = terms
        .iter()
        .map(|(t, c)| format!("{{\"term\": \"{t}\", \"coefficient\": {c}}}"))
        .collect();
    let text = format!(
        "{{\"format\": \"ipa-sysid-model\", \"version\": 3, \"model\": {{\"kind\": \"narx\", \
         \"ts\": 0.01, \"na\": 1, \"nb\": 1, \"nk\": 1, \"degree\": 1, \"terms\": [{}]}}}}\n",
        terms.join(", ")
    );
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A record `t,u,y` of 200 samples, |u| = 1, y(k) = 0.5 y(k−1) + u(k−1), Ts = 0.01 s.
fn small_record(dir: &Path) -> (PathBuf, Vec<f64>) {
    let n = 200;
    let u: Vec<f64> = (0..n)
        .map(|k| if (k / 7) % 2 == 0 { 1.0 } else { -1.0 })
        .collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.5 * y[k - 1] + u[k - 1];
    }
    (write_tuy(dir, "small.csv", 0.01, &u, &y), y)
}

// θ = 1e300 on y(k−1): each term 1e300 · |y(k−1)| is beyond √(f64::MAX / N), so the squared errors
// overflow: a numerical failure (exit 1) naming the term and its coefficient, as for an ARX file.
#[test]
fn a_narx_coefficient_that_overflows_the_prediction_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let (data, y) = small_record(dir.path());
    let model = narx_file(
        dir.path(),
        "big.json",
        &[("y(k-1)", "1e300"), ("u(k-1)", "1")],
    );
    let o = run(&["validate", "--model", s(&model), "--data", s(&data)]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    // The largest term: 1e300 times the largest |y(k−1)| over k >= k0 = 1.
    let y_max = y[..y.len() - 1].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let size = format!("{:e}", 1e300 * y_max);
    assert!(
        e.contains("the term y(k-1) with coefficient 1e300 (the file's \"terms\"[0])")
            && e.contains(&size),
        "{size}: {e}"
    );
    assert!(!e.contains("inf"), "{e}");
}

// θ = 1e100 on y(k−1) does not overflow: y_pred = 1e100 · y(k−1) + u(k−1), written in %g form (a
// short cell that reads back to the value computed here), never as a 100-digit decimal.
#[test]
fn validate_out_cells_are_in_shortest_form() {
    let dir = tempfile::tempdir().unwrap();
    let (data, y) = small_record(dir.path());
    let model = narx_file(
        dir.path(),
        "big100.json",
        &[("y(k-1)", "1e100"), ("u(k-1)", "1")],
    );
    let out = dir.path().join("v.csv");
    let o = run(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(&out).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "y_pred").unwrap();
    let u = |k: usize| if (k / 7) % 2 == 0 { 1.0 } else { -1.0 };
    let mut checked = 0;
    for (k, line) in lines.enumerate() {
        for cell in line.split(',') {
            assert!(cell.len() <= 26, "line {}: {cell}", k + 2);
        }
        if k >= 1 {
            let want = 1e100 * y[k - 1] + u(k - 1);
            let got: f64 = line.split(',').nth(col).unwrap().parse().unwrap();
            assert!(
                (got - want).abs() <= 1e-12 * want.abs(),
                "{k}: {got} {want}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 199);
}

// u(k−100000) is a lagged variable: its lag is what is wrong (beyond 2 · 100, the longest of any model).
#[test]
fn a_lag_beyond_every_model_is_said_as_such() {
    let dir = tempfile::tempdir().unwrap();
    let (data, _) = small_record(dir.path());
    let model = narx_file(dir.path(), "lag.json", &[("u(k-100000)", "1")]);
    let o = run(&["validate", "--model", s(&model), "--data", s(&data)]);
    let e = stderr(&o);
    assert!(!o.status.success(), "{e}");
    assert!(
        e.contains("'u(k-100000)': its lag 100000 is outside the model's orders"),
        "{e}"
    );
    assert!(!e.contains("not a lagged variable"), "{e}");
}

// ---------------------------------------------------------------------------------------------------
// L-6: a widening that leaves no command outside the deadzone.

// With Δ >= u_max = 255 every command |u| <= 255 lies in the widened deadzone |u| <= Δ: no command
// moves the plant, said in a warning; Δ = 254 leaves |u| in (254, 255], so no such warning.
#[test]
fn a_deadzone_change_of_at_least_u_max_is_said() {
    for (change, said) in [("1:1e300", true), ("1:255", true), ("1:254", false)] {
        let o = run(&[
            "control",
            "--plant",
            "paper",
            "--setpoint",
            "50",
            "--duration",
            "2",
            "--deadzone-change",
            change,
        ]);
        let e = format!("{}{}", stdout(&o), stderr(&o));
        assert!(o.status.success(), "{change}: {e}");
        assert_eq!(
            e.contains("no command can move the plant"),
            said,
            "{change}: {e}"
        );
        assert!(!e.contains("0000000000"), "{change}: {e}");
    }
}

// ---------------------------------------------------------------------------------------------------
// L-8: a ratio in %g form; a linear plant's rounding-noise breakpoint.

// The file's times step 0.05 s, the paper plant runs at 0.01 s: 0.01 / 0.05 = 0.2 (not the f64
// quotient's 0.19999999999999998).
#[test]
fn the_replay_ratio_is_printed_in_short_form() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in_t.csv");
    std::fs::write(&input, "t,u\n0,1\n0.05,2\n").unwrap();
    let arg = format!("file:{}", s(&input));
    let o = run(&[
        "simulate",
        "--plant",
        "paper",
        "--input",
        &arg,
        "--out",
        s(&dir.path().join("o.csv")),
    ]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(
        e.contains("replayed 0.2 times as far apart as recorded"),
        "{e}"
    );
    assert!(!e.contains("0.19999"), "{e}");
}

// A linear ARX plant has no deadzone: the identified breakpoints are rounding noise around 0 (one of
// them of either sign), within 1e-9 · u_max of it: the tuned controller runs, with no "deadzone around
// u = 0" refusal.
#[test]
fn a_linear_plant_runs_the_tuned_controller() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json");
    std::fs::write(
        &model,
        r#"{"format": "ipa-sysid-model", "version": 3, "model": {"kind": "arx", "ts": 0.1,
            "na": 1, "nb": 1, "nk": 1, "a": [-0.9001719937555707], "b": [0.4998227350064692],
            "offset": null}}"#,
    )
    .unwrap();
    let out = dir.path().join("rp");
    let plant = format!("model:{}", s(&model));
    let o = run(&["reproduce", "--plant", &plant, "--out", s(&out)]);
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    let summary = std::fs::read_to_string(out.join("summary.json")).unwrap();
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    for text in [&summary, &report, &e] {
        assert!(!text.contains("a deadzone around u = 0"), "{text}");
        assert!(!text.contains("tuned controller was not run"), "{text}");
    }
}
