//! Temporary files of [`crate::write_atomic`] and folders of [`crate::write_folder`] removed when the
//! process is stopped by a signal.
//!
//! A write lists its temporary file here from creation until the rename; [`remove_temporaries_on_signals`]
//! starts a thread that, on SIGINT, SIGTERM or SIGHUP, removes every listed file and then ends the
//! process as the signal would have (so the exit status still says "killed by SIGTERM"). The list is
//! locked across the rename, so a file is either renamed into place or removed, never left behind.
//! SIGKILL cannot be caught: after `kill -9` a `.ipa-sysid-*.tmp` file may remain (the output itself is
//! still either the old or the new file).

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Mutex, MutexGuard};

/// A run that ends by itself when asked ([`accept_stop`]): the first SIGINT or SIGTERM then sets
/// [`STOP_ASKED`] instead of ending the process.
static STOP_ACCEPTED: AtomicBool = AtomicBool::new(false);
/// A stop was asked by SIGINT or SIGTERM while [`STOP_ACCEPTED`].
static STOP_ASKED: AtomicBool = AtomicBool::new(false);

/// Lets the first SIGINT or SIGTERM ask the run to stop ([`stop_asked`]) instead of ending the process:
/// `track --follow` then ends after the line being read (or at its next poll) and writes its summary and `--json` (audit
/// s16 L12). A second signal ends the process as before (temporaries removed). Only with
/// [`remove_temporaries_on_signals`] started (the command line).
pub fn accept_stop() {
    STOP_ACCEPTED.store(true, Ordering::SeqCst);
}

/// Whether a stop was asked ([`accept_stop`]).
pub fn stop_asked() -> bool {
    STOP_ASKED.load(Ordering::SeqCst)
}

static PENDING: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn pending() -> MutexGuard<'static, Vec<PathBuf>> {
    // A panic while the list was held cannot leave it inconsistent (pushes and removes only).
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// A temporary file listed for removal on a signal; unlisted when dropped.
pub(crate) struct Pending {
    path: PathBuf,
}

impl Pending {
    /// Creates a temporary file in `dir` with `builder` and lists it, with the list locked so that a
    /// signal cannot come between the creation and the listing.
    pub(crate) fn create(
        builder: &tempfile::Builder<'_, '_>,
        dir: &Path,
    ) -> std::io::Result<(tempfile::NamedTempFile, Self)> {
        let mut list = pending();
        let tmp = builder.tempfile_in(dir)?;
        list.push(tmp.path().to_path_buf());
        let path = tmp.path().to_path_buf();
        Ok((tmp, Pending { path }))
    }

    /// Renames `tmp` to `to` and unlists it, with the list locked so that a signal cannot come between.
    pub(crate) fn persist(self, tmp: tempfile::NamedTempFile, to: &Path) -> std::io::Result<()> {
        let mut list = pending();
        let result = tmp.persist(to).map(|_| ()).map_err(|e| e.error);
        list.retain(|p| p != &self.path);
        drop(list);
        result
    }
}

/// A temporary folder ([`crate::write_folder`]) listed for removal (with everything in it) on a signal;
/// unlisted when dropped.
pub(crate) struct PendingDir {
    path: PathBuf,
}

impl PendingDir {
    /// Creates a temporary folder in `dir` with `builder` and lists it, with the list locked.
    pub(crate) fn create(
        builder: &tempfile::Builder<'_, '_>,
        dir: &Path,
    ) -> std::io::Result<(tempfile::TempDir, Self)> {
        let mut list = pending();
        let tmp = builder.tempdir_in(dir)?;
        list.push(tmp.path().to_path_buf());
        let path = tmp.path().to_path_buf();
        Ok((tmp, PendingDir { path }))
    }

    /// Runs `f` (the renames that put the folder in place) with the list locked, so that a signal
    /// comes before them (the temporary folder is removed) or after them (the folder is in place),
    /// never between; unlists the folder.
    pub(crate) fn finish<T>(self, f: impl FnOnce() -> T) -> T {
        let mut list = pending();
        let out = f();
        list.retain(|p| p != &self.path);
        out
    }
}

impl Drop for PendingDir {
    fn drop(&mut self) {
        pending().retain(|p| p != &self.path);
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        pending().retain(|p| p != &self.path);
    }
}

/// Starts (once per process) the thread that removes the temporary files of unfinished writes when
/// SIGINT, SIGTERM or SIGHUP arrives, then ends the process as that signal does by default. The
/// command line calls it at start; a library embedding `sysid-io` (the Python module) does not, so that
/// the host keeps its own signal handling.
#[cfg(unix)]
pub fn remove_temporaries_on_signals() -> std::io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    static STARTED: std::sync::OnceLock<()> = std::sync::OnceLock::new();
    if STARTED.get().is_some() {
        return Ok(());
    }
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])?;
    std::thread::Builder::new()
        .name("remove-temporaries".into())
        .spawn(move || {
            for signal in signals.forever() {
                // The first SIGINT or SIGTERM of a run that stops by itself only asks it to stop.
                if signal != SIGHUP
                    && STOP_ACCEPTED.load(Ordering::SeqCst)
                    && !STOP_ASKED.swap(true, Ordering::SeqCst)
                {
                    continue;
                }
                let list = pending();
                for p in list.iter() {
                    if p.is_dir() {
                        let _ = std::fs::remove_dir_all(p);
                    } else {
                        let _ = std::fs::remove_file(p);
                    }
                }
                // Ends the process with the list still locked: no rename can follow the removal.
                let _ = signal_hook::low_level::emulate_default_handler(signal);
                std::process::exit(128 + signal);
            }
        })?;
    let _ = STARTED.set(());
    Ok(())
}

/// Without Unix signals there is nothing to install.
#[cfg(not(unix))]
pub fn remove_temporaries_on_signals() -> std::io::Result<()> {
    Ok(())
}
