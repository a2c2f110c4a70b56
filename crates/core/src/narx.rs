//! Polynomial NARX models (nonlinear ARX with polynomial terms; Billings 2013, ch. 3; SysIdentPy):
//!
//! ```text
//! y(k) = Σ_i θ_i · m_i(k) + e(k),   m_i(k) = Π_j v_j(k)^{p_ij},   Σ_j p_ij ≤ D
//! ```
//!
//! with the lagged variables v = (y(k−1), …, y(k−na), u(k−nk), …, u(k−nk−nb+1)), D the degree and, when
//! the model has one, the constant monomial m = 1. A model keeps only the monomials (terms) that its
//! structure selection chose (orthogonal forward regression, crate `sysid`). Its free-run simulation
//! feeds back its own outputs; a polynomial feedback can blow up, which [`NarxModel::simulate`] detects
//! (a non-finite output, or one farther from the data than [`BLOW_UP_SPANS`] times their range) and
//! reports instead of returning silent nonsense.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::model::MAX_ORDER;
use crate::{PlantError, SysidError};

/// Largest polynomial degree D accepted anywhere (the number of candidate terms grows as C(n + D, D)).
pub const MAX_DEGREE: usize = 5;
/// Largest number of terms a model may hold (bounds what a model file makes the reader allocate).
pub const MAX_TERMS: usize = 10_000;
/// A free-run output farther than this many ranges of the data from the data's middle counts as a
/// blow-up of the simulation (the polynomial feedback escaped; see [`NarxModel::simulate`]).
pub const BLOW_UP_SPANS: f64 = 10.0;

/// One lagged variable of a NARX regressor: y(k − lag) (lag ≥ 1) or u(k − lag) (lag ≥ 0).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Lagged {
    /// y(k − lag), lag ≥ 1.
    Y(usize),
    /// u(k − lag), lag ≥ 0.
    U(usize),
}

impl fmt::Display for Lagged {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (s, lag) = match self {
            Lagged::Y(l) => ("y", *l),
            Lagged::U(l) => ("u", *l),
        };
        if lag == 0 {
            write!(f, "{s}(k)")
        } else {
            write!(f, "{s}(k-{lag})")
        }
    }
}

/// A monomial term Π v_j^{p_j} of lagged variables; the empty product is the constant term `1`.
/// Factors are kept sorted (y before u, smaller lag first), so equal monomials compare equal.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Term {
    factors: Vec<Lagged>,
}

impl Term {
    /// The constant term 1.
    pub fn constant() -> Self {
        Term {
            factors: Vec::new(),
        }
    }
    /// The product of `factors` (repetitions are powers), in canonical order.
    pub fn new(mut factors: Vec<Lagged>) -> Self {
        factors.sort();
        Term { factors }
    }
    /// The factors, with repetitions for powers, in canonical order.
    pub fn factors(&self) -> &[Lagged] {
        &self.factors
    }
    /// The degree Σ p_j (0 for the constant).
    pub fn degree(&self) -> usize {
        self.factors.len()
    }
    /// True for the constant term.
    pub fn is_constant(&self) -> bool {
        self.factors.is_empty()
    }
    /// True when a factor is a lagged input u(k−l): the term lets the model respond to the input.
    pub fn has_input(&self) -> bool {
        self.factors.iter().any(|f| matches!(f, Lagged::U(_)))
    }
    /// The value of the monomial given the value of each factor.
    #[inline]
    fn eval(&self, value: impl Fn(Lagged) -> f64) -> f64 {
        self.factors.iter().fold(1.0, |acc, &v| acc * value(v))
    }
}

impl fmt::Display for Term {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.factors.is_empty() {
            return f.write_str("1");
        }
        let mut first = true;
        let mut i = 0;
        while i < self.factors.len() {
            let v = self.factors[i];
            let power = self.factors[i..].iter().take_while(|&&w| w == v).count();
            if !first {
                f.write_str("*")?;
            }
            first = false;
            write!(f, "{v}")?;
            if power > 1 {
                write!(f, "^{power}")?;
            }
            i += power;
        }
        Ok(())
    }
}

impl FromStr for Term {
    type Err = String;
    /// Parses `1`, `y(k-1)`, `u(k)`, `y(k-1)^2*u(k-2)`.
    fn from_str(text: &str) -> Result<Self, String> {
        let text = text.trim();
        if text == "1" {
            return Ok(Term::constant());
        }
        let mut factors = Vec::new();
        for part in text.split('*') {
            let part = part.trim();
            let (var, power) = match part.split_once('^') {
                Some((v, p)) => (
                    v.trim(),
                    p.trim().parse::<usize>().map_err(|_| {
                        format!("'{part}': the power after ^ must be a whole number")
                    })?,
                ),
                None => (part, 1),
            };
            if power == 0 || power > MAX_DEGREE {
                return Err(format!("'{part}': a power must be 1..{MAX_DEGREE}"));
            }
            let lagged = parse_lagged(var)?;
            factors.extend(std::iter::repeat_n(lagged, power));
            if factors.len() > MAX_DEGREE {
                return Err(format!("'{text}': degree above {MAX_DEGREE}"));
            }
        }
        Ok(Term::new(factors))
    }
}

/// `y(k-L)` or `u(k-L)`; an error in words otherwise — a lag beyond every model's orders said as such
/// (audit s32 L-4: `u(k-100000)` was "not a lagged variable").
fn parse_lagged(text: &str) -> Result<Lagged, String> {
    let not_lagged = || {
        format!(
            "'{text}' is not a lagged variable; expected y(k-L) with L >= 1 or u(k-L) with L >= 0"
        )
    };
    let (name, rest) = text.split_at(text.chars().next().map_or(0, char::len_utf8));
    let inner = rest
        .strip_prefix("(k")
        .and_then(|r| r.strip_suffix(')'))
        .ok_or_else(not_lagged)?;
    let lag = if inner.is_empty() {
        0
    } else {
        // Digits only (no sign, no spaces): a lag too long for usize is beyond the orders too.
        let digits = inner.strip_prefix('-').ok_or_else(not_lagged)?;
        if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
            return Err(not_lagged());
        }
        digits.parse::<usize>().unwrap_or(usize::MAX)
    };
    if !matches!(name, "y" | "u") || (name == "y" && lag == 0) {
        return Err(not_lagged());
    }
    // The longest lag of any model: y(k-na) with na <= MAX_ORDER, u(k-nk-nb+1) with nk, nb <= MAX_ORDER.
    if lag > 2 * MAX_ORDER {
        return Err(format!(
            "'{text}': its lag {} is outside the model's orders (a lag is at most {} samples: na, nb \
             and nk are each at most {MAX_ORDER})",
            if lag == usize::MAX { digits_of(inner) } else { lag.to_string() },
            2 * MAX_ORDER
        ));
    }
    Ok(if name == "y" {
        Lagged::Y(lag)
    } else {
        Lagged::U(lag)
    })
}

/// The digits of a lag `-DIGITS` as written (one too long for usize), at most 40 characters.
fn digits_of(inner: &str) -> String {
    let d = inner.trim_start_matches('-');
    crate::error::cut_chars(d, 40).unwrap_or_else(|| d.to_string())
}

/// Every monomial of degree 1..=`degree` in the lagged variables of (na, nb, nk), plus the constant
/// when `constant`: the candidate terms of a structure selection, C(na + nb + D, D) − 1 (+ 1) of them,
/// constant first, then by degree, then in the variables' order.
pub fn candidate_terms(
    na: usize,
    nb: usize,
    nk: usize,
    degree: usize,
    constant: bool,
) -> Vec<Term> {
    let vars: Vec<Lagged> = (1..=na)
        .map(Lagged::Y)
        .chain((0..nb).map(|j| Lagged::U(nk + j)))
        .collect();
    let mut out = Vec::new();
    if constant {
        out.push(Term::constant());
    }
    // Multisets of size d drawn from vars, by non-decreasing indices.
    for d in 1..=degree {
        let mut idx = vec![0usize; d];
        if vars.is_empty() {
            break;
        }
        loop {
            out.push(Term::new(idx.iter().map(|&i| vars[i]).collect()));
            // Next non-decreasing index vector.
            let mut pos = d;
            while pos > 0 && idx[pos - 1] == vars.len() - 1 {
                pos -= 1;
            }
            if pos == 0 {
                break;
            }
            idx[pos - 1] += 1;
            let v = idx[pos - 1];
            idx[pos..].iter_mut().for_each(|i| *i = v);
        }
    }
    out
}

/// The number of candidate terms [`candidate_terms`] makes, computed without building them (to bound
/// the work a flag asks for before allocating); saturates at `usize::MAX`.
pub fn candidate_count(na: usize, nb: usize, degree: usize, constant: bool) -> usize {
    // C(n + D, D) − 1 monomials of degree 1..=D in n variables.
    let n = na + nb;
    let mut c: u128 = 1;
    for i in 1..=degree as u128 {
        c = c.saturating_mul(n as u128 + i) / i;
    }
    let c = c.saturating_sub(1) + u128::from(constant);
    usize::try_from(c).unwrap_or(usize::MAX)
}

/// A fitted polynomial NARX model: the selected terms and their coefficients θ.
///
/// Fields are private; the constructor checks that every term uses lags inside (na, nb, nk), that the
/// degree is at most D and that every coefficient is finite.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "NarxRepr", into = "NarxRepr")]
pub struct NarxModel {
    ts: f64,
    na: usize,
    nb: usize,
    nk: usize,
    degree: usize,
    terms: Vec<Term>,
    theta: Vec<f64>,
    /// The range of the estimation data (u and y), when recorded: outside it the polynomial
    /// extrapolates, and a simulation from a y0 or an input beyond it may diverge (audit s17 M-d).
    data_range: Option<crate::DataRange>,
    /// The identification that wrote the model file (its record, columns, estimation fit and
    /// warnings), as a linear model's ([`crate::model::Provenance`]): `validate` compares its fit with
    /// the estimation fit and repeats the warnings (audit s33 M-1).
    provenance: Option<Box<crate::model::Provenance>>,
}

/// The serialised form: `kind: "narx"`, Ts, the lags, the degree and the terms with their coefficients.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct NarxRepr {
    kind: NarxKind,
    ts: f64,
    na: usize,
    nb: usize,
    nk: usize,
    degree: usize,
    terms: Vec<TermRepr>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    data_range: Option<crate::DataRange>,
    /// The identification that wrote the file; absent in files written before session 33.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    identification: Option<crate::model::Provenance>,
}

#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
enum NarxKind {
    Narx,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct TermRepr {
    term: String,
    coefficient: f64,
}

impl TryFrom<NarxRepr> for NarxModel {
    type Error = SysidError;
    fn try_from(r: NarxRepr) -> Result<Self, SysidError> {
        if r.terms.len() > MAX_TERMS {
            return Err(SysidError::Data(format!(
                "invalid model: more than {MAX_TERMS} terms"
            )));
        }
        let mut terms = Vec::with_capacity(r.terms.len());
        let mut theta = Vec::with_capacity(r.terms.len());
        for t in r.terms {
            terms.push(
                t.term
                    .parse::<Term>()
                    .map_err(|e| SysidError::Data(format!("invalid model: term {e}")))?,
            );
            theta.push(t.coefficient);
        }
        NarxModel::new(r.ts, r.na, r.nb, r.nk, r.degree, terms, theta)?
            .with_data_range(r.data_range)?
            .with_provenance(r.identification)
    }
}

impl From<NarxModel> for NarxRepr {
    fn from(m: NarxModel) -> Self {
        NarxRepr {
            kind: NarxKind::Narx,
            ts: m.ts,
            na: m.na,
            nb: m.nb,
            nk: m.nk,
            degree: m.degree,
            data_range: m.data_range,
            identification: m.provenance.map(|p| *p),
            terms: m
                .terms
                .iter()
                .zip(&m.theta)
                .map(|(t, c)| TermRepr {
                    term: t.to_string(),
                    coefficient: *c,
                })
                .collect(),
        }
    }
}

/// A free-run simulation of a NARX model ([`NarxModel::simulate`]).
#[derive(Debug, Clone, PartialEq)]
pub struct NarxSimulation {
    /// ŷ(k): the measured y(k) for k < k0, then the model's own outputs; NaN from the blow-up on.
    pub y: Vec<f64>,
    /// The first sample at which the output was non-finite or left the band of [`BLOW_UP_SPANS`]
    /// ranges of the data around their middle, if it did.
    pub blew_up_at: Option<usize>,
}

impl NarxModel {
    /// A model from its parts: Ts (s), the lags na, nb, nk, the degree D, the terms and their
    /// coefficients θ (one per term). Fails on lags above [`MAX_ORDER`], D above [`MAX_DEGREE`], a term
    /// outside the lags or above D, a repeated term, or a non-finite number.
    pub fn new(
        ts: f64,
        na: usize,
        nb: usize,
        nk: usize,
        degree: usize,
        terms: Vec<Term>,
        theta: Vec<f64>,
    ) -> Result<Self, SysidError> {
        let bad = |m: String| Err(SysidError::Data(format!("invalid model: {m}")));
        crate::model::check_order("na", na)?;
        crate::model::check_order("nb", nb)?;
        crate::model::check_order("nk", nk)?;
        if degree == 0 || degree > MAX_DEGREE {
            return bad(format!("degree = {degree}; expected 1..{MAX_DEGREE}"));
        }
        if let Err(m) = crate::model::model_ts(ts) {
            return bad(m);
        }
        if terms.len() != theta.len() {
            return bad(format!(
                "{} terms but {} coefficients",
                terms.len(),
                theta.len()
            ));
        }
        if terms.is_empty() {
            return bad("a NARX model needs at least one term".into());
        }
        if theta.iter().any(|v| !v.is_finite()) {
            return bad("a coefficient is NaN or infinite".into());
        }
        for (i, t) in terms.iter().enumerate() {
            if t.degree() > degree {
                return bad(format!("term {t} has a degree above {degree}"));
            }
            let outside = t.factors().iter().any(|v| match *v {
                Lagged::Y(l) => l == 0 || l > na,
                Lagged::U(l) => l < nk || l >= nk + nb,
            });
            if outside {
                return bad(format!(
                    "term {t} uses a lag outside na = {na}, nb = {nb}, nk = {nk}"
                ));
            }
            if terms[..i].contains(t) {
                return bad(format!("term {t} appears twice"));
            }
        }
        Ok(NarxModel {
            ts,
            na,
            nb,
            nk,
            degree,
            terms,
            theta,
            data_range: None,
            provenance: None,
        })
    }

    /// The same model with the identification's record `provenance` (or without one); fails on one
    /// whose sizes a model file may not hold ([`crate::model::Provenance::check_sizes`]).
    pub fn with_provenance(
        mut self,
        provenance: Option<crate::model::Provenance>,
    ) -> Result<Self, SysidError> {
        if let Some(p) = &provenance {
            p.check_sizes()
                .map_err(|m| SysidError::Data(format!("invalid model: {m}")))?;
        }
        self.provenance = provenance.map(Box::new);
        Ok(self)
    }

    /// The identification that wrote the model file, if recorded.
    pub fn provenance(&self) -> Option<&crate::model::Provenance> {
        self.provenance.as_deref()
    }

    /// The same model with the estimation data's range recorded (`None` clears it); fails on a range
    /// that is not one finite [min, max] pair for the input and one for y.
    pub fn with_data_range(mut self, range: Option<crate::DataRange>) -> Result<Self, SysidError> {
        if let Some(r) = &range {
            r.check(1)?;
        }
        self.data_range = range;
        Ok(self)
    }

    /// The range of the data the model was estimated on, if recorded.
    pub fn data_range(&self) -> Option<&crate::DataRange> {
        self.data_range.as_ref()
    }

    /// Sampling period Ts in s.
    pub fn ts(&self) -> f64 {
        self.ts
    }
    /// na: largest output lag.
    pub fn na(&self) -> usize {
        self.na
    }
    /// nb: number of input lags.
    pub fn nb(&self) -> usize {
        self.nb
    }
    /// nk: input delay in samples.
    pub fn nk(&self) -> usize {
        self.nk
    }
    /// D: the largest degree of a term.
    pub fn degree(&self) -> usize {
        self.degree
    }
    /// The selected terms.
    pub fn terms(&self) -> &[Term] {
        &self.terms
    }
    /// θ: one coefficient per term.
    pub fn theta(&self) -> &[f64] {
        &self.theta
    }
    /// The number of estimated parameters (terms).
    pub fn parameter_count(&self) -> usize {
        self.terms.len()
    }
    /// k0 = max(na, nk + nb − 1): the first sample every regressor exists at.
    pub fn k0(&self) -> usize {
        self.na.max((self.nk + self.nb).saturating_sub(1))
    }

    /// The same model with coefficients `theta` (same terms); fails on a length mismatch or a
    /// non-finite value.
    pub fn with_theta(&self, theta: Vec<f64>) -> Result<Self, SysidError> {
        NarxModel::new(
            self.ts,
            self.na,
            self.nb,
            self.nk,
            self.degree,
            self.terms.clone(),
            theta,
        )?
        .with_data_range(self.data_range.clone())
    }

    /// The position of a lagged variable in the vector v = (y(k−1..k−na), u(k−nk..k−nk−nb+1)) that
    /// [`NarxModel::lagged_values`] fills.
    pub fn variable_index(&self, v: Lagged) -> usize {
        match v {
            Lagged::Y(l) => l - 1,
            Lagged::U(l) => self.na + l - self.nk,
        }
    }

    /// Each term as the positions of its factors in v (repeated for powers).
    pub fn term_indices(&self) -> Vec<Vec<usize>> {
        self.terms
            .iter()
            .map(|t| {
                t.factors()
                    .iter()
                    .map(|&v| self.variable_index(v))
                    .collect()
            })
            .collect()
    }

    /// Fills the first na + nb entries of `v` with y(k−1..k−na) from `y_past(lag)` and u(k−nk..k−nk−nb+1).
    #[inline]
    pub fn lagged_values(&self, k: usize, u: &[f64], y_past: impl Fn(usize) -> f64, v: &mut [f64]) {
        for l in 1..=self.na {
            v[l - 1] = y_past(l);
        }
        for j in 0..self.nb {
            v[self.na + j] = u[k - self.nk - j];
        }
    }

    /// One-step-ahead prediction ŷ(k|k−1) from the measured past outputs (the regression's fit);
    /// entries k < k0 are copies of y. Fails on records of different lengths or a non-finite value.
    pub fn predict(&self, u: &[f64], y: &[f64]) -> Result<Vec<f64>, SysidError> {
        check_lengths(u, y)?;
        let k0 = self.k0().min(y.len());
        let mut out = y[..k0].to_vec();
        let table = Monomials::of(self);
        let mut vals = table.values();
        for k in k0..y.len() {
            self.lagged_values(k, u, |l| y[k - l], &mut vals);
            table.eval(&mut vals);
            let v = table.output(&self.theta, &vals);
            if !v.is_finite() {
                let why = self
                    .overflowing_term(u, y)
                    .map_or_else(String::new, |w| format!(": {w}"));
                return Err(SysidError::Numerical(format!(
                    "the prediction of the NARX model became non-finite at sample {k}{why}"
                )));
            }
            out.push(v);
        }
        Ok(out)
    }

    /// The term whose coefficient makes the one-step prediction overflow f64 on a record whose own
    /// values do not, in words (audit s32 L-4; the NARX counterpart of
    /// [`crate::Model::overflowing_term`]): the term θ_i · m_i(k) of largest size over the record,
    /// when it exceeds √(f64::MAX / N) — beyond that its prediction errors cannot be squared and summed
    /// over the record's N rows — while every |y| and |u| stays within it. `None` when no single term
    /// explains it, or the record's own values are beyond the bound (the data are to blame then).
    pub fn overflowing_term(&self, u: &[f64], y: &[f64]) -> Option<String> {
        let rows = y.len().min(u.len());
        let limit = (f64::MAX / rows.max(1) as f64).sqrt();
        // NaN is beyond too.
        let beyond = |v: f64| v.is_nan() || v.abs() > limit;
        if y.iter().chain(u).any(|&v| beyond(v)) {
            return None;
        }
        let k0 = self.k0().min(rows);
        let idx = self.term_indices();
        let mut vals = vec![0.0; self.na + self.nb];
        // (size, term index) of the largest |θ_i m_i(k)|; NaN (0 · inf) counts as infinite.
        let mut worst: Option<(f64, usize)> = None;
        for k in k0..rows {
            self.lagged_values(k, u, |l| y[k - l], &mut vals);
            for (i, (ix, c)) in idx.iter().zip(&self.theta).enumerate() {
                let t = (c * ix.iter().map(|&j| vals[j]).product::<f64>()).abs();
                let t = if t.is_nan() { f64::INFINITY } else { t };
                if worst.is_none_or(|(w, _)| t > w) {
                    worst = Some((t, i));
                }
            }
        }
        let (size, i) = worst?;
        beyond(size).then(|| {
            format!(
                "the term {} with coefficient {:e} (the file's \"terms\"[{i}]) gives a term of {} in \
                 the one-step prediction, beyond what f64 can square and sum over the record's {rows} \
                 rows (√(f64::MAX / N) = {limit:e})",
                self.terms[i],
                self.theta[i],
                crate::format::shortest(size)
            )
        })
    }

    /// Free-run simulation (MATLAB `sim`/`compare`, infinite horizon) from the measured initial outputs
    /// y(0..k0): ŷ(k) = Σ θ_i m_i(k) with the model's own past outputs in the monomials.
    ///
    /// A polynomial feedback can escape to infinity. The run stops at the first sample whose output is
    /// non-finite or farther than [`BLOW_UP_SPANS`] ranges of y from the middle of y's range, and says so
    /// in [`NarxSimulation::blew_up_at`] (the rest of ŷ is NaN); callers warn. Fails only on records of
    /// different lengths.
    pub fn simulate(&self, u: &[f64], y: &[f64]) -> Result<NarxSimulation, SysidError> {
        self.simulate_each(u, y, &Monomials::of(self), |_, _, _| {})
    }

    /// [`NarxModel::simulate`] through the table `table` (of this model's terms, with any products a
    /// caller added), calling `each(k, v, ŷ(k))` at each sample k ≥ k0 the run reaches without a
    /// blow-up, v the table's values at k (the lagged values of the run and their products): what a
    /// computation along the run (the sensitivities of a refinement) needs, without a second pass.
    pub fn simulate_each(
        &self,
        u: &[f64],
        y: &[f64],
        table: &Monomials,
        mut each: impl FnMut(usize, &[f64], f64),
    ) -> Result<NarxSimulation, SysidError> {
        check_lengths(u, y)?;
        let (lo, hi) = y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let mid = 0.5 * (lo + hi);
        let band = BLOW_UP_SPANS * (hi - lo).max(f64::MIN_POSITIVE) + 0.5 * (hi - lo);
        let n = y.len();
        let k0 = self.k0().min(n);
        let mut out = Vec::with_capacity(n);
        out.extend_from_slice(&y[..k0]);
        let mut vals = table.values();
        for k in k0..n {
            self.lagged_values(k, u, |l| out[k - l], &mut vals);
            table.eval(&mut vals);
            let v = table.output(&self.theta, &vals);
            if !v.is_finite() || (v - mid).abs() > band {
                out.resize(n, f64::NAN);
                return Ok(NarxSimulation {
                    y: out,
                    blew_up_at: Some(k),
                });
            }
            each(k, &vals, v);
            out.push(v);
        }
        Ok(NarxSimulation {
            y: out,
            blew_up_at: None,
        })
    }
}

/// The monomials of a model's terms compiled for evaluation, sharing their products: a value vector
/// ([`Monomials::values`]) holds the na + nb lagged values v of [`NarxModel::lagged_values`], then a 1
/// (the empty product), then one slot per product of two or more factors that a term (or, through
/// [`Monomials::slot`], a caller) needs, each computed by [`Monomials::eval`] as the product of its
/// prefix (all factors but the last, itself a slot) times its last factor. A monomial's value is thus
/// ((v_a · v_b) · v_c) · …, the same multiplications in the same order as a fold over its factors
/// from 1 (1 · v_a = v_a exactly), so a simulation through this table gives the same numbers, to the
/// bit, as one that multiplies each term's factors anew; each shared prefix is multiplied once a row
/// instead of once a term.
#[derive(Debug, Clone)]
pub struct Monomials {
    /// The slot of each product of two or more factors: (slot of its prefix, position of its last
    /// factor in v), in an order where a prefix comes before the products that extend it.
    nodes: Vec<(usize, usize)>,
    /// Factor positions of each product's slot (for [`Monomials::slot`] to find a product again).
    known: std::collections::HashMap<Vec<usize>, usize>,
    /// The slot of each term of the model.
    terms: Vec<usize>,
    /// Position of the 1 (= na + nb); the nodes follow it.
    one: usize,
}

impl Monomials {
    /// The table of `model`'s terms.
    pub fn of(model: &NarxModel) -> Self {
        let one = model.na + model.nb;
        let mut table = Monomials {
            nodes: Vec::new(),
            known: std::collections::HashMap::new(),
            terms: Vec::new(),
            one,
        };
        table.terms = model
            .terms
            .iter()
            .map(|t| {
                let pos: Vec<usize> = t.factors.iter().map(|&v| model.variable_index(v)).collect();
                table.slot(&pos)
            })
            .collect();
        table
    }

    /// The slot of the product of the values at positions `pos` of v (in the order given: a term's
    /// factors in canonical order), added when new; the empty product is the 1's slot.
    pub fn slot(&mut self, pos: &[usize]) -> usize {
        match pos {
            [] => self.one,
            [a] => *a,
            [prefix @ .., last] => {
                if let Some(&s) = self.known.get(pos) {
                    return s;
                }
                let parent = self.slot(prefix);
                let s = self.one + 1 + self.nodes.len();
                self.nodes.push((parent, *last));
                self.known.insert(pos.to_vec(), s);
                s
            }
        }
    }

    /// A value vector: na + nb zeros for the lagged values, the 1, and a slot per product.
    pub fn values(&self) -> Vec<f64> {
        let mut v = vec![0.0; self.one + 1 + self.nodes.len()];
        v[self.one] = 1.0;
        v
    }

    /// Computes every product slot of `v` from its lagged values (filled by
    /// [`NarxModel::lagged_values`]).
    #[inline]
    pub fn eval(&self, v: &mut [f64]) {
        for (s, &(parent, last)) in (self.one + 1..).zip(&self.nodes) {
            v[s] = v[parent] * v[last];
        }
    }

    /// The monomials m_i of the model's terms from `v` (after [`Monomials::eval`]) into `out`.
    #[inline]
    pub fn fill(&self, v: &[f64], out: &mut [f64]) {
        for (m, &s) in out.iter_mut().zip(&self.terms) {
            *m = v[s];
        }
    }

    /// Σ θ_i m_i from `v` (after [`Monomials::eval`]), summed in the terms' order.
    #[inline(never)]
    pub fn output(&self, theta: &[f64], v: &[f64]) -> f64 {
        // A loop from the neutral element of `Iterator::sum` (the number `.sum()` would give), whose
        // accumulator the compiler keeps in a register.
        let mut acc: f64 = std::iter::empty::<f64>().sum();
        for (&s, c) in self.terms.iter().zip(theta) {
            acc += c * v[s];
        }
        acc
    }
}

fn check_lengths(u: &[f64], y: &[f64]) -> Result<(), SysidError> {
    if u.len() != y.len() {
        return Err(SysidError::Data(format!(
            "the input record has {} samples but the output record {}",
            u.len(),
            y.len()
        )));
    }
    Ok(())
}

/// A NARX model run as a [`Plant`](crate::Plant), sample by sample from rest: every past output equal
/// to y0 and every past input 0. Needs nk ≥ 1 (y(k+1) cannot depend on a u(k+1) not yet applied).
#[derive(Debug, Clone)]
pub struct NarxPlant {
    model: NarxModel,
    /// y(k), y(k−1), …, newest first (length max(na, 1)).
    y_hist: Vec<f64>,
    /// u(k), u(k−1), …, newest first (length nk + nb), filled as commands are applied.
    u_hist: Vec<f64>,
    label: String,
    /// The level every past output was set to by the last reset (y0).
    y0: f64,
    /// [min, max] of the inputs applied since the last reset.
    u_applied: (f64, f64),
}

impl NarxPlant {
    /// Wraps `model`; fails for nk = 0 (direct feed-through).
    pub fn new(model: NarxModel, label: impl Into<String>) -> Result<Self, SysidError> {
        if model.nk == 0 {
            return Err(SysidError::Data(
                "a model with nk = 0 (direct feed-through) cannot be used as a plant; nk >= 1 is needed".into(),
            ));
        }
        let y_hist = vec![0.0; model.na.max(1)];
        let u_hist = vec![0.0; model.nk + model.nb];
        Ok(NarxPlant {
            model,
            y_hist,
            u_hist,
            label: label.into(),
            y0: 0.0,
            u_applied: (f64::INFINITY, f64::NEG_INFINITY),
        })
    }
    /// The wrapped model.
    pub fn model(&self) -> &NarxModel {
        &self.model
    }

    /// Why a polynomial run diverged, in words (audit s17 M-d): the start y0 or the inputs applied
    /// beyond the estimation data's range ([`DataRange::excursion_of`](crate::DataRange::excursion_of)),
    /// where the polynomial's higher powers take over, and what to change; empty when neither left it
    /// or no range is recorded (a file written before the range was stored: then that is said).
    fn divergence_cause(&self) -> String {
        let Some(range) = self.model.data_range() else {
            return ": a polynomial model diverges outside the data it was estimated on, and this file \
                    records no data range to check the start y0 and the input against (identify \
                    again with --save-model to record it); try a y0 and an input within the \
                    estimation data's"
                .into();
        };
        let [ylo, yhi] = range.y;
        let mut why = Vec::new();
        if crate::DataRange::excursion_of((self.y0, self.y0), (ylo, yhi)).is_some() {
            why.push(format!(
                "it started from y0 = {} but the estimation data had y in [{ylo}, {yhi}] (give --y0 \
                 inside it)",
                self.y0
            ));
        }
        if let Some([ulo, uhi]) = range.u.first().copied() {
            if crate::DataRange::excursion_of(self.u_applied, (ulo, uhi)).is_some() {
                why.push(format!(
                    "its input reached [{}, {}] but the estimation data had u in [{ulo}, {uhi}] (keep \
                     the commands within it: simulate's --amplitude or --input file:CSV in the model's \
                     units; control's gains and --u-max)",
                    self.u_applied.0, self.u_applied.1
                ));
            }
        }
        if why.is_empty() {
            String::new()
        } else {
            format!(
                ": a polynomial model diverges outside the data it was estimated on, and {}",
                why.join("; and ")
            )
        }
    }
}

impl crate::Plant for NarxPlant {
    fn ts(&self) -> f64 {
        self.model.ts
    }
    fn output(&self) -> f64 {
        self.y_hist[0]
    }
    fn step(&mut self, u: f64) -> Result<f64, PlantError> {
        // u(k) enters; y(k+1) uses y(k+1−l) = y_hist[l−1] and u(k+1−l) = u_hist[l−1].
        self.u_hist.rotate_right(1);
        self.u_hist[0] = u;
        self.u_applied = (self.u_applied.0.min(u), self.u_applied.1.max(u));
        let (yh, uh) = (&self.y_hist, &self.u_hist);
        let v: f64 = self
            .model
            .terms
            .iter()
            .zip(&self.model.theta)
            .map(|(t, c)| {
                c * t.eval(|var| match var {
                    Lagged::Y(l) => yh[l - 1],
                    Lagged::U(l) => uh[l - 1],
                })
            })
            .sum();
        if !v.is_finite() {
            return Err(PlantError::Diverged(format!(
                "{} output became non-finite{}",
                self.label,
                self.divergence_cause()
            )));
        }
        self.y_hist.rotate_right(1);
        self.y_hist[0] = v;
        Ok(v)
    }
    fn reset(&mut self, y0_mm: f64) {
        self.y_hist.iter_mut().for_each(|v| *v = y0_mm);
        self.u_hist.iter_mut().for_each(|v| *v = 0.0);
        self.y0 = y0_mm;
        self.u_applied = (f64::INFINITY, f64::NEG_INFINITY);
    }
    fn name(&self) -> String {
        self.label.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // The shared-product table gives each monomial as the fold Π from 1 over its factors and the
    // output as Σ θ_i m_i in the terms' order, to the bit: every term of (2, 2, 1) up to degree 3 with
    // a constant, at values that do not round alike in any other order.
    #[test]
    fn shared_products_are_the_folds_to_the_bit() {
        let terms = candidate_terms(2, 2, 1, 3, true);
        let theta: Vec<f64> = (0..terms.len())
            .map(|i| 0.1 + 1.0 / (3.0 + i as f64))
            .collect();
        let model = NarxModel::new(1.0, 2, 2, 1, 3, terms.clone(), theta.clone()).unwrap();
        let table = Monomials::of(&model);
        let (u, y) = (
            [0.3, -1.7, 2.9, 0.11],
            [1.0 / 3.0, -2.0 / 7.0, 5.0 / 11.0, 0.0],
        );
        let mut v = table.values();
        model.lagged_values(3, &u, |l| y[3 - l], &mut v);
        table.eval(&mut v);
        let value = |f: Lagged| match f {
            Lagged::Y(l) => y[3 - l],
            Lagged::U(l) => u[3 - l],
        };
        let mut m = vec![0.0; terms.len()];
        table.fill(&v, &mut m);
        for (t, mi) in terms.iter().zip(&m) {
            let fold = t.factors().iter().fold(1.0, |acc, &f| acc * value(f));
            assert_eq!(mi.to_bits(), fold.to_bits(), "{t}");
        }
        let sum: f64 = terms
            .iter()
            .zip(&theta)
            .map(|(t, c)| c * t.factors().iter().fold(1.0, |acc, &f| acc * value(f)))
            .sum();
        assert_eq!(table.output(&theta, &v).to_bits(), sum.to_bits());
    }

    // Audit s32 L-4: a lag beyond 2 · MAX_ORDER is said as a lag outside the orders, not as "not a
    // lagged variable" (kept for what is not y(k-L) or u(k-L)).
    #[test]
    fn a_lag_beyond_the_orders_is_named_as_such() {
        let e = "u(k-100000)".parse::<Term>().unwrap_err();
        assert!(
            e.contains("its lag 100000 is outside the model's orders"),
            "{e}"
        );
        let e = "y(k-99999999999999999999999)".parse::<Term>().unwrap_err();
        assert!(
            e.contains("its lag 99999999999999999999999 is outside"),
            "{e}"
        );
        assert_eq!(
            "u(k-200)".parse::<Term>().unwrap(),
            Term::new(vec![Lagged::U(2 * MAX_ORDER)])
        );
        for bad in ["sin(u)", "y(k)", "u(k+1)", "u(k- 1)", "\u{fc}(k-1)"] {
            let e = bad.parse::<Term>().unwrap_err();
            assert!(e.contains("is not a lagged variable"), "{bad}: {e}");
        }
    }

    // Terms print and parse back; powers group repeated factors.
    #[test]
    fn terms_print_and_parse_back() {
        let t = Term::new(vec![Lagged::U(2), Lagged::Y(1), Lagged::Y(1)]);
        assert_eq!(t.to_string(), "y(k-1)^2*u(k-2)");
        assert_eq!("y(k-1)^2*u(k-2)".parse::<Term>().unwrap(), t);
        assert_eq!("u(k)".parse::<Term>().unwrap().to_string(), "u(k)");
        assert_eq!("1".parse::<Term>().unwrap(), Term::constant());
        assert!("y(k)".parse::<Term>().is_err());
        assert!("x(k-1)".parse::<Term>().is_err());
    }

    // C(n + D, D) − 1 monomials of degree 1..D in n variables: n = 3, D = 2 gives 9, + the constant.
    #[test]
    fn candidate_terms_count_the_multisets() {
        let c = candidate_terms(2, 1, 1, 2, true);
        assert_eq!(c.len(), 10);
        assert_eq!(candidate_count(2, 1, 2, true), 10);
        assert_eq!(candidate_count(4, 4, 3, false), 164);
        assert_eq!(candidate_terms(4, 4, 0, 3, false).len(), 164);
        let mut sorted = c.clone();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), c.len());
    }

    // y(k) = 0.5 y(k−1) + u(k−1)²: simulation by hand, and a plant run agrees.
    #[test]
    fn simulation_and_plant_follow_the_equation() {
        let m = NarxModel::new(
            1.0,
            1,
            1,
            1,
            2,
            vec!["y(k-1)".parse().unwrap(), "u(k-1)^2".parse().unwrap()],
            vec![0.5, 1.0],
        )
        .unwrap();
        let u = [2.0, 1.0, 0.0, 0.0];
        let y = [0.0, 9.0, 9.0, 9.0];
        let s = m.simulate(&u, &y).unwrap();
        assert_eq!(s.y, vec![0.0, 4.0, 3.0, 1.5]);
        assert_eq!(s.blew_up_at, None);
        let mut p = NarxPlant::new(m, "m").unwrap();
        crate::Plant::reset(&mut p, 0.0);
        let run = crate::run_open_loop(&mut p, &u).unwrap();
        assert_eq!(run, vec![0.0, 4.0, 3.0, 1.5]);
    }

    // y(k) = y(k−1)² from y(0) = 2 escapes: the blow-up is reported, not returned as numbers.
    #[test]
    fn a_blow_up_is_reported() {
        let m = NarxModel::new(
            1.0,
            1,
            1,
            1,
            2,
            vec!["y(k-1)^2".parse().unwrap()],
            vec![1.0],
        )
        .unwrap();
        let y = [2.0, 4.0, 16.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let s = m.simulate(&[0.0; 8], &y).unwrap();
        // Range 16, band 10 · 16 + 8 around 8: 256 at k = 3 escapes.
        assert_eq!(s.blew_up_at, Some(3));
        assert!(s.y[3].is_nan());
    }

    #[test]
    fn invalid_models_are_refused() {
        let t: Term = "y(k-3)".parse().unwrap();
        assert!(NarxModel::new(1.0, 2, 1, 1, 2, vec![t], vec![1.0]).is_err());
        let t: Term = "u(k)".parse().unwrap();
        assert!(NarxModel::new(1.0, 2, 1, 1, 2, vec![t], vec![1.0]).is_err());
        let t: Term = "y(k-1)^3".parse().unwrap();
        assert!(NarxModel::new(1.0, 2, 1, 1, 2, vec![t], vec![1.0]).is_err());
    }
}
