//! The CSV reader on small hand-written files: what is accepted and what is refused, and where.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use sysid::data::{read_csv_bytes, CsvOptions};

fn read(text: &str, opts: &CsvOptions) -> Result<sysid::Dataset, String> {
    read_csv_bytes(text.as_bytes(), "f.csv", opts).map_err(|e| e.to_string())
}

// A time column 0, 0.01, …, 0.07 has mean step 0.07/7, which is 0.01 only after rounding.
#[test]
fn ts_from_a_decimal_time_column_is_the_decimal_step() {
    let mut s = String::from("t,u,y\n");
    for k in 0..8 {
        s += &format!(
            "{},{},{}\n",
            [0.0, 0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07][k],
            k,
            k
        );
    }
    let d = read(&s, &CsvOptions::default()).unwrap();
    assert_eq!(d.ts(), 0.01);
    assert_eq!(d.u(), (0..8).map(f64::from).collect::<Vec<_>>());
}

// The cascaded-tanks layout: quoted names, a trailing comma on every row, a Ts column filled only once.
#[test]
fn quoted_headers_and_trailing_empty_fields_are_accepted() {
    let text = "\"uEst\",\"yEst\",\"Ts\",\n3.25,5.2,4,\n3.24,5.21,,\n";
    let opts = CsvOptions {
        u_col: "uEst".into(),
        y_col: "yEst".into(),
        ts: Some(4.0),
        ..CsvOptions::default()
    };
    let d = read(text, &opts).unwrap();
    assert_eq!(
        (d.u().to_vec(), d.y().to_vec(), d.ts()),
        (vec![3.25, 3.24], vec![5.2, 5.21], 4.0)
    );
}

#[test]
fn a_semicolon_delimited_export_is_accepted() {
    let d = read("t;u;y\n0;1;2\n0.5;3;4\n", &CsvOptions::default()).unwrap();
    assert_eq!(
        (d.u().to_vec(), d.y().to_vec(), d.ts()),
        (vec![1.0, 3.0], vec![2.0, 4.0], 0.5)
    );
}

#[test]
fn decreasing_time_is_refused_at_its_line() {
    let e = read(
        "t,u,y\n0,1,1\n0.01,1,1\n0.005,1,1\n",
        &CsvOptions::default(),
    )
    .unwrap_err();
    assert!(e.starts_with("f.csv:4:1:"), "{e}");
}

#[test]
fn non_uniform_time_is_refused_at_its_line() {
    let e = read(
        "t,u,y\n0,1,1\n0.01,1,1\n0.02,1,1\n0.04,1,1\n",
        &CsvOptions::default(),
    )
    .unwrap_err();
    assert!(
        e.starts_with("f.csv:5:1:") && e.contains("non-uniform"),
        "{e}"
    );
}

#[test]
fn a_missing_time_column_without_ts_says_how_to_fix_it() {
    let e = read("u,y\n1,2\n", &CsvOptions::default()).unwrap_err();
    assert!(e.contains("--ts") && e.contains("--t-col"), "{e}");
}

// At Ts = 0.1 s the times are k/10: t_3 is the decimal 0.3, which 3 × 0.1 (0.30000000000000004) is not.
#[test]
fn sample_times_at_a_whole_rate_are_the_logger_decimals() {
    let t = sysid::data::sample_times(4, 0.1);
    assert_eq!(t, vec![0.0, 0.1, 0.2, 0.3]);
    assert_ne!(3.0 * 0.1, 0.3);
    assert_eq!(sysid::data::sample_times(8, 0.01)[7], 0.07);
    assert_eq!(sysid::data::sample_times(3, 0.3), vec![0.0, 0.3, 0.6]);
}
