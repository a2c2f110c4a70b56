//! `order` through the binary: ranking, JSON, range syntax errors.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;
use common::bin;

/// y(k) = 0.7 y(k−1) + 0.5 u(k−2), noise-free (na = 1, nb = 1, nk = 2), by a plain loop.
fn record(dir: &std::path::Path, name: &str, phase: usize) -> std::path::PathBuf {
    let n = 600;
    let u: Vec<f64> = (0..n)
        .map(|k| (((k / 7 + phase) * 7919) % 19) as f64 - 9.0)
        .collect();
    let mut y = vec![0.0; n];
    for k in 2..n {
        y[k] = 0.7 * y[k - 1] + 0.5 * u[k - 2];
    }
    let mut s = String::from("t,u,y\n");
    for k in 0..n {
        s += &format!("{},{},{}\n", k as f64 * 0.1, u[k], y[k]);
    }
    let p = dir.join(name);
    std::fs::write(&p, s).unwrap();
    p
}

// The generating structure (1, 1, 2) fits the validation record exactly and has the fewest parameters of
// all exact structures, so it ranks first; the JSON lists every structure of the 2 × 2 × 3 grid.
#[test]
fn order_ranks_the_generating_structure_first() {
    let dir = tempfile::tempdir().unwrap();
    let est = record(dir.path(), "est.csv", 0);
    let val = record(dir.path(), "val.csv", 3);
    let json = dir.path().join("order.json");
    let out = bin()
        .args(["order", "--data"])
        .arg(&est)
        .arg("--validation")
        .arg(&val)
        .args(["--na", "1..2", "--nb", "1..2", "--nk", "1..3", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let c = doc["candidates"].as_array().unwrap();
    assert_eq!(c.len(), 12);
    assert_eq!(
        (
            c[0]["orders"]["na"].as_u64(),
            c[0]["orders"]["nb"].as_u64(),
            c[0]["orders"]["nk"].as_u64()
        ),
        (Some(1), Some(1), Some(2))
    );
    assert!(c[0]["fit_validation"].as_f64().unwrap() > 99.999);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("by selection fit"), "{text}");
}

#[test]
fn a_reversed_range_is_refused_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let est = record(dir.path(), "est.csv", 0);
    let out = bin()
        .args(["order", "--data"])
        .arg(&est)
        .args(["--na", "3..1"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--na") && err.contains("a..b"), "{err}");
}

/// y(k) = 0.6 y(k−1) + 0.4 u(k−1) + 3 with u in 4..10: a process around a non-zero operating point
/// (noise-free, by a plain loop); a little deterministic wobble keeps the regression well posed.
fn offset_record(dir: &std::path::Path, name: &str, phase: usize) -> std::path::PathBuf {
    let n = 500;
    let u: Vec<f64> = (0..n)
        .map(|k| 4.0 + ((((k / 9 + phase) * 7919) % 13) as f64) / 2.0)
        .collect();
    let mut y = vec![10.0; n];
    for k in 1..n {
        y[k] = 0.6 * y[k - 1] + 0.4 * u[k - 1] + 3.0;
    }
    let mut s = String::from("t,u,y\n");
    for k in 0..n {
        s += &format!("{},{},{}\n", k as f64 * 0.1, u[k], y[k]);
    }
    let p = dir.join(name);
    std::fs::write(&p, s).unwrap();
    p
}

fn order_json(args: &[&str], dir: &std::path::Path) -> (serde_json::Value, String) {
    let json = dir.join("o.json");
    let out = bin().args(args).arg("--json").arg(&json).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let doc = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (doc, String::from_utf8_lossy(&out.stderr).into_owned())
}

// Issue 27 item 4: without --offset the search on a process with a constant term says that the output
// has a non-zero operating point and that --offset fits better (it does: the data have c = 3); with
// --offset, or with --detrend mean, it does not. `order --detrend mean` judges the chosen structure on
// the test record as `identify --detrend mean` does (same fit, two paths: shifted records here, a model
// carrying its operating point there).
#[test]
fn order_detects_an_operating_point_and_detrends_like_identify() {
    let dir = tempfile::tempdir().unwrap();
    let est = offset_record(dir.path(), "est.csv", 0);
    let val = offset_record(dir.path(), "val.csv", 5);
    let (e, v) = (est.to_str().unwrap(), val.to_str().unwrap());
    let grid = ["--na", "1", "--nb", "1", "--nk", "1"];
    let base = ["order", "--data", e, "--validation", v];
    let args = |extra: &[&str]| -> Vec<String> {
        base.iter()
            .chain(grid.iter())
            .chain(extra.iter())
            .map(|s| s.to_string())
            .collect()
    };
    let plain = args(&[]);
    let (doc, _) = order_json(
        &plain.iter().map(String::as_str).collect::<Vec<_>>(),
        dir.path(),
    );
    let said = |doc: &serde_json::Value| {
        doc["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().contains("non-zero operating point"))
    };
    assert!(said(&doc), "{doc}");
    for extra in [&["--offset"][..], &["--detrend", "mean"][..]] {
        let a = args(extra);
        let (doc, _) = order_json(
            &a.iter().map(String::as_str).collect::<Vec<_>>(),
            dir.path(),
        );
        assert!(!said(&doc), "{extra:?}: {doc}");
    }
    let a = args(&["--detrend", "mean"]);
    let (doc, _) = order_json(
        &a.iter().map(String::as_str).collect::<Vec<_>>(),
        dir.path(),
    );
    let order_fit = doc["test"]["fit_sim_percent"].as_f64().unwrap();
    let id_json = dir.path().join("id.json");
    let out = bin()
        .args(["identify", "--data", e, "--validation", v])
        .args(["--structure", "arx", "--method", "ls", "--detrend", "mean"])
        .args(grid)
        .arg("--json")
        .arg(&id_json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let id: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&id_json).unwrap()).unwrap();
    // `test.fit_sim_percent` is the worse of estimated and measured initial outputs (audit s21 L-A1).
    let v = &id["metrics"]["validation"];
    let id_fit = v["fit_sim_percent"]
        .as_f64()
        .unwrap()
        .min(v["fit_sim_measured_percent"].as_f64().unwrap());
    assert!(
        (order_fit - id_fit).abs() < 1e-6,
        "order {order_fit} vs identify {id_fit}"
    );
    // --detrend linear is refused, naming the flag.
    let out = bin()
        .args(["order", "--data", e, "--detrend", "linear"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--detrend"));
}

// A record on which every structure fails numerically (values of 1e300: the least-squares sums
// overflow) is an error, exit 1, as identify's on the same data; the table still lists each structure
// with its failure, and the user's --json file is left as it was (audit s10 F7.6).
#[test]
fn order_fails_when_no_structure_can_be_estimated() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = String::from("u,y\n");
    for k in 0..300 {
        s += &format!("{}e300,{}e300\n", 1 + k % 7, 2 + k % 5);
    }
    let data = dir.path().join("huge.csv");
    std::fs::write(&data, s).unwrap();
    let json = dir.path().join("mine.json");
    std::fs::write(&json, "mine\n").unwrap();
    let out = bin()
        .args([
            "order", "--ts", "0.1", "--na", "1..2", "--nb", "1..2", "--nk", "1", "--data",
        ])
        .arg(&data)
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert_eq!(out.status.code(), Some(1), "{stdout}{stderr}");
    assert!(
        stderr.contains("every one of the 4 structures failed"),
        "{stderr}"
    );
    assert_eq!(stdout.matches("numerical failure").count(), 4, "{stdout}");
    assert!(stdout.contains("nothing could be estimated"), "{stdout}");
    assert_eq!(std::fs::read_to_string(&json).unwrap(), "mine\n");
    let identify = bin()
        .args([
            "identify",
            "--ts",
            "0.1",
            "--structure",
            "arx",
            "--method",
            "ls",
            "--data",
        ])
        .arg(&data)
        .output()
        .unwrap();
    assert_eq!(identify.status.code(), Some(1));
}

// The data's failure, not a numerical one: two inputs that are the same column make every structure's
// regressors linearly dependent, so every structure is refused by the data: exit 2, as identify's on
// the same record (audit s14 L-j: order exited 1 where identify exits 2).
#[test]
fn order_exits_as_identify_when_the_data_refuse_every_structure() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = String::from("u1,u2,y\n");
    let mut y = 0.0;
    for k in 0..300 {
        let u = ((k * 7919) % 13) as f64 - 6.0;
        y = 0.5 * y + u;
        s += &format!("{u},{u},{y}\n");
    }
    let data = dir.path().join("twins.csv");
    std::fs::write(&data, s).unwrap();
    let run = |cmd: &[&str]| {
        bin()
            .args(cmd)
            .args([
                "--ts",
                "0.1",
                "--u-col",
                "u1,u2",
                "--structure",
                "arx",
                "--data",
            ])
            .arg(&data)
            .output()
            .unwrap()
    };
    let identify = run(&["identify", "--method", "ls"]);
    assert_eq!(identify.status.code(), Some(2));
    let order = run(&["order", "--na", "1..2", "--nb", "1", "--nk", "1"]);
    let stderr = String::from_utf8_lossy(&order.stderr);
    assert_eq!(order.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("every one of the 2 structures failed"),
        "{stderr}"
    );
    assert!(stderr.contains("linearly dependent"), "{stderr}");
    // track follows one input: the list is refused as a list, not looked up as a column's name.
    let track = bin()
        .args(["track", "--u-col", "u1,u2", "--data"])
        .arg(&data)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&track.stderr);
    assert_eq!(track.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("invalid setting --u-col = u1,u2: one input column"),
        "{stderr}"
    );
}

/// Rows 0..300: y(k) = 0.7 y(k−1) + 0.5 u(k−2); rows 300..600: y(k) = 0.2 y(k−1) + 2 u(k−2) (another
/// plant), noise-free, by a plain loop.
fn two_plant_record(dir: &std::path::Path) -> std::path::PathBuf {
    let n = 600;
    let u: Vec<f64> = (0..n)
        .map(|k| (((k / 7) * 7919) % 19) as f64 - 9.0)
        .collect();
    let mut y = vec![0.0; n];
    for k in 2..n {
        let (a, b) = if k < 300 { (0.7, 0.5) } else { (0.2, 2.0) };
        y[k] = a * y[k - 1] + b * u[k - 2];
    }
    let mut s = String::from("t,u,y\n");
    for k in 0..n {
        s += &format!("{},{},{}\n", k as f64 * 0.1, u[k], y[k]);
    }
    let p = dir.join("two.csv");
    std::fs::write(&p, s).unwrap();
    p
}

// Audit s11 O1: the --selection-rows are never used for estimation, as the help says. On a record whose
// two halves come from two plants, ARX(1, 1, 2) estimated on the rows left after removing the selection
// rows (one plant, noise-free) fits them exactly (100 %); estimated on all 600 rows (the old behaviour)
// it could not, since no single (a, b) reproduces both halves. The selection half is the other plant,
// so its fit is far from 100 %.
#[test]
fn selection_rows_are_not_used_for_estimation() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_plant_record(dir.path());
    let d = data.to_str().unwrap();
    let grid = ["--na", "1", "--nb", "1", "--nk", "2"];
    for (sel, est_rows) in [("300..600", "[0..300]"), ("0..300", "[300..600]")] {
        let mut args = vec!["order", "--data", d, "--selection-rows", sel];
        args.extend(grid);
        let (doc, _) = order_json(&args, dir.path());
        assert!(
            doc["data"].as_str().unwrap().ends_with(est_rows),
            "{sel}: {}",
            doc["data"]
        );
        let c = &doc["candidates"][0];
        assert!(
            c["fit_estimation"].as_f64().unwrap() > 99.9999,
            "{sel}: {c}"
        );
        assert!(c["fit_validation"].as_f64().unwrap() < 99.0, "{sel}: {c}");
    }
    // With --rows 0..300 the selection rows lie outside the data rows: the estimation is rows 0..300.
    let mut args = vec![
        "order",
        "--data",
        d,
        "--rows",
        "0..300",
        "--selection-rows",
        "300..600",
    ];
    args.extend(grid);
    let (doc, _) = order_json(&args, dir.path());
    assert!(doc["data"].as_str().unwrap().ends_with("[0..300]"));
    // Selection rows in the middle would cut the estimation rows in two: refused, pointing at --rows.
    let out = bin()
        .args(["order", "--data", d, "--selection-rows", "200..400"])
        .args(grid)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--selection-rows 200..400") && err.contains("--rows 0..200"),
        "{err}"
    );
    // A selection of every data row leaves nothing to estimate on.
    let out = bin()
        .args(["order", "--data", d, "--selection-rows", "0..600"])
        .args(grid)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
}

// Audit s11 O1: a selection part of 10 rows on a grid whose largest k0 = max(na, nk + nb − 1) is
// max(3, 2 + 2 − 1) = 3 holds fewer than 5 k0 = 15 samples: said, with the 10 − 3 = 7 compared samples.
#[test]
fn a_short_selection_part_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_plant_record(dir.path());
    let d = data.to_str().unwrap();
    let args = [
        "order",
        "--data",
        d,
        "--rows",
        "0..300",
        "--selection-rows",
        "290..300",
        "--na",
        "1..3",
        "--nb",
        "1..2",
        "--nk",
        "0..2",
    ];
    let (doc, _) = order_json(&args, dir.path());
    let w: Vec<&str> = doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(
        w.iter().any(|w| w.contains("holds only 10 samples")
            && w.contains("k0 = 3")
            && w.contains("7 compared")),
        "{w:?}"
    );
    // 290 rows of selection on the same grid: no such warning.
    let (doc, _) = order_json(
        &[
            "order",
            "--data",
            d,
            "--selection-rows",
            "300..600",
            "--na",
            "1..3",
            "--nb",
            "1..2",
            "--nk",
            "0..2",
        ],
        dir.path(),
    );
    assert!(!doc["warnings"].to_string().contains("holds only"), "{doc}");
}

// Audit s11 V1: `order`'s test record must be held out; the --data file itself as --validation, or
// --val-rows inside the --selection-rows, is said to give an in-sample test fit.
#[test]
fn a_test_record_that_is_the_estimation_data_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_plant_record(dir.path());
    let d = data.to_str().unwrap();
    let grid = ["--na", "1", "--nb", "1", "--nk", "2"];
    let (doc, _) = order_json(
        &[&["order", "--data", d, "--validation", d][..], &grid].concat(),
        dir.path(),
    );
    assert!(
        doc["warnings"]
            .to_string()
            .contains("the test record is the estimation data"),
        "{doc}"
    );
    let (doc, _) = order_json(
        &[
            &[
                "order",
                "--data",
                d,
                "--rows",
                "0..300",
                "--selection-rows",
                "300..500",
                "--val-rows",
                "450..600",
            ][..],
            &grid,
        ]
        .concat(),
        dir.path(),
    );
    let w = doc["warnings"].to_string();
    assert!(
        w.contains("the test record overlaps the selection data (rows 450..500"),
        "{w}"
    );
    assert!(!w.contains("the estimation data"), "{w}");
    // The chosen structure's test line says whether the test record was held out.
    let test_line = |val_rows: &str| -> String {
        let args = [
            &[
                "order",
                "--data",
                d,
                "--rows",
                "0..300",
                "--selection-rows",
                "300..500",
            ][..],
            &["--val-rows", val_rows][..],
            &grid,
        ]
        .concat();
        let out = bin().args(&args).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        text.lines()
            .find(|l| l.contains("test fit"))
            .unwrap_or_else(|| panic!("{text}"))
            .to_string()
    };
    assert!(test_line("450..600").contains("NOT held out"));
    assert!(test_line("500..600").contains("never used for ranking"));
}

// Audit s12: the NARX search's settings were accepted and ignored when no narxD class is searched (plain
// `order`, or --classes without a NARX class); they are refused naming the flag, and accepted with one.
#[test]
fn narx_settings_without_a_narx_class_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_plant_record(dir.path());
    let d = data.to_str().unwrap();
    let grid = ["--na", "1", "--nb", "1", "--nk", "1"];
    for (extra, flag) in [
        (&["--stop", "bic"][..], "--stop"),
        (&["--max-terms", "5"][..], "--max-terms"),
        (&["--no-refine"][..], "--no-refine"),
        (
            &["--classes", "arx,wiener:saturation", "--selection", "0.3"][..],
            "--selection",
        ),
    ] {
        let out = bin()
            .args([&["order", "--data", d][..], &grid, extra].concat())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag}: {err}");
        assert!(
            err.contains(&format!("{flag} is a setting of the NARX class search")),
            "{flag}: {err}"
        );
    }
    let (doc, _) = order_json(
        &[
            &["order", "--data", d][..],
            &grid,
            &["--classes", "arx,narx2", "--stop", "bic"],
        ]
        .concat(),
        dir.path(),
    );
    assert!(
        doc["candidates"].as_array().is_some_and(|c| !c.is_empty()),
        "{doc}"
    );
}

// A Wiener candidate has no one-step equation error, so no AIC: null with the reason in the JSON and a
// line under the table, while an ARX candidate keeps its one-step AIC (audit s28 L-2: the Wiener
// row's column held a simulation-based figure under the same name).
#[test]
fn a_wiener_candidate_has_no_aic_and_says_why() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_plant_record(dir.path());
    let d = data.to_str().unwrap();
    let args = [
        "order",
        "--data",
        d,
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
        "--classes",
        "arx,wiener:saturation",
    ];
    let (doc, _) = order_json(&args, dir.path());
    let out = bin().args(args).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    let candidates = doc["candidates"].as_array().unwrap();
    let of = |class: &str| {
        candidates
            .iter()
            .find(|c| c["class"] == class)
            .unwrap_or_else(|| panic!("{class}: {doc}"))
    };
    let (arx, wiener) = (of("arx"), of("wiener:saturation"));
    assert!(
        arx["aic"].is_f64() && arx.get("aic_note").is_none(),
        "{arx}"
    );
    assert!(wiener["aic"].is_null(), "{wiener}");
    assert!(
        wiener["aic_note"]
            .as_str()
            .is_some_and(|n| n.contains("no one-step equation error")),
        "{wiener}"
    );
    assert!(
        text.contains("AIC of wiener:saturation: loss V, FPE and AIC are n/a"),
        "{text}"
    );
}

// Audit s30 H-1: on a one-sided input (u only 3.4 or 6.4, never negative) the Hammerstein estimator holds
// three deadzone parameters fixed, so its model is the ARX model with an offset: na + nb + 1 = 2 + 1 + 1
// = 4 estimated parameters (counted here by hand), in `order`'s table as in `identify`; `order` counted 7.
#[test]
fn order_counts_only_the_parameters_a_one_sided_fit_estimated() {
    let dir = tempfile::tempdir().unwrap();
    let (mut u, mut y) = (Vec::new(), Vec::new());
    let mut state = 7u64;
    let (mut y1, mut y2, mut u1) = (20.0f64, 20.0f64, 3.4f64);
    for k in 0..600 {
        if k % 9 == 0 {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
        }
        let uk = if (state >> 40) & 1 == 1 { 6.4 } else { 3.4 };
        // Small deterministic "noise" so the fit is not exact.
        let e = 0.01 * (((k * 7919) % 13) as f64 - 6.0);
        let yk = 1.2 * y1 - 0.4 * y2 + 0.5 * u1 + 2.0 + e;
        u.push(uk);
        y.push(yk);
        (y2, y1, u1) = (y1, yk, uk);
    }
    let data = common::write_tuy(dir.path(), "one_sided.csv", 0.08, &u, &y);
    let d = data.to_str().unwrap();
    let grid = ["--na", "2..2", "--nb", "1..1", "--nk", "1..1", "--offset"];
    let (doc, _) = order_json(
        &[
            &["order", "--data", d, "--structure", "hammerstein"][..],
            &grid,
        ]
        .concat(),
        dir.path(),
    );
    let p = doc["candidates"][0]["p"].as_u64().unwrap();
    assert_eq!(p, 4, "{doc}");
    let (doc, _) = order_json(
        &[
            &["order", "--data", d, "--classes", "arx,hammerstein"][..],
            &grid,
        ]
        .concat(),
        dir.path(),
    );
    for c in doc["candidates"].as_array().unwrap() {
        assert_eq!(c["p"].as_u64(), Some(4), "{c}");
    }
}
