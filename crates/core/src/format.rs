//! Numbers as people write them, for the words the libraries produce (warnings, notes) and the
//! reports alike: one rounding rule ([`sig`]), so a warning and a table print an estimate the same way.

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
