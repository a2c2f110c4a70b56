//! `ipa-sysid validate`: metrics of a saved model on new data (MATLAB `compare`).

use std::path::{Path, PathBuf};

use sysid::metrics::metrics;

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
    let m = metrics(&model, &data)?;
    let value = serde_json::json!({
        "model": model,
        "poles": sysid::summary::poles(&model),
        "stable": model.is_stable(),
        "metrics": { "validation": m },
    });
    let text = format!(
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
    if args.json.as_deref().is_some_and(|p| p.as_os_str() == "-") {
        eprint!("{text}");
    } else {
        print!("{text}");
    }
    if let Some(path) = &args.json {
        let json = serde_json::to_string_pretty(&value)? + "\n";
        write_output(path, json.as_bytes(), &inputs, "--json")?;
    }
    Ok(())
}
