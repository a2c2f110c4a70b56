//! The `identify --structure narx --json` document ([`NarxReport`]), shared by the command line and the
//! Python package (`NarxFit.to_dict()`); assembled from what `sysid::narx` computed.

use serde::Serialize;

use sysid::narx::{
    blow_up_warning, narx_metrics, narx_trust, NarxFit, NarxMetrics, NarxSettings, Refinement,
    StopCurve, StopRule, TermReport,
};
use sysid::narx_model::NarxModel;
use sysid::warnings::Record;
use sysid::{Dataset, SysidError};

/// Estimation and (optional) validation metrics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NarxMetricsPair {
    /// On the estimation record.
    pub estimation: NarxMetrics,
    /// On the validation record, if one was given.
    pub validation: Option<NarxMetrics>,
}

/// The `identify --json` document of a polynomial NARX identification.
#[derive(Debug, Clone, Serialize)]
pub struct NarxReport {
    /// Always `narx`.
    pub structure: &'static str,
    /// The model (the keys of its model file).
    pub model: NarxModel,
    /// The selected terms with coefficients, standard deviations and ERR, in FROLS order.
    pub terms: Vec<TermReport>,
    /// The selection: candidates, Σ ERR, the stopping rule's curve and chosen n.
    pub selection: SelectionReport,
    /// The simulation-error refinement, if run.
    pub refinement: Option<Refinement>,
    /// Metrics.
    pub metrics: NarxMetricsPair,
    /// Warnings in words (also printed).
    pub warnings: Vec<String>,
}

/// How the terms were selected.
#[derive(Debug, Clone, Serialize)]
pub struct SelectionReport {
    /// Number of candidate monomials.
    pub candidates: usize,
    /// Σ ERR of the selected terms.
    pub err_sum: f64,
    /// The stopping rule, its values and the chosen number of terms.
    pub stop: StopCurve,
    /// The selection part's fraction of the estimation record (rule `sim`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub selection_fraction: Option<f64>,
}

impl NarxReport {
    /// Assembles the report of `fit` with metrics on `est` and `val`; a blow-up on either record, and
    /// on the validation record a negative fit or one far below the linear least-squares ARX baseline
    /// ([`narx_trust`]) or far below the estimation fit (`sysid::trust::held_out_drop`), add a warning.
    pub fn assemble(
        fit: NarxFit,
        settings: &NarxSettings,
        est: &Dataset,
        val: Option<&Dataset>,
    ) -> Result<Self, SysidError> {
        let estimation = narx_metrics(&fit.model, est)?;
        let validation = val.map(|v| narx_metrics(&fit.model, v)).transpose()?;
        let mut warnings = fit.warnings;
        if let (Some(v), Some(vd)) = (&validation, val) {
            if let Some(k) = v.blew_up_at {
                warnings.push(blow_up_warning("validation", &v.data, k));
            }
            warnings.extend(
                narx_trust(
                    Record::Validation,
                    &fit.model,
                    settings.constant,
                    est,
                    vd,
                    v,
                )
                .iter()
                .chain(&sysid::trust::held_out_drop(
                    (Record::Estimation, estimation.fit_sim_percent),
                    (Record::Validation, v.fit_sim_percent),
                ))
                .map(ToString::to_string),
            );
            // The validation record's input beyond the estimation data's, as for every other class.
            warnings.extend(crate::headed_validation(crate::extrapolation_words(
                fit.model.data_range(),
                ["u"],
                &[sysid_core::DataRange::extremes(vd.u())],
            )));
        }
        Ok(NarxReport {
            structure: "narx",
            model: fit.model,
            terms: fit.terms,
            selection: SelectionReport {
                candidates: fit.candidates,
                err_sum: fit.err_sum,
                stop: fit.stop,
                selection_fraction: (settings.stop == StopRule::Sim).then_some(settings.selection),
            },
            refinement: fit.refinement,
            metrics: NarxMetricsPair {
                estimation,
                validation,
            },
            warnings,
        })
    }
}
