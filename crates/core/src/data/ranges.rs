//! Row ranges of a record (`--rows A..B`, `--val-rows`, `--split F`): which data rows an estimation or a
//! validation uses, so that one file can hold both parts without splitting it by hand.
//!
//! Rows are data rows (the header is not counted), 0-based, half-open: `100..600` is rows 100 to 599,
//! `A..` runs to the end and `..B` starts at row 0 (Rust and Python slices; MATLAB's `z(101:600)`).

use std::ops::Range;
use std::str::FromStr;

use crate::error::Setting;
use crate::{Dataset, SysidError};

/// A half-open range of data rows `A..B`, either end optional (`A..`, `..B`, `..`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct RowRange {
    /// First row A (0-based, included); `None` = row 0.
    pub start: Option<usize>,
    /// Row B after the last one (excluded); `None` = the end of the record.
    pub end: Option<usize>,
}

const EXPECTED: &str =
    "a row range A..B (0-based data rows, B excluded; A.. and ..B allowed), e.g. 0..500";

impl FromStr for RowRange {
    type Err = SysidError;

    fn from_str(s: &str) -> Result<Self, SysidError> {
        let bad = || SysidError::setting(Setting::Other("--rows"), s, EXPECTED);
        let (a, b) = s.trim().split_once("..").ok_or_else(bad)?;
        let end_of = |t: &str| -> Result<Option<usize>, SysidError> {
            let t = t.trim();
            if t.is_empty() {
                Ok(None)
            } else {
                t.parse().map(Some).map_err(|_| bad())
            }
        };
        let r = RowRange {
            start: end_of(a)?,
            end: end_of(b)?,
        };
        if let (Some(a), Some(b)) = (r.start, r.end) {
            if a >= b {
                return Err(bad());
            }
        }
        Ok(r)
    }
}

impl std::fmt::Display for RowRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(a) = self.start {
            write!(f, "{a}")?;
        }
        f.write_str("..")?;
        if let Some(b) = self.end {
            write!(f, "{b}")?;
        }
        Ok(())
    }
}

impl RowRange {
    /// The rows `A..B` of a record of `n` rows; fails (naming `flag` and the file `name`) when the range
    /// reaches past the end or holds no row.
    pub fn resolve(
        &self,
        n: usize,
        flag: &'static str,
        name: &str,
    ) -> Result<Range<usize>, SysidError> {
        let a = self.start.unwrap_or(0);
        let b = self.end.unwrap_or(n);
        if b > n || a >= b {
            return Err(SysidError::setting(
                Setting::Other(flag),
                self,
                &format!("{EXPECTED}, inside the {n} data rows of {name}"),
            ));
        }
        Ok(a..b)
    }
}

impl RowRange {
    /// The rows two ranges of one file share (`None` when they are disjoint); an open end stays open,
    /// since both reach the same end of the file.
    pub fn intersection(&self, other: &RowRange) -> Option<RowRange> {
        let start = self.start.max(other.start);
        let end = match (self.end, other.end) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        };
        match (start, end) {
            (Some(a), Some(b)) if a >= b => None,
            (None, Some(0)) => None,
            _ => Some(RowRange { start, end }),
        }
    }
}

/// The number of estimation rows of `--split F`: ⌊F·N⌋ of N rows, the rest being validation rows; fails
/// unless 0 < F < 1 and both parts hold at least one row.
pub fn split_rows(n: usize, fraction: f64) -> Result<usize, SysidError> {
    let bad = || {
        SysidError::setting(
            Setting::Other("--split"),
            fraction,
            &format!(
                "a fraction F with 0 < F < 1 of the {n} rows for estimation, leaving rows for validation"
            ),
        )
    };
    if !(fraction.is_finite() && fraction > 0.0 && fraction < 1.0) {
        return Err(bad());
    }
    let k = (fraction * n as f64).floor() as usize;
    if k == 0 || k >= n {
        return Err(bad());
    }
    Ok(k)
}

use super::Input;

impl Dataset {
    /// Rows `r` of the record (same Ts); its name says which rows (`file.csv[100..600]`).
    pub fn rows(&self, r: Range<usize>) -> Dataset {
        let r = r.start.min(self.len())..r.end.min(self.len());
        Dataset {
            inputs: self
                .inputs
                .iter()
                .map(|i| Input {
                    name: i.name.clone(),
                    u: i.u[r.clone()].to_vec(),
                })
                .collect(),
            y: self.y[r.clone()].to_vec(),
            ts: self.ts,
            name: format!("{}[{}..{}]", self.name, r.start, r.end),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::RowRange;

    fn r(text: &str) -> RowRange {
        text.parse().unwrap()
    }

    #[test]
    fn overlapping_ranges_share_the_rows_between_the_later_start_and_the_earlier_end() {
        assert_eq!(
            r("0..600").intersection(&r("500..1000")),
            Some(r("500..600"))
        );
        assert_eq!(r("..").intersection(&r("600..1000")), Some(r("600..1000")));
        assert_eq!(r("100..").intersection(&r("..300")), Some(r("100..300")));
        assert_eq!(r("100..").intersection(&r("50..")), Some(r("100..")));
    }

    #[test]
    fn ranges_that_only_touch_share_no_row() {
        assert_eq!(r("0..600").intersection(&r("600..1000")), None);
        assert_eq!(r("600..").intersection(&r("..600")), None);
        assert_eq!(r("..10").intersection(&r("20..")), None);
    }
}
