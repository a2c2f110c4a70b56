//! Detrending (`--detrend none|mean|linear`, MATLAB `detrend`): the operating point of the estimation
//! record is removed from u and y before estimation and stored in the model, which puts it back whenever it
//! simulates, predicts or runs as a plant, so that every output stays in the user's units.
//!
//! For `mean`, u(k) − ū and y(k) − ȳ are identified. For `linear`, the least-squares line through each
//! signal, s(k) ≈ s̄ + β (k − k̄), is removed. The least-squares line passes through (k̄, s̄), so in both
//! cases the stored operating point is (ū, ȳ): a model with an operating point maps a record as
//! y(k) = y0 + model(u(k) − u0). A drift removed by `linear` is a property of the estimation record, not of
//! the system, and is not put back.

use serde::{Deserialize, Serialize};

use crate::Dataset;

/// How to remove the estimation record's operating point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Detrend {
    /// Use the data as they are (no operating point).
    #[default]
    None,
    /// Remove the means ū, ȳ.
    Mean,
    /// Remove the least-squares straight line of each signal (its mean and its drift).
    Linear,
}

impl std::fmt::Display for Detrend {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Detrend::None => "none",
            Detrend::Mean => "mean",
            Detrend::Linear => "linear",
        })
    }
}

/// The operating point (u0, y0) a model was identified around: the model relates u − u0 to y − y0.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatingPoint {
    /// u0 of each input, in the input's units (for the IPA: PWM counts), in the model's input order.
    pub u: Vec<f64>,
    /// y0 in the output's units (for the IPA: mm).
    pub y: f64,
}

/// The mean s̄ and the least-squares slope β per sample of s(k) ≈ s̄ + β (k − k̄); β = 0 for fewer than
/// two samples.
pub fn line_fit(s: &[f64]) -> (f64, f64) {
    let n = s.len();
    if n == 0 {
        return (0.0, 0.0);
    }
    let mean = s.iter().sum::<f64>() / n as f64;
    let kbar = (n as f64 - 1.0) / 2.0;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (k, v) in s.iter().enumerate() {
        let dk = k as f64 - kbar;
        sxy += dk * (v - mean);
        sxx += dk * dk;
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (mean, slope)
}

impl OperatingPoint {
    /// `data` with this operating point subtracted: u_i − u0_i for each input (in order), y − y0. A
    /// record of another experiment judged around the estimation record's operating point (what a model
    /// carrying it does to any record); an input without its u0 is left as it is.
    pub fn remove_from(&self, data: &Dataset) -> Dataset {
        let inputs = data
            .inputs()
            .iter()
            .enumerate()
            .map(|(m, i)| {
                let u0 = self.u.get(m).copied().unwrap_or(0.0);
                (i.name().to_string(), i.u().iter().map(|v| v - u0).collect())
            })
            .collect();
        let y = data.y().iter().map(|v| v - self.y).collect();
        // Shifted signals of a valid record are finite (a finite shift) and as long as y.
        Dataset::with_inputs(inputs, y, data.ts(), data.name()).unwrap_or_else(|_| data.clone())
    }
}

fn remove(s: &[f64], how: Detrend) -> Vec<f64> {
    let (mean, slope) = line_fit(s);
    let slope = if how == Detrend::Linear { slope } else { 0.0 };
    let kbar = (s.len() as f64 - 1.0) / 2.0;
    s.iter()
        .enumerate()
        .map(|(k, v)| v - mean - slope * (k as f64 - kbar))
        .collect()
}

/// The record with the least-squares drift β (k − k̄) of each signal removed and its mean kept: the data
/// an `--detrend linear` model was estimated from, in the user's units (its operating point (ū, ȳ) put
/// back), on which its estimation figures are scored (audit s18 M-3). Also the slopes β per sample of
/// each input (in the record's order) and of y.
pub fn drift_removed(data: &Dataset) -> (Dataset, Vec<f64>, f64) {
    let keep_mean = |s: &[f64]| {
        let (mean, slope) = line_fit(s);
        let out: Vec<f64> = remove(s, Detrend::Linear)
            .iter()
            .map(|v| v + mean)
            .collect();
        (out, slope)
    };
    let (inputs, slopes): (Vec<(String, Vec<f64>)>, Vec<f64>) = data
        .inputs()
        .iter()
        .map(|i| {
            let (u, b) = keep_mean(i.u());
            ((i.name().to_string(), u), b)
        })
        .unzip();
    let (y, slope_y) = keep_mean(data.y());
    // Shifted signals of a valid record are finite and as long as y.
    let out =
        Dataset::with_inputs(inputs, y, data.ts(), data.name()).unwrap_or_else(|_| data.clone());
    (out, slopes, slope_y)
}

/// The record with its operating point removed, and that operating point (`None` for [`Detrend::None`],
/// which returns the record unchanged).
pub fn detrend(data: &Dataset, how: Detrend) -> (Dataset, Option<OperatingPoint>) {
    let (u, y, op) = detrend_signals(&data.input_signals(), data.y(), how);
    let inputs = data
        .inputs()
        .iter()
        .map(|i| i.name().to_string())
        .zip(u)
        .collect();
    // The detrended signals of a valid record are finite and as long as y.
    let out =
        Dataset::with_inputs(inputs, y, data.ts(), data.name()).unwrap_or_else(|_| data.clone());
    (out, op)
}

/// [`detrend`] of a record with several inputs (one signal per input in `u`, the output `y`): each
/// signal has its own mean (and, for [`Detrend::Linear`], line) removed; the operating point holds the
/// mean of each input and of y. [`Detrend::None`] returns the signals unchanged and `None`.
pub fn detrend_signals(
    u: &[&[f64]],
    y: &[f64],
    how: Detrend,
) -> (Vec<Vec<f64>>, Vec<f64>, Option<OperatingPoint>) {
    if how == Detrend::None {
        return (u.iter().map(|u| u.to_vec()).collect(), y.to_vec(), None);
    }
    let op = OperatingPoint {
        u: u.iter().map(|u| line_fit(u).0).collect(),
        y: line_fit(y).0,
    };
    (
        u.iter().map(|u| remove(u, how)).collect(),
        remove(y, how),
        Some(op),
    )
}
