//! Data workflow through the binary (issue 13): row ranges, detrending, time units and resampling,
//! header-less files, written predictions. Every expectation is computed here, independently of the
//! library (plain loops and closed-form least squares).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic
#![allow(clippy::needless_range_loop)] // the expectations index signals as the equations do

use std::path::{Path, PathBuf};
use std::process::Output;

mod common;
use common::{bin, json, s};

fn run(args: &[&str]) -> Output {
    let out = bin().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn num(v: &serde_json::Value) -> f64 {
    v.as_f64().unwrap()
}

/// A deterministic, persistently exciting input (a sum of incommensurate sines plus a ramp of levels).
fn input(n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let k = k as f64;
            (0.37 * k).sin()
                + 0.6 * (1.91 * k).sin()
                + 0.3 * (0.053 * k).cos()
                + ((k / 7.0).floor() % 3.0)
        })
        .collect()
}

/// y(k) = -a y(k-1) + b u(k-1) + c from y(0) = y_init.
fn arx1(u: &[f64], a: f64, b: f64, c: f64, y_init: f64) -> Vec<f64> {
    let mut y = vec![y_init; u.len()];
    for k in 1..u.len() {
        y[k] = -a * y[k - 1] + b * u[k - 1] + c;
    }
    y
}

fn write_uy(path: &Path, u: &[f64], y: &[f64]) {
    let mut t = String::from("u,y\n");
    for (a, b) in u.iter().zip(y) {
        t.push_str(&format!("{a},{b}\n"));
    }
    std::fs::write(path, t).unwrap();
}

/// Least squares of z(k) = θ1 p(k) + θ2 q(k) by the 2x2 normal equations.
fn ls2(z: &[f64], p: &[f64], q: &[f64]) -> (f64, f64) {
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let (pp, pq, qq, pz, qz) = (dot(p, p), dot(p, q), dot(q, q), dot(p, z), dot(q, z));
    let det = pp * qq - pq * pq;
    ((qq * pz - pq * qz) / det, (pp * qz - pq * pz) / det)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

/// Fit % = 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) (MATLAB `compare`).
fn fit_pct(y: &[f64], yhat: &[f64]) -> f64 {
    let m = mean(y);
    let e: f64 = y
        .iter()
        .zip(yhat)
        .map(|(a, b)| (a - b).powi(2))
        .sum::<f64>()
        .sqrt();
    let d: f64 = y.iter().map(|a| (a - m).powi(2)).sum::<f64>().sqrt();
    100.0 * (1.0 - e / d)
}

/// The free-run simulation of a first-order model (pole `pole`, k0 = 1) from the estimated initial output
/// (MATLAB `compare`'s default), given its simulation `measured` from the measured y(0): ŷ(k; η) =
/// ŷ_m(k) + pole^k (η − y(0)), and δ = η − y(0) minimises Σ_k (y(k) − ŷ_m(k) − pole^k δ)², so
/// δ = Σ pole^k r(k) / Σ pole^2k with r = y − ŷ_m (r(0) = 0).
fn estimated_initial_first_order(y: &[f64], measured: &[f64], pole: f64) -> Vec<f64> {
    let s: Vec<f64> = (0..y.len()).map(|k| pole.powi(k as i32)).collect();
    let num: f64 = (0..y.len()).map(|k| s[k] * (y[k] - measured[k])).sum();
    let den: f64 = s.iter().map(|v| v * v).sum();
    let delta = num / den;
    (0..y.len()).map(|k| measured[k] + s[k] * delta).collect()
}

/// Runs a command that must fail with exit code 2 (bad usage or input) without a panic; its stderr.
/// A parameter's name as the text report prints it: `b_l`, or `b_l (u1)` with its input.
fn label(p: &serde_json::Value) -> String {
    match p["input"].as_str() {
        Some(i) => format!("{} ({i})", p["name"].as_str().unwrap()),
        None => p["name"].as_str().unwrap().to_string(),
    }
}

/// A command's standard output then its standard error, as text (warnings go to either).
fn stdout_and_stderr(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn fails(args: &[&str]) -> String {
    let out = bin().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr).to_string();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    err
}

fn identify_json(extra: &[&str], out: &Path) -> serde_json::Value {
    let mut args = vec![
        "identify", "--model", "arx", "--method", "ls", "--na", "1", "--nb", "1", "--nk", "1",
        "--ts", "0.1", "--json",
    ];
    args.push(s(out));
    args.extend_from_slice(extra);
    run(&args);
    json(out)
}

#[test]
fn rows_select_the_estimation_part_and_val_rows_the_validation_part() {
    let dir = tempfile::tempdir().unwrap();
    // Rows 0..300 follow y = 0.7 y(k-1) + 2 u(k-1); rows 300.. another system entirely.
    let u = input(500);
    let mut y = arx1(&u[..300], -0.7, 2.0, 0.0, 0.0);
    let tail = arx1(&u[300..], 0.4, -1.0, 3.0, y[299]);
    y.extend(tail);
    let f = dir.path().join("two.csv");
    write_uy(&f, &u, &y);
    let out = dir.path().join("r.json");

    let j = identify_json(
        &["--data", s(&f), "--rows", "0..300", "--val-rows", "..300"],
        &out,
    );
    let a1 = num(&j["model"]["a"][0]);
    let b1 = num(&j["model"]["b"][0]);
    assert!(
        (a1 + 0.7).abs() < 1e-9 && (b1 - 2.0).abs() < 1e-9,
        "a1 {a1} b1 {b1}"
    );
    // N = rows used = 300 - k0 (k0 = 1) on both records; the validation is the same system: fit 100 %.
    assert_eq!(j["metrics"]["estimation"]["n"], 299);
    assert_eq!(j["metrics"]["validation"]["n"], 299);
    assert!(num(&j["metrics"]["validation"]["fit_sim_percent"]) > 99.999);

    // The same flags without --rows mix the two systems: the estimate is not the first one.
    let j = identify_json(&["--data", s(&f)], &out);
    assert!((num(&j["model"]["a"][0]) + 0.7).abs() > 1e-3);

    // `A..` runs to the end; validation rows of the second system give a poor fit.
    let j = identify_json(
        &["--data", s(&f), "--rows", "..300", "--val-rows", "300.."],
        &out,
    );
    assert_eq!(j["metrics"]["validation"]["n"], 199);
    assert!(num(&j["metrics"]["validation"]["fit_sim_percent"]) < 90.0);

    // --split 0.6 of 500 rows: 300 estimation rows (the first system, exact), 200 validation rows.
    let j = identify_json(&["--data", s(&f), "--split", "0.6"], &out);
    assert!((num(&j["model"]["a"][0]) + 0.7).abs() < 1e-9);
    assert_eq!(j["metrics"]["estimation"]["n"], 299);
    assert_eq!(j["metrics"]["validation"]["n"], 199);
}

#[test]
fn bad_row_ranges_are_refused_with_the_flag_and_what_was_expected() {
    let dir = tempfile::tempdir().unwrap();
    let u = input(50);
    let y = arx1(&u, -0.5, 1.0, 0.0, 0.0);
    let f = dir.path().join("d.csv");
    write_uy(&f, &u, &y);
    for (flag, value, want) in [
        ("--rows", "10..5", "A..B"),
        ("--rows", "0..51", "inside the 50 data rows"),
        ("--rows", "x", "A..B"),
        ("--val-rows", "40..60", "inside the 50 data rows"),
        ("--split", "1.5", "0 < F < 1"),
    ] {
        let out = fails(&[
            "identify",
            "--data",
            s(&f),
            "--ts",
            "1",
            "--model",
            "arx",
            flag,
            value,
        ]);
        let err = out;
        assert!(
            err.contains(want) && !err.contains("panicked"),
            "{flag} {value}: {err}"
        );
    }
}

#[test]
fn detrend_mean_identifies_deviations_and_puts_the_operating_point_back() {
    let dir = tempfile::tempdir().unwrap();
    let n = 400;
    let u: Vec<f64> = input(n).iter().map(|v| 100.0 + 5.0 * v).collect();
    // Around (u, y) = (100, 50): y - 50 = 0.8 (y(k-1) - 50) + 0.3 (u(k-1) - 100), plus a small wobble so
    // that the data are not exactly ARX in the record's own means.
    let mut y = vec![50.0; n];
    for k in 1..n {
        y[k] = 50.0
            + 0.8 * (y[k - 1] - 50.0)
            + 0.3 * (u[k - 1] - 100.0)
            + 0.05 * (0.7 * k as f64).sin();
    }
    let f = dir.path().join("op.csv");
    write_uy(&f, &u, &y);
    let model = dir.path().join("m.json");
    let out = dir.path().join("r.json");
    for how in ["mean", "linear"] {
        let j = identify_json(
            &["--data", s(&f), "--detrend", how, "--save-model", s(&model)],
            &out,
        );
        // Independent: remove the mean (and for `linear` the least-squares line) of each signal, then
        // least squares of y'(k) on -y'(k-1), u'(k-1).
        let remove = |v: &[f64]| -> Vec<f64> {
            let m = mean(v);
            let kbar = (v.len() as f64 - 1.0) / 2.0;
            let slope = if how == "linear" {
                let num: f64 = v
                    .iter()
                    .enumerate()
                    .map(|(k, x)| (k as f64 - kbar) * (x - m))
                    .sum();
                let den: f64 = (0..v.len()).map(|k| (k as f64 - kbar).powi(2)).sum();
                num / den
            } else {
                0.0
            };
            v.iter()
                .enumerate()
                .map(|(k, x)| x - m - slope * (k as f64 - kbar))
                .collect()
        };
        let (ud, yd) = (remove(&u), remove(&y));
        let z = &yd[1..];
        let p: Vec<f64> = yd[..n - 1].iter().map(|v| -v).collect();
        let (a1, b1) = ls2(z, &p, &ud[..n - 1]);
        let got_a = num(&j["model"]["a"][0]);
        let got_b = num(&j["model"]["b"][0]);
        assert!(
            (got_a - a1).abs() < 1e-9 && (got_b - b1).abs() < 1e-9,
            "{how}: {got_a} {got_b} vs {a1} {b1}"
        );
        let op = &j["model"]["operating_point"];
        assert!((num(&op["u"][0]) - mean(&u)).abs() < 1e-9, "{how}: {op}");
        assert!((num(&op["y"]) - mean(&y)).abs() < 1e-9, "{how}: {op}");
        assert_eq!(j["detrend"], how);
        // The saved model carries the operating point (version 2's field; the file is version 3
        // since it also records its identification, audit s20 M-3).
        let m = json(&model);
        assert_eq!(m["version"], 3);
        assert_eq!(m["model"]["operating_point"], *op);

        // validate --out: y_sim in the user's units = y0 + the deviation model run on u - u0.
        let csv = dir.path().join(format!("o_{how}.csv"));
        run(&[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&f),
            "--ts",
            "0.1",
            "--out",
            s(&csv),
        ]);
        let (u0, y0) = (mean(&u), mean(&y));
        let mut measured = vec![y[0]; n];
        for k in 1..n {
            measured[k] = y0 - a1 * (measured[k - 1] - y0) + b1 * (u[k - 1] - u0);
        }
        // From the estimated initial output, as the reported fit (the free response is that of 1/A).
        let sim = estimated_initial_first_order(&y, &measured, -a1);
        let got = read_columns(&csv);
        for k in 0..n {
            assert!(
                (got["y_sim"][k] - sim[k]).abs() < 1e-7,
                "{how} k = {k}: {} vs {}",
                got["y_sim"][k],
                sim[k]
            );
            // From the measured initial output y(0): the recursion above (audit s24 M-2).
            assert!(
                (got["y_sim_y0meas"][k] - measured[k]).abs() < 1e-7,
                "{how} k = {k}: {} vs {}",
                got["y_sim_y0meas"][k],
                measured[k]
            );
        }
    }
    // simulate with the (last, linear-detrended) model as the plant: from rest at y0 with u = u0 + 2 from
    // sample 0, y - y0 follows the deviation model driven by 2.
    let m = json(&model);
    let (a1, b1) = (num(&m["model"]["a"][0]), num(&m["model"]["b"][0]));
    let (u0, y0) = (mean(&u), mean(&y));
    let sim = dir.path().join("sim.csv");
    let plant = format!("model:{}", s(&model));
    let (step, start) = (format!("step:{}@0", u0 + 2.0), format!("{y0}"));
    run(&[
        "simulate",
        "--plant",
        &plant,
        "--input",
        &step,
        "--samples",
        "30",
        "--y0",
        &start,
        "--out",
        s(&sim),
    ]);
    let got = read_columns(&sim);
    let mut dev = 0.0;
    for k in 0..30 {
        assert!(
            (got["y"][k] - (y0 + dev)).abs() < 1e-7,
            "k = {k}: {} vs {}",
            got["y"][k],
            y0 + dev
        );
        dev = -a1 * dev + b1 * 2.0;
    }
    // Without --detrend the JSON has no operating point and no detrend key (today's keys).
    let j = identify_json(&["--data", s(&f)], &out);
    assert!(j["model"].get("operating_point").is_none() && j.get("detrend").is_none());
}

/// The columns of a CSV written by `validate --out` (empty cells as NaN).
fn read_columns(path: &Path) -> std::collections::HashMap<String, Vec<f64>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let names: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    let mut cols: std::collections::HashMap<String, Vec<f64>> =
        names.iter().map(|n| (n.clone(), Vec::new())).collect();
    for rec in r.records() {
        let rec = rec.unwrap();
        for (name, cell) in names.iter().zip(rec.iter()) {
            cols.get_mut(name)
                .unwrap()
                .push(cell.parse().unwrap_or(f64::NAN));
        }
    }
    cols
}

/// A version-1 model file (the format before operating points) of y = 0.8 y(k-1) + 0.5 u(k-1) + 0.1.
fn v1_model(dir: &Path, ts: f64) -> PathBuf {
    let p = dir.join("v1.json");
    std::fs::write(
        &p,
        format!(
            r#"{{"format": "ipa-sysid-model", "version": 1, "model": {{"kind": "arx", "ts": {ts}, "na": 1,
            "nb": 1, "nk": 1, "a": [-0.8], "b": [0.5], "offset": 0.1}}}}"#
        ),
    )
    .unwrap();
    p
}

#[test]
fn validate_out_writes_simulation_and_k_step_prediction() {
    let dir = tempfile::tempdir().unwrap();
    let n = 120;
    let u = input(n);
    // Data from a different system, so that prediction and simulation differ.
    let y: Vec<f64> = arx1(&u, -0.6, 0.9, 0.0, 1.0)
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.2 * (0.9 * k as f64).cos())
        .collect();
    let f = dir.path().join("d.csv");
    write_uy(&f, &u, &y);
    let model = v1_model(dir.path(), 0.1);
    let step = |prev: f64, k: usize| 0.8 * prev + 0.5 * u[k - 1] + 0.1;
    for horizon in [1usize, 3, 1000] {
        let csv = dir.path().join(format!("o{horizon}.csv"));
        let js = dir.path().join(format!("o{horizon}.json"));
        let h = horizon.to_string();
        run(&[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&f),
            "--ts",
            "0.1",
            "--out",
            s(&csv),
            "--horizon",
            &h,
            "--json",
            s(&js),
        ]);
        let got = read_columns(&csv);
        // ŷ(k | k - K): start from the measured y(k - K) (or y(0)) and step the model K times.
        let mut pred = vec![y[0]; n];
        for k in 1..n {
            let start = k.saturating_sub(horizon);
            let mut v = y[start];
            for j in start + 1..=k {
                v = step(v, j);
            }
            pred[k] = v;
        }
        let mut measured = vec![y[0]; n];
        for k in 1..n {
            measured[k] = step(measured[k - 1], k);
        }
        // y_sim starts from the estimated initial output, as the reported simulation fit does.
        let sim = estimated_initial_first_order(&y, &measured, 0.8);
        let reported = num(&json(&js)["metrics"]["validation"]["fit_sim_percent"]);
        assert!((reported - fit_pct(&y[1..], &sim[1..])).abs() < 1e-9);
        for k in 0..n {
            assert!((got["t"][k] - 0.1 * k as f64).abs() < 1e-12);
            assert_eq!(got["y"][k], y[k]);
            assert!(
                (got["y_pred"][k] - pred[k]).abs() < 1e-9,
                "K = {horizon}, k = {k}"
            );
            assert!((got["y_sim"][k] - sim[k]).abs() < 1e-9, "k = {k}");
            assert!((got["residual"][k] - (y[k] - pred[k])).abs() < 1e-9);
        }
        // The K-step fit in the JSON is 100 (1 - |y - ŷ| / |y - ȳ|) over k >= k0 = 1.
        let yk = &y[1..];
        let want_fit = fit_pct(yk, &pred[1..]);
        let fit = num(&json(&js)["fit_pred_horizon_percent"]);
        assert!((fit - want_fit).abs() < 1e-9, "K = {horizon}: {fit}");
    }
    let out = fails(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&f),
        "--ts",
        "0.1",
        "--horizon",
        "0",
    ]);
    assert!(out.contains("--horizon"));
}

#[test]
fn header_less_millisecond_records_are_read_and_resampled_linearly() {
    let dir = tempfile::tempdir().unwrap();
    // Tab-separated, no header, time in ms with irregular steps (10, 10, 15, 5, 30, 10, ...).
    let t_ms: Vec<f64> = {
        let steps = [10.0, 10.0, 15.0, 5.0, 30.0, 10.0, 10.0, 10.0];
        let mut t = vec![0.0];
        for k in 0..80 {
            let last = t[t.len() - 1];
            t.push(last + steps[k % steps.len()]);
        }
        t
    };
    let u: Vec<f64> = t_ms.iter().map(|t| (t / 37.0).sin() * 3.0).collect();
    let y: Vec<f64> = t_ms.iter().map(|t| (t / 53.0).cos() + t / 1000.0).collect();
    let mut text = String::new();
    for k in 0..t_ms.len() {
        text.push_str(&format!("{}\t7\t{}\t{}\n", t_ms[k], u[k], y[k]));
    }
    let f = dir.path().join("log.tsv");
    std::fs::write(&f, text).unwrap();
    let model = v1_model(dir.path(), 0.01);
    let csv = dir.path().join("o.csv");
    let cols = [
        "--no-header",
        "--t-col",
        "1",
        "--u-col",
        "3",
        "--y-col",
        "4",
        "--time-unit",
        "ms",
    ];
    // Without --resample the non-uniform column is refused, naming line 4 (the 15 ms step) and the fix.
    let err = fails(
        &[
            &["validate", "--model", s(&model), "--data", s(&f)][..],
            &cols[..],
        ]
        .concat(),
    );
    assert!(
        err.contains("log.tsv:4:1") && err.contains("--resample"),
        "{err}"
    );

    let out = run(&[
        &[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&f),
            "--resample",
            "0.01",
            "--out",
            s(&csv),
        ][..],
        &cols[..],
    ]
    .concat());
    // The reader's note is printed once, among the report's warnings (audit s18 L-6).
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(
        text.contains("warning: data:") && text.matches("resampled 81 rows").count() == 1,
        "{text}"
    );
    let got = read_columns(&csv);
    // Grid 0, 10, ... ms up to the last time; y by linear interpolation between the neighbours.
    let t_last = t_ms[t_ms.len() - 1];
    let m = (t_last / 10.0).floor() as usize + 1;
    assert_eq!(got["y"].len(), m);
    for j in 0..m {
        let tj = 10.0 * j as f64;
        let i = t_ms
            .iter()
            .rposition(|&t| t <= tj)
            .unwrap()
            .min(t_ms.len() - 2);
        let w = (tj - t_ms[i]) / (t_ms[i + 1] - t_ms[i]);
        let want = y[i] + w * (y[i + 1] - y[i]);
        assert!(
            (got["y"][j] - want).abs() < 1e-9,
            "j = {j}: {} vs {want}",
            got["y"][j]
        );
        assert!((got["t"][j] - tj / 1000.0).abs() < 1e-12);
    }

    // A uniform millisecond column gives Ts in seconds.
    let mut text = String::new();
    for k in 0..60 {
        text.push_str(&format!("{}\t{}\t{}\n", 20 * k, u[k], y[k]));
    }
    let g = dir.path().join("uniform.tsv");
    std::fs::write(&g, text).unwrap();
    let js = dir.path().join("r.json");
    run(&[
        "identify",
        "--data",
        s(&g),
        "--no-header",
        "--t-col",
        "1",
        "--u-col",
        "2",
        "--y-col",
        "3",
        "--time-unit",
        "ms",
        "--model",
        "arx",
        "--method",
        "ls",
        "--na",
        "1",
        "--json",
        s(&js),
    ]);
    assert_eq!(num(&json(&js)["model"]["ts"]), 0.02);
}

#[test]
fn one_word_per_meaning_with_the_old_spellings_kept() {
    let dir = tempfile::tempdir().unwrap();
    let u = input(200);
    let y = arx1(&u, -0.5, 1.0, 0.0, 0.0);
    let f = dir.path().join("d.csv");
    write_uy(&f, &u, &y);
    // --structure and its old spelling --model give the same model.
    let a = dir.path().join("a.json");
    let b = dir.path().join("b.json");
    for (flag, out) in [("--structure", &a), ("--model", &b)] {
        run(&[
            "identify",
            "--data",
            s(&f),
            "--ts",
            "1",
            flag,
            "arx",
            "--method",
            "ls",
            "--save-model",
            s(out),
        ]);
    }
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    assert_eq!(json(&a)["model"]["kind"], "arx");
    // simulate: --y0 as in control, --x0 still accepted; both start the model plant at that position.
    let (p, q) = (dir.path().join("p.csv"), dir.path().join("q.csv"));
    let plant = format!("model:{}", s(&a));
    for (flag, out) in [("--y0", &p), ("--x0", &q)] {
        run(&[
            "simulate",
            "--plant",
            &plant,
            "--input",
            "step:0",
            "--samples",
            "5",
            flag,
            "7.5",
            "--out",
            s(out),
        ]);
    }
    assert_eq!(std::fs::read(&p).unwrap(), std::fs::read(&q).unwrap());
    // A zero input from rest at y0 = 7.5 with y = 0.5 y(k-1) + u(k-1): 7.5, 3.75, 1.875, ...
    let cols = read_columns(&p);
    let a1 = num(&json(&a)["model"]["a"][0]);
    let mut want = 7.5;
    for v in &cols["y"] {
        assert!((v - want).abs() < 1e-9, "{v} vs {want}");
        want *= -a1;
    }
    // --plant has the same default (ipa) in every command.
    for cmd in ["simulate", "control", "montecarlo"] {
        let help = String::from_utf8(bin().args([cmd, "--help"]).output().unwrap().stdout).unwrap();
        let line = help
            .lines()
            .skip_while(|l| !l.contains("--plant <"))
            .take(4)
            .collect::<String>();
        assert!(line.contains("[default: ipa]"), "{cmd}: {line}");
    }
    // identify with a range of orders points to `order`.
    let err = fails(&["identify", "--data", s(&f), "--ts", "1", "--na", "1..5"]);
    assert!(err.contains("ipa-sysid order"));
}

/// y(k) = 0.6 y(k-1) + b1 u(k-nk) + b2 u(k-nk-1), noise-free.
fn delayed(u: &[f64], nk: usize, b1: f64, b2: f64) -> Vec<f64> {
    let mut y = vec![0.0; u.len()];
    for k in nk + 1..u.len() {
        y[k] = 0.6 * y[k - 1] + b1 * u[k - nk] + b2 * u[k - nk - 1];
    }
    y
}

/// `delay --max-delay MAX` on `f` at Ts = 0.1 s: its JSON and its output.
fn delay_json(f: &Path, max: &str, out: &Path) -> (serde_json::Value, Output) {
    let o = run(&[
        "delay",
        "--data",
        s(f),
        "--ts",
        "0.1",
        "--max-delay",
        max,
        "--json",
        s(out),
    ]);
    (json(out), o)
}

#[test]
fn delay_finds_the_generating_delay() {
    let dir = tempfile::tempdir().unwrap();
    let u = input(400);
    let y = delayed(&u, 4, 1.0, 0.5);
    let f = dir.path().join("d.csv");
    write_uy(&f, &u, &y);
    let out = dir.path().join("delay.json");
    let (j, _) = delay_json(&f, "10", &out);
    assert_eq!(j["nk"], 4);
    assert!((num(&j["delay_s"]) - 0.4).abs() < 1e-12);
    // All candidates on the same rows k >= k0 = max(na, 10 + nb - 1) = 11.
    assert_eq!(j["n"], 400 - 11);
    let c = j["candidates"].as_array().unwrap();
    assert_eq!(c.len(), 11);
    for cand in c {
        let nk = cand["nk"].as_u64().unwrap();
        match cand["loss"].as_f64() {
            Some(loss) if nk == 4 => {
                assert!(loss < 1e-20, "the generating delay fits exactly: {loss}")
            }
            Some(loss) => assert!(nk != 5 && loss > 1e-6, "nk = {nk}: {loss}"),
            // Noise-free data, nk = 5: y(k-1) = 0.6 y(k-2) + u(k-5) + 0.5 u(k-6) is a combination of the
            // other regressors, which cannot be fitted (and is said so).
            None => assert!(
                nk == 5
                    && cand["error"]
                        .as_str()
                        .unwrap()
                        .contains("linearly dependent")
            ),
        }
    }
    // A delay of 6 with --max-delay 5: nk = 5 with nb = 2 (b1 = 0, b2 = 1) fits exactly, and being the
    // largest tried, the result says to look further, and that its own lead (b1 = 0) is within noise.
    let y = delayed(&u, 5, 0.0, 1.0);
    write_uy(&f, &u, &y);
    let (j, o) = delay_json(&f, "5", &out);
    assert_eq!(j["nk"], 5);
    let warned = |what: &str| {
        j["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains(what))
    };
    assert!(warned("--max-delay"), "{j}");
    assert!(warned("u(k − 5) is within noise of 0"), "{j}");
    assert!(String::from_utf8_lossy(&o.stdout).contains("warning: "));
}

// Audit s11 D1: a second input column used to be read and ignored (the delay of the first reported as
// "the" delay). The delay is estimated for one input at a time: a list is refused naming --u-col, by
// `delay` and by `order --nk auto`; each input alone gets its own generating delay (u: 4, x: 2).
#[test]
fn delay_refuses_several_inputs_and_finds_each_inputs_delay_alone() {
    let dir = tempfile::tempdir().unwrap();
    let u = input(400);
    let x: Vec<f64> = u.iter().rev().copied().collect();
    let (yu, yx) = (delayed(&u, 4, 1.0, 0.5), delayed(&x, 2, 1.0, 0.5));
    let f = dir.path().join("two.csv");
    let mut text = String::from("u,x,yu,yx\n");
    for k in 0..u.len() {
        text += &format!("{},{},{},{}\n", u[k], x[k], yu[k], yx[k]);
    }
    std::fs::write(&f, text).unwrap();
    for cmd in [
        &[
            "delay",
            "--data",
            s(&f),
            "--ts",
            "1",
            "--y-col",
            "yu",
            "--u-col",
            "u,x",
        ][..],
        &[
            "order",
            "--data",
            s(&f),
            "--ts",
            "1",
            "--y-col",
            "yu",
            "--u-col",
            "u,x",
            "--nk",
            "auto",
        ],
    ] {
        let err = fails(cmd);
        assert!(
            err.contains("--u-col") && err.contains("one input"),
            "{err}"
        );
    }
    for (ucol, ycol, nk) in [("u", "yu", 4), ("x", "yx", 2)] {
        let out = dir.path().join(format!("{ucol}.json"));
        run(&[
            "delay",
            "--data",
            s(&f),
            "--ts",
            "1",
            "--u-col",
            ucol,
            "--y-col",
            ycol,
            "--json",
            s(&out),
        ]);
        assert_eq!(json(&out)["nk"], nk, "{ucol}");
    }
}

#[test]
fn order_ranks_on_a_selection_set_and_reports_the_test_fit_separately() {
    let dir = tempfile::tempdir().unwrap();
    // Estimation file: system A (nk = 2); test file: system B (nk = 1, other gains).
    let u = input(450);
    let mut ya = vec![0.0; 450];
    for k in 2..450 {
        ya[k] = 0.7 * ya[k - 1] + 0.5 * u[k - 2];
    }
    let ut: Vec<f64> = input(500)[50..].to_vec();
    let mut yb = vec![0.0; 450];
    for k in 1..450 {
        yb[k] = 0.5 * yb[k - 1] + 0.9 * ut[k - 1];
    }
    let (fa, fb) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
    write_uy(&fa, &u, &ya);
    write_uy(&fb, &ut, &yb);
    let out = dir.path().join("order.json");
    let grid = [
        "--na", "1..2", "--nb", "1..2", "--nk", "1..2", "--ts", "0.1",
    ];
    for extra in [
        vec![],
        vec!["--selection-rows", "300..450", "--rows", "0..300"],
    ] {
        let mut args = vec![
            "order",
            "--data",
            s(&fa),
            "--validation",
            s(&fb),
            "--json",
            s(&out),
        ];
        args.extend_from_slice(&grid);
        args.extend(extra.iter().copied());
        run(&args);
        let j = json(&out);
        // Ranked on rows of the estimation file (system A): the generating structure (1, 1, 2) first,
        // although system B would prefer nk = 1.
        let best = &j["candidates"][0]["orders"];
        assert_eq!(
            (
                best["na"].as_u64(),
                best["nb"].as_u64(),
                best["nk"].as_u64()
            ),
            (Some(1), Some(1), Some(2))
        );
        assert!(
            j["selection"]
                .as_str()
                .unwrap()
                .ends_with("a.csv[300..450]"),
            "{}",
            j["selection"]
        );
        // The test fit: the exact model of A simulated on B's input, computed here.
        let mut sim = vec![yb[0], yb[1]];
        for k in 2..450 {
            let v = 0.7 * sim[k - 1] + 0.5 * ut[k - 2];
            sim.push(v);
        }
        let (yk, sk) = (&yb[2..], &sim[2..]);
        let want = fit_pct(yk, sk);
        // The simulation above starts from the measured outputs: compare with that metric.
        let got = num(&j["test"]["metrics"]["fit_sim_measured_percent"]);
        assert!((got - want).abs() < 1e-6, "test fit {got} vs {want}");
        assert!(j["test"]["data"].as_str().unwrap().ends_with("b.csv"));
    }
}

/// A Level 5 MAT-file written by hand from the format specification (independent of the reader crate):
/// a 128-byte header, then one miMATRIX element per variable (double class), optionally each wrapped in
/// a zlib-compressed miCOMPRESSED element as MATLAB's default `save` writes.
fn mat_file(vars: &[(&str, usize, usize, &[f64])], compressed: bool) -> Vec<u8> {
    fn tag(out: &mut Vec<u8>, ty: u32, len: usize) {
        out.extend_from_slice(&ty.to_le_bytes());
        out.extend_from_slice(&(len as u32).to_le_bytes());
    }
    fn pad(out: &mut Vec<u8>) {
        while out.len() % 8 != 0 {
            out.push(0);
        }
    }
    let mut text = b"MATLAB 5.0 MAT-file, written by the ipa-sysid tests".to_vec();
    text.resize(116, b' ');
    let mut out = text;
    out.extend_from_slice(&[0u8; 8]); // subsystem data offset
    out.extend_from_slice(&0x0100u16.to_le_bytes());
    out.extend_from_slice(b"IM"); // little-endian marker
    for (name, rows, cols, data) in vars {
        let mut body = Vec::new();
        tag(&mut body, 6, 8); // miUINT32 array flags
        body.extend_from_slice(&6u32.to_le_bytes()); // mxDOUBLE_CLASS
        body.extend_from_slice(&0u32.to_le_bytes());
        tag(&mut body, 5, 8); // miINT32 dimensions
        body.extend_from_slice(&(*rows as i32).to_le_bytes());
        body.extend_from_slice(&(*cols as i32).to_le_bytes());
        tag(&mut body, 1, name.len()); // miINT8 name
        body.extend_from_slice(name.as_bytes());
        pad(&mut body);
        tag(&mut body, 9, 8 * data.len()); // miDOUBLE real part, column-major
        for v in *data {
            body.extend_from_slice(&v.to_le_bytes());
        }
        pad(&mut body);
        let mut element = Vec::new();
        tag(&mut element, 14, body.len()); // miMATRIX
        element.extend_from_slice(&body);
        if compressed {
            use std::io::Write;
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&element).unwrap();
            let zipped = z.finish().unwrap();
            tag(&mut out, 15, zipped.len()); // miCOMPRESSED
            out.extend_from_slice(&zipped);
        } else {
            out.extend_from_slice(&element);
        }
    }
    out
}

#[test]
fn mat_files_are_read_by_variable_name() {
    let dir = tempfile::tempdir().unwrap();
    let n = 200;
    let u = input(n);
    let y = arx1(&u, -0.7, 2.0, 0.0, 0.0);
    let t: Vec<f64> = (0..n).map(|k| 0.05 * k as f64).collect();
    let m = [1.0, 2.0, 3.0, 4.0, 5.0, 6.0];
    for compressed in [false, true] {
        // u a column vector, y a row vector, t a column, M a 2x3 matrix.
        let bytes = mat_file(
            &[
                ("uu", n, 1, &u),
                ("yy", 1, n, &y),
                ("time", n, 1, &t),
                ("M", 2, 3, &m),
            ],
            compressed,
        );
        let f = dir.path().join(format!("rec{compressed}.mat"));
        std::fs::write(&f, bytes).unwrap();
        let out = dir.path().join("r.json");
        let j = identify_json(
            &[
                "--data",
                s(&f),
                "--u-col",
                "uu",
                "--y-col",
                "yy",
                "--rows",
                "0..150",
                "--val-rows",
                "150..",
            ],
            &out,
        );
        assert!(
            (num(&j["model"]["a"][0]) + 0.7).abs() < 1e-9,
            "{}",
            j["model"]
        );
        assert!((num(&j["model"]["b"][0]) - 2.0).abs() < 1e-9);
        assert_eq!(j["metrics"]["estimation"]["n"], 149);
        assert_eq!(j["metrics"]["validation"]["n"], 49);
        // Ts from the time variable (without --ts).
        let out2 = dir.path().join("r2.json");
        run(&[
            "identify",
            "--data",
            s(&f),
            "--u-col",
            "uu",
            "--y-col",
            "yy",
            "--t-col",
            "time",
            "--structure",
            "arx",
            "--method",
            "ls",
            "--na",
            "1",
            "--json",
            s(&out2),
        ]);
        assert!((num(&json(&out2)["model"]["ts"]) - 0.05).abs() < 1e-12);
        // A matrix is not a signal; a missing variable lists the ones there are.
        for (var, want) in [("M", "2x3 array"), ("nope", "uu")] {
            let o = fails(&[
                "identify",
                "--data",
                s(&f),
                "--ts",
                "1",
                "--u-col",
                var,
                "--y-col",
                "yy",
            ]);
            let err = o;
            assert!(err.contains(want) && err.contains("rec"), "{var}: {err}");
        }
    }
    // MATLAB v7.3 (HDF5) is refused with the way out.
    let mut v73 = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 .".to_vec();
    v73.resize(512, b' ');
    v73.extend_from_slice(b"\x89HDF\r\n\x1a\n");
    let f = dir.path().join("new.mat");
    std::fs::write(&f, v73).unwrap();
    let o = fails(&["identify", "--data", s(&f), "--ts", "1"]);
    let err = o;
    assert!(
        err.contains("v7.3") && err.contains("-v7") && err.contains("new.mat"),
        "{err}"
    );
    // A truncated file is an error, not a panic.
    let mut bytes = mat_file(&[("u", n, 1, &u), ("y", n, 1, &y)], false);
    bytes.truncate(700);
    std::fs::write(&f, bytes).unwrap();
    let o = fails(&["identify", "--data", s(&f), "--ts", "1"]);
    assert!(!o.contains("panicked"));
}

/// `identify --merge` of two records with a first-order `structure` (na = nb = nk = 1) by least squares.
fn merge_json(a: &str, b: &str, structure: &str, out: &Path) {
    run(&[
        "identify",
        "--data",
        a,
        b,
        "--merge",
        "--structure",
        structure,
        "--method",
        "ls",
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
        "--ts",
        "0.1",
        "--json",
        s(out),
    ]);
}

#[test]
fn merge_estimates_one_model_without_rows_spanning_records() {
    let dir = tempfile::tempdir().unwrap();
    // Two experiments on y = 0.7 y(k-1) + 2 u(k-1), with a wobble on y so that the fit is not exact, and
    // very different starting points (a naive concatenation would have a wrong row at the seam).
    let make = |phase: usize, y_init: f64| {
        let u: Vec<f64> = input(300 + phase)[phase..].to_vec();
        let mut y = arx1(&u, -0.7, 2.0, 0.0, y_init);
        for (k, v) in y.iter_mut().enumerate() {
            *v += 0.3 * (1.3 * (k + phase) as f64).sin();
        }
        (u, y)
    };
    let (u1, y1) = make(0, 0.0);
    let (u2, y2) = make(37, 80.0);
    let (f1, f2) = (dir.path().join("e1.csv"), dir.path().join("e2.csv"));
    write_uy(&f1, &u1, &y1);
    write_uy(&f2, &u2, &y2);
    let out = dir.path().join("m.json");
    // Without --merge several files are batch mode, where splitting one file has no meaning.
    let err = fails(&[
        "identify",
        "--data",
        s(&f1),
        s(&f2),
        "--split",
        "0.5",
        "--ts",
        "0.1",
    ]);
    assert!(
        err.contains("batch mode") && err.contains("--merge"),
        "{err}"
    );
    merge_json(s(&f1), s(&f2), "arx", &out);
    let j = json(&out);
    // Expected: least squares over rows k = 1..N-1 of each record, stacked (no seam row).
    let (mut z, mut p, mut q) = (Vec::new(), Vec::new(), Vec::new());
    for (u, y) in [(&u1, &y1), (&u2, &y2)] {
        for k in 1..u.len() {
            z.push(y[k]);
            p.push(-y[k - 1]);
            q.push(u[k - 1]);
        }
    }
    let (a1, b1) = ls2(&z, &p, &q);
    let (ga, gb) = (num(&j["model"]["a"][0]), num(&j["model"]["b"][0]));
    assert!(
        (ga - a1).abs() < 1e-9 && (gb - b1).abs() < 1e-9,
        "{ga} {gb} vs {a1} {b1}"
    );
    // Per-record and pooled free-run fits, computed here.
    let sim = |u: &[f64], y: &[f64]| {
        let mut s = vec![y[0]; u.len()];
        for k in 1..u.len() {
            s[k] = -a1 * s[k - 1] + b1 * u[k - 1];
        }
        s
    };
    let fit = fit_pct;
    let (s1, s2) = (sim(&u1, &y1), sim(&u2, &y2));
    let recs = j["records"].as_array().unwrap();
    assert_eq!(recs.len(), 2);
    // These simulations start from the measured outputs: compare with that metric.
    assert!(
        (num(&recs[0]["metrics"]["fit_sim_measured_percent"]) - fit(&y1[1..], &s1[1..])).abs()
            < 1e-6
    );
    assert!(
        (num(&recs[1]["metrics"]["fit_sim_measured_percent"]) - fit(&y2[1..], &s2[1..])).abs()
            < 1e-6
    );
    // Pooled: every record's rows, each record against its own mean ȳ_r (audit s17 H-1):
    // fit = 100 (1 − √(Σ_r ‖y_r − ŝ_r‖²) / √(Σ_r ‖y_r − ȳ_r‖²)).
    let sq = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, z)| (x - z).powi(2)).sum::<f64>();
    let dev = |a: &[f64]| {
        let m = a.iter().sum::<f64>() / a.len() as f64;
        a.iter().map(|x| (x - m).powi(2)).sum::<f64>()
    };
    let pooled_of = |a: &[f64], b: &[f64]| {
        let e = sq(&y1[1..], a) + sq(&y2[1..], b);
        100.0 * (1.0 - (e / (dev(&y1[1..]) + dev(&y2[1..]))).sqrt())
    };
    let pooled = &j["metrics"]["estimation"];
    let want = pooled_of(&s1[1..], &s2[1..]);
    assert!((num(&pooled["fit_sim_measured_percent"]) - want).abs() < 1e-6);
    // The pooled free-run fit starts each record from its own estimated initial output, as the
    // per-record fits do (MATLAB compare).
    let (e1, e2) = (
        estimated_initial_first_order(&y1, &s1, -a1),
        estimated_initial_first_order(&y2, &s2, -a1),
    );
    assert!((num(&recs[0]["metrics"]["fit_sim_percent"]) - fit(&y1[1..], &e1[1..])).abs() < 1e-6);
    assert!((num(&recs[1]["metrics"]["fit_sim_percent"]) - fit(&y2[1..], &e2[1..])).abs() < 1e-6);
    let pooled_fit = num(&pooled["fit_sim_percent"]);
    let want_e = pooled_of(&e1[1..], &e2[1..]);
    assert!((pooled_fit - want_e).abs() < 1e-6, "{pooled_fit}");
    // The start at 80 mm makes the two differ: the measured y(0) carries the wobble.
    assert!((want_e - want).abs() > 1e-6);
    // RLS on the merged records runs its passes over both records (no regressor spans two) and
    // settles at the same least-squares solution.
    let rls = dir.path().join("rls.json");
    run(&[
        "identify",
        "--data",
        s(&f1),
        s(&f2),
        "--merge",
        "--structure",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
        "--method",
        "rls",
        "--ts",
        "0.1",
        "--json",
        s(&rls),
    ]);
    let jr = json(&rls);
    let (ra, rb) = (num(&jr["model"]["a"][0]), num(&jr["model"]["b"][0]));
    assert!(
        (ra - a1).abs() < 1e-6 && (rb - b1).abs() < 1e-6,
        "{ra} {rb} vs {a1} {b1}"
    );
    // Output error and IV work on one record; with --merge they are refused by name.
    let o = fails(&[
        "identify",
        "--data",
        s(&f1),
        s(&f2),
        "--merge",
        "--method",
        "oe",
        "--ts",
        "0.1",
    ]);
    assert!(o.contains("--method"), "{o}");
}

#[test]
fn merge_recovers_a_hammerstein_deadzone_from_two_records() {
    let dir = tempfile::tempdir().unwrap();
    // x = valve(u) (b_l = -1, b_r = 0.5, m_l = 0.8, m_r = 1.2); y = 0.6 y(k-1) + x(k-1).
    let dz = valve;
    let mut files = Vec::new();
    for (i, phase) in [0usize, 53].iter().enumerate() {
        let u: Vec<f64> = input(400 + phase)[*phase..]
            .iter()
            .map(|v| 3.0 * (v - 1.0))
            .collect();
        let mut y = vec![10.0 * i as f64; u.len()];
        for k in 1..u.len() {
            y[k] = 0.6 * y[k - 1] + dz(u[k - 1]);
        }
        let f = dir.path().join(format!("h{i}.csv"));
        write_uy(&f, &u, &y);
        files.push(f);
    }
    let out = dir.path().join("h.json");
    merge_json(s(&files[0]), s(&files[1]), "hammerstein", &out);
    let m = &json(&out)["model"];
    let d = &m["deadzone"];
    for (got, want) in [
        (num(&m["a"][0]), -0.6),
        (num(&d["b_l"]), -1.0),
        (num(&d["b_r"]), 0.5),
        (num(&d["m_l"]), 0.8),
        (num(&d["m_r"]), 1.2),
    ] {
        assert!((got - want).abs() < 1e-6, "{m}");
    }
}

/// Two inputs: u1 with nb = 2, nk = 1 through `f1`, u2 linear with nb = 1, nk = 2:
/// y(k) = 0.5 y(k-1) + f1(u1(k-1)) + b12 f1(u1(k-2)) - 2 u2(k-2).
fn miso_record(
    dir: &Path,
    f1: &dyn Fn(f64) -> f64,
    b12: f64,
) -> (PathBuf, Vec<f64>, Vec<f64>, Vec<f64>) {
    let n = 400;
    let u1: Vec<f64> = input(n).iter().map(|v| 3.0 * (v - 1.0)).collect();
    let u2: Vec<f64> = input(n + 61)[61..].to_vec();
    let mut y = vec![0.0; n];
    for k in 2..n {
        y[k] = 0.5 * y[k - 1] + f1(u1[k - 1]) + b12 * f1(u1[k - 2]) - 2.0 * u2[k - 2];
    }
    let mut text = String::from("u1,u2,y\n");
    for k in 0..n {
        text.push_str(&format!("{},{},{}\n", u1[k], u2[k], y[k]));
    }
    let f = dir.join("miso.csv");
    std::fs::write(&f, text).unwrap();
    (f, u1, u2, y)
}

/// `identify` of the two-input record `f` (nb = 2,1, nk = 1,2, na = 1) by `method`, plus `extra`.
fn miso_identify(f: &str, structure: &str, method: &str, extra: &[&str]) {
    let mut args = vec![
        "identify",
        "--data",
        f,
        "--u-col",
        "u1,u2",
        "--nb",
        "2,1",
        "--nk",
        "1,2",
        "--na",
        "1",
        "--structure",
        structure,
        "--method",
        method,
        "--ts",
        "0.1",
    ];
    args.extend_from_slice(extra);
    run(&args);
}

/// The deadzone of input u1 in the Hammerstein two-input records: b_l = -1, b_r = 0.5, m_l = 0.8, m_r = 1.2.
fn valve(v: f64) -> f64 {
    if v >= 0.5 {
        1.2 * (v - 0.5)
    } else if v <= -1.0 {
        0.8 * (v + 1.0)
    } else {
        0.0
    }
}

/// Identifies the noise-free two-input Hammerstein record (deadzone `valve` on u1, b = (1, 0.3); u2
/// linear with b = -2; a1 = -0.5) by `method`, checks every parameter against the generating model within
/// `tol` and returns the record, the JSON and the saved model file.
fn hammerstein_miso(dir: &Path, method: &str, tol: f64) -> (PathBuf, serde_json::Value, PathBuf) {
    let (f, ..) = miso_record(dir, &valve, 0.3);
    let out = dir.join(format!("ham_{method}.json"));
    let model = dir.join(format!("ham_{method}_model.json"));
    miso_identify(
        s(&f),
        "hammerstein",
        method,
        &[
            "--linear-inputs",
            "u2",
            "--json",
            s(&out),
            "--save-model",
            s(&model),
        ],
    );
    let j = json(&out);
    let inputs = j["model"]["inputs"].as_array().unwrap();
    let d = &inputs[0]["deadzone"];
    for (got, want) in [
        (&j["model"]["a"][0], -0.5),
        (&inputs[0]["b"][1], 0.3),
        (&d["b_l"], -1.0),
        (&d["b_r"], 0.5),
        (&d["m_l"], 0.8),
        (&d["m_r"], 1.2),
        (&inputs[1]["b"][0], -2.0),
    ] {
        assert!((num(got) - want).abs() < tol, "{method}: {}", j["model"]);
    }
    (f, j, model)
}

#[test]
fn several_inputs_arx_and_hammerstein_with_a_linear_input() {
    let dir = tempfile::tempdir().unwrap();
    // ARX: f1 = identity, b = (1, 0.3) for u1 and (-2) for u2.
    let (f, u1, u2, y) = miso_record(dir.path(), &|v| v, 0.3);
    let out = dir.path().join("arx.json");
    let model = dir.path().join("arx_model.json");
    miso_identify(
        s(&f),
        "arx",
        "ls",
        &[
            "--rows",
            "0..300",
            "--val-rows",
            "300..",
            "--json",
            s(&out),
            "--save-model",
            s(&model),
        ],
    );
    let j = json(&out);
    let inputs = j["model"]["inputs"].as_array().unwrap();
    assert_eq!(inputs.len(), 2);
    assert_eq!(
        (inputs[0]["name"].as_str(), inputs[1]["name"].as_str()),
        (Some("u1"), Some("u2"))
    );
    assert_eq!(
        (inputs[0]["nb"].as_u64(), inputs[0]["nk"].as_u64()),
        (Some(2), Some(1))
    );
    assert_eq!(
        (inputs[1]["nb"].as_u64(), inputs[1]["nk"].as_u64()),
        (Some(1), Some(2))
    );
    for (got, want) in [
        (&j["model"]["a"][0], -0.5),
        (&inputs[0]["b"][0], 1.0),
        (&inputs[0]["b"][1], 0.3),
        (&inputs[1]["b"][0], -2.0),
    ] {
        assert!((num(got) - want).abs() < 1e-9, "{}", j["model"]);
    }
    // Single-input keys are kept: the top-level nb, nk, b repeat the first input.
    assert_eq!(j["model"]["nb"], 2);
    assert_eq!(j["metrics"]["validation"]["n"], 98); // rows 300..400, k0 = max(1, 1+2-1, 2+1-1) = 2
                                                     // validate reads the model's input columns by name; the exact model simulates the data exactly.
    let csv = dir.path().join("v.csv");
    run(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&f),
        "--ts",
        "0.1",
        "--out",
        s(&csv),
    ]);
    let got = read_columns(&csv);
    let mut sim = vec![y[0], y[1]];
    for k in 2..y.len() {
        sim.push(0.5 * sim[k - 1] + u1[k - 1] + 0.3 * u1[k - 2] - 2.0 * u2[k - 2]);
    }
    for k in 0..y.len() {
        assert!((got["y_sim"][k] - sim[k]).abs() < 1e-6, "k = {k}");
    }

    // Hammerstein: a deadzone on u1, u2 declared linear.
    let (f, j, _) = hammerstein_miso(dir.path(), "ls", 1e-6);
    let inputs = j["model"]["inputs"].as_array().unwrap();
    assert_eq!(num(&inputs[0]["b"][0]), 1.0);
    assert!(inputs[1].get("deadzone").is_none());
    // A list of the wrong length is refused by flag.
    let err = fails(&[
        "identify",
        "--data",
        s(&f),
        "--u-col",
        "u1,u2",
        "--nb",
        "2,1,1",
        "--method",
        "ls",
        "--ts",
        "0.1",
    ]);
    assert!(err.contains("--nb") && err.contains("2 inputs"), "{err}");
}

/// Least squares of z ≈ Φ θ by the normal equations ΦᵀΦ θ = Φᵀz, solved by Gaussian elimination with
/// partial pivoting (rows of Φ given one by one).
fn normal_equations(rows: &[Vec<f64>], z: &[f64]) -> Vec<f64> {
    let p = rows[0].len();
    let mut m = vec![vec![0.0; p + 1]; p];
    for (r, zk) in rows.iter().zip(z) {
        for i in 0..p {
            for j in 0..p {
                m[i][j] += r[i] * r[j];
            }
            m[i][p] += r[i] * zk;
        }
    }
    for c in 0..p {
        let piv = (c..p)
            .max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))
            .unwrap();
        m.swap(c, piv);
        for r in c + 1..p {
            let f = m[r][c] / m[c][c];
            for j in c..=p {
                m[r][j] -= f * m[c][j];
            }
        }
    }
    let mut theta = vec![0.0; p];
    for i in (0..p).rev() {
        let rest: f64 = (i + 1..p).map(|j| m[i][j] * theta[j]).sum();
        theta[i] = (m[i][p] - rest) / m[i][i];
    }
    theta
}

#[test]
fn several_inputs_by_rls_reach_the_least_squares_solution() {
    let dir = tempfile::tempdir().unwrap();
    let (f, u1, u2, y) = miso_record(dir.path(), &|v| v, 0.3);
    // A deterministic disturbance on y, so that the least-squares solution is not the true system.
    let y: Vec<f64> = y
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.4 * (2.3 * k as f64).sin())
        .collect();
    let mut text = String::from("u1,u2,y\n");
    for k in 0..y.len() {
        text.push_str(&format!("{},{},{}\n", u1[k], u2[k], y[k]));
    }
    std::fs::write(&f, text).unwrap();
    // θ = [a1, b1(u1), b2(u1), b1(u2), c] over rows k >= k0 = 2, by the normal equations.
    let (mut rows, mut z) = (Vec::new(), Vec::new());
    for k in 2..y.len() {
        rows.push(vec![-y[k - 1], u1[k - 1], u1[k - 2], u2[k - 2], 1.0]);
        z.push(y[k]);
    }
    let want = normal_equations(&rows, &z);
    let out = dir.path().join("rls.json");
    miso_identify(s(&f), "arx", "rls", &["--offset", "--json", s(&out)]);
    let j = json(&out);
    let m = &j["model"];
    let inputs = m["inputs"].as_array().unwrap();
    let got = [
        num(&m["a"][0]),
        num(&inputs[0]["b"][0]),
        num(&inputs[0]["b"][1]),
        num(&inputs[1]["b"][0]),
        num(&m["offset"]),
    ];
    for (g, w) in got.iter().zip(&want) {
        assert!(
            (g - w).abs() < 1e-6 * (1.0 + w.abs()),
            "{got:?} vs {want:?}"
        );
    }
    assert_eq!(j["estimation"]["method"], "rls");
    assert_eq!(j["estimation"]["converged"], true);
    // The record has no constant (c = 0 in truth, the disturbance has mean ≈ 0): one doubt is that c is
    // within two standard deviations of zero. The other (since session 34, audit s34 M-2): the
    // disturbance sits on the output, so the equation error carries it and the residuals' lag-1
    // correlation is about cos 2.3 = −0.67, the signature of output noise that biases rls.
    let w: Vec<&str> = j["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(
        w.iter().all(|w| {
            (w.contains("poorly determined")
                && w.rsplit_once("may help): ")
                    .is_some_and(|(_, l)| l.starts_with("c = ") && !l.contains(", ")))
                || w.contains("negatively correlated at lag 1")
        }),
        "{w:?}"
    );
    let noise = w
        .iter()
        .find(|w| w.contains("negatively correlated at lag 1"))
        .unwrap_or_else(|| panic!("the output disturbance is not named: {w:?}"));
    let r1: f64 = {
        let rest = &noise[noise.find("(r = ").unwrap() + 5..];
        rest[..rest.find(')').unwrap()].parse().unwrap()
    };
    assert!((r1 - 2.3f64.cos()).abs() < 0.05, "r1 = {r1}");

    // Hammerstein by RLS: a deadzone on u1, u2 linear, noise-free: the passes reach the generating model.
    hammerstein_miso(dir.path(), "rls", 1e-4);
    // Hammerstein by IV: noise-free, the LS start is exact and every IV residual is 0, so IV keeps
    // the generating model (to 1e-8).
    let (_, j, _) = hammerstein_miso(dir.path(), "iv", 1e-8);
    assert_eq!(j["estimation"]["method"], "iv");
}

/// Writes columns u1, u2, y.
fn write_u1u2y(path: &Path, u1: &[f64], u2: &[f64], y: &[f64]) {
    let mut text = String::from("u1,u2,y\n");
    for k in 0..y.len() {
        text.push_str(&format!("{},{},{}\n", u1[k], u2[k], y[k]));
    }
    std::fs::write(path, text).unwrap();
}

/// Two inputs with white noise at the OUTPUT:
/// x(k) = 0.9 x(k-1) + f1(u1(k-1)) + 0.5 f1(u1(k-2)) + 0.4 u2(k-2), y = x + `noise` e (e of unit
/// variance). The equation error e(k) − 0.9 e(k−1) is coloured, so least squares is biased (a1 pulled
/// towards 0); the output-error criterion's minimiser is the generating model.
fn noisy_miso(dir: &Path, f1: &dyn Fn(f64) -> f64, noise: f64, name: &str) -> PathBuf {
    let n = 3000;
    let u1: Vec<f64> = input(n).iter().map(|v| 3.0 * (v - 1.0)).collect();
    let u2: Vec<f64> = ipa_testdata::white(n, 7).iter().map(|v| 2.0 * v).collect();
    let e = ipa_testdata::white(n, 99);
    let mut x = vec![0.0; n];
    for k in 2..n {
        x[k] = 0.9 * x[k - 1] + f1(u1[k - 1]) + 0.5 * f1(u1[k - 2]) + 0.4 * u2[k - 2];
    }
    let y: Vec<f64> = x.iter().zip(&e).map(|(x, e)| x + noise * e).collect();
    let f = dir.join(name);
    write_u1u2y(&f, &u1, &u2, &y);
    f
}

#[test]
fn output_error_with_two_inputs_recovers_the_model_that_least_squares_biases() {
    let dir = tempfile::tempdir().unwrap();
    let args_of = |f: &Path, structure: &str, method: &str, extra: &[&str]| {
        let out = dir.path().join(format!("{structure}_{method}.json"));
        let mut args = vec![
            "identify",
            "--data",
            s(f),
            "--u-col",
            "u1,u2",
            "--nb",
            "2,1",
            "--nk",
            "1,2",
            "--na",
            "1",
            "--structure",
            structure,
            "--method",
            method,
            "--ts",
            "0.1",
            "--rows",
            "0..2400",
            "--val-rows",
            "2400..",
            "--json",
            s(&out),
        ];
        args.extend_from_slice(extra);
        run(&args);
        json(&out)
    };
    // ARX: the generating a1 = -0.9, b(u1) = (1, 0.5), b(u2) = 0.4.
    let f = noisy_miso(dir.path(), &|v| v, 6.0, "arx.csv");
    let want = [-0.9, 1.0, 0.5, 0.4];
    let coeffs = |j: &serde_json::Value| {
        let m = &j["model"];
        let i = m["inputs"].as_array().unwrap();
        [
            num(&m["a"][0]),
            num(&i[0]["b"][0]),
            num(&i[0]["b"][1]),
            num(&i[1]["b"][0]),
        ]
    };
    let ls = args_of(&f, "arx", "ls", &[]);
    let oe = args_of(&f, "arx", "oe", &[]);
    let (ls_c, oe_c) = (coeffs(&ls), coeffs(&oe));
    // Least squares is visibly biased on a1; output error is close on every coefficient.
    assert!((ls_c[0] - want[0]).abs() > 0.05, "LS {ls_c:?}");
    for (g, w) in oe_c.iter().zip(&want) {
        assert!((g - w).abs() < 0.03, "OE {oe_c:?} vs {want:?}");
    }
    assert_eq!(oe["estimation"]["method"], "oe");
    assert_eq!(oe["model"]["noise_model"], "output-error");
    let fit = |j: &serde_json::Value| num(&j["metrics"]["validation"]["fit_sim_percent"]);
    assert!(
        fit(&oe) > fit(&ls) + 1.0,
        "OE {} vs LS {}",
        fit(&oe),
        fit(&ls)
    );
    // Every free parameter has a standard deviation, and the truth lies within 4 of them.
    let params = oe["parameters"].as_array().unwrap();
    assert_eq!(params.len(), 4, "{params:?}");
    for (p, w) in params.iter().zip(&want) {
        let (v, sd) = (num(&p["value"]), num(&p["std"]));
        assert!(sd > 0.0 && (v - w).abs() < 4.0 * sd, "{p} vs {w}");
    }
    assert!(oe["estimation"]["note"]
        .as_str()
        .unwrap()
        .contains("output-error refinement"));

    // Hammerstein: the deadzone `valve` on u1, u2 linear: output error recovers the deadzone too.
    let f = noisy_miso(dir.path(), &valve, 2.0, "ham.csv");
    let ls = args_of(&f, "hammerstein", "ls", &["--linear-inputs", "u2"]);
    let oe = args_of(&f, "hammerstein", "oe", &["--linear-inputs", "u2"]);
    let get = |j: &serde_json::Value| {
        let m = &j["model"];
        let i = m["inputs"].as_array().unwrap();
        let d = &i[0]["deadzone"];
        [
            num(&m["a"][0]),
            num(&i[0]["b"][1]),
            num(&i[1]["b"][0]),
            num(&d["b_l"]),
            num(&d["b_r"]),
            num(&d["m_l"]),
            num(&d["m_r"]),
        ]
    };
    let want = [-0.9, 0.5, 0.4, -1.0, 0.5, 0.8, 1.2];
    let (ls_c, oe_c) = (get(&ls), get(&oe));
    assert!((ls_c[0] - want[0]).abs() > 0.02, "LS {ls_c:?}");
    assert!((oe_c[0] - want[0]).abs() < 0.005, "OE {oe_c:?}");
    for (g, w) in oe_c.iter().zip(&want) {
        assert!(
            (g - w).abs() < 0.06 * (1.0 + w.abs()),
            "OE {oe_c:?} vs {want:?}"
        );
    }
    assert!(fit(&oe) > fit(&ls), "OE {} vs LS {}", fit(&oe), fit(&ls));
}

#[test]
fn several_input_models_are_simulated_on_recorded_inputs_and_refused_as_control_plants() {
    let dir = tempfile::tempdir().unwrap();
    // The generating model y(k) = 0.5 y(k-1) + u1(k-1) + 0.3 u1(k-2) - 2 u2(k-2), identified exactly.
    let (f, u1, u2, _) = miso_record(dir.path(), &|v| v, 0.3);
    let model = dir.path().join("m.json");
    miso_identify(s(&f), "arx", "ls", &["--save-model", s(&model)]);
    let spec = format!("model:{}", s(&model));
    let out = dir.path().join("o.csv");
    // simulate runs it from rest at y0 on the recorded commands (file columns named as the inputs):
    // y(0) = y0, y(k) = 0.5 y(k-1) + u1(k-1) + 0.3 u1(k-2) - 2 u2(k-2) with u(k < 0) = 0.
    run(&[
        "simulate",
        "--plant",
        &spec,
        "--input",
        &format!("file:{}", s(&f)),
        "--y0",
        "7",
        "--out",
        s(&out),
    ]);
    let got = read_columns(&out);
    let at = |v: &[f64], k: isize| if k < 0 { 0.0 } else { v[k as usize] };
    let mut y = vec![7.0; u1.len()];
    for k in 1..u1.len() {
        let i = k as isize;
        y[k] = 0.5 * y[k - 1] + at(&u1, i - 1) + 0.3 * at(&u1, i - 2) - 2.0 * at(&u2, i - 2);
    }
    assert_eq!(got["u1"], u1);
    assert_eq!(got["u2"], u2);
    for k in 0..y.len() {
        assert!(
            (got["y"][k] - y[k]).abs() < 1e-6 * (1.0 + y[k].abs()),
            "k = {k}"
        );
        assert!((got["t"][k] - 0.1 * k as f64).abs() < 1e-12);
    }
    // A designed input cannot drive two inputs; control drives one command.
    let err = fails(&["simulate", "--plant", &spec, "--out", s(&out)]);
    assert!(err.contains("--input") && err.contains("u1, u2"), "{err}");
    let err = fails(&["control", "--plant", &spec, "--setpoint", "10"]);
    assert!(
        err.contains("2 inputs (u1, u2)") && err.contains("one command"),
        "{err}"
    );
    // --compensate-deadzone needs a single-input Hammerstein model.
    let (_, _, ham) = hammerstein_miso(dir.path(), "ls", 1e-6);
    let err = fails(&[
        "control",
        "--plant",
        "paper",
        "--setpoint",
        "10",
        "--compensate-deadzone",
        s(&ham),
    ]);
    assert!(
        err.contains("--compensate-deadzone") && err.contains("2 inputs"),
        "{err}"
    );
}

/// (ΦᵀΦ)⁻¹ by Gauss–Jordan elimination with partial pivoting (rows of Φ given one by one).
fn inverse_gram(rows: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let p = rows[0].len();
    let mut m = vec![vec![0.0; 2 * p]; p];
    for r in rows {
        for i in 0..p {
            for j in 0..p {
                m[i][j] += r[i] * r[j];
            }
        }
    }
    for i in 0..p {
        m[i][p + i] = 1.0;
    }
    for c in 0..p {
        let piv = (c..p)
            .max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))
            .unwrap();
        m.swap(c, piv);
        let d = m[c][c];
        for j in 0..2 * p {
            m[c][j] /= d;
        }
        for r in 0..p {
            if r != c {
                let f = m[r][c];
                for j in 0..2 * p {
                    m[r][j] -= f * m[c][j];
                }
            }
        }
    }
    m.iter().map(|r| r[p..].to_vec()).collect()
}

/// The two-input ARX record of `miso_record` (a1 = -0.5, b(u1) = (1, 0.3), b(u2) = -2) with a
/// deterministic disturbance 0.4 sin(2.3 k + `phase`) on y, so that least squares is not exact.
fn disturbed_miso(dir: &Path, name: &str, phase: f64) -> (PathBuf, Vec<f64>, Vec<f64>, Vec<f64>) {
    let (_, u1, u2, y) = miso_record(dir, &|v| v, 0.3);
    let y: Vec<f64> = y
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.4 * (2.3 * k as f64 + phase).sin())
        .collect();
    let f = dir.join(name);
    write_u1u2y(&f, &u1, &u2, &y);
    (f, u1, u2, y)
}

/// Regression rows [-y(k-1), u1(k-1), u1(k-2), u2(k-2)] and targets y(k), k = 2..N (nb = 2,1, nk = 1,2).
fn miso_rows(u1: &[f64], u2: &[f64], y: &[f64]) -> (Vec<Vec<f64>>, Vec<f64>) {
    (2..y.len())
        .map(|k| (vec![-y[k - 1], u1[k - 1], u1[k - 2], u2[k - 2]], y[k]))
        .unzip()
}

#[test]
fn several_input_standard_deviations_are_sigma_squared_times_the_inverse_gram_matrix() {
    let dir = tempfile::tempdir().unwrap();
    let (f, u1, u2, y) = disturbed_miso(dir.path(), "d.csv", 0.0);
    let (rows, z) = miso_rows(&u1, &u2, &y);
    let theta = normal_equations(&rows, &z);
    let eps: Vec<f64> = rows
        .iter()
        .zip(&z)
        .map(|(r, zk)| zk - r.iter().zip(&theta).map(|(a, b)| a * b).sum::<f64>())
        .collect();
    let (n, p) = (rows.len(), theta.len());
    let sigma2 = eps.iter().map(|e| e * e).sum::<f64>() / (n - p) as f64;
    let inv = inverse_gram(&rows);
    for method in ["ls", "rls"] {
        let out = dir.path().join(format!("{method}.json"));
        miso_identify(s(&f), "arx", method, &["--json", s(&out)]);
        let j = json(&out);
        let params = j["parameters"].as_array().unwrap();
        let names: Vec<String> = params.iter().map(label).collect();
        assert_eq!(names, ["a1", "b1 (u1)", "b2 (u1)", "b1 (u2)"]);
        for (i, prm) in params.iter().enumerate() {
            let want = (sigma2 * inv[i][i]).sqrt();
            let got = num(&prm["std"]);
            assert!(
                (got - want).abs() < 1e-5 * want,
                "{method} {i}: {got} vs {want}"
            );
        }
        assert!((num(&j["estimation"]["noise_variance"]) - sigma2).abs() < 1e-5 * sigma2);
    }
    // Residual analysis of the LS model: the one-step errors ε(k), k >= 2, against EACH input.
    let j = json(&dir.path().join("ls.json"));
    let a = &j["residuals"]["estimation"];
    let m = a["max_lag"].as_u64().unwrap() as usize;
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let e_bar = mean(&eps);
    let e: Vec<f64> = eps.iter().map(|v| v - e_bar).collect();
    let inputs = a["inputs"].as_array().unwrap();
    assert_eq!(inputs.len(), 2);
    for (c, u) in inputs.iter().zip([&u1, &u2]) {
        let u = &u[2..];
        let u_bar = mean(u);
        let v: Vec<f64> = u.iter().map(|x| x - u_bar).collect();
        let cov = |a: &[f64], b: &[f64], tau: usize| {
            a[tau..].iter().zip(b).map(|(x, y)| x * y).sum::<f64>() / n as f64
        };
        let scale = (cov(&e, &e, 0) * cov(&v, &v, 0)).sqrt();
        // r_εu(τ) = R_εu(τ) / √(R_ε(0) R_u(0)), ε(t) against u(t − τ); index M + τ.
        for tau in [0usize, 3] {
            let want = cov(&e, &v, tau) / scale;
            let got = num(&c["cross_correlation"][m + tau]);
            assert!(
                (got - want).abs() < 1e-6,
                "{} lag {tau}: {got} vs {want}",
                c["name"]
            );
        }
    }
    assert_eq!(
        (inputs[0]["name"].as_str(), inputs[1]["name"].as_str()),
        (Some("u1"), Some("u2"))
    );
}

#[test]
fn several_inputs_detrended_keep_each_operating_point_and_put_it_back() {
    let dir = tempfile::tempdir().unwrap();
    let (_, u1, u2, y) = disturbed_miso(dir.path(), "d.csv", 0.0);
    // Operating point away from zero.
    let u1: Vec<f64> = u1.iter().map(|v| v + 5.0).collect();
    let u2: Vec<f64> = u2.iter().map(|v| v - 3.0).collect();
    let y: Vec<f64> = y.iter().map(|v| v + 10.0).collect();
    let f = dir.path().join("op.csv");
    write_u1u2y(&f, &u1, &u2, &y);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (m1, m2, my) = (mean(&u1), mean(&u2), mean(&y));
    let d = |v: &[f64], m: f64| v.iter().map(|x| x - m).collect::<Vec<f64>>();
    let (d1, d2, dy) = (d(&u1, m1), d(&u2, m2), d(&y, my));
    let (rows, z) = miso_rows(&d1, &d2, &dy);
    let theta = normal_equations(&rows, &z);
    let out = dir.path().join("dt.json");
    let model = dir.path().join("dt_model.json");
    miso_identify(
        s(&f),
        "arx",
        "ls",
        &[
            "--detrend",
            "mean",
            "--json",
            s(&out),
            "--save-model",
            s(&model),
        ],
    );
    let j = json(&out);
    let mj = &j["model"];
    let i = mj["inputs"].as_array().unwrap();
    let got = [
        num(&mj["a"][0]),
        num(&i[0]["b"][0]),
        num(&i[0]["b"][1]),
        num(&i[1]["b"][0]),
    ];
    for (g, w) in got.iter().zip(&theta) {
        assert!(
            (g - w).abs() < 1e-8 * (1.0 + w.abs()),
            "{got:?} vs {theta:?}"
        );
    }
    let op = &mj["operating_point"];
    for (g, w) in [(&op["u"][0], m1), (&op["u"][1], m2), (&op["y"], my)] {
        assert!((num(g) - w).abs() < 1e-9 * (1.0 + w.abs()), "{op}");
    }
    // validate puts the operating point back: the one-step prediction is ȳ plus the deviation model's
    // prediction from the measured deviations.
    let csv = dir.path().join("v.csv");
    run(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&f),
        "--ts",
        "0.1",
        "--out",
        s(&csv),
    ]);
    let got = read_columns(&csv);
    for k in 2..y.len() {
        let want = my - theta[0] * dy[k - 1]
            + theta[1] * d1[k - 1]
            + theta[2] * d1[k - 2]
            + theta[3] * d2[k - 2];
        assert!((got["y_pred"][k] - want).abs() < 1e-6, "k = {k}");
    }
}

#[test]
fn several_inputs_merged_pool_the_rows_of_each_record_and_none_across() {
    let dir = tempfile::tempdir().unwrap();
    let (fa, a1, a2, ay) = disturbed_miso(dir.path(), "a.csv", 0.0);
    // The second record: the same system on the inputs reversed in time, another disturbance phase.
    let (b1, b2): (Vec<f64>, Vec<f64>) = (
        a1.iter().rev().copied().collect(),
        a2.iter().rev().copied().collect(),
    );
    let mut by = vec![0.0; b1.len()];
    for k in 2..by.len() {
        by[k] = 0.5 * by[k - 1] + b1[k - 1] + 0.3 * b1[k - 2] - 2.0 * b2[k - 2];
    }
    for (k, v) in by.iter_mut().enumerate() {
        *v += 0.4 * (2.3 * k as f64 + 1.0).sin() + 0.7;
    }
    let fb = dir.path().join("b.csv");
    write_u1u2y(&fb, &b1, &b2, &by);
    let (mut rows, mut z) = miso_rows(&a1, &a2, &ay);
    let (rb, zb) = miso_rows(&b1, &b2, &by);
    rows.extend(rb);
    z.extend(zb);
    let theta = normal_equations(&rows, &z);
    let out = dir.path().join("merged.json");
    run(&[
        "identify",
        "--data",
        s(&fa),
        s(&fb),
        "--merge",
        "--u-col",
        "u1,u2",
        "--nb",
        "2,1",
        "--nk",
        "1,2",
        "--na",
        "1",
        "--structure",
        "arx",
        "--method",
        "ls",
        "--ts",
        "0.1",
        "--json",
        s(&out),
    ]);
    let j = json(&out);
    let mj = &j["model"];
    let i = mj["inputs"].as_array().unwrap();
    let got = [
        num(&mj["a"][0]),
        num(&i[0]["b"][0]),
        num(&i[0]["b"][1]),
        num(&i[1]["b"][0]),
    ];
    for (g, w) in got.iter().zip(&theta) {
        assert!(
            (g - w).abs() < 1e-8 * (1.0 + w.abs()),
            "{got:?} vs {theta:?}"
        );
    }
    let records = j["records"].as_array().unwrap();
    assert_eq!(records.len(), 2);
    assert_eq!(
        records[0]["metrics"]["n"].as_u64().unwrap() + records[1]["metrics"]["n"].as_u64().unwrap(),
        j["metrics"]["estimation"]["n"].as_u64().unwrap()
    );
    // Detrending merged records is refused by name, not silently done per record.
    let err = fails(&[
        "identify",
        "--data",
        s(&fa),
        s(&fb),
        "--merge",
        "--u-col",
        "u1,u2",
        "--method",
        "ls",
        "--detrend",
        "mean",
        "--ts",
        "0.1",
    ]);
    assert!(
        err.contains("--merge") && err.contains("--detrend"),
        "{err}"
    );
    // So are validation rows without saying of which file.
    let err = fails(&[
        "identify",
        "--data",
        s(&fa),
        s(&fb),
        "--merge",
        "--u-col",
        "u1,u2",
        "--method",
        "ls",
        "--val-rows",
        "300..",
        "--ts",
        "0.1",
    ]);
    assert!(
        err.contains("--val-rows") && err.contains("--validation"),
        "{err}"
    );
}

// Two inputs, u1 through a deadzone whose right breakpoint b_r = 1 is one of u1's levels
// (-3, -2, -1.5, 0, 1, 2, 3), u2 linear: y(k) = 0.5 y(k-1) + f(u1(k-1)) - 2 u2(k-1), noise-free. The
// key-term estimate is exact, so b_r = 1 sits on a level: the single-input warning appears, naming the
// input, b_r (u1) loses its standard deviation, and b_l = -1 (between levels) gets no warning.
#[test]
fn several_input_deadzone_warnings_name_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let levels = [-3.0, -2.0, -1.5, 0.0, 1.0, 2.0, 3.0];
    let n = 700;
    let pick = ipa_testdata::white(n / 5 + 1, 17);
    let u1: Vec<f64> = (0..n)
        .map(|k| {
            let r = (pick[k / 5] / (2.0 * 3f64.sqrt()) + 0.5) * levels.len() as f64;
            levels[(r as usize).min(levels.len() - 1)]
        })
        .collect();
    let u2 = ipa_testdata::white(n, 23);
    let f = |v: f64| {
        if v >= 1.0 {
            1.2 * (v - 1.0)
        } else if v <= -1.0 {
            0.8 * (v + 1.0)
        } else {
            0.0
        }
    };
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.5 * y[k - 1] + f(u1[k - 1]) - 2.0 * u2[k - 1];
    }
    let data = dir.path().join("levels.csv");
    write_u1u2y(&data, &u1, &u2, &y);
    let out = dir.path().join("levels.json");
    run(&[
        "identify",
        "--data",
        s(&data),
        "--u-col",
        "u1,u2",
        "--nb",
        "1",
        "--nk",
        "1",
        "--na",
        "1",
        "--structure",
        "hammerstein",
        "--linear-inputs",
        "u2",
        "--method",
        "ls",
        "--ts",
        "0.1",
        "--json",
        s(&out),
    ]);
    let j = json(&out);
    let d = &j["model"]["inputs"][0]["deadzone"];
    assert!((num(&d["b_r"]) - 1.0).abs() < 1e-9, "{d}");
    assert!((num(&d["b_l"]) + 1.0).abs() < 1e-9, "{d}");
    let warnings: Vec<&str> = j["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(
        warnings
            .iter()
            .any(|w| w.starts_with("input u1: b_r = 1.000000 lies on the input level 1")),
        "{warnings:?}"
    );
    assert!(!warnings.iter().any(|w| w.contains("b_l")), "{warnings:?}");
    let param = |name: &str| {
        j["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| label(p) == name)
            .unwrap()
            .clone()
    };
    assert!(param("b_r (u1)")["std"].is_null());
    assert!(num(&param("b_l (u1)")["std"]) >= 0.0);
}

// The Hammerstein guard with several inputs, from the binary: RLS with forgetting 0.8 and one pass on
// the noisy two-input Hammerstein record ends on an estimate fitted to its last samples, which simulates
// the record far worse than the linear ARX least-squares model of the same orders. Without --fallback a
// warning says so; with it the linear model is returned, written as a Hammerstein model: a1 and the B of
// each input from the normal equations on rows [−y(k−1), u1(k−1), u1(k−2), u2(k−2)] (computed here),
// b_l = b_r = 0, m_l = m_r = b1(u1), b(u1) = (1, b2/b1).
#[test]
fn several_input_hammerstein_estimates_far_worse_than_the_linear_start_are_flagged_or_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let f = noisy_miso(dir.path(), &valve, 2.0, "ham.csv");
    let run_rls = |extra: &[&str], out: &Path| {
        let mut args = vec![
            "identify",
            "--data",
            s(&f),
            "--u-col",
            "u1,u2",
            "--nb",
            "2,1",
            "--nk",
            "1,2",
            "--na",
            "1",
            "--linear-inputs",
            "u2",
            "--method",
            "rls",
            "--forgetting",
            "0.8",
            "--passes",
            "1",
            "--rls-form",
            "ud",
            "--ts",
            "0.1",
            "--json",
            s(out),
        ];
        args.extend_from_slice(extra);
        run(&args);
        json(out)
    };
    let texts = |j: &serde_json::Value| -> Vec<String> {
        j["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .map(|w| w.as_str().unwrap().to_string())
            .collect()
    };
    let plain = run_rls(&[], &dir.path().join("plain.json"));
    assert!(
        texts(&plain)
            .iter()
            .any(|w| w.contains("far worse than the linear start")
                && w.contains("the linear ARX model of the same orders does better")),
        "{:?}",
        texts(&plain)
    );
    let fb = run_rls(&["--fallback"], &dir.path().join("fb.json"));
    assert!(
        texts(&fb)
            .iter()
            .any(|w| w.starts_with("fallback used: the linear ARX least-squares model")),
        "{:?}",
        texts(&fb)
    );
    // The fallback's fixed breakpoints are explained by that warning, not called singular.
    assert!(
        !texts(&fb)
            .iter()
            .any(|w| w.contains("could not be computed")),
        "{:?}",
        texts(&fb)
    );
    let c = read_columns(&f);
    let (u1, u2, y) = (&c["u1"], &c["u2"], &c["y"]);
    let rows: Vec<Vec<f64>> = (2..y.len())
        .map(|k| vec![-y[k - 1], u1[k - 1], u1[k - 2], u2[k - 2]])
        .collect();
    let th = normal_equations(&rows, &y[2..]);
    let m = &fb["model"];
    let i = m["inputs"].as_array().unwrap();
    let d = &i[0]["deadzone"];
    for (got, want) in [
        (&m["a"][0], th[0]),
        (&d["b_l"], 0.0),
        (&d["b_r"], 0.0),
        (&d["m_l"], th[1]),
        (&d["m_r"], th[1]),
        (&i[0]["b"][0], 1.0),
        (&i[0]["b"][1], th[2] / th[1]),
        (&i[1]["b"][0], th[3]),
    ] {
        assert!((num(got) - want).abs() < 1e-8, "{m} vs {th:?}");
    }
}

// Audit s30 M-2: one input value of 1e200 among ±1 (data row 201, file line 202: the header is line 1)
// made every estimate on the record meaningless (b1 = 5e-201) with exit 0 and no row named. The reader
// names it at its line and column, identify warns (and --strict fails), validate prints it before its
// overflow error. An impulse (one 1 among 0s) is no outlier, nor is a value 1e5 times the others.
#[test]
fn a_lone_outlier_is_named_at_its_line_and_column() {
    let dir = tempfile::tempdir().unwrap();
    let n = 500;
    let u: Vec<f64> = (0..n)
        .map(|k| if (k * 37 + 11) % 7 < 3 { 1.0 } else { -1.0 })
        .collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.9 * y[k - 1] + 0.5 * u[k - 1];
    }
    // identify ARX(1, 1, 1) by LS on `f` with `extra` flags.
    let id = |f: &Path, extra: &[&str]| {
        let mut a = vec![
            "identify",
            "--data",
            s(f),
            "--ts",
            "0.1",
            "--structure",
            "arx",
            "--na",
            "1",
            "--nb",
            "1",
            "--nk",
            "1",
            "--method",
            "ls",
        ];
        a.extend_from_slice(extra);
        bin().args(&a).output().unwrap()
    };
    let mut bad = u.clone();
    bad[201] = 1e200;
    let f = dir.path().join("huge.csv");
    write_uy(&f, &bad, &y);
    let o = id(&f, &[]);
    let err = stdout_and_stderr(&o);
    assert!(o.status.success(), "{err}");
    let named = "huge.csv:203:1: u = 1e200 is at least 1e6 times every other value";
    assert!(err.contains(named), "{err}");
    assert_eq!(id(&f, &["--strict"]).status.code(), Some(1));
    // The streamed reader names it at the same place (found in its first pass), a MAT-file by the
    // element's 1-based index in its variable.
    let err = stdout_and_stderr(&id(&f, &["--stream", "on"]));
    assert!(err.contains(named), "{err}");
    let mat = dir.path().join("huge.mat");
    common::write_mat(&mat, &["u", "y"], &[&bad, &y]);
    let err = stdout_and_stderr(&id(&mat, &[]));
    let named_mat = "huge.mat: variable 'u' element 202 (1-based): u = 1e200 is at least 1e6 times";
    assert!(err.contains(named_mat), "{err}");
    // validate fails on the overflow, naming the row first.
    let model = dir.path().join("m.json");
    let clean = dir.path().join("clean.csv");
    write_uy(&clean, &u, &y);
    assert!(id(&clean, &["--save-model", s(&model)]).status.success());
    let o = bin()
        .args(["validate", "--model", s(&model), "--data", s(&f)])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr).to_string();
    assert!(!o.status.success() && err.contains(named), "{err}");
    // Not outliers: an impulse among zeros, a value 1e5 times the others.
    for (name, value, others) in [("impulse.csv", 1.0, 0.0), ("big.csv", 1e5, 1.0)] {
        let mut v: Vec<f64> = u.iter().map(|x| x * others).collect();
        v[201] = value;
        let f = dir.path().join(name);
        write_uy(&f, &v, &y);
        for stream in ["off", "on"] {
            let err = stdout_and_stderr(&id(&f, &["--stream", stream]));
            assert!(!err.contains("outlier"), "{name}, --stream {stream}: {err}");
        }
    }
}

// Audit s31 L-1: several inputs from a MAT-file (`--u-col u1,u2`) are several variables, as several
// columns of a CSV (the list was looked up as one variable name and refused). The estimate equals the
// normal-equations solve of the same record, as the CSV's does.
#[test]
fn several_inputs_are_read_from_a_mat_file() {
    let dir = tempfile::tempdir().unwrap();
    let (_, u1, u2, y) = disturbed_miso(dir.path(), "d.csv", 0.0);
    let (rows, z) = miso_rows(&u1, &u2, &y);
    let theta = normal_equations(&rows, &z);
    let n = y.len();
    let f = dir.path().join("d.mat");
    std::fs::write(
        &f,
        mat_file(
            &[("u1", n, 1, &u1), ("u2", n, 1, &u2), ("y", n, 1, &y)],
            true,
        ),
    )
    .unwrap();
    let out = dir.path().join("mat.json");
    miso_identify(s(&f), "arx", "ls", &["--json", s(&out)]);
    let j = json(&out);
    let params = j["parameters"].as_array().unwrap();
    assert_eq!(params.len(), theta.len());
    for (prm, want) in params.iter().zip(&theta) {
        let got = num(&prm["value"]);
        assert!(
            (got - want).abs() < 1e-9 * want.abs().max(1.0),
            "{got} vs {want}"
        );
    }
}

// Audit s30 L-13: a record whose output lies wholly outside the model's estimation data (y near 50
// there; near 0 here, beyond 10 % of the span) is said by validate; a record inside it is not.
#[test]
fn validate_says_an_output_wholly_outside_the_estimation_data() {
    let dir = tempfile::tempdir().unwrap();
    let u = input(300);
    // y = 0.5 y(k−1) + 2 u(k−1) + 25: around 50 + 4u; the same plant without the constant: around 4u.
    let y_est = arx1(&u, -0.5, 2.0, 25.0, 50.0);
    let y_far = arx1(&u, -0.5, 2.0, 0.0, 0.0);
    let (est, far) = (dir.path().join("est.csv"), dir.path().join("far.csv"));
    write_uy(&est, &u, &y_est);
    write_uy(&far, &u, &y_far);
    let model = dir.path().join("m.json");
    run(&[
        "identify",
        "--data",
        s(&est),
        "--ts",
        "0.1",
        "--structure",
        "arx",
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
        "--offset",
        "--method",
        "ls",
        "--save-model",
        s(&model),
    ]);
    // In memory and read in passes (`--stream on`: the output's extremes of the metrics' pass).
    let said = |f: &Path, stream: &str| {
        stdout_and_stderr(
            &bin()
                .args([
                    "validate",
                    "--model",
                    s(&model),
                    "--data",
                    s(f),
                    "--stream",
                    stream,
                ])
                .output()
                .unwrap(),
        )
        .contains("wholly outside the model's estimation data")
    };
    for stream in ["off", "on"] {
        assert!(said(&far, stream), "--stream {stream}");
        assert!(!said(&est, stream), "--stream {stream}");
    }
}

// Audit s30 L-14: `simulate --plant model:NARX` without --y0 started at 100 (mm), outside any record not
// in mm around 100, and failed; it now starts at the middle of the outputs the model was estimated on
// (its data_range), computed here from the record.
#[test]
fn a_narx_model_is_simulated_from_the_middle_of_its_data() {
    let dir = tempfile::tempdir().unwrap();
    let u: Vec<f64> = input(400).iter().map(|v| 0.5 * v - 0.5).collect();
    let mut y = vec![4.5; u.len()];
    for k in 1..u.len() {
        y[k] = 2.25 + 0.5 * y[k - 1] + 0.5 * u[k - 1] + 0.02 * u[k - 1] * u[k - 1];
    }
    let f = dir.path().join("n.csv");
    write_uy(&f, &u, &y);
    let model = dir.path().join("narx.json");
    run(&[
        "identify",
        "--data",
        s(&f),
        "--ts",
        "0.1",
        "--structure",
        "narx",
        "--degree",
        "2",
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
        "--offset",
        "--save-model",
        s(&model),
    ]);
    let out = dir.path().join("sim.csv");
    let spec = format!("model:{}", s(&model));
    run(&[
        "simulate",
        "--plant",
        &spec,
        "--input",
        "step:0.2@5",
        "--samples",
        "30",
        "--out",
        s(&out),
    ]);
    let text = std::fs::read_to_string(&out).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = header.iter().position(|h| *h == "y").unwrap();
    let first: f64 = text
        .lines()
        .nth(1)
        .unwrap()
        .split(',')
        .nth(col)
        .unwrap()
        .parse()
        .unwrap();
    let (lo, hi) = y
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    assert!(
        (first - 0.5 * (lo + hi)).abs() < 1e-9,
        "{first} vs {}",
        0.5 * (lo + hi)
    );
}
