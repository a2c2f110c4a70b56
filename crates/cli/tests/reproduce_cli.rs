//! `reproduce` through the binary on the paper's model (fast): every promised file and JSON key exists, and
//! the closed-loop metrics in summary.json agree with the trace written beside them (recomputed here).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;
use common::read_trace;
use std::process::Command;

#[test]
fn reproduce_on_the_paper_model_writes_report_summary_figures_and_data() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(["reproduce", "--plant", "paper", "--seed", "3", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    for needle in ["Table III", "Table IV", "Table V", "Acceptance"] {
        assert!(stdout.contains(needle), "{needle} missing from:\n{stdout}");
    }
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for m in ["arx", "hammerstein"] {
        let v = &s["models"][m];
        assert_eq!(
            v["model"]["kind"],
            if m == "arx" { "arx" } else { "hammerstein" }
        );
        assert!(
            v["metrics"]["validation"]["fit_sim_percent"].is_number(),
            "{m}"
        );
        assert!(v["poles"].as_array().is_some_and(|p| p.len() == 3));
    }
    for which in ["fixed", "unfixed"] {
        for side in ["model", "plant"] {
            let m = &s["closed_loop"][which][side];
            for key in [
                "overshoot_mm",
                "overshoot_percent",
                "steady_state_error_mm",
                "rise_time_s",
                "settling_time_s",
            ] {
                assert!(
                    m.get(key).is_some(),
                    "closed_loop.{which}.{side}.{key} missing"
                );
            }
        }
    }
    // On the paper's own (noise-free) model the Hammerstein RLS fit must beat the linear ARX.
    let fit = |m: &str| {
        s["models"][m]["metrics"]["validation"]["fit_sim_percent"]
            .as_f64()
            .unwrap()
    };
    assert!(
        fit("hammerstein") > fit("arx"),
        "{} vs {}",
        fit("hammerstein"),
        fit("arx")
    );

    // Independent check of the plant's fixed set-point metrics from the trace file.
    let (t, r, _, y) = read_trace(&out.join("data/closed_loop_fixed_plant.csv"));
    let (y0, setpoint) = (y[0], r[0]);
    let fin = *y.last().unwrap();
    let peak = y.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let os = (peak - fin).max(0.0);
    let m = &s["closed_loop"]["fixed"]["plant"];
    assert!((m["overshoot_mm"].as_f64().unwrap() - os).abs() < 1e-9);
    assert!((m["steady_state_error_mm"].as_f64().unwrap() - (setpoint - fin)).abs() < 1e-9);
    let first = |level: f64| {
        let target = y0 + level * (fin - y0);
        let k = y.iter().position(|&v| v >= target).unwrap();
        t[k - 1] + (target - y[k - 1]) / (y[k] - y[k - 1]) * (t[k] - t[k - 1])
    };
    let rise = first(0.9) - first(0.1);
    assert!(
        (m["rise_time_s"].as_f64().unwrap() - rise).abs() < 1e-9,
        "{rise} vs {m}"
    );

    for f in [
        "report.html",
        "data/estimation.csv",
        "data/validation.csv",
        "data/closed_loop_unfixed_plant.csv",
    ] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    for stem in [
        "fig2_experiment",
        "fig4_deadzone",
        "fig5_fit",
        "fig6_open_loop",
        "fig7a_closed_loop_fixed",
        "fig7b_closed_loop_unfixed",
        "rls_convergence",
    ] {
        for ext in ["svg", "png"] {
            assert!(
                out.join("figures").join(format!("{stem}.{ext}")).is_file(),
                "{stem}.{ext} missing"
            );
        }
    }
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("data:image/png;base64,") && !html.contains("<script"));
}

// Audit s14 M-e: `reproduce --plant model:FILE` carried none of the doubts `control` gives on the same
// plant. A first-order model with Ts = 1 s estimated on commands within [−1, 1]: reproduce's staircase
// drives ±255 counts (its design, far outside the data), and the changing set-point holds each of its
// five set-points 4 s = 4 samples, fewer than the 20 a step needs to be judged; the text, summary.json
// and the report say both, and the changing set-point's criterion is "not judged". The run's words use
// the model's units, not the IPA's mm (session 17).
#[test]
fn reproduce_on_a_model_plant_says_what_control_would_doubt() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json");
    std::fs::write(
        &model,
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "arx", "ts": 1.0,
        "na": 1, "nb": 1, "nk": 1, "a": [-0.5], "b": [0.1], "offset": null,
        "data_range": {"u": [[-1.0, 1.0]], "y": [-0.2, 0.2]}}}"#,
    )
    .unwrap();
    let out = dir.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(["reproduce", "--out"])
        .arg(&out)
        .arg("--plant")
        .arg(format!("model:{}", model.display()))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(!String::from_utf8_lossy(&o.stderr).contains("replaced"));
    let stdout = String::from_utf8_lossy(&o.stdout);
    let extrapolates =
        "the plant model's estimation data had u in [-1, 1]: outside it the model extrapolates";
    assert!(stdout.contains(extrapolates), "{stdout}");
    assert!(
        // The model plant's own units (its record's), not the IPA's mm (as `control` says them).
        stdout.contains("PI on the plant, changing set-point: the step to r = 120 (y's units) at t = 4.000 s is too short to judge: 4 samples"),
        "{stdout}"
    );
    assert!(
        stdout.contains("[not judged] pi_changing_setpoint_steady_state_error"),
        "{stdout}"
    );
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let warnings: Vec<&str> = s["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    assert!(
        warnings.iter().any(|w| w.contains(extrapolates)),
        "{warnings:?}"
    );
    assert!(
        warnings.iter().any(|w| w.contains("too short to judge")),
        "{warnings:?}"
    );
    let criterion = s["acceptance"]["criteria"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["id"] == "pi_changing_setpoint_steady_state_error")
        .unwrap();
    assert_eq!(criterion["status"], "not judged");
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("outside it the model extrapolates"));
    // Audit s28 L-9: no plant figure is labelled in the IPA's units: the acceptance, Table V's rows (the
    // paper's columns stay mm and say so) and the figures' captions.
    let fixed = s["acceptance"]["criteria"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["id"] == "pi_steady_state_error")
        .unwrap()["criterion"]
        .as_str()
        .unwrap()
        .to_string();
    assert!(
        fixed.contains("(y's units)") && !fixed.contains(" mm"),
        "{fixed}"
    );
    assert!(
        stdout.contains("steady-state error (y's units; the paper's: mm)"),
        "{stdout}"
    );
    assert!(
        html.contains("measured position y (y&#39;s units)"),
        "captions in the model's units"
    );
    // A second run into the same folder (its marker says an earlier run wrote it) replaces it, and
    // says so as every other output does ("replaced FILE", session 22's M-B9).
    let again = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(["reproduce", "--out"])
        .arg(&out)
        .arg("--plant")
        .arg(format!("model:{}", model.display()))
        .output()
        .unwrap();
    assert!(
        again.status.success(),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
    assert!(
        String::from_utf8_lossy(&again.stderr).contains(&format!("replaced {}", out.display())),
        "{}",
        String::from_utf8_lossy(&again.stderr)
    );
}

/// Audit s28 L-9: on a model plant sampled every 4 s the fixed set-point's 40 s run has 11 samples (t = 0,
/// 4, …, 40), fewer than the 20 a step needs: its overshoot and steady-state error are "not judged", never
/// "not met", in the text and summary.json.
#[test]
fn a_fixed_step_too_short_to_settle_is_not_judged() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m4.json");
    std::fs::write(
        &model,
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "arx", "ts": 4.0,
        "na": 1, "nb": 1, "nk": 1, "a": [-0.5], "b": [0.1], "offset": null}}"#,
    )
    .unwrap();
    let out = dir.path().join("run");
    let o = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(["reproduce", "--out"])
        .arg(&out)
        .arg("--plant")
        .arg(format!("model:{}", model.display()))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    for id in ["pi_overshoot", "pi_steady_state_error"] {
        assert!(
            stdout.contains(&format!("[not judged] {id}")),
            "{id}: {stdout}"
        );
    }
    assert!(stdout.contains("too short to settle"), "{stdout}");
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for c in s["acceptance"]["criteria"].as_array().unwrap() {
        if c["id"] == "pi_overshoot" || c["id"] == "pi_steady_state_error" {
            assert_eq!(c["status"], "not judged", "{c}");
            assert_eq!(c["met"], false, "{c}");
        }
    }
}
