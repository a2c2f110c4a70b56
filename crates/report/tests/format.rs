//! Number formatting: significant digits counted by hand, rounding that carries into a new digit,
//! scientific notation outside 1e-3..1e5, integers whole.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use report::format::{estimate, opt, pm, sig, std_dev};

#[test]
fn estimates_keep_four_significant_digits() {
    for (v, s) in [
        (30.83012, "30.83"),
        (-27.8109, "-27.81"),
        (0.0811371, "0.08114"),
        (0.00505503, "0.005055"),
        (1.4120, "1.412"),
        (1.41, "1.41"), // trailing zeros trimmed
        (-2.25133, "-2.251"),
        (92.9665, "92.97"),
        (12345.6, "1.235e4"), // 5 integer digits do not fit in 4
        (9.99961, "10"),      // rounding carries into a new digit: 10.00 trimmed
        (0.99996, "1"),
        (8.510e-4, "8.51e-4"),
        (1.53602e-4, "1.536e-4"),
        (2.5e6, "2.5e6"),
        (255.0, "255"), // an integer is printed whole
        (2000.0, "2000"),
        (-50.0, "-50"),
        (0.0, "0"),
    ] {
        assert_eq!(estimate(v), s, "{v}");
    }
}

#[test]
fn standard_deviations_keep_two() {
    for (v, s) in [
        (3.51834, "3.5"),
        (0.0134527, "0.013"),
        (1.57902e-4, "1.6e-4"),
        (0.29411, "0.29"),
        (0.096, "0.096"),
        (0.0996, "0.1"),
    ] {
        assert_eq!(std_dev(v), s, "{v}");
    }
}

#[test]
fn value_with_deviation_and_missing_values() {
    assert_eq!(pm(30.83012, Some(3.51834)), "30.83 ± 3.5");
    assert_eq!(pm(-0.548478, Some(0.0114236)), "-0.5485 ± 0.011");
    assert_eq!(pm(1.0, None), "1");
    assert_eq!(opt(None), "n/a");
    assert_eq!(opt(Some(74.9038)), "74.9");
    assert_eq!(sig(f64::NAN, 4), "NaN");
    assert_eq!(sig(f64::NEG_INFINITY, 4), "-inf");
    assert_eq!(sig(0.123456, 1), "0.1");
    assert_eq!(sig(0.123456, 0), "0.1", "digits are clamped to at least 1");
}
