//! A documented output is one the current code produces: every block of the README and of `docs/*.md`
//! that is marked as a command's output is re-run here with the binary and compared with the text.
//!
//! Markers (HTML comments, invisible on the rendered page):
//! - `<!-- doc-check: run -->` before a ```` ```sh ```` block: its `ipa-sysid …` lines are run, in order,
//!   in one scratch folder per document (comments after `#` are ignored);
//! - `<!-- doc-check: output of: ipa-sysid ARGS -->` before a ```` ```text ```` block: `ipa-sysid ARGS` is
//!   run in that folder and its standard output must equal the block, line by line (trailing blanks
//!   ignored).
//!
//! `DOC_CHECK_UPDATE=1 cargo test -p ipa-sysid --test docs_cli` rewrites the blocks with what the binary
//! prints now (then read the diff: the text around a block may need to follow). The Python examples of
//! `docs/python.md` are checked the same way by `python/tests/test_docs.py`.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};
use std::process::Command;

const RUN: &str = "<!-- doc-check: run -->";
const OUTPUT_OF: &str = "<!-- doc-check: output of: ";

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Splits a command line on blanks (the documented commands quote nothing).
fn run(dir: &Path, line: &str) -> String {
    let line = line.split('#').next().unwrap_or("").trim();
    let mut words = line.split_whitespace();
    assert_eq!(
        words.next(),
        Some("ipa-sysid"),
        "not an ipa-sysid command: {line}"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(words)
        .current_dir(dir)
        .output()
        .expect("run ipa-sysid");
    assert!(
        out.status.success(),
        "`{line}` failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// The fenced block starting at or after line `from`: (index of the opening fence, index of the closing).
fn fenced(lines: &[&str], from: usize) -> (usize, usize) {
    let open = (from..lines.len())
        .find(|&i| lines[i].starts_with("```"))
        .expect("a fenced block after the marker");
    let close = (open + 1..lines.len())
        .find(|&i| lines[i].starts_with("```"))
        .expect("the block's closing fence");
    (open, close)
}

/// Checks (or, with `DOC_CHECK_UPDATE`, rewrites) the marked blocks of one document; returns how many
/// output blocks it compared.
fn check(doc: &str) -> usize {
    let path = repo().join(doc);
    let text = std::fs::read_to_string(&path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let scratch = tempfile::tempdir().unwrap();
    let update = std::env::var_os("DOC_CHECK_UPDATE").is_some();
    let mut rewritten: Vec<String> = Vec::new();
    let (mut i, mut compared, mut mismatches) = (0, 0, Vec::new());
    while i < lines.len() {
        let line = lines[i];
        rewritten.push(line.to_string());
        if line.trim() == RUN {
            let (open, close) = fenced(&lines, i + 1);
            for cmd in &lines[open + 1..close] {
                if cmd.trim_start().starts_with("ipa-sysid") {
                    run(scratch.path(), cmd);
                }
            }
        } else if let Some(rest) = line.trim().strip_prefix(OUTPUT_OF) {
            let cmd = rest.trim_end_matches("-->").trim();
            let (open, close) = fenced(&lines, i + 1);
            let got = run(scratch.path(), cmd);
            let want: Vec<&str> = lines[open + 1..close]
                .iter()
                .map(|l| l.trim_end())
                .collect();
            let have: Vec<&str> = got.lines().map(str::trim_end).collect();
            compared += 1;
            if want != have {
                mismatches.push(format!(
                    "{doc}:{}: the output of `{cmd}` differs from the documented block:\n--- documented\n{}\n--- now\n{}",
                    open + 2,
                    want.join("\n"),
                    have.join("\n")
                ));
            }
            rewritten.extend(lines[i + 1..=open].iter().map(|l| l.to_string()));
            rewritten.extend(have.iter().map(|l| l.to_string()));
            rewritten.push(lines[close].to_string());
            i = close + 1;
            continue;
        }
        i += 1;
    }
    if update && !mismatches.is_empty() {
        let mut out = rewritten.join("\n");
        out.push('\n');
        std::fs::write(&path, out).unwrap();
        eprintln!("{doc}: rewrote {} block(s)", mismatches.len());
    } else {
        assert!(mismatches.is_empty(), "{}", mismatches.join("\n\n"));
    }
    compared
}

#[test]
fn the_readme_worked_example_prints_what_the_readme_says() {
    assert!(check("README.md") >= 1);
}

#[test]
fn the_control_page_prints_what_it_says() {
    assert!(check("docs/control.md") >= 1);
}

#[test]
fn the_identification_page_prints_what_it_says() {
    assert!(check("docs/identification.md") >= 1);
}
