//! Temporary files of [`crate::write_atomic`], folders of [`crate::write_folder`] and child processes
//! of a run (`bench long`'s), removed or ended when the process is stopped by a signal.
//!
//! A write lists its temporary file here from creation until the rename; [`remove_temporaries_on_signals`]
//! starts a thread that, on SIGINT, SIGTERM, SIGHUP or SIGQUIT, ends every listed child process (SIGTERM,
//! then SIGKILL after [`CHILD_GRACE`]) and waits for it, removes every listed file and folder, and then
//! ends the process as the signal would have (so the exit status still says "killed by SIGTERM";
//! SIGQUIT exits with status 131 without a core dump). SIGXFSZ (a file-size limit, `ulimit -f`) is
//! ignored, so that a write past the limit fails with EFBIG, which the writer reports and cleans up.
//!
//! The list is locked across the renames of one run's outputs ([`locked`]: all of them, audit s36
//! M-1), so a signal comes before them (every temporary removed, every output as it was) or after them
//! (every output new), never between. A listed folder that is still being filled when the signal
//! comes is first renamed away (so that the writer's later creations under its name fail) and then
//! removed, again until nothing is left (audit s36 M-2). SIGKILL cannot be caught: after `kill -9` a
//! `.ipa-sysid-*` temporary may remain (the output itself is still either the old or the new file).

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

/// One listed temporary: its path and, for a temporary folder that becomes an output folder, the
/// folder it will become (so that an error about a file inside it names the user's path).
struct Entry {
    path: PathBuf,
    dest: Option<PathBuf>,
}

/// What the signal thread ends and removes.
pub(crate) struct List {
    entries: Vec<Entry>,
    /// Process ids of listed children ([`spawn_listed`]).
    children: Vec<u32>,
}

impl List {
    fn unlist(&mut self, path: &Path) {
        self.entries.retain(|e| e.path != path);
    }
}

static PENDING: Mutex<List> = Mutex::new(List {
    entries: Vec::new(),
    children: Vec::new(),
});

fn pending() -> MutexGuard<'static, List> {
    // A panic while the list was held cannot leave it inconsistent (pushes and removes only).
    PENDING.lock().unwrap_or_else(|e| e.into_inner())
}

/// Runs `f` with the list locked: a signal that comes meanwhile is handled (children ended, temporaries
/// removed, process ended) only after `f`, so what `f` renames into place is either all done or, when
/// the signal came first, not started. `f` must not create or drop a [`Pending`] or [`PendingDir`]
/// other than through the `*_locked` methods (the lock is not re-entrant).
pub(crate) fn locked<T>(f: impl FnOnce(&mut List) -> T) -> T {
    let mut list = pending();
    f(&mut list)
}

/// `path` as the user named it: a path inside a listed temporary folder that will become the output
/// folder `DIR` is shown inside `DIR` (audit s36 L-1: an error named `.ipa-sysid-3h6MUD/figures/…`).
pub(crate) fn shown_path(path: &Path) -> PathBuf {
    let list = pending();
    for e in &list.entries {
        if let (Some(dest), Ok(rest)) = (&e.dest, path.strip_prefix(&e.path)) {
            return dest.join(rest);
        }
    }
    path.to_path_buf()
}

/// A temporary file listed for removal on a signal; unlisted when dropped.
pub(crate) struct Pending {
    path: PathBuf,
    listed: bool,
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
        let path = tmp.path().to_path_buf();
        list.entries.push(Entry {
            path: path.clone(),
            dest: None,
        });
        Ok((tmp, Pending { path, listed: true }))
    }

    /// Renames `tmp` to `to` and unlists it, inside [`locked`] (`list` is the locked list).
    pub(crate) fn persist_locked(
        mut self,
        list: &mut List,
        tmp: tempfile::NamedTempFile,
        to: &Path,
    ) -> std::io::Result<()> {
        let result = tmp.persist(to).map(|_| ()).map_err(|e| e.error);
        list.unlist(&self.path);
        self.listed = false;
        result
    }

    /// Removes `tmp` and unlists it, inside [`locked`].
    pub(crate) fn discard_locked(mut self, list: &mut List, tmp: tempfile::NamedTempFile) {
        drop(tmp);
        list.unlist(&self.path);
        self.listed = false;
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        if self.listed {
            pending().unlist(&self.path);
        }
    }
}

/// A temporary folder ([`crate::write_folder`]) listed for removal (with everything in it) on a signal
/// from its creation; removed and then unlisted when dropped unless [`PendingDir::finish`] put it in
/// place.
pub(crate) struct PendingDir {
    dir: Option<tempfile::TempDir>,
    path: PathBuf,
}

impl PendingDir {
    /// Creates a temporary folder in `parent` with `builder` and lists it, with the list locked;
    /// `dest` is the output folder it will become, if any ([`shown_path`]).
    pub(crate) fn create(
        builder: &tempfile::Builder<'_, '_>,
        parent: &Path,
        dest: Option<&Path>,
    ) -> std::io::Result<Self> {
        let mut list = pending();
        let dir = builder.tempdir_in(parent)?;
        let path = dir.path().to_path_buf();
        list.entries.push(Entry {
            path: path.clone(),
            dest: dest.map(Path::to_path_buf),
        });
        Ok(PendingDir {
            dir: Some(dir),
            path,
        })
    }

    /// The temporary folder.
    pub(crate) fn path(&self) -> &Path {
        &self.path
    }

    /// Runs `f` (the renames that put the folder in place) with the list locked, so that a signal
    /// comes before them (the temporary folder is removed) or after them (the folder is in place),
    /// never between. When `f` succeeds the folder is kept and unlisted; when it fails the folder is
    /// removed (then unlisted) as on a drop.
    pub(crate) fn finish<E>(mut self, f: impl FnOnce(&Path) -> Result<(), E>) -> Result<(), E> {
        let mut list = pending();
        f(&self.path)?;
        list.unlist(&self.path);
        if let Some(d) = self.dir.take() {
            let _ = d.keep();
        }
        Ok(())
    }
}

impl Drop for PendingDir {
    fn drop(&mut self) {
        // Removed first, unlisted after: a signal during the removal finishes it.
        if let Some(d) = self.dir.take() {
            let _ = d.close();
        }
        pending().unlist(&self.path);
    }
}

/// A folder of a run's own scratch files (`bench long`'s records), removed with everything in it
/// when the run ends ([`ScratchDir::remove`], or a drop) and when a signal ends the process.
pub struct ScratchDir {
    path: PathBuf,
}

impl ScratchDir {
    /// Creates the folder `path` (and its missing parents) and lists it for removal on a signal, with
    /// the list locked so that no signal comes between. The folder must be the run's own: a folder that
    /// exists already is refused (`AlreadyExists`), so that nothing of a user's is removed.
    pub fn create(path: &Path) -> std::io::Result<Self> {
        let mut list = pending();
        if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)?;
        }
        std::fs::create_dir(path)?;
        list.entries.push(Entry {
            path: path.to_path_buf(),
            dest: None,
        });
        Ok(ScratchDir {
            path: path.to_path_buf(),
        })
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Removes the folder with everything in it, then unlists it.
    pub fn remove(self) {
        drop(self);
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
        pending().unlist(&self.path);
    }
}

/// A child process listed to be ended (and waited for) when a signal ends this process
/// ([`spawn_listed`]); unlisted when dropped (after the caller waited for it).
pub struct ListedChild {
    pid: u32,
}

impl Drop for ListedChild {
    fn drop(&mut self) {
        pending().children.retain(|&p| p != self.pid);
    }
}

/// Spawns `cmd` and lists the child, with the list locked so that a signal cannot come between the
/// spawn and the listing: a signal that ends this process first ends the child (SIGTERM, then SIGKILL
/// after [`CHILD_GRACE`]) and waits for it (audit s36 M-4: `bench long` stopped by SIGTERM left its
/// child `simulate` running). Keep the [`ListedChild`] until the child was waited for.
pub fn spawn_listed(
    cmd: &mut std::process::Command,
) -> std::io::Result<(std::process::Child, ListedChild)> {
    let mut list = pending();
    let child = cmd.spawn()?;
    let pid = child.id();
    list.children.push(pid);
    Ok((child, ListedChild { pid }))
}

/// How long a listed child is given to end after SIGTERM before SIGKILL.
pub const CHILD_GRACE: std::time::Duration = std::time::Duration::from_secs(3);

/// Ends the child `pid` (SIGTERM, then SIGKILL after [`CHILD_GRACE`]) and reaps it. A child the main
/// thread reaped meanwhile is gone (`ECHILD`).
#[cfg(unix)]
fn end_child(pid: u32) {
    let Ok(pid) = libc::pid_t::try_from(pid) else {
        return;
    };
    // SAFETY: plain system calls on a process id of our own child.
    unsafe {
        libc::kill(pid, libc::SIGTERM);
    }
    let start = std::time::Instant::now();
    let mut killed = false;
    loop {
        let mut status = 0;
        // SAFETY: as above; `status` lives across the call.
        let r = unsafe { libc::waitpid(pid, &mut status, libc::WNOHANG) };
        if r != 0 {
            // Reaped (r == pid) or not ours any more (-1, ECHILD: the main thread reaped it).
            return;
        }
        if !killed && start.elapsed() >= CHILD_GRACE {
            // SAFETY: as above.
            unsafe {
                libc::kill(pid, libc::SIGKILL);
            }
            killed = true;
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// Removes a listed temporary folder that the main thread may still be filling: renamed away first
/// (the writer's later creations under its name then fail), then removed until it is gone (an entry
/// created by a call already under way when the rename came makes one removal fail: it is tried
/// again); the old name is removed too if the writer made it again meanwhile. Gives up after
/// [`REMOVAL_PATIENCE`] (a folder that cannot be removed at all: permissions changed under it).
fn remove_folder_racing(path: &Path) {
    let mut name = path.as_os_str().to_owned();
    name.push(".removing");
    let away = PathBuf::from(name);
    let left = |p: &Path| std::fs::symlink_metadata(p).is_ok();
    let start = std::time::Instant::now();
    while start.elapsed() < REMOVAL_PATIENCE {
        let target = if std::fs::rename(path, &away).is_ok() || !left(path) {
            away.as_path()
        } else {
            path
        };
        let _ = std::fs::remove_dir_all(target);
        if !left(path) && !left(&away) {
            return;
        }
        std::thread::yield_now();
    }
}

/// How long [`remove_folder_racing`] keeps trying.
const REMOVAL_PATIENCE: std::time::Duration = std::time::Duration::from_secs(2);

/// Starts (once per process) the thread that, when SIGINT, SIGTERM, SIGHUP or SIGQUIT arrives, ends
/// the listed child processes, removes the temporary files and folders of unfinished writes, then ends
/// the process as that signal does by default (SIGQUIT: exit status 131, no core dump); and ignores
/// SIGXFSZ (a write past `ulimit -f` then fails with EFBIG and is cleaned up as any failed write). The
/// command line calls it at start; a library embedding `sysid-io` (the Python module) does not, so
/// that the host keeps its own signal handling.
#[cfg(unix)]
pub fn remove_temporaries_on_signals() -> std::io::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGQUIT, SIGTERM};
    static STARTED: std::sync::OnceLock<()> = std::sync::OnceLock::new();
    if STARTED.get().is_some() {
        return Ok(());
    }
    // SAFETY: setting a signal's disposition to "ignore" installs no handler code.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP, SIGQUIT])?;
    std::thread::Builder::new()
        .name("remove-temporaries".into())
        .spawn(move || {
            for signal in signals.forever() {
                // The first SIGINT or SIGTERM of a run that stops by itself only asks it to stop.
                if (signal == SIGINT || signal == SIGTERM)
                    && STOP_ACCEPTED.load(Ordering::SeqCst)
                    && !STOP_ASKED.swap(true, Ordering::SeqCst)
                {
                    continue;
                }
                let list = pending();
                for &pid in &list.children {
                    end_child(pid);
                }
                for e in &list.entries {
                    let p = &e.path;
                    match std::fs::symlink_metadata(p) {
                        Ok(m) if m.is_dir() => remove_folder_racing(p),
                        Ok(_) => {
                            let _ = std::fs::remove_file(p);
                        }
                        Err(_) => {}
                    }
                }
                // Ends the process with the list still locked: no rename can follow the removal.
                if signal == SIGQUIT {
                    std::process::exit(128 + signal);
                }
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

#[cfg(not(unix))]
fn end_child(_pid: u32) {}

#[cfg(all(test, unix))]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    // What the signal thread sees when it takes the list (it removes the listed temporaries and ends the
    // process right then) is one run's outputs all old or all new: an observer that takes the lock
    // over and over while the main thread rewrites a pair of outputs, each run writing its generation
    // number into both, always reads the same number in both (audit s36 M-1: the renames were locked
    // one at a time, so the signal could land between them).
    #[test]
    fn one_runs_outputs_are_renamed_in_one_step_against_the_signal_thread() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("m.json"), dir.path().join("j.json"));
        crate::write_all_atomic_as(&[(&a, b"0"), (&b, b"0")], true).unwrap();
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let observer = {
            let (a, b, stop) = (a.clone(), b.clone(), stop.clone());
            std::thread::spawn(move || {
                let mut looks = 0u64;
                while !stop.load(Ordering::SeqCst) {
                    locked(|_| {
                        let (x, y) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
                        assert_eq!(x, y, "the signal thread would see a mixed pair");
                    });
                    looks += 1;
                    std::thread::yield_now();
                }
                looks
            })
        };
        for generation in 1..=300u32 {
            let g = generation.to_string();
            crate::write_all_atomic_as(&[(&a, g.as_bytes()), (&b, g.as_bytes())], true).unwrap();
        }
        stop.store(true, Ordering::SeqCst);
        let looks = observer.join().unwrap();
        assert!(looks > 0);
        assert_eq!(std::fs::read(&a).unwrap(), b"300");
    }

    // A folder that another thread is still filling as fast as it can is removed whole by the signal
    // thread's removal, and the writer's later creations under its name fail (audit s36 M-2: the
    // removal met new entries, failed, and left the folder half there).
    #[test]
    fn a_folder_being_filled_is_removed_whole() {
        let root = tempfile::tempdir().unwrap();
        let target = root.path().join(".ipa-sysid-test");
        std::fs::create_dir(&target).unwrap();
        for i in 0..2000 {
            std::fs::write(target.join(format!("old{i}")), "x").unwrap();
        }
        let stop = std::sync::Arc::new(AtomicBool::new(false));
        let writer = {
            let (target, stop) = (target.clone(), stop.clone());
            std::thread::spawn(move || {
                let (mut made, mut i) = (0u64, 0u64);
                while !stop.load(Ordering::SeqCst) {
                    // As `copy_missing` does: files and sub-folders by path.
                    let sub = target.join(format!("d{i}"));
                    if std::fs::create_dir(&sub).is_ok()
                        && std::fs::write(sub.join("f"), "y").is_ok()
                    {
                        made += 1;
                    }
                    i += 1;
                }
                made
            })
        };
        std::thread::sleep(std::time::Duration::from_millis(20));
        remove_folder_racing(&target);
        let left: Vec<_> = std::fs::read_dir(root.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        // The writer goes on trying after the removal: nothing it does can bring the folder back.
        std::thread::sleep(std::time::Duration::from_millis(20));
        stop.store(true, Ordering::SeqCst);
        let made = writer.join().unwrap();
        assert!(made > 0, "the writer never ran");
        assert!(left.is_empty(), "{left:?}");
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 0);
    }

    // A listed child is ended and reaped by the signal thread's `end_child`: a `sleep 30` is gone
    // within the grace time (it dies at SIGTERM), and its pid is no longer ours.
    #[test]
    fn a_listed_child_is_ended_and_reaped() {
        let (child, listed) = spawn_listed(std::process::Command::new("sleep").arg("30")).unwrap();
        let pid = child.id();
        assert!(pending().children.contains(&pid));
        let start = std::time::Instant::now();
        end_child(pid);
        assert!(start.elapsed() < CHILD_GRACE);
        // Reaped: waiting for it again says it is not our child any more.
        let mut status = 0;
        // SAFETY: a plain system call on a process id; `status` lives across it.
        let r = unsafe { libc::waitpid(pid as libc::pid_t, &mut status, libc::WNOHANG) };
        assert_eq!(r, -1);
        drop(listed);
        assert!(!pending().children.contains(&pid));
        std::mem::forget(child);
    }
}
