//! The output nonlinearity y = g(v) (Wiener, Hammerstein–Wiener): recovery from noise-free data (the
//! quantities that do not depend on the scale shared by g and the linear block), the model's own
//! simulation and plant against a hand-written loop, the model file, warnings and refusals. Data are
//! generated here by plain loops, independent of the library.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::Signals;
use sysid::wiener::output_warnings;
use sysid::{identify, Dataset, Identification, InputSpec, Method, Model, NonlinearityKind};
use sysid::{InputChannel, ModelKind, Plant, StaticNonlinearity, Warning};

fn levels(n: usize, lo: f64, hi: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = Vec::with_capacity(n);
    while u.len() < n {
        let v = rng.gen_range(lo..hi);
        u.extend(std::iter::repeat_n(v, rng.gen_range(3..15)));
    }
    u.truncate(n);
    u
}

/// v(k) = 1.2 v(k−1) − 0.5 v(k−2) + 0.3 x(k−1) + 0.1 x(k−2), x = f(u), y = g(v), zero history.
fn wiener(u: &[f64], f: impl Fn(f64) -> f64, g: impl Fn(f64) -> f64) -> (Vec<f64>, Vec<f64>) {
    let x: Vec<f64> = u.iter().map(|v| f(*v)).collect();
    let mut v = vec![0.0; u.len()];
    for k in 2..u.len() {
        v[k] = 1.2 * v[k - 1] - 0.5 * v[k - 2] + 0.3 * x[k - 1] + 0.1 * x[k - 2];
    }
    let y = v.iter().map(|v| g(*v)).collect();
    (v, y)
}

fn settings(input: NonlinearityKind, output: NonlinearityKind) -> Identification {
    Identification::default()
        .with_kind(ModelKind::Arx)
        .with_orders(2, 2, 1)
        .with_method(Method::Ls)
        .with_inputs(vec![InputSpec {
            nb: 2,
            nk: 1,
            nonlinearity: input,
        }])
        .with_output_nonlinearity(Some(output))
}

fn close(got: f64, want: f64, tol: f64) -> bool {
    (got - want).abs() <= tol * (1.0 + want.abs())
}

// Wiener with an output saturation at −1 and 2: the fit holds g's gain m at its least-squares value, so
// the data determine A, m·B and the limits of y, m·s_l = −1 and m·s_r = 2.
#[test]
fn a_wiener_saturation_is_recovered_up_to_the_shared_scale() {
    let u = levels(2000, -3.0, 4.0, 2);
    let (_, y) = wiener(&u, |u| u, |v| v.clamp(-1.0, 2.0));
    let data = Dataset::new(Signals { u, y }, 0.1, "wiener").unwrap();
    let fit = identify(
        &data,
        &settings(NonlinearityKind::Linear, NonlinearityKind::Saturation),
    )
    .unwrap();
    let m = &fit.model;
    let Some(StaticNonlinearity::Saturation(g)) = m.output_nonlinearity().copied() else {
        panic!("{m:?}");
    };
    let msg = format!("{m:?} {:?}", fit.warnings);
    assert!(
        close(m.a()[0], -1.2, 1e-8) && close(m.a()[1], 0.5, 1e-8),
        "{msg}"
    );
    assert!(
        close(g.m * m.b()[0], 0.3, 1e-8) && close(g.m * m.b()[1], 0.1, 1e-8),
        "{msg}"
    );
    assert!(
        close(g.m * g.s_l, -1.0, 1e-8) && close(g.m * g.s_r, 2.0, 1e-8),
        "{msg}"
    );
    assert!(fit.warnings.is_empty(), "{msg}");
    assert_eq!(fit.method, Method::Oe);
    // g's gain is reported without a standard deviation (fixed); s_l, s_r with one.
    let out: Vec<_> = fit
        .params
        .iter()
        .filter(|p| p.input.as_deref() == Some("output"))
        .collect();
    assert_eq!(out.len(), 3);
    assert!(out[0].std.is_some() && out[1].std.is_some() && out[2].std.is_none());
    // p counts A, B and the two free limits.
    assert_eq!(m.parameter_count(), 2 + 2 + 2);
    // Kept as `--method oe` keeps its refinement: on the RMSE pooled over both initial states,
    // √((RMSE_est² + RMSE_meas²)/2), pooled here from each model's two simulation RMSEs; the start is
    // the same structure without the output nonlinearity.
    let pooled = |model: &Model| {
        let mm = sysid::metrics::metrics(model, &data).unwrap();
        let (a, b) = (mm.rmse_sim.unwrap(), mm.rmse_sim_measured.unwrap());
        ((a * a + b * b) / 2.0).sqrt()
    };
    let start = identify(
        &data,
        &settings(NonlinearityKind::Linear, NonlinearityKind::Linear)
            .with_output_nonlinearity(None),
    )
    .unwrap();
    let Some(sysid::Note::KeptCandidate {
        rmse,
        criterion,
        others,
        ..
    }) = fit
        .notes
        .iter()
        .find(|n| matches!(n, sysid::Note::KeptCandidate { .. }))
    else {
        panic!("{:?}", fit.notes);
    };
    assert_eq!(*criterion, sysid::fitted::POOLED_CRITERION);
    assert!(close(*rmse, pooled(m), 1e-9), "{rmse} vs {}", pooled(m));
    let start_rmse = others[0].1.unwrap();
    assert!(
        close(start_rmse, pooled(&start.model), 1e-9),
        "{start_rmse} vs {}",
        pooled(&start.model)
    );
    assert!(*rmse < start_rmse);
}

// Hammerstein–Wiener: an input saturation at (−2, 3) and an output polynomial v + 0.2 v². The scale
// shared by g and the input block: g1 and m_in, with g1·m_in·b = (0.3, 0.1)·… and g2 / g1² = 0.2 / s²
// where s = the input slope scale. The invariants checked: A, the input limits, and y itself (fit 100 %).
#[test]
fn a_hammerstein_wiener_model_is_recovered() {
    let u = levels(2000, -4.0, 5.0, 5);
    let (_, y) = wiener(&u, |u| u.clamp(-2.0, 3.0), |v| v + 0.2 * v * v);
    let data = Dataset::new(Signals { u, y }, 0.1, "hw").unwrap();
    let fit = identify(
        &data,
        &settings(
            NonlinearityKind::Saturation,
            NonlinearityKind::Polynomial { degree: 2 },
        ),
    )
    .unwrap();
    let m = &fit.model;
    let msg = format!("{m:?} {:?}", fit.warnings);
    assert!(
        close(m.a()[0], -1.2, 1e-7) && close(m.a()[1], 0.5, 1e-7),
        "{msg}"
    );
    let StaticNonlinearity::Saturation(f) = *m.input().nonlinearity() else {
        panic!("{msg}");
    };
    assert!(close(f.s_l, -2.0, 1e-7) && close(f.s_r, 3.0, 1e-7), "{msg}");
    let Some(StaticNonlinearity::Polynomial(g)) = m.output_nonlinearity().copied() else {
        panic!("{msg}");
    };
    // v_fit = v_true / g1 (the B of the fit carries 1/g1 of the true gain, b1 = 1 fixed, so m_in·b2 …):
    // g(v_fit) = g1 v_fit + g2 v_fit² = v + 0.2 v² means g2 / g1² = 0.2, and m_in = 0.3 / g1.
    let (g1, g2) = (g.coefficients()[0], g.coefficients()[1]);
    assert!(close(g2 / (g1 * g1), 0.2, 1e-7), "{msg}");
    assert!(
        close(f.m * g1, 0.3, 1e-7) && close(m.b()[1], 1.0 / 3.0, 1e-7),
        "{msg}"
    );
    let sim = m.simulate(&[data.u()], data.y()).unwrap();
    let worst = sim
        .iter()
        .zip(data.y())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-7, "{worst}");
}

// The model's simulation and plant apply g after the linear block, as a hand-written loop does.
#[test]
fn simulation_and_plant_apply_the_output_nonlinearity() {
    let g = StaticNonlinearity::Saturation(sysid::nonlinearity::Saturation {
        s_l: -0.5,
        s_r: 0.8,
        m: 1.5,
    });
    let input = InputChannel::new("u", 1, vec![0.4, 0.2], StaticNonlinearity::Linear).unwrap();
    let model = Model::new(0.1, vec![-1.2, 0.5], vec![input], Some(0.05))
        .unwrap()
        .with_output_nonlinearity(Some(g))
        .unwrap();
    let u = levels(300, -3.0, 4.0, 9);
    // Loop: v from rest (v = 0), y = 1.5 clamp(v, −0.5, 0.8).
    let mut v = vec![0.0; u.len()];
    for k in 2..u.len() {
        v[k] = 1.2 * v[k - 1] - 0.5 * v[k - 2] + 0.4 * u[k - 1] + 0.2 * u[k - 2] + 0.05;
    }
    let want: Vec<f64> = v.iter().map(|v| 1.5 * v.clamp(-0.5, 0.8)).collect();
    // simulate from measured initial outputs v(0) = v(1) = 0 (the first two y are copied).
    let sim = model.simulate(&[&u], &vec![0.0; u.len()]).unwrap();
    for k in 2..u.len() {
        assert!((sim[k] - want[k]).abs() < 1e-12, "k = {k}");
    }
    // The plant from rest (v = 0 and u = 0 before k = 0): y(k) before applying u(k).
    let at = |s: &[f64], k: isize| if k < 0 { 0.0 } else { s[k as usize] };
    let mut w = vec![0.0; u.len()];
    for k in 1..u.len() as isize {
        w[k as usize] = 1.2 * at(&w, k - 1) - 0.5 * at(&w, k - 2)
            + 0.4 * at(&u, k - 1)
            + 0.2 * at(&u, k - 2)
            + 0.05;
    }
    let mut plant = sysid::ModelPlant::new(model.clone(), "m").unwrap();
    plant.reset(0.0);
    for (k, uk) in u.iter().enumerate().take(u.len() - 1) {
        let want = 1.5 * w[k].clamp(-0.5, 0.8);
        assert!((plant.output() - want).abs() < 1e-12, "k = {k}");
        plant.step(*uk).unwrap();
    }
    // The model file keeps g; a model without one has no key.
    let text = serde_json::to_string(&model).unwrap();
    assert!(
        text.contains("\"output_nonlinearity\":{\"kind\":\"saturation\""),
        "{text}"
    );
    assert_eq!(serde_json::from_str::<Model>(&text).unwrap(), model);
    let plain = Model::arx(0.1, vec![-0.5], vec![1.0], 1, None).unwrap();
    assert!(!serde_json::to_string(&plain)
        .unwrap()
        .contains("output_nonlinearity"));
    // A deadzone is not an output nonlinearity.
    let dz = StaticNonlinearity::Deadzone(sysid::Deadzone {
        b_l: -1.0,
        b_r: 1.0,
        m_l: 1.0,
        m_r: 1.0,
    });
    assert!(plain.with_output_nonlinearity(Some(dz)).is_err());
}

// Audit s31 M-1: a free run from measured initial outputs starts the linear block at v(k) = g⁻¹(y(k))
// for k < k0, not at y(k) (a gain m = 1.5 would start the state 50 % off). Measured y(0) = 0.9,
// y(1) = 1.05 are 1.5 · v with v = 0.6, 0.7 (inside the limits); the recursion goes on from those.
#[test]
fn measured_initial_outputs_enter_the_linear_block_through_the_inverse_of_g() {
    let g = StaticNonlinearity::Saturation(sysid::nonlinearity::Saturation {
        s_l: -0.5,
        s_r: 0.8,
        m: 1.5,
    });
    let input = InputChannel::new("u", 1, vec![0.4, 0.2], StaticNonlinearity::Linear).unwrap();
    let model = Model::new(0.1, vec![-1.2, 0.5], vec![input], Some(0.05))
        .unwrap()
        .with_output_nonlinearity(Some(g))
        .unwrap();
    let u = levels(200, -3.0, 4.0, 11);
    let mut v = vec![0.6, 0.7];
    for k in 2..u.len() {
        v.push(1.2 * v[k - 1] - 0.5 * v[k - 2] + 0.4 * u[k - 1] + 0.2 * u[k - 2] + 0.05);
    }
    let mut y = vec![0.9, 1.05];
    y.resize(u.len(), 0.0);
    let sim = model.simulate(&[&u], &y).unwrap();
    for k in 2..u.len() {
        let want = 1.5 * v[k].clamp(-0.5, 0.8);
        assert!(
            (sim[k] - want).abs() < 1e-12,
            "k = {k}: {} vs {want}",
            sim[k]
        );
    }
    let lin = model.simulate_linear_part(&[&u], &y).unwrap();
    for k in 0..u.len() {
        assert!((lin[k] - v[k]).abs() < 1e-12, "k = {k}");
    }
    // A plant reset to rest at y0 = 0.9 outputs 0.9 (v = 0.6 inside), not g(0.9) = 1.2 (clamped).
    let mut plant = sysid::ModelPlant::new(model, "m").unwrap();
    plant.reset(0.9);
    assert!((plant.output() - 0.9).abs() < 1e-12, "{}", plant.output());
}

// g⁻¹ of every output map kind: f(preimage(x)) = x where x is in f's range; the root nearest x for a
// map that turns (x = 0.375 under v − 0.5 v²: roots 0.5 and 1.5, nearest 0.5); beyond the range the
// nearest value f reaches (saturation: the limit).
#[test]
fn the_preimage_of_each_output_map() {
    let sat = StaticNonlinearity::Saturation(sysid::nonlinearity::Saturation {
        s_l: -1.0,
        s_r: 2.0,
        m: 3.0,
    });
    assert_eq!(sat.preimage(1.5), 0.5);
    assert_eq!(sat.preimage(9.0), 2.0);
    assert_eq!(sat.preimage(-7.0), -1.0);
    let poly =
        StaticNonlinearity::Polynomial(sysid::nonlinearity::Polynomial::new(&[1.0, -0.5]).unwrap());
    let r = poly.preimage(0.375);
    assert!((r - 0.5).abs() < 1e-12, "{r}");
    let cubic = StaticNonlinearity::Polynomial(
        sysid::nonlinearity::Polynomial::new(&[2.0, 0.0, 0.1]).unwrap(),
    );
    for x in [-30.0, -1.0, 0.0, 0.3, 7.0, 250.0] {
        let v = cubic.preimage(x);
        assert!(
            (cubic.apply(v) - x).abs() < 1e-9 * (1.0 + x.abs()),
            "{x}: {v}"
        );
    }
}

// Warnings on g against the range of v: a limit outside it; a polynomial that turns inside it
// (1 v − 0.5 v²: g' = 0 at v = 1, inside [−2, 2]); a monotone map passes.
#[test]
fn output_warnings_name_undetermined_limits_and_turning_maps() {
    let v: Vec<f64> = (0..=40).map(|i| -2.0 + 0.1 * i as f64).collect();
    let sat = StaticNonlinearity::Saturation(sysid::nonlinearity::Saturation {
        s_l: -1.0,
        s_r: 3.0,
        m: 1.0,
    });
    let w = output_warnings(&sat, &v);
    assert!(
        matches!(&w[..], [Warning::NonlinearityShape { why, .. }] if why.starts_with("s_r = 3.")),
        "{w:?}"
    );
    let turn =
        StaticNonlinearity::Polynomial(sysid::nonlinearity::Polynomial::new(&[1.0, -0.5]).unwrap());
    let w = output_warnings(&turn, &v);
    assert!(
        w.len() == 1 && w[0].to_string().contains("not monotone"),
        "{w:?}"
    );
    let mono =
        StaticNonlinearity::Polynomial(sysid::nonlinearity::Polynomial::new(&[1.0, 0.1]).unwrap());
    assert!(output_warnings(&mono, &v).is_empty());
}

// A deadzone output, and merged records, are refused by name.
#[test]
fn unsupported_output_structures_are_refused() {
    let s = settings(NonlinearityKind::Linear, NonlinearityKind::Deadzone);
    let e = s.check().unwrap_err().to_string();
    assert!(e.contains("--output-nonlinearity"), "{e}");
    let u = levels(300, -3.0, 4.0, 3);
    let (_, y) = wiener(&u, |u| u, |v| v);
    let a = Dataset::new(
        Signals {
            u: u.clone(),
            y: y.clone(),
        },
        0.1,
        "a",
    )
    .unwrap();
    let b = Dataset::new(Signals { u, y }, 0.1, "b").unwrap();
    let e = identify(
        &[a, b][..],
        &settings(NonlinearityKind::Linear, NonlinearityKind::Saturation),
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("one record"), "{e}");
}

// Audit s31 M-2: a fitted output saturation whose limits lie inside the measured output's range is said
// (the samples beyond them counted here by hand); limits around every sample, or a handful beyond
// (fewer than 1 % or 5), say nothing.
#[test]
fn output_limits_inside_the_measured_range_are_said() {
    let g = StaticNonlinearity::Saturation(sysid::nonlinearity::Saturation {
        s_l: 1.6,
        s_r: 4.8,
        m: 2.0,
    });
    // 101 outputs 2.9, 2.97, …, 9.9 (step 0.07); the limits are 2 · 1.6 = 3.2 and 2 · 4.8 = 9.6: below
    // are 2.9, 2.97, 3.04, 3.11, 3.18 (5), above 9.62, 9.69, 9.76, 9.83, 9.9 (5).
    let y: Vec<f64> = (0..101).map(|i| 2.9 + 0.07 * f64::from(i)).collect();
    let w = sysid::wiener::output_limit_warning(&g, &y, 0.0).expect("a warning");
    let text = w.to_string();
    assert!(text.contains("5 samples below and 5 above"), "{text}");
    // With an operating point the limits and range are printed in the record's units.
    let dy: Vec<f64> = y.iter().map(|v| v - 1.0).collect();
    let w = sysid::wiener::output_limit_warning(&g, &dy, 1.0).expect("a warning");
    assert!(w.to_string().contains("(4.2 .. 10.6)"), "{w}");
    let wide = StaticNonlinearity::Saturation(sysid::nonlinearity::Saturation {
        s_l: 1.0,
        s_r: 6.0,
        m: 2.0,
    });
    assert!(sysid::wiener::output_limit_warning(&wide, &y, 0.0).is_none());
    // Four samples beyond: fewer than 5.
    let mut few = vec![5.0; 400];
    few[..4].iter_mut().for_each(|v| *v = 20.0);
    assert!(sysid::wiener::output_limit_warning(&g, &few, 0.0).is_none());
}
