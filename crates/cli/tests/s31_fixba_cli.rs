//! Session 31, fixba (audit s30 LOW findings L-1, L-2, L-3, L-5, L-6, L-7, L-9, L-11): each expectation
//! from a hand-made file, its line counted by hand, or a closed form.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::path::Path;

mod common;
use common::{run, run_json, s, stderr, stdout};

/// Standard error of `ipa-sysid ARGS`, which must exit 2.
fn refused(args: &[&str]) -> String {
    let out = run(args);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
    stderr(&out)
}

/// The warnings of a `--json` document as one text.
fn warnings(doc: &serde_json::Value) -> String {
    common::warnings(doc).join("\n")
}

// ---------------------------------------------------------------------------------------------------
// L-1: no residual degrees of freedom.

/// `u,y` rows (1, 2), (2, 3), (3, 4): ARX(1, 1, 1) has the two regression rows
/// 3 = −a1·2 + b1·1 and 4 = −a1·3 + b1·2, solved exactly by a1 = −2, b1 = −1 (N = p = 2).
fn three_samples(dir: &Path) -> std::path::PathBuf {
    let p = dir.join("n_eq_p.csv");
    std::fs::write(&p, "u,y\n1,2\n2,3\n3,4\n").unwrap();
    p
}

// σ̂² = RSS/(N − p) with N = p is 0/0: undetermined, so no ± (was ± 1.4e-15, rounding noise), in memory
// and read in passes, for every estimator that reports one.
#[test]
fn no_residual_degrees_of_freedom_gives_no_standard_deviation_for_any_estimator() {
    let dir = tempfile::tempdir().unwrap();
    let data = three_samples(dir.path());
    let mut cases: Vec<Vec<&str>> = ["ls", "rls", "iv"]
        .iter()
        .map(|m| common::identify_arx(&data, "1", "1", m))
        .collect();
    let mut streamed = common::identify_arx(&data, "1", "1", "ls");
    streamed.extend(["--stream", "on"]);
    cases.push(streamed);
    for mut args in cases {
        args.extend(["--nk", "1", "--ts", "0.1"]);
        let doc = run_json(dir.path(), &args);
        let params = doc["parameters"].as_array().unwrap();
        let value = |name: &str| {
            params
                .iter()
                .find(|q| q["name"] == name)
                .unwrap_or_else(|| panic!("{args:?}: no {name}"))
        };
        if !args.contains(&"rls") {
            // RLS from P(0) = 1e6·I is only close to the exact solve.
            assert!((value("a1")["value"].as_f64().unwrap() + 2.0).abs() < 1e-9);
            assert!((value("b1")["value"].as_f64().unwrap() + 1.0).abs() < 1e-9);
        }
        for q in params {
            assert!(q["std"].is_null(), "{args:?}: {q}");
        }
        assert!(
            doc["estimation"]["noise_variance"].is_null(),
            "{args:?}: {}",
            doc["estimation"]
        );
        assert!(
            warnings(&doc).contains("no residual degrees of freedom"),
            "{args:?}: {}",
            warnings(&doc)
        );
        let out = run(&args[..args.len()]);
        let text = stdout(&out);
        assert!(text.contains("± n/a"), "{args:?}: {text}");
    }
}

// One more row, (4, 6), leaves N − p = 1: Φ = [[−2, 1], [−3, 2], [−4, 3]], y = (3, 4, 6) (regressors
// −y(k−1), u(k−1)). ΦᵀΦ = [[29, −20], [−20, 14]] (det 6), Φᵀy = (−42, 29); θ = (ΦᵀΦ)⁻¹Φᵀy =
// ((14·−42 + 20·29)/6, (20·−42 + 29·29)/6) = (−8/6, 1/6); residuals y − Φθ = (3 − 8/3 − 1/6,
// 4 − 4 − 1/3, 6 − 16/3 − 1/2) = (1/6, −1/3, 1/6), RSS = 1/6; σ̂² = RSS/1; std a1 = √(σ̂²·14/6),
// std b1 = √(σ̂²·29/6).
#[test]
fn one_residual_degree_of_freedom_gives_the_textbook_standard_deviations() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("n_p1.csv");
    std::fs::write(&data, "u,y\n1,2\n2,3\n3,4\n4,6\n").unwrap();
    let mut args = common::identify_arx(&data, "1", "1", "ls");
    args.extend(["--nk", "1", "--ts", "0.1"]);
    let doc = run_json(dir.path(), &args);
    let sigma2 = 1.0 / 6.0;
    let nv = doc["estimation"]["noise_variance"].as_f64().unwrap();
    assert!((nv - sigma2).abs() < 1e-12, "{nv}");
    let params = doc["parameters"].as_array().unwrap();
    for (name, value, g) in [
        ("a1", -8.0 / 6.0, 14.0 / 6.0),
        ("b1", 1.0 / 6.0, 29.0 / 6.0),
    ] {
        let q = params.iter().find(|q| q["name"] == name).unwrap();
        assert!((q["value"].as_f64().unwrap() - value).abs() < 1e-12, "{q}");
        let std = q["std"].as_f64().unwrap();
        assert!((std - (sigma2 * g).sqrt()).abs() < 1e-12, "{q}");
    }
}
