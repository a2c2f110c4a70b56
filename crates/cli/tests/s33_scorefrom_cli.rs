//! `validate --score-from K` (session 33): every figure over the samples k >= max(K, k0) only, as the
//! nonlinear_benchmarks records are scored after their state-initialisation window. The expectations
//! are computed here by hand loops from `validate --out`'s columns (y, y_sim, y_sim_y0meas, residual),
//! never from the figures under test. Through the binary.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;

use serde_json::Value;

mod common;
use common::{bin, json, lcg, stderr, write_csv};

/// The samples scored from: past the transient of [`transient_record`].
const K: usize = 40;

/// y(k) = 1.5 y(k−1) − 0.7 y(k−2) + u(k−1) + 0.5 u(k−2) + 0.6 u(k−1)³/9 + e(k), u a staircase in
/// [−3, 3] held 4 samples, e uniform in ±0.05 (LCG `seed`), started from y(0) = y(1) = `y_start`: a
/// record whose first samples are an initial-state transient when y_start is far from rest. The cubic
/// term gives the NARX and Hammerstein models something to fit. Test data computed here. Returns (u, y).
fn transient_record(n: usize, seed: u64, y_start: f64) -> (Vec<f64>, Vec<f64>) {
    let mut r = lcg(seed);
    let mut u = Vec::with_capacity(n);
    let mut level = 0.0;
    for k in 0..n {
        if k % 4 == 0 {
            level = 6.0 * r.unit() - 3.0;
        }
        u.push(level);
    }
    let mut y = vec![y_start; n];
    for k in 2..n {
        let e = 0.1 * r.unit() - 0.05;
        y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2]
            + u[k - 1]
            + 0.5 * u[k - 2]
            + 0.6 * u[k - 1].powi(3) / 9.0
            + e;
    }
    (u, y)
}

/// Runs `ipa-sysid ARGS` in `dir`; it must succeed. Returns its standard output.
fn ok(dir: &Path, args: &[&str]) -> String {
    let o = bin().current_dir(dir).args(args).output().unwrap();
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// The estimation record est.csv (from rest) and the test record val.csv (from y = 12, far from rest)
/// in `dir`, 600 samples each, t,u,y at Ts = 0.1 s.
fn records(dir: &Path) {
    let (u, y) = transient_record(600, 7, 0.0);
    write_csv(&dir.join("est.csv"), "t,u,y", Some(0.1), &[&u, &y]);
    let (u, y) = transient_record(600, 11, 12.0);
    write_csv(&dir.join("val.csv"), "t,u,y", Some(0.1), &[&u, &y]);
}

/// The model classes `validate` takes, by their `identify` flags (file name, flags).
fn models() -> Vec<(&'static str, Vec<&'static str>)> {
    let lin = ["--na", "2", "--nb", "2", "--nk", "1"];
    let with = |extra: &[&'static str]| lin.iter().chain(extra).copied().collect::<Vec<_>>();
    vec![
        (
            "arx_ls.json",
            with(&["--structure", "arx", "--method", "ls"]),
        ),
        (
            "arx_oe.json",
            with(&["--structure", "arx", "--method", "oe"]),
        ),
        (
            "arx_iv.json",
            with(&["--structure", "arx", "--method", "iv"]),
        ),
        (
            "hammer.json",
            with(&[
                "--structure",
                "hammerstein",
                "--nonlinearity",
                "polynomial",
                "--degree",
                "3",
                "--method",
                "ls",
            ]),
        ),
        ("narx.json", with(&["--structure", "narx", "--degree", "3"])),
    ]
}

/// Identifies every model of [`models`] on est.csv in `dir`.
fn identify_all(dir: &Path) {
    for (file, flags) in models() {
        let mut args = vec!["identify", "--data", "est.csv", "--save-model", file];
        args.extend(flags);
        ok(dir, &args);
    }
}

/// `validate --out`'s rows as (header, rows of cells; an empty cell is None).
fn out_rows(path: &Path) -> (Vec<String>, Vec<Vec<Option<f64>>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(|c| c.parse::<f64>().ok()).collect())
        .collect();
    (header, rows)
}

/// The column `name` of `--out` rows.
fn col(header: &[String], rows: &[Vec<Option<f64>>], name: &str) -> Vec<f64> {
    let i = header.iter().position(|h| h == name).unwrap();
    rows.iter().map(|r| r[i].unwrap()).collect()
}

/// RMSE √(Σ (y − ŷ)² / N) and fit % 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) over k >= from, by a plain loop.
fn rmse_fit(y: &[f64], yhat: &[f64], from: usize) -> (f64, f64) {
    let n = (y.len() - from) as f64;
    let mut mean = 0.0;
    for v in &y[from..] {
        mean += v;
    }
    mean /= n;
    let (mut sse, mut dev) = (0.0, 0.0);
    for k in from..y.len() {
        sse += (y[k] - yhat[k]) * (y[k] - yhat[k]);
        dev += (y[k] - mean) * (y[k] - mean);
    }
    ((sse / n).sqrt(), 100.0 * (1.0 - sse.sqrt() / dev.sqrt()))
}

/// |got − want| within `rel` of |want| (sums in another order round differently).
fn close(got: &Value, want: f64, rel: f64, what: &str) {
    let g = got
        .as_f64()
        .unwrap_or_else(|| panic!("{what}: {got} is not a number"));
    assert!(
        (g - want).abs() <= rel * want.abs().max(1e-12),
        "{what}: {g} vs {want} computed from --out"
    );
}

/// The figures the test checks against its own loops: simulation RMSE and fit (estimated and measured
/// initial outputs), one-step RMSE and fit, MATLAB's LossFcn and FPE (N, p from the loop and the file).
fn check_figures(
    m: &Value,
    header: &[String],
    rows: &[Vec<Option<f64>>],
    from: usize,
    rel: f64,
    what: &str,
) {
    let y = col(header, rows, "y");
    let (rmse, fit) = rmse_fit(&y, &col(header, rows, "y_sim"), from);
    close(&m["rmse_sim"], rmse, rel, &format!("{what} rmse_sim"));
    close(&m["fit_sim_percent"], fit, rel, &format!("{what} fit_sim"));
    let (rmse, fit) = rmse_fit(&y, &col(header, rows, "y_sim_y0meas"), from);
    close(
        &m["rmse_sim_measured"],
        rmse,
        rel,
        &format!("{what} rmse_sim_measured"),
    );
    close(
        &m["fit_sim_measured_percent"],
        fit,
        rel,
        &format!("{what} fit_sim_measured"),
    );
    let (rmse, fit) = rmse_fit(&y, &col(header, rows, "y_pred"), from);
    close(&m["rmse_pred"], rmse, rel, &format!("{what} rmse_pred"));
    close(
        &m["fit_pred_percent"],
        fit,
        rel,
        &format!("{what} fit_pred"),
    );
    // MATLAB's LossFcn = mean e² of the one-step errors (residual = y − y_pred), FPE = LossFcn (N + p)
    // / (N − p).
    let res = col(header, rows, "residual");
    let n = y.len() - from;
    let mut loss = 0.0;
    for e in &res[from..] {
        loss += e * e;
    }
    loss /= n as f64;
    assert_eq!(m["n"].as_u64().unwrap() as usize, n, "{what} N");
    close(&m["loss_fcn"], loss, rel, &format!("{what} loss_fcn"));
    let p = m
        .get("p")
        .and_then(Value::as_u64)
        .map_or_else(|| 0.0, |p| p as f64);
    if p > 0.0 {
        let fpe = loss * (n as f64 + p) / (n as f64 - p);
        close(&m["fpe_matlab"], fpe, rel, &format!("{what} fpe_matlab"));
    }
}

// Every model class validate takes (ARX by ls, oe and iv, a polynomial Hammerstein, a polynomial NARX),
// in memory: the scored RMSE and fit of each simulation and of the one-step prediction, LossFcn and FPE
// equal a hand loop over k >= K of `--out`'s own columns; the simulations are those of a run without
// the option (the first six columns identical); `scored` is 0 before K and 1 from K; the JSON says
// score_from = K, and the text "scored from sample K".
#[test]
fn scored_figures_are_the_columns_from_k_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    records(d);
    identify_all(d);
    let k = K.to_string();
    for (file, _) in models() {
        let text = ok(
            d,
            &[
                "validate",
                "--model",
                file,
                "--data",
                "val.csv",
                "--score-from",
                &k,
                "--out",
                "o.csv",
                "--json",
                "v.json",
            ],
        );
        assert!(
            text.contains(&format!("scored from sample {K} on")),
            "{file}: {text}"
        );
        let doc = json(&d.join("v.json"));
        assert_eq!(doc["score_from"], serde_json::json!(K), "{file}");
        let (header, rows) = out_rows(&d.join("o.csv"));
        assert_eq!(
            header,
            [
                "t",
                "y",
                "y_sim",
                "y_sim_y0meas",
                "y_pred",
                "residual",
                "scored"
            ],
            "{file}"
        );
        assert_eq!(rows.len(), 600, "{file}: every sample written");
        for (i, r) in rows.iter().enumerate() {
            assert_eq!(r[6], Some(if i >= K { 1.0 } else { 0.0 }), "{file} row {i}");
        }
        let m = &doc["metrics"]["validation"];
        check_figures(m, &header, &rows, K, 1e-9, file);
        // The same simulations and predictions without the option: the six columns are the same text,
        // and the figures are those of k >= k0 (here 2: different, the transient is scored).
        ok(
            d,
            &[
                "validate", "--model", file, "--data", "val.csv", "--out", "o0.csv", "--json",
                "v0.json",
            ],
        );
        let with: Vec<String> = std::fs::read_to_string(d.join("o.csv"))
            .unwrap()
            .lines()
            .map(|l| l.rsplit_once(',').unwrap().0.to_string())
            .collect();
        let without: Vec<String> = std::fs::read_to_string(d.join("o0.csv"))
            .unwrap()
            .lines()
            .map(String::from)
            .collect();
        assert_eq!(
            with, without,
            "{file}: the simulations changed with --score-from"
        );
        let doc0 = json(&d.join("v0.json"));
        assert_eq!(doc0["score_from"], serde_json::json!(2), "{file}: k0");
        let (h0, r0) = out_rows(&d.join("o0.csv"));
        check_figures(&doc0["metrics"]["validation"], &h0, &r0, 2, 1e-9, file);
        let (r_k, r_0) = (
            m["rmse_sim_measured"].as_f64(),
            doc0["metrics"]["validation"]["rmse_sim_measured"].as_f64(),
        );
        assert_ne!(r_k, r_0, "{file}: scoring from K changed nothing");
    }
}

// Read in passes (`--stream on`, the single-input linear models it takes): the same scored figures as
// the hand loop over the in-memory run's `--out` columns (the passes sum in another order: 1e-9), and
// the same JSON key.
#[test]
fn streamed_scored_figures_are_the_columns_from_k_on() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    records(d);
    identify_all(d);
    let k = K.to_string();
    for file in ["arx_ls.json", "arx_oe.json", "arx_iv.json", "hammer.json"] {
        ok(
            d,
            &[
                "validate",
                "--model",
                file,
                "--data",
                "val.csv",
                "--score-from",
                &k,
                "--out",
                "o.csv",
            ],
        );
        let text = ok(
            d,
            &[
                "validate",
                "--model",
                file,
                "--data",
                "val.csv",
                "--score-from",
                &k,
                "--stream",
                "on",
                "--json",
                "s.json",
            ],
        );
        assert!(
            text.contains(&format!("scored from sample {K} on")),
            "{file}: {text}"
        );
        let doc = json(&d.join("s.json"));
        assert_eq!(doc["score_from"], serde_json::json!(K), "{file}");
        let (header, rows) = out_rows(&d.join("o.csv"));
        check_figures(
            &doc["metrics"]["validation"],
            &header,
            &rows,
            K,
            1e-9,
            &format!("{file} streamed"),
        );
    }
}

// A K at or past the record's end (600 samples), or leaving no more samples than the model's
// parameters (ARX (2, 2, 1): p = 4, so K = 596 leaves 4), is refused naming --score-from and the
// record's length, exit 2, and nothing is written — in memory, read in passes and for a NARX model.
// K = 595 leaves 5 > 4 and is taken.
#[test]
fn a_start_past_the_record_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    records(d);
    identify_all(d);
    let cases: [(&str, &str, &[&str]); 5] = [
        ("arx_ls.json", "600", &[]),
        ("arx_ls.json", "596", &[]),
        ("arx_ls.json", "5000", &["--stream", "on"]),
        ("arx_ls.json", "596", &["--stream", "on"]),
        ("narx.json", "600", &[]),
    ];
    for (file, k, extra) in cases {
        let mut args = vec![
            "validate",
            "--model",
            file,
            "--data",
            "val.csv",
            "--score-from",
            k,
            "--json",
            "r.json",
        ];
        if extra.is_empty() {
            args.extend(["--out", "r.csv"]);
        }
        args.extend(extra.iter().copied());
        let o = bin().current_dir(d).args(&args).output().unwrap();
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("--score-from") && err.contains("600 samples"),
            "{args:?}: {err}"
        );
        assert!(
            !d.join("r.json").exists() && !d.join("r.csv").exists(),
            "{args:?}: written"
        );
    }
    ok(
        d,
        &[
            "validate",
            "--model",
            "arx_ls.json",
            "--data",
            "val.csv",
            "--score-from",
            "595",
        ],
    );
}

// A K before the model's first predicted sample k0 = 2 scores from k0: the JSON says 2, the text says
// so, and the figures are those of the run without the option.
#[test]
fn a_start_before_k0_scores_from_k0() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    records(d);
    identify_all(d);
    let text = ok(
        d,
        &[
            "validate",
            "--model",
            "arx_ls.json",
            "--data",
            "val.csv",
            "--score-from",
            "1",
            "--json",
            "a.json",
        ],
    );
    assert!(
        text.contains("scored from sample 2 on, the model's first predicted sample k0"),
        "{text}"
    );
    ok(
        d,
        &[
            "validate",
            "--model",
            "arx_ls.json",
            "--data",
            "val.csv",
            "--json",
            "b.json",
        ],
    );
    let (a, b) = (json(&d.join("a.json")), json(&d.join("b.json")));
    assert_eq!(a["score_from"], serde_json::json!(2));
    assert_eq!(a["metrics"], b["metrics"]);
}
