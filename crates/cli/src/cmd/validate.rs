//! `ipa-sysid validate`: metrics of a saved model on new data (MATLAB `compare`).

use std::path::{Path, PathBuf};

use sysid::summary::ValidationReport;

use super::common::{check_outputs, print_notes, write_output, ColumnArgs};

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
    /// Write the model's output as CSV: t,y,y_sim,y_pred,residual (residual = y − y_pred; y_pred is the
    /// --horizon-step prediction; MATLAB `compare`/`predict`).
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// Prediction horizon K in samples for y_pred and the prediction metrics (MATLAB `predict(m, z, K)`;
    /// 1 = one-step-ahead).
    #[arg(long, value_name = "K", default_value_t = 1)]
    pub horizon: usize,
}

/// Runs `validate`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let inputs: [&Path; 2] = [&args.model, &args.data];
    check_outputs(&[(&args.json, "--json"), (&args.out, "--out")], &inputs)?;
    if args.horizon == 0 {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--horizon"),
            0,
            "a prediction horizon K >= 1 in samples"
        ));
    }
    let model = sysid::model_file::read_model(&args.model)?;
    let mut opts = args.columns.csv_options();
    opts.fallback_ts = Some(model.ts());
    // A model with several inputs reads one column per input: --u-col u1,u2 or the model's input names.
    let miso = model.inputs().len() > 1 || opts.u_col.contains(',');
    let cols: Vec<String> = if opts.u_col.contains(',') {
        opts.u_col
            .split(',')
            .map(|s| s.trim().to_string())
            .collect()
    } else if miso {
        model
            .inputs()
            .iter()
            .map(|i| i.name().to_string())
            .collect()
    } else {
        vec![opts.u_col.clone()]
    };
    let all_cols = opts.u_col.clone();
    if let Some(first) = cols.first() {
        opts.u_col = first.clone();
    }
    let record = sysid::data::read_record(&args.data, &opts)?;
    print_notes(&record.notes);
    let data = record.data;
    let mut extra: Vec<Vec<f64>> = Vec::new();
    if miso {
        if cols.len() != model.inputs().len() {
            anyhow::bail!(sysid::SysidError::setting(
                sysid::Setting::UCol,
                &all_cols,
                &format!("one column per model input ({})", model.inputs().len())
            ));
        }
        for c in &cols {
            let o = sysid::data::CsvOptions {
                u_col: c.clone(),
                ..opts.clone()
            };
            extra.push(sysid::data::read_record(&args.data, &o)?.data.u);
        }
    }
    let us: Vec<&[f64]> = if extra.is_empty() {
        vec![data.u.as_slice()]
    } else {
        extra.iter().map(Vec::as_slice).collect()
    };
    if (data.ts - model.ts()).abs() > 1e-3 * model.ts() {
        anyhow::bail!(
            "{}: the data are sampled at Ts = {} s but the model was identified at Ts = {} s; \
             resample the data or pass the matching --ts",
            data.name,
            data.ts,
            model.ts()
        );
    }
    let mut report =
        ValidationReport::assemble_miso(&model, &us, &data.y, &data.name, args.resid_lags)?;
    report
        .warnings
        .extend(record.notes.iter().map(|n| format!("data: {n}")));
    let m = report.metrics.validation.clone();
    let out = sysid::metrics::model_output(&model, &us, &data.y, args.horizon)?;
    let mut value = serde_json::to_value(&report)?;
    if let Some(obj) = value.as_object_mut() {
        obj.insert("horizon".into(), serde_json::json!(args.horizon));
        obj.insert(
            "fit_pred_horizon_percent".into(),
            serde_json::json!(out.fit_pred_percent),
        );
        obj.insert("data_notes".into(), serde_json::json!(record.notes));
    }
    let mut text = format!(
        "{} on {} ({} samples): fit {} % (simulation), {} % (1-step prediction){}; loss {}, FPE {}; {}\n",
        args.model.display(),
        data.name,
        data.len(),
        m.fit_sim_percent.map_or("n/a".into(), |v| format!("{v:.2}")),
        m.fit_pred_percent.map_or("n/a".into(), |v| format!("{v:.2}")),
        if args.horizon > 1 {
            format!(
                ", {} % ({}-step prediction)",
                out.fit_pred_percent.map_or("n/a".into(), |v| format!("{v:.2}")),
                args.horizon
            )
        } else {
            String::new()
        },
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
    if let Some(path) = &args.out {
        let t = sysid::data::sample_times(data.len(), data.ts);
        let mut w = csv::Writer::from_writer(Vec::new());
        w.write_record(["t", "y", "y_sim", "y_pred", "residual"])?;
        for k in 0..data.len() {
            let sim = out
                .y_sim
                .as_ref()
                .map_or(String::new(), |s| s[k].to_string());
            w.write_record([
                t[k].to_string(),
                data.y[k].to_string(),
                sim,
                out.y_pred[k].to_string(),
                (data.y[k] - out.y_pred[k]).to_string(),
            ])?;
        }
        let bytes = w.into_inner().map_err(|e| anyhow::anyhow!("{e}"))?;
        write_output(path, &bytes, &inputs, "--out")?;
    }
    if let Some(path) = &args.json {
        let json = serde_json::to_string_pretty(&value)? + "\n";
        write_output(path, json.as_bytes(), &inputs, "--json")?;
    }
    crate::exit::strict(args.strict, report.warnings.len())
}
