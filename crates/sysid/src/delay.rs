//! Input delay estimation (`ipa-sysid delay`, MATLAB `delayest`): ARX models with the same na, nb and
//! every delay nk = 0..=nk_max are fitted by least squares on the same regression rows, and the delay
//! whose one-step prediction error is smallest wins.
//!
//! Every candidate has the same number of parameters (na + nb + 1: a constant term c absorbs non-zero
//! means, unlike `delayest`), and every candidate's loss is summed over the same rows k ≥ k0 =
//! max(na, nk_max + nb − 1), so the losses compare like with like.
//!
//! The smallest loss alone over-estimates the input's reach: a candidate whose first input lag comes
//! before the true delay carries one coefficient (b at lag nk) that only fits noise, and wins by a
//! fraction of a percent (audit s30 M-1: nk = 0 for a one-sample delay, b at lag 0 = −7e-4 ± 4e-4). So
//! the delay is the loss minimum moved to the next delay for as long as the leading coefficient, of
//! u(k − nk), is within [`LEAD_T`] standard deviations of 0 and the next delay fits within 5 % of the
//! minimum's loss: the first lag the data show an effect at. When another remaining candidate's loss is
//! within 5 % of the chosen one's, the delay is poorly determined by these data and the result says so.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::{Dataset, SysidError};

/// One delay tried.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DelayCandidate {
    /// nk: delay in samples.
    pub nk: usize,
    /// Loss V = (1/N) Σ ½ ε² of the one-step prediction errors (paper eq. 14), units of y²; `None` when
    /// this delay's regressors are linearly dependent (see `error`).
    pub loss: Option<f64>,
    /// b_lead: the coefficient of u(k − nk), the first input lag of this candidate (units of y per unit
    /// of u); `None` when the delay could not be fitted.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub b_lead: Option<f64>,
    /// Standard deviation of `b_lead` (√(σ̂² [(ΦᵀΦ)⁻¹]_jj), σ̂² = RSS / (N − p)); `None` when N ≤ p or
    /// it could not be computed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub b_lead_std: Option<f64>,
    /// Whether `b_lead` is within [`LEAD_T`] standard deviations of 0, or below 1e-9 of the largest
    /// input coefficient (an exact fit's rounding); false when either is unknown (no standard deviation
    /// is no evidence of a null effect).
    pub lead_within_noise: bool,
    /// Why this delay could not be fitted (for noise-free data, delays beyond the true one make the
    /// past outputs a combination of the inputs).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// The estimated delay and every candidate.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DelayEstimate {
    /// nk: the estimated input delay in samples.
    pub nk: usize,
    /// na of the ARX models compared.
    pub na: usize,
    /// nb of the ARX models compared.
    pub nb: usize,
    /// N: regression rows per candidate.
    pub n: usize,
    /// Every delay tried, in order of nk.
    pub candidates: Vec<DelayCandidate>,
    /// Ratio of the runner-up's loss to the chosen delay's (≥ 1; `None` with a single candidate). The
    /// delays set aside for a leading coefficient within noise (see `notes`) are not runners-up.
    pub margin: Option<f64>,
    /// How the delay was chosen when it is not the loss minimum, in words (the minimum's leading input
    /// coefficient within noise of 0).
    pub notes: Vec<String>,
    /// Reasons not to trust the estimate, in words (empty when all is well): the delay is poorly
    /// determined, or it is the largest one tried (the optimum may lie beyond).
    pub warnings: Vec<String>,
}

/// Whether delay `nk` among `candidates` (indexed by nk) is blocked: its own first input lag is within
/// noise of 0 and the next delay could not be fitted (an output that repeats the input makes its
/// regressors dependent), so the comparison points past nk without saying where.
fn blocked_at(candidates: &[DelayCandidate], nk: usize) -> bool {
    candidates.get(nk).is_some_and(|c| c.lead_within_noise)
        && candidates.get(nk + 1).is_some_and(|c| c.loss.is_none())
}

impl DelayEstimate {
    /// The estimate is not determined by the comparison: the chosen delay is blocked (its own first
    /// input lag within noise, the next delay not fitted; audit s35 L-2). `margin` is then `None`.
    pub fn blocked(&self) -> bool {
        blocked_at(&self.candidates, self.nk)
    }
}

/// Ratio of runner-up to best loss below which the delay counts as poorly determined.
pub const CLEAR_MARGIN: f64 = 1.05;

/// |b_lead| / σ(b_lead) below which a candidate's first input lag shows no effect (about 95 % two-sided
/// for a Gaussian estimate).
pub const LEAD_T: f64 = 2.0;

/// Relative size below which a loss or a coefficient is an exact fit's rounding: losses below
/// `ROUNDING²` · mean(y²) are equal, a lead below `ROUNDING` · max |b_j| is 0.
const ROUNDING: f64 = 1e-9;

/// Φ, y and the names of Φ's columns.
pub(crate) type ArxRegression = (DMatrix<f64>, DVector<f64>, Vec<String>);

/// The ARX regression y(k) = −Σ a_i y(k−i) + Σ_j b_j u(k−nk−j+1) + c over rows k = k0..N−1:
/// (Φ, y) with columns a1..a_na, b1..b_nb, c, allocated fallibly (a failed allocation is an error,
/// not an abort).
pub(crate) fn arx_regression(
    y: &[f64],
    u: &[f64],
    na: usize,
    nb: usize,
    nk: usize,
    k0: usize,
) -> Result<ArxRegression, SysidError> {
    let n = y.len().min(u.len()).saturating_sub(k0);
    let p = na + nb + 1;
    let mut phi = crate::ls::try_matrix(n, p, "the regression matrix")?;
    for c in 0..p {
        for (r, v) in phi.column_mut(c).iter_mut().enumerate() {
            let k = k0 + r;
            *v = if c < na {
                -y[k - 1 - c]
            } else if c < na + nb {
                u[k - nk - (c - na)]
            } else {
                1.0
            };
        }
    }
    let mut target = DVector::from_vec(crate::ls::try_zeros(n, "the regression targets")?);
    for (r, v) in target.iter_mut().enumerate() {
        *v = y[k0 + r];
    }
    let names = (1..=na)
        .map(|i| format!("a{i}"))
        .chain((1..=nb).map(|j| format!("b{j}")))
        .chain(std::iter::once("c".to_string()))
        .collect();
    Ok((phi, target, names))
}

/// The identification whose memory a delay search needs at its peak: ARX (na, nb, nk = `max_delay`)
/// with a constant term, by least squares. Its regression rows are the search's, k ≥ k0 = max(na,
/// nk_max + nb − 1), its p = na + nb + 1 parameters are every candidate's, and least squares holds
/// one candidate's Φ and [Φ | y] at a time ([`crate::Identification::numbers_per_row`]).
fn memory_identification(
    na: usize,
    nb: usize,
    max_delay: usize,
    max_memory: crate::ls::MemoryBudget,
) -> crate::Identification {
    crate::IdentifyOptions {
        model: crate::ModelKind::Arx,
        na,
        nb,
        nk: max_delay,
        method: crate::Method::Ls,
        offset: true,
        max_memory,
        ..crate::IdentifyOptions::default()
    }
    .settings()
}

/// Estimates the input delay of `data` by comparing ARX(na, nb, nk) fits for nk = 0..=max_delay
/// (the memory of one fit bounded by the default [`crate::ls::MemoryBudget`]).
pub fn estimate_delay(
    data: &Dataset,
    na: usize,
    nb: usize,
    max_delay: usize,
) -> Result<DelayEstimate, SysidError> {
    estimate_delay_with_progress(data, na, nb, max_delay, &|_| {}, Default::default())
}

/// Regression rows × candidates above which a delay search is long enough (seconds) for the command
/// line to report each candidate as it is fitted.
pub const PROGRESS_WORK: usize = 10_000_000;

/// [`estimate_delay`], calling `progress` with each candidate once it is fitted (the command line
/// prints a line per candidate on a long record, so that a search of minutes is not silent), with
/// the memory of one fit bounded by `max_memory` (`--max-memory`).
pub fn estimate_delay_with_progress(
    data: &Dataset,
    na: usize,
    nb: usize,
    max_delay: usize,
    progress: &dyn Fn(&DelayCandidate),
    max_memory: crate::ls::MemoryBudget,
) -> Result<DelayEstimate, SysidError> {
    if data.inputs().len() != 1 {
        // One delay per input would need one search per input; MATLAB `delayest` is single-input too.
        let names: Vec<&str> = data.inputs().iter().map(|i| i.name()).collect();
        return Err(SysidError::setting(
            crate::Setting::UCol,
            names.join(","),
            "one input column: the delay is estimated for one input at a time (as MATLAB delayest); \
             run it once per input (--u-col NAME)",
        ));
    }
    if nb == 0 {
        return Err(SysidError::setting(
            crate::Setting::Nb,
            nb,
            "at least one B coefficient",
        ));
    }
    // The orders every estimator accepts (near the integer limit the sizes below wrapped around and
    // the allocation panicked; audit s14 H-d).
    for (setting, v) in [(crate::Setting::Na, na), (crate::Setting::Nb, nb)] {
        if v > crate::model::MAX_ORDER {
            return Err(SysidError::setting(
                setting,
                v,
                &format!("an order of at most {}", crate::model::MAX_ORDER),
            ));
        }
    }
    if max_delay > crate::model::MAX_ORDER {
        return Err(SysidError::setting(
            crate::Setting::Other("--max-delay"),
            max_delay,
            &format!("a delay of at most {} samples", crate::model::MAX_ORDER),
        ));
    }
    let k0 = na.max(max_delay + nb - 1);
    let p = na + nb + 1;
    if data.len() < k0 + p + 1 {
        return Err(SysidError::Data(format!(
            "{}: {} samples are too few to compare delays up to {max_delay} with na = {na}, nb = {nb} \
             (at least {} are needed)",
            data.name(),
            data.len(),
            k0 + p + 1
        )));
    }
    // Φ, y and the QR's [Φ | y] of one candidate at a time, and the record: the bound of every
    // estimation's memory, checked before any of them is allocated, by the one check of every
    // identification.
    memory_identification(na, nb, max_delay, max_memory)
        .check_memory(std::slice::from_ref(data))?;
    // Signals whose squares underflow compare every delay by a loss of 0 (audit s35 H-2): refused as
    // every identification refuses them.
    if let Some(e) = crate::estimate::tiny_signal_of(data) {
        return Err(e);
    }
    let mut candidates = Vec::with_capacity(max_delay + 1);
    for nk in 0..=max_delay {
        let (phi, target, names) = arx_regression(data.y(), data.u(), na, nb, nk, k0)?;
        candidates.push(match crate::ls::solve(&phi, &target, &names) {
            Ok(sol) => {
                let rows = target.len();
                // σ̂² from the residual degrees of freedom; none left (N = p) means no σ̂ at all (NaN,
                // filtered below).
                let var =
                    Some(crate::ls::noise_variance(sol.rss, rows, p) * sol.inv_gram[(na, na)]);
                let b_lead = Some(sol.theta[na]).filter(|b| b.is_finite());
                let b_lead_std = var.filter(|v| v.is_finite() && *v >= 0.0).map(f64::sqrt);
                let b_max = sol.theta.rows(na, nb).amax();
                DelayCandidate {
                    nk,
                    loss: Some(0.5 * sol.rss / rows as f64),
                    b_lead,
                    b_lead_std,
                    lead_within_noise: match (b_lead, b_lead_std) {
                        (Some(b), Some(s)) => b.abs() < (LEAD_T * s).max(ROUNDING * b_max),
                        (Some(b), None) => b.abs() < ROUNDING * b_max,
                        _ => false,
                    },
                    error: None,
                }
            }
            Err(e) if !e.is_numerical() => DelayCandidate {
                nk,
                loss: None,
                b_lead: None,
                b_lead_std: None,
                lead_within_noise: false,
                error: Some(e.to_string()),
            },
            Err(e) => return Err(e.context(&format!("{} (nk = {nk})", data.name()))),
        });
        if let Some(c) = candidates.last() {
            progress(c);
        }
    }
    let mut order: Vec<(usize, f64)> = candidates
        .iter()
        .filter_map(|c| c.loss.map(|l| (c.nk, l)))
        .collect();
    order.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    let Some(&(min_nk, min_loss)) = order.first() else {
        return Err(SysidError::Data(format!(
            "{}: no delay in 0..={max_delay} could be fitted: {}",
            data.name(),
            candidates
                .first()
                .and_then(|c| c.error.clone())
                .unwrap_or_default()
        )));
    };
    // Loss ratio of `l` to `best` (≥ 1 for l ≥ best), losses below an exact fit's rounding counted
    // as that level (two exact fits are equal; data all zero gives 1).
    let mean_square = data.y().iter().map(|v| v * v).sum::<f64>() / data.len() as f64;
    let floor = ROUNDING * ROUNDING * mean_square;
    let ratio = |l: f64, best: f64| {
        let (l, best) = (l.max(floor), best.max(floor));
        if best > 0.0 {
            l / best
        } else {
            1.0
        }
    };
    // The delays just below `chosen` whose first input lag shows no effect: they hold `chosen`'s lags
    // and earlier ones that fit only noise, so they are no evidence of a shorter delay.
    let set_aside = |chosen: usize| {
        let mut lo = chosen;
        while lo > 0 && candidates[lo - 1].lead_within_noise {
            lo -= 1;
        }
        lo..chosen
    };
    // The best competitor of delay `chosen` (nk, loss ratio to `chosen`'s), the delays set aside left
    // out.
    let runner_up = |chosen: usize| {
        let chosen_loss = candidates[chosen].loss.unwrap_or(min_loss);
        order
            .iter()
            .filter(|&&(nk, _)| nk != chosen && !set_aside(chosen).contains(&nk))
            .map(|&(nk, l)| (nk, ratio(l, chosen_loss)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    };
    // From the loss minimum on, while its first input lag shows no effect and the next delay fits
    // almost as well, the delay is the next one (the candidates are indexed by nk). Kept only when
    // that settles the question (no other delay fits almost as well as the one reached): when many
    // delays fit alike (a gradual response), leads within noise tell nothing and the minimum stays,
    // with the warning below.
    let mut shifted = min_nk;
    while candidates[shifted].lead_within_noise
        && candidates
            .get(shifted + 1)
            .and_then(|c| c.loss)
            .is_some_and(|l| ratio(l, min_loss) < CLEAR_MARGIN)
    {
        shifted += 1;
    }
    let best_nk = if runner_up(shifted).is_none_or(|r| r.1 >= CLEAR_MARGIN) {
        shifted
    } else {
        min_nk
    };
    let best_loss = candidates[best_nk].loss.unwrap_or(min_loss);
    let lead = |c: &DelayCandidate| {
        format!(
            "{} ± {}",
            sysid_core::format::sig(c.b_lead.unwrap_or(f64::NAN), 3),
            c.b_lead_std
                .map_or_else(|| "n/a".to_string(), |s| sysid_core::format::sig(s, 2))
        )
    };
    let mut warnings = Vec::new();
    let mut notes = Vec::new();
    if best_nk != min_nk {
        notes.push(format!(
            "nk = {min_nk} has the smallest loss, but its coefficient of u(k − {min_nk}) is {} (within \
             noise of 0){}; the delay is taken as nk = {best_nk}, which fits almost as well (loss {:.3} % \
             higher){}, and no other delay does",
            lead(&candidates[min_nk]),
            match best_nk - min_nk {
                1 => String::new(),
                2 => format!(", as is that of nk = {}", min_nk + 1),
                _ => format!(", as are those of nk = {}..={}", min_nk + 1, best_nk - 1),
            },
            100.0 * (ratio(best_loss, min_loss) - 1.0),
            if candidates[best_nk].lead_within_noise {
                String::new()
            } else {
                format!(" and whose first input lag shows an effect ({})", lead(&candidates[best_nk]))
            }
        ));
    } else if let Some((nk, m)) = set_aside(best_nk)
        .filter_map(|nk| candidates[nk].loss.map(|l| (nk, ratio(l, best_loss))))
        .filter(|r| r.1 < CLEAR_MARGIN)
        .min_by(|a, b| a.1.total_cmp(&b.1))
    {
        // A shorter delay that fits almost as well only by an input lag within noise: said, not warned.
        notes.push(format!(
            "nk = {nk} fits almost as well (loss {:.3} % higher), but its coefficient of u(k − {nk}) is \
             {} (within noise of 0): it holds nk = {best_nk}'s input lags and earlier ones that fit only \
             noise, no evidence of a shorter delay",
            100.0 * (m - 1.0),
            lead(&candidates[nk])
        ));
    }
    let runner_up = runner_up(best_nk);
    // The best delay's own first input lag within noise while the next delay could not be fitted: the
    // data point past nk, but the comparison cannot say where, so no margin is claimed (audit s35 L-2:
    // y(k) = u(k − 2) exactly gave nk = 1 with a margin of 4.9e16; the warning below says why).
    let blocked = blocked_at(&candidates, best_nk);
    let margin = runner_up.map(|r| r.1).filter(|_| !blocked);
    // Every reason is kept (one used to hide the other).
    if let Some((r_nk, m)) = runner_up {
        if m < CLEAR_MARGIN {
            warnings.push(format!(
                "the delay is poorly determined: nk = {r_nk} fits almost as well (loss {:.3} % higher); \
                 the input may not excite the system enough, or the system responds gradually",
                100.0 * (m - 1.0),
            ));
        }
    }
    if candidates[best_nk].lead_within_noise {
        let next = candidates.get(best_nk + 1);
        warnings.push(format!(
            "nk = {best_nk}'s own coefficient of u(k − {best_nk}) is within noise of 0 ({}): the input \
             may act only from a later lag{}",
            lead(&candidates[best_nk]),
            match next {
                Some(c) if c.loss.is_none() => format!(
                    ", but nk = {} could not be fitted ({}); so the delay is not determined here (it may \
                     be nk = {} or more: an output that repeats the input, as an exact delayed copy, \
                     makes the past outputs and the later input lags the same regressors): try a \
                     smaller --na, --na 0 for such a copy",
                    c.nk,
                    c.error.as_deref().unwrap_or("no fit"),
                    c.nk
                ),
                Some(c) if c.loss.is_some_and(|l| ratio(l, best_loss) >= CLEAR_MARGIN) => {
                    format!(", but nk = {} fits more than 5 % worse", c.nk)
                }
                Some(_) => ", and the delays around it fit alike (the data do not tell them apart)"
                    .to_string(),
                None => String::new(),
            }
        ));
    }
    if best_nk == max_delay && max_delay > 0 {
        warnings.push(format!(
            "the best delay is the largest one tried ({max_delay}): the optimum may lie beyond the \
             searched range; try a larger --max-delay"
        ));
    }
    Ok(DelayEstimate {
        nk: best_nk,
        na,
        nb,
        n: data.len() - k0,
        candidates,
        margin: margin.filter(|m| m.is_finite()),
        notes,
        warnings,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    // Audit s35 L-2: y(k) = u(k − 2) exactly (a staircase input). With na = nb = 2, nk = 2's regressors
    // −y(k − 1) = −u(k − 3) and u(k − 3) coincide, so nk = 2 cannot be fitted, and nk = 1 fits exactly
    // with its own u(k − 1) coefficient 0: no margin is claimed and the warning says the delay is not
    // determined, with --na 0; with na = 0 the search finds nk = 2 (b(k − 2) = 1, the copy).
    #[test]
    fn an_exact_delayed_copy_claims_no_margin_for_a_blocked_delay() {
        let n = 400;
        let u: Vec<f64> = (0..n)
            .map(|k| [3.0, -1.0, 4.0, 1.0, -5.0][k / 9 % 5])
            .collect();
        let y: Vec<f64> = (0..n)
            .map(|k| if k >= 2 { u[k - 2] } else { 0.0 })
            .collect();
        let data = Dataset::new(sysid_core::data::Signals { u, y }, 0.01, "copy").unwrap();
        let est = estimate_delay(&data, 2, 2, 5).unwrap();
        assert!(est.candidates[2].loss.is_none(), "{:?}", est.candidates[2]);
        assert_eq!(est.nk, 1);
        assert_eq!(est.margin, None);
        assert!(est.blocked());
        assert!(
            est.warnings
                .iter()
                .any(|w| w.contains("the delay is not determined here") && w.contains("--na 0")),
            "{:?}",
            est.warnings
        );
        let est = estimate_delay(&data, 0, 2, 5).unwrap();
        assert_eq!(est.nk, 2);
        assert!(!est.blocked());
        assert!(est.margin.is_some_and(|m| m > CLEAR_MARGIN));
    }

    // The delay search's memory is counted as one least-squares candidate at a time: on N samples,
    // N − k0 rows (k0 = max(na, nk_max + nb − 1)) of p = na + nb + 1 parameters (a constant term),
    // each holding Φ and the QR's [Φ | y] (2p + 1 numbers) and about four for the record: 2p + 4.
    #[test]
    fn a_delay_search_is_counted_as_one_least_squares_candidate() {
        for (na, nb, max_delay) in [(2, 2, 10), (4, 1, 0), (1, 6, 3)] {
            let n = 1000;
            let u: Vec<f64> = (0..n).map(|k| (k % 7) as f64).collect();
            let data =
                Dataset::new(sysid_core::data::Signals { u: u.clone(), y: u }, 0.01, "r").unwrap();
            let id = memory_identification(na, nb, max_delay, Default::default());
            let reg = id.regression(&["u"]).unwrap();
            let k0 = na.max(max_delay + nb - 1);
            let p = na + nb + 1;
            assert_eq!(reg.rows(std::slice::from_ref(&data)), n - k0);
            assert_eq!(reg.len(), p);
            assert!(!reg.nonlinear());
            assert_eq!(id.numbers_per_row(p, reg.nonlinear()), 2 * p + 4);
        }
    }
}
