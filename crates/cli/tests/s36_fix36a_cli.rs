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

/// y(k) = 0.9 y(k−1) + 0.5 u(k−1) (noise-free), u a ±1 pattern, both then multiplied by `scale_u` and
/// `scale_y`: ARX(1, 1, 1) by LS recovers a1 = −0.9 and b1 = 0.5 · scale_y / scale_u exactly.
fn scaled_first_order(
    dir: &std::path::Path,
    name: &str,
    scale_u: f64,
    scale_y: f64,
) -> std::path::PathBuf {
    let n = 400;
    let u: Vec<f64> = (0..n)
        .map(|k| if (k * 37 + 11) % 7 < 3 { 1.0 } else { -1.0 })
        .collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.9 * y[k - 1] + 0.5 * u[k - 1];
    }
    let u: Vec<f64> = u.iter().map(|v| v * scale_u).collect();
    let y: Vec<f64> = y.iter().map(|v| v * scale_y).collect();
    write_tuy(dir, name, 0.01, &u, &y)
}

/// Audit s35 H-2: an output of ~1e-168 made RLS return a1 = a2 = 0 and a wrong b with RMSE 0, loss 0,
/// every fit n/a and no warning (the squares of the signals underflow f64). A signal whose largest
/// magnitude is below 1e-140 (its squares below 1e-280) is now refused by every estimator, the delay
/// search and NARX, naming the signal and the power of ten that rescales it; at 1e-130 the estimate is
/// still exact. y here is at most 5 (|y| ≤ 0.5/(1 − 0.9)), so y × 1e-170 is at most 5e-170 and the
/// factor that brings it to order 1 is 1e170 (5e-170 · 1e170 = 5); likewise u × 1e-200 (|u| = 1).
#[test]
fn a_signal_too_small_for_its_squares_is_refused_with_the_factor_that_rescales_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let tiny_y = scaled_first_order(d, "tiny_y.csv", 1.0, 1e-170);
    let tiny_u = scaled_first_order(d, "tiny_u.csv", 1e-200, 1.0);
    let arx = |f: &std::path::Path, method: &str| {
        let mut a: Vec<String> = [
            "identify",
            "--data",
            s(f),
            "--structure",
            "arx",
            "--na",
            "1",
            "--nb",
            "1",
            "--method",
        ]
        .iter()
        .map(|x| x.to_string())
        .collect();
        a.push(method.into());
        a
    };
    let mut runs: Vec<(Vec<String>, &str, &str)> = Vec::new();
    for m in ["rls", "ls", "oe", "iv"] {
        runs.push((
            arx(&tiny_y, m),
            "the output y is at most",
            "multiply it by 1e170",
        ));
        runs.push((
            arx(&tiny_u, m),
            "the input u is at most",
            "multiply it by 1e200",
        ));
    }
    let mut streamed = arx(&tiny_y, "ls");
    streamed.extend(["--stream".to_string(), "on".to_string()]);
    runs.push((streamed, "the output y is at most", "multiply it by 1e170"));
    for what in [vec!["delay"], vec!["identify", "--structure", "narx"]] {
        let mut a: Vec<String> = what.iter().map(|x| x.to_string()).collect();
        a.extend(["--data".to_string(), s(&tiny_y).to_string()]);
        runs.push((a, "the output y is at most", "multiply it by 1e170"));
    }
    for (args, what, factor) in &runs {
        let out = bin().args(args).output().unwrap();
        let e = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {e}");
        assert!(e.contains(what) && e.contains(factor), "{args:?}: {e}");
        assert!(e.contains("rescale"), "{e}");
    }
    // At 1e-130 (squares 1e-260, normal) the estimate is the exact one: a1 = −0.9, b1 = 0.5e-130.
    let small = scaled_first_order(d, "small.csv", 1.0, 1e-130);
    let mut a = arx(&small, "ls");
    a.extend(["--json".to_string(), "-".to_string()]);
    let out = bin().args(&a).output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let a1 = doc["model"]["a"][0].as_f64().unwrap();
    let b1 = doc["model"]["b"][0].as_f64().unwrap();
    assert!((a1 + 0.9).abs() < 1e-9, "{a1}");
    assert!((b1 / 0.5e-130 - 1.0).abs() < 1e-9, "{b1}");
}

/// Audit s35 M-2: a record cut inside its last number (`0.82,242,10` for `…,107.99139766052642`) was
/// read with the cut value, silently. A file that ends without a line end whose last cell has fewer
/// digits than each of the same column's ten cells before it now gets a note naming that cell's line
/// and column, in memory and under `--stream on` (same words); the same file with its line end, and a
/// complete last row without one (as two shared real records end), get none. The record: y(k) =
/// 100 + 10 sin(k/5) + k/1000 printed with Rust's shortest round-trip digits (13 to 17 of them for these
/// values), 200 rows, so the cut last row `1.99,...,10` (line 201: the header is line 1, column 3)
/// has 2 digits against at least 13.
#[test]
fn a_record_cut_inside_its_last_number_is_noted_at_that_cell() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u: Vec<f64> = (0..200)
        .map(|k| if (k / 7) % 2 == 0 { 50.0 } else { -50.0 })
        .collect();
    let y: Vec<f64> = (0..200)
        .map(|k| 100.0 + 10.0 * (k as f64 / 5.0).sin() + k as f64 / 1000.0)
        .collect();
    let whole = write_tuy(d, "whole.csv", 0.01, &u, &y);
    let text = std::fs::read_to_string(&whole).unwrap();
    let body = text.trim_end_matches('\n');
    let last_line = body.lines().last().unwrap();
    let (head, last_y) = last_line.rsplit_once(',').unwrap();
    assert!(
        last_y.chars().filter(char::is_ascii_digit).count() >= 13,
        "{last_y}"
    );
    let cut_text = format!("{}{head},10", &body[..body.len() - last_line.len()]);
    let cut = d.join("cut.csv");
    std::fs::write(&cut, &cut_text).unwrap();
    let unterminated = d.join("unterminated.csv");
    std::fs::write(&unterminated, body).unwrap();
    let run = |f: &std::path::Path, stream: &str| {
        let out = bin()
            .args(["identify", "--data", s(f), "--structure", "arx"])
            .args([
                "--na", "1", "--nb", "1", "--method", "ls", "--stream", stream,
            ])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        // The report's warnings are printed with it (stdout), the reader's first ones on stderr.
        format!("{}{}", String::from_utf8_lossy(&out.stdout), stderr(&out))
    };
    let mut said = Vec::new();
    for stream in ["off", "on"] {
        let e = run(&cut, stream);
        let note = e
            .lines()
            .find(|l| l.contains("may have been cut"))
            .unwrap_or_else(|| panic!("{stream}: no note: {e}"))
            .to_string();
        assert!(note.contains("cut.csv:201:3:"), "{note}");
        assert!(note.contains("y = 10 there has 2 digit(s)"), "{note}");
        said.push(note);
        for f in [&whole, &unterminated] {
            let e = run(f, stream);
            assert!(!e.contains("may have been cut"), "{stream} {f:?}: {e}");
        }
    }
    assert_eq!(said[0], said[1]);
}

/// fix35's known gap: in a comma-delimited file whose decimal commas are quoted, one row that wrote
/// its `0,5` unquoted split it into two cells and, under a header wide enough (an unused `note` column
/// here), was read as u = 0 and y = 5. Now refused at its line and column (row k = 30 is line 32: the
/// header is line 1; u is column 2), in memory and under `--stream on`; the same file with that cell
/// quoted is read.
#[test]
fn an_unquoted_decimal_comma_in_a_file_of_quoted_ones_is_refused_at_its_cell() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let write = |name: &str, bare: bool| {
        let mut text = String::from("t,u,y,note\n");
        for k in 0..60 {
            let t = format!("{:.2}", k as f64 / 100.0).replace('.', ",");
            let u = format!("{:.1}", 50.0 * (k as f64 / 3.0).sin()).replace('.', ",");
            let y = format!("{:.3}", 10.0 + 5.0 * (k as f64 / 4.0).sin()).replace('.', ",");
            if k == 30 && bare {
                text.push_str(&format!("\"{t}\",0,5,\"{y}\"\n"));
            } else if k == 30 {
                text.push_str(&format!("\"{t}\",\"0,5\",\"{y}\",\n"));
            } else {
                text.push_str(&format!("\"{t}\",\"{u}\",\"{y}\",\n"));
            }
        }
        let path = d.join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let bad = write("bare.csv", true);
    let good = write("quoted.csv", false);
    for stream in ["off", "on"] {
        let run = |f: &std::path::Path| {
            bin()
                .args(["identify", "--data", s(f), "--structure", "arx"])
                .args([
                    "--na", "1", "--nb", "1", "--method", "ls", "--stream", stream,
                ])
                .output()
                .unwrap()
        };
        let out = run(&bad);
        let e = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{stream}: {e}");
        assert!(e.contains("bare.csv:32:2: '0,5' reads as two cells"), "{e}");
        let out = run(&good);
        assert!(out.status.success(), "{stream}: {}", stderr(&out));
    }
}

/// Audit s35 L-1: a NARX model file's ts was not bounded as every other model file's is (1e300 and
/// 1e-300 were simulated, at t = 0, 1e300, 2e300, ...). Now the one bound of model files, 1e-6 s to 1e9
/// s, refuses both, naming ts; the file as written (ts = 0.01) simulates.
#[test]
fn a_narx_model_files_sampling_period_has_the_bounds_of_every_model_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let u: Vec<f64> = (0..400)
        .map(|k| 50.0 * ((k as f64) / 9.0).sin() + 30.0 * ((k as f64) / 4.0).cos())
        .collect();
    let mut y = vec![0.0; 400];
    for k in 1..400 {
        y[k] = 0.8 * y[k - 1] + 0.02 * u[k - 1] + 0.001 * u[k - 1] * u[k - 1];
    }
    let data = write_tuy(d, "narx.csv", 0.01, &u, &y);
    let model = d.join("m.json");
    let out = bin()
        .args(["identify", "--data", s(&data), "--structure", "narx"])
        .args(["--save-model", s(&model)])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&model).unwrap();
    assert!(text.contains("\"ts\": 0.01"), "{text}");
    let simulate = |m: &std::path::Path| {
        let plant = format!("model:{}", s(m));
        bin()
            .args(["simulate", "--plant", &plant, "--samples", "20", "--out"])
            .arg(d.join("sim.csv"))
            .output()
            .unwrap()
    };
    assert!(simulate(&model).status.success());
    for (ts, words) in [("1e300", "above 1e9 s"), ("1e-300", "below 1e-6 s")] {
        let bad = d.join(format!("ts{ts}.json"));
        std::fs::write(&bad, text.replace("\"ts\": 0.01", &format!("\"ts\": {ts}"))).unwrap();
        let out = simulate(&bad);
        let e = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{ts}: {e}");
        assert!(e.contains(&format!("ts = {ts} s is {words}")), "{e}");
    }
}

/// The model's parameters of `identify --structure arx --na 2 --nb 2 --method ls` on `data` (column
/// names `u_col`, `y_col`, `--ts 4`), from its `--json` report.
fn arx_parameters(
    dir: &std::path::Path,
    data: &std::path::Path,
    u_col: &str,
    y_col: &str,
) -> String {
    let doc = common::run_json(
        dir,
        &[
            "identify",
            "--data",
            s(data),
            "--u-col",
            u_col,
            "--y-col",
            y_col,
            "--ts",
            "4",
            "--structure",
            "arx",
            "--na",
            "2",
            "--nb",
            "2",
            "--method",
            "ls",
        ],
    );
    doc["model"].to_string()
}

/// Audit s37 H-1: the check above refused a valid file. A European logger writes the time in ms and
/// the input in counts as bare integers, the output with a quoted decimal comma, and fills an optional
/// column on one row (`Ts` on the first, as the cascaded tanks' file does): that row has more filled
/// cells than the others and starts with two bare integers (`0,33`), which were taken for a split
/// number. Columns of bare integers hold them on every row, so they are no sign of a split: the file is
/// read, and gives the model of the same numbers written with points and no optional column.
#[test]
fn bare_integer_columns_beside_quoted_decimal_commas_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (mut eu, mut plain) = (
        String::from("t_ms,u_counts,\"y\",\"Ts\"\n"),
        String::from("t_ms,u_counts,y\n"),
    );
    let mut y = [5.0f64, 5.0];
    for k in 0..300usize {
        let u = 30 + ((k * 7919) % 13) as i64 - 6 + if (k / 20) % 2 == 0 { 0 } else { 10 };
        let yk = 1.5 * y[0] - 0.6 * y[1] + 0.01 * u as f64 + 0.001 * ((k * 31) % 7) as f64;
        y = [yk, y[0]];
        let yt = format!("{yk:.4}");
        let t = 4000 * k;
        let ts = if k == 0 { "4" } else { "" };
        eu.push_str(&format!("{t},{u},\"{}\",{ts}\n", yt.replace('.', ",")));
        plain.push_str(&format!("{t},{u},{yt}\n"));
    }
    let (eu_path, plain_path) = (d.join("eu.csv"), d.join("plain.csv"));
    std::fs::write(&eu_path, eu).unwrap();
    std::fs::write(&plain_path, plain).unwrap();
    assert_eq!(
        arx_parameters(d, &eu_path, "u_counts", "y"),
        arx_parameters(d, &plain_path, "u_counts", "y")
    );
}

/// Audit s37 M-3: a CSV whose header's first name holds `=` (`V1=in,V2=out`) was refused as "TOML text"
/// (session 36's sniffing of a first line `key = value` with commas). Read as CSV: the same model as the
/// same rows under the header `u,y`.
#[test]
fn a_csv_header_with_an_equals_sign_is_read_as_csv() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut rows = String::new();
    let mut y = [0.0f64, 0.0];
    for k in 0..300usize {
        let u = if (k / 15) % 2 == 0 { 1.0 } else { -1.0 } + 0.1 * ((k * 13) % 5) as f64;
        let yk = 1.2 * y[0] - 0.5 * y[1] + 0.3 * u;
        y = [yk, y[0]];
        rows.push_str(&format!("{u},{yk}\n"));
    }
    let (eq_path, plain_path) = (d.join("eq.csv"), d.join("plain.csv"));
    std::fs::write(&eq_path, format!("V1=in,V2=out\n{rows}")).unwrap();
    std::fs::write(&plain_path, format!("u,y\n{rows}")).unwrap();
    assert_eq!(
        arx_parameters(d, &eq_path, "V1=in", "V2=out"),
        arx_parameters(d, &plain_path, "u", "y")
    );
}
