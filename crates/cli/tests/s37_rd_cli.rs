//! Session 37 (helper rd37): `track`'s two guards `identify` has (a file cut inside its last number,
//! a signal below 1e-140), copy and truncate under a logger that does not append (audit s36 L-5), a
//! long line after the first MiB found as it is read (audit s36 H-2), and `validate`'s "fit n/a" on a
//! tiny record said in words.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{bin, json, run, s, stderr, warnings};

/// A `t,u,y` record of `n` rows at 100 Hz of an ARX(2, 2) plant driven by a staircase, its output
/// times `scale`, written with every digit (`{:e}` keeps tiny values exact).
fn record(path: &std::path::Path, n: usize, scale: f64) {
    let (mut y1, mut y2, mut u1, mut u2) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let mut text = String::from("t,u,y\n");
    for k in 0..n {
        let u = [40.0, -25.0, 60.0, 0.0, -50.0][k / 37 % 5];
        let y = 1.5 * y1 - 0.7 * y2 + 0.5 * u1 + 0.25 * u2;
        text.push_str(&format!("{},{u},{:e}\n", k as f64 * 0.01, y * scale));
        (y2, y1, u2, u1) = (y1, y, u1, u);
    }
    std::fs::write(path, text).unwrap();
}

// Audit s36 L-5, the audit's ct.py scenario: the "logger" opens the file without O_APPEND, writes a
// header and 2000 rows, the file is truncated (logrotate copytruncate), and the logger writes 2000 more
// rows at its own offset, so the file starts with P NUL bytes (P: the bytes it had written). `track
// --follow` ends at its idle time-out as usual (exit 0, summary, --json) instead of exit 2 "header
// changed (columns moved?)", and says the file starts with P NUL bytes and why.
#[test]
fn copy_truncate_under_a_logger_that_does_not_append_keeps_the_run() {
    use std::io::{Seek, Write};
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("src.csv");
    record(&src, 4000, 1.0);
    let text = std::fs::read_to_string(&src).unwrap();
    let lines: Vec<&str> = text.split_inclusive('\n').collect();
    let first: String = lines[..2001].concat();
    let later: String = lines[2001..].concat();
    let ct = dir.path().join("ct.csv");
    let out = dir.path().join("ct.json");
    let mut logger = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .open(&ct)
        .unwrap();
    logger.write_all(first.as_bytes()).unwrap();
    logger.flush().unwrap();
    let child = bin()
        .args([
            "track",
            "--follow",
            s(&ct),
            "--structure",
            "arx",
            "--na",
            "2",
        ])
        .args(["--nb", "2", "--idle-timeout", "2", "--json", s(&out)])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    std::fs::OpenOptions::new()
        .write(true)
        .open(&ct)
        .unwrap()
        .set_len(0)
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(50));
    // The logger's own offset: where it had written up to (no O_APPEND, so not the new end).
    assert_eq!(logger.stream_position().unwrap(), first.len() as u64);
    logger.write_all(later.as_bytes()).unwrap();
    logger.flush().unwrap();
    let done = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&done.stderr);
    assert_eq!(done.status.code(), Some(0), "{err}");
    let doc = json(&out);
    let w = warnings(&doc);
    let hole = format!("starts with {} NUL bytes", first.len());
    assert!(w.iter().any(|w| w.contains(&hole)), "{w:?}");
    assert!(!err.contains("columns moved"), "{err}");
    // Every row of the second part is tracked after the hole (the first part too, unless the machine
    // was too slow to read it all in 1.5 s).
    let samples = doc["samples"].as_u64().unwrap();
    assert!((2000..=4000).contains(&samples), "{samples}");
}

// Audit s35 M-2 for `track --data FILE`: a record whose last row ends without a line end and whose last
// y was cut to 2 digits ("10" where the column's values have 15 or more) gets the note of the other
// readers, at that row's line (the header and 300 rows: line 302) and column 3, in the summary's
// warnings (text and --json); `identify` on the same file says the same words.
#[test]
fn track_notes_a_file_cut_inside_its_last_number() {
    let dir = tempfile::tempdir().unwrap();
    let full = dir.path().join("full.csv");
    record(&full, 301, 1.0);
    let text = std::fs::read_to_string(&full).unwrap();
    let last_start = text.trim_end().rfind('\n').unwrap() + 1;
    let last = &text[last_start..];
    let y_at = last.rfind(',').unwrap() + 1;
    let cut_text = format!("{}{}", &text[..last_start + y_at], "10");
    let cut = dir.path().join("cut.csv");
    std::fs::write(&cut, &cut_text).unwrap();
    let out = dir.path().join("t.json");
    let o = run(&[
        "track",
        "--data",
        s(&cut),
        "--structure",
        "arx",
        "--na",
        "2",
        "--nb",
        "2",
        "--json",
        s(&out),
    ]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    let words =
        "cut.csv:302:3: the file ends inside its last row, without a line end, and y = 10 there \
                 has 2 digit(s)";
    assert!(err.contains(words), "{err}");
    assert!(warnings(&json(&out)).iter().any(|w| w.contains(words)));
    let id = run(&[
        "identify",
        "--data",
        s(&cut),
        "--structure",
        "arx",
        "--na",
        "2",
        "--nb",
        "2",
        "--method",
        "ls",
    ]);
    assert!(stderr(&id).contains(words) || String::from_utf8_lossy(&id.stdout).contains(words));
}

// Session 35's refusal of a signal below 1e-140, for track: y scaled by 1e-170 is tracked (no record
// to measure first) but said in identify's words with the factor that rescales it; with --strict the
// warning makes exit 1 and --json is not written. The factor: the largest |y| of the record times
// 1e-170, its -floor(log10) computed here.
#[test]
fn track_says_a_tiny_signal_in_identifys_words() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("tiny.csv");
    record(&rec, 600, 1e-170);
    let text = std::fs::read_to_string(&rec).unwrap();
    let largest = text
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max);
    let factor = format!("multiply it by 1e{}", -largest.log10().floor());
    let out = dir.path().join("t.json");
    let args = [
        "track",
        "--data",
        s(&rec),
        "--structure",
        "arx",
        "--na",
        "2",
        "--nb",
        "2",
        "--json",
        s(&out),
    ];
    let o = run(&args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    let words = "the output y is at most";
    let w = warnings(&json(&out));
    let said: Vec<_> = w.iter().filter(|w| w.contains(words)).collect();
    assert_eq!(said.len(), 1, "{w:?}");
    assert!(
        said[0].contains("f64 loses the sums of squares"),
        "{}",
        said[0]
    );
    assert!(said[0].contains(&factor), "{} / {factor}", said[0]);
    let id = run(&[
        "identify",
        "--data",
        s(&rec),
        "--structure",
        "arx",
        "--method",
        "rls",
    ]);
    assert_eq!(id.status.code(), Some(1));
    assert!(stderr(&id).contains(&factor), "{}", stderr(&id));
    let strict_out = dir.path().join("strict.json");
    let mut strict: Vec<&str> = args[..args.len() - 1].to_vec();
    strict.extend([s(&strict_out), "--strict"]);
    let o = run(&strict);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(!strict_out.exists());
}

// Audit s36 H-2's second half: a line longer than the 1 MiB bound that starts after the first MiB (a
// header, 100 000 rows of about 13 bytes, then 2 MiB without a line end, then more rows) is refused
// naming its line (100 002: the header and the rows before it) and the bound, by every in-memory
// reader (identify here).
#[test]
fn a_long_line_after_the_first_mib_is_refused_at_its_line() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("long.csv");
    let mut text = String::from("t,u,y\n");
    for k in 0..100_000 {
        text.push_str(&format!("{},{},{}\n", k as f64 * 0.01, k % 7, k % 5));
    }
    assert!(text.len() > 1 << 20);
    text.push_str(&"1".repeat(2 << 20));
    text.push('\n');
    for k in 0..1000 {
        text.push_str(&format!("{},{},{}\n", k as f64 * 0.01, k % 7, k % 5));
    }
    std::fs::write(&f, text).unwrap();
    let o = run(&["identify", "--data", s(&f), "--structure", "arx"]);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("long.csv:100002:1048577: the line is longer than 1048576 bytes"),
        "{err}"
    );
}

// `validate` of a model on a record whose output is about 1e-170: its fit figures are "n/a" (their sums
// of squares underflow) and a warning now says why, in identify's words, with the factor (the largest
// |y| computed here), in the text and the --json; in memory and --stream on alike.
#[test]
fn validate_says_why_the_fit_of_a_tiny_record_is_not_available() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("rec.csv");
    record(&rec, 600, 1.0);
    let model = dir.path().join("m.json");
    let o = run(&[
        "identify",
        "--data",
        s(&rec),
        "--structure",
        "arx",
        "--method",
        "ls",
        "--na",
        "2",
        "--nb",
        "2",
        "--save-model",
        s(&model),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let tiny = dir.path().join("tiny.csv");
    record(&tiny, 600, 1e-170);
    let text = std::fs::read_to_string(&tiny).unwrap();
    let largest = text
        .lines()
        .skip(1)
        .map(|l| l.rsplit(',').next().unwrap().parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max);
    let factor = format!("multiply it by 1e{}", -largest.log10().floor());
    for stream in ["off", "on"] {
        let out = dir.path().join(format!("v_{stream}.json"));
        let o = run(&[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&tiny),
            "--stream",
            stream,
            "--json",
            s(&out),
        ]);
        let text = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
        assert_eq!(o.status.code(), Some(0), "{text}");
        assert!(text.contains("n/a"), "{text}");
        let w = warnings(&json(&out));
        let said: Vec<_> = w
            .iter()
            .filter(|w| w.contains("the output y is at most") && w.contains(&factor))
            .collect();
        assert_eq!(said.len(), 1, "--stream {stream}: {w:?}");
        assert!(text.contains(said[0].as_str()), "{text}");
    }
}

// Audit s35 L-9: a time column of nanoseconds since 1970 (1.732e18 + k·10^7: `time.time_ns()` at
// 100 Hz). Read as seconds, the note offers `--time-unit ns` (it offered ms and us, neither of which
// reads it); with `--time-unit ns` Ts is 0.01 s up to f64's rounding of such times (256 ns apart
// there: |Ts − 0.01| ≤ 256e-9 / 599 rows, well under 1e-6 relative) and the estimate is that of
// the same rows with t in seconds.
#[test]
fn a_nanosecond_epoch_time_column_is_read_with_time_unit_ns() {
    let dir = tempfile::tempdir().unwrap();
    let secs = dir.path().join("s.csv");
    record(&secs, 600, 1.0);
    let text = std::fs::read_to_string(&secs).unwrap();
    let mut ns = String::from("t,u,y\n");
    for (k, line) in text.lines().skip(1).enumerate() {
        let rest = line.split_once(',').unwrap().1;
        ns.push_str(&format!(
            "{},{rest}\n",
            1_732_000_000_000_000_000u64 + k as u64 * 10_000_000
        ));
    }
    let nsf = dir.path().join("ns.csv");
    std::fs::write(&nsf, ns).unwrap();
    let fit = |file: &std::path::Path, extra: &[&str]| {
        let out = dir.path().join("f.json");
        let mut args = vec![
            "identify",
            "--data",
            s(file),
            "--structure",
            "arx",
            "--method",
            "ls",
            "--na",
            "2",
            "--nb",
            "2",
            "--json",
            s(&out),
        ];
        args.extend(extra);
        let o = run(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        (json(&out), stderr(&o))
    };
    let (plain, _) = fit(&nsf, &[]);
    let said = warnings(&plain);
    assert!(
        said.iter()
            .any(|w| w.contains("pass --time-unit ms (or us, or ns)")),
        "{said:?}"
    );
    assert!(plain["model"]["ts"].as_f64().unwrap() > 1e6);
    let (read_ns, _) = fit(&nsf, &["--time-unit", "ns"]);
    let said = warnings(&read_ns);
    assert!(!said.iter().any(|w| w.contains("--time-unit")), "{said:?}");
    let (read_s, _) = fit(&secs, &[]);
    let ts = read_ns["model"]["ts"].as_f64().unwrap();
    assert!((ts - 0.01).abs() < 1e-8, "{ts}");
    for key in ["a", "b"] {
        let (p, q) = (
            read_ns["model"][key].as_array().unwrap(),
            read_s["model"][key].as_array().unwrap(),
        );
        for (p, q) in p.iter().zip(q) {
            assert_eq!(p.as_f64(), q.as_f64(), "{key}");
        }
    }
}

// Audit s35 L-11: a MAT-file whose first data element's type word (bytes 128..132 after the 128-byte
// header) is 0, no MAT data type, lost that variable (`t`) without a word; now the file is refused as
// damaged, naming the element and its byte. The same file undamaged is read.
#[test]
fn a_mat_element_of_no_mat_type_is_refused_as_damage() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("r.mat");
    let t: Vec<f64> = (0..300).map(|k| k as f64 * 0.01).collect();
    let u: Vec<f64> = (0..300).map(|k| [1.0, -2.0, 3.0][k / 11 % 3]).collect();
    let y: Vec<f64> = (0..300)
        .map(|k| if k > 0 { u[k - 1] } else { 0.0 })
        .collect();
    common::write_mat(&f, &["t", "u", "y"], &[&t, &u, &y]);
    let args = [
        "identify",
        "--data",
        s(&f),
        "--structure",
        "arx",
        "--method",
        "ls",
    ];
    let o = run(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let mut bytes = std::fs::read(&f).unwrap();
    bytes[128..132].copy_from_slice(&0u32.to_le_bytes());
    std::fs::write(&f, bytes).unwrap();
    let o = run(&args);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("data element 1 at byte 128 has type 0, not a MAT data type"),
        "{err}"
    );
}

// Audit s35 L-6: an output on a level of 1e12 (y + 1e12, the motion about 1e2: 1e10 times smaller)
// is refused as linearly dependent, as before, but the words now say the level is the cause and how
// to remove it; the same record without the level is identified.
#[test]
fn an_output_on_a_huge_level_is_said_to_be_one() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("r.csv");
    record(&rec, 600, 1.0);
    let text = std::fs::read_to_string(&rec).unwrap();
    let mut lifted = String::from("t,u,y\n");
    for line in text.lines().skip(1) {
        let (head, y) = line.rsplit_once(',').unwrap();
        lifted.push_str(&format!("{head},{:?}\n", y.parse::<f64>().unwrap() + 1e12));
    }
    let off = dir.path().join("off.csv");
    std::fs::write(&off, lifted).unwrap();
    let args = |f: &std::path::Path| {
        run(&[
            "identify",
            "--data",
            s(f),
            "--structure",
            "arx",
            "--method",
            "ls",
        ])
    };
    assert!(args(&rec).status.success());
    let o = args(&off);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("linearly dependent"), "{err}");
    assert!(
        err.contains("on a level of 1.000e12") && err.contains("--detrend mean"),
        "{err}"
    );
}

// Audit s35 L-2 through the command line: y(k) = u(k − 2) exactly. The headline says the delay is
// not determined, the JSON holds no margin (it held 4.9e16), and `--na 0` finds nk = 2.
#[test]
fn delay_on_an_exact_delayed_copy_says_it_is_not_determined() {
    let dir = tempfile::tempdir().unwrap();
    let f = dir.path().join("copy.csv");
    let u: Vec<f64> = (0..400)
        .map(|k| [3.0, -1.0, 4.0, 1.0, -5.0][k / 9 % 5])
        .collect();
    let y: Vec<f64> = (0..400)
        .map(|k| if k >= 2 { u[k - 2] } else { 0.0 })
        .collect();
    common::write_tuy(dir.path(), "copy.csv", 0.01, &u, &y);
    let out = dir.path().join("d.json");
    let o = run(&[
        "delay",
        "--data",
        s(&f),
        "--max-delay",
        "5",
        "--json",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
    let doc = json(&out);
    assert_eq!(doc["nk"], 1, "{doc}");
    assert!(doc["margin"].is_null(), "{doc}");
    assert!(
        text.contains("nk = 1 samples (0.01 s; not determined: nk + 1 could not be fitted"),
        "{text}"
    );
    let o = run(&[
        "delay",
        "--data",
        s(&f),
        "--max-delay",
        "5",
        "--na",
        "0",
        "--json",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(json(&out)["nk"], 2);
}

/// Audit s37's LOW items of words: an output that is 0 at every sample is said as such, not as an
/// input that does not excite a₁ (L-6); `track` on a header-less file asks for a header instead of a
/// `--no-header` it lacks (L-3); the record budget's refusal gives the budget in GB beside GiB, the
/// unit of the figure it compares (L-2); track's two-level input names what identify does with such
/// a record instead of saying it refuses it (L-4).
#[test]
fn audit_s37_words_say_the_true_cause() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // L-6: y = 0 everywhere, u moving.
    let mut text = String::from("t,u,y\n");
    for k in 0..200 {
        text.push_str(&format!("{},{},0\n", k as f64 * 0.01, (k % 7) as f64 - 3.0));
    }
    let zero = d.join("yzero.csv");
    std::fs::write(&zero, text).unwrap();
    let out = run(&[
        "identify",
        "--data",
        s(&zero),
        "--structure",
        "arx",
        "--method",
        "ls",
    ]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(
        e.contains("regressor a1 is zero over the whole record: the output y is 0 at every sample"),
        "{e}"
    );
    // L-3: a header-less file given to track.
    let mut text = String::new();
    for k in 0..50 {
        let (u, y) = ((k % 5) as f64 + 0.25, (k % 3) as f64 + 0.5);
        text.push_str(&format!("{},{u},{y}\n", k as f64 * 0.01 + 0.005));
    }
    let bare = d.join("bare.csv");
    std::fs::write(&bare, text).unwrap();
    let out = run(&["track", "--data", s(&bare), "--u-col", "2", "--y-col", "3"]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(e.contains("no header row, which this command needs"), "{e}");
    assert!(!e.contains("pass --no-header"), "{e}");
    // L-2: 0.01 GiB = 10 737 418 bytes, 0.011 GB; 83 887 samples × 128 bytes exceed it.
    let out = run(&[
        "simulate",
        "--samples",
        "83887",
        "--max-memory",
        "0.01",
        "--out",
        s(&d.join("o.csv")),
    ]);
    let e = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{e}");
    let gb = (0.01 * (1u64 << 30) as f64) / 1e9;
    assert!(
        e.contains(&format!("budget of 0.01 GiB ({gb:.3} GB, --max-memory)")),
        "{e}"
    );
    // Audit s35 L-3's rest: a tiny command limit is said in exponent form, not 320 zeros.
    let doc = common::run_json(
        d,
        &[
            "control",
            "--plant",
            "paper",
            "--setpoint",
            "50",
            "--duration",
            "1",
            "--u-max",
            "1e-320",
        ],
    );
    let w = warnings(&doc);
    assert!(
        w.iter()
            .any(|w| w.contains("the command is saturated at ±1e-320 ")),
        "{w:?}"
    );
    // L-4: a one-sided input of two levels.
    let mut text = String::from("t,u,y\n");
    let mut y = 0.0;
    for k in 0..400 {
        let u = if (k / 40) % 2 == 0 { 6.41 } else { 3.41 };
        y = 0.9 * y + 0.1 * u;
        text.push_str(&format!("{},{u},{y}\n", k as f64 * 0.01));
    }
    let two = d.join("two.csv");
    std::fs::write(&two, text).unwrap();
    let doc = common::run_json(d, &["track", "--data", s(&two), "--every", "100000"]);
    let w = warnings(&doc);
    assert!(
        w.iter().any(|w| w.contains("only 2 distinct level(s)")
            && w.contains("identify does not estimate it from such a record either")),
        "{w:?}"
    );
}
