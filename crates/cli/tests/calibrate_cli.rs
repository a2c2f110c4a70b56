//! `ipa-sysid calibrate` end to end: simulate a plant with known parameters, calibrate, and use the
//! written plant-config with the other commands.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::Path;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
}

fn run(dir: &Path, args: &[&str]) -> std::process::Output {
    bin().current_dir(dir).args(args).output().unwrap()
}

// A plant with a 20 % larger moving mass and supply conductance than the defaults: calibrating
// those two from the defaults recovers them (within 2 %, the target), the twin's TOML is a
// plant-config that `simulate` takes, and the JSON report has the twin and the Hammerstein baseline
// on the validation record, the twin far better (the baseline cannot follow stick-slip motion).
#[test]
fn calibrate_recovers_a_known_plant_and_writes_a_usable_plant_config() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(
        p.join("truth.toml"),
        "[load]\nmoving_mass_kg = 0.72\n[valve]\nsupply_conductance_dm3_s_bar = 0.12\n",
    )
    .unwrap();
    for (input, seed, out) in [
        ("calibration", "1", "est.csv"),
        ("staircase", "2", "val.csv"),
    ] {
        let o = run(
            p,
            &[
                "simulate",
                "--plant-config",
                "truth.toml",
                "--input",
                input,
                "--samples",
                "1000",
                "--seed",
                seed,
                "--out",
                out,
            ],
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "est.csv",
            "--validation",
            "val.csv",
            "--free",
            "moving_mass,supply_conductance",
            "--out",
            "twin.toml",
            "--json",
            "twin.json",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("best Hammerstein model"), "{text}");
    let cfg = ipa::PlantConfig::from_toml_file(&p.join("twin.toml")).unwrap();
    assert!(
        (cfg.load.moving_mass_kg / 0.72 - 1.0).abs() < 0.02,
        "{cfg:?}"
    );
    assert!((cfg.valve.supply_conductance_dm3_s_bar / 0.12 - 1.0).abs() < 0.02);
    let j: serde_json::Value =
        serde_json::from_slice(&std::fs::read(p.join("twin.json")).unwrap()).unwrap();
    let twin = j["fit_validation_percent"].as_f64().unwrap();
    let hammerstein = j["hammerstein"]["fit_percent"].as_f64().unwrap();
    assert!(twin > 98.0 && twin > hammerstein, "{twin} vs {hammerstein}");
    assert!(j["warnings"].is_array());
    let o = run(
        p,
        &[
            "simulate",
            "--plant-config",
            "twin.toml",
            "--samples",
            "50",
            "--out",
            "s.csv",
        ],
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

// Bad input: an unknown parameter name, a missing column and an output over the input are refused
// with a message naming the culprit, exit code 2, and no file written.
#[test]
fn bad_calibrate_input_is_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("r.csv"), "t,u,pos\n0,0,1\n").unwrap();
    let o = run(
        p,
        &[
            "calibrate",
            "--data",
            "r.csv",
            "--free",
            "mass",
            "--out",
            "o.toml",
        ],
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("moving_mass"));
    let o = run(p, &["calibrate", "--data", "r.csv", "--out", "o.toml"]);
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("r.csv") && e.contains('y'), "{e}");
    let o = run(p, &["calibrate", "--data", "r.csv", "--out", "r.csv"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(!p.join("o.toml").exists());
    assert_eq!(
        std::fs::read_to_string(p.join("r.csv")).unwrap(),
        "t,u,pos\n0,0,1\n"
    );
}
