//! What an estimator is fitted to ([`Problem`]: the records, the one regression of the structure and
//! what the data determine of each input's nonlinearity) and the [`Estimator`] trait every method
//! implements.

use crate::blocks::BlockStart;
use crate::fitted::{Fitted, Method};
use crate::regression::{Channel, Regression};
use sysid_core::{Dataset, Model, Stop, SysidError};

/// One record or several (merged experiments, MATLAB `merge`): what [`identify`](crate::identify) accepts.
pub trait Records {
    /// The records.
    fn records(&self) -> &[Dataset];
}

impl Records for Dataset {
    fn records(&self) -> &[Dataset] {
        std::slice::from_ref(self)
    }
}

impl Records for [Dataset] {
    fn records(&self) -> &[Dataset] {
        self
    }
}

impl Records for Vec<Dataset> {
    fn records(&self) -> &[Dataset] {
        self
    }
}

/// What an estimator is fitted to: the records, the regression of the structure and, per input, what
/// the data determine of its static nonlinearity. Made by [`Problem::new`], which checks that the data
/// can support the structure.
#[derive(Debug, Clone)]
pub struct Problem<'a> {
    records: &'a [Dataset],
    regression: Regression,
    starts: Vec<BlockStart>,
    name: String,
    cancel: Stop,
}

impl<'a> Problem<'a> {
    /// Checks the structure `regression` against `records` (same inputs and Ts in every record, enough
    /// rows) and finds what each input determines of its nonlinearity ([`crate::blocks::Block::start`]);
    /// with `drop_unexcited_branch`, what a one-sided input cannot determine is dropped instead of
    /// refused.
    pub fn new(
        records: &'a [Dataset],
        regression: Regression,
        drop_unexcited_branch: bool,
    ) -> Result<Self, SysidError> {
        let Some(first) = records.first() else {
            return Err(SysidError::Data(
                "identification needs at least one record".into(),
            ));
        };
        let names: Vec<&str> = first.inputs().iter().map(|i| i.name()).collect();
        for r in records {
            if (r.ts() - first.ts()).abs() > 1e-3 * first.ts() {
                return Err(SysidError::Data(format!(
                    "{} is sampled at Ts = {} s but {} at Ts = {} s; merged records need the same Ts",
                    r.name(),
                    sysid_core::format::Shortest(r.ts()),
                    first.name(),
                    sysid_core::format::Shortest(first.ts())
                )));
            }
            if r.inputs()
                .iter()
                .map(|i| i.name())
                .ne(names.iter().copied())
            {
                return Err(SysidError::Data(format!(
                    "{} and {} have different inputs; merged records must have the same inputs, in the same order",
                    first.name(),
                    r.name()
                )));
            }
        }
        let name = records
            .iter()
            .map(Dataset::name)
            .collect::<Vec<_>>()
            .join(" + ");
        let p = regression.len();
        let k0 = regression.k0();
        let rows = regression.rows(records);
        if records.len() == 1 {
            let n = first.len();
            if n <= k0 || n - k0 < p {
                let list = |f: fn(&Channel) -> usize| {
                    regression
                        .channels()
                        .iter()
                        .map(|c| f(c).to_string())
                        .collect::<Vec<_>>()
                        .join(",")
                };
                return Err(SysidError::Data(format!(
                    "{}: {n} samples leave {} regression rows for {p} parameters (na = {}, nb = {}, nk = {}); \
                     more data or lower orders are needed",
                    first.name(),
                    n.saturating_sub(k0),
                    regression.na(),
                    list(|c| c.nb),
                    list(|c| c.nk),
                )));
            }
        } else if rows <= p {
            return Err(SysidError::Data(format!(
                "the merged records give {rows} regression rows for {p} parameters; more data or lower orders"
            )));
        }
        let several = regression.channels().len() > 1;
        let mut starts = Vec::with_capacity(names.len());
        for (m, ch) in regression.channels().iter().enumerate() {
            let u = sysid_core::ls::try_collect(
                records
                    .iter()
                    .flat_map(|r| r.inputs()[m].u().iter().copied()),
                records.iter().map(|r| r.inputs()[m].u().len()).sum(),
                &format!("the input of {name}"),
            )?;
            let who = if several {
                format!("{} (input {})", name, ch.name)
            } else {
                name.clone()
            };
            starts.push(ch.kind.block().start(
                &u,
                regression.offset(),
                drop_unexcited_branch,
                &who,
            )?);
        }
        Ok(Problem {
            records,
            regression,
            starts,
            name,
            cancel: Stop::never(),
        })
    }

    /// The same problem with the caller's stop check, which the estimators poll at each iteration,
    /// pass or stage ([`Stop`]).
    pub fn with_cancel(mut self, cancel: Stop) -> Self {
        self.cancel = cancel;
        self
    }
    /// The caller's stop check ([`Stop::never`] unless [`Problem::with_cancel`] gave one).
    pub fn cancel(&self) -> &Stop {
        &self.cancel
    }

    /// The records.
    pub fn records(&self) -> &'a [Dataset] {
        self.records
    }
    /// The regression of the structure.
    pub fn regression(&self) -> &Regression {
        &self.regression
    }
    /// What the data determine of each input's nonlinearity.
    pub fn starts(&self) -> &[BlockStart] {
        &self.starts
    }
    /// The records' names, for messages.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// Ts in s.
    pub fn ts(&self) -> f64 {
        self.records[0].ts()
    }
    /// The same problem with every input linear (the ARX structure of the same orders).
    pub(crate) fn linear(&self) -> Result<Problem<'a>, SysidError> {
        let regression = self.regression.linear()?;
        let starts = regression
            .channels()
            .iter()
            .map(|c| c.kind.block().start(&[], false, true, &self.name))
            .collect::<Result<_, _>>()?;
        Ok(Problem {
            records: self.records,
            regression,
            starts,
            name: self.name.clone(),
            cancel: self.cancel.clone(),
        })
    }
    /// Input m of every record, one after the other.
    pub(crate) fn input_samples(&self, m: usize) -> Vec<f64> {
        self.records
            .iter()
            .flat_map(|r| r.inputs()[m].u().iter().copied())
            .collect()
    }
    /// The remarks of the blocks' starts (a dropped branch...), naming the input when there are several.
    pub(crate) fn notes(&self) -> Vec<String> {
        let several = self.starts.len() > 1;
        self.regression
            .channels()
            .iter()
            .zip(&self.starts)
            .flat_map(|(c, s)| {
                s.notes.iter().map(move |n| {
                    if several {
                        format!("input {}: {n}", c.name)
                    } else {
                        n.clone()
                    }
                })
            })
            .collect()
    }

    /// The metrics of `model` on the estimation records (pooled over several); `None` when they cannot
    /// be computed.
    pub(crate) fn metrics(&self, model: &Model) -> Option<sysid_core::metrics::Metrics> {
        sysid_core::metrics::pooled_metrics(model, self.records).ok()
    }
}

/// An estimation method: checks its settings and fits a [`Problem`].
pub trait Estimator {
    /// Which method this is (reported in the fitted result).
    fn method(&self) -> Method;
    /// Checks the settings (each error names the [`Setting`](sysid_core::Setting) at fault).
    fn check(&self) -> Result<(), SysidError>;
    /// Fits the problem. Called by [`identify`](crate::identify), which checks the settings first and applies the common
    /// safeguards after.
    fn fit(&self, problem: &Problem) -> Result<Fitted, SysidError>;
}
