//! One stability verdict (brief s23 stab): the same hand-built model files through every command that
//! judges a model's poles — `simulate`, `validate`, `response`, `tune`, `control` — and records made
//! by the same models through `identify`, must give the same verdict. The expected verdict of each
//! case is named from where its poles were put (0.5 settles; 1 − 10⁻¹², 1, 1 + 10⁻¹² are an
//! integrator, rounding aside; 1 + 10⁻³ is unstable; −1 and e^{±iπ/3} are on the unit circle away from
//! 1; coefficients too large for f64 give poles that are not numbers: unstable), never from the
//! program's output; each command's words for that verdict are its documented ones.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::{Path, PathBuf};

mod common;
use common::{run as ipa_sysid, s, stderr};

/// The verdicts of `sysid_core::Stability`, named here from the poles placed.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Verdict {
    Settles,
    Integrator,
    OnCircle,
    Unstable,
}

impl Verdict {
    /// The name in JSON (`stability`).
    fn name(self) -> &'static str {
        match self {
            Verdict::Settles => "settles",
            Verdict::Integrator => "integrator",
            Verdict::OnCircle => "on_circle",
            Verdict::Unstable => "unstable",
        }
    }
}

/// A case: its name, the difference-equation coefficients α_i of y(k) = Σ α_i y(k−i) + u(k−1) + …
/// (A(z) = z^na − α_1 z^(na−1) − … has the placed poles), and the verdict those poles call for.
struct Case {
    what: &'static str,
    alpha: Vec<f64>,
    verdict: Verdict,
}

fn cases() -> Vec<Case> {
    // e^{±iπ/3}: A(z) = z² − 2 cos(π/3) z + 1 = z² − z + 1, so y(k) = y(k−1) − y(k−2) + ….
    let c = 2.0 * (std::f64::consts::FRAC_PI_3).cos();
    vec![
        Case {
            what: "0.5",
            alpha: vec![0.5],
            verdict: Verdict::Settles,
        },
        Case {
            what: "0.9995 (an IPA position model's slow pole)",
            alpha: vec![0.9995],
            verdict: Verdict::Settles,
        },
        Case {
            what: "1 - 1e-12",
            alpha: vec![1.0 - 1e-12],
            verdict: Verdict::Integrator,
        },
        Case {
            what: "1",
            alpha: vec![1.0],
            verdict: Verdict::Integrator,
        },
        Case {
            what: "1 + 1e-12",
            alpha: vec![1.0 + 1e-12],
            verdict: Verdict::Integrator,
        },
        Case {
            what: "1 + 1e-3",
            alpha: vec![1.0 + 1e-3],
            verdict: Verdict::Unstable,
        },
        Case {
            what: "-1",
            alpha: vec![-1.0],
            verdict: Verdict::OnCircle,
        },
        Case {
            what: "e^{±iπ/3}",
            alpha: vec![c, -1.0],
            verdict: Verdict::OnCircle,
        },
    ]
}

/// A version-2 Hammerstein model file (deadzone ±20 counts, slopes 0.005, Ts = 0.01 s, nk = 1, b =
/// [1]) whose A(q) = 1 − Σ α_i q⁻ⁱ: the model file's `a` holds −α.
fn model_file(dir: &Path, name: &str, a: &[f64]) -> PathBuf {
    let path = dir.join(name);
    let model = serde_json::json!({
        "kind": "hammerstein", "ts": 0.01, "na": a.len(), "nb": 1, "nk": 1,
        "a": a, "b": [1.0], "offset": null,
        "deadzone": {"b_l": -20.0, "b_r": 20.0, "m_l": 0.005, "m_r": 0.005},
        "noise_model": "output-error"
    });
    let doc = serde_json::json!({"format": "ipa-sysid-model", "version": 2, "model": model});
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

fn strings(v: &serde_json::Value) -> Vec<String> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_str().unwrap().to_string())
        .collect()
}

/// `simulate --plant model:FILE`'s words on stderr for each verdict (`simulate`'s `warning:` lines).
fn simulate_says(dir: &Path, model: &Path) -> Verdict {
    let o = ipa_sysid(&[
        "simulate",
        "--plant",
        &format!("model:{}", s(model)),
        "--input",
        "step:10@5",
        "--samples",
        "12",
        "--out",
        s(&dir.join("sim.csv")),
        "--force",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let e = stderr(&o);
    let said = [
        (e.contains("unstable model"), Verdict::Unstable),
        (
            e.contains("a pole at 1 (an integrator)"),
            Verdict::Integrator,
        ),
        (
            e.contains("a pole on the unit circle away from 1"),
            Verdict::OnCircle,
        ),
    ];
    one_verdict(&said, &e)
}

/// The one verdict among `said` that holds (`Settles` when none does); two at once fail the test.
fn one_verdict(said: &[(bool, Verdict)], text: &str) -> Verdict {
    let held: Vec<Verdict> = said.iter().filter(|x| x.0).map(|x| x.1).collect();
    assert!(held.len() <= 1, "two verdicts at once {held:?}: {text}");
    held.first().copied().unwrap_or(Verdict::Settles)
}

/// `identify`'s (and `validate`'s) warning for each verdict (`sysid::Warning`'s words).
fn warning_verdict(w: &[String]) -> Verdict {
    let any = |p: &str| w.iter().any(|w| w.contains(p));
    one_verdict(
        &[
            (any("unstable model: a pole has modulus"), Verdict::Unstable),
            (any("a pole at z = 1 (modulus"), Verdict::Integrator),
            (any("on the unit circle away from z = 1"), Verdict::OnCircle),
        ],
        &format!("{w:?}"),
    )
}

/// `validate --model FILE --data REC --json -`: its `stability`, `stable` and warnings.
fn validate_says(dir: &Path, model: &Path, record: &Path) -> Verdict {
    let o = ipa_sysid(&[
        "validate",
        "--model",
        s(model),
        "--data",
        s(record),
        "--json",
        "-",
    ]);
    let _ = dir;
    let j: serde_json::Value = serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|_| panic!("validate: no JSON; {}", stderr(&o)));
    let v = warning_verdict(&strings(&j["warnings"]));
    assert_eq!(j["stability"], v.name(), "validate: {j}");
    assert_eq!(j["stable"], v == Verdict::Settles, "validate: {j}");
    // The summary line (on stderr beside `--json -`) ends with the same verdict in words: it said
    // "UNSTABLE" for an integrator while the JSON said "integrator" (audit s27 L-10).
    let text = stderr(&o);
    let summary = text
        .lines()
        .find(|l| l.contains(" samples): fit "))
        .unwrap_or_else(|| panic!("validate: no summary line; {text}"));
    let said = summary.rsplit("; ").next().unwrap_or_default();
    let word = match said {
        "stable" => Verdict::Settles,
        "an integrator" => Verdict::Integrator,
        "on the stability boundary" => Verdict::OnCircle,
        "UNSTABLE" => Verdict::Unstable,
        other => panic!("validate's summary ends with {other:?}: {summary}"),
    };
    assert_eq!(word, v, "validate's summary line: {summary}");
    v
}

/// `response --model FILE --json -`: the DC gain's note for each verdict.
fn response_says(model: &Path) -> Verdict {
    let o = ipa_sysid(&["response", "--model", s(model), "--json", "-"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let v = match j["dc_gain_note"].as_str() {
        None => Verdict::Settles,
        Some("infinite (integrator)") => Verdict::Integrator,
        Some("not defined (unstable)") => Verdict::Unstable,
        Some("not defined (a pole on the stability boundary)") => Verdict::OnCircle,
        Some(other) => panic!("response: {other}"),
    };
    assert_eq!(
        warning_verdict(&strings(&j["warnings"])),
        v,
        "response's warning and its DC gain disagree: {j}"
    );
    v
}

/// `tune --model FILE`: its `the model tuned on:` warning and `open_loop_unstable`.
fn tune_says(dir: &Path, model: &Path) -> Verdict {
    let t = common::tune(dir, model, &["--max-evaluations", "8", "--variants", "1"]);
    let tuned_on: Vec<String> = strings(&t.report["warnings"])
        .into_iter()
        .filter_map(|w| w.strip_prefix("the model tuned on: ").map(String::from))
        .collect();
    let v = warning_verdict(&tuned_on);
    assert_eq!(
        t.report["margins"]["open_loop_unstable"],
        v == Verdict::Unstable,
        "tune: {}",
        t.report
    );
    v
}

/// `control --plant model:FILE`'s plant check, in its text and in its JSON `warnings` (which must
/// agree): an on-circle plant model (an undamped oscillation) and an unstable one are warned of; an
/// integrator is a position actuator's normal dynamics and is not, so it reads as `Settles` here.
fn control_says(dir: &Path, model: &Path) -> Verdict {
    let json = dir.join("control.json");
    let o = ipa_sysid(&[
        "control",
        "--plant",
        &format!("model:{}", s(model)),
        "--setpoint",
        "3",
        "--duration",
        "0.5",
        "--out",
        s(&dir.join("c.csv")),
        "--json",
        s(&json),
        "--force",
    ]);
    assert!(o.status.success(), "control: {}", stderr(&o));
    let said = |text: &str| {
        one_verdict(
            &[
                (
                    text.contains("the plant model is unstable"),
                    Verdict::Unstable,
                ),
                (
                    text.contains("the plant model has a pole on the unit circle away from z = 1"),
                    Verdict::OnCircle,
                ),
            ],
            text,
        )
    };
    let text = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let in_json = said(&strings(&j["warnings"]).join("\n"));
    assert_eq!(said(&text), in_json, "control: text {text}\nJSON {j}");
    in_json
}

/// `identify` on the noise-free record y(k) = Σ α_i y(k−i) + u(k−1) of a random input: least squares
/// recovers α to rounding, far inside the band ε = 10⁻⁵, so its verdict is the placed poles'. Checks
/// the JSON's `stability` and `stable`, its warning and the text's "Poles: … →" line agree.
fn identify_says(dir: &Path, alpha: &[f64]) -> Verdict {
    let mut g = common::lcg(7);
    let (u, y) = common::arx_signals(200, alpha, &[1.0], |_| g.unit() - 0.5);
    let rec = dir.join("id.csv");
    common::write_csv(&rec, "u,y", None, &[&u, &y]);
    let na = alpha.len().to_string();
    let json = dir.join("id.json");
    let mut args = common::identify_arx(&rec, &na, "1", "ls");
    args.extend(["--ts", "0.01", "--json", s(&json), "--force"]);
    let o = ipa_sysid(&args);
    let j: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(&json).unwrap_or_else(|_| panic!("identify: {}", stderr(&o))),
    )
    .unwrap();
    let v = warning_verdict(&strings(&j["warnings"]));
    assert_eq!(j["stability"], v.name(), "identify: {j}");
    assert_eq!(j["stable"], v == Verdict::Settles, "identify: {j}");
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    let poles = text
        .lines()
        .find(|l| l.starts_with("Poles:"))
        .unwrap_or_else(|| panic!("{text}"))
        .to_string();
    let line_says = one_verdict(
        &[
            (poles.contains("UNSTABLE"), Verdict::Unstable),
            (poles.contains("an integrator"), Verdict::Integrator),
            (poles.contains("away from z = 1"), Verdict::OnCircle),
        ],
        &poles,
    );
    assert_eq!(line_says, v, "{poles}");
    if v == Verdict::Settles {
        assert!(poles.contains("→ stable"), "{poles}");
    }
    v
}

#[test]
fn every_command_gives_the_verdict_of_the_poles_placed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A validation record: any input, any output (the verdict is the model's, not the record's).
    let mut g = common::lcg(3);
    let u: Vec<f64> = (0..100).map(|_| 200.0 * (g.unit() - 0.5)).collect();
    let y: Vec<f64> = (0..100).map(|k| (k as f64 * 0.1).sin()).collect();
    let record = d.join("val.csv");
    common::write_csv(&record, "u,y", None, &[&u, &y]);
    for case in cases() {
        let a: Vec<f64> = case.alpha.iter().map(|x| -x).collect();
        let model = model_file(d, "m.json", &a);
        let want = case.verdict;
        let what = case.what;
        assert_eq!(simulate_says(d, &model), want, "simulate, poles {what}");
        assert_eq!(
            validate_says(d, &model, &record),
            want,
            "validate, poles {what}"
        );
        assert_eq!(response_says(&model), want, "response, poles {what}");
        assert_eq!(tune_says(d, &model), want, "tune, poles {what}");
        // control words what an actuator does not do; an integrator is what a position actuator does.
        let control_want = match want {
            Verdict::Integrator => Verdict::Settles,
            v => v,
        };
        assert_eq!(
            control_says(d, &model),
            control_want,
            "control, poles {what}"
        );
        assert_eq!(
            identify_says(d, &case.alpha),
            want,
            "identify, poles {what}"
        );
    }
}

// a = [1e308, 1e308]: A(z) = z² + 1e308 z + 1e308 has poles that are not finite numbers in f64 (the
// companion matrix overflows): the verdict is unstable. `simulate` says so before its run overflows;
// the others refuse the file with a numerical failure (exit 1) — none calls it stable or an integrator.
#[test]
fn poles_that_are_not_numbers_are_unstable_or_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let model = model_file(d, "nan.json", &[1e308, 1e308]);
    let o = ipa_sysid(&[
        "simulate",
        "--plant",
        &format!("model:{}", s(&model)),
        "--input",
        "step:10@5",
        "--samples",
        "12",
        "--out",
        s(&d.join("sim.csv")),
    ]);
    let e = stderr(&o);
    assert!(
        e.contains("unstable model (a pole is not a finite number"),
        "{e}"
    );
    let record = d.join("val.csv");
    common::write_csv(
        &record,
        "u,y",
        None,
        &[&[1.0, 2.0, 3.0, 4.0], &[0.0, 1.0, 0.0, 1.0]],
    );
    for args in [
        vec!["validate", "--model", s(&model), "--data", s(&record)],
        vec!["response", "--model", s(&model)],
        vec![
            "control",
            "--plant",
            &format!("model:{}", s(&model)),
            "--setpoint",
            "3",
            "--duration",
            "0.5",
            "--out",
            s(&d.join("c.csv")),
        ],
    ] {
        let o = ipa_sysid(&args);
        let text = String::from_utf8_lossy(&o.stdout).into_owned() + &stderr(&o);
        let said_unstable = text.contains("unstable");
        assert!(
            said_unstable || o.status.code() == Some(1),
            "{args:?}: neither unstable nor refused: {text}"
        );
        assert!(
            !text.contains("integrator") && !text.contains("→ stable"),
            "{args:?}: {text}"
        );
    }
}
