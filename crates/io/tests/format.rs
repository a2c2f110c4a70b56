//! `format_one_decimal` prints exactly what the standard formatter `{:.1}` prints.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use sysid_io::format_one_decimal;

// The expectation is the standard library's own `{:.1}`, on pressures of the physics plant's range, on
// exact binary ties (x.25, x.75: ties to even), on the decimals nearest to the ties (x.05, x.15, ...),
// and on values outside the fast path (negative, huge, non-finite).
#[test]
fn matches_the_standard_formatter() {
    let mut values = vec![
        0.0,
        -0.0,
        0.05,
        0.15,
        0.25,
        0.35,
        0.45,
        0.75,
        1.25,
        2.5,
        9.95,
        99.95,
        101325.0,
        101325.05,
        101325.25,
        600000.75,
        1e11 + 0.25,
        1e12,
        1e15 + 0.5,
        -3.25,
        -101325.05,
        f64::MAX,
        f64::MIN_POSITIVE,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for k in 0..20_000u64 {
        let tenth = k as f64 / 10.0;
        values.extend([tenth + 0.05, tenth + 0.049_999_9, tenth + 0.050_000_1]);
        values.push(f64::from_bits(tenth.to_bits() + 1) + 0.05);
    }
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    for _ in 0..200_000 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        values.push((state >> 11) as f64 / (1u64 << 53) as f64 * 8e5);
    }
    for x in values {
        assert_eq!(format_one_decimal(x), format!("{x:.1}"), "{x:e}");
    }
}

// The expectation is the standard library's `{}` (its `{:e}` below 1e-5 and from 1e16): on sample times k / 100 and k · 0.0016384, integer
// commands, encoder positions (multiples of 0.01 mm), values with 1 to 4 decimals, random reals, and
// values outside the fast path (zero, -0, huge, tiny, non-finite).
#[test]
fn shortest_matches_the_standard_formatter() {
    let mut values = vec![
        0.0,
        -0.0,
        1e9,
        -1e9,
        999_999_999.999,
        1e-300,
        5e-324,
        1e300,
        f64::MAX,
        f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        0.1 + 0.2,
        1.0 / 3.0,
        -2.0 / 3.0,
        0.0005,
        0.0015,
    ];
    for k in 0..300_000i64 {
        values.push(k as f64 / 100.0);
        values.push(k as f64 * 0.0016384);
        values.push((k - 150_000) as f64 * 0.01);
    }
    for k in -255..=255i64 {
        values.push(k as f64);
    }
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for _ in 0..200_000 {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let r = (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5;
        values.extend([r, r * 2e3, (r * 2e5).round() / 1e3, (r * 2e7).round() / 1e4]);
    }
    for x in values {
        // Exponent form (`{:e}`, shortest digits too) outside 1e-5 <= |x| < 1e16, as `{:?}` switches:
        // 1e-300 is `1e-300`, not 300 digits (audit s16 L9).
        let expected = if x != 0.0 && x.is_finite() && !(1e-5..1e16).contains(&x.abs()) {
            format!("{x:e}")
        } else {
            x.to_string()
        };
        assert_eq!(sysid_io::format_shortest(x), expected, "{x:e}");
    }
}
