//! Session 36. Audit s36 H-1 and H-2: sizes that abort on a failed allocation are refused in words
//! before the work (a record file larger than the memory the process may take; `simulate` and
//! `montecarlo` runs larger than `--max-memory`); the streamed identification names each file's own
//! passes; a model file's stray top-level key is refused.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{bin, s, stderr};

/// Bytes per sample of the record budget: 16 numbers of 8 bytes (docs/reliability.md, "Resource
/// bounds").
const BYTES_PER_SAMPLE: u64 = 16 * 8;
const GIB: u64 = 1 << 30;

/// Runs the binary with `args` under a virtual-memory limit of `kib` KiB (`ulimit -v`).
#[cfg(target_os = "linux")]
fn limited(kib: u64, args: &[&str]) -> std::process::Output {
    std::process::Command::new("sh")
        .arg("-c")
        .arg(format!("ulimit -v {kib} && exec \"$0\" \"$@\""))
        .arg(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(args)
        .output()
        .unwrap()
}

// A 1.5 GB record (a sparse file: no disk used) under a 1 GB memory limit: the reservation of its size
// fails, which used to abort the process (exit 134, SIGABRT); now an error names the file (exit 2).
#[cfg(target_os = "linux")]
#[test]
fn a_record_larger_than_the_memory_limit_is_refused_not_aborted() {
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.csv");
    let f = std::fs::File::create(&big).unwrap();
    f.set_len(1_500_000_000).unwrap();
    drop(f);
    let out = limited(1_000_000, &["identify", "--data", s(&big)]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("big.csv") && err.contains("cannot be held in memory here"),
        "{err}"
    );
}

// `simulate` of a physics plant: the budget of --max-memory applies (it used to apply to model plants
// only, and 5 × 10^7 samples took about 4.6 GB): the largest run that fits is named.
#[test]
fn simulate_refuses_a_run_beyond_its_memory_budget_before_it_starts() {
    let dir = tempfile::tempdir().unwrap();
    let out_csv = dir.path().join("x.csv");
    for (plant, samples, gib) in [("ipa", "50000000", 4u64), ("paper", "10000000", 1)] {
        let out = bin()
            .args([
                "simulate",
                "--plant",
                plant,
                "--samples",
                samples,
                "--max-memory",
                &gib.to_string(),
                "--out",
                s(&out_csv),
            ])
            .output()
            .unwrap();
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{err}");
        let fit = gib * GIB / BYTES_PER_SAMPLE;
        assert!(
            err.contains(&format!("use at most {fit} samples")) && err.contains("--max-memory"),
            "{err}"
        );
        assert!(!out_csv.exists());
    }
    // Within the budget: written (1 GiB holds 8 388 608 samples; 3000 are nothing).
    let out = bin()
        .args([
            "simulate",
            "--samples",
            "3000",
            "--max-memory",
            "1",
            "--out",
            s(&out_csv),
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
}

// `montecarlo`: the runs in flight at once (one per worker thread: 2 here) each hold a record.
#[test]
fn montecarlo_refuses_runs_beyond_its_memory_budget_before_any_run() {
    let out = bin()
        .env("RAYON_NUM_THREADS", "2")
        .args([
            "montecarlo",
            "--runs",
            "4",
            "--samples",
            "50000000",
            "--max-work",
            "100000000000",
        ])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    let fit = 4 * GIB / (BYTES_PER_SAMPLE * 2);
    assert!(
        err.contains("2 run(s) at once") && err.contains(&format!("use at most {fit} samples")),
        "{err}"
    );
}

// `identify --stream on --validation`: a note per file, each with its own passes: the estimation
// record 3 (the fit, then its metrics in 2), the validation record 2 (its metrics).
#[test]
fn a_streamed_identification_notes_each_files_passes() {
    let dir = tempfile::tempdir().unwrap();
    let (est, val) = (dir.path().join("e.csv"), dir.path().join("v.csv"));
    for (path, seed) in [(&est, "1"), (&val, "2")] {
        let out = bin()
            .args(["simulate", "--seed", seed, "--out", s(path)])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
    }
    let out = bin()
        .args([
            "identify",
            "--data",
            s(&est),
            "--validation",
            s(&val),
            "--structure",
            "arx",
            "--method",
            "ls",
            "--stream",
            "on",
        ])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("e.csv was read in 3 passes"), "{err}");
    assert!(err.contains("v.csv was read in 2 passes"), "{err}");
}

// A model file holds "format", "version" and "model": a key beside them is refused, naming it.
#[test]
fn a_stray_top_level_key_of_a_model_file_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (rec, model) = (dir.path().join("r.csv"), dir.path().join("m.json"));
    let out = bin()
        .args(["simulate", "--samples", "600", "--out", s(&rec)])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let out = bin()
        .args([
            "identify",
            "--data",
            s(&rec),
            "--method",
            "ls",
            "--save-model",
            s(&model),
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let text = std::fs::read_to_string(&model).unwrap();
    std::fs::write(&model, text.replacen('{', "{\n  \"ts\": 0.02,", 1)).unwrap();
    let out = bin()
        .args(["validate", "--model", s(&model), "--data", s(&rec)])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("m.json") && err.contains("unknown key \"ts\" at the top level"),
        "{err}"
    );
}
