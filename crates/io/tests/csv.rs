#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]
//! `write_csv` / `write_columns_csv`: the bytes on disk, written out by hand.

use sysid_io::{write_columns_csv, write_csv, OutputError};

#[test]
fn columns_are_written_row_by_row_with_shortest_decimals() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.csv");
    let t = [0.0, 0.01, 0.02];
    let u = [1.5, -2.0, 100.0];
    let y = [0.1 + 0.2, f64::NAN, -1e-7];
    write_columns_csv(&path, &["t", "u", "y"], &[&t, &u, &y]).unwrap();
    // The shortest round-trip decimal: 0.1 + 0.2 = 0.30000000000000004; below 1e-5 in size the exponent
    // form (1e-7 reads back exactly and is shorter than 0.0000001); NaN spelt NaN.
    let expected = "t,u,y\n0,1.5,0.30000000000000004\n0.01,-2,NaN\n0.02,100,-1e-7\n";
    assert_eq!(std::fs::read_to_string(&path).unwrap(), expected);
}

#[test]
fn cells_needing_quotes_are_quoted() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("q.csv");
    write_csv(&path, &["name", "note"], [["a,b", "say \"hi\""]]).unwrap();
    assert_eq!(
        std::fs::read_to_string(&path).unwrap(),
        "name,note\n\"a,b\",\"say \"\"hi\"\"\"\n"
    );
}

#[test]
fn mismatched_columns_are_refused_and_nothing_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.csv");
    let e = write_columns_csv(&path, &["t", "u"], &[&[0.0, 1.0], &[2.0]]).unwrap_err();
    assert!(matches!(e, OutputError::Io { .. }), "{e}");
    assert!(e.to_string().contains("equal length"), "{e}");
    let e = write_columns_csv(&path, &["t"], &[&[0.0], &[2.0]]).unwrap_err();
    assert!(e.to_string().contains("one name per column"), "{e}");
    assert!(!path.exists());
}
