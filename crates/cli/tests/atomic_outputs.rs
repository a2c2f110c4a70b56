//! Output files through the binary: a failed run leaves existing outputs untouched, an output path equal
//! to an input (or to another output) is refused, no temporary file is left behind, and the written files
//! have ordinary permissions.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn corpus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/corpus")
}

/// Runs the binary in `dir` with `args`; `{c}` stands for the corpus folder, `{t}` for `dir`.
fn run(args: &str, dir: &Path) -> Output {
    let c = corpus();
    let argv: Vec<String> = args
        .split_whitespace()
        .map(|a| {
            a.replace("{c}", &c.display().to_string())
                .replace("{t}", &dir.display().to_string())
        })
        .collect();
    Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(&argv)
        .current_dir(dir)
        .output()
        .expect("the binary runs")
}

/// Files in `dir` whose names mark them as temporary files of `write_atomic`.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .expect("readable folder")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".ipa-sysid-") || n.ends_with(".tmp"))
        .collect()
}

const SENTINEL: &str = "the user's precious file\n";

/// Copies `good.csv` and `good_model.json` into `dir` (as inputs the test may try to overwrite) and
/// writes the sentinel to each of `outputs`.
fn setup(dir: &Path, outputs: &[&str]) {
    std::fs::copy(corpus().join("good.csv"), dir.join("data.csv")).unwrap();
    std::fs::copy(corpus().join("good_model.json"), dir.join("model.json")).unwrap();
    for o in outputs {
        std::fs::write(dir.join(o), SENTINEL).unwrap();
    }
}

// A run that fails — on bad input (2) or numerically (1), before or after the computation — leaves
// every existing output file byte for byte as it was, and leaves no temporary file.
#[test]
fn failed_runs_leave_existing_outputs_untouched() {
    let cases: &[(&str, i32, &[&str])] = &[
        // bad data, read after the outputs were checked
        (
            "identify --data {c}/csv/text_cell.csv --json {t}/fit.json --save-model {t}/m.json",
            2,
            &["fit.json", "m.json"],
        ),
        // numerical failure in RLS, after reading
        (
            "identify --data {c}/csv/overflow.csv --json {t}/fit.json --save-model {t}/m.json",
            1,
            &["fit.json", "m.json"],
        ),
        // the second output's folder does not exist: nothing is written, not even the first output
        (
            "identify --data {t}/data.csv --json {t}/fit.json --save-model {t}/missing/m.json",
            2,
            &["fit.json"],
        ),
        (
            "validate --model {c}/model/truncated.json --data {t}/data.csv --json {t}/v.json",
            2,
            &["v.json"],
        ),
        // the plant blows up mid-run: neither the trace nor the JSON is written
        (
            "control --plant model:{c}/model/unstable.json --setpoint 5 --out {t}/trace.csv --json {t}/c.json",
            1,
            &["trace.csv", "c.json"],
        ),
        (
            "simulate --plant model:{c}/model/unstable.json --input step:100 --samples 200 --out {t}/sim.csv",
            1,
            &["sim.csv"],
        ),
        (
            "order --data {t}/data.csv --na 5..2 --json {t}/order.json",
            2,
            &["order.json"],
        ),
        (
            "montecarlo --runs 1 --samples 0 --json {t}/mc.json",
            2,
            &["mc.json"],
        ),
    ];
    for (args, code, outputs) in cases {
        let dir = tempfile::tempdir().unwrap();
        setup(dir.path(), outputs);
        let out = run(args, dir.path());
        assert_eq!(
            out.status.code(),
            Some(*code),
            "{args}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        for o in *outputs {
            assert_eq!(
                std::fs::read_to_string(dir.path().join(o)).unwrap(),
                SENTINEL,
                "{args}: {o} was modified"
            );
        }
        assert!(
            leftovers(dir.path()).is_empty(),
            "{args}: {:?}",
            leftovers(dir.path())
        );
    }
}

// A second output that cannot be written (a full disk: /dev/full) after the first was made: neither is
// written, the first keeps its old content (audit s14 M-f: `--out` was already replaced).
#[cfg(target_os = "linux")]
#[test]
fn a_failing_second_output_leaves_the_first_as_it_was() {
    let cases: &[(&str, &str)] = &[
        (
            "control --plant ipa --setpoint 50 --duration 1 --out {t}/trace.csv --json /dev/full",
            "trace.csv",
        ),
        (
            "validate --model {t}/model.json --data {t}/data.csv --out {t}/v.csv --json /dev/full",
            "v.csv",
        ),
        (
            "calibrate --data {t}/data.csv --out {t}/k.toml --json /dev/full --max-iterations 2 --no-baseline",
            "k.toml",
        ),
        (
            "tune --model {t}/model.json --out {t}/t.json --json /dev/full --max-evaluations 8 --variants 1 --physics-variants 0",
            "t.json",
        ),
    ];
    for (args, first) in cases {
        let dir = tempfile::tempdir().unwrap();
        setup(dir.path(), &[first]);
        // The sentinel is not of the output's kind: --force, or the run refuses it (audit s22 M-B9).
        let out = run(&format!("{args} --force"), dir.path());
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args}: {err}");
        assert!(err.contains("/dev/full"), "{args}: {err}");
        assert_eq!(
            std::fs::read_to_string(dir.path().join(first)).unwrap(),
            SENTINEL,
            "{args}: {first} was replaced"
        );
        assert!(leftovers(dir.path()).is_empty(), "{args}");
    }
}

// `--strict` on a result with warnings exits 1 and writes no output file: an earlier model (the one a
// script `identify --strict --save-model m.json || exit 1` relies on) stays (audit s14 H-a); without
// --strict the same run writes both.
#[test]
fn strict_with_warnings_replaces_no_output() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path(), &["m.json", "fit.json"]);
    // The record's output replaced by a deterministic scramble: the deadzone is not determined
    // (warnings), whatever the estimator does.
    let text = std::fs::read_to_string(dir.path().join("data.csv")).unwrap();
    let mut lines = text.lines();
    let mut noisy = format!("{}\n", lines.next().unwrap());
    for (k, line) in lines.enumerate() {
        let f: Vec<&str> = line.split(',').collect();
        let y = 3.0 * ((k * k) as f64 * 0.37).sin();
        noisy.push_str(&format!("{},{},{y:.4}\n", f[0], f[1]));
    }
    std::fs::write(dir.path().join("noise.csv"), noisy).unwrap();
    let args = "identify --data {t}/noise.csv --strict --save-model {t}/m.json --json {t}/fit.json";
    let out = run(args, dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("--strict"), "{err}");
    assert!(
        err.contains("not written (any earlier file there is unchanged): --json")
            && err.contains("--save-model"),
        "{err}"
    );
    for o in ["m.json", "fit.json"] {
        assert_eq!(
            std::fs::read_to_string(dir.path().join(o)).unwrap(),
            SENTINEL,
            "{o}"
        );
    }
    // The sentinel is not of the outputs' kind: replacing it needs --force (audit s22 M-B9).
    let out = run(&args.replace(" --strict", " --force"), dir.path());
    assert!(out.status.success());
    for o in ["m.json", "fit.json"] {
        assert_ne!(
            std::fs::read_to_string(dir.path().join(o)).unwrap(),
            SENTINEL,
            "{o}"
        );
    }
    assert!(leftovers(dir.path()).is_empty());
    // Batch mode (two files) keeps the rule: an earlier --json stays (audit s16 M10); standard output
    // still gets every line.
    std::fs::write(dir.path().join("fit.jsonl"), SENTINEL).unwrap();
    let batch = "identify --data {t}/noise.csv {t}/data.csv --strict --json {t}/fit.jsonl";
    let out = run(batch, dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("not written (any earlier file there is unchanged): --json"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(dir.path().join("fit.jsonl")).unwrap(),
        SENTINEL
    );
    let out = run(&batch.replace("{t}/fit.jsonl", "-"), dir.path());
    assert_eq!(out.status.code(), Some(1));
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 2);
    let out = run(&batch.replace(" --strict", " --force"), dir.path());
    assert!(out.status.success());
    assert_eq!(
        std::fs::read_to_string(dir.path().join("fit.jsonl"))
            .unwrap()
            .lines()
            .count(),
        2
    );
    assert!(leftovers(dir.path()).is_empty());
}

// Every output flag refuses a path that is one of the run's inputs (also through another spelling of
// the same path), and the input is left as it was.
#[test]
fn an_output_equal_to_an_input_is_refused() {
    let cases: &[(&str, &str, &str)] = &[
        ("identify --data {t}/data.csv --json {t}/data.csv", "--json", "data.csv"),
        ("identify --data {t}/data.csv --json {t}/./data.csv", "--json", "data.csv"),
        (
            "identify --data {c}/good.csv --validation {t}/data.csv --save-model {t}/data.csv",
            "--save-model",
            "data.csv",
        ),
        ("validate --model {t}/model.json --data {t}/data.csv --json {t}/model.json", "--json", "model.json"),
        ("validate --model {t}/model.json --data {t}/data.csv --json {t}/data.csv", "--json", "data.csv"),
        ("order --data {t}/data.csv --na 1 --nb 1 --nk 1 --json {t}/data.csv", "--json", "data.csv"),
        ("montecarlo --plant model:{t}/model.json --runs 1 --json {t}/model.json", "--json", "model.json"),
        (
            "control --plant model:{t}/model.json --setpoint 5 --duration 0.1 --out {t}/model.json",
            "--out",
            "model.json",
        ),
        (
            "control --plant model:{t}/model.json --setpoint 5 --duration 0.1 --json {t}/model.json",
            "--json",
            "model.json",
        ),
        (
            "control --plant paper --setpoint 5 --duration 0.1 --compensate-deadzone {t}/model.json --json {t}/model.json",
            "--json",
            "model.json",
        ),
        (
            "bench plant --plant model:{t}/model.json --samples 10 --repetitions 1 --json {t}/model.json",
            "--json",
            "model.json",
        ),
        (
            "simulate --plant paper --input file:{t}/data.csv --out {t}/./data.csv",
            "--out",
            "data.csv",
        ),
        (
            "simulate --plant model:{t}/model.json --samples 10 --out {t}/model.json",
            "--out",
            "model.json",
        ),
        // reproduce writes a whole folder: an input inside it is refused
        ("reproduce --plant model:{t}/model.json --out {t}", "--out", "model.json"),
    ];
    for (args, flag, input) in cases {
        let dir = tempfile::tempdir().unwrap();
        setup(dir.path(), &[]);
        let before = std::fs::read(dir.path().join(input)).unwrap();
        let out = run(args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args}: {stderr}");
        assert!(stderr.contains(flag), "{args}: {stderr}");
        assert!(!stderr.contains("panicked"), "{args}: {stderr}");
        assert_eq!(
            std::fs::read(dir.path().join(input)).unwrap(),
            before,
            "{args}"
        );
        assert!(leftovers(dir.path()).is_empty(), "{args}");
    }
}

// Two outputs of one run on the same file would silently keep only the last: refused.
#[test]
fn two_outputs_on_one_file_are_refused() {
    for args in [
        "identify --data {t}/data.csv --method ls --json {t}/a.json --save-model {t}/./a.json",
        "control --plant paper --setpoint 5 --duration 0.1 --out {t}/a.json --json {t}/a.json",
        // Two spellings of one file (audit s16 H2): relative against ./, absolute, through sub/..
        "control --plant paper --setpoint 5 --duration 0.1 --out a.json --json ./a.json",
        "control --plant paper --setpoint 5 --duration 0.1 --out sub/../a.json --json {t}/a.json",
        "tune --model {t}/model.json --out a.json --json ./a.json",
        "tune --model {t}/model.json --out {t}/a.json --json a.json",
    ] {
        let dir = tempfile::tempdir().unwrap();
        setup(dir.path(), &[]);
        std::fs::create_dir(dir.path().join("sub")).unwrap();
        let out = run(args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args}: {stderr}");
        assert!(stderr.contains("different from"), "{args}: {stderr}");
        assert!(!dir.path().join("a.json").exists(), "{args}");
    }
}

// An output path that is a folder, or in a folder that does not exist, is refused before any work.
#[test]
fn unwritable_output_paths_are_refused_before_work() {
    for (args, needle) in [
        ("identify --data {t}/data.csv --json {t}", "a file name"),
        (
            "identify --data {t}/data.csv --save-model {t}/no/such/dir/m.json",
            "does not exist",
        ),
        (
            "validate --model {t}/model.json --data {t}/data.csv --json {t}/none/v.json",
            "does not exist",
        ),
        (
            "control --plant paper --setpoint 5 --out {t}/none/trace.csv",
            "does not exist",
        ),
        ("order --data {t}/data.csv --json {t}", "a file name"),
        (
            "simulate --plant paper --out {t}/none/sim.csv",
            "does not exist",
        ),
    ] {
        let dir = tempfile::tempdir().unwrap();
        setup(dir.path(), &[]);
        let out = run(args, dir.path());
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args}: {stderr}");
        assert!(stderr.contains(needle), "{args}: {stderr}");
        // refused before the computation: nothing was printed as a result
        assert!(out.stdout.is_empty(), "{args}");
    }
}

// A successful run replaces an existing output entirely (no mix of old and new content), keeps that
// file's permissions, gives new files the permissions of any newly created file, and leaves no
// temporary file.
#[test]
fn successful_runs_replace_outputs_whole_with_ordinary_permissions() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path(), &["fit.json"]);
    // The sentinel is not a JSON report: --force (audit s22 M-B9).
    let out = run(
        "identify --data {t}/data.csv --method ls --json {t}/fit.json --save-model {t}/m.json --force",
        dir.path(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("fit.json")).unwrap();
    assert!(!text.contains(SENTINEL.trim()));
    let v: serde_json::Value = serde_json::from_str(&text).expect("whole, valid JSON");
    assert!(v["model"].is_object());
    assert!(
        leftovers(dir.path()).is_empty(),
        "{:?}",
        leftovers(dir.path())
    );
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        // A file created the ordinary way gets 0o666 less the umask; the new model file must match.
        let probe = dir.path().join("probe");
        std::fs::write(&probe, "x").unwrap();
        assert_eq!(mode(&dir.path().join("m.json")), mode(&probe));
        // An existing output keeps its own permissions.
        let fit = dir.path().join("fit.json");
        std::fs::set_permissions(&fit, std::fs::Permissions::from_mode(0o640)).unwrap();
        let out = run(
            "identify --data {t}/data.csv --method ls --json {t}/fit.json",
            dir.path(),
        );
        assert!(out.status.success());
        assert_eq!(mode(&fit), 0o640);
    }
}

// CSV and JSON outputs never hold NaN or inf text: missing metrics are JSON null, and a run that would
// produce non-finite numbers fails instead (tested above).
#[test]
fn outputs_hold_no_nan_text() {
    let dir = tempfile::tempdir().unwrap();
    setup(dir.path(), &[]);
    for args in [
        "identify --data {t}/data.csv --json {t}/fit.json",
        "validate --model {t}/model.json --data {t}/data.csv --json {t}/v.json",
        "validate --model {c}/model/unstable.json --data {t}/data.csv --json {t}/unstable.json",
        "control --plant paper --setpoint 5 --duration 1 --out {t}/trace.csv --json {t}/c.json",
        "simulate --plant paper --samples 300 --out {t}/sim.csv",
    ] {
        let out = run(args, dir.path());
        assert!(
            out.status.success(),
            "{args}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    for f in [
        "fit.json",
        "v.json",
        "unstable.json",
        "trace.csv",
        "c.json",
        "sim.csv",
    ] {
        let text = std::fs::read_to_string(dir.path().join(f)).unwrap();
        let lower = text.to_lowercase();
        assert!(
            !lower.contains("nan") && !lower.contains("inf"),
            "{f}: {text}"
        );
    }
    // The unstable model's free-run simulation overflows: its fit is reported as null, not NaN.
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("unstable.json")).unwrap())
            .unwrap();
    assert!(v["metrics"]["validation"]["fit_sim_percent"].is_null());
    assert_eq!(v["stable"], serde_json::Value::Bool(false));
}
