//! Session 23 (helper fixaf), the audit s22 leftovers through the binary: a date-time column that
//! --t-col did not name is said to be unread with --ts (M-B10); a missing column's message says who
//! chose its name — the default, the user, the model file (L-N3); `--data FOLDER` names the `*.csv`
//! entries it skipped without opening them (L-B12); Ts has a ceiling, 1e9 s (L-B3); `reproduce` says
//! when it replaced its folder (item 6); `tune` gives one warning per fact for a specification beyond
//! the model's data (item 7, in trust_cli). Records are generated here; the expectations are the words
//! and values written into them, never copied from the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};

mod common;
use common::{
    arx_signals, identify_arx, lcg, run as ipa_sysid, run_json_code, s, stderr, warnings,
};

/// `dir/NAME` with the header `time,u,y`: `time` ISO 8601 stamps 2026-11-27T10:00:00 + 0.1 s · k, rows
/// 100..150 left out (a 5 s gap), u and y from y(k) = 0.5 y(k−1) + u(k−1) with a random input. Returns
/// the path and the first stamp as written.
fn stamped(dir: &Path, name: &str) -> (PathBuf, String) {
    let mut r = lcg(7);
    let (u, y) = arx_signals(400, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let mut text = String::from("time,u,y\n");
    for k in (0..400).filter(|k| !(100..150).contains(k)) {
        let tenths = k as u64; // 0.1 s each
        let (sec, tenth) = (tenths / 10, tenths % 10);
        text.push_str(&format!(
            "2026-11-27T10:{:02}:{:02}.{tenth},{},{}\n",
            sec / 60,
            sec % 60,
            u[k],
            y[k]
        ));
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    (path, "2026-11-27T10:00:00.0".to_string())
}

// M-B10: with --ts, a column `time` of dates and times that --t-col (default t) did not name is not
// read: its gap passed without a word. The JSON warnings and the text now name the column, its first
// stamp and that the stamps are not checked; with --t-col time the time column's own note is given
// instead, once (not both).
#[test]
fn a_date_time_column_not_named_by_t_col_is_said_to_be_unread() {
    let dir = tempfile::tempdir().unwrap();
    let (data, first) = stamped(dir.path(), "stamped.csv");
    let mut args = identify_arx(&data, "1", "1", "ls");
    args.extend(["--ts", "0.1"]);
    let (code, doc) = run_json_code(dir.path(), &args);
    assert_eq!(code, 0);
    let w = warnings(&doc);
    let said: Vec<&String> = w.iter().filter(|w| w.contains("dates and times")).collect();
    assert_eq!(said.len(), 1, "{w:?}");
    assert!(
        said[0].contains(&format!(
            "the column time (not the time column: --t-col is t) holds dates and times ('{first}')"
        )) && said[0].contains("Ts = --ts 0.1 s is taken as given")
            && said[0].contains("not checked"),
        "{}",
        said[0]
    );
    // The text (the report on standard output) says it too.
    let o = ipa_sysid(&args);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("the column time (not the time column: --t-col is t)"),
        "{text}"
    );
    // Named by --t-col: the time column's note, and only it.
    args.extend(["--t-col", "time"]);
    let (_, doc) = run_json_code(dir.path(), &args);
    let w = warnings(&doc);
    let said: Vec<&String> = w.iter().filter(|w| w.contains("dates and times")).collect();
    assert_eq!(said.len(), 1, "{w:?}");
    assert!(
        said[0].contains(&format!(
            "the time column time holds dates and times ('{first}')"
        )),
        "{}",
        said[0]
    );
    // A record with a numeric time column t beside the stamps: Ts from t, nothing said of the stamps.
    let mut r = lcg(3);
    let (u, y) = arx_signals(300, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let mut text = String::from("t,date,u,y\n");
    for k in 0..300 {
        text.push_str(&format!(
            "{},2026-11-27 10:00:00,{},{}\n",
            k as f64 * 0.1,
            u[k],
            y[k]
        ));
    }
    let both = dir.path().join("both.csv");
    std::fs::write(&both, text).unwrap();
    let (code, doc) = run_json_code(dir.path(), &identify_arx(&both, "1", "1", "ls"));
    assert_eq!(code, 0);
    assert!(
        !warnings(&doc).iter().any(|w| w.contains("dates and times")),
        "{:?}",
        warnings(&doc)
    );
}

/// `dir/named.csv` with the header `time,input,output` (time in seconds, Ts = 0.1 s).
fn named(dir: &Path) -> PathBuf {
    let mut r = lcg(11);
    let (u, y) = arx_signals(300, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let path = dir.join("named.csv");
    common::write_csv(&path, "time,input,output", Some(0.1), &[&u, &y]);
    path
}

// L-N3: "no column named 'u' (chosen by --u-col)" was said when no --u-col was typed. The default's
// name is called the default, a typed name is "chosen by --u-col", and a name `validate` took from the
// model file is called the model file's column.
#[test]
fn a_missing_column_is_said_to_come_from_the_default_the_user_or_the_model_file() {
    let dir = tempfile::tempdir().unwrap();
    let data = named(dir.path());
    let o = ipa_sysid(&["identify", "--data", s(&data), "--t-col", "time"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains(
            "no column named 'u' (the default of --u-col; name yours with --u-col NAME); the header \
             has: time, input, output"
        ),
        "{}",
        stderr(&o)
    );
    let o = ipa_sysid(&[
        "identify",
        "--data",
        s(&data),
        "--t-col",
        "time",
        "--u-col",
        "inp",
    ]);
    assert!(
        stderr(&o).contains("no column named 'inp' (chosen by --u-col)"),
        "{}",
        stderr(&o)
    );
    // A model identified from input/output, validated on a record of u,y: the model file's columns.
    let model = dir.path().join("m.json");
    let mut args = identify_arx(&data, "1", "1", "ls");
    args.extend([
        "--u-col",
        "input",
        "--y-col",
        "output",
        "--t-col",
        "time",
        "--save-model",
        s(&model),
    ]);
    let o = ipa_sysid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let plain = dir.path().join("plain.csv");
    common::write_csv(
        &plain,
        "t,u,y",
        Some(0.1),
        &[&[1.0, 0.0, 1.0], &[0.0, 1.0, 0.5]],
    );
    let o = ipa_sysid(&["validate", "--model", s(&model), "--data", s(&plain)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains(
            "no column named 'input' (the model file's column, read because --u-col was not given; \
             name yours with --u-col NAME)"
        ),
        "{}",
        stderr(&o)
    );
    let o = ipa_sysid(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&plain),
        "--u-col",
        "u",
    ]);
    assert!(
        stderr(&o)
            .contains("no column named 'output' (the model file's column, read because --y-col"),
        "{}",
        stderr(&o)
    );
}

// L-B12: a folder holding a record, a FIFO, a link to a device and a link loop, all named *.csv:
// the record is identified, the other three are named with what they are (text and one JSON line
// each), and none is opened (a FIFO opened for reading would block the run forever).
#[test]
fn a_data_folder_names_the_entries_it_skipped_and_opens_none() {
    let dir = tempfile::tempdir().unwrap();
    let fold = dir.path().join("fold");
    std::fs::create_dir(&fold).unwrap();
    named(dir.path());
    let mut r = lcg(5);
    let (u, y) = arx_signals(300, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    common::write_csv(&fold.join("a.csv"), "t,u,y", Some(0.1), &[&u, &y]);
    let fifo = std::process::Command::new("mkfifo")
        .arg(fold.join("b.csv"))
        .status()
        .unwrap();
    assert!(fifo.success());
    std::os::unix::fs::symlink("/dev/zero", fold.join("c.csv")).unwrap();
    std::os::unix::fs::symlink("loop.csv", fold.join("loop.csv")).unwrap();
    let json = dir.path().join("lines.json");
    let mut args = identify_arx(&fold, "1", "1", "ls");
    args.extend(["--json", s(&json)]);
    let o = ipa_sysid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let f = |name: &str| fold.join(name).display().to_string();
    assert!(
        stderr(&o).contains(&format!(
            "note: skipped 3 entries of --data named *.csv or *.mat that are not a regular file and were not \
             opened: {} (a FIFO), {} (a device), {} (a link to nothing: broken, or a loop)",
            f("b.csv"),
            f("c.csv"),
            f("loop.csv")
        )),
        "{}",
        stderr(&o)
    );
    let lines: Vec<serde_json::Value> = std::fs::read_to_string(&json)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 4);
    assert_eq!(lines[0]["file"], f("a.csv"));
    assert!(lines[0]["model"].is_object());
    for (line, name, what) in [
        (&lines[1], "b.csv", "a FIFO"),
        (&lines[2], "c.csv", "a device"),
        (&lines[3], "loop.csv", "a link to nothing"),
    ] {
        assert_eq!(line["file"], f(name));
        let skipped = line["skipped"].as_str().unwrap();
        assert!(
            skipped.starts_with(what) && skipped.ends_with("not opened"),
            "{skipped}"
        );
    }
}

// L-B3: Ts has a ceiling, 1e9 s (about 32 years): a model file of Ts = 1e308 s (whose impulse
// response `response` printed at t = inf) is refused at load naming the file and ts; `identify --ts
// 2e9` is refused naming --ts; a daily record (Ts = 86 400 s) is identified, saved and read back.
#[test]
fn ts_above_a_billion_seconds_is_refused_where_it_is_given() {
    let dir = tempfile::tempdir().unwrap();
    let huge = dir.path().join("huge.json");
    std::fs::write(
        &huge,
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "arx", "ts": 1e308,
        "na": 1, "nb": 1, "nk": 1, "a": [-0.5], "b": [0.1], "offset": null}}"#,
    )
    .unwrap();
    let o = ipa_sysid(&[
        "response",
        "--model",
        s(&huge),
        "--points",
        "3",
        "--samples",
        "3",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains(&format!(
            "{}: invalid model: ts = 1e308 s is above 1e9 s",
            huge.display()
        )) && !String::from_utf8_lossy(&o.stdout).contains("inf"),
        "{}",
        stderr(&o)
    );
    let mut r = lcg(9);
    let (u, y) = arx_signals(300, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let data = dir.path().join("uy.csv");
    common::write_csv(&data, "u,y", None, &[&u, &y]);
    let mut args = identify_arx(&data, "1", "1", "ls");
    args.extend(["--ts", "2e9"]);
    let o = ipa_sysid(&args);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("invalid setting --ts = 2000000000")
            && stderr(&o).contains("at most 1e9 s"),
        "{}",
        stderr(&o)
    );
    let daily = dir.path().join("daily.json");
    let mut args = identify_arx(&data, "1", "1", "ls");
    args.extend(["--ts", "86400", "--save-model", s(&daily)]);
    let o = ipa_sysid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&daily).unwrap()).unwrap();
    assert_eq!(doc["model"]["ts"].as_f64(), Some(86_400.0));
    let o = ipa_sysid(&[
        "response",
        "--model",
        s(&daily),
        "--points",
        "3",
        "--samples",
        "3",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}
