//! Benchmarks of the kernels that matter for speed: the RLS update, a full Hammerstein identification
//! and a plant simulation. The `ipa-sysid bench` subcommand is a thin front end to these functions.
//!
//! Every figure is measured as: one untimed warm-up run, then `repetitions` timed runs; the report gives
//! the best run (the least disturbed by other processes on the machine) and the median. Runs shorter
//! than about 20 ms are batched (a run repeats the work until it has taken at least that long) so that
//! the clock's resolution does not matter.

use std::hint::black_box;
use std::time::{Duration, Instant};

use rand::{Rng, RngCore};
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use crate::rng::SplitMix64;
use sysid::data::Signals;
use sysid::rls::{flops_per_update, ReferenceRls, Rls, RlsN};
use sysid::{identify, Estimator, Identification, Method};
use sysid::{Dataset, Model, ModelKind, ModelPlant, Plant, SysidError};

/// Shortest timed run; shorter work is repeated within one run until it takes at least this long.
pub const MIN_RUN: Duration = Duration::from_millis(20);

/// Best and median of the timed runs, in seconds per unit of work (one update, one identification…).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    /// Fastest run, seconds per unit.
    pub best_s: f64,
    /// Median run, seconds per unit.
    pub median_s: f64,
    /// Number of timed runs.
    pub repetitions: usize,
    /// Units of work per timed run.
    pub units_per_run: usize,
    /// CPU time of the calling thread, seconds per unit, in the run that used the least: on a machine
    /// shared with other jobs the wall clock also counts the time the thread waited for a core.
    pub best_cpu_s: f64,
}

/// CPU time consumed by the calling thread so far (`CLOCK_THREAD_CPUTIME_ID`), s; NaN if the clock
/// cannot be read.
fn thread_cpu_seconds() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes one timespec through a valid, exclusive pointer.
    let r = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    if r == 0 {
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

/// Times `work`, which performs `units` units of work per call: one warm-up call, then `repetitions`
/// timed runs of as many calls as needed to last [`MIN_RUN`] (at least one call).
pub fn time_it<E>(
    repetitions: usize,
    units: usize,
    mut work: impl FnMut() -> Result<(), E>,
) -> Result<Timing, E> {
    let repetitions = repetitions.max(1);
    let t0 = Instant::now();
    work()?;
    let once = t0.elapsed().as_secs_f64().max(1e-9);
    let calls = ((MIN_RUN.as_secs_f64() / once).ceil() as usize).clamp(1, 1_000_000);
    let mut per_unit = Vec::with_capacity(repetitions);
    let mut best_cpu = f64::INFINITY;
    let per_run = (calls * units.max(1)) as f64;
    for _ in 0..repetitions {
        let c = thread_cpu_seconds();
        let t = Instant::now();
        for _ in 0..calls {
            work()?;
        }
        per_unit.push(t.elapsed().as_secs_f64() / per_run);
        best_cpu = best_cpu.min((thread_cpu_seconds() - c) / per_run);
    }
    per_unit.sort_by(f64::total_cmp);
    Ok(Timing {
        best_s: per_unit[0],
        median_s: per_unit[per_unit.len() / 2],
        repetitions,
        units_per_run: calls * units.max(1),
        best_cpu_s: best_cpu,
    })
}

/// A deterministic staircase input in PWM counts: integer levels uniform in [−`amplitude_counts`,
/// `amplitude_counts`] held for 10..=50 samples (0.1–0.5 s at Ts = 0.01 s, like the paper's "continuous
/// step signal"). Used where the richer experiment design of the `ipa` crate is not available.
pub fn staircase(samples: usize, amplitude_counts: f64, seed: u64) -> Vec<f64> {
    let mut rng = SplitMix64::new(seed);
    let a = amplitude_counts.abs().floor();
    let mut u = Vec::with_capacity(samples);
    while u.len() < samples {
        let level = (rng.range(-a, a + 1.0)).floor().min(a);
        let hold = 10 + (rng.next_u64() % 41) as usize;
        for _ in 0..hold.min(samples - u.len()) {
            u.push(level);
        }
    }
    u
}

/// The paper's experiment on its "actual" model ([`Model::paper`], Ts = 0.01 s): the output y (mm) of
/// the model driven by `u` (counts) from rest, plus white measurement noise of standard deviation
/// `noise_std_mm` (seeded, Gaussian).
pub fn paper_experiment(u: &[f64], noise_std_mm: f64, seed: u64) -> Result<Dataset, SysidError> {
    if !(noise_std_mm.is_finite() && noise_std_mm >= 0.0) {
        return Err(SysidError::setting(
            sysid::Setting::Other("--noise"),
            noise_std_mm,
            "a standard deviation >= 0 in mm",
        ));
    }
    let model = Model::paper();
    let ts = model.ts();
    let mut plant = ModelPlant::new(model, "paper model")?;
    let mut y = sysid::plant::run_open_loop(&mut plant, u)?;
    let mut rng = SplitMix64::new(seed ^ 0x5EED);
    for v in &mut y {
        *v += noise_std_mm * rng.sample::<f64, _>(StandardNormal);
    }
    Dataset::new(Signals { u: u.to_vec(), y }, ts, "paper model experiment")
}

/// Result of [`bench_rls`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RlsBench {
    /// n: number of parameters.
    pub params: usize,
    /// Updates per timed run.
    pub samples: usize,
    /// ρ: forgetting factor used.
    pub forgetting: f64,
    /// Updates per second of [`Rls::update`] (heap storage, the estimators' path), best run.
    pub samples_per_second: f64,
    /// The same, median run.
    pub median_samples_per_second: f64,
    /// Nanoseconds per update, best run.
    pub ns_per_update: f64,
    /// Updates per second of the array-backed [`RlsN`] (n ≤ [`sysid::rls::MAX_FIXED`] only), best run.
    pub fixed_samples_per_second: Option<f64>,
    /// Updates per second of the plain loop [`ReferenceRls`], best run.
    pub reference_samples_per_second: f64,
    /// Flops per update ([`flops_per_update`]).
    pub flops_per_update: f64,
    /// flops_per_update × samples_per_second / 1e9.
    pub gflops: f64,
    /// Timed runs.
    pub repetitions: usize,
}

/// Regressors and outputs for the RLS benchmark: `ring` regressors (uniform in [−1, 1]) and
/// y = φᵀθ* + 0.01·e, cycled through by the timed loop.
fn rls_data(n: usize, ring: usize, seed: u64) -> (Vec<f64>, Vec<f64>) {
    let mut rng = SplitMix64::new(seed);
    let truth: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
    let mut phi = Vec::with_capacity(ring * n);
    let mut y = Vec::with_capacity(ring);
    for _ in 0..ring {
        let row: Vec<f64> = (0..n).map(|_| rng.range(-1.0, 1.0)).collect();
        y.push(
            row.iter().zip(&truth).map(|(a, b)| a * b).sum::<f64>()
                + 0.01 * rng.sample::<f64, _>(StandardNormal),
        );
        phi.extend(row);
    }
    (phi, y)
}

/// Measures RLS throughput for `params` parameters over `samples` updates per run (random regressors
/// cycled from a ring of 1024, so the data stay in the L1/L2 cache and the update itself is measured).
pub fn bench_rls(
    params: usize,
    samples: usize,
    forgetting: f64,
    repetitions: usize,
) -> Result<RlsBench, SysidError> {
    if params == 0 || params > 1000 {
        return Err(SysidError::setting(
            sysid::Setting::Other("--params"),
            params,
            "between 1 and 1000 parameters",
        ));
    }
    if samples == 0 {
        return Err(SysidError::setting(
            sysid::Setting::Other("--samples"),
            samples,
            "at least one update",
        ));
    }
    sysid::rls::check_settings(forgetting, 1e3)?;
    let (phi, y) = rls_data(params, 1024, 42 + params as u64);
    let rows = || {
        phi.chunks_exact(params)
            .zip(y.iter().copied())
            .cycle()
            .take(samples)
    };
    let fast = time_it(repetitions, samples, || {
        let mut est = Rls::new(params, forgetting, 1e3)?;
        for (k, (row, yk)) in rows().enumerate() {
            black_box(est.update(black_box(row), yk, k)?);
        }
        black_box(est.theta());
        Ok::<(), SysidError>(())
    })?;
    let reference = time_it(repetitions, samples, || {
        let mut est = ReferenceRls::new(params, forgetting, 1e3)?;
        for (k, (row, yk)) in rows().enumerate() {
            black_box(est.update(black_box(row), yk, k)?);
        }
        black_box(&est.theta);
        Ok::<(), SysidError>(())
    })?;
    let fixed = bench_fixed(params, &phi, &y, samples, forgetting, repetitions)?;
    let flops = flops_per_update(params, forgetting);
    Ok(RlsBench {
        params,
        samples,
        forgetting,
        samples_per_second: 1.0 / fast.best_s,
        median_samples_per_second: 1.0 / fast.median_s,
        ns_per_update: fast.best_s * 1e9,
        fixed_samples_per_second: fixed.map(|t| 1.0 / t.best_s),
        reference_samples_per_second: 1.0 / reference.best_s,
        flops_per_update: flops,
        gflops: flops / fast.best_s / 1e9,
        repetitions: fast.repetitions,
    })
}

/// Times [`RlsN`] for n ≤ [`sysid::rls::MAX_FIXED`] (a compile-time size chosen at run time).
fn bench_fixed(
    params: usize,
    phi: &[f64],
    y: &[f64],
    samples: usize,
    forgetting: f64,
    repetitions: usize,
) -> Result<Option<Timing>, SysidError> {
    fn run<const N: usize>(
        phi: &[f64],
        y: &[f64],
        samples: usize,
        forgetting: f64,
        repetitions: usize,
    ) -> Result<Timing, SysidError> {
        let rows: Vec<[f64; N]> = phi
            .chunks_exact(N)
            .map(|c| std::array::from_fn(|i| c[i]))
            .collect();
        time_it(repetitions, samples, || {
            let mut est = RlsN::<N>::new(forgetting, 1e3)?;
            for (k, (row, yk)) in rows
                .iter()
                .zip(y.iter().copied())
                .cycle()
                .take(samples)
                .enumerate()
            {
                black_box(est.update(black_box(row), yk, k)?);
            }
            black_box(est.theta());
            Ok(())
        })
    }
    macro_rules! dispatch {
        ($($k:literal)*) => {
            match params {
                $($k => Some(run::<$k>(phi, y, samples, forgetting, repetitions)?),)*
                _ => None,
            }
        };
    }
    Ok(dispatch!(1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16))
}

/// Result of [`bench_identify`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct IdentifyBench {
    /// Estimator.
    pub method: Method,
    /// Samples in the record.
    pub samples: usize,
    /// Wall time of one full identification (settings check, estimation, standard deviations), best run.
    pub seconds_per_identification: f64,
    /// The same, median run.
    pub median_seconds_per_identification: f64,
    /// CPU time of one identification (the timing thread's), the run that used the least.
    pub cpu_seconds_per_identification: f64,
    /// Key-term iterations (LS) or passes (RLS) the identification took.
    pub iterations: usize,
    /// Whether the estimator reported convergence.
    pub converged: bool,
    /// Timed runs.
    pub repetitions: usize,
}

/// Times a full identification of `data` with `settings` (the same call as `ipa-sysid identify`, without
/// reading files or computing validation metrics).
pub fn bench_identify(
    data: &Dataset,
    settings: &Identification,
    repetitions: usize,
) -> Result<IdentifyBench, SysidError> {
    let fit = identify(data, settings)?;
    let t = time_it(repetitions, 1, || {
        black_box(identify(black_box(data), settings)?);
        Ok::<(), SysidError>(())
    })?;
    Ok(IdentifyBench {
        method: settings.estimator.method(),
        samples: data.len(),
        seconds_per_identification: t.best_s,
        median_seconds_per_identification: t.median_s,
        cpu_seconds_per_identification: t.best_cpu_s,
        iterations: fit.iterations,
        converged: fit.converged(),
        repetitions: t.repetitions,
    })
}

/// The paper's Hammerstein structure (na = 3, nb = 1, nk = 1) with `method` and default settings.
pub fn paper_settings(method: Method) -> Identification {
    Identification::default()
        .with_kind(ModelKind::Hammerstein)
        .with_orders(3, 1, 1)
        .with_method(method)
}

/// Result of [`bench_plant`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlantBench {
    /// The plant's name.
    pub plant: String,
    /// Samples per run.
    pub samples: usize,
    /// Simulated time per run, s (samples × Ts).
    pub simulated_seconds: f64,
    /// Wall time per run, s, best run.
    pub wall_seconds: f64,
    /// Simulated seconds per wall-clock second, best run.
    pub real_time_factor: f64,
    /// The same, median run.
    pub median_real_time_factor: f64,
    /// Timed runs.
    pub repetitions: usize,
}

/// Times `plant` open loop over the commands `u` (counts), reset to its initial output before each run.
pub fn bench_plant(
    plant: &mut dyn Plant,
    u: &[f64],
    repetitions: usize,
) -> Result<PlantBench, SysidError> {
    if u.is_empty() {
        return Err(SysidError::setting(
            sysid::Setting::Other("--samples"),
            0,
            "at least one sample",
        ));
    }
    let y0 = plant.output();
    let t = time_it(repetitions, u.len(), || {
        plant.reset(y0);
        for &uk in u {
            black_box(plant.step(black_box(uk))?);
        }
        Ok::<(), SysidError>(())
    })?;
    let ts = plant.ts();
    Ok(PlantBench {
        plant: plant.name(),
        samples: u.len(),
        simulated_seconds: u.len() as f64 * ts,
        wall_seconds: t.best_s * u.len() as f64,
        real_time_factor: ts / t.best_s,
        median_real_time_factor: ts / t.median_s,
        repetitions: t.repetitions,
    })
}

/// Result of [`peak_flops`]: the machine's measured floating-point throughput on one core.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PeakFlops {
    /// GFLOP/s of independent multiply and add chains as this build compiles them (baseline x86-64:
    /// 128-bit SSE2 vectors, separate multiply and add instructions, no FMA) — the ceiling for code of
    /// this build, including the RLS kernels.
    pub gflops_build_target: f64,
    /// Nanoseconds per addition in a chain of dependent additions: the latency of one floating-point
    /// add. Divided into the add latency in cycles (3 on AMD Zen 4, 4 on Intel Skylake and later) it
    /// gives the clock frequency the benchmarks actually ran at.
    pub dependent_add_ns: f64,
}

/// Measures the floating-point ceiling of this build on one core: 24 independent accumulators
/// (12 two-lane vectors), each doing a multiply and an add per step — enough independent work to cover
/// the 3 + 3 cycle latency of the pair on the two multiply and two add pipes of a current x86 core —
/// compiled for the build's target (SSE2 unless `-C target-cpu` is set).
pub fn peak_flops(repetitions: usize) -> PeakFlops {
    const LANES: usize = 24;
    const STEPS: usize = 200_000;
    let t = time_it(repetitions, STEPS * LANES * 2, || {
        let mut acc = black_box([1.0f64; LANES]);
        let m = black_box(0.999_999_9f64);
        let c = black_box(1e-7f64);
        for _ in 0..STEPS {
            for a in acc.iter_mut() {
                *a = *a * m + c;
            }
        }
        black_box(acc);
        Ok::<(), SysidError>(())
    });
    let best = t.map(|t| t.best_s).unwrap_or(f64::NAN);
    const CHAIN: usize = 10_000_000;
    let chain = time_it(repetitions, CHAIN, || {
        let mut x = black_box(1.0f64);
        let d = black_box(1e-9f64);
        for _ in 0..CHAIN {
            x += d;
        }
        black_box(x);
        Ok::<(), SysidError>(())
    });
    PeakFlops {
        gflops_build_target: 1.0 / best / 1e9,
        dependent_add_ns: chain.map(|t| t.best_s * 1e9).unwrap_or(f64::NAN),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Levels are integers within ±A and held for at least 10 samples (except the truncated last one).
    #[test]
    fn staircase_levels_are_bounded_integers_held_ten_samples_or_more() {
        let u = staircase(3000, 255.0, 7);
        assert_eq!(u.len(), 3000);
        assert!(u.iter().all(|v| v.abs() <= 255.0 && v.fract() == 0.0));
        let mut run = 1;
        let mut runs = Vec::new();
        for k in 1..u.len() {
            if u[k] == u[k - 1] {
                run += 1;
            } else {
                runs.push(run);
                run = 1;
            }
        }
        assert!(runs.len() > 20 && runs.iter().all(|&r| r >= 10), "{runs:?}");
    }

    // With zero noise the experiment is the paper model's own response: y(k+1) = −Σ a_i y(k+1−i) + x(k).
    #[test]
    fn noise_free_paper_experiment_follows_the_difference_equation() {
        let u = staircase(400, 200.0, 3);
        let d = paper_experiment(&u, 0.0, 1).unwrap();
        let m = Model::paper();
        for (k, &uk) in u.iter().enumerate().take(399).skip(3) {
            let x = m.input_map(uk);
            let want = -m.a()[0] * d.y()[k] - m.a()[1] * d.y()[k - 1] - m.a()[2] * d.y()[k - 2] + x;
            assert!(
                (d.y()[k + 1] - want).abs() <= 1e-9 * (1.0 + want.abs()),
                "k={k}"
            );
        }
    }

    // Work that fails in the warm-up run is reported, not timed.
    #[test]
    fn failing_work_is_an_error_not_a_timing() {
        let r = time_it(3, 1, || Err::<(), _>("boom"));
        assert_eq!(r.unwrap_err(), "boom");
    }

    #[test]
    fn rls_bench_refuses_zero_parameters() {
        assert!(bench_rls(0, 10, 1.0, 1).is_err());
    }
}
