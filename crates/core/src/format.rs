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

/// A pole's modulus |p| as the tool's verdicts print it: six decimals near the unit circle, where
/// 1.000001 and 0.999999 differ in kind (`1.020000`), scientific with four beyond 1e6 (`1.0000e308`,
/// not 309 digits: audit s28 L-3). NaN and ±inf print as Rust does. The one rule of every "a pole has
/// modulus" message (stability, identify's warnings, simulate, control, tune).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Modulus(pub f64);

impl std::fmt::Display for Modulus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = self.0;
        if p.is_finite() && p.abs() >= 1e6 {
            write!(f, "{p:.4e}")
        } else {
            write!(f, "{p:.6}")
        }
    }
}

/// A string read from a file (a model file's record name, column names, identify's warnings, an
/// input's name) made safe to print on a terminal: every control character — C0 (ESC, CR, NUL, BS,
/// tab, newline, …), DEL, C1 (the 8-bit CSI U+009B …) — and every bidirectional-text control
/// (U+061C, U+200E/F, U+202A–U+202E, U+2066–U+2069) is written as a visible escape (`\u{1b}`, `\r`,
/// `\n`, `\t`, `\u{202e}`), so that a file cannot clear the screen, set the window title or overwrite
/// the warning that quotes it (audit s21 M-B1). Everything else is kept as it is, a plain string
/// unchanged and unallocated. The one function every printer of such a string uses (command line and
/// Python package).
///
/// ```
/// use sysid_core::format::visible;
/// assert_eq!(visible("dryer.csv"), "dryer.csv");
/// assert_eq!(visible("\u{1b}[2Jdo not\r use\0"), "\\u{1b}[2Jdo not\\r use\\u{0}");
/// ```
pub fn visible(s: &str) -> std::borrow::Cow<'_, str> {
    let hidden = |c: char| {
        c.is_control()
            || matches!(c, '\u{061c}' | '\u{200e}' | '\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}')
    };
    if !s.chars().any(hidden) {
        return std::borrow::Cow::Borrowed(s);
    }
    let mut out = String::with_capacity(s.len() + 16);
    for c in s.chars() {
        match c {
            '\n' => out.push_str("\\n"),
            '\r' => out.push_str("\\r"),
            '\t' => out.push_str("\\t"),
            c if hidden(c) => out.extend(c.escape_unicode()),
            c => out.push(c),
        }
    }
    std::borrow::Cow::Owned(out)
}

/// [`visible`] of every line of a message of several lines that quotes a file (the TOML parser's
/// error, whose snippet line is the file's own text: audit s22 M-B5), its line breaks kept as they
/// are (a `\r` before one is escaped).
///
/// ```
/// use sysid_core::format::visible_lines;
/// assert_eq!(visible_lines("at line 3\n3 | m = \"a\u{1b}[2J\""), "at line 3\n3 | m = \"a\\u{1b}[2J\"");
/// ```
pub fn visible_lines(s: &str) -> String {
    s.split('\n').map(visible).collect::<Vec<_>>().join("\n")
}

#[cfg(test)]
mod tests {

    // Audit s28 L-3: 1e308 printed with {:.6} took 309 digits; six decimals stay near the circle.
    #[test]
    fn a_modulus_is_fixed_near_the_circle_and_scientific_far_from_it() {
        assert_eq!(Modulus(1.02).to_string(), "1.020000");
        assert_eq!(Modulus(999_999.5).to_string(), "999999.500000");
        assert_eq!(Modulus(1e308).to_string(), "1.0000e308");
        assert_eq!(Modulus(2.5e6).to_string(), "2.5000e6");
        assert_eq!(Modulus(f64::INFINITY).to_string(), "inf");
    }

    use super::*;

    #[test]
    fn every_control_and_bidi_character_becomes_a_visible_escape_and_plain_text_is_borrowed() {
        use std::borrow::Cow;
        assert!(matches!(visible("dryer.csv [0..148] µ"), Cow::Borrowed(_)));
        // ESC, BEL, CR, NUL, BS, DEL, the 8-bit CSI U+009B and the right-to-left override U+202E.
        assert_eq!(
            visible("a\u{1b}b\u{7}c\rd\0e\u{8}f\u{7f}g\u{9b}h\u{202e}i\tj\nk"),
            "a\\u{1b}b\\u{7}c\\rd\\u{0}e\\u{8}f\\u{7f}g\\u{9b}h\\u{202e}i\\tj\\nk"
        );
        for c in (0u32..0x20).chain(0x7f..0xa0) {
            let s = char::from_u32(c).unwrap().to_string();
            assert!(!visible(&s).chars().any(char::is_control), "{c:#x}");
        }
    }

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
