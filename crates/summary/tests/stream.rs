//! The streaming path (`sysid::stream`, records read in passes) against the in-memory path on the same
//! records: the same parameters, metrics and residual analysis to 1e-9 whatever the chunk size.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::stream::DatasetSource;
use sysid::data::Signals;
use sysid::detrend::{detrend, Detrend};
use sysid::metrics::Metrics;
use sysid::model::NoiseModel;
use sysid::{identify, Dataset, Identification, Method, Model, ModelKind};
use sysid_summary::stream::{identify_report, validation_report};
use sysid_summary::{IdentifyReport, ResidualEntry, ValidationReport};

/// A staircase of random levels in [-100, 100] held 5..30 samples.
fn staircase(rng: &mut ChaCha8Rng, n: usize) -> Vec<f64> {
    let mut u = Vec::with_capacity(n);
    while u.len() < n {
        let level: f64 = rng.gen_range(-100.0..100.0);
        let hold = rng.gen_range(5..30);
        u.extend(std::iter::repeat_n(level, hold));
    }
    u.truncate(n);
    u
}

/// y(k) = 1.5 y(k−1) − 0.7 y(k−2) + 0.05 u(k−1) + 0.03 u(k−2) + 2 + drift k + e(k), e uniform ±0.1.
fn arx_record(seed: u64, n: usize, drift: f64) -> Dataset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let u = staircase(&mut rng, n);
    let mut y = vec![10.0; n];
    for k in 2..n {
        y[k] = 1.5 * y[k - 1] - 0.7 * y[k - 2]
            + 0.05 * u[k - 1]
            + 0.03 * u[k - 2]
            + 2.0
            + drift * k as f64
            + rng.gen_range(-0.1..0.1);
    }
    Dataset::new(Signals { u, y }, 0.01, format!("arx{seed}")).unwrap()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * a.abs().max(b.abs()).max(1.0)
}

fn assert_close_opt(what: &str, a: Option<f64>, b: Option<f64>) {
    match (a, b) {
        (Some(a), Some(b)) => assert!(close(a, b, 1e-9), "{what}: {a} vs {b}"),
        (None, None) => {}
        _ => panic!("{what}: {a:?} vs {b:?}"),
    }
}

fn assert_metrics(what: &str, a: &Metrics, b: &Metrics) {
    assert_eq!((a.n, a.p), (b.n, b.p), "{what}");
    assert_close_opt(
        &format!("{what} fit sim"),
        a.fit_sim_percent,
        b.fit_sim_percent,
    );
    assert_close_opt(
        &format!("{what} fit pred"),
        a.fit_pred_percent,
        b.fit_pred_percent,
    );
    assert_close_opt(&format!("{what} rmse sim"), a.rmse_sim, b.rmse_sim);
    assert_close_opt(
        &format!("{what} fit sim measured"),
        a.fit_sim_measured_percent,
        b.fit_sim_measured_percent,
    );
    assert_close_opt(&format!("{what} loss"), a.loss, b.loss);
    assert_close_opt(&format!("{what} fpe"), a.fpe, b.fpe);
    assert_close_opt(&format!("{what} aic"), a.aic, b.aic);
    // MATLAB's figures, from the model's own prediction errors (audit s32 M-2).
    assert_close_opt(&format!("{what} loss_fcn"), a.loss_fcn, b.loss_fcn);
    assert_close_opt(&format!("{what} fpe_matlab"), a.fpe_matlab, b.fpe_matlab);
    assert_close_opt(&format!("{what} aic_matlab"), a.aic_matlab, b.aic_matlab);
    assert_eq!(a.note.is_some(), b.note.is_some(), "{what} note");
}

fn assert_residuals(what: &str, a: &ResidualEntry, b: &ResidualEntry) {
    match (a, b) {
        (ResidualEntry::Analysis(a), ResidualEntry::Analysis(b)) => {
            assert_eq!((a.n, a.white, a.independent), (b.n, b.white, b.independent));
            assert!(close(a.ljung_box_q, b.ljung_box_q, 1e-9), "{what}");
            assert!(close(a.cross_statistic, b.cross_statistic, 1e-9), "{what}");
            for (x, y) in a.autocorrelation.iter().zip(&b.autocorrelation) {
                assert!(close(*x, *y, 1e-9), "{what}");
            }
        }
        (ResidualEntry::Unavailable { error: a }, ResidualEntry::Unavailable { error: b }) => {
            assert_eq!(a, b, "{what}")
        }
        _ => panic!("{what}: {a:?} vs {b:?}"),
    }
}

fn in_memory(
    est: &Dataset,
    val: Option<&Dataset>,
    s: &Identification,
    how: Detrend,
) -> IdentifyReport {
    let (detrended, op) = detrend(est, how);
    let mut fit = identify(&detrended, s).unwrap();
    fit.model = fit.model.with_operating_point(op).unwrap();
    // After `--detrend linear` the estimation figures are scored on the record with its drift removed
    // and its means kept, as `identify` does in memory (audit s18 M-3).
    let scored = match how {
        Detrend::Linear => sysid::detrend::drift_removed(est).0,
        _ => est.clone(),
    };
    IdentifyReport::assemble(&fit, s, std::slice::from_ref(&scored), val, 25).unwrap()
}

// Least squares accumulated block by block is the same least-squares problem: parameters, their
// standard deviations, every metric and the residual tests agree with the in-memory path to 1e-9, for
// chunks of 1, 7 and 4096 samples, with and without the offset, for each detrending, with a
// validation record.
#[test]
fn streamed_arx_identification_equals_the_in_memory_one() {
    let est = arx_record(1, 6000, 0.0);
    let val = arx_record(2, 3000, 0.0);
    for (offset, how, drift) in [
        (true, Detrend::None, 0.0),
        (false, Detrend::Mean, 0.0),
        (false, Detrend::Linear, 1e-4),
    ] {
        let est = if drift > 0.0 {
            arx_record(3, 6000, drift)
        } else {
            est.clone()
        };
        let s = Identification::default()
            .with_kind(ModelKind::Arx)
            .with_orders(2, 2, 1)
            .with_offset(offset)
            .with_method(Method::Ls);
        let want = in_memory(&est, Some(&val), &s, how);
        for chunk in [1, 7, 4096] {
            let mut e = DatasetSource::new(&est, chunk);
            let mut v = DatasetSource::new(&val, chunk);
            let got = identify_report(&mut e, Some(&mut v), &s, how, 25).unwrap();
            let (_, r) = &got.result;
            let what = format!("offset {offset}, {how}, chunk {chunk}");
            assert_eq!(r.parameters.len(), want.parameters.len());
            for (a, b) in r.parameters.iter().zip(&want.parameters) {
                assert_eq!(a.name, b.name);
                assert!(
                    close(a.value, b.value, 1e-9),
                    "{what} {}: {} vs {}",
                    a.name,
                    a.value,
                    b.value
                );
                assert_close_opt(&format!("{what} std {}", a.name), a.std, b.std);
            }
            assert!(close(
                r.estimation.noise_variance.unwrap(),
                want.estimation.noise_variance.unwrap(),
                1e-9
            ));
            assert_eq!(r.model.operating_point().is_some(), how != Detrend::None);
            assert_metrics(&what, &r.metrics.estimation, &want.metrics.estimation);
            assert_metrics(
                &what,
                r.metrics.validation.as_ref().unwrap(),
                want.metrics.validation.as_ref().unwrap(),
            );
            assert_residuals(&what, &r.residuals.estimation, &want.residuals.estimation);
            assert_residuals(
                &what,
                r.residuals.validation.as_ref().unwrap(),
                want.residuals.validation.as_ref().unwrap(),
            );
            assert_eq!(r.warnings, want.warnings, "{what}");
            // The estimation record: the fit (1 pass, 2 with --detrend mean, 3 with linear: the means,
            // the slopes) and its metrics (2 passes, 4 with linear: the drift of the record the
            // metrics are scored on, read again); the validation record: its metrics (2 passes).
            assert_eq!(
                got.passes,
                3 + usize::from(how != Detrend::None) + 3 * usize::from(how == Detrend::Linear)
            );
            assert_eq!(got.val_passes, 2);
        }
    }
}

fn assert_validation(what: &str, model: &Model, data: &Dataset) {
    let want = ValidationReport::assemble(model, data, 25);
    let got = validation_report(model, &mut DatasetSource::new(data, 1000), 25, 0);
    match (got, want) {
        (Ok(g), Ok(w)) => {
            assert_metrics(what, &g.result.metrics.validation, &w.metrics.validation);
            assert_residuals(
                what,
                &g.result.residuals.validation,
                &w.residuals.validation,
            );
            assert_eq!(g.result.warnings, w.warnings, "{what}");
        }
        (Err(g), Err(w)) => assert_eq!(g.to_string(), w.to_string(), "{what}"),
        (g, w) => panic!("{what}: {g:?} vs {w:?}"),
    }
}

// Validation of saved models of every kind: the paper's Hammerstein model (deadzone, equation
// error), the same model as an output-error model (its predictor is the simulation from the estimated
// initial outputs, three passes), and an unstable model whose simulation overflows (no simulation
// metrics, a note) — each as in memory.
#[test]
fn streamed_validation_equals_the_in_memory_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let n = 20_000;
    let u = staircase(&mut rng, n);
    let paper = Model::paper();
    let mut y = paper.simulate(&[&u], &vec![0.0; n]).unwrap();
    for v in y.iter_mut() {
        *v += rng.gen_range(-0.05..0.05);
    }
    let data = Dataset::new(Signals { u, y }, 0.01, "paper").unwrap();
    assert_validation("paper", &paper, &data);
    let oe = Model::paper().with_noise_model(NoiseModel::OutputError);
    assert_validation("paper OE", &oe, &data);
    let unstable = Model::arx(0.01, vec![-1.05], vec![0.01], 1, None).unwrap();
    assert_validation("unstable", &unstable, &data);
}

// What cannot be streamed is refused in words that name the way out.
#[test]
fn hammerstein_and_recursive_methods_are_refused_clearly() {
    let est = arx_record(1, 500, 0.0);
    for s in [
        Identification::default().with_method(Method::Ls),
        Identification::default()
            .with_kind(ModelKind::Arx)
            .with_method(Method::Rls),
    ] {
        let e = identify_report(
            &mut DatasetSource::new(&est, 64),
            None,
            &s,
            Detrend::None,
            25,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("--stream") && e.contains("ls"), "{e}");
    }
}
