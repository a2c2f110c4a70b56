//! `identify` and `validate` through the binary: JSON schema, exact recovery end to end, clear errors.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;
use common::{bin, paper_record, write_tuy};

use std::path::Path;

#[test]
fn identify_writes_the_documented_json_and_recovers_the_paper_model() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(1200, 0);
    let data = write_tuy(dir.path(), "est.csv", 0.01, &u, &y);
    let (u2, y2) = paper_record(800, 5);
    let val = write_tuy(dir.path(), "val.csv", 0.01, &u2, &y2);
    let json = dir.path().join("out.json");
    let model = dir.path().join("model.json");
    let out = bin()
        .args(["identify", "--method", "ls", "--data"])
        .arg(&data)
        .arg("--validation")
        .arg(&val)
        .arg("--json")
        .arg(&json)
        .arg("--save-model")
        .arg(&model)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("b_r") && text.contains("stable"), "{text}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let m = &v["model"];
    assert_eq!(m["kind"], "hammerstein");
    assert_eq!(
        (m["na"].as_u64(), m["nb"].as_u64(), m["nk"].as_u64()),
        (Some(3), Some(1), Some(1))
    );
    assert!((m["ts"].as_f64().unwrap() - 0.01).abs() < 1e-12);
    assert!(m["offset"].is_null());
    let a: Vec<f64> = m["a"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    for (g, w) in a.iter().zip([-1.869, 0.9976, -0.1284]) {
        assert!((g - w).abs() < 1e-8, "{a:?}");
    }
    assert_eq!(m["b"][0].as_f64(), Some(1.0));
    let dz = &m["deadzone"];
    assert!((dz["b_r"].as_f64().unwrap() - 1.41).abs() < 1e-8);
    assert!((dz["b_l"].as_f64().unwrap() + 1.5).abs() < 1e-8);
    assert!((dz["m_r"].as_f64().unwrap() - 2.38 * 15.67e-4).abs() < 1e-12);
    assert_eq!(v["poles"].as_array().unwrap().len(), 3);
    assert!(v["poles"][0]["re"].is_f64() && v["poles"][0]["im"].is_f64());
    assert_eq!(v["stable"], true);
    assert_eq!(v["estimation"]["method"], "ls");
    assert_eq!(v["estimation"]["converged"], true);
    assert!(v["estimation"]["iterations"].as_u64().unwrap() >= 1);
    for part in ["estimation", "validation"] {
        let mm = &v["metrics"][part];
        for key in [
            "fit_sim_percent",
            "fit_pred_percent",
            "rmse_sim",
            "rmse_pred",
            "loss",
            "fpe",
            "aic",
            "n",
            "p",
        ] {
            assert!(mm.get(key).is_some(), "metrics.{part}.{key} missing");
        }
        // A noise-free exact model fits its own data to rounding.
        assert!(mm["fit_sim_percent"].as_f64().unwrap() > 99.999, "{mm}");
        assert_eq!(mm["p"].as_u64(), Some(7));
    }
    assert_eq!(v["metrics"]["validation"]["n"].as_u64(), Some(800 - 3));

    // validate: the saved model on the validation record gives the same numbers as identify's validation.
    let out = bin()
        .args(["validate", "--json", "-", "--model"])
        .arg(&model)
        .arg("--data")
        .arg(&val)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let w: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(w["metrics"]["validation"], v["metrics"]["validation"]);
}

fn run_err(args: &[&str], files: &[(&str, &str)]) -> (i32, String) {
    let dir = tempfile::tempdir().unwrap();
    for (name, content) in files {
        std::fs::write(dir.path().join(name), content).unwrap();
    }
    let out = bin().current_dir(dir.path()).args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!stderr.contains("panicked"), "{stderr}");
    (out.status.code().unwrap_or(-1), stderr)
}

#[test]
fn bad_cells_are_reported_with_file_line_and_column() {
    let (code, err) = run_err(
        &["identify", "--data", "d.csv"],
        &[("d.csv", "t,u,y\n0,1,2\n0.01,NaN,3\n")],
    );
    assert_eq!(code, 2);
    assert!(
        err.contains("d.csv:3:2") && err.contains("not a finite number"),
        "{err}"
    );
    let (code, err) = run_err(
        &["identify", "--data", "d.csv"],
        &[("d.csv", "t,u,y\n0,1,2\n0.01,1,abc\n")],
    );
    assert_eq!(code, 2);
    assert!(err.contains("d.csv:3:3") && err.contains("'abc'"), "{err}");
}

#[test]
fn missing_column_names_what_the_header_has() {
    let (code, err) = run_err(
        &["identify", "--data", "d.csv", "--y-col", "pos"],
        &[("d.csv", "t,u,y\n0,1,2\n")],
    );
    assert_eq!(code, 2);
    assert!(
        err.contains("no column named 'pos'") && err.contains("t, u, y"),
        "{err}"
    );
}

#[test]
fn out_of_range_flags_are_refused_naming_the_flag() {
    let csv = "t,u,y\n0,1,2\n0.01,-1,3\n";
    for (flag, value, needle) in [
        ("--forgetting", "1.5", "--forgetting"),
        ("--forgetting", "0", "--forgetting"),
        ("--p0", "-1", "--p0"),
        ("--nb", "0", "--nb"),
        ("--ts", "0", "--ts"),
    ] {
        let (code, err) = run_err(
            &["identify", "--data", "d.csv", flag, value],
            &[("d.csv", csv)],
        );
        assert_eq!(code, 2, "{flag} {value}: {err}");
        assert!(err.contains(needle), "{flag} {value}: {err}");
    }
}

#[test]
fn an_output_path_equal_to_the_input_is_refused_and_the_input_is_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(300, 0);
    let data = write_tuy(dir.path(), "d.csv", 0.01, &u, &y);
    let before = std::fs::read(&data).unwrap();
    let out = bin()
        .args(["identify", "--method", "ls", "--data"])
        .arg(&data)
        .arg("--json")
        .arg(&data)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--json"));
    assert_eq!(std::fs::read(&data).unwrap(), before);
}

#[test]
fn too_few_samples_for_the_orders_is_a_clear_error() {
    let (code, err) = run_err(
        &["identify", "--data", "d.csv", "--na", "5"],
        &[("d.csv", "t,u,y\n0,1,2\n0.01,-1,3\n0.02,2,1\n")],
    );
    assert_eq!(code, 2);
    assert!(err.contains("regression rows"), "{err}");
}

// `warnings` is always present (empty for the exact paper model); `residuals` holds the estimation and
// validation analyses with M autocorrelations and 2M + 1 cross-correlations; the residuals of an exact
// model are zero... so use a noisy copy: y + a deterministic ±0.001 mm dither.
#[test]
fn identify_json_carries_warnings_and_residual_analysis() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(1200, 0);
    let y: Vec<f64> = y
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.001 * (((k * 7919) % 13) as f64 - 6.0) / 6.0)
        .collect();
    let est = write_tuy(dir.path(), "est.csv", 0.01, &u, &y);
    let (u2, y2) = paper_record(1200, 3);
    let val = write_tuy(dir.path(), "val.csv", 0.01, &u2, &y2);
    let out = bin()
        .args(["identify", "--data"])
        .arg(&est)
        .arg("--validation")
        .arg(&val)
        .args(["--method", "ls", "--resid-lags", "10", "--json", "-"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["warnings"].is_array(), "{v}");
    for which in ["estimation", "validation"] {
        let r = &v["residuals"][which];
        assert_eq!(r["max_lag"], 10, "{which}: {r}");
        assert_eq!(r["autocorrelation"].as_array().unwrap().len(), 10);
        assert_eq!(r["cross_correlation"].as_array().unwrap().len(), 21);
        assert!(r["white"].is_boolean() && r["independent"].is_boolean());
        // The 99 % bound is 2.58/√N with N the rows after k0 = 3.
        let bound = r["bound"].as_f64().unwrap();
        assert!(
            (bound - 2.58 / ((1200.0f64 - 3.0).sqrt())).abs() < 1e-12,
            "{bound}"
        );
    }
}

// --strict turns warnings into exit code 1; without it the exit code stays 0 and the warning is printed
// as a `warning:` line. The case: ARX(1,1,1) on an output that is a random walk unrelated to the input
// (a deterministic generator), whose free-run simulation is worse than the mean (negative fit).
#[test]
fn strict_turns_warnings_into_exit_code_1() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = common::lcg(7);
    let mut next = || rng.unit() * 2.0 - 1.0;
    let n = 400;
    let u: Vec<f64> = (0..n).map(|_| next()).collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = y[k - 1] + next();
    }
    let est = write_tuy(dir.path(), "est.csv", 0.01, &u, &y);
    let run = |strict: bool| {
        let mut c = bin();
        c.args(["identify", "--data"]).arg(&est).args([
            "--model", "arx", "--na", "1", "--nb", "1", "--nk", "1", "--method", "ls", "--json",
            "-",
        ]);
        if strict {
            c.arg("--strict");
        }
        c.output().unwrap()
    };
    let loose = run(false);
    assert!(loose.status.success());
    let v: serde_json::Value = serde_json::from_slice(&loose.stdout).unwrap();
    let warnings = v["warnings"].as_array().unwrap();
    assert!(!warnings.is_empty(), "{v}");
    let stderr = String::from_utf8_lossy(&loose.stderr);
    assert!(
        stderr.contains("warning: negative simulation fit"),
        "{stderr}"
    );
    let strict = run(true);
    assert_eq!(strict.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&strict.stderr).contains("--strict"));
}

// `validate --json` reports the residual analysis and the warnings of the record too.
#[test]
fn validate_reports_residuals_and_warnings() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(1200, 0);
    let est = write_tuy(dir.path(), "est.csv", 0.01, &u, &y);
    let model = dir.path().join("m.json");
    let ok = bin()
        .args(["identify", "--data"])
        .arg(&est)
        .args(["--method", "ls", "--save-model"])
        .arg(&model)
        .output()
        .unwrap();
    assert!(ok.status.success());
    let (u2, y2) = paper_record(1200, 5);
    let y2: Vec<f64> = y2
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.001 * (((k * 104729) % 11) as f64 - 5.0) / 5.0)
        .collect();
    let val = write_tuy(dir.path(), "val.csv", 0.01, &u2, &y2);
    let out = bin()
        .args(["validate", "--model"])
        .arg(&model)
        .arg("--data")
        .arg(&val)
        .args(["--json", "-"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(v["warnings"].as_array().unwrap().is_empty(), "{v}");
    assert_eq!(
        v["residuals"]["validation"]["autocorrelation"]
            .as_array()
            .unwrap()
            .len(),
        25
    );
    assert!(
        v["metrics"]["validation"]["fit_sim_percent"]
            .as_f64()
            .unwrap()
            > 99.0
    );
}

/// The `warnings` of `identify ARGS` (ARX by least squares) run in `dir`.
fn identify_warnings(dir: &Path, args: &[&str]) -> Vec<String> {
    let args = [
        &["identify", "--structure", "arx", "--method", "ls"][..],
        args,
    ]
    .concat();
    common::warnings(&common::run_json(dir, &args))
}

// Audit s11 V1: a validation record that is (part of) the estimation data is said to give an in-sample
// fit: the same file with overlapping rows (rows 500..1000 ∩ 0..600 = 500..600), the --data file itself,
// or a copy of its samples under another name; disjoint rows (0..600 and 600..1000) are not warned.
#[test]
fn a_validation_record_that_is_the_estimation_data_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(1000, 0);
    write_tuy(dir.path(), "d.csv", 0.01, &u, &y);
    write_tuy(dir.path(), "copy.csv", 0.01, &u, &y);
    let d = ["--data", "d.csv", "--ts", "0.01"];
    let in_sample = |w: &[String]| w.iter().any(|w| w.contains("in-sample"));
    let w = identify_warnings(
        dir.path(),
        &[&d[..], &["--rows", "0..600", "--val-rows", "500..1000"]].concat(),
    );
    assert!(
        w.iter()
            .any(|w| w.contains("rows 500..600 of d.csv are in both")
                && w.contains("partly in-sample")),
        "{w:?}"
    );
    let w = identify_warnings(dir.path(), &[&d[..], &["--validation", "d.csv"]].concat());
    assert!(
        w.iter().any(
            |w| w.contains("the validation record is the estimation data")
                && w.contains("in-sample")
        ),
        "{w:?}"
    );
    let w = identify_warnings(
        dir.path(),
        &[&d[..], &["--validation", "copy.csv"]].concat(),
    );
    assert!(
        w.iter().any(|w| w.contains("holds the same samples")),
        "{w:?}"
    );
    let w = identify_warnings(
        dir.path(),
        &[&d[..], &["--rows", "0..600", "--val-rows", "600..1000"]].concat(),
    );
    assert!(!in_sample(&w), "{w:?}");
    let w = identify_warnings(dir.path(), &[&d[..], &["--split", "0.6"]].concat());
    assert!(!in_sample(&w), "{w:?}");
    // Merging a record with its copy counts every sample twice; another record is not warned.
    let twice = |w: &[String]| w.iter().any(|w| w.contains("every sample counts twice"));
    let merge = ["--data", "d.csv", "copy.csv", "--merge", "--ts", "0.01"];
    let w = identify_warnings(dir.path(), &merge);
    assert!(
        w.iter().any(|w| twice(std::slice::from_ref(w))
            && w.contains("copy.csv holds the same samples as")
            && w.contains("d.csv")),
        "{w:?}"
    );
    let (u2, y2) = paper_record(1000, 1);
    write_tuy(dir.path(), "other.csv", 0.01, &u2, &y2);
    let other = ["--data", "d.csv", "other.csv", "--merge", "--ts", "0.01"];
    assert!(!twice(&identify_warnings(dir.path(), &other)));
    // Two experiments side by side in one file (as the cascaded tanks' uEst, yEst, uVal, yVal): the
    // same rows of other columns are held out (audit s12 F1); the same columns are not.
    let mut both = String::from("uEst,yEst,uVal,yVal\n");
    for k in 0..u.len() {
        both += &format!("{},{},{},{}\n", u[k], y[k], u2[k], y2[k]);
    }
    std::fs::write(dir.path().join("both.csv"), both).unwrap();
    let side = [
        "--data",
        "both.csv",
        "--u-col",
        "uEst",
        "--y-col",
        "yEst",
        "--ts",
        "0.01",
        "--validation",
        "both.csv",
        "--val-y-col",
        "yVal",
    ];
    let w = identify_warnings(dir.path(), &[&side[..], &["--val-u-col", "uVal"]].concat());
    assert!(!in_sample(&w), "{w:?}");
    // NARX says it too (audit s12 F2), for the same rows and for a copy.
    for val in ["d.csv", "copy.csv"] {
        let narx = [
            "identify",
            "--structure",
            "narx",
            "--degree",
            "2",
            "--na",
            "2",
            "--nb",
            "2",
            "--nk",
            "1",
            "--data",
            "d.csv",
            "--ts",
            "0.01",
            "--validation",
            val,
        ];
        let doc = common::run_json(dir.path(), &narx);
        assert!(in_sample(&common::warnings(&doc)), "{val}: {doc}");
        // Its free run starts from the measured outputs, under both names (audit s12 L).
        let m = &doc["metrics"]["validation"];
        assert!(m["fit_sim_percent"].is_number(), "{m}");
        assert_eq!(m["fit_sim_measured_percent"], m["fit_sim_percent"], "{m}");
    }
    let w = identify_warnings(dir.path(), &side[..10]);
    assert!(
        w.iter()
            .any(|w| w.contains("the validation record is the estimation data")),
        "{w:?}"
    );
}

// Audit s11 A4: an output written to standard output (`-`) is the only thing there, so it parses: the
// model of `identify --save-model -` is one JSON document, `validate --out -` is a CSV whose first line
// is its header; two outputs on standard output are refused naming the second flag.
#[test]
fn an_output_to_standard_output_is_alone_there() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(600, 0);
    write_tuy(dir.path(), "d.csv", 0.01, &u, &y);
    let run = |args: &[&str]| bin().current_dir(dir.path()).args(args).output().unwrap();
    let id = [
        "identify",
        "--data",
        "d.csv",
        "--structure",
        "arx",
        "--method",
        "ls",
    ];
    let o = run(&[&id[..], &["--save-model", "-"]].concat());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let model: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(model["format"], "ipa-sysid-model");
    std::fs::write(dir.path().join("m.json"), &o.stdout).unwrap();
    let o = run(&[
        "validate", "--model", "m.json", "--data", "d.csv", "--out", "-",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let csv = String::from_utf8(o.stdout).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines[0], "t,y,y_sim,y_sim_y0meas,y_pred,residual");
    assert_eq!(lines.len(), 601, "a header and one row per sample");
    let o = run(&[&id[..], &["--save-model", "-", "--json", "-"]].concat());
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--json") && err.contains("standard output"),
        "{err}"
    );
    assert!(o.stdout.is_empty());
}

// Audits s10-s12: a record read with u and y swapped (the command, held in levels for 17 samples, as
// the output; the measured position, changing at almost every sample, as the input) gets warnings that
// never named the columns; now a hint beside them says they may be swapped. The right way round: none.
#[test]
fn swapped_columns_are_pointed_out() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(1000, 0);
    write_tuy(dir.path(), "d.csv", 0.01, &u, &y);
    let hint = |w: &[String]| {
        w.iter()
            .any(|w| w.contains("are --u-col and --y-col swapped?"))
    };
    // The paper's method (the default structure), which warns on the swapped record; the hint comes
    // only beside other warnings (an ARX fits the swapped record's differentiator without one).
    let d = ["identify", "--data", "d.csv", "--ts", "0.01"];
    let warnings =
        |extra: &[&str]| common::warnings(&common::run_json(dir.path(), &[&d[..], extra].concat()));
    let swapped = warnings(&["--u-col", "y", "--y-col", "u"]);
    assert!(hint(&swapped), "{swapped:?}");
    assert!(!hint(&warnings(&[])));
}

// A validation record whose input leaves the model's estimation data (commands up to ±250 counts for a
// model fitted on ±100) is warned by `validate` and by `identify --validation`, text and JSON: the fit
// judges equations never fitted there (audit s14 M-c); a record within the range is not.
#[test]
fn validation_inputs_outside_the_estimation_data_are_warned() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = |args: &[&str]| {
        let o = bin().current_dir(d).args(args).output().unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        o
    };
    for (amplitude, seed, out) in [("100", "1", "e.csv"), ("250", "2", "v.csv")] {
        run(&[
            "simulate",
            "--plant",
            "paper",
            "--input",
            "aprbs",
            "--amplitude",
            amplitude,
            "--samples",
            "800",
            "--seed",
            seed,
            "--out",
            out,
        ]);
    }
    run(&["identify", "--data", "e.csv", "--save-model", "m.json"]);
    let said = "the record's input u spans [-250, 249] but the model's estimation data had it in [-97, 99]";
    let text = |o: &std::process::Output| {
        String::from_utf8_lossy(&o.stdout).into_owned() + &String::from_utf8_lossy(&o.stderr)
    };
    let o = run(&[
        "validate", "--model", "m.json", "--data", "v.csv", "--json", "vj.json",
    ]);
    assert!(text(&o).contains(said), "{}", text(&o));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("vj.json")).unwrap()).unwrap();
    assert!(
        v["warnings"].to_string().contains(said),
        "{}",
        v["warnings"]
    );
    let o = run(&["identify", "--data", "e.csv", "--validation", "v.csv"]);
    assert!(
        text(&o).contains(&format!("warning: validation: {said}")),
        "{}",
        text(&o)
    );
    let o = run(&["validate", "--model", "m.json", "--data", "e.csv"]);
    assert!(!text(&o).contains("extrapolates"), "{}", text(&o));
}

// A record whose output sits at 50 (a second-order ARX response plus a level) identified without a
// constant term fits negatively; the warning names the operating point and the flags that fix it; with
// --offset there is no such warning (audit s14 M-a: nine warnings and none named --offset/--detrend).
#[test]
fn a_level_the_model_cannot_hold_is_named_with_its_fix() {
    let dir = tempfile::tempdir().unwrap();
    let n = 600;
    let u: Vec<f64> = (0..n)
        .map(|k| [60.0, -80.0, 120.0, -40.0, 90.0, -120.0][(k / 40) % 6])
        .collect();
    let mut x = vec![0.0; n];
    for k in 2..n {
        x[k] = 0.7 * x[k - 1] + 0.1 * x[k - 2] + 0.02 * u[k - 1];
    }
    let y: Vec<f64> = x.iter().map(|v| 50.0 + v).collect();
    let est = write_tuy(dir.path(), "lvl.csv", 0.01, &u, &y);
    let run = |extra: &[&str]| {
        let o = bin()
            .args(["identify", "--data"])
            .arg(&est)
            .args([
                "--structure",
                "arx",
                "--method",
                "ls",
                "--rows",
                "0..300",
                "--val-rows",
                "300..600",
                "--json",
                "-",
            ])
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        v["warnings"].to_string()
    };
    let plain = run(&[]);
    assert!(
        plain.contains("the output lies far from zero")
            && plain.contains("--offset")
            && plain.contains("--detrend mean"),
        "{plain}"
    );
    assert!(!run(&["--offset"]).contains("far from zero"));
    // The streamed path says the same (the hint reads the model's data range, not the record).
    assert!(run(&["--stream", "on"]).contains("the output lies far from zero"));
}

// Audit s14 L-c: a detrended model's deadzone is in u − u0, and `tune` speaks of it in the record's
// units: identify labels the coordinates and gives the breakpoints + u0 (u0 = the record's mean input,
// from the model file; b_l + u0 computed here); without detrending there is no such line.
#[test]
fn a_detrended_deadzone_says_which_input_it_maps() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(1200, 0);
    let data = write_tuy(dir.path(), "rec.csv", 0.01, &u, &y);
    let model = dir.path().join("m.json");
    let o = bin()
        .args(["identify", "--method", "ls", "--detrend", "mean", "--data"])
        .arg(&data)
        .arg("--save-model")
        .arg(&model)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    let u0 = m["model"]["operating_point"]["u"][0].as_f64().unwrap();
    let mean = u.iter().sum::<f64>() / u.len() as f64;
    assert!(
        (u0 - mean).abs() < 1e-9 * mean.abs().max(1.0),
        "{u0} vs {mean}"
    );
    let b_l = m["model"]["deadzone"]["b_l"].as_f64().unwrap();
    assert!(
        text.contains("(the input nonlinearity maps the detrended input u − u0, u0 = ")
            && text.contains("in the record's units its breakpoints are b_l = "),
        "{text}"
    );
    // The printed b_l in the record's units is b_l + u0 to 6 significant digits.
    let at = text.find("its breakpoints are b_l = ").unwrap() + "its breakpoints are b_l = ".len();
    let shown: f64 = text[at..]
        .split(',')
        .next()
        .unwrap()
        .trim()
        .parse()
        .unwrap();
    assert!(
        (shown - (b_l + u0)).abs() <= 1e-5 * (b_l + u0).abs().max(1e-3),
        "{shown} vs {}",
        b_l + u0
    );
    let plain = bin()
        .args(["identify", "--method", "ls", "--data"])
        .arg(&data)
        .output()
        .unwrap();
    assert!(!String::from_utf8_lossy(&plain.stdout).contains("detrended input"));
}
