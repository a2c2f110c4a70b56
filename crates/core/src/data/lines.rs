//! A CSV record read one line at a time, as its lines arrive (`track`: standard input, a file being
//! appended, a serial port), by the rules of the in-memory reader [`super::read_record`]:
//! - the header line is read by that reader itself (byte-order mark, delimiter — a comma, or a semicolon
//!   or a tab when the header has no comma outside its quoted names —, quoted and trimmed names, no empty or duplicate name, the
//!   hints of a missing column);
//! - each data line is split by the `csv` crate with that delimiter and the same quoting, a value beyond
//!   the header's columns is refused (ragged row), a line of bare delimiters is blank;
//! - each cell is read by the in-memory reader's cell parser (spaces and quotes around it, a decimal comma
//!   `0,01` with a semicolon or tab delimiter, finite numbers only); a comma-separated file's quoted
//!   decimal commas (`"1,5"`), which the in-memory reader reads when its rows show them, are refused
//!   here with why: the mark is decided from the header line, which holds no number.
//!
//! What differs: a quoted field cannot span lines (a line is a record), and the caller bounds the length
//! of a line as it reads it.

use std::io::Read;

use super::{
    marked_cell_value, ragged_row, sniff_delimiter, table_of, CsvOptions, DecimalMarks, Table,
};
use crate::error::Setting;
use crate::SysidError;

/// The line being parsed, handed to the `csv` reader (which owns it) one line at a time.
#[derive(Debug, Default)]
struct Feed {
    line: Vec<u8>,
    at: usize,
}

impl Read for Feed {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let rest = &self.line[self.at..];
        let n = rest.len().min(buf.len());
        buf[..n].copy_from_slice(&rest[..n]);
        self.at += n;
        Ok(n)
    }
}

/// A CSV record read line by line (see the module documentation).
#[derive(Debug)]
pub struct CsvLines {
    /// The header (no rows): names, decimal comma, the source's name.
    table: Table,
    rdr: csv::Reader<Feed>,
    rec: csv::ByteRecord,
    /// Bytes handed to `rdr` so far (to check that each line is exactly one record).
    fed: u64,
    /// The decimal marks read so far (a file uses one: [`DecimalMarks`]).
    marks: std::cell::RefCell<DecimalMarks>,
    /// The cell delimiter (to name an unclosed quote's column).
    delimiter: u8,
    /// The digit counts of the cells ([`super::digits`]; `None`: empty) of the last data rows read, at
    /// most [`super::CUT_LOOKBACK`] + 1, the last one last: what [`CsvLines::cut_note`] compares the
    /// last row with.
    recent: std::collections::VecDeque<Vec<Option<usize>>>,
}

impl CsvLines {
    /// The reader of the record whose header row is `line` (without its line end); `name` is the source
    /// in messages (`<stdin>`, a path).
    pub fn from_header(line: &[u8], name: &str) -> Result<Self, SysidError> {
        let table = table_of(line, name, true, false, None, true, None)?;
        let text =
            std::str::from_utf8(line.strip_prefix(b"\xef\xbb\xbf").unwrap_or(line)).unwrap_or("");
        let delimiter = sniff_delimiter(text);
        let rdr = csv::ReaderBuilder::new()
            .delimiter(delimiter)
            .has_headers(false)
            .flexible(true)
            .from_reader(Feed::default());
        Ok(CsvLines {
            table,
            rdr,
            rec: csv::ByteRecord::new(),
            fed: 0,
            marks: Default::default(),
            delimiter,
            recent: Default::default(),
        })
    }

    /// The column names of the header.
    pub fn headers(&self) -> &[String] {
        &self.table.headers
    }

    /// The 0-based indices of the u and y columns of `opts` (different columns), and of the time column:
    /// `Some` when the header names `opts.t_col`, `None` when it does not and `opts.ts` gives Ts;
    /// otherwise the in-memory reader's error.
    pub fn columns(&self, opts: &CsvOptions) -> Result<(usize, usize, Option<usize>), SysidError> {
        let (u, y, _) = self.table.columns(opts)?;
        let t = match self.table.column_index(&opts.t_col, Setting::TCol) {
            Ok(t) => Some(t),
            Err(_) if opts.ts.is_some() => None,
            Err(_) => Some(self.table.time_column(opts, &self.table.name)?),
        };
        Ok((u, y, t))
    }

    /// Splits data line `line` (without its line end), line number `line_no` of the source; `false` for a
    /// blank line or a line of bare delimiters. The cells are then read by [`CsvLines::value`].
    pub fn read_line(&mut self, line: &[u8], line_no: usize) -> Result<bool, SysidError> {
        let name = &self.table.name;
        let feed = self.rdr.get_mut();
        feed.line.clear();
        feed.line.extend_from_slice(line);
        feed.line.push(b'\n');
        feed.at = 0;
        self.fed += line.len() as u64 + 1;
        let whole = match self.rdr.read_byte_record(&mut self.rec) {
            Ok(read) => read && self.rdr.position().byte() == self.fed,
            Err(_) => false,
        };
        // One line, one record: a carriage return inside the line or an unclosed quote would make it
        // several records, or a record that goes on into the next line.
        if !whole || self.rec.iter().any(|f| f.contains(&b'\n')) {
            // A quoted cell still open at the line's end is named with its column, by the rule of
            // every reader ([`super::quotes`]).
            if let Err(fault) = super::quotes::QuoteGuard::check(line, self.delimiter) {
                let mut place = super::quotes::QuotePlace::of(line, self.delimiter, fault.open());
                place.line = line_no;
                place.record = 1;
                let headers = &self.table.headers;
                return Err(super::quotes::quote_error(
                    name, fault, place, headers, true, true, None,
                ));
            }
            return Err(SysidError::Parse {
                file: name.clone(),
                line: line_no,
                column: 1,
                message: "malformed CSV line (an unclosed quote or a carriage return inside the \
                          line); expected one record per line"
                    .into(),
            });
        }
        let blank = |f: &[u8]| f.trim_ascii().is_empty();
        if self.rec.iter().all(blank) {
            return Ok(false);
        }
        let width = self.table.headers.len();
        if let Some(extra) = self.rec.iter().skip(width).position(|f| !blank(f)) {
            return Err(ragged_row(
                name,
                line_no,
                width,
                extra,
                !self.table.marks.comma_delimited(),
            ));
        }
        // The row's digit counts, a row that left the window lending its vector (no allocation per row
        // once the window is full).
        let mut counts = if self.recent.len() > super::CUT_LOOKBACK {
            self.recent.pop_front().unwrap_or_default()
        } else {
            Vec::with_capacity(width)
        };
        counts.clear();
        counts.extend(
            self.rec
                .iter()
                .take(width)
                .map(|f| (!blank(f)).then(|| f.iter().filter(|b| b.is_ascii_digit()).count())),
        );
        self.recent.push_back(counts);
        Ok(true)
    }

    /// The note of a source that ends inside its last row, the one last read by
    /// [`CsvLines::read_line`] (line `line_no`), without a line end (the caller knows that): the
    /// in-memory reader's note of a file that may have been cut inside its last number, by its rule and
    /// in its words ([`super::cut_note`]: the row's last non-empty cell has fewer digits than each of
    /// the same column's cells in the (up to) [`super::CUT_LOOKBACK`] rows before it, at least three).
    /// `None` when the row does not look cut.
    pub fn cut_note(&self, line_no: usize) -> Option<String> {
        let (front, back) = self.recent.as_slices();
        let rows: Vec<&Vec<Option<usize>>> = front.iter().chain(back).collect();
        let (_, previous) = rows.split_last()?;
        let col = self
            .rec
            .iter()
            .take(self.table.headers.len())
            .rposition(|f| !f.trim_ascii().is_empty())?;
        let cell = std::str::from_utf8(self.rec.get(col)?).ok()?.trim();
        let counts: Vec<usize> = previous
            .iter()
            .filter_map(|r| r.get(col).copied().flatten())
            .collect();
        let header = self.table.headers.get(col).map_or("?", String::as_str);
        super::cut_note(&self.table.name, line_no, col, header, cell, &counts)
    }

    /// The number in column `col` of the line last read by [`CsvLines::read_line`] (line `line_no`).
    pub fn value(&self, col: usize, line_no: usize) -> Result<f64, SysidError> {
        let at = |message: String| SysidError::Parse {
            file: self.table.name.clone(),
            line: line_no,
            column: col + 1,
            message,
        };
        let cell = match self.rec.get(col).map(std::str::from_utf8) {
            Some(Err(_)) => {
                return Err(at(
                    "the line is not UTF-8 text (binary data?); expected CSV".into(),
                ))
            }
            Some(Ok(c)) => Some(c.trim()),
            None => None,
        };
        let cname = self.table.headers.get(col).map_or("?", String::as_str);
        marked_cell_value(
            cell,
            self.rec.len(),
            self.table.headers.len(),
            cname,
            self.table.marks,
            &mut self.marks.borrow_mut(),
            &|| line_no,
            col + 1,
        )
        .map_err(at)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opts(ts: Option<f64>) -> CsvOptions {
        CsvOptions {
            ts,
            ..CsvOptions::default()
        }
    }

    // A semicolon-delimited export with a decimal comma, quoted names and a byte-order mark reads as the
    // numbers it writes: 0,01 is 1/100.
    #[test]
    fn a_semicolon_line_with_decimal_commas_reads_its_numbers() {
        let mut r = CsvLines::from_header(b"\xef\xbb\xbf\"t\"; \"u\" ;y", "<test>").unwrap();
        assert_eq!(r.headers(), ["t", "u", "y"]);
        assert_eq!(r.columns(&opts(None)).unwrap(), (1, 2, Some(0)));
        assert!(r.read_line(b"0,01; -3 ;\"2,5\"", 2).unwrap());
        let v: Vec<f64> = (0..3).map(|c| r.value(c, 2).unwrap()).collect();
        assert_eq!(v, [0.01, -3.0, 2.5]);
        assert!(!r.read_line(b" ; ;", 3).unwrap());
        assert!(r.read_line(b"0,02;1;2", 4).unwrap());
        assert_eq!(r.value(0, 4).unwrap(), 0.02);
    }

    // Audit s21 M-B5: a line that writes a point after lines with decimal commas is refused at that
    // cell, naming the first comma (1.500 may mean 1500 in such a file).
    #[test]
    fn a_point_after_decimal_commas_is_refused() {
        let mut r = CsvLines::from_header(b"t;u;y", "<test>").unwrap();
        assert!(r.read_line(b"0;0,98;1", 2).unwrap());
        assert_eq!(r.value(1, 2).unwrap(), 0.98);
        assert!(r.read_line(b"0,01;1.500;1", 3).unwrap());
        let e = r.value(1, 3).unwrap_err().to_string();
        assert!(
            e.starts_with("<test>:3:2:") && e.contains("line 2, column 2: '0,98'"),
            "{e}"
        );
    }

    // A line-by-line reader decides the decimal mark of a comma-separated file from its header alone:
    // a quoted decimal comma (pandas' decimal=',') is refused with why, never read as 1 or 15.
    #[test]
    fn a_quoted_decimal_comma_read_line_by_line_is_refused_with_why() {
        let mut r = CsvLines::from_header(b"\"t\",\"u\"", "<test>").unwrap();
        assert!(r.read_line(b"\"0\",\"1,5\"", 2).unwrap());
        let e = r.value(1, 2).unwrap_err().to_string();
        assert!(
            e.starts_with("<test>:2:2: '1,5' in column 'u' is not a number"),
            "{e}"
        );
        assert!(
            e.contains("none when read line by line as track reads"),
            "{e}"
        );
    }

    #[test]
    fn errors_name_the_line_and_column() {
        let mut r = CsvLines::from_header(b"t,u,y", "<test>").unwrap();
        assert!(r.read_line(b"0,abc,1", 7).unwrap());
        let e = r.value(1, 7).unwrap_err().to_string();
        assert!(e.starts_with("<test>:7:2:") && e.contains("'abc'"), "{e}");
        let e = r.read_line(b"0,1,2,3", 8).unwrap_err().to_string();
        assert!(e.starts_with("<test>:8:4:") && e.contains("ragged"), "{e}");
        let e = r.read_line(b"0,\"1,2", 9).unwrap_err().to_string();
        // The quote opens column u's cell at byte 3 and the line ends before it closes.
        assert!(
            e.starts_with("<test>:9:3:")
                && e.contains("column 'u'")
                && e.contains("end of the line"),
            "{e}"
        );
    }

    #[test]
    fn the_header_is_checked_by_the_in_memory_reader() {
        let dup = CsvLines::from_header(b"t,u,u", "<test>").unwrap_err();
        assert!(
            dup.to_string().contains("duplicate column name 'u'"),
            "{dup}"
        );
        let r = CsvLines::from_header(b"time,u,y", "<test>").unwrap();
        assert_eq!(r.columns(&opts(Some(0.01))).unwrap(), (1, 2, None));
        assert!(r
            .columns(&opts(None))
            .unwrap_err()
            .to_string()
            .contains("--t-col"));
    }
}
