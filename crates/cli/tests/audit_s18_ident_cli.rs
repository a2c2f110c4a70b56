//! Audit s18 identification findings through the binary: the residual tests can reject on short
//! records (H-1), detrended estimation metrics are scored on the detrended data (M-3), and the other
//! figures a MATLAB user checks (L-3, L-6, L-7).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;

use std::path::Path;

use common::{bin, identify_arx, run_json, write_tuy};

/// A ±1 pseudo-random binary input (xorshift64), deterministic.
fn prbs(n: usize, seed: u64) -> Vec<f64> {
    let mut x = seed.max(1);
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            if x >> 63 == 1 {
                1.0
            } else {
                -1.0
            }
        })
        .collect()
}

/// Uniform noise in [−1, 1) (xorshift64), deterministic.
fn noise(n: usize, seed: u64) -> Vec<f64> {
    let mut x = seed.max(1);
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        })
        .collect()
}

fn text_of(dir: &Path, args: &[&str]) -> (i32, String, String) {
    let out = bin().current_dir(dir).args(args).output().unwrap();
    (
        out.status.code().unwrap(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

// H-1: the plant y(k) = 0.5 y(k−1) + u(k−4) + small noise has a delay of 4 samples; an ARX (1,1,1)
// leaves u(k−4) in its residual (correlation ≈ 0.9 at lag +4 by construction). On 60 rows (59
// residuals, M = 25) the portmanteau S = N·R² ≤ 59 can never exceed the 1 % point of χ²(51), 77.39, so
// the verdict must come from the per-lag check and be "NOT independent", with the short-record note.
#[test]
fn a_wrong_delay_on_a_short_record_is_not_independent() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 60;
    let (u, w) = (prbs(n, 7), noise(n, 11));
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.5 * y[k - 1] + if k >= 4 { u[k - 4] } else { 0.0 } + 0.05 * w[k];
    }
    write_tuy(tmp.path(), "short.csv", 0.01, &u, &y);
    let args = [
        identify_arx(Path::new("short.csv"), "1", "1", "ls"),
        vec!["--nk", "1"],
    ]
    .concat();
    let doc = run_json(tmp.path(), &args);
    let r = &doc["residuals"]["estimation"];
    let nres = r["n"].as_f64().unwrap();
    assert_eq!(nres, 59.0);
    assert!(r["cross_statistic"].as_f64().unwrap() <= nres * (1.0 + 1e-12));
    assert!(
        r["cross_p"].as_f64().unwrap() >= 0.01,
        "S alone would accept"
    );
    assert!((r["cross_statistic_critical"].as_f64().unwrap() - 77.385_962).abs() < 1e-5);
    // The lag-4 correlation is beyond the joint band 3.724/√59 (normal point at 0.01/51, two-sided).
    let r4 = r["cross_correlation"][25 + 4].as_f64().unwrap();
    assert!(r4.abs() > 3.724 / nres.sqrt(), "r(4) = {r4}");
    assert_eq!(r["independent"], false);
    let (code, stdout, _) = text_of(tmp.path(), &args);
    assert_eq!(code, 0);
    assert!(stdout.contains("NOT independent"), "{stdout}");
    // 57.34 (M = 17) < 59 < 59.89 (M = 18), scipy chi2.isf(0.01, 35) and chi2.isf(0.01, 37).
    assert!(
        stdout.contains("59 rows are too few for the independence statistic at M = 25")
            && stdout.contains("--resid-lags 17 or fewer"),
        "{stdout}"
    );
}

/// s(k) − (s̄ + β (k − k̄)) + s̄: the least-squares line's drift removed, the mean kept (by hand).
fn undrift(s: &[f64]) -> Vec<f64> {
    let n = s.len() as f64;
    let mean = s.iter().sum::<f64>() / n;
    let kbar = (n - 1.0) / 2.0;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, v) in s.iter().enumerate() {
        sxy += (k as f64 - kbar) * (v - mean);
        sxx += (k as f64 - kbar).powi(2);
    }
    let beta = sxy / sxx;
    s.iter()
        .enumerate()
        .map(|(k, v)| v - beta * (k as f64 - kbar))
        .collect()
}

/// Solves the 3×3 system A x = b by Cramer's rule.
fn solve3(a: [[f64; 3]; 3], b: [f64; 3]) -> [f64; 3] {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    let mut x = [0.0; 3];
    for (j, xj) in x.iter_mut().enumerate() {
        let mut m = a;
        for i in 0..3 {
            m[i][j] = b[i];
        }
        *xj = det(m) / d;
    }
    x
}

// M-3: y(k) = 1.5 y(k−1) − 0.7 y(k−2) + 0.5 u(k−1) plus a drift 0.01·k and small noise. With
// `--detrend linear` the model is estimated on the detrended record, so its estimation figures are
// scored there (MATLAB `compare(detrend(z, 1), m)`): the one-step fit equals the one computed here by
// hand (detrend, 3×3 normal equations, prediction), the free-run fit is high, and the raw record's
// figures (drift left in, what `validate` scores) are reported apart and are poor. In memory and read in
// passes (`--stream on`) alike.
#[test]
#[allow(clippy::needless_range_loop)] // the regression rows k − 1, k − 2 are the point
fn linear_detrend_scores_the_estimation_figures_on_the_detrended_record() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 1000;
    let levels = [2.0, 3.0, 4.0, 5.0];
    let pick = prbs(n / 20 * 2, 5);
    let u: Vec<f64> = (0..n)
        .map(|k| {
            let j = k / 20;
            levels[(pick[2 * j] > 0.0) as usize * 2 + (pick[2 * j + 1] > 0.0) as usize]
        })
        .collect();
    let w = noise(n, 3);
    let mut x = vec![0.0; n];
    for k in 2..n {
        x[k] = 1.5 * x[k - 1] - 0.7 * x[k - 2] + 0.5 * u[k - 1];
    }
    let y: Vec<f64> = (0..n)
        .map(|k| x[k] + 0.01 * k as f64 + 0.05 * w[k])
        .collect();
    write_tuy(tmp.path(), "drift.csv", 0.1, &u, &y);

    // By hand: LS of ARX (2, 1, 1) on the detrended signals, rows k ≥ 2, and its one-step fit.
    let (ud, yd) = (undrift(&u), undrift(&y));
    let mean = |s: &[f64]| s.iter().sum::<f64>() / s.len() as f64;
    let (um, ym) = (mean(&ud), mean(&yd));
    let (ud, yd): (Vec<f64>, Vec<f64>) = (
        ud.iter().map(|v| v - um).collect(),
        yd.iter().map(|v| v - ym).collect(),
    );
    let phi = |k: usize| [-yd[k - 1], -yd[k - 2], ud[k - 1]];
    let (mut a, mut b) = ([[0.0; 3]; 3], [0.0; 3]);
    for k in 2..n {
        let p = phi(k);
        for i in 0..3 {
            b[i] += p[i] * yd[k];
            for j in 0..3 {
                a[i][j] += p[i] * p[j];
            }
        }
    }
    let theta = solve3(a, b);
    let target = &yd[2..];
    let tm = mean(target);
    let (mut num, mut den) = (0.0, 0.0);
    for k in 2..n {
        let p = phi(k);
        let pred = p[0] * theta[0] + p[1] * theta[1] + p[2] * theta[2];
        num += (yd[k] - pred).powi(2);
        den += (yd[k] - tm).powi(2);
    }
    let fit_pred = 100.0 * (1.0 - (num / den).sqrt());

    for stream in ["off", "on"] {
        let doc = run_json(
            tmp.path(),
            &[
                identify_arx(Path::new("drift.csv"), "2", "1", "ls"),
                vec!["--nk", "1", "--detrend", "linear", "--stream", stream],
            ]
            .concat(),
        );
        let est = &doc["metrics"]["estimation"];
        let got = est["fit_pred_percent"].as_f64().unwrap();
        assert!(
            (got - fit_pred).abs() < 1e-6,
            "{stream}: {got} vs {fit_pred}"
        );
        let sim = est["fit_sim_percent"].as_f64().unwrap();
        assert!(sim > 90.0, "{stream}: free-run fit {sim}");
        assert_eq!(doc["detrend_scoring"]["scored_on"], "detrended");
        if stream == "off" {
            let raw = &doc["detrend_scoring"]["raw_record"];
            assert!(raw["fit_sim_percent"].as_f64().unwrap() < 60.0, "{raw}");
            let beta_y = doc["detrend_scoring"]["drift_per_sample"]["y"]
                .as_f64()
                .unwrap();
            assert!((beta_y - 0.01).abs() < 0.003, "{beta_y}");
        }
    }
}

// M-7: the paper's Table III plant with 0.2 mm white output noise (1500 samples, seed 115). The
// output-error refinement reaches the noise level (RMSE ≈ 0.2 from estimated initial outputs); the old
// rule (the worse of the RMSEs from estimated and measured initial outputs) threw it away for the
// biased LS start (b_r < 0, a1 ≈ −1.21), because the noise of the measured y(0..2) drifts through the
// 0.9992 pole. Judged on both initial states pooled, the refinement is kept and recovers the known
// plant: a = (−1.869, 0.9976, −0.1284), b_r = 1.41 (docs/paper.md).
#[test]
fn output_error_keeps_a_refinement_that_found_the_plant() {
    let tmp = tempfile::tempdir().unwrap();
    let (code, _, err) = text_of(
        tmp.path(),
        &[
            "simulate",
            "--plant",
            "paper",
            "--seed",
            "115",
            "--noise-std",
            "0.2",
            "--samples",
            "1500",
            "--out",
            "p115.csv",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let doc = run_json(
        tmp.path(),
        &[
            "identify", "--data", "p115.csv", "--method", "oe", "--na", "3", "--nb", "1",
        ],
    );
    assert!(
        doc["estimation"]["returned"].is_null(),
        "fallback: {}",
        doc["estimation"]["returned"]
    );
    let m = &doc["model"];
    // Each a_i within 4 of its reported standard deviations of the truth (the ± of OE on this plant
    // match the Monte Carlo spread: audit s18, mc3.py, ratio 0.97–1.04).
    let params = doc["parameters"].as_array().unwrap();
    for (i, want) in [-1.869, 0.9976, -0.1284].iter().enumerate() {
        let name = format!("a{}", i + 1);
        let q = params.iter().find(|q| q["name"] == name.as_str()).unwrap();
        let (got, sd) = (q["value"].as_f64().unwrap(), q["std"].as_f64().unwrap());
        assert!(
            (got - want).abs() < 4.0 * sd,
            "{name} = {got} ± {sd} vs {want}"
        );
    }
    let b_r = m["deadzone"]["b_r"].as_f64().unwrap();
    assert!((b_r - 1.41).abs() < 0.2, "b_r = {b_r}");
    let rmse = doc["metrics"]["estimation"]["rmse_sim"].as_f64().unwrap();
    assert!(rmse < 0.25, "RMSE from estimated initial outputs {rmse}");
}

// L-7: an input that never goes negative leaves the deadzone's left branch undetermined; the
// estimator holds m_l = b_l = 0 ("one-sided input"). p (and so FPE and AIC) counts the estimated
// parameters only, as MATLAB counts free parameters: p = the parameters listed without `fixed`, FPE =
// (N + p)/(N − p) V and AIC = ln(2V) + 2p/N (paper eq. 15; MATLAB's normalised AIC) by hand.
#[test]
fn parameters_held_fixed_are_not_counted_in_fpe_and_aic() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 800;
    let levels = [0.0, 20.0, 45.0, 70.0, 100.0];
    let pick = noise(n / 10 + 1, 9);
    let u: Vec<f64> = (0..n)
        .map(|k| levels[(((pick[k / 10] + 1.0) / 2.0 * 5.0) as usize).min(4)])
        .collect();
    let w = noise(n, 13);
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.8 * y[k - 1] + 0.01 * (u[k - 1] - 10.0).max(0.0) + 0.002 * w[k];
    }
    write_tuy(tmp.path(), "onesided.csv", 0.01, &u, &y);
    let doc = run_json(
        tmp.path(),
        &[
            "identify",
            "--data",
            "onesided.csv",
            "--method",
            "ls",
            "--na",
            "1",
            "--nb",
            "1",
        ],
    );
    let params = doc["parameters"].as_array().unwrap();
    assert!(
        params.iter().any(|q| q["fixed"] == "one-sided input"),
        "no branch dropped: {params:?}"
    );
    let p = params.iter().filter(|q| q["fixed"].is_null()).count();
    let m = &doc["metrics"]["estimation"];
    assert_eq!(m["p"].as_u64().unwrap() as usize, p);
    let (nn, v) = (m["n"].as_f64().unwrap(), m["loss"].as_f64().unwrap());
    let pf = p as f64;
    let fpe = (nn + pf) / (nn - pf) * v;
    let aic = (2.0 * v).ln() + 2.0 * pf / nn;
    assert!(
        (m["fpe"].as_f64().unwrap() - fpe).abs() <= 1e-12 * fpe,
        "{m}"
    );
    assert!(
        (m["aic"].as_f64().unwrap() - aic).abs() <= 1e-12 * aic.abs(),
        "{m}"
    );
}

// L-6: `validate --resample` prints the reader's note once (among the warnings), and a Ts mismatch
// after resampling onto the wrong period names the model's period in its advice.
#[test]
fn validate_resample_notes_once_and_advises_the_models_period() {
    let tmp = tempfile::tempdir().unwrap();
    let n = 300;
    let u = prbs(n, 21);
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.7 * y[k - 1] + 0.5 * u[k - 1];
    }
    write_tuy(tmp.path(), "est.csv", 0.08, &u, &y);
    let (code, _, err) = text_of(
        tmp.path(),
        &[
            identify_arx(Path::new("est.csv"), "1", "1", "ls"),
            vec!["--nk", "1", "--save-model", "m.json"],
        ]
        .concat(),
    );
    assert_eq!(code, 0, "{err}");
    // Irregular time stamps (0.05 … 0.11 s apart): the reader resamples onto the asked period.
    let mut s = String::from("t,u,y\n");
    let mut t = 0.0;
    for k in 0..n {
        s += &format!("{t},{},{}\n", u[k], y[k]);
        t += 0.05 + 0.02 * (k % 4) as f64;
    }
    std::fs::write(tmp.path().join("nu.csv"), s).unwrap();
    let (code, out, err) = text_of(
        tmp.path(),
        &[
            "validate",
            "--model",
            "m.json",
            "--data",
            "nu.csv",
            "--resample",
            "0.08",
        ],
    );
    assert_eq!(code, 0, "{err}");
    let all = out + &err;
    assert_eq!(all.matches("resampled").count(), 1, "{all}");
    let (code, out, err) = text_of(
        tmp.path(),
        &[
            "validate",
            "--model",
            "m.json",
            "--data",
            "nu.csv",
            "--resample",
            "0.1",
        ],
    );
    assert_ne!(code, 0);
    assert!((out + &err).contains("--resample 0.08"), "{err}");
}
