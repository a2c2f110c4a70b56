//! The `identify --json` and `validate --json` documents of records read in passes
//! (`identify --stream`, `validate --stream`; the computing is `sysid::stream`): the same documents as
//! [`IdentifyReport::assemble`] and [`ValidationReport::assemble`] on the same records held in memory,
//! to rounding.

use sysid::data::stream::RecordSource;
use sysid::detrend::Detrend;
use sysid::stream::{identify_checked, record_metrics, Streamed, StreamedFit};
use sysid::{Dataset, Fitted, Identification, Model, SysidError};

use crate::{
    IdentifyReport, OperatingPointCheck, ResidualsPair, ValidationReport, OPERATING_POINT_MAX_ROWS,
};

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
    // The measured operating-point check, as `IdentifyReport::assemble` runs it on records in memory,
    // on the same rows: the first OPERATING_POINT_MAX_ROWS of each record, copied into memory by one
    // pass each (bounded memory) and checked by the in-memory code.
    let longest = shape.rows.max(val_shape.map_or(0, |s| s.rows));
    if OperatingPointCheck::of(&fit, settings, &report.metrics, longest).is_some() {
        let est_head = head_of(est)?;
        passes += 1;
        let val_head = match val {
            Some(v) => {
                passes += 1;
                Some(head_of(v)?)
            }
            None => None,
        };
        let hint = crate::measured_operating_point_hint_of(
            &fit,
            settings,
            (&est_head, val_head.as_ref()),
            &report.metrics,
            longest,
        );
        report.put_operating_point_hint(hint);
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

/// The first [`OPERATING_POINT_MAX_ROWS`] samples of a record read in passes, in memory (one pass; the
/// rest of the record is read and not kept).
fn head_of(data: &mut dyn RecordSource) -> Result<Dataset, SysidError> {
    let (mut u, mut y) = (Vec::new(), Vec::new());
    let shape = data.pass(&mut |k, uc, yc| {
        let take = OPERATING_POINT_MAX_ROWS.saturating_sub(k).min(yc.len());
        u.extend_from_slice(uc.get(..take).unwrap_or_default());
        y.extend_from_slice(yc.get(..take).unwrap_or_default());
        Ok(())
    })?;
    Dataset::new(sysid::data::Signals { u, y }, shape.ts, data.name())
}
