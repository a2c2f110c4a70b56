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
    let csv = common::moving_output_csv(dir.path(), n);
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

/// A CSV record `u,y` of `n` rows: a pseudo-random input in [−1, 1) and the ARX(2, 2, 1) output
/// y(k) = 1.2 y(k−1) − 0.5 y(k−2) + u(k−1) + 0.5 u(k−2) (excited, so that only the size can be
/// refused).
fn excited_csv(dir: &std::path::Path, n: usize) -> std::path::PathBuf {
    let mut rng = common::lcg(20);
    let (u, y) = common::arx_signals(n, &[1.2, -0.5], &[1.0, 0.5], |_| 2.0 * rng.unit() - 1.0);
    let path = dir.join("r.csv");
    common::write_csv(&path, "u,y", None, &[&u, &y]);
    path
}

/// `args` followed by `--max-memory GIB`.
fn with_budget(args: &[&str], gib: &str) -> std::process::Output {
    bin()
        .args(args)
        .args(["--max-memory", gib])
        .output()
        .unwrap()
}

#[test]
fn a_small_record_is_refused_under_a_tiny_max_memory_and_accepted_under_a_larger_one() {
    // ARX(8, 2, 1) by least squares on 10 000 samples (the record is ARX(2, 2, 1) without noise: nb = 2
    // keeps the regressors independent): N = 10 000 − k0 rows, k0 = max(na, nk + nb − 1) = 8,
    // p = na + nb = 10, 2p + 4 = 24 numbers of 8 bytes per row (docs/reliability.md):
    // 1 918 464 bytes = 0.0019 GB, more than 0.0015 GiB (1 610 612 bytes), less than 0.003 GiB. The
    // record itself (its text and rows, held to the same budget since audit s27 M-1) is read within
    // 0.0015 GiB: at most twice its bytes plus 8 bytes per cell, per row and per line number.
    let dir = tempfile::tempdir().unwrap();
    let n = 10_000;
    let csv = excited_csv(dir.path(), n);
    let file = std::fs::metadata(&csv).unwrap().len() as f64;
    let args = [
        common::identify_arx(&csv, "8", "2", "ls"),
        vec!["--ts", "0.01", "--nk", "1"],
    ]
    .concat();
    let rows = n - 8;
    let bytes = rows * 24 * 8;
    let tiny = 0.0015 * (1u64 << 30) as f64;
    assert!(bytes as f64 > tiny && (bytes as f64) < 0.003 * (1u64 << 30) as f64);
    assert!(
        2.0 * file + ((8 * (2 + 2) * n) as f64) < tiny,
        "the record fits"
    );
    let o = with_budget(&args, "0.0015");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("{rows} regression rows of 10 parameters")),
        "{err}"
    );
    // 1 918 464 bytes are 0.0019 GB (two significant digits below 0.1 GB).
    assert_eq!(bytes, 1_918_464);
    assert!(err.contains("about 0.0019 GB"), "{err}");
    // The budget in GB beside its GiB, the unit of the figure it is compared with (audit s37 L-2).
    let budget_gb = 0.0015 * (1u64 << 30) as f64 / 1e9;
    assert!(
        err.contains(&format!(
            "budget of 0.0015 GiB ({budget_gb:.4} GB, --max-memory)"
        )),
        "{err}"
    );
    let fit = (tiny.floor() / (24.0 * 8.0)).floor() as usize;
    assert!(err.contains(&format!("at most {fit} rows")), "{err}");
    assert!(
        err.contains("raise --max-memory") && err.contains("if this machine has the memory"),
        "{err}"
    );
    // ARX by least squares from a CSV file: --stream on would read it in passes, and the refusal says so.
    assert!(err.contains("--stream on"), "{err}");
    let o = with_budget(&args, "0.003");
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    // Hammerstein by least squares cannot be streamed: the same refusal does not offer it (orders 2, 2:
    // the key-term estimation of its deadzone and ARX parameters needs more than 0.0015 GiB here).
    let mut hammerstein = [
        common::identify_arx(&csv, "2", "2", "ls"),
        vec!["--ts", "0.01", "--nk", "1"],
    ]
    .concat();
    let structure = hammerstein.iter().position(|a| *a == "arx").unwrap();
    hammerstein[structure] = "hammerstein";
    let o = with_budget(&hammerstein, "0.0015");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("regression rows"), "{err}");
    assert!(err.contains("raise --max-memory"), "{err}");
    assert!(!err.contains("--stream on"), "{err}");
}

#[test]
fn delay_and_order_take_the_same_budget() {
    // delay (na = nb = 6, delays 0..=10): ARX(6, 6, 10) with c, N = 10 000 − max(6, 10 + 6 − 1) =
    // 9985 rows, p = 13, 2p + 4 = 30 numbers per row: 2.4 MB > 0.0015 GiB (1 610 612 bytes), within
    // which the record itself is read (audit s27 M-1: its text and rows count against the budget too).
    let dir = tempfile::tempdir().unwrap();
    let csv = excited_csv(dir.path(), 10_000);
    let data = csv.to_str().unwrap();
    let delay = [
        "delay", "--data", data, "--ts", "0.01", "--na", "6", "--nb", "6",
    ];
    let o = with_budget(&delay, "0.0015");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("9985 regression rows of 13 parameters"),
        "{err}"
    );
    assert!(err.contains("raise --max-memory"), "{err}");
    assert_eq!(with_budget(&delay, "0.01").status.code(), Some(0));
    // order over na, nb = 1..8, nk = 1 by least squares, one worker thread: its largest structure
    // ARX(8, 8, 1) on the estimation part (the first 2/3 of the record, --selection-split: 6666 rows,
    // N = 6666 − 8) needs 6658 × 36 × 8 bytes = 1.9 MB > 0.0015 GiB, refused as one fit.
    let order = [
        "order", "--data", data, "--ts", "0.01", "--na", "1..8", "--nb", "1..8", "--nk", "1",
    ];
    let run = |gib: &str| {
        bin()
            .env("RAYON_NUM_THREADS", "1")
            .args(order)
            .args(["--max-memory", gib])
            .output()
            .unwrap()
    };
    let o = run("0.0015");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("6658 regression rows of 16 parameters"),
        "{err}"
    );
    assert!(err.contains("about 0.0019 GB"), "{err}");
    assert!(!err.contains("fitted at once"), "{err}");
    assert!(o.stdout.is_empty());
    assert_eq!(
        run("0.01").status.code(),
        Some(0),
        "{}",
        stderr(&run("0.01"))
    );
}

#[test]
fn a_max_memory_that_is_no_size_is_refused_with_its_unit() {
    let dir = tempfile::tempdir().unwrap();
    let csv = excited_csv(dir.path(), 100);
    for bad in ["0", "nan", "inf", "2000", "lots", "4GB"] {
        let o = with_budget(
            &["identify", "--data", csv.to_str().unwrap(), "--ts", "0.01"],
            bad,
        );
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{bad}: {err}");
        assert!(
            err.contains("--max-memory") && err.contains("GiB"),
            "{bad}: {err}"
        );
    }
}
