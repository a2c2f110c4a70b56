//! Numbers as reports print them.
//!
//! The reproduction report prints every estimate and measured quantity with [`estimate`] (4 significant
//! digits) and every standard deviation with [`std_dev`] (2 significant digits), in its HTML tables, its
//! terminal tables and its captions alike: `30.83 ± 3.5`, `0.08114 s`, `8.51e-4`. [`num`] is the older
//! 6-digit format kept for the command line's own tables.

/// Formats a number for a report: 6 significant digits, scientific for very large or small values.
pub fn num(v: f64) -> String {
    fn trim(s: String) -> String {
        match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            None if s.contains('.') => s.trim_end_matches('0').trim_end_matches('.').to_string(),
            _ => s,
        }
    }
    if v == 0.0 {
        "0".into()
    } else if !v.is_finite() {
        format!("{v}")
    } else if v.abs() >= 1e5 || v.abs() < 1e-3 {
        trim(format!("{v:.5e}"))
    } else {
        let digits = (5 - v.abs().log10().floor() as i32).clamp(0, 9) as usize;
        trim(format!("{v:.digits$}"))
    }
}

/// `v` rounded to `digits` significant digits (1 to 15), trailing zeros trimmed: fixed notation for
/// 1e-3 ≤ |v| < 1e5 when the integer part fits in `digits` (`0.08114`, `30.83`, `1.41`), scientific
/// otherwise (`8.51e-4`, `1.235e4` for 12345.6 with 4 digits). An integer below 1e5 in magnitude
/// is printed whole (`255`, `2000`, `-50`); 0 is `0`; NaN and ±inf print as Rust does.
pub fn sig(v: f64, digits: usize) -> String {
    let digits = digits.clamp(1, 15);
    if v == 0.0 {
        return "0".into();
    }
    if !v.is_finite() {
        return format!("{v}");
    }
    if v.fract() == 0.0 && v.abs() < 1e5 {
        // An integer is exact: printed whole (a count, a number of samples, a set-point).
        return format!("{v:.0}");
    }
    // The exponent after rounding (9.9996 to 4 digits is 10.00, exponent 1, not 0).
    let sci = format!("{:.*e}", digits - 1, v);
    let exponent: i32 = sci
        .split_once('e')
        .and_then(|(_, e)| e.parse().ok())
        .unwrap_or(0);
    if !(-3..5).contains(&exponent) || exponent >= digits as i32 {
        return match sci.split_once('e') {
            Some((m, e)) => format!("{}e{e}", trim_zeros(m)),
            None => sci,
        };
    }
    let decimals = (digits as i32 - 1 - exponent).max(0) as usize;
    trim_zeros(&format!("{v:.decimals$}"))
}

/// `1.500` → `1.5`, `2.000` → `2`; a string without a decimal point is returned unchanged.
fn trim_zeros(s: &str) -> String {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s.to_string()
    }
}

/// An estimate or measured value: 4 significant digits ([`sig`]).
pub fn estimate(v: f64) -> String {
    sig(v, 4)
}

/// A standard deviation: 2 significant digits ([`sig`]).
pub fn std_dev(v: f64) -> String {
    sig(v, 2)
}

/// An estimate with its standard deviation, `30.83 ± 3.5`; the estimate alone when `std` is `None`.
pub fn pm(v: f64, std: Option<f64>) -> String {
    match std {
        Some(s) => format!("{} ± {}", estimate(v), std_dev(s)),
        None => estimate(v),
    }
}

/// An optional estimate: [`estimate`], or `n/a` when there is none.
pub fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".into(), estimate)
}
