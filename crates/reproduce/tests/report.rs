//! `reproduce` on the physics plant (the default) and on the paper's model: the acceptance criteria carry
//! their ids and are recomputed here from the numbers in `summary.json`; the closed loop runs on a stable
//! model chosen by the stated rule (re-applied here to the poles); the report has the four new sections
//! and figures; one colour per model in every figure's legend; the method recovers the paper's model.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use ipa_reproduce::{colours, run, ReproduceSettings};
use serde_json::Value;

/// One run per plant, shared by the tests, written under Cargo's scratch folder for integration tests
/// (replaced by the next run, so nothing accumulates).
fn run_once(plant: &'static str) -> &'static (PathBuf, Value) {
    static IPA: OnceLock<(PathBuf, Value)> = OnceLock::new();
    static PAPER: OnceLock<(PathBuf, Value)> = OnceLock::new();
    let cell = if plant == "ipa" { &IPA } else { &PAPER };
    cell.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("reproduce-report-{plant}"));
        let _ = std::fs::remove_dir_all(&dir);
        let s = ReproduceSettings {
            plant: plant.into(),
            out_dir: dir,
            ..ReproduceSettings::default()
        };
        let out = run(&s, &mut |_, _| {}).unwrap();
        (s.out_dir, out.summary)
    })
}

fn stable_by_poles(model: &Value) -> bool {
    model["poles"]
        .as_array()
        .unwrap()
        .iter()
        .all(|p| p["re"].as_f64().unwrap().hypot(p["im"].as_f64().unwrap()) < 1.0)
}

fn fit(s: &Value, key: &str) -> f64 {
    s["models"][key]["metrics"]["validation"]["fit_sim_percent"]
        .as_f64()
        .unwrap()
}

fn criterion<'a>(s: &'a Value, id: &str) -> &'a Value {
    s["acceptance"]["criteria"]
        .as_array()
        .unwrap()
        .iter()
        .find(|c| c["id"] == id)
        .unwrap_or_else(|| panic!("criterion {id} missing"))
}

#[test]
fn every_criterion_has_an_id_and_the_verdicts_follow_from_the_numbers() {
    for plant in ["ipa", "paper"] {
        let (dir, s) = run_once(plant);
        let crits = s["acceptance"]["criteria"].as_array().unwrap();
        let mut ids: Vec<&str> = crits.iter().map(|c| c["id"].as_str().unwrap()).collect();
        for c in crits {
            assert!(c["met"].is_boolean() && c["criterion"].is_string(), "{c}");
        }
        for id in [
            "hammerstein_beats_arx",
            "hammerstein_stable",
            "pi_overshoot",
            "pi_steady_state_error",
        ] {
            assert!(ids.contains(&id), "{plant}: {id} missing from {ids:?}");
        }
        ids.sort_unstable();
        let n = ids.len();
        ids.dedup();
        assert_eq!(ids.len(), n, "ids must be unique");

        // "Hammerstein beats ARX" needs a positive Hammerstein fit above the ARX's, and both models
        // stable: a comparison with an unstable model is "not judged", never met.
        let (h, a) = (fit(s, "hammerstein"), fit(s, "arx"));
        let both_stable =
            stable_by_poles(&s["models"]["hammerstein"]) && stable_by_poles(&s["models"]["arx"]);
        assert_eq!(
            criterion(s, "hammerstein_beats_arx")["met"],
            both_stable && h > 0.0 && h > a,
            "{plant}: {h} vs {a}"
        );
        assert_eq!(
            criterion(s, "hammerstein_beats_arx")["status"],
            if !both_stable {
                "not judged"
            } else if h > 0.0 && h > a {
                "met"
            } else {
                "not met"
            }
        );
        // The changing set-point's steps, each against 2 % of its own step.
        let steps = s["closed_loop"]["unfixed"]["steps_plant"]
            .as_array()
            .unwrap();
        if !steps.is_empty() {
            let all_within = steps.iter().all(|g| {
                let size =
                    (g["setpoint_mm"].as_f64().unwrap() - g["y0_mm"].as_f64().unwrap()).abs();
                g["metrics"]["steady_state_error_mm"]
                    .as_f64()
                    .is_some_and(|e| size > 0.0 && 100.0 * e.abs() / size < 2.0)
            });
            assert_eq!(
                criterion(s, "pi_changing_setpoint_steady_state_error")["met"],
                all_within
            );
        }
        // A process check is not a criterion.
        assert!(!ids.contains(&"closed_loop_model_stable"));
        assert_eq!(
            criterion(s, "hammerstein_stable")["met"],
            stable_by_poles(&s["models"]["hammerstein"])
        );
        // A fit comparison involving an unstable model says so in words.
        let any_unstable =
            !stable_by_poles(&s["models"]["hammerstein"]) || !stable_by_poles(&s["models"]["arx"]);
        assert_eq!(
            criterion(s, "hammerstein_beats_arx")["criterion"]
                .as_str()
                .unwrap()
                .contains("UNSTABLE"),
            any_unstable,
            "{plant}"
        );
        // The overshoot is judged by the peak past the set-point r (as `control`'s acceptance line and
        // `tune`'s counts), recomputed from the recorded trace: OS_r = max(0, max_k sign(r − y0)(y(k) − r)),
        // as % of |r − y0|.
        let (r, y0) = (
            s["settings"]["fixed_setpoint_mm"].as_f64().unwrap(),
            s["settings"]["fixed_start_mm"].as_f64().unwrap(),
        );
        let step = (r - y0).abs();
        let trace = std::fs::read_to_string(dir.join("data/closed_loop_fixed_plant.csv")).unwrap();
        let peak_past_r = trace
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(3).unwrap().parse::<f64>().unwrap())
            .map(|y| (r - y0).signum() * (y - r))
            .fold(0.0, f64::max);
        let os_r = 100.0 * peak_past_r / step;
        let json_os_r = s["closed_loop"]["fixed"]["plant"]["overshoot_past_setpoint_percent"]
            .as_f64()
            .unwrap();
        assert!(
            (json_os_r - os_r).abs() < 1e-6,
            "{plant}: {json_os_r} vs {os_r}"
        );
        assert_eq!(criterion(s, "pi_overshoot")["met"], os_r < 10.0);
        // Table V's acceptance row shows the number the verdict judged.
        let said = criterion(s, "pi_overshoot")["criterion"].as_str().unwrap();
        let number = said
            .split("overshoot past r ")
            .nth(1)
            .and_then(|t| t.split(' ').next())
            .unwrap_or_else(|| panic!("{plant}: {said}"));
        let page = html(dir);
        let row = page
            .split("<tr>")
            .find(|row| row.contains("overshoot past r (% of the step to r"))
            .unwrap_or_else(|| panic!("{plant}: Table V has no acceptance row"));
        assert!(
            row.contains(&format!(">{number}<")),
            "{plant}: {number} not in {row}"
        );
        let ess = s["closed_loop"]["fixed"]["plant"]["steady_state_error_mm"]
            .as_f64()
            .unwrap();
        assert_eq!(
            criterion(s, "pi_steady_state_error")["met"],
            ess.abs() < 0.02 * step
        );
        let all = crits.iter().all(|c| c["met"] == true);
        assert_eq!(s["acceptance"]["accepted"], all);
    }
}

// On the physics plant both RLS fits are negative (issue 12): the old verdict called that a pass.
#[test]
fn a_negative_hammerstein_fit_never_beats_the_arx() {
    let (_, s) = run_once("ipa");
    if fit(s, "hammerstein") <= 0.0 {
        assert_eq!(criterion(s, "hammerstein_beats_arx")["met"], false);
        assert!(criterion(s, "hammerstein_beats_arx")["criterion"]
            .as_str()
            .unwrap()
            .contains("no better than the record's mean"));
    }
}

/// The rule, applied independently to the poles and fits in `summary.json`.
fn expected_closed_loop_model(s: &Value) -> Option<String> {
    let models = s["models"].as_object().unwrap();
    if stable_by_poles(&models["hammerstein"]) {
        return Some("hammerstein".into());
    }
    let mut best: Option<(&String, f64)> = None;
    for (k, m) in models {
        if k.starts_with("hammerstein") && stable_by_poles(m) {
            let f = fit(s, k);
            if best.is_none_or(|(_, b)| f > b) {
                best = Some((k, f));
            }
        }
    }
    best.map(|(k, _)| k.clone())
        .or_else(|| stable_by_poles(&models["arx"]).then(|| "arx".to_string()))
}

#[test]
fn the_closed_loop_runs_on_a_stable_model_chosen_by_the_stated_rule() {
    for plant in ["ipa", "paper"] {
        let (dir, s) = run_once(plant);
        let chosen = s["closed_loop"]["model"].as_str().map(str::to_string);
        assert_eq!(chosen, expected_closed_loop_model(s), "{plant}");
        assert!(s["closed_loop"]["model_rule"]
            .as_str()
            .unwrap()
            .contains("never controlled"));
        let key = chosen.expect("a stable model exists on both plants");
        assert!(
            s["models"].get(&key).is_some(),
            "{key} is not a key of models"
        );
        assert!(stable_by_poles(&s["models"][&key]));
        assert_eq!(s["open_loop"]["model"], key.as_str());
        // The simulated closed loop of the chosen model really ran and was written.
        assert!(dir.join("data/closed_loop_fixed_model.csv").is_file());
    }
    // On the physics plant the paper's RLS model is unstable: shown, not controlled.
    let (_, s) = run_once("ipa");
    if !stable_by_poles(&s["models"]["hammerstein"]) {
        assert_ne!(s["closed_loop"]["model"], "hammerstein");
    }
}

fn html(dir: &Path) -> String {
    std::fs::read_to_string(dir.join("report.html")).unwrap()
}

#[test]
fn the_new_sections_and_figures_exist() {
    let (dir, s) = run_once("ipa");
    let page = html(dir);
    for id in [
        "paper-model",
        "differences",
        "residuals",
        "frequency-response",
    ] {
        assert!(
            page.contains(&format!("<section id=\"{id}\">")),
            "section {id} missing"
        );
    }
    // The paper's model comes first, before the physics plant's experiment.
    let first = |needle: &str| page.find(needle).unwrap();
    assert!(first("<section id=\"paper-model\">") < first("<section id=\"experiment\">"));
    for stem in ["residuals", "bode"] {
        for ext in ["svg", "png"] {
            let f = dir.join("figures").join(format!("{stem}.{ext}"));
            assert!(
                std::fs::metadata(&f).unwrap().len() > 1000,
                "{} missing or empty",
                f.display()
            );
        }
    }
    // Every figure has alt text; the report names the colour key once.
    assert_eq!(
        page.matches("<figure>").count(),
        page.matches(" alt=\"").count()
    );
    assert!(page.contains("Colours are the same in every figure"));
    // Residual analyses in summary.json: both records of every model, the 99 % bound 2.58/√N.
    for key in s["models"].as_object().unwrap().keys() {
        for record in ["estimation", "validation"] {
            let r = &s["residuals"][key][record];
            let n = r["n"].as_f64().unwrap();
            assert!((r["bound"].as_f64().unwrap() - 2.58 / n.sqrt()).abs() < 1e-12);
            assert!(r["white"].is_boolean() && r["independent"].is_boolean());
        }
    }
    let diffs = s["differences"].as_array().unwrap();
    for id in [
        "b_r",
        "b_l",
        "m_r",
        "m_l",
        "dominant_pole",
        "fit",
        "loss",
        "fpe",
        "settling_time",
    ] {
        let d = diffs.iter().find(|d| d["id"] == id).unwrap();
        assert!(!d["reason"].as_str().unwrap().is_empty(), "{id}");
    }
}

// Audit s31 M-5: the differences table quoted the fit from estimated initial outputs (61.96 % for an
// unstable RLS model whose Table IV fit is −7.5 %). Its fit row is, for every model, the worse of the
// validation fits from estimated and measured initial outputs, as Table IV and the verdict quote.
#[test]
fn the_differences_fit_is_the_worse_of_both_initial_states() {
    let (_, s) = run_once("ipa");
    let d = s["differences"]
        .as_array()
        .unwrap()
        .iter()
        .find(|d| d["id"] == "fit")
        .unwrap();
    let plant = d["plant"].as_object().unwrap();
    assert!(!plant.is_empty());
    for (label, value) in plant {
        let (_, m) = s["models"]
            .as_object()
            .unwrap()
            .iter()
            .find(|(_, m)| {
                // The table's short names: "RLS (paper)" is the paper's method, the others are in the
                // model's label.
                let l = m["label"].as_str().unwrap();
                if label == "RLS (paper)" {
                    l.contains("paper's method")
                } else {
                    l.contains(label.as_str())
                }
            })
            .unwrap_or_else(|| panic!("no model labelled {label}"));
        let v = &m["metrics"]["validation"];
        let worse = [&v["fit_sim_percent"], &v["fit_sim_measured_percent"]]
            .iter()
            .filter_map(|f| f.as_f64())
            .reduce(f64::min)
            .unwrap();
        assert_eq!(value.as_f64().unwrap(), worse, "{label}");
    }
}

// Numbers in the report: 4 significant digits for estimates, 2 for standard deviations; never the
// old 6-digit forms such as "± 3.51834".
#[test]
fn estimates_have_four_significant_digits_and_deviations_two() {
    let (dir, _) = run_once("ipa");
    // Cells split "value ± std" into two no-wrap spans; read them as text.
    let page = html(dir)
        .replace("<span class=\"nw\">", "")
        .replace("</span>", "");
    let mut seen = 0;
    for (i, _) in page.match_indices(" ± ") {
        let before = &page[..i];
        let after = &page[i + " ± ".len()..];
        let value: String = before
            .chars()
            .rev()
            .take_while(|c| !matches!(c, '>' | ' ' | '('))
            .collect::<Vec<_>>()
            .into_iter()
            .rev()
            .collect();
        let std: String = after
            .chars()
            .take_while(|c| !matches!(c, '<' | ' ' | ')' | ';' | ','))
            .collect();
        let digits = |s: &str| {
            let mantissa = s.split(['e', 'i']).next().unwrap();
            mantissa
                .trim_start_matches('-')
                .chars()
                .filter(char::is_ascii_digit)
                .collect::<String>()
                .trim_start_matches('0')
                .len()
        };
        if std.ends_with('i') {
            // A complex pole re ± im·i: both parts are estimates.
            assert!(
                digits(&value) <= 4 && digits(&std) <= 4,
                "pole {value} ± {std}"
            );
        } else if value.parse::<f64>().is_ok() && std.parse::<f64>().is_ok() {
            seen += 1;
            assert!(digits(&value) <= 4, "estimate {value} ± {std}");
            assert!(digits(&std) <= 2, "deviation {value} ± {std}");
        }
    }
    assert!(seen > 20, "only {seen} value ± std pairs found");
}

/// For each legend box of an SVG figure: (label, colour of its legend mark).
fn legend_entries(svg: &str) -> Vec<(String, String)> {
    let num = |s: &str, key: &str| -> Option<f64> {
        let i = s.find(&format!("{key}=\""))? + key.len() + 2;
        s[i..].split('"').next()?.parse().ok()
    };
    let mut out = Vec::new();
    // (x, y, width, height) and where in the document the box is: a legend is drawn after its panel's
    // curves, so its marks are the lines after it (a curve may run under the box: audit s33 M-4's
    // curves clipped at the frame, not below the legend).
    let boxes: Vec<((f64, f64, f64, f64), usize)> = svg
        .match_indices("<rect ")
        .filter_map(|(i, _)| {
            let tag = &svg[i..i + svg[i..].find('>')?];
            (tag.contains("fill=\"none\"") && tag.contains("stroke=\"#787878\"")).then(|| {
                (
                    (
                        num(tag, "x").unwrap(),
                        num(tag, "y").unwrap(),
                        num(tag, "width").unwrap(),
                        num(tag, "height").unwrap(),
                    ),
                    i,
                )
            })
        })
        .collect();
    let inside = |b: &(f64, f64, f64, f64), x: f64, y: f64| {
        x >= b.0 && x <= b.0 + b.2 && y >= b.1 && y <= b.1 + b.3
    };
    // Texts (top y, label) and single-colour polylines (mean x, mean y, colour).
    let texts: Vec<(f64, f64, String)> = svg
        .match_indices("<text ")
        .filter_map(|(i, _)| {
            let end = i + svg[i..].find("</text>")?;
            let tag_end = i + svg[i..].find('>')?;
            let tag = &svg[i..tag_end];
            let label = svg[tag_end + 1..end].trim().replace("&apos;", "'");
            Some((num(tag, "x")?, num(tag, "y")?, label))
        })
        .collect();
    let lines: Vec<(f64, f64, String, usize)> = svg
        .match_indices("<polyline ")
        .filter_map(|(i, _)| {
            let tag = &svg[i..i + svg[i..].find("/>")?];
            let colour = tag
                .split("stroke=\"")
                .nth(1)?
                .split('"')
                .next()?
                .to_string();
            let pts: Vec<(f64, f64)> = tag
                .split("points=\"")
                .nth(1)?
                .split('"')
                .next()?
                .split_whitespace()
                .filter_map(|p| {
                    let (x, y) = p.split_once(',')?;
                    Some((x.parse().ok()?, y.parse().ok()?))
                })
                .collect();
            let n = pts.len() as f64;
            (n > 0.0).then(|| {
                (
                    pts.iter().map(|p| p.0).sum::<f64>() / n,
                    pts.iter().map(|p| p.1).sum::<f64>() / n,
                    colour,
                    i,
                )
            })
        })
        .collect();
    for (b, at) in &boxes {
        for (tx, ty, label) in texts.iter().filter(|t| inside(b, t.0, t.1)) {
            // The mark sits left of its text, a few pixels below the text's top; in a legend of
            // several columns (below the plot, since session 34) the entry to its left in the same
            // row is left of it too, so of the marks nearest in height the nearest to the left.
            let mark = lines
                .iter()
                .filter(|l| l.3 > *at && inside(b, l.0, l.1) && l.0 < *tx && l.1 >= *ty)
                .min_by(|p, q| {
                    (p.1 - ty)
                        .total_cmp(&(q.1 - ty))
                        .then((tx - p.0).total_cmp(&(tx - q.0)))
                });
            if let Some((_, _, c, _)) = mark {
                out.push((label.clone(), c.clone()));
            }
        }
    }
    out
}

#[test]
fn each_model_has_one_colour_in_every_figure() {
    let (dir, s) = run_once("ipa");
    let labels: Vec<(String, String)> = s["models"]
        .as_object()
        .unwrap()
        .iter()
        .map(|(k, m)| (k.clone(), m["label"].as_str().unwrap().to_string()))
        .collect();
    let mut checked = 0;
    for entry in std::fs::read_dir(dir.join("figures")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "svg") {
            continue;
        }
        let svg = std::fs::read_to_string(&path).unwrap();
        for (label, colour) in legend_entries(&svg) {
            for (key, model_label) in &labels {
                if label.contains(model_label.as_str()) {
                    checked += 1;
                    assert_eq!(
                        colour.to_uppercase(),
                        colours::hex(colours::model(key)),
                        "{}: legend entry {label:?}",
                        path.display()
                    );
                }
            }
            if label == "plant" || label == "measured" {
                assert_eq!(
                    colour.to_uppercase(),
                    colours::hex(colours::PLANT),
                    "{label}"
                );
            }
        }
    }
    // fig5 (3 models), residuals (2 x 4), bode (2 x 4), deadzone (3), the closed loops and open loop.
    assert!(checked >= 20, "only {checked} legend entries checked");
    // Distinct models have distinct colours.
    let mut hexes: Vec<String> = labels
        .iter()
        .map(|(k, _)| colours::hex(colours::model(k)))
        .collect();
    hexes.push(colours::hex(colours::PLANT));
    hexes.push(colours::hex(colours::PAPER));
    let n = hexes.len();
    hexes.sort();
    hexes.dedup();
    assert_eq!(hexes.len(), n);
}

/// The paper's Table III actual values normalised to b1 = 1 (slopes times b1 = 15.67e-4), by hand.
const ACTUAL_NORMALISED: [(&str, f64); 7] = [
    ("b_r", 1.41),
    ("b_l", -1.50),
    ("m_r", 2.38 * 15.67e-4),
    ("m_l", 3.46 * 15.67e-4),
    ("a1", -1.869),
    ("a2", 0.9976),
    ("a3", -0.1284),
];

#[test]
fn the_method_recovers_the_papers_model_without_noise() {
    let (dir, s) = run_once("ipa");
    let runs = s["paper_model"]["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 2);
    let clean = runs.iter().find(|r| r["record"] == "noise-free").unwrap();
    let noisy = runs.iter().find(|r| r["record"] != "noise-free").unwrap();
    assert_eq!(noisy["output_noise_std_mm"], 0.01);
    let value = |r: &Value, name: &str| {
        r["params"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .unwrap()["value"]
            .as_f64()
            .unwrap()
    };
    for (name, truth) in ACTUAL_NORMALISED {
        let e = value(clean, name);
        assert!(((e - truth) / truth).abs() < 1e-4, "{name}: {e} vs {truth}");
        // With 0.01 mm of noise the estimate stays within 10 % (breakpoints within 0.5 count).
        let n = value(noisy, name);
        let tol = if name.starts_with('b') {
            0.5
        } else {
            0.1 * truth.abs()
        };
        assert!((n - truth).abs() < tol, "{name} (noisy): {n} vs {truth}");
    }
    let page = html(dir);
    let section = &page[page.find("<section id=\"paper-model\">").unwrap()..];
    let section = &section[..section.find("</section>").unwrap()];
    assert!(section.contains("paper: actual"));
    assert!(section.contains("<td class=\"paper num\">1.41</td>"));
}

// Bode of a first-order lag y(k) = p y(k−1) + g x(k−1): |G| = g/|1 − p e^{−jωTs}|, closed form.
#[test]
fn bode_matches_the_closed_form_of_a_first_order_model() {
    let (p, g, ts) = (0.9, 0.5, 0.01);
    let m = sysid::Model::arx(ts, vec![-p], vec![g], 1, None).unwrap();
    let b = ipa_reproduce::analysis::bode(&m, 2.0, 0.01, 50);
    assert_eq!(b.f_hz.len(), 50);
    assert!(
        (b.f_hz[49] - 50.0).abs() < 1e-9,
        "last frequency is Nyquist"
    );
    for k in [0, 17, 49] {
        let w = 2.0 * std::f64::consts::PI * b.f_hz[k] * ts;
        let (re, im) = (1.0 - p * w.cos(), p * w.sin());
        let mag = 2.0 * g / re.hypot(im);
        assert!((b.mag_db[k] - 20.0 * mag.log10()).abs() < 1e-9, "{k}");
        // arg G = −ωTs − arg(1 − p e^{−jω}).
        let phase = (-w - im.atan2(re)).to_degrees();
        assert!(
            (b.phase_deg[k] - phase).abs() < 1e-9,
            "{k}: {} vs {phase}",
            b.phase_deg[k]
        );
    }
}

// The residual figure: the 99 % band is one legend entry (both bounds one series), the legend sits once
// (bottom panel), and no model label is listed twice.
#[test]
fn the_residual_band_has_one_legend_entry_and_one_style() {
    let (dir, _) = run_once("ipa");
    let svg = std::fs::read_to_string(dir.join("figures/residuals.svg")).unwrap();
    let entries = legend_entries(&svg);
    let band = entries.iter().filter(|(l, _)| l.contains("99 %")).count();
    assert_eq!(band, 1, "legend entries: {entries:?}");
    let mut labels: Vec<&String> = entries.iter().map(|(l, _)| l).collect();
    let n = labels.len();
    labels.sort();
    labels.dedup();
    assert_eq!(labels.len(), n, "a label listed twice: {entries:?}");
}

// Table V's data columns hold measurements of their own source; a threshold (the paper's acceptance)
// sits in the criterion's label, never in a data cell.
#[test]
fn table_five_has_no_threshold_in_a_data_column() {
    let (dir, _) = run_once("ipa");
    let page = html(dir);
    let start = page.find("Table V").expect("Table V");
    let table = &page[start..start + page[start..].find("</table>").unwrap()];
    for row in table.split("<tr").skip(1) {
        let cells: Vec<&str> = row.split("<td").skip(1).collect();
        for cell in cells.iter().skip(1) {
            assert!(
                !cell.contains("acceptance"),
                "a threshold in a data cell: {row}"
            );
        }
    }
}

// Issue 25: Table V's "tuned controller" rows; the plant's steady-state error in summary.json is the
// set-point minus the last position of the tuned run's trace (read back here), and the tuned controller
// leaves a smaller error than the paper's PI on the physics plant's 50 mm step (the PI creeps in the
// valve's deadzone; the deadzone inverse and the hold band stop within 0.05 mm).
#[test]
fn table_five_has_the_tuned_controller_rows() {
    let (dir, s) = run_once("ipa");
    let page = html(dir);
    let start = page.find("Table V").expect("Table V");
    let table = &page[start..start + page[start..].find("</table>").unwrap()];
    for label in [
        "tuned: overshoot (mm)",
        "tuned: e_ss (mm)",
        "tuned: settling time (s)",
    ] {
        assert!(table.contains(label), "{label} missing from Table V");
    }
    let fixed = &s["closed_loop"]["fixed"];
    let tuned = &fixed["tuned"];
    let ess = tuned["plant"]["steady_state_error_mm"].as_f64().unwrap();
    let text = std::fs::read_to_string(dir.join("data/closed_loop_fixed_plant_tuned.csv")).unwrap();
    let last = text.lines().last().unwrap();
    let v: Vec<f64> = last.split(',').map(|x| x.parse().unwrap()).collect();
    assert!((ess - (v[1] - v[3])).abs() < 1e-12, "{ess} vs {last}");
    let pi_ess = fixed["plant"]["steady_state_error_mm"].as_f64().unwrap();
    assert!(
        ess.abs() <= 0.05 && ess.abs() < pi_ess.abs(),
        "{ess} vs {pi_ess}"
    );
    assert!(tuned["controller"]["kp"].as_f64().unwrap() > 0.0);
}

/// The report's calibrated twin: its open-loop fit is re-computed here from the parameters in
/// `summary.json` (a fresh physics plant with those values, driven by the recorded open-loop command
/// from the recorded start, compared with the recorded plant output by eq. 13 written out), and it is
/// far above every identified model, as docs/twin.md reports; on the paper's model there is no twin,
/// and the summary says why.
#[test]
fn the_calibrated_twin_section_matches_its_parameters_and_beats_the_models() {
    use ipa::calibrate::Parameter;
    use sysid::Plant;
    let (dir, s) = run_once("ipa");
    assert!(html(dir).contains("<section id=\"twin\">"));
    let t = &s["twin"];
    let mut cfg = ipa::PlantConfig::default();
    for p in t["parameters"].as_array().unwrap() {
        let name = p["name"].as_str().unwrap();
        let par = Parameter::ALL.iter().find(|q| q.name() == name).unwrap();
        par.set(&mut cfg, p["value"].as_f64().unwrap());
    }
    let ol = std::fs::read_to_string(dir.join("data/open_loop.csv")).unwrap();
    let rows: Vec<Vec<f64>> = ol
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    let mut plant = ipa::Ipa::with_ts(cfg, s["settings"]["ts"].as_f64().unwrap()).unwrap();
    plant.reset(s["settings"]["experiment_start_mm"].as_f64().unwrap());
    let (mut num, mut den) = (0.0, 0.0);
    let mean = rows.iter().map(|r| r[2]).sum::<f64>() / rows.len() as f64;
    for r in &rows {
        let y_twin = plant.position_mm(); // the twin is simulated unquantised (calibrate::free_run)
        num += (r[2] - y_twin).powi(2);
        den += (r[2] - mean).powi(2);
        plant.step(r[1]).unwrap();
    }
    let fit = 100.0 * (1.0 - (num / den).sqrt());
    let reported = t["open_loop_fit_percent"].as_f64().unwrap();
    assert!((fit - reported).abs() < 1e-6, "{fit} vs {reported}");
    let val = t["validation_fit_percent"].as_f64().unwrap();
    assert!(val >= 98.0 && reported >= 98.0, "{val} {reported}");
    for (key, m) in t["models"].as_object().unwrap() {
        let mv = m["validation_fit_percent"].as_f64().unwrap();
        assert!(val > mv, "{key}: twin {val} vs model {mv}");
        // The same number as the model's own validation metrics (measured initial outputs).
        let own = s["models"][key]["metrics"]["validation"]["fit_sim_measured_percent"]
            .as_f64()
            .unwrap();
        assert_eq!(mv, own, "{key}");
    }
    let (_, paper) = run_once("paper");
    assert!(paper["twin"]["not_run"]
        .as_str()
        .unwrap()
        .contains("not the physics IPA"));
}

/// The open-loop column of the twin table and the open-loop test's fit simulate each model from the measured
/// initial outputs, as `validate` does (audit s11: they simulated from rest at the experiment's start, a
/// start `validate` does not offer, and the ranking flipped). Re-simulated here by the ARX recursion of each
/// saved model: y_hat(k) = y(k) for k < k0 = max(na, nk + nb − 1), then −Σ a_i y_hat(k−i) + Σ b_j x(k−nk−j+1)
/// + c, with x = f(u) the model's static map, and eq. (13)'s fit over k ≥ k0 computed here.
#[test]
fn the_open_loop_fits_start_from_the_measured_outputs_as_validate_does() {
    let (dir, s) = run_once("ipa");
    let ol = std::fs::read_to_string(dir.join("data/open_loop.csv")).unwrap();
    let rows: Vec<Vec<f64>> = ol
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    let u: Vec<f64> = rows.iter().map(|r| r[1]).collect();
    let y: Vec<f64> = rows.iter().map(|r| r[2]).collect();
    let chosen = s["open_loop"]["model"].as_str().expect("a stable model");
    for (key, m) in s["twin"]["models"].as_object().unwrap() {
        let model = sysid::model_file::read_model(&dir.join(format!("model_{key}.json"))).unwrap();
        let (a, ch) = (model.a(), &model.inputs()[0]);
        let (b, nk, c) = (ch.b(), ch.nk(), model.offset().unwrap_or(0.0));
        let k0 = a.len().max(nk + b.len() - 1);
        let x: Vec<f64> = u.iter().map(|&v| model.input_map(v)).collect();
        let mut yh = y[..k0].to_vec();
        for k in k0..y.len() {
            let ar: f64 = a.iter().enumerate().map(|(i, ai)| ai * yh[k - 1 - i]).sum();
            let ex: f64 = b.iter().enumerate().map(|(j, bj)| bj * x[k - nk - j]).sum();
            yh.push(-ar + ex + c);
        }
        // Eq. (13) over the samples the model predicts, k ≥ k0 (docs/estimators.md).
        let yk = &y[k0..];
        let mean = yk.iter().sum::<f64>() / yk.len() as f64;
        let den: f64 = yk.iter().map(|v| (v - mean).powi(2)).sum();
        let num: f64 = yk.iter().zip(&yh[k0..]).map(|(p, q)| (p - q).powi(2)).sum();
        let fit = 100.0 * (1.0 - (num / den).sqrt());
        let reported = m["open_loop_fit_percent"].as_f64().unwrap();
        assert!(
            (fit - reported).abs() < 1e-6 * fit.abs().max(1.0),
            "{key}: {fit} vs {reported}"
        );
        if key == chosen {
            let f = s["open_loop"]["fit_percent"].as_f64().unwrap();
            assert!((fit - f).abs() < 1e-6 * fit.abs().max(1.0), "{fit} vs {f}");
            for (r, v) in rows.iter().zip(&yh) {
                assert!(
                    (r[3] - v).abs() <= 1e-9 * v.abs().max(1.0),
                    "{} vs {v}",
                    r[3]
                );
            }
        }
    }
}

// Audit s31 L-4: the report's residual table for an output-error model used the simulation from the
// measured initial outputs, where validate uses its y_pred (the simulation from the estimated ones). The
// table's residual std on the validation record is the 1/N standard deviation (mean removed) of
// y − y_pred over k ≥ k0, y_pred computed here by validate's model_output from data/validation.csv.
#[test]
fn the_residual_table_uses_validates_prediction() {
    let (dir, s) = run_once("ipa");
    let text = std::fs::read_to_string(dir.join("data/validation.csv")).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|c| c.parse().unwrap()).collect())
        .collect();
    let u: Vec<f64> = rows.iter().map(|r| r[1]).collect();
    let y: Vec<f64> = rows.iter().map(|r| r[2]).collect();
    let key = "hammerstein_oe";
    let model = sysid::model_file::read_model(&dir.join(format!("model_{key}.json"))).unwrap();
    let pred = sysid_core::metrics::model_output(&model, &[&u], &y, 1)
        .unwrap()
        .y_pred;
    let k0 = model.k0();
    let e: Vec<f64> = y[k0..]
        .iter()
        .zip(&pred[k0..])
        .map(|(a, b)| a - b)
        .collect();
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    let std = (e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / e.len() as f64).sqrt();
    let got = s["residuals"][key]["validation"]["residual_std"]
        .as_f64()
        .unwrap();
    assert!((got - std).abs() <= 1e-9 * std, "{got} vs {std}");
}
