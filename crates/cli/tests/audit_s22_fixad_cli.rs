//! Audit s22 (helper fixad) through the binary: `validate`'s in-sample rule compares columns and
//! samples, not file names (M-R2); `order` without a test record warns the chosen structure's fall
//! from its estimation fit to its selection fit (M-R1); `tune` and `control` say when the loop leaves
//! the model's data (M-B1). Records are generated here from difference equations; expectations are
//! worked out by hand from them, never copied from the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};

mod common;
use common::{arx_signals, lcg, run as ipa_sysid, run_json_code, stderr, warnings, write_csv};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// `dir/two.csv` with two experiments side by side: u,y from y(k) = 0.5 y(k−1) + u(k−1) and u2,y2
/// from y(k) = 0.8 y(k−1) + 0.3 u(k−1), each with its own random input in [−1, 1] (600 rows, Ts =
/// 0.1 s by --ts).
fn two_experiments(dir: &Path) -> PathBuf {
    let mut r1 = lcg(1);
    let mut r2 = lcg(2);
    let (u, y) = arx_signals(600, &[0.5], &[1.0], |_| 2.0 * r1.unit() - 1.0);
    let (u2, y2) = arx_signals(600, &[0.8], &[0.3], |_| 2.0 * r2.unit() - 1.0);
    let path = dir.join("two.csv");
    write_csv(&path, "u,y,u2,y2", None, &[&u, &y, &u2, &y2]);
    path
}

fn in_sample(w: &[String]) -> Vec<&String> {
    w.iter().filter(|w| w.contains("in-sample")).collect()
}

// M-R2: a model estimated on u,y of two.csv. Validated on u2,y2 of the same file (the other
// experiment): held out, no in-sample word. On u,y again: in-sample. On a copy of two.csv under
// another name, in the estimation columns: the same samples, in-sample.
#[test]
fn validate_judges_in_sample_by_columns_and_samples_not_names() {
    let dir = tempfile::tempdir().unwrap();
    let data = two_experiments(dir.path());
    let model = dir.path().join("m.json");
    let mut args = common::identify_arx(&data, "1", "1", "ls");
    args.extend(["--ts", "0.1", "--save-model", s(&model)]);
    let o = ipa_sysid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let validate = |file: &Path, cols: &[&str]| {
        let mut a = vec!["validate", "--model", s(&model), "--data", s(file)];
        a.extend(cols);
        run_json_code(dir.path(), &a).1
    };
    let other = validate(&data, &["--u-col", "u2", "--y-col", "y2"]);
    assert!(in_sample(&warnings(&other)).is_empty(), "{other}");
    let same = validate(&data, &[]);
    let w = warnings(&same);
    assert!(
        in_sample(&w)
            .iter()
            .any(|w| w.starts_with("this is the data the model was estimated on")),
        "{w:?}"
    );
    let copy = dir.path().join("copy.csv");
    std::fs::copy(&data, &copy).unwrap();
    let copied = validate(&copy, &[]);
    let w = warnings(&copied);
    assert!(
        in_sample(&w)
            .iter()
            .any(|w| w.contains("holds the same samples as the estimation record")),
        "{w:?}"
    );
    // --strict: the copy's in-sample fit is a warning, so it exits 1.
    let o = ipa_sysid(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&copy),
        "--strict",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
}

// M-R2 on the measured record: the cascaded tanks' file holds the estimation (uEst, yEst) and the
// test (uVal, yVal) experiments; validating on the test columns is held out.
#[test]
fn the_cascaded_tanks_test_columns_are_held_out() {
    let Some(root) = ipa_testdata::shared_data() else {
        return;
    };
    let d = root.join("cascaded_tanks/dataBenchmark.csv");
    if !d.is_file() {
        eprintln!("SKIPPED: {} is absent", d.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("ct.json");
    let o = ipa_sysid(&[
        "identify",
        "--data",
        s(&d),
        "--u-col",
        "uEst",
        "--y-col",
        "yEst",
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
        "--offset",
        "--save-model",
        s(&model),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (_, doc) = run_json_code(
        dir.path(),
        &[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&d),
            "--u-col",
            "uVal",
            "--y-col",
            "yVal",
            "--ts",
            "4",
        ],
    );
    assert!(in_sample(&warnings(&doc)).is_empty(), "{doc}");
    let (_, doc) = run_json_code(
        dir.path(),
        &[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&d),
            "--ts",
            "4",
        ],
    );
    assert!(!in_sample(&warnings(&doc)).is_empty(), "{doc}");
}

