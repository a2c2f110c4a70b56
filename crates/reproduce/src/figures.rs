//! Stage 4: the figures (the paper's Figs. 2, 4–7 and this project's residual, convergence and Bode
//! figures), each with its caption.

use control::Trace;
use report::format::estimate;
use report::plot::{Figure, Panel, Series, SeriesStyle};
use sysid::{Dataset, Model};

use crate::analysis;
use crate::colours;
use crate::study::{Loop, Study};
use crate::ReproduceSettings;

pub(crate) type Fig = (&'static str, Figure, String);

fn sim_or_nan(model: &Model, d: &Dataset) -> Vec<f64> {
    model
        .simulate(&[d.u()], d.y())
        .unwrap_or_else(|_| vec![f64::NAN; d.len()])
}

/// A y range for `v` that ignores its first `skip` samples (the start-up transient of a recursive
/// estimate), padded by 10 % of the span (or of |value| for a constant).
fn settled_range(v: &[f64], skip: usize) -> Option<(f64, f64)> {
    let tail = v.get(skip..).filter(|t| !t.is_empty()).unwrap_or(v);
    let (lo, hi) = measured_range(tail)?;
    let pad = if hi > lo {
        0.1 * (hi - lo)
    } else {
        0.1 * lo.abs().max(1e-12)
    };
    Some((lo - pad, hi + pad))
}

/// The finite minimum and maximum of `v`; `None` when no sample is finite.
fn measured_range(v: &[f64]) -> Option<(f64, f64)> {
    let (lo, hi) = v
        .iter()
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
            (a.min(x), b.max(x))
        });
    (lo <= hi).then_some((lo, hi))
}

/// Frequency responses of the linear blocks drawn in the Bode figure: (key, label, model, gain), the
/// Hammerstein blocks scaled by their mean deadzone slope (m_l + m_r)/2 so that all are in mm/count.
fn bode_models(st: &Study) -> Vec<(&'static str, String, Model, f64)> {
    let mean_slope = |m: &Model| m.deadzone().map_or(1.0, |d| 0.5 * (d.m_l + d.m_r));
    let mut v: Vec<(&'static str, String, Model, f64)> = st
        .models
        .iter()
        .map(|m| {
            (
                m.key,
                m.label.to_string(),
                m.fit.model.clone(),
                mean_slope(&m.fit.model),
            )
        })
        .collect();
    let paper = Model::paper();
    let g = mean_slope(&paper);
    v.push(("paper", "paper's actual model (Table III)".into(), paper, g));
    v
}

pub(crate) fn figures(s: &ReproduceSettings, st: &Study) -> Vec<Fig> {
    let ts = st.ts;
    let t = sysid::data::sample_times(st.est.len(), ts);
    let mut figs: Vec<Fig> = Vec::new();
    let plant_c = colours::PLANT;
    // Axis labels in the plant's units: the IPA's counts and mm, a model plant's own (audit s28 L-9).
    let (yu, uu) = (st.y_unit(), st.u_unit());
    let y_axis = format!("y ({yu})");
    let u_axis = format!("u ({uu})");
    figs.push((
        "fig2_experiment",
        Figure::new("Experiment: staircase input and measured position (paper's Fig. 2)")
            .panel(Panel::new("time (s)", u_axis.as_str()).series(Series::step("u: PWM command", t.clone(), st.est.u().to_vec()).colour(plant_c)))
            .panel(Panel::new("time (s)", y_axis.as_str()).series(Series::line("y: position", t.clone(), st.est.y().to_vec()).colour(plant_c))),
        format!("The estimation record: the staircase command u ({uu}) and the measured position y ({yu})."),
    ));

    // Deadzone: RLS solid, the others dashed on top so that coinciding curves stay visible.
    let us: Vec<f64> = (-255..=255).map(f64::from).collect();
    let mut dz_panel = Panel::new(u_axis.as_str(), "x (key-term units, b1 = 1)");
    for (i, m) in st.hammersteins().iter().enumerate() {
        let y = m.fit.model.internal(&us);
        let series = if i == 0 {
            Series::line(m.label, us.clone(), y)
        } else {
            Series::dashed(m.label, us.clone(), y)
        };
        dz_panel = dz_panel.series(series.colour(colours::model(m.key)));
    }
    dz_panel = dz_panel.series(
        Series::dashed(
            "paper's actual model (Table III)",
            us.clone(),
            Model::paper().internal(&us),
        )
        .colour(colours::PAPER),
    );
    let (rls, ls) = (st.model("hammerstein"), st.model("hammerstein_ls"));
    let coincide = match (rls, ls) {
        (Some(a), Some(b)) => {
            let (ya, yb) = (a.fit.model.internal(&us), b.fit.model.internal(&us));
            let scale = ya
                .iter()
                .map(|v| v.abs())
                .fold(0.0, f64::max)
                .max(f64::MIN_POSITIVE);
            let gap = ya
                .iter()
                .zip(&yb)
                .map(|(p, q)| (p - q).abs())
                .fold(0.0, f64::max);
            Some(100.0 * gap / scale)
        }
        _ => None,
    };
    figs.push((
        "fig4_deadzone",
        Figure::new("Identified valve deadzone x = f(u) (paper's Fig. 4)").panel(dz_panel),
        format!(
            "The identified static nonlinearity: the valve deadzone between b_l and b_r and the slopes m_l, m_r \
             (b1 = 1), with the paper's Table III actual deadzone (slopes times its b1). The RLS curve is solid, \
             the others dashed on top of it{}.",
            coincide.map_or(String::new(), |g| format!(
                "; the RLS and key-term LS curves differ by at most {} % of the largest |x|, so they overlap",
                estimate(g)
            ))
        ),
    ));

    let tv = sysid::data::sample_times(st.val.len(), ts);
    let fit_title = "Validation record: measured vs simulated output (paper's Fig. 5)";
    let measured = Series::line("measured", tv.clone(), st.val.y().to_vec()).colour(plant_c);
    // The view is the measured range with a quarter of its span on each side: a diverging simulation
    // would otherwise scale the figure so that the measured record is a flat line. A model leaving the
    // axes drawn is clipped at the frame, and a point marks its first sample outside (audit s33 M-4: the
    // clip and the caption follow the drawn axes; the legend goes below the plot when no corner is free,
    // so no curve runs under it).
    let view = measured_range(st.val.y()).map(|(lo, hi)| {
        let pad = if hi > lo {
            0.25 * (hi - lo)
        } else {
            0.1 * lo.abs().max(1.0)
        };
        (lo - pad, hi + pad)
    });
    let sims: Vec<(&'static str, &'static str, Vec<f64>)> =
        ["arx", "hammerstein", "hammerstein_oe"]
            .into_iter()
            .filter_map(|key| {
                st.model(key)
                    .map(|m| (key, m.label, sim_or_nan(&m.fit.model, &st.val)))
            })
            .collect();
    let fit_panel = |marks: &[(&'static str, f64, f64)]| {
        let mut p = Panel::new("time (s)", y_axis.as_str()).series(measured.clone());
        for (key, label, y) in &sims {
            for &(_, t, edge) in marks.iter().filter(|m| m.0 == *key) {
                p = p.series(Series::points("", vec![t], vec![edge]).colour(colours::model(key)));
            }
            p = p.series(Series::dashed(*label, tv.clone(), y.clone()).colour(colours::model(key)));
        }
        if let Some((lo, hi)) = view {
            p = p.y_range(lo, hi);
        }
        p
    };
    let fit_figure =
        |marks: &[(&'static str, f64, f64)]| Figure::new(fit_title).panel(fit_panel(marks));
    // The axes drawn without the marks; a mark sits on a clipped curve's point, so it moves neither the
    // legend nor the axes (the caption states the final figure's range all the same).
    let drawn = report::plot::y_axes(&fit_figure(&[]))
        .ok()
        .and_then(|r| r.first().copied());
    let mut marks = Vec::new();
    let mut leaving = Vec::new();
    if let (Some((lo, hi)), Some(_)) = (drawn, view) {
        for (key, label, y) in &sims {
            if let Some(k) = y.iter().position(|v| !(lo..=hi).contains(v) && !v.is_nan()) {
                let edge = if y[k] > hi { hi } else { lo };
                marks.push((*key, tv[k], edge));
                leaving.push(format!("{label} at t = {} s", estimate(tv[k])));
            }
        }
    }
    let fig5 = fit_figure(&marks);
    let mut caption =
        "Free-run simulation of the models on the validation record (which was not used for estimation)."
            .to_string();
    let drawn = report::plot::y_axes(&fig5)
        .ok()
        .and_then(|r| r.first().copied());
    if let (Some(_), Some((lo, hi))) = (view, drawn) {
        caption.push_str(&format!(
            " The y axis runs from {} to {} {yu}: the measured range widened by a quarter of its span on each \
             side.",
            estimate(lo),
            estimate(hi)
        ));
        if leaving.is_empty() {
            caption.push_str(" No model leaves it.");
        } else {
            caption.push_str(&format!(
                " Leaving it (marked by a point, then drawn along the frame): {}.",
                leaving.join("; ")
            ));
        }
    }
    figs.push(("fig5_fit", fig5, caption));

    let t_ol = sysid::data::sample_times(st.u_ol.len(), ts);
    let mut y_ol = Panel::new("time (s)", y_axis.as_str())
        .series(Series::line("plant", t_ol.clone(), st.y_ol_plant.clone()).colour(plant_c));
    if let (Some(m), Some(y)) = (st.cl(), &st.y_ol_model) {
        y_ol = y_ol
            .series(Series::dashed(m.label, t_ol.clone(), y.clone()).colour(colours::model(m.key)));
    }
    figs.push((
        "fig6_open_loop",
        Figure::new("Open-loop test: stable identified model vs plant (paper's Fig. 6)")
            .panel(Panel::new("time (s)", u_axis.as_str()).series(
                Series::step("u", t_ol.clone(), st.u_ol.clone()).colour(plant_c),
            ))
            .panel(y_ol),
        match st.cl() {
            Some(m) => format!(
                "A fresh staircase applied to the plant and to {} (the stable model chosen by the stated rule) from the same start.",
                m.label
            ),
            None => "A fresh staircase applied to the plant; no identified model is stable, so none is simulated.".into(),
        },
    ));

    // Closed loops: y (and for the fixed set-point a zoom on the first second(s)), then u.
    let cl_label = st.cl().map_or("model", |m| m.label);
    let cl_colour = st.cl().map_or(plant_c, |m| colours::model(m.key));
    let y_panel = |lp: &Loop, until: f64| {
        let cut = |tr: &Trace, v: &[f64]| -> (Vec<f64>, Vec<f64>) {
            tr.t.iter()
                .zip(v)
                .filter(|(t, _)| **t <= until)
                .map(|(t, v)| (*t, *v))
                .unzip()
        };
        let (tp, r) = cut(&lp.plant, &lp.plant.r);
        let (_, yp) = cut(&lp.plant, &lp.plant.y);
        let mut p = Panel::new("time (s)", y_axis.as_str())
            .series(Series::step("set-point r", tp.clone(), r).colour(colours::SETPOINT))
            .series(Series::line("plant", tp, yp).colour(plant_c));
        if let Some(m) = &lp.model {
            let (tm, ym) = cut(m, &m.y);
            p = p
                .series(Series::dashed(format!("simulated: {cl_label}"), tm, ym).colour(cl_colour));
        }
        p
    };
    let u_panel = |lp: &Loop| {
        let mut p = Panel::new("time (s)", u_axis.as_str()).series(
            Series::step("u: plant", lp.plant.t.clone(), lp.plant.u.clone()).colour(plant_c),
        );
        if let Some(m) = &lp.model {
            p = p.series(
                Series::step(format!("u: {cl_label}"), m.t.clone(), m.u.clone()).colour(cl_colour),
            );
        }
        p
    };
    let rise = [Some(&st.fixed.m_plant), st.fixed.m_model.as_ref()]
        .iter()
        .flatten()
        .filter_map(|m| m.rise_time_s)
        .fold(0.0, f64::max);
    let zoom = (10.0 * rise).clamp(1.0, s.fixed_duration_s);
    let sim_note = if st.cl().is_some() {
        format!("the simulated {cl_label} vs the plant")
    } else {
        "the plant only (no identified model is stable)".to_string()
    };
    figs.push((
        "fig7a_closed_loop_fixed",
        Figure::new("PI control, fixed set-point (paper's Fig. 7a)")
            .size(960, 1120)
            .panel(y_panel(&st.fixed, f64::INFINITY))
            .panel(y_panel(&st.fixed, zoom))
            .panel(u_panel(&st.fixed)),
        format!(
            "PI (Kp = {}, Ki = {}) from rest to the fixed set-point: {sim_note}. Top: the whole {} s; middle: the \
             first {} s, where the rise happens; bottom: the commands.",
            estimate(s.pi.kp),
            estimate(s.pi.ki),
            estimate(s.fixed_duration_s),
            estimate(zoom)
        ),
    ));
    figs.push((
        "fig7b_closed_loop_unfixed",
        Figure::new("PI control, changing set-point (paper's Fig. 7b)")
            .panel(y_panel(&st.unfixed, f64::INFINITY))
            .panel(u_panel(&st.unfixed)),
        format!(
            "PI (Kp = {}, Ki = {}) following a staircase of set-points: {sim_note}.",
            estimate(s.pi.kp),
            estimate(s.pi.ki)
        ),
    ));

    // RLS convergence: one panel per parameter, each scaled to its settled range.
    let ham = &st.ham().fit;
    if !ham.history.is_empty() {
        let th: Vec<f64> = ham.history_samples.iter().map(|&k| k as f64 * ts).collect();
        let skip = ham.history.len() / 10;
        let mut fig = Figure::new("RLS parameter convergence (Hammerstein, paper's method)");
        let gain = st.gain_unit();
        for (name, unit) in [
            ("b_r", format!("b_r ({uu})")),
            ("b_l", format!("b_l ({uu})")),
            ("m_r", format!("m_r ({gain})")),
            ("m_l", format!("m_l ({gain})")),
            ("a1", "a1 (dimensionless)".into()),
            ("a2", "a2 (dimensionless)".into()),
            ("a3", "a3 (dimensionless)".into()),
        ] {
            let Some(i) = ham.params.iter().position(|p| p.name == name) else {
                continue;
            };
            let v: Vec<f64> = ham
                .history
                .iter()
                .map(|h| h.get(i).copied().unwrap_or(f64::NAN))
                .collect();
            let mut panel = Panel::new("time (s)", unit).series(
                Series::line("", th.clone(), v.clone()).colour(colours::model("hammerstein")),
            );
            if let Some((lo, hi)) = settled_range(&v, skip) {
                panel = panel.y_range(lo, hi);
            }
            fig = fig.panel(panel);
        }
        let n = fig.panels.len() as u32;
        figs.push((
            "rls_convergence",
            fig.size(960, 120 + 190 * n),
            format!(
                "The recursive estimates after each sample of the estimation record, one panel per parameter. Each \
                 panel's y range is the range of the estimate after the first {} s (10 % of the record), widened by \
                 10 % of its span on each side, so that the settling is visible; the start-up transient is clipped \
                 at the panel's edges.",
                estimate(skip as f64 * ts)
            ),
        ));
    }

    // Residual correlations on the validation record.
    let mut acf = Panel::new("lag τ (samples)", "autocorrelation r_ε(τ)");
    let mut ccf = Panel::new("lag τ (samples)", "cross-correlation r_εu(τ)");
    let mut bound = None;
    for r in &st.residuals {
        let Ok(a) = &r.validation else { continue };
        let label = st.model(r.key).map_or(r.key, |m| m.label);
        let lags: Vec<f64> = (1..=a.max_lag).map(|l| l as f64).collect();
        // Key-term LS nearly coincides with RLS: dashed on top so that both stay visible.
        let style = if r.key == "hammerstein_ls" {
            SeriesStyle::Dashed
        } else {
            SeriesStyle::Line
        };
        // One legend, in the bottom panel: the autocorrelation of an output-error model's residuals stays
        // near 1, so a legend in the top panel would either hide data or stretch the axis past |r| = 1.
        acf = acf.series(
            Series::new("", lags, a.autocorrelation.clone(), style).colour(colours::model(r.key)),
        );
        let m = a.max_lag as f64;
        let lags: Vec<f64> = (0..a.cross_correlation.len())
            .map(|i| i as f64 - m)
            .collect();
        ccf = ccf.series(
            Series::new(label, lags, a.cross_correlation.clone(), style)
                .colour(colours::model(r.key)),
        );
        bound = Some((a.bound, a.max_lag as f64));
    }
    if let Some((b, m)) = bound {
        // Both bounds are one series (a NaN breaks the line), so they share one dash pattern and one
        // legend entry.
        let band = |label: &str, from: f64| {
            Series::dashed(
                label,
                vec![from, m, f64::NAN, from, m],
                vec![b, b, f64::NAN, -b, -b],
            )
            .colour(colours::BOUND)
        };
        acf = acf.series(band("", 1.0));
        ccf = ccf.series(band("99 % bounds ±2.58/√N", -m));
    }
    figs.push((
        "residuals",
        Figure::new("Residual analysis on the validation record (one-step prediction errors)")
            .panel(acf)
            .panel(ccf),
        "Autocorrelation of each model's one-step prediction residuals ε (top) and their cross-correlation with \
         the input u (bottom; ε(t) against u(t − τ)), on the validation record, with the 99 % bounds ±2.58/√N (dashed grey). The \
         legend of the bottom panel holds for both. A model that has captured the dynamics leaves residuals \
         inside both bands."
            .into(),
    ));

    // Bode plots of the linear blocks.
    let mut mag = Panel::new(
        "frequency f (Hz, log scale)",
        format!("|G| (dB re 1 {})", st.gain_unit()),
    )
    .x_log10();
    let mut phase = Panel::new("frequency f (Hz, log scale)", "phase of G (degrees)").x_log10();
    for (i, (key, label, model, gain)) in bode_models(st).into_iter().enumerate() {
        let b = analysis::bode(&model, gain, 0.01, 300);
        let lf: Vec<f64> = b.f_hz.iter().map(|f| f.log10()).collect();
        let (sm, sp) = if i == 0 || key == "hammerstein" {
            (
                Series::line(label.clone(), lf.clone(), b.mag_db),
                Series::line(label, lf, b.phase_deg),
            )
        } else {
            (
                Series::dashed(label.clone(), lf.clone(), b.mag_db),
                Series::dashed(label, lf, b.phase_deg),
            )
        };
        mag = mag.series(sm.colour(colours::model(key)));
        phase = phase.series(sp.colour(colours::model(key)));
    }
    figs.push((
        "bode",
        Figure::new("Frequency response of the identified linear blocks").panel(mag).panel(phase),
        format!(
            "Bode magnitude and phase of G(e^(jωTs)) = m̄ B(e^(−jωTs))/A(e^(−jωTs)) from 0.01 Hz to the Nyquist \
             frequency {} Hz. The Hammerstein blocks have b1 = 1 (their static gain sits in the deadzone slopes), so \
             they are multiplied by the mean slope m̄ = (m_l + m_r)/2 to compare with the ARX (m̄ = 1) in {}; \
             the paper's actual model is scaled the same way.",
            estimate(0.5 / ts),
            st.gain_unit()
        ),
    ));
    figs
}
