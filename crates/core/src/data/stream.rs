//! Long records read in passes with bounded memory (`identify --stream`, `validate --stream`).
//!
//! A [`RecordSource`] hands its samples to a consumer in consecutive chunks, as many times as the
//! consumer asks (one pass per call of [`RecordSource::pass`]); nothing but one chunk of
//! [`CHUNK_ROWS`] samples is held. [`CsvStream`] re-reads a CSV file from the start for every pass:
//! the `csv` crate's [`csv::ByteRecord`] is reused from row to row (no allocation per row) and each cell
//! is parsed by the standard library's `f64` parser (the Eisel–Lemire "fast float" algorithm since Rust
//! 1.55). [`DatasetSource`] passes over a record held in memory (tests, the Python package).
//!
//! What the streaming reader accepts is what [`super::read_record`] accepts (the header, delimiter,
//! decimal comma, quoting, blank-line and ragged-row rules are shared; the first 64 KiB are checked by
//! the in-memory reader itself), with these differences (docs/data.md, "Long records"):
//! - the time column must be uniform within 0.1 % of the **mean** step (t_last − t_0)/(N − 1), which is
//!   also Ts; the in-memory reader compares with the median step ([`super::TimeSteps`] is
//!   [`super::uniform_time`]'s rule sample by sample, with its words). The two agree on a uniform
//!   record and on one with a gap, not on a jitter near 0.1 % (one side of the median more often than
//!   the other moves the mean): the refusal says so and points to `--stream off`
//!   ([`STREAM_TIME_RULE`]; audit s27 L-7);
//! - the reader's notes ([`CsvStream::notes`], [`super::time_notes`]) take the time column's typical
//!   step as the median step of the first 1 MiB, not of the whole column (audit s27 M-2);
//! - `--resample` and MATLAB `.mat` files are refused (they need the whole record);
//! - the input must be a file that can be read again (not standard input or a pipe);
//! - with `--rows A..B` the pass stops at row B: what follows is not read (a fault there is not seen).
//!
//! Rows are located by their byte offset (the `csv` crate's position) as they pass, and a line number is
//! counted from the bytes only for an error or a note ([`record_place`]); a row that holds a byte that is
//! not UTF-8 text or a NUL byte is refused whatever columns are read, as in memory (audit s27 L-1, L-2).
//! - there is no limit on the number of rows or the file size ([`super::MAX_SAMPLES`],
//!   [`super::MAX_FILE_BYTES`] protect the in-memory reader only).

use std::io::{Read, Seek};
use std::path::{Path, PathBuf};

use super::quotes::{quote_error, Place, QuoteFault, QuoteGuard, QuotePlace};
use super::{
    check_ts, csv_err, marked_cell_value, ragged_row, sniff_delimiter, time_fault_message,
    CsvOptions, Dataset, TimeFault, TimeSteps,
};
use crate::error::Setting;
use crate::SysidError;

/// Samples handed to the consumer at a time (two buffers of this many f64: 128 KiB).
pub const CHUNK_ROWS: usize = 8192;

/// Bytes at the start of a CSV file checked by the in-memory reader (header, delimiter, first rows):
/// one line of the longest a CSV line may be ([`super::MAX_LINE_BYTES`]) and one byte more, so that the
/// header is bounded as in the other readers.
pub const PREFIX_BYTES: usize = super::MAX_LINE_BYTES + 1;

/// A reader that refuses a line longer than [`super::MAX_LINE_BYTES`] as its bytes pass (the `csv`
/// crate would grow its record to hold the whole line): `over` is then the byte offset, in what it read,
/// at which that line starts. Lines are not counted as the bytes pass (session 26: splitting every read
/// into its lines was 7 % of a streamed identification): [`line_at`] counts them for the error.
#[derive(Debug)]
struct LineBound<R> {
    inner: R,
    /// Bytes read so far.
    read: u64,
    /// Where the current line starts (an offset into what was read).
    line_start: u64,
    over: Option<u64>,
    /// The rule of quoted cells ([`super::quotes`]): a quoted cell may hold line ends, so the bound on
    /// lines alone would let one cell grow with the file (audit s27 H-1).
    quotes: QuoteGuard,
    /// The quoted cell that broke the rule.
    quote: Option<QuoteFault>,
}

impl<R> LineBound<R> {
    /// Bounds the lines and quoted cells of the CSV text `inner`, whose cells are separated by
    /// `delimiter`.
    fn new(inner: R, delimiter: u8) -> Self {
        LineBound {
            inner,
            read: 0,
            line_start: 0,
            over: None,
            quotes: QuoteGuard::new(delimiter),
            quote: None,
        }
    }
}

impl<R: Read> Read for LineBound<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        let data = &buf[..n];
        let quotes = if n == 0 && !buf.is_empty() {
            self.quotes.end()
        } else {
            self.quotes.feed(data)
        };
        if let Err(fault) = quotes {
            self.quote = Some(fault);
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                "a quoted cell not closed, or longer than the bound of one CSV line",
            ));
        }
        let at = self.read;
        self.read += n as u64;
        // A line from `start` to `end` (its line end excluded) is too long.
        let long = |start: u64, end: u64| end - start > super::MAX_LINE_BYTES as u64;
        // Only the first and the last line end of the bytes read are looked for (both searches stop
        // within a line of about 30 bytes): a line between them is shorter than the read, so it can be
        // too long only in a read longer than the bound, whose line ends are then all looked at.
        let mut over = None;
        match data.iter().position(|&b| b == b'\n') {
            None => {
                if long(self.line_start, self.read) {
                    over = Some(self.line_start);
                }
            }
            Some(first) => {
                if long(self.line_start, at + first as u64) {
                    over = Some(self.line_start);
                } else if n > super::MAX_LINE_BYTES {
                    let mut start = at + first as u64 + 1;
                    for (i, _) in data
                        .iter()
                        .enumerate()
                        .skip(first + 1)
                        .filter(|(_, &b)| b == b'\n')
                    {
                        let end = at + i as u64;
                        if long(start, end) {
                            over = Some(start);
                            break;
                        }
                        start = end + 1;
                    }
                }
                let last = data.iter().rposition(|&b| b == b'\n').unwrap_or(first);
                self.line_start = at + last as u64 + 1;
                if over.is_none() && long(self.line_start, self.read) {
                    over = Some(self.line_start);
                }
            }
        }
        if over.is_some() {
            self.over = over;
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                "a line longer than the bound of one CSV line",
            ));
        }
        Ok(n)
    }
}

/// The number (1-based) of the line that starts at byte `at` of `file` after its first `skip` bytes (a
/// byte-order mark): its line ends before it, counted (the error of a line too long: [`LineBound`]).
fn line_at(mut file: &std::fs::File, skip: u64, at: u64) -> std::io::Result<usize> {
    use std::io::{Seek, SeekFrom};
    file.seek(SeekFrom::Start(skip))?;
    let mut rest = std::io::BufReader::with_capacity(1 << 16, file.take(at));
    let mut lines = 1;
    loop {
        let chunk = std::io::BufRead::fill_buf(&mut rest)?;
        if chunk.is_empty() {
            return Ok(lines);
        }
        lines += chunk.iter().filter(|&&b| b == b'\n').count();
        let used = chunk.len();
        std::io::BufRead::consume(&mut rest, used);
    }
}

/// Where the record that the `csv` crate positions at byte `at` of `file` (after its first `skip` bytes,
/// a byte-order mark) lies: the line it starts on, and its first byte that is not UTF-8 text or is NUL.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct RecordPlace {
    /// The line (1-based) the record starts on.
    line: usize,
    /// The line and byte column (1-based, as the in-memory reader's) of the record's first byte that is
    /// not UTF-8 text, or is NUL (`true`); `None` when none was looked for or found.
    bad: Option<(usize, usize, bool)>,
}

/// Bytes of a record looked at for its first byte that is not text (a few of its lines).
const LOOK_BYTES: u64 = 4 * super::MAX_LINE_BYTES as u64;

/// The [`RecordPlace`] of the record the `csv` crate positions at byte `at` (after the first `skip`
/// bytes); its first byte that is not text is looked for when `look`.
///
/// The crate's position of a record is where the line end before it began (the record before consumed
/// that line end's first byte), and its line count is the `\n`s before that: one short after a CRLF
/// line end, and more after blank lines (audit s27 L-1). Here the line ends and blank lines at `at` are
/// skipped and counted, as the in-memory reader counts lines from byte offsets. Rows are located by that
/// byte offset while they pass; this re-reads the file up to them, on an error or a note only.
fn record_place(
    mut file: &std::fs::File,
    skip: u64,
    at: u64,
    look: bool,
) -> std::io::Result<RecordPlace> {
    use std::io::{BufRead, Seek, SeekFrom};
    file.seek(SeekFrom::Start(skip))?;
    let mut rest = std::io::BufReader::with_capacity(1 << 16, file);
    let newlines = |b: &[u8]| b.iter().filter(|&&c| c == b'\n').count();
    let (mut line, mut pos) = (1usize, 0u64);
    while pos < at {
        let chunk = rest.fill_buf()?;
        if chunk.is_empty() {
            return Ok(RecordPlace { line, bad: None });
        }
        let n = chunk
            .len()
            .min(usize::try_from(at - pos).unwrap_or(usize::MAX));
        line += newlines(&chunk[..n]);
        rest.consume(n);
        pos += n as u64;
    }
    loop {
        let chunk = rest.fill_buf()?;
        let run = chunk
            .iter()
            .take_while(|&&c| c == b'\r' || c == b'\n')
            .count();
        let whole = run == chunk.len() && run > 0;
        line += newlines(&chunk[..run]);
        rest.consume(run);
        if !whole {
            break;
        }
    }
    if !look {
        return Ok(RecordPlace { line, bad: None });
    }
    let mut bytes = Vec::new();
    rest.take(LOOK_BYTES).read_to_end(&mut bytes)?;
    let valid = match std::str::from_utf8(&bytes) {
        Ok(_) => bytes.len(),
        Err(e) => e.valid_up_to(),
    };
    let nul = bytes[..valid].iter().position(|&b| b == 0);
    let (offset, is_nul) = match nul {
        Some(k) => (k, true),
        None if valid < bytes.len() => (valid, false),
        None => return Ok(RecordPlace { line, bad: None }),
    };
    let (l, column) = super::line_col(&bytes, offset);
    Ok(RecordPlace {
        line,
        bad: Some((line + l - 1, column, is_nul)),
    })
}

/// The place (line, column, field) of byte `at` of `file` after its first `skip` bytes (a byte-order
/// mark), in CSV text whose cells are separated by `delimiter` (the error of a quoted cell: [`LineBound`]).
fn place_at(mut file: &std::fs::File, skip: u64, at: u64, delimiter: u8) -> std::io::Result<Place> {
    use std::io::{Seek, SeekFrom};
    file.seek(SeekFrom::Start(skip))?;
    let mut rest = std::io::BufReader::with_capacity(1 << 16, file.take(at));
    let mut place = QuotePlace::new(delimiter);
    loop {
        let chunk = std::io::BufRead::fill_buf(&mut rest)?;
        if chunk.is_empty() {
            return Ok(place.here());
        }
        place.feed(chunk);
        let used = chunk.len();
        std::io::BufRead::consume(&mut rest, used);
    }
}

/// The length and sampling period of a record, known after a complete pass.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shape {
    /// N: number of samples.
    pub rows: usize,
    /// Ts in s.
    pub ts: f64,
}

/// What the streamed reader's refusal of a non-uniform time column adds (audit s27 L-7): its rule is
/// not the in-memory reader's, which may accept the record.
pub const STREAM_TIME_RULE: &str = "; note: --stream compares each step with the mean step, the \
     in-memory reader (--stream off) with the median step, which accepts steps that jitter within \
     0.1 % of it: --stream off may read this record";

/// The consumer of one pass: called with the index k of the chunk's first sample and the chunk's
/// u(k..) and y(k..) (equal lengths, at most [`CHUNK_ROWS`]).
pub type ChunkFn<'a> = dyn FnMut(usize, &[f64], &[f64]) -> Result<(), SysidError> + 'a;

/// A record that can be read from the start as many times as needed, in chunks.
pub trait RecordSource {
    /// Where the data come from, for messages (as [`Dataset::name`]).
    fn name(&self) -> &str;
    /// One pass over the whole record, in order; returns its shape. Fails with the reader's error
    /// (file, line, column) or the consumer's.
    fn pass(&mut self, consume: &mut ChunkFn<'_>) -> Result<Shape, SysidError>;
}

/// A record held in memory, passed in chunks of `chunk` samples.
#[derive(Debug, Clone)]
pub struct DatasetSource<'a> {
    data: &'a Dataset,
    chunk: usize,
}

impl<'a> DatasetSource<'a> {
    /// Passes over `data` in chunks of `chunk` samples (at least 1).
    pub fn new(data: &'a Dataset, chunk: usize) -> Self {
        DatasetSource {
            data,
            chunk: chunk.max(1),
        }
    }
}

impl RecordSource for DatasetSource<'_> {
    fn name(&self) -> &str {
        self.data.name()
    }

    fn pass(&mut self, consume: &mut ChunkFn<'_>) -> Result<Shape, SysidError> {
        let n = self.data.len();
        let mut k = 0;
        while k < n {
            let end = (k + self.chunk).min(n);
            consume(k, &self.data.u()[k..end], &self.data.y()[k..end])?;
            k = end;
        }
        Ok(Shape {
            rows: n,
            ts: self.data.ts(),
        })
    }
}

/// A CSV file read in passes (see the module documentation).
#[derive(Debug, Clone)]
pub struct CsvStream {
    path: PathBuf,
    name: String,
    delimiter: u8,
    has_header: bool,
    bom: bool,
    marks: super::CellMarks,
    headers: Vec<String>,
    ucol: usize,
    ycol: usize,
    /// The time column, when Ts comes from it.
    tcol: Option<usize>,
    ts_given: Option<f64>,
    time_scale: f64,
    rows: Option<super::RowRange>,
    rows_flag: &'static str,
    shape: Option<Shape>,
    /// The file as the first pass found it: a later pass over a changed or replaced file is refused.
    first_pass: Option<Fingerprint>,
    /// The time notes ([`CsvStream::notes`]) and what the first pass needs to make them.
    notes: TimeNoting,
}

/// The reader's notes of a streamed record ([`super::time_notes`], the in-memory reader's notes and
/// words: audit s27 M-2): those the first 1 MiB gives at `open` (dates and times not read under `--ts`)
/// and those of the time column, made from the first pass's [`TimeSteps::facts`].
#[derive(Debug, Clone)]
struct TimeNoting {
    /// Notes known at `open`, then every note once the first pass has ended.
    notes: Vec<String>,
    /// The time column read under `--ts` for its notes only (a fault there ends its scan, no error).
    given_col: Option<usize>,
    /// The median step (s) of the time column in the first 1 MiB: the typical step of the notes.
    reference: f64,
    unit: super::TimeUnit,
}

/// What identifies the content of one pass: the file (device, inode, size, modification time) when it
/// was opened, and a checksum ([`mix`] folded over the bits of every u and y read).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Fingerprint {
    file: FileId,
    checksum: u64,
}

/// A file's identity and version as its metadata tells them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct FileId {
    dev: u64,
    ino: u64,
    len: u64,
    modified: Option<std::time::SystemTime>,
}

impl FileId {
    fn of(meta: &std::fs::Metadata) -> Self {
        #[cfg(unix)]
        let (dev, ino) = {
            use std::os::unix::fs::MetadataExt;
            (meta.dev(), meta.ino())
        };
        #[cfg(not(unix))]
        let (dev, ino) = (0, 0);
        FileId {
            dev,
            ino,
            len: meta.len(),
            modified: meta.modified().ok(),
        }
    }

    /// How `self` differs from the `first` pass's file, in words (`None`: it does not).
    fn change_from(&self, first: &FileId) -> Option<String> {
        if (self.dev, self.ino) != (first.dev, first.ino) {
            Some("it was replaced by another file (a different inode)".into())
        } else if self.len != first.len {
            Some(format!(
                "its size changed from {} to {} bytes",
                first.len, self.len
            ))
        } else if self.modified != first.modified {
            Some("it was modified (a different modification time)".into())
        } else {
            None
        }
    }
}

/// One step of the pass's checksum: `hash` with the bits of `v` folded in, a word at a time (rotate,
/// exclusive or, multiply by an odd constant, as FxHash). Each step is a bijection of `hash` for a given
/// `v` and of `v` for a given `hash`, so a record that differs from another in one value gives another
/// checksum for certain; several changes cancel with a chance of about 2⁻⁶⁴. (FNV-1a, a byte at a time,
/// took about a tenth of a streamed identification's time: session 26.)
fn mix(hash: u64, v: f64) -> u64 {
    (hash.rotate_left(5) ^ v.to_bits()).wrapping_mul(0x517c_c1b7_2722_0a95)
}

/// The checksum of a pass before its first value.
const CHECKSUM_START: u64 = 0xcbf2_9ce4_8422_2325;

/// The checksum a pass over the samples u(k), y(k) finds ([`CsvStream::checksum`]): a record read in
/// memory is compared with a streamed one by it (the validation record that copies the estimation
/// record, audit s27 M-2).
pub fn samples_checksum(u: &[f64], y: &[f64]) -> u64 {
    u.iter()
        .zip(y)
        .fold(CHECKSUM_START, |h, (&uk, &yk)| mix(mix(h, uk), yk))
}

impl CsvStream {
    /// Opens `path` with the reader options `opts`: checks the header and the first rows (the in-memory
    /// reader's rules) and finds the columns. Nothing else is read until [`RecordSource::pass`].
    pub fn open(path: &Path, opts: &CsvOptions) -> Result<Self, SysidError> {
        let name = path.display().to_string();
        let io = |source| SysidError::Io {
            path: path.to_path_buf(),
            source,
        };
        let file = super::bounded::open_input(path, "a streamed record (read several times)")?;
        let meta = file.metadata().map_err(io)?;
        let mut prefix = Vec::with_capacity(PREFIX_BYTES);
        file.take(PREFIX_BYTES as u64)
            .read_to_end(&mut prefix)
            .map_err(io)?;
        let is_mat_name = super::mat::has_mat_name(path);
        if is_mat_name || super::mat::is_mat(&prefix) {
            return Err(SysidError::File {
                file: name,
                message:
                    "streaming reads CSV text; a MATLAB .mat record is read in memory (leave out \
                          --stream)"
                        .into(),
            });
        }
        // A model file, a plant configuration, a Parquet file…: said as the in-memory reader says it.
        super::check_record_kind(&prefix, &name, "a data file")?;
        if opts.resample.is_some() {
            return Err(SysidError::setting(
                Setting::Other("--resample"),
                "given",
                "no --resample with --stream: resampling needs the whole record in memory",
            ));
        }
        // Every reader's bound on a line (the header first), before the prefix is parsed.
        super::check_line_lengths(&prefix, &name)?;
        // The in-memory reader checks the header and the first rows (up to the last whole line).
        let whole = (meta.len() as usize) <= prefix.len();
        let checked = if whole {
            &prefix[..]
        } else {
            let end = prefix.iter().rposition(|&b| b == b'\n').ok_or_else(|| {
                SysidError::File {
                    file: name.clone(),
                    message: format!(
                        "the first line is longer than {PREFIX_BYTES} bytes; expected a CSV header row"
                    ),
                }
            })?;
            &prefix[..=end]
        };
        // A first data row that does not end within the prefix left the header alone in it, which the
        // in-memory reader called "a header but no data rows" (audit s19 L-7): say what it is.
        let rows_in_prefix = checked
            .split(|&b| b == b'\n')
            .filter(|l| !l.trim_ascii().is_empty())
            .count();
        if !whole && rows_in_prefix <= usize::from(!opts.no_header) {
            return Err(SysidError::Parse {
                file: name,
                line: checked.iter().filter(|&&b| b == b'\n').count() + 1,
                column: 1,
                message: format!(
                    "the first data row does not end within the file's first {PREFIX_BYTES} bytes \
                     (--stream checks the header and the first rows there); expected CSV rows such as \
                     0.01,12,3.5"
                ),
            });
        }
        // The prefix of a longer file may end inside a quoted cell that closes later: the pass checks it.
        let table = super::table_of(checked, &name, !opts.no_header, true, None, whole, None)?;
        let (ucol, ycol, ts_given) = table.columns(opts)?;
        let tcol = match ts_given {
            Some(ts) => {
                check_ts(ts)?;
                None
            }
            None => Some(table.time_column(opts, &name)?),
        };
        // The notes of the in-memory reader: under --ts, a time column is read for its notes when the
        // first 1 MiB holds numbers there (else the date-and-time notes of the first row say why not).
        let mut notes = Vec::new();
        let mut given_col = None;
        if let Some(ts) = ts_given {
            let named = opts
                .ts
                .and(table.headers.iter().position(|h| *h == opts.t_col));
            match named.filter(|&c| table.numbers(c).is_ok()) {
                Some(c) => given_col = Some(c),
                None => notes.extend(super::ts_contradiction(&table, opts, ts)?),
            }
            notes.extend(super::unnamed_date_times(&table, opts, &[ucol], ycol, ts));
        }
        let reference = tcol
            .or(given_col)
            .and_then(|c| table.numbers(c).ok())
            .map(|t| {
                t.iter()
                    .map(|v| v * opts.time_unit.seconds())
                    .collect::<Vec<_>>()
            })
            .and_then(|t| super::median_step(&t))
            .unwrap_or(0.0);
        let bom = prefix.starts_with(b"\xef\xbb\xbf");
        let text = std::str::from_utf8(&checked[usize::from(bom) * 3..]).unwrap_or("");
        Ok(CsvStream {
            path: path.to_path_buf(),
            name,
            delimiter: sniff_delimiter(text),
            has_header: !opts.no_header,
            bom,
            marks: table.marks,
            headers: table.headers,
            ucol,
            ycol,
            tcol,
            ts_given,
            time_scale: opts.time_unit.seconds(),
            rows: opts.rows,
            rows_flag: opts.rows_flag,
            shape: None,
            first_pass: None,
            notes: TimeNoting {
                notes,
                given_col,
                reference,
                unit: opts.time_unit,
            },
        })
    }

    /// The reader's notes on the record, in the in-memory reader's words ([`super::read_record`]'s
    /// `Record::notes`): complete once the first pass has ended.
    pub fn notes(&self) -> &[String] {
        &self.notes.notes
    }

    /// The checksum of the u and y values of the first complete pass (`None` before it): equal for two
    /// records that hold the same samples ([`samples_checksum`] of a record in memory).
    pub fn checksum(&self) -> Option<u64> {
        self.first_pass.map(|f| f.checksum)
    }

    /// The time notes of the first pass ([`super::time_notes`]) from its scan of the time column `col`.
    fn time_notes(&self, scan: &TimeSteps, col: usize, ts: f64) -> Vec<String> {
        let column = &self.headers[col];
        scan.facts()
            .map(|f| super::time_notes(&f, self.ts_given, ts, self.notes.unit, column))
            .unwrap_or_default()
    }

    /// The shape found by the first complete pass (`None` before it).
    pub fn shape(&self) -> Option<Shape> {
        self.shape
    }

    /// The error of a file that changed between passes (`how`, in words).
    fn changed(&self, how: &str) -> SysidError {
        SysidError::File {
            file: self.name.clone(),
            message: format!(
                "the file changed between the passes of --stream ({how}): the model would come from \
                 one version and the metrics from another; run again on a file that is not being written"
            ),
        }
    }

    /// `err` (met while reading the pass), or the error of a file that changed while it was being read
    /// when the open `file` no longer matches `opened` (its metadata when the pass opened it): a file
    /// truncated under the reader ends it with a half row, whose "empty cell" at a line past the new
    /// end would blame the data (audit s23 L-B2).
    fn or_changed(&self, err: SysidError, file: &std::fs::File, opened: &FileId) -> SysidError {
        match self.changed_during(file, opened) {
            Some(changed) => changed,
            None => err,
        }
    }

    /// The error of a file that changed while this pass read it (the open `file` against `opened`),
    /// if it did.
    fn changed_during(&self, file: &std::fs::File, opened: &FileId) -> Option<SysidError> {
        let now = FileId::of(&file.metadata().ok()?);
        let how = now.change_from(opened)?;
        Some(SysidError::File {
            file: self.name.clone(),
            message: format!(
                "the file changed while it was being read ({how}): the record would be part of one \
                 version and part of another; run again on a file that is not being written"
            ),
        })
    }

    /// The [`RecordPlace`] of the record at byte `at` (its `csv` position), the file opened again.
    fn place_of(&self, at: u64, look: bool) -> std::io::Result<RecordPlace> {
        let file = std::fs::File::open(&self.path)?;
        record_place(&file, 3 * u64::from(self.bom), at, look)
    }

    /// The in-memory reader's note of a file that may have been cut inside its last number
    /// ([`super::cut_note_of_rows`]), from the rows whose records start at byte offsets `tail` (the
    /// file's last rows, oldest first), read again from the file.
    fn cut_note(&self, tail: &std::collections::VecDeque<u64>) -> std::io::Result<Option<String>> {
        let (Some(&from), Some(&last)) = (tail.front(), tail.back()) else {
            return Ok(None);
        };
        let mut file = std::fs::File::open(&self.path)?;
        file.seek(std::io::SeekFrom::Start(3 * u64::from(self.bom) + from))?;
        let mut bytes = Vec::new();
        file.read_to_end(&mut bytes)?;
        if super::ends_a_line(&bytes) {
            return Ok(None);
        }
        let mut rdr = csv::ReaderBuilder::new()
            .delimiter(self.delimiter)
            .has_headers(false)
            .flexible(true)
            .from_reader(bytes.as_slice());
        let records: Vec<csv::StringRecord> = rdr.records().filter_map(Result::ok).collect();
        let rows: Vec<Vec<&str>> = records
            .iter()
            .map(|r| r.iter().map(trimmed).collect::<Vec<_>>())
            .filter(|r| r.iter().any(|c| !c.is_empty()))
            .collect();
        let file_name = self.path.display().to_string();
        Ok(super::cut_note_of_rows(
            &file_name,
            &self.headers,
            self.line_of(last),
            &rows,
        ))
    }

    /// The line of the record at byte `at` (0 when the file can no longer be read).
    fn line_of(&self, at: u64) -> usize {
        self.place_of(at, false).map_or(0, |p| p.line)
    }

    /// The error at column `col` (0-based) of the record at byte `at` (its `csv` position).
    fn at(&self, at: u64, col: usize, message: String) -> SysidError {
        SysidError::Parse {
            file: self.path.display().to_string(),
            line: self.line_of(at),
            column: col + 1,
            message,
        }
    }

    /// The error of the record at byte `at` that holds a byte that is not UTF-8 text, or a NUL byte: the
    /// in-memory reader's words, at that byte's line and byte column (audit s27 L-2: every byte of the
    /// record is refused, read or not, as in memory).
    fn not_text(&self, at: u64) -> SysidError {
        let place = self.place_of(at, true);
        let (line, column, nul) = match place {
            Ok(RecordPlace { bad: Some(b), .. }) => b,
            Ok(RecordPlace { line, bad: None }) => (line, 1, false),
            Err(_) => (0, 1, false),
        };
        SysidError::Parse {
            file: self.path.display().to_string(),
            line,
            column,
            message: if nul {
                "NUL byte: the file is binary, not CSV text"
            } else {
                "the file is not UTF-8 text (binary data?); expected CSV"
            }
            .into(),
        }
    }

    /// Ts from the time steps of a pass ([`TimeSteps::ts`]), or its fault at its line with the
    /// reader's words ([`time_fault_message`]).
    fn ts_of(&self, scan: &TimeSteps, col: usize) -> Result<f64, SysidError> {
        scan.ts().map_err(|fault| self.time_error(fault, col))
    }

    /// A time fault (whose `k` is the byte offset of its row's record, [`TimeSteps::push`]) as the reader's
    /// error, at the row's line.
    fn time_error(&self, fault: TimeFault, col: usize) -> SysidError {
        let mut message = time_fault_message(&fault);
        if matches!(fault, TimeFault::NonUniformMean { .. }) {
            // --resample needs the whole record in memory.
            message = message.replace(
                "onto a uniform grid,",
                "onto a uniform grid (in memory, without --stream),",
            );
            // The two rules differ on a jitter near 0.1 % (audit s27 L-7): say so, and the way out.
            message.push_str(STREAM_TIME_RULE);
        }
        match fault.sample() {
            Some(at) => self.at(at as u64, col, message),
            None => SysidError::File {
                file: self.name.clone(),
                message,
            },
        }
    }
}

impl RecordSource for CsvStream {
    fn name(&self) -> &str {
        &self.name
    }

    fn pass(&mut self, consume: &mut ChunkFn<'_>) -> Result<Shape, SysidError> {
        let io = |source| SysidError::Io {
            path: self.path.clone(),
            source,
        };
        let mut file = super::bounded::open_input(&self.path, "a streamed record")?;
        let file_id = FileId::of(&file.metadata().map_err(io)?);
        if let Some(change) = self.first_pass.and_then(|f| file_id.change_from(&f.file)) {
            return Err(self.changed(&change));
        }
        let mut checksum = CHECKSUM_START;
        if self.bom {
            let mut skip = [0u8; 3];
            file.read_exact(&mut skip).map_err(io)?;
        }
        let mut rdr = csv::ReaderBuilder::new()
            .delimiter(self.delimiter)
            .has_headers(self.has_header)
            .flexible(true)
            .buffer_capacity(1 << 16)
            .from_reader(LineBound::new(file, self.delimiter));
        let file_name = self.path.display().to_string();
        let width = self.headers.len();
        let (first, end) = match self.rows {
            Some(r) => (r.start.unwrap_or(0), r.end),
            None => (0, None),
        };
        // Time is checked on the first pass only; later passes read u and y.
        let tcol = self.tcol.filter(|_| self.shape.is_none());
        let mut given_col = self.notes.given_col.filter(|_| self.shape.is_none());
        let mut scan = TimeSteps::with_reference(self.notes.reference);
        let mut marks = super::DecimalMarks::default();
        // The largest |u| and |y| of the first pass and where they are (the reader's outlier note).
        let mut largest = [crate::ls::Largest::<u64>::default(); 2];
        // The row's record, lent to a StringRecord while its cells are read, `spare` standing in for
        // it meanwhile: two records swapped, no allocation per row, and no `Option` whose `None` could
        // never be met.
        let mut rec = csv::ByteRecord::new();
        let mut spare = csv::ByteRecord::new();
        let (mut u, mut y) = (
            Vec::with_capacity(CHUNK_ROWS),
            Vec::with_capacity(CHUNK_ROWS),
        );
        let (mut row, mut used, mut chunk_start) = (0usize, 0usize, 0usize);
        // The first pass's last rows (their records' byte offsets) and whether it read to the file's
        // end: the cut-file note reads them again there (`cut_note`).
        let mut tail = std::collections::VecDeque::with_capacity(super::CUT_LOOKBACK + 1);
        let mut to_end = false;
        loop {
            match rdr.read_byte_record(&mut rec) {
                Ok(true) => {}
                Ok(false) => {
                    to_end = true;
                    break;
                }
                Err(e) => {
                    let bound = rdr.get_ref();
                    let skip = 3 * u64::from(self.bom);
                    let e = if let Some(fault) = bound.quote {
                        let place = |at| place_at(&bound.inner, skip, at, self.delimiter);
                        let after = match fault {
                            QuoteFault::TextAfter { at, .. } => Some(place(at).map_err(io)?.line),
                            _ => None,
                        };
                        let opened = place(fault.open()).map_err(io)?;
                        let (headers, has_header) = (&self.headers, self.has_header);
                        quote_error(&file_name, fault, opened, headers, has_header, false, after)
                    } else if let Some(at) = bound.over {
                        let line = line_at(&bound.inner, skip, at).map_err(io)?;
                        return Err(super::long_line(&file_name, line));
                    } else {
                        csv_err(&file_name, e)
                    };
                    return Err(self.or_changed(e, &bound.inner, &file_id));
                }
            }
            // Fields are trimmed here (csv's own trimming allocates a new record per row).
            let blank = |f: &[u8]| f.trim_ascii().is_empty();
            if rec.iter().all(blank) {
                continue; // a blank line or a row of bare delimiters
            }
            // The row's place: the byte offset of its record, made a line only on an error or a note.
            let at = rec.position().map_or(0, csv::Position::byte);
            if let Some(extra) = rec.iter().skip(width).position(|f| !blank(f)) {
                let line = self.line_of(at);
                let e = ragged_row(
                    &file_name,
                    line,
                    width,
                    extra,
                    !self.marks.comma_delimited(),
                );
                return Err(self.or_changed(e, &rdr.get_ref().inner, &file_id));
            }
            if self.shape.is_none() {
                if tail.len() > super::CUT_LOOKBACK {
                    tail.pop_front();
                }
                tail.push_back(at);
            }
            let index = row;
            row += 1;
            if index < first {
                let b = rec.as_slice();
                if !(b.is_ascii() || std::str::from_utf8(b).is_ok()) || has_nul(b) {
                    let e = self.not_text(at);
                    return Err(self.or_changed(e, &rdr.get_ref().inner, &file_id));
                }
                continue;
            }
            if end.is_some_and(|b| index >= b) {
                break;
            }
            // The row is checked as UTF-8 once, whole (csv's StringRecord: an ASCII row at the speed of
            // `is_ascii`), rather than cell by cell (session 26: `from_utf8` per cell was 6 % of a
            // streamed identification), and for a NUL byte; a row that is not text is refused whatever
            // columns are read, at its first such byte, as the in-memory reader refuses it (audit s27 L-2).
            let bytes = std::mem::replace(&mut rec, spare);
            let text = match csv::StringRecord::from_byte_record(bytes) {
                Ok(t) if !has_nul(t.as_slice().as_bytes()) => t,
                _ => {
                    return Err(self.or_changed(self.not_text(at), &rdr.get_ref().inner, &file_id))
                }
            };
            let fields = text.len();
            let mut value = |col: usize| -> Result<f64, SysidError> {
                marked_cell_value(
                    text.get(col).map(trimmed),
                    fields,
                    width,
                    &self.headers[col],
                    self.marks,
                    &mut marks,
                    &|| self.line_of(at),
                    col + 1,
                )
                .map_err(|mut m| {
                    if index == 0 && !self.has_header && super::looks_like_header(text.iter()) {
                        m.push_str(super::NO_HEADER_ON_HEADER_HINT);
                    }
                    let units = (index == 0 && self.has_header)
                        .then(|| super::units_row(&text.iter().collect::<Vec<_>>()))
                        .flatten();
                    match units {
                        Some((column, words)) => self.at(at, column - 1, words),
                        None => self.at(at, col, m),
                    }
                })
            };
            let cells = value(self.ucol).and_then(|uk| Ok((uk, value(self.ycol)?)));
            let (uk, yk) = cells.map_err(|e| self.or_changed(e, &rdr.get_ref().inner, &file_id))?;
            checksum = mix(mix(checksum, uk), yk);
            if self.shape.is_none() {
                largest[0].push(at, uk);
                largest[1].push(at, yk);
            }
            u.push(uk);
            y.push(yk);
            if let Some(tc) = tcol {
                value(tc)
                    .and_then(|t| {
                        scan.push(t * self.time_scale, at as usize)
                            .map_err(|f| self.time_error(f, tc))
                    })
                    .map_err(|e| self.or_changed(e, &rdr.get_ref().inner, &file_id))?;
            } else if let Some(tc) = given_col {
                // Under --ts the column is read for its notes only: a fault ends its scan, except a
                // time that goes back, refused as in memory (`super::time_goes_back`).
                match value(tc).map(|t| scan.push(t * self.time_scale, at as usize)) {
                    Ok(Ok(())) => {}
                    Ok(Err(TimeFault::NotIncreasing { k, t, previous })) if t < previous => {
                        return Err(self.time_error(TimeFault::GoesBack { k, t, previous }, tc));
                    }
                    _ => given_col = None,
                }
            }
            spare = std::mem::replace(&mut rec, text.into_byte_record());
            used += 1;
            if u.len() == CHUNK_ROWS {
                consume(chunk_start, &u, &y)?;
                chunk_start += u.len();
                u.clear();
                y.clear();
            }
        }
        if !u.is_empty() {
            consume(chunk_start, &u, &y)?;
        }
        // A file truncated or appended to under this pass, even at a line's end (audit s23 L-B2).
        if let Some(changed) = self.changed_during(&rdr.get_ref().inner, &file_id) {
            return Err(changed);
        }
        if let Some(r) = self.rows {
            // The in-memory reader's check and message (the end must lie inside the record).
            let range = r.resolve(row, self.rows_flag, &file_name)?;
            if self.shape.is_none() {
                self.name = format!("{file_name}[{}..{}]", range.start, range.end);
            }
        }
        if used == 0 {
            return Err(SysidError::File {
                file: self.name.clone(),
                message: "the file has a header but no data rows".into(),
            });
        }
        let shape = match self.shape {
            Some(s) if s.rows != used => {
                return Err(SysidError::File {
                    file: self.name.clone(),
                    message: format!(
                        "the file changed while it was being read: {used} rows on this pass, {} on the \
                         first",
                        s.rows
                    ),
                })
            }
            Some(s) => s,
            None => Shape {
                rows: used,
                ts: match (self.ts_given, self.tcol) {
                    (Some(ts), _) => ts,
                    (None, Some(tc)) => self.ts_of(&scan, tc)?,
                    (None, None) => unreachable_ts(&self.name)?,
                },
            },
        };
        if self.shape.is_none() && to_end {
            let note = self.cut_note(&tail).map_err(io)?;
            self.notes.notes.extend(note);
        }
        if self.shape.is_none() {
            // The in-memory reader's outlier note (`super::lone_outlier`), u's before y's.
            for (l, col) in largest.iter().zip([self.ucol, self.ycol]) {
                let place = || format!("{file_name}:{}:{}", self.line_of(l.at), col + 1);
                let note = super::outlier_note(l, place, &self.headers[col]);
                self.notes.notes.extend(note);
            }
            match (self.tcol, given_col) {
                (Some(c), _) | (None, Some(c)) => {
                    let notes = self.time_notes(&scan, c, shape.ts);
                    self.notes.notes.extend(notes);
                }
                (None, None) => {}
            }
        }
        match self.first_pass {
            Some(f) if f.checksum != checksum => {
                return Err(self.changed("its u and y values differ from the first pass's"))
            }
            Some(_) => {}
            None => {
                self.first_pass = Some(Fingerprint {
                    file: file_id,
                    checksum,
                })
            }
        }
        self.shape = Some(shape);
        Ok(shape)
    }
}

/// True when `bytes` hold a NUL byte: their smallest byte, a loop without an early exit that the
/// compiler makes a vector minimum (a row of 20–40 bytes: `memchr` per row cost 2.4 % of a streamed
/// identification's instructions, this about a tenth of it; callgrind, audit s27 L-2).
fn has_nul(bytes: &[u8]) -> bool {
    bytes.iter().fold(u8::MAX, |m, &b| m.min(b)) == 0
}

/// `cell.trim()`, without looking at its characters when it starts and ends with a printable ASCII
/// character (neither whitespace nor part of a longer character: nothing to trim), as a number does.
fn trimmed(cell: &str) -> &str {
    match cell.as_bytes() {
        [first, .., last] if first.is_ascii_graphic() && last.is_ascii_graphic() => cell,
        [only] if only.is_ascii_graphic() => cell,
        _ => cell.trim(),
    }
}

/// `open` makes sure that Ts is given or a time column exists; this is the error should that change.
fn unreachable_ts(name: &str) -> Result<f64, SysidError> {
    Err(SysidError::File {
        file: name.to_string(),
        message: "no sampling period: pass --ts".into(),
    })
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn write_record(path: &Path, offset: f64) {
        let mut text = String::from("t,u,y\n");
        for k in 0..50 {
            text.push_str(&format!(
                "{},{},{}\n",
                k as f64 * 0.01,
                k % 3,
                offset + k as f64
            ));
        }
        std::fs::write(path, text).unwrap();
    }

    fn pass(s: &mut CsvStream) -> Result<Shape, SysidError> {
        s.pass(&mut |_, _, _| Ok(()))
    }

    // Audit s22 H-B2: every reader refuses a line longer than MAX_LINE_BYTES = 2^20 bytes, naming its line:
    // a first line with no end (refused from the first MiB + 1 byte the reader looks at), and a data row
    // far beyond that prefix (refused by the streamed pass as its bytes go by, and by the in-memory
    // reader before its rows are parsed). Lines of exactly 2^20 bytes are not refused.
    #[test]
    fn every_reader_bounds_a_line() {
        let dir = tempfile::tempdir().unwrap();
        let bound = 1usize << 20;
        let opts = CsvOptions::default();
        let long = |line: usize| {
            format!(
                "long.csv:{line}:{}: the line is longer than {bound} bytes",
                bound + 1
            )
        };
        let path = dir.path().join("long.csv");
        // No line end at all (3 MiB): the header.
        std::fs::write(&path, "1".repeat(3 * bound)).unwrap();
        let name_of = |e: SysidError| {
            e.to_string()
                .replace(&format!("{}/", dir.path().display()), "")
        };
        let e = name_of(CsvStream::open(&path, &opts).unwrap_err());
        assert!(e.starts_with(&long(1)) && e.contains("header"), "{e}");
        let e = name_of(super::super::read_record(&path, &opts).unwrap_err());
        assert!(e.starts_with(&long(1)), "{e}");
        // 100 000 short rows (beyond the prefix), then a row of 2^20 + 1 bytes at line 100 002.
        let mut text = String::from("t,u,y\n");
        for k in 0..100_000 {
            text.push_str(&format!("{},{},{}\n", k as f64 * 0.01, k % 3, k % 5));
        }
        assert!(text.len() > PREFIX_BYTES);
        let mut ok = text.clone();
        ok.push_str(&format!("300,1,{}\n", "1".repeat(bound - 6)));
        text.push_str(&format!("300,1,{}\n", "1".repeat(bound - 5)));
        std::fs::write(&path, &text).unwrap();
        let mut s = CsvStream::open(&path, &opts).unwrap();
        let e = name_of(pass(&mut s).unwrap_err());
        assert!(e.starts_with(&long(100_002)), "{e}");
        let e = name_of(super::super::read_record(&path, &opts).unwrap_err());
        assert!(e.starts_with(&long(100_002)), "{e}");
        // One byte shorter: the line is read (and its cell refused as a value, not as a line).
        std::fs::write(&path, &ok).unwrap();
        let mut s = CsvStream::open(&path, &opts).unwrap();
        assert!(!name_of(pass(&mut s).unwrap_err()).contains("longer than"));
    }

    // LineBound looks only at the first and last line ends of a read: a read longer than the bound (not
    // made by the csv crate, whose buffer is 64 KiB) has every line end looked at, so a long line between
    // two short ones is found, at its first byte; a line of exactly the bound passes. Through CsvStream,
    // a file with a byte-order mark names the long line's number as the in-memory reader does.
    #[test]
    fn a_long_line_is_found_wherever_the_reads_cut() {
        let bound = super::super::MAX_LINE_BYTES;
        let read_all = |text: &[u8], piece: usize| {
            let mut r = LineBound::new(text, b',');
            let mut buf = vec![0u8; piece];
            loop {
                match r.read(&mut buf) {
                    Ok(0) => return None,
                    Ok(_) => {}
                    Err(_) => return r.over,
                }
            }
        };
        let mut text = b"a\n".to_vec();
        text.extend(std::iter::repeat_n(b'x', bound + 1));
        text.extend(b"\nb\n");
        for piece in [3 * bound, bound / 3, 1 << 16, 7] {
            assert_eq!(read_all(&text, piece), Some(2), "piece {piece}");
        }
        let mut ok = b"a\n".to_vec();
        ok.extend(std::iter::repeat_n(b'x', bound));
        ok.extend(b"\nb\n");
        for piece in [3 * bound, bound / 3, 1 << 16, 7] {
            assert_eq!(read_all(&ok, piece), None, "piece {piece}");
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("bom.csv");
        let mut file = b"\xef\xbb\xbft,u,y\n".to_vec();
        for k in 0..40_000 {
            file.extend(format!("{},{},{}\n", k as f64 * 0.01, k % 3, k % 5).bytes());
        }
        file.extend(format!("400,1,{}\n", "1".repeat(bound)).bytes());
        std::fs::write(&path, &file).unwrap();
        let mut s = CsvStream::open(&path, &CsvOptions::default()).unwrap();
        let e = pass(&mut s).unwrap_err().to_string();
        let mem = super::super::read_record(&path, &CsvOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bom.csv:40002:1048577: the line is longer than"),
            "{e}"
        );
        assert_eq!(e, mem);
    }

    // A file replaced between two passes by another of the same length and shape is refused on the
    // second pass (a model from one file and metrics from another would be silently wrong).
    #[test]
    fn a_file_replaced_between_passes_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        write_record(&path, 0.0);
        let mut s = CsvStream::open(&path, &CsvOptions::default()).unwrap();
        pass(&mut s).unwrap();
        pass(&mut s).unwrap(); // an unchanged file passes again
        let other = dir.path().join("other.csv");
        write_record(&other, 1.0);
        std::fs::rename(&other, &path).unwrap();
        let e = pass(&mut s).unwrap_err().to_string();
        assert!(e.contains("changed between the passes"), "{e}");
    }

    // Audit s23 L-B2: a file truncated while a pass reads it (here from the pass's own consumer, after
    // its first chunk of 8192 rows: deterministic, no race) ends the pass with "the file changed while
    // it was being read", naming both sizes, never an "empty cell" at a line past the new end; the first
    // pass and a later one alike. Truncated at a line's end (a whole number of rows left), the same.
    #[test]
    fn a_file_truncated_under_a_pass_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("big.csv");
        let mut text = String::from("t,u,y\n");
        for k in 0..40_000 {
            text.push_str(&format!("{},{},{}\n", k as f64 * 0.01, k % 3, k % 7));
        }
        let full = text.len();
        // Mid-line (byte 200 001) and at a line's end (the header and the first 2000 rows).
        let at_line_end = text.match_indices('\n').nth(2000).unwrap().0 + 1;
        for (second_pass, cut) in [(false, 200_001), (true, 200_001), (false, at_line_end)] {
            std::fs::write(&path, &text).unwrap();
            let mut s = CsvStream::open(&path, &CsvOptions::default()).unwrap();
            if second_pass {
                pass(&mut s).unwrap();
            }
            let mut once = true;
            let e = s
                .pass(&mut |_, _, _| {
                    if std::mem::take(&mut once) {
                        let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
                        f.set_len(cut as u64).unwrap();
                    }
                    Ok(())
                })
                .unwrap_err()
                .to_string();
            assert!(
                e.contains(&format!(
                    "the file changed while it was being read (its size changed from {full} to {cut} bytes)"
                )),
                "{e}"
            );
            assert!(!e.contains("empty cell"), "{e}");
        }
    }

    // Rewritten in place with the same size and different values: the checksum of the values differs,
    // whatever the modification time says.
    #[test]
    fn a_file_rewritten_in_place_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        write_record(&path, 0.0);
        let mut s = CsvStream::open(&path, &CsvOptions::default()).unwrap();
        pass(&mut s).unwrap();
        let modified = std::fs::metadata(&path).unwrap().modified().unwrap();
        let text = std::fs::read_to_string(&path)
            .unwrap()
            .replace(",2\n", ",7\n");
        let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
        use std::io::Write as _;
        (&f).write_all(text.as_bytes()).unwrap();
        f.set_modified(modified).unwrap();
        drop(f);
        let e = pass(&mut s).unwrap_err().to_string();
        assert!(e.contains("changed between the passes"), "{e}");
    }

    // Audit s21 M-B5: the streamed reader refuses a file that writes both decimal marks as the in-memory
    // reader does, at the point's cell, naming the first decimal comma; a file of decimal commas only
    // passes.
    #[test]
    fn a_file_that_mixes_decimal_marks_is_refused_when_streamed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("mix.csv");
        std::fs::write(&path, "t;u;y\n0;0,98;1\n0,01;1.500;2\n0,02;1;3\n").unwrap();
        let e = CsvStream::open(&path, &CsvOptions::default())
            .and_then(|mut s| pass(&mut s))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("mix.csv:3:2:")
                && e.contains("'1.500'")
                && e.contains("line 2, column 2: '0,98'"),
            "{e}"
        );
        let mem =
            super::super::read_table(&std::fs::read(&path).unwrap(), &path.display().to_string())
                .unwrap_err()
                .to_string();
        assert_eq!(e, mem);
        std::fs::write(&path, "t;u;y\n0;0,98;1\n0,01;1,5;2\n0,02;1;3\n").unwrap();
        let mut s = CsvStream::open(&path, &CsvOptions::default()).unwrap();
        pass(&mut s).unwrap();
    }

    /// The line (1-based) of the first line of `text` that holds `marker`, counted here by splitting
    /// the text at its `\n`s (independent of both readers).
    fn line_holding(text: &[u8], marker: &[u8]) -> usize {
        text.split(|&b| b == b'\n')
            .position(|l| l.windows(marker.len()).any(|w| w == marker))
            .unwrap()
            + 1
    }

    /// The streamed reader's error on `text`, and the in-memory reader's.
    fn both_errors(dir: &Path, text: &[u8], opts: &CsvOptions) -> (String, String) {
        let path = dir.join("r.csv");
        std::fs::write(&path, text).unwrap();
        let streamed = CsvStream::open(&path, opts)
            .and_then(|mut s| pass(&mut s))
            .unwrap_err()
            .to_string();
        let mem = super::super::read_csv(&path, opts).unwrap_err().to_string();
        (streamed, mem)
    }

    #[test]
    fn lines_are_counted_across_crlf_lf_switches_and_blank_lines() {
        // Audit s27 L-1: the line ends change after the first MiB (CRLF, then LF, then blank lines and
        // CRLF again): the csv crate's own line count is one short after each CRLF and blank line.
        let dir = tempfile::tempdir().unwrap();
        let mut pieces: Vec<Vec<u8>> = Vec::new();
        let (mut k, mut bytes) = (0, 0);
        let mut row = |end: &str| {
            k += 1;
            format!("{},{},{}{end}", k as f64 * 0.01, k % 7, k % 5).into_bytes()
        };
        while bytes < (1 << 20) + 1000 {
            pieces.push(row("\r\n"));
            bytes += pieces.last().unwrap().len();
        }
        let crlf_end = pieces.len();
        pieces.extend((0..100).map(|_| row("\n")));
        let lf_end = pieces.len();
        pieces.push(b"\r\n\n \r\n".to_vec());
        pieces.extend((0..20).map(|_| row("\r\n")));
        // A cell that is not a number, a ragged row, a time that goes back: each in the LF stretch, just
        // after the blank lines, and near the end; each at its line in both readers.
        for at in [crlf_end + 50, lf_end + 1, pieces.len() - 3] {
            for (bad, marker) in [
                (&b"9e9,oops,1\r\n"[..], &b"oops"[..]),
                (&b"9e9,1,2,extra\n"[..], &b"extra"[..]),
                (&b"0.005,1,2\n"[..], &b"0.005,1,2"[..]),
            ] {
                let mut text = b"t,u,y\r\n".to_vec();
                for (i, p) in pieces.iter().enumerate() {
                    if i == at {
                        text.extend_from_slice(bad);
                    }
                    text.extend_from_slice(p);
                }
                let line = line_holding(&text, marker);
                let (streamed, mem) = both_errors(dir.path(), &text, &CsvOptions::default());
                assert!(
                    streamed.contains(&format!("r.csv:{line}:")),
                    "{streamed} (line {line})"
                );
                assert!(
                    mem.contains(&format!("r.csv:{line}:")),
                    "{mem} (line {line})"
                );
            }
        }
    }

    #[test]
    fn a_row_that_is_not_text_is_refused_in_a_column_that_is_not_read() {
        // Audit s27 L-2: a byte that is not UTF-8, or a NUL, in a column neither u nor y nor t is refused
        // as the in-memory reader refuses it, at the same line and byte column.
        let dir = tempfile::tempdir().unwrap();
        for (bad, nul) in [(&b"ab\xffc"[..], false), (&b"ab\x00c"[..], true)] {
            for skipped in [false, true] {
                let mut text = b"t,u,y,note\r\n".to_vec();
                // Past the first MiB, which `open` checks with the in-memory reader's own rules.
                for k in 0..100_000 {
                    text.extend_from_slice(
                        format!("{},{},{},ok\r\n", k as f64 * 0.01, k % 3, k).as_bytes(),
                    );
                }
                text.extend_from_slice(b"9e3,1,2,");
                text.extend_from_slice(bad);
                text.extend_from_slice(b"\n9e4,1,2,ok\n");
                let line = line_holding(&text, b"9e3,");
                // The bad byte is the 11th of its line ("9e3,1,2,ab" before it).
                let opts = CsvOptions {
                    // The row read, or skipped by --rows (the in-memory reader refuses the file whole).
                    rows: skipped.then_some(super::super::RowRange {
                        start: Some(100_001),
                        end: None,
                    }),
                    ..CsvOptions::default()
                };
                let (streamed, mem) = both_errors(dir.path(), &text, &opts);
                let words = if nul { "NUL byte" } else { "not UTF-8 text" };
                assert!(
                    streamed.contains(&format!("r.csv:{line}:11:")) && streamed.contains(words),
                    "{streamed} (line {line})"
                );
                assert!(
                    mem.contains(&format!("r.csv:{line}:11:")) && mem.contains(words),
                    "{mem}"
                );
            }
        }
    }
}
