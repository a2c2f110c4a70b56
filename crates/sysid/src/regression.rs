//! The one linear-in-parameters regression of every estimator, over one or several inputs and one or
//! several records (docs/paper.md, eq. 8, generalised to several inputs as MATLAB's `arx`/`idnlhw` do):
//!
//! ```text
//! y(k) = −Σ a_i y(k−i) + Σ_inputs [ key terms of f_m at u_m(k − nk_m) + Σ_{j ≥ j_m} b_j^(m) x̂_m(k − nk_m − j) ] + c
//! ```
//!
//! with x̂_m = f̂_m(u_m) the current estimate of input m's static nonlinearity. An input with key terms
//! (a deadzone) has b1 = 1 (the key-term normalisation) and j_m = 1; a linear input has j_m = 0 (its B
//! starts at b1 on x = u). θ (the **key-term layout**) holds every input's key terms, then a1..a_na, then
//! each input's B (from b2 or b1), then c. The **physical layout** (what output error moves) is the same
//! with each input's physical parameters in place of its key terms. Rows are k ≥ k0 = max(na,
//! nk_m + nb_m − 1) of each record; no row spans two records. With one input the layouts are those of
//! `sysid_core::param`.

use nalgebra::{DMatrix, DVector};

use crate::blocks::{sd, Block, BlockStart, NonlinearityKind};
use crate::fitted::Param;
use sysid_core::model::MAX_ORDER;
use sysid_core::{
    Dataset, InputChannel, Model, ParamName, Setting, StaticNonlinearity, SysidError,
};

/// One input of the structure: its name (the model's input name), orders and nonlinearity kind.
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    /// The input's name.
    pub name: String,
    /// nb: number of B coefficients (b1 = 1 included for a nonlinear input).
    pub nb: usize,
    /// nk: delay in samples.
    pub nk: usize,
    /// Its static nonlinearity.
    pub kind: NonlinearityKind,
}

impl Channel {
    fn block(&self) -> &'static dyn Block {
        self.kind.block()
    }
    /// True when the input has key terms (b1 = 1 normalised).
    fn keyed(&self) -> bool {
        !self.block().key_names().is_empty()
    }
    /// Index of the first B coefficient in θ (1 for a keyed input: b1 = 1 is fixed).
    fn b_from(&self) -> usize {
        usize::from(self.keyed())
    }
}

/// The regression of a structure (module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Regression {
    na: usize,
    offset: bool,
    channels: Vec<Channel>,
    k0: usize,
    n_key: usize,
    n_phys: usize,
    len: usize,
}

impl Regression {
    /// Checks the orders and lays out θ.
    pub fn new(na: usize, offset: bool, channels: Vec<Channel>) -> Result<Self, SysidError> {
        if channels.is_empty() {
            return Err(SysidError::Data("a model needs at least one input".into()));
        }
        let several = channels.len() > 1;
        let which = |c: &Channel| {
            if several {
                format!(" for input {}", c.name)
            } else {
                String::new()
            }
        };
        if na > MAX_ORDER {
            return Err(SysidError::setting(
                Setting::Na,
                na,
                &format!("an order of at most {MAX_ORDER}"),
            ));
        }
        for c in &channels {
            c.kind.check()?;
            for (setting, v) in [(Setting::Nb, c.nb), (Setting::Nk, c.nk)] {
                if v > MAX_ORDER {
                    return Err(SysidError::setting(
                        setting,
                        format!("{v}{}", which(c)),
                        &format!("an order of at most {MAX_ORDER}"),
                    ));
                }
            }
            if c.keyed() && c.nb == 0 {
                return Err(SysidError::setting(
                    Setting::Nb,
                    format!("0{}", which(c)),
                    "nb >= 1 for a Hammerstein model (b1 = 1 is the key term)",
                ));
            }
            if several && c.nb == 0 {
                return Err(SysidError::setting(
                    Setting::Nb,
                    format!("0{}", which(c)),
                    "at least one B coefficient per input",
                ));
            }
        }
        let k0 = channels
            .iter()
            .map(|c| (c.nk + c.nb).saturating_sub(1))
            .fold(na, usize::max);
        let n_key = channels.iter().map(|c| c.block().key_names().len()).sum();
        let n_phys = channels
            .iter()
            .map(|c| c.block().physical_names().len())
            .sum();
        let n_b: usize = channels.iter().map(|c| c.nb - c.b_from()).sum();
        let len = n_key + na + n_b + usize::from(offset);
        if len == 0 {
            return Err(SysidError::Data(
                "the model has no parameter to estimate (na = nb = 0)".into(),
            ));
        }
        Ok(Regression {
            na,
            offset,
            channels,
            k0,
            n_key,
            n_phys,
            len,
        })
    }

    /// The inputs.
    pub fn channels(&self) -> &[Channel] {
        &self.channels
    }
    /// na.
    pub fn na(&self) -> usize {
        self.na
    }
    /// Whether c is estimated.
    pub fn offset(&self) -> bool {
        self.offset
    }
    /// First regression sample k0 of every record.
    pub fn k0(&self) -> usize {
        self.k0
    }
    /// Number of entries of θ (key-term layout).
    pub fn len(&self) -> usize {
        self.len
    }
    /// True without entries (never: [`Regression::new`] refuses it).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// True when some input has key terms (the key-term iteration is needed).
    pub fn nonlinear(&self) -> bool {
        self.n_key > 0
    }
    /// Regression rows of `records` (k ≥ k0 of each).
    pub fn rows(&self, records: &[Dataset]) -> usize {
        records
            .iter()
            .map(|r| r.len().saturating_sub(self.k0))
            .sum()
    }

    /// Marks in `params` the block parameters the data do not determine (`starts`' fixed entries: a
    /// one-sided input's dropped branch) as [`crate::fitted::FIXED_ONE_SIDED`].
    pub fn mark_fixed(&self, starts: &[BlockStart], params: &mut [Param]) {
        for (c, (ch, start)) in self.channels.iter().zip(starts).enumerate() {
            let names = ch.kind.block().physical_names();
            for (name, free) in names.iter().zip(&start.free_physical) {
                let input = self.input_of(c);
                if let Some(p) = params
                    .iter_mut()
                    .filter(|_| !free)
                    .find(|p| p.name == *name && p.input == input)
                {
                    p.fixed = Some(crate::fitted::FIXED_ONE_SIDED.to_string());
                }
            }
        }
    }

    /// The label of a parameter of input `c` (its name in brackets with several inputs).
    fn input_of(&self, c: usize) -> Option<String> {
        (self.channels.len() > 1).then(|| self.channels[c].name.clone())
    }

    /// The names of θ's entries (key-term layout), for messages.
    pub fn names(&self) -> Vec<String> {
        let label = |n: ParamName, c: Option<usize>| match c.and_then(|c| self.input_of(c)) {
            Some(i) => format!("{n} ({i})"),
            None => n.to_string(),
        };
        let mut out = Vec::with_capacity(self.len);
        for (c, ch) in self.channels.iter().enumerate() {
            out.extend(ch.block().key_names().iter().map(|n| label(*n, Some(c))));
        }
        out.extend((1..=self.na).map(|i| label(ParamName::A(i), None)));
        for (c, ch) in self.channels.iter().enumerate() {
            out.extend((ch.b_from() + 1..=ch.nb).map(|j| label(ParamName::B(j), Some(c))));
        }
        if self.offset {
            out.push(label(ParamName::C, None));
        }
        out
    }

    /// The names of the physical layout's entries (`b_l (u1)` with several inputs), for messages.
    pub fn physical_labels(&self) -> Vec<String> {
        self.params_from(|_| (0.0, None))
            .iter()
            .filter(|p| {
                // b1 = 1 of a keyed input is reported but is not an entry.
                !(p.name == ParamName::B(1)
                    && self
                        .channels
                        .iter()
                        .any(|c| c.keyed() && p.input.as_deref().is_none_or(|i| i == c.name)))
            })
            .map(Param::label)
            .collect()
    }

    /// Fills `row` with φ(k) from the inputs `u` (one per channel), the output sequence `ys` (the
    /// measured y, or an auxiliary simulation for the IV instruments) and the current nonlinearities
    /// `f`. Requires k ≥ k0.
    #[inline]
    pub fn fill_row(
        &self,
        u: &[&[f64]],
        ys: &[f64],
        f: &[StaticNonlinearity],
        k: usize,
        row: &mut [f64],
    ) {
        let mut i = 0;
        for ((ch, u), f) in self.channels.iter().zip(u).zip(f) {
            let n = ch.block().key_names().len();
            if n > 0 {
                ch.block()
                    .fill_key_terms(f, u[k - ch.nk], &mut row[i..i + n]);
                i += n;
            }
        }
        for a in 1..=self.na {
            row[i] = -ys[k - a];
            i += 1;
        }
        for ((ch, u), f) in self.channels.iter().zip(u).zip(f) {
            for j in ch.b_from()..ch.nb {
                row[i] = f.apply(u[k - ch.nk - j]);
                i += 1;
            }
        }
        if self.offset {
            row[i] = 1.0;
        }
    }

    /// Φ and y of every record's rows k ≥ k0 stacked (records one after the other: no row spans two),
    /// with the nonlinearities `f`. The same rows as [`Regression::fill_row`] gives, built column by
    /// column (Φ is stored by columns; only the key terms need a call per row). Φ and y are allocated
    /// fallibly ([`sysid_core::ls::try_matrix`]): a failed allocation is an error, not an abort (the
    /// size is bounded before, by [`crate::Identification::check_memory`]).
    pub fn stacked(
        &self,
        records: &[Dataset],
        f: &[StaticNonlinearity],
    ) -> Result<(DMatrix<f64>, DVector<f64>), SysidError> {
        let rows = self.rows(records);
        let mut phi = sysid_core::ls::try_matrix(rows, self.len, "the regression matrix")?;
        let mut y = DVector::from_vec(sysid_core::ls::try_zeros(rows, "the regression targets")?);
        self.stacked_into::<false>(records, f, &mut phi, &mut y);
        Ok((phi, y))
    }

    /// [`Regression::stacked`] into the first rows of `phi` and `y`, which have room for them (at least
    /// the regression's rows, and its columns); rows below are left as they are (the caller's extra
    /// rows), so a buffer is reused without being cleared. With `TRACK`, returns true when the columns
    /// that depend on `f` (the key terms, x̂ = f(u)) are what `phi` held before to the bit (so when
    /// `phi` held these records' rows, Φ repeats); without, always true.
    pub fn stacked_into<const TRACK: bool>(
        &self,
        records: &[Dataset],
        f: &[StaticNonlinearity],
        phi: &mut DMatrix<f64>,
        y: &mut DVector<f64>,
    ) -> bool {
        let mut unchanged = true;
        let mut keys_unchanged = true;
        let mut write = |d: &mut f64, v: f64| {
            if TRACK {
                unchanged &= d.to_bits() == v.to_bits();
            }
            *d = v;
        };
        // `rows` is the stride of Φ's columns (its whole height).
        let rows = phi.nrows();
        debug_assert!(rows >= self.rows(records) && phi.ncols() == self.len && y.len() == rows);
        let data = phi.as_mut_slice();
        let k0 = self.k0;
        let mut at = 0;
        for r in records {
            let (u, ys) = (r.input_signals(), r.y());
            let m = r.len().saturating_sub(k0);
            if m == 0 {
                continue; // a record no longer than k0 gives no row
            }
            // Column c of this record's block of rows.
            let mut col = 0;
            let column = |c: usize| c * rows + at..c * rows + at + m;
            for ((ch, u), f) in self.channels.iter().zip(&u).zip(f) {
                let block = ch.block();
                let n = block.key_names().len();
                if n == 0 {
                    continue;
                }
                let commands = &u[k0 - ch.nk..k0 - ch.nk + m];
                let same = block.fill_key_columns(f, commands, &mut data[col * rows + at..], rows);
                keys_unchanged &= same;
                col += n;
            }
            for a in 1..=self.na {
                for (d, v) in data[column(col)].iter_mut().zip(&ys[k0 - a..]) {
                    *d = -v;
                }
                col += 1;
            }
            for ((ch, u), f) in self.channels.iter().zip(&u).zip(f) {
                for j in ch.b_from()..ch.nb {
                    for (d, v) in data[column(col)].iter_mut().zip(&u[k0 - ch.nk - j..]) {
                        write(d, f.apply(*v));
                    }
                    col += 1;
                }
            }
            if self.offset {
                data[column(col)].fill(1.0);
            }
            y.as_mut_slice()[at..at + m].copy_from_slice(&ys[k0..]);
            at += m;
        }
        unchanged && (keys_unchanged || !TRACK)
    }

    /// Which entries of θ the data determine (the blocks' free key terms; the rest is free).
    pub fn free_key(&self, starts: &[BlockStart]) -> Vec<bool> {
        let mut free = Vec::with_capacity(self.len);
        for s in starts {
            free.extend_from_slice(&s.free_key);
        }
        free.resize(self.len, true);
        free
    }

    /// Which entries of the physical layout the data determine.
    pub fn free_physical(&self, starts: &[BlockStart]) -> Vec<bool> {
        let mut free = Vec::with_capacity(self.physical_len());
        for s in starts {
            free.extend_from_slice(&s.free_physical);
        }
        free.resize(self.physical_len(), true);
        free
    }

    /// Number of entries of the physical layout.
    pub fn physical_len(&self) -> usize {
        self.len - self.n_key + self.n_phys
    }

    /// The nonlinearities `f` updated from the key terms of θ̂ (breakpoints clamped to each block's
    /// limit, fixed parts imposed); linear inputs keep theirs.
    pub fn update(&self, theta: &[f64], f: &mut [StaticNonlinearity], starts: &[BlockStart]) {
        let mut i = 0;
        for ((ch, f), s) in self.channels.iter().zip(f.iter_mut()).zip(starts) {
            let b = ch.block();
            let n = b.key_names().len();
            if n > 0 {
                b.set_key_terms(&theta[i..i + n], f, s.limit);
                if !s.all_free() {
                    *f = s.impose(b, f);
                }
                i += n;
            }
        }
    }

    /// The model of θ̂ (key-term layout) sampled at `ts` s: each block from its key terms (a parameter
    /// they do not determine is 0), its fixed parts imposed.
    pub fn model_of(
        &self,
        theta: &[f64],
        starts: &[BlockStart],
        ts: f64,
    ) -> Result<Model, SysidError> {
        let mut f = Vec::with_capacity(self.channels.len());
        let mut i = 0;
        for (ch, s) in self.channels.iter().zip(starts) {
            let b = ch.block();
            let n = b.key_names().len();
            let zero = b.of_physical(&vec![0.0; b.physical_names().len()]);
            let next = b.of_key_terms(&theta[i..i + n], &zero, f64::INFINITY);
            f.push(s.impose(b, &next));
            i += n;
        }
        self.model_with(&f, &theta[self.n_key..], ts)
    }

    /// The model with nonlinearities `f` and the linear part `rest` = [a.., B of each input, c] (the
    /// common tail of both layouts).
    fn model_with(
        &self,
        f: &[StaticNonlinearity],
        rest: &[f64],
        ts: f64,
    ) -> Result<Model, SysidError> {
        let a = rest[..self.na].to_vec();
        let mut i = self.na;
        let mut channels = Vec::with_capacity(self.channels.len());
        for (ch, f) in self.channels.iter().zip(f) {
            let mut b = Vec::with_capacity(ch.nb);
            if ch.keyed() {
                b.push(1.0);
            }
            let n = ch.nb - ch.b_from();
            b.extend_from_slice(&rest[i..i + n]);
            i += n;
            channels.push(InputChannel::new(ch.name.clone(), ch.nk, b, *f)?);
        }
        let c = self.offset.then(|| rest[i]);
        Model::new(ts, a, channels, c)
    }

    /// The linear tail [a.., B of each input (from b2 for a keyed one), c] of `model`.
    fn tail_of(&self, model: &Model) -> Vec<f64> {
        let mut v = model.a().to_vec();
        for (ch, m) in self.channels.iter().zip(model.inputs()) {
            v.extend_from_slice(&m.b()[ch.b_from()..]);
        }
        v.extend(model.offset());
        v
    }

    /// θ of `model` in the key-term layout.
    pub fn key_vector(&self, model: &Model) -> Vec<f64> {
        let mut v = Vec::with_capacity(self.len);
        for (ch, m) in self.channels.iter().zip(model.inputs()) {
            v.extend(ch.block().key_terms(m.nonlinearity()));
        }
        v.extend(self.tail_of(model));
        v
    }

    /// The physical-layout vector of `model`.
    pub fn physical_vector(&self, model: &Model) -> Vec<f64> {
        let mut v = Vec::with_capacity(self.physical_len());
        for (ch, m) in self.channels.iter().zip(model.inputs()) {
            v.extend(ch.block().physical(m.nonlinearity()));
        }
        v.extend(self.tail_of(model));
        v
    }

    /// The model of a physical-layout vector `v` sampled at `ts` s.
    pub fn model_of_physical(&self, v: &[f64], ts: f64) -> Result<Model, SysidError> {
        let mut f = Vec::with_capacity(self.channels.len());
        let mut i = 0;
        for ch in &self.channels {
            let n = ch.block().physical_names().len();
            f.push(ch.block().of_physical(&v[i..i + n]));
            i += n;
        }
        self.model_with(&f, &v[self.n_phys..], ts)
    }

    /// The reported parameters (each block's physical parameters, a.., each input's B with b1 = 1 of a
    /// keyed input fixed, c) with `entry(i)` the value and standard deviation of physical-layout entry i.
    pub fn params_from(&self, entry: impl Fn(usize) -> (f64, Option<f64>)) -> Vec<Param> {
        let mut out = Vec::with_capacity(self.physical_len() + self.channels.len());
        let param =
            |name: ParamName, input: Option<String>, (value, std): (f64, Option<f64>)| Param {
                name,
                input,
                value,
                std,
                fixed: None,
            };
        let mut i = 0;
        for (c, ch) in self.channels.iter().enumerate() {
            for n in ch.block().physical_names() {
                out.push(param(*n, self.input_of(c), entry(i)));
                i += 1;
            }
        }
        for a in 1..=self.na {
            out.push(param(ParamName::A(a), None, entry(i)));
            i += 1;
        }
        for (c, ch) in self.channels.iter().enumerate() {
            if ch.keyed() {
                out.push(Param {
                    fixed: Some(crate::fitted::FIXED_NORMALISATION.to_string()),
                    ..param(ParamName::B(1), self.input_of(c), (1.0, None))
                });
            }
            for j in ch.b_from() + 1..=ch.nb {
                out.push(param(ParamName::B(j), self.input_of(c), entry(i)));
                i += 1;
            }
        }
        if self.offset {
            out.push(param(ParamName::C, None, entry(i)));
        }
        out
    }

    /// The physical parameters of key-term θ̂ with standard deviations from Cov(θ̂) (delta method
    /// for the blocks' derived parameters), as the key terms give them.
    pub fn params_of_theta(&self, theta: &[f64], cov: Option<&DMatrix<f64>>) -> Vec<Param> {
        let mut blocks = Vec::with_capacity(self.n_phys);
        let mut at = 0;
        for ch in &self.channels {
            blocks.extend(ch.block().physical_with_std(theta, cov, at));
            at += ch.block().key_names().len();
        }
        let shift = self.n_key;
        self.params_from(|i| {
            if i < self.n_phys {
                blocks[i]
            } else {
                let j = i - self.n_phys + shift;
                (theta[j], sd(cov, j))
            }
        })
    }

    /// [`Regression::params_of_theta`] with the parameters the data do not determine set to their
    /// value in `model` and without a standard deviation.
    pub fn params(
        &self,
        theta: &[f64],
        cov: Option<&DMatrix<f64>>,
        model: &Model,
        starts: &[BlockStart],
    ) -> Vec<Param> {
        let mut params = self.params_of_theta(theta, cov);
        let values = self.physical_vector(model);
        let free = self.free_physical(starts);
        for (i, q) in params.iter_mut().take(self.n_phys).enumerate() {
            if !free[i] {
                q.value = values[i];
                q.std = None;
            }
        }
        params
    }

    /// The same regression with every input linear (the ARX structure of the same orders).
    pub fn linear(&self) -> Result<Regression, SysidError> {
        let channels = self
            .channels
            .iter()
            .map(|c| Channel {
                kind: NonlinearityKind::Linear,
                ..c.clone()
            })
            .collect();
        Regression::new(self.na, self.offset, channels)
    }
}

/// The full vector with `sub` in the entries marked free and `base` elsewhere.
pub(crate) fn scatter(free: &[bool], sub: &[f64], base: &[f64]) -> Vec<f64> {
    let mut out = vec![0.0; free.len().min(base.len())];
    scatter_into(free, sub, base, &mut out);
    out
}

/// [`scatter`] into `out` (its length: the full size), without allocating.
pub(crate) fn scatter_into(free: &[bool], sub: &[f64], base: &[f64], out: &mut [f64]) {
    let mut it = sub.iter();
    for ((v, f), b) in out.iter_mut().zip(free).zip(base) {
        *v = if *f { *it.next().unwrap_or(b) } else { *b };
    }
}

/// The full matrix with `sub` in the rows and columns marked free and zeros elsewhere.
pub(crate) fn scatter_matrix(free: &[bool], sub: &DMatrix<f64>) -> DMatrix<f64> {
    let idx: Vec<usize> = (0..free.len()).filter(|&i| free[i]).collect();
    let mut out = DMatrix::zeros(free.len(), free.len());
    for (a, &i) in idx.iter().enumerate() {
        for (b, &j) in idx.iter().enumerate() {
            out[(i, j)] = sub[(a, b)];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use sysid_core::Deadzone;

    // Layout of several-input parameters: deadzones first, then a, then each input's B with b1 = 1 of a
    // nonlinear input inserted (fixed) even when nb = 1 leaves it no free coefficient; the vector maps back
    // to the same model.
    #[test]
    fn several_input_parameters_list_each_fixed_b1_in_its_place() {
        let dz = |b: f64| {
            StaticNonlinearity::Deadzone(Deadzone {
                b_l: -b,
                b_r: b,
                m_l: 0.5,
                m_r: 0.7,
            })
        };
        let inputs = vec![
            InputChannel::new("v1", 1, vec![1.0], dz(1.0)).unwrap(),
            InputChannel::new("p", 2, vec![0.2, 0.1], StaticNonlinearity::Linear).unwrap(),
            InputChannel::new("v2", 1, vec![1.0], dz(2.0)).unwrap(),
        ];
        let model = Model::new(0.01, vec![-0.9], inputs, None).unwrap();
        let channel = |name: &str, nb, nk, kind| Channel {
            name: name.into(),
            nb,
            nk,
            kind,
        };
        let reg = Regression::new(
            1,
            false,
            vec![
                channel("v1", 1, 1, NonlinearityKind::Deadzone),
                channel("p", 2, 2, NonlinearityKind::Linear),
                channel("v2", 1, 1, NonlinearityKind::Deadzone),
            ],
        )
        .unwrap();
        let v = reg.physical_vector(&model);
        assert_eq!(v.len(), reg.physical_len());
        let params = reg.params_from(|i| (v[i], Some(1.0)));
        let labels: Vec<String> = params.iter().map(Param::label).collect();
        let got: Vec<&str> = labels.iter().map(String::as_str).collect();
        assert_eq!(
            got,
            [
                "b_l (v1)", "b_r (v1)", "m_l (v1)", "m_r (v1)", "b_l (v2)", "b_r (v2)", "m_l (v2)",
                "m_r (v2)", "a1", "b1 (v1)", "b1 (p)", "b2 (p)", "b1 (v2)"
            ]
        );
        let fixed: Vec<bool> = params.iter().map(|p| p.std.is_none()).collect();
        assert_eq!(fixed.iter().filter(|f| **f).count(), 2);
        assert!(fixed[9] && fixed[12]);
        assert_eq!(reg.model_of_physical(&v, 0.01).unwrap(), model);
    }

    // Φ built column by column (`stacked_into`, the key terms one call per record) holds, to the bit, the
    // rows `fill_row` builds one at a time, for every kind of block (deadzone, saturation, deadzone with
    // saturation, piecewise-linear, polynomial, linear) over two records; built again into the same
    // buffer it reports the f-dependent columns unchanged, and changed after f moves.
    #[test]
    fn stacked_rows_are_the_rows_built_one_at_a_time() {
        let kinds = [
            NonlinearityKind::Deadzone,
            NonlinearityKind::Saturation,
            NonlinearityKind::DeadzoneSaturation,
            NonlinearityKind::PiecewiseLinear { breakpoints: 2 },
            NonlinearityKind::Polynomial { degree: 3 },
        ];
        let wave = |k: usize, s: f64| ((k as f64 * s).sin() * 200.0).round();
        let record = |n: usize, seed: f64, name: &str| {
            let u1: Vec<f64> = (0..n).map(|k| wave(k, 0.37 + seed)).collect();
            let u2: Vec<f64> = (0..n).map(|k| wave(k, 0.11 + seed) * 0.5).collect();
            let y: Vec<f64> = (0..n).map(|k| wave(k, 0.05 + seed) * 0.01).collect();
            Dataset::with_inputs(vec![("a".into(), u1), ("b".into(), u2)], y, 0.01, name).unwrap()
        };
        let records = [record(60, 0.0, "r1"), record(45, 0.3, "r2")];
        for kind in kinds {
            let channels = vec![
                Channel {
                    name: "a".into(),
                    nb: 2,
                    nk: 1,
                    kind,
                },
                Channel {
                    name: "b".into(),
                    nb: 2,
                    nk: 0,
                    kind: NonlinearityKind::Linear,
                },
            ];
            let reg = Regression::new(2, true, channels).unwrap();
            let u_all: Vec<f64> = records
                .iter()
                .flat_map(|r| r.inputs()[0].u().iter().copied())
                .collect();
            let start = kind.block().start(&u_all, true, true, "t").unwrap();
            let f = vec![start.initial, StaticNonlinearity::Linear];
            let (phi, y) = reg.stacked(&records, &f).unwrap();
            let mut row = vec![0.0; reg.len()];
            let mut at = 0;
            for r in &records {
                let u = r.input_signals();
                for k in reg.k0()..r.len() {
                    reg.fill_row(&u, r.y(), &f, k, &mut row);
                    for (c, v) in row.iter().enumerate() {
                        assert_eq!(
                            phi[(at, c)].to_bits(),
                            v.to_bits(),
                            "{kind:?} row {at} column {c}"
                        );
                    }
                    assert_eq!(y[at], r.y()[k]);
                    at += 1;
                }
            }
            assert_eq!(at, phi.nrows());
            let (mut again, mut y2) = (phi.clone(), y.clone());
            assert!(reg.stacked_into::<true>(&records, &f, &mut again, &mut y2));
            // Moving the nonlinearity changes its key-term columns.
            let mut theta = vec![0.0; reg.len()];
            for (i, v) in theta.iter_mut().enumerate() {
                *v = 0.3 + 0.1 * i as f64;
            }
            let mut moved = f.clone();
            let linear = NonlinearityKind::Linear
                .block()
                .start(&[], false, true, "t");
            reg.update(&theta, &mut moved, &[start, linear.unwrap()]);
            assert!(
                !reg.stacked_into::<true>(&records, &moved, &mut again, &mut y2),
                "{kind:?}"
            );
        }
    }
}
