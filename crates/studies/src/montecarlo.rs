//! Monte Carlo study of estimator bias and spread under white output noise.
//!
//! Run r (r = 0..R−1) is seeded with s_r = [`run_seed`](seed, r). An experiment closure turns (r, s_r) into
//! an input record u and the plant's noise-free output y₀ (the plant wiring lives with the caller: the
//! command line builds plants with the `ipa` crate). The study adds white Gaussian noise of standard
//! deviation σ (`rand_distr::StandardNormal` on ChaCha8 seeded with s_r) to y₀ and identifies the model with every method on the same
//! noisy record. Runs are independent and processed in parallel (rayon); the result depends only on the
//! seed, not on the number of threads.
//!
//! Per method and physical parameter θ: mean, sample standard deviation, and, when the truth θ₀ is known,
//! bias = mean − θ₀ and RMSE = √(mean (θ̂ − θ₀)²). Failed runs are counted, not averaged.

use rand::{Rng, RngCore, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::rng::SplitMix64;
use sysid::data::Signals;
use sysid::{identify, Identification, Method};
use sysid::{Dataset, Model, ModelKind, ParamName, SysidError};
use sysid_core::param::{Layout, Parameterisation};

/// The seed of run `run` of a study seeded with `seed`: the first output of [`SplitMix64`] started from
/// seed ⊕ (run·0x9E3779B97F4A7C15 + 0xD1B54A32D192ED03), so that neighbouring seeds and runs give
/// unrelated streams.
pub fn run_seed(seed: u64, run: usize) -> u64 {
    SplitMix64::new(
        seed ^ (run as u64)
            .wrapping_mul(0x9E37_79B9_7F4A_7C15)
            .wrapping_add(0xD1B5_4A32_D192_ED03),
    )
    .next_u64()
}

/// Settings of a study.
#[derive(Debug, Clone)]
pub struct StudySettings {
    /// Number of runs R.
    pub runs: usize,
    /// Study seed.
    pub seed: u64,
    /// σ: standard deviation of the white output noise (units of y, mm for the IPA).
    pub noise_std: f64,
    /// Methods compared on every run.
    pub methods: Vec<Method>,
    /// Estimator settings (structure, forgetting...); the method is replaced by each of `methods`.
    pub base: Identification,
    /// Sampling period Ts in s of the records.
    pub ts_s: f64,
}

/// Statistics of one parameter under one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamStats {
    /// Parameter name (b_l, b_r, m_l, m_r, a1.., b1.., c).
    pub name: ParamName,
    /// The true value, when known.
    pub truth: Option<f64>,
    /// Mean of the estimates.
    pub mean: f64,
    /// Sample standard deviation of the estimates (n − 1 in the denominator; 0 for one run).
    pub std: f64,
    /// mean − truth.
    pub bias: Option<f64>,
    /// √(mean (θ̂ − truth)²).
    pub rmse: Option<f64>,
}

/// The results of one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodStats {
    /// The method.
    pub method: Method,
    /// Runs that produced an estimate.
    pub ok_runs: usize,
    /// Runs that failed, with the first error message.
    pub failed_runs: usize,
    /// The first failure's message.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_error: Option<String>,
    /// Per parameter.
    pub params: Vec<ParamStats>,
}

/// The whole study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyReport {
    /// Runs.
    pub runs: usize,
    /// Seed.
    pub seed: u64,
    /// σ of the output noise.
    pub noise_std: f64,
    /// Per method.
    pub methods: Vec<MethodStats>,
}

/// One parameter's value in the physical layout, by name.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NamedValue {
    /// The parameter (b_l, b_r, m_l, m_r, a1.., b2.. or b1.., c).
    pub name: ParamName,
    /// Its value (counts for b_l, b_r; dimensionless otherwise).
    pub value: f64,
}

/// The true physical parameters of a model, by name, in the order of
/// [`Parameterisation`] with [`Layout::Physical`] (b1 of a Hammerstein model is fixed at 1 and left out).
pub fn truth_of(model: &Model) -> Vec<NamedValue> {
    Parameterisation::of_model(model, Layout::Physical)
        .named_vector_of(model)
        .into_iter()
        .map(|(name, value)| NamedValue { name, value })
        .collect()
}

/// What one method gave on one run: its estimates, or the failure's message.
type Outcome = Result<Vec<NamedValue>, String>;

/// Mean, sample standard deviation and, against `truth`, bias and RMSE of the estimates `vals` of one
/// parameter.
fn param_stats(name: ParamName, vals: &[f64], truth: Option<f64>) -> ParamStats {
    let n = vals.len().max(1) as f64;
    let mean = vals.iter().sum::<f64>() / n;
    let std = if vals.len() > 1 {
        (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (vals.len() - 1) as f64).sqrt()
    } else {
        0.0
    };
    ParamStats {
        name,
        truth,
        mean,
        std,
        bias: truth.map(|t| mean - t),
        rmse: truth.map(|t| (vals.iter().map(|v| (v - t).powi(2)).sum::<f64>() / n).sqrt()),
    }
}

/// An experiment: (run index, run seed) → (u, noise-free y), or a message.
pub type Experiment = dyn Fn(usize, u64) -> Result<(Vec<f64>, Vec<f64>), String> + Sync;

/// Runs the study. `experiment(run, run_seed)` returns (u, noise-free y); `truth` the true parameters
/// when known; `progress` is called after each run.
pub fn study(
    st: &StudySettings,
    truth: Option<&[NamedValue]>,
    experiment: &Experiment,
    progress: &(dyn Fn() + Sync),
) -> Result<StudyReport, SysidError> {
    if st.runs == 0 || st.runs > 1_000_000 {
        return Err(SysidError::setting(
            sysid::Setting::Other("--runs"),
            st.runs,
            "between 1 and 1000000 runs",
        ));
    }
    if !(st.noise_std.is_finite() && st.noise_std >= 0.0) {
        return Err(SysidError::setting(
            sysid::Setting::Other("--noise-std"),
            st.noise_std,
            "a finite standard deviation >= 0",
        ));
    }
    if st.methods.is_empty() {
        return Err(SysidError::setting(
            sysid::Setting::Other("--method"),
            "",
            "at least one of ls, rls, iv, oe",
        ));
    }
    for m in &st.methods {
        st.base.clone().with_method(*m).check()?;
    }
    // results[run][method]: the outcome of that method on that run.
    let hammer = st.base.structure.kind == ModelKind::Hammerstein;
    let results: Vec<Vec<Outcome>> = (0..st.runs)
        .into_par_iter()
        .map(|r| {
            let seed = run_seed(st.seed, r);
            let out = match experiment(r, seed) {
                Err(e) => st
                    .methods
                    .iter()
                    .map(|_| Err(format!("run {r}: experiment: {e}")))
                    .collect(),
                Ok((u, y0)) => {
                    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x006E_6F69_7365);
                    let y: Vec<f64> = y0
                        .iter()
                        .map(|v| v + st.noise_std * rng.sample::<f64, _>(StandardNormal))
                        .collect();
                    match Dataset::new(Signals { u, y }, st.ts_s, format!("run {r}")) {
                        Err(e) => st.methods.iter().map(|_| Err(e.to_string())).collect(),
                        Ok(data) => st
                            .methods
                            .iter()
                            .map(|m| {
                                identify(&data, &st.base.clone().with_method(*m))
                                    .map(|f| {
                                        f.params
                                            .into_iter()
                                            .filter(|p| !(hammer && p.name == ParamName::B(1)))
                                            .map(|p| NamedValue {
                                                name: p.name,
                                                value: p.value,
                                            })
                                            .collect()
                                    })
                                    .map_err(|e| format!("run {r}: {e}"))
                            })
                            .collect(),
                    }
                }
            };
            progress();
            out
        })
        .collect();
    let mut methods = Vec::new();
    for (mi, m) in st.methods.iter().enumerate() {
        let ok: Vec<&Vec<NamedValue>> =
            results.iter().filter_map(|r| r[mi].as_ref().ok()).collect();
        let errors: Vec<&String> = results
            .iter()
            .filter_map(|r| r[mi].as_ref().err())
            .collect();
        let names: Vec<ParamName> = ok
            .first()
            .map(|v| v.iter().map(|p| p.name).collect())
            .unwrap_or_default();
        let find =
            |v: &[NamedValue], name: ParamName| v.iter().find(|p| p.name == name).map(|p| p.value);
        let params = names
            .iter()
            .map(|&name| {
                let vals: Vec<f64> = ok.iter().filter_map(|v| find(v, name)).collect();
                param_stats(name, &vals, truth.and_then(|t| find(t, name)))
            })
            .collect();
        methods.push(MethodStats {
            method: *m,
            ok_runs: ok.len(),
            failed_runs: errors.len(),
            first_error: errors.first().map(|e| e.to_string()),
            params,
        });
    }
    Ok(StudyReport {
        runs: st.runs,
        seed: st.seed,
        noise_std: st.noise_std,
        methods,
    })
}

impl StudyReport {
    /// A plain-text table: per method, per parameter, truth, mean, bias, std, RMSE.
    pub fn to_text(&self) -> String {
        use report::format::num;
        use std::fmt::Write;
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Monte Carlo: {} runs, seed {}, output noise std {}",
            self.runs,
            self.seed,
            num(self.noise_std)
        );
        for m in &self.methods {
            let _ = writeln!(
                s,
                "\nmethod {} ({} ok, {} failed)",
                m.method, m.ok_runs, m.failed_runs
            );
            if let Some(e) = &m.first_error {
                let _ = writeln!(s, "  first failure: {e}");
            }
            let _ = writeln!(
                s,
                "  {:<6}{:>14}{:>14}{:>14}{:>14}{:>14}",
                "param", "truth", "mean", "bias", "std", "RMSE"
            );
            let o = |v: Option<f64>| v.map_or_else(|| "-".to_string(), num);
            for p in &m.params {
                let _ = writeln!(
                    s,
                    "  {:<6}{:>14}{:>14}{:>14}{:>14}{:>14}",
                    p.name,
                    o(p.truth),
                    num(p.mean),
                    o(p.bias),
                    num(p.std),
                    o(p.rmse)
                );
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn experiment(_r: usize, seed: u64) -> Result<(Vec<f64>, Vec<f64>), String> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let u: Vec<f64> = (0..300).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let mut y = vec![0.0; 300];
        for k in 1..300 {
            y[k] = 0.5 * y[k - 1] + 2.0 * u[k - 1];
        }
        Ok((u, y))
    }

    fn settings(noise: f64) -> StudySettings {
        StudySettings {
            runs: 6,
            seed: 11,
            noise_std: noise,
            methods: vec![Method::Ls, Method::Oe],
            base: Identification::default()
                .with_kind(ModelKind::Arx)
                .with_orders(1, 1, 1),
            ts_s: 1.0,
        }
    }

    // The truth of the paper's model is its Table III "actual" column normalised to b1 = 1 (slopes times
    // b1 = 15.67e-4), without the fixed b1.
    #[test]
    fn truth_of_the_paper_model_is_table_iii_without_b1() {
        let b1 = 15.67e-4;
        let want = [
            ("b_l", -1.50),
            ("b_r", 1.41),
            ("m_l", 3.46 * b1),
            ("m_r", 2.38 * b1),
            ("a1", -1.869),
            ("a2", 0.9976),
            ("a3", -0.1284),
        ];
        let got = truth_of(&Model::paper());
        assert_eq!(got.len(), want.len());
        for (g, (name, value)) in got.iter().zip(want) {
            assert_eq!(g.name.to_string(), name);
            assert!((g.value - value).abs() < 1e-12, "{name}: {}", g.value);
        }
    }

    // Noise-free ARX records: every run recovers a1 = −0.5, b1 = 2 exactly: bias, std and RMSE are 0.
    #[test]
    fn noise_free_runs_have_no_bias_and_no_spread() {
        let truth = [(ParamName::A(1), -0.5), (ParamName::B(1), 2.0)]
            .map(|(name, value)| NamedValue { name, value });
        let r = study(&settings(0.0), Some(&truth), &experiment, &|| {}).unwrap();
        for m in &r.methods {
            assert_eq!(m.ok_runs, 6);
            for p in &m.params {
                assert!(
                    p.bias.unwrap().abs() < 1e-9 && p.std < 1e-9 && p.rmse.unwrap() < 1e-9,
                    "{p:?}"
                );
            }
        }
    }

    // RMSE² = bias² + (n−1)/n · std² for any sample (the identity behind the table).
    #[test]
    fn rmse_squared_is_bias_squared_plus_biased_variance() {
        let truth = [(ParamName::A(1), -0.5), (ParamName::B(1), 2.0)]
            .map(|(name, value)| NamedValue { name, value });
        let r = study(&settings(0.3), Some(&truth), &experiment, &|| {}).unwrap();
        for p in &r.methods[0].params {
            let lhs = p.rmse.unwrap().powi(2);
            let rhs = p.bias.unwrap().powi(2) + 5.0 / 6.0 * p.std.powi(2);
            assert!((lhs - rhs).abs() < 1e-12 * (1.0 + lhs), "{p:?}");
        }
        // The same seed gives the same report.
        assert_eq!(
            r,
            study(&settings(0.3), Some(&truth), &experiment, &|| {}).unwrap()
        );
    }
}
