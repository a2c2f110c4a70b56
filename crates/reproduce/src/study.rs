//! Stage 2's result and everything after it reads: the identified models, the closed-loop tests and the
//! rule that picks the model for the simulated loops.

use control::{StepMetrics, Trace};
use report::format::estimate;
use sysid::Dataset;
use sysid::Fitted as FittedModel;
use sysid_summary::IdentifyReport;

use crate::analysis;

/// One identified model of the run.
pub(crate) struct Fitted {
    /// Key in `summary.json` `models` and in `model_<key>.json`.
    pub(crate) key: &'static str,
    /// Label in tables and figures.
    pub(crate) label: &'static str,
    /// Column heading in the terminal tables.
    pub(crate) short: &'static str,
    pub(crate) fit: FittedModel,
    pub(crate) rep: IdentifyReport,
}

/// A closed-loop test on the plant and on the stable identified model (none when no model is stable).
pub(crate) struct Loop {
    pub(crate) plant: Trace,
    pub(crate) model: Option<Trace>,
    pub(crate) m_plant: StepMetrics,
    pub(crate) m_model: Option<StepMetrics>,
}

/// An acceptance criterion: a stable `id` (the key tests and scripts use), whether it is met, and the
/// sentence that says what was compared.
pub(crate) struct Criterion {
    pub(crate) id: &'static str,
    pub(crate) met: bool,
    /// False when the criterion cannot be judged (a fit comparison between models of which one is
    /// unstable): shown as "not judged", never as a pass.
    pub(crate) judged: bool,
    pub(crate) text: String,
}

impl Criterion {
    /// The plain status: "met", "not met" or "not judged".
    pub(crate) fn status(&self) -> &'static str {
        match (self.judged, self.met) {
            (false, _) => "not judged",
            (true, true) => "met",
            (true, false) => "not met",
        }
    }
}

/// Everything a run computed; the tables, figures, report and summary are views of it.
/// The tuned controller's fixed set-point runs.
pub(crate) struct Tuned {
    pub(crate) settings: control::ControllerSettings,
    /// What `tune` said of it.
    pub(crate) verdict: crate::closed_loop::TuneVerdict,
    pub(crate) m_model: StepMetrics,
    pub(crate) m_plant: StepMetrics,
}

pub(crate) struct Study {
    pub(crate) plant_name: String,
    /// The units of the plant's u and y: the IPA's counts and mm, or a model plant's own (its estimation
    /// record's, which the model does not name: "(u's units)", "(y's units)"; audit s28 L-9).
    pub(crate) units: control::Units,
    pub(crate) ts: f64,
    pub(crate) est: Dataset,
    pub(crate) val: Dataset,
    /// `[arx, hammerstein (RLS), hammerstein_ls, hammerstein_oe]`: the first two are the paper's.
    pub(crate) models: Vec<Fitted>,
    /// Index in `models` of the model used for the open-loop test and the simulated closed loops
    /// (see [`closed_loop_choice`]); `None` when no identified model is stable.
    pub(crate) cl_model: Option<usize>,
    pub(crate) u_ol: Vec<f64>,
    pub(crate) y_ol_plant: Vec<f64>,
    pub(crate) y_ol_model: Option<Vec<f64>>,
    pub(crate) fit_ol: Option<f64>,
    pub(crate) fixed: Loop,
    pub(crate) compensated: Result<StepMetrics, String>,
    /// The tuned controller (issue 25) on the fixed set-point: its settings, metrics on the model and
    /// on the plant; the reason when it was not run.
    pub(crate) tuned: Result<Tuned, String>,
    pub(crate) unfixed: Loop,
    pub(crate) steps_plant: Vec<control::StepSegment>,
    pub(crate) steps_model: Vec<control::StepSegment>,
    pub(crate) paper_check: analysis::PaperCheck,
    pub(crate) residuals: Vec<analysis::ModelResiduals>,
    /// The calibrated twin beside the identified models, or why there is none.
    pub(crate) twin: Result<crate::twin::Twin, String>,
    /// Why the plant's runs may not deserve trust, in words (a model plant's own doubts, experiments
    /// beyond its data, each closed-loop run's: `control::loop_warnings`); empty when all is well.
    pub(crate) warnings: Vec<String>,
    pub(crate) verdicts: Vec<Criterion>,
    /// Checks of the process (not the paper's criteria): e.g. a stable model was available to control.
    pub(crate) checks: Vec<Criterion>,
}

impl Study {
    /// y's unit without parentheses: "mm", or a model plant's "y's units" (audit s28 L-9).
    pub(crate) fn y_unit(&self) -> &'static str {
        bare(self.units.y)
    }
    /// u's unit without parentheses: "counts", or a model plant's "u's units".
    pub(crate) fn u_unit(&self) -> &'static str {
        bare(self.units.u)
    }
    /// The unit of a gain from u to y: "mm/count", or a model plant's "y's units per u's unit".
    pub(crate) fn gain_unit(&self) -> String {
        if self.units == control::Units::IPA {
            "mm/count".into()
        } else {
            format!(
                "{} per {}",
                self.y_unit(),
                self.u_unit().trim_end_matches('s')
            )
        }
    }
    pub(crate) fn arx(&self) -> &Fitted {
        &self.models[0]
    }
    pub(crate) fn ham(&self) -> &Fitted {
        &self.models[1]
    }
    pub(crate) fn hammersteins(&self) -> &[Fitted] {
        &self.models[1..]
    }
    pub(crate) fn model(&self, key: &str) -> Option<&Fitted> {
        self.models.iter().find(|m| m.key == key)
    }
    /// The model the open-loop test and the simulated closed loops ran on.
    pub(crate) fn cl(&self) -> Option<&Fitted> {
        self.cl_model.and_then(|i| self.models.get(i))
    }
}

/// The rule that picks the model for the open-loop test and the simulated closed loops, in words.
pub const CLOSED_LOOP_RULE: &str = "the paper's model (Hammerstein by RLS) when all its poles are inside the unit circle; \
     otherwise the stable Hammerstein model with the best free-run fit on the validation record; otherwise the \
     linear ARX if it is stable; otherwise none (an unstable model is shown but never controlled)";

/// Applies [`CLOSED_LOOP_RULE`] to `models` (`[arx, hammerstein, ...]`).
pub(crate) fn closed_loop_choice(models: &[Fitted]) -> Option<usize> {
    if models.get(1).is_some_and(|m| m.rep.stable) {
        return Some(1);
    }
    let best = models
        .iter()
        .enumerate()
        .skip(1)
        .filter(|(_, m)| m.rep.stable)
        .max_by(|(_, a), (_, b)| {
            let f = |m: &Fitted| validation_fit(&m.rep).unwrap_or(f64::NEG_INFINITY);
            f(a).total_cmp(&f(b))
        })
        .map(|(i, _)| i);
    best.or_else(|| models.first().filter(|m| m.rep.stable).map(|_| 0))
}

/// The report's stability verdict in a word for the page's tables and headline (`stable` is only the
/// verdict `settles`): `stable`, `an integrator`, `on the stability boundary` or `UNSTABLE`
/// ([`sysid_core::Stability::word`], the one short wording).
pub(crate) fn stability_word(r: &IdentifyReport) -> &'static str {
    r.model.stability().word()
}

/// The simulation fit % of a model on the validation record that its initial state cannot flatter (the
/// worse of estimated and measured initial outputs, `sysid::trust::guarded_fit`): the figure the verdict,
/// the acceptance criteria, Table IV and the differences table quote.
pub(crate) fn validation_fit(r: &IdentifyReport) -> Option<f64> {
    r.metrics
        .validation
        .as_ref()
        .and_then(sysid::trust::guarded_fit)
}

pub(crate) fn pole_list(r: &IdentifyReport) -> String {
    r.poles
        .iter()
        .filter(|p| p.im >= 0.0)
        .map(|p| {
            if p.im.abs() < 1e-12 {
                estimate(p.re)
            } else {
                format!("{} ± {}i", estimate(p.re), estimate(p.im.abs()))
            }
        })
        .collect::<Vec<_>>()
        .join(", ")
}

/// A unit as an axis or a sentence takes it: "(y's units)" without its parentheses.
fn bare(unit: &'static str) -> &'static str {
    unit.strip_prefix('(')
        .and_then(|u| u.strip_suffix(')'))
        .unwrap_or(unit)
}
