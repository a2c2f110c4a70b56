//! Session 37 (helper io37): signals and output atomicity through the binary (audit s36 M-2, M-4, L-1,
//! L-2, L-4). The one-step commit of a run's outputs (M-1) and the folder removal that does not race
//! its writer are checked in `sysid-io`'s unit tests (cleanup.rs), where the lock can be observed.

#![cfg(unix)]
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::io::Read;
use std::os::unix::process::ExitStatusExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{bin, stderr};

/// The `.ipa-sysid-*` entries (files or folders) directly in `dir`.
fn leftovers(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(".ipa-sysid-"))
        .collect()
}

fn term(pid: u32) {
    // SAFETY: a plain system call on our own child's process id.
    unsafe {
        libc::kill(pid as libc::pid_t, libc::SIGTERM);
    }
}

/// Reads 10 bytes of the command's standard output, then closes it as `| head -c 10` does; returns
/// the exit status and standard error.
fn read_ten_bytes_then_close(cmd: &mut Command) -> (std::process::ExitStatus, String) {
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .stdin(Stdio::null())
        .spawn()
        .unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut ten = [0u8; 10];
    out.read_exact(&mut ten).unwrap();
    drop(out);
    let o = child.wait_with_output().unwrap();
    (o.status, String::from_utf8_lossy(&o.stderr).into_owned())
}

// A reader of standard output that stops early (`| head -c 10`) is not an error, for every command that
// writes data there (audit s36 L-2: `simulate --out -` and `track` said "Broken pipe" with exit 2 while
// identify and --help ended quietly): exit 0, nothing on standard error.
#[test]
fn a_reader_that_stops_early_ends_the_run_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // About 7 MB of CSV: far more than a pipe holds, so the writes after the close fail.
    let (status, err) = read_ten_bytes_then_close(bin().current_dir(d).args([
        "simulate",
        "--samples",
        "200000",
        "--out",
        "-",
    ]));
    assert_eq!(status.code(), Some(0), "{err}");
    assert!(err.is_empty(), "{err}");
    let out = bin()
        .current_dir(d)
        .args(["simulate", "--samples", "20000", "--out", "rec.csv"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let (status, err) = read_ten_bytes_then_close(
        bin()
            .current_dir(d)
            .args(["track", "--data", "rec.csv", "--every", "1"]),
    );
    assert_eq!(status.code(), Some(0), "{err}");
    assert!(err.is_empty(), "{err}");
    // A failure to write that is not a closed reader stays an error: /dev/full as standard output.
    let out = bin()
        .current_dir(d)
        .args(["simulate", "--samples", "1000", "--out", "-"])
        .stdout(
            std::fs::OpenOptions::new()
                .write(true)
                .open("/dev/full")
                .unwrap(),
        )
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

// A file-size limit (`ulimit -f`, SIGXFSZ) makes the write fail with "File too large", reported,
// exit 2, the temporary removed; SIGQUIT (Ctrl-\) during a write removes the temporary and exits 131
// (audit s36 L-4: both left a half-written `.ipa-sysid-*.tmp`).
#[test]
fn a_file_size_limit_and_sigquit_leave_no_temporary() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // 500 blocks of 1024 bytes: a record of 100 000 samples (some 3.5 MB) does not fit.
    let out = Command::new("sh")
        .current_dir(d)
        .args([
            "-c",
            "ulimit -f 500; exec \"$0\" simulate --samples 100000 --out f.csv",
        ])
        .arg(env!("CARGO_BIN_EXE_ipa-sysid"))
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(2),
        "{:?} {}",
        out.status,
        stderr(&out)
    );
    assert!(
        stderr(&out).contains("f.csv") && stderr(&out).contains("File too large"),
        "{}",
        stderr(&out)
    );
    assert!(!stderr(&out).contains(".ipa-sysid-"), "{}", stderr(&out));
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
    assert!(!d.join("f.csv").exists());

    let mut child = bin()
        .current_dir(d)
        .args(["simulate", "--samples", "3000000", "--out", "big.csv"])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut seen = false;
    while child.try_wait().unwrap().is_none() {
        if !leftovers(d).is_empty() {
            seen = true;
            // SAFETY: a plain system call on our own child's process id.
            unsafe {
                libc::kill(child.id() as libc::pid_t, libc::SIGQUIT);
            }
            break;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let status = child.wait().unwrap();
    assert!(seen, "the write was never seen in progress ({status})");
    assert_eq!(status.code(), Some(131), "{status}");
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
    assert!(!d.join("big.csv").exists());
}

// An output in a folder this user cannot write is refused before the work, naming the folder and the
// user's path, not a hidden temporary (audit s36 L-1: found after the whole run). Root writes any
// folder, so as root the run is made as `nobody` (uid 65534).
#[test]
fn an_unwritable_output_folder_is_refused_before_the_work() {
    use std::os::unix::fs::PermissionsExt;
    use std::os::unix::process::CommandExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = bin()
        .current_dir(d)
        .args(["simulate", "--samples", "2000", "--out", "rec.csv"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let nb = d.join("nb");
    std::fs::create_dir(&nb).unwrap();
    // SAFETY: getuid has no preconditions.
    let root = unsafe { libc::getuid() } == 0;
    let mut cmd = bin();
    if root {
        // nobody must reach the binary and the record, not write nb (root's, 755).
        std::fs::set_permissions(d, std::fs::Permissions::from_mode(0o755)).unwrap();
        std::fs::set_permissions(d.join("rec.csv"), std::fs::Permissions::from_mode(0o644))
            .unwrap();
        let exe = Path::new(env!("CARGO_BIN_EXE_ipa-sysid"));
        let reachable = exe
            .ancestors()
            .skip(1)
            .all(|a| std::fs::metadata(a).is_ok_and(|m| m.permissions().mode() & 0o001 != 0));
        if !reachable {
            eprintln!(
                "SKIPPED: the binary is not reachable by nobody (a folder above it is not o+x)"
            );
            return;
        }
        cmd.uid(65534).gid(65534);
    } else {
        std::fs::set_permissions(&nb, std::fs::Permissions::from_mode(0o555)).unwrap();
    }
    let out = cmd
        .current_dir(d)
        .args([
            "identify",
            "--data",
            "rec.csv",
            "--structure",
            "arx",
            "--na",
            "2",
            "--nb",
            "2",
            "--method",
            "ls",
            "--save-model",
            "nb/m.json",
        ])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--save-model = nb/m.json") && err.contains("checked before the run"),
        "{err}"
    );
    assert!(!err.contains(".ipa-sysid-"), "{err}");
    // Refused before the work: nothing of the identification was printed.
    assert!(
        out.stdout.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert_eq!(std::fs::read_dir(&nb).unwrap().count(), 0);
    // A folder output in that folder, and an earlier run's folder (with entries) that cannot be moved
    // aside in a writable folder: both refused before the run, nothing created in either.
    let w = d.join("w");
    std::fs::create_dir(&w).unwrap();
    std::fs::set_permissions(&w, std::fs::Permissions::from_mode(0o777)).unwrap();
    let r2 = w.join("R2");
    std::fs::create_dir(&r2).unwrap();
    std::fs::write(r2.join(".ipa-sysid-output"), "marker").unwrap();
    if !root {
        std::fs::set_permissions(&r2, std::fs::Permissions::from_mode(0o555)).unwrap();
    }
    let again = || {
        let mut c = bin();
        if root {
            use std::os::unix::process::CommandExt;
            c.uid(65534).gid(65534);
        }
        c.current_dir(d)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        c
    };
    let out = again()
        .args(["reproduce", "--plant", "paper", "--out", "nb/R"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--out = nb/R") && err.contains("checked before the run"),
        "{err}"
    );
    assert_eq!(std::fs::read_dir(&nb).unwrap().count(), 0);
    let out = again()
        .args(["reproduce", "--plant", "paper", "--out", "w/R2"])
        .output()
        .unwrap();
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("is not writable") && err.contains("checked before the run"),
        "{err}"
    );
    assert_eq!(std::fs::read_dir(&r2).unwrap().count(), 1);
    assert_eq!(
        std::fs::read_dir(&w).unwrap().count(),
        1,
        "nothing left beside R2"
    );
    if !root {
        std::fs::set_permissions(&nb, std::fs::Permissions::from_mode(0o755)).unwrap();
        std::fs::set_permissions(&r2, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
}

/// Whether `r` is a whole `reproduce` folder, old or new: the user's 20 000 files all there, and its
/// report either the old one (the word `stale` written before the run) or a new HTML page.
fn whole(r: &Path) -> Result<&'static str, String> {
    let notes = std::fs::read_dir(r.join("mynotes"))
        .map_err(|e| format!("mynotes: {e}"))?
        .count();
    if notes != 20_000 {
        return Err(format!("{notes} of 20000 user files"));
    }
    match std::fs::read_to_string(r.join("report.html")) {
        Ok(t) if t == "stale" => Ok("old"),
        Ok(t) if t.contains("<html") => Ok("new"),
        Ok(_) => Err("report.html is neither".into()),
        Err(e) => Err(format!("report.html: {e}")),
    }
}

// `reproduce --out R` over a folder of an earlier run to which the user added 20 000 files, stopped by
// SIGTERM at several points of the run and as soon as the new folder is in place: R is whole (old or
// new), the user's files are all there, and no `.ipa-sysid-*` file or folder is left beside it (audit
// s36 M-2: the removal raced the still-filling writer, and the holder of the previous folder was never
// listed).
#[test]
fn sigterm_during_reproduce_into_a_big_folder_leaves_no_temporary_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let r = d.join("R");
    let run = || {
        bin()
            .current_dir(d)
            .args(["reproduce", "--plant", "paper", "--out", "R"])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let out = run().wait_with_output().unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    std::fs::create_dir(r.join("mynotes")).unwrap();
    for i in 0..20_000 {
        std::fs::write(r.join(format!("mynotes/n{i}.txt")), "mine").unwrap();
    }
    // An uninterrupted run over the big folder: its length places the signals below.
    std::fs::write(r.join("report.html"), "stale").unwrap();
    let start = Instant::now();
    let out = run().wait_with_output().unwrap();
    let full = start.elapsed();
    assert!(out.status.success(), "{}", stderr(&out));
    assert_eq!(whole(&r), Ok("new"));
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
    let mut outcomes = Vec::new();
    for fraction in [0.2, 0.5, 0.75, 0.9, 1.0, 1.1] {
        std::fs::write(r.join("report.html"), "stale").unwrap();
        let mut child = run();
        let at = full.mul_f64(fraction);
        let t0 = Instant::now();
        while t0.elapsed() < at && child.try_wait().unwrap().is_none() {
            std::thread::sleep(Duration::from_millis(2));
        }
        term(child.id());
        let status = child.wait().unwrap();
        let state = whole(&r);
        assert!(state.is_ok(), "SIGTERM at {at:?}: {state:?} ({status})");
        assert!(
            leftovers(d).is_empty(),
            "SIGTERM at {at:?}: {:?}",
            leftovers(d)
        );
        outcomes.push((fraction, status.signal(), state));
    }
    // SIGTERM as soon as R is the new folder (its inode changed): the previous folder, moved into a
    // listed holder, is removed too.
    use std::os::unix::fs::MetadataExt;
    std::fs::write(r.join("report.html"), "stale").unwrap();
    let inode = std::fs::metadata(&r).unwrap().ino();
    let mut child = run();
    let mut seen = false;
    while child.try_wait().unwrap().is_none() {
        if std::fs::metadata(&r).is_ok_and(|m| m.ino() != inode) {
            term(child.id());
            seen = true;
            break;
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    let status = child.wait().unwrap();
    assert_eq!(whole(&r), Ok("new"), "({status}, seen {seen})");
    assert!(leftovers(d).is_empty(), "{:?}", leftovers(d));
    eprintln!("run {full:?}; outcomes {outcomes:?}; at the swap: seen {seen}, {status}");
}

/// The process ids of `pid`'s children (Linux's /proc/PID/task/*/children).
fn children(pid: u32) -> Vec<u32> {
    let mut out = Vec::new();
    if let Ok(tasks) = std::fs::read_dir(format!("/proc/{pid}/task")) {
        for t in tasks.flatten() {
            if let Ok(text) = std::fs::read_to_string(t.path().join("children")) {
                out.extend(
                    text.split_whitespace()
                        .filter_map(|p| p.parse::<u32>().ok()),
                );
            }
        }
    }
    out
}

// `bench long` stopped by SIGTERM while its child `simulate` writes a record: the child is ended and
// waited for (no orphan left running) and the benchmark's own record folder in the temporary folder
// is removed (audit s36 M-4).
#[cfg(target_os = "linux")]
#[test]
fn sigterm_to_bench_long_ends_its_child_and_removes_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let tmp = dir.path().join("tmp");
    std::fs::create_dir(&tmp).unwrap();
    let mut child = bin()
        .current_dir(dir.path())
        .env("TMPDIR", &tmp)
        .args(["bench", "long", "--rows", "5e6", "--no-numpy"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let folder: PathBuf = tmp.join(format!("ipa-sysid-bench-long-{}", child.id()));
    let start = Instant::now();
    let mut grandchildren = Vec::new();
    while child.try_wait().unwrap().is_none() && start.elapsed() < Duration::from_secs(60) {
        grandchildren = children(child.id());
        if !grandchildren.is_empty() && folder.is_dir() {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(!grandchildren.is_empty(), "the child was never seen");
    // Let the child start its work, then stop the benchmark.
    std::thread::sleep(Duration::from_millis(300));
    term(child.id());
    let status = child.wait().unwrap();
    assert_eq!(status.signal(), Some(libc::SIGTERM), "{status}");
    for g in &grandchildren {
        // Reaped by the benchmark before it ended: no such process (a zombie would still be listed).
        assert!(
            !Path::new(&format!("/proc/{g}")).exists(),
            "child {g} is still there: {:?}",
            std::fs::read_to_string(format!("/proc/{g}/cmdline"))
        );
    }
    assert!(!folder.exists(), "{} is left", folder.display());
    assert_eq!(std::fs::read_dir(&tmp).unwrap().count(), 0);
}

// `bench narx --peer PYTHON` stopped by SIGTERM while its peer runs (here a stand-in interpreter that
// sleeps when asked to import the peer's module): the peer is ended and waited for, not orphaned (audit
// s36 M-4, checked for the peers of bench oe/narx).
#[cfg(target_os = "linux")]
#[test]
fn sigterm_to_bench_narx_ends_its_peer() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fake = d.join("python");
    std::fs::write(&fake, "#!/bin/sh\nexec sleep 30\n").unwrap();
    std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755)).unwrap();
    std::fs::create_dir(d.join("data")).unwrap();
    let mut child = bin()
        .current_dir(d)
        .args(["bench", "narx", "--data-dir", "data", "--peer", "./python"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let mut peers = Vec::new();
    while child.try_wait().unwrap().is_none() && start.elapsed() < Duration::from_secs(30) {
        peers = children(child.id());
        if !peers.is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    assert!(!peers.is_empty(), "the peer was never seen");
    std::thread::sleep(Duration::from_millis(100));
    term(child.id());
    let status = child.wait().unwrap();
    assert_eq!(status.signal(), Some(libc::SIGTERM), "{status}");
    for p in &peers {
        assert!(
            !Path::new(&format!("/proc/{p}")).exists(),
            "peer {p} is still there"
        );
    }
}
