//! Session 29, fixax (audit s27 L-11 remainder): `validate --horizon K` is bounded by the model steps
//! it takes, and the reader's refusal for memory offers `--stream on` only where the command would
//! read that record in passes with those settings.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use std::path::Path;

mod common;
use common::{arx_signals, run, s, stderr, write_csv};

/// Standard error of `ipa-sysid ARGS`, which must exit 2.
fn refused(args: &[&str]) -> String {
    let out = run(args);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
    stderr(&out)
}

/// `ipa-sysid ARGS`, which must succeed.
fn succeeds(args: &[&str]) {
    let out = run(args);
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
}

/// An ARX(2, 2) record of `n` samples: y(k) = 1.5 y(k−1) − 0.7 y(k−2) + 0.5 u(k−1) + 0.2 u(k−2) with a
/// pseudo-random input.
fn record(path: &Path, n: usize) {
    let mut rng = common::lcg(3);
    let (u, y) = arx_signals(n, &[1.5, -0.7], &[0.5, 0.2], |_| rng.unit() - 0.5);
    write_csv(path, "t,u,y", Some(0.01), &[&u, &y]);
}

fn save_arx(data: &Path, model: &Path) {
    let mut args = common::identify_arx_named(s(data), "2", "2", "ls");
    args.extend(["--save-model", s(model)]);
    succeeds(&args);
}

// K = N/2 on 100 000 samples took 54 s in silence (audit s27 L-11). An ARX(2, 2, 1) copies k0 = 2
// samples, so the prediction takes (N − 2 − K)·K model steps: 49 998·50 000 = 2 499 900 000 > 10⁹,
// refused at once. With M = 99 998 the horizons within 10⁹ are K ≤ 11 270 (88 728·11 270 =
// 999 964 560; 88 727·11 271 = 1 000 042 017) and K ≥ 88 728 (the same products, mirrored).
#[test]
fn validate_refuses_a_horizon_beyond_the_step_bound_naming_its_cost_and_the_horizons_that_fit() {
    let dir = tempfile::tempdir().unwrap();
    let (data, model) = (dir.path().join("r.csv"), dir.path().join("m.json"));
    record(&data, 100_000);
    save_arx(&data, &model);
    let e = refused(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--horizon",
        "50000",
    ]);
    assert!(
        e.contains(
            "a 50000-step prediction of 100000 samples takes (N − k0 − K)·K = 2499900000 model steps"
        ) && e.contains("K <= 11270 or K >= 88728"),
        "{e}"
    );
    // K ≥ N − k0 is the simulation: no step beyond it, accepted.
    succeeds(&[
        "validate",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--horizon",
        "99998",
    ]);
}

// 20 000 rows of t, u, y need about 2 MB with the file's text, more than --max-memory 0.001
// (1 073 741 bytes): the reader refuses them. It offers `--stream on` to an ARX by least squares
// (`identify --stream off` was asked, and would stream) and to `validate --horizon 1`, which read such
// a record in passes, and not to a Hammerstein identification, `validate --horizon 2` or `order`,
// which refuse `--stream on` (before, every refusal said "--stream on, where the command allows it").
#[test]
fn the_readers_refusal_for_memory_offers_stream_on_only_where_the_command_would_stream() {
    let dir = tempfile::tempdir().unwrap();
    let (data, model, small) = (
        dir.path().join("r.csv"),
        dir.path().join("m.json"),
        dir.path().join("small.csv"),
    );
    record(&data, 20_000);
    record(&small, 500);
    save_arx(&small, &model);
    let budget = ["--max-memory", "0.001"];
    let arx: Vec<&str> = common::identify_arx_named(s(&data), "2", "2", "ls")
        .into_iter()
        .chain(["--stream", "off"])
        .chain(budget)
        .collect();
    let hammerstein: Vec<&str> = [
        "identify",
        "--data",
        s(&data),
        "--structure",
        "hammerstein",
        "--nonlinearity",
        "polynomial",
        "--degree",
        "2",
    ]
    .into_iter()
    .chain(budget)
    .collect();
    let validate = |k: &'static str| -> Vec<&str> {
        [
            "validate",
            "--model",
            s(&model),
            "--data",
            s(&data),
            "--horizon",
            k,
            "--stream",
            "off",
        ]
        .into_iter()
        .chain(budget)
        .collect()
    };
    let order: Vec<&str> = ["order", "--data", s(&data)]
        .into_iter()
        .chain(budget)
        .collect();
    let cases: [(&str, Vec<&str>, bool); 5] = [
        ("identify arx", arx, true),
        ("identify hammerstein", hammerstein, false),
        ("validate --horizon 1", validate("1"), true),
        ("validate --horizon 2", validate("2"), false),
        ("order", order, false),
    ];
    for (name, args, offers) in cases {
        let e = refused(&args);
        assert!(
            e.contains("more than the budget of 1073741 bytes"),
            "{name}: {e}"
        );
        assert_eq!(
            e.contains("read it in passes (--stream on, which reads the CSV record in passes"),
            offers,
            "{name}: {e}"
        );
        if !offers {
            assert!(!e.contains("--stream"), "{name}: {e}");
        }
    }
}
