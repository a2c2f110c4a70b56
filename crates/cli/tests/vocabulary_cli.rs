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
