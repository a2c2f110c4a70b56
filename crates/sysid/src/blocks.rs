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
use sysid_core::nonlinearity::{MAX_BREAKPOINTS, MAX_DEGREE};
use sysid_core::param::deadzone_from_theta;
use sysid_core::{
    Deadzone, DeadzoneSaturation, ParamName, PiecewiseLinear, Polynomial, Saturation, Setting,
    StaticNonlinearity, SysidError,
};

/// The kind of static nonlinearity of one input (the `--nonlinearity` values).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NonlinearityKind {
    /// x = u (an ARX input).
    Linear,
    /// The asymmetric valve deadzone of paper eq. (1): b_l, b_r, m_l, m_r.
    Deadzone,
    /// Asymmetric saturation x = m clamp(u, s_l, s_r).
    Saturation,
    /// A deadzone whose branches saturate: b_l, b_r, s_l, s_r, m_l, m_r.
    DeadzoneSaturation,
    /// A continuous piecewise-linear map through the origin with K breakpoints (`--breakpoints K`).
    PiecewiseLinear {
        /// K: number of breakpoints, 1..=[`MAX_BREAKPOINTS`].
        breakpoints: usize,
    },
    /// A polynomial through the origin of degree D (`--degree D`).
    Polynomial {
        /// D: degree, 1..=[`MAX_DEGREE`].
        degree: usize,
    },
}

/// K of `piecewise-linear` when `--breakpoints` is not given.
pub const DEFAULT_BREAKPOINTS: usize = 2;
/// K = 0 stands for `--breakpoints auto`: [`crate::identify`] tries K = 1..=[`MAX_AUTO_BREAKPOINTS`]
/// and keeps the smallest AIC on the estimation data.
pub const AUTO_BREAKPOINTS: usize = 0;
/// The largest K `--breakpoints auto` tries.
pub const MAX_AUTO_BREAKPOINTS: usize = 4;
/// D of `polynomial` when `--degree` is not given.
pub const DEFAULT_DEGREE: usize = 3;

impl std::fmt::Display for NonlinearityKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            NonlinearityKind::Linear => "linear",
            NonlinearityKind::Deadzone => "deadzone",
            NonlinearityKind::Saturation => "saturation",
            NonlinearityKind::DeadzoneSaturation => "deadzone-saturation",
            NonlinearityKind::PiecewiseLinear { .. } => "piecewise-linear",
            NonlinearityKind::Polynomial { .. } => "polynomial",
        })
    }
}

impl std::str::FromStr for NonlinearityKind {
    type Err = String;
    /// The kind's word; `piecewise-linear` has [`DEFAULT_BREAKPOINTS`] and `polynomial`
    /// [`DEFAULT_DEGREE`] until [`NonlinearityKind::with_breakpoints`] / `with_degree` say otherwise.
    fn from_str(t: &str) -> Result<Self, String> {
        match t.trim() {
            "linear" => Ok(NonlinearityKind::Linear),
            "deadzone" => Ok(NonlinearityKind::Deadzone),
            "saturation" => Ok(NonlinearityKind::Saturation),
            "deadzone-saturation" => Ok(NonlinearityKind::DeadzoneSaturation),
            "piecewise-linear" => Ok(NonlinearityKind::PiecewiseLinear {
                breakpoints: DEFAULT_BREAKPOINTS,
            }),
            "polynomial" => Ok(NonlinearityKind::Polynomial {
                degree: DEFAULT_DEGREE,
            }),
            other => Err(format!(
                "'{other}' is not a static nonlinearity; expected linear, deadzone, saturation, \
                 deadzone-saturation, piecewise-linear or polynomial"
            )),
        }
    }
}

impl NonlinearityKind {
    /// The block that estimates this kind.
    pub fn block(&self) -> &'static dyn Block {
        match *self {
            NonlinearityKind::Linear => &LinearBlock,
            NonlinearityKind::Deadzone => &DeadzoneBlock,
            NonlinearityKind::Saturation => &SaturationBlock,
            NonlinearityKind::DeadzoneSaturation => &DeadzoneSaturationBlock,
            NonlinearityKind::PiecewiseLinear { breakpoints } => {
                &PIECEWISE[breakpoints.min(MAX_BREAKPOINTS)]
            }
            NonlinearityKind::Polynomial { degree } => &POLYNOMIAL[degree.min(MAX_DEGREE)],
        }
    }

    /// The kind of a fitted nonlinearity.
    pub fn of(f: &StaticNonlinearity) -> Self {
        match f {
            StaticNonlinearity::Linear => NonlinearityKind::Linear,
            StaticNonlinearity::Deadzone(_) => NonlinearityKind::Deadzone,
            StaticNonlinearity::Saturation(_) => NonlinearityKind::Saturation,
            StaticNonlinearity::DeadzoneSaturation(_) => NonlinearityKind::DeadzoneSaturation,
            StaticNonlinearity::PiecewiseLinear(p) => NonlinearityKind::PiecewiseLinear {
                breakpoints: p.breakpoints().len(),
            },
            StaticNonlinearity::Polynomial(p) => NonlinearityKind::Polynomial {
                degree: p.coefficients().len(),
            },
        }
    }

    /// The same kind with K breakpoints if it is piecewise-linear.
    pub fn with_breakpoints(self, k: usize) -> Self {
        match self {
            NonlinearityKind::PiecewiseLinear { .. } => {
                NonlinearityKind::PiecewiseLinear { breakpoints: k }
            }
            other => other,
        }
    }

    /// The same kind with degree D if it is a polynomial.
    pub fn with_degree(self, d: usize) -> Self {
        match self {
            NonlinearityKind::Polynomial { .. } => NonlinearityKind::Polynomial { degree: d },
            other => other,
        }
    }

    /// Fails when K or D is out of range (naming `--breakpoints` / `--degree`).
    pub fn check(&self) -> Result<(), SysidError> {
        match *self {
            NonlinearityKind::PiecewiseLinear { breakpoints: k }
                if k != AUTO_BREAKPOINTS && !(1..=MAX_BREAKPOINTS).contains(&k) =>
            {
                Err(SysidError::setting(
                    Setting::Other("--breakpoints"),
                    k,
                    &format!("a number of breakpoints from 1 to {MAX_BREAKPOINTS}, or auto"),
                ))
            }
            NonlinearityKind::Polynomial { degree: d } if !(1..=MAX_DEGREE).contains(&d) => {
                Err(SysidError::setting(
                    Setting::Other("--degree"),
                    d,
                    &format!("a degree from 1 to {MAX_DEGREE}"),
                ))
            }
            _ => Ok(()),
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
    /// True when the data determine every physical parameter ([`BlockStart::impose`] changes nothing).
    pub fn all_free(&self) -> bool {
        self.free_physical.iter().all(|v| *v)
    }

    /// `f` with its fixed parameters set to their fixed values.
    pub fn impose(&self, block: &dyn Block, f: &StaticNonlinearity) -> StaticNonlinearity {
        if self.all_free() {
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
    /// The key-term columns of the rows at the commands `u` (one row per command), the values of
    /// [`Block::fill_key_terms`]: key term t of row q goes to `out[t · stride + q]`. Returns true when
    /// every value written equals, to the bit, what `out` held there. (One call per record instead of
    /// one per row: inside, [`Block::fill_key_terms`] is the kind's own, inlined.)
    fn fill_key_columns(
        &self,
        f: &StaticNonlinearity,
        u: &[f64],
        out: &mut [f64],
        stride: usize,
    ) -> bool {
        let mut key = vec![0.0; self.key_names().len()];
        let mut unchanged = true;
        for (q, &uq) in u.iter().enumerate() {
            self.fill_key_terms(f, uq, &mut key);
            for (t, v) in key.iter().enumerate() {
                let d = &mut out[t * stride + q];
                unchanged &= d.to_bits() == v.to_bits();
                *d = *v;
            }
        }
        unchanged
    }
    /// The nonlinearity from estimated key terms `key`; a parameter they do not determine keeps its
    /// value in `prev`; breakpoints are clamped to ±`limit`.
    fn of_key_terms(
        &self,
        key: &[f64],
        prev: &StaticNonlinearity,
        limit: f64,
    ) -> StaticNonlinearity;
    /// `f` replaced by [`Block::of_key_terms`]`(key, f, limit)`, in place (the recursion calls it at
    /// every sample; a kind may avoid moving the whole nonlinearity).
    fn set_key_terms(&self, key: &[f64], f: &mut StaticNonlinearity, limit: f64) {
        *f = self.of_key_terms(key, f, limit);
    }
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
    /// The physical parameters `v` with crossed breakpoints put in order, in the ways worth trying
    /// (empty when they are in order or the kind has none). A deadzone with b_l > b_r jumps by
    /// m_l (b_r − b_l) at b_r, a discontinuity the output-error search's one-sided derivative cannot
    /// see across: the search restarts from each of these, where the map is continuous again.
    fn ordered(&self, _v: &[f64]) -> Vec<Vec<f64>> {
        Vec::new()
    }
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

/// Physical parameters starting [b_l, b_r, …] with crossed breakpoints (b_l > b_r) put in order in
/// the three ways [`Block::ordered`] lists: b_l down to b_r, both to their midpoint, b_r up to b_l;
/// empty when they are in order (or not finite).
fn ordered_breakpoints(v: &[f64]) -> Vec<Vec<f64>> {
    if !(v.len() >= 2 && v[0] > v[1] && v[0].is_finite() && v[1].is_finite()) {
        return Vec::new();
    }
    let mid = 0.5 * (v[0] + v[1]);
    [(v[1], v[1]), (mid, mid), (v[0], v[0])]
        .iter()
        .map(|&(b_l, b_r)| {
            let mut w = v.to_vec();
            w[0] = b_l;
            w[1] = b_r;
            w
        })
        .collect()
}

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
    /// The same values as the default (those of [`Block::fill_key_terms`] above, row by row), written
    /// straight into the four columns with the deadzone read once: a loop without calls or a row
    /// buffer (Φ is built for the rank test and every closed-form pass).
    fn fill_key_columns(
        &self,
        f: &StaticNonlinearity,
        u: &[f64],
        out: &mut [f64],
        stride: usize,
    ) -> bool {
        let d = dz(f);
        let m = u.len();
        let (c0, rest) = out.split_at_mut(stride);
        let (c1, rest) = rest.split_at_mut(stride);
        let (c2, c3) = rest.split_at_mut(stride);
        let (c0, c1, c2, c3) = (&mut c0[..m], &mut c1[..m], &mut c2[..m], &mut c3[..m]);
        // The bits that differ from what the columns held, or-ed together: 0 when nothing changed.
        let mut changed = 0u64;
        for q in 0..m {
            let uq = u[q];
            let (hr, hl) = (d.h_r(uq), d.h_l(uq));
            let v = [hr * uq, -hr, hl * uq, -hl];
            changed |= (c0[q].to_bits() ^ v[0].to_bits())
                | (c1[q].to_bits() ^ v[1].to_bits())
                | (c2[q].to_bits() ^ v[2].to_bits())
                | (c3[q].to_bits() ^ v[3].to_bits());
            c0[q] = v[0];
            c1[q] = v[1];
            c2[q] = v[2];
            c3[q] = v[3];
        }
        changed == 0
    }
    fn of_key_terms(
        &self,
        key: &[f64],
        prev: &StaticNonlinearity,
        limit: f64,
    ) -> StaticNonlinearity {
        StaticNonlinearity::Deadzone(deadzone_from_theta(key, dz(prev), limit))
    }
    fn set_key_terms(&self, key: &[f64], f: &mut StaticNonlinearity, limit: f64) {
        match f {
            StaticNonlinearity::Deadzone(d) => *d = deadzone_from_theta(key, *d, limit),
            _ => *f = self.of_key_terms(key, f, limit),
        }
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
    fn ordered(&self, v: &[f64]) -> Vec<Vec<f64>> {
        ordered_breakpoints(v)
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
        deadzone_warnings(
            &dz(f),
            u,
            (left, right),
            (start.free_physical[0], start.free_physical[1]),
            (std[0], std[1]),
        )
    }
}

/// The standard deviation of Σ_i w_i θ_{idx_i} from Cov(θ̂) (a linear combination of estimates).
fn combination_std(cov: Option<&DMatrix<f64>>, terms: &[(usize, f64)]) -> Option<f64> {
    let c = cov?;
    let mut v = 0.0;
    for &(i, wi) in terms {
        for &(j, wj) in terms {
            v += wi * wj * c[(i, j)];
        }
    }
    (v.is_finite() && v >= 0.0).then(|| v.sqrt())
}

/// `num / den` clamped to ±`limit`, or `prev` when not finite (a breakpoint from its key-term product).
fn ratio_or(num: f64, den: f64, prev: f64, limit: f64) -> f64 {
    let r = num / den;
    if r.is_finite() {
        r.clamp(-limit, limit)
    } else {
        prev
    }
}

/// The q-quantile (0..1) of `v` (sorted copy; empty: 0).
fn quantile(v: &[f64], q: f64) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return 0.0;
    }
    s.sort_by(f64::total_cmp);
    s[((s.len() - 1) as f64 * q).round() as usize]
}

/// Distinct input levels a deadzone needs to be determined: 4 with two branches whose breakpoints are
/// both free (b_l, m_l, b_r, m_r), otherwise 3 (`identify`'s refusal and `track`'s end-of-run warning).
pub(crate) fn deadzone_levels_needed(both_branches_free: bool) -> usize {
    if both_branches_free {
        4
    } else {
        3
    }
}

/// Refuses an input with fewer than `need` distinct levels for a block of `kind`.
fn need_levels(u: &[f64], need: usize, kind: &str, name: &str) -> Result<Vec<f64>, SysidError> {
    let levels = levels_of(u);
    if levels.len() < need {
        return Err(SysidError::Data(format!(
            "{name}: the input has {} distinct level(s); a {kind} input nonlinearity needs at least {need} \
             (not persistently exciting)",
            levels.len()
        )));
    }
    Ok(levels)
}

/// Distinct input levels a saturation needs to be determined: one at or beyond each limit and two
/// inside the linear interval ([`SaturationBlock`]'s start refuses fewer).
pub(crate) const SATURATION_LEVELS: usize = 4;

/// Magnitude standing for "no limit" in the linear equivalent of a saturating kind (finite, so that
/// m s_r stays finite; far outside any record).
const NO_LIMIT: f64 = 1e100;

/// Asymmetric saturation x = m clamp(u, s_l, s_r). Physical [s_l, s_r, m]; key terms [m, m s_l, m s_r]
/// with regressors [h u, h_lo, h_hi] at u(k − nk) (h_lo = [u ≤ s_l], h_hi = [u ≥ s_r], h = 1 − h_lo − h_hi).
pub struct SaturationBlock;

fn sat(f: &StaticNonlinearity) -> Saturation {
    match f {
        StaticNonlinearity::Saturation(s) => *s,
        _ => Saturation {
            s_l: 0.0,
            s_r: 0.0,
            m: 0.0,
        },
    }
}

impl Block for SaturationBlock {
    fn physical_names(&self) -> &'static [ParamName] {
        &[ParamName::SL, ParamName::SR, ParamName::M]
    }
    fn key_names(&self) -> &'static [ParamName] {
        &[ParamName::M, ParamName::MSl, ParamName::MSr]
    }
    fn physical(&self, f: &StaticNonlinearity) -> Vec<f64> {
        let s = sat(f);
        vec![s.s_l, s.s_r, s.m]
    }
    fn of_physical(&self, v: &[f64]) -> StaticNonlinearity {
        StaticNonlinearity::Saturation(Saturation {
            s_l: v[0],
            s_r: v[1],
            m: v[2],
        })
    }
    fn key_terms(&self, f: &StaticNonlinearity) -> Vec<f64> {
        let s = sat(f);
        vec![s.m, s.m * s.s_l, s.m * s.s_r]
    }
    fn fill_key_terms(&self, f: &StaticNonlinearity, u: f64, out: &mut [f64]) {
        let s = sat(f);
        let (lo, hi) = if u <= s.s_l {
            (1.0, 0.0)
        } else if u >= s.s_r {
            (0.0, 1.0)
        } else {
            (0.0, 0.0)
        };
        out[0] = (1.0 - lo - hi) * u;
        out[1] = lo;
        out[2] = hi;
    }
    fn of_key_terms(
        &self,
        key: &[f64],
        prev: &StaticNonlinearity,
        limit: f64,
    ) -> StaticNonlinearity {
        let p = sat(prev);
        StaticNonlinearity::Saturation(Saturation {
            s_l: ratio_or(key[1], key[0], p.s_l, limit),
            s_r: ratio_or(key[2], key[0], p.s_r, limit),
            m: key[0],
        })
    }
    fn physical_with_std(
        &self,
        theta: &[f64],
        cov: Option<&DMatrix<f64>>,
        at: usize,
    ) -> Vec<(f64, Option<f64>)> {
        vec![
            ratio_with_std(theta, cov, at, at + 1),
            ratio_with_std(theta, cov, at, at + 2),
            (theta[at], sd(cov, at)),
        ]
    }
    fn derivative(&self, f: &StaticNonlinearity, which: usize, u: f64) -> f64 {
        let s = sat(f);
        let lo = u <= s.s_l;
        let hi = !lo && u >= s.s_r;
        match which {
            0 => f64::from(u8::from(lo)) * s.m,
            1 => f64::from(u8::from(hi)) * s.m,
            _ => {
                if lo {
                    s.s_l
                } else if hi {
                    s.s_r
                } else {
                    u
                }
            }
        }
    }
    fn is_degenerate(&self, f: &StaticNonlinearity) -> bool {
        sat(f).m == 0.0
    }
    fn start(&self, u: &[f64], _: bool, _: bool, name: &str) -> Result<BlockStart, SysidError> {
        // Each of the map's three pieces needs its levels: every level at or below s_l gives the one
        // value m s_l, so s_l needs a level there, s_r likewise above; the slope m of the linear
        // interval needs two levels inside it (the rule of the saturation's own warning). Fewer than
        // 1 + 2 + 1 = 4 distinct levels leave a limit or the slope free, which the regression would
        // only report as an unexcited regressor (audit s35b L-8: "regressor m is zero" on a
        // three-level input).
        let levels = levels_of(u);
        if levels.len() < SATURATION_LEVELS {
            let list: Vec<String> = levels
                .iter()
                .map(|&v| sysid_core::format::shortest(v))
                .collect();
            return Err(SysidError::Data(format!(
                "{name}: the input takes only {} distinct level(s) ({}); a saturation input \
                 nonlinearity needs at least {SATURATION_LEVELS} distinct levels: one at or beyond each \
                 limit (s_l, s_r) and two inside the linear interval for its slope m (use a linear \
                 input, --structure arx, or an input with several amplitudes)",
                levels.len(),
                list.join(", ")
            )));
        }
        // Limits at the 10 % and 90 % quantiles: some samples on each saturated part and inside.
        let (mut s_l, mut s_r) = (quantile(u, 0.1), quantile(u, 0.9));
        if s_l >= s_r || s_l <= levels[0] && s_r >= levels[levels.len() - 1] {
            s_l = levels[0];
            s_r = levels[levels.len() - 1];
        }
        let limit = levels[0].abs().max(levels[levels.len() - 1].abs());
        Ok(BlockStart {
            initial: StaticNonlinearity::Saturation(Saturation { s_l, s_r, m: 1.0 }),
            free_key: vec![true; 3],
            free_physical: vec![true; 3],
            limit,
            notes: Vec::new(),
        })
    }
    fn linear_equivalent(
        &self,
        b1: f64,
        b1_std: Option<f64>,
    ) -> (StaticNonlinearity, Vec<Option<f64>>) {
        let s = Saturation {
            s_l: -NO_LIMIT,
            s_r: NO_LIMIT,
            m: b1,
        };
        (StaticNonlinearity::Saturation(s), vec![None, None, b1_std])
    }
    fn warnings(
        &self,
        f: &StaticNonlinearity,
        u: &[f64],
        _: &BlockStart,
        std: &[Option<f64>],
    ) -> (Vec<Warning>, Vec<ParamName>) {
        let s = sat(f);
        let (mut w, mut no_std) = (Vec::new(), Vec::new());
        let levels = levels_of(u);
        if s.s_l >= s.s_r {
            w.push(Warning::NonlinearityShape {
                kind: "saturation",
                why: format!(
                    "not physical: s_l = {} >= s_r = {} (no linear interval)",
                    s.s_l, s.s_r
                ),
            });
        }
        check_breakpoint(ParamName::SL, s.s_l, std[0], &levels, &mut w, &mut no_std);
        check_breakpoint(ParamName::SR, s.s_r, std[1], &levels, &mut w, &mut no_std);
        let inside = levels.iter().filter(|l| **l > s.s_l && **l < s.s_r).count();
        if inside < 2 {
            w.push(Warning::NonlinearityShape {
                kind: "saturation",
                why: format!(
                    "{inside} distinct input level(s) inside the linear interval: its slope m is not determined"
                ),
            });
        }
        (w, no_std)
    }
}

/// A deadzone whose branches saturate. Physical [b_l, b_r, s_l, s_r, m_l, m_r]; key terms
/// [m_r, m_r b_r, m_r s_r, m_l, m_l b_l, m_l s_l] with regressors [h_r u, −(h_r + H_r), H_r, h_l u,
/// −(h_l + H_l), H_l] (H_r = [u ≥ s_r], h_r = [b_r ≤ u < s_r], H_l = [u ≤ s_l], h_l = [s_l < u ≤ b_l]).
pub struct DeadzoneSaturationBlock;

fn dzs(f: &StaticNonlinearity) -> DeadzoneSaturation {
    match f {
        StaticNonlinearity::DeadzoneSaturation(d) => *d,
        _ => DeadzoneSaturation {
            b_l: 0.0,
            b_r: 0.0,
            s_l: 0.0,
            s_r: 0.0,
            m_l: 0.0,
            m_r: 0.0,
        },
    }
}

/// The regions of u for a deadzone with saturation: (h_r, H_r, h_l, H_l), in the order of
/// [`DeadzoneSaturation::apply`].
fn dzs_regions(d: &DeadzoneSaturation, u: f64) -> (f64, f64, f64, f64) {
    if u >= d.s_r {
        (0.0, 1.0, 0.0, 0.0)
    } else if u >= d.b_r {
        (1.0, 0.0, 0.0, 0.0)
    } else if u <= d.s_l {
        (0.0, 0.0, 0.0, 1.0)
    } else if u <= d.b_l {
        (0.0, 0.0, 1.0, 0.0)
    } else {
        (0.0, 0.0, 0.0, 0.0)
    }
}

impl Block for DeadzoneSaturationBlock {
    fn physical_names(&self) -> &'static [ParamName] {
        &[
            ParamName::BL,
            ParamName::BR,
            ParamName::SL,
            ParamName::SR,
            ParamName::ML,
            ParamName::MR,
        ]
    }
    fn key_names(&self) -> &'static [ParamName] {
        &[
            ParamName::MR,
            ParamName::MrBr,
            ParamName::MrSr,
            ParamName::ML,
            ParamName::MlBl,
            ParamName::MlSl,
        ]
    }
    fn physical(&self, f: &StaticNonlinearity) -> Vec<f64> {
        let d = dzs(f);
        vec![d.b_l, d.b_r, d.s_l, d.s_r, d.m_l, d.m_r]
    }
    fn of_physical(&self, v: &[f64]) -> StaticNonlinearity {
        StaticNonlinearity::DeadzoneSaturation(DeadzoneSaturation {
            b_l: v[0],
            b_r: v[1],
            s_l: v[2],
            s_r: v[3],
            m_l: v[4],
            m_r: v[5],
        })
    }
    fn key_terms(&self, f: &StaticNonlinearity) -> Vec<f64> {
        let d = dzs(f);
        vec![
            d.m_r,
            d.m_r * d.b_r,
            d.m_r * d.s_r,
            d.m_l,
            d.m_l * d.b_l,
            d.m_l * d.s_l,
        ]
    }
    fn fill_key_terms(&self, f: &StaticNonlinearity, u: f64, out: &mut [f64]) {
        let (hr, sr, hl, sl) = dzs_regions(&dzs(f), u);
        out[0] = hr * u;
        out[1] = -(hr + sr);
        out[2] = sr;
        out[3] = hl * u;
        out[4] = -(hl + sl);
        out[5] = sl;
    }
    fn of_key_terms(
        &self,
        key: &[f64],
        prev: &StaticNonlinearity,
        limit: f64,
    ) -> StaticNonlinearity {
        let p = dzs(prev);
        StaticNonlinearity::DeadzoneSaturation(DeadzoneSaturation {
            b_r: ratio_or(key[1], key[0], p.b_r, limit),
            s_r: ratio_or(key[2], key[0], p.s_r, limit),
            m_r: key[0],
            b_l: ratio_or(key[4], key[3], p.b_l, limit),
            s_l: ratio_or(key[5], key[3], p.s_l, limit),
            m_l: key[3],
        })
    }
    fn physical_with_std(
        &self,
        theta: &[f64],
        cov: Option<&DMatrix<f64>>,
        at: usize,
    ) -> Vec<(f64, Option<f64>)> {
        vec![
            ratio_with_std(theta, cov, at + 3, at + 4),
            ratio_with_std(theta, cov, at, at + 1),
            ratio_with_std(theta, cov, at + 3, at + 5),
            ratio_with_std(theta, cov, at, at + 2),
            (theta[at + 3], sd(cov, at + 3)),
            (theta[at], sd(cov, at)),
        ]
    }
    fn ordered(&self, v: &[f64]) -> Vec<Vec<f64>> {
        ordered_breakpoints(v)
    }
    fn derivative(&self, f: &StaticNonlinearity, which: usize, u: f64) -> f64 {
        let d = dzs(f);
        let (hr, sr, hl, sl) = dzs_regions(&d, u);
        match which {
            0 => -d.m_l * (hl + sl),
            1 => -d.m_r * (hr + sr),
            2 => d.m_l * sl,
            3 => d.m_r * sr,
            4 => hl * (u - d.b_l) + sl * (d.s_l - d.b_l),
            _ => hr * (u - d.b_r) + sr * (d.s_r - d.b_r),
        }
    }
    fn is_degenerate(&self, f: &StaticNonlinearity) -> bool {
        let d = dzs(f);
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
        let dz = b.initial_deadzone();
        // Saturation breakpoints at the 90 % quantile of |u| on each excited side.
        let pos: Vec<f64> = u.iter().copied().filter(|v| *v > 0.0).collect();
        let neg: Vec<f64> = u.iter().filter(|v| **v < 0.0).map(|v| -v).collect();
        let s_r = if b.right { quantile(&pos, 0.9) } else { 0.0 };
        let s_l = if b.left { -quantile(&neg, 0.9) } else { 0.0 };
        let (l, r) = (b.left, b.right);
        Ok(BlockStart {
            initial: StaticNonlinearity::DeadzoneSaturation(DeadzoneSaturation {
                b_l: dz.b_l,
                b_r: dz.b_r,
                s_l,
                s_r,
                m_l: dz.m_l,
                m_r: dz.m_r,
            }),
            free_key: vec![r, r && !b.b_r_fixed, r, l, l && !b.b_l_fixed, l],
            free_physical: vec![l && !b.b_l_fixed, r && !b.b_r_fixed, l, r, l, r],
            limit: b.limit,
            notes: b.notes(),
        })
    }
    fn linear_equivalent(
        &self,
        b1: f64,
        b1_std: Option<f64>,
    ) -> (StaticNonlinearity, Vec<Option<f64>>) {
        let d = DeadzoneSaturation {
            b_l: 0.0,
            b_r: 0.0,
            s_l: -NO_LIMIT,
            s_r: NO_LIMIT,
            m_l: b1,
            m_r: b1,
        };
        (
            StaticNonlinearity::DeadzoneSaturation(d),
            vec![None, None, None, None, b1_std, b1_std],
        )
    }
    fn warnings(
        &self,
        f: &StaticNonlinearity,
        u: &[f64],
        start: &BlockStart,
        std: &[Option<f64>],
    ) -> (Vec<Warning>, Vec<ParamName>) {
        let d = dzs(f);
        let (left, right) = (start.free_physical[4], start.free_physical[5]);
        let as_dz = Deadzone {
            b_l: d.b_l,
            b_r: d.b_r,
            m_l: d.m_l,
            m_r: d.m_r,
        };
        let (mut w, mut no_std) = deadzone_warnings(
            &as_dz,
            u,
            (left, right),
            (start.free_physical[0], start.free_physical[1]),
            (std[0], std[1]),
        );
        let levels = levels_of(u);
        let sides = [
            (
                left,
                ParamName::SL,
                d.s_l,
                std[2],
                d.s_l >= d.b_l,
                "s_l >= b_l",
            ),
            (
                right,
                ParamName::SR,
                d.s_r,
                std[3],
                d.s_r <= d.b_r,
                "s_r <= b_r",
            ),
        ];
        for (estimated, name, value, s, crossed, what) in sides {
            if !estimated {
                continue;
            }
            if crossed {
                w.push(Warning::NonlinearityShape {
                    kind: "deadzone-saturation",
                    why: format!("not physical: {what} ({name} = {value}): the branch saturates before it opens"),
                });
            }
            check_breakpoint(name, value, s, &levels, &mut w, &mut no_std);
        }
        (w, no_std)
    }
}

/// A piecewise-linear map through the origin with K breakpoints ([`PiecewiseLinear`]). Physical
/// [p_1..p_K, s_0..s_K]; key terms [s_0, d_1, d_1 p_1, …, d_K, d_K p_K] (d_i = s_i − s_{i−1}) with
/// regressors [u, h_1 u, −(h_1 − [p_1 < 0]), …] (h_i = [u ≥ p_i]): d_i (h_i u − p_i (h_i − [p_i < 0]))
/// = d_i [(u − p_i)_+ − (−p_i)_+].
pub struct PiecewiseBlock {
    k: usize,
}

const PWL_NAMES: usize = 2 * MAX_BREAKPOINTS + 1;

/// The physical (`key` false) or key-term names of K breakpoints, in the first 2K + 1 entries.
const fn pwl_names(k: usize, key: bool) -> [ParamName; PWL_NAMES] {
    let mut a = [ParamName::C; PWL_NAMES];
    if key {
        a[0] = ParamName::Slope(0);
        let mut i = 1;
        while i <= k {
            a[2 * i - 1] = ParamName::Kink(i);
            a[2 * i] = ParamName::KinkKnot(i);
            i += 1;
        }
    } else {
        let mut i = 0;
        while i < k {
            a[i] = ParamName::Knot(i + 1);
            i += 1;
        }
        let mut j = 0;
        while j <= k {
            a[k + j] = ParamName::Slope(j);
            j += 1;
        }
    }
    a
}

const fn pwl_table(key: bool) -> [[ParamName; PWL_NAMES]; MAX_BREAKPOINTS + 1] {
    let mut t = [[ParamName::C; PWL_NAMES]; MAX_BREAKPOINTS + 1];
    let mut k = 0;
    while k <= MAX_BREAKPOINTS {
        t[k] = pwl_names(k, key);
        k += 1;
    }
    t
}

static PWL_PHYSICAL: [[ParamName; PWL_NAMES]; MAX_BREAKPOINTS + 1] = pwl_table(false);
static PWL_KEY: [[ParamName; PWL_NAMES]; MAX_BREAKPOINTS + 1] = pwl_table(true);

static PIECEWISE: [PiecewiseBlock; MAX_BREAKPOINTS + 1] = [
    PiecewiseBlock { k: 0 },
    PiecewiseBlock { k: 1 },
    PiecewiseBlock { k: 2 },
    PiecewiseBlock { k: 3 },
    PiecewiseBlock { k: 4 },
    PiecewiseBlock { k: 5 },
    PiecewiseBlock { k: 6 },
    PiecewiseBlock { k: 7 },
    PiecewiseBlock { k: 8 },
];

impl PiecewiseBlock {
    /// The map of `f`, or the identity-like map of K breakpoints at 0 with zero slopes.
    fn pwl(&self, f: &StaticNonlinearity) -> PiecewiseLinear {
        match f {
            StaticNonlinearity::PiecewiseLinear(p) if p.breakpoints().len() == self.k => *p,
            _ => PiecewiseLinear::new(&vec![0.0; self.k], &vec![0.0; self.k + 1])
                .unwrap_or_else(|_| unreachable_pwl()),
        }
    }

    /// The map from breakpoints and slope changes (pairs sorted by breakpoint) and s_0.
    fn from_kinks(s0: f64, mut kinks: Vec<(f64, f64)>) -> StaticNonlinearity {
        kinks.sort_by(|a, b| a.0.total_cmp(&b.0));
        let p: Vec<f64> = kinks.iter().map(|k| k.0).collect();
        let mut s = Vec::with_capacity(p.len() + 1);
        s.push(s0);
        for (_, d) in &kinks {
            s.push(s[s.len() - 1] + d);
        }
        match PiecewiseLinear::new(&p, &s) {
            Ok(f) => StaticNonlinearity::PiecewiseLinear(f),
            Err(_) => StaticNonlinearity::Linear,
        }
    }
}

/// A K = 1 map of zeros (the blocks are only built for K in 1..=MAX_BREAKPOINTS, checked by
/// [`NonlinearityKind::check`]; this keeps a bad K from panicking).
fn unreachable_pwl() -> PiecewiseLinear {
    match PiecewiseLinear::new(&[0.0], &[0.0, 0.0]) {
        Ok(p) => p,
        Err(_) => unreachable!("one breakpoint and two slopes are a valid piecewise-linear map"),
    }
}

impl Block for PiecewiseBlock {
    fn physical_names(&self) -> &'static [ParamName] {
        &PWL_PHYSICAL[self.k][..2 * self.k + 1]
    }
    fn key_names(&self) -> &'static [ParamName] {
        &PWL_KEY[self.k][..2 * self.k + 1]
    }
    fn physical(&self, f: &StaticNonlinearity) -> Vec<f64> {
        let p = self.pwl(f);
        p.breakpoints().iter().chain(p.slopes()).copied().collect()
    }
    fn of_physical(&self, v: &[f64]) -> StaticNonlinearity {
        let k = self.k;
        match PiecewiseLinear::new(&v[..k], &v[k..=2 * k]) {
            Ok(p) => StaticNonlinearity::PiecewiseLinear(p),
            Err(_) => StaticNonlinearity::Linear,
        }
    }
    fn key_terms(&self, f: &StaticNonlinearity) -> Vec<f64> {
        let p = self.pwl(f);
        let s = p.slopes();
        let mut v = vec![s[0]];
        for (i, pi) in p.breakpoints().iter().enumerate() {
            let d = s[i + 1] - s[i];
            v.extend([d, d * pi]);
        }
        v
    }
    fn fill_key_terms(&self, f: &StaticNonlinearity, u: f64, out: &mut [f64]) {
        let p = self.pwl(f);
        out[0] = u;
        for (i, pi) in p.breakpoints().iter().enumerate() {
            let h = if u >= *pi { 1.0 } else { 0.0 };
            let neg = if *pi < 0.0 { 1.0 } else { 0.0 };
            out[2 * i + 1] = h * u;
            out[2 * i + 2] = -(h - neg);
        }
    }
    fn of_key_terms(
        &self,
        key: &[f64],
        prev: &StaticNonlinearity,
        limit: f64,
    ) -> StaticNonlinearity {
        let old = self.pwl(prev);
        let kinks = (0..self.k)
            .map(|i| {
                let d = key[2 * i + 1];
                (ratio_or(key[2 * i + 2], d, old.breakpoints()[i], limit), d)
            })
            .collect();
        Self::from_kinks(key[0], kinks)
    }
    fn physical_with_std(
        &self,
        theta: &[f64],
        cov: Option<&DMatrix<f64>>,
        at: usize,
    ) -> Vec<(f64, Option<f64>)> {
        // Breakpoints p_i = (d_i p_i) / d_i by the delta method, then sorted with their kinks; the
        // slopes s_j = s_0 + Σ_{sorted i ≤ j} d_i are linear in θ.
        let mut kinks: Vec<(usize, (f64, Option<f64>))> = (0..self.k)
            .map(|i| {
                let d = at + 2 * i + 1;
                (d, ratio_with_std(theta, cov, d, d + 1))
            })
            .collect();
        kinks.sort_by(|a, b| a.1 .0.total_cmp(&b.1 .0));
        let mut out: Vec<(f64, Option<f64>)> = kinks.iter().map(|k| k.1).collect();
        let mut terms = vec![(at, 1.0)];
        let mut s = theta[at];
        out.push((s, sd(cov, at)));
        for (d, _) in &kinks {
            terms.push((*d, 1.0));
            s += theta[*d];
            out.push((s, combination_std(cov, &terms)));
        }
        out
    }
    fn derivative(&self, f: &StaticNonlinearity, which: usize, u: f64) -> f64 {
        let p = self.pwl(f);
        let (k, s) = (self.k, p.slopes());
        if which < k {
            let pi = p.breakpoints()[which];
            let h = if u >= pi { 1.0 } else { 0.0 };
            let neg = if pi < 0.0 { 1.0 } else { 0.0 };
            return -(s[which + 1] - s[which]) * (h - neg);
        }
        let j = which - k;
        let mut v = if j == 0 { u } else { p.hinge(j, u) };
        if j < k {
            v -= p.hinge(j + 1, u);
        }
        v
    }
    fn is_degenerate(&self, f: &StaticNonlinearity) -> bool {
        self.pwl(f).slopes().iter().all(|s| *s == 0.0)
    }
    fn start(&self, u: &[f64], _: bool, _: bool, name: &str) -> Result<BlockStart, SysidError> {
        let k = self.k;
        let levels = need_levels(u, k + 2, "piecewise-linear", name)?;
        // Breakpoints at the quantiles i/(K+1) of u, moved to distinct levels strictly inside the range.
        let inner = &levels[1..levels.len() - 1];
        let mut p: Vec<f64> = (1..=k)
            .map(|i| quantile(u, i as f64 / (k + 1) as f64))
            .collect();
        p.dedup();
        if p.len() < k || p[0] <= levels[0] || p[p.len() - 1] >= levels[levels.len() - 1] {
            p = (1..=k)
                .map(|i| inner[(i * inner.len()) / (k + 1)])
                .collect();
            p.dedup();
            if p.len() < k {
                p = inner[..k].to_vec();
            }
        }
        let initial = PiecewiseLinear::new(&p, &vec![1.0; k + 1])?;
        let limit = levels[0].abs().max(levels[levels.len() - 1].abs());
        Ok(BlockStart {
            initial: StaticNonlinearity::PiecewiseLinear(initial),
            free_key: vec![true; 2 * k + 1],
            free_physical: vec![true; 2 * k + 1],
            limit,
            notes: Vec::new(),
        })
    }
    fn linear_equivalent(
        &self,
        b1: f64,
        b1_std: Option<f64>,
    ) -> (StaticNonlinearity, Vec<Option<f64>>) {
        let k = self.k;
        let f = PiecewiseLinear::new(&vec![0.0; k], &vec![b1; k + 1])
            .map(StaticNonlinearity::PiecewiseLinear)
            .unwrap_or(StaticNonlinearity::Linear);
        let mut std = vec![None; k];
        std.extend(vec![b1_std; k + 1]);
        (f, std)
    }
    fn warnings(
        &self,
        f: &StaticNonlinearity,
        u: &[f64],
        _: &BlockStart,
        std: &[Option<f64>],
    ) -> (Vec<Warning>, Vec<ParamName>) {
        let p = self.pwl(f);
        let (mut w, mut no_std) = (Vec::new(), Vec::new());
        let levels = levels_of(u);
        let bp = p.breakpoints();
        for (i, pi) in bp.iter().enumerate() {
            check_breakpoint(
                ParamName::Knot(i + 1),
                *pi,
                std[i],
                &levels,
                &mut w,
                &mut no_std,
            );
        }
        // Each segment needs two distinct levels to determine its slope.
        for j in 0..=bp.len() {
            let lo = if j == 0 { f64::NEG_INFINITY } else { bp[j - 1] };
            let hi = bp.get(j).copied().unwrap_or(f64::INFINITY);
            let n = levels.iter().filter(|l| **l >= lo && **l <= hi).count();
            if n < 2 {
                w.push(Warning::NonlinearityShape {
                    kind: "piecewise-linear",
                    why: format!(
                        "segment {j} ({lo} .. {hi}) holds {n} distinct input level(s): its slope s{j} is not determined"
                    ),
                });
            }
        }
        (w, no_std)
    }
}

/// A polynomial through the origin of degree D ([`Polynomial`]): physical parameters and key terms
/// [g_1..g_D] with regressors [u, u², …, u^D] (linear in its parameters: no iteration on the block).
pub struct PolynomialBlock {
    d: usize,
}

static POLY_NAMES: [ParamName; MAX_DEGREE] = [
    ParamName::Poly(1),
    ParamName::Poly(2),
    ParamName::Poly(3),
    ParamName::Poly(4),
    ParamName::Poly(5),
    ParamName::Poly(6),
    ParamName::Poly(7),
    ParamName::Poly(8),
];

static POLYNOMIAL: [PolynomialBlock; MAX_DEGREE + 1] = [
    PolynomialBlock { d: 0 },
    PolynomialBlock { d: 1 },
    PolynomialBlock { d: 2 },
    PolynomialBlock { d: 3 },
    PolynomialBlock { d: 4 },
    PolynomialBlock { d: 5 },
    PolynomialBlock { d: 6 },
    PolynomialBlock { d: 7 },
    PolynomialBlock { d: 8 },
];

impl PolynomialBlock {
    fn coefficients(&self, f: &StaticNonlinearity) -> Vec<f64> {
        match f {
            StaticNonlinearity::Polynomial(p) if p.coefficients().len() == self.d => {
                p.coefficients().to_vec()
            }
            _ => vec![0.0; self.d],
        }
    }
}

impl Block for PolynomialBlock {
    fn physical_names(&self) -> &'static [ParamName] {
        &POLY_NAMES[..self.d]
    }
    fn key_names(&self) -> &'static [ParamName] {
        &POLY_NAMES[..self.d]
    }
    fn physical(&self, f: &StaticNonlinearity) -> Vec<f64> {
        self.coefficients(f)
    }
    fn of_physical(&self, v: &[f64]) -> StaticNonlinearity {
        Polynomial::new(&v[..self.d])
            .map(StaticNonlinearity::Polynomial)
            .unwrap_or(StaticNonlinearity::Linear)
    }
    fn key_terms(&self, f: &StaticNonlinearity) -> Vec<f64> {
        self.coefficients(f)
    }
    fn fill_key_terms(&self, _: &StaticNonlinearity, u: f64, out: &mut [f64]) {
        let mut p = u;
        for o in out.iter_mut().take(self.d) {
            *o = p;
            p *= u;
        }
    }
    fn of_key_terms(&self, key: &[f64], _: &StaticNonlinearity, _: f64) -> StaticNonlinearity {
        self.of_physical(key)
    }
    fn physical_with_std(
        &self,
        theta: &[f64],
        cov: Option<&DMatrix<f64>>,
        at: usize,
    ) -> Vec<(f64, Option<f64>)> {
        (at..at + self.d).map(|i| (theta[i], sd(cov, i))).collect()
    }
    fn derivative(&self, _: &StaticNonlinearity, which: usize, u: f64) -> f64 {
        u.powi(which as i32 + 1)
    }
    fn is_degenerate(&self, f: &StaticNonlinearity) -> bool {
        self.coefficients(f).iter().all(|g| *g == 0.0)
    }
    fn start(&self, u: &[f64], _: bool, _: bool, name: &str) -> Result<BlockStart, SysidError> {
        let levels = need_levels(u, self.d + 1, "polynomial", name)?;
        let mut g = vec![0.0; self.d];
        g[0] = 1.0;
        Ok(BlockStart {
            initial: self.of_physical(&g),
            free_key: vec![true; self.d],
            free_physical: vec![true; self.d],
            limit: levels[0].abs().max(levels[levels.len() - 1].abs()),
            notes: Vec::new(),
        })
    }
    fn linear_equivalent(
        &self,
        b1: f64,
        b1_std: Option<f64>,
    ) -> (StaticNonlinearity, Vec<Option<f64>>) {
        let mut g = vec![0.0; self.d];
        g[0] = b1;
        let mut std = vec![None; self.d];
        std[0] = b1_std;
        (self.of_physical(&g), std)
    }
    fn warnings(
        &self,
        f: &StaticNonlinearity,
        u: &[f64],
        _: &BlockStart,
        _: &[Option<f64>],
    ) -> (Vec<Warning>, Vec<ParamName>) {
        let mut w = Vec::new();
        let levels = levels_of(u);
        if let (Some(&lo), Some(&hi)) = (levels.first(), levels.last()) {
            if let Some(at) = monotonicity_change(|v| f.apply(v), lo, hi) {
                w.push(Warning::NonlinearityShape {
                    kind: "polynomial",
                    why: format!(
                        "not monotone over the input range {lo} .. {hi} (it turns near u = {at:.6}): a larger \
                         command does not always give a larger x, which an actuator map rarely does"
                    ),
                });
            }
        }
        (w, Vec::new())
    }
}

/// Where f changes direction on [lo, hi] (sampled at 512 points, ignoring steps below 1e-12 of its
/// range), if it does.
pub(crate) fn monotonicity_change(f: impl Fn(f64) -> f64, lo: f64, hi: f64) -> Option<f64> {
    const N: usize = 512;
    let xs: Vec<f64> = (0..=N)
        .map(|i| lo + (hi - lo) * i as f64 / N as f64)
        .collect();
    let ys: Vec<f64> = xs.iter().map(|x| f(*x)).collect();
    let span = ys.iter().fold(0.0_f64, |m, y| m.max(y.abs())).max(1e-300);
    let mut dir = 0.0;
    for i in 1..=N {
        let step = ys[i] - ys[i - 1];
        if step.abs() <= 1e-12 * span {
            continue;
        }
        if dir * step < 0.0 {
            return Some(xs[i - 1]);
        }
        dir = step.signum();
    }
    None
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

/// The extremes of the positive and of the negative commands of an input (±∞ when there is none),
/// and whether some command is neither (0 or NaN).
#[derive(Debug, Clone, Copy, PartialEq)]
struct SignedExtremes {
    min_pos: f64,
    max_pos: f64,
    max_neg: f64,
    min_neg: f64,
    zero: bool,
}

impl SignedExtremes {
    const NONE: SignedExtremes = SignedExtremes {
        min_pos: f64::INFINITY,
        max_pos: f64::NEG_INFINITY,
        max_neg: f64::NEG_INFINITY,
        min_neg: f64::INFINITY,
        zero: false,
    };

    /// Takes the command `v` in (branch-free selects: a positive `v` can only move the positive
    /// extremes, a negative one the negative extremes, anything else sets `zero`).
    #[inline]
    fn take(&mut self, v: f64) {
        let (pos, neg) = (v > 0.0, v < 0.0);
        self.min_pos = if pos && v < self.min_pos {
            v
        } else {
            self.min_pos
        };
        self.max_pos = if pos && v > self.max_pos {
            v
        } else {
            self.max_pos
        };
        self.max_neg = if neg && v > self.max_neg {
            v
        } else {
            self.max_neg
        };
        self.min_neg = if neg && v < self.min_neg {
            v
        } else {
            self.min_neg
        };
        self.zero |= !pos && !neg;
    }

    /// The extremes of `u`, in four lanes (independent, vectorisable) then combined. The extremes of
    /// a set of nonzero numbers (no NaN: those are neither positive nor negative) do not depend on the
    /// order they are taken in, and equal nonzero numbers have the same bits: the result is the
    /// sample-by-sample one to the bit.
    fn of(u: &[f64]) -> Self {
        let mut lanes = [Self::NONE; 4];
        let mut chunks = u.chunks_exact(4);
        for c in &mut chunks {
            for (lane, &v) in lanes.iter_mut().zip(c) {
                lane.take(v);
            }
        }
        let mut all = Self::NONE;
        for lane in &lanes {
            all.min_pos = if lane.min_pos < all.min_pos {
                lane.min_pos
            } else {
                all.min_pos
            };
            all.max_pos = if lane.max_pos > all.max_pos {
                lane.max_pos
            } else {
                all.max_pos
            };
            all.max_neg = if lane.max_neg > all.max_neg {
                lane.max_neg
            } else {
                all.max_neg
            };
            all.min_neg = if lane.min_neg < all.min_neg {
                lane.min_neg
            } else {
                all.min_neg
            };
            all.zero |= lane.zero;
        }
        for &v in chunks.remainder() {
            all.take(v);
        }
        all
    }
}

impl Branches {
    /// Looks at the input `u`. With `allow_one_sided == false` a one-sided input is refused (as the
    /// paper's method would fail on it); otherwise the unexcited branch is dropped.
    fn of(u: &[f64], offset: bool, allow_one_sided: bool, name: &str) -> Result<Self, SysidError> {
        let SignedExtremes {
            min_pos,
            max_pos,
            max_neg,
            min_neg,
            zero,
        } = SignedExtremes::of(u);
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
        let (b_l_fixed, b_r_fixed) = (
            left && !right && !zero && offset,
            right && !left && !zero && offset,
        );
        // Too few levels (a PRBS, a relay test, a three-level test signal) cannot determine a deadzone
        // with free breakpoints: the linear block sees one value of the map per level, so a map with
        // more free parameters than levels fits in many ways, which the regression would only report
        // as an unexcited regressor. Both branches with free breakpoints (b_l, m_l, b_r, m_r) need 4
        // levels, otherwise 3. (A constant input keeps the regression's own "constant input" error.)
        let need = deadzone_levels_needed(left && right && !b_l_fixed && !b_r_fixed);
        if let (false, false, Some(levels)) = (b_l_fixed, b_r_fixed, few_levels(u, need)) {
            if levels.len() >= 2 {
                // Exponent form beyond 1e16 (1e300 is not printed with 301 digits).
                let list: Vec<String> = levels
                    .iter()
                    .map(|v| {
                        if v.abs() < 1e16 {
                            v.to_string()
                        } else {
                            format!("{v:e}")
                        }
                    })
                    .collect();
                return Err(SysidError::Data(format!(
                    "{name}: the input takes only {} distinct levels ({}); a deadzone input \
                     nonlinearity {} needs at least {need} distinct levels: a static map through {} \
                     points is not determined (use a linear input, --structure arx, or an input with \
                     several amplitudes)",
                    levels.len(),
                    list.join(", "),
                    if need == 4 {
                        "with two branches (b_l, m_l, b_r, m_r)"
                    } else {
                        "with a free breakpoint"
                    },
                    levels.len()
                )));
            }
        }
        Ok(Branches {
            left,
            right,
            b_l_fixed,
            b_r_fixed,
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
/// branch was estimated (not dropped for a one-sided input); `free_l`/`free_r`: whether its breakpoint
/// was (a one-sided input whose every sample lies on one branch has that breakpoint fixed at 0: the
/// offset absorbs it, and no check blames the data for it; audit s16 L4). Returns the warnings and the
/// names of the breakpoints whose standard deviation is not meaningful.
pub fn deadzone_warnings(
    d: &Deadzone,
    u: &[f64],
    (left, right): (bool, bool),
    (free_l, free_r): (bool, bool),
    (std_l, std_r): (Option<f64>, Option<f64>),
) -> (Vec<Warning>, Vec<ParamName>) {
    let mut w = Vec::new();
    let mut no_std = Vec::new();
    let levels = levels_of(u);
    if levels.is_empty() {
        return (w, no_std);
    }
    if left && right && d.b_l > d.b_r {
        w.push(Warning::NonPhysicalDeadzone {
            why: format!("b_l = {} > b_r = {}", d.b_l, d.b_r),
        });
    }
    let (lo, hi) = (levels[0], levels[levels.len() - 1]);
    if levels.iter().all(|&l| d.apply(l) == 0.0) && (d.m_l != 0.0 || d.m_r != 0.0) {
        w.push(Warning::InputSwallowed {
            breakpoints: (d.b_l, d.b_r),
            range: (lo, hi),
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
        (left, free_l, ParamName::BL, d.b_l, std_l, Branch::Left),
        (right, free_r, ParamName::BR, d.b_r, std_r, Branch::Right),
    ];
    for (estimated, free, name, b, std, branch) in checks {
        if !estimated {
            continue;
        }
        if free {
            check_breakpoint(name, b, std, &levels, &mut w, &mut no_std);
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

/// The distinct finite values of `u`, sorted, when there are fewer than `need` of them (one pass,
/// stopping at the `need`-th value, so that it costs a few samples on any rich input).
fn few_levels(u: &[f64], need: usize) -> Option<Vec<f64>> {
    let mut seen: Vec<f64> = Vec::with_capacity(need);
    for v in u.iter().copied().filter(|v| v.is_finite()) {
        if !seen.contains(&v) {
            if seen.len() + 1 >= need {
                return None;
            }
            seen.push(v);
        }
    }
    seen.sort_unstable_by(f64::total_cmp);
    Some(seen)
}

/// The distinct values of `u`, sorted.
pub(crate) fn levels_of(u: &[f64]) -> Vec<f64> {
    // Runs of one value (a staircase holds each level for many samples) shrink to one entry before the
    // sort, as they are collected: the same distinct values, far fewer to sort.
    let mut levels: Vec<f64> = Vec::new();
    for &v in u {
        if v.is_finite() && levels.last().is_none_or(|l| !l.total_cmp(&v).is_eq()) {
            levels.push(v);
        }
    }
    // Entries equal under the total order are the same number: an unstable sort gives the same list.
    levels.sort_unstable_by(f64::total_cmp);
    levels.dedup();
    levels
}

/// Checks breakpoint `name` = `b` against the sorted distinct input `levels`: on a level (within 1e-9
/// relative, or within its standard deviation `std`) or not bracketed by the data. Pushes the warning
/// and, when its standard deviation is not meaningful, the name to `no_std`.
pub(crate) fn check_breakpoint(
    name: ParamName,
    b: f64,
    std: Option<f64>,
    levels: &[f64],
    w: &mut Vec<Warning>,
    no_std: &mut Vec<ParamName>,
) {
    let (Some(&u_min), Some(&u_max)) = (levels.first(), levels.last()) else {
        return;
    };
    let on = |l: f64| 1e-9 * l.abs().max(1.0);
    let reach = |l: f64| on(l).max(std.unwrap_or(0.0));
    // The nearest level (not the first within reach: a deviation of thousands of counts reaches the
    // lowest level first, audit s13 L17).
    let nearest = levels
        .iter()
        .copied()
        .min_by(|a, c| (b - a).abs().total_cmp(&(b - c).abs()));
    let on_level = nearest.filter(|l| (b - l).abs() <= on(*l));
    let outside = b < u_min - on(u_min) || b > u_max + on(u_max);
    if let (Some(level), false) = (nearest, outside && on_level.is_none()) {
        if (b - level).abs() <= reach(level) {
            w.push(Warning::BreakpointOnInputLevel {
                name,
                value: b,
                level,
                // On the level itself the deviation says nothing; near it, the withheld value is named.
                std: std.filter(|_| on_level.is_none()),
            });
            no_std.push(name);
            return;
        }
    }
    // Beyond the data (or on its edge): no samples on one side, whatever the deviation.
    if b <= u_min || b >= u_max {
        w.push(Warning::BreakpointNotBracketed {
            name,
            value: b,
            u_min,
            u_max,
        });
        no_std.push(name);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Crossed breakpoints (b_l = 0.753 > b_r = 0.037, the audit's robot arm end) are put in order in
    // three ways, each with b_l = b_r and the slopes kept; ordered ones are left alone.
    #[test]
    fn crossed_deadzone_breakpoints_are_put_in_order() {
        let v = [0.753, 0.037, 0.0025, 0.0102];
        let got = DeadzoneBlock.ordered(&v);
        let mid = 0.5 * (0.753 + 0.037);
        let want = [[0.037, 0.037], [mid, mid], [0.753, 0.753]];
        assert_eq!(got.len(), 3);
        for (g, w) in got.iter().zip(want) {
            assert_eq!((g[0], g[1], g[2], g[3]), (w[0], w[1], 0.0025, 0.0102));
        }
        assert!(DeadzoneBlock.ordered(&[-0.1, 0.2, 1.0, 1.0]).is_empty());
        assert!(LinearBlock.ordered(&[]).is_empty());
        // Deadzone with saturation: [b_l, b_r, s_l, s_r, m_l, m_r].
        let w = DeadzoneSaturationBlock.ordered(&[1.0, -1.0, -5.0, 5.0, 1.0, 1.0]);
        assert_eq!(w[0], vec![-1.0, -1.0, -5.0, 5.0, 1.0, 1.0]);
    }

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

    // The four-lane extremes are the sample-by-sample ones (written out here with f64::min/max and
    // branches) to the bit, for lengths around the lane count, zeros of both signs, NaN and ±∞.
    #[test]
    fn signed_extremes_in_four_lanes_are_the_sample_by_sample_ones() {
        let values = [
            0.0,
            -0.0,
            1.5,
            -2.0,
            f64::NAN,
            3.0,
            -1e-300,
            f64::INFINITY,
            7.0,
            -7.0,
        ];
        let mut cases: Vec<Vec<f64>> = Vec::new();
        for len in 0..=13 {
            for shift in 0..values.len() {
                cases.push(
                    (0..len)
                        .map(|i| values[(i * 7 + shift) % values.len()])
                        .collect(),
                );
            }
        }
        cases.push((0..1000).map(|k| (k as f64 * 0.37).sin() * 1e3).collect());
        for u in &cases {
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
            let e = SignedExtremes::of(u);
            let bits = |v: [f64; 4]| v.map(f64::to_bits);
            assert_eq!(
                bits([e.min_pos, e.max_pos, e.max_neg, e.min_neg]),
                bits([min_pos, max_pos, max_neg, min_neg]),
                "{u:?}"
            );
            assert_eq!(e.zero, zero, "{u:?}");
        }
    }

    // A staircase of levels −60, −56, −48, −33, 20, 40, 60: a deadzone with b_l = −48 (on a level, two
    // levels below it) and b_r = 25 (between levels) warns about b_l only; b_r keeps its standard
    // deviation.
    #[test]
    fn few_levels_counts_distinct_finite_values() {
        assert_eq!(
            few_levels(&[1.0, -1.0, 1.0, 1.0, -1.0], 3),
            Some(vec![-1.0, 1.0])
        );
        assert_eq!(
            few_levels(&[0.0, f64::NAN, 5.0, 0.0], 3),
            Some(vec![0.0, 5.0])
        );
        assert_eq!(few_levels(&[2.0, 2.0, 2.0], 3), Some(vec![2.0]));
        assert_eq!(few_levels(&[1.0, -1.0, 0.0, 1.0], 3), None);
        assert_eq!(
            few_levels(&[1.0, -1.0, 0.0, 1.0], 4),
            Some(vec![-1.0, 0.0, 1.0])
        );
        assert_eq!(few_levels(&[1.0, -1.0, 0.0, 2.0], 4), None);
        assert_eq!(few_levels(&[], 3), Some(vec![]));
        // A two-sided deadzone on a three-level input (−1, 0, 1): four parameters, three points.
        let err = DeadzoneBlock
            .start(&[1.0, -1.0, 0.0, 1.0, 0.0, -1.0], false, false, "three.csv")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            err.contains("three.csv") && err.contains("only 3 distinct levels (-1, 0, 1)"),
            "{err}"
        );
        // A deadzone start on a two-level input is refused, naming the record.
        let err = DeadzoneBlock
            .start(&[1.0, -1.0, -1.0, 1.0, 1.0, -1.0], false, false, "prbs.csv")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            err.contains("prbs.csv") && err.contains("only 2 distinct levels"),
            "{err}"
        );
    }

    // Inputs −0.4..0.4 inside a deadzone [−0.7, 0.8]: x = 0 for every sample, so the model cannot
    // respond; a deadzone [−0.3, 0.8] lets −0.4 through and is not flagged so.
    #[test]
    fn a_deadzone_holding_every_input_is_flagged() {
        let u = [-0.4, -0.1, 0.0, 0.2, 0.4];
        let swallowed = |b_l: f64| {
            let d = Deadzone {
                b_l,
                b_r: 0.8,
                m_l: 1.0,
                m_r: 1.0,
            };
            deadzone_warnings(&d, &u, (true, true), (true, true), (None, None))
                .0
                .iter()
                .any(|w| matches!(w, Warning::InputSwallowed { .. }))
        };
        assert!(swallowed(-0.7));
        assert!(!swallowed(-0.3));
    }

    #[test]
    fn a_breakpoint_on_an_input_level_is_flagged() {
        let d = data(vec![-60.0, -56.0, -48.0, -33.0, 20.0, 40.0, 60.0, -56.0]);
        let dz = Deadzone {
            b_l: -48.0,
            b_r: 25.0,
            m_l: 0.005,
            m_r: 0.005,
        };
        let (w, no_std) = deadzone_warnings(&dz, d.u(), (true, true), (true, true), (None, None));
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
        let (w, _) = deadzone_warnings(
            &near,
            d.u(),
            (true, true),
            (true, true),
            (Some(0.5), Some(0.1)),
        );
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
        let (w, _) = deadzone_warnings(
            &far,
            d.u(),
            (true, true),
            (true, true),
            (Some(0.3), Some(0.1)),
        );
        let text = w[0].to_string();
        assert!(
            text.contains("b_l = -47.780000 is 0.220 from the input level -48, less than its standard deviation 0.300"),
            "{text}"
        );
        let apart = Deadzone { b_l: -47.6, ..dz };
        let (w, no_std) = deadzone_warnings(
            &apart,
            d.u(),
            (true, true),
            (true, true),
            (Some(0.1), Some(0.1)),
        );
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
        let (w, no_std) = deadzone_warnings(&dz, d.u(), (true, true), (true, true), (None, None));
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
        // Far beyond the data with a deviation that spans every level (audit s13 L17: b_r = 3344.8
        // ± 46333 for commands −59..60 was "3403.818 from the input level −59 ... a kink"): not
        // bracketed, never a kink at the lowest level.
        let mut w = Vec::new();
        let mut no_std = Vec::new();
        check_breakpoint(
            ParamName::BR,
            3344.8,
            Some(46333.0),
            &[-59.0, -20.0, 0.0, 30.0, 60.0],
            &mut w,
            &mut no_std,
        );
        assert_eq!(no_std, vec![ParamName::BR]);
        assert!(
            matches!(w[..], [Warning::BreakpointNotBracketed { u_max, .. }] if u_max == 60.0),
            "{w:?}"
        );
        // Inside the data, a deviation that reaches several levels names the nearest one.
        let mut w = Vec::new();
        check_breakpoint(
            ParamName::BR,
            27.0,
            Some(100.0),
            &[-59.0, -20.0, 0.0, 30.0, 60.0],
            &mut w,
            &mut Vec::new(),
        );
        assert!(
            matches!(w[..], [Warning::BreakpointOnInputLevel { level, .. }] if level == 30.0),
            "{w:?}"
        );
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
        let (w, _) = deadzone_warnings(&dz, d.u(), (true, true), (true, true), (None, None));
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
        let (w, _) = deadzone_warnings(&dz, d.u(), (false, true), (false, true), (None, None));
        assert!(w.is_empty(), "{w:?}");
    }
}
