//! `sysid-io`: writing output files safely — atomically (temporary file in the same folder, then
//! rename), never over one of the run's input files. Shared by the command line, the report and the
//! reproduction pipeline; the libraries that compute never write files. [`Follow`] reads a source that is
//! still being written (`track --follow`).

use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

pub mod follow;
pub use follow::Follow;

/// Why an output could not be written. Options are named as the caller names them (`flag`).
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The operating system refused.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The output path chosen by an option is unusable (a folder, an input file, a missing folder).
    #[error("invalid setting {flag} = {}: {expected}", path.display())]
    Refused {
        /// The option that chose the path, as the caller names it (e.g. `--out`).
        flag: String,
        /// The path.
        path: PathBuf,
        /// What is accepted.
        expected: String,
    },
}

fn refused(flag: &str, path: &Path, expected: impl Into<String>) -> OutputError {
    OutputError::Refused {
        flag: flag.to_string(),
        path: path.to_path_buf(),
        expected: expected.into(),
    }
}

/// Writes `bytes` to `path` atomically: the content goes to a temporary file beside `path` (flushed to
/// disk), which is then renamed over it, so a crash or a failed run never leaves a half-written file and
/// an existing file is either untouched or entirely replaced.
///
/// The new file gets the permissions of the file it replaces, or the usual ones for a new file (0o666
/// less the umask) — not the 0o600 of a bare temporary file. A symbolic link at `path` is replaced by
/// the file, not followed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let io = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    if path.is_dir() {
        return Err(io(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            "is a folder; expected a file name",
        )));
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    builder.prefix(".ipa-sysid-").suffix(".tmp");
    let permissions = match std::fs::symlink_metadata(path) {
        Ok(m) if m.is_file() => Some(m.permissions()),
        _ => default_permissions(),
    };
    if let Some(p) = permissions {
        builder.permissions(p);
    }
    let mut tmp = builder.tempfile_in(dir).map_err(io)?;
    tmp.write_all(bytes).map_err(io)?;
    tmp.as_file().sync_all().map_err(io)?;
    tmp.persist(path).map_err(|e| io(e.error))?;
    // Make the rename itself durable; not every platform or file system can sync a folder.
    if let Ok(d) = std::fs::File::open(dir) {
        let _ = d.sync_all();
    }
    Ok(())
}

/// Writes a CSV table to `path` atomically ([`write_atomic`]) through `csv::Writer` (fields quoted
/// only where needed, `\n` line ends): the `header` row, then every row of `rows`, whose cells the
/// caller has already formatted.
pub fn write_csv<R, C>(path: &Path, header: &[&str], rows: R) -> Result<(), OutputError>
where
    R: IntoIterator,
    R::Item: IntoIterator<Item = C>,
    C: AsRef<[u8]>,
{
    let io = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header).map_err(|e| io(e.into()))?;
    for row in rows {
        w.write_record(row).map_err(|e| io(e.into()))?;
    }
    let bytes = w.into_inner().map_err(|e| io(e.into_error()))?;
    write_atomic(path, &bytes)
}

/// `x` as Rust's `{}` prints it (the shortest decimal that reads back as the same f64), without the
/// general formatter's cost for the common case of a record ([`push_shortest`]).
pub fn format_shortest(x: f64) -> String {
    let mut out = String::with_capacity(16);
    push_shortest(&mut out, x);
    out
}

/// Appends `x` as Rust's `{}` prints it to `out`. Fast path for values with at most three decimals and
/// |x| < 1e9 (sample times, integer commands, encoder counts): for the smallest d in 0..=3 such that
/// n / 10^d == x with n = round(x 10^d), the decimal n · 10^-d reads back as x (the division and the
/// parser both round the same exact quotient correctly), and it is the only one with d decimals
/// (their spacing, 10^-d, far exceeds the spacing of f64 below 1e9), so it is the shortest. Every
/// other value goes through `{}`.
pub fn push_shortest(out: &mut String, x: f64) {
    const SCALE: [f64; 4] = [1.0, 10.0, 100.0, 1000.0];
    if x != 0.0 && x.abs() < 1e9 {
        for (d, &scale) in SCALE.iter().enumerate() {
            let n = (x * scale).round();
            if n / scale == x {
                if n < 0.0 {
                    out.push('-');
                }
                let m = n.abs() as u64;
                let p = 10u64.pow(d as u32);
                let mut digits = itoa::Buffer::new();
                out.push_str(digits.format(m / p));
                if d > 0 {
                    out.push('.');
                    let frac = digits.format(m % p);
                    out.extend(std::iter::repeat_n('0', d - frac.len()));
                    out.push_str(frac);
                }
                return;
            }
        }
    }
    // Writing to a String cannot fail.
    let _ = write!(out, "{x}");
}

/// `x` with one decimal, exactly as `format!("{x:.1}")` ([`push_one_decimal`]).
pub fn format_one_decimal(x: f64) -> String {
    let mut out = String::with_capacity(16);
    push_one_decimal(&mut out, x);
    out
}

/// Appends `x` with one decimal to `out`, exactly as `{:.1}` (the decimal nearest to the exact binary
/// value, ties to even) but without the general formatter's cost for the common case: for 0 <= x <
/// 1e12 whose tenths are not within 1e-3 of a tie, the rounded product 10 x (off the exact one by at
/// most 1.2e-4) rounds to the same integer, printed with a decimal point; every other value (negative,
/// -0, NaN, huge) goes through `{:.1}`.
pub fn push_one_decimal(out: &mut String, x: f64) {
    let q = x * 10.0;
    if x.is_sign_positive() && x < 1e12 && (q - q.floor() - 0.5).abs() > 1e-3 {
        let n = q.round() as u64;
        out.push_str(itoa::Buffer::new().format(n / 10));
        out.push('.');
        out.push(char::from(b'0' + (n % 10) as u8));
    } else {
        let _ = write!(out, "{x:.1}");
    }
}

/// How [`write_formatted_columns_csv`] prints the numbers of a column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NumberFormat {
    /// Rust's `{}`: the shortest decimal that reads back as the same f64 ([`push_shortest`]).
    Shortest,
    /// `{:.1}`: one decimal ([`push_one_decimal`]).
    OneDecimal,
}

impl NumberFormat {
    /// Appends `x` in this format to `out`.
    pub fn push(self, out: &mut String, x: f64) {
        match self {
            NumberFormat::Shortest => push_shortest(out, x),
            NumberFormat::OneDecimal => push_one_decimal(out, x),
        }
    }
}

/// Writes equally long columns of numbers as a CSV table to `path` atomically ([`write_csv`]): the
/// `header` row, then row k holds `columns[j][k]` for every j, each printed with Rust's `{}` (the
/// shortest decimal that reads back as the same f64). Fails, writing nothing, when the header and the
/// columns differ in number or the columns in length.
pub fn write_columns_csv(
    path: &Path,
    header: &[&str],
    columns: &[&[f64]],
) -> Result<(), OutputError> {
    let formatted: Vec<(&[f64], NumberFormat)> = columns
        .iter()
        .map(|&c| (c, NumberFormat::Shortest))
        .collect();
    write_formatted_columns_csv(path, header, &formatted)
}

/// [`write_columns_csv`] with a [`NumberFormat`] per column; the cells are formatted into buffers
/// reused from row to row (no allocation per row), and written through `csv::Writer` as
/// [`write_csv`] does.
pub fn write_formatted_columns_csv(
    path: &Path,
    header: &[&str],
    columns: &[(&[f64], NumberFormat)],
) -> Result<(), OutputError> {
    let n = columns.first().map_or(0, |c| c.0.len());
    if header.len() != columns.len() || columns.iter().any(|c| c.0.len() != n) {
        return Err(OutputError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "{} header names for {} columns of lengths {:?}; expected one name per column and columns of equal length",
                    header.len(),
                    columns.len(),
                    columns.iter().map(|c| c.0.len()).collect::<Vec<_>>()
                ),
            ),
        });
    }
    let io = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut w = csv::Writer::from_writer(Vec::with_capacity(n * columns.len() * 12 + 64));
    w.write_record(header).map_err(|e| io(e.into()))?;
    let mut cells = vec![String::new(); columns.len()];
    for k in 0..n {
        for (cell, &(column, format)) in cells.iter_mut().zip(columns) {
            cell.clear();
            format.push(cell, column[k]);
        }
        w.write_record(&cells).map_err(|e| io(e.into()))?;
    }
    let bytes = w.into_inner().map_err(|e| io(e.into_error()))?;
    write_atomic(path, &bytes)
}

#[cfg(unix)]
fn default_permissions() -> Option<std::fs::Permissions> {
    use std::os::unix::fs::PermissionsExt;
    Some(std::fs::Permissions::from_mode(0o666)) // the umask applies on creation
}

#[cfg(not(unix))]
fn default_permissions() -> Option<std::fs::Permissions> {
    None
}

/// Refuses to write `output` when it is the same file as any of `inputs` (compared after resolving
/// links, so `./a.csv` and `a.csv` are the same file).
pub fn refuse_overwrite_input(
    output: &Path,
    inputs: &[&Path],
    flag: &str,
) -> Result<(), OutputError> {
    let canon = |p: &Path| std::fs::canonicalize(p).ok();
    if let Some(out) = canon(output) {
        for input in inputs {
            if canon(input).as_deref() == Some(out.as_path()) {
                return Err(refused(
                    flag,
                    output,
                    "an output path different from every input file (refusing to overwrite your data)",
                ));
            }
        }
    }
    Ok(())
}

/// Checks before any work that `output` can be written: its folder exists and it is not itself a
/// folder; `flag` names the option in messages.
pub fn check_writable(output: &Path, flag: &str) -> Result<(), OutputError> {
    if output.is_dir() {
        return Err(refused(flag, output, "a file name (this is a folder)"));
    }
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !dir.is_dir() {
        return Err(refused(
            flag,
            output,
            format!(
                "a file in an existing folder ({} does not exist)",
                dir.display()
            ),
        ));
    }
    Ok(())
}
