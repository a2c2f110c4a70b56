//! A folder of outputs written as a whole ([`write_folder`]): filled in a temporary folder beside it,
//! then renamed into place, so a reader never sees half a data set and a failed run leaves nothing.

use std::path::Path;

use crate::cleanup::PendingDir;
use crate::{refused, OutputError, TEMP_PREFIX};

/// Writes the folder `dir` (chosen by option `flag`) as a whole: `fill` writes every file into a new
/// temporary folder beside `dir`, which is then renamed to `dir`. A missing or empty `dir` is replaced;
/// an existing folder with entries is refused unless `overwrite` (then it is replaced by the new one and
/// its old entries are removed, after the new folder is in place); a path that is not a folder is
/// refused. When `fill` fails, the temporary folder is removed and `dir` is untouched. Returns whether
/// an existing folder with entries was replaced (for the caller's "replaced DIR", as every file output
/// says it).
pub fn write_folder<E>(
    dir: &Path,
    flag: &str,
    overwrite: bool,
    fill: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<bool, E>
where
    E: From<OutputError>,
{
    let io = |source| OutputError::Io {
        path: dir.to_path_buf(),
        source,
    };
    let parent = crate::parent_dir(dir);
    if !parent.is_dir() {
        return Err(refused(
            flag,
            dir,
            format!(
                "a folder in an existing folder ({} does not exist)",
                parent.display()
            ),
        )
        .into());
    }
    check_folder_path(dir, flag)?;
    let existing = match std::fs::symlink_metadata(dir) {
        Ok(m) if m.is_dir() => {
            let count = std::fs::read_dir(dir).map_err(io)?.count();
            if count > 0 && !overwrite {
                return Err(refused(
                    flag,
                    dir,
                    format!(
                        "a new or empty folder (this one holds {count} entr{}; pass --overwrite to replace \
                         it and everything in it)",
                        if count == 1 { "y" } else { "ies" }
                    ),
                )
                .into());
            }
            count > 0
        }
        // `check_folder_path` let only a folder or nothing through.
        Ok(_) => return Err(refused(flag, dir, "a folder").into()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
        Err(e) => return Err(io(e).into()),
    };
    // Listed for removal on a signal from its creation until it is renamed into place.
    let tmp = PendingDir::create(
        tempfile::Builder::new().prefix(TEMP_PREFIX),
        parent,
        Some(dir),
    )
    .map_err(io)?;
    fill(tmp.path())?;
    // The holder of the previous folder, listed from its creation too (audit s36 M-2: it was not, so a
    // signal left it behind, empty or holding the whole previous folder).
    let old = if existing {
        Some(
            PendingDir::create(tempfile::Builder::new().prefix(TEMP_PREFIX), parent, None)
                .map_err(io)?,
        )
    } else {
        None
    };
    // The renames run with the signal list locked: a signal removes the new folder before them or
    // comes after both, never between (the user's folder is never left moved aside).
    tmp.finish(|new: &Path| -> Result<(), OutputError> {
        match &old {
            Some(old) => {
                // The old folder moves into the holder (removed, still listed, when `old` is
                // dropped), the new takes its place.
                let old_dir = old.path().join("old");
                std::fs::rename(dir, &old_dir).map_err(io)?;
                if let Err(e) = std::fs::rename(new, dir) {
                    // Put the old folder back; the new one is removed with `tmp`.
                    let _ = std::fs::rename(&old_dir, dir);
                    return Err(io(e));
                }
            }
            None => std::fs::rename(new, dir).map_err(io)?,
        }
        Ok(())
    })?;
    drop(old);
    Ok(existing)
}

/// Refuses an output folder path `dir` (option `flag`) that names something other than a folder or
/// nothing, in words that say what it is: a symbolic link (even to a folder: the folder is replaced by
/// a rename, which would replace the link, not what it names), a regular file, a device, a FIFO or a
/// socket. The one check of every folder output ([`write_folder`], [`crate::write_claimed_folder`]).
///
/// Also before any work (audit s36 L-1): a folder can be created in `dir`'s parent (a trial
/// temporary) and, when `dir` holds entries, `dir` itself is writable (moving a folder to another
/// parent rewrites its `..`; checked by `access`, creating nothing there); and `dir` is not a mount
/// point (its device differs from its parent's: a rename cannot replace it). A bind mount of a folder
/// of the same file system is not seen by the device test.
pub fn check_folder_path(dir: &Path, flag: &str) -> Result<(), OutputError> {
    let meta = match std::fs::symlink_metadata(dir) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let parent = crate::parent_dir(dir);
            if parent.is_dir() {
                crate::check_can_create(
                    parent,
                    flag,
                    dir,
                    "a folder in a folder this user can write",
                )?;
            }
            return Ok(());
        }
        Err(source) => {
            return Err(OutputError::Io {
                path: dir.to_path_buf(),
                source,
            })
        }
    };
    let kind = meta.file_type();
    if kind.is_dir() {
        let parent = crate::parent_dir(dir);
        if is_mount_point(&meta, parent) {
            return Err(refused(
                flag,
                dir,
                format!(
                    "a folder that is not a mount point ({} is the root of another file system than \
                     {}; the output folder is put in place by a rename, which cannot replace a mount \
                     point: name a folder inside it)",
                    dir.display(),
                    parent.display()
                ),
            ));
        }
        crate::check_can_create(
            parent,
            flag,
            dir,
            "a folder in a folder this user can write",
        )?;
        if std::fs::read_dir(dir).is_ok_and(|mut d| d.next().is_some()) {
            writable_folder(dir, flag)?;
        }
        return Ok(());
    }
    let what = if kind.is_symlink() {
        let target = std::fs::read_link(dir)
            .map(|t| t.display().to_string())
            .unwrap_or_else(|_| "an unreadable target".to_string());
        let names = match std::fs::metadata(dir) {
            Ok(m) if m.is_dir() => "a folder",
            Ok(m) if m.is_file() => "a file",
            Ok(_) => "something that is not a folder",
            Err(_) => "nothing: broken, or a loop",
        };
        format!(
            "a folder, not a symbolic link ({} is a symbolic link to {target}, {names}; pass the \
             folder itself)",
            dir.display()
        )
    } else if kind.is_file() {
        "a folder (this is a file)".to_string()
    } else {
        format!("a folder (this is {})", special_kind(&kind))
    };
    Err(refused(flag, dir, what))
}

/// Refuses the existing folder `dir` (option `flag`) that this process may not write (`access(W_OK)`:
/// its permissions, a read-only file system), without creating anything in it: it may be a user's
/// folder that a later check refuses. A folder with entries is moved aside by a rename that rewrites
/// its `..`, which needs that permission.
#[cfg(unix)]
fn writable_folder(dir: &Path, flag: &str) -> Result<(), OutputError> {
    use std::os::unix::ffi::OsStrExt;
    let Ok(c) = std::ffi::CString::new(dir.as_os_str().as_bytes()) else {
        return Ok(());
    };
    // SAFETY: a NUL-terminated path that outlives the call.
    if unsafe { libc::access(c.as_ptr(), libc::W_OK) } == 0 {
        return Ok(());
    }
    Err(refused(
        flag,
        dir,
        format!(
            "a folder this user can write (the folder {} is not writable: {}; checked before the run)",
            dir.display(),
            std::io::Error::last_os_error()
        ),
    ))
}

#[cfg(not(unix))]
fn writable_folder(_dir: &Path, _flag: &str) -> Result<(), OutputError> {
    Ok(())
}

/// Whether the folder `dir` (its metadata `meta`) is a mount point: its device differs from that of
/// its parent folder `parent`.
#[cfg(unix)]
fn is_mount_point(meta: &std::fs::Metadata, parent: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata(parent).is_ok_and(|p| p.dev() != meta.dev())
}

#[cfg(not(unix))]
fn is_mount_point(_meta: &std::fs::Metadata, _parent: &Path) -> bool {
    false
}

/// "a device", "a FIFO" or "a socket": what a path that is neither a file, a folder nor a link is.
#[cfg(unix)]
pub(crate) fn special_kind(kind: &std::fs::FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if kind.is_char_device() || kind.is_block_device() {
        "a device"
    } else if kind.is_fifo() {
        "a FIFO (named pipe)"
    } else if kind.is_socket() {
        "a socket"
    } else {
        "neither a file nor a folder"
    }
}

#[cfg(not(unix))]
pub(crate) fn special_kind(_kind: &std::fs::FileType) -> &'static str {
    "neither a file nor a folder"
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn fill_one(name: &'static str) -> impl FnOnce(&Path) -> Result<(), OutputError> {
        move |d: &Path| {
            std::fs::write(d.join(name), "x").unwrap();
            Ok(())
        }
    }

    // A new folder appears whole; a folder with entries is refused and left as it was unless asked;
    // when asked it holds only the new entries.
    #[test]
    fn a_full_folder_is_replaced_only_when_asked() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("fleet");
        assert!(!write_folder(&dir, "--out", false, fill_one("a")).unwrap());
        assert!(dir.join("a").is_file());
        let e = write_folder(&dir, "--out", false, fill_one("b"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("--overwrite") && e.contains("1 entry"), "{e}");
        assert!(dir.join("a").is_file() && !dir.join("b").exists());
        assert!(write_folder(&dir, "--out", true, fill_one("b")).unwrap());
        assert!(dir.join("b").is_file() && !dir.join("a").exists());
        // Nothing temporary is left beside it.
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1);
    }

    // A write inside the folder being filled that fails names the file at its place in the output
    // folder, not in the hidden temporary one (audit s36 L-1).
    #[test]
    fn an_error_inside_a_folder_output_names_the_users_path() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("fleet");
        let e = write_folder(&dir, "--out", false, |tmp: &Path| {
            crate::write_atomic(&tmp.join("missing/x.csv"), b"t,u,y\n")
        })
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with(&format!("{}: ", dir.join("missing/x.csv").display())),
            "{e}"
        );
        assert!(!e.contains(TEMP_PREFIX), "{e}");
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 0);
    }

    // A failing fill leaves no folder behind.
    #[test]
    fn a_failed_fill_leaves_nothing() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("fleet");
        let r = write_folder(&dir, "--out", false, |_: &Path| {
            Err(OutputError::Io {
                path: dir.clone(),
                source: std::io::Error::other("boom"),
            })
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 0);
    }
}

#[cfg(all(test, target_os = "linux"))]
#[allow(clippy::unwrap_used)]
mod mount_tests {
    use super::*;

    // /proc is the mount point of the proc file system, a device other than its parent's: a folder
    // output there is refused before any work, naming the mount point (audit s36 L-1: the rename
    // failed with "Device or resource busy" after the whole run).
    #[test]
    fn a_mount_point_is_refused_as_an_output_folder() {
        let proc_dir = Path::new("/proc");
        if !proc_dir.join("self").exists() {
            eprintln!("SKIPPED: no /proc on this machine");
            return;
        }
        let e = check_folder_path(proc_dir, "--out")
            .unwrap_err()
            .to_string();
        assert!(e.contains("mount point"), "{e}");
        // A plain folder in a temporary folder is not.
        let root = tempfile::tempdir().unwrap();
        std::fs::create_dir(root.path().join("d")).unwrap();
        check_folder_path(&root.path().join("d"), "--out").unwrap();
        // The trial temporaries are gone.
        assert_eq!(std::fs::read_dir(root.path()).unwrap().count(), 1);
    }
}
