//! A fleet window (`monitor::window`) against `identify --json`'s report of the same record
//! (`IdentifyReport::assemble`): the same model, parameters, metrics and warnings; the residual analysis,
//! which a fleet row does not carry, not computed.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::Signals;
use sysid::online::{DetectorSettings, TrackSettings};
use sysid::{identify, Dataset, IdentifyOptions, Method, Orders};
use sysid_summary::monitor::{window, WindowSettings};
use sysid_summary::{IdentifyReport, ResidualEntry};

/// A deadzone (b_l = −20, b_r = 15, m_l = 0.9, m_r = 1.1) then y(k) = 1.2 y(k−1) − 0.5 y(k−2) +
/// 0.1 y(k−3) + 0.02 x(k−1) + e(k), e uniform ±0.01, on a staircase of levels in [−100, 100] held
/// 5..30 samples.
fn hammerstein_record(seed: u64, n: usize) -> Dataset {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut u = Vec::with_capacity(n);
    while u.len() < n {
        let level = rng.gen_range(-100.0f64..100.0).round();
        u.extend(std::iter::repeat_n(level, rng.gen_range(5..30)));
    }
    u.truncate(n);
    let x: Vec<f64> = u
        .iter()
        .map(|&v| {
            if v >= 15.0 {
                1.1 * (v - 15.0)
            } else if v <= -20.0 {
                0.9 * (v + 20.0)
            } else {
                0.0
            }
        })
        .collect();
    let mut y = vec![0.0; n];
    for k in 3..n {
        y[k] = 1.2 * y[k - 1] - 0.5 * y[k - 2]
            + 0.1 * y[k - 3]
            + 0.02 * x[k - 1]
            + rng.gen_range(-0.01..0.01);
    }
    Dataset::new(Signals { u, y }, 0.01, format!("window{seed}")).unwrap()
}

#[test]
fn a_window_reports_what_identify_reports_without_the_residual_analysis() {
    let identification = IdentifyOptions {
        method: Method::Ls,
        ..IdentifyOptions::default()
    }
    .settings();
    let settings = WindowSettings {
        identification: identification.clone(),
        track: TrackSettings {
            orders: Orders {
                na: 3,
                nb: 1,
                nk: 1,
            },
            detector: Some(DetectorSettings {
                warmup: 200,
                calibration: 800,
                ..DetectorSettings::default()
            }),
            ..TrackSettings::default()
        },
    };
    for seed in 1..=4 {
        let data = hammerstein_record(seed, 2000);
        let w = window(&data, &settings).unwrap();
        let fit = identify(&data, &identification).unwrap();
        let full =
            IdentifyReport::assemble(&fit, &identification, std::slice::from_ref(&data), None, 25)
                .unwrap();
        // The full report has a residual analysis; the window's says it was not computed.
        assert!(matches!(
            full.residuals.estimation,
            ResidualEntry::Analysis(_)
        ));
        match &w.report.residuals.estimation {
            ResidualEntry::Unavailable { error } => assert_eq!(error, "not computed"),
            other => panic!("seed {seed}: expected no residual analysis, got {other:?}"),
        }
        // Everything else is the same document, value for value.
        let mut expected = full.clone();
        expected.residuals = w.report.residuals.clone();
        assert_eq!(w.report, expected, "seed {seed}");
        assert!(!w.report.parameters.is_empty());
    }
}
