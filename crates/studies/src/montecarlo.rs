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
//!
//! One wild run (an estimator that diverged on one unlucky record) dominates a mean and a standard
//! deviation, so each parameter also has its median and robust standard deviation 1.4826 · MAD (the
//! median absolute deviation, scaled to equal σ for a normal sample), and the runs more than
//! [`OUTLIER_ROBUST_STDS`] robust standard deviations from the median are counted as outliers; the
//! report's `warnings` say when a method has any (its mean, std and RMSE are then not to be read), and
//! how many of its runs' identifications carried warnings of their own.

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

/// An estimate further than this many robust standard deviations (1.4826 · MAD) from the median is an
/// outlier. A normal sample has none beyond 10 σ (probability 1.5e-23 per run).
pub const OUTLIER_ROBUST_STDS: f64 = 10.0;

/// Statistics of one parameter under one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParamStats {
    /// Parameter name (b_l, b_r, m_l, m_r, a1.., b1.., c).
    pub name: ParamName,
    /// The true value, when known.
    pub truth: Option<f64>,
    /// Mean of the estimates.
    pub mean: f64,
    /// Sample standard deviation of the estimates (n − 1 in the denominator); `None` (JSON null) for
    /// fewer than two runs, where it is undefined, not 0 (audit s30 M-7).
    pub std: Option<f64>,
    /// mean − truth.
    pub bias: Option<f64>,
    /// √(mean (θ̂ − truth)²).
    pub rmse: Option<f64>,
    /// Median of the estimates.
    pub median: f64,
    /// Robust standard deviation 1.4826 · median |θ̂ − median|; `None` for fewer than two runs.
    pub robust_std: Option<f64>,
    /// Estimates further than [`OUTLIER_ROBUST_STDS`] robust standard deviations from the median (none
    /// when the robust std is 0).
    pub outliers: usize,
    /// The estimate furthest from the median, when there are outliers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub worst_outlier: Option<f64>,
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
    /// Runs whose identification gave an estimate with warnings of its own (as `identify` prints).
    pub warned_runs: usize,
    /// The first of those warnings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_warning: Option<String>,
    /// The first failure's message.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub first_error: Option<String>,
    /// Per parameter.
    pub params: Vec<ParamStats>,
}

/// What a study simulated and estimated, for its report (audit s35b L-21: the JSON had neither, so two
/// studies' files were told apart only by their numbers). Set by the caller that made the records.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyExperiment {
    /// The plant (`paper`, `ipa`, `model:FILE`).
    pub plant: String,
    /// The input design (`staircase`, `prbs`, …, `file:CSV`).
    pub input: String,
    /// Its amplitude (PWM counts).
    pub amplitude: f64,
    /// Samples per run.
    pub samples: usize,
    /// Ts in s.
    pub ts_s: f64,
    /// The estimated structure (`hammerstein`, `arx`, …).
    pub structure: String,
    /// Its orders.
    pub na: usize,
    /// Its orders.
    pub nb: usize,
    /// Its orders.
    pub nk: usize,
    /// With a constant term.
    pub offset: bool,
}

/// The whole study.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StudyReport {
    /// What was simulated and estimated (`None` until the caller sets it; JSON `null`).
    pub experiment: Option<StudyExperiment>,
    /// Runs.
    pub runs: usize,
    /// Seed.
    pub seed: u64,
    /// σ of the output noise.
    pub noise_std: f64,
    /// Per method.
    pub methods: Vec<MethodStats>,
    /// What makes parts of the table untrustworthy: outliers that dominate a method's mean and std,
    /// runs whose identification was warned.
    pub warnings: Vec<String>,
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

/// What one method gave on one run: its estimates and the first warning of the identification, or the
/// failure's message.
type Outcome = Result<(Vec<NamedValue>, Option<String>), String>;

/// The median of `v` (sorted in place; NaN-free values), 0 for none.
pub fn median_of(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Mean, sample standard deviation and, against `truth`, bias and RMSE of the estimates `vals` of one
/// parameter.
fn param_stats(name: ParamName, vals: &[f64], truth: Option<f64>) -> ParamStats {
    let n = vals.len().max(1) as f64;
    let mean = vals.iter().sum::<f64>() / n;
    let spread = vals.len() > 1;
    let std = spread.then(|| {
        (vals.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (vals.len() - 1) as f64).sqrt()
    });
    let median = median_of(&mut vals.to_vec());
    let robust_std = spread.then(|| {
        1.4826 * median_of(&mut vals.iter().map(|v| (v - median).abs()).collect::<Vec<_>>())
    });
    let r = robust_std.unwrap_or(0.0);
    let far = |v: &f64| r > 0.0 && (v - median).abs() > OUTLIER_ROBUST_STDS * r;
    let outliers = vals.iter().filter(|v| far(v)).count();
    let worst_outlier = vals
        .iter()
        .copied()
        .filter(far)
        .max_by(|a, b| (a - median).abs().total_cmp(&(b - median).abs()));
    ParamStats {
        name,
        truth,
        mean,
        std,
        bias: truth.map(|t| mean - t),
        rmse: truth.map(|t| (vals.iter().map(|v| (v - t).powi(2)).sum::<f64>() / n).sqrt()),
        median,
        robust_std,
        outliers,
        worst_outlier,
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
                                        let warned = f.warnings.first().map(|w| w.to_string());
                                        let values = f
                                            .params
                                            .into_iter()
                                            .filter(|p| !(hammer && p.name == ParamName::B(1)))
                                            .map(|p| NamedValue {
                                                name: p.name,
                                                value: p.value,
                                            })
                                            .collect();
                                        (values, warned)
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
    let mut warnings = Vec::new();
    for (mi, m) in st.methods.iter().enumerate() {
        let ok_runs: Vec<&(Vec<NamedValue>, Option<String>)> =
            results.iter().filter_map(|r| r[mi].as_ref().ok()).collect();
        let ok: Vec<&Vec<NamedValue>> = ok_runs.iter().map(|(v, _)| v).collect();
        let warned: Vec<&String> = ok_runs.iter().filter_map(|(_, w)| w.as_ref()).collect();
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
        let params: Vec<ParamStats> = names
            .iter()
            .map(|&name| {
                let vals: Vec<f64> = ok.iter().filter_map(|v| find(v, name)).collect();
                param_stats(name, &vals, truth.and_then(|t| find(t, name)))
            })
            .collect();
        let wild: Vec<String> = params
            .iter()
            .filter(|p| p.outliers > 0)
            .map(|p| {
                format!(
                    "{} in {} run(s) (the furthest {}; median {}, robust std {})",
                    p.name,
                    p.outliers,
                    report::format::num(p.worst_outlier.unwrap_or(f64::NAN)),
                    report::format::num(p.median),
                    report::format::num(p.robust_std.unwrap_or(f64::NAN))
                )
            })
            .collect();
        if !wild.is_empty() {
            warnings.push(format!(
                "method {m}: outliers more than {OUTLIER_ROBUST_STDS} robust standard deviations (1.4826 MAD) \
                 from the median: {}; its mean, std, bias and RMSE include them and may be far off: read the \
                 median and the robust std",
                wild.join("; ")
            ));
        }
        if ok.len() < 2 && !params.is_empty() {
            warnings.push(format!(
                "method {m}: {} run(s) gave an estimate: a spread (std, robust std) needs at least two, \
                 so it is n/a, and the bias is one run's error, not the method's (run more: --runs)",
                ok.len()
            ));
        }
        if let Some(w) = warned.first() {
            warnings.push(format!(
                "method {m}: {} of {} runs' estimates carried warnings of their own, which the table \
                 averages in (the first: {w})",
                warned.len(),
                ok.len()
            ));
        }
        methods.push(MethodStats {
            method: *m,
            ok_runs: ok.len(),
            failed_runs: errors.len(),
            first_error: errors.first().map(|e| e.to_string()),
            warned_runs: warned.len(),
            first_warning: warned.first().map(|w| w.to_string()),
            params,
        });
    }
    Ok(StudyReport {
        experiment: None,
        runs: st.runs,
        seed: st.seed,
        noise_std: st.noise_std,
        methods,
        warnings,
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
                "  {:<6}{:>14}{:>14}{:>14}{:>14}{:>14}{:>14}{:>14}",
                "param", "truth", "mean", "bias", "std", "RMSE", "median", "robust std"
            );
            let o = |v: Option<f64>| v.map_or_else(|| "-".to_string(), num);
            for p in &m.params {
                let _ = writeln!(
                    s,
                    "  {:<6}{:>14}{:>14}{:>14}{:>14}{:>14}{:>14}{:>14}{}",
                    p.name,
                    o(p.truth),
                    num(p.mean),
                    o(p.bias),
                    o(p.std),
                    o(p.rmse),
                    num(p.median),
                    o(p.robust_std),
                    if p.outliers > 0 {
                        format!("  ({} outlier(s))", p.outliers)
                    } else {
                        String::new()
                    }
                );
            }
        }
        for w in &self.warnings {
            let _ = writeln!(s, "warning: {w}");
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
                    p.bias.unwrap().abs() < 1e-9 && p.std.unwrap() < 1e-9 && p.rmse.unwrap() < 1e-9,
                    "{p:?}"
                );
            }
        }
    }

    // Audit s30 M-7: one estimate has no spread (n − 1 = 0): std and robust std are n/a, not 0.
    #[test]
    fn one_run_has_no_spread() {
        let p = param_stats(ParamName::A(1), &[2.5], Some(3.0));
        assert_eq!(
            (p.std, p.robust_std, p.mean, p.bias),
            (None, None, 2.5, Some(-0.5))
        );
        let q = param_stats(ParamName::A(1), &[2.0, 4.0], None);
        // Two values: s = √((1 + 1)/1) = √2; MAD = median(1, 1) = 1.
        assert_eq!(q.std, Some(2f64.sqrt()));
        assert_eq!(q.robust_std, Some(1.4826));
    }

    // Median and robust std by hand: values 1, 2, 3, 4, 100 have median 3, absolute deviations
    // 2, 1, 0, 1, 97 (median 1), so robust std 1.4826; 100 is 97 / 1.4826 = 65 robust stds away.
    #[test]
    fn median_robust_std_and_outliers_by_hand() {
        let p = param_stats(ParamName::A(1), &[4.0, 100.0, 1.0, 3.0, 2.0], Some(3.0));
        assert_eq!(p.median, 3.0);
        assert!((p.robust_std.unwrap() - 1.4826).abs() < 1e-12);
        assert_eq!((p.outliers, p.worst_outlier), (1, Some(100.0)));
        assert_eq!(p.mean, 22.0);
        // Equal values: robust std 0, no outliers (nothing to scale by).
        let q = param_stats(ParamName::A(1), &[2.0, 2.0, 2.0, 7.0], None);
        assert_eq!((q.median, q.robust_std, q.outliers), (2.0, Some(0.0), 0));
    }

    // One run whose input is 1e6 times smaller (b1 is then not determined: noise / 1e-6) is an
    // outlier of b1 that the mean follows; the report says so and the median stays near the truth.
    #[test]
    fn one_wild_run_is_named_and_the_median_is_not_moved() {
        let wild = |r: usize, seed: u64| {
            let (u, _) = experiment(r, seed)?;
            let scale = if r == 3 { 1e-6 } else { 1.0 };
            let u: Vec<f64> = u.iter().map(|v| v * scale).collect();
            let mut y = vec![0.0; u.len()];
            for k in 1..u.len() {
                y[k] = 0.5 * y[k - 1] + 2.0 * u[k - 1];
            }
            Ok((u, y))
        };
        let mut st = settings(0.1);
        st.runs = 12;
        st.methods = vec![Method::Ls];
        let r = study(&st, None, &wild, &|| {}).unwrap();
        let b1 = r.methods[0]
            .params
            .iter()
            .find(|p| p.name == ParamName::B(1))
            .unwrap();
        assert_eq!(b1.outliers, 1, "{b1:?}");
        assert!((b1.median - 2.0).abs() < 0.05, "{b1:?}");
        assert!(b1.std.unwrap() > 100.0 * b1.robust_std.unwrap(), "{b1:?}");
        assert!(
            r.warnings
                .iter()
                .any(|w| w.contains("method ls: outliers") && w.contains("b1 in 1 run(s)")),
            "{:?}",
            r.warnings
        );
        // Without the wild run: no outlier, no warning.
        let r = study(&st, None, &experiment, &|| {}).unwrap();
        assert!(r.methods[0].params.iter().all(|p| p.outliers == 0));
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    }

    // RMSE² = bias² + (n−1)/n · std² for any sample (the identity behind the table).
    #[test]
    fn rmse_squared_is_bias_squared_plus_biased_variance() {
        let truth = [(ParamName::A(1), -0.5), (ParamName::B(1), 2.0)]
            .map(|(name, value)| NamedValue { name, value });
        let r = study(&settings(0.3), Some(&truth), &experiment, &|| {}).unwrap();
        for p in &r.methods[0].params {
            let lhs = p.rmse.unwrap().powi(2);
            let rhs = p.bias.unwrap().powi(2) + 5.0 / 6.0 * p.std.unwrap().powi(2);
            assert!((lhs - rhs).abs() < 1e-12 * (1.0 + lhs), "{p:?}");
        }
        // The same seed gives the same report.
        assert_eq!(
            r,
            study(&settings(0.3), Some(&truth), &experiment, &|| {}).unwrap()
        );
    }
}
