//! `ipa-sysid identify`: a model from a CSV of input/output data (MATLAB `arx`, plus the Hammerstein model).

use std::path::{Path, PathBuf};

use sysid::estimate::{identify, IdentifySettings, Method};
use sysid::summary::IdentifyReport;
use sysid::validation::metrics;
use sysid::{ModelKind, Orders};

use super::common::{check_outputs, write_output, ColumnArgs, ValidationArgs};

/// Model structure flag values.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum KindArg {
    /// Static deadzone (b_l, b_r, m_l, m_r) followed by ARX, b1 = 1.
    Hammerstein,
    /// Linear ARX.
    Arx,
}

/// Estimator flag values.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum MethodArg {
    /// Batch least squares via QR (Hammerstein: iterated key-term separation).
    Ls,
    /// Recursive least squares with forgetting (paper eqs. 9-12).
    Rls,
    /// Output-error refinement (Levenberg-Marquardt on the simulation error) from the LS estimate:
    /// unbiased under output (measurement) noise. Batch.
    Oe,
    /// Recursive instrumental variables, instruments from an auxiliary model's simulated output:
    /// unbiased under output noise. Recursive.
    Iv,
}

/// RLS covariance form (`--rls-form`).
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum RlsFormArg {
    /// Dense P, the paper's eq. 12.
    Standard,
    /// Bierman's UD factorisation P = U D U^T (numerically robust).
    Ud,
}

/// RLS covariance-windup protection (`--windup`).
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum WindupArg {
    /// Ordinary exponential forgetting.
    None,
    /// Scale P down whenever tr P exceeds --max-trace.
    Trace,
    /// Directional forgetting: forget only along the measured regressor.
    Directional,
}

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
    pub model: KindArg,
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
    pub method: MethodArg,
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
    pub rls_form: RlsFormArg,
    /// RLS covariance-windup protection (for long records with periods without excitation).
    #[arg(long, value_enum, default_value = "none")]
    pub windup: WindupArg,
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
    /// The estimator settings these flags describe.
    pub fn settings(&self) -> IdentifySettings {
        IdentifySettings {
            kind: match self.model {
                KindArg::Hammerstein => ModelKind::Hammerstein,
                KindArg::Arx => ModelKind::Arx,
            },
            orders: Orders {
                na: self.na,
                nb: self.nb,
                nk: self.nk,
            },
            method: match self.method {
                MethodArg::Ls => Method::Ls,
                MethodArg::Rls => Method::Rls,
                MethodArg::Oe => Method::Oe,
                MethodArg::Iv => Method::Iv,
            },
            forgetting: self.forgetting,
            p0: self.p0,
            offset: self.offset,
            passes: self.passes,
            max_iterations: self.max_iterations,
            rls_form: match self.rls_form {
                RlsFormArg::Standard => sysid::rls_ud::RlsForm::Standard,
                RlsFormArg::Ud => sysid::rls_ud::RlsForm::Ud,
            },
            windup: match self.windup {
                WindupArg::None => sysid::windup::Windup::None,
                WindupArg::Trace => sysid::windup::Windup::Trace,
                WindupArg::Directional => sysid::windup::Windup::Directional,
            },
            max_trace: self.max_trace,
            iv_stages: self.iv_stages,
            // A one-sided input (never negative or never positive) drops the unexcited deadzone branch
            // and says so in the report's note.
            drop_unexcited_branch: true,
            ..IdentifySettings::default()
        }
    }
}

/// Runs `identify`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if super::identify_batch::is_batch(&args.data) {
        return super::identify_batch::run(args);
    }
    let settings = args.settings();
    settings.structure()?; // refuse bad flags before reading anything
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
        report.to_text()
    );
    if json_to_stdout {
        eprint!("{text}");
    } else {
        print!("{text}");
    }
    if let Some(path) = &args.json {
        write_output(path, report.to_json().as_bytes(), &inputs, "--json")?;
    }
    if let Some(path) = &args.save_model {
        write_output(
            path,
            sysid::model_file::to_json(&fit.model).as_bytes(),
            &inputs,
            "--save-model",
        )?;
    }
    Ok(())
}
