//! Reading a source that is still being written (`track --follow FILE`, `track --serial`): end of data
//! and read time-outs mean "nothing yet", not "finished".

use std::io::{ErrorKind, Read};
use std::time::{Duration, Instant};

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
        }
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
                    return Ok(n);
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                // A serial port's read time-out: it has already waited.
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock) => true,
                Err(e) => return Err(e),
            };
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
    use std::io::{BufRead, BufReader, Seek, SeekFrom, Write};

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
}
