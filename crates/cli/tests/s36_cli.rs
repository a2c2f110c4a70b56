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
    // Audit s37 L-1: an `identify --json` report without its "format" mark (as every version before
    // session 32 wrote it) is a report, read for its model as then: `validate` prints the same fit as
    // with the marked report.
    let report = dir.path().join("report.json");
    let out = bin()
        .args([
            "identify",
            "--data",
            s(&rec),
            "--method",
            "ls",
            "--json",
            s(&report),
        ])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let validate = |path: &std::path::Path| {
        let out = bin()
            .args(["validate", "--model", s(path), "--data", s(&rec)])
            .output()
            .unwrap();
        assert!(out.status.success(), "{}", stderr(&out));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let marked = validate(&report);
    assert!(doc.as_object_mut().unwrap().remove("format").is_some());
    let unmarked = dir.path().join("old.json");
    std::fs::write(&unmarked, doc.to_string()).unwrap();
    assert_eq!(
        validate(&unmarked).replace("old.json", "report.json"),
        marked
    );
}

/// `t,u,y` rows k = from..to of a first-order response to a ±1 square wave (period 10 samples).
fn rows(from: usize, to: usize) -> String {
    let mut y = 0.0_f64;
    let mut out = String::new();
    for k in 0..to {
        let u = if (k / 5) % 2 == 0 { 1.0 } else { -1.0 };
        if k >= from {
            out.push_str(&format!("{:.2},{u},{y}\n", k as f64 * 0.01));
        }
        y = 0.9 * y + 0.1 * u;
    }
    out
}

/// Waits for `track`'s JSON line of sample `k` on `out`.
#[cfg(unix)]
fn wait_for_line(out: &mut impl std::io::BufRead, k: usize) {
    let mut line = String::new();
    loop {
        line.clear();
        assert!(out.read_line(&mut line).unwrap() > 0, "track ended early");
        let v: serde_json::Value = serde_json::from_str(&line).unwrap();
        if v["k"] == k {
            return;
        }
    }
}

// Audit s36 L-6: `logger | track --data -` (docs/online.md's live example) stopped by Ctrl-C, which
// reaches the logger too (its end closes the pipe, here in the middle of a line): the run ends with
// its summary and --json of the 40 finished rows, exit 0. The unfinished line is dropped with a
// warning when track had read it before the stop; a stop seen between two lines ends the run there,
// before reading it, and nothing was dropped (a race of the signal with the reader: both endings are
// right, so either is accepted; the warning's own words are tested without a signal by the unit test
// `a_live_source_ending_inside_its_last_line_drops_it_and_keeps_the_run`, crates/cli/src/cmd/track_stream.rs).
#[cfg(unix)]
#[test]
fn a_piped_track_stopped_by_ctrl_c_ends_with_its_summary() {
    use std::io::{BufReader, Write};
    use std::process::Stdio;
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("s.json");
    let mut child = bin()
        .args(["track", "--data", "-", "--structure", "arx", "--no-detect"])
        .args(["--every", "1", "--json", s(&summary)])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut stdin = child.stdin.take().unwrap();
    write!(stdin, "t,u,y\n{}0.40,1", rows(0, 40)).unwrap();
    stdin.flush().unwrap();
    let mut out = BufReader::new(child.stdout.take().unwrap());
    wait_for_line(&mut out, 39);
    let kill = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    drop(stdin);
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(doc["samples"], 40);
    let said = doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|w| w.as_str().unwrap().contains("ended inside its last line"))
        .count();
    assert!(said <= 1, "{doc}");
    if said == 1 {
        assert!(doc["warnings"]
            .to_string()
            .contains("ended inside its last line (6 bytes without a line end"));
    }
}

// Audit s36 L-10: a followed file that holds only its header, stopped by Ctrl-C: exit 2 and no
// --json, as the idle time-out ends the same run (it wrote a summary with "model": null, exit 0).
#[cfg(unix)]
#[test]
fn a_followed_header_stopped_by_ctrl_c_is_an_error_as_at_the_idle_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let (path, summary) = (dir.path().join("h.csv"), dir.path().join("s.json"));
    std::fs::write(&path, "t,u,y\n").unwrap();
    let child = bin()
        .args(["track", "--follow", s(&path), "--json", s(&summary)])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The header is read within the first 20 ms poll; the signal comes well after it.
    std::thread::sleep(std::time::Duration::from_millis(700));
    let kill = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("h.csv") && err.contains("before any data row"),
        "{err}"
    );
    assert!(!summary.exists());
}
