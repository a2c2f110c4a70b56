//! `ipa-sysid identify`: a model from a CSV of input/output data (MATLAB `arx`, plus the Hammerstein model).

use std::path::{Path, PathBuf};

use sysid::data::stream::{CsvStream, RecordSource};
use sysid::estimate::{identify, Identification, Method, Passes};
use sysid::rls_ud::RlsForm;
use sysid::summary::IdentifyReport;
use sysid::windup::Windup;
use sysid::{IdentifyOptions, ModelKind};

use super::common::{
    check_outputs, print_notes, print_report, stream_note, write_output, ColumnArgs, StreamMode,
    ValidationArgs,
};
use sysid::detrend::{detrend, Detrend};

/// One order per input (`--nb 2,1`; one value applies to every input).
#[derive(Debug, Clone, PartialEq)]
pub struct OrderList(pub Vec<usize>);

impl OrderList {
    /// The first (for one input: the only) value.
    pub fn first(&self) -> usize {
        self.0.first().copied().unwrap_or(0)
    }

    /// The value for each of `n` inputs: one value applies to all; fails (naming `flag`) unless there is
    /// one value or one per input.
    pub fn per_input(&self, n: usize, flag: &'static str) -> anyhow::Result<Vec<usize>> {
        match self.0.len() {
            1 => Ok(vec![self.first(); n]),
            m if m == n => Ok(self.0.clone()),
            m => Err(sysid::SysidError::setting(
                sysid::Setting::Other(flag),
                format!("{m} values"),
                &format!("one value for every input, or one per input ({n} inputs)"),
            )
            .into()),
        }
    }
}

/// Parses `--nb 2` or, with several inputs, `--nb 2,1`.
fn parse_order_list(text: &str) -> Result<OrderList, String> {
    text.split(',')
        .map(parse_order)
        .collect::<Result<_, _>>()
        .map(OrderList)
}

/// Parses one order (`--na 3`); a range such as `1..5` points to `order`, which compares structures.
fn parse_order(text: &str) -> Result<usize, String> {
    if text.contains("..") {
        return Err(format!(
            "identify fits one structure; to compare orders {text} use `ipa-sysid order --na 1..5 --nb 1..3 \
             --nk 0..5` (it ranks them by fit, AIC and FPE), then identify the chosen one"
        ));
    }
    text.trim()
        .parse()
        .map_err(|e| format!("{e}; expected a whole number >= 0"))
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
    /// Model structure (`--model` is an older spelling; `--model` names a model file elsewhere). Default:
    /// the paper's Hammerstein model; `order` and `delay` search linear (arx) structures, as MATLAB's
    /// `arxstruc` and `delayest` do.
    #[arg(
        long = "structure",
        alias = "model",
        value_name = "STRUCTURE",
        value_enum,
        default_value = "hammerstein"
    )]
    pub model: ModelKind,
    /// na: number of poles (order of A).
    #[arg(long, default_value_t = 3, value_parser = parse_order)]
    pub na: usize,
    /// nb: number of B coefficients (>= 1 for Hammerstein); with several inputs one per input (2,1) or
    /// one for all.
    #[arg(long, default_value = "1", value_parser = parse_order_list)]
    pub nb: OrderList,
    /// nk: input delay in samples; with several inputs one per input (1,2) or one for all.
    #[arg(long, default_value = "1", value_parser = parse_order_list)]
    pub nk: OrderList,
    /// Several inputs (--u-col u1,u2) with --structure hammerstein: these inputs are linear (no deadzone).
    #[arg(long, value_name = "NAME,...", value_delimiter = ',')]
    pub linear_inputs: Vec<String>,
    /// Estimator. Default: the paper's recursive least squares (`order` defaults to ls, its closed form).
    #[arg(long, value_enum, default_value = "rls")]
    pub method: Method,
    /// RLS forgetting factor ρ in (0, 1].
    #[arg(long, default_value_t = 1.0)]
    pub forgetting: f64,
    /// RLS initial covariance P(0) = p0 · I.
    #[arg(long, default_value_t = 1e6)]
    pub p0: f64,
    /// RLS passes over the data: `auto` (default) repeats passes until the estimate settles (at most
    /// 100); `1` is the paper's single pass; N runs exactly N (later passes restart P and refine).
    #[arg(long, default_value = "auto", value_parser = parse_passes)]
    pub passes: Passes,
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
    /// Remove the estimation record's operating point from u and y (MATLAB `detrend`): `mean` (ū, ȳ) or
    /// `linear` (a straight line per signal). The model stores (u0, y0) = (ū, ȳ) (one u0 per input) and
    /// puts it back in validate, simulate and control.
    #[arg(long, value_enum, default_value = "none")]
    pub detrend: Detrend,
    /// Several --data files: estimate ONE model from all of them (MATLAB `merge`; no regression row spans
    /// two records), with metrics per record and pooled. Least squares only (--method ls); several
    /// inputs (--u-col u1,u2) too.
    #[arg(long)]
    pub merge: bool,
    #[command(flatten)]
    pub val: ValidationArgs,
    /// Lags M of the residual analysis (autocorrelation τ = 1..M, cross-correlation τ = −M..M).
    #[arg(long, default_value_t = sysid::residuals::DEFAULT_MAX_LAG, value_name = "M")]
    pub resid_lags: usize,
    /// Hammerstein: when the estimate diverges, is unstable or simulates the estimation data far worse
    /// (10 fit points) than the linear ARX model of the same orders, return that linear model written
    /// as a Hammerstein model (b_l = b_r = 0) instead; a warning says so either way.
    #[arg(long)]
    pub fallback: bool,
    /// Exit with code 1 when the result carries warnings (they are printed either way).
    #[arg(long)]
    pub strict: bool,
    /// Write the JSON summary here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Save the model for `validate --model` and `--plant model:FILE`.
    #[arg(long, value_name = "MODEL.json")]
    pub save_model: Option<PathBuf>,
    /// Read the record in passes with bounded memory (ARX by least squares; docs/data.md, "Long
    /// records"): `auto` streams a CSV file of 64 MiB or more when the identification allows it;
    /// `--stream` alone is `on`.
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, default_missing_value = "on", value_name = "WHEN")]
    pub stream: StreamMode,
}

/// `--passes`: a whole number of passes, or `auto`.
fn parse_passes(text: &str) -> Result<Passes, String> {
    match text.trim() {
        "auto" => Ok(Passes::AUTO),
        t => t.parse::<usize>().map(Passes::Fixed).map_err(|_| {
            format!("'{t}' is not a number of passes; expected a whole number such as 1, or auto")
        }),
    }
}

impl Args {
    /// The identification these flags describe (one input; several inputs go through `miso`).
    pub fn settings(&self) -> Identification {
        IdentifyOptions {
            model: self.model,
            na: self.na,
            nb: self.nb.first(),
            nk: self.nk.first(),
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
            fallback: self.fallback,
        }
        .settings()
    }
}

/// Runs `identify`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let several = args.columns.u_col.contains(',')
        || args.merge
        || super::identify_batch::is_batch(&args.data);
    if args.stream == StreamMode::On && several {
        anyhow::bail!(sysid::stream::refused(
            "several inputs, --merge and several files are read in memory"
        ));
    }
    if args.columns.u_col.contains(',') {
        return run_miso(&args);
    }
    if args.nb.0.len() > 1 || args.nk.0.len() > 1 || !args.linear_inputs.is_empty() {
        anyhow::bail!(
            "--nb/--nk lists and --linear-inputs are for several inputs: name them with --u-col u1,u2"
        );
    }
    if args.merge {
        return run_merged(&args);
    }
    if super::identify_batch::is_batch(&args.data) {
        return super::identify_batch::run(args);
    }
    let settings = args.settings();
    settings.check()?; // refuse bad flags before reading anything
    let Some(data_path) = args.data.first() else {
        anyhow::bail!("--data needs a file");
    };
    if streaming(&args, &settings, data_path)? {
        return run_streamed(&args, &settings, data_path);
    }
    let inputs = checked_inputs(&args, data_path)?;
    let opts = args.columns.csv_options();
    let records = args.val.records(data_path, &opts)?;
    print_notes(&records.notes);
    let (data, val) = (records.est, records.val);
    let (detrended, op) = detrend(&data, args.detrend);
    let mut fit = identify(&detrended, &settings)?;
    fit.model = fit.model.with_operating_point(op)?;
    // Metrics, residuals and warnings in the user's units: the model puts its operating point back.
    let mut report =
        IdentifyReport::assemble(&fit, &settings, &data, val.as_ref(), args.resid_lags)?;
    // The reader's warnings (a resampled record...) are warnings about these numbers too.
    report
        .warnings
        .extend(records.notes.iter().map(|n| format!("data: {n}")));
    let est = (data.name.as_str(), data.len());
    let val = val.as_ref().map(|v| (v.name.as_str(), v.len()));
    output(
        &args,
        &report,
        &fit.model,
        est,
        val,
        &records.notes,
        &inputs,
    )
}

/// Prints the report of an identification (`est` and `val`: the records' names and lengths) and writes
/// `--json` and `--save-model`; the in-memory and the streaming paths share it.
fn output(
    args: &Args,
    report: &IdentifyReport,
    model: &sysid::Model,
    est: (&str, usize),
    val: Option<(&str, usize)>,
    notes: &[String],
    inputs: &[&Path],
) -> anyhow::Result<()> {
    let json_to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    let text = format!(
        "Data: {} ({} samples){}\n{}",
        est.0,
        est.1,
        val.map(|(name, len)| format!("; validation: {name} ({len} samples)"))
            .unwrap_or_default(),
        crate::text::identify_report(report)
    ) + &model
        .operating_point()
        .map(|o| {
            format!(
                "Detrended ({}): the model works around the operating point u0 = {}, y0 = {} (put back in \
                 its simulations and predictions)\n",
                args.detrend,
                o.u.iter().map(|v| report::format::num(*v)).collect::<Vec<_>>().join(", "),
                report::format::num(o.y)
            )
        })
        .unwrap_or_default();
    if json_to_stdout {
        eprint!("{text}");
    } else {
        print!("{text}");
    }
    if let Some(path) = &args.json {
        let mut json = report.to_json()?;
        if !notes.is_empty() || args.detrend != Detrend::None {
            // The reader's warnings and the detrending travel with the numbers they concern.
            let mut value: serde_json::Value = serde_json::from_str(&json)?;
            if let Some(obj) = value.as_object_mut() {
                obj.insert("detrend".into(), serde_json::json!(args.detrend));
                obj.insert("data_notes".into(), serde_json::json!(notes));
            }
            json = serde_json::to_string_pretty(&value)? + "\n";
        }
        write_output(path, json.as_bytes(), inputs, "--json")?;
    }
    save_model(args, model, inputs)?;
    crate::exit::strict(args.strict, report.warnings.len())
}

/// Whether to read the record in passes (`--stream`, [`StreamMode::decide`]): ARX by least squares,
/// without `--split` or `--resample`.
fn streaming(args: &Args, settings: &Identification, data: &Path) -> anyhow::Result<bool> {
    let why = sysid::stream::unsupported(settings)
        .or_else(|| {
            args.val.split.is_some().then(|| {
                "--split needs the record's length before reading it; use --rows and --val-rows"
                    .into()
            })
        })
        .or_else(|| {
            args.columns
                .resample
                .is_some()
                .then(|| "--resample needs the whole record".into())
        });
    args.stream.decide(data, why, sysid::stream::refused)
}

/// `identify` with the records read in passes (`sysid::stream`): memory does not grow with the record.
fn run_streamed(args: &Args, settings: &Identification, data_path: &Path) -> anyhow::Result<()> {
    let inputs = checked_inputs(args, data_path)?;
    let opts = args.columns.csv_options();
    let mut est = CsvStream::open(data_path, &opts)?;
    let mut val = match args.val.validation_source(data_path, &opts) {
        Some((path, vopts)) => Some(CsvStream::open(path, &vopts)?),
        None => None,
    };
    let streamed = sysid::stream::identify_report(
        &mut est,
        val.as_mut().map(|v| v as &mut dyn RecordSource),
        settings,
        args.detrend,
        args.resid_lags,
    )?;
    let (fit, report) = &streamed.result;
    stream_note(
        est.name(),
        streamed.passes,
        streamed.shape.rows,
        args.stream,
    );
    let val_desc = val
        .as_ref()
        .zip(streamed.val_shape)
        .map(|(v, s)| (v.name(), s.rows));
    output(
        args,
        report,
        &fit.model,
        (est.name(), streamed.shape.rows),
        val_desc,
        &[],
        &inputs,
    )
}

/// The input files (the record and the validation file) after checking that the outputs can be written
/// and name none of them.
fn checked_inputs<'a>(args: &'a Args, data_path: &'a Path) -> anyhow::Result<Vec<&'a Path>> {
    let mut inputs: Vec<&Path> = vec![data_path];
    inputs.extend(args.val.validation.as_deref());
    check_outputs(
        &[(&args.json, "--json"), (&args.save_model, "--save-model")],
        &inputs,
    )?;
    Ok(inputs)
}

/// Writes `--save-model`, if given.
fn save_model(args: &Args, model: &sysid::Model, inputs: &[&Path]) -> anyhow::Result<()> {
    if let Some(path) = &args.save_model {
        let json = sysid::model_file::to_json(model)?;
        write_output(path, json.as_bytes(), inputs, "--save-model")?;
    }
    Ok(())
}

/// Runs `identify --merge`: one model from every `--data` record.
fn run_merged(args: &Args) -> anyhow::Result<()> {
    let settings = args.settings();
    settings.check()?;
    if args.method != Method::Ls {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--method"),
            args.method,
            "ls: --merge estimates by least squares on the stacked records"
        ));
    }
    if args.detrend != Detrend::None || args.val.split.is_some() {
        anyhow::bail!(
            "--merge cannot be combined with --detrend or --split; detrend or split the records first"
        );
    }
    let files = super::identify_batch::expand(&args.data)?;
    let mut inputs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.val.validation.as_deref());
    check_outputs(
        &[(&args.json, "--json"), (&args.save_model, "--save-model")],
        &inputs,
    )?;
    let opts = args.columns.csv_options();
    let mut records = Vec::with_capacity(files.len());
    let mut notes = Vec::new();
    for f in &files {
        let r = sysid::data::read_record(f, &opts)?;
        notes.extend(r.notes);
        records.push(r.data);
    }
    let val = args.val.read(&opts)?;
    print_notes(&notes);
    let fit = sysid::merge::identify_merged(&records, settings.structure, args.max_iterations)?;
    let est = sysid::merge::merged_metrics(&fit.model, &records)?;
    let val_metrics = val
        .as_ref()
        .map(|v| sysid::metrics::metrics(&fit.model, v))
        .transpose()?;
    let o = |v: Option<f64>| v.map_or_else(|| "n/a".to_string(), |v| format!("{v:.2}"));
    let mut text = format!(
        "Merged estimation: one {} model (na = {}, nb = {}, nk = {}) by least squares from {} records \
         ({} regression rows; no row spans two records), {} iteration(s)\n  a = {:?}\n  b = {:?}{}{}\n\n",
        fit.model.kind(),
        fit.model.na(),
        fit.model.nb(),
        fit.model.nk(),
        records.len(),
        fit.rows.iter().sum::<usize>(),
        fit.iterations,
        fit.model.a(),
        fit.model.b(),
        fit.model
            .deadzone()
            .map(|d| format!("\n  deadzone: b_l = {}, b_r = {}, m_l = {}, m_r = {}", d.b_l, d.b_r, d.m_l, d.m_r))
            .unwrap_or_default(),
        fit.model.offset().map(|c| format!("\n  c = {c}")).unwrap_or_default(),
    );
    text.push_str(
        "Free-run fits simulate each record from its own estimated initial outputs (MATLAB compare); \
         pooled: all records' rows k >= k0 with one mean\n",
    );
    text.push_str(&format!(
        "{:<50} {:>8} {:>14} {:>14}\n",
        "record", "N", "fit sim %", "fit pred %"
    ));
    for (name, m) in &est.records {
        text.push_str(&format!(
            "{:<50} {:>8} {:>14} {:>14}\n",
            name,
            m.n,
            o(m.fit_sim_percent),
            o(m.fit_pred_percent)
        ));
    }
    text.push_str(&format!(
        "{:<50} {:>8} {:>14} {:>14}\n",
        "pooled",
        est.records.iter().map(|(_, m)| m.n).sum::<usize>(),
        o(est.pooled_fit_sim_percent),
        o(est.pooled_fit_pred_percent)
    ));
    if let (Some(v), Some(m)) = (&val, &val_metrics) {
        text.push_str(&format!(
            "{:<50} {:>8} {:>14} {:>14}  (validation)\n",
            v.name,
            m.n,
            o(m.fit_sim_percent),
            o(m.fit_pred_percent)
        ));
    }
    print_report(&text, args.json.as_deref());
    if let Some(path) = &args.json {
        let value = serde_json::json!({
            "model": fit.model,
            "merged": records.iter().map(|r| r.name.clone()).collect::<Vec<_>>(),
            "iterations": fit.iterations,
            "stable": fit.model.is_stable(),
            "metrics": {
                "estimation": est.records.iter().map(|(name, m)| serde_json::json!({"data": name, "metrics": m})).collect::<Vec<_>>(),
                "pooled": {
                    "fit_sim_percent": est.pooled_fit_sim_percent,
                    "fit_sim_measured_percent": est.pooled_fit_sim_measured_percent,
                    "fit_pred_percent": est.pooled_fit_pred_percent,
                },
                "validation": val_metrics,
            },
            "data_notes": notes,
        });
        let json = serde_json::to_string_pretty(&value)? + "\n";
        write_output(path, json.as_bytes(), &inputs, "--json")?;
    }
    save_model(args, &fit.model, &inputs)
}

/// Runs `identify --u-col u1,u2,...`: one model with several inputs (MISO), by least squares, RLS,
/// output error or instrumental variables, with the single-input safeguards applied per input.
fn run_miso(args: &Args) -> anyhow::Result<()> {
    let names: Vec<String> = args
        .columns
        .u_col
        .split(',')
        .map(|s| s.trim().to_string())
        .collect();
    if args.merge {
        if args.method != Method::Ls || args.val.split.is_some() {
            anyhow::bail!(
                "--merge with several inputs (--u-col {}) estimates by least squares (--method ls), without --split",
                args.columns.u_col
            );
        }
    } else if args.data.len() != 1 {
        anyhow::bail!(
            "several inputs (--u-col {}) are estimated from one --data file, or from several with --merge",
            args.columns.u_col
        );
    }
    if args.merge && args.val.val_rows.is_some() && args.val.validation.is_none() {
        anyhow::bail!(
            "--merge with --val-rows needs --validation FILE (which of the merged records would the rows be of?)"
        );
    }
    if args.merge && args.detrend != Detrend::None {
        anyhow::bail!("--merge cannot be combined with --detrend; detrend the records first");
    }
    for l in &args.linear_inputs {
        if !names.contains(l) {
            anyhow::bail!(sysid::SysidError::setting(
                sysid::Setting::Other("--linear-inputs"),
                l,
                &format!("names among the inputs of --u-col ({})", names.join(", "))
            ));
        }
    }
    args.settings().check()?;
    let nb = args.nb.per_input(names.len(), "--nb")?;
    let nk = args.nk.per_input(names.len(), "--nk")?;
    let files = if args.merge {
        super::identify_batch::expand(&args.data)?
    } else {
        args.data.clone()
    };
    let mut inputs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.val.validation.as_deref());
    check_outputs(
        &[(&args.json, "--json"), (&args.save_model, "--save-model")],
        &inputs,
    )?;
    let mut records = Vec::with_capacity(files.len());
    let mut notes = Vec::new();
    let mut val = None;
    for f in &files {
        let (est, v) = read_miso(args, f, &names, &mut notes)?;
        records.push(est);
        if val.is_none() {
            val = v;
        }
    }
    notes.dedup();
    print_notes(&notes);
    let Some(first) = records.first() else {
        anyhow::bail!("--data needs a file");
    };
    let ts = first.ts;
    let problem_inputs = |u: &[Vec<f64>]| -> Vec<sysid::miso::MisoInput> {
        names
            .iter()
            .zip(u)
            .enumerate()
            .map(|(i, (name, u))| sysid::miso::MisoInput {
                name: name.clone(),
                u: u.clone(),
                nb: nb[i],
                nk: nk[i],
                linear: args.linear_inputs.contains(name),
            })
            .collect()
    };
    let fit = if args.merge {
        let segments: Vec<Vec<sysid::miso::MisoInput>> =
            records.iter().map(|r| problem_inputs(&r.u)).collect();
        let ys: Vec<&[f64]> = records.iter().map(|r| r.y.as_slice()).collect();
        sysid::miso::least_squares_merged(
            &segments,
            &ys,
            ts,
            args.na,
            args.model,
            args.offset,
            args.max_iterations,
        )?
    } else {
        let r = first;
        let us: Vec<&[f64]> = r.u.iter().map(Vec::as_slice).collect();
        let (du, dy, op) = sysid::detrend::detrend_signals(&us, &r.y, args.detrend);
        let est_inputs = problem_inputs(&du);
        let problem = sysid::miso::MisoProblem {
            inputs: &est_inputs,
            y: &dy,
            ts,
            na: args.na,
            kind: args.model,
            offset: args.offset,
        };
        let mut fit = problem.identify(&args.settings(), &r.name)?;
        fit.model = fit.model.with_operating_point(op)?;
        fit
    };
    // Metrics, residuals and warnings in the user's units (the model puts its operating point back).
    let est_u: Vec<Vec<&[f64]>> = records
        .iter()
        .map(|r| r.u.iter().map(Vec::as_slice).collect())
        .collect();
    let est_records: Vec<sysid::summary::MisoRecord> = records
        .iter()
        .zip(&est_u)
        .map(|(r, u)| sysid::summary::MisoRecord {
            name: &r.name,
            u,
            y: &r.y,
        })
        .collect();
    let val_u: Option<Vec<&[f64]>> = val
        .as_ref()
        .map(|v| v.u.iter().map(Vec::as_slice).collect());
    let val_record = val
        .as_ref()
        .zip(val_u.as_ref())
        .map(|(v, u)| sysid::summary::MisoRecord {
            name: &v.name,
            u,
            y: &v.y,
        });
    let mut report = sysid::summary::MisoReport::assemble(
        fit,
        args.method,
        &est_records,
        val_record.as_ref(),
        args.resid_lags,
    )?;
    report
        .warnings
        .extend(notes.iter().map(|n| format!("data: {n}")));
    let (fit, warnings) = (&report.fit, &report.warnings);
    let how = match (args.method, fit.converged) {
        (Method::Rls, true) => format!(
            "recursive least squares ({} pass(es), settled)",
            fit.iterations
        ),
        (Method::Rls, false) => format!(
            "recursive least squares ({} pass(es), NOT settled)",
            fit.iterations
        ),
        (Method::Oe, c) => format!(
            "output error ({} iteration(s){})",
            fit.iterations,
            if c { ", converged" } else { ", NOT converged" }
        ),
        (Method::Iv, c) => format!(
            "instrumental variables ({} stage(s){})",
            fit.iterations,
            if c { ", settled" } else { ", NOT settled" }
        ),
        (_, true) => format!("least squares ({} key-term iteration(s))", fit.iterations),
        (_, false) => format!(
            "least squares ({} key-term iteration(s), NOT converged)",
            fit.iterations
        ),
    };
    let m = &fit.model;
    let data_name = records
        .iter()
        .map(|r| r.name.as_str())
        .collect::<Vec<_>>()
        .join(" + ");
    let n_samples: usize = records.iter().map(|r| r.y.len()).sum();
    let mut text = format!(
        "Data: {data_name} ({n_samples} samples){}{}\n{} model with {} inputs, na = {}, Ts = {} s, estimated by {how}\n  \
         a = {:?}{}\n",
        if args.merge {
            format!(" merged ({} records; no regression row spans two records)", records.len())
        } else {
            String::new()
        },
        val.as_ref()
            .map(|v| format!("; validation: {} ({} samples)", v.name, v.y.len()))
            .unwrap_or_default(),
        m.kind(),
        m.inputs().len(),
        m.na(),
        ts,
        m.a(),
        m.offset().map(|c| format!("\n  c = {c}")).unwrap_or_default(),
    );
    for ch in m.inputs() {
        text.push_str(&format!(
            "  input {}: nb = {}, nk = {}, b = {:?}{}\n",
            ch.name(),
            ch.nb(),
            ch.nk(),
            ch.b(),
            ch.deadzone()
                .map(|d| format!(
                    ", deadzone b_l = {}, b_r = {}, m_l = {}, m_r = {}",
                    d.b_l, d.b_r, d.m_l, d.m_r
                ))
                .unwrap_or_else(|| ", linear".into())
        ));
    }
    if let Some(o) = m.operating_point() {
        text.push_str(&format!(
            "Detrended ({}): the model works around the operating point u0 = {}, y0 = {} (put back in its \
             simulations and predictions)\n",
            args.detrend,
            o.u.iter().map(|v| report::format::num(*v)).collect::<Vec<_>>().join(", "),
            report::format::num(o.y)
        ));
    }
    text.push_str("\nParameters (estimate ± standard deviation)\n");
    for p in &fit.params {
        let sd = match (&p.std, p.name.starts_with("b1 (") && p.value == 1.0) {
            (_, true) => " (fixed: normalisation)".to_string(),
            (Some(s), _) => format!("  ± {}", report::format::num(*s)),
            (None, _) => "  ± n/a".to_string(),
        };
        text.push_str(&format!(
            "  {:<14} = {:>14}{sd}\n",
            p.name,
            report::format::num(p.value)
        ));
    }
    for n in &fit.notes {
        text.push_str(&format!("note: {n}\n"));
    }
    let o = |v: Option<f64>| v.map_or_else(|| "n/a".to_string(), |v| format!("{v:.4}"));
    text.push_str(&format!(
        "\nFit % (simulation): estimation {}{}; {}\n",
        report
            .estimation
            .iter()
            .map(|e| o(e.metrics.fit_sim_percent))
            .collect::<Vec<_>>()
            .join(", "),
        report
            .validation
            .as_ref()
            .map(|v| format!(", validation {}", o(v.metrics.fit_sim_percent)))
            .unwrap_or_default(),
        if m.is_stable() { "stable" } else { "UNSTABLE" }
    ));
    let mut entries: Vec<(&str, &sysid::summary::ResidualEntry)> = report
        .estimation
        .iter()
        .map(|e| ("estimation", &e.residuals))
        .collect();
    if let Some(v) = &report.validation {
        entries.push(("validation", &v.residuals));
    }
    text.push_str(&crate::text::residuals_text(&entries));
    for w in warnings {
        text.push_str(&format!("warning: {w}\n"));
    }
    print_report(&text, args.json.as_deref());
    if let Some(path) = &args.json {
        let mut value = report.to_json_value();
        if let Some(obj) = value.as_object_mut() {
            obj.insert("detrend".into(), serde_json::json!(args.detrend));
            if args.merge {
                let names: Vec<&str> = records.iter().map(|r| r.name.as_str()).collect();
                obj.insert("merged".into(), serde_json::json!(names));
            }
            obj.insert("data_notes".into(), serde_json::json!(notes));
        }
        let json = serde_json::to_string_pretty(&value)? + "\n";
        write_output(path, json.as_bytes(), &inputs, "--json")?;
    }
    save_model(args, m, &inputs)?;
    crate::exit::strict(args.strict, warnings.len())
}

/// One record with several inputs: each input's signal, the output, Ts and the name.
struct MisoRecord {
    u: Vec<Vec<f64>>,
    y: Vec<f64>,
    ts: f64,
    name: String,
}

/// Reads the estimation record (and, when asked for, the validation record) of `file` with one input
/// column per name in `names` (same output column, same rows); the reader's notes go to `notes`.
fn read_miso(
    args: &Args,
    file: &Path,
    names: &[String],
    notes: &mut Vec<String>,
) -> anyhow::Result<(MisoRecord, Option<MisoRecord>)> {
    let mut est: Option<MisoRecord> = None;
    let mut val: Option<MisoRecord> = None;
    for name in names {
        let mut opts = args.columns.csv_options();
        opts.u_col = name.clone();
        let val_args = ValidationArgs {
            val_u_col: None,
            ..args.val.clone()
        };
        let r = val_args.records(file, &opts)?;
        notes.extend(r.notes);
        let e = est.get_or_insert_with(|| MisoRecord {
            u: Vec::new(),
            y: r.est.y.clone(),
            ts: r.est.ts,
            name: r.est.name.clone(),
        });
        e.u.push(r.est.u);
        if let Some(v) = r.val {
            let vr = val.get_or_insert_with(|| MisoRecord {
                u: Vec::new(),
                y: v.y.clone(),
                ts: v.ts,
                name: v.name.clone(),
            });
            vr.u.push(v.u);
        }
    }
    let Some(est) = est else {
        anyhow::bail!("--u-col names no input");
    };
    Ok((est, val))
}
