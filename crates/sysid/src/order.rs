//! Order and delay selection (MATLAB `arxstruc` / `selstruc`): every structure (na, nb, nk) of a grid is
//! estimated and ranked by its free-run simulation fit on a validation record (or on the estimation
//! record when none is given), with the normalised AIC and the FPE (paper eq. 15) of the estimation record
//! beside it. The structures are estimated in parallel (rayon).
//!
//! Ranking: the selection fit a spurious slow pole cannot game ([`crate::trust::guarded_fit`]: the worse
//! of the fits from estimated and from measured initial outputs), descending (to 1e-6 %); a structure
//! that a warning disqualifies ([`qualifies`], [`disqualifies`]: unstable, negative or diverging
//! simulation fit, estimation failed, not converged, worse than its linear start or far below the
//! linear baseline, a nonlinearity that is not physical) comes after every qualified one; ties go to fewer parameters, then to the smaller AIC. [`recommended`] is
//! the best qualified structure, and [`search_warnings`] says when there is none or when it lies on the
//! edge of the searched grid.

#[cfg(feature = "parallel")]
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::estimate::{identify, Identification};
use crate::trust::{guarded_fit, metric_warnings};
use crate::warnings::{Concern, Record, Warning};
use sysid_core::metrics::metrics;
use sysid_core::{Dataset, Orders, SysidError};

/// One evaluated structure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// na, nb, nk.
    pub orders: Orders,
    /// Number of estimated parameters p.
    pub p: usize,
    /// Fit % of the free-run simulation on the estimation record.
    pub fit_estimation: Option<f64>,
    /// The guarded fit % on the estimation record (the worse of estimated and measured initial
    /// outputs, [`crate::trust::guarded_fit`]): what the selection fit is compared with
    /// ([`crate::trust::held_out_drop`]) when there is no test record (audit s22 M-R1).
    #[serde(skip)]
    pub fit_estimation_guarded: Option<f64>,
    /// Fit % of the free-run simulation on the validation record (when given).
    pub fit_validation: Option<f64>,
    /// Normalised AIC on the estimation record (ln(mean ε²) + 2p/N).
    pub aic: Option<f64>,
    /// FPE on the estimation record (paper eq. 15).
    pub fpe: Option<f64>,
    /// The model settles: its stability verdict ([`sysid_core::Model::stability`]) is `settles`, every
    /// pole inside the unit circle by more than ε = [`sysid_core::stability::MARGIN`] (`identify`'s
    /// `stable`).
    pub stable: bool,
    /// The stability verdict's name ([`sysid_core::Stability::name`]: `settles`, `integrator`,
    /// `on_circle`, `unstable`); empty for a structure that could not be estimated.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub stability: String,
    /// The fit the ranking uses: on the validation record when given, else on the estimation record,
    /// the worse of estimated and measured initial outputs ([`crate::trust::guarded_fit`]).
    #[serde(default)]
    pub ranking_fit: Option<f64>,
    /// The identification's warnings and those of the selection record (initial state, negative fit).
    #[serde(default)]
    pub warnings: Vec<String>,
    /// Why the structure could not be estimated.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
    /// Whether that failure was numerical (`SysidError::is_numerical`) rather than the data's or a
    /// setting's: the command line's exit code when every structure fails (1 against 2).
    #[serde(skip)]
    pub error_numerical: bool,
    /// The first of its warnings that disqualifies it ([`disqualifies`]), when one does.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub disqualified: Option<String>,
}

/// Whether the warning `w` disqualifies its model from being recommended (by `order` and by `order
/// --classes`): an unstable model, a negative or diverging simulation, an estimator that did not
/// converge, an estimate that simulates worse than its linear start or far below the plain linear
/// least-squares baseline, a nonlinearity that is not physical, a NARX model without an input term.
pub fn disqualifies(w: &Warning) -> bool {
    match w {
        Warning::Unstable { .. }
        | Warning::OnCircle { .. }
        | Warning::PoorSimulation { .. }
        | Warning::NotConverged { .. }
        | Warning::LinearStartBetter { .. }
        | Warning::NonPhysicalDeadzone { .. }
        | Warning::NonlinearityShape { .. }
        | Warning::NoInputTerm { .. }
        | Warning::InputSwallowed { .. }
        | Warning::Trust(Concern::BelowBaseline { .. }) => true,
        Warning::ForInput { warning, .. } => disqualifies(warning),
        // A pole near 1 may be a true integrator (EMPS); poorly determined parameters are said, not
        // disqualifying.
        _ => false,
    }
}

/// The first of `warnings` that disqualifies its model ([`disqualifies`]), in words.
pub fn disqualification<'a>(warnings: impl IntoIterator<Item = &'a Warning>) -> Option<String> {
    warnings
        .into_iter()
        .find(|w| disqualifies(w))
        .map(ToString::to_string)
}

/// True when a candidate may be recommended: estimated (`failed` false), not diverging (`diverges`
/// false: a linear model's verdict is not `unstable`, an integrator may be recommended with its
/// warning; a NARX model's simulation does not blow up), with a non-negative ranking fit and no
/// disqualifying warning (`disqualified`, from [`disqualification`]: a pole on the unit circle away
/// from 1 is one). The one rule of `order` and `order --classes`.
pub fn qualifies(
    failed: bool,
    diverges: bool,
    ranking_fit: Option<f64>,
    disqualified: Option<&str>,
) -> bool {
    !failed && !diverges && ranking_fit.is_some_and(|f| f >= 0.0) && disqualified.is_none()
}

/// Whether a candidate diverges, from its stability verdict's name `stability` (empty: none, as for a
/// NARX model or a document written before the verdict) and its `stable` flag.
pub fn diverges(stability: &str, stable: bool) -> bool {
    match stability {
        "" => !stable,
        name => name == "unstable",
    }
}

impl Candidate {
    /// The fit the ranking uses (see [`Candidate::ranking_fit`]).
    pub fn ranking_fit(&self) -> Option<f64> {
        self.ranking_fit
    }

    /// True when the structure may be recommended ([`qualifies`]).
    pub fn qualified(&self) -> bool {
        qualifies(
            self.error.is_some(),
            diverges(&self.stability, self.stable),
            self.ranking_fit,
            self.disqualified.as_deref(),
        )
    }
}

/// The recommended structure: the best-ranked qualified one ([`Candidate::qualified`]).
pub fn recommended(ranked: &[Candidate]) -> Option<&Candidate> {
    ranked.iter().find(|c| c.qualified())
}

/// Warnings about a ranking over the grid `na` × `nb` × `nk`: no structure qualifies, or the
/// recommended one has an order at the largest value searched (the optimum may lie beyond the grid).
pub fn search_warnings(
    ranked: &[Candidate],
    na: &[usize],
    nb: &[usize],
    nk: &[usize],
) -> Vec<String> {
    let Some(best) = recommended(ranked) else {
        return vec![
            "no structure of the grid qualifies (every one is unstable, simulates worse than the mean \
             of the selection record, failed, or carries another disqualifying warning): none is \
             recommended"
                .to_string(),
        ];
    };
    let o = best.orders;
    let mut w = Vec::new();
    for (name, v, grid) in [("na", o.na, na), ("nb", o.nb, nb), ("nk", o.nk, nk)] {
        let (lo, hi) = (grid.iter().min(), grid.iter().max());
        if let (Some(&lo), Some(&hi)) = (lo, hi) {
            if hi > lo && v == hi {
                w.push(format!(
                    "the recommended {name} = {v} is the largest searched ({name} {lo}..{hi}): the optimum \
                     may lie beyond the grid; widen --{name}"
                ));
            }
        }
    }
    w
}

/// Estimates every (na, nb, nk) of the grid with the identification `base` (its orders are
/// ignored) and returns the candidates ranked best first. `progress` is called once per structure, from
/// the worker threads.
pub fn search(
    est: &Dataset,
    val: Option<&Dataset>,
    na: &[usize],
    nb: &[usize],
    nk: &[usize],
    base: &Identification,
    progress: &(dyn Fn() + Sync),
) -> Vec<Candidate> {
    let grid: Vec<Orders> = na
        .iter()
        .flat_map(|&a| {
            nb.iter().flat_map(move |&b| {
                nk.iter().map(move |&k| Orders {
                    na: a,
                    nb: b,
                    nk: k,
                })
            })
        })
        .collect();
    let run = |&o: &Orders| {
        let c = evaluate(est, val, o, base);
        progress();
        c
    };
    // With the `parallel` feature the structures are estimated on all cores.
    #[cfg(feature = "parallel")]
    let mut out: Vec<Candidate> = grid.par_iter().map(run).collect();
    #[cfg(not(feature = "parallel"))]
    let mut out: Vec<Candidate> = grid.iter().map(run).collect();
    // Fits are compared to 1e-6 % (rounding noise of an exact fit must not decide); then fewer
    // parameters, then AIC.
    let key = |c: &Candidate| {
        c.ranking_fit()
            .map_or(f64::NEG_INFINITY, |f| (f * 1e6).round())
    };
    out.sort_by(|x, y| {
        y.qualified()
            .cmp(&x.qualified())
            .then(key(y).total_cmp(&key(x)))
            .then(x.p.cmp(&y.p))
            .then_with(|| {
                x.aic
                    .unwrap_or(f64::INFINITY)
                    .total_cmp(&y.aic.unwrap_or(f64::INFINITY))
            })
    });
    out
}

/// Percentage points by which the same structure with a constant term must beat the recommended one
/// without it on the selection part before [`offset_hint`] speaks.
pub const OFFSET_HINT_MARGIN: f64 = 5.0;

/// When a model was chosen without a constant term: `base` (without c) at `orders`, estimated on `est`
/// and ranked on `val` as the order search ranks, against the same with `--offset`. A hint (in words)
/// when c fits the selection part by more than [`OFFSET_HINT_MARGIN`] points better: the output has a
/// non-zero operating point (ȳ, and ū, far from 0) that a model without c can only mimic through its
/// dynamics. `without` is the selection fit without c when already known (the search's); `what` names
/// the model compared (`the recommended (2, 2, 1)`) and `advice` says what to run again. The one test
/// behind `order`, `order --classes` (on ARX of the recommended orders) and NARX `identify` (on ARX of
/// its lags). `None` with an offset already, without a selection part, or when c does not help (an
/// integrating plant, a record about 0).
pub fn offset_hint(
    (est, val): (&Dataset, Option<&Dataset>),
    base: &Identification,
    (orders, without, own): (Orders, Option<f64>, Option<f64>),
    (what, advice): (&str, &str),
) -> Option<String> {
    if base.structure.offset {
        return None;
    }
    let val = val?;
    let without = match without {
        Some(f) => f,
        None => evaluate(est, Some(val), orders, base).ranking_fit?,
    };
    let with = evaluate(est, Some(val), orders, &base.clone().with_offset(true));
    offset_hint_of(mean_of(est.y()), &with, (without, own), (what, advice))
}

/// The mean ȳ of a record's output (0 for an empty one), as [`offset_hint`] names it.
pub fn mean_of(y: &[f64]) -> f64 {
    y.iter().sum::<f64>() / y.len().max(1) as f64
}

/// The decision and the words of [`offset_hint`] from its figures, wherever they were computed (in
/// memory, or on the first rows of a record read in passes, copied into memory): `with`, the
/// structure with a constant term c judged as the order search judges ([`judged`]), speaks when it
/// qualifies and its ranking fit beats `without` (the selection fit without c, %) by more than
/// [`OFFSET_HINT_MARGIN`] points, and beats `own` (the fit of the model identified, when the caller
/// has one that is not this ARX: a model that already fits needs no c) by as much; `mean` is ȳ of the
/// estimation part.
pub fn offset_hint_of(
    mean: f64,
    with: &Candidate,
    (without, own): (f64, Option<f64>),
    (what, advice): (&str, &str),
) -> Option<String> {
    let with_fit = with.ranking_fit.filter(|_| with.qualified())?;
    let beats = |f: f64| with_fit > f + OFFSET_HINT_MARGIN;
    (beats(without) && own.is_none_or(beats)).then(|| {
        format!(
            "the output has a non-zero operating point (mean {mean:.4} over the estimation part): {what} \
             with a constant term (--offset) fits the selection part by {with_fit:.1} % instead of \
             {without:.1} %; {advice}"
        )
    })
}

/// Refuses a search whose structures would need more memory than `base`'s
/// [`Identification::max_memory`] before any is fitted: the largest structure of the grid
/// (highest na and nb, smallest nk: the most parameters and rows) checked as
/// [`Identification::check_memory`] checks one identification, times the structures fitted at once
/// (one per worker thread with the `parallel` feature).
pub fn check_memory(
    est: &Dataset,
    na: &[usize],
    nb: &[usize],
    nk: &[usize],
    base: &Identification,
) -> Result<(), SysidError> {
    let (Some(&a), Some(&b), Some(&k)) = (na.iter().max(), nb.iter().max(), nk.iter().min()) else {
        return Ok(());
    };
    base.clone().with_orders(a, b, k).check_memory_at_once(
        std::slice::from_ref(est),
        fitted_at_once(grid_size(na, nb, nk)),
    )
}

/// How many of a search's `jobs` structures are fitted at once: one per worker thread with the
/// `parallel` feature (at most `jobs`), else one.
pub(crate) fn fitted_at_once(jobs: usize) -> usize {
    #[cfg(feature = "parallel")]
    let workers = rayon::current_num_threads();
    #[cfg(not(feature = "parallel"))]
    let workers = 1;
    workers.min(jobs).max(1)
}

/// The number of structures in a grid.
/// The most structures one search fits (orders × classes): about 10–20 s at the IPA's record sizes
/// with least squares, so that a typed range (`--na 1..100 --nb 1..100 --nk 0..100`, a million
/// structures and hours of silent work; audit s13 M10) is refused with its size instead.
pub const MAX_STRUCTURES: usize = 20_000;

/// The number of structures of the grid na × nb × nk.
pub fn grid_size(na: &[usize], nb: &[usize], nk: &[usize]) -> usize {
    na.len() * nb.len() * nk.len()
}

fn evaluate(est: &Dataset, val: Option<&Dataset>, o: Orders, base: &Identification) -> Candidate {
    let settings = Identification {
        structure: sysid_core::Structure {
            orders: o,
            ..base.structure
        },
        ..base.clone()
    };
    match identify(est, &settings) {
        Ok(fit) => judged(
            o,
            &fit,
            metrics(&fit.model, est),
            val.map(|v| metrics(&fit.model, v)),
        ),
        Err(e) => Candidate::failed(o, &e),
    }
}

impl Candidate {
    /// A structure whose identification failed with `e`.
    pub(crate) fn failed(orders: Orders, e: &SysidError) -> Self {
        Candidate {
            orders,
            p: 0,
            fit_estimation: None,
            fit_estimation_guarded: None,
            fit_validation: None,
            aic: None,
            fpe: None,
            stable: false,
            stability: String::new(),
            ranking_fit: None,
            warnings: Vec::new(),
            error: Some(e.to_string()),
            error_numerical: e.is_numerical(),
            disqualified: None,
        }
    }
}

/// A fitted structure judged as the order search judges it: its metrics on the estimation record
/// (`est`) and, when there is one, on the selection record (`val`, which then ranks it), its
/// stability and the warnings that disqualify. The metrics may come from a record in memory
/// (`sysid_core::metrics::metrics`) or read in passes (`sysid::stream::record_metrics`).
pub fn judged(
    o: Orders,
    fit: &crate::fitted::Fitted,
    est: Result<sysid_core::metrics::Metrics, SysidError>,
    val: Option<Result<sysid_core::metrics::Metrics, SysidError>>,
) -> Candidate {
    let mut c = Candidate {
        error: None,
        error_numerical: false,
        ..Candidate::failed(o, &SysidError::Numerical(String::new()))
    };
    // The estimated parameters only, as `identify` counts them (audit s30 H-1).
    c.p = fit.estimated_parameter_count();
    let est = est.map(|m| fit.estimated_metrics(m));
    let stability = fit.model.stability();
    c.stable = stability.settles();
    c.stability = stability.name().to_string();
    c.warnings = fit.warnings.iter().map(ToString::to_string).collect();
    c.disqualified = disqualification(&fit.warnings);
    match est {
        Ok(m) => {
            c.fit_estimation = m.fit_sim_percent;
            c.aic = m.aic;
            c.fpe = m.fpe;
            c.ranking_fit = guarded_fit(&m);
            c.fit_estimation_guarded = c.ranking_fit;
        }
        Err(e) => {
            c.error = Some(e.to_string());
            c.error_numerical = e.is_numerical();
        }
    }
    if let Some(v) = val {
        match v {
            Ok(m) => {
                c.fit_validation = m.fit_sim_percent;
                c.ranking_fit = guarded_fit(&m);
                let w = metric_warnings(Record::Selection, &m);
                c.disqualified = c.disqualified.take().or_else(|| disqualification(&w));
                c.warnings.extend(w.iter().map(ToString::to_string));
            }
            Err(e) => {
                c.error = Some(format!("validation: {e}"));
                c.error_numerical = e.is_numerical();
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fitted::Method;
    use sysid_core::data::Signals;
    use sysid_core::ModelKind;

    // The rule shared with `order --classes`: which warnings disqualify, and that any one of them, an
    // instability, a failure or a negative fit does.
    #[test]
    fn disqualifying_warnings_are_the_ones_that_make_a_model_unusable() {
        use crate::warnings::Concern;
        let bad = [
            Warning::Unstable {
                max_pole_modulus: 1.01,
            },
            Warning::PoorSimulation {
                record: Record::Validation,
                fit_percent: Some(-3.0),
            },
            Warning::NotConverged { how: "cap".into() },
            Warning::LinearStartBetter {
                why: "worse".into(),
            },
            Warning::NonPhysicalDeadzone {
                why: "b_l > b_r".into(),
            },
            Warning::NoInputTerm { terms: 1 },
            Warning::Trust(Concern::BelowBaseline {
                record: Record::Estimation,
                fit: 4.6,
                baseline: 40.0,
            }),
            Warning::ForInput {
                input: "u1".into(),
                warning: Box::new(Warning::NonPhysicalDeadzone { why: "x".into() }),
            },
        ];
        for w in &bad {
            assert!(disqualifies(w), "{w}");
        }
        let fine = [
            Warning::Trust(Concern::NoStandardDeviations { why: "x".into() }),
            Warning::Fallback {
                used: "linear".into(),
                why: "x".into(),
            },
        ];
        assert!(fine.iter().all(|w| !disqualifies(w)));
        assert_eq!(disqualification(&fine), None);
        let mixed = [fine[0].clone(), bad[2].clone()];
        assert_eq!(disqualification(&mixed), Some(bad[2].to_string()));
        assert!(qualifies(false, false, Some(0.0), None));
        assert!(!qualifies(true, false, Some(50.0), None));
        assert!(!qualifies(false, true, Some(50.0), None));
        assert!(!qualifies(false, false, Some(-0.1), None));
        assert!(!qualifies(false, false, None, None));
        assert!(!qualifies(false, false, Some(50.0), Some("not converged")));
        // An integrator does not diverge (it is recommended with its warning); an unstable model does.
        assert!(!diverges("integrator", false) && diverges("unstable", false));
        assert!(diverges("", false) && !diverges("", true));
    }

    // Data from y(k) = 0.6 y(k−1) + u(k−2) − 0.3 u(k−3) (na = 1, nb = 2, nk = 2), noise-free: the true
    // structure fits 100 %, and so does every structure containing it; AIC then prefers the fewest parameters.
    #[test]
    fn the_generating_structure_ranks_first() {
        let u: Vec<f64> = (0..400)
            .map(|k| (((k * 7919) % 23) as f64 - 11.0) * if (k / 17) % 2 == 0 { 1.0 } else { 0.5 })
            .collect();
        let mut y = vec![0.0; 400];
        for k in 3..400 {
            y[k] = 0.6 * y[k - 1] + u[k - 2] - 0.3 * u[k - 3];
        }
        let data = Dataset::new(Signals { u, y }, 1.0, "t").unwrap();
        let base = Identification::default()
            .with_kind(ModelKind::Arx)
            .with_method(Method::Ls);
        let r = search(&data, None, &[1, 2], &[1, 2], &[1, 2, 3], &base, &|| {});
        assert_eq!(r.len(), 12);
        assert_eq!(
            r[0].orders,
            Orders {
                na: 1,
                nb: 2,
                nk: 2
            },
            "{r:?}"
        );
        assert!(r[0].fit_estimation.unwrap() > 99.999);
    }
}
