//! `bench oe` through the binary: a data folder without the records skips both cases in words and
//! exits 0; `--data-dir` is required (the records are not part of the project).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;
use common::bin;

#[test]
fn absent_records_are_skipped_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("oe.json");
    let out = bin()
        .args(["bench", "oe", "--repetitions", "1", "--data-dir"])
        .arg(dir.path())
        .arg("--json")
        .arg(&json)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    for name in ["emps", "silverbox"] {
        assert!(
            text.lines()
                .any(|l| l.contains(name) && l.contains("skipped") && l.contains("not found")),
            "{text}"
        );
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let cases = v["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 2);
    assert!(cases
        .iter()
        .all(|c| c["skipped"].is_string() && c.get("output_error").is_none()));
}

#[test]
fn the_data_folder_must_be_named() {
    let out = bin().args(["bench", "oe"]).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--data-dir"));
    // A folder that does not exist (a typo) is a usage error, not a run that measured nothing.
    let dir = tempfile::tempdir().unwrap();
    for what in ["oe", "narx"] {
        let out = bin()
            .args(["bench", what, "--repetitions", "1", "--data-dir"])
            .arg(dir.path().join("typo"))
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2), "{what}");
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(
            e.contains("--data-dir") && e.contains("an existing folder"),
            "{e}"
        );
    }
}
