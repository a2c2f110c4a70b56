//! Session 25 (helper fixal) through the binary: `validate` of a polynomial NARX model has the record
//! budget of a linear model's (`--max-memory`; before, none: audit s23 H-B1's leftover). The
//! expectation is the record's size times the numbers `validate` holds per sample (16 f64 of 8
//! bytes), computed here from the record written, never from the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{arx_signals, lcg, run as ipa_sysid, s, stderr, write_csv};

#[test]
fn narx_validate_refuses_a_record_beyond_its_memory_budget() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 1000;
    let mut r = lcg(11);
    let (u, y) = arx_signals(n, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let csv = d.join("rec.csv");
    write_csv(&csv, "u,y", None, &[&u, &y]);
    let model = d.join("narx.json");
    let fit = ipa_sysid(&[
        "identify",
        "--data",
        s(&csv),
        "--ts",
        "1",
        "--structure",
        "narx",
        "--degree",
        "2",
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
        "--save-model",
        s(&model),
    ]);
    assert!(fit.status.success(), "{}", stderr(&fit));
    let validate = |gib: &str| {
        ipa_sysid(&[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&csv),
            "--ts",
            "1",
            "--max-memory",
            gib,
        ])
    };
    let need = n as f64 * 16.0 * 8.0; // 128 000 bytes
                                      // 0.001 GiB = 1 073 741 bytes ≥ the need: validated.
    assert!(0.001 * 1024f64.powi(3) > need);
    let ok = validate("0.001");
    assert!(ok.status.success(), "{}", stderr(&ok));
    // 0.0001 GiB = 107 374 bytes < the need: refused before the simulation, naming the record and
    // the option.
    assert!(0.0001 * 1024f64.powi(3) < need);
    let no = validate("0.0001");
    let err = stderr(&no);
    assert_eq!(no.status.code(), Some(2), "{err}");
    assert!(err.contains("rec.csv"), "{err}");
    assert!(err.contains("--max-memory"), "{err}");
    assert!(err.contains(&format!("{n} regression rows")), "{err}");
}
