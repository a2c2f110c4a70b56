//! Reading a whole input file with a bound on the bytes read *as they are read*.
//!
//! A size taken from the file's metadata is 0 for a device, a pipe or `/proc` files, so it cannot bound
//! `--data /dev/zero` or a FIFO that never ends; [`read_bounded`] reads through `Read::take(max + 1)`
//! and refuses the file as soon as one byte more than `max` has come. Every reader of a whole input file
//! (data, model, plant configuration, input and profile files) goes through it, and every input file is
//! opened by [`open_input`], which refuses what is not a regular file: opening a FIFO with no writer
//! waits forever, and a device or a socket is not a saved record.

use std::io::Read;
use std::path::Path;

use crate::SysidError;

/// The bytes of `path`, at most `max` of them; `what` names the kind of file in the error (e.g.
/// "a data file") and `advice` says what to do (e.g. "split the record").
pub fn read_bounded(
    path: &Path,
    max: u64,
    what: &str,
    advice: &str,
) -> Result<Vec<u8>, SysidError> {
    read_bounded_checked(path, max, what, advice, PREFIX_BYTES, |_| Ok(()))
}

/// Opens an input file (`what` names its kind in the error, e.g. "a data file") for reading, refusing
/// anything but a regular file (a symbolic link is followed) before it is opened: a FIFO (named pipe)
/// would block the open until a writer came, a character or block device or a socket is not a saved
/// record, and a folder cannot be read. The one open of every whole-file input (`--data`, `--model`,
/// `--plant-config`, `--controller`, `--input file:`, `--profile file:`, `calibrate --data`, and the
/// streamed passes of `--stream`); `track --data` and `--follow` read live streams and open their source
/// themselves.
pub fn open_input(path: &Path, what: &str) -> Result<std::fs::File, SysidError> {
    let io = |source| SysidError::Io {
        path: path.to_path_buf(),
        source,
    };
    if path.as_os_str() == "-" && std::fs::metadata(path).is_err() {
        // `-` is standard input for `track --data -` and standard output for `--json -`; here it is
        // a file name (audit s14 L-r: "-: No such file or directory").
        return Err(SysidError::File {
            file: "-".into(),
            message: format!(
                "standard input is not read here: {what} is read from a saved file (only `track --data -` \
                 reads standard input); save the data to a file and give its name"
            ),
        });
    }
    let kind = std::fs::metadata(path).map_err(io)?.file_type();
    if !kind.is_file() {
        return Err(SysidError::File {
            file: path.display().to_string(),
            message: format!(
                "this is {}, not a regular file; {what} is read from a saved file (save the \
                 data to a file first)",
                kind_name(&kind)
            ),
        });
    }
    std::fs::File::open(path).map_err(io)
}

/// "a folder", "a FIFO (named pipe)", ... for the error of [`open_input`].
fn kind_name(kind: &std::fs::FileType) -> &'static str {
    if kind.is_dir() {
        return "a folder";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return "a FIFO (named pipe: opening it would wait for a writer)";
        }
        if kind.is_char_device() {
            return "a character device";
        }
        if kind.is_block_device() {
            return "a block device";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// Bytes looked at by the `check` of [`read_bounded_checked`] before the rest is read.
pub const PREFIX_BYTES: usize = 1 << 16;

/// [`read_bounded`] that first reads up to `prefix` bytes and passes them to `check`, which can refuse
/// the file before the rest is read (binary data where text is expected, a first line with no end:
/// a corrupt data file is refused after its first MiB, not after the size bound).
pub fn read_bounded_checked(
    path: &Path,
    max: u64,
    what: &str,
    advice: &str,
    prefix: usize,
    check: impl FnOnce(&[u8]) -> Result<(), SysidError>,
) -> Result<Vec<u8>, SysidError> {
    read_bounded_lines(path, max, what, advice, prefix, |p| check(p).map(|()| None))
}

/// [`read_bounded_checked`] whose `check` may also ask for a bound on every line of the rest
/// (`Some(bytes)`): the rest is then read in chunks of [`CHUNK_BYTES`] and each chunk's lines measured
/// as it comes (audit s36 H-2: a line longer than the bound that started after the prefix was found
/// only once the whole file had been read into memory — 1.5 GB for a 1.5 GB file).
fn read_bounded_lines(
    path: &Path,
    max: u64,
    what: &str,
    advice: &str,
    prefix: usize,
    check: impl FnOnce(&[u8]) -> Result<Option<usize>, SysidError>,
) -> Result<Vec<u8>, SysidError> {
    let io = |source| SysidError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = open_input(path, what)?;
    // The metadata length, when there is one, refuses a large regular file before it is read.
    let known = file
        .metadata()
        .ok()
        .filter(|m| m.is_file())
        .map(|m| m.len());
    if let Some(size) = known.filter(|&s| s > max) {
        return Err(too_large(path, max, what, advice, &format!("{size} bytes")));
    }
    // The file's size reserved at once, fallibly: a file larger than the memory this process may take
    // (a `ulimit -v`, a container's limit) is refused in words, where an infallible reservation
    // aborted the process (audit s36 H-2). `read_to_end` reserves what it grows by fallibly too.
    let size = known.unwrap_or(0).min(max);
    let mut bytes = Vec::new();
    if bytes
        .try_reserve_exact(usize::try_from(size).unwrap_or(usize::MAX))
        .is_err()
    {
        return Err(SysidError::File {
            file: path.display().to_string(),
            message: format!(
                "{size} bytes: {what} of this size cannot be held in memory here (reserving its size \
                 failed: the memory this process may use is smaller); {advice}"
            ),
        });
    }
    let mut file = file.take(max.saturating_add(1));
    (&mut file)
        .take(prefix as u64)
        .read_to_end(&mut bytes)
        .map_err(io)?;
    match check(&bytes)? {
        None => {
            file.read_to_end(&mut bytes).map_err(io)?;
        }
        Some(bound) => {
            let name = path.display().to_string();
            read_lines_bounded(&mut file, &mut bytes, bound, &name)?;
        }
    }
    if bytes.len() as u64 > max {
        return Err(too_large(
            path,
            max,
            what,
            advice,
            &format!("it did not end within {max} bytes (a device or a stream)"),
        ));
    }
    Ok(bytes)
}

/// The chunk in which [`read_bounded_lines`] reads and measures the lines of a file after its prefix,
/// bytes: a line beyond the bound is found at most this many bytes after its bound is crossed.
pub const CHUNK_BYTES: usize = 1 << 20;

/// Appends the rest of `reader` to `bytes` (which hold what was read of the file before), in chunks of
/// [`CHUNK_BYTES`], refusing a line (bytes between two LF, as [`super::check_line_lengths`] counts
/// them) longer than `bound` as soon as the chunk that crosses the bound has been read: the error of
/// [`super::long_line`], naming `name` and the line. The one error of a long line wherever it starts,
/// in the first MiB or after it (audit s36 H-2).
fn read_lines_bounded<R: Read>(
    reader: &mut R,
    bytes: &mut Vec<u8>,
    bound: usize,
    name: &str,
) -> Result<(), SysidError> {
    let io = |source| SysidError::Io {
        path: name.into(),
        source,
    };
    // The line being measured: its number (1-based) and the offset of its first byte (after a
    // byte-order mark, as the prefix's check counts it).
    let (mut line, mut start) = (1usize, 3 * usize::from(bytes.starts_with(b"\xef\xbb\xbf")));
    let mut scanned = 0usize;
    loop {
        for nl in memchr::memchr_iter(b'\n', &bytes[scanned..]) {
            let at = scanned + nl;
            if at - start > bound {
                return Err(super::long_line(name, line));
            }
            line += 1;
            start = at + 1;
        }
        scanned = bytes.len();
        if scanned - start > bound {
            return Err(super::long_line(name, line));
        }
        let read = (&mut *reader)
            .take(CHUNK_BYTES as u64)
            .read_to_end(bytes)
            .map_err(io)?;
        if read == 0 {
            return Ok(());
        }
    }
}

/// The bytes of a record file (CSV text or a MAT-file; `what` names it in messages), at most
/// [`super::MAX_FILE_BYTES`]: binary bytes that are not a MAT-file are refused within the first MiB +
/// 1 byte, and a line longer than [`super::MAX_LINE_BYTES`] as it is read, within a MiB after its bound
/// wherever it starts (a file of zeros or one with no line end would otherwise be read up to the size
/// bound, and its one line copied several times, before the CSV reader refused it: audit s22 H-B2; a long
/// line after the first MiB was found only after the whole file had been read: audit s36 H-2).
pub fn read_data_file(path: &Path, what: &str) -> Result<Vec<u8>, SysidError> {
    let is_mat_name = super::mat::has_mat_name(path);
    read_bounded_lines(
        path,
        super::MAX_FILE_BYTES,
        what,
        "split the record",
        super::MAX_LINE_BYTES + 1,
        |prefix| {
            if is_mat_name || super::mat::is_mat(prefix) {
                return Ok(None);
            }
            // The CSV reader's own first checks (and messages), on the first bytes only.
            let at = |offset: usize, body: &[u8], message: &str| {
                let (line, column) = super::line_col(body, offset);
                SysidError::Parse {
                    file: path.display().to_string(),
                    line,
                    column,
                    message: message.into(),
                }
            };
            super::check_record_kind(prefix, &path.display().to_string(), what)?;
            let body = prefix.strip_prefix(b"\xef\xbb\xbf").unwrap_or(prefix);
            let valid = match std::str::from_utf8(body) {
                Ok(_) => body.len(),
                // A character cut by the end of the prefix is not an error.
                Err(e) if e.error_len().is_none() => e.valid_up_to(),
                Err(e) => {
                    return Err(at(
                        e.valid_up_to(),
                        body,
                        "the file is not UTF-8 text (binary data?); expected CSV",
                    ))
                }
            };
            match body[..valid].iter().position(|&b| b == 0) {
                Some(nul) => Err(at(nul, body, "NUL byte: the file is binary, not CSV text")),
                None => super::check_line_lengths(body, &path.display().to_string()),
            }?;
            Ok(Some(super::MAX_LINE_BYTES))
        },
    )
}

/// [`read_bounded`] as UTF-8 text (a TOML or JSON file); the error names the first byte that is not.
pub fn read_bounded_text(
    path: &Path,
    max: u64,
    what: &str,
    advice: &str,
) -> Result<String, SysidError> {
    let bytes = read_bounded(path, max, what, advice)?;
    // A MAT-file, a Parquet file or UTF-16 text is named as such, by the readers' one sniffing helper
    // (audit s32 L-12: a MAT-file was "byte 132 is not UTF-8 text").
    if let Some(k @ (super::Sniffed::Mat | super::Sniffed::Parquet | super::Sniffed::Utf16)) =
        super::Sniffed::of(&bytes[..bytes.len().min(4096)])
    {
        return Err(SysidError::File {
            file: path.display().to_string(),
            message: format!("this is {}, not {what}", k.describe()),
        });
    }
    String::from_utf8(bytes).map_err(|e| SysidError::File {
        file: path.display().to_string(),
        message: format!(
            "byte {} is not UTF-8 text; expected {what} in text form",
            e.utf8_error().valid_up_to()
        ),
    })
}

fn too_large(path: &Path, max: u64, what: &str, advice: &str, got: &str) -> SysidError {
    SysidError::File {
        file: path.display().to_string(),
        message: format!("{got}: {what} may have at most {max} bytes; {advice}"),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    // /dev/zero never ends: a device is refused before it is read.
    #[cfg(unix)]
    #[test]
    fn an_endless_device_is_refused_before_it_is_read() {
        let e = read_bounded(Path::new("/dev/zero"), 1000, "a data file", "split it").unwrap_err();
        assert!(e.to_string().contains("a character device"), "{e}");
    }

    // `-` (no such file) is said not to be standard input here (audit s14 L-r).
    #[test]
    fn a_dash_is_not_standard_input_here() {
        let e = read_bounded(Path::new("-"), 1000, "a data file", "").unwrap_err();
        assert!(
            e.to_string().contains("-: standard input is not read here"),
            "{e}"
        );
    }

    /// A reader that fails once it is asked for more than the bytes it was given.
    struct Then<'a>(&'a [u8]);

    impl Read for Then<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if self.0.is_empty() && !buf.is_empty() {
                return Err(std::io::Error::other(
                    "read past the end of what the test gave",
                ));
            }
            let n = self.0.len().min(buf.len());
            buf[..n].copy_from_slice(&self.0[..n]);
            self.0 = &self.0[n..];
            Ok(n)
        }
    }

    // Audit s36 H-2: a line longer than the bound that starts after the first 3 MiB (a header, then
    // rows of 100 bytes) is refused as it is read: the reader holds the file only up to two chunks past
    // that line's start and fails on any read beyond, so the long-line error naming line L (counted
    // here: the header and `rows` rows before it) proves the read stopped within them.
    #[test]
    fn a_long_line_after_the_first_mib_is_refused_as_it_is_read() {
        let bound = 1000;
        let row = "0.01,12,3.5".repeat(9); // 99 bytes
        let rows = (3 * CHUNK_BYTES) / 100; // more than the first chunks
        let mut text = String::from("t,u,y\n");
        for _ in 0..rows {
            text.push_str(&row);
            text.push('\n');
        }
        let long_at = 1 + rows + 1;
        text.push_str(&"7".repeat(bound + 1 + 2 * CHUNK_BYTES));
        let (head, rest) = text.as_bytes().split_at(50);
        let mut bytes = head.to_vec();
        let e = read_lines_bounded(&mut Then(rest), &mut bytes, bound, "f.csv").unwrap_err();
        assert_eq!(
            e.to_string(),
            crate::data::long_line("f.csv", long_at).to_string()
        );
        assert!(e.to_string().contains(&format!("f.csv:{long_at}:")), "{e}");
        // The same rows with a line end before the bound are read whole, the last line without an end.
        let mut ok = String::from("t,u,y\n");
        ok.push_str(&format!("{}\n", "1".repeat(bound)));
        ok.push_str(&"2".repeat(bound));
        let mut bytes = Vec::new();
        read_lines_bounded(&mut ok.as_bytes(), &mut bytes, bound, "f.csv").unwrap();
        assert_eq!(bytes, ok.as_bytes());
    }

    // A file of exactly max bytes is read whole; one byte more is refused.
    #[test]
    fn the_bound_is_inclusive() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f");
        std::fs::write(&p, [b'x'; 10]).unwrap();
        assert_eq!(read_bounded(&p, 10, "a file", "").unwrap().len(), 10);
        assert!(read_bounded(&p, 9, "a file", "").is_err());
    }
}
