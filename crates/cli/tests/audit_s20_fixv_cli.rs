//! Session 20 (fixv): the memory bound of every estimation (`sysid::ls::MemoryNeed`) through the
//! binary where session 19 left it open — `order --classes` checks its largest class fit before it
//! fits any (exit 2, the code of a data problem, with the rows, p and memory of that fit).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{bin, stderr};

/// The budget of docs/reliability.md ("Resource bounds"): 4 GiB.
const BUDGET: f64 = 4.0 * 1024.0 * 1024.0 * 1024.0;

#[test]
fn a_class_search_over_the_memory_budget_is_refused_before_any_fit() {
    // `order --classes arx,narx3` over na = nb = 10, nk = 1 on 200 000 samples, two worker threads.
    // The largest fit is narx3 at (10, 10, 1), on the whole estimation record (its terms are chosen
    // on its last part): the monomials of degree 1..=3 in 20 lagged variables, M = C(23, 3) − 1 =
    // 1770 candidate terms (no --offset, no constant), 2M + min(T, M) + 4 numbers per row (T = 30,
    // --max-terms) for N = 200 000 − k0 rows, k0 = max(na, nk + nb − 1) = 10; two fits at once
    // double it: 11.4 GB > 4 GiB. ARX(10, 10, 1) on the estimation part needs far less (2p + 4
    // numbers per row, p = 20). The output moves (0, 1, 0, 1, …) so that the size is what is refused.
    let dir = tempfile::tempdir().unwrap();
    let n = 200_000;
    let csv = dir.path().join("long.csv");
    std::fs::write(&csv, format!("u,y\n{}", "0,0\n0,1\n".repeat(n / 2))).unwrap();
    let o = bin()
        .env("RAYON_NUM_THREADS", "2")
        .args([
            "order",
            "--data",
            csv.to_str().unwrap(),
            "--ts",
            "0.01",
            "--classes",
            "arx,narx3",
            "--na",
            "10",
            "--nb",
            "10",
            "--nk",
            "1",
        ])
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    let m = 23 * 22 * 21 / 6 - 1;
    let per_row = 2.0 * (2.0 * m as f64 + 30.0 + 4.0);
    let rows = n - 10;
    let bytes = rows as f64 * per_row * 8.0;
    assert!(bytes > BUDGET);
    assert!(
        err.contains(&format!(
            "(2 structures fitted at once): {rows} regression rows of {m} parameters"
        )),
        "{err}"
    );
    assert!(
        err.contains(&format!("about {:.1} GB", bytes / 1e9)),
        "{err}"
    );
    let fit = (BUDGET / (per_row * 8.0)).floor() as usize;
    assert!(err.contains(&format!("at most {fit} rows")), "{err}");
    assert!(
        !err.contains("panicked") && !err.contains("backtrace"),
        "{err}"
    );
    // Refused before the search: no ranking was printed.
    assert!(
        o.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
}
