//! `ipa-sysid validate`: metrics of a saved model on new data (MATLAB `compare`).

use std::path::{Path, PathBuf};

use sysid::summary::ValidationReport;

use super::common::{check_outputs, write_output, ColumnArgs};

/// Flags of `validate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Model file written by `identify --save-model` (or an `identify --json` file).
    #[arg(long, value_name = "MODEL.json")]
    pub model: PathBuf,
    /// CSV file with the validation record. Without a time column and --ts, the model's Ts is used.
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Lags M of the residual analysis (autocorrelation τ = 1..M, cross-correlation τ = −M..M).
    #[arg(long, default_value_t = sysid::residuals::DEFAULT_MAX_LAG, value_name = "M")]
    pub resid_lags: usize,
    /// Exit with code 1 when the result carries warnings (they are printed either way).
    #[arg(long)]
    pub strict: bool,
    /// Write the metrics as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

/// Runs `validate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let inputs: [&Path; 2] = [&args.model, &args.data];
    check_outputs(&[(&args.json, "--json")], &inputs)?;
    let model = sysid::model_file::read_model(&args.model)?;
    let mut opts = args.columns.csv_options();
    opts.fallback_ts = Some(model.ts());
    let data = sysid::data::read_csv(&args.data, &opts)?;
    if (data.ts - model.ts()).abs() > 1e-3 * model.ts() {
        anyhow::bail!(
            "{}: the data are sampled at Ts = {} s but the model was identified at Ts = {} s; \
             resample the data or pass the matching --ts",
            data.name,
            data.ts,
            model.ts()
        );
    }
    let report = ValidationReport::assemble(&model, &data, args.resid_lags)?;
    let m = &report.metrics.validation;
    let mut text = format!(
        "{} on {} ({} samples): fit {} % (simulation), {} % (1-step prediction); loss {}, FPE {}; {}\n",
        args.model.display(),
        data.name,
        data.len(),
        m.fit_sim_percent.map_or("n/a".into(), |v| format!("{v:.2}")),
        m.fit_pred_percent.map_or("n/a".into(), |v| format!("{v:.2}")),
        report::format::num(m.loss),
        m.fpe.map_or("n/a".into(), report::format::num),
        if model.is_stable() { "stable" } else { "UNSTABLE" }
    );
    text.push_str(&crate::text::residuals_text(&[(
        "validation",
        &report.residuals.validation,
    )]));
    for w in &report.warnings {
        text.push_str(&format!("warning: {w}\n"));
    }
    if args.json.as_deref().is_some_and(|p| p.as_os_str() == "-") {
        eprint!("{text}");
    } else {
        print!("{text}");
    }
    if let Some(path) = &args.json {
        write_output(path, report.to_json()?.as_bytes(), &inputs, "--json")?;
    }
    crate::exit::strict(args.strict, report.warnings.len())
}
