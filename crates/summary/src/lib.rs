//! The documents an identification is reported in: `identify --json` ([`IdentifyReport`], also
//! embedded by `reproduce` in `summary.json` `models.*`) and `validate --json` ([`ValidationReport`]).
//! One schema for the command line, the Python package (`Fit.to_dict()`) and `reproduce`.
//!
//! The application side of the identification: everything here is assembled from what the library
//! `sysid` computed (the fit, its metrics, the residual analysis, the trust checks); nothing is
//! estimated here. [`stream`] makes the same documents for records read in passes; [`monitor`] one
//! window of a fleet (the report and the online tracker's change points); [`narx`] the document of a
//! polynomial NARX identification.

use serde::{Deserialize, Serialize};

use sysid::metrics::{metrics, pooled_metrics, Metrics};
use sysid::residuals::ResidualAnalysis;
use sysid::trust::{baseline_warning, guarded_fit, held_out_drop, metric_warnings};
use sysid::warnings::{Concern, Record, Warning};
use sysid::SysidError;
use sysid::{Dataset, EstimatorSettings, Fitted, Identification, Method, Model, Param, Passes};

pub mod monitor;
pub mod narx;
pub mod simulation;
pub mod stream;

/// A pole p = re + i·im of the linear block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pole {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
    /// Modulus |p| (stable when < 1).
    pub abs: f64,
}

/// How the model was estimated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EstimationInfo {
    /// `ls` or `rls`.
    pub method: Method,
    /// Key-term iterations (LS) or passes (RLS).
    pub iterations: usize,
    /// See [`Fitted::converged`].
    pub converged: bool,
    /// RLS forgetting factor ρ (RLS only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub forgetting: Option<f64>,
    /// RLS P(0) scale (RLS only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub p0: Option<f64>,
    /// RLS passes: `"until-settled"` (the default) or `"fixed"` (the paper's single pass is
    /// `"fixed"` with 1 iteration). RLS only.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub passes: Option<String>,
    /// σ̂² of the one-step prediction errors; `None` (JSON null) when it is undetermined (no more
    /// regression rows than estimated parameters, N ≤ p).
    pub noise_variance: Option<f64>,
    /// Remarks (limit cycle, best iterate kept...).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub note: Option<String>,
    /// What was returned when it is not the estimate of `method` itself: the `used` text of the
    /// fallback warning (e.g. "the least-squares start instead of the output-error refinement"), so
    /// that `method`, `iterations` and `converged` describe the estimator that ran, and this field the
    /// model that was kept. Absent when `method`'s own estimate was returned.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub returned: Option<String>,
}

/// Metrics on the estimation record and, when given, on the validation record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetricsPair {
    /// On the estimation data.
    pub estimation: Metrics,
    /// On the `--validation` data.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub validation: Option<Metrics>,
}

/// The residual analysis of one record, or why it could not be made.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ResidualEntry {
    /// The analysis (MATLAB `resid`).
    Analysis(Box<ResidualAnalysis>),
    /// Why there is none (record too short for the lags, constant residuals...).
    Unavailable {
        /// The reason.
        error: String,
    },
}

/// Residual analysis on the estimation record and, when given, on the validation record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ResidualsPair {
    /// On the estimation data.
    pub estimation: ResidualEntry,
    /// On the validation data.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub validation: Option<ResidualEntry>,
}

/// The residual analysis of `model` on `data` with `max_lag` lags
/// ([`sysid::residuals::residual_analysis`]), or why there is none, as the documents carry it.
pub fn residual_analysis(model: &Model, data: &Dataset, max_lag: usize) -> ResidualEntry {
    ResidualEntry::from(sysid::residuals::residual_analysis(model, data, max_lag))
}

impl From<Result<ResidualAnalysis, String>> for ResidualEntry {
    fn from(r: Result<ResidualAnalysis, String>) -> Self {
        match r {
            Ok(a) => ResidualEntry::Analysis(Box::new(a)),
            Err(error) => ResidualEntry::Unavailable { error },
        }
    }
}

/// The metrics of `fit` on its estimation records: those the safeguards of `identify` computed on the
/// same records (checked), unless the model or the records changed since.
fn estimation_metrics(fit: &Fitted, est_data: &[Dataset]) -> Result<Metrics, SysidError> {
    match fit.estimation_metrics(est_data) {
        Some(kept) => Ok(kept.clone()),
        None => pooled_metrics(&fit.model, est_data),
    }
}

/// The fit's warnings with those about its estimation record's figures judged on `est`, the metrics of
/// the model on `est_data` (the records as reported): a poor simulation and a flattering initial state
/// are judged again; a fit far below the plain ARX-LS baseline is kept when the identification found it
/// (its baseline saw the detrended record, as the model did; a baseline on the record as reported has
/// no operating point and could only be weaker) and, for one record, judged on the reported figures
/// when it did not.
fn estimation_warnings_on(
    fit: &Fitted,
    settings: &Identification,
    est_data: &[Dataset],
    est: &Metrics,
) -> Vec<String> {
    let metric = |w: &Warning| {
        w.record() == Some(Record::Estimation)
            && !matches!(w, Warning::Trust(Concern::BelowBaseline { .. }))
    };
    let below_said = fit
        .warnings
        .iter()
        .any(|w| w.record() == Some(Record::Estimation) && !metric(w));
    let on_record = match est_data {
        [one] if !below_said => {
            baseline_warning(Record::Estimation, fit, settings, est_data, one, est)
        }
        _ => None,
    };
    fit.warnings
        .iter()
        .filter(|w| !metric(w))
        .cloned()
        .chain(metric_warnings(Record::Estimation, est))
        .chain(on_record)
        .map(|w| w.to_string())
        .collect()
}

/// Metrics and residual analysis of a model on one of several estimation records.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordReport {
    /// The record's name.
    pub data: String,
    /// Metrics (fit, loss, FPE...).
    pub metrics: Metrics,
    /// Residual analysis.
    pub residuals: ResidualEntry,
}

/// The whole `identify --json` document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifyReport {
    /// The fitted model (the same object a model file holds).
    pub model: Model,
    /// The inputs' names, when the model has several (its parameters name their input).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub inputs: Option<Vec<String>>,
    /// Physical parameters with standard deviations.
    pub parameters: Vec<Param>,
    /// Poles of the linear block, largest modulus first.
    pub poles: Vec<Pole>,
    /// The model settles: its stability verdict ([`Model::stability`]) is `settles`, every pole inside
    /// the unit circle by more than ε = [`sysid_core::stability::MARGIN`] = 10⁻⁵ (an integrator, a pole
    /// on the circle and an unstable model are not stable).
    pub stable: bool,
    /// The stability verdict's name ([`sysid_core::Stability::name`]): `settles`, `integrator`,
    /// `on_circle` or `unstable`; the same for the same model in every command.
    #[serde(default)]
    pub stability: String,
    /// Estimation record.
    pub estimation: EstimationInfo,
    /// Validation metrics.
    pub metrics: MetricsPair,
    /// Residual analysis (MATLAB `resid`) of the one-step prediction errors.
    pub residuals: ResidualsPair,
    /// Several estimation records (merged experiments): each one's metrics and residual analysis
    /// (`metrics.estimation` then pools the rows of every record; `residuals.estimation` is per record
    /// only, here).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub records: Option<Vec<RecordReport>>,
    /// Reasons not to trust the model blindly, in words (always present; empty when all is well).
    pub warnings: Vec<String>,
}

impl IdentifyReport {
    /// Assembles the whole report of a fit on its estimation data and, optionally, validation data:
    /// metrics, residual analysis with `max_lag` lags, and the warnings (the fit's own plus those the
    /// validation record raises). The one place where the `identify --json` document is made (the
    /// command line and the Python package both call it; a fleet window takes the same document without
    /// the residual analysis, [`IdentifyReport::without_residuals`]).
    ///
    /// With several estimation records (`est_data`: merged experiments) `metrics.estimation` pools their
    /// rows and `records` holds each one's metrics and residual analysis.
    pub fn assemble(
        fit: &Fitted,
        settings: &Identification,
        est_data: &[Dataset],
        val_data: Option<&Dataset>,
        max_lag: usize,
    ) -> Result<Self, SysidError> {
        let m = &fit.model;
        // Metrics not kept by the identification are of another record than the one the fit's
        // safeguards judged (a record put back in the user's units after `--detrend linear`, whose
        // drift the model does not carry): the warnings about the estimation figures are judged again
        // on the figures reported.
        let rejudge = fit.estimation_metrics(est_data).is_none();
        let est = estimation_metrics(fit, est_data)?;
        let val = val_data.map(|v| metrics(m, v)).transpose()?;
        let (estimation, records) = match est_data {
            [one] => (residual_analysis(m, one, max_lag), None),
            many => (
                ResidualEntry::Unavailable {
                    error: "several records: see each record's residual analysis in records".into(),
                },
                Some(
                    many.iter()
                        .map(|r| {
                            Ok(RecordReport {
                                data: r.name().to_string(),
                                metrics: metrics(m, r)?
                                    .with_parameter_count(fit.estimated_parameter_count()),
                                residuals: residual_analysis(m, r, max_lag),
                            })
                        })
                        .collect::<Result<Vec<_>, SysidError>>()?,
                ),
            ),
        };
        let residuals = ResidualsPair {
            estimation,
            validation: val_data.map(|v| residual_analysis(m, v, max_lag)),
        };
        let below = match (val_data, &val) {
            (Some(v), Some(vm)) => {
                baseline_warning(Record::Validation, fit, settings, est_data, v, vm)
            }
            _ => None,
        };
        let mut report = Self::from_parts(fit, settings, est, val, residuals);
        report.records = records;
        if rejudge {
            let later = report.warnings.split_off(fit.warnings.len());
            report.warnings =
                estimation_warnings_on(fit, settings, est_data, &report.metrics.estimation);
            report.warnings.extend(later);
        }
        report.warnings.extend(below.map(|w| w.to_string()));
        // Few regression rows per parameter: the fits describe the noise as much as the plant (audit
        // s17 L-k: N = 5 rows for p = 4 parameters printed a 99.6 % fit).
        let (n, p) = (report.metrics.estimation.n, report.metrics.estimation.p);
        if n < FEW_ROWS_PER_PARAMETER * p {
            report.warnings.push(format!(
                "the estimation used N = {n} regression rows for p = {p} parameters (fewer than \
                 {FEW_ROWS_PER_PARAMETER} per parameter; the fit from estimated initial outputs frees \
                 {} more values): the parameters are barely determined and the estimation fits flatter \
                 the model; use a longer record (--rows) or lower orders",
                m.k0()
            ));
        }
        // Merged records: each record's own fits judged as one record's are (a poor simulation, a
        // flattering initial state), so that the pooled figures cannot hide a record the model does
        // not simulate, and `--strict` refuses it (audit s17 H-1).
        for r in report.records.iter().flatten() {
            report.warnings.extend(
                metric_warnings(Record::Estimation, &r.metrics)
                    .into_iter()
                    .map(|w| format!("merged record {}: {w}", r.data)),
            );
        }
        if let Some(v) = val_data {
            report
                .warnings
                .extend(Self::validation_extrapolation(m, &input_extremes(v)));
        }
        let hint =
            measured_operating_point_hint(fit, settings, (est_data, val_data), &report.metrics);
        report.put_operating_point_hint(hint);
        Ok(report)
    }

    /// The measured operating-point check's warning ([`OperatingPointCheck`]), when it speaks, added to
    /// the range-based hint about the same level (which has no figures) after "measured:", or else
    /// after the others (one warning about the level, not two):
    /// the one place where it joins a report, in memory ([`IdentifyReport::assemble`],
    /// [`IdentifyReport::without_residuals`]) and read in passes ([`stream::identify_report`]).
    pub fn put_operating_point_hint(&mut self, hint: Option<String>) {
        let Some(w) = hint else { return };
        match self
            .warnings
            .iter_mut()
            .find(|x| x.starts_with(OPERATING_POINT_HINT))
        {
            Some(range) => *range = format!("{range}; measured: {w}"),
            None => self.warnings.push(w),
        }
    }

    /// The validation record's inputs (their [min, max], `input_extremes`) beyond the model's data range,
    /// each warning headed "validation:" (in memory and read in passes alike).
    pub fn validation_extrapolation(model: &Model, input_extremes: &[(f64, f64)]) -> Vec<String> {
        headed_validation(ValidationReport::extrapolation_warnings_of(
            model,
            input_extremes,
        ))
    }

    /// [`IdentifyReport::assemble`] on one or more estimation records without validation data and
    /// without the residual analysis: the same model, parameters, metrics, poles and warnings (the
    /// residual analysis adds none), `residuals.estimation` saying "not computed" and no per-record
    /// `records`. For callers that carry no residual test, e.g. a fleet window
    /// ([`monitor::window`]): the residual analysis is a tenth of such a window's time.
    pub fn without_residuals(
        fit: &Fitted,
        settings: &Identification,
        est_data: &[Dataset],
    ) -> Result<Self, SysidError> {
        let est = estimation_metrics(fit, est_data)?;
        let mut report = Self::new(fit, settings, est, None);
        let hint = measured_operating_point_hint(fit, settings, (est_data, None), &report.metrics);
        report.put_operating_point_hint(hint);
        Ok(report)
    }

    /// The report from metrics and residual analyses computed elsewhere (the streaming path,
    /// `sysid::stream`), with the warnings [`IdentifyReport::assemble`] adds.
    pub fn from_parts(
        fit: &Fitted,
        settings: &Identification,
        est: Metrics,
        val: Option<Metrics>,
        residuals: ResidualsPair,
    ) -> Self {
        let mut report = IdentifyReport::new(fit, settings, est, val);
        report.residuals = residuals;
        if let Some(m) = &report.metrics.validation {
            report.warnings.extend(
                metric_warnings(Record::Validation, m)
                    .iter()
                    .chain(&held_out_drop(
                        (Record::Estimation, guarded_fit(&report.metrics.estimation)),
                        (Record::Validation, guarded_fit(m)),
                    ))
                    .map(ToString::to_string),
            );
        }
        // Output noise seen through an equation-error estimate (audit s34 M-2): the estimation
        // record's residuals, the ones the estimate was fitted to.
        if let ResidualEntry::Analysis(a) = &report.residuals.estimation {
            report.warnings.extend(
                sysid::trust::output_noise_bias(fit.method, a)
                    .iter()
                    .map(ToString::to_string),
            );
        }
        // The validation record's input–residual test, the one that judges the model (audit s20 M-1).
        if let Some(ResidualEntry::Analysis(a)) = &report.residuals.validation {
            report.warnings.extend(
                sysid::trust::input_dynamics_left(Record::Validation, a)
                    .iter()
                    .map(ToString::to_string),
            );
        }
        report
            .warnings
            .extend(operating_point_hint(&fit.model, &report.metrics));
        report
    }

    /// The report of a fit from metrics computed elsewhere (no residual analysis; the fit's own
    /// warnings). Prefer [`IdentifyReport::assemble`].
    pub fn new(
        fit: &Fitted,
        settings: &Identification,
        est: Metrics,
        val: Option<Metrics>,
    ) -> Self {
        let rls = match settings.estimator {
            EstimatorSettings::Rls(r) if fit.method == Method::Rls => Some(r),
            _ => None,
        };
        let several = fit.model.inputs().len() > 1;
        // p counts the estimated parameters only: those the estimator held fixed (a dropped deadzone
        // branch) do not enter FPE and AIC (audit s18 L-7).
        let estimated = |m: Metrics| fit.estimated_metrics(m);
        let (est, val) = (estimated(est), val.map(estimated));
        IdentifyReport {
            model: fit.model.clone(),
            inputs: several.then(|| {
                fit.model
                    .inputs()
                    .iter()
                    .map(|c| c.name().to_string())
                    .collect()
            }),
            parameters: fit.params.clone(),
            poles: poles(&fit.model),
            stable: fit.model.stability().settles(),
            stability: fit.model.stability().name().to_string(),
            estimation: EstimationInfo {
                method: fit.method,
                iterations: fit.iterations,
                converged: fit.converged(),
                forgetting: rls.map(|r| r.forgetting),
                p0: rls.map(|r| r.p0),
                passes: rls.map(|r| match r.passes {
                    Passes::Fixed(_) => "fixed".to_string(),
                    Passes::UntilSettled { .. } => "until-settled".to_string(),
                }),
                noise_variance: (!fit.noise_variance.is_nan()).then_some(fit.noise_variance),
                note: fit.note(),
                returned: fit.warnings.iter().find_map(|w| match w {
                    Warning::Fallback { used, .. } => Some(used.clone()),
                    _ => None,
                }),
            },
            metrics: MetricsPair {
                estimation: est,
                validation: val,
            },
            residuals: ResidualsPair {
                estimation: ResidualEntry::Unavailable {
                    error: "not computed".into(),
                },
                validation: None,
            },
            records: None,
            // The fit's own warnings, then a deadzone that no compensator takes (audit s33 L-5; the
            // model as reported: with its operating point and data range).
            warnings: fit
                .warnings
                .iter()
                .cloned()
                .chain(Warning::if_deadzone_not_a_valve(&fit.model))
                .map(|w| w.to_string())
                .collect(),
        }
    }

    /// Pretty JSON text (ending with a newline), marked as a report (`sysid_core::data::report_json`).
    pub fn to_json(&self) -> Result<String, SysidError> {
        sysid_core::data::report_json(self, true)
            .map(|s| s + "\n")
            .map_err(|e| SysidError::Numerical(format!("the summary could not be serialised: {e}")))
    }
}

/// Metrics of a validation record (`validate --json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationMetrics {
    /// On the validation data.
    pub validation: Metrics,
}

/// Residual analysis of a validation record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationResiduals {
    /// On the validation data.
    pub validation: ResidualEntry,
}

/// The `validate --json` document: a saved model judged on new data.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidationReport {
    /// The model.
    pub model: Model,
    /// Its poles, largest modulus first.
    pub poles: Vec<Pole>,
    /// The model settles: its stability verdict ([`Model::stability`]) is `settles`, every pole inside
    /// the unit circle by more than ε = [`sysid_core::stability::MARGIN`] = 10⁻⁵ (an integrator, a pole
    /// on the circle and an unstable model are not stable).
    pub stable: bool,
    /// The stability verdict's name ([`sysid_core::Stability::name`]): `settles`, `integrator`,
    /// `on_circle` or `unstable`; the same for the same model in every command.
    #[serde(default)]
    pub stability: String,
    /// The first sample scored (0-based row of the record): max(K, k0), K the first sample asked for
    /// (`validate --score-from K`, 0 by default) and k0 the model's largest lag
    /// ([`sysid_core::metrics::first_scored`]). Every figure of `metrics` and `residuals` is over the
    /// rows from it on; the simulations and predictions run over the whole record all the same.
    #[serde(default)]
    pub score_from: usize,
    /// Metrics on the record.
    pub metrics: ValidationMetrics,
    /// Residual analysis on the record.
    pub residuals: ValidationResiduals,
    /// Reasons not to trust the model on this record, in words (always present).
    pub warnings: Vec<String>,
}

/// Each input's [min, max] over `data` (NaN skipped): what [`ValidationReport::from_parts`] judges
/// against the model's data range.
pub fn input_extremes(data: &Dataset) -> Vec<(f64, f64)> {
    data.input_signals()
        .iter()
        .map(|u| sysid_core::DataRange::extremes(*u))
        .collect()
}

/// The warning of a record (named `record`) judged by `model` whose input (its [min, max] per input,
/// `u`, in the model's input order) or output (`y`) is at most [`sysid::estimate::SMALLEST_SIGNAL`] in
/// magnitude: in the words of `identify`'s refusal of such a record
/// ([`sysid::estimate::tiny_signal`]), which say why its fit figures are "n/a" or wrong (their sums of
/// squares underflow; audit s35 H-2: `validate` showed "fit n/a" without a word). `None` otherwise.
pub fn tiny_signal_warning(
    model: &Model,
    u: &[(f64, f64)],
    y: (f64, f64),
    record: &str,
) -> Option<String> {
    let range = sysid_core::DataRange {
        u: u.iter().map(|&(lo, hi)| [lo, hi]).collect(),
        y: [y.0, y.1],
    };
    let names: Vec<&str> = model.inputs().iter().map(|i| i.name()).collect();
    sysid::estimate::tiny_signal(&range, &names, record).map(|e| match e {
        SysidError::Numerical(m) => m,
        e => e.to_string(),
    })
}

/// A warning per input whose [min, max] over a record (`extremes`, one pair per input, in the order of
/// `names`) leaves the estimation data's range `range` (a model's `data_range`) by more than a tenth
/// of it (`DataRange::excursion_of`, the rule of `simulate` and `control`): there the model
/// extrapolates, so its fit on the record judges equations never fitted there. The one rule of every
/// model class (ARX, Hammerstein, Wiener, several inputs, NARX: audit s28 L-1 found NARX's
/// `identify --validation` without it). None without a recorded range.
pub fn extrapolation_words<'a>(
    range: Option<&sysid_core::DataRange>,
    names: impl IntoIterator<Item = &'a str>,
    extremes: &[(f64, f64)],
) -> Vec<String> {
    let Some(range) = range else {
        return Vec::new();
    };
    extremes
        .iter()
        .zip(&range.u)
        .zip(names)
        .filter_map(|((&ext, &[lo, hi]), name)| {
            let (u_min, u_max) = sysid_core::DataRange::excursion_of(ext, (lo, hi))?;
            Some(format!(
                "the record's input {name} spans [{u_min}, {u_max}] but the model's estimation data had \
                 it in [{lo}, {hi}]: outside it the model extrapolates, so this fit judges equations \
                 never fitted there"
            ))
        })
        .collect()
}

/// `words` about a validation record, each headed "validation:" as identify prints them.
pub fn headed_validation(words: Vec<String>) -> Vec<String> {
    words
        .into_iter()
        .map(|w| format!("validation: {w}"))
        .collect()
}

impl ValidationReport {
    /// Validates `model` on `data`: metrics, residual analysis with `max_lag` lags, warnings (unstable
    /// model, negative or diverging simulation fit).
    pub fn assemble(model: &Model, data: &Dataset, max_lag: usize) -> Result<Self, SysidError> {
        Self::assemble_scored_from(model, data, max_lag, 0)
    }

    /// [`ValidationReport::assemble`] with every figure (metrics and residual analysis) over the rows
    /// k ≥ max(K, k0) of `data` only, K = `score_from` (0-based; `validate --score-from`, checked by
    /// [`sysid_core::metrics::check_scored`]). The warnings judge those figures; the input and output
    /// ranges are the whole record's (the model is driven by all of it).
    pub fn assemble_scored_from(
        model: &Model,
        data: &Dataset,
        max_lag: usize,
        score_from: usize,
    ) -> Result<Self, SysidError> {
        let m = sysid_core::metrics::metrics_scored_from(model, data, score_from)?;
        let extremes = input_extremes(data);
        let mut report = Self::from_parts(
            model,
            m,
            ResidualEntry::from(sysid::residuals::residual_analysis_scored_from(
                model, data, max_lag, score_from,
            )),
            &extremes,
            score_from,
        );
        report.warnings.extend(record_outside_data(model, data.y()));
        report.warnings.extend(tiny_signal_warning(
            model,
            &extremes,
            sysid_core::DataRange::extremes(data.y()),
            data.name(),
        ));
        Ok(report)
    }

    /// A warning per input whose [min, max] over the record (`extremes`, [`input_extremes`]; a record
    /// read in passes: `sysid::stream::Streamed::u_extremes`) leaves the model's estimation data range
    /// (its `data_range`) by more than a tenth of it (`DataRange::excursion_of`, the rule of `simulate`
    /// and `control`): there the model extrapolates, so its fit on this record judges equations never
    /// fitted there (audit s14 M-c: a fit fell from 72 to 35 % for an input scaled by 1.1, without a
    /// word). None without a recorded range.
    pub fn extrapolation_warnings_of(model: &Model, extremes: &[(f64, f64)]) -> Vec<String> {
        extrapolation_words(
            model.data_range(),
            model.inputs().iter().map(|i| i.name()),
            extremes,
        )
    }

    /// The report from metrics, a residual analysis and each input's [min, max] over the record computed
    /// elsewhere (the streaming path, `sysid::stream`), with the warnings [`ValidationReport::assemble`]
    /// gives (the one place they are put together); the figures scored from sample `score_from` = K
    /// (max(K, k0) is reported, [`sysid_core::metrics::first_scored`]).
    pub fn from_parts(
        model: &Model,
        m: Metrics,
        residuals: ResidualEntry,
        input_extremes: &[(f64, f64)],
        score_from: usize,
    ) -> Self {
        let mut warnings = Self::record_warnings(model, &m, input_extremes);
        // The record's input–residual test (audit s20 M-1), as identify's validation record.
        if let ResidualEntry::Analysis(a) = &residuals {
            warnings.extend(
                sysid::trust::input_dynamics_left(Record::Validation, a)
                    .iter()
                    .map(ToString::to_string),
            );
        }
        ValidationReport {
            model: model.clone(),
            poles: poles(model),
            stable: model.stability().settles(),
            stability: model.stability().name().to_string(),
            score_from: sysid_core::metrics::first_scored(model.k0(), score_from),
            metrics: ValidationMetrics { validation: m },
            residuals: ValidationResiduals {
                validation: residuals,
            },
            warnings,
        }
    }

    /// Every warning of a model judged on a record with metrics `m` and inputs spanning
    /// `input_extremes` ([`input_extremes`]): [`ValidationReport::warnings_of`], then the record's input
    /// beyond the model's data range (what `validate`, its streamed path and Python's `Model.metrics`
    /// say).
    pub fn record_warnings(
        model: &Model,
        m: &Metrics,
        input_extremes: &[(f64, f64)],
    ) -> Vec<String> {
        let mut w = Self::warnings_of(model, m);
        w.extend(Self::extrapolation_warnings_of(model, input_extremes));
        w
    }

    /// The warnings of a model judged on a record with metrics `m`: an unstable or integrating model,
    /// a deadzone no compensator takes ([`Warning::if_deadzone_not_a_valve`]), a negative or diverging simulation fit, a fit flattered by the initial state, a fit far below
    /// the one the model file records on its estimation record (`sysid::trust::held_out_drop`; what
    /// `validate` and Python's `Model.metrics` say).
    pub fn warnings_of(model: &Model, m: &Metrics) -> Vec<String> {
        let estimation_fit = model.provenance().and_then(|p| p.fit_estimation_percent);
        Warning::if_not_settling(model)
            .into_iter()
            .chain(Warning::if_deadzone_not_a_valve(model))
            .chain(metric_warnings(Record::Validation, m))
            .chain(held_out_drop(
                (Record::Estimation, estimation_fit),
                (Record::Validation, guarded_fit(m)),
            ))
            .map(|w| w.to_string())
            .collect()
    }

    /// Pretty JSON text (ending with a newline), marked as a report (`sysid_core::data::report_json`).
    pub fn to_json(&self) -> Result<String, SysidError> {
        sysid_core::data::report_json(self, true)
            .map(|s| s + "\n")
            .map_err(|e| SysidError::Numerical(format!("the report could not be serialised: {e}")))
    }
}

/// How the range-based operating-point hint ([`operating_point_hint`]) begins, so that the measured
/// one ([`OperatingPointCheck`]) can join it.
const OPERATING_POINT_HINT: &str = "the output lies far from zero";

/// The fraction of the estimation record (its end) on which the measured operating-point check ranks
/// the two ARX fits when there is no validation record: NARX's default selection part.
pub const OPERATING_POINT_SELECTION: f64 = 1.0 / 3.0;

/// The most samples of each record the measured operating-point check reads: its first
/// `OPERATING_POINT_MAX_ROWS` (1000 s at the IPA's Ts = 0.01 s, plenty to tell whether a constant term
/// helps). A bound on the check's cost, the same in memory and read in passes: a record read in passes
/// (`identify --stream`) has these rows copied into memory by one pass (about 1.6 MB) and checked as in
/// memory, where the check read the whole file about 11 more times (session 25: a 1e6-row record was
/// read in 14 passes instead of 3, the streamed identification 3–4× slower than issue 16 measured).
pub const OPERATING_POINT_MAX_ROWS: usize = 100_000;

/// The measured operating-point check (audit s23 M-R1): for a model without a constant term and
/// without an operating point (no `--offset`, no `--detrend`), of any structure and method,
/// [`sysid::order::offset_hint`] — the one test `order` and NARX `identify` run — on ARX of the same
/// orders (na, nb, nk) by least squares, estimated on the estimation record and ranked on the
/// validation record (without one: estimated on the first 1 − [`OPERATING_POINT_SELECTION`] of the
/// estimation record and ranked on the rest). It speaks when a constant term c lifts that simulation fit
/// by more than [`sysid::order::OFFSET_HINT_MARGIN`] points, with both figures, so that a plant whose
/// output level is not an operating point (an integrator, whose c would be a drift) stays silent unless
/// c truly helps. One estimation record only. The records in memory: [`measured_operating_point_hint`];
/// read in passes: [`stream::identify_report`], on the same first [`OPERATING_POINT_MAX_ROWS`] rows copied into memory; the decision and
/// words are `sysid::order::offset_hint_of`'s in both.
#[derive(Debug, Clone)]
pub struct OperatingPointCheck {
    /// ARX of the model's orders by least squares, without c.
    pub arx: Identification,
    /// What is compared, in words.
    pub what: String,
    /// What to run again, with the record the figures are on.
    pub advice: String,
    /// The model's own guarded fit (%) on the record that ranks (the validation record; without
    /// one, its estimation record): ARX with c must beat it too, so that a model that already fits
    /// (a Hammerstein model of a deadzone plant, 100 %) hears nothing of what ARX would gain.
    pub own: Option<f64>,
}

impl OperatingPointCheck {
    /// The check for `fit` identified with `settings`, or `None` when it does not apply (a constant
    /// term or an operating point already). `validation`: a validation record ranks the fits.
    /// `longest`: the number of samples of the longest record the check would read (estimation or
    /// validation); beyond [`OPERATING_POINT_MAX_ROWS`] the words say which part was read.
    pub fn of(
        fit: &Fitted,
        settings: &Identification,
        metrics: &MetricsPair,
        longest: usize,
    ) -> Option<Self> {
        let validation = metrics.validation.is_some();
        let m = &fit.model;
        if settings.structure.offset || m.offset().is_some() || m.operating_point().is_some() {
            return None;
        }
        let o = settings.structure.orders;
        let cut = longest > OPERATING_POINT_MAX_ROWS;
        let max = OPERATING_POINT_MAX_ROWS;
        let on = match (validation, cut) {
            (true, false) => "the selection part here: the validation record".to_string(),
            (true, true) => format!(
                "the selection part here: the validation record's first {max} samples, estimated on the estimation \
                 record's first {max}"
            ),
            (false, false) => {
                "the selection part here: the last third of the estimation record, estimated on the rest".to_string()
            }
            (false, true) => format!(
                "the selection part here: the last third of the estimation record's first {max} samples, estimated \
                 on the rest of them"
            ),
        };
        Some(OperatingPointCheck {
            arx: Identification::default()
                .with_kind(sysid::ModelKind::Arx)
                .with_method(Method::Ls)
                .with_orders(o.na, o.nb, o.nk),
            what: format!(
                "ARX of the same orders ({}, {}, {}), by ls,",
                o.na, o.nb, o.nk
            ),
            advice: format!("{OFFSET_ADVICE} ({on})"),
            own: guarded_fit(metrics.validation.as_ref().unwrap_or(&metrics.estimation)),
        })
    }

    /// Whether the check may apply to a model identified with `settings` and `detrend`, as known before
    /// the fit: never with a constant term (`--offset`) or an operating point (`--detrend`), where
    /// [`OperatingPointCheck::of`] returns `None` whatever the fit. A record read in passes keeps its
    /// first rows for the check only when it may apply ([`stream::identify_report`]).
    pub fn may_apply(settings: &Identification, detrend: sysid::detrend::Detrend) -> bool {
        !settings.structure.offset && detrend == sysid::detrend::Detrend::None
    }

    /// The estimation rows of an estimation record of `n` samples when there is no validation record
    /// (the rest ranks).
    pub fn estimation_rows(n: usize) -> Option<usize> {
        sysid::data::split_rows(n, 1.0 - OPERATING_POINT_SELECTION).ok()
    }
}

/// The [`OperatingPointCheck`] of a fit on records in memory (one estimation record; several: `None`).
pub fn measured_operating_point_hint(
    fit: &Fitted,
    settings: &Identification,
    (est_data, val_data): (&[Dataset], Option<&Dataset>),
    metrics: &MetricsPair,
) -> Option<String> {
    let [est] = est_data else { return None };
    let longest = est.len().max(val_data.map_or(0, Dataset::len));
    measured_operating_point_hint_of(fit, settings, (est, val_data), metrics, longest)
}

/// [`measured_operating_point_hint`] on `est` and `val_data` whose longest record (before any of it was
/// left out) had `longest` samples: the check reads their first [`OPERATING_POINT_MAX_ROWS`] samples
/// (a record read in passes: [`stream::identify_report`] passes those, with the record's length).
pub(crate) fn measured_operating_point_hint_of(
    fit: &Fitted,
    settings: &Identification,
    (est, val_data): (&Dataset, Option<&Dataset>),
    metrics: &MetricsPair,
    longest: usize,
) -> Option<String> {
    let c = OperatingPointCheck::of(fit, settings, metrics, longest)?;
    let words = (c.what.as_str(), c.advice.as_str());
    let o = c.arx.structure.orders;
    // The first OPERATING_POINT_MAX_ROWS samples of each record.
    let head = |d: &Dataset| {
        (d.len() > OPERATING_POINT_MAX_ROWS).then(|| d.rows(0..OPERATING_POINT_MAX_ROWS))
    };
    let (est_head, val_head) = (head(est), val_data.and_then(head));
    let est = est_head.as_ref().unwrap_or(est);
    let val_data = val_head.as_ref().or(val_data);
    match val_data {
        Some(v) => sysid::order::offset_hint((est, Some(v)), &c.arx, (o, None, c.own), words),
        None => {
            let (n, k) = (est.len(), OperatingPointCheck::estimation_rows(est.len())?);
            sysid::order::offset_hint(
                (&est.rows(0..k), Some(&est.rows(k..n))),
                &c.arx,
                (o, None, c.own),
                words,
            )
        }
    }
}

/// What to run again when a constant term or an operating point would help, in the words of both
/// surfaces, the command line's flags and the Python package's keywords (audit s25 L-5: the Python
/// keyword of `--detrend mean` was left out).
pub const OFFSET_ADVICE: &str =
    "identify again with --offset (a constant c) or --detrend mean (Python: \
     offset=True or detrend=\"mean\")";

/// When a model without a constant term and without an operating point simulates worse than the mean
/// (a negative fit on either record) or has a fit the initial state flatters (the fits from estimated
/// and measured initial outputs more than `INITIAL_STATE_MARGIN` points apart; audit s20 L-2), and its estimation output lies far from zero (its recorded range
/// [lo, hi] excludes 0 and min(|lo|, |hi|) exceeds hi − lo): the likely cause in words, with the flags
/// that fix it (audit s14 M-a: fits of −1465 … −2033 % on real records, nine warnings, none naming
/// `--offset` or `--detrend`). The range is the model's (`data_range`), so the in-memory and the
/// streamed paths say the same.
fn operating_point_hint(model: &Model, m: &MetricsPair) -> Option<String> {
    if model.offset().is_some() || model.operating_point().is_some() {
        return None;
    }
    let negative = |x: Option<&Metrics>| {
        x.is_some_and(|x| {
            [x.fit_sim_percent, x.fit_sim_measured_percent]
                .into_iter()
                .flatten()
                .any(|f| f < 0.0)
        })
    };
    // Or a fit the initial state flatters by more than the margin (audit s20 L-2: the gas furnace
    // without --offset, 45.35 % from estimated against 0.82 % from measured initial outputs, a pole at
    // 0.99989 carrying the level, was told only of "a slow or spurious mode").
    let flattered = |x: &Metrics| {
        matches!((x.fit_sim_percent, x.fit_sim_measured_percent),
            (Some(e), Some(k)) if (e - k).abs() > sysid::trust::INITIAL_STATE_MARGIN)
    };
    let why = if negative(Some(&m.estimation)) || negative(m.validation.as_ref()) {
        "the negative fit"
    } else if flattered(&m.estimation) || m.validation.as_ref().is_some_and(flattered) {
        "the gap between the fits from estimated and from measured initial outputs (the initial state \
         sets the level)"
    } else {
        return None;
    };
    let [lo, hi] = model.data_range()?.y;
    let far = (lo > 0.0 || hi < 0.0) && lo.abs().min(hi.abs()) > hi - lo;
    far.then(|| {
        format!(
            "{OPERATING_POINT_HINT} (estimation data {lo:.4} .. {hi:.4}) and the model has no \
             constant term: it can only reach that level through its dynamics, the likely cause of \
             {why}; {OFFSET_ADVICE}"
        )
    })
}

/// The fewest regression rows per estimated parameter before `identify` warns that the estimate is
/// barely determined (N < 10 p).
pub const FEW_ROWS_PER_PARAMETER: usize = 10;

/// True when `a` and `b` hold exactly the same samples (every input and the output), whatever their names.
pub fn same_samples(a: &sysid::Dataset, b: &sysid::Dataset) -> bool {
    a.y() == b.y() && a.input_signals() == b.input_signals()
}

/// The fewest consecutive samples two records must share, input and output alike, for one to count as
/// cut from the other ([`shared_run`]): long enough that two experiments from rest do not match by their
/// quiet start alone (the run must also move, see there).
pub const MIN_SHARED_SAMPLES: usize = 50;

/// The longest run of consecutive samples (every input and the output equal, bit for bit) that begins
/// at the first sample of `a` or of `b` and appears in the other: `(start in a, start in b, length)`.
/// Two cuts of one record share such a run (the later cut starts inside the earlier one), and so do a
/// record and a file that contains it (spliced, or the whole record). `None` when no run of at least
/// `min(MIN_SHARED_SAMPLES, shorter length)` samples (and ≥ 10) is shared, or when the run's output
/// never moves (a rest both experiments started from).
pub fn shared_run(a: &sysid::Dataset, b: &sysid::Dataset) -> Option<(usize, usize, usize)> {
    let (ua, ub) = (a.input_signals(), b.input_signals());
    let (ya, yb) = (a.y(), b.y());
    let min = MIN_SHARED_SAMPLES.min(ya.len()).min(yb.len());
    if min < 10 || ua.len() != ub.len() {
        return None;
    }
    let equal = |i: usize, j: usize| {
        ya[i].to_bits() == yb[j].to_bits()
            && ua
                .iter()
                .zip(&ub)
                .all(|(x, z)| x[i].to_bits() == z[j].to_bits())
    };
    // next_change[i]: the first k > i whose output differs from y_a(i) (a run from i moves iff it
    // reaches it), so the check is O(1) per start.
    let mut next_change = vec![ya.len(); ya.len()];
    for i in (0..ya.len().saturating_sub(1)).rev() {
        next_change[i] = if ya[i + 1].to_bits() != ya[i].to_bits() {
            i + 1
        } else {
            next_change[i + 1]
        };
    }
    let mut best: Option<(usize, usize, usize)> = None;
    // The head of `b` inside `a`, then the head of `a` inside `b`: for every start, the length of the
    // common prefix of the head and the haystack from there, by the Z-algorithm over head ++ [gap] ++
    // haystack (O(len a + len b) comparisons; a start-by-start scan was quadratic on records that rest
    // for long stretches).
    for head_of_b in [true, false] {
        let (head_len, hay_len) = if head_of_b {
            (yb.len(), ya.len())
        } else {
            (ya.len(), yb.len())
        };
        // Position p of the joined sequence: Some((i, j)) names sample i of `a` or j of `b` as the
        // pair `equal` compares; the gap at p = head_len equals nothing.
        let sample = |p: usize| -> Option<usize> {
            match p.cmp(&head_len) {
                std::cmp::Ordering::Less => Some(p),
                std::cmp::Ordering::Equal => None,
                std::cmp::Ordering::Greater => Some(p - head_len - 1),
            }
        };
        let same = |p: usize, q: usize| -> bool {
            // p is always inside the head (a prefix position), q anywhere after it.
            match (sample(p), sample(q), q > head_len) {
                (Some(h), Some(x), true) if head_of_b => equal(x, h),
                (Some(h), Some(x), true) => equal(h, x),
                (Some(h), Some(x), false) if head_of_b => {
                    yb[h].to_bits() == yb[x].to_bits()
                        && ub.iter().all(|z| z[h].to_bits() == z[x].to_bits())
                }
                (Some(h), Some(x), false) => {
                    ya[h].to_bits() == ya[x].to_bits()
                        && ua.iter().all(|z| z[h].to_bits() == z[x].to_bits())
                }
                _ => false,
            }
        };
        let total = head_len + 1 + hay_len;
        let mut z = vec![0usize; total];
        let (mut l, mut r) = (0usize, 0usize);
        for p in 1..total {
            let mut k = if p < r { (r - p).min(z[p - l]) } else { 0 };
            while p + k < total && same(k, p + k) {
                k += 1;
            }
            z[p] = k;
            if p + k > r {
                (l, r) = (p, p + k);
            }
        }
        for start in 0..hay_len {
            let n = z[head_len + 1 + start];
            let (i0, j0) = if head_of_b { (start, 0) } else { (0, start) };
            let moves = n > 0 && next_change[i0] < i0 + n;
            if n >= min && moves && best.is_none_or(|(_, _, m)| n > m) {
                best = Some((i0, j0, n));
            }
        }
    }
    best
}

/// The warning of a `what` record named `test` that holds the very samples of the estimation record
/// named `est`: the one wording of the in-memory check ([`same_samples_warning`]) and of the streamed one
/// (by the passes' checksums, `sysid_core::data::stream::CsvStream::checksum`).
pub fn same_samples_words(what: &str, test: &str, est: &str) -> String {
    format!(
        "the {what} record {test} holds the same samples as the estimation record {est}: its fit is \
         in-sample, not held out"
    )
}

/// A warning when the `what` record holds exactly the samples of the estimation record `est` (a copy
/// of the file, say), or a run of at least [`MIN_SHARED_SAMPLES`] of them (a file cut from the
/// record, or one containing it: audit s17 M-e): its fit is then in-sample, wholly or in part.
pub fn same_samples_warning(
    what: &str,
    test: &sysid::Dataset,
    est: &sysid::Dataset,
) -> Option<String> {
    if same_samples(test, est) {
        return Some(same_samples_words(what, test.name(), est.name()));
    }
    let (i, j, n) = shared_run(test, est)?;
    Some(format!(
        "the {what} record {} holds {n} consecutive samples of the estimation record {} (its samples \
         {i}..{} are the estimation record's {j}..{}: {:.0} % of the {what} record): its fit is \
         in-sample there, not held out; cut the {what} rows from a part of the experiment the \
         estimation did not use",
        test.name(),
        est.name(),
        i + n,
        j + n,
        100.0 * n as f64 / test.len().max(1) as f64
    ))
}

/// A record's name split into the file and the rows it holds, absolute in the file: `f.csv[100..600]`
/// is rows 100..600 of `f.csv`, and a cut of a cut (`f.csv[100..600][0..250]`, `--rows` then
/// `--split`) rows 100..350; `None` for the whole file (a name without a row suffix).
pub fn record_rows(name: &str) -> (&str, Option<std::ops::Range<usize>>) {
    let mut base = name;
    let mut cuts = Vec::new();
    while let Some(inner) = base.strip_suffix(']') {
        let Some(open) = inner.rfind('[') else { break };
        let Some((a, b)) = inner[open + 1..].split_once("..") else {
            break;
        };
        let (Ok(a), Ok(b)) = (a.parse::<usize>(), b.parse::<usize>()) else {
            break;
        };
        cuts.push(a..b.max(a));
        base = &inner[..open];
    }
    // The outermost cut was stripped last: compose from it inwards.
    let rows = cuts.into_iter().rev().reduce(|outer, inner| {
        let start = outer.start + inner.start;
        start.min(outer.end)..(outer.start + inner.end).min(outer.end)
    });
    (base, rows)
}

/// A warning when the record `name` of `len` rows that `validate` judges `model` on holds rows of the
/// model's own estimation record, as the model file's identification record names it
/// (`Provenance::record`: file and rows, [`record_rows`]; audit s21 M-A2): wholly, "this is the data
/// the model was estimated on", or in part, with the count. Files are compared by their path as given,
/// else by their canonical path. `None` without an identification record, for another file, or for
/// disjoint rows. Row numbers are those of the names (a record resampled on reading is numbered in
/// samples after resampling).
///
/// `columns`: the input columns and the output column the record was read from, when it has a header.
/// When the model file names its own (`Provenance::u_columns`, `y_column`) and they differ, the record
/// is another experiment of the same file and `None` is returned (audit s22 M-R2: the cascaded tanks'
/// test record uVal/yVal beside the estimation record uEst/yEst was called in-sample). A copy of the
/// estimation record under another name is found by its samples ([`same_samples_warning`]), not here.
pub fn estimation_rows_warning(
    provenance: Option<&sysid_core::model::Provenance>,
    name: &str,
    len: usize,
    columns: Option<(&[String], &str)>,
) -> Option<String> {
    let p = provenance?;
    if let (Some((u, y)), Some(est_y)) = (columns, p.y_column.as_deref()) {
        if !p.u_columns.is_empty() && (p.u_columns.as_slice() != u || est_y != y) {
            return None;
        }
    }
    let record = &p.record;
    let (est_file, est_rows) = record_rows(record);
    let (file, rows) = record_rows(name);
    let same_file = est_file == file
        || matches!(
            (std::fs::canonicalize(est_file), std::fs::canonicalize(file)),
            (Ok(a), Ok(b)) if a == b
        );
    if !same_file {
        return None;
    }
    let rows = rows.unwrap_or(0..len);
    let est_rows = est_rows.unwrap_or(0..usize::MAX);
    let shared = rows
        .end
        .min(est_rows.end)
        .saturating_sub(rows.start.max(est_rows.start));
    if shared == 0 {
        return None;
    }
    Some(if shared >= rows.len() {
        format!(
            "this is the data the model was estimated on (the model file's identification record \
             {record} holds every row of {name}): the fit is in-sample, not a validation; validate \
             on rows the estimation did not use"
        )
    } else {
        format!(
            "{shared} of the {} rows of {name} ({:.0} %) are rows the model was estimated on (the \
             model file's identification record {record}): the fit is in-sample there, not a pure \
             validation; validate on rows the estimation did not use",
            rows.len(),
            100.0 * shared as f64 / rows.len().max(1) as f64
        )
    })
}

/// A warning when the simulated (or predicted) output `y` of `model` leaves the range of the model's
/// estimation data by more than a tenth of that range (`DataRange::excursion`; audit s13 M3: an OE model
/// of a 0..195 mm record simulated −95..465 mm, beyond the data and the actuator's stroke, without a
/// word): the model was never fitted there, so the record says what the equations do, not what the
/// plant would. `None` without a recorded data range. `simulate --plant model:` and Python's
/// `Model.simulate` / `Model.predict`.
pub fn output_outside_data(model: &Model, y: &[f64]) -> Option<String> {
    output_outside_range(model.data_range()?, y)
}

/// [`output_outside_data`] for a recorded range (a linear or a NARX model's).
pub fn output_outside_range(range: &sysid_core::DataRange, y: &[f64]) -> Option<String> {
    let [lo, hi] = range.y;
    let (y_min, y_max) = sysid_core::DataRange::excursion(y, (lo, hi))?;
    Some(format!(
        "the simulated output spans [{y_min:.6}, {y_max:.6}] but the model's estimation data had y in \
         [{lo}, {hi}]: outside it the model extrapolates (a real actuator would meet its end stops or \
         other physics the model never saw), so this part of the record is the equations' guess, not \
         the plant's"
    ))
}

/// A warning when the input `u` driving a single-input `model` leaves the range of its estimation
/// data by more than a tenth of that range (`DataRange::excursion`, audit s12 F4): outside it the
/// model extrapolates (a NARX or polynomial block most of all). `None` for a model without a recorded
/// data range or a range `u` stays in. `simulate --plant model:` (which adds its own advice) and
/// Python's `Model.simulate` / `Model.predict`.
pub fn input_outside_data(model: &Model, u: &[f64]) -> Option<String> {
    let name = model.inputs().first().map_or("u", |c| c.name());
    input_outside_range(model.data_range()?, name, u)
}

/// A record whose output lies wholly outside the model's estimation data (beyond 10 % of that range's
/// span on one side: [`sysid_core::DataRange::excursion_of`]'s margin), in words: another operating
/// point or other units, where the fit says little about the model (audit s30 L-13: a record in ±5
/// validated against a model estimated on y in [45.6, 60.2] warned of the fit only). `None` without a
/// recorded range, or when the ranges overlap. `validate` (in memory; read in passes through
/// [`record_outside_extremes`]) and Python's `Model.metrics`.
pub fn record_outside_data(model: &Model, y: &[f64]) -> Option<String> {
    record_outside_extremes(model, sysid_core::DataRange::extremes(y))
}

/// [`record_outside_data`] of an output whose [min, max] is already known (a record read in passes).
pub fn record_outside_extremes(model: &Model, (min, max): (f64, f64)) -> Option<String> {
    let [lo, hi] = model.data_range()?.y;
    let margin = 0.1 * (hi - lo).abs();
    (min.is_finite() && max.is_finite() && (max < lo - margin || min > hi + margin)).then(|| {
        format!(
            "the record's output spans [{}, {}], wholly outside the model's estimation data (y in [{}, \
             {}]): another operating point or other units; the fit on it says little about the model",
            sysid_core::format::Shortest(min),
            sysid_core::format::Shortest(max),
            sysid_core::format::Shortest(lo),
            sysid_core::format::Shortest(hi)
        )
    })
}

/// [`input_outside_data`] for a recorded range (a linear or a NARX model's) and the input's `name`.
pub fn input_outside_range(range: &sysid_core::DataRange, name: &str, u: &[f64]) -> Option<String> {
    let [lo, hi] = *range.u.first()?;
    let (u_min, u_max) = sysid_core::DataRange::excursion(u, (lo, hi))?;
    Some(format!(
        "the input spans [{u_min}, {u_max}] but the model's estimation data had {name} in [{lo}, {hi}]: \
         outside it the model extrapolates"
    ))
}

/// The poles of a model as JSON-friendly values.
pub fn poles(model: &Model) -> Vec<Pole> {
    model
        .poles()
        .iter()
        .map(|p| Pole {
            re: p.re,
            im: p.im,
            abs: p.norm(),
        })
        .collect()
}
