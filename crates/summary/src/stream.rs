//! The `identify --json` and `validate --json` documents of records read in passes
//! (`identify --stream`, `validate --stream`; the computing is `sysid::stream`): the same documents as
//! [`IdentifyReport::assemble`] and [`ValidationReport::assemble`] on the same records held in memory,
//! to rounding.

use sysid::data::stream::{ChunkFn, RecordSource, Shape};
use sysid::detrend::Detrend;
use sysid::stream::{identify_checked, record_metrics_scored_from, Streamed, StreamedFit};
use sysid::{Dataset, Fitted, Identification, Model, SysidError};

use crate::{
    IdentifyReport, OperatingPointCheck, ResidualsPair, ValidationReport, OPERATING_POINT_MAX_ROWS,
};

/// Identifies an ARX model by least squares from `est` in passes ([`identify_checked`]) and makes the
/// whole `identify --json` report (metrics and residual analysis with `max_lag` lags on `est` and, when
/// given, on `val`).
pub fn identify_report(
    est: &mut dyn RecordSource,
    val: Option<&mut dyn RecordSource>,
    settings: &Identification,
    detrend: Detrend,
    max_lag: usize,
) -> Result<Streamed<(Fitted, IdentifyReport)>, SysidError> {
    // The first rows of each record, kept from the identification's first pass for the operating-point
    // check below (no pass of its own), when the check may apply (not with --offset or --detrend).
    let keep = OperatingPointCheck::may_apply(settings, detrend);
    let mut est = HeadKept::new(est, keep);
    let mut val = val.map(|v| HeadKept::new(v, keep));
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
        y_extremes,
        passes,
        val_passes,
    } = identify_checked(
        &mut est,
        val.as_mut().map(|v| v as &mut dyn RecordSource),
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
    // on the same rows: the first OPERATING_POINT_MAX_ROWS of each record (kept by the first pass,
    // bounded memory), checked by the in-memory code.
    let longest = shape.rows.max(val_shape.map_or(0, |s| s.rows));
    if keep && OperatingPointCheck::of(&fit, settings, &report.metrics, longest).is_some() {
        let est_head = est.head()?;
        let val_head = val.map(|v| v.head()).transpose()?;
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
        y_extremes,
        passes,
        val_passes,
    })
}

/// The `validate --json` report of `model` on `data` read in passes (as
/// [`ValidationReport::assemble_scored_from`]), every figure over the rows k ≥ max(K, k0), K =
/// `score_from` (0: from k0).
pub fn validation_report(
    model: &Model,
    data: &mut dyn RecordSource,
    max_lag: usize,
    score_from: usize,
) -> Result<Streamed<ValidationReport>, SysidError> {
    let on = record_metrics_scored_from(model, data, max_lag, score_from)?;
    let (m, r) = on.result;
    let extremes: Vec<(f64, f64)> = on.u_extremes.into_iter().collect();
    let mut report = ValidationReport::from_parts(model, m, r.into(), &extremes, score_from);
    // The output against the model's data range, as `ValidationReport::assemble` judges it.
    let outside = on
        .y_extremes
        .and_then(|ext| crate::record_outside_extremes(model, ext));
    report.warnings.extend(outside);
    if let (Some(u), Some(y)) = (on.u_extremes, on.y_extremes) {
        report
            .warnings
            .extend(crate::tiny_signal_warning(model, &[u], y, data.name()));
    }
    Ok(Streamed {
        result: report,
        shape: on.shape,
        val_shape: None,
        u_extremes: on.u_extremes,
        val_u_extremes: None,
        y_extremes: on.y_extremes,
        passes: on.passes,
        val_passes: 0,
    })
}

/// A record read in passes that keeps its first [`OPERATING_POINT_MAX_ROWS`] samples (u and y, in
/// memory) as its first complete pass reads them, for the operating-point check; or nothing, passing
/// every pass through, when told not to keep them.
struct HeadKept<'a> {
    inner: &'a mut dyn RecordSource,
    /// Whether the first samples are kept.
    keep: bool,
    /// The first samples and Ts, once a pass has completed.
    kept: Option<(Vec<f64>, Vec<f64>, f64)>,
}

impl<'a> HeadKept<'a> {
    fn new(inner: &'a mut dyn RecordSource, keep: bool) -> Self {
        HeadKept {
            inner,
            keep,
            kept: None,
        }
    }

    /// The kept samples as a record (an error if no pass completed: not reached after a successful
    /// identification, which reads every record).
    fn head(self) -> Result<Dataset, SysidError> {
        let name = self.inner.name().to_string();
        let (u, y, ts) = self.kept.ok_or_else(|| {
            SysidError::Numerical(format!("{name}: the record was not read before the check"))
        })?;
        Dataset::new(sysid::data::Signals { u, y }, ts, name)
    }
}

impl RecordSource for HeadKept<'_> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn pass(&mut self, consume: &mut ChunkFn<'_>) -> Result<Shape, SysidError> {
        if !self.keep || self.kept.is_some() {
            return self.inner.pass(consume);
        }
        let (mut u, mut y) = (Vec::new(), Vec::new());
        let shape = self.inner.pass(&mut |k, uc, yc| {
            let take = OPERATING_POINT_MAX_ROWS.saturating_sub(k).min(yc.len());
            u.extend_from_slice(uc.get(..take).unwrap_or_default());
            y.extend_from_slice(yc.get(..take).unwrap_or_default());
            consume(k, uc, yc)
        })?;
        self.kept = Some((u, y, shape.ts));
        Ok(shape)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use sysid::data::stream::DatasetSource;
    use sysid::data::Signals;

    // The first OPERATING_POINT_MAX_ROWS samples are kept by the first pass (chunks that straddle the
    // bound are cut), every chunk still reaches the consumer; told not to keep them, nothing is kept and
    // the passes are the record's own.
    #[test]
    fn the_head_is_kept_only_when_asked() {
        let n = OPERATING_POINT_MAX_ROWS + 12_345;
        let u: Vec<f64> = (0..n).map(|k| k as f64).collect();
        let y: Vec<f64> = (0..n).map(|k| -(k as f64)).collect();
        let data = Dataset::new(Signals { u, y }, 0.01, "r").unwrap();
        for keep in [true, false] {
            let mut src = DatasetSource::new(&data, 7_000);
            let mut kept = HeadKept::new(&mut src, keep);
            for _ in 0..2 {
                let mut seen = 0;
                let shape = kept
                    .pass(&mut |k, uc, _| {
                        assert_eq!(k, seen);
                        seen += uc.len();
                        Ok(())
                    })
                    .unwrap();
                assert_eq!((seen, shape.rows), (n, n));
            }
            match (keep, kept.kept.as_ref()) {
                (true, Some((u, y, ts))) => {
                    assert_eq!(u.len(), OPERATING_POINT_MAX_ROWS);
                    assert_eq!(y.len(), OPERATING_POINT_MAX_ROWS);
                    assert_eq!((u[99_999], y[99_999], *ts), (99_999.0, -99_999.0, 0.01));
                }
                (false, None) => {}
                (keep, k) => panic!("keep {keep}: kept {:?}", k.map(|k| k.0.len())),
            }
        }
    }
}
