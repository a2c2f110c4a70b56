//! Session 26 (helper fixan) through the binary: the record budget of `--max-memory` holds on the one
//! reader for every command that reads a record (before, `order`, `delay` and `calibrate` read a
//! compressed `.mat` without it), and a saved model's run by `simulate --plant model:FILE` has
//! `validate`'s record budget (N samples × 16 numbers × 8 bytes; before, none: a NARX model on a long
//! `--input file:` was simulated whatever its length). Session 27 (audit s27 M-1): a CSV record read
//! into memory is held to the same budget before its rows are parsed (before, a 74 MB file took 650 MB
//! before the estimation's budget refused it). The expectations are computed here from the bytes
//! written and the documented rule, never from the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{arx_signals, identify_arx, lcg, mat_tag, run as ipa_sysid, s, stderr, write_tuy};
use std::io::Write;
use std::path::Path;

/// Samples the hostile variable declares: the reader's bound on a record (`MAX_SAMPLES`), so that the
/// element passes the per-variable size check and only the budget stops it.
const DECLARED_SAMPLES: u64 = 50_000_000;

/// A Level 5 `.mat` file whose one compressed variable `u` declares an inflated element of about
/// 400 MB (a double vector of [`DECLARED_SAMPLES`]) while its compressed stream holds only the
/// header and 64 KiB of zeros: a reader that trusts the declared size allocates 400 MB for a file of
/// a few hundred bytes. Returns the declared inflated bytes (the element's tag and data).
fn hostile_mat(path: &Path) -> u64 {
    let mut head = Vec::new();
    mat_tag(&mut head, 6, &[6, 0, 0, 0, 0, 0, 0, 0]); // array flags: class double
    let mut dims = (DECLARED_SAMPLES as i32).to_le_bytes().to_vec();
    dims.extend_from_slice(&1i32.to_le_bytes());
    mat_tag(&mut head, 5, &dims);
    mat_tag(&mut head, 1, b"u");
    head.extend_from_slice(&9u32.to_le_bytes()); // miDOUBLE
    head.extend_from_slice(&((8 * DECLARED_SAMPLES) as u32).to_le_bytes());
    let declared = head.len() as u64 + 8 * DECLARED_SAMPLES;
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    z.write_all(&14u32.to_le_bytes()).unwrap(); // miMATRIX
    z.write_all(&(declared as u32).to_le_bytes()).unwrap();
    z.write_all(&head).unwrap();
    z.write_all(&vec![0u8; 1 << 16]).unwrap();
    let zipped = z.finish().unwrap();
    let mut bytes = b"MATLAB 5.0 MAT-file, fixan".to_vec();
    bytes.resize(116, b' ');
    bytes.extend_from_slice(&[0; 8]);
    bytes.extend_from_slice(&0x0100u16.to_le_bytes());
    bytes.extend_from_slice(b"IM");
    bytes.extend_from_slice(&15u32.to_le_bytes()); // miCOMPRESSED
    bytes.extend_from_slice(&(zipped.len() as u32).to_le_bytes());
    bytes.extend_from_slice(&zipped);
    std::fs::write(path, bytes).unwrap();
    declared + 8
}

#[test]
fn every_command_that_reads_a_record_holds_the_mat_reader_to_max_memory() {
    let dir = tempfile::tempdir().unwrap();
    let mat = dir.path().join("hostile.mat");
    let inflated = hostile_mat(&mat);
    assert!(
        std::fs::metadata(&mat).unwrap().len() < 2000,
        "a small file"
    );
    // A model for validate, identified on a small CSV record.
    let mut r = lcg(3);
    let (u, y) = arx_signals(400, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let csv = write_tuy(dir.path(), "small.csv", 1.0, &u, &y);
    let model = dir.path().join("m.json");
    let mut args = identify_arx(&csv, "1", "1", "ls");
    args.extend(["--save-model", s(&model)]);
    let made = ipa_sysid(&args);
    assert!(made.status.success(), "{}", stderr(&made));
    let out = dir.path().join("twin.toml");
    let m = s(&mat);
    // 0.1 GiB, less than the 400 MB the element declares.
    let budget = (0.1 * 1024f64.powi(3)) as u64;
    assert!(inflated > budget);
    let cases: [(&str, Vec<&str>); 5] = [
        (
            "identify",
            vec![
                "identify", "--data", m, "--ts", "1", "--na", "1", "--nb", "1",
            ],
        ),
        (
            "validate",
            vec!["validate", "--model", s(&model), "--data", m, "--ts", "1"],
        ),
        (
            "order",
            vec![
                "order", "--data", m, "--ts", "1", "--na", "1..2", "--nb", "1", "--nk", "1",
            ],
        ),
        ("delay", vec!["delay", "--data", m, "--ts", "1"]),
        (
            "calibrate",
            vec!["calibrate", "--data", m, "--ts", "0.01", "--out", s(&out)],
        ),
    ];
    for (command, mut args) in cases {
        args.extend(["--max-memory", "0.1"]);
        let o = ipa_sysid(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{command}: {err}");
        assert!(
            err.contains("hostile.mat"),
            "{command} names the file: {err}"
        );
        assert!(err.contains("variable 'u'"), "{command}: {err}");
        assert!(
            err.contains(&format!("to {inflated} bytes")),
            "{command}: {err}"
        );
        assert!(
            err.contains(&format!("budget of {budget} bytes")),
            "{command}: {err}"
        );
        assert!(err.contains("--max-memory"), "{command}: {err}");
    }
    assert!(!out.exists(), "calibrate wrote nothing");
}

/// `simulate --plant model:FILE` of N samples needs N × 16 × 8 bytes (validate's record budget):
/// refused beyond `--max-memory`, for a linear and a NARX model, naming the model and the option;
/// the same run within the budget writes its record.
#[test]
fn simulate_of_a_model_has_the_record_budget_of_validate() {
    let dir = tempfile::tempdir().unwrap();
    let mut r = lcg(7);
    let (u, y) = arx_signals(600, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let csv = write_tuy(dir.path(), "rec.csv", 1.0, &u, &y);
    let linear = dir.path().join("arx.json");
    let narx = dir.path().join("narx.json");
    for (model, structure) in [(&linear, "arx"), (&narx, "narx")] {
        let mut args = vec![
            "identify",
            "--data",
            s(&csv),
            "--structure",
            structure,
            "--na",
            "1",
        ];
        args.extend(["--nb", "1", "--save-model", s(model)]);
        if structure == "arx" {
            args.extend(["--method", "ls"]);
        }
        let made = ipa_sysid(&args);
        assert!(made.status.success(), "{}", stderr(&made));
    }
    // 100 000 samples × 16 × 8 = 12 800 000 bytes: beyond 0.01 GiB (10 737 418), within 0.1 GiB.
    let n = 100_000u64;
    let need = n * 16 * 8;
    assert!(need > (0.01 * 1024f64.powi(3)) as u64 && need < (0.1 * 1024f64.powi(3)) as u64);
    for model in [&linear, &narx] {
        let plant = format!("model:{}", s(model));
        let out = dir.path().join("sim.csv");
        let run = |gib: &str| {
            ipa_sysid(&[
                "simulate",
                "--plant",
                &plant,
                "--input",
                "prbs",
                "--samples",
                "100000",
                "--y0",
                "0",
                "--out",
                s(&out),
                "--max-memory",
                gib,
            ])
        };
        let no = run("0.01");
        let err = stderr(&no);
        assert_eq!(no.status.code(), Some(2), "{err}");
        assert!(err.contains(&format!("model:{}", s(model))), "{err}");
        assert!(err.contains("a record of 100000 samples"), "{err}");
        assert!(err.contains("--max-memory"), "{err}");
        assert!(!out.exists(), "nothing written: {err}");
        let ok = run("0.1");
        assert!(ok.status.success(), "{}", stderr(&ok));
        let rows = std::fs::read_to_string(&out).unwrap().lines().count();
        assert_eq!(rows, 100_001, "header and N rows");
        std::fs::remove_file(&out).unwrap();
    }
}

/// A CSV record read into memory holds at least its own bytes: under a budget smaller than the file
/// every command that reads a record refuses it (exit 2, naming the file, the budget in bytes and
/// `--max-memory`) before parsing it; under a budget above an upper bound of what its rows can take
/// (twice the text, for the file and its cells, plus 8 bytes per cell, per row and per line number)
/// the same commands run.
#[test]
fn a_csv_record_is_held_to_max_memory_before_its_rows_are_parsed() {
    let dir = tempfile::tempdir().unwrap();
    let mut r = lcg(5);
    let n = 40_000;
    let (u, y) = arx_signals(n, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let csv = write_tuy(dir.path(), "long.csv", 0.01, &u, &y);
    let small = write_tuy(dir.path(), "small.csv", 0.01, &u[..400], &y[..400]);
    let model = dir.path().join("m.json");
    let mut args = identify_arx(&small, "1", "1", "ls");
    args.extend(["--save-model", s(&model)]);
    let made = ipa_sysid(&args);
    assert!(made.status.success(), "{}", stderr(&made));
    let file = std::fs::metadata(&csv).unwrap().len();
    let gib = 1024f64.powi(3);
    let below = "0.0005"; // 536 870 bytes
    assert!(
        ((0.0005 * gib) as u64) < file,
        "the file is larger than the budget"
    );
    let upper = 2 * file + 8 * (3 + 2) * n as u64;
    let above = "0.01"; // 10.7 MB
    assert!(upper < (0.01 * gib) as u64);
    let c = s(&csv);
    let cases: [(&str, Vec<&str>); 4] = [
        ("identify", identify_arx(&csv, "1", "1", "ls")),
        (
            "validate",
            vec!["validate", "--model", s(&model), "--data", c],
        ),
        (
            "order",
            vec![
                "order", "--data", c, "--na", "1..2", "--nb", "1", "--nk", "1",
            ],
        ),
        ("delay", vec!["delay", "--data", c]),
    ];
    for (command, args) in cases {
        let mut refused = args.clone();
        refused.extend(["--max-memory", below]);
        let o = ipa_sysid(&refused);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{command}: {err}");
        assert!(err.contains("long.csv"), "{command} names the file: {err}");
        let budget = (0.0005 * gib) as u64;
        assert!(
            err.contains(&format!("budget of {budget} bytes")),
            "{command}: {err}"
        );
        assert!(err.contains("--max-memory"), "{command}: {err}");
        let mut within = args;
        within.extend(["--max-memory", above]);
        let o = ipa_sysid(&within);
        assert!(o.status.success(), "{command}: {}", stderr(&o));
    }
}
