//! Batch identification and the order search give the same output whatever the number of worker
//! threads (`RAYON_NUM_THREADS` = 1 or 2): each file and each structure is estimated independently by
//! the same serial code, and the results are put back in the input order before ranking or printing.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;

/// An ARX(2, 2, 1) record, y(k) = 1.5 y(k−1) − 0.7 y(k−2) + u(k−1) + 0.5 u(k−2), plus white output
/// noise (a fixed linear congruential sequence, so that the estimators have something to refine).
fn record(dir: &Path, name: &str, seed: u64) -> PathBuf {
    let n = 800;
    // The sequence starts one step after `seed`.
    let mut rng = common::lcg(seed);
    rng.next_u64();
    let mut noise = || (rng.unit() - 0.5) * 0.2;
    let u: Vec<f64> = (0..n)
        .map(|k| {
            if ((k / 13) * 7 + seed as usize) % 3 == 0 {
                1.0
            } else {
                -1.0
            }
        })
        .collect();
    let mut x = vec![0.0; n];
    for k in 2..n {
        x[k] = 1.5 * x[k - 1] - 0.7 * x[k - 2] + u[k - 1] + 0.5 * u[k - 2];
    }
    let mut s = String::from("t,u,y\n");
    for k in 0..n {
        s += &format!("{},{},{}\n", k as f64 * 0.01, u[k], x[k] + noise());
    }
    let p = dir.join(name);
    std::fs::write(&p, s).unwrap();
    p
}

fn run(threads: usize, args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .env("RAYON_NUM_THREADS", threads.to_string())
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

// Four files, output error: the JSON lines are byte-identical with one and with two worker threads.
#[test]
fn batch_output_error_is_identical_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let files: Vec<String> = (0..4)
        .map(|i| {
            record(dir.path(), &format!("r{i}.csv"), i)
                .display()
                .to_string()
        })
        .collect();
    let mut args = vec!["identify", "--data"];
    args.extend(files.iter().map(String::as_str));
    args.extend([
        "--model", "arx", "--na", "2", "--nb", "2", "--nk", "1", "--method", "oe",
    ]);
    let one = run(1, &args);
    let two = run(2, &args);
    assert!(String::from_utf8_lossy(&one.stderr).contains("on 1 threads"));
    assert!(String::from_utf8_lossy(&two.stderr).contains("on 2 threads"));
    assert_eq!(String::from_utf8_lossy(&one.stdout).lines().count(), 4);
    assert_eq!(one.stdout, two.stdout);
}

// Output-error order search over a 3 × 2 × 2 grid: the same ranking and figures (JSON) on one and two
// worker threads.
#[test]
fn order_search_with_output_error_is_identical_on_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let est = record(dir.path(), "est.csv", 5).display().to_string();
    let args = [
        "order", "--data", &est, "--model", "arx", "--method", "oe", "--na", "1..3", "--nb",
        "1..2", "--nk", "1..2", "--json", "-",
    ];
    let one = run(1, &args);
    let two = run(2, &args);
    let json: serde_json::Value = serde_json::from_slice(&one.stdout).unwrap();
    assert_eq!(json["candidates"].as_array().unwrap().len(), 12);
    assert_eq!(one.stdout, two.stdout);
}
