//! Audit s26 (helper fixap) through the binary: a file of the wrong kind is named for what it is by the
//! readers' one sniffing helper (L-1: a model file as `--data`, a CSV record as `--model` or
//! `--plant model:FILE`, a model file as `--controller`), never by a parser's message ("ragged row …
//! decimal commas", "not valid JSON: expected ident", "unknown field `model`"). The expectations are the
//! exit code and the words, not a copy of the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{paper_record, run as ipa_sysid, s, stderr, write_tuy};

#[test]
fn a_file_of_the_wrong_kind_is_named_for_what_it_is() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(3000, 0);
    let csv = write_tuy(dir.path(), "est.csv", 0.01, &u, &y);
    let model = dir.path().join("model.json");
    let o = ipa_sysid(&[
        "identify",
        "--data",
        s(&csv),
        "--method",
        "ls",
        "--save-model",
        s(&model),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ctrl = dir.path().join("ctrl.json");
    std::fs::write(
        &ctrl,
        "{\n  \"format\": \"ipa-sysid-controller\",\n  \"version\": 1\n}\n",
    )
    .unwrap();
    let other = dir.path().join("idout.json");
    std::fs::write(&other, "{\n  \"model\": {\"kind\": \"hammerstein\"}\n}\n").unwrap();
    let refused = |args: &[&str], words: &[&str], never: &[&str]| {
        let o = ipa_sysid(args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        for w in words {
            assert!(err.contains(w), "{args:?}: no {w:?} in {err}");
        }
        for w in never {
            assert!(!err.contains(w), "{args:?}: {w:?} in {err}");
        }
    };
    let parser = [
        "ragged row",
        "decimal comma",
        "the header has",
        "expected ident",
        "unknown field",
    ];
    // A model file, a controller file and another JSON document as the record.
    for cmd in [
        &["validate", "--model", s(&model), "--data"][..],
        &["identify", "--data"],
        &[
            "calibrate",
            "--out",
            s(&dir.path().join("t.toml")),
            "--data",
        ],
    ] {
        let mut a = cmd.to_vec();
        a.push(s(&model));
        refused(
            &a,
            &[
                "model.json:1:1: this is not a",
                "(CSV text or a .mat file) but a model file",
                "give it to --model",
            ],
            &parser,
        );
    }
    refused(
        &["identify", "--data", s(&ctrl)],
        &["but a controller file", "--controller"],
        &parser,
    );
    refused(
        &["identify", "--data", s(&other)],
        &["but a JSON document", "identify --json"],
        &parser,
    );
    // A CSV record as the model file, as the plant's model and as the controller.
    refused(
        &["validate", "--model", s(&csv), "--data", s(&csv)],
        &["est.csv: this is CSV text (a record?)", "not a model file"],
        &parser,
    );
    refused(
        &[
            "control",
            "--plant",
            &format!("model:{}", s(&csv)),
            "--setpoint",
            "50",
        ],
        &["this is CSV text (a record?)", "not a model file"],
        &parser,
    );
    refused(
        &[
            "control",
            "--plant",
            "ipa",
            "--setpoint",
            "50",
            "--controller",
            s(&model),
        ],
        &["this is a model file", "not a controller file"],
        &parser,
    );
}

// L-2: a time column in milliseconds computed in floating point (t × 1000 of a 0.01 s record:
// 2009.9999999999998 among the whole numbers) gave Ts = 10 s without a word.
#[test]
fn a_time_column_in_milliseconds_points_to_time_unit_ms() {
    let dir = tempfile::tempdir().unwrap();
    let (u, y) = paper_record(3000, 0);
    // As a logger's seconds 0.01·k written with two decimals, then multiplied by 1000.
    let t: Vec<f64> = (0..u.len())
        .map(|k| format!("{:.2}", k as f64 * 0.01).parse::<f64>().unwrap() * 1000.0)
        .collect();
    assert!(
        t.iter().any(|v| v.fract() != 0.0),
        "the test's column has no rounding to tolerate"
    );
    let mut text = String::from("t,u,y\n");
    for k in 0..u.len() {
        text += &format!("{},{},{}\n", t[k], u[k], y[k]);
    }
    let ms = dir.path().join("ms.csv");
    std::fs::write(&ms, text).unwrap();
    let o = ipa_sysid(&["identify", "--data", s(&ms), "--method", "ls"]);
    let err = stderr(&o) + &String::from_utf8_lossy(&o.stdout);
    assert!(err.contains("Ts = 10 s"), "{err}");
    assert!(err.contains("--time-unit ms"), "{err}");
    // Named as milliseconds: said whatever the step.
    let named = dir.path().join("named.csv");
    let mut text = String::from("t_ms,u,y\n");
    for k in 0..u.len() {
        text += &format!("{},{},{}\n", k, u[k], y[k]);
    }
    std::fs::write(&named, text).unwrap();
    let o = ipa_sysid(&[
        "identify",
        "--data",
        s(&named),
        "--t-col",
        "t_ms",
        "--method",
        "ls",
    ]);
    let err = stderr(&o) + &String::from_utf8_lossy(&o.stdout);
    assert!(
        err.contains("named as milliseconds") && err.contains("--time-unit ms"),
        "{err}"
    );
    // The same column with --time-unit ms: Ts = 0.01 s / 1 ms, no note.
    let o = ipa_sysid(&[
        "identify",
        "--data",
        s(&ms),
        "--method",
        "ls",
        "--time-unit",
        "ms",
    ]);
    let err = stderr(&o) + &String::from_utf8_lossy(&o.stdout);
    assert!(
        err.contains("Ts = 0.01 s") && !err.contains("--time-unit ms"),
        "{err}"
    );
}
