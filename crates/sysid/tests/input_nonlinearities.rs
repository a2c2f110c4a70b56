//! The input nonlinearities beyond the deadzone (saturation, deadzone + saturation, piecewise-linear,
//! polynomial): exact recovery from noise-free data by every method that fits them, hand-derived
//! regressors and derivatives, warnings, and the model file. The data are generated here by a plain
//! difference-equation loop with the nonlinearities written out by hand, independent of the library.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::Signals;
use sysid::{
    identify, Dataset, Identification, InputSpec, Method, Model, NonlinearityKind, Passes,
};
use sysid::{ModelKind, StaticNonlinearity, Warning};

/// Random levels in [lo, hi] held 1..10 samples.
fn levels(n: usize, lo: f64, hi: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = Vec::with_capacity(n);
    while u.len() < n {
        let v = rng.gen_range(lo..hi);
        let hold = rng.gen_range(1..10);
        u.extend(std::iter::repeat_n(v, hold));
    }
    u.truncate(n);
    u
}

/// y(k) = −Σ a_i y(k−i) + Σ_j b_j x(k−nk−j+1) + c, zero history, x = f(u).
fn simulate(
    u: &[f64],
    f: impl Fn(f64) -> f64,
    a: &[f64],
    b: &[f64],
    nk: usize,
    c: f64,
) -> Vec<f64> {
    let x: Vec<f64> = u.iter().map(|v| f(*v)).collect();
    ipa_testdata::arx_response(&x, a, b, nk, c)
}

fn clamp(u: f64, lo: f64, hi: f64) -> f64 {
    u.max(lo).min(hi)
}

/// x = m clamp(u, −3, 4) with m = 2.
fn saturation(u: f64) -> f64 {
    2.0 * clamp(u, -3.0, 4.0)
}

/// Deadzone (−1, 1.5) with slopes 2 (left) and 1.5 (right), saturating at −4 and 5.
fn deadzone_saturation(u: f64) -> f64 {
    if u >= 5.0 {
        1.5 * (5.0 - 1.5)
    } else if u >= 1.5 {
        1.5 * (u - 1.5)
    } else if u <= -4.0 {
        2.0 * (-4.0 + 1.0)
    } else if u <= -1.0 {
        2.0 * (u + 1.0)
    } else {
        0.0
    }
}

/// Breakpoints −2 and 3, slopes 0.5, 2, 1, through the origin (written segment by segment).
fn piecewise(u: f64) -> f64 {
    if u <= -2.0 {
        0.5 * (u + 2.0) - 2.0 * 2.0
    } else if u <= 3.0 {
        2.0 * u
    } else {
        2.0 * 3.0 + (u - 3.0)
    }
}

/// 1.5 u + 0.1 u² + 0.01 u³ (monotone: 1.5 + 0.2 u + 0.03 u² > 0 for every u).
fn polynomial(u: f64) -> f64 {
    1.5 * u + 0.1 * u * u + 0.01 * u * u * u
}

struct Case {
    kind: NonlinearityKind,
    f: fn(f64) -> f64,
    /// The physical parameters in the block's order.
    want: Vec<f64>,
}

fn cases() -> Vec<Case> {
    vec![
        Case {
            kind: NonlinearityKind::Saturation,
            f: saturation,
            want: vec![-3.0, 4.0, 2.0],
        },
        Case {
            kind: NonlinearityKind::DeadzoneSaturation,
            f: deadzone_saturation,
            want: vec![-1.0, 1.5, -4.0, 5.0, 2.0, 1.5],
        },
        Case {
            kind: NonlinearityKind::PiecewiseLinear { breakpoints: 2 },
            f: piecewise,
            want: vec![-2.0, 3.0, 0.5, 2.0, 1.0],
        },
        Case {
            kind: NonlinearityKind::Polynomial { degree: 3 },
            f: polynomial,
            want: vec![1.5, 0.1, 0.01],
        },
    ]
}

fn close(got: f64, want: f64, tol: f64) -> bool {
    (got - want).abs() <= tol * (1.0 + want.abs())
}

/// Noise-free data of A = 1 − 0.7 q⁻¹ + 0.1 q⁻², B = q⁻¹ (1 + 0.5 q⁻¹) after the case's f, with an
/// offset c when `c` is not 0.
fn data(case: &Case, c: f64, seed: u64) -> Dataset {
    let u = levels(2000, -6.0, 7.0, seed);
    let y = simulate(&u, case.f, &[-0.7, 0.1], &[1.0, 0.5], 1, c);
    Dataset::new(Signals { u, y }, 0.01, "synthetic").unwrap()
}

fn settings(case: &Case, method: Method, offset: bool) -> Identification {
    Identification::default()
        .with_kind(ModelKind::Hammerstein)
        .with_orders(2, 2, 1)
        .with_method(method)
        .with_passes(Passes::AUTO)
        .with_offset(offset)
        .with_inputs(vec![InputSpec {
            nb: 2,
            nk: 1,
            nonlinearity: case.kind,
        }])
}

fn check(case: &Case, method: Method, offset: bool, tol: f64) {
    let c = if offset { 0.3 } else { 0.0 };
    let d = data(case, c, 11);
    let fit = identify(&d, &settings(case, method, offset)).unwrap();
    let m = &fit.model;
    let got = case.kind.block().physical(m.input().nonlinearity());
    let msg = format!("{} by {method:?}: {got:?} {:?}", case.kind, fit.warnings);
    assert_eq!(got.len(), case.want.len(), "{msg}");
    for (g, w) in got.iter().zip(&case.want) {
        assert!(close(*g, *w, tol), "{msg}");
    }
    assert!(
        close(m.a()[0], -0.7, tol) && close(m.a()[1], 0.1, tol),
        "{msg}"
    );
    assert!(close(m.b()[1], 0.5, tol), "{msg}");
    if offset {
        assert!(close(m.offset().unwrap(), c, tol), "{msg}");
    }
    // A true model recovered exactly has no warning (breakpoints between levels, slopes determined).
    assert!(fit.warnings.is_empty(), "{msg}");
    // Each reported physical parameter has a (tiny) standard deviation on noise-free data.
    for p in fit.params.iter().take(case.want.len()) {
        assert!(p.std.is_some_and(|s| s < 1e-6), "{msg}: {p:?}");
    }
}

#[test]
fn least_squares_recovers_every_kind_exactly() {
    for case in cases() {
        check(&case, Method::Ls, false, 1e-8);
        check(&case, Method::Ls, true, 1e-8);
    }
}

#[test]
fn output_error_and_iv_recover_every_kind_exactly() {
    for case in cases() {
        check(&case, Method::Oe, false, 1e-8);
        check(&case, Method::Iv, false, 1e-8);
    }
}

// RLS (passes until settled) on the kinds with at most one breakpoint per side of the range; with more
// breakpoints (deadzone + saturation, piecewise-linear) a pass can settle on a wrong switching (then the
// warnings say so: see below).
#[test]
fn recursive_least_squares_recovers_saturation_and_polynomial() {
    for case in cases() {
        if matches!(
            case.kind,
            NonlinearityKind::Saturation | NonlinearityKind::Polynomial { .. }
        ) {
            check(&case, Method::Rls, false, 1e-8);
        }
    }
}

// Whatever RLS returns on the other kinds, it is either the true model or says it is not.
#[test]
fn recursive_least_squares_on_several_breakpoints_is_right_or_warns() {
    for case in &cases()[1..3] {
        let fit = identify(&data(case, 0.0, 11), &settings(case, Method::Rls, false)).unwrap();
        let got = case.kind.block().physical(fit.model.input().nonlinearity());
        let exact = got.iter().zip(&case.want).all(|(g, w)| close(*g, *w, 1e-6));
        assert!(exact || !fit.warnings.is_empty(), "{} {got:?}", case.kind);
    }
}

// The key-term regressors, derived by hand from each kind's equations, and Σ key term × regressor = f(u).
#[test]
fn key_term_regressors_are_the_hand_derived_ones() {
    let sat = NonlinearityKind::Saturation.block();
    let f = sat.of_physical(&[-1.0, 2.0, 3.0]);
    let mut out = [0.0; 3];
    for (u, want) in [
        (-5.0, [0.0, 1.0, 0.0]), // h_lo = 1
        (0.5, [0.5, 0.0, 0.0]),  // inside: u
        (4.0, [0.0, 0.0, 1.0]),  // h_hi = 1
    ] {
        sat.fill_key_terms(&f, u, &mut out);
        assert_eq!(out, want, "u = {u}");
    }
    // Piecewise: p = (−2, 3), s = (0.5, 2, 1): regressors [u, h1 u, −(h1 − [p1<0]), h2 u, −(h2 − [p2<0])].
    let pwl = NonlinearityKind::PiecewiseLinear { breakpoints: 2 }.block();
    let f = pwl.of_physical(&[-2.0, 3.0, 0.5, 2.0, 1.0]);
    let mut out = [0.0; 5];
    for (u, want) in [
        (-3.0, [-3.0, 0.0, 1.0, 0.0, 0.0]),
        (1.0, [1.0, 1.0, 0.0, 0.0, 0.0]),
        (5.0, [5.0, 5.0, 0.0, 5.0, -1.0]),
    ] {
        pwl.fill_key_terms(&f, u, &mut out);
        assert_eq!(out, want, "u = {u}");
    }
    // Key terms [s0, d1, d1 p1, d2, d2 p2] = [0.5, 1.5, −3, −1, −3].
    assert_eq!(pwl.key_terms(&f), vec![0.5, 1.5, -3.0, -1.0, -3.0]);
    // Deadzone with saturation: [h_r u, −(h_r + H_r), H_r, h_l u, −(h_l + H_l), H_l].
    let dzs = NonlinearityKind::DeadzoneSaturation.block();
    let f = dzs.of_physical(&[-1.0, 1.5, -4.0, 5.0, 2.0, 1.5]);
    let mut out = [0.0; 6];
    for (u, want) in [
        (6.0, [0.0, -1.0, 1.0, 0.0, 0.0, 0.0]),
        (2.0, [2.0, -1.0, 0.0, 0.0, 0.0, 0.0]),
        (0.0, [0.0; 6]),
        (-2.0, [0.0, 0.0, 0.0, -2.0, -1.0, 0.0]),
        (-7.0, [0.0, 0.0, 0.0, 0.0, -1.0, 1.0]),
    ] {
        dzs.fill_key_terms(&f, u, &mut out);
        assert_eq!(out, want, "u = {u}");
    }
    let poly = NonlinearityKind::Polynomial { degree: 3 }.block();
    let mut out = [0.0; 3];
    poly.fill_key_terms(&poly.of_physical(&[1.0, 0.0, 0.0]), -2.0, &mut out);
    assert_eq!(out, [-2.0, 4.0, -8.0]);
    // For every kind: the key terms dotted with the regressors give x = f(u), the hand-written f.
    for case in cases() {
        let b = case.kind.block();
        let f = b.of_physical(&case.want);
        let key = b.key_terms(&f);
        let mut r = vec![0.0; key.len()];
        for i in 0..=260 {
            let u = -6.5 + 0.05 * i as f64;
            b.fill_key_terms(&f, u, &mut r);
            let x: f64 = key.iter().zip(&r).map(|(k, r)| k * r).sum();
            assert!((x - (case.f)(u)).abs() < 1e-12, "{} at u = {u}", case.kind);
            assert!(
                (f.apply(u) - (case.f)(u)).abs() < 1e-12,
                "{} at u = {u}",
                case.kind
            );
        }
    }
}

// ∂x/∂p of each block against central differences of the hand-written f, away from the kinks.
#[test]
fn derivatives_match_finite_differences() {
    for case in cases() {
        let b = case.kind.block();
        let f = b.of_physical(&case.want);
        for which in 0..case.want.len() {
            for u in [-5.5, -3.3, -1.7, 0.4, 2.2, 3.7, 6.1] {
                let h = 1e-6;
                let mut up = case.want.clone();
                up[which] += h;
                let mut dn = case.want.clone();
                dn[which] -= h;
                let fd = (b.of_physical(&up).apply(u) - b.of_physical(&dn).apply(u)) / (2.0 * h);
                let got = b.derivative(&f, which, u);
                assert!(
                    (got - fd).abs() < 1e-6,
                    "{} parameter {which} at u = {u}: {got} vs {fd}",
                    case.kind
                );
            }
        }
    }
}

// Warnings against the input: a saturation limit on an input level, one outside the input range, crossed
// limits, a polynomial that turns inside the range (1 + 0 u − 0.1 u² ... here g = (1, 0, −0.1): f' = 1 −
// 0.3 u² = 0 at u = ±1.826, inside [−3, 3]).
#[test]
fn warnings_name_what_is_wrong() {
    let u: Vec<f64> = vec![-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0];
    let sat = NonlinearityKind::Saturation.block();
    let start = sat.start(&u, false, true, "t").unwrap();
    let (w, no_std) = sat.warnings(&sat.of_physical(&[-2.0, 5.0, 1.0]), &u, &start, &[None; 3]);
    assert!(
        w.iter()
            .any(|w| matches!(w, Warning::BreakpointOnInputLevel { value, .. } if *value == -2.0)),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|w| matches!(w, Warning::BreakpointNotBracketed { value, .. } if *value == 5.0)),
        "{w:?}"
    );
    assert_eq!(no_std.len(), 2);
    let (w, _) = sat.warnings(&sat.of_physical(&[1.5, -1.5, 1.0]), &u, &start, &[None; 3]);
    assert!(
        w.iter()
            .any(|w| w.to_string().contains("s_l = 1.5 >= s_r = -1.5")),
        "{w:?}"
    );
    let poly = NonlinearityKind::Polynomial { degree: 3 }.block();
    let start = poly.start(&u, false, true, "t").unwrap();
    let (w, _) = poly.warnings(&poly.of_physical(&[1.0, 0.0, -0.1]), &u, &start, &[None; 3]);
    let turn = (1.0_f64 / 0.3).sqrt();
    match &w[..] {
        [Warning::NonlinearityShape { why, .. }] => {
            let at: f64 = why
                .split("near u = ")
                .nth(1)
                .unwrap()
                .split(')')
                .next()
                .unwrap()
                .parse()
                .unwrap();
            assert!((at.abs() - turn).abs() < 6.0 / 512.0 + 1e-9, "{why}");
        }
        other => panic!("{other:?}"),
    }
    let (w, _) = poly.warnings(&poly.of_physical(&[1.0, 0.0, 0.1]), &u, &start, &[None; 3]);
    assert!(w.is_empty(), "a monotone cubic: {w:?}");
    // A piecewise-linear segment without two levels: p = (2.5, 2.8) leaves none between them.
    let pwl = NonlinearityKind::PiecewiseLinear { breakpoints: 2 }.block();
    let start = pwl.start(&u, false, true, "t").unwrap();
    let (w, _) = pwl.warnings(
        &pwl.of_physical(&[2.5, 2.8, 1.0, 1.0, 1.0]),
        &u,
        &start,
        &[None; 5],
    );
    assert!(
        w.iter().any(|w| w.to_string().contains("segment 1")),
        "{w:?}"
    );
}

// Model files: each kind is written under `nonlinearity` and reads back equal; a deadzone keeps its
// `deadzone` key; too many breakpoints and two nonlinearity keys are refused with a message.
#[test]
fn model_files_round_trip_every_kind() {
    for case in cases() {
        let f = case.kind.block().of_physical(&case.want);
        let input = sysid::InputChannel::new("u", 1, vec![1.0, 0.5], f).unwrap();
        let m = Model::new(0.01, vec![-0.7, 0.1], vec![input], Some(0.3)).unwrap();
        let text = serde_json::to_string(&m).unwrap();
        assert!(
            text.contains(&format!("\"kind\":\"{}\"", case.kind)),
            "{text}"
        );
        let back: Model = serde_json::from_str(&text).unwrap();
        assert_eq!(back, m);
        assert_eq!(back.parameter_count(), 2 + 1 + case.want.len() + 1);
    }
    let too_many = r#"{"kind":"hammerstein","ts":0.01,"na":0,"nb":1,"nk":1,"a":[],"b":[1.0],"offset":null,
        "nonlinearity":{"kind":"piecewise-linear","breakpoints":[1,2,3,4,5,6,7,8,9],"slopes":[1,1,1,1,1,1,1,1,1,1]}}"#;
    let e = serde_json::from_str::<Model>(too_many)
        .unwrap_err()
        .to_string();
    assert!(e.contains("1 to 8 breakpoints"), "{e}");
    let both = r#"{"kind":"hammerstein","ts":0.01,"na":0,"nb":1,"nk":1,"a":[],"b":[1.0],"offset":null,
        "deadzone":{"b_l":-1,"b_r":1,"m_l":1,"m_r":1},"nonlinearity":{"kind":"polynomial","coefficients":[1]}}"#;
    let e = serde_json::from_str::<Model>(both).unwrap_err().to_string();
    assert!(e.contains("both a deadzone and a nonlinearity"), "{e}");
    // An older deadzone file (no nonlinearity key) still loads.
    let old = r#"{"kind":"hammerstein","ts":0.01,"na":1,"nb":1,"nk":1,"a":[-0.5],"b":[1.0],"offset":null,
        "deadzone":{"b_l":-1,"b_r":1,"m_l":1,"m_r":2}}"#;
    let m: Model = serde_json::from_str(old).unwrap();
    assert!(matches!(
        m.input().nonlinearity(),
        StaticNonlinearity::Deadzone(_)
    ));
}

// `--breakpoints auto` (K = 0): on the piecewise-linear case (K = 2 true) with white output noise of
// σ = 0.05, K = 1 cannot fit the two kinks and K = 3, 4 add parameters the data do not need; the smallest
// AIC is K = 2, and the note lists every K tried.
#[test]
fn auto_breakpoints_choose_k_by_the_estimation_aic() {
    let case = &cases()[2];
    let clean = data(case, 0.0, 11);
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let y: Vec<f64> = clean
        .y()
        .iter()
        .map(|v| v + 0.05 * (rng.gen::<f64>() + rng.gen::<f64>() + rng.gen::<f64>() - 1.5) * 2.0)
        .collect();
    let noisy = Dataset::new(
        Signals {
            u: clean.u().to_vec(),
            y,
        },
        0.01,
        "noisy",
    )
    .unwrap();
    let auto = Case {
        kind: NonlinearityKind::PiecewiseLinear {
            breakpoints: sysid::blocks::AUTO_BREAKPOINTS,
        },
        f: piecewise,
        want: Vec::new(),
    };
    let fit = identify(&noisy, &settings(&auto, Method::Ls, false)).unwrap();
    let StaticNonlinearity::PiecewiseLinear(p) = fit.model.input().nonlinearity() else {
        panic!("{:?}", fit.model);
    };
    assert_eq!(p.breakpoints().len(), 2, "{:?}", fit.notes);
    let note = fit.note().unwrap();
    assert!(note.contains("K = 2 chosen by the smallest AIC"), "{note}");
    for k in 1..=4 {
        assert!(note.contains(&format!("K = {k}: ")), "{note}");
    }
}

// K and D out of range are refused by name before any data are read (K = 0 is `auto`).
#[test]
fn breakpoints_and_degree_out_of_range_are_refused() {
    let bad = [
        (
            NonlinearityKind::PiecewiseLinear { breakpoints: 9 },
            "--breakpoints",
        ),
        (NonlinearityKind::Polynomial { degree: 0 }, "--degree"),
        (NonlinearityKind::Polynomial { degree: 9 }, "--degree"),
    ];
    for (kind, flag) in bad {
        let s = Identification::default().with_inputs(vec![InputSpec {
            nb: 1,
            nk: 1,
            nonlinearity: kind,
        }]);
        let e = s.check().unwrap_err().to_string();
        assert!(e.contains(flag), "{e}");
    }
}
