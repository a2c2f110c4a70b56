//! `ipa-sysid bench`: RLS throughput, identification time and the plant's real-time factor. The timing
//! loops live in `sysid_studies::bench`; this file parses flags, builds the inputs and prints.

use std::path::PathBuf;

use anyhow::Context;
use serde::Serialize;
use sysid::estimate::Method;
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
    #[command(flatten)]
    pub common: CommonArgs,
}

/// Runs `bench`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.what {
        What::Rls(a) => rls(a),
        What::Identify(a) => identify(a),
        What::Plant(a) => plant(a),
    }
}

fn emit<T: Serialize>(
    text: &str,
    value: &T,
    json: &Option<PathBuf>,
    inputs: &[&std::path::Path],
) -> anyhow::Result<()> {
    let to_stdout = json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    if to_stdout {
        eprint!("{text}");
    } else {
        print!("{text}");
    }
    if let Some(path) = json {
        let body =
            serde_json::to_string_pretty(value).context("serialising the benchmark result")? + "\n";
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
    }
    let n = a.samples as usize;
    let u = ipa::input::generate(&ipa::InputSpec::Staircase, n, 0.01, 255.0, a.seed)?;
    let data = paper_experiment(&u, a.noise, a.seed)?;
    let reps = a.common.repetitions as usize;
    let ls = bench_identify(&data, &paper_settings(Method::Ls), reps)?;
    let rls = bench_identify(&data, &paper_settings(Method::Rls), reps)?;
    let line = |b: &sysid_studies::bench::IdentifyBench| {
        format!(
            "  {:<4} {:>10.1} µs per identification (median {:.1} µs), {} {}, converged: {}\n",
            b.method.to_string(),
            b.seconds_per_identification * 1e6,
            b.median_seconds_per_identification * 1e6,
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
         (staircase input, noise {} mm), best of {reps}:\n{}{}",
        a.noise,
        line(&ls),
        line(&rls)
    );
    let out = Out {
        benchmark: "identify",
        samples: n,
        noise_std_mm: a.noise,
        seed: a.seed,
        ls,
        rls,
    };
    emit(&text, &out, &a.common.json, &[])
}

fn plant(a: PlantArgs) -> anyhow::Result<()> {
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
