//! One vocabulary across the commands: help texts say what the command really does, and the same word
//! means the same flag everywhere.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::process::Command;

fn help(cmd: &str) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args([cmd, "--help"])
        .output()
        .expect("run ipa-sysid");
    assert!(out.status.success());
    String::from_utf8(out.stdout).unwrap()
}

// `order` ranks on a selection part of the estimation record; the test record never ranks.
#[test]
fn order_help_says_it_ranks_on_the_selection_part() {
    let h = help("order");
    let about = h.lines().next().unwrap();
    assert!(about.contains("selection part"), "{about}");
    assert!(!about.contains("by validation fit"), "{about}");
}

// Every command that writes a JSON document takes it as `--json FILE` (track's former `--json-summary`
// still works).
#[test]
fn every_command_writing_json_calls_the_flag_json() {
    for cmd in [
        "identify",
        "validate",
        "control",
        "order",
        "delay",
        "montecarlo",
        "track",
    ] {
        let h = help(cmd);
        assert!(h.contains("--json <"), "{cmd} --help has no --json:\n{h}");
    }
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.json"), dir.path().join("b.json"));
    let data = "t,u,y\n0,0,0\n0.01,10,0\n0.02,-10,0.1\n0.03,5,0.05\n";
    for (flag, path) in [("--json", &a), ("--json-summary", &b)] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
            .args(["track", "--data", "-", flag, path.to_str().unwrap()])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::null())
            .spawn()
            .unwrap();
        use std::io::Write;
        child
            .stdin
            .take()
            .unwrap()
            .write_all(data.as_bytes())
            .unwrap();
        assert!(child.wait().unwrap().success(), "{flag}");
    }
    assert_eq!(
        std::fs::read_to_string(&a).unwrap(),
        std::fs::read_to_string(&b).unwrap()
    );
}
