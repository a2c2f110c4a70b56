//! Numbers as people write them, for the words the libraries produce (warnings, notes) and the
//! reports alike: one rounding rule ([`sig`]), so a warning and a table print an estimate the same way;
//! one exact rule ([`Shortest`]) for numbers printed to be read back (Ts, times, a CSV's cells).

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

/// A number printed exactly and compactly: the shortest decimal that reads back as the same f64, as
/// Rust's `{}` prints it (`0.01`, `2`, `-3.5`), but in exponent form outside 1e-5 ≤ |v| < 1e16
/// (`1e-300`, not 300 digits; `1.5e-7`; `1e20`), as `{:?}` switches (audit s16 L9: a model Ts of
/// 1e-300 printed 300-digit decimals in a message and in a CSV's t column). 0, NaN and ±inf print as
/// `{}` does. For Ts and times in messages, and the cells of the CSV files the tool writes
/// (`sysid_io::push_shortest`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shortest(pub f64);

impl std::fmt::Display for Shortest {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = self.0;
        if v != 0.0 && v.is_finite() && !(1e-5..1e16).contains(&v.abs()) {
            write!(f, "{v:e}")
        } else {
            write!(f, "{v}")
        }
    }
}

/// `v` as [`Shortest`] prints it.
pub fn shortest(v: f64) -> String {
    Shortest(v).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    // Every printed form reads back as the same f64, and is never longer than Rust's `{}` or `{:e}`.
    #[test]
    fn shortest_reads_back_exactly_and_is_never_longer_than_either_standard_form() {
        for v in [
            1e-300,
            0.01,
            1.0 / 3.0,
            2.0,
            -3.5,
            1.5e-7,
            1e-5,
            9.99e-6,
            1e16,
            123456789.125,
            -2.5e18,
            f64::MIN_POSITIVE,
            f64::MAX,
            5e-324,
        ] {
            let s = shortest(v);
            assert_eq!(s.parse::<f64>().unwrap(), v, "{s}");
            assert!(
                s.len() <= format!("{v}").len().max(format!("{v:e}").len()),
                "{s}"
            );
        }
        assert_eq!(shortest(1e-300), "1e-300");
        assert_eq!(shortest(0.01), "0.01");
        assert_eq!(shortest(2.0), "2");
        assert_eq!(shortest(0.0), "0");
    }
}
