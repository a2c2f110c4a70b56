//! Audit s20 through the binary: `response` (M-2: a model's frequency response, impulse and step, DC
//! gain and a PI loop's margins), decimal-comma and date-time CSV errors that name the cause (L-1,
//! L-5), and the `--samples` refusal in the "invalid setting X = V" form (L-3). Each expectation is
//! computed here from the model's coefficients or from what the user passed, never copied from output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};

mod common;
use common::{run as ipa_sysid, s, stderr};

/// A model file at Ts = 0.05 s: A = 1 − α z⁻¹, B = β, nk = 1 (y(k) = α y(k−1) + β x(k−1)), ARX, or
/// Hammerstein with b1 = 1 (β = 1) and the given deadzone.
fn model_file(
    dir: &Path,
    name: &str,
    alpha: f64,
    beta: f64,
    deadzone: Option<[f64; 4]>,
) -> PathBuf {
    let path = dir.join(name);
    let mut model = serde_json::json!({
        "kind": if deadzone.is_some() { "hammerstein" } else { "arx" },
        "ts": 0.05, "na": 1, "nb": 1, "nk": 1,
        "a": [-alpha], "b": [beta], "offset": null,
        "noise_model": "equation-error"
    });
    if let Some([b_l, b_r, m_l, m_r]) = deadzone {
        model["deadzone"] = serde_json::json!({"b_l": b_l, "b_r": b_r, "m_l": m_l, "m_r": m_r});
        model["noise_model"] = "output-error".into();
    }
    let doc = serde_json::json!({"format": "ipa-sysid-model", "version": 2, "model": model});
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

/// The Hammerstein model file of the tests: α = 0.9, b1 = 1, deadzone b_l = −20, b_r = 30, m_l = 0.02,
/// m_r = 0.01 (G(1) = 10; from u 0.1 on the right, 0.2 on the left).
fn hammerstein_file(dir: &Path) -> PathBuf {
    model_file(dir, "h.json", 0.9, 1.0, Some([-20.0, 30.0, 0.02, 0.01]))
}

fn json_of(args: &[&str]) -> serde_json::Value {
    let o = ipa_sysid(args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    serde_json::from_slice(&o.stdout).unwrap()
}

fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

// M-2: G(e^{jθ}) = β e^{−jθ} / (1 − α e^{−jθ}), θ = 2π f Ts; impulse β α^(k−1); DC gain β / (1 − α).
#[test]
fn response_of_a_first_order_arx_file_is_the_hand_computed_one() {
    let dir = tempfile::tempdir().unwrap();
    let (alpha, beta, ts) = (0.7, 0.4, 0.05);
    let m = model_file(dir.path(), "arx.json", alpha, beta, None);
    let csv = dir.path().join("bode.csv");
    let r = json_of(&[
        "response",
        "--model",
        s(&m),
        "--points",
        "11",
        "--samples",
        "8",
        "--out",
        s(&csv),
        "--json",
        "-",
    ]);
    assert!((r["dc_gain"].as_f64().unwrap() - beta / (1.0 - alpha)).abs() < 1e-12);
    let imp = floats(&r["impulse"]);
    assert_eq!(imp.len(), 8);
    assert_eq!(imp[0], 0.0);
    for (k, h) in imp.iter().enumerate().skip(1) {
        assert!(
            (h - beta * alpha.powi(k as i32 - 1)).abs() < 1e-12,
            "impulse {k}"
        );
    }
    let (f, mag, ph) = (
        floats(&r["bode"]["f_hz"]),
        floats(&r["bode"]["mag_db"]),
        floats(&r["bode"]["phase_deg"]),
    );
    assert_eq!(f.len(), 11);
    assert!((f[10] - 0.5 / ts).abs() < 1e-9);
    for i in 0..11 {
        let th = 2.0 * std::f64::consts::PI * f[i] * ts;
        let g = beta / (1.0 - 2.0 * alpha * th.cos() + alpha * alpha).sqrt();
        let p = -th - (alpha * th.sin()).atan2(1.0 - alpha * th.cos());
        assert!((mag[i] - 20.0 * g.log10()).abs() < 1e-9 && (ph[i] - p.to_degrees()).abs() < 1e-7);
    }
    // The CSV holds the same table.
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("f_hz,w_rad_s,mag_db,phase_deg"));
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 11);
    assert!(rows.iter().zip(&mag).all(|(row, m)| row[2] == *m));
}

// M-2: the printed report of a Hammerstein model says which gain: G with b1 = 1 and m_r, m_l per side,
// with their dB offsets (20 log10 0.01 = −40 dB, 20 log10 0.02 ≈ −33.98 dB).
#[test]
fn response_of_a_hammerstein_file_states_the_slope_per_side() {
    let dir = tempfile::tempdir().unwrap();
    let m = hammerstein_file(dir.path());
    let o = ipa_sysid(&["response", "--model", s(&m), "--kp", "2", "--ki", "0.5"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(out.contains("b1 = 1"), "{out}");
    assert!(
        out.contains("m_r G = 0.01 G") && out.contains("(-40.00 dB)"),
        "{out}"
    );
    assert!(
        out.contains("m_l G = 0.02 G") && out.contains("(-33.98 dB)"),
        "{out}"
    );
    // DC gain G(1) = 1 / (1 − 0.9) = 10; from u: 0.1 on the right, 0.2 on the left.
    assert!(out.contains("G(1) = 10; right: 0.1; left: 0.2"), "{out}");
    assert!(out.contains("margins:  PI Kp = 2, Ki = 0.5"), "{out}");
    assert!(
        out.contains("|m_r G| dB") && out.contains("|m_l G| dB"),
        "{out}"
    );
}

/// `response --model MODEL --json - ARGS`: its `margins` object.
fn margins_of(model: &Path, args: &[&str]) -> serde_json::Value {
    let r = json_of(&[&["response", "--model", s(model), "--json", "-"], args].concat());
    r["margins"].clone()
}

// Session 21: `response --controller` reads the file `tune --out` wrote (as `control --controller`)
// and gives the margins `tune` reported for it; a controller with Kd = 0 gives those of its Kp, Ki
// passed as --kp/--ki; and --controller beside --kp is refused.
#[test]
fn response_margins_of_a_controller_file_are_tunes_and_those_of_its_gains() {
    let dir = tempfile::tempdir().unwrap();
    let m = hammerstein_file(dir.path());
    let tuned = common::tune(
        dir.path(),
        &m,
        &["--max-evaluations", "10", "--variants", "1"],
    );
    let c = s(&tuned.controller);
    let from_file = margins_of(&m, &["--controller", c]);
    assert!(from_file["gain_margin_db"].is_number(), "{from_file}");
    assert_eq!(from_file, tuned.report["margins"]);
    // The same file with its derivative removed: the PI of its Kp, Ki (written out in full).
    let mut file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&tuned.controller).unwrap()).unwrap();
    file["controller"]["kd"] = 0.0.into();
    file["controller"]["derivative_filter_s"] = 0.0.into();
    let pi_file = dir.path().join("pi.json");
    std::fs::write(&pi_file, file.to_string()).unwrap();
    let (kp, ki) = (
        file["controller"]["kp"].as_f64().unwrap(),
        file["controller"]["ki"].as_f64().unwrap(),
    );
    assert_eq!(
        margins_of(&m, &["--controller", s(&pi_file)]),
        margins_of(
            &m,
            &["--kp", &format!("{kp:?}"), "--ki", &format!("{ki:?}")]
        )
    );
    let o = ipa_sysid(&["response", "--model", s(&m), "--controller", c, "--kp", "1"]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains("--controller") && e.contains("--kp") && e.contains("cannot be used with"),
        "{e}"
    );
}

// Session 21: the hand-derived loop of the library's test through a controller file: L = K β z⁻¹ /
// (1 − α z⁻¹) with K = Kp = 4 (Ki = Kd = 0), α = 0.5, β = 0.25 (Kβ = 1): |L| = 1 where cos θ = 0.25,
// PM = 180° + arg L there; L(−1) = −Kβ/(1 + α): GM = 20 log10 1.5 dB at ω = π/Ts. The printed line
// names the file and its gains (the JSON's `controller` too); a file that says it did not meet its
// specification gets a `controller:` warning; a controller tuned at another Ts is refused naming
// --controller.
#[test]
fn response_margins_of_a_hand_written_controller_file_are_the_hand_derived_ones() {
    let dir = tempfile::tempdir().unwrap();
    let (alpha, beta, ts) = (0.5, 0.25, 0.05);
    let m = model_file(dir.path(), "arx.json", alpha, beta, None);
    let controller = |name: &str, ts: f64| {
        let path = dir.path().join(name);
        let c = serde_json::json!({"format": "ipa-sysid-controller", "version": 1, "controller": {
            "ts_s": ts, "kp": 4.0, "ki": 0.0, "kd": 0.0, "derivative_filter_s": 0.0, "u_max": 255.0,
            "hold_band_mm": 0.0, "fine_band_mm": 0.0, "reset_on_crossing": false, "compensator": null}});
        std::fs::write(&path, c.to_string()).unwrap();
        path
    };
    let c = controller("p.json", ts);
    let g = margins_of(&m, &["--controller", s(&c)]);
    let th = 0.25f64.acos();
    let pm = 180.0 + (-th - (alpha * th.sin()).atan2(1.0 - alpha * th.cos())).to_degrees();
    let f = |k: &str| g[k].as_f64().unwrap();
    assert!((f("phase_margin_deg") - pm).abs() < 0.01, "{g} vs {pm}");
    assert!((f("gain_crossover_rad_s") - th / ts).abs() < 1e-3 * th / ts);
    assert!(
        (f("gain_margin_db") - 20.0 * 1.5f64.log10()).abs() < 1e-6,
        "{g}"
    );
    let pi = std::f64::consts::PI;
    assert!((f("phase_crossover_rad_s") - pi / ts).abs() < 1e-6 * pi / ts);
    let o = ipa_sysid(&["response", "--model", s(&m), "--controller", s(&c)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(
        out.contains(&format!(
            "margins:  {} Kp = 4, Ki = 0, Kd = 0, Tf = 0 s: gain ",
            c.display()
        )),
        "{out}"
    );
    // The JSON names the controller as the text does; the file carries no verdict: no controller word.
    let r = json_of(&[
        "response",
        "--model",
        s(&m),
        "--controller",
        s(&c),
        "--json",
        "-",
    ]);
    // The controller of the margins as the file's numbers (audit s22 L-B7: a rounded string before).
    let gains = serde_json::json!({"file": s(&c), "kp": 4.0, "ki": 0.0, "kd": 0.0, "tf_s": 0.0});
    assert_eq!(r["controller"], gains, "{r}");
    let said = |r: &serde_json::Value| {
        r["warnings"]
            .as_array()
            .unwrap()
            .iter()
            .any(|w| w.as_str().unwrap().starts_with("controller: "))
    };
    assert!(!said(&r), "{r}");
    // A file whose provenance says it did not meet its specification: said, as `control` says it.
    let mut file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&c).unwrap()).unwrap();
    file["provenance"] = serde_json::json!({"meets_spec": false});
    let unmet = dir.path().join("unmet.json");
    std::fs::write(&unmet, file.to_string()).unwrap();
    let r = json_of(&[
        "response",
        "--model",
        s(&m),
        "--controller",
        s(&unmet),
        "--json",
        "-",
    ]);
    assert!(said(&r), "{r}");
    let other = controller("other.json", 0.01);
    let o = ipa_sysid(&["response", "--model", s(&m), "--controller", s(&other)]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains("invalid setting --controller")
            && e.contains("the model's Ts = 0.05 s")
            && e.contains("tuned for Ts = 0.01 s"),
        "{e}"
    );
}

// Session 21: one formatter of a complex pole. A = 1 − z⁻¹ + 0.5 z⁻²: z² − z + 0.5 = 0 gives
// p = 0.5 ± 0.5i, |p| = √0.5 = 0.707107 (6 digits). `response` prints the pair with its modulus,
// `identify` (noise-free record of that model, so least squares recovers it) without.
#[test]
fn identify_and_response_print_a_complex_pole_pair_in_one_form() {
    let dir = tempfile::tempdir().unwrap();
    let data = dir.path().join("pair.csv");
    let mut g = common::lcg(21);
    let (u, y) = common::arx_signals(400, &[1.0, -0.5], &[1.0], |_| g.unit() - 0.5);
    common::write_csv(&data, "u,y", None, &[&u, &y]);
    let model = dir.path().join("pair.json");
    let args = [
        common::identify_arx(&data, "2", "1", "ls"),
        vec!["--ts", "0.05", "--save-model", s(&model)],
    ]
    .concat();
    let o = ipa_sysid(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(
        out.contains("Poles: 0.5 + 0.5i, 0.5 - 0.5i  → stable"),
        "{out}"
    );
    let o = ipa_sysid(&["response", "--model", s(&model)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8(o.stdout).unwrap();
    assert!(
        out.contains("poles:    0.5 + 0.5i (|p| 0.707107), 0.5 - 0.5i (|p| 0.707107)\n"),
        "{out}"
    );
}

/// A 2-column record with the given header and rows (one string per line).
fn csv(dir: &Path, name: &str, lines: &[&str]) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, lines.join("\n") + "\n").unwrap();
    path
}

// L-1: a comma-separated file whose numbers have decimal commas, quoted or not, in memory and streamed:
// the error names decimal commas and the ways out.
#[test]
fn decimal_commas_in_a_comma_separated_file_are_named_as_the_cause() {
    let dir = tempfile::tempdir().unwrap();
    let quoted = csv(
        dir.path(),
        "quoted.csv",
        &["\"u\",\"y\"", "\"-0,109\",\"53,8\"", "\"0,5\",\"53,9\""],
    );
    let ragged = csv(
        dir.path(),
        "ragged.csv",
        &["u,y", "-0,109,53,8", "0,5,53,9"],
    );
    // Since session 35 (fix35, audit s34 L-4) quoted fields separate the columns, so quoted decimal
    // commas are read (crates/cli/tests/s35_fix35_cli.rs checks the values): these two rows are read
    // and are too few for the model, the refusal says so, not a decimal-comma cause.
    for stream in [None, Some("on")] {
        let mut args = vec![
            "identify",
            "--data",
            s(&quoted),
            "--ts",
            "1",
            "--structure",
            "arx",
        ];
        args.extend(["--method", "ls"]);
        if let Some(on) = stream {
            args.extend(["--stream", on]);
        }
        let o = ipa_sysid(&args);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
        assert!(
            e.contains("2 samples") && !e.contains("decimal commas"),
            "{args:?}: {e}"
        );
    }
    for (file, what) in [(&ragged, "ragged row")] {
        for stream in [None, Some("on")] {
            let mut args = vec![
                "identify",
                "--data",
                s(file),
                "--ts",
                "1",
                "--structure",
                "arx",
                "--method",
                "ls",
            ];
            if let Some(on) = stream {
                args.extend(["--stream", on]);
            }
            let o = ipa_sysid(&args);
            let e = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {e}");
            assert!(
                e.contains(what)
                    && e.contains("decimal commas")
                    && e.contains("';' as the separator"),
                "{args:?}: {e}"
            );
        }
    }
    // A plain non-number in a comma-separated file gets no such hint.
    let word = csv(dir.path(), "word.csv", &["u,y", "abc,1", "1,2"]);
    let e = stderr(&ipa_sysid(&["identify", "--data", s(&word), "--ts", "1"]));
    assert!(
        e.contains("is not a number") && !e.contains("decimal commas"),
        "{e}"
    );
}

// L-5: a time column of date-times: the error names --ts, and --ts works on the same file, with a note
// that the stamps were not checked (audit s21 M-B6).
#[test]
fn a_date_time_column_names_ts_as_the_way_out() {
    let dir = tempfile::tempdir().unwrap();
    let mut lines = vec!["t,u,y".to_string()];
    let mut y = 0.0f64;
    let mut u_prev = 0.0;
    for k in 0..200 {
        let u = if (k / 10) % 2 == 0 { 1.0 } else { -1.0 };
        y = 0.8 * y + 0.3 * u_prev + 0.001 * ((k * 7919 % 13) as f64 - 6.0);
        lines.push(format!(
            "2026-01-01 00:{:02}:{:02},{u},{y}",
            k * 9 / 60,
            k * 9 % 60
        ));
        u_prev = u;
    }
    let refs: Vec<&str> = lines.iter().map(String::as_str).collect();
    let f = csv(dir.path(), "dt.csv", &refs);
    let o = ipa_sysid(&["identify", "--data", s(&f), "--structure", "arx"]);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("'2026-01-01 00:00:00'") && e.contains("--ts SECONDS"),
        "{e}"
    );
    let o = ipa_sysid(&[
        "identify",
        "--data",
        s(&f),
        "--structure",
        "arx",
        "--ts",
        "9",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Audit s21 M-B6: the stamps are not read with --ts, and the output says so (here --ts 9 is right;
    // a --ts 900 would pass the same way).
    let said = format!("{}{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    assert!(
        said.contains("the time column t holds dates and times ('2026-01-01 00:00:00')")
            && said.contains("not checked"),
        "{said}"
    );
}

// L-3: the --samples refusal in the form of every other refusal of docs/reliability.md's table.
#[test]
fn samples_out_of_range_is_an_invalid_setting() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.csv");
    let o = ipa_sysid(&["simulate", "--samples", "10000000000", "--out", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("invalid setting --samples = 10000000000: expected 1..=50000000"),
        "{}",
        stderr(&o)
    );
}
