//! Static nonlinearities x = f(u) as blocks of the estimation: everything that depends on the kind of
//! nonlinearity lives here, so that the estimators (LS, RLS, IV, OE in `estimate.rs`, `oe.rs`) and the
//! regression (`regression.rs`) never mention a deadzone.
//!
//! A kind ([`NonlinearityKind`], chosen per input: `--nonlinearity deadzone` or
//! `--nonlinearity u1=deadzone,u2=linear`) gives its [`Block`]:
//! - its **physical parameters** (names, vector <-> [`StaticNonlinearity`]) — what output error moves and
//!   what is reported;
//! - its **key terms** (docs/paper.md, eq. 8): when f is linear in its parameters after the key-term
//!   normalisation b1 = 1, the regressor entries that replace b1 x(k−nk), their names, the update of the
//!   current f from their estimate, and the map to the physical parameters with standard deviations
//!   (delta method);
//! - its **derivative** ∂x/∂p for the output-error sensitivities;
//! - its **start** from the data (which parameters the data determine; the paper's method fails on a
//!   one-sided input, so a deadzone drops the unexcited branch) and its **warnings** against the data.
//!
//! A linear input has no parameter of its own: its B polynomial starts at b1 on x = u.

use nalgebra::DMatrix;

use crate::warnings::{Branch, Warning};
use sysid_core::param::deadzone_from_theta;
use sysid_core::{Deadzone, ParamName, StaticNonlinearity, SysidError};

/// The kind of static nonlinearity of one input (the `--nonlinearity` values).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
pub enum NonlinearityKind {
    /// x = u (an ARX input).
    Linear,
    /// The asymmetric valve deadzone of paper eq. (1): b_l, b_r, m_l, m_r.
    Deadzone,
}

impl std::fmt::Display for NonlinearityKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            NonlinearityKind::Linear => "linear",
            NonlinearityKind::Deadzone => "deadzone",
        })
    }
}

impl std::str::FromStr for NonlinearityKind {
    type Err = String;
    fn from_str(t: &str) -> Result<Self, String> {
        match t.trim() {
            "linear" => Ok(NonlinearityKind::Linear),
            "deadzone" => Ok(NonlinearityKind::Deadzone),
            other => Err(format!(
                "'{other}' is not a static nonlinearity; expected linear or deadzone"
            )),
        }
    }
}

impl NonlinearityKind {
    /// The block that estimates this kind.
    pub fn block(&self) -> &'static dyn Block {
        match self {
            NonlinearityKind::Linear => &LinearBlock,
            NonlinearityKind::Deadzone => &DeadzoneBlock,
        }
    }

    /// The kind of a fitted nonlinearity.
    pub fn of(f: &StaticNonlinearity) -> Self {
        match f {
            StaticNonlinearity::Linear => NonlinearityKind::Linear,
            StaticNonlinearity::Deadzone(_) => NonlinearityKind::Deadzone,
        }
    }
}

/// What the data determine of one block before estimation (made by [`Block::start`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BlockStart {
    /// The nonlinearity the key-term iteration and RLS start from; its entries that are not free are
    /// the values they are fixed at.
    pub initial: StaticNonlinearity,
    /// Which key terms are estimated.
    pub free_key: Vec<bool>,
    /// Which physical parameters are estimated.
    pub free_physical: Vec<bool>,
    /// Bound on the magnitude of a breakpoint estimate during the iterations (max |u|).
    pub limit: f64,
    /// Remarks for the report (a dropped branch...).
    pub notes: Vec<String>,
}

impl BlockStart {
    /// `f` with its fixed parameters set to their fixed values.
    pub fn impose(&self, block: &dyn Block, f: &StaticNonlinearity) -> StaticNonlinearity {
        if self.free_physical.iter().all(|v| *v) {
            return *f;
        }
        let mut v = block.physical(f);
        let fixed = block.physical(&self.initial);
        for ((v, fixed), free) in v.iter_mut().zip(fixed).zip(&self.free_physical) {
            if !free {
                *v = fixed;
            }
        }
        block.of_physical(&v)
    }
}

/// The estimation side of a static nonlinearity (module docs). Slices of parameters are the block's
/// own entries, in the order of [`Block::physical_names`] or [`Block::key_names`].
pub trait Block: Sync {
    /// Names of the physical parameters (empty for a linear input).
    fn physical_names(&self) -> &'static [ParamName];
    /// Names of the key terms (empty: no key term, the input's B starts at b1).
    fn key_names(&self) -> &'static [ParamName];
    /// The physical parameters of `f` (of this kind).
    fn physical(&self, f: &StaticNonlinearity) -> Vec<f64>;
    /// The nonlinearity with physical parameters `v` (no validation: an iterate may be non-finite).
    fn of_physical(&self, v: &[f64]) -> StaticNonlinearity;
    /// The key terms of `f`, the values the regression estimates.
    fn key_terms(&self, f: &StaticNonlinearity) -> Vec<f64>;
    /// Fills `out` (one entry per key term) with the regressors at the command u, the switching of the
    /// current estimate `f`.
    fn fill_key_terms(&self, f: &StaticNonlinearity, u: f64, out: &mut [f64]);
    /// The nonlinearity from estimated key terms `key`; a parameter they do not determine keeps its
    /// value in `prev`; breakpoints are clamped to ±`limit`.
    fn of_key_terms(
        &self,
        key: &[f64],
        prev: &StaticNonlinearity,
        limit: f64,
    ) -> StaticNonlinearity;
    /// The physical parameters from the key terms at `theta[at..]` with their standard deviations from
    /// Cov(θ̂) (delta method); a value the key terms do not determine is NaN.
    fn physical_with_std(
        &self,
        theta: &[f64],
        cov: Option<&DMatrix<f64>>,
        at: usize,
    ) -> Vec<(f64, Option<f64>)>;
    /// ∂x/∂p for physical parameter `which` at the command u (a one-sided derivative at a kink).
    fn derivative(&self, f: &StaticNonlinearity, which: usize, u: f64) -> f64;
    /// True when the key-term estimate `f` cannot switch any regressor on (every slope zero: the
    /// recursion's first samples); RLS then keeps the start.
    fn is_degenerate(&self, f: &StaticNonlinearity) -> bool;
    /// What the input `u` (every record's samples) determines; `offset`: the model estimates c;
    /// `allow_one_sided`: drop what the data cannot determine instead of refusing them (`name` names the
    /// data in the error).
    fn start(
        &self,
        u: &[f64],
        offset: bool,
        allow_one_sided: bool,
        name: &str,
    ) -> Result<BlockStart, SysidError>;
    /// The linear map x = b1 u written in this kind (the linear ARX start of the safeguards), with the
    /// standard deviation of each physical parameter given that of b1.
    fn linear_equivalent(
        &self,
        b1: f64,
        b1_std: Option<f64>,
    ) -> (StaticNonlinearity, Vec<Option<f64>>);
    /// Checks the estimate `f` against its input `u`; `std[i]` is the standard deviation of physical
    /// parameter i. Returns the warnings and the parameters whose standard deviation is not meaningful.
    fn warnings(
        &self,
        f: &StaticNonlinearity,
        u: &[f64],
        start: &BlockStart,
        std: &[Option<f64>],
    ) -> (Vec<Warning>, Vec<ParamName>);
}

/// x = u.
pub struct LinearBlock;

impl Block for LinearBlock {
    fn physical_names(&self) -> &'static [ParamName] {
        &[]
    }
    fn key_names(&self) -> &'static [ParamName] {
        &[]
    }
    fn physical(&self, _: &StaticNonlinearity) -> Vec<f64> {
        Vec::new()
    }
    fn of_physical(&self, _: &[f64]) -> StaticNonlinearity {
        StaticNonlinearity::Linear
    }
    fn key_terms(&self, _: &StaticNonlinearity) -> Vec<f64> {
        Vec::new()
    }
    fn fill_key_terms(&self, _: &StaticNonlinearity, _: f64, _: &mut [f64]) {}
    fn of_key_terms(&self, _: &[f64], _: &StaticNonlinearity, _: f64) -> StaticNonlinearity {
        StaticNonlinearity::Linear
    }
    fn physical_with_std(
        &self,
        _: &[f64],
        _: Option<&DMatrix<f64>>,
        _: usize,
    ) -> Vec<(f64, Option<f64>)> {
        Vec::new()
    }
    fn derivative(&self, _: &StaticNonlinearity, _: usize, _: f64) -> f64 {
        0.0
    }
    fn is_degenerate(&self, _: &StaticNonlinearity) -> bool {
        false
    }
    fn start(&self, _: &[f64], _: bool, _: bool, _: &str) -> Result<BlockStart, SysidError> {
        Ok(BlockStart {
            initial: StaticNonlinearity::Linear,
            free_key: Vec::new(),
            free_physical: Vec::new(),
            limit: f64::INFINITY,
            notes: Vec::new(),
        })
    }
    fn linear_equivalent(&self, _: f64, _: Option<f64>) -> (StaticNonlinearity, Vec<Option<f64>>) {
        (StaticNonlinearity::Linear, Vec::new())
    }
    fn warnings(
        &self,
        _: &StaticNonlinearity,
        _: &[f64],
        _: &BlockStart,
        _: &[Option<f64>],
    ) -> (Vec<Warning>, Vec<ParamName>) {
        (Vec::new(), Vec::new())
    }
}

/// The asymmetric deadzone (paper eq. 1). Physical [b_l, b_r, m_l, m_r]; key terms
/// [m_r, m_r b_r, m_l, m_l b_l] with regressors [h_r u, −h_r, h_l u, −h_l] at u(k − nk)
/// (h_r = [u ≥ b_r], h_l = [u ≤ b_l], paper eqs. 2–3).
pub struct DeadzoneBlock;

/// The deadzone of `f` (zero for another kind, which a deadzone block is never given).
fn dz(f: &StaticNonlinearity) -> Deadzone {
    f.deadzone().copied().unwrap_or(ZERO)
}

const ZERO: Deadzone = Deadzone {
    b_l: 0.0,
    b_r: 0.0,
    m_l: 0.0,
    m_r: 0.0,
};

/// The ratio b = θ_j / θ_i (a breakpoint from its key-term product and slope) and its standard deviation
/// by the delta method (gradient (−θ_j/θ_i², 1/θ_i)) from Cov(θ̂); NaN and `None` when θ_i = 0.
pub(crate) fn ratio_with_std(
    theta: &[f64],
    cov: Option<&DMatrix<f64>>,
    i: usize,
    j: usize,
) -> (f64, Option<f64>) {
    let (ti, tj) = (theta[i], theta[j]);
    let value = if ti != 0.0 { tj / ti } else { f64::NAN };
    let std = cov.and_then(|c| {
        if ti == 0.0 {
            return None;
        }
        let (gi, gj) = (-tj / (ti * ti), 1.0 / ti);
        let v = gi * gi * c[(i, i)] + 2.0 * gi * gj * c[(i, j)] + gj * gj * c[(j, j)];
        (v.is_finite() && v >= 0.0).then(|| v.sqrt())
    });
    (value, std)
}

/// The standard deviation of entry i from Cov(θ̂), when meaningful.
pub(crate) fn sd(cov: Option<&DMatrix<f64>>, i: usize) -> Option<f64> {
    cov.map(|c| c[(i, i)])
        .filter(|v| v.is_finite() && *v >= 0.0)
        .map(f64::sqrt)
}

impl Block for DeadzoneBlock {
    fn physical_names(&self) -> &'static [ParamName] {
        &[ParamName::BL, ParamName::BR, ParamName::ML, ParamName::MR]
    }
    fn key_names(&self) -> &'static [ParamName] {
        &[
            ParamName::MR,
            ParamName::MrBr,
            ParamName::ML,
            ParamName::MlBl,
        ]
    }
    fn physical(&self, f: &StaticNonlinearity) -> Vec<f64> {
        let d = dz(f);
        vec![d.b_l, d.b_r, d.m_l, d.m_r]
    }
    fn of_physical(&self, v: &[f64]) -> StaticNonlinearity {
        StaticNonlinearity::Deadzone(Deadzone {
            b_l: v[0],
            b_r: v[1],
            m_l: v[2],
            m_r: v[3],
        })
    }
    fn key_terms(&self, f: &StaticNonlinearity) -> Vec<f64> {
        let d = dz(f);
        vec![d.m_r, d.m_r * d.b_r, d.m_l, d.m_l * d.b_l]
    }
    fn fill_key_terms(&self, f: &StaticNonlinearity, u: f64, out: &mut [f64]) {
        let d = dz(f);
        let (hr, hl) = (d.h_r(u), d.h_l(u));
        out[0] = hr * u;
        out[1] = -hr;
        out[2] = hl * u;
        out[3] = -hl;
    }
    fn of_key_terms(
        &self,
        key: &[f64],
        prev: &StaticNonlinearity,
        limit: f64,
    ) -> StaticNonlinearity {
        StaticNonlinearity::Deadzone(deadzone_from_theta(key, dz(prev), limit))
    }
    fn physical_with_std(
        &self,
        theta: &[f64],
        cov: Option<&DMatrix<f64>>,
        at: usize,
    ) -> Vec<(f64, Option<f64>)> {
        vec![
            ratio_with_std(theta, cov, at + 2, at + 3),
            ratio_with_std(theta, cov, at, at + 1),
            (theta[at + 2], sd(cov, at + 2)),
            (theta[at], sd(cov, at)),
        ]
    }
    fn derivative(&self, f: &StaticNonlinearity, which: usize, u: f64) -> f64 {
        let d = dz(f);
        let hr = d.h_r(u);
        let hl = if hr > 0.0 { 0.0 } else { d.h_l(u) };
        match which {
            0 => -d.m_l * hl,
            1 => -d.m_r * hr,
            2 => hl * (u - d.b_l),
            _ => hr * (u - d.b_r),
        }
    }
    fn is_degenerate(&self, f: &StaticNonlinearity) -> bool {
        let d = dz(f);
        d.m_r == 0.0 && d.m_l == 0.0
    }
    fn start(
        &self,
        u: &[f64],
        offset: bool,
        allow_one_sided: bool,
        name: &str,
    ) -> Result<BlockStart, SysidError> {
        let b = Branches::of(u, offset, allow_one_sided, name)?;
        Ok(BlockStart {
            initial: StaticNonlinearity::Deadzone(b.initial_deadzone()),
            free_key: vec![
                b.right,
                b.right && !b.b_r_fixed,
                b.left,
                b.left && !b.b_l_fixed,
            ],
            free_physical: vec![
                b.left && !b.b_l_fixed,
                b.right && !b.b_r_fixed,
                b.left,
                b.right,
            ],
            limit: b.limit,
            notes: b.notes(),
        })
    }
    fn linear_equivalent(
        &self,
        b1: f64,
        b1_std: Option<f64>,
    ) -> (StaticNonlinearity, Vec<Option<f64>>) {
        let d = Deadzone {
            b_l: 0.0,
            b_r: 0.0,
            m_l: b1,
            m_r: b1,
        };
        (
            StaticNonlinearity::Deadzone(d),
            vec![None, None, b1_std, b1_std],
        )
    }
    fn warnings(
        &self,
        f: &StaticNonlinearity,
        u: &[f64],
        start: &BlockStart,
        std: &[Option<f64>],
    ) -> (Vec<Warning>, Vec<ParamName>) {
        let (left, right) = (start.free_physical[2], start.free_physical[3]);
        deadzone_warnings(&dz(f), u, (left, right), (std[0], std[1]))
    }
}

/// Which parts of the deadzone a record can determine: the left branch (u <= b_l) is only seen when the
/// input goes below zero, the right branch (u >= b_r) only when it goes above.
///
/// Real records are often one-sided (a pump voltage, a heater voltage never goes negative). Then the
/// unexcited branch is dropped: its slope is fixed at 0 and its breakpoint at 0, so that the fitted
/// model maps every u on that side to x = 0. When, in addition, every sample lies on the remaining
/// branch and the model has an offset c, the breakpoint of that branch and c are the same regressor
/// (−m_r b_r is a constant), so the breakpoint is fixed at 0 and c absorbs it.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Branches {
    left: bool,
    right: bool,
    b_l_fixed: bool,
    b_r_fixed: bool,
    max_neg: f64,
    min_pos: f64,
    limit: f64,
}

impl Branches {
    /// Looks at the input `u`. With `allow_one_sided == false` a one-sided input is refused (as the
    /// paper's method would fail on it); otherwise the unexcited branch is dropped.
    fn of(u: &[f64], offset: bool, allow_one_sided: bool, name: &str) -> Result<Self, SysidError> {
        let (mut min_pos, mut max_pos, mut max_neg, mut min_neg) = (
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
        );
        let mut zero = false;
        for &v in u {
            if v > 0.0 {
                min_pos = min_pos.min(v);
                max_pos = max_pos.max(v);
            } else if v < 0.0 {
                max_neg = max_neg.max(v);
                min_neg = min_neg.min(v);
            } else {
                zero = true;
            }
        }
        let right = min_pos.is_finite();
        let left = max_neg.is_finite();
        if !(allow_one_sided || left && right) {
            return Err(SysidError::Data(format!(
                "{name}: the input is never {}: a Hammerstein deadzone needs commands on both sides of zero \
                 (not persistently exciting); use --model arx or richer data",
                if right { "negative" } else { "positive" }
            )));
        }
        if !left && !right {
            return Err(SysidError::Data(format!(
                "{name}: the input is zero throughout: a Hammerstein model cannot be estimated (not persistently exciting)",
            )));
        }
        let limit = max_pos.max(-min_neg).max(0.0);
        // Two-sided input without a zero command and with an offset: with the breakpoints at the smallest
        // commands h_r + h_l = 1 on every sample, which is the offset's column. Start instead with the
        // breakpoints at the 10 % quantiles of |u| on each side, so that some samples lie in the deadzone.
        let (mut start_neg, mut start_pos) = (max_neg, min_pos);
        if offset && left && right && !zero {
            let quantile = |mut v: Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v[(v.len() - 1) / 10]
            };
            start_pos = quantile(u.iter().copied().filter(|&v| v > 0.0).collect());
            start_neg = -quantile(u.iter().filter(|&&v| v < 0.0).map(|v| -v).collect());
        }
        Ok(Branches {
            left,
            right,
            b_l_fixed: left && !right && !zero && offset,
            b_r_fixed: right && !left && !zero && offset,
            max_neg: if left { start_neg } else { 0.0 },
            min_pos: if right { start_pos } else { 0.0 },
            limit,
        })
    }

    /// The deadzone the key-term iteration starts from: breakpoints at the smallest commands on each
    /// side (every nonzero command switches its branch on), unit slopes; a dropped branch has slope 0 and
    /// breakpoint 0, a fixed breakpoint is 0.
    fn initial_deadzone(&self) -> Deadzone {
        Deadzone {
            b_l: if self.left && !self.b_l_fixed {
                self.max_neg
            } else {
                0.0
            },
            b_r: if self.right && !self.b_r_fixed {
                self.min_pos
            } else {
                0.0
            },
            m_l: if self.left { 1.0 } else { 0.0 },
            m_r: if self.right { 1.0 } else { 0.0 },
        }
    }

    /// The remarks for the report, one per fixed part (empty when nothing is fixed).
    fn notes(&self) -> Vec<String> {
        let mut parts = Vec::new();
        if !self.left {
            parts.push("the input is never negative: the left deadzone branch is not excited and was dropped (m_l = 0, b_l = 0 fixed)".to_string());
        }
        if !self.right {
            parts.push("the input is never positive: the right deadzone branch is not excited and was dropped (m_r = 0, b_r = 0 fixed)".to_string());
        }
        if self.b_r_fixed {
            parts.push("every input sample is on the right branch, so b_r cannot be separated from the offset c: b_r = 0 fixed (c absorbs -m_r b_r)".to_string());
        }
        if self.b_l_fixed {
            parts.push("every input sample is on the left branch, so b_l cannot be separated from the offset c: b_l = 0 fixed (c absorbs -m_l b_l)".to_string());
        }
        parts
    }
}

/// Checks a deadzone estimate against the input it was estimated from: a physical shape, breakpoints
/// bracketed by the data and not on an input level (nor within their standard deviation `std_l`,
/// `std_r` of one), at least two distinct levels on each estimated branch. `left`/`right`: whether that
/// branch was estimated (not dropped for a one-sided input). Returns the warnings and the names of the
/// breakpoints whose standard deviation is not meaningful.
pub fn deadzone_warnings(
    d: &Deadzone,
    u: &[f64],
    (left, right): (bool, bool),
    (std_l, std_r): (Option<f64>, Option<f64>),
) -> (Vec<Warning>, Vec<ParamName>) {
    let mut w = Vec::new();
    let mut no_std = Vec::new();
    let mut levels: Vec<f64> = u.to_vec();
    levels.sort_by(f64::total_cmp);
    levels.dedup();
    let (u_min, u_max) = match (levels.first(), levels.last()) {
        (Some(a), Some(b)) => (*a, *b),
        _ => return (w, no_std),
    };
    if left && right && d.b_l > d.b_r {
        w.push(Warning::NonPhysicalDeadzone {
            why: format!("b_l = {} > b_r = {}", d.b_l, d.b_r),
        });
    }
    if left && right && d.m_l * d.m_r < 0.0 {
        w.push(Warning::NonPhysicalDeadzone {
            why: format!(
                "the slopes have opposite signs (m_l = {}, m_r = {})",
                d.m_l, d.m_r
            ),
        });
    }
    let checks = [
        (left, ParamName::BL, d.b_l, std_l, Branch::Left),
        (right, ParamName::BR, d.b_r, std_r, Branch::Right),
    ];
    for (estimated, name, b, std, branch) in checks {
        if !estimated {
            continue;
        }
        let on = |l: f64| 1e-9 * l.abs().max(1.0);
        let reach = |l: f64| on(l).max(std.unwrap_or(0.0));
        if let Some(level) = levels.iter().find(|l| (b - **l).abs() <= reach(**l)) {
            w.push(Warning::BreakpointOnInputLevel {
                name,
                value: b,
                level: *level,
                // On the level itself the deviation says nothing; near it, the withheld value is named.
                std: std.filter(|_| (b - *level).abs() > on(*level)),
            });
            no_std.push(name);
        } else if b <= u_min || b >= u_max {
            w.push(Warning::BreakpointNotBracketed {
                name,
                value: b,
                u_min,
                u_max,
            });
            no_std.push(name);
        }
        let beyond = levels
            .iter()
            .filter(|l| match branch {
                Branch::Left => **l < b,
                Branch::Right => **l > b,
            })
            .count();
        if beyond < 2 {
            w.push(Warning::FewInputLevels {
                branch,
                levels: beyond,
            });
        }
    }
    (w, no_std)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start(u: &[f64], offset: bool) -> Branches {
        Branches::of(u, offset, true, "t").unwrap()
    }

    // u in {1, 2, 3}: no negative command, so m_l and m_l b_l (key terms 2, 3) are not estimated.
    #[test]
    fn a_positive_input_drops_the_left_branch() {
        let b = start(&[1.0, 2.0, 3.0], false);
        assert!(!b.left && b.right && !b.b_r_fixed);
        let s = DeadzoneBlock
            .start(&[1.0, 2.0, 3.0], false, true, "t")
            .unwrap();
        assert_eq!(s.free_key, [true, true, false, false]);
        assert_eq!(s.free_physical, [false, true, false, true]);
    }

    // Every u > 0 with an offset: the column −h_r is the constant −1, the offset column's negative.
    #[test]
    fn with_an_offset_a_breakpoint_below_all_samples_is_fixed() {
        assert!(start(&[1.0, 2.0, 3.0], true).b_r_fixed);
        assert!(
            !start(&[0.0, 2.0, 3.0], true).b_r_fixed,
            "a zero command leaves h_r non-constant"
        );
    }

    #[test]
    fn one_sided_input_is_refused_unless_allowed() {
        let e = Branches::of(&[-1.0, -2.0], false, false, "t").unwrap_err();
        assert!(e.to_string().contains("never positive"), "{e}");
    }

    // A dropped branch: impose sets its slope and breakpoint to the fixed 0 whatever the estimate says.
    #[test]
    fn imposing_a_dropped_branch_zeroes_it() {
        let s = DeadzoneBlock
            .start(&[1.0, 2.0, 3.0], false, true, "t")
            .unwrap();
        let f = DeadzoneBlock.of_physical(&[-3.0, 1.5, 0.7, 2.0]);
        assert_eq!(
            DeadzoneBlock.physical(&s.impose(&DeadzoneBlock, &f)),
            [0.0, 1.5, 0.0, 2.0]
        );
    }

    struct D {
        u: Vec<f64>,
    }
    impl D {
        fn u(&self) -> &[f64] {
            &self.u
        }
    }
    fn data(u: Vec<f64>) -> D {
        D { u }
    }

    // A staircase of levels −60, −56, −48, −33, 20, 40, 60: a deadzone with b_l = −48 (on a level, two
    // levels below it) and b_r = 25 (between levels) warns about b_l only; b_r keeps its standard
    // deviation.
    #[test]
    fn a_breakpoint_on_an_input_level_is_flagged() {
        let d = data(vec![-60.0, -56.0, -48.0, -33.0, 20.0, 40.0, 60.0, -56.0]);
        let dz = Deadzone {
            b_l: -48.0,
            b_r: 25.0,
            m_l: 0.005,
            m_r: 0.005,
        };
        let (w, no_std) = deadzone_warnings(&dz, d.u(), (true, true), (None, None));
        assert_eq!(no_std, vec![ParamName::BL]);
        assert!(matches!(
            w[..],
            [Warning::BreakpointOnInputLevel { level, .. }] if level == -48.0
        ));
        assert!(w[0].to_string().contains("lies on the input level -48"));
        // A breakpoint 4e-5 from the level, with a standard deviation of 0.5: the kink is within one
        // standard deviation, so the same warning; 0.4 away with σ 0.1 is not.
        let near = Deadzone {
            b_l: -47.99996,
            ..dz
        };
        let (w, _) = deadzone_warnings(&near, d.u(), (true, true), (Some(0.5), Some(0.1)));
        assert!(
            matches!(w[..], [Warning::BreakpointOnInputLevel { .. }]),
            "{w:?}"
        );
        // The words say how far it is and which deviation was withheld, never "lies on" (issue 27
        // item 5): 4e-5 from -48, deviation 0.5.
        let text = w[0].to_string();
        assert!(
            text.contains(
                "is 4.0e-5 from the input level -48, less than its standard deviation 0.500"
            ),
            "{text}"
        );
        assert!(!text.contains("lies on"), "{text}");
        let far = Deadzone { b_l: -47.78, ..dz };
        let (w, _) = deadzone_warnings(&far, d.u(), (true, true), (Some(0.3), Some(0.1)));
        let text = w[0].to_string();
        assert!(
            text.contains("b_l = -47.780000 is 0.220 from the input level -48, less than its standard deviation 0.300"),
            "{text}"
        );
        let apart = Deadzone { b_l: -47.6, ..dz };
        let (w, no_std) = deadzone_warnings(&apart, d.u(), (true, true), (Some(0.1), Some(0.1)));
        assert!(w.is_empty() && no_std.is_empty(), "{w:?}");
    }

    // b_r above every command: not bracketed; the right branch has no level beyond it.
    #[test]
    fn a_breakpoint_outside_the_input_range_is_not_bracketed() {
        let d = data(vec![-30.0, -20.0, -10.0, 5.0, 10.0]);
        let dz = Deadzone {
            b_l: -15.0,
            b_r: 12.0,
            m_l: 1.0,
            m_r: 1.0,
        };
        let (w, no_std) = deadzone_warnings(&dz, d.u(), (true, true), (None, None));
        assert_eq!(no_std, vec![ParamName::BR]);
        assert!(w.contains(&Warning::BreakpointNotBracketed {
            name: ParamName::BR,
            value: 12.0,
            u_min: -30.0,
            u_max: 10.0
        }));
        assert!(w.contains(&Warning::FewInputLevels {
            branch: Branch::Right,
            levels: 0
        }));
        // Left: levels below −15 are −30 and −20: two, enough.
        assert!(!w.contains(&Warning::FewInputLevels {
            branch: Branch::Left,
            levels: 2
        }));
    }

    // b_l > b_r and slopes of opposite sign are not a valve deadzone.
    #[test]
    fn crossed_breakpoints_and_opposite_slopes_are_not_physical() {
        let d = data(vec![-30.0, -20.0, -10.0, 10.0, 20.0, 30.0]);
        let dz = Deadzone {
            b_l: 5.0,
            b_r: -5.0,
            m_l: -1.0,
            m_r: 1.0,
        };
        let (w, _) = deadzone_warnings(&dz, d.u(), (true, true), (None, None));
        let n = w
            .iter()
            .filter(|w| matches!(w, Warning::NonPhysicalDeadzone { .. }))
            .count();
        assert_eq!(n, 2, "{w:?}");
    }

    // A dropped branch is not checked.
    #[test]
    fn dropped_branches_are_not_checked() {
        let d = data(vec![1.0, 2.0, 3.0, 4.0]);
        let dz = Deadzone {
            b_l: 0.0,
            b_r: 1.5,
            m_l: 0.0,
            m_r: 1.0,
        };
        let (w, _) = deadzone_warnings(&dz, d.u(), (false, true), (None, None));
        assert!(w.is_empty(), "{w:?}");
    }
}
