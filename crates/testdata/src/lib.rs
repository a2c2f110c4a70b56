//! Where the tests find the real measured records of `../shared/data`, how a test that cannot run says
//! so visibly, and the deterministic test noise [`white`] that several test files share.
//!
//! The records are read at run time from the folder beside the repository (`../shared/data`, or the
//! folder named by `IPA_SYSID_SHARED_DATA`), never copied into it. A test that needs a record it cannot
//! find calls [`shared_data`] or [`record`], gets `None` and returns early: the test harness would then
//! print `ok`, so the skip is also appended, one line per test, to the file named by
//! `IPA_SYSID_SKIP_LOG`. `scripts/test` sets that variable, prints the skipped tests at the end, and
//! fails when the data folder is present but a test skipped anyway (a record renamed or moved).
//!
//! Hand-written because it is twenty lines: no test-support crate knows this project's data folder.

use std::io::Write;
use std::path::PathBuf;

/// The environment variable naming the shared data folder (default: `../shared/data` beside the
/// repository root).
pub const DATA_ENV: &str = "IPA_SYSID_SHARED_DATA";
/// The environment variable naming the file that collects skipped tests (set by `scripts/test`).
pub const SKIP_LOG_ENV: &str = "IPA_SYSID_SKIP_LOG";

/// The shared data folder if it exists; otherwise the skip is recorded and `None` returned.
pub fn shared_data() -> Option<PathBuf> {
    let dir = data_folder();
    if dir.is_dir() {
        Some(dir)
    } else {
        skip(&format!(
            "the shared data folder {} is absent",
            dir.display()
        ));
        None
    }
}

/// One record of the shared data folder (`rel` is relative to it, e.g. `"silverbox/SNLS80mV.csv"`) if it
/// exists; otherwise the skip is recorded and `None` returned.
pub fn record(rel: &str) -> Option<PathBuf> {
    let path = data_folder().join(rel);
    if path.is_file() {
        Some(path)
    } else {
        skip(&format!("the record {} is absent", path.display()));
        None
    }
}

/// Records that the running test is skipped, with the reason: printed (seen with `--nocapture` and in
/// failures) and appended to the skip log when `IPA_SYSID_SKIP_LOG` names one.
pub fn skip(reason: &str) {
    // libtest names each test's thread after the test.
    let current = std::thread::current();
    let test = current.name().unwrap_or("<unnamed test>");
    println!("SKIPPED {test}: {reason}");
    eprintln!("SKIPPED {test}: {reason}");
    if let Some(log) = std::env::var_os(SKIP_LOG_ENV) {
        let written = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .and_then(|mut f| writeln!(f, "{test}: {reason}"));
        if let Err(e) = written {
            eprintln!(
                "could not append to the skip log {}: {e}",
                log.to_string_lossy()
            );
        }
    }
}

fn data_folder() -> PathBuf {
    match std::env::var_os(DATA_ENV) {
        Some(dir) => PathBuf::from(dir),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"),
    }
}

/// A deterministic stand-in for white noise of unit variance: `n` draws of a 64-bit LCG (Knuth's MMIX
/// constants) from `seed`, uniform on (−√3, √3). The same `(n, seed)` gives the same samples on every
/// machine, so test expectations computed from it are reproducible.
pub fn white(n: usize, seed: u64) -> Vec<f64> {
    let mut x = seed;
    (0..n)
        .map(|_| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * 3f64.sqrt()
        })
        .collect()
}

/// The response of A(q) y = B(q) x + c written out as a plain loop, the tests' independent reference:
/// y(k) = −Σ a_i y(k−i) + Σ_j b_j x(k−nk−j+1) + c with zero history before k = 0.
pub fn arx_response(x: &[f64], a: &[f64], b: &[f64], nk: usize, c: f64) -> Vec<f64> {
    let mut y = vec![0.0; x.len()];
    for k in 0..x.len() {
        let mut v = c;
        for (i, ai) in a.iter().enumerate() {
            if k > i {
                v -= ai * y[k - 1 - i];
            }
        }
        for (j, bj) in b.iter().enumerate() {
            if k >= nk + j {
                v += bj * x[k - nk - j];
            }
        }
        y[k] = v;
    }
    y
}
