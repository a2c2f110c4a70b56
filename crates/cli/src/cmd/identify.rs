//! `ipa-sysid identify`: a model from a CSV of input/output data (MATLAB `arx`, plus the Hammerstein model).

use std::path::{Path, PathBuf};

use sysid::estimate::{identify, Identification, Method};
use sysid::metrics::metrics;
use sysid::rls_ud::RlsForm;
use sysid::summary::IdentifyReport;
use sysid::windup::Windup;
use sysid::{IdentifyOptions, ModelKind};

use super::common::{check_outputs, write_output, ColumnArgs, ValidationArgs};

/// Flags of `identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// CSV file with a header row (columns chosen by --u-col, --y-col, --t-col). Several files or a
    /// folder (its *.csv files) identify each in parallel: one JSON line per file to --json or stdout.
    #[arg(long, value_name = "FILE", num_args = 1.., required = true)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Model structure.
    #[arg(long, value_enum, default_value = "hammerstein")]
    pub model: ModelKind,
    /// na: number of poles (order of A).
    #[arg(long, default_value_t = 3)]
    pub na: usize,
    /// nb: number of B coefficients (>= 1 for Hammerstein).
    #[arg(long, default_value_t = 1)]
    pub nb: usize,
    /// nk: input delay in samples.
    #[arg(long, default_value_t = 1)]
    pub nk: usize,
    /// Estimator.
    #[arg(long, value_enum, default_value = "rls")]
    pub method: Method,
    /// RLS forgetting factor ρ in (0, 1].
    #[arg(long, default_value_t = 1.0)]
    pub forgetting: f64,
    /// RLS initial covariance P(0) = p0 · I.
    #[arg(long, default_value_t = 1e6)]
    pub p0: f64,
    /// RLS passes over the data (later passes restart P and refine the estimate).
    #[arg(long, default_value_t = 1)]
    pub passes: usize,
    /// Maximum key-term iterations (Hammerstein with --method ls).
    #[arg(long, default_value_t = 100)]
    pub max_iterations: usize,
    /// RLS covariance form.
    #[arg(long, value_enum, default_value = "standard")]
    pub rls_form: RlsForm,
    /// RLS covariance-windup protection (for long records with periods without excitation).
    #[arg(long, value_enum, default_value = "none")]
    pub windup: Windup,
    /// Bound on tr P for --windup trace (default: p0 times the number of parameters).
    #[arg(long, value_name = "T")]
    pub max_trace: Option<f64>,
    /// IV stages (each rebuilds the instruments from the previous stage's model).
    #[arg(long, default_value_t = 10)]
    pub iv_stages: usize,
    /// Estimate a constant term c in the linear block.
    #[arg(long)]
    pub offset: bool,
    #[command(flatten)]
    pub val: ValidationArgs,
    /// Write the JSON summary here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Save the model for `validate --model` and `--plant model:FILE`.
    #[arg(long, value_name = "MODEL.json")]
    pub save_model: Option<PathBuf>,
}

impl Args {
    /// The identification these flags describe.
    pub fn settings(&self) -> Identification {
        IdentifyOptions {
            model: self.model,
            na: self.na,
            nb: self.nb,
            nk: self.nk,
            method: self.method,
            forgetting: self.forgetting,
            p0: self.p0,
            passes: self.passes,
            max_iterations: self.max_iterations,
            rls_form: self.rls_form,
            windup: self.windup,
            max_trace: self.max_trace,
            iv_stages: self.iv_stages,
            offset: self.offset,
        }
        .settings()
    }
}

/// Runs `identify`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if super::identify_batch::is_batch(&args.data) {
        return super::identify_batch::run(args);
    }
    let settings = args.settings();
    settings.check()?; // refuse bad flags before reading anything
    let Some(data_path) = args.data.first() else {
        anyhow::bail!("--data needs a file");
    };
    let mut inputs: Vec<&Path> = vec![data_path.as_path()];
    inputs.extend(args.val.validation.as_deref());
    check_outputs(
        &[(&args.json, "--json"), (&args.save_model, "--save-model")],
        &inputs,
    )?;
    let opts = args.columns.csv_options();
    let data = sysid::data::read_csv(data_path, &opts)?;
    let val = args.val.read(&opts)?;
    let fit = identify(&data, &settings)?;
    let est = metrics(&fit.model, &data)?;
    let val_metrics = val.as_ref().map(|v| metrics(&fit.model, v)).transpose()?;
    let report = IdentifyReport::new(&fit, &settings, est, val_metrics);
    let json_to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    let text = format!(
        "Data: {} ({} samples){}\n{}",
        data.name,
        data.len(),
        val.as_ref()
            .map(|v| format!("; validation: {} ({} samples)", v.name, v.len()))
            .unwrap_or_default(),
        crate::text::identify_report(&report)
    );
    if json_to_stdout {
        eprint!("{text}");
    } else {
        print!("{text}");
    }
    if let Some(path) = &args.json {
        write_output(path, report.to_json()?.as_bytes(), &inputs, "--json")?;
    }
    if let Some(path) = &args.save_model {
        write_output(
            path,
            sysid::model_file::to_json(&fit.model)?.as_bytes(),
            &inputs,
            "--save-model",
        )?;
    }
    Ok(())
}
