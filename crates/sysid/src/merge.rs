//! One model from several experiments (`identify --data a.csv b.csv --merge`, MATLAB `merge`): least
//! squares on the regression rows of every record stacked, where no row spans two records (each record
//! contributes its rows k ≥ k0 = max(na, nk + nb − 1) of its own samples only).
//!
//! ARX: one solve of the stacked regression. Hammerstein: the key-term iteration (docs/paper.md) on the
//! stacked rows: the switching functions and internal signal are rebuilt from the current deadzone, the
//! regression solved, the deadzone updated, until θ changes by less than 1e-10 (relative) or
//! `max_iterations`.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use sysid_core::metrics::{
    fit_percent, metrics, one_step_prediction, simulate_estimated_initial, Metrics,
};
use sysid_core::param::{Layout, Parameterisation};
use sysid_core::{Dataset, Deadzone, Model, ModelKind, Structure, SysidError};

/// The result of a merged estimation.
#[derive(Debug, Clone, PartialEq)]
pub struct MergedFit {
    /// The model.
    pub model: Model,
    /// Key-term iterations (1 for ARX).
    pub iterations: usize,
    /// Regression rows per record.
    pub rows: Vec<usize>,
}

/// Free-run fits of one model over several records: each record's and the pooled one.
///
/// As in the per-record [`Metrics`], each record's free-run simulation starts from its own estimated
/// initial outputs (MATLAB `compare`'s default, [`simulate_estimated_initial`]); the pooled fits put
/// those simulations (and the one-step predictions) of every record's rows k ≥ k0 side by side, with
/// one ȳ over all of them. The `*_measured` value pools the simulations from the measured initial
/// outputs instead.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MergedMetrics {
    /// Per record: its name and metrics.
    pub records: Vec<(String, Metrics)>,
    /// Fit % of the free-run simulations (estimated initial outputs per record) over all records' rows
    /// k ≥ k0 pooled (one ȳ for all); `None` when a simulation diverged.
    pub pooled_fit_sim_percent: Option<f64>,
    /// The same from the measured initial outputs of each record.
    pub pooled_fit_sim_measured_percent: Option<f64>,
    /// Fit % of the one-step predictions, pooled.
    pub pooled_fit_pred_percent: Option<f64>,
}

/// Estimates one model of `structure` from all `records` by least squares (module docs).
pub fn identify_merged(
    records: &[Dataset],
    structure: Structure,
    max_iterations: usize,
) -> Result<MergedFit, SysidError> {
    let Some(first) = records.first() else {
        return Err(SysidError::Data("--merge needs at least one record".into()));
    };
    for r in records {
        if (r.ts - first.ts).abs() > 1e-3 * first.ts {
            return Err(SysidError::Data(format!(
                "{} is sampled at Ts = {} s but {} at Ts = {} s; merged records need the same Ts",
                r.name, r.ts, first.name, first.ts
            )));
        }
    }
    let o = structure.orders;
    let k0 = o.na.max(o.nk + o.nb.max(1) - 1);
    let rows: Vec<usize> = records.iter().map(|r| r.len().saturating_sub(k0)).collect();
    let n: usize = rows.iter().sum();
    let p = structure.n_params();
    if n <= p {
        return Err(SysidError::Data(format!(
            "the merged records give {n} regression rows for {p} parameters; more data or lower orders"
        )));
    }
    let names = structure.theta_names();
    let target = DVector::from_iterator(
        n,
        records.iter().flat_map(|r| (k0..r.len()).map(|k| r.y[k])),
    );
    let solve = |dz: &Deadzone| -> Result<Vec<f64>, SysidError> {
        let mut phi = DMatrix::zeros(n, p);
        let mut row = vec![0.0; p];
        let mut i = 0;
        for r in records {
            for k in k0..r.len() {
                structure.fill_row(&r.u, &r.y, k, dz, &mut row);
                for (j, v) in row.iter().enumerate() {
                    phi[(i, j)] = *v;
                }
                i += 1;
            }
        }
        Ok(crate::ls::solve(&phi, &target, &names)?
            .theta
            .iter()
            .copied()
            .collect())
    };
    let nonlinear = [structure.kind == ModelKind::Hammerstein];
    let (theta, _, iterations, _) =
        crate::miso::key_term_iteration(&nonlinear, max_iterations, |dz| solve(&dz[0]))?;
    let model = Parameterisation::new(structure, Layout::KeyTerm).model_of(&theta, first.ts)?;
    Ok(MergedFit {
        model,
        iterations,
        rows,
    })
}

/// The metrics of `model` on each record and pooled over all of them (see [`MergedMetrics`]).
pub fn merged_metrics(model: &Model, records: &[Dataset]) -> Result<MergedMetrics, SysidError> {
    let k0 = model.k0();
    let (mut y, mut sim, mut sim_measured, mut pred) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut sim_ok, mut measured_ok) = (true, true);
    let mut per = Vec::with_capacity(records.len());
    for r in records {
        per.push((r.name.clone(), metrics(model, r)?));
        let from = k0.min(r.len());
        y.extend_from_slice(&r.y[from..]);
        pred.extend_from_slice(&one_step_prediction(model, r)?[from..]);
        match simulate_estimated_initial(model, r) {
            Ok((s, _)) => sim.extend_from_slice(&s[from..]),
            Err(_) => sim_ok = false,
        }
        match model.simulate(&r.u, &r.y) {
            Ok(s) => sim_measured.extend_from_slice(&s[from..]),
            Err(_) => measured_ok = false,
        }
    }
    Ok(MergedMetrics {
        records: per,
        pooled_fit_sim_percent: sim_ok.then(|| fit_percent(&y, &sim)).flatten(),
        pooled_fit_sim_measured_percent: measured_ok
            .then(|| fit_percent(&y, &sim_measured))
            .flatten(),
        pooled_fit_pred_percent: fit_percent(&y, &pred),
    })
}
