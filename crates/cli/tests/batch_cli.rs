//! `identify` batch mode through the binary: a folder or several files, one JSON line per file, failures
//! reported per file with a non-zero exit, each line equal to the single-file `--json` object.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::Path;

use serde_json::Value;

mod common;
use common::{bin, paper_record, write_tuy};

fn lines(text: &str) -> Vec<Value> {
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not JSON: {e}: {l}")))
        .collect()
}

// A folder: its *.csv files in name order (other files ignored), one line each; a malformed file gets an
// error line naming line and column, the others are still identified, and the exit code is 2.
#[test]
fn folder_gives_one_line_per_csv_in_name_order_and_fails_at_the_end() {
    let dir = tempfile::tempdir().unwrap();
    for (i, name) in ["c.csv", "a.csv", "b.csv"].iter().enumerate() {
        let (u, y) = paper_record(900, 3 * i);
        write_tuy(dir.path(), name, 0.01, &u, &y);
    }
    std::fs::write(dir.path().join("bad.csv"), "t,u,y\n0,1,2\n0.01,oops,3\n").unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not data").unwrap();
    let out = bin()
        .args(["identify", "--method", "ls", "--data"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v = lines(&String::from_utf8(out.stdout).unwrap());
    let files: Vec<String> = v
        .iter()
        .map(|l| {
            Path::new(l["file"].as_str().unwrap())
                .file_name()
                .unwrap()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    assert_eq!(files, ["a.csv", "b.csv", "bad.csv", "c.csv"]);
    let err = v[2]["error"].as_str().unwrap();
    assert!(err.contains(":3:2:") && err.contains("oops"), "{err}");
    for l in [&v[0], &v[1], &v[3]] {
        assert!(l.get("error").is_none());
        // Noise-free paper data: a1 = −1.869 is recovered.
        let a1 = l["model"]["a"][0].as_f64().unwrap();
        assert!((a1 + 1.869).abs() < 1e-6, "a1 = {a1}");
    }
}

// Each batch line is the single-file --json object of that file plus "file"; explicit files keep the
// order given; --json OUT receives the lines and the exit code is 0 when every file succeeds.
#[test]
fn explicit_files_keep_their_order_and_match_single_file_output() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(700, 1);
    let second = write_tuy(dir.path(), "z.csv", 0.01, &u, &y);
    let (u, y) = paper_record(800, 4);
    let first = write_tuy(dir.path(), "m.csv", 0.01, &u, &y);
    let out_path = dir.path().join("all.jsonl");
    let out = bin()
        .args(["identify", "--method", "rls", "--passes", "3", "--data"])
        .arg(&first)
        .arg(&second)
        .arg("--json")
        .arg(&out_path)
        .output()
        .unwrap();
    assert!(out.status.success());
    let v = lines(&std::fs::read_to_string(&out_path).unwrap());
    assert_eq!(v.len(), 2);
    // Standard error says how many lines carry warnings, counted here from the lines themselves
    // (audit s13 L12: it said nothing of them).
    let warned = v
        .iter()
        .filter(|l| l["warnings"].as_array().is_some_and(|w| !w.is_empty()))
        .count();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.contains(&format!(
            "warning: {warned} of 2 identified files have warnings"
        )),
        warned > 0,
        "{err}"
    );
    for (line, path) in v.iter().zip([&first, &second]) {
        assert_eq!(line["file"].as_str().unwrap(), path.display().to_string());
        let single = dir.path().join("single.json");
        let st = bin()
            .args(["identify", "--method", "rls", "--passes", "3", "--data"])
            .arg(path)
            .arg("--json")
            .arg(&single)
            .output()
            .unwrap();
        assert!(st.status.success());
        let want: Value = serde_json::from_str(&std::fs::read_to_string(&single).unwrap()).unwrap();
        let mut got = line.clone();
        got.as_object_mut().unwrap().remove("file");
        assert_eq!(got, want);
    }
}

// One model file cannot hold many models: --save-model is refused in batch mode before any work.
#[test]
fn save_model_is_refused_in_batch_mode() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(300, 0);
    let a = write_tuy(dir.path(), "a.csv", 0.01, &u, &y);
    let b = write_tuy(dir.path(), "b.csv", 0.01, &u, &y);
    let out = bin()
        .args(["identify", "--data"])
        .arg(&a)
        .arg(&b)
        .arg("--save-model")
        .arg(dir.path().join("m.json"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--save-model"));
    assert!(out.stdout.is_empty());
}

#[test]
fn folder_without_csv_files_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = bin()
        .args(["identify", "--data"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("*.csv"));
}

// The reader's notes travel with each file's line (audit s24 M-3): a --ts that contradicts the time
// column (t steps 0.01 s, --ts 1: 100 times) is said in the folder run's warnings, as by the run on the
// file alone — the ratio is computed here from the two steps, not read from the program.
#[test]
fn a_folder_run_carries_the_readers_notes_like_the_single_file_run() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(900, 1);
    write_tuy(dir.path(), "a.csv", 0.01, &u, &y);
    let folder = bin()
        .args([
            "identify",
            "--method",
            "ls",
            "--structure",
            "arx",
            "--ts",
            "1",
            "--data",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    let v = lines(&String::from_utf8(folder.stdout).unwrap());
    let warnings: Vec<&str> = v[0]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    let ratio = format!("{} times", 1.0 / 0.01);
    let said: Vec<&&str> = warnings
        .iter()
        .filter(|w| w.starts_with("data: ") && w.contains("contradicts the time column"))
        .collect();
    assert_eq!(said.len(), 1, "{warnings:?}");
    assert!(said[0].contains(&ratio), "{said:?} ({ratio})");
    let single = bin()
        .args([
            "identify",
            "--method",
            "ls",
            "--structure",
            "arx",
            "--ts",
            "1",
            "--json",
            "-",
            "--data",
        ])
        .arg(dir.path().join("a.csv"))
        .output()
        .unwrap();
    let one: Value = serde_json::from_slice(&single.stdout).unwrap();
    assert!(
        one["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str() == Some(*said[0])),
        "{}",
        one["warnings"]
    );
}

// Records sampled at different Ts in one folder (audit s26 L-5): the odd file's line says so in its
// "warnings", the others' lines do not, and the run's summary names every Ts with its count.
#[test]
fn a_folder_of_records_at_different_sampling_times_says_so() {
    let dir = tempfile::tempdir().unwrap();
    for (name, ts) in [("a.csv", 0.01), ("b.csv", 0.01), ("c.csv", 0.02)] {
        let (u, y) = paper_record(900, 1);
        write_tuy(dir.path(), name, ts, &u, &y);
    }
    let out = bin()
        .args(["identify", "--method", "ls", "--structure", "arx", "--data"])
        .arg(dir.path())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("sampling times differ: Ts = 0.01 s (2 files), 0.02 s (1 file)"),
        "{stderr}"
    );
    let v = lines(&String::from_utf8(out.stdout).unwrap());
    assert_eq!(v.len(), 3);
    let odd: Vec<bool> = v
        .iter()
        .map(|l| {
            l["warnings"].as_array().unwrap().iter().any(|w| {
                w.as_str()
                    .unwrap()
                    .starts_with("batch: this record is sampled every")
            })
        })
        .collect();
    assert_eq!(odd, [false, false, true], "{v:?}");
    let said = v[2]["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .find(|w| w.starts_with("batch:"))
        .unwrap();
    assert!(
        said.contains("every 0.02 s, 2 of the run's 3 identified records every 0.01 s"),
        "{said}"
    );
    // One Ts: no word about it.
    std::fs::remove_file(dir.path().join("c.csv")).unwrap();
    let out = bin()
        .args(["identify", "--method", "ls", "--structure", "arx", "--data"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!String::from_utf8_lossy(&out.stderr).contains("sampling times differ"));
}
