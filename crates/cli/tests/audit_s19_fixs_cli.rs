//! Audit s19, the command line's findings L-3, L-4, L-7, L-8 and L-9 through the binary: a NaN `--ts`,
//! errors that blamed flags the user did not pass, a first row too long for `--stream on`'s check, a
//! header-only record given to `track`, and the time column chosen as the input. Each expectation is
//! written from what the user passed (the flag, the spec key, the line), never copied from the output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Stdio;

mod common;
use common::{bin, identify_arx, run as ipa_sysid, s, stderr};

/// A record `t,u,y` of `n` samples at Ts = 0.01 s: u a ±60-count square wave of period 40, y the ARX
/// y(k) = 0.9 y(k−1) + 0.05 u(k−1).
fn record(dir: &Path, n: usize) -> PathBuf {
    let path = dir.join("r.csv");
    let mut text = String::from("t,u,y\n");
    let mut y = 0.0f64;
    let mut u_prev = 0.0;
    for k in 0..n {
        let u = if (k / 20) % 2 == 0 { 60.0 } else { -60.0 };
        y = 0.9 * y + 0.05 * u_prev;
        text.push_str(&format!("{},{u},{y}\n", k as f64 * 0.01));
        u_prev = u;
    }
    std::fs::write(&path, text).unwrap();
    path
}

/// A Hammerstein model file at Ts = 0.01 s: A = 1 − 0.9 z⁻¹, B = 1, nk = 1, deadzone ±20 counts,
/// slopes 0.005.
fn model_file(dir: &Path) -> PathBuf {
    let path = dir.join("m.json");
    let doc = serde_json::json!({
        "format": "ipa-sysid-model", "version": 2,
        "model": {
            "kind": "hammerstein", "ts": 0.01, "na": 1, "nb": 1, "nk": 1,
            "a": [-0.9], "b": [1.0], "offset": null,
            "deadzone": {"b_l": -20.0, "b_r": 20.0, "m_l": 0.005, "m_r": 0.005},
            "noise_model": "output-error"
        }
    });
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

// L-3: every wrong --ts of a model plant is refused, NaN included (NaN compares false with everything,
// so `|ts − Ts| > tol` let it through, and the run went on at the model's Ts without a word).
#[test]
fn a_nan_ts_is_refused_for_the_paper_and_a_model_plant() {
    let dir = tempfile::tempdir().unwrap();
    let m = model_file(dir.path());
    let out = dir.path().join("o.csv");
    for plant in ["paper".to_string(), format!("model:{}", s(&m))] {
        let o = ipa_sysid(&[
            "simulate",
            "--plant",
            &plant,
            "--samples",
            "5",
            "--out",
            s(&out),
            "--ts",
            "nan",
        ]);
        assert_eq!(o.status.code(), Some(2), "{plant}: {}", stderr(&o));
        // Both models are sampled at 0.01 s (the paper's Table III; the file written above).
        assert!(
            stderr(&o).contains("invalid setting --ts = NaN")
                && stderr(&o).contains("sampled at Ts = 0.01 s"),
            "{plant}: {}",
            stderr(&o)
        );
        assert!(!out.exists(), "{plant}: nothing is written");
    }
    // The model's own Ts is still accepted.
    let o = ipa_sysid(&[
        "simulate",
        "--plant",
        "paper",
        "--samples",
        "5",
        "--out",
        s(&out),
        "--ts",
        "0.01",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

// L-9: the time column (`t`, or the one --t-col names) as the input or the output is refused as
// `--y-col` equal to `--u-col` is, in memory and streamed.
#[test]
fn the_time_column_cannot_be_the_input_or_the_output() {
    let dir = tempfile::tempdir().unwrap();
    let data = record(dir.path(), 400);
    let base = [identify_arx(&data, "1", "1", "ls"), vec!["--nk", "1"]].concat();
    for stream in ["off", "on"] {
        for flag in ["--u-col", "--y-col"] {
            let mut args = base.to_vec();
            args.extend([flag, "t", "--stream", stream]);
            let o = ipa_sysid(&args);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
            let want = format!("invalid setting {flag} = t: a column different from --t-col");
            assert!(stderr(&o).contains(&want), "{args:?}: {}", stderr(&o));
        }
    }
    // A time column named otherwise (--t-col time) is protected the same way; `t` is then a free name.
    let renamed = dir.path().join("time.csv");
    let text = std::fs::read_to_string(&data)
        .unwrap()
        .replacen("t,u,y", "time,u,y", 1);
    std::fs::write(&renamed, text).unwrap();
    let o = ipa_sysid(
        &[
            identify_arx(&renamed, "1", "1", "ls"),
            vec!["--nk", "1", "--t-col", "time", "--u-col", "time"],
        ]
        .concat(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("invalid setting --u-col = time: a column different from --t-col"),
        "{}",
        stderr(&o)
    );
    // The ordinary choice still works.
    let o = ipa_sysid(&base);
    assert!(o.status.success(), "{}", stderr(&o));
}

// L-8: `track` on a record that ends after its header has no model to report: exit 2 with the other
// commands' words, from a file and from standard input.
#[test]
fn track_on_a_header_only_record_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let hdr = dir.path().join("hdr.csv");
    std::fs::write(&hdr, "t,u,y\n").unwrap();
    let o = ipa_sysid(&["track", "--data", s(&hdr)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the file has a header but no data rows"),
        "{}",
        stderr(&o)
    );
    let mut child = bin()
        .args(["track", "--data", "-", "--ts", "0.01"])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    child.stdin.take().unwrap().write_all(b"t,u,y\n\n").unwrap();
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("the file has a header but no data rows"),
        "{}",
        stderr(&o)
    );
    // One data row is a (short) run, not this error.
    std::fs::write(&hdr, "t,u,y\n0,1,2\n").unwrap();
    let o = ipa_sysid(&["track", "--data", s(&hdr)]);
    assert!(!stderr(&o).contains("no data rows"), "{}", stderr(&o));
}

// L-7: `--stream on` checks the header and the first rows within the file's first MiB + 1 byte (audit s22
// H-B2: the bound of one CSV line, 2^20 bytes, and one more); a first data row that does not end there is
// named as such, at its line, not "a header but no data rows".
#[test]
fn a_first_row_longer_than_the_streamed_check_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let long = dir.path().join("long.csv");
    let mut text = String::from("t,u,y\n");
    text.push_str(&"1".repeat(1_100_000));
    text.push_str(",1,1\n");
    for k in 1..400 {
        text.push_str(&format!("{},{},{}\n", k as f64 * 0.01, k % 7, k % 5));
    }
    std::fs::write(&long, text).unwrap();
    let o = ipa_sysid(
        &[
            identify_arx(&long, "1", "1", "ls"),
            vec!["--nk", "1", "--stream", "on"],
        ]
        .concat(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    // The row is line 2 of the file; the check reads 2^20 + 1 = 1048577 bytes.
    assert!(e.contains(&format!("{}:2:1:", s(&long))), "{e}");
    assert!(
        e.contains(&format!(
            "the first data row does not end within the file's first {} bytes",
            (1 << 20) + 1
        )),
        "{e}"
    );
    assert!(!e.contains("no data rows"), "{e}");
}

/// `tune --model M --spec SPEC` with a short search.
fn tune(dir: &Path, spec: &str) -> std::process::Output {
    let m = model_file(dir);
    let out = dir.join("c.json");
    ipa_sysid(&[
        "tune",
        "--model",
        s(&m),
        "--spec",
        spec,
        "--out",
        s(&out),
        "--variants",
        "1",
        "--max-evaluations",
        "8",
    ])
}

// L-4: a specification whose scale takes the search's gains beyond the controller's bound (1e6) is
// refused naming the key the user wrote, not `--kp` (tune has no such flag); so is a `u-max` beyond
// the controller's command bound (1e6 counts), not as `--u-max`.
#[test]
fn tune_errors_name_the_spec_key_not_a_flag_tune_lacks() {
    let dir = tempfile::tempdir().unwrap();
    // The search's largest gain is Ki = e^6.9 counts/(mm·s) at the IPA's scale; a smallest step d < 10
    // mm multiplies it by 10 / d, so d must be at least 10 e^6.9 / 1e6 mm (u-max = 255).
    let need = 10.0 * 6.9f64.exp() / 1e6;
    let unit = 10f64.powf(need.log10().floor() - 2.0);
    let need = (need / unit).ceil() * unit;
    let o = tune(dir.path(), "steps=1e-9");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("invalid setting --spec = steps=1e-9"), "{e}");
    assert!(
        e.contains(&format!("steps of at least {need} mm")),
        "{need}: {e}"
    );
    assert!(!e.contains("--kp") && !e.contains("--ki"), "{e}");
    let o = tune(dir.path(), "u-max=1e308");
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("invalid setting --spec = u-max=1e308") && e.contains("at most 1e6 counts"),
        "{e}"
    );
    assert!(!e.contains("--u-max"), "{e}");
    // A step just above the bound passes this check (whatever the short search then finds).
    let o = tune(dir.path(), &format!("steps={}", need * 1.01));
    assert!(!stderr(&o).contains("steps of at least"), "{}", stderr(&o));
}

// L-4: back-calculation without --tracking-time uses Ti = Kp/Ki; when that default is unusable (Ki so
// small that Kp/Ki overflows) the error says it is the default and names what the user passed.
#[test]
fn an_unusable_default_tracking_time_does_not_blame_tracking_time() {
    let o = ipa_sysid(&[
        "control",
        "--plant",
        "paper",
        "--setpoint",
        "50",
        "--anti-windup",
        "back-calculation",
        "--ki",
        "1e-320",
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    // Kp = 14 (the default) over Ki = 1e-320 overflows to inf.
    assert!(!e.contains("--tracking-time ="), "{e}");
    assert!(
        e.contains("invalid setting --anti-windup = back-calculation"),
        "{e}"
    );
    assert!(
        e.contains("Ti = Kp/Ki = inf s") && e.contains("Ki = 1e-320"),
        "{e}"
    );
    assert!(e.contains("give --tracking-time"), "{e}");
}
