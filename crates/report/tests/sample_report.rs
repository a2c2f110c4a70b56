//! A sample report shaped like the one `reproduce` writes (synthetic data, not results), checked for
//! structure and self-containment. With `REPORT_SAMPLE_OUT=DIR` set, the report and its figures are
//! also written to DIR, for a look in a browser (`scripts/check_report_browser.sh DIR/report.html`).

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;

use common::check_well_formed;
use report::html::{Report, Section, Table, Verdict};
use report::plot::{save_figure, Figure, Panel, Series};

const TS_S: f64 = 0.01;

/// Staircase PWM input: levels held for 1 s, cycling through ±255 and smaller steps.
fn staircase_input(n: usize) -> Vec<f64> {
    let levels = [255.0, -255.0, 160.0, -120.0, 255.0, -60.0, 90.0, -255.0];
    (0..n).map(|k| levels[(k / 100) % levels.len()]).collect()
}

/// A toy plant for the sample only: deadzone of ±40 counts then an integrator, stroke 0..100 mm.
fn toy_output(u: &[f64]) -> Vec<f64> {
    let mut y = vec![50.0; u.len()];
    for k in 1..u.len() {
        let x = if u[k - 1] > 40.0 {
            u[k - 1] - 40.0
        } else if u[k - 1] < -40.0 {
            u[k - 1] + 40.0
        } else {
            0.0
        };
        y[k] = (y[k - 1] + TS_S * 0.6 * x).clamp(0.0, 100.0);
    }
    y
}

fn time(n: usize) -> Vec<f64> {
    (0..n).map(|k| k as f64 * TS_S).collect()
}

fn figures() -> Vec<(&'static str, Figure)> {
    let n = 2000;
    let t = time(n);
    let u = staircase_input(n);
    let y = toy_output(&u);
    let y_arx: Vec<f64> = y
        .iter()
        .enumerate()
        .map(|(k, v)| v + 2.0 * (k as f64 * 0.013).sin())
        .collect();
    let y_ham: Vec<f64> = y
        .iter()
        .enumerate()
        .map(|(k, v)| v + 0.6 * (k as f64 * 0.021).cos())
        .collect();
    let u_dz: Vec<f64> = (-255..=255).map(f64::from).collect();
    let x_dz: Vec<f64> = u_dz
        .iter()
        .map(|&u| {
            if u > 40.0 {
                0.004 * (u - 40.0)
            } else if u < -40.0 {
                0.0055 * (u + 40.0)
            } else {
                0.0
            }
        })
        .collect();
    let t_cl = time(500);
    let r: Vec<f64> = t_cl.iter().map(|_| 50.0).collect();
    let y_model: Vec<f64> = t_cl
        .iter()
        .map(|&t| 50.0 * (1.0 - (-t / 0.1).exp()))
        .collect();
    let y_plant: Vec<f64> = t_cl
        .iter()
        .map(|&t| 50.0 * (1.0 - (-t / 0.3).exp() * (1.0 + 0.2 * (8.0 * t).sin())))
        .collect();
    let it: Vec<f64> = (0..n).map(|k| k as f64).collect();
    let a1: Vec<f64> = it
        .iter()
        .map(|&k| -1.82 - 0.5 * (-k / 150.0).exp())
        .collect();
    let a2: Vec<f64> = it.iter().map(|&k| 1.0 + 0.4 * (-k / 200.0).exp()).collect();
    let a3: Vec<f64> = it
        .iter()
        .map(|&k| -0.18 + 0.3 * (-k / 90.0).exp())
        .collect();
    vec![
        (
            "fig2_data",
            Figure::new("Fig. 2 - identification data")
                .panel(
                    Panel::new("time t (s)", "input u (PWM counts)").series(Series::step(
                        "u",
                        t.clone(),
                        u,
                    )),
                )
                .panel(
                    Panel::new("time t (s)", "position y (mm)").series(Series::line(
                        "measured y",
                        t.clone(),
                        y.clone(),
                    )),
                ),
        ),
        (
            "fig4_deadzone",
            Figure::new("Fig. 4 - identified valve deadzone").panel(
                Panel::new("command u (PWM counts)", "internal variable x")
                    .series(Series::line("identified", u_dz.clone(), x_dz.clone()))
                    .series(Series::dashed(
                        "paper",
                        u_dz.clone(),
                        u_dz.iter().map(|u| u * 0.004).collect(),
                    )),
            ),
        ),
        (
            "fig5_fit",
            Figure::new("Fig. 5 - validation: measured vs models").panel(
                Panel::new("time t (s)", "position y (mm)")
                    .series(Series::line("measured", t.clone(), y))
                    .series(Series::dashed("ARX (fit 87.1 %)", t.clone(), y_arx))
                    .series(Series::dashed("Hammerstein (fit 93.0 %)", t, y_ham)),
            ),
        ),
        (
            "fig7a_closed_loop_fixed",
            Figure::new("Fig. 7a - PI closed loop, fixed set-point").panel(
                Panel::new("time t (s)", "position y (mm)")
                    .series(Series::dashed("set-point r", t_cl.clone(), r))
                    .series(Series::line("Hammerstein model", t_cl.clone(), y_model))
                    .series(Series::line("IPA plant", t_cl, y_plant)),
            ),
        ),
        (
            "rls_convergence",
            Figure::new("RLS parameter convergence").panel(
                Panel::new("sample k", "estimate")
                    .series(Series::line("a1", it.clone(), a1))
                    .series(Series::line("a2", it.clone(), a2))
                    .series(Series::line("a3", it, a3)),
            ),
        ),
    ]
}

fn sample_report() -> Report {
    let table3 = Table::new([
        "Block",
        "Parameter",
        "Ours (RLS)",
        "Paper estimated",
        "Paper actual",
    ])
    .caption("Hammerstein model parameters (Table III)")
    .paper_column(3)
    .paper_column(4)
    .row(["Deadzone", "b_r (counts)", "40.12", "1.4120", "1.4100"])
    .row(["Deadzone", "b_l (counts)", "-39.80", "-1.5010", "-1.5000"])
    .row(["Linear", "a_1", "-1.8412", "-1.8200", "-1.8690"])
    .row([
        "Linear",
        "b_1",
        "1.0 (normalised)",
        "7.4980e-4",
        "15.6700e-4",
    ]);
    let table4 = Table::new([
        "Criterion",
        "ARX (ours)",
        "Hammerstein (ours)",
        "ARX (paper)",
        "Hammerstein (paper)",
    ])
    .caption("Validation (Table IV)")
    .paper_column(3)
    .paper_column(4)
    .row(["Best fit (%)", "87.1", "93.0", "87.3102", "92.9665"])
    .row(["Loss V", "4.2e-3", "0.9e-3", "4.4000e-3", "0.8510e-3"]);
    let mut sections = vec![
        Section::new("What this report shows")
            .paragraph("SAMPLE DATA, not results: this report exercises the report layer with synthetic signals.")
            .list(["Identification data (Fig. 2)", "Deadzone (Fig. 4)", "Validation (Fig. 5, Table IV)"])
            .code("ipa-sysid reproduce --out out/ --seed 1"),
        Section::new("Fitted model").table(table3),
        Section::new("Validation").table(table4).callout(Verdict::Pass, "Hammerstein fit 93.0 % > ARX fit 87.1 %."),
        Section::new("Closed loop").callout(Verdict::Fail, "Overshoot 12.3 % > 10 % (sample text)."),
    ];
    for (i, (stem, fig)) in figures().into_iter().enumerate() {
        let caption = format!("{} (file figures/{stem}.svg)", fig.title);
        let s = sections.remove(1.min(sections.len() - 1));
        let s = if i % 2 == 0 {
            s.figure(&fig, caption).unwrap()
        } else {
            s.figure_png(&fig, caption).unwrap()
        };
        sections.insert(1.min(sections.len()), s);
    }
    let mut report = Report::new("IPA identification - sample report")
        .subtitle("plant: sample, seed: 0")
        .intro("This sample checks the layout of the report produced by ipa-sysid reproduce.")
        .footer("ipa-sysid report layer sample");
    for s in sections {
        report.push_section(s);
    }
    report
}

// The sample report is one well-formed document, with 5 figures (2 as data-URI images), 2 tables
// and every section heading listed in the table of contents.
#[test]
fn sample_report_is_self_contained_and_well_formed() {
    let report = sample_report();
    let html = report.to_html();
    let names = check_well_formed(&html).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(names.iter().filter(|n| *n == "html").count(), 1);
    assert_eq!(names.iter().filter(|n| *n == "figure").count(), 5);
    assert_eq!(names.iter().filter(|n| *n == "img").count(), 2);
    assert_eq!(names.iter().filter(|n| *n == "svg").count(), 3);
    assert_eq!(names.iter().filter(|n| *n == "table").count(), 2);
    assert_eq!(html.matches("<img src=\"data:image/png;base64,").count(), 2);
    assert!(
        !html.contains("http://")
            || html.matches("http://").count()
                == html.matches("xmlns=\"http://www.w3.org/2000/svg\"").count()
    );
    assert!(!html.contains("<script") && !html.contains("https://"));
    for s in report.sections() {
        assert!(
            html.contains(&format!(">{}</a></li>", s.heading())),
            "{} not in contents",
            s.heading()
        );
    }
    if let Some(dir) = std::env::var_os("REPORT_SAMPLE_OUT") {
        let dir = std::path::PathBuf::from(dir);
        let figs = dir.join("figures");
        std::fs::create_dir_all(&figs).unwrap();
        for (stem, fig) in figures() {
            save_figure(&fig, &figs, stem).unwrap();
        }
        report.save(&dir.join("report.html")).unwrap();
    }
}
