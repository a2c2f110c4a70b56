//! `ipa-sysid tune` and `control --controller` end to end: the controller file, the JSON, the tuned
//! controller's commands recomputed here from the trace by an independent implementation of the
//! equations of docs/control.md, and errors that name the file or flag.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::Path;

mod common;
use common::{run as ipa_sysid, stderr};

/// y(k) = y(k-1) + f(u(k-1)), deadzone b_l = -20, b_r = 20, slopes 0.005 mm/count per sample.
const MODEL: &str = r#"{
  "format": "ipa-sysid-model",
  "version": 2,
  "model": {
    "kind": "hammerstein", "ts": 0.01, "na": 1, "nb": 1, "nk": 1,
    "a": [-1.0], "b": [1.0], "offset": null,
    "deadzone": {"b_l": -20.0, "b_r": 20.0, "m_l": 0.005, "m_r": 0.005},
    "noise_model": "output-error"
  }
}
"#;

fn tuned(dir: &Path) -> (std::path::PathBuf, serde_json::Value) {
    let model = dir.join("m.json");
    std::fs::write(&model, MODEL).unwrap();
    let t = common::tune(dir, &model, &["--max-evaluations", "40"]);
    assert!(t.text.contains("paper PI 14/1"), "{}", t.text);
    (t.controller, t.report)
}

#[test]
fn tune_writes_a_controller_file_and_a_report_with_the_paper_pi_beside_it() {
    let dir = tempfile::tempdir().unwrap();
    let (out, doc) = tuned(dir.path());
    let file: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(file["format"], "ipa-sysid-controller");
    assert_eq!(file["controller"]["hold_band_mm"], 0.02);
    // 5 variants × 8 steps (sizes 10, 30, 70, 150 mm up and down).
    assert_eq!(
        doc["on_model"]["tuned"]["runs"].as_array().unwrap().len(),
        40
    );
    assert_eq!(
        doc["on_model"]["paper_pi"]["runs"]
            .as_array()
            .unwrap()
            .len(),
        40
    );
    assert!(doc["evaluations"].as_u64().unwrap() <= 40);
    assert!(doc["warnings"].is_array());
    assert!(doc["margins"]["phase_margin_deg"].is_number());
    // Verified on the model only: said.
    assert!(doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .any(|w| w.as_str().unwrap().contains("verified on the model only")));
}

/// The controller of docs/control.md, written again here: e = r - y, filtered derivative of -y, hold
/// band, nudge mode, integral reset on a sign change, clamping, shift deadzone inverse scaled in the
/// fine band, then Kd D added and clamped.
fn reference_commands(c: &serde_json::Value, r: &[f64], y: &[f64]) -> Vec<f64> {
    let g = |k: &str| c[k].as_f64().unwrap();
    let (ts, kp, ki, kd, tf, umax, hold, fine) = (
        g("ts_s"),
        g("kp"),
        g("ki"),
        g("kd"),
        g("derivative_filter_s"),
        g("u_max"),
        g("hold_band_mm"),
        g("fine_band_mm"),
    );
    let reset = c["reset_on_crossing"].as_bool().unwrap();
    let dz = &c["compensator"]["deadzone"];
    let (bl, br) = (dz["b_l"].as_f64().unwrap(), dz["b_r"].as_f64().unwrap());
    let alpha = tf / (tf + ts);
    let (mut i, mut d, mut e_prev) = (0.0f64, 0.0f64, 0.0f64);
    // Nudge mode: (band, ρ, β, N_r, γ), the samples at rest, the learnt breakaway commands (left,
    // right) and the nudge under way (side ±1, y_0, e_0, u_n, moving, its ramp rate, ramp-and-cut).
    // Ramp-and-cut (e_c, ρ_min): rate per mm a (left, right) = ρ / e_c at first, learnt at the rest
    // after a ramp-and-cut's end from the move d = side (y − y_0): d > |e_0| + e_h → a × max(1/4,
    // |e_0| / d), d < |e_0| / 2 → a × 5/4 (not with a creep limit), then a kept within
    // [ρ_min / e_c, ρ / e_h]. Creep (e_v > 0, session 18): a ramp-and-cut nudge with e e_0 > 0 ends
    // when the sample's move towards r exceeds e_v, holds u_n while it is in (0, e_v] (the first
    // such sample learns u_b) and ramps on otherwise (y_0 = y before the first motion). Slip brake
    // (a_p, T_p; session 19): a nudge that ends at a sample whose move towards r exceeds e_v (e_h
    // without a creep limit) commands −side a_p u_max from that sample while the piston moves
    // towards r, at most T_p samples. Relearning (session 20): the creep's end at a first motion
    // learns u_b = u_n, a held nudge that has moved and rests more than N_r samples ramps on as one
    // that has not (y_0 = y), and the slip brake goes on only while the move exceeds e_v (e_h).
    let nudge = &c["nudge"];
    let n = nudge.is_object().then(|| {
        let h = |k: &str| nudge[k].as_f64().unwrap();
        (
            h("band_mm"),
            h("ramp_counts_s"),
            h("start_fraction"),
            h("rest_samples"),
            h("cut_fraction"),
        )
    });
    let mut still = 0.0f64;
    let mut ub = [bl.abs(), br.abs()];
    let mut under_way: Option<(f64, f64, f64, f64, bool, f64, bool)> = None;
    let (e_c, rho_min, e_v) = (
        nudge["cut_band_mm"].as_f64().unwrap_or(0.0),
        nudge["min_ramp_counts_s"].as_f64().unwrap_or(0.0),
        nudge["creep_step_mm"].as_f64().unwrap_or(0.0),
    );
    let (a_p, t_p) = (
        nudge["slip_brake_fraction"].as_f64().unwrap_or(0.0),
        nudge["slip_brake_samples"].as_f64().unwrap_or(0.0),
    );
    let slip = if e_v > 0.0 { e_v } else { hold };
    let relearn = nudge["relearn"].as_bool().unwrap_or(false);
    let slipping = if relearn { slip } else { 0.0 };
    // The slip brake under way: the nudge's side and the samples given.
    let mut pulse: Option<(f64, f64)> = None;
    // The command at a nudge's end at sample k (side ±1): 0, or the slip brake's first sample.
    let end = |side: f64, k: usize, pulse: &mut Option<(f64, f64)>| -> f64 {
        let step = if k == 0 {
            0.0
        } else {
            side * (y[k] - y[k - 1])
        };
        if a_p > 0.0 && t_p > 0.0 && step > slip {
            *pulse = Some((side, 1.0));
            -side * a_p * umax
        } else {
            0.0
        }
    };
    let rho_max = n.map_or(0.0, |n| n.1);
    let mut a = if e_c > 0.0 {
        [rho_max / e_c; 2]
    } else {
        [0.0; 2]
    };
    // The last ramp-and-cut that ended (side, y_0, e_0), until the next nudge starts.
    let mut ended: Option<(f64, f64, f64)> = None;
    let mut out = Vec::new();
    for k in 0..r.len() {
        let e = r[k] - y[k];
        let dy = if k == 0 { 0.0 } else { (y[k] - y[k - 1]) / ts };
        d = alpha * d - (1.0 - alpha) * dy;
        still = if k > 0 && y[k] == y[k - 1] {
            still + 1.0
        } else {
            0.0
        };
        if let Some((side, given)) = pulse {
            if given < t_p && side * (y[k] - y[k - 1]) > slipping {
                pulse = Some((side, given + 1.0));
                e_prev = e;
                out.push(-side * a_p * umax);
                continue;
            }
            pulse = None;
        }
        if e.abs() <= hold {
            e_prev = e;
            let mut u = 0.0;
            if let Some((side, y0, e0, _, _, _, cuts)) = under_way.take() {
                if cuts {
                    ended = Some((side, y0, e0));
                }
                u = end(side, k, &mut pulse);
            }
            out.push(u);
            continue;
        }
        if let Some((band, rho, beta, rest, gamma)) = n.filter(|n| e.abs() <= n.0) {
            i = 0.0;
            e_prev = e;
            let idx = |side: f64| usize::from(side > 0.0);
            let u = match under_way {
                Some((side, y0, e0, un, moving, rate, true)) if e_v > 0.0 && e * e0 > 0.0 => {
                    let step = side * (y[k] - y[k - 1]);
                    if step > e_v {
                        if relearn && !moving {
                            ub[idx(side)] = un;
                        }
                        under_way = None;
                        ended = Some((side, y0, e0));
                        end(side, k, &mut pulse)
                    } else if step > 0.0 {
                        if !moving {
                            ub[idx(side)] = un;
                        }
                        under_way = Some((side, y0, e0, un, true, rate, true));
                        side * un
                    } else {
                        let un = (un + rate * ts).min(umax);
                        let y0 = if moving { y0 } else { y[k] };
                        under_way = Some((side, y0, e0, un, moving, rate, true));
                        side * un
                    }
                }
                Some((side, y0, e0, un, moving, rate, cuts)) => {
                    let towards = side * (y[k] - y0) > 0.0;
                    if (y[k] != y0 && (y[k] - y0).abs() >= gamma * e0.abs())
                        || e * e0 <= 0.0
                        || (cuts && !moving && towards)
                    {
                        if cuts && !moving && towards {
                            ub[idx(side)] = un;
                        }
                        under_way = None;
                        if cuts {
                            ended = Some((side, y0, e0));
                        }
                        end(side, k, &mut pulse)
                    } else if moving && relearn && still > rest {
                        let un = (un + rate * ts).min(umax);
                        under_way = Some((side, y[k], e0, un, false, rate, cuts));
                        side * un
                    } else if moving {
                        side * un
                    } else if towards {
                        ub[idx(side)] = un;
                        under_way = Some((side, y0, e0, un, true, rate, cuts));
                        side * un
                    } else {
                        // Stuck, or a count away from r: ramp on from here.
                        let un = (un + rate * ts).min(umax);
                        under_way = Some((side, y[k], e0, un, false, rate, cuts));
                        side * un
                    }
                }
                None if still < rest => 0.0,
                None => {
                    if let Some((side, y0, e0)) = ended.take() {
                        let moved = side * (y[k] - y0);
                        let j = idx(side);
                        if moved > e0.abs() + hold {
                            a[j] *= (e0.abs() / moved).max(0.25);
                        } else if moved < 0.5 * e0.abs() && e_v == 0.0 {
                            a[j] *= 1.25;
                        }
                        a[j] = a[j].clamp(rho_min / e_c, rho_max / hold.max(1e-3));
                    }
                    let side = if e > 0.0 { 1.0 } else { -1.0 };
                    let un = (beta * ub[idx(side)]).min(umax);
                    let cuts = e.abs() <= e_c;
                    let rate = if cuts {
                        (a[idx(side)] * e.abs()).clamp(rho_min, rho)
                    } else {
                        rho
                    };
                    under_way = Some((side, y[k], e, un, false, rate, cuts));
                    side * un
                }
            };
            let _ = band;
            out.push(u);
            continue;
        }
        under_way = None;
        ended = None;
        if reset && e * e_prev < 0.0 {
            i = 0.0;
        }
        e_prev = e;
        let v = kp * e + i + ki * ts * e;
        let u_pi = if v.abs() > umax && e * v > 0.0 {
            (kp * e + i).clamp(-umax, umax)
        } else {
            i += ki * ts * e;
            v.clamp(-umax, umax)
        };
        let shift = if u_pi > 0.0 {
            br
        } else if u_pi < 0.0 {
            bl
        } else {
            0.0
        };
        // The inverse u_c = sat(u_pi + shift), and in the fine band u_pi + w (u_c − u_pi).
        let w = if e.abs() < fine { e.abs() / fine } else { 1.0 };
        let u_c = (u_pi + shift).clamp(-umax, umax);
        let comp = if w < 1.0 {
            u_pi + w * (u_c - u_pi)
        } else {
            u_c
        };
        out.push((comp + kd * d).clamp(-umax, umax));
    }
    out
}

#[test]
fn control_runs_the_tuned_controller_as_documented() {
    let dir = tempfile::tempdir().unwrap();
    let (out, _) = tuned(dir.path());
    let model = dir.path().join("m.json");
    let trace = dir.path().join("tr.csv");
    let json = dir.path().join("c_out.json");
    let o = ipa_sysid(&[
        "control",
        "--plant",
        &format!("model:{}", model.display()),
        "--controller",
        out.to_str().unwrap(),
        "--profile",
        "staircase:40,38,90@2",
        "--out",
        trace.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("tuned PID"));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(doc["settings"]["controller"]["file"], out.to_str().unwrap());
    let text = std::fs::read_to_string(&trace).unwrap();
    let (mut r, mut u, mut y) = (vec![], vec![], vec![]);
    for line in text.lines().skip(1) {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        r.push(v[1]);
        u.push(v[2]);
        y.push(v[3]);
    }
    let c: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    let want = reference_commands(&c["controller"], &r, &y);
    for k in 0..u.len() {
        assert!(
            (u[k] - want[k]).abs() <= 1e-9 * (1.0 + want[k].abs()),
            "sample {k}: {} vs {}",
            u[k],
            want[k]
        );
    }
    // The hold band is used: some samples command exactly 0 after the first step has settled.
    assert!(u.iter().filter(|v| **v == 0.0).count() > 10);
}

#[test]
fn bad_inputs_name_the_file_or_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("c.json");
    let o = ipa_sysid(&[
        "tune",
        "--model",
        "no_such_model.json",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no_such_model.json"), "{}", stderr(&o));
    assert!(!out.exists());

    let model = dir.path().join("m.json");
    std::fs::write(&model, MODEL).unwrap();
    let o = ipa_sysid(&[
        "tune",
        "--model",
        model.to_str().unwrap(),
        "--spec",
        "overshoot=fast",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--spec"), "{}", stderr(&o));

    // A twin held at an end stop by its external force: named, with the file and the force (it was
    // the identification's "input is never positive ... use --model arx", audit s13 L15).
    let cfg = ipa_sysid(&["plant-config"]);
    assert!(cfg.status.success());
    let text = String::from_utf8_lossy(&cfg.stdout)
        .replace("external_force_n = 0.0", "external_force_n = 5000.0");
    assert!(text.contains("external_force_n = 5000.0"));
    let pinned = dir.path().join("pinned.toml");
    std::fs::write(&pinned, text).unwrap();
    let o = ipa_sysid(&[
        "tune",
        "--plant-config",
        pinned.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains("pinned.toml: the twin's piston sits at its extended end stop (200 mm)")
            && e.contains("external_force_n = 5000 N"),
        "{e}"
    );
    assert!(!out.exists());

    // A model of Ts = 1 s with the default specification: its 3 s runs are 3 samples; the error says
    // that run=3 is the default and what to give (audit s14 L-b: it read as if --spec had been given).
    let slow = dir.path().join("slow.json");
    std::fs::write(&slow, MODEL.replace("\"ts\": 0.01", "\"ts\": 1.0")).unwrap();
    let o = ipa_sysid(&[
        "tune",
        "--model",
        slow.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains("run=3 (the default, made for Ts = 0.01 s)") && e.contains("run=20 or longer"),
        "{e}"
    );

    // The same model with the advised run=20 is accepted (the run is bounded in samples, 6000, not
    // in seconds: audit s16 M1 advised run=180 for Ts = 9 s and then refused it), a run of 6001
    // samples is not, and a request of more than 1e8 simulated samples is refused before any work:
    // (10000 + 20) evaluations × 200 variants × 8 steps × 300 samples = 4.8e9 (audit s16 M11).
    let o = ipa_sysid(&[
        "tune",
        "--model",
        slow.to_str().unwrap(),
        "--spec",
        "run=6001",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("runs of at most 6000 samples: 6000 s at the model's Ts = 1 s"),
        "{}",
        stderr(&o)
    );
    // Huge and tiny values come back as typed, not digit by digit (audit s28 L-3: run=1e308 printed
    // 309 digits): the error names each key with its value in exponent form.
    for (spec, words) in [
        ("run=1e308", "run=1e308"),
        ("high=1e308", "high=1e308"),
        ("low=-1e308", "low=-1e308"),
        ("settling=1e300", "settling=1e300"),
    ] {
        let o = ipa_sysid(&[
            "tune",
            "--model",
            model.to_str().unwrap(),
            "--spec",
            spec,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2), "{spec}");
        let e = stderr(&o);
        assert!(
            e.contains(words) && !e.contains("00000000000"),
            "{spec}: {e}"
        );
    }
    let o = ipa_sysid(&[
        "tune",
        "--model",
        model.to_str().unwrap(),
        "--max-evaluations",
        "10000",
        "--variants",
        "200",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains("--max-evaluations = 10000")
            && e.contains("at most 1e8 simulated samples")
            && e.contains("(10000 evaluations + 53 after the search) × 200 variants"),
        "{e}"
    );
    assert!(!out.exists());
    let o = ipa_sysid(&[
        "tune",
        "--model",
        slow.to_str().unwrap(),
        "--spec",
        "run=20",
        "--max-evaluations",
        "8",
        "--variants",
        "1",
        "--physics-variants",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(
        !stderr(&o).contains("invalid setting --spec"),
        "{}",
        stderr(&o)
    );
    let _ = std::fs::remove_file(&out);

    // A one-sided input's model (identify fixes the unexcited branch at m_l = b_l = 0): refused as one,
    // not as "positive slopes" the user could not give (audit s16 M1).
    let one_sided = dir.path().join("one_sided.json");
    std::fs::write(
        &one_sided,
        MODEL.replace(
            "\"b_l\": -20.0, \"b_r\": 20.0, \"m_l\": 0.005",
            "\"b_l\": 0.0, \"b_r\": 20.0, \"m_l\": 0.0",
        ),
    )
    .unwrap();
    let o = ipa_sysid(&[
        "tune",
        "--model",
        one_sided.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("a one-sided input") && stderr(&o).contains("driven both ways"),
        "{}",
        stderr(&o)
    );

    // The search's sizes: checked once, by the library, for the command line and Python alike.
    for (flag, value, said) in [
        (
            "--max-evaluations",
            "3",
            "invalid setting --max-evaluations = 3: a whole number in 8..=10000",
        ),
        (
            "--variants",
            "0",
            "invalid setting --variants = 0: a whole number in 1..=200",
        ),
        (
            "--physics-variants",
            "201",
            "invalid setting --physics-variants = 201: a whole number in 0..=200",
        ),
    ] {
        let o = ipa_sysid(&[
            "tune",
            "--model",
            model.to_str().unwrap(),
            flag,
            value,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(2));
        assert!(stderr(&o).contains(said), "{}", stderr(&o));
        assert!(!out.exists());
    }

    // --out over the model is refused and the model is untouched.
    let o = ipa_sysid(&[
        "tune",
        "--model",
        model.to_str().unwrap(),
        "--out",
        model.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert_eq!(std::fs::read_to_string(&model).unwrap(), MODEL);

    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        "{\n  \"format\": \"ipa-sysid-controller\",\n  oops\n}\n",
    )
    .unwrap();
    let o = ipa_sysid(&[
        "control",
        "--plant",
        "paper",
        "--controller",
        bad.to_str().unwrap(),
        "--setpoint",
        "10",
    ]);
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(e.contains("bad.json:3:"), "{e}");
}

/// `tune --model` of MODEL with A(q) = 1 + a1 q⁻¹ (one pole at z = −a1): its JSON document.
fn tune_first_order(dir: &Path, a1: f64) -> serde_json::Value {
    let model = dir.join(format!("m{a1}.json"));
    std::fs::write(&model, MODEL.replace("[-1.0]", &format!("[{a1}]"))).unwrap();
    let common::Tuned {
        report: doc, text, ..
    } = common::tune(dir, &model, &["--max-evaluations", "10", "--variants", "1"]);
    let unstable = doc["margins"]["open_loop_unstable"].as_bool().unwrap();
    assert_eq!(text.contains("UNSTABLE open loop"), unstable, "{text}");
    doc
}

// Audit s11 T1: tuned on a model with a pole at z = 1.02 (a1 = −1.02), the report carries identify's
// unstable-model warning with that modulus, and says that the margins of an unstable open loop do not
// show closed-loop stability; with the pole at 0.9 neither is said.
#[test]
fn tuning_on_an_unstable_model_says_so_and_qualifies_the_margins() {
    let dir = tempfile::tempdir().unwrap();
    let doc = tune_first_order(dir.path(), -1.02);
    let w = doc["warnings"].to_string();
    assert!(
        w.contains("the model tuned on: unstable model: a pole has modulus 1.020000"),
        "{w}"
    );
    assert!(
        w.contains("do not show that the closed loop is stable"),
        "{w}"
    );
    assert_eq!(doc["margins"]["open_loop_unstable"], true);
    let doc = tune_first_order(dir.path(), -0.9);
    let w = doc["warnings"].to_string();
    assert!(
        !w.contains("the model tuned on") && !w.contains("do not show"),
        "{w}"
    );
    assert_eq!(doc["margins"]["open_loop_unstable"], false);
}

// Audit s11 A4: `tune --out -` writes the controller file alone on standard output (it parses as one
// JSON document), the table goes to standard error; `--out - --json -` is refused naming --json.
#[test]
fn a_controller_to_standard_output_is_alone_there() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("m.json");
    std::fs::write(&model, MODEL).unwrap();
    let m = model.to_str().unwrap();
    let args = [
        "tune",
        "--model",
        m,
        "--max-evaluations",
        "8",
        "--variants",
        "1",
    ];
    let o = ipa_sysid(&[&args[..], &["--out", "-"]].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let c: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(c["format"], "ipa-sysid-controller");
    assert!(stderr(&o).contains("paper PI 14/1"));
    let o = ipa_sysid(&[&args[..], &["--out", "-", "--json", "-"]].concat());
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("--json"), "{}", stderr(&o));
}

// Audit s12: a Hammerstein model with another input block is not called "ARX" when tune refuses it.
#[test]
fn a_model_without_a_deadzone_is_refused_naming_its_input_block() {
    let dir = tempfile::tempdir().unwrap();
    let rec = dir.path().join("r.csv");
    let model = dir.path().join("p.json");
    let o = ipa_sysid(&[
        "simulate",
        "--plant",
        "paper",
        "--samples",
        "1500",
        "--out",
        rec.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = ipa_sysid(&[
        "identify",
        "--data",
        rec.to_str().unwrap(),
        "--nonlinearity",
        "polynomial",
        "--degree",
        "3",
        "--method",
        "ls",
        "--save-model",
        model.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("c.json");
    let o = ipa_sysid(&[
        "tune",
        "--model",
        model.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(
        e.contains("this model's input block is a polynomial") && !e.contains("is ARX"),
        "{e}"
    );
    assert!(!out.exists());
}

/// Audit s28 L-6: a controller tuned on a twin says so when it runs on another plant — the built-in
/// physics IPA, another twin, the paper's model, a model file — and not on its own twin (by path, or
/// a copy of the same bytes in another folder).
#[test]
fn a_controller_tuned_on_a_twin_says_so_on_another_plant() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let p = |name: &str| d.join(name).display().to_string();
    let config = ipa_sysid(&["plant-config"]);
    assert!(config.status.success(), "{}", stderr(&config));
    std::fs::write(d.join("twin.toml"), &config.stdout).unwrap();
    std::fs::create_dir(d.join("copy")).unwrap();
    std::fs::write(d.join("copy").join("same.toml"), &config.stdout).unwrap();
    // Another twin: a heavier load.
    let other = String::from_utf8_lossy(&config.stdout)
        .replace("moving_mass_kg = 0.6", "moving_mass_kg = 0.9");
    assert_ne!(
        other.as_bytes(),
        &config.stdout[..],
        "the mass line was found"
    );
    std::fs::write(d.join("other.toml"), other).unwrap();
    let tune = ipa_sysid(&[
        "tune",
        "--plant-config",
        &p("twin.toml"),
        "--out",
        &p("c.json"),
        "--variants",
        "1",
        "--max-evaluations",
        "8",
        "--physics-variants",
        "0",
    ]);
    assert!(tune.status.success(), "{}", stderr(&tune));
    let words = "the controller file was tuned on the twin";
    let control = |plant: &[String]| {
        let c = p("c.json");
        let mut args = vec![
            "control",
            "--controller",
            &c,
            "--setpoint",
            "60",
            "--duration",
            "0.3",
        ];
        args.push("--plant");
        args.extend(plant.iter().map(String::as_str));
        let o = ipa_sysid(&args);
        assert!(o.status.success(), "{plant:?}: {}", stderr(&o));
        String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o)
    };
    let owned = |a: &[&str]| a.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    let other = p("other.toml");
    for (plant, not_on) in [
        (
            owned(&["ipa"]),
            "not on the built-in physics IPA".to_string(),
        ),
        (
            owned(&["ipa", "--plant-config", &other]),
            format!("not on the physics plant of {other}"),
        ),
        (owned(&["paper"]), "not on the paper's model".to_string()),
    ] {
        let text = control(&plant);
        assert!(
            text.contains(words) && text.contains(&not_on),
            "{plant:?}: {text}"
        );
    }
    for same in ["twin.toml", "copy/same.toml"] {
        let text = control(&owned(&["ipa", "--plant-config", &p(same)]));
        assert!(!text.contains(words), "{same}: {text}");
    }
}
