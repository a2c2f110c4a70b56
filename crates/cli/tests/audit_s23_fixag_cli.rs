//! Audit s23 (helper fixag) through the binary: a 0.6 MB compressed `.mat` holding two vectors of
//! 40 000 000 zeros (H-B1) ends `identify` under a memory limit with a clean error (exit 2, naming the
//! file), not a signal from a failed allocation, and `validate` refuses it under its memory budget
//! instead of taking 4.4 GB for ten minutes. The file is generated here (the audit's generator,
//! appendix of /work/audit/s23/FINDINGS.md); the expectation is the exit code and the words, never a
//! copy of the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::io::Write;
use std::path::{Path, PathBuf};

mod common;
use common::{arx_signals, identify_arx, lcg, mat_tag, run as ipa_sysid, stderr, write_csv};

/// One miCOMPRESSED element holding a double n x 1 vector named `name`: `first`, then zeros (u starts
/// with a 1 so that the input is not constant, which is refused before any memory is needed: audit
/// s32 M-1).
fn zero_vector(name: &[u8], n: usize, first: f64) -> Vec<u8> {
    let mut head = Vec::new();
    mat_tag(&mut head, 6, &[6, 0, 0, 0, 0, 0, 0, 0]);
    let mut dims = (n as i32).to_le_bytes().to_vec();
    dims.extend_from_slice(&1i32.to_le_bytes());
    mat_tag(&mut head, 5, &dims);
    mat_tag(&mut head, 1, name);
    head.extend_from_slice(&9u32.to_le_bytes());
    head.extend_from_slice(&((8 * n) as u32).to_le_bytes());
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::best());
    z.write_all(&14u32.to_le_bytes()).unwrap();
    z.write_all(&((head.len() + 8 * n) as u32).to_le_bytes())
        .unwrap();
    z.write_all(&head).unwrap();
    z.write_all(&first.to_le_bytes()).unwrap();
    let block = vec![0u8; 1 << 22];
    let mut left = 8 * (n - 1);
    while left > 0 {
        let k = left.min(block.len());
        z.write_all(&block[..k]).unwrap();
        left -= k;
    }
    let zipped = z.finish().unwrap();
    let mut out = 15u32.to_le_bytes().to_vec();
    out.extend_from_slice(&(zipped.len() as u32).to_le_bytes());
    out.extend_from_slice(&zipped);
    out
}

/// `dir/bigz.mat`: u and y, 40 000 000 zeros each (640 MB of values in well under 1 MB of file).
fn bigz(dir: &Path) -> PathBuf {
    let mut bytes = b"MATLAB 5.0 MAT-file, fixag".to_vec();
    bytes.resize(116, b' ');
    bytes.extend_from_slice(&[0; 8]);
    bytes.extend_from_slice(&0x0100u16.to_le_bytes());
    bytes.extend_from_slice(b"IM");
    bytes.extend(zero_vector(b"u", 40_000_000, 1.0));
    bytes.extend(zero_vector(b"y", 40_000_000, 0.0));
    assert!(bytes.len() < 1_000_000, "{} bytes", bytes.len());
    let path = dir.join("bigz.mat");
    std::fs::write(&path, bytes).unwrap();
    path
}

/// Runs the binary with `args` under `ulimit -v KIB` (a shell that then execs it).
fn limited(kib: u64, args: &[&str]) -> std::process::Output {
    let bin = env!("CARGO_BIN_EXE_ipa-sysid");
    let quoted: Vec<String> = args.iter().map(|a| format!("'{a}'")).collect();
    std::process::Command::new("bash")
        .arg("-c")
        .arg(format!(
            "ulimit -v {kib}; exec '{bin}' {}",
            quoted.join(" ")
        ))
        .output()
        .unwrap()
}

// H-B1: identify under a 1.5 GB address-space limit aborted (SIGABRT) at an infallible copy of the
// input; now every full-length copy the record drives is fallible: exit code 2 and a message naming
// the file and the memory, whatever allocation fails first.
#[test]
fn a_compressed_mat_bomb_is_a_clean_error_under_a_memory_limit() {
    let dir = tempfile::tempdir().unwrap();
    let mat = bigz(dir.path());
    let out = limited(
        1_500_000,
        &[identify_arx(&mat, "1", "1", "ls"), vec!["--ts", "1"]].concat(),
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "not a clean error: {err}");
    assert!(err.contains("bigz.mat"), "{err}");
    assert!(err.contains("GB"), "{err}");
    assert!(
        !err.contains("panicked") && !err.contains("backtrace"),
        "{err}"
    );
}

// H-B1: validate had no budget: 594 s and 4.38 GB for this file. 40 M samples × 16 numbers × 8 bytes
// = 5.12 GB is more than the default 4 GiB (4.29 GB): refused once the record is read, naming the
// budget; the same file and a record of 1000 samples pass with --max-memory as large as needed.
#[test]
fn validate_refuses_a_record_beyond_its_memory_budget() {
    let dir = tempfile::tempdir().unwrap();
    let mat = bigz(dir.path());
    let mut r = lcg(7);
    let (u, y) = arx_signals(1000, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let csv = dir.path().join("small.csv");
    write_csv(&csv, "u,y", None, &[&u, &y]);
    let model = dir.path().join("m.json");
    let fit = ipa_sysid(
        &[
            identify_arx(&csv, "1", "1", "ls"),
            vec!["--ts", "1", "--save-model", model.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(fit.status.success(), "{}", stderr(&fit));
    let out = limited(
        1_500_000,
        &[
            "validate",
            "--model",
            model.to_str().unwrap(),
            "--data",
            mat.to_str().unwrap(),
            "--ts",
            "1",
        ],
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("bigz.mat"), "{err}");
    assert!(
        err.contains("--max-memory") || err.contains("memory"),
        "{err}"
    );
    // 1000 samples × 16 × 8 = 128 000 bytes: within a budget of 0.001 GiB (1 073 741 bytes).
    let ok = ipa_sysid(&[
        "validate",
        "--model",
        model.to_str().unwrap(),
        "--data",
        csv.to_str().unwrap(),
        "--ts",
        "1",
        "--max-memory",
        "0.001",
    ]);
    assert!(ok.status.success(), "{}", stderr(&ok));
    // 0.0001 GiB = 107 374 bytes < 128 000: refused.
    let no = ipa_sysid(&[
        "validate",
        "--model",
        model.to_str().unwrap(),
        "--data",
        csv.to_str().unwrap(),
        "--ts",
        "1",
        "--max-memory",
        "0.0001",
    ]);
    assert_eq!(no.status.code(), Some(2), "{}", stderr(&no));
    assert!(stderr(&no).contains("--max-memory"), "{}", stderr(&no));
}

// L-N1: a Parquet file (the fleet's own output starts with the magic PAR1) and a UTF-16 CSV (a
// byte-order mark FF FE or FE FF) are named for what they are, with what reads them.
#[test]
fn parquet_and_utf16_files_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let parquet = dir.path().join("part-00000.parquet");
    std::fs::write(&parquet, b"PAR1\x15\x00\x15\x1c\x00\x00binary").unwrap();
    let out = ipa_sysid(&["identify", "--data", parquet.to_str().unwrap(), "--ts", "1"]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("Parquet") && err.contains("ipa_sysid.fleet") && err.contains("read_parquet"),
        "{err}"
    );
    for bom in [&b"\xff\xfe"[..], &b"\xfe\xff"[..]] {
        let mut bytes = bom.to_vec();
        // "u,y\n1,2\n" in UTF-16 of the mark's order.
        for c in "u,y\n1,2\n".encode_utf16() {
            let b = if bom[0] == 0xff {
                c.to_le_bytes()
            } else {
                c.to_be_bytes()
            };
            bytes.extend_from_slice(&b);
        }
        let csv = dir.path().join("u16.csv");
        std::fs::write(&csv, &bytes).unwrap();
        let out = ipa_sysid(&["identify", "--data", csv.to_str().unwrap(), "--ts", "1"]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(
            err.contains("UTF-16") && err.contains("save it as UTF-8"),
            "{err}"
        );
    }
}
