//! Files of the wrong kind, said as such by every reader (audit s27 L-4): a model file given to
//! `track` and to the streaming reader, a plant configuration (TOML) given as a record, a model or a
//! controller, and a model file or record given as a plant configuration. Each must name what the file
//! is and where it goes, and exit 2 without reading further.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{arx_signals, bin, s, stderr, write_tuy};

/// A record, a model file saved from it, and the plant configuration `plant-config` prints.
fn files(dir: &std::path::Path) -> (std::path::PathBuf, std::path::PathBuf, std::path::PathBuf) {
    let (u, y) = arx_signals(400, &[0.5], &[1.0], |k| {
        if (k / 7) % 2 == 0 {
            1.0
        } else {
            -1.0
        }
    });
    let data = write_tuy(dir, "a.csv", 0.01, &u, &y);
    let model = dir.join("m.json");
    let o = bin()
        .args(["identify", "--data", s(&data), "--structure", "arx"])
        .args(["--method", "ls", "--save-model", s(&model)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let toml = dir.join("plant.toml");
    let o = bin().arg("plant-config").output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::write(&toml, &o.stdout).unwrap();
    (data, model, toml)
}

#[test]
fn every_reader_names_a_file_of_another_kind() {
    let dir = tempfile::tempdir().unwrap();
    let (data, model, toml) = files(dir.path());
    let (d, m, t) = (s(&data), s(&model), s(&toml));
    let a_model = "but a model file (JSON, \"format\": \"ipa-sysid-model\"";
    let a_toml = "TOML text (a plant configuration";
    let arx_ls = ["--structure", "arx", "--method", "ls"];
    let never = dir.path().join("never.csv").display().to_string();
    let cases: Vec<(Vec<&str>, String)> = vec![
        // track's reader, from a file and followed.
        (vec!["track", "--data", m], format!("{m}:1:1: this is not a data file")),
        (vec!["track", "--follow", m], a_model.into()),
        (vec!["track", "--data", t], a_toml.into()),
        // The streaming reader: the estimation and the validation record.
        (
            [&["identify", "--data", m][..], &arx_ls, &["--stream", "on"]].concat(),
            format!("{m}:1:1: this is not a data file (CSV text or a .mat file) {a_model}"),
        ),
        (
            [
                &["identify", "--data", d][..],
                &arx_ls,
                &["--validation", m, "--stream", "on"],
            ]
            .concat(),
            a_model.into(),
        ),
        // A plant configuration as a record, in memory and streamed.
        (vec!["identify", "--data", t], format!("{t}:1:1: this is not a data file")),
        (
            [&["identify", "--data", t][..], &arx_ls, &["--stream", "on"]].concat(),
            a_toml.into(),
        ),
        // ... as a model and as a controller.
        (
            vec!["validate", "--model", t, "--data", d],
            format!("{a_toml}, as `ipa-sysid plant-config` writes it?); give a plant configuration to --plant-config, not a model file"),
        ),
        (
            vec!["control", "--plant", "paper", "--controller", t, "--setpoint", "5"],
            "not a controller file".into(),
        ),
        // A model file and a record as the plant configuration.
        (
            vec!["simulate", "--plant", "ipa", "--plant-config", m, "--input", "prbs", "--out", &never],
            "this is a model file (JSON".into(),
        ),
        (
            vec!["simulate", "--plant", "ipa", "--plant-config", d, "--input", "prbs", "--out", &never],
            "this is CSV text (a record?); give a record to --data, not a plant configuration".into(),
        ),
    ];
    for (args, words) in cases {
        let o = bin().args(&args).output().unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(e.contains(&words), "{args:?}: expected `{words}` in\n{e}");
        assert!(!e.contains("panicked"), "{args:?}: {e}");
    }
    assert!(!std::path::Path::new(&never).exists());
    // The plant configuration itself still reads as one (the sniffing never refuses valid TOML).
    let out = dir.path().join("sim.csv");
    let o = bin()
        .args(["simulate", "--plant", "ipa", "--plant-config", t])
        .args(["--input", "prbs", "--out", s(&out)])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn track_names_a_file_of_another_kind_on_standard_input_and_keeps_a_record_whole() {
    // The reader's own first bytes are looked at (session 30): standard input is sniffed too, and a
    // record read that way loses none of its bytes to the look.
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let (data, model, _) = files(dir.path());
    let feed = |bytes: Vec<u8>| {
        let mut child = bin()
            .args(["track", "--data", "-"])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        child.stdin.take().unwrap().write_all(&bytes).unwrap();
        child.wait_with_output().unwrap()
    };
    let o = feed(std::fs::read(&model).unwrap());
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("<stdin>:1:1: this is not a data file"), "{e}");
    // The record: as many samples from standard input as from the file (400 rows).
    let o = feed(std::fs::read(&data).unwrap());
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("400 samples"), "{e}");
}
