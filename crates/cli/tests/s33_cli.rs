//! Audit s33 (coordinator's fixes). M-1: `validate --model NARX.json` never said that the held-out
//! fit fell far below the estimation fit (gas furnace: 92.38 % → 53.18 %, no warning), while an ARX
//! model's file records its estimation fit and validate compares. A NARX model file now records its
//! identification (record, columns, estimation fit, warnings) as a linear model's does, and validate
//! applies the same rules: the held-out drop, the in-sample record, the identification's warnings, the
//! columns by name.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{bin, lcg, s, stderr, stdout, write_tuy};

/// A NARX plant y_k = 0.6 y_{k−1} + g u_{k−1} + 0.2 u_{k−1}² + noise, its input gain g = 0.5 over the
/// first 400 samples and `g2` over the next 400.
fn changing_plant(g2: f64) -> (Vec<f64>, Vec<f64>) {
    let mut r = lcg(33);
    let n = 800;
    let u: Vec<f64> = (0..n).map(|_| 2.0 * r.unit() - 1.0).collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        let g = if k < 400 { 0.5 } else { g2 };
        y[k] = 0.6 * y[k - 1] + g * u[k - 1] + 0.2 * u[k - 1] * u[k - 1] + 0.01 * (r.unit() - 0.5);
    }
    (u, y)
}

/// The simulation fit % over samples k ≥ k0 of `validate --out`'s y and y_sim columns, by hand:
/// 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖), ȳ the mean of the scored y.
fn fit_from_out(path: &std::path::Path, k0: usize) -> f64 {
    let mut rd = csv::Reader::from_path(path).unwrap();
    let h = rd.headers().unwrap().clone();
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    let (iy, is) = (col("y"), col("y_sim"));
    let rows: Vec<(f64, f64)> = rd
        .records()
        .map(|r| {
            let r = r.unwrap();
            (r[iy].parse().unwrap(), r[is].parse().unwrap())
        })
        .skip(k0)
        .collect();
    let mean = rows.iter().map(|p| p.0).sum::<f64>() / rows.len() as f64;
    let err: f64 = rows.iter().map(|p| (p.0 - p.1).powi(2)).sum::<f64>().sqrt();
    let dev: f64 = rows
        .iter()
        .map(|p| (p.0 - mean).powi(2))
        .sum::<f64>()
        .sqrt();
    100.0 * (1.0 - err / dev)
}

fn identify_narx(data: &std::path::Path, model: &std::path::Path) {
    let o = bin()
        .args(["identify", "--data", s(data), "--rows", "0..400"])
        .args(["--structure", "narx", "--na", "1", "--nb", "1", "--nk", "1"])
        .args(["--save-model", s(model)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

fn validate(
    model: &std::path::Path,
    data: &std::path::Path,
    rows: &str,
    out: &std::path::Path,
) -> String {
    let o = bin()
        .args([
            "validate",
            "--model",
            s(model),
            "--data",
            s(data),
            "--rows",
            rows,
        ])
        .args(["--out", s(out), "--force"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    stdout(&o)
}

#[test]
fn a_narx_model_validated_far_below_its_estimation_fit_is_said_so() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = changing_plant(0.1);
    let data = write_tuy(dir.path(), "d.csv", 0.1, &u, &y);
    let model = dir.path().join("n.json");
    identify_narx(&data, &model);
    // The file records the identification: the record with its rows and the columns.
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let id = &file["model"]["identification"];
    assert!(
        id["record"].as_str().unwrap().ends_with("d.csv[0..400]"),
        "{file}"
    );
    assert_eq!(id["y_column"], "y", "{file}");
    // Both fits by hand from validate --out (lags y1, u1: k0 = 1).
    let est_out = dir.path().join("est.csv");
    let in_sample = validate(&model, &data, "0..400", &est_out);
    let fit_est = fit_from_out(&est_out, 1);
    assert!(
        in_sample.contains("this is the data the model was estimated on"),
        "{in_sample}"
    );
    let val_out = dir.path().join("val.csv");
    let text = validate(&model, &data, "400..800", &val_out);
    let fit_val = fit_from_out(&val_out, 1);
    assert!(
        fit_est - fit_val > 15.0,
        "est {fit_est}, val {fit_val}: the case must drop"
    );
    let words = format!(
        "from {fit_est:.2} % on the estimation data to {fit_val:.2} % on the validation data"
    );
    assert!(text.contains(&words), "expected «{words}» in:\n{text}");
    assert!(
        !text.contains("this is the data the model was estimated on"),
        "{text}"
    );
}

#[test]
fn a_narx_model_validated_near_its_estimation_fit_is_not_warned() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = changing_plant(0.5);
    let data = write_tuy(dir.path(), "d.csv", 0.1, &u, &y);
    let model = dir.path().join("n.json");
    identify_narx(&data, &model);
    let (est_out, val_out) = (dir.path().join("e.csv"), dir.path().join("v.csv"));
    validate(&model, &data, "0..400", &est_out);
    let text = validate(&model, &data, "400..800", &val_out);
    let drop = fit_from_out(&est_out, 1) - fit_from_out(&val_out, 1);
    assert!(drop < 15.0, "drop {drop}: the case must not drop");
    assert!(!text.contains("on the estimation data to"), "{text}");
}

#[test]
fn a_narx_model_file_without_its_identification_still_loads() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = changing_plant(0.1);
    let data = write_tuy(dir.path(), "d.csv", 0.1, &u, &y);
    let model = dir.path().join("n.json");
    identify_narx(&data, &model);
    // A file written before the identification was recorded: nothing to compare, no warning, no error.
    let mut file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    file["model"]
        .as_object_mut()
        .unwrap()
        .remove("identification");
    let old = dir.path().join("old.json");
    std::fs::write(&old, serde_json::to_string_pretty(&file).unwrap()).unwrap();
    let text = validate(&old, &data, "400..800", &dir.path().join("v.csv"));
    assert!(!text.contains("on the estimation data to"), "{text}");
    // The identification's own warnings are repeated, as a linear model file's.
    file["model"]["identification"] = serde_json::json!({
        "record": "elsewhere.csv",
        "fit_estimation_percent": 50.0,
        "warnings": ["a doubt of the identification"]
    });
    std::fs::write(&old, serde_json::to_string_pretty(&file).unwrap()).unwrap();
    let text = validate(&old, &data, "400..800", &dir.path().join("v.csv"));
    assert!(
        text.contains("model: this model's identification on elsewhere.csv (free-run fit 50.00 % on it) warned: a doubt of the identification"),
        "{text}"
    );
}

// H-1: an input that never goes negative leaves the deadzone's left branch undetermined; identify holds
// it fixed and counts only the estimated parameters in p, FPE and AIC. The model file did not say so,
// so `validate` counted every parameter: for the same model and record its p, FPE and AIC disagreed with
// identify's (hair dryer: FPE 8.5965e-4 vs 8.4931e-4). Now the file records `fixed_parameters` and one p
// holds for the model wherever it is scored: p = the parameters identify lists without `fixed`, FPE =
// (N + p)/(N − p) V and AIC = ln(2V) + 2p/N by hand from validate's own N and V.
#[test]
fn validate_counts_the_parameters_identify_estimated() {
    let dir = tempfile::tempdir().unwrap();
    let n = 1200;
    let mut r = lcg(7);
    let levels = [0.0, 20.0, 45.0, 70.0, 100.0];
    let mut u = vec![0.0; n];
    for k in 0..n {
        u[k] = if k % 10 == 0 {
            levels[((r.unit() * 5.0) as usize).min(4)]
        } else {
            u[k - 1]
        };
    }
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.8 * y[k - 1] + 0.01 * (u[k - 1] - 10.0_f64).max(0.0) + 0.002 * (r.unit() - 0.5);
    }
    let data = write_tuy(dir.path(), "onesided.csv", 0.01, &u, &y);
    let (id_json, model) = (dir.path().join("id.json"), dir.path().join("m.json"));
    let o = bin()
        .args([
            "identify",
            "--data",
            s(&data),
            "--rows",
            "0..800",
            "--method",
            "ls",
        ])
        .args(["--na", "1", "--nb", "2", "--structure", "hammerstein"])
        .args(["--validation", s(&data), "--val-rows", "800.."])
        .args(["--json", s(&id_json), "--save-model", s(&model)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let id: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&id_json).unwrap()).unwrap();
    let params = id["parameters"].as_array().unwrap();
    let fixed = params
        .iter()
        .filter(|q| q["fixed"] == "one-sided input")
        .count();
    assert!(fixed > 0, "no branch dropped: {params:?}");
    let p = params.iter().filter(|q| q["fixed"].is_null()).count();
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    assert_eq!(file["model"]["fixed_parameters"], fixed, "{file}");
    let val_json = dir.path().join("val.json");
    let o = bin()
        .args([
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&data),
            "--rows",
            "800..",
        ])
        .args(["--json", s(&val_json)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let val: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&val_json).unwrap()).unwrap();
    let m = &val["metrics"]["validation"];
    assert_eq!(m["p"].as_u64().unwrap() as usize, p, "{m}");
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
    // identify's own validation figures are the same numbers.
    let iv = &id["metrics"]["validation"];
    for key in ["p", "n", "loss", "fpe", "aic", "fpe_matlab", "aic_matlab"] {
        assert_eq!(iv[key], m[key], "{key}: identify {iv} validate {m}");
    }
    // A hand-edited file claiming more fixed parameters than the structure has is refused.
    let mut bad = file.clone();
    bad["model"]["fixed_parameters"] = serde_json::json!(99);
    let bad_path = dir.path().join("bad.json");
    std::fs::write(&bad_path, serde_json::to_string(&bad).unwrap()).unwrap();
    let o = bin()
        .args(["validate", "--model", s(&bad_path), "--data", s(&data)])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("fixed_parameters = 99"),
        "{}",
        stderr(&o)
    );
}
