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

pub use sysid_core::format::sig;

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
