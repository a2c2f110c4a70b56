//! The optical encoder (AEDR-8300 reading a linear strip): position quantised to its resolution.

/// Quantises the piston position to whole encoder counts.
#[derive(Debug, Clone, PartialEq)]
pub struct Encoder {
    resolution_mm: f64,
    /// 1 / resolution when it is a whole number of counts per mm (then readings are count / that,
    /// which prints as a short decimal), else None.
    counts_per_mm: Option<f64>,
}

impl Encoder {
    /// An encoder with `resolution_mm` mm per count (positive).
    pub fn new(resolution_mm: f64) -> Self {
        let inv = 1.0 / resolution_mm;
        let counts_per_mm = ((inv - inv.round()).abs() < 1e-9 * inv).then(|| inv.round());
        Encoder {
            resolution_mm,
            counts_per_mm,
        }
    }

    /// Encoder count at position `x_mm` (rounded to the nearest count; count 0 at the retracted end).
    pub fn count(&self, x_mm: f64) -> i64 {
        match self.counts_per_mm {
            Some(c) => (x_mm * c).round() as i64,
            None => (x_mm / self.resolution_mm).round() as i64,
        }
    }

    /// The reading y in mm: count times the resolution.
    pub fn read_mm(&self, x_mm: f64) -> f64 {
        let n = self.count(x_mm) as f64;
        match self.counts_per_mm {
            Some(c) => n / c,
            None => n * self.resolution_mm,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // 12.344 mm is 1234.4 counts of 0.01 mm -> 1234 counts -> 12.34 mm; 12.345 -> 1234.5 rounds away.
    #[test]
    fn readings_are_rounded_to_whole_counts() {
        let e = Encoder::new(0.01);
        assert_eq!(e.read_mm(12.344), 12.34);
        assert_eq!(e.read_mm(0.004), 0.0);
        assert_eq!(e.read_mm(199.996), 200.0);
        // 1 mm / 0.3 mm = 3.33 counts -> 3 counts -> 0.9 mm.
        assert!((Encoder::new(0.3).read_mm(1.0) - 0.9).abs() < 1e-12);
    }
}
