//! The one rule every CSV reader applies to quoted cells (audit s27 H-1).
//!
//! A cell that starts with `"` is quoted (the `csv` crate's rule, RFC 4180): it ends at the next `"` that
//! is not doubled (`""` is a quote inside the cell), and it may hold delimiters and line ends. A quote
//! that is never closed makes the rest of the file one cell: a record of 100 000 rows became a model of
//! its first 1 001 rows, with no word. So, in the in-memory reader ([`super::read_table_with`]), the
//! streaming reader ([`super::stream::CsvStream`]) and the line reader ([`super::lines`], which takes
//! one record per line and refuses a quoted line end anyway):
//! - a quoted cell that is not closed by the end of the file is refused;
//! - a quoted cell longer than [`MAX_LINE_BYTES`] bytes from its opening quote to its closing quote
//!   (the bound of one CSV line) is refused as soon as its first [`MAX_LINE_BYTES`] bytes have been read,
//!   so that no reader holds more than that of one cell (a quoted cell may hold line ends, each line of
//!   it short: the bound on lines alone would let it grow with the file);
//! - a closing quote followed by anything but spaces or tabs before the next delimiter or line end is
//!   refused (RFC 4180): two cells that each open a quote (`"2 inch bore` on rows 1000 and 5000) made the
//!   rows between one cell, spliced out of the record with no word;
//!
//! each with the file, the line and column (byte, 1-based) where the quote opened, and the cell's column
//! name. A `"` inside an unquoted cell (`piston 2" bore`) is an ordinary character, as in the `csv` crate.
//!
//! [`QuoteGuard`] follows only whether a quoted cell is open, looking for quotes with `memchr` (a file
//! with no quote costs one vectorised scan of its bytes); [`QuotePlace`] finds the line, column and
//! field of a fault by reading the bytes before it again, on the error path only.

use super::MAX_LINE_BYTES;

/// A quoted cell that breaks the rule, found by [`QuoteGuard`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum QuoteFault {
    /// The cell whose quote is at byte `open` is not closed by the end of the file.
    Unclosed {
        /// Byte offset of the opening quote.
        open: u64,
    },
    /// The cell whose quote is at byte `open` runs for more than [`MAX_LINE_BYTES`] bytes.
    TooLong {
        /// Byte offset of the opening quote.
        open: u64,
    },
    /// The cell whose quote is at byte `open` is followed after its closing quote by text (byte `at`)
    /// before the next delimiter or line end: the quote that closed it was another cell's opening one
    /// (two unclosed quotes cut the rows between them out of the record: audit s27 H-1).
    TextAfter {
        /// Byte offset of the opening quote.
        open: u64,
        /// Byte offset of the first byte of text after the closing quote.
        at: u64,
    },
}

impl QuoteFault {
    /// Byte offset of the opening quote.
    pub(crate) fn open(self) -> u64 {
        match self {
            QuoteFault::Unclosed { open }
            | QuoteFault::TooLong { open }
            | QuoteFault::TextAfter { open, .. } => open,
        }
    }
}

/// Follows the bytes of CSV text, fed in order, and finds the first quoted cell that breaks the rule.
#[derive(Debug, Clone)]
pub(crate) struct QuoteGuard {
    delimiter: u8,
    /// Bytes fed so far.
    pos: u64,
    /// The last byte fed (a line end before the first: a cell starts there).
    prev: u8,
    /// The opening quote's offset while a quoted cell is open.
    open: Option<u64>,
    /// Inside a quoted cell, the last byte was a quote: the cell's end, or the first of `""`.
    quote_last: bool,
    /// After a closed quoted cell, before its delimiter or line end: its opening quote's offset (only
    /// spaces and tabs may come before the delimiter).
    closed: Option<u64>,
}

impl QuoteGuard {
    /// A guard for text whose cells are separated by `delimiter`.
    pub(crate) fn new(delimiter: u8) -> Self {
        QuoteGuard {
            delimiter,
            pos: 0,
            prev: b'\n',
            open: None,
            quote_last: false,
            closed: None,
        }
    }

    /// Follows the next bytes of the text; the first fault of a cell longer than the bound.
    pub(crate) fn feed(&mut self, data: &[u8]) -> Result<(), QuoteFault> {
        let n = data.len();
        let mut i = 0;
        while i < n {
            if let Some(open) = self.closed {
                let b = data[i];
                if b == self.delimiter || b == b'\n' || b == b'\r' {
                    self.closed = None;
                } else if b == b' ' || b == b'\t' {
                    i += 1;
                } else {
                    return Err(QuoteFault::TextAfter {
                        open,
                        at: self.pos + i as u64,
                    });
                }
                continue;
            }
            match self.open {
                Some(open) if self.quote_last => {
                    self.quote_last = false;
                    if data[i] == b'"' {
                        i += 1; // "" inside the cell
                    } else {
                        // The cell ended at the quote before byte i.
                        self.open = None;
                        self.closed = Some(open);
                        // Its length, both quotes included: (pos + i - 1) - open + 1.
                        if self.pos + i as u64 - open > MAX_LINE_BYTES as u64 {
                            return Err(QuoteFault::TooLong { open });
                        }
                    }
                }
                Some(_) => match memchr::memchr(b'"', &data[i..]) {
                    Some(j) => {
                        i += j + 1;
                        self.quote_last = true;
                    }
                    None => i = n,
                },
                None => match memchr::memchr(b'"', &data[i..]) {
                    Some(j) => {
                        let q = i + j;
                        let before = if q > 0 { data[q - 1] } else { self.prev };
                        if before == self.delimiter || before == b'\n' || before == b'\r' {
                            self.open = Some(self.pos + q as u64);
                            self.quote_last = false;
                        }
                        i = q + 1;
                    }
                    None => i = n,
                },
            }
        }
        if let Some(&last) = data.last() {
            self.prev = last;
        }
        self.pos += n as u64;
        match self.open {
            // More than the bound read since the quote: the cell is longer whatever follows.
            Some(open) if self.pos - open > MAX_LINE_BYTES as u64 => {
                Err(QuoteFault::TooLong { open })
            }
            _ => Ok(()),
        }
    }

    /// At the end of the text: the fault of a quoted cell still open.
    pub(crate) fn end(&self) -> Result<(), QuoteFault> {
        match self.open {
            Some(open) if !self.quote_last => Err(QuoteFault::Unclosed { open }),
            _ => Ok(()),
        }
    }

    /// [`QuoteGuard::feed`] over the whole `text`, then [`QuoteGuard::end`].
    pub(crate) fn check(text: &[u8], delimiter: u8) -> Result<(), QuoteFault> {
        let mut guard = QuoteGuard::new(delimiter);
        guard.feed(text)?;
        guard.end()
    }
}

/// Where a byte lies in CSV text: its line and column, the record and the field it belongs to, found by
/// feeding the text before it (the `csv` crate's rules: blank lines are no record, `\r` and `\n` end a
/// record outside quotes).
#[derive(Debug, Clone)]
pub(crate) struct QuotePlace {
    delimiter: u8,
    pos: u64,
    /// Line (1-based) of the next byte and the offset where that line starts.
    line: usize,
    line_start: u64,
    /// Records ended before the current one (blank lines are no record).
    records: usize,
    /// Field (0-based) of the current record, and whether the record has a byte yet.
    field: usize,
    in_record: bool,
    field_start: bool,
    in_quote: bool,
    quote_last: bool,
}

/// The place of one byte: see [`QuotePlace`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Place {
    /// Line, 1-based.
    pub line: usize,
    /// Byte column in the line, 1-based.
    pub column: usize,
    /// Record, 0-based (the header, when the text has one, is record 0).
    pub record: usize,
    /// Field of the record, 0-based.
    pub field: usize,
}

impl QuotePlace {
    /// A finder for text whose cells are separated by `delimiter`.
    pub(crate) fn new(delimiter: u8) -> Self {
        QuotePlace {
            delimiter,
            pos: 0,
            line: 1,
            line_start: 0,
            records: 0,
            field: 0,
            in_record: false,
            field_start: true,
            in_quote: false,
            quote_last: false,
        }
    }

    /// Follows the next bytes of the text.
    pub(crate) fn feed(&mut self, data: &[u8]) {
        for &b in data {
            let mut unquoted = !self.in_quote;
            if self.in_quote {
                if self.quote_last {
                    self.quote_last = false;
                    if b != b'"' {
                        self.in_quote = false;
                        unquoted = true;
                    }
                } else if b == b'"' {
                    self.quote_last = true;
                } else if b == b'\n' {
                    self.line += 1;
                    self.line_start = self.pos + 1;
                }
            }
            if unquoted {
                if b == self.delimiter {
                    self.field += 1;
                    self.field_start = true;
                    self.in_record = true;
                } else if b == b'\n' || b == b'\r' {
                    self.records += usize::from(self.in_record);
                    self.field = 0;
                    self.field_start = true;
                    self.in_record = false;
                    if b == b'\n' {
                        self.line += 1;
                        self.line_start = self.pos + 1;
                    }
                } else {
                    self.in_quote = b == b'"' && self.field_start;
                    self.field_start = false;
                    self.in_record = true;
                }
            }
            self.pos += 1;
        }
    }

    /// The place of the next byte.
    pub(crate) fn here(&self) -> Place {
        Place {
            line: self.line,
            column: (self.pos - self.line_start) as usize + 1,
            record: self.records,
            field: self.field,
        }
    }

    /// The place of byte `at` of `text`.
    pub(crate) fn of(text: &[u8], delimiter: u8, at: u64) -> Place {
        let mut place = QuotePlace::new(delimiter);
        place.feed(&text[..(at as usize).min(text.len())]);
        place.here()
    }
}

/// The error of `fault` at `place` in file `name`, whose column names are `headers` (`has_header`: the
/// first record is the header row; `per_line`: the reader takes one record per line, `track`'s;
/// `after_line`: the line of a [`QuoteFault::TextAfter`]'s text).
pub(crate) fn quote_error(
    name: &str,
    fault: QuoteFault,
    place: Place,
    headers: &[String],
    has_header: bool,
    per_line: bool,
    after_line: Option<usize>,
) -> crate::SysidError {
    let cell = if has_header && place.record == 0 {
        format!(
            "a quoted name in the header row (field {})",
            place.field + 1
        )
    } else {
        match headers.get(place.field) {
            Some(h) => format!(
                "a quoted cell in column '{}' (field {})",
                super::shorten(h),
                place.field + 1
            ),
            None => format!(
                "a quoted cell in field {}, beyond the header's {} columns",
                place.field + 1,
                headers.len()
            ),
        }
    };
    let what = match fault {
        QuoteFault::Unclosed { .. } => {
            if per_line {
                "opens a quote here that is not closed before the end of the line (this reader takes \
                 one record per line)"
                    .to_string()
            } else {
                "opens a quote here that is not closed before the end of the file (the rest of the \
                 file would be one cell)"
                    .to_string()
            }
        }
        QuoteFault::TextAfter { .. } => format!(
            "opens a quote here whose closing quote{} is followed by other text before the next \
             delimiter: that quote is most likely another cell's opening one, and the rows between \
             would be one cell",
            after_line.map_or(String::new(), |l| format!(" (line {l})"))
        ),
        QuoteFault::TooLong { .. } => format!(
            "opens a quote here that is not closed within {MAX_LINE_BYTES} bytes, the bound of one CSV \
             line (a quoted cell may hold line ends, not more than that)"
        ),
    };
    crate::SysidError::Parse {
        file: name.to_string(),
        line: place.line,
        column: place.column,
        message: format!(
            "{cell} {what}; expected a closing '\"' (a quote inside a quoted cell is written twice, \
             \"2\"\" bore\"; or leave the cell unquoted: 2\" bore)"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // A cell that opens a quote at its start and never closes it is unclosed at the quote's byte.
    #[test]
    fn an_opening_quote_never_closed_is_unclosed_at_its_byte() {
        let text = b"t,u,y,note\n0,1,2,ok\n0.01,1,2,\"2 inch bore\n0.02,1,2,ok\n";
        let open = text.iter().position(|&b| b == b'"').unwrap() as u64;
        assert_eq!(
            QuoteGuard::check(text, b','),
            Err(QuoteFault::Unclosed { open })
        );
        // Line 3, the quote's byte column 10, record 2 (the header is record 0), field 3 (note).
        let place = QuotePlace::of(text, b',', open);
        assert_eq!(
            place,
            Place {
                line: 3,
                column: 10,
                record: 2,
                field: 3
            }
        );
    }

    // RFC 4180: a quoted cell may hold delimiters, line ends and doubled quotes.
    #[test]
    fn closed_quoted_cells_with_line_ends_and_doubled_quotes_pass() {
        let text = b"\"t\",\"u\"\r\n0,\"a,\nb \"\"c\"\"\"\n1,\"\"\n";
        assert_eq!(QuoteGuard::check(text, b','), Ok(()));
        // Fed a byte at a time, the same.
        let mut guard = QuoteGuard::new(b',');
        for b in text {
            guard.feed(std::slice::from_ref(b)).unwrap();
        }
        assert_eq!(guard.end(), Ok(()));
    }

    // Two cells that each open a quote: the second quote closes the first cell and text follows it, so
    // the rows between them would be one cell; spaces after a closing quote are allowed (trimmed).
    #[test]
    fn text_after_a_closing_quote_is_refused_and_spaces_are_not() {
        let text = b"a,b\n1,\"x\n2,ok\n3,\"y\n4,ok\n";
        let open = 6;
        let at = text.iter().rposition(|&b| b == b'"').unwrap() as u64 + 1;
        assert_eq!(
            QuoteGuard::check(text, b','),
            Err(QuoteFault::TextAfter { open, at })
        );
        assert_eq!(QuoteGuard::check(b"a,b\n\"1\" ,\"2\"\t\r\n", b','), Ok(()));
    }

    // A quote inside an unquoted cell is an ordinary character (the csv crate's reading).
    #[test]
    fn a_quote_inside_an_unquoted_cell_is_literal() {
        assert_eq!(QuoteGuard::check(b"a,b\n1,piston 2\" bore\n", b','), Ok(()));
        assert_eq!(QuoteGuard::check(b"a;b\n1; \"x\n", b';'), Ok(()));
        // After a semicolon delimiter the quote opens a cell; a comma is then not a delimiter.
        assert!(QuoteGuard::check(b"a;b\n1;\"x\n", b';').is_err());
        assert_eq!(QuoteGuard::check(b"a;b\n1,\"x\n", b';'), Ok(()));
    }

    // A quoted cell of MAX_LINE_BYTES + 1 bytes between its quotes is too long, however many line ends
    // it holds; one of MAX_LINE_BYTES - 2 (the quotes included: MAX_LINE_BYTES) passes.
    #[test]
    fn a_quoted_cell_longer_than_the_line_bound_is_refused_in_any_feeding() {
        let cell = |inner: usize| {
            let mut t = b"a,b\n1,\"".to_vec();
            t.extend((0..inner).map(|i| if i % 50 == 49 { b'\n' } else { b'x' }));
            t.extend_from_slice(b"\"\n2,3\n");
            t
        };
        let ok = cell(MAX_LINE_BYTES - 2);
        assert_eq!(QuoteGuard::check(&ok, b','), Ok(()));
        let long = cell(MAX_LINE_BYTES + 1);
        assert_eq!(
            QuoteGuard::check(&long, b','),
            Err(QuoteFault::TooLong { open: 6 })
        );
        for size in [1, 7, 4096, 65536] {
            let mut guard = QuoteGuard::new(b',');
            let fault = long
                .chunks(size)
                .try_for_each(|c| guard.feed(c))
                .and_then(|()| guard.end());
            assert_eq!(
                fault,
                Err(QuoteFault::TooLong { open: 6 }),
                "chunks of {size}"
            );
            let mut guard = QuoteGuard::new(b',');
            let fine = ok
                .chunks(size)
                .try_for_each(|c| guard.feed(c))
                .and_then(|()| guard.end());
            assert_eq!(fine, Ok(()), "chunks of {size}");
        }
    }
}
