//! `ipa-sysid bench`: RLS throughput, identification time, the plant's real-time factor and output error
//! on real records (`bench_oe.rs`). The timing loops live in `sysid_studies`; this file parses flags,
//! builds the inputs and prints.

use std::path::PathBuf;

use anyhow::Context;
use serde::Serialize;
use sysid::Method;
use sysid_studies::bench::{
    bench_identify, bench_plant, bench_rls, paper_experiment, paper_settings, peak_flops,
};

use super::common::write_output;

/// Flags of `bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    #[command(subcommand)]
    pub what: What,
}

/// Which benchmark.
#[derive(Debug, clap::Subcommand)]
pub enum What {
    /// RLS updates per second on random data (fast kernel, array-backed kernel and the plain reference loop).
    Rls(RlsArgs),
    /// Seconds per full Hammerstein identification (LS and RLS) of the paper's 2000-sample experiment.
    Identify(IdentifyArgs),
    /// Real-time factor of a plant simulation (simulated seconds per wall-clock second).
    Plant(PlantArgs),
    /// Seconds, iterations and fit of output-error identification on the EMPS and silverbox records
    /// (`--peer PYTHON`: SysIdentPy's FROLS on the same records in the same run).
    Oe(super::bench_oe::OeArgs),
    /// Seconds and test RMSE of polynomial NARX identification on real records (cascaded tanks,
    /// silverbox, coupled drives, hydraulic actuator; `--peer PYTHON`: SysIdentPy's FROLS in the same run).
    Narx(super::bench_narx::NarxArgs),
    /// Rows per second and peak memory of the streaming identification of long records (child
    /// processes), beside the in-memory path and a numpy least-squares peer in the same run.
    Long(LongArgs),
}

/// Record lengths (`--rows 1e6,1e7`).
#[derive(Debug, Clone, PartialEq)]
pub struct RowsList(pub Vec<usize>);

/// Parses `--rows 1000000,10000000` (each at least 10).
fn parse_rows_list(text: &str) -> Result<RowsList, String> {
    text.split(',')
        .map(|t| {
            let t = t.trim().replace('_', "");
            let v = t
                .parse::<f64>()
                .ok()
                .filter(|v| v.fract() == 0.0 && *v >= 10.0 && *v <= 1e9)
                .ok_or_else(|| {
                    format!("'{t}': expected a number of rows between 10 and 1e9, such as 1e6")
                })?;
            Ok(v as usize)
        })
        .collect::<Result<_, _>>()
        .map(RowsList)
}

/// Flags of `bench long`.
#[derive(Debug, clap::Args)]
pub struct LongArgs {
    /// Record lengths N (comma-separated; 1e6 accepted).
    #[arg(long, default_value = "1e6,1e7", value_parser = parse_rows_list, value_name = "N,...")]
    pub rows: RowsList,
    /// Folder for the records and logs (default: a new folder in the system's temporary folder, removed
    /// afterwards). A record of 1e7 rows takes about 310 MB.
    #[arg(long, value_name = "DIR")]
    pub dir: Option<PathBuf>,
    /// Also time the in-memory path (`--stream off`) on records of at most this many rows (it needs
    /// about 250 bytes per row).
    #[arg(long, default_value_t = 1_000_000, value_name = "N")]
    pub in_memory_max: usize,
    /// Python interpreter with numpy for the peer.
    #[arg(long, default_value = "python3", value_name = "PYTHON")]
    pub python: PathBuf,
    /// The numpy peer script.
    #[arg(
        long,
        default_value = "scripts/bench_numpy_long.py",
        value_name = "FILE"
    )]
    pub numpy_script: PathBuf,
    /// Leave out the numpy peer.
    #[arg(long)]
    pub no_numpy: bool,
    /// Write the result as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

/// Flags shared by every benchmark.
#[derive(Debug, clap::Args)]
pub struct CommonArgs {
    /// Timed repetitions (the best and the median are reported).
    #[arg(long, default_value_t = 7, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub repetitions: u64,
    /// Write the result as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

/// Flags of `bench rls`.
#[derive(Debug, clap::Args)]
pub struct RlsArgs {
    /// n: number of parameters.
    #[arg(long, default_value_t = 9, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub params: u64,
    /// Updates per timed run.
    #[arg(long, default_value_t = 1_000_000, value_parser = clap::value_parser!(u64).range(1..=1_000_000_000))]
    pub samples: u64,
    /// ρ: forgetting factor in (0, 1] (ρ = 1 skips the division of P by ρ).
    #[arg(long, default_value_t = 0.99)]
    pub forgetting: f64,
    #[command(flatten)]
    pub common: CommonArgs,
}

/// Flags of `bench identify`.
#[derive(Debug, clap::Args)]
pub struct IdentifyArgs {
    /// Samples of the experiment (Ts = 0.01 s).
    #[arg(long, default_value_t = 2000, value_parser = clap::value_parser!(u64).range(10..=10_000_000))]
    pub samples: u64,
    /// Standard deviation of the white measurement noise added to y, mm.
    #[arg(long, default_value_t = 0.01)]
    pub noise: f64,
    /// Seed of the staircase input and the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[command(flatten)]
    pub common: CommonArgs,
}

/// Flags of `bench plant`.
#[derive(Debug, clap::Args)]
pub struct PlantArgs {
    /// Plant: `ipa` (physics), `paper` or `model:FILE`.
    #[arg(long, default_value = "ipa")]
    pub plant: String,
    /// TOML parameters of the physics plant (see `plant-config`).
    #[arg(long, value_name = "FILE")]
    pub plant_config: Option<PathBuf>,
    /// Samples simulated per run (staircase input, Ts = 0.01 s).
    #[arg(long, default_value_t = 6000, value_parser = clap::value_parser!(u64).range(1..=100_000_000))]
    pub samples: u64,
    /// Physics plant only: also time the previous integrator (classical RK4 at the default substeps,
    /// `ipa::plant::Integrator::Rk4`) on the same input in the same run, and print the speed-up.
    #[arg(long)]
    pub reference: bool,
    /// Physics plant only: also print the largest difference of the unquantised position (mm) to the
    /// 16×-refined reference (RK4 with substeps 16 times shorter) over the benchmark record (not timed).
    #[arg(long)]
    pub accuracy: bool,
    #[command(flatten)]
    pub common: CommonArgs,
}

/// Runs `bench`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.what {
        What::Rls(a) => rls(a),
        What::Identify(a) => identify(a),
        What::Plant(a) => plant(a),
        What::Oe(a) => super::bench_oe::run(a),
        What::Narx(a) => super::bench_narx::run(a),
        What::Long(a) => long(a),
    }
}

/// Prints a benchmark's text and writes `value` as JSON to `--json` (`inputs`: the files read, which
/// the output may not replace).
pub(super) fn emit<T: Serialize>(
    text: &str,
    value: &T,
    json: &Option<PathBuf>,
    inputs: &[&std::path::Path],
) -> anyhow::Result<()> {
    super::common::print_report(text, &[json.as_deref()])?;
    if let Some(path) = json {
        let body = super::common::report_json(value, true)
            .context("serialising the benchmark result")?
            + "\n";
        write_output(path, body.as_bytes(), inputs, "--json")?;
    }
    Ok(())
}

fn rls(a: RlsArgs) -> anyhow::Result<()> {
    #[derive(Serialize)]
    struct Out {
        benchmark: &'static str,
        #[serde(flatten)]
        rls: sysid_studies::bench::RlsBench,
        peak_gflops_build_target: f64,
        fraction_of_peak: f64,
        dependent_add_ns: f64,
    }
    let r = bench_rls(
        a.params as usize,
        a.samples as usize,
        a.forgetting,
        a.common.repetitions as usize,
    )?;
    let machine = peak_flops(a.common.repetitions as usize);
    let peak = machine.gflops_build_target;
    let text = format!(
        "RLS, n = {} parameters, rho = {}, {} updates per run, best of {}:\n  \
         fast (Rls::update):       {:.4e} samples/s ({:.1} ns/update, median {:.4e} samples/s)\n  \
         array (RlsN<{}>):         {}\n  \
         reference (plain loop):   {:.4e} samples/s\n  \
         flops/update:             {} -> {:.2} GFLOP/s ({:.0} % of the measured {:.1} GFLOP/s mul+add peak of this build)\n  \
         dependent add latency:    {:.3} ns (clock = add latency in cycles / this)\n",
        r.params,
        r.forgetting,
        r.samples,
        r.repetitions,
        r.samples_per_second,
        r.ns_per_update,
        r.median_samples_per_second,
        r.params,
        r.fixed_samples_per_second.map_or(format!("n/a (n > {})", sysid::rls::MAX_FIXED), |v| format!("{v:.4e} samples/s")),
        r.reference_samples_per_second,
        r.flops_per_update,
        r.gflops,
        100.0 * r.gflops / peak,
        peak,
        machine.dependent_add_ns
    );
    let out = Out {
        benchmark: "rls",
        fraction_of_peak: r.gflops / peak,
        rls: r,
        peak_gflops_build_target: peak,
        dependent_add_ns: machine.dependent_add_ns,
    };
    emit(&text, &out, &a.common.json, &[])
}

fn identify(a: IdentifyArgs) -> anyhow::Result<()> {
    #[derive(Serialize)]
    struct Out {
        benchmark: &'static str,
        samples: usize,
        noise_std_mm: f64,
        seed: u64,
        ls: sysid_studies::bench::IdentifyBench,
        rls: sysid_studies::bench::IdentifyBench,
        /// The paper's single RLS pass (`identify --passes 1`), what the figure of 0.25 ms timed.
        rls_one_pass: sysid_studies::bench::IdentifyBench,
    }
    let n = a.samples as usize;
    let u = ipa::input::generate(&ipa::InputSpec::Staircase, n, 0.01, 255.0, a.seed)?;
    let data = paper_experiment(&u, a.noise, a.seed)?;
    let reps = a.common.repetitions as usize;
    let ls = bench_identify(&data, &paper_settings(Method::Ls), reps)?;
    let rls = bench_identify(&data, &paper_settings(Method::Rls), reps)?;
    let one_pass = paper_settings(Method::Rls).with_passes(sysid::Passes::Fixed(1));
    let rls_one_pass = bench_identify(&data, &one_pass, reps)?;
    let line = |b: &sysid_studies::bench::IdentifyBench| {
        format!(
            "  {:<4} {:>10.1} µs per identification (median {:.1} µs; CPU time {:.1} µs), {} {}, converged: {}\n",
            b.method.to_string(),
            b.seconds_per_identification * 1e6,
            b.median_seconds_per_identification * 1e6,
            b.cpu_seconds_per_identification * 1e6,
            b.iterations,
            if b.method == Method::Ls {
                "key-term iterations"
            } else {
                "pass(es)"
            },
            b.converged
        )
    };
    let text = format!(
        "Hammerstein identification (na = 3, nb = 1, nk = 1) of {n} samples of the paper model \
         (staircase input, noise {} mm), best of {reps}:\n{}{}{} (the paper's single pass, --passes 1)\n",
        a.noise,
        line(&ls),
        line(&rls),
        line(&rls_one_pass).trim_end()
    );
    let out = Out {
        benchmark: "identify",
        samples: n,
        noise_std_mm: a.noise,
        seed: a.seed,
        ls,
        rls,
        rls_one_pass,
    };
    emit(&text, &out, &a.common.json, &[])
}

/// Integrator work per sample of the physics plant (last timed run).
#[derive(Serialize)]
struct IntegratorWork {
    integrator: String,
    steps_per_sample: f64,
    rejected_steps_per_sample: f64,
    derivative_evaluations_per_sample: f64,
}

fn work(p: &ipa::Ipa, samples: usize) -> IntegratorWork {
    let st = p.integration_stats();
    let n = samples as f64;
    IntegratorWork {
        integrator: format!("{:?}", p.integrator()),
        steps_per_sample: st.steps as f64 / n,
        rejected_steps_per_sample: st.rejected_steps as f64 / n,
        derivative_evaluations_per_sample: st.derivative_evaluations as f64 / n,
    }
}

fn work_line(w: &IntegratorWork) -> String {
    format!(
        "  {}: {:.2} steps ({:.2} rejected), {:.1} derivative evaluations per sample\n",
        w.integrator,
        w.steps_per_sample,
        w.rejected_steps_per_sample,
        w.derivative_evaluations_per_sample
    )
}

/// Unquantised positions (mm) after each sample of `u`, from rest at mid-stroke, with `integrator` and
/// the RK4 substeps divided by `refine`.
fn positions(
    cfg: &ipa::PlantConfig,
    integrator: ipa::plant::Integrator,
    refine: f64,
    u: &[f64],
) -> anyhow::Result<Vec<f64>> {
    let mut cfg = cfg.clone();
    cfg.integration.max_substep_ms /= refine;
    cfg.integration.slow_substep_ms /= refine;
    let mut p = ipa::Ipa::new(cfg)?;
    p.set_integrator(integrator);
    u.iter()
        .map(|&uk| {
            p.advance(uk)?;
            Ok(p.position_mm())
        })
        .collect()
}

fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn plant(a: PlantArgs) -> anyhow::Result<()> {
    if a.plant.trim() == "ipa" {
        return physics_plant(a);
    }
    if a.reference || a.accuracy {
        anyhow::bail!("--reference and --accuracy apply to --plant ipa only");
    }
    #[derive(Serialize)]
    struct Out {
        benchmark: &'static str,
        #[serde(flatten)]
        plant: sysid_studies::bench::PlantBench,
    }
    let inputs = ipa::spec::spec_input_files(&a.plant, a.plant_config.as_deref());
    let mut p = ipa::plant_from_spec(&a.plant, a.plant_config.as_deref())?;
    let u = ipa::input::generate(
        &ipa::InputSpec::Staircase,
        a.samples as usize,
        p.ts(),
        255.0,
        1,
    )?;
    let r = bench_plant(p.as_mut(), &u, a.common.repetitions as usize)?;
    let text = format!(
        "Plant '{}': {} samples ({:.1} s simulated) in {:.4} s, real-time factor {:.0} (median {:.0}), best of {}\n",
        r.plant, r.samples, r.simulated_seconds, r.wall_seconds, r.real_time_factor, r.median_real_time_factor, r.repetitions
    );
    emit(
        &text,
        &Out {
            benchmark: "plant",
            plant: r,
        },
        &a.common.json,
        &inputs,
    )
}

/// `bench plant` for the physics plant: the production integrator, and on request the RK4 reference
/// timed in the same run and the accuracy against the 16×-refined reference.
fn physics_plant(a: PlantArgs) -> anyhow::Result<()> {
    use ipa::plant::Integrator;
    use sysid::Plant;
    #[derive(Serialize)]
    struct Out {
        benchmark: &'static str,
        #[serde(flatten)]
        plant: sysid_studies::bench::PlantBench,
        work: IntegratorWork,
        #[serde(skip_serializing_if = "Option::is_none")]
        reference: Option<Reference>,
        #[serde(skip_serializing_if = "Option::is_none")]
        accuracy: Option<Accuracy>,
    }
    #[derive(Serialize)]
    struct Reference {
        #[serde(flatten)]
        plant: sysid_studies::bench::PlantBench,
        work: IntegratorWork,
        /// Best real-time factor over the reference's best.
        speedup: f64,
        /// Median over median.
        median_speedup: f64,
    }
    #[derive(Serialize)]
    struct Accuracy {
        refined_reference: &'static str,
        max_position_difference_mm: f64,
        reference_max_position_difference_mm: f64,
    }
    let inputs = ipa::spec::spec_input_files(&a.plant, a.plant_config.as_deref());
    let cfg = match a.plant_config.as_deref() {
        Some(path) => ipa::PlantConfig::from_toml_file(path)?,
        None => ipa::PlantConfig::default(),
    };
    let mut p = ipa::Ipa::new(cfg.clone())?;
    let n = a.samples as usize;
    let u = ipa::input::generate(&ipa::InputSpec::Staircase, n, p.ts(), 255.0, 1)?;
    let reps = a.common.repetitions as usize;
    let r = bench_plant(&mut p, &u, reps)?;
    let w = work(&p, n);
    let mut text = format!(
        "Plant '{}': {} samples ({:.1} s simulated) in {:.4} s, real-time factor {:.0} (median {:.0}), best of {}\n",
        r.plant, r.samples, r.simulated_seconds, r.wall_seconds, r.real_time_factor, r.median_real_time_factor, r.repetitions
    );
    text.push_str(&work_line(&w));
    let reference = if a.reference {
        let mut q = ipa::Ipa::new(cfg.clone())?;
        q.set_integrator(Integrator::Rk4);
        let rr = bench_plant(&mut q, &u, reps)?;
        let rw = work(&q, n);
        text.push_str(&format!(
            "Reference (previous integrator, classical RK4, substeps {} / {} ms), same input and run: {:.4} s, real-time factor {:.0} (median {:.0})\n",
            cfg.integration.max_substep_ms,
            cfg.integration.slow_substep_ms,
            rr.wall_seconds,
            rr.real_time_factor,
            rr.median_real_time_factor
        ));
        text.push_str(&work_line(&rw));
        let speedup = r.real_time_factor / rr.real_time_factor;
        let median_speedup = r.median_real_time_factor / rr.median_real_time_factor;
        text.push_str(&format!(
            "  speed-up {speedup:.2} (median {median_speedup:.2})\n"
        ));
        Some(Reference {
            plant: rr,
            work: rw,
            speedup,
            median_speedup,
        })
    } else {
        None
    };
    let accuracy = if a.accuracy {
        let fine = positions(&cfg, Integrator::Rk4, 16.0, &u)?;
        let ours = positions(&cfg, Integrator::DormandPrince, 1.0, &u)?;
        let rk4 = positions(&cfg, Integrator::Rk4, 1.0, &u)?;
        let acc = Accuracy {
            refined_reference: "classical RK4, substeps divided by 16",
            max_position_difference_mm: max_abs_diff(&ours, &fine),
            reference_max_position_difference_mm: max_abs_diff(&rk4, &fine),
        };
        text.push_str(&format!(
            "Accuracy over the record (unquantised position vs RK4 with 16x shorter substeps): max difference {:.3e} mm ({:?}), {:.3e} mm (RK4 at the default substeps)\n",
            acc.max_position_difference_mm,
            p.integrator(),
            acc.reference_max_position_difference_mm
        ));
        Some(acc)
    } else {
        None
    };
    emit(
        &text,
        &Out {
            benchmark: "plant",
            plant: r,
            work: w,
            reference,
            accuracy,
        },
        &a.common.json,
        &inputs,
    )
}

/// The load average of the last minute (`/proc/loadavg`), when the system has one.
fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg")
        .ok()?
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

fn long(a: LongArgs) -> anyhow::Result<()> {
    use sysid_studies::long::{bench_long, LongConfig, Measured};
    #[derive(Serialize)]
    struct Out {
        benchmark: &'static str,
        load_average_before: Option<f64>,
        load_average_after: Option<f64>,
        results: Vec<sysid_studies::long::LongRow>,
    }
    if a.rows.0.is_empty() {
        anyhow::bail!("--rows needs at least one record length");
    }
    let numpy = if a.no_numpy {
        None
    } else if a.numpy_script.is_file() {
        Some((a.python.clone(), a.numpy_script.clone()))
    } else {
        anyhow::bail!(
            "the numpy peer {} is not there: run from the repository's root, pass --numpy-script FILE, or \
             --no-numpy",
            a.numpy_script.display()
        );
    };
    // The default folder is the run's own: listed for removal on a signal from its creation (audit
    // s36 M-4: a SIGTERM left hundreds of MB of records in the temporary folder).
    let (dir, scratch) = match &a.dir {
        Some(d) => {
            std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
            (d.clone(), None)
        }
        None => {
            let d =
                std::env::temp_dir().join(format!("ipa-sysid-bench-long-{}", std::process::id()));
            let scratch = sysid_io::ScratchDir::create(&d)
                .with_context(|| format!("creating {}", d.display()))?;
            (d, Some(scratch))
        }
    };
    let cfg = LongConfig {
        exe: std::env::current_exe().context("finding the ipa-sysid binary")?,
        dir: dir.clone(),
        rows: a.rows.0.clone(),
        in_memory_max: a.in_memory_max,
        numpy,
    };
    let before = load_average();
    let results = bench_long(&cfg, |what| eprintln!("bench long: {what}..."));
    if let Some(scratch) = scratch {
        scratch.remove();
    }
    let results = results.map_err(|e| anyhow::anyhow!("bench long: {e}"))?;
    let after = load_average();
    let mib = |m: &Measured| {
        m.run.peak_rss_bytes.map_or("n/a".to_string(), |b| {
            format!("{:.1}", b as f64 / 1048576.0)
        })
    };
    let line = |name: &str, m: &Measured| {
        format!(
            "  {name:<34} {:>9.2} s {:>12.3e} rows/s {:>10} MiB peak RSS{}\n",
            m.run.wall_s,
            m.rows_per_s,
            mib(m),
            m.max_rel_diff_to_stream.map_or(String::new(), |d| format!(
                "   θ differs from streamed by ≤ {d:.1e} (relative)"
            ))
        )
    };
    let mut text = format!(
        "Long records: ARX(3,1,1) by least squares on `simulate --plant paper` records (child processes; \
         wall time from start to exit, peak RSS = the child's ru_maxrss); load average {} before, {} after\n",
        before.map_or("n/a".into(), |v| format!("{v:.2}")),
        after.map_or("n/a".into(), |v| format!("{v:.2}")),
    );
    for r in &results {
        text.push_str(&format!(
            "{} rows ({:.1} MB CSV):\n",
            r.rows,
            r.file_bytes as f64 / 1e6
        ));
        text.push_str(&line("ipa-sysid identify --stream on", &r.stream));
        if let Some(m) = &r.in_memory {
            text.push_str(&line("ipa-sysid identify --stream off", m));
        }
        if let Some(e) = &r.numpy_error {
            text.push_str(&format!("  numpy peer: no result ({e})\n"));
        }
        if let (Some(m), Some(d)) = (&r.numpy, &r.numpy_detail) {
            text.push_str(&line(
                &format!("numpy {} lstsq (Python {})", d.numpy, d.python),
                m,
            ));
            text.push_str(&format!(
                "  {:<34} read {:.2} s, lstsq {:.2} s (θ only: no standard deviations, metrics or residual tests)\n",
                "", d.read_s, d.solve_s
            ));
        }
    }
    let out = Out {
        benchmark: "long",
        load_average_before: before,
        load_average_after: after,
        results,
    };
    emit(&text, &out, &a.json, &[])
}

/// The JSON document of a benchmark on the public records (`bench oe`, `bench narx`): its cases
/// (`C`, one per record, run or skipped) and the peer's versions when it ran in the same run.
#[derive(Serialize)]
pub(super) struct RecordBench<C> {
    pub benchmark: &'static str,
    pub data_dir: String,
    pub repetitions: usize,
    pub cases: Vec<C>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peer_versions: Option<serde_json::Value>,
    /// Why the peer failed after ipa-sysid's own work (its results are kept; the exit is non-zero).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peer_failure: Option<String>,
}

/// The end of a benchmark whose results are printed: an error (non-zero exit) when its peer failed
/// (audit s32 L-2), after the results and the warning that says why.
pub(super) fn peer_exit<C>(out: &RecordBench<C>) -> anyhow::Result<()> {
    match &out.peer_failure {
        Some(_) => anyhow::bail!(
            "--peer: the peer failed (the warning above); ipa-sysid's own results are printed"
        ),
        None => Ok(()),
    }
}

/// Why a case of a benchmark on the public records is skipped: its file `path` is absent.
pub(super) fn absent(path: &std::path::Path) -> String {
    format!(
        "{} not found (the record is not part of the project)",
        path.display()
    )
}

/// The peer's versions (its JSON's `versions`, null when absent).
pub(super) fn peer_versions(peer: &serde_json::Value) -> serde_json::Value {
    peer.get("versions")
        .cloned()
        .unwrap_or(serde_json::Value::Null)
}

/// The peer's result for the case `name` (its JSON's `cases.NAME`), if it gave one.
pub(super) fn peer_case<'a>(
    peer: &'a serde_json::Value,
    name: &str,
) -> Option<&'a serde_json::Value> {
    peer.get("cases").and_then(|c| c.get(name))
}

/// Refuses a `--data-dir` that is not a folder (a typo): the benchmark would skip every case and exit
/// 0 having measured nothing (audit s16 L10). An existing folder without the records skips each case
/// in words, as documented.
pub fn check_data_dir(dir: &std::path::Path) -> anyhow::Result<()> {
    if !dir.is_dir() {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--data-dir"),
            dir.display(),
            "an existing folder (the one holding the public benchmark records)"
        ));
    }
    Ok(())
}
