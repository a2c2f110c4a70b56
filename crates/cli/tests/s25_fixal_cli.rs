//! Session 25 (helper fixal) through the binary: `validate` of a polynomial NARX model has the record
//! budget of a linear model's (`--max-memory`; before, none: audit s23 H-B1's leftover). The
//! expectation is the record's size times the numbers `validate` holds per sample (16 f64 of 8
//! bytes), computed here from the record written, never from the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

mod common;
use common::{arx_signals, lcg, mat_tag, run as ipa_sysid, s, stderr, write_csv};

#[test]
fn narx_validate_refuses_a_record_beyond_its_memory_budget() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let n = 1000;
    let mut r = lcg(11);
    let (u, y) = arx_signals(n, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let csv = d.join("rec.csv");
    // Three decimals: the record's own read (its text and rows, held to the same budget since audit
    // s27 M-1: at most twice its bytes plus 8 bytes per cell, per row and per line number) stays
    // within the smaller budget below, so that validate's own need is what is refused.
    let u: Vec<f64> = u.iter().map(|v| (v * 1e3).round() / 1e3).collect();
    let y: Vec<f64> = y.iter().map(|v| (v * 1e3).round() / 1e3).collect();
    write_csv(&csv, "u,y", None, &[&u, &y]);
    let file = std::fs::metadata(&csv).unwrap().len() as f64;
    assert!(2.0 * file + ((8 * (2 + 2) * n) as f64) < 0.0001 * 1024f64.powi(3));
    let model = d.join("narx.json");
    let fit = ipa_sysid(&[
        "identify",
        "--data",
        s(&csv),
        "--ts",
        "1",
        "--structure",
        "narx",
        "--degree",
        "2",
        "--na",
        "1",
        "--nb",
        "1",
        "--nk",
        "1",
        "--save-model",
        s(&model),
    ]);
    assert!(fit.status.success(), "{}", stderr(&fit));
    let validate = |gib: &str| {
        ipa_sysid(&[
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&csv),
            "--ts",
            "1",
            "--max-memory",
            gib,
        ])
    };
    let need = n as f64 * 16.0 * 8.0; // 128 000 bytes
                                      // 0.001 GiB = 1 073 741 bytes ≥ the need: validated.
    assert!(0.001 * 1024f64.powi(3) > need);
    let ok = validate("0.001");
    assert!(ok.status.success(), "{}", stderr(&ok));
    // 0.0001 GiB = 107 374 bytes < the need: refused before the simulation, naming the record and
    // the option.
    assert!(0.0001 * 1024f64.powi(3) < need);
    let no = validate("0.0001");
    let err = stderr(&no);
    assert_eq!(no.status.code(), Some(2), "{err}");
    assert!(err.contains("rec.csv"), "{err}");
    assert!(err.contains("--max-memory"), "{err}");
    assert!(err.contains(&format!("a record of {n} samples")), "{err}");
}

/// One miCOMPRESSED element holding the double n × 1 vector `values` named `name` (MAT-File Format,
/// Level 5): its inflated element is an 8-byte miMATRIX tag and `head.len() + 8 n` bytes of data.
fn compressed_vector(name: &[u8], values: &[f64]) -> (Vec<u8>, u64) {
    use std::io::Write;
    let n = values.len();
    let mut head = Vec::new();
    mat_tag(&mut head, 6, &[6, 0, 0, 0, 0, 0, 0, 0]); // array flags: class double
    let mut dims = (n as i32).to_le_bytes().to_vec();
    dims.extend_from_slice(&1i32.to_le_bytes());
    mat_tag(&mut head, 5, &dims);
    mat_tag(&mut head, 1, name);
    head.extend_from_slice(&9u32.to_le_bytes()); // miDOUBLE
    head.extend_from_slice(&((8 * n) as u32).to_le_bytes());
    let declared = (head.len() + 8 * n) as u32;
    let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    z.write_all(&14u32.to_le_bytes()).unwrap(); // miMATRIX
    z.write_all(&declared.to_le_bytes()).unwrap();
    z.write_all(&head).unwrap();
    for v in values {
        z.write_all(&v.to_le_bytes()).unwrap();
    }
    let zipped = z.finish().unwrap();
    let mut out = 15u32.to_le_bytes().to_vec(); // miCOMPRESSED
    out.extend_from_slice(&(zipped.len() as u32).to_le_bytes());
    out.extend_from_slice(&zipped);
    // The inflated bytes of the element: its 8-byte tag and its declared data.
    (out, u64::from(declared) + 8)
}

// s23 H-B1's leftover: the `.mat` reader's own bytes (the inflated elements of the variables asked
// for) count against --max-memory before they are inflated. A record of u and y, 100 000 samples each:
// each element inflates to 8 + 56 + 800 000 bytes; u alone fits 0.001 GiB (1 073 741 bytes), u and y
// together (1 600 128) do not: refused at y, naming the file, the bytes and the option. Under 0.1 GiB
// the same file is identified (its estimation's own need, about 0.011 GB, fits too).
#[test]
fn a_mat_records_inflated_bytes_count_against_max_memory() {
    let dir = tempfile::tempdir().unwrap();
    let n = 100_000;
    let mut r = lcg(5);
    let (u, y) = arx_signals(n, &[0.5], &[1.0], |_| 2.0 * r.unit() - 1.0);
    let mut bytes = b"MATLAB 5.0 MAT-file, fixal".to_vec();
    bytes.resize(116, b' ');
    bytes.extend_from_slice(&[0; 8]);
    bytes.extend_from_slice(&0x0100u16.to_le_bytes());
    bytes.extend_from_slice(b"IM");
    let (eu, iu) = compressed_vector(b"u", &u);
    let (ey, iy) = compressed_vector(b"y", &y);
    assert_eq!((iu, iy), (800_064, 800_064));
    bytes.extend(eu);
    bytes.extend(ey);
    let mat = dir.path().join("rec.mat");
    std::fs::write(&mat, bytes).unwrap();
    let identify = |gib: &str| {
        ipa_sysid(&[
            "identify",
            "--data",
            s(&mat),
            "--ts",
            "1",
            "--na",
            "1",
            "--nb",
            "1",
            "--nk",
            "1",
            "--max-memory",
            gib,
        ])
    };
    let budget = (0.001 * 1024f64.powi(3)) as u64; // 1 073 741 bytes
    assert!(iu <= budget && iu + iy > budget);
    let no = identify("0.001");
    let err = stderr(&no);
    assert_eq!(no.status.code(), Some(2), "{err}");
    assert!(err.contains("rec.mat"), "{err}");
    assert!(err.contains("variable 'y'"), "{err}");
    assert!(err.contains(&format!("to {} bytes", iu + iy)), "{err}");
    assert!(err.contains(&format!("budget of {budget} bytes")), "{err}");
    assert!(err.contains("--max-memory"), "{err}");
    let ok = identify("0.1");
    assert!(ok.status.success(), "{}", stderr(&ok));
}
