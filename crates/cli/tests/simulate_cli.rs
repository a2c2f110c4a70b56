//! `ipa-sysid simulate` and `plant-config` end to end.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::Path;

mod common;
use common::bin;

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

/// A model file of y(k) = −a1 y(k−1) + b1 (u(k−1) − u0) + c around the operating point (u0, y0) when
/// given (version 2), written by hand.
fn first_order_model(dir: &Path, name: &str, a1: f64, c: f64, op: Option<(f64, f64)>) -> String {
    let op = op.map_or(String::new(), |(u0, y0)| {
        format!(r#", "operating_point": {{"u": [{u0}], "y": {y0}}}"#)
    });
    std::fs::write(
        dir.join(name),
        format!(
            r#"{{"format": "ipa-sysid-model", "version": 2, "model": {{"kind": "arx", "ts": 0.1, "na": 1,
            "nb": 1, "nk": 1, "a": [{a1}], "b": [0.5], "offset": {c}{op}}}}}"#
        ),
    )
    .unwrap();
    format!("model:{name}")
}

// Without --y0 a stable model starts at rest at its own level — the fixed point y = y0 + c / (1 + a1)
// of its equation with the input at the operating point — so the record shows the input's response
// and no decay from an arbitrary start; an integrator (no resting level) starts mid-stroke at 100 mm as
// the IPA does (so does a near-integrator); --y0 still overrides. Expectations: the difference equation run here.
#[test]
fn a_stable_model_starts_at_its_own_resting_level() {
    let dir = tempfile::tempdir().unwrap();
    let run = |plant: &str, extra: &[&str], out: &str| {
        let mut args = vec!["--plant", plant];
        args.extend(extra);
        let o = simulate(dir.path(), &args, out);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (
            sysid::data::read_csv(&dir.path().join(out), &Default::default()).unwrap(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let expect = |y0: f64, a1: f64, c: f64, u0: f64, yop: f64, u: &[f64]| {
        let mut y = vec![y0];
        for k in 0..u.len() - 1 {
            let dev = y[k] - yop;
            y.push(yop - a1 * dev + 0.5 * (u[k] - u0) + c);
        }
        y
    };
    let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9);

    // Stable, no operating point: rest 0.1 / (1 − 0.8) = 0.5.
    let m = first_order_model(dir.path(), "stable.json", -0.8, 0.1, None);
    let (d, err) = run(&m, &["--input", "step:10@5", "--samples", "12"], "s.csv");
    let want = expect(0.5, -0.8, 0.1, 0.0, 0.0, d.u());
    assert!(close(d.y(), &want), "{:?} vs {want:?}", d.y());
    assert!(d.y()[..6].iter().all(|y| (y - 0.5).abs() < 1e-12));
    assert!(
        err.contains("held before the start, the model's resting level"),
        "{err}"
    );

    // Stable around (u0, y0) = (20, 3): rest 3 + 0.1 / 0.2 = 3.5 with the input at u0.
    std::fs::write(dir.path().join("u.csv"), "u\n20\n20\n20\n30\n30\n30\n30\n").unwrap();
    let m = first_order_model(dir.path(), "op.json", -0.8, 0.1, Some((20.0, 3.0)));
    let (d, _) = run(&m, &["--input", "file:u.csv"], "o.csv");
    let want = expect(3.5, -0.8, 0.1, 20.0, 3.0, d.u());
    assert!(close(d.y(), &want), "{:?} vs {want:?}", d.y());
    assert!((d.y()[3] - 3.5).abs() < 1e-12);

    // An integrator has no resting level: mid-stroke, as the IPA.
    let m = first_order_model(dir.path(), "int.json", -1.0, 0.0, None);
    let (d, err) = run(&m, &["--input", "step:10@5", "--samples", "12"], "i.csv");
    assert_eq!(d.y()[0], 100.0);
    assert!(close(d.y(), &expect(100.0, -1.0, 0.0, 0.0, 0.0, d.u())));
    assert!(err.contains("from y0 = 100 held before the start"), "{err}");
    assert!(err.contains("no resting level"), "{err}");
    // A pole at 1 is an integrator, not an unstable model (audit s9 S3).
    assert!(err.contains("a pole at 1 (an integrator)"), "{err}");
    assert!(!err.contains("unstable"), "{err}");

    // A near-integrator (pole 0.9995, time constant 2000 samples: an identified position model) too.
    let m = first_order_model(dir.path(), "near.json", -0.9995, 0.01, None);
    let (d, _) = run(&m, &["--input", "step:10@5", "--samples", "12"], "n.csv");
    assert_eq!(d.y()[0], 100.0);

    // A pole at 1.02 is unstable, and said so. (Its record goes to its own file: u.csv above is the
    // input, a one-column table, which an output of another header may not replace.)
    let m = first_order_model(dir.path(), "unstable.json", -1.02, 0.0, None);
    let (_, err) = run(&m, &["--input", "step:10@5", "--samples", "12"], "un.csv");
    assert!(
        err.contains("unstable model (a pole has modulus 1.020000"),
        "{err}"
    );

    // --y0 overrides the resting level, and the words say where the model goes from there
    // (audit s9 S2: "from rest" was untrue for a start away from the resting level).
    let m = first_order_model(dir.path(), "stable2.json", -0.8, 0.1, None);
    let (d, err) = run(
        &m,
        &["--input", "step:10@5", "--samples", "12", "--y0", "7"],
        "y.csv",
    );
    assert!(close(d.y(), &expect(7.0, -0.8, 0.1, 0.0, 0.0, d.u())));
    assert!(err.contains("the model rests at 0.5"), "{err}");

    // With an output nonlinearity y = g(v) the linear part starts at its own rest, v̄ = 0.1 / 0.2,
    // so the record is flat until the step (audit s9 S1: it started at g(100), saturated, and
    // decayed), and the words give y(0) as recorded.
    std::fs::write(
        dir.path().join("wiener.json"),
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "arx", "ts": 0.1, "na": 1,
        "nb": 1, "nk": 1, "a": [-0.8], "b": [0.5], "offset": 0.1,
        "output_nonlinearity": {"kind": "saturation", "s_l": -1.0, "s_r": 0.3, "m": 1.0}}}"#,
    )
    .unwrap();
    let (d, err) = run(
        "model:wiener.json",
        &["--input", "step:10@5", "--samples", "12"],
        "w.csv",
    );
    assert!(d.y()[..6].iter().all(|y| *y == d.y()[0]), "{:?}", d.y());
    assert!(err.contains("with the linear part held at 0.5"), "{err}");
    assert!(
        err.contains(&format!("y(0) = {}", d.y()[0])) && err.contains("resting level"),
        "{err}"
    );
}

// A model without an operating point (identified without --detrend mean) rests for every past command 0; when its
// estimation data never had u = 0 (its stored data range) the record opens with a transient from a state
// the data never showed, and `simulate` says so (audit s11 S3). Not said when 0 is inside the range, when
// the model has an operating point, or when the user chose the start.
#[test]
fn a_rest_outside_the_models_data_is_pointed_out() {
    let dir = tempfile::tempdir().unwrap();
    let model = |name: &str, range: &str, op: &str| {
        std::fs::write(
            dir.path().join(name),
            format!(
                r#"{{"format": "ipa-sysid-model", "version": 2, "model": {{"kind": "arx", "ts": 0.1, "na": 1,
                "nb": 1, "nk": 1, "a": [-0.8], "b": [0.5], "offset": 0.1{op},
                "data_range": {{"u": [{range}], "y": [2.0, 9.0]}}}}}}"#
            ),
        )
        .unwrap();
        format!("model:{name}")
    };
    let warned = |plant: &str, extra: &[&str]| {
        let mut args = vec!["--plant", plant, "--input", "step:5@3", "--samples", "8"];
        args.extend(extra);
        let o = simulate(dir.path(), &args, "s.csv");
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{err}");
        err.contains("warning: the model starts at its rest")
            .then_some(err)
    };
    let outside = model("off.json", "[3.0, 6.0]", "");
    let err = warned(&outside, &[]).expect("a warning");
    // Its rest c / (1 + a1) = 0.1 / 0.2 = 0.5, the input's range and the output's.
    assert!(
        err.contains("y0 = 0.5") && err.contains("u in [3, 6]"),
        "{err}"
    );
    assert!(
        err.contains("[2, 9]") && err.contains("--detrend mean"),
        "{err}"
    );
    assert!(warned(&outside, &["--y0", "4"]).is_none());
    assert!(warned(&model("in.json", "[-1.0, 6.0]", ""), &[]).is_none());
    let op = r#", "operating_point": {"u": [4.5], "y": 5.0}"#;
    assert!(warned(&model("op.json", "[3.0, 6.0]", op), &[]).is_none());
}

// Audit s12 F4: the designed inputs are the IPA's. At a slow sampling period the multisine's band (1 Hz
// up to 0.8 f_Nyquist = 0.1 Hz at Ts = 4 s) holds no harmonic, so it is refused instead of written as a
// constant; an input outside the model's data (PRBS ±255 counts against data in [0.4, 6.5]) is warned;
// one inside (a step to 5 against data in [-1, 6]) is not.
#[test]
fn an_input_the_model_never_saw_is_pointed_out_and_an_empty_multisine_refused() {
    let dir = tempfile::tempdir().unwrap();
    let model = |name: &str, ts: f64, range: &str| {
        std::fs::write(
            dir.path().join(name),
            format!(
                r#"{{"format": "ipa-sysid-model", "version": 2, "model": {{"kind": "arx", "ts": {ts}, "na": 1,
                "nb": 1, "nk": 1, "a": [-0.8], "b": [0.5], "operating_point": {{"u": [3.0], "y": 5.0}},
                "data_range": {{"u": [{range}], "y": [2.0, 9.0]}}}}}}"#
            ),
        )
        .unwrap();
        format!("model:{name}")
    };
    let slow = model("slow.json", 4.0, "[0.4, 6.5]");
    let o = simulate(
        dir.path(),
        &["--plant", &slow, "--input", "multisine", "--samples", "500"],
        "m.csv",
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("fewer than 2 harmonics") && err.contains("Ts = 4 s"),
        "{err}"
    );
    assert!(!dir.path().join("m.csv").exists());
    let o = simulate(
        dir.path(),
        &["--plant", &slow, "--input", "prbs", "--samples", "200"],
        "p.csv",
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("warning: the input spans [-255, 255]") && err.contains("in [0.4, 6.5]"),
        "{err}"
    );
    let fast = model("in.json", 0.1, "[-1.0, 6.0]");
    let o = simulate(
        dir.path(),
        &["--plant", &fast, "--input", "step:5@3", "--samples", "8"],
        "s.csv",
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(
        o.status.success() && !err.contains("the input spans"),
        "{err}"
    );
    // The output too (audit s13 M3): y = 5 + 0.5 (u − 3) / (1 − 0.8) at rest, so a step to u = 6, inside
    // the data's input range, settles at 12.5, beyond the data's [2, 9] by more than a tenth of its
    // span (before the step u(0) = 0 gives y(1) = 5 + 0.5 (0 − 3) = 3.5, the lowest); after 8 samples
    // of a step to 5 (y < 5 + 5 = 10, here 8.4) it is still within 9.7.
    assert!(!err.contains("simulated output spans"), "{err}");
    let o = simulate(
        dir.path(),
        &["--plant", &fast, "--input", "step:6@1", "--samples", "100"],
        "o.csv",
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(
        !err.contains("the input spans")
            && err.contains("warning: the simulated output spans [3.500000, 12.5")
            && err.contains("had y in [2, 9]: outside it the model extrapolates"),
        "{err}"
    );
}

// Audit s16 L14: `--input file:CSV` with a time column replays the commands at the column's step
// (0.02 s here: the written record's t steps 0.02 s); a --ts that contradicts it is said in the
// reader's words, and a model plant with its own Ts says the commands are not replayed as recorded.
// A file without a time column keeps the default Ts = 0.01 s.
#[test]
fn a_command_file_s_time_column_sets_ts_or_is_said() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let ts_file = 0.02;
    let mut with_t = String::from("t,u\n");
    let mut without_t = String::from("u\n");
    for k in 0..300 {
        let u = if (k / 50) % 2 == 0 { 120 } else { -120 };
        with_t += &format!("{},{u}\n", k as f64 * ts_file);
        without_t += &format!("{u}\n");
    }
    std::fs::write(p.join("u_t.csv"), with_t).unwrap();
    std::fs::write(p.join("u.csv"), without_t).unwrap();
    let steps = |file: &str| -> Vec<f64> {
        let text = std::fs::read_to_string(p.join(file)).unwrap();
        let t: Vec<f64> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap().parse().unwrap())
            .collect();
        t.windows(2).map(|w| w[1] - w[0]).collect()
    };

    let o = simulate(p, &["--plant", "ipa", "--input", "file:u_t.csv"], "a.csv");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("(Ts = 0.02 s, the time column t of u_t.csv)"),
        "{err}"
    );
    assert!(!err.contains("warning"), "{err}");
    assert!(steps("a.csv").iter().all(|d| (d - ts_file).abs() < 1e-9));

    let o = simulate(
        p,
        &["--plant", "ipa", "--input", "file:u_t.csv", "--ts", "0.01"],
        "b.csv",
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains(
            "u_t.csv: --ts 0.01 s contradicts the time column t (its typical step is 0.02 s)"
        ),
        "{err}"
    );
    assert!(steps("b.csv").iter().all(|d| (d - 0.01).abs() < 1e-9));

    // The paper's model runs at its own Ts = 0.01 s.
    let o = simulate(p, &["--plant", "paper", "--input", "file:u_t.csv"], "c.csv");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("its time column t steps 0.02 s, but the plant runs at its own Ts = 0.01 s"),
        "{err}"
    );

    let o = simulate(p, &["--plant", "ipa", "--input", "file:u.csv"], "d.csv");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("(Ts = 0.01 s)") && !err.contains("warning"),
        "{err}"
    );
    assert!(steps("d.csv").iter().all(|d| (d - 0.01).abs() < 1e-9));
}

// The paper's model has no end stops: a record of it that leaves the IPA's stroke 0..200 mm says so
// (audit s16 L3: an APRBS record reached −966 mm without a word); one that stays inside does not.
// Whether it left is read from the written record here.
#[test]
fn a_paper_record_beyond_the_stroke_is_warned() {
    let dir = tempfile::tempdir().unwrap();
    for (input, samples) in [("aprbs", "3000"), ("step:20@10", "50")] {
        let o = simulate(
            dir.path(),
            &[
                "--plant",
                "paper",
                "--input",
                input,
                "--samples",
                samples,
                "--seed",
                "3",
            ],
            "p.csv",
        );
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let d = sysid::data::read_csv(&dir.path().join("p.csv"), &Default::default()).unwrap();
        let beyond = d.y().iter().any(|y| *y < 0.0 || *y > 200.0);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(
            e.contains("beyond the IPA's stroke 0..200 mm"),
            beyond,
            "{input}: {e}"
        );
        if input == "aprbs" {
            assert!(beyond, "the APRBS record was expected to leave the stroke");
        }
    }
}

// A tiny model Ts is printed compactly (the shortest decimal that reads back), not as hundreds of
// digits, in the message and in the CSV's t column, whose cells read back as k Ts (audit s16 L9: a
// 496-character stderr line and 300-digit t cells for Ts = 1e-300 s). Since audit s21 L-B2 a model file's
// Ts must be at least 1e-6 s: 1e-300 is refused naming ts, in one short line; 1.1e-6 s is the tiny Ts
// checked here.
#[test]
fn a_tiny_model_ts_is_printed_compactly_and_exactly() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("tiny.json"),
        r#"{"format": "ipa-sysid-model", "version": 2, "model": {"kind": "arx", "ts": 1.1e-6, "na": 1,
        "nb": 1, "nk": 1, "a": [-0.8], "b": [0.5]}}"#,
    )
    .unwrap();
    let o = simulate(
        dir.path(),
        &[
            "--plant",
            "model:tiny.json",
            "--input",
            "step:10@2",
            "--samples",
            "20",
        ],
        "s.csv",
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(o.status.success(), "{err}");
    assert!(err.contains("(Ts = 1.1e-6 s"), "{err}");
    assert!(err.lines().all(|l| l.len() < 300), "{err}");
    let csv = std::fs::read_to_string(dir.path().join("s.csv")).unwrap();
    let mut rows = 0;
    for (k, line) in csv.lines().skip(1).enumerate() {
        let t = line.split(',').next().unwrap();
        assert!(t.len() <= 24, "row {k}: {t}");
        let v: f64 = t.parse().unwrap();
        // t_k = k Ts within a rounding of the product.
        let expected = k as f64 * 1.1e-6;
        assert!(
            (v - expected).abs() <= 1e-15 * expected,
            "row {k}: {v} vs {expected}"
        );
        rows += 1;
    }
    assert_eq!(rows, 20);
    // The same model's Ts in a refusal: --ts against the model's own Ts.
    let o = simulate(
        dir.path(),
        &["--plant", "model:tiny.json", "--ts", "0.01"],
        "s2.csv",
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success());
    assert!(err.contains("sampled at Ts = 1.1e-6 s"), "{err}");
    assert!(err.lines().all(|l| l.len() < 300), "{err}");
    // Ts = 1e-300 s: refused naming ts, the value in exponent form, one short line.
    let text = std::fs::read_to_string(dir.path().join("tiny.json"))
        .unwrap()
        .replace("1.1e-6", "1e-300");
    std::fs::write(dir.path().join("tiny.json"), text).unwrap();
    let o = simulate(
        dir.path(),
        &["--plant", "model:tiny.json", "--samples", "20"],
        "s3.csv",
    );
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("ts = 1e-300 s is below 1e-6 s"), "{err}");
    assert!(err.lines().all(|l| l.len() < 300), "{err}");
}

// Audit s34 H-1's last point: the paper's plant leaks (A(1) ≠ 0: a pole just inside 1), so y0 = 100 held
// before the start is not its rest and y moves away from it with the input at 0; `simulate` said "from
// rest at y0 = 100"; now the paper plant's start is worded as a model's (held level, possible drift).
#[test]
fn the_paper_plant_start_is_not_called_rest() {
    let dir = tempfile::tempdir().unwrap();
    let out = simulate(dir.path(), &["--plant", "paper"], "p.csv");
    assert!(out.status.success());
    let words = String::from_utf8_lossy(&out.stderr);
    assert!(!words.contains("from rest"), "{words}");
    assert!(
        words.contains("from y0 = 100 held before the start"),
        "{words}"
    );
    assert!(words.contains("drift"), "{words}");
}
