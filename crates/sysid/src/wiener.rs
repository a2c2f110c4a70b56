//! An output nonlinearity y = g(v) after the linear block (a Wiener model; Hammerstein–Wiener with
//! input nonlinearities), as MATLAB idnlhw's OutputNonlinearity: a saturation, a piecewise-linear map
//! or a polynomial (the blocks of [`crate::blocks`]).
//!
//! Fitted by output error (simulation error) from a start the tool finds itself:
//! 1. the model without output nonlinearity, by the chosen method (the input blocks' key-term LS, RLS,
//!    IV or OE);
//! 2. its linear block's simulated output v̂ (from the measured initial outputs); g by least squares on
//!    (v̂, y) with the block's key-term iteration (a static regression y(k) = g(v̂(k)));
//! 3. every parameter (input blocks, A, B, c, g, initial outputs) by the output-error search
//!    ([`crate::oe::refine_with_output`]), with g's gain held at its least-squares value: g(v) and the
//!    linear block's gain are only determined up to a common scale (the saturation's m, the
//!    piecewise-linear s0, the polynomial's g1 are that scale).
//!
//! The result is kept as `--method oe` keeps its refinement ([`crate::methods::refinement_kept`]):
//! unless its start simulates the estimation data better by more than 1 % on the RMSE pooled over
//! estimated and measured initial outputs (audit s18 M-7; session 19: before, the worse of the two,
//! which lets the noisy measured initial outputs decide); otherwise the start is returned with a
//! warning. Warnings
//! also say when a limit or breakpoint of g lies outside the range of v̂ (not determined) and when g
//! is not monotone over that range (it cannot be inverted there: a controller cannot reach every
//! output).

use crate::blocks::{monotonicity_change, Block, NonlinearityKind};
use crate::fitted::{Fitted, Method, Note};
use crate::ls;
use crate::methods::{both_rmses, refinement_kept, simulation_rmses};
use crate::oe::{self, OutputStart};
use crate::problem::Problem;
use crate::warnings::Warning;
use nalgebra::{DMatrix, DVector};
use sysid_core::{Setting, StaticNonlinearity, SysidError};

/// True for the kinds an output nonlinearity can be.
pub fn is_output_kind(kind: NonlinearityKind) -> bool {
    matches!(
        kind,
        NonlinearityKind::Saturation
            | NonlinearityKind::PiecewiseLinear { .. }
            | NonlinearityKind::Polynomial { .. }
    )
}

/// Refuses a kind that cannot be an output nonlinearity (naming `--output-nonlinearity`).
pub fn check_output_kind(kind: NonlinearityKind) -> Result<(), SysidError> {
    if !is_output_kind(kind) {
        return Err(SysidError::setting(
            Setting::Other("--output-nonlinearity"),
            kind,
            "saturation, piecewise-linear or polynomial",
        ));
    }
    kind.check()
}

/// The physical parameter of g that carries its gain (held fixed: module docs).
fn gain_index(kind: NonlinearityKind) -> usize {
    match kind {
        NonlinearityKind::Saturation => 2,
        NonlinearityKind::PiecewiseLinear { breakpoints } => breakpoints,
        _ => 0,
    }
}

/// g by least squares on (v, y): the block's key-term iteration on the static regression
/// y(k) = Σ key terms × regressors(v(k)), from the block's start on v; at most 100 iterations, the
/// iterate with the smallest residual kept. Falls back to the block's start when no regression solves.
fn static_fit(
    block: &dyn Block,
    v: &[f64],
    y: &[f64],
    name: &str,
) -> Result<StaticNonlinearity, SysidError> {
    let start = block.start(v, false, true, name)?;
    let n_key = block.key_names().len();
    let mut f = start.initial;
    let mut best: Option<(f64, StaticNonlinearity)> = None;
    let mut prev: Option<DVector<f64>> = None;
    let mut row = vec![0.0; n_key];
    for _ in 0..100 {
        let mut phi = DMatrix::<f64>::zeros(v.len(), n_key);
        for (k, vk) in v.iter().enumerate() {
            block.fill_key_terms(&f, *vk, &mut row);
            for (j, r) in row.iter().enumerate() {
                phi[(k, j)] = *r;
            }
        }
        let Ok(sol) = ls::solve(&phi, &DVector::from_column_slice(y), &[]) else {
            break;
        };
        let next = block.of_key_terms(sol.theta.as_slice(), &f, start.limit);
        let rss: f64 = v
            .iter()
            .zip(y)
            .map(|(vk, yk)| (yk - next.apply(*vk)).powi(2))
            .sum();
        if rss.is_finite() && best.as_ref().is_none_or(|b| rss < b.0) {
            best = Some((rss, next));
        }
        let settled = prev
            .as_ref()
            .is_some_and(|p| (&sol.theta - p).norm() <= 1e-10 * (1.0 + sol.theta.norm()));
        prev = Some(sol.theta);
        f = next;
        if settled {
            break;
        }
    }
    Ok(best.map_or(start.initial, |b| b.1))
}

/// Adds the output nonlinearity `kind` to the fitted `start` of problem `p` (module docs), in at most
/// `max_iterations` output-error iterations.
pub(crate) fn refine(
    p: &Problem,
    kind: NonlinearityKind,
    start: Fitted,
    max_iterations: usize,
) -> Result<Fitted, SysidError> {
    let [data] = p.records() else {
        return Err(SysidError::setting(
            Setting::Other("--output-nonlinearity"),
            kind,
            "one record: an output nonlinearity is fitted by output error, which works on one record (not --merge)",
        ));
    };
    let name = data.name();
    let u = data.input_signals();
    let reg = p.regression();
    let k0 = reg.k0().min(data.len());
    let v = start.model.simulate_linear_part(&u, data.y())?;
    let block = kind.block();
    let g0 = static_fit(
        block,
        &v[k0..],
        &data.y()[k0..],
        &format!("{name} (simulated output)"),
    )?;
    let mut free_g = vec![true; block.physical_names().len()];
    free_g[gain_index(kind)] = false;
    let free = reg.free_physical(p.starts());
    let fit = oe::refine_with_output(
        data,
        reg,
        &free,
        &start.model,
        Some(OutputStart {
            block,
            start: g0,
            free: &free_g,
        }),
        max_iterations,
        p.cancel(),
    )?;
    let refined = simulation_rmses(&fit.model, data);
    let before = simulation_rmses(&start.model, data);
    let (refined_rmse, before_rmse) = (refined.map(|r| r.pooled), before.map(|b| b.pooled));
    let mut notes: Vec<Note> = start
        .notes
        .iter()
        .cloned()
        .map(|n| Note::Start(Box::new(n)))
        .collect();
    notes.push(Note::Refinement {
        rss_start: fit.rss_start,
        rss: fit.rss,
        iterations: fit.iterations,
        evaluations: fit.evaluations,
        stopped: fit.stop.to_string(),
    });
    let termination = fit.stop.termination();
    // Neither simulates stably: the start is returned, with the warning.
    let better = refinement_kept(refined, before).unwrap_or(false);
    let start_words = format!("the {} model without output nonlinearity", start.method);
    if !better {
        let why = format!(
            "the model with the {kind} output nonlinearity simulates the estimation data worse from both \
             initial states together (pooled RMSE {} against {} for its start; with it {}, start {})",
            refined_rmse.map_or("diverges".into(), |r| format!("{r:.6e}")),
            before_rmse.map_or("n/a".into(), |r| format!("{r:.6e}")),
            both_rmses(refined),
            both_rmses(before),
        );
        let mut warnings = start.warnings.clone();
        warnings.push(Warning::Fallback {
            used: start_words,
            why,
        });
        return Ok(Fitted {
            notes,
            warnings,
            termination,
            iterations: fit.iterations,
            ..start
        }
        .with_method(Method::Oe));
    }
    if let Some(r) = refined_rmse {
        notes.push(Note::KeptCandidate {
            kept: "output-error fit with the output nonlinearity",
            rmse: r,
            criterion: crate::fitted::POOLED_CRITERION,
            others: vec![("start without output nonlinearity", before_rmse)],
        });
    }
    let mut warnings: Vec<Warning> = crate::trust::std_warning(fit.std_unavailable.clone())
        .into_iter()
        .collect();
    let v_final = fit.model.simulate_linear_part(&u, data.y())?;
    if let Some(g) = fit.model.output_nonlinearity() {
        warnings.extend(output_warnings(g, &v_final[k0..]));
        // g works in deviations from the operating point, if the model has one.
        let y0 = fit.model.operating_point().map_or(0.0, |o| o.y);
        let dy: Vec<f64> = data.y()[k0..].iter().map(|y| y - y0).collect();
        warnings.extend(output_limit_warning(g, &dy, y0));
    }
    Ok(Fitted {
        iterations: fit.iterations,
        termination,
        notes,
        warnings,
        ..Fitted::new(fit.model, fit.params, Method::Oe, fit.noise_variance)
    })
}

/// A saturation's output limits, m·s_l and m·s_r, inside the measured output's range: at least 1 % of
/// the samples (and 5) beyond them, which the model cannot reach (audit s31 M-2: the cascaded tanks clip
/// at 10 V, 48 samples there, while the fitted limits were 3.19 and 9.58 V with 105 samples below; a
/// user reads s_r as the clip level). `dy`: the measured outputs in deviations from `y0`.
pub fn output_limit_warning(g: &StaticNonlinearity, dy: &[f64], y0: f64) -> Option<Warning> {
    let StaticNonlinearity::Saturation(s) = g else {
        return None;
    };
    let (a, b) = (s.m * s.s_l, s.m * s.s_r);
    let (lo, hi) = (a.min(b), a.max(b));
    let (min, max) = dy
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(*v), h.max(*v))
        });
    if !(lo.is_finite() && hi.is_finite() && min.is_finite() && max.is_finite()) {
        return None;
    }
    let tol = 1e-9 * (max - min).abs().max(f64::MIN_POSITIVE);
    let below = dy.iter().filter(|v| **v < lo - tol).count();
    let above = dy.iter().filter(|v| **v > hi + tol).count();
    let beyond = below + above;
    (beyond >= 5 && beyond * 100 >= dy.len()).then(|| Warning::NonlinearityShape {
        kind: "output saturation",
        why: format!(
            "its output limits ({} .. {}) lie inside the measured output's range ({} .. {}): {below} \
             samples below and {above} above them, which the model cannot reach; read s_l and s_r as \
             the bends of a fitted curve, not as the output's physical limits",
            sysid_core::format::sig(lo + y0, 4),
            sysid_core::format::sig(hi + y0, 4),
            sysid_core::format::sig(min + y0, 4),
            sysid_core::format::sig(max + y0, 4),
        ),
    })
}

/// Checks g against the range of the linear block's simulated output `v`: limits or breakpoints
/// outside it are not determined; a map that turns inside it cannot be inverted there.
pub fn output_warnings(g: &StaticNonlinearity, v: &[f64]) -> Vec<Warning> {
    let mut w = Vec::new();
    let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !(lo.is_finite() && hi.is_finite()) {
        return w;
    }
    // The shape a model file's reader names (`model_file::load_warnings`): limits that cross leave no
    // linear interval, and the model's output is a constant (audit s16 M7).
    let kind = match g {
        StaticNonlinearity::Saturation(_) => "output saturation",
        StaticNonlinearity::PiecewiseLinear(_) => "output piecewise-linear",
        StaticNonlinearity::Polynomial(_) => "output polynomial",
        _ => "output",
    };
    w.extend(
        g.shape_problems()
            .into_iter()
            .map(|why| Warning::NonlinearityShape { kind, why }),
    );
    let outside = |name: &str, b: f64, w: &mut Vec<Warning>, kind: &'static str| {
        if b <= lo || b >= hi {
            w.push(Warning::NonlinearityShape {
                kind,
                why: format!(
                    "{name} = {b:.6} lies outside the range of the linear block's simulated output ({lo:.6} .. \
                     {hi:.6}): no sample on one side of it, so it is not determined"
                ),
            });
        }
    };
    match g {
        StaticNonlinearity::Saturation(s) => {
            outside("s_l", s.s_l, &mut w, "output saturation");
            outside("s_r", s.s_r, &mut w, "output saturation");
        }
        StaticNonlinearity::PiecewiseLinear(p) => {
            for (i, b) in p.breakpoints().iter().enumerate() {
                outside(
                    &format!("p{}", i + 1),
                    *b,
                    &mut w,
                    "output piecewise-linear",
                );
            }
            let signs: Vec<f64> = p
                .slopes()
                .iter()
                .enumerate()
                .filter(|(j, _)| {
                    let from = if *j == 0 {
                        f64::NEG_INFINITY
                    } else {
                        p.breakpoints()[j - 1]
                    };
                    let to = p.breakpoints().get(*j).copied().unwrap_or(f64::INFINITY);
                    from < hi && to > lo
                })
                .map(|(_, s)| *s)
                .collect();
            // Slopes within 1e-4 of the largest are flat, not a change of direction.
            let tiny = 1e-4 * signs.iter().fold(0.0_f64, |m, s| m.max(s.abs()));
            if signs.iter().any(|s| *s > tiny) && signs.iter().any(|s| *s < -tiny) {
                w.push(Warning::NonlinearityShape {
                    kind: "output piecewise-linear",
                    why: format!(
                        "not monotone over the range of the linear block's output ({lo:.6} .. {hi:.6}): slopes of \
                         both signs {signs:?}, so it cannot be inverted there (a set-point may be reached by two \
                         commands or none)"
                    ),
                });
            }
        }
        StaticNonlinearity::Polynomial(_) => {
            if let Some(at) = monotonicity_change(|x| g.apply(x), lo, hi) {
                w.push(Warning::NonlinearityShape {
                    kind: "output polynomial",
                    why: format!(
                        "not monotone over the range of the linear block's output ({lo:.6} .. {hi:.6}; it turns near \
                         v = {at:.6}), so it cannot be inverted there"
                    ),
                });
            }
        }
        _ => {}
    }
    w
}

#[cfg(test)]
mod tests {
    use super::*;
    use sysid_core::nonlinearity::Saturation;

    // An output saturation whose limits cross (s_l = 0.8 > s_r = −0.4) maps every v to one constant: said
    // in words, as a model file's reader says it (audit s16 M7); limits in order and inside the range of
    // v say nothing.
    #[test]
    fn crossed_output_limits_are_warned() {
        let v: Vec<f64> = (0..=20).map(|k| -1.0 + 0.1 * k as f64).collect();
        let crossed = StaticNonlinearity::Saturation(Saturation {
            s_l: 0.8,
            s_r: -0.4,
            m: 1.0,
        });
        let w: Vec<String> = output_warnings(&crossed, &v)
            .iter()
            .map(ToString::to_string)
            .collect();
        assert!(
            w.iter().any(|w| w
                .starts_with("output saturation nonlinearity: s_l = 0.8 >= s_r = -0.4")
                && w.contains("the limits cross")),
            "{w:?}"
        );
        let fine = StaticNonlinearity::Saturation(Saturation {
            s_l: -0.5,
            s_r: 0.5,
            m: 1.0,
        });
        assert!(output_warnings(&fine, &v).is_empty());
    }

    // A fit of exactly 0 % is no better than the record's mean: warned, as a negative one is.
    #[test]
    fn a_fit_of_zero_is_no_better_than_the_mean() {
        use crate::warnings::Record;
        let w = Warning::if_poor_simulation(Record::Estimation, Some(0.0)).unwrap();
        assert!(
            w.to_string().contains("no better than the record's mean"),
            "{w}"
        );
        assert!(Warning::if_poor_simulation(Record::Estimation, Some(1e-3)).is_none());
    }
}
