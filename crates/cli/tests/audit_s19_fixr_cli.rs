//! Audit s19 H-1 through the binary: a record whose estimation would need more memory than
//! `--max-memory` (4 GiB by default, `sysid::ls::MAX_ESTIMATION_BYTES`) is refused before any N × p matrix is allocated (exit 2, the
//! code of a data problem, with the rows, p, the memory and the way forward), and a long `delay`
//! search says how far it is on stderr.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};

mod common;
use common::{identify_arx, run as ipa_sysid, stderr};

/// The budget of docs/reliability.md ("Resource bounds"): 4 GiB.
const BUDGET: f64 = 4.0 * 1024.0 * 1024.0 * 1024.0;

/// A CSV record `u,y` of `n` rows of zeros (cheap to write and read; the size check comes before any
/// look at the data's excitation).
fn zeros_csv(dir: &Path, n: usize) -> PathBuf {
    let path = dir.join("long.csv");
    std::fs::write(&path, format!("u,y\n{}", "0,0\n".repeat(n))).unwrap();
    path
}

#[test]
fn an_estimation_over_the_memory_budget_is_refused_before_it_allocates() {
    // Output error on ARX(100, 100, 1): p = 200 parameters, N = n − 100 regression rows, and by
    // docs/reliability.md 5p + 4 numbers of 8 bytes per row: 560 000 rows need 4.5 GB > 4 GiB.
    let dir = tempfile::tempdir().unwrap();
    let n = 560_000;
    let csv = zeros_csv(dir.path(), n);
    let o = ipa_sysid(
        &[
            identify_arx(&csv, "100", "100", "oe"),
            vec!["--ts", "0.01", "--nk", "1"],
        ]
        .concat(),
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    let rows = n - 100;
    let bytes = rows as f64 * (5.0 * 200.0 + 4.0) * 8.0;
    assert!(bytes > BUDGET);
    assert!(
        err.contains(&format!("{rows} regression rows of 200 parameters")),
        "{err}"
    );
    assert!(
        err.contains(&format!("about {:.1} GB", bytes / 1e9)),
        "{err}"
    );
    assert!(
        err.contains("--rows") && err.contains("--resample"),
        "{err}"
    );
    assert!(
        !err.contains("panicked") && !err.contains("backtrace"),
        "{err}"
    );
    // The most rows the message offers do fit the budget, one more does not.
    let fit = (BUDGET / ((5.0 * 200.0 + 4.0) * 8.0)).floor() as usize;
    assert!(err.contains(&format!("at most {fit} rows")), "{err}");
}

#[test]
fn least_squares_on_the_same_record_needs_less_and_is_checked_with_its_own_size() {
    // ARX(100, 100, 1) by least squares holds 2p + 4 numbers per row: 560 000 rows need 1.8 GB, under
    // the budget, so the size check lets it through and the data's own problem is what is reported
    // (a zero input cannot determine the model: exit 2, not the memory message).
    let dir = tempfile::tempdir().unwrap();
    let csv = zeros_csv(dir.path(), 560_000);
    let o = ipa_sysid(
        &[
            identify_arx(&csv, "100", "100", "ls"),
            vec!["--ts", "0.01", "--nk", "1"],
        ]
        .concat(),
    );
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(!err.contains("--max-memory"), "{err}");
}

#[test]
fn a_long_delay_search_reports_each_candidate_on_stderr() {
    // 100 000 samples × 101 delays ≥ 10⁷ (sysid::delay::PROGRESS_WORK): one line per delay fitted.
    let dir = tempfile::tempdir().unwrap();
    let n = 100_000;
    let u: Vec<f64> = (0..n).map(|k| ((k * 7919) % 13) as f64 - 6.0).collect();
    let mut y = vec![0.0; n];
    for k in 3..n {
        y[k] = 0.5 * y[k - 1] + u[k - 3];
    }
    let mut text = String::from("u,y\n");
    for k in 0..n {
        text.push_str(&format!("{},{}\n", u[k], y[k]));
    }
    let csv = dir.path().join("d.csv");
    std::fs::write(&csv, text).unwrap();
    let o = ipa_sysid(&[
        "delay",
        "--data",
        csv.to_str().unwrap(),
        "--ts",
        "0.01",
        "--max-delay",
        "100",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    let lines = err
        .lines()
        .filter(|l| l.starts_with("delay: nk = "))
        .count();
    assert_eq!(lines, 101, "{err}");
    assert!(err.contains("delay: nk = 100 fitted (101 of 101"), "{err}");
}

#[test]
fn a_narx_estimation_over_the_memory_budget_is_refused_before_it_allocates() {
    // Polynomial NARX with na = nb = 10 and degree 3, without --offset (no constant): the monomials
    // of degree 1..=3 in 20 lagged variables, M = C(23, 3) − 1 = 1770 candidate terms; by sysid::narx::numbers_per_row the FROLS peak holds 2M + min(T, M) + 4 numbers per row
    // (T = --max-terms, 30 by default). k0 = max(na, nk + nb − 1) = 10, so 200 000 samples give
    // 199 990 rows: 5.7 GB > 4 GiB. The output moves (0, 1, 0, 1, …) so that the size is what is
    // refused.
    let dir = tempfile::tempdir().unwrap();
    let n = 200_000;
    let csv = common::moving_output_csv(dir.path(), n);
    let o = ipa_sysid(&[
        "identify",
        "--data",
        csv.to_str().unwrap(),
        "--ts",
        "0.01",
        "--structure",
        "narx",
        "--na",
        "10",
        "--nb",
        "10",
        "--nk",
        "1",
        "--degree",
        "3",
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    let m = 23 * 22 * 21 / 6 - 1;
    let per_row = 2.0 * m as f64 + 30.0 + 4.0;
    let rows = n - 10;
    let bytes = rows as f64 * per_row * 8.0;
    assert!(bytes > BUDGET);
    assert!(
        err.contains(&format!("{rows} regression rows of {m} parameters")),
        "{err}"
    );
    assert!(
        err.contains(&format!("about {:.1} GB", bytes / 1e9)),
        "{err}"
    );
    assert!(
        !err.contains("panicked") && !err.contains("backtrace"),
        "{err}"
    );
    let fit = (BUDGET / (per_row * 8.0)).floor() as usize;
    assert!(err.contains(&format!("at most {fit} rows")), "{err}");
}
