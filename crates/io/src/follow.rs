//! Reading a source that is still being written (`track --follow FILE`, `track --serial`): end of data
//! and read time-outs mean "nothing yet", not "finished".
//!
//! A followed *file* ([`Follow::file`]) is also watched for being changed under the reader: whenever
//! the reader is at the end of the data (and at least once a second while data flow), the path is
//! looked at again. A file **truncated** (its size is below what was read) or **rewritten** in place (its
//! first bytes differ from those read) — log rotation by copy and truncate — is read again from its
//! beginning (after its first line when that is the header line read before), and the note passed to
//! [`Follow::on_restart`] says so. A file **replaced** (renamed away and created again — log rotation
//! by `create`, logrotate's default — deleted and created again, or renamed over: another inode) is
//! followed as `tail -F` does: the descriptor still open is first read to its end (the lines the
//! logger wrote into the renamed file before it reopened its log), then the new file is read from its
//! beginning (after the header line read before when it starts with it again), with a note (audit
//! s27 L-3).

use std::fs::File;
use std::io::{ErrorKind, Read};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Opens the file at a path, with its identity (device, inode).
type Reopen<R> = fn(&Path) -> std::io::Result<(R, Option<(u64, u64)>)>;

/// What a [`Follow`] is told when a followed file is read again from its beginning.
type Note = Box<dyn FnMut(&str) + Send>;

/// What a reader of lines above a [`Follow`] needs to know of its restarts ([`Follow::restarts`]): how
/// many times the followed file was read again from its beginning, and whether the last restart skipped
/// the header line (the first line then returned is the content's line 2). A line read after the count
/// changed is the first line of the new content: line numbers and the time check start again there.
#[derive(Debug, Default)]
pub struct Restarts {
    count: std::sync::atomic::AtomicU64,
    header_skipped: std::sync::atomic::AtomicBool,
}

impl Restarts {
    /// How many times the followed file was read again from its beginning.
    pub fn count(&self) -> u64 {
        self.count.load(std::sync::atomic::Ordering::SeqCst)
    }

    /// Whether the last restart skipped the header line the new content starts with.
    pub fn header_skipped(&self) -> bool {
        self.header_skipped
            .load(std::sync::atomic::Ordering::SeqCst)
    }
}

/// How many of a followed file's first bytes are kept to detect a rewrite.
const HEAD_BYTES: usize = 4096;

/// How often a followed file is checked while data flow.
const CHECK_EVERY: Duration = Duration::from_secs(1);

/// A reader that waits for more data: when the inner reader reports the end of its data (a file
/// not yet appended to) or times out (a serial port), it polls again every `poll` until new bytes come.
/// With an idle time-out it ends (reports end of data) once no byte has come for that long; without
/// one it waits for ever (until the process is stopped).
pub struct Follow<R> {
    inner: R,
    idle_timeout: Option<Duration>,
    poll: Duration,
    last_data: Instant,
    watch: Option<Watch>,
    /// Moves the reader to a byte position (a followed file read again from its beginning).
    seek_to: Option<fn(&mut R, u64) -> std::io::Result<u64>>,
    /// Opens the file now at the followed path (a followed file replaced by another inode).
    reopen: Option<Reopen<R>>,
    /// Told when a followed file is read again from its beginning.
    on_restart: Option<Note>,
    /// The last read found no data: the next data are checked before they are returned.
    idle: bool,
    /// After a restart: the header line to skip if the file starts with it again (not yet decided).
    pending_header: Option<Vec<u8>>,
    /// The restarts, as a reader of lines above this one sees them ([`Follow::restarts`]).
    restarts: std::sync::Arc<Restarts>,
}

impl<R> std::fmt::Debug for Follow<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Follow")
            .field("idle_timeout", &self.idle_timeout)
            .field("poll", &self.poll)
            .field("watch", &self.watch)
            .finish_non_exhaustive()
    }
}

/// What a look at a followed file found.
enum Change {
    /// Still the file being read.
    None,
    /// Truncated or rewritten: read again from the beginning (after `header`, the first line read
    /// before, when the file starts with it again); `what` says what happened.
    Restart { header: Vec<u8>, what: String },
}

/// What is known of a followed file: its path, identity, the bytes read and the first of them.
#[derive(Debug)]
struct Watch {
    path: PathBuf,
    id: Option<(u64, u64)>,
    read: u64,
    head: Vec<u8>,
    checked: Instant,
    /// The path now names another file (another inode): the open descriptor is read to its end,
    /// then the new file is followed.
    replaced: bool,
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

    /// Whether the file at the path is still the one being read: marked `replaced` when it is another
    /// inode (followed once the open descriptor is read to its end), a restart when it was truncated or
    /// rewritten in place.
    fn check(&mut self) -> std::io::Result<Change> {
        self.checked = Instant::now();
        // Deleted and not yet created again: nothing to read, keep waiting.
        let Ok(mut now) = File::open(&self.path) else {
            return Ok(Change::None);
        };
        let meta = now.metadata()?;
        if self.id.is_some() && identity(&meta) != self.id {
            // Replaced: the descriptor still open is read to its end before the new file is followed.
            self.replaced = true;
            return Ok(Change::None);
        }
        let what = if meta.len() < self.read {
            format!(
                "the followed file was truncated to {} bytes after {} were read",
                meta.len(),
                self.read
            )
        } else {
            let mut head = Vec::with_capacity(self.head.len());
            (&mut now)
                .take(self.head.len() as u64)
                .read_to_end(&mut head)?;
            if head == self.head {
                return Ok(Change::None);
            }
            format!(
                "the followed file was rewritten (its first bytes changed) after {} bytes were read",
                self.read
            )
        };
        // Read again from the beginning (after the header line when the file starts with it again:
        // decided by the reader once the file holds that many bytes).
        let header = match self.head.iter().position(|&b| b == b'\n') {
            Some(end) => self.head[..=end].to_vec(),
            None => Vec::new(),
        };
        self.head.clear();
        self.read = 0;
        Ok(Change::Restart { header, what })
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
            seek_to: None,
            reopen: None,
            on_restart: None,
            idle: false,
            pending_header: None,
            restarts: std::sync::Arc::default(),
        }
    }

    /// The restarts of a followed file ([`Restarts`]), shared with whoever reads lines above this
    /// reader (`track`: line numbers and the time check start again with the new content; audit s23
    /// L-B5).
    pub fn restarts(&self) -> std::sync::Arc<Restarts> {
        std::sync::Arc::clone(&self.restarts)
    }

    /// Calls `note` with a message when a followed file is read again from its beginning (truncated
    /// or rewritten in place: log rotation by copy and truncate).
    pub fn on_restart(mut self, note: impl FnMut(&str) + Send + 'static) -> Self {
        self.on_restart = Some(Box::new(note));
        self
    }

    /// Looks at the followed file (if any): `true` when it was truncated or rewritten, and the reader now
    /// reads it again from its beginning.
    fn watch(&mut self) -> std::io::Result<bool> {
        let Some(w) = &mut self.watch else {
            return Ok(false);
        };
        let Change::Restart { header, what } = w.check()? else {
            return Ok(false);
        };
        if let Some(seek) = self.seek_to {
            seek(&mut self.inner, 0)?;
        }
        if !header.is_empty() {
            self.pending_header = Some(header);
        }
        use std::sync::atomic::Ordering;
        self.restarts.header_skipped.store(false, Ordering::SeqCst);
        self.restarts.count.fetch_add(1, Ordering::SeqCst);
        if let Some(note) = &mut self.on_restart {
            note(&format!(
                "{what} (log rotation by copy and truncate?): reading it again from its beginning (after \
                 its header line if it starts with it again)"
            ));
        }
        Ok(true)
    }

    /// The followed file was replaced and its open descriptor is read to its end: follows the file now
    /// at the path from its beginning (after the header line read before when it starts with it
    /// again). `false` when there is nothing to switch to (not replaced, or the new file cannot be
    /// opened yet: wait).
    fn switch_to_new_file(&mut self) -> std::io::Result<bool> {
        let (Some(w), Some(reopen)) = (&mut self.watch, self.reopen) else {
            return Ok(false);
        };
        if !w.replaced {
            return Ok(false);
        }
        let Ok((file, id)) = reopen(&w.path) else {
            return Ok(false);
        };
        self.inner = file;
        let what = format!(
            "the followed file was replaced (renamed away and created again, or deleted and created \
             again: log rotation by create?) after {} bytes were read, the old file read to its end: \
             reading the new file from its beginning (after its header line if it starts with it \
             again)",
            w.read
        );
        let header = match w.head.iter().position(|&b| b == b'\n') {
            Some(end) => w.head[..=end].to_vec(),
            None => Vec::new(),
        };
        w.id = id;
        w.head.clear();
        w.read = 0;
        w.replaced = false;
        w.checked = Instant::now();
        if !header.is_empty() {
            self.pending_header = Some(header);
        }
        use std::sync::atomic::Ordering;
        self.restarts.header_skipped.store(false, Ordering::SeqCst);
        self.restarts.count.fetch_add(1, Ordering::SeqCst);
        if let Some(note) = &mut self.on_restart {
            note(&what);
        }
        Ok(true)
    }

    /// After a restart, skips the header line when the file starts with it again: `false` while the
    /// file is too short to tell (wait for more).
    fn skip_header(&mut self) -> std::io::Result<bool> {
        let (Some(header), Some(w)) = (&self.pending_header, &mut self.watch) else {
            return Ok(true);
        };
        let mut start = Vec::with_capacity(header.len());
        if let Ok(f) = File::open(&w.path) {
            f.take(header.len() as u64).read_to_end(&mut start)?;
        }
        if start.len() < header.len() && header.starts_with(&start) {
            return Ok(false);
        }
        if start == *header {
            if let Some(seek) = self.seek_to {
                seek(&mut self.inner, header.len() as u64)?;
            }
            w.saw(header);
            self.restarts
                .header_skipped
                .store(true, std::sync::atomic::Ordering::SeqCst);
        }
        self.pending_header = None;
        Ok(true)
    }
}

impl Follow<File> {
    /// Follows the file at `path` ([`Follow::new`]): read again from its beginning when it is truncated
    /// or rewritten, stopped with an error when it is replaced (see the module documentation).
    pub fn file(
        path: &Path,
        idle_timeout: Option<Duration>,
        poll: Duration,
    ) -> std::io::Result<Self> {
        let file = File::open(path)?;
        let id = identity(&file.metadata()?);
        let mut f = Follow::new(file, idle_timeout, poll);
        f.seek_to = Some(|file: &mut File, at: u64| {
            use std::io::Seek;
            file.seek(std::io::SeekFrom::Start(at))
        });
        f.reopen = Some(|p: &Path| {
            let file = File::open(p)?;
            let id = identity(&file.metadata()?);
            Ok((file, id))
        });
        f.watch = Some(Watch {
            path: path.to_path_buf(),
            id,
            read: 0,
            head: Vec::new(),
            checked: Instant::now(),
            replaced: false,
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
            let ready = self.skip_header()?;
            let waited = match if ready { self.inner.read(buf) } else { Ok(0) } {
                Ok(0) => false,
                Ok(n) => {
                    // Data after a pause, or a second of data: the file is looked at first, and bytes
                    // read from a file truncated or rewritten under the reader are dropped (it is read
                    // again from its beginning).
                    let due = self
                        .watch
                        .as_ref()
                        .is_some_and(|w| self.idle || w.checked.elapsed() >= CHECK_EVERY);
                    self.idle = false;
                    if due && self.watch()? {
                        continue;
                    }
                    self.last_data = Instant::now();
                    if let Some(w) = &mut self.watch {
                        w.saw(&buf[..n]);
                    }
                    return Ok(n);
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                // A serial port's read time-out: it has already waited.
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => true,
                Err(e) => return Err(e),
            };
            self.idle = true;
            // The old descriptor of a replaced file read to its end: on to the new file.
            if self.switch_to_new_file()? {
                continue;
            }
            self.watch()?;
            // No byte now: the end after the idle time-out, or when a stop was asked (the first
            // Ctrl-C of `track --follow`, [`crate::accept_stop`]; audit s16 L12).
            if self
                .idle_timeout
                .is_some_and(|t| self.last_data.elapsed() >= t)
                || crate::stop_asked()
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
    /// returns what was read (until 500 ms without data) or the error that stopped the reader, and the
    /// notes of restarts.
    fn follow_through(
        initial: &str,
        change: impl FnOnce(&std::path::Path) + Send + 'static,
    ) -> (std::io::Result<String>, Vec<String>) {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.csv");
        std::fs::write(&path, initial).unwrap();
        let p = path.clone();
        let writer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            change(&p);
        });
        let notes = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let n = notes.clone();
        let reader = Follow::file(
            &path,
            Some(Duration::from_millis(500)),
            Duration::from_millis(10),
        )
        .unwrap()
        .on_restart(move |m| n.lock().unwrap().push(m.to_string()));
        let mut out = String::new();
        let r = BufReader::new(reader).read_to_string(&mut out).map(|_| out);
        writer.join().unwrap();
        let notes = notes.lock().unwrap().clone();
        (r, notes)
    }

    // A file truncated and written again (log rotation by copy and truncate) is read again from its
    // beginning, after the header line it starts with again, with a note; what was read before stays.
    #[test]
    fn a_truncated_file_is_read_again_from_its_beginning() {
        let (out, notes) = follow_through("t,u,y\n0,1,2\n0.01,1,2\n", |p| {
            std::fs::write(p, "").unwrap();
            std::thread::sleep(Duration::from_millis(100));
            std::fs::write(p, "t,u,y\n0.02,1,3\n").unwrap();
        });
        assert_eq!(out.unwrap(), "t,u,y\n0,1,2\n0.01,1,2\n0.02,1,3\n");
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(
            notes[0].contains("truncated to 0 bytes after 21 were read"),
            "{notes:?}"
        );
    }

    // Truncated and written again with data only (copytruncate: the writer appends on without a
    // header): the new bytes are read from the beginning.
    #[test]
    fn a_truncated_file_without_its_header_is_read_from_byte_0() {
        let (out, notes) = follow_through("t,u,y\n0,1,2\n", |p| {
            let f = std::fs::OpenOptions::new().write(true).open(p).unwrap();
            f.set_len(0).unwrap();
            std::thread::sleep(Duration::from_millis(100));
            std::fs::write(p, "0.01,1,2\n").unwrap();
        });
        assert_eq!(out.unwrap(), "t,u,y\n0,1,2\n0.01,1,2\n");
        assert_eq!(notes.len(), 1, "{notes:?}");
    }

    // A file renamed over by another (another inode), even longer than what was read, is detected:
    // the new file is read from its beginning, after the header line it starts with again.
    #[cfg(unix)]
    #[test]
    fn a_file_renamed_over_is_followed_from_its_beginning() {
        let (out, notes) = follow_through("t,u,y\n0,1,2\n", |p| {
            let other = p.with_extension("new");
            std::fs::write(&other, "t,u,y\n5,1,2\n5.01,1,2\n5.02,1,2\n").unwrap();
            std::fs::rename(&other, p).unwrap();
        });
        assert_eq!(out.unwrap(), "t,u,y\n0,1,2\n5,1,2\n5.01,1,2\n5.02,1,2\n");
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].contains("replaced"), "{notes:?}");
        assert!(notes[0].contains("after 12 bytes were read"), "{notes:?}");
    }

    // logrotate's `create` between two reads: the file is renamed, an empty one created at the path,
    // and the logger writes on into the renamed file (its open descriptor) until it reopens. Those
    // lines are read first (the old descriptor to its end), then the new file's (audit s27 L-3).
    #[cfg(unix)]
    #[test]
    fn create_rotation_reads_the_renamed_file_to_its_end_then_the_new_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("log.csv");
        let rotated = dir.path().join("log.csv.1");
        std::fs::write(&path, "t,u,y\n0,1,2\n").unwrap();
        let notes = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let n = notes.clone();
        let mut reader = BufReader::new(
            Follow::file(
                &path,
                Some(Duration::from_millis(200)),
                Duration::from_millis(5),
            )
            .unwrap()
            .on_restart(move |m| n.lock().unwrap().push(m.to_string())),
        );
        let mut line = String::new();
        reader.read_line(&mut line).unwrap();
        reader.read_line(&mut line).unwrap();
        assert_eq!(line, "t,u,y\n0,1,2\n");
        // The rotation, deterministically between two reads.
        std::fs::rename(&path, &rotated).unwrap();
        std::fs::write(&path, "").unwrap();
        let mut old = std::fs::OpenOptions::new()
            .append(true)
            .open(&rotated)
            .unwrap();
        old.write_all(b"0.01,1,2\n0.02,1,2\n").unwrap();
        // The logger reopens (HUP) and writes into the new file, header first.
        std::fs::write(&path, "t,u,y\n0.03,1,2\n").unwrap();
        let mut rest = String::new();
        reader.read_to_string(&mut rest).unwrap();
        assert_eq!(rest, "0.01,1,2\n0.02,1,2\n0.03,1,2\n");
        let notes = notes.lock().unwrap().clone();
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].contains("log rotation by create"), "{notes:?}");
    }

    // Rewritten in place with new, longer content (same inode, larger size): the first bytes differ,
    // so it is read again from its beginning (after the header).
    #[test]
    fn a_rewritten_file_is_read_again() {
        let (out, notes) = follow_through("t,u,y\n0,1,2\n", |p| {
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .truncate(true)
                .open(p)
                .unwrap();
            f.write_all(b"t,u,y\n5,1,2\n5.01,1,2\n5.02,1,2\n").unwrap();
        });
        assert_eq!(out.unwrap(), "t,u,y\n0,1,2\n5,1,2\n5.01,1,2\n5.02,1,2\n");
        // Between the truncation and the write the file may be seen empty (truncated): either is right.
        assert!(!notes.is_empty(), "{notes:?}");
    }
}
