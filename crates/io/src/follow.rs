//! Reading a source that is still being written (`track --follow FILE`, `track --serial`): end of data
//! and read time-outs mean "nothing yet", not "finished".
//!
//! A followed *file* ([`Follow::file`]) is also watched for being replaced under the reader: whenever
//! the reader is at the end of the data (and at least once a second while data flow), the path is
//! looked at again, and reading stops with an error ([`ErrorKind::InvalidData`], saying what happened)
//! when the file was truncated (its size is below what was read), replaced (deleted and created again, or
//! renamed over: another inode) or rewritten (its first bytes differ from those read) — log rotation.
//! Reading on from the old position would skip the new file's first samples and parse a line fragment.
//! `track` then stops; start it again on the new file.

use std::fs::File;
use std::io::{ErrorKind, Read};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// How many of a followed file's first bytes are kept to detect a rewrite.
const HEAD_BYTES: usize = 4096;

/// How often a followed file is checked while data flow.
const CHECK_EVERY: Duration = Duration::from_secs(1);

/// A reader that waits for more data: when the inner reader reports the end of its data (a file
/// not yet appended to) or times out (a serial port), it polls again every `poll` until new bytes come.
/// With an idle time-out it ends (reports end of data) once no byte has come for that long; without
/// one it waits for ever (until the process is stopped).
#[derive(Debug)]
pub struct Follow<R> {
    inner: R,
    idle_timeout: Option<Duration>,
    poll: Duration,
    last_data: Instant,
    watch: Option<Watch>,
}

/// What is known of a followed file: its path, identity, the bytes read and the first of them.
#[derive(Debug)]
struct Watch {
    path: PathBuf,
    id: Option<(u64, u64)>,
    read: u64,
    head: Vec<u8>,
    checked: Instant,
}

#[cfg(unix)]
fn identity(meta: &std::fs::Metadata) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    Some((meta.dev(), meta.ino()))
}

#[cfg(not(unix))]
fn identity(_meta: &std::fs::Metadata) -> Option<(u64, u64)> {
    None
}

impl Watch {
    /// Records `bytes` just read.
    fn saw(&mut self, bytes: &[u8]) {
        if self.head.len() < HEAD_BYTES {
            let take = (HEAD_BYTES - self.head.len()).min(bytes.len());
            self.head.extend_from_slice(&bytes[..take]);
        }
        self.read += bytes.len() as u64;
    }

    /// Whether the file at the path is still the one being read; the error says what happened.
    fn check(&mut self) -> std::io::Result<()> {
        self.checked = Instant::now();
        let stop = |what: String| {
            std::io::Error::new(
                ErrorKind::InvalidData,
                format!(
                    "{what} after {} bytes were read (log rotation?); reading on would mix two files, so \
                     track stops: start it again on the new file",
                    self.read
                ),
            )
        };
        // Deleted and not yet created again: nothing to read, keep waiting.
        let Ok(mut now) = File::open(&self.path) else {
            return Ok(());
        };
        let meta = now.metadata()?;
        if self.id.is_some() && identity(&meta) != self.id {
            return Err(stop(
                "the followed file was replaced (deleted and created again, or renamed over)"
                    .into(),
            ));
        }
        if meta.len() < self.read {
            return Err(stop(format!(
                "the followed file was truncated to {} bytes",
                meta.len()
            )));
        }
        let mut head = Vec::with_capacity(self.head.len());
        (&mut now)
            .take(self.head.len() as u64)
            .read_to_end(&mut head)?;
        if head != self.head {
            return Err(stop(
                "the followed file was rewritten (its first bytes changed)".into(),
            ));
        }
        Ok(())
    }
}

impl<R: Read> Follow<R> {
    /// Follows `inner`, polling every `poll` and ending after `idle_timeout` without new bytes (`None`:
    /// never).
    pub fn new(inner: R, idle_timeout: Option<Duration>, poll: Duration) -> Self {
        Follow {
            inner,
            idle_timeout,
            poll,
            last_data: Instant::now(),
            watch: None,
        }
    }
}

impl Follow<File> {
    /// Follows the file at `path` ([`Follow::new`]), and stops with an error when it is truncated,
    /// replaced or rewritten (see the module documentation).
    pub fn file(
        path: &Path,
        idle_timeout: Option<Duration>,
        poll: Duration,
    ) -> std::io::Result<Self> {
        let file = File::open(path)?;
        let id = identity(&file.metadata()?);
        let mut f = Follow::new(file, idle_timeout, poll);
        f.watch = Some(Watch {
            path: path.to_path_buf(),
            id,
            read: 0,
            head: Vec::new(),
            checked: Instant::now(),
        });
        Ok(f)
    }
}

impl<R: Read> Read for Follow<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        loop {
            let waited = match self.inner.read(buf) {
                Ok(0) => false,
                Ok(n) => {
                    self.last_data = Instant::now();
                    if let Some(w) = &mut self.watch {
                        w.saw(&buf[..n]);
                        if w.checked.elapsed() >= CHECK_EVERY {
                            w.check()?;
                        }
                    }
                    return Ok(n);
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                // A serial port's read time-out: it has already waited.
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => true,
                Err(e) => return Err(e),
            };
            if let Some(w) = &mut self.watch {
                w.check()?;
            }
            if self
                .idle_timeout
                .is_some_and(|t| self.last_data.elapsed() >= t)
            {
                return Ok(0);
            }
            if !waited {
                std::thread::sleep(self.poll);
            }
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use std::io::{BufRead, BufReader, Read, Seek, SeekFrom, Write};

    // A line appended after the reader first hit the end of the file is still read, and the reader
    // ends once the idle time-out has passed without new bytes.
    #[test]
    fn reads_what_is_appended_later_and_ends_after_the_idle_timeout() {
        let mut file = tempfile::NamedTempFile::new().unwrap();
        writeln!(file, "t,u,y").unwrap();
        file.flush().unwrap();
        let path = file.path().to_path_buf();
        let writer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(150));
            writeln!(file, "0,1,2").unwrap();
            file.flush().unwrap();
            file.seek(SeekFrom::End(0)).unwrap();
            file
        });
        let reader = Follow::new(
            std::fs::File::open(&path).unwrap(),
            Some(Duration::from_millis(600)),
            Duration::from_millis(10),
        );
        let start = Instant::now();
        let lines: Vec<String> = BufReader::new(reader).lines().map(|l| l.unwrap()).collect();
        let _file = writer.join().unwrap();
        assert_eq!(lines, ["t,u,y", "0,1,2"]);
        assert!(start.elapsed() >= Duration::from_millis(600));
    }

    /// Follows a file holding `initial` while another thread applies `change` to it after 100 ms;
    /// returns what was read and the error that stopped the reader.
    fn follow_through(
        initial: &str,
        change: impl FnOnce(&std::path::Path) + Send + 'static,
    ) -> (String, std::io::Error) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.csv");
        std::fs::write(&path, initial).unwrap();
        let p = path.clone();
        let writer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            change(&p);
        });
        let reader = Follow::file(
            &path,
            Some(Duration::from_secs(5)),
            Duration::from_millis(10),
        )
        .unwrap();
        let mut out = String::new();
        let e = BufReader::new(reader).read_to_string(&mut out).unwrap_err();
        writer.join().unwrap();
        (out, e)
    }

    // A file truncated and written again (log rotation by copy-truncate) stops the reader with an error
    // that says so, instead of reading the new content from the old position.
    #[test]
    fn a_truncated_file_stops_the_reader() {
        let (_, e) = follow_through("t,u,y\n0,1,2\n0.01,1,2\n", |p| {
            std::fs::write(p, "t,u\n").unwrap(); // shorter than what was read
        });
        assert_eq!(e.kind(), ErrorKind::InvalidData);
        assert!(e.to_string().contains("truncated"), "{e}");
    }

    // A file deleted and created again (another inode), even longer than what was read, is detected.
    #[cfg(unix)]
    #[test]
    fn a_recreated_file_stops_the_reader() {
        let (out, e) = follow_through("t,u,y\n0,1,2\n", |p| {
            let other = p.with_extension("new");
            std::fs::write(&other, "t,u,y\n0,1,2\n0.01,1,2\n0.02,1,2\n").unwrap();
            std::fs::rename(&other, p).unwrap();
        });
        assert!(e.to_string().contains("replaced"), "{e}");
        assert_eq!(out, "t,u,y\n0,1,2\n");
    }

    // Rewritten in place with new, longer content (same inode, larger size): the first bytes differ.
    #[test]
    fn a_rewritten_file_stops_the_reader() {
        let (_, e) = follow_through("t,u,y\n0,1,2\n", |p| {
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .truncate(true)
                .open(p)
                .unwrap();
            f.write_all(b"t,u,y\n5,1,2\n5.01,1,2\n5.02,1,2\n").unwrap();
        });
        // Between the truncation and the write the file may be seen empty (truncated): either is right.
        let m = e.to_string();
        assert!(m.contains("rewritten") || m.contains("truncated"), "{m}");
    }
}
