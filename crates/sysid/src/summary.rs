//! The JSON summary of an identification (`identify --json`), also embedded by `reproduce` in
//! `summary.json` (`models.arx`, `models.hammerstein`).

use serde::{Deserialize, Serialize};

use crate::estimate::{Identified, IdentifySettings, Method, Param};
use crate::validation::Metrics;
use crate::Model;

/// A pole p = re + i·im of the linear block.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pole {
    /// Real part.
    pub re: f64,
    /// Imaginary part.
    pub im: f64,
    /// Modulus |p| (stable when < 1).
    pub abs: f64,
}

/// How the model was estimated.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EstimationInfo {
    /// `ls` or `rls`.
    pub method: Method,
    /// Key-term iterations (LS) or passes (RLS).
    pub iterations: usize,
    /// See [`Identified::converged`].
    pub converged: bool,
    /// RLS forgetting factor ρ (RLS only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub forgetting: Option<f64>,
    /// RLS P(0) scale (RLS only).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub p0: Option<f64>,
    /// σ̂² of the one-step prediction errors.
    pub noise_variance: f64,
    /// Remarks (limit cycle, best iterate kept...).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub note: Option<String>,
}

/// Metrics on the estimation record and, when given, on the validation record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetricsPair {
    /// On the estimation data.
    pub estimation: Metrics,
    /// On the `--validation` data.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub validation: Option<Metrics>,
}

/// The whole `identify --json` document.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifyReport {
    /// The fitted model (the same object a model file holds).
    pub model: Model,
    /// Physical parameters with standard deviations.
    pub parameters: Vec<Param>,
    /// Poles of the linear block, largest modulus first.
    pub poles: Vec<Pole>,
    /// All poles strictly inside the unit circle.
    pub stable: bool,
    /// Estimation record.
    pub estimation: EstimationInfo,
    /// Validation metrics.
    pub metrics: MetricsPair,
}

impl IdentifyReport {
    /// Assembles the report of a fit.
    pub fn new(
        fit: &Identified,
        settings: &IdentifySettings,
        est: Metrics,
        val: Option<Metrics>,
    ) -> Self {
        let rls = fit.method == Method::Rls;
        IdentifyReport {
            model: fit.model.clone(),
            parameters: fit.params.clone(),
            poles: poles(&fit.model),
            stable: fit.model.is_stable(),
            estimation: EstimationInfo {
                method: fit.method,
                iterations: fit.iterations,
                converged: fit.converged,
                forgetting: rls.then_some(settings.forgetting),
                p0: rls.then_some(settings.p0),
                noise_variance: fit.noise_variance,
                note: fit.note.clone(),
            },
            metrics: MetricsPair {
                estimation: est,
                validation: val,
            },
        }
    }

    /// Pretty JSON text.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default() + "\n"
    }
}

/// The poles of a model as JSON-friendly values.
pub fn poles(model: &Model) -> Vec<Pole> {
    model
        .poles()
        .iter()
        .map(|p| Pole {
            re: p.re,
            im: p.im,
            abs: p.norm(),
        })
        .collect()
}

/// Formats a number for a report: 6 significant digits, scientific for very large or small values.
pub fn num(v: f64) -> String {
    fn trim(s: String) -> String {
        match s.split_once('e') {
            Some((m, e)) if m.contains('.') => {
                format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
            }
            None if s.contains('.') => s.trim_end_matches('0').trim_end_matches('.').to_string(),
            _ => s,
        }
    }
    if v == 0.0 {
        "0".into()
    } else if !v.is_finite() {
        format!("{v}")
    } else if v.abs() >= 1e5 || v.abs() < 1e-3 {
        trim(format!("{v:.5e}"))
    } else {
        let digits = (5 - v.abs().log10().floor() as i32).clamp(0, 9) as usize;
        trim(format!("{v:.digits$}"))
    }
}

/// A row of the text metrics table: label and how to format the value from a [`Metrics`].
type MetricRow = (&'static str, fn(&Metrics) -> String);

fn opt(v: Option<f64>) -> String {
    v.map_or_else(|| "n/a".into(), num)
}

impl IdentifyReport {
    /// A readable plain-text report (parameters ± std, poles, stability, metrics), as `identify` prints.
    pub fn to_text(&self) -> String {
        use std::fmt::Write;
        let m = &self.model;
        let mut s = String::new();
        let kind = match m.kind {
            crate::ModelKind::Arx => "Linear ARX".to_string(),
            crate::ModelKind::Hammerstein => "Hammerstein (deadzone + ARX)".to_string(),
        };
        let _ = writeln!(
            s,
            "{kind} model, na = {} nb = {} nk = {}, Ts = {} s, estimated by {} ({} {}, {})",
            m.na,
            m.nb,
            m.nk,
            num(m.ts),
            self.estimation.method,
            self.estimation.iterations,
            match self.estimation.method {
                Method::Ls | Method::Oe => "iteration(s)",
                Method::Rls => "pass(es)",
                Method::Iv => "stage(s)",
            },
            if self.estimation.converged {
                "converged"
            } else {
                "NOT converged"
            }
        );
        if let Some(note) = &self.estimation.note {
            let _ = writeln!(s, "note: {note}");
        }
        let _ = writeln!(s, "\nParameters (estimate ± standard deviation)");
        for p in &self.parameters {
            let sd = match p.std {
                Some(v) => format!("± {}", num(v)),
                None if p.name == "b1" && m.kind == crate::ModelKind::Hammerstein => {
                    "(fixed: normalisation)".into()
                }
                None => "± n/a".into(),
            };
            let _ = writeln!(s, "  {:<6} = {:>14}  {sd}", p.name, num(p.value));
        }
        let poles: Vec<String> = self
            .poles
            .iter()
            .map(|p| {
                if p.im.abs() < 1e-12 {
                    num(p.re)
                } else {
                    format!(
                        "{} {} {}i",
                        num(p.re),
                        if p.im < 0.0 { "-" } else { "+" },
                        num(p.im.abs())
                    )
                }
            })
            .collect();
        let _ = writeln!(
            s,
            "\nPoles: {}  → {}",
            if poles.is_empty() {
                "none".to_string()
            } else {
                poles.join(", ")
            },
            if self.stable {
                "stable (all inside the unit circle)"
            } else {
                "UNSTABLE (a pole on or outside the unit circle)"
            }
        );
        let val = self.metrics.validation.as_ref();
        let _ = writeln!(
            s,
            "\n{:<22}{:>16}{:>16}",
            "Metric",
            "estimation",
            if val.is_some() { "validation" } else { "" }
        );
        let rows: [MetricRow; 9] = [
            ("fit % (simulation)", |m| opt(m.fit_sim_percent)),
            ("fit % (1-step pred.)", |m| opt(m.fit_pred_percent)),
            ("RMSE (simulation)", |m| opt(m.rmse_sim)),
            ("RMSE (1-step pred.)", |m| num(m.rmse_pred)),
            ("loss V (eq. 14)", |m| num(m.loss)),
            ("FPE (eq. 15)", |m| opt(m.fpe)),
            ("AIC (normalised)", |m| opt(m.aic)),
            ("N (rows used)", |m| m.n.to_string()),
            ("p (parameters)", |m| m.p.to_string()),
        ];
        for (label, f) in rows {
            let _ = writeln!(
                s,
                "{label:<22}{:>16}{:>16}",
                f(&self.metrics.estimation),
                val.map(f).unwrap_or_default()
            );
        }
        for (which, mm) in [
            ("estimation", Some(&self.metrics.estimation)),
            ("validation", val),
        ] {
            if let Some(note) = mm.and_then(|m| m.note.as_ref()) {
                let _ = writeln!(s, "note ({which}): {note}");
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    // Six significant digits, trailing zeros dropped: 0.01 → "0.01", 1.41 → "1.41", 1/3 → "0.333333".
    #[test]
    fn numbers_keep_six_significant_digits_without_trailing_zeros() {
        assert_eq!(super::num(0.01), "0.01");
        assert_eq!(super::num(1.41), "1.41");
        assert_eq!(super::num(1.0 / 3.0), "0.333333");
        assert_eq!(super::num(-1234.5678), "-1234.57");
        assert_eq!(super::num(2.5e-4), "2.5e-4");
        assert_eq!(super::num(100.0), "100");
    }
}
