//! `ipa-sysid simulate` and `plant-config` end to end.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::Path;
use std::process::Command;

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
}

fn simulate(dir: &Path, extra: &[&str], out: &str) -> std::process::Output {
    bin()
        .current_dir(dir)
        .arg("simulate")
        .args(extra)
        .args(["--out", out])
        .output()
        .unwrap()
}

// The default experiment writes t,u,y plus pressures that sysid's reader accepts (Ts = 0.01 s from t).
#[test]
fn default_simulation_is_readable_and_byte_identical_per_seed() {
    let dir = tempfile::tempdir().unwrap();
    let a = simulate(dir.path(), &["--samples", "300"], "a.csv");
    assert!(a.status.success(), "{}", String::from_utf8_lossy(&a.stderr));
    simulate(dir.path(), &["--samples", "300"], "b.csv");
    simulate(dir.path(), &["--samples", "300", "--seed", "1"], "c.csv");
    let ra = std::fs::read(dir.path().join("a.csv")).unwrap();
    assert_eq!(ra, std::fs::read(dir.path().join("b.csv")).unwrap());
    assert_ne!(ra, std::fs::read(dir.path().join("c.csv")).unwrap());
    let text = String::from_utf8(ra).unwrap();
    assert!(text.starts_with("t,u,y,p_a_pa,p_b_pa\n"));
    let d = sysid::data::read_csv(&dir.path().join("a.csv"), &Default::default()).unwrap();
    assert_eq!(d.len(), 300);
    assert!((d.ts() - 0.01).abs() < 1e-12);
    assert_eq!(d.y()[0], 100.0);
    assert!(d.u().iter().all(|u| u.abs() <= 255.0));
}

// The paper model: y(1) = -a1 y0 - a2 y0 - a3 y0 + x(0) with x = m_r (u - b_r) for u >= b_r.
#[test]
fn paper_plant_follows_its_difference_equation() {
    let dir = tempfile::tempdir().unwrap();
    let o = simulate(
        dir.path(),
        &[
            "--plant",
            "paper",
            "--input",
            "step:100@0",
            "--samples",
            "3",
            "--x0",
            "0",
        ],
        "p.csv",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d = sysid::data::read_csv(&dir.path().join("p.csv"), &Default::default()).unwrap();
    let x = 2.38 * 15.67e-4 * (100.0 - 1.41);
    assert_eq!(d.y()[0], 0.0);
    assert!((d.y()[1] - x).abs() < 1e-12);
    assert!((d.y()[2] - (1.869 * x + x)).abs() < 1e-12);
}

#[test]
fn file_input_and_noise() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("u.csv"), "u\n0\n50\n-50\n255\n").unwrap();
    let o = simulate(
        dir.path(),
        &["--input", "file:u.csv", "--noise-std", "0.1"],
        "o.csv",
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d = sysid::data::read_csv(&dir.path().join("o.csv"), &Default::default()).unwrap();
    assert_eq!(d.u(), vec![0.0, 50.0, -50.0, 255.0]);
    assert!(
        d.y().iter().any(|y| (y * 100.0).fract().abs() > 1e-6),
        "noise must leave the 0.01 mm grid"
    );
}

#[test]
fn refuses_to_overwrite_inputs_and_explains_bad_flags() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("u.csv"), "u\n1\n").unwrap();
    std::fs::write(dir.path().join("c.toml"), "[load]\nmoving_mass_kg = 1.0\n").unwrap();
    for (extra, out, needle) in [
        (vec!["--input", "file:u.csv"], "u.csv", "--out"),
        (vec!["--plant-config", "c.toml"], "c.toml", "--out"),
        (vec!["--input", "sine"], "x.csv", "--input"),
        (vec!["--plant", "robot"], "x.csv", "--plant"),
        (
            vec!["--plant", "paper", "--plant-config", "c.toml"],
            "x.csv",
            "--plant-config",
        ),
        (vec!["--plant", "paper", "--ts", "0.02"], "x.csv", "--ts"),
        (vec!["--noise-std", "-1"], "x.csv", "--noise-std"),
        (
            vec!["--plant", "model:missing.json"],
            "x.csv",
            "missing.json",
        ),
    ] {
        let o = simulate(dir.path(), &extra, out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(needle), "{extra:?}: {err}");
    }
    assert_eq!(
        std::fs::read_to_string(dir.path().join("u.csv")).unwrap(),
        "u\n1\n"
    );
    std::fs::write(
        dir.path().join("bad.toml"),
        "[valve]\nopening_delay = 1.0\n",
    )
    .unwrap();
    let o = simulate(dir.path(), &["--plant-config", "bad.toml"], "x.csv");
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("opening_delay"));
    assert!(!dir.path().join("x.csv").exists());
}

// plant-config prints TOML that parses back to the defaults and can be passed to --plant-config.
#[test]
fn plant_config_prints_the_defaults_as_toml() {
    let dir = tempfile::tempdir().unwrap();
    let o = bin().arg("plant-config").output().unwrap();
    assert!(o.status.success());
    let text = String::from_utf8(o.stdout).unwrap();
    assert_eq!(
        ipa::PlantConfig::from_toml_str(&text, "stdout").unwrap(),
        ipa::PlantConfig::default()
    );
    std::fs::write(dir.path().join("c.toml"), &text).unwrap();
    let s = simulate(
        dir.path(),
        &["--plant-config", "c.toml", "--samples", "20"],
        "x.csv",
    );
    assert!(s.status.success(), "{}", String::from_utf8_lossy(&s.stderr));
}
