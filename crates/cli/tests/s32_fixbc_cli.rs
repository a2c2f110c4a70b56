//! Session 32, fixbc (audit s32 M-2): MATLAB's LossFcn, FPE and normalised AIC of every model, from the
//! model's own one-step prediction errors. Expectations by a hand loop over `validate --out`'s `y` and
//! `y_pred` columns.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::path::Path;

mod common;
use common::{run_json, s};

/// y(k) = 1.5 y(k−1) − 0.7 y(k−2) + 0.5 u(k−1) + 0.3 u(k−2) from rest, u a staircase of random levels
/// held 20 samples, then measured with uniform noise ±0.5 added to y (output error: the ARX and the
/// OE estimates differ). Written to `dir/rec.csv` at Ts = 0.01 s.
fn record(dir: &Path) -> std::path::PathBuf {
    let mut rng = common::lcg(32);
    let mut level = 0.0;
    let (u, y) = common::arx_signals(1500, &[1.5, -0.7], &[0.5, 0.3], |k| {
        if k % 20 == 0 {
            level = 20.0 * rng.unit() - 10.0;
        }
        level
    });
    let mut noise = common::lcg(7);
    let y: Vec<f64> = y.iter().map(|v| v + noise.unit() - 0.5).collect();
    common::write_tuy(dir, "rec.csv", 0.01, &u, &y)
}

/// The columns `name` of a CSV file with a header.
fn column(path: &Path, name: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let i = lines
        .next()
        .unwrap()
        .split(',')
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name}"));
    lines
        .map(|l| l.split(',').nth(i).unwrap().parse().unwrap())
        .collect()
}

fn close(a: f64, b: f64, what: &str) {
    assert!(
        (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-300),
        "{what}: {a} vs {b}"
    );
}

fn num(m: &serde_json::Value, key: &str) -> f64 {
    m[key]
        .as_f64()
        .unwrap_or_else(|| panic!("metrics.{key} is not a number: {m}"))
}

// For an ARX model (least squares) and an output-error model of the same record: LossFcn = mean e²,
// FPE = LossFcn (N + p)/(N − p) and nAIC = ln LossFcn + 2p/N over the rows k ≥ k0 of e = y − y_pred
// (`validate --out`, summed here), in `validate --json`, `identify --json` (same record) and
// `validate --stream on` alike. For the ARX model LossFcn = 2V, FPE = 2·FPE(eq. 15) and nAIC = the
// equation-error AIC; for the OE model y_pred is its simulation, so LossFcn is the simulation error's.
#[test]
fn matlab_loss_fpe_and_aic_are_the_models_own_prediction_errors() {
    let dir = tempfile::tempdir().unwrap();
    let rec = record(dir.path());
    for method in ["ls", "oe"] {
        let model = dir.path().join(format!("{method}.json"));
        let mut args = common::identify_arx(&rec, "2", "2", method);
        args.extend(["--save-model", s(&model)]);
        let id = run_json(dir.path(), &args);
        let out = dir.path().join(format!("{method}_out.csv"));
        let val = run_json(
            dir.path(),
            &[
                "validate",
                "--model",
                s(&model),
                "--data",
                s(&rec),
                "--out",
                s(&out),
            ],
        );
        let m = &val["metrics"]["validation"];
        let (n, p) = (m["n"].as_u64().unwrap() as usize, m["p"].as_u64().unwrap());
        let (y, pred) = (column(&out, "y"), column(&out, "y_pred"));
        let k0 = y.len() - n;
        let mut sse = 0.0;
        for k in k0..y.len() {
            sse += (y[k] - pred[k]) * (y[k] - pred[k]);
        }
        let (nf, pf) = (n as f64, p as f64);
        let loss_fcn = sse / nf;
        let fpe = loss_fcn * (nf + pf) / (nf - pf);
        let aic = loss_fcn.ln() + 2.0 * pf / nf;
        close(num(m, "loss_fcn"), loss_fcn, &format!("{method} loss_fcn"));
        close(num(m, "fpe_matlab"), fpe, &format!("{method} fpe_matlab"));
        close(num(m, "aic_matlab"), aic, &format!("{method} aic_matlab"));
        // identify's estimation figures are the same record's.
        let e = &id["metrics"]["estimation"];
        for key in ["loss_fcn", "fpe_matlab", "aic_matlab"] {
            close(
                num(e, key),
                num(m, key),
                &format!("{method} identify {key}"),
            );
        }
        // Read in passes: the same numbers.
        let streamed = run_json(
            dir.path(),
            &[
                "validate",
                "--model",
                s(&model),
                "--data",
                s(&rec),
                "--stream",
                "on",
            ],
        );
        let sm = &streamed["metrics"]["validation"];
        for key in ["loss_fcn", "fpe_matlab", "aic_matlab"] {
            close(
                num(sm, key),
                num(m, key),
                &format!("{method} streamed {key}"),
            );
        }
        if method == "ls" {
            // The ARX predictor is the equation error: LossFcn = 2V exactly as MATLAB's.
            close(loss_fcn, 2.0 * num(m, "loss"), "ls LossFcn = 2V");
            close(fpe, 2.0 * num(m, "fpe"), "ls FPE = 2 FPE(eq. 15)");
            close(aic, num(m, "aic"), "ls nAIC = AIC");
        } else {
            // The OE predictor is the simulation from the estimated initial outputs.
            assert_eq!(column(&out, "y_sim"), pred);
            assert!(
                (loss_fcn - 2.0 * num(m, "loss")).abs() > 1e-3 * loss_fcn,
                "the OE model's LossFcn is its simulation error's, not 2V: {m}"
            );
            close(loss_fcn, 2.0 * num(m, "loss_sim"), "oe LossFcn = 2 V_sim");
        }
    }
}

// The text table names MATLAB's rows, and the footnote no longer calls the equation-error figures
// MATLAB's (audit s32 M-2).
#[test]
fn the_text_table_names_matlabs_rows() {
    let dir = tempfile::tempdir().unwrap();
    let rec = record(dir.path());
    let out = common::run(&common::identify_arx(&rec, "2", "2", "oe"));
    assert!(out.status.success(), "{}", common::stderr(&out));
    let text = common::stdout(&out);
    for row in [
        "LossFcn (MATLAB)",
        "FPE (MATLAB)",
        "nAIC (MATLAB aic)",
        "AIC (eq. error)",
    ] {
        assert!(text.contains(row), "no row {row}: {text}");
    }
    assert!(!text.contains("half of MATLAB's"), "{text}");
}

// A polynomial NARX model: MATLAB's figures from its one-step prediction errors too, p = the number of
// its terms (the model file's `terms`), by the same hand loop over `validate --out`.
#[test]
fn a_narx_model_reports_matlabs_figures_of_its_one_step_errors() {
    let dir = tempfile::tempdir().unwrap();
    let rec = record(dir.path());
    let model = dir.path().join("narx.json");
    let args = [
        "identify",
        "--data",
        s(&rec),
        "--structure",
        "narx",
        "--na",
        "2",
        "--nb",
        "2",
        "--degree",
        "2",
        "--save-model",
        s(&model),
    ];
    run_json(dir.path(), &args);
    let p = common::json(&model)["model"]["terms"]
        .as_array()
        .unwrap()
        .len() as f64;
    let out = dir.path().join("narx_out.csv");
    let val = run_json(
        dir.path(),
        &[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&rec),
            "--out",
            s(&out),
        ],
    );
    let m = &val["metrics"]["validation"];
    let n = m["n"].as_u64().unwrap() as usize;
    let (y, pred) = (column(&out, "y"), column(&out, "y_pred"));
    let mut sse = 0.0;
    for k in y.len() - n..y.len() {
        sse += (y[k] - pred[k]) * (y[k] - pred[k]);
    }
    let nf = n as f64;
    let loss_fcn = sse / nf;
    close(num(m, "loss_fcn"), loss_fcn, "narx loss_fcn");
    close(
        num(m, "fpe_matlab"),
        loss_fcn * (nf + p) / (nf - p),
        "narx fpe_matlab",
    );
    close(
        num(m, "aic_matlab"),
        loss_fcn.ln() + 2.0 * p / nf,
        "narx aic_matlab",
    );
}
