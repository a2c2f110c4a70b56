//! A model file with an absurd coefficient is blamed, not the data (audit s17 L-c rest), through the
//! binary: `validate` names the model file and the coefficient when one term |θ| · max|signal| of the
//! prediction is beyond √(f64::MAX / N) (computed here) while the record's own values are modest; a
//! record whose own values are beyond that bound is still the data's fault.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;
use std::process::Output;

mod common;
use common::{bin, stderr};

/// A record of N = 200 rows: u a ±1 square wave of period 20, y(k) = 0.5 y(k−1) + `scale` · u(k−1)
/// (so |y| < 2 · scale), Ts = 0.1 s.
fn record(path: &Path, scale: f64) {
    let mut text = String::from("t,u,y\n");
    let mut y_prev = 0.0;
    let mut u_prev = 0.0;
    for k in 0..200 {
        let u = if (k / 10) % 2 == 0 { 1.0 } else { -1.0 };
        let y = 0.5 * y_prev + scale * u_prev;
        text.push_str(&format!("{},{u},{y:e}\n", k as f64 * 0.1));
        (y_prev, u_prev) = (y, u);
    }
    std::fs::write(path, text).unwrap();
}

/// An ARX(2, 1, 1) model file with A = 1 + a1 q^-1 + a2 q^-2, B = b1, offset c.
fn model(path: &Path, a: [f64; 2], b1: f64, offset: Option<f64>) {
    let offset = offset.map_or("null".to_string(), |c| format!("{c:e}"));
    std::fs::write(
        path,
        format!(
            r#"{{"format": "ipa-sysid-model", "version": 2, "model": {{"kind": "arx", "ts": 0.1,
               "na": 2, "nb": 1, "nk": 1, "a": [{:e}, {:e}], "b": [{b1:e}], "offset": {offset}}}}}"#,
            a[0], a[1]
        ),
    )
    .unwrap();
}

fn validate(dir: &Path, model: &str, data: &str) -> Output {
    bin()
        .current_dir(dir)
        .args(["validate", "--model", model, "--data", data])
        .output()
        .unwrap()
}

/// (model file, [a1, a2], b1, offset c, the words that name the absurd coefficient)
type Case = (&'static str, [f64; 2], f64, Option<f64>, &'static str);

// √(f64::MAX / 200) ≈ 9.5e152: a2 = 1e308 on |y| < 2 gives a term near 1e308 (one term beyond it);
// b1 = 1e300 on |u| = 1 likewise; an offset of 1e300 likewise. Each is named, with the file, and the
// data's advice ("rescale the data") is not given.
#[test]
fn an_absurd_coefficient_is_named_with_its_model_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    record(&p.join("rec.csv"), 1.0);
    let limit = (f64::MAX / 200.0).sqrt();
    let cases: [Case; 3] = [
        ("a.json", [-0.5, 1e308], 1.0, None, "a2 = 1e308"),
        ("b.json", [-0.5, 0.0], 1e300, None, "b1 = 1e300"),
        ("c.json", [-0.5, 0.0], 1.0, Some(1e300), "offset c = 1e300"),
    ];
    for (file, a, b1, c, named) in cases {
        // The premise, computed here: the named term alone exceeds the bound, the data do not.
        let term = a[1].abs().max(b1.abs()).max(c.unwrap_or(0.0).abs());
        assert!(term > limit && 2.0 < limit);
        model(&p.join(file), a, b1, c);
        let o = validate(p, file, "rec.csv");
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(1), "{e}");
        assert!(e.contains(&format!("{file}: the model's {named}")), "{e}");
        assert!(e.contains("absurd coefficient"), "{e}");
        assert!(e.contains("rec.csv is not to blame"), "{e}");
        assert!(!e.contains("rescale the data"), "{e}");
    }
}

// The other way round: a sane model (a1 = −0.5, b1 = 1) on a record scaled by 1e160, whose |y| up to
// 2e160 is itself beyond √(f64::MAX / 200): the data are to blame, and the error says so.
#[test]
fn a_record_beyond_the_bound_is_still_the_datas_fault() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    record(&p.join("huge.csv"), 1e160);
    assert!(1e160 > (f64::MAX / 200.0).sqrt());
    model(&p.join("m.json"), [-0.5, 0.0], 1.0, None);
    let o = validate(p, "m.json", "huge.csv");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(e.contains("rescale the data"), "{e}");
    assert!(!e.contains("absurd coefficient"), "{e}");
}

fn validate_streamed(dir: &Path, model: &str, data: &str) -> Output {
    bin()
        .current_dir(dir)
        .args(["validate", "--stream", "--model", model, "--data", data])
        .output()
        .unwrap()
}

// `validate --stream` reads the record in passes but blames the same file and coefficient, in the same
// words, as `validate` on the record in memory (one path: the record's sizes, gathered in one more pass
// only on the failure); a record beyond the bound is still the data's fault there too.
#[test]
fn the_streamed_validate_blames_the_model_file_as_the_in_memory_one_does() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    record(&p.join("rec.csv"), 1.0);
    record(&p.join("huge.csv"), 1e160);
    let cases: [Case; 3] = [
        ("a.json", [-0.5, 1e308], 1.0, None, "a2 = 1e308"),
        ("b.json", [-0.5, 0.0], 1e300, None, "b1 = 1e300"),
        ("c.json", [-0.5, 0.0], 1.0, Some(1e300), "offset c = 1e300"),
    ];
    for (file, a, b1, c, named) in cases {
        model(&p.join(file), a, b1, c);
        let (held, streamed) = (
            validate(p, file, "rec.csv"),
            validate_streamed(p, file, "rec.csv"),
        );
        let e = stderr(&streamed);
        assert_eq!(streamed.status.code(), Some(1), "{e}");
        assert!(e.contains(&format!("{file}: the model's {named}")), "{e}");
        assert!(e.contains("rec.csv is not to blame"), "{e}");
        assert!(!e.contains("rescale the data"), "{e}");
        assert_eq!(e, stderr(&held), "{file}: streamed vs in memory");
    }
    model(&p.join("m.json"), [-0.5, 0.0], 1.0, None);
    let o = validate_streamed(p, "m.json", "huge.csv");
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{e}");
    assert!(!e.contains("absurd coefficient"), "{e}");
}
