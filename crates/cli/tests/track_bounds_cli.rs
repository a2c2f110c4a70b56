//! `ipa-sysid track` on hostile flags and streams (issue 21, items 2 and 4): every size a flag drives is
//! bounded before anything is allocated — the orders by the bound `identify` applies, the windows by a
//! record's limit — and a line is bounded as it is read. Each is refused with exit code 2 and a message
//! naming the flag or the line; nothing panics (101) or aborts (134).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::io::Write;
use std::process::{Command, Output, Stdio};

use proptest::prelude::*;

const BIN: &str = env!("CARGO_BIN_EXE_ipa-sysid");
const U64_MAX: &str = "18446744073709551615";

fn track(flags: &[&str], stdin: &[u8]) -> Output {
    let mut child = Command::new(BIN)
        .args(["track", "--data", "-"])
        .args(flags)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut input = child.stdin.take().unwrap();
    // The tool may stop reading early (an error): a broken pipe is then expected.
    let _ = input.write_all(stdin);
    drop(input);
    child.wait_with_output().unwrap()
}

/// A short record of t,u,y lines (a square wave through a deadzone and an integrator).
fn record(n: usize) -> Vec<u8> {
    let mut s = String::from("t,u,y\n");
    let mut y = 0.0;
    for k in 0..n {
        let u = if (k / 20) % 2 == 0 { 80.0 } else { -60.0 };
        y += 1e-3 * u;
        s += &format!("{},{u},{y}\n", k as f64 * 0.01);
    }
    s.into_bytes()
}

fn refused(o: &Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(needle), "expected '{needle}' in: {err}");
}

// identify's bound on the orders (at most 100) holds for track: before, --nk/--nb u64::MAX panicked
// (index out of bounds), --na 100000 aborted on an 80 GB allocation and --na u64::MAX exited 0.
#[test]
fn orders_above_identify_bound_are_refused_naming_the_flag() {
    let data = record(200);
    for (flag, value) in [
        ("--na", "100000"),
        ("--na", U64_MAX),
        ("--nb", U64_MAX),
        ("--nk", U64_MAX),
        ("--na", "101"),
    ] {
        let o = track(&[flag, value], &data);
        refused(&o, &format!("{flag} = {value}: an order of at most 100"));
    }
    // The same words as identify's.
    let o = track(&["--structure", "arx", "--na", "0", "--nb", "0"], &data);
    refused(&o, "no parameter to estimate");
    // The bound itself is accepted.
    let o = track(&["--structure", "arx", "--na", "100", "--nb", "2"], &data);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

// The windows are bounded by a record's limit (50 000 000 samples) and reserved as samples come:
// before, u64::MAX panicked on the capacity.
#[test]
fn windows_beyond_a_record_are_refused_naming_the_flag() {
    let data = record(200);
    for flag in ["--pe-window", "--detect-calibration"] {
        let o = track(&[flag, U64_MAX], &data);
        refused(&o, &format!("{flag} = {U64_MAX}"));
        let o = track(&[flag, "50000000"], &data);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
}

// A stream that never ends a line (binary data, /dev/zero, a wrong baud rate) is refused once a line
// passes 1 MiB, naming the line; before, the line buffer grew until memory ran out.
#[test]
fn a_stream_without_line_ends_is_refused_at_the_line_bound() {
    let mut data = b"t,u,y\n0,1,2\n".to_vec();
    data.extend(std::iter::repeat_n(b'7', 3 << 20));
    let o = track(&[], &data);
    refused(&o, "<stdin>:3:1: the line is longer than 1048576 bytes");
    if std::path::Path::new("/dev/zero").exists() {
        let o = Command::new(BIN)
            .args(["track", "--data", "-"])
            .stdin(std::fs::File::open("/dev/zero").unwrap())
            .output()
            .unwrap();
        refused(&o, "<stdin>:1:1: the line is longer than");
    } else {
        eprintln!("SKIPPED: no /dev/zero on this system");
    }
}

/// A size flag's value: small (the usual range, and around the bounds) or any u64.
fn size() -> impl Strategy<Value = u64> {
    prop_oneof![0u64..300, 99u64..103, any::<u64>()]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 40, ..ProptestConfig::default() })]
    // Any values of track's size flags: a result (exit 0) or a refusal (exit 2) with a message, never a
    // panic (101), an abort (134) or a signal.
    #[test]
    fn any_size_flags_give_a_result_or_a_message(
        na in size(), nb in size(), nk in size(), pe in size(), cal in size(), warm in size(),
        every in size(), arx in any::<bool>(),
    ) {
        let values = [na, nb, nk, pe, cal, warm, every].map(|v| v.to_string());
        let mut flags = vec![
            "--na", &values[0], "--nb", &values[1], "--nk", &values[2], "--pe-window", &values[3],
            "--detect-calibration", &values[4], "--detect-warmup", &values[5], "--every", &values[6],
        ];
        if arx {
            flags.extend(["--structure", "arx"]);
        }
        let o = track(&flags, &record(300));
        let err = String::from_utf8_lossy(&o.stderr);
        prop_assert!(matches!(o.status.code(), Some(0 | 2)), "{:?} {flags:?}: {err}", o.status);
        if o.status.code() == Some(2) {
            prop_assert!(err.contains("error: "), "{flags:?}: {err}");
        }
    }
}
