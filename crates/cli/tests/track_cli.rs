//! `ipa-sysid track` end to end: the one-pass recursive identification reproduced sample by sample from
//! standard input, the JSON line format, the summary, malformed input, a file being appended
//! (`--follow`) and a serial port (`--serial`, on a pseudo-terminal pair); hostile flags and streams.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::Duration;

use proptest::prelude::*;

mod common;

const BIN: &str = env!("CARGO_BIN_EXE_ipa-sysid");

fn run(args: &[&str], stdin: &[u8]) -> Output {
    let mut child = Command::new(BIN)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut input = child.stdin.take().unwrap();
    // Written from another thread while the output is read (a child whose output fills its pipe before
    // it has read all its input would wait on this test, and this test on it). The tool may stop
    // reading early (an error): a broken pipe is then expected.
    let stdin = stdin.to_vec();
    let writer = std::thread::spawn(move || {
        let _ = input.write_all(&stdin);
    });
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap();
    out
}

fn simulate(dir: &Path, samples: usize, seed: u64) -> std::path::PathBuf {
    let out = dir.join(format!("rec{seed}.csv"));
    let o = run(
        &[
            "simulate",
            "--plant",
            "paper",
            "--input",
            "aprbs",
            "--samples",
            &samples.to_string(),
            "--noise-std",
            "0.01",
            "--seed",
            &seed.to_string(),
            "--out",
            out.to_str().unwrap(),
        ],
        b"",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

/// The model's numbers in a fixed order: b_l, b_r, m_l, m_r, a..., b...
fn numbers(model: &serde_json::Value) -> Vec<f64> {
    let dz = &model["deadzone"];
    let mut v: Vec<f64> = ["b_l", "b_r", "m_l", "m_r"]
        .iter()
        .map(|k| dz[k].as_f64().unwrap())
        .collect();
    for key in ["a", "b"] {
        v.extend(
            model[key]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap()),
        );
    }
    v
}

// identify takes its start deadzone from the whole record (largest negative and smallest positive
// command, and max |u| as the clamp); the test reads them from the CSV itself and gives them to track,
// which then runs the same recursion sample by sample.
#[test]
fn track_from_stdin_ends_at_the_model_of_the_one_pass_recursive_identification() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), 3000, 3);
    let text = std::fs::read(&data).unwrap();
    let u: Vec<f64> = String::from_utf8_lossy(&text)
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
        .collect();
    let b_l0 = u
        .iter()
        .copied()
        .filter(|&v| v < 0.0)
        .fold(f64::NEG_INFINITY, f64::max);
    let b_r0 = u
        .iter()
        .copied()
        .filter(|&v| v > 0.0)
        .fold(f64::INFINITY, f64::min);
    let limit = u.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    let summary = dir.path().join("summary.json");
    let o = run(
        &[
            "track",
            "--data",
            "-",
            "--windup",
            "none",
            "--every",
            "1000",
            "--b-l0",
            &b_l0.to_string(),
            "--b-r0",
            &b_r0.to_string(),
            "--breakpoint-limit",
            &limit.to_string(),
            "--json",
            summary.to_str().unwrap(),
        ],
        &text,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<serde_json::Value> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // Lines at k = 999, 1999, 2999 (every 1000 samples, k 0-based).
    let ks: Vec<u64> = lines.iter().map(|l| l["k"].as_u64().unwrap()).collect();
    assert_eq!(ks, [999, 1999, 2999]);
    let last = lines.last().unwrap();
    assert!((last["t"].as_f64().unwrap() - 29.99).abs() < 1e-9);
    for key in ["model", "poles", "stable", "change", "pe_rms", "warnings"] {
        assert!(!last[key].is_null(), "{key} in {last}");
    }
    let json = dir.path().join("identify.json");
    let o = run(
        &[
            "identify",
            "--data",
            data.to_str().unwrap(),
            "--method",
            "rls",
            "--passes",
            "1",
            "--windup",
            "none",
            "--json",
            json.to_str().unwrap(),
        ],
        b"",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let id: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(s["samples"], 3000);
    // The same estimate, the same verdict in the same words as identify's (session 24: track's JSON had
    // only the boolean).
    assert!(id["stability"].is_string(), "{}", id["stability"]);
    assert_eq!(last["stability"], id["stability"]);
    assert_eq!(s["stability"], id["stability"]);
    for model in [&last["model"], &s["model"]] {
        for (a, b) in numbers(model).iter().zip(numbers(&id["model"])) {
            assert!((a - b).abs() <= 1e-9 * b.abs(), "track {a} identify {b}");
        }
    }
}

// A stationary record of 50 000 samples of the paper's plant with output noise (the prediction errors
// are then coloured, a harder case than the white errors of the CUSUM's run-length table): no alarm.
#[test]
fn a_stationary_simulated_record_gives_no_change_point() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), 50_000, 7);
    let s = track_summary(&data, &[]);
    assert_eq!(s["samples"], 50_000);
    assert_eq!(s["change_points"], serde_json::json!([]));
}

/// `track --data FILE EXTRA...` with one JSON line at most and `--json`: the summary.
fn track_summary(data: &Path, extra: &[&str]) -> serde_json::Value {
    let summary = data.with_extension(format!("summary{}.json", extra.join("")));
    let mut args = vec![
        "track",
        "--data",
        data.to_str().unwrap(),
        "--every",
        "100000",
        "--json",
        summary.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let o = run(&args, b"");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap()
}

// The physics plant (the default of `simulate`) on its default staircase, unchanged for 50 000 samples.
// Its friction is outside the tracked model, so the errors come in bursts while the piston moves; with
// the fixed threshold h = 60 alone (`--detect-excursion-factor 0`) such records alarmed again after
// every calibration. The threshold calibrated on the record's own bursts gives no alarm.
#[test]
fn a_stationary_physics_plant_record_gives_no_change_point() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("ipa.csv");
    let o = run(
        &[
            "simulate",
            "--samples",
            "50000",
            "--noise-std",
            "0.01",
            "--seed",
            "2",
            "--out",
            data.to_str().unwrap(),
        ],
        b"",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let count = |factor: &str| {
        let s = track_summary(&data, &["--detect-excursion-factor", factor]);
        assert_eq!(s["samples"], 50_000);
        (
            s["change_points"].as_array().unwrap().len(),
            s["detector_threshold"].as_f64().unwrap(),
        )
    };
    let (fixed, h) = count("0");
    assert!(fixed > 0 && h == 60.0, "{fixed} alarms with h = {h}");
    let (calibrated, h) = count("4");
    assert_eq!(calibrated, 0, "threshold {h}");
    assert!(h > 60.0, "threshold {h}");
}

#[test]
fn a_malformed_line_is_an_error_naming_line_and_column() {
    let o = run(&["track", "--data", "-"], b"t,u,y\n0,1,2\n0.01,abc,3\n");
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("<stdin>:3:2:") && err.contains("'abc'"),
        "{err}"
    );
    let o = run(&["track", "--data", "-"], b"time,u,y\n0,1,2\n");
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--t-col"));
}

fn paper_lines(n: usize) -> String {
    // A square wave through the paper's deadzone; the content only has to be numbers here.
    (0..n)
        .map(|k| {
            format!(
                "{},{},{}\n",
                k as f64 * 0.01,
                if (k / 7) % 2 == 0 { 100 } else { -100 },
                k as f64 * 0.1
            )
        })
        .collect()
}

/// Starts `track` on `source` (flags naming the source) with a 1.5-s idle time-out, no detector, a line
/// every `every` samples and the summary to `summary`.
fn spawn_track(source: &[&str], every: &str, summary: &Path) -> std::process::Child {
    Command::new(BIN)
        .arg("track")
        .args(source)
        .args(["--idle-timeout", "1.5", "--no-detect", "--every", every])
        .args(["--json", summary.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// Waits for `child`; returns its summary's sample count and the number of JSON lines it printed.
fn finish(child: std::process::Child, summary: &Path) -> (u64, usize) {
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(summary).unwrap()).unwrap();
    let lines = String::from_utf8(o.stdout).unwrap().lines().count();
    (s["samples"].as_u64().unwrap(), lines)
}

// Lines appended after track has reached the end of the file are read; it stops after the idle
// time-out.
#[test]
fn follow_reads_lines_appended_later_and_stops_after_the_idle_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("live.csv");
    let mut f = std::fs::File::create(&path).unwrap();
    write!(f, "t,u,y\n{}", paper_lines(10)).unwrap();
    f.flush().unwrap();
    let summary = dir.path().join("s.json");
    let child = spawn_track(&["--follow", path.to_str().unwrap()], "5", &summary);
    std::thread::sleep(Duration::from_millis(500));
    let more: String = paper_lines(30)
        .lines()
        .skip(10)
        .map(|l| format!("{l}\n"))
        .collect();
    f.write_all(more.as_bytes()).unwrap();
    f.flush().unwrap();
    // 30 samples, lines at k = 4, 9, ..., 29.
    assert_eq!(finish(child, &summary), (30, 6));
}

// Audit s16 L12: `track --follow` without --idle-timeout is stopped by Ctrl-C (SIGINT): the first one
// ends the run (after the line being read, or at the next poll), with the end summary and --json of
// every sample read (the 40 written here: track has printed the line of the 40th, k = 39, before the
// signal is sent), exit 0 and a note on stderr that a signal stopped it.
#[cfg(unix)]
#[test]
fn follow_stopped_by_sigint_writes_its_summary() {
    use std::io::{BufRead, BufReader};
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("live.csv");
    std::fs::write(&path, format!("t,u,y\n{}", paper_lines(40))).unwrap();
    let summary = dir.path().join("s.json");
    let mut child = Command::new(BIN)
        .args(["track", "--follow", path.to_str().unwrap()])
        .args(["--no-detect", "--every", "1"])
        .args(["--json", summary.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // A watchdog: a run that never stops is killed after 60 s, so the test fails instead of hanging.
    let done = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let (pid, watched) = (child.id().to_string(), done.clone());
    std::thread::spawn(move || {
        std::thread::sleep(std::time::Duration::from_secs(60));
        if !watched.load(std::sync::atomic::Ordering::SeqCst) {
            let _ = Command::new("kill").args(["-KILL", &pid]).status();
        }
    });
    // Read the streamed lines until the last sample's (k = 39) has come (the first samples, before the
    // regressor is full, print no line).
    let mut out = BufReader::new(child.stdout.take().unwrap());
    let mut line = String::new();
    loop {
        line.clear();
        assert!(out.read_line(&mut line).unwrap() > 0, "track ended early");
        let k: serde_json::Value = serde_json::from_str(&line).unwrap();
        if k["k"] == 39 {
            break;
        }
    }
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let o = child.wait_with_output().unwrap();
    done.store(true, std::sync::atomic::Ordering::SeqCst);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(err.contains("stopped by a signal"), "{err}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(s["samples"], 40);
}

// Log rotation by copy and truncate: the followed file is emptied, then the logger writes on (here with
// its header again). track notes it on stderr and reads the file again from its beginning (after the
// header): every sample is read once, and the run ends normally (audit s10 F7.7: it ended in "the line
// is longer than 1048576 bytes").
#[test]
fn follow_reads_a_file_truncated_under_it_again_from_its_beginning() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("live.csv");
    let all = paper_lines(30);
    let first: String = all.lines().take(20).map(|l| format!("{l}\n")).collect();
    let rest: String = all.lines().skip(20).map(|l| format!("{l}\n")).collect();
    std::fs::write(&path, format!("t,u,y\n{first}")).unwrap();
    let summary = dir.path().join("s.json");
    let child = spawn_track(&["--follow", path.to_str().unwrap()], "5", &summary);
    std::thread::sleep(Duration::from_millis(500));
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.set_len(0).unwrap();
    drop(f);
    std::thread::sleep(Duration::from_millis(200));
    std::fs::write(&path, format!("t,u,y\n{rest}")).unwrap();
    let o = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("live.csv") && err.contains("truncated to 0 bytes"),
        "{err}"
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&summary).unwrap()).unwrap();
    assert_eq!(s["samples"].as_u64(), Some(30), "{err}");
}

// A pseudo-terminal pair stands in for the serial cable: the test writes CSV lines to the master side,
// track reads the slave side as a serial port.
#[cfg(unix)]
#[test]
fn serial_reads_lines_from_a_pseudo_terminal() {
    use serialport::SerialPort;
    let (mut master, slave) = serialport::TTYPort::pair().unwrap();
    let name = slave.name().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let summary = dir.path().join("s.json");
    let child = spawn_track(&["--serial", &name, "--baud", "115200"], "10", &summary);
    std::thread::sleep(Duration::from_millis(400));
    master
        .write_all(format!("t,u,y\n{}", paper_lines(20)).as_bytes())
        .unwrap();
    master.flush().unwrap();
    assert_eq!(finish(child, &summary), (20, 2));
    drop(slave);
}

// Issue 20, drift 6: `track` reads with `identify`'s CSV rules. A spreadsheet export of a record —
// semicolon delimiter, decimal commas, quoted names, a byte-order mark, CRLF line ends — is the same
// record to `identify` and to `track`: both give the numbers they give on the comma-separated original.
#[test]
fn track_reads_a_semicolon_file_that_identify_reads_with_the_same_numbers() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), 2000, 11);
    let text = std::fs::read_to_string(&data).unwrap();
    let mut semi = String::from("\u{feff}");
    for (i, line) in text.lines().enumerate() {
        let cells: Vec<String> = line
            .split(',')
            .map(|c| {
                if i == 0 {
                    format!("\"{c}\"")
                } else {
                    c.replace('.', ",")
                }
            })
            .collect();
        semi += &cells.join(";");
        semi += "\r\n";
    }
    let semi_path = dir.path().join("semicolon.csv");
    std::fs::write(&semi_path, semi).unwrap();
    let identify_model = |path: &Path| {
        let json = path.with_extension("identify.json");
        let o = run(
            &[
                "identify",
                "--data",
                path.to_str().unwrap(),
                "--method",
                "rls",
                "--passes",
                "1",
                "--json",
                json.to_str().unwrap(),
            ],
            b"",
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        numbers(&v["model"])
    };
    assert_eq!(identify_model(&semi_path), identify_model(&data));
    let (a, b) = (track_summary(&semi_path, &[]), track_summary(&data, &[]));
    assert_eq!(a["samples"], 2000);
    assert_eq!(numbers(&a["model"]), numbers(&b["model"]));
    // Standard input is read by the same rules.
    let o = run(
        &["track", "--data", "-", "--every", "100000"],
        &std::fs::read(&semi_path).unwrap(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // 2000 samples are fewer than the detector needs to arm (a warning says so, then the count).
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.lines().any(|l| l.starts_with("2000 samples")), "{err}");
}

// Hostile flags and streams (issue 21, items 2 and 4): every size a flag drives is bounded before
// anything is allocated — the orders by the bound `identify` applies, the windows by a record's limit —
// and a line is bounded as it is read. Each is refused with exit code 2 and a message naming the flag or
// the line; nothing panics (101) or aborts (134).

const U64_MAX: &str = "18446744073709551615";

/// `track --data - FLAGS...` on `stdin`.
fn track(flags: &[&str], stdin: &[u8]) -> Output {
    let mut args = vec!["track", "--data", "-"];
    args.extend_from_slice(flags);
    run(&args, stdin)
}

/// A short record of t,u,y lines (a square wave through a deadzone and an integrator).
fn record(n: usize) -> Vec<u8> {
    let mut s = String::from("t,u,y\n");
    let mut y = 0.0;
    for k in 0..n {
        let u = if (k / 20) % 2 == 0 { 80.0 } else { -60.0 };
        y += 1e-3 * u;
        s += &format!("{},{u},{y}\n", k as f64 * 0.01);
    }
    s.into_bytes()
}

fn refused(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(needle), "expected '{needle}' in: {err}");
}

// Time that stands still is refused at its line in the readers' words (one rule:
// sysid_core::data::increasing_time), with track's way out; at the second sample as later.
#[test]
fn time_that_does_not_increase_is_refused_in_the_readers_words() {
    for bad_line in [3usize, 30] {
        let text = String::from_utf8(record(50)).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        // Line L (1-based) holds sample L - 2 at t = (L - 2) 0.01; give it the time of line L - 1.
        let previous = (bad_line - 3) as f64 * 0.01;
        let cells: Vec<String> = lines[bad_line - 1].split(',').map(String::from).collect();
        lines[bad_line - 1] = format!("{previous},{},{}", cells[1], cells[2]);
        let input = lines.join("\n") + "\n";
        let o = track(&[], input.as_bytes());
        refused(
            &o,
            &format!(
                "<stdin>:{bad_line}:1: time {previous} s does not increase after {previous} s on the \
                 previous row; expected strictly increasing time (a restarted logger"
            ),
        );
    }
}

// identify's bound on the orders (at most 100) holds for track: before, --nk/--nb u64::MAX panicked
// (index out of bounds), --na 100000 aborted on an 80 GB allocation and --na u64::MAX exited 0.
#[test]
fn orders_above_identify_bound_are_refused_naming_the_flag() {
    let data = record(200);
    for (flag, value) in [
        ("--na", "100000"),
        ("--na", U64_MAX),
        ("--nb", U64_MAX),
        ("--nk", U64_MAX),
        ("--na", "101"),
    ] {
        let o = track(&[flag, value], &data);
        refused(&o, &format!("{flag} = {value}: an order of at most 100"));
    }
    // The same words as identify's.
    let o = track(&["--structure", "arx", "--na", "0", "--nb", "0"], &data);
    refused(&o, "no parameter to estimate");
    // The bound itself is accepted.
    let o = track(&["--structure", "arx", "--na", "100", "--nb", "2"], &data);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

// The windows are bounded by a record's limit (50 000 000 samples) and reserved as samples come:
// before, u64::MAX panicked on the capacity.
#[test]
fn windows_beyond_a_record_are_refused_naming_the_flag() {
    let data = record(200);
    for flag in ["--pe-window", "--detect-calibration"] {
        let o = track(&[flag, U64_MAX], &data);
        refused(&o, &format!("{flag} = {U64_MAX}"));
        let o = track(&[flag, "50000000"], &data);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
}

// A stream that never ends a line (binary data, /dev/zero, a wrong baud rate) is refused once a line
// passes 1 MiB, naming the line; before, the line buffer grew until memory ran out.
#[test]
fn a_stream_without_line_ends_is_refused_at_the_line_bound() {
    let mut data = b"t,u,y\n0,1,2\n".to_vec();
    data.extend(std::iter::repeat_n(b'7', 3 << 20));
    let o = track(&[], &data);
    refused(&o, "<stdin>:3:1: the line is longer than 1048576 bytes");
    if std::path::Path::new("/dev/zero").exists() {
        let o = Command::new(BIN)
            .args(["track", "--data", "-"])
            .stdin(std::fs::File::open("/dev/zero").unwrap())
            .output()
            .unwrap();
        refused(&o, "<stdin>:1:1: the line is longer than");
    } else {
        eprintln!("SKIPPED: no /dev/zero on this system");
    }
}

/// A size flag's value: small (the usual range, and around the bounds) or any u64.
fn size() -> impl Strategy<Value = u64> {
    prop_oneof![0u64..300, 99u64..103, any::<u64>()]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 40, ..ProptestConfig::default() })]
    // Any values of track's size flags: a result (exit 0) or a refusal (exit 2) with a message, never a
    // panic (101), an abort (134) or a signal.
    #[test]
    fn any_size_flags_give_a_result_or_a_message(
        na in size(), nb in size(), nk in size(), pe in size(), cal in size(), warm in size(),
        every in size(), arx in any::<bool>(),
    ) {
        let values = [na, nb, nk, pe, cal, warm, every].map(|v| v.to_string());
        let mut flags = vec![
            "--na", &values[0], "--nb", &values[1], "--nk", &values[2], "--pe-window", &values[3],
            "--detect-calibration", &values[4], "--detect-warmup", &values[5], "--every", &values[6],
        ];
        if arx {
            flags.extend(["--structure", "arx"]);
        }
        let o = track(&flags, &record(300));
        let err = String::from_utf8_lossy(&o.stderr);
        prop_assert!(matches!(o.status.code(), Some(0 | 2)), "{:?} {flags:?}: {err}", o.status);
        if o.status.code() == Some(2) {
            prop_assert!(err.contains("error: "), "{flags:?}: {err}");
        }
    }
}

// Audit s11 A1: the detector arms after k0 + warm-up + calibration samples: k0 = max(na, nk + nb − 1) =
// max(3, 1) = 3 for the default structure, so 3 + 500 + 2000 = 2503. A record one sample shorter ends
// with a summary warning that no change could be detected; at 2503 samples the detector is armed and
// nothing is said.
#[test]
fn a_record_too_short_to_arm_the_change_detector_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), 2503, 3);
    let text = std::fs::read_to_string(&data).unwrap();
    let short = dir.path().join("short.csv");
    let lines: Vec<&str> = text.lines().collect();
    std::fs::write(&short, lines[..lines.len() - 1].join("\n") + "\n").unwrap();
    let s = track_summary(&short, &[]);
    assert_eq!(s["samples"], 2502);
    let w = s["warnings"].to_string();
    assert!(
        w.contains("the change detector never armed")
            && w.contains("= 2503 samples, the record has 2502"),
        "{w}"
    );
    let s = track_summary(&data, &[]);
    assert_eq!(s["samples"], 2503);
    assert!(!s["warnings"].to_string().contains("never armed"), "{s}");
}

/// y(k) = 1.5 y(k−1) − 0.56 y(k−2) + f(u(k−1)) + e(k): a deadzone (slopes 0.01) whose breakpoints widen
/// from −30/25 to −60/55 at k = 6000, u a pseudo-random level held 20 samples in ±150, e uniform in
/// ±0.05 (a plain loop and a linear congruential generator).
fn deadzone_change_record(path: &Path) {
    let n = 12_000;
    let mut rng = common::lcg(12345);
    let mut rand = || rng.unit();
    let mut u = vec![0.0; n];
    let mut level = 0.0;
    for (k, v) in u.iter_mut().enumerate() {
        if k % 20 == 0 {
            level = 300.0 * rand() - 150.0;
        }
        *v = level;
    }
    let f = |v: f64, k: usize| {
        let (bl, br) = if k < 6000 {
            (-30.0, 25.0)
        } else {
            (-60.0, 55.0)
        };
        if v >= br {
            0.01 * (v - br)
        } else if v <= bl {
            0.01 * (v - bl)
        } else {
            0.0
        }
    };
    let mut x = vec![0.0; n];
    let mut y = vec![0.0; n];
    for k in 2..n {
        x[k] = 1.5 * x[k - 1] - 0.56 * x[k - 2] + f(u[k - 1], k);
    }
    for k in 0..n {
        y[k] = x[k] + 0.1 * rand() - 0.05;
    }
    let mut s = String::from("t,u,y\n");
    for k in 0..n {
        s += &format!("{},{},{}\n", k as f64 * 0.01, u[k], y[k]);
    }
    std::fs::write(path, s).unwrap();
}

// Audit s11 A2: after a detected change without --restart-on-change the final model is estimated from
// both plants; the summary says so. With --restart-on-change it is not said.
#[test]
fn a_change_without_restart_says_the_final_model_blends_both_plants() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("chg.csv");
    deadzone_change_record(&data);
    let orders = ["--na", "2", "--nb", "1", "--nk", "1"];
    let s = track_summary(&data, &orders);
    let changes = s["change_points"].as_array().unwrap();
    assert!(!changes.is_empty(), "{s}");
    let first = changes[0]["k"].as_u64().unwrap();
    assert!((6000..6500).contains(&first), "{first}");
    let w = s["warnings"].to_string();
    assert!(
        w.contains("without --restart-on-change") && w.contains("a blend of both plants"),
        "{w}"
    );
    let s = track_summary(&data, &[&orders[..], &["--restart-on-change"]].concat());
    assert!(!s["warnings"].to_string().contains("blend"), "{s}");
}

// Audit s35b L-5: a change point carries the threshold it was judged against. With the excursion
// factor 0 the threshold is the H given, before and after every re-arming.
#[test]
fn a_change_point_carries_the_threshold_it_was_judged_against() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("chg.csv");
    deadzone_change_record(&data);
    let args = [
        "--na",
        "2",
        "--nb",
        "1",
        "--nk",
        "1",
        "--detect-excursion-factor",
        "0",
        "--detect-threshold",
        "77",
    ];
    let s = track_summary(&data, &args);
    let changes = s["change_points"].as_array().unwrap();
    assert!(!changes.is_empty(), "{s}");
    for c in changes {
        assert_eq!(c["threshold"], 77.0, "{s}");
    }
}

// Audit s11 A4: `track --json -` keeps standard output a JSON-lines stream: every line parses on its own,
// one per `--every` samples, and the last is the summary (it has `samples`, the lines have `k`).
#[test]
fn the_summary_on_standard_output_is_one_more_json_line() {
    let dir = tempfile::tempdir().unwrap();
    let data = simulate(dir.path(), 1000, 4);
    let o = run(
        &[
            "track",
            "--data",
            data.to_str().unwrap(),
            "--every",
            "250",
            "--json",
            "-",
        ],
        b"",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let lines: Vec<serde_json::Value> = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // A line after every 250th sample: the 250th, 500th, 750th and 1000th (k = 249, 499, 749, 999, k
    // 0-based), then the summary.
    let ks: Vec<u64> = lines[..lines.len() - 1]
        .iter()
        .map(|l| l["k"].as_u64().unwrap())
        .collect();
    assert_eq!(ks, [249, 499, 749, 999]);
    let last = lines.last().unwrap();
    assert_eq!(last["samples"], 1000);
    assert!(last.get("k").is_none());
}

// Audit s12 F7: a two-level input (the dryer's 3.41 / 6.41 V) cannot determine a deadzone, which
// `identify` refuses; `track` reads live data and cannot refuse, so its summary says it, and that the
// left branch, never reached by a positive input, still holds the start's values. A record of the
// paper's plant (a staircase of many levels, both signs) gets neither warning.
#[test]
fn an_input_that_cannot_determine_the_deadzone_is_said_at_the_end() {
    let dir = tempfile::tempdir().unwrap();
    let mut s = String::from("t,u,y\n");
    let mut y = 0.0;
    for k in 0..600 {
        let u = if (k / 25) % 2 == 0 { 3.41 } else { 6.41 };
        y = 0.9 * y + 0.1 * u;
        s += &format!("{},{u},{y}\n", k as f64 * 0.08);
    }
    let two = dir.path().join("two.csv");
    std::fs::write(&two, s).unwrap();
    let w = track_summary(&two, &[])["warnings"].to_string();
    assert!(
        w.contains("the input took only 2 distinct level(s) (3.41, 6.41)")
            && w.contains("needs at least 3"),
        "{w}"
    );
    assert!(
        w.contains("the input was never negative: the left branch (b_l, m_l) is not estimated"),
        "{w}"
    );
    // Its key terms start at 0 and a regressor that is always 0 never moves them (P φ has no entry
    // there): the estimate reports 0s, said as such, and they are no verdict of implausibility (audit
    // s14 L-h: "holds the start's values (breakpoint -1)" beside b_l = 0, then "implausible: m_l = 0").
    assert!(
        w.contains("the estimate reports b_l = 0, m_l = 0, no value of the plant's"),
        "{w}"
    );
    assert!(!w.contains("m_l = 0: a slope"), "{w}");
    let data = simulate(dir.path(), 3000, 3);
    let w = track_summary(&data, &[])["warnings"].to_string();
    assert!(
        !w.contains("distinct level") && !w.contains("the input was never"),
        "{w}"
    );
}

/// The record of [`record`] with its time column written in milliseconds (t = 10 k).
fn record_ms(n: usize) -> Vec<u8> {
    let text = String::from_utf8(record(n)).unwrap();
    let mut lines = text.lines();
    let mut s = format!("{}\n", lines.next().unwrap());
    for (k, line) in lines.enumerate() {
        let rest = line.split_once(',').unwrap().1;
        s += &format!("{},{rest}\n", 10 * k);
    }
    s.into_bytes()
}

// Audit s16 L11: a time column in milliseconds read as seconds gives Ts = 10 s; track says so with
// identify's hint, and `--time-unit ms` (identify's flag) reads it as 10 ms = 0.01 s, the Ts of the
// same record written in seconds, in every model line and the summary.
#[test]
fn track_takes_time_unit_and_gives_identify_s_millisecond_hint() {
    let o = track(&["--every", "100", "--json", "-"], &record_ms(400));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("if it holds milliseconds"), "{err}");
    assert!(err.contains("pass --time-unit ms"), "{err}");

    let o = track(
        &["--every", "100", "--json", "-", "--time-unit", "ms"],
        &record_ms(400),
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(!err.contains("milliseconds"), "{err}");
    let text = String::from_utf8_lossy(&o.stdout);
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(lines.len() >= 4, "{text}");
    for l in &lines {
        let ts = l["model"]["ts"].as_f64().unwrap();
        assert!((ts - 10.0 * 1e-3).abs() < 1e-12, "{l}");
    }
    // The summary's last time: 10 (n - 1) ms in seconds.
    let t_end = lines.last().unwrap()["t_end"].as_f64().unwrap();
    assert!((t_end - 3.99).abs() < 1e-9, "{t_end}");
}

// Audit s16 L11: a --ts that contradicts the time column is said once, in identify's words, not as a
// "time jump" at every sample whose step differs from --ts; a real jump in the column is still said.
#[test]
fn a_ts_contradicting_the_time_column_is_said_once_as_identify_says_it() {
    let o = track(&["--every", "100", "--ts", "0.02"], &record(400));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(
        err.matches("--ts 0.02 s contradicts the time column t (its typical step is 0.01 s)")
            .count(),
        1,
        "{err}"
    );
    assert!(!err.contains("time jump"), "{err}");

    // The same record with 5 samples missing after row 200: one jump, measured against the column's
    // own 0.01 s step.
    let text = String::from_utf8(record(400)).unwrap();
    let kept: String = text
        .lines()
        .enumerate()
        .filter(|(i, _)| !(202..207).contains(i))
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    let o = track(&["--every", "100", "--ts", "0.02"], kept.as_bytes());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(err.matches("time jumps from").count(), 1, "{err}");
    assert_eq!(
        err.matches("contradicts the time column").count(),
        1,
        "{err}"
    );
}

// An input that stays within the start breakpoints ±1 (a ball-and-beam record, |u| < 0.031) never
// switches the deadzone on: x(k) = 0 at every sample and the tracked model never used the input. The
// summary says so naming --b-l0/--b-r0 and the start identify would take from the samples (the largest
// u < 0, the smallest u > 0, max |u|: computed here from the record); with that start the input enters
// (audit s16 L8: the warning called the estimate "implausible" instead).
#[test]
fn an_input_inside_the_start_breakpoints_is_said_with_the_start_to_use() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("small.csv");
    let levels = [0.02, -0.011, 0.031, -0.025, 0.007, -0.018, 0.013, -0.029];
    let n = 4000;
    let u: Vec<f64> = (0..n).map(|k| levels[(k / 37) % levels.len()]).collect();
    // A deadzone with breakpoints ±0.005 and slope 1 before a first-order lag.
    let dz = |v: f64| {
        if v > 0.005 {
            v - 0.005
        } else if v < -0.005 {
            v + 0.005
        } else {
            0.0
        }
    };
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.9 * y[k - 1] + 2.0 * dz(u[k - 1]);
    }
    let mut text = String::from("t,u,y\n");
    for k in 0..n {
        text.push_str(&format!("{},{},{}\n", k as f64 * 0.1, u[k], y[k]));
    }
    std::fs::write(&data, text).unwrap();
    let s = track_summary(&data, &[]);
    let warnings: Vec<String> = s["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap().to_string())
        .collect();
    let max_neg = u
        .iter()
        .copied()
        .filter(|&v| v < 0.0)
        .fold(f64::MIN, f64::max);
    let min_pos = u
        .iter()
        .copied()
        .filter(|&v| v > 0.0)
        .fold(f64::MAX, f64::min);
    let limit = u.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let expected = format!(
        "no input sample passed the start breakpoints --b-l0 -1 / --b-r0 1 (the input stayed within \
         [{}, {}])",
        u.iter().copied().fold(f64::MAX, f64::min),
        u.iter().copied().fold(f64::MIN, f64::max)
    );
    let advice = format!("--b-l0 {max_neg} --b-r0 {min_pos} --breakpoint-limit {limit}");
    assert!(
        warnings
            .iter()
            .any(|w| w.contains(&expected) && w.contains(&advice)),
        "{warnings:#?}"
    );
    assert!(
        !warnings.iter().any(|w| w.contains("implausible")),
        "{warnings:#?}"
    );
    // With that start the input is used: both slopes are estimated away from 0.
    let (l, r, lim) = (max_neg.to_string(), min_pos.to_string(), limit.to_string());
    let s = track_summary(
        &data,
        &["--b-l0", &l, "--b-r0", &r, "--breakpoint-limit", &lim],
    );
    let w = s["warnings"].to_string();
    assert!(!w.contains("no input sample passed"), "{w}");
    let d = &s["model"]["deadzone"];
    assert!(
        d["m_l"].as_f64().unwrap() > 0.5 && d["m_r"].as_f64().unwrap() > 0.5,
        "{d}"
    );
}

// Audit s30 M-3: a record whose lines end in CR only (an old Mac export) is read by track as by every
// other reader: the same JSON lines as the same record with LF line ends (it was "a header but no data
// rows").
#[test]
fn a_record_with_cr_line_ends_is_tracked_as_with_lf() {
    let dir = tempfile::tempdir().unwrap();
    let lf = std::fs::read(simulate(dir.path(), 300, 4)).unwrap();
    let cr: Vec<u8> = lf
        .iter()
        .map(|&b| if b == b'\n' { b'\r' } else { b })
        .collect();
    let a = run(&["track", "--data", "-"], &lf);
    let b = run(&["track", "--data", "-"], &cr);
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    assert!(b.status.success(), "{}", String::from_utf8_lossy(&b.stderr));
    assert_eq!(a.stdout, b.stdout);
    assert!(!a.stdout.is_empty());
}
