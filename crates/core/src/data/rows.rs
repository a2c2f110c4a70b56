//! The data rows of a CSV table held in memory, compactly.
//!
//! A `csv::StringRecord` per row costs about 240 bytes for a row of t, u, y whose text is 27 bytes
//! (two heap blocks, their headers and slack, the record's position), so a 74 MB file took 650 MB
//! before any budget was consulted (audit s27 M-1). Here every row's cells, trimmed as the CSV
//! reader gives them, lie one after another in one string, with one end offset per cell and one
//! (line, first cell) pair per row: about the text's size plus 8 bytes per cell and 16 per row,
//! allocated once (the reader counts the lines before it parses them) and fallibly, so that what a
//! file asks for is known and checked against `--max-memory` before it is allocated
//! ([`Rows::bytes_for`]). No crate does this for the `csv` crate's records, hence this module.

use core::ops::Range;

/// The data rows of a table: every row's first `width` cells (the header's width; the cells beyond
/// it are empty, else the row is refused, and are not kept).
#[derive(Debug, Clone, Default)]
pub(crate) struct Rows {
    /// Every kept cell's text, one after another.
    text: String,
    /// The end of every kept cell in `text`, row after row.
    ends: Vec<usize>,
    /// Per row: its line in the file (1-based) and the index in `ends` of its first cell.
    starts: Vec<(usize, usize)>,
    /// The rows in use (`--rows A..B` narrows it without copying).
    window: Range<usize>,
}

/// One row of [`Rows`].
#[derive(Debug, Clone, Copy)]
pub(crate) struct Row<'a> {
    rows: &'a Rows,
    /// Index of the row's first cell in `rows.ends`, and one past its last.
    cells: (usize, usize),
}

impl Rows {
    /// The bytes `lines` rows of at most `width` cells whose text is at most `text_bytes` take here
    /// (what [`Rows::with_capacity`] allocates).
    pub(crate) fn bytes_for(lines: usize, width: usize, text_bytes: usize) -> u64 {
        let word = core::mem::size_of::<usize>() as u64;
        (text_bytes as u64)
            .saturating_add((lines as u64).saturating_mul(word.saturating_mul(width as u64 + 2)))
    }

    /// Room for `lines` rows of at most `width` cells and `text_bytes` bytes of text, or the bytes that
    /// could not be allocated.
    pub(crate) fn with_capacity(
        lines: usize,
        width: usize,
        text_bytes: usize,
    ) -> Result<Rows, u64> {
        let mut rows = Rows::default();
        let fail = || Rows::bytes_for(lines, width, text_bytes);
        rows.text
            .try_reserve_exact(text_bytes)
            .map_err(|_| fail())?;
        rows.ends
            .try_reserve_exact(lines.saturating_mul(width))
            .map_err(|_| fail())?;
        rows.starts.try_reserve_exact(lines).map_err(|_| fail())?;
        Ok(rows)
    }

    /// Appends the row at `line` with `cells` (only the first `width` kept). Within the capacity
    /// reserved this does not allocate; beyond it, it grows as a `Vec` does.
    pub(crate) fn push<'c>(
        &mut self,
        line: usize,
        cells: impl Iterator<Item = &'c str>,
        width: usize,
    ) {
        self.starts.push((line, self.ends.len()));
        for cell in cells.take(width) {
            self.text.push_str(cell);
            self.ends.push(self.text.len());
        }
        self.window = 0..self.starts.len();
    }

    /// Number of rows in use.
    pub(crate) fn len(&self) -> usize {
        self.window.len()
    }

    /// True when no row is in use.
    pub(crate) fn is_empty(&self) -> bool {
        self.window.is_empty()
    }

    /// Keeps only rows `range` (indices into the rows in use).
    pub(crate) fn keep(&mut self, range: Range<usize>) {
        let start = self.window.start + range.start.min(self.len());
        let end = self.window.start + range.end.min(self.len());
        self.window = start..end.max(start);
    }

    /// Row `i` of the rows in use.
    pub(crate) fn get(&self, i: usize) -> Option<(usize, Row<'_>)> {
        if i >= self.len() {
            return None;
        }
        let at = self.window.start + i;
        let (line, first) = self.starts[at];
        let last = self.starts.get(at + 1).map_or(self.ends.len(), |s| s.1);
        Some((
            line,
            Row {
                rows: self,
                cells: (first, last),
            },
        ))
    }

    /// The rows in use with their lines.
    pub(crate) fn iter(&self) -> impl Iterator<Item = (usize, Row<'_>)> + '_ {
        (0..self.len()).filter_map(move |i| self.get(i))
    }
}

impl<'a> Row<'a> {
    /// Number of cells kept (at most the header's width).
    pub(crate) fn len(&self) -> usize {
        self.cells.1 - self.cells.0
    }

    /// Cell `col` (0-based), `None` when the row ends before it.
    pub(crate) fn get(&self, col: usize) -> Option<&'a str> {
        let k = self
            .cells
            .0
            .checked_add(col)
            .filter(|&k| k < self.cells.1)?;
        let start = if k == 0 { 0 } else { self.rows.ends[k - 1] };
        self.rows.text.get(start..self.rows.ends[k])
    }

    /// The cells in order.
    pub(crate) fn iter(&self) -> impl Iterator<Item = &'a str> + 'a {
        let row = *self;
        (0..row.len()).filter_map(move |c| row.get(c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_give_back_their_cells_lines_and_windows() {
        let input: [(usize, &[&str]); 4] = [
            (2, &["0", "1.5", "x"]),
            (3, &["", "2", ""]),
            (5, &["7"]),
            (6, &["a", "b", "c", "", ""]),
        ];
        let mut rows = Rows::with_capacity(4, 3, 64).unwrap();
        for (line, cells) in input {
            rows.push(line, cells.iter().copied(), 3);
        }
        assert_eq!(rows.len(), 4);
        for (i, (line, cells)) in input.iter().enumerate() {
            let (l, row) = rows.get(i).unwrap();
            assert_eq!(l, *line);
            let kept = &cells[..cells.len().min(3)];
            assert_eq!(row.len(), kept.len());
            assert_eq!(row.iter().collect::<Vec<_>>(), kept);
            for (c, cell) in kept.iter().enumerate() {
                assert_eq!(row.get(c), Some(*cell));
            }
            assert_eq!(row.get(kept.len()), None);
        }
        rows.keep(1..3);
        let lines: Vec<usize> = rows.iter().map(|(l, _)| l).collect();
        assert_eq!(lines, [3, 5]);
        assert_eq!(rows.get(1).unwrap().1.get(0), Some("7"));
        assert!(rows.get(2).is_none());
        rows.keep(1..9);
        assert_eq!(rows.len(), 1);
        assert_eq!(rows.get(0).unwrap().0, 5);
    }

    #[test]
    fn a_request_beyond_the_address_space_is_an_error_not_an_abort() {
        let lines = usize::MAX / 4;
        let need = Rows::bytes_for(lines, 3, 10);
        assert_eq!(Rows::with_capacity(lines, 3, 10).unwrap_err(), need);
        assert!(need > u64::from(u32::MAX));
    }
}
