//! The C example of `ipa-embedded` (crates/embedded/examples/c/track.c, linked against the static
//! library) against `ipa-sysid identify --method rls --passes 1` (also with `--rls-form ud`) on records of
//! the physics IPA simulator:
//! every parameter equal to 1e-9 relative (in practice bit for bit: the embedded estimator does the
//! same floating-point operations in the same order, and both sides print round-trip decimals).
//!
//! The static library is built by `cargo build --release -p ipa-embedded` into a target folder inside
//! the test's temporary folder (no lock contention with the running `cargo test`; the crate has no
//! dependencies, so this takes seconds). Skips with a message when no C compiler `cc` is installed.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn cli(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_ipa-sysid"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "ipa-sysid {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// Builds the static library and the C example `track` once; returns the example's path.
fn build_track(dir: &Path) -> PathBuf {
    build_example(dir, "track")
}

/// Builds the static library and the C example `NAME` (crates/embedded/examples/c/NAME.c); returns
/// the example's path.
fn build_example(dir: &Path, name: &str) -> PathBuf {
    let target = dir.join("target");
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let status = Command::new(cargo)
        .args(["build", "--release", "--offline", "-p", "ipa-embedded"])
        .arg("--target-dir")
        .arg(&target)
        .current_dir(workspace())
        .status()
        .unwrap();
    assert!(status.success(), "cargo build -p ipa-embedded failed");
    let lib = target.join("release/libipa_embedded.a");
    assert!(lib.exists(), "{} was not built", lib.display());
    let exe = dir.join(name);
    let ws = workspace();
    let out = Command::new("cc")
        .args(["-O2", "-std=c99"])
        .arg(format!(
            "-I{}",
            ws.join("crates/embedded/include").display()
        ))
        .arg(ws.join(format!("crates/embedded/examples/c/{name}.c")))
        .arg(&lib)
        .args(["-lm", "-lpthread", "-ldl", "-o"])
        .arg(&exe)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "cc failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    exe
}

fn no_cc() -> bool {
    let missing = Command::new("cc")
        .arg("--version")
        .stdout(Stdio::null())
        .status()
        .is_err();
    if missing {
        eprintln!("SKIPPED: no C compiler `cc` on this machine; the C example was not checked");
    }
    missing
}

fn numbers(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn close(a: f64, b: f64) -> bool {
    a == b || (a - b).abs() <= 1e-9 * a.abs().max(b.abs())
}

#[test]
fn c_example_matches_identify_rls_single_pass() {
    if no_cc() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let track = build_track(tmp.path());
    // Audit s31 L-6: a NaN in the record is named at its line (4: header, a row, a blank line, the NaN
    // row), not reported as "ipa_hrls_init failed: -3".
    let mut child = Command::new(&track)
        .args(["3", "1", "1", "1"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    {
        use std::io::Write;
        let mut stdin = child.stdin.take().unwrap();
        stdin.write_all(b"u,y\n1,2\n\nnan,3\n").unwrap();
    }
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("line 4: u = nan, y = 3: not finite"), "{err}");
    let mut bitwise = 0;
    let mut total = 0;
    for (seed, na, nb, nk, rho, form) in [
        (1, 3, 1, 1, "1", "standard"),
        (1, 3, 1, 1, "0.99", "standard"),
        (2, 2, 2, 1, "1", "standard"),
        (3, 2, 3, 2, "0.995", "standard"),
        (4, 3, 1, 1, "0.99", "ud"),
    ] {
        let csv = tmp.path().join(format!("rec{seed}.csv"));
        let csv_s = csv.to_str().unwrap();
        cli(&[
            "simulate",
            "--plant",
            "ipa",
            "--seed",
            &seed.to_string(),
            "--out",
            csv_s,
        ]);
        let (na_s, nb_s, nk_s) = (na.to_string(), nb.to_string(), nk.to_string());
        let json = cli(&[
            "identify",
            "--data",
            csv_s,
            "--method",
            "rls",
            "--passes",
            "1",
            "--forgetting",
            rho,
            "--na",
            &na_s,
            "--nb",
            &nb_s,
            "--nk",
            &nk_s,
            "--rls-form",
            form,
            "--json",
            "-",
        ]);
        let report: serde_json::Value = serde_json::from_str(&json).unwrap();
        let model = &report["model"];
        let run_track = |form: &str| {
            let out = Command::new(&track)
                .args([&na_s, &nb_s, &nk_s, rho, "1e6", form])
                .stdin(std::fs::File::open(&csv).unwrap())
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "track failed: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
        };
        let c = run_track(form);
        // The two covariance forms agree only to rounding (≈ 1e-10 here), closer than the tolerance: check
        // that the form argument reaches the library, i.e. the other form gives different bits.
        let other = run_track(if form == "ud" { "standard" } else { "ud" });
        assert_ne!(
            c.to_string(),
            other.to_string(),
            "FORM must change the computation"
        );
        let mut pairs: Vec<(String, f64, f64)> = Vec::new();
        for name in ["b_l", "b_r", "m_l", "m_r"] {
            let cli_v = model["deadzone"][name].as_f64().unwrap();
            pairs.push((name.into(), cli_v, c[name].as_f64().unwrap()));
        }
        for key in ["a", "b"] {
            let (x, y) = (numbers(&model[key]), numbers(&c[key]));
            assert_eq!(x.len(), y.len(), "{key}: length");
            for (i, (p, q)) in x.iter().zip(&y).enumerate() {
                pairs.push((format!("{key}{}", i + 1), *p, *q));
            }
        }
        assert_eq!(pairs.len(), 4 + na + nb);
        for (name, cli_v, c_v) in &pairs {
            assert!(
                close(*cli_v, *c_v),
                "seed {seed} ({na},{nb},{nk}) rho {rho} {form}: {name}: identify {cli_v:e}, C {c_v:e}"
            );
            total += 1;
            bitwise += usize::from(cli_v.to_bits() == c_v.to_bits());
        }
        // A deadzone estimate of an excited two-sided record is not trivially zero.
        assert!(pairs.iter().take(4).all(|(_, v, _)| *v != 0.0), "{pairs:?}");
    }
    eprintln!("{bitwise} of {total} parameters bit for bit equal");
}

/// The tuned controller in C (examples/c/position.c, `ipa_ctl_step` once per sample) fed the set-point
/// and position of a run recorded by `ipa-sysid control --controller` on the physics plant gives the
/// recorded commands bit for bit (both sides print round-trip decimals; the CSV's r and y parse to the
/// same doubles).
#[test]
fn c_controller_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::None);
}

/// The same with the approach with braking (`brake`, session 14) in the file: the staircase's steps
/// of 82 and 60 mm (>= e_a = 30 mm) are approached with the full command and braked.
#[test]
fn c_controller_with_a_brake_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Fixed);
}

/// The same with the brake's lead learnt per direction (`learn`, `lead_max_s`) and its release
/// (`release_samples`; session 15) on a staircase that goes up 82 mm and down 60 mm twice, so that
/// the second move each way brakes with the lead the first taught; the same C replay with the
/// learning and the release off gives other commands.
#[test]
fn c_controller_with_a_learnt_brake_lead_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Learnt);
}

/// The same with the short-step approach (`short_approach`, session 17) beside the brake: the
/// staircase's steps of 20, 15 and 20 mm (<= e_m = 40 mm) are driven at U u_max = 89.25 counts and
/// braked at −a_s u_max = ∓127.5, the 75 mm step keeps the brake; the same C replay without the
/// short-step fields (a struct with them zeroed) gives other commands.
#[test]
fn c_controller_with_a_short_step_approach_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Short);
}

// Session 18: the nudge's creep limit e_v (the 40th argument of position.c).
#[test]
fn c_controller_with_a_creeping_ramp_and_cut_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Creep);
}

// Session 19: the brake's re-brake (the 41st argument of position.c), with a brake of 10 samples, a
// release of 10 and a hold of 8 samples at rest, on a staircase whose 125 mm step (45 → 170 mm)
// rests 3.1 mm short under the brake and slides on to 170.7 mm as the brake is released without the
// re-brake; the same C replay without it (0) gives other commands.
#[test]
fn c_controller_with_a_rebrake_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Rebrake);
}

// Session 19: the nudge's slip brake a_p, T_p (the 42nd and 43rd arguments of position.c, after the
// re-brake's 0).
#[test]
fn c_controller_with_a_slip_brake_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Slip);
}

// Session 20: the nudge's relearning (the 44th argument of position.c, after the slip brake's two);
// the same C replay without it (0) gives other commands.
#[test]
fn c_controller_that_relearns_the_breakaway_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Relearn);
}

// Session 20: the previews of the approach with braking and of the short-step approach (the two
// arguments of position.c after the relearning); the same C replay with both 0 gives other commands.
#[test]
fn c_controller_with_the_previews_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Preview);
}

// Session 23: the short-step approach's breakaway seed (the two arguments of position.c after the
// previews); the same C replay with both 0 gives other commands.
#[test]
fn c_controller_with_a_breakaway_seed_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::Seed);
}

// Session 23: the held nudge's learnt cut fraction (the 49th argument of position.c, after the
// previews and the seed's two, 0 0); the same C replay without it (0) gives other commands.
#[test]
fn c_controller_that_learns_the_cut_fraction_matches_control_bit_for_bit_on_a_recorded_run() {
    c_controller_matches_control(Brake::CutLearn);
}

/// Which approach the controller file of [`c_controller_matches_control`] has.
#[derive(Clone, Copy, PartialEq)]
enum Brake {
    None,
    Fixed,
    Learnt,
    /// The fixed brake and the short-step approach.
    Short,
    /// As `Short`, with ramp-and-cut's creep limit e_v = 0.015 mm per sample.
    Creep,
    /// As `Creep`, with a brake of 10 samples released over 10 samples, its hold ended after 8
    /// samples at rest and the re-brake on.
    Rebrake,
    /// As `Creep`, with the nudge's slip brake a_p = 0.25, T_p = 5.
    Slip,
    /// As `Slip`, with the nudge's relearning.
    Relearn,
    /// As `Slip`, with the previews of the approach with braking and of the short-step approach.
    Preview,
    /// As `Preview`, with the short-step approach's breakaway seed κ_s = 0.8 at any speed.
    Seed,
    /// As `Relearn`, with the held nudge's learnt cut fraction and a 3 mm rest band (held nudges
    /// from far).
    CutLearn,
}

fn c_controller_matches_control(brake: Brake) {
    if no_cc() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let exe = build_example(tmp.path(), "position");
    // A model identified on a record of the physics plant, a controller tuned on it, a run on the plant.
    let rec = tmp.path().join("rec.csv");
    let model = tmp.path().join("m.json");
    let ctl = tmp.path().join("c.json");
    let trace = tmp.path().join("trace.csv");
    let p = |x: &Path| x.to_str().unwrap().to_string();
    cli(&[
        "simulate",
        "--plant",
        "ipa",
        "--seed",
        "1",
        "--samples",
        "3000",
        "--out",
        &p(&rec),
    ]);
    cli(&[
        "identify",
        "--data",
        &p(&rec),
        "--method",
        "oe",
        "--save-model",
        &p(&model),
    ]);
    cli(&[
        "tune",
        "--model",
        &p(&model),
        "--out",
        &p(&ctl),
        "--max-evaluations",
        "30",
    ]);
    // A ramp-and-cut band (tune keeps it only where it lowers the cost, which on this model it may
    // not), so that the run exercises that branch too.
    let mut file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&ctl).unwrap()).unwrap();
    file["controller"]["nudge"]["cut_band_mm"] = serde_json::json!(0.3);
    file["controller"]["nudge"]["min_ramp_counts_s"] = serde_json::json!(20.0);
    // tune may choose a short-step approach (session 17); only the `Short` run has one.
    file["controller"]
        .as_object_mut()
        .unwrap()
        .remove("short_approach");
    // tune may choose the slip brake (session 19) and the relearning (session 20); only the `Slip`
    // and `Relearn` runs have them.
    for k in [
        "slip_brake_fraction",
        "slip_brake_samples",
        "relearn",
        "cut_learn",
    ] {
        file["controller"]["nudge"]
            .as_object_mut()
            .unwrap()
            .remove(k);
    }
    if brake == Brake::None {
        // tune may choose one (session 15); this run is the controller without it.
        file["controller"].as_object_mut().unwrap().remove("brake");
    } else {
        file["controller"]["brake"] = serde_json::json!({"min_step_mm": 30.0, "switch_mm": 0.0,
            "lead_s": 0.02, "strength": 0.25, "samples": 25, "rest_samples": 3});
    }
    if brake == Brake::Learnt {
        file["controller"]["brake"]["learn"] = serde_json::json!(0.5);
        file["controller"]["brake"]["lead_max_s"] = serde_json::json!(0.1);
        file["controller"]["brake"]["release_samples"] = serde_json::json!(10);
    }
    if brake == Brake::Rebrake {
        file["controller"]["brake"]["samples"] = serde_json::json!(10);
        file["controller"]["brake"]["release_samples"] = serde_json::json!(10);
        file["controller"]["brake"]["rest_samples"] = serde_json::json!(8);
        file["controller"]["brake"]["rebrake"] = serde_json::json!(true);
    }
    if matches!(
        brake,
        Brake::Short
            | Brake::Creep
            | Brake::Rebrake
            | Brake::Slip
            | Brake::Relearn
            | Brake::Preview
            | Brake::Seed
            | Brake::CutLearn
    ) {
        file["controller"]["short_approach"] = serde_json::json!({"max_step_mm": 40.0,
            "drive_fraction": 0.35, "ramp_counts_s": 500.0, "switch_mm": 0.5, "lead_s": 0.01,
            "brake_strength": 0.5, "brake_samples": 3, "rest_samples": 2});
    }
    if matches!(
        brake,
        Brake::Creep
            | Brake::Rebrake
            | Brake::Slip
            | Brake::Relearn
            | Brake::Preview
            | Brake::Seed
            | Brake::CutLearn
    ) {
        file["controller"]["nudge"]["creep_step_mm"] = serde_json::json!(0.015);
    }
    if matches!(brake, Brake::Preview | Brake::Seed) {
        file["controller"]["brake"]["preview"] = serde_json::json!(true);
        file["controller"]["short_approach"]["preview"] = serde_json::json!(true);
    }
    if brake == Brake::Seed {
        file["controller"]["short_approach"]["breakaway_seed"] = serde_json::json!(0.8);
    }
    if matches!(
        brake,
        Brake::Slip | Brake::Relearn | Brake::Preview | Brake::Seed | Brake::CutLearn
    ) {
        file["controller"]["nudge"]["slip_brake_fraction"] = serde_json::json!(0.25);
        file["controller"]["nudge"]["slip_brake_samples"] = serde_json::json!(5);
    }
    if matches!(brake, Brake::Relearn | Brake::CutLearn) {
        file["controller"]["nudge"]["relearn"] = serde_json::json!(true);
    }
    if brake == Brake::CutLearn {
        file["controller"]["nudge"]["cut_learn"] = serde_json::json!(true);
        file["controller"]["nudge"]["rest_band_mm"] = serde_json::json!(3.0);
    }
    let (profile, samples) = match brake {
        Brake::Learnt => ("staircase:40,38,120,60,120,60@2", 1201),
        Brake::Short
        | Brake::Creep
        | Brake::Slip
        | Brake::Relearn
        | Brake::Preview
        | Brake::Seed
        | Brake::CutLearn => ("staircase:40,60,45,120,100@2", 1001),
        Brake::Rebrake => ("staircase:40,60,45,170,100@2", 1001),
        _ => ("staircase:40,38,120,60@2", 801),
    };
    std::fs::write(&ctl, serde_json::to_string_pretty(&file).unwrap()).unwrap();
    cli(&[
        "control",
        "--plant",
        "ipa",
        "--controller",
        &p(&ctl),
        "--profile",
        profile,
        "--out",
        &p(&trace),
    ]);
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&ctl).unwrap()).unwrap();
    let c = &doc["controller"];
    let g = |k: &str| format!("{:?}", c[k].as_f64().unwrap());
    let mut args: Vec<String> = [
        "ts_s",
        "kp",
        "ki",
        "kd",
        "derivative_filter_s",
        "u_max",
        "hold_band_mm",
        "fine_band_mm",
    ]
    .iter()
    .map(|k| g(k))
    .collect();
    args.push(
        if c["reset_on_crossing"].as_bool().unwrap() {
            "1"
        } else {
            "0"
        }
        .into(),
    );
    let dz = &c["compensator"]["deadzone"];
    assert!(
        dz.is_object(),
        "the tuned controller has a deadzone inverse"
    );
    for k in ["b_l", "b_r", "m_l", "m_r"] {
        args.push(format!("{:?}", dz[k].as_f64().unwrap()));
    }
    let nudge = &c["nudge"];
    assert!(nudge.is_object(), "the tuned controller has a nudge mode");
    for k in ["band_mm", "ramp_counts_s", "start_fraction"] {
        args.push(format!("{:?}", nudge[k].as_f64().unwrap()));
    }
    args.push(nudge["rest_samples"].as_u64().unwrap().to_string());
    args.push(format!("{:?}", nudge["cut_fraction"].as_f64().unwrap()));
    for k in ["rest_band_mm", "cut_band_mm", "min_ramp_counts_s"] {
        args.push(format!("{:?}", nudge[k].as_f64().unwrap()));
    }
    if brake != Brake::None {
        let b = &c["brake"];
        for k in ["min_step_mm", "switch_mm", "lead_s", "strength"] {
            args.push(format!("{:?}", b[k].as_f64().unwrap()));
        }
        for k in ["samples", "rest_samples"] {
            args.push(b[k].as_u64().unwrap().to_string());
        }
    }
    let replay = |args: &[String]| -> Vec<f64> {
        let out = Command::new(&exe)
            .args(args)
            .stdin(std::fs::File::open(&trace).unwrap())
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout)
            .unwrap()
            .lines()
            .map(|l| l.parse().unwrap())
            .collect()
    };
    let unlearnt = matches!(brake, Brake::Learnt | Brake::Short).then(|| replay(&args));
    if matches!(
        brake,
        Brake::Learnt
            | Brake::Short
            | Brake::Creep
            | Brake::Rebrake
            | Brake::Slip
            | Brake::Relearn
            | Brake::Preview
            | Brake::Seed
            | Brake::CutLearn
    ) {
        let b = &c["brake"];
        for k in ["learn", "lead_max_s"] {
            args.push(format!("{:?}", b[k].as_f64().unwrap_or(0.0)));
        }
        args.push(b["release_samples"].as_u64().unwrap_or(0).to_string());
    }
    if matches!(
        brake,
        Brake::Short
            | Brake::Creep
            | Brake::Rebrake
            | Brake::Slip
            | Brake::Relearn
            | Brake::Preview
            | Brake::Seed
            | Brake::CutLearn
    ) {
        let a = &c["short_approach"];
        for k in [
            "max_step_mm",
            "drive_fraction",
            "ramp_counts_s",
            "switch_mm",
            "lead_s",
            "brake_strength",
        ] {
            args.push(format!("{:?}", a[k].as_f64().unwrap()));
        }
        for k in ["brake_samples", "rest_samples"] {
            args.push(a[k].as_u64().unwrap().to_string());
        }
    }
    // The creep limit last: the replay without it is the ramp-and-cut that cuts at the first count.
    let unlearnt = if brake == Brake::Creep {
        let without = replay(&args);
        args.push(format!("{:?}", nudge["creep_step_mm"].as_f64().unwrap()));
        Some(without)
    } else {
        unlearnt
    };
    // The re-brake after the creep limit: the replay without it (0) brakes no slip.
    let unlearnt = if brake == Brake::Rebrake {
        args.push(format!("{:?}", nudge["creep_step_mm"].as_f64().unwrap()));
        let mut without = args.clone();
        without.push("0".into());
        args.push(
            if c["brake"]["rebrake"].as_bool().unwrap() {
                "1"
            } else {
                "0"
            }
            .into(),
        );
        Some(replay(&without))
    // The slip brake after the creep limit and the re-brake (off here): the replay without it closes
    // the valves at a slip.
    } else if brake == Brake::Slip {
        args.push(format!("{:?}", nudge["creep_step_mm"].as_f64().unwrap()));
        args.push("0".into());
        let without = replay(&args);
        args.push(format!(
            "{:?}",
            nudge["slip_brake_fraction"].as_f64().unwrap()
        ));
        args.push(nudge["slip_brake_samples"].as_u64().unwrap().to_string());
        Some(without)
    // The relearning after the slip brake: the replay without it (0) learns no breakaway at a slip.
    // The previews after the relearning (0 here): the replay with both 0 switches a sample later.
    } else if matches!(
        brake,
        Brake::Relearn | Brake::Preview | Brake::Seed | Brake::CutLearn
    ) {
        args.push(format!("{:?}", nudge["creep_step_mm"].as_f64().unwrap()));
        args.push("0".into());
        args.push(format!(
            "{:?}",
            nudge["slip_brake_fraction"].as_f64().unwrap()
        ));
        args.push(nudge["slip_brake_samples"].as_u64().unwrap().to_string());
        let mut without = args.clone();
        if brake == Brake::CutLearn {
            // The relearning and the previews as the file has them, then the cut fraction's rule.
            args.push("1".into());
            for k in ["brake", "short_approach"] {
                args.push(
                    if c[k]["preview"].as_bool().unwrap_or(false) {
                        "1"
                    } else {
                        "0"
                    }
                    .into(),
                );
            }
            // The seed's two (off in this file), then the cut fraction's rule.
            args.extend(["0".to_string(), "0".to_string()]);
            without = args.clone();
            without.push("0".into());
            args.push(
                if nudge["cut_learn"].as_bool().unwrap() {
                    "1"
                } else {
                    "0"
                }
                .into(),
            );
        } else if brake == Brake::Relearn {
            without.push("0".into());
            args.push(
                if nudge["relearn"].as_bool().unwrap() {
                    "1"
                } else {
                    "0"
                }
                .into(),
            );
        } else {
            args.push("0".into());
            without = args.clone();
            without.extend(["0".to_string(), "0".to_string()]);
            for k in ["brake", "short_approach"] {
                args.push(
                    if c[k]["preview"].as_bool().unwrap() {
                        "1"
                    } else {
                        "0"
                    }
                    .into(),
                );
            }
            // The seed after the previews: the replay without it (0, 0) ramps the first nudge
            // from β |c b|.
            if brake == Brake::Seed {
                without = args.clone();
                without.extend(["0".to_string(), "0".to_string()]);
                let a = &c["short_approach"];
                for k in ["breakaway_seed", "seed_speed_mm_s"] {
                    args.push(format!("{:?}", a[k].as_f64().unwrap_or(0.0)));
                }
            }
        }
        Some(replay(&without))
    } else {
        unlearnt
    };
    let from_c = replay(&args);
    let recorded: Vec<f64> = std::fs::read_to_string(&trace)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
        .collect();
    assert_eq!(from_c.len(), recorded.len());
    assert_eq!(recorded.len(), samples);
    if let Some(unlearnt) = unlearnt {
        assert_ne!(
            unlearnt, recorded,
            "the learnt lead, the short-step approach, the creep, the re-brake, the slip brake, the relearning or the learnt cut fraction changed no command"
        );
    }
    for (k, (a, b)) in from_c.iter().zip(&recorded).enumerate() {
        assert_eq!(a.to_bits(), b.to_bits(), "sample {k}: C {a} vs control {b}");
    }
    // The run exercises every branch: the PID outside the nudge band, the valve closed (0), and nudges
    // (a command while e_h < |e| <= e_n).
    let band = nudge["band_mm"].as_f64().unwrap();
    let hold = c["hold_band_mm"].as_f64().unwrap();
    let rows: Vec<(f64, f64)> = std::fs::read_to_string(&trace)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[1] - v[3], v[2])
        })
        .collect();
    assert!(rows.iter().any(|(e, u)| e.abs() > band && *u != 0.0));
    assert!(recorded.contains(&0.0));
    let nudges = rows
        .iter()
        .filter(|(e, u)| e.abs() > hold && e.abs() <= band && *u != 0.0)
        .count();
    assert!(nudges > 0, "no nudge in the run");
    // With the brake: its reverse command −a_b u_max = −0.25 × 255 after a full command (both
    // directions: the staircase goes up 82 mm and down 60 mm).
    if matches!(brake, Brake::Fixed | Brake::Learnt) {
        assert!(recorded.contains(&-63.75) && recorded.contains(&63.75));
        assert!(recorded.contains(&255.0) && recorded.contains(&-255.0));
    }
    // With the short-step approach: the brake up (75 mm, full command then −63.75), the short
    // drive both ways at 0.35 × 255 = 89.25 (raised by 5 per sample while the piston has not moved)
    // and its brake ∓0.5 × 255.
    // With the slip brake: a reverse command −side a_p u_max = ∓63.75 in the nudge band, against
    // the error's sign (a nudge towards r cut during a slip).
    if brake == Brake::Slip {
        assert!(rows
            .iter()
            .any(|(e, u)| e.abs() <= band && *u == -e.signum() * 63.75));
    }
    if brake == Brake::Short {
        assert!(recorded.contains(&255.0) && recorded.contains(&-63.75));
        assert!(recorded.contains(&89.25) && recorded.contains(&-89.25));
        assert!(recorded.contains(&-127.5) && recorded.contains(&127.5));
    }
}

/// Audit s19 M-1, L-1, L-2 and s31 M-6 through the C interface (crates/embedded/examples/c/refusals.c,
/// one line `NAME RC [VALUES]` per case; outputs preset to 42). Codes: 0 OK, −1 IPA_ERR_SETTING, −3
/// IPA_ERR_NOT_FINITE, −4 IPA_ERR_NUMERICAL, −6 IPA_ERR_NULL, −8 IPA_ERR_NOT_INITIALISED, −9
/// IPA_ERR_RANGE (the controllers' range, audit s31 M-6, and the estimator's, audit s33 H-2).
#[test]
fn c_interface_refuses_the_audit_s19_cases() {
    if no_cc() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let exe = build_example(dir.path(), "refusals");
    let out = Command::new(&exe).output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let line = |name: &str| -> Vec<f64> {
        let l = text
            .lines()
            .find(|l| l.split(' ').next() == Some(name))
            .unwrap_or_else(|| panic!("no line {name} in\n{text}"));
        l.split(' ').skip(1).map(|v| v.parse().unwrap()).collect()
    };
    let (ok, setting, not_finite, numerical) = (0.0, -1.0, -3.0, -4.0);
    // M-1: Ts = 1e-310 s is below the 1 µs floor; 1e-6 s and 0.01 s are kept.
    assert_eq!(line("ctl_init_ts_1e-310"), [setting]);
    assert_eq!(line("ctl_init_ts_1e-6"), [ok]);
    assert_eq!(line("ctl_init_ts_0.01"), [ok]);
    // r = 50, Kp = 3: y = 0 → 150; y = 1e308 → the velocity 1e310 overflows, 0 × ∞ = NaN: refused,
    // u not written; y = 1 → 3 × 49 = 147, as if the refused sample had not been given.
    assert_eq!(line("ctl_step_0"), [ok, 150.0]);
    assert_eq!(line("ctl_step_1"), [numerical, 42.0]);
    assert_eq!(line("ctl_step_2"), [ok, 147.0]);
    // PI, Kp = 0: e = 2e308 = ∞, Kp e = NaN: refused.
    assert_eq!(line("pi_init"), [ok]);
    assert_eq!(line("pi_step_overflow"), [numerical, 42.0]);
    // Audit s31 M-6: the plausibility range. On storage not (yet) a PI: −8; null: −6; a crossed or
    // NaN range: −1; [0, 200]: kept.
    let (null, not_initialised, range) = (-6.0, -8.0, -9.0);
    assert_eq!(line("pi_set_range_uninitialised"), [not_initialised]);
    assert_eq!(line("pi_set_range_null"), [null]);
    assert_eq!(line("pi_set_range_crossed"), [setting]);
    assert_eq!(line("pi_set_range_nan"), [setting]);
    assert_eq!(line("pi_set_range"), [ok]);
    // The glitch y = −1e6 mm (and a set-point of 250 mm) is refused with IPA_ERR_RANGE, u not
    // written; without a range it is taken: e = 1 000 050 mm saturates at +255.
    assert_eq!(line("pi_glitch_ranged"), [range, 42.0]);
    assert_eq!(line("pi_set_point_out_of_range"), [range, 42.0]);
    assert_eq!(line("pi_glitch_unranged"), [ok, 255.0]);
    // The next sample (e = 0.1 mm): the ranged controller gives bit for bit the command of the one that
    // never saw the glitch; the other has I = (1 − a)(0.1 + 10 000.5) + a (255 − 14 000 700) with
    // a = Ts/Tt = 1/1400, i.e. −9 605.6/1400 (crates/embedded/tests/wild_sample.rs derives it), and
    // commands Kp 0.1 + I + Ki Ts 0.1 = 1.4 − 6.861 142 857… + 0.001 < 0: away from r.
    let after = line("pi_after_glitch");
    assert_eq!(after[..3], [ok, ok, ok]);
    assert_eq!(after[3].to_bits(), after[5].to_bits(), "{after:?}");
    let by_hand = 1.4 - 9605.6 / 1400.0 + 0.001;
    assert!((after[4] - by_hand).abs() < 1e-9, "{after:?} vs {by_hand}");
    // The tuned controller (Kp = 3) with the range [0, 200]: a crossed range −1; the glitch refused,
    // u not written; then y = 1: 3 × 49 = 147.
    assert_eq!(line("ctl_set_range_crossed"), [setting]);
    assert_eq!(line("ctl_set_range"), [ok]);
    assert_eq!(line("ctl_glitch_ranged"), [range, 42.0]);
    assert_eq!(line("ctl_after_glitch"), [ok, 147.0]);
    // L-1: NaN and −∞ controller outputs are refused; u = 5 → b_r + m_r u / m_r = 10 + 5 = 15.
    assert_eq!(line("dz_nan"), [not_finite, 42.0]);
    assert_eq!(line("dz_minus_inf"), [not_finite, 42.0]);
    assert_eq!(line("dz_5"), [ok, 15.0]);
    // L-1: a NaN or ±∞ command in the record is reported (outputs untouched); the finite record's
    // largest negative −7, smallest positive 12 and max |u| 100.
    assert_eq!(line("record_start_nan"), [not_finite, 42.0, 42.0, 42.0]);
    assert_eq!(line("record_start_inf"), [not_finite, 42.0, 42.0, 42.0]);
    assert_eq!(line("record_start_finite"), [ok, -7.0, 12.0, 100.0]);
    // L-2: b_l0 = 1 > 0 and the crossed (+∞, −∞) are refused; the one-sided (−∞, +∞) is kept.
    assert_eq!(line("hrls_init_bl0_1"), [setting]);
    assert_eq!(line("hrls_init_crossed_inf"), [setting]);
    assert_eq!(line("hrls_init_one_sided"), [ok]);
    // Audit s33 H-2: the estimator's plausibility range [−5, 205] mm. On storage not (yet) an
    // estimator: −8; null: −6; crossed or NaN: −1; then kept.
    assert_eq!(line("hrls_set_range_uninitialised"), [not_initialised]);
    assert_eq!(line("hrls_set_range_null"), [null]);
    assert_eq!(line("hrls_set_range_crossed"), [setting]);
    assert_eq!(line("hrls_set_range_nan"), [setting]);
    assert_eq!(line("hrls_set_range"), [ok]);
    // The glitch y = 1000 mm: refused with −9 and the storage byte for byte unchanged (1) with the
    // range; taken (0) without one, as before.
    assert_eq!(line("hrls_glitch_ranged"), [range, 1.0]);
    assert_eq!(line("hrls_glitch_unranged"), [ok]);
    // Every other update OK; θ̂ (n = 7) of the ranged estimator bit for bit that of one that never saw
    // the glitch (1), the unranged one's not (0).
    assert_eq!(line("hrls_after_glitch"), [0.0, 7.0, 1.0, 0.0]);
    // A command beyond limit = 255 counts: refused with the range (state unchanged), taken without.
    assert_eq!(line("hrls_u_beyond_limit_ranged"), [range, 1.0]);
    assert_eq!(line("hrls_u_beyond_limit_unranged"), [ok]);
    // θ̂ = 0 (no update yet): slopes 0, IPA_NOT_PHYSICAL (3) for reason 1 (no valve deadzone).
    assert_eq!(line("hrls_deadzone_reason_fresh"), [3.0, 1.0]);
    assert_eq!(
        line("hrls_deadzone_reason_uninitialised"),
        [not_initialised]
    );
}

/// docs/embedded.md's "The C example" prints what the example prints now (audit s20 D-2: the UD line
/// had gone stale after a change to the UD update, unnoticed because only C against the CLI was checked):
/// the page's `./track …` lines are run on the page's record (`simulate --plant ipa --seed 1`) and
/// their output must equal the "Output (measured)" block line by line; every number of the paragraph
/// after it (identify's figures, shortest round-trip form) must be bit for bit one of those doubles.
#[test]
fn the_embedded_page_prints_what_the_c_example_prints() {
    if no_cc() {
        return;
    }
    let page = std::fs::read_to_string(workspace().join("docs/embedded.md")).unwrap();
    let section = page
        .split("## The C example")
        .nth(1)
        .expect("docs/embedded.md has a section '## The C example'");
    let (commands, rest) = section
        .split_once("Output (measured):")
        .expect("the section has 'Output (measured):'");
    let track_lines: Vec<Vec<&str>> = commands
        .lines()
        .filter_map(|l| l.trim().strip_prefix("./track "))
        .map(|l| {
            l.split('<')
                .next()
                .unwrap()
                .split_whitespace()
                .collect::<Vec<&str>>()
        })
        .collect();
    assert_eq!(track_lines.len(), 3, "the page runs ./track three times");
    assert!(
        commands.contains("ipa-sysid simulate --plant ipa --seed 1 --out est.csv"),
        "the page's record is simulate --plant ipa --seed 1"
    );
    let mut blocks = rest.split("```");
    let _before = blocks.next();
    let block = blocks.next().expect("the output block");
    let documented: Vec<&str> = block
        .lines()
        .skip(1) // the fence's info string ("text")
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect();
    let paragraph = blocks.next().expect("the paragraph after the block");
    let paragraph = paragraph
        .split("## ")
        .next()
        .unwrap()
        .split("The example's usage")
        .next()
        .unwrap();

    let tmp = tempfile::tempdir().unwrap();
    let track = build_track(tmp.path());
    let csv = tmp.path().join("est.csv");
    cli(&[
        "simulate",
        "--plant",
        "ipa",
        "--seed",
        "1",
        "--out",
        csv.to_str().unwrap(),
    ]);
    let mut printed = Vec::new();
    for args in &track_lines {
        let out = Command::new(&track)
            .args(args)
            .stdin(std::fs::File::open(&csv).unwrap())
            .output()
            .unwrap();
        assert!(out.status.success(), "./track {args:?} failed");
        printed.push(String::from_utf8(out.stdout).unwrap().trim().to_string());
    }
    assert_eq!(
        documented, printed,
        "docs/embedded.md's C output block differs from what ./track prints now"
    );

    // Every double the C example printed, then the paragraph's numbers must each be one of them.
    let mut doubles: Vec<f64> = Vec::new();
    for line in &printed {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        for name in ["b_l", "b_r", "m_l", "m_r"] {
            doubles.push(v[name].as_f64().unwrap());
        }
        doubles.extend(numbers(&v["a"]));
    }
    let numbers_in_text: Vec<f64> = paragraph
        .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-' || c == 'e'))
        .filter(|w| w.contains('.') && w.len() > 12)
        .map(|w| w.trim_end_matches('.').parse::<f64>().unwrap())
        .collect();
    assert!(
        numbers_in_text.len() >= 21,
        "the paragraph quotes identify's figures ({} found)",
        numbers_in_text.len()
    );
    for x in &numbers_in_text {
        assert!(
            doubles.iter().any(|d| d.to_bits() == x.to_bits()),
            "docs/embedded.md: identify's figure {x:e} is none of the doubles the C example prints now"
        );
    }
}
