//! Audit s23's CLI findings fixed by helper fixak (session 24), through the binary: a folder output
//! named by a symbolic link or a device is refused in words that say what it is (L-B3); `identify
//! --data FOLDER` reads the folder's `.mat` records as `--data FILE.mat` does (L-B6); `track --follow`
//! after a copy-truncate rotation counts lines in the new content and accepts its restarted clock (a
//! new time origin, said in a warning; L-B5). L-B2 (a file truncated under a `--stream` pass) is tested
//! deterministically in `crates/core/src/data/stream.rs` (the truncation made from the pass's own
//! consumer). Expectations are closed forms and the words asked for, never the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;

mod common;
use common::{arx_signals, identify_arx, lcg, run as ipa_sysid, stderr, write_csv, write_mat};

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

// L-B3: reproduce and simulate --fleet (the two folder outputs) refuse a link to a folder naming it a
// link and its target, and /dev/null as a device; the link and its folder are left as they were.
#[test]
fn a_folder_output_names_a_link_or_a_device() {
    let dir = tempfile::tempdir().unwrap();
    let target = dir.path().join("target_dir");
    std::fs::create_dir(&target).unwrap();
    let link = dir.path().join("rlink");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    for args in [
        vec!["reproduce", "--out", s(&link)],
        vec![
            "simulate",
            "--fleet",
            "2",
            "--worn",
            "0.5",
            "--seed",
            "1",
            "--out",
            s(&link),
        ],
    ] {
        let o = ipa_sysid(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains(&format!(
                "a folder, not a symbolic link ({} is a symbolic link to {}, a folder; pass the folder itself)",
                link.display(),
                target.display()
            )),
            "{args:?}: {e}"
        );
        assert!(!e.contains("this is a file"), "{e}");
        assert!(std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read_dir(&target).unwrap().count(), 0);
    }
    for args in [
        vec!["reproduce", "--out", "/dev/null"],
        vec![
            "simulate",
            "--fleet",
            "2",
            "--worn",
            "0.5",
            "--seed",
            "1",
            "--out",
            "/dev/null",
        ],
    ] {
        let o = ipa_sysid(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(e.contains("a folder (this is a device)"), "{args:?}: {e}");
        assert!(!e.contains("os error"), "{e}");
    }
}

// L-B6: a folder of one CSV and one .mat record of two different first-order systems gives one line
// for each, in name order, with each system's exact coefficients (noise-free data: least squares
// recovers a1 = −0.8, b1 = 0.5 and a1 = −0.6, b1 = 2); a folder of .mat records only is read too.
#[test]
fn a_folder_reads_its_mat_records() {
    let dir = tempfile::tempdir().unwrap();
    let fold = dir.path().join("matdir");
    std::fs::create_dir(&fold).unwrap();
    let mut g = lcg(7);
    let input: Vec<f64> = (0..400).map(|_| g.unit() * 2.0 - 1.0).collect();
    let (u1, y1) = arx_signals(400, &[0.8], &[0.5], |k| input[k]);
    let (u2, y2) = arx_signals(400, &[0.6], &[2.0], |k| input[k]);
    write_csv(&fold.join("a.csv"), "u,y", None, &[&u1, &y1]);
    write_mat(&fold.join("b.mat"), &["u", "y"], &[&u2, &y2]);
    let check = |fold: &Path, expected: &[(&str, f64, f64)]| {
        let mut args = identify_arx(fold, "1", "1", "ls");
        args.extend(["--ts", "1"]);
        let o = ipa_sysid(&args);
        assert!(o.status.success(), "{}", stderr(&o));
        let lines: Vec<serde_json::Value> = String::from_utf8_lossy(&o.stdout)
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), expected.len(), "{lines:?}");
        for (l, (name, a1, b1)) in lines.iter().zip(expected) {
            assert!(l["file"].as_str().unwrap().ends_with(name), "{l}");
            let (a, b) = (
                l["model"]["a"][0].as_f64().unwrap(),
                l["model"]["b"][0].as_f64().unwrap(),
            );
            assert!(
                (a - a1).abs() < 1e-9 && (b - b1).abs() < 1e-9,
                "{name}: a {a}, b {b}"
            );
        }
    };
    check(&fold, &[("a.csv", -0.8, 0.5), ("b.mat", -0.6, 2.0)]);
    std::fs::remove_file(fold.join("a.csv")).unwrap();
    check(&fold, &[("b.mat", -0.6, 2.0)]);
}

// L-B5: a followed file truncated and written again from its beginning (header, then rows whose clock
// starts again at 0 s): track reads on to the idle time-out instead of refusing the restarted clock at
// a line of the old file; the restart is said in a warning naming line 2 of the new content and t = 0.
// The rotation happens while track waits (sleeps of seconds around a poll of 50 ms and an idle
// time-out of 4 s); every sample of both contents is counted.
#[test]
fn a_rotated_followed_file_is_read_on_with_a_new_time_origin() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = lcg(3);
    let input: Vec<f64> = (0..600).map(|_| g.unit() * 2.0 - 1.0).collect();
    let (u, y) = arx_signals(600, &[0.8], &[0.5], |k| input[k]);
    let rows = |n: usize| -> String {
        let mut t = String::from("t,u,y\n");
        for k in 0..n {
            t.push_str(&format!("{},{},{}\n", k as f64 * 0.01, u[k], y[k]));
        }
        t
    };
    let live = dir.path().join("live.csv");
    std::fs::write(&live, rows(500)).unwrap();
    let json = dir.path().join("summary.json");
    let child = common::bin()
        .args([
            "track",
            "--follow",
            s(&live),
            "--idle-timeout",
            "4",
            "--every",
            "100",
        ])
        .args(["--json", s(&json)])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(1500));
    std::fs::OpenOptions::new()
        .write(true)
        .open(&live)
        .unwrap()
        .set_len(0)
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(500));
    {
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&live)
            .unwrap();
        f.write_all(rows(300).as_bytes()).unwrap();
    }
    let o = child.wait_with_output().unwrap();
    let e = stderr(&o);
    assert!(o.status.success(), "{e}");
    assert!(e.contains("truncated to 0 bytes"), "{e}");
    assert!(
        e.contains("from line 2 of the new content (after its header line) on, time starts again at t = 0 s"),
        "{e}"
    );
    assert!(!e.contains("does not increase"), "{e}");
    assert!(e.contains("800 samples"), "{e}");
}
