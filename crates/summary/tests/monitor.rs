//! A fleet window (`monitor::window`) against `identify --json`'s report of the same record
//! (`IdentifyReport::assemble`): the same model, parameters, metrics and warnings; the residual analysis,
//! which a fleet row does not carry, not computed.
#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use sysid::data::Signals;
use sysid::online::{DetectorSettings, TrackSettings};
use sysid::{identify, Dataset, IdentifyOptions, Method, Orders};
use sysid_summary::monitor::{
    partition, window, windows, WindowFault, WindowSettings, WINDOW_RECORD,
};
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

/// The settings of the fleet's windows (`identify --method ls`, `track` with a 200/800 detector).
fn fleet_settings() -> WindowSettings {
    WindowSettings {
        identification: IdentifyOptions {
            method: Method::Ls,
            ..IdentifyOptions::default()
        }
        .settings(),
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
    }
}

// A partition's windows: each actuator's rows cut into whole windows (the rest left out), rows named
// in the partition; bad offsets and too small a window refused.
#[test]
fn a_partition_is_cut_into_whole_windows_per_actuator() {
    let spans = windows(&[0, 5, 5, 12], 12, 3).unwrap();
    let got: Vec<_> = spans
        .iter()
        .map(|s| (s.group, s.window, s.first, s.last))
        .collect();
    // Actuator 0: rows 0..5 → one window 0..=2 (rows 3, 4 left out); actuator 1: none; actuator 2:
    // rows 5..12 → 5..=7 and 8..=10 (row 11 left out).
    assert_eq!(got, vec![(0, 0, 0, 2), (2, 0, 5, 7), (2, 1, 8, 10)]);
    assert!(windows(&[0, 5], 6, 3).is_err()); // offsets do not end at the rows
    assert!(windows(&[0, 5, 4], 4, 2).is_err()); // decreasing
    assert!(windows(&[1, 4], 4, 2).is_err()); // not from 0
    assert!(windows(&[0, 4], 4, 1).is_err());
}

// Audit s26 L-3 at its depth: a window with a NaN is a fault naming the signal, the sample within the
// window and the value (the fleet words it with the actuator's id and the sample's time); the other
// windows are identified as `window` identifies them alone.
#[test]
fn a_window_with_a_nan_is_a_fact_the_others_go_on() {
    let a = hammerstein_record(1, 4000);
    let b = hammerstein_record(2, 2000);
    let mut u = [a.u(), b.u()].concat();
    let mut y = [a.y(), b.y()].concat();
    y[2000 + 1000] = f64::NAN; // actuator 0, window 1, its sample 1000
    u[4000 + 7] = f64::INFINITY; // actuator 1, window 0, sample 7
    let settings = fleet_settings();
    let spans = windows(&[0, 4000, 6000], 6000, 2000).unwrap();
    let out = partition(&u, &y, &spans, 0.01, &settings).unwrap();
    assert_eq!(out.len(), 3);
    let alone = window(
        &Dataset::new(
            Signals {
                u: a.u()[..2000].to_vec(),
                y: a.y()[..2000].to_vec(),
            },
            0.01,
            "w",
        )
        .unwrap(),
        &settings,
    )
    .unwrap();
    match &out[0] {
        Ok(r) => assert_eq!(r.report, alone.report),
        Err(e) => panic!("window 0 failed: {e:?}"),
    }
    match &out[1] {
        Err(WindowFault::NonFinite(f)) => {
            assert_eq!((f.signal.as_str(), f.sample), ("y", 1000));
            assert!(f.value.is_nan());
        }
        other => panic!("expected a NaN fault, got {other:?}"),
    }
    match &out[2] {
        Err(WindowFault::NonFinite(f)) => {
            assert_eq!(
                (f.signal.as_str(), f.sample, f.value),
                ("u", 7, f64::INFINITY)
            );
        }
        other => panic!("expected an inf fault, got {other:?}"),
    }
    // Spans beyond the rows are refused, not sliced out of bounds.
    let far = windows(&[0, 8000], 8000, 2000).unwrap();
    assert!(partition(&u, &y, &far, 0.01, &settings).is_err());
    // A stop the caller requested (Python's Ctrl-C) ends the whole partition: no window's row, and
    // no fault row standing for a window that was never identified.
    let mut stopped = fleet_settings();
    stopped.identification.cancel = sysid::Stop::new();
    stopped.identification.cancel.request();
    assert!(matches!(
        partition(&u, &y, &spans, 0.01, &stopped),
        Err(sysid::SysidError::Cancelled)
    ));
}

// A window whose identification fails (a constant input: nothing to estimate from) is a `Failed`
// fault whose message, the window's record left unnamed, opens with neither "the window" nor a group.
#[test]
fn a_failed_identification_is_said_without_the_record_s_name() {
    let n = 2000;
    let u = vec![0.0; n];
    let y: Vec<f64> = (0..n).map(|k| (k as f64 * 0.1).sin()).collect();
    let spans = windows(&[0, n], n, n).unwrap();
    let out = partition(&u, &y, &spans, 0.01, &fleet_settings()).unwrap();
    match &out[0] {
        Err(WindowFault::Failed(e)) => {
            let text = e.render_within(WINDOW_RECORD, &|s| s.flag().to_string());
            assert!(
                !text.is_empty() && !text.starts_with(WINDOW_RECORD),
                "{text}"
            );
            assert!(e.to_string().starts_with(WINDOW_RECORD), "{e}");
        }
        other => panic!(
            "expected an identification failure, got {:?}",
            other.as_ref().map(|_| ())
        ),
    }
}
