//! Trustworthy estimates (issue "no confidently wrong model"): the output-error search stays stable and
//! never does worse than its least-squares start on the reported criterion; Hammerstein estimates that
//! blow up carry a warning (or fall back); residual tests tell output error from equation error; the
//! default recursive identification converges. Real records are read from `../shared/data` at run time
//! and the tests that need them skip, saying so, when the folder is absent.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests may panic

use std::path::Path;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::{read_csv, CsvOptions, Signals};
use sysid::metrics::metrics;
use sysid::residuals::residual_analysis;
use sysid::{identify, Identification, Method};
use sysid::{Dataset, Model, ModelKind, Warning};

fn read(path: &Path, u: &str, y: &str, ts: f64) -> Dataset {
    let opts = CsvOptions {
        u_col: u.into(),
        y_col: y.into(),
        t_col: "t".into(),
        ts: Some(ts),
        fallback_ts: None,
        ..CsvOptions::default()
    };
    read_csv(path, &opts).unwrap()
}

/// Rows `a..b` of a record.
fn rows(d: &Dataset, a: usize, b: usize) -> Dataset {
    Dataset::new(
        Signals {
            u: d.u()[a..b].to_vec(),
            y: d.y()[a..b].to_vec(),
        },
        d.ts(),
        format!("{}[{a}..{b}]", d.name()),
    )
    .unwrap()
}

fn arx(na: usize, nb: usize, nk: usize, method: Method) -> Identification {
    Identification::default()
        .with_kind(ModelKind::Arx)
        .with_orders(na, nb, nk)
        .with_offset(true)
        .with_method(method)
}

/// The records of the table, split as each SOURCE.md gives: (name, estimation, orders).
fn table_cases(dir: &Path) -> Vec<(&'static str, Dataset, (usize, usize, usize))> {
    let arm = read(&dir.join("robot_arm_flexible/robot_arm.csv"), "u", "y", 1.0);
    let bb = read(&dir.join("ball_and_beam/ballbeam.csv"), "u", "y", 1.0);
    let dryer = read(&dir.join("hair_dryer_pt326/dryer.csv"), "u", "y", 1.0);
    let emps = read(&dir.join("emps/DATA_EMPS.csv"), "vir", "qm", 0.001);
    let hydraulic = read(&dir.join("hydraulic_actuator/actuator.csv"), "u", "p", 1.0);
    let drives = read(
        &dir.join("coupled_electric_drives_prbs/DATAPRBS.csv"),
        "u1",
        "z1",
        0.02,
    );
    let tanks = read(
        &dir.join("cascaded_tanks/dataBenchmark.csv"),
        "uEst",
        "yEst",
        4.0,
    );
    vec![
        // Beyond the table: other structures on other records.
        (
            "hydraulic actuator (3,2,1)",
            rows(&hydraulic, 0, 512),
            (3, 2, 1),
        ),
        ("coupled drives (2,2,1)", rows(&drives, 0, 250), (2, 2, 1)),
        ("cascaded tanks (4,3,0)", tanks, (4, 3, 0)),
        ("robot arm (8,7,1)", rows(&arm, 0, 512), (8, 7, 1)),
        ("robot arm (12,10,0)", rows(&arm, 0, 512), (12, 10, 0)),
        ("EMPS (6,5,0)", emps, (6, 5, 0)),
        ("ball and beam (2,2,1)", rows(&bb, 0, 500), (2, 2, 1)),
        ("hair dryer (3,5,2)", rows(&dryer, 0, 500), (3, 5, 2)),
    ]
}

/// The simulation RMSE neither initial state flatters: the larger of the RMSEs from estimated and from
/// measured initial outputs (the criterion output error judges its candidates on, issue 22).
/// √((RMSE_est² + RMSE_meas²)/2), computed here from the two RMSEs: the criterion output error keeps its
/// candidates on since audit s18 M-7 (before: the larger of the two).
fn pooled_rmse(model: &Model, data: &Dataset) -> Option<f64> {
    let m = metrics(model, data).ok()?;
    let (a, b) = (m.rmse_sim?, m.rmse_sim_measured?);
    Some(((a * a + b * b) / 2.0).sqrt())
}

/// A refinement within this relative margin of its start is kept (`methods::OE_VERDICT_TOLERANCE`).
const KEPT_WITHIN: f64 = 0.01;

// On every record of the table, output error with an offset returns a stable model whose estimation
// simulation RMSE pooled over both initial states (the criterion it keeps its candidates on) is not
// above least squares' by more than the 1 % a refinement is allowed; it converges within its cap or
// warns that it did not.
#[test]
fn output_error_is_stable_and_never_worse_than_least_squares_on_real_records() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    for (name, est, (na, nb, nk)) in table_cases(&dir) {
        let ls = identify(&est, &arx(na, nb, nk, Method::Ls)).unwrap();
        let oe = identify(&est, &arx(na, nb, nk, Method::Oe)).unwrap();
        let rmse_ls = pooled_rmse(&ls.model, &est).unwrap();
        let rmse_oe = pooled_rmse(&oe.model, &est).unwrap();
        // The poles, computed independently of the search's stability test.
        let max_pole = oe
            .model
            .poles()
            .iter()
            .map(|p| p.norm())
            .fold(0.0, f64::max);
        // Stable as the tool's verdict says it: not an integrator either (a pole within 1e-5 of the
        // unit circle; audit s35c: ball and beam returned a refinement held at |p| = 1 − 1e-6, 0.6 %
        // worse than its stable start, until session 35).
        assert!(max_pole < 1.0 - 1e-5, "{name}: OE pole modulus {max_pole}");
        assert!(
            rmse_oe <= rmse_ls * (1.0 + KEPT_WITHIN + 1e-12),
            "{name}: OE {rmse_oe} > LS {rmse_ls}"
        );
        // Converged, or it says it did not (since session 34 a model with an input nonlinearity keeps
        // the lower end of the searches from the LS and the IV starts even at the iteration cap; these
        // ARX cases search from LS only).
        assert!(
            oe.converged()
                || oe
                    .warnings
                    .iter()
                    .any(|w| matches!(w, Warning::NotConverged { .. })),
            "{name}: {:?}",
            oe.note()
        );
        assert!(
            !oe.warnings
                .iter()
                .any(|w| matches!(w, Warning::Unstable { .. })),
            "{name}"
        );
    }
}

// Key-term LS on the Hammerstein structure blows up on these records (issue table: robot arm (8,7,1)
// with offset, gas furnace (2,2,3), cascaded tanks (2,4,1) without offset): whenever the estimate
// simulates worse than the record's mean, diverges or is unstable, it carries a warning; with the
// fallback on, the result simulates at least as well as the linear ARX start minus the margin.
#[test]
fn blown_up_hammerstein_estimates_are_never_silent() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let arm = read(&dir.join("robot_arm_flexible/robot_arm.csv"), "u", "y", 1.0);
    let gas = read(
        &dir.join("gas_furnace_box_jenkins/gas_furnace.csv"),
        "InputGasRate",
        "CO2",
        9.0,
    );
    let tanks = read(
        &dir.join("cascaded_tanks/dataBenchmark.csv"),
        "uEst",
        "yEst",
        4.0,
    );
    let cases = [
        ("robot arm", rows(&arm, 0, 512), (8, 7, 1), true),
        ("gas furnace", rows(&gas, 0, 148), (2, 2, 3), false),
        ("cascaded tanks", tanks, (2, 4, 1), false),
    ];
    for (name, est, (na, nb, nk), offset) in cases {
        for fallback in [false, true] {
            let s = Identification {
                drop_unexcited_branch: true,
                fallback,
                ..Identification::default()
            }
            .with_orders(na, nb, nk)
            .with_offset(offset)
            .with_method(Method::Ls);
            let fit = identify(&est, &s).unwrap();
            let m = metrics(&fit.model, &est).unwrap();
            let bad = m.fit_sim_percent.is_none_or(|f| f < 0.0) || !fit.model.stability().settles();
            assert!(!bad || !fit.warnings.is_empty(), "{name}: silent {m:?}");
            // The linear start, computed here on its own.
            let lin = identify(
                &est,
                &Identification::default()
                    .with_kind(ModelKind::Arx)
                    .with_orders(na, nb, nk)
                    .with_offset(offset)
                    .with_method(Method::Ls),
            )
            .unwrap();
            let lin_fit = metrics(&lin.model, &est).unwrap().fit_sim_percent.unwrap();
            let got = m.fit_sim_percent.unwrap_or(f64::NEG_INFINITY);
            if fallback {
                assert!(
                    got >= lin_fit - sysid::estimate::FALLBACK_FIT_MARGIN - 1e-9,
                    "{name}: fallback result {got} vs linear {lin_fit}"
                );
            } else if got < lin_fit - sysid::estimate::FALLBACK_FIT_MARGIN {
                assert!(
                    fit.warnings
                        .iter()
                        .any(|w| matches!(w, Warning::LinearStartBetter { .. })),
                    "{name}: {:?}",
                    fit.warnings
                );
            }
        }
    }
}

/// y = B/A u + e with e white: a stable second-order output-error system.
fn oe_system(seed: u64) -> Dataset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = 3000;
    let u: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let mut x = vec![0.0; n];
    for k in 2..n {
        x[k] = 1.5 * x[k - 1] - 0.7 * x[k - 2] + u[k - 1] + 0.5 * u[k - 2];
    }
    let y: Vec<f64> = x
        .iter()
        .map(|v| v + 0.5 * rng.gen_range(-1.0..1.0))
        .collect();
    Dataset::new(Signals { u, y }, 1.0, "oe system").unwrap()
}

fn verdicts(model: &Model, data: &Dataset) -> (bool, bool) {
    match residual_analysis(model, data, 25) {
        Ok(a) => (a.white, a.independent),
        Err(error) => panic!("{error}"),
    }
}

// On an output-error system (white noise added at the output), the residuals of the output-error
// estimate are white and independent of the input, and those of equation-error least squares on the
// same data are not white (their equation error is A(q) e, coloured).
#[test]
fn residual_tests_tell_output_error_from_equation_error() {
    for seed in [1, 2, 3] {
        let data = oe_system(seed);
        let s = |m| {
            Identification::default()
                .with_kind(ModelKind::Arx)
                .with_orders(2, 2, 1)
                .with_method(m)
        };
        let oe = identify(&data, &s(Method::Oe)).unwrap();
        let ls = identify(&data, &s(Method::Ls)).unwrap();
        let (white, independent) = verdicts(&oe.model, &data);
        assert!(
            white && independent,
            "seed {seed}: OE residuals {white} {independent}"
        );
        let (white, _) = verdicts(&ls.model, &data);
        assert!(!white, "seed {seed}: LS residuals judged white");
    }
}

fn paper_record(n: usize, seed: u64) -> Dataset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = Vec::with_capacity(n);
    while u.len() < n {
        let level = rng.gen_range(-40i32..=40) as f64;
        let hold = rng.gen_range(10..50);
        for _ in 0..hold.min(n - u.len()) {
            u.push(level);
        }
    }
    let y = Model::paper().simulate(&[&u], &vec![0.0; n]).unwrap();
    Dataset::new(Signals { u, y }, 0.01, "paper").unwrap()
}

// The default identification (RLS, passes until settled) on noise-free data of the paper's model
// converges and recovers it to 1e-8 relative; the paper's single pass does not settle and says so.
#[test]
fn default_identification_converges_exactly_on_the_paper_model() {
    let data = paper_record(2000, 7);
    let fit = identify(&data, &Identification::default()).unwrap();
    assert!(fit.converged(), "{:?}", fit.note());
    assert!(fit.warnings.is_empty(), "{:?}", fit.warnings);
    let truth = Model::paper();
    let (d, t) = (fit.model.deadzone().unwrap(), truth.deadzone().unwrap());
    for (got, want) in [
        (d.b_l, t.b_l),
        (d.b_r, t.b_r),
        (d.m_l, t.m_l),
        (d.m_r, t.m_r),
    ]
    .into_iter()
    .chain(fit.model.a().iter().copied().zip(truth.a().iter().copied()))
    {
        assert!((got - want).abs() <= 1e-8 * want.abs(), "{got} vs {want}");
    }
    let single = Identification::default().with_passes(sysid::Passes::Fixed(1));
    let fit1 = identify(&data, &single).unwrap();
    if !fit1.converged() {
        assert!(
            fit1.warnings
                .iter()
                .any(|w| matches!(w, Warning::NotConverged { .. })),
            "{:?}",
            fit1.warnings
        );
    }
}

// An unstable estimate is flagged: ARX(1,1,1) on a record that grows geometrically, y(k) = 1.05 y(k−1)
// + u(k−1), has its pole at 1.05.
#[test]
fn an_unstable_model_is_flagged() {
    let n = 60;
    let u: Vec<f64> = (0..n).map(|k| if k % 7 < 3 { 1.0 } else { -0.5 }).collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 1.05 * y[k - 1] + u[k - 1];
    }
    let data = Dataset::new(Signals { u, y }, 1.0, "growing").unwrap();
    let fit = identify(
        &data,
        &Identification::default()
            .with_kind(ModelKind::Arx)
            .with_orders(1, 1, 1)
            .with_method(Method::Ls),
    )
    .unwrap();
    assert!((fit.model.a()[0] + 1.05).abs() < 1e-9);
    assert!(
        fit.warnings
            .iter()
            .any(|w| matches!(w, Warning::Unstable { max_pole_modulus } if (max_pole_modulus - 1.05).abs() < 1e-9)),
        "{:?}",
        fit.warnings
    );
}

// A model that simulates worse than the mean is flagged: ARX(1,1,1) on a record whose output is a
// random walk unrelated to the input: the estimated pole sits near 1 and b near 0, so the free run is
// the initial output drifting slowly, below 0 % fit.
#[test]
fn a_negative_simulation_fit_is_flagged() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let n = 400;
    let u: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = y[k - 1] + rng.gen_range(-1.0..1.0);
    }
    let data = Dataset::new(Signals { u, y }, 1.0, "random walk").unwrap();
    let fit = identify(
        &data,
        &Identification::default()
            .with_kind(ModelKind::Arx)
            .with_orders(1, 1, 1)
            .with_method(Method::Ls),
    )
    .unwrap();
    let f = metrics(&fit.model, &data).unwrap().fit_sim_percent.unwrap();
    let flagged = fit
        .warnings
        .iter()
        .any(|w| matches!(w, Warning::PoorSimulation { .. }));
    assert!(
        f < 0.0,
        "the case must simulate worse than the mean: fit {f}"
    );
    assert!(flagged, "fit {f}: {:?}", fit.warnings);
}

// The same guarantee for the Hammerstein structure on two-sided real records: output error returns a
// stable model, never simulating the estimation data worse than its (stable) key-term LS start.
#[test]
fn hammerstein_output_error_is_stable_and_never_worse_than_its_start() {
    let Some(dir) = ipa_testdata::shared_data() else {
        return;
    };
    let hydraulic = read(&dir.join("hydraulic_actuator/actuator.csv"), "u", "p", 1.0);
    let bb = read(&dir.join("ball_and_beam/ballbeam.csv"), "u", "y", 1.0);
    let cases = [
        (
            "hydraulic actuator (3,2,1)",
            rows(&hydraulic, 0, 512),
            (3, 2, 1),
        ),
        ("ball and beam (2,2,1)", rows(&bb, 0, 500), (2, 2, 1)),
    ];
    for (name, est, (na, nb, nk)) in cases {
        let s = |m| {
            Identification {
                drop_unexcited_branch: true,
                ..Identification::default()
            }
            .with_orders(na, nb, nk)
            .with_offset(true)
            .with_method(m)
        };
        let ls = identify(&est, &s(Method::Ls)).unwrap();
        let oe = identify(&est, &s(Method::Oe)).unwrap();
        let max_pole = oe
            .model
            .poles()
            .iter()
            .map(|p| p.norm())
            .fold(0.0, f64::max);
        assert!(max_pole < 1.0, "{name}: OE pole modulus {max_pole}");
        let rmse_oe = pooled_rmse(&oe.model, &est).unwrap();
        if ls.model.poles_inside_unit_circle() {
            if let Some(rmse_ls) = pooled_rmse(&ls.model, &est) {
                assert!(
                    rmse_oe <= rmse_ls * (1.0 + KEPT_WITHIN + 1e-12),
                    "{name}: {rmse_oe} > {rmse_ls}"
                );
            }
        }
    }
}

// The estimation metrics `identify` computes once for its safeguards and hands to the report are the
// metrics of the returned model on the same record, value for value (checked against
// `metrics::metrics` run afresh); they are withheld for any other record (one sample changed, another
// name) and once the model is changed, so that a report never shows another model's or record's figures.
#[test]
fn kept_estimation_metrics_are_the_models_on_its_own_record_only() {
    let clean = paper_record(2000, 11);
    let record = |y: Vec<f64>, name: &str| {
        Dataset::new(
            Signals {
                u: clean.u().to_vec(),
                y,
            },
            0.01,
            name,
        )
        .unwrap()
    };
    let y: Vec<f64> = clean
        .y()
        .iter()
        .zip(ipa_testdata::white(2000, 3))
        .map(|(y, e)| y + 0.01 * e)
        .collect();
    let noisy = record(y.clone(), "noisy");
    for method in [Method::Ls, Method::Rls] {
        let s = Identification::default().with_method(method);
        let fit = identify(&noisy, &s).unwrap();
        let fresh = metrics(&fit.model, &noisy).unwrap();
        let kept = |d: &Dataset| fit.estimation_metrics(std::slice::from_ref(d)).cloned();
        assert_eq!(kept(&noisy), Some(fresh));
        let mut other = y.clone();
        other[1000] += 1e-9;
        assert_eq!(kept(&record(other, "noisy")), None);
        assert_eq!(kept(&record(y.clone(), "renamed")), None);
        let mut changed = fit.clone();
        changed.model = Model::paper();
        assert_eq!(
            changed.estimation_metrics(std::slice::from_ref(&noisy)),
            None
        );
    }
}

// y(k) = 0.5 y(k−1) + u(k−1) + e(k), white u ~ U(−1, 1), e ~ U(−1, 1), 400 samples, fitted by least
// squares with nb = 2 (b2, at lag 2, is 0 in truth). b1 ± σ and a1 ± σ: σ ≈ sqrt(σ_e² / (N var)) ≈
// 0.03–0.05 against values of 1 and 0.5, far from zero; b2's estimate is 0 plus noise of the same σ, so
// it lies within 2σ of zero (|b̂2| < 2σ̂ is a 95 % event; the seed is fixed). Only b2 is named.
#[test]
fn a_parameter_within_two_standard_deviations_of_zero_is_named_as_poorly_determined() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let n = 400;
    let u: Vec<f64> = (0..n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let mut y = vec![0.0; n];
    for k in 1..n {
        y[k] = 0.5 * y[k - 1] + u[k - 1] + rng.gen_range(-1.0..1.0);
    }
    let data = Dataset::new(Signals { u, y }, 0.01, "b2 is zero").unwrap();
    let fit = identify(
        &vec![data],
        &Identification::default()
            .with_kind(ModelKind::Arx)
            .with_orders(1, 2, 1)
            .with_method(Method::Ls),
    )
    .unwrap();
    let b2 = fit.params.iter().find(|q| q.label() == "b2").unwrap();
    let sd = b2.std.unwrap();
    // Independent of the tool's check: the estimate against its standard deviation.
    assert!(b2.value.abs() < 2.0 * sd, "b2 = {} ± {sd}", b2.value);
    let said: Vec<String> = fit
        .warnings
        .iter()
        .map(ToString::to_string)
        .filter(|w| w.contains("poorly determined"))
        .collect();
    assert_eq!(said.len(), 1, "{:?}", fit.warnings);
    assert!(said[0].starts_with("1 of 3 parameters"), "{}", said[0]);
    assert!(said[0].contains("b2 = "), "{}", said[0]);
    assert!(
        !said[0].contains("b1 =") && !said[0].contains("a1 ="),
        "{}",
        said[0]
    );
}
