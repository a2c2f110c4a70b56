//! `order` through the binary: ranking, JSON, range syntax errors.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
}

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
