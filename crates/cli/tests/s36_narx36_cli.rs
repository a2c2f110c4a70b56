//! Session 36 (narx36): a saturation on too few input levels is refused with the level count it
//! needs (audit s35b L-8).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;

use common::bin;

// A saturation x = m clamp(u, s_l, s_r) is determined by a level at or beyond each limit and two
// inside the linear interval: 1 + 2 + 1 = 4 distinct levels. The input u ∈ {−1, 0, 1} (period 7:
// −1, 0, 1, 1, 0, −1, 0) drives y(k) = 0.8 y(k−1) + u(k−1); three levels are refused with the
// count, the levels and the number needed (not "regressor m is zero"), exit 2; a fourth level (2)
// lets the identification run.
#[test]
fn a_saturation_on_three_levels_says_it_needs_four() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, pattern: &[f64]| {
        let mut y = 0.0;
        let mut u_prev = 0.0;
        let mut text = String::from("u,y\n");
        for k in 0..500 {
            let u = pattern[k % pattern.len()];
            y = 0.8 * y + u_prev;
            u_prev = u;
            text.push_str(&format!("{u},{y}\n"));
        }
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        path
    };
    let three = write("lev3.csv", &[-1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 0.0]);
    for method in ["ls", "oe"] {
        let out = bin()
            .args(["identify", "--data"])
            .arg(&three)
            .args([
                "--ts",
                "1",
                "--nonlinearity",
                "saturation",
                "--method",
                method,
            ])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(
            err.contains("lev3.csv: the input takes only 3 distinct level(s) (-1, 0, 1)")
                && err.contains("needs at least 4 distinct levels"),
            "{err}"
        );
        assert!(!err.contains("regressor m is zero"), "{err}");
    }
    let four = write("lev4.csv", &[-1.0, 0.0, 1.0, 2.0, 0.0, -1.0, 1.0, 2.0, 0.0]);
    let out = bin()
        .args(["identify", "--data"])
        .arg(&four)
        .args(["--ts", "1", "--nonlinearity", "saturation"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("distinct level(s)"), "{err}");
}
