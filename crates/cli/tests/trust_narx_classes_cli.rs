//! Trust of polynomial NARX identification and of `order --classes` on the measured records of
//! `../shared/data`, through the binary (issue 22, audit findings 3 and 4): the negative-fit, baseline
//! and no-input warnings of NARX models, and a class search that never recommends a candidate a
//! warning disqualifies and reports the chosen model's test-record warnings. Each test skips, saying
//! so, when the folder is absent. The baseline comes from a separate run of the binary (plain ARX least
//! squares); the rules are checked against the JSON's own figures, never against a copied output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;

use common::{run_json_code, warnings};
use serde_json::Value;

const HYDRAULIC: [&str; 10] = [
    "--data",
    "hydraulic_actuator/actuator.csv",
    "--ts",
    "1",
    "--y-col",
    "p",
    "--rows",
    "0..512",
    "--val-rows",
    "512..1024",
];

const DRIVES: [&str; 12] = [
    "--data",
    "coupled_electric_drives_prbs/DATAPRBS.csv",
    "--ts",
    "0.02",
    "--u-col",
    "u1",
    "--y-col",
    "z1",
    "--rows",
    "0..250",
    "--val-rows",
    "250..500",
];

/// Every NARX fit of `doc` that is negative, or more than 20 points below the baseline fit of the
/// same record in `base` (an `identify --structure arx --method ls` document), has its warning.
fn assert_narx_rules(doc: &Value, base: &Value) {
    let w = warnings(doc);
    for record in ["estimation", "validation"] {
        let Some(fit) = doc["metrics"][record]["fit_sim_percent"].as_f64() else {
            continue;
        };
        if fit < 0.0 {
            assert!(
                w.iter()
                    .any(|w| w.contains(&format!("negative simulation fit on the {record} data"))),
                "{record}: fit {fit} without a warning: {w:?}"
            );
        }
        let m = &base["metrics"][record];
        let baseline = m["fit_sim_percent"]
            .as_f64()
            .unwrap()
            .min(m["fit_sim_measured_percent"].as_f64().unwrap());
        if fit < baseline - 20.0 {
            assert!(
                w.iter().any(|w| w.contains(&format!(
                    "simulates the {record} data far worse than the plain linear least-squares ARX"
                ))),
                "{record}: fit {fit} against the baseline's {baseline} without a warning: {w:?}"
            );
        }
    }
    let has_input = doc["terms"]
        .as_array()
        .unwrap()
        .iter()
        .any(|t| t["term"].as_str().unwrap().contains("u(k"));
    if !has_input {
        assert!(
            w.iter().any(|w| w.contains("the model has no input term")),
            "{w:?}"
        );
    }
}

// Audit finding 3: hydraulic NARX (3, 3, 1) of degree 3 was y(k) = 0.428 y(k−1), no input term, fit
// −0.99 % / −0.69 % against the ARX baseline's 50.8 % / 35.7 %, with no word of it. Now the term choice
// falls back to the best one with an input term, says so, and every rule holds against the baseline.
#[test]
fn narx_without_an_input_term_is_not_chosen_silently_on_the_hydraulic_record() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let lags = ["--na", "3", "--nb", "3", "--nk", "1"];
    let mut args = vec!["identify"];
    args.extend(HYDRAULIC);
    args.extend(lags);
    let mut narx = args.clone();
    narx.extend(["--structure", "narx", "--degree", "3"]);
    let (_, doc) = run_json_code(&dir, &narx);
    let mut arx = args.clone();
    arx.extend(["--structure", "arx", "--method", "ls"]);
    let (_, base) = run_json_code(&dir, &arx);
    assert_narx_rules(&doc, &base);
    let terms: Vec<&str> = doc["terms"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["term"].as_str().unwrap())
        .collect();
    assert!(terms.iter().any(|t| t.contains("u(k")), "{terms:?}");
    // The one-term y(k−1) model of the audit is gone, and the fallback says why the terms differ from
    // the stopping rule's own choice when it made one.
    assert!(terms.len() > 1, "{terms:?}");
}

// Audit finding 3: coupled drives NARX (1, 1, 1) had a validation fit of −0.27 % with `warnings: []`.
// Every negative fit is warned, and `--strict` then exits 1 (as for the other structures).
#[test]
fn narx_negative_fit_is_warned_and_fails_strict_on_the_coupled_drives() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    // (lags, degree): the degree is the NARX model's only (the ARX baseline has none; identify refuses
    // --degree there).
    for (extra, degree) in [
        (&["--na", "1", "--nb", "1", "--nk", "1"][..], "2"),
        (&["--nb", "2", "--nk", "1", "--na", "2"][..], "3"),
    ] {
        let mut args = vec!["identify"];
        args.extend(DRIVES);
        args.extend(extra);
        let mut narx = args.clone();
        narx.extend(["--structure", "narx", "--degree", degree]);
        let (code, doc) = run_json_code(&dir, &narx);
        assert_eq!(code, 0);
        let mut arx = args.clone();
        arx.extend(["--structure", "arx", "--method", "ls"]);
        let (_, base) = run_json_code(&dir, &arx);
        assert_narx_rules(&doc, &base);
        if !warnings(&doc).is_empty() {
            // --strict: exit 1, and the untrusted result's JSON is not written.
            narx.push("--strict");
            let tmp = tempfile::tempdir().unwrap();
            let json = tmp.path().join("strict.json");
            let out = common::bin()
                .current_dir(&dir)
                .args(&narx)
                .arg("--json")
                .arg(&json)
                .output()
                .unwrap();
            assert_eq!(out.status.code(), Some(1), "{extra:?}");
            assert!(!json.exists(), "{extra:?}");
            assert!(String::from_utf8_lossy(&out.stderr).contains("not written"));
        }
    }
}

// `validate` of a saved NARX model says what `identify` says of its validation record: a negative fit,
// and a model without an input term (the coupled drives (2, 2, 1) of degree 3 keeps output terms only,
// every term set with an input blowing up on the selection part).
#[test]
fn validate_of_a_narx_model_warns_like_identify() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("narx.json");
    let model = model.to_str().unwrap();
    let mut args = vec!["identify"];
    args.extend(&DRIVES[..10]);
    args.extend([
        "--structure",
        "narx",
        "--na",
        "2",
        "--nb",
        "2",
        "--nk",
        "1",
        "--degree",
        "3",
        "--save-model",
        model,
    ]);
    run_json_code(&dir, &args);
    let text = std::fs::read_to_string(model).unwrap();
    let file: Value = serde_json::from_str(&text).unwrap();
    // The terms' names (the file's identification record repeats identify's warnings, which name u(k…)).
    let has_input = file["model"]["terms"].to_string().contains("u(k");
    let mut args = vec!["validate", "--model", model];
    args.extend(&DRIVES[..8]);
    args.extend(["--rows", "250..500"]);
    let (code, doc) = run_json_code(&dir, &args);
    assert_eq!(code, 0);
    let w = warnings(&doc);
    assert_eq!(
        w.iter().any(|w| w.contains("the model has no input term")),
        !has_input,
        "{w:?}"
    );
    let fit = doc["metrics"]["validation"]["fit_sim_percent"].as_f64();
    assert_eq!(
        w.iter()
            .any(|w| w.contains("negative simulation fit on the validation data")),
        fit.is_some_and(|f| f < 0.0),
        "{fit:?} {w:?}"
    );
}

/// The candidate of `doc` (an `order --classes` document) that was chosen.
fn chosen_candidate(doc: &Value) -> &Value {
    let c = &doc["chosen"];
    doc["candidates"]
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["class"] == c["class"] && d["orders"] == c["orders"])
        .unwrap()
}

// Audit finding 4: on the hydraulic record the class search recommended hammerstein (4, 4, 0), whose
// own warnings say its estimate simulates far worse than its linear start, it did not converge and its
// deadzone is not physical. The least-RMSE candidate is now passed over with a warning naming it, and
// the recommended one carries no disqualifying warning and a non-negative selection fit.
#[test]
fn order_classes_never_recommends_a_disqualified_candidate_on_the_hydraulic_record() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let mut args = vec!["order"];
    args.extend(HYDRAULIC);
    args.extend([
        "--na",
        "3..4",
        "--nb",
        "4",
        "--nk",
        "0",
        "--classes",
        "arx,hammerstein,narx2",
    ]);
    let (code, doc) = run_json_code(&dir, &args);
    assert_eq!(code, 0);
    let cands = doc["candidates"].as_array().unwrap();
    let disqualifying = [
        "far worse than the linear start",
        "not converged",
        "deadzone not physical",
        "unstable model",
        "negative simulation fit",
        "no input term",
        "blew up",
    ];
    let bad = |c: &Value| {
        c["warnings"].as_array().unwrap().iter().any(|w| {
            let w = w.as_str().unwrap();
            disqualifying.iter().any(|d| w.contains(d))
        }) || c["selection_fit_percent"].as_f64().is_none_or(|f| f < 0.0)
    };
    let least = cands
        .iter()
        .filter(|c| c["selection_rmse"].as_f64().is_some())
        .min_by(|a, b| {
            a["selection_rmse"]
                .as_f64()
                .unwrap()
                .total_cmp(&b["selection_rmse"].as_f64().unwrap())
        })
        .unwrap();
    match doc["chosen"].as_object() {
        Some(_) => {
            let chosen = chosen_candidate(&doc);
            assert!(!bad(chosen), "{chosen}");
            assert!(chosen.get("disqualified").is_none(), "{chosen}");
            if bad(least) {
                assert_ne!(least, chosen);
                let name = format!(
                    "{} ({}, {}, {})",
                    least["class"].as_str().unwrap(),
                    least["orders"]["na"],
                    least["orders"]["nb"],
                    least["orders"]["nk"]
                );
                assert!(
                    warnings(&doc)
                        .iter()
                        .any(|w| w.contains(&name) && w.contains("not recommended")),
                    "{name}: {:?}",
                    warnings(&doc)
                );
            }
        }
        None => {
            assert!(cands.iter().all(bad));
            assert!(warnings(&doc)
                .iter()
                .any(|w| w.contains("no structure qualifies")));
        }
    }
    // Every candidate after the first disqualified one is disqualified too (qualified ones first).
    let first_bad = cands.iter().position(bad).unwrap_or(cands.len());
    assert!(cands[first_bad..].iter().all(bad), "{cands:?}");
}

// Audit finding 4: coupled drives narx3 (2, 2, 0) was chosen with a test fit of −18.9 % and no word of
// the test record. Its negative test fit is now a warning, as plain `order` gives it.
#[test]
fn order_classes_warns_about_the_chosen_models_test_record() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let mut args = vec!["order"];
    args.extend(DRIVES);
    args.extend(["--na", "2", "--nb", "2", "--nk", "0", "--classes", "narx3"]);
    let (code, doc) = run_json_code(&dir, &args);
    assert_eq!(code, 0);
    let Some(fit) = doc["chosen"]["fit_sim_percent"].as_f64() else {
        return;
    };
    let said = warnings(&doc)
        .iter()
        .any(|w| w.starts_with("test record: negative simulation fit"));
    assert_eq!(said, fit < 0.0, "fit {fit}: {:?}", warnings(&doc));
}

/// The cascaded tanks' estimation signals (uEst, yEst) with their own rows, without --offset.
const TANKS: [&str; 8] = [
    "--data",
    "cascaded_tanks/dataBenchmark.csv",
    "--ts",
    "4",
    "--u-col",
    "uEst",
    "--y-col",
    "yEst",
];

/// The lags (3, 2, 0) of the audit's tanks NARX model.
const TANKS_LAGS: [&str; 6] = ["--na", "3", "--nb", "2", "--nk", "0"];

/// The selection fit (%) of ARX (3, 2, 0) by least squares estimated on rows 0..682 of the tanks'
/// estimation signals and simulated on rows 682..1024, with or without a constant term: the worse of
/// estimated and measured initial outputs, as the order search ranks. Separate `identify` runs.
fn tanks_arx_selection_fit(dir: &std::path::Path, offset: bool) -> f64 {
    let mut args = vec!["identify"];
    args.extend(TANKS);
    args.extend(TANKS_LAGS);
    args.extend([
        "--structure",
        "arx",
        "--method",
        "ls",
        "--rows",
        "0..682",
        "--val-rows",
        "682..1024",
    ]);
    if offset {
        args.push("--offset");
    }
    let (_, doc) = run_json_code(dir, &args);
    let m = &doc["metrics"]["validation"];
    m["fit_sim_percent"]
        .as_f64()
        .unwrap()
        .min(m["fit_sim_measured_percent"].as_f64().unwrap())
}

/// The offset hint among `warnings`, if any, with the two fits it quotes (with, without c).
fn offset_hint(warnings: &[String]) -> Option<(f64, f64)> {
    let w = warnings
        .iter()
        .find(|w| w.contains("the output has a non-zero operating point"))?;
    let num = |after: &str| -> f64 {
        let rest = &w[w.find(after).unwrap() + after.len()..];
        rest.split_whitespace().next().unwrap().parse().unwrap()
    };
    Some((num("fits the selection part by "), num("instead of ")))
}

/// `doc` holds the offset hint quoting the fits (with, without c) to their printed 0.1, and `advice`.
fn assert_hint(doc: &Value, (with, without): (f64, f64), advice: &str) {
    let w = warnings(doc);
    let (h_with, h_without) = offset_hint(&w).unwrap_or_else(|| panic!("no hint: {w:?}"));
    assert!(
        (h_with - with).abs() < 0.051 && (h_without - without).abs() < 0.051,
        "{w:?}"
    );
    assert!(w.iter().any(|w| w.contains(advice)), "{w:?}");
}

// Audit s12 F8: without --offset on the cascaded tanks (output mean about 5.4 V), plain `order` says a
// constant term would help, but NARX `identify` (−6.8 % on the test record) and `order --classes` said
// nothing. Both now give the same hint through the same test: ARX (3, 2, 0) on the selection part with
// and without c, whose fits are computed here by two separate `identify` runs. With --offset: no hint.
#[test]
fn narx_and_class_search_say_add_offset_on_the_cascaded_tanks() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let (with, without) = (
        tanks_arx_selection_fit(&dir, true),
        tanks_arx_selection_fit(&dir, false),
    );
    assert!(with > without + 5.0, "with c {with} %, without {without} %");
    let mut narx = vec!["identify"];
    narx.extend(TANKS);
    narx.extend(TANKS_LAGS);
    narx.extend(["--structure", "narx", "--degree", "2"]);
    let (_, doc) = run_json_code(&dir, &narx);
    assert_hint(&doc, (with, without), "identify again with --offset");
    narx.push("--offset");
    let (_, doc) = run_json_code(&dir, &narx);
    assert_eq!(offset_hint(&warnings(&doc)), None);

    let mut classes = vec!["order"];
    classes.extend(TANKS);
    classes.extend(TANKS_LAGS);
    classes.extend(["--classes", "narx2"]);
    let (_, doc) = run_json_code(&dir, &classes);
    assert_hint(&doc, (with, without), "search again with --offset");
}
