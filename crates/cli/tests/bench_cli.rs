//! `bench` through the binary with tiny sizes (speed itself is measured by the benchmarks, not by
//! tests): the JSON reports are complete and internally consistent.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::process::Command;

use serde_json::Value;

fn bench(args: &[&str]) -> Value {
    let out = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .arg("bench")
        .args(args)
        .args(["--json", "-"])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn f(v: &Value, key: &str) -> f64 {
    v[key]
        .as_f64()
        .unwrap_or_else(|| panic!("missing {key}: {v}"))
}

// flops per update for n = 5, ρ < 1: ε 2n + Pφ 2n² + denominator 2n + 1 division + gain n + θ 2n
// + 3 per distinct entry of P (n(n+1)/2 = 15) + 1/ρ = 10 + 50 + 10 + 1 + 5 + 10 + 45 + 1 = 132;
// GFLOP/s = flops × samples/s / 1e9 and ns/update = 1e9 / (samples/s).
#[test]
fn rls_bench_reports_consistent_throughput_and_flops() {
    let v = bench(&[
        "rls",
        "--params",
        "5",
        "--samples",
        "2000",
        "--repetitions",
        "1",
    ]);
    assert_eq!(v["params"], 5);
    assert_eq!(f(&v, "flops_per_update"), 132.0);
    let sps = f(&v, "samples_per_second");
    assert!(sps > 0.0 && sps.is_finite());
    assert!((f(&v, "gflops") - 132.0 * sps / 1e9).abs() <= 1e-9 * f(&v, "gflops"));
    assert!((f(&v, "ns_per_update") - 1e9 / sps).abs() <= 1e-9 * f(&v, "ns_per_update"));
    assert!(f(&v, "reference_samples_per_second") > 0.0 && f(&v, "fixed_samples_per_second") > 0.0);
    assert!(f(&v, "peak_gflops_build_target") > 0.0);
}

// n = 17 has no fixed-size kernel: the array figure is absent (null), the others are there.
#[test]
fn rls_bench_above_the_fixed_sizes_has_no_array_figure() {
    let v = bench(&[
        "rls",
        "--params",
        "17",
        "--samples",
        "500",
        "--repetitions",
        "1",
        "--forgetting",
        "1",
    ]);
    assert!(v["fixed_samples_per_second"].is_null());
    // ρ = 1: 3n² + 8n + 1 = 867 + 136 + 1 = 1004.
    assert_eq!(f(&v, "flops_per_update"), 1004.0);
}

#[test]
fn identify_bench_times_both_estimators() {
    let v = bench(&["identify", "--samples", "400", "--repetitions", "1"]);
    for m in ["ls", "rls"] {
        assert_eq!(v[m]["method"], m);
        assert_eq!(v[m]["samples"], 400);
        assert!(v[m]["seconds_per_identification"].as_f64().unwrap() > 0.0);
    }
}

// Real-time factor = simulated time / wall time = samples · Ts / wall.
#[test]
fn plant_bench_real_time_factor_is_simulated_over_wall_time() {
    let v = bench(&[
        "plant",
        "--plant",
        "paper",
        "--samples",
        "300",
        "--repetitions",
        "1",
    ]);
    assert!((f(&v, "simulated_seconds") - 3.0).abs() < 1e-9);
    let rtf = f(&v, "real_time_factor");
    assert!((rtf - 3.0 / f(&v, "wall_seconds")).abs() <= 1e-9 * rtf);
}

#[test]
fn rls_bench_refuses_a_bad_forgetting_factor() {
    let out = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(["bench", "rls", "--forgetting", "1.5"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--forgetting"));
}

// Physics plant with --reference and --accuracy: the RK4 peer is timed on the same record (speed-up =
// real-time factor over the peer's), and the production integrator stays within 1e-3 mm of the
// 16×-refined RK4 reference over it.
#[test]
fn physics_plant_bench_times_the_rk4_reference_and_reports_the_accuracy() {
    let v = bench(&[
        "plant",
        "--samples",
        "200",
        "--repetitions",
        "1",
        "--reference",
        "--accuracy",
    ]);
    assert_eq!(v["work"]["integrator"], "DormandPrince");
    let r = &v["reference"];
    assert_eq!(r["work"]["integrator"], "Rk4");
    assert_eq!(r["samples"], 200);
    let speedup = f(&v, "real_time_factor") / f(r, "real_time_factor");
    assert!((f(r, "speedup") - speedup).abs() <= 1e-9 * speedup);
    let acc = f(&v["accuracy"], "max_position_difference_mm");
    assert!((0.0..1e-3).contains(&acc), "{acc}");
}

// `bench long` on a tiny record (no numpy): the streamed and in-memory runs are child processes of the
// binary with their own peak memory, rows/s = N / wall time, and both estimate the same θ (1e-9).
#[test]
fn long_bench_measures_child_runs_of_the_streamed_and_in_memory_paths() {
    let dir = tempfile::tempdir().unwrap();
    let v = bench(&[
        "long",
        "--rows",
        "3000",
        "--no-numpy",
        "--dir",
        dir.path().to_str().unwrap(),
    ]);
    let r = &v["results"][0];
    assert_eq!(r["rows"].as_u64(), Some(3000));
    for key in ["stream", "in_memory"] {
        let m = &r[key];
        let (wall, rate) = (f(m, "wall_s"), f(m, "rows_per_s"));
        assert!((rate * wall - 3000.0).abs() < 1e-6 * 3000.0, "{m}");
        assert!(f(m, "peak_rss_bytes") > 0.0, "{m}");
    }
    assert!(f(&r["in_memory"], "max_rel_diff_to_stream") < 1e-9, "{r}");
    assert!(r["numpy"].is_null());
    // The record itself is not kept.
    assert!(!dir.path().join("long_3000.csv").exists());
}
