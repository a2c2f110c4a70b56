//! Batch least squares (the one QR solver of the crate), computed by
//! Householder QR of the augmented matrix [Φ D⁻¹ | y] without ever forming Q (never the normal
//! equations).
//!
//! For Φ (N × p) with column norms D = diag(‖Φ e_j‖) and y (N), the reflections H_p−1 ⋯ H_0 reduce
//! [Φ D⁻¹ | y] to
//!
//! ```text
//! ⎡ R  z ⎤   p rows
//! ⎣ 0  r ⎦   N − p rows
//! ```
//!
//! so that θ̂ = D⁻¹ R⁻¹ z, ‖y − Φθ̂‖² = ‖r‖² and (ΦᵀΦ)⁻¹ = D⁻¹ R⁻¹ R⁻ᵀ D⁻¹. The work is about
//! 4 N Σ_k (p − k) + 2 N p flops (≈ 0.25 Mflop for N = 2000, p = 7). The rows are folded into R
//! [`FOLD_ROWS`] at a time (row-block Householder QR, the kernel [`QrAccumulator`] uses for records too
//! long to hold), so that each block stays in the first-level cache while every reflection passes over
//! it, in contiguous column loops with several accumulators (vectorised, four columns per pass); one
//! allocation of N (p + 1) numbers per solve, and a [`LsWorkspace`] that keeps even that buffer between
//! solves (the key-term iteration solves one problem of the same size per iteration).

use nalgebra::{DMatrix, DVector};

use crate::SysidError;

/// Result of a least-squares solve of y ≈ Φ θ.
#[derive(Debug, Clone)]
pub struct LsSolution {
    /// θ̂, the minimiser of ‖y − Φθ‖².
    pub theta: DVector<f64>,
    /// (ΦᵀΦ)⁻¹, from the triangular factor (multiply by σ² for the covariance of θ̂).
    pub inv_gram: DMatrix<f64>,
    /// Residual sum of squares ‖y − Φθ̂‖².
    pub rss: f64,
}

/// σ̂² = RSS / (N − p), in the output's unit squared: the noise variance of `rows` regression rows
/// (or residuals) N left after `params` estimated parameters p. NaN when N ≤ p: with no residual
/// degrees of freedom the residuals are zero by construction and say nothing of the noise, so no
/// standard deviation follows from them ([`NO_RESIDUAL_DOF`] says why; audit s30 L-1: N = p = 2 printed
/// a1 = −2 ± 1.4e-15, rounding noise). The one place every estimator forms σ̂².
pub fn noise_variance(rss: f64, rows: usize, params: usize) -> f64 {
    if rows > params {
        rss / (rows - params) as f64
    } else {
        f64::NAN
    }
}

/// Why no standard deviation is given when [`noise_variance`] is NaN (N ≤ p).
pub const NO_RESIDUAL_DOF: &str = "no residual degrees of freedom (no more regression rows than \
     estimated parameters, N ≤ p): the residuals are zero by construction, so the noise variance \
     RSS/(N − p) and every standard deviation are undetermined; use a longer record (--rows) or lower \
     orders";

/// Relative size below which a diagonal entry of R (of the column-normalised Φ) counts as zero.
pub const RANK_TOLERANCE: f64 = 1e-10;

/// The default most memory the matrices of one estimation may take: 4 GiB (2³² bytes). A record at
/// the readers' limit (`sysid::data::MAX_SAMPLES` = 50 000 000 samples) drives N × p matrices of
/// several GB (a valid 3.9 MB compressed `.mat` drove 6.4 GB and aborted on the failed allocation;
/// audit s19 H-1), so the size is checked ([`MemoryNeed::check`]) before any of them is allocated;
/// with the record itself the peak then stays below the 6 GB limit the project measures its bounds
/// against. A machine with more memory raises it ([`MemoryBudget`], `--max-memory GIB`).
pub const MAX_ESTIMATION_BYTES: u64 = 1 << 32;

/// Numbers (f64) a run over a record holds per sample at its peak: a model's run holds the record,
/// its simulation, predictions, residuals and their copies (`validate` measured 4.38 GB for 40 M
/// samples, 13.7 per sample; audit s23 H-B1); a physics plant's run its states, the record's columns
/// and their CSV text (`simulate` measured about 92 bytes per sample; audit s36 H-1). The one record
/// budget of `validate`, `simulate`, `montecarlo` and Python's `simulate_plant`, checked against
/// [`MemoryBudget`] before the run.
pub const RECORD_NUMBERS_PER_SAMPLE: usize = 16;

/// The most memory the matrices of one estimation may take, in GiB (2³⁰ bytes): the command line's
/// `--max-memory GIB`, the Python package's `max_memory_gb`; [`MAX_ESTIMATION_BYTES`] (4 GiB) by
/// default. Made only by [`MemoryBudget::from_gib`], so it is always more than 0 bytes and at most
/// [`MemoryBudget::MAX_GIB`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MemoryBudget {
    /// The budget in GiB as given (shown as given in messages).
    gib: f64,
}

impl MemoryBudget {
    /// The largest budget accepted, 1024 GiB (1 TiB): more is a typing slip, not a machine's memory.
    pub const MAX_GIB: f64 = 1024.0;

    /// A budget of `gib` GiB (2³⁰ bytes each); refuses NaN, infinities, 0, negative numbers, less than
    /// one byte and more than [`MemoryBudget::MAX_GIB`].
    pub fn from_gib(gib: f64) -> Result<Self, SysidError> {
        if gib.is_finite() && gib > 0.0 && gib <= Self::MAX_GIB && gib * GIB >= 1.0 {
            Ok(MemoryBudget { gib })
        } else {
            Err(SysidError::setting(
                crate::Setting::MaxMemory,
                gib,
                &format!(
                    "a memory size in GiB (2^30 bytes), more than 0 and at most {}",
                    Self::MAX_GIB
                ),
            ))
        }
    }

    /// The budget in GiB.
    pub fn gib(self) -> f64 {
        self.gib
    }

    /// The budget in bytes (rounded down).
    pub fn bytes(self) -> u64 {
        (self.gib * GIB) as u64
    }
}

impl Default for MemoryBudget {
    /// [`MAX_ESTIMATION_BYTES`]: 4 GiB.
    fn default() -> Self {
        MemoryBudget {
            gib: MAX_ESTIMATION_BYTES as f64 / GIB,
        }
    }
}

impl std::fmt::Display for MemoryBudget {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.gib)
    }
}

impl std::str::FromStr for MemoryBudget {
    type Err = SysidError;
    /// A number of GiB (`8`, `0.5`), as `--max-memory` takes it.
    fn from_str(t: &str) -> Result<Self, SysidError> {
        let gib = t.trim().parse::<f64>().map_err(|_| {
            SysidError::setting(
                crate::Setting::MaxMemory,
                t,
                "a memory size in GiB (2^30 bytes), a number such as 8 or 0.5",
            )
        })?;
        Self::from_gib(gib)
    }
}

/// Bytes in a GiB.
const GIB: f64 = (1u64 << 30) as f64;

/// A memory size in GB (10⁹ bytes) as the refusals write it: one decimal from 0.1 GB, two significant
/// digits below (so that a small need under a small budget is not written 0.0 GB).
pub fn format_gb(bytes: u64) -> String {
    let gb = bytes as f64 / 1e9;
    if gb >= 0.1 || gb == 0.0 {
        format!("{gb:.1}")
    } else {
        let decimals = (1.0 - gb.log10().floor()).max(1.0) as usize;
        format!("{gb:.decimals$}")
    }
}

/// The bytes `per_row` numbers (f64) for each of `rows` regression rows take: the memory an estimation
/// of N = `rows` rows needs at its peak when it holds `per_row` numbers per row (for p parameters,
/// e.g. Φ and the QR's [Φ | y] are 2p + 1). Saturates instead of wrapping.
pub fn estimation_bytes(rows: usize, per_row: usize) -> u64 {
    (rows as u64)
        .saturating_mul(per_row as u64)
        .saturating_mul(std::mem::size_of::<f64>() as u64)
}

/// Runs over `samples` samples, `at_once` of them held together (one per worker thread), against
/// `budget`: `Ok(())` when their [`RECORD_NUMBERS_PER_SAMPLE`] numbers of 8 bytes per sample fit, else
/// `Err((bytes needed, the most samples per run that fit))`. The one arithmetic of the record budget
/// (`validate`, `simulate`, `montecarlo`, Python `simulate_plant`); the callers word the refusal.
pub fn record_budget(
    samples: usize,
    at_once: usize,
    budget: MemoryBudget,
) -> Result<(), (u64, u64)> {
    let at_once = at_once.max(1) as u64;
    let need = estimation_bytes(samples, RECORD_NUMBERS_PER_SAMPLE).saturating_mul(at_once);
    if need <= budget.bytes() {
        return Ok(());
    }
    let per_sample = estimation_bytes(1, RECORD_NUMBERS_PER_SAMPLE).saturating_mul(at_once);
    Err((need, budget.bytes() / per_sample))
}

/// The memory one estimation needs at its peak: `per_row` numbers (f64) for each of its `rows`
/// regression rows (N) of `p` parameters ([`estimation_bytes`]); `what` names the record (and the fits
/// held in memory together). Checked by [`MemoryNeed::check`] before anything is allocated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MemoryNeed {
    /// The record (and the fits held at once), as the refusal names it.
    pub what: String,
    /// N: regression rows.
    pub rows: usize,
    /// p: parameters (columns of Φ).
    pub p: usize,
    /// Numbers (f64) held per regression row at the peak.
    pub per_row: usize,
}

impl MemoryNeed {
    /// The bytes this estimation needs ([`estimation_bytes`]).
    pub fn bytes(&self) -> u64 {
        estimation_bytes(self.rows, self.per_row)
    }

    /// This need for `at_once` such estimations held in memory together (a search's structures
    /// fitted at once, one per worker thread): the numbers per row times `at_once`, and the count
    /// named in the refusal when it is more than one.
    pub fn at_once(mut self, at_once: usize) -> Self {
        if at_once > 1 {
            self.per_row = self.per_row.saturating_mul(at_once);
            self.what = format!("{} ({at_once} structures fitted at once)", self.what);
        }
        self
    }

    /// Refuses, before anything is allocated, this estimation when it needs more than `budget`; the
    /// message gives N, p, the memory needed and the way forward (a part of the record, a coarser
    /// sampling, lower orders, or a larger budget on a machine that has the memory).
    pub fn check(&self, budget: MemoryBudget) -> Result<(), SysidError> {
        let bytes = self.bytes();
        if bytes <= budget.bytes() {
            return Ok(());
        }
        // The most rows that fit the budget with these orders.
        let fit = budget.bytes() / (self.per_row.max(1) as u64 * std::mem::size_of::<f64>() as u64);
        Err(SysidError::Data(format!(
            "{}: {} regression rows of {} parameters need about {} GB for the estimation's \
             matrices (N × p numbers), more than its budget of {budget} GiB ({} GB, --max-memory); use at \
             most {fit} rows of the record (--rows A..B, or a slice of the arrays), a coarser \
             sampling (--resample TS, or decimate the record), or lower orders, or raise \
             --max-memory (max_memory_gb in Python) if this machine has the memory",
            self.what,
            self.rows,
            self.p,
            format_gb(bytes),
            format_gb(budget.bytes()),
        )))
    }
}

/// The error of a failed allocation of `numbers` f64 for `what` (a data problem: the record is too
/// large for the memory left).
fn out_of_memory(what: &str, numbers: usize) -> SysidError {
    SysidError::Data(format!(
        "not enough memory for {what}: {numbers} numbers ({:.1} GB) could not be allocated; use a part \
         of the record (--rows A..B, or a slice of the arrays), a coarser sampling (--resample TS) or \
         lower orders",
        estimation_bytes(numbers, 1) as f64 / 1e9
    ))
}

/// `len` zeros in a vector allocated fallibly: a failed allocation is an error naming `what`, not an
/// abort of the process.
pub fn try_zeros(len: usize, what: &str) -> Result<Vec<f64>, SysidError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| out_of_memory(what, len))?;
    v.resize(len, 0.0);
    Ok(v)
}

/// The `len` numbers of `values` in a vector allocated fallibly ([`try_zeros`]'s error when it cannot
/// be): the full-length copies of a record (its input over several records, a simulation's output)
/// are made with it, so that a record too large for the memory left is an error, not an abort
/// (audit s23 H-B1).
pub fn try_collect(
    values: impl IntoIterator<Item = f64>,
    len: usize,
    what: &str,
) -> Result<Vec<f64>, SysidError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len)
        .map_err(|_| out_of_memory(what, len))?;
    v.extend(values.into_iter().take(len));
    Ok(v)
}

/// A `rows` × `cols` matrix of zeros allocated fallibly ([`try_zeros`]): the N × p regression
/// matrices are built with it, so that a failed allocation is an error, not an abort.
pub fn try_matrix(rows: usize, cols: usize, what: &str) -> Result<DMatrix<f64>, SysidError> {
    let len = rows
        .checked_mul(cols)
        .ok_or_else(|| out_of_memory(what, usize::MAX))?;
    Ok(DMatrix::from_vec(rows, cols, try_zeros(len, what)?))
}

/// Reusable storage for [`LsWorkspace::solve`]: the augmented matrix, by columns.
#[derive(Debug, Clone, Default)]
pub struct LsWorkspace {
    a: Vec<f64>,
}

/// Largest buffer (in numbers) that [`solve`] keeps between calls on a thread: 512 Ki numbers = 4 MiB,
/// enough for 65 536 rows of 7 parameters; bigger problems allocate and free their own.
pub const KEPT_WORKSPACE: usize = 1 << 19;

thread_local! {
    static WORKSPACE: std::cell::RefCell<LsWorkspace> = std::cell::RefCell::new(LsWorkspace::new());
}

/// Solves min ‖y − Φθ‖ by Householder QR of the column-normalised [Φ | y], with a rank test on R. `names` label the columns in errors. Reuses a per-thread buffer
/// (up to [`KEPT_WORKSPACE`] numbers), so that repeated solves (the key-term iteration, Monte Carlo
/// runs) allocate no large block.
pub fn solve(
    phi: &DMatrix<f64>,
    y: &DVector<f64>,
    names: &[String],
) -> Result<LsSolution, SysidError> {
    WORKSPACE.with(|ws| match ws.try_borrow_mut() {
        Ok(mut ws) => {
            let result = ws.solve(phi, y, names);
            if ws.a.capacity() > KEPT_WORKSPACE {
                *ws = LsWorkspace::new();
            }
            result
        }
        // Re-entered on this thread (cannot happen today): use a fresh buffer.
        Err(_) => LsWorkspace::new().solve(phi, y, names),
    })
}

/// The rank test of [`solve`] alone, for a verdict on the data before any estimate: the same checks
/// in the same order (finite values, too few rows, a zero or overflowing column, then |R_kk| of the
/// column-normalised Φ against [`RANK_TOLERANCE`]) and the same diagonal of R to the bit, without
/// the target column (the reflections that would update it change nothing to the left of it) and
/// without the solution. The same verdict as `solve(phi, y, names)` for any finite y.
pub fn rank_test(phi: &DMatrix<f64>, names: &[String]) -> Result<(), SysidError> {
    WORKSPACE.with(|ws| match ws.try_borrow_mut() {
        Ok(mut ws) => {
            let result = ws.factor(phi, None, names, true).map(|_| ());
            if ws.a.capacity() > KEPT_WORKSPACE {
                *ws = LsWorkspace::new();
            }
            result
        }
        Err(_) => LsWorkspace::new()
            .factor(phi, None, names, true)
            .map(|_| ()),
    })
}

impl LsWorkspace {
    /// An empty workspace (it grows to N (p + 1) numbers on first use).
    pub fn new() -> Self {
        Self::default()
    }

    /// Solves min ‖y − Φθ‖, reusing this workspace's buffer. See [`solve`].
    pub fn solve(
        &mut self,
        phi: &DMatrix<f64>,
        y: &DVector<f64>,
        names: &[String],
    ) -> Result<LsSolution, SysidError> {
        self.triangularise(phi, y, names, true)?.solution()
    }

    /// The Householder triangularisation of [Φ D⁻¹ | y] (module docs): R, z = Qᵀy and ‖r‖², with the
    /// column scales D. With `rank_test` a (near-)zero pivot is refused as in [`solve`]; without it the
    /// caller regularises (a damped step, [`Triangular::damped_step`]).
    pub fn triangularise(
        &mut self,
        phi: &DMatrix<f64>,
        y: &DVector<f64>,
        names: &[String],
        rank_test: bool,
    ) -> Result<Triangular, SysidError> {
        let (r, scale, rss) = self.factor(phi, Some(y), names, rank_test)?;
        Ok(Triangular {
            r,
            scale,
            rss,
            p: phi.ncols(),
        })
    }

    /// [`LsWorkspace::triangularise`]'s factorisation: R and z by rows (p rows of p + 1), D and ‖r‖².
    /// Without `y` only R's columns are computed (z is left 0, ‖r‖² is 0): the reflections are grouped
    /// as with y, so R is the same to the bit.
    #[allow(clippy::type_complexity)]
    fn factor(
        &mut self,
        phi: &DMatrix<f64>,
        y: Option<&DVector<f64>>,
        names: &[String],
        rank_test: bool,
    ) -> Result<(Vec<f64>, Vec<f64>, f64), SysidError> {
        let (n, p) = phi.shape();
        if let Some(y) = y.filter(|y| y.len() != n) {
            return Err(SysidError::Data(format!(
                "{n} regression rows but {} targets",
                y.len()
            )));
        }
        check_problem(
            n,
            p,
            all_finite(phi.as_slice()) && y.is_none_or(|y| all_finite(y.as_slice())),
        )?;
        let name = |j: usize| column_name(names, j);
        // Augmented matrix [Φ D⁻¹ | y], by columns; column scaling makes the rank test independent of
        // units (counts vs mm vs 0/1 switches).
        let cols = p + 1;
        self.a.clear();
        let len = n.saturating_mul(cols);
        self.a
            .try_reserve_exact(len)
            .map_err(|_| out_of_memory("the least-squares factorisation", len))?;
        let mut scale = vec![0.0; p];
        for (j, scale_j) in scale.iter_mut().enumerate() {
            let src = phi.column(j);
            let src = src.as_slice();
            let norm = scaled_norm(src);
            // Without the rank test (a damped step) a column that is zero over the record (a
            // parameter the current iterate does not excite, e.g. a breakpoint beyond every command)
            // takes the scale 1, as MINPACK's `lmder` does: its step is then 0, the others are found.
            let norm = if !rank_test && norm == 0.0 { 1.0 } else { norm };
            check_norm(norm, || name(j))?;
            *scale_j = norm;
            let inv = 1.0 / norm;
            self.a.extend(src.iter().map(|s| s * inv));
        }
        // The columns present: y's too, or only Φ's.
        let live = match y {
            Some(y) => {
                self.a.extend_from_slice(y.as_slice());
                cols
            }
            None => p,
        };
        // R of [Φ D⁻¹ | y] (cols × cols, by rows), folded in [`FOLD_ROWS`] rows at a time: each block
        // stays in the first-level cache while every reflection passes over it (the reflections of the
        // whole columns passed over the N·(p + 1) numbers once per pair of columns).
        let mut rr = vec![0.0; cols * cols];
        for start in (0..n).step_by(FOLD_ROWS) {
            let m = FOLD_ROWS.min(n - start);
            fold_rows(&mut rr, &mut self.a[start..], n, m, cols, live);
        }
        for k in 0..p {
            // |R_kk| = ‖column k after the reflections of the columns before it‖; the rank test of
            // ls::solve.
            if rank_test && rr[k * cols + k].abs() < RANK_TOLERANCE {
                // A column carried by one value (an outlier such as 1e308 among values of 10) looks
                // dependent once scaled: say so rather than blame the input's excitation.
                if let Some(e) = (0..p).find_map(|j| one_value_column(phi, j, &name)) {
                    return Err(e);
                }
                return Err(dependent(&name(k)));
            }
        }
        // ‖r‖²: what is left of the transformed y below row p.
        let rss = rr[p * cols + p] * rr[p * cols + p];
        rr.truncate(p * cols);
        Ok((rr, scale, rss))
    }
}

/// The triangular factor of a scaled least-squares problem (see [`LsWorkspace::triangularise`]):
/// [Φ D⁻¹ | y] = Q [R z; 0 r].
#[derive(Debug, Clone)]
pub struct Triangular {
    /// R and z by rows: `r[k * (p + 1) + c]`, column p holding z.
    r: Vec<f64>,
    /// D: the column norms of Φ.
    scale: Vec<f64>,
    /// ‖r‖²: the residual sum of squares of the least-squares solution.
    rss: f64,
    p: usize,
}

impl Triangular {
    /// The column norms D of Φ.
    pub fn scale(&self) -> &[f64] {
        &self.scale
    }

    /// ‖y − Φ θ̂‖²: the residual sum of squares of the undamped least-squares solution (for a
    /// Levenberg–Marquardt search, ‖y‖² minus it is the reduction its Gauss–Newton step predicts).
    pub fn rss(&self) -> f64 {
        self.rss
    }

    /// The damped step δ minimising ‖y − Φ δ‖² + λ ‖D δ‖² (Levenberg–Marquardt with Marquardt's
    /// scaling): in the scaled variables w = D δ it is min ‖z − R w‖² + λ ‖w‖², solved by a Householder
    /// QR of the small stacked matrix [R; √λ I] (2p × p). Fails when that system is singular (λ = 0 on a
    /// rank-deficient Φ) or the result is not finite.
    pub fn damped_step(&self, lambda: f64) -> Result<DVector<f64>, SysidError> {
        let p = self.p;
        let cols = p + 1;
        let mut a = DMatrix::<f64>::zeros(2 * p, p);
        let mut b = DVector::<f64>::zeros(2 * p);
        for k in 0..p {
            for c in k..p {
                a[(k, c)] = self.r[k * cols + c];
            }
            b[k] = self.r[k * cols + p];
            a[(p + k, k)] = lambda.max(0.0).sqrt();
        }
        let qr = a.qr();
        let qtb = qr.q().transpose() * b;
        let w = qr.r().solve_upper_triangular(&qtb).ok_or_else(|| {
            SysidError::Numerical("the damped least-squares step is singular".into())
        })?;
        let delta = DVector::from_iterator(p, w.iter().zip(&self.scale).map(|(wi, si)| wi / si));
        if delta.iter().any(|v| !v.is_finite()) {
            return Err(SysidError::Numerical(
                "the damped least-squares step is not finite".into(),
            ));
        }
        Ok(delta)
    }

    /// The reduction of ‖y − Φ δ‖² that the linear model predicts for the step `delta`:
    /// ‖y‖² − ‖y − Φ δ‖² = ‖z‖² − ‖z − R D δ‖² (the rows below R are untouched by δ). A
    /// Levenberg–Marquardt search compares it with the actual reduction of its loss.
    pub fn predicted_reduction(&self, delta: &[f64]) -> f64 {
        let (p, cols) = (self.p, self.p + 1);
        let w: Vec<f64> = delta.iter().zip(&self.scale).map(|(d, s)| d * s).collect();
        let (mut zz, mut left) = (0.0, 0.0);
        for k in 0..p {
            let z = self.r[k * cols + p];
            let rw: f64 = (k..p).map(|c| self.r[k * cols + c] * w[c]).sum();
            zz += z * z;
            left += (z - rw) * (z - rw);
        }
        zz - left
    }

    /// The least-squares solution θ̂, (ΦᵀΦ)⁻¹ and the RSS.
    pub fn solution(&self) -> Result<LsSolution, SysidError> {
        let (p, cols, r, scale, rss) = (self.p, self.p + 1, &self.r, &self.scale, self.rss);
        // θ̂ = D⁻¹ R⁻¹ z by back substitution.
        let mut z = vec![0.0; p];
        for k in (0..p).rev() {
            let mut s = r[k * cols + p];
            for c in k + 1..p {
                s -= r[k * cols + c] * z[c];
            }
            z[k] = s / r[k * cols + k];
        }
        let theta = DVector::from_iterator(p, z.iter().zip(scale).map(|(zi, si)| zi / si));
        // R⁻¹ (upper triangular) by columns, then (ΦᵀΦ)⁻¹ = D⁻¹ R⁻¹ R⁻ᵀ D⁻¹.
        let mut rinv = DMatrix::<f64>::zeros(p, p);
        for j in 0..p {
            rinv[(j, j)] = 1.0 / r[j * cols + j];
            for i in (0..j).rev() {
                let mut s = 0.0;
                for m in i + 1..=j {
                    s += r[i * cols + m] * rinv[(m, j)];
                }
                rinv[(i, j)] = -s / r[i * cols + i];
            }
        }
        let mut inv_gram = DMatrix::<f64>::zeros(p, p);
        for i in 0..p {
            for j in i..p {
                let mut s = 0.0;
                for m in j..p {
                    s += rinv[(i, m)] * rinv[(j, m)];
                }
                let v = s / (scale[i] * scale[j]);
                inv_gram[(i, j)] = v;
                inv_gram[(j, i)] = v;
            }
        }
        if !rss.is_finite() || theta.iter().any(|v| !v.is_finite()) {
            return Err(SysidError::Numerical(
                "least squares produced a non-finite estimate".into(),
            ));
        }
        Ok(LsSolution {
            theta,
            inv_gram,
            rss,
        })
    }
}

/// Rows of [φ y] collected before they are folded into R ([`QrAccumulator`]).
pub const FOLD_ROWS: usize = 256;

/// The least-squares problem min ‖y − Φθ‖ accumulated row by row in O(p²) memory, for records too long
/// to hold (`identify --stream`): the (p + 1) × (p + 1) triangular factor R of [Φ | y] is updated with
/// each block of [`FOLD_ROWS`] rows by Householder reflections of the stacked matrix [R; block]
/// (row-block QR, the building step of TSQR; Golub & Van Loan, *Matrix Computations*, 4th ed., §5.2 and
/// §6.5.3). The normal equations are never formed.
///
/// [Φ | y] = Q [R; 0] has the same triangular factor whatever order the rows arrive in, so at the end
/// the column norms ‖Φ e_j‖ are the norms of R's columns, and R D⁻¹ is the factor of the column-scaled
/// [Φ D⁻¹ | y] that [`LsWorkspace::triangularise`] computes: the same [`Triangular`], the same rank test,
/// the same θ̂, (ΦᵀΦ)⁻¹ and RSS up to rounding. Each column is pre-scaled by a power of two chosen from
/// the first block (exact in floating point), so that magnitudes such as 1e160 neither overflow nor
/// underflow in the reflections.
#[derive(Debug, Clone)]
pub struct QrAccumulator {
    /// p + 1: the regressors and the target.
    cols: usize,
    /// R by rows, `r[i * cols + j]`, upper triangular (of the pre-scaled columns).
    r: Vec<f64>,
    /// The rows not yet folded, by columns: `block[j * FOLD_ROWS + i]`.
    block: Vec<f64>,
    filled: usize,
    rows: usize,
    /// The power of two each column is multiplied by (set by the first fold).
    pre: Option<Vec<f64>>,
    finite: bool,
}

impl QrAccumulator {
    /// An empty problem with `p` regressors.
    pub fn new(p: usize) -> Self {
        let cols = p + 1;
        QrAccumulator {
            cols,
            r: vec![0.0; cols * cols],
            block: vec![0.0; cols * FOLD_ROWS],
            filled: 0,
            rows: 0,
            pre: None,
            finite: true,
        }
    }

    /// Number of rows added.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Adds the row φᵀ θ ≈ y (`phi` has p entries).
    #[inline]
    pub fn push(&mut self, phi: &[f64], y: f64) {
        let i = self.filled;
        for (j, v) in phi.iter().take(self.cols - 1).enumerate() {
            self.block[j * FOLD_ROWS + i] = *v;
        }
        self.block[(self.cols - 1) * FOLD_ROWS + i] = y;
        self.filled += 1;
        self.rows += 1;
        if self.filled == FOLD_ROWS {
            self.fold();
        }
    }

    /// Folds the collected rows into R: for each column k, the reflection that maps (R_kk, block(:, k))
    /// to (±σ, 0) is applied to the columns on its right.
    fn fold(&mut self) {
        let (m, cols) = (self.filled, self.cols);
        if m == 0 {
            return;
        }
        let block = &mut self.block;
        if block
            .chunks(FOLD_ROWS)
            .any(|c| c[..m].iter().any(|v| !v.is_finite()))
        {
            self.finite = false;
        }
        let pre = self.pre.get_or_insert_with(|| {
            block
                .chunks(FOLD_ROWS)
                .map(|c| {
                    let peak = c[..m].iter().fold(0.0f64, |a, v| a.max(v.abs()));
                    if peak > 0.0 && peak.is_finite() {
                        // 2^−e with 2^e the power of two nearest above the peak: exact scaling.
                        let e = peak.log2().ceil() as i32;
                        2f64.powi(-e.clamp(-1000, 1000))
                    } else {
                        1.0
                    }
                })
                .collect()
        });
        for (j, s) in pre.iter().enumerate() {
            if *s != 1.0 {
                block[j * FOLD_ROWS..j * FOLD_ROWS + m]
                    .iter_mut()
                    .for_each(|v| *v *= s);
            }
        }
        fold_rows(&mut self.r, block, FOLD_ROWS, m, cols, cols);
        self.filled = 0;
    }

    /// The triangular factor of the column-scaled problem, as [`LsWorkspace::triangularise`] gives it
    /// for the same rows held in memory (same checks and messages; `names` label the columns).
    pub fn triangular(
        mut self,
        names: &[String],
        rank_test: bool,
    ) -> Result<Triangular, SysidError> {
        self.fold();
        let (cols, p, n) = (self.cols, self.cols - 1, self.rows);
        check_problem(n, p, self.finite && self.r.iter().all(|v| v.is_finite()))?;
        let name = |j: usize| column_name(names, j);
        let pre = self.pre.unwrap_or_else(|| vec![1.0; cols]);
        let r = &self.r;
        let mut out = vec![0.0; p * cols];
        let mut scale = vec![0.0; p];
        let mut column = Vec::with_capacity(cols);
        for j in 0..p {
            column.clear();
            column.extend((0..=j).map(|i| r[i * cols + j]));
            let norm = scaled_norm(&column);
            scale[j] = norm / pre[j];
            check_norm(scale[j], || name(j))?;
            for i in 0..=j {
                out[i * cols + j] = r[i * cols + j] / norm;
            }
        }
        for k in 0..p {
            if rank_test && out[k * cols + k].abs() < RANK_TOLERANCE {
                return Err(dependent(&name(k)));
            }
            out[k * cols + p] = r[k * cols + p] / pre[p];
        }
        let tail = r[p * cols + p] / pre[p];
        Ok(Triangular {
            r: out,
            scale,
            rss: tail * tail,
            p,
        })
    }

    /// θ̂, (ΦᵀΦ)⁻¹ and the RSS (as [`solve`] on the same rows).
    pub fn solve(self, names: &[String]) -> Result<LsSolution, SysidError> {
        self.triangular(names, true)?.solution()
    }
}

/// Folds `m` rows into the upper-triangular `r` (cols × cols, by rows): the rows are column j of
/// `block` at `block[j * ld..j * ld + m]`, and are overwritten. For each column k, the Householder
/// reflection that maps (R_kk, rows(:, k)) to (±σ, 0) is applied to the columns on its right, so that
/// [R; rows] = Q [R'; 0] (row-block QR, the building step of TSQR; Golub & Van Loan, *Matrix
/// Computations*, 4th ed., §5.2). A column with nothing below the diagonal is left as it is (H = I).
///
/// Only the first `live` columns are present (and computed): the columns on the right are grouped by
/// four as for all `cols`, so each live column gets the same operations as with them.
fn fold_rows(r: &mut [f64], block: &mut [f64], ld: usize, m: usize, cols: usize, live: usize) {
    for k in 0..live {
        let (left, right) = block.split_at_mut(((k + 1) * ld).min(block.len()));
        let a = &left[k * ld..k * ld + m];
        let aa = dot(a, a);
        if aa == 0.0 {
            continue; // nothing below the diagonal to annihilate
        }
        let rkk = r[k * cols + k];
        let sigma = (rkk * rkk + aa).sqrt();
        let alpha = if rkk > 0.0 { -sigma } else { sigma };
        // v = (R_kk − α, a); H = I − β v vᵀ with vᵀv = 2σ(σ + |R_kk|).
        let v0 = rkk - alpha;
        let beta = 1.0 / (sigma * (sigma + rkk.abs()));
        // The columns on the right four at a time (one pass over the rows for four dot products,
        // one for four updates), then one by one.
        let mut rest = right;
        let mut c = k + 1;
        while c < live {
            if cols - c >= 4 && live - c >= 4 {
                let (c0, t) = rest.split_at_mut(ld);
                let (c1, t) = t.split_at_mut(ld);
                let (c2, t) = t.split_at_mut(ld);
                let (c3, t) = t.split_at_mut(ld.min(t.len()));
                let mut four = [&mut c0[..m], &mut c1[..m], &mut c2[..m], &mut c3[..m]];
                let d = dot4(a, &four);
                let mut w = [0.0; 4];
                for q in 0..4 {
                    w[q] = beta * (v0 * r[k * cols + c + q] + d[q]);
                    r[k * cols + c + q] -= w[q] * v0;
                }
                axpy4(&w, a, &mut four);
                rest = t;
                c += 4;
            } else if cols - c >= 4 {
                // A group of four whose last columns are absent: the live ones as in the group.
                let rk = &mut r[k * cols + c..];
                rest = match live - c {
                    1 => reflect_columns::<1>(a, rest, ld, m, rk, beta, v0),
                    2 => reflect_columns::<2>(a, rest, ld, m, rk, beta, v0),
                    _ => reflect_columns::<3>(a, rest, ld, m, rk, beta, v0),
                };
                c += 4;
            } else {
                let (col, t) = rest.split_at_mut(ld.min(rest.len()));
                let col = &mut col[..m];
                let w = beta * (v0 * r[k * cols + c] + dot(a, col));
                r[k * cols + c] -= w * v0;
                axpy(-w, a, col);
                rest = t;
                c += 1;
            }
        }
        r[k * cols + k] = alpha;
    }
}

/// Applies the reflection (v0, `a`), β to the N = 1..3 columns at the start of `rest` (each `ld`
/// long, rows `..m` used) whose entries of R's row are `rk[..N]`, each column with the operations
/// [`dot4`] and [`axpy4`] give a column of a group of four ([`dot_columns`], [`axpy_columns`]).
/// Returns what follows those columns.
#[inline]
fn reflect_columns<'a, const N: usize>(
    a: &[f64],
    rest: &'a mut [f64],
    ld: usize,
    m: usize,
    rk: &mut [f64],
    beta: f64,
    v0: f64,
) -> &'a mut [f64] {
    let mut tail = rest;
    let mut group: [&mut [f64]; N] = std::array::from_fn(|_| {
        let t = std::mem::take(&mut tail);
        let (col, after) = t.split_at_mut(ld.min(t.len()));
        tail = after;
        &mut col[..m]
    });
    let d = dot_columns(a, &group);
    let mut w = [0.0; N];
    for q in 0..N {
        w[q] = beta * (v0 * rk[q] + d[q]);
        rk[q] -= w[q] * v0;
    }
    axpy_columns(&w, a, &mut group);
    tail
}

/// The checks before a solve: at least as many rows `n` as parameters `p`, every value finite.
fn check_problem(n: usize, p: usize, finite: bool) -> Result<(), SysidError> {
    if n < p {
        return Err(SysidError::Data(format!(
            "{n} regression rows for {p} parameters: too few samples for these orders"
        )));
    }
    if !finite {
        return Err(SysidError::Numerical(
            "non-finite value in the regression data".into(),
        ));
    }
    Ok(())
}

/// The name of column `j` for messages.
fn column_name(names: &[String], j: usize) -> String {
    names
        .get(j)
        .cloned()
        .unwrap_or_else(|| format!("column {}", j + 1))
}

/// A column norm must be positive (the input excites the regressor) and finite. An output lag's
/// regressor (`a1`, `a2`, … = −y(k − i)) is zero only where y is: then the output is 0 on every row
/// used (a dead sensor, the wrong column), not an input that fails to excite (audit s37 L-6).
fn check_norm(norm: f64, name: impl Fn() -> String) -> Result<(), SysidError> {
    if norm == 0.0 {
        let name = name();
        let output_lag = name
            .strip_prefix('a')
            .is_some_and(|i| !i.is_empty() && i.bytes().all(|b| b.is_ascii_digit()));
        let why = if output_lag {
            "the output y is 0 at every sample it uses (a dead sensor, or the wrong --y-col?), so \
             nothing determines it"
        } else {
            "the input does not excite it (not persistently exciting)"
        };
        return Err(SysidError::Data(format!(
            "regressor {name} is zero over the whole record: {why}"
        )));
    }
    if !norm.is_finite() {
        return Err(SysidError::Numerical(format!(
            "regressor {} overflows (too large values)",
            name()
        )));
    }
    Ok(())
}

/// Column `j` of Φ when one value carries it: every other value is below [`RANK_TOLERANCE`] times the
/// largest (nonzero), so that after scaling the column is a single spike and the fit cannot use the
/// rest of the record. Names the regression row (0-based) and the value.
fn one_value_column(
    phi: &DMatrix<f64>,
    j: usize,
    name: &impl Fn(usize) -> String,
) -> Option<SysidError> {
    let col = phi.column(j);
    let (row, big, rest) = largest_and_rest(col.iter().copied());
    (rest > 0.0 && rest < RANK_TOLERANCE * big).then(|| {
        SysidError::Numerical(format!(
            "regressor {} is carried by one value, {:e} in regression row {row} of {}, while every other \
             value is at most {rest:e}: an outlier or a unit error in the data (remove or rescale it); \
             the rest of the record cannot determine the parameters",
            name(j),
            col[row],
            col.len()
        ))
    })
}

/// The row of the largest |value|, that magnitude, and the largest |value| of every other row (0 for
/// fewer than two values): the one measure of "a value carried alone" of least squares' regressor check
/// ([`one_value_column`]), in one pass ([`Largest`], which the readers' outlier note keeps).
pub(crate) fn largest_and_rest(values: impl Iterator<Item = f64>) -> (usize, f64, f64) {
    let mut l = Largest::default();
    for (i, v) in values.enumerate() {
        l.push(i, v);
    }
    (l.at, l.big, l.rest)
}

/// The largest |value| of a sequence seen one value at a time, the value itself and its place `at`
/// (a row, or the streamed reader's byte offset), and the largest |value| of every other place: what
/// [`largest_and_rest`] folds, kept by a reader that never holds the column (the streamed CSV reader's
/// outlier note). The first of equal largest values is kept, the others count in `rest`; a NaN is not
/// counted.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Largest<P> {
    /// Where the largest |value| is.
    pub at: P,
    /// The value there (signed).
    pub value: f64,
    /// Its magnitude.
    pub big: f64,
    /// The largest magnitude of every other place (0 when none).
    pub rest: f64,
    /// How many values were seen.
    pub count: usize,
}

impl<P: Copy> Largest<P> {
    /// One more value `v` at place `at`.
    pub fn push(&mut self, at: P, v: f64) {
        let a = v.abs();
        if a > self.big {
            self.rest = self.big;
            self.big = a;
            self.value = v;
            self.at = at;
        } else {
            self.rest = self.rest.max(a);
        }
        self.count += 1;
    }
}

fn dependent(name: &str) -> SysidError {
    SysidError::Data(format!(
        "the regressors are linearly dependent (at {name}): the input is not persistently exciting for \
         this model structure (constant input, too few distinct levels, or orders too high), or the \
         output never moves (every command inside the deadzone, for example)"
    ))
}

/// xᵀy over the common length, with eight independent accumulators (vectorised into four chains of
/// two-lane additions, enough to keep the adders busy; the order of summation differs from a plain
/// loop only by rounding).
#[inline]
pub fn dot(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    let (x, y) = (&x[..n], &y[..n]);
    let mut acc = [0.0; 8];
    let mut xc = x.chunks_exact(8);
    let mut yc = y.chunks_exact(8);
    for (a, b) in (&mut xc).zip(&mut yc) {
        for i in 0..8 {
            acc[i] += a[i] * b[i];
        }
    }
    let mut s = ((acc[0] + acc[1]) + (acc[2] + acc[3])) + ((acc[4] + acc[5]) + (acc[6] + acc[7]));
    for (a, b) in xc.remainder().iter().zip(yc.remainder()) {
        s += a * b;
    }
    s
}

/// xᵀc_q for four columns c_q of x's length, in one pass over x (two accumulators per column).
#[inline]
fn dot4(x: &[f64], c: &[&mut [f64]; 4]) -> [f64; 4] {
    let n = x.len();
    let (c0, c1, c2, c3) = (&c[0][..n], &c[1][..n], &c[2][..n], &c[3][..n]);
    let mut acc = [[0.0; 2]; 4];
    let pairs = n / 2;
    for i in 0..pairs {
        for l in 0..2 {
            let (k, xv) = (2 * i + l, x[2 * i + l]);
            acc[0][l] += xv * c0[k];
            acc[1][l] += xv * c1[k];
            acc[2][l] += xv * c2[k];
            acc[3][l] += xv * c3[k];
        }
    }
    let mut out = [0.0; 4];
    for q in 0..4 {
        out[q] = acc[q][0] + acc[q][1];
    }
    if n % 2 == 1 {
        let xv = x[n - 1];
        out[0] += xv * c0[n - 1];
        out[1] += xv * c1[n - 1];
        out[2] += xv * c2[n - 1];
        out[3] += xv * c3[n - 1];
    }
    out
}

/// c_q ← c_q − w_q x for four columns, in one pass over x.
#[inline]
fn axpy4(w: &[f64; 4], x: &[f64], c: &mut [&mut [f64]; 4]) {
    let n = x.len();
    let [c0, c1, c2, c3] = c;
    let (c0, c1, c2, c3) = (&mut c0[..n], &mut c1[..n], &mut c2[..n], &mut c3[..n]);
    for (i, xv) in x.iter().enumerate() {
        c0[i] -= w[0] * xv;
        c1[i] -= w[1] * xv;
        c2[i] -= w[2] * xv;
        c3[i] -= w[3] * xv;
    }
}

/// [`dot4`] for N columns: each column's sums are [`dot4`]'s for it.
#[inline]
fn dot_columns<const N: usize>(x: &[f64], c: &[&mut [f64]; N]) -> [f64; N] {
    let n = x.len();
    let c: [&[f64]; N] = std::array::from_fn(|q| &c[q][..n]);
    let mut acc = [[0.0; 2]; N];
    let pairs = n / 2;
    for i in 0..pairs {
        for l in 0..2 {
            let (k, xv) = (2 * i + l, x[2 * i + l]);
            for q in 0..N {
                acc[q][l] += xv * c[q][k];
            }
        }
    }
    let mut out = [0.0; N];
    for q in 0..N {
        out[q] = acc[q][0] + acc[q][1];
    }
    if n % 2 == 1 {
        let xv = x[n - 1];
        for q in 0..N {
            out[q] += xv * c[q][n - 1];
        }
    }
    out
}

/// [`axpy4`] for N columns.
#[inline]
fn axpy_columns<const N: usize>(w: &[f64; N], x: &[f64], c: &mut [&mut [f64]; N]) {
    for (i, xv) in x.iter().enumerate() {
        for q in 0..N {
            c[q][i] -= w[q] * xv;
        }
    }
}

/// y ← y + a x.
#[inline]
fn axpy(a: f64, x: &[f64], y: &mut [f64]) {
    for (yi, xi) in y.iter_mut().zip(x) {
        *yi += a * xi;
    }
}

/// True when every entry of `x` is finite: Σ 0·x_i is ±0 for finite entries and NaN as soon as one is
/// infinite or NaN (four independent sums, vectorisable; this check runs over the whole Φ of every
/// solve).
pub(crate) fn all_finite(x: &[f64]) -> bool {
    let mut acc = [0.0f64; 4];
    let mut chunks = x.chunks_exact(4);
    for c in &mut chunks {
        for i in 0..4 {
            acc[i] += c[i] * 0.0;
        }
    }
    let tail = chunks.remainder().iter().fold(0.0, |a, v| a + v * 0.0);
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail == 0.0
}

/// Σ x_i² with four independent accumulators (vectorisable).
fn sum_of_squares(x: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let mut chunks = x.chunks_exact(4);
    for c in &mut chunks {
        for i in 0..4 {
            acc[i] += c[i] * c[i];
        }
    }
    let tail = chunks.remainder().iter().fold(0.0, |a, v| a + v * v);
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// Below this sum of squares some squares may have lost digits to underflow (entries under ~1e−154);
/// above it they are negligible against the sum.
const PLAIN_NORM_MIN: f64 = 1e-250;
/// Above this sum of squares (or when it overflows) the norm is computed with scaling.
const PLAIN_NORM_MAX: f64 = 1e250;

/// ‖x‖₂, so that columns of 1e160 or 1e-200 neither overflow nor underflow (the plain sum of squares
/// would give inf or 0 and a false rank verdict): √(Σ x_i²) when that sum lies safely inside the range
/// of f64 (one vectorised pass, the usual case), else m·‖x/m‖₂ with m = max |x_i|. The two agree to
/// rounding.
pub(crate) fn scaled_norm(x: &[f64]) -> f64 {
    let plain = sum_of_squares(x);
    if (PLAIN_NORM_MIN..=PLAIN_NORM_MAX).contains(&plain) {
        return plain.sqrt();
    }
    let m = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if m == 0.0 || !m.is_finite() {
        return m;
    }
    let inv = 1.0 / m;
    m * x.iter().map(|v| (v * inv) * (v * inv)).sum::<f64>().sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    // σ̂² = RSS/(N − p): 6/(5 − 2) = 2; with N = p (0/0) or N < p there is no residual left to say it.
    #[test]
    fn noise_variance_divides_by_the_residual_degrees_of_freedom_and_has_none_at_n_equal_p() {
        assert_eq!(noise_variance(6.0, 5, 2), 2.0);
        assert!(noise_variance(0.0, 2, 2).is_nan());
        assert!(noise_variance(1.0, 1, 3).is_nan());
    }

    // --max-memory GIB: a size in GiB (2³⁰ bytes), more than 0 and at most 1 TiB; 4 GiB by default.
    #[test]
    fn a_memory_budget_is_a_positive_size_in_gib_up_to_a_tebibyte() {
        assert_eq!(MemoryBudget::default().bytes(), 4 * 1024 * 1024 * 1024);
        assert_eq!(
            MemoryBudget::from_gib(0.5).unwrap().bytes(),
            512 * 1024 * 1024
        );
        assert_eq!("1024".parse::<MemoryBudget>().unwrap().bytes(), 1u64 << 40);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 1024.5, 1e-12] {
            let e = MemoryBudget::from_gib(bad).unwrap_err().to_string();
            assert!(e.contains("GiB"), "{bad}: {e}");
        }
        for bad in ["", "8GB", "lots", "nan", "-2"] {
            assert!(bad.parse::<MemoryBudget>().is_err(), "{bad}");
        }
    }

    // A need is refused exactly when its bytes (rows × numbers per row × 8) exceed the budget, and
    // the rows it offers are the most that fit: 1000 rows × 12 numbers × 8 bytes = 96 000 bytes.
    #[test]
    fn a_need_over_its_budget_is_refused_with_the_rows_that_fit() {
        let need = MemoryNeed {
            what: "r".into(),
            rows: 1000,
            p: 4,
            per_row: 12,
        };
        let exact = MemoryBudget::from_gib(96_000.0 / (1u64 << 30) as f64).unwrap();
        assert!(need.check(exact).is_ok());
        let under = MemoryBudget::from_gib(95_999.0 / (1u64 << 30) as f64).unwrap();
        let e = need.check(under).unwrap_err().to_string();
        // 95 999 bytes / 96 bytes per row = 999 rows; 9.6e-5 GB.
        assert!(e.contains("at most 999 rows"), "{e}");
        assert!(e.contains("about 0.000096 GB"), "{e}");
        assert!(e.contains("raise --max-memory"), "{e}");
    }

    #[test]
    fn sizes_in_gb_keep_two_significant_digits_below_a_tenth() {
        assert_eq!(format_gb(5_700_000_000), "5.7");
        assert_eq!(format_gb(100_000_000), "0.1");
        assert_eq!(format_gb(48_000_000), "0.048");
        assert_eq!(format_gb(960_000), "0.00096");
    }

    /// Independent reference: nalgebra's QR, without column scaling or rank test.
    fn nalgebra_qr(phi: &DMatrix<f64>, y: &DVector<f64>) -> LsSolution {
        let qr = phi.clone().qr();
        let r = qr.r();
        let qty = qr.q().transpose() * y;
        let theta = r.solve_upper_triangular(&qty).unwrap();
        let r_inv = r.clone().try_inverse().unwrap();
        let inv_gram = &r_inv * r_inv.transpose();
        let rss = (y - phi * &theta).norm_squared();
        LsSolution {
            theta,
            inv_gram,
            rss,
        }
    }

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / a.abs().max(b.abs()).max(1e-300)
    }

    // Line through (0,1), (1,3), (2,5): y = 1 + 2t exactly, so θ = [1, 2] and RSS = 0.
    #[test]
    fn fits_a_line_through_three_collinear_points() {
        let phi = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 1.0, 1.0, 1.0, 2.0]);
        let y = DVector::from_vec(vec![1.0, 3.0, 5.0]);
        let s = solve(&phi, &y, &[]).unwrap();
        assert!((s.theta[0] - 1.0).abs() < 1e-12 && (s.theta[1] - 2.0).abs() < 1e-12);
        assert!(s.rss < 1e-24);
    }

    // Fitting y = c to (1, 2, 6): c = mean = 3, RSS = 4 + 1 + 9 = 14, (ΦᵀΦ)⁻¹ = 1/3.
    #[test]
    fn constant_regressor_gives_the_mean_and_its_variance_factor() {
        let phi = DMatrix::from_element(3, 1, 1.0);
        let y = DVector::from_vec(vec![1.0, 2.0, 6.0]);
        let s = solve(&phi, &y, &[]).unwrap();
        assert!((s.theta[0] - 3.0).abs() < 1e-12);
        assert!((s.rss - 14.0).abs() < 1e-12);
        assert!((s.inv_gram[(0, 0)] - 1.0 / 3.0).abs() < 1e-12);
    }

    // Line fit to t = 0, 1, 2, 3 with y = (0, 1, 1, 3), by hand: ΦᵀΦ = [[4, 6], [6, 14]], det 20,
    // (ΦᵀΦ)⁻¹ = [[0.7, −0.3], [−0.3, 0.2]], Φᵀy = (5, 12), θ = (−0.1, 0.9), residuals (0.1, 0.2, −0.7, 0.4),
    // RSS = 0.7.
    #[test]
    fn line_fit_matches_the_hand_computed_normal_equations() {
        let phi = DMatrix::from_row_slice(4, 2, &[1.0, 0.0, 1.0, 1.0, 1.0, 2.0, 1.0, 3.0]);
        let y = DVector::from_vec(vec![0.0, 1.0, 1.0, 3.0]);
        let s = solve(&phi, &y, &[]).unwrap();
        assert!((s.theta[0] + 0.1).abs() < 1e-12 && (s.theta[1] - 0.9).abs() < 1e-12);
        assert!((s.rss - 0.7).abs() < 1e-12);
        let want = [[0.7, -0.3], [-0.3, 0.2]];
        for (i, row) in want.iter().enumerate() {
            for (j, w) in row.iter().enumerate() {
                assert!((s.inv_gram[(i, j)] - w).abs() < 1e-12);
            }
        }
    }

    // Same problem, same answer: θ̂, RSS and (ΦᵀΦ)⁻¹ agree with nalgebra's own Householder QR (θ̂ = R⁻¹ Qᵀ y,
    // (ΦᵀΦ)⁻¹ = R⁻¹ R⁻ᵀ) to 1e-9 relative on random well-conditioned problems with columns of very
    // different scales.
    #[test]
    fn agrees_with_the_reference_qr_solver() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        for (n, p) in [(7, 7), (50, 3), (2000, 7), (333, 12)] {
            let phi = DMatrix::from_fn(n, p, |_, j| {
                rng.gen_range(-1.0..1.0) * 10f64.powi(j as i32 - 3)
            });
            let y = DVector::from_fn(n, |_, _| rng.gen_range(-5.0..5.0));
            let a = solve(&phi, &y, &[]).unwrap();
            let b = nalgebra_qr(&phi, &y);
            for j in 0..p {
                assert!(
                    rel(a.theta[j], b.theta[j]) < 1e-9,
                    "n={n} p={p} θ{j}: {} vs {}",
                    a.theta[j],
                    b.theta[j]
                );
                for i in 0..p {
                    assert!(
                        (a.inv_gram[(i, j)] - b.inv_gram[(i, j)]).abs()
                            < 1e-9 * b.inv_gram[(i, i)].abs().max(b.inv_gram[(j, j)].abs())
                    );
                }
            }
            assert!(
                n == p || rel(a.rss, b.rss) < 1e-9,
                "rss {} vs {}",
                a.rss,
                b.rss
            );
        }
    }

    #[test]
    fn dependent_and_zero_columns_are_refused_as_not_exciting() {
        let phi = DMatrix::from_row_slice(3, 2, &[1.0, 2.0, 1.0, 2.0, 1.0, 2.0]);
        let y = DVector::from_vec(vec![1.0, 1.0, 1.0]);
        let e = solve(&phi, &y, &["a".into(), "b".into()]).unwrap_err();
        assert!(
            e.to_string().contains("persistently exciting") && e.to_string().contains("b"),
            "{e}"
        );
        let phi = DMatrix::from_row_slice(3, 2, &[1.0, 0.0, 2.0, 0.0, 3.0, 0.0]);
        let e = solve(&phi, &y, &["a".into(), "b".into()]).unwrap_err();
        assert!(e.to_string().contains("regressor b is zero"), "{e}");
    }

    // By hand: the largest |value| −7 at index 2 (the later 7 ties and counts in rest), the rest 7;
    // a NaN is not counted; nothing seen gives place 0 and magnitudes 0.
    #[test]
    fn largest_keeps_the_first_largest_and_the_largest_of_the_rest() {
        assert_eq!(
            largest_and_rest([1.0, -3.0, -7.0, f64::NAN, 7.0, 2.0].into_iter()),
            (2, 7.0, 7.0)
        );
        assert_eq!(
            largest_and_rest([0.5, -4.0, 2.0].into_iter()),
            (1, 4.0, 2.0)
        );
        assert_eq!(largest_and_rest(std::iter::empty()), (0, 0.0, 0.0));
        let mut l = Largest::default();
        for (at, v) in [(10u64, 1.0), (20, -1e200), (30, 2.0)] {
            l.push(at, v);
        }
        assert_eq!(
            (l.at, l.value, l.big, l.rest, l.count),
            (20, -1e200, 1e200, 2.0, 3)
        );
    }

    #[test]
    fn a_column_carried_by_one_outlier_is_named_with_its_row_not_called_unexciting() {
        // y(k−1) and u(k−1) of a record whose row 4 holds 1e308 in both (audit s13 L1): scaled, both
        // columns are the same spike, numerically dependent; the error names the value instead.
        let mut a: Vec<f64> = vec![3.0, -1.0, 2.0, 4.0, 1e308, 5.0, -2.0, 1.0];
        let b = [0.5, 2.0, -3.0, 1.0, 1e308, -1.0, 4.0, 2.0];
        let y = DVector::from_vec(a.iter().map(|v: &f64| v.min(10.0)).collect());
        let phi = DMatrix::from_fn(8, 2, |i, j| if j == 0 { a[i] } else { b[i] });
        let e = solve(&phi, &y, &["a1".into(), "a2".into()]).unwrap_err();
        let m = e.to_string();
        assert!(e.is_numerical(), "{m}");
        assert!(
            m.contains("regressor a1 is carried by one value, 1e308 in regression row 4 of 8"),
            "{m}"
        );
        assert!(m.contains("at most 5e0"), "{m}");
        // Without the outlier the same columns solve.
        a[4] = 6.0;
        let b = [0.5, 2.0, -3.0, 1.0, 2.5, -1.0, 4.0, 2.0];
        let phi = DMatrix::from_fn(8, 2, |i, j| if j == 0 { a[i] } else { b[i] });
        assert!(solve(&phi, &y, &["a1".into(), "a2".into()]).is_ok());
    }

    #[test]
    fn non_finite_data_and_too_few_rows_are_errors() {
        let phi = DMatrix::from_row_slice(2, 1, &[1.0, f64::NAN]);
        let y = DVector::from_vec(vec![1.0, 1.0]);
        assert!(solve(&phi, &y, &[]).unwrap_err().is_numerical());
        let phi = DMatrix::from_row_slice(1, 2, &[1.0, 2.0]);
        assert!(!solve(&phi, &DVector::from_vec(vec![1.0]), &[])
            .unwrap_err()
            .is_numerical());
    }

    // The rank test alone (no target column) factors Φ into the same R as the solve with y, to the bit,
    // for every number of columns (the groups of four with their last columns absent: p = 3, 4, 5, 7,
    // 8, 11), and refuses exactly what the solve refuses: a zero column, dependent columns, too few
    // rows, a non-finite value.
    #[test]
    fn rank_test_alone_has_the_solves_triangle_and_verdict() {
        let mut rng = ChaCha8Rng::seed_from_u64(22);
        for p in [1, 2, 3, 4, 5, 7, 8, 11] {
            for n in [p, p + 1, 300, 700] {
                let phi = DMatrix::from_fn(n, p, |_, _| rng.gen_range(-1.0..1.0));
                let y = DVector::from_fn(n, |_, _| rng.gen_range(-1.0..1.0));
                let (r_y, scale_y, _) = LsWorkspace::new()
                    .factor(&phi, Some(&y), &[], true)
                    .unwrap();
                let (r, scale, _) = LsWorkspace::new().factor(&phi, None, &[], true).unwrap();
                let cols = p + 1;
                for k in 0..p {
                    for c in k..p {
                        assert_eq!(
                            r[k * cols + c].to_bits(),
                            r_y[k * cols + c].to_bits(),
                            "p {p} n {n} R[{k}][{c}]"
                        );
                    }
                }
                assert_eq!(scale, scale_y);
                assert!(rank_test(&phi, &[]).is_ok());
            }
        }
        let names: Vec<String> = (1..=4).map(|j| format!("x{j}")).collect();
        let y = DVector::from_fn(50, |i, _| (i as f64 * 0.3).cos());
        let base = DMatrix::from_fn(50, 4, |i, j| ((i * (j + 2)) as f64 * 0.7).sin());
        let mut zero = base.clone();
        zero.column_mut(2).fill(0.0);
        let mut dependent = base.clone();
        let c0 = dependent.column(0).clone_owned();
        dependent.set_column(3, &(c0 * 2.0));
        let mut infinite = base.clone();
        infinite[(7, 1)] = f64::INFINITY;
        let short = base.rows(0, 3).clone_owned();
        for phi in [zero, dependent, infinite, short] {
            let ys = DVector::from_fn(phi.nrows(), |i, _| y[i]);
            let want = solve(&phi, &ys, &names).unwrap_err().to_string();
            let got = rank_test(&phi, &names).unwrap_err().to_string();
            assert_eq!(got, want);
        }
    }

    // A workspace reused for problems of different sizes gives the same answers as fresh solves.
    #[test]
    fn reused_workspace_gives_the_same_answers() {
        let mut ws = LsWorkspace::new();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        for (n, p) in [(100, 4), (20, 2), (300, 6)] {
            let phi = DMatrix::from_fn(n, p, |_, _| rng.gen_range(-1.0..1.0));
            let y = DVector::from_fn(n, |_, _| rng.gen_range(-1.0..1.0));
            let a = ws.solve(&phi, &y, &[]).unwrap();
            let b = solve(&phi, &y, &[]).unwrap();
            assert_eq!(a.theta, b.theta);
            assert_eq!(a.rss, b.rss);
        }
    }

    // Row-block QR: the accumulated factor gives what the in-memory QR gives on the same rows (θ̂,
    // (ΦᵀΦ)⁻¹, RSS to 1e-12 relative; two different sequences of reflections of the same matrix), for
    // fewer rows than one block, several blocks with a partial last one, and columns 1e±150 apart.
    #[test]
    fn accumulated_factor_agrees_with_the_in_memory_qr() {
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        for (n, p, big) in [(5, 3, 0), (1000, 5, 0), (3 * FOLD_ROWS + 17, 7, 150)] {
            let expo = |j: usize| if j == 0 { big } else { -big * (j as i32 % 2) };
            let phi = DMatrix::from_fn(n, p, |_, j| rng.gen_range(-1.0..1.0) * 10f64.powi(expo(j)));
            // y = Σ_j (j + 1) 10^−e_j φ_j + noise: every θ_j is of order one in its own units.
            let y = DVector::from_fn(n, |i, _| {
                (0..p)
                    .map(|j| (j + 1) as f64 * 10f64.powi(-expo(j)) * phi[(i, j)])
                    .sum::<f64>()
                    + rng.gen_range(-1.0..1.0)
            });
            let a = solve(&phi, &y, &[]).unwrap();
            let mut acc = QrAccumulator::new(p);
            let mut row = vec![0.0; p];
            for i in 0..n {
                for (j, r) in row.iter_mut().enumerate() {
                    *r = phi[(i, j)];
                }
                acc.push(&row, y[i]);
            }
            assert_eq!(acc.rows(), n);
            let b = acc.solve(&[]).unwrap();
            for j in 0..p {
                assert!(rel(a.theta[j], b.theta[j]) < 1e-12, "n={n} θ{j}");
                for i in 0..p {
                    assert!(rel(a.inv_gram[(i, j)], b.inv_gram[(i, j)]) < 1e-10);
                }
            }
            assert!(n == p || rel(a.rss, b.rss) < 1e-12, "{} {}", a.rss, b.rss);
        }
    }

    #[test]
    fn accumulator_refuses_what_the_in_memory_solver_refuses() {
        let mut acc = QrAccumulator::new(2);
        for _ in 0..10 {
            acc.push(&[1.0, 2.0], 1.0);
        }
        let e = acc.solve(&["a".into(), "b".into()]).unwrap_err();
        assert!(e.to_string().contains("persistently exciting") && e.to_string().contains("b"));
        let mut acc = QrAccumulator::new(2);
        acc.push(&[1.0, 0.0], 1.0);
        acc.push(&[2.0, 0.0], 1.0);
        let e = acc.solve(&["a".into(), "b".into()]).unwrap_err();
        assert!(e.to_string().contains("regressor b is zero"), "{e}");
        let mut acc = QrAccumulator::new(2);
        acc.push(&[1.0, 0.0], 1.0);
        assert!(!acc.solve(&[]).unwrap_err().is_numerical());
        let mut acc = QrAccumulator::new(1);
        acc.push(&[f64::NAN], 1.0);
        acc.push(&[1.0], 1.0);
        assert!(acc.solve(&[]).unwrap_err().is_numerical());
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod record_budget_tests {
    use super::{record_budget, MemoryBudget};

    // 1 GiB holds 2^30 / (16 × 8) = 8 388 608 samples of one run, half as many of each of two runs.
    #[test]
    fn the_record_budget_is_sixteen_numbers_per_sample_per_run() {
        let gib = MemoryBudget::from_gib(1.0).unwrap();
        assert_eq!(record_budget(8_388_608, 1, gib), Ok(()));
        assert_eq!(
            record_budget(8_388_609, 1, gib),
            Err((8_388_609 * 128, 8_388_608))
        );
        assert_eq!(record_budget(4_194_304, 2, gib), Ok(()));
        assert_eq!(
            record_budget(4_194_305, 2, gib),
            Err((4_194_305 * 256, 4_194_304))
        );
        assert_eq!(record_budget(0, 0, gib), Ok(()));
    }
}
