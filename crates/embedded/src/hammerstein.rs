//! The paper's recursive Hammerstein estimator: deadzone key-term regressor (eq. 8 as reconstructed in docs/paper.md §2.3) and
//! RLS with forgetting (eqs. 9–12), the switching functions and the internal variable x̂ evaluated with
//! the latest θ̂ at every sample.
//!
//! ```text
//! y(k) = m_r h_r u(k−d) − (m_r b_r) h_r + m_l h_l u(k−d) − (m_l b_l) h_l
//!        − a_1 y(k−1) − … − a_na y(k−na) + b_2 x̂(k−d−1) + … + b_nb x̂(k−d−nb+1) + e(k)
//! θ = [m_r, m_r b_r, m_l, m_l b_l, a_1..a_na, b_2..b_nb]       (b_1 = 1: the key term)
//! φ = [h_r u(k−d), −h_r, h_l u(k−d), −h_l, −y(k−1)..−y(k−na), x̂(k−d−1)..x̂(k−d−nb+1)]
//! ```
//!
//! with d = nk, h_r = [u(k−d) ≥ b̂_r], h_l = [u(k−d) ≤ b̂_l] and x̂ = f̂(u) the current deadzone estimate.
//!
//! # Per sample (exactly `sysid`'s first RLS pass, `identify --method rls --passes 1`)
//!
//! Sample k (counted from 0 at the first [`HammersteinRls::update`]) is buffered only while
//! k < k0 = max(na, nk + nb − 1), as `sysid` starts its regression at k0. At k ≥ k0:
//!
//! 1. for k > k0: b̂_r = θ̂₂/θ̂₁ and b̂_l = θ̂₄/θ̂₃ clamped to ±limit (a ratio that is not finite keeps the
//!    previous breakpoint), m̂_r = θ̂₁, m̂_l = θ̂₃; when θ̂₁ = θ̂₃ = 0 the initial deadzone is used;
//! 2. φ(k) from that deadzone; 3. one RLS update (eqs. 9–12).
//!
//! The initial deadzone has unit slopes and the breakpoints b_l0, b_r0. `sysid` takes them from the
//! whole record (largest negative and smallest positive command, `limit` = max |u|):
//! [`HammersteinSettings::from_record`] computes the same. Online, with integer PWM commands,
//! b_l0 = −1, b_r0 = 1 and limit = 255 give the same switching on the first sample for any record;
//! only nb ≥ 2 (x̂ of the first samples) then differs slightly from the record-based start.
//! A record that never goes negative (positive) gets b_l0 = −∞ (b_r0 = +∞): the unexcited branch's
//! regressor columns stay zero, as `identify` drops that branch (m = b = 0 in the model).
//! The optional offset c of `identify --offset` is not supported.

use crate::deadzone::Deadzone;
use crate::pi::Range;
use crate::rls::{self, Form, Rls};
use crate::{Error, Float};

/// Settings of a [`HammersteinRls`]. Orders: na poles, nb coefficients of B (b1 = 1), nk delay.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HammersteinSettings<F: Float> {
    /// na: order of A.
    pub na: usize,
    /// nb ≥ 1: coefficients of B (b1 = 1 is the key term).
    pub nb: usize,
    /// nk = d: input delay in samples.
    pub nk: usize,
    /// ρ ∈ (0, 1]: forgetting factor.
    pub forgetting: F,
    /// P(0) = p0 · I (`identify --p0`, default 1e6).
    pub p0: F,
    /// Initial left breakpoint b_l0 (counts, ≤ 0; −∞ for a record that is never negative).
    pub b_l0: F,
    /// Initial right breakpoint b_r0 (counts, ≥ 0; +∞ for a record that is never positive).
    pub b_r0: F,
    /// Bound on |b̂_l|, |b̂_r| while estimating (counts; `sysid`: max |u| of the record).
    pub limit: F,
    /// Windup guard: bound T on tr P (`identify --windup trace --max-trace T`), `None` for the paper's
    /// plain forgetting.
    pub max_trace: Option<F>,
    /// Covariance form: [`Form::Standard`] (the paper's eq. 12) or [`Form::Ud`] (`--rls-form ud`; use it
    /// with f32: eq. 12 in f32 loses P's positive definiteness on IPA records, [`Error::Indefinite`]).
    pub form: Form,
}

impl<F: Float> HammersteinSettings<F> {
    /// The paper's structure na = 3, nb = 1, nk = 1 with ρ = 1, p0 = 1e6, b_l0 = −1, b_r0 = 1,
    /// limit = 255 counts (the online start for integer PWM commands), no guard, eq. 12. With f32 set
    /// `form` to [`Form::Ud`]: eq. 12 in f32 from p0 = 1e6 was refused ([`Error::Indefinite`]) within
    /// 3 000 samples on most IPA records tested (from the 10th sample on the benchmark's).
    pub fn paper() -> Self {
        HammersteinSettings {
            na: 3,
            nb: 1,
            nk: 1,
            forgetting: F::ONE,
            p0: F::from_f64(1e6),
            b_l0: -F::ONE,
            b_r0: F::ONE,
            limit: F::from_f64(255.0),
            max_trace: None,
            form: Form::Standard,
        }
    }

    /// The start `sysid` uses for a whole record of commands `u`: b_l0 = the largest u < 0 (−∞ when
    /// none), b_r0 = the smallest u > 0 (+∞ when none), limit = max |u|. Other fields are kept.
    /// Non-finite commands are ignored. 0 flops (comparisons only).
    pub fn from_record(mut self, u: &[F]) -> Self {
        let (mut max_neg, mut min_pos, mut limit) = (-F::INFINITY, F::INFINITY, F::ZERO);
        for &v in u.iter().filter(|v| v.is_finite()) {
            if v > F::ZERO && v < min_pos {
                min_pos = v;
            }
            if v < F::ZERO && v > max_neg {
                max_neg = v;
            }
            if v.abs() > limit {
                limit = v.abs();
            }
        }
        self.b_l0 = max_neg;
        self.b_r0 = min_pos;
        self.limit = limit;
        self
    }
}

/// The recursive Hammerstein estimator for n = 3 + na + nb ≤ `N` parameters and delay lines of `D`
/// samples (na ≤ D, nk + nb − 1 ≤ D). No heap; `Copy`.
///
/// Size (`core::mem::size_of`, test `state_sizes`): the [`Rls`] state plus 2 D + 11 floats (9 and the
/// plausibility range of [`with_range`](Self::with_range)) and 5 `usize`, e.g. [`PaperHrls<f64>`]
/// (N = 7, D = 3) 688 bytes on a 64-bit host, `PaperHrls<f32>` 344 bytes on a 32-bit target (376 on a
/// 64-bit host); 16 (f64) or 8 (f32) bytes less before the range (audit s33 H-2).
///
/// Cost per sample ([`flops_per_sample`]): the RLS update for n parameters plus 4 + na + 2 nb flops
/// for the deadzone from θ̂ and the regressor: 242 flops for the paper's orders with ρ < 1, 213 with
/// ρ = 1 (UD form: 291 for either with N = 7, 249 with a capacity N ≥ 8: [`flops_per_sample_ud`]);
/// plus D + D moves of the delay lines, and two comparisons for the plausibility range (four with one
/// set: y against y_min and y_max, |u| against limit; session 33, not re-timed by the benches).
#[derive(Debug, Clone, Copy)]
pub struct HammersteinRls<F: Float, const N: usize, const D: usize> {
    rls: Rls<F, N>,
    /// u(k−1), …, u(k−D).
    u_past: [F; D],
    /// y(k−1), …, y(k−D).
    y_past: [F; D],
    /// The deadzone of the switching functions and x̂ (from the latest θ̂).
    dz: Deadzone<F>,
    /// The initial deadzone (unit slopes, b_l0, b_r0).
    initial: Deadzone<F>,
    limit: F,
    na: usize,
    nb: usize,
    nk: usize,
    k0: usize,
    /// Samples seen (saturating).
    k: usize,
    /// The plausible positions y ([`with_range`](Self::with_range); none by default).
    range: Range<F>,
}

/// Why [`HammersteinRls::plausible_deadzone`] refuses an estimated deadzone (its documentation gives
/// each rule). The C interface's `ipa_hrls_deadzone` returns `IPA_NOT_PHYSICAL` for each, and
/// `ipa_hrls_deadzone_reason` the code in brackets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Implausible {
    /// No valve deadzone: a parameter not finite, b_l > 0, b_r < 0 (beyond 1e-9 · limit, the
    /// compensators' rounding) or a slope ≤ 0 (1).
    NotPhysical = 1,
    /// A breakpoint beyond ±limit, outside every command (2).
    BeyondLimit = 2,
    /// A coefficient of A beyond C(na, i) 2^i: a pole outside |z| = 2, a diverged estimate (3).
    Diverged = 3,
    /// With a range: one sample of the full command moves the model by more than the range (4).
    TooSteep = 4,
}

/// The paper's structure na = 3, nb = 1, nk = 1: 7 parameters, delay lines of 3 samples.
pub type PaperHrls<F> = HammersteinRls<F, 7, 3>;

impl<F: Float, const N: usize, const D: usize> HammersteinRls<F, N, D> {
    /// A new estimator. Errors: [`Error::Capacity`] when nb = 0 or the orders do not fit N and D;
    /// [`Error::Setting`] for ρ, p0, max_trace out of range, a breakpoint outside b_l0 ≤ 0 ≤ b_r0
    /// (NaN, b_l0 > 0, b_r0 < 0; b_l0 = −∞ or b_r0 = +∞ is an unexcited branch) or a NaN / negative
    /// limit.
    pub fn new(s: HammersteinSettings<F>) -> Result<Self, Error> {
        if s.nb == 0 {
            return Err(Error::Capacity);
        }
        let n =
            s.na.checked_add(s.nb)
                .and_then(|v| v.checked_add(3))
                .ok_or(Error::Capacity)?;
        let u_lags = s.nk.checked_add(s.nb - 1).ok_or(Error::Capacity)?;
        if n > N || s.na > D || u_lags > D {
            return Err(Error::Capacity);
        }
        // NaN breakpoints would silently switch a branch off; b_l0 = −∞ or b_r0 = +∞ is allowed (an
        // unexcited branch); b_l0 > 0 or b_r0 < 0 (+∞ / −∞ among them) is not a deadzone around
        // u = 0 (audit s19 L-2).
        let limit_bad = matches!(
            s.limit.partial_cmp(&F::ZERO),
            None | Some(core::cmp::Ordering::Less)
        );
        let crossed = s.b_l0 > F::ZERO || s.b_r0 < F::ZERO;
        if is_nan(s.b_l0) || is_nan(s.b_r0) || crossed || limit_bad {
            return Err(Error::Setting);
        }
        let mut rls = Rls::new(n, s.forgetting, s.p0)?.with_form(s.form);
        if let Some(t) = s.max_trace {
            rls = rls.with_max_trace(t)?;
        }
        let initial = Deadzone {
            b_l: s.b_l0,
            b_r: s.b_r0,
            m_l: F::ONE,
            m_r: F::ONE,
        };
        Ok(HammersteinRls {
            rls,
            u_past: [F::ZERO; D],
            y_past: [F::ZERO; D],
            dz: initial,
            initial,
            limit: s.limit,
            na: s.na,
            nb: s.nb,
            nk: s.nk,
            k0: s.na.max(u_lags),
            k: 0,
            range: Range::none(),
        })
    }

    /// The same estimator with a plausibility range [y_min, y_max] (mm) for the measured position:
    /// from then on [`update`](Self::update) refuses, with [`Error::OutOfRange`] and the state
    /// unchanged, a sample whose y lies outside it or whose command |u| exceeds `limit` (the bound the
    /// estimator already has on its breakpoints: the largest command, 255 counts for the IPA's PWM).
    /// Typically the stroke with a margin for the sensor's noise, e.g. [−5, 205] mm for a 200 mm
    /// stroke; the same range as the controller's ([`Pi::with_range`](crate::Pi::with_range)).
    /// y_min or y_max not finite, or y_min ≥ y_max, gives [`Error::Setting`]. θ̂, P and the delay lines
    /// are kept, so it can be set at any time.
    ///
    /// Why: without it every finite sample is taken, and one garbage position (an encoder glitch of
    /// 1000 mm on a 200 mm stroke, or 2e306 from a bad read) corrupts θ̂ for good: audit s33 H-2
    /// measured a deadzone of b_l −249, m_l 14× the truth after 60 s of good samples at ρ = 0.99, or
    /// every later update failing with [`Error::Numerical`]. The range also sets the scale of
    /// [`plausible_deadzone`](Self::plausible_deadzone)'s slope rule.
    ///
    /// ```
    /// use ipa_embedded::{Error, HammersteinSettings, hammerstein::PaperHrls};
    /// let mut est = PaperHrls::new(HammersteinSettings::<f64>::paper())
    ///     .unwrap()
    ///     .with_range(-5.0, 205.0)
    ///     .unwrap();
    /// assert_eq!(est.update(100.0, 1000.0), Err(Error::OutOfRange)); // y: a glitch
    /// assert_eq!(est.update(300.0, 50.0), Err(Error::OutOfRange)); // |u| > limit = 255
    /// assert_eq!(est.samples(), 0); // neither was taken
    /// assert_eq!(est.update(100.0, 50.0), Ok(None));
    /// ```
    pub fn with_range(self, y_min_mm: F, y_max_mm: F) -> Result<Self, Error> {
        Ok(HammersteinRls {
            range: Range::new(y_min_mm, y_max_mm)?,
            ..self
        })
    }

    /// The plausibility range [y_min, y_max] in mm, `None` when none was set
    /// ([`with_range`](Self::with_range)).
    pub fn range(&self) -> Option<(F, F)> {
        self.range.get()
    }

    /// Feeds sample k: the command u(k) (counts) and the measured position y(k) (mm). Returns the
    /// a-priori prediction error ε(k) = y(k) − φᵀ(k) θ̂(k−1) in mm, or `None` while the delay lines fill
    /// (k < k0). Errors leave the state unchanged: [`Error::NotFinite`] for a non-finite u or y,
    /// [`Error::OutOfRange`] with a plausibility range ([`with_range`](Self::with_range)) for y
    /// outside it or |u| > limit, [`Error::Numerical`] or [`Error::Indefinite`] from the RLS update
    /// ([`Rls::update`]). With ρ < 1 and no windup guard (`max_trace`), P grows by 1/ρ per sample in
    /// the directions the input does not excite (an actuator at rest): once it overflows or loses
    /// definiteness, the error repeats on every later sample, exciting or not, until
    /// [`restart_covariance`](Self::restart_covariance) (audit s33 M-3); set `max_trace` to prevent it.
    pub fn update(&mut self, u: F, y: F) -> Result<Option<F>, Error> {
        if !(u.is_finite() && y.is_finite()) {
            return Err(Error::NotFinite);
        }
        // With a range, |u| ≤ limit too (u is finite here and limit never NaN).
        if !self.range.contains(y) || (self.range.get().is_some() && u.abs() > self.limit) {
            return Err(Error::OutOfRange);
        }
        let mut eps = None;
        if self.k >= self.k0 {
            let mut dz = self.dz;
            if self.k > self.k0 {
                let t = self.rls.theta();
                dz = deadzone_from_theta(t, dz, self.limit);
                if first(t, 0) == F::ZERO && first(t, 2) == F::ZERO {
                    dz = self.initial;
                }
            }
            let mut phi = [F::ZERO; N];
            self.regressor(&dz, u, &mut phi)?;
            eps = Some(self.rls.update(&phi, y)?);
            self.dz = dz;
        }
        push(&mut self.u_past, u);
        push(&mut self.y_past, y);
        self.k = self.k.saturating_add(1);
        Ok(eps)
    }

    /// φ(k) for the current command u(k) = `u_now` with deadzone `dz`.
    fn regressor(&self, dz: &Deadzone<F>, u_now: F, phi: &mut [F; N]) -> Result<(), Error> {
        let mut slots = phi.iter_mut();
        let mut put = |v: F| -> Result<(), Error> {
            *slots.next().ok_or(Error::Capacity)? = v;
            Ok(())
        };
        let uk = self.u_lag(u_now, self.nk);
        let (hr, hl) = (dz.h_r(uk), dz.h_l(uk));
        put(hr * uk)?;
        put(-hr)?;
        put(hl * uk)?;
        put(-hl)?;
        for y in self.y_past.iter().take(self.na) {
            put(-*y)?;
        }
        for j in 1..self.nb {
            put(dz.apply(self.u_lag(u_now, self.nk.saturating_add(j))))?;
        }
        Ok(())
    }

    /// u(k − lag) (0 before the first sample).
    fn u_lag(&self, u_now: F, lag: usize) -> F {
        match lag.checked_sub(1) {
            None => u_now,
            Some(i) => self.u_past.get(i).copied().unwrap_or(F::ZERO),
        }
    }

    /// θ̂ = [m_r, m_r b_r, m_l, m_l b_l, a_1..a_na, b_2..b_nb] (the first n entries; the rest are 0).
    pub fn theta(&self) -> &[F; N] {
        self.rls.theta()
    }

    /// The underlying RLS state (θ̂, P).
    pub fn rls(&self) -> &Rls<F, N> {
        &self.rls
    }

    /// Restarts the covariance P = p0 · I, keeping θ̂ and the delay lines: what `ipa-sysid track` does
    /// after a detected change, so the estimate moves quickly from where it was to the changed valve.
    pub fn restart_covariance(&mut self) {
        self.rls.restart_covariance();
    }

    /// The fitted model's deadzone, as `identify` reports it: b_r = θ̂₂/θ̂₁, b_l = θ̂₄/θ̂₃ (0 when the
    /// ratio is not finite, no clamping), m_r = θ̂₁, m_l = θ̂₃.
    pub fn deadzone(&self) -> Deadzone<F> {
        let zero = Deadzone {
            b_l: F::ZERO,
            b_r: F::ZERO,
            m_l: F::ZERO,
            m_r: F::ZERO,
        };
        deadzone_from_theta(self.rls.theta(), zero, F::INFINITY)
    }

    /// The fitted deadzone ([`deadzone`](Self::deadzone)) when it is one to compensate with, or why not
    /// (the rule of `ipa_hrls_deadzone`'s [`IPA_OK`](crate::ffi::IPA_OK)), checked in this order:
    ///
    /// 1. [`Implausible::NotPhysical`]: no valve deadzone ([`Deadzone::is_physical`]: a parameter not
    ///    finite, b_l > 0, b_r < 0 or a slope ≤ 0), its breakpoints rounded first as the compensators
    ///    round them ([`rounded_breakpoints`](crate::deadzone::rounded_breakpoints) with u_max =
    ///    `limit`: a b_l ∈ (0, 1e-9 · limit] or b_r ∈ [−1e-9 · limit, 0) is taken as 0, so an estimate
    ///    that [`Compensator::new`](crate::Compensator::new) at u_max = `limit` accepts is not refused
    ///    here; with `limit` = ∞ no rounding: b_l = +1e-18 is refused). The deadzone returned carries
    ///    the rounded breakpoints;
    /// 2. [`Implausible::BeyondLimit`]: |b_l| or |b_r| > `limit`, a breakpoint beyond every command;
    /// 3. [`Implausible::Diverged`]: a coefficient |a_i| > C(na, i) 2^i. Every polynomial
    ///    1 + a_1 z⁻¹ + … + a_na z^−na whose roots lie in |z| ≤ R has |a_i| ≤ C(na, i) R^i (Vieta), so
    ///    this is a pole outside |z| = 2: a position that more than doubles every sample with no
    ///    command, no actuator's (a stable or integrating plant has its poles in |z| ≤ 1);
    /// 4. [`Implausible::TooSteep`], with a range ([`with_range`](Self::with_range)) and a finite
    ///    `limit` only: |f̂(limit)| or |f̂(−limit)| > y_max − y_min, i.e. one sample of the full
    ///    command would move the modelled position (b_1 = 1: x̂ adds to y(k + nk)) by more than the
    ///    whole plausible range. Without a range slopes have no scale in mm and are not bounded.
    ///
    /// Audit s33 H-2: one sample y = 2e306 taken without a range left m_l = 3.85e302 and
    /// a_1 = −5.4e303 (rule 3). No rule can tell a glitch of 1000 mm that left b_l = −249, m_l 14×
    /// the truth but a_1 = −1.67 from a valve; only the range, which refuses the sample, prevents it.
    /// Cost: 4 + 3 na comparisons and flops, 2 + 2 na more for the binomial bounds.
    pub fn plausible_deadzone(&self) -> Result<Deadzone<F>, Implausible> {
        // The compensators' one rounding rule, at this estimator's command limit: a breakpoint on the
        // wrong side of 0 by at most 1e-9 · limit is taken as 0 (none with an infinite limit).
        let raw = self.deadzone();
        let (b_l, b_r) = crate::deadzone::rounded_breakpoints(raw.b_l, raw.b_r, self.limit);
        let d = Deadzone { b_l, b_r, ..raw };
        if !d.is_physical() {
            return Err(Implausible::NotPhysical);
        }
        if !(-self.limit <= d.b_l && d.b_r <= self.limit) {
            return Err(Implausible::BeyondLimit);
        }
        // C(na, i) 2^i = C(na, i − 1) 2^(i − 1) · 2 (na − i + 1) / i, exact in floating point for
        // na ≤ 8 (integers below 2^24).
        let mut bound = F::ONE;
        let a = self.rls.theta().iter().skip(4).take(self.na);
        for (i, &ai) in (1..).zip(a) {
            let (num, den) = (self.na + 1 - i, i);
            bound = bound * F::from_f64((2 * num) as f64) / F::from_f64(den as f64);
            let within = ai.is_finite() && ai.abs() <= bound;
            if !within {
                return Err(Implausible::Diverged);
            }
        }
        if let Some(span) = self.range.span() {
            if self.limit.is_finite() {
                let (right, left) = (d.apply(self.limit), d.apply(-self.limit));
                if !(right <= span && -left <= span) {
                    return Err(Implausible::TooSteep);
                }
            }
        }
        Ok(d)
    }

    /// The deadzone the switching functions use at the next sample's step 1 input (the one of the last
    /// update).
    pub fn switching_deadzone(&self) -> Deadzone<F> {
        self.dz
    }

    /// Writes a_1..a_na (A = 1 + a_1 q⁻¹ + … + a_na q^−na) to `out`; returns na, or [`Error::Length`]
    /// when `out` is shorter.
    pub fn a(&self, out: &mut [F]) -> Result<usize, Error> {
        let src = self.rls.theta().iter().skip(4).take(self.na);
        copy_out(src, out, self.na)
    }

    /// Writes b_1..b_nb (b_1 = 1; B = b_1 q^−nk + … + b_nb q^−(nk+nb−1)) to `out`; returns nb, or
    /// [`Error::Length`] when `out` is shorter.
    pub fn b(&self, out: &mut [F]) -> Result<usize, Error> {
        let rest = self.rls.theta().iter().skip(4 + self.na).take(self.nb - 1);
        copy_out(core::iter::once(&F::ONE).chain(rest), out, self.nb)
    }

    /// (na, nb, nk).
    pub fn orders(&self) -> (usize, usize, usize) {
        (self.na, self.nb, self.nk)
    }

    /// Samples fed so far (saturating).
    pub fn samples(&self) -> usize {
        self.k
    }
}

/// Flops per sample of [`HammersteinRls::update`] after the delay lines are full: the RLS update for
/// n = 3 + na + nb parameters ([`rls::flops_per_update`]) plus 2 divisions for b̂_r, b̂_l, 2
/// multiplications h u(k−d), 2 + na sign changes and 2 per x̂ term (nb − 1 of them).
pub fn flops_per_sample(na: usize, nb: usize, rho_is_one: bool) -> usize {
    rls::flops_per_update(3 + na + nb, rho_is_one) + 4 + na + 2 * nb
}

/// As [`flops_per_sample`] with the UD form ([`rls::flops_per_update_ud`]) in a state of capacity
/// `capacity` (the `N` of [`HammersteinRls<F, N, D>`]; the same for ρ < 1 and ρ = 1).
pub fn flops_per_sample_ud(na: usize, nb: usize, capacity: usize) -> usize {
    rls::flops_per_update_ud(3 + na + nb, capacity) + 4 + na + 2 * nb
}

/// Deadzone from θ = [m_r, m_r b_r, m_l, m_l b_l, ...] as `sysid` computes it: a breakpoint whose
/// ratio is not finite keeps its `prev` value; breakpoints are clamped to ±`limit`.
fn deadzone_from_theta<F: Float>(theta: &[F], prev: Deadzone<F>, limit: F) -> Deadzone<F> {
    let ratio = |num: F, den: F, prev: F| {
        let r = num / den;
        if r.is_finite() {
            r.clamp_to(-limit, limit)
        } else {
            prev
        }
    };
    Deadzone {
        b_r: ratio(first(theta, 1), first(theta, 0), prev.b_r),
        b_l: ratio(first(theta, 3), first(theta, 2), prev.b_l),
        m_r: first(theta, 0),
        m_l: first(theta, 2),
    }
}

/// θ_i, 0 when out of range.
fn first<F: Float>(theta: &[F], i: usize) -> F {
    theta.get(i).copied().unwrap_or(F::ZERO)
}

/// Shifts a delay line by one sample: line[0] = v, line[i] = old line[i − 1].
fn push<F: Float>(line: &mut [F], v: F) {
    let mut carry = v;
    for slot in line.iter_mut() {
        core::mem::swap(slot, &mut carry);
    }
}

fn copy_out<'a, F: Float + 'a>(
    src: impl Iterator<Item = &'a F>,
    out: &mut [F],
    len: usize,
) -> Result<usize, Error> {
    let out = out.get_mut(..len).ok_or(Error::Length)?;
    for (o, v) in out.iter_mut().zip(src) {
        *o = *v;
    }
    Ok(len)
}

/// NaN: the only value not comparable with itself.
fn is_nan<F: Float>(v: F) -> bool {
    v.partial_cmp(&v).is_none()
}

#[cfg(test)]
#[allow(clippy::indexing_slicing, clippy::unwrap_used)]
mod tests {
    use super::*;

    // A noise-free paper-like plant: the true deadzone and ARX(2, 2, 1) with b1 = 1. Once the switching
    // functions agree with the true ones every new regression row is exact, so with forgetting (ρ = 0.98,
    // which forgets the rows built with the early, wrong switching) the recursion settles on the true
    // parameters.
    #[test]
    fn recovers_a_noise_free_hammerstein_plant() {
        let truth = Deadzone {
            b_l: -12.0,
            b_r: 9.0,
            m_l: 0.004,
            m_r: 0.003,
        };
        let (a1, a2, b2) = (-1.2, 0.35, 0.5);
        let n = 4000;
        let mut x = [0.0f64; 2];
        let mut y = [0.0f64; 3];
        let mut s = HammersteinSettings::paper();
        s.na = 2;
        s.nb = 2;
        s.forgetting = 0.98;
        let mut est = HammersteinRls::<f64, 8, 4>::new(s).unwrap();
        let mut seed = 12345u64;
        let mut u_prev = 0.0;
        for k in 0..n {
            // Pseudo-random levels in [−255, 255], each held 7 samples.
            if k % 7 == 0 {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                u_prev = ((seed >> 33) % 511) as f64 - 255.0;
            }
            let u = u_prev;
            // y(k) = −a1 y(k−1) − a2 y(k−2) + x(k−1) + b2 x(k−2).
            let yk = -a1 * y[0] - a2 * y[1] + x[0] + b2 * x[1];
            est.update(u, yk).unwrap();
            y = [yk, y[0], y[1]];
            x = [truth.apply(u), x[0]];
        }
        let d = est.deadzone();
        assert!((d.b_l - truth.b_l).abs() < 1e-3, "{d:?}");
        assert!((d.b_r - truth.b_r).abs() < 1e-3, "{d:?}");
        assert!((d.m_l / truth.m_l - 1.0).abs() < 1e-4, "{d:?}");
        assert!((d.m_r / truth.m_r - 1.0).abs() < 1e-4, "{d:?}");
        let mut a = [0.0; 2];
        let mut b = [0.0; 2];
        assert_eq!(est.a(&mut a).unwrap(), 2);
        assert_eq!(est.b(&mut b).unwrap(), 2);
        assert!(
            (a[0] - a1).abs() < 1e-6 && (a[1] - a2).abs() < 1e-6,
            "{a:?}"
        );
        assert_eq!(b[0], 1.0);
        assert!((b[1] - b2).abs() < 1e-5, "{b:?}");

        // A covariance restart (as after a change alarm) keeps θ̂ and sets P = p0 I exactly.
        let theta = *est.theta();
        assert!(
            (est.rls().p(0, 0) - s.p0).abs() > 1.0,
            "P has moved away from p0 I"
        );
        est.restart_covariance();
        assert_eq!(*est.theta(), theta);
        let n_par = 3 + s.na + s.nb;
        for i in 0..n_par {
            for j in 0..n_par {
                assert_eq!(est.rls().p(i, j), if i == j { s.p0 } else { 0.0 });
            }
        }
    }

    #[test]
    fn orders_beyond_the_capacity_and_bad_samples_are_errors() {
        let mut s = HammersteinSettings::<f64>::paper();
        s.na = 4; // n = 8 > 7
        assert_eq!(PaperHrls::new(s).unwrap_err(), Error::Capacity);
        let mut s = HammersteinSettings::<f64>::paper();
        s.nk = 4; // nk + nb − 1 = 4 > D = 3
        assert_eq!(PaperHrls::new(s).unwrap_err(), Error::Capacity);
        let mut s = HammersteinSettings::<f64>::paper();
        s.nb = 0;
        assert_eq!(PaperHrls::new(s).unwrap_err(), Error::Capacity);
        let mut s = HammersteinSettings::<f64>::paper();
        s.b_r0 = f64::NAN;
        assert_eq!(PaperHrls::new(s).unwrap_err(), Error::Setting);
        let mut est = PaperHrls::new(HammersteinSettings::<f64>::paper()).unwrap();
        assert_eq!(est.update(f64::NAN, 0.0).unwrap_err(), Error::NotFinite);
        assert_eq!(est.samples(), 0, "a refused sample is not counted");
        // k0 = 3: the first three samples only fill the delay lines.
        for _ in 0..3 {
            assert_eq!(est.update(1.0, 0.0).unwrap(), None);
        }
        assert!(est.update(1.0, 0.0).unwrap().is_some());
        let mut short = [0.0; 2];
        assert_eq!(est.a(&mut short).unwrap_err(), Error::Length);
    }

    // Largest negative, smallest positive, max |u|; a one-sided record gets an infinite breakpoint.
    #[test]
    fn record_start_follows_the_smallest_commands() {
        let s = HammersteinSettings::<f64>::paper().from_record(&[0.0, 30.0, -7.0, 12.0, -100.0]);
        assert_eq!((s.b_l0, s.b_r0, s.limit), (-7.0, 12.0, 100.0));
        let s = HammersteinSettings::<f32>::paper().from_record(&[0.0, 30.0, 12.0]);
        assert_eq!((s.b_l0, s.b_r0, s.limit), (f32::NEG_INFINITY, 12.0, 30.0));
    }

    // Paper orders, n = 7: RLS 3.5·49 + 8.5·7 + 2 = 233 (ρ < 1) or 3·49 + 8·7 + 1 = 204 (ρ = 1), plus
    // 2 ratios, 2 products h·u, 2 + 3 sign changes, no x̂ term: 9.
    #[test]
    fn flops_per_sample_for_the_paper_orders() {
        assert_eq!(flops_per_sample(3, 1, false), 242);
        assert_eq!(flops_per_sample(3, 1, true), 213);
        // UD: 4·49 + 12·7 + 2 = 282 in `PaperHrls` (N = 7), 3·49 + 13·7 + 2 = 240 in the C interface's
        // N = 19 (the partial gains kept), plus the same 9.
        assert_eq!(flops_per_sample_ud(3, 1, 7), 291);
        assert_eq!(flops_per_sample_ud(3, 1, 19), 249);
    }

    #[test]
    fn delay_line_shifts_by_one_sample() {
        let mut line = [1.0, 2.0, 3.0];
        push(&mut line, 0.0);
        assert_eq!(line, [0.0, 1.0, 2.0]);
        let mut empty: [f64; 0] = [];
        push(&mut empty, 1.0);
    }
}
