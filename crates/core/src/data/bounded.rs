//! Reading a whole input file with a bound on the bytes read *as they are read*.
//!
//! A size taken from the file's metadata is 0 for a device, a pipe or `/proc` files, so it cannot bound
//! `--data /dev/zero` or a FIFO that never ends; [`read_bounded`] reads through `Read::take(max + 1)`
//! and refuses the file as soon as one byte more than `max` has come. Every reader of a whole input file
//! (data, model, plant configuration, input and profile files) goes through it.

use std::io::Read;
use std::path::Path;

use crate::SysidError;

/// The bytes of `path`, at most `max` of them; `what` names the kind of file in the error (e.g.
/// "a data file") and `advice` says what to do (e.g. "split the record").
pub fn read_bounded(path: &Path, max: u64, what: &str, advice: &str) -> Result<Vec<u8>, SysidError> {
    let io = |source| SysidError::Io {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(io)?;
    // The metadata length, when there is one, refuses a large regular file before it is read.
    let known = file.metadata().ok().filter(|m| m.is_file()).map(|m| m.len());
    if let Some(size) = known.filter(|&s| s > max) {
        return Err(too_large(path, max, what, advice, &format!("{size} bytes")));
    }
    let mut bytes = Vec::with_capacity(known.unwrap_or(0).min(max) as usize);
    file.take(max.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(io)?;
    if bytes.len() as u64 > max {
        return Err(too_large(
            path,
            max,
            what,
            advice,
            "more bytes (a device or a stream that did not end)",
        ));
    }
    Ok(bytes)
}

/// [`read_bounded`] as UTF-8 text (a TOML or JSON file); the error names the first byte that is not.
pub fn read_bounded_text(
    path: &Path,
    max: u64,
    what: &str,
    advice: &str,
) -> Result<String, SysidError> {
    let bytes = read_bounded(path, max, what, advice)?;
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
        message: format!("{got} is more than the {max} bytes {what} may have; {advice}"),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    // /dev/zero never ends and its metadata length is 0: the bound stops the read after max + 1 bytes.
    #[cfg(unix)]
    #[test]
    fn an_endless_device_is_refused_after_the_bound() {
        let e = read_bounded(Path::new("/dev/zero"), 1000, "a data file", "split it").unwrap_err();
        assert!(e.to_string().contains("more than the 1000 bytes"), "{e}");
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
