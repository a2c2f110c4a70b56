//! Input/output data records and the CSV reader.
//!
//! A CSV file has a header row; columns are chosen by name. The delimiter is a comma, or a semicolon or
//! a tab when the header row has no comma but one of those (as exported by spreadsheets in many locales).
//! Trailing empty fields (as in some benchmark files) are tolerated; every cell that is read must hold a
//! finite number, otherwise the error names the file, line and column.

use std::path::Path;

use crate::SysidError;

/// Upper bound on the number of samples read from one file (keeps hostile inputs from exhausting memory).
pub const MAX_SAMPLES: usize = 50_000_000;

/// A uniformly sampled SISO record: u(k) and y(k), k = 0..N-1, sampled every `ts` seconds.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// Input u(k) (for the IPA: PWM command in counts).
    pub u: Vec<f64>,
    /// Output y(k) (for the IPA: position in mm).
    pub y: Vec<f64>,
    /// Sampling period Ts in s.
    pub ts: f64,
    /// Where the data came from (file name), for messages.
    pub name: String,
}

impl Dataset {
    /// A record from vectors; fails on unequal lengths, non-finite values or a bad Ts.
    pub fn new(u: Vec<f64>, y: Vec<f64>, ts: f64, name: impl Into<String>) -> Result<Self, SysidError> {
        let name = name.into();
        if u.len() != y.len() {
            return Err(SysidError::File {
                file: name,
                message: format!("u has {} samples but y has {}", u.len(), y.len()),
            });
        }
        check_ts(ts)?;
        for (what, v) in [("u", &u), ("y", &y)] {
            if let Some(k) = v.iter().position(|x| !x.is_finite()) {
                return Err(SysidError::File {
                    file: name,
                    message: format!("{what}({k}) = {} is not a finite number", v[k]),
                });
            }
        }
        Ok(Dataset { u, y, ts, name })
    }

    /// Number of samples N.
    pub fn len(&self) -> usize {
        self.u.len()
    }

    /// True when the record holds no sample.
    pub fn is_empty(&self) -> bool {
        self.u.is_empty()
    }
}

fn check_ts(ts: f64) -> Result<(), SysidError> {
    if ts.is_finite() && ts > 0.0 {
        Ok(())
    } else {
        Err(SysidError::setting("--ts", ts, "a positive, finite sampling period in seconds"))
    }
}

/// How to read a CSV record.
#[derive(Debug, Clone, PartialEq)]
pub struct CsvOptions {
    /// Name of the input column (`--u-col`, default `u`).
    pub u_col: String,
    /// Name of the output column (`--y-col`, default `y`).
    pub y_col: String,
    /// Name of the optional time column (`--t-col`, default `t`), used for Ts when `ts` is `None`.
    pub t_col: String,
    /// Sampling period in s (`--ts`); when given, the time column is not needed and not read.
    pub ts: Option<f64>,
    /// Ts to use when `ts` is `None` and the file has no time column (e.g. a saved model's Ts).
    pub fallback_ts: Option<f64>,
}

impl Default for CsvOptions {
    fn default() -> Self {
        CsvOptions { u_col: "u".into(), y_col: "y".into(), t_col: "t".into(), ts: None, fallback_ts: None }
    }
}

/// Reads a record from a CSV file.
pub fn read_csv(path: &Path, opts: &CsvOptions) -> Result<Dataset, SysidError> {
    let bytes = std::fs::read(path).map_err(|source| SysidError::Io { path: path.to_path_buf(), source })?;
    read_csv_bytes(&bytes, &path.display().to_string(), opts)
}

/// Reads a record from CSV text held in memory; `name` is used in messages.
pub fn read_csv_bytes(bytes: &[u8], name: &str, opts: &CsvOptions) -> Result<Dataset, SysidError> {
    let table = read_table(bytes, name)?;
    let ucol = table.column_index(&opts.u_col, "--u-col")?;
    let ycol = table.column_index(&opts.y_col, "--y-col")?;
    let has_t = table.headers.iter().any(|h| *h == opts.t_col);
    let ts_given = opts.ts.or(if has_t { None } else { opts.fallback_ts });
    let tcol = match ts_given {
        Some(_) => None,
        None => Some(table.column_index(&opts.t_col, "--t-col").map_err(|_| SysidError::File {
            file: name.to_string(),
            message: format!(
                "no time column '{}' and no --ts: pass --ts SECONDS or name the time column with --t-col \
                 (columns are: {})",
                opts.t_col,
                table.header_list()
            ),
        })?),
    };
    let u = table.numbers(ucol)?;
    let y = table.numbers(ycol)?;
    let ts = match (ts_given, tcol) {
        (Some(ts), _) => {
            check_ts(ts)?;
            ts
        }
        (None, Some(tc)) => {
            let t = table.numbers(tc)?;
            uniform_ts(&t, &table, tc)?
        }
        (None, None) => unreachable!("tcol is Some when ts is None"),
    };
    Dataset::new(u, y, ts, name)
}

/// A parsed CSV table: header names and raw cells with their line numbers.
#[derive(Debug)]
pub struct Table {
    name: String,
    /// Column names, trimmed and unquoted.
    pub headers: Vec<String>,
    rows: Vec<(usize, csv::StringRecord)>,
}

/// Parses CSV bytes into a [`Table`], checking the header and the shape of every row.
pub fn read_table(bytes: &[u8], name: &str) -> Result<Table, SysidError> {
    let file_err = |message: String| SysidError::File { file: name.to_string(), message };
    if bytes.is_empty() || bytes.iter().all(|b| b.is_ascii_whitespace()) {
        return Err(file_err("the file is empty; expected a header row and data rows".into()));
    }
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let (line, column) = line_col(bytes, e.valid_up_to());
        SysidError::Parse {
            file: name.to_string(),
            line,
            column,
            message: "the file is not UTF-8 text (binary data?); expected CSV".into(),
        }
    })?;
    if text.contains('\0') {
        let (line, column) = line_col(bytes, text.find('\0').unwrap_or(0));
        return Err(SysidError::Parse {
            file: name.to_string(),
            line,
            column,
            message: "NUL byte: the file is binary, not CSV text".into(),
        });
    }
    let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
    let delimiter = if !first.contains(',') && first.contains(';') {
        b';'
    } else if !first.contains(',') && first.contains('\t') {
        b'\t'
    } else {
        b','
    };
    let mut rdr = csv::ReaderBuilder::new()
        .delimiter(delimiter)
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header = rdr.headers().map_err(|e| csv_err(name, e))?.clone();
    let mut headers: Vec<String> = header.iter().map(|h| h.to_string()).collect();
    while headers.last().is_some_and(|h| h.is_empty()) {
        headers.pop();
    }
    if headers.is_empty() {
        return Err(file_err("the header row is empty; expected column names such as u,y".into()));
    }
    for (i, h) in headers.iter().enumerate() {
        if h.is_empty() {
            return Err(SysidError::Parse {
                file: name.to_string(),
                line: 1,
                column: i + 1,
                message: "empty column name in the header row".into(),
            });
        }
        if let Some(j) = headers[..i].iter().position(|g| g == h) {
            return Err(SysidError::Parse {
                file: name.to_string(),
                line: 1,
                column: i + 1,
                message: format!("duplicate column name '{h}' (also column {}); names must be unique", j + 1),
            });
        }
    }
    let mut rows = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(|e| csv_err(name, e))?;
        let line = rec.position().map_or(0, |p| p.line() as usize);
        if rec.iter().all(|f| f.is_empty()) {
            continue; // a blank line or a row of bare delimiters
        }
        if let Some(extra) = rec.iter().skip(headers.len()).position(|f| !f.is_empty()) {
            return Err(SysidError::Parse {
                file: name.to_string(),
                line,
                column: headers.len() + extra + 1,
                message: format!("ragged row: a value beyond the {} columns of the header", headers.len()),
            });
        }
        if rows.len() >= MAX_SAMPLES {
            return Err(file_err(format!("more than {MAX_SAMPLES} data rows; split the record")));
        }
        rows.push((line, rec));
    }
    if rows.is_empty() {
        return Err(file_err("the file has a header but no data rows".into()));
    }
    Ok(Table { name: name.to_string(), headers, rows })
}

fn csv_err(name: &str, e: csv::Error) -> SysidError {
    let (line, column) = e.position().map_or((0, 0), |p| (p.line() as usize, 1));
    SysidError::Parse { file: name.to_string(), line, column, message: format!("malformed CSV: {e}") }
}

fn line_col(bytes: &[u8], offset: usize) -> (usize, usize) {
    let before = &bytes[..offset.min(bytes.len())];
    let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
    let column = offset - before.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1) + 1;
    (line, column)
}

impl Table {
    /// Number of data rows.
    pub fn len(&self) -> usize {
        self.rows.len()
    }

    /// True when there is no data row.
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }

    fn header_list(&self) -> String {
        self.headers.join(", ")
    }

    /// The 0-based index of the column called `col`; `flag` names the option that chose it.
    pub fn column_index(&self, col: &str, flag: &str) -> Result<usize, SysidError> {
        self.headers.iter().position(|h| h == col).ok_or_else(|| SysidError::File {
            file: self.name.clone(),
            message: format!(
                "no column named '{col}' (chosen by {flag}); the header has: {}",
                self.header_list()
            ),
        })
    }

    /// Every cell of column `col` as a finite f64, or an error at the first bad cell.
    pub fn numbers(&self, col: usize) -> Result<Vec<f64>, SysidError> {
        let cname = &self.headers[col];
        self.rows
            .iter()
            .map(|(line, rec)| {
                let err = |message: String| SysidError::Parse {
                    file: self.name.clone(),
                    line: *line,
                    column: col + 1,
                    message,
                };
                let cell = rec.get(col).unwrap_or("");
                if cell.is_empty() {
                    return Err(err(format!("empty cell in column '{cname}'; expected a number")));
                }
                let v: f64 = cell
                    .parse()
                    .map_err(|_| err(format!("'{}' in column '{cname}' is not a number", shorten(cell))))?;
                if !v.is_finite() {
                    return Err(err(format!("'{cell}' in column '{cname}' is not a finite number")));
                }
                Ok(v)
            })
            .collect()
    }

    /// The line number (1-based) of data row `row`.
    pub fn line_of(&self, row: usize) -> usize {
        self.rows[row].0
    }
}

fn shorten(s: &str) -> String {
    if s.chars().count() > 40 {
        format!("{}...", s.chars().take(40).collect::<String>())
    } else {
        s.to_string()
    }
}

/// Ts from a time column: every step must be positive and equal to the mean step within 0.1 %.
fn uniform_ts(t: &[f64], table: &Table, col: usize) -> Result<f64, SysidError> {
    if t.len() < 2 {
        return Err(SysidError::File {
            file: table.name.clone(),
            message: "one sample is not enough to find Ts from the time column; pass --ts".into(),
        });
    }
    let ts = (t[t.len() - 1] - t[0]) / (t.len() - 1) as f64;
    for k in 1..t.len() {
        let dt = t[k] - t[k - 1];
        if dt <= 0.0 || !ts.is_finite() || ts <= 0.0 {
            return Err(SysidError::Parse {
                file: table.name.clone(),
                line: table.line_of(k),
                column: col + 1,
                message: format!(
                    "time {} does not increase after {} on the previous row; time must increase",
                    t[k],
                    t[k - 1]
                ),
            });
        }
        if (dt - ts).abs() > 1e-3 * ts {
            return Err(SysidError::Parse {
                file: table.name.clone(),
                line: table.line_of(k),
                column: col + 1,
                message: format!(
                    "non-uniform sampling: step {dt} s differs from the mean step {ts} s by more than 0.1 %; \
                     resample the record or pass --ts"
                ),
            });
        }
    }
    Ok(ts)
}
