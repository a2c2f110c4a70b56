//! The `identify --json` and `validate --json` documents of records read in passes
//! (`identify --stream`, `validate --stream`; the computing is `sysid::stream`): the same documents as
//! [`IdentifyReport::assemble`] and [`ValidationReport::assemble`] on the same records held in memory,
//! to rounding.

use std::cell::RefCell;
use sysid::data::stream::RecordSource;
use sysid::detrend::Detrend;
use sysid::stream::{identify_checked, offset_hint, record_metrics, RowsOf, Streamed, StreamedFit};
use sysid::{Fitted, Identification, Model, SysidError};

use crate::{IdentifyReport, OperatingPointCheck, ResidualsPair, ValidationReport};

/// Identifies an ARX model by least squares from `est` in passes ([`identify_checked`]) and makes the
/// whole `identify --json` report (metrics and residual analysis with `max_lag` lags on `est` and, when
/// given, on `val`).
pub fn identify_report(
    est: &mut dyn RecordSource,
    mut val: Option<&mut dyn RecordSource>,
    settings: &Identification,
    detrend: Detrend,
    max_lag: usize,
) -> Result<Streamed<(Fitted, IdentifyReport)>, SysidError> {
    let Streamed {
        result:
            StreamedFit {
                fit,
                estimation: (est_metrics, est_resid),
                validation,
            },
        shape,
        val_shape,
        u_extremes,
        val_u_extremes,
        mut passes,
    } = identify_checked(
        est,
        val.as_mut().map(|v| &mut **v as &mut dyn RecordSource),
        settings,
        detrend,
        max_lag,
    )?;
    let (val_metrics, val_resid) = match validation {
        Some((m, r)) => (Some(m), Some(r.into())),
        None => (None, None),
    };
    let mut report = IdentifyReport::from_parts(
        &fit,
        settings,
        est_metrics,
        val_metrics,
        ResidualsPair {
            estimation: est_resid.into(),
            validation: val_resid,
        },
    );
    // The validation record against the model's data range, as `IdentifyReport::assemble` judges it.
    if let Some(ext) = val_u_extremes {
        report
            .warnings
            .extend(IdentifyReport::validation_extrapolation(&fit.model, &[ext]));
    }
    // The measured operating-point check, as `IdentifyReport::assemble` runs it on records in memory:
    // more passes (ARX with and without c, their metrics, ȳ).
    if let Some(c) = OperatingPointCheck::of(&fit, settings, &report.metrics) {
        let words = (c.what.as_str(), c.advice.as_str());
        let hint = match val {
            Some(v) => Some(offset_hint(est, Some(v), &c.arx, (None, c.own), words)?),
            // Without a validation record: estimated on the first two thirds, ranked on the last.
            None => match OperatingPointCheck::estimation_rows(shape.rows) {
                Some(k) => {
                    let shared = RefCell::new(est);
                    let mut head = RowsOf::new(&shared, 0..k);
                    let mut tail = RowsOf::new(&shared, k..shape.rows);
                    Some(offset_hint(
                        &mut head,
                        Some(&mut tail),
                        &c.arx,
                        (None, c.own),
                        words,
                    )?)
                }
                None => None,
            },
        };
        if let Some(h) = hint {
            passes += h.passes;
            report.put_operating_point_hint(h.result);
        }
    }
    Ok(Streamed {
        result: (fit, report),
        shape,
        val_shape,
        u_extremes,
        val_u_extremes,
        passes,
    })
}

/// The `validate --json` report of `model` on `data` read in passes (as [`ValidationReport::assemble`]).
pub fn validation_report(
    model: &Model,
    data: &mut dyn RecordSource,
    max_lag: usize,
) -> Result<Streamed<ValidationReport>, SysidError> {
    let on = record_metrics(model, data, max_lag)?;
    let (m, r) = on.result;
    let extremes: Vec<(f64, f64)> = on.u_extremes.into_iter().collect();
    Ok(Streamed {
        result: ValidationReport::from_parts(model, m, r.into(), &extremes),
        shape: on.shape,
        val_shape: None,
        u_extremes: on.u_extremes,
        val_u_extremes: None,
        passes: on.passes,
    })
}
